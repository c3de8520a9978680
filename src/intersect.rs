//! Triangle intersectors, chosen by type: the BVH's primitive type *is* the intersector, so a
//! kernel pays for exactly the test it uses.
//!
//! - [`Triangle`]: fast Möller–Trumbore (normal form). Not watertight: a ray through a shared
//!   edge or vertex can slip between the two triangles.
//! - [`Watertight`]: Woop, Benthin and Wald (JCGT 2013): shear into ray space, edge functions
//!   recomputed in f64 when one is exactly zero, so a ray through a shared edge of a closed mesh
//!   hits at least one of its triangles.
//! - [`Exact`]: the same test carried out entirely in f64: the reference the others are
//!   judged against.
//!
//! ```
//! use quiver_rt::intersect::{Exact, Watertight};
//! use quiver_rt::{Primitive, Ray, Triangle};
//! use glam::Vec3A;
//! let a = Triangle::new(Vec3A::ZERO, Vec3A::X, Vec3A::Y);
//! let b = Triangle::new(Vec3A::X, Vec3A::new(1.0, 1.0, 0.0), Vec3A::Y);
//! // Straight down the shared edge's midpoint: watertight hits one of the two.
//! let ray = Ray::new(Vec3A::new(0.5, 0.5, 1.0), -Vec3A::Z);
//! assert!(Watertight(a).intersect(&ray).is_some() || Watertight(b).intersect(&ray).is_some());
//! assert_eq!(Exact(a).intersect(&ray).unwrap().t, 1.0);
//! ```

use crate::geometry::{Aabb, PrimHit, Ray, Triangle};
use crate::primitive::Primitive;
use glam::{DVec3, Vec3A};

/// A triangle tested with the watertight algorithm.
#[repr(transparent)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Watertight(pub Triangle);

/// A triangle tested entirely in f64 (the accuracy reference).
#[repr(transparent)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Exact(pub Triangle);

/// The ray-space shear of Woop et al.: the axis of largest direction component becomes z, and
/// x and y keep the winding.
#[inline(always)]
pub(crate) fn shear_axes(d: Vec3A) -> (usize, usize, usize) {
    let a = d.abs();
    let kz = if a.x >= a.y && a.x >= a.z {
        0
    } else if a.y >= a.z {
        1
    } else {
        2
    };
    let (mut kx, mut ky) = ((kz + 1) % 3, (kz + 2) % 3);
    if d[kz] < 0.0 {
        std::mem::swap(&mut kx, &mut ky);
    }
    (kx, ky, kz)
}

/// Turns edge functions and the scaled distance into a hit, two-sided, honouring the ray's
/// interval. `u` weighs the second vertex and `v` the third, as everywhere in quiver.
#[inline(always)]
fn finish<T: Into<f64> + Copy>(u: T, v: T, w: T, t_scaled: T, ray: &Ray) -> Option<PrimHit> {
    let (u, v, w, ts) = (u.into(), v.into(), w.into(), t_scaled.into());
    if (u < 0.0 || v < 0.0 || w < 0.0) && (u > 0.0 || v > 0.0 || w > 0.0) {
        return None;
    }
    let det = u + v + w;
    if det == 0.0 {
        return None;
    }
    let t = (ts / det) as f32;
    if !(t >= ray.t_min && t <= ray.t_max) {
        return None;
    }
    Some(PrimHit {
        t,
        u: (v / det) as f32,
        v: (w / det) as f32,
    })
}

impl Primitive for Watertight {
    const LEAF_FORMAT: crate::primitive::LeafFormat =
        crate::primitive::LeafFormat::WatertightTriangles;

    #[inline]
    fn triangle(&self) -> Option<Triangle> {
        Some(self.0)
    }

    fn bounds(&self) -> Aabb {
        Primitive::bounds(&self.0)
    }

    fn is_finite(&self) -> bool {
        self.0.is_finite()
    }

    fn scaled(&self, s: f32) -> Option<Self> {
        self.0.scaled(s).map(Watertight)
    }

    /// The watertight test. Like [`Triangle::intersect`] it takes the test again on the
    /// triangle and ray scaled by powers of two (exact) when a product of lengths may have
    /// left f32's range (a determinant or `t` numerator non-finite or below `2^-100`), so
    /// every finite input gives a finite `t` or a miss, at any scale.
    #[inline(always)]
    fn intersect(&self, ray: &Ray) -> Option<PrimHit> {
        match watertight::<true>(&self.0, ray) {
            Ok(h) => h,
            Err(OutOfRange) => watertight_rescaled(&self.0, ray),
        }
    }

    fn surface_area(&self) -> f32 {
        self.0.surface_area()
    }
}

/// A product of lengths in the watertight test may have left f32's range.
struct OutOfRange;

/// The watertight test in the ray's and triangle's own units; with `CHECKED`, an error where
/// a product may have left f32's range (without, as computed: in the unit frame).
#[inline(always)]
fn watertight<const CHECKED: bool>(
    tri: &Triangle,
    ray: &Ray,
) -> Result<Option<PrimHit>, OutOfRange> {
    const SMALL: f32 = 1.0 / (1u128 << 100) as f32;
    const LARGE: f32 = (1u128 << 100) as f32;
    let d = ray.dir;
    let (kx, ky, kz) = shear_axes(d);
    let sz = 1.0 / d[kz];
    let (sx, sy) = (d[kx] * sz, d[ky] * sz);
    let rel = tri.v.map(|p| p - ray.origin);
    let x = rel.map(|p| p[kx] - sx * p[kz]);
    let y = rel.map(|p| p[ky] - sy * p[kz]);
    // Edge functions: U for the edge opposite vertex 0, and so on.
    let mut u = x[2] * y[1] - y[2] * x[1];
    let mut v = x[0] * y[2] - y[0] * x[2];
    let mut w = x[1] * y[0] - y[1] * x[0];
    if u == 0.0 || v == 0.0 || w == 0.0 {
        // On an edge in f32: decide in f64, where the products are exact.
        let e =
            |a: f32, b: f32, c: f32, dd: f32| (a as f64 * b as f64 - c as f64 * dd as f64) as f32;
        u = e(x[2], y[1], y[2], x[1]);
        v = e(x[0], y[2], y[0], x[2]);
        w = e(x[1], y[0], y[1], x[0]);
    }
    if (u < 0.0 || v < 0.0 || w < 0.0) && (u > 0.0 || v > 0.0 || w > 0.0) {
        return Ok(None);
    }
    let det = u + v + w;
    if det == 0.0 {
        // Degenerate or parallel, unless everything underflowed.
        // (Products of coordinates of at least 2^-50 cannot underflow.)
        let tiny = 1.0 / (1u64 << 50) as f32;
        return if !CHECKED
            || sz.is_finite() && x.iter().chain(&y).all(|c| c.abs() >= tiny || *c == 0.0)
        {
            Ok(None)
        } else {
            Err(OutOfRange)
        };
    }
    let z = rel.map(|p| sz * p[kz]);
    let t_scaled = u * z[0] + v * z[1] + w * z[2];
    let inv = 1.0 / det;
    let t = t_scaled * inv;
    if CHECKED
        && !(det.abs() >= SMALL && det.abs() <= LARGE && t.is_finite() && t_scaled.abs() >= SMALL)
    {
        return Err(OutOfRange);
    }
    if !(t >= ray.t_min && t <= ray.t_max) {
        return Ok(None);
    }
    Ok(Some(PrimHit {
        t,
        u: v * inv,
        v: w * inv,
    }))
}

/// [`watertight`] on the triangle and ray scaled by powers of two: the vertices and origin to
/// bring the triangle near unit size (no coordinate past `2^100`), the direction near unit
/// length; `t` scaled back by their ratio.
#[cold]
#[inline(never)]
fn watertight_rescaled(tri: &Triangle, ray: &Ray) -> Option<PrimHit> {
    let (tri_l, ray_l, e) = crate::geometry::unit_frame(tri, ray)?;
    let Ok(h) = watertight::<false>(&tri_l, &ray_l) else {
        return None;
    };
    let h = h?;
    let t = crate::geometry::scale2(crate::geometry::scale2(h.t, e / 2), e - e / 2);
    (t.is_finite() && t >= ray.t_min && t <= ray.t_max).then_some(PrimHit { t, ..h })
}

impl Primitive for Exact {
    fn bounds(&self) -> Aabb {
        Primitive::bounds(&self.0)
    }

    fn is_finite(&self) -> bool {
        self.0.is_finite()
    }

    fn scaled(&self, s: f32) -> Option<Self> {
        self.0.scaled(s).map(Exact)
    }

    #[inline]
    fn intersect(&self, ray: &Ray) -> Option<PrimHit> {
        let f = |p: Vec3A| DVec3::new(p.x as f64, p.y as f64, p.z as f64);
        let d = f(ray.dir);
        let (kx, ky, kz) = shear_axes(ray.dir);
        let sz = 1.0 / d[kz];
        let (sx, sy) = (d[kx] * sz, d[ky] * sz);
        let rel = self.0.v.map(|p| f(p) - f(ray.origin));
        let x = rel.map(|p| p[kx] - sx * p[kz]);
        let y = rel.map(|p| p[ky] - sy * p[kz]);
        let u = x[2] * y[1] - y[2] * x[1];
        let v = x[0] * y[2] - y[0] * x[2];
        let w = x[1] * y[0] - y[1] * x[0];
        let z = rel.map(|p| sz * p[kz]);
        finish(u, v, w, u * z[0] + v * z[1] + w * z[2], ray)
    }

    fn surface_area(&self) -> f32 {
        self.0.surface_area()
    }
}
