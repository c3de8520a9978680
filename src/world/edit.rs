//! Changing a [`World`] without building it again: [`WorldEdit`] refits, replaces or
//! rebuilds one geometry, adds geometries, adds, removes, moves and re-masks instances; when
//! the edit ends, the instances' world boxes are recomputed and the top-level BVH refit or
//! rebuilt, so the world is never seen half edited.

use super::builder::set_slot;
use super::deform::check_steps;
use super::instance::{check_instance, motion_of, placement};
use super::top::{instance_box, top_level, world_boxes, TopEnds};
use super::{Geometry, GeometryFilter, GeometryId, InstanceId, InstanceLeaf};
use super::{Motion, MovingTriangles, World, WorldError};
use crate::geometry::{Aabb, Triangle};
use crate::layout::moved::RefitTarget;
use crate::layout::refit::RefitInput;
use crate::mesh::{Mesh, Positions};
use crate::primitive::Primitive;
use crate::{BuildOptions, Bvh, Instance};
use glam::Affine3A;
use rayon::prelude::*;
use std::sync::atomic::{AtomicBool, Ordering};

/// Changes to a [`World`] between frames of an animation, from [`World::edit`]: geometries
/// refit to moved primitives ([`Bvh::refit`](crate::Bvh::refit): the same count, the same
/// order, the same tree), instances given new transforms or masks. Each change is checked and
/// made at once (a refused one changes nothing); when the edit ends ([`WorldEdit::commit`], or
/// when it is dropped, also by an early `?`) the world boxes of the instances that changed or
/// place a changed geometry are recomputed and the top-level BVH is refit over them. The edit
/// borrows the world, so no query sees it in between. The result answers exactly as a world
/// built afresh from the new geometries and instances does.
///
/// Structure changes too, each touching only what it names: [`WorldEdit::add_instance`],
/// [`WorldEdit::remove_instance`] and [`WorldEdit::set_instance`] (ids stay stable: a removed
/// instance's id is never given to another), [`WorldEdit::add_triangles`] and its kin (a new
/// geometry, built alone), [`WorldEdit::replace_triangles`] and its kin (new primitives, any
/// count, for one geometry, built alone with the options given: its preset, layout and leaf
/// size are its own) and [`WorldEdit::rebuild_geometry`] (the same primitives, a fresh tree,
/// for a geometry whose refits have loosened it).
///
/// The top level is refit by default: the tree of the last build, its boxes fit to where the
/// instances are now, as cheap as a pass over its nodes. It is rebuilt instead when an
/// instance was added, or an instance's world box left f32's range or came back into it (the
/// build leaves such instances out), and when [`WorldEdit::rebuild_top`] asks for it, as a
/// renderer does once motion has loosened the tree (Embree's top-level build quality).
///
/// Pools: geometry builds run on the pool of the [`BuildOptions`] they are given (the
/// current pool when it names none); the top level's refit or rebuild and the refits of
/// geometries run on the pool the edit ends on (the current one: wrap
/// [`WorldEdit::commit`] in `pool.install` to choose).
///
/// ```
/// use quiver_rt::glam::{Affine3A, Vec3A};
/// use quiver_rt::{BuildOptions, Instance, InstanceId, Ray, RayQuery, World};
/// let indices = [[0, 1, 2], [0, 2, 3]];
/// let square = |z: f32| [[0.0, 0.0, z], [1.0, 0.0, z], [1.0, 1.0, z], [0.0, 1.0, z]];
/// let mut b = World::builder();
/// let g = b.add_mesh(&square(0.0), &indices).unwrap();
/// b.add_instance(Instance::of(g));
/// let moving = b.add_instance(Instance::of(g).transform(Affine3A::from_translation(Vec3A::X.into())));
/// let mut world = b.build(&BuildOptions::default()).unwrap();
/// let ray = Ray::new(Vec3A::new(1.5, 0.5, 1.0), -Vec3A::Z);
/// assert_eq!(world.closest_hit(&ray).map(|h| (h.instance, h.t)), Some((moving, 1.0)));
///
/// // Next frame: the mesh sinks by 1, the second instance slides away.
/// let mut edit = world.edit();
/// edit.refit_mesh(g, &square(-1.0), &indices).unwrap();
/// edit.set_transform(moving, Affine3A::from_translation(Vec3A::new(3.0, 0.0, 0.0).into()))
///     .unwrap();
/// edit.commit();
/// assert_eq!(world.closest_hit(&ray), None);
/// let ray = Ray::new(Vec3A::new(3.5, 0.5, 1.0), -Vec3A::Z);
/// assert_eq!(world.closest_hit(&ray).map(|h| (h.instance, h.t)), Some((moving, 2.0)));
///
/// // A refused change names what was wrong and changes nothing.
/// let mut edit = world.edit();
/// assert!(edit.refit_mesh(g, &square(0.0)[..2], &indices).is_err());
/// assert!(edit.set_transform(InstanceId(7), Affine3A::IDENTITY).is_err());
/// ```
#[must_use = "the top level is refit when the edit ends"]
pub struct WorldEdit<'w, P: Primitive = Triangle> {
    world: &'w mut World<P>,
    /// A geometry was refit during the edit (the top level's refit computes every world box
    /// afresh, so it needs not know which).
    geometry_refit: bool,
    /// Instances moved or re-masked during the edit (empty until the first).
    instances: Vec<bool>,
    /// Rebuild the top level when the edit ends rather than refit it.
    rebuild_top: bool,
}

impl<P: Primitive> World<P> {
    /// Starts changing the world for the next frame of an animation (see [`WorldEdit`]).
    pub fn edit(&mut self) -> WorldEdit<'_, P> {
        WorldEdit {
            world: self,
            geometry_refit: false,
            instances: Vec::new(),
            rebuild_top: false,
        }
    }
}

fn mark(flags: &mut Vec<bool>, len: usize, i: usize) {
    if flags.len() < len.max(i + 1) {
        flags.resize(len.max(i + 1), false);
    }
    flags[i] = true;
}

impl<P: Primitive> WorldEdit<'_, P> {
    /// Geometry `g` for a change.
    fn geometry(&mut self, g: GeometryId) -> Result<&mut Geometry<P>, WorldError> {
        let n = self.world.geometries.len();
        self.world
            .geometries
            .get_mut(g.0 as usize)
            .ok_or(WorldError::NoGeometry {
                geometry: g.0,
                geometries: n,
            })
    }

    /// Refits triangle geometry `geometry` (added by [`super::WorldBuilder::add_triangles`])
    /// to `tris`: its triangles, moved, in the same order.
    ///
    /// # Errors
    /// [`WorldError::NoGeometry`], [`WorldError::GeometryKind`] for a geometry of the world's
    /// own primitive type or [`WorldError::Refit`] with [`Bvh::refit`](crate::Bvh::refit)'s
    /// reason.
    pub fn refit_triangles(
        &mut self,
        geometry: GeometryId,
        tris: &[Triangle],
    ) -> Result<(), WorldError> {
        let done = match self.geometry(geometry)? {
            Geometry::Triangles(bvh, kept) => refit_kept(geometry, bvh, kept, tris),
            Geometry::Prims(..) => Err(prims_not_triangles(geometry)),
            Geometry::MovingTriangles(_) => Err(moving_not_triangles(geometry)),
        };
        self.refit(done)
    }

    /// Refits mesh geometry `geometry` (added by [`super::WorldBuilder::add_mesh`]) to new vertex
    /// positions for the same triangles ([`Bvh::refit_mesh`](crate::Bvh::refit_mesh)).
    ///
    /// # Errors
    /// As [`WorldEdit::refit_triangles`]; a bad index is a [`WorldError::Refit`] naming the
    /// mesh error.
    pub fn refit_mesh<'v>(
        &mut self,
        geometry: GeometryId,
        positions: impl Into<Positions<'v>>,
        indices: &[[u32; 3]],
    ) -> Result<(), WorldError> {
        let positions = positions.into();
        let done = match self.geometry(geometry)? {
            Geometry::Triangles(bvh, kept) => {
                bvh.refit_mesh(positions, indices)
                    .map_err(|error| WorldError::Refit {
                        geometry: geometry.0,
                        error,
                    })?;
                // The refit checked the indices and the count.
                if let Ok(mesh) = Mesh::new(positions, indices) {
                    kept.par_iter_mut()
                        .enumerate()
                        .for_each(|(i, t)| *t = mesh.triangle(i as u32));
                }
                Ok(())
            }
            Geometry::Prims(..) => Err(prims_not_triangles(geometry)),
            Geometry::MovingTriangles(_) => Err(moving_not_triangles(geometry)),
        };
        self.refit(done)
    }

    /// Refits geometry `geometry` of the world's primitive type (added by
    /// [`super::WorldBuilder::add_prims`]) to `prims`: its primitives, moved, in the same
    /// order.
    ///
    /// # Errors
    /// As [`WorldEdit::refit_triangles`], [`WorldError::GeometryKind`] for a triangle
    /// geometry.
    pub fn refit_prims(&mut self, geometry: GeometryId, prims: &[P]) -> Result<(), WorldError> {
        let done = match self.geometry(geometry)? {
            Geometry::Prims(bvh, kept) => refit_kept(geometry, bvh, kept, prims),
            Geometry::Triangles(..) => Err(WorldError::GeometryKind {
                geometry: geometry.0,
                holds: "triangles",
            }),
            Geometry::MovingTriangles(_) => Err(moving_not_triangles(geometry)),
        };
        self.refit(done)
    }

    /// Refits moving mesh `geometry` (added by
    /// [`super::WorldBuilder::add_moving_triangles`]) to new time steps: as many steps as it
    /// has, each of its triangles in the same order, moved. Each segment's tree is kept and
    /// its boxes at both ends computed afresh (a refit, not a rebuild: a tree that motion has
    /// loosened is built again by [`WorldEdit::rebuild_geometry`]).
    ///
    /// ```
    /// use quiver_rt::glam::Vec3A;
    /// use quiver_rt::{BuildOptions, Instance, Ray, RayQuery, Triangle, World, WorldError};
    /// let tri = |z: f32| Triangle::new(Vec3A::new(0.0, 0.0, z), Vec3A::new(1.0, 0.0, z), Vec3A::new(0.0, 1.0, z));
    /// let mut b = World::builder();
    /// let g = b.add_moving_triangles(vec![vec![tri(0.0)], vec![tri(-2.0)]])?;
    /// b.add_instance(Instance::of(g));
    /// let mut world = b.build(&BuildOptions::default())?;
    /// let ray = Ray::new(Vec3A::new(0.2, 0.2, 1.0), -Vec3A::Z).with_time(0.5);
    /// assert_eq!(world.closest_hit(&ray).map(|h| h.t), Some(2.0));
    ///
    /// let mut edit = world.edit();
    /// edit.refit_moving_triangles(g, vec![vec![tri(-4.0)], vec![tri(-6.0)]])?;
    /// // Three steps where the mesh has two: refused, nothing changed.
    /// let three = vec![vec![tri(0.0)]; 3];
    /// assert!(matches!(edit.refit_moving_triangles(g, three), Err(WorldError::Steps { .. })));
    /// edit.commit();
    /// assert_eq!(world.closest_hit(&ray).map(|h| h.t), Some(6.0));
    /// # Ok::<(), WorldError>(())
    /// ```
    ///
    /// # Errors
    /// [`WorldError::NoGeometry`], [`WorldError::GeometryKind`] for a geometry that is not a
    /// moving mesh, [`WorldError::Steps`] for steps that could not make one (as
    /// [`super::WorldBuilder::add_moving_triangles`] checks them) or of another count of
    /// steps or triangles than the mesh has.
    pub fn refit_moving_triangles(
        &mut self,
        geometry: GeometryId,
        steps: Vec<Vec<Triangle>>,
    ) -> Result<(), WorldError> {
        let g = geometry.0 as usize;
        let done = match self.geometry(geometry)? {
            Geometry::MovingTriangles(m) => {
                check_steps(&steps).map_err(|e| WorldError::steps(g, e))?;
                if steps.len() != m.steps().len() {
                    return Err(WorldError::steps(
                        g,
                        (None, "a different number of steps than the mesh refit"),
                    ));
                }
                if steps[0].len() != m.len() {
                    return Err(WorldError::steps(
                        g,
                        (
                            Some(0),
                            "a different number of triangles than the mesh refit",
                        ),
                    ));
                }
                m.refit(steps);
                Ok(())
            }
            Geometry::Triangles(..) => Err(WorldError::GeometryKind {
                geometry: geometry.0,
                holds: "triangles",
            }),
            Geometry::Prims(..) => Err(prims_not_triangles(geometry)),
        };
        self.refit(done)
    }

    /// Notes a geometry as refit once `done` says it was.
    fn refit(&mut self, done: Result<(), WorldError>) -> Result<(), WorldError> {
        done?;
        self.geometry_refit = true;
        Ok(())
    }

    /// Instance `i`, to be changed to `change(old)` and, where `motion` is given, to move by
    /// it (`Some(None)`: to stand still); checked as the builder checks an instance.
    fn instance(
        &mut self,
        InstanceId(i): InstanceId,
        change: impl FnOnce(&mut super::Instance),
        motion: Option<Option<Motion>>,
    ) -> Result<(), WorldError> {
        let n = self.world.instances.len();
        let Some(old) = self.world.instances.get(i as usize) else {
            return Err(WorldError::NoInstance {
                instance: i,
                instances: n,
            });
        };
        if self.world.removed.get(i as usize) == Some(&true) {
            return Err(WorldError::Removed { instance: i });
        }
        let mut new = *old;
        change(&mut new);
        let moving = match &motion {
            Some(m) => m.as_ref(),
            None => motion_of(&self.world.motions, i as usize),
        };
        check_instance(i as usize, &new, moving, self.world.geometries.len())?;
        self.world.instances[i as usize] = new;
        match motion {
            Some(None) if self.world.motions.len() <= i as usize => {}
            Some(m) => set_slot(&mut self.world.motions, i as usize, m),
            None => {}
        }
        mark(&mut self.instances, n, i as usize);
        Ok(())
    }

    /// Places instance `instance` by `transform` (object to world) from now on; an instance
    /// that moved stands still there.
    ///
    /// # Errors
    /// [`WorldError::NoInstance`], or [`WorldError::Transform`] for a transform that is not
    /// finite or not invertible, as [`super::WorldBuilder::build`] refuses.
    pub fn set_transform(
        &mut self,
        instance: InstanceId,
        transform: Affine3A,
    ) -> Result<(), WorldError> {
        self.instance(instance, |i| i.transform = transform, Some(None))
    }

    /// Moves instance `instance` by `motion` from now on (as
    /// [`WorldBuilder::add_moving_instance`](super::WorldBuilder::add_moving_instance) does:
    /// its transform becomes the motion's first key).
    ///
    /// ```
    /// use quiver_rt::glam::{Affine3A, Vec3, Vec3A};
    /// use quiver_rt::{BuildOptions, Instance, Motion, Ray, RayQuery, Triangle, World};
    /// let mut b = World::builder();
    /// let g = b.add_triangles(vec![Triangle::new(Vec3A::ZERO, Vec3A::X, Vec3A::Y)]);
    /// let i = b.add_instance(Instance::of(g));
    /// let mut world = b.build(&BuildOptions::default())?;
    /// let rise = Motion::linear(vec![Affine3A::IDENTITY, Affine3A::from_translation(Vec3::Z)]);
    /// world.edit().set_motion(i, rise)?;
    /// let ray = Ray::new(Vec3A::new(0.2, 0.2, 5.0), -Vec3A::Z).with_time(0.5);
    /// assert_eq!(world.closest_hit(&ray).map(|h| h.t), Some(4.5));
    /// world.edit().set_transform(i, Affine3A::IDENTITY)?; // stands still again
    /// assert!(world.motion(i).is_none());
    /// assert_eq!(world.closest_hit(&ray).map(|h| h.t), Some(5.0));
    /// # Ok::<(), quiver_rt::WorldError>(())
    /// ```
    ///
    /// # Errors
    /// [`WorldError::NoInstance`], [`WorldError::Removed`], or [`WorldError::Motion`] for a
    /// motion [`super::WorldBuilder::build`] refuses.
    pub fn set_motion(&mut self, instance: InstanceId, motion: Motion) -> Result<(), WorldError> {
        let first = motion.keys().first().copied().unwrap_or(Affine3A::IDENTITY);
        self.instance(instance, |i| i.transform = first, Some(Some(motion)))
    }

    /// Shows instance `instance` only to rays whose mask shares a bit with `mask`.
    ///
    /// # Errors
    /// [`WorldError::NoInstance`].
    pub fn set_mask(&mut self, instance: InstanceId, mask: u32) -> Result<(), WorldError> {
        self.instance(instance, |i| i.mask = mask, None)
    }

    /// Replaces instance `instance` by `new` (another geometry, transform, mask or user
    /// id; standing still); its id stays.
    ///
    /// # Errors
    /// As [`WorldEdit::set_transform`], and [`WorldError::Geometry`] when `new` names no
    /// geometry.
    pub fn set_instance(&mut self, instance: InstanceId, new: Instance) -> Result<(), WorldError> {
        self.instance(instance, |i| *i = new, Some(None))
    }

    /// Adds an instance; returns its id, one past every id given before (removed ones
    /// included). The top level is rebuilt when the edit ends.
    ///
    /// # Errors
    /// As [`super::WorldBuilder::build`] refuses an instance: [`WorldError::Geometry`],
    /// [`WorldError::Transform`], or [`WorldError::TooMany`].
    pub fn add_instance(&mut self, instance: Instance) -> Result<InstanceId, WorldError> {
        let i = self.world.instances.len();
        if i >= u32::MAX as usize - 1 {
            return Err(WorldError::TooMany);
        }
        check_instance(i, &instance, None, self.world.geometries.len())?;
        self.world.instances.push(instance);
        mark(&mut self.instances, i + 1, i);
        Ok(InstanceId(i as u32))
    }

    /// Removes instance `instance` from the world: no ray meets it from the end of the edit;
    /// its id is not given to another ([`World::is_live`] tells it is gone).
    ///
    /// # Errors
    /// [`WorldError::NoInstance`], [`WorldError::Removed`] when it was removed before.
    pub fn remove_instance(&mut self, instance: InstanceId) -> Result<(), WorldError> {
        self.instance(instance, |_| (), None)?;
        let n = self.world.instances.len();
        mark(&mut self.world.removed, n, instance.0 as usize);
        Ok(())
    }

    /// Adds triangles as a new geometry, its BVH built now with `options`; returns its id.
    ///
    /// # Errors
    /// [`WorldError::Config`] for options out of range, [`WorldError::TooMany`].
    pub fn add_triangles(
        &mut self,
        tris: Vec<Triangle>,
        options: &BuildOptions<'_>,
    ) -> Result<GeometryId, WorldError> {
        let g = built(tris, options, Geometry::Triangles)?;
        self.push_geometry(g)
    }

    /// Adds a moving mesh as a new geometry, its BVHs built now on `options`' instruction set
    /// (as [`super::WorldBuilder::add_moving_triangles`] builds them); returns its id.
    ///
    /// ```
    /// use quiver_rt::glam::Vec3A;
    /// use quiver_rt::{BuildOptions, Instance, Ray, RayQuery, Triangle, World};
    /// let tri = |z: f32| Triangle::new(Vec3A::new(0.0, 0.0, z), Vec3A::new(1.0, 0.0, z), Vec3A::new(0.0, 1.0, z));
    /// let mut world = World::builder().build(&BuildOptions::default())?;
    /// let mut edit = world.edit();
    /// let g = edit.add_moving_triangles(vec![vec![tri(0.0)], vec![tri(-2.0)]], &BuildOptions::default())?;
    /// edit.add_instance(Instance::of(g))?;
    /// edit.commit();
    /// let ray = Ray::new(Vec3A::new(0.2, 0.2, 1.0), -Vec3A::Z);
    /// assert_eq!(world.closest_hit(&ray.with_time(0.5)).map(|h| h.t), Some(2.0));
    /// # Ok::<(), quiver_rt::WorldError>(())
    /// ```
    ///
    /// # Errors
    /// [`WorldError::Steps`] for steps that cannot make a moving mesh (as the builder checks
    /// them), [`WorldError::Config`], [`WorldError::TooMany`].
    pub fn add_moving_triangles(
        &mut self,
        steps: Vec<Vec<Triangle>>,
        options: &BuildOptions<'_>,
    ) -> Result<GeometryId, WorldError> {
        check_steps(&steps).map_err(|e| WorldError::steps(self.world.geometries.len(), e))?;
        options.config.check().map_err(WorldError::Config)?;
        let m = options.run(|| MovingTriangles::new(steps, options.chosen_isa()));
        self.push_geometry(Geometry::MovingTriangles(m))
    }

    /// Adds an indexed mesh as a new geometry ([`WorldEdit::add_triangles`]).
    ///
    /// # Errors
    /// As [`WorldEdit::add_triangles`], [`WorldError::Mesh`] for an index past the vertices.
    pub fn add_mesh<'v>(
        &mut self,
        positions: impl Into<Positions<'v>>,
        indices: &[[u32; 3]],
        options: &BuildOptions<'_>,
    ) -> Result<GeometryId, WorldError> {
        let tris = mesh_triangles(self.world.geometries.len(), positions.into(), indices)?;
        self.add_triangles(tris, options)
    }

    /// Adds primitives of the world's type as a new geometry ([`WorldEdit::add_triangles`]).
    ///
    /// # Errors
    /// As [`WorldEdit::add_triangles`].
    pub fn add_prims(
        &mut self,
        prims: Vec<P>,
        options: &BuildOptions<'_>,
    ) -> Result<GeometryId, WorldError> {
        let g = built(prims, options, Geometry::Prims)?;
        self.push_geometry(g)
    }

    /// Gives geometry `geometry` new triangles (any count, any topology), its BVH built
    /// afresh, alone, with `options`; every instance placing it places the new one.
    ///
    /// # Errors
    /// [`WorldError::NoGeometry`], [`WorldError::Config`].
    pub fn replace_triangles(
        &mut self,
        geometry: GeometryId,
        tris: Vec<Triangle>,
        options: &BuildOptions<'_>,
    ) -> Result<(), WorldError> {
        self.geometry(geometry)?;
        let g = built(tris, options, Geometry::Triangles)?;
        self.set_geometry(geometry, g)
    }

    /// Gives geometry `geometry` a new indexed mesh ([`WorldEdit::replace_triangles`]).
    ///
    /// # Errors
    /// As [`WorldEdit::replace_triangles`], [`WorldError::Mesh`] for an index past the
    /// vertices.
    pub fn replace_mesh<'v>(
        &mut self,
        geometry: GeometryId,
        positions: impl Into<Positions<'v>>,
        indices: &[[u32; 3]],
        options: &BuildOptions<'_>,
    ) -> Result<(), WorldError> {
        self.geometry(geometry)?;
        let tris = mesh_triangles(geometry.0 as usize, positions.into(), indices)?;
        self.replace_triangles(geometry, tris, options)
    }

    /// Gives geometry `geometry` new primitives of the world's type
    /// ([`WorldEdit::replace_triangles`]).
    ///
    /// # Errors
    /// As [`WorldEdit::replace_triangles`].
    pub fn replace_prims(
        &mut self,
        geometry: GeometryId,
        prims: Vec<P>,
        options: &BuildOptions<'_>,
    ) -> Result<(), WorldError> {
        self.geometry(geometry)?;
        let g = built(prims, options, Geometry::Prims)?;
        self.set_geometry(geometry, g)
    }

    /// Builds geometry `geometry`'s BVH again over its primitives as they are now, with
    /// `options` (another preset, layout or leaf size; or the same, for a tree that refits
    /// have loosened).
    ///
    /// # Errors
    /// [`WorldError::NoGeometry`], [`WorldError::Config`].
    pub fn rebuild_geometry(
        &mut self,
        geometry: GeometryId,
        options: &BuildOptions<'_>,
    ) -> Result<(), WorldError> {
        let g = match self.geometry(geometry)? {
            Geometry::Triangles(_, t) => built(t.clone(), options, Geometry::Triangles)?,
            Geometry::Prims(_, p) => built(p.clone(), options, Geometry::Prims)?,
            Geometry::MovingTriangles(m) => {
                options.config.check().map_err(WorldError::Config)?;
                Geometry::MovingTriangles(options.run(|| m.rebuilt(options.chosen_isa())))
            }
        };
        self.set_geometry(geometry, g)
    }

    /// Gives geometry `geometry` its own filter, or takes it away with `None`
    /// ([`super::WorldBuilder::set_filter`]).
    ///
    /// # Errors
    /// [`WorldError::NoGeometry`].
    pub fn set_filter(
        &mut self,
        geometry: GeometryId,
        keep: Option<GeometryFilter>,
    ) -> Result<(), WorldError> {
        self.geometry(geometry)?;
        super::builder::set_slot(&mut self.world.filters, geometry.0 as usize, keep);
        Ok(())
    }

    /// Rebuilds the top level when the edit ends, rather than refitting it: a tree fit to
    /// where the instances are now (a refit keeps the tree of the last build, which motion
    /// loosens).
    pub fn rebuild_top(&mut self) {
        self.rebuild_top = true;
    }

    fn push_geometry(&mut self, g: Geometry<P>) -> Result<GeometryId, WorldError> {
        let n = self.world.geometries.len();
        if n >= u32::MAX as usize - 1 {
            return Err(WorldError::TooMany);
        }
        self.world.geometries.push(g);
        Ok(GeometryId(n as u32))
    }

    fn set_geometry(&mut self, geometry: GeometryId, g: Geometry<P>) -> Result<(), WorldError> {
        *self.geometry(geometry)? = g;
        // Every world box is computed afresh by the top level's refit.
        self.geometry_refit = true;
        Ok(())
    }

    /// Ends the edit: the changed instances' world boxes are recomputed and the top level is
    /// refit or rebuilt (what dropping the edit also does).
    pub fn commit(self) {}

    /// Brings the top level up to date with the changes so far.
    fn finish(&mut self) {
        if !self.geometry_refit && self.instances.is_empty() && !self.rebuild_top {
            return;
        }
        self.world.refit_top(&self.instances, self.rebuild_top);
        self.geometry_refit = false;
        self.rebuild_top = false;
        self.instances.clear();
    }
}

/// Refits geometry `geometry`'s BVH to `moved` and its kept primitives (for normals) with it.
fn refit_kept<Q: Primitive>(
    geometry: GeometryId,
    bvh: &mut Bvh<Q>,
    kept: &mut [Q],
    moved: &[Q],
) -> Result<(), WorldError> {
    bvh.refit(moved).map_err(|error| WorldError::Refit {
        geometry: geometry.0,
        error,
    })?;
    kept.clone_from_slice(moved);
    Ok(())
}

/// A geometry of `prims` (`kind` is `Geometry::Triangles` or `Geometry::Prims`), its BVH
/// built with `options`.
fn built<Q: Primitive, P>(
    prims: Vec<Q>,
    options: &BuildOptions<'_>,
    kind: fn(Bvh<Q>, Vec<Q>) -> Geometry<P>,
) -> Result<Geometry<P>, WorldError> {
    options.config.check().map_err(WorldError::Config)?;
    let bvh = Bvh::build(&prims, options).expect("the settings were checked");
    Ok(kind(bvh, prims))
}

/// The triangles of a mesh that is to be geometry `geometry`.
fn mesh_triangles(
    geometry: usize,
    positions: Positions<'_>,
    indices: &[[u32; 3]],
) -> Result<Vec<Triangle>, WorldError> {
    let mesh =
        Mesh::new(positions, indices).map_err(|error| WorldError::Mesh { geometry, error })?;
    Ok((0..indices.len() as u32)
        .map(|i| mesh.triangle(i))
        .collect())
}

fn moving_not_triangles(geometry: GeometryId) -> WorldError {
    WorldError::GeometryKind {
        geometry: geometry.0,
        holds: "a moving mesh (refit by WorldEdit::refit_moving_triangles)",
    }
}

fn prims_not_triangles(geometry: GeometryId) -> WorldError {
    WorldError::GeometryKind {
        geometry: geometry.0,
        holds: "primitives of the world's type",
    }
}

impl<P: Primitive> Drop for WorldEdit<'_, P> {
    fn drop(&mut self) {
        self.finish();
    }
}

/// The top level's new primitives: each instance as placed now.
struct InstancesNow<'a, P> {
    instances: &'a [super::Instance],
    /// The moving instances' motions (shorter than `instances`: the rest do not move).
    motions: &'a [Option<super::Motion>],
    geometries: &'a [Geometry<P>],
    /// Which instances were removed (shorter than `instances`: the rest were not).
    removed: &'a [bool],
    /// Which instances changed (empty: none).
    moved_instances: &'a [bool],
    /// Set when an instance the top level holds has a world box out of f32's range now.
    lost: AtomicBool,
}

impl<P: Primitive> RefitInput<InstanceLeaf> for InstancesNow<'_, P> {
    fn get(&self, id: u32) -> InstanceLeaf {
        let inst = &self.instances[id as usize];
        let moving = motion_of(self.motions, id as usize).is_some();
        InstanceLeaf::new(id as usize, inst, placement(&inst.transform), moving)
    }

    fn refresh(&self, id: u32, p: &mut InstanceLeaf) {
        if self.moved_instances.get(id as usize) == Some(&true) {
            *p = self.get(id);
        }
    }

    /// The world box as placed now, from the instance's transform and its geometry's box:
    /// the record keeps none (it fills one line without), so the refit computes it for every
    /// instance, moved or not (eight corners transformed: small beside the refit's walk of
    /// the nodes, and a refit geometry needs no flag of its own).
    fn bounds(&self, id: u32, _: &InstanceLeaf) -> Aabb {
        let gone = self.removed.get(id as usize) == Some(&true);
        let motion = motion_of(self.motions, id as usize);
        let b = instance_box(&self.instances[id as usize], motion, self.geometries, gone);
        if !b.is_finite() {
            self.lost.store(true, Ordering::Relaxed);
        }
        b
    }
}

impl<P: Primitive> World<P> {
    /// The instances' world boxes recomputed and the top level refit over them (rebuilt
    /// instead when `rebuild` asks, or an instance's box went out of f32's range or came back,
    /// or an instance was removed or added: the build leaves out those out of range and
    /// those removed).
    fn refit_top(&mut self, moved_instances: &[bool], rebuild: bool) {
        let src = InstancesNow {
            instances: &self.instances,
            motions: &self.motions,
            geometries: &self.geometries,
            removed: &self.removed,
            moved_instances,
            lost: AtomicBool::new(false),
        };
        if !rebuild {
            // The refit walks the leaves with their input indices, which the top level does
            // not keep (`top_level`): each record's instance is its index.
            self.top.prim_ids = self.top.prims.iter().map(|p| p.instance).collect();
            self.top.refit_from(&src);
            self.top.prim_ids = Vec::new();
        }
        let n = src.instances.len();
        let mut rebuild = rebuild || src.lost.load(Ordering::Relaxed);
        if rebuild || self.top.prims.len() < n {
            let boxes = world_boxes(src.instances, src.motions, src.geometries, src.removed);
            if !rebuild {
                // Those the build left out must stay out of range.
                let mut in_top = vec![false; n];
                for p in &self.top.prims {
                    in_top[p.instance as usize] = true;
                }
                rebuild = (0..n).any(|i| !in_top[i] && boxes[i].is_finite());
            }
            if rebuild {
                let placed: Vec<InstanceLeaf> =
                    (0..n as u32).into_par_iter().map(|i| src.get(i)).collect();
                self.top = top_level(&placed, &boxes, self.top.isa());
            }
            // The world's box as the build takes it: the union of every instance's.
            self.bounds = boxes.iter().fold(Aabb::EMPTY, |b, w| b.union(w));
        } else {
            self.bounds = self.top.bounds;
        }
        self.ends = TopEnds::of(
            &self.top,
            &self.instances,
            &self.motions,
            &self.geometries,
            &self.removed,
        );
    }
}
