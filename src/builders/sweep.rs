//! Full-sweep SAH: on each axis the primitives are sorted by centroid and every plane between
//! two distinct centroids is evaluated exactly. O(n log² n) overall; the quality reference the
//! binned builder is measured against.

use super::recurse::{build_tree, refs_bounds, sort_on, take_split, Ctx, Partition, Ref, Splitter};
use super::{model_score, BuildConfig, BuildNode, Side};
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
        refs: &mut [Ref],
        scratch: &mut [Ref],
        node: &Aabb,
        _: &Aabb,
    ) -> Option<Partition> {
        let n = refs.len();
        let mut right_area = vec![0f32; n];
        // The cost models other than the SAH also need each right side's box and primitive
        // area on their own.
        let mut right_side = vec![(0f32, 0f32); if ctx.areas.is_some() { n } else { 0 }];
        // (score, axis, left count, weighted cost for the leaf test)
        let mut best: Option<(f32, usize, usize, f32)> = None;
        for axis in 0..3 {
            scratch.copy_from_slice(refs);
            sort_on(scratch, axis);
            let key = |j: usize| scratch[j].center()[axis];
            let mut acc = Aabb::EMPTY;
            let mut acc_area = 0f32;
            for j in (1..n).rev() {
                acc = acc.union(&scratch[j].bounds());
                right_area[j] = acc.half_area() * ctx.config.tests(n - j);
                if let Some(areas) = ctx.areas {
                    acc_area += areas[scratch[j].id() as usize];
                    right_side[j] = (acc.half_area(), acc_area);
                }
            }
            let mut left = Aabb::EMPTY;
            let mut left_area = 0f32;
            for j in 1..n {
                left = left.union(&scratch[j - 1].bounds());
                if let Some(areas) = ctx.areas {
                    left_area += areas[scratch[j - 1].id() as usize];
                }
                // Only a plane between two distinct centroids is a real split.
                if key(j - 1) == key(j) {
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
                    let w = left.half_area() * ctx.config.tests(j) + right_area[j];
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
        sort_on(refs, axis);
        Some(Partition {
            left_len: nl,
            left: refs_bounds(&refs[..nl]),
            right: refs_bounds(&refs[nl..]),
            moved: false,
        })
    }
}
