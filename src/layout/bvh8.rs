//! 8-wide BVHs: the binary tree collapsed so each node holds up to eight child boxes, tested
//! in one 8-lane slab test (one AVX2 instruction per step on the AVX2 path).

use super::collapse::{collapse_sah, Wide};
use super::moved::{refit_unscaled, RefitError};
use super::tri4::{self, FarGroups, Tri4};
use super::walk::sah_cost;
use super::{Footprint, Inputs, LeafPrims};
use crate::builders::{BuildConfig, BuildTree, TreeError};
use crate::geometry::Aabb;
use crate::geometry::Triangle;
use crate::isa::{Isa, Kernels};
use crate::primitive::{LeafFormat, Primitive};
use bytemuck::{Pod, Zeroable};
use rayon::prelude::*;

/// An 8-wide node with exact boxes: 256 bytes (four cache lines), 64-byte aligned.
///
/// The eight child boxes are six rows of eight floats (min x, y, z, then max x, y, z; one lane
/// per child), each row 32-byte aligned for one AVX load. Child `i`: `count[i] == 0` is an
/// inner child at node `child[i]`; otherwise a leaf of `count[i] & !LEAF` primitives from
/// `child[i]` (the first primitive, or for SIMD triangle leaves the first [`Tri4`] group).
/// Unused slots are empty leaves with an inverted box no ray enters.
#[repr(C, align(64))]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct Bvh8Node {
    /// `[min_x, min_y, min_z, max_x, max_y, max_z]`, one lane per child.
    pub planes: [[f32; 8]; 6],
    /// Child node index (inner) or first primitive (leaf).
    pub child: [u32; 8],
    /// 0 for an inner child, [`Bvh8Node::LEAF`] | primitive count for a leaf.
    pub count: [u32; 8],
}

const _: () = assert!(std::mem::size_of::<Bvh8Node>() == 256);
const _: () = assert!(std::mem::align_of::<Bvh8Node>() == 64);

impl Bvh8Node {
    /// Flag bit marking a leaf child in [`Bvh8Node::count`].
    pub const LEAF: u32 = 1 << 31;

    pub(crate) fn encode(w: &Wide<8>) -> Self {
        // Depth-first order: collapsed node `j` is stored at position `j`.
        let (planes, child, count) = w.rows(Self::LEAF, |j| j);
        Bvh8Node {
            planes,
            child,
            count,
        }
    }
}

/// An 8-wide BVH in depth-first order over triangles (or any `P`), traversed with the
/// instruction set chosen when it was built ([`Isa`]).
///
/// ```
/// use quiver_rt::layout::Bvh8;
/// use quiver_rt::traverse::reference;
/// use quiver_rt::{BuildOptions, Bvh, Isa, Layout, Ray, RayQuery, Triangle};
/// use glam::Vec3A;
/// let tris: Vec<Triangle> = (0..300)
///     .map(|i| {
///         let o = Vec3A::new((i % 20) as f32, (i / 20) as f32, 0.0);
///         Triangle::new(o, o + Vec3A::X, o + Vec3A::Y)
///     })
///     .collect();
/// let ray = Ray::new(Vec3A::new(7.2, 3.3, 1.0), -Vec3A::Z);
/// for isa in Isa::ALL {
///     let bvh = Bvh::build(&tris, &BuildOptions::default().layout(Layout::Bvh8Dfs).isa(isa)).unwrap();
///     assert_eq!(bvh.closest_hit(&ray), reference::closest_hit(&tris, &ray));
/// }
/// let (_, tree) = Bvh::build_with_tree(&tris, &BuildOptions::default()).unwrap();
/// let bvh: Bvh8 = Bvh8::from_tree(&tree, &tris, &Default::default(), Isa::detect()).unwrap();
/// assert!(bvh.prims().is_empty() && bvh.groups().len() >= 300 / 4); // SIMD groups of four
/// ```
///
/// The instruction set is chosen when the BVH is made and checked against the CPU; it cannot
/// be set afterwards except through that check:
///
/// ```compile_fail
/// use quiver_rt::layout::Bvh8;
/// use quiver_rt::Isa;
/// fn force(bvh: &mut Bvh8) {
///     bvh.isa = Isa::Avx2; // private: only `with_isa`, which asks the CPU, changes it
/// }
/// ```
#[derive(Clone, Debug)]
pub struct Bvh8<P = Triangle> {
    /// Nodes in depth-first order; the root is node 0.
    pub(crate) nodes: Vec<Bvh8Node>,
    /// Primitives in leaf order.
    pub(crate) prims: Vec<P>,
    /// For each entry of `prims`, its index in the input. Empty in a world's top level,
    /// whose records name their instance (`world::top_level`), outside its refit.
    pub(crate) prim_ids: Vec<u32>,
    /// The leaves as SIMD groups of four triangles, for primitive types with a triangle
    /// [`LeafFormat`] (empty otherwise); leaf children then index these groups.
    pub(crate) tri4: Vec<Tri4>,
    /// The groups stored far ([`Tri4`]): where there are any, the leaves take the path that
    /// tests such groups lane by lane (a layout without one never looks).
    pub(crate) far: FarGroups,
    /// The kernels queries run on, checked against the CPU when chosen.
    pub(crate) kernels: Kernels,
    /// Every primitive's box.
    pub(crate) bounds: Aabb,
    /// What the layout was built over.
    pub(crate) inputs: Inputs,
}

impl<P: Primitive> Bvh8<P> {
    /// Collapses and lays out a built binary tree over `prims` (the build's input), after
    /// checking that the tree fits them ([`BuildTree::check`]; its boxes are recomputed from
    /// `prims`), traversed on `isa` where this CPU has it. The collapse is SAH-optimal under
    /// `config`'s costs and may merge small leaves up to its `max_leaf_size`.
    ///
    /// # Errors
    /// [`TreeError`] when the tree does not fit `prims`, is not in depth-first preorder, or
    /// is deeper than traversal allows.
    pub fn from_tree(
        tree: &BuildTree,
        prims: &[P],
        config: &BuildConfig,
        isa: Isa,
    ) -> Result<Self, TreeError> {
        let inputs = Inputs::of(tree, prims.len());
        let (tree, prims) = super::checked(tree, prims)?;
        tree.check_leaf_size(Bvh8Node::LEAF - 1)?;
        Ok(Self::from_leaf_prims(
            &tree,
            prims.into(),
            inputs,
            isa,
            config,
        ))
    }

    /// Lays out a checked tree with the primitives already in its leaf order.
    pub(crate) fn from_leaf_prims(
        tree: &BuildTree,
        prims: LeafPrims<P>,
        inputs: Inputs,
        isa: Isa,
        config: &BuildConfig,
    ) -> Self {
        // A SIMD leaf costs by the group of four it tests at once, a plain one by the
        // primitive: with the group cost, teapot12's eye rays ran 1.11x faster and its nodes
        // took 13.8 instead of 26.0 bytes per triangle (`quiver layouts`, one run).
        let c_i = config.intersection_cost;
        let leaf_cost = |n: u32| match P::LEAF_FORMAT {
            LeafFormat::Plain => c_i * n as f32,
            _ => c_i * tri4::groups(n) as f32,
        };
        // Merged leaves stay below the flag bit whatever `max_leaf_size` says.
        let max_leaf = config.max_leaf_size.min((Bvh8Node::LEAF - 1) as usize);
        let mut wide = collapse_sah::<8>(tree, max_leaf, config.traversal_cost, leaf_cost);
        let (groups, far) = tri4::pack_leaves(&mut wide, &prims, &tree.prim_indices);
        let prims = tri4::plain_only(prims, &tree.prim_indices);
        let mut nodes = crate::mem::with_capacity(wide.len());
        nodes.par_extend(wide.par_iter().map(Bvh8Node::encode));
        Bvh8 {
            nodes,
            prims,
            prim_ids: tree.prim_indices.clone(),
            far,
            tri4: groups,
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

    /// The same BVH traversed with `isa` (or [`Isa::Portable`] where unsupported).
    pub fn with_isa(mut self, isa: Isa) -> Self {
        self.kernels = Kernels::new(isa);
        self
    }

    /// The instruction set queries run on.
    pub fn isa(&self) -> Isa {
        self.kernels.isa()
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
    /// ([`LeafFormat`]): their leaves are only the SIMD [`groups`](Bvh8::groups), which hold
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
