//! Approximate agglomerative clustering (Gu et al. 2013). The primitives, sorted along a
//! Morton curve, are split by the code's bits (a spatial-median *constraint tree*) down to
//! sets of fewer than δ; each set is clustered greedily (always the pair with the smallest
//! union box area) down to `f(δ)` clusters, and on the way up the two children's clusters
//! are pooled and clustered down to `f(n)` for the n primitives below, until one cluster
//! remains at the root. `f(n) = c·n^α` with `c = δ^(1/2+ε)/2` and `α = 1/2 − ε`.
//!
//! Settings (Gu et al., the thesis's Table 2): *HQ* δ = 20, ε = 0.1; *fast* δ = 4, ε = 0.2.
//! The two halves of a constraint node are independent, so they are built as rayon tasks;
//! each returns its own clusters and nodes, which the parent renumbers in a fixed order, so
//! the tree is the same for any thread count. (The thesis ran AAC on one thread.)

use super::cluster::Links;
use super::morton::{sorted, Curve};
use super::{BuildConfig, BuildNode};
use crate::geometry::Aabb;

/// Below this many primitives a constraint subtree is built on the current thread.
const TASK_MIN: usize = 4096;

/// δ and ε of one AAC setting.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Setting {
    /// Sets of fewer primitives than this are clustered directly.
    pub delta: usize,
    /// Steers how many clusters each level keeps.
    pub epsilon: f64,
}

/// Gu et al.'s high-quality setting.
pub(crate) const HQ: Setting = Setting {
    delta: 20,
    epsilon: 0.1,
};

/// Gu et al.'s fast setting.
pub(crate) const FAST: Setting = Setting {
    delta: 4,
    epsilon: 0.2,
};

impl Setting {
    /// How many clusters a set over `n` primitives is reduced to (at least one).
    fn keep(&self, n: usize) -> usize {
        let c = (self.delta as f64).powf(0.5 + self.epsilon) / 2.0;
        let f = c * (n as f64).powf(0.5 - self.epsilon);
        (f.round() as usize).max(1)
    }
}

pub(super) fn build(
    bounds: &[Aabb],
    idx: Vec<u32>,
    config: &BuildConfig,
    setting: Setting,
    curve: Curve,
) -> (Vec<BuildNode>, Vec<u32>) {
    let (order, codes) = sorted(bounds, &idx, curve);
    let mut links = Links::singletons(order, bounds);
    let job = Job {
        codes: &codes,
        boxes: &links.bounds,
        setting,
    };
    let mut top = job.subtree(0, codes.len());
    top.reduce_to(1);
    // Move the clusters' nodes into the shared tree: local node k (after the units) becomes
    // units + k.
    let units = links.units() as u32;
    for (node, [a, b]) in top.nodes.iter().zip(&top.children) {
        links.bounds.push(*node);
        links.children.push([a.global(units), b.global(units)]);
    }
    links.root = top.clusters[0].global(units);
    links.into_build_tree(bounds, config)
}

/// A node reference inside one subtree's result: a unit (by global index) or one of the
/// subtree's own inner nodes.
#[derive(Clone, Copy, Debug)]
enum Ref {
    Unit(u32),
    Inner(u32),
}

impl Ref {
    fn global(self, units: u32) -> u32 {
        match self {
            Ref::Unit(u) => u,
            Ref::Inner(k) => units + k,
        }
    }

    fn shifted(self, by: u32) -> Ref {
        match self {
            Ref::Inner(k) => Ref::Inner(k + by),
            u => u,
        }
    }
}

/// A constraint subtree's result: the clusters it leaves and the inner nodes it made.
struct Part {
    clusters: Vec<Ref>,
    /// Each cluster's box, parallel to `clusters`.
    boxes: Vec<Aabb>,
    /// Boxes of the inner nodes made here.
    nodes: Vec<Aabb>,
    children: Vec<[Ref; 2]>,
}

struct Job<'a> {
    codes: &'a [u64],
    boxes: &'a [Aabb],
    setting: Setting,
}

impl Job<'_> {
    /// Clusters the units `lo..hi` (sorted by code), split by their codes' bits.
    fn subtree(&self, lo: usize, hi: usize) -> Part {
        let n = hi - lo;
        if n < self.setting.delta {
            let mut part = Part {
                clusters: (lo as u32..hi as u32).map(Ref::Unit).collect(),
                boxes: self.boxes[lo..hi].to_vec(),
                nodes: Vec::new(),
                children: Vec::new(),
            };
            part.reduce_to(self.setting.keep(self.setting.delta));
            return part;
        }
        let mid = self.split(lo, hi);
        let (a, b) = if n >= TASK_MIN {
            rayon::join(|| self.subtree(lo, mid), || self.subtree(mid, hi))
        } else {
            (self.subtree(lo, mid), self.subtree(mid, hi))
        };
        let mut part = a.append(b);
        part.reduce_to(self.setting.keep(n));
        part
    }

    /// Where the range splits: at the highest bit in which its first and last codes differ
    /// (all codes agree above it, being sorted), or in the middle when every code is equal
    /// (coincident centroids).
    fn split(&self, lo: usize, hi: usize) -> usize {
        let codes = &self.codes[lo..hi];
        let diff = codes[0] ^ codes[codes.len() - 1];
        if diff == 0 {
            return lo + codes.len() / 2;
        }
        let top = 63 - diff.leading_zeros();
        lo + codes.partition_point(|c| (c >> top) & 1 == 0)
    }
}

impl Part {
    /// This part's clusters followed by `other`'s, `other`'s inner nodes renumbered after ours.
    fn append(mut self, other: Part) -> Part {
        let by = self.nodes.len() as u32;
        self.clusters
            .extend(other.clusters.iter().map(|r| r.shifted(by)));
        self.boxes.extend(other.boxes);
        self.nodes.extend(other.nodes);
        self.children.extend(
            other
                .children
                .iter()
                .map(|[a, b]| [a.shifted(by), b.shifted(by)]),
        );
        self
    }

    /// Merges the closest pair (smallest union area; ties to the lower positions) until at
    /// most `target` clusters remain. Each cluster remembers its nearest neighbour, and only
    /// clusters whose neighbour was consumed search again.
    fn reduce_to(&mut self, target: usize) {
        let m = self.clusters.len();
        if m <= target {
            return;
        }
        let mut near: Vec<(f32, usize)> = (0..m).map(|i| self.nearest(i)).collect();
        while self.clusters.len() > target {
            let mut best = 0;
            for i in 1..near.len() {
                if near[i].0.total_cmp(&near[best].0).is_lt() {
                    best = i;
                }
            }
            let (a, b) = (best.min(near[best].1), best.max(near[best].1));
            let bounds = self.boxes[a].union(&self.boxes[b]);
            self.nodes.push(bounds);
            self.children.push([self.clusters[a], self.clusters[b]]);
            // The new cluster takes a's place; the last one moves into b's.
            self.clusters[a] = Ref::Inner(self.nodes.len() as u32 - 1);
            self.boxes[a] = bounds;
            // Clusters that pointed at a or b (and the new a) search again.
            let mut stale: Vec<bool> = near.iter().map(|e| e.1 == a || e.1 == b).collect();
            stale[a] = true;
            let last = self.clusters.len() - 1;
            self.clusters.swap_remove(b);
            self.boxes.swap_remove(b);
            near.swap_remove(b);
            stale.swap_remove(b);
            if b != last {
                for entry in near.iter_mut().filter(|e| e.1 == last) {
                    entry.1 = b;
                }
            }
            if self.clusters.len() == 1 {
                break;
            }
            for i in 0..near.len() {
                if stale[i] {
                    near[i] = self.nearest(i);
                }
            }
        }
    }

    /// The cluster whose union with `i` has the smallest area, and that area.
    fn nearest(&self, i: usize) -> (f32, usize) {
        let mut best = (f32::INFINITY, usize::MAX);
        for j in 0..self.boxes.len() {
            if j == i {
                continue;
            }
            let d = self.boxes[i].union(&self.boxes[j]).half_area();
            if best.1 == usize::MAX || d.total_cmp(&best.0).is_lt() {
                best = (d, j);
            }
        }
        best
    }
}
