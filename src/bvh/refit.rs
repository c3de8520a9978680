//! Refitting a [`Bvh`] to primitives that moved (animation, deformation): the same tree, its
//! boxes recomputed; [`RefitError`] for input a refit cannot take; [`Bvh::sah_cost`] to judge
//! when a refit tree has loosened enough to rebuild.

use super::any_layout::AnyLayout;
use super::Bvh;
use crate::frame::Frame;
use crate::geometry::Triangle;
use crate::layout::moved::{check_moved, MovedPrims, RefitError, RefitTarget};
use crate::layout::refit::RefitInput;
use crate::layout::walk::sah_cost;
use crate::layout::Inputs;
use crate::mesh::{Mesh, Positions};
use crate::primitive::Primitive;
use rayon::prelude::*;

impl<P: Primitive> RefitTarget<P> for AnyLayout<P> {
    fn inputs(&self) -> Inputs {
        match self {
            AnyLayout::Bvh2(b) => b.inputs(),
            AnyLayout::Bvh4(b) => b.inputs(),
            AnyLayout::QBvh4(b) => b.inputs(),
            AnyLayout::Bvh8(b) => b.inputs(),
        }
    }

    fn held_ids(&self) -> &[u32] {
        match self {
            AnyLayout::Bvh2(b) => b.held_ids(),
            AnyLayout::Bvh4(b) => b.held_ids(),
            AnyLayout::QBvh4(b) => b.held_ids(),
            AnyLayout::Bvh8(b) => b.held_ids(),
        }
    }

    fn refit_from<S: RefitInput<P>>(&mut self, src: &S) {
        match self {
            AnyLayout::Bvh2(b) => b.refit_from(src),
            AnyLayout::Bvh4(b) => b.refit_from(src),
            AnyLayout::QBvh4(b) => b.refit_from(src),
            AnyLayout::Bvh8(b) => b.refit_from(src),
        }
    }
}

impl<P: Primitive> Bvh<P> {
    /// Refits the BVH to `prims`: the primitives it was built over, moved, in the same order
    /// (as many as it was built over, those the build dropped included). The tree stays as
    /// it was built; every box is recomputed bottom-up, in parallel over subtrees on the
    /// current rayon pool (call it inside [`rayon::ThreadPool::install`] for another), in
    /// place: the nodes, the leaf-order copy of the primitives (plain leaves), the SIMD
    /// triangle groups and quantized planes are rewritten, none of those arrays reallocated. Queries then answer
    /// exactly as a fresh layout of the same build tree over `prims` ([`Bvh::from_tree`])
    /// does, and the BVH takes the frame `prims` call for, as that layout would (a scene
    /// moved far from unit size is scaled by a power of two, one brought back is not). A
    /// refit takes 6 to 7% of the default build's time (the README's "Refit": 5.7 to 7.4% on
    /// 0.1 to 1 million triangles, 1 and 2 threads): the way to follow vertices that move
    /// while the topology stays.
    ///
    /// # When to rebuild instead
    ///
    /// The tree was chosen for the positions it was built over. When primitives move far
    /// relative to each other (a character's arm swept across its body, an explosion's
    /// fragments), leaves gather primitives that are no longer near each other, the boxes
    /// grow and overlap, and rays enter more of them: queries slow down, though they stay
    /// exact. [`Bvh::sah_cost`] measures it: the cost of the refit tree against the cost
    /// taken after the build says how much slower it has become, and past a threshold of the
    /// renderer's choosing (1.5 is common) a rebuild pays for itself.
    ///
    /// A tree with spatial splits ([`crate::builders::Builder::Sbvh`],
    /// [`crate::BuildOptions::high_quality`]) holds a split primitive in several leaves,
    /// each box bounding only its piece. A refit boxes each leaf's whole primitives: still
    /// correct (every box contains what its leaves hold), but the splits' tightness is gone,
    /// so such a BVH's [`Bvh::sah_cost`] rises even for primitives that did not move;
    /// rebuilding is the way to get it back.
    ///
    /// ```
    /// use quiver_rt::traverse::reference;
    /// use quiver_rt::{Bvh, Ray, RayQuery, RefitError, Triangle};
    /// use glam::Vec3A;
    /// // A strip of 100 triangles, waved up and down by `phase`.
    /// let strip = |phase: f32| -> Vec<Triangle> {
    ///     (0..100)
    ///         .map(|i| {
    ///             let o = Vec3A::new(i as f32, (0.3 * i as f32 + phase).sin(), 0.0);
    ///             Triangle::new(o, o + Vec3A::X, o + Vec3A::Y)
    ///         })
    ///         .collect()
    /// };
    /// let mut bvh = Bvh::new(&strip(0.0));
    /// let mut built = bvh.sah_cost();
    /// for frame in 1..10 {
    ///     let tris = strip(0.5 * frame as f32);
    ///     bvh.refit(&tris).unwrap();
    ///     let ray = Ray::new(Vec3A::new(40.2, tris[40].v[0].y + 0.2, 1.0), -Vec3A::Z);
    ///     assert_eq!(bvh.closest_hit(&ray), reference::closest_hit(&tris, &ray));
    /// }
    /// // The wave keeps neighbours together: the tree is about as good as built.
    /// assert!(bvh.sah_cost() < 1.5 * built);
    ///
    /// // Every triangle sent somewhere else along the strip: each leaf now spans it all.
    /// let scattered: Vec<Triangle> = (0..100)
    ///     .map(|i| {
    ///         let o = Vec3A::new(((i * 37) % 100) as f32, 0.0, 0.0);
    ///         Triangle::new(o, o + Vec3A::X, o + Vec3A::Y)
    ///     })
    ///     .collect();
    /// bvh.refit(&scattered).unwrap();
    /// let ray = Ray::new(Vec3A::new(74.2, 0.2, 1.0), -Vec3A::Z);
    /// assert_eq!(bvh.closest_hit(&ray).map(|h| h.prim), Some(2)); // still exact
    /// let refit = bvh.sah_cost();
    /// assert!(refit > 10.0 * built); // rays now enter ten times the nodes and leaves
    /// // Past the renderer's threshold, a rebuild (whose cost is the new yardstick).
    /// if refit > 1.5 * built {
    ///     bvh = Bvh::new(&scattered);
    ///     built = bvh.sah_cost();
    /// }
    /// assert!(built < refit / 5.0);
    ///
    /// // The same primitives, or none of it.
    /// let mut bvh = Bvh::new(&strip(0.0));
    /// assert_eq!(
    ///     bvh.refit(&strip(0.0)[..99]),
    ///     Err(RefitError::Count { expected: 100, given: 99 })
    /// );
    /// ```
    ///
    /// # Errors
    /// [`RefitError::Count`] for another number of primitives; [`RefitError::NonFinite`] for a
    /// primitive the tree holds that has a non-finite coordinate now (builds drop those, a
    /// refit cannot); [`RefitError::NotInTree`] for a primitive the build dropped (non-finite
    /// then) that is finite now. Nothing is changed then.
    pub fn refit(&mut self, prims: &[P]) -> Result<(), RefitError> {
        self.refit_by(prims.len(), Some(prims), |i| prims[i as usize].clone())
    }

    /// The SAH cost of the laid-out nodes, with unit costs: `Σ A(inner)/A(root) + Σ
    /// A(leaf)·n(leaf)/A(root)` over the nodes the layout's walk enters (the wide nodes and
    /// leaf slots of a 4- or 8-wide layout; a quantized layout's boxes as decoded), in f64.
    /// For a binary layout it is [`crate::builders::BuildTree::sah_cost`] of the tree with the
    /// default costs. It predicts the work of a ray ([`crate::predict`]), so the ratio of the
    /// cost after a refit to the cost after the build says how much a refit has slowed the
    /// BVH down (see [`Bvh::refit`]). One pass over the nodes, not the primitives: taken only
    /// when asked for.
    ///
    /// ```
    /// use quiver_rt::builders::BuildConfig;
    /// use quiver_rt::{BuildOptions, Bvh, Layout, Triangle};
    /// use glam::Vec3A;
    /// let tris: Vec<Triangle> = (0..64)
    ///     .map(|i| Triangle::new(Vec3A::splat(i as f32), Vec3A::splat(i as f32) + Vec3A::X, Vec3A::Y))
    ///     .collect();
    /// let (bvh, tree) = Bvh::build_with_tree(&tris, &BuildOptions::default().layout(Layout::Bvh2Dfs)).unwrap();
    /// assert_eq!(bvh.sah_cost(), tree.sah_cost(&BuildConfig::default()));
    /// ```
    pub fn sah_cost(&self) -> f64 {
        sah_cost(self)
    }

    /// The refit over `n` primitives, primitive `i` being `get(i)` (`slice[i]`, where they
    /// are a slice).
    fn refit_by<G: Fn(u32) -> P + Sync>(
        &mut self,
        n: usize,
        slice: Option<&[P]>,
        get: G,
    ) -> Result<(), RefitError> {
        let summary = check_moved(self.layout.inputs(), self.layout.held_ids(), n, slice, &get)?;
        // The frame a build over these primitives would choose (a type that cannot be scaled
        // keeps its own units).
        let mut frame = summary.sizes.frame();
        if !frame.is_identity()
            && !(0..n)
                .into_par_iter()
                .all(|i| frame.prim(&get(i as u32)).is_some())
        {
            frame = Frame::default();
        }
        // Moving into or out of a scaled frame only changes the units the boxes are
        // recomputed in.
        self.frame = frame;
        self.layout.refit_from(&MovedPrims { get, frame, slice });
        self.bounds = summary.all;
        Ok(())
    }
}

impl Bvh<Triangle> {
    /// [`Bvh::refit`] for a BVH built from an indexed mesh ([`Bvh::from_mesh`],
    /// [`Bvh::build_mesh`]): new vertex positions for the same triangles,
    /// triangle `i` having corners `positions[indices[i][0]]`, `…[1]]`, `…[2]]` as in the
    /// build. The index buffer must have as many triangles as the build's (it may be the same
    /// buffer, and usually is: only the vertices moved); the vertex count may differ.
    ///
    /// ```
    /// use quiver_rt::{Bvh, Ray, RayQuery, RefitError};
    /// use glam::Vec3A;
    /// let indices = [[0, 1, 2], [0, 2, 3]];
    /// let square = |z: f32| [[0.0, 0.0, z], [1.0, 0.0, z], [1.0, 1.0, z], [0.0, 1.0, z]];
    /// let mut bvh = Bvh::from_mesh(&square(0.0), &indices).unwrap();
    /// bvh.refit_mesh(&square(-3.0), &indices).unwrap();
    /// let hit = bvh.closest_hit(&Ray::new(Vec3A::new(0.25, 0.75, 1.0), -Vec3A::Z)).unwrap();
    /// assert_eq!((hit.prim, hit.t), (1, 4.0));
    /// assert!(matches!(
    ///     bvh.refit_mesh(&square(0.0)[..3], &indices),
    ///     Err(RefitError::Mesh(quiver_rt::MeshError::IndexOutOfRange { triangle: 1, corner: 2, .. }))
    /// ));
    /// ```
    ///
    /// # Errors
    /// As [`Bvh::refit`], and [`RefitError::Mesh`] when an index names no vertex.
    pub fn refit_mesh<'v>(
        &mut self,
        positions: impl Into<Positions<'v>>,
        indices: &[[u32; 3]],
    ) -> Result<(), RefitError> {
        let expected = self.layout.inputs().len;
        if indices.len() != expected {
            return Err(RefitError::Count {
                expected,
                given: indices.len(),
            });
        }
        let mesh = Mesh::new(positions.into(), indices)?;
        self.refit_by(indices.len(), None, |i| mesh.triangle(i))
    }
}
