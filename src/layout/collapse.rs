//! Collapsing the binary build tree into a wide one (4 or 8 children per node), the step
//! before a wide node format encodes it.
//!
//! Each wide node starts from a binary node's two children and repeatedly opens the inner
//! child of largest surface area (the one a ray is most likely to enter, so pulling its
//! children up saves the most visits) until it has `W` children or only leaves.

use crate::builders::{BuildTree, NodeKind};

/// The collapsed tree's types are `pub` inside a private module so that the node formats'
/// `encode` (a public trait method) can name them while nobody outside the crate can.
pub(crate) mod types {
    use crate::geometry::Aabb;

    /// A child of a node in the collapsed tree.
    #[derive(Clone, Copy, Debug, PartialEq)]
    pub enum Child {
        /// An unused slot.
        Empty,
        /// Index of a wide node.
        Inner(u32),
        /// A run of primitives in leaf order.
        Leaf {
            /// First primitive.
            first: u32,
            /// Number of primitives.
            count: u32,
        },
    }

    /// A node of the collapsed tree before it is encoded.
    #[derive(Clone, Debug)]
    pub struct Wide<const W: usize> {
        /// Child boxes.
        pub boxes: [Aabb; W],
        /// Children.
        pub kids: [Child; W],
    }

    impl<const W: usize> Wide<W> {
        /// A node with no used slot (also what padding slots encode).
        pub const EMPTY: Self = Wide {
            boxes: [Aabb::EMPTY; W],
            kids: [Child::Empty; W],
        };

        /// The exact node formats' fields: the boxes as `[min xyz, max xyz]` rows of `W`
        /// lanes, and per child (node position, 0) for an inner child, (first, `leaf` |
        /// count) for a leaf, (0, `leaf`) for an unused slot. `pos` maps a collapsed node
        /// index to its position in the node array.
        pub fn rows(
            &self,
            leaf: u32,
            pos: impl Fn(u32) -> u32,
        ) -> ([[f32; W]; 6], [u32; W], [u32; W]) {
            let mut planes = [[0.0; W]; 6];
            let (mut child, mut count) = ([0; W], [0; W]);
            for (i, (b, k)) in self.boxes.iter().zip(&self.kids).enumerate() {
                for a in 0..3 {
                    planes[a][i] = b.min[a];
                    planes[3 + a][i] = b.max[a];
                }
                (child[i], count[i]) = match *k {
                    Child::Empty => (0, leaf),
                    Child::Inner(j) => (pos(j), 0),
                    Child::Leaf { first, count } => (first, leaf | count),
                };
            }
            (planes, child, count)
        }
    }
}

pub(crate) use types::{Child, Wide};

/// Collapses `tree` into `W`-wide nodes in preorder (node 0 the root).
pub(crate) fn collapse<const W: usize>(tree: &BuildTree) -> Vec<Wide<W>> {
    let mut out = Vec::with_capacity(tree.nodes.len() / (W - 1) + 1);
    let root = &tree.nodes[0];
    match root.kind {
        NodeKind::Inner { .. } => {
            collapse_node(tree, 0, &mut out);
        }
        NodeKind::Leaf { first, count } => {
            let mut w = Wide::EMPTY;
            if count > 0 {
                w.boxes[0] = root.bounds;
                w.kids[0] = Child::Leaf { first, count };
            }
            out.push(w);
        }
    }
    out
}

fn collapse_node<const W: usize>(tree: &BuildTree, node: u32, out: &mut Vec<Wide<W>>) -> u32 {
    let me = out.len() as u32;
    out.push(Wide::EMPTY);
    let is_inner = |n: u32| matches!(tree.nodes[n as usize].kind, NodeKind::Inner { .. });
    let kids_of = |n: u32| match tree.nodes[n as usize].kind {
        NodeKind::Inner { left, right } => (left, right),
        NodeKind::Leaf { .. } => unreachable!("only inner nodes are opened"),
    };
    let (l, r) = kids_of(node);
    let mut list = vec![l, r];
    while list.len() < W {
        let widest = list
            .iter()
            .enumerate()
            .filter(|(_, &n)| is_inner(n))
            .max_by(|(_, &a), (_, &b)| {
                let area = |n: u32| tree.nodes[n as usize].bounds.half_area();
                area(a).total_cmp(&area(b)).then(b.cmp(&a))
            })
            .map(|(i, _)| i);
        let Some(i) = widest else { break };
        let (a, b) = kids_of(list[i]);
        list.splice(i..=i, [a, b]);
    }
    for (slot, &n) in list.iter().enumerate() {
        let bn = &tree.nodes[n as usize];
        let kid = match bn.kind {
            NodeKind::Inner { .. } => Child::Inner(collapse_node(tree, n, out)),
            NodeKind::Leaf { first, count } => Child::Leaf { first, count },
        };
        out[me as usize].boxes[slot] = bn.bounds;
        out[me as usize].kids[slot] = kid;
    }
    me
}

/// What a binary node becomes in the SAH-optimal collapse, for a given number of parent
/// slots.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Choice {
    /// One slot: a leaf with all the subtree's primitives.
    Leaf,
    /// One slot: a wide node of its own.
    Wide,
    /// As with one slot fewer.
    Fewer,
    /// Opened: `k` slots for the left subtree, the rest for the right.
    Split(u8),
}

/// The SAH-optimal collapse of a binary tree into `W`-wide nodes (the dynamic programme of
/// Ylitie, Karras and Laine, "Efficient Incoherent Ray Traversal on GPUs Through Compressed
/// Wide BVHs", HPG 2017, section 4.1). For every binary node and every slot budget `i ≤ W` it
/// finds the cheapest way to hand the subtree to its parent in at most `i` slots, each slot a
/// leaf or a wide node of its own, by the wide SAH: `traversal_cost · area` per wide node
/// plus `area · leaf_cost(primitives)` per leaf. Unlike the greedy collapse it fills wide nodes at the
/// bottom of the tree too, and it may merge small binary leaves into one leaf of up to
/// `max_leaf` primitives (a subtree's primitives are contiguous in leaf order).
pub(crate) fn collapse_sah<const W: usize>(
    tree: &BuildTree,
    max_leaf: usize,
    traversal_cost: f32,
    leaf_cost: impl Fn(u32) -> f32 + Sync,
) -> Vec<Wide<W>> {
    let n = tree.nodes.len();
    let root = &tree.nodes[0];
    if let NodeKind::Leaf { .. } = root.kind {
        return collapse::<W>(tree);
    }
    // A leaf the build made always fits, whatever `max_leaf` says.
    let built_max = tree.nodes.iter().map(|n| match n.kind {
        NodeKind::Leaf { count, .. } => count as usize,
        NodeKind::Inner { .. } => 0,
    });
    let max_leaf = max_leaf.max(built_max.max().unwrap_or(0)) as u32;
    let costs = Costs {
        tree,
        max_leaf,
        traversal_cost,
        leaf_cost,
    };
    let mut dp = crate::mem::with_capacity(n);
    dp.resize(n, Dp::<W>::UNSET);
    costs.subtree(0, &mut dp);
    let plan = Plan { tree, dp: &dp };
    let mut out = crate::mem::with_capacity(n / (W - 1) + 1);
    plan.emit(0, &mut out);
    out
}

/// Below this many binary nodes a subtree's costs are computed on one thread.
const PAR_NODES: usize = 8192;

/// The dynamic programme's answer for one binary node.
#[derive(Clone, Copy)]
struct Dp<const W: usize> {
    /// Cheapest cost with at most `i + 1` slots, and how it is reached.
    cost: [f32; W],
    choice: [Choice; W],
    /// Should the node become a wide node, the slots its left subtree gets.
    open_k: u8,
    /// The node's primitives: first and count in leaf order.
    range: (u32, u32),
    /// Binary leaves in the subtree.
    leaves: u32,
}

impl<const W: usize> Dp<W> {
    const UNSET: Self = Dp {
        cost: [0.0; W],
        choice: [Choice::Fewer; W],
        open_k: 0,
        range: (0, 0),
        leaves: 1,
    };
}

/// What the programme weighs.
struct Costs<'a, F> {
    tree: &'a BuildTree,
    max_leaf: u32,
    traversal_cost: f32,
    leaf_cost: F,
}

impl<F: Fn(u32) -> f32 + Sync> Costs<'_, F> {
    /// Fills `dp` (one entry per node of the subtree rooted at `i0`, which in preorder are
    /// the nodes `i0..i0 + dp.len()`), splitting large subtrees between threads: a
    /// subtree's nodes are one contiguous run, its left child's right after it.
    fn subtree<const W: usize>(&self, i0: usize, dp: &mut [Dp<W>]) {
        if dp.len() < PAR_NODES {
            // Children come after their parent in preorder: backwards, each node sees its
            // children done.
            for i in (0..dp.len()).rev() {
                dp[i] = self.node(i0 + i, |c| &dp[c - i0]);
            }
            return;
        }
        let NodeKind::Inner { left, right } = self.tree.nodes[i0].kind else {
            unreachable!("a subtree of many nodes has an inner root")
        };
        let (left, right) = (left as usize, right as usize);
        debug_assert_eq!(left, i0 + 1, "preorder: the left child follows its parent");
        let (me, kids) = dp.split_at_mut(1);
        let (l, r) = kids.split_at_mut(right - left);
        rayon::join(|| self.subtree(left, l), || self.subtree(right, r));
        me[0] = self.node(i0, |c| if c == left { &l[0] } else { &r[0] });
    }

    /// Node `i`'s entry from its children's (`done(child)`).
    fn node<'d, const W: usize>(&self, i: usize, done: impl Fn(usize) -> &'d Dp<W>) -> Dp<W> {
        let node = &self.tree.nodes[i];
        let area = node.bounds.half_area();
        let mut out = Dp::UNSET;
        let (split, split_k) = match node.kind {
            NodeKind::Leaf { first, count } => {
                out.range = (first, count);
                ([f32::INFINITY; W], [0u8; W])
            }
            NodeKind::Inner { left, right } => {
                let (l, r) = (done(left as usize), done(right as usize));
                debug_assert_eq!(r.range.0, l.range.0 + l.range.1, "contiguous leaves");
                out.range = (l.range.0, l.range.1 + r.range.1);
                out.leaves = l.leaves + r.leaves;
                let mut split = [f32::INFINITY; W];
                let mut split_k = [0u8; W];
                // A subtree of L binary leaves fills at most L slots: with more, its children's
                // costs stay at their last value, every budget past L keeps L's cost (the
                // `Fewer` below) and only the full budget's split matters (the wide node's
                // cost and how it shares its slots out). Costs never rise with the budget,
                // so the sums past L cannot beat L's; the full loop stays for NaN costs,
                // where that order does not hold.
                let finite = |d: &Dp<W>| !d.cost.iter().any(|c| c.is_nan());
                let top = if finite(l) && finite(r) {
                    (out.leaves as usize).min(W)
                } else {
                    W
                };
                for j in (2..=top).chain((top < W).then_some(W)) {
                    for k in 1..j {
                        let c = l.cost[k - 1] + r.cost[j - k - 1];
                        // The first candidate always counts, so a split is chosen even when
                        // every cost is infinite or NaN (boxes out at f32's range).
                        if k == 1 || c < split[j - 1] {
                            (split[j - 1], split_k[j - 1]) = (c, k as u8);
                        }
                    }
                }
                (split, split_k)
            }
        };
        let count = out.range.1;
        let leaf = if count <= self.max_leaf {
            area * (self.leaf_cost)(count)
        } else {
            f32::INFINITY
        };
        let wide = self.traversal_cost * area + split[W - 1];
        let inner = matches!(node.kind, NodeKind::Inner { .. });
        // A leaf only within `max_leaf` (infinite costs must not tie a big node into one).
        let leaf_wins = wide.partial_cmp(&leaf) != Some(std::cmp::Ordering::Less);
        (out.cost[0], out.choice[0]) = if !inner || (count <= self.max_leaf && leaf_wins) {
            (leaf, Choice::Leaf)
        } else {
            (wide, Choice::Wide)
        };
        for j in 2..=W {
            (out.cost[j - 1], out.choice[j - 1]) = if !inner || out.cost[j - 2] <= split[j - 1] {
                (out.cost[j - 2], Choice::Fewer)
            } else {
                (split[j - 1], Choice::Split(split_k[j - 1]))
            };
        }
        out.open_k = split_k[W - 1];
        out
    }
}

/// The collapse's decisions, and what the nodes cover.
struct Plan<'a, const W: usize> {
    tree: &'a BuildTree,
    dp: &'a [Dp<W>],
}

/// A slot of a wide node: a binary node that becomes a leaf or a wide node.
#[derive(Clone, Copy)]
enum Slot {
    Leaf(usize),
    Wide(usize),
}

/// The slots of one wide node (at most `W`).
struct Slots<const W: usize> {
    slots: [Slot; W],
    len: usize,
}

impl<const W: usize> Plan<'_, W> {
    /// The slots binary node `n` fills with a budget of `i`.
    fn slots(&self, n: usize, i: usize, out: &mut Slots<W>) {
        match self.dp[n].choice[i - 1] {
            Choice::Leaf => out.push(Slot::Leaf(n)),
            Choice::Wide => out.push(Slot::Wide(n)),
            Choice::Fewer => self.slots(n, i - 1, out),
            Choice::Split(k) => {
                let NodeKind::Inner { left, right } = self.tree.nodes[n].kind else {
                    unreachable!("only inner nodes split")
                };
                self.slots(left as usize, k as usize, out);
                self.slots(right as usize, i - k as usize, out);
            }
        }
    }

    /// Emits binary node `n` as a wide node (and its wide descendants) in preorder; returns
    /// its index.
    fn emit(&self, n: usize, out: &mut Vec<Wide<W>>) -> u32 {
        let me = out.len() as u32;
        out.push(Wide::EMPTY);
        let NodeKind::Inner { left, right } = self.tree.nodes[n].kind else {
            unreachable!("wide nodes come from inner nodes")
        };
        // The node's own W slots, as its best split shared them out.
        let k = self.dp[n].open_k as usize;
        debug_assert!((1..W).contains(&k));
        let mut slots = Slots {
            slots: [Slot::Leaf(0); W],
            len: 0,
        };
        self.slots(left as usize, k, &mut slots);
        self.slots(right as usize, W - k, &mut slots);
        for (slot, &s) in slots.slots[..slots.len].iter().enumerate() {
            let (b, kid) = match s {
                Slot::Leaf(c) => {
                    let (first, count) = self.dp[c].range;
                    (c, Child::Leaf { first, count })
                }
                Slot::Wide(c) => (c, Child::Inner(self.emit(c, out))),
            };
            out[me as usize].boxes[slot] = self.tree.nodes[b].bounds;
            out[me as usize].kids[slot] = kid;
        }
        me
    }
}

impl<const W: usize> Slots<W> {
    fn push(&mut self, s: Slot) {
        self.slots[self.len] = s;
        self.len += 1;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::builders::BuildNode;
    use crate::geometry::Aabb;
    use glam::Vec3A;

    /// A hand-made binary tree: root → A (inner: leaf 0, A2) and B (inner: leaves 3, 4), with
    /// A2 (inner: leaves 1, 2). `a2` and `b` are the edge lengths of A2's and B's cubes.
    fn tree(a2: f32, b: f32) -> BuildTree {
        let cube = |e: f32| Aabb::new(Vec3A::ZERO, Vec3A::splat(e));
        let inner = |e: f32, left: u32, right: u32| BuildNode {
            bounds: cube(e),
            kind: NodeKind::Inner { left, right },
        };
        let leaf = |first: u32| BuildNode {
            bounds: cube(0.1 * (first + 1) as f32),
            kind: NodeKind::Leaf { first, count: 1 },
        };
        BuildTree {
            nodes: vec![
                inner(10.0, 1, 6),
                inner(9.0, 2, 3),
                leaf(0),
                inner(a2, 4, 5),
                leaf(1),
                leaf(2),
                inner(b, 7, 8),
                leaf(3),
                leaf(4),
            ],
            prim_indices: (0..5).collect(),
            dropped: 0,
        }
    }

    fn leaf(first: u32) -> Child {
        Child::Leaf { first, count: 1 }
    }

    #[test]
    fn collapse_opens_the_inner_child_of_largest_area_first() {
        // Root's children A (area 9²) and B: A is opened first. Then A2 or B, whichever is
        // larger, is opened; the other stays an inner child with its own wide node.
        let wide = collapse::<4>(&tree(5.0, 2.0));
        assert_eq!(wide.len(), 2);
        assert_eq!(wide[0].kids, [leaf(0), leaf(1), leaf(2), Child::Inner(1)]);
        assert_eq!(wide[1].kids, [leaf(3), leaf(4), Child::Empty, Child::Empty]);
        let wide = collapse::<4>(&tree(2.0, 5.0));
        assert_eq!(wide[0].kids, [leaf(0), Child::Inner(1), leaf(3), leaf(4)]);
        assert_eq!(wide[1].kids, [leaf(1), leaf(2), Child::Empty, Child::Empty]);
        // Each slot's box is its binary node's box; unused slots are empty boxes.
        let t = tree(2.0, 5.0);
        let b = |n: usize| t.nodes[n].bounds;
        assert_eq!(wide[0].boxes, [b(2), b(3), b(7), b(8)]);
        assert_eq!(wide[1].boxes, [b(4), b(5), Aabb::EMPTY, Aabb::EMPTY]);
    }

    #[test]
    fn a_leaf_root_collapses_to_one_node_and_an_empty_tree_to_an_empty_node() {
        let one = BuildTree {
            nodes: vec![crate::builders::BuildNode {
                bounds: Aabb::new(Vec3A::ZERO, Vec3A::ONE),
                kind: NodeKind::Leaf { first: 0, count: 3 },
            }],
            prim_indices: vec![0, 1, 2],
            dropped: 0,
        };
        let wide = collapse::<4>(&one);
        assert_eq!(wide.len(), 1);
        assert_eq!(wide[0].kids[0], Child::Leaf { first: 0, count: 3 });
        assert_eq!(wide[0].kids[1..], [Child::Empty; 3]);
        let empty =
            crate::builders::build(&[], &Default::default(), crate::builders::Builder::Binned);
        let wide = collapse::<4>(&empty);
        assert_eq!(wide.len(), 1);
        assert_eq!(wide[0].kids, [Child::Empty; 4]);
    }

    #[test]
    fn collapse_keeps_every_leaf_once() {
        let bounds = crate::testing::soup_bounds(3000, 1);
        let tree = crate::builders::build(
            &bounds,
            &Default::default(),
            crate::builders::Builder::Binned,
        );
        let wide = collapse::<4>(&tree);
        check_cover(&wide, tree.prim_indices.len(), tree.stats().max_leaf as u32);
        assert_greedy_fill(&wide);
    }

    /// A greedily collapsed node has fewer than `W` children only when none of them could be
    /// opened.
    fn assert_greedy_fill<const W: usize>(wide: &[Wide<W>]) {
        for w in wide {
            let used = w.kids.iter().filter(|k| **k != Child::Empty).count();
            let inner = w
                .kids
                .iter()
                .filter(|k| matches!(k, Child::Inner(_)))
                .count();
            assert!(
                used == W || inner == 0,
                "{used} children, {inner} of them inner"
            );
        }
    }

    #[test]
    fn eight_wide_nodes_open_until_eight_children() {
        let tree = crate::builders::build(
            &crate::testing::soup_bounds(3000, 2),
            &Default::default(),
            crate::builders::Builder::Binned,
        );
        let wide = collapse::<8>(&tree);
        assert_greedy_fill(&wide);
        let mut leaves = 0;
        for w in &wide {
            leaves += w
                .kids
                .iter()
                .filter(|k| matches!(k, Child::Leaf { .. }))
                .count();
        }
        assert_eq!(leaves, tree.stats().leaves);
        assert!(wide.len() < collapse::<4>(&tree).len());
    }

    /// The wide SAH cost: `c_T · area` per wide node, `c_I · area · count` per leaf.
    fn wide_cost<const W: usize>(wide: &[Wide<W>], c_t: f32, c_i: f32) -> f64 {
        wide.iter()
            .map(|w| {
                let area = w
                    .boxes
                    .iter()
                    .fold(Aabb::EMPTY, |a, b| a.union(b))
                    .half_area();
                let leaves: f64 = w
                    .boxes
                    .iter()
                    .zip(&w.kids)
                    .map(|(b, k)| match k {
                        Child::Leaf { count, .. } => (c_i * b.half_area() * *count as f32) as f64,
                        _ => 0.0,
                    })
                    .sum();
                (c_t * area) as f64 + leaves
            })
            .sum()
    }

    /// Every primitive in exactly one leaf, leaves within `max_leaf`, every inner child a
    /// later node, each slot's box containing its leaf's or node's boxes.
    fn check_cover<const W: usize>(wide: &[Wide<W>], prims: usize, max_leaf: u32) {
        let mut covered = vec![false; prims];
        for (i, w) in wide.iter().enumerate() {
            for (b, k) in w.boxes.iter().zip(&w.kids) {
                match *k {
                    Child::Leaf { first, count } => {
                        assert!(count <= max_leaf, "leaf of {count} > {max_leaf}");
                        for c in &mut covered[first as usize..(first + count) as usize] {
                            assert!(!std::mem::replace(c, true), "primitive in two leaves");
                        }
                    }
                    Child::Inner(j) => {
                        assert!(j as usize > i);
                        let inside = wide[j as usize]
                            .boxes
                            .iter()
                            .fold(Aabb::EMPTY, |a, c| a.union(c));
                        assert!(b.contains(&inside));
                    }
                    Child::Empty => {}
                }
            }
        }
        assert!(covered.iter().all(|&c| c), "a primitive in no leaf");
    }

    #[test]
    fn sah_collapse_covers_everything_and_beats_the_greedy_one() {
        for (n, seed) in [(40, 1), (3000, 2), (20000, 3)] {
            let bounds = crate::testing::soup_bounds(n, seed);
            let tree = crate::builders::build(
                &bounds,
                &Default::default(),
                crate::builders::Builder::Binned,
            );
            for max_leaf in [1usize, 4, 8] {
                let dp = collapse_sah::<8>(&tree, max_leaf, 1.0, |n| n as f32);
                let limit = max_leaf.max(tree.stats().max_leaf) as u32;
                check_cover(&dp, n, limit);
                let greedy = collapse::<8>(&tree);
                let (c_dp, c_greedy) = (wide_cost(&dp, 1.0, 1.0), wide_cost(&greedy, 1.0, 1.0));
                assert!(
                    c_dp <= c_greedy * (1.0 + 1e-5),
                    "{n} {max_leaf}: {c_dp} > {c_greedy}"
                );
                let dp4 = collapse_sah::<4>(&tree, max_leaf, 1.0, |n| n as f32);
                check_cover(&dp4, n, limit);
                let c4 = (
                    wide_cost(&dp4, 1.0, 1.0),
                    wide_cost(&collapse::<4>(&tree), 1.0, 1.0),
                );
                assert!(c4.0 <= c4.1 * (1.0 + 1e-5), "{n} {max_leaf} 4-wide: {c4:?}");
            }
        }
    }

    #[test]
    fn sah_collapse_survives_infinite_and_nan_costs() {
        // Boxes out at f32's range: their areas are infinite, so are all costs; with zero-
        // extent boxes at infinity-straddling coordinates some areas are NaN. Found by fuzzing.
        let big = f32::MAX;
        let bounds: Vec<Aabb> = (0..40)
            .map(|i| {
                let x = if i % 2 == 0 { -big } else { big * 0.5 };
                Aabb::new(
                    Vec3A::new(x, -big, i as f32),
                    Vec3A::new(big, big, i as f32 + 1.0),
                )
            })
            .collect();
        let tree = crate::builders::build(
            &bounds,
            &Default::default(),
            crate::builders::Builder::Binned,
        );
        for leaf_cost in [1.0, f32::NAN] {
            let wide = collapse_sah::<8>(&tree, 8, 1.0, |n| leaf_cost * n as f32);
            check_cover(&wide, 40, 8.max(tree.stats().max_leaf as u32));
        }
    }

    #[test]
    fn sah_collapse_fills_the_bottom_of_a_balanced_tree() {
        // 64 unit-spaced boxes: a balanced binary tree of depth 6 with one box per leaf. The
        // greedy collapse leaves 2-child nodes at the bottom; the optimal one, with leaves of
        // one primitive, uses two levels of eight.
        let bounds: Vec<Aabb> = (0..64)
            .map(|i| {
                Aabb::new(
                    Vec3A::new(i as f32 * 2.0, 0.0, 0.0),
                    Vec3A::new(i as f32 * 2.0 + 1.0, 1.0, 1.0),
                )
            })
            .collect();
        let config = crate::builders::BuildConfig {
            max_leaf_size: 1,
            ..Default::default()
        };
        let tree = crate::builders::build(&bounds, &config, crate::builders::Builder::Binned);
        let dp = collapse_sah::<8>(&tree, 1, 1.0, |n| n as f32);
        check_cover(&dp, 64, 1);
        assert_eq!(dp.len(), 9, "a root and eight full nodes");
        assert!(dp.iter().all(|w| w.kids.iter().all(|k| *k != Child::Empty)));
        // With cheap primitive tests, leaves of up to eight merge: one node of eight leaves.
        let merged = collapse_sah::<8>(&tree, 8, 1.0, |n| 0.01 * n as f32);
        check_cover(&merged, 64, 8);
        assert_eq!(merged.len(), 1);
    }
}
