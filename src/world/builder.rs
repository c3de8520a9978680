//! [`WorldBuilder`]: geometries and instances collected, then built into a [`World`].

use super::instance::placements;
use super::top::{top_level, world_boxes, InstanceLeaf, TopEnds};
use super::{
    Geometry, GeometryFilter, GeometryId, Instance, InstanceId, Motion, MovingTriangles, World,
    WorldError, WorldHit,
};
use crate::bvh::{BuildOptions, Bvh};
use crate::geometry::{Aabb, Triangle};
use crate::mesh::{Mesh, MeshError, Positions};
use crate::primitive::Primitive;

/// Where a world's geometries and instances are collected before [`WorldBuilder::build`].
///
/// ```
/// use quiver_rt::{BuildOptions, Instance, Triangle, World, WorldError};
/// use quiver_rt::glam::{Affine3A, Vec3A};
/// let mut b = World::builder();
/// let g = b.add_triangles(vec![Triangle::new(Vec3A::ZERO, Vec3A::X, Vec3A::Y)]);
/// b.add_instance(Instance::of(g).transform(Affine3A::from_scale(Vec3A::ZERO.into())));
/// let e = b.build(&BuildOptions::default()).unwrap_err();
/// assert_eq!(e, WorldError::Transform { instance: 0, why: "not invertible" });
/// ```
#[derive(Clone, Debug)]
pub struct WorldBuilder<P = Triangle> {
    pending: Vec<PendingGeometry<P>>,
    /// Build options of the geometries given their own (`set_options`), by index (empty
    /// when none has any).
    options: Vec<Option<BuildOptions<'static>>>,
    /// The geometries' own filters, by index (empty when none has one).
    filters: Vec<Option<GeometryFilter>>,
    instances: Vec<Instance>,
    /// The moving instances' motions, by index (empty when none moves).
    motions: Vec<Option<Motion>>,
    /// The first mesh whose indices did not check out, reported by `build`.
    bad_mesh: Option<(usize, MeshError)>,
    /// The first moving mesh whose steps did not check out, reported by `build`.
    bad_steps: Option<WorldError>,
}

/// A geometry before its BVH is built.
#[derive(Clone, Debug)]
enum PendingGeometry<P> {
    Triangles(Vec<Triangle>),
    Prims(Vec<P>),
    /// A moving mesh's time steps, checked.
    MovingTriangles(Vec<Vec<Triangle>>),
}

impl<P> Default for WorldBuilder<P> {
    fn default() -> Self {
        WorldBuilder {
            pending: Vec::new(),
            options: Vec::new(),
            filters: Vec::new(),
            instances: Vec::new(),
            motions: Vec::new(),
            bad_mesh: None,
            bad_steps: None,
        }
    }
}

impl<P: Primitive> WorldBuilder<P> {
    /// An empty builder: no geometries, no instances.
    pub fn new() -> Self {
        WorldBuilder::default()
    }

    /// Adds an indexed triangle mesh as a geometry (read now: the buffers need not outlive
    /// the call). An index past the vertices is reported by [`WorldBuilder::build`], naming
    /// the geometry; it is also returned here.
    ///
    /// # Errors
    /// [`MeshError`] when an index names no vertex.
    pub fn add_mesh<'v>(
        &mut self,
        positions: impl Into<Positions<'v>>,
        indices: &[[u32; 3]],
    ) -> Result<GeometryId, MeshError> {
        let id = GeometryId(self.pending.len() as u32);
        match Mesh::new(positions.into(), indices) {
            Ok(mesh) => {
                let tris = (0..indices.len() as u32)
                    .map(|i| mesh.triangle(i))
                    .collect();
                self.pending.push(PendingGeometry::Triangles(tris));
                Ok(id)
            }
            Err(e) => {
                // Keeps the numbering of the geometries after it; `build` reports the error.
                self.pending.push(PendingGeometry::Triangles(Vec::new()));
                self.bad_mesh.get_or_insert((id.0 as usize, e.clone()));
                Err(e)
            }
        }
    }

    /// Adds triangles as a geometry.
    pub fn add_triangles(&mut self, tris: Vec<Triangle>) -> GeometryId {
        self.pending.push(PendingGeometry::Triangles(tris));
        GeometryId(self.pending.len() as u32 - 1)
    }

    /// Adds a deforming triangle mesh as a geometry: `steps[j]` its triangles at time
    /// `j / (steps.len() - 1)` of the shutter, the same triangles in the same order at every
    /// step. A ray at time `t` ([`Ray::time`](crate::Ray::time), clamped into `[0, 1]`, NaN
    /// as 0) meets the triangles interpolated to `t`
    /// ([`MovingTriangles::triangle_at`](super::MovingTriangles::triangle_at)); its hits name
    /// the triangle's index in a step. It is placed by instances as any geometry is (moving
    /// instances too). Its BVHs (one per pair of neighbouring steps) are built on the build's
    /// instruction set with the binned SAH builder, whatever preset or layout the options name.
    ///
    /// Packets go into it ray by ray (each at its time); point queries at a time
    /// ([`World::closest_point_at`](super::World::closest_point_at)) measure its triangles
    /// where they are then (walking the tree of that time's segment); a world holding one
    /// is saved with its steps ([`World::save`](super::World::save), world file version 2),
    /// its trees built again at load.
    ///
    /// ```
    /// use quiver_rt::glam::Vec3A;
    /// use quiver_rt::{BuildOptions, Instance, Ray, RayQuery, Triangle, World, WorldError};
    /// let tri = |x: f32| Triangle::new(Vec3A::new(x, 0.0, 0.0), Vec3A::new(x + 1.0, 0.0, 0.0), Vec3A::new(x, 1.0, 0.0));
    /// let mut b = World::builder();
    /// // Slides 4 along x while the shutter is open.
    /// let g = b.add_moving_triangles(vec![vec![tri(0.0)], vec![tri(4.0)]])?;
    /// b.add_instance(Instance::of(g));
    /// let world = b.build(&BuildOptions::default())?;
    /// let ray = Ray::new(Vec3A::new(2.2, 0.2, 1.0), -Vec3A::Z);
    /// assert!(world.closest_hit(&ray).is_none());
    /// assert_eq!(world.closest_hit(&ray.with_time(0.5)).map(|h| h.prim), Some(0));
    ///
    /// // Steps that cannot make a moving mesh are refused, naming what is wrong.
    /// let mut b = World::builder();
    /// let e = b.add_moving_triangles(vec![vec![tri(0.0)], vec![]]).unwrap_err();
    /// assert_eq!(e, WorldError::Steps { geometry: 0, step: Some(1), why: "a different number of triangles than step 0" });
    /// # Ok::<(), WorldError>(())
    /// ```
    ///
    /// # Errors
    /// [`WorldError::Steps`] for fewer than two steps, steps of different triangle counts or
    /// a vertex that is not finite (also reported by [`WorldBuilder::build`]; the id is then
    /// taken by an empty geometry, so the ids after it stay).
    pub fn add_moving_triangles(
        &mut self,
        steps: Vec<Vec<Triangle>>,
    ) -> Result<GeometryId, WorldError> {
        let g = self.pending.len();
        match super::deform::check_steps(&steps) {
            Ok(()) => {
                self.pending.push(PendingGeometry::MovingTriangles(steps));
                Ok(GeometryId(g as u32))
            }
            Err(e) => {
                let e = WorldError::steps(g, e);
                self.pending.push(PendingGeometry::Triangles(Vec::new()));
                self.bad_steps.get_or_insert(e.clone());
                Err(e)
            }
        }
    }

    /// Adds primitives of the world's type as a geometry.
    pub fn add_prims(&mut self, prims: Vec<P>) -> GeometryId {
        self.pending.push(PendingGeometry::Prims(prims));
        GeometryId(self.pending.len() as u32 - 1)
    }

    /// Builds geometry `geometry` with `options` (its own preset, layout, leaf size or
    /// instruction set) rather than with the options [`WorldBuilder::build`] is given. The
    /// pool is not taken: every geometry builds on the build's pool.
    ///
    /// ```
    /// use quiver_rt::{BuildOptions, Instance, Layout, Triangle, World};
    /// use quiver_rt::glam::Vec3A;
    /// let tri = Triangle::new(Vec3A::ZERO, Vec3A::X, Vec3A::Y);
    /// let mut b = World::builder();
    /// let leaves = b.add_triangles(vec![tri; 64]);
    /// b.set_options(leaves, &BuildOptions::fast().layout(Layout::Bvh4Quant)).unwrap();
    /// b.add_instance(Instance::of(leaves));
    /// let world = b.build(&BuildOptions::default()).unwrap();
    /// assert_eq!(world.geometries().len(), 1);
    /// ```
    ///
    /// # Errors
    /// [`WorldError::NoGeometry`] when `geometry` was not added.
    pub fn set_options(
        &mut self,
        geometry: GeometryId,
        options: &BuildOptions<'_>,
    ) -> Result<(), WorldError> {
        let g = self.pending_index(geometry)?;
        set_slot(&mut self.options, g, Some(options.without_pool()));
        Ok(())
    }

    /// Gives geometry `geometry` its own filter: every candidate hit of the geometry, in
    /// any instance, is kept only when `keep` accepts it (after the query's own filter, if
    /// any). An alpha test on foliage cards, say, called for the cards' hits only.
    ///
    /// ```
    /// use quiver_rt::{BuildOptions, Instance, Ray, RayQuery, Triangle, World, WorldHit};
    /// use quiver_rt::glam::Vec3A;
    /// let card = Triangle::new(Vec3A::ZERO, Vec3A::X, Vec3A::Y);
    /// let wall = Triangle::new(Vec3A::new(0.0, 0.0, -1.0), Vec3A::new(1.0, 0.0, -1.0), Vec3A::new(0.0, 1.0, -1.0));
    /// let mut b = World::builder();
    /// let leaves = b.add_triangles(vec![card]);
    /// let walls = b.add_triangles(vec![wall]);
    /// // Cut-out where u > 0.3: the ray passes through the card and meets the wall.
    /// b.set_filter(leaves, |h: &WorldHit| h.u <= 0.3).unwrap();
    /// b.add_instance(Instance::of(leaves));
    /// b.add_instance(Instance::of(walls));
    /// let world = b.build(&BuildOptions::default()).unwrap();
    /// let ray = Ray::new(Vec3A::new(0.5, 0.2, 1.0), -Vec3A::Z);
    /// assert_eq!(world.closest_hit(&ray).map(|h| h.geometry), Some(walls));
    /// let ray = Ray::new(Vec3A::new(0.1, 0.2, 1.0), -Vec3A::Z);
    /// assert_eq!(world.closest_hit(&ray).map(|h| h.geometry), Some(leaves));
    /// ```
    ///
    /// # Errors
    /// [`WorldError::NoGeometry`] when `geometry` was not added.
    pub fn set_filter(
        &mut self,
        geometry: GeometryId,
        keep: impl Fn(&WorldHit) -> bool + Send + Sync + 'static,
    ) -> Result<(), WorldError> {
        let g = self.pending_index(geometry)?;
        set_slot(&mut self.filters, g, Some(GeometryFilter::new(keep)));
        Ok(())
    }

    /// The index of `geometry` among those added, or the error naming it.
    fn pending_index(&self, geometry: GeometryId) -> Result<usize, WorldError> {
        let g = geometry.0 as usize;
        if g < self.pending.len() {
            Ok(g)
        } else {
            Err(WorldError::NoGeometry {
                geometry: geometry.0,
                geometries: self.pending.len(),
            })
        }
    }

    /// Adds an instance; returns its id, the index [`WorldHit::instance`](super::WorldHit)
    /// reports.
    pub fn add_instance(&mut self, instance: Instance) -> InstanceId {
        self.instances.push(instance);
        InstanceId(self.instances.len() as u32 - 1)
    }

    /// Adds an instance that moves by `motion` over the shutter: a ray at time `t`
    /// ([`Ray::time`](crate::Ray::time)) meets it where [`Motion::at`] places it then.
    /// `instance`'s own transform is replaced by the motion's first key (what
    /// [`World::instance`] reports, and where point queries find the instance). The motion is
    /// checked by [`WorldBuilder::build`] ([`WorldError::Motion`]).
    ///
    /// ```
    /// use quiver_rt::glam::{Affine3A, Vec3, Vec3A};
    /// use quiver_rt::{BuildOptions, Instance, Motion, Ray, RayQuery, Triangle, World};
    /// let mut b = World::builder();
    /// let g = b.add_triangles(vec![Triangle::new(Vec3A::ZERO, Vec3A::X, Vec3A::Y)]);
    /// // Slides 4 along x while the shutter is open.
    /// let slide = Motion::linear(vec![
    ///     Affine3A::IDENTITY,
    ///     Affine3A::from_translation(Vec3::new(4.0, 0.0, 0.0)),
    /// ]);
    /// b.add_moving_instance(Instance::of(g), slide);
    /// let world = b.build(&BuildOptions::default())?;
    /// let ray = Ray::new(Vec3A::new(2.2, 0.2, 1.0), -Vec3A::Z);
    /// assert!(world.closest_hit(&ray).is_none()); // at time 0 the triangle is at x in [0, 1]
    /// assert_eq!(world.closest_hit(&ray.with_time(0.5)).map(|h| h.t), Some(1.0));
    /// # Ok::<(), quiver_rt::WorldError>(())
    /// ```
    pub fn add_moving_instance(&mut self, instance: Instance, motion: Motion) -> InstanceId {
        let id = self.add_instance(instance.transform(motion.at(0.0)));
        set_slot(&mut self.motions, id.0 as usize, Some(motion));
        id
    }

    /// Builds every geometry's BVH with `options` (in parallel, on its pool) and the
    /// top-level BVH over the instances' world boxes (binned SAH, 8-wide nodes, on
    /// `options`' instruction set). The same builder gives the same world on any pool.
    ///
    /// # Errors
    /// [`WorldError`] for a build setting out of range ([`WorldError::Config`]), more than
    /// `u32::MAX - 1` instances or geometries, a bad mesh, an instance naming no geometry, a
    /// transform that is not finite or not invertible, or a motion that cannot move an
    /// instance ([`WorldError::Motion`]). An empty world is not an error: it is hit by nothing.
    pub fn build(self, options: &BuildOptions<'_>) -> Result<World<P>, WorldError> {
        use rayon::prelude::*;
        options.config.check().map_err(WorldError::Config)?;
        for own in self.options.iter().flatten() {
            own.config.check().map_err(WorldError::Config)?;
        }
        if self.instances.len() >= u32::MAX as usize || self.pending.len() >= u32::MAX as usize {
            return Err(WorldError::TooMany);
        }
        if let Some((geometry, error)) = self.bad_mesh {
            return Err(WorldError::Mesh { geometry, error });
        }
        if let Some(e) = self.bad_steps {
            return Err(e);
        }
        // Checked before the geometries' builds, which are the long part.
        let leaves = placements(&self.instances, &self.motions, self.pending.len())?;
        let mut own: Vec<Option<BuildOptions<'_>>> = vec![None; self.pending.len()];
        for (slot, o) in own.iter_mut().zip(self.options) {
            *slot = o.map(|o| o.pool_of(options));
        }
        let geometries: Vec<Geometry<P>> = options.run(|| {
            self.pending
                .into_par_iter()
                .zip(own)
                .map(|(s, own)| {
                    let options = own.as_ref().unwrap_or(options);
                    match s {
                        PendingGeometry::Triangles(t) => {
                            Geometry::Triangles(checked(&t, options), t)
                        }
                        PendingGeometry::Prims(p) => Geometry::Prims(checked(&p, options), p),
                        PendingGeometry::MovingTriangles(s) => {
                            Geometry::MovingTriangles(MovingTriangles::new(s, options.chosen_isa()))
                        }
                    }
                })
                .collect()
        });
        let placed = Placed {
            geometries,
            instances: self.instances,
            motions: self.motions,
            removed: Vec::new(),
            leaves,
        };
        let mut world = placed.world(options);
        world.filters = self.filters;
        Ok(world)
    }
}

/// Built geometries and their instances (`motions[i]`: instance `i`'s motion; `removed[i]`:
/// instance `i` removed; either may be shorter than `instances`), with the instances' leaf
/// records ([`placements`], which checked them): a world but for its top level.
pub(super) struct Placed<P> {
    pub geometries: Vec<Geometry<P>>,
    pub instances: Vec<Instance>,
    pub motions: Vec<Option<Motion>>,
    pub removed: Vec<bool>,
    pub leaves: Vec<InstanceLeaf>,
}

impl<P: Primitive> Placed<P> {
    /// The world, its top level built over the instances (on `options`' pool, for its
    /// instruction set), no filters set.
    pub fn world(self, options: &BuildOptions<'_>) -> World<P> {
        let Placed {
            geometries,
            instances,
            motions,
            removed,
            leaves,
        } = self;
        let boxes = options.run(|| world_boxes(&instances, &motions, &geometries, &removed));
        let top = options.run(|| top_level(&leaves, &boxes, options.chosen_isa()));
        let bounds = boxes.iter().fold(Aabb::EMPTY, |b, w| b.union(w));
        let ends = TopEnds::of(&top, &instances, &motions, &geometries, &removed);
        World {
            geometries,
            instances,
            motions,
            removed,
            filters: Vec::new(),
            top,
            ends,
            bounds,
        }
    }
}

/// Sets entry `i` of a per-geometry list that holds entries up to the last one set, growing
/// it with `None`s as needed.
pub(super) fn set_slot<T: Clone>(slots: &mut Vec<Option<T>>, i: usize, value: Option<T>) {
    if slots.len() <= i {
        slots.resize(i + 1, None);
    }
    slots[i] = value;
}

/// The BVH over `prims` with `options`, whose settings were checked.
fn checked<Q: Primitive>(prims: &[Q], options: &BuildOptions<'_>) -> Bvh<Q> {
    Bvh::build(prims, options).expect("the settings were checked")
}
