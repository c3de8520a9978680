//! quiver: BVH construction and ray shooting on CPUs.
//!
//! Give it triangles (or any [`Primitive`]), get a [`Bvh`]; ask it for the closest hit or
//! any hit along a ray, one ray at a time or 64 at once ([`RayQuery`]).
//!
//! ```
//! use quiver_rt::{Bvh, Ray, RayQuery};
//! use glam::Vec3A;
//!
//! // A unit square in the z = 0 plane: four vertices, two triangles.
//! let positions = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]];
//! let indices = [[0, 1, 2], [0, 2, 3]];
//! let bvh = Bvh::from_mesh(&positions, &indices).expect("every index names a vertex");
//!
//! // A ray straight down onto the upper-left half.
//! let ray = Ray::new(Vec3A::new(0.25, 0.75, 2.0), Vec3A::new(0.0, 0.0, -1.0));
//! let hit = bvh.closest_hit(&ray).expect("the ray hits the square");
//! assert_eq!((hit.prim, hit.t), (1, 2.0)); // the second triangle, two units away
//! assert!(bvh.any_hit(&ray));
//! ```
//!
//! The pipeline, one module per stage: [`builders`] (SAH trees over primitive bounds) →
//! [`layout`] (compact node arrays: binary, 4-wide, quantized; in several memory orders) →
//! [`traverse`] (single-ray and packet kernels, closest and any hit, statistics).
//! [`Bvh::new`] and [`BuildOptions`] run the first two; [`geometry`] holds rays, boxes,
//! triangles and hit records, [`intersect`] the watertight and exact triangle tests, and
//! [`mod@reference`] the brute-force oracle every kernel is tested against.
//!
//! This crate depends only on glam, wide, rayon and bytemuck. Scenes (the SPD generators,
//! NFF and OBJ files), analytic shapes and the SPD renderer live in `quiver-scenes`; the
//! measurement harness in `quiver-lab`; the command line in `quiver-rt-cli` (the `quiver` binary).

#![warn(missing_docs)]

// The crates whose types the public API names, so an embedder uses the very versions quiver
// was built with: glam (`Vec3A` in rays and boxes), wide (`f32x8` in a primitive's eight-ray
// test), rayon (the `ThreadPool` a build runs on) and bytemuck (`Pod` node types).
pub use bytemuck;
pub use glam;
pub use rayon;
pub use wide;

pub mod builders;
mod bvh;
mod frame;
pub mod geometry;
pub mod intersect;
mod isa;
pub mod layout;
mod mask;
mod mem;
mod mesh;
pub mod predict;
pub mod primitive;
mod rng;
#[cfg(test)]
mod testing;
pub mod traverse;
pub mod world;

pub use bvh::{BuildOptions, Bvh, RefitError};
pub use geometry::{Aabb, Hit, PrimHit, Ray, Triangle};
pub use isa::{Isa, ISA_ENV};
pub use layout::{
    Bvh2, Bvh2Mapping, Bvh2Node, Bvh4, Bvh4Mapping, Bvh4Node, Bvh8, Bvh8Node, Footprint, Layout,
    Node4, QBvh4, QBvh4Node, Tri4,
};
pub use mesh::{MeshError, Positions};
pub use primitive::{LeafFormat, Primitive};
pub use traverse::{reference, RayQuery};
pub use world::{Geometry, GeometryId, Instance, World, WorldBuilder, WorldError, WorldHit};
