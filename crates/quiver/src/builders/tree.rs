//! [`BuildTree`], every builder's output: a binary tree of boxes over ranges of a primitive
//! index array, with its shape statistics, SAH cost and invariant check.

use super::BuildConfig;
use crate::geometry::Aabb;

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
    /// Input primitive indices in leaf order.
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
    /// the cost becomes `c_T * inner_nodes + c_I * references`.
    pub fn sah_cost(&self, config: &BuildConfig) -> f64 {
        let root_area = self.nodes[0].bounds.half_area() as f64;
        let area = |b: &Aabb| {
            if root_area > 0.0 {
                b.half_area() as f64 / root_area
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

    /// Checks the invariants every build must keep, given the boxes and configuration it was
    /// built from: every node reachable exactly once from the root, every finite primitive
    /// referenced exactly once (and no other), no leaf above `config.max_leaf_size`, every
    /// parent box containing its children, every leaf box containing its primitives.
    /// Returns a description of the first violation.
    pub fn validate(&self, bounds: &[Aabb], config: &BuildConfig) -> Result<(), String> {
        let mut seen_node = vec![false; self.nodes.len()];
        let mut seen_prim = vec![false; bounds.len()];
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
                        if std::mem::replace(&mut seen_prim[p as usize], true) {
                            return Err(format!("primitive {p} referenced twice"));
                        }
                        if !node.bounds.contains(pb) {
                            return Err(format!("leaf {i} does not contain primitive {p}"));
                        }
                        refs += 1;
                    }
                }
            }
        }
        if let Some(i) = seen_node.iter().position(|&s| !s) {
            return Err(format!("node {i} unreachable"));
        }
        for (p, b) in bounds.iter().enumerate() {
            if b.is_finite() != seen_prim[p] {
                return Err(format!(
                    "primitive {p} (finite: {}) referenced: {}",
                    b.is_finite(),
                    seen_prim[p]
                ));
            }
        }
        if refs != self.prim_indices.len() || refs + self.dropped != bounds.len() {
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
