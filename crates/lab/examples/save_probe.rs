//! Save probe: `cargo run --release -p quiver-lab --example save_probe -- SCENE [LAYOUT] [REPS]`
//! builds SCENE (a generator name such as `balls6`, or a mesh file; analytic shapes
//! tessellated) in LAYOUT (default `bvh8-dfs`), saves it to a file in the temporary
//! directory, loads it back (from the file, and from bytes already in memory), and prints the
//! fastest of REPS rounds (default 3) of each: build, save, load; the file's size against the
//! BVH's footprint; and whether the loaded BVH answers the eye rays as the built one. With
//! `SEED=DIR` it also writes a small saved file for the `saved` fuzz target's seed corpus.
use quiver_rt::{BuildOptions, Bvh, Layout, RayQuery};
use quiver_scenes::scene::tessellate::DEFAULT_RESOLUTION;
use quiver_scenes::Scene;
use std::time::Instant;

fn main() {
    let a: Vec<String> = std::env::args().collect();
    let name = a.get(1).map_or("balls5", |s| s.as_str());
    let layout: Layout = a
        .get(2)
        .map_or(Ok(Layout::Bvh8Dfs), |s| s.parse())
        .expect("layout");
    let reps: usize = a.get(3).map_or(3, |s| s.parse().expect("reps"));
    if let Ok(dir) = std::env::var("SEED") {
        write_seed(&dir);
    }
    let scene = Scene::load(name)
        .expect("scene")
        .into_patches(DEFAULT_RESOLUTION);
    let tris = scene.triangles();
    let options = BuildOptions::default().layout(layout);
    let fastest = |f: &mut dyn FnMut()| {
        (0..reps)
            .map(|_| {
                let start = Instant::now();
                f();
                start.elapsed().as_secs_f64() * 1e3
            })
            .fold(f64::INFINITY, f64::min)
    };
    let mut bvh = None;
    let build_ms = fastest(&mut || bvh = Some(Bvh::build(&tris, &options).unwrap()));
    let bvh = bvh.unwrap();
    let path = std::env::temp_dir().join(format!("save_probe-{}.qbvh", std::process::id()));
    let save_ms = fastest(&mut || {
        let mut f = std::io::BufWriter::new(std::fs::File::create(&path).unwrap());
        bvh.save(&mut f).unwrap();
        std::io::Write::flush(&mut f).unwrap();
    });
    let mut loaded = None;
    let load_ms = fastest(&mut || {
        let mut f = std::fs::File::open(&path).unwrap();
        loaded = Some(Bvh::load(&mut f).unwrap());
    });
    let bytes = std::fs::read(&path).unwrap();
    let from_bytes_ms = fastest(&mut || loaded = Some(Bvh::from_bytes(&bytes).unwrap()));
    let loaded = loaded.unwrap();
    std::fs::remove_file(&path).ok();
    let eye = quiver_lab::rays::camera_rays(&scene.camera, 256);
    let same = eye
        .iter()
        .all(|r| bvh.closest_hit(r) == loaded.closest_hit(r));
    let fp = bvh.footprint();
    println!(
        "{name} {layout}: {} triangles, {} threads",
        tris.len(),
        rayon::current_num_threads()
    );
    println!("build {build_ms:.1} ms, save {save_ms:.1} ms, load (file) {load_ms:.1} ms, load (bytes) {from_bytes_ms:.1} ms");
    println!(
        "build / load (file) {:.1}x, build / load (bytes) {:.1}x",
        build_ms / load_ms,
        build_ms / from_bytes_ms
    );
    println!(
        "file {} bytes, footprint kept {} bytes (file / kept {:.4}), traversal bytes {}",
        bytes.len(),
        fp.kept,
        bytes.len() as f64 / fp.kept as f64,
        fp.bytes
    );
    println!("loaded answers the {} eye rays as built: {same}", eye.len());
    assert!(same);
}

/// A small saved file (raw-mode seed: a leading 0 byte, then the file) for `fuzz/corpus/saved`.
fn write_seed(dir: &str) {
    let scene = Scene::load("tetra2").unwrap();
    let tris = scene.triangles();
    for layout in [Layout::Bvh8Dfs, Layout::Bvh2SubtreePage] {
        let bvh = Bvh::build(&tris, &BuildOptions::default().layout(layout)).unwrap();
        let mut seed = vec![0u8];
        bvh.save(&mut seed).unwrap();
        std::fs::write(format!("{dir}/raw-{layout}"), seed).unwrap();
    }
}
