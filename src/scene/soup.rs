//! A seeded random triangle soup in the unit cube: `soupN` has N triangles of a size that
//! keeps their total area roughly independent of N. Seed fixed, so `soupN` is always the same.

use super::{Camera, Scene};
use crate::geometry::{Aabb, Triangle};
use crate::rng::Rng;
use glam::Vec3A;

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
        Camera::framing(&Aabb::new(Vec3A::ZERO, Vec3A::ONE)),
        vec![Vec3A::new(3.0, 4.0, 5.0)],
        Vec3A::splat(0.2),
    )
}
