//! Memory layouts of built trees: compact, cache-aligned node arrays ready for traversal.
//!
//! So far one layout: [`Bvh2`], 32-byte binary nodes in depth-first order with the leaf
//! triangles copied into leaf order, so a leaf is a contiguous run of triangles.

mod bvh2;

pub use bvh2::{triangle_bounds, Bvh2, Bvh2Node};
