//! [`Bvh4Node`]: the exact 4-wide node format, f32 boxes in six SIMD rows, 128 bytes.

use super::bvh4::Node4;
use super::collapse::Wide;
use bytemuck::{Pod, Zeroable};
use wide::f32x4;

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

    fn encode(w: &Wide<4>, pos: &[u32]) -> Self {
        let (planes, child, count) = w.rows(Self::LEAF, |j| pos[j as usize]);
        Bvh4Node {
            planes,
            child,
            count,
        }
    }
}
