//! Turning objects into triangles: polygons by ear clipping (concave ones included), patches
//! by fans, and spheres and cones into polygonal patches the way the SPD's patch mode does.

use super::Shape;
use crate::geometry::Triangle;
use crate::primitive::{Cone, Polygon, Sphere};
use glam::Vec3A;

/// Appends the triangles of one shape to `out`.
pub fn shape_triangles(shape: &Shape, out: &mut Vec<Triangle>) {
    match shape {
        Shape::Triangle(t) => out.push(*t),
        Shape::Polygon(v) => polygon_triangles(v, out),
        Shape::Patch { verts, .. } => polygon_triangles(verts, out),
        Shape::Sphere(s) => {
            for (verts, _) in sphere_patches(s, DEFAULT_RESOLUTION) {
                polygon_triangles(&verts, out);
            }
        }
        Shape::Cone(c) => {
            for (verts, _) in cone_patches(c, DEFAULT_RESOLUTION) {
                polygon_triangles(&verts, out);
            }
        }
    }
}

/// The SPD's default tessellation resolution for patch mode.
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

/// A sphere as polygonal patches (vertices, normals), placeholder until the SPD's exact
/// tessellation is in: `2 * res` longitude by `res` latitude bands.
pub fn sphere_patches(s: &Sphere, res: u32) -> Vec<(Vec<Vec3A>, Vec<Vec3A>)> {
    let (nu, nv) = (2 * res.max(2), res.max(2));
    let dir = |u: u32, v: u32| {
        let phi = std::f32::consts::TAU * u as f32 / nu as f32;
        let theta = std::f32::consts::PI * v as f32 / nv as f32;
        Vec3A::new(
            theta.sin() * phi.cos(),
            theta.sin() * phi.sin(),
            theta.cos(),
        )
    };
    let mut out = Vec::new();
    for v in 0..nv {
        for u in 0..nu {
            let n = [dir(u, v), dir(u + 1, v), dir(u + 1, v + 1), dir(u, v + 1)];
            let p = n.map(|d| s.center + d * s.radius);
            out.push((p.to_vec(), n.to_vec()));
        }
    }
    out
}

/// A cone as polygonal patches (placeholder like [`sphere_patches`]).
pub fn cone_patches(c: &Cone, res: u32) -> Vec<(Vec<Vec3A>, Vec<Vec3A>)> {
    let axis = (c.apex - c.base).normalize_or_zero();
    let u = axis.any_orthonormal_vector();
    let w = axis.cross(u);
    let n = 4 * res.max(1);
    let ring = |k: u32| {
        let a = std::f32::consts::TAU * k as f32 / n as f32;
        u * a.cos() + w * a.sin()
    };
    (0..n)
        .map(|k| {
            let (r0, r1) = (ring(k), ring(k + 1));
            let p = vec![
                c.base + r0 * c.base_radius,
                c.base + r1 * c.base_radius,
                c.apex + r1 * c.apex_radius,
                c.apex + r0 * c.apex_radius,
            ];
            (p, vec![r0, r1, r1, r0])
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn area(tris: &[Triangle]) -> f32 {
        tris.iter()
            .map(|t| (t.v[1] - t.v[0]).cross(t.v[2] - t.v[0]).length() * 0.5)
            .sum()
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
