//! Single-ray traversal of a [`Bvh2`] in any of its memory mappings.

use super::search::test_prims;
use super::stats::Stats;
use super::{Ask, BoxTest, Filter, RayQuery, SlabRay, Stack};
use crate::builders::MAX_DEPTH;
use crate::geometry::{Hit, Ray};
use crate::layout::bvh2::{compact_children, Addressing};
use crate::layout::{Bvh2, Bvh2Node};
use crate::primitive::Primitive;
use std::ops::Range;

/// The node's box as eight floats: min at 0..3, max at 4..7.
#[inline(always)]
fn planes(n: &Bvh2Node) -> &[f32; 8] {
    bytemuck::cast_ref(n)
}

/// How a kernel finds the children of inner node `i`; one kernel is compiled per rule.
trait Children {
    fn of(i: usize, n: &Bvh2Node) -> (usize, usize);
}

struct DepthFirst;
impl Children for DepthFirst {
    #[inline(always)]
    fn of(i: usize, n: &Bvh2Node) -> (usize, usize) {
        (i + 1, n.link as usize)
    }
}

struct Explicit;
impl Children for Explicit {
    #[inline(always)]
    fn of(_: usize, n: &Bvh2Node) -> (usize, usize) {
        (n.link as usize, n.count as usize)
    }
}

struct Compact;
impl Children for Compact {
    #[inline(always)]
    fn of(i: usize, n: &Bvh2Node) -> (usize, usize) {
        if n.count == 0 {
            compact_children(i, n.link)
        } else {
            (n.link as usize, n.count as usize)
        }
    }
}

/// Binary nodes have no packet kernel: packet queries go ray by ray.
impl<P: Primitive> RayQuery for Bvh2<P> {
    type Hit = Hit;

    fn trace_with<A: Ask, B: BoxTest, S: Stats, F: Filter<Hit>>(
        &self,
        ray: &Ray,
        stats: &mut S,
        filter: &mut F,
    ) -> A::Answer<Hit> {
        let ray = &ray.raised_t_min();
        let mut best = Hit::none(ray.t_max);
        traverse::<P, B, S, _>(self, ray, stats, |range, limit, stats| {
            let found = test_prims::<A, P, S, F>(
                &self.prims[range.clone()],
                &self.prim_ids[range],
                ray,
                &mut best,
                stats,
                filter,
            );
            if A::ANY {
                return found;
            }
            *limit = best.t;
            false
        });
        A::answer(best.found())
    }
}

/// The walk compiled for the BVH's child-addressing rule.
#[inline(always)]
fn traverse<P, B, S, F>(bvh: &Bvh2<P>, ray: &Ray, stats: &mut S, leaf: F)
where
    B: BoxTest,
    S: Stats,
    F: FnMut(Range<usize>, &mut f32, &mut S) -> bool,
{
    match bvh.mapping.addressing() {
        Addressing::DepthFirst => walk::<DepthFirst, B, S, F>(&bvh.nodes, ray, stats, leaf),
        Addressing::Explicit => walk::<Explicit, B, S, F>(&bvh.nodes, ray, stats, leaf),
        Addressing::Compact => walk::<Compact, B, S, F>(&bvh.nodes, ray, stats, leaf),
    }
}

/// Visits the leaves the ray may hit, nearer child first. `leaf(primitives, t_limit, stats)`
/// tests a leaf, may lower `t_limit` (boxes entered beyond it are skipped; a box entered
/// exactly at it is still visited, so ties are seen) and returns true to stop.
#[inline(always)]
fn walk<C, B, S, F>(nodes: &[Bvh2Node], ray: &Ray, stats: &mut S, mut leaf: F)
where
    C: Children,
    B: BoxTest,
    S: Stats,
    F: FnMut(Range<usize>, &mut f32, &mut S) -> bool,
{
    let sr = SlabRay::new(ray);
    let mut limit = ray.t_max;
    let mut stack: Stack<(u32, f32), { MAX_DEPTH + 1 }> = Stack::new();
    let mut node = 0usize;
    stats.boxes(1);
    if sr.enter::<B>(planes(&nodes[0]), limit * B::SLACK).is_none() {
        return;
    }
    loop {
        let n = &nodes[node];
        stats.node();
        if n.is_leaf() {
            let first = n.link as usize;
            stats.leaf();
            if leaf(first..first + n.prim_count() as usize, &mut limit, stats) {
                return;
            }
        } else {
            let (l, r) = C::of(node, n);
            let bound = limit * B::SLACK;
            stats.boxes(2);
            let tl = sr.enter::<B>(planes(&nodes[l]), bound);
            let tr = sr.enter::<B>(planes(&nodes[r]), bound);
            match (tl, tr) {
                (Some(a), Some(b)) => {
                    let (near, far, t_far) = if a <= b { (l, r, b) } else { (r, l, a) };
                    stack.push((far as u32, t_far));
                    node = near;
                    continue;
                }
                (Some(_), None) => {
                    node = l;
                    continue;
                }
                (None, Some(_)) => {
                    node = r;
                    continue;
                }
                (None, None) => {}
            }
        }
        // Pop the next box still worth entering.
        loop {
            let Some((i, t)) = stack.pop() else { return };
            if t <= limit * B::SLACK {
                node = i as usize;
                break;
            }
        }
    }
}
