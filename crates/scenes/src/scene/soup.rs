//! Synthetic test geometry: a seeded random triangle soup, and a closed icosphere.
//!
//! The soup lives in the unit cube: `soupN` has N triangles of a size that
//! keeps their total area roughly independent of N. Seed fixed, so `soupN` is always the same.

use super::{Camera, Scene};
use crate::rng::Rng;
use glam::Vec3A;
use quiver_rt::geometry::{Aabb, Triangle};

pub(super) fn soup(n: u32) -> Scene {
    let mut rng = Rng::new(0x5EED_0000 ^ n as u64);
    let edge = 2.0 / (n.max(1) as f32).cbrt();
    let tris: Vec<Triangle> = (0..n)
        .map(|_| {
            let c = rng.in_box(Vec3A::ZERO, Vec3A::ONE);
            let mut v = || c + rng.in_box(Vec3A::splat(-edge), Vec3A::splat(edge)) * 0.5;
            Triangle::new(v(), v(), v())
        })
        .collect();
    Scene::from_triangles(
        format!("soup{n}"),
        tris,
        Camera::framing(&Aabb::new(Vec3A::ZERO, Vec3A::ONE))
            .expect("the unit cube is framed at any scale"),
        vec![Vec3A::new(3.0, 4.0, 5.0)],
        Vec3A::splat(0.2),
    )
}

/// An icosahedron subdivided `n` times onto the unit sphere: a closed mesh in which every edge
/// is shared by two triangles with bit-identical vertices (midpoints are computed from the two
/// endpoints in a fixed order), the test object for watertightness.
pub(super) fn icosphere(n: u32) -> Scene {
    let t = (1.0 + 5f32.sqrt()) / 2.0;
    let v: Vec<Vec3A> = [
        [-1.0, t, 0.0],
        [1.0, t, 0.0],
        [-1.0, -t, 0.0],
        [1.0, -t, 0.0],
        [0.0, -1.0, t],
        [0.0, 1.0, t],
        [0.0, -1.0, -t],
        [0.0, 1.0, -t],
        [t, 0.0, -1.0],
        [t, 0.0, 1.0],
        [-t, 0.0, -1.0],
        [-t, 0.0, 1.0],
    ]
    .iter()
    .map(|p| Vec3A::from(*p).normalize())
    .collect();
    const FACES: [[usize; 3]; 20] = [
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    let mut tris: Vec<[Vec3A; 3]> = FACES.iter().map(|f| [v[f[0]], v[f[1]], v[f[2]]]).collect();
    let mid = |a: Vec3A, b: Vec3A| {
        let (p, q) = if a.to_array() < b.to_array() {
            (a, b)
        } else {
            (b, a)
        };
        ((p + q) * 0.5).normalize()
    };
    for _ in 0..n {
        tris = tris
            .iter()
            .flat_map(|&[a, b, c]| {
                let (ab, bc, ca) = (mid(a, b), mid(b, c), mid(c, a));
                [[a, ab, ca], [ab, b, bc], [ca, bc, c], [ab, bc, ca]]
            })
            .collect();
    }
    Scene::from_triangles(
        format!("icosphere{n}"),
        tris.into_iter()
            .map(|[a, b, c]| Triangle::new(a, b, c))
            .collect(),
        Camera::new(Vec3A::new(0.0, 0.0, 4.0), Vec3A::ZERO, Vec3A::Y, 45.0),
        vec![Vec3A::new(3.0, 4.0, 5.0)],
        Vec3A::splat(0.2),
    )
}
