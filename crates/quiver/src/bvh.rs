//! The front door: [`Bvh`], a BVH in any [`Layout`], built by [`Bvh::new`] with sensible
//! defaults or by [`BuildOptions`] with every choice (builder, layout, leaf size, bins, thread
//! pool), from a primitive slice or an indexed mesh.

use crate::builders::{build_with_areas, prim_bounds, BuildConfig, BuildTree, Builder, CostModel};
use crate::frame::{Back, Frame};
use crate::geometry::{Aabb, Hit, Ray, Triangle};
use crate::isa::Isa;
use crate::layout::bvh2::leaf_order;
use crate::layout::{Bvh2, Bvh4, Bvh8, Footprint, Layout, QBvh4};
use crate::mesh::{Mesh, MeshError};
use crate::primitive::Primitive;
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
pub struct Bvh<P = Triangle> {
    nodes: Nodes<P>,
}

/// The nodes and leaves of one [`Layout`].
#[derive(Clone, Debug)]
pub(crate) enum Nodes<P> {
    /// Binary nodes.
    Bvh2(Bvh2<P>),
    /// 4-wide exact nodes.
    Bvh4(Bvh4<P>),
    /// 4-wide quantized nodes.
    QBvh4(QBvh4<P>),
    /// 8-wide exact nodes.
    Bvh8(Bvh8<P>),
    /// Nodes built in a scaled frame, for a scene far from unit size (see
    /// [`Primitive::scaled`]). A variant of its own, so that unscaled BVHs pay nothing for it.
    Scaled(Box<Scaled<P>>),
}

/// Nodes and primitives in a frame scaled by a power of two, and the frame.
#[derive(Clone, Debug)]
pub(crate) struct Scaled<P> {
    frame: Frame,
    nodes: Nodes<P>,
}

impl<P> Bvh<P> {
    /// The nodes of the layout, for readers inside the crate (the cost predictor).
    pub(crate) fn layout_nodes(&self) -> &Nodes<P> {
        &self.nodes
    }
}

impl<P> Nodes<P> {
    /// The nodes of the layout itself, out of any scaled frame, and `b` (world units) in
    /// their frame.
    pub(crate) fn unframed(&self, b: &Aabb) -> (&Nodes<P>, Aabb) {
        match self {
            Nodes::Scaled(s) => (&s.nodes, s.frame.aabb(b)),
            other => (other, *b),
        }
    }

    /// These nodes, built in `frame`.
    fn framed(self, frame: Frame) -> Nodes<P> {
        if frame.is_identity() {
            self
        } else {
            Nodes::Scaled(Box::new(Scaled { frame, nodes: self }))
        }
    }
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
        let frame = Frame::for_prims(&prim_bounds(prims));
        let config = BuildConfig::default();
        match frame_prims(frame, prims) {
            Some(local) => Bvh {
                nodes: layout
                    .lay_out(
                        &tree.refit(&prim_bounds(&local)),
                        leaf_order(tree, &local),
                        Isa::detect(),
                        &config,
                    )
                    .framed(frame),
            },
            None => Bvh {
                nodes: layout.lay_out(tree, leaf_order(tree, prims), Isa::detect(), &config),
            },
        }
    }

    /// The instruction set queries run on: the BVH's own for 8-wide nodes (all queries) and
    /// 4-wide nodes (packet queries), portable for the binary layouts (they have no AVX2
    /// kernels).
    pub fn isa(&self) -> Isa {
        self.nodes.isa()
    }

    /// The same BVH traversed with `isa` where it has kernels for it (see [`Bvh::isa`]).
    pub fn with_isa(self, isa: Isa) -> Self {
        Bvh {
            nodes: self.nodes.with_isa(isa),
        }
    }

    /// What the nodes and leaves occupy.
    pub fn footprint(&self) -> Footprint {
        self.nodes.footprint()
    }
}

impl<P: Primitive> Nodes<P> {
    fn isa(&self) -> Isa {
        match self {
            Nodes::Bvh8(b) => b.isa,
            Nodes::Bvh4(b) => b.isa,
            Nodes::QBvh4(b) => b.isa,
            Nodes::Scaled(s) => s.nodes.isa(),
            _ => Isa::Portable,
        }
    }

    fn with_isa(self, isa: Isa) -> Self {
        match self {
            Nodes::Bvh8(b) => Nodes::Bvh8(b.with_isa(isa)),
            Nodes::Bvh4(b) => Nodes::Bvh4(b.with_isa(isa)),
            Nodes::QBvh4(b) => Nodes::QBvh4(b.with_isa(isa)),
            Nodes::Scaled(s) => {
                let Scaled { frame, nodes } = *s;
                nodes.with_isa(isa).framed(frame)
            }
            other => other,
        }
    }

    fn footprint(&self) -> Footprint {
        match self {
            Nodes::Bvh2(b) => b.footprint(),
            Nodes::Bvh4(b) => b.footprint(),
            Nodes::QBvh4(b) => b.footprint(),
            Nodes::Bvh8(b) => b.footprint(),
            Nodes::Scaled(s) => s.nodes.footprint(),
        }
    }
}

/// The primitives in `frame`: `None` for the identity frame (use them as they are) and for
/// types that cannot be scaled.
fn frame_prims<P: Primitive>(frame: Frame, prims: &[P]) -> Option<Vec<P>> {
    if frame.is_identity() {
        None
    } else {
        frame.prims(prims)
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

impl<P: Primitive> RayQuery for Nodes<P> {
    #[inline(always)]
    fn closest_hit_with<B: BoxTest, S: Stats>(&self, ray: &Ray, stats: &mut S) -> Option<Hit> {
        match self {
            Nodes::Bvh2(b) => b.closest_hit_with::<B, S>(ray, stats),
            Nodes::Bvh4(b) => b.closest_hit_with::<B, S>(ray, stats),
            Nodes::QBvh4(b) => b.closest_hit_with::<B, S>(ray, stats),
            Nodes::Bvh8(b) => b.closest_hit_with::<B, S>(ray, stats),
            Nodes::Scaled(s) => s.closest_hit_with::<B, S>(ray, stats),
        }
    }

    #[inline(always)]
    fn any_hit_with<B: BoxTest, S: Stats>(&self, ray: &Ray, stats: &mut S) -> bool {
        match self {
            Nodes::Bvh2(b) => b.any_hit_with::<B, S>(ray, stats),
            Nodes::Bvh4(b) => b.any_hit_with::<B, S>(ray, stats),
            Nodes::QBvh4(b) => b.any_hit_with::<B, S>(ray, stats),
            Nodes::Bvh8(b) => b.any_hit_with::<B, S>(ray, stats),
            Nodes::Scaled(s) => s.any_hit_with::<B, S>(ray, stats),
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
            Nodes::Bvh2(b) => b.closest_hit_packet_with::<B, S>(rays, active, mode, hits, stats),
            Nodes::Bvh4(b) => b.closest_hit_packet_with::<B, S>(rays, active, mode, hits, stats),
            Nodes::QBvh4(b) => b.closest_hit_packet_with::<B, S>(rays, active, mode, hits, stats),
            Nodes::Bvh8(b) => b.closest_hit_packet_with::<B, S>(rays, active, mode, hits, stats),
            Nodes::Scaled(s) => s.closest_hit_packet_with::<B, S>(rays, active, mode, hits, stats),
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
            Nodes::Bvh2(b) => b.any_hit_packet_with::<B, S>(rays, active, mode, occluded, stats),
            Nodes::Bvh4(b) => b.any_hit_packet_with::<B, S>(rays, active, mode, occluded, stats),
            Nodes::QBvh4(b) => b.any_hit_packet_with::<B, S>(rays, active, mode, occluded, stats),
            Nodes::Bvh8(b) => b.any_hit_packet_with::<B, S>(rays, active, mode, occluded, stats),
            Nodes::Scaled(s) => s.any_hit_packet_with::<B, S>(rays, active, mode, occluded, stats),
        }
    }
}

/// Rays per batch brought into a scaled BVH's frame for a packet query: a whole number of
/// packets, so the packets are the ones an unscaled BVH would form.
const FRAME_BATCH: usize = 4 * crate::traverse::PACKET_RAYS;

impl<P: Primitive> RayQuery for Bvh<P> {
    #[inline(always)]
    fn closest_hit_with<B: BoxTest, S: Stats>(&self, ray: &Ray, stats: &mut S) -> Option<Hit> {
        self.nodes.closest_hit_with::<B, S>(ray, stats)
    }

    #[inline(always)]
    fn any_hit_with<B: BoxTest, S: Stats>(&self, ray: &Ray, stats: &mut S) -> bool {
        self.nodes.any_hit_with::<B, S>(ray, stats)
    }

    fn closest_hit_packet_with<B: BoxTest, S: Stats>(
        &self,
        rays: &[Ray],
        active: Option<&[bool]>,
        mode: PacketMode,
        hits: &mut [Option<Hit>],
        stats: &mut S,
    ) {
        self.nodes
            .closest_hit_packet_with::<B, S>(rays, active, mode, hits, stats)
    }

    fn any_hit_packet_with<B: BoxTest, S: Stats>(
        &self,
        rays: &[Ray],
        active: Option<&[bool]>,
        mode: PacketMode,
        occluded: &mut [bool],
        stats: &mut S,
    ) {
        self.nodes
            .any_hit_packet_with::<B, S>(rays, active, mode, occluded, stats)
    }
}

impl<P: Primitive> RayQuery for Scaled<P> {
    fn closest_hit_with<B: BoxTest, S: Stats>(&self, ray: &Ray, stats: &mut S) -> Option<Hit> {
        let (local, back) = self.frame.ray(ray);
        let hit = self.nodes.closest_hit_with::<B, S>(&local, stats);
        hit.map(|h| back.hit(h))
    }

    fn any_hit_with<B: BoxTest, S: Stats>(&self, ray: &Ray, stats: &mut S) -> bool {
        self.nodes
            .any_hit_with::<B, S>(&self.frame.ray(ray).0, stats)
    }

    fn closest_hit_packet_with<B: BoxTest, S: Stats>(
        &self,
        rays: &[Ray],
        active: Option<&[bool]>,
        mode: PacketMode,
        hits: &mut [Option<Hit>],
        stats: &mut S,
    ) {
        assert_eq!(hits.len(), rays.len(), "one hit slot per ray");
        self.in_frame(rays, active, |local, backs, active, at| {
            let hits = &mut hits[at..at + local.len()];
            self.nodes
                .closest_hit_packet_with::<B, S>(local, active, mode, hits, stats);
            for (h, back) in hits.iter_mut().zip(backs) {
                *h = h.map(|h| back.hit(h));
            }
        });
    }

    fn any_hit_packet_with<B: BoxTest, S: Stats>(
        &self,
        rays: &[Ray],
        active: Option<&[bool]>,
        mode: PacketMode,
        occluded: &mut [bool],
        stats: &mut S,
    ) {
        assert_eq!(occluded.len(), rays.len(), "one flag per ray");
        self.in_frame(rays, active, |local, _, active, at| {
            let occluded = &mut occluded[at..at + local.len()];
            self.nodes
                .any_hit_packet_with::<B, S>(local, active, mode, occluded, stats);
        });
    }
}

impl<P: Primitive> Scaled<P> {
    /// Calls `f(local rays, their ways back, their active flags, index of the first)` batch
    /// by batch with the rays brought into the frame, on the stack.
    fn in_frame(
        &self,
        rays: &[Ray],
        active: Option<&[bool]>,
        mut f: impl FnMut(&[Ray], &[Back], Option<&[bool]>, usize),
    ) {
        if let Some(a) = active {
            assert_eq!(a.len(), rays.len(), "one active flag per ray");
        }
        let mut local = [Ray::new(glam::Vec3A::ZERO, glam::Vec3A::ZERO); FRAME_BATCH];
        let mut backs = [Back::default(); FRAME_BATCH];
        for (n, batch) in rays.chunks(FRAME_BATCH).enumerate() {
            let at = n * FRAME_BATCH;
            for ((l, b), r) in local.iter_mut().zip(&mut backs).zip(batch) {
                (*l, *b) = self.frame.ray(r);
            }
            f(
                &local[..batch.len()],
                &backs[..batch.len()],
                active.map(|a| &a[at..at + batch.len()]),
                at,
            );
        }
    }
}

/// How to build a [`Bvh`]: which builder, which layout, the build settings and the thread
/// pool. Plain data with chainable setters; [`BuildOptions::default`] is what [`Bvh::new`]
/// uses, [`BuildOptions::quality`] and [`BuildOptions::compact`] are presets.
///
/// ```
/// use quiver::{builders::Builder, BuildOptions, Layout, Triangle};
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

    /// Builds a BVH over `prims`; hits report each primitive's index in `prims`.
    ///
    /// # Panics
    /// When [`BuildConfig::check`] finds a setting out of range: `bins` outside 2..=1024,
    /// `max_leaf_size` 0, or a negative or non-finite SAH cost.
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
            let bounds = prim_bounds(prims);
            let frame = Frame::for_prims(&bounds);
            let local = frame_prims(frame, prims);
            // A type that cannot be scaled stays in its own units.
            let frame = if local.is_some() {
                frame
            } else {
                Frame::default()
            };
            let in_frame = local.as_deref().unwrap_or(prims);
            let tree = build_with_areas(
                &frame.boxes(&bounds),
                self.areas(in_frame).as_deref(),
                &self.effective_config(),
                self.builder,
            );
            let nodes = self.lay_out(&tree, leaf_order(&tree, in_frame));
            (
                Bvh {
                    nodes: nodes.framed(frame),
                },
                frame.world_tree(tree, &bounds),
            )
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
            let bounds = mesh.bounds();
            let frame = Frame::for_prims(&bounds);
            let framed = |i: u32| match frame.is_identity() {
                true => mesh.triangle(i),
                false => frame.prim(&mesh.triangle(i)).expect("triangles scale"),
            };
            // Surface areas only for a cost model that weighs them.
            let areas: Option<Vec<f32>> = (self.config.cost_model != CostModel::Sah).then(|| {
                (0..bounds.len() as u32)
                    .into_par_iter()
                    .map(|i| framed(i).surface_area())
                    .collect()
            });
            let tree = build_with_areas(
                &frame.boxes(&bounds),
                areas.as_deref(),
                &self.effective_config(),
                self.builder,
            );
            let leaf_tris = tree.prim_indices.par_iter().map(|&i| framed(i)).collect();
            let nodes = self.lay_out(&tree, leaf_tris);
            (
                Bvh {
                    nodes: nodes.framed(frame),
                },
                frame.world_tree(tree, &bounds),
            )
        }))
    }

    /// Each primitive's surface area (in the build's frame), for a cost model that weighs
    /// them; `None` for the SAH, which does not.
    fn areas<P: Primitive>(&self, prims: &[P]) -> Option<Vec<f32>> {
        use rayon::prelude::*;
        (self.config.cost_model != CostModel::Sah)
            .then(|| prims.par_iter().map(|p| p.surface_area()).collect())
    }

    /// The settings the build runs with: the quantized layout stores leaf sizes in 16 bits,
    /// so its leaves are capped at 65535 primitives.
    fn effective_config(&self) -> BuildConfig {
        let mut config = self.config.clone();
        if self.layout == Layout::Bvh4Quant {
            config.max_leaf_size = config.max_leaf_size.min(u16::MAX as usize);
        }
        config
    }

    /// Lays out a tree built with these options over `prims` in leaf order.
    fn lay_out<P: Primitive>(&self, tree: &BuildTree, prims: Vec<P>) -> Nodes<P> {
        self.layout
            .lay_out(tree, prims, self.chosen_isa(), &self.effective_config())
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
    use glam::Vec3A;

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
    fn huge_leaves_in_the_quantized_layout_are_capped_not_a_panic() {
        // 70,000 copies of one triangle cannot be split; with leaves of up to 100,000 they
        // made one leaf, more than the layout's 16-bit count holds.
        let tris = vec![crate::Triangle::new(Vec3A::ZERO, Vec3A::X, Vec3A::Y); 70_000];
        let (bvh, tree) = BuildOptions::default()
            .layout(Layout::Bvh4Quant)
            .max_leaf_size(100_000)
            .build_with_tree(&tris);
        assert!(tree.stats().max_leaf <= 65535);
        let (_, uncapped) = BuildOptions::default()
            .max_leaf_size(100_000)
            .build_with_tree(&tris);
        assert!(
            uncapped.stats().max_leaf > 65535,
            "the case is the one that overflowed"
        );
        let ray = Ray::new(Vec3A::new(0.25, 0.25, 1.0), -Vec3A::Z);
        assert_eq!(
            bvh.closest_hit(&ray),
            crate::reference::closest_hit(&tris, &ray)
        );
    }

    #[test]
    fn a_mesh_far_from_unit_size_hits_what_it_hits_at_unit_size() {
        let tris = soup(300, 4);
        let s = 2f32.powi(100);
        let positions: Vec<[f32; 3]> = tris
            .iter()
            .flat_map(|t| t.v.map(|v| (v * s).to_array()))
            .collect();
        let indices: Vec<[u32; 3]> = (0..tris.len() as u32)
            .map(|i| [3 * i, 3 * i + 1, 3 * i + 2])
            .collect();
        let (big, tree) = BuildOptions::default()
            .build_mesh_with_tree(&positions, &indices)
            .unwrap();
        assert!(matches!(big.nodes, Nodes::Scaled(_)));
        let unit = Bvh::new(&tris);
        for i in 0..200 {
            let o = Vec3A::new(i as f32 / 200.0, 0.5, -1.0);
            let ray = Ray::new(o, Vec3A::new(0.1, 0.05, 1.0));
            let want = unit.closest_hit(&ray).map(|h| Hit { t: h.t * s, ..h });
            assert_eq!(big.closest_hit(&Ray::new(o * s, ray.dir)), want, "ray {i}");
        }
        // The tree is told in the caller's units: its boxes hold the world triangles.
        let world: Vec<Triangle> = tris.iter().map(|t| t.scaled(s).unwrap()).collect();
        tree.validate(&prim_bounds(&world), &BuildConfig::default())
            .unwrap();
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
