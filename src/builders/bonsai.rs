//! Bonsai (Ganestam et al. 2015): primitives are cut by spatial-median planes into groups of
//! at most N, a full-sweep SAH *mini tree* is built over each group (in parallel), optionally
//! the mini trees are *pruned* — one whose root box is larger than T times the mean mini-tree
//! root area is replaced by its largest subtrees under that area — and a full-sweep *top
//! tree* over the mini-tree roots, weighing each by its primitive count, joins them. The
//! result is compacted into SAH leaves like the bottom-up builders' ([`super::cluster`]).
//!
//! Settings (the thesis's Table 3): Bonsai N = 512 without pruning; BonsaiP N = 512,
//! T = 0.1; BonsaiP* N = 4096, T = 0.01. Groups are cut and mini trees built as rayon tasks,
//! each a function of its own primitives, so the tree is the same for any thread count.

use super::cluster::Links;
use super::{bounds_of, sweep, widest_axis, BuildConfig, BuildNode, NodeKind, MEDIAN_DEPTH};
use crate::geometry::Aabb;
use rayon::prelude::*;

/// N and T of one Bonsai setting.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Setting {
    /// Largest group a mini tree is built over.
    pub group: usize,
    /// Pruning threshold relative to the mean mini-tree root area; `None`: no pruning.
    pub prune: Option<f32>,
}

/// Bonsai without pruning.
pub(crate) const PLAIN: Setting = Setting {
    group: 512,
    prune: None,
};

/// BonsaiP.
pub(crate) const PRUNED: Setting = Setting {
    group: 512,
    prune: Some(0.1),
};

/// BonsaiP*.
pub(crate) const PRUNED_4096: Setting = Setting {
    group: 4096,
    prune: Some(0.01),
};

pub(super) fn build(
    bounds: &[Aabb],
    mut idx: Vec<u32>,
    config: &BuildConfig,
    setting: Setting,
) -> (Vec<BuildNode>, Vec<u32>) {
    let mut groups = Vec::new();
    select(bounds, &mut idx, 0, setting.group, &mut groups);
    // Bonsai minimises the plain SAH (see `build_finite`).
    let sah = BuildConfig {
        cost_model: super::CostModel::Sah,
        ..config.clone()
    };
    // One mini tree per group, over the group's boxes renumbered from 0.
    let minis: Vec<(Vec<BuildNode>, Vec<u32>)> = groups
        .par_iter()
        .map(|&(lo, hi)| {
            let local: Vec<Aabb> = idx[lo..hi].iter().map(|&p| bounds[p as usize]).collect();
            let (nodes, order) =
                sweep::build(&local, None, (0..local.len() as u32).collect(), &sah);
            let prims = order.iter().map(|&k| idx[lo + k as usize]).collect();
            (nodes, prims)
        })
        .collect();
    let (mut links, mut roots) = stitch(&minis);
    if let Some(t) = setting.prune {
        roots = prune(&links, &roots, t);
    }
    links.root = top_tree(&mut links, &roots);
    links.into_build_tree(bounds, config)
}

/// Cuts `idx` into groups of at most `n` at the spatial median of the widest centroid axis
/// (the object median where every centroid is equal), appending `(start, end)` ranges in
/// order; `at` is where `idx` starts in the whole array.
fn select(bounds: &[Aabb], idx: &mut [u32], at: usize, n: usize, out: &mut Vec<(usize, usize)>) {
    if idx.len() <= n {
        out.push((at, at + idx.len()));
        return;
    }
    let (_, c) = bounds_of(bounds, idx);
    let axis = widest_axis(c.extent());
    let mid = (c.min[axis] + c.max[axis]) * 0.5;
    let (mut left, right): (Vec<u32>, Vec<u32>) = idx
        .iter()
        .partition(|&&p| bounds[p as usize].center()[axis] < mid);
    let nl = if left.is_empty() || right.is_empty() {
        idx.len() / 2
    } else {
        let nl = left.len();
        left.extend(right);
        idx.copy_from_slice(&left);
        nl
    };
    let (l, r) = idx.split_at_mut(nl);
    if l.len() + r.len() >= 4 * n {
        let (mut a, mut b) = (Vec::new(), Vec::new());
        rayon::join(
            || select(bounds, l, at, n, &mut a),
            || select(bounds, r, at + nl, n, &mut b),
        );
        out.extend(a);
        out.extend(b);
    } else {
        select(bounds, l, at, n, out);
        select(bounds, r, at + nl, n, out);
    }
}

/// All mini trees in one [`Links`] (units: their leaves) and each one's root.
fn stitch(minis: &[(Vec<BuildNode>, Vec<u32>)]) -> (Links, Vec<u32>) {
    let is_leaf = |n: &BuildNode| matches!(n.kind, NodeKind::Leaf { .. });
    let units: usize = minis
        .iter()
        .map(|(nodes, _)| nodes.iter().filter(|n| is_leaf(n)).count())
        .sum();
    let mut first = Vec::with_capacity(units + 1);
    let mut prims = Vec::new();
    let mut bounds = vec![Aabb::EMPTY; units];
    let mut children = Vec::new();
    let mut roots = Vec::with_capacity(minis.len());
    let (mut next_unit, mut next_inner) = (0u32, units as u32);
    for (nodes, order) in minis {
        // Units are numbered as met, inner nodes after all units, both in preorder.
        let id: Vec<u32> = nodes
            .iter()
            .map(|n| {
                let counter = if is_leaf(n) {
                    &mut next_unit
                } else {
                    &mut next_inner
                };
                *counter += 1;
                *counter - 1
            })
            .collect();
        for (n, &i) in nodes.iter().zip(&id) {
            match n.kind {
                NodeKind::Leaf { first: f, count } => {
                    bounds[i as usize] = n.bounds;
                    first.push(prims.len() as u32);
                    prims.extend_from_slice(&order[f as usize..(f + count) as usize]);
                }
                NodeKind::Inner { left, right } => {
                    bounds.push(n.bounds);
                    children.push([id[left as usize], id[right as usize]]);
                }
            }
        }
        roots.push(id[0]);
    }
    first.push(prims.len() as u32);
    let links = Links {
        first,
        prims,
        bounds,
        children,
        root: 0,
    };
    (links, roots)
}

/// Replaces every root whose box is larger than `t` times the mean root area by the largest
/// subtrees below it whose boxes are not (or its leaves).
fn prune(links: &Links, roots: &[u32], t: f32) -> Vec<u32> {
    let area = |x: u32| links.bounds[x as usize].half_area();
    let mean = roots.iter().map(|&r| area(r) as f64).sum::<f64>() / roots.len() as f64;
    let limit = t as f64 * mean;
    let units = links.units() as u32;
    let mut out = Vec::with_capacity(roots.len());
    for &r in roots {
        let mut stack = vec![r];
        while let Some(x) = stack.pop() {
            if x < units || area(x) as f64 <= limit {
                out.push(x);
            } else {
                let [a, b] = links.children[(x - units) as usize];
                stack.push(b);
                stack.push(a);
            }
        }
    }
    out
}

/// Joins `roots` by full-sweep SAH, each weighted by its primitive count, and returns the
/// top tree's root.
fn top_tree(links: &mut Links, roots: &[u32]) -> u32 {
    let weight: Vec<f32> = roots.iter().map(|&r| prim_count(links, r) as f32).collect();
    let mut items: Vec<usize> = (0..roots.len()).collect();
    top_node(links, roots, &weight, &mut items, 0)
}

fn prim_count(links: &Links, root: u32) -> usize {
    let units = links.units() as u32;
    let mut stack = vec![root];
    let mut n = 0;
    while let Some(x) = stack.pop() {
        if x < units {
            n += (links.first[x as usize + 1] - links.first[x as usize]) as usize;
        } else {
            stack.extend(links.children[(x - units) as usize]);
        }
    }
    n
}

fn top_node(
    links: &mut Links,
    roots: &[u32],
    weight: &[f32],
    items: &mut [usize],
    depth: usize,
) -> u32 {
    if items.len() == 1 {
        return roots[items[0]];
    }
    let boxes = |i: usize| links.bounds[roots[i] as usize];
    let key = |i: usize, axis: usize| boxes(i).center()[axis];
    let n = items.len();
    // (weighted cost, axis, left count); below MEDIAN_DEPTH the middle of the widest axis.
    let mut best: Option<(f32, usize, usize)> = None;
    if depth < MEDIAN_DEPTH {
        let mut right = vec![0f32; n];
        for axis in 0..3 {
            items.sort_unstable_by(|&a, &b| key(a, axis).total_cmp(&key(b, axis)).then(a.cmp(&b)));
            let (mut acc, mut w) = (Aabb::EMPTY, 0f32);
            for j in (1..n).rev() {
                acc = acc.union(&boxes(items[j]));
                w += weight[items[j]];
                right[j] = acc.half_area() * w;
            }
            let (mut acc, mut w) = (Aabb::EMPTY, 0f32);
            for j in 1..n {
                acc = acc.union(&boxes(items[j - 1]));
                w += weight[items[j - 1]];
                let cost = acc.half_area() * w + right[j];
                if best.is_none_or(|(c, _, _)| cost.total_cmp(&c).is_lt()) {
                    best = Some((cost, axis, j));
                }
            }
        }
    }
    let (axis, nl) = match best {
        Some((_, axis, nl)) => (axis, nl),
        None => {
            let c = items.iter().fold(Aabb::EMPTY, |mut c, &i| {
                c.grow(boxes(i).center());
                c
            });
            (widest_axis(c.extent()), n / 2)
        }
    };
    items.sort_unstable_by(|&a, &b| key(a, axis).total_cmp(&key(b, axis)).then(a.cmp(&b)));
    let (l, r) = items.split_at_mut(nl);
    let a = top_node(links, roots, weight, l, depth + 1);
    let b = top_node(links, roots, weight, r, depth + 1);
    links.join(a, b)
}
