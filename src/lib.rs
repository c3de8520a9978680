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
//! [`Bvh::new`] and [`Bvh::build`] with [`BuildOptions`] run the first two; [`World`] places
//! BVHs as instances under one top level; [`geometry`] holds rays, boxes, triangles and hit
//! records, [`intersect`] the watertight and exact triangle tests, and
//! [`traverse::reference`](mod@traverse::reference) the brute-force oracle every kernel is
//! tested against. [`prelude`] imports what a renderer needs in one line.
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
pub mod names;
pub mod point;
pub mod predict;
pub mod primitive;
mod rng;
mod save;
#[cfg(test)]
mod testing;
pub mod traverse;
pub mod world;

// The crate root names what a renderer meets first (25 items, besides the modules and the
// crates above); the layouts' types, the builders' parameters and the traversal's type
// parameters live in their modules, as do the rarer names (`builders::TreeError`,
// `layout::Footprint`, `names::ParseError`, `traverse::reference`, `world::Interpolation`,
// `world::WorldPointHit`) and the file format's `Bvh::FORMAT_VERSION`.
pub use builders::BuildError;
pub use bvh::{BuildOptions, Bvh, RefitError};
pub use geometry::{Aabb, Hit, PrimHit, Ray, Triangle};
pub use isa::Isa;
pub use layout::Layout;
pub use mesh::{MeshError, Positions};
pub use point::PointHit;
pub use primitive::Primitive;
pub use save::LoadError;
pub use traverse::RayQuery;
pub use world::{
    GeometryId, Instance, InstanceId, Motion, World, WorldBuilder, WorldError, WorldHit,
};

/// What a renderer needs in one import: `use quiver_rt::prelude::*;` brings the BVH and its
/// build options, the layouts' names, rays, triangles and hits, the query trait, worlds with
/// their instances and ids, and every error a build, refit or world can return.
///
/// ```
/// use quiver_rt::prelude::*;
/// use quiver_rt::glam::Vec3A;
/// let tris = [Triangle::new(Vec3A::ZERO, Vec3A::X, Vec3A::Y)];
/// let bvh = Bvh::build(&tris, &BuildOptions::fast().layout(Layout::Bvh4Dfs))?;
/// let hit: Option<Hit> = bvh.closest_hit(&Ray::new(Vec3A::new(0.2, 0.2, 1.0), -Vec3A::Z));
/// assert_eq!(hit.map(|h| h.prim), Some(0));
///
/// let mut scene = WorldBuilder::new();
/// let g: GeometryId = scene.add_triangles(tris.to_vec());
/// let i: InstanceId = scene.add_instance(Instance::of(g));
/// let world: World = scene.build(&BuildOptions::default())?;
/// let hit: Option<WorldHit> = world.closest_hit(&Ray::new(Vec3A::new(0.2, 0.2, 1.0), -Vec3A::Z));
/// assert_eq!(hit.map(|h| h.instance), Some(i));
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub mod prelude {
    pub use crate::builders::{Builder, TreeError};
    pub use crate::{
        Aabb, BuildError, BuildOptions, Bvh, GeometryId, Hit, Instance, InstanceId, Layout,
        MeshError, Motion, Positions, PrimHit, Primitive, Ray, RayQuery, RefitError, Triangle,
        World, WorldBuilder, WorldError, WorldHit,
    };
}
