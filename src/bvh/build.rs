//! Building a [`Bvh`] with [`BuildOptions`]: from a primitive slice ([`Bvh::build`]) or an
//! indexed triangle mesh ([`Bvh::build_mesh`]), data first and options last, optionally
//! returning the binary build tree beside it.

use super::options::frame_prims;
use super::{BuildOptions, Bvh};
use crate::builders::{build_clipped, BuildError, BuildTree, CostModel, Triangles};
use crate::frame::Frame;
use crate::layout::{Inputs, LeafPrims};
use crate::mesh::{Mesh, Positions};
use crate::primitive::{LeafFormat, Primitive};
use crate::Triangle;

impl<P: Primitive> Bvh<P> {
    /// Builds a BVH over `prims` with `options`; hits report each primitive's index in
    /// `prims`. [`Bvh::new`] is this with the default options, which cannot fail.
    ///
    /// ```
    /// use quiver_rt::builders::Builder;
    /// use quiver_rt::{BuildOptions, Bvh, Layout, Ray, RayQuery, Triangle};
    /// use glam::Vec3A;
    /// let tris: Vec<Triangle> = (0..50)
    ///     .map(|i| {
    ///         let o = Vec3A::new(i as f32, 0.0, 0.0);
    ///         Triangle::new(o, o + Vec3A::X, o + Vec3A::Y)
    ///     })
    ///     .collect();
    /// let ray = Ray::new(Vec3A::new(7.25, 0.5, 1.0), -Vec3A::Z);
    /// let options = BuildOptions::default().builder(Builder::Sweep).layout(Layout::Bvh4Quant);
    /// let bvh = Bvh::build(&tris, &options).unwrap();
    /// assert_eq!(bvh.closest_hit(&ray).map(|h| h.prim), Some(7));
    /// assert!(Bvh::build(&tris, &BuildOptions::default().bins(1)).is_err());
    /// ```
    ///
    /// # Errors
    /// [`BuildError::Config`] when a setting of `options.config` is out of range
    /// ([`crate::builders::BuildConfig::check`]).
    pub fn build(prims: &[P], options: &BuildOptions<'_>) -> Result<Bvh<P>, BuildError> {
        Ok(Self::build_with_tree(prims, options)?.0)
    }

    /// [`Bvh::build`], also returning the binary build tree (for SAH cost, tree statistics,
    /// or laying the same tree out again with [`Bvh::from_tree`]).
    ///
    /// ```
    /// use quiver_rt::{BuildOptions, Bvh, Triangle};
    /// use glam::Vec3A;
    /// let tris = vec![Triangle::new(Vec3A::ZERO, Vec3A::X, Vec3A::Y); 100];
    /// let four = BuildOptions::default().max_leaf_size(4);
    /// let (bvh, tree) = Bvh::build_with_tree(&tris, &four).unwrap();
    /// assert!(tree.stats().max_leaf <= 4);
    /// assert!(bvh.footprint().nodes >= 1);
    /// ```
    ///
    /// # Errors
    /// As [`Bvh::build`].
    pub fn build_with_tree(
        prims: &[P],
        options: &BuildOptions<'_>,
    ) -> Result<(Bvh<P>, BuildTree), BuildError> {
        options.config.check()?;
        options.run(|| {
            let (bounds, frame) = Frame::bounds(prims.len(), |i| {
                crate::isa::prefetch_stream(prims, i);
                prims[i].bounds()
            });
            let local = frame_prims(frame, prims);
            // A type that cannot be scaled stays in its own units.
            let frame = if local.is_some() {
                frame
            } else {
                Frame::default()
            };
            let in_frame = local.as_deref().unwrap_or(prims);
            // The triangle a spatial split clips is the one the kernels test.
            let get = |i: u32| match P::LEAF_FORMAT {
                LeafFormat::Plain => None,
                _ => in_frame[i as usize].triangle(),
            };
            let soon = |i: u32| crate::isa::prefetch_at(in_frame, i as usize);
            let tri = Triangles {
                get: &get,
                soon: &soon,
            };
            let tree = build_clipped(
                &frame.boxes(&bounds),
                options.areas(in_frame).as_deref(),
                &options.effective_config::<P>(),
                options.builder,
                Some(tri),
            )?;
            let inputs = Inputs::of(&tree, prims.len());
            let nodes = options.lay_out(&tree, LeafPrims::Slice(in_frame), inputs);
            let tree = frame.world_tree(tree, &bounds);
            Ok((Bvh::of(nodes, frame, &tree), tree))
        })
    }
}

impl Bvh {
    /// Builds a BVH over an indexed triangle mesh with `options` (see [`Bvh::from_mesh`] for
    /// the defaults): triangle `i` has corners `positions[indices[i][0]]`, `…[1]]`, `…[2]]`,
    /// and hits report `i`. The buffers are read in place.
    ///
    /// ```
    /// use quiver_rt::{BuildError, BuildOptions, Bvh, MeshError, Ray, RayQuery};
    /// use glam::Vec3A;
    /// let positions = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]];
    /// let bvh = Bvh::build_mesh(&positions, &[[0, 1, 2], [0, 2, 3]], &BuildOptions::fast()).unwrap();
    /// let hit = bvh.closest_hit(&Ray::new(Vec3A::new(0.25, 0.75, 1.0), -Vec3A::Z)).unwrap();
    /// assert_eq!(hit.prim, 1);
    /// let bad = Bvh::build_mesh(&positions, &[[0, 1, 7]], &BuildOptions::default());
    /// assert!(matches!(bad, Err(BuildError::Mesh(MeshError::IndexOutOfRange { index: 7, .. }))));
    /// ```
    ///
    /// # Errors
    /// [`BuildError::Mesh`] when an index names no vertex or there are more than `u32::MAX`
    /// triangles; [`BuildError::Config`] as [`Bvh::build`].
    pub fn build_mesh<'v>(
        positions: impl Into<Positions<'v>>,
        indices: &[[u32; 3]],
        options: &BuildOptions<'_>,
    ) -> Result<Bvh, BuildError> {
        Ok(Self::build_mesh_with_tree(positions, indices, options)?.0)
    }

    /// [`Bvh::build_mesh`], also returning the build tree.
    ///
    /// # Errors
    /// As [`Bvh::build_mesh`].
    pub fn build_mesh_with_tree<'v>(
        positions: impl Into<Positions<'v>>,
        indices: &[[u32; 3]],
        options: &BuildOptions<'_>,
    ) -> Result<(Bvh, BuildTree), BuildError> {
        let mesh = Mesh::new(positions.into(), indices)?;
        options.config.check()?;
        options.run(|| {
            use rayon::prelude::*;
            let (bounds, frame) = mesh.bounds();
            let framed = |i: u32| match frame.is_identity() {
                true => mesh.triangle(i),
                false => frame.prim(&mesh.triangle(i)).expect("triangles scale"),
            };
            // Surface areas only for a cost model that weighs them.
            let areas: Option<Vec<f32>> =
                (options.config.cost_model != CostModel::Sah).then(|| {
                    (0..bounds.len() as u32)
                        .into_par_iter()
                        .map(|i| framed(i).surface_area())
                        .collect()
                });
            let get = |i: u32| Some(framed(i));
            let tri = Triangles {
                get: &get,
                soon: &|_| {},
            };
            let tree = build_clipped(
                &frame.boxes(&bounds),
                areas.as_deref(),
                &options.effective_config::<Triangle>(),
                options.builder,
                Some(tri),
            )?;
            let inputs = Inputs::of(&tree, indices.len());
            let nodes = options.lay_out(&tree, LeafPrims::Input(&framed), inputs);
            let tree = frame.world_tree(tree, &bounds);
            Ok((Bvh::of(nodes, frame, &tree), tree))
        })
    }
}
