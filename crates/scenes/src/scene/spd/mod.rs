//! Eric Haines' Standard Procedural Databases, generated in Rust from the SPD's definitions
//! (erich666/StandardProceduralDatabases: geometry and constants of each generator, the
//! shared library's output rules). Every generator emits its scene in curve mode, in the SPD
//! program's object order; [`Scene::into_patches`] gives patch mode.
//!
//! Generator arithmetic is done in f64, as the C programs do, and rounded to f32 only when an
//! object is stored.

pub(crate) mod balls;
pub(crate) mod gears;
pub(crate) mod jacks;
pub(crate) mod lattice;
mod mat;
pub(crate) mod mount;
pub(crate) mod rings;
pub(crate) mod sombrero;
pub(crate) mod teapot;
pub(crate) mod tetra;
pub(crate) mod tree;

use super::{Camera, Census, Light, Material, Object, Scene, Shape};
use crate::primitive::{Cone, Sphere};
use glam::{DVec3, Vec3A};
use quiver_rt::Triangle;
use std::cell::RefCell;

/// The SPD's "UNC sky blue" background.
pub(crate) const SKY: [f64; 3] = [0.078, 0.361, 0.753];

/// Collects a generator's output the way the SPD library's `lib_output_*` calls do.
pub(crate) struct Spd {
    scene: Scene,
    current: Option<u32>,
}

fn v3(p: DVec3) -> Vec3A {
    Vec3A::new(p.x as f32, p.y as f32, p.z as f32)
}

impl Spd {
    /// A new scene with the given background colour (`lib_output_background_color`).
    pub fn new(name: String, background: [f64; 3]) -> Spd {
        Spd {
            scene: Scene {
                name,
                objects: Vec::new(),
                materials: Vec::new(),
                camera: Camera::new(Vec3A::ZERO, Vec3A::Z, Vec3A::Y, 45.0),
                lights: Vec::new(),
                background: v3(DVec3::from(background)),
                hither: 1.0,
                resolution: [512, 512],
                groups: Vec::new(),
            },
            current: None,
        }
    }

    /// `lib_output_viewpoint(from, at, up, angle, aspect 1, hither, res, res)`.
    pub fn view(&mut self, from: DVec3, at: DVec3, up: DVec3, angle: f64, hither: f64, res: u32) {
        self.scene.camera = Camera::new(v3(from), v3(at), v3(up), angle as f32);
        self.scene.hither = hither as f32;
        self.scene.resolution = [res, res];
    }

    /// `lib_output_light(pos)` (white; the SPD writes no light colours).
    pub fn light(&mut self, pos: DVec3) {
        self.scene.lights.push(Light {
            pos: v3(pos),
            color: Vec3A::ONE,
        });
    }

    /// `lib_output_color(rgb, ka, kd, ks, ks_spec, ang, kt, ior)`: sets the material of the
    /// objects that follow. `ang` is the highlight half-angle in degrees, turned into the Phong
    /// exponent the SPD writes; an `ior` below 1 (the SPD writes 0 for opaque surfaces) is 1.
    pub fn material(&mut self, rgb: [f64; 3], kd: f64, ks: f64, ang: f64, kt: f64, ior: f64) {
        let m = Material {
            color: v3(DVec3::from(rgb)),
            kd: kd as f32,
            ks: ks as f32,
            shine: shine(ang) as f32,
            t: kt as f32,
            ior: ior.max(1.0) as f32,
        };
        let i = match self.scene.materials.iter().position(|x| *x == m) {
            Some(i) => i,
            None => {
                self.scene.materials.push(m);
                self.scene.materials.len() - 1
            }
        };
        self.current = Some(i as u32);
    }

    fn push(&mut self, shape: Shape) {
        let material = self
            .current
            .expect("an SPD generator sets a material before its objects");
        // Under `count`, the object is counted and not kept.
        let counted = COUNTING.with(|c| c.borrow_mut().as_mut().map(|n| n.add(&shape)));
        if counted.is_none() {
            self.scene.objects.push(Object { shape, material });
        }
    }

    /// `lib_output_sphere` in curve mode.
    pub fn sphere(&mut self, center: DVec3, radius: f64) {
        self.push(Shape::Sphere(Sphere {
            center: v3(center),
            radius: radius as f32,
        }));
    }

    /// `lib_output_cylcone` in curve mode (base and apex centres with their radii).
    pub fn cone(&mut self, base: DVec3, base_radius: f64, apex: DVec3, apex_radius: f64) {
        self.push(Shape::Cone(Cone {
            base: v3(base),
            base_radius: base_radius as f32,
            apex: v3(apex),
            apex_radius: apex_radius as f32,
        }));
    }

    /// `lib_output_polygon`: dropping vertices closer than 1e-6 to their successor, and the
    /// polygon if fewer than three remain.
    pub fn polygon(&mut self, verts: &[DVec3]) {
        let mut v: Vec<DVec3> = verts.to_vec();
        let mut i = 0;
        while i < v.len() && v.len() >= 3 {
            if (v[i] - v[(i + 1) % v.len()]).length() < 1e-6 {
                v.remove(i);
            } else {
                i += 1;
            }
        }
        match v.len() {
            0..=2 => {}
            3 => self.push(Shape::Triangle(Triangle::new(v3(v[0]), v3(v[1]), v3(v[2])))),
            _ => self.push(Shape::Polygon(v.into_iter().map(v3).collect())),
        }
    }

    /// `lib_output_polypatch`: a polygon with a normal per vertex.
    pub fn patch(&mut self, verts: &[DVec3], normals: &[DVec3]) {
        self.push(Shape::Patch {
            verts: verts.iter().copied().map(v3).collect(),
            normals: normals.iter().copied().map(v3).collect(),
        });
    }

    /// The finished scene.
    pub fn finish(self) -> Scene {
        self.scene
    }
}

thread_local! {
    /// Set while [`count`] runs a generator on this thread: objects go into it, not the scene.
    static COUNTING: RefCell<Option<Census>> = const { RefCell::new(None) };
}

/// The census of the scene `make(size)` would make, found by running it with every object
/// counted instead of stored (the SPD programs' arithmetic without their memory).
pub(crate) fn count(make: fn(u32) -> Scene, size: u32) -> Census {
    /// Ends counting on this thread however `make` returns (a panic included), so a later
    /// generator run keeps its objects.
    struct Reset;
    impl Drop for Reset {
        fn drop(&mut self) {
            COUNTING.with(|c| c.borrow_mut().take());
        }
    }
    let _reset = Reset;
    COUNTING.with(|c| *c.borrow_mut() = Some(Census::default()));
    drop(make(size));
    COUNTING.with(|c| c.borrow_mut().take()).unwrap_or_default()
}

/// The Phong exponent for a highlight that falls to 50% at `ang` degrees off the mirror
/// direction (`lib_output_color`).
pub(crate) fn shine(ang: f64) -> f64 {
    let a = std::f64::consts::PI * ang / 180.0;
    if a <= 0.0 {
        100000.0
    } else if a >= std::f64::consts::FRAC_PI_2 {
        1.0
    } else {
        0.5f64.ln() / a.cos().ln()
    }
}

/// Right-handed rotation of `p` about unit axis `u` by `a` radians (Rodrigues).
#[allow(unused_imports)]
pub(crate) use super::tessellate::rotate;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shine_matches_the_spd_table() {
        // §3.4 of the SPD spec: %g renderings of lib_output_color's exponents.
        for (ang, want) in [
            (6.7, 101.148),
            (10.0, 45.2776),
            (20.0, 11.1434),
            (30.0, 4.81884),
            (37.0, 3.0827),
            (40.0, 2.60078),
        ] {
            assert!(
                (shine(ang) - want).abs() < 5e-4 * want,
                "{ang}: {}",
                shine(ang)
            );
        }
        assert_eq!((shine(0.0), shine(90.0)), (100000.0, 1.0));
    }
}
