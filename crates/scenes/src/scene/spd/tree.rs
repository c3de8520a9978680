//! SPD `tree`: a binary tree after Aono and Kunii, built of cones with a sphere capping each
//! branch, standing on a green field. Size `n` gives `2^(n+1) - 1` cones and as many spheres.
//! SPD default size 11 (4095 of each).
//!
//! Branch frames are the SPD library's row-vector 4×4 matrices, multiplied with the same sums,
//! so the f64 results follow the C program's rounding.

use super::mat::{apply, mul, rotate_x, rotate_z, Mat, IDENTITY};
use super::{Spd, SKY};
use crate::scene::Scene;
use glam::DVec3;
use std::f64::consts::PI;

/// Branching angle of each child against its parent, degrees.
const BRANCH_ANGLE: [f64; 2] = [40.0, 25.0];
/// Turn of each child about its parent's axis, degrees.
const DIVERGENCE: [f64; 2] = [90.0, 140.0 + 90.0];
/// Length of each child relative to its parent.
const CONTRACTION: [f64; 2] = [0.65, 0.70];
/// Radius of a child relative to its parent, and of a branch's tip relative to its base.
const TAPER: f64 = 0.67;
/// Base radius of the trunk relative to its length.
const WIDTH: f64 = 0.15;

pub(crate) fn make(size: u32) -> Scene {
    let mut spd = Spd::new(format!("tree{size}"), SKY);
    spd.view(
        DVec3::new(4.5, 0.4, 2.0),
        DVec3::new(0.0, 0.0, 1.5),
        DVec3::Z,
        45.0,
        1.0,
        512,
    );
    for [x, y, z] in [
        [-5.0, 5.0, 50.0],
        [30.0, -30.0, 30.0],
        [-40.0, -30.0, 20.0],
        [10.0, 30.0, 40.0],
        [-30.0, 40.0, 10.0],
        [50.0, 25.0, 20.0],
        [-10.0, -60.0, 30.0],
    ] {
        spd.light(DVec3::new(x, y, z));
    }

    spd.material([0.2, 0.7, 0.2], 1.0, 0.0, 0.0, 0.0, 0.0);
    spd.polygon(&[
        DVec3::new(50.0, 50.0, 0.0),
        DVec3::new(-50.0, 50.0, 0.0),
        DVec3::new(-50.0, -50.0, 0.0),
        DVec3::new(50.0, -50.0, 0.0),
    ]);

    spd.material([0.55, 0.4, 0.2], 1.0, 0.0, 0.0, 0.0, 0.0);
    // A child's frame relative to its parent's: tilt, turn, shrink, then move to the
    // parent's tip at z = 1.
    let step: [Mat; 2] = std::array::from_fn(|i| {
        let turn = mul(
            &rotate_x(BRANCH_ANGLE[i] * PI / 180.0),
            &rotate_z(DIVERGENCE[i] * PI / 180.0),
        );
        let c = CONTRACTION[i];
        let shrink_and_lift = [
            [c, 0.0, 0.0, 0.0],
            [0.0, c, 0.0, 0.0],
            [0.0, 0.0, c, 0.0],
            [0.0, 0.0, 1.0, 1.0],
        ];
        mul(&turn, &shrink_and_lift)
    });
    grow(&mut spd, &step, &IDENTITY, 1.0, size);
    spd.finish()
}

/// Writes the branch whose frame is `frame` (a unit segment along +Z) with its tip sphere,
/// then, depth first, its two children.
fn grow(spd: &mut Spd, step: &[Mat; 2], frame: &Mat, scale: f64, depth: u32) {
    let base = apply(DVec3::ZERO, frame);
    let base_r = scale * WIDTH;
    let apex = apply(DVec3::Z, frame);
    let apex_r = base_r * TAPER;
    spd.cone(base, base_r, apex, apex_r);
    spd.sphere(apex, apex_r);
    if depth > 0 {
        for s in step {
            grow(spd, step, &mul(s, frame), scale * TAPER, depth - 1);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::spd::mat::testing::{close, close3, counts};
    use crate::scene::Shape;

    #[test]
    fn counts_match_the_c_program() {
        for (size, n) in [(0, 1), (1, 3), (11, 4095), (12, 8191)] {
            let s = make(size);
            assert_eq!(s.name, format!("tree{size}"));
            assert_eq!(counts(&s), [n, n, 1, 0], "size {size}");
        }
    }

    #[test]
    fn view_lights_field_and_materials() {
        let s = make(3);
        assert!(close3(s.camera.from, [4.5, 0.4, 2.0]));
        assert!(close3(s.camera.at, [0.0, 0.0, 1.5]));
        assert!(close3(s.camera.up, [0.0, 0.0, 1.0]));
        assert_eq!(
            (s.camera.angle, s.hither, s.resolution),
            (45.0, 1.0, [512, 512])
        );
        assert!(close3(s.background, SKY));
        let want = [
            [-5.0, 5.0, 50.0],
            [30.0, -30.0, 30.0],
            [-40.0, -30.0, 20.0],
            [10.0, 30.0, 40.0],
            [-30.0, 40.0, 10.0],
            [50.0, 25.0, 20.0],
            [-10.0, -60.0, 30.0],
        ];
        assert_eq!(s.lights.len(), 7);
        for (l, w) in s.lights.iter().zip(want) {
            assert!(close3(l.pos, w), "{:?}", l.pos);
        }

        let field = s.materials[s.objects[0].material as usize];
        assert!(close3(field.color, [0.2, 0.7, 0.2]));
        assert_eq!(
            (field.kd, field.ks, field.shine, field.t, field.ior),
            (1.0, 0.0, 1e5, 0.0, 1.0)
        );
        let Shape::Polygon(v) = &s.objects[0].shape else {
            panic!("field is not a 4-gon")
        };
        let want = [
            [50.0, 50.0, 0.0],
            [-50.0, 50.0, 0.0],
            [-50.0, -50.0, 0.0],
            [50.0, -50.0, 0.0],
        ];
        for (p, w) in v.iter().zip(want) {
            assert!(close3(*p, w), "{p:?}");
        }
        assert_eq!(s.materials.len(), 2);
        let wood = s.materials[s.objects[1].material as usize];
        assert!(close3(wood.color, [0.55, 0.4, 0.2]));
        assert_eq!(
            (wood.kd, wood.ks, wood.shine, wood.t, wood.ior),
            (1.0, 0.0, 1e5, 0.0, 1.0)
        );
        assert!(s.objects[1..]
            .iter()
            .all(|o| o.material == s.objects[1].material));
    }

    #[test]
    fn first_branches_match_the_c_output() {
        let s = make(11);
        let Shape::Cone(trunk) = &s.objects[1].shape else {
            panic!("trunk")
        };
        assert!(close3(trunk.base, [0.0; 3]) && close(trunk.base_radius, 0.15));
        assert!(close3(trunk.apex, [0.0, 0.0, 1.0]) && close(trunk.apex_radius, 0.1005));
        let Shape::Sphere(cap) = &s.objects[2].shape else {
            panic!("cap")
        };
        assert!(close3(cap.center, [0.0, 0.0, 1.0]) && close(cap.radius, 0.1005));
        // "c 0 0 1 0.1005 0.417812 -2.55836e-17 1.49793 0.067335"
        let Shape::Cone(b) = &s.objects[3].shape else {
            panic!("first branch")
        };
        assert!(close3(b.base, [0.0, 0.0, 1.0]) && close(b.base_radius, 0.1005));
        assert!(close3(b.apex, [0.417812, -2.55836e-17, 1.49793]));
        assert!(close(b.apex_radius, 0.067335));
        assert!(b.apex.y.abs() < 1e-15);
    }

    #[test]
    fn branches_are_pre_order_and_connected() {
        // Every branch starts at its parent's tip; in pre-order the parent of the branch at
        // index k (0-based, trunk first) is found by walking the implicit binary tree.
        let size = 4;
        let s = make(size);
        let cones: Vec<_> = s.objects[1..]
            .iter()
            .step_by(2)
            .map(|o| match &o.shape {
                Shape::Cone(c) => *c,
                other => panic!("expected a cone, got {other:?}"),
            })
            .collect();
        fn walk(idx: &mut usize, depth: u32, parent: Option<usize>, out: &mut Vec<Option<usize>>) {
            let me = *idx;
            out.push(parent);
            *idx += 1;
            if depth > 0 {
                walk(idx, depth - 1, Some(me), out);
                walk(idx, depth - 1, Some(me), out);
            }
        }
        let mut parents = Vec::new();
        walk(&mut 0, size, None, &mut parents);
        assert_eq!(parents.len(), cones.len());
        for (k, p) in parents.iter().enumerate() {
            if let Some(p) = *p {
                assert!((cones[k].base - cones[p].apex).length() < 1e-5, "{k}");
                assert!(close(
                    cones[k].base_radius,
                    f64::from(cones[p].base_radius) * TAPER
                ));
            }
        }
    }
}
