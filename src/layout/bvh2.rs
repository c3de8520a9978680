use crate::build::{build, BuildConfig, BuildTree, Builder, NodeKind};
use crate::geometry::{Aabb, Triangle};
use bytemuck::{Pod, Zeroable};
use glam::Vec3A;

/// A binary BVH node: 32 bytes, two to a 64-byte cache line.
///
/// Inner node: `link` is the right child's index (the left child follows its parent), `count`
/// is 0. Leaf: `link` is the first triangle, `count` is [`Bvh2Node::LEAF`] | triangle count.
#[repr(C, align(32))]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct Bvh2Node {
    /// Lower corner of the box.
    pub min: [f32; 3],
    /// Right child (inner) or first triangle (leaf).
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
}

/// A binary BVH over triangles in depth-first order, with triangles stored in leaf order.
///
/// ```
/// use quiver::{Bvh2, Ray, Triangle};
/// use quiver::build::{BuildConfig, Builder};
/// use glam::Vec3A;
/// let tris = vec![Triangle::new(Vec3A::ZERO, Vec3A::X, Vec3A::Y)];
/// let bvh = Bvh2::build(&tris, &BuildConfig::default(), Builder::Binned).0;
/// let hit = bvh.closest_hit(&Ray::new(Vec3A::new(0.2, 0.2, 1.0), -Vec3A::Z)).unwrap();
/// assert_eq!((hit.prim, hit.t), (0, 1.0));
/// ```
#[derive(Clone, Debug)]
pub struct Bvh2 {
    /// Nodes in depth-first order; the root is node 0.
    pub nodes: Vec<Bvh2Node>,
    /// Triangles in leaf order.
    pub tris: Vec<Triangle>,
    /// For each entry of `tris`, its index in the input.
    pub prim_ids: Vec<u32>,
}

impl Bvh2 {
    /// Builds the tree over `tris` and lays it out; also returns the intermediate tree (for
    /// SAH cost and statistics).
    pub fn build(tris: &[Triangle], config: &BuildConfig, builder: Builder) -> (Bvh2, BuildTree) {
        let bounds = triangle_bounds(tris);
        let tree = build(&bounds, config, builder);
        (Bvh2::from_tree(&tree, tris), tree)
    }

    /// Lays out a built tree. The build tree is already in preorder with each left child right
    /// after its parent, which is exactly the depth-first mapping.
    pub fn from_tree(tree: &BuildTree, tris: &[Triangle]) -> Bvh2 {
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
                Bvh2Node {
                    min: n.bounds.min.into(),
                    link,
                    max: n.bounds.max.into(),
                    count,
                }
            })
            .collect();
        let tris = tree
            .prim_indices
            .par_iter()
            .map(|&i| tris[i as usize])
            .collect();
        Bvh2 {
            nodes,
            tris,
            prim_ids: tree.prim_indices.clone(),
        }
    }

    /// Bytes of node and leaf data the traversal reads.
    pub fn bytes(&self) -> usize {
        std::mem::size_of_val(self.nodes.as_slice())
            + std::mem::size_of_val(self.tris.as_slice())
            + std::mem::size_of_val(self.prim_ids.as_slice())
    }
}

/// One bounding box per triangle, the builders' input. A triangle with a non-finite vertex
/// gets a NaN box, so the build drops it (a min/max over a NaN would silently ignore it).
pub fn triangle_bounds(tris: &[Triangle]) -> Vec<Aabb> {
    use rayon::prelude::*;
    tris.par_iter()
        .map(|t| {
            if t.is_finite() {
                t.bounds()
            } else {
                Aabb::new(Vec3A::NAN, Vec3A::NAN)
            }
        })
        .collect()
}
