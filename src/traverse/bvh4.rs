//! Single-ray traversal of 4-wide BVHs: the four child boxes of a node are tested at once
//! with `wide::f32x4`, hit children are visited nearest first, any-hit exits at the first hit.

use super::leaves::Leaves;
use super::simd::{bits, insert_farthest_first, NanFirst};
use super::stats::Stats;
use super::{slab_reciprocal, BoxTest, Filter, Stack};
use crate::builders::MAX_DEPTH;
use crate::geometry::{Hit, Ray};
use crate::layout::Bvh4Node;
use crate::primitive::Primitive;
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
/// searching up to `limit`. See `Bvh2`'s walk for the `leaf` contract. `ORDERED`: visit hit
/// children nearest first (closest hit) or in slot order (any hit).
#[inline(always)]
fn walk<N, B, S, F, const ORDERED: bool>(
    nodes: &[N],
    ray: &Ray,
    root: usize,
    mut limit: f32,
    stats: &mut S,
    mut leaf: F,
) where
    N: WideNode,
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
        if ORDERED {
            // Push hit children farthest first, so the nearest is popped next.
            if mask.is_power_of_two() {
                // One child hit (the common case): nothing to order.
                let i = mask.trailing_zeros() as usize;
                let (c, count) = n.child(i);
                stack.push((c, count, t[i]));
            } else {
                let mut hits = [(0.0f32, 0u32); 4];
                let mut k = 0;
                for i in bits(mask) {
                    insert_farthest_first(&mut hits, k, t[i], i as u32);
                    k += 1;
                }
                for &(ti, i) in &hits[..k] {
                    let (c, count) = n.child(i as usize);
                    stack.push((c, count, ti));
                }
            }
        } else {
            // Any hit stops at the first hit wherever it is: no ordering to pay for.
            for i in bits(mask) {
                let (c, count) = n.child(i);
                stack.push((c, count, t[i]));
            }
        }
        // Pop until an inner node worth entering; leaves are handled on the way.
        loop {
            let Some((c, count, ti)) = stack.pop() else {
                return;
            };
            if ti > limit * B::SLACK {
                continue;
            }
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
    }
}

/// Closest-hit and any-hit over one 4-wide node format, the leaves' far path compiled in or
/// out (`FAR`: the layout's `far`; see `traverse::wide`, which picks).
#[inline(always)]
pub(crate) fn closest<
    N: WideNode,
    B: BoxTest,
    P: Primitive,
    S: Stats,
    F: Filter<Hit>,
    const FAR: bool,
>(
    nodes: &[N],
    leaves: &Leaves<P>,
    ray: &Ray,
    stats: &mut S,
    filter: &mut F,
) -> Option<Hit> {
    let ray = &ray.raised_t_min();
    let mut best = Hit::none(ray.t_max);
    closest_walk::<N, B, P, S, F, FAR>(nodes, leaves, ray, 0, &mut best, stats, filter);
    best.found()
}

/// Closest hit in the subtree of inner node `root`, improving on `best`, whose distance is
/// the search limit.
#[inline(always)]
pub(crate) fn closest_from<N: WideNode, B: BoxTest, P: Primitive, S: Stats, F: Filter<Hit>>(
    nodes: &[N],
    leaves: &Leaves<P>,
    ray: &Ray,
    root: usize,
    best: &mut Hit,
    stats: &mut S,
    filter: &mut F,
) {
    if leaves.far.any() {
        *best = closest_far::<N, B, P, S, F>(nodes, leaves, ray, root, *best, stats, filter);
        return;
    }
    closest_walk::<N, B, P, S, F, false>(nodes, leaves, ray, root, best, stats, filter);
}

/// [`closest_from`] over a layout holding far groups ([`crate::layout::Tri4`]), out of the
/// fast walk's line; `best` by value, so the fast walk's never has its address taken.
#[cold]
#[inline(never)]
fn closest_far<N: WideNode, B: BoxTest, P: Primitive, S: Stats, F: Filter<Hit>>(
    nodes: &[N],
    leaves: &Leaves<P>,
    ray: &Ray,
    root: usize,
    mut best: Hit,
    stats: &mut S,
    filter: &mut F,
) -> Hit {
    closest_walk::<N, B, P, S, F, true>(nodes, leaves, ray, root, &mut best, stats, filter);
    best
}

/// The closest-hit walk, its leaves with the far groups' path compiled in or out (`FAR`).
#[inline(always)]
fn closest_walk<
    N: WideNode,
    B: BoxTest,
    P: Primitive,
    S: Stats,
    F: Filter<Hit>,
    const FAR: bool,
>(
    nodes: &[N],
    leaves: &Leaves<P>,
    ray: &Ray,
    root: usize,
    best: &mut Hit,
    stats: &mut S,
    filter: &mut F,
) {
    let mut prep = None;
    walk::<N, B, S, _, true>(
        nodes,
        ray,
        root,
        best.t,
        stats,
        #[inline(always)]
        |range, limit, stats| {
            let count = range.len() as u32;
            leaves.closest_as::<S, F, FAR>(range.start, count, ray, &mut prep, best, stats, filter);
            *limit = best.t;
            false
        },
    );
}

#[inline(always)]
pub(crate) fn any<
    N: WideNode,
    B: BoxTest,
    P: Primitive,
    S: Stats,
    F: Filter<Hit>,
    const FAR: bool,
>(
    nodes: &[N],
    leaves: &Leaves<P>,
    ray: &Ray,
    stats: &mut S,
    filter: &mut F,
) -> bool {
    any_walk::<N, B, P, S, F, FAR>(nodes, leaves, &ray.raised_t_min(), 0, stats, filter)
}

/// Any hit in the subtree of inner node `root`.
#[inline(always)]
pub(crate) fn any_from<N: WideNode, B: BoxTest, P: Primitive, S: Stats, F: Filter<Hit>>(
    nodes: &[N],
    leaves: &Leaves<P>,
    ray: &Ray,
    root: usize,
    stats: &mut S,
    filter: &mut F,
) -> bool {
    if leaves.far.any() {
        return any_far::<N, B, P, S, F>(nodes, leaves, ray, root, stats, filter);
    }
    any_walk::<N, B, P, S, F, false>(nodes, leaves, ray, root, stats, filter)
}

/// [`any_from`] over a layout holding far groups, out of the fast walk's line.
#[cold]
#[inline(never)]
fn any_far<N: WideNode, B: BoxTest, P: Primitive, S: Stats, F: Filter<Hit>>(
    nodes: &[N],
    leaves: &Leaves<P>,
    ray: &Ray,
    root: usize,
    stats: &mut S,
    filter: &mut F,
) -> bool {
    any_walk::<N, B, P, S, F, true>(nodes, leaves, ray, root, stats, filter)
}

/// The any-hit walk, its leaves with the far groups' path compiled in or out (`FAR`).
#[inline(always)]
fn any_walk<N: WideNode, B: BoxTest, P: Primitive, S: Stats, F: Filter<Hit>, const FAR: bool>(
    nodes: &[N],
    leaves: &Leaves<P>,
    ray: &Ray,
    root: usize,
    stats: &mut S,
    filter: &mut F,
) -> bool {
    let mut prep = None;
    let mut hit = false;
    walk::<N, B, S, _, false>(
        nodes,
        ray,
        root,
        ray.t_max,
        stats,
        #[inline(always)]
        |range, _, stats| {
            let count = range.len() as u32;
            hit = leaves.any_as::<S, F, FAR>(range.start, count, ray, &mut prep, stats, filter);
            hit
        },
    );
    hit
}
