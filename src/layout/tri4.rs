//! SIMD triangle leaves: a leaf's triangles in groups of four, structure of arrays, with the
//! terms of the triangle test that do not depend on the ray computed once, when the BVH is
//! laid out ([`crate::primitive::LeafFormat`]).

use super::collapse::{Child, Wide};
use super::LeafPrims;
use crate::geometry::{pow2, Triangle};
use crate::primitive::{LeafFormat, Primitive};
use bytemuck::{Pod, Zeroable};

use glam::{Mat4, Vec3A, Vec4};

/// Four triangles, one per SIMD lane: 160 bytes.
///
/// `rows` holds three vectors, each as x, y and z rows of four lanes. For
/// [`LeafFormat::FastTriangles`]: `v0`, `e1 = v0 - v1` and `e2 = v2 - v0`, computed with the
/// same glam arithmetic as [`Triangle::intersect`], which the kernels complete with
/// `n = e1 × e2` in the same operations (six products a test, but no memory: a stored normal
/// was a quarter of the leaf bytes a ray reads); for [`LeafFormat::WatertightTriangles`]:
/// `v0`, `v1`, `v2`. An unused lane is all NaN, which every test rejects without a mask (NaN
/// fails every comparison it must pass), with id `u32::MAX`.
///
/// A group holding a triangle too large or too small for the SIMD arithmetic (it could
/// overflow or underflow f32 where the scalar tests rescale: a coordinate or edge past
/// `2^32`, an edge below `2^-40`, a normal outside `2^-80..2^66`; a scene mixing unit sizes
/// with 1e15 or 1e-15 holds such groups) is stored *far*: `v0`, `v1`, `v2` in both formats,
/// its index in the layout's list of far groups, and the kernels test its lanes one by one
/// with the scalar test, so every layout answers what [`Triangle::intersect`] answers.
///
/// ```
/// use quiver_rt::glam::Vec3A;
/// use quiver_rt::layout::Bvh8;
/// use quiver_rt::{BuildOptions, Bvh, Isa, Triangle};
/// let tris = [Triangle::new(Vec3A::ZERO, Vec3A::X, Vec3A::Y); 3];
/// let (_, tree) = Bvh::build_with_tree(&tris, &BuildOptions::default()).unwrap();
/// let bvh: Bvh8 = Bvh8::from_tree(&tree, &tris, &Default::default(), Isa::detect()).unwrap();
/// let g = &bvh.groups()[0];
/// assert_eq!(std::mem::size_of_val(g), 160);
/// let mut ids = g.id;
/// ids.sort();
/// assert_eq!(ids, [0, 1, 2, u32::MAX]);
/// // The fast format's second row is e1 = v0 - v1 = -X; an unused lane is NaN.
/// assert_eq!(g.rows[1][0][..3], [-1.0; 3]);
/// assert!(g.rows[1][0][3].is_nan());
/// ```
#[repr(C, align(16))]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct Tri4 {
    /// Three vectors as `[x, y, z]` rows of four lanes.
    pub rows: [[[f32; 4]; 3]; 3],
    /// Each lane's primitive index in the input; `u32::MAX` for an unused lane.
    pub id: [u32; 4],
}

const _: () = assert!(std::mem::size_of::<Tri4>() == 160);

/// The groups of a layout stored far (see [`Tri4`]): their indices, ascending. Empty in
/// nearly every BVH; only the kernels' far path, which a layout without far groups never
/// takes, looks a group up.
#[derive(Clone, Debug, Default, PartialEq)]
pub(crate) struct FarGroups(Vec<u32>);

impl FarGroups {
    /// Whether any group is far.
    #[inline(always)]
    pub(crate) fn any(&self) -> bool {
        !self.0.is_empty()
    }

    /// Whether group `g` is far.
    #[inline]
    pub(crate) fn has(&self, g: usize) -> bool {
        self.0.binary_search(&(g as u32)).is_ok()
    }

    /// The far groups' indices, ascending (what a saved BVH stores).
    pub(crate) fn ids(&self) -> &[u32] {
        &self.0
    }

    /// The list of these group indices, which the caller has checked are strictly
    /// ascending and name groups that exist (a loaded file's).
    pub(crate) fn from_checked(ids: Vec<u32>) -> Self {
        FarGroups(ids)
    }

    /// The bytes the list holds.
    pub(crate) fn bytes(&self) -> usize {
        std::mem::size_of_val(&self.0[..])
    }

    /// The far groups among `groups`, whose lanes' triangles `tri(id)` gives, decided as
    /// [`fill`] decides them (for a refit that made some group far).
    pub(crate) fn find(groups: &[Tri4], tri: impl Fn(u32) -> Option<Triangle> + Sync) -> Self {
        use rayon::prelude::*;
        let far = groups
            .par_iter()
            .enumerate()
            .filter_map(|(i, g)| {
                let tris = g.id.map(|id| if id == u32::MAX { None } else { tri(id) });
                fast_rows(&tris).1.then_some(i as u32)
            })
            .collect();
        FarGroups(far)
    }
}

/// Groups of four needed for `count` triangles.
#[inline(always)]
pub(crate) fn groups(count: u32) -> u32 {
    count.div_ceil(4)
}

/// A triangle's fast-test terms: `v0`, `e1 = v0 - v1`, `e2 = v2 - v0`, `n = e1 × e2`, with
/// the same glam arithmetic as [`Triangle::intersect`].
fn fast_terms(t: &Triangle) -> [Vec3A; 4] {
    let e1 = t.v[0] - t.v[1];
    let e2 = t.v[2] - t.v[0];
    [t.v[0], e1, e2, e1.cross(e2)]
}

/// The lanes of a group (bit `i`: lane `i`) whose triangles are outside the band where the
/// SIMD tests compute exactly what the scalar tests compute: a coordinate or edge past
/// `2^32`, an edge below `2^-40` (unless zero), a normal outside `2^-80..2^66` (unless zero).
/// `corners` holds each lane's largest coordinate magnitude, `[e1, e2, n]` the lanes' fast
/// terms as rows. Every triangle packed is finite, and `n` is finite wherever both edges are
/// inside the band, so the lanes' maxima here are the scalar test's maxima.
fn out_of_band(corners: Vec4, [e1, e2, n]: [&[[f32; 4]; 3]; 3]) -> u32 {
    let largest = |r: &[[f32; 4]; 3]| {
        let [x, y, z] = r.map(|row| Vec4::from_array(row).abs());
        x.max(y).max(z)
    };
    let within = |m: Vec4, lo: f32, hi: f32| {
        m.cmple(Vec4::splat(hi)) & (m.cmpge(Vec4::splat(lo)) | m.cmpeq(Vec4::ZERO))
    };
    let ok = corners.cmple(Vec4::splat(pow2(32)))
        & within(largest(e1), pow2(-40), pow2(32))
        & within(largest(e2), pow2(-40), pow2(32))
        & within(largest(n), pow2(-80), pow2(66));
    !ok.bitmask() & 0xf
}

/// Four lanes' vectors as rows: `rows[k][a][lane]` is component `a` of `lanes[lane][k]`.
#[inline(always)]
fn transpose<const K: usize>(lanes: &[[Vec3A; K]; 4]) -> [[[f32; 4]; 3]; K] {
    std::array::from_fn(|k| {
        let m = Mat4::from_cols(
            lanes[0][k].extend(0.0),
            lanes[1][k].extend(0.0),
            lanes[2][k].extend(0.0),
            lanes[3][k].extend(0.0),
        )
        .transpose();
        [
            m.x_axis.to_array(),
            m.y_axis.to_array(),
            m.z_axis.to_array(),
        ]
    })
}

/// A group's fast-test terms as rows (`v0`, `e1`, `e2`, `n`; an unused lane NaN), and
/// whether the group is far: some triangle outside the band (see [`Tri4`]).
#[inline(always)]
fn fast_rows(tris: &[Option<Triangle>; 4]) -> ([[[f32; 4]; 3]; 4], bool) {
    let fast = transpose(&tris.map(|t| t.map_or([Vec3A::NAN; 4], |t| fast_terms(&t))));
    let mut corners = [0.0f32; 4];
    let mut used = 0u32;
    for (lane, t) in tris.iter().enumerate() {
        if let Some(t) = t {
            used |= 1 << lane;
            let [a, b, c] = t.v.map(Vec3A::abs);
            corners[lane] = a.max(b).max(c).max_element();
        }
    }
    let far = out_of_band(Vec4::from_array(corners), [&fast[1], &fast[2], &fast[3]]) & used != 0;
    (fast, far)
}

/// Writes the rows of one group from its lanes' triangles (`None`: an unused lane or a
/// primitive without a triangle, never hit) as `format` stores them; a far group when any
/// triangle is outside the band (see [`Tri4`]). The ids are the caller's. What packing and
/// refitting both write; returns whether the group is far.
pub(crate) fn fill(g: &mut Tri4, tris: &[Option<Triangle>; 4], format: LeafFormat) -> bool {
    let (fast, far) = fast_rows(tris);
    g.rows = match format {
        LeafFormat::FastTriangles if !far => [fast[0], fast[1], fast[2]],
        LeafFormat::FastTriangles | LeafFormat::WatertightTriangles => {
            transpose(&tris.map(|t| t.map_or([Vec3A::NAN; 3], |t| t.v)))
        }
        LeafFormat::Plain => unreachable!("plain leaves are not packed"),
    };
    far
}

/// How many leaf positions ahead packing prefetches its primitives: enough loads in flight
/// to hide most of a gather's latency.
const PREFETCH: usize = 16;

/// Writes the groups of the leaf over leaf positions `range` (`ids`: every position's input
/// index) in `format` to `out`, which holds exactly `groups(range.len())` of them, the first
/// being group `base`; adds those stored far to `far`.
fn pack<P: Primitive>(
    prims: &LeafPrims<P>,
    ids: &[u32],
    range: std::ops::Range<usize>,
    format: LeafFormat,
    (base, out): (u32, &mut [Tri4]),
    far: &mut Vec<u32>,
) {
    for ((start, g), i) in range.clone().step_by(4).zip(out).zip(base..) {
        let four = start..(start + 4).min(range.end);
        g.id = [u32::MAX; 4];
        g.id[..four.len()].copy_from_slice(&ids[four.clone()]);
        let mut tris = [None; 4];
        for (t, j) in tris.iter_mut().zip(four) {
            prims.prefetch(ids, j + PREFETCH);
            *t = prims.at(ids, j).triangle();
        }
        if fill(g, &tris, format) {
            far.push(i);
        }
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
/// nodes, then filled by all threads, each leaf into its own range. Also returns the groups
/// stored far (see [`Tri4`]).
pub(crate) fn pack_leaves<P: Primitive, const W: usize>(
    wide: &mut [Wide<W>],
    prims: &LeafPrims<P>,
    ids: &[u32],
) -> (Vec<Tri4>, FarGroups) {
    use rayon::prelude::*;
    if P::LEAF_FORMAT == LeafFormat::Plain {
        return (Vec::new(), FarGroups::default());
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
    let mut out: Vec<Tri4> = crate::mem::zeroed_vec(total as usize);
    let mut rest = &mut out[..];
    let mut jobs = Vec::with_capacity(leaves.len());
    let mut base = 0u32;
    for (first, count) in leaves {
        let n = groups(count as u32);
        let (mine, tail) = std::mem::take(&mut rest).split_at_mut(n as usize);
        rest = tail;
        jobs.push((first..first + count, (base, mine)));
        base += n;
    }
    let mut far: Vec<u32> = jobs
        .into_par_iter()
        .with_min_len(256)
        .fold(Vec::new, |mut far, (range, out)| {
            pack(prims, ids, range, P::LEAF_FORMAT, out, &mut far);
            far
        })
        .reduce(Vec::new, |mut a, mut b| {
            a.append(&mut b);
            a
        });
    far.sort_unstable();
    (out, FarGroups(far))
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
}
