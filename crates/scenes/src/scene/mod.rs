//! Scene sources: the ten SPD generators ([`GENERATORS`]), a seeded random triangle soup,
//! NFF, OBJ, PLY and glTF files. A scene argument is either a generator name with an optional
//! size (`tetra6`, `balls`, `soup100000`) or a path ending in `.nff`, `.obj`, `.ply`,
//! `.ply.gz`, `.gltf` or `.glb`.
//!
//! ```
//! use quiver_scenes::scene::Scene;
//! let s = Scene::load("tetra2").unwrap();
//! assert_eq!((s.objects.len(), s.triangles().len()), (16, 16));
//! assert!(Scene::load("nosuchscene").unwrap_err().to_string().contains("tetra"));
//! ```
//!
//! Files are read strictly, and every format reports a fault alike: as
//! `file:line: what was expected` ([`SceneError::Parse`]) where the fault has a line (NFF, OBJ,
//! a PLY header or ASCII body, glTF's JSON), as `file: item: what was expected`
//! ([`SceneError::Item`]) where it has none (a binary PLY element, a glTF accessor). A NaN or infinite number is an
//! error too, unless [`LoadOptions`] asks for the primitives and lights that hold one to be
//! dropped and counted ([`LoadReport`]):
//!
//! ```
//! use quiver_scenes::scene::{nff, LoadOptions, NonFinite};
//! let text = "f 1 1 1 1 0 0 0 1\ns 0 0 0 1\ns 0 nan 0 1\n";
//! let e = nff::parse(text, "two.nff").unwrap_err();
//! assert_eq!(e.to_string(), "two.nff:3: sphere centre y is NaN ('nan')");
//! let lax = LoadOptions::default().non_finite(NonFinite::Drop);
//! let (scene, report) = nff::parse_with(text, "two.nff", &lax).unwrap();
//! assert_eq!((scene.objects.len(), report.dropped_primitives), (1, 1));
//! ```

mod camera;
mod census;
pub mod gltf;
pub mod nff;
pub mod obj;
pub mod ply;
mod read;
mod soup;
mod spd;
pub mod tessellate;

pub use camera::{Camera, CameraError, View};
pub use census::Census;
pub use read::{read_bytes, read_text, MAX_FILE_BYTES};

use crate::primitive::{Cone, PatchTriangle, Polygon, PolygonPiece, Prim, Sphere};
use glam::Vec3A;
use quiver_rt::geometry::{Aabb, Triangle};
use quiver_rt::primitive::Primitive;
use std::fmt;
use std::ops::Range;
use std::path::{Path, PathBuf};

/// A surface description in NFF terms (`f r g b Kd Ks Shine T index_of_refraction`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Material {
    /// Base colour, linear RGB in 0..1.
    pub color: Vec3A,
    /// Diffuse coefficient.
    pub kd: f32,
    /// Specular coefficient; above 0 the surface reflects (and gets Phong highlights).
    pub ks: f32,
    /// Phong exponent.
    pub shine: f32,
    /// Transmittance; above 0 the surface refracts.
    pub t: f32,
    /// Index of refraction.
    pub ior: f32,
}

impl Material {
    /// The material of files that bring none: white, diffuse, not reflective.
    pub const DEFAULT: Material = Material {
        color: Vec3A::ONE,
        kd: 0.8,
        ks: 0.0,
        shine: 0.0,
        t: 0.0,
        ior: 1.0,
    };
}

/// One object as the SPD counts it: a sphere, a cone or cylinder, a polygon or a polygonal
/// patch.
#[derive(Clone, Debug, PartialEq)]
pub enum Shape {
    /// NFF `s`.
    Sphere(Sphere),
    /// NFF `c`.
    Cone(Cone),
    /// NFF `p` with three vertices.
    Triangle(Triangle),
    /// NFF `p` with more vertices (planar, possibly concave).
    Polygon(Vec<Vec3A>),
    /// NFF `pp`: a planar polygon with a normal per vertex.
    Patch {
        /// Vertices.
        verts: Vec<Vec3A>,
        /// One normal per vertex.
        normals: Vec<Vec3A>,
    },
}

/// A shape and the index of its material in [`Scene::materials`].
#[derive(Clone, Debug, PartialEq)]
pub struct Object {
    /// The geometry.
    pub shape: Shape,
    /// Index into [`Scene::materials`].
    pub material: u32,
}

/// A positional light.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Light {
    /// Position.
    pub pos: Vec3A,
    /// Colour (white unless the scene says otherwise).
    pub color: Vec3A,
}

/// A named run of consecutive objects that came from one mesh of a file: an OBJ `o`/`g`
/// group, a PLY file, a glTF mesh primitive placed by a node. Plain data, kept so that a later
/// stage can instance or select meshes; the BVH and the renderer do not read it.
///
/// ```
/// use quiver_scenes::scene::{obj, Group};
/// let text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\no wing\nf 1 2 3\ng tip\nf 2 4 3\n";
/// let scene = obj::parse(text, "plane.obj").unwrap();
/// assert_eq!(scene.groups, [
///     Group { name: "wing".into(), objects: 0..1 },
///     Group { name: "wing/tip".into(), objects: 1..2 },
/// ]);
/// ```
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Group {
    /// The name the file gives it (see each reader for how it is formed).
    pub name: String,
    /// Its objects: indices into [`Scene::objects`], never empty.
    pub objects: Range<u32>,
}

/// Geometry plus the viewpoint, lights and materials that go with it: an NFF file's content.
#[derive(Clone, Debug)]
pub struct Scene {
    /// The name it was loaded by (`tetra6`, a file path, ...).
    pub name: String,
    /// The objects, in output order.
    pub objects: Vec<Object>,
    /// Materials the objects refer to.
    pub materials: Vec<Material>,
    /// The viewpoint.
    pub camera: Camera,
    /// Positional lights.
    pub lights: Vec<Light>,
    /// Background colour (linear RGB).
    pub background: Vec3A,
    /// Distance of the near clipping plane (NFF `hither`); eye rays start there.
    pub hither: f32,
    /// Image size the scene was designed for (NFF `resolution`).
    pub resolution: [u32; 2],
    /// Which objects came from which mesh of the file, in object order and without overlap:
    /// OBJ `o`/`g` groups, one group per PLY file, one per glTF mesh primitive placed by a
    /// node. Empty for generated scenes and NFF files, which have no meshes to name; objects a
    /// group does not cover belong to none.
    pub groups: Vec<Group>,
}

/// A procedural scene: its name, the size it gets without one, and how to make it.
pub struct Generator {
    /// Name prefix on the command line.
    pub name: &'static str,
    /// Size used when the name has no number.
    pub default_size: u32,
    /// Smallest size accepted (the SPD lattice divides by zero at 0).
    pub min_size: u32,
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
        name: "balls",
        default_size: 4,
        min_size: 0,
        // 7 is 5.4 million spheres: traced as instances (`--instanced`) it fits in a few GB;
        // flattened, the memory estimate refuses it before any work.
        max_size: 7,
        about: "SPD sphereflake: (9^(size+1)-1)/8 mirrored spheres on a floor",
        make: spd::balls::make,
    },
    Generator {
        name: "gears",
        default_size: 4,
        min_size: 0,
        max_size: 12,
        about: "SPD gears: size^3 gear pairs with 144-vertex concave faces, some transparent",
        make: spd::gears::make,
    },
    Generator {
        name: "jacks",
        default_size: 1,
        min_size: 0,
        max_size: 6,
        about: "SPD jacks: recursive jacks of spheres and cylinders",
        make: spd::jacks::make,
    },
    Generator {
        name: "lattice",
        default_size: 12,
        min_size: 1,
        max_size: 60,
        about: "SPD lattice: (size+1)^3 spheres joined by cylinders",
        make: spd::lattice::make,
    },
    Generator {
        name: "mount",
        default_size: 6,
        min_size: 0,
        max_size: 10,
        about: "SPD fractal mountain: 2*4^size triangles and 4 glass spheres",
        make: spd::mount::make,
    },
    Generator {
        name: "rings",
        default_size: 7,
        min_size: 0,
        max_size: 40,
        about: "SPD rings: pentagonal rings of spheres and cylinders",
        make: spd::rings::make,
    },
    Generator {
        name: "sombrero",
        default_size: 1,
        min_size: 0,
        max_size: 6,
        about: "SPD sombrero: a height field of 2*(2^(size+4)-1)^2 triangles",
        make: spd::sombrero::make,
    },
    Generator {
        name: "teapot",
        default_size: 6,
        min_size: 0,
        max_size: 128,
        about:
            "SPD teapot: Bezier patches tessellated to 64*size^2-8*size triangles on a checkerboard",
        make: spd::teapot::make,
    },
    Generator {
        name: "tetra",
        default_size: 6,
        min_size: 0,
        max_size: 12,
        about: "SPD tetra: recursive tetrahedron, 4^size triangles",
        make: spd::tetra::make,
    },
    Generator {
        name: "tree",
        default_size: 11,
        min_size: 0,
        max_size: 18,
        about: "SPD tree: a branching tree of 2^(size+1)-1 cones and spheres",
        make: spd::tree::make,
    },
    Generator {
        name: "icosphere",
        default_size: 4,
        min_size: 0,
        max_size: 9,
        about: "a closed unit sphere: an icosahedron subdivided size times, 20*4^size triangles",
        make: soup::icosphere,
    },
    Generator {
        name: "soup",
        default_size: 10_000,
        min_size: 0,
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
        /// The smallest accepted.
        min: u32,
        /// The largest accepted.
        max: u32,
    },
    /// A file that could not be used as a whole (unreadable, or an OBJ without faces).
    File {
        /// The file.
        path: PathBuf,
        /// What went wrong.
        message: String,
    },
    /// A file holding more primitives than [`LoadOptions::max_primitives`] allows, found at
    /// `line` before the rest was read.
    TooLarge {
        /// The file.
        path: PathBuf,
        /// The line where the count passed the limit.
        line: usize,
        /// The limit.
        limit: u64,
    },
    /// A file whose load would pass [`LoadOptions::max_primitives`] or
    /// [`LoadOptions::max_bytes`], refused at `item` before the allocation that would pass it.
    ///
    /// ```
    /// use quiver_scenes::scene::{ply, LoadOptions, SceneError};
    /// let head = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n\
    ///             property float y\nproperty float z\nelement face 1\n\
    ///             property list uchar int vertex_indices\nend_header\n\
    ///             0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
    /// let none = LoadOptions::default().max_primitives(0);
    /// let e = ply::parse_with(head.as_bytes(), "t.ply", &none).unwrap_err();
    /// assert!(matches!(e, SceneError::OverBudget { needs: 1, limit: 0, .. }));
    /// assert_eq!(e.to_string(), "t.ply: face 0 (line 13): needs 1 primitives, more than the \
    ///     0 this load allows (LoadOptions::max_primitives)");
    /// ```
    OverBudget {
        /// The file.
        path: PathBuf,
        /// Where the load stopped: `element vertex (line 3)`, `nodes[4]/meshes[0]/1`, ...
        item: String,
        /// What the load would hold with the item: primitives or bytes.
        needs: u64,
        /// The limit it would pass.
        limit: u64,
        /// Which limit.
        unit: Budgeted,
    },
    /// A fault at one line of a scene file (NFF, OBJ, a PLY header or ASCII body, glTF JSON);
    /// shown as `file:line: message`.
    Parse {
        /// The file.
        path: PathBuf,
        /// The line, from 1.
        line: usize,
        /// What was found and what was expected there.
        message: String,
    },
    /// A fault in a part of a file that has no line: an element of a binary PLY body, a glTF
    /// accessor, buffer view, node or mesh; shown as `file: item: message`.
    ///
    /// ```
    /// use quiver_scenes::scene::{ply, SceneError};
    /// // A header of 178 bytes claiming four billion vertices, then 16 bytes.
    /// let head = "ply\nformat binary_little_endian 1.0\nelement vertex 4000000000\n\
    ///             property float x\nproperty float y\nproperty float z\nelement face 0\n\
    ///             property list uchar int vertex_indices\nend_header\n";
    /// let mut file = head.as_bytes().to_vec();
    /// file.extend_from_slice(&[0; 16]);
    /// let e = ply::parse(&file, "short.ply").unwrap_err();
    /// assert!(matches!(e, SceneError::Item { .. }));
    /// assert_eq!(e.to_string(), "short.ply: element vertex (byte 178): 4000000000 instances \
    ///     of at least 12 bytes each do not fit in the 16 bytes left in the file");
    /// ```
    Item {
        /// The file.
        path: PathBuf,
        /// Which part: `vertex 12, property y (byte 200)`, `accessors[3]`, ...
        item: String,
        /// What was found and what was expected there.
        message: String,
    },
}

impl SceneError {
    /// The line a [`SceneError::Parse`] points at.
    ///
    /// ```
    /// use quiver_scenes::scene::obj;
    /// let e = obj::parse("v 0 0 0\nv 1 0 0\nf 1 2\n", "two.obj").unwrap_err();
    /// assert_eq!(e.line(), Some(3));
    /// assert_eq!(e.to_string(), "two.obj:3: face needs at least 3 vertices, got 2");
    /// ```
    pub fn line(&self) -> Option<usize> {
        match self {
            SceneError::Parse { line, .. } => Some(*line),
            _ => None,
        }
    }
}

impl fmt::Display for SceneError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SceneError::Unknown(s) => {
                let names: Vec<_> = GENERATORS.iter().map(|g| g.name).collect();
                write!(
                    f,
                    "unknown scene '{s}': expected a generator name with an optional size ({}), \
                     or a .nff, .obj, .ply, .ply.gz, .gltf or .glb file",
                    names.join(", ")
                )
            }
            SceneError::Size {
                name,
                size,
                min,
                max,
            } => {
                write!(
                    f,
                    "scene '{name}': size '{size}' must be a number from {min} to {max}"
                )
            }
            SceneError::File { path, message } => write!(f, "{}: {message}", path.display()),
            SceneError::TooLarge { path, line, limit } => write!(
                f,
                "{}:{line}: more than {limit} primitives, the most this load allows \
                 (LoadOptions::max_primitives)",
                path.display()
            ),
            SceneError::OverBudget {
                path,
                item,
                needs,
                limit,
                unit,
            } => match unit {
                Budgeted::Primitives => write!(
                    f,
                    "{}: {item}: needs {needs} primitives, more than the {limit} this load \
                     allows (LoadOptions::max_primitives)",
                    path.display()
                ),
                Budgeted::Bytes => write!(
                    f,
                    "{}: {item}: needs about {needs} bytes of memory, more than the {limit} \
                     this load may use (LoadOptions::max_bytes)",
                    path.display()
                ),
            },
            SceneError::Parse {
                path,
                line,
                message,
            } => write!(f, "{}:{line}: {message}", path.display()),
            SceneError::Item {
                path,
                item,
                message,
            } => write!(f, "{}: {item}: {message}", path.display()),
        }
    }
}

impl std::error::Error for SceneError {}

/// What a file loader does with a NaN or infinite number.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum NonFinite {
    /// Fail with the number's file and line (the default).
    #[default]
    Error,
    /// Leave out the primitive or light that holds it and count it in [`LoadReport`]. Numbers
    /// no primitive or light owns (the view, background, materials) are errors still.
    Drop,
}

/// How files are read: [`Scene::load_with`], [`nff::parse_with`], [`obj::parse_with`].
///
/// ```
/// use quiver_scenes::scene::{LoadOptions, NonFinite, MAX_FILE_BYTES};
/// assert_eq!(LoadOptions::default().non_finite, NonFinite::Error);
/// assert_eq!(LoadOptions::default().max_file_bytes, MAX_FILE_BYTES);
/// let lax = LoadOptions::default().non_finite(NonFinite::Drop).max_file_bytes(1 << 20);
/// assert_eq!((lax.non_finite, lax.max_file_bytes), (NonFinite::Drop, 1 << 20));
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LoadOptions {
    /// What a NaN or infinite number does.
    pub non_finite: NonFinite,
    /// The largest file read ([`read_bytes`]); [`MAX_FILE_BYTES`] by default.
    pub max_file_bytes: u64,
    /// The most primitives a file may hold, counted as they trace (a sphere, cone or
    /// triangle is one, a polygon or face of `n` vertices `n - 2`); a file with more fails
    /// with [`SceneError::TooLarge`] as soon as the count passes it, before the rest is
    /// stored. Unlimited by default; a caller with a memory budget sets it. Every reader
    /// counts glTF's placements too: a mesh placed by `k` nodes is `k` times its triangles.
    pub max_primitives: u64,
    /// The most memory a load may hold at once, in bytes: the file's bytes (inflated, for
    /// `.ply.gz`), the external glTF buffers, the reader's vertex and index lists, the
    /// triangles and objects it makes. Every reader checks it from the size it is about to
    /// allocate, before allocating, and fails with [`SceneError::OverBudget`] naming the item.
    /// Unlimited by default; a caller with a memory budget sets it.
    pub max_bytes: u64,
    /// Whether a file may name files outside its own folder (a glTF buffer URI such as
    /// `../x.bin`, `/abs/x.bin` or a symbolic link that leads out). Off by default: a renderer
    /// that loads user-supplied files must not read the machine's other files.
    pub outside_files: bool,
}

impl Default for LoadOptions {
    fn default() -> Self {
        LoadOptions {
            non_finite: NonFinite::default(),
            max_file_bytes: MAX_FILE_BYTES,
            max_primitives: u64::MAX,
            max_bytes: u64::MAX,
            outside_files: false,
        }
    }
}

impl LoadOptions {
    /// Sets [`LoadOptions::non_finite`].
    pub fn non_finite(mut self, n: NonFinite) -> Self {
        self.non_finite = n;
        self
    }

    /// Sets [`LoadOptions::max_file_bytes`].
    pub fn max_file_bytes(mut self, bytes: u64) -> Self {
        self.max_file_bytes = bytes;
        self
    }

    /// Sets [`LoadOptions::max_primitives`].
    ///
    /// ```
    /// use quiver_scenes::scene::{obj, LoadOptions};
    /// let quad = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n";
    /// let two = LoadOptions::default().max_primitives(2);
    /// assert!(obj::parse_with(quad, "q.obj", &two).is_ok());
    /// let one = LoadOptions::default().max_primitives(1);
    /// let e = obj::parse_with(quad, "q.obj", &one).unwrap_err().to_string();
    /// assert!(e.starts_with("q.obj:5: more than 1 primitives"), "{e}");
    /// ```
    pub fn max_primitives(mut self, count: u64) -> Self {
        self.max_primitives = count;
        self
    }

    /// Sets [`LoadOptions::max_bytes`].
    ///
    /// ```
    /// use quiver_scenes::scene::{obj, LoadOptions, SceneError};
    /// let quad = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n";
    /// assert!(obj::parse_with(quad, "q.obj", &LoadOptions::default().max_bytes(1 << 20)).is_ok());
    /// let e = obj::parse_with(quad, "q.obj", &LoadOptions::default().max_bytes(100)).unwrap_err();
    /// assert!(matches!(e, SceneError::OverBudget { limit: 100, .. }), "{e}");
    /// ```
    pub fn max_bytes(mut self, bytes: u64) -> Self {
        self.max_bytes = bytes;
        self
    }

    /// Sets [`LoadOptions::outside_files`].
    pub fn outside_files(mut self, allowed: bool) -> Self {
        self.outside_files = allowed;
        self
    }
}

/// Which limit of [`LoadOptions`] a [`SceneError::OverBudget`] load would pass.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Budgeted {
    /// [`LoadOptions::max_primitives`].
    Primitives,
    /// [`LoadOptions::max_bytes`].
    Bytes,
}

/// Bytes one primitive read from a mesh file costs beside its triangle: the scene object
/// [`mesh_scene`] makes of it (alive with the triangles while the scene is made).
pub(crate) const OBJECT_BYTES: u64 = std::mem::size_of::<Object>() as u64;

/// What a load holds so far against [`LoadOptions::max_bytes`] and
/// [`LoadOptions::max_primitives`]: each reader charges a size before allocating it.
pub(crate) struct Budget<'p> {
    path: &'p Path,
    max_bytes: u64,
    max_prims: u64,
    bytes: u64,
    prims: u64,
}

impl<'p> Budget<'p> {
    pub(crate) fn new(path: &'p Path, opts: &LoadOptions) -> Budget<'p> {
        Budget {
            path,
            max_bytes: opts.max_bytes,
            max_prims: opts.max_primitives,
            bytes: 0,
            prims: 0,
        }
    }

    fn over(&self, item: String, needs: u64, limit: u64, unit: Budgeted) -> SceneError {
        SceneError::OverBudget {
            path: self.path.into(),
            item,
            needs,
            limit,
            unit,
        }
    }

    /// Charges `n` bytes about to be allocated for `item`.
    pub(crate) fn bytes(
        &mut self,
        n: u64,
        item: impl FnOnce() -> String,
    ) -> Result<(), SceneError> {
        let total = self.bytes.saturating_add(n);
        if total > self.max_bytes {
            return Err(self.over(item(), total, self.max_bytes, Budgeted::Bytes));
        }
        self.bytes = total;
        Ok(())
    }

    /// Gives back `n` bytes freed.
    pub(crate) fn release(&mut self, n: u64) {
        self.bytes = self.bytes.saturating_sub(n);
    }

    /// Charges `n` primitives about to be stored for `item`, and the objects they become
    /// ([`OBJECT_BYTES`]; the caller charges their triangles where it stores them).
    pub(crate) fn prims(&mut self, n: u64, item: impl Fn() -> String) -> Result<(), SceneError> {
        let total = self.prims.saturating_add(n);
        if total > self.max_prims {
            return Err(self.over(item(), total, self.max_prims, Budgeted::Primitives));
        }
        self.bytes(n.saturating_mul(OBJECT_BYTES), item)?;
        self.prims = total;
        Ok(())
    }

    /// Room in `v` for `extra` more items, charged as the capacity it adds (doubling, as a
    /// push would, so a reader pushing one at a time is charged what it holds).
    pub(crate) fn grow<T>(
        &mut self,
        v: &mut Vec<T>,
        extra: usize,
        item: impl FnOnce() -> String,
    ) -> Result<(), SceneError> {
        let need = v.len().saturating_add(extra);
        if need <= v.capacity() {
            return Ok(());
        }
        let cap = need.max(v.capacity().saturating_mul(2));
        let size = std::mem::size_of::<T>() as u64;
        self.bytes((cap - v.capacity()) as u64 * size, item)?;
        v.reserve_exact(cap - v.len());
        Ok(())
    }
}

/// `text` without a leading UTF-8 byte order mark, which some editors write and which would
/// otherwise be read as part of the first word.
pub(crate) fn strip_bom(text: &str) -> &str {
    text.strip_prefix('\u{feff}').unwrap_or(text)
}

/// What a load left out under [`NonFinite::Drop`]; empty otherwise.
///
/// ```
/// use quiver_scenes::scene::{obj, LoadOptions, NonFinite};
/// let text = "v 0 0 0\nv 1 0 0\nv 0 inf 0\nv 0 1 0\nf 1 2 3\nf 1 2 4\n";
/// let lax = LoadOptions::default().non_finite(NonFinite::Drop);
/// let (scene, report) = obj::parse_with(text, "m.obj", &lax).unwrap();
/// assert_eq!((scene.objects.len(), report.dropped_primitives), (1, 1));
/// assert_eq!(report.reasons, ["m.obj:5: face dropped: its vertex 3 (line 3) is not finite"]);
/// assert_eq!(report.to_string(), "dropped 1 primitive with non-finite numbers \
///     (m.obj:5: face dropped: its vertex 3 (line 3) is not finite)");
/// ```
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct LoadReport {
    /// Primitives left out, counted as [`LoadOptions::max_primitives`] counts them: a
    /// sphere, cone or triangle is one, a polygon or face of `n` vertices `n - 2` (its
    /// triangles). One reason is noted per face or shape, so a dropped quad counts 2.
    pub dropped_primitives: usize,
    /// NFF lights left out.
    pub dropped_lights: usize,
    /// Why, as `file:line: ...`, for the first [`LoadReport::REASONS_KEPT`] drops in file
    /// order.
    pub reasons: Vec<String>,
    /// How many reasons there were in all (one a dropped face, shape or light), of which
    /// [`LoadReport::reasons`] keeps the first.
    pub reasons_total: usize,
}

impl LoadReport {
    /// How many reasons [`LoadReport::reasons`] keeps: enough to find the fault, few enough
    /// for a file with millions of NaNs.
    pub const REASONS_KEPT: usize = 8;

    /// True when nothing was dropped.
    pub fn is_empty(&self) -> bool {
        self.dropped_primitives == 0 && self.dropped_lights == 0
    }

    fn note(&mut self, reason: String) {
        self.reasons_total += 1;
        if self.reasons.len() < Self::REASONS_KEPT {
            self.reasons.push(reason);
        }
    }

    pub(crate) fn drop_primitive(&mut self, reason: String) {
        self.drop_primitives(1, reason);
    }

    /// `n` primitives left out for one reason (a face of `n + 2` corners).
    pub(crate) fn drop_primitives(&mut self, n: usize, reason: String) {
        self.dropped_primitives += n;
        self.note(reason);
    }

    pub(crate) fn drop_light(&mut self, reason: String) {
        self.dropped_lights += 1;
        self.note(reason);
    }
}

impl fmt::Display for LoadReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let count = |n: usize, what: &str| format!("{n} {what}{}", if n == 1 { "" } else { "s" });
        let mut parts = Vec::new();
        if self.dropped_primitives > 0 {
            parts.push(count(self.dropped_primitives, "primitive"));
        }
        if self.dropped_lights > 0 {
            parts.push(count(self.dropped_lights, "light"));
        }
        if parts.is_empty() {
            return write!(f, "nothing dropped");
        }
        write!(
            f,
            "dropped {} with non-finite numbers ({}",
            parts.join(" and "),
            self.reasons.join("; ")
        )?;
        if self.reasons_total > self.reasons.len() {
            write!(f, "; {} more", self.reasons_total - self.reasons.len())?;
        }
        write!(f, ")")
    }
}

/// One number read from a file: the value, or a message saying what was expected. NaN and
/// infinity are returned as values for the caller to fail on or drop ([`non_finite`]).
pub(crate) fn number(tok: &str, what: &str) -> Result<f32, String> {
    tok.parse::<f32>()
        .map_err(|_| format!("expected a number for {what}, got '{tok}'"))
}

/// The message for a number that parsed but is not finite (`1e39` is infinite in f32).
pub(crate) fn non_finite(what: &str, tok: &str, x: f32) -> String {
    let kind = if x.is_nan() { "NaN" } else { "infinite" };
    format!("{what} is {kind} ('{tok}')")
}

/// At most 40 characters of `s`, for messages quoting what may be binary garbage.
pub(crate) fn clip(s: &str) -> String {
    let mut out: String = s.chars().take(40).collect();
    if s.chars().count() > 40 {
        out.push_str("...");
    }
    out
}

/// Most bytes a `.gz` file may inflate to: far above any mesh quiver can hold, low enough that
/// a small hostile file cannot exhaust memory.
pub const MAX_INFLATED_BYTES: u64 = 1 << 32;

/// A gzip file's inflated bytes, at most [`MAX_INFLATED_BYTES`], at most
/// [`LoadOptions::max_file_bytes`], and within [`LoadOptions::max_bytes`] with the packed
/// bytes it is inflated from: the inflated size is checked as it is reached, never guessed
/// from the packed one.
fn read_gzip(path: &Path, opts: &LoadOptions) -> Result<Vec<u8>, SceneError> {
    use std::io::Read;
    let packed = read_within(path, opts)?;
    let over = |needs: u64| SceneError::OverBudget {
        path: path.into(),
        item: "the inflated data (gzip)".into(),
        needs,
        limit: opts.max_bytes,
        unit: Budgeted::Bytes,
    };
    let room = opts.max_bytes.saturating_sub(packed.len() as u64);
    let cap = MAX_INFLATED_BYTES.min(opts.max_file_bytes);
    let fail = |message: String| SceneError::File {
        path: path.into(),
        message,
    };
    let mut out = Vec::new();
    let mut inflate = flate2::read::MultiGzDecoder::new(packed.as_slice()).take(cap.min(room) + 1);
    // In steps, so the vector never holds (or doubles to) more than the budget allows.
    let mut chunk = vec![0u8; 1 << 16];
    loop {
        let n = inflate
            .read(&mut chunk)
            .map_err(|e| fail(format!("cannot inflate (gzip): {e}")))?;
        if n == 0 {
            break;
        }
        let len = out.len() as u64 + n as u64;
        if len > cap {
            return Err(fail(format!("inflates to more than {cap} bytes (gzip)")));
        }
        if len > room {
            return Err(over(packed.len() as u64 + len));
        }
        if out.len() + n > out.capacity() {
            // Doubling, but never past what the budget and the cap leave.
            let want = (out.capacity() * 2).max(out.len() + n).max(1 << 16) as u64;
            out.reserve_exact(want.min(room).min(cap) as usize - out.len());
        }
        out.extend_from_slice(&chunk[..n]);
    }
    Ok(out)
}

/// A file's bytes for a reader ([`read_bytes`]), refused before reading when the file alone
/// passes [`LoadOptions::max_bytes`].
fn read_within(path: &Path, opts: &LoadOptions) -> Result<Vec<u8>, SceneError> {
    if let Ok(meta) = std::fs::metadata(path) {
        if meta.is_file() && meta.len() > opts.max_bytes && meta.len() <= opts.max_file_bytes {
            return Err(SceneError::OverBudget {
                path: path.into(),
                item: "the file".into(),
                needs: meta.len(),
                limit: opts.max_bytes,
                unit: Budgeted::Bytes,
            });
        }
    }
    read_bytes(path, opts.max_file_bytes.min(opts.max_bytes))
}

/// A scene of the triangles read from a mesh file (OBJ, PLY, glTF): the default material, a
/// camera that frames the mesh from above one corner, one light beyond the far corner, a grey
/// background, and the file's groups.
pub(crate) fn mesh_scene(
    path: &Path,
    tris: Vec<Triangle>,
    groups: Vec<Group>,
) -> Result<Scene, SceneError> {
    let bounds = tris.iter().fold(Aabb::EMPTY, |b, t| b.union(&t.bounds()));
    let camera = Camera::framing(&bounds).map_err(|e| SceneError::File {
        path: path.into(),
        message: format!("mesh files bring no view, and {e}"),
    })?;
    // Beyond the far corner; from the eye when the mesh is empty or too large for f32.
    let light = Some(bounds.max + bounds.extent())
        .filter(|l| !bounds.is_empty() && l.is_finite())
        .unwrap_or(camera.from);
    let mut scene = Scene::from_triangles(
        path.display().to_string(),
        tris,
        camera,
        vec![light],
        Vec3A::splat(0.2),
    );
    scene.groups = groups;
    Ok(scene)
}

/// Collects [`Group`]s as a reader emits objects: `start` opens a group at the current
/// object count, and a group that received no object is left out.
#[derive(Default)]
pub(crate) struct Groups {
    done: Vec<Group>,
    open: Option<(String, u32)>,
}

impl Groups {
    /// Closes the open group at `objects` and opens `name` there.
    pub(crate) fn start(&mut self, name: String, objects: usize) {
        self.close(objects);
        self.open = Some((name, objects as u32));
    }

    /// Closes the open group at `objects`, keeping it if it is not empty.
    pub(crate) fn close(&mut self, objects: usize) {
        if let Some((name, start)) = self.open.take() {
            if objects as u32 > start {
                self.done.push(Group {
                    name,
                    objects: start..objects as u32,
                });
            }
        }
    }

    /// Every group, the open one closed at `objects`.
    pub(crate) fn finish(mut self, objects: usize) -> Vec<Group> {
        self.close(objects);
        self.done
    }
}

impl Scene {
    /// Loads a scene by name (`tetra6`, `soup1000`) or from an `.nff` or `.obj` path,
    /// strictly: any fault in a file, a NaN or infinite number included, is an error naming
    /// the file and line. [`Scene::load_with`] can drop non-finite primitives instead.
    ///
    /// ```
    /// use quiver_scenes::Scene;
    /// let e = Scene::load("/nonexistent/x.obj").unwrap_err().to_string();
    /// assert!(e.starts_with("/nonexistent/x.obj: cannot read: "), "{e}");
    /// ```
    pub fn load(spec: &str) -> Result<Scene, SceneError> {
        Scene::load_with(spec, &LoadOptions::default()).map(|(scene, _)| scene)
    }

    /// [`Scene::load`] with options, and what they made the loader leave out. Generators
    /// always report nothing dropped.
    ///
    /// ```
    /// use quiver_scenes::scene::{LoadOptions, NonFinite, Scene};
    /// let lax = LoadOptions::default().non_finite(NonFinite::Drop);
    /// let (scene, report) = Scene::load_with("tetra1", &lax).unwrap();
    /// assert_eq!((scene.objects.len(), report.is_empty()), (4, true));
    /// ```
    pub fn load_with(spec: &str, opts: &LoadOptions) -> Result<(Scene, LoadReport), SceneError> {
        let lower = spec.to_ascii_lowercase();
        let path = Path::new(spec);
        let text = |bytes: Vec<u8>| {
            String::from_utf8(bytes)
                .unwrap_or_else(|e| String::from_utf8_lossy(e.as_bytes()).into_owned())
        };
        if lower.ends_with(".ply.gz") {
            return ply::parse_with(&read_gzip(path, opts)?, spec, opts);
        }
        if lower.ends_with(".ply") {
            return ply::parse_with(&read_within(path, opts)?, spec, opts);
        }
        if lower.ends_with(".gltf") || lower.ends_with(".glb") {
            return gltf::parse_with(&read_within(path, opts)?, spec, opts);
        }
        if lower.ends_with(".obj") {
            return obj::parse_with(&text(read_within(path, opts)?), spec, opts);
        }
        if lower.ends_with(".nff") {
            return nff::parse_with(&text(read_within(path, opts)?), spec, opts);
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
                .filter(|s| (gen.min_size..=gen.max_size).contains(s))
                .ok_or_else(|| SceneError::Size {
                    name: name.into(),
                    size: size.into(),
                    min: gen.min_size,
                    max: gen.max_size,
                })?
        };
        Ok(((gen.make)(size), LoadReport::default()))
    }

    /// Bounds of all finite objects.
    pub fn bounds(&self) -> Aabb {
        let (prims, _) = self.prims();
        prims
            .iter()
            .map(|p| p.bounds())
            .filter(|b| b.is_finite())
            .fold(Aabb::EMPTY, |a, b| a.union(&b))
    }

    /// A scene of triangles with one default material (soups, meshes).
    pub fn from_triangles(
        name: String,
        tris: Vec<Triangle>,
        camera: Camera,
        lights: Vec<Vec3A>,
        background: Vec3A,
    ) -> Scene {
        Scene {
            name,
            objects: tris
                .into_iter()
                .map(|t| Object {
                    shape: Shape::Triangle(t),
                    material: 0,
                })
                .collect(),
            materials: vec![Material::DEFAULT],
            camera,
            lights: lights
                .into_iter()
                .map(|pos| Light {
                    pos,
                    color: Vec3A::ONE,
                })
                .collect(),
            background,
            hither: 1e-3,
            resolution: [512, 512],
            groups: Vec::new(),
        }
    }

    /// The primitives a curve-mode BVH holds, and for each the index of its object: spheres
    /// and cones stay analytic, a polygon is traced as its triangles ([`PolygonPiece`]: the
    /// polygon's normal, a watertight test) and stays one object for shading and counts, a
    /// patch becomes a fan of patch triangles.
    pub fn prims(&self) -> (Vec<Prim>, Vec<u32>) {
        let mut prims = Vec::with_capacity(self.objects.len());
        let mut owner = Vec::with_capacity(self.objects.len());
        for (i, o) in self.objects.iter().enumerate() {
            let before = prims.len();
            match &o.shape {
                Shape::Sphere(s) => prims.push(Prim::Sphere(*s)),
                Shape::Cone(c) => prims.push(Prim::Cone(*c)),
                Shape::Triangle(t) => prims.push(Prim::Triangle(*t)),
                // Traced as its triangles (see `PolygonPiece`), shaded as the polygon.
                Shape::Polygon(v) => {
                    let normal = Polygon::new(v.clone()).normal();
                    let mut tris = Vec::with_capacity(v.len());
                    tessellate::polygon_triangles(v, &mut tris);
                    prims.extend(
                        tris.into_iter()
                            .map(|tri| Prim::Piece(PolygonPiece { tri, normal })),
                    );
                }
                Shape::Patch { verts, normals } => {
                    for k in 1..verts.len().saturating_sub(1) {
                        prims.push(Prim::Patch(PatchTriangle {
                            tri: Triangle::new(verts[0], verts[k], verts[k + 1]),
                            normals: [normals[0], normals[k], normals[k + 1]],
                        }));
                    }
                }
            }
            owner.resize(owner.len() + prims.len() - before, i as u32);
        }
        (prims, owner)
    }

    /// Every object as triangles: polygons triangulated (concave ones by ear clipping),
    /// patches as fans, spheres and cones tessellated as the SPD's patch mode does at its
    /// default resolution. The all-triangle fast path's input.
    pub fn triangles(&self) -> Vec<Triangle> {
        self.triangles_with_owner().0
    }

    /// [`Scene::triangles`] and, for each triangle, the index of its object.
    pub fn triangles_with_owner(&self) -> (Vec<Triangle>, Vec<u32>) {
        let (tris, owner, _) = self.triangles_with_normals();
        (tris, owner)
    }

    /// [`Scene::triangles_with_owner`] plus, per triangle, the vertex normals of triangles cut
    /// from patches (or from spheres and cones), `None` for flat ones.
    pub fn triangles_with_normals(&self) -> (Vec<Triangle>, Vec<u32>, Vec<Option<[Vec3A; 3]>>) {
        let mut out = Vec::with_capacity(self.objects.len());
        let mut owner = Vec::with_capacity(self.objects.len());
        let mut normals = Vec::with_capacity(self.objects.len());
        for (i, o) in self.objects.iter().enumerate() {
            tessellate::shape_triangles(&o.shape, &mut out, &mut normals);
            owner.resize(out.len(), i as u32);
        }
        (out, owner, normals)
    }

    /// The scene in the SPD's patch mode: every sphere and cone replaced by the polygonal
    /// patches [`tessellate`] makes of it at `resolution`; polygons and patches unchanged.
    pub fn into_patches(mut self, resolution: u32) -> Scene {
        let mut objects = Vec::with_capacity(self.objects.len());
        // Where each old object starts among the new ones (and the end), to move the groups.
        let mut starts = Vec::with_capacity(self.objects.len() + 1);
        for o in self.objects {
            starts.push(objects.len() as u32);
            let patches = match &o.shape {
                Shape::Sphere(s) => tessellate::sphere_patches(s, resolution),
                Shape::Cone(c) => tessellate::cone_patches(c, resolution),
                _ => {
                    objects.push(o);
                    continue;
                }
            };
            objects.extend(patches.into_iter().map(|(verts, normals)| Object {
                shape: Shape::Patch { verts, normals },
                material: o.material,
            }));
        }
        starts.push(objects.len() as u32);
        for g in &mut self.groups {
            g.objects = starts[g.objects.start as usize]..starts[g.objects.end as usize];
        }
        self.objects = objects;
        self
    }

    /// Materials whose surfaces are two-sided: those of polygonal patches (the SPD asks for a
    /// two-sided teapot, whose lid lets the viewer see back faces; patches elsewhere are
    /// closed surfaces where it makes no difference).
    pub fn two_sided_materials(&self) -> Vec<u32> {
        let mut m: Vec<u32> = self
            .objects
            .iter()
            .filter(|o| matches!(o.shape, Shape::Patch { .. }))
            .map(|o| o.material)
            .collect();
        m.sort_unstable();
        m.dedup();
        m
    }

    /// The materials [`Scene::two_sided_materials`] gives for this scene in patch mode, without
    /// tessellating it: those of patches, spheres and cones (which patch mode turns into
    /// patches).
    ///
    /// ```
    /// use quiver_scenes::Scene;
    /// let balls = Scene::load("balls1").unwrap();
    /// assert_eq!(balls.patch_mode_two_sided_materials(), balls.clone().into_patches(2).two_sided_materials());
    /// ```
    pub fn patch_mode_two_sided_materials(&self) -> Vec<u32> {
        let mut m: Vec<u32> = self
            .objects
            .iter()
            .filter(|o| {
                matches!(
                    o.shape,
                    Shape::Patch { .. } | Shape::Sphere(_) | Shape::Cone(_)
                )
            })
            .map(|o| o.material)
            .collect();
        m.sort_unstable();
        m.dedup();
        m
    }

    /// True when every object is a triangle (no analytic shape, polygon or patch).
    pub fn is_all_triangles(&self) -> bool {
        self.objects
            .iter()
            .all(|o| matches!(o.shape, Shape::Triangle(_)))
    }
}
