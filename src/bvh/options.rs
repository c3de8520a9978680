//! [`BuildOptions`]: how a [`Bvh`] is built (builder, layout, leaf size, bins, costs, thread
//! pool, instruction set), with the presets on one axis (fast, default, high quality) and the
//! layout a separate choice.

use super::any_layout::{lay_out, AnyLayout};
use crate::builders::{BuildConfig, BuildTree, Builder, CostModel};
use crate::frame::Frame;
use crate::isa::Isa;
use crate::layout::{Inputs, Layout, LeafPrims};
use crate::primitive::{LeafFormat, Primitive};
use rayon::ThreadPool;

#[cfg(doc)]
use super::Bvh;

/// How to build a [`Bvh`]: which builder, which layout, the build settings and the thread
/// pool. Plain data with chainable setters, given to [`Bvh::build`], [`Bvh::build_mesh`] and
/// [`crate::WorldBuilder::build`]. The presets are one axis, from quick builds to fast
/// traces: [`BuildOptions::fast`], [`BuildOptions::default`] (what [`Bvh::new`] uses) and
/// [`BuildOptions::high_quality`]; the layout is a separate choice ([`BuildOptions::layout`]),
/// and so is any other builder ([`BuildOptions::builder`], e.g. the full-sweep SAH).
///
/// ```
/// use quiver_rt::{builders::Builder, BuildOptions, Bvh, Layout, Triangle};
/// use glam::Vec3A;
/// let tris = vec![Triangle::new(Vec3A::ZERO, Vec3A::X, Vec3A::Y); 100];
/// let pool = rayon::ThreadPoolBuilder::new().num_threads(2).build().unwrap();
/// let options = BuildOptions::default()
///     .builder(Builder::Sweep)
///     .layout(Layout::Bvh2Subtree)
///     .max_leaf_size(4)
///     .thread_pool(&pool);
/// let (bvh, tree) = Bvh::build_with_tree(&tris, &options).unwrap();
/// assert!(tree.stats().max_leaf <= 4);
/// assert!(bvh.footprint().nodes >= tree.stats().nodes);
/// // Half the node bytes of the default layout: a layout, not a preset.
/// let compact = Bvh::build(&tris, &BuildOptions::default().layout(Layout::Bvh4Quant)).unwrap();
/// assert!(compact.footprint().node_bytes < Bvh::new(&tris).footprint().node_bytes);
/// ```
#[derive(Clone, Debug, Default)]
pub struct BuildOptions<'p> {
    /// The tree builder.
    pub builder: Builder,
    /// The memory layout of the nodes.
    pub layout: Layout,
    /// Bins, leaf size, SAH costs, the horizontal/vertical threshold.
    pub config: BuildConfig,
    /// The rayon pool to build on; `None` for the current one (the global pool, or the pool
    /// this is called from inside).
    pub pool: Option<&'p ThreadPool>,
    /// The instruction set the BVH's kernels run on; `None` for [`Isa::detect`] (the best
    /// the CPU has, unless `QUIVER_ISA=portable`). One not supported here falls back to
    /// [`Isa::Portable`]. The 8-wide layout runs every query on it, the 4-wide layouts their
    /// packet queries; the binary layouts have portable kernels only.
    pub isa: Option<Isa>,
}

impl BuildOptions<'static> {
    /// The fast preset, for scenes rebuilt every frame: the linear BVH ([`Builder::Lbvh`]),
    /// one Morton sort and a split per node found by binary search. It builds several times
    /// faster than the default binned SAH, and its tree costs more to trace (both measured in
    /// the repository's docs/builds-and-presets.md).
    ///
    /// ```
    /// use quiver_rt::{BuildOptions, Bvh, Ray, RayQuery, Triangle};
    /// use glam::Vec3A;
    /// let tris: Vec<Triangle> = (0..50)
    ///     .map(|i| {
    ///         let o = Vec3A::new(i as f32, 0.0, 0.0);
    ///         Triangle::new(o, o + Vec3A::X, o + Vec3A::Y)
    ///     })
    ///     .collect();
    /// let bvh = Bvh::build(&tris, &BuildOptions::fast()).unwrap();
    /// let ray = Ray::new(Vec3A::new(7.25, 0.5, 1.0), -Vec3A::Z);
    /// assert_eq!(bvh.closest_hit(&ray).map(|h| h.prim), Some(7));
    /// ```
    pub fn fast() -> Self {
        BuildOptions {
            builder: Builder::Lbvh,
            ..Default::default()
        }
    }

    /// The spatial-split builder ([`Builder::Sbvh`]) with the default layout: object and
    /// spatial split candidates scored by the SAH, so long, thin or overlapping triangles
    /// are cut at split planes instead of stretching boxes over their neighbours. The tree
    /// holds up to 1.3 references per primitive (a split triangle sits in several leaves;
    /// hits still name it once, by its index in the input). Builds take 3.1 to 4.1 times the
    /// default's (docs/spatial-splits.md); traces were faster where triangles are long or
    /// overlap (1.14 to 1.44 times on eye rays), and at most 5% slower elsewhere. A refit
    /// keeps the tree but boxes whole primitives, losing the spatial splits' tightness:
    /// rebuild after large motion.
    ///
    /// ```
    /// use quiver_rt::traverse::reference;
    /// use quiver_rt::{BuildOptions, Bvh, Ray, RayQuery, Triangle};
    /// use glam::Vec3A;
    /// // Long slivers crossing each other, one above the other: spatial splits cut them.
    /// let tris: Vec<Triangle> = (0..64)
    ///     .map(|i| {
    ///         let (y, z) = (i as f32 * 0.1, i as f32 * 0.01);
    ///         let far = Vec3A::new(10.0, 6.4 - y, z);
    ///         Triangle::new(Vec3A::new(0.0, y, z), far, far + Vec3A::Y * 0.05)
    ///     })
    ///     .collect();
    /// let (bvh, tree) = Bvh::build_with_tree(&tris, &BuildOptions::high_quality()).unwrap();
    /// assert!(tree.prim_indices.len() <= tris.len() * 13 / 10);
    /// for i in 0..100 {
    ///     let ray = Ray::new(Vec3A::new(i as f32 * 0.1, 3.2, -1.0), Vec3A::Z);
    ///     assert_eq!(bvh.closest_hit(&ray), reference::closest_hit(&tris, &ray));
    /// }
    /// ```
    pub fn high_quality() -> Self {
        BuildOptions {
            builder: Builder::Sbvh,
            ..Default::default()
        }
    }
}

impl<'p> BuildOptions<'p> {
    /// Uses `builder`.
    pub fn builder(self, builder: Builder) -> Self {
        BuildOptions { builder, ..self }
    }

    /// Lays the nodes out as `layout`.
    pub fn layout(self, layout: Layout) -> Self {
        BuildOptions { layout, ..self }
    }

    /// Makes leaves of at most `n` primitives (`n >= 1`; `bvh4-quant` stores leaf sizes in 16
    /// bits and caps them at 65535).
    pub fn max_leaf_size(mut self, n: usize) -> Self {
        self.config.max_leaf_size = n;
        self
    }

    /// Bins per axis for the binned builder (2 to 1024).
    pub fn bins(mut self, n: usize) -> Self {
        self.config.bins = n;
        self
    }

    /// How splits are scored: the SAH (default) or a ray-termination variant
    /// ([`CostModel`]); the variants weigh each primitive's [`Primitive::surface_area`].
    pub fn cost_model(mut self, model: CostModel) -> Self {
        self.config.cost_model = model;
        self
    }

    /// All build settings at once.
    pub fn config(self, config: BuildConfig) -> Self {
        BuildOptions { config, ..self }
    }

    /// Builds on `pool` instead of the current rayon pool.
    pub fn thread_pool<'q>(self, pool: &'q ThreadPool) -> BuildOptions<'q> {
        BuildOptions {
            builder: self.builder,
            layout: self.layout,
            config: self.config,
            pool: Some(pool),
            isa: self.isa,
        }
    }

    /// Runs the BVH's queries on `isa` (where supported; see [`BuildOptions::isa`]).
    pub fn isa(self, isa: Isa) -> Self {
        BuildOptions {
            isa: Some(isa),
            ..self
        }
    }

    /// Each primitive's surface area (in the build's frame), for a cost model that weighs
    /// them; `None` for the SAH, which does not.
    pub(crate) fn areas<P: Primitive>(&self, prims: &[P]) -> Option<Vec<f32>> {
        use rayon::prelude::*;
        (self.config.cost_model != CostModel::Sah)
            .then(|| prims.par_iter().map(|p| p.surface_area()).collect())
    }

    /// The settings the build runs with over primitives `P`: a `leaf_group` of 0 becomes the
    /// layout's ([`Layout::leaf_group`], 1 for plain primitives), so the SAH counts the
    /// tests the leaves will make; the quantized layout stores leaf sizes in 16 bits, so its
    /// leaves are capped at 65535 primitives.
    pub(crate) fn effective_config<P: Primitive>(&self) -> BuildConfig {
        let mut config = self.config.clone();
        if config.leaf_group == 0 {
            config.leaf_group = match P::LEAF_FORMAT {
                LeafFormat::Plain => 1,
                _ => self.layout.leaf_group(),
            };
        }
        if self.layout == Layout::Bvh4Quant {
            config.max_leaf_size = config.max_leaf_size.min(u16::MAX as usize);
        }
        config
    }

    /// Lays out a checked tree over `prims` (in its leaf order, or read through it).
    pub(crate) fn lay_out<'i, P: Primitive + 'i>(
        &self,
        tree: &BuildTree,
        prims: impl Into<LeafPrims<'i, P>>,
        inputs: Inputs,
    ) -> AnyLayout<P> {
        lay_out(
            self.layout,
            tree,
            prims.into(),
            inputs,
            self.chosen_isa(),
            &self.effective_config::<P>(),
        )
    }

    /// The instruction set asked for, or the detected one.
    pub(crate) fn chosen_isa(&self) -> Isa {
        self.isa.unwrap_or_else(Isa::detect)
    }

    /// The same options, building on the current pool (to be kept past the pool's lifetime).
    pub(crate) fn without_pool(&self) -> BuildOptions<'static> {
        BuildOptions {
            builder: self.builder,
            layout: self.layout,
            config: self.config.clone(),
            pool: None,
            isa: self.isa,
        }
    }

    /// These options on `other`'s pool.
    pub(crate) fn pool_of<'q>(&self, other: &BuildOptions<'q>) -> BuildOptions<'q> {
        BuildOptions {
            pool: other.pool,
            ..self.without_pool()
        }
    }

    /// Runs `f` on the chosen pool.
    pub(crate) fn run<R: Send>(&self, f: impl FnOnce() -> R + Send) -> R {
        match self.pool {
            Some(pool) => pool.install(f),
            None => f(),
        }
    }
}

/// The primitives in `frame`: `None` for the identity frame (use them as they are) and for
/// types that cannot be scaled.
pub(crate) fn frame_prims<P: Primitive>(frame: Frame, prims: &[P]) -> Option<Vec<P>> {
    if frame.is_identity() {
        None
    } else {
        frame.prims(prims)
    }
}
