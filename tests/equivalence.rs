//! BVH2 traversal against the brute-force reference: the same primitive and the same t for
//! every ray, and any-hit agreeing with closest-hit.

use quiver::build::{BuildConfig, Builder};
use quiver::scene::Scene;
use quiver::{rays, reference, Bvh2, Hit, Ray, Triangle};
use rayon::prelude::*;

/// Checks every ray against `want` (the reference's answers).
fn check(bvh: &Bvh2, rays: &[Ray], want: &[Option<Hit>], what: &str) {
    rays.par_iter()
        .zip(want)
        .enumerate()
        .for_each(|(i, (ray, want))| {
            assert_eq!(bvh.closest_hit(ray), *want, "{what}: ray {i} {ray:?}");
            assert_eq!(
                bvh.any_hit(ray),
                want.is_some(),
                "{what}: any-hit, ray {i} {ray:?}"
            );
        });
}

fn reference_hits(tris: &[Triangle], rays: &[Ray]) -> Vec<Option<Hit>> {
    rays.par_iter()
        .map(|r| reference::closest_hit(tris, r))
        .collect()
}

/// Both builders against the reference on random and camera rays; returns the fraction of
/// random and camera rays that hit.
fn check_scene(scene: &Scene, n_random: usize, cam_res: usize) -> (f64, f64) {
    let config = BuildConfig::default();
    let random = rays::random_rays(&scene.bounds(), n_random, 42);
    let cam = rays::camera_rays(&scene.camera, cam_res);
    let want_random = reference_hits(&scene.triangles, &random);
    let want_cam = reference_hits(&scene.triangles, &cam);
    for builder in [Builder::Binned, Builder::Sweep] {
        let (bvh, _) = Bvh2::build(&scene.triangles, &config, builder);
        check(
            &bvh,
            &random,
            &want_random,
            &format!("{} {builder} random", scene.name),
        );
        check(
            &bvh,
            &cam,
            &want_cam,
            &format!("{} {builder} camera", scene.name),
        );
    }
    let frac = |w: &[Option<Hit>]| w.iter().filter(|h| h.is_some()).count() as f64 / w.len() as f64;
    (frac(&want_random), frac(&want_cam))
}

#[test]
fn mesh_tetra7_16k_triangles() {
    let scene = Scene::load("tetra7").unwrap();
    assert_eq!(scene.triangles.len(), 16384);
    let (random, camera) = check_scene(&scene, 100_000, 320);
    // The workload must exercise hits, not just misses.
    assert!(
        random > 0.05 && camera > 0.1,
        "hit fractions {random} {camera}"
    );
}

#[test]
fn random_soup_20k() {
    let (random, camera) = check_scene(&Scene::load("soup20000").unwrap(), 100_000, 320);
    assert!(
        random > 0.05 && camera > 0.1,
        "hit fractions {random} {camera}"
    );
}

#[test]
fn small_soups_many_seeds() {
    for n in [1, 2, 3, 7, 50, 300] {
        check_scene(&Scene::load(&format!("soup{n}")).unwrap(), 2_000, 16);
    }
}

/// Short rays (segments) exercise t_min/t_max pruning.
#[test]
fn segments() {
    let scene = Scene::load("soup5000").unwrap();
    let (bvh, _) = Bvh2::build(&scene.triangles, &BuildConfig::default(), Builder::Binned);
    let segs: Vec<Ray> = rays::random_rays(&scene.bounds(), 50_000, 9)
        .into_iter()
        .enumerate()
        .map(|(i, r)| {
            Ray::segment(
                r.origin,
                r.dir,
                (i % 7) as f32 * 0.02,
                0.05 + (i % 13) as f32 * 0.03,
            )
        })
        .collect();
    check(
        &bvh,
        &segs,
        &reference_hits(&scene.triangles, &segs),
        "segments",
    );
}
