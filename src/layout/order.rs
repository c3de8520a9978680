//! Memory mappings: where each node of a tree goes in the node array.
//!
//! A mapping is computed on a [`Shape`] (children and surface area of every node, with node 0
//! the root and nodes numbered in depth-first preorder) and returned as a slot table:
//! `slots[i]` is the node stored at array position `i`, or [`HOLE`] for padding. The layouts
//! then write their own node format into those positions.
//!
//! The mappings follow Havran's thesis (ch. 7): depth-first, breadth-first, random (the
//! baseline that shows what locality is worth), and *subtree* mappings that fill a cache line
//! or a page with a connected piece of the tree, so that one fetch brings the nodes a ray is
//! likely to visit next.

use crate::rng::Rng;
use std::collections::BinaryHeap;

/// No node: padding in a slot table, or a missing child in a [`Shape`].
pub(crate) const HOLE: u32 = u32::MAX;

/// The structure of a tree, independent of its node format.
pub(crate) struct Shape {
    /// Up to four children per node (inner children only; leaves held inside a node's slots
    /// are not separate nodes); unused entries are [`HOLE`].
    pub kids: Vec<[u32; 4]>,
    /// Surface area (half) of each node's box: the likelihood a ray that reaches the parent
    /// visits it is proportional to it.
    pub area: Vec<f32>,
}

impl Shape {
    fn children(&self, n: u32) -> impl Iterator<Item = u32> + '_ {
        self.kids[n as usize].iter().copied().filter(|&k| k != HOLE)
    }

    fn len(&self) -> usize {
        self.kids.len()
    }
}

/// Depth-first preorder, children in stored order.
pub(crate) fn depth_first(shape: &Shape) -> Vec<u32> {
    let mut out = Vec::with_capacity(shape.len());
    let mut stack = vec![0u32];
    while let Some(n) = stack.pop() {
        out.push(n);
        let kids: Vec<u32> = shape.children(n).collect();
        stack.extend(kids.iter().rev());
    }
    out
}

/// Breadth-first (level) order.
pub(crate) fn breadth_first(shape: &Shape) -> Vec<u32> {
    let mut out = Vec::with_capacity(shape.len());
    out.push(0);
    let mut i = 0;
    while i < out.len() {
        let n = out[i];
        out.extend(shape.children(n));
        i += 1;
    }
    out
}

/// The root first, every other node at a random (seeded) position.
pub(crate) fn shuffled(shape: &Shape, seed: u64) -> Vec<u32> {
    let mut out: Vec<u32> = (0..shape.len() as u32).collect();
    let mut rng = Rng::new(seed);
    for i in (2..out.len()).rev() {
        let j = 1 + (rng.next_u64() % i as u64) as usize;
        out.swap(i, j);
    }
    out
}

/// Subtree mapping: the node array is cut into groups of `cap` slots (a page, say), and each
/// group is filled with connected pieces of the tree, each grown from its root by always
/// adding the frontier node of largest area (the one a ray is most likely to visit next)
/// until the group is full. Pieces are placed in depth-first order of their roots. A piece
/// never straddles a group boundary and no slot is left empty.
pub(crate) fn subtree(shape: &Shape, cap: usize) -> Vec<u32> {
    let mut slots = Vec::with_capacity(shape.len());
    let mut roots = vec![0u32];
    while let Some(root) = roots.pop() {
        let room = cap - slots.len() % cap;
        let mut frontier = BinaryHeap::new();
        frontier.push(ByArea(shape.area[root as usize], root));
        let mut taken = 0;
        while taken < room {
            let Some(ByArea(_, n)) = frontier.pop() else {
                break;
            };
            slots.push(n);
            taken += 1;
            for k in shape.children(n) {
                frontier.push(ByArea(shape.area[k as usize], k));
            }
        }
        // Nodes are numbered in preorder, so sorting the frontier by number puts the next
        // pieces in depth-first order.
        let mut rest: Vec<u32> = frontier.into_iter().map(|ByArea(_, n)| n).collect();
        rest.sort_unstable_by(|a, b| b.cmp(a));
        roots.extend(rest);
    }
    slots
}

/// Compact subtree mapping for binary trees: each block is a complete binary heap of height
/// `h` in `2^h` slots aligned to `2^h`. The heap is 1-indexed (slot 0 of a block is padding),
/// so a node at block position `p` has its children inside the block at `2p` and `2p + 1`:
/// siblings share a cache line, and need no link. Only nodes on the block's bottom level link
/// to other blocks. `h` is `max_h`, or less for a subtree that is not that tall, so short
/// subtrees near the leaves do not reserve a full page. A block whose root has no children
/// takes a single slot (it is never used to address children), placed in the padding of
/// earlier blocks when there is any.
///
/// Returns the slot table and, per slot, the height of the block whose interior holds it (0
/// for bottom-level nodes, single nodes and holes).
pub(crate) fn compact(shape: &Shape, max_h: u32) -> (Vec<u32>, Vec<u8>) {
    let height = heights(shape);
    let mut packer = Packer::default();
    let mut interior = Vec::new();
    // The traversal starts at slot 0, which no block interior can use (slot 0 of a block is
    // padding), so the root sits there alone and links to its children explicitly.
    let mut roots = match shape.kids[0] {
        [l, r, ..] if l != HOLE => {
            packer.place_aligned(&[0, HOLE]);
            vec![r, l]
        }
        _ => vec![0],
    };
    while let Some(root) = roots.pop() {
        if shape.children(root).next().is_none() {
            packer.place_single(root, 2);
            continue;
        }
        let h = max_h.min(height[root as usize] + 1);
        let size = 1usize << h;
        let mut heap = vec![HOLE; size];
        let mut inside = vec![0u8; size];
        heap[1] = root;
        let mut next_roots = Vec::new();
        for p in 1..size {
            let n = heap[p];
            if n == HOLE {
                continue;
            }
            let kids: Vec<u32> = shape.children(n).collect();
            debug_assert!(
                kids.is_empty() || kids.len() == 2,
                "compact mapping needs a binary tree"
            );
            if kids.is_empty() {
                continue;
            }
            if 2 * p + 1 < size {
                inside[p] = h as u8;
                heap[2 * p] = kids[0];
                heap[2 * p + 1] = kids[1];
            } else {
                next_roots.extend(kids);
            }
        }
        next_roots.sort_unstable_by(|a, b| b.cmp(a));
        roots.extend(next_roots);
        let start = packer.place_aligned(&heap);
        interior.resize(start, 0);
        interior.extend_from_slice(&inside);
    }
    interior.resize(packer.slots.len(), 0);
    (packer.slots, interior)
}

/// Subtree mapping for binary trees whose traversal reads both children of a node together:
/// the unit of access is a *sibling pair*, stored in one 64-byte line. Pairs are grouped into
/// blocks of up to `cap_pairs` by [`subtree`] (grown by area, depth-first between blocks); the
/// root takes a line of its own.
pub(crate) fn sibling_pairs(shape: &Shape, cap_pairs: usize) -> Vec<u32> {
    // Unit 0 is the root's line; unit k > 0 holds the children of the k-th inner node in
    // preorder, which numbers the units in preorder too.
    let mut unit_of = vec![HOLE; shape.len()];
    let mut lines: Vec<[u32; 2]> = vec![[0, HOLE]];
    let mut units = Shape {
        kids: vec![[HOLE; 4]],
        area: vec![shape.area[0]],
    };
    for n in 0..shape.len() as u32 {
        let kids: Vec<u32> = shape.children(n).collect();
        if kids.is_empty() {
            continue;
        }
        debug_assert_eq!(kids.len(), 2, "sibling pairs need a binary tree");
        unit_of[n as usize] = lines.len() as u32;
        lines.push([kids[0], kids[1]]);
        units.kids.push([HOLE; 4]);
        units.area.push(shape.area[n as usize]);
    }
    // A unit's children are the units of its inner members (the root's line holds the root).
    for (u, line) in lines.iter().enumerate() {
        let mut j = 0;
        for &m in line.iter().filter(|&&m| m != HOLE) {
            if unit_of[m as usize] != HOLE {
                units.kids[u][j] = unit_of[m as usize];
                j += 1;
            }
        }
    }
    subtree(&units, cap_pairs)
        .iter()
        .flat_map(|&u| {
            if u == HOLE {
                [HOLE, HOLE]
            } else {
                lines[u as usize]
            }
        })
        .collect()
}

/// Height of every node's subtree (0 for a leaf). Children always follow their parent in the
/// preorder numbering, so one backward pass suffices.
fn heights(shape: &Shape) -> Vec<u32> {
    let mut h = vec![0u32; shape.len()];
    for n in (0..shape.len()).rev() {
        h[n] = shape
            .children(n as u32)
            .map(|k| h[k as usize] + 1)
            .max()
            .unwrap_or(0);
    }
    h
}

/// Orders nodes by area (ties by lower node number first, for determinism).
#[derive(PartialEq)]
struct ByArea(f32, u32);

impl Eq for ByArea {}

impl PartialOrd for ByArea {
    fn partial_cmp(&self, other: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(other))
    }
}

impl Ord for ByArea {
    fn cmp(&self, other: &Self) -> std::cmp::Ordering {
        self.0.total_cmp(&other.0).then(other.1.cmp(&self.1))
    }
}

/// Places aligned blocks into a growing slot table, remembering padding for single nodes.
#[derive(Default)]
struct Packer {
    slots: Vec<u32>,
    /// Unused slots, most recent last (nearest to what is being placed now).
    holes: Vec<usize>,
}

impl Packer {
    /// A single node: into a hole, or else a fresh aligned group of `size` slots.
    fn place_single(&mut self, node: u32, size: usize) {
        if let Some(h) = self.holes.pop() {
            self.slots[h] = node;
        } else {
            let mut group = vec![HOLE; size];
            group[0] = node;
            self.place_aligned(&group);
        }
    }

    /// Appends `block` (holes included) at the next multiple of its length; returns where.
    fn place_aligned(&mut self, block: &[u32]) -> usize {
        let start = self.slots.len().next_multiple_of(block.len());
        self.pad_to(start);
        for (i, &n) in block.iter().enumerate() {
            if n == HOLE {
                self.holes.push(start + i);
            }
        }
        // Holes only ever appear at the end of the table, so `holes` stays sorted and
        // popping takes the most recent one: the nearest to the nodes placed next.
        self.slots.extend_from_slice(block);
        start
    }

    fn pad_to(&mut self, end: usize) {
        while self.slots.len() < end {
            self.holes.push(self.slots.len());
            self.slots.push(HOLE);
        }
    }
}

/// Inverse of a slot table: the position of every node.
pub(crate) fn positions(slots: &[u32], nodes: usize) -> Vec<u32> {
    let mut pos = vec![HOLE; nodes];
    for (i, &n) in slots.iter().enumerate() {
        if n != HOLE {
            pos[n as usize] = i as u32;
        }
    }
    pos
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A complete binary tree of `levels` levels in preorder, all areas equal but the
    /// right subtree of the root made larger, so greedy blocks prefer it.
    fn tree(levels: u32) -> Shape {
        fn add(s: &mut Shape, level: u32, levels: u32, area: f32) -> u32 {
            let me = s.kids.len() as u32;
            s.kids.push([HOLE; 4]);
            s.area.push(area);
            if level + 1 < levels {
                let l = add(s, level + 1, levels, area / 2.0);
                let r = add(
                    s,
                    level + 1,
                    levels,
                    area / 2.0 + if level == 0 { 1.0 } else { 0.0 },
                );
                s.kids[me as usize][..2].copy_from_slice(&[l, r]);
            }
            me
        }
        let mut s = Shape {
            kids: vec![],
            area: vec![],
        };
        add(&mut s, 0, levels, 100.0);
        s
    }

    fn is_permutation(slots: &[u32], n: usize) -> bool {
        let mut seen = vec![false; n];
        for &s in slots.iter().filter(|&&s| s != HOLE) {
            if std::mem::replace(&mut seen[s as usize], true) {
                return false;
            }
        }
        seen.iter().all(|&s| s)
    }

    #[test]
    fn every_mapping_places_every_node_once() {
        let s = tree(9);
        let n = s.len();
        assert_eq!(depth_first(&s), (0..n as u32).collect::<Vec<_>>());
        assert!(is_permutation(&breadth_first(&s), n));
        assert!(is_permutation(&shuffled(&s, 1), n));
        for cap in [1, 2, 32, 128] {
            assert!(is_permutation(&subtree(&s, cap), n), "subtree {cap}");
        }
        for cap in [1, 64] {
            assert!(is_permutation(&sibling_pairs(&s, cap), n), "pairs {cap}");
        }
        for h in [2, 7] {
            assert!(is_permutation(&compact(&s, h).0, n), "compact {h}");
        }
    }

    #[test]
    fn subtree_blocks_grow_by_area_and_fill_groups() {
        let s = tree(4);
        // The root's right child (preorder number 8) has the larger area.
        assert_eq!(&subtree(&s, 2)[..2], &[0, 8]);
        // A group of four: the root, then always the largest frontier node (ties: lower number).
        assert_eq!(&subtree(&s, 4)[..4], &[0, 8, 1, 9]);
    }

    #[test]
    fn sibling_pairs_share_lines() {
        let s = tree(7);
        for cap in [1, 64] {
            let slots = sibling_pairs(&s, cap);
            let pos = positions(&slots, s.len());
            assert_eq!(pos[0], 0);
            for kids in s.kids.iter().filter(|k| k[0] != HOLE) {
                let (l, r) = (pos[kids[0] as usize], pos[kids[1] as usize]);
                assert_eq!((l % 2, r), (0, l + 1));
            }
        }
    }

    #[test]
    fn compact_children_sit_at_heap_positions() {
        let s = tree(6);
        for max_h in [2, 3, 7] {
            let (slots, interior) = compact(&s, max_h);
            let pos = positions(&slots, s.len());
            let mut inside = 0;
            for (n, kids) in s.kids.iter().enumerate() {
                let i = pos[n] as usize;
                let h = interior[i] as u32;
                if h > 0 {
                    inside += 1;
                    let p = i % (1 << h);
                    assert_eq!(pos[kids[0] as usize] as usize, i + p);
                    assert_eq!(pos[kids[1] as usize] as usize, i + p + 1);
                    assert_eq!(pos[kids[0] as usize] % 2, 0, "siblings share a line");
                }
            }
            // A 6-level complete tree: every block interior is used.
            assert!(inside > 0);
        }
    }
}
