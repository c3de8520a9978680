//! A renderer's scene: geometries (BVHs over meshes, triangles or any [`Primitive`]) placed
//! by instances (a geometry, an affine object-to-world transform, a visibility mask and a
//! user id), under one top-level BVH over the instances' world boxes. Queried like any BVH
//! ([`RayQuery`](crate::RayQuery)), with hits that name the instance, geometry and primitive
//! ([`WorldHit`]), ray masks ([`Ray::mask`]) and hit filters ([`crate::traverse::Filter`]).
//!
//! Rays are brought into an instance's object space, not the geometry into world space: the
//! inverse transform is applied to the origin and the direction, the direction is not
//! renormalised, so a hit's `t` is the same parameter along the world ray and hits from
//! different instances compare directly. An instance with the identity transform (a world-space
//! geometry placed once) skips the transform. Equal distances go to the lower instance index,
//! then, inside one instance, to the lower primitive index: the order of the same scene
//! flattened instance by instance. One limit: a triangle large and far from the origin for
//! its size has a computed distance that can round below its instance box's entry by more than
//! the box test's slack, and a walk that has already found a hit that near culls the box. Of
//! two hits within that rounding of each other, which is reported can then depend on the order
//! of the walk (a single ray, a packet, an edited or a rebuilt top level); both are hits the
//! f64 oracle admits.
//!
//! An instance can move while the shutter is open ([`Motion`], added by
//! [`WorldBuilder::add_moving_instance`]): a ray at [`Ray::time`] meets it where its motion
//! places it then, and answers as the world built with every instance placed at that time.
//!
//! One level of instancing: an instance places a geometry, not another world. Nested instances
//! would put a transform, a top-level walk and a stack of ray states on every level; the
//! scenes quiver serves (the SPD, OBJ groups, a forest of trees) need one, Embree's and
//! tinybvh's common cases are one level, and a renderer that needs two can flatten the lower
//! level into a geometry, whose BVH then holds the combined transforms' triangles.
//!
//! ```
//! use quiver_rt::glam::{Affine3A, Vec3A};
//! use quiver_rt::{BuildOptions, Instance, Ray, RayQuery, World};
//!
//! // A unit square (two triangles) as a mesh, placed twice.
//! let positions = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]];
//! let indices = [[0, 1, 2], [0, 2, 3]];
//! let mut builder = World::builder();
//! let square = builder.add_mesh(&positions, &indices).unwrap();
//! let near = builder.add_instance(Instance::of(square).mask(0b01).user_id(10));
//! let far = builder.add_instance(
//!     Instance::of(square)
//!         .transform(Affine3A::from_translation(Vec3A::new(0.0, 0.0, -2.0).into()))
//!         .mask(0b10)
//!         .user_id(11),
//! );
//! let world = builder.build(&BuildOptions::default()).unwrap();
//!
//! let ray = Ray::new(Vec3A::new(0.25, 0.75, 1.0), -Vec3A::Z);
//! let hit = world.closest_hit(&ray).unwrap();
//! assert_eq!((hit.instance, hit.geometry, hit.prim, hit.t), (near, square, 1, 1.0));
//! assert_eq!(world.instance(hit.instance).user_id, 10);
//! assert_eq!(world.normal(&ray, &hit), Some(Vec3A::Z));
//! // A ray that sees only mask 0b10 passes the first square and meets the second.
//! let hit = world.closest_hit(&ray.with_mask(0b10)).unwrap();
//! assert_eq!((hit.instance, hit.t), (far, 3.0));
//! ```

mod builder;
mod deform;
mod edit;
mod error;
mod filter;
mod geometry;
mod hit;
mod instance;
mod motion;
mod packet;
mod point;
mod query;
mod save;
mod top;

pub use builder::WorldBuilder;
pub use deform::MovingTriangles;
pub use edit::WorldEdit;
pub use error::WorldError;
pub use filter::GeometryFilter;
pub use geometry::Geometry;
pub use hit::WorldHit;
pub use instance::{invert, GeometryId, Instance, InstanceId, INVERSE_TOLERANCE};
pub use motion::{Interpolation, Motion, MAX_MOTION_KEYS};
pub use point::WorldPointHit;

use crate::geometry::{unit_or_zero, Aabb, PrimHit, Ray, Triangle};
use crate::layout::walk::{NodeVisit, WalkNodes};
use crate::layout::{Bvh8, Footprint};
use crate::primitive::Primitive;
use glam::{Mat3A, Vec3A};
use top::{InstanceLeaf, TopEnds};

/// Geometries placed by instances under one top-level BVH (see the [module](self) docs).
#[derive(Clone, Debug)]
pub struct World<P = Triangle> {
    geometries: Vec<Geometry<P>>,
    instances: Vec<Instance>,
    /// `motions[i]`: instance `i`'s motion, if it moves. Empty until the first moving one.
    motions: Vec<Option<Motion>>,
    /// `removed[i]`: instance `i` was removed by an edit (its id is never given again). Empty
    /// until the first removal.
    removed: Vec<bool>,
    /// `filters[g]`: geometry `g`'s own filter. Empty until the first is set.
    filters: Vec<Option<GeometryFilter>>,
    top: Bvh8<InstanceLeaf>,
    /// The top level's boxes at both ends of the shutter: what a ray at a time walks in a
    /// world with moving instances. Empty while `motions` is.
    ends: TopEnds,
    bounds: Aabb,
}

impl World {
    /// An empty builder for a world of triangle geometries ([`WorldBuilder::new`] for other
    /// primitive types).
    pub fn builder() -> WorldBuilder {
        WorldBuilder::new()
    }
}

impl<P: Primitive> World<P> {
    /// Instance `i` as it was added (or last edited).
    ///
    /// # Panics
    /// When `i` is not one of the world's instances (a hit's `instance` always is).
    pub fn instance(&self, i: InstanceId) -> &Instance {
        &self.instances[i.0 as usize]
    }

    /// True when `i` names an instance of the world that was not removed
    /// ([`WorldEdit::remove_instance`]).
    ///
    /// ```
    /// use quiver_rt::{BuildOptions, Instance, InstanceId, Triangle, World};
    /// use quiver_rt::glam::Vec3A;
    /// let mut b = World::builder();
    /// let g = b.add_triangles(vec![Triangle::new(Vec3A::ZERO, Vec3A::X, Vec3A::Y)]);
    /// let a = b.add_instance(Instance::of(g));
    /// let mut world = b.build(&BuildOptions::default()).unwrap();
    /// world.edit().remove_instance(a).unwrap();
    /// assert!(!world.is_live(a) && !world.is_live(InstanceId(5)));
    /// ```
    pub fn is_live(&self, i: InstanceId) -> bool {
        (i.0 as usize) < self.instances.len() && self.removed.get(i.0 as usize) != Some(&true)
    }

    /// Instance `i`'s motion, if it moves (`None` for a static instance or an id the world
    /// does not have).
    pub fn motion(&self, i: InstanceId) -> Option<&Motion> {
        instance::motion_of(&self.motions, i.0 as usize)
    }

    /// Where instance `inst` (object to world) is at the time `ray` is shot: its motion's
    /// transform then, or its own transform.
    fn transform_at(&self, inst: InstanceId, ray: &Ray) -> Option<glam::Affine3A> {
        match self.motion(inst) {
            Some(m) => Some(m.at(ray.shutter_time())),
            None => self.instances.get(inst.0 as usize).map(|i| i.transform),
        }
    }

    /// Every instance, in the order added, removed ones included (as they were last placed:
    /// [`World::is_live`] tells which are still in the world), so an [`InstanceId`] indexes it.
    pub fn instances(&self) -> &[Instance] {
        &self.instances
    }

    /// Every geometry, in the order added.
    pub fn geometries(&self) -> &[Geometry<P>] {
        &self.geometries
    }

    /// The box around every instance, in world space.
    pub fn bounds(&self) -> Aabb {
        self.bounds
    }

    /// The world-space geometric normal at `hit` of `ray` (unit length, on the side the
    /// primitive's winding faces, as placed at the ray's time: a mirroring transform reverses
    /// it), or `None` where the primitive type gives no normal
    /// ([`Primitive::geometric_normal`]).
    pub fn normal(&self, ray: &Ray, hit: &WorldHit) -> Option<Vec3A> {
        let transform = self.transform_at(hit.instance, ray)?;
        let g = self.geometries.get(hit.geometry.0 as usize)?;
        let to_object = instance::invert(&transform).ok()?;
        let at = to_object.transform_point3a(ray.at(hit.t));
        let local = PrimHit {
            t: hit.t,
            u: hit.u,
            v: hit.v,
        };
        let n = g.normal(hit.prim, at, &local, ray.shutter_time())?;
        // Normals go by the inverse transpose of the linear part; a mirroring transform also
        // reverses the winding, which is what says which side a triangle faces.
        let inverse_t: Mat3A = to_object.matrix3.transpose();
        let n = unit_or_zero(inverse_t * n);
        Some(if instance::mirrors(&transform) { -n } else { n })
    }

    /// Geometry `g`'s own filter, if it has one.
    #[inline(always)]
    pub(crate) fn own_filter(&self, g: u32) -> Option<&GeometryFilter> {
        self.filters.get(g as usize).and_then(Option::as_ref)
    }

    /// The top-level BVH, for readers inside the crate (the cost predictor).
    pub(crate) fn top(&self) -> &Bvh8<InstanceLeaf> {
        &self.top
    }

    /// What the world occupies: the top level, every geometry's BVH once (however often it is
    /// placed), the instance records and the motions' keys. `nodes` counts the top level's and the geometries'
    /// node slots.
    pub fn footprint(&self) -> Footprint {
        let top = self.top.footprint();
        let motions = self
            .motions
            .iter()
            .flatten()
            .map(Motion::bytes)
            .sum::<usize>();
        let instances = std::mem::size_of_val(self.instances.as_slice())
            + std::mem::size_of_val(self.motions.as_slice())
            + motions
            + std::mem::size_of_val(self.ends.nodes.as_slice())
            + std::mem::size_of_val(self.ends.leaves.as_slice());
        self.geometries.iter().fold(
            Footprint {
                nodes: top.nodes,
                node_bytes: top.node_bytes,
                bytes: top.bytes + instances,
                kept: top.kept + instances,
            },
            |f, g| {
                let g = g.footprint();
                Footprint {
                    nodes: f.nodes + g.nodes,
                    node_bytes: f.node_bytes + g.node_bytes,
                    bytes: f.bytes + g.bytes,
                    kept: f.kept + g.kept,
                }
            },
        )
    }
}

/// The nodes a world's walks can enter: its top level's, then each geometry's once (a census
/// of the structure; a ray's walk enters a geometry's once per instance it meets).
impl<P: Primitive> WalkNodes for World<P> {
    fn walk_nodes(&self, f: &mut dyn FnMut(NodeVisit)) {
        self.top().walk_nodes(f);
        for g in self.geometries() {
            match g {
                Geometry::Triangles(b, _) => b.walk_nodes(f),
                Geometry::Prims(b, _) => b.walk_nodes(f),
                Geometry::MovingTriangles(m) => m.segment_trees().for_each(|b| b.walk_nodes(f)),
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bvh::BuildOptions;
    use crate::testing::soup;
    use glam::Affine3A;

    #[test]
    fn building_a_world_twice_gives_the_same_top_level_tree_on_any_pool() {
        let tris = soup(200, 3);
        let make = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            let mut b = World::builder();
            let g = b.add_triangles(tris.clone());
            for i in 0..500 {
                let at = Vec3A::new((i % 23) as f32, (i / 23) as f32, (i % 7) as f32);
                b.add_instance(Instance::of(g).transform(Affine3A::from_translation(at.into())));
            }
            b.build(&BuildOptions::default().thread_pool(&pool))
                .unwrap()
        };
        let (a, b, c) = (make(1), make(2), make(2));
        for other in [&b, &c] {
            assert_eq!(a.top.nodes, other.top.nodes);
            let instances = |w: &World| w.top.prims.iter().map(|p| p.instance).collect::<Vec<_>>();
            assert_eq!(instances(&a), instances(other));
        }
        assert_eq!(a.top.prims.len(), 500);
    }
}
