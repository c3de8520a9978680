//! [`Bvh8Ends`]: an 8-wide node array's child boxes at both ends of the shutter, for things
//! that move while it is open. A ray at time `t` meets child `i` in the box
//! `start + t * delta`: each primitive's ends are chosen so that this box holds it at every
//! time, and a node's ends are the unions of its children's, which then hold them too
//! (a union of linearly moving boxes lies inside the linearly moving union of their ends).

use super::Bvh8Node;
use crate::geometry::Aabb;
use glam::Vec3A;

/// Node `n`'s eight child boxes at time 0 (`start`) and their change to time 1 (`delta`),
/// in the rows of [`Bvh8Node::planes`]: 384 bytes, 64-byte aligned. An unused slot keeps the
/// node's inverted box and no change, so no ray at any time enters it.
#[repr(C, align(64))]
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Bvh8Ends {
    /// `[min_x, min_y, min_z, max_x, max_y, max_z]` at time 0, one lane per child.
    pub(crate) start: [[f32; 8]; 6],
    /// What each plane adds by time 1.
    pub(crate) delta: [[f32; 8]; 6],
}

const _: () = assert!(std::mem::size_of::<Bvh8Ends>() == 384);

/// The ends of every node of `nodes` (depth-first, children after their parent), given each
/// leaf primitive's ends by `leaf(prim)`: a box at time 0 and one at time 1 whose linear
/// interpolation holds the primitive at every time in between, already padded for the
/// rounding of `start + t * delta` (see [`pad_ends`]). A leaf of several primitives gets the
/// union of theirs; a primitive with an empty end keeps the node's box (it is out of the
/// build's reach: nothing enters it).
pub(crate) fn node_ends(nodes: &[Bvh8Node], leaf: impl Fn(usize) -> [Aabb; 2]) -> Vec<Bvh8Ends> {
    let mut ends = vec![
        Bvh8Ends {
            start: [[0.0; 8]; 6],
            delta: [[0.0; 8]; 6],
        };
        nodes.len()
    ];
    // Each node's own ends (the union of its children's), filled before its parent reads it.
    let mut whole = vec![[Aabb::EMPTY; 2]; nodes.len()];
    for j in (0..nodes.len()).rev() {
        let n = &nodes[j];
        let mut e = Bvh8Ends {
            start: n.planes,
            delta: [[0.0; 8]; 6],
        };
        let mut union = [Aabb::EMPTY; 2];
        for i in 0..8 {
            let kids = match n.count[i] {
                0 => whole[n.child[i] as usize],
                c => {
                    let first = n.child[i] as usize;
                    (first..first + (c & !Bvh8Node::LEAF) as usize)
                        .map(&leaf)
                        .fold([Aabb::EMPTY; 2], |u, b| {
                            [u[0].union(&b[0]), u[1].union(&b[1])]
                        })
                }
            };
            if kids[0].is_empty() || kids[1].is_empty() {
                continue;
            }
            let [start, delta] = rows(kids);
            for r in 0..6 {
                e.start[r][i] = start[r];
                e.delta[r][i] = delta[r];
            }
            union = [union[0].union(&kids[0]), union[1].union(&kids[1])];
        }
        ends[j] = e;
        whole[j] = union;
    }
    ends
}

/// Ends `[a, b]` as the walk takes them: the planes at time 0 and their change to time 1
/// (rows as [`Bvh8Node::planes`]). Ends so far apart that their change overflows become the
/// box over both, still; an empty end the empty box, still (no ray enters it).
pub(crate) fn rows([a, b]: [Aabb; 2]) -> [[f32; 6]; 2] {
    let (from, lo, hi) = match (a.is_empty() || b.is_empty(), b.min - a.min, b.max - a.max) {
        (true, _, _) => (Aabb::EMPTY, Vec3A::ZERO, Vec3A::ZERO),
        (false, lo, hi) if lo.is_finite() && hi.is_finite() => (a, lo, hi),
        (false, _, _) => (a.union(&b), Vec3A::ZERO, Vec3A::ZERO),
    };
    [
        [
            from.min.x, from.min.y, from.min.z, from.max.x, from.max.y, from.max.z,
        ],
        [lo.x, lo.y, lo.z, hi.x, hi.y, hi.z],
    ]
}

/// Ends `[a, b]` widened so the box the walk computes, `start + t * delta` in f32 (with
/// `delta` rounded), holds the exact interpolation of `[a, b]` at every `t` in `[0, 1]`:
/// both ends move out by 2^-19 of the largest coordinate either holds, several times the
/// few ulps that rounding can cost. Finite ends stay finite.
pub(crate) fn pad_ends([a, b]: [Aabb; 2]) -> [Aabb; 2] {
    if a.is_empty() || b.is_empty() {
        return [Aabb::EMPTY; 2];
    }
    let size = [a.min, a.max, b.min, b.max]
        .iter()
        .fold(0.0f32, |m, v| m.max(v.abs().max_element()));
    let pad = Vec3A::splat(size * (1.0 / (1u32 << 19) as f32));
    let lo = Vec3A::splat(f32::MIN);
    let hi = Vec3A::splat(f32::MAX);
    let out = |x: Aabb| Aabb::new((x.min - pad).max(lo), (x.max + pad).min(hi));
    [out(a), out(b)]
}
