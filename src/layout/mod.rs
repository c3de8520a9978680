//! Memory layouts of built trees: compact, cache-aligned node arrays ready for traversal.
//!
//! - [`Bvh2`]: 32-byte binary nodes (two per cache line) in any [`Bvh2Mapping`]: depth-first,
//!   breadth-first, shuffled, subtree blocks of a line or a page, and compact subtree blocks.
//! - [`Bvh4`]: the tree collapsed to 4-wide 128-byte nodes (depth-first or page subtrees).
//! - [`QBvh4`]: 4-wide nodes with 8-bit quantized boxes, 64 bytes (one line) each.
//! - [`Bvh8`]: 8-wide 256-byte nodes, depth-first, SIMD triangle leaves; the default.
//!
//! Each is also at the crate root (`quiver_rt::Bvh8`); their contents are read through
//! accessors (`nodes`, `node_bytes`, `prims`, `prim_ids`, `footprint`), never written: a
//! layout made by quiver is a checked tree, and no safe code can make it loop or read out of
//! bounds.
//!
//! In every layout the primitives are copied into leaf order, so a leaf is a contiguous run
//! the intersector reads directly. [`crate::Bvh`] holds any of them behind one interface,
//! chosen by [`Layout`].

pub(crate) mod bvh2;
pub(crate) mod bvh4;
mod bvh4_node;
pub(crate) mod bvh8;
pub(crate) mod collapse;
pub(crate) mod ends;
pub(crate) mod moved;
pub(crate) mod order;
mod qbvh4_node;
pub(crate) mod refit;
pub(crate) mod tri4;
pub(crate) mod walk;

pub use bvh2::{Bvh2, Bvh2Mapping, Bvh2Node};
pub use bvh4::{Bvh4, Bvh4Mapping, Bvh4Node, Node4, QBvh4, QBvh4Node};
pub use bvh8::{Bvh8, Bvh8Node};
pub use tri4::Tri4;

use crate::builders::{prim_bounds, BuildTree, TreeError};
use crate::names::{by_name, ParseError};
use crate::primitive::Primitive;
use std::fmt;
use std::str::FromStr;

/// Every layout quiver can build, by its command-line name.
///
/// The default, `bvh8-dfs`, is the fastest single-ray layout in our measurements (README,
/// "Against obvhs and Embree"); the 4- and 8-wide layouts have packet kernels; `bvh4-quant` needs the
/// least node memory.
///
/// ```
/// use quiver_rt::Layout;
/// assert_eq!(Layout::default(), Layout::Bvh8Dfs);
/// ```
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
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
    /// `bvh8-dfs`: 8-wide 256-byte nodes, depth-first, SIMD triangle leaves, with AVX2
    /// kernels where the CPU has them ([`crate::Isa`]). The default.
    #[default]
    Bvh8Dfs,
}

impl Layout {
    /// All layouts, in the order reports list them.
    pub const ALL: [Layout; 11] = [
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
        Layout::Bvh8Dfs,
    ];

    /// Triangles a leaf of this layout tests at once, for primitives with a triangle
    /// [`crate::primitive::LeafFormat`]: 4 for the wide layouts, whose leaves are SIMD groups of four,
    /// 1 for the binary ones. Plain primitives are tested one by one in every layout.
    ///
    /// ```
    /// use quiver_rt::layout::Layout;
    /// assert_eq!(Layout::Bvh8Dfs.leaf_group(), 4);
    /// assert_eq!(Layout::Bvh2Dfs.leaf_group(), 1);
    /// ```
    pub fn leaf_group(self) -> usize {
        match self {
            Layout::Bvh4Dfs | Layout::Bvh4Subtree | Layout::Bvh4Quant | Layout::Bvh8Dfs => 4,
            _ => 1,
        }
    }

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
            Layout::Bvh8Dfs => "bvh8-dfs",
        }
    }
}

impl fmt::Display for Layout {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Layout {
    type Err = ParseError;

    /// A layout by its [`Layout::name`]; the error lists the names.
    ///
    /// ```
    /// use quiver_rt::layout::Layout;
    /// assert_eq!("bvh4-quant".parse::<Layout>(), Ok(Layout::Bvh4Quant));
    /// assert!("bvh3".parse::<Layout>().unwrap_err().expected.contains(&"bvh2-dfs"));
    /// ```
    fn from_str(s: &str) -> Result<Self, ParseError> {
        by_name(s, &Layout::ALL, Layout::name, "layout")
    }
}

/// A layout's primitives: already in the tree's leaf order, or read from the input order
/// through the tree's leaf order. The wide layouts over a triangle format read each
/// primitive once, into their SIMD groups, and keep none, so the build gives them the input
/// rather than gathering a leaf-order copy they would drop (on an 871k-triangle mesh the copy
/// was 4% of the default build).
pub(crate) enum LeafPrims<'a, P> {
    /// The leaf-order primitives.
    Ordered(Vec<P>),
    /// The primitive of each input index.
    Input(&'a (dyn Fn(u32) -> P + Sync)),
    /// The input itself, by input index: read in leaf order, out of its own, so a layout
    /// prefetches the primitives ahead of the one it packs.
    Slice(&'a [P]),
}

impl<P: Primitive> LeafPrims<'_, P> {
    /// The primitive at leaf position `j` (`ids`: the tree's leaf order of input indices).
    #[inline]
    pub fn at(&self, ids: &[u32], j: usize) -> P {
        match self {
            LeafPrims::Ordered(v) => v[j].clone(),
            LeafPrims::Input(f) => f(ids[j]),
            LeafPrims::Slice(s) => s[ids[j] as usize].clone(),
        }
    }

    /// Starts loading the primitive at leaf position `j`, if there is one and the
    /// primitives are in memory the layout can see.
    #[inline(always)]
    pub fn prefetch(&self, ids: &[u32], j: usize) {
        if let (LeafPrims::Slice(s), Some(&i)) = (self, ids.get(j)) {
            crate::isa::prefetch_at(s, i as usize);
        }
    }

    /// All of them in leaf order.
    pub fn into_ordered(self, ids: &[u32]) -> Vec<P> {
        use rayon::prelude::*;
        match self {
            LeafPrims::Ordered(v) => v,
            LeafPrims::Input(f) => ids.par_iter().map(|&i| f(i)).collect(),
            LeafPrims::Slice(s) => ids.par_iter().map(|&i| s[i as usize].clone()).collect(),
        }
    }
}

impl<P> From<Vec<P>> for LeafPrims<'_, P> {
    fn from(v: Vec<P>) -> Self {
        LeafPrims::Ordered(v)
    }
}

/// `tree` checked against `prims` (the structure [`BuildTree::check`] checks) with its boxes recomputed from them,
/// and the primitives in its leaf order: what every layout's `from_tree` lays out.
pub(crate) fn checked<P: Primitive>(
    tree: &BuildTree,
    prims: &[P],
) -> Result<(BuildTree, Vec<P>), TreeError> {
    let bounds = prim_bounds(prims);
    tree.check_structure(&bounds)?;
    Ok((tree.refit(&bounds), bvh2::leaf_order(tree, prims)))
}

/// How many primitives a layout was built over (those the build dropped included), and how
/// many of them its tree holds (each once, however many leaves name a piece of it): what a
/// refit checks the moved primitives against.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Inputs {
    /// The primitives given to the build.
    pub(crate) len: usize,
    /// Those the tree holds: `len` less the dropped.
    pub(crate) held: usize,
}

impl Inputs {
    /// The inputs of `tree`, built over `len` primitives.
    pub(crate) fn of(tree: &BuildTree, len: usize) -> Inputs {
        Inputs {
            len,
            held: len - tree.dropped,
        }
    }
}

/// What a laid-out BVH occupies in memory.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Footprint {
    /// Node slots in the node array (padding included).
    pub nodes: usize,
    /// Bytes of the node array.
    pub node_bytes: usize,
    /// Bytes of node and leaf data the traversal reads: nodes, primitives, primitive ids.
    pub bytes: usize,
    /// Bytes of everything the layout keeps: what the traversal reads and what only a
    /// refit reads (the leaf order's input indices, where the SIMD groups hold them too).
    pub kept: usize,
}

impl Footprint {
    /// A wide layout's: what its kernels read (the nodes and the SIMD groups, where the
    /// leaves have them, else the leaf-order primitives and their ids), and all it keeps.
    pub(crate) fn wide<N, P>(
        nodes: &[N],
        prims: &[P],
        ids: &[u32],
        groups: &[Tri4],
        far: &tri4::FarGroups,
    ) -> Footprint {
        let mut f = if groups.is_empty() {
            Footprint::of(nodes, prims, ids)
        } else {
            Footprint::of(nodes, groups, &[])
        };
        f.kept = f.node_bytes
            + std::mem::size_of_val(prims)
            + std::mem::size_of_val(ids)
            + std::mem::size_of_val(groups)
            + far.bytes();
        f
    }

    pub(crate) fn of<N, P>(nodes: &[N], prims: &[P], ids: &[u32]) -> Footprint {
        let node_bytes = std::mem::size_of_val(nodes);
        let bytes = node_bytes + std::mem::size_of_val(prims) + std::mem::size_of_val(ids);
        Footprint {
            nodes: nodes.len(),
            node_bytes,
            bytes,
            kept: bytes,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::{Bvh2, Bvh2Mapping, Bvh4, Bvh4Mapping, Bvh8, Footprint, QBvh4, Tri4};
    use crate::bvh::BuildOptions;
    use crate::intersect::Watertight;
    use crate::testing::soup;
    use crate::{Bvh, Isa, Primitive};
    use std::mem::size_of;

    /// One layout's footprint against the formats' sizes: `copy` primitives kept in leaf
    /// order, `groups` SIMD groups, one input index per primitive.
    fn check<P>(f: Footprint, n: usize, copy: usize, groups: usize, what: &str) {
        let groups = groups * size_of::<Tri4>();
        let (ids, prims) = (4 * n, copy * size_of::<P>());
        assert_eq!(f.kept, f.node_bytes + groups + ids + prims, "{what}");
        let read = if groups > 0 { groups } else { ids + prims };
        assert_eq!(f.bytes, f.node_bytes + read, "{what}");
    }

    /// A wide layout over a triangle format keeps its nodes, its SIMD groups and one input
    /// index per triangle, no copy of the triangles; a binary one keeps its leaf-order
    /// primitives and ids beside its nodes.
    fn keeps<P: Primitive>(prims: &[P]) {
        let n = prims.len();
        let (_, tree) = Bvh::build_with_tree(prims, &BuildOptions::default()).unwrap();
        let config = Default::default();
        let isa = Isa::detect();
        let b2 = Bvh2::from_tree(&tree, prims, Bvh2Mapping::DepthFirst).unwrap();
        assert_eq!(b2.prims().len(), n);
        check::<P>(b2.footprint(), n, n, 0, "bvh2");
        let b4: Bvh4<P> = Bvh4::from_tree(&tree, prims, Bvh4Mapping::DepthFirst, isa).unwrap();
        assert!(b4.prims().is_empty() && !b4.groups().is_empty());
        check::<P>(b4.footprint(), n, 0, b4.groups().len(), "bvh4");
        let q4: QBvh4<P> = QBvh4::from_tree(&tree, prims, Bvh4Mapping::DepthFirst, isa).unwrap();
        assert!(q4.prims().is_empty());
        check::<P>(q4.footprint(), n, 0, q4.groups().len(), "qbvh4");
        let b8: Bvh8<P> = Bvh8::from_tree(&tree, prims, &config, isa).unwrap();
        assert!(b8.prims().is_empty());
        check::<P>(b8.footprint(), n, 0, b8.groups().len(), "bvh8");
    }

    #[test]
    fn wide_triangle_layouts_keep_no_copy_of_the_triangles() {
        let tris = soup(500, 7);
        keeps(&tris);
        let watertight: Vec<Watertight> = tris.iter().map(|&t| Watertight(t)).collect();
        keeps(&watertight);
    }
}
