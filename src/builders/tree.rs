//! [`BuildTree`], every builder's output: a binary tree of boxes over ranges of a primitive
//! index array, with its shape statistics, SAH cost and invariant check.

use super::BuildConfig;
use crate::geometry::Aabb;
use std::fmt;

/// What a node of the [`BuildTree`] is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum NodeKind {
    /// An inner node with two children (indices into [`BuildTree::nodes`]).
    Inner {
        /// Left child.
        left: u32,
        /// Right child.
        right: u32,
    },
    /// A leaf holding `prim_indices[first .. first + count]`.
    Leaf {
        /// First slot in [`BuildTree::prim_indices`].
        first: u32,
        /// Number of primitives.
        count: u32,
    },
}

/// One node of the intermediate tree.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BuildNode {
    /// Bounds of everything below.
    pub bounds: Aabb,
    /// Inner or leaf.
    pub kind: NodeKind,
}

/// The builders' output: a binary tree in depth-first preorder (root at 0, a left child right
/// after its parent) whose leaves index ranges of `prim_indices`.
#[derive(Clone, Debug, PartialEq)]
pub struct BuildTree {
    /// Nodes in depth-first preorder.
    pub nodes: Vec<BuildNode>,
    /// Input primitive indices in leaf order: a permutation of the finite primitives for
    /// every builder but [`super::Builder::Sbvh`], whose spatial splits put a primitive in
    /// each leaf that holds a piece of it (never twice in one leaf), up to 1.3 references per
    /// primitive in all. A query still reports such a primitive once, by its input index;
    /// counted statistics ([`crate::traverse::Stats`]) count each leaf's test.
    pub prim_indices: Vec<u32>,
    /// Primitives left out because their bounds were not finite.
    pub dropped: usize,
}

/// Counts that describe a tree's shape.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TreeStats {
    /// All nodes.
    pub nodes: usize,
    /// Leaves.
    pub leaves: usize,
    /// Longest root-to-leaf path in edges.
    pub depth: usize,
    /// Largest leaf.
    pub max_leaf: usize,
}

/// Depth below which builders stop trusting the SAH and split at the object median, so that a
/// pathological input (exponentially spaced centroids) cannot make the tree linear. With it the
/// depth stays below `MEDIAN_DEPTH + log2(n) + 1`, which bounds every traversal stack.
pub(crate) const MEDIAN_DEPTH: usize = 48;

/// The deepest tree any builder makes for up to 2^32 primitives; traversal stacks use it.
pub const MAX_DEPTH: usize = MEDIAN_DEPTH + 33;

/// Why a [`BuildTree`] cannot be laid out over a primitive slice (see [`BuildTree::check`]):
/// each names the node, slot or primitive at fault.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum TreeError {
    /// The tree has no nodes (an empty build has one empty leaf).
    NoNodes,
    /// The tree is for another number of primitives: its index array and dropped count
    /// account for `tree`, the slice holds `prims`.
    PrimCount {
        /// `prim_indices.len() + dropped`.
        tree: usize,
        /// Primitives given.
        prims: usize,
    },
    /// Node `node` is not where depth-first preorder puts it: reached as `expected`, or
    /// (`expected == usize::MAX`) never reached from the root; or its child link `child`
    /// is not the next node of the preorder.
    Order {
        /// The node.
        node: usize,
        /// The preorder position it was reached at.
        expected: usize,
        /// The offending child link, if any.
        child: Option<u32>,
    },
    /// Node `node` lies `depth` edges below the root, deeper than the kernels' stacks hold.
    TooDeep {
        /// The node.
        node: usize,
        /// Its depth.
        depth: usize,
        /// The deepest allowed ([`MAX_DEPTH`]).
        max: usize,
    },
    /// Leaf `node` does not cover the next `count` slots of the index array (leaves in
    /// preorder must cover `prim_indices` in order, each slot once).
    LeafRange {
        /// The leaf.
        node: usize,
        /// Its first slot.
        first: u32,
        /// Its slot count.
        count: u32,
        /// The slot the next leaf had to start at.
        expected: usize,
    },
    /// Slot `slot` of the index array names primitive `prim`, which is out of range, already
    /// named, or not finite (builders drop those).
    PrimIndex {
        /// The slot in `prim_indices`.
        slot: usize,
        /// The primitive it names.
        prim: u32,
        /// What is wrong with it.
        why: &'static str,
    },
    /// Primitive `prim` is finite but in no leaf: the tree would never hit it.
    Unreferenced {
        /// The primitive.
        prim: usize,
    },
    /// Leaf `node` holds `count` primitives, more than the layout stores (`max`).
    LeafSize {
        /// The leaf.
        node: usize,
        /// Its primitives.
        count: u32,
        /// The layout's limit.
        max: u32,
    },
}

impl fmt::Display for TreeError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            TreeError::NoNodes => write!(f, "the tree has no nodes"),
            TreeError::PrimCount { tree, prims } => write!(
                f,
                "the tree is for {tree} primitives (indexed and dropped), {prims} were given"
            ),
            TreeError::Order {
                node,
                expected,
                child: Some(c),
            } => write!(
                f,
                "node {node} (preorder position {expected}): child link {c} is not the next \
                 node of a depth-first preorder"
            ),
            TreeError::Order { node, .. } => write!(
                f,
                "node {node} is not reached from the root in depth-first preorder"
            ),
            TreeError::TooDeep { node, depth, max } => write!(
                f,
                "node {node} lies {depth} levels deep; traversal allows at most {max}"
            ),
            TreeError::LeafRange {
                node,
                first,
                count,
                expected,
            } => write!(
                f,
                "leaf {node} covers slots {first}..{} of the index array, expected them to \
                 start at {expected}",
                *first as u64 + *count as u64
            ),
            TreeError::PrimIndex { slot, prim, why } => {
                write!(
                    f,
                    "slot {slot} of the index array names primitive {prim}: {why}"
                )
            }
            TreeError::Unreferenced { prim } => {
                write!(f, "primitive {prim} is finite but in no leaf")
            }
            TreeError::LeafSize { node, count, max } => write!(
                f,
                "leaf {node} holds {count} primitives; this layout stores at most {max}"
            ),
        }
    }
}

impl std::error::Error for TreeError {}

impl BuildTree {
    /// The same tree with its boxes recomputed bottom-up from `bounds` (one per input
    /// primitive): the tree of a build made in a BVH's scaled frame, told in the caller's units.
    pub(crate) fn refit(&self, bounds: &[Aabb]) -> BuildTree {
        let mut nodes = self.nodes.clone();
        // Preorder: every child comes after its parent, so a reverse sweep sees children first.
        for i in (0..nodes.len()).rev() {
            nodes[i].bounds = match nodes[i].kind {
                NodeKind::Leaf { first, count } => self.prim_indices
                    [first as usize..(first + count) as usize]
                    .iter()
                    .fold(Aabb::EMPTY, |b, &p| b.union(&bounds[p as usize])),
                NodeKind::Inner { left, right } => nodes[left as usize]
                    .bounds
                    .union(&nodes[right as usize].bounds),
            };
        }
        BuildTree {
            nodes,
            prim_indices: self.prim_indices.clone(),
            dropped: self.dropped,
        }
    }

    /// Shape counts: nodes, leaves, depth, largest leaf.
    pub fn stats(&self) -> TreeStats {
        let mut s = TreeStats {
            nodes: self.nodes.len(),
            ..TreeStats::default()
        };
        let mut stack = vec![(0usize, 0usize)];
        while let Some((i, d)) = stack.pop() {
            s.depth = s.depth.max(d);
            match self.nodes[i].kind {
                NodeKind::Inner { left, right } => {
                    stack.push((left as usize, d + 1));
                    stack.push((right as usize, d + 1));
                }
                NodeKind::Leaf { count, .. } => {
                    s.leaves += 1;
                    s.max_leaf = s.max_leaf.max(count as usize);
                }
            }
        }
        s
    }

    /// SAH cost `c_T * ΣA(inner)/A(root) + c_I * Σ A(leaf)·n(leaf)/A(root)`.
    ///
    /// A root of zero area (all geometry on one point or line) makes every node equally likely:
    /// the cost becomes `c_T * inner_nodes + c_I * references`. Areas are taken in f64, so the
    /// cost of a tree with finite boxes is finite at any scale.
    pub fn sah_cost(&self, config: &BuildConfig) -> f64 {
        let root_area = self.nodes[0].bounds.half_area_f64();
        let area = |b: &Aabb| {
            if root_area > 0.0 {
                b.half_area_f64() / root_area
            } else {
                1.0
            }
        };
        self.nodes
            .iter()
            .map(|n| match n.kind {
                NodeKind::Inner { .. } => config.traversal_cost as f64 * area(&n.bounds),
                NodeKind::Leaf { count, .. } => {
                    config.intersection_cost as f64 * area(&n.bounds) * count as f64
                }
            })
            .sum()
    }

    /// Checks that this tree can be laid out over the primitives with boxes `bounds` (one per
    /// input primitive) and traversed safely: nodes in depth-first preorder (root at 0, each
    /// left child right after its parent), no deeper than [`MAX_DEPTH`], leaves covering the
    /// index array in order, every finite primitive named and nothing else, and the
    /// primitives named plus `dropped` equal to `bounds.len()`. Boxes are not checked: the layouts
    /// recompute them from the primitives. What [`crate::Bvh::from_tree`] and every layout's
    /// `from_tree` check before they lay a tree out.
    ///
    /// A primitive may be named by several leaves (a spatial split's pieces, see
    /// [`super::Builder::Sbvh`]) but by one leaf only once; it then counts once towards
    /// `bounds.len()`.
    ///
    /// ```
    /// use quiver_rt::builders::{build, BuildConfig, Builder, TreeError};
    /// use quiver_rt::Aabb;
    /// use glam::Vec3A;
    /// let boxes: Vec<Aabb> = (0..10).map(|i| Aabb::new(Vec3A::splat(i as f32), Vec3A::splat(i as f32 + 0.5))).collect();
    /// let tree = build(&boxes, &BuildConfig::default(), Builder::Binned);
    /// assert_eq!(tree.check(&boxes), Ok(()));
    /// assert!(matches!(tree.check(&boxes[..9]), Err(TreeError::PrimCount { tree: 10, prims: 9 })));
    /// ```
    pub fn check(&self, bounds: &[Aabb]) -> Result<(), TreeError> {
        if self.nodes.is_empty() {
            return Err(TreeError::NoNodes);
        }
        // Each primitive counts once, however many leaves name it (spatial splits); an
        // index out of range counts as one more (it is refused below).
        let mut seen = vec![false; bounds.len()];
        let mut distinct = 0u64;
        for &p in &self.prim_indices {
            match seen.get_mut(p as usize) {
                Some(s) => {
                    distinct += !std::mem::replace(s, true) as u64;
                }
                None => distinct += 1,
            }
        }
        let named = distinct + self.dropped as u64;
        if named != bounds.len() as u64 {
            return Err(TreeError::PrimCount {
                tree: named.min(usize::MAX as u64) as usize,
                prims: bounds.len(),
            });
        }
        // Walk in preorder: the k-th node popped must be node k, the next leaf must start
        // where the last one ended. This alone rules out cycles, shared subtrees and stray
        // links, since every node is reached once and in order.
        let mut stack = vec![(0u32, 0usize)];
        let (mut next, mut slot) = (0usize, 0usize);
        while let Some((i, depth)) = stack.pop() {
            let i = i as usize;
            if i != next {
                return Err(TreeError::Order {
                    node: i,
                    expected: next,
                    child: None,
                });
            }
            next += 1;
            if depth > MAX_DEPTH {
                return Err(TreeError::TooDeep {
                    node: i,
                    depth,
                    max: MAX_DEPTH,
                });
            }
            match self.nodes[i].kind {
                NodeKind::Inner { left, right } => {
                    let n = self.nodes.len();
                    for (c, ok) in [
                        (left, left as usize == i + 1),
                        (right, right as usize > i + 1),
                    ] {
                        if !ok || c as usize >= n {
                            return Err(TreeError::Order {
                                node: i,
                                expected: i,
                                child: Some(c),
                            });
                        }
                    }
                    stack.push((right, depth + 1));
                    stack.push((left, depth + 1));
                }
                NodeKind::Leaf { first, count } => {
                    let end = first as usize + count as usize;
                    if first as usize != slot || end > self.prim_indices.len() {
                        return Err(TreeError::LeafRange {
                            node: i,
                            first,
                            count,
                            expected: slot,
                        });
                    }
                    slot = end;
                }
            }
        }
        if next != self.nodes.len() {
            return Err(TreeError::Order {
                node: next,
                expected: usize::MAX,
                child: None,
            });
        }
        if slot != self.prim_indices.len() {
            return Err(TreeError::LeafRange {
                node: self.nodes.len(),
                first: slot as u32,
                count: 0,
                expected: self.prim_indices.len(),
            });
        }
        for (k, &p) in self.prim_indices.iter().enumerate() {
            let bad = |why| {
                Err(TreeError::PrimIndex {
                    slot: k,
                    prim: p,
                    why,
                })
            };
            let Some(b) = bounds.get(p as usize) else {
                return bad("out of range");
            };
            if !b.is_finite() {
                return bad("not finite");
            }
        }
        // Several leaves may name a primitive (a spatial split's pieces), one leaf only once.
        let mut last_leaf = vec![u32::MAX; bounds.len()];
        for (i, n) in self.nodes.iter().enumerate() {
            if let NodeKind::Leaf { first, count } = n.kind {
                let range = first as usize..first as usize + count as usize;
                for (k, &p) in self.prim_indices[range.clone()].iter().enumerate() {
                    if std::mem::replace(&mut last_leaf[p as usize], i as u32) == i as u32 {
                        return Err(TreeError::PrimIndex {
                            slot: range.start + k,
                            prim: p,
                            why: "named twice in one leaf",
                        });
                    }
                }
            }
        }
        if let Some(p) = (0..bounds.len()).find(|&p| !seen[p] && bounds[p].is_finite()) {
            return Err(TreeError::Unreferenced { prim: p });
        }
        Ok(())
    }

    /// The largest leaf, for layouts that store leaf sizes in fewer bits.
    pub(crate) fn check_leaf_size(&self, max: u32) -> Result<(), TreeError> {
        for (i, n) in self.nodes.iter().enumerate() {
            if let NodeKind::Leaf { count, .. } = n.kind {
                if count > max {
                    return Err(TreeError::LeafSize {
                        node: i,
                        count,
                        max,
                    });
                }
            }
        }
        Ok(())
    }

    /// Checks the invariants every build must keep, given the boxes and configuration it was
    /// built from: everything [`BuildTree::check`] checks (preorder, depth, leaf ranges,
    /// primitive references), and every node reachable exactly once from the root, every finite primitive
    /// referenced (and no other), no leaf above `config.max_leaf_size`, every
    /// parent box containing its children, every leaf box containing the primitives only it
    /// names and meeting those several leaves name (the pieces of a spatial split, whose
    /// union only the geometry can check).
    /// Returns a description of the first violation.
    pub fn validate(&self, bounds: &[Aabb], config: &BuildConfig) -> Result<(), String> {
        self.check(bounds).map_err(|e| e.to_string())?;
        let mut seen_node = vec![false; self.nodes.len()];
        // How many leaves name each primitive, and the last of them.
        let mut named = vec![(0u32, 0usize); bounds.len()];
        let mut refs = 0usize;
        let mut stack = vec![0usize];
        while let Some(i) = stack.pop() {
            let node = self
                .nodes
                .get(i)
                .ok_or(format!("child index {i} out of range"))?;
            if std::mem::replace(&mut seen_node[i], true) {
                return Err(format!("node {i} reached twice"));
            }
            match node.kind {
                NodeKind::Inner { left, right } => {
                    for c in [left as usize, right as usize] {
                        let child = self
                            .nodes
                            .get(c)
                            .ok_or(format!("node {i}: child {c} out of range"))?;
                        if !node.bounds.contains(&child.bounds) {
                            return Err(format!("node {i} does not contain child {c}"));
                        }
                        stack.push(c);
                    }
                }
                NodeKind::Leaf { first, count } => {
                    if count as usize > config.max_leaf_size {
                        return Err(format!("leaf {i} holds {count} > {}", config.max_leaf_size));
                    }
                    let range = first as usize..(first + count) as usize;
                    let ids = self
                        .prim_indices
                        .get(range)
                        .ok_or(format!("leaf {i}: range out of bounds"))?;
                    for &p in ids {
                        let pb = bounds
                            .get(p as usize)
                            .ok_or(format!("leaf {i}: primitive {p} out of range"))?;
                        let common = Aabb {
                            min: node.bounds.min.max(pb.min),
                            max: node.bounds.max.min(pb.max),
                        };
                        if common.is_empty() {
                            return Err(format!("leaf {i} does not meet primitive {p}"));
                        }
                        let n = &mut named[p as usize];
                        *n = (n.0 + 1, i);
                        refs += 1;
                    }
                }
            }
        }
        if let Some(i) = seen_node.iter().position(|&s| !s) {
            return Err(format!("node {i} unreachable"));
        }
        let mut distinct = 0;
        for (p, b) in bounds.iter().enumerate() {
            let (times, leaf) = named[p];
            if b.is_finite() != (times > 0) {
                return Err(format!(
                    "primitive {p} (finite: {}) referenced {times} times",
                    b.is_finite(),
                ));
            }
            // Named once, it was never split: its leaf holds all of it.
            if times == 1 && !self.nodes[leaf].bounds.contains(b) {
                return Err(format!("leaf {leaf} does not contain primitive {p}"));
            }
            distinct += (times > 0) as usize;
        }
        if refs != self.prim_indices.len() || distinct + self.dropped != bounds.len() {
            return Err(format!(
                "{refs} references, {} indices, {} dropped, {} primitives",
                self.prim_indices.len(),
                self.dropped,
                bounds.len()
            ));
        }
        Ok(())
    }
}
