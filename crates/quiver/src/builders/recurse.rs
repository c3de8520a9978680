//! The recursion both builders share: leaf-or-split decision, depth guard, median fallback,
//! node slots and vertical (task) parallelism. A builder only supplies how to find and apply
//! the best SAH split of one node.

use super::{
    bounds_of, median_split, split_beats_leaf, BuildConfig, BuildNode, NodeKind, MEDIAN_DEPTH,
};
use crate::geometry::Aabb;
use glam::Vec3A;
use rayon::prelude::*;

/// Below this many primitives a subtree is built on the current thread: a rayon task costs
/// more than the work it would share.
const TASK_CUTOFF: usize = 512;

/// Chunk size for the horizontal (data-parallel) passes over one node's primitives.
pub(crate) const CHUNK: usize = 16 * 1024;

/// Everything a node's split needs to read.
pub(crate) struct Ctx<'a> {
    pub config: &'a BuildConfig,
    pub bounds: &'a [Aabb],
    pub centroids: &'a [Vec3A],
    /// Each primitive's surface area, for cost models other than the SAH (`None` for it).
    pub areas: Option<&'a [f32]>,
}

/// A node's primitives after a split: the first `left_len` go left.
pub(crate) struct Partition {
    pub left_len: usize,
    /// Bounds and centroid bounds of the left side.
    pub left: (Aabb, Aabb),
    /// Bounds and centroid bounds of the right side.
    pub right: (Aabb, Aabb),
}

/// How a builder splits one node.
pub(crate) trait Splitter: Sync {
    /// Finds the cheapest SAH split of `idx` and, if it beats a leaf (or `idx` is too large
    /// for a leaf), reorders `idx` (using `scratch` of equal length) and describes the halves.
    /// Returns `None` when no split separates the primitives or a leaf is cheaper.
    fn split(
        &self,
        ctx: &Ctx,
        idx: &mut [u32],
        scratch: &mut [u32],
        node: &Aabb,
        centroids: &Aabb,
    ) -> Option<Partition>;
}

/// True when a split with weighted child cost `weighted` should be taken for a node of `n`.
pub(crate) fn take_split(config: &BuildConfig, node_area: f32, weighted: f32, n: usize) -> bool {
    n > config.max_leaf_size || split_beats_leaf(config, node_area, weighted, n)
}

/// Builds the tree over `idx` (finite primitives only, at least one) and returns the nodes in
/// preorder together with `idx` reordered into leaf order.
pub(crate) fn build_tree<S: Splitter>(
    splitter: &S,
    bounds: &[Aabb],
    areas: Option<&[f32]>,
    mut idx: Vec<u32>,
    config: &BuildConfig,
) -> (Vec<BuildNode>, Vec<u32>) {
    assert!(
        idx.len() < (u32::MAX / 2) as usize,
        "too many primitives for 32-bit node indices"
    );
    let centroids: Vec<Vec3A> = bounds.par_iter().map(|b| b.center()).collect();
    let ctx = Ctx {
        config,
        bounds,
        centroids: &centroids,
        areas,
    };
    let (node, cent) = idx
        .par_chunks(CHUNK)
        .map(|ch| bounds_of(bounds, ch))
        .reduce(
            || (Aabb::EMPTY, Aabb::EMPTY),
            |a, b| (a.0.union(&b.0), a.1.union(&b.1)),
        );
    let mut scratch = vec![0u32; idx.len()];
    // A subtree over n primitives has at most 2n - 1 nodes. Giving each subtree exactly that
    // many slots fixes every node's position by the input alone, so parallel tasks write
    // disjoint ranges and the result cannot depend on scheduling.
    // Zeroed memory comes from the OS lazily, so the slots a tree never uses cost nothing.
    let mut slots: Vec<Slot> = bytemuck::zeroed_vec(2 * idx.len() - 1);
    let job = Job {
        splitter,
        ctx: &ctx,
    };
    job.node(&mut idx, &mut scratch, &mut slots, 0, 0, node, cent, 0);
    (compact(&slots), idx)
}

/// A node as the recursion writes it into its preallocated position; all zeros is "no node".
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Slot {
    min: [f32; 3],
    max: [f32; 3],
    /// Left child slot (inner) or first primitive (leaf).
    a: u32,
    /// Right child slot (inner) or primitive count (leaf).
    b: u32,
    tag: u32,
}

impl Slot {
    const INNER: u32 = 1;
    const LEAF: u32 = 2;

    fn new(bounds: &Aabb, tag: u32, a: u32, b: u32) -> Slot {
        Slot {
            min: bounds.min.into(),
            max: bounds.max.into(),
            a,
            b,
            tag,
        }
    }
}

/// Collects the nodes reachable from slot 0 into a gap-free preorder array. Walking the tree
/// (rather than scanning every slot) reads only the slots that hold nodes.
fn compact(slots: &[Slot]) -> Vec<BuildNode> {
    let mut out: Vec<BuildNode> = Vec::with_capacity(slots.len() / 2 + 1);
    // (slot, output index of the parent whose right link points here)
    let mut stack = vec![(0u32, u32::MAX)];
    while let Some((s, parent)) = stack.pop() {
        let me = out.len() as u32;
        if let Some(NodeKind::Inner { right, .. }) =
            out.get_mut(parent as usize).map(|p| &mut p.kind)
        {
            *right = me;
        }
        let slot = &slots[s as usize];
        let bounds = Aabb::new(slot.min.into(), slot.max.into());
        let kind = if slot.tag == Slot::INNER {
            stack.push((slot.b, me));
            stack.push((slot.a, u32::MAX));
            NodeKind::Inner {
                left: me + 1,
                right: 0,
            }
        } else {
            debug_assert_eq!(slot.tag, Slot::LEAF);
            NodeKind::Leaf {
                first: slot.a,
                count: slot.b,
            }
        };
        out.push(BuildNode { bounds, kind });
    }
    out
}

struct Job<'a, S> {
    splitter: &'a S,
    ctx: &'a Ctx<'a>,
}

impl<S: Splitter> Job<'_, S> {
    #[allow(clippy::too_many_arguments)]
    fn node(
        &self,
        idx: &mut [u32],
        scratch: &mut [u32],
        slots: &mut [Slot],
        slot: u32,
        first: u32,
        bounds: Aabb,
        centroids: Aabb,
        depth: usize,
    ) {
        let n = idx.len();
        let config = self.ctx.config;
        let split = if n == 1 {
            None
        } else if depth < MEDIAN_DEPTH {
            self.splitter
                .split(self.ctx, idx, scratch, &bounds, &centroids)
        } else {
            None
        };
        let split = match split {
            Some(s) => s,
            None if n <= config.max_leaf_size => {
                slots[0] = Slot::new(&bounds, Slot::LEAF, first, n as u32);
                return;
            }
            None => {
                let nl = median_split(self.ctx.bounds, idx, &centroids);
                Partition {
                    left_len: nl,
                    left: bounds_of(self.ctx.bounds, &idx[..nl]),
                    right: bounds_of(self.ctx.bounds, &idx[nl..]),
                }
            }
        };
        let nl = split.left_len;
        debug_assert!(nl > 0 && nl < n);
        let left_slot = slot + 1;
        let right_slot = slot + 2 * nl as u32;
        slots[0] = Slot::new(&bounds, Slot::INNER, left_slot, right_slot);
        let (l_idx, r_idx) = idx.split_at_mut(nl);
        let (l_scr, r_scr) = scratch.split_at_mut(nl);
        let (l_slots, r_slots) = slots[1..].split_at_mut(2 * nl - 1);
        let mut left = || {
            self.node(
                l_idx,
                l_scr,
                l_slots,
                left_slot,
                first,
                split.left.0,
                split.left.1,
                depth + 1,
            )
        };
        let mut right = || {
            let rfirst = first + nl as u32;
            self.node(
                r_idx,
                r_scr,
                r_slots,
                right_slot,
                rfirst,
                split.right.0,
                split.right.1,
                depth + 1,
            )
        };
        if n >= TASK_CUTOFF {
            rayon::join(left, right);
        } else {
            left();
            right();
        }
    }
}

/// Stable partition of `idx` by `goes_left` (called with each primitive's centroid), through
/// `scratch`; returns the left count and the centroid bounds of both sides. Large inputs are
/// partitioned by all threads: each chunk counts its left elements, a prefix sum gives every
/// chunk its output ranges, and chunks scatter in parallel. Being stable, and the box
/// reductions exact, the result is the same for any number of threads.
pub(crate) fn stable_partition<F>(
    idx: &mut [u32],
    scratch: &mut [u32],
    centroids: &[Vec3A],
    parallel: bool,
    goes_left: F,
) -> (usize, Aabb, Aabb)
where
    F: Fn(Vec3A) -> bool + Sync,
{
    let left_of = |i: u32| goes_left(centroids[i as usize]);
    let scatter = |src: &[u32], l: &mut [u32], r: &mut [u32]| {
        let (mut a, mut b) = (0, 0);
        let (mut cl, mut cr) = (Aabb::EMPTY, Aabb::EMPTY);
        for &i in src {
            let c = centroids[i as usize];
            if goes_left(c) {
                l[a] = i;
                a += 1;
                cl.grow(c);
            } else {
                r[b] = i;
                b += 1;
                cr.grow(c);
            }
        }
        (cl, cr)
    };
    if parallel {
        let counts: Vec<usize> = idx
            .par_chunks(CHUNK)
            .map(|ch| ch.iter().filter(|&&i| left_of(i)).count())
            .collect();
        let n_left: usize = counts.iter().sum();
        let (mut ls, mut rs) = scratch.split_at_mut(n_left);
        let mut parts = Vec::with_capacity(counts.len());
        for (ch, &c) in idx.chunks(CHUNK).zip(&counts) {
            let (l, lrest) = std::mem::take(&mut ls).split_at_mut(c);
            let (r, rrest) = std::mem::take(&mut rs).split_at_mut(ch.len() - c);
            ls = lrest;
            rs = rrest;
            parts.push((ch, l, r));
        }
        let (cl, cr) = parts
            .into_par_iter()
            .map(|(ch, l, r)| scatter(ch, l, r))
            .reduce(
                || (Aabb::EMPTY, Aabb::EMPTY),
                |a, b| (a.0.union(&b.0), a.1.union(&b.1)),
            );
        idx.par_chunks_mut(CHUNK)
            .zip(scratch.par_chunks(CHUNK))
            .for_each(|(d, s)| d.copy_from_slice(s));
        (n_left, cl, cr)
    } else {
        // One pass: left elements fill `scratch` from the front, right ones from the back
        // (so the right side comes out reversed and is turned around on the way back).
        let n = idx.len();
        let (mut a, mut b) = (0, n);
        let (mut cl, mut cr) = (Aabb::EMPTY, Aabb::EMPTY);
        for &i in idx.iter() {
            let c = centroids[i as usize];
            if goes_left(c) {
                scratch[a] = i;
                a += 1;
                cl.grow(c);
            } else {
                b -= 1;
                scratch[b] = i;
                cr.grow(c);
            }
        }
        idx[..a].copy_from_slice(&scratch[..a]);
        for (d, s) in idx[a..].iter_mut().zip(scratch[a..].iter().rev()) {
            *d = *s;
        }
        (a, cl, cr)
    }
}
