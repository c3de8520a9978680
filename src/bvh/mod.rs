//! The front door: [`Bvh`], a BVH in any [`Layout`], built by [`Bvh::new`] with sensible
//! defaults or by [`BuildOptions`] with every choice (builder, layout, leaf size, bins, thread
//! pool), from a primitive slice or an indexed mesh.

mod any_layout;
mod build;
mod options;
mod refit;

pub use crate::layout::moved::RefitError;
pub(crate) use any_layout::AnyLayout;
pub use options::BuildOptions;

use crate::builders::{prim_bounds, BuildError, BuildTree, TreeError};
use crate::frame::Frame;
use crate::geometry::{Aabb, Hit, Ray, Triangle};
use crate::isa::{Isa, Kernels};
use crate::layout::walk::{NodeVisit, WalkNodes};
use crate::layout::{bvh2::leaf_order, Footprint, Inputs};
use crate::mesh::{MeshError, Positions};
use crate::primitive::Primitive;
use crate::traverse::lane8::F8;
use crate::traverse::packet::{InLanes, RayPacket};
use crate::traverse::{Ask, BoxTest, Filter, PacketQuery, RayQuery, Stats};
use options::frame_prims;

/// A laid-out BVH in any [`crate::Layout`], answering every query of [`RayQuery`].
///
/// ```
/// use quiver_rt::traverse::reference;
/// use quiver_rt::{BuildOptions, Bvh, Layout, Ray, RayQuery, Triangle};
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
///     let bvh = Bvh::build(&tris, &BuildOptions::default().layout(layout)).unwrap();
///     assert_eq!(bvh.closest_hit(&ray), reference::closest_hit(&tris, &ray));
/// }
/// ```
#[derive(Clone, Debug)]
pub struct Bvh<P = Triangle> {
    /// The nodes and leaves, in the units of `frame`.
    pub(crate) layout: AnyLayout<P>,
    /// The identity, or for a scene far from unit size the power-of-two scale the layout was
    /// built in (see [`Primitive::scaled`]).
    pub(crate) frame: Frame,
    /// Every primitive's box, in the caller's units.
    pub(crate) bounds: Aabb,
}

impl<P> Bvh<P> {
    /// A BVH over `layout`, whose tree (in the caller's units) is `tree`.
    fn of(layout: AnyLayout<P>, frame: Frame, tree: &BuildTree) -> Self {
        Bvh {
            layout,
            frame,
            bounds: tree.nodes.first().map_or(Aabb::EMPTY, |n| n.bounds),
        }
    }

    /// The layout and the frame it was built in, for readers inside the crate (the cost
    /// predictor).
    pub(crate) fn layout(&self) -> (&AnyLayout<P>, Frame) {
        (&self.layout, self.frame)
    }

    /// The box around every primitive the BVH holds (those with finite coordinates), in the
    /// units of the input; an empty box ([`Aabb::is_empty`]) for a BVH of nothing.
    ///
    /// ```
    /// use quiver_rt::{Aabb, Bvh, Triangle};
    /// use glam::Vec3A;
    /// let bvh = Bvh::new(&[Triangle::new(Vec3A::ZERO, Vec3A::X, Vec3A::new(0.0, 2.0, 3.0))]);
    /// assert_eq!(bvh.bounds(), Aabb::new(Vec3A::ZERO, Vec3A::new(1.0, 2.0, 3.0)));
    /// assert!(Bvh::<Triangle>::new(&[]).bounds().is_empty());
    /// ```
    pub fn bounds(&self) -> Aabb {
        self.bounds
    }
}

impl<P: Primitive> Bvh<P> {
    /// Builds over `prims` with the default [`BuildOptions`]: binned SAH, leaves of up to 8,
    /// the default layout (`bvh8-dfs`), on the current rayon thread pool. Hits report each
    /// primitive's index in `prims`.
    ///
    /// ```
    /// use quiver_rt::{Bvh, Ray, RayQuery, Triangle};
    /// use glam::Vec3A;
    /// let bvh = Bvh::new(&[Triangle::new(Vec3A::ZERO, Vec3A::X, Vec3A::Y)]);
    /// assert!(bvh.any_hit(&Ray::new(Vec3A::new(0.2, 0.2, 1.0), -Vec3A::Z)));
    /// ```
    pub fn new(prims: &[P]) -> Self {
        Bvh::build(prims, &BuildOptions::default()).expect("the default options are in range")
    }

    /// Lays out a built tree over `prims` (the build's input) with `options`' layout,
    /// instruction set and leaf settings (the builder is not used: the tree is built). The
    /// tree's structure is checked first (as [`BuildTree::check`] checks it: preorder, depth,
    /// leaf ranges, primitive references) and its boxes recomputed from `prims`, so a tree
    /// quiver accepts can never make a query panic, loop, or miss a primitive.
    ///
    /// ```
    /// use quiver_rt::builders::TreeError;
    /// use quiver_rt::{BuildOptions, Bvh, Layout, Ray, RayQuery, Triangle};
    /// use glam::Vec3A;
    /// let tris: Vec<Triangle> = (0..40)
    ///     .map(|i| Triangle::new(Vec3A::new(i as f32, 0.0, 0.0), Vec3A::new(i as f32 + 1.0, 0.0, 0.0), Vec3A::new(i as f32, 1.0, 0.0)))
    ///     .collect();
    /// let four = BuildOptions::default().max_leaf_size(4);
    /// let (_, tree) = Bvh::build_with_tree(&tris, &four).unwrap();
    /// let again = Bvh::from_tree(&tree, &tris, &four.clone().layout(Layout::Bvh2Dfs)).unwrap();
    /// let ray = Ray::new(Vec3A::new(7.2, 0.3, 1.0), -Vec3A::Z);
    /// assert_eq!(again.closest_hit(&ray).map(|h| h.prim), Some(7));
    /// // The tree of other primitives is refused.
    /// assert!(matches!(
    ///     Bvh::from_tree(&tree, &tris[..39], &four),
    ///     Err(TreeError::PrimCount { tree: 40, prims: 39 })
    /// ));
    /// ```
    ///
    /// # Errors
    /// [`TreeError`] when the tree does not fit `prims` (count, indices, leaf ranges), is not
    /// in depth-first preorder, is deeper than the kernels' stacks, or has a leaf too large
    /// for the layout.
    pub fn from_tree(
        tree: &BuildTree,
        prims: &[P],
        options: &BuildOptions<'_>,
    ) -> Result<Self, TreeError> {
        let bounds = prim_bounds(prims);
        tree.check_structure(&bounds)?;
        // What the layout's leaf counts can hold (the 8-wide collapse merges leaves only up to
        // the options' leaf size, which it caps the same way).
        tree.check_leaf_size(match options.layout {
            crate::layout::Layout::Bvh4Quant => u16::MAX as u32,
            _ => crate::layout::Bvh2Node::LEAF - 1,
        })?;
        let world = tree.refit(&bounds);
        let frame = Frame::for_prims(&bounds);
        let inputs = Inputs::of(tree, prims.len());
        let (layout, frame) = options.run(|| match frame_prims(frame, prims) {
            Some(local) => {
                let tree = tree.refit(&prim_bounds(&local));
                (
                    options.lay_out(&tree, leaf_order(&tree, &local), inputs),
                    frame,
                )
            }
            None => (
                options.lay_out(&world, leaf_order(tree, prims), inputs),
                Frame::default(),
            ),
        });
        Ok(Bvh::of(layout, frame, &world))
    }

    /// The instruction set queries run on: the BVH's own for 8-wide nodes (all queries) and
    /// 4-wide nodes (packet queries), portable for the binary layouts (they have no AVX2
    /// kernels).
    pub fn isa(&self) -> Isa {
        self.layout.isa()
    }

    /// The same BVH traversed with `isa` where it has kernels for it (see [`Bvh::isa`]).
    pub fn with_isa(self, isa: Isa) -> Self {
        Bvh {
            layout: self.layout.with_isa(isa),
            ..self
        }
    }

    /// What the nodes and leaves occupy.
    pub fn footprint(&self) -> Footprint {
        self.layout.footprint()
    }

    /// The query `A` of one ray on the caller's lanes `V` (a world's ray entering an
    /// instance; see [`crate::layout::Bvh8`]'s `one_ray`): false, with nothing done, where
    /// this BVH takes the ray the usual way (another layout, kernels or frame).
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn one_ray<V: F8, A: Ask, B: BoxTest, S: Stats, F: Filter<Hit>>(
        &self,
        kernels: Kernels,
        cpu: V::Cpu,
        ray: &Ray,
        best: &mut Hit,
        stats: &mut S,
        filter: &mut F,
    ) -> bool {
        self.frame.is_identity()
            && self
                .layout
                .one_ray::<V, A, B, S, F>(kernels, cpu, ray, best, stats, filter)
    }

    /// The query `A` of a packet already in lanes, on the caller's lanes `V` (see
    /// [`Bvh::one_ray`]).
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn in_lanes<V: F8, A: Ask, B: BoxTest, S: Stats, F: Filter<Hit>>(
        &self,
        kernels: Kernels,
        cpu: V::Cpu,
        pk: &mut RayPacket,
        best: InLanes<'_>,
        stats: &mut S,
        filter: &mut F,
    ) -> bool {
        self.frame.is_identity()
            && self
                .layout
                .in_lanes::<V, A, B, S, F>(kernels, cpu, pk, best, stats, filter)
    }
}

impl Bvh {
    /// Builds over an indexed triangle mesh with the default [`BuildOptions`]: triangle `i`
    /// has corners `positions[indices[i][0]]`, `…[1]]`, `…[2]]`, and hits report `i`. The
    /// buffers are read in place: packed `[f32; 3]` positions as they are, positions inside
    /// an interleaved vertex buffer through [`Positions::strided`] or
    /// [`Positions::of_vertices`], never copied first.
    ///
    /// # Errors
    /// [`MeshError`] when an index names no vertex, or there are more than `u32::MAX`
    /// triangles.
    pub fn from_mesh<'v>(
        positions: impl Into<Positions<'v>>,
        indices: &[[u32; 3]],
    ) -> Result<Self, MeshError> {
        match Bvh::build_mesh(positions, indices, &BuildOptions::default()) {
            Ok(bvh) => Ok(bvh),
            Err(BuildError::Mesh(e)) => Err(e),
            Err(e) => unreachable!("the default options are in range: {e}"),
        }
    }
}

impl<P: Primitive> RayQuery for Bvh<P> {
    type Hit = Hit;

    /// The layout's query (a scene built in a scaled frame takes the cold path that brings
    /// its rays in and its hits back).
    #[inline(always)]
    fn trace_with<A: Ask, B: BoxTest, S: Stats, F: Filter<Hit>>(
        &self,
        ray: &Ray,
        stats: &mut S,
        filter: &mut F,
    ) -> A::Answer<Hit> {
        if !self.frame.is_identity() {
            return any_layout::trace_scaled::<P, A, B, S, F>(
                &self.layout,
                self.frame,
                ray,
                stats,
                filter,
            );
        }
        self.layout.trace_with::<A, B, S, F>(ray, stats, filter)
    }

    fn trace_packet_with<A: Ask, B: BoxTest, S: Stats, F: Filter<Hit>>(
        &self,
        query: PacketQuery<'_>,
        hits: &mut [A::Answer<Hit>],
        stats: &mut S,
        filter: &mut F,
    ) {
        if !self.frame.is_identity() {
            return any_layout::trace_packet_scaled::<P, A, B, S, F>(
                &self.layout,
                self.frame,
                query,
                hits,
                stats,
                filter,
            );
        }
        self.layout
            .trace_packet_with::<A, B, S, F>(query, hits, stats, filter)
    }
}

impl<P: Primitive> WalkNodes for Bvh<P> {
    /// The layout's own nodes, in the frame the BVH was built in (see [`Bvh::predict_within`]
    /// for lines given in world units).
    fn walk_nodes(&self, f: &mut dyn FnMut(NodeVisit)) {
        // A frame scales every box by one power of two, which leaves area ratios alone.
        self.layout().0.walk_nodes(f)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::builders::BuildConfig;
    use crate::layout::Layout;
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
            let (from_tris, t1) = Bvh::build_with_tree(&tris, &options).unwrap();
            let (from_mesh, t2) =
                Bvh::build_mesh_with_tree(&positions, &indices, &options).unwrap();
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
                    crate::traverse::reference::closest_hit(&tris, &ray),
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
        let quant = BuildOptions::default()
            .layout(Layout::Bvh4Quant)
            .max_leaf_size(100_000);
        let (bvh, tree) = Bvh::build_with_tree(&tris, &quant).unwrap();
        assert!(tree.stats().max_leaf <= 65535);
        let (_, uncapped) =
            Bvh::build_with_tree(&tris, &BuildOptions::default().max_leaf_size(100_000)).unwrap();
        assert!(
            uncapped.stats().max_leaf > 65535,
            "the case is the one that overflowed"
        );
        let ray = Ray::new(Vec3A::new(0.25, 0.25, 1.0), -Vec3A::Z);
        assert_eq!(
            bvh.closest_hit(&ray),
            crate::traverse::reference::closest_hit(&tris, &ray)
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
        let (big, tree) =
            Bvh::build_mesh_with_tree(&positions, &indices, &BuildOptions::default()).unwrap();
        assert!(!big.frame.is_identity());
        let unit = Bvh::new(&tris);
        for i in 0..200 {
            let o = Vec3A::new(i as f32 / 200.0, 0.5, -1.0);
            let ray = Ray::new(o, Vec3A::new(0.1, 0.05, 1.0));
            let want = unit.closest_hit(&ray).map(|h| Hit { t: h.t * s, ..h });
            assert_eq!(big.closest_hit(&Ray::new(o * s, ray.dir)), want, "ray {i}");
        }
        // The tree is told in the caller's units: its boxes hold the world triangles.
        let world: Vec<Triangle> = tris.iter().map(|t| t.scaled(s).unwrap()).collect();
        tree.check(&prim_bounds(&world), &BuildConfig::default())
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
        let (_, a) =
            Bvh::build_with_tree(&tris, &BuildOptions::default().thread_pool(&one)).unwrap();
        let (_, b) =
            Bvh::build_with_tree(&tris, &BuildOptions::default().thread_pool(&two)).unwrap();
        assert_eq!(a, b);
        assert_eq!(one.install(rayon::current_num_threads), 1);
    }
}
