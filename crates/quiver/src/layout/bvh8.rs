//! 8-wide BVHs: the binary tree collapsed so each node holds up to eight child boxes, tested
//! in one 8-lane slab test (one AVX2 instruction per step on the AVX2 path).

use super::bvh2::leaf_order;
use super::collapse::{collapse_sah, Wide};
use super::tri4::{self, Tri4};
use super::Footprint;
use crate::builders::{BuildConfig, BuildTree};
use crate::geometry::Triangle;
use crate::isa::Isa;
use crate::primitive::{LeafFormat, Primitive};
use bytemuck::{Pod, Zeroable};

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

    fn encode(w: &Wide<8>) -> Self {
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
/// use quiver::{reference, BuildOptions, Isa, Layout, Ray, RayQuery, Triangle};
/// use glam::Vec3A;
/// let tris: Vec<Triangle> = (0..300)
///     .map(|i| {
///         let o = Vec3A::new((i % 20) as f32, (i / 20) as f32, 0.0);
///         Triangle::new(o, o + Vec3A::X, o + Vec3A::Y)
///     })
///     .collect();
/// let ray = Ray::new(Vec3A::new(7.2, 3.3, 1.0), -Vec3A::Z);
/// for isa in Isa::ALL {
///     let bvh = BuildOptions::default().layout(Layout::Bvh8Dfs).isa(isa).build(&tris);
///     assert_eq!(bvh.closest_hit(&ray), reference::closest_hit(&tris, &ray));
/// }
/// ```
#[derive(Clone, Debug)]
pub struct Bvh8<P = Triangle> {
    /// Nodes in depth-first order; the root is node 0.
    pub nodes: Vec<Bvh8Node>,
    /// Primitives in leaf order.
    pub prims: Vec<P>,
    /// For each entry of `prims`, its index in the input.
    pub prim_ids: Vec<u32>,
    /// The leaves as SIMD groups of four triangles, for primitive types with a triangle
    /// [`LeafFormat`] (empty otherwise); leaf children then index these groups.
    pub tri4: Vec<Tri4>,
    /// The kernels queries run on ([`Isa::Portable`] where the CPU lacks the one asked for).
    pub isa: Isa,
}

impl<P: Primitive> Bvh8<P> {
    /// Collapses and lays out a built binary tree over `prims` (the build's input), for the
    /// instruction set [`Isa::detect`] picks. The collapse is SAH-optimal under `config`'s
    /// costs and may merge small leaves up to its `max_leaf_size`.
    pub fn from_tree(tree: &BuildTree, prims: &[P], config: &BuildConfig) -> Self {
        Self::from_leaf_prims(tree, leaf_order(tree, prims), Isa::detect(), config)
    }

    /// [`Bvh8::from_tree`] with the primitives already in the tree's leaf order.
    pub(crate) fn from_leaf_prims(
        tree: &BuildTree,
        prims: Vec<P>,
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
        let wide = collapse_sah::<8>(tree, config.max_leaf_size, config.traversal_cost, leaf_cost);
        let mut wide = wide;
        let groups = tri4::pack_leaves(&mut wide, &prims, &tree.prim_indices);
        let nodes = wide.iter().map(Bvh8Node::encode).collect();
        Bvh8 {
            nodes,
            prims,
            prim_ids: tree.prim_indices.clone(),
            tri4: groups,
            isa: isa.or_portable(),
        }
    }

    /// The same BVH traversed with `isa` (or [`Isa::Portable`] where unsupported).
    pub fn with_isa(mut self, isa: Isa) -> Self {
        self.isa = isa.or_portable();
        self
    }

    /// What the nodes and the leaf data the kernels read occupy (the SIMD groups, where
    /// the leaves have them).
    pub fn footprint(&self) -> Footprint {
        if self.tri4.is_empty() {
            Footprint::of(&self.nodes, &self.prims, &self.prim_ids)
        } else {
            Footprint::of(&self.nodes, &self.tri4, &[])
        }
    }
}
