//! The recursion both builders share: leaf-or-split decision, depth guard, median fallback,
//! node slots and vertical (task) parallelism. A builder only supplies how to find and apply
//! the best SAH split of one node.

use super::{bounds_of, median_split, split_beats_leaf, BuildConfig, BuildNode, NodeKind, MEDIAN_DEPTH};
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
    fn split(&self, ctx: &Ctx, idx: &mut [u32], scratch: &mut [u32], node: &Aabb, centroids: &Aabb) -> Option<Partition>;
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
    mut idx: Vec<u32>,
    config: &BuildConfig,
) -> (Vec<BuildNode>, Vec<u32>) {
    assert!(idx.len() < (u32::MAX / 2) as usize, "too many primitives for 32-bit node indices");
    let centroids: Vec<Vec3A> = bounds.par_iter().map(|b| b.center()).collect();
    let ctx = Ctx {
        config,
        bounds,
        centroids: &centroids,
    };
    let (node, cent) = idx
        .par_chunks(CHUNK)
        .map(|ch| bounds_of(bounds, ch))
        .reduce(|| (Aabb::EMPTY, Aabb::EMPTY), |a, b| (a.0.union(&b.0), a.1.union(&b.1)));
    let mut scratch = vec![0u32; idx.len()];
    // A subtree over n primitives has at most 2n - 1 nodes. Giving each subtree exactly that
    // many slots fixes every node's position by the input alone, so parallel tasks write
    // disjoint ranges and the result cannot depend on scheduling.
    let mut slots = vec![None; 2 * idx.len() - 1];
    let job = Job {
        splitter,
        ctx: &ctx,
    };
    job.node(&mut idx, &mut scratch, &mut slots, 0, 0, node, cent, 0);
    (super::compact(slots), idx)
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
        slots: &mut [Option<BuildNode>],
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
            self.splitter.split(self.ctx, idx, scratch, &bounds, &centroids)
        } else {
            None
        };
        let split = match split {
            Some(s) => s,
            None if n <= config.max_leaf_size => {
                slots[0] = Some(BuildNode {
                    bounds,
                    kind: NodeKind::Leaf {
                        first,
                        count: n as u32,
                    },
                });
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
        slots[0] = Some(BuildNode {
            bounds,
            kind: NodeKind::Inner {
                left: left_slot,
                right: right_slot,
            },
        });
        let (l_idx, r_idx) = idx.split_at_mut(nl);
        let (l_scr, r_scr) = scratch.split_at_mut(nl);
        let (l_slots, r_slots) = slots[1..].split_at_mut(2 * nl - 1);
        let mut left = || self.node(l_idx, l_scr, l_slots, left_slot, first, split.left.0, split.left.1, depth + 1);
        let mut right = || {
            let rfirst = first + nl as u32;
            self.node(r_idx, r_scr, r_slots, right_slot, rfirst, split.right.0, split.right.1, depth + 1)
        };
        if n >= TASK_CUTOFF {
            rayon::join(left, right);
        } else {
            left();
            right();
        }
    }
}

/// Stable partition of `idx` by `goes_left`, through `scratch`; returns the left count. Large
/// inputs are partitioned by all threads: each chunk counts its left elements, a prefix sum
/// gives every chunk its output ranges, and chunks scatter in parallel. Being stable, the
/// result is the same for any number of threads.
pub(crate) fn stable_partition<F>(idx: &mut [u32], scratch: &mut [u32], parallel: bool, goes_left: F) -> usize
where
    F: Fn(u32) -> bool + Sync,
{
    let scatter = |src: &[u32], l: &mut [u32], r: &mut [u32]| {
        let (mut a, mut b) = (0, 0);
        for &i in src {
            if goes_left(i) {
                l[a] = i;
                a += 1;
            } else {
                r[b] = i;
                b += 1;
            }
        }
    };
    let n_left = if parallel {
        let counts: Vec<usize> = idx
            .par_chunks(CHUNK)
            .map(|ch| ch.iter().filter(|&&i| goes_left(i)).count())
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
        parts.into_par_iter().for_each(|(ch, l, r)| scatter(ch, l, r));
        idx.par_chunks_mut(CHUNK)
            .zip(scratch.par_chunks(CHUNK))
            .for_each(|(d, s)| d.copy_from_slice(s));
        n_left
    } else {
        let n_left = idx.iter().filter(|&&i| goes_left(i)).count();
        let (l, r) = scratch.split_at_mut(n_left);
        scatter(idx, l, r);
        idx.copy_from_slice(scratch);
        n_left
    };
    n_left
}
