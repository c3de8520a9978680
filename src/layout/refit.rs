//! Refitting a laid-out BVH in place: the same tree and node order over primitives that moved.
//!
//! The primitives come from a [`Source`] by their input index. A layout with plain leaves
//! refreshes its leaf-order copy of the primitives; a wide layout over a triangle format,
//! which keeps no copy, repacks its SIMD triangle groups ([`Tri4`]) lane by lane straight from
//! the source (each lane names its input index); every layout recomputes every box bottom-up: a leaf's box is the
//! union of its primitives' boxes, an inner node's the union of its children's, exactly as a
//! fresh layout of the build tree over the new primitives computes them (unions are exact, so
//! the grouping does not matter). Quantized nodes are encoded again from the exact boxes.
//! Nothing is allocated beyond a few task records.
//!
//! Depth-first layouts (`bvh2-dfs`, `bvh4-dfs`, `bvh4-quant`, `bvh8-dfs`) keep every subtree
//! in one contiguous run of the node array, and its SIMD groups in one run of the group
//! array: the arrays split into disjoint slices per subtree, and subtrees are refit as
//! parallel tasks (safe code, `split_at_mut`). The other mappings scatter a subtree, so their
//! leaves are refit in parallel and their inner nodes by one bottom-up walk.

use super::bvh2::{compact_children, Addressing, Bvh2, Bvh2Mapping, Bvh2Node};
use super::bvh4::{Bvh4, Bvh4Mapping, Bvh4Node, Node4};
use super::bvh8::{Bvh8, Bvh8Node};
use super::collapse::{Child, Wide};
use super::tri4::{fill, groups as group_count, FarGroups, Tri4};
use crate::geometry::Aabb;
use crate::primitive::{LeafFormat, Primitive};
use rayon::prelude::*;
use std::sync::atomic::{AtomicBool, Ordering};

/// Where a refit takes its new primitives: by input index, in the layout's own frame.
pub(crate) trait Source<P>: Sync {
    /// Primitive `id` of the new input.
    fn get(&self, id: u32) -> P;

    /// Brings `p`, the layout's copy of primitive `id`, up to date.
    #[inline]
    fn refresh(&self, id: u32, p: &mut P) {
        *p = self.get(id);
    }

    /// Starts loading primitive `id`, where the source knows its address.
    #[inline]
    fn prefetch(&self, _id: u32) {}

    /// The box of `p`, the up-to-date primitive `id`: every leaf box a refit computes comes
    /// from here, so a source whose primitives keep no box of their own (the world's
    /// placed instances) can compute it from what it knows.
    #[inline]
    fn bounds(&self, _id: u32, p: &P) -> Aabb
    where
        P: Primitive,
    {
        p.bounds()
    }
}

/// A subtree of at most this many nodes is refit by one task, without further splitting.
const TASK_NODES: usize = 256;

/// Primitives per task when the leaf-order copy is refreshed.
const TASK_PRIMS: usize = 4096;

/// Refreshes the leaf-order copy: `prims[k]` is input primitive `ids[k]`.
fn refresh_prims<P: Primitive, S: Source<P>>(prims: &mut [P], ids: &[u32], src: &S) {
    prims
        .par_iter_mut()
        .zip(ids.par_iter())
        .with_min_len(TASK_PRIMS)
        .for_each(|(p, &id)| src.refresh(id, p));
}

/// How a refit reads its new primitives.
struct Ctx<'a, S> {
    src: &'a S,
    /// The leaf-order copy was refreshed beforehand (in parallel): leaves only read it.
    fresh: bool,
    /// Set once any group is repacked far ([`Tri4`]), so no pass over the groups must ask.
    far: &'a AtomicBool,
}

impl<'a, S> Ctx<'a, S> {
    /// `run` refreshed unless it already is, and the context that reads it as it is.
    fn fresh<P: Primitive>(cx: &Ctx<'a, S>, run: &mut Run<'_, P>) -> Ctx<'a, S>
    where
        S: Source<P>,
    {
        if !cx.fresh {
            for (p, &id) in run.prims.iter_mut().zip(run.ids) {
                cx.src.refresh(id, p);
            }
            if run.prims.len() != run.ids.len() {
                // No copy to refresh: the leaves read the source, so start every load now
                // (a task's primitives fit in L2; one by one, each read waited for memory).
                for &id in run.ids {
                    cx.src.prefetch(id);
                }
            }
        }
        Ctx {
            src: cx.src,
            fresh: true,
            far: cx.far,
        }
    }

    /// One leaf of input indices `ids`: the primitives of the leaf-order copy (`prims`)
    /// refreshed where the layout keeps one, else (a wide layout over a triangle format) its
    /// SIMD `groups` repacked straight from the source; and its box, the union of the
    /// primitives'.
    #[inline]
    fn leaf<P: Primitive>(&self, prims: &mut [P], ids: &[u32], groups: &mut [Tri4]) -> Aabb
    where
        S: Source<P>,
    {
        let mut b = Aabb::EMPTY;
        if prims.len() != ids.len() {
            for (g, four) in groups.iter_mut().zip(ids.chunks(4)) {
                let mut tris = [None; 4];
                for (t, &id) in tris.iter_mut().zip(four) {
                    let p = self.src.get(id);
                    b = b.union(&self.src.bounds(id, &p));
                    *t = p.triangle();
                }
                if fill(g, &tris, P::LEAF_FORMAT) {
                    self.far.store(true, Ordering::Relaxed);
                }
            }
            return b;
        }
        for (p, &id) in prims.iter_mut().zip(ids) {
            if !self.fresh {
                self.src.refresh(id, p);
            }
            b = b.union(&self.src.bounds(id, p));
        }
        b
    }
}

/// The SIMD groups of a leaf slot (`first`, `count`) in `groups`, which start at group
/// `gbase`; none for plain leaves (whose `first` is a primitive) and for empty slots.
#[inline]
fn leaf_groups<P: Primitive>(
    groups: &mut [Tri4],
    gbase: usize,
    first: u32,
    count: u32,
) -> &mut [Tri4] {
    if P::LEAF_FORMAT == LeafFormat::Plain || count == 0 {
        return &mut [];
    }
    let at = first as usize - gbase;
    &mut groups[at..at + group_count(count) as usize]
}

/// One slot of a wide node.
#[derive(Clone, Copy, Debug)]
enum Slot {
    /// An inner child at this node position.
    Inner(u32),
    /// A leaf (or, with `count` 0, an unused slot).
    Leaf { first: u32, count: u32 },
}

/// A wide node format as the refit reads and rewrites it.
trait WideNode<const W: usize>: Send + Sync {
    /// The node's slots.
    fn slots(&self) -> [Slot; W];
    /// The primitives in the node's leaf slots.
    fn leaf_prims(&self) -> usize {
        self.slots()
            .iter()
            .map(|s| match *s {
                Slot::Leaf { count, .. } => count as usize,
                Slot::Inner(_) => 0,
            })
            .sum()
    }
    /// Rewrites the node's boxes (its links stay as they are).
    fn set(&mut self, boxes: &[Aabb; W], slots: &[Slot; W]);
}

impl WideNode<8> for Bvh8Node {
    #[inline]
    fn slots(&self) -> [Slot; 8] {
        std::array::from_fn(|i| match self.count[i] {
            0 => Slot::Inner(self.child[i]),
            c => Slot::Leaf {
                first: self.child[i],
                count: c & !Bvh8Node::LEAF,
            },
        })
    }

    #[inline]
    fn leaf_prims(&self) -> usize {
        // Inner children count 0; leaves and unused slots carry the flag.
        self.count
            .iter()
            .map(|&c| (c & !Bvh8Node::LEAF) as usize)
            .sum()
    }

    #[inline]
    fn set(&mut self, boxes: &[Aabb; 8], _: &[Slot; 8]) {
        for (i, b) in boxes.iter().enumerate() {
            for a in 0..3 {
                self.planes[a][i] = b.min[a];
                self.planes[3 + a][i] = b.max[a];
            }
        }
    }
}

impl<N: Node4> WideNode<4> for N {
    #[inline]
    fn slots(&self) -> [Slot; 4] {
        std::array::from_fn(|i| match self.child(i) {
            (c, 0) => Slot::Inner(c),
            (first, c) => Slot::Leaf {
                first,
                count: c & !Bvh4Node::LEAF,
            },
        })
    }

    /// Encodes the node again from its exact boxes (a quantized node's frame and planes
    /// follow its boxes), as the layout encoded it.
    fn set(&mut self, boxes: &[Aabb; 4], slots: &[Slot; 4]) {
        let mut w = Wide::<4>::EMPTY;
        // Inner child `i` names entry `i` of `pos`, which holds its node position.
        let mut pos = [0u32; 4];
        for (i, s) in slots.iter().enumerate() {
            w.boxes[i] = boxes[i];
            w.kids[i] = match *s {
                Slot::Inner(c) => {
                    pos[i] = c;
                    Child::Inner(i as u32)
                }
                Slot::Leaf { first, count } => Child::Leaf { first, count },
            };
        }
        *self = N::encode(&w, &pos);
    }
}

fn union_all(boxes: &[Aabb]) -> Aabb {
    boxes.iter().fold(Aabb::EMPTY, |a, b| a.union(b))
}

/// The leaf-order primitives of a subtree (from position `at` of the whole copy) and their
/// input indices: a leaf takes the next `count` of them.
struct Run<'a, P> {
    prims: &'a mut [P],
    ids: &'a [u32],
}

impl<'a, P> Run<'a, P> {
    /// The first `count` primitives, for a leaf or a subtree; the rest stay. A wide layout
    /// over a triangle format keeps no leaf-order copy (`tri4::plain_only`): its run holds
    /// ids only, and only they split.
    fn take(&mut self, count: usize) -> Run<'a, P> {
        let copy = if self.prims.len() == self.ids.len() {
            count
        } else {
            0
        };
        let (prims, rest) = std::mem::take(&mut self.prims).split_at_mut(copy);
        let (ids, rest_ids) = self.ids.split_at(count);
        (self.prims, self.ids) = (rest, rest_ids);
        Run { prims, ids }
    }
}

/// Refits the subtree at node position `at`, one node after another, in any mapping: `nodes`
/// holds the node positions from `base` on, `groups` the groups from `gbase` on, `run` the
/// subtree's primitives (and those after it), which the leaves take in slot order: leaf order.
#[allow(clippy::too_many_arguments)]
fn wide_seq<const W: usize, N: WideNode<W>, P: Primitive, S: Source<P>>(
    nodes: &mut [N],
    base: usize,
    groups: &mut [Tri4],
    gbase: usize,
    run: &mut Run<'_, P>,
    at: usize,
    cx: &Ctx<'_, S>,
) -> Aabb {
    let slots = nodes[at - base].slots();
    let mut boxes = [Aabb::EMPTY; W];
    for (b, s) in boxes.iter_mut().zip(&slots) {
        *b = match *s {
            Slot::Inner(c) => wide_seq(nodes, base, groups, gbase, run, c as usize, cx),
            Slot::Leaf { first, count } => {
                let leaf = run.take(count as usize);
                let g = leaf_groups::<P>(groups, gbase, first, count);
                cx.leaf(leaf.prims, leaf.ids, g)
            }
        };
    }
    nodes[at - base].set(&boxes, &slots);
    union_all(&boxes)
}

/// A subtree handed to a task: its nodes (from position `base`), its groups (from `gbase`),
/// its primitives, the parent's slot it fills and, once refit, its box.
struct Task<'a, N, P> {
    nodes: &'a mut [N],
    base: usize,
    groups: &'a mut [Tri4],
    gbase: usize,
    run: Run<'a, P>,
    slot: usize,
    out: Aabb,
}

impl<N, P> Default for Task<'_, N, P> {
    fn default() -> Self {
        Task {
            nodes: &mut [],
            base: 0,
            groups: &mut [],
            gbase: 0,
            run: Run {
                prims: &mut [],
                ids: &[],
            },
            slot: 0,
            out: Aabb::EMPTY,
        }
    }
}

/// The first group of the first node in `nodes` that has a SIMD leaf: where the groups of
/// the subtrees laid out from there begin (groups are packed node by node, in node order).
fn first_group<const W: usize, N: WideNode<W>>(nodes: &[N]) -> Option<usize> {
    nodes.iter().find_map(|n| {
        n.slots().iter().find_map(|s| match *s {
            Slot::Leaf { first, count } if count > 0 => Some(first as usize),
            _ => None,
        })
    })
}

/// The primitives under the nodes of a depth-first subtree: its leaves' counts.
fn prims_under<const W: usize, N: WideNode<W>>(nodes: &[N]) -> usize {
    nodes.iter().map(|n| n.leaf_prims()).sum()
}

/// Refits a depth-first subtree: `nodes` is the whole subtree (its root first, at position
/// `base`), `groups` all of its SIMD groups (from group `gbase`), `run` its primitives. A
/// large subtree hands its inner children to parallel tasks, each with its own slices.
fn wide_dfs<const W: usize, N: WideNode<W>, P: Primitive, S: Source<P>>(
    nodes: &mut [N],
    base: usize,
    groups: &mut [Tri4],
    gbase: usize,
    mut run: Run<'_, P>,
    cx: &Ctx<'_, S>,
) -> Aabb {
    if nodes.len() <= TASK_NODES {
        if nodes.is_empty() {
            return Aabb::EMPTY;
        }
        // The task's primitives first, in one tight loop (the new input is read in leaf
        // order, out of its own: the loads overlap best without the leaf work between them),
        // then the walk reads the fresh copy.
        let fresh = Ctx::fresh(cx, &mut run);
        return wide_seq(nodes, base, groups, gbase, &mut run, base, &fresh);
    }
    let simd = P::LEAF_FORMAT != LeafFormat::Plain;
    let end = base + nodes.len();
    let groups_end = gbase + groups.len();
    let (root, rest) = nodes.split_first_mut().expect("a non-empty subtree");
    let slots = root.slots();
    // The root's own leaves were packed first, then each inner child's subtree, in slot order.
    let own: usize = slots
        .iter()
        .map(|s| match *s {
            Slot::Leaf { count, .. } if simd => group_count(count) as usize,
            _ => 0,
        })
        .sum();
    let (own_groups, mut rest_groups) = groups.split_at_mut(own);
    let mut tasks: [Task<'_, N, P>; W] = std::array::from_fn(|_| Task::default());
    let mut leaves: [Run<'_, P>; W] = std::array::from_fn(|_| Run {
        prims: &mut [],
        ids: &[],
    });
    let mut n_tasks = 0;
    let (mut rest_nodes, mut at, mut g_at) = (rest, base + 1, gbase + own);
    for (i, s) in slots.iter().enumerate() {
        let c = match *s {
            Slot::Leaf { count, .. } => {
                leaves[i] = run.take(count as usize);
                continue;
            }
            Slot::Inner(c) => c as usize,
        };
        debug_assert_eq!(c, at, "depth-first: each subtree follows the last");
        // The subtree runs to the next inner child, or to the end of this one.
        let next = slots[i + 1..]
            .iter()
            .find_map(|s| match *s {
                Slot::Inner(c) => Some(c as usize),
                Slot::Leaf { .. } => None,
            })
            .unwrap_or(end);
        let (mine, tail) = std::mem::take(&mut rest_nodes).split_at_mut(next - at);
        let g_end = if simd {
            first_group(tail).unwrap_or(groups_end)
        } else {
            g_at
        };
        let (my_groups, g_tail) = std::mem::take(&mut rest_groups).split_at_mut(g_end - g_at);
        let my_run = run.take(prims_under(mine));
        tasks[n_tasks] = Task {
            nodes: mine,
            base: at,
            groups: my_groups,
            gbase: g_at,
            run: my_run,
            slot: i,
            out: Aabb::EMPTY,
        };
        n_tasks += 1;
        (rest_nodes, rest_groups, at, g_at) = (tail, g_tail, next, g_end);
    }
    run_tasks(&mut tasks[..n_tasks], cx);
    let mut boxes = [Aabb::EMPTY; W];
    for t in &tasks[..n_tasks] {
        boxes[t.slot] = t.out;
    }
    for (i, s) in slots.iter().enumerate() {
        if let Slot::Leaf { first, count } = *s {
            let leaf = std::mem::replace(
                &mut leaves[i],
                Run {
                    prims: &mut [],
                    ids: &[],
                },
            );
            let g = leaf_groups::<P>(own_groups, gbase, first, count);
            boxes[i] = cx.leaf(leaf.prims, leaf.ids, g);
        }
    }
    root.set(&boxes, &slots);
    union_all(&boxes)
}

/// Runs the tasks, halves in parallel.
fn run_tasks<const W: usize, N: WideNode<W>, P: Primitive, S: Source<P>>(
    tasks: &mut [Task<'_, N, P>],
    cx: &Ctx<'_, S>,
) {
    match tasks {
        [] => {}
        [t] => {
            let run = Run {
                prims: std::mem::take(&mut t.run.prims),
                ids: t.run.ids,
            };
            t.out = wide_dfs(t.nodes, t.base, t.groups, t.gbase, run, cx);
        }
        _ => {
            let (a, b) = tasks.split_at_mut(tasks.len() / 2);
            rayon::join(|| run_tasks(a, cx), || run_tasks(b, cx));
        }
    }
}

/// The shared steps of the wide layouts; returns the root's box. Depth-first layouts refresh
/// the leaf-order copy (plain leaves) or repack the SIMD groups (triangle formats, no copy)
/// leaf by leaf inside their parallel tasks (one read of each new primitive serves its copy
/// or its lane, and its leaf's box); the other mappings refresh a copy in parallel first,
/// then walk the tree once. Also returns whether any SIMD group is far now.
fn refit_wide<const W: usize, N: WideNode<W>, P: Primitive, S: Source<P>>(
    nodes: &mut [N],
    prims: &mut [P],
    ids: &[u32],
    groups: &mut [Tri4],
    depth_first: bool,
    src: &S,
) -> (Aabb, bool) {
    let far = AtomicBool::new(false);
    let root = if depth_first {
        let cx = Ctx {
            src,
            fresh: false,
            far: &far,
        };
        wide_dfs(nodes, 0, groups, 0, Run { prims, ids }, &cx)
    } else {
        refresh_prims(prims, ids, src);
        let cx = Ctx {
            src,
            fresh: true,
            far: &far,
        };
        wide_seq(nodes, 0, groups, 0, &mut Run { prims, ids }, 0, &cx)
    };
    (root, far.into_inner())
}

/// The far groups after a refit that found some (`far`), or none: found in a pass of their
/// own, which the refit's tasks, each filling its own groups, could not share a list for.
fn far_groups<P: Primitive, S: Source<P>>(far: bool, groups: &[Tri4], src: &S) -> FarGroups {
    if !far {
        return FarGroups::default();
    }
    FarGroups::find(groups, |id| src.get(id).triangle())
}

impl<P: Primitive> Bvh8<P> {
    /// Refits in place from `src` (see the [module](self) docs).
    pub(crate) fn refit<S: Source<P>>(&mut self, src: &S) {
        let far;
        (self.bounds, far) = refit_wide::<8, _, _, _>(
            &mut self.nodes,
            &mut self.prims,
            &self.prim_ids,
            &mut self.tri4,
            true,
            src,
        );
        self.far = far_groups(far, &self.tri4, src);
    }
}

impl<P: Primitive, N: Node4> Bvh4<P, N> {
    /// Refits in place from `src`, quantized nodes encoded again (see the [module](self) docs).
    pub(crate) fn refit<S: Source<P>>(&mut self, src: &S) {
        let far;
        (self.bounds, far) = refit_wide::<4, _, _, _>(
            &mut self.nodes,
            &mut self.prims,
            &self.prim_ids,
            &mut self.tri4,
            self.mapping == Bvh4Mapping::DepthFirst,
            src,
        );
        self.far = far_groups(far, &self.tri4, src);
    }
}

#[inline]
fn set_box(n: &mut Bvh2Node, b: &Aabb) {
    n.min = b.min.into();
    n.max = b.max.into();
}

/// The box of a plain leaf: `count` primitives of the (refreshed) leaf-order copy from
/// `first`, whose input indices `ids` holds at the same positions.
#[inline]
fn plain_leaf<P: Primitive, S: Source<P>>(
    prims: &[P],
    ids: &[u32],
    src: &S,
    first: u32,
    count: u32,
) -> Aabb {
    let leaf = first as usize..first as usize + count as usize;
    prims[leaf.clone()]
        .iter()
        .zip(&ids[leaf])
        .fold(Aabb::EMPTY, |b, (p, &id)| b.union(&src.bounds(id, p)))
}

/// Refits a depth-first binary subtree (`nodes` from position `base`, the root first) over
/// its primitives (`run`, from leaf-order position `pbase`), each refreshed by its leaf; the
/// two children of a large subtree in parallel.
fn bvh2_dfs<P: Primitive, S: Source<P>>(
    nodes: &mut [Bvh2Node],
    base: usize,
    mut run: Run<'_, P>,
    pbase: usize,
    cx: &Ctx<'_, S>,
) -> Aabb {
    let len = nodes.len();
    if len <= TASK_NODES && !cx.fresh {
        // As in `wide_dfs`: the task's primitives in one loop, then its nodes.
        let fresh = Ctx::fresh(cx, &mut run);
        return bvh2_dfs(nodes, base, run, pbase, &fresh);
    }
    let Some((root, rest)) = nodes.split_first_mut() else {
        return Aabb::EMPTY;
    };
    let b = if root.is_leaf() {
        cx.leaf(run.prims, run.ids, &mut [])
    } else {
        let right = root.link as usize;
        let (l, r) = rest.split_at_mut(right - base - 1);
        // The right subtree's primitives start at its leftmost leaf's (in preorder, its first
        // leaf), every leaf's `first` being its leaf-order position.
        let split = r
            .iter()
            .find(|n| n.is_leaf())
            .map_or(pbase + run.prims.len(), |n| n.link as usize);
        let left = run.take(split - pbase);
        let (lb, rb) = if len > TASK_NODES {
            rayon::join(
                || bvh2_dfs(l, base + 1, left, pbase, cx),
                || bvh2_dfs(r, right, run, split, cx),
            )
        } else {
            (
                bvh2_dfs(l, base + 1, left, pbase, cx),
                bvh2_dfs(r, right, run, split, cx),
            )
        };
        lb.union(&rb)
    };
    set_box(root, &b);
    b
}

/// The inner boxes of any binary mapping, bottom-up from node `at` (leaf boxes already set).
fn bvh2_inner(nodes: &mut [Bvh2Node], at: usize, addressing: Addressing) -> Aabb {
    let n = nodes[at];
    if n.is_leaf() {
        return n.bounds();
    }
    let (l, r) = match addressing {
        Addressing::DepthFirst => (at + 1, n.link as usize),
        Addressing::Explicit => (n.link as usize, n.count as usize),
        Addressing::Compact if n.count == 0 => compact_children(at, n.link),
        Addressing::Compact => (n.link as usize, n.count as usize),
    };
    let b = bvh2_inner(nodes, l, addressing).union(&bvh2_inner(nodes, r, addressing));
    set_box(&mut nodes[at], &b);
    b
}

impl<P: Primitive> Bvh2<P> {
    /// Refits in place from `src` (see the [module](self) docs).
    pub(crate) fn refit<S: Source<P>>(&mut self, src: &S) {
        if self.mapping == Bvh2Mapping::DepthFirst {
            let run = Run {
                prims: &mut self.prims,
                ids: &self.prim_ids,
            };
            // Binary layouts keep plain leaves: no groups, nothing far.
            let far = AtomicBool::new(false);
            let cx = Ctx {
                src,
                fresh: false,
                far: &far,
            };
            bvh2_dfs(&mut self.nodes, 0, run, 0, &cx);
            return;
        }
        refresh_prims(&mut self.prims, &self.prim_ids, src);
        let (prims, ids) = (&self.prims, &self.prim_ids);
        // Leaves (padding slots are empty leaves and stay empty) are independent.
        self.nodes
            .par_iter_mut()
            .with_min_len(TASK_NODES)
            .filter(|n| n.is_leaf())
            .for_each(|n| set_box(n, &plain_leaf(prims, ids, src, n.link, n.prim_count())));
        if !self.nodes.is_empty() {
            bvh2_inner(&mut self.nodes, 0, self.mapping.addressing());
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::builders::{prim_bounds, BuildTree};
    use crate::bvh::BuildOptions;
    use crate::intersect::Watertight;
    use crate::layout::bvh2::leaf_order;
    use crate::layout::Layout;
    use crate::testing::soup;
    use crate::Triangle;
    use glam::Vec3A;

    /// The new primitives straight from a slice.
    struct Slice<'a, P>(&'a [P]);

    impl<P: Primitive> Source<P> for Slice<'_, P> {
        fn get(&self, id: u32) -> P {
            self.0[id as usize].clone()
        }
    }

    /// Every layout of `tree`, laid out over `prims` from scratch.
    fn laid<P: Primitive>(tree: &BuildTree, prims: &[P]) -> Vec<(Layout, crate::bvh::AnyLayout<P>)> {
        let tree = tree.refit(&prim_bounds(prims));
        Layout::ALL
            .iter()
            .map(|&l| {
                let options = BuildOptions::default().layout(l);
                (l, options.lay_out(&tree, leaf_order(&tree, prims)))
            })
            .collect()
    }

    fn refit<P: Primitive>(l: &mut crate::bvh::AnyLayout<P>, prims: &[P]) {
        let src = Slice(prims);
        match l {
            crate::bvh::AnyLayout::Bvh2(b) => b.refit(&src),
            crate::bvh::AnyLayout::Bvh4(b) => b.refit(&src),
            crate::bvh::AnyLayout::QBvh4(b) => b.refit(&src),
            crate::bvh::AnyLayout::Bvh8(b) => b.refit(&src),
        }
    }

    /// The arrays of a layout, as bytes (NaN lanes compare by their bits).
    fn bytes<P: Primitive>(l: &crate::bvh::AnyLayout<P>) -> (Vec<u8>, Vec<u8>, Vec<u32>, Aabb) {
        use crate::bvh::AnyLayout;
        match l {
            AnyLayout::Bvh2(b) => (
                b.node_bytes().to_vec(),
                Vec::new(),
                b.prim_ids().to_vec(),
                b.bounds(),
            ),
            AnyLayout::Bvh4(b) => (
                b.node_bytes().to_vec(),
                bytemuck::cast_slice(b.groups()).to_vec(),
                b.prim_ids().to_vec(),
                b.bounds(),
            ),
            AnyLayout::QBvh4(b) => (
                b.node_bytes().to_vec(),
                bytemuck::cast_slice(b.groups()).to_vec(),
                b.prim_ids().to_vec(),
                b.bounds(),
            ),
            AnyLayout::Bvh8(b) => (
                b.node_bytes().to_vec(),
                bytemuck::cast_slice(b.groups()).to_vec(),
                b.prim_ids().to_vec(),
                b.bounds(),
            ),
        }
    }

    fn moved(tris: &[Triangle], by: f32) -> Vec<Triangle> {
        tris.iter()
            .map(|t| {
                let w = |v: Vec3A| v + by * Vec3A::new((3.0 * v.y).sin(), (2.0 * v.z).cos(), 0.5);
                Triangle::new(w(t.v[0]), w(t.v[1]), w(t.v[2]))
            })
            .collect()
    }

    /// A refit to other primitives and back gives the original layout bit for bit: the
    /// boxes, the quantized planes, the SIMD groups, in every layout, on any pool.
    #[test]
    fn a_refit_there_and_back_is_the_original_layout_bit_for_bit() {
        let a = soup(20_000, 7);
        let b = moved(&a, 0.05);
        for builder_leaf in [1usize, 8] {
            let options = BuildOptions::default().max_leaf_size(builder_leaf);
            let (_, tree) = options.build_with_tree(&a);
            for threads in [1, 2] {
                let pool = rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .build()
                    .unwrap();
                for ((layout, mut l), (_, original)) in
                    laid(&tree, &a).into_iter().zip(laid(&tree, &a))
                {
                    pool.install(|| refit(&mut l, &b));
                    assert_ne!(bytes(&l).0, bytes(&original).0, "{layout}: the boxes moved");
                    pool.install(|| refit(&mut l, &a));
                    assert_eq!(bytes(&l), bytes(&original), "{layout}, {threads} threads");
                }
            }
        }
    }

    /// Where the layout's shape does not depend on the boxes (the binary layouts but the
    /// area-grown page blocks), a refit is a fresh layout over the new primitives, bit for bit.
    #[test]
    fn a_refit_binary_layout_is_the_fresh_layout_of_the_new_primitives() {
        let a = soup(2000, 3);
        let b = moved(&a, 0.2);
        let (_, tree) = BuildOptions::default().build_with_tree(&a);
        for ((layout, mut l), (_, fresh)) in laid(&tree, &a).into_iter().zip(laid(&tree, &b)) {
            if !matches!(l, crate::bvh::AnyLayout::Bvh2(_)) || layout == Layout::Bvh2SubtreePage {
                continue;
            }
            refit(&mut l, &b);
            assert_eq!(bytes(&l), bytes(&fresh), "{layout}");
        }
    }

    /// A scene scaled by a power of two has every area scaled exactly, so every layout (the
    /// collapses, the area-grown blocks, the quantization) makes the same shape: there the
    /// refit of a layout over `a` to `2a` must be the fresh layout over `2a`, bit for bit,
    /// nodes and SIMD groups in both triangle formats.
    #[test]
    fn a_refit_to_a_scaled_scene_is_its_fresh_layout_in_every_layout() {
        let a = soup(20_000, 5);
        let b: Vec<Triangle> = a.iter().map(|t| t.scaled(2.0).unwrap()).collect();
        let (_, tree) = BuildOptions::default().build_with_tree(&a);
        for ((layout, mut l), (_, fresh)) in laid(&tree, &a).into_iter().zip(laid(&tree, &b)) {
            refit(&mut l, &b);
            assert_eq!(bytes(&l), bytes(&fresh), "{layout}: fast triangles");
        }
        let wa: Vec<Watertight> = a.iter().map(|t| Watertight(*t)).collect();
        let wb: Vec<Watertight> = b.iter().map(|t| Watertight(*t)).collect();
        for ((layout, mut l), (_, fresh)) in laid(&tree, &wa).into_iter().zip(laid(&tree, &wb)) {
            refit(&mut l, &wb);
            assert_eq!(bytes(&l), bytes(&fresh), "{layout}: watertight triangles");
        }
    }
}
