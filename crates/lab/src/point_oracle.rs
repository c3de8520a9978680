//! [`PointOracle`]: the closest point of a set of triangles by brute force in f64, sharing no
//! arithmetic with quiver's f32 kernel (`Triangle::closest_point`, Ericson's region test), to
//! judge `Bvh::closest_point` and `World::closest_point`.
//!
//! Per triangle the oracle projects the point onto the plane (`q = p - n·((p-a)·n)/(n·n)`,
//! `n` the cross product of the two shortest edges), keeps the projection when it lies on
//! the inner side of all three edges, and otherwise takes the nearest of the three edges
//! (clamped segment projections). A triangle whose normal is shorter than 2^-26 of the
//! product of those edges' lengths (a needle, such as one 2e6 long and 1e-6 wide: its normal
//! is then not known to 2^-25) goes straight to its edges, which lie within 2^-26 of its
//! shorter edges' length of every point of it. Every other step rounds at 2^-53, far below
//! what an f32 kernel resolves.
//!
//! # The tolerance
//!
//! An answer's distance may differ from the exact one by at most
//! `tol = TOL_K·ε·(d + size)` with `ε = 2^-24`, `d` the exact nearest distance and `size`
//! the scene's extent plus its reach (the largest coordinate magnitude of its box: the f32
//! point `a + u·ab + v·ac` rounds at the ulps of its coordinates), [`TOL_K`] = 8. A
//! primitive is *admissible* when its exact distance lies within `tol` of the nearest; the
//! point returned must lie within `tol` of its triangle and its distance within `tol` of the
//! exact distance to that triangle.
//!
//! Measured with `cargo test -p quiver-lab --lib point_oracle::tests::measured_error --
//! --nocapture` (which prints the numbers and fails if they grow past the ones quoted here):
//! over 6,000 points (1,500 per scene: inside the scene's box, exactly on vertices, on edges,
//! and 1 to 1,000 scene sizes away) on four scenes (`soup2000`, `tetra4`, and the first 500
//! triangles of `soup2000` scaled by 1e-20 and by 1e20, which the BVH builds in its scaled
//! frame), `Bvh::closest_point`'s distance erred from the exact nearest by at most
//! **0.98 ε·(d + size)** (soup2000; 0.89 on tetra4, 0.92 at 1e-20, 0.95 at 1e20), and its
//! point lay at most **0.65 ε·(d + size)** off its triangle. Over 2,000 points near 300
//! near-collinear slivers (the third vertex 2^-18 to 2^-30 of the edge length off the line
//! of the first two) the distance erred by at most **0.58 ε·(d + size)** and the point lay
//! at most 0.56 off: the kernel takes slivers through its f64 path. (Before that path, with
//! Ericson's region test in f32 alone, a point 1.2e-7 from a 2^-18 sliver was answered
//! 6e-4 away: about 970 ε·(d + size).) `TOL_K = 8` is eight times the largest error seen.
//!
//! ```
//! use glam::Vec3A;
//! use quiver_rt::{Bvh, Triangle};
//! use quiver_lab::point_oracle::PointOracle;
//! let tris = [Triangle::new(Vec3A::ZERO, Vec3A::X, Vec3A::Y), Triangle::new(Vec3A::Z, Vec3A::Z + Vec3A::X, Vec3A::Z + Vec3A::Y)];
//! let oracle = PointOracle::new(&tris);
//! let p = Vec3A::new(0.2, 0.2, 0.25);
//! let a = oracle.answer(p, f32::INFINITY);
//! assert_eq!((a.distance, a.admissible.as_slice()), (0.25, &[(0, 0)][..]));
//! let hit = Bvh::new(&tris).closest_point(p, f32::INFINITY).unwrap();
//! oracle.check_bvh(p, f32::INFINITY, Some(&hit)).unwrap();
//! // Half way between the two: either is right.
//! assert_eq!(oracle.answer(Vec3A::new(0.2, 0.2, 0.5), f32::INFINITY).admissible.len(), 2);
//! ```

use crate::worlds::Placements;
use glam::{DAffine3, DVec3, Vec3A};
use quiver_rt::point::PointHit;
use quiver_rt::world::{Geometry, WorldPointHit};
use quiver_rt::{Instance, Triangle, World};
use rayon::prelude::*;

/// The tolerance factor: an answer may be off by `TOL_K·ε·(d + size)` (see the module docs).
pub const TOL_K: f64 = 8.0;

/// f32's unit roundoff.
const EPS: f64 = 1.0 / (1u64 << 24) as f64;

/// A triangle in f64 with who it is: (instance, primitive); instance 0 for a plain BVH.
#[derive(Clone, Copy, Debug)]
struct Tri {
    v: [DVec3; 3],
    id: (u32, u32),
}

/// Brute-force closest points over triangles in f64 (see the module docs).
#[derive(Clone, Debug)]
pub struct PointOracle {
    tris: Vec<Tri>,
    /// The scene's extent plus its reach (largest coordinate magnitude).
    size: f64,
}

/// What the oracle says about one point.
#[derive(Clone, Debug, PartialEq)]
pub struct PointAnswer {
    /// The exact nearest distance (infinite for a scene of nothing).
    pub distance: f64,
    /// The (instance, primitive) pairs whose exact distance lies within `tolerance` of it,
    /// sorted.
    pub admissible: Vec<(u32, u32)>,
    /// The band: `TOL_K·ε·(distance + size)`.
    pub tolerance: f64,
}

/// What a kernel answered, in the oracle's terms.
#[derive(Clone, Copy, Debug)]
pub struct Got {
    /// (instance, primitive): instance 0 for a plain BVH.
    pub id: (u32, u32),
    /// The point on the primitive.
    pub point: Vec3A,
    /// Its barycentrics.
    pub u: f32,
    /// Its barycentrics.
    pub v: f32,
    /// The reported distance.
    pub distance: f32,
}

impl From<&PointHit> for Got {
    fn from(h: &PointHit) -> Got {
        Got {
            id: (0, h.prim),
            point: h.point,
            u: h.u,
            v: h.v,
            distance: h.distance,
        }
    }
}

impl From<&WorldPointHit> for Got {
    fn from(h: &WorldPointHit) -> Got {
        Got {
            id: (h.instance.0, h.prim),
            point: h.point,
            u: h.u,
            v: h.v,
            distance: h.distance,
        }
    }
}

fn wide(v: Vec3A) -> DVec3 {
    DVec3::new(v.x as f64, v.y as f64, v.z as f64)
}

/// The point of segment `a..b` nearest `p`.
fn on_segment(a: DVec3, b: DVec3, p: DVec3) -> DVec3 {
    let d = b - a;
    let dd = d.length_squared();
    if dd == 0.0 {
        return a;
    }
    a + d * ((p - a).dot(d) / dd).clamp(0.0, 1.0)
}

/// The exact (to f64) point of triangle `v` nearest `p`.
pub fn closest_f64(v: &[DVec3; 3], p: DVec3) -> DVec3 {
    // The normal from the two shortest edges (those meeting at the vertex opposite the longest):
    // its rounding, a few f64 epsilons of the product of the lengths crossed, is then least.
    let opposite = |i: usize| (v[(i + 2) % 3] - v[(i + 1) % 3]).length_squared();
    let k = (0..3)
        .max_by(|&i, &j| opposite(i).total_cmp(&opposite(j)))
        .unwrap_or(0);
    let (a, b, c) = (v[k], v[(k + 1) % 3], v[(k + 2) % 3]);
    let n = (b - a).cross(c - a);
    let nn = n.length_squared();
    // Trust the plane only where the normal is at least 2^-26 of that product (its rounding
    // then below 2^-25 of it); a narrower triangle lies within 2^-26 of its shorter edges'
    // length of its edges, and they answer for it.
    let bound = (b - a).length_squared() * (c - a).length_squared() * PLANE_TRUST;
    if nn.is_finite() && bound.is_finite() && nn > bound {
        let q = p - n * ((p - a).dot(n) / nn);
        // Inside: on the inner side of each edge, each test a cross product of that edge alone.
        let inner = |s: DVec3, e: DVec3| (e - s).cross(q - s).dot(n) >= 0.0;
        if inner(a, b) && inner(b, c) && inner(c, a) {
            return q;
        }
    }
    let mut best = on_segment(a, b, p);
    for q in [on_segment(a, c, p), on_segment(b, c, p)] {
        if (q - p).length_squared() < (best - p).length_squared() {
            best = q;
        }
    }
    best
}

/// `(2^-26)^2`: see [`closest_f64`].
const PLANE_TRUST: f64 = 1.0 / (1u64 << 52) as f64;

impl PointOracle {
    /// The oracle over `tris` (a BVH's input; ids `(0, index)`); non-finite triangles are
    /// left out, as builds drop them.
    pub fn new(tris: &[Triangle]) -> PointOracle {
        Self::of(
            tris.iter()
                .enumerate()
                .filter(|(_, t)| t.is_finite())
                .map(|(i, t)| Tri {
                    v: t.v.map(wide),
                    id: (0, i as u32),
                })
                .collect(),
        )
    }

    /// The oracle over a world's triangle geometries, each instance's triangles placed by
    /// its transform in f64 (ids `(instance, primitive)`).
    pub fn for_world(world: &World) -> PointOracle {
        Self::placed(world.instances(), |g| {
            match world.geometries().get(g as usize) {
                Some(Geometry::Triangles(_, g)) => g,
                _ => &[],
            }
        })
    }

    /// The oracle over a scene of instances ([`Placements`]), as [`PointOracle::for_world`]
    /// over its world: what `World::closest_point` on the world of a moving scene placed at
    /// a time ([`Placements::deformed_at`]) is judged by, with no world built.
    pub fn for_placements(placements: &Placements) -> PointOracle {
        Self::placed(&placements.instances, |g| {
            &placements.geometries[g as usize]
        })
    }

    /// Each instance's triangles (`geometry(g)` for its geometry `g`), placed by its
    /// transform in f64.
    fn placed<'a>(instances: &[Instance], geometry: impl Fn(u32) -> &'a [Triangle]) -> PointOracle {
        let mut tris = Vec::new();
        for (i, inst) in instances.iter().enumerate() {
            let m = DAffine3::from_cols_array(&inst.transform.to_cols_array().map(f64::from));
            let g = geometry(inst.geometry.0);
            for (j, t) in g.iter().enumerate().filter(|(_, t)| t.is_finite()) {
                tris.push(Tri {
                    v: t.v.map(|p| m.transform_point3(wide(p))),
                    id: (i as u32, j as u32),
                });
            }
        }
        Self::of(tris)
    }

    fn of(tris: Vec<Tri>) -> PointOracle {
        let (mut lo, mut hi) = (DVec3::INFINITY, DVec3::NEG_INFINITY);
        for t in &tris {
            for p in t.v {
                (lo, hi) = (lo.min(p), hi.max(p));
            }
        }
        let size = if tris.is_empty() {
            0.0
        } else {
            (hi - lo).max_element() + lo.abs().max(hi.abs()).max_element()
        };
        PointOracle { tris, size }
    }

    /// The scene's extent plus reach: the `size` of the tolerance.
    pub fn size(&self) -> f64 {
        self.size
    }

    /// The band at nearest distance `d`.
    pub fn tolerance(&self, d: f64) -> f64 {
        TOL_K * EPS * (d + self.size)
    }

    /// Every triangle's exact distance from `p`, with its id.
    fn distances(&self, p: DVec3) -> Vec<(f64, (u32, u32))> {
        self.tris
            .par_iter()
            .map(|t| ((closest_f64(&t.v, p) - p).length(), t.id))
            .collect()
    }

    /// The nearest distance and the admissible primitives for `p`, whatever `max_distance`
    /// (which only [`PointOracle::check`] reads).
    pub fn answer(&self, p: Vec3A, _max_distance: f32) -> PointAnswer {
        let all = self.distances(wide(p));
        let distance = all.iter().map(|x| x.0).fold(f64::INFINITY, f64::min);
        let tolerance = self.tolerance(distance);
        let mut admissible: Vec<(u32, u32)> = all
            .iter()
            .filter(|x| x.0 <= distance + tolerance)
            .map(|x| x.1)
            .collect();
        admissible.sort_unstable();
        PointAnswer {
            distance,
            admissible,
            tolerance,
        }
    }

    /// The exact distance from `p` to the triangle `id`, and the triangle.
    fn of_id(&self, id: (u32, u32), p: DVec3) -> Option<(f64, [DVec3; 3])> {
        let t = self.tris.iter().find(|t| t.id == id)?;
        Some(((closest_f64(&t.v, p) - p).length(), t.v))
    }

    /// Checks a kernel's answer for `p` within `max_distance` (see the module docs): `None`
    /// only when no triangle lies within `max_distance` less the band; otherwise an
    /// admissible primitive, within `max_distance`, whose point lies on it (within the band)
    /// at the distance reported, barycentrics in the triangle that give the point.
    ///
    /// # Errors
    /// What is wrong, with the numbers.
    #[allow(clippy::neg_cmp_op_on_partial_ord)] // a NaN anywhere must fail the check
    pub fn check(&self, p: Vec3A, max_distance: f32, got: Option<Got>) -> Result<(), String> {
        let a = self.answer(p, max_distance);
        let tol = a.tolerance;
        let max = max_distance as f64;
        let Some(g) = got else {
            return if a.distance <= max - tol {
                Err(format!(
                    "at {p}: nothing found, but {:?} lie at {} <= {max} (band {tol:e})",
                    a.admissible, a.distance
                ))
            } else {
                Ok(())
            };
        };
        let fail = |why: String| Err(format!("at {p} (max {max}): {g:?}: {why}; oracle {a:?}"));
        let pw = wide(p);
        if !(g.distance as f64 <= max) {
            return fail("beyond max_distance".into());
        }
        if !(a.distance <= max + tol) {
            return fail("nothing lies that near".into());
        }
        if !a.admissible.contains(&g.id) {
            return fail("not an admissible primitive".into());
        }
        let Some((d_id, v)) = self.of_id(g.id, pw) else {
            return fail("no such primitive".into());
        };
        let gd = g.distance as f64;
        if !((gd - d_id).abs() <= tol && (gd - a.distance).abs() <= tol) {
            return fail(format!("distance off by {:e}", (gd - d_id).abs()));
        }
        let q = wide(g.point);
        if !(((q - pw).length() - gd).abs() <= tol) {
            return fail("the point does not lie at the distance reported".into());
        }
        let off = (closest_f64(&v, q) - q).length();
        if !(off <= tol) {
            return fail(format!("the point lies {off:e} off its triangle"));
        }
        let (u, w) = (g.u as f64, g.v as f64);
        let slack = 1e-6;
        if !(u >= 0.0 && w >= 0.0 && u + w <= 1.0 + slack) {
            return fail("barycentrics outside the triangle".into());
        }
        let at = v[0] + (v[1] - v[0]) * u + (v[2] - v[0]) * w;
        if !((at - q).length() <= tol) {
            return fail(format!("barycentrics give {at}, not the point"));
        }
        Ok(())
    }

    /// [`PointOracle::check`] of a BVH's answer.
    ///
    /// # Errors
    /// As [`PointOracle::check`].
    pub fn check_bvh(
        &self,
        p: Vec3A,
        max_distance: f32,
        got: Option<&PointHit>,
    ) -> Result<(), String> {
        self.check(p, max_distance, got.map(Got::from))
    }

    /// [`PointOracle::check`] of a world's answer.
    ///
    /// # Errors
    /// As [`PointOracle::check`].
    pub fn check_world(
        &self,
        p: Vec3A,
        max_distance: f32,
        got: Option<&WorldPointHit>,
    ) -> Result<(), String> {
        self.check(p, max_distance, got.map(Got::from))
    }

    /// How far a kernel's answer is from the exact one, in units of `ε·(d + size)`: the
    /// larger of its distance's error and its point's distance off its triangle. For the
    /// measurement in the module docs.
    pub fn deviation(&self, p: Vec3A, got: &Got) -> (f64, f64) {
        let a = self.answer(p, f32::INFINITY);
        let unit = EPS * (a.distance + self.size);
        let d = (got.distance as f64 - a.distance).abs() / unit;
        let off = self
            .of_id(got.id, wide(got.point))
            .map_or(f64::INFINITY, |(o, _)| o / unit);
        (d, off)
    }
}

/// Test points for a scene of `tris` with box `lo..hi`: inside the box, on vertices, on
/// edges, and far away (up to `far` box sizes), `n` of them from `seed`.
pub fn points(tris: &[Triangle], n: usize, far: f32, seed: u64) -> Vec<Vec3A> {
    let mut rng = quiver_scenes::rng::Rng::new(seed);
    let (mut lo, mut hi) = (Vec3A::INFINITY, Vec3A::NEG_INFINITY);
    for t in tris {
        lo = lo.min(t.bounds().min);
        hi = hi.max(t.bounds().max);
    }
    let size = (hi - lo).max_element();
    let centre = (lo + hi) * 0.5;
    (0..n)
        .map(|i| {
            let t = &tris[(rng.next_u64() % tris.len() as u64) as usize];
            match i % 5 {
                0 | 1 => rng.in_box(lo, hi),
                2 => t.v[(rng.next_u64() % 3) as usize],
                3 => {
                    let k = (rng.next_u64() % 3) as usize;
                    let s = rng.f32();
                    t.v[k] + (t.v[(k + 1) % 3] - t.v[k]) * s
                }
                _ => centre + rng.unit_vector() * size * rng.range(1.0, far),
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use quiver_rt::{BuildOptions, Bvh, Layout};
    use quiver_scenes::Scene;

    /// The largest deviations (distance, point off its triangle) of `Bvh::closest_point` over
    /// `points`.
    fn worst(tris: &[Triangle], points: &[Vec3A]) -> (f64, f64) {
        let oracle = PointOracle::new(tris);
        let bvh = Bvh::build(tris, &BuildOptions::default().layout(Layout::Bvh8Dfs)).unwrap();
        points
            .iter()
            .map(|&p| {
                let hit = bvh.closest_point(p, f32::INFINITY).unwrap();
                oracle.check_bvh(p, f32::INFINITY, Some(&hit)).unwrap();
                oracle.deviation(p, &Got::from(&hit))
            })
            .fold((0.0, 0.0), |a, b| (a.0.max(b.0), a.1.max(b.1)))
    }

    /// A needle 2e6 long and about 1e-6 wide (from a fuzzed world, placed by a sheared,
    /// scaled instance): the cross product of its long edges rounds to a wrong normal, and
    /// projecting onto that plane once put a point 3.7e4 off the triangle. Each of its
    /// vertices and edge midpoints is its own nearest point.
    #[test]
    fn a_needle_is_its_own_nearest_point() {
        let m = DAffine3::from_cols(
            DVec3::new(-2.2198093, 2.1184902, 0.35734835),
            DVec3::new(-0.10766612, -0.36903736, 0.92570454),
            DVec3::new(2.199247, 2.1188023, 1.1004612),
            DVec3::new(0.5, -1.0, 2.0),
        );
        let v = [
            DVec3::new(0.0, -1968116.3, 221.7229),
            DVec3::ZERO,
            DVec3::new(0.0, -1.1094962e-6, 0.0),
        ]
        .map(|p| m.transform_point3(p));
        for i in 0..3 {
            let (s, e) = (v[i], v[(i + 1) % 3]);
            for p in [s, (s + e) * 0.5] {
                let off = (closest_f64(&v, p) - p).length();
                // Rounding at the ulps of coordinates near 1e6 (2^-33) allowed.
                assert!(off <= 1e-6, "{p}: {off}");
            }
        }
    }

    /// Near-collinear slivers: the third vertex `2^-18..2^-30` of the edge off its line.
    pub(crate) fn slivers(n: usize, seed: u64) -> Vec<Triangle> {
        let mut rng = quiver_scenes::rng::Rng::new(seed);
        (0..n)
            .map(|i| {
                let a = rng.in_box(Vec3A::ZERO, Vec3A::splat(4.0));
                let d = rng.unit_vector() * rng.range(0.1, 1.0);
                let off = rng.unit_vector() * d.length() * 2f32.powi(-18 - (i % 13) as i32);
                Triangle::new(a, a + d, a + d * rng.range(0.0, 1.0) + off)
            })
            .collect()
    }

    /// The measurement the module docs quote (and hold to: it fails if the kernel errs more
    /// than they say).
    #[test]
    fn measured_error() {
        let soup = Scene::load("soup2000").unwrap().triangles();
        let tetra = Scene::load("tetra4").unwrap().triangles();
        let small: Vec<Triangle> = soup[..500].to_vec();
        let mut table = Vec::new();
        for (name, tris) in [
            ("soup2000", soup.clone()),
            ("tetra4", tetra),
            (
                "soup500 x 1e-20",
                small
                    .iter()
                    .map(|t| Triangle {
                        v: t.v.map(|p| p * 1e-20),
                    })
                    .collect(),
            ),
            (
                "soup500 x 1e20",
                small
                    .iter()
                    .map(|t| Triangle {
                        v: t.v.map(|p| p * 1e20),
                    })
                    .collect(),
            ),
        ] {
            let pts = points(&tris, 1500, 1000.0, 11);
            table.push((name, worst(&tris, &pts)));
        }
        let s = slivers(300, 5);
        let pts = points(&s, 2000, 4.0, 12);
        let sliver = worst(&s, &pts);
        for (name, (d, off)) in &table {
            println!("{name}: distance {d:.3} eps(d+size), point off {off:.3}");
        }
        println!(
            "slivers: distance {:.3}, point off {:.3}",
            sliver.0, sliver.1
        );
        let (d, off) = table
            .iter()
            .fold((0.0f64, 0.0f64), |a, (_, b)| (a.0.max(b.0), a.1.max(b.1)));
        assert!(d <= 0.99 && off <= 0.66, "the docs' numbers: {d} {off}");
        assert!(
            sliver.0 <= 1.5 && sliver.1 <= 1.5,
            "the docs' sliver numbers: {sliver:?}"
        );
    }
}
