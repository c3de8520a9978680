//! Packet probe: `cargo run --release --example pk -- SCENE LAYOUT SIZE REPS` traces the
//! scene's 512² eye rays (patch mode, as triangles) in 8×8 tiles on one thread: with the
//! packet kernel in packets of SIZE rays (8, 16, 32 or 64; 0 = single rays), REPS rounds,
//! and prints the fastest round's Mrays/s. For quick A/B runs and profiling; the tables come
//! from `quiver packets`.
use quiver_rt::traverse::{FastBoxes, NoFilter, NoStats, PacketMode, PacketQuery};
use quiver_rt::{BuildOptions, Layout, RayQuery};
use quiver_scenes::scene::tessellate::DEFAULT_RESOLUTION;
use quiver_scenes::Scene;
use std::time::Instant;

fn main() {
    let a: Vec<String> = std::env::args().collect();
    let name = a.get(1).map_or("teapot12", |s| s.as_str());
    let layout: Layout = a
        .get(2)
        .map_or("bvh8-dfs", |s| s.as_str())
        .parse()
        .expect("layout");
    let size: usize = a.get(3).map_or(64, |s| s.parse().expect("size"));
    let reps: usize = a.get(4).map_or(20, |s| s.parse().expect("reps"));
    let scene = Scene::load(name)
        .expect("scene")
        .into_patches(DEFAULT_RESOLUTION);
    let bvh = BuildOptions::default()
        .layout(layout)
        .build(&scene.triangles());
    let eye = quiver_lab::rays::camera_tiles(&scene.camera, 512, 8);
    let mut out = vec![None; eye.len()];
    let mut best = f64::MAX;
    for _ in 0..reps {
        let t = Instant::now();
        if size == 0 {
            for (o, r) in out.iter_mut().zip(&eye) {
                *o = bvh.closest_hit(r);
            }
        } else {
            for (o, r) in out.chunks_mut(size).zip(eye.chunks(size)) {
                let mode = PacketMode::Always;
                bvh.closest_hit_packet_with::<FastBoxes, NoStats, _>(
                    PacketQuery::new(r).mode(mode),
                    o,
                    &mut NoStats,
                    &mut NoFilter,
                );
            }
        }
        best = best.min(t.elapsed().as_secs_f64());
    }
    let hits = out.iter().filter(|h| h.is_some()).count();
    let mrays = eye.len() as f64 / best / 1e6;
    println!(
        "{name} {} size {size}: {mrays:.2} Mrays/s, {hits} hits",
        layout.name()
    );
}
