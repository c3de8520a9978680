//! Point queries (`Bvh::closest_point`, `Bvh::point_query`, `World::closest_point`) against
//! the brute-force f64 `PointOracle`: every layout, points inside, outside, on vertices and
//! edges and far away, scenes at 1e-20 and 1e20 (built in a scaled frame), worlds under
//! rotation, non-uniform scale and shear (distances in world space), the distance cut-off,
//! the callback's "all within a radius", and bad inputs.

use crate::common::build;
use glam::{Affine3A, DVec3, Mat3, Quat, Vec3, Vec3A};
use quiver_lab::point_oracle::{closest_f64, points, PointOracle};
use quiver_rt::{
    Aabb, BuildOptions, Bvh, Instance, Layout, PrimHit, Primitive, Ray, Triangle, World,
};
use quiver_scenes::Scene;

fn wide(v: Vec3A) -> DVec3 {
    DVec3::new(v.x as f64, v.y as f64, v.z as f64)
}

/// `Bvh::closest_point` in `layout` over `tris` at `pts`, unlimited and cut off at a
/// fraction of the oracle's distance either side, judged by the oracle.
fn against_oracle(tris: &[Triangle], pts: &[Vec3A], layouts: &[Layout], what: &str) {
    let oracle = PointOracle::new(tris);
    for &layout in layouts {
        let bvh = build(tris, layout);
        for (k, &p) in pts.iter().enumerate() {
            let hit = bvh.closest_point(p, f32::INFINITY);
            assert!(hit.is_some(), "{what} {layout}: nothing at {p}");
            if let Err(e) = oracle.check_bvh(p, f32::INFINITY, hit.as_ref()) {
                panic!("{what} {layout}: {e}");
            }
            // The cut-off: a radius below the nearest finds nothing, one above finds it.
            let d = oracle.answer(p, f32::INFINITY).distance as f32;
            let max = d * [0.5, 0.9, 1.1, 2.0][k % 4];
            if let Err(e) = oracle.check_bvh(p, max, bvh.closest_point(p, max).as_ref()) {
                panic!("{what} {layout} max {max}: {e}");
            }
        }
    }
}

#[test]
fn every_layout_answers_as_the_oracle() {
    let soup = Scene::load("soup1000").unwrap().triangles();
    let pts = points(&soup, 120, 1000.0, 1);
    against_oracle(&soup, &pts, &Layout::ALL, "soup1000");
    let tetra = Scene::load("tetra3").unwrap().triangles();
    let pts = points(&tetra, 120, 50.0, 2);
    against_oracle(&tetra, &pts, &Layout::ALL, "tetra3");
}

#[test]
fn points_exactly_on_vertices_and_edges_are_at_distance_zero() {
    let tris = Scene::load("tetra3").unwrap().triangles();
    let oracle = PointOracle::new(&tris);
    for layout in [Layout::Bvh2Dfs, Layout::Bvh4Quant, Layout::Bvh8Dfs] {
        let bvh = build(&tris, layout);
        for t in tris.iter().step_by(7) {
            for p in [t.v[0], t.v[2], (t.v[0] + t.v[1]) * 0.5] {
                let hit = bvh.closest_point(p, 0.0);
                // The oracle says how near zero: its nearest is exactly on the triangle.
                let a = oracle.answer(p, 0.0);
                assert!(a.distance <= a.tolerance, "{p}: {a:?}");
                if let Err(e) = oracle.check_bvh(p, f32::INFINITY, hit.as_ref()) {
                    panic!("{layout}: {e}");
                }
            }
        }
    }
}

#[test]
fn scenes_at_1e_minus_20_and_1e20_answer_through_their_frame() {
    let soup = Scene::load("soup300").unwrap().triangles();
    for s in [1e-20f32, 1e20] {
        let tris: Vec<Triangle> = soup
            .iter()
            .map(|t| Triangle {
                v: t.v.map(|p| p * s),
            })
            .collect();
        let pts = points(&tris, 60, 100.0, 3);
        against_oracle(
            &tris,
            &pts,
            &[
                Layout::Bvh2Compact,
                Layout::Bvh4Dfs,
                Layout::Bvh4Quant,
                Layout::Bvh8Dfs,
            ],
            &format!("soup300 x {s:e}"),
        );
    }
}

/// A world of two geometries placed by rotated, non-uniformly scaled and sheared instances.
fn sheared_world() -> World {
    let soup = Scene::load("soup200").unwrap().triangles();
    let tetra = Scene::load("tetra2").unwrap().triangles();
    let mut b = World::builder();
    let g0 = b.add_triangles(soup);
    let g1 = b.add_triangles(tetra);
    let shear = |x: f32, z: f32| Mat3::from_cols(Vec3::X, Vec3::new(x, 1.0, z), Vec3::Z);
    let placements = [
        (g0, Affine3A::IDENTITY),
        (
            g0,
            Affine3A::from_mat3_translation(
                Mat3::from_quat(Quat::from_rotation_y(0.7))
                    * shear(0.6, -0.3)
                    * Mat3::from_diagonal(Vec3::new(5.0, 0.3, 1.0)),
                Vec3::new(2.0, 0.0, 0.5),
            ),
        ),
        (
            g1,
            Affine3A::from_scale_rotation_translation(
                Vec3::new(0.2, 3.0, 1.5),
                Quat::from_axis_angle(Vec3::new(1.0, 1.0, 0.0).normalize(), 1.1),
                Vec3::new(-1.5, 1.0, 0.0),
            ),
        ),
        (
            g1,
            Affine3A::from_mat3_translation(shear(-2.0, 0.8), Vec3::new(0.5, -2.0, 1.0)),
        ),
    ];
    for (g, m) in placements {
        b.add_instance(Instance::of(g).transform(m));
    }
    b.build(&BuildOptions::default()).unwrap()
}

#[test]
fn worlds_measure_in_world_space_under_scale_and_shear() {
    let world = sheared_world();
    let oracle = PointOracle::for_world(&world);
    // Points from the placed triangles (world-space vertices and edges) and around them.
    let mut placed = Vec::new();
    for inst in world.instances() {
        let quiver_rt::world::Geometry::Triangles(_, tris) =
            &world.geometries()[inst.geometry.0 as usize]
        else {
            unreachable!()
        };
        placed.extend(tris.iter().map(|t| Triangle {
            v: t.v.map(|p| inst.transform.transform_point3a(p)),
        }));
    }
    let pts = points(&placed, 300, 100.0, 4);
    let mut found_in_sheared = 0;
    for (k, &p) in pts.iter().enumerate() {
        let hit = world.closest_point(p, f32::INFINITY);
        if let Err(e) = oracle.check_world(p, f32::INFINITY, hit.as_ref()) {
            panic!("{e}");
        }
        found_in_sheared += usize::from(hit.is_some_and(|h| h.instance.0 != 0));
        let d = oracle.answer(p, f32::INFINITY).distance as f32;
        let max = d * [0.5, 0.95, 1.05, 3.0][k % 4];
        if let Err(e) = oracle.check_world(p, max, world.closest_point(p, max).as_ref()) {
            panic!("max {max}: {e}");
        }
    }
    assert!(
        found_in_sheared > 100,
        "the transformed instances are what is tested"
    );
}

#[test]
fn all_within_a_radius_is_every_primitive_the_oracle_puts_there() {
    let tris = Scene::load("soup500").unwrap().triangles();
    let oracle = PointOracle::new(&tris);
    let pts = points(&tris, 40, 3.0, 5);
    for layout in Layout::ALL {
        let bvh = build(&tris, layout);
        for (k, &p) in pts.iter().enumerate() {
            let r = [0.05f32, 0.2, 0.6][k % 3];
            let mut got = Vec::new();
            let finished = bvh.point_query(p, r, |i, radius| {
                assert_eq!(*radius, r, "an unshrunk radius comes back as it was");
                let (q, _, _) = tris[i as usize].closest_point(p);
                if q.distance(p) <= r {
                    got.push(i);
                }
                true
            });
            assert!(finished);
            let band = oracle.tolerance(r as f64);
            let pw = wide(p);
            for (i, t) in tris.iter().enumerate() {
                let d = (closest_f64(&t.v.map(wide), pw) - pw).length();
                let i = i as u32;
                if d < r as f64 - band {
                    assert!(got.contains(&i), "{layout} {p} r {r}: {i} at {d} missing");
                }
                if d > r as f64 + band {
                    assert!(
                        !got.contains(&i),
                        "{layout} {p} r {r}: {i} at {d} is not within"
                    );
                }
            }
            let mut sorted = got.clone();
            sorted.sort_unstable();
            sorted.dedup();
            // Binned SAH (the default) puts each primitive in one leaf.
            assert_eq!(sorted.len(), got.len(), "each primitive offered once");
        }
    }
}

/// A custom primitive: a sphere, measured by its own distance.
#[derive(Clone)]
struct Ball(Vec3A, f32);

impl Primitive for Ball {
    fn bounds(&self) -> Aabb {
        Aabb::new(self.0 - self.1, self.0 + self.1)
    }
    fn intersect(&self, _: &Ray) -> Option<PrimHit> {
        None
    }
}

#[test]
fn the_callback_finds_the_nearest_custom_primitive_in_every_layout() {
    let mut rng = quiver_scenes::rng::Rng::new(9);
    let balls: Vec<Ball> = (0..400)
        .map(|_| {
            Ball(
                rng.in_box(Vec3A::ZERO, Vec3A::splat(10.0)),
                rng.range(0.01, 0.3),
            )
        })
        .collect();
    // Surface distance in f64, by brute force.
    let dist = |b: &Ball, p: Vec3A| ((wide(p) - wide(b.0)).length() - b.1 as f64).max(0.0);
    for layout in Layout::ALL {
        let bvh = build(&balls, layout);
        for _ in 0..50 {
            let p = rng.in_box(Vec3A::splat(-2.0), Vec3A::splat(12.0));
            let mut best = (f64::INFINITY, u32::MAX);
            let mut visits = 0;
            bvh.point_query(p, f32::INFINITY, |i, r| {
                visits += 1;
                let d = dist(&balls[i as usize], p);
                if d < best.0 {
                    best = (d, i);
                    *r = (d as f32).next_up();
                }
                true
            });
            let want = balls
                .iter()
                .map(|b| dist(b, p))
                .fold(f64::INFINITY, f64::min);
            assert_eq!(best.0, want, "{layout} {p}");
            assert!(
                visits < balls.len() / 2,
                "{layout}: the shrinking radius prunes ({visits})"
            );
        }
        // Returning false stops the walk at once.
        let mut n = 0;
        assert!(!bvh.point_query(Vec3A::splat(5.0), f32::INFINITY, |_, _| {
            n += 1;
            false
        }));
        assert_eq!(n, 1);
    }
}

#[test]
fn nan_and_negative_inputs_answer_nothing() {
    let tris = Scene::load("soup100").unwrap().triangles();
    let world = sheared_world();
    for layout in [Layout::Bvh2Dfs, Layout::Bvh4Quant, Layout::Bvh8Dfs] {
        let bvh = build(&tris, layout);
        for (p, r) in [
            (Vec3A::new(f32::NAN, 0.0, 0.0), 1.0),
            (Vec3A::ZERO, f32::NAN),
            (Vec3A::ZERO, -1.0),
            (Vec3A::ZERO, f32::NEG_INFINITY),
            (Vec3A::new(0.0, f32::INFINITY, 0.0), f32::INFINITY),
        ] {
            assert_eq!(bvh.closest_point(p, r), None, "{layout} {p} {r}");
            assert_eq!(world.closest_point(p, r), None, "{p} {r}");
            assert!(bvh.point_query(p, r, |_, _| panic!("offered {p} {r}")));
        }
        // A radius of zero finds a point only on a triangle.
        assert_eq!(bvh.closest_point(Vec3A::splat(50.0), 0.0), None);
    }
    // Triangles with a NaN vertex are dropped by the build, and never answer.
    let mut with_nan = tris.clone();
    with_nan[3].v[1].x = f32::NAN;
    let bvh = Bvh::new(&with_nan);
    let oracle = PointOracle::new(&with_nan);
    for p in points(&tris, 50, 10.0, 6) {
        let hit = bvh.closest_point(p, f32::INFINITY);
        assert_ne!(hit.map(|h| h.prim), Some(3));
        oracle.check_bvh(p, f32::INFINITY, hit.as_ref()).unwrap();
    }
}

#[test]
fn spatial_splits_answer_as_the_oracle() {
    // The SBVH puts a primitive in several leaves: the walk meets it more than once.
    let tris = Scene::load("tetra3").unwrap().triangles();
    let oracle = PointOracle::new(&tris);
    let pts = points(&tris, 100, 20.0, 7);
    for layout in [Layout::Bvh2Dfs, Layout::Bvh4Quant, Layout::Bvh8Dfs] {
        let bvh = Bvh::build(&tris, &BuildOptions::high_quality().layout(layout)).unwrap();
        for &p in &pts {
            let hit = bvh.closest_point(p, f32::INFINITY);
            if let Err(e) = oracle.check_bvh(p, f32::INFINITY, hit.as_ref()) {
                panic!("sbvh {layout}: {e}");
            }
        }
    }
}
