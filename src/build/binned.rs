//! Binned SAH (Wald 2007): centroids are projected into `K` bins per axis; a sweep over the
//! bins finds the cheapest plane. Nodes above [`BuildConfig::horizontal_threshold`] are binned
//! by all threads at once (private bins merged by an exact reduction).

use super::recurse::{build_tree, stable_partition, take_split, Ctx, Partition, Splitter, CHUNK};
use super::{BuildConfig, BuildNode};
use crate::geometry::Aabb;
use glam::Vec3A;
use rayon::prelude::*;

pub(super) fn build(bounds: &[Aabb], idx: Vec<u32>, config: &BuildConfig) -> (Vec<BuildNode>, Vec<u32>) {
    build_tree(&Binned, bounds, idx, config)
}

struct Binned;

/// Primitive bounds, centroid bounds and count of one bin (or of a run of bins).
#[derive(Clone, Copy)]
struct Bin {
    bounds: Aabb,
    centroids: Aabb,
    count: u32,
}

impl Bin {
    const EMPTY: Bin = Bin {
        bounds: Aabb::EMPTY,
        centroids: Aabb::EMPTY,
        count: 0,
    };

    fn merge(&self, o: &Bin) -> Bin {
        Bin {
            bounds: self.bounds.union(&o.bounds),
            centroids: self.centroids.union(&o.centroids),
            count: self.count + o.count,
        }
    }
}

/// Maps a centroid to its bin on each axis.
struct Mapper {
    origin: Vec3A,
    scale: Vec3A,
    last: usize,
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
            last: bins - 1,
        }
    }

    #[inline(always)]
    fn bin(&self, c: Vec3A, axis: usize) -> usize {
        // `as usize` saturates (and maps NaN to 0), so every centroid lands in a valid bin.
        (((c[axis] - self.origin[axis]) * self.scale[axis]) as usize).min(self.last)
    }
}

fn bin_prims(ctx: &Ctx, idx: &[u32], map: &Mapper) -> Vec<Bin> {
    let k = map.last + 1;
    let mut bins = vec![Bin::EMPTY; 3 * k];
    for &i in idx {
        let c = ctx.centroids[i as usize];
        let b = ctx.bounds[i as usize];
        for axis in 0..3 {
            let bin = &mut bins[axis * k + map.bin(c, axis)];
            bin.bounds = bin.bounds.union(&b);
            bin.centroids.grow(c);
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
    let mut right_cost = vec![0f32; k];
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
        let mut left = Bin::EMPTY;
        let total: u32 = bins.iter().map(|b| b.count).sum();
        for b in 1..k {
            left = left.merge(&bins[b - 1]);
            if left.count == 0 || left.count == total {
                continue;
            }
            let w = left.bounds.half_area() * left.count as f32 + right_cost[b];
            if best.as_ref().is_none_or(|p| w < p.weighted) {
                best = Some(Plane { axis, bin: b, weighted: w });
            }
        }
    }
    best
}

impl Splitter for Binned {
    fn split(&self, ctx: &Ctx, idx: &mut [u32], scratch: &mut [u32], node: &Aabb, centroids: &Aabb) -> Option<Partition> {
        let k = ctx.config.bins;
        let map = Mapper::new(centroids, k);
        let horizontal = idx.len() >= ctx.config.horizontal_threshold;
        let bins = if horizontal {
            idx.par_chunks(CHUNK)
                .map(|ch| bin_prims(ctx, ch, &map))
                .reduce(|| vec![Bin::EMPTY; 3 * k], |a, b| a.iter().zip(&b).map(|(x, y)| x.merge(y)).collect())
        } else {
            bin_prims(ctx, idx, &map)
        };
        let plane = best_plane(&bins, k, &map)?;
        if !take_split(ctx.config, node.half_area(), plane.weighted, idx.len()) {
            return None;
        }
        let row = &bins[plane.axis * k..(plane.axis + 1) * k];
        let side = |r: &[Bin]| r.iter().fold(Bin::EMPTY, |a, b| a.merge(b));
        let (l, r) = (side(&row[..plane.bin]), side(&row[plane.bin..]));
        let cent = ctx.centroids;
        let nl = stable_partition(idx, scratch, horizontal, |i| {
            map.bin(cent[i as usize], plane.axis) < plane.bin
        });
        debug_assert_eq!(nl, l.count as usize);
        Some(Partition {
            left_len: nl,
            left: (l.bounds, l.centroids),
            right: (r.bounds, r.centroids),
        })
    }
}
