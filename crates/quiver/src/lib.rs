//! quiver: ray shooting on CPUs.

pub mod build;
pub mod geometry;
pub mod intersect;
pub mod layout;
mod rng;
#[cfg(test)]
mod testing;
pub mod traverse;

pub use geometry::{Aabb, Hit, Primitive, Ray, TriHit, Triangle};
pub use layout::{Bvh, Bvh2, Layout};
pub use traverse::reference;
