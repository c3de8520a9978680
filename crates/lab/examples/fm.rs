//! Filter and mask price probe: `cargo run --release -p quiver-lab --example fm -- SCENE MODE`
//! builds SCENE (an SPD generator name) as instances of unit shapes, the world `quiver bench
//! --instanced` measures, and traces its 256² eye rays (closest hit) and their shadow rays
//! (any hit) once, in MODE: `plain` (no filter, default masks), `filter` (a filter that
//! accepts every hit), `mask` (ray mask 1, which every instance shares: it excludes nothing)
//! `packets` (the eye rays in 8×8 tiles, closest hits as packets of 64), `flat-packets` (the
//! same through the flattened patch scene), `packets50` (the packets 50 times), `plain20` and
//! `flat` (the plain rays 20 times, through the world and through the flattened patch scene,
//! for `perf record`), `counts` (nodes, boxes, leaves and primitives a ray, instanced beside
//! flattened) or `none` (builds only). `FM_BUILDER=NAME` builds the world with that builder
//! (a `quiver_rt::builders::Builder` name, e.g. `sbvh` or `sweep`) instead of the default.
//! Meant for `valgrind --tool=callgrind --toggle-collect='fm::trace*'`, whose instruction
//! counts, unlike times on a shared machine, repeat exactly: the difference between modes is
//! the features' price per ray.
use quiver_rt::{BuildOptions, Hit, Ray, RayQuery};
use quiver_lab::rays;
use quiver_scenes::accel::SceneBvh;
use quiver_scenes::scene::tessellate::DEFAULT_RESOLUTION;
use quiver_scenes::Scene;

#[inline(never)]
fn trace_plain(q: &SceneBvh, eye: &[Ray], shadow: &[Ray]) -> usize {
    let closest = eye.iter().filter(|r| q.closest_hit(r).is_some()).count();
    closest + shadow.iter().filter(|r| q.any_hit(r)).count()
}

/// The 256² eye rays in 8×8 tiles, closest hits as packets of 64.
#[inline(never)]
fn trace_packets<Q: RayQuery>(q: &Q, tiles: &[Ray]) -> usize {
    let mut out = [None; 64];
    let mut hits = 0;
    for p in tiles.chunks(64) {
        q.closest_hit_packet(p, &mut out[..p.len()]);
        hits += out[..p.len()].iter().filter(|h| h.is_some()).count();
    }
    hits
}

#[inline(never)]
fn trace_filtered(q: &SceneBvh, eye: &[Ray], shadow: &[Ray]) -> usize {
    let accept = |_: &Hit| true;
    let closest = eye
        .iter()
        .filter(|r| q.closest_hit_filtered(r, accept).is_some())
        .count();
    closest
        + shadow
            .iter()
            .filter(|r| q.any_hit_filtered(r, accept))
            .count()
}

fn main() {
    let a: Vec<String> = std::env::args().collect();
    let name = a.get(1).map_or("balls4", |s| s.as_str());
    let mode = a.get(2).map_or("plain", |s| s.as_str());
    let scene = Scene::load(name).expect("scene");
    let mut opts = BuildOptions::default();
    if let Ok(name) = std::env::var("FM_BUILDER") {
        opts = opts.builder(name.parse().expect("FM_BUILDER"));
    }
    let q =
        SceneBvh::build_instanced(&scene, DEFAULT_RESOLUTION, &opts).expect("an instanced world");
    let eye = rays::camera_rays(&scene.camera, 256);
    let light = scene.lights.first().map_or(scene.camera.from, |l| l.pos);
    let shadow = rays::shadow_rays(&q, &eye, &[light]);
    // The same scene flattened to world-space triangles, for the modes that compare.
    let flattened = || {
        let patched = scene.clone().into_patches(DEFAULT_RESOLUTION);
        SceneBvh::build_triangles(&patched, &BuildOptions::default())
    };
    let mask = |v: &[Ray]| v.iter().map(|r| r.with_mask(0b1)).collect::<Vec<_>>();
    let hits = match mode {
        "plain" => trace_plain(&q, &eye, &shadow),
        "filter" => trace_filtered(&q, &eye, &shadow),
        "mask" => trace_plain(&q, &mask(&eye), &mask(&shadow)),
        "packets" => trace_packets(&q, &rays::camera_tiles(&scene.camera, 256, 8)),
        "packets50" => {
            let tiles = rays::camera_tiles(&scene.camera, 256, 8);
            (0..50).map(|_| trace_packets(&q, &tiles)).sum()
        }
        "flat-packets" => trace_packets(&flattened(), &rays::camera_tiles(&scene.camera, 256, 8)),
        "flat" => {
            let flat = flattened();
            (0..20).map(|_| trace_plain(&flat, &eye, &shadow)).sum()
        }
        "plain20" => (0..20).map(|_| trace_plain(&q, &eye, &shadow)).sum(),
        "counts" => {
            let flat = flattened();
            for (label, q) in [("instanced", &q), ("flattened", &flat)] {
                let (mut ce, mut cs) = (
                    quiver_rt::traverse::Counters::default(),
                    quiver_rt::traverse::Counters::default(),
                );
                eye.iter().for_each(|r| {
                    let _ = q.closest_hit_counted(r, &mut ce);
                });
                shadow.iter().for_each(|r| {
                    let _ = q.any_hit_counted(r, &mut cs);
                });
                println!("{label} eye {ce:?}\n{label} shadow {cs:?}");
            }
            0
        }
        "none" => 0,
        m => panic!(
            "unknown mode {m}: plain, filter, mask, packets, packets50, flat-packets, flat, \
             plain20, counts or none"
        ),
    };
    println!(
        "{name} {mode}: {} eye, {} shadow rays, {hits} hits",
        eye.len(),
        shadow.len()
    );
}
