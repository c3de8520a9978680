//! [`Ray`]: an origin, a direction and the interval of accepted hit distances; and
//! [`offset_ray_origin`], where a ray leaving a surface starts.

use glam::Vec3A;

/// A ray `origin + t * dir` restricted to `t_min <= t <= t_max`.
///
/// `dir` need not be normalised; `t` is measured in units of `dir`.
///
/// Queries search `[max(t_min, 0), t_max]`: a `t_min` below zero, `-inf` or NaN counts as zero in
/// the [`reference`](crate::traverse::reference), every layout, packets and [`crate::World`] alike,
/// so a ray never hits what lies behind its origin. (A primitive's own test, called directly, takes
/// the interval as given; the queries hand it the raised one.)
///
/// ```
/// use quiver_rt::traverse::reference;
/// use quiver_rt::{Bvh, Ray, RayQuery, Triangle};
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
    /// When in the shutter interval the ray is shot, from 0 (opening) to 1 (closing): a
    /// moving instance of a [`crate::World`] is met where its [`crate::Motion`] places it
    /// then. 0 by default; a static scene ignores it (its answers are the same at any time).
    /// Queries clamp it into `[0, 1]` and take NaN as 0 ([`Ray::shutter_time`]). It sits in
    /// what was padding: a ray is 48 bytes with it or without it.
    pub time: f32,
}

// The time field fills the padding after the mask: a larger ray would cost every packet and
// every ray buffer of a renderer.
const _: () = assert!(std::mem::size_of::<Ray>() == 48);

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
            time: 0.0,
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

    /// The same ray shot at `time` in the shutter interval (see [`Ray::time`]).
    ///
    /// ```
    /// use quiver_rt::Ray;
    /// use glam::Vec3A;
    /// let r = Ray::new(Vec3A::ZERO, Vec3A::Z).with_time(0.25);
    /// assert_eq!((r.time, Ray::new(Vec3A::ZERO, Vec3A::Z).time), (0.25, 0.0));
    /// ```
    #[inline]
    pub fn with_time(self, time: f32) -> Self {
        Ray { time, ..self }
    }

    /// The time every query uses: [`Ray::time`] clamped into `[0, 1]`, NaN taken as 0 (a
    /// time out of the shutter is the nearest end of it, never a miss).
    ///
    /// ```
    /// use quiver_rt::Ray;
    /// use glam::Vec3A;
    /// let at = |t: f32| Ray::new(Vec3A::ZERO, Vec3A::Z).with_time(t).shutter_time();
    /// assert_eq!([at(0.5), at(-1.0), at(7.0), at(f32::NAN), at(f32::INFINITY)], [0.5, 0.0, 1.0, 0.0, 1.0]);
    /// ```
    #[inline(always)]
    pub fn shutter_time(&self) -> f32 {
        shutter(self.time)
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

/// `time` as every query takes it ([`Ray::shutter_time`]): clamped into `[0, 1]`, NaN as 0.
#[inline(always)]
#[allow(clippy::manual_clamp)] // `clamp` keeps a NaN, and a NaN time must be 0
pub(crate) fn shutter(time: f32) -> f32 {
    // `max` returns the other operand for a NaN.
    time.max(0.0).min(1.0)
}
