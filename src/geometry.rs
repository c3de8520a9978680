//! Geometry core: rays, boxes, triangles and hit records on glam's `Vec3A`.
//!
//! Conventions every kernel in quiver shares:
//! - a ray accepts hits with `t_min <= t <= t_max` (a closed interval); every query (the
//!   [`crate::reference`], every layout and kernel, packets, [`crate::World`]) takes a
//!   `t_min` below zero, `-inf` or NaN as zero: nothing behind the origin is ever hit (see
//!   [`Ray`]);
//! - among hits at the same distance the lower primitive index wins, so every kernel, whatever
//!   order it visits primitives in, reports the same primitive as the brute-force reference;
//! - a primitive with a non-finite vertex is invisible: builds drop it (and count it), the
//!   reference skips it.

use glam::Vec3A;

/// A ray `origin + t * dir` restricted to `t_min <= t <= t_max`.
///
/// `dir` need not be normalised; `t` is measured in units of `dir`.
///
/// Queries search `[max(t_min, 0), t_max]`: a `t_min` below zero, `-inf` or NaN counts as
/// zero in the [`crate::reference`], every layout, packets and [`crate::World`] alike, so a
/// ray never hits what lies behind its origin. (A primitive's own test, called directly, takes
/// the interval as given; the queries hand it the raised one.)
///
/// ```
/// use quiver_rt::{reference, Bvh, Ray, RayQuery, Triangle};
/// use glam::Vec3A;
/// let behind = Triangle::new(Vec3A::new(0.0, 0.0, -5.0), Vec3A::new(1.0, 0.0, -5.0), Vec3A::new(0.0, 1.0, -5.0));
/// let ahead = Triangle::new(Vec3A::new(0.0, 0.0, 3.0), Vec3A::new(1.0, 0.0, 3.0), Vec3A::new(0.0, 1.0, 3.0));
/// let tris = [behind, ahead];
/// let bvh = Bvh::new(&tris);
/// for t_min in [-10.0, f32::NEG_INFINITY, f32::NAN] {
///     let ray = Ray::segment(Vec3A::new(0.2, 0.2, 0.0), Vec3A::Z, t_min, f32::INFINITY);
///     assert_eq!(reference::closest_hit(&tris, &ray).map(|h| (h.prim, h.t)), Some((1, 3.0)));
///     assert_eq!(bvh.closest_hit(&ray), reference::closest_hit(&tris, &ray));
/// }
/// ```
///
/// ```
/// use quiver_rt::Ray;
/// use glam::Vec3A;
/// let r = Ray::new(Vec3A::ZERO, Vec3A::Z);
/// assert_eq!(r.at(2.0), Vec3A::new(0.0, 0.0, 2.0));
/// assert_eq!((r.t_min, r.t_max), (0.0, f32::INFINITY));
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray {
    /// Where the ray starts.
    pub origin: Vec3A,
    /// Direction; zero components (either sign) are allowed.
    pub dir: Vec3A,
    /// Smallest accepted hit distance; queries take anything below zero (and NaN) as zero.
    pub t_min: f32,
    /// Largest accepted hit distance.
    pub t_max: f32,
    /// Which instances of a [`crate::World`] the ray sees: an instance whose mask shares no
    /// bit with it is never entered. Every bit set by default (the ray sees everything); a
    /// single BVH has no instances and ignores it.
    pub mask: u32,
}

impl Ray {
    /// A ray over `[0, +inf]`.
    #[inline]
    pub fn new(origin: Vec3A, dir: Vec3A) -> Self {
        Self::segment(origin, dir, 0.0, f32::INFINITY)
    }

    /// A ray over `[t_min, t_max]`.
    #[inline]
    pub fn segment(origin: Vec3A, dir: Vec3A, t_min: f32, t_max: f32) -> Self {
        Ray {
            origin,
            dir,
            t_min,
            t_max,
            mask: u32::MAX,
        }
    }

    /// The same ray seeing only the instances whose mask shares a bit with `mask`.
    ///
    /// ```
    /// use quiver_rt::Ray;
    /// use glam::Vec3A;
    /// let shadow = Ray::new(Vec3A::ZERO, Vec3A::Z).with_mask(0b10);
    /// assert_eq!((shadow.mask, Ray::new(Vec3A::ZERO, Vec3A::Z).mask), (0b10, u32::MAX));
    /// ```
    #[inline]
    pub fn with_mask(self, mask: u32) -> Self {
        Ray { mask, ..self }
    }

    /// The ray as every query takes it: a `t_min` below zero (or NaN) raised to zero.
    #[inline(always)]
    pub(crate) fn raised_t_min(&self) -> Ray {
        Ray {
            // `max` returns the other operand for a NaN.
            t_min: self.t_min.max(0.0),
            ..*self
        }
    }

    /// The point at distance `t`.
    #[inline]
    pub fn at(&self, t: f32) -> Vec3A {
        self.origin + self.dir * t
    }
}

/// An axis-aligned bounding box. The empty box has `min = +inf`, `max = -inf`.
///
/// ```
/// use quiver_rt::Aabb;
/// use glam::Vec3A;
/// let mut b = Aabb::EMPTY;
/// b.grow(Vec3A::ZERO);
/// b.grow(Vec3A::new(1.0, 2.0, 3.0));
/// assert_eq!(b.half_area(), 1.0 * 2.0 + 2.0 * 3.0 + 3.0 * 1.0);
/// ```
#[derive(Clone, Copy, Debug, PartialEq, bytemuck::Zeroable)]
pub struct Aabb {
    /// Lower corner.
    pub min: Vec3A,
    /// Upper corner.
    pub max: Vec3A,
}

impl Aabb {
    /// The box containing nothing; the identity of [`Aabb::union`].
    pub const EMPTY: Aabb = Aabb {
        min: Vec3A::splat(f32::INFINITY),
        max: Vec3A::splat(f32::NEG_INFINITY),
    };

    /// The box spanned by two corners.
    #[inline]
    pub fn new(min: Vec3A, max: Vec3A) -> Self {
        Aabb { min, max }
    }

    /// Extends the box to contain `p`.
    #[inline]
    pub fn grow(&mut self, p: Vec3A) {
        self.min = self.min.min(p);
        self.max = self.max.max(p);
    }

    /// The smallest box containing both.
    #[inline]
    pub fn union(&self, other: &Aabb) -> Aabb {
        Aabb {
            min: self.min.min(other.min),
            max: self.max.max(other.max),
        }
    }

    /// True when both corners are finite (no NaN, no infinity).
    #[inline]
    pub fn is_finite(&self) -> bool {
        // One vector test per corner and no branch: refits and builds ask it of every box.
        (self.min.is_finite_mask() & self.max.is_finite_mask()).all()
    }

    /// True when the box contains no point.
    #[inline]
    pub fn is_empty(&self) -> bool {
        self.min.cmpgt(self.max).any()
    }

    /// Edge lengths; zero for the empty box.
    #[inline]
    pub fn extent(&self) -> Vec3A {
        (self.max - self.min).max(Vec3A::ZERO)
    }

    /// Half the surface area: the SAH only ever needs ratios of areas. Zero when empty.
    ///
    /// For a finite box it is finite: past f32's range (edges of about `1e19` and more) it
    /// saturates at `f32::MAX`. [`Aabb::half_area_f64`] has the exact value.
    ///
    /// ```
    /// use quiver_rt::Aabb;
    /// use glam::Vec3A;
    /// let huge = Aabb::new(Vec3A::splat(-1e30), Vec3A::splat(1e30));
    /// assert_eq!(huge.half_area(), f32::MAX);
    /// assert_eq!(huge.half_area_f64(), 3.0 * 2e30f32 as f64 * 2e30f32 as f64);
    /// ```
    #[inline]
    pub fn half_area(&self) -> f32 {
        let e = self.extent();
        let a = e.x * e.y + e.y * e.z + e.z * e.x;
        if a.is_finite() || !self.is_finite() {
            a
        } else {
            self.half_area_f64().min(f32::MAX as f64) as f32
        }
    }

    /// Half the surface area in f64, where no finite box overflows. Zero when empty.
    #[inline]
    pub fn half_area_f64(&self) -> f64 {
        let e = (self.max.as_dvec3() - self.min.as_dvec3()).max(glam::DVec3::ZERO);
        e.x * e.y + e.y * e.z + e.z * e.x
    }

    /// The centre point.
    #[inline]
    pub fn center(&self) -> Vec3A {
        (self.min + self.max) * 0.5
    }

    /// True when `other` lies inside this box (boundaries included). The empty box lies in
    /// every box.
    #[inline]
    pub fn contains(&self, other: &Aabb) -> bool {
        other.is_empty() || (self.min.cmple(other.min).all() && other.max.cmple(self.max).all())
    }
}

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

/// What one primitive test found: the distance and two surface parameters (barycentrics for
/// triangles; each shape documents its own).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PrimHit {
    /// Hit distance along the ray.
    pub t: f32,
    /// First surface parameter (a triangle: barycentric weight of the second vertex).
    pub u: f32,
    /// Second surface parameter (a triangle: barycentric weight of the third vertex).
    pub v: f32,
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
        mask: ray.mask,
    };
    Some((
        Triangle {
            v: tri.v.map(|p| scale(p, -k)),
        },
        local,
        k - j,
    ))
}

/// `v` scaled to unit length at any size, or zero for a zero or non-finite vector.
///
/// glam's `normalize_or_zero` squares the components, so a normal computed as the cross
/// product of two edges is lost beyond about 1e19 (overflow) or below 1e-19 (underflow) —
/// edges of about 1e10 and 1e-10. This first brings the largest component near 1 by powers of
/// two, which is exact: wherever `normalize_or_zero` works, the result is the same bits.
///
/// ```
/// use quiver_rt::geometry::unit_or_zero;
/// use glam::Vec3A;
/// let huge = Vec3A::new(3e30, 4e30, 0.0);
/// assert_eq!(huge.normalize_or_zero(), Vec3A::ZERO); // squared: overflow
/// assert!(unit_or_zero(huge).abs_diff_eq(Vec3A::new(0.6, 0.8, 0.0), 1e-7));
/// // Powers of two are exact: the same bits as at unit size.
/// assert_eq!(unit_or_zero(Vec3A::new(3.0, 4.0, 0.0) * 2f32.powi(100)), Vec3A::new(3.0, 4.0, 0.0).normalize());
/// assert_eq!(unit_or_zero(Vec3A::new(0.0, 1e-30, 0.0)), Vec3A::Y);
/// assert_eq!(unit_or_zero(Vec3A::new(0.0, 0.0, -1e-45)), -Vec3A::Z); // subnormal
/// assert_eq!(unit_or_zero(Vec3A::ZERO), Vec3A::ZERO);
/// ```
#[inline]
pub fn unit_or_zero(v: Vec3A) -> Vec3A {
    let m = v.abs().max_element();
    if !m.is_finite() {
        return Vec3A::ZERO;
    }
    (v * unit_scale(m)).normalize_or_zero()
}

/// The power of two that brings a magnitude `m` near 1 when products of two or three such
/// magnitudes would leave f32's range (`m` outside `2^-40..=2^40`), else 1: multiply the
/// vectors of a cross or dot product by it first, and the product keeps its digits at any
/// scale with the same bits as before wherever it had them.
///
/// ```
/// use quiver_rt::geometry::unit_scale;
/// assert_eq!(unit_scale(3.0), 1.0);
/// assert_eq!(unit_scale(1e30) * 1e30, 1e30 * 2f32.powi(-99));
/// assert!((1.0..2.0).contains(&(unit_scale(1e-30) * 1e-30)));
/// ```
#[inline]
pub fn unit_scale(m: f32) -> f32 {
    const BAND: f32 = (1u64 << 40) as f32;
    if !(m.is_finite() && m > 0.0) || (1.0 / BAND..=BAND).contains(&m) {
        return 1.0;
    }
    // 2^-e for m in [2^e, 2^(e+1)); the factor itself must be an f32, so a subnormal m only
    // comes up by 2^127 (to at least 2^-22, still far from underflow).
    scale2(1.0, -exponent(m).max(-127))
}

/// `2^e` for `e` in f32's normal exponent range.
pub(crate) fn pow2(e: i32) -> f32 {
    debug_assert!((-126..=127).contains(&e));
    f32::from_bits(((e + 127) as u32) << 23)
}

/// The exponent of `x` (finite, positive): `x` lies in `[2^e, 2^(e+1))`.
pub(crate) fn exponent(x: f32) -> i32 {
    if x >= f32::MIN_POSITIVE {
        ((x.to_bits() >> 23) & 0xff) as i32 - 127
    } else {
        // Subnormal: count from the smallest normal down.
        -127 - (x.to_bits().leading_zeros() as i32 - 9)
    }
}

/// `x * 2^e` for `e` beyond f32's exponent range too, in two exact steps.
#[inline(always)]
pub(crate) fn scale2(x: f32, e: i32) -> f32 {
    let half = e / 2;
    x * pow2(half) * pow2(e - half)
}

/// A closest-hit answer: the distance, the primitive's index in the input, and barycentrics.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    /// Hit distance along the ray.
    pub t: f32,
    /// Index of the primitive in the scene's input order.
    pub prim: u32,
    /// Barycentric weight of the primitive's second vertex.
    pub u: f32,
    /// Barycentric weight of the primitive's third vertex.
    pub v: f32,
}

impl Hit {
    /// The "nothing yet" record a closest-hit search starts from: any hit at or before `t_max`
    /// beats it.
    #[inline(always)]
    pub fn none(t_max: f32) -> Hit {
        Hit {
            t: t_max,
            prim: u32::MAX,
            u: 0.0,
            v: 0.0,
        }
    }

    /// `Some(self)` unless this is still the [`Hit::none`] record.
    #[inline(always)]
    pub fn found(self) -> Option<Hit> {
        (self.prim != u32::MAX).then_some(self)
    }

    /// True when `(t, prim)` should replace `self` as the closest hit: nearer, or equally near
    /// with a lower primitive index. This total order makes every kernel agree on ties.
    #[inline(always)]
    pub fn is_beaten_by(&self, t: f32, prim: u32) -> bool {
        t < self.t || (t == self.t && prim < self.prim)
    }

    /// Takes `hit` on primitive `prim` as the closest hit when it beats `self` (see
    /// [`Hit::is_beaten_by`]); returns whether it did. Every kernel's leaf test goes through
    /// this, so all apply the same order.
    ///
    /// ```
    /// use quiver_rt::{Hit, PrimHit};
    /// let mut best = Hit::none(10.0);
    /// assert!(best.offer(3, PrimHit { t: 2.0, u: 0.1, v: 0.2 }));
    /// assert!(!best.offer(5, PrimHit { t: 2.0, u: 0.0, v: 0.0 }));
    /// assert!(best.offer(1, PrimHit { t: 2.0, u: 0.0, v: 0.0 }));
    /// assert_eq!(best.found().map(|h| (h.prim, h.t)), Some((1, 2.0)));
    /// ```
    #[inline(always)]
    pub fn offer(&mut self, prim: u32, hit: PrimHit) -> bool {
        let beaten = self.is_beaten_by(hit.t, prim);
        if beaten {
            *self = Hit {
                t: hit.t,
                prim,
                u: hit.u,
                v: hit.v,
            };
        }
        beaten
    }
}

/// Moves a surface point off the surface along `n` (the side the new ray leaves from) by a few
/// ulps of its own coordinates: Wächter and Binder, "A Fast and Robust Method for Avoiding
/// Self-Intersection" (Ray Tracing Gems, ch. 6). Unlike an epsilon it scales with the
/// coordinates, so it works for scenes far from the origin and tiny ones alike.
///
/// ```
/// use quiver_rt::geometry::offset_ray_origin;
/// use glam::Vec3A;
/// let p = Vec3A::new(1e6, 0.0, 1.0);
/// let q = offset_ray_origin(p, Vec3A::Z);
/// assert!(q.z > p.z && q.x == p.x);
/// ```
#[inline]
pub fn offset_ray_origin(p: Vec3A, n: Vec3A) -> Vec3A {
    const ORIGIN: f32 = 1.0 / 32.0;
    const FLOAT_SCALE: f32 = 1.0 / 65536.0;
    const INT_SCALE: f32 = 256.0;
    let one = |p: f32, n: f32| {
        if p.abs() < ORIGIN {
            // Near zero the ulps are tiny: a fixed small step instead.
            p + FLOAT_SCALE * n
        } else {
            let of = (INT_SCALE * n) as i32;
            let of = if p < 0.0 { -of } else { of };
            f32::from_bits((p.to_bits() as i32).wrapping_add(of) as u32)
        }
    };
    Vec3A::new(one(p.x, n.x), one(p.y, n.y), one(p.z, n.z))
}
