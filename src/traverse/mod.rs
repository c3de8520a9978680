//! Ray queries: the [`RayQuery`] trait, the BVH traversal kernels behind it, and the
//! brute-force [`mod@reference`] every kernel is checked against.
//!
//! A query's path: the structure's [`RayQuery::trace_with`] (one `match` over its layout)
//! → `dispatch` (the instruction set and the far-group path, picked once) → the layout's walk
//! (`bvh2`, `bvh4`, `bvh8`, or [`packet`]'s) → the leaf test (`leaves`: plain primitives
//! through `search`, triangles through `tri4`'s SIMD groups). Each walk is written once for
//! both questions ([`Ask`]: closest hit or any hit) and once for every instruction set
//! (`lane8`'s lanes), and each layout's [`RayQuery`] sits with its walk.
//!
//! Beside them: `boxes` (the slab test, plain or conservative), `stack`, `simd`, and
//! [`Stats`] sinks that compile away when unused.

mod boxes;
mod bvh2;
pub(crate) mod bvh4;
pub(crate) mod bvh8;
pub(crate) mod dispatch;
pub(crate) mod lane8;
pub(crate) mod leaves;
pub mod packet;
pub(crate) mod query;
pub mod reference;
pub(crate) mod search;
pub(crate) mod simd;
pub(crate) mod stack;
mod stats;
mod tri4;

pub(crate) use boxes::{slab_reciprocal, SlabRay};
pub use boxes::{BoxTest, ConservativeBoxes, FastBoxes};
pub use packet::{PacketMode, PacketQuery, PACKET_RAYS};
pub use query::{AnyHit, Ask, ClosestHit, Filter, NoFilter, RayQuery};
pub(crate) use search::prim_hit;
pub(crate) use stack::Stack;
pub use stats::{Counters, NoStats, Stats};
