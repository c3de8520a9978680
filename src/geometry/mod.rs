//! Geometry core: rays, boxes, triangles and hit records on glam's `Vec3A`.
//!
//! Conventions every kernel in quiver shares:
//! - a ray accepts hits with `t_min <= t <= t_max` (a closed interval); every query (the
//!   [`reference`](crate::traverse::reference), every layout and kernel, packets, [`crate::World`])
//!   takes a `t_min` below zero, `-inf` or NaN as zero: nothing behind the origin is ever hit (see
//!   [`Ray`]);
//! - among hits at the same distance the lower primitive index wins, so every kernel, whatever
//!   order it visits primitives in, reports the same primitive as the brute-force reference;
//! - a primitive with a non-finite vertex is invisible: builds drop it (and count it), the
//!   reference skips it.
//!
//! One file per idea: [`Ray`] (and [`offset_ray_origin`] for rays leaving a surface), [`Aabb`],
//! [`Triangle`] with its Möller–Trumbore test, the hit records [`PrimHit`] and [`Hit`], and
//! the power-of-two scaling that keeps the tests exact far from unit size.

mod aabb;
mod hit;
mod ray;
mod scale;
mod triangle;

pub use aabb::Aabb;
pub use hit::{Hit, PrimHit};
pub(crate) use ray::shutter;
pub use ray::{offset_ray_origin, Ray};
pub(crate) use scale::{exponent, pow2, scale2};
pub use scale::{unit_or_zero, unit_scale};
pub use triangle::Triangle;
pub(crate) use triangle::{closest_uv, unit_frame};
