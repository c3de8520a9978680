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
//! use quiver_rt::{BuildOptions, Bvh, Layout, Triangle};
//! use glam::Vec3A;
//! let tris: Vec<Triangle> = (0..64)
//!     .map(|i| {
//!         let o = Vec3A::new((i % 8) as f32, (i / 8) as f32, 0.0);
//!         Triangle::new(o, o + Vec3A::X, o + Vec3A::Y)
//!     })
//!     .collect();
//! let (bvh, tree) = Bvh::build_with_tree(&tris, &BuildOptions::default().layout(Layout::Bvh2Dfs)).unwrap();
//! let (p, q) = (predict(&tree), predict(&bvh));
//! // The binary layout holds the build tree's nodes: the same sums.
//! assert!((p.nodes - q.nodes).abs() < 1e-9 && p.nodes >= 1.0);
//! assert!(p.leaves <= p.nodes && p.prim_tests >= p.leaves);
//! ```

use crate::bvh::Bvh;
use crate::geometry::Aabb;
use crate::primitive::Primitive;

pub use crate::layout::walk::{NodeVisit, WalkNodes};

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
    /// use quiver_rt::{BuildOptions, Bvh, Triangle};
    /// use glam::Vec3A;
    /// let tris = vec![Triangle::new(Vec3A::ZERO, Vec3A::X, Vec3A::Y)];
    /// let (_, tree) = Bvh::build_with_tree(&tris, &BuildOptions::default()).unwrap();
    /// let p = predict(&tree);
    /// // One leaf holding one triangle, entered by every line: W = 2·A(B).
    /// assert_eq!(p.aronov(0.0), 2.0);
    /// ```
    pub fn aronov(&self, object_area: f64) -> f64 {
        (self.nodes + self.prim_tests) / (1.0 + object_area)
    }
}

/// The prediction for lines through the structure's own root box.
pub fn predict<T: WalkNodes + ?Sized>(t: &T) -> Prediction {
    let mut root = None;
    t.walk_nodes(&mut |p| {
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
pub fn predict_within<T: WalkNodes + ?Sized>(t: &T, root: &Aabb) -> Prediction {
    let root_area = root.half_area() as f64;
    let mut p = Prediction {
        root: *root,
        nodes: 0.0,
        inner: 0.0,
        leaves: 0.0,
        box_tests: 0.0,
        prim_tests: 0.0,
    };
    t.walk_nodes(&mut |piece| {
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
/// use quiver_rt::{BuildOptions, Bvh, Layout, Triangle};
/// use glam::Vec3A;
/// let tris: Vec<Triangle> = (0..100)
///     .map(|i| Triangle::new(Vec3A::splat(i as f32), Vec3A::X, Vec3A::Y))
///     .collect();
/// let (bvh, tree) = Bvh::build_with_tree(&tris, &BuildOptions::default().layout(Layout::Bvh4Dfs)).unwrap();
/// let (binary, wide) = (census(&tree), census(&bvh));
/// assert_eq!((binary.references, wide.references), (100, 100));
/// assert_eq!(binary.inner + 1, binary.leaves); // a binary tree
/// assert!(wide.inner < binary.inner);
/// ```
pub fn census<T: WalkNodes + ?Sized>(t: &T) -> Census {
    let mut c = Census::default();
    t.walk_nodes(&mut |p| {
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

impl<P: Primitive> Bvh<P> {
    /// [`predict_within`] for lines through `root` given in world units (a BVH built in a
    /// scaled frame holds its boxes scaled; the prediction is the same either way).
    ///
    /// ```
    /// use quiver_rt::predict::predict;
    /// use quiver_rt::{BuildOptions, Bvh, Layout, Triangle};
    /// use glam::Vec3A;
    /// let tris: Vec<Triangle> = (0..50)
    ///     .map(|i| Triangle::new(Vec3A::splat(i as f32), Vec3A::X, Vec3A::Y))
    ///     .collect();
    /// let (bvh, tree) = Bvh::build_with_tree(&tris, &BuildOptions::default().layout(Layout::Bvh8Dfs)).unwrap();
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
