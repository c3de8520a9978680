//! Memory layouts of built trees: compact, cache-aligned node arrays ready for traversal.
//!
//! - [`Bvh2`]: 32-byte binary nodes (two per cache line) in any [`Bvh2Mapping`]: depth-first,
//!   breadth-first, shuffled, subtree blocks of a line or a page, and compact subtree blocks.
//! - [`Bvh4`]: the tree collapsed to 4-wide 128-byte nodes (depth-first or page subtrees).
//! - [`QBvh4`]: 4-wide nodes with 8-bit quantized boxes, 64 bytes (one line) each.
//!
//! In every layout the triangles are copied into leaf order, so a leaf is a contiguous run the
//! intersector reads directly. [`Bvh`] holds any of them behind one interface, chosen by
//! [`Layout`].

pub(crate) mod bvh2;
pub(crate) mod bvh4;
pub(crate) mod order;

pub use bvh2::{prim_bounds, triangle_bounds, Bvh2, Bvh2Mapping, Bvh2Node};
pub use bvh4::{Bvh4, Bvh4Mapping, Bvh4Node, QBvh4, QBvh4Node};

use crate::build::{build, BuildConfig, BuildTree, Builder};
use crate::geometry::{Hit, Primitive, Ray, Triangle};
use crate::traverse::{BoxTest, Counters, Stats};
use std::fmt;
use std::str::FromStr;

/// Every layout quiver can build, by its command-line name.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Layout {
    /// `bvh2-dfs`: binary, depth-first.
    Bvh2Dfs,
    /// `bvh2-bfs`: binary, breadth-first.
    Bvh2Bfs,
    /// `bvh2-shuffled`: binary, random order.
    Bvh2Shuffled,
    /// `bvh2-subtree`: binary, cache-line subtree blocks.
    Bvh2Subtree,
    /// `bvh2-subtree-page`: binary, page subtree blocks.
    Bvh2SubtreePage,
    /// `bvh2-compact`: binary, compact (implicitly addressed) two-line blocks.
    Bvh2Compact,
    /// `bvh2-compact-page`: binary, compact page blocks.
    Bvh2CompactPage,
    /// `bvh4-dfs`: 4-wide, depth-first.
    Bvh4Dfs,
    /// `bvh4-subtree`: 4-wide, page subtree blocks.
    Bvh4Subtree,
    /// `bvh4-quant`: 4-wide quantized 64-byte nodes, depth-first.
    Bvh4Quant,
}

impl Layout {
    /// All layouts, in the order reports list them.
    pub const ALL: [Layout; 10] = [
        Layout::Bvh2Dfs,
        Layout::Bvh2Bfs,
        Layout::Bvh2Shuffled,
        Layout::Bvh2Subtree,
        Layout::Bvh2SubtreePage,
        Layout::Bvh2Compact,
        Layout::Bvh2CompactPage,
        Layout::Bvh4Dfs,
        Layout::Bvh4Subtree,
        Layout::Bvh4Quant,
    ];

    /// The command-line and report name.
    pub fn name(self) -> &'static str {
        match self {
            Layout::Bvh2Dfs => "bvh2-dfs",
            Layout::Bvh2Bfs => "bvh2-bfs",
            Layout::Bvh2Shuffled => "bvh2-shuffled",
            Layout::Bvh2Subtree => "bvh2-subtree",
            Layout::Bvh2SubtreePage => "bvh2-subtree-page",
            Layout::Bvh2Compact => "bvh2-compact",
            Layout::Bvh2CompactPage => "bvh2-compact-page",
            Layout::Bvh4Dfs => "bvh4-dfs",
            Layout::Bvh4Subtree => "bvh4-subtree",
            Layout::Bvh4Quant => "bvh4-quant",
        }
    }
}

impl fmt::Display for Layout {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Layout {
    type Err = String;

    /// ```
    /// use quiver::layout::Layout;
    /// assert_eq!("bvh4-quant".parse::<Layout>(), Ok(Layout::Bvh4Quant));
    /// assert!("bvh3".parse::<Layout>().unwrap_err().contains("bvh2-dfs"));
    /// ```
    fn from_str(s: &str) -> Result<Self, String> {
        Layout::ALL
            .into_iter()
            .find(|l| l.name() == s)
            .ok_or_else(|| {
                let names: Vec<&str> = Layout::ALL.iter().map(|l| l.name()).collect();
                format!("unknown layout '{s}': expected one of {}", names.join(", "))
            })
    }
}

/// A laid-out BVH in any [`Layout`], with the queries every layout answers.
///
/// ```
/// use quiver::layout::{Bvh, Layout};
/// use quiver::build::{BuildConfig, Builder};
/// use quiver::{reference};
/// use quiver_scenes::{scene::Scene};
/// let scene = Scene::load("tetra4").unwrap();
/// let tris = scene.triangles();
/// let ray = scene.camera.ray(0.0, 0.1);
/// for layout in Layout::ALL {
///     let (bvh, _) = Bvh::build(&tris, &BuildConfig::default(), Builder::Binned, layout);
///     assert_eq!(bvh.closest_hit(&ray), reference::closest_hit(&tris, &ray));
/// }
/// ```
#[derive(Clone, Debug)]
pub enum Bvh<P = Triangle> {
    /// Binary nodes.
    Bvh2(Bvh2<P>),
    /// 4-wide exact nodes.
    Bvh4(Bvh4<P>),
    /// 4-wide quantized nodes.
    QBvh4(QBvh4<P>),
}

impl<P: Primitive> Bvh<P> {
    /// Builds over `prims` and lays the tree out as `layout`; also returns the build tree.
    pub fn build(
        prims: &[P],
        config: &BuildConfig,
        builder: Builder,
        layout: Layout,
    ) -> (Self, BuildTree) {
        let tree = build(&prim_bounds(prims), config, builder);
        (Bvh::from_tree(&tree, prims, layout), tree)
    }

    /// Lays out a built tree.
    pub fn from_tree(tree: &BuildTree, prims: &[P], layout: Layout) -> Self {
        let b2 = |m| Bvh::Bvh2(Bvh2::from_tree_mapped(tree, prims, m));
        match layout {
            Layout::Bvh2Dfs => b2(Bvh2Mapping::DepthFirst),
            Layout::Bvh2Bfs => b2(Bvh2Mapping::BreadthFirst),
            Layout::Bvh2Shuffled => b2(Bvh2Mapping::Shuffled),
            Layout::Bvh2Subtree => b2(Bvh2Mapping::Subtree),
            Layout::Bvh2SubtreePage => b2(Bvh2Mapping::SubtreePage),
            Layout::Bvh2Compact => b2(Bvh2Mapping::Compact),
            Layout::Bvh2CompactPage => b2(Bvh2Mapping::CompactPage),
            Layout::Bvh4Dfs => Bvh::Bvh4(Bvh4::from_tree(tree, prims, Bvh4Mapping::DepthFirst)),
            Layout::Bvh4Subtree => Bvh::Bvh4(Bvh4::from_tree(tree, prims, Bvh4Mapping::Subtree)),
            Layout::Bvh4Quant => Bvh::QBvh4(QBvh4::from_tree(tree, prims)),
        }
    }

    /// Node slots in the array (padding included).
    pub fn nodes(&self) -> usize {
        match self {
            Bvh::Bvh2(b) => b.nodes.len(),
            Bvh::Bvh4(b) => b.nodes.len(),
            Bvh::QBvh4(b) => b.nodes.len(),
        }
    }

    /// Bytes of the node array.
    pub fn node_bytes(&self) -> usize {
        match self {
            Bvh::Bvh2(b) => b.node_bytes(),
            Bvh::Bvh4(b) => b.node_bytes(),
            Bvh::QBvh4(b) => b.node_bytes(),
        }
    }

    /// Bytes of node and leaf data the traversal reads.
    pub fn bytes(&self) -> usize {
        match self {
            Bvh::Bvh2(b) => b.bytes(),
            Bvh::Bvh4(b) => b.bytes(),
            Bvh::QBvh4(b) => b.bytes(),
        }
    }

    /// The nearest hit (lowest primitive index on ties).
    pub fn closest_hit(&self, ray: &Ray) -> Option<Hit> {
        match self {
            Bvh::Bvh2(b) => b.closest_hit(ray),
            Bvh::Bvh4(b) => b.closest_hit(ray),
            Bvh::QBvh4(b) => b.closest_hit(ray),
        }
    }

    /// Whether anything is hit.
    pub fn any_hit(&self, ray: &Ray) -> bool {
        match self {
            Bvh::Bvh2(b) => b.any_hit(ray),
            Bvh::Bvh4(b) => b.any_hit(ray),
            Bvh::QBvh4(b) => b.any_hit(ray),
        }
    }

    /// Closest hit, counting into `c`.
    pub fn closest_hit_counted(&self, ray: &Ray, c: &mut Counters) -> Option<Hit> {
        match self {
            Bvh::Bvh2(b) => b.closest_hit_counted(ray, c),
            Bvh::Bvh4(b) => b.closest_hit_counted(ray, c),
            Bvh::QBvh4(b) => b.closest_hit_counted(ray, c),
        }
    }

    /// Closest hit with a chosen box test and statistics sink.
    pub fn closest_hit_with<B: BoxTest, S: Stats>(&self, ray: &Ray, stats: &mut S) -> Option<Hit> {
        match self {
            Bvh::Bvh2(b) => b.closest_hit_with::<B, S>(ray, stats),
            Bvh::Bvh4(b) => b.closest_hit_with::<B, S>(ray, stats),
            Bvh::QBvh4(b) => b.closest_hit_with::<B, S>(ray, stats),
        }
    }

    /// Any hit with a chosen box test and statistics sink.
    pub fn any_hit_with<B: BoxTest, S: Stats>(&self, ray: &Ray, stats: &mut S) -> bool {
        match self {
            Bvh::Bvh2(b) => b.any_hit_with::<B, S>(ray, stats),
            Bvh::Bvh4(b) => b.any_hit_with::<B, S>(ray, stats),
            Bvh::QBvh4(b) => b.any_hit_with::<B, S>(ray, stats),
        }
    }

    /// Any hit, counting into `c`.
    pub fn any_hit_counted(&self, ray: &Ray, c: &mut Counters) -> bool {
        match self {
            Bvh::Bvh2(b) => b.any_hit_counted(ray, c),
            Bvh::Bvh4(b) => b.any_hit_counted(ray, c),
            Bvh::QBvh4(b) => b.any_hit_counted(ray, c),
        }
    }
}
