//! What a scene is made of, counted without making it: [`Census`] of a generator name and
//! size ([`Census::of_generator`], by running the generator with a counter in place of its
//! object list, so no object is ever stored), or of a loaded scene ([`Census::of`]). Callers
//! use it to estimate memory before the work: patch mode turns each sphere into `12 r²` and
//! each cone into `8 r` triangles ([`Census::patch_triangles`]), which is where scenes grow.
//!
//! ```
//! use quiver_scenes::scene::{Census, Scene};
//! let c = Census::of_generator("balls2").unwrap().unwrap();
//! assert_eq!((c.spheres, c.polygons, c.polygon_vertices), (91, 1, 4));
//! assert_eq!(c, Census::of(&Scene::load("balls2").unwrap()));
//! // balls6 in patch mode: 597,871 spheres of 192 triangles each.
//! let big = Census::of_generator("balls6").unwrap().unwrap();
//! assert_eq!(big.patch_triangles(4), 597_871 * 192 + 2);
//! assert!(Census::of_generator("teapot.obj").unwrap().is_none());
//! assert!(Census::of_generator("balls8").is_err());
//! ```

use super::{Scene, SceneError, Shape, GENERATORS};

/// How many objects of each kind a scene holds, and their vertices.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Census {
    /// NFF `s`.
    pub spheres: u64,
    /// NFF `c`.
    pub cones: u64,
    /// Three-vertex polygons.
    pub triangles: u64,
    /// Polygons of more than three vertices, and their vertices in all.
    pub polygons: u64,
    /// See [`Census::polygons`].
    pub polygon_vertices: u64,
    /// Polygonal patches (a normal per vertex), and their vertices in all.
    pub patches: u64,
    /// See [`Census::patches`].
    pub patch_vertices: u64,
}

impl Census {
    /// Counts `scene`'s objects.
    pub fn of(scene: &Scene) -> Census {
        let mut c = Census::default();
        for o in &scene.objects {
            c.add(&o.shape);
        }
        c
    }

    /// The census of the scene `spec` names if it is a generator name with an optional size
    /// (`tetra6`, `balls`), without making it; `Ok(None)` for anything else (a file, for the
    /// loader to read); the loader's own error for a generator size out of range. Costs the
    /// generator's arithmetic, not its memory: balls6 counts 597,872 objects in a few ms.
    pub fn of_generator(spec: &str) -> Result<Option<Census>, SceneError> {
        let split = spec
            .find(|c: char| c.is_ascii_digit())
            .unwrap_or(spec.len());
        let (name, size) = spec.split_at(split);
        let Some(gen) = GENERATORS.iter().find(|g| g.name == name) else {
            return Ok(None);
        };
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
        Ok(Some(match gen.name {
            // The two generators that are not SPD programs make triangles directly.
            "soup" => Census {
                triangles: size as u64,
                ..Census::default()
            },
            "icosphere" => Census {
                triangles: 20 << (2 * size as u64),
                ..Census::default()
            },
            _ => super::spd::count(gen.make, size),
        }))
    }

    /// Adds one object.
    pub fn add(&mut self, shape: &Shape) {
        match shape {
            Shape::Sphere(_) => self.spheres += 1,
            Shape::Cone(_) => self.cones += 1,
            Shape::Triangle(_) => self.triangles += 1,
            Shape::Polygon(v) => {
                self.polygons += 1;
                self.polygon_vertices += v.len() as u64;
            }
            Shape::Patch { verts, .. } => {
                self.patches += 1;
                self.patch_vertices += verts.len() as u64;
            }
        }
    }

    /// Objects in all.
    pub fn objects(&self) -> u64 {
        self.spheres + self.cones + self.triangles + self.polygons + self.patches
    }

    /// Triangles of the polygons and patches (a polygon of `n` vertices makes `n - 2`).
    pub fn polygon_triangles(&self) -> u64 {
        let pieces = |count: u64, verts: u64| verts.saturating_sub(2 * count);
        pieces(self.polygons, self.polygon_vertices) + pieces(self.patches, self.patch_vertices)
    }

    /// Primitives of a curve-mode build ([`Scene::prims`]): each sphere, cone and triangle,
    /// and the triangles of polygons and patches.
    pub fn curve_primitives(&self) -> u64 {
        self.spheres + self.cones + self.triangles + self.polygon_triangles()
    }

    /// Triangles of the scene in patch mode at `resolution` ([`Scene::into_patches`] and then
    /// [`Scene::triangles`]): `12 r²` per sphere, `8 r` per cone, the rest as in curve mode.
    pub fn patch_triangles(&self, resolution: u32) -> u64 {
        let r = resolution.max(1) as u64;
        self.spheres * 12 * r * r + self.cones * 8 * r + self.triangles + self.polygon_triangles()
    }

    /// Objects of the scene in patch mode: each sphere and cone becomes one three-vertex
    /// patch per triangle.
    pub fn patch_objects(&self, resolution: u32) -> u64 {
        let r = resolution.max(1) as u64;
        self.spheres * 12 * r * r
            + self.cones * 8 * r
            + self.triangles
            + self.polygons
            + self.patches
    }

    /// [`Census::patch_objects`] as a census: the spheres' and cones' patches counted as
    /// patches of three vertices.
    pub fn in_patch_mode(&self, resolution: u32) -> Census {
        let r = resolution.max(1) as u64;
        let new = self.spheres * 12 * r * r + self.cones * 8 * r;
        Census {
            spheres: 0,
            cones: 0,
            patches: self.patches + new,
            patch_vertices: self.patch_vertices + 3 * new,
            ..*self
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The counted census is the generated scene's, for every generator at its smallest sizes
    /// and a few larger ones; and a size out of range is the loader's own error.
    #[test]
    fn generator_census_equals_the_scene_it_makes() {
        for g in GENERATORS {
            let top = if g.name == "soup" {
                2000
            } else {
                g.max_size.min(g.min_size + 3)
            };
            let mut sizes: Vec<u32> = (g.min_size..=top.min(g.min_size + 3)).collect();
            sizes.extend([top, g.default_size.min(top)]);
            for size in sizes {
                let spec = format!("{}{size}", g.name);
                let counted = Census::of_generator(&spec).unwrap().unwrap();
                let scene = Scene::load(&spec).unwrap();
                assert_eq!(counted, Census::of(&scene), "{spec}");
                assert_eq!(
                    counted.curve_primitives(),
                    scene.prims().0.len() as u64,
                    "{spec}"
                );
                let patched = scene.clone().into_patches(3);
                assert_eq!(counted.in_patch_mode(3), Census::of(&patched), "{spec}");
                assert_eq!(
                    counted.patch_triangles(3),
                    patched.triangles().len() as u64,
                    "{spec}"
                );
                assert_eq!(
                    counted.patch_objects(3),
                    patched.objects.len() as u64,
                    "{spec}"
                );
            }
            let bare = Census::of_generator(g.name).unwrap().unwrap();
            let spec = format!("{}{}", g.name, g.default_size);
            assert_eq!(bare, Census::of_generator(&spec).unwrap().unwrap());
            let past = format!("{}{}", g.name, g.max_size as u64 + 1);
            assert_eq!(
                Census::of_generator(&past).unwrap_err().to_string(),
                Scene::load(&past).unwrap_err().to_string()
            );
        }
        // Counting leaves generation as it was.
        assert_eq!(Scene::load("tetra2").unwrap().objects.len(), 16);
    }
}
