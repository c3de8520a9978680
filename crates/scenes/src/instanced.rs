//! A scene in the SPD's patch mode traced as a [`World`] of instances: every sphere is an
//! instance of one tessellated unit sphere, every cone and cylinder an instance of a
//! tessellated unit cone of its radius ratio (one geometry per ratio, up to
//! [`MAX_CONE_SHAPES`]; the others stay world-space triangles), and everything else (polygons,
//! patches, triangles) one world-space geometry placed at the identity.
//!
//! The unit shapes are tessellated by the very functions patch mode uses
//! ([`tessellate::sphere_patches`], [`tessellate::cone_patches`]) and placed by the affine
//! map that takes the unit shape onto each object, so an instanced scene is the flattened patch
//! scene up to the rounding of the placement (a vertex lands within an ulp or two of where
//! patch mode puts it). Hits are numbered as in a flattened list, instance by instance:
//! `quiver_rt::Hit::prim` is the instance's first number plus the primitive's index in its
//! geometry, so the renderer and every `RayQuery` user read an instanced scene like any
//! other.
//!
//! ```
//! use quiver_rt::{BuildOptions, RayQuery};
//! use quiver_scenes::instanced::Instanced;
//! use quiver_scenes::Scene;
//! let scene = Scene::load("balls1").unwrap();
//! let inst = Instanced::build(&scene, 4, &BuildOptions::default()).unwrap();
//! assert_eq!(inst.world().instances().len(), 1 + 10); // the floor, and ten spheres
//! let hit = inst.closest_hit(&scene.camera.ray(0.0, 0.0)).unwrap();
//! assert!((inst.object_of(hit.prim) as usize) < scene.objects.len());
//! ```

use crate::primitive::{Cone, PatchTriangle, Prim, Sphere};
use crate::scene::{tessellate, Scene, Shape};
use glam::{Affine3A, DVec3, Mat3A, Vec3, Vec3A};
use quiver_rt::layout::Footprint;
use quiver_rt::traverse::{Ask, BoxTest, Filter, PacketQuery, RayQuery, Stats, PACKET_RAYS};
use quiver_rt::{
    BuildOptions, GeometryId, Hit, Instance, InstanceId, Motion, PrimHit, Ray, Triangle, World,
    WorldError, WorldHit,
};

/// Distinct cone radius ratios that get a unit shape of their own; cones of further ratios
/// stay world-space triangles (a tree of many tapers gains little from a geometry per taper).
pub const MAX_CONE_SHAPES: usize = 32;

/// A scene's spheres and cones as instances of unit shapes (see the [module](self) docs).
#[derive(Clone, Debug)]
pub struct Instanced {
    world: World,
    /// Each instance's first hit number (and the end): numbers run instance by instance.
    starts: Vec<u64>,
    /// Each instance's scene object (instance 0, the world-space geometry, reads `owner`).
    object: Vec<u32>,
    /// For each world-space triangle, its scene object.
    owner: Vec<u32>,
    /// Each geometry's triangles' vertex normals, where they came from patches.
    normals: Vec<Vec<Option<[Vec3A; 3]>>>,
}

/// A unit shape and the objects placed as it.
struct Shapes {
    tris: Vec<Triangle>,
    normals: Vec<Option<[Vec3A; 3]>>,
}

impl Shapes {
    fn of(patches: Vec<(Vec<Vec3A>, Vec<Vec3A>)>) -> Shapes {
        let (mut tris, mut normals) = (Vec::new(), Vec::new());
        for (verts, n) in patches {
            let shape = Shape::Patch { verts, normals: n };
            tessellate::shape_triangles(&shape, &mut tris, &mut normals);
        }
        Shapes { tris, normals }
    }
}

/// The map from the unit sphere onto `s`.
fn sphere_map(s: &Sphere) -> Affine3A {
    Affine3A::from_scale_rotation_translation(
        Vec3::splat(s.radius),
        glam::Quat::IDENTITY,
        s.center.into(),
    )
}

/// The unit cone of `c`'s shape (base radius 1 at the origin, apex radius `ratio` at `+z`)
/// and the map onto `c`, or `None` for a cone the unit shapes cannot place (no base radius,
/// no height).
fn cone_map(c: &Cone) -> Option<(f32, Affine3A)> {
    let d = |v: Vec3A| DVec3::new(v.x as f64, v.y as f64, v.z as f64);
    let (base, apex) = (d(c.base), d(c.apex));
    let (br, ar) = (c.base_radius as f64, c.apex_radius as f64);
    let axis = apex - base;
    let h = axis.length();
    if h == 0.0 || br <= 0.0 || !(h.is_finite() && br.is_finite() && ar.is_finite()) {
        return None;
    }
    let na = axis / h;
    // The side direction patch mode starts from (`cone_patches`): the unit cone's is +y.
    let side = axis.cross(DVec3::Z);
    let sd = if side.length() < 1e-6 {
        axis.cross(DVec3::X).normalize()
    } else {
        side.normalize()
    };
    let f = |v: DVec3| Vec3A::new(v.x as f32, v.y as f32, v.z as f32);
    let m = Affine3A {
        matrix3: Mat3A::from_cols(f(sd.cross(na) * br), f(sd * br), f(na * h)),
        translation: f(base),
    };
    Some(((ar / br) as f32, m))
}

/// A motion for each placed sphere and cone, for motion-blur pictures and benchmarks: over
/// the shutter, the shape drifts in a straight line by its own size (a sphere's radius, a
/// cone's base radius) along a direction of its own, fixed by its object index `object` (the
/// golden-angle spiral spreads the directions evenly), from where `placement` puts it.
///
/// ```
/// use quiver_rt::glam::{Affine3A, Vec3};
/// use quiver_scenes::instanced::scatter;
/// let at = Affine3A::from_scale_rotation_translation(Vec3::splat(2.0), Default::default(), Vec3::X);
/// let m = scatter(7, at);
/// let moved = m.at(1.0).translation - m.at(0.0).translation;
/// assert!((moved.length() - 2.0).abs() < 1e-5 && m.at(0.0) == at);
/// ```
pub fn scatter(object: u32, placement: Affine3A) -> Motion {
    let k = object as f64;
    let z = 1.0 - 2.0 * (k * 0.618_033_988_749_895).fract();
    let (r, phi) = ((1.0 - z * z).max(0.0).sqrt(), k * 2.399_963_229_728_653);
    let dir = Vec3::new((r * phi.cos()) as f32, (r * phi.sin()) as f32, z as f32);
    let size = placement.matrix3.x_axis.length();
    let end = Affine3A::from_translation(dir * size) * placement;
    Motion::linear(vec![placement, end])
}

/// How the shapes of [`Instanced::build_moving`] move: `None` for a static scene.
type Moves<'a> = Option<&'a dyn Fn(u32, Affine3A) -> Motion>;

impl Instanced {
    /// `scene` (in curve mode: spheres and cones as shapes) with its spheres and cones
    /// tessellated at `resolution` as instances of unit shapes, built with `options`.
    ///
    /// # Errors
    /// [`WorldError`] when a placement cannot be inverted (a sphere of radius 0, say), or the
    /// scene's triangles would number more than `u32::MAX` (hits number them in 32 bits).
    pub fn build(
        scene: &Scene,
        resolution: u32,
        options: &BuildOptions,
    ) -> Result<Instanced, WorldError> {
        Self::build_with(scene, resolution, options, None)
    }

    /// [`Instanced::build`] with every placed sphere and cone moving by `motion(object,
    /// placement)` (e.g. [`scatter`]) over the shutter: rays see it where it is at their
    /// [`Ray::time`]. What stays in world space (polygons, patches, the floor) stands still.
    ///
    /// ```
    /// use quiver_rt::{BuildOptions, RayQuery};
    /// use quiver_scenes::instanced::{scatter, Instanced};
    /// use quiver_scenes::Scene;
    /// let scene = Scene::load("balls1").unwrap();
    /// let inst = Instanced::build_moving(&scene, 4, &BuildOptions::default(), &scatter).unwrap();
    /// assert!(inst.world().motion(quiver_rt::InstanceId(1)).is_some());
    /// ```
    ///
    /// # Errors
    /// As [`Instanced::build`], and [`WorldError::Motion`] for a motion the world refuses.
    pub fn build_moving(
        scene: &Scene,
        resolution: u32,
        options: &BuildOptions,
        motion: &dyn Fn(u32, Affine3A) -> Motion,
    ) -> Result<Instanced, WorldError> {
        Self::build_with(scene, resolution, options, Some(motion))
    }

    fn build_with(
        scene: &Scene,
        resolution: u32,
        options: &BuildOptions,
        motion: Moves<'_>,
    ) -> Result<Instanced, WorldError> {
        let sphere = Shapes::of(tessellate::sphere_patches(
            &Sphere {
                center: Vec3A::ZERO,
                radius: 1.0,
            },
            resolution,
        ));
        let mut cones: Vec<(u32, Shapes)> = Vec::new();
        let (mut world_tris, mut owner, mut world_normals) = (Vec::new(), Vec::new(), Vec::new());
        // (object, shape index: 0 the sphere, 1 + k the k-th cone ratio, map).
        let mut placed: Vec<(u32, usize, Affine3A)> = Vec::new();
        for (i, o) in scene.objects.iter().enumerate() {
            let shape = match &o.shape {
                Shape::Sphere(s) if s.radius > 0.0 => Some((0, sphere_map(s))),
                Shape::Cone(c) => cone_map(c).and_then(|(ratio, m)| {
                    let key = ratio.to_bits();
                    let k = match cones.iter().position(|(r, _)| *r == key) {
                        Some(k) => k,
                        None if cones.len() < MAX_CONE_SHAPES => {
                            let unit = Cone {
                                base: Vec3A::ZERO,
                                base_radius: 1.0,
                                apex: Vec3A::Z,
                                apex_radius: ratio,
                            };
                            cones.push((
                                key,
                                Shapes::of(tessellate::cone_patches(&unit, resolution)),
                            ));
                            cones.len() - 1
                        }
                        None => return None,
                    };
                    Some((1 + k, m))
                }),
                _ => None,
            };
            // A map the walk cannot invert in f32 (a radius past 1e38 or below 1e-38, say)
            // places nothing: the object is tessellated in world space instead, as patch mode
            // draws it.
            match shape.filter(|(_, m)| quiver_rt::world::invert(m).is_ok()) {
                Some((k, m)) => placed.push((i as u32, k, m)),
                None => {
                    let patched = match &o.shape {
                        Shape::Sphere(s) => Some(tessellate::sphere_patches(s, resolution)),
                        Shape::Cone(c) => Some(tessellate::cone_patches(c, resolution)),
                        _ => None,
                    };
                    let before = world_tris.len();
                    match patched {
                        Some(p) => {
                            for (verts, n) in p {
                                let s = Shape::Patch { verts, normals: n };
                                tessellate::shape_triangles(
                                    &s,
                                    &mut world_tris,
                                    &mut world_normals,
                                );
                            }
                        }
                        None => tessellate::shape_triangles(
                            &o.shape,
                            &mut world_tris,
                            &mut world_normals,
                        ),
                    }
                    owner.resize(owner.len() + world_tris.len() - before, i as u32);
                }
            }
        }
        let mut b = World::builder();
        let counts: Vec<u64> = std::iter::once(world_tris.len() as u64)
            .chain(std::iter::once(sphere.tris.len() as u64))
            .chain(cones.iter().map(|(_, s)| s.tris.len() as u64))
            .collect();
        b.add_triangles(world_tris);
        b.add_triangles(sphere.tris);
        let mut normals = vec![world_normals, sphere.normals];
        for (_, s) in cones {
            b.add_triangles(s.tris);
            normals.push(s.normals);
        }
        b.add_instance(Instance::of(GeometryId(0)));
        let mut starts = vec![0u64, counts[0]];
        let mut object = vec![u32::MAX];
        for &(obj, k, m) in &placed {
            let inst = Instance::of(GeometryId(1 + k as u32))
                .transform(m)
                .user_id(obj);
            match motion {
                Some(f) => b.add_moving_instance(inst, f(obj, m)),
                None => b.add_instance(inst),
            };
            starts.push(starts.last().unwrap() + counts[1 + k]);
            object.push(obj);
        }
        if *starts.last().unwrap() > u32::MAX as u64 {
            return Err(WorldError::TooMany);
        }
        Ok(Instanced {
            world: b.build(options)?,
            starts,
            object,
            owner,
            normals,
        })
    }

    /// The world traced.
    pub fn world(&self) -> &World {
        &self.world
    }

    /// Triangles in the flattened scene (what hits are numbered by).
    pub fn primitives(&self) -> u64 {
        *self.starts.last().unwrap()
    }

    /// The instance and geometry-local primitive of hit number `prim`.
    fn split(&self, prim: u32) -> (usize, u32) {
        let i = self.starts.partition_point(|&s| s <= prim as u64) - 1;
        (i, (prim as u64 - self.starts[i]) as u32)
    }

    /// The scene object hit number `prim` came from.
    pub fn object_of(&self, prim: u32) -> u32 {
        match self.split(prim) {
            (0, p) => self.owner[p as usize],
            (i, _) => self.object[i],
        }
    }

    /// A world hit as a hit of the flattened numbering.
    #[inline(always)]
    fn flat(&self, h: &WorldHit) -> Hit {
        Hit {
            t: h.t,
            prim: (self.starts[h.instance.0 as usize] + h.prim as u64) as u32,
            u: h.u,
            v: h.v,
        }
    }

    /// The triangle of hit number `prim` in its geometry's space, its vertex normals if any,
    /// and where its instance is (object to world) when `ray` is shot.
    fn triangle(&self, prim: u32, ray: &Ray) -> (Triangle, Option<[Vec3A; 3]>, Affine3A) {
        let (i, p) = self.split(prim);
        let id = InstanceId(i as u32);
        let inst = self.world.instance(id);
        let g = inst.geometry.0 as usize;
        let tri = match &self.world.geometries()[g] {
            quiver_rt::world::Geometry::Triangles(_, t) => t[p as usize],
            quiver_rt::world::Geometry::Prims(_, t) => t[p as usize],
            quiver_rt::world::Geometry::MovingTriangles(m) => m
                .triangle_at(p, ray.shutter_time())
                .expect("a hit names a triangle of its geometry"),
        };
        let placed = match self.world.motion(id) {
            Some(m) => m.at(ray.shutter_time()),
            None => inst.transform,
        };
        (tri, self.normals[g][p as usize], placed)
    }

    /// The shading normal at `hit` of `ray`, as the flattened patch scene's: the patch's
    /// vertex normals interpolated (a plain triangle's face normal) in object space, brought
    /// to world space by the inverse transpose of the placement.
    pub fn normal(&self, ray: &Ray, hit: &Hit) -> Vec3A {
        let (tri, normals, placed) = self.triangle(hit.prim, ray);
        let th = PrimHit {
            t: hit.t,
            u: hit.u,
            v: hit.v,
        };
        let local = match normals {
            Some(normals) => Prim::Patch(PatchTriangle { tri, normals }).normal(ray, &th),
            None => Prim::Triangle(tri).normal(ray, &th),
        };
        if placed == Affine3A::IDENTITY {
            return local;
        }
        let to_object = quiver_rt::world::invert(&placed).unwrap_or(Affine3A::IDENTITY);
        let inverse_t = to_object.matrix3.transpose();
        (inverse_t * local).normalize_or_zero()
    }

    /// Hit number `prim`'s own test against `ray` (in its instance's object space): the one
    /// test Havran's ideal algorithm makes.
    pub fn intersect_one(&self, ray: &Ray, prim: u32) -> Option<PrimHit> {
        let (tri, _, placed) = self.triangle(prim, ray);
        let to_object = quiver_rt::world::invert(&placed).unwrap_or(Affine3A::IDENTITY);
        let local = Ray {
            origin: to_object.transform_point3a(ray.origin),
            dir: to_object.transform_vector3a(ray.dir),
            ..*ray
        };
        tri.intersect(&local)
    }

    /// What the world occupies.
    pub fn footprint(&self) -> Footprint {
        self.world.footprint()
    }
}

/// The caller's filter on flattened hits, asked about the world's candidates.
struct Flat<'a, F> {
    scene: &'a Instanced,
    filter: &'a mut F,
}

impl<F: Filter<Hit>> Filter<WorldHit> for Flat<'_, F> {
    const ACTIVE: bool = F::ACTIVE;
    #[inline(always)]
    fn accept(&mut self, h: &WorldHit) -> bool {
        self.filter.accept(&self.scene.flat(h))
    }
}

impl RayQuery for Instanced {
    type Hit = Hit;

    fn trace_with<A: Ask, B: BoxTest, S: Stats, F: Filter<Hit>>(
        &self,
        ray: &Ray,
        stats: &mut S,
        filter: &mut F,
    ) -> A::Answer<Hit> {
        let mut f = Flat {
            scene: self,
            filter,
        };
        let h = self.world.trace_with::<A, B, S, _>(ray, stats, &mut f);
        A::map(h, |h| self.flat(&h))
    }

    fn trace_packet_with<A: Ask, B: BoxTest, S: Stats, F: Filter<Hit>>(
        &self,
        query: PacketQuery<'_>,
        hits: &mut [A::Answer<Hit>],
        stats: &mut S,
        filter: &mut F,
    ) {
        assert_eq!(hits.len(), query.rays.len(), "one hit slot per ray");
        let mut found = [A::Answer::<WorldHit>::default(); PACKET_RAYS];
        for (k, (rays, hits)) in query
            .rays
            .chunks(PACKET_RAYS)
            .zip(hits.chunks_mut(PACKET_RAYS))
            .enumerate()
        {
            let at = k * PACKET_RAYS;
            let part = PacketQuery {
                rays,
                active: query.active.map(|a| &a[at..at + rays.len()]),
                mode: query.mode,
            };
            let found = &mut found[..rays.len()];
            let mut f = Flat {
                scene: self,
                filter: &mut *filter,
            };
            self.world
                .trace_packet_with::<A, B, S, _>(part, found, stats, &mut f);
            for (h, w) in hits.iter_mut().zip(found.iter()) {
                *h = A::map(*w, |w| self.flat(&w));
            }
        }
    }
}

/// A mesh file's groups ([`Scene::groups`]: OBJ `o`/`g` groups, glTF mesh primitives, a PLY
/// file) as the geometries of one [`World`], so that a hit names its mesh: geometry `g` holds
/// the triangles of group `g`'s objects in object order (as [`Scene::triangles`] lists them)
/// and is placed once at the identity, with the instance id `g`, so [`WorldHit::instance`]
/// and [`WorldHit::geometry`] are both the group's index. Objects no group covers (and all of
/// them in a scene without groups) form one more geometry, its instance id `u32::MAX`. A
/// group with no triangles (degenerate polygons only) gets an empty geometry, never hit.
///
/// Placed at the identity, every instance costs no transform work, so the world answers what
/// a BVH over [`Scene::triangles`] answers; only the numbering differs.
///
/// ```
/// use quiver_rt::{BuildOptions, RayQuery};
/// use quiver_rt::glam::Vec3A;
/// use quiver_scenes::instanced::grouped;
/// use quiver_scenes::scene::obj;
/// let text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 0 1 1\n\
///             o near\nf 4 5 6\no far\nf 1 2 3\n";
/// let scene = obj::parse(text, "two.obj").unwrap();
/// let world = grouped(&scene, &BuildOptions::default()).unwrap();
/// let hit = world.closest_hit(&quiver_rt::Ray::new(Vec3A::new(0.2, 0.2, 2.0), -Vec3A::Z)).unwrap();
/// assert_eq!(scene.groups[hit.instance.0 as usize].name, "near");
/// ```
///
/// # Errors
/// [`WorldError::TooMany`] when a group has more than `u32::MAX` triangles.
pub fn grouped(scene: &Scene, options: &BuildOptions) -> Result<World, WorldError> {
    let mut b = World::builder();
    let mut covered = vec![false; scene.objects.len()];
    let triangles_of = |objects: &mut dyn Iterator<Item = usize>| {
        let (mut tris, mut normals) = (Vec::new(), Vec::new());
        for i in objects {
            tessellate::shape_triangles(&scene.objects[i].shape, &mut tris, &mut normals);
        }
        tris
    };
    for (g, group) in scene.groups.iter().enumerate() {
        let range = group.objects.start as usize..(group.objects.end as usize).min(covered.len());
        for c in &mut covered[range.clone()] {
            *c = true;
        }
        let geometry = b.add_triangles(triangles_of(&mut range.into_iter()));
        b.add_instance(Instance::of(geometry).user_id(g as u32));
    }
    if covered.iter().any(|c| !c) {
        let rest = triangles_of(&mut (0..covered.len()).filter(|&i| !covered[i]));
        let geometry = b.add_triangles(rest);
        b.add_instance(Instance::of(geometry).user_id(u32::MAX));
    }
    b.build(options)
}
