//! Single-ray traversal of 8-wide BVHs ([`Bvh8`]) and their [`RayQuery`]: the eight child
//! boxes of a node in one 8-lane slab test, written once over the lanes of every instruction
//! set ([`F8`]; `dispatch` picks), which compute every lane with the same operations in the
//! same order, so every instruction set visits the same nodes and returns the same hits.
//! Closest hit visits hit children nearest first; any hit takes them unordered and stops at
//! the first hit.

use super::dispatch::{self, LaneKernel};
use super::lane8::F8;
use super::leaves::Leaves;
use super::packet::{self, InLanes, PacketQuery, RayPacket};
use super::simd::bits;
use super::stats::Stats;
use super::{slab_reciprocal, Ask, BoxTest, Filter, RayQuery, Stack};
use crate::builders::MAX_DEPTH;
use crate::geometry::{Hit, Ray};
use crate::isa::Kernels;
use crate::layout::ends::Bvh8Ends;
use crate::layout::{Bvh8, Bvh8Node};
use crate::primitive::Primitive;
use std::marker::PhantomData;
use wide::f32x8;

/// A ray prepared for the slab test of a node's eight boxes in eight lanes of `V`.
pub(crate) struct Ray8<V: F8> {
    cpu: V::Cpu,
    origin: [V; 3],
    inv: [V; 3],
    /// Per axis, the plane row entered first (min row, or max row for a negative direction).
    near: [usize; 3],
    far: [usize; 3],
    t_min: V,
}

impl<V: F8> Ray8<V> {
    #[inline(always)]
    pub(crate) fn new(cpu: V::Cpu, ray: &Ray) -> Self {
        Self::from_parts(
            cpu,
            ray.origin.into(),
            slab_reciprocal(ray.dir).into(),
            ray.t_min,
        )
    }

    /// From an origin, the slab reciprocals of the direction and `t_min`.
    #[inline(always)]
    pub(crate) fn from_parts(cpu: V::Cpu, origin: [f32; 3], inv: [f32; 3], t_min: f32) -> Self {
        let neg = inv.map(|x| x.is_sign_negative() as usize);
        Ray8 {
            cpu,
            origin: V::splat3(cpu, origin),
            inv: V::splat3(cpu, inv),
            near: [0, 1, 2].map(|a| a + 3 * neg[a]),
            far: [0, 1, 2].map(|a| a + 3 - 3 * neg[a]),
            t_min: V::splat(cpu, t_min),
        }
    }

    /// Entry distances of the eight boxes and the mask of those entered within
    /// `[t_min, t_max]` (boundaries included; `t_max` already scaled by the box test's slack).
    #[inline(always)]
    pub(crate) fn enter<B: BoxTest>(&self, n: &Bvh8Node, t_max: f32) -> ([f32; 8], u32) {
        let (near, mask) = self.enter_lanes::<B>(n, t_max);
        (near.to_array(), mask)
    }

    /// [`Ray8::enter`] with the distances left in lanes.
    #[inline(always)]
    pub(crate) fn enter_lanes<B: BoxTest>(&self, n: &Bvh8Node, t_max: f32) -> (V, u32) {
        self.enter_planes::<B>(
            #[inline(always)]
            |row| V::load(self.cpu, &n.planes[row]),
            t_max,
        )
    }

    /// [`Ray8::enter_lanes`] with the plane rows given by `p` (row `r` as
    /// [`Bvh8Node::planes`] orders them).
    #[inline(always)]
    fn enter_planes<B: BoxTest>(&self, p: impl Fn(usize) -> V, t_max: f32) -> (V, u32) {
        let slack = V::splat(self.cpu, B::SLACK);
        let mut near = self.t_min;
        let mut far = V::splat(self.cpu, t_max);
        for a in 0..3 {
            let tn = p(self.near[a]).sub(self.origin[a]).mul(self.inv[a]);
            let tf = p(self.far[a]).sub(self.origin[a]).mul(self.inv[a]);
            near = tn.max_nan_first(near);
            far = tf.mul(slack).min_nan_first(far);
        }
        (near, near.le_bits(far))
    }
}

/// How the walk meets node `node`'s eight child boxes: the entry distances in lanes and the
/// mask of the boxes entered within `[t_min, t_max]`.
pub(crate) trait Enter8<V: F8> {
    fn enter_node<B: BoxTest>(&self, node: usize, n: &Bvh8Node, t_max: f32) -> (V, u32);
}

impl<V: F8> Enter8<V> for Ray8<V> {
    #[inline(always)]
    fn enter_node<B: BoxTest>(&self, _: usize, n: &Bvh8Node, t_max: f32) -> (V, u32) {
        self.enter_lanes::<B>(n, t_max)
    }
}

/// A ray at its time against nodes whose boxes move over the shutter ([`Bvh8Ends`], one per
/// node): each child box taken where it is at that time.
pub(crate) struct Ray8At<'a, V: F8> {
    ray: Ray8<V>,
    time: V,
    ends: &'a [Bvh8Ends],
}

impl<'a, V: F8> Ray8At<'a, V> {
    /// `ray` at its shutter time, against `ends` (one per node of the array walked).
    #[inline(always)]
    pub(crate) fn new(cpu: V::Cpu, ray: &Ray, ends: &'a [Bvh8Ends]) -> Self {
        Ray8At {
            ray: Ray8::new(cpu, ray),
            time: V::splat(cpu, ray.shutter_time()),
            ends,
        }
    }
}

impl<V: F8> Enter8<V> for Ray8At<'_, V> {
    #[inline(always)]
    fn enter_node<B: BoxTest>(&self, node: usize, _: &Bvh8Node, t_max: f32) -> (V, u32) {
        let e = &self.ends[node];
        let cpu = self.ray.cpu;
        self.ray.enter_planes::<B>(
            #[inline(always)]
            |row| V::load(cpu, &e.start[row]).add(V::load(cpu, &e.delta[row]).mul(self.time)),
            t_max,
        )
    }
}

/// The walk over the subtree of inner node `root`, searching up to `limit`: `leaf(first,
/// count, limit, stats)` tests a leaf (its first primitive or group, and its primitive
/// count), may lower the limit, and returns true to stop. Where a node sends the ray into
/// several children, `touch(child, count)` is told of each as it is pushed, so it can start
/// loading them: one is taken next, the others wait on the stack, and their cache misses
/// then overlap the work in between instead of each stalling the walk in turn. Closest hit
/// visits hit children nearest first; any hit (`A::ANY`) in slot order (it stops at the
/// first hit and gains nothing from sorting).
#[inline(always)]
pub(crate) fn walk<V, A, B, S, F>(
    nodes: &[Bvh8Node],
    ray: &impl Enter8<V>,
    root: usize,
    mut limit: f32,
    stats: &mut S,
    mut leaf: F,
    touch: impl Fn(u32, u32),
) where
    V: F8,
    A: Ask,
    B: BoxTest,
    S: Stats,
    F: FnMut(usize, u32, &mut f32, &mut S) -> bool,
{
    // Each node pushes at most seven entries beyond the one it continues with.
    let mut stack: Stack<(u32, u32, f32), { 7 * MAX_DEPTH + 8 }> = Stack::new();
    let mut node = root;
    loop {
        let n = &nodes[node];
        stats.node();
        stats.boxes(8);
        let (near, mask) = ray.enter_node::<B>(node, n, limit * B::SLACK);
        // The child taken next is held here rather than pushed and popped: the next node's
        // address then does not wait on a store and a load through the stack. The held entry
        // is a plain value each pop replaces: taken through an `Option` chain
        // (`take().or_else(pop)`, or a helper returning one), LLVM zeroed the whole
        // `MaybeUninit` stack on every ray.
        let mut next = if mask.is_power_of_two() {
            // One child hit (the common case): nothing to order.
            let i = mask.trailing_zeros() as usize;
            (n.child[i], n.count[i], near.to_array()[i])
        } else if mask != 0 {
            if !A::ANY {
                // Push hit children farthest first and take the nearest (see
                // `F8::order_hits`: the lanes order them, in registers where they can).
                let (k, child, count, t) = near.order_hits(mask, &n.child, &n.count);
                for j in 0..k - 1 {
                    touch(child[j], count[j]);
                    stack.push((child[j], count[j], t[j]));
                }
                (child[k - 1], count[k - 1], t[k - 1])
            } else {
                // Any order serves; the last hit child is taken next.
                let t = near.to_array();
                let last = 31 - mask.leading_zeros() as usize;
                for i in bits(mask & !(1 << last)) {
                    touch(n.child[i], n.count[i]);
                    stack.push((n.child[i], n.count[i], t[i]));
                }
                (n.child[last], n.count[last], t[last])
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
            let beyond = ti > limit * B::SLACK;
            if !beyond {
                if count & Bvh8Node::LEAF == 0 {
                    node = c as usize;
                    break;
                }
                stats.node();
                stats.leaf();
                if leaf(c as usize, count & !Bvh8Node::LEAF, &mut limit, stats) {
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

/// Starts loading a child the walk pushed: an inner node's four lines, or a leaf's first
/// group.
#[inline(always)]
fn touch<P: Primitive>(nodes: &[Bvh8Node], leaves: &Leaves<P>, c: u32, count: u32) {
    if count & Bvh8Node::LEAF == 0 {
        crate::isa::prefetch_index(nodes, c as usize, 4);
    } else {
        leaves.prefetch(c as usize);
    }
}

/// The search `A` in the subtree of inner node `root`, improving `best`, whose distance is the
/// search limit (the ray's `t_min` raised already). `FAR`: the leaves' far-group path,
/// compiled in only for a layout that holds far groups.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub(crate) fn search<V, A, B, P, S, F, const FAR: bool>(
    cpu: V::Cpu,
    nodes: &[Bvh8Node],
    leaves: &Leaves<P>,
    ray: &Ray,
    root: usize,
    best: &mut Hit,
    stats: &mut S,
    filter: &mut F,
) where
    V: F8,
    A: Ask,
    B: BoxTest,
    P: Primitive,
    S: Stats,
    F: Filter<Hit>,
{
    // Prepared at the first leaf: many rays never reach one.
    let mut prep = None;
    let r8 = Ray8::<V>::new(cpu, ray);
    walk::<V, A, B, S, _>(
        nodes,
        &r8,
        root,
        best.t,
        stats,
        #[inline(always)]
        |first, count, limit, stats| {
            let found = leaves
                .test::<V, A, S, F, FAR>(cpu, first, count, ray, &mut prep, best, stats, filter);
            if A::ANY {
                return found;
            }
            *limit = best.t;
            false
        },
        #[inline(always)]
        |c, count| touch(nodes, leaves, c, count),
    );
}

/// [`search`] with the far-group path picked at run time, for a walk that starts in another
/// (a packet's ray continuing alone, a world's ray entering an instance): the far path is a
/// cold call of its own, and `best` goes to it by value, so the fast walk's search state
/// never has its address taken.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub(crate) fn search_from<V, A, B, P, S, F>(
    cpu: V::Cpu,
    nodes: &[Bvh8Node],
    leaves: &Leaves<P>,
    ray: &Ray,
    root: usize,
    best: &mut Hit,
    stats: &mut S,
    filter: &mut F,
) where
    V: F8,
    A: Ask,
    B: BoxTest,
    P: Primitive,
    S: Stats,
    F: Filter<Hit>,
{
    if leaves.far.any() {
        *best = search_far::<A, B, P, S, F>(nodes, leaves, ray, root, *best, stats, filter);
        return;
    }
    search::<V, A, B, P, S, F, false>(cpu, nodes, leaves, ray, root, best, stats, filter);
}

/// [`search`] over a layout holding far groups, on the portable lanes (as `dispatch` runs such
/// a layout), in a cold function of its own.
#[cold]
#[inline(never)]
#[allow(clippy::too_many_arguments)]
fn search_far<A, B, P, S, F>(
    nodes: &[Bvh8Node],
    leaves: &Leaves<P>,
    ray: &Ray,
    root: usize,
    mut best: Hit,
    stats: &mut S,
    filter: &mut F,
) -> Hit
where
    A: Ask,
    B: BoxTest,
    P: Primitive,
    S: Stats,
    F: Filter<Hit>,
{
    search::<f32x8, A, B, P, S, F, true>((), nodes, leaves, ray, root, &mut best, stats, filter);
    best
}

/// One ray's query of a [`Bvh8`], as the kernel [`dispatch`] runs.
struct Trace<'a, P, A, B, S, F> {
    bvh: &'a Bvh8<P>,
    ray: &'a Ray,
    stats: &'a mut S,
    filter: &'a mut F,
    ask: PhantomData<(A, B)>,
}

impl<P, A, B, S, F> LaneKernel for Trace<'_, P, A, B, S, F>
where
    P: Primitive,
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
        search::<V, A, B, P, S, F, FAR>(
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

impl<P: Primitive> RayQuery for Bvh8<P> {
    type Hit = Hit;

    fn trace_with<A: Ask, B: BoxTest, S: Stats, F: Filter<Hit>>(
        &self,
        ray: &Ray,
        stats: &mut S,
        filter: &mut F,
    ) -> A::Answer<Hit> {
        let kernel = Trace::<P, A, B, S, F> {
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
        packet::trace_rays::<Bvh8Node, A, B, P, S, F>(
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

impl<P: Primitive> Bvh8<P> {
    /// The search `A` of `ray` (its `t_min` raised already) improving `best`, on the caller's
    /// lanes `V`, which run `kernels` (a world's ray entering an instance): the 8-wide walk
    /// inlined into the caller's, without this BVH's dispatch and call. False, with nothing
    /// done, where this BVH runs other kernels.
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn one_ray<V: F8, A: Ask, B: BoxTest, S: Stats, F: Filter<Hit>>(
        &self,
        kernels: Kernels,
        cpu: V::Cpu,
        ray: &Ray,
        best: &mut Hit,
        stats: &mut S,
        filter: &mut F,
    ) -> bool {
        let ours = self.kernels == kernels;
        if ours && !self.nodes.is_empty() {
            let leaves = self.leaves();
            search_from::<V, A, B, P, S, F>(cpu, &self.nodes, &leaves, ray, 0, best, stats, filter);
        }
        ours
    }

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
            packet::in_lanes::<Bvh8Node, V, A, B, P, S, F>(
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
