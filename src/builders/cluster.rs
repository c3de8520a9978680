//! What the bottom-up builders (PLOC, AAC) and the insertion-based optimisation share: a binary
//! tree over *units* (groups of primitives, usually one each) linked by child indices, and its
//! conversion into a [`BuildNode`] preorder with the SAH leaf compaction of Bittner et al.
//! (2013): a subtree becomes one leaf wherever that is cheaper than keeping it, within
//! [`BuildConfig::max_leaf_size`].
//!
//! Clustering can make chains as long as the input (exponentially spaced centroids merge one
//! at a time), so everything here walks the tree with explicit stacks, and below
//! [`MEDIAN_DEPTH`] a subtree the compaction keeps is rebuilt by object-median splits: the
//! same depth bound the top-down builders keep, so every traversal stack fits.

use super::{bounds_of, median_split, BuildConfig, BuildNode, NodeKind, MEDIAN_DEPTH};
use crate::geometry::Aabb;

/// A binary tree over units. Nodes `0..units` are the units (unit `k` holds
/// `prims[first[k]..first[k + 1]]`); node `units + i` is inner node `i` with children
/// `children[i]`. Every node's box is in `bounds`.
pub(crate) struct Links {
    /// Start of each unit's primitives in `prims`, plus the end.
    pub first: Vec<u32>,
    /// Primitive indices, unit by unit.
    pub prims: Vec<u32>,
    /// Boxes of the units, then of the inner nodes.
    pub bounds: Vec<Aabb>,
    /// Children of each inner node.
    pub children: Vec<[u32; 2]>,
    /// The root's node index.
    pub root: u32,
}

impl Links {
    /// One unit per primitive, in the given order, with no inner nodes yet.
    pub(crate) fn singletons(order: Vec<u32>, prim_bounds: &[Aabb]) -> Links {
        let n = order.len();
        let mut bounds = Vec::with_capacity(2 * n);
        bounds.extend(order.iter().map(|&p| prim_bounds[p as usize]));
        Links {
            first: (0..=n as u32).collect(),
            prims: order,
            bounds,
            children: Vec::with_capacity(n.saturating_sub(1)),
            root: 0,
        }
    }

    /// Number of units.
    pub(crate) fn units(&self) -> usize {
        self.first.len() - 1
    }

    /// Adds an inner node over `a` and `b` and returns its index.
    pub(crate) fn join(&mut self, a: u32, b: u32) -> u32 {
        let id = self.bounds.len() as u32;
        let bounds = self.bounds[a as usize].union(&self.bounds[b as usize]);
        self.bounds.push(bounds);
        self.children.push([a, b]);
        id
    }

    fn kids(&self, node: u32) -> Option<[u32; 2]> {
        let u = self.units() as u32;
        (node >= u).then(|| self.children[(node - u) as usize])
    }

    fn unit_prims(&self, unit: u32) -> &[u32] {
        &self.prims[self.first[unit as usize] as usize..self.first[unit as usize + 1] as usize]
    }

    /// Appends the primitives below `node` to `out`, left to right.
    fn gather(&self, node: u32, out: &mut Vec<u32>) {
        let mut stack = vec![node];
        while let Some(x) = stack.pop() {
            match self.kids(x) {
                Some([l, r]) => {
                    stack.push(r);
                    stack.push(l);
                }
                None => out.extend_from_slice(self.unit_prims(x)),
            }
        }
    }

    /// Nodes below and including the root, children before parents.
    pub(crate) fn postorder(&self) -> Vec<u32> {
        let mut out = Vec::with_capacity(self.bounds.len());
        let mut stack = vec![self.root];
        // Reverse of (node, right, left) preorder is a valid postorder.
        while let Some(x) = stack.pop() {
            out.push(x);
            if let Some([l, r]) = self.kids(x) {
                stack.push(l);
                stack.push(r);
            }
        }
        out.reverse();
        out
    }

    /// The tree as a [`BuildNode`] preorder and the primitives in leaf order, with every
    /// subtree collapsed into a leaf where the SAH prefers it (and it fits in a leaf).
    pub(crate) fn into_build_tree(
        self,
        prim_bounds: &[Aabb],
        config: &BuildConfig,
    ) -> (Vec<BuildNode>, Vec<u32>) {
        let collapse = self.leaf_choice(config);
        let mut nodes: Vec<BuildNode> = Vec::with_capacity(self.bounds.len());
        let mut out_prims: Vec<u32> = Vec::with_capacity(self.prims.len());
        // (node, depth, output index of the parent whose right link points here)
        let mut stack = vec![(self.root, 0usize, u32::MAX)];
        let mut scratch = Vec::new();
        while let Some((x, depth, parent)) = stack.pop() {
            let me = nodes.len() as u32;
            if let Some(NodeKind::Inner { right, .. }) =
                nodes.get_mut(parent as usize).map(|p| &mut p.kind)
            {
                *right = me;
            }
            let kids = self.kids(x).filter(|_| !collapse[x as usize]);
            match kids {
                Some([l, r]) if depth < MEDIAN_DEPTH => {
                    nodes.push(BuildNode {
                        bounds: self.bounds[x as usize],
                        kind: NodeKind::Inner {
                            left: me + 1,
                            right: 0,
                        },
                    });
                    stack.push((r, depth + 1, me));
                    stack.push((l, depth + 1, u32::MAX));
                }
                Some(_) => {
                    scratch.clear();
                    self.gather(x, &mut scratch);
                    median_tree(
                        prim_bounds,
                        &mut scratch,
                        config,
                        &mut nodes,
                        &mut out_prims,
                    );
                }
                None => {
                    let first = out_prims.len() as u32;
                    self.gather(x, &mut out_prims);
                    nodes.push(BuildNode {
                        bounds: self.bounds[x as usize],
                        kind: NodeKind::Leaf {
                            first,
                            count: out_prims.len() as u32 - first,
                        },
                    });
                }
            }
        }
        (nodes, out_prims)
    }

    /// For every node, whether it becomes a leaf: the cheaper of leaf and split, bottom-up,
    /// where a node's split cost already counts its children's own best choice. Areas are
    /// relative to the root; a root of zero area counts every node alike, as
    /// [`super::BuildTree::sah_cost`] does.
    fn leaf_choice(&self, config: &BuildConfig) -> Vec<bool> {
        let n = self.bounds.len();
        let root_area = self.bounds[self.root as usize].half_area_f64();
        let area = |x: u32| {
            if root_area > 0.0 {
                self.bounds[x as usize].half_area_f64()
            } else {
                1.0
            }
        };
        let (ct, ci) = (
            config.traversal_cost as f64,
            config.intersection_cost as f64,
        );
        let mut count = vec![0usize; n];
        let mut cost = vec![0f64; n];
        let mut leaf = vec![false; n];
        for x in self.postorder() {
            let i = x as usize;
            match self.kids(x) {
                None => {
                    count[i] = self.unit_prims(x).len();
                    cost[i] = ci * area(x) * config.tests(count[i]) as f64;
                    leaf[i] = true;
                }
                Some([l, r]) => {
                    count[i] = count[l as usize] + count[r as usize];
                    let split = ct * area(x) + cost[l as usize] + cost[r as usize];
                    let as_leaf = ci * area(x) * config.tests(count[i]) as f64;
                    leaf[i] = count[i] <= config.max_leaf_size && as_leaf <= split;
                    cost[i] = if leaf[i] { as_leaf } else { split };
                }
            }
        }
        leaf
    }
}

/// Appends a tree over `idx` split at object medians down to leaves that fit (the top-down
/// builders' fallback below [`MEDIAN_DEPTH`]): depth at most `log2(n) + 1`.
fn median_tree(
    prim_bounds: &[Aabb],
    idx: &mut [u32],
    config: &BuildConfig,
    nodes: &mut Vec<BuildNode>,
    out_prims: &mut Vec<u32>,
) {
    let (bounds, centroids) = bounds_of(prim_bounds, idx);
    if idx.len() <= config.max_leaf_size {
        let first = out_prims.len() as u32;
        out_prims.extend_from_slice(idx);
        nodes.push(BuildNode {
            bounds,
            kind: NodeKind::Leaf {
                first,
                count: idx.len() as u32,
            },
        });
        return;
    }
    let me = nodes.len();
    nodes.push(BuildNode {
        bounds,
        kind: NodeKind::Inner {
            left: me as u32 + 1,
            right: 0,
        },
    });
    let nl = median_split(prim_bounds, idx, &centroids);
    let (l, r) = idx.split_at_mut(nl);
    median_tree(prim_bounds, l, config, nodes, out_prims);
    let right = nodes.len() as u32;
    nodes[me].kind = NodeKind::Inner {
        left: me as u32 + 1,
        right,
    };
    median_tree(prim_bounds, r, config, nodes, out_prims);
}

/// A [`BuildNode`] preorder (a builder's output) as [`Links`] whose units are its leaves.
pub(crate) fn from_build_tree(nodes: &[BuildNode], prim_indices: &[u32]) -> Links {
    let leaves = nodes
        .iter()
        .filter(|n| matches!(n.kind, NodeKind::Leaf { .. }))
        .count();
    // Units are numbered in preorder; inner nodes after them, also in preorder.
    let mut id = vec![0u32; nodes.len()];
    let (mut next_unit, mut next_inner) = (0u32, leaves as u32);
    let mut first = Vec::with_capacity(leaves + 1);
    let mut prims = Vec::with_capacity(prim_indices.len());
    let mut bounds = vec![Aabb::EMPTY; nodes.len()];
    for (i, n) in nodes.iter().enumerate() {
        if let NodeKind::Leaf { first: f, count } = n.kind {
            id[i] = next_unit;
            next_unit += 1;
            first.push(prims.len() as u32);
            prims.extend_from_slice(&prim_indices[f as usize..(f + count) as usize]);
        } else {
            id[i] = next_inner;
            next_inner += 1;
        }
        bounds[id[i] as usize] = n.bounds;
    }
    first.push(prims.len() as u32);
    let children = nodes
        .iter()
        .filter_map(|n| match n.kind {
            NodeKind::Inner { left, right } => Some([id[left as usize], id[right as usize]]),
            NodeKind::Leaf { .. } => None,
        })
        .collect();
    Links {
        first,
        prims,
        bounds,
        children,
        root: id[0],
    }
}
