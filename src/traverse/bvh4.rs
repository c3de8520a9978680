//! Single-ray traversal of 4-wide BVHs ([`Bvh4`], both node formats) and their
//! [`RayQuery`]: the four child boxes of a node are tested at once with `wide::f32x4`, hit
//! children are visited nearest first, any hit exits at the first hit.

use super::dispatch::{self, LaneKernel};
use super::lane8::F8;
use super::leaves::Leaves;
use super::packet::{self, InLanes, PacketQuery, RayPacket};
use super::simd::{bits, insert_farthest_first, NanFirst};
use super::stats::Stats;
use super::{slab_reciprocal, Ask, BoxTest, Filter, RayQuery, Stack};
use crate::builders::MAX_DEPTH;
use crate::geometry::{Hit, Ray};
use crate::isa::Kernels;
use crate::layout::{Bvh4, Bvh4Node};
use crate::primitive::Primitive;
use std::marker::PhantomData;
use wide::f32x4;

/// The kernels' name for a 4-wide node format.
pub(crate) use crate::layout::Node4 as WideNode;

/// A ray prepared for 4-wide slab tests.
pub(crate) struct Ray4 {
    origin: [f32x4; 3],
    inv: [f32x4; 3],
    /// Per axis, the plane row entered first (min row, or max row for a negative direction).
    near: [usize; 3],
    far: [usize; 3],
    t_min: f32x4,
}

impl Ray4 {
    #[inline(always)]
    fn new(ray: &Ray) -> Self {
        let inv = slab_reciprocal(ray.dir);
        Self::from_parts(ray.origin.into(), inv.into(), ray.t_min)
    }

    /// From an origin, the slab reciprocals of the direction and `t_min`.
    #[inline(always)]
    pub(crate) fn from_parts(origin: [f32; 3], inv: [f32; 3], t_min: f32) -> Self {
        let neg = inv.map(|x| x.is_sign_negative() as usize);
        Ray4 {
            origin: origin.map(f32x4::splat),
            inv: inv.map(f32x4::splat),
            near: [0, 1, 2].map(|a| a + 3 * neg[a]),
            far: [0, 1, 2].map(|a| a + 3 - 3 * neg[a]),
            t_min: f32x4::splat(t_min),
        }
    }

    /// Entry distances of the four boxes and the mask of those entered within
    /// `[t_min, t_max]` (boundaries included).
    #[inline(always)]
    pub(crate) fn enter<B: BoxTest>(&self, p: &[f32x4; 6], t_max: f32) -> ([f32; 4], u32) {
        let mut near = self.t_min;
        let mut far = f32x4::splat(t_max);
        for a in 0..3 {
            let tn = (p[self.near[a]] - self.origin[a]) * self.inv[a];
            let tf = (p[self.far[a]] - self.origin[a]) * self.inv[a];
            near = tn.max_nan_first(near);
            far = (tf * f32x4::splat(B::SLACK)).min_nan_first(far);
        }
        (near.to_array(), near.simd_le(far).to_bitmask())
    }
}

/// Stack entry: (node or first primitive, leaf count or 0, entry distance).
type Entry = (u32, u32, f32);

/// The 4-wide walk, shared by both node formats, over the subtree of inner node `root`,
/// searching up to `limit`. See `Bvh2`'s walk for the `leaf` contract. Closest hit visits hit
/// children nearest first, any hit (`A::ANY`) in slot order.
#[inline(always)]
fn walk<N, A, B, S, F>(
    nodes: &[N],
    ray: &Ray,
    root: usize,
    mut limit: f32,
    stats: &mut S,
    mut leaf: F,
) where
    N: WideNode,
    A: Ask,
    B: BoxTest,
    S: Stats,
    F: FnMut(std::ops::Range<usize>, &mut f32, &mut S) -> bool,
{
    let r4 = Ray4::new(ray);
    // Each node pushes at most three entries beyond the one it continues with.
    let mut stack: Stack<Entry, { 3 * MAX_DEPTH + 4 }> = Stack::new();
    let mut node = root;
    loop {
        let n = &nodes[node];
        stats.node();
        stats.boxes(4);
        let (t, mask) = r4.enter::<B>(&n.planes(), limit * B::SLACK);
        // The child taken next is held here rather than pushed and popped (as in the 8-wide
        // walk): the next node's address then does not wait on a store and a load through the
        // stack.
        let mut next = if mask.is_power_of_two() {
            // One child hit (the common case): nothing to order.
            let i = mask.trailing_zeros() as usize;
            let (c, count) = n.child(i);
            (c, count, t[i])
        } else if mask != 0 {
            if !A::ANY {
                // Push hit children farthest first and take the nearest.
                let mut hits = [(0.0f32, 0u32); 4];
                let mut k = 0;
                for i in bits(mask) {
                    insert_farthest_first(&mut hits, k, t[i], i as u32);
                    k += 1;
                }
                for &(ti, i) in &hits[..k - 1] {
                    let (c, count) = n.child(i as usize);
                    stack.push((c, count, ti));
                }
                let (tn, near) = hits[k - 1];
                let (c, count) = n.child(near as usize);
                (c, count, tn)
            } else {
                // Any hit stops at the first hit wherever it is: no ordering to pay for.
                let last = 31 - mask.leading_zeros() as usize;
                for i in bits(mask & !(1 << last)) {
                    let (c, count) = n.child(i);
                    stack.push((c, count, t[i]));
                }
                let (c, count) = n.child(last);
                (c, count, t[last])
            }
        } else {
            match stack.pop() {
                Some(e) => e,
                None => return,
            }
        };
        // From the held child, then popping, until an inner node worth entering; leaves are
        // handled on the way.
        loop {
            let (c, count, ti) = next;
            if ti <= limit * B::SLACK {
                if count & Bvh4Node::LEAF == 0 {
                    node = c as usize;
                    break;
                }
                let count = count & !Bvh4Node::LEAF;
                stats.node();
                stats.leaf();
                if leaf(c as usize..(c + count) as usize, &mut limit, stats) {
                    return;
                }
            }
            next = match stack.pop() {
                Some(e) => e,
                None => return,
            };
        }
    }
}

/// The search `A` in the subtree of inner node `root`, improving `best`, whose distance is the
/// search limit (the ray's `t_min` raised already). `FAR`: the leaves' far-group path,
/// compiled in only for a layout that holds far groups.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub(crate) fn search<V, N, A, B, P, S, F, const FAR: bool>(
    cpu: V::Cpu,
    nodes: &[N],
    leaves: &Leaves<P>,
    ray: &Ray,
    root: usize,
    best: &mut Hit,
    stats: &mut S,
    filter: &mut F,
) where
    N: WideNode,
    A: Ask,
    B: BoxTest,
    P: Primitive,
    S: Stats,
    F: Filter<Hit>,
    V: F8,
{
    let mut prep = None;
    walk::<N, A, B, S, _>(
        nodes,
        ray,
        root,
        best.t,
        stats,
        #[inline(always)]
        |range, limit, stats| {
            let count = range.len() as u32;
            let found = leaves.test::<V, A, S, F, FAR>(
                cpu,
                range.start,
                count,
                ray,
                &mut prep,
                best,
                stats,
                filter,
            );
            if A::ANY {
                return found;
            }
            *limit = best.t;
            false
        },
    );
}

/// [`search`] with the far-group path picked at run time (see `bvh8::search_from`).
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub(crate) fn search_from<V, N, A, B, P, S, F>(
    cpu: V::Cpu,
    nodes: &[N],
    leaves: &Leaves<P>,
    ray: &Ray,
    root: usize,
    best: &mut Hit,
    stats: &mut S,
    filter: &mut F,
) where
    V: F8,
    N: WideNode,
    A: Ask,
    B: BoxTest,
    P: Primitive,
    S: Stats,
    F: Filter<Hit>,
{
    if leaves.far.any() {
        *best = search_far::<N, A, B, P, S, F>(nodes, leaves, ray, root, *best, stats, filter);
        return;
    }
    search::<V, N, A, B, P, S, F, false>(cpu, nodes, leaves, ray, root, best, stats, filter);
}

/// [`search`] over a layout holding far groups, on the portable lanes, in a cold function of
/// its own (see `bvh8::search_from`).
#[cold]
#[inline(never)]
fn search_far<N, A, B, P, S, F>(
    nodes: &[N],
    leaves: &Leaves<P>,
    ray: &Ray,
    root: usize,
    mut best: Hit,
    stats: &mut S,
    filter: &mut F,
) -> Hit
where
    N: WideNode,
    A: Ask,
    B: BoxTest,
    P: Primitive,
    S: Stats,
    F: Filter<Hit>,
{
    let cpu = ();
    search::<wide::f32x8, N, A, B, P, S, F, true>(
        cpu, nodes, leaves, ray, root, &mut best, stats, filter,
    );
    best
}

/// One ray's query of a [`Bvh4`], as the kernel [`dispatch`] runs (its slab test is four
/// `f32x4` lanes on every instruction set; the dispatch picks the far-group path).
struct Trace<'a, P, N, A, B, S, F> {
    bvh: &'a Bvh4<P, N>,
    ray: &'a Ray,
    stats: &'a mut S,
    filter: &'a mut F,
    ask: PhantomData<(A, B)>,
}

impl<P, N, A, B, S, F> LaneKernel for Trace<'_, P, N, A, B, S, F>
where
    P: Primitive,
    N: WideNode,
    A: Ask,
    B: BoxTest,
    S: Stats,
    F: Filter<Hit>,
{
    type Out = A::Answer<Hit>;

    #[inline(always)]
    fn run<V: F8, const FAR: bool>(self, cpu: V::Cpu) -> A::Answer<Hit> {
        let ray = &self.ray.raised_t_min();
        let mut best = Hit::none(ray.t_max);
        let leaves = self.bvh.leaves();
        let nodes = &self.bvh.nodes;
        search::<V, N, A, B, P, S, F, FAR>(
            cpu,
            nodes,
            &leaves,
            ray,
            0,
            &mut best,
            self.stats,
            self.filter,
        );
        A::answer(best.found())
    }
}

impl<P: Primitive, N: WideNode> RayQuery for Bvh4<P, N> {
    type Hit = Hit;

    fn trace_with<A: Ask, B: BoxTest, S: Stats, F: Filter<Hit>>(
        &self,
        ray: &Ray,
        stats: &mut S,
        filter: &mut F,
    ) -> A::Answer<Hit> {
        let kernel = Trace::<P, N, A, B, S, F> {
            bvh: self,
            ray,
            stats,
            filter,
            ask: PhantomData,
        };
        dispatch::run(self.kernels, self.far.any(), kernel)
    }

    fn trace_packet_with<A: Ask, B: BoxTest, S: Stats, F: Filter<Hit>>(
        &self,
        query: PacketQuery<'_>,
        hits: &mut [A::Answer<Hit>],
        stats: &mut S,
        filter: &mut F,
    ) {
        let leaves = self.leaves();
        packet::trace_rays::<N, A, B, P, S, F>(
            self.kernels,
            &self.nodes,
            &leaves,
            query,
            hits,
            stats,
            filter,
        )
    }
}

impl<P: Primitive, N: WideNode> Bvh4<P, N> {
    /// `ask` of a packet already in lanes, on the caller's lanes `V`, which run `kernels`:
    /// false, with nothing done, where this BVH runs other kernels (ask it the usual way).
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn in_lanes<V: F8, A: Ask, B: BoxTest, S: Stats, F: Filter<Hit>>(
        &self,
        kernels: Kernels,
        cpu: V::Cpu,
        pk: &mut RayPacket,
        ask: InLanes<'_>,
        stats: &mut S,
        filter: &mut F,
    ) -> bool {
        let ours = self.kernels == kernels;
        if ours {
            let leaves = self.leaves();
            packet::in_lanes::<N, V, A, B, P, S, F>(
                cpu,
                &self.nodes,
                &leaves,
                pk,
                ask,
                stats,
                filter,
            );
        }
        ours
    }
}
