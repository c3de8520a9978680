//! [`BuildError`]: why a build could not start.

use super::ConfigError;
use crate::mesh::MeshError;
use std::fmt;

/// Why a build refused its input: a setting out of range, a mesh whose indices name no
/// vertex, or surface areas that do not match the primitives. Nothing is built then.
///
/// ```
/// use quiver_rt::builders::{BuildConfig, ConfigError};
/// use quiver_rt::{BuildError, BuildOptions, Bvh, Triangle};
/// use glam::Vec3A;
/// let tris = [Triangle::new(Vec3A::ZERO, Vec3A::X, Vec3A::Y)];
/// let zero_leaves = BuildOptions::default().max_leaf_size(0);
/// let e = Bvh::build(&tris, &zero_leaves).unwrap_err();
/// assert_eq!(e, BuildError::Config(ConfigError::MaxLeafSize));
/// assert_eq!(e.to_string(), "build settings: max_leaf_size must be at least 1, got 0");
/// ```
#[derive(Clone, Debug, PartialEq)]
pub enum BuildError {
    /// A [`BuildConfig`](super::BuildConfig) setting out of range
    /// ([`BuildConfig::check`](super::BuildConfig::check)).
    Config(ConfigError),
    /// The mesh built over names a vertex it does not have, or has too many triangles.
    Mesh(MeshError),
    /// `areas` surface areas were given for `prims` primitives
    /// ([`build_with_areas`](super::build_with_areas) takes one per primitive).
    AreaCount {
        /// Areas given.
        areas: usize,
        /// Primitives (boxes) given.
        prims: usize,
    },
}

impl fmt::Display for BuildError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            BuildError::Config(e) => write!(f, "build settings: {e}"),
            BuildError::Mesh(e) => write!(f, "{e}"),
            BuildError::AreaCount { areas, prims } => write!(
                f,
                "{areas} surface areas given for {prims} primitives: one per primitive"
            ),
        }
    }
}

impl std::error::Error for BuildError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            BuildError::Config(e) => Some(e),
            BuildError::Mesh(e) => Some(e),
            BuildError::AreaCount { .. } => None,
        }
    }
}

impl From<ConfigError> for BuildError {
    fn from(e: ConfigError) -> Self {
        BuildError::Config(e)
    }
}

impl From<MeshError> for BuildError {
    fn from(e: MeshError) -> Self {
        BuildError::Mesh(e)
    }
}
