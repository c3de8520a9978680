//! quiver against obvhs 0.4 on the same triangles and rays. The two use different triangle
//! arithmetic, so they may differ where a ray meets two triangles at (nearly) the same distance
//! or passes within rounding of a triangle's edge. Every disagreement is checked in f64 and
//! must be such a tie or edge case; their number is bounded.

use glam::{DVec3, Vec3A};
use obvhs::{bvh2::builder::build_bvh2_from_tris, ray::RayHit, BvhBuildParams};
use quiver::{Bvh, Hit, Ray, RayQuery, Triangle};
use quiver_lab::rays;
use quiver_scenes::Scene;
use rayon::prelude::*;
use std::time::Duration;

/// f64 barycentrics `(t, u, v)` of the ray's crossing with the triangle's plane; `None` when
/// parallel. Exact to about 1e-15 relative for f32 input: the judge of what f32 kernels say.
fn crossing_f64(tri: &Triangle, ray: &Ray) -> Option<(f64, f64, f64)> {
    let d = |v: Vec3A| DVec3::new(v.x as f64, v.y as f64, v.z as f64);
    let (v0, v1, v2) = (d(tri.v[0]), d(tri.v[1]), d(tri.v[2]));
    let (o, dir) = (d(ray.origin), d(ray.dir));
    let (e1, e2) = (v1 - v0, v2 - v0);
    let p = dir.cross(e2);
    let det = e1.dot(p);
    if det == 0.0 {
        return None;
    }
    let s = o - v0;
    let q = s.cross(e1);
    Some((e2.dot(q) / det, s.dot(p) / det, dir.dot(q) / det))
}

/// Distance from `p` to the segment `a..b`.
fn segment_distance(p: DVec3, a: DVec3, b: DVec3) -> f64 {
    let ab = b - a;
    let s = ((p - a).dot(ab) / ab.length_squared().max(f64::MIN_POSITIVE)).clamp(0.0, 1.0);
    (a + ab * s - p).length()
}

/// The f64 crossing distance `t` and the signed distance of the crossing from the triangle's
/// boundary (positive outside, negative inside), in world units relative to the magnitude of
/// the coordinates involved. f32 kernels round every input relative to that magnitude, so a
/// small absolute value is a graze they may see either way.
fn outside(tri: &Triangle, ray: &Ray) -> Option<(f64, f64)> {
    let (t, u, v) = crossing_f64(tri, ray)?;
    let d = |v: Vec3A| DVec3::new(v.x as f64, v.y as f64, v.z as f64);
    let (a, b, c) = (d(tri.v[0]), d(tri.v[1]), d(tri.v[2]));
    let p = d(ray.origin) + d(ray.dir) * t;
    let boundary = segment_distance(p, a, b)
        .min(segment_distance(p, b, c))
        .min(segment_distance(p, c, a));
    let inside = u >= 0.0 && v >= 0.0 && u + v <= 1.0;
    let dist = if inside { -boundary } else { boundary };
    let scale = [a, b, c, d(ray.origin), p]
        .iter()
        .map(|x| x.abs().max_element())
        .fold(f64::MIN_POSITIVE, f64::max);
    Some((t, dist / scale))
}

/// Relative distance within which f32 kernels may disagree about inside/outside (about 170
/// ulps of the coordinates: a few ulps of rounding amplified by sliver triangles and grazing
/// angles).
const EDGE_EPS: f64 = 1e-5;
/// Relative distance within which two hits are a tie.
const TIE_EPS: f64 = 1e-5;

#[derive(Debug)]
enum Verdict {
    Agree,
    Tie,
    Edge,
    Wrong,
}

fn judge(tris: &[Triangle], ray: &Ray, q: Option<Hit>, o: Option<(u32, f32)>) -> Verdict {
    let same_t =
        |a: f32, b: f32| (a as f64 - b as f64).abs() <= TIE_EPS * (a.abs().max(1.0) as f64);
    match (q, o) {
        (None, None) => Verdict::Agree,
        (Some(h), Some((p, t))) if h.prim == p && same_t(h.t, t) => Verdict::Agree,
        (Some(h), Some((p, t))) => {
            // Two different primitives: a tie when both are genuinely (or within rounding)
            // crossed at the same distance in f64.
            let a = outside(&tris[h.prim as usize], ray);
            let b = outside(&tris[p as usize], ray);
            match (a, b) {
                (Some((ta, ea)), Some((tb, eb))) if ea <= EDGE_EPS && eb <= EDGE_EPS => {
                    if (ta - tb).abs() <= TIE_EPS * ta.abs().max(1.0) && same_t(h.t, t) {
                        Verdict::Tie
                    } else if ea.abs() <= EDGE_EPS || eb.abs() <= EDGE_EPS {
                        // One of them is grazed: one engine saw it, the other went past.
                        Verdict::Edge
                    } else {
                        Verdict::Wrong
                    }
                }
                _ => Verdict::Wrong,
            }
        }
        // One engine hit a triangle the other missed: the crossing must graze an edge.
        (Some(Hit { prim, .. }), None) | (None, Some((prim, _))) => {
            match outside(&tris[prim as usize], ray) {
                Some((_, e)) if e.abs() <= EDGE_EPS => Verdict::Edge,
                _ => Verdict::Wrong,
            }
        }
    }
}

fn compare(scene: &Scene, rays: &[Ray]) -> (usize, usize, usize) {
    let tris = &scene.triangles();
    let bvh = Bvh::new(tris);
    let otris = quiver_lab::obvhs_bridge::triangles(tris);
    let obvh = build_bvh2_from_tris(
        &otris,
        BvhBuildParams::medium_build(),
        &mut Duration::default(),
    );
    let verdicts: Vec<Verdict> = rays
        .par_iter()
        .map(|ray| {
            let oray = obvhs::ray::Ray::new(ray.origin, ray.dir, ray.t_min, ray.t_max);
            let mut hit = RayHit::none();
            let found = obvh.ray_traverse(oray, &mut hit, |r, slot| {
                otris[obvh.primitive_indices[slot] as usize].intersect(r)
            });
            let o = found.then(|| (obvh.primitive_indices[hit.primitive_id as usize], hit.t));
            let q = bvh.closest_hit(ray);
            let v = judge(tris, ray, q, o);
            if matches!(v, Verdict::Wrong) && std::env::var("QUIVER_DEBUG").is_ok() {
                let info = |p: u32| (p, outside(&tris[p as usize], ray));
                eprintln!(
                    "q={q:?} {:?} o={o:?} {:?}",
                    q.map(|h| info(h.prim)),
                    o.map(|h| info(h.0))
                );
            }
            v
        })
        .collect();
    let count = |f: fn(&Verdict) -> bool| verdicts.iter().filter(|v| f(v)).count();
    let wrong: Vec<_> = rays
        .iter()
        .zip(&verdicts)
        .filter(|(_, v)| matches!(v, Verdict::Wrong))
        .take(5)
        .collect();
    assert!(
        wrong.is_empty(),
        "{}: disagreements that are no tie or edge case: {wrong:?}",
        scene.name
    );
    (
        count(|v| matches!(v, Verdict::Agree)),
        count(|v| matches!(v, Verdict::Tie)),
        count(|v| matches!(v, Verdict::Edge)),
    )
}

/// Rays from outside the scene aimed exactly at edge midpoints and vertices: where two
/// triangles meet, so f32 kernels legitimately pick different ones.
fn edge_rays(scene: &Scene, n: usize) -> Vec<Ray> {
    let b = scene.bounds();
    let eye = b.max + b.extent() * 1.5;
    scene
        .triangles()
        .iter()
        .flat_map(|t| [(t.v[0] + t.v[1]) * 0.5, (t.v[1] + t.v[2]) * 0.5, t.v[0]])
        .take(n)
        .map(|p| Ray::new(eye, p - eye))
        .collect()
}

fn check(name: &str) {
    let scene = Scene::load(name).unwrap();
    let mut rays = rays::random_rays(&scene.bounds(), 100_000, 11);
    rays.extend(rays::camera_rays(&scene.camera, 256));
    let (agree, ties, edges) = compare(&scene, &rays);
    println!(
        "{name}: {} random+camera rays, {agree} agree, {ties} ties, {edges} edge cases",
        rays.len()
    );
    // Edge cases need a ray within ~EDGE_EPS (relative) of an edge; with a handful of
    // triangles crossed per ray that is well under one ray in 10^4.
    assert!(
        ties + edges <= rays.len() / 10_000,
        "{name}: {ties} ties + {edges} edge cases"
    );
    let aimed = edge_rays(&scene, 30_000);
    let (agree, ties, edges) = compare(&scene, &aimed);
    println!(
        "{name}: {} edge/vertex rays, {agree} agree, {ties} ties, {edges} edge cases",
        aimed.len()
    );
}

#[test]
fn agrees_with_obvhs_on_tetra7() {
    check("tetra7");
}

#[test]
fn agrees_with_obvhs_on_soup() {
    check("soup20000");
}

/// The judge itself: a tie, an edge graze and a plain error are told apart.
#[test]
fn judge_tells_ties_edges_and_errors_apart() {
    let v = |x: f32, y: f32| Vec3A::new(x, y, 0.0);
    // Two triangles sharing the edge x = 0, and one far behind them.
    let tris = [
        Triangle::new(v(0.0, -1.0), v(0.0, 1.0), v(-1.0, 0.0)),
        Triangle::new(v(0.0, -1.0), v(1.0, 0.0), v(0.0, 1.0)),
        Triangle::new(
            Vec3A::new(-5.0, -5.0, -3.0),
            Vec3A::new(5.0, -5.0, -3.0),
            Vec3A::new(0.0, 5.0, -3.0),
        ),
    ];
    let hit = |prim, t| {
        Some(Hit {
            t,
            prim,
            u: 0.0,
            v: 0.0,
        })
    };
    let on_edge = Ray::new(Vec3A::new(0.0, 0.25, 1.0), -Vec3A::Z);
    assert!(matches!(
        judge(&tris, &on_edge, hit(0, 1.0), Some((1, 1.0))),
        Verdict::Tie
    ));
    let grazing = Ray::new(Vec3A::new(1e-7, 0.25, 1.0), -Vec3A::Z);
    assert!(matches!(
        judge(&tris, &grazing, hit(1, 1.0), None),
        Verdict::Edge
    ));
    let inside = Ray::new(Vec3A::new(0.5, 0.0, 1.0), -Vec3A::Z);
    assert!(matches!(
        judge(&tris, &inside, hit(1, 1.0), Some((2, 4.0))),
        Verdict::Wrong
    ));
    assert!(matches!(
        judge(&tris, &inside, hit(1, 1.0), None),
        Verdict::Wrong
    ));
    assert!(matches!(
        judge(&tris, &inside, hit(1, 1.0), Some((1, 1.0))),
        Verdict::Agree
    ));
}
