//! SPD `rings`: a pyramid of objects, each made of six interlocking pentagonal rings of
//! cylinders with spheres at the joints, in front of a white wall. Size `n` gives `n` layers,
//! layer `d` holding `(d + 1)^2` objects of 30 cylinders and 30 spheres. SPD default size 7
//! (4200 of each).
//!
//! The ring points are rotated with the SPD library's row-vector matrices and the same sums,
//! so the f64 results follow the C program's rounding.

use super::mat::{apply, rotate_x, rotate_z};
use super::{Spd, SKY};
use crate::scene::Scene;
use glam::DVec3;
use std::f64::consts::PI;

/// Radius of every cylinder and sphere.
const RADIUS: f64 = 0.07412;

/// How much each layer spreads out relative to the one before (1: not at all).
const SPREAD_OUT: f64 = 1.0;

/// Ring colours: red, green, blue and their complements.
const COLORS: [[f64; 3]; 6] = [
    [1.0, 0.0, 0.0],
    [0.0, 1.0, 0.0],
    [0.0, 0.0, 1.0],
    [0.0, 1.0, 1.0],
    [1.0, 0.0, 1.0],
    [1.0, 1.0, 0.0],
];

pub(crate) fn make(size: u32) -> Scene {
    let spread = 1.0 / (PI / 8.0).sin();
    let (y_step, xz_step) = if SPREAD_OUT <= spread {
        (spread / SPREAD_OUT, 1.0)
    } else {
        (1.0, SPREAD_OUT / spread)
    };

    let mut spd = Spd::new(format!("rings{size}"), SKY);
    let from = DVec3::new(-1.0, -spread, 0.5);
    let at = DVec3::new(from.x, from.y + 1.0, from.z);
    spd.view(from, at, DVec3::Z, 45.0, 1.0, 512);
    spd.light(DVec3::new(3.0, -spread, 3.0));
    spd.light(DVec3::new(-4.0, -spread, 1.0));
    spd.light(DVec3::new(2.0, -spread, -4.0));

    // The wall behind the pyramid just fills the 45° view, plus 1%.
    spd.material([1.0; 3], 1.0, 0.0, 0.0, 0.0, 0.0);
    let wy = y_step * (f64::from(size) + 1.0);
    let wxz = 1.01 * (wy - from.y) * (PI / 8.0).tan();
    spd.polygon(&[
        DVec3::new(wxz + from.x, wy, wxz + from.z),
        DVec3::new(-wxz + from.x, wy, wxz + from.z),
        DVec3::new(-wxz + from.x, wy, -wxz + from.z),
        DVec3::new(wxz + from.x, wy, -wxz + from.z),
    ]);

    let points = ring_points(RADIUS);
    for layer in 0..i64::from(size) {
        let y = y_step * (layer + 1) as f64;
        for iz in 0..=layer {
            let z = xz_step * (2 * iz - layer) as f64;
            for ix in 0..=layer {
                let offset = DVec3::new(xz_step * (2 * ix - layer) as f64, y, z);
                object(&mut spd, &points, offset);
            }
        }
    }
    spd.finish()
}

/// One object: six rings of five cylinders, each cylinder running from a ring point back to
/// the previous point of its ring, and a sphere on every point.
fn object(spd: &mut Spd, points: &[DVec3; 30], offset: DVec3) {
    for e in 0..30 {
        let prev = if e % 5 == 0 {
            spd.material(COLORS[e / 5], 0.5, 0.2, 37.0, 0.0, 0.0);
            e + 4
        } else {
            e - 1
        };
        let base = points[e] + offset;
        let apex = points[prev] + offset;
        spd.cone(base, RADIUS, apex, RADIUS);
        spd.sphere(base, RADIUS);
    }
}

/// The 30 edge midpoints of a dodecahedron, as six pentagons of five points, scaled so that
/// spheres of radius `minor` on them stay within the unit sphere.
fn ring_points(minor: f64) -> [DVec3; 30] {
    let scale = 1.0 / (1.0 + minor);
    let mut p = [DVec3::ZERO; 30];
    for (k, v) in p.iter_mut().take(5).enumerate() {
        let a = k as f64 * 2.0 * PI / 5.0;
        *v = DVec3::new(scale * a.cos(), scale * a.sin(), 0.0);
    }
    // The dihedral angle between adjacent faces tips the first pentagon onto a neighbour;
    // spinning about Z by 36° + k·72° places the five neighbours.
    let tip = rotate_x(2.0 * ((PI / 3.0).cos() / (PI / 5.0).sin()).acos());
    for ring in 1..6 {
        let spin = rotate_z(PI * (2.0 * (ring - 1) as f64 + 1.0) / 5.0);
        for k in 0..5 {
            p[5 * ring + k] = apply(apply(p[k], &tip), &spin);
        }
    }
    p
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::spd::mat::testing::{close, close3, counts};
    use crate::scene::Shape;
    use glam::Vec3A;

    const SPREAD: f64 = 2.613125929752753;

    /// §4.4's table of ring points, to its six digits.
    const POINTS: [[f64; 3]; 30] = [
        [0.930995, 0.0, 0.0],
        [0.287693, 0.885429, 0.0],
        [-0.753191, 0.547225, 0.0],
        [-0.753191, -0.547225, 0.0],
        [0.287693, -0.885429, 0.0],
        [0.753191, 0.547225, 0.0],
        [0.0, 0.489453, 0.791951],
        [-0.753191, -0.244726, 0.489453],
        [-0.465497, -0.640702, -0.489453],
        [0.465497, -0.151249, -0.791951],
        [-0.287693, 0.885429, 0.0],
        [-0.465497, 0.151249, 0.791951],
        [0.0, -0.791951, 0.489453],
        [0.465497, -0.640702, -0.489453],
        [0.287693, 0.395976, -0.791951],
        [-0.930995, 0.0, 0.0],
        [-0.287693, -0.395976, 0.791951],
        [0.753191, -0.244726, 0.489453],
        [0.753191, 0.244726, -0.489453],
        [-0.287693, 0.395976, -0.791951],
        [-0.287693, -0.885429, 0.0],
        [0.287693, -0.395976, 0.791951],
        [0.465497, 0.640702, 0.489453],
        [0.0, 0.791951, -0.489453],
        [-0.465497, -0.151249, -0.791951],
        [0.753191, -0.547225, 0.0],
        [0.465497, 0.151249, 0.791951],
        [-0.465497, 0.640702, 0.489453],
        [-0.753191, 0.244726, -0.489453],
        [0.0, -0.489453, -0.791951],
    ];

    fn near(a: Vec3A, b: [f64; 3]) -> bool {
        (0..3).all(|i| (f64::from(a[i]) - b[i]).abs() < 1.5e-6)
    }

    #[test]
    fn counts_match_the_c_program() {
        for (size, n) in [(0, 0), (1, 30), (2, 150), (7, 4200), (8, 6120)] {
            let s = make(size);
            assert_eq!(s.name, format!("rings{size}"));
            assert_eq!(counts(&s), [n, n, 1, 0], "size {size}");
        }
    }

    #[test]
    fn view_lights_wall_and_materials() {
        let s = make(7);
        assert!(close3(s.camera.from, [-1.0, -SPREAD, 0.5]));
        assert!(close3(s.camera.at, [-1.0, -SPREAD + 1.0, 0.5]));
        assert!(close3(s.camera.up, [0.0, 0.0, 1.0]));
        assert_eq!(
            (s.camera.angle, s.hither, s.resolution),
            (45.0, 1.0, [512, 512])
        );
        assert!(close3(s.background, SKY));
        let lights: Vec<Vec3A> = s.lights.iter().map(|l| l.pos).collect();
        let want = [
            [3.0, -SPREAD, 3.0],
            [-4.0, -SPREAD, 1.0],
            [2.0, -SPREAD, -4.0],
        ];
        assert_eq!(lights.len(), 3);
        for (l, w) in lights.iter().zip(want) {
            assert!(close3(*l, w), "{l:?}");
        }

        let wall = s.materials[s.objects[0].material as usize];
        assert!(close3(wall.color, [1.0; 3]));
        assert_eq!(
            (wall.kd, wall.ks, wall.shine, wall.t, wall.ior),
            (1.0, 0.0, 1e5, 0.0, 1.0)
        );
        let Shape::Polygon(v) = &s.objects[0].shape else {
            panic!("wall is not a 4-gon")
        };
        let wy = SPREAD * 8.0;
        let w = 1.01 * (wy + SPREAD) * (PI / 8.0).tan();
        let want = [
            [w - 1.0, wy, w + 0.5],
            [-w - 1.0, wy, w + 0.5],
            [-w - 1.0, wy, -w + 0.5],
            [w - 1.0, wy, -w + 0.5],
        ];
        for (p, w) in v.iter().zip(want) {
            assert!(close3(*p, w), "{p:?}");
        }

        // Six ring materials besides the wall; each ring of five cylinders and spheres
        // shares one.
        assert_eq!(s.materials.len(), 7);
        for (i, o) in s.objects[1..].iter().enumerate() {
            let ring = (i / 10) % 6;
            let m = s.materials[o.material as usize];
            assert!(close3(m.color, COLORS[ring]));
            assert_eq!((m.kd, m.ks, m.t, m.ior), (0.5, 0.2, 0.0, 1.0));
            assert!(close(m.shine, 3.0827));
        }
    }

    #[test]
    fn first_object_follows_the_point_table() {
        let s = make(1);
        let offset = [0.0, SPREAD, 0.0];
        let at = |p: [f64; 3]| [p[0] + offset[0], p[1] + offset[1], p[2] + offset[2]];
        for (e, &point) in POINTS.iter().enumerate() {
            let prev = if e % 5 == 0 { e + 4 } else { e - 1 };
            let Shape::Cone(c) = &s.objects[1 + 2 * e].shape else {
                panic!("cylinder {e}")
            };
            assert!(near(c.base, at(point)), "{e}: {:?}", c.base);
            assert!(near(c.apex, at(POINTS[prev])), "{e}: {:?}", c.apex);
            assert!(close(c.base_radius, RADIUS) && close(c.apex_radius, RADIUS));
            let Shape::Sphere(sp) = &s.objects[2 + 2 * e].shape else {
                panic!("sphere {e}")
            };
            assert!(near(sp.center, at(point)), "{e}: {:?}", sp.center);
            assert!(close(sp.radius, RADIUS));
        }
    }

    #[test]
    fn layers_form_a_pyramid() {
        // Layer 1's four objects: z outer, x inner, at x, z in {-1, 1}.
        let s = make(2);
        let first_sphere = |obj: usize| match &s.objects[1 + obj * 60 + 1].shape {
            Shape::Sphere(sp) => sp.center,
            other => panic!("expected a sphere, got {other:?}"),
        };
        let p0 = POINTS[0];
        for (obj, (x, z)) in [(-1.0, -1.0), (1.0, -1.0), (-1.0, 1.0), (1.0, 1.0)]
            .into_iter()
            .enumerate()
        {
            let want = [p0[0] + x, p0[1] + 2.0 * SPREAD, p0[2] + z];
            assert!(near(first_sphere(obj + 1), want), "{obj}");
        }
    }
}
