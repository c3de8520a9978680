//! [`WorldError`]: what a world could not be built or edited from.

use crate::builders::ConfigError;
use crate::bvh::RefitError;
use crate::mesh::MeshError;
use std::fmt;

/// What a [`World`](super::World) could not be built from or edited to: each names the instance or geometry at fault.
#[derive(Clone, Debug, PartialEq)]
pub enum WorldError {
    /// A setting of the build options' [`BuildConfig`](crate::builders::BuildConfig) is out
    /// of range.
    Config(ConfigError),
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
        /// singular for f32 ([`invert`](super::invert)).
        why: &'static str,
    },
    /// Instance `instance`'s [`Motion`](super::Motion) cannot move it: `why`, at key `key`
    /// where one key is at fault.
    Motion {
        /// The instance.
        instance: usize,
        /// The key at fault, if one is.
        key: Option<usize>,
        /// Fewer than two keys or too many, a key not finite or not invertible ([`invert`](
        /// super::invert)), keys that mirror beside keys that do not, or a decomposed step of
        /// half a turn or more.
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
    /// An edit named instance `instance`, which an earlier edit removed.
    Removed {
        /// The instance named.
        instance: u32,
    },
    /// An edit gave geometry `geometry` primitives of the other kind: it `holds` triangles
    /// or the world's own primitive type.
    GeometryKind {
        /// The geometry.
        geometry: u32,
        /// What it holds: "triangles", "primitives of the world's type" or "a moving mesh
        /// ...".
        holds: &'static str,
    },
    /// Geometry `geometry`'s time steps cannot make a moving mesh
    /// ([`WorldBuilder::add_moving_triangles`](super::WorldBuilder::add_moving_triangles),
    /// [`WorldEdit::refit_moving_triangles`](super::WorldEdit::refit_moving_triangles)): `why`,
    /// at step `step` where one step is at fault.
    Steps {
        /// The geometry (the index it has or would have had).
        geometry: usize,
        /// The step at fault, if one is.
        step: Option<usize>,
        /// Fewer than two steps, a step of a different number of triangles than step 0, a
        /// vertex that is not finite, or (a refit) a different number of steps than the mesh
        /// has.
        why: &'static str,
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
            WorldError::Config(e) => write!(f, "build settings: {e}"),
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
            WorldError::Motion {
                instance,
                key: Some(key),
                why,
            } => write!(f, "instance {instance}: motion key {key}: {why}"),
            WorldError::Motion {
                instance,
                key: None,
                why,
            } => write!(f, "instance {instance}: the motion has {why}"),
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
            WorldError::Removed { instance } => {
                write!(f, "instance {instance} was removed from the world")
            }
            WorldError::GeometryKind { geometry, holds } => {
                write!(f, "geometry {geometry} holds {holds}, and takes only those")
            }
            WorldError::Refit { geometry, error } => write!(f, "geometry {geometry}: {error}"),
            WorldError::Steps {
                geometry,
                step: Some(step),
                why,
            } => write!(f, "geometry {geometry}: time step {step} has {why}"),
            WorldError::Steps {
                geometry,
                step: None,
                why,
            } => write!(f, "geometry {geometry}: the moving mesh has {why}"),
        }
    }
}

impl std::error::Error for WorldError {}
