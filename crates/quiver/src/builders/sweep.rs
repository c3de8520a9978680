//! Full-sweep SAH: on each axis the primitives are sorted by centroid and every plane between
//! two distinct centroids is evaluated exactly. O(n log² n) overall; the quality reference the
//! binned builder is measured against.

use super::recurse::{build_tree, take_split, Ctx, Partition, Splitter};
use super::{bounds_of, model_score, BuildConfig, BuildNode, Side};
use crate::geometry::Aabb;

pub(super) fn build(
    bounds: &[Aabb],
    areas: Option<&[f32]>,
    idx: Vec<u32>,
    config: &BuildConfig,
) -> (Vec<BuildNode>, Vec<u32>) {
    build_tree(&Sweep, bounds, areas, idx, config)
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
        // The cost models other than the SAH also need each right side's box and primitive
        // area on their own.
        let mut right_side = vec![(0f32, 0f32); if ctx.areas.is_some() { n } else { 0 }];
        // (score, axis, left count, weighted cost for the leaf test)
        let mut best: Option<(f32, usize, usize, f32)> = None;
        for axis in 0..3 {
            let key = |i: u32| ctx.centroids[i as usize][axis];
            scratch.copy_from_slice(idx);
            scratch.sort_unstable_by(|&a, &b| key(a).total_cmp(&key(b)).then(a.cmp(&b)));
            let mut acc = Aabb::EMPTY;
            let mut acc_area = 0f32;
            for j in (1..n).rev() {
                acc = acc.union(&ctx.bounds[scratch[j] as usize]);
                right_area[j] = acc.half_area() * (n - j) as f32;
                if let Some(areas) = ctx.areas {
                    acc_area += areas[scratch[j] as usize];
                    right_side[j] = (acc.half_area(), acc_area);
                }
            }
            let mut left = Aabb::EMPTY;
            let mut left_area = 0f32;
            for j in 1..n {
                left = left.union(&ctx.bounds[scratch[j - 1] as usize]);
                if let Some(areas) = ctx.areas {
                    left_area += areas[scratch[j - 1] as usize];
                }
                // Only a plane between two distinct centroids is a real split.
                if key(scratch[j - 1]) == key(scratch[j]) {
                    continue;
                }
                let (score, w) = if ctx.areas.is_some() {
                    let l = Side {
                        half_area: left.half_area(),
                        count: j,
                        prim_area: left_area,
                    };
                    let r = Side {
                        half_area: right_side[j].0,
                        count: n - j,
                        prim_area: right_side[j].1,
                    };
                    model_score(ctx.config, node.half_area(), &l, &r)
                } else {
                    let w = left.half_area() * j as f32 + right_area[j];
                    (w, w)
                };
                if best.is_none_or(|(bs, _, _, _)| score < bs) {
                    best = Some((score, axis, j, w));
                }
            }
        }
        let (_, axis, nl, weighted) = best?;
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
