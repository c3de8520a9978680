//! Packet traversal against the single-ray kernel and the brute-force reference: every ray of
//! every packet gets exactly the single-ray answer, for coherent and incoherent packets, mixed
//! direction signs, short and boundary t_max, inactive lanes, partial packets and axis-parallel
//! rays, on every 4- and 8-wide layout, on every instruction set, and on fast triangles,
//! watertight triangles and mixed primitives alike.

use crate::common::{build, WIDE};
use glam::Vec3A;
use quiver_lab::rays;
use quiver_rt::intersect::Watertight;
use quiver_rt::traverse::{
    reference, BoxTest, ConservativeBoxes, FastBoxes, NoFilter, NoStats, PacketMode, PacketQuery,
};
use quiver_rt::{BuildOptions, Bvh, Hit, Isa, Layout, Primitive, Ray, RayQuery};
use quiver_scenes::rng::Rng;
use quiver_scenes::Scene;
use rayon::prelude::*;

/// What a hit slot holds before a query: a record no query answers, so a slot the query
/// leaves unwritten shows.
const STALE: Hit = Hit {
    t: -1.0,
    prim: u32::MAX,
    u: 0.0,
    v: 0.0,
};

/// Packet answers of `rays` (with an optional active mask) against the single-ray kernel with
/// the same box test, for both packet modes that use packets.
fn check_against_single<P: Primitive, B: BoxTest>(
    bvh: &Bvh<P>,
    rays: &[Ray],
    active: Option<&[bool]>,
    what: &str,
) {
    for mode in [PacketMode::Always, PacketMode::Auto] {
        let mut hits = vec![Some(STALE); rays.len()];
        let mut occluded = vec![true; rays.len()];
        bvh.closest_hit_packet_with::<B, _, _>(
            PacketQuery { rays, active, mode },
            &mut hits,
            &mut NoStats,
            &mut NoFilter,
        );
        bvh.any_hit_packet_with::<B, _, _>(
            PacketQuery { rays, active, mode },
            &mut occluded,
            &mut NoStats,
            &mut NoFilter,
        );
        for (i, ray) in rays.iter().enumerate() {
            let on = active.is_none_or(|a| a[i]);
            let want = on
                .then(|| bvh.closest_hit_with::<B, _, _>(ray, &mut NoStats, &mut NoFilter))
                .flatten();
            let want_any = on && bvh.any_hit_with::<B, _, _>(ray, &mut NoStats, &mut NoFilter);
            assert_eq!(hits[i], want, "{what} {mode:?}: closest, ray {i} {ray:?}");
            assert_eq!(
                occluded[i], want_any,
                "{what} {mode:?}: any, ray {i} {ray:?}"
            );
        }
    }
}

/// The conservative packet kernel against the brute-force reference (and, through
/// [`check_against_single`], against the single-ray kernel with both box tests).
fn check<P: Primitive>(
    bvh: &Bvh<P>,
    prims: &[P],
    rays: &[Ray],
    active: Option<&[bool]>,
    what: &str,
) {
    check_against_single::<P, ConservativeBoxes>(bvh, rays, active, what);
    check_against_single::<P, FastBoxes>(bvh, rays, active, &format!("{what} fast"));
    let mut hits = vec![None; rays.len()];
    bvh.closest_hit_packet_with::<ConservativeBoxes, _, _>(
        PacketQuery {
            rays,
            active,
            mode: PacketMode::Always,
        },
        &mut hits,
        &mut NoStats,
        &mut NoFilter,
    );
    let want: Vec<Option<Hit>> = rays
        .par_iter()
        .enumerate()
        .map(|(i, r)| {
            active
                .is_none_or(|a| a[i])
                .then(|| reference::closest_hit(prims, r))
                .flatten()
        })
        .collect();
    for (i, (h, w)) in hits.iter().zip(&want).enumerate() {
        assert_eq!(h, w, "{what}: reference, ray {i} {:?}", rays[i]);
    }
}

/// Shadow rays from the eye rays' hit points toward every light.
fn shadow_rays<P: Primitive>(bvh: &Bvh<P>, scene: &Scene, eye: &[Ray]) -> Vec<Ray> {
    let lights: Vec<Vec3A> = scene.lights.iter().map(|l| l.pos).collect();
    rays::shadow_rays(bvh, eye, &lights)
}

#[test]
fn eye_and_shadow_packets_match_single_rays_and_reference() {
    for spec in ["tetra4", "gears1", "teapot6"] {
        let scene = Scene::load(spec).unwrap();
        let tris = scene.triangles();
        let eye = rays::camera_tiles(&scene.camera, 48, 8);
        for layout in WIDE {
            let bvh = build(&tris, layout);
            let shadow = shadow_rays(&bvh, &scene, &eye);
            check(&bvh, &tris, &eye, None, &format!("{spec} {layout} eye"));
            check(
                &bvh,
                &tris,
                &shadow,
                None,
                &format!("{spec} {layout} shadow"),
            );
        }
    }
}

#[test]
fn packets_match_on_every_instruction_set_and_leaf_format() {
    // The packet kernels run on the portable and the AVX2 lanes; both must give each ray its
    // single-ray answer, for fast and for watertight triangle groups, on every wide layout.
    for spec in ["tetra4", "teapot6"] {
        let scene = Scene::load(spec).unwrap();
        let tris = scene.triangles();
        let tight: Vec<Watertight> = tris.iter().map(|&t| Watertight(t)).collect();
        let eye = rays::camera_tiles(&scene.camera, 48, 8);
        for layout in WIDE {
            for isa in Isa::ALL {
                let options = BuildOptions::default().layout(layout).isa(isa);
                let bvh = Bvh::build(&tris, &options).unwrap();
                let shadow = shadow_rays(&bvh, &scene, &eye);
                let what = format!("{spec} {layout} {isa:?}");
                check(&bvh, &tris, &eye, None, &format!("{what} eye"));
                check(&bvh, &tris, &shadow, None, &format!("{what} shadow"));
                let bvh = Bvh::build(&tight, &options).unwrap();
                check(&bvh, &tight, &eye, None, &format!("{what} watertight eye"));
                check(
                    &bvh,
                    &tight,
                    &shadow,
                    None,
                    &format!("{what} watertight shadow"),
                );
            }
        }
    }
}

#[test]
fn mixed_primitives_match_with_eight_lane_spheres_and_cones() {
    // Curve mode: spheres and cones (tested eight rays at a time) and polygons (ray by ray)
    // next to triangles.
    for spec in ["balls2", "gears1", "tree3"] {
        let scene = Scene::load(spec).unwrap();
        assert!(
            !scene.is_all_triangles(),
            "{spec} should have analytic shapes"
        );
        let (prims, _) = scene.prims();
        let eye = rays::camera_tiles(&scene.camera, 32, 8);
        for layout in WIDE {
            let bvh = build(&prims, layout);
            let shadow = shadow_rays(&bvh, &scene, &eye);
            check(&bvh, &prims, &eye, None, &format!("{spec} {layout} eye"));
            check(
                &bvh,
                &prims,
                &shadow,
                None,
                &format!("{spec} {layout} shadow"),
            );
        }
    }
}

#[test]
fn incoherent_packets_match() {
    let scene = Scene::load("tetra5").unwrap();
    let tris = scene.triangles();
    let random = rays::random_rays(&scene.bounds(), 2048, 7);
    for layout in WIDE {
        let bvh = build(&tris, layout);
        check(&bvh, &tris, &random, None, &format!("{layout} random"));
    }
}

#[test]
fn mixed_signs_axis_parallel_rays_and_signed_zeros_match() {
    let scene = Scene::load("gears1").unwrap();
    let tris = scene.triangles();
    let c = scene.bounds().center();
    let mut rays = Vec::new();
    // From the centre in every octant: each packet holds all eight sign patterns.
    let mut rng = Rng::new(3);
    for _ in 0..256 {
        rays.push(Ray::new(c, rng.unit_vector()));
    }
    // Axis-parallel rays with +0 and -0 in the other components, over a grid of origins.
    let ext = scene.bounds().extent();
    for i in 0..16 {
        for j in 0..8 {
            let (s, t) = (i as f32 / 15.0 - 0.5, j as f32 / 7.0 - 0.5);
            let z = if (i + j) % 2 == 0 { 0.0 } else { -0.0 };
            let o = c + Vec3A::new(s * ext.x, t * ext.y, 0.0);
            rays.push(Ray::new(o + Vec3A::Z * ext.z, Vec3A::new(z, -z, -1.0)));
            rays.push(Ray::new(o - Vec3A::Z * ext.z, Vec3A::new(-z, z, 1.0)));
            let o = c + Vec3A::new(0.0, s * ext.y, t * ext.z);
            rays.push(Ray::new(o - Vec3A::X * ext.x, Vec3A::new(1.0, z, z)));
        }
    }
    for layout in WIDE {
        let bvh = build(&tris, layout);
        check(&bvh, &tris, &rays, None, &format!("{layout} signs"));
    }
}

#[test]
fn short_and_boundary_t_max_match() {
    let scene = Scene::load("teapot6").unwrap();
    let tris = scene.triangles();
    let eye = rays::camera_tiles(&scene.camera, 32, 8);
    let want: Vec<Option<Hit>> = eye
        .iter()
        .map(|r| reference::closest_hit(&tris, r))
        .collect();
    // Per ray: half its hit distance (hits nothing nearer), exactly its hit distance (the
    // closed interval keeps the hit), just below it, or a short fixed segment.
    let rays: Vec<Ray> = eye
        .iter()
        .zip(&want)
        .enumerate()
        .map(|(i, (r, w))| {
            let t = w.map_or(1.0, |h| h.t);
            let t_max = match i % 4 {
                0 => t * 0.5,
                1 => t,
                2 => f32::from_bits(t.to_bits() - 1),
                _ => 0.25,
            };
            Ray { t_max, ..*r }
        })
        .collect();
    for layout in WIDE {
        let bvh = build(&tris, layout);
        check(&bvh, &tris, &rays, None, &format!("{layout} t_max"));
    }
    // The boundary case keeps its hit: the packet honours the closed interval.
    let bvh = build(&tris, Layout::Bvh4Dfs);
    let mut hits = vec![None; rays.len()];
    bvh.closest_hit_packet(&rays, &mut hits);
    let kept = (1..rays.len())
        .step_by(4)
        .filter(|&i| want[i].is_some())
        .all(|i| hits[i] == want[i]);
    assert!(kept);
}

#[test]
fn inactive_lanes_and_partial_packets_match() {
    let scene = Scene::load("tetra4").unwrap();
    let tris = scene.triangles();
    let eye = rays::camera_tiles(&scene.camera, 24, 8);
    let mut rng = Rng::new(11);
    let active: Vec<bool> = eye.iter().map(|_| rng.range(0.0, 1.0) < 0.6).collect();
    for layout in WIDE {
        let bvh = build(&tris, layout);
        check(
            &bvh,
            &tris,
            &eye,
            Some(&active),
            &format!("{layout} inactive"),
        );
        // Every partial packet length, and lengths spanning several packets.
        for n in (1..64).chain([65, 127, 129]) {
            check_against_single::<_, ConservativeBoxes>(
                &bvh,
                &eye[..n],
                Some(&active[..n]),
                &format!("{layout} partial {n}"),
            );
        }
    }
    // No active ray at all: nothing is traced and every answer is empty.
    let bvh = build(&tris, Layout::Bvh4Dfs);
    let mut hits = vec![Some(STALE); 64];
    let none = vec![false; 64];
    bvh.closest_hit_packet_with::<ConservativeBoxes, _, _>(
        PacketQuery::new(&eye[..64])
            .active(&none)
            .mode(PacketMode::Always),
        &mut hits,
        &mut NoStats,
        &mut NoFilter,
    );
    assert!(hits.iter().all(Option::is_none));
}

#[test]
fn the_binary_layout_answers_packet_queries_ray_by_ray() {
    let scene = Scene::load("tetra3").unwrap();
    let tris = scene.triangles();
    let eye = rays::camera_tiles(&scene.camera, 16, 8);
    let bvh = build(&tris, Layout::Bvh2Dfs);
    check(&bvh, &tris, &eye, None, "bvh2");
}

#[test]
fn nan_and_degenerate_rays_in_a_packet_match() {
    let scene = Scene::load("tetra3").unwrap();
    let tris = scene.triangles();
    let mut rays = rays::camera_tiles(&scene.camera, 8, 8);
    rays[3].t_max = f32::NAN;
    rays[5].t_min = f32::NAN;
    rays[9].dir = Vec3A::ZERO;
    rays[12].dir = Vec3A::new(1e-40, -1e-40, -1.0);
    rays[20].origin = Vec3A::splat(f32::INFINITY);
    rays[33].t_min = f32::NEG_INFINITY;
    rays[40].dir = Vec3A::new(f32::INFINITY, 0.0, -1.0);
    for layout in WIDE {
        let bvh = build(&tris, layout);
        check_against_single::<_, ConservativeBoxes>(&bvh, &rays, None, &format!("{layout} nan"));
    }
}
