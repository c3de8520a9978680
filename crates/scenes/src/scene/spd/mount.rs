//! SPD `mount`: a fractal mountain grown by midpoint displacement on a square grid, with a
//! pyramid of four glass spheres in front of it. Size `n` gives `2·4^n` triangles and 4 spheres.
//! SPD default size 6.
//!
//! The heights come from the SPD's deterministic noise: the original ("buggy") coordinate hash
//! seeds the library's Gaussian generator, so the mountain is the one of the 1987 CG&A article.
//! For sizes above 7 the hash shifts by negative counts, undefined in C; this follows what
//! x86-64 does with them (the count is taken modulo 64).

use super::{Spd, SKY};
use crate::scene::Scene;
use glam::DVec3;
use std::f64::consts::PI;

/// Fractal dimension of the surface, between 2 and 3.
const FRACTAL_DIMENSION: f64 = 2.2;
/// Offset added to every hash: selects which mountain is grown.
const MOUNTAIN_NO: i64 = 21;
/// The C program's √2 for the centre displacement, kept for its rounding.
#[allow(clippy::approx_constant)]
const ROOT_2: f64 = 1.4142136;
/// Lower-left corner and side of the mountain's square.
const CORNER: f64 = -1.0;
const WIDTH: f64 = 2.0;

pub(crate) fn make(size: u32) -> Scene {
    let mut spd = Spd::new(format!("mount{size}"), SKY);
    spd.view(
        DVec3::new(-1.6, 1.6, 1.7),
        DVec3::ZERO,
        DVec3::Z,
        45.0,
        0.01,
        512,
    );
    spd.light(DVec3::new(-100.0, -100.0, 100.0));

    // Clear crystal spheres.
    spd.material([1.0, 1.0, 1.0], 0.1, 0.1, 6.7, 0.9, 1.5);
    spheres(&mut spd, DVec3::new(-0.8, 0.8, 1.0), 0.17);

    // Grey-brown matte mountain.
    spd.material([0.5, 0.45, 0.35], 1.0, 0.0, 0.0, 0.0, 0.0);
    let ratio = 2.0 / (2.0f64.ln() / (FRACTAL_DIMENSION - 1.0)).exp();
    // Cells per side: a C `int` shift (the count wraps modulo 32, as on x86-64).
    let n = 1i32.wrapping_shl(size);
    let mountain = Mountain {
        cells: f64::from(n),
        roughness: (ratio * ratio - 1.0).sqrt(),
        size: size as i32,
    };
    mountain.grow(&mut spd, i64::from(n), 0, 0, [0.0; 4]);
    spd.finish()
}

/// A tetrahedral pile of four spheres of radius `r`: one on top of `c`, three below it.
fn spheres(spd: &mut Spd, c: DVec3, r: f64) {
    let up = DVec3::new(0.0, 0.0, r * (3.0f64 / 2.0).sqrt());
    spd.sphere(DVec3::new(c.x + up.x, c.y + up.y, c.z + up.z), r);

    // Tip the top offset over by the tetrahedral angle, then spin it three ways.
    let axis = normalize(DVec3::new(1.0, 1.0, 0.0));
    let tipped = times(up, &axis_rotation(axis, (-1.0f64 / 3.0).acos()));
    for i in 0..3 {
        let p = times(tipped, &z_rotation(f64::from(i) * 2.0 * PI / 3.0));
        spd.sphere(DVec3::new(p.x + c.x, p.y + c.y, p.z + c.z), r);
    }
}

/// `v / |v|` component by component (a zero vector stays zero).
fn normalize(v: DVec3) -> DVec3 {
    let d = (v.x * v.x + v.y * v.y + v.z * v.z).sqrt();
    if d > 0.0 {
        DVec3::new(v.x / d, v.y / d, v.z / d)
    } else {
        v
    }
}

/// Row vector `v` times the 3×3 matrix `m`.
fn times(v: DVec3, m: &[[f64; 3]; 3]) -> DVec3 {
    let col = |j: usize| v.x * m[0][j] + v.y * m[1][j] + v.z * m[2][j];
    DVec3::new(col(0), col(1), col(2))
}

/// Right-handed rotation by `a` about +Z, for row vectors.
fn z_rotation(a: f64) -> [[f64; 3]; 3] {
    let (s, c) = (a.sin(), a.cos());
    [[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]]
}

/// Right-handed rotation by `a` about the unit axis `u`, for row vectors.
fn axis_rotation(u: DVec3, a: f64) -> [[f64; 3]; 3] {
    let (s, c) = (a.sin(), a.cos());
    let t = 1.0 - c;
    [
        [
            u.x * u.x + (1.0 - u.x * u.x) * c,
            u.x * u.y * t + u.z * s,
            u.x * u.z * t - u.y * s,
        ],
        [
            u.x * u.y * t - u.z * s,
            u.y * u.y + (1.0 - u.y * u.y) * c,
            u.y * u.z * t + u.x * s,
        ],
        [
            u.x * u.z * t + u.y * s,
            u.y * u.z * t - u.x * s,
            u.z * u.z + (1.0 - u.z * u.z) * c,
        ],
    ]
}

/// The original SPD coordinate hash of grid point (a, b) for size `size`: three shifted copies
/// of the coordinates summed in 64-bit unsigned arithmetic, keeping the low 16 bits. Shift
/// counts wrap modulo 64 as x86-64 does (this only matters above size 7).
fn hash(a: i64, b: i64, size: i32) -> i64 {
    let shl = |v: i64, by: i32| (v as u64).wrapping_shl(by.wrapping_sub(size) as u32);
    let h = shl(a, 23).wrapping_add(shl(b, 15)).wrapping_add(shl(a, 7));
    (h & 0xffff) as i64
}

/// The SPD library's deterministic normal deviate for `seed` (Numerical Recipes' polar
/// method fed by a small linear congruential generator).
fn gauss(seed: i64) -> f64 {
    const M1: i64 = 134_456;
    const IA1: i64 = 8121;
    const IC1: i64 = 28_411;
    let mut ix2 = seed;
    loop {
        let ix1 = (IC1 + ix2 * IA1) % M1;
        ix2 = (IC1 + ix1 * IA1) % M1;
        let v1 = ix1 as f64 * 2.0 * 1.0 / M1 as f64 - 1.0;
        let v2 = ix2 as f64 * 2.0 * 1.0 / M1 as f64 - 1.0;
        let r = v1 * v1 + v2 * v2;
        if r < 1.0 {
            return v1 * (-2.0 * r.ln() / r).sqrt();
        }
    }
}

struct Mountain {
    /// Grid cells per side, as a float.
    cells: f64,
    /// Height scale of a displacement relative to the half-side it spans.
    roughness: f64,
    /// The size factor, which the hash mixes in.
    size: i32,
}

impl Mountain {
    /// The unit-variance displacement of grid point (a, b).
    fn bump(&self, a: i64, b: i64) -> f64 {
        gauss(MOUNTAIN_NO + hash(a, b, self.size))
    }

    /// The square of `w` cells whose lower-left grid point is (x, y), with corner heights
    /// `z` = [lower-left, lower-right, upper-right, upper-left]: split into four until single
    /// cells remain, each written as two triangles.
    fn grow(&self, spd: &mut Spd, w: i64, x: i64, y: i64, z: [f64; 4]) {
        let [ll, lr, ur, ul] = z;
        if w == 1 {
            let lx = CORNER + x as f64 * WIDTH / self.cells;
            let rx = CORNER + (x + 1) as f64 * WIDTH / self.cells;
            let ly = CORNER + y as f64 * WIDTH / self.cells;
            let uy = CORNER + (y + 1) as f64 * WIDTH / self.cells;
            let c = [
                DVec3::new(lx, ly, ll),
                DVec3::new(rx, ly, lr),
                DVec3::new(rx, uy, ur),
                DVec3::new(lx, uy, ul),
            ];
            spd.polygon(&[c[0], c[1], c[2]]);
            spd.polygon(&[c[2], c[3], c[0]]);
            return;
        }
        if w < 1 {
            // Only reachable through an overflowed cell count at absurd sizes.
            return;
        }
        let h = w >> 1;
        let rise = h as f64 * WIDTH / self.cells * self.roughness;
        let lower = (ll + lr) / 2.0 + rise * self.bump(x + h, y);
        let right = (lr + ur) / 2.0 + rise * self.bump(x + w, y + h);
        let upper = (ur + ul) / 2.0 + rise * self.bump(x + h, y + w);
        let left = (ul + ll) / 2.0 + rise * self.bump(x, y + h);
        let middle = (ll + lr + ur + ul) / 4.0 + ROOT_2 * rise * self.bump(x + h, y + h);
        self.grow(spd, h, x, y, [ll, lower, middle, left]);
        self.grow(spd, h, x + h, y, [lower, lr, right, middle]);
        self.grow(spd, h, x + h, y + h, [middle, right, ur, upper]);
        self.grow(spd, h, x, y + h, [left, middle, upper, ul]);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::spd::mat::testing::{close, close3, kinds, tri};
    use crate::scene::Shape;

    #[test]
    fn counts_match_the_c_program() {
        for (size, tris) in [(0, 2), (1, 8), (6, 8192), (7, 32768)] {
            let s = make(size);
            assert_eq!(s.name, format!("mount{size}"));
            assert_eq!(kinds(&s), [4, 0, tris, 0, 0], "size {size}");
        }
    }

    #[test]
    fn view_light_and_glass_spheres() {
        let s = make(1);
        assert!(close3(s.camera.from, [-1.6, 1.6, 1.7]));
        assert!(close3(s.camera.at, [0.0; 3]));
        assert!(close3(s.camera.up, [0.0, 0.0, 1.0]));
        assert_eq!((s.camera.angle, s.resolution), (45.0, [512, 512]));
        assert!(close(s.hither, 0.01));
        assert!(close3(s.background, SKY));
        assert_eq!(s.lights.len(), 1);
        assert!(close3(s.lights[0].pos, [-100.0, -100.0, 100.0]));

        let want = [
            [-0.8, 0.8, 1.20821],
            [-0.661196, 0.661196, 0.930598],
            [-0.749194, 0.98961, 0.930598],
            [-0.98961, 0.749194, 0.930598],
        ];
        for (o, w) in s.objects[..4].iter().zip(want) {
            let Shape::Sphere(sp) = &o.shape else {
                panic!("expected a sphere")
            };
            assert!(close3(sp.center, w), "{:?}", sp.center);
            assert!(close(sp.radius, 0.17));
            let m = s.materials[o.material as usize];
            assert!(close3(m.color, [1.0; 3]));
            assert_eq!((m.kd, m.ks, m.t, m.ior), (0.1, 0.1, 0.9, 1.5));
            assert!(close(m.shine, 101.148));
        }
        let m = s.materials[s.objects[4].material as usize];
        assert!(close3(m.color, [0.5, 0.45, 0.35]));
        assert_eq!((m.kd, m.ks, m.shine, m.t, m.ior), (1.0, 0.0, 1e5, 0.0, 1.0));
    }

    #[test]
    fn first_triangles_match_the_c_output() {
        // `mount -s 1`: p 3 (-1 -1 0) (0 -1 -0.5481) (0 0 0.529551), then (0 0 0.529551)
        // (-1 0 -0.314742) (-1 -1 0), then (0 -1 -0.5481) (1 -1 0) (1 0 0.657244).
        let s = make(1);
        let t = tri(&s, 4);
        assert!(close3(t[0], [-1.0, -1.0, 0.0]) && close3(t[1], [0.0, -1.0, -0.5481]));
        assert!(close3(t[2], [0.0, 0.0, 0.529551]));
        let t = tri(&s, 5);
        assert!(close3(t[0], [0.0, 0.0, 0.529551]) && close3(t[1], [-1.0, 0.0, -0.314742]));
        assert!(close3(t[2], [-1.0, -1.0, 0.0]));
        let t = tri(&s, 6);
        assert!(close3(t[0], [0.0, -1.0, -0.5481]) && close3(t[2], [1.0, 0.0, 0.657244]));
    }

    #[test]
    fn size_8_matches_the_c_output() {
        // Triangle 1001 of `mount -s 8` (x86-64 build): the hash's third shift count is -1.
        let s = make(8);
        let t = tri(&s, 4 + 1000);
        assert!(close3(t[0], [-0.859375, -0.90625, -0.169388327]));
        assert!(close3(t[1], [-0.8515625, -0.90625, -0.171369601]));
        assert!(close3(t[2], [-0.8515625, -0.8984375, -0.153220675]));
    }

    #[test]
    fn hash_and_noise() {
        assert_eq!(hash(1, 0, 1), ((1 << 22) + (1 << 6)) & 0xffff);
        assert_eq!(hash(3, 5, 6), ((3 << 17) + (5 << 9) + (3 << 1)) & 0xffff);
        // Size 8: the count 7 - 8 = -1 acts as 63 on x86-64.
        assert_eq!(
            hash(1, 1, 8),
            ((1u64 << 15) + (1 << 7) + (1u64 << 63)) as i64 & 0xffff
        );
    }
}
