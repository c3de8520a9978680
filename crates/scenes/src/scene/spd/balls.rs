//! SPD `balls`: Haines' "sphereflake". A sphere carries nine spheres a third its size, each of
//! which carries nine more, down to the requested depth, above a beige floor square. Size `n`
//! gives `(9^(n+1) - 1) / 8` spheres and one polygon. SPD default size 4 (7381 spheres).
//!
//! Rotations are built as the SPD library's row-vector 4×4 matrices and applied with the same
//! sums, so the f64 results follow the C program's rounding.

use super::mat::{apply, axis_rotation, rotate_y, rotate_z, unit, IDENTITY};
use super::{Spd, SKY};
use crate::scene::Scene;
use glam::DVec3;
use std::f64::consts::PI;

pub(crate) fn make(size: u32) -> Scene {
    let mut spd = Spd::new(format!("balls{size}"), SKY);
    spd.view(
        DVec3::new(2.1, 1.3, 1.7),
        DVec3::ZERO,
        DVec3::Z,
        45.0,
        0.01,
        512,
    );
    spd.light(DVec3::new(4.0, 3.0, 2.0));
    spd.light(DVec3::new(1.0, -4.0, 4.0));
    spd.light(DVec3::new(-3.0, 1.0, 5.0));

    // The radius of a sphere enclosing the whole flake.
    let radius = 1.0;

    spd.material([1.0, 0.75, 0.33], 0.8, 0.0, 0.0, 0.0, 1.0);
    let (fx, fy, fz) = (12.0 * radius, 12.0 * radius, -radius / 2.0);
    spd.polygon(&[
        DVec3::new(fx, fy, fz),
        DVec3::new(-fx, fy, fz),
        DVec3::new(-fx, -fy, fz),
        DVec3::new(fx, -fy, fz),
    ]);

    spd.material([1.0, 0.9, 0.7], 0.5, 0.5, 37.0, 0.0, 1.0);
    let dirs = child_directions();
    flake(
        &mut spd,
        &dirs,
        size,
        DVec3::ZERO,
        radius / 2.0,
        DVec3::Z,
        1.0 / 3.0,
    );
    spd.finish()
}

/// Writes the sphere at `c` with radius `r`, then (if `depth` allows) its nine children
/// around `dir`, each with its own subtree, depth first. `ratio` is a child's radius relative
/// to its parent's.
fn flake(spd: &mut Spd, dirs: &[DVec3; 9], depth: u32, c: DVec3, r: f64, dir: DVec3, ratio: f64) {
    spd.sphere(c, r);
    if depth == 0 {
        return;
    }
    // Orientation taking +Z to `dir`; the thresholds absorb child directions whose length
    // falls a little short of 1.
    let m = if dir.z >= 0.9999 {
        IDENTITY
    } else if dir.z <= -0.9999 {
        rotate_y(PI)
    } else {
        let z = DVec3::Z;
        let axis = unit(z.cross(dir));
        axis_rotation(axis, z.dot(dir).acos())
    };
    let dist = r * (1.0 + ratio);
    for d in dirs {
        let p = apply(*d, &m);
        let cc = DVec3::new(p.x * dist + c.x, p.y * dist + c.y, p.z * dist + c.z);
        let off = cc - c;
        let child_dir = DVec3::new(off.x / dist, off.y / dist, off.z / dist);
        flake(spd, dirs, depth - 1, cc, r * ratio, child_dir, ratio);
    }
}

/// The nine unit offsets of a sphere's children about +Z: three raised 35.26° above the
/// equator, 120° apart, each followed by two on the equator.
fn child_directions() -> [DVec3; 9] {
    let h = 1.0 / 2.0f64.sqrt();
    let tilt = axis_rotation(
        unit(DVec3::new(1.0, -1.0, 0.0)),
        (2.0 / 6.0f64.sqrt()).asin(),
    );
    let trio = [
        DVec3::new(h, h, 0.0),
        DVec3::new(h, 0.0, -h),
        DVec3::new(0.0, h, -h),
    ]
    .map(|v| apply(v, &tilt));
    let mut out = [DVec3::ZERO; 9];
    for set in 0..3 {
        let spin = rotate_z(set as f64 * 2.0 * PI / 3.0);
        for (k, v) in trio.iter().enumerate() {
            out[set * 3 + k] = apply(*v, &spin);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::spd::mat::testing::{close, close3, counts};
    use crate::scene::Shape;
    use glam::Vec3A;
    use std::f64::consts::FRAC_1_SQRT_2;

    #[test]
    fn counts_match_the_c_program() {
        for (size, spheres) in [(0, 1), (1, 10), (4, 7381), (5, 66430)] {
            let s = make(size);
            assert_eq!(s.name, format!("balls{size}"));
            assert_eq!(counts(&s), [spheres, 0, 1, 0], "size {size}");
        }
    }

    #[test]
    fn view_lights_and_materials() {
        let s = make(2);
        assert!(close3(s.camera.from, [2.1, 1.3, 1.7]));
        assert!(close3(s.camera.at, [0.0; 3]));
        assert!(close3(s.camera.up, [0.0, 0.0, 1.0]));
        assert_eq!((s.camera.angle, s.resolution), (45.0, [512, 512]));
        assert!(close(s.hither, 0.01));
        assert!(close3(s.background, SKY));
        let lights: Vec<Vec3A> = s.lights.iter().map(|l| l.pos).collect();
        assert_eq!(lights.len(), 3);
        for (l, want) in lights
            .iter()
            .zip([[4.0, 3.0, 2.0], [1.0, -4.0, 4.0], [-3.0, 1.0, 5.0]])
        {
            assert!(close3(*l, want), "{l:?}");
        }

        // Floor first, with its own material, then every sphere with the mirror material.
        assert_eq!(s.materials.len(), 2);
        let floor = s.materials[s.objects[0].material as usize];
        assert!(close3(floor.color, [1.0, 0.75, 0.33]));
        assert_eq!(
            (floor.kd, floor.ks, floor.shine, floor.t, floor.ior),
            (0.8, 0.0, 1e5, 0.0, 1.0)
        );
        let Shape::Polygon(v) = &s.objects[0].shape else {
            panic!("floor is not a 4-gon")
        };
        let want = [
            [12.0, 12.0, -0.5],
            [-12.0, 12.0, -0.5],
            [-12.0, -12.0, -0.5],
            [12.0, -12.0, -0.5],
        ];
        assert_eq!(v.len(), 4);
        for (p, w) in v.iter().zip(want) {
            assert!(close3(*p, w), "{p:?}");
        }
        let ball = s.materials[s.objects[1].material as usize];
        assert!(close3(ball.color, [1.0, 0.9, 0.7]));
        assert_eq!((ball.kd, ball.ks, ball.t, ball.ior), (0.5, 0.5, 0.0, 1.0));
        assert!(close(ball.shine, 3.0827));
        assert!(s.objects[1..]
            .iter()
            .all(|o| o.material == s.objects[1].material));
    }

    #[test]
    fn first_level_follows_the_direction_table() {
        // §4.1's objset, in order; the first level uses it unrotated at distance 4r/3.
        let dirs = [
            [0.408248290, 0.408248290, 0.816496581],
            [0.965925826, 0.258819045, 0.0],
            [0.258819045, 0.965925826, 0.0],
            [-0.557677536, 0.149429245, 0.816496581],
            [-FRAC_1_SQRT_2, FRAC_1_SQRT_2, 0.0],
            [-0.965925826, -0.258819045, 0.0],
            [0.149429245, -0.557677536, 0.816496581],
            [-0.258819045, -0.965925826, 0.0],
            [FRAC_1_SQRT_2, -FRAC_1_SQRT_2, 0.0],
        ];
        let s = make(1);
        let spheres: Vec<_> = s.objects[1..]
            .iter()
            .map(|o| match &o.shape {
                Shape::Sphere(sp) => *sp,
                other => panic!("expected a sphere, got {other:?}"),
            })
            .collect();
        assert!(close3(spheres[0].center, [0.0; 3]) && close(spheres[0].radius, 0.5));
        for (sp, d) in spheres[1..].iter().zip(dirs) {
            assert!(
                close3(sp.center, d.map(|x| x * 2.0 / 3.0)),
                "{:?}",
                sp.center
            );
            assert!(close(sp.radius, 1.0 / 6.0));
        }
        // "s 0.272166 0.272166 0.544331 0.166667"
        assert!(close3(spheres[1].center, [0.272166, 0.272166, 0.544331]));
    }

    #[test]
    fn children_touch_their_parents_depth_first() {
        // Pre-order at size 2: root, then child 0 and its nine, child 1 and its nine, ...
        let s = make(2);
        let sph: Vec<_> = s.objects[1..]
            .iter()
            .map(|o| match &o.shape {
                Shape::Sphere(sp) => *sp,
                other => panic!("expected a sphere, got {other:?}"),
            })
            .collect();
        assert_eq!(sph.len(), 91);
        for child in 0..9 {
            let p = sph[1 + child * 10];
            assert!(close(p.center.length(), 2.0 / 3.0));
            assert!(close(p.radius, 1.0 / 6.0));
            for g in &sph[2 + child * 10..11 + child * 10] {
                assert!(close(g.radius, 1.0 / 18.0));
                assert!(close(
                    (g.center - p.center).length(),
                    1.0 / 6.0 + 1.0 / 18.0
                ));
                // Grandchildren sit on the far side of their parent, away from the root.
                assert!((g.center - p.center).dot(p.center) >= -1e-6);
            }
        }
    }
}
