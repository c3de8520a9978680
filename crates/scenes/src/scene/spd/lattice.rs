//! SPD `lattice` (Antonio Costa): a cubic grid of spheres filling the unit cube, each joined to
//! its neighbours by thin red (x), green (y) and blue (z) cylinders. Size `n` gives `n` cells
//! per side: `(n + 1)^3` spheres and `3 n (n + 1)^2` cylinders. SPD default size 12.
//!
//! Size 0 divides by zero, as the C program does: one sphere with non-finite centre and
//! radius, and a non-finite view.

use super::{Spd, SKY};
use crate::scene::Scene;
use glam::DVec3;

/// Sphere radius for one cell of unit size.
const SPHERE_R: f64 = 1.0 / 4.0;
/// Cylinder radius for one cell of unit size.
const ROD_R: f64 = 1.0 / 16.0;

pub(crate) fn make(size: u32) -> Scene {
    let n = f64::from(size);
    let cell = 1.0 / n;
    let sphere_r = SPHERE_R / n;
    let rod_r = ROD_R / n;
    // Rods start a little inside the spheres, short of where they would poke out.
    let inset = (sphere_r * (1.0 - (ROD_R / SPHERE_R).sqrt())) * 0.99;

    let mut spd = Spd::new(format!("lattice{size}"), SKY);
    let x_mid = (f64::from(size >> 1) + 0.5) * cell;
    let z_off = 1.0 / (2.0 * n);
    spd.view(
        DVec3::new(x_mid, 1.0, 1.0 - z_off),
        DVec3::new(x_mid, -1.0, -1.0 - z_off),
        DVec3::new(0.2, 1.0, 0.0),
        60.0,
        0.0,
        512,
    );
    for [x, y, z] in [
        [2.0, 0.5, 0.5],
        [-1.0, 0.5, 0.5],
        [0.5, 2.0, 0.5],
        [0.5, -1.0, 0.5],
        [0.5, 0.5, 2.0],
        [0.5, 0.5, -1.0],
    ] {
        spd.light(DVec3::new(x, y, z));
    }

    // Rod colours along x, y and z.
    let rods = [[0.9, 0.1, 0.1], [0.1, 0.9, 0.1], [0.1, 0.1, 0.9]];
    for x in 0..=size {
        let x0 = f64::from(x) / n;
        for y in 0..=size {
            let y0 = f64::from(y) / n;
            for z in 0..=size {
                let z0 = f64::from(z) / n;
                let p = DVec3::new(x0, y0, z0);
                spd.material([0.9; 3], 0.5, 0.5, 37.0, 0.0, 0.0);
                spd.sphere(p, sphere_r);
                for (k, (color, i)) in rods.iter().zip([x, y, z]).enumerate() {
                    if i == size {
                        continue;
                    }
                    spd.material(*color, 0.99, 0.0, 0.0, 0.0, 0.0);
                    // Only the rod's own coordinate moves: the others are copied exactly.
                    let (mut a, mut b) = (p, p);
                    a[k] = p[k] + inset;
                    b[k] = p[k] + cell - inset;
                    spd.cone(a, rod_r, b, rod_r);
                }
            }
        }
    }
    spd.finish()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::spd::mat::testing::{close, close3, counts};
    use crate::scene::Shape;

    #[test]
    fn counts_match_the_c_program() {
        for (size, spheres, rods) in [
            (0, 1, 0),
            (1, 8, 12),
            (2, 27, 54),
            (12, 2197, 6084),
            (13, 2744, 7644),
        ] {
            let s = make(size);
            assert_eq!(s.name, format!("lattice{size}"));
            assert_eq!(counts(&s), [spheres, rods, 0, 0], "size {size}");
        }
    }

    #[test]
    fn view_and_lights() {
        let s = make(12);
        assert!(close3(s.camera.from, [0.541667, 1.0, 0.958333]));
        assert!(close3(s.camera.at, [0.541667, -1.0, -1.041667]));
        assert!(close3(s.camera.up, [0.2, 1.0, 0.0]));
        assert_eq!(
            (s.camera.angle, s.hither, s.resolution),
            (60.0, 0.0, [512, 512])
        );
        assert!(close3(s.background, SKY));
        let want = [
            [2.0, 0.5, 0.5],
            [-1.0, 0.5, 0.5],
            [0.5, 2.0, 0.5],
            [0.5, -1.0, 0.5],
            [0.5, 0.5, 2.0],
            [0.5, 0.5, -1.0],
        ];
        assert_eq!(s.lights.len(), 6);
        for (l, w) in s.lights.iter().zip(want) {
            assert!(close3(l.pos, w), "{:?}", l.pos);
        }
        // Odd sizes put the eye over a cell centre too: (SF >> 1) + 0.5 cells.
        assert!(close(make(3).camera.from.x, 1.5 / 3.0));
    }

    #[test]
    fn first_cell_and_materials() {
        let s = make(12);
        let delta = 0.12375 / 12.0;
        let Shape::Sphere(sp) = &s.objects[0].shape else {
            panic!("sphere")
        };
        assert!(close3(sp.center, [0.0; 3]) && close(sp.radius, 1.0 / 48.0));
        let ends = [
            ([delta, 0.0, 0.0], [1.0 / 12.0 - delta, 0.0, 0.0]),
            ([0.0, delta, 0.0], [0.0, 1.0 / 12.0 - delta, 0.0]),
            ([0.0, 0.0, delta], [0.0, 0.0, 1.0 / 12.0 - delta]),
        ];
        let colors = [[0.9, 0.1, 0.1], [0.1, 0.9, 0.1], [0.1, 0.1, 0.9]];
        for (i, ((a, b), color)) in ends.into_iter().zip(colors).enumerate() {
            let o = &s.objects[1 + i];
            let Shape::Cone(c) = &o.shape else {
                panic!("rod {i}")
            };
            assert!(close3(c.base, a) && close3(c.apex, b), "{c:?}");
            assert!(close(c.base_radius, 1.0 / 192.0) && close(c.apex_radius, 1.0 / 192.0));
            let m = s.materials[o.material as usize];
            assert!(close3(m.color, color));
            assert_eq!(
                (m.kd, m.ks, m.shine, m.t, m.ior),
                (0.99, 0.0, 1e5, 0.0, 1.0)
            );
        }
        let ball = s.materials[s.objects[0].material as usize];
        assert!(close3(ball.color, [0.9; 3]));
        assert_eq!((ball.kd, ball.ks, ball.t, ball.ior), (0.5, 0.5, 0.0, 1.0));
        assert!(close(ball.shine, 3.0827));
        assert_eq!(s.materials.len(), 4);

        // The last z of the first column has no z rod; the next sphere follows at once.
        let Shape::Sphere(sp) = &s.objects[4 * 12].shape else {
            panic!("sphere")
        };
        assert!(close3(sp.center, [0.0, 0.0, 1.0]));
        let Shape::Cone(c) = &s.objects[4 * 12 + 1].shape else {
            panic!("rod")
        };
        assert!(close3(c.base, [delta, 0.0, 1.0]));
        let Shape::Sphere(sp) = &s.objects[4 * 12 + 3].shape else {
            panic!("sphere")
        };
        assert!(close3(sp.center, [0.0, 1.0 / 12.0, 0.0]));
        // Nothing past the far corner sphere.
        let Shape::Sphere(sp) = &s.objects.last().unwrap().shape else {
            panic!("sphere")
        };
        assert!(close3(sp.center, [1.0; 3]));
    }

    #[test]
    fn size_zero_does_not_panic() {
        let s = make(0);
        assert_eq!(s.objects.len(), 1);
    }
}
