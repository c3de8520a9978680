//! quiver's C API: BVH builds over indexed triangle meshes, closest-hit, any-hit and
//! closest-point queries (one ray, or arrays traced in parallel), refits, saved BVHs, and
//! instanced worlds with per-geometry filters and edits.
//!
//! The C declarations are in `include/quiver.h`, written by hand; every function there is one
//! `#[no_mangle] extern "C"` function here, and a test (`tests/header.rs`) keeps the two
//! lists equal. The header documents the contract of each function (ownership, lifetimes,
//! thread safety, status codes); the Rust items below repeat it briefly for Rust readers.
//!
//! Three rules hold for every function:
//! - No panic crosses the boundary: each body runs inside one wrapper (`error::guard`), which
//!   turns a panic into [`QvStatus::Panic`] and its message.
//! - A null pointer is refused with [`QvStatus::NullPointer`], never read.
//! - A refused call says why in [`qv_last_error`], naming the argument (and the vertex,
//!   triangle or instance) at fault.
//!
//! A panic is caught only when the library is built with `panic = "unwind"` (Cargo's
//! default); a build with `panic = "abort"` aborts instead.

#![warn(missing_docs)]
// Every unsafe operation sits in its own block with its own SAFETY argument, unsafe fns included.
#![deny(unsafe_op_in_unsafe_fn)]

mod buffers;
mod bvh;
mod error;
mod files;
mod trace;
mod types;
mod world;

pub use bvh::{
    qv_bvh_any_hit, qv_bvh_any_hits, qv_bvh_build_indexed, qv_bvh_build_indexed_with,
    qv_bvh_closest_hit, qv_bvh_closest_hits, qv_bvh_closest_point, qv_bvh_footprint, qv_bvh_free,
    qv_bvh_load, qv_bvh_refit, qv_bvh_save, QvBvh,
};
pub use error::{qv_last_error, QvStatus};
pub use types::{QvBuildOptions, QvFilterFn, QvHit, QvPointHit, QvQuality, QvRay, QV_INVALID_ID};
pub use world::{
    qv_world_add_instance, qv_world_add_mesh, qv_world_any_hit, qv_world_any_hits, qv_world_build,
    qv_world_build_with, qv_world_builder_add_instance, qv_world_builder_add_mesh,
    qv_world_builder_add_moving_instance, qv_world_builder_add_moving_mesh, qv_world_builder_free,
    qv_world_builder_new, qv_world_builder_set_filter, qv_world_builder_set_options,
    qv_world_closest_hit, qv_world_closest_hits, qv_world_closest_point, qv_world_closest_point_at,
    qv_world_footprint, qv_world_free, qv_world_load, qv_world_refit_mesh,
    qv_world_remove_instance, qv_world_save, qv_world_set_mask, qv_world_set_motion,
    qv_world_set_transform, QvWorld, QvWorldBuilder,
};

#[cfg(test)]
mod tests;
