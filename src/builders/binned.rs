//! Binned SAH (Wald 2007): centroids are projected into `K` bins per axis; a sweep over the
//! bins finds the cheapest plane. Nodes above [`BuildConfig::horizontal_threshold`] are binned
//! by all threads at once (private bins merged by an exact reduction).

use super::recurse::{
    build_tree, par_partition_into, partition_into, take_split, Ctx, Partition, Ref, Splitter,
    CHUNK,
};
use super::{model_score, split_beats_leaf, BuildConfig, BuildNode, Side};
use crate::geometry::Aabb;
use glam::{UVec3, Vec3A};
use rayon::prelude::*;

pub(super) fn build(
    bounds: &[Aabb],
    areas: Option<&[f32]>,
    idx: Vec<u32>,
    config: &BuildConfig,
) -> (Vec<BuildNode>, Vec<u32>) {
    build_tree(&Binned, bounds, areas, idx, config)
}

pub(crate) struct Binned;

/// Primitive bounds and count of one bin (or of a run of bins). Children's centroid bounds
/// are gathered later, by the partition, so binning touches one box per primitive and axis.
#[derive(Clone, Copy)]
struct Bin {
    bounds: Aabb,
    count: u32,
}

impl Bin {
    const EMPTY: Bin = Bin {
        bounds: Aabb::EMPTY,
        count: 0,
    };

    fn merge(&self, o: &Bin) -> Bin {
        Bin {
            bounds: self.bounds.union(&o.bounds),
            count: self.count + o.count,
        }
    }
}

/// Maps a centroid to its bin on each axis.
struct Mapper {
    origin: Vec3A,
    scale: Vec3A,
    last: UVec3,
    /// `last` as floats, the clamp before the truncation.
    top: Vec3A,
}

impl Mapper {
    fn new(centroids: &Aabb, bins: usize) -> Self {
        let e = centroids.extent();
        // The factor just below `bins` keeps the maximum centroid inside the last bin.
        let k = bins as f32 * (1.0 - 1e-6);
        let scale = Vec3A::select(e.cmpgt(Vec3A::ZERO), Vec3A::splat(k) / e, Vec3A::ZERO);
        Mapper {
            origin: centroids.min,
            scale,
            last: UVec3::splat(bins as u32 - 1),
            top: Vec3A::splat((bins - 1) as f32),
        }
    }

    /// The bin on all three axes at once. The position is clamped to `0..=last` in floats
    /// (`max` maps NaN, from 0 · inf on a tiny extent, to 0), so truncating it is exact: the
    /// bin a saturating cast and a clamp to `last` would give.
    #[inline(always)]
    fn bins(&self, c: Vec3A) -> UVec3 {
        truncate(
            ((c - self.origin) * self.scale)
                .max(Vec3A::ZERO)
                .min(self.top),
        )
    }

    /// Whether `bins(c)[axis] < bin` for a split bin `1 <= bin <= last`, without the cast:
    /// truncating a non-negative `f` gives less than an integer `bin` exactly when `f < bin`,
    /// negative `f` and NaN go to bin 0, and the clamp to `last` cannot cross `bin`.
    #[inline(always)]
    #[allow(clippy::neg_cmp_op_on_partial_ord)] // NaN (0 · inf on a tiny extent) must go left
    fn left_of(&self, c: Vec3A, axis: usize, bin: f32) -> bool {
        let f = (c[axis] - self.origin[axis]) * self.scale[axis];
        !(f >= bin)
    }
}

/// Bins `refs` into `bins` (three rows of `k`, one per axis).
/// Truncates three floats in `0..=1024` to integers, four lanes in one instruction.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn truncate(f: Vec3A) -> UVec3 {
    let lanes: wide::f32x4 = bytemuck::cast(std::arch::x86_64::__m128::from(f));
    let i = lanes.fast_trunc_int().to_array();
    UVec3::new(i[0] as u32, i[1] as u32, i[2] as u32)
}

#[cfg(not(target_arch = "x86_64"))]
#[inline(always)]
fn truncate(f: Vec3A) -> UVec3 {
    f.as_uvec3()
}

/// Bins `refs` into `bins` (three rows of `k`, one per axis). Returns which bins are
/// occupied on each axis as bit masks (bin `j` is bit `j`; only meaningful for `k <= 64`).
///
/// Neighbouring references mostly fall into the same bins, so binning them one after the
/// other makes each bin update wait for the last one's store. Large runs therefore alternate
/// between two sets of bins, merged at the end: two independent chains, and the same bins
/// (unions and counts do not depend on the order).
fn bin_prims(refs: &[Ref], map: &Mapper, bins: &mut [Bin]) -> [u64; 3] {
    let k = map.last.x as usize + 1;
    if refs.len() < PAIRED_BINNING || k > STACK_BINS {
        return bin_into(refs.iter(), map, bins, k);
    }
    let mut odd = [Bin::EMPTY; 3 * STACK_BINS];
    let odd = &mut odd[..3 * k];
    let mut occupied = bin_into(refs.iter().step_by(2), map, bins, k);
    let o = bin_into(refs.iter().skip(1).step_by(2), map, odd, k);
    for (a, b) in bins.iter_mut().zip(odd.iter()) {
        *a = a.merge(b);
    }
    (0..3).for_each(|a| occupied[a] |= o[a]);
    occupied
}

/// References from which [`bin_prims`] bins with two sets.
const PAIRED_BINNING: usize = 64;

/// Bins every reference of `refs` into `bins` (three rows of `k`).
#[inline(always)]
fn bin_into<'a>(
    refs: impl Iterator<Item = &'a Ref>,
    map: &Mapper,
    bins: &mut [Bin],
    k: usize,
) -> [u64; 3] {
    let (x, rest) = bins.split_at_mut(k);
    let (y, z) = rest.split_at_mut(k);
    let mut occupied = [0u64; 3];
    for r in refs {
        let b = r.bounds();
        let at = map.bins(r.center());
        for (a, (row, j)) in [(&mut *x, at.x), (&mut *y, at.y), (&mut *z, at.z)]
            .into_iter()
            .enumerate()
        {
            let bin = &mut row[j as usize];
            bin.bounds = bin.bounds.union(&b);
            bin.count += 1;
            occupied[a] |= 1 << (j & 63);
        }
    }
    occupied
}

/// Bins per axis up to which a node's bins live on the stack (the default is 16).
const STACK_BINS: usize = 16;

/// The cheapest plane: axis, first bin of the right side, and Σ area·tests of both sides
/// ([`BuildConfig::tests`]).
struct Plane {
    axis: usize,
    bin: usize,
    weighted: f32,
}

///
/// Only the planes just right of a non-empty bin are scored: a plane right of an empty bin
/// splits the primitives exactly as the plane one bin to its left does, so its cost is that
/// plane's and it could never win (ties go to the first plane). Small nodes, most of whose
/// bins are empty, are the bulk of a build, and this makes their sweep cost their primitive
/// count instead of the bin count.
fn best_plane(
    config: &BuildConfig,
    bins: &[Bin],
    occupied: [u64; 3],
    k: usize,
    map: &Mapper,
) -> Option<Plane> {
    // Zeroing sweep buffers for 1024 bins cost more than the whole sweep of a small node.
    if k <= STACK_BINS {
        let (mut cost, mut used) = ([0.0; STACK_BINS], [0; STACK_BINS]);
        best_plane_in(config, bins, occupied, k, map, &mut cost, &mut used)
    } else {
        let (mut cost, mut used) = (vec![0.0; k], vec![0; k]);
        best_plane_in(config, bins, occupied, k, map, &mut cost, &mut used)
    }
}

/// [`best_plane`] with buffers of at least `k` entries.
fn best_plane_in(
    config: &BuildConfig,
    bins: &[Bin],
    occupied: [u64; 3],
    k: usize,
    map: &Mapper,
    right_cost: &mut [f32],
    used: &mut [u16],
) -> Option<Plane> {
    let mut best: Option<Plane> = None;
    for axis in 0..3 {
        if map.scale[axis] == 0.0 {
            continue;
        }
        let bins = &bins[axis * k..(axis + 1) * k];
        let mut m = 0;
        if k <= 64 {
            let mut bits = occupied[axis];
            while bits != 0 {
                used[m] = bits.trailing_zeros() as u16;
                m += 1;
                bits &= bits - 1;
            }
        } else {
            for (b, bin) in bins.iter().enumerate() {
                used[m] = b as u16;
                m += (bin.count > 0) as usize;
            }
        }
        let used = &used[..m];
        let mut acc = Bin::EMPTY;
        for j in (1..m).rev() {
            acc = acc.merge(&bins[used[j] as usize]);
            right_cost[j] = acc.bounds.half_area() * config.tests(acc.count as usize);
        }
        let mut left = Bin::EMPTY;
        for j in 1..m {
            left = left.merge(&bins[used[j - 1] as usize]);
            let w = left.bounds.half_area() * config.tests(left.count as usize) + right_cost[j];
            if best.as_ref().is_none_or(|p| w < p.weighted) {
                best = Some(Plane {
                    axis,
                    bin: used[j - 1] as usize + 1,
                    weighted: w,
                });
            }
        }
    }
    best
}

/// Σ surface area of the primitives in each bin, per axis (for the cost models other than the
/// SAH). Large nodes are summed chunk by chunk in parallel and the chunks' sums added in chunk
/// order, so the float sums, and the tree, do not depend on the number of threads.
fn bin_areas(areas: &[f32], refs: &[Ref], map: &Mapper, horizontal: bool) -> Vec<f32> {
    let k = map.last.x as usize + 1;
    let one = |ch: &[Ref]| {
        let mut sums = vec![0f32; 3 * k];
        for r in ch {
            let at = map.bins(r.center());
            let a = areas[r.id() as usize];
            sums[at.x as usize] += a;
            sums[k + at.y as usize] += a;
            sums[2 * k + at.z as usize] += a;
        }
        sums
    };
    if !horizontal {
        return one(refs);
    }
    let parts: Vec<Vec<f32>> = refs.par_chunks(CHUNK).map(one).collect();
    parts.into_iter().fold(vec![0f32; 3 * k], |mut acc, p| {
        acc.iter_mut().zip(&p).for_each(|(a, b)| *a += b);
        acc
    })
}

/// [`best_plane`] under the configured cost model: the lowest score, with the weighted child
/// cost the leaf test reads.
fn best_plane_model(
    config: &BuildConfig,
    bins: &[Bin],
    areas: &[f32],
    k: usize,
    map: &Mapper,
    parent_area: f32,
) -> Option<Plane> {
    let mut best: Option<(f32, Plane)> = None;
    let mut right = vec![(Bin::EMPTY, 0f32); k];
    for axis in 0..3 {
        if map.scale[axis] == 0.0 {
            continue;
        }
        let bins = &bins[axis * k..(axis + 1) * k];
        let areas = &areas[axis * k..(axis + 1) * k];
        let mut acc = (Bin::EMPTY, 0f32);
        for b in (1..k).rev() {
            acc = (acc.0.merge(&bins[b]), acc.1 + areas[b]);
            right[b] = acc;
        }
        let total = acc.0.count + bins[0].count;
        let mut left = (Bin::EMPTY, 0f32);
        for b in 1..k {
            left = (left.0.merge(&bins[b - 1]), left.1 + areas[b - 1]);
            if left.0.count == 0 || left.0.count == total {
                continue;
            }
            let side = |(bin, a): (Bin, f32)| Side {
                half_area: bin.bounds.half_area(),
                count: bin.count as usize,
                prim_area: a,
            };
            let (score, weighted) = model_score(config, parent_area, &side(left), &side(right[b]));
            if best.as_ref().is_none_or(|(s, _)| score < *s) {
                best = Some((
                    score,
                    Plane {
                        axis,
                        bin: b,
                        weighted,
                    },
                ));
            }
        }
    }
    best.map(|(_, p)| p)
}

/// True when no plane can split `refs` more cheaply than a leaf under the SAH, so that
/// binning them would end in a leaf anyway: most of a build's nodes are a few primitives of a
/// dense mesh, and this leaves their bins untouched.
///
/// Each side of a split holds at least one primitive, and its box contains that primitive's
/// box, so any plane's weighted cost is at least `tests(1)` times the sum of the largest and
/// the smallest primitive's half area. Every step of the sweep's cost (`half_area`, the
/// products, the sum, the split cost) rounds monotonically, so the rounded bound is below
/// every rounded plane cost, and a bound that does not beat the leaf means no plane does: the
/// tree is the one the full sweep builds.
fn leaf_must_win(config: &BuildConfig, node: &Aabb, refs: &[Ref]) -> bool {
    let n = refs.len();
    if n > config.max_leaf_size {
        return false;
    }
    let (mut lo, mut hi) = (f32::INFINITY, 0f32);
    for r in refs {
        let a = r.bounds().half_area();
        (lo, hi) = (lo.min(a), hi.max(a));
    }
    let one = config.tests(1);
    !split_beats_leaf(config, node.half_area(), hi * one + lo * one, n)
}

impl Splitter for Binned {
    fn split(
        &self,
        ctx: &Ctx,
        refs: &mut [Ref],
        spare: &mut [Ref],
        node: &Aabb,
        centroids: &Aabb,
    ) -> Option<Partition> {
        if ctx.areas.is_none() && leaf_must_win(ctx.config, node, refs) {
            return None;
        }
        let k = ctx.config.bins;
        let map = Mapper::new(centroids, k);
        let horizontal = refs.len() >= ctx.config.horizontal_threshold;
        // Large nodes keep each chunk's bins: their counts give every chunk its share of
        // the partition's output without a counting pass.
        let mut chunks: Vec<Vec<Bin>> = Vec::new();
        let mut stack = [Bin::EMPTY; 3 * STACK_BINS];
        let mut heap: Vec<Bin>;
        let mut occupied = [0u64; 3];
        let bins: &[Bin] = if horizontal {
            let parts: Vec<(Vec<Bin>, [u64; 3])> = refs
                .par_chunks(CHUNK)
                .map(|ch| {
                    let mut b = vec![Bin::EMPTY; 3 * k];
                    let o = bin_prims(ch, &map, &mut b);
                    (b, o)
                })
                .collect();
            heap = vec![Bin::EMPTY; 3 * k];
            for (c, o) in parts {
                heap.iter_mut().zip(&c).for_each(|(a, b)| *a = a.merge(b));
                (0..3).for_each(|a| occupied[a] |= o[a]);
                chunks.push(c);
            }
            &heap
        } else if k <= STACK_BINS {
            occupied = bin_prims(refs, &map, &mut stack[..3 * k]);
            &stack[..3 * k]
        } else {
            heap = vec![Bin::EMPTY; 3 * k];
            occupied = bin_prims(refs, &map, &mut heap);
            &heap
        };
        let plane = match ctx.areas {
            None => best_plane(ctx.config, bins, occupied, k, &map)?,
            Some(areas) => {
                let sums = bin_areas(areas, refs, &map, horizontal);
                best_plane_model(ctx.config, bins, &sums, k, &map, node.half_area())?
            }
        };
        if !take_split(ctx.config, node.half_area(), plane.weighted, refs.len()) {
            return None;
        }
        let side = |r: &[Bin]| r.iter().fold(Bin::EMPTY, |a, b| a.merge(b));
        let (lo, mid, hi) = (
            plane.axis * k,
            plane.axis * k + plane.bin,
            (plane.axis + 1) * k,
        );
        let (l, r) = (side(&bins[lo..mid]), side(&bins[mid..hi]));
        let (axis, bin) = (plane.axis, plane.bin as f32);
        let goes_left = |c| map.left_of(c, axis, bin);
        let (cl, cr) = if horizontal {
            let counts: Vec<usize> = chunks
                .iter()
                .map(|c| c[lo..mid].iter().map(|b| b.count as usize).sum())
                .collect();
            par_partition_into(refs, spare, &counts, goes_left)
        } else {
            partition_into(refs, spare, l.count as usize, goes_left)
        };
        Some(Partition {
            left_len: l.count as usize,
            left: (l.bounds, cl),
            right: (r.bounds, cr),
            moved: true,
        })
    }
}
