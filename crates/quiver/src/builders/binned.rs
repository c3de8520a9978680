//! Binned SAH (Wald 2007): centroids are projected into `K` bins per axis; a sweep over the
//! bins finds the cheapest plane. Nodes above [`BuildConfig::horizontal_threshold`] are binned
//! by all threads at once (private bins merged by an exact reduction).

use super::recurse::{build_tree, stable_partition, take_split, Ctx, Partition, Splitter, CHUNK};
use super::{model_score, BuildConfig, BuildNode, Side};
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

struct Binned;

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
        }
    }

    /// The bin on all three axes at once. The float-to-int cast saturates (and maps NaN to
    /// 0), so every centroid lands in a valid bin.
    #[inline(always)]
    fn bins(&self, c: Vec3A) -> UVec3 {
        ((c - self.origin) * self.scale).as_uvec3().min(self.last)
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

fn bin_prims(ctx: &Ctx, idx: &[u32], map: &Mapper) -> Vec<Bin> {
    let k = map.last.x as usize + 1;
    let mut bins = vec![Bin::EMPTY; 3 * k];
    let (x, rest) = bins.split_at_mut(k);
    let (y, z) = rest.split_at_mut(k);
    for &i in idx {
        let b = ctx.bounds[i as usize];
        let at = map.bins(ctx.centroids[i as usize]);
        for (row, j) in [(&mut *x, at.x), (&mut *y, at.y), (&mut *z, at.z)] {
            let bin = &mut row[j as usize];
            bin.bounds = bin.bounds.union(&b);
            bin.count += 1;
        }
    }
    bins
}

/// The cheapest plane: axis, first bin of the right side, and Σ area·count of both sides.
struct Plane {
    axis: usize,
    bin: usize,
    weighted: f32,
}

fn best_plane(bins: &[Bin], k: usize, map: &Mapper) -> Option<Plane> {
    let mut best: Option<Plane> = None;
    // Bin counts are small (the CLI caps them at 1024), so the sweep fits on the stack.
    let mut right_cost = [0f32; 1024];
    for axis in 0..3 {
        if map.scale[axis] == 0.0 {
            continue;
        }
        let bins = &bins[axis * k..(axis + 1) * k];
        let mut acc = Bin::EMPTY;
        for b in (1..k).rev() {
            acc = acc.merge(&bins[b]);
            right_cost[b] = acc.bounds.half_area() * acc.count as f32;
        }
        let total = acc.count + bins[0].count;
        let mut left = Bin::EMPTY;
        for b in 1..k {
            left = left.merge(&bins[b - 1]);
            if left.count == 0 || left.count == total {
                continue;
            }
            let w = left.bounds.half_area() * left.count as f32 + right_cost[b];
            if best.as_ref().is_none_or(|p| w < p.weighted) {
                best = Some(Plane {
                    axis,
                    bin: b,
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
fn bin_areas(ctx: &Ctx, areas: &[f32], idx: &[u32], map: &Mapper, horizontal: bool) -> Vec<f32> {
    let k = map.last.x as usize + 1;
    let one = |ch: &[u32]| {
        let mut sums = vec![0f32; 3 * k];
        for &i in ch {
            let at = map.bins(ctx.centroids[i as usize]);
            let a = areas[i as usize];
            sums[at.x as usize] += a;
            sums[k + at.y as usize] += a;
            sums[2 * k + at.z as usize] += a;
        }
        sums
    };
    if !horizontal {
        return one(idx);
    }
    let parts: Vec<Vec<f32>> = idx.par_chunks(CHUNK).map(one).collect();
    parts.into_iter().fold(vec![0f32; 3 * k], |mut acc, p| {
        acc.iter_mut().zip(&p).for_each(|(a, b)| *a += b);
        acc
    })
}

/// [`best_plane`] under the configured cost model: the lowest score, with the weighted child
/// cost the leaf test reads.
fn best_plane_model(
    ctx: &Ctx,
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
            let (score, weighted) =
                model_score(ctx.config, parent_area, &side(left), &side(right[b]));
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

impl Splitter for Binned {
    fn split(
        &self,
        ctx: &Ctx,
        idx: &mut [u32],
        scratch: &mut [u32],
        node: &Aabb,
        centroids: &Aabb,
    ) -> Option<Partition> {
        let k = ctx.config.bins;
        let map = Mapper::new(centroids, k);
        let horizontal = idx.len() >= ctx.config.horizontal_threshold;
        let bins = if horizontal {
            idx.par_chunks(CHUNK)
                .map(|ch| bin_prims(ctx, ch, &map))
                .reduce(
                    || vec![Bin::EMPTY; 3 * k],
                    |a, b| a.iter().zip(&b).map(|(x, y)| x.merge(y)).collect(),
                )
        } else {
            bin_prims(ctx, idx, &map)
        };
        let plane = match ctx.areas {
            None => best_plane(&bins, k, &map)?,
            Some(areas) => {
                let sums = bin_areas(ctx, areas, idx, &map, horizontal);
                best_plane_model(ctx, &bins, &sums, k, &map, node.half_area())?
            }
        };
        if !take_split(ctx.config, node.half_area(), plane.weighted, idx.len()) {
            return None;
        }
        let row = &bins[plane.axis * k..(plane.axis + 1) * k];
        let side = |r: &[Bin]| r.iter().fold(Bin::EMPTY, |a, b| a.merge(b));
        let (l, r) = (side(&row[..plane.bin]), side(&row[plane.bin..]));
        let (axis, bin) = (plane.axis, plane.bin as f32);
        let (nl, cl, cr) = stable_partition(idx, scratch, ctx.centroids, horizontal, |c| {
            map.left_of(c, axis, bin)
        });
        debug_assert_eq!(nl, l.count as usize);
        Some(Partition {
            left_len: nl,
            left: (l.bounds, cl),
            right: (r.bounds, cr),
        })
    }
}
