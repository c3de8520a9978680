//! The SPD library's 4×4 matrices for row vectors (`p' = p·M`), with its element formulas, so
//! generators that transform points round exactly as the C programs do.

use glam::DVec3;

/// A 4×4 matrix acting on row vectors; row 3 holds the translation.
pub(crate) type Mat = [[f64; 4]; 4];

/// The identity.
pub(crate) const IDENTITY: Mat = [
    [1.0, 0.0, 0.0, 0.0],
    [0.0, 1.0, 0.0, 0.0],
    [0.0, 0.0, 1.0, 0.0],
    [0.0, 0.0, 0.0, 1.0],
];

/// `p·M` for a point (implicit fourth coordinate 1).
pub(crate) fn apply(p: DVec3, m: &Mat) -> DVec3 {
    let col = |j: usize| p.x * m[0][j] + p.y * m[1][j] + p.z * m[2][j] + m[3][j];
    DVec3::new(col(0), col(1), col(2))
}

/// `A·B`: apply A first, then B.
pub(crate) fn mul(a: &Mat, b: &Mat) -> Mat {
    std::array::from_fn(|i| {
        std::array::from_fn(|j| {
            a[i][0] * b[0][j] + a[i][1] * b[1][j] + a[i][2] * b[2][j] + a[i][3] * b[3][j]
        })
    })
}

/// Right-handed rotation by `a` radians about X.
pub(crate) fn rotate_x(a: f64) -> Mat {
    let (s, c) = (a.sin(), a.cos());
    let mut m = IDENTITY;
    (m[1][1], m[2][2], m[1][2], m[2][1]) = (c, c, s, -s);
    m
}

/// Right-handed rotation by `a` radians about Y.
pub(crate) fn rotate_y(a: f64) -> Mat {
    let (s, c) = (a.sin(), a.cos());
    let mut m = IDENTITY;
    (m[0][0], m[2][2], m[2][0], m[0][2]) = (c, c, s, -s);
    m
}

/// Right-handed rotation by `a` radians about Z.
pub(crate) fn rotate_z(a: f64) -> Mat {
    let (s, c) = (a.sin(), a.cos());
    let mut m = IDENTITY;
    (m[0][0], m[1][1], m[0][1], m[1][0]) = (c, c, s, -s);
    m
}

/// Right-handed rotation by `a` radians about the unit axis `u`.
pub(crate) fn axis_rotation(u: DVec3, a: f64) -> Mat {
    let (s, c) = (a.sin(), a.cos());
    let t = 1.0 - c;
    [
        [
            u.x * u.x + (1.0 - u.x * u.x) * c,
            u.x * u.y * t + u.z * s,
            u.x * u.z * t - u.y * s,
            0.0,
        ],
        [
            u.x * u.y * t - u.z * s,
            u.y * u.y + (1.0 - u.y * u.y) * c,
            u.y * u.z * t + u.x * s,
            0.0,
        ],
        [
            u.x * u.z * t + u.y * s,
            u.y * u.z * t - u.x * s,
            u.z * u.z + (1.0 - u.z * u.z) * c,
            0.0,
        ],
        [0.0, 0.0, 0.0, 1.0],
    ]
}

/// `v / |v|`, dividing each component as the C does (a zero vector stays zero).
pub(crate) fn unit(v: DVec3) -> DVec3 {
    let len = (v.x * v.x + v.y * v.y + v.z * v.z).sqrt();
    if len > 0.0 {
        DVec3::new(v.x / len, v.y / len, v.z / len)
    } else {
        v
    }
}

/// Shared helpers for the generators' tests.
#[cfg(test)]
pub(crate) mod testing {
    use crate::scene::{Scene, Shape};
    use glam::Vec3A;

    /// An f32 stored value against the f64 the C computed.
    pub fn close(a: f32, b: f64) -> bool {
        (f64::from(a) - b).abs() <= 1e-5 * b.abs().max(1.0)
    }

    /// [`close`] per component.
    pub fn close3(a: Vec3A, b: [f64; 3]) -> bool {
        close(a.x, b[0]) && close(a.y, b[1]) && close(a.z, b[2])
    }

    /// (spheres, cones, triangles, other polygons, patches)
    pub fn kinds(s: &Scene) -> [usize; 5] {
        let mut n = [0; 5];
        for o in &s.objects {
            n[match o.shape {
                Shape::Sphere(_) => 0,
                Shape::Cone(_) => 1,
                Shape::Triangle(_) => 2,
                Shape::Polygon(_) => 3,
                Shape::Patch { .. } => 4,
            }] += 1;
        }
        n
    }

    /// The vertices of object `i`, which must be a triangle.
    pub fn tri(s: &Scene, i: usize) -> [Vec3A; 3] {
        match &s.objects[i].shape {
            Shape::Triangle(t) => t.v,
            other => panic!("object {i} is not a triangle: {other:?}"),
        }
    }

    /// (spheres, cones, polygons, patches)
    pub fn counts(s: &Scene) -> [usize; 4] {
        let mut n = [0; 4];
        for o in &s.objects {
            n[match o.shape {
                Shape::Sphere(_) => 0,
                Shape::Cone(_) => 1,
                Shape::Triangle(_) | Shape::Polygon(_) => 2,
                Shape::Patch { .. } => 3,
            }] += 1;
        }
        n
    }
}
