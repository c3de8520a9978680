//! What a world places: [`Instance`] (a geometry, its transform, mask and the caller's own
//! id), the ids that name geometries and instances ([`GeometryId`], [`InstanceId`]), and the
//! checks a placement must pass.

use super::top::InstanceLeaf;
use super::{Motion, WorldError};
use glam::{Affine3A, Mat3A, Vec3A};

/// A geometry's index in its [`World`](super::World), in the order geometries were added:
/// what [`WorldBuilder`](super::WorldBuilder)'s `add_mesh`, `add_triangles` and `add_prims`
/// return, [`Instance::of`] takes and [`WorldHit::geometry`](super::WorldHit::geometry)
/// reports.
///
/// ```
/// use quiver_rt::{GeometryId, Triangle, World};
/// use quiver_rt::glam::Vec3A;
/// let mut b = World::builder();
/// let tri = Triangle::new(Vec3A::ZERO, Vec3A::X, Vec3A::Y);
/// assert_eq!(b.add_triangles(vec![tri]), GeometryId(0));
/// assert_eq!(b.add_triangles(vec![tri]), GeometryId(1));
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct GeometryId(pub u32);

/// An instance's index in its [`World`](super::World), in the order instances were added:
/// what [`WorldBuilder::add_instance`](super::WorldBuilder::add_instance) returns,
/// [`WorldHit::instance`](super::WorldHit::instance) reports and
/// [`World::instance`](super::World::instance) and the edits take. (The caller's own id for
/// an instance, which quiver never reads, is [`Instance::user_id`].)
///
/// ```
/// use quiver_rt::{Instance, InstanceId, Triangle, World};
/// use quiver_rt::glam::Vec3A;
/// let mut b = World::builder();
/// let g = b.add_triangles(vec![Triangle::new(Vec3A::ZERO, Vec3A::X, Vec3A::Y)]);
/// assert_eq!(b.add_instance(Instance::of(g)), InstanceId(0));
/// assert_eq!(b.add_instance(Instance::of(g).user_id(7)), InstanceId(1));
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct InstanceId(pub u32);

/// One placement of a geometry: which geometry, its object-to-world transform (a 3×4
/// affine map), which rays see it and the caller's own id for it.
///
/// ```
/// use quiver_rt::glam::{Affine3A, Vec3};
/// use quiver_rt::{GeometryId, Instance};
/// let tree = Instance::of(GeometryId(3))
///     .transform(Affine3A::from_scale(Vec3::splat(2.0)))
///     .mask(0b01)
///     .user_id(42);
/// assert_eq!((tree.geometry, tree.mask, tree.user_id), (GeometryId(3), 1, 42));
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
    /// The caller's own id for the instance (a material, an object in the caller's scene);
    /// quiver never reads it. 0 by default. Not the instance's [`InstanceId`], its index.
    pub user_id: u32,
}

impl Instance {
    /// `geometry` in world space (the identity transform), seen by every ray, user id 0.
    pub fn of(geometry: GeometryId) -> Instance {
        Instance {
            geometry,
            transform: Affine3A::IDENTITY,
            mask: u32::MAX,
            user_id: 0,
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

    /// The caller's own id for this instance ([`Instance::user_id`]).
    pub fn user_id(self, user_id: u32) -> Instance {
        Instance { user_id, ..self }
    }
}

/// The instance's inverse transform (at time 0, if it moves by `motion`) and whether it is
/// the identity, or what is wrong with it.
pub(super) fn check_instance(
    index: usize,
    inst: &Instance,
    motion: Option<&Motion>,
    geometries: usize,
) -> Result<(Affine3A, bool), WorldError> {
    if inst.geometry.0 as usize >= geometries {
        return Err(WorldError::Geometry {
            instance: index,
            geometry: inst.geometry.0,
            geometries,
        });
    }
    if let Some(m) = motion {
        m.check(index)?;
    }
    let m = &inst.transform;
    invert(m).map_err(|why| WorldError::Transform {
        instance: index,
        why,
    })?;
    Ok(placement(m))
}

/// Instance `i`'s motion in a per-instance list that holds entries up to the last moving one.
pub(super) fn motion_of(motions: &[Option<Motion>], i: usize) -> Option<&Motion> {
    motions.get(i).and_then(Option::as_ref)
}

/// Every instance's record for the top level's leaves, in instance order, each checked as
/// [`check_instance`] checks it (the first error, in instance order, is the answer), or
/// [`WorldError::TooMany`] for more than `u32::MAX - 1` instances or geometries.
pub(super) fn placements(
    instances: &[Instance],
    motions: &[Option<Motion>],
    geometries: usize,
) -> Result<Vec<InstanceLeaf>, WorldError> {
    if instances.len() >= u32::MAX as usize || geometries >= u32::MAX as usize {
        return Err(WorldError::TooMany);
    }
    instances
        .iter()
        .enumerate()
        .map(|(i, inst)| {
            let motion = motion_of(motions, i);
            let placed = check_instance(i, inst, motion, geometries)?;
            Ok(InstanceLeaf::new(i, inst, placed, motion.is_some()))
        })
        .collect()
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
/// // The inverse of the f32 nearest 1e13, in f64, rounded once to f32.
/// let big = Affine3A::from_scale(Vec3::splat(1e13));
/// assert_eq!(invert(&big).unwrap().matrix3.x_axis.x, (1.0 / 1e13f32 as f64) as f32);
/// let tiny = Affine3A::from_scale(Vec3::splat(1e-30));
/// assert_eq!(invert(&tiny).unwrap().matrix3.x_axis.x, (1.0 / 1e-30f32 as f64) as f32);
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
pub(super) fn placement(m: &Affine3A) -> (Affine3A, bool) {
    (
        invert(m).unwrap_or(Affine3A::IDENTITY),
        *m == Affine3A::IDENTITY,
    )
}
