//! [`QBvh4Node`]: the quantized 4-wide node format, child boxes rounded outward to 8 bits per
//! plane in a per-node frame, 64 bytes (one cache line).

use super::bvh4::Node4;
use super::collapse::{Child, Wide};
use super::Bvh4Node;
use crate::geometry::Aabb;
use bytemuck::{Pod, Zeroable};
use wide::f32x4;

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

    fn encode(w: &Wide<4>, pos: &[u32]) -> Self {
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
    #[cfg(test)]
    fn child_bounds(&self, i: usize) -> Aabb {
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
        let w = Wide::<4> {
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
                let w = Wide::<4> {
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
