//! Traversal cost predicted from surface areas alone, before a ray is traced.
//!
//! For a convex body `K` inside a convex body `R`, the share of the lines meeting `R` that
//! also meet `K` is `SA(K) / SA(R)` (Cauchy–Crofton: the mean projected area of a convex body
//! is a quarter of its surface area). A traversal that never stops early enters a node exactly
//! when the line pierces the node's box, so over isotropic random lines through the root box
//! the expected number of nodes entered is `Σ SA(node) / SA(root)`, of leaves
//! `Σ SA(leaf) / SA(root)`, and of primitive tests `Σ SA(leaf)·n(leaf) / SA(root)`. These are
//! identities in expectation, not estimates: the lab's isotropic lines check them within
//! sampling error. Rays that stop at their first hit do less; how much less is what the
//! identity cannot say.
//!
//! Aronov, Brönnimann, Chang and Chiang (2005) turn the same sums into a cost predictor for a
//! whole scene: their simplified weighted work `W(T)` (equation 4 of the paper) sums
//! `(1 + |S_i|)·A(B_i)` over the cells, and their efficiency `E(T)` (equation 5) divides it
//! by `A(B) + Σ_s A(s)`, the root box's area plus the objects' surface area
//! ([`Prediction::aronov`]).
//!
//! ```
//! use quiver_rt::predict::predict;
//! use quiver_rt::{BuildOptions, Layout, Triangle};
//! use glam::Vec3A;
//! let tris: Vec<Triangle> = (0..64)
//!     .map(|i| {
//!         let o = Vec3A::new((i % 8) as f32, (i / 8) as f32, 0.0);
//!         Triangle::new(o, o + Vec3A::X, o + Vec3A::Y)
//!     })
//!     .collect();
//! let (bvh, tree) = BuildOptions::default().layout(Layout::Bvh2Dfs).build_with_tree(&tris);
//! let (p, q) = (predict(&tree), predict(&bvh));
//! // The binary layout holds the build tree's nodes: the same sums.
//! assert!((p.nodes - q.nodes).abs() < 1e-9 && p.nodes >= 1.0);
//! assert!(p.leaves <= p.nodes && p.prim_tests >= p.leaves);
//! ```

use crate::builders::{BuildTree, NodeKind};
use crate::bvh::{AnyLayout, Bvh};
use crate::geometry::Aabb;
use crate::layout::bvh2::{compact_children, Addressing};
use crate::layout::{Bvh2, Bvh4, Bvh8, Bvh8Node, Node4};
use crate::primitive::Primitive;
use crate::world::{Geometry, World};

/// One node as a traversal meets it: its box, the boxes it tests when entered, and the
/// primitives it tests when it is a leaf.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Piece {
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
pub trait Pieces {
    /// Calls `f` once for every node a traversal can enter, the root first. The root's box is
    /// the box of the whole tree (every line through it enters the root).
    fn pieces(&self, f: &mut dyn FnMut(Piece));
}

/// Expected work per isotropic random line through [`Prediction::root`], for a walk that
/// never stops early (see the module documentation for why these are exact expectations).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Prediction {
    /// The box the lines pass through; every node box is clipped to it.
    pub root: Aabb,
    /// Nodes entered (inner and leaf): Σ SA(node) / SA(root).
    pub nodes: f64,
    /// Inner nodes entered: Σ SA(inner) / SA(root).
    pub inner: f64,
    /// Leaves entered: Σ SA(leaf) / SA(root).
    pub leaves: f64,
    /// Ray-box tests: Σ SA(node)·(boxes the node tests) / SA(root).
    pub box_tests: f64,
    /// Ray-primitive tests: Σ SA(leaf)·n(leaf) / SA(root).
    pub prim_tests: f64,
}

impl Prediction {
    /// Aronov et al.'s simplified predictor `E(T) = W(T) / (A(B) + Σ_s A(s))`, with every node
    /// of the hierarchy as a cell (`|S_i|` = 0 for inner nodes): the expected cells entered
    /// plus objects tested per line through the root, times `A(B) / (A(B) + Σ_s A(s))`.
    /// `object_area` is `Σ_s A(s) / A(B)`: the objects' surface area over the root box's
    /// (a flat triangle's surface counts both sides, twice its area, as the Cauchy–Crofton
    /// measure of the lines meeting it does).
    ///
    /// ```
    /// use quiver_rt::predict::predict;
    /// use quiver_rt::{BuildOptions, Triangle};
    /// use glam::Vec3A;
    /// let tris = vec![Triangle::new(Vec3A::ZERO, Vec3A::X, Vec3A::Y)];
    /// let (_, tree) = BuildOptions::default().build_with_tree(&tris);
    /// let p = predict(&tree);
    /// // One leaf holding one triangle, entered by every line: W = 2·A(B).
    /// assert_eq!(p.aronov(0.0), 2.0);
    /// ```
    pub fn aronov(&self, object_area: f64) -> f64 {
        (self.nodes + self.prim_tests) / (1.0 + object_area)
    }
}

/// The prediction for lines through the structure's own root box.
pub fn predict<T: Pieces + ?Sized>(t: &T) -> Prediction {
    let mut root = None;
    t.pieces(&mut |p| {
        root.get_or_insert(p.bounds);
    });
    predict_within(t, &root.unwrap_or(Aabb::EMPTY))
}

/// The prediction for lines through `root`, in the structure's own coordinates (a box that
/// contains every node, or the box the caller's lines pass through). Node boxes are clipped
/// to it: a line through `root` meets a box exactly where it meets the box's part inside
/// `root`, which is convex, so the identity still holds for boxes that stick out (quantized
/// boxes rounded outward). A root of zero area (every primitive on one point or line) counts
/// every node as entered.
pub fn predict_within<T: Pieces + ?Sized>(t: &T, root: &Aabb) -> Prediction {
    let root_area = root.half_area() as f64;
    let mut p = Prediction {
        root: *root,
        nodes: 0.0,
        inner: 0.0,
        leaves: 0.0,
        box_tests: 0.0,
        prim_tests: 0.0,
    };
    t.pieces(&mut |piece| {
        let clipped = clip(&piece.bounds, root);
        if clipped.is_empty() {
            return;
        }
        let w = if root_area > 0.0 {
            clipped.half_area() as f64 / root_area
        } else {
            1.0
        };
        p.nodes += w;
        if piece.leaf {
            p.leaves += w;
        } else {
            p.inner += w;
        }
        p.box_tests += w * piece.box_tests as f64;
        p.prim_tests += w * piece.prims as f64;
    });
    p
}

/// The node counts of Havran's minimum testing output (thesis, section 2.5: the subset of
/// static properties of the data structure) for the structure a walk actually traverses.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Census {
    /// `N_G`: generic (inner) nodes.
    pub inner: usize,
    /// `N_E`: elementary nodes (leaves).
    pub leaves: usize,
    /// `N_EE`: empty elementary nodes (leaves referencing no object).
    pub empty_leaves: usize,
    /// `N_ER`: object references in the leaves.
    pub references: usize,
}

/// Counts the inner nodes, leaves, empty leaves and references of `t` as a walk sees it (for
/// a wide layout, wide nodes and leaf slots; unused slots are not leaves).
///
/// ```
/// use quiver_rt::predict::census;
/// use quiver_rt::{BuildOptions, Layout, Triangle};
/// use glam::Vec3A;
/// let tris: Vec<Triangle> = (0..100)
///     .map(|i| Triangle::new(Vec3A::splat(i as f32), Vec3A::X, Vec3A::Y))
///     .collect();
/// let (bvh, tree) = BuildOptions::default().layout(Layout::Bvh4Dfs).build_with_tree(&tris);
/// let (binary, wide) = (census(&tree), census(&bvh));
/// assert_eq!((binary.references, wide.references), (100, 100));
/// assert_eq!(binary.inner + 1, binary.leaves); // a binary tree
/// assert!(wide.inner < binary.inner);
/// ```
pub fn census<T: Pieces + ?Sized>(t: &T) -> Census {
    let mut c = Census::default();
    t.pieces(&mut |p| {
        if p.leaf {
            c.leaves += 1;
            c.empty_leaves += usize::from(p.prims == 0);
            c.references += p.prims as usize;
        } else {
            c.inner += 1;
        }
    });
    c
}

fn clip(b: &Aabb, to: &Aabb) -> Aabb {
    Aabb::new(b.min.max(to.min), b.max.min(to.max))
}

impl Pieces for BuildTree {
    /// The binary tree as the binary walk meets it: the root's box is tested once, then each
    /// inner node tests both children's boxes.
    fn pieces(&self, f: &mut dyn FnMut(Piece)) {
        for (i, n) in self.nodes.iter().enumerate() {
            let root_test = u32::from(i == 0);
            f(match n.kind {
                NodeKind::Inner { .. } => Piece {
                    bounds: n.bounds,
                    box_tests: 2 + root_test,
                    prims: 0,
                    leaf: false,
                },
                NodeKind::Leaf { count, .. } => Piece {
                    bounds: n.bounds,
                    box_tests: root_test,
                    prims: count,
                    leaf: true,
                },
            });
        }
    }
}

impl<P: Primitive> Pieces for Bvh2<P> {
    /// Walked from the root by the mapping's child rule, so padding slots are left out.
    fn pieces(&self, f: &mut dyn FnMut(Piece)) {
        let addressing = self.mapping.addressing();
        let mut stack = vec![0usize];
        while let Some(i) = stack.pop() {
            let n = &self.nodes[i];
            let root_test = u32::from(i == 0);
            if n.is_leaf() {
                f(Piece {
                    bounds: n.bounds(),
                    box_tests: root_test,
                    prims: n.prim_count(),
                    leaf: true,
                });
                continue;
            }
            f(Piece {
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
fn wide_pieces(
    width: u32,
    slots: impl Fn(usize) -> Vec<(Aabb, u32, u32, bool)>,
    f: &mut dyn FnMut(Piece),
) {
    let root_box = slots(0)
        .iter()
        .filter(|s| !s.0.is_empty())
        .fold(Aabb::EMPTY, |a, s| a.union(&s.0));
    f(Piece {
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
            f(Piece {
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

impl<P: Primitive, N: Node4> Pieces for Bvh4<P, N> {
    fn pieces(&self, f: &mut dyn FnMut(Piece)) {
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
        wide_pieces(4, slots, f);
    }
}

impl<P: Primitive> Pieces for Bvh8<P> {
    fn pieces(&self, f: &mut dyn FnMut(Piece)) {
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
        wide_pieces(8, slots, f);
    }
}

impl<P: Primitive> Pieces for AnyLayout<P> {
    fn pieces(&self, f: &mut dyn FnMut(Piece)) {
        match self {
            AnyLayout::Bvh2(b) => b.pieces(f),
            AnyLayout::Bvh4(b) => b.pieces(f),
            AnyLayout::QBvh4(b) => b.pieces(f),
            AnyLayout::Bvh8(b) => b.pieces(f),
        }
    }
}

/// The nodes a world's walks can enter: its top level's, then each geometry's once (a census
/// of the structure; a ray's walk enters a geometry's once per instance it meets).
impl<P: Primitive> Pieces for World<P> {
    fn pieces(&self, f: &mut dyn FnMut(Piece)) {
        self.top().pieces(f);
        for g in self.geometries() {
            match g {
                Geometry::Triangles(b, _) => b.pieces(f),
                Geometry::Prims(b, _) => b.pieces(f),
            }
        }
    }
}

impl<P: Primitive> Pieces for Bvh<P> {
    /// The layout's own nodes, in the frame the BVH was built in (see [`Bvh::predict_within`]
    /// for lines given in world units).
    fn pieces(&self, f: &mut dyn FnMut(Piece)) {
        // A frame scales every box by one power of two, which leaves area ratios alone.
        self.layout().0.pieces(f)
    }
}

impl<P: Primitive> Bvh<P> {
    /// [`predict_within`] for lines through `root` given in world units (a BVH built in a
    /// scaled frame holds its boxes scaled; the prediction is the same either way).
    ///
    /// ```
    /// use quiver_rt::predict::predict;
    /// use quiver_rt::{BuildOptions, Layout, Triangle};
    /// use glam::Vec3A;
    /// let tris: Vec<Triangle> = (0..50)
    ///     .map(|i| Triangle::new(Vec3A::splat(i as f32), Vec3A::X, Vec3A::Y))
    ///     .collect();
    /// let (bvh, tree) = BuildOptions::default().layout(Layout::Bvh8Dfs).build_with_tree(&tris);
    /// let p = bvh.predict_within(&tree.nodes[0].bounds);
    /// assert!(p.nodes >= 1.0 && p.box_tests >= 8.0);
    /// ```
    pub fn predict_within(&self, root: &Aabb) -> Prediction {
        let (layout, frame) = self.layout();
        let mut p = predict_within(layout, &frame.aabb(root));
        p.root = *root;
        p
    }
}
