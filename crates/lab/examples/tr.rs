//! Trace probe: `cargo run --release -p quiver-lab --example tr -- SCENE REPS [RAYS]` builds
//! the default BVH over SCENE (a generator name or a mesh file, as triangles) and traces, on
//! one thread, its 512² eye rays, shadow rays from their hits toward the first light, and RAYS
//! incoherent rays (default 200,000), REPS rounds each, interleaved; prints the fastest
//! round's Mrays/s of each. The fastest round is what a busy machine perturbs least: for
//! quick A/B runs of two builds; the tables come from `quiver bench`. Environment knobs for
//! trying build settings: `TR_LEAF` (largest leaf), `TR_BINS`, `TR_CT` (the SAH's node cost)
//! and `TR_BUILDER` (a `quiver_rt::builders::Builder` name, e.g. `sbvh` or `sweep`).
use quiver_rt::{Bvh, RayQuery};
use quiver_scenes::scene::tessellate::DEFAULT_RESOLUTION;
use quiver_scenes::Scene;
use std::time::Instant;

fn main() {
    let a: Vec<String> = std::env::args().collect();
    let name = a.get(1).map_or("teapot12", |s| s.as_str());
    let reps: usize = a.get(2).map_or(10, |s| s.parse().expect("reps"));
    let n: usize = a.get(3).map_or(200_000, |s| s.parse().expect("rays"));
    let scene = Scene::load(name)
        .expect("scene")
        .into_patches(DEFAULT_RESOLUTION);
    let tris = scene.triangles();
    let env = |k: &str| std::env::var(k).ok().map(|v| v.parse::<f32>().expect(k));
    let mut config = quiver_rt::builders::BuildConfig::default();
    if let Some(v) = env("TR_LEAF") {
        config.max_leaf_size = v as usize;
    }
    if let Some(v) = env("TR_BINS") {
        config.bins = v as usize;
    }
    if let Some(v) = env("TR_CT") {
        config.traversal_cost = v;
    }
    let mut options = quiver_rt::BuildOptions::default().config(config);
    if let Ok(name) = std::env::var("TR_BUILDER") {
        options = options.builder(name.parse().expect("TR_BUILDER"));
    }
    let bvh: Bvh = options.build(&tris);
    let eye = quiver_lab::rays::camera_rays(&scene.camera, 512);
    let light = scene.lights.first().map_or(scene.camera.from, |l| l.pos);
    let shadow = quiver_lab::rays::shadow_rays(&bvh, &eye, &[light]);
    let incoherent = quiver_lab::rays::random_rays(&scene.bounds(), n, 11);
    let sets = [
        ("eye", &eye, false),
        ("shadow", &shadow, true),
        ("incoherent", &incoherent, false),
    ];
    let mut best = [f64::MAX; 3];
    for _ in 0..reps {
        for (b, (_, rays, any)) in best.iter_mut().zip(&sets) {
            let t = Instant::now();
            let mut hits = 0usize;
            for r in rays.iter() {
                hits += if *any {
                    bvh.any_hit(r) as usize
                } else {
                    bvh.closest_hit(r).is_some() as usize
                };
            }
            std::hint::black_box(hits);
            *b = b.min(t.elapsed().as_secs_f64());
        }
    }
    for ((what, rays, _), b) in sets.iter().zip(best) {
        print!("{what} {:.3} ", rays.len() as f64 / b / 1e6);
    }
    println!("Mrays/s ({name}, {} triangles)", tris.len());
}
