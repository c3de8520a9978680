//! What a world places: [`Instance`] (a geometry, its transform, mask and the caller's own
//! id), the ids that name geometries and instances ([`GeometryId`], [`InstanceId`]), and the
//! checks a placement must pass.

use super::WorldError;
use glam::Affine3A;

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

/// The instance's inverse transform and whether it is the identity, or what is wrong with it.
pub(super) fn check_instance(
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
    let bad = |why| {
        Err(WorldError::Transform {
            instance: index,
            why,
        })
    };
    if !m.is_finite() {
        return bad("not finite");
    }
    if m.matrix3.determinant() == 0.0 {
        return bad("not invertible");
    }
    let (inverse, identity) = placement(m);
    if !inverse.is_finite() {
        return bad("out of f32's range to invert (its inverse is not finite)");
    }
    Ok((inverse, identity))
}

/// A checked transform's inverse and whether it is the identity.
pub(super) fn placement(m: &Affine3A) -> (Affine3A, bool) {
    (m.inverse(), *m == Affine3A::IDENTITY)
}
