//! Brute-force ray queries over all primitives, no acceleration structure: the oracle.
//!
//! ```
//! use quiver_rt::traverse::reference;
//! use quiver_rt::{Ray, Triangle};
//! use glam::Vec3A;
//! let tris = [Triangle::new(Vec3A::ZERO, Vec3A::X, Vec3A::Y)];
//! let ray = Ray::new(Vec3A::new(0.1, 0.1, 1.0), -Vec3A::Z);
//! assert_eq!(reference::closest_hit(&tris, &ray).unwrap().t, 1.0);
//! assert!(reference::any_hit(&tris, &ray));
//! ```

use crate::geometry::{Hit, Ray};
use crate::primitive::Primitive;

/// A primitive the builders keep. Others are invisible.
fn visible<P: Primitive>(p: &P) -> bool {
    p.is_finite()
}

/// The nearest hit; on equal distance the lowest index. Non-finite primitives are skipped; a
/// `t_min` below zero or NaN counts as zero (see [`Ray`]).
/// Each primitive is tested as every kernel tests it (for a triangle [`crate::primitive::LeafFormat`],
/// as its triangle).
pub fn closest_hit<P: Primitive>(prims: &[P], ray: &Ray) -> Option<Hit> {
    let ray = &ray.raised_t_min();
    let mut best: Option<Hit> = None;
    for (i, p) in prims.iter().enumerate() {
        if !visible(p) {
            continue;
        }
        if let Some(h) = super::prim_hit(p, ray) {
            if best.is_none_or(|b| b.is_beaten_by(h.t, i as u32)) {
                best = Some(Hit {
                    t: h.t,
                    prim: i as u32,
                    u: h.u,
                    v: h.v,
                });
            }
        }
    }
    best
}

/// True when any finite primitive is hit within the ray's interval.
pub fn any_hit<P: Primitive>(prims: &[P], ray: &Ray) -> bool {
    let ray = &ray.raised_t_min();
    prims
        .iter()
        .any(|p| visible(p) && super::prim_hit(p, ray).is_some())
}
