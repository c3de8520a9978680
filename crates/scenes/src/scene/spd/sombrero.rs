//! SPD `sombrero` (Alexander Enzmann): a height field of the damped ripple
//! `cos(2πρ)·e^(-ρ)` over a square grid of `w = 32·2^(n-1)` samples per side, written as
//! `2(w-1)²` triangles (the SPD always polygonises height fields). SPD default size 1.
//!
//! As in the C program the samples are stored as 32-bit floats, taken `8/w` apart but laid
//! out `8/(w-1)` apart, and the heights run along +Y although the view's up is +Z.

use super::{Spd, SKY};
use crate::scene::Scene;
use glam::DVec3;

/// The C program's value of 2π (its `3.14159265358` times 2), kept for its rounding.
#[allow(clippy::approx_constant)]
const TWO_PI_A: f64 = 2.0 * 3.14159265358 * 1.0;

pub(crate) fn make(size: u32) -> Scene {
    let mut spd = Spd::new(format!("sombrero{size}"), SKY);
    spd.view(
        DVec3::new(0.0, 5.0, -8.0),
        DVec3::ZERO,
        DVec3::Z,
        40.0,
        0.01,
        512,
    );
    spd.light(DVec3::new(10.0, 10.0, -10.0));

    // Shiny red.
    spd.material([1.0, 0.1, 0.1], 0.8, 0.0, 40.0, 0.0, 1.0);

    // Samples per side: 32, 64, 128, ... computed as the C does in 32-bit unsigned arithmetic
    // (the shift count wraps modulo 32, so size 0 gives an empty field).
    let w = 32u32.wrapping_mul(1u32.wrapping_shl(size.wrapping_sub(1))) as usize;
    let data = samples(w, -4.0, 4.0);
    height_field(&mut spd, &data, w, [-4.0, 4.0], -3.0, [-4.0, 4.0]);
    spd.finish()
}

/// The `w`×`w` height samples (row `i` along y, column `j` along x) over [lo, hi]², with
/// coordinates accumulated by repeated addition as in the C.
fn samples(w: usize, lo: f64, hi: f64) -> Vec<f32> {
    let step = (hi - lo) / w as f64;
    let mut data = Vec::with_capacity(w * w);
    let mut y = lo;
    for _ in 0..w {
        let mut x = lo;
        for _ in 0..w {
            let rho = (x * x + y * y).sqrt();
            let h = 3.0 * (TWO_PI_A * rho).cos() * (-(x * x + y * y).sqrt()).exp() / 3.0;
            data.push(h as f32);
            x += step;
        }
        y += step;
    }
    data
}

/// `lib_output_height` in NFF: vertex (i, j) is `(x0 + j·dx, y0 + data[i][j], z0 + i·dz)` on a
/// grid spanning `x` and `z`; each cell gives two triangles.
fn height_field(spd: &mut Spd, data: &[f32], w: usize, x: [f64; 2], y0: f64, z: [f64; 2]) {
    if w < 2 {
        return;
    }
    let dx = (x[1] - x[0]) / (w - 1) as f64;
    let dz = (z[1] - z[0]) / (w - 1) as f64;
    let v = |i: usize, j: usize| {
        DVec3::new(
            x[0] + j as f64 * dx,
            y0 + f64::from(data[i * w + j]),
            z[0] + i as f64 * dz,
        )
    };
    for i in 0..w - 1 {
        for j in 0..w - 1 {
            spd.polygon(&[v(i, j), v(i + 1, j + 1), v(i, j + 1)]);
            spd.polygon(&[v(i, j), v(i + 1, j), v(i + 1, j + 1)]);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::spd::mat::testing::{close, close3, kinds, tri};

    #[test]
    fn counts_match_the_c_program() {
        for (size, tris) in [(0, 0), (1, 1922), (2, 7938), (4, 130050)] {
            let s = make(size);
            assert_eq!(s.name, format!("sombrero{size}"));
            assert_eq!(kinds(&s), [0, 0, tris, 0, 0], "size {size}");
        }
    }

    #[test]
    fn view_light_and_material() {
        let s = make(1);
        assert!(close3(s.camera.from, [0.0, 5.0, -8.0]));
        assert!(close3(s.camera.at, [0.0; 3]));
        assert!(close3(s.camera.up, [0.0, 0.0, 1.0]));
        assert_eq!((s.camera.angle, s.resolution), (40.0, [512, 512]));
        assert!(close(s.hither, 0.01));
        assert!(close3(s.background, SKY));
        assert_eq!(s.lights.len(), 1);
        assert!(close3(s.lights[0].pos, [10.0, 10.0, -10.0]));
        assert_eq!(s.materials.len(), 1);
        let m = s.materials[0];
        assert!(close3(m.color, [1.0, 0.1, 0.1]));
        assert_eq!((m.kd, m.ks, m.t, m.ior), (0.8, 0.0, 0.0, 1.0));
        assert!(close(m.shine, 2.60078));
    }

    #[test]
    fn first_triangles_match_the_c_output() {
        // `sombrero -s 1`: the first cell's two triangles.
        let s = make(1);
        let t = tri(&s, 0);
        assert!(close3(t[0], [-4.0, -3.00193, -4.0]));
        assert!(close3(t[1], [-3.74194, -3.00164, -3.74194]));
        assert!(close3(t[2], [-3.74194, -3.00413, -4.0]));
        let t = tri(&s, 1);
        assert!(close3(t[0], [-4.0, -3.00193, -4.0]));
        assert!(close3(t[1], [-4.0, -3.00413, -3.74194]));
        assert!(close3(t[2], [-3.74194, -3.00164, -3.74194]));
        // The last vertex is the far corner of the grid.
        let t = tri(&s, 1921);
        assert!(close(t[2].x, 4.0) && close(t[2].z, 4.0));
    }

    #[test]
    fn heights_are_rounded_to_f32() {
        // The sample at the centre of the grid (x = y = 0) is cos(0)·e^0 = 1.
        let w = 32;
        let d = samples(w, -4.0, 4.0);
        assert_eq!(d[16 * w + 16], 1.0);
        assert!(d.iter().all(|h| h.abs() <= 1.0));
    }
}
