//! What the packet walk needs of a node format, for 4-wide ([`Node4`]) and 8-wide
//! ([`Bvh8Node`]) nodes: the first ray's test of all children, a child's box and link, the
//! cull test, and the single-ray walks a ray continues with once the packet comes apart.

use super::bound::Bound;
use crate::geometry::{Hit, Ray};
use crate::layout::{Bvh4Node, Bvh8Node, Node4};
use crate::primitive::Primitive;
use crate::traverse::bvh4::{self, Ray4};
use crate::traverse::bvh8::{self, Ray8};
use crate::traverse::lane8::F8;
use crate::traverse::leaves::Leaves;
use crate::traverse::{Ask, BoxTest, Filter, Stats};

/// A node format the packet walk runs over. `V` is the lane type of the kernel (portable or
/// AVX2), which the 8-wide format also tests its boxes with.
pub(crate) trait PacketNode: Sized {
    /// Children per node.
    const WIDTH: usize;
    /// The first ray of a packet prepared for the node test.
    type First<V: F8>;
    /// Prepares the node test for a ray with this origin, slab reciprocals and `t_min`.
    fn first<V: F8>(cpu: V::Cpu, origin: [f32; 3], inv: [f32; 3], t_min: f32) -> Self::First<V>;
    /// Entry distances of the children (lanes from `WIDTH` on unused) and the mask of those
    /// the prepared ray enters within `t_max` (already scaled by the box test's slack).
    fn enter_first<V: F8, B: BoxTest>(&self, r: &Self::First<V>, t_max: f32) -> ([f32; 8], u32);
    /// Child `i`: node index or first primitive, and 0 (inner) or `LEAF | count`; `LEAF`
    /// alone marks an unused slot.
    fn child(&self, i: usize) -> (u32, u32);
    /// Child `i`'s box as `[min xyz, max xyz]`.
    fn slot_box(&self, i: usize) -> [f32; 6];
    /// Mask of the children some active ray of the bound may enter.
    fn may_enter<V: F8, B: BoxTest>(&self, cpu: V::Cpu, bound: &Bound) -> u32;
    /// The search `A` of one ray in the subtree of inner node `root`, improving `best`.
    #[allow(clippy::too_many_arguments)]
    fn search_from<V: F8, A: Ask, B: BoxTest, P: Primitive, S: Stats, F: Filter<Hit>>(
        cpu: V::Cpu,
        nodes: &[Self],
        leaves: &Leaves<P>,
        ray: &Ray,
        root: usize,
        best: &mut Hit,
        stats: &mut S,
        filter: &mut F,
    );
}

/// The leaf flag shared by both formats' child links.
pub(crate) const LEAF: u32 = Bvh4Node::LEAF;
const _: () = assert!(Bvh4Node::LEAF == Bvh8Node::LEAF);

impl<N: Node4> PacketNode for N {
    const WIDTH: usize = 4;
    type First<V: F8> = Ray4;

    #[inline(always)]
    fn first<V: F8>(_: V::Cpu, origin: [f32; 3], inv: [f32; 3], t_min: f32) -> Ray4 {
        Ray4::from_parts(origin, inv, t_min)
    }

    #[inline(always)]
    fn enter_first<V: F8, B: BoxTest>(&self, r: &Ray4, t_max: f32) -> ([f32; 8], u32) {
        let (t, mask) = r.enter::<B>(&self.planes(), t_max);
        let mut t8 = [0.0; 8];
        t8[..4].copy_from_slice(&t);
        (t8, mask)
    }

    #[inline(always)]
    fn child(&self, i: usize) -> (u32, u32) {
        Node4::child(self, i)
    }

    #[inline(always)]
    fn slot_box(&self, i: usize) -> [f32; 6] {
        let p = self.planes();
        let at = |r: usize| p[r].as_array()[i];
        [at(0), at(1), at(2), at(3), at(4), at(5)]
    }

    #[inline(always)]
    fn may_enter<V: F8, B: BoxTest>(&self, _: V::Cpu, bound: &Bound) -> u32 {
        bound.may_enter::<B>(&self.planes())
    }

    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    fn search_from<V: F8, A: Ask, B: BoxTest, P: Primitive, S: Stats, F: Filter<Hit>>(
        cpu: V::Cpu,
        nodes: &[Self],
        leaves: &Leaves<P>,
        ray: &Ray,
        root: usize,
        best: &mut Hit,
        stats: &mut S,
        filter: &mut F,
    ) {
        bvh4::search_from::<V, N, A, B, P, S, F>(cpu, nodes, leaves, ray, root, best, stats, filter)
    }
}

impl PacketNode for Bvh8Node {
    const WIDTH: usize = 8;
    type First<V: F8> = Ray8<V>;

    #[inline(always)]
    fn first<V: F8>(cpu: V::Cpu, origin: [f32; 3], inv: [f32; 3], t_min: f32) -> Ray8<V> {
        Ray8::from_parts(cpu, origin, inv, t_min)
    }

    #[inline(always)]
    fn enter_first<V: F8, B: BoxTest>(&self, r: &Ray8<V>, t_max: f32) -> ([f32; 8], u32) {
        r.enter::<B>(self, t_max)
    }

    #[inline(always)]
    fn child(&self, i: usize) -> (u32, u32) {
        (self.child[i], self.count[i])
    }

    #[inline(always)]
    fn slot_box(&self, i: usize) -> [f32; 6] {
        let p = &self.planes;
        [p[0][i], p[1][i], p[2][i], p[3][i], p[4][i], p[5][i]]
    }

    #[inline(always)]
    fn may_enter<V: F8, B: BoxTest>(&self, cpu: V::Cpu, bound: &Bound) -> u32 {
        bound.may_enter8::<V, B>(cpu, &self.planes)
    }

    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    fn search_from<V: F8, A: Ask, B: BoxTest, P: Primitive, S: Stats, F: Filter<Hit>>(
        cpu: V::Cpu,
        nodes: &[Self],
        leaves: &Leaves<P>,
        ray: &Ray,
        root: usize,
        best: &mut Hit,
        stats: &mut S,
        filter: &mut F,
    ) {
        bvh8::search_from::<V, A, B, P, S, F>(cpu, nodes, leaves, ray, root, best, stats, filter)
    }
}
