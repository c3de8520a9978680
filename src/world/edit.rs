//! Animating a [`World`]: [`WorldEdit`] refits geometries to moved primitives and moves or
//! re-masks instances; when the edit ends, the instances' world boxes are recomputed and the
//! top-level BVH refit, so the world is never seen half edited.

use super::{check_instance, instance_box, placement, top_level, world_boxes};
use super::{Geometry, GeometryId, Placed};
use super::{World, WorldError};
use crate::geometry::{Aabb, Triangle};
use crate::layout::refit::Source;
use crate::mesh::{Mesh, Positions};
use crate::primitive::Primitive;
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
/// A refit keeps each tree as it was built: see [`Bvh::refit`](crate::Bvh::refit) for when
/// motion has loosened a geometry's tree enough to rebuild it (a new world) instead. The top
/// level is rebuilt rather than refit when an instance's world box leaves f32's range or comes
/// back into it (the build leaves such instances out).
///
/// ```
/// use quiver_rt::glam::{Affine3A, Vec3A};
/// use quiver_rt::{BuildOptions, Instance, Ray, RayQuery, World};
/// let indices = [[0, 1, 2], [0, 2, 3]];
/// let square = |z: f32| [[0.0, 0.0, z], [1.0, 0.0, z], [1.0, 1.0, z], [0.0, 1.0, z]];
/// let mut b = World::builder();
/// let g = b.mesh(&square(0.0), &indices).unwrap();
/// b.instance(Instance::of(g));
/// let moving = b.instance(Instance::of(g).transform(Affine3A::from_translation(Vec3A::X.into())));
/// let mut world = b.build(&BuildOptions::default()).unwrap();
/// let ray = Ray::new(Vec3A::new(1.5, 0.5, 1.0), -Vec3A::Z);
/// assert_eq!(world.closest_hit(&ray).map(|h| (h.instance, h.t)), Some((1, 1.0)));
///
/// // Next frame: the mesh sinks by 1, the second instance slides away.
/// let mut edit = world.edit();
/// edit.mesh(g, &square(-1.0), &indices).unwrap();
/// edit.transform(moving, Affine3A::from_translation(Vec3A::new(3.0, 0.0, 0.0).into()))
///     .unwrap();
/// edit.commit();
/// assert_eq!(world.closest_hit(&ray), None);
/// let ray = Ray::new(Vec3A::new(3.5, 0.5, 1.0), -Vec3A::Z);
/// assert_eq!(world.closest_hit(&ray).map(|h| (h.instance, h.t)), Some((1, 2.0)));
///
/// // A refused change names what was wrong and changes nothing.
/// let mut edit = world.edit();
/// assert!(edit.mesh(g, &square(0.0)[..2], &indices).is_err());
/// assert!(edit.transform(7, Affine3A::IDENTITY).is_err());
/// ```
#[must_use = "the top level is refit when the edit ends"]
pub struct WorldEdit<'w, P: Primitive = Triangle> {
    world: &'w mut World<P>,
    /// A geometry was refit during the edit (the top level's refit computes every world box
    /// afresh, so it needs not know which).
    geometry_refit: bool,
    /// Instances moved or re-masked during the edit (empty until the first).
    instances: Vec<bool>,
}

impl<P: Primitive> World<P> {
    /// Starts changing the world for the next frame of an animation (see [`WorldEdit`]).
    pub fn edit(&mut self) -> WorldEdit<'_, P> {
        WorldEdit {
            world: self,
            geometry_refit: false,
            instances: Vec::new(),
        }
    }
}

fn mark(flags: &mut Vec<bool>, len: usize, i: usize) {
    if flags.is_empty() {
        flags.resize(len, false);
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

    /// Refits triangle geometry `geometry` (added by [`super::WorldBuilder::triangles`]) to
    /// `tris`: its triangles, moved, in the same order.
    ///
    /// # Errors
    /// [`WorldError::NoGeometry`], [`WorldError::GeometryKind`] for a geometry of the world's
    /// own primitive type or [`WorldError::Refit`] with [`Bvh::refit`](crate::Bvh::refit)'s
    /// reason.
    pub fn triangles(&mut self, geometry: GeometryId, tris: &[Triangle]) -> Result<(), WorldError> {
        let done = match self.geometry(geometry)? {
            Geometry::Triangles(bvh, kept) => {
                bvh.refit(tris).map_err(|error| WorldError::Refit {
                    geometry: geometry.0,
                    error,
                })?;
                kept.clone_from_slice(tris);
                Ok(())
            }
            Geometry::Prims(..) => Err(prims_not_triangles(geometry)),
        };
        self.refit(done)
    }

    /// Refits mesh geometry `geometry` (added by [`super::WorldBuilder::mesh`]) to new vertex
    /// positions for the same triangles ([`Bvh::refit_mesh`](crate::Bvh::refit_mesh)).
    ///
    /// # Errors
    /// As [`WorldEdit::triangles`]; a bad index is a [`WorldError::Refit`] naming the mesh
    /// error.
    pub fn mesh<'v>(
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
        };
        self.refit(done)
    }

    /// Refits geometry `geometry` of the world's primitive type (added by
    /// [`super::WorldBuilder::prims`]) to `prims`: its primitives, moved, in the same order.
    ///
    /// # Errors
    /// As [`WorldEdit::triangles`], [`WorldError::GeometryKind`] for a triangle geometry.
    pub fn prims(&mut self, geometry: GeometryId, prims: &[P]) -> Result<(), WorldError> {
        let done = match self.geometry(geometry)? {
            Geometry::Prims(bvh, kept) => {
                bvh.refit(prims).map_err(|error| WorldError::Refit {
                    geometry: geometry.0,
                    error,
                })?;
                kept.clone_from_slice(prims);
                Ok(())
            }
            Geometry::Triangles(..) => Err(WorldError::GeometryKind {
                geometry: geometry.0,
                holds: "triangles",
            }),
        };
        self.refit(done)
    }

    /// Notes a geometry as refit once `done` says it was.
    fn refit(&mut self, done: Result<(), WorldError>) -> Result<(), WorldError> {
        done?;
        self.geometry_refit = true;
        Ok(())
    }

    /// Instance `i`, to be changed to `change(old)`, which is checked as the builder checks an
    /// instance.
    fn instance(
        &mut self,
        i: u32,
        change: impl FnOnce(&mut super::Instance),
    ) -> Result<(), WorldError> {
        let n = self.world.instances.len();
        let Some(old) = self.world.instances.get(i as usize) else {
            return Err(WorldError::NoInstance {
                instance: i,
                instances: n,
            });
        };
        let mut new = *old;
        change(&mut new);
        check_instance(i as usize, &new, self.world.geometries.len())?;
        self.world.instances[i as usize] = new;
        mark(&mut self.instances, n, i as usize);
        Ok(())
    }

    /// Places instance `instance` by `transform` (object to world) from now on.
    ///
    /// # Errors
    /// [`WorldError::NoInstance`], or [`WorldError::Transform`] for a transform that is not
    /// finite or not invertible, as [`super::WorldBuilder::build`] refuses.
    pub fn transform(&mut self, instance: u32, transform: Affine3A) -> Result<(), WorldError> {
        self.instance(instance, |i| i.transform = transform)
    }

    /// Shows instance `instance` only to rays whose mask shares a bit with `mask`.
    ///
    /// # Errors
    /// [`WorldError::NoInstance`].
    pub fn mask(&mut self, instance: u32, mask: u32) -> Result<(), WorldError> {
        self.instance(instance, |i| i.mask = mask)
    }

    /// Ends the edit: the changed instances' world boxes are recomputed and the top level is
    /// refit (what dropping the edit also does).
    pub fn commit(self) {}

    /// Brings the top level up to date with the changes so far.
    fn finish(&mut self) {
        if !self.geometry_refit && self.instances.is_empty() {
            return;
        }
        self.world.refit_top(&self.instances);
        self.geometry_refit = false;
        self.instances.clear();
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
struct Top<'a, P> {
    instances: &'a [super::Instance],
    geometries: &'a [Geometry<P>],
    /// Which instances changed (empty: none).
    moved_instances: &'a [bool],
    /// Set when an instance the top level holds has a world box out of f32's range now.
    lost: AtomicBool,
}

impl<P: Primitive> Source<Placed> for Top<'_, P> {
    fn get(&self, id: u32) -> Placed {
        let inst = &self.instances[id as usize];
        Placed::new(id as usize, inst, placement(&inst.transform))
    }

    fn refresh(&self, id: u32, p: &mut Placed) {
        if self.moved_instances.get(id as usize) == Some(&true) {
            *p = self.get(id);
        }
    }

    /// The world box as placed now, from the instance's transform and its geometry's box:
    /// the record keeps none (it fills one line without), so the refit computes it for every
    /// instance, moved or not (eight corners transformed: small beside the refit's walk of
    /// the nodes, and a refit geometry needs no flag of its own).
    fn bounds(&self, id: u32, _: &Placed) -> Aabb {
        let b = instance_box(&self.instances[id as usize], self.geometries);
        if !b.is_finite() {
            self.lost.store(true, Ordering::Relaxed);
        }
        b
    }
}

impl<P: Primitive> World<P> {
    /// The instances' world boxes recomputed and the top level refit over them (rebuilt
    /// instead when an instance's box went out of f32's range or came back: the build leaves
    /// those out).
    fn refit_top(&mut self, moved_instances: &[bool]) {
        let src = Top {
            instances: &self.instances,
            geometries: &self.geometries,
            moved_instances,
            lost: AtomicBool::new(false),
        };
        // The refit walks the leaves with their input indices, which the top level does not
        // keep (`top_level`): each record's instance is its index.
        self.top.prim_ids = self.top.prims.iter().map(|p| p.instance).collect();
        self.top.refit(&src);
        self.top.prim_ids = Vec::new();
        let n = src.instances.len();
        let mut rebuild = src.lost.load(Ordering::Relaxed);
        if rebuild || self.top.prims.len() < n {
            let boxes = world_boxes(src.instances, src.geometries);
            if !rebuild {
                // Those the build left out must stay out of range.
                let mut in_top = vec![false; n];
                for p in &self.top.prims {
                    in_top[p.instance as usize] = true;
                }
                rebuild = (0..n).any(|i| !in_top[i] && boxes[i].is_finite());
            }
            if rebuild {
                let placed: Vec<Placed> =
                    (0..n as u32).into_par_iter().map(|i| src.get(i)).collect();
                self.top = top_level(&placed, &boxes, self.top.isa());
            }
            // The world's box as the build takes it: the union of every instance's.
            self.bounds = boxes.iter().fold(Aabb::EMPTY, |b, w| b.union(w));
        } else {
            self.bounds = self.top.bounds;
        }
    }
}
