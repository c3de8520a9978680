//! World save probe: `cargo run --release -p quiver-lab --example world_save_probe -- SCENE
//! [REPS]` builds SCENE's instanced world (`quiver_scenes::instanced`: every sphere and cone
//! an instance of a tessellated unit shape), saves it to a file in the temporary directory,
//! loads it back (from the file, and from bytes already in memory), and prints the fastest of
//! REPS rounds (default 3) of each: build, save, load; the file's size against the world's
//! footprint; and whether the loaded world answers the eye rays as the built one.
use quiver_rt::{BuildOptions, RayQuery, World};
use quiver_scenes::instanced::Instanced;
use quiver_scenes::scene::tessellate::DEFAULT_RESOLUTION;
use quiver_scenes::Scene;
use std::time::Instant;

fn main() {
    let a: Vec<String> = std::env::args().collect();
    let name = a.get(1).map_or("balls6", |s| s.as_str());
    let reps: usize = a.get(2).map_or(3, |s| s.parse().expect("reps"));
    let scene = Scene::load(name).expect("scene");
    let options = BuildOptions::default();
    let fastest = |f: &mut dyn FnMut()| {
        (0..reps)
            .map(|_| {
                let start = Instant::now();
                f();
                start.elapsed().as_secs_f64() * 1e3
            })
            .fold(f64::INFINITY, f64::min)
    };
    let mut built = None;
    let build_ms = fastest(&mut || {
        built = Some(Instanced::build(&scene, DEFAULT_RESOLUTION, &options).unwrap())
    });
    let built = built.unwrap();
    let world = built.world();
    let path = std::env::temp_dir().join(format!("world_save_probe-{}.qwld", std::process::id()));
    let save_ms = fastest(&mut || {
        let mut f = std::io::BufWriter::new(std::fs::File::create(&path).unwrap());
        world.save(&mut f).unwrap();
        std::io::Write::flush(&mut f).unwrap();
    });
    let mut loaded = None;
    let load_ms = fastest(&mut || {
        let mut f = std::fs::File::open(&path).unwrap();
        loaded = Some(World::load(&mut f).unwrap());
    });
    let bytes = std::fs::read(&path).unwrap();
    let from_bytes_ms = fastest(&mut || loaded = Some(World::from_bytes(&bytes).unwrap()));
    let loaded = loaded.unwrap();
    std::fs::remove_file(&path).ok();
    let eye = quiver_lab::rays::camera_rays(&scene.camera, 256);
    let same = eye
        .iter()
        .all(|r| world.closest_hit(r) == loaded.closest_hit(r));
    let fp = world.footprint();
    println!(
        "{name} instanced: {} instances, {} geometries, {} primitives placed, {} threads",
        world.instances().len(),
        world.geometries().len(),
        built.primitives(),
        rayon::current_num_threads()
    );
    println!("build {build_ms:.1} ms, save {save_ms:.1} ms, load (file) {load_ms:.1} ms, load (bytes) {from_bytes_ms:.1} ms");
    println!(
        "build / load (file) {:.1}x, build / load (bytes) {:.1}x",
        build_ms / load_ms,
        build_ms / from_bytes_ms
    );
    println!(
        "file {} bytes, footprint kept {} bytes (file / kept {:.4})",
        bytes.len(),
        fp.kept,
        bytes.len() as f64 / fp.kept as f64,
    );
    println!("loaded answers the {} eye rays as built: {same}", eye.len());
    assert!(same);
}
