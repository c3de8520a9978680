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
//! flattened instance by instance.
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
//! let square = builder.mesh(&positions, &indices).unwrap();
//! builder.instance(Instance::of(square).mask(0b01).id(10));
//! builder.instance(
//!     Instance::of(square)
//!         .transform(Affine3A::from_translation(Vec3A::new(0.0, 0.0, -2.0).into()))
//!         .mask(0b10)
//!         .id(11),
//! );
//! let world = builder.build(&BuildOptions::default()).unwrap();
//!
//! let ray = Ray::new(Vec3A::new(0.25, 0.75, 1.0), -Vec3A::Z);
//! let hit = world.closest_hit(&ray).unwrap();
//! assert_eq!((hit.instance, hit.geometry, hit.prim, hit.t), (0, 0, 1, 1.0));
//! assert_eq!(world.instance(hit.instance).id, 10);
//! assert_eq!(world.normal(&ray, &hit), Some(Vec3A::Z));
//! // A ray that sees only mask 0b10 passes the first square and meets the second.
//! let hit = world.closest_hit(&ray.with_mask(0b10)).unwrap();
//! assert_eq!((hit.instance, hit.t), (1, 3.0));
//! ```

mod edit;
mod packet;
mod query;

pub use edit::WorldEdit;

use crate::builders::{build, BuildConfig, Builder};
use crate::bvh::BuildOptions;
use crate::bvh::RefitError;
use crate::geometry::{unit_or_zero, Aabb, PrimHit, Ray, Triangle};
use crate::isa::Isa;
use crate::layout::{bvh2::leaf_order, Bvh8, Footprint};
use crate::mesh::{Mesh, MeshError, Positions};
use crate::primitive::Primitive;
use crate::Bvh;
use glam::{Affine3A, Mat3A, Vec3A, Vec4, Vec4Swizzles};
use std::fmt;

/// A geometry's index in its [`World`] (what [`WorldBuilder`]'s `mesh`, `triangles` and
/// `prims` return, and [`Instance::of`] takes).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct GeometryId(pub u32);

/// One placement of a geometry: which geometry, its object-to-world transform (a 3×4
/// affine map), which rays see it and the caller's own id for it.
///
/// ```
/// use quiver_rt::glam::{Affine3A, Vec3};
/// use quiver_rt::{GeometryId, Instance};
/// let tree = Instance::of(GeometryId(3))
///     .transform(Affine3A::from_scale(Vec3::splat(2.0)))
///     .mask(0b01)
///     .id(42);
/// assert_eq!((tree.geometry, tree.mask, tree.id), (GeometryId(3), 1, 42));
/// assert_eq!(Instance::of(GeometryId(0)).mask, u32::MAX); // seen by every ray
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Instance {
    /// The geometry placed.
    pub geometry: GeometryId,
    /// Object space to world space. Must be finite and invertible.
    pub transform: Affine3A,
    /// A ray enters the instance only when `ray.mask & mask != 0`. Every bit by default.
    pub mask: u32,
    /// The caller's id for the instance (quiver never reads it). 0 by default.
    pub id: u32,
}

impl Instance {
    /// `geometry` in world space (the identity transform), seen by every ray, id 0.
    pub fn of(geometry: GeometryId) -> Instance {
        Instance {
            geometry,
            transform: Affine3A::IDENTITY,
            mask: u32::MAX,
            id: 0,
        }
    }

    /// Places the geometry by `transform` (object to world).
    pub fn transform(self, transform: Affine3A) -> Instance {
        Instance { transform, ..self }
    }

    /// Seen only by rays whose mask shares a bit with `mask`.
    pub fn mask(self, mask: u32) -> Instance {
        Instance { mask, ..self }
    }

    /// The caller's own id for this instance.
    pub fn id(self, id: u32) -> Instance {
        Instance { id, ..self }
    }
}

/// What a hit in a [`World`] names: enough for a shader to find the surface and its material.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WorldHit {
    /// Distance along the world ray (in units of its direction).
    pub t: f32,
    /// The instance hit: its index in the order instances were added.
    pub instance: u32,
    /// The geometry it places.
    pub geometry: u32,
    /// The primitive of that geometry: its index in the geometry's input.
    pub prim: u32,
    /// Barycentric weight of the primitive's second vertex (a primitive's own first surface
    /// parameter for other types).
    pub u: f32,
    /// Barycentric weight of the third vertex (or the second surface parameter).
    pub v: f32,
}

impl WorldHit {
    /// The "nothing yet" record a closest-hit search starts from.
    pub(crate) fn none(t_max: f32) -> WorldHit {
        WorldHit {
            t: t_max,
            instance: u32::MAX,
            geometry: u32::MAX,
            prim: u32::MAX,
            u: 0.0,
            v: 0.0,
        }
    }

    /// `Some(self)` unless nothing was found.
    pub(crate) fn found(self) -> Option<WorldHit> {
        (self.instance != u32::MAX).then_some(self)
    }

    /// Whether a hit at `t` in `instance` replaces this one: nearer, or as near in a lower
    /// instance (inside one instance the geometry's own tie rule has already chosen).
    #[inline(always)]
    pub(crate) fn is_beaten_by(&self, t: f32, instance: u32) -> bool {
        t < self.t || (t == self.t && instance < self.instance)
    }
}

/// The BVH of one geometry, with its primitives in input order for normals.
#[derive(Clone, Debug)]
pub enum Geometry<P = Triangle> {
    /// Triangles (from a mesh or a slice), on the triangle fast path.
    Triangles(Bvh<Triangle>, Vec<Triangle>),
    /// Primitives of the world's own type.
    Prims(Bvh<P>, Vec<P>),
}

impl<P: Primitive> Geometry<P> {
    /// The box around every primitive, in object space.
    pub fn bounds(&self) -> Aabb {
        match self {
            Geometry::Triangles(b, _) => b.bounds(),
            Geometry::Prims(b, _) => b.bounds(),
        }
    }

    /// Primitives in the geometry.
    pub fn len(&self) -> usize {
        match self {
            Geometry::Triangles(_, t) => t.len(),
            Geometry::Prims(_, p) => p.len(),
        }
    }

    /// True for a geometry of no primitives.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// What the BVH occupies (nodes and the leaf data its kernels read) and the primitives
    /// kept in input order (for normals).
    pub fn footprint(&self) -> Footprint {
        let (f, kept) = match self {
            Geometry::Triangles(b, t) => (b.footprint(), std::mem::size_of_val(t.as_slice())),
            Geometry::Prims(b, p) => (b.footprint(), std::mem::size_of_val(p.as_slice())),
        };
        Footprint {
            bytes: f.bytes + kept,
            kept: f.kept + kept,
            ..f
        }
    }

    /// The object-space geometric normal of primitive `prim` at `hit`, if its type has one.
    fn normal(&self, prim: u32, at: Vec3A, hit: &PrimHit) -> Option<Vec3A> {
        match self {
            Geometry::Triangles(_, t) => t.get(prim as usize)?.geometric_normal(at, hit),
            Geometry::Prims(_, p) => p.get(prim as usize)?.geometric_normal(at, hit),
        }
    }
}

/// What a [`World`] could not be built from: each names the instance or geometry at fault.
#[derive(Clone, Debug, PartialEq)]
pub enum WorldError {
    /// Instance `instance` names geometry `geometry`, but the world has `geometries`.
    Geometry {
        /// The instance.
        instance: usize,
        /// The geometry it names.
        geometry: u32,
        /// How many there are.
        geometries: usize,
    },
    /// Instance `instance`'s transform cannot place a geometry: `why`.
    Transform {
        /// The instance.
        instance: usize,
        /// Not finite, not invertible, its inverse out of f32's range, or too close to
        /// singular for f32 ([`invert`]).
        why: &'static str,
    },
    /// Geometry `geometry`'s mesh: an index names no vertex, or too many triangles.
    Mesh {
        /// The geometry.
        geometry: usize,
        /// What was wrong.
        error: MeshError,
    },
    /// More than `u32::MAX` instances or geometries.
    TooMany,
    /// An edit named geometry `geometry`, but the world has `geometries`.
    NoGeometry {
        /// The geometry named.
        geometry: u32,
        /// How many there are.
        geometries: usize,
    },
    /// An edit named instance `instance`, but the world has `instances`.
    NoInstance {
        /// The instance named.
        instance: u32,
        /// How many there are.
        instances: usize,
    },
    /// An edit gave geometry `geometry` primitives of the other kind: it `holds` triangles
    /// or the world's own primitive type.
    GeometryKind {
        /// The geometry.
        geometry: u32,
        /// What it holds: "triangles" or "primitives of the world's type".
        holds: &'static str,
    },
    /// Geometry `geometry` could not be refit to the primitives given.
    Refit {
        /// The geometry.
        geometry: u32,
        /// Why.
        error: RefitError,
    },
}

impl fmt::Display for WorldError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            WorldError::Geometry {
                instance,
                geometry,
                geometries,
            } => write!(
                f,
                "instance {instance} places geometry {geometry}, but the world has {geometries}"
            ),
            WorldError::Transform { instance, why } => {
                write!(f, "instance {instance}: the transform is {why}")
            }
            WorldError::Mesh { geometry, error } => write!(f, "geometry {geometry}: {error}"),
            WorldError::TooMany => write!(f, "more than 2^32 - 1 instances or geometries"),
            WorldError::NoGeometry {
                geometry,
                geometries,
            } => write!(
                f,
                "geometry {geometry} does not exist: the world has {geometries}"
            ),
            WorldError::NoInstance {
                instance,
                instances,
            } => write!(
                f,
                "instance {instance} does not exist: the world has {instances}"
            ),
            WorldError::GeometryKind { geometry, holds } => {
                write!(f, "geometry {geometry} holds {holds}, and takes only those")
            }
            WorldError::Refit { geometry, error } => write!(f, "geometry {geometry}: {error}"),
        }
    }
}

impl std::error::Error for WorldError {}

/// Where a world's geometries and instances are collected before [`WorldBuilder::build`].
///
/// ```
/// use quiver_rt::{BuildOptions, Instance, Triangle, World, WorldError};
/// use quiver_rt::glam::{Affine3A, Vec3A};
/// let mut b = World::builder();
/// let g = b.triangles(vec![Triangle::new(Vec3A::ZERO, Vec3A::X, Vec3A::Y)]);
/// b.instance(Instance::of(g).transform(Affine3A::from_scale(Vec3A::ZERO.into())));
/// let e = b.build(&BuildOptions::default()).unwrap_err();
/// assert_eq!(e, WorldError::Transform { instance: 0, why: "not invertible" });
/// ```
#[derive(Clone, Debug)]
pub struct WorldBuilder<P = Triangle> {
    sources: Vec<Source<P>>,
    instances: Vec<Instance>,
    /// The first mesh whose indices did not check out, reported by `build`.
    bad_mesh: Option<(usize, MeshError)>,
}

/// A geometry before its BVH is built.
#[derive(Clone, Debug)]
enum Source<P> {
    Triangles(Vec<Triangle>),
    Prims(Vec<P>),
}

impl<P> Default for WorldBuilder<P> {
    fn default() -> Self {
        WorldBuilder {
            sources: Vec::new(),
            instances: Vec::new(),
            bad_mesh: None,
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
    pub fn mesh<'v>(
        &mut self,
        positions: impl Into<Positions<'v>>,
        indices: &[[u32; 3]],
    ) -> Result<GeometryId, MeshError> {
        let id = GeometryId(self.sources.len() as u32);
        match Mesh::new(positions.into(), indices) {
            Ok(mesh) => {
                let tris = (0..indices.len() as u32)
                    .map(|i| mesh.triangle(i))
                    .collect();
                self.sources.push(Source::Triangles(tris));
                Ok(id)
            }
            Err(e) => {
                // Keeps the numbering of the geometries after it; `build` reports the error.
                self.sources.push(Source::Triangles(Vec::new()));
                self.bad_mesh.get_or_insert((id.0 as usize, e.clone()));
                Err(e)
            }
        }
    }

    /// Adds triangles as a geometry.
    pub fn triangles(&mut self, tris: Vec<Triangle>) -> GeometryId {
        self.sources.push(Source::Triangles(tris));
        GeometryId(self.sources.len() as u32 - 1)
    }

    /// Adds primitives of the world's type as a geometry.
    pub fn prims(&mut self, prims: Vec<P>) -> GeometryId {
        self.sources.push(Source::Prims(prims));
        GeometryId(self.sources.len() as u32 - 1)
    }

    /// Adds an instance; returns its index (what [`WorldHit::instance`] reports).
    pub fn instance(&mut self, instance: Instance) -> u32 {
        self.instances.push(instance);
        self.instances.len() as u32 - 1
    }

    /// Builds every geometry's BVH with `options` (in parallel, on its pool) and the
    /// top-level BVH over the instances' world boxes (binned SAH, 8-wide nodes, on
    /// `options`' instruction set). The same builder gives the same world on any pool.
    ///
    /// # Errors
    /// [`WorldError`] for an instance naming no geometry, a transform that is not finite or
    /// not invertible, a bad mesh, or more than `u32::MAX` instances. An empty world is not
    /// an error: it is hit by nothing.
    pub fn build(self, options: &BuildOptions<'_>) -> Result<World<P>, WorldError> {
        use rayon::prelude::*;
        if self.instances.len() >= u32::MAX as usize || self.sources.len() >= u32::MAX as usize {
            return Err(WorldError::TooMany);
        }
        if let Some((geometry, error)) = self.bad_mesh {
            return Err(WorldError::Mesh { geometry, error });
        }
        let placements = self
            .instances
            .iter()
            .enumerate()
            .map(|(i, inst)| check_instance(i, inst, self.sources.len()))
            .collect::<Result<Vec<_>, _>>()?;
        let geometries: Vec<Geometry<P>> = options.run(|| {
            self.sources
                .into_par_iter()
                .map(|s| match s {
                    Source::Triangles(t) => Geometry::Triangles(options.build(&t), t),
                    Source::Prims(p) => Geometry::Prims(options.build(&p), p),
                })
                .collect()
        });
        let placed: Vec<Placed> = placements
            .into_iter()
            .enumerate()
            .map(|(i, placement)| Placed::new(i, &self.instances[i], placement))
            .collect();
        let boxes = options.run(|| world_boxes(&self.instances, &geometries));
        let top = options.run(|| top_level(&placed, &boxes, options.chosen_isa()));
        let bounds = boxes.iter().fold(Aabb::EMPTY, |b, w| b.union(w));
        Ok(World {
            geometries,
            instances: self.instances,
            top,
            bounds,
        })
    }
}

/// The instance's inverse transform and whether it is the identity, or what is wrong with it.
fn check_instance(
    index: usize,
    inst: &Instance,
    geometries: usize,
) -> Result<(Affine3A, bool), WorldError> {
    if inst.geometry.0 as usize >= geometries {
        return Err(WorldError::Geometry {
            instance: index,
            geometry: inst.geometry.0,
            geometries,
        });
    }
    let m = &inst.transform;
    invert(m).map_err(|why| WorldError::Transform {
        instance: index,
        why,
    })?;
    Ok(placement(m))
}

/// How far from the identity a transform times its f32 inverse may be, in each entry of the
/// linear part (and relative to the sizes added, in the translation): a few thousand ulps,
/// room for the rounding of a well-placed transform at any scale, far less than a transform
/// too close to singular for f32 (whose inverse's rounding moves hits visibly) leaves.
pub const INVERSE_TOLERANCE: f64 = 1.0 / 8192.0;

/// The inverse of an instance transform as the walk uses it (world to object space), or why
/// it cannot place a geometry: not finite, singular, an inverse out of f32's range, or an
/// inverse that is not one (the transform times it, in f64, is off the identity by more than
/// [`INVERSE_TOLERANCE`]). Computed in f64 and rounded once, so any scale whose inverse f32
/// holds is served: glam's f32 inverse divides by the f32 determinant, which overflows for a
/// uniform scale past about 7e12 (the inverse then comes out as zeros) and underflows below
/// about 1e-15.
///
/// ```
/// use quiver_rt::glam::{Affine3A, Vec3};
/// use quiver_rt::world::invert;
/// let big = Affine3A::from_scale(Vec3::splat(1e13));
/// assert_eq!(invert(&big).unwrap().matrix3.x_axis.x, 1e-13);
/// let tiny = Affine3A::from_scale(Vec3::splat(1e-30));
/// assert_eq!(invert(&tiny).unwrap().matrix3.x_axis.x, 1e30);
/// assert!(invert(&Affine3A::from_scale(Vec3::splat(1e-39))).is_err()); // 1e39 is past f32
/// assert!(invert(&Affine3A::from_scale(Vec3::new(1.0, 0.0, 1.0))).is_err());
/// ```
pub fn invert(m: &Affine3A) -> Result<Affine3A, &'static str> {
    if !m.is_finite() {
        return Err("not finite");
    }
    let wide = glam::DAffine3::from_cols_array(&m.to_cols_array().map(f64::from));
    // Entries of f32's range: the f64 determinant neither overflows nor underflows.
    if wide.matrix3.determinant() == 0.0 {
        return Err("not invertible");
    }
    let inverse = wide.matrix3.inverse();
    let f = |v: glam::DVec3| Vec3A::new(v.x as f32, v.y as f32, v.z as f32);
    let linear = Mat3A::from_cols(f(inverse.x_axis), f(inverse.y_axis), f(inverse.z_axis));
    // The translation through the rounded linear part: a world point near the instance then
    // maps as that one linear map of its offset from it, whose rounding error scales with the
    // offset, not with the distance from the origin.
    let d = |v: Vec3A| glam::DVec3::new(v.x as f64, v.y as f64, v.z as f64);
    let lin64 = glam::DMat3::from_cols(d(linear.x_axis), d(linear.y_axis), d(linear.z_axis));
    let rounded = Affine3A {
        matrix3: linear,
        translation: f(-(lin64 * wide.translation)),
    };
    // Where glam's f32 inverse is finite and is one (the check below), it is kept: the walk's
    // answers for every transform it served stay as they were; the f64 one serves the rest.
    let glam_inverse = m.inverse();
    if glam_inverse.is_finite() && is_inverse(&wide, &glam_inverse) {
        return Ok(glam_inverse);
    }
    if !rounded.is_finite() {
        return Err("out of f32's range to invert (its inverse is not finite)");
    }
    if !is_inverse(&wide, &rounded) {
        return Err("too close to singular for f32 (it times its f32 inverse is not the identity)");
    }
    Ok(rounded)
}

/// Whether `inverse` (f32) times `wide` (the transform in f64) is the identity within
/// [`INVERSE_TOLERANCE`].
fn is_inverse(wide: &glam::DAffine3, inverse: &Affine3A) -> bool {
    let rounded = inverse;
    let back = glam::DAffine3::from_cols_array(&rounded.to_cols_array().map(f64::from));
    let product = wide * back;
    let abs =
        |a: glam::DMat3| glam::DMat3::from_cols(a.x_axis.abs(), a.y_axis.abs(), a.z_axis.abs());
    let linear_off = (product.matrix3 - glam::DMat3::IDENTITY)
        .to_cols_array()
        .into_iter()
        .fold(0.0f64, |a, x| a.max(x.abs()));
    // The translation's error, against the size of what was added to make it.
    let size = abs(wide.matrix3) * back.translation.abs() + wide.translation.abs();
    let moved_off = product
        .translation
        .abs()
        .cmpgt(size * INVERSE_TOLERANCE)
        .any();
    linear_off <= INVERSE_TOLERANCE && !moved_off
}

/// Whether `m` mirrors (reverses a triangle's winding): its determinant's sign, taken in f64
/// so that it neither overflows nor underflows to zero at any f32 scale.
pub(crate) fn mirrors(m: &Affine3A) -> bool {
    let d = glam::DMat3::from_cols_array(&m.matrix3.to_cols_array().map(f64::from));
    d.determinant() < 0.0
}

/// A checked transform's inverse ([`invert`]) and whether it is the identity.
fn placement(m: &Affine3A) -> (Affine3A, bool) {
    (
        invert(m).unwrap_or(Affine3A::IDENTITY),
        *m == Affine3A::IDENTITY,
    )
}

/// The world box of an object box placed by `m`: the box of its eight transformed corners.
fn world_box(m: &Affine3A, b: &Aabb) -> Aabb {
    if b.is_empty() {
        return Aabb::EMPTY;
    }
    let mut out = Aabb::EMPTY;
    for k in 0..8 {
        let c = Vec3A::new(
            if k & 1 == 0 { b.min.x } else { b.max.x },
            if k & 2 == 0 { b.min.y } else { b.max.y },
            if k & 4 == 0 { b.min.z } else { b.max.z },
        );
        out.grow(m.transform_point3a(c));
    }
    // The walk meets the geometry through the inverse transform, the box went through the
    // forward one: widened by 2^-20 of its coordinates' size, rounding in either cannot cull
    // a hit the object-space walk would find. In halves, and clamped to the finite range, so
    // a box reaching toward f32::MAX stays finite (an infinite box would drop the instance):
    // every point the walk can meet is finite, so the clamped box still holds it.
    let half = out.min.abs().max(out.max.abs()) * 0.5 + (out.max * 0.5 - out.min * 0.5);
    let pad = half * (1.0 / (1u32 << 19) as f32);
    let finite = |v: Vec3A| v.clamp(Vec3A::splat(f32::MIN), Vec3A::splat(f32::MAX));
    Aabb::new(finite(out.min - pad), finite(out.max + pad))
}

/// Every instance's world box, in instance order: what the top level is built over. Kept
/// out of [`Placed`], which the walks read, so a placed instance fills one cache line; the
/// refit computes them again from the instances ([`Source::bounds`] of `edit::Top`).
///
/// [`Source::bounds`]: crate::layout::refit::Source::bounds
fn world_boxes<P: Primitive>(instances: &[Instance], geometries: &[Geometry<P>]) -> Vec<Aabb> {
    use rayon::prelude::*;
    instances
        .par_iter()
        .map(|inst| instance_box(inst, geometries))
        .collect()
}

/// The world box of instance `inst` as placed now.
fn instance_box<P: Primitive>(inst: &Instance, geometries: &[Geometry<P>]) -> Aabb {
    world_box(
        &inst.transform,
        &geometries[inst.geometry.0 as usize].bounds(),
    )
}

/// The top-level BVH over `placed` (in instance order), whose world boxes are `boxes`:
/// 8-wide, one instance per leaf (an instance's test is a whole walk of its geometry, far
/// costlier than a node's). The build drops an instance whose box is not finite.
///
/// It keeps no input indices (`prim_ids` empty): the input index of a record is the
/// instance it names, so they would repeat `Placed::instance` in 4 more bytes an instance.
/// Only a refit reads them, and `World::refit_top` lends it a copy for the while.
fn top_level(placed: &[Placed], boxes: &[Aabb], isa: Isa) -> Bvh8<Placed> {
    let config = BuildConfig {
        max_leaf_size: 1,
        ..BuildConfig::default()
    };
    let tree = build(boxes, &config, Builder::Binned);
    let mut top = Bvh8::from_leaf_prims(&tree, leaf_order(&tree, placed).into(), isa, &config);
    debug_assert!(top
        .prims
        .iter()
        .map(|p| p.instance)
        .eq(top.prim_ids.iter().copied()));
    top.prim_ids = Vec::new();
    top
}

/// An instance as the walks read it, in top-level leaf order: one cache line, so a leaf's
/// instance costs the walk one miss. Its world box is not kept (the walks never read it:
/// the top level's nodes hold it); builds and refits compute it from the [`Instance`].
#[derive(Clone, Debug)]
#[repr(C, align(64))]
pub(crate) struct Placed {
    /// World to object space, packed into 48 bytes: `to_object[j]` holds column `j` of the
    /// linear part in lanes 0..3 and the translation's component `j` in lane 3 (read through
    /// [`Placed::world_to_object`], or lane by lane by the packet transform).
    pub(crate) to_object: [[f32; 4]; 3],
    pub(crate) geometry: u32,
    pub(crate) mask: u32,
    /// Its index among the instances.
    pub(crate) instance: u32,
    /// The identity transform: rays go in as they are.
    pub(crate) identity: bool,
}

// One line per instance: a record that grew past it would cost every instance entry a
// second miss and the world's memory target (issue 26) its margin.
const _: () = assert!(std::mem::size_of::<Placed>() == 64);

impl Placed {
    /// Instance `index` (`inst`, with its checked `placement`).
    fn new(index: usize, inst: &Instance, (world_to_object, identity): (Affine3A, bool)) -> Placed {
        let (m, t) = (world_to_object.matrix3, world_to_object.translation);
        let col = |c: Vec3A, t: f32| [c.x, c.y, c.z, t];
        Placed {
            to_object: [col(m.x_axis, t.x), col(m.y_axis, t.y), col(m.z_axis, t.z)],
            geometry: inst.geometry.0,
            mask: inst.mask,
            instance: index as u32,
            identity,
        }
    }

    /// World to object space: the inverse transform the instance was placed with, the same
    /// floats in the same lanes, so glam's products run as they did on it. Each vector is
    /// built from its three floats (lane 3 a copy of lane 2, as [`Vec3A::new`] makes it):
    /// lane 3 then repeats lane 2's arithmetic, and never multiplies a translation
    /// component, which may be subnormal (an assist per multiply, ~100x its cost) or make a
    /// subnormal product.
    #[inline(always)]
    pub(crate) fn world_to_object(&self) -> Affine3A {
        // Whole columns loaded and shuffled in registers (a load and a shuffle a column, two
        // shuffles for the translation); element by element, LLVM built each from scalars.
        let [x, y, z] = self.to_object.map(Vec4::from_array);
        let col = |c: Vec4| Vec3A::from_vec4(c.xyzz());
        Affine3A {
            matrix3: Mat3A::from_cols(col(x), col(y), col(z)),
            translation: Vec3A::new(x.w, y.w, z.w),
        }
    }

    /// `ray` in object space, searching up to `t_max` (the same parameter as in world space).
    #[inline(always)]
    pub(crate) fn local(&self, ray: &Ray, t_max: f32) -> Ray {
        if self.identity {
            return Ray { t_max, ..*ray };
        }
        let to_object = self.world_to_object();
        Ray {
            origin: to_object.transform_point3a(ray.origin),
            dir: to_object.transform_vector3a(ray.dir),
            t_max,
            ..*ray
        }
    }
}

/// The top level's primitive, for the layout's sake only: [`Bvh8`] holds it as its leaf
/// data, which the world's walks read (they test the instance's geometry, never `intersect`).
///
/// `bounds` is not called either, so the record keeps no box. No path of `Bvh8<Placed>`
/// reaches it: the build takes the world boxes from [`world_boxes`] (never `prim_bounds`),
/// `Bvh8::from_leaf_prims` lays out the tree's boxes (a plain leaf format packs no groups and
/// reads no primitive's box), `footprint` counts bytes, and the refit asks its source for
/// every leaf box ([`Source::bounds`](crate::layout::refit::Source::bounds), which
/// `edit::Top` computes from the instance); nor are the defaults that call it
/// (`surface_area`, `is_finite`), nor the layout's own queries. A path that did would be a bug,
/// so it panics rather than give a box.
impl Primitive for Placed {
    fn bounds(&self) -> Aabb {
        unreachable!("a placed instance keeps no box: its world box comes from the instance")
    }
    fn intersect(&self, _: &Ray) -> Option<PrimHit> {
        None
    }
}

/// Geometries placed by instances under one top-level BVH (see the [module](self) docs).
#[derive(Clone, Debug)]
pub struct World<P = Triangle> {
    geometries: Vec<Geometry<P>>,
    instances: Vec<Instance>,
    top: Bvh8<Placed>,
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
    /// Instance `i` as it was added.
    ///
    /// # Panics
    /// When `i` is not an instance index (a hit's `instance` always is).
    pub fn instance(&self, i: u32) -> &Instance {
        &self.instances[i as usize]
    }

    /// Every instance, in the order added.
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
    /// primitive's winding faces, as placed: a mirroring transform reverses it), or `None`
    /// where the primitive type gives no normal
    /// ([`Primitive::geometric_normal`]).
    pub fn normal(&self, ray: &Ray, hit: &WorldHit) -> Option<Vec3A> {
        let inst = self.instances.get(hit.instance as usize)?;
        let g = self.geometries.get(hit.geometry as usize)?;
        let to_object = invert(&inst.transform).ok()?;
        let at = to_object.transform_point3a(ray.at(hit.t));
        let local = PrimHit {
            t: hit.t,
            u: hit.u,
            v: hit.v,
        };
        let n = g.normal(hit.prim, at, &local)?;
        // Normals go by the inverse transpose of the linear part; a mirroring transform also
        // reverses the winding, which is what says which side a triangle faces.
        let inverse_t: Mat3A = to_object.matrix3.transpose();
        let n = unit_or_zero(inverse_t * n);
        Some(if mirrors(&inst.transform) { -n } else { n })
    }

    /// The top-level BVH, for readers inside the crate (the cost predictor).
    pub(crate) fn top(&self) -> &Bvh8<Placed> {
        &self.top
    }

    /// What the world occupies: the top level, every geometry's BVH once (however often it is
    /// placed) and the instance records. `nodes` counts the top level's and the geometries'
    /// node slots.
    pub fn footprint(&self) -> Footprint {
        let top = self.top.footprint();
        let instances = std::mem::size_of_val(self.instances.as_slice());
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::soup;

    #[test]
    fn building_a_world_twice_gives_the_same_top_level_tree_on_any_pool() {
        let tris = soup(200, 3);
        let make = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            let mut b = World::builder();
            let g = b.triangles(tris.clone());
            for i in 0..500 {
                let at = Vec3A::new((i % 23) as f32, (i / 23) as f32, (i % 7) as f32);
                b.instance(Instance::of(g).transform(Affine3A::from_translation(at.into())));
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
