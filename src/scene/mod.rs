//! Scene sources: the SPD generators (so far `tetra`), a seeded random triangle soup, and OBJ
//! files. A scene argument is either a generator name with an optional size (`tetra6`,
//! `tetra`, `soup100000`) or a path ending in `.obj`.
//!
//! ```
//! use quiver::scene::Scene;
//! let s = Scene::load("tetra2").unwrap();
//! assert_eq!((s.objects, s.triangles.len()), (16, 16));
//! assert!(Scene::load("nosuchscene").unwrap_err().to_string().contains("tetra"));
//! ```

mod camera;
#[cfg(feature = "obj")]
mod obj;
mod soup;
mod tetra;

pub use camera::Camera;

use crate::geometry::{Aabb, Triangle};
use glam::Vec3A;
use std::fmt;
use std::path::{Path, PathBuf};

/// Geometry plus the viewpoint and lights that go with it.
#[derive(Clone, Debug)]
pub struct Scene {
    /// The name it was loaded by (`tetra6`, a file path, ...).
    pub name: String,
    /// All geometry as triangles.
    pub triangles: Vec<Triangle>,
    /// What the source counts as objects (the SPD counts each polygon once).
    pub objects: usize,
    /// The viewpoint.
    pub camera: Camera,
    /// Positional lights.
    pub lights: Vec<Vec3A>,
    /// Background colour (linear RGB).
    pub background: Vec3A,
}

/// A procedural scene: its name, the size it gets without one, and how to make it.
pub struct Generator {
    /// Name prefix on the command line.
    pub name: &'static str,
    /// Size used when the name has no number.
    pub default_size: u32,
    /// Largest size accepted (keeps a typo from exhausting memory).
    pub max_size: u32,
    /// One line for `--help` and error messages.
    pub about: &'static str,
    /// Makes the scene of a given size.
    pub make: fn(u32) -> Scene,
}

/// Every built-in generator.
pub const GENERATORS: &[Generator] = &[
    Generator {
        name: "tetra",
        default_size: 6,
        max_size: 12,
        about: "SPD tetra: recursive tetrahedron, 4^size triangles",
        make: tetra::tetra,
    },
    Generator {
        name: "soup",
        default_size: 10_000,
        max_size: 50_000_000,
        about: "seeded random triangle soup, size = triangle count",
        make: soup::soup,
    },
];

/// Why a scene could not be loaded.
#[derive(Debug)]
pub enum SceneError {
    /// A name that is neither a known generator nor a supported file.
    Unknown(String),
    /// A generator size outside its range.
    Size {
        /// The generator.
        name: String,
        /// The size asked for.
        size: String,
        /// The largest accepted.
        max: u32,
    },
    /// A file that could not be read or parsed.
    File {
        /// The file.
        path: PathBuf,
        /// What went wrong, with a line number where known.
        message: String,
    },
}

impl fmt::Display for SceneError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SceneError::Unknown(s) => {
                let names: Vec<_> = GENERATORS.iter().map(|g| g.name).collect();
                write!(
                    f,
                    "unknown scene '{s}': expected a generator name with an optional size ({}) or a .obj file",
                    names.join(", ")
                )
            }
            SceneError::Size { name, size, max } => {
                write!(
                    f,
                    "scene '{name}': size '{size}' must be a number from 0 to {max}"
                )
            }
            SceneError::File { path, message } => write!(f, "{}: {message}", path.display()),
        }
    }
}

impl std::error::Error for SceneError {}

impl Scene {
    /// Loads a scene by name (`tetra6`, `soup1000`) or from an `.obj` path.
    pub fn load(spec: &str) -> Result<Scene, SceneError> {
        let lower = spec.to_ascii_lowercase();
        if lower.ends_with(".obj") {
            return load_obj(Path::new(spec));
        }
        if lower.ends_with(".nff") {
            return Err(SceneError::File {
                path: spec.into(),
                message: "NFF files are not supported yet".into(),
            });
        }
        let split = spec
            .find(|c: char| c.is_ascii_digit())
            .unwrap_or(spec.len());
        let (name, size) = spec.split_at(split);
        let gen = GENERATORS
            .iter()
            .find(|g| g.name == name)
            .ok_or_else(|| SceneError::Unknown(spec.to_string()))?;
        let size = if size.is_empty() {
            gen.default_size
        } else {
            size.parse::<u32>()
                .ok()
                .filter(|&s| s <= gen.max_size)
                .ok_or_else(|| SceneError::Size {
                    name: name.into(),
                    size: size.into(),
                    max: gen.max_size,
                })?
        };
        Ok((gen.make)(size))
    }

    /// Bounds of all finite triangles.
    pub fn bounds(&self) -> Aabb {
        self.triangles
            .iter()
            .filter(|t| t.is_finite())
            .fold(Aabb::EMPTY, |b, t| b.union(&t.bounds()))
    }
}

#[cfg(feature = "obj")]
fn load_obj(path: &Path) -> Result<Scene, SceneError> {
    obj::load(path)
}

#[cfg(not(feature = "obj"))]
fn load_obj(path: &Path) -> Result<Scene, SceneError> {
    Err(SceneError::File {
        path: path.into(),
        message: "OBJ support needs quiver's `obj` feature".into(),
    })
}
