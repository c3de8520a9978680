//! Parallel locally-ordered clustering (Meister and Bittner 2018). Primitives sorted along a
//! Morton curve start as one cluster each; every iteration each cluster finds its nearest
//! neighbour (smallest union box area) among the `radius` clusters either side of it in the
//! curve order, mutual nearest neighbours merge into the lower position, and the survivors
//! are compacted in order. All three phases run on all threads; the tree is then compacted
//! into SAH leaves ([`super::cluster`]).
//!
//! Ties between equal distances are broken by a total order on *pairs* (distance, gap in the
//! array, parity of the lower position, lower position), so the globally least pair is
//! always mutual (every iteration merges at least once) and a run of identical boxes merges
//! pairwise, halving each iteration instead of one pair at a time. Every choice is a function
//! of the array, so the tree is the same for any thread count.

use super::cluster::Links;
use super::morton::{sorted, Curve};
use super::{BuildConfig, BuildNode};
use crate::geometry::Aabb;
use rayon::prelude::*;

/// Below this many clusters an iteration runs on one thread.
const PARALLEL_MIN: usize = 4096;

pub(super) fn build(
    bounds: &[Aabb],
    idx: Vec<u32>,
    config: &BuildConfig,
    radius: usize,
    curve: Curve,
) -> (Vec<BuildNode>, Vec<u32>) {
    let (order, _) = sorted(bounds, &idx, curve);
    let mut links = Links::singletons(order, bounds);
    let n = links.units();
    let mut clusters: Vec<u32> = (0..n as u32).collect();
    let mut boxes: Vec<Aabb> = links.bounds.clone();
    while clusters.len() > 1 {
        let nn = neighbours(&boxes, radius);
        let parallel = clusters.len() >= PARALLEL_MIN;
        let mutual = |i: usize| nn[nn[i] as usize] as usize == i;
        let merges: Vec<usize> = if parallel {
            (0..clusters.len())
                .into_par_iter()
                .filter(|&i| mutual(i) && i < nn[i] as usize)
                .collect()
        } else {
            (0..clusters.len())
                .filter(|&i| mutual(i) && i < nn[i] as usize)
                .collect()
        };
        for &i in &merges {
            let j = nn[i] as usize;
            let id = links.join(clusters[i], clusters[j]);
            clusters[i] = id;
            boxes[i] = links.bounds[id as usize];
        }
        // The higher member of each merged pair is gone; keep the rest in order.
        let keep = |i: &usize| !(mutual(*i) && *i > nn[*i] as usize);
        let (c, b): (Vec<u32>, Vec<Aabb>) = if parallel {
            (0..clusters.len())
                .into_par_iter()
                .filter(keep)
                .map(|i| (clusters[i], boxes[i]))
                .unzip()
        } else {
            (0..clusters.len())
                .filter(keep)
                .map(|i| (clusters[i], boxes[i]))
                .unzip()
        };
        clusters = c;
        boxes = b;
    }
    links.root = clusters[0];
    links.into_build_tree(bounds, config)
}

/// Each cluster's nearest neighbour within `radius` positions.
fn neighbours(boxes: &[Aabb], radius: usize) -> Vec<u32> {
    let m = boxes.len();
    let best = |i: usize| {
        let lo = i.saturating_sub(radius);
        let hi = (i + radius + 1).min(m);
        let mut best: Option<((f32, usize, usize, usize), usize)> = None;
        for j in (lo..hi).filter(|&j| j != i) {
            let d = boxes[i].union(&boxes[j]).half_area();
            let low = i.min(j);
            let key = (d, i.abs_diff(j), low & 1, low);
            if best.is_none_or(|(k, _)| less(&key, &k)) {
                best = Some((key, j));
            }
        }
        best.map_or(i as u32, |(_, j)| j as u32)
    };
    if m >= PARALLEL_MIN {
        (0..m).into_par_iter().map(best).collect()
    } else {
        (0..m).map(best).collect()
    }
}

/// The pair order: distance by `total_cmp` (a NaN area from an overflowing box still has a
/// place), then the tie-breakers.
fn less(a: &(f32, usize, usize, usize), b: &(f32, usize, usize, usize)) -> bool {
    a.0.total_cmp(&b.0)
        .then((a.1, a.2, a.3).cmp(&(b.1, b.2, b.3)))
        .is_lt()
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3A;

    fn cube(x: f32) -> Aabb {
        Aabb::new(Vec3A::new(x, 0.0, 0.0), Vec3A::new(x + 1.0, 1.0, 1.0))
    }

    #[test]
    fn nearest_neighbour_is_the_smallest_union() {
        // Cubes at 0, 1.5, 10, 10.5: 0 and 1.5 pair up, 10 and 10.5 pair up.
        let boxes = [cube(0.0), cube(1.5), cube(10.0), cube(10.5)];
        assert_eq!(neighbours(&boxes, 3), vec![1, 0, 3, 2]);
        // With radius 1, box 1 sees only boxes 0 and 2.
        assert_eq!(neighbours(&boxes, 1), vec![1, 0, 3, 2]);
    }

    #[test]
    fn identical_boxes_pair_up_in_order() {
        let boxes = vec![cube(0.0); 6];
        assert_eq!(neighbours(&boxes, 2), vec![1, 0, 3, 2, 5, 4]);
    }
}
