//! SPD `tetra`: a Sierpinski tetrahedron (after Glassner and Kay & Kajiya). Size `n` gives
//! `4^n` triangles (4 for size 0 and 1). SPD default size 6.

use super::{Spd, SKY};
use crate::scene::Scene;
use glam::DVec3;

/// The corner signs with product +1, in the SPD's loop order (x outer, then y, then z).
const SIGNS: [DVec3; 4] = [
    DVec3::new(-1.0, -1.0, 1.0),
    DVec3::new(-1.0, 1.0, -1.0),
    DVec3::new(1.0, -1.0, -1.0),
    DVec3::new(1.0, 1.0, 1.0),
];

pub(crate) fn make(size: u32) -> Scene {
    let mut spd = Spd::new(format!("tetra{size}"), SKY);
    spd.view(
        DVec3::new(1.022846, -3.177154, -2.174512),
        DVec3::new(-0.004103, -0.004103, 0.216539),
        DVec3::new(-0.816497, -0.816497, 0.816497),
        45.0,
        1.0,
        512,
    );
    spd.light(DVec3::new(2.0, -18.0, -5.0));
    spd.material([1.0, 0.2, 0.2], 1.0, 0.0, 0.0, 0.0, 0.0);
    tet(&mut spd, size, DVec3::ZERO, 1.0);
    spd.finish()
}

fn tet(spd: &mut Spd, depth: u32, c: DVec3, r: f64) {
    if depth <= 1 {
        let v = SIGNS.map(|s| c + s * r);
        // All four faces wind counter-clockwise seen from outside.
        for [a, b, d] in [[0, 1, 2], [3, 2, 1], [2, 3, 0], [1, 0, 3]] {
            spd.polygon(&[v[a], v[b], v[d]]);
        }
    } else {
        for s in SIGNS {
            tet(spd, depth - 1, c + s * (r / 2.0), r / 2.0);
        }
    }
}
