//! [`World::closest_point`] and [`World::closest_point_at`]: the closest point of a world's
//! triangles, measured in world space through every instance's transform (a moving
//! instance's at the query's time).
//!
//! The top level is walked nearest box first with the world radius. An instance's geometry is
//! searched in object space, where a non-uniform scale or a shear does not keep distances: a
//! world distance `d` is at most `‖M⁻¹‖·d` in object space (`M⁻¹` the world-to-object linear
//! part, `‖·‖` its largest singular value, bounded here by the Frobenius norm), so the
//! object-space walk runs with that radius, a superset, and each candidate triangle is
//! placed in world space and measured there. Barycentrics are kept by affine maps, so the
//! world triangle's are the object triangle's. The top level's box of a moving instance holds
//! it over its whole motion, so the walk is the same at any time; only the instance's
//! transform (and so its stretch) is taken at the time.

use super::instance::motion_of;
use super::top::InstanceLeaf;
use super::{Geometry, GeometryId, InstanceId, World};
use crate::geometry::Triangle;
use crate::point::{may_reach, measure, wide, PointWalk, PrimAt};
use crate::primitive::Primitive;
use glam::{Affine3A, Vec3A};

/// The closest point of a [`World`]'s triangles to a query point ([`World::closest_point`]),
/// in world space.
///
/// ```
/// use quiver_rt::glam::{Affine3A, Vec3, Vec3A};
/// use quiver_rt::world::WorldPointHit;
/// use quiver_rt::{BuildOptions, Instance, Triangle, World};
/// let mut b = World::builder();
/// let g = b.add_triangles(vec![Triangle::new(Vec3A::ZERO, Vec3A::X, Vec3A::Y)]);
/// let i = b.add_instance(Instance::of(g).transform(Affine3A::from_scale(Vec3::new(4.0, 1.0, 1.0))));
/// let world = b.build(&BuildOptions::default()).unwrap();
/// let hit: WorldPointHit = world.closest_point(Vec3A::new(2.0, 0.25, 1.5), f32::INFINITY).unwrap();
/// assert_eq!((hit.instance, hit.geometry, hit.prim), (i, g, 0));
/// assert_eq!((hit.point, hit.distance), (Vec3A::new(2.0, 0.25, 0.0), 1.5));
/// assert_eq!((hit.u, hit.v), (0.5, 0.25));
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WorldPointHit {
    /// The instance: its index in the order instances were added.
    pub instance: InstanceId,
    /// The geometry it places.
    pub geometry: GeometryId,
    /// The primitive of that geometry: its index in the geometry's input.
    pub prim: u32,
    /// The nearest point, in world space.
    pub point: Vec3A,
    /// Barycentric weight of the triangle's second vertex at `point`.
    pub u: f32,
    /// Barycentric weight of the third vertex.
    pub v: f32,
    /// The world-space distance from the query point to `point`.
    pub distance: f32,
}

/// The world-to-object linear part's largest stretch `‖M⁻¹‖`, bounded above, in f64, with
/// room for the rounding of the transform and of the object-space walk: the square root of
/// the smaller of two bounds on the largest eigenvalue of `AᵀA` (`A` the linear part), its
/// trace (the squared Frobenius norm) and its largest Gershgorin row sum. The second is tight
/// for a rotation with a uniform scale (`AᵀA` is then `s²·I` but for rounding), where the
/// first is `√3` times too large and would widen every instance's object-space walk so.
fn stretch(to_object: &Affine3A) -> f64 {
    let c = [
        to_object.matrix3.x_axis,
        to_object.matrix3.y_axis,
        to_object.matrix3.z_axis,
    ]
    .map(wide);
    let ata = |i: usize, j: usize| c[i].dot(c[j]);
    let trace = ata(0, 0) + ata(1, 1) + ata(2, 2);
    let gershgorin = (0..3)
        .map(|i| (0..3).map(|j| ata(i, j).abs()).sum::<f64>())
        .fold(0.0, f64::max);
    trace.min(gershgorin).sqrt() * (1.0 + 1.0 / 1024.0)
}

/// `t`'s vertices placed by `m` (in f32, as the ray queries place their rays the other way).
fn placed(m: &Affine3A, identity: bool, t: Triangle) -> Triangle {
    if identity {
        t
    } else {
        Triangle {
            v: t.v.map(|p| m.transform_point3a(p)),
        }
    }
}

impl<P: Primitive> World<P> {
    /// The point of the world's triangles nearest `point` (world space), within
    /// `max_distance` (inclusive), measured in world space under any instance transform
    /// (non-uniform scale and shear included): the instance, geometry and primitive, the
    /// point, its barycentrics and the distance; `None` when nothing lies that near.
    /// Primitives without a triangle ([`Primitive::triangle`]) are skipped; instance masks are
    /// not consulted (a point query has no ray). A moving instance is where it is at time 0
    /// (its motion's first key, its [`Instance::transform`](super::Instance::transform)):
    /// [`World::closest_point_at`] at time 0, which measures at any other time.
    ///
    /// Each candidate triangle is placed in world space by its instance's transform (in f32)
    /// and measured there with [`Triangle::closest_point`]; its distance from the query point
    /// is taken in f64. Equal distances go to the lower instance, then the lower primitive. A
    /// NaN or non-finite `point`, or a NaN or negative `max_distance`, answers `None`.
    ///
    /// ```
    /// use quiver_rt::glam::{Affine3A, Vec3A};
    /// use quiver_rt::{BuildOptions, Instance, Triangle, World};
    /// let mut b = World::builder();
    /// let g = b.add_triangles(vec![Triangle::new(Vec3A::ZERO, Vec3A::X, Vec3A::Y)]);
    /// b.add_instance(Instance::of(g));
    /// let up = b.add_instance(Instance::of(g).transform(Affine3A::from_translation([0.0, 0.0, 5.0].into())));
    /// let world = b.build(&BuildOptions::default()).unwrap();
    /// let hit = world.closest_point(Vec3A::new(0.2, 0.2, 4.0), f32::INFINITY).unwrap();
    /// assert_eq!((hit.instance, hit.distance), (up, 1.0));
    /// assert_eq!(world.closest_point(Vec3A::new(0.2, 0.2, 4.0), 0.5), None);
    /// assert_eq!(world.closest_point(Vec3A::NAN, 1.0), None);
    /// ```
    pub fn closest_point(&self, point: Vec3A, max_distance: f32) -> Option<WorldPointHit> {
        self.closest_point_at(point, max_distance, 0.0)
    }

    /// [`World::closest_point`] at shutter time `time`: each moving instance measured where
    /// its [`Motion`](super::Motion) places it then ([`Motion::at`](super::Motion::at)), the
    /// others where they stand. `time` is taken as a ray's is
    /// ([`Ray::shutter_time`](crate::Ray::shutter_time)): clamped into `[0, 1]`, NaN as 0. The
    /// answer is the one the world built with every instance placed at `time` gives. A
    /// linear motion at a time its interpolated transform has no f32 inverse (a flat matrix,
    /// halfway through a half turn) is skipped then, as rays at that time miss it.
    ///
    /// ```
    /// use quiver_rt::glam::{Affine3A, Vec3, Vec3A};
    /// use quiver_rt::{BuildOptions, Instance, Motion, Triangle, World};
    /// let mut b = World::builder();
    /// let g = b.add_triangles(vec![Triangle::new(Vec3A::ZERO, Vec3A::X, Vec3A::Y)]);
    /// // Rises from z = 0 to z = 4 while the shutter is open.
    /// let rise = Motion::linear(vec![Affine3A::IDENTITY, Affine3A::from_translation(Vec3::new(0.0, 0.0, 4.0))]);
    /// let i = b.add_moving_instance(Instance::of(g), rise);
    /// let world = b.build(&BuildOptions::default()).unwrap();
    /// let p = Vec3A::new(0.25, 0.25, 3.0);
    /// let start = world.closest_point_at(p, f32::INFINITY, 0.0).unwrap();
    /// assert_eq!((start.instance, start.point, start.distance), (i, Vec3A::new(0.25, 0.25, 0.0), 3.0));
    /// let half = world.closest_point_at(p, f32::INFINITY, 0.5).unwrap();
    /// assert_eq!((half.point, half.distance), (Vec3A::new(0.25, 0.25, 2.0), 1.0));
    /// // Past the shutter is its end (z = 4); NaN is time 0; no time is `closest_point`'s 0.
    /// assert_eq!(world.closest_point_at(p, f32::INFINITY, 7.0).map(|h| h.distance), Some(1.0));
    /// assert_eq!(world.closest_point_at(p, f32::INFINITY, f32::NAN), Some(start));
    /// assert_eq!(world.closest_point(p, f32::INFINITY), Some(start));
    /// ```
    pub fn closest_point_at(
        &self,
        point: Vec3A,
        max_distance: f32,
        time: f32,
    ) -> Option<WorldPointHit> {
        if !(point.is_finite() && max_distance >= 0.0) {
            return None;
        }
        let p = wide(point);
        let mut radius = max_distance as f64;
        let mut best: Option<(f64, u32, u32)> = None;
        let mut hit = None;
        self.top
            .point_walk(point, &mut radius, &mut |_, leaf, radius| {
                let PrimAt::Prim(leaf) = leaf else {
                    return true;
                };
                let Some(geometry) = self.geometries.get(leaf.geometry as usize) else {
                    return true;
                };
                let Some((to_world, to_object, identity)) = self.placed_at(leaf, time) else {
                    return true;
                };
                let (local, stretch) = if identity {
                    (point, 1.0)
                } else {
                    (to_object.transform_point3a(point), stretch(&to_object))
                };
                // Object-space radius: the world radius stretched, with a slack for the rounding
                // of the point's transform (a few ulps of its object-space coordinates).
                let slack = local.abs().max_element() as f64 * (1.0 / (1u64 << 18) as f64);
                let r_obj = *radius * stretch + slack;
                let mut offer = |id: u32, (d, q, u, v): (f64, Vec3A, f32, f32), r_obj: &mut f64| {
                    let better = match best {
                        None => true,
                        Some((bd, bi, bp)) => d < bd || (d == bd && (leaf.instance, id) < (bi, bp)),
                    };
                    if d <= *radius && better {
                        best = Some((d, leaf.instance, id));
                        *radius = d;
                        *r_obj = d * stretch + slack;
                        hit = Some(WorldPointHit {
                            instance: InstanceId(leaf.instance),
                            geometry: GeometryId(leaf.geometry),
                            prim: id,
                            point: q,
                            u,
                            v,
                            distance: d as f32,
                        });
                    }
                };
                // A placed triangle: moved into world space (in f32) and measured there.
                let mut placed_measure = |id: u32, tri: Option<Triangle>, r_obj: &mut f64| {
                    if let Some(tri) = tri.filter(|t| may_reach(t.v, local, *r_obj)) {
                        let (q, u, v) = placed(&to_world, identity, tri).closest_point(point);
                        offer(id, ((p - wide(q)).length(), q, u, v), r_obj);
                    }
                    true
                };
                match geometry {
                    // At the identity the world's triangle is the object's: measured on the
                    // edges the leaf stores, as `Bvh::closest_point` does (the same answer as
                    // placing the input triangle, without reading it).
                    Geometry::Triangles(bvh, _) if identity => {
                        bvh.walk_points(local, r_obj, &mut |id, prim, at, r, up| {
                            if let Some(m) = measure(prim, p, at, *r, up) {
                                offer(id, m, r);
                            }
                            true
                        })
                    }
                    Geometry::Triangles(bvh, tris) => {
                        bvh.walk_points(local, r_obj, &mut |id, _, _, r, _| {
                            placed_measure(id, tris.get(id as usize).copied(), r)
                        })
                    }
                    Geometry::Prims(bvh, prims) => {
                        bvh.walk_points(local, r_obj, &mut |id, _, _, r, _| {
                            placed_measure(id, prims.get(id as usize).and_then(|p| p.triangle()), r)
                        })
                    }
                    // The tree of the segment `time` falls in, whose boxes hold each
                    // triangle all segment long; each measured where it is at `time`.
                    Geometry::MovingTriangles(m) => {
                        let mut r = r_obj;
                        m.tree_at(time).point_walk(local, &mut r, &mut |id, _, r| {
                            placed_measure(id, m.triangle_at(id, time), r)
                        })
                    }
                };
                true
            });
        hit
    }

    /// Where instance `leaf` is at `time`: its object-to-world and world-to-object
    /// transforms, and whether they are the identity. A static instance's are those it was
    /// placed with; a moving one's its motion's at `time` (clamped by [`Motion::at`]) and
    /// the inverse rays enter it through then, or `None` where that has no f32 inverse.
    ///
    /// [`Motion::at`]: super::Motion::at
    fn placed_at(&self, leaf: &InstanceLeaf, time: f32) -> Option<(Affine3A, Affine3A, bool)> {
        let i = leaf.instance as usize;
        if !leaf.moving {
            let to_world = self.instances.get(i)?.transform;
            return Some((to_world, leaf.world_to_object(), leaf.identity));
        }
        let motion = motion_of(&self.motions, i)?;
        Some((motion.at(time), motion.to_object(time)?, false))
    }
}
