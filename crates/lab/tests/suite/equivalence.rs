//! Every layout's traversal against the brute-force reference: the same primitive and the
//! same t for every ray, any-hit agreeing with closest-hit, and the counting kernels giving the
//! plain kernels' answers.

use crate::common::{hit_fraction, reference_hits};
use glam::Vec3A;
use quiver::build::{build, prim_bounds, BuildConfig, Builder};
use quiver::traverse::Counters;
use quiver::{Bvh, Hit, Isa, Layout, Ray, RayQuery, Triangle};
use quiver_lab::rays;
use quiver_scenes::Scene;
use rayon::prelude::*;

/// Checks every ray against `want` (the reference's answers), with the plain and the counting
/// kernels.
fn check(bvh: &Bvh, rays: &[Ray], want: &[Option<Hit>], what: &str) {
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
            let mut c = Counters::default();
            assert_eq!(
                bvh.closest_hit_counted(ray, &mut c),
                *want,
                "{what}: counted, ray {i}"
            );
            assert_eq!(
                bvh.any_hit_counted(ray, &mut c),
                want.is_some(),
                "{what}: counted any, ray {i}"
            );
            // A hit needs at least one node, leaf and primitive test behind it.
            if want.is_some() {
                assert!(
                    c.nodes >= 2 && c.leaves >= 2 && c.prim_tests >= 2,
                    "{what}: {c:?}"
                );
            }
        });
}

/// A named ray set with the reference's answers.
type RaySet<'a> = (&'a str, &'a [Ray], &'a [Option<Hit>]);

/// Builds once per builder and checks every layout.
fn check_layouts(tris: &[Triangle], sets: &[RaySet], what: &str) {
    let bounds = prim_bounds(tris);
    for builder in Builder::ALL {
        let tree = build(&bounds, &BuildConfig::default(), builder);
        for layout in Layout::ALL {
            let laid_out = Bvh::from_tree(&tree, tris, layout);
            // Every instruction set the layout has kernels for (and this CPU runs).
            for isa in Isa::ALL {
                let bvh = laid_out.clone().with_isa(isa);
                if bvh.isa() != isa {
                    continue;
                }
                for (name, rays, want) in sets {
                    check(
                        &bvh,
                        rays,
                        want,
                        &format!("{what} {builder} {layout} {isa} {name}"),
                    );
                }
            }
        }
    }
}

/// Both builders and every layout against the reference on random and camera rays; returns
/// the fraction of random and camera rays that hit.
fn check_scene(scene: &Scene, n_random: usize, cam_res: usize) -> (f64, f64) {
    let random = rays::random_rays(&scene.bounds(), n_random, 42);
    let cam = rays::camera_rays(&scene.camera, cam_res);
    let want_random = reference_hits(&scene.triangles(), &random);
    let want_cam = reference_hits(&scene.triangles(), &cam);
    check_layouts(
        &scene.triangles(),
        &[
            ("random", &random, &want_random),
            ("camera", &cam, &want_cam),
        ],
        &scene.name,
    );
    (hit_fraction(&want_random), hit_fraction(&want_cam))
}

#[test]
fn mesh_tetra7_16k_triangles() {
    let scene = Scene::load("tetra7").unwrap();
    assert_eq!(scene.triangles().len(), 16384);
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
    let want = reference_hits(&scene.triangles(), &segs);
    check_layouts(
        &scene.triangles(),
        &[("segments", &segs, &want)],
        "soup5000",
    );
}

/// Axis-parallel rays with +0.0 and -0.0 in the other components, through a grid of unit
/// triangles in the z = 0 plane and along the planes of their edges and boxes.
#[test]
fn axis_parallel_rays_with_signed_zeros() {
    let mut tris = Vec::new();
    for i in 0..20 {
        for j in 0..20 {
            let o = Vec3A::new(i as f32, j as f32, 0.0);
            tris.push(Triangle::new(o, o + Vec3A::X, o + Vec3A::Y));
            tris.push(Triangle::new(
                o + Vec3A::X,
                o + Vec3A::X + Vec3A::Y,
                o + Vec3A::Y,
            ));
        }
    }
    let mut rays = Vec::new();
    for k in 0..=80 {
        // Quarter steps: the rays run through triangle interiors, along shared edges and
        // exactly on box faces.
        let c = k as f32 * 0.25;
        for z in [0.0f32, -0.0] {
            for (ox, oy) in [(c, 0.3), (0.3, c), (c, c), (c, 20.0 - c)] {
                rays.push(Ray::new(Vec3A::new(ox, oy, 5.0), Vec3A::new(z, z, -1.0)));
                rays.push(Ray::new(Vec3A::new(ox, oy, -5.0), Vec3A::new(z, -z, 1.0)));
            }
            // In the plane of the triangles, along x and y.
            rays.push(Ray::new(Vec3A::new(-1.0, c, 0.0), Vec3A::new(1.0, z, z)));
            rays.push(Ray::new(Vec3A::new(c, 21.0, 0.0), Vec3A::new(z, -1.0, -z)));
        }
    }
    let want = reference_hits(&tris, &rays);
    assert!(want.iter().filter(|h| h.is_some()).count() > rays.len() / 2);
    check_layouts(&tris, &[("axis-parallel", &rays, &want)], "grid");
}

/// A real scanned mesh (tests/data/bunny.obj, see tests/data/README.md).
#[test]
fn stanford_bunny() {
    let scene = Scene::load(concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/bunny.obj")).unwrap();
    assert_eq!(scene.triangles().len(), 3674);
    let (random, camera) = check_scene(&scene, 20_000, 128);
    assert!(
        random > 0.05 && camera > 0.1,
        "hit fractions {random} {camera}"
    );
}

/// The watertight intersector through every layout and instruction set (bvh8 tests it four
/// triangles at a time) against the scalar watertight reference, on rays aimed at vertices and
/// edge midpoints of a closed mesh, where the f64 fallback decides.
#[test]
fn watertight_leaves_match_the_scalar_watertight_test() {
    use quiver::intersect::Watertight;
    use quiver::{reference, BuildOptions};
    let tris = Scene::load("icosphere3").unwrap().triangles();
    let wt: Vec<Watertight> = tris.iter().map(|&t| Watertight(t)).collect();
    let mut rays = rays::random_rays(&Scene::load("icosphere3").unwrap().bounds(), 5_000, 4);
    for t in &tris {
        for p in [t.v[0], (t.v[0] + t.v[1]) * 0.5] {
            rays.push(Ray::new(Vec3A::new(0.01, 0.02, 0.03), p));
            rays.push(Ray::new(p * 3.0, -p));
        }
    }
    let want = reference_hits(&wt, &rays);
    assert!(want.iter().filter(|h| h.is_some()).count() > rays.len() / 2);
    for layout in Layout::ALL {
        let laid_out = BuildOptions::default().layout(layout).build(&wt);
        for isa in Isa::ALL {
            let bvh = laid_out.clone().with_isa(isa);
            if bvh.isa() != isa {
                continue;
            }
            rays.par_iter()
                .zip(&want)
                .enumerate()
                .for_each(|(i, (r, w))| {
                    assert_eq!(bvh.closest_hit(r), *w, "{layout} {isa} ray {i} {r:?}");
                    assert_eq!(
                        bvh.any_hit(r),
                        reference::any_hit(&wt, r),
                        "{layout} {isa} any ray {i}"
                    );
                });
        }
    }
}
