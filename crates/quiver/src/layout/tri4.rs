//! SIMD triangle leaves: a leaf's triangles in groups of four, structure of arrays, with the
//! terms of the triangle test that do not depend on the ray computed once, when the BVH is
//! laid out ([`crate::LeafFormat`]).

use super::collapse::{Child, Wide};
use crate::geometry::Triangle;
use crate::primitive::{LeafFormat, Primitive};
use bytemuck::{Pod, Zeroable};

use glam::Vec3A;

/// Four triangles, one per SIMD lane: 208 bytes.
///
/// `rows` holds four vectors, each as x, y and z rows of four lanes. For
/// [`LeafFormat::FastTriangles`]: `v0`, `e1 = v0 - v1`, `e2 = v2 - v0` and `n = e1 × e2`,
/// computed with the same glam arithmetic as [`Triangle::intersect`]; for
/// [`LeafFormat::WatertightTriangles`]: `v0`, `v1`, `v2` and zeros. An unused lane is all
/// NaN, which every test rejects without a mask (NaN fails every comparison it must pass),
/// with id `u32::MAX`.
#[repr(C, align(16))]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct Tri4 {
    /// Four vectors as `[x, y, z]` rows of four lanes.
    pub rows: [[[f32; 4]; 3]; 4],
    /// Each lane's primitive index in the input; `u32::MAX` for an unused lane.
    pub id: [u32; 4],
}

const _: () = assert!(std::mem::size_of::<Tri4>() == 208);

/// Groups of four needed for `count` triangles.
#[inline(always)]
pub(crate) fn groups(count: u32) -> u32 {
    count.div_ceil(4)
}

/// Writes the groups of one leaf (`prims` and their input `ids`) in `format` to `out`, which
/// holds exactly `groups(prims.len())` of them.
fn pack<P: Primitive>(prims: &[P], ids: &[u32], format: LeafFormat, out: &mut [Tri4]) {
    for ((chunk, chunk_ids), g) in prims.chunks(4).zip(ids.chunks(4)).zip(out) {
        *g = Tri4 {
            rows: [[[f32::NAN; 4]; 3]; 4],
            id: [u32::MAX; 4],
        };
        for (lane, (p, &id)) in chunk.iter().zip(chunk_ids).enumerate() {
            g.id[lane] = id;
            // A triangle type without a triangle is never hit: its lane stays NaN.
            let Some(t) = p.triangle() else { continue };
            let vectors: [Vec3A; 4] = match format {
                LeafFormat::FastTriangles => {
                    let e1 = t.v[0] - t.v[1];
                    let e2 = t.v[2] - t.v[0];
                    [t.v[0], e1, e2, e1.cross(e2)]
                }
                LeafFormat::WatertightTriangles => [t.v[0], t.v[1], t.v[2], Vec3A::ZERO],
                LeafFormat::Plain => unreachable!("plain leaves are not packed"),
            };
            for (row, v) in g.rows.iter_mut().zip(vectors) {
                for a in 0..3 {
                    row[a][lane] = v[a];
                }
            }
        }
    }
}

/// For primitive types with a triangle [`LeafFormat`]: packs every leaf of the collapsed tree
/// into groups and points the leaf at its first group instead of its first primitive. Plain
/// formats keep their leaves and get no groups. The groups are numbered in one pass over the
/// nodes, then filled by all threads, each leaf into its own range.
pub(crate) fn pack_leaves<P: Primitive, const W: usize>(
    wide: &mut [Wide<W>],
    prims: &[P],
    ids: &[u32],
) -> Vec<Tri4> {
    use rayon::prelude::*;
    if P::LEAF_FORMAT == LeafFormat::Plain {
        return Vec::new();
    }
    // (first primitive, count) of each leaf, in the order its groups are stored.
    let mut leaves = Vec::new();
    let mut total = 0u32;
    for w in wide {
        for k in &mut w.kids {
            if let Child::Leaf { first, count } = k {
                leaves.push((*first as usize, *count as usize));
                *first = total;
                total += groups(*count);
            }
        }
    }
    let mut out: Vec<Tri4> = bytemuck::zeroed_vec(total as usize);
    let mut rest = &mut out[..];
    let mut jobs = Vec::with_capacity(leaves.len());
    for (first, count) in leaves {
        let (mine, tail) = std::mem::take(&mut rest).split_at_mut(groups(count as u32) as usize);
        rest = tail;
        jobs.push((first..first + count, mine));
    }
    jobs.into_par_iter()
        .with_min_len(256)
        .for_each(|(range, mine)| pack(&prims[range.clone()], &ids[range], P::LEAF_FORMAT, mine));
    out
}

impl Tri4 {
    /// Lane `lane`'s triangle as a watertight group stores it.
    #[inline]
    pub(crate) fn watertight_triangle(&self, lane: usize) -> Triangle {
        let v = |k: usize| {
            Vec3A::new(
                self.rows[k][0][lane],
                self.rows[k][1][lane],
                self.rows[k][2][lane],
            )
        };
        Triangle::new(v(0), v(1), v(2))
    }
}
