//! [`Triangle`] and its Möller–Trumbore test, with the cold path that retakes the test in a
//! power-of-two frame when a product leaves f32's range.

use super::scale::{exponent, scale2};
use super::{Aabb, PrimHit, Ray};
use glam::Vec3A;

/// A triangle given by its three vertices.
///
/// ```
/// use quiver_rt::{Ray, Triangle};
/// use glam::Vec3A;
/// let tri = Triangle::new(Vec3A::ZERO, Vec3A::X, Vec3A::Y);
/// let hit = tri.intersect(&Ray::new(Vec3A::new(0.25, 0.25, -1.0), Vec3A::Z)).unwrap();
/// assert_eq!(hit.t, 1.0);
/// assert_eq!((hit.u, hit.v), (0.25, 0.25));
/// // u weighs the second vertex (here +x), v the third (+y).
/// let hit = tri.intersect(&Ray::new(Vec3A::new(0.5, 0.25, 1.0), -Vec3A::Z)).unwrap();
/// assert_eq!((hit.u, hit.v), (0.5, 0.25));
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Triangle {
    /// The vertices; barycentric `u` weighs `v[1]`, `v` weighs `v[2]`.
    pub v: [Vec3A; 3],
}

impl Triangle {
    /// A triangle from its vertices.
    #[inline]
    pub fn new(a: Vec3A, b: Vec3A, c: Vec3A) -> Self {
        Triangle { v: [a, b, c] }
    }

    /// The bounding box of the three vertices.
    #[inline]
    pub fn bounds(&self) -> Aabb {
        Aabb {
            min: self.v[0].min(self.v[1]).min(self.v[2]),
            max: self.v[0].max(self.v[1]).max(self.v[2]),
        }
    }

    /// True when every vertex coordinate is finite. Non-finite triangles are invisible.
    #[inline]
    pub fn is_finite(&self) -> bool {
        self.v.iter().all(|p| p.is_finite())
    }

    /// Möller–Trumbore ray/triangle test, two-sided, in its geometric-normal form (as Embree
    /// writes it). Returns the hit when `t` lies in `[ray.t_min, ray.t_max]` and the
    /// barycentrics lie in the closed triangle.
    ///
    /// `t` is the plane distance `n·(v0 - o) / n·d` with both dot products sharing one normal
    /// `n`, so `t` is the exact distance to a plane rotated by the rounding of `n` about `v0`.
    /// The textbook form (`e2·(s×e1) / det`) divides two differently rounded triple products
    /// and loses digits at grazing angles (seen against obvhs and f64: 4e-5 relative error).
    ///
    /// Degenerate triangles (zero area) never hit: their determinant is zero. Every comparison
    /// is written so that a NaN rejects the hit.
    ///
    /// # Numbers at the edge of f32
    ///
    /// The test multiplies up to three lengths (`n·c`), so on its own it would overflow for
    /// triangles beyond about `1e12` and lose `t` below about `1e-12`. When the determinant,
    /// `u`, `v` or `t` comes out of range (non-finite, or a determinant or `t` numerator
    /// below `2^-100`, a product that may have underflowed), a cold path takes the test again
    /// with the vertices and origin scaled by a power of two that brings the triangle near
    /// unit size, and the direction near unit length (exact in f32; `t` scaled back exactly),
    /// as a [`crate::Bvh`] over such a scene traces it. So for every finite input the test
    /// returns a finite `t` or a miss, and it hits wherever the triangle scaled to unit size
    /// is hit: from `1e-30` to `1e35` and beyond. Ordinary inputs never take the cold path
    /// (except a ray exactly parallel to the plane, which it finds parallel again). Still
    /// missed: a triangle whose area underflows even at unit size (a sliver of relative width
    /// below `2^-120`), and one more than `2^100` times smaller than its distance from the
    /// ray's origin (the ray cannot aim at it in f32).
    ///
    /// ```
    /// use quiver_rt::{Ray, Triangle};
    /// use glam::Vec3A;
    /// // Sizes from about 1e-30 to 1e35, powers of two so that the expected values are exact.
    /// for s in [-100, 0, 50, 100, 116].map(|e| 2f32.powi(e)) {
    ///     let tri = Triangle::new(Vec3A::ZERO, Vec3A::X * s, Vec3A::Y * s);
    ///     let ray = Ray::new(Vec3A::new(0.25 * s, 0.25 * s, -s), Vec3A::Z);
    ///     let hit = tri.intersect(&ray).unwrap();
    ///     assert_eq!((hit.t, hit.u, hit.v), (s, 0.25, 0.25));
    /// }
    /// ```
    #[inline(always)]
    pub fn intersect(&self, ray: &Ray) -> Option<PrimHit> {
        // Determinants and `t` numerators in this band are clear of overflow and underflow.
        const SMALL: f32 = 1.0 / (1u128 << 100) as f32;
        const LARGE: f32 = (1u128 << 100) as f32;
        let e1 = self.v[0] - self.v[1];
        let e2 = self.v[2] - self.v[0];
        let n = e1.cross(e2);
        let det = n.dot(ray.dir);
        if !(det.abs() >= SMALL && det.abs() <= LARGE) {
            // Zero (parallel or degenerate), underflowed, overflowed or NaN.
            return self.intersect_rescaled(ray);
        }
        let inv = 1.0 / det;
        let c = self.v[0] - ray.origin;
        let r = ray.dir.cross(c);
        let u = r.dot(e2) * inv;
        let v = r.dot(e1) * inv;
        if !(u >= 0.0 && v >= 0.0 && u + v <= 1.0) {
            // A product that overflowed makes `u` or `v` infinite or NaN.
            if ((u + v) * 0.0).is_nan() {
                return self.intersect_rescaled(ray);
            }
            return None;
        }
        let tn = n.dot(c);
        let t = tn * inv;
        if !(t.is_finite() && tn.abs() >= SMALL) {
            // Overflowed, or possibly underflowed (also an origin on the plane: t = 0).
            return self.intersect_rescaled(ray);
        }
        if t >= ray.t_min && t <= ray.t_max {
            Some(PrimHit { t, u, v })
        } else {
            None
        }
    }

    /// [`Triangle::intersect`] on the triangle and ray in their [`unit_frame`]: the test's
    /// own operations, unchecked (in that frame nothing leaves f32's range), and `t` scaled
    /// back.
    #[cold]
    #[inline(never)]
    fn intersect_rescaled(&self, ray: &Ray) -> Option<PrimHit> {
        let (tri, local, e) = unit_frame(self, ray)?;
        let e1 = tri.v[0] - tri.v[1];
        let e2 = tri.v[2] - tri.v[0];
        let n = e1.cross(e2);
        let det = n.dot(local.dir);
        if det == 0.0 {
            return None;
        }
        let inv = 1.0 / det;
        let c = tri.v[0] - local.origin;
        let r = local.dir.cross(c);
        let u = r.dot(e2) * inv;
        let v = r.dot(e1) * inv;
        if !(u >= 0.0 && v >= 0.0 && u + v <= 1.0) {
            return None;
        }
        let t = scale2(scale2(n.dot(c) * inv, e / 2), e - e / 2);
        (t.is_finite() && t >= ray.t_min && t <= ray.t_max).then_some(PrimHit { t, u, v })
    }
}

/// The triangle and ray scaled by powers of two for a test whose products of lengths would
/// leave f32's range: the vertices and origin by the one that brings the triangle's extent
/// near 1 (but no coordinate past `2^100`), the direction by the one that brings it near
/// unit length, the ray's interval opened to everything. Returns them with `e`: a distance
/// found in the frame is `2^e` times as long in world units. Both factors are exact, and the
/// triangle tests commute with them. `None` when no test can hit: a non-finite or zero
/// direction, a non-finite origin or vertex, a triangle that is a point.
pub(crate) fn unit_frame(tri: &Triangle, ray: &Ray) -> Option<(Triangle, Ray, i32)> {
    let b = tri.bounds();
    let reach = b.min.abs().max(b.max.abs()).max_element();
    let reach = reach.max(ray.origin.abs().max_element());
    let m = ray.dir.abs().max_element();
    if !(tri.is_finite() && reach.is_finite() && m.is_finite() && m > 0.0) {
        return None;
    }
    // Halves first: the extent of a triangle spanning -3e38..3e38 is not an f32.
    let half = (b.max * 0.5 - b.min * 0.5).max_element();
    if half == 0.0 {
        return None;
    }
    let k = (exponent(half) + 1).max(exponent(reach) - 100);
    let j = exponent(m);
    let scale = |p: Vec3A, e: i32| Vec3A::new(scale2(p.x, e), scale2(p.y, e), scale2(p.z, e));
    let local = Ray {
        origin: scale(ray.origin, -k),
        dir: scale(ray.dir, -j),
        t_min: f32::NEG_INFINITY,
        t_max: f32::INFINITY,
        ..*ray
    };
    Some((
        Triangle {
            v: tri.v.map(|p| scale(p, -k)),
        },
        local,
        k - j,
    ))
}

impl Triangle {
    /// The point of the (closed) triangle nearest `p`, with its barycentrics `(u, v)` (`u`
    /// weighs `v[1]`, `v` weighs `v[2]`; the point is `v[0] + u·(v[1] - v[0]) + v·(v[2] -
    /// v[0])`, both in `[0, 1]`, `u + v <= 1`).
    ///
    /// Ericson's region method (Real-Time Collision Detection, 5.1.5) in f32: the Voronoi
    /// region of `p` (a vertex, an edge or the face) is decided from dot products of the edges
    /// with `p` relative to the vertices. The edges and `p - v[0]` are first brought near unit
    /// size by one power of two (exact), so the products of up to four lengths the test takes
    /// neither overflow nor underflow at any scale. A sliver (an angle at `v[0]` whose sine is
    /// below 1/8), a degenerate triangle, or a face region whose barycentrics round out of the
    /// triangle takes a cold path in f64 instead (the plane projection where it lies inside,
    /// else the nearest point of the three edges): in f32 the region test's products of nearly
    /// parallel edges cancel. The answer always lies on the triangle.
    ///
    /// For a non-finite `p` or triangle the answer is `v[0]` with `(0, 0)`, or NaN: callers
    /// that care check [`Triangle::is_finite`] and `p` first (the BVH queries do).
    ///
    /// ```
    /// use quiver_rt::Triangle;
    /// use glam::Vec3A;
    /// let tri = Triangle::new(Vec3A::ZERO, Vec3A::X, Vec3A::Y);
    /// // Above the face: straight down onto it.
    /// assert_eq!(tri.closest_point(Vec3A::new(0.25, 0.5, 3.0)), (Vec3A::new(0.25, 0.5, 0.0), 0.25, 0.5));
    /// // Beyond the second vertex: the vertex itself.
    /// assert_eq!(tri.closest_point(Vec3A::new(2.0, -1.0, 0.0)), (Vec3A::X, 1.0, 0.0));
    /// // Beside the hypotenuse: its midpoint.
    /// assert_eq!(tri.closest_point(Vec3A::new(1.0, 1.0, 0.0)), (Vec3A::new(0.5, 0.5, 0.0), 0.5, 0.5));
    /// ```
    pub fn closest_point(&self, p: Vec3A) -> (Vec3A, f32, f32) {
        let (a, ab, ac) = (self.v[0], self.v[1] - self.v[0], self.v[2] - self.v[0]);
        let (u, v) = closest_uv(a, ab, ac, p);
        (a + ab * u + ac * v, u, v)
    }
}

/// The barycentrics of the point nearest `p` on the triangle with vertex `a` and edges `ab`,
/// `ac` (see [`Triangle::closest_point`], which this is, given the edges: the wide layouts
/// store exactly these edges).
#[inline]
pub(crate) fn closest_uv(a: Vec3A, ab: Vec3A, ac: Vec3A, p: Vec3A) -> (f32, f32) {
    let ap = p - a;
    let m = ab.abs().max(ac.abs()).max(ap.abs()).max_element();
    if !(m > 0.0 && m.is_finite()) {
        // `p` on a point-triangle, or something non-finite.
        return (0.0, 0.0);
    }
    // One exact power of two: the largest length near 1 (a subnormal `m` in two steps).
    let e = -exponent(m);
    let s = |w: Vec3A| Vec3A::new(scale2(w.x, e), scale2(w.y, e), scale2(w.z, e));
    let (ab, ac, ap) = (s(ab), s(ac), s(ap));
    regions(wide(ab), wide(ac), wide(ap)).unwrap_or_else(|| closest_uv_wide(ab, ac, ap))
}

/// `v` in f64.
#[inline]
fn wide(v: Vec3A) -> glam::DVec3 {
    glam::DVec3::new(v.x as f64, v.y as f64, v.z as f64)
}

/// Ericson's region test on unit-sized inputs, in f64: its dot products of differences
/// cancel, and in f32 a point a few thousandths of the triangle's size from its face could
/// come back nine f32 epsilons of the size away. `None` for a sliver (the
/// sine of the angle at `a` below 1/8: the face and edge regions' decisions cancel there, see
/// [`closest_uv_wide`]) and where the face region's barycentrics come out of the triangle.
#[inline]
fn regions(ab: glam::DVec3, ac: glam::DVec3, ap: glam::DVec3) -> Option<(f32, f32)> {
    let n = ab.cross(ac);
    // Also NaN (an overflowed product): the f64 path decides.
    let face = n.length_squared() * 64.0 > ab.length_squared() * ac.length_squared();
    if !face {
        return None;
    }
    let d1 = ab.dot(ap);
    let d2 = ac.dot(ap);
    if d1 <= 0.0 && d2 <= 0.0 {
        return Some((0.0, 0.0));
    }
    let bp = ap - ab;
    let d3 = ab.dot(bp);
    let d4 = ac.dot(bp);
    if d3 >= 0.0 && d4 <= d3 {
        return Some((1.0, 0.0));
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return Some((clamp01(d1 / (d1 - d3)) as f32, 0.0));
    }
    let cp = ap - ac;
    let d5 = ab.dot(cp);
    let d6 = ac.dot(cp);
    if d6 >= 0.0 && d5 <= d6 {
        return Some((0.0, 1.0));
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return Some((0.0, clamp01(d2 / (d2 - d6)) as f32));
    }
    let va = d3 * d6 - d5 * d4;
    let (p, q) = (d4 - d3, d5 - d6);
    if va <= 0.0 && p >= 0.0 && q >= 0.0 {
        let w = clamp01(p / (p + q));
        return Some(((1.0 - w) as f32, w as f32));
    }
    let denom = 1.0 / (va + vb + vc);
    let (v, w) = (vb * denom, vc * denom);
    (v >= 0.0 && w >= 0.0 && v + w <= 1.0).then_some((v as f32, w as f32))
}

/// `x` in `[0, 1]`; 0 for NaN (a zero-length edge).
#[inline]
fn clamp01(x: f64) -> f64 {
    if x > 0.0 {
        x.min(1.0)
    } else {
        0.0
    }
}

/// The closest point's barycentrics for a sliver or a degenerate triangle (unit-sized
/// inputs), in f64: the f32 products of nearly parallel edges cancel (the region test's
/// `va`, `vb`, `vc` lose digits as the square of the sliver's aspect ratio, the cross product
/// as its first power), and in f64 they keep 29 more bits. The projection onto the plane
/// where its barycentrics (cross products with the normal) lie in the triangle, else the
/// nearest point of the three edges.
#[cold]
#[inline(never)]
fn closest_uv_wide(ab: Vec3A, ac: Vec3A, ap: Vec3A) -> (f32, f32) {
    let (ab, ac, ap) = (wide(ab), wide(ac), wide(ap));
    let n = ab.cross(ac);
    let nn = n.length_squared();
    let (mut u, mut v) = (-1.0, -1.0);
    if nn > 0.0 {
        u = ap.cross(ac).dot(n) / nn;
        v = ab.cross(ap).dot(n) / nn;
    }
    if !(u >= 0.0 && v >= 0.0 && u + v <= 1.0) {
        // The segment from `o` along `d`: its parameter nearest `ap`.
        let along = |o: glam::DVec3, d: glam::DVec3| {
            let t = (ap - o).dot(d) / d.length_squared();
            if t > 0.0 {
                t.min(1.0)
            } else {
                0.0
            }
        };
        let (t_ab, t_ac, t_bc) = (
            along(glam::DVec3::ZERO, ab),
            along(glam::DVec3::ZERO, ac),
            along(ab, ac - ab),
        );
        let mut best = f64::INFINITY;
        for (cu, cv) in [(t_ab, 0.0), (0.0, t_ac), (1.0 - t_bc, t_bc)] {
            let d = (ab * cu + ac * cv - ap).length_squared();
            if d < best {
                (best, u, v) = (d, cu, cv);
            }
        }
    }
    let u = u as f32;
    (u, (v as f32).min(1.0 - u))
}
