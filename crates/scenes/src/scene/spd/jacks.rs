//! SPD `jacks` (Alexander Enzmann): a jack of three crossed cylinders capped by six spheres,
//! with a half-size copy in each of its eight octants, recursively. Size `n` gives
//! `(8^n - 1) / 7` jacks (one at size 0, as the C recursion writes its root regardless), each
//! 3 cylinders and 6 spheres. SPD default size 1.
//!
//! The placement goes through the SPD library's transform stack: 4×4 row-vector matrices
//! where each new operation is pre-multiplied, so it acts on the object first. Points are
//! transformed with the library's sums and radii scaled by the length of the matrix's first
//! row (the library assumes uniform scaling).

use super::mat::{apply, mul, rotate_x, rotate_y, Mat, IDENTITY};
use super::Spd;
use crate::scene::Scene;
use glam::DVec3;
use std::f64::consts::PI;

/// "DarkPurple".
const BACKGROUND: [f64; 3] = [0.2, 0.05, 0.2];
/// "Pink".
const PINK: [f64; 3] = [0.737, 0.561, 0.561];

pub(crate) fn make(size: u32) -> Scene {
    let mut spd = Spd::new(format!("jacks{size}"), BACKGROUND);
    spd.view(
        DVec3::new(0.0, 0.0, -8.0),
        DVec3::ZERO,
        DVec3::Y,
        25.0,
        0.001,
        256,
    );
    spd.light(DVec3::new(-10.0, 3.0, -20.0));

    // Tilt the whole pile: about X by -30°, then (pre-multiplied, so applied first) about Y
    // by -20°.
    let root = mul(&rotate_x(-30.0 * PI / 180.0), &IDENTITY);
    let root = mul(&rotate_y(-20.0 * PI / 180.0), &root);

    spd.material(PINK, 0.7, 0.7, 20.0, 0.0, 1.0);
    jacks(&mut spd, 1, size, &root);
    spd.finish()
}

/// Writes the jack placed by `m`, then, below `max_depth`, the eight half-size jacks centred
/// on the octant corners (±½, ±½, ±½) of its frame.
fn jacks(spd: &mut Spd, depth: u32, max_depth: u32, m: &Mat) {
    jack(spd, &mul(&scaling(0.75), m));
    if depth < max_depth {
        for i in [-0.5, 0.5] {
            for j in [-0.5, 0.5] {
                for k in [-0.5, 0.5] {
                    let child = mul(&translation(DVec3::new(i, j, k)), m);
                    let child = mul(&scaling(0.5), &child);
                    jacks(spd, depth + 1, max_depth, &child);
                }
            }
        }
    }
}

/// One jack in the frame `m`: cylinders of radius 0.1 along X, Y and Z from -1 to 1, then
/// spheres of radius 0.2 at +X, +Y, +Z, -X, -Y, -Z.
fn jack(spd: &mut Spd, m: &Mat) {
    let scale = row_length(m);
    for [a, b] in [
        [[-1.0, 0.0, 0.0], [1.0, 0.0, 0.0]],
        [[0.0, -1.0, 0.0], [0.0, 1.0, 0.0]],
        [[0.0, 0.0, -1.0], [0.0, 0.0, 1.0]],
    ] {
        let (base, apex) = (apply(DVec3::from(a), m), apply(DVec3::from(b), m));
        spd.cone(base, 0.1 * scale, apex, 0.1 * scale);
    }
    for end in [
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, 1.0],
        [-1.0, 0.0, 0.0],
        [0.0, -1.0, 0.0],
        [0.0, 0.0, -1.0],
    ] {
        spd.sphere(apply(DVec3::from(end), m), 0.2 * scale);
    }
}

/// |first row of the 3×3 part|: the x scale the library applies to radii.
fn row_length(m: &Mat) -> f64 {
    let r = m[0];
    (r[0] * r[0] + r[1] * r[1] + r[2] * r[2]).sqrt()
}

fn scaling(s: f64) -> Mat {
    let mut m = IDENTITY;
    m[0][0] = s;
    m[1][1] = s;
    m[2][2] = s;
    m
}

fn translation(t: DVec3) -> Mat {
    let mut m = IDENTITY;
    m[3][0] = t.x;
    m[3][1] = t.y;
    m[3][2] = t.z;
    m
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::spd::mat::testing::{close, close3, kinds};
    use crate::scene::Shape;

    #[test]
    fn counts_match_the_c_program() {
        for (size, spheres, cylinders) in [(0, 6, 3), (1, 6, 3), (2, 54, 27), (4, 3510, 1755)] {
            let s = make(size);
            assert_eq!(s.name, format!("jacks{size}"));
            assert_eq!(kinds(&s), [spheres, cylinders, 0, 0, 0], "size {size}");
        }
    }

    #[test]
    fn view_light_and_material() {
        let s = make(1);
        assert!(close3(s.camera.from, [0.0, 0.0, -8.0]));
        assert!(close3(s.camera.at, [0.0; 3]));
        assert!(close3(s.camera.up, [0.0, 1.0, 0.0]));
        assert_eq!((s.camera.angle, s.resolution), (25.0, [256, 256]));
        assert!(close(s.hither, 0.001));
        assert!(close3(s.background, [0.2, 0.05, 0.2]));
        assert_eq!(s.lights.len(), 1);
        assert!(close3(s.lights[0].pos, [-10.0, 3.0, -20.0]));
        assert_eq!(s.materials.len(), 1);
        let m = s.materials[0];
        assert!(close3(m.color, [0.737, 0.561, 0.561]));
        assert_eq!((m.kd, m.ks, m.t, m.ior), (0.7, 0.7, 0.0, 1.0));
        assert!(close(m.shine, 11.1434));
    }

    #[test]
    fn root_jack_matches_the_c_output() {
        // `jacks -s 1`, §4.9.
        let s = make(1);
        let Shape::Cone(c) = &s.objects[0].shape else {
            panic!("expected a cylinder")
        };
        assert!(close3(c.base, [-0.704769, -0.128258, -0.222149]));
        assert!(close3(c.apex, [0.704769, 0.128258, 0.222149]));
        assert!(close(c.base_radius, 0.075) && close(c.apex_radius, 0.075));
        let Shape::Cone(c) = &s.objects[1].shape else {
            panic!("expected a cylinder")
        };
        assert!(close3(c.base, [0.0, -0.649519, 0.375]));
        let Shape::Sphere(sp) = &s.objects[3].shape else {
            panic!("expected a sphere")
        };
        assert!(close3(sp.center, [0.704769, 0.128258, 0.222149]) && close(sp.radius, 0.15));
        let Shape::Sphere(sp) = &s.objects[8].shape else {
            panic!("expected a sphere")
        };
        assert!(close3(sp.center, [0.256515, -0.352385, -0.610348]));
    }

    #[test]
    fn children_are_half_size_in_the_octants() {
        let s = make(2);
        // The first child (octant -,-,-) follows the root's nine objects.
        let Shape::Cone(c) = &s.objects[9].shape else {
            panic!("expected a cylinder")
        };
        assert!(close(c.base_radius, 0.0375));
        let Shape::Sphere(sp) = &s.objects[12].shape else {
            panic!("expected a sphere")
        };
        assert!(close(sp.radius, 0.075));
        // Every child's centre is at distance |(½,½,½)| = √3/2 from the root's.
        for k in 0..8 {
            let Shape::Cone(c) = &s.objects[9 + 9 * k].shape else {
                panic!()
            };
            let centre = (c.base + c.apex) * 0.5;
            assert!(close(centre.length(), 3f64.sqrt() / 2.0), "{centre:?}");
        }
    }
}
