//! Turning objects into triangles: polygons by ear clipping (concave ones included), patches
//! by fans, and spheres and cones into polygonal patches the way the SPD's patch mode does.

use super::Shape;
use crate::primitive::{Cone, Polygon, Sphere};
use glam::{DVec3, Vec3A};
use quiver::geometry::Triangle;

/// Appends the triangles of one shape to `out`, and to `normals` the vertex normals of each
/// (patches, and spheres and cones through their SPD tessellation, at `DEFAULT_RESOLUTION`)
/// or `None` (flat polygons).
pub fn shape_triangles(
    shape: &Shape,
    out: &mut Vec<Triangle>,
    normals: &mut Vec<Option<[Vec3A; 3]>>,
) {
    let start = out.len();
    match shape {
        Shape::Triangle(t) => out.push(*t),
        Shape::Polygon(v) => polygon_triangles(v, out),
        Shape::Patch { verts, normals: n } => return patch_fan(verts, n, out, normals),
        Shape::Sphere(s) => {
            for (verts, n) in sphere_patches(s, DEFAULT_RESOLUTION) {
                patch_fan(&verts, &n, out, normals);
            }
            return;
        }
        Shape::Cone(c) => {
            for (verts, n) in cone_patches(c, DEFAULT_RESOLUTION) {
                patch_fan(&verts, &n, out, normals);
            }
            return;
        }
    }
    normals.resize(normals.len() + out.len() - start, None);
}

/// A patch (the SPD's are triangles) as a fan, keeping each vertex's normal.
fn patch_fan(
    verts: &[Vec3A],
    n: &[Vec3A],
    out: &mut Vec<Triangle>,
    normals: &mut Vec<Option<[Vec3A; 3]>>,
) {
    for k in 1..verts.len().saturating_sub(1) {
        out.push(Triangle::new(verts[0], verts[k], verts[k + 1]));
        normals.push(Some([n[0], n[k], n[k + 1]]));
    }
}

/// The default tessellation resolution for patch mode: 4, the value the SPD Readme states
/// and its poly/patch statistics use (the programs' own `OUTPUT_RESOLUTION` is 3).
pub const DEFAULT_RESOLUTION: u32 = 4;

/// Triangulates a planar polygon by ear clipping in its projection plane. Convex polygons
/// give a fan; collinear and repeated vertices are tolerated (degenerate ears are skipped when
/// possible, never looped on).
pub fn polygon_triangles(verts: &[Vec3A], out: &mut Vec<Triangle>) {
    match verts.len() {
        0..=2 => return,
        3 => {
            out.push(Triangle::new(verts[0], verts[1], verts[2]));
            return;
        }
        _ => {}
    }
    let poly = Polygon::new(verts.to_vec());
    let n = poly.normal();
    let m = n.abs();
    let (i, j) = if m.x >= m.y && m.x >= m.z {
        (1, 2)
    } else if m.y >= m.z {
        (2, 0)
    } else {
        (0, 1)
    };
    let p2 = |v: Vec3A| (v[i] as f64, v[j] as f64);
    // Orientation of the projected polygon: ears must turn the same way.
    let area: f64 = (0..verts.len())
        .map(|k| {
            let (a, b) = (p2(verts[k]), p2(verts[(k + 1) % verts.len()]));
            a.0 * b.1 - b.0 * a.1
        })
        .sum();
    let sign = if area >= 0.0 { 1.0 } else { -1.0 };
    let cross = |a: (f64, f64), b: (f64, f64), c: (f64, f64)| {
        (b.0 - a.0) * (c.1 - a.1) - (b.1 - a.1) * (c.0 - a.0)
    };
    let mut idx: Vec<usize> = (0..verts.len()).collect();
    while idx.len() > 3 {
        let k = idx.len();
        let ear = (0..k).find(|&e| {
            let (a, b, c) = (
                p2(verts[idx[(e + k - 1) % k]]),
                p2(verts[idx[e]]),
                p2(verts[idx[(e + 1) % k]]),
            );
            if cross(a, b, c) * sign <= 0.0 {
                return false;
            }
            // No other vertex inside (or on) the candidate ear.
            idx.iter().enumerate().all(|(q, &vi)| {
                if q == e || q == (e + k - 1) % k || q == (e + 1) % k {
                    return true;
                }
                let p = p2(verts[vi]);
                let (d1, d2, d3) = (
                    cross(a, b, p) * sign,
                    cross(b, c, p) * sign,
                    cross(c, a, p) * sign,
                );
                !(d1 >= 0.0 && d2 >= 0.0 && d3 >= 0.0)
            })
        });
        // Only degenerate remains (collinear runs): cut anywhere to finish.
        let e = ear.unwrap_or(0);
        out.push(Triangle::new(
            verts[idx[(e + k - 1) % k]],
            verts[idx[e]],
            verts[idx[(e + 1) % k]],
        ));
        idx.remove(e);
    }
    out.push(Triangle::new(verts[idx[0]], verts[idx[1]], verts[idx[2]]));
}

/// A sphere as the SPD's patch mode writes it (`lib_output_polygon_sphere`): the six faces of
/// a cube projected onto the sphere, each an `res × res` grid cut into two triangles per cell,
/// `12 res^2` triangles in all, counter-clockwise from outside, with the unit radial
/// direction as each vertex normal. Faces come in the order -X, -Y, -Z, +X, +Y, +Z.
pub fn sphere_patches(s: &Sphere, res: u32) -> Vec<(Vec<Vec3A>, Vec<Vec3A>)> {
    use std::f64::consts::FRAC_PI_4;
    let r = res.max(1) as usize;
    let angle = |e: usize| FRAC_PI_4 * (2.0 * e as f64 / r as f64 - 1.0);
    // The +Z face: crossing a meridian direction with a parallel direction.
    let mut grid: Vec<Vec<DVec3>> = (0..=r)
        .map(|u| {
            let a = angle(u);
            let xa = DVec3::new(a.cos(), 0.0, -a.sin());
            (0..=r)
                .map(|v| {
                    let b = angle(v);
                    xa.cross(DVec3::new(0.0, b.cos(), b.sin())).normalize()
                })
                .collect()
        })
        .collect();
    let center = DVec3::new(s.center.x as f64, s.center.y as f64, s.center.z as f64);
    let radius = s.radius as f64;
    let f = |p: DVec3| Vec3A::new(p.x as f32, p.y as f32, p.z as f32);
    let mut out = Vec::with_capacity(12 * r * r);
    for face in 0..6 {
        // Each face is the previous one turned by a quarter about the next axis.
        for p in grid.iter_mut().flatten() {
            *p = match (face + 2) % 3 {
                0 => DVec3::new(-p.y, p.x, p.z),
                1 => DVec3::new(p.x, -p.z, p.y),
                _ => DVec3::new(-p.z, p.y, p.x),
            };
        }
        for u in 0..r {
            for v in 0..r {
                let q = [
                    grid[u][v],
                    grid[u][v + 1],
                    grid[u + 1][v + 1],
                    grid[u + 1][v],
                ];
                for tri in [[q[0], q[1], q[2]], [q[2], q[3], q[0]]] {
                    out.push((
                        tri.iter().map(|&n| f(center + n * radius)).collect(),
                        tri.iter().map(|&n| f(n)).collect(),
                    ));
                }
            }
        }
    }
    out
}

/// A cone or cylinder as the SPD's patch mode writes it (`lib_output_polygon_cylcone`): `4 res`
/// segments around the axis, two triangles each (`8 res` in all), facing outward, with normals
/// that lean by the cone's slope.
pub fn cone_patches(c: &Cone, res: u32) -> Vec<(Vec<Vec3A>, Vec<Vec3A>)> {
    let d = |v: Vec3A| DVec3::new(v.x as f64, v.y as f64, v.z as f64);
    let f = |p: DVec3| Vec3A::new(p.x as f32, p.y as f32, p.z as f32);
    let (base, apex) = (d(c.base), d(c.apex));
    let (br, ar) = (c.base_radius as f64, c.apex_radius as f64);
    let axis = apex - base;
    let h = axis.length();
    if h == 0.0 {
        return Vec::new();
    }
    let na = axis / h;
    let side = axis.cross(DVec3::Z);
    let sd = if side.length() < 1e-6 {
        axis.cross(DVec3::X).normalize()
    } else {
        side.normalize()
    };
    let (r0, r1) = (sd * br, sd * ar);
    let sn = if br == ar {
        sd
    } else {
        (sd * h + na * (br - ar)).normalize()
    };
    let n = 4 * res.max(1) as usize;
    let step = std::f64::consts::TAU / n as f64;
    let (mut b_prev, mut a_prev, mut n_prev) = (base + r0, apex + r1, sn);
    let mut theta = 0.0;
    let mut out = Vec::with_capacity(2 * n);
    for _ in 0..n {
        // The angle accumulates by repeated addition, as the SPD library does.
        theta += step;
        let (a_i, b_i, n_i) = (
            apex + rotate(r1, na, theta),
            base + rotate(r0, na, theta),
            rotate(sn, na, theta),
        );
        out.push((
            vec![f(a_i), f(a_prev), f(b_prev)],
            vec![f(n_i), f(n_prev), f(n_prev)],
        ));
        out.push((
            vec![f(b_i), f(a_i), f(b_prev)],
            vec![f(n_i), f(n_i), f(n_prev)],
        ));
        (a_prev, b_prev, n_prev) = (a_i, b_i, n_i);
    }
    out
}

/// Right-handed rotation of `p` about unit axis `u` by `a` radians (Rodrigues' formula).
pub(crate) fn rotate(p: DVec3, u: DVec3, a: f64) -> DVec3 {
    let (s, c) = a.sin_cos();
    p * c + u.cross(p) * s + u * u.dot(p) * (1.0 - c)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn area(tris: &[Triangle]) -> f32 {
        tris.iter()
            .map(|t| (t.v[1] - t.v[0]).cross(t.v[2] - t.v[0]).length() * 0.5)
            .sum()
    }

    /// Every vertex on the surface, every normal radial, outward winding, 12 r^2 triangles.
    #[test]
    fn sphere_patches_lie_on_the_sphere_and_face_out() {
        let s = Sphere {
            center: Vec3A::new(1.0, 2.0, 3.0),
            radius: 2.0,
        };
        for res in [1, 3, 4] {
            let p = sphere_patches(&s, res);
            assert_eq!(p.len(), 12 * (res * res) as usize);
            for (v, n) in &p {
                for (x, nx) in v.iter().zip(n) {
                    assert!(((*x - s.center).length() - 2.0).abs() < 1e-5);
                    assert!((*nx - (*x - s.center) / 2.0).length() < 1e-5);
                }
                let face = (v[1] - v[0]).cross(v[2] - v[0]);
                assert!(face.dot(v[0] - s.center) > 0.0, "winding");
            }
        }
        // Resolution 1 gives the cube's corners.
        let corner = 1.0 / 3f32.sqrt();
        for (_, n) in sphere_patches(&s, 1) {
            assert!(n
                .iter()
                .all(|x| (x.abs() - Vec3A::splat(corner)).abs().max_element() < 1e-6));
        }
    }

    #[test]
    fn cone_patches_lie_on_the_cone_and_face_out() {
        let c = Cone {
            base: Vec3A::ZERO,
            base_radius: 2.0,
            apex: Vec3A::new(0.0, 0.0, 2.0),
            apex_radius: 1.0,
        };
        for res in [1, 3, 4] {
            let p = cone_patches(&c, res);
            assert_eq!(p.len(), 8 * res as usize);
            for (v, _) in &p {
                for x in v {
                    let r = (x.x * x.x + x.y * x.y).sqrt();
                    assert!((r - (2.0 - x.z / 2.0)).abs() < 1e-5, "{x}");
                }
                let face = (v[1] - v[0]).cross(v[2] - v[0]);
                let out = Vec3A::new(v[0].x, v[0].y, 0.0);
                assert!(face.dot(out) > 0.0, "winding");
            }
        }
    }

    #[test]
    fn ear_clipping_covers_a_concave_polygon_exactly() {
        // A U shape of area 3*3 - 1*2 = 7, in both orientations.
        let mut u: Vec<Vec3A> = [
            [0.0, 0.0],
            [3.0, 0.0],
            [3.0, 3.0],
            [2.0, 3.0],
            [2.0, 1.0],
            [1.0, 1.0],
            [1.0, 3.0],
            [0.0, 3.0],
        ]
        .iter()
        .map(|&[x, y]| Vec3A::new(x, 1.0, y))
        .collect();
        for _ in 0..2 {
            let mut tris = Vec::new();
            polygon_triangles(&u, &mut tris);
            assert_eq!(tris.len(), u.len() - 2);
            assert!((area(&tris) - 7.0).abs() < 1e-5, "area {}", area(&tris));
            u.reverse();
        }
    }
}
