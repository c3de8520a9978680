//! The high-quality preset (spatial splits) against the default build:
//! `cargo run --release -p quiver-lab --example sbvh_bench -- [--reps N] [--res R] [--rays N]
//! SCENE...` with generator names, mesh files or `slivers` (long, thin, crossing triangles).
//! Per scene, in one run: the median build time of each preset (builds interleaved), the SAH
//! cost of each tree and laid-out BVH, the references, and the median time of eye rays (an
//! R × R camera image) and random rays through each BVH (rounds interleaved), on the current
//! thread count, with the ratios default / high-quality.

use glam::Vec3A;
use quiver_rt::builders::BuildConfig;
use quiver_rt::{BuildOptions, Bvh, Ray, Triangle};
use quiver_lab::measure::{median_times_interleaved, trace, Query};
use quiver_lab::rays;
use quiver_scenes::Scene;
use std::time::Instant;

/// Long thin triangles between random points of a 10-unit cube, a few hundredths wide.
fn slivers(n: usize) -> Vec<Triangle> {
    let mut s = 0x9e37_79b9_7f4a_7c15u64;
    let mut f = move || {
        s ^= s >> 12;
        s ^= s << 25;
        s ^= s >> 27;
        ((s.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 40) as f32) / (1u64 << 24) as f32
    };
    (0..n)
        .map(|_| {
            let a = Vec3A::new(f(), f(), f()) * 10.0;
            let b = Vec3A::new(f(), f(), f()) * 10.0;
            let w = (Vec3A::new(f(), f(), f()) - 0.5) * 0.08;
            Triangle::new(a, b, b + w)
        })
        .collect()
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() {
    let mut args = std::env::args().skip(1);
    let (mut reps, mut res, mut n_rays) = (5usize, 512usize, 200_000usize);
    let mut scenes = Vec::new();
    while let Some(a) = args.next() {
        let mut num = || args.next().and_then(|v| v.parse().ok()).expect("a number");
        match a.as_str() {
            "--reps" => reps = num(),
            "--res" => res = num(),
            "--rays" => n_rays = num(),
            _ => scenes.push(a),
        }
    }
    println!(
        "threads {}, reps {reps}, eye {res}x{res}, random {n_rays}",
        rayon::current_num_threads()
    );
    println!(
        "{:<28} {:>8} | {:>9} {:>9} {:>5} | {:>8} {:>8} {:>8} {:>8} | {:>6} | {:>8} {:>8} {:>5} | {:>8} {:>8} {:>5}",
        "scene", "tris", "build def", "build hq", "x", "SAH def", "SAH hq", "BVH def", "BVH hq",
        "refs", "eye def", "eye hq", "x", "rnd def", "rnd hq", "x"
    );
    for name in scenes {
        let (tris, camera_rays) = if let Some(n) = name.strip_prefix("slivers") {
            let tris = slivers(n.parse().unwrap_or(200_000));
            let b = tris
                .iter()
                .fold(quiver_rt::Aabb::EMPTY, |a, t| a.union(&t.bounds()));
            let cam = quiver_scenes::Camera::framing(&b).ok();
            (tris, cam.map(|c| rays::camera_rays(&c, res)))
        } else {
            let scene = Scene::load(&name).expect("scene");
            let tris = scene.triangles();
            (tris, Some(rays::camera_rays(&scene.camera, res)))
        };
        let presets = [BuildOptions::default(), BuildOptions::high_quality()];
        let mut build_ms = [vec![], vec![]];
        let mut built: Vec<Option<(Bvh, quiver_rt::builders::BuildTree)>> = vec![None, None];
        for _ in 0..reps.max(1) {
            for (k, p) in presets.iter().enumerate() {
                built[k] = None;
                let t = Instant::now();
                let out = p.build_with_tree(&tris);
                build_ms[k].push(t.elapsed().as_secs_f64() * 1e3);
                built[k] = Some(out);
            }
        }
        let built: Vec<(Bvh, quiver_rt::builders::BuildTree)> = built.into_iter().flatten().collect();
        let config = BuildConfig::default();
        let bounds = built[0].0.bounds();
        let random: Vec<Ray> = rays::random_rays(&bounds, n_rays, 7);
        let time = |rays: &[Ray]| {
            let mut hits = [0usize; 2];
            let t = median_times_interleaved(reps, 2, |i| {
                hits[i] = trace(&built[i].0, rays, Query::Closest);
            });
            assert_eq!(hits[0], hits[1], "{name}: both BVHs hit the same rays");
            [t[0].as_secs_f64() * 1e3, t[1].as_secs_f64() * 1e3]
        };
        let eye = camera_rays.as_deref().map(time).unwrap_or([f64::NAN; 2]);
        let rnd = time(&random);
        let b = [median(build_ms[0].clone()), median(build_ms[1].clone())];
        println!(
            "{:<28} {:>8} | {:>9.1} {:>9.1} {:>5.2} | {:>8.2} {:>8.2} {:>8.2} {:>8.2} | {:>6.3} | {:>8.2} {:>8.2} {:>5.3} | {:>8.2} {:>8.2} {:>5.3}",
            name,
            tris.len(),
            b[0],
            b[1],
            b[1] / b[0],
            built[0].1.sah_cost(&config),
            built[1].1.sah_cost(&config),
            built[0].0.sah_cost(),
            built[1].0.sah_cost(),
            built[1].1.prim_indices.len() as f64 / tris.len() as f64,
            eye[0],
            eye[1],
            eye[0] / eye[1],
            rnd[0],
            rnd[1],
            rnd[0] / rnd[1],
        );
    }
}
