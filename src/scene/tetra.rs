//! The SPD `tetra` scene (Haines): a tetrahedral Sierpinski pyramid after Glassner and
//! Kay & Kajiya. Size `n` gives 4^n triangles (4 for sizes 0 and 1).

use super::{Camera, Scene};
use crate::geometry::Triangle;
use glam::Vec3A;

/// Corners of the unit cube whose coordinate product is +1: a regular tetrahedron.
const CORNERS: [Vec3A; 4] = [
    Vec3A::new(-1.0, -1.0, 1.0),
    Vec3A::new(-1.0, 1.0, -1.0),
    Vec3A::new(1.0, -1.0, -1.0),
    Vec3A::new(1.0, 1.0, 1.0),
];

pub(super) fn tetra(size: u32) -> Scene {
    let mut tris = Vec::with_capacity(4usize.pow(size.max(1)));
    pyramid(size, Vec3A::ZERO, 1.0, &mut tris);
    Scene::from_triangles(
        format!("tetra{size}"),
        tris,
        Camera::new(
            Vec3A::new(1.022846, -3.177154, -2.174512),
            Vec3A::new(-0.004103, -0.004103, 0.216539),
            Vec3A::new(-0.816497, -0.816497, 0.816497),
            45.0,
        ),
        vec![Vec3A::new(2.0, -18.0, -5.0)],
        Vec3A::new(0.078, 0.361, 0.753),
    )
}

fn pyramid(depth: u32, center: Vec3A, half: f32, out: &mut Vec<Triangle>) {
    if depth <= 1 {
        let p = CORNERS.map(|c| center + c * half);
        // Faces use corners (f, f+1, f+2) mod 4, odd faces reversed, so all face outward the
        // same way the SPD program writes them.
        for f in 0..4 {
            let mut ord = [f, (f + 1) % 4, (f + 2) % 4];
            if f % 2 == 1 {
                ord.swap(0, 2);
            }
            out.push(Triangle::new(p[ord[0]], p[ord[1]], p[ord[2]]));
        }
    } else {
        for c in CORNERS {
            pyramid(depth - 1, center + c * (half * 0.5), half * 0.5, out);
        }
    }
}
