//! Single-ray traversal of 8-wide BVHs: the eight child boxes of a node in one 8-lane slab
//! test. Two implementations of that test, chosen per BVH ([`crate::Isa`]): `wide::f32x8`
//! (two SSE halves on baseline x86-64) and AVX2 intrinsics (one 256-bit register), which
//! compute every lane with the same operations in the same order, so both walks visit the
//! same nodes and return the same hits. Closest hit visits hit children nearest first; any
//! hit pushes them unordered and stops at the first hit.

use super::lane8::F8;
use super::leaves::Leaves;
use super::simd::{bits, insert_farthest_first};
use super::stats::Stats;
use super::{slab_reciprocal, BoxTest, Filter, Stack};
use crate::builders::MAX_DEPTH;
use crate::geometry::{Hit, Ray};
use crate::isa::Kernels;
use crate::layout::{Bvh8, Bvh8Node};
use crate::primitive::Primitive;
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
        let p = |row: usize| V::load(self.cpu, &n.planes[row]);
        let slack = V::splat(self.cpu, B::SLACK);
        let mut near = self.t_min;
        let mut far = V::splat(self.cpu, t_max);
        for a in 0..3 {
            let tn = p(self.near[a]).sub(self.origin[a]).mul(self.inv[a]);
            let tf = p(self.far[a]).sub(self.origin[a]).mul(self.inv[a]);
            near = tn.max_nan_first(near);
            far = tf.mul(slack).min_nan_first(far);
        }
        (near.to_array(), near.le(far).bitmask())
    }
}

/// The walk over the subtree of inner node `root`, searching up to `limit`: `leaf(first,
/// count, limit, stats)` tests a leaf (its first primitive or group, and its primitive
/// count), may lower the limit, and returns true to stop. Where a node sends the ray into
/// several children, `touch(child, count)` is told of each as it is pushed, so it can start
/// loading them: one is taken next, the others wait on the stack, and their cache misses
/// then overlap the work in between instead of each stalling the walk in turn. `ORDERED`:
/// visit hit children nearest first (closest hit) or in slot order (any hit, which stops at
/// the first hit and gains nothing from sorting).
#[inline(always)]
pub(crate) fn walk<V, B, S, F, const ORDERED: bool>(
    nodes: &[Bvh8Node],
    ray: &Ray8<V>,
    root: usize,
    mut limit: f32,
    stats: &mut S,
    mut leaf: F,
    touch: impl Fn(u32, u32),
) where
    V: F8,
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
        let (t, mask) = ray.enter::<B>(n, limit * B::SLACK);
        // The child taken next is held here rather than pushed and popped: the next node's
        // address then does not wait on a store and a load through the stack. The held entry
        // is a plain value each pop replaces: taken through an `Option` chain
        // (`take().or_else(pop)`, or a helper returning one), LLVM zeroed the whole
        // `MaybeUninit` stack on every ray.
        let mut next = if mask.is_power_of_two() {
            // One child hit (the common case): nothing to order.
            let i = mask.trailing_zeros() as usize;
            (n.child[i], n.count[i], t[i])
        } else if mask != 0 {
            if ORDERED {
                // Push hit children farthest first and take the nearest. Measured against
                // per-octant precomputed orders (children by centre along the ray's octant, 32
                // more bytes a node): those ran eye rays 4-29% faster but incoherent rays up
                // to 12% slower (`quiver layouts`, 1 thread, medians of 3 runs), and the
                // nearest hit child first plus octant order for the rest was slower than both.
                let mut hits = [(0.0f32, 0u32); 8];
                let mut k = 0;
                for i in bits(mask) {
                    insert_farthest_first(&mut hits, k, t[i], i as u32);
                    k += 1;
                }
                let (tn, near) = hits[k - 1];
                for &(ti, i) in &hits[..k - 1] {
                    touch(n.child[i as usize], n.count[i as usize]);
                    stack.push((n.child[i as usize], n.count[i as usize], ti));
                }
                (n.child[near as usize], n.count[near as usize], tn)
            } else {
                // Any order serves; the last hit child is taken next.
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

/// Closest hit in the subtree of inner node `root`, improving on `best`, whose distance is
/// the search limit.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub(crate) fn closest_from<V: F8, B: BoxTest, P: Primitive, S: Stats, F: Filter<Hit>>(
    cpu: V::Cpu,
    nodes: &[Bvh8Node],
    leaves: &Leaves<P>,
    ray: &Ray,
    root: usize,
    best: &mut Hit,
    stats: &mut S,
    filter: &mut F,
) {
    if leaves.far.any() {
        *best = closest_far::<V, B, P, S, F>(cpu, nodes, leaves, ray, root, *best, stats, filter);
        return;
    }
    closest_walk::<V, B, P, S, F, false>(cpu, nodes, leaves, ray, root, best, stats, filter);
}

/// [`closest_from`] over a layout holding far groups ([`crate::layout::Tri4`]), out of the
/// fast walk's line; `best` by value, so the fast walk's never has its address taken.
#[cold]
#[inline(never)]
#[allow(clippy::too_many_arguments)]
fn closest_far<V: F8, B: BoxTest, P: Primitive, S: Stats, F: Filter<Hit>>(
    cpu: V::Cpu,
    nodes: &[Bvh8Node],
    leaves: &Leaves<P>,
    ray: &Ray,
    root: usize,
    mut best: Hit,
    stats: &mut S,
    filter: &mut F,
) -> Hit {
    closest_walk::<V, B, P, S, F, true>(cpu, nodes, leaves, ray, root, &mut best, stats, filter);
    best
}

/// The closest-hit walk, its leaves with the far groups' path compiled in or out (`FAR`).
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn closest_walk<V: F8, B: BoxTest, P: Primitive, S: Stats, F: Filter<Hit>, const FAR: bool>(
    cpu: V::Cpu,
    nodes: &[Bvh8Node],
    leaves: &Leaves<P>,
    ray: &Ray,
    root: usize,
    best: &mut Hit,
    stats: &mut S,
    filter: &mut F,
) {
    // Prepared at the first leaf: many rays never reach one.
    let mut prep = None;
    let r8 = Ray8::<V>::new(cpu, ray);
    walk::<V, B, S, _, true>(
        nodes,
        &r8,
        root,
        best.t,
        stats,
        #[inline(always)]
        |first, count, limit, stats| {
            leaves.closest_as::<S, F, FAR>(first, count, ray, &mut prep, best, stats, filter);
            *limit = best.t;
            false
        },
        #[inline(always)]
        |c, count| touch(nodes, leaves, c, count),
    );
}

/// Whether anything in the subtree of inner node `root` is hit.
#[inline(always)]
pub(crate) fn any_from<V: F8, B: BoxTest, P: Primitive, S: Stats, F: Filter<Hit>>(
    cpu: V::Cpu,
    nodes: &[Bvh8Node],
    leaves: &Leaves<P>,
    ray: &Ray,
    root: usize,
    stats: &mut S,
    filter: &mut F,
) -> bool {
    if leaves.far.any() {
        return any_far::<V, B, P, S, F>(cpu, nodes, leaves, ray, root, stats, filter);
    }
    any_walk::<V, B, P, S, F, false>(cpu, nodes, leaves, ray, root, stats, filter)
}

/// [`any_from`] over a layout holding far groups, out of the fast walk's line.
#[cold]
#[inline(never)]
fn any_far<V: F8, B: BoxTest, P: Primitive, S: Stats, F: Filter<Hit>>(
    cpu: V::Cpu,
    nodes: &[Bvh8Node],
    leaves: &Leaves<P>,
    ray: &Ray,
    root: usize,
    stats: &mut S,
    filter: &mut F,
) -> bool {
    any_walk::<V, B, P, S, F, true>(cpu, nodes, leaves, ray, root, stats, filter)
}

/// The any-hit walk, its leaves with the far groups' path compiled in or out (`FAR`).
#[inline(always)]
fn any_walk<V: F8, B: BoxTest, P: Primitive, S: Stats, F: Filter<Hit>, const FAR: bool>(
    cpu: V::Cpu,
    nodes: &[Bvh8Node],
    leaves: &Leaves<P>,
    ray: &Ray,
    root: usize,
    stats: &mut S,
    filter: &mut F,
) -> bool {
    let mut prep = None;
    let mut hit = false;
    let r8 = Ray8::<V>::new(cpu, ray);
    walk::<V, B, S, _, false>(
        nodes,
        &r8,
        root,
        ray.t_max,
        stats,
        #[inline(always)]
        |first, count, _, stats| {
            hit = leaves.any_as::<S, F, FAR>(first, count, ray, &mut prep, stats, filter);
            hit
        },
        #[inline(always)]
        |c, count| touch(nodes, leaves, c, count),
    );
    hit
}

/// Closest hit over lanes of `V`, the leaves' far path compiled in or out (`FAR`: the
/// layout's `far`).
#[inline(always)]
fn closest<V: F8, B: BoxTest, P: Primitive, S: Stats, F: Filter<Hit>, const FAR: bool>(
    cpu: V::Cpu,
    bvh: &Bvh8<P>,
    ray: &Ray,
    stats: &mut S,
    filter: &mut F,
) -> Option<Hit> {
    let ray = &ray.raised_t_min();
    let mut best = Hit::none(ray.t_max);
    let leaves = bvh.leaves();
    closest_walk::<V, B, P, S, F, FAR>(cpu, &bvh.nodes, &leaves, ray, 0, &mut best, stats, filter);
    best.found()
}

/// Any hit over lanes of `V` (`FAR` as for [`closest`]).
#[inline(always)]
fn any<V: F8, B: BoxTest, P: Primitive, S: Stats, F: Filter<Hit>, const FAR: bool>(
    cpu: V::Cpu,
    bvh: &Bvh8<P>,
    ray: &Ray,
    stats: &mut S,
    filter: &mut F,
) -> bool {
    let ray = &ray.raised_t_min();
    any_walk::<V, B, P, S, F, FAR>(cpu, &bvh.nodes, &bvh.leaves(), ray, 0, stats, filter)
}

/// The closest hit of one ray on `kernels`: the one place a single-ray 8-wide query picks
/// its lanes. A layout holding far groups takes its own kernels, so the others carry no
/// trace of that path.
#[inline]
pub(crate) fn closest_on<B: BoxTest, P: Primitive, S: Stats, F: Filter<Hit>>(
    kernels: Kernels,
    bvh: &Bvh8<P>,
    ray: &Ray,
    stats: &mut S,
    filter: &mut F,
) -> Option<Hit> {
    if bvh.far.any() {
        return closest_on_far::<B, P, S, F>(kernels, bvh, ray, stats, filter);
    }
    closest_on_as::<B, P, S, F, false>(kernels, bvh, ray, stats, filter)
}

#[cold]
#[inline(never)]
fn closest_on_far<B: BoxTest, P: Primitive, S: Stats, F: Filter<Hit>>(
    kernels: Kernels,
    bvh: &Bvh8<P>,
    ray: &Ray,
    stats: &mut S,
    filter: &mut F,
) -> Option<Hit> {
    closest_on_as::<B, P, S, F, true>(kernels, bvh, ray, stats, filter)
}

#[inline(always)]
fn closest_on_as<B: BoxTest, P: Primitive, S: Stats, F: Filter<Hit>, const FAR: bool>(
    kernels: Kernels,
    bvh: &Bvh8<P>,
    ray: &Ray,
    stats: &mut S,
    filter: &mut F,
) -> Option<Hit> {
    match kernels {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: `cpu` proves the CPU has AVX2 and FMA (only detection makes one).
        Kernels::Avx2(cpu) => unsafe {
            avx2::closest::<B, P, S, F, FAR>(cpu, bvh, ray, stats, filter)
        },
        _ => closest::<f32x8, B, P, S, F, FAR>((), bvh, ray, stats, filter),
    }
}

/// Whether one ray hits anything, on `kernels` (see [`closest_on`]).
#[inline]
pub(crate) fn any_on<B: BoxTest, P: Primitive, S: Stats, F: Filter<Hit>>(
    kernels: Kernels,
    bvh: &Bvh8<P>,
    ray: &Ray,
    stats: &mut S,
    filter: &mut F,
) -> bool {
    if bvh.far.any() {
        return any_on_far::<B, P, S, F>(kernels, bvh, ray, stats, filter);
    }
    any_on_as::<B, P, S, F, false>(kernels, bvh, ray, stats, filter)
}

#[cold]
#[inline(never)]
fn any_on_far<B: BoxTest, P: Primitive, S: Stats, F: Filter<Hit>>(
    kernels: Kernels,
    bvh: &Bvh8<P>,
    ray: &Ray,
    stats: &mut S,
    filter: &mut F,
) -> bool {
    any_on_as::<B, P, S, F, true>(kernels, bvh, ray, stats, filter)
}

#[inline(always)]
fn any_on_as<B: BoxTest, P: Primitive, S: Stats, F: Filter<Hit>, const FAR: bool>(
    kernels: Kernels,
    bvh: &Bvh8<P>,
    ray: &Ray,
    stats: &mut S,
    filter: &mut F,
) -> bool {
    match kernels {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: as in `closest_on_as`.
        Kernels::Avx2(cpu) => unsafe { avx2::any::<B, P, S, F, FAR>(cpu, bvh, ray, stats, filter) },
        _ => any::<f32x8, B, P, S, F, FAR>((), bvh, ray, stats, filter),
    }
}

/// The AVX2 kernels: the same walks on 256-bit registers, compiled with AVX2 enabled (every
/// function they call is inlined into these).
#[cfg(target_arch = "x86_64")]
mod avx2 {
    use super::*;
    use crate::isa::Avx2Cpu;
    use crate::traverse::lane8::Avx;

    /// # Safety
    /// The CPU must support AVX2 and FMA (as `cpu` proves).
    #[target_feature(enable = "avx2,fma")]
    pub(super) unsafe fn closest<
        B: BoxTest,
        P: Primitive,
        S: Stats,
        F: Filter<Hit>,
        const FAR: bool,
    >(
        cpu: Avx2Cpu,
        bvh: &Bvh8<P>,
        ray: &Ray,
        stats: &mut S,
        filter: &mut F,
    ) -> Option<Hit> {
        super::closest::<Avx, B, P, S, F, FAR>(cpu, bvh, ray, stats, filter)
    }

    /// # Safety
    /// The CPU must support AVX2 and FMA (as `cpu` proves).
    #[target_feature(enable = "avx2,fma")]
    pub(super) unsafe fn any<
        B: BoxTest,
        P: Primitive,
        S: Stats,
        F: Filter<Hit>,
        const FAR: bool,
    >(
        cpu: Avx2Cpu,
        bvh: &Bvh8<P>,
        ray: &Ray,
        stats: &mut S,
        filter: &mut F,
    ) -> bool {
        super::any::<Avx, B, P, S, F, FAR>(cpu, bvh, ray, stats, filter)
    }
}
