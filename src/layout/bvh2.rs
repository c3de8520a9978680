use super::order::{self, Shape, HOLE};
use super::Footprint;
use crate::builders::{BuildTree, NodeKind, TreeError};
use crate::geometry::{Aabb, Triangle};
use crate::primitive::Primitive;
use bytemuck::{Pod, Zeroable};

/// A binary BVH node: 32 bytes, two to a 64-byte cache line.
///
/// Leaf: `link` is the first primitive, `count` is [`Bvh2Node::LEAF`] | primitive count. Inner
/// node, by [`Bvh2Mapping`]: depth-first stores the right child in `link` (the left child
/// follows its parent) and 0 in `count`; the other mappings store the left child in `link` and
/// the right in `count`, except that inside a compact block `count` is 0 and `link` holds the
/// block's height, and the children are found by position.
#[repr(C, align(32))]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct Bvh2Node {
    /// Lower corner of the box.
    pub min: [f32; 3],
    /// Right child (inner) or first primitive (leaf).
    pub link: u32,
    /// Upper corner of the box.
    pub max: [f32; 3],
    /// 0 for inner nodes, `LEAF | count` for leaves.
    pub count: u32,
}

const _: () = assert!(std::mem::size_of::<Bvh2Node>() == 32);
const _: () = assert!(std::mem::align_of::<Bvh2Node>() == 32);

impl Bvh2Node {
    /// Flag bit marking a leaf in [`Bvh2Node::count`].
    pub const LEAF: u32 = 1 << 31;

    /// True for leaves (including the empty leaf of an empty scene).
    #[inline(always)]
    pub fn is_leaf(&self) -> bool {
        self.count & Self::LEAF != 0
    }

    /// Triangles in a leaf.
    #[inline(always)]
    pub fn prim_count(&self) -> u32 {
        self.count & !Self::LEAF
    }

    /// The node's box.
    pub fn bounds(&self) -> Aabb {
        Aabb::new(self.min.into(), self.max.into())
    }

    fn new(bounds: &Aabb, link: u32, count: u32) -> Self {
        Bvh2Node {
            min: bounds.min.into(),
            link,
            max: bounds.max.into(),
            count,
        }
    }
}

/// Where a [`Bvh2`]'s nodes sit in memory (Havran's mappings).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Bvh2Mapping {
    /// Depth-first preorder: the left child follows its parent; only the right child's index
    /// is stored.
    DepthFirst,
    /// Breadth-first (level) order; both child indices stored. A baseline.
    BreadthFirst,
    /// Random order (seeded, root first); both child indices stored. The no-locality baseline.
    Shuffled,
    /// Subtree blocks of one 64-byte cache line. The traversal reads both children of a node
    /// together, so the block is a sibling pair; pairs are placed depth-first. Both child
    /// indices stored.
    Subtree,
    /// Subtree blocks of one 4 KiB page: 64 sibling pairs grown from the block root by area.
    SubtreePage,
    /// Compact subtree blocks of two cache lines: a 3-node heap (plus one pad slot) whose
    /// inner children are found by position (siblings share a line); only links leaving the
    /// block are stored.
    Compact,
    /// Compact subtree blocks of up to one page: a heap of up to 127 nodes (smaller for
    /// short subtrees near the leaves).
    CompactPage,
}

/// How a traversal finds a node's children; one kernel is compiled per variant.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Addressing {
    /// Left child at `i + 1`, right child at `link`.
    DepthFirst,
    /// Left child at `link`, right at `count`.
    Explicit,
    /// Heap blocks (see [`Bvh2Mapping::Compact`]): an inner node with `count == 0` lies inside
    /// a block of height `link` and finds its children by position; any other inner node
    /// stores left in `link`, right in `count`.
    Compact,
}

impl Bvh2Mapping {
    pub(crate) fn addressing(self) -> Addressing {
        match self {
            Bvh2Mapping::DepthFirst => Addressing::DepthFirst,
            Bvh2Mapping::BreadthFirst
            | Bvh2Mapping::Shuffled
            | Bvh2Mapping::Subtree
            | Bvh2Mapping::SubtreePage => Addressing::Explicit,
            Bvh2Mapping::Compact | Bvh2Mapping::CompactPage => Addressing::Compact,
        }
    }

    /// The slot table and, for compact mappings, the block height of each block-interior slot.
    fn slots(self, shape: &Shape) -> (Vec<u32>, Vec<u8>) {
        const LINE: usize = 64 / std::mem::size_of::<Bvh2Node>();
        const PAGE: usize = 4096 / std::mem::size_of::<Bvh2Node>();
        let plain = match self {
            Bvh2Mapping::DepthFirst => order::depth_first(shape),
            Bvh2Mapping::BreadthFirst => order::breadth_first(shape),
            Bvh2Mapping::Shuffled => order::shuffled(shape, 0x5eed),
            Bvh2Mapping::Subtree => order::sibling_pairs(shape, 1),
            Bvh2Mapping::SubtreePage => order::sibling_pairs(shape, PAGE / LINE),
            Bvh2Mapping::Compact => return order::compact(shape, 2),
            Bvh2Mapping::CompactPage => return order::compact(shape, 7),
        };
        let n = plain.len();
        (plain, vec![0; n])
    }
}

/// A binary BVH over triangles (or any `P`): 32-byte nodes in the chosen [`Bvh2Mapping`], primitives copied
/// into leaf order so a leaf is a contiguous run the intersector reads directly.
///
/// ```
/// use quiver_rt::{BuildOptions, Bvh2, Bvh2Mapping, Ray, RayQuery, Triangle};
/// use glam::Vec3A;
/// let tris = vec![Triangle::new(Vec3A::ZERO, Vec3A::X, Vec3A::Y)];
/// let (_, tree) = BuildOptions::default().build_with_tree(&tris);
/// let bvh = Bvh2::from_tree(&tree, &tris, Bvh2Mapping::DepthFirst).unwrap();
/// let hit = bvh.closest_hit(&Ray::new(Vec3A::new(0.2, 0.2, 1.0), -Vec3A::Z)).unwrap();
/// assert_eq!((hit.prim, hit.t), (0, 1.0));
/// assert_eq!(bvh.prim_ids(), &[0]);
/// ```
#[derive(Clone, Debug)]
pub struct Bvh2<P = Triangle> {
    /// Nodes in the order of `mapping`; the root is node 0. Padding slots hold empty leaves.
    pub(crate) nodes: Vec<Bvh2Node>,
    /// Primitives in leaf order.
    pub(crate) prims: Vec<P>,
    /// For each entry of `prims`, its index in the input.
    pub(crate) prim_ids: Vec<u32>,
    /// How the nodes are ordered and linked.
    pub(crate) mapping: Bvh2Mapping,
}

impl<P: Primitive> Bvh2<P> {
    /// Lays out a built tree over `prims` (the build's input) in `mapping`, after checking
    /// that the tree fits them ([`BuildTree::check`]); its boxes are recomputed from `prims`.
    ///
    /// ```
    /// use quiver_rt::builders::{build, prim_bounds, BuildConfig, Builder};
    /// use quiver_rt::{Bvh2, Bvh2Mapping, Ray, RayQuery, Triangle};
    /// use glam::Vec3A;
    /// let tris: Vec<Triangle> = (0..64)
    ///     .map(|i| {
    ///         let o = Vec3A::new((i % 8) as f32, (i / 8) as f32, 0.0);
    ///         Triangle::new(o, o + Vec3A::X, o + Vec3A::Y)
    ///     })
    ///     .collect();
    /// let tree = build(&prim_bounds(&tris), &BuildConfig::default(), Builder::Binned);
    /// let dfs = Bvh2::from_tree(&tree, &tris, Bvh2Mapping::DepthFirst).unwrap();
    /// let sub = Bvh2::from_tree(&tree, &tris, Bvh2Mapping::Subtree).unwrap();
    /// let ray = Ray::new(Vec3A::new(3.2, 5.1, 1.0), -Vec3A::Z);
    /// assert_eq!(dfs.closest_hit(&ray).map(|h| h.prim), Some(43));
    /// assert_eq!(dfs.closest_hit(&ray), sub.closest_hit(&ray));
    /// // A tree for other primitives is an error, not a wrong answer.
    /// assert!(Bvh2::from_tree(&tree, &tris[..10], Bvh2Mapping::DepthFirst).is_err());
    /// ```
    ///
    /// # Errors
    /// [`TreeError`] when the tree does not fit `prims`, is not in depth-first preorder, is
    /// deeper than traversal allows, or has a leaf of `2^31` primitives or more.
    pub fn from_tree(
        tree: &BuildTree,
        prims: &[P],
        mapping: Bvh2Mapping,
    ) -> Result<Self, TreeError> {
        let (tree, prims) = super::checked(tree, prims)?;
        tree.check_leaf_size(Bvh2Node::LEAF - 1)?;
        Ok(Self::from_leaf_prims(&tree, prims, mapping))
    }

    /// The build tree is already in preorder with each left child right after its parent, so
    /// the depth-first layout is a straight (parallel) conversion.
    fn depth_first(tree: &BuildTree, prims: Vec<P>) -> Self {
        use rayon::prelude::*;
        let nodes = tree
            .nodes
            .par_iter()
            .enumerate()
            .map(|(i, n)| {
                let (link, count) = match n.kind {
                    NodeKind::Inner { left, right } => {
                        debug_assert_eq!(left as usize, i + 1);
                        (right, 0)
                    }
                    NodeKind::Leaf { first, count } => (first, Bvh2Node::LEAF | count),
                };
                Bvh2Node::new(&n.bounds, link, count)
            })
            .collect();
        Bvh2 {
            nodes,
            prims,
            prim_ids: tree.prim_indices.clone(),
            mapping: Bvh2Mapping::DepthFirst,
        }
    }

    /// Lays out a checked tree with the primitives already in its leaf order.
    pub(crate) fn from_leaf_prims(tree: &BuildTree, prims: Vec<P>, mapping: Bvh2Mapping) -> Self {
        if mapping == Bvh2Mapping::DepthFirst {
            return Bvh2::depth_first(tree, prims);
        }
        let shape = Shape {
            kids: tree
                .nodes
                .iter()
                .map(|n| match n.kind {
                    NodeKind::Inner { left, right } => [left, right, HOLE, HOLE],
                    NodeKind::Leaf { .. } => [HOLE; 4],
                })
                .collect(),
            area: tree.nodes.iter().map(|n| n.bounds.half_area()).collect(),
        };
        let (slots, interior) = mapping.slots(&shape);
        let pos = order::positions(&slots, tree.nodes.len());
        let nodes = slots
            .iter()
            .enumerate()
            .map(|(i, &n)| {
                if n == HOLE {
                    return Bvh2Node::new(&Aabb::EMPTY, 0, Bvh2Node::LEAF);
                }
                let node = &tree.nodes[n as usize];
                let (link, count) = match node.kind {
                    NodeKind::Leaf { first, count } => (first, Bvh2Node::LEAF | count),
                    NodeKind::Inner { left, right } => {
                        let (l, r) = (pos[left as usize], pos[right as usize]);
                        match interior[i] {
                            0 => (l, r),
                            h => {
                                debug_assert_eq!(
                                    compact_children(i, h as u32),
                                    (l as usize, r as usize)
                                );
                                (h as u32, 0)
                            }
                        }
                    }
                };
                Bvh2Node::new(&node.bounds, link, count)
            })
            .collect();
        Bvh2 {
            nodes,
            prims,
            prim_ids: tree.prim_indices.clone(),
            mapping,
        }
    }

    /// What the nodes and leaves occupy (padding slots included).
    pub fn footprint(&self) -> Footprint {
        Footprint::of(&self.nodes, &self.prims, &self.prim_ids)
    }

    /// The nodes, root first, in the order of [`Bvh2::mapping`].
    pub fn nodes(&self) -> &[Bvh2Node] {
        &self.nodes
    }

    /// The node array as bytes, as the traversal reads it.
    pub fn node_bytes(&self) -> &[u8] {
        bytemuck::cast_slice(&self.nodes)
    }

    /// The primitives in leaf order.
    pub fn prims(&self) -> &[P] {
        &self.prims
    }

    /// For each entry of [`Bvh2::prims`], its index in the input (what hits report).
    pub fn prim_ids(&self) -> &[u32] {
        &self.prim_ids
    }

    /// How the nodes are ordered and linked.
    pub fn mapping(&self) -> Bvh2Mapping {
        self.mapping
    }

    /// The root's box: every primitive's box.
    pub fn bounds(&self) -> Aabb {
        self.nodes[0].bounds()
    }
}

/// Positions of the children of slot `i` inside a compact block of height `h`: at block
/// position `p` they are `2p` and `2p + 1`, i.e. `i + p` and `i + p + 1`.
#[inline(always)]
pub(crate) fn compact_children(i: usize, h: u32) -> (usize, usize) {
    let p = i & ((1 << h) - 1);
    (i + p, i + p + 1)
}

/// The input primitives in the order the leaves reference them.
pub(crate) fn leaf_order<P: Primitive>(tree: &BuildTree, prims: &[P]) -> Vec<P> {
    use rayon::prelude::*;
    tree.prim_indices
        .par_iter()
        .map(|&i| prims[i as usize].clone())
        .collect()
}
