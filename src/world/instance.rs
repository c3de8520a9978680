//! What a world places: [`Instance`] (a geometry, its transform, mask and the caller's id),
//! the ids that name geometries ([`GeometryId`]), and the checks a placement must pass.

use super::WorldError;
use glam::Affine3A;

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
