//! Linear BVH (Lauterbach et al. 2009; Karras 2012): the primitives sorted once along a Morton
//! curve of their centroids, then every node split where its run of codes changes in the
//! highest bit in which its first and last code differ. Finding a split is a binary search and
//! nothing moves after the sort, so the tree is built down to single primitives with constant
//! work per node: boxes are unions of the children's on the way back up, and a node becomes a
//! leaf where the SAH prefers it (the optimal collapse of Bittner et al. 2013, bottom-up, in
//! the same pass).
//!
//! The sort key is the code above the primitive's input index, so every key is distinct and
//! the order, and the tree, are the same for any number of threads; each task writes its
//! nodes densely (a node the collapse turns into a leaf drops its subtree's nodes from the end
//! of the task's vector) and [`super::recurse`]'s pieces lay them out in preorder. The code
//! gets what the index leaves of 64 bits (42 bits, 14 per axis, for a million primitives; at
//! least 30), which also bounds the depth: each split below the root clears one more code bit
//! or halves a run of equal codes, so no path is longer than 64 edges.
//!
//! The fast preset's builder: several times quicker than the binned SAH, with a costlier tree
//! (the planes fall on a fixed grid, wherever the primitives are).

use super::recurse::Piece;
use super::{BuildConfig, BuildNode, NodeKind};
use crate::geometry::Aabb;
use glam::Vec3A;
use rayon::prelude::*;

/// Subtrees this small are built on the current thread.
const TASK_CUTOFF: usize = 2048;

pub(super) fn build(
    bounds: &[Aabb],
    idx: Vec<u32>,
    config: &BuildConfig,
) -> (Vec<BuildNode>, Vec<u32>) {
    assert!(
        bounds.len() < (u32::MAX / 2) as usize,
        "too many primitives for 32-bit node indices"
    );
    let id_bits = (u32::BITS - (bounds.len().max(2) as u32 - 1).leading_zeros()).max(1);
    let keys = sorted_keys(bounds, &idx, id_bits);
    let order: Vec<u32> = keys
        .par_iter()
        .map(|&k| (k & ((1u64 << id_bits) - 1)) as u32)
        .collect();
    let job = Job {
        bounds,
        config,
        id_bits,
        id_mask: (1u64 << id_bits) - 1,
    };
    let (piece, ..) = job.node(&keys, 0);
    let mut nodes = Vec::with_capacity(piece.len());
    piece.flatten(&mut nodes);
    (nodes, order)
}

/// Each primitive's key (Morton code of its centroid, then its index), sorted.
fn sorted_keys(bounds: &[Aabb], idx: &[u32], id_bits: u32) -> Vec<u64> {
    let scene = idx
        .par_chunks(16 * 1024)
        .map(|ch| {
            ch.iter().fold(Aabb::EMPTY, |mut c, &i| {
                c.grow(bounds[i as usize].center());
                c
            })
        })
        .reduce(|| Aabb::EMPTY, |a, b| a.union(&b));
    let axis_bits = ((64 - id_bits) / 3).min(21);
    let cells = (1u64 << axis_bits) as f32;
    let e = scene.extent();
    // Cells per unit on each axis; an axis without extent puts everything in cell 0.
    let scale = Vec3A::select(e.cmpgt(Vec3A::ZERO), Vec3A::splat(cells) / e, Vec3A::ZERO);
    let top = (1u32 << axis_bits) - 1;
    let mut keys: Vec<u64> = idx
        .par_iter()
        .map(|&i| {
            let q = ((bounds[i as usize].center() - scene.min) * scale).to_array();
            // The float-to-int cast saturates (and sends NaN to 0); the top cell is closed.
            let cell = |x: f32| (x as u32).min(top) as u64;
            let code = spread(cell(q[0])) << 2 | spread(cell(q[1])) << 1 | spread(cell(q[2]));
            code << id_bits | i as u64
        })
        .collect();
    keys.par_sort_unstable();
    keys
}

/// The low 21 bits of `x` moved to every third bit (bit k to bit 3k).
fn spread(x: u64) -> u64 {
    let mut x = x & 0x1f_ffff;
    x = (x | x << 32) & 0x001f_0000_0000_ffff;
    x = (x | x << 16) & 0x001f_0000_ff00_00ff;
    x = (x | x << 8) & 0x100f_00f0_0f00_f00f;
    x = (x | x << 4) & 0x10c3_0c30_c30c_30c3;
    x = (x | x << 2) & 0x1249_2492_4924_9249;
    x
}

struct Job<'a> {
    bounds: &'a [Aabb],
    config: &'a BuildConfig,
    id_bits: u32,
    id_mask: u64,
}

impl Job<'_> {
    /// Builds the subtree over `keys` (positions `first..` of the sorted order); returns it,
    /// its box and its SAH cost (in units of half area).
    fn node(&self, keys: &[u64], first: u32) -> (Piece, Aabb, f32) {
        let n = keys.len();
        if n < TASK_CUTOFF {
            // Leaves hold at most `max_leaf_size`, so the nodes number at most 2n - 1; most
            // subtrees collapse to far fewer.
            let mut nodes = Vec::with_capacity(n);
            let (b, cost) = self.serial(keys, first, &mut nodes);
            return (Piece::Nodes(nodes), b, cost);
        }
        let mid = self.split(keys);
        let (left_keys, right_keys) = keys.split_at(mid);
        let ((l, lb, lc), (r, rb, rc)) = rayon::join(
            || self.node(left_keys, first),
            || self.node(right_keys, first + mid as u32),
        );
        let b = lb.union(&rb);
        match self.choose(n, &b, lc + rc) {
            (cost, true) => (Piece::Nodes(vec![leaf(b, first, n)]), b, cost),
            (cost, false) => (Piece::join(b, l, r), b, cost),
        }
    }

    /// [`Job::node`] on this thread: the subtree's nodes appended to `out` in preorder,
    /// links counted from the start of `out`.
    fn serial(&self, keys: &[u64], first: u32, out: &mut Vec<BuildNode>) -> (Aabb, f32) {
        let n = keys.len();
        let config = self.config;
        if n == 1 {
            let b = self.bounds[(keys[0] & self.id_mask) as usize];
            out.push(leaf(b, first, 1));
            return (
                b,
                config.intersection_cost * config.tests(1) * b.half_area(),
            );
        }
        let mid = self.split(keys);
        let me = out.len();
        out.push(leaf(Aabb::EMPTY, first, 0));
        let (lb, lc) = self.serial(&keys[..mid], first, out);
        let right = out.len();
        let (rb, rc) = self.serial(&keys[mid..], first + mid as u32, out);
        let b = lb.union(&rb);
        let (cost, is_leaf) = self.choose(n, &b, lc + rc);
        out[me] = if is_leaf {
            out.truncate(me + 1);
            leaf(b, first, n)
        } else {
            BuildNode {
                bounds: b,
                kind: NodeKind::Inner {
                    left: me as u32 + 1,
                    right: right as u32,
                },
            }
        };
        (b, cost)
    }

    /// A node of `n` primitives, box `b` and children costing `children`: its cost, and
    /// whether the SAH makes it a leaf (the optimal collapse, bottom-up).
    fn choose(&self, n: usize, b: &Aabb, children: f32) -> (f32, bool) {
        let config = self.config;
        let area = b.half_area();
        let inner = config.traversal_cost * area + children;
        let leaf = config.intersection_cost * config.tests(n) * area;
        if n <= config.max_leaf_size && leaf <= inner {
            (leaf, true)
        } else {
            (inner, false)
        }
    }

    /// Where `keys` (two or more, sorted) split: at the first key with the highest differing
    /// code bit set, or in the middle of a run of equal codes.
    fn split(&self, keys: &[u64]) -> usize {
        let n = keys.len();
        let differ = keys[0] ^ keys[n - 1];
        let bit = 63 - differ.leading_zeros();
        if bit < self.id_bits {
            return n / 2;
        }
        // Every key of the run agrees above `bit`, so those with it clear come first.
        keys.partition_point(|&k| (k >> bit) & 1 == 0)
    }
}

/// A leaf over sorted positions `first..first + n`.
fn leaf(bounds: Aabb, first: u32, n: usize) -> BuildNode {
    BuildNode {
        bounds,
        kind: NodeKind::Leaf {
            first,
            count: n as u32,
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::builders::morton::tests::point;
    use crate::builders::NodeKind;

    #[test]
    fn spread_moves_each_bit_to_three_times_its_place() {
        for k in 0..21 {
            assert_eq!(spread(1 << k), 1 << (3 * k), "bit {k}");
        }
        assert_eq!(spread(0x1f_ffff), 0x1249_2492_4924_9249);
    }

    #[test]
    fn the_root_splits_at_the_top_morton_bit() {
        // Centroids span 0..3 on x: the top code bit is x's upper half, so the two points
        // below x = 1.5 go left whatever their input order.
        let boxes = [
            point(3.0, 0.0, 0.0),
            point(0.0, 0.0, 0.0),
            point(2.5, 0.0, 0.0),
            point(1.0, 0.0, 0.0),
        ];
        let config = BuildConfig {
            max_leaf_size: 1,
            ..BuildConfig::default()
        };
        let (nodes, order) = build(&boxes, (0..4).collect(), &config);
        let NodeKind::Inner { left, right } = nodes[0].kind else {
            panic!("the root must split");
        };
        assert_eq!(nodes[left as usize].bounds.max.x, 1.0);
        assert_eq!(nodes[right as usize].bounds.min.x, 2.5);
        assert_eq!(order, vec![1, 3, 2, 0]);
    }

    #[test]
    fn equal_codes_halve_in_index_order() {
        let boxes = vec![point(1.0, 1.0, 1.0); 5];
        let config = BuildConfig {
            max_leaf_size: 1,
            ..BuildConfig::default()
        };
        let (nodes, order) = build(&boxes, (0..5).collect(), &config);
        assert_eq!(order, vec![0, 1, 2, 3, 4]);
        assert_eq!(nodes.len(), 9);
    }
}
