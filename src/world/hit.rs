//! [`WorldHit`]: what a world's query answers, instance, geometry and primitive.

use super::{GeometryId, InstanceId};

/// What a hit in a [`World`](super::World) names: enough for a shader to find the surface and
/// its material ([`World::instance`](super::World::instance) gives the instance's
/// [`Instance::user_id`](super::Instance::user_id)).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WorldHit {
    /// Distance along the world ray (in units of its direction).
    pub t: f32,
    /// The instance hit: its index in the order instances were added.
    pub instance: InstanceId,
    /// The geometry it places.
    pub geometry: GeometryId,
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
            instance: InstanceId(u32::MAX),
            geometry: GeometryId(u32::MAX),
            prim: u32::MAX,
            u: 0.0,
            v: 0.0,
        }
    }

    /// `Some(self)` unless nothing was found.
    pub(crate) fn found(self) -> Option<WorldHit> {
        (self.instance.0 != u32::MAX).then_some(self)
    }

    /// Whether a hit at `t` in `instance` replaces this one: nearer, or as near in a lower
    /// instance (inside one instance the geometry's own tie rule has already chosen).
    #[inline(always)]
    pub(crate) fn is_beaten_by(&self, t: f32, instance: u32) -> bool {
        t < self.t || (t == self.t && instance < self.instance.0)
    }
}
