//! SPD `gears`: a `size`×`size`×`size` block of meshing 36-tooth gears above a reflective
//! square. Each gear is a concave 144-vertex top face, 144 side quadrilaterals and a 144-vertex
//! bottom face; some gears are transparent. Size `n` gives `146·n³ + 1` polygons. SPD default
//! size 4.
//!
//! The tooth corners are rotated with the SPD library's row-vector Z rotation and its sums, so
//! the f64 coordinates round the way the C program's do.

use super::{Spd, SKY};
use crate::scene::Scene;
use glam::DVec3;
use std::f64::consts::PI;

/// Teeth per gear (four outline vertices each).
const TEETH: usize = 36;
/// Tip radius relative to the pitch: slightly under 1 so meshing gears never touch.
const OUTER_EDGE_RATIO: f64 = 0.995;
/// Root radius relative to the pitch.
const INNER_EDGE_RATIO: f64 = 0.9;
/// Largest gear thickness.
const DEPTH_RATIO: f64 = 0.1;

pub(crate) fn make(size: u32) -> Scene {
    let mut spd = Spd::new(format!("gears{size}"), SKY);
    spd.view(
        DVec3::new(-1.1, -2.1, 2.6),
        DVec3::ZERO,
        DVec3::Z,
        45.0,
        1.0,
        512,
    );
    for l in [
        [2.0, 4.0, 4.0],
        [-2.0, 4.0, 3.0],
        [2.0, -2.5, 2.5],
        [-1.0, -4.0, 2.0],
        // Just behind the eye.
        [-1.111, -2.121, 2.626],
    ] {
        spd.light(DVec3::from(l));
    }

    // The reflective off-white ground square.
    spd.material([1.0, 0.85, 0.7], 0.3, 0.6, 37.0, 0.0, 0.0);
    spd.polygon(&[
        DVec3::new(2.0, 2.0, 0.0),
        DVec3::new(-2.0, 2.0, 0.0),
        DVec3::new(-2.0, -2.0, 0.0),
        DVec3::new(2.0, -2.0, 0.0),
    ]);

    let edge_diff = 1.0 - INNER_EDGE_RATIO;
    let n = size as u64;
    let sf = f64::from(size);
    // Pitch radius: `size` gears per row, neighbours overlapping by the tooth depth.
    let radius = 1.0 / (sf - (i64::from(size) - 1) as f64 * edge_diff / 2.0);
    let first = -1.0 + radius;
    let step_xy = radius * (2.0 - edge_diff);
    let step_z = -1.0 / sf;
    let thickness = min(DEPTH_RATIO, 1.0 / (2.0 * sf));

    for iz in 0..n {
        let cz = 1.0 + iz as f64 * step_z;
        for iy in 0..n {
            let cy = first + iy as f64 * step_xy;
            for ix in 0..n {
                let cx = first + ix as f64 * step_xy;
                let color = gear_color(ix, iy, iz);
                if (ix * 4 + iy * 2 + iz) % 5 == 0 {
                    spd.material(color, 0.2, 0.0, 0.0, 0.8, 1.1);
                } else {
                    spd.material(color, 1.0, 0.0, 0.0, 0.0, 0.0);
                }
                // Alternate gears are turned by half a tooth so that neighbours mesh.
                let phase = PI * ((ix + iy + iz) % 2) as f64 / TEETH as f64;
                gear(
                    &mut spd,
                    DVec3::new(cx, cy, cz),
                    phase,
                    OUTER_EDGE_RATIO * radius,
                    (1.0 - edge_diff) * radius,
                    thickness,
                );
            }
        }
    }
    spd.finish()
}

/// `A < B ? A : B`, as the C macro.
fn min(a: f64, b: f64) -> f64 {
    if a < b {
        a
    } else {
        b
    }
}

/// `A > B ? A : B`, as the C macro.
fn max(a: f64, b: f64) -> f64 {
    if a > b {
        a
    } else {
        b
    }
}

/// The fractional part of a non-negative number.
fn frac(a: f64) -> f64 {
    a - a.trunc()
}

/// A pseudo-random colour for the gear at grid cell (ix, iy, iz), scaled so its largest
/// component is 1.
fn gear_color(ix: u64, iy: u64, iz: u64) -> [f64; 3] {
    let c = [
        0.01 + frac((ix * 3 + iy * 2 + iz + 1) as f64 * 5.0 / 7.0),
        0.01 + frac((iy * 3 + iz * 2 + ix + 1) as f64 * 3.0 / 7.0),
        0.01 + frac((iz * 3 + ix * 2 + iy + 1) as f64 * 2.0 / 7.0),
    ];
    let m = max(max(c[0], c[1]), c[2]);
    c.map(|x| x / m)
}

/// The point `(r, 0, z)` turned by `a` radians about +Z (row vector times the SPD's Z-rotation
/// matrix), then moved by `center`.
fn turned(r: f64, z: f64, a: f64, center: DVec3) -> DVec3 {
    let (s, c) = (a.sin(), a.cos());
    let x = r * c + 0.0 * -s + z * 0.0;
    let y = r * s + 0.0 * c + z * 0.0;
    let z = r * 0.0 + 0.0 * 0.0 + z * 1.0;
    DVec3::new(x + center.x, y + center.y, z + center.z)
}

/// The four outline vertices of the tooth at `at` radians: two on the tip circle, two on the
/// root circle. A negative `pitch` (the angle one tooth spans) walks the outline backwards.
fn tooth(out: &mut Vec<DVec3>, at: f64, pitch: f64, center: DVec3, tip: f64, root: f64, z: f64) {
    out.push(turned(tip, z, at - 0.19 * pitch, center));
    out.push(turned(tip, z, at + 0.19 * pitch, center));
    out.push(turned(root, z, at + 0.3 * pitch, center));
    out.push(turned(root, z, at + 0.7 * pitch, center));
}

/// One gear whose top face lies at `center`: top face (counter-clockwise from +Z), the side
/// walls, then the bottom face `thickness` lower (clockwise from +Z).
fn gear(spd: &mut Spd, center: DVec3, phase: f64, tip: f64, root: f64, thickness: f64) {
    let pitch = 2.0 * PI / TEETH as f64;

    let mut top = Vec::with_capacity(4 * TEETH);
    for n in 0..TEETH {
        let at = phase + 2.0 * PI * n as f64 / TEETH as f64;
        tooth(&mut top, at, pitch, center, tip, root, 0.0);
    }
    spd.polygon(&top);

    for k in 0..top.len() {
        let a = top[k];
        let b = top[(k + 1) % top.len()];
        let down = |p: DVec3| DVec3::new(p.x, p.y, p.z - thickness);
        spd.polygon(&[a, down(a), down(b), b]);
    }

    let mut bottom = Vec::with_capacity(4 * TEETH);
    for n in 0..TEETH {
        let at = phase - 2.0 * PI * n as f64 / TEETH as f64;
        tooth(&mut bottom, at, -pitch, center, tip, root, -thickness);
    }
    spd.polygon(&bottom);
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::spd::mat::testing::{close, close3, kinds};
    use crate::scene::Shape;
    use glam::Vec3A;

    fn poly(s: &Scene, i: usize) -> &[Vec3A] {
        match &s.objects[i].shape {
            Shape::Polygon(v) => v,
            other => panic!("object {i} is not a polygon: {other:?}"),
        }
    }

    /// (spheres, cones, triangles, quadrilaterals, larger polygons, patches)
    fn by_kind(s: &Scene) -> [usize; 6] {
        let [sp, co, tri, poly, pp] = kinds(s);
        let quads = s
            .objects
            .iter()
            .filter(|o| matches!(&o.shape, Shape::Polygon(v) if v.len() == 4))
            .count();
        [sp, co, tri, quads, poly - quads, pp]
    }

    #[test]
    fn counts_match_the_c_program() {
        // §5.4: p = 146·n³ + 1, of which 2n³ are 144-gons.
        for (size, faces, quads) in [
            (0, 0, 1),
            (1, 2, 145),
            (2, 16, 1153),
            (4, 128, 9217),
            (5, 250, 18001),
        ] {
            let s = make(size);
            assert_eq!(s.name, format!("gears{size}"));
            assert_eq!(by_kind(&s), [0, 0, 0, quads, faces, 0], "size {size}");
        }
    }

    #[test]
    fn view_lights_and_ground() {
        let s = make(1);
        assert!(close3(s.camera.from, [-1.1, -2.1, 2.6]));
        assert!(close3(s.camera.at, [0.0; 3]));
        assert!(close3(s.camera.up, [0.0, 0.0, 1.0]));
        assert_eq!((s.camera.angle, s.resolution), (45.0, [512, 512]));
        assert!(close(s.hither, 1.0));
        assert!(close3(s.background, SKY));
        let want = [
            [2.0, 4.0, 4.0],
            [-2.0, 4.0, 3.0],
            [2.0, -2.5, 2.5],
            [-1.0, -4.0, 2.0],
            [-1.111, -2.121, 2.626],
        ];
        assert_eq!(s.lights.len(), 5);
        for (l, w) in s.lights.iter().zip(want) {
            assert!(close3(l.pos, w), "{:?}", l.pos);
        }
        let ground = s.materials[s.objects[0].material as usize];
        assert!(close3(ground.color, [1.0, 0.85, 0.7]));
        assert_eq!(
            (ground.kd, ground.ks, ground.t, ground.ior),
            (0.3, 0.6, 0.0, 1.0)
        );
        assert!(close(ground.shine, 3.0827));
        let g = poly(&s, 0);
        for (p, w) in g.iter().zip([
            [2.0, 2.0, 0.0],
            [-2.0, 2.0, 0.0],
            [-2.0, -2.0, 0.0],
            [2.0, -2.0, 0.0],
        ]) {
            assert!(close3(*p, w));
        }
    }

    #[test]
    fn first_gear_matches_the_c_output() {
        let s = make(4);
        // "f 1 0.605523 0.408284 0.2 0 100000 0.8 1.1"
        let m = s.materials[s.objects[1].material as usize];
        assert!(close3(m.color, [1.0, 0.605523, 0.408284]));
        assert_eq!((m.kd, m.ks, m.shine, m.t), (0.2, 0.0, 1e5, 0.8));
        assert!(close(m.ior, 1.1));
        let top = poly(&s, 1);
        assert_eq!(top.len(), 144);
        // First vertices of the top face of gear (0,0,0) at size 4 (from the C output).
        assert!(close3(top[0], [-0.481960269, -0.748828416, 1.0]));
        assert!(close3(top[2], [-0.506813875, -0.728025361, 1.0]));
        // The first side wall and the bottom face.
        let side = poly(&s, 2);
        assert!(close3(side[1], [-0.481960269, -0.748828416, 0.9]));
        let bottom = poly(&s, 146);
        assert_eq!(bottom.len(), 144);
        assert!(close3(bottom[0], [-0.481960269, -0.731691064, 0.9]));
        assert!(bottom.iter().all(|p| close(p.z, 0.9)));
    }

    #[test]
    fn transparent_gear_counts() {
        // §4.2: 1, 2, 6, 13, 25 transparent gears for sizes 1..5.
        for (size, want) in [(1, 1), (2, 2), (3, 6), (4, 13), (5, 25)] {
            let s = make(size);
            let n = s
                .objects
                .iter()
                .filter(|o| matches!(&o.shape, Shape::Polygon(v) if v.len() == 144))
                .filter(|o| s.materials[o.material as usize].t > 0.0)
                .count();
            assert_eq!(n, 2 * want, "size {size}");
        }
    }

    #[test]
    fn faces_face_the_right_way() {
        let s = make(2);
        let faces: Vec<&[Vec3A]> = s
            .objects
            .iter()
            .filter_map(|o| match &o.shape {
                Shape::Polygon(v) if v.len() == 144 => Some(v.as_slice()),
                _ => None,
            })
            .collect();
        assert_eq!(faces.len(), 16);
        for (k, v) in faces.iter().enumerate() {
            // Signed area seen from +Z: each gear's top face comes first and winds
            // counter-clockwise, its bottom face clockwise.
            let area: f32 = (0..v.len())
                .map(|i| {
                    let (a, b) = (v[i], v[(i + 1) % v.len()]);
                    a.x * b.y - b.x * a.y
                })
                .sum();
            assert_eq!(area > 0.0, k % 2 == 0, "face {k}");
            // The first corner is convex, so it gives the face's facing.
            let n = (v[1] - v[0]).cross(v[2] - v[1]);
            assert!(n.z * area > 0.0, "face {k}");
        }
    }
}
