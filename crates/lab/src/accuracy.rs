//! What accuracy costs: every combination of triangle intersector (fast, watertight, f64),
//! box test (plain, conservative) and secondary-ray offset (epsilon, ulps), measured in time
//! and in errors on the same rays.
//!
//! - **Mrays/s**: closest-hit and any-hit throughput on incoherent rays through the scene.
//! - **Leaks**: rays aimed exactly at the shared edges and vertices of a closed mesh (an
//!   icosphere, from inside and outside) that hit nothing, per million.
//! - **Self-hits**: reflection rays leaving a hit point that hit their own primitive first,
//!   per million secondary rays.
//! - **Reference mismatches**: rays whose hit (primitive, or hit/miss) differs from the f64
//!   intersector with conservative boxes, per million.
//!
//! ```
//! use quiver_lab::accuracy::evaluate;
//! use quiver_scenes::scene::Scene;
//! let tris = Scene::load("tetra3").unwrap().triangles();
//! let rows = evaluate(&tris, 2000, 1, 1);
//! assert_eq!(rows.len(), 12);
//! let watertight = rows.iter().find(|r| r.intersector == "watertight" && r.box_test == "conservative").unwrap();
//! assert_eq!(watertight.leaks_per_million, 0.0);
//! ```

use crate::measure;
use glam::Vec3A;
use quiver_rt::intersect::{Exact, Watertight};
use quiver_rt::traverse::{BoxTest, ConservativeBoxes, FastBoxes, NoFilter, NoStats};
use quiver_rt::{Bvh, Primitive, Ray, RayQuery, Triangle};
use quiver_scenes::render::Offset;
use quiver_scenes::Scene;
use rayon::prelude::*;

/// One combination's measurements.
#[derive(Clone, Debug, PartialEq)]
pub struct Row {
    /// `fast`, `watertight` or `f64`.
    pub intersector: &'static str,
    /// `plain` or `conservative`.
    pub box_test: &'static str,
    /// `epsilon` or `ulps`.
    pub offset: &'static str,
    /// Closest-hit throughput on incoherent rays.
    pub mrays_per_s: f64,
    /// Any-hit throughput on the same rays.
    pub any_mrays_per_s: f64,
    /// Closed-mesh edge/vertex rays that leaked, per million.
    pub leaks_per_million: f64,
    /// Secondary rays that re-hit their own primitive, per million.
    pub self_hits_per_million: f64,
    /// Rays answered differently from the f64 reference, per million.
    pub ref_mismatch_per_million: f64,
}

/// A triangle's corners and edge midpoints: where a ray between two triangles of a closed
/// mesh can leak through.
///
/// ```
/// use glam::Vec3A;
/// let t = quiver_rt::Triangle::new(Vec3A::ZERO, Vec3A::X, Vec3A::Y);
/// assert_eq!(quiver_lab::accuracy::edge_points(&t)[3], Vec3A::new(0.5, 0.0, 0.0));
/// ```
pub fn edge_points(t: &Triangle) -> [Vec3A; 6] {
    let [a, b, c] = t.v;
    [a, b, c, (a + b) * 0.5, (b + c) * 0.5, (c + a) * 0.5]
}

/// Rays aimed exactly at every vertex and edge midpoint of a closed mesh around the origin,
/// from a few interior points and from outside through the centre: each must hit.
pub fn closed_mesh_rays(tris: &[Triangle]) -> Vec<Ray> {
    let inside = [
        Vec3A::ZERO,
        Vec3A::new(0.2, -0.1, 0.3),
        Vec3A::new(-0.3, 0.25, -0.1),
        Vec3A::new(0.05, 0.4, 0.1),
    ];
    let mut rays = Vec::new();
    for t in tris {
        for p in edge_points(t) {
            rays.extend(inside.iter().map(|&o| Ray::new(o, p - o)));
            rays.push(Ray::new(p * 3.0, -p * 3.0));
        }
    }
    rays
}

/// Measures all twelve combinations on `scene_tris` with `n_rays` incoherent rays, `reps`
/// timed repetitions (median), and the leak test on an icosphere of `sphere_level`
/// subdivisions. Runs on the current rayon pool.
pub fn evaluate(
    scene_tris: &[Triangle],
    n_rays: usize,
    reps: usize,
    sphere_level: u32,
) -> Vec<Row> {
    let bounds = scene_tris
        .iter()
        .fold(quiver_rt::Aabb::EMPTY, |b, t| b.union(&t.bounds()));
    let rays = crate::rays::random_rays(&bounds, n_rays, 17);
    let sphere = Scene::load(&format!("icosphere{sphere_level}"))
        .map(|s| s.triangles())
        .unwrap_or_default();
    let closed = closed_mesh_rays(&sphere);
    let wt = |t: &[Triangle]| t.iter().map(|&t| Watertight(t)).collect::<Vec<_>>();
    let ex = |t: &[Triangle]| t.iter().map(|&t| Exact(t)).collect::<Vec<_>>();
    let (fast, water, f64_) = (
        Bvh::new(scene_tris),
        Bvh::new(&wt(scene_tris)),
        Bvh::new(&ex(scene_tris)),
    );
    let want: Vec<Option<u32>> = rays
        .par_iter()
        .map(|r| {
            f64_.closest_hit_with::<ConservativeBoxes, _, _>(r, &mut NoStats, &mut NoFilter)
                .map(|h| h.prim)
        })
        .collect();
    let ctx = Ctx {
        tris: scene_tris,
        rays: &rays,
        want: &want,
        closed: &closed,
        size: bounds.extent().max_element(),
    };
    let count = |q: Kernel, any: bool| measure::count_hits(&rays, |r| q(r, any));
    // The six kernels, in row order, timed side by side so a slow spell hits all alike.
    let kernels: [Kernel; 6] = [
        &|r, any| query::<_, FastBoxes>(&fast, r, any),
        &|r, any| query::<_, ConservativeBoxes>(&fast, r, any),
        &|r, any| query::<_, FastBoxes>(&water, r, any),
        &|r, any| query::<_, ConservativeBoxes>(&water, r, any),
        &|r, any| query::<_, FastBoxes>(&f64_, r, any),
        &|r, any| query::<_, ConservativeBoxes>(&f64_, r, any),
    ];
    let speed = |any: bool| {
        measure::median_times_interleaved(reps, kernels.len(), |i| {
            std::hint::black_box(count(kernels[i], any));
        })
        .into_iter()
        .map(|t| measure::mrays_per_s(rays.len(), t))
        .collect::<Vec<_>>()
    };
    let (closest, any) = (speed(false), speed(true));
    let speed = |i: usize| (closest[i], any[i]);
    let mut rows = Vec::new();
    rows.extend(combo::<_, FastBoxes>(
        ("fast", "plain"),
        &fast,
        &Bvh::new(&sphere),
        speed(0),
        &ctx,
    ));
    rows.extend(combo::<_, ConservativeBoxes>(
        ("fast", "conservative"),
        &fast,
        &Bvh::new(&sphere),
        speed(1),
        &ctx,
    ));
    rows.extend(combo::<_, FastBoxes>(
        ("watertight", "plain"),
        &water,
        &Bvh::new(&wt(&sphere)),
        speed(2),
        &ctx,
    ));
    rows.extend(combo::<_, ConservativeBoxes>(
        ("watertight", "conservative"),
        &water,
        &Bvh::new(&wt(&sphere)),
        speed(3),
        &ctx,
    ));
    rows.extend(combo::<_, FastBoxes>(
        ("f64", "plain"),
        &f64_,
        &Bvh::new(&ex(&sphere)),
        speed(4),
        &ctx,
    ));
    rows.extend(combo::<_, ConservativeBoxes>(
        ("f64", "conservative"),
        &f64_,
        &Bvh::new(&ex(&sphere)),
        speed(5),
        &ctx,
    ));
    rows
}

/// One combination's query: `(ray, any)` to whether the ray hit.
type Kernel<'a> = &'a (dyn Fn(&Ray, bool) -> bool + Sync);

/// Closest hit found (or, with `any`, anything hit) by `bvh` with box test `B`.
fn query<P: Primitive, B: BoxTest>(bvh: &Bvh<P>, r: &Ray, any: bool) -> bool {
    if any {
        bvh.any_hit_with::<B, _, _>(r, &mut NoStats, &mut NoFilter)
    } else {
        bvh.closest_hit_with::<B, _, _>(r, &mut NoStats, &mut NoFilter)
            .is_some()
    }
}

struct Ctx<'a> {
    /// The scene's triangles (the primitives of every combination wrap them, same order).
    tris: &'a [Triangle],
    rays: &'a [Ray],
    want: &'a [Option<u32>],
    closed: &'a [Ray],
    /// The scene's largest extent (secondary-ray offsets are relative to it).
    size: f32,
}

fn per_million(count: usize, of: usize) -> f64 {
    count as f64 * 1e6 / of.max(1) as f64
}

/// The error measurements of one combination (its speeds measured beside the others).
fn combo<P: Primitive, B: BoxTest>(
    (intersector, box_test): (&'static str, &'static str),
    bvh: &Bvh<P>,
    sphere_bvh: &Bvh<P>,
    (mrays, any_mrays): (f64, f64),
    ctx: &Ctx,
) -> Vec<Row> {
    let closest = |r: &Ray| bvh.closest_hit_with::<B, _, _>(r, &mut NoStats, &mut NoFilter);
    let leaks = ctx
        .closed
        .par_iter()
        .filter(|r| !sphere_bvh.any_hit_with::<B, _, _>(r, &mut NoStats, &mut NoFilter))
        .count();
    let hits: Vec<Option<quiver_rt::Hit>> = ctx.rays.par_iter().map(closest).collect();
    let mismatches = hits
        .iter()
        .zip(ctx.want)
        .filter(|(h, w)| h.map(|h| h.prim) != **w)
        .count();
    [("epsilon", Offset::Epsilon), ("ulps", Offset::Ulps)]
        .into_iter()
        .map(|(offset, method)| {
            // Mirror rays off every hit: the first thing they meet must not be where they start.
            let (secondary, self_hits) = ctx
                .rays
                .par_iter()
                .zip(&hits)
                .filter_map(|(r, h)| h.map(|h| (r, h)))
                .map(|(r, h)| {
                    let p = r.at(h.t);
                    let t = &ctx.tris[h.prim as usize];
                    let normal = (t.v[1] - t.v[0]).cross(t.v[2] - t.v[0]).normalize_or_zero();
                    let side = if normal.dot(r.dir) < 0.0 {
                        normal
                    } else {
                        -normal
                    };
                    let d = r.dir - side * (2.0 * r.dir.dot(side));
                    let s = method.ray(ctx.size, p, side, d, f32::INFINITY);
                    (
                        1usize,
                        closest(&s).is_some_and(|s| s.prim == h.prim) as usize,
                    )
                })
                .reduce(|| (0, 0), |a, b| (a.0 + b.0, a.1 + b.1));
            Row {
                intersector,
                box_test,
                offset,
                mrays_per_s: mrays,
                any_mrays_per_s: any_mrays,
                leaks_per_million: per_million(leaks, ctx.closed.len()),
                self_hits_per_million: per_million(self_hits, secondary),
                ref_mismatch_per_million: per_million(mismatches, ctx.rays.len()),
            }
        })
        .collect()
}
