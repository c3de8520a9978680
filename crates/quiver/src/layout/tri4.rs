//! SIMD triangle leaves: a leaf's triangles in groups of four, structure of arrays, with the
//! terms of the triangle test that do not depend on the ray computed once, when the BVH is
//! laid out ([`crate::LeafFormat`]).

use super::collapse::{Child, Wide};
use super::LeafPrims;
use crate::geometry::{pow2, Triangle};
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
///
/// A group holding a triangle too large or too small for the SIMD arithmetic (it could
/// overflow or underflow f32 where the scalar tests rescale: a coordinate or edge past
/// `2^32`, an edge below `2^-40`, a normal outside `2^-80..2^66`; a scene mixing unit sizes
/// with 1e15 or 1e-15 holds such groups) is stored *far*: `v0`, `v1`, `v2` in both formats,
/// row 3 all NaN with the payload `0x7fc029ca`, and the kernels test its lanes one by one
/// with the scalar test, so every layout answers what [`Triangle::intersect`] answers.
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

/// Row 3's word in every lane of a far group (see [`Tri4`]): a NaN no arithmetic produces
/// and no triangle the builders keep holds (a non-finite triangle is far itself).
const FAR: u32 = 0x7fc0_29ca;

/// A triangle's fast-test terms: `v0`, `e1 = v0 - v1`, `e2 = v2 - v0`, `n = e1 × e2`, with
/// the same glam arithmetic as [`Triangle::intersect`].
fn fast_terms(t: &Triangle) -> [Vec3A; 4] {
    let e1 = t.v[0] - t.v[1];
    let e2 = t.v[2] - t.v[0];
    [t.v[0], e1, e2, e1.cross(e2)]
}

/// Whether the SIMD tests compute exactly what the scalar tests compute for `t`, whose
/// [`fast_terms`] are `[_, e1, e2, n]`: its coordinates, edges and normal (largest component
/// of each) inside the band where their products with a ray's terms neither overflow nor
/// underflow.
fn in_band(t: &Triangle, [_, e1, e2, n]: &[Vec3A; 4]) -> bool {
    let within = |v: Vec3A, lo: f32, hi: f32| {
        let m = v.abs().max_element();
        m <= hi && (m >= lo || m == 0.0)
    };
    t.v.iter().all(|&v| within(v, 0.0, pow2(32)))
        && within(*e1, pow2(-40), pow2(32))
        && within(*e2, pow2(-40), pow2(32))
        && within(*n, pow2(-80), pow2(66))
}

/// Writes the rows of one group from its lanes' triangles (`None`: an unused lane or a
/// primitive without a triangle, never hit) as `format` stores them; a far group when any
/// triangle is outside the band (see [`Tri4`]). The ids are the caller's. What packing and
/// refitting both write.
pub(crate) fn fill(g: &mut Tri4, tris: &[Option<Triangle>; 4], format: LeafFormat) {
    let fast = tris.map(|t| t.map(|t| fast_terms(&t)));
    let far = tris
        .iter()
        .zip(&fast)
        .any(|pair| matches!(pair, (Some(t), Some(f)) if !in_band(t, f)));
    g.rows = [[[f32::NAN; 4]; 3]; 4];
    for (lane, (t, f)) in tris.iter().zip(fast).enumerate() {
        let (Some(t), Some(f)) = (t, f) else { continue };
        let vectors: [Vec3A; 4] = match format {
            _ if far => [t.v[0], t.v[1], t.v[2], Vec3A::NAN],
            LeafFormat::FastTriangles => f,
            LeafFormat::WatertightTriangles => [t.v[0], t.v[1], t.v[2], Vec3A::ZERO],
            LeafFormat::Plain => unreachable!("plain leaves are not packed"),
        };
        for (row, v) in g.rows.iter_mut().zip(vectors) {
            for a in 0..3 {
                row[a][lane] = v[a];
            }
        }
    }
    if far {
        g.rows[3] = [[f32::from_bits(FAR); 4]; 3];
    }
}

/// Writes the groups of the leaf over leaf positions `range` (`ids`: every position's input
/// index) in `format` to `out`, which holds exactly `groups(range.len())` of them.
fn pack<P: Primitive>(
    prims: &LeafPrims<P>,
    ids: &[u32],
    range: std::ops::Range<usize>,
    format: LeafFormat,
    out: &mut [Tri4],
) {
    for (start, g) in range.clone().step_by(4).zip(out) {
        let four = start..(start + 4).min(range.end);
        g.id = [u32::MAX; 4];
        g.id[..four.len()].copy_from_slice(&ids[four.clone()]);
        let mut tris = [None; 4];
        for (t, j) in tris.iter_mut().zip(four) {
            *t = prims.at(ids, j).triangle();
        }
        fill(g, &tris, format);
    }
}

/// The leaf-order primitives a wide layout keeps: all of them for a plain leaf format, none
/// for a triangle format, whose SIMD groups hold every triangle (and far groups its exact
/// corners), so nothing reads a second copy; a refit takes the new ones from its source.
pub(crate) fn plain_only<P: Primitive>(prims: LeafPrims<P>, ids: &[u32]) -> Vec<P> {
    match P::LEAF_FORMAT {
        LeafFormat::Plain => prims.into_ordered(ids),
        _ => Vec::new(),
    }
}

/// For primitive types with a triangle [`LeafFormat`]: packs every leaf of the collapsed tree
/// into groups and points the leaf at its first group instead of its first primitive. Plain
/// formats keep their leaves and get no groups. The groups are numbered in one pass over the
/// nodes, then filled by all threads, each leaf into its own range.
pub(crate) fn pack_leaves<P: Primitive, const W: usize>(
    wide: &mut [Wide<W>],
    prims: &LeafPrims<P>,
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
        .for_each(|(range, mine)| pack(prims, ids, range, P::LEAF_FORMAT, mine));
    out
}

impl Tri4 {
    /// Lane `lane`'s triangle as a watertight or a far group stores it.
    #[inline]
    pub(crate) fn triangle(&self, lane: usize) -> Triangle {
        let v = |k: usize| {
            Vec3A::new(
                self.rows[k][0][lane],
                self.rows[k][1][lane],
                self.rows[k][2][lane],
            )
        };
        Triangle::new(v(0), v(1), v(2))
    }

    /// Whether the kernels test this group lane by lane with the scalar test (see [`Tri4`]).
    #[inline(always)]
    pub(crate) fn is_far(&self) -> bool {
        self.rows[3][0][0].to_bits() == FAR
    }
}

/// Whether any of `groups` is far: a layout holding one takes its leaves' slower path.
pub(crate) fn holds_far(groups: &[Tri4]) -> bool {
    use rayon::prelude::*;
    groups.par_iter().with_min_len(4096).any(Tri4::is_far)
}
