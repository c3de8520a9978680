//! BVH construction over primitive bounds: parallel binned SAH, the full-sweep SAH reference,
//! and the other builders of Frantál's comparison (2019): PLOC, AAC, insertion-based
//! optimisation and construction, extended Morton codes (see [`Builder`]).
//!
//! Every builder takes one [`Aabb`] per primitive and produces a [`BuildTree`]: a binary tree
//! of boxes whose leaves are contiguous ranges of a primitive index array. The tree depends
//! only on the input and the [`BuildConfig`], never on the number of threads: every reduction a
//! build does (box min/max, counts) is exact, every partition is stable, and the clustering
//! builders break every tie by position.
//!
//! ```
//! use quiver::build::{build, BuildConfig, Builder};
//! use quiver::Aabb;
//! use glam::Vec3A;
//! let boxes: Vec<Aabb> = (0..100)
//!     .map(|i| Aabb::new(Vec3A::splat(i as f32), Vec3A::splat(i as f32 + 0.5)))
//!     .collect();
//! let tree = build(&boxes, &BuildConfig::default(), Builder::Binned);
//! tree.validate(&boxes, &BuildConfig::default()).unwrap();
//! assert!(tree.sah_cost(&BuildConfig::default()) > 0.0);
//! ```

mod aac;
mod binned;
mod bonsai;
mod cluster;
mod insertion;
mod morton;
mod ploc;
mod recurse;
mod sweep;

use crate::geometry::{Aabb, Primitive};
use glam::Vec3A;
use std::fmt;

/// Settings shared by the builders.
#[derive(Clone, Debug, PartialEq)]
pub struct BuildConfig {
    /// Bins per axis in the binned builder, 2 to 1024.
    pub bins: usize,
    /// Largest leaf a build may make; nodes above it are always split.
    pub max_leaf_size: usize,
    /// SAH cost of visiting an inner node (c_T).
    pub traversal_cost: f32,
    /// SAH cost of testing one primitive (c_I).
    pub intersection_cost: f32,
    /// Nodes with at least this many primitives are built *horizontally* (all threads bin and
    /// partition the one node); smaller nodes are built *vertically* (each subtree is a task).
    pub horizontal_threshold: usize,
}

impl Default for BuildConfig {
    fn default() -> Self {
        BuildConfig {
            bins: 16,
            max_leaf_size: 8,
            traversal_cost: 1.0,
            intersection_cost: 1.0,
            horizontal_threshold: 1 << 16,
        }
    }
}

impl BuildConfig {
    /// Whether the settings are in range, and if not which one is wrong: what [`build`]
    /// checks before it starts, for callers that take settings from users.
    ///
    /// ```
    /// use quiver::build::BuildConfig;
    /// assert!(BuildConfig::default().check().is_ok());
    /// let bad = BuildConfig { bins: 1, ..BuildConfig::default() };
    /// assert!(bad.check().unwrap_err().contains("bins"));
    /// ```
    pub fn check(&self) -> Result<(), String> {
        if !(2..=1024).contains(&self.bins) {
            return Err(format!("bins must be in 2..=1024, got {}", self.bins));
        }
        if self.max_leaf_size < 1 {
            return Err("max_leaf_size must be at least 1, got 0".into());
        }
        for (name, c) in [
            ("traversal_cost", self.traversal_cost),
            ("intersection_cost", self.intersection_cost),
        ] {
            if !(c.is_finite() && c >= 0.0) {
                return Err(format!("{name} must be a finite number >= 0, got {c}"));
            }
        }
        Ok(())
    }
}

/// Which algorithm builds the tree.
///
/// The bottom-up builders (PLOC, AAC, insertion) build down to one primitive per leaf and
/// then collapse every subtree into a leaf where the SAH prefers it and it fits in
/// [`BuildConfig::max_leaf_size`] (Bittner et al.'s compaction), so their trees obey the same
/// leaf limit as the top-down ones. Parameters are those of Frantál's Table 8.
///
/// ```
/// use quiver::build::Builder;
/// assert_eq!(Builder::default(), Builder::Binned);
/// assert_eq!("sweep".parse::<Builder>(), Ok(Builder::Sweep));
/// assert_eq!("ploc10".parse::<Builder>(), Ok(Builder::Ploc10));
/// ```
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Builder {
    /// Parallel binned SAH (horizontal near the root, vertical below). The default.
    #[default]
    Binned,
    /// Full-sweep SAH: every primitive boundary is a candidate plane. The quality reference.
    Sweep,
    /// The binned tree built to single-primitive leaves, improved by the insertion-based
    /// optimisation ([`optimize`]), then compacted into SAH leaves.
    BinnedOpt,
    /// The full-sweep tree, optimised the same way (the thesis's FSWO).
    SweepOpt,
    /// Parallel locally-ordered clustering (Meister and Bittner 2018), search radius 10.
    Ploc10,
    /// PLOC with search radius 25.
    Ploc25,
    /// PLOC with search radius 100.
    Ploc100,
    /// PLOC (radius 10) over extended Morton codes (EMC-64-var, Vinkler et al. 2017).
    Ploc10Emc,
    /// Approximate agglomerative clustering (Gu et al. 2013), fast setting: δ = 4, ε = 0.2.
    AacFast,
    /// AAC, high-quality setting: δ = 20, ε = 0.1.
    AacHq,
    /// AAC-HQ over extended Morton codes.
    AacHqEmc,
    /// Bonsai (Ganestam et al. 2015): spatial-median groups of 512, full-sweep mini trees,
    /// a full-sweep top tree over them; no pruning.
    Bonsai,
    /// BonsaiP: groups of 512, mini trees larger than 0.1 × the mean pruned.
    BonsaiP,
    /// BonsaiP*: groups of 4096, pruning threshold 0.01 × the mean.
    BonsaiP4096,
    /// Insertion-based construction (Bittner et al. 2015): batch 8000, 1% of nodes
    /// optimised per batch, coherence threshold 1.5. Sequential.
    Insertion,
}

impl Builder {
    /// Every builder, in the order reports list them.
    pub const ALL: [Builder; 15] = [
        Builder::Binned,
        Builder::Sweep,
        Builder::BinnedOpt,
        Builder::SweepOpt,
        Builder::Ploc10,
        Builder::Ploc25,
        Builder::Ploc100,
        Builder::Ploc10Emc,
        Builder::AacFast,
        Builder::AacHq,
        Builder::AacHqEmc,
        Builder::Bonsai,
        Builder::BonsaiP,
        Builder::BonsaiP4096,
        Builder::Insertion,
    ];

    /// The name used on the command line and in reports.
    pub fn name(self) -> &'static str {
        match self {
            Builder::Binned => "binned",
            Builder::Sweep => "sweep",
            Builder::BinnedOpt => "binned+opt",
            Builder::SweepOpt => "sweep+opt",
            Builder::Ploc10 => "ploc10",
            Builder::Ploc25 => "ploc25",
            Builder::Ploc100 => "ploc100",
            Builder::Ploc10Emc => "ploc10-emc",
            Builder::AacFast => "aac-fast",
            Builder::AacHq => "aac-hq",
            Builder::AacHqEmc => "aac-hq-emc",
            Builder::Bonsai => "bonsai",
            Builder::BonsaiP => "bonsai-p",
            Builder::BonsaiP4096 => "bonsai-p4096",
            Builder::Insertion => "insertion",
        }
    }
}

impl fmt::Display for Builder {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for Builder {
    type Err = String;

    /// A builder by its [`Builder::name`]; the error lists the names.
    fn from_str(s: &str) -> Result<Self, String> {
        Builder::ALL
            .into_iter()
            .find(|b| b.name() == s)
            .ok_or_else(|| {
                let names: Vec<&str> = Builder::ALL.iter().map(|b| b.name()).collect();
                format!(
                    "unknown builder '{s}': expected one of {}",
                    names.join(", ")
                )
            })
    }
}

/// What a node of the [`BuildTree`] is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum NodeKind {
    /// An inner node with two children (indices into [`BuildTree::nodes`]).
    Inner {
        /// Left child.
        left: u32,
        /// Right child.
        right: u32,
    },
    /// A leaf holding `prim_indices[first .. first + count]`.
    Leaf {
        /// First slot in [`BuildTree::prim_indices`].
        first: u32,
        /// Number of primitives.
        count: u32,
    },
}

/// One node of the intermediate tree.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BuildNode {
    /// Bounds of everything below.
    pub bounds: Aabb,
    /// Inner or leaf.
    pub kind: NodeKind,
}

/// The builders' output: a binary tree in depth-first preorder (root at 0, a left child right
/// after its parent) whose leaves index ranges of `prim_indices`.
#[derive(Clone, Debug, PartialEq)]
pub struct BuildTree {
    /// Nodes in depth-first preorder.
    pub nodes: Vec<BuildNode>,
    /// Input primitive indices in leaf order.
    pub prim_indices: Vec<u32>,
    /// Primitives left out because their bounds were not finite.
    pub dropped: usize,
}

/// Counts that describe a tree's shape.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TreeStats {
    /// All nodes.
    pub nodes: usize,
    /// Leaves.
    pub leaves: usize,
    /// Longest root-to-leaf path in edges.
    pub depth: usize,
    /// Largest leaf.
    pub max_leaf: usize,
}

/// Builds a tree over `bounds` (one box per primitive) on the current rayon thread pool.
///
/// Primitives whose box is not finite (a NaN or infinite coordinate) are dropped and counted in
/// [`BuildTree::dropped`]; an empty input gives a single empty leaf.
///
/// # Panics
/// When [`BuildConfig::check`] finds a setting out of range (call it first to report the
/// error instead).
pub fn build(bounds: &[Aabb], config: &BuildConfig, builder: Builder) -> BuildTree {
    if let Err(e) = config.check() {
        panic!("BuildConfig: {e}");
    }
    let indices: Vec<u32> = (0..bounds.len() as u32)
        .filter(|&i| is_finite(&bounds[i as usize]))
        .collect();
    let dropped = bounds.len() - indices.len();
    let (nodes, prim_indices) = if indices.is_empty() {
        let empty = BuildNode {
            bounds: Aabb::EMPTY,
            kind: NodeKind::Leaf { first: 0, count: 0 },
        };
        (vec![empty], indices)
    } else {
        build_finite(bounds, indices, config, builder)
    };
    BuildTree {
        nodes,
        prim_indices,
        dropped,
    }
}

/// The chosen builder over the finite primitives `indices` (at least one).
fn build_finite(
    bounds: &[Aabb],
    indices: Vec<u32>,
    config: &BuildConfig,
    builder: Builder,
) -> (Vec<BuildNode>, Vec<u32>) {
    use morton::Curve::{Extended, Morton};
    match builder {
        Builder::Binned => binned::build(bounds, indices, config),
        Builder::Sweep => sweep::build(bounds, indices, config),
        Builder::BinnedOpt | Builder::SweepOpt => {
            let singles = BuildConfig {
                max_leaf_size: 1,
                ..config.clone()
            };
            let (nodes, prims) = if builder == Builder::BinnedOpt {
                binned::build(bounds, indices, &singles)
            } else {
                sweep::build(bounds, indices, &singles)
            };
            let mut links = cluster::from_build_tree(&nodes, &prims);
            insertion::optimize(&mut links);
            links.into_build_tree(bounds, config)
        }
        Builder::Ploc10 => ploc::build(bounds, indices, config, 10, Morton),
        Builder::Ploc25 => ploc::build(bounds, indices, config, 25, Morton),
        Builder::Ploc100 => ploc::build(bounds, indices, config, 100, Morton),
        Builder::Ploc10Emc => ploc::build(bounds, indices, config, 10, Extended),
        Builder::AacFast => aac::build(bounds, indices, config, aac::FAST, Morton),
        Builder::AacHq => aac::build(bounds, indices, config, aac::HQ, Morton),
        Builder::AacHqEmc => aac::build(bounds, indices, config, aac::HQ, Extended),
        Builder::Bonsai => bonsai::build(bounds, indices, config, bonsai::PLAIN),
        Builder::BonsaiP => bonsai::build(bounds, indices, config, bonsai::PRUNED),
        Builder::BonsaiP4096 => bonsai::build(bounds, indices, config, bonsai::PRUNED_4096),
        Builder::Insertion => {
            let mut links = cluster::Links::singletons(indices, bounds);
            insertion::construct(&mut links);
            links.into_build_tree(bounds, config)
        }
    }
}

/// Bittner et al.'s insertion-based optimisation as a pass over any tree: its leaves stay as
/// they are, the inner nodes are rearranged to lower the SAH cost, and subtrees are then
/// collapsed into leaves where that is cheaper (within `config.max_leaf_size`). `bounds` are
/// the boxes the tree was built from. [`Builder::BinnedOpt`] applies it to a binned tree
/// built down to single primitives, which leaves it more to rearrange.
///
/// ```
/// use quiver::build::{build, optimize, BuildConfig, Builder};
/// use quiver::Aabb;
/// use glam::Vec3A;
/// let boxes: Vec<Aabb> = (0..200)
///     .map(|i| {
///         let p = Vec3A::new((i * 37 % 101) as f32, (i * 13 % 7) as f32, 0.0);
///         Aabb::new(p, p + Vec3A::splat(0.5))
///     })
///     .collect();
/// let config = BuildConfig::default();
/// let tree = build(&boxes, &config, Builder::Binned);
/// let better = optimize(&tree, &boxes, &config);
/// better.validate(&boxes, &config).unwrap();
/// assert!(better.sah_cost(&config) <= tree.sah_cost(&config) * 1.0001);
/// ```
pub fn optimize(tree: &BuildTree, bounds: &[Aabb], config: &BuildConfig) -> BuildTree {
    if tree.prim_indices.is_empty() {
        return tree.clone();
    }
    let mut links = cluster::from_build_tree(&tree.nodes, &tree.prim_indices);
    insertion::optimize(&mut links);
    let (nodes, prim_indices) = links.into_build_tree(bounds, config);
    BuildTree {
        nodes,
        prim_indices,
        dropped: tree.dropped,
    }
}

fn is_finite(b: &Aabb) -> bool {
    b.is_finite()
}

/// One bounding box per primitive, the builders' input (computed in parallel). A primitive
/// with a non-finite coordinate gets a NaN box, so the build drops it.
pub fn prim_bounds<P: Primitive>(prims: &[P]) -> Vec<Aabb> {
    use rayon::prelude::*;
    prims.par_iter().map(|p| p.bounds()).collect()
}

/// Depth below which builders stop trusting the SAH and split at the object median, so that a
/// pathological input (exponentially spaced centroids) cannot make the tree linear. With it the
/// depth stays below `MEDIAN_DEPTH + log2(n) + 1`, which bounds every traversal stack.
pub(crate) const MEDIAN_DEPTH: usize = 48;

/// The deepest tree any builder makes for up to 2^32 primitives; traversal stacks use it.
pub const MAX_DEPTH: usize = MEDIAN_DEPTH + 33;

/// SAH cost of splitting a node of area `parent_area` into children with area·count products
/// summing to `weighted`, compared with making it a leaf of `n` primitives.
pub(crate) fn split_beats_leaf(
    config: &BuildConfig,
    parent_area: f32,
    weighted: f32,
    n: usize,
) -> bool {
    split_cost(config, parent_area, weighted, n) < config.intersection_cost * n as f32
}

/// `c_T + c_I * weighted / A_P`; a zero-area parent (every primitive at one point) makes each
/// child as likely to be hit as the parent.
pub(crate) fn split_cost(config: &BuildConfig, parent_area: f32, weighted: f32, n: usize) -> f32 {
    let ratio = if parent_area > 0.0 {
        weighted / parent_area
    } else {
        n as f32
    };
    config.traversal_cost + config.intersection_cost * ratio
}

/// Bounds and centroid bounds of a set of primitives.
pub(crate) fn bounds_of(bounds: &[Aabb], idx: &[u32]) -> (Aabb, Aabb) {
    let mut b = Aabb::EMPTY;
    let mut c = Aabb::EMPTY;
    for &i in idx {
        let pb = bounds[i as usize];
        b = b.union(&pb);
        c.grow(pb.center());
    }
    (b, c)
}

/// Splits `idx` at its median along the widest centroid axis (ties broken by index, so the
/// result is a function of the input alone). Returns the size of the left half.
pub(crate) fn median_split(bounds: &[Aabb], idx: &mut [u32], centroid_bounds: &Aabb) -> usize {
    let axis = widest_axis(centroid_bounds.extent());
    idx.sort_unstable_by(|&a, &b| {
        let ca = bounds[a as usize].center()[axis];
        let cb = bounds[b as usize].center()[axis];
        ca.total_cmp(&cb).then(a.cmp(&b))
    });
    idx.len() / 2
}

pub(crate) fn widest_axis(e: Vec3A) -> usize {
    if e.x >= e.y && e.x >= e.z {
        0
    } else if e.y >= e.z {
        1
    } else {
        2
    }
}

impl BuildTree {
    /// The same tree with its boxes recomputed bottom-up from `bounds` (one per input
    /// primitive): the tree of a build made in a BVH's scaled frame, told in the caller's units.
    pub(crate) fn refit(&self, bounds: &[Aabb]) -> BuildTree {
        let mut nodes = self.nodes.clone();
        // Preorder: every child comes after its parent, so a reverse sweep sees children first.
        for i in (0..nodes.len()).rev() {
            nodes[i].bounds = match nodes[i].kind {
                NodeKind::Leaf { first, count } => self.prim_indices
                    [first as usize..(first + count) as usize]
                    .iter()
                    .fold(Aabb::EMPTY, |b, &p| b.union(&bounds[p as usize])),
                NodeKind::Inner { left, right } => nodes[left as usize]
                    .bounds
                    .union(&nodes[right as usize].bounds),
            };
        }
        BuildTree {
            nodes,
            prim_indices: self.prim_indices.clone(),
            dropped: self.dropped,
        }
    }

    /// Shape counts: nodes, leaves, depth, largest leaf.
    pub fn stats(&self) -> TreeStats {
        let mut s = TreeStats {
            nodes: self.nodes.len(),
            ..TreeStats::default()
        };
        let mut stack = vec![(0usize, 0usize)];
        while let Some((i, d)) = stack.pop() {
            s.depth = s.depth.max(d);
            match self.nodes[i].kind {
                NodeKind::Inner { left, right } => {
                    stack.push((left as usize, d + 1));
                    stack.push((right as usize, d + 1));
                }
                NodeKind::Leaf { count, .. } => {
                    s.leaves += 1;
                    s.max_leaf = s.max_leaf.max(count as usize);
                }
            }
        }
        s
    }

    /// SAH cost `c_T * ΣA(inner)/A(root) + c_I * Σ A(leaf)·n(leaf)/A(root)`.
    ///
    /// A root of zero area (all geometry on one point or line) makes every node equally likely:
    /// the cost becomes `c_T * inner_nodes + c_I * references`.
    pub fn sah_cost(&self, config: &BuildConfig) -> f64 {
        let root_area = self.nodes[0].bounds.half_area() as f64;
        let area = |b: &Aabb| {
            if root_area > 0.0 {
                b.half_area() as f64 / root_area
            } else {
                1.0
            }
        };
        self.nodes
            .iter()
            .map(|n| match n.kind {
                NodeKind::Inner { .. } => config.traversal_cost as f64 * area(&n.bounds),
                NodeKind::Leaf { count, .. } => {
                    config.intersection_cost as f64 * area(&n.bounds) * count as f64
                }
            })
            .sum()
    }

    /// Checks the invariants every build must keep, given the boxes and configuration it was
    /// built from: every node reachable exactly once from the root, every finite primitive
    /// referenced exactly once (and no other), no leaf above `config.max_leaf_size`, every
    /// parent box containing its children, every leaf box containing its primitives.
    /// Returns a description of the first violation.
    pub fn validate(&self, bounds: &[Aabb], config: &BuildConfig) -> Result<(), String> {
        let mut seen_node = vec![false; self.nodes.len()];
        let mut seen_prim = vec![false; bounds.len()];
        let mut refs = 0usize;
        let mut stack = vec![0usize];
        while let Some(i) = stack.pop() {
            let node = self
                .nodes
                .get(i)
                .ok_or(format!("child index {i} out of range"))?;
            if std::mem::replace(&mut seen_node[i], true) {
                return Err(format!("node {i} reached twice"));
            }
            match node.kind {
                NodeKind::Inner { left, right } => {
                    for c in [left as usize, right as usize] {
                        let child = self
                            .nodes
                            .get(c)
                            .ok_or(format!("node {i}: child {c} out of range"))?;
                        if !node.bounds.contains(&child.bounds) {
                            return Err(format!("node {i} does not contain child {c}"));
                        }
                        stack.push(c);
                    }
                }
                NodeKind::Leaf { first, count } => {
                    if count as usize > config.max_leaf_size {
                        return Err(format!("leaf {i} holds {count} > {}", config.max_leaf_size));
                    }
                    let range = first as usize..(first + count) as usize;
                    let ids = self
                        .prim_indices
                        .get(range)
                        .ok_or(format!("leaf {i}: range out of bounds"))?;
                    for &p in ids {
                        let pb = bounds
                            .get(p as usize)
                            .ok_or(format!("leaf {i}: primitive {p} out of range"))?;
                        if std::mem::replace(&mut seen_prim[p as usize], true) {
                            return Err(format!("primitive {p} referenced twice"));
                        }
                        if !node.bounds.contains(pb) {
                            return Err(format!("leaf {i} does not contain primitive {p}"));
                        }
                        refs += 1;
                    }
                }
            }
        }
        if let Some(i) = seen_node.iter().position(|&s| !s) {
            return Err(format!("node {i} unreachable"));
        }
        for (p, b) in bounds.iter().enumerate() {
            if is_finite(b) != seen_prim[p] {
                return Err(format!(
                    "primitive {p} (finite: {}) referenced: {}",
                    is_finite(b),
                    seen_prim[p]
                ));
            }
        }
        if refs != self.prim_indices.len() || refs + self.dropped != bounds.len() {
            return Err(format!(
                "{refs} references, {} indices, {} dropped, {} primitives",
                self.prim_indices.len(),
                self.dropped,
                bounds.len()
            ));
        }
        Ok(())
    }
}
