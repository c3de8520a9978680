//! The first-active-ray walk over a 4- or 8-wide tree, and the hand-over to single rays when
//! a packet comes apart.

use super::lanes::RayPacket;
use super::node::{PacketNode, LEAF};
use crate::builders::MAX_DEPTH;
use crate::traverse::lane8::F8;
use crate::traverse::simd::{bits, insert_farthest_first};
use crate::traverse::{BoxTest, Stack, Stats};
use std::ops::Range;

/// Stack entry: a child, where its box is (slot of a parent node), the first ray entering it
/// and that ray's entry distance, and the rays that may enter it. The box is re-read only when
/// needed (leaf, or a new first ray), which is cheaper than carrying it.
#[derive(Clone, Copy)]
struct Entry {
    child: u32,
    /// 0 for an inner node, `LEAF | count` for a leaf.
    count: u32,
    first: u32,
    t: f32,
    parent: u32,
    slot: u32,
    /// The rays that may enter the child: every ray that enters it is in here. Searches for
    /// a first ray scan only these, so they get cheaper as the packet spreads out.
    mask: u64,
}

impl Entry {
    /// The primitives of a leaf entry.
    #[inline(always)]
    fn leaf_range(&self) -> Range<usize> {
        let count = self.count & !LEAF;
        self.child as usize..(self.child + count) as usize
    }
}

/// Bits above `i`.
#[inline(always)]
fn above(i: usize) -> u64 {
    (u64::MAX << i) << 1
}

/// What the packet walk hands its caller.
pub(crate) enum Visit<'b> {
    /// A leaf's primitives, for the active rays of the mask that enter the box.
    Leaf(Range<usize>, &'b [f32; 6], u64),
    /// One ray alone, from its current limit, after the packet came apart.
    Alone(usize, AloneIn),
}

/// Where a ray continues alone.
pub(crate) enum AloneIn {
    Leaf(Range<usize>),
    Inner(usize),
}

/// The packet walk over one node format, in lanes of `V`. `visit(packet, what, stats)` handles a leaf
/// for the packet or a subtree for one ray ([`Visit`]) and returns true once every ray is done
/// (any-hit), which ends the walk.
///
/// Each node is tested against its first ray alone. A child that ray misses is tested
/// against the other candidate rays (those that may have entered the node), which gives
/// the child's exact candidate set, so the deeper the walk, the fewer rays a search scans.
/// When the packet comes apart ([`RayPacket::came_apart`]), each remaining ray finishes the
/// stacked subtrees alone with the single-ray walk.
#[inline(always)]
pub(crate) fn walk<N, V, B, S, F>(
    cpu: V::Cpu,
    nodes: &[N],
    pk: &mut RayPacket,
    stats: &mut S,
    prefetch: impl Fn(usize),
    mut visit: F,
) where
    N: PacketNode,
    V: F8,
    B: BoxTest,
    S: Stats,
    F: FnMut(&mut RayPacket, Visit, &mut S) -> bool,
{
    if pk.active == 0 {
        return;
    }
    // Each node pushes at most seven entries beyond the one it continues with.
    let mut stack: Stack<Entry, { 7 * MAX_DEPTH + 8 }> = Stack::new();
    let mut node = 0usize;
    let mut mask = pk.active;
    let mut first = mask.trailing_zeros() as usize;
    // The first ray prepared for node tests; it often stays first for many nodes.
    let (mut r1, mut r1_of) = (pk.first::<N, V>(cpu, first), first);
    loop {
        let n = &nodes[node];
        stats.node();
        stats.boxes(N::WIDTH as u32);
        let mut used = 0u32;
        for i in 0..N::WIDTH {
            used |= ((n.child(i).1 != LEAF) as u32) << i;
        }
        if r1_of != first {
            (r1, r1_of) = (pk.first::<N, V>(cpu, first), first);
        }
        let (t, hit) = n.enter_first::<V, B>(&r1, pk.limit(first) * B::SLACK);
        let hit = hit & used;
        // (entry distance, (slot, first ray, candidates)), farthest first.
        let mut kids = [(0.0f32, (0usize, 0usize, 0u64)); 8];
        let mut k = 0;
        // A child the first ray misses may still be entered by a later candidate.
        let rest = mask & above(first);
        let mut missed = !hit & used;
        if missed != 0 && rest & pk.active != 0 {
            missed &= n.may_enter::<V, B>(cpu, &pk.bound);
        } else {
            missed = 0;
        }
        for i in bits(missed) {
            stats.boxes(1);
            let (m, tf) = pk.enter_all::<V, B>(cpu, &n.slot_box(i), rest);
            if m != 0 {
                insert_farthest_first(&mut kids, k, tf, (i, m.trailing_zeros() as usize, m));
                k += 1;
            }
        }
        for i in bits(hit) {
            insert_farthest_first(&mut kids, k, t[i], (i, first, mask));
            k += 1;
        }
        for &(ti, (i, f, m)) in &kids[..k] {
            let (child, count) = n.child(i);
            if count & LEAF != 0 {
                prefetch(child as usize);
            }
            stack.push(Entry {
                child,
                count,
                first: f as u32,
                t: ti,
                parent: node as u32,
                slot: i as u32,
                mask: m,
            });
        }
        // Pop until an inner node some ray still enters; leaves are handled on the way.
        loop {
            let Some(e) = stack.pop() else {
                return;
            };
            let mut f = e.first as usize;
            let is_leaf = e.count & LEAF != 0;
            let valid = pk.active >> f & 1 == 1 && e.t <= pk.limit(f) * B::SLACK;
            if valid && !is_leaf {
                (node, first, mask) = (e.child as usize, f, e.mask);
                break;
            }
            let b = nodes[e.parent as usize].slot_box(e.slot as usize);
            if !valid {
                // The first ray was shortened (or retired) since the push: look for another.
                match pk.find_first::<V, B>(cpu, &b, e.mask & above(f)) {
                    Some((nf, _)) => f = nf,
                    None => continue,
                }
                if !is_leaf {
                    (node, first, mask) = (e.child as usize, f, e.mask);
                    break;
                }
            }
            stats.node();
            stats.leaf();
            if visit(
                pk,
                Visit::Leaf(e.leaf_range(), &b, e.mask & !((1u64 << f) - 1)),
                stats,
            ) {
                return;
            }
            if pk.came_apart() {
                // Nearest first, as the packet would have gone on. The entries are popped
                // one by one: handing the stack itself to the (outlined) hand-over made the
                // compiler zero the whole stack on every walk (callgrind, +12%).
                while let Some(e) = stack.pop() {
                    V::outlined(
                        cpu,
                        #[inline(always)]
                        || finish_alone::<N, V, B, S, F>(cpu, nodes, pk, &e, stats, &mut visit),
                    );
                    if pk.active == 0 {
                        return;
                    }
                }
                return;
            }
        }
    }
}

/// Every active ray that may enter stacked entry `e` finishes it alone: if its box is
/// entered (tested exactly as the single-ray walk tests it), the leaf's primitives or the inner
/// node's subtree with the single-ray walk. Called for the stacked entries nearest first, so
/// each ray meets its entries in the order the single-ray walk would. Outlined by the caller
/// ([`F8::outlined`]): the hand-over is rare and long.
#[inline(always)]
fn finish_alone<N, V, B, S, F>(
    cpu: V::Cpu,
    nodes: &[N],
    pk: &mut RayPacket,
    e: &Entry,
    stats: &mut S,
    visit: &mut F,
) where
    N: PacketNode,
    V: F8,
    B: BoxTest,
    S: Stats,
    F: FnMut(&mut RayPacket, Visit, &mut S) -> bool,
{
    let parent = &nodes[e.parent as usize];
    for i in bits(pk.active & e.mask) {
        let r1 = pk.first::<N, V>(cpu, i);
        if parent.enter_first::<V, B>(&r1, pk.limit(i) * B::SLACK).1 >> e.slot & 1 == 0 {
            continue;
        }
        let at = match e.count & LEAF {
            0 => AloneIn::Inner(e.child as usize),
            _ => AloneIn::Leaf(e.leaf_range()),
        };
        visit(pk, Visit::Alone(i, at), stats);
    }
}
