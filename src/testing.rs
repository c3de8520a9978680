//! Test inputs for the core's unit tests, which cannot use the scene generators (they live in
//! quiver-scenes, which depends on this crate).

use crate::geometry::{Aabb, Triangle};
use crate::rng::Rng;
use glam::Vec3A;

/// `n` random triangles of varied size in the unit cube, from `seed`.
pub(crate) fn soup(n: usize, seed: u64) -> Vec<Triangle> {
    let mut rng = Rng::new(seed);
    (0..n)
        .map(|i| {
            let c = rng.in_box(Vec3A::ZERO, Vec3A::ONE);
            // Sizes spread over two orders of magnitude, so the tree is not uniform.
            let edge = 0.002 * (1 + i % 100) as f32;
            let mut v = || c + rng.in_box(Vec3A::splat(-edge), Vec3A::splat(edge));
            Triangle::new(v(), v(), v())
        })
        .collect()
}

/// The bounds of [`soup`]`(n, seed)`.
pub(crate) fn soup_bounds(n: usize, seed: u64) -> Vec<Aabb> {
    soup(n, seed).iter().map(|t| t.bounds()).collect()
}
