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
    /// How a split is scored: the plain SAH (the default), or one of Moulin and Dutré's
    /// variants for rays that terminate ([`CostModel`]).
    pub cost_model: CostModel,
}

/// The cost a builder minimises when it picks a split, for both builders.
///
/// The SAH assumes rays that never stop. Moulin and Dutré ("On the use of local ray
/// termination for efficiently constructing qualitative BSPs, BIHs and (S)BVHs") adapt it to
/// rays that end at their first hit. Both variants here use their *average projected surface
/// area* (APSA) approximation of the chance that a ray crossing a child's box hits one of its
/// primitives: `H = min(ΣSA(primitives) / SA(box), 1)` (their equation 5.19), which needs each
/// primitive's surface area ([`crate::Primitive::surface_area`]).
///
/// ```
/// use quiver::build::CostModel;
/// assert_eq!(CostModel::default(), CostModel::Sah);
/// assert_eq!("rtsah".parse::<CostModel>(), Ok(CostModel::Rtsah));
/// ```
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum CostModel {
    /// `c_T + c_I·(p_L·n_L + p_R·n_R)` with `p = SA(child) / SA(parent)`.
    #[default]
    Sah,
    /// The ray termination SAH (their equation 3.4) with local ray termination: of the rays
    /// that pierce both children, half meet the left one first (`p_fL = p_fR = 1/2`), and
    /// those stopped there never test the right one's primitives (probability `H_L`, APSA).
    /// The share of rays piercing both children, `p_L↔R`, is taken as
    /// `max(0, p_L + p_R - 1)`: exact when the children tile the parent (a BSP split), a
    /// lower bound for a BVH's children (their grid-transport estimate is not built), so
    /// splits whose children's areas do not sum past the parent's are scored as by the SAH.
    /// Also decides when a node becomes a leaf.
    Rtsah,
    /// The shadow ray distribution heuristic (their equation 3.23), a gain to maximise for
    /// any-hit rays: `max(p_L·H_L·(c + p_R·n_R), p_R·H_R·(c + p_L·n_L))` (the tests saved when
    /// the child visited first stops the ray), with `c = c_T / c_I` as the box test's cost
    /// relative to a primitive's. Leaves are decided by the SAH of the chosen split. quiver's
    /// kernels keep their own child order (nearest first, or slot order for any hit), so
    /// the traversal-order half of SRDH is not used.
    Srdh,
}

impl CostModel {
    /// Every cost model, in the order reports list them.
    pub const ALL: [CostModel; 3] = [CostModel::Sah, CostModel::Rtsah, CostModel::Srdh];

    /// The name used on the command line and in reports.
    pub fn name(self) -> &'static str {
        match self {
            CostModel::Sah => "sah",
            CostModel::Rtsah => "rtsah",
            CostModel::Srdh => "srdh",
        }
    }
}

impl fmt::Display for CostModel {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for CostModel {
    type Err = String;

    /// A cost model by its [`CostModel::name`]; the error lists the names.
    fn from_str(s: &str) -> Result<Self, String> {
        by_name(s, &CostModel::ALL, CostModel::name, "cost model")
    }
}

/// The item of `all` called `s`; the error names `what` and lists the names.
fn by_name<T: Copy>(
    s: &str,
    all: &[T],
    name: fn(T) -> &'static str,
    what: &str,
) -> Result<T, String> {
    all.iter().copied().find(|&x| name(x) == s).ok_or_else(|| {
        let names: Vec<&str> = all.iter().map(|&x| name(x)).collect();
        format!("unknown {what} '{s}': expected one of {}", names.join(", "))
    })
}

/// One side of a candidate split as the cost models see it.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Side {
    /// Half the surface area of the side's box.
    pub half_area: f32,
    /// Primitives on the side.
    pub count: usize,
    /// Σ surface area of those primitives.
    pub prim_area: f32,
}

impl Side {
    /// APSA: the chance that a ray crossing the box hits one of the primitives.
    fn hit_chance(&self) -> f32 {
        if self.half_area > 0.0 {
            (self.prim_area / (2.0 * self.half_area)).min(1.0)
        } else if self.prim_area > 0.0 {
            1.0
        } else {
            0.0
        }
    }
}

/// A candidate split's score under `config.cost_model`, lower is better, and its weighted
/// child cost for the leaf test ([`split_beats_leaf`]): `(score, weighted)`. For the SAH
/// both are `Σ half area · count`.
pub(crate) fn model_score(
    config: &BuildConfig,
    parent_area: f32,
    l: &Side,
    r: &Side,
) -> (f32, f32) {
    let sah = l.half_area * l.count as f32 + r.half_area * r.count as f32;
    match config.cost_model {
        CostModel::Sah => (sah, sah),
        CostModel::Rtsah => {
            // p_L↔R · A_P, and the tests each side's primitives are spared by the other.
            let both = (l.half_area + r.half_area - parent_area).max(0.0);
            let spared =
                0.5 * both * (r.hit_chance() * l.count as f32 + l.hit_chance() * r.count as f32);
            (sah - spared, sah - spared)
        }
        CostModel::Srdh => {
            let c = if config.intersection_cost > 0.0 {
                config.traversal_cost / config.intersection_cost
            } else {
                1.0
            };
            let p = |s: &Side| {
                if parent_area > 0.0 {
                    s.half_area / parent_area
                } else {
                    1.0
                }
            };
            let gain = (p(l) * l.hit_chance() * (c + p(r) * r.count as f32))
                .max(p(r) * r.hit_chance() * (c + p(l) * l.count as f32));
            (-gain, sah)
        }
    }
}

impl Default for BuildConfig {
    fn default() -> Self {
        BuildConfig {
            bins: 16,
            max_leaf_size: 8,
            traversal_cost: 1.0,
            intersection_cost: 1.0,
            horizontal_threshold: 1 << 16,
            cost_model: CostModel::Sah,
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
        by_name(s, &Builder::ALL, Builder::name, "builder")
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
/// [`BuildTree::dropped`]; an empty input gives a single empty leaf. A cost model other than
/// the SAH needs each primitive's surface area: here it is taken from its box (see
/// [`build_with_areas`] to give the real ones).
///
/// # Panics
/// When [`BuildConfig::check`] finds a setting out of range (call it first to report the
/// error instead).
pub fn build(bounds: &[Aabb], config: &BuildConfig, builder: Builder) -> BuildTree {
    build_with_areas(bounds, None, config, builder)
}

/// [`build`] with each primitive's surface area (`areas[i]` for `bounds[i]`), which the cost
/// models other than the SAH weigh ([`CostModel`]); the SAH ignores them. Without areas a
/// primitive's box's half surface area stands in (a flat primitive's two sides, exact for a
/// right triangle spanning its box's largest face, more otherwise).
///
/// # Panics
/// As [`build`], and when `areas` is given with another length than `bounds`.
///
/// ```
/// use quiver::build::{build_with_areas, BuildConfig, Builder, CostModel};
/// use quiver::Aabb;
/// use glam::Vec3A;
/// let boxes: Vec<Aabb> = (0..100)
///     .map(|i| Aabb::new(Vec3A::splat(i as f32), Vec3A::splat(i as f32 + 0.5)))
///     .collect();
/// let areas = vec![0.1; 100];
/// let config = BuildConfig { cost_model: CostModel::Rtsah, ..BuildConfig::default() };
/// let tree = build_with_areas(&boxes, Some(&areas), &config, Builder::Sweep);
/// tree.validate(&boxes, &config).unwrap();
/// ```
pub fn build_with_areas(
    bounds: &[Aabb],
    areas: Option<&[f32]>,
    config: &BuildConfig,
    builder: Builder,
) -> BuildTree {
    if let Err(e) = config.check() {
        panic!("BuildConfig: {e}");
    }
    if let Some(a) = areas {
        assert_eq!(a.len(), bounds.len(), "one surface area per primitive");
    }
    let indices: Vec<u32> = (0..bounds.len() as u32)
        .filter(|&i| is_finite(&bounds[i as usize]))
        .collect();
    let dropped = bounds.len() - indices.len();
    // The SAH never reads areas; the other models get the given ones or the boxes' stand-in.
    let proxy: Vec<f32>;
    let areas = match (config.cost_model, areas) {
        (CostModel::Sah, _) => None,
        (_, Some(a)) => Some(a),
        (_, None) => {
            use rayon::prelude::*;
            proxy = bounds.par_iter().map(|b| b.half_area()).collect();
            Some(&proxy[..])
        }
    };
    let (nodes, prim_indices) = if indices.is_empty() {
        let empty = BuildNode {
            bounds: Aabb::EMPTY,
            kind: NodeKind::Leaf { first: 0, count: 0 },
        };
        (vec![empty], indices)
    } else {
        build_finite(bounds, areas, indices, config, builder)
    };
    BuildTree {
        nodes,
        prim_indices,
        dropped,
    }
}

/// The chosen builder over the finite primitives `indices` (at least one). `areas` feeds the
/// cost models of the top-down builders (binned and sweep); the bottom-up builders and the
/// clustering ones minimise the plain SAH whatever `config.cost_model` says.
fn build_finite(
    bounds: &[Aabb],
    areas: Option<&[f32]>,
    indices: Vec<u32>,
    config: &BuildConfig,
    builder: Builder,
) -> (Vec<BuildNode>, Vec<u32>) {
    use morton::Curve::{Extended, Morton};
    match builder {
        Builder::Binned => binned::build(bounds, areas, indices, config),
        Builder::Sweep => sweep::build(bounds, areas, indices, config),
        Builder::BinnedOpt | Builder::SweepOpt => {
            let singles = BuildConfig {
                max_leaf_size: 1,
                ..config.clone()
            };
            let (nodes, prims) = if builder == Builder::BinnedOpt {
                binned::build(bounds, areas, indices, &singles)
            } else {
                sweep::build(bounds, areas, indices, &singles)
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
