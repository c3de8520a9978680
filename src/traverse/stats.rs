//! Traversal statistics that cost nothing when switched off.
//!
//! Every kernel is generic over a [`Stats`] sink. [`NoStats`] has empty inlined methods, so the
//! counting calls vanish from the compiled plain kernel; [`Counters`] counts. The choice is made
//! at compile time, never by a branch in the hot loop.

use std::ops::AddAssign;

/// Where a kernel reports what it did.
pub trait Stats {
    /// A node was visited (its children's boxes tested, or its primitives if a leaf).
    fn node(&mut self);
    /// `n` boxes were tested against the ray.
    fn boxes(&mut self, n: u32);
    /// A leaf was visited.
    fn leaf(&mut self);
    /// A visited leaf changed nothing: no primitive hit (any-hit), or none nearer than the best
    /// so far (closest-hit). The BVH analogue of an empty kd-tree cell: a wasted leaf visit.
    fn empty_leaf(&mut self);
    /// `n` primitives were tested.
    fn prims(&mut self, n: u32);
}

/// The plain kernels' sink: counts nothing, compiles to nothing.
#[derive(Clone, Copy, Debug, Default)]
pub struct NoStats;

impl Stats for NoStats {
    #[inline(always)]
    fn node(&mut self) {}
    #[inline(always)]
    fn boxes(&mut self, _: u32) {}
    #[inline(always)]
    fn leaf(&mut self) {}
    #[inline(always)]
    fn empty_leaf(&mut self) {}
    #[inline(always)]
    fn prims(&mut self, _: u32) {}
}

/// Counts of one ray's traversal, or (added up) of many.
///
/// ```
/// use quiver_rt::{BuildOptions, Layout, Ray, RayQuery, Triangle};
/// use quiver_rt::traverse::Counters;
/// use glam::Vec3A;
/// let tris = vec![Triangle::new(Vec3A::ZERO, Vec3A::X, Vec3A::Y)];
/// let bvh = BuildOptions::default().layout(Layout::Bvh2Dfs).build(&tris);
/// let mut c = Counters::default();
/// bvh.closest_hit_counted(&Ray::new(Vec3A::new(0.2, 0.2, 1.0), -Vec3A::Z), &mut c);
/// assert_eq!((c.nodes, c.leaves, c.prim_tests, c.empty_leaves), (1, 1, 1, 0));
/// ```
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Counters {
    /// Nodes visited (inner and leaf).
    pub nodes: u64,
    /// Ray-box tests.
    pub box_tests: u64,
    /// Leaves visited.
    pub leaves: u64,
    /// Leaves visited that changed nothing (see [`Stats::empty_leaf`]).
    pub empty_leaves: u64,
    /// Ray-primitive tests.
    pub prim_tests: u64,
}

impl Stats for Counters {
    #[inline(always)]
    fn node(&mut self) {
        self.nodes += 1;
    }
    #[inline(always)]
    fn boxes(&mut self, n: u32) {
        self.box_tests += n as u64;
    }
    #[inline(always)]
    fn leaf(&mut self) {
        self.leaves += 1;
    }
    #[inline(always)]
    fn empty_leaf(&mut self) {
        self.empty_leaves += 1;
    }
    #[inline(always)]
    fn prims(&mut self, n: u32) {
        self.prim_tests += n as u64;
    }
}

impl AddAssign for Counters {
    fn add_assign(&mut self, o: Counters) {
        self.nodes += o.nodes;
        self.box_tests += o.box_tests;
        self.leaves += o.leaves;
        self.empty_leaves += o.empty_leaves;
        self.prim_tests += o.prim_tests;
    }
}
