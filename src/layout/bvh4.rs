//! 4-wide BVHs: the binary tree collapsed so each node holds up to four child boxes, tested
//! together with SIMD. Two node formats: [`Bvh4Node`] (exact f32 boxes, 128 bytes) and
//! [`QBvh4Node`] (boxes quantized to 8 bits in a per-node frame, 64 bytes: one cache line).

use super::collapse::{self, collapse, Child};
use super::order::{self, Shape, HOLE};
use super::tri4::{self, FarGroups, Tri4};
use super::{Footprint, LeafPrims};
use crate::builders::{BuildTree, TreeError};
use crate::geometry::{Aabb, Triangle};
use crate::isa::{Isa, Kernels};
use crate::primitive::Primitive;
use bytemuck::{Pod, Zeroable};
use wide::f32x4;

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

/// A 4-wide node with exact boxes: 128 bytes (two cache lines), 64-byte aligned.
///
/// The four child boxes are stored as six SIMD rows (min x, y, z, then max x, y, z; one lane
/// per child). Child `i`: `count[i] == 0` means an inner child at node index `child[i]`;
/// otherwise it is a leaf of `count[i] & !LEAF` primitives from `child[i]`. Unused slots are
/// empty leaves with an empty (inverted) box that no ray enters.
#[repr(C, align(64))]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct Bvh4Node {
    /// `[min_x, min_y, min_z, max_x, max_y, max_z]`, one lane per child.
    pub planes: [[f32; 4]; 6],
    /// Child node index (inner) or first primitive (leaf).
    pub child: [u32; 4],
    /// 0 for an inner child, [`Bvh4Node::LEAF`] | primitive count for a leaf.
    pub count: [u32; 4],
}

const _: () = assert!(std::mem::size_of::<Bvh4Node>() == 128);
const _: () = assert!(std::mem::align_of::<Bvh4Node>() == 64);

impl Bvh4Node {
    /// Flag bit marking a leaf child in [`Bvh4Node::count`].
    pub const LEAF: u32 = 1 << 31;
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

impl Node4 for Bvh4Node {
    const MAX_LEAF: u32 = Bvh4Node::LEAF - 1;

    #[inline(always)]
    fn planes(&self) -> [f32x4; 6] {
        *bytemuck::cast_ref::<[[f32; 4]; 6], [f32x4; 6]>(&self.planes)
    }

    #[inline(always)]
    fn child(&self, i: usize) -> (u32, u32) {
        (self.child[i], self.count[i])
    }

    fn encode(w: &Wide, pos: &[u32]) -> Self {
        let (planes, child, count) = w.rows(Self::LEAF, |j| pos[j as usize]);
        Bvh4Node {
            planes,
            child,
            count,
        }
    }
}

/// A 4-wide BVH: the build tree collapsed so each node holds up to four children, in the
/// node format `N` (exact [`Bvh4Node`]s by default; [`QBvh4`] for quantized ones), over
/// triangles unless `P` says otherwise. (Name the type where it is built, as below: a
/// default type parameter does not pick the node format in an expression.)
///
/// ```
/// use quiver_rt::{reference, BuildOptions, Bvh4, Bvh4Mapping, Isa, QBvh4, Ray, RayQuery, Triangle};
/// use glam::Vec3A;
/// let tris: Vec<Triangle> = (0..100)
///     .map(|i| {
///         let o = Vec3A::new(i as f32, 0.0, 0.0);
///         Triangle::new(o, o + Vec3A::X, o + Vec3A::Y)
///     })
///     .collect();
/// let (_, tree) = BuildOptions::default().build_with_tree(&tris);
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
/// use quiver_rt::{Bvh4, Isa, Triangle};
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
    /// [`crate::LeafFormat`] (empty otherwise); leaf children then index these groups.
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
        let (tree, prims) = super::checked(tree, prims)?;
        tree.check_leaf_size(N::MAX_LEAF)?;
        Ok(Self::from_leaf_prims(&tree, prims.into(), mapping, isa))
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
        }
    }

    /// What the nodes and the leaf data the kernels read occupy (the SIMD groups, where
    /// the leaves have them), and everything the layout keeps.
    pub fn footprint(&self) -> Footprint {
        let mut f = if self.tri4.is_empty() {
            Footprint::of(&self.nodes, &self.prims, &self.prim_ids)
        } else {
            Footprint::of(&self.nodes, &self.tri4, &[])
        };
        f.kept = f.node_bytes
            + std::mem::size_of_val(&self.prims[..])
            + std::mem::size_of_val(&self.prim_ids[..])
            + std::mem::size_of_val(&self.tri4[..])
            + self.far.bytes();
        f
    }

    /// The nodes, root first, in the order of [`Bvh4::mapping`].
    pub fn nodes(&self) -> &[N] {
        &self.nodes
    }

    /// The node array as bytes, as the traversal reads it.
    pub fn node_bytes(&self) -> &[u8] {
        bytemuck::cast_slice(&self.nodes)
    }

    /// The primitives in leaf order, for plain leaf formats. Empty for triangle formats
    /// ([`LeafFormat`](crate::LeafFormat)): their leaves are only the SIMD [`groups`](Bvh4::groups), which hold
    /// each triangle and its input index, so the layout keeps no second copy; the primitive
    /// at leaf position `k` is the input's `prim_ids()[k]`.
    pub fn prims(&self) -> &[P] {
        &self.prims
    }

    /// For each primitive in leaf order, its index in the input (what hits report).
    pub fn prim_ids(&self) -> &[u32] {
        &self.prim_ids
    }

    /// The leaves as SIMD triangle groups (triangle leaf formats; empty otherwise).
    pub fn groups(&self) -> &[Tri4] {
        &self.tri4
    }

    /// Node order.
    pub fn mapping(&self) -> Bvh4Mapping {
        self.mapping
    }

    /// Every primitive's box.
    pub fn bounds(&self) -> Aabb {
        self.bounds
    }
}

/// A 4-wide node in one 64-byte cache line: child boxes quantized to 8 bits per plane.
///
/// Coordinates are `origin + q · 2^exp` per axis, with `q` in 0..=255. Quantization rounds
/// outward and is checked in the same f32 arithmetic the traversal uses, so a decoded box
/// always contains the exact one: traversal may enter more boxes, never fewer. Child `i`:
/// `count[i] == 0` is an inner child at node `child[i]`, otherwise a leaf of `count[i]`
/// primitives from `child[i]`. Unused slots decode to an inverted box no ray enters, and carry
/// `child[i] == u32::MAX`.
#[repr(C, align(64))]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct QBvh4Node {
    /// Lower corner of the node's frame.
    pub origin: [f32; 3],
    /// Per-axis step `2^exp` (`-126 <= exp <= 127`).
    pub exp: [i8; 3],
    /// Unused.
    pub pad: u8,
    /// `[min_x, min_y, min_z, max_x, max_y, max_z]` in steps from `origin`, one byte per child.
    pub q: [[u8; 4]; 6],
    /// Child node index (inner) or first primitive (leaf).
    pub child: [u32; 4],
    /// 0 for an inner child, else the leaf's primitive count.
    pub count: [u16; 4],
}

const _: () = assert!(std::mem::size_of::<QBvh4Node>() == 64);
const _: () = assert!(std::mem::align_of::<QBvh4Node>() == 64);

/// `2^e` for a normal exponent.
#[inline(always)]
fn pow2(e: i8) -> f32 {
    f32::from_bits(((e as i32 + 127) as u32) << 23)
}

/// Decodes one quantized coordinate exactly as the traversal does (a multiply, then an add).
#[inline(always)]
fn decode(origin: f32, step: f32, q: u8) -> f32 {
    origin + q as f32 * step
}

impl Node4 for QBvh4Node {
    const MAX_LEAF: u32 = u16::MAX as u32;

    #[inline(always)]
    fn planes(&self) -> [f32x4; 6] {
        let mut out = [f32x4::ZERO; 6];
        for (row, q) in out.iter_mut().zip(&self.q) {
            *row = f32x4::new([q[0] as f32, q[1] as f32, q[2] as f32, q[3] as f32]);
        }
        for a in 0..3 {
            // Multiply, then add: the arithmetic the encoder verified as conservative.
            let (o, step) = (
                f32x4::splat(self.origin[a]),
                f32x4::splat(pow2(self.exp[a])),
            );
            out[a] = out[a] * step + o;
            out[3 + a] = out[3 + a] * step + o;
        }
        out
    }

    #[inline(always)]
    fn child(&self, i: usize) -> (u32, u32) {
        match self.count[i] {
            // Inner, unless this is an unused slot (marked by an impossible node index).
            0 if self.child[i] == u32::MAX => (0, Bvh4Node::LEAF),
            0 => (self.child[i], 0),
            n => (self.child[i], Bvh4Node::LEAF | n as u32),
        }
    }

    fn encode(w: &Wide, pos: &[u32]) -> Self {
        let frame = w.boxes.iter().fold(Aabb::EMPTY, |a, b| a.union(b));
        let mut n = QBvh4Node::zeroed();
        if frame.is_empty() {
            for i in 0..4 {
                (n.q[0][i], n.q[3][i]) = (255, 0);
                n.child[i] = u32::MAX;
            }
            return n;
        }
        n.origin = frame.min.into();
        for a in 0..3 {
            let (lo, hi) = (frame.min[a], frame.max[a]);
            // The smallest step whose 255th multiple reaches the frame's top.
            let mut e = ((hi - lo) / 255.0).log2().ceil().clamp(-126.0, 127.0) as i8;
            while e < 127 && decode(lo, pow2(e), 255) < hi {
                e += 1;
            }
            n.exp[a] = e;
        }
        for (i, (b, k)) in w.boxes.iter().zip(&w.kids).enumerate() {
            // A leaf of no primitives holds nothing: it becomes an unused slot, since a count
            // of 0 here means an inner node (a tree from outside may give such a leaf a real
            // box and any `first`, which would otherwise send the walk to node `first`).
            if matches!(*k, Child::Empty | Child::Leaf { count: 0, .. }) {
                for a in 0..3 {
                    (n.q[a][i], n.q[3 + a][i]) = (255, 0);
                }
                n.child[i] = u32::MAX;
                continue;
            }
            for a in 0..3 {
                let (o, step) = (n.origin[a], pow2(n.exp[a]));
                let mut qlo = ((b.min[a] - o) / step).floor().clamp(0.0, 255.0) as u8;
                while qlo > 0 && decode(o, step, qlo) > b.min[a] {
                    qlo -= 1;
                }
                let mut qhi = ((b.max[a] - o) / step).ceil().clamp(0.0, 255.0) as u8;
                while qhi < 255 && decode(o, step, qhi) < b.max[a] {
                    qhi += 1;
                }
                debug_assert!(decode(o, step, qlo) <= b.min[a] && decode(o, step, qhi) >= b.max[a]);
                (n.q[a][i], n.q[3 + a][i]) = (qlo, qhi);
            }
            (n.child[i], n.count[i]) = match *k {
                Child::Empty | Child::Leaf { count: 0, .. } => unreachable!(),
                Child::Inner(j) => (pos[j as usize], 0),
                // Leaves above `MAX_LEAF` are refused before encoding (`from_tree`) or
                // never built (`BuildOptions` caps the leaf size for this layout).
                Child::Leaf { first, count } => (first, count.min(u16::MAX as u32) as u16),
            };
        }
        n
    }
}

impl QBvh4Node {
    /// The decoded box of child `i` (conservative: contains the exact box).
    pub fn child_bounds(&self, i: usize) -> Aabb {
        let mut b = Aabb::EMPTY;
        for a in 0..3 {
            let (o, step) = (self.origin[a], pow2(self.exp[a]));
            b.min[a] = decode(o, step, self.q[a][i]);
            b.max[a] = decode(o, step, self.q[3 + a][i]);
        }
        b
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3A;

    /// An empty leaf with a real box (a tree from outside can have one) must not read as
    /// an inner node: with `first` 0 that was the root, and the walk never ended.
    #[test]
    fn an_empty_leaf_is_an_unused_slot_not_an_inner_node() {
        let b = Aabb::new(Vec3A::ZERO, Vec3A::ONE);
        let w = Wide {
            boxes: [b; 4],
            kids: [
                Child::Leaf { first: 0, count: 0 },
                Child::Leaf { first: 0, count: 2 },
                Child::Empty,
                Child::Leaf { first: 5, count: 0 },
            ],
        };
        let n = QBvh4Node::encode(&w, &[]);
        for i in [0, 2, 3] {
            assert_eq!(n.child(i), (0, Bvh4Node::LEAF), "slot {i}");
        }
        assert_eq!(n.child(1), (0, Bvh4Node::LEAF | 2));
    }

    #[test]
    fn quantized_boxes_contain_the_exact_ones() {
        let mut rng = crate::rng::Rng::new(3);
        for scale in [1e-6f32, 1.0, 1e3, 1e7] {
            for _ in 0..200 {
                let mut boxes = [Aabb::EMPTY; 4];
                for b in boxes.iter_mut() {
                    let c = rng.in_box(Vec3A::splat(-scale), Vec3A::splat(scale))
                        + Vec3A::splat(scale * 3.0);
                    let e = rng.in_box(Vec3A::ZERO, Vec3A::splat(scale * 0.1));
                    *b = Aabb::new(c - e, c + e);
                }
                let w = Wide {
                    boxes,
                    kids: [Child::Leaf { first: 0, count: 1 }; 4],
                };
                let n = QBvh4Node::encode(&w, &[]);
                for (i, b) in boxes.iter().enumerate() {
                    assert!(
                        n.child_bounds(i).contains(b),
                        "scale {scale}: {b:?} not in {:?}",
                        n.child_bounds(i)
                    );
                }
            }
        }
    }
}
