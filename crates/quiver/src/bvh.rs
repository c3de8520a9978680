//! The front door: [`Bvh`], a BVH in any [`Layout`], built by [`Bvh::new`] with sensible
//! defaults or by [`BuildOptions`] with every choice (builder, layout, leaf size, bins, thread
//! pool), from a primitive slice or an indexed mesh.

use crate::build::{build, prim_bounds, BuildConfig, BuildTree, Builder};
use crate::geometry::{Hit, Primitive, Ray, Triangle};
use crate::isa::Isa;
use crate::layout::bvh2::leaf_order;
use crate::layout::{Bvh2, Bvh4, Bvh8, Footprint, Layout, QBvh4};
use crate::mesh::{Mesh, MeshError};
use crate::traverse::{BoxTest, PacketMode, RayQuery, Stats};
use rayon::ThreadPool;

/// A laid-out BVH in any [`Layout`], answering every query of [`RayQuery`].
///
/// ```
/// use quiver::{reference, BuildOptions, Bvh, Layout, Ray, RayQuery, Triangle};
/// use glam::Vec3A;
/// let tris: Vec<Triangle> = (0..50)
///     .map(|i| {
///         let o = Vec3A::new(i as f32, 0.0, -(i as f32));
///         Triangle::new(o, o + Vec3A::X, o + Vec3A::Y)
///     })
///     .collect();
/// let ray = Ray::new(Vec3A::new(7.25, 0.5, 5.0), -Vec3A::Z);
/// let default = Bvh::new(&tris);
/// assert_eq!(default.closest_hit(&ray).map(|h| h.prim), Some(7));
/// for layout in Layout::ALL {
///     let bvh = BuildOptions::default().layout(layout).build(&tris);
///     assert_eq!(bvh.closest_hit(&ray), reference::closest_hit(&tris, &ray));
/// }
/// ```
#[derive(Clone, Debug)]
pub enum Bvh<P = Triangle> {
    /// Binary nodes.
    Bvh2(Bvh2<P>),
    /// 4-wide exact nodes.
    Bvh4(Bvh4<P>),
    /// 4-wide quantized nodes.
    QBvh4(QBvh4<P>),
    /// 8-wide exact nodes.
    Bvh8(Bvh8<P>),
}

impl<P: Primitive> Bvh<P> {
    /// Builds over `prims` with the default [`BuildOptions`]: binned SAH, leaves of up to 8,
    /// the default layout (`bvh8-dfs`), on the current rayon thread pool. Hits report each
    /// primitive's index in `prims`.
    pub fn new(prims: &[P]) -> Self {
        BuildOptions::default().build(prims)
    }

    /// Lays out a built tree over `prims` (the build's input) as `layout`, for the
    /// instruction set [`Isa::detect`] picks.
    pub fn from_tree(tree: &BuildTree, prims: &[P], layout: Layout) -> Self {
        layout.lay_out(
            tree,
            leaf_order(tree, prims),
            Isa::detect(),
            &BuildConfig::default(),
        )
    }

    /// The instruction set queries run on: the BVH's own for 8-wide nodes, portable for the
    /// others (they have no AVX2 kernels).
    pub fn isa(&self) -> Isa {
        match self {
            Bvh::Bvh8(b) => b.isa,
            _ => Isa::Portable,
        }
    }

    /// The same BVH traversed with `isa` where it has kernels for it (see [`Bvh::isa`]).
    pub fn with_isa(self, isa: Isa) -> Self {
        match self {
            Bvh::Bvh8(b) => Bvh::Bvh8(b.with_isa(isa)),
            other => other,
        }
    }

    /// What the nodes and leaves occupy.
    pub fn footprint(&self) -> Footprint {
        match self {
            Bvh::Bvh2(b) => b.footprint(),
            Bvh::Bvh4(b) => b.footprint(),
            Bvh::QBvh4(b) => b.footprint(),
            Bvh::Bvh8(b) => b.footprint(),
        }
    }
}

impl Bvh {
    /// Builds over an indexed triangle mesh with the default [`BuildOptions`]: triangle `i`
    /// has corners `positions[indices[i][0]]`, `…[1]]`, `…[2]]`, and hits report `i`. The
    /// buffers are read in place; the BVH keeps its own copy of the triangles in leaf order.
    ///
    /// # Errors
    /// [`MeshError`] when an index names no vertex, or there are more than `u32::MAX`
    /// triangles.
    pub fn from_mesh(positions: &[[f32; 3]], indices: &[[u32; 3]]) -> Result<Self, MeshError> {
        BuildOptions::default().build_mesh(positions, indices)
    }
}

impl<P: Primitive> RayQuery for Bvh<P> {
    #[inline]
    fn closest_hit_with<B: BoxTest, S: Stats>(&self, ray: &Ray, stats: &mut S) -> Option<Hit> {
        match self {
            Bvh::Bvh2(b) => b.closest_hit_with::<B, S>(ray, stats),
            Bvh::Bvh4(b) => b.closest_hit_with::<B, S>(ray, stats),
            Bvh::QBvh4(b) => b.closest_hit_with::<B, S>(ray, stats),
            Bvh::Bvh8(b) => b.closest_hit_with::<B, S>(ray, stats),
        }
    }

    #[inline]
    fn any_hit_with<B: BoxTest, S: Stats>(&self, ray: &Ray, stats: &mut S) -> bool {
        match self {
            Bvh::Bvh2(b) => b.any_hit_with::<B, S>(ray, stats),
            Bvh::Bvh4(b) => b.any_hit_with::<B, S>(ray, stats),
            Bvh::QBvh4(b) => b.any_hit_with::<B, S>(ray, stats),
            Bvh::Bvh8(b) => b.any_hit_with::<B, S>(ray, stats),
        }
    }

    fn closest_hit_packet_with<B: BoxTest, S: Stats>(
        &self,
        rays: &[Ray],
        active: Option<&[bool]>,
        mode: PacketMode,
        hits: &mut [Option<Hit>],
        stats: &mut S,
    ) {
        match self {
            Bvh::Bvh2(b) => b.closest_hit_packet_with::<B, S>(rays, active, mode, hits, stats),
            Bvh::Bvh4(b) => b.closest_hit_packet_with::<B, S>(rays, active, mode, hits, stats),
            Bvh::QBvh4(b) => b.closest_hit_packet_with::<B, S>(rays, active, mode, hits, stats),
            Bvh::Bvh8(b) => b.closest_hit_packet_with::<B, S>(rays, active, mode, hits, stats),
        }
    }

    fn any_hit_packet_with<B: BoxTest, S: Stats>(
        &self,
        rays: &[Ray],
        active: Option<&[bool]>,
        mode: PacketMode,
        occluded: &mut [bool],
        stats: &mut S,
    ) {
        match self {
            Bvh::Bvh2(b) => b.any_hit_packet_with::<B, S>(rays, active, mode, occluded, stats),
            Bvh::Bvh4(b) => b.any_hit_packet_with::<B, S>(rays, active, mode, occluded, stats),
            Bvh::QBvh4(b) => b.any_hit_packet_with::<B, S>(rays, active, mode, occluded, stats),
            Bvh::Bvh8(b) => b.any_hit_packet_with::<B, S>(rays, active, mode, occluded, stats),
        }
    }
}

/// How to build a [`Bvh`]: which builder, which layout, the build settings and the thread
/// pool. Plain data with chainable setters; [`BuildOptions::default`] is what [`Bvh::new`]
/// uses, [`BuildOptions::quality`] and [`BuildOptions::compact`] are presets.
///
/// ```
/// use quiver::{build::Builder, BuildOptions, Layout, Triangle};
/// use glam::Vec3A;
/// let tris = vec![Triangle::new(Vec3A::ZERO, Vec3A::X, Vec3A::Y); 100];
/// let pool = rayon::ThreadPoolBuilder::new().num_threads(2).build().unwrap();
/// let (bvh, tree) = BuildOptions::default()
///     .builder(Builder::Sweep)
///     .layout(Layout::Bvh2Subtree)
///     .max_leaf_size(4)
///     .thread_pool(&pool)
///     .build_with_tree(&tris);
/// assert!(tree.stats().max_leaf <= 4);
/// assert!(bvh.footprint().nodes >= tree.stats().nodes);
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
    /// [`Isa::Portable`]. Only 8-wide layouts have AVX2 kernels so far.
    pub isa: Option<Isa>,
}

impl BuildOptions<'static> {
    /// The full-sweep SAH builder (every primitive boundary a candidate plane): the best tree
    /// quiver builds, several times slower to build than the binned default.
    pub fn quality() -> Self {
        BuildOptions {
            builder: Builder::Sweep,
            ..Default::default()
        }
    }

    /// The quantized 4-wide layout: 64-byte nodes, half the node memory of the default
    /// layout, for large scenes.
    pub fn compact() -> Self {
        BuildOptions {
            layout: Layout::Bvh4Quant,
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

    /// Makes leaves of at most `n` primitives (`n >= 1`; at most 65535 for `bvh4-quant`).
    pub fn max_leaf_size(mut self, n: usize) -> Self {
        self.config.max_leaf_size = n;
        self
    }

    /// Bins per axis for the binned builder (2 to 1024).
    pub fn bins(mut self, n: usize) -> Self {
        self.config.bins = n;
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

    /// Builds a BVH over `prims`; hits report each primitive's index in `prims`.
    ///
    /// # Panics
    /// When the settings are out of range: `bins` outside 2..=1024, `max_leaf_size` 0, or
    /// above 65535 with the `bvh4-quant` layout.
    pub fn build<P: Primitive>(&self, prims: &[P]) -> Bvh<P> {
        self.build_with_tree(prims).0
    }

    /// [`BuildOptions::build`], also returning the binary build tree (for SAH cost, tree
    /// statistics, or laying the same tree out again with [`Bvh::from_tree`]).
    ///
    /// # Panics
    /// As [`BuildOptions::build`].
    pub fn build_with_tree<P: Primitive>(&self, prims: &[P]) -> (Bvh<P>, BuildTree) {
        self.run(|| {
            let tree = build(&prim_bounds(prims), &self.config, self.builder);
            let bvh = self.layout.lay_out(
                &tree,
                leaf_order(&tree, prims),
                self.chosen_isa(),
                &self.config,
            );
            (bvh, tree)
        })
    }

    /// Builds a BVH over an indexed triangle mesh (see [`Bvh::from_mesh`]).
    ///
    /// # Errors
    /// [`MeshError`] when an index names no vertex, or there are more than `u32::MAX`
    /// triangles.
    ///
    /// # Panics
    /// As [`BuildOptions::build`].
    pub fn build_mesh(
        &self,
        positions: &[[f32; 3]],
        indices: &[[u32; 3]],
    ) -> Result<Bvh, MeshError> {
        Ok(self.build_mesh_with_tree(positions, indices)?.0)
    }

    /// [`BuildOptions::build_mesh`], also returning the build tree.
    ///
    /// # Errors
    /// As [`BuildOptions::build_mesh`].
    ///
    /// # Panics
    /// As [`BuildOptions::build`].
    pub fn build_mesh_with_tree(
        &self,
        positions: &[[f32; 3]],
        indices: &[[u32; 3]],
    ) -> Result<(Bvh, BuildTree), MeshError> {
        let mesh = Mesh::new(positions, indices)?;
        Ok(self.run(|| {
            use rayon::prelude::*;
            let tree = build(&mesh.bounds(), &self.config, self.builder);
            let leaf_tris = tree
                .prim_indices
                .par_iter()
                .map(|&i| mesh.triangle(i))
                .collect();
            let bvh = self
                .layout
                .lay_out(&tree, leaf_tris, self.chosen_isa(), &self.config);
            (bvh, tree)
        }))
    }

    /// The instruction set asked for, or the detected one.
    fn chosen_isa(&self) -> Isa {
        self.isa.unwrap_or_else(Isa::detect)
    }

    /// Runs `f` on the chosen pool.
    fn run<R: Send>(&self, f: impl FnOnce() -> R + Send) -> R {
        match self.pool {
            Some(pool) => pool.install(f),
            None => f(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::soup;

    #[test]
    fn a_mesh_builds_the_same_bvh_as_its_triangles() {
        let tris = soup(500, 9);
        // The same triangles as a vertex buffer (three vertices each, some shared) and indices.
        let mut positions: Vec<[f32; 3]> = Vec::new();
        let mut indices = Vec::new();
        for t in &tris {
            let base = positions.len() as u32;
            positions.extend(t.v.iter().map(|v| v.to_array()));
            indices.push([base, base + 1, base + 2]);
        }
        for layout in Layout::ALL {
            let options = BuildOptions::default().layout(layout);
            let (from_tris, t1) = options.build_with_tree(&tris);
            let (from_mesh, t2) = options.build_mesh_with_tree(&positions, &indices).unwrap();
            assert_eq!(t1, t2, "{layout}");
            assert_eq!(from_tris.footprint(), from_mesh.footprint(), "{layout}");
            for i in 0..200 {
                let o = glam::Vec3A::new(i as f32 / 200.0, 0.5, -1.0);
                let ray = Ray::new(o, glam::Vec3A::new(0.1, 0.05, 1.0));
                assert_eq!(
                    from_tris.closest_hit(&ray),
                    from_mesh.closest_hit(&ray),
                    "{layout}"
                );
                assert_eq!(
                    from_mesh.closest_hit(&ray),
                    crate::reference::closest_hit(&tris, &ray),
                    "{layout}"
                );
            }
        }
    }

    #[test]
    fn a_bad_index_is_an_error_not_a_panic() {
        let e = Bvh::from_mesh(&[[0.0; 3]; 4], &[[0, 1, 2], [1, 2, 9]]).unwrap_err();
        assert!(matches!(
            e,
            MeshError::IndexOutOfRange {
                triangle: 1,
                corner: 2,
                index: 9,
                ..
            }
        ));
        assert!(
            Bvh::from_mesh(&[], &[]).is_ok(),
            "an empty mesh is a valid, empty BVH"
        );
    }

    #[test]
    fn the_same_tree_on_any_pool() {
        let tris = soup(3000, 4);
        let one = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap();
        let two = rayon::ThreadPoolBuilder::new()
            .num_threads(2)
            .build()
            .unwrap();
        let (_, a) = BuildOptions::default()
            .thread_pool(&one)
            .build_with_tree(&tris);
        let (_, b) = BuildOptions::default()
            .thread_pool(&two)
            .build_with_tree(&tris);
        assert_eq!(a, b);
        assert_eq!(one.install(rayon::current_num_threads), 1);
    }
}
