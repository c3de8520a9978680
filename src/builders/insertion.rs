//! Bittner, Hapala and Havran's insertion-based optimisation (2013) and the insertion-based
//! construction built on it (Bittner et al. 2015).
//!
//! *Optimisation*: each iteration takes the 1% of inner nodes with the worst combined
//! inefficiency `M_comb = A(N)/mean(A(children)) · A(N)/min(A(children)) · A(N)`, and for each
//! removes it and its parent, then reinserts its two children (larger first) where a
//! branch-and-bound search finds the least total area increase. The sum of inner-node areas
//! (the only part of the SAH cost that moves: leaves are not touched) is checked every
//! `P_T = 10` iterations, and the phase ends when a check brings no gain; a second phase picks
//! the nodes at random (seeded), checked every `P_R = 5` iterations. Sequential, so the result
//! is the same for any thread count.
//!
//! *Construction*: primitives inserted one by one in input order into a growing tree by the
//! same search; two consecutive primitives whose union is less than 1.5 times their areas'
//! sum go in as a pair (the coherence test), and after every batch of 8,000 insertions one
//! optimisation iteration runs over the tree (the thesis's Table 8: batch = 8000,
//! oFrac = 0.01, coh = 1.5). Bittner et al. restrict that iteration to recently touched
//! branches; here it takes the worst 1% of the whole tree.

use super::cluster::Links;
use crate::geometry::Aabb;
use crate::rng::Rng;
use std::cmp::Reverse;
use std::collections::BinaryHeap;

const NONE: u32 = u32::MAX;

/// Iterations between cost checks in the inefficiency-driven phase.
const P_T: usize = 10;
/// Iterations between cost checks in the random phase.
const P_R: usize = 5;
/// Share of inner nodes reinserted per iteration.
const FRACTION: f64 = 0.01;
/// Checks in a row without a new best cost that end a phase.
const PATIENCE: usize = 3;
/// No phase runs longer than this many checks, whatever the cost does.
const MAX_CHECKS: usize = 50;

/// Insertions between global optimisation iterations in the construction.
const BATCH: usize = 8000;
/// Consecutive primitives with `A(a ∪ b) / (A(a) + A(b))` below this are inserted as a pair.
const COHERENCE: f32 = 1.5;

/// A tree being edited: [`Links`] plus parent links.
struct Editable<'a> {
    links: &'a mut Links,
    parent: Vec<u32>,
    units: u32,
}

impl<'a> Editable<'a> {
    fn new(links: &'a mut Links) -> Self {
        let units = links.units() as u32;
        let mut parent = vec![NONE; links.bounds.len()];
        for (i, [a, b]) in links.children.iter().enumerate() {
            parent[*a as usize] = units + i as u32;
            parent[*b as usize] = units + i as u32;
        }
        Editable {
            links,
            parent,
            units,
        }
    }

    fn kids(&self, x: u32) -> Option<[u32; 2]> {
        (x >= self.units).then(|| self.links.children[(x - self.units) as usize])
    }

    fn area(&self, x: u32) -> f32 {
        self.links.bounds[x as usize].half_area()
    }

    fn replace_child(&mut self, parent: u32, old: u32, new: u32) {
        let k = &mut self.links.children[(parent - self.units) as usize];
        if k[0] == old {
            k[0] = new;
        } else {
            k[1] = new;
        }
        self.parent[new as usize] = parent;
    }

    /// Recomputes boxes from `x` up to the root, stopping where a box does not change.
    fn refit(&mut self, mut x: u32) {
        while x != NONE {
            let [a, b] = self.kids(x).expect("only inner nodes are refitted");
            let bounds = self.links.bounds[a as usize].union(&self.links.bounds[b as usize]);
            if bounds == self.links.bounds[x as usize] {
                break;
            }
            self.links.bounds[x as usize] = bounds;
            x = self.parent[x as usize];
        }
    }

    /// Takes inner node `n` (not the root) and its parent out of the tree; returns its
    /// children and the two freed nodes.
    fn remove(&mut self, n: u32) -> ([u32; 2], [u32; 2]) {
        let kids = self.kids(n).expect("an inner node");
        let p = self.parent[n as usize];
        let [pa, pb] = self.kids(p).expect("a parent is inner");
        let sibling = if pa == n { pb } else { pa };
        let g = self.parent[p as usize];
        if g == NONE {
            self.links.root = sibling;
            self.parent[sibling as usize] = NONE;
        } else {
            self.replace_child(g, p, sibling);
            self.refit(g);
        }
        (kids, [n, p])
    }

    /// Hangs `x` beside the node the search picks, under the free inner node `link`.
    fn insert(&mut self, x: u32, link: u32) {
        let at = self.best_place(x);
        let q = self.parent[at as usize];
        self.links.children[(link - self.units) as usize] = [at, x];
        self.parent[at as usize] = link;
        self.parent[x as usize] = link;
        self.parent[link as usize] = q;
        self.links.bounds[link as usize] =
            self.links.bounds[at as usize].union(&self.links.bounds[x as usize]);
        if q == NONE {
            self.links.root = link;
        } else {
            self.replace_child(q, at, link);
            self.refit(q);
        }
    }

    /// Branch and bound over the tree for the node whose sibling `x` should become: the one
    /// minimising `A(node ∪ x)` plus the area every ancestor would gain. Subtrees whose
    /// inherited gain plus `A(x)` (a lower bound on anything below) cannot beat the best are
    /// skipped, cheapest first.
    fn best_place(&self, x: u32) -> u32 {
        let bx = self.links.bounds[x as usize];
        let ax = bx.half_area();
        let root = self.links.root;
        let mut best = (f32::INFINITY, root);
        let mut heap = BinaryHeap::new();
        heap.push(Reverse((key(0.0), root)));
        while let Some(Reverse((k, node))) = heap.pop() {
            let induced = f32::from_bits(k);
            if (induced + ax).total_cmp(&best.0).is_ge() {
                break;
            }
            let merged = self.links.bounds[node as usize].union(&bx).half_area();
            let total = induced + merged;
            if total < best.0 {
                best = (total, node);
            }
            if let Some([a, b]) = self.kids(node) {
                let below = total - self.area(node);
                if below + ax < best.0 {
                    heap.push(Reverse((key(below), a)));
                    heap.push(Reverse((key(below), b)));
                }
            }
        }
        best.1
    }

    /// Removes `n` and reinserts its children, the larger first.
    fn reinsert(&mut self, n: u32) {
        if self.parent[n as usize] == NONE || self.kids(n).is_none() {
            return;
        }
        let ([a, b], [l1, l2]) = self.remove(n);
        let (first, second) = if self.area(a).total_cmp(&self.area(b)).is_ge() {
            (a, b)
        } else {
            (b, a)
        };
        self.insert(first, l1);
        self.insert(second, l2);
    }

    fn inner_area(&self) -> f64 {
        // Every inner node index is in use in a complete tree.
        (self.units..self.links.bounds.len() as u32)
            .map(|x| self.area(x) as f64)
            .sum()
    }

    /// `M_comb` of inner node `x`: large for a node much bigger than its children, or than
    /// its smaller child, and for large nodes.
    fn inefficiency(&self, x: u32) -> f32 {
        let [a, b] = self.kids(x).expect("inner");
        let (an, aa, ab) = (self.area(x), self.area(a), self.area(b));
        an / ((aa + ab) * 0.5) * (an / aa.min(ab)) * an
    }

    /// The `k` inner nodes (not the root) below index `allocated` of worst `M_comb`, worst
    /// first; ties by index.
    fn worst(&self, k: usize, allocated: u32) -> Vec<u32> {
        let mut all: Vec<(f32, u32)> = (self.units..allocated)
            .filter(|&x| self.parent[x as usize] != NONE)
            .map(|x| (self.inefficiency(x), x))
            .collect();
        let order = |p: &(f32, u32), q: &(f32, u32)| q.0.total_cmp(&p.0).then(p.1.cmp(&q.1));
        let k = k.min(all.len());
        if k == 0 {
            return Vec::new();
        }
        all.select_nth_unstable_by(k - 1, order);
        all.truncate(k);
        all.sort_unstable_by(order);
        all.into_iter().map(|(_, x)| x).collect()
    }

    fn per_iteration(&self) -> usize {
        let inner = self.links.bounds.len() - self.units as usize;
        ((inner as f64 * FRACTION).ceil() as usize).max(1)
    }

    /// Runs iterations in groups of `every` while a group lowers the inner area, and leaves
    /// the tree as it was after the best group (a reinsertion may raise the cost for a
    /// while before lowering it, so the last group may be worse).
    fn phase(&mut self, every: usize, mut pick: impl FnMut(&Self) -> Vec<u32>) {
        let mut best = self.inner_area();
        let mut saved = self.snapshot();
        let mut misses = 0;
        for _ in 0..MAX_CHECKS {
            for _ in 0..every {
                for n in pick(self) {
                    self.reinsert(n);
                }
            }
            let now = self.inner_area();
            if now.total_cmp(&best).is_ge() {
                misses += 1;
                if misses == PATIENCE {
                    break;
                }
                continue;
            }
            misses = 0;
            best = now;
            saved = self.snapshot();
        }
        self.restore(saved);
    }

    fn snapshot(&self) -> Snapshot {
        Snapshot {
            bounds: self.links.bounds.clone(),
            children: self.links.children.clone(),
            parent: self.parent.clone(),
            root: self.links.root,
        }
    }

    fn restore(&mut self, s: Snapshot) {
        self.links.bounds = s.bounds;
        self.links.children = s.children;
        self.parent = s.parent;
        self.links.root = s.root;
    }
}

/// The editable parts of a tree, saved at its best cost so far.
struct Snapshot {
    bounds: Vec<Aabb>,
    children: Vec<[u32; 2]>,
    parent: Vec<u32>,
    root: u32,
}

/// Non-negative f32 as an order-preserving integer (the heap's key).
fn key(x: f32) -> u32 {
    x.max(0.0).to_bits()
}

/// Optimises `links` in place (a complete tree: every inner node in use).
pub(crate) fn optimize(links: &mut Links) {
    if links.children.len() < 3 {
        return;
    }
    let mut t = Editable::new(links);
    let k = t.per_iteration();
    let all = t.links.bounds.len() as u32;
    t.phase(P_T, |t| t.worst(k, all));
    let mut rng = Rng::new(0x1b0);
    t.phase(P_R, |t| {
        let inner = t.links.children.len() as u64;
        (0..k)
            .map(|_| t.units + (rng.next_u64() % inner) as u32)
            .collect()
    });
}

/// Builds a tree by inserting the units of `links` (which has no inner nodes yet) one by one.
pub(crate) fn construct(links: &mut Links) {
    let n = links.units() as u32;
    // Every inner node is allocated up front: n - 1 of them, used in order.
    links.bounds.resize(2 * n as usize - 1, Aabb::EMPTY);
    links.children.resize(n as usize - 1, [0, 0]);
    links.root = 0;
    let mut t = Editable::new(links);
    // The placeholder children linked nothing.
    t.parent.fill(NONE);
    let mut next_inner = n;
    let mut since_update = 0;
    let mut i = 0;
    let mut empty = true;
    while i < n {
        let mut x = i;
        i += 1;
        if i < n {
            let (a, b) = (t.links.bounds[x as usize], t.links.bounds[i as usize]);
            let sum = a.half_area() + b.half_area();
            if a.union(&b).half_area() < COHERENCE * sum {
                let link = next_inner;
                next_inner += 1;
                t.links.children[(link - n) as usize] = [x, i];
                t.links.bounds[link as usize] = a.union(&b);
                t.parent[x as usize] = link;
                t.parent[i as usize] = link;
                x = link;
                i += 1;
            }
        }
        if std::mem::take(&mut empty) {
            // The first unit or pair is the tree so far.
            t.links.root = x;
            t.parent[x as usize] = NONE;
        } else {
            let link = next_inner;
            next_inner += 1;
            t.insert(x, link);
        }
        since_update += 1;
        if since_update >= BATCH {
            since_update = 0;
            let used = next_inner - n;
            if used >= 3 {
                let k = ((used as f64 * FRACTION).ceil() as usize).max(1);
                for node in t.worst(k, next_inner) {
                    t.reinsert(node);
                }
            }
        }
    }
    debug_assert_eq!(next_inner, 2 * n - 1);
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::builders::cluster::Links;
    use glam::Vec3A;

    /// Small boxes scattered at random, joined pairwise in input order: every inner node
    /// spans boxes from all over the scene, the worst kind of tree.
    fn random_order_tree(n: usize) -> Links {
        let mut rng = Rng::new(7);
        let boxes: Vec<Aabb> = (0..n)
            .map(|_| {
                let p = rng.in_box(Vec3A::ZERO, Vec3A::splat(100.0));
                Aabb::new(p, p + Vec3A::ONE)
            })
            .collect();
        let mut links = Links::singletons((0..n as u32).collect(), &boxes);
        let mut level: Vec<u32> = (0..n as u32).collect();
        while level.len() > 1 {
            let next: Vec<u32> = level
                .chunks(2)
                .map(|c| {
                    if c.len() == 2 {
                        links.join(c[0], c[1])
                    } else {
                        c[0]
                    }
                })
                .collect();
            level = next;
        }
        links.root = level[0];
        links
    }

    fn inner_area(links: &Links) -> f64 {
        let u = links.units();
        links.bounds[u..].iter().map(|b| b.half_area_f64()).sum()
    }

    #[test]
    fn optimisation_repairs_a_random_order_tree() {
        let mut links = random_order_tree(2000);
        let before = inner_area(&links);
        optimize(&mut links);
        let after = inner_area(&links);
        // Each of the ~log2(n) levels of the random tree has inner boxes about the size of the
        // scene, so its inner area is about n · A(root); a spatial tree's is about
        // A(root) · log2(n). Anything that reorganises the tree at all cuts most of it.
        assert!(after < 0.5 * before, "inner area {before} -> {after}");
        // Still one tree over all units.
        let mut seen = vec![false; links.bounds.len()];
        for x in links.postorder() {
            assert!(!std::mem::replace(&mut seen[x as usize], true));
        }
        assert!(seen.iter().all(|&s| s));
    }

    #[test]
    fn construction_links_every_unit_once() {
        let links0 = random_order_tree(1);
        assert_eq!(links0.units(), 1);
        let mut rng = Rng::new(9);
        let boxes: Vec<Aabb> = (0..500)
            .map(|_| {
                let p = rng.in_box(Vec3A::ZERO, Vec3A::splat(10.0));
                Aabb::new(p, p + Vec3A::splat(0.5))
            })
            .collect();
        let mut links = Links::singletons((0..500).collect(), &boxes);
        construct(&mut links);
        let mut seen = vec![false; links.bounds.len()];
        for x in links.postorder() {
            assert!(!std::mem::replace(&mut seen[x as usize], true));
        }
        assert!(seen.iter().all(|&s| s));
    }
}
