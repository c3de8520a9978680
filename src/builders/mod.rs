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
//! use quiver_rt::builders::{build, BuildConfig, Builder};
//! use quiver_rt::Aabb;
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
mod builder;
mod cluster;
mod config;
mod cost;
mod insertion;
mod lbvh;
mod morton;
mod ploc;
mod recurse;
mod sbvh;
mod split;
mod sweep;
mod tree;

pub use builder::Builder;
pub use config::{BuildConfig, GROUP_TEST_COST};
pub use cost::CostModel;
pub(crate) use cost::{model_score, split_beats_leaf, Side};
pub(crate) use split::{bounds_of, median_split, widest_axis};
pub(crate) use tree::MEDIAN_DEPTH;
pub use tree::{BuildNode, BuildTree, NodeKind, TreeError, TreeStats, MAX_DEPTH};

use crate::geometry::{Aabb, Triangle};
use crate::primitive::Primitive;

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
/// use quiver_rt::builders::{build_with_areas, BuildConfig, Builder, CostModel};
/// use quiver_rt::Aabb;
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
    build_clipped(bounds, areas, config, builder, None)
}

/// Each primitive's triangle by input index, for the spatial splits of [`Builder::Sbvh`].
#[derive(Clone, Copy)]
pub(crate) struct Triangles<'a> {
    /// The triangle of primitive `i` (`None` for a primitive that has none: its box is
    /// clipped instead).
    pub get: &'a (dyn Fn(u32) -> Option<Triangle> + Sync),
    /// A hint that `get(i)` comes soon, so its memory can be fetched meanwhile: the spatial
    /// pass reads the triangles in the order of a node's references, a gather from the
    /// input. May do nothing.
    pub soon: &'a (dyn Fn(u32) + Sync),
}

/// [`build_with_areas`], with the triangles [`Builder::Sbvh`] clips at its spatial split
/// planes (`None`: it clips the boxes). The other builders ignore them.
pub(crate) fn build_clipped(
    bounds: &[Aabb],
    areas: Option<&[f32]>,
    config: &BuildConfig,
    builder: Builder,
    triangles: Option<Triangles<'_>>,
) -> BuildTree {
    if let Err(e) = config.check() {
        panic!("BuildConfig: {e}");
    }
    if let Some(a) = areas {
        assert_eq!(a.len(), bounds.len(), "one surface area per primitive");
    }
    let indices: Vec<u32> = {
        use rayon::prelude::*;
        (0..bounds.len() as u32)
            .into_par_iter()
            .filter(|&i| bounds[i as usize].is_finite())
            .collect()
    };
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
        let clip = triangles.map_or(sbvh::Clip::Boxes, sbvh::Clip::Triangles);
        build_finite(bounds, areas, indices, config, builder, clip)
    };
    BuildTree {
        nodes,
        prim_indices,
        dropped,
    }
}

/// The chosen builder over the finite primitives `indices` (at least one). `areas` feeds the
/// cost models of the top-down builders (binned and sweep); the bottom-up builders and the
/// clustering ones and the SBVH minimise the plain SAH whatever `config.cost_model` says.
fn build_finite(
    bounds: &[Aabb],
    areas: Option<&[f32]>,
    indices: Vec<u32>,
    config: &BuildConfig,
    builder: Builder,
    clip: sbvh::Clip<'_>,
) -> (Vec<BuildNode>, Vec<u32>) {
    use morton::Curve::{Extended, Morton};
    match builder {
        Builder::Sbvh => sbvh::build(bounds, indices, config, clip),
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
        Builder::Lbvh => lbvh::build(bounds, indices, config),
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
/// use quiver_rt::builders::{build, optimize, BuildConfig, Builder};
/// use quiver_rt::Aabb;
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
///
/// A tree that names a primitive in several leaves ([`Builder::Sbvh`]) is returned as it is:
/// the optimisation moves whole primitives, and merging leaves could name one twice in a leaf.
pub fn optimize(tree: &BuildTree, bounds: &[Aabb], config: &BuildConfig) -> BuildTree {
    if tree.prim_indices.is_empty() || tree.prim_indices.len() + tree.dropped > bounds.len() {
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

/// One bounding box per primitive, the builders' input (computed in parallel). A primitive
/// with a non-finite coordinate gets a NaN box, so the build drops it.
pub fn prim_bounds<P: Primitive>(prims: &[P]) -> Vec<Aabb> {
    use rayon::prelude::*;
    prims.par_iter().map(|p| p.bounds()).collect()
}
