//! 4-wide BVHs: the binary tree collapsed so each node holds up to four child boxes, tested
//! together with SIMD, in either node format of [`Node4`]: [`Bvh4Node`] (exact f32 boxes,
//! 128 bytes, in `bvh4_node.rs`) or [`QBvh4Node`] (boxes quantized to 8 bits in a per-node
//! frame, 64 bytes: one cache line, in `qbvh4_node.rs`).

use super::collapse::{self, collapse, Child};
use super::moved::{refit_unscaled, RefitError};
use super::order::{self, Shape, HOLE};
use super::tri4::{self, FarGroups, Tri4};
use super::walk::sah_cost;
use super::{Footprint, Inputs, LeafPrims};
use crate::builders::{BuildTree, TreeError};
use crate::geometry::{Aabb, Triangle};
use crate::isa::{Isa, Kernels};
use crate::primitive::Primitive;
use bytemuck::Pod;
use wide::f32x4;

pub use super::bvh4_node::Bvh4Node;
pub use super::qbvh4_node::QBvh4Node;

/// A collapsed 4-wide node.
type Wide = collapse::Wide<4>;

/// Where a 4-wide BVH's nodes sit in memory.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Bvh4Mapping {
    /// Depth-first preorder.
    DepthFirst,
    /// Subtree blocks of one 4 KiB page, grown from each block root by area.
    Subtree,
}

/// Orders the collapsed tree and returns (slot table, position of every wide node).
fn arrange(wide: &[Wide], mapping: Bvh4Mapping, node_size: usize) -> (Vec<u32>, Vec<u32>) {
    let slots = match mapping {
        Bvh4Mapping::DepthFirst => (0..wide.len() as u32).collect(),
        Bvh4Mapping::Subtree => {
            let shape = Shape {
                kids: wide
                    .iter()
                    .map(|w| {
                        w.kids.map(|k| match k {
                            Child::Inner(i) => i,
                            _ => HOLE,
                        })
                    })
                    .collect(),
                area: wide
                    .iter()
                    .map(|w| {
                        w.boxes
                            .iter()
                            .fold(Aabb::EMPTY, |a, b| a.union(b))
                            .half_area()
                    })
                    .collect(),
            };
            order::subtree(&shape, 4096 / node_size)
        }
    };
    let pos = order::positions(&slots, wide.len());
    (slots, pos)
}

/// A 4-wide node format: [`Bvh4Node`] (exact boxes) or [`QBvh4Node`] (quantized boxes).
/// [`Bvh4`] and the 4-wide traversal kernels are generic over it, so a new format is one
/// implementation of this trait, inside quiver: the trait is sealed, because the kernels
/// trust a format's child links to form the checked tree it was encoded from.
pub trait Node4: Pod + Send + Sync + sealed::Sealed {
    /// The child boxes as `[min_x, min_y, min_z, max_x, max_y, max_z]` rows, one lane per
    /// child, as the traversal's slab test reads them.
    fn planes(&self) -> [f32x4; 6];
    /// Child `i` as (node index or first primitive, `Bvh4Node::LEAF | count` for a leaf, 0
    /// for an inner node). Unused slots are empty leaves: a ray whose every slab distance is
    /// NaN (all direction components subnormal) "enters" every box, so they must be harmless.
    fn child(&self, i: usize) -> (u32, u32);
    /// The most primitives a leaf of this format holds.
    const MAX_LEAF: u32;
    /// Encodes a collapsed node; `pos` maps collapsed node indices to array positions.
    #[doc(hidden)]
    fn encode(w: &collapse::types::Wide<4>, pos: &[u32]) -> Self;
}

/// Only quiver's own node formats implement [`Node4`].
mod sealed {
    pub trait Sealed {}
    impl Sealed for super::Bvh4Node {}
    impl Sealed for super::QBvh4Node {}
}

/// A 4-wide BVH: the build tree collapsed so each node holds up to four children, in the
/// node format `N` (exact [`Bvh4Node`]s by default; [`QBvh4`] for quantized ones), over
/// triangles unless `P` says otherwise. (Name the type where it is built, as below: a
/// default type parameter does not pick the node format in an expression.)
///
/// ```
/// use quiver_rt::layout::{Bvh4, Bvh4Mapping, QBvh4};
/// use quiver_rt::traverse::reference;
/// use quiver_rt::{BuildOptions, Bvh, Isa, Ray, RayQuery, Triangle};
/// use glam::Vec3A;
/// let tris: Vec<Triangle> = (0..100)
///     .map(|i| {
///         let o = Vec3A::new(i as f32, 0.0, 0.0);
///         Triangle::new(o, o + Vec3A::X, o + Vec3A::Y)
///     })
///     .collect();
/// let (_, tree) = Bvh::build_with_tree(&tris, &BuildOptions::default()).unwrap();
/// let exact: Bvh4 = Bvh4::from_tree(&tree, &tris, Bvh4Mapping::DepthFirst, Isa::detect()).unwrap();
/// let quantized: QBvh4 = QBvh4::from_tree(&tree, &tris, Bvh4Mapping::Subtree, Isa::Portable).unwrap();
/// let ray = Ray::new(Vec3A::new(41.2, 0.3, 1.0), -Vec3A::Z);
/// assert_eq!(exact.closest_hit(&ray), reference::closest_hit(&tris, &ray));
/// assert_eq!(quantized.closest_hit(&ray), exact.closest_hit(&ray));
/// assert!(quantized.footprint().node_bytes < exact.footprint().node_bytes);
/// assert_eq!(quantized.isa(), Isa::Portable);
/// ```
///
/// The instruction set is chosen when the BVH is made and checked against the CPU; it cannot
/// be set afterwards except through that check:
///
/// ```compile_fail
/// use quiver_rt::layout::Bvh4;
/// use quiver_rt::{Isa, Triangle};
/// fn force(bvh: &mut Bvh4) {
///     bvh.isa = Isa::Avx2; // private: only `with_isa`, which asks the CPU, changes it
/// }
/// ```
#[derive(Clone, Debug)]
pub struct Bvh4<P = Triangle, N = Bvh4Node> {
    /// Nodes; the root is node 0. Padding slots are nodes with four empty children.
    pub(crate) nodes: Vec<N>,
    /// Primitives in leaf order.
    pub(crate) prims: Vec<P>,
    /// For each entry of `prims`, its index in the input.
    pub(crate) prim_ids: Vec<u32>,
    /// The leaves as SIMD groups of four triangles, for primitive types with a triangle
    /// [`crate::primitive::LeafFormat`] (empty otherwise); leaf children then index these groups.
    pub(crate) tri4: Vec<Tri4>,
    /// The groups stored far ([`Tri4`]): where there are any, the leaves take the path that
    /// tests such groups lane by lane (a layout without one never looks).
    pub(crate) far: FarGroups,
    /// Node order.
    pub(crate) mapping: Bvh4Mapping,
    /// The kernels packet queries run on (single rays run the same 4-lane kernel on either).
    pub(crate) kernels: Kernels,
    /// Every primitive's box.
    pub(crate) bounds: Aabb,
    /// What the layout was built over.
    pub(crate) inputs: Inputs,
}

/// A 4-wide BVH with quantized 64-byte nodes ([`QBvh4Node`]).
pub type QBvh4<P = Triangle> = Bvh4<P, QBvh4Node>;

impl<P: Primitive, N: Node4> Bvh4<P, N> {
    /// Collapses, encodes and lays out a built binary tree over `prims` (the build's input),
    /// after checking that the tree fits them ([`BuildTree::check`]; its boxes are recomputed
    /// from `prims`), with packet queries on `isa` where this CPU has it.
    ///
    /// # Errors
    /// [`TreeError`] when the tree does not fit `prims`, is not in depth-first preorder, is
    /// deeper than traversal allows, or has a leaf too large for the node format (65535
    /// primitives for [`QBvh4`], `2^31 - 1` for [`Bvh4Node`]).
    pub fn from_tree(
        tree: &BuildTree,
        prims: &[P],
        mapping: Bvh4Mapping,
        isa: Isa,
    ) -> Result<Self, TreeError> {
        let inputs = Inputs::of(tree, prims.len());
        let (tree, prims) = super::checked(tree, prims)?;
        tree.check_leaf_size(N::MAX_LEAF)?;
        Ok(Self::from_leaf_prims(
            &tree,
            prims.into(),
            mapping,
            inputs,
            isa,
        ))
    }

    /// The same BVH with packet queries on `isa` (or [`Isa::Portable`] where unsupported).
    pub fn with_isa(mut self, isa: Isa) -> Self {
        self.kernels = Kernels::new(isa);
        self
    }

    /// The instruction set packet queries run on.
    pub fn isa(&self) -> Isa {
        self.kernels.isa()
    }

    /// Lays out a checked tree with the primitives already in its leaf order.
    pub(crate) fn from_leaf_prims(
        tree: &BuildTree,
        prims: LeafPrims<P>,
        mapping: Bvh4Mapping,
        inputs: Inputs,
        isa: Isa,
    ) -> Self {
        let mut wide = collapse(tree);
        let (groups, far) = tri4::pack_leaves(&mut wide, &prims, &tree.prim_indices);
        let prims = tri4::plain_only(prims, &tree.prim_indices);
        let (slots, pos) = arrange(&wide, mapping, std::mem::size_of::<N>());
        let mut nodes = crate::mem::with_capacity(slots.len());
        nodes.extend(slots.iter().map(|&s| {
            N::encode(
                if s == HOLE {
                    &Wide::EMPTY
                } else {
                    &wide[s as usize]
                },
                &pos,
            )
        }));
        Bvh4 {
            nodes,
            prims,
            prim_ids: tree.prim_indices.clone(),
            far,
            tri4: groups,
            mapping,
            kernels: Kernels::new(isa),
            bounds: tree.nodes[0].bounds,
            inputs,
        }
    }

    /// Refits the layout to `prims`: the primitives it was laid out over, moved, in the same
    /// order (as [`crate::Bvh::refit`], in the caller's units). The tree and node order stay;
    /// every box is recomputed bottom-up in place.
    ///
    /// # Errors
    /// [`RefitError`] as [`crate::Bvh::refit`]; nothing is changed then.
    pub fn refit(&mut self, prims: &[P]) -> Result<(), RefitError> {
        refit_unscaled(self, prims)
    }

    /// The SAH cost of the nodes the walk enters, with unit costs (as [`crate::Bvh::sah_cost`]):
    /// compare it after a refit with its value after the build to judge when to rebuild.
    pub fn sah_cost(&self) -> f64 {
        sah_cost(self)
    }

    /// What the nodes and the leaf data the kernels read occupy (the SIMD groups, where
    /// the leaves have them), and everything the layout keeps.
    pub fn footprint(&self) -> Footprint {
        Footprint::wide(
            &self.nodes,
            &self.prims,
            &self.prim_ids,
            &self.tri4,
            &self.far,
        )
    }

    /// The node array as bytes, as the traversal reads it.
    pub fn node_bytes(&self) -> &[u8] {
        bytemuck::cast_slice(&self.nodes)
    }

    /// The primitives in leaf order, for plain leaf formats. Empty for triangle formats
    /// ([`LeafFormat`](crate::primitive::LeafFormat)): their leaves are only the SIMD [`groups`](Bvh4::groups), which hold
    /// each triangle and its input index, so the layout keeps no second copy; the primitive
    /// at leaf position `k` is the one the groups name there.
    pub fn prims(&self) -> &[P] {
        &self.prims
    }

    /// The leaves as SIMD triangle groups (triangle leaf formats; empty otherwise).
    pub fn groups(&self) -> &[Tri4] {
        &self.tri4
    }

    /// Every primitive's box.
    pub fn bounds(&self) -> Aabb {
        self.bounds
    }
}
