//! Full-sweep SAH: on each axis the primitives are sorted by centroid and every plane between
//! two distinct centroids is evaluated exactly. O(n log² n) overall; the quality reference the
//! binned builder is measured against.

use super::recurse::{build_tree, take_split, Ctx, Partition, Splitter};
use super::{bounds_of, BuildConfig, BuildNode};
use crate::geometry::Aabb;

pub(super) fn build(
    bounds: &[Aabb],
    idx: Vec<u32>,
    config: &BuildConfig,
) -> (Vec<BuildNode>, Vec<u32>) {
    build_tree(&Sweep, bounds, idx, config)
}

struct Sweep;

impl Splitter for Sweep {
    fn split(
        &self,
        ctx: &Ctx,
        idx: &mut [u32],
        scratch: &mut [u32],
        node: &Aabb,
        _: &Aabb,
    ) -> Option<Partition> {
        let n = idx.len();
        let mut right_area = vec![0f32; n];
        // (weighted cost, axis, left count)
        let mut best: Option<(f32, usize, usize)> = None;
        for axis in 0..3 {
            let key = |i: u32| ctx.centroids[i as usize][axis];
            scratch.copy_from_slice(idx);
            scratch.sort_unstable_by(|&a, &b| key(a).total_cmp(&key(b)).then(a.cmp(&b)));
            let mut acc = Aabb::EMPTY;
            for j in (1..n).rev() {
                acc = acc.union(&ctx.bounds[scratch[j] as usize]);
                right_area[j] = acc.half_area() * (n - j) as f32;
            }
            let mut left = Aabb::EMPTY;
            for j in 1..n {
                left = left.union(&ctx.bounds[scratch[j - 1] as usize]);
                // Only a plane between two distinct centroids is a real split.
                if key(scratch[j - 1]) == key(scratch[j]) {
                    continue;
                }
                let w = left.half_area() * j as f32 + right_area[j];
                if best.is_none_or(|(bw, _, _)| w < bw) {
                    best = Some((w, axis, j));
                }
            }
        }
        let (weighted, axis, nl) = best?;
        if !take_split(ctx.config, node.half_area(), weighted, n) {
            return None;
        }
        let key = |i: u32| ctx.centroids[i as usize][axis];
        idx.sort_unstable_by(|&a, &b| key(a).total_cmp(&key(b)).then(a.cmp(&b)));
        Some(Partition {
            left_len: nl,
            left: bounds_of(ctx.bounds, &idx[..nl]),
            right: bounds_of(ctx.bounds, &idx[nl..]),
        })
    }
}
