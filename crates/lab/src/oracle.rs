//! An oracle for closest-hit queries over triangles that shares no arithmetic with quiver's
//! kernels, and says for every ray whether an f32 kernel's answer can be judged exactly.
//!
//! quiver's brute-force reference (`quiver_rt::traverse::reference`) calls the very
//! `Triangle::intersect` the kernels call, so comparing the two checks traversal but not the
//! triangle test. This oracle computes in f64 with its own formulation, signed volumes (Plücker's
//! side test written with the vertices relative to the ray origin): with `A`, `B`, `C` the vertices
//! minus the origin and `d` the direction,
//!
//! - `w0 = d·(B×C)`, `w1 = d·(C×A)`, `w2 = d·(A×B)` are the volumes the ray spans with each
//!   edge; the ray's line crosses the triangle where all three share a sign, and `w1/S`,
//!   `w2/S` (with `S = w0 + w1 + w2 = d·n`) are the barycentrics `u` (weight of the second
//!   vertex) and `v` (of the third);
//! - `t = A·(B×C) / S`: the triple product is `n·A`, so this is the plane's distance along
//!   `d`, from the same products as the barycentrics.
//!
//! A vertex minus the origin is exact in f64 for f32 inputs within 2^29 of each other in
//! magnitude; the products then round at 2^-53, so the oracle's own error is a few 2^-53 of
//! its terms, millions of times below what an f32 kernel resolves (2^-24).
//!
//! # Decidable rays and the band
//!
//! An f32 kernel rounds; where the exact answer lies within the kernel's rounding error of a
//! decision (inside or outside a triangle, which of two triangles is nearer, inside or
//! outside `[t_min, t_max]`), either outcome is right. The oracle bounds that error for every
//! crossing from the f32 unit roundoff `ε = 2^-24` and the crossing's conditioning:
//!
//! - barycentrics: both of quiver's tests (Möller–Trumbore in normal form, and Woop's
//!   watertight shear) form `u` from products of coordinates relative to the ray origin,
//!   rounded by `ε·dist` (`dist` the farthest vertex from the origin), and divide by twice the
//!   area projected across the ray, `2·area·|cos|` (`cos` between ray and normal). So
//!   `uv_tol = BARY_K·ε·κ` with `κ = dist·L / (2·area·|cos|)`, `L` the longest edge: about
//!   1e-6 for a triangle met head-on from a few of its sizes away;
//! - distance: rounding the normal tilts the plane about a vertex and rounding the origin
//!   shifts it, each by `ε` relative, amplified by `1/|cos|` and by the sliver factor
//!   `q = L² / (2·area)`: `t_tol = T_K·ε·(t + L/|d|)·q / |cos|`, about ten ulps of `t` for an
//!   equilateral triangle met head-on from afar.
//!
//! - range: where a product of up to three of the lengths involved (longest edge, farthest
//!   vertex from the origin, the direction's length) leaves `2^-100..=2^100`, the f32 test
//!   overflows or flushes to zero and no rounding model holds; such a crossing is treated as
//!   grazed (below).
//!
//! A ray is *decidable* when exactly one answer is admissible: the nearest crossing whose
//! barycentric margin `min(w, u, v)` exceeds `uv_tol`, whose `t` lies more than `t_tol`
//! inside `[t_min, t_max]` and that is not grazed, with no other crossing within the
//! tolerances of its `t` (a tie) and no banded or grazed crossing in front of it; or, for a
//! miss, no crossing within any band. Otherwise the ray is ambiguous ([`Ambiguity`]), and
//! [`Answer::admissible`] lists every hit an f32 kernel may report.
//!
//! A crossing is *grazed* when `|cos| <` [`COS_MIN`] (2^-12: its `t_tol` would pass 2^15
//! ulps) or `uv_tol >` [`BAND_CAP`] (the point is not placed on the triangle to a sixteenth of
//! its size). While `uv_tol <= 1` the barycentrics still say whether it can be hit at all;
//! beyond that, and where the line is parallel to the plane in f64 or the triangle has no
//! area, the f32 plane may tilt into a hit anywhere the line passes near the triangle, and so
//! it is admissible there at any distance.
//!
//! `T_K` and `BARY_K` are 8. A worst-case count of the rounding steps, every error aligned,
//! gives about 16 for `t` and more for `u`; the largest deviations the equivalence tests see
//! (they print them) are 0.37 of `t_tol` and 0.28 of `uv_tol`, so 8 leaves about three times
//! the largest error seen while keeping the band under 0.1% of random and camera rays.
//!
//! Speed: the triangles are kept in groups of 32 in Morton order of their centroids, each
//! with a bounding sphere; a ray tests the triangles of a group only if it passes near the
//! sphere (grown by [`BAND_CAP`]'s reach), and [`Oracle::closest_hits`] runs rays in
//! parallel. 100,000 random rays take about 0.2 s over the 16k triangles of `tetra7` and 1.5 s
//! over `soup20000` on two cores.
//!
//! ```
//! use glam::Vec3A;
//! use quiver_rt::{Ray, Triangle};
//! use quiver_lab::oracle::Oracle;
//! let tris = [Triangle::new(Vec3A::ZERO, Vec3A::X, Vec3A::Y)];
//! let oracle = Oracle::new(&tris);
//! let a = oracle.closest_hit(&Ray::new(Vec3A::new(0.25, 0.5, 2.0), -Vec3A::Z));
//! let hit = a.hit.unwrap();
//! assert_eq!((hit.prim, hit.t, hit.u, hit.v), (0, 2.0, 0.25, 0.5));
//! assert!(a.is_decidable());
//! // Down the hypotenuse: the fast test may hit or slip through.
//! let edge = oracle.closest_hit(&Ray::new(Vec3A::new(0.5, 0.5, 2.0), -Vec3A::Z));
//! assert!(!edge.is_decidable() && edge.may_miss);
//! ```

use glam::{DVec3, Vec3A};
use quiver_rt::{Hit, Ray, Triangle};
use rayon::prelude::*;

/// The f32 unit roundoff, `2^-24`: the relative error of one rounded f32 operation.
pub const UNIT_ROUNDOFF: f64 = 1.0 / (1u64 << 24) as f64;

/// Barycentric tolerance in units of `ε·κ` (see the module doc).
pub const BARY_K: f64 = 8.0;

/// Distance tolerance in units of `ε·(t + L/|d|)·q/|cos|` (see the module doc).
pub const T_K: f64 = 8.0;

/// Below this `|cos|` between ray and normal a crossing is grazed: ambiguous if it can be hit
/// at all (see the module doc).
pub const COS_MIN: f64 = 1.0 / 4096.0;

/// A barycentric band wider than this marks a crossing as grazed: an f32 test cannot place
/// the point on the triangle to better than a sixteenth of its size.
pub const BAND_CAP: f64 = 1.0 / 16.0;

/// Largest product of lengths an f32 test is judged at (`2^100`, and its reciprocal the
/// smallest): past it, a sum of three such products may overflow, or they lose their digits
/// to subnormals.
const F32_PRODUCTS: f64 = 1.2676506002282294e30;

/// Triangles per culling group. Groups are runs of triangles in Morton order of their
/// centroids, each with a bounding sphere the ray must pass near.
const GROUP: usize = 32;

/// Sphere radii are grown by this factor before the cull: a crossing whose barycentrics are
/// all `>= -BAND_CAP` lies within `(1 + 4·BAND_CAP)` radii of any sphere around the vertices
/// (it is `Σ wᵢ·vᵢ` with `Σ |wᵢ| <= 1 + 4·BAND_CAP`).
const REACH: f64 = 1.0 + 4.0 * BAND_CAP;

fn f64v(p: Vec3A) -> DVec3 {
    DVec3::new(p.x as f64, p.y as f64, p.z as f64)
}

/// A triangle in f64 with what its tolerances need.
#[derive(Clone, Copy, Debug)]
struct Tri {
    v: [DVec3; 3],
    /// `(b - a) × (c - a)`: twice the area, along the normal.
    n: DVec3,
    /// `|n|`.
    n_len: f64,
    /// Longest edge.
    longest: f64,
    /// Bounding sphere.
    center: DVec3,
    radius: f64,
    prim: u32,
}

impl Tri {
    fn new(t: &Triangle, prim: u32) -> Tri {
        let v = t.v.map(f64v);
        let n = (v[1] - v[0]).cross(v[2] - v[0]);
        let longest = (v[1] - v[0])
            .length()
            .max((v[2] - v[1]).length())
            .max((v[0] - v[2]).length());
        let center = (v[0] + v[1] + v[2]) / 3.0;
        let radius = v.iter().map(|p| (*p - center).length()).fold(0.0, f64::max);
        Tri {
            v,
            n,
            n_len: n.length(),
            longest,
            center,
            radius,
            prim,
        }
    }
}

/// A run of triangles (in the oracle's order) and a sphere around all their spheres.
#[derive(Clone, Copy, Debug)]
struct Group {
    center: DVec3,
    radius: f64,
    start: usize,
    end: usize,
}

/// The ray in f64.
struct Line {
    o: DVec3,
    d: DVec3,
    d_len: f64,
    t_min: f64,
    t_max: f64,
}

impl Line {
    fn new(r: &Ray) -> Line {
        let d = f64v(r.dir);
        Line {
            o: f64v(r.origin),
            d,
            d_len: d.length(),
            t_min: r.t_min as f64,
            t_max: r.t_max as f64,
        }
    }

    /// The `t` range over which the line is inside the sphere, if it enters it. NaN input
    /// (a zero direction) enters nothing.
    fn sphere(&self, center: DVec3, radius: f64) -> Option<(f64, f64)> {
        let to = center - self.o;
        let dd = self.d_len * self.d_len;
        let miss2 = to.cross(self.d).length_squared() / dd;
        let r2 = radius * radius;
        (miss2 <= r2).then(|| {
            let mid = to.dot(self.d) / dd;
            let half = (r2 - miss2).sqrt() / self.d_len;
            (mid - half, mid + half)
        })
    }

    /// True when the line passes through the sphere somewhere near `[t_min, t_max]`; the slack
    /// of one diameter keeps crossings whose tolerance reaches across an interval end.
    fn near_sphere(&self, center: DVec3, radius: f64) -> bool {
        self.sphere(center, radius).is_some_and(|(lo, hi)| {
            let slack = 2.0 * radius / self.d_len;
            lo <= self.t_max + slack && hi >= self.t_min - slack
        })
    }
}

/// Where the ray's line crosses one triangle's plane, with the tolerances an f32 test of it
/// carries.
#[derive(Clone, Copy, Debug)]
struct Crossing {
    hit: OracleHit,
    /// `min(w, u, v)`: positive inside, negative outside, in units of the triangle.
    margin: f64,
    /// `|cos|` between ray and normal.
    cos: f64,
    /// The smallest `t` an f32 test might report for this triangle.
    front: f64,
}

impl Crossing {
    /// Written negated so that a NaN (no crossing known) counts as grazed.
    fn grazed(&self) -> bool {
        !(self.cos >= COS_MIN && self.hit.uv_tol <= BAND_CAP)
    }
}

/// The signed-volume test (see the module doc). `None` when the line is parallel to the plane
/// or the triangle has no area.
fn crossing(tri: &Tri, line: &Line, slack: f64) -> Option<Crossing> {
    let [a, b, c] = tri.v.map(|p| p - line.o);
    let bc = b.cross(c);
    let w0 = line.d.dot(bc);
    let w1 = line.d.dot(c.cross(a));
    let w2 = line.d.dot(a.cross(b));
    let s = w0 + w1 + w2;
    if s == 0.0 || !s.is_finite() || tri.n_len == 0.0 {
        return None;
    }
    let t = a.dot(bc) / s;
    let (w, u, v) = (w0 / s, w1 / s, w2 / s);
    let cos = (line.d.dot(tri.n) / (line.d_len * tri.n_len)).abs();
    let dist = a.length().max(b.length()).max(c.length());
    let kappa = dist * tri.longest / (tri.n_len * cos);
    let q = tri.longest * tri.longest / tri.n_len;
    let t_tol = slack * T_K * UNIT_ROUNDOFF * (t.abs() + tri.longest / line.d_len) * q / cos;
    // An f32 test forms products of up to three of these lengths (the fast test's normal
    // `L²`, `n·d`, `d×c`, `n·c`; the watertight test's edge functions and scaled distance);
    // beyond f32's range they overflow or flush to zero and no rounding model holds: any
    // answer near the triangle is admissible, as for a grazed crossing.
    let (l, dd) = (tri.longest, line.d_len);
    let in_f32 = [
        l * l,
        l * l * dd,
        dd * dist,
        dd * dist * l,
        l * l * dist,
        dist * dist * dist,
    ]
    .iter()
    .all(|m| (F32_PRODUCTS.recip()..=F32_PRODUCTS).contains(m));
    let uv_tol = if in_f32 {
        slack * BARY_K * UNIT_ROUNDOFF * kappa
    } else {
        f64::INFINITY
    };
    Some(Crossing {
        hit: OracleHit {
            prim: tri.prim,
            t,
            u,
            v,
            t_tol,
            uv_tol,
        },
        margin: w.min(u).min(v),
        cos,
        front: t - t_tol,
    })
}

/// One triangle crossing: the f64 answer and how far an f32 test of it may stray.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OracleHit {
    /// Index of the triangle in the oracle's input.
    pub prim: u32,
    /// Distance along the ray, in units of its direction.
    pub t: f64,
    /// Barycentric weight of the second vertex.
    pub u: f64,
    /// Barycentric weight of the third vertex.
    pub v: f64,
    /// How far an f32 test's `t` may lie from `t` (absolute); infinite where the f32 plane
    /// may tilt into a hit anywhere near the triangle (see the module doc).
    pub t_tol: f64,
    /// How far an f32 test's `u` and `v` may lie from `u` and `v`: the edge band's width.
    pub uv_tol: f64,
}

impl OracleHit {
    /// Whether `got` is this crossing as an f32 test may report it: the same primitive, `t`,
    /// `u` and `v` within the tolerances.
    ///
    /// ```
    /// use quiver_rt::Hit;
    /// use quiver_lab::oracle::OracleHit;
    /// let want = OracleHit { prim: 3, t: 2.0, u: 0.25, v: 0.5, t_tol: 1e-6, uv_tol: 1e-6 };
    /// assert!(want.matches(&Hit { prim: 3, t: 2.0, u: 0.25, v: 0.5 }));
    /// assert!(!want.matches(&Hit { prim: 3, t: 2.0, u: 0.5, v: 0.25 }));
    /// ```
    pub fn matches(&self, got: &Hit) -> bool {
        // An infinite tolerance (a grazed crossing) accepts anything, even where the oracle
        // has no value to compare with.
        let close = |got: f32, want: f64, tol: f64| {
            tol == f64::INFINITY || (got as f64 - want).abs() <= tol
        };
        got.prim == self.prim
            && close(got.t, self.t, self.t_tol)
            && close(got.u, self.u, self.uv_tol)
            && close(got.v, self.v, self.uv_tol)
    }

    /// How far `got` strays from this crossing as a fraction of the tolerances: `t`'s, and the
    /// larger of `u`'s and `v`'s. Both at most 1 for a match; the tests print the largest seen,
    /// which shows the headroom [`T_K`] and [`BARY_K`] leave.
    ///
    /// ```
    /// use quiver_rt::Hit;
    /// use quiver_lab::oracle::OracleHit;
    /// let want = OracleHit { prim: 0, t: 2.0, u: 0.25, v: 0.5, t_tol: 1e-3, uv_tol: 1e-3 };
    /// let got = Hit { prim: 0, t: 2.0005, u: 0.25, v: 0.49975 };
    /// let (t, uv) = want.deviation(&got);
    /// assert!((t - 0.5).abs() < 0.01 && (uv - 0.25).abs() < 0.01);
    /// ```
    pub fn deviation(&self, got: &Hit) -> (f64, f64) {
        let du = (got.u as f64 - self.u)
            .abs()
            .max((got.v as f64 - self.v).abs());
        ((got.t as f64 - self.t).abs() / self.t_tol, du / self.uv_tol)
    }
}

/// Why a ray's f32 answer cannot be judged exactly: the first reason found, naming the
/// triangle that causes it.
///
/// ```
/// use glam::Vec3A;
/// use quiver_rt::{Ray, Triangle};
/// use quiver_lab::oracle::{Ambiguity, Oracle};
/// let tri = Triangle::new(Vec3A::ZERO, Vec3A::X, Vec3A::Y);
/// let ray = Ray::new(Vec3A::new(0.25, 0.25, 1.0), -Vec3A::Z);
/// let twice = Oracle::new(&[tri, tri]).closest_hit(&ray);
/// assert_eq!(twice.ambiguity, Some(Ambiguity::Tie { prims: (0, 1) }));
/// let ends_there = Ray::segment(ray.origin, ray.dir, 0.0, 1.0);
/// let answer = Oracle::new(&[tri]).closest_hit(&ends_there);
/// assert_eq!(answer.ambiguity, Some(Ambiguity::Interval { prim: 0 }));
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Ambiguity {
    /// A crossing in front of the answer lies within its band of the triangle's boundary
    /// (`|min(w, u, v)| <= uv_tol`).
    Edge {
        /// The triangle whose edge the ray grazes.
        prim: u32,
    },
    /// Two crossings lie within their distance tolerances of each other.
    Tie {
        /// The two triangles, the lower index first.
        prims: (u32, u32),
    },
    /// A crossing lies within its distance tolerance of `t_min` or `t_max`.
    Interval {
        /// The triangle crossed there.
        prim: u32,
    },
    /// The ray passes near a triangle nearly parallel to its plane (`|cos| <` [`COS_MIN`]),
    /// or so ill-conditioned that its band exceeds [`BAND_CAP`].
    Grazing {
        /// The grazed triangle.
        prim: u32,
    },
}

/// The oracle's verdict on one ray.
#[derive(Clone, Debug, PartialEq)]
pub struct Answer {
    /// The exact closest hit (in f64): the nearest crossing inside the closed triangle and
    /// the closed `[t_min, t_max]`, the lower index on equal distance.
    pub hit: Option<OracleHit>,
    /// `None` when the ray is decidable: then [`Answer::hit`] is the only right answer.
    pub ambiguity: Option<Ambiguity>,
    /// Every hit an f32 kernel may report, nearest first (on a decidable ray, just `hit`).
    pub admissible: Vec<OracleHit>,
    /// Whether an f32 kernel may report no hit.
    pub may_miss: bool,
}

impl Answer {
    /// True when exactly one answer is right.
    pub fn is_decidable(&self) -> bool {
        self.ambiguity.is_none()
    }

    /// Checks an f32 kernel's answer: on a decidable ray it must be [`Answer::hit`] (within
    /// the crossing's tolerances) or, for a miss, none; on an ambiguous ray one of
    /// [`Answer::admissible`], or none where [`Answer::may_miss`].
    ///
    /// ```
    /// use glam::Vec3A;
    /// use quiver_rt::{Ray, Triangle};
    /// use quiver_lab::oracle::Oracle;
    /// let tri = Triangle::new(Vec3A::ZERO, Vec3A::X, Vec3A::Y);
    /// let ray = Ray::new(Vec3A::new(0.25, 0.5, 2.0), -Vec3A::Z);
    /// let answer = Oracle::new(&[tri]).closest_hit(&ray);
    /// let got = tri.intersect(&ray).map(|h| quiver_rt::Hit { t: h.t, prim: 0, u: h.u, v: h.v });
    /// assert!(answer.check(got).is_ok());
    /// assert!(answer.check(None).is_err());
    /// ```
    ///
    /// # Errors
    /// [`Mismatch`] naming the kernel's answer and the oracle's.
    pub fn check(&self, got: Option<Hit>) -> Result<(), Mismatch> {
        match got {
            None if self.may_miss => Ok(()),
            Some(h) if self.admissible.iter().any(|a| a.matches(&h)) => Ok(()),
            _ => Err(Mismatch {
                got,
                oracle: self.clone(),
            }),
        }
    }
}

/// An f32 kernel's answer the oracle does not admit ([`Answer::check`]).
#[derive(Clone, Debug, PartialEq)]
pub struct Mismatch {
    /// What the kernel answered.
    pub got: Option<Hit>,
    /// The oracle's verdict on the ray.
    pub oracle: Answer,
}

impl std::fmt::Display for Mismatch {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match &self.got {
            None => write!(f, "no hit; oracle: {:?}", self.oracle),
            Some(h) => write!(f, "{h:?}; oracle: {:?}", self.oracle),
        }
    }
}

impl std::error::Error for Mismatch {}

/// The oracle over a set of triangles: f64 copies grouped for culling. Non-finite triangles
/// are left out (they are invisible to quiver too).
///
/// ```
/// use glam::Vec3A;
/// use quiver_rt::{Ray, Triangle};
/// use quiver_lab::oracle::Oracle;
/// let near = Triangle::new(Vec3A::new(-1.0, -1.0, 1.0), Vec3A::new(3.0, -1.0, 1.0), Vec3A::new(-1.0, 3.0, 1.0));
/// let far = Triangle::new(Vec3A::new(-1.0, -1.0, 5.0), Vec3A::new(3.0, -1.0, 5.0), Vec3A::new(-1.0, 3.0, 5.0));
/// let oracle = Oracle::new(&[far, near]);
/// let answers = oracle.closest_hits(&[Ray::new(Vec3A::ZERO, Vec3A::Z), Ray::new(Vec3A::ZERO, -Vec3A::Z)]);
/// assert_eq!(answers[0].hit.map(|h| (h.prim, h.t)), Some((1, 1.0)));
/// assert!(answers[1].hit.is_none() && answers[1].is_decidable());
/// ```
#[derive(Clone, Debug)]
pub struct Oracle {
    tris: Vec<Tri>,
    groups: Vec<Group>,
    /// The factor the f32 bands are widened by (1 for a kernel that tests these very
    /// triangles).
    slack: f64,
}

impl Oracle {
    /// Prepares `tris`: f64 copies in Morton order of their centroids, in groups of 32 with
    /// bounding spheres.
    pub fn new(tris: &[Triangle]) -> Oracle {
        Oracle::with_slack(tris, 1.0)
    }

    /// [`Oracle::new`] for a kernel whose arithmetic rounds `slack` times as much as an f32
    /// test of these triangles: every band (`t_tol`, `uv_tol`) widened by that factor. For an
    /// instanced scene judged against its flattened triangles: the kernel tests each
    /// instance's object-space triangles with the ray brought there by the inverse transform,
    /// and both that ray and the flattened triangles carry the transforms' rounding.
    ///
    /// ```
    /// use glam::Vec3A;
    /// use quiver_rt::{Ray, Triangle};
    /// use quiver_lab::oracle::Oracle;
    /// let tri = [Triangle::new(Vec3A::ZERO, Vec3A::X, Vec3A::Y)];
    /// let ray = Ray::new(Vec3A::new(0.25, 0.25, 1.0), -Vec3A::Z);
    /// let (one, four) = (Oracle::new(&tri).closest_hit(&ray), Oracle::with_slack(&tri, 4.0).closest_hit(&ray));
    /// assert_eq!(four.hit.unwrap().t_tol, 4.0 * one.hit.unwrap().t_tol);
    /// ```
    pub fn with_slack(tris: &[Triangle], slack: f64) -> Oracle {
        let mut tris: Vec<Tri> = tris
            .iter()
            .enumerate()
            .filter(|(_, t)| t.is_finite())
            .map(|(i, t)| Tri::new(t, i as u32))
            .collect();
        let (lo, hi) = tris.iter().fold(
            (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
            |(lo, hi), t| (lo.min(t.center), hi.max(t.center)),
        );
        let scale = (hi - lo).max(DVec3::splat(f64::MIN_POSITIVE));
        tris.sort_by_cached_key(|t| morton((t.center - lo) / scale));
        let groups = (0..tris.len())
            .step_by(GROUP)
            .map(|start| {
                let end = (start + GROUP).min(tris.len());
                let (lo, hi) = tris[start..end].iter().flat_map(|t| t.v).fold(
                    (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
                    |(lo, hi), p| (lo.min(p), hi.max(p)),
                );
                let center = (lo + hi) * 0.5;
                // Around the triangles' spheres, not just their vertices, so that grown by
                // REACH it holds each triangle's sphere grown alike: the cull never drops a
                // triangle the per-triangle tests would look at.
                let radius = tris[start..end]
                    .iter()
                    .map(|t| (t.center - center).length() + t.radius)
                    .fold(0.0, f64::max);
                Group {
                    center,
                    radius,
                    start,
                    end,
                }
            })
            .collect();
        Oracle {
            tris,
            groups,
            slack,
        }
    }

    /// The verdict on one ray (see the module doc).
    ///
    /// ```
    /// use glam::Vec3A;
    /// use quiver_rt::{Ray, Triangle};
    /// use quiver_lab::oracle::Oracle;
    /// let oracle = Oracle::new(&[Triangle::new(Vec3A::ZERO, Vec3A::X, Vec3A::Y)]);
    /// // t in units of the direction: a direction of length 2 meets the plane at t = 0.5.
    /// let ray = Ray::new(Vec3A::new(0.25, 0.25, 1.0), Vec3A::new(0.0, 0.0, -2.0));
    /// assert_eq!(oracle.closest_hit(&ray).hit.unwrap().t, 0.5);
    /// // Clearly outside [t_min, t_max]: a decidable miss.
    /// let late = oracle.closest_hit(&Ray::segment(ray.origin, ray.dir, 0.75, 2.0));
    /// assert!(late.hit.is_none() && late.is_decidable());
    /// ```
    pub fn closest_hit(&self, ray: &Ray) -> Answer {
        let line = Line::new(ray);
        let mut found = Vec::new();
        for g in &self.groups {
            if !line.near_sphere(g.center, g.radius * REACH) {
                continue;
            }
            for tri in &self.tris[g.start..g.end] {
                Self::visit(tri, &line, self.slack, &mut found);
            }
        }
        judge(&line, found)
    }

    /// [`Oracle::closest_hit`] for every ray, in parallel.
    pub fn closest_hits(&self, rays: &[Ray]) -> Vec<Answer> {
        rays.par_iter().map(|r| self.closest_hit(r)).collect()
    }

    /// Adds the triangle's crossing to `found` when an f32 test might report it: inside or
    /// within its band, within its tolerance of the interval, or grazed near the ray.
    fn visit(tri: &Tri, line: &Line, slack: f64, found: &mut Vec<Crossing>) {
        let x = crossing(tri, line, slack);
        // Where the barycentrics are known to within the triangle's size, they decide. The
        // line must also pass near the triangle's grown sphere, which lies inside its group's:
        // then the group cull drops nothing this accepts. (Within BAND_CAP the crossing lies
        // in that sphere anyway; past it, that is the oracle's reach.)
        if let Some(x) = x.filter(|x| x.hit.uv_tol <= 1.0) {
            let h = x.hit;
            if x.margin >= -h.uv_tol
                && h.t >= line.t_min - h.t_tol
                && h.t <= line.t_max + h.t_tol
                && line.near_sphere(tri.center, tri.radius * REACH)
            {
                found.push(x);
            }
            return;
        }
        // Too ill-conditioned, parallel in f64 or without area: an f32 rounding may tilt the
        // plane into a hit anywhere the line runs near the triangle, at a distance no better
        // known.
        if !line.near_sphere(tri.center, tri.radius * REACH) {
            return;
        }
        let Some((entry, _)) = line.sphere(tri.center, tri.radius * REACH) else {
            return;
        };
        let (t, u, v, margin, cos) = x.map_or((entry, f64::NAN, f64::NAN, f64::NAN, 0.0), |x| {
            (x.hit.t, x.hit.u, x.hit.v, x.margin, x.cos)
        });
        // Where the crossing's own distance bound reaches further forward than the sphere
        // (a near-parallel ray: `n·c` and `n·d` both cancel, and f32 has reported t = 0 for a
        // crossing at t = -0.19 with the triangle 2e6 away), that bound is what a test may do.
        let front = x.map_or(entry, |x| entry.min(x.front));
        found.push(Crossing {
            hit: OracleHit {
                prim: tri.prim,
                t,
                u,
                v,
                t_tol: f64::INFINITY,
                uv_tol: f64::INFINITY,
            },
            margin,
            cos,
            front,
        });
    }

    /// The oracle without its culling: every triangle tested. For checking the cull.
    #[cfg(test)]
    fn closest_hit_unculled(&self, ray: &Ray) -> Answer {
        let line = Line::new(ray);
        let mut found = Vec::new();
        for tri in &self.tris {
            Self::visit(tri, &line, self.slack, &mut found);
        }
        judge(&line, found)
    }
}

/// The verdict from the crossings an f32 test might report.
fn judge(line: &Line, mut found: Vec<Crossing>) -> Answer {
    let order = |a: &OracleHit, b: &OracleHit| a.t.total_cmp(&b.t).then(a.prim.cmp(&b.prim));
    found.sort_by(|a, b| order(&a.hit, &b.hit));
    let exact = found
        .iter()
        .filter(|x| x.margin >= 0.0 && x.hit.t >= line.t_min && x.hit.t <= line.t_max)
        .map(|x| x.hit)
        .next();
    let firm = |x: &Crossing| {
        let h = &x.hit;
        !x.grazed()
            && x.margin > h.uv_tol
            && h.t - h.t_tol > line.t_min
            && h.t + h.t_tol < line.t_max
    };
    let first_firm = found.iter().find(|x| firm(x)).map(|x| x.hit);
    // Everything that could be reported in front of (or tied with) the first firm hit.
    let reach = first_firm.map_or(f64::INFINITY, |h| h.t + h.t_tol);
    let admissible: Vec<Crossing> = found.into_iter().filter(|x| x.front <= reach).collect();
    let ambiguity = admissible
        .iter()
        .find(|x| Some(x.hit) != first_firm)
        .map(|x| {
            let h = x.hit;
            if x.grazed() {
                Ambiguity::Grazing { prim: h.prim }
            } else if x.margin.abs() <= h.uv_tol {
                Ambiguity::Edge { prim: h.prim }
            } else if (h.t - line.t_min).abs() <= h.t_tol || (h.t - line.t_max).abs() <= h.t_tol {
                Ambiguity::Interval { prim: h.prim }
            } else {
                let first = first_firm.map_or(h.prim, |f| f.prim);
                Ambiguity::Tie {
                    prims: (first.min(h.prim), first.max(h.prim)),
                }
            }
        });
    Answer {
        hit: exact,
        ambiguity,
        admissible: admissible.iter().map(|x| x.hit).collect(),
        may_miss: first_firm.is_none(),
    }
}

/// Morton code of a point in the unit cube, 21 bits per axis.
fn morton(p: DVec3) -> u64 {
    let spread = |x: f64| {
        let mut v = (x.clamp(0.0, 1.0) * ((1u64 << 21) - 1) as f64) as u64;
        v = (v | v << 32) & 0x1f00000000ffff;
        v = (v | v << 16) & 0x1f0000ff0000ff;
        v = (v | v << 8) & 0x100f00f00f00f00f;
        v = (v | v << 4) & 0x10c30c30c30c30c3;
        (v | v << 2) & 0x1249249249249249
    };
    spread(p.x) | spread(p.y) << 1 | spread(p.z) << 2
}

#[cfg(test)]
mod tests {
    use super::*;
    use quiver_scenes::Scene;

    fn v(x: f32, y: f32, z: f32) -> Vec3A {
        Vec3A::new(x, y, z)
    }

    fn hit(prim: u32, t: f32, u: f32, v: f32) -> Option<Hit> {
        Some(Hit { t, prim, u, v })
    }

    /// Two triangles sharing the edge x = 0 in the plane z = 0, and a large one at z = -3.
    fn scene() -> [Triangle; 3] {
        [
            Triangle::new(v(0.0, -1.0, 0.0), v(0.0, 1.0, 0.0), v(-1.0, 0.0, 0.0)),
            Triangle::new(v(0.0, -1.0, 0.0), v(1.0, 0.0, 0.0), v(0.0, 1.0, 0.0)),
            Triangle::new(v(-5.0, -5.0, -3.0), v(5.0, -5.0, -3.0), v(0.0, 5.0, -3.0)),
        ]
    }

    #[test]
    fn u_weighs_the_second_vertex_and_v_the_third() {
        let tri = Triangle::new(v(1.0, 1.0, 1.0), v(5.0, 1.0, 1.0), v(1.0, 3.0, 1.0));
        let a = Oracle::new(&[tri]).closest_hit(&Ray::new(v(2.0, 2.0, 3.0), v(0.0, 0.0, -0.5)));
        let h = a.hit.unwrap();
        assert_eq!((h.prim, h.t, h.u, h.v), (0, 4.0, 0.25, 0.5));
        assert!(a.is_decidable() && !a.may_miss);
        assert_eq!(a.admissible, vec![h]);
        // Near and head-on: t to a few millionths, u and v to about one.
        assert!(h.t_tol < 5e-6 * h.t && h.uv_tol < 1e-6, "{h:?}");
        assert!(a.check(hit(0, 4.0, 0.25, 0.5)).is_ok());
        assert!(a.check(hit(0, 4.0, 0.5, 0.25)).is_err(), "u and v swapped");
        assert!(a.check(hit(0, 4.001, 0.25, 0.5)).is_err(), "t off");
        assert!(
            a.check(hit(1, 4.0, 0.25, 0.5)).is_err(),
            "another primitive"
        );
        assert!(a.check(None).is_err(), "a miss");
    }

    #[test]
    fn decidable_rays_and_misses() {
        let o = Oracle::new(&scene());
        let inside = o.closest_hit(&Ray::new(v(0.5, 0.0, 1.0), -Vec3A::Z));
        assert!(inside.is_decidable());
        assert_eq!(inside.hit.map(|h| (h.prim, h.t)), Some((1, 1.0)));
        let behind = o.closest_hit(&Ray::new(v(0.5, 0.0, 1.0), Vec3A::Z));
        assert!(behind.is_decidable() && behind.hit.is_none() && behind.may_miss);
        assert!(behind.check(None).is_ok() && behind.check(hit(1, 1.0, 0.0, 0.0)).is_err());
        // Past the small pair, onto the large triangle.
        let far = o.closest_hit(&Ray::new(v(3.0, -2.0, 1.0), -Vec3A::Z));
        assert!(far.is_decidable());
        assert_eq!(far.hit.map(|h| (h.prim, h.t)), Some((2, 4.0)));
    }

    #[test]
    fn edges_ties_interval_ends_and_grazes_are_ambiguous() {
        let o = Oracle::new(&scene());
        // Down the shared edge: either triangle, or (a fast test slipping through) the one
        // behind, but never a miss.
        let edge = o.closest_hit(&Ray::new(v(0.0, 0.25, 1.0), -Vec3A::Z));
        assert!(
            matches!(edge.ambiguity, Some(Ambiguity::Edge { .. })),
            "{edge:?}"
        );
        assert!(!edge.may_miss);
        for prim in [0, 1] {
            assert!(edge
                .check(hit(prim, 1.0, 0.375, 0.0).map(|mut h| {
                    (h.u, h.v) = if prim == 0 {
                        (0.625, 0.0)
                    } else {
                        (0.0, 0.625)
                    };
                    h
                }))
                .is_ok());
        }
        assert!(edge.admissible.iter().any(|h| h.prim == 2));
        assert!(edge.check(None).is_err());
        // Just off the edge by less than the band, and by clearly more.
        let near = o.closest_hit(&Ray::new(v(1e-7, 0.25, 1.0), -Vec3A::Z));
        assert!(matches!(near.ambiguity, Some(Ambiguity::Edge { .. })));
        let off = o.closest_hit(&Ray::new(v(1e-3, 0.25, 1.0), -Vec3A::Z));
        assert!(off.is_decidable());

        // Two copies of a triangle: a tie, either index is right, a miss is not.
        let tri = scene()[1];
        let tie = Oracle::new(&[tri, tri]).closest_hit(&Ray::new(v(0.5, 0.0, 1.0), -Vec3A::Z));
        assert_eq!(tie.ambiguity, Some(Ambiguity::Tie { prims: (0, 1) }));
        assert!(tie.check(hit(1, 1.0, 0.5, 0.25)).is_ok() && tie.check(None).is_err());

        // A segment ending on the triangle: in or out of [t_min, t_max] by a rounding.
        let end = o.closest_hit(&Ray::segment(v(0.5, 0.0, 1.0), -Vec3A::Z, 0.0, 1.0));
        assert_eq!(end.ambiguity, Some(Ambiguity::Interval { prim: 1 }));
        assert!(end.may_miss && end.check(hit(1, 1.0, 0.5, 0.25)).is_ok());
        let start = o.closest_hit(&Ray::segment(v(0.5, 0.0, 1.0), -Vec3A::Z, 1.0, 5.0));
        assert_eq!(start.ambiguity, Some(Ambiguity::Interval { prim: 1 }));
        assert!(!start.may_miss, "the large triangle is behind");

        // Nearly in the plane of the large triangle, crossing it in the middle.
        let graze = o.closest_hit(&Ray::new(v(-1.0, 0.0, -3.0 + 1e-5), v(1.0, 0.0, -1e-5)));
        assert_eq!(graze.ambiguity, Some(Ambiguity::Grazing { prim: 2 }));
        // In its plane: parallel in f64, and an f32 test might still tilt into it.
        let flat = o.closest_hit(&Ray::new(v(-6.0, 0.0, -3.0), Vec3A::X));
        assert_eq!(flat.ambiguity, Some(Ambiguity::Grazing { prim: 2 }));
        assert!(flat.may_miss && flat.check(hit(2, 6.0, 0.3, 0.3)).is_ok());
    }

    /// The group cull changes no verdict: the same answers as testing every triangle, over
    /// random rays, short segments, axis-parallel rays and rays aimed at vertices and edges.
    #[test]
    fn culling_changes_no_verdict() {
        let scene = Scene::load("soup300").unwrap();
        let tris = scene.triangles();
        let o = Oracle::new(&tris);
        let mut rays = crate::rays::random_rays(&scene.bounds(), 3_000, 5);
        rays.extend(crate::rays::camera_rays(&scene.camera, 32));
        let n = rays.len();
        for i in 0..n {
            let r = rays[i];
            let (t0, t1) = (0.01 * (i % 5) as f32, 0.1 * (i % 7) as f32);
            rays.push(Ray::segment(r.origin, r.dir, t0, t1));
            let axis = Vec3A::AXES[i % 3] * if i % 2 == 0 { 1.0 } else { -1.0 };
            rays.push(Ray::new(r.origin, axis));
            let t = tris[i % tris.len()].v;
            let aim = [t[0], (t[0] + t[1]) * 0.5][i % 2];
            rays.push(Ray::new(r.origin, aim - r.origin));
        }
        let mut ambiguous = 0;
        for r in &rays {
            let a = o.closest_hit(r);
            assert_eq!(a, o.closest_hit_unculled(r), "{r:?}");
            ambiguous += !a.is_decidable() as usize;
        }
        assert!(
            ambiguous > 100,
            "{ambiguous} ambiguous rays: the band is not exercised"
        );
    }

    /// Non-finite triangles are invisible, as in quiver; a degenerate one is never a firm hit.
    #[test]
    fn non_finite_and_degenerate_triangles() {
        let mut tris = scene().to_vec();
        tris.insert(
            0,
            Triangle::new(v(f32::NAN, 0.0, 0.0), v(1.0, 0.0, 0.0), v(0.0, 1.0, 0.0)),
        );
        tris.insert(
            0,
            Triangle::new(v(0.0, 0.0, 0.5), v(1.0, 0.0, 0.5), v(2.0, 0.0, 0.5)),
        );
        let o = Oracle::new(&tris);
        let a = o.closest_hit(&Ray::new(v(0.5, 0.0, 1.0), -Vec3A::Z));
        assert_eq!(a.hit.map(|h| h.prim), Some(3));
        assert!(a.admissible.iter().all(|h| h.prim != 1));
        assert_eq!(a.ambiguity, Some(Ambiguity::Grazing { prim: 0 }));
    }
}
