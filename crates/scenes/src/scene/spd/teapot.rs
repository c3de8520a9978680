//! SPD `teapot`: the Newell teapot with Crow's bottom, 32 bicubic Bezier patches, each
//! tessellated on an `n`×`n` grid into smooth (`pp`) triangles, standing on an `n`×`n`
//! checkerboard. Size `n` gives `64n² − 8n` triangles (the cusp cells of the lid and the
//! bottom lose one triangle each) and `n²` squares. SPD default size 6; the Readme's
//! statistics use 12.

use super::{Spd, SKY};
use crate::scene::Scene;
use glam::DVec3;

type Mat4 = [[f64; 4]; 4];

/// The cubic Bezier basis in power form: `[u³ u² u 1] · BEZIER` gives the Bernstein weights.
const BEZIER: Mat4 = [
    [-1.0, 3.0, -3.0, 1.0],
    [3.0, -6.0, 3.0, 0.0],
    [-3.0, 3.0, 0.0, 0.0],
    [1.0, 0.0, 0.0, 0.0],
];

pub(crate) fn make(size: u32) -> Scene {
    let mut spd = Spd::new(format!("teapot{size}"), SKY);
    spd.view(
        DVec3::new(4.86, 7.2, 5.4),
        DVec3::ZERO,
        DVec3::Z,
        45.0,
        1.0,
        512,
    );
    spd.light(DVec3::new(-3.1, 9.8, 12.1));
    spd.light(DVec3::new(11.3, 5.1, 8.8));
    checkerboard(&mut spd, size);
    teapot(&mut spd, size);
    spd.finish()
}

/// Board coordinate of grid line `k` of `n`: the board spans [−4, 4].
fn board(k: u32, n: u32) -> f64 {
    4.0 * (2.0 * f64::from(k) / f64::from(n) - 1.0)
}

/// White squares where `s + t` is odd, then grey squares where it is even.
fn checkerboard(spd: &mut Spd, n: u32) {
    for (rgb, parity) in [([1.0; 3], 1), ([0.5; 3], 0)] {
        spd.material(rgb, 0.5, 0.5, 30.0, 0.0, 0.0);
        for s in 0..n {
            for t in 0..n {
                if (s + t) % 2 == parity {
                    let (x0, x1) = (board(s, n), board(s + 1, n));
                    let (y0, y1) = (board(t, n), board(t + 1, n));
                    spd.polygon(&[
                        DVec3::new(x0, y0, 0.0),
                        DVec3::new(x1, y0, 0.0),
                        DVec3::new(x1, y1, 0.0),
                        DVec3::new(x0, y1, 0.0),
                    ]);
                }
            }
        }
    }
}

fn mat_mul(a: &Mat4, b: &Mat4) -> Mat4 {
    let mut r = [[0.0; 4]; 4];
    for (i, row) in r.iter_mut().enumerate() {
        for (j, x) in row.iter_mut().enumerate() {
            *x = a[i][0] * b[0][j] + a[i][1] * b[1][j] + a[i][2] * b[2][j] + a[i][3] * b[3][j];
        }
    }
    r
}

fn transpose(a: &Mat4) -> Mat4 {
    let mut r = [[0.0; 4]; 4];
    for (i, row) in a.iter().enumerate() {
        for (j, &x) in row.iter().enumerate() {
            r[j][i] = x;
        }
    }
    r
}

/// Row vector times matrix.
fn row_mul(v: &[f64; 4], m: &Mat4) -> [f64; 4] {
    let mut r = [0.0; 4];
    for (j, x) in r.iter_mut().enumerate() {
        *x = v[0] * m[0][j] + v[1] * m[1][j] + v[2] * m[2][j] + v[3] * m[3][j];
    }
    r
}

fn dot4(a: &[f64; 4], b: &[f64; 4]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3]
}

/// The power vector `[u³ u² u 1]` and its derivative `[3u² 2u 1 0]`.
fn powers(u: f64) -> ([f64; 4], [f64; 4]) {
    let u2 = u * u;
    ([u2 * u, u2, u, 1.0], [u2 * 3.0, u * 2.0, 1.0, 0.0])
}

/// `v / |v|`, leaving a zero vector unchanged.
fn normalize(v: DVec3) -> DVec3 {
    let len = (v.x * v.x + v.y * v.y + v.z * v.z).sqrt();
    if len > 0.0 {
        DVec3::new(v.x / len, v.y / len, v.z / len)
    } else {
        v
    }
}

fn cross(a: DVec3, b: DVec3) -> DVec3 {
    DVec3::new(
        a.y * b.z - a.z * b.y,
        a.z * b.x - a.x * b.z,
        a.x * b.y - a.y * b.x,
    )
}

/// One patch in power form: `coef[axis] = BEZIER · G · BEZIERᵀ`, so that a coordinate is
/// `[s³ s² s 1] · coef · [t³ t² t 1]ᵀ`.
struct Patch {
    coef: [Mat4; 3],
}

impl Patch {
    fn new(indices: &[u16; 16]) -> Patch {
        let bt = transpose(&BEZIER);
        let coef = std::array::from_fn(|axis| {
            let mut g = [[0.0; 4]; 4];
            for (r, row) in g.iter_mut().enumerate() {
                for (c, x) in row.iter_mut().enumerate() {
                    *x = VERTS[usize::from(indices[4 * r + c])][axis];
                }
            }
            mat_mul(&mat_mul(&BEZIER, &g), &bt)
        });
        Patch { coef }
    }

    /// The point at `(s, t)` and its normal `normalize(∂P/∂t × ∂P/∂s)` (zero where the
    /// tangents are parallel or vanish).
    fn eval(&self, s: f64, t: f64) -> (DVec3, DVec3) {
        let (sp, dsp) = powers(s);
        let (tp, dtp) = powers(t);
        let mut p = [0.0; 3];
        let mut ds = [0.0; 3];
        let mut dt = [0.0; 3];
        for axis in 0..3 {
            let m = &self.coef[axis];
            let row = row_mul(&sp, m);
            p[axis] = dot4(&row, &tp);
            ds[axis] = dot4(&row_mul(&dsp, m), &tp);
            dt[axis] = dot4(&row, &dtp);
        }
        let n = normalize(cross(DVec3::from(dt), DVec3::from(ds)));
        (DVec3::from(p), n)
    }
}

/// The SPD's cusp test: a triangle with two or more vertices on the z axis (within 1e-4) is
/// degenerate and dropped (`false`); a single such vertex gets the axial normal, up at the
/// lid knob (z > 1.5) and down at the bottom centre.
fn fix_cusp(verts: &[DVec3; 3], normals: &mut [DVec3; 3]) -> bool {
    let on_axis: Vec<usize> = (0..3)
        .filter(|&i| verts[i].x.abs() <= 1e-4 && verts[i].y.abs() <= 1e-4)
        .collect();
    match on_axis[..] {
        [] => true,
        [i] => {
            normals[i] = if verts[i].z > 1.5 {
                DVec3::Z
            } else {
                DVec3::NEG_Z
            };
            true
        }
        _ => false,
    }
}

/// The 32 patches in order; in each, s-steps outer, t-steps inner, and per cell the triangles
/// (K0, K1, K2) and (K2, K3, K0) over the cell corners K0 = (s, t), K1 = (s, t+1),
/// K2 = (s+1, t+1), K3 = (s+1, t).
fn teapot(spd: &mut Spd, n: u32) {
    spd.material([1.0, 0.5, 0.1], 0.75, 0.25, 37.0, 0.0, 0.0);
    let nf = f64::from(n);
    for indices in &PATCHES {
        let patch = Patch::new(indices);
        for i in 0..n {
            for j in 0..n {
                let corners = [(i, j), (i, j + 1), (i + 1, j + 1), (i + 1, j)];
                for tri in [[0, 1, 2], [2, 3, 0]] {
                    let mut verts = [DVec3::ZERO; 3];
                    let mut normals = [DVec3::ZERO; 3];
                    for (k, &c) in tri.iter().enumerate() {
                        let (s, t) = corners[c];
                        (verts[k], normals[k]) = patch.eval(f64::from(s) / nf, f64::from(t) / nf);
                    }
                    if fix_cusp(&verts, &mut normals) {
                        spd.patch(&verts, &normals);
                    }
                }
            }
        }
    }
}

/// Control-point indices of the 32 patches (`teapot.c`'s `Patches`), row-major `G[r][c]`:
/// 0–3 rim, 4–11 body, 12–15 handle, 16–19 spout, 20–27 lid, 28–31 bottom.
#[rustfmt::skip]
const PATCHES: [[u16; 16]; 32] = [
    [0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15],
    [3, 16, 17, 18, 7, 19, 20, 21, 11, 22, 23, 24, 15, 25, 26, 27],
    [18, 28, 29, 30, 21, 31, 32, 33, 24, 34, 35, 36, 27, 37, 38, 39],
    [30, 40, 41, 0, 33, 42, 43, 4, 36, 44, 45, 8, 39, 46, 47, 12],
    [12, 13, 14, 15, 48, 49, 50, 51, 52, 53, 54, 55, 56, 57, 58, 59],
    [15, 25, 26, 27, 51, 60, 61, 62, 55, 63, 64, 65, 59, 66, 67, 68],
    [27, 37, 38, 39, 62, 69, 70, 71, 65, 72, 73, 74, 68, 75, 76, 77],
    [39, 46, 47, 12, 71, 78, 79, 48, 74, 80, 81, 52, 77, 82, 83, 56],
    [56, 57, 58, 59, 84, 85, 86, 87, 88, 89, 90, 91, 92, 93, 94, 95],
    [59, 66, 67, 68, 87, 96, 97, 98, 91, 99, 100, 101, 95, 102, 103, 104],
    [68, 75, 76, 77, 98, 105, 106, 107, 101, 108, 109, 110, 104, 111, 112, 113],
    [77, 82, 83, 56, 107, 114, 115, 84, 110, 116, 117, 88, 113, 118, 119, 92],
    [120, 121, 122, 123, 124, 125, 126, 127, 128, 129, 130, 131, 132, 133, 134, 135],
    [123, 136, 137, 120, 127, 138, 139, 124, 131, 140, 141, 128, 135, 142, 143, 132],
    [132, 133, 134, 135, 144, 145, 146, 147, 148, 149, 150, 151, 68, 152, 153, 154],
    [135, 142, 143, 132, 147, 155, 156, 144, 151, 157, 158, 148, 154, 159, 160, 68],
    [161, 162, 163, 164, 165, 166, 167, 168, 169, 170, 171, 172, 173, 174, 175, 176],
    [164, 177, 178, 161, 168, 179, 180, 165, 172, 181, 182, 169, 176, 183, 184, 173],
    [173, 174, 175, 176, 185, 186, 187, 188, 189, 190, 191, 192, 193, 194, 195, 196],
    [176, 183, 184, 173, 188, 197, 198, 185, 192, 199, 200, 189, 196, 201, 202, 193],
    [203, 203, 203, 203, 204, 205, 206, 207, 208, 208, 208, 208, 209, 210, 211, 212],
    [203, 203, 203, 203, 207, 213, 214, 215, 208, 208, 208, 208, 212, 216, 217, 218],
    [203, 203, 203, 203, 215, 219, 220, 221, 208, 208, 208, 208, 218, 222, 223, 224],
    [203, 203, 203, 203, 221, 225, 226, 204, 208, 208, 208, 208, 224, 227, 228, 209],
    [209, 210, 211, 212, 229, 230, 231, 232, 233, 234, 235, 236, 237, 238, 239, 240],
    [212, 216, 217, 218, 232, 241, 242, 243, 236, 244, 245, 246, 240, 247, 248, 249],
    [218, 222, 223, 224, 243, 250, 251, 252, 246, 253, 254, 255, 249, 256, 257, 258],
    [224, 227, 228, 209, 252, 259, 260, 229, 255, 261, 262, 233, 258, 263, 264, 237],
    [265, 265, 265, 265, 266, 267, 268, 269, 270, 271, 272, 273, 92, 119, 118, 113],
    [265, 265, 265, 265, 269, 274, 275, 276, 273, 277, 278, 279, 113, 112, 111, 104],
    [265, 265, 265, 265, 276, 280, 281, 282, 279, 283, 284, 285, 104, 103, 102, 95],
    [265, 265, 265, 265, 282, 286, 287, 266, 285, 288, 289, 270, 95, 94, 93, 92],
];

/// The 290 control points (`teapot.c`'s `Verts`).
const VERTS: [[f64; 3]; 290] = [
    [1.4, 0.0, 2.4],
    [1.4, -0.784, 2.4],
    [0.784, -1.4, 2.4],
    [0.0, -1.4, 2.4],
    [1.3375, 0.0, 2.53125],
    [1.3375, -0.749, 2.53125],
    [0.749, -1.3375, 2.53125],
    [0.0, -1.3375, 2.53125],
    [1.4375, 0.0, 2.53125],
    [1.4375, -0.805, 2.53125],
    [0.805, -1.4375, 2.53125],
    [0.0, -1.4375, 2.53125],
    [1.5, 0.0, 2.4],
    [1.5, -0.84, 2.4],
    [0.84, -1.5, 2.4],
    [0.0, -1.5, 2.4],
    [-0.784, -1.4, 2.4],
    [-1.4, -0.784, 2.4],
    [-1.4, 0.0, 2.4],
    [-0.749, -1.3375, 2.53125],
    [-1.3375, -0.749, 2.53125],
    [-1.3375, 0.0, 2.53125],
    [-0.805, -1.4375, 2.53125],
    [-1.4375, -0.805, 2.53125],
    [-1.4375, 0.0, 2.53125],
    [-0.84, -1.5, 2.4],
    [-1.5, -0.84, 2.4],
    [-1.5, 0.0, 2.4],
    [-1.4, 0.784, 2.4],
    [-0.784, 1.4, 2.4],
    [0.0, 1.4, 2.4],
    [-1.3375, 0.749, 2.53125],
    [-0.749, 1.3375, 2.53125],
    [0.0, 1.3375, 2.53125],
    [-1.4375, 0.805, 2.53125],
    [-0.805, 1.4375, 2.53125],
    [0.0, 1.4375, 2.53125],
    [-1.5, 0.84, 2.4],
    [-0.84, 1.5, 2.4],
    [0.0, 1.5, 2.4],
    [0.784, 1.4, 2.4],
    [1.4, 0.784, 2.4],
    [0.749, 1.3375, 2.53125],
    [1.3375, 0.749, 2.53125],
    [0.805, 1.4375, 2.53125],
    [1.4375, 0.805, 2.53125],
    [0.84, 1.5, 2.4],
    [1.5, 0.84, 2.4],
    [1.75, 0.0, 1.875],
    [1.75, -0.98, 1.875],
    [0.98, -1.75, 1.875],
    [0.0, -1.75, 1.875],
    [2.0, 0.0, 1.35],
    [2.0, -1.12, 1.35],
    [1.12, -2.0, 1.35],
    [0.0, -2.0, 1.35],
    [2.0, 0.0, 0.9],
    [2.0, -1.12, 0.9],
    [1.12, -2.0, 0.9],
    [0.0, -2.0, 0.9],
    [-0.98, -1.75, 1.875],
    [-1.75, -0.98, 1.875],
    [-1.75, 0.0, 1.875],
    [-1.12, -2.0, 1.35],
    [-2.0, -1.12, 1.35],
    [-2.0, 0.0, 1.35],
    [-1.12, -2.0, 0.9],
    [-2.0, -1.12, 0.9],
    [-2.0, 0.0, 0.9],
    [-1.75, 0.98, 1.875],
    [-0.98, 1.75, 1.875],
    [0.0, 1.75, 1.875],
    [-2.0, 1.12, 1.35],
    [-1.12, 2.0, 1.35],
    [0.0, 2.0, 1.35],
    [-2.0, 1.12, 0.9],
    [-1.12, 2.0, 0.9],
    [0.0, 2.0, 0.9],
    [0.98, 1.75, 1.875],
    [1.75, 0.98, 1.875],
    [1.12, 2.0, 1.35],
    [2.0, 1.12, 1.35],
    [1.12, 2.0, 0.9],
    [2.0, 1.12, 0.9],
    [2.0, 0.0, 0.45],
    [2.0, -1.12, 0.45],
    [1.12, -2.0, 0.45],
    [0.0, -2.0, 0.45],
    [1.5, 0.0, 0.225],
    [1.5, -0.84, 0.225],
    [0.84, -1.5, 0.225],
    [0.0, -1.5, 0.225],
    [1.5, 0.0, 0.15],
    [1.5, -0.84, 0.15],
    [0.84, -1.5, 0.15],
    [0.0, -1.5, 0.15],
    [-1.12, -2.0, 0.45],
    [-2.0, -1.12, 0.45],
    [-2.0, 0.0, 0.45],
    [-0.84, -1.5, 0.225],
    [-1.5, -0.84, 0.225],
    [-1.5, 0.0, 0.225],
    [-0.84, -1.5, 0.15],
    [-1.5, -0.84, 0.15],
    [-1.5, 0.0, 0.15],
    [-2.0, 1.12, 0.45],
    [-1.12, 2.0, 0.45],
    [0.0, 2.0, 0.45],
    [-1.5, 0.84, 0.225],
    [-0.84, 1.5, 0.225],
    [0.0, 1.5, 0.225],
    [-1.5, 0.84, 0.15],
    [-0.84, 1.5, 0.15],
    [0.0, 1.5, 0.15],
    [1.12, 2.0, 0.45],
    [2.0, 1.12, 0.45],
    [0.84, 1.5, 0.225],
    [1.5, 0.84, 0.225],
    [0.84, 1.5, 0.15],
    [1.5, 0.84, 0.15],
    [-1.6, 0.0, 2.025],
    [-1.6, -0.3, 2.025],
    [-1.5, -0.3, 2.25],
    [-1.5, 0.0, 2.25],
    [-2.3, 0.0, 2.025],
    [-2.3, -0.3, 2.025],
    [-2.5, -0.3, 2.25],
    [-2.5, 0.0, 2.25],
    [-2.7, 0.0, 2.025],
    [-2.7, -0.3, 2.025],
    [-3.0, -0.3, 2.25],
    [-3.0, 0.0, 2.25],
    [-2.7, 0.0, 1.8],
    [-2.7, -0.3, 1.8],
    [-3.0, -0.3, 1.8],
    [-3.0, 0.0, 1.8],
    [-1.5, 0.3, 2.25],
    [-1.6, 0.3, 2.025],
    [-2.5, 0.3, 2.25],
    [-2.3, 0.3, 2.025],
    [-3.0, 0.3, 2.25],
    [-2.7, 0.3, 2.025],
    [-3.0, 0.3, 1.8],
    [-2.7, 0.3, 1.8],
    [-2.7, 0.0, 1.575],
    [-2.7, -0.3, 1.575],
    [-3.0, -0.3, 1.35],
    [-3.0, 0.0, 1.35],
    [-2.5, 0.0, 1.125],
    [-2.5, -0.3, 1.125],
    [-2.65, -0.3, 0.9375],
    [-2.65, 0.0, 0.9375],
    [-2.0, -0.3, 0.9],
    [-1.9, -0.3, 0.6],
    [-1.9, 0.0, 0.6],
    [-3.0, 0.3, 1.35],
    [-2.7, 0.3, 1.575],
    [-2.65, 0.3, 0.9375],
    [-2.5, 0.3, 1.125],
    [-1.9, 0.3, 0.6],
    [-2.0, 0.3, 0.9],
    [1.7, 0.0, 1.425],
    [1.7, -0.66, 1.425],
    [1.7, -0.66, 0.6],
    [1.7, 0.0, 0.6],
    [2.6, 0.0, 1.425],
    [2.6, -0.66, 1.425],
    [3.1, -0.66, 0.825],
    [3.1, 0.0, 0.825],
    [2.3, 0.0, 2.1],
    [2.3, -0.25, 2.1],
    [2.4, -0.25, 2.025],
    [2.4, 0.0, 2.025],
    [2.7, 0.0, 2.4],
    [2.7, -0.25, 2.4],
    [3.3, -0.25, 2.4],
    [3.3, 0.0, 2.4],
    [1.7, 0.66, 0.6],
    [1.7, 0.66, 1.425],
    [3.1, 0.66, 0.825],
    [2.6, 0.66, 1.425],
    [2.4, 0.25, 2.025],
    [2.3, 0.25, 2.1],
    [3.3, 0.25, 2.4],
    [2.7, 0.25, 2.4],
    [2.8, 0.0, 2.475],
    [2.8, -0.25, 2.475],
    [3.525, -0.25, 2.49375],
    [3.525, 0.0, 2.49375],
    [2.9, 0.0, 2.475],
    [2.9, -0.15, 2.475],
    [3.45, -0.15, 2.5125],
    [3.45, 0.0, 2.5125],
    [2.8, 0.0, 2.4],
    [2.8, -0.15, 2.4],
    [3.2, -0.15, 2.4],
    [3.2, 0.0, 2.4],
    [3.525, 0.25, 2.49375],
    [2.8, 0.25, 2.475],
    [3.45, 0.15, 2.5125],
    [2.9, 0.15, 2.475],
    [3.2, 0.15, 2.4],
    [2.8, 0.15, 2.4],
    [0.0, 0.0, 3.15],
    [0.8, 0.0, 3.15],
    [0.8, -0.45, 3.15],
    [0.45, -0.8, 3.15],
    [0.0, -0.8, 3.15],
    [0.0, 0.0, 2.85],
    [0.2, 0.0, 2.7],
    [0.2, -0.112, 2.7],
    [0.112, -0.2, 2.7],
    [0.0, -0.2, 2.7],
    [-0.45, -0.8, 3.15],
    [-0.8, -0.45, 3.15],
    [-0.8, 0.0, 3.15],
    [-0.112, -0.2, 2.7],
    [-0.2, -0.112, 2.7],
    [-0.2, 0.0, 2.7],
    [-0.8, 0.45, 3.15],
    [-0.45, 0.8, 3.15],
    [0.0, 0.8, 3.15],
    [-0.2, 0.112, 2.7],
    [-0.112, 0.2, 2.7],
    [0.0, 0.2, 2.7],
    [0.45, 0.8, 3.15],
    [0.8, 0.45, 3.15],
    [0.112, 0.2, 2.7],
    [0.2, 0.112, 2.7],
    [0.4, 0.0, 2.55],
    [0.4, -0.224, 2.55],
    [0.224, -0.4, 2.55],
    [0.0, -0.4, 2.55],
    [1.3, 0.0, 2.55],
    [1.3, -0.728, 2.55],
    [0.728, -1.3, 2.55],
    [0.0, -1.3, 2.55],
    [1.3, 0.0, 2.4],
    [1.3, -0.728, 2.4],
    [0.728, -1.3, 2.4],
    [0.0, -1.3, 2.4],
    [-0.224, -0.4, 2.55],
    [-0.4, -0.224, 2.55],
    [-0.4, 0.0, 2.55],
    [-0.728, -1.3, 2.55],
    [-1.3, -0.728, 2.55],
    [-1.3, 0.0, 2.55],
    [-0.728, -1.3, 2.4],
    [-1.3, -0.728, 2.4],
    [-1.3, 0.0, 2.4],
    [-0.4, 0.224, 2.55],
    [-0.224, 0.4, 2.55],
    [0.0, 0.4, 2.55],
    [-1.3, 0.728, 2.55],
    [-0.728, 1.3, 2.55],
    [0.0, 1.3, 2.55],
    [-1.3, 0.728, 2.4],
    [-0.728, 1.3, 2.4],
    [0.0, 1.3, 2.4],
    [0.224, 0.4, 2.55],
    [0.4, 0.224, 2.55],
    [0.728, 1.3, 2.55],
    [1.3, 0.728, 2.55],
    [0.728, 1.3, 2.4],
    [1.3, 0.728, 2.4],
    [0.0, 0.0, 0.0],
    [1.425, 0.0, 0.0],
    [1.425, 0.798, 0.0],
    [0.798, 1.425, 0.0],
    [0.0, 1.425, 0.0],
    [1.5, 0.0, 0.075],
    [1.5, 0.84, 0.075],
    [0.84, 1.5, 0.075],
    [0.0, 1.5, 0.075],
    [-0.798, 1.425, 0.0],
    [-1.425, 0.798, 0.0],
    [-1.425, 0.0, 0.0],
    [-0.84, 1.5, 0.075],
    [-1.5, 0.84, 0.075],
    [-1.5, 0.0, 0.075],
    [-1.425, -0.798, 0.0],
    [-0.798, -1.425, 0.0],
    [0.0, -1.425, 0.0],
    [-1.5, -0.84, 0.075],
    [-0.84, -1.5, 0.075],
    [0.0, -1.5, 0.075],
    [0.798, -1.425, 0.0],
    [1.425, -0.798, 0.0],
    [0.84, -1.5, 0.075],
    [1.5, -0.84, 0.075],
];

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::spd::mat::testing::kinds;

    /// (patch triangles, plain triangles, squares)
    fn counts(s: &Scene) -> (usize, usize, usize) {
        let [_, _, tri, poly, pp] = kinds(s);
        (pp, tri, poly)
    }

    /// Vertex lists equal within f32 rounding.
    fn close(a: &[Vec3A], b: &[Vec3A]) -> bool {
        a.len() == b.len()
            && a.iter().zip(b).all(|(x, y)| {
                (*x - *y).abs().max_element() <= 1e-5 * y.abs().max_element().max(1.0)
            })
    }
    use crate::scene::Shape;
    use glam::Vec3A;

    #[test]
    fn counts_match_the_spec() {
        for (n, pp, squares) in [(1, 56, 1), (2, 240, 4), (6, 2256, 36), (12, 9120, 144)] {
            let scene = make(n);
            assert_eq!(scene.name, format!("teapot{n}"));
            assert_eq!(counts(&scene), (pp, 0, squares), "size {n}");
            let nn = n as usize;
            assert_eq!(64 * nn * nn - 8 * nn, pp);
            assert_eq!(scene.lights.len(), 2);
            assert_eq!(scene.materials.len(), 3);
        }
    }

    #[test]
    fn size_zero_is_empty() {
        let scene = make(0);
        assert_eq!(scene.name, "teapot0");
        assert!(scene.objects.is_empty());
    }

    #[test]
    fn order_and_materials() {
        let n = 6;
        let scene = make(n);
        let (white, grey) = (n * n / 2, n * n - n * n / 2);
        let mats: Vec<u32> = scene.objects.iter().map(|o| o.material).collect();
        assert!(mats[..white as usize].iter().all(|&m| m == 0));
        assert!(mats[white as usize..(white + grey) as usize]
            .iter()
            .all(|&m| m == 1));
        assert!(mats[(white + grey) as usize..].iter().all(|&m| m == 2));
        let m = &scene.materials;
        assert_eq!(m[0].color, Vec3A::ONE);
        assert_eq!(m[1].color, Vec3A::splat(0.5));
        assert_eq!(m[2].color, Vec3A::new(1.0, 0.5, 0.1));
        assert_eq!((m[2].kd, m[2].ks, m[2].t, m[2].ior), (0.75, 0.25, 0.0, 1.0));
        assert!((m[0].shine - 4.81884).abs() < 1e-4 && (m[2].shine - 3.0827).abs() < 1e-4);
        // First white square is (s, t) = (0, 1); first grey one is (0, 0).
        let Shape::Polygon(v) = &scene.objects[0].shape else {
            panic!()
        };
        let x = |k: f64| (4.0 * (2.0 * k / 6.0 - 1.0)) as f32;
        assert_eq!(v[0], Vec3A::new(-4.0, x(1.0), 0.0));
        assert_eq!(v[2], Vec3A::new(x(1.0), x(2.0), 0.0));
        let Shape::Polygon(v) = &scene.objects[white as usize].shape else {
            panic!()
        };
        assert_eq!(v[0], Vec3A::new(-4.0, -4.0, 0.0));
        assert_eq!(v[1], Vec3A::new(x(1.0), -4.0, 0.0));
    }

    #[test]
    fn normals_are_unit() {
        for n in [1, 2, 6, 12] {
            for o in &make(n).objects {
                if let Shape::Patch { normals, .. } = &o.shape {
                    for nv in normals {
                        assert!(nv.is_finite() && (nv.length() - 1.0).abs() < 1e-5, "{nv}");
                    }
                }
            }
        }
    }

    fn patches(scene: &Scene) -> Vec<(&[Vec3A], &[Vec3A])> {
        scene
            .objects
            .iter()
            .filter_map(|o| match &o.shape {
                Shape::Patch { verts, normals } => Some((&verts[..], &normals[..])),
                _ => None,
            })
            .collect()
    }

    #[test]
    fn patch_corners_interpolate_control_points() {
        // Size 1: each patch's triangles sit on its four corner control points.
        let scene = make(1);
        let p = patches(&scene);
        let v = |i: usize| Vec3A::from(DVec3::from(VERTS[i]).as_vec3());
        // Rim patch 0: A = (G00, G03, G33), B = (G33, G30, G00).
        assert!(close(p[0].0, &[v(0), v(3), v(15)]));
        assert!(close(p[1].0, &[v(15), v(12), v(0)]));
        // At this coarse size the first normal (at control point 0, s = t = 0) comes out
        // pointing inward and down, as the compiled C writes it (-0.902861 -0 -0.429934).
        let want = Vec3A::new(-0.902_860_5, 0.0, -0.429_933_58);
        assert!(close(&p[0].1[..1], &[want]));
        // Lid patch 20 loses triangle A; B = (212, 209, 203) with the knob normal up.
        let lid = 20 * 2;
        assert!(close(p[lid].0, &[v(212), v(209), v(203)]));
        assert_eq!(p[lid].1[2], Vec3A::Z);
        // Bottom patch 28 (after 4 lid patches with one triangle each): B only, normal down.
        let bottom = 28 * 2 - 4;
        assert!(close(p[bottom].0, &[v(113), v(92), v(265)]));
        assert_eq!(p[bottom].1[2], Vec3A::NEG_Z);
        assert_eq!(p.len(), bottom + 4);
    }

    #[test]
    fn normals_face_outward() {
        // Body patch 4 starts at control point 12, (1.5, 0, 2.4), where the normal points
        // away from the axis.
        let scene = make(2);
        let p = patches(&scene);
        let body = 4 * 8;
        let (v, nrm) = p[body];
        assert_eq!(v[0], Vec3A::new(1.5, 0.0, 2.4));
        assert!(nrm[0].x > 0.5 && nrm[0].y.abs() < 1e-6);
        // Every bottom centre normal points down and every lid knob normal up.
        for (v, nrm) in &p {
            for k in 0..3 {
                if v[k].x.abs() <= 1e-4 && v[k].y.abs() <= 1e-4 {
                    let want = if v[k].z > 1.5 { Vec3A::Z } else { Vec3A::NEG_Z };
                    assert_eq!(nrm[k], want);
                }
            }
        }
    }
}
