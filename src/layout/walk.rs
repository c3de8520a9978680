//! [`WalkNodes`]: a tree seen as the nodes its walk may enter ([`NodeVisit`]: the node's box,
//! the boxes it tests, the primitives it tests), for the build tree and every layout. What
//! the cost predictor ([`crate::predict`]) and [`crate::Bvh::sah_cost`] read.

use super::bvh2::{compact_children, Addressing};
use super::{Bvh2, Bvh4, Bvh8, Bvh8Node, Node4};
use crate::builders::{BuildTree, NodeKind};
use crate::geometry::Aabb;
use crate::primitive::Primitive;

/// The SAH cost of what `t`'s walk enters, with unit costs: `Σ A(inner)/A(root) +
/// Σ A(leaf)·n(leaf)/A(root)`, in f64 (every node counts once when the root has no area).
pub(crate) fn sah_cost<T: WalkNodes + ?Sized>(t: &T) -> f64 {
    let mut root = None;
    let mut cost = 0.0f64;
    t.walk_nodes(&mut |p| {
        let r = *root.get_or_insert(p.bounds.half_area_f64());
        let a = if r > 0.0 {
            p.bounds.half_area_f64() / r
        } else {
            1.0
        };
        cost += if p.leaf { a * p.prims as f64 } else { a };
    });
    cost
}

/// One node as a traversal meets it: its box, the boxes it tests when entered, and the
/// primitives it tests when it is a leaf.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NodeVisit {
    /// The box the parent tests before entering this node (for the root, the box of the
    /// whole tree).
    pub bounds: Aabb,
    /// Ray-box tests made when the node is entered (children's boxes for an inner node).
    pub box_tests: u32,
    /// Primitives in the leaf; 0 for an inner node.
    pub prims: u32,
    /// Whether the node is a leaf.
    pub leaf: bool,
}

/// Something whose traversal cost can be predicted: a build tree or a laid-out BVH, seen as
/// the nodes its walk may enter.
pub trait WalkNodes {
    /// Calls `f` once for every node a traversal can enter, the root first. The root's box is
    /// the box of the whole tree (every line through it enters the root).
    fn walk_nodes(&self, f: &mut dyn FnMut(NodeVisit));
}

impl WalkNodes for BuildTree {
    /// The binary tree as the binary walk meets it: the root's box is tested once, then each
    /// inner node tests both children's boxes.
    fn walk_nodes(&self, f: &mut dyn FnMut(NodeVisit)) {
        for (i, n) in self.nodes.iter().enumerate() {
            let root_test = u32::from(i == 0);
            f(match n.kind {
                NodeKind::Inner { .. } => NodeVisit {
                    bounds: n.bounds,
                    box_tests: 2 + root_test,
                    prims: 0,
                    leaf: false,
                },
                NodeKind::Leaf { count, .. } => NodeVisit {
                    bounds: n.bounds,
                    box_tests: root_test,
                    prims: count,
                    leaf: true,
                },
            });
        }
    }
}

impl<P: Primitive> WalkNodes for Bvh2<P> {
    /// Walked from the root by the mapping's child rule, so padding slots are left out.
    fn walk_nodes(&self, f: &mut dyn FnMut(NodeVisit)) {
        let addressing = self.mapping.addressing();
        let mut stack = vec![0usize];
        while let Some(i) = stack.pop() {
            let n = &self.nodes[i];
            let root_test = u32::from(i == 0);
            if n.is_leaf() {
                f(NodeVisit {
                    bounds: n.bounds(),
                    box_tests: root_test,
                    prims: n.prim_count(),
                    leaf: true,
                });
                continue;
            }
            f(NodeVisit {
                bounds: n.bounds(),
                box_tests: 2 + root_test,
                prims: 0,
                leaf: false,
            });
            let (l, r) = match addressing {
                Addressing::DepthFirst => (i + 1, n.link as usize),
                Addressing::Explicit => (n.link as usize, n.count as usize),
                Addressing::Compact if n.count == 0 => compact_children(i, n.link),
                Addressing::Compact => (n.link as usize, n.count as usize),
            };
            stack.push(r);
            stack.push(l);
        }
    }
}

/// A wide walk: the root node is entered by every ray and tests all `W` slots; a child slot
/// is entered when its box is hit. `slot(node, i)` gives child `i`'s box, its (index, count)
/// pair and whether it is a leaf; empty slots (empty boxes) are skipped.
fn wide_walk(
    width: u32,
    slots: impl Fn(usize) -> Vec<(Aabb, u32, u32, bool)>,
    f: &mut dyn FnMut(NodeVisit),
) {
    let root_box = slots(0)
        .iter()
        .filter(|s| !s.0.is_empty())
        .fold(Aabb::EMPTY, |a, s| a.union(&s.0));
    f(NodeVisit {
        bounds: root_box,
        box_tests: width,
        prims: 0,
        leaf: false,
    });
    let mut stack = vec![0usize];
    while let Some(i) = stack.pop() {
        for (bounds, child, count, leaf) in slots(i) {
            if bounds.is_empty() || (leaf && count == 0) {
                continue;
            }
            f(NodeVisit {
                bounds,
                box_tests: if leaf { 0 } else { width },
                prims: count,
                leaf,
            });
            if !leaf {
                stack.push(child as usize);
            }
        }
    }
}

impl<P: Primitive, N: Node4> WalkNodes for Bvh4<P, N> {
    fn walk_nodes(&self, f: &mut dyn FnMut(NodeVisit)) {
        let slots = |i: usize| {
            let n = &self.nodes[i];
            let planes = n.planes().map(|r| r.to_array());
            (0..4)
                .map(|k| {
                    let b = Aabb::new(
                        [planes[0][k], planes[1][k], planes[2][k]].into(),
                        [planes[3][k], planes[4][k], planes[5][k]].into(),
                    );
                    let (c, count) = n.child(k);
                    let leaf = count & crate::layout::Bvh4Node::LEAF != 0;
                    (b, c, count & !crate::layout::Bvh4Node::LEAF, leaf)
                })
                .collect()
        };
        wide_walk(4, slots, f);
    }
}

impl<P: Primitive> WalkNodes for Bvh8<P> {
    fn walk_nodes(&self, f: &mut dyn FnMut(NodeVisit)) {
        let slots = |i: usize| {
            let n = &self.nodes[i];
            (0..8)
                .map(|k| {
                    let p = &n.planes;
                    let b = Aabb::new(
                        [p[0][k], p[1][k], p[2][k]].into(),
                        [p[3][k], p[4][k], p[5][k]].into(),
                    );
                    let leaf = n.count[k] & Bvh8Node::LEAF != 0;
                    (b, n.child[k], n.count[k] & !Bvh8Node::LEAF, leaf)
                })
                .collect()
        };
        wide_walk(8, slots, f);
    }
}
