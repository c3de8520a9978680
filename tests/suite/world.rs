//! Worlds of instances against the same scene flattened to world-space triangles, judged by
//! the independent f64 oracle: the instance, geometry and primitive of every decidable ray,
//! `t` within the bands widened by the transforms' rounding; masks and filters against the
//! flattened scene with the masked or rejected triangles left out; every layout and
//! instruction set, single rays and packets; errors for bad input, never panics.

use glam::{Affine3A, Quat, Vec3, Vec3A};
use quiver_lab::oracle::Oracle;
use quiver_lab::rays::random_rays;
use quiver_rt::traverse::{reference, ConservativeBoxes, NoStats, PacketMode, PacketQuery};
use quiver_rt::{
    Aabb, BuildOptions, GeometryId, Hit, Instance, InstanceId, Isa, Layout, Ray, RayQuery,
    Triangle, World, WorldError, WorldHit,
};
use quiver_scenes::rng::Rng;
use quiver_scenes::Scene;

use quiver_lab::worlds::{check, Placements as Setup};

/// The triangles of `scene`.
fn tris(scene: &str) -> Vec<Triangle> {
    Scene::load(scene).unwrap().triangles()
}

/// Three geometries (a soup, a closed sphere, a tetrahedron fractal) placed 40 times: one at
/// the identity, the others rotated, scaled unevenly (some mirrored) and moved, with masks
/// from a small set.
pub(crate) fn setup(seed: u64) -> Setup {
    let geometries = vec![tris("soup300"), tris("icosphere2"), tris("tetra3")];
    let mut rng = Rng::new(seed);
    let mut instances = vec![Instance::of(GeometryId(0))];
    for i in 1..40u32 {
        let axis = Vec3::from(rng.in_box(Vec3A::splat(-1.0), Vec3A::ONE)).normalize_or(Vec3::Z);
        let angle = rng
            .in_box(Vec3A::ZERO, Vec3A::splat(std::f32::consts::TAU))
            .x;
        let mut scale = Vec3::from(rng.in_box(Vec3A::splat(0.4), Vec3A::splat(1.6)));
        if i % 7 == 0 {
            scale.x = -scale.x;
        }
        let at = Vec3::from(rng.in_box(Vec3A::splat(-4.0), Vec3A::splat(4.0)));
        let transform = Affine3A::from_scale_rotation_translation(
            scale,
            Quat::from_axis_angle(axis, angle),
            at,
        );
        instances.push(
            Instance::of(GeometryId(i % 3))
                .transform(transform)
                .mask([0b01, 0b10, 0b11, u32::MAX][i as usize % 4])
                .user_id(1000 + i),
        );
    }
    Setup {
        geometries,
        instances,
    }
}

#[test]
fn instanced_worlds_answer_what_the_flattened_scene_answers() {
    let s = setup(11);
    let rays = s.rays(1500, 3);
    let (flat, names) = s.flattened(|_, _| true);
    let oracle = Oracle::with_slack(&flat, s.slack());
    let answers = oracle.closest_hits(&rays);
    let decidable = answers.iter().filter(|a| a.is_decidable()).count();
    let hits = answers
        .iter()
        .filter(|a| a.is_decidable() && a.hit.is_some())
        .count();
    assert!(
        decidable > rays.len() * 9 / 10,
        "{decidable} of {} decidable",
        rays.len()
    );
    assert!(hits > rays.len() / 4, "{hits} decidable hits");
    for layout in Layout::ALL {
        for isa in Isa::ALL {
            let world = s.world(&BuildOptions::default().layout(layout).isa(isa));
            let mut hits = vec![None; rays.len()];
            let mut occluded = vec![false; rays.len()];
            for mode in [PacketMode::Always, PacketMode::Never, PacketMode::Auto] {
                let q = PacketQuery::new(&rays).mode(mode);
                world.closest_hit_packet_with::<ConservativeBoxes, _, _>(
                    q,
                    &mut hits,
                    &mut NoStats,
                    &mut quiver_rt::traverse::NoFilter,
                );
                world.any_hit_packet_with::<ConservativeBoxes, _, _>(
                    q,
                    &mut occluded,
                    &mut NoStats,
                    &mut quiver_rt::traverse::NoFilter,
                );
                for (i, r) in rays.iter().enumerate() {
                    let single = world.closest_hit(r);
                    let at = || format!("{layout} {isa} {mode:?} ray {i}: {r:?}");
                    assert_eq!(hits[i], single, "{} packet against single ray", at());
                    assert_eq!(occluded[i], world.any_hit(r), "{} any packet", at());
                    assert_eq!(
                        world.any_hit(r),
                        single.is_some(),
                        "{} any against closest",
                        at()
                    );
                    if let Err(e) = check(&answers[i], single, &names) {
                        panic!("{}: {e}", at());
                    }
                }
            }
        }
    }
}

#[test]
fn masks_hide_instances_as_if_they_were_not_there() {
    let s = setup(12);
    let base = s.rays(800, 5);
    let world = s.world(&BuildOptions::default());
    for ray_mask in [0b01u32, 0b10, 0b100, u32::MAX] {
        let rays: Vec<Ray> = base.iter().map(|r| r.with_mask(ray_mask)).collect();
        let (flat, names) = s.flattened(|i, _| s.instances[i as usize].mask & ray_mask != 0);
        let answers = Oracle::with_slack(&flat, s.slack()).closest_hits(&rays);
        let mut hits = vec![None; rays.len()];
        let q = PacketQuery::new(&rays).mode(PacketMode::Always);
        world.closest_hit_packet_with::<ConservativeBoxes, _, _>(
            q,
            &mut hits,
            &mut NoStats,
            &mut quiver_rt::traverse::NoFilter,
        );
        for (i, r) in rays.iter().enumerate() {
            let got = world.closest_hit(r);
            assert_eq!(hits[i], got, "mask {ray_mask:b} ray {i}: packet");
            check(&answers[i], got, &names)
                .unwrap_or_else(|e| panic!("mask {ray_mask:b} ray {i}: {e}"));
            if let Some(h) = got {
                assert_ne!(s.instances[h.instance.0 as usize].mask & ray_mask, 0);
            }
        }
    }
    // Mixed masks in one packet: each ray sees its own instances.
    let mixed: Vec<Ray> = base
        .iter()
        .enumerate()
        .map(|(i, r)| r.with_mask([0b01, 0b10, u32::MAX, 0][i % 4]))
        .collect();
    let mut hits = vec![None; mixed.len()];
    let q = PacketQuery::new(&mixed).mode(PacketMode::Always);
    world.closest_hit_packet_with::<ConservativeBoxes, _, _>(
        q,
        &mut hits,
        &mut NoStats,
        &mut quiver_rt::traverse::NoFilter,
    );
    for (i, r) in mixed.iter().enumerate() {
        assert_eq!(hits[i], world.closest_hit(r), "mixed masks ray {i}");
    }
    assert!(mixed.iter().skip(3).step_by(4).all(|r| r.mask == 0));
    assert!(mixed
        .iter()
        .filter(|r| r.mask == 0)
        .all(|r| world.closest_hit(r).is_none()));
}

#[test]
fn filters_skip_rejected_candidates_as_if_those_triangles_were_not_there() {
    let s = setup(13);
    let rays = s.rays(800, 7);
    let reject = |instance: u32, prim: u32| (instance + prim).is_multiple_of(4);
    let (flat, names) = s.flattened(|i, j| !reject(i, j));
    let answers = Oracle::with_slack(&flat, s.slack()).closest_hits(&rays);
    let mut asked = 0;
    for layout in [Layout::Bvh8Dfs, Layout::Bvh2Dfs, Layout::Bvh4Quant] {
        let world = s.world(&BuildOptions::default().layout(layout));
        let keep = |h: &WorldHit| !reject(h.instance.0, h.prim);
        let mut hits = vec![None; rays.len()];
        let mut occluded = vec![false; rays.len()];
        let mut counted = |h: &WorldHit| {
            asked += 1;
            keep(h)
        };
        let q = PacketQuery::new(&rays).mode(PacketMode::Always);
        world.closest_hit_packet_with::<ConservativeBoxes, _, _>(
            q,
            &mut hits,
            &mut NoStats,
            &mut counted,
        );
        world.any_hit_packet_with::<ConservativeBoxes, _, _>(
            q,
            &mut occluded,
            &mut NoStats,
            &mut keep.clone(),
        );
        for (i, r) in rays.iter().enumerate() {
            let got = world.closest_hit_filtered(r, keep);
            assert_eq!(hits[i], got, "{layout} ray {i}: packet");
            assert_eq!(occluded[i], got.is_some(), "{layout} ray {i}: any packet");
            assert_eq!(
                world.any_hit_filtered(r, keep),
                got.is_some(),
                "{layout} ray {i}: any"
            );
            check(&answers[i], got, &names).unwrap_or_else(|e| panic!("{layout} ray {i}: {e}"));
        }
    }
    assert!(asked > 0);
}

#[test]
fn normals_are_the_flattened_triangles_normals() {
    let s = setup(14);
    let world = s.world(&BuildOptions::default());
    let (flat, names) = s.flattened(|_, _| true);
    let mut checked = 0;
    for r in s.rays(400, 9) {
        let Some(h) = world.closest_hit(&r) else {
            continue;
        };
        let k = names
            .iter()
            .position(|&n| n == (h.instance.0, h.geometry.0, h.prim))
            .unwrap();
        let t = &flat[k];
        let want = (t.v[1] - t.v[0]).cross(t.v[2] - t.v[0]).normalize();
        let got = world.normal(&r, &h).unwrap();
        assert!(got.dot(want) > 0.999, "{got} against {want}");
        checked += 1;
    }
    assert!(checked > 100);
}

#[test]
fn bad_worlds_are_errors_and_odd_ones_answer_right() {
    let tri = Triangle::new(Vec3A::ZERO, Vec3A::X, Vec3A::Y);
    let options = BuildOptions::default();
    let one = |inst: Instance| {
        let mut b = World::builder();
        b.add_triangles(vec![tri]);
        b.add_instance(inst);
        b.build(&options)
    };
    let g = GeometryId(0);
    assert_eq!(
        one(Instance::of(GeometryId(3))).unwrap_err(),
        WorldError::Geometry {
            instance: 0,
            geometry: 3,
            geometries: 1
        }
    );
    for (m, why) in [
        (
            Affine3A::from_scale(Vec3::new(1.0, 0.0, 1.0)),
            "not invertible",
        ),
        (
            Affine3A::from_translation(Vec3::new(f32::NAN, 0.0, 0.0)),
            "not finite",
        ),
        (
            Affine3A::from_translation(Vec3::new(f32::INFINITY, 0.0, 0.0)),
            "not finite",
        ),
        // 1e39 is past f32's range.
        (
            Affine3A::from_scale(Vec3::splat(1e-39)),
            "out of f32's range to invert (its inverse is not finite)",
        ),
        // Nearly singular (determinant -3e-5 of entries up to 9): the rounding of its f32
        // inverse (entries near 1e5) moves the product off the identity by about 0.1.
        (
            Affine3A::from_cols(
                Vec3A::new(1.0, 2.0, 3.0),
                Vec3A::new(4.0, 5.0, 6.0),
                Vec3A::new(7.0, 8.0, 9.00001),
                Vec3A::ZERO,
            ),
            "too close to singular for f32 (it times its f32 inverse is not the identity)",
        ),
    ] {
        let e = one(Instance::of(g).transform(m)).unwrap_err();
        assert_eq!(e, WorldError::Transform { instance: 0, why }, "{m:?}");
        assert!(e.to_string().contains("instance 0"));
    }
    let mut b = World::builder();
    assert!(b.add_mesh(&[[0.0; 3]; 3], &[[0, 1, 5]]).is_err());
    b.add_instance(Instance::of(g));
    assert!(matches!(
        b.build(&options),
        Err(WorldError::Mesh { geometry: 0, .. })
    ));

    // Empty worlds: no geometry, or geometries but no instance, or an empty geometry placed.
    let ray = Ray::new(Vec3A::new(0.2, 0.2, 1.0), -Vec3A::Z);
    let empty = World::builder().build(&options).unwrap();
    let mut unplaced = World::builder();
    unplaced.add_triangles(vec![tri]);
    let unplaced = unplaced.build(&options).unwrap();
    let mut nothing = World::builder();
    let e = nothing.add_triangles(Vec::new());
    nothing.add_instance(Instance::of(e));
    let nothing = nothing.build(&options).unwrap();
    for w in [&empty, &unplaced, &nothing] {
        assert_eq!(w.closest_hit(&ray), None);
        assert!(!w.any_hit(&ray));
        let mut hits = vec![
            Some(WorldHit {
                t: 0.0,
                instance: InstanceId(9),
                geometry: GeometryId(9),
                prim: 9,
                u: 0.0,
                v: 0.0
            });
            3
        ];
        w.closest_hit_packet(&[ray; 3], &mut hits);
        assert_eq!(hits, vec![None; 3]);
    }
}

#[test]
fn a_million_instances_of_one_triangle_answer_like_brute_force() {
    let tri = Triangle::new(Vec3A::ZERO, Vec3A::X, Vec3A::Y);
    let mut rng = Rng::new(5);
    let mut b = World::builder();
    let g = b.add_triangles(vec![tri]);
    let mut flat = Vec::new();
    for _ in 0..1_000_000 {
        let at = Vec3::from(rng.in_box(Vec3A::splat(-100.0), Vec3A::splat(100.0)));
        let m = Affine3A::from_scale_rotation_translation(
            Vec3::splat(2.0),
            Quat::from_rotation_y(at.x),
            at,
        );
        b.add_instance(Instance::of(g).transform(m));
        flat.push(Triangle::new(
            m.transform_point3a(tri.v[0]),
            m.transform_point3a(tri.v[1]),
            m.transform_point3a(tri.v[2]),
        ));
    }
    let world = b.build(&BuildOptions::default()).unwrap();
    let bounds = flat.iter().fold(Aabb::EMPTY, |b, t| b.union(&t.bounds()));
    let rays = random_rays(&bounds, 60, 2);
    // Rotations and a uniform scale: cond(M) = 1, so the bands widen by 1 + 2 (see `Setup::slack`).
    let oracle = Oracle::with_slack(&flat, 3.0).closest_hits(&rays);
    let mut hits = 0;
    for (r, a) in rays.iter().zip(&oracle) {
        let got = world.closest_hit(r);
        a.check(got.map(|h| Hit {
            t: h.t,
            prim: h.instance.0,
            u: h.u,
            v: h.v,
        }))
        .unwrap();
        hits += got.is_some() as usize;
        // And like quiver's own reference over the flattened triangles, where decidable.
        if a.is_decidable() {
            assert_eq!(
                got.map(|h| h.instance.0),
                reference::closest_hit(&flat, r).map(|h| h.prim)
            );
        }
    }
    assert!(hits > 10, "{hits} of 60 rays hit");
}

#[test]
fn the_same_world_on_any_pool() {
    let s = setup(15);
    let rays = s.rays(300, 1);
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let two = rayon::ThreadPoolBuilder::new()
        .num_threads(2)
        .build()
        .unwrap();
    let a = s.world(&BuildOptions::default().thread_pool(&one));
    let b = s.world(&BuildOptions::default().thread_pool(&two));
    assert_eq!(a.footprint(), b.footprint());
    for r in &rays {
        assert_eq!(a.closest_hit(r), b.closest_hit(r));
    }
}

/// An OBJ's `o`/`g` groups as the geometries of one world (`quiver_scenes::instanced::
/// grouped`): every hit names the group whose triangle the f64 oracle finds over the whole
/// file's triangles, and the triangle within it; objects before the first group form the
/// last geometry.
#[test]
fn obj_groups_are_the_geometries_of_one_world() {
    use std::fmt::Write as _;
    let parts = [
        tris("soup200"),
        tris("tetra3"),
        tris("icosphere2"),
        tris("soup50"),
    ];
    let mut text = String::new();
    let mut v = 0;
    for (k, part) in parts.iter().enumerate() {
        match k {
            0 => {} // before any `o`: in no group
            1 => text.push_str("o tetra\n"),
            2 => text.push_str("g ball\n"),
            _ => text.push_str("o soup\n"),
        }
        for t in part {
            for p in t.v {
                // Moved apart so the parts overlap only partly.
                let p = p + Vec3A::new(k as f32 * 0.7, 0.0, 0.0);
                writeln!(text, "v {} {} {}", p.x, p.y, p.z).unwrap();
            }
            writeln!(text, "f {} {} {}", v + 1, v + 2, v + 3).unwrap();
            v += 3;
        }
    }
    let scene = quiver_scenes::scene::obj::parse(&text, "groups.obj").unwrap();
    let names: Vec<&str> = scene.groups.iter().map(|g| g.name.as_str()).collect();
    assert_eq!(names, ["default", "tetra", "tetra/ball", "soup"]);
    let flat = scene.triangles();
    // Where each part's triangles start in the file's list.
    let sizes: Vec<usize> = parts.iter().map(Vec::len).collect();
    let starts: Vec<u32> = (0..4)
        .map(|k| sizes[..k].iter().sum::<usize>() as u32)
        .collect();
    let bounds = flat.iter().fold(Aabb::EMPTY, |b, t| b.union(&t.bounds()));
    // Random rays, and as many aimed at the centroids of triangles spread over the file.
    let mut rays = random_rays(&bounds, 1000, 5);
    for (k, r) in random_rays(&bounds, 1000, 6).iter().enumerate() {
        let t = &flat[(k * 7919) % flat.len()];
        rays.push(Ray::new(
            r.origin,
            (t.v[0] + t.v[1] + t.v[2]) / 3.0 - r.origin,
        ));
    }
    let answers = Oracle::new(&flat).closest_hits(&rays);
    // Every object in a group; then the first group dropped, so its objects are in none and
    // form the last geometry.
    let mut partial = scene.clone();
    partial.groups.remove(0);
    for (scene, first) in [(&scene, 0), (&partial, 1)] {
        let world = quiver_scenes::instanced::grouped(scene, &BuildOptions::default()).unwrap();
        assert_eq!(world.instances().len(), 4);
        let mut named = 0;
        for (ray, answer) in rays.iter().zip(&answers) {
            let got = world.closest_hit(ray).map(|h| {
                assert_eq!(h.geometry.0, h.instance.0);
                let part = match world.instance(h.instance).user_id {
                    u32::MAX => 0,
                    group => group as usize + first,
                };
                named += 1;
                Hit {
                    t: h.t,
                    prim: starts[part] + h.prim,
                    u: h.u,
                    v: h.v,
                }
            });
            if answer.is_decidable() {
                answer.check(got).unwrap();
            }
        }
        assert!(named > 1000, "{named} hits");
    }
}

/// Rays for a world of scale `k`: from all around its flattened box, and aimed at triangles.
fn scaled_setup(k: f32, seed: u64, shear: f32) -> Setup {
    let geometries = vec![tris("icosphere2"), tris("tetra3")];
    let mut rng = Rng::new(seed);
    let mut instances = Vec::new();
    for i in 0..12u32 {
        let axis = Vec3::from(rng.in_box(Vec3A::splat(-1.0), Vec3A::ONE)).normalize_or(Vec3::Z);
        let angle = rng.in_box(Vec3A::ZERO, Vec3A::splat(6.0)).x;
        let uneven = Vec3::from(rng.in_box(Vec3A::splat(0.5), Vec3A::splat(2.0)));
        let at = Vec3::from(rng.in_box(Vec3A::splat(-6.0), Vec3A::splat(6.0)));
        let mut m = Affine3A::from_scale_rotation_translation(
            uneven,
            Quat::from_axis_angle(axis, angle),
            at,
        );
        // A shear of up to `shear` in one column, then the whole placement scaled by `k`.
        m.matrix3.z_axis += m.matrix3.x_axis * shear * (i % 3) as f32 / 2.0;
        m.matrix3 *= k;
        m.translation *= k;
        if i % 5 == 0 {
            m.matrix3.x_axis = -m.matrix3.x_axis;
        }
        instances.push(Instance::of(GeometryId(i % 2)).transform(m));
    }
    Setup {
        geometries,
        instances,
    }
}

/// `v` times the power of two `unit`, which must be exact for finite coordinates (asserted:
/// no overflow, nothing rounded into the subnormals).
fn exactly_scaled(v: Vec3A, unit: f64) -> Vec3A {
    let f = |x: f32| {
        let y = (x as f64 * unit) as f32;
        let back = (y as f64 / unit) as f32;
        assert!(!x.is_finite() || back == x, "{x} times {unit} is not exact");
        y
    };
    Vec3A::new(f(v.x), f(v.y), f(v.z))
}

/// Checks every ray of `s` against the f64 oracle over the flattened scene (single rays and
/// packets); returns how many decidable rays hit.
///
/// The oracle judges the flattened scene and the rays multiplied by the power of two that
/// brings the scene to about unit size: exact, so the same geometry with the same `t`, `u`
/// and `v`. At the scene's own scale (1e-30, 1e30) the oracle calls every crossing grazed,
/// since an f32 test in world space would form products past 2^±100 and no rounding model
/// holds; the world never tests there (it takes each ray into its instance's object space,
/// about unit size), and at unit size the oracle's f32 rounding model is the one that
/// applies, widened by the transforms' slack as at scale 1.
fn against_flattened(s: &Setup, rays: &[Ray], what: &str) -> usize {
    let (flat, names) = s.flattened(|_, _| true);
    let bounds = flat.iter().fold(Aabb::EMPTY, |b, t| b.union(&t.bounds()));
    let extent = (bounds.max - bounds.min).max_element() as f64;
    let unit = 2f64.powi(-(extent.log2().round() as i32));
    let unit_flat: Vec<Triangle> = flat
        .iter()
        .map(|t| Triangle {
            v: t.v.map(|p| exactly_scaled(p, unit)),
        })
        .collect();
    let unit_rays: Vec<Ray> = rays
        .iter()
        .map(|r| Ray {
            origin: exactly_scaled(r.origin, unit),
            dir: exactly_scaled(r.dir, unit),
            ..*r
        })
        .collect();
    let oracle = Oracle::with_slack(&unit_flat, s.slack());
    let answers = oracle.closest_hits(&unit_rays);
    let world = s.world(&BuildOptions::default());
    let mut hits = vec![None; rays.len()];
    world.closest_hit_packet_with::<ConservativeBoxes, _, _>(
        PacketQuery::new(rays).mode(PacketMode::Always),
        &mut hits,
        &mut NoStats,
        &mut quiver_rt::traverse::NoFilter,
    );
    for (i, r) in rays.iter().enumerate() {
        let single = world.closest_hit(r);
        assert_eq!(hits[i], single, "{what} ray {i}: packet against single");
        if let Err(e) = check(&answers[i], single, &names) {
            panic!("{what} ray {i} {r:?}: {e}");
        }
    }
    answers
        .iter()
        .filter(|a| a.is_decidable() && a.hit.is_some())
        .count()
}

/// Issue 49: instances scaled from 1e-30 to 1e30 (rotated, some sheared and mirrored) are all
/// accepted, and answer what the flattened scene answers by the f64 oracle; before, a uniform
/// scale past ~7e12 was accepted with a zero inverse and never hit, and one below ~1e-13 was
/// refused though f32 holds its inverse.
#[test]
fn instances_at_every_scale_answer_as_the_flattened_scene() {
    for exp in [-30, -20, -13, -5, 0, 5, 13, 20, 30] {
        let k = 10f32.powi(exp);
        let s = scaled_setup(k, 7u64.wrapping_add(exp as u64), 1.0);
        for inst in &s.instances {
            assert!(
                quiver_rt::world::invert(&inst.transform).is_ok(),
                "scale 1e{exp}: {:?}",
                inst.transform
            );
        }
        // Directions of length `k`, so hits lie at t of about 1 at every scale; each is
        // brought near unit length before `normalize`, whose squared length would underflow
        // (at 1e-30) or overflow (at 1e30) in f32.
        let rays: Vec<Ray> = s
            .rays(400, 5)
            .iter()
            .map(|r| {
                Ray::new(
                    r.origin,
                    (r.dir / r.dir.abs().max_element()).normalize() * k,
                )
            })
            .collect();
        let hits = against_flattened(&s, &rays, &format!("scale 1e{exp}"));
        assert!(
            hits > rays.len() / 4,
            "scale 1e{exp}: {hits} decidable hits"
        );
    }
}

/// A transform moved by an edit to 1e13 (accepted before with a zero inverse) is hit, as the
/// flattened scene is.
#[test]
fn an_edit_to_a_large_scale_is_hit() {
    let mut s = scaled_setup(1.0, 3, 0.0);
    let mut world = s.world(&BuildOptions::default());
    let big = Affine3A::from_scale(Vec3::splat(1e13));
    let mut edit = world.edit();
    edit.set_transform(InstanceId(0), big).unwrap();
    edit.commit();
    s.instances[0] = s.instances[0].transform(big);
    let ray = Ray::new(Vec3A::new(0.1, 0.2, 5e13), -Vec3A::Z);
    let (flat, names) = s.flattened(|_, _| true);
    let answer = Oracle::new(&flat).closest_hit(&ray);
    assert!(answer.hit.is_some());
    check(&answer, world.closest_hit(&ray), &names).unwrap();
}

/// Property: random transforms with scales of 1e-38 to 1e38, shears up to 1e4 and rotations
/// either are refused with one of the documented reasons, or build a world that answers as
/// the flattened scene does.
#[test]
fn random_transforms_near_the_limits_are_refused_or_answer_right() {
    let mut rng = Rng::new(49);
    let mut accepted = 0;
    for case in 0..40 {
        let u = rng.in_box(Vec3A::ZERO, Vec3A::ONE);
        let exp = (u.x * 76.0 - 38.0).round() as i32;
        let shear = 10f32.powf(u.y * 4.0);
        let k = 10f32.powi(exp);
        let s = scaled_setup(k, 100 + case, shear);
        let refused = s
            .instances
            .iter()
            .find_map(|i| quiver_rt::world::invert(&i.transform).err());
        if let Some(why) = refused {
            assert!(
                ["not invertible", "not finite"].contains(&why)
                    || why.starts_with("out of f32's range")
                    || why.starts_with("too close to singular"),
                "{why}"
            );
            let mut b = World::builder();
            b.add_triangles(s.geometries[0].clone());
            b.add_triangles(s.geometries[1].clone());
            for inst in &s.instances {
                b.add_instance(*inst);
            }
            assert!(matches!(
                b.build(&BuildOptions::default()),
                Err(WorldError::Transform { .. })
            ));
            continue;
        }
        accepted += 1;
        let rays: Vec<Ray> = s
            .rays(150, case)
            .iter()
            .map(|r| {
                Ray::new(
                    r.origin,
                    (r.dir / r.dir.abs().max_element()).normalize() * k,
                )
            })
            .collect();
        against_flattened(&s, &rays, &format!("case {case}: 1e{exp}, shear {shear}"));
    }
    assert!(accepted > 20, "{accepted} of 40 accepted");
}

/// The world `edited` and the same state built afresh (`fresh`, whose instance `k` is the
/// edited world's `live[k]`) answer every ray alike: the same instance, geometry, primitive
/// and bit-identical `t`, `u`, `v` for single rays and packets, closest and any hit.
fn answers_alike(edited: &World, fresh: &World, live: &[u32], rays: &[Ray], what: &str) {
    let renamed = |h: WorldHit| WorldHit {
        instance: InstanceId(live[h.instance.0 as usize]),
        ..h
    };
    let (mut closest, mut any) = (vec![None; rays.len()], vec![false; rays.len()]);
    let q = PacketQuery::new(rays).mode(PacketMode::Always);
    edited.closest_hit_packet_with::<ConservativeBoxes, _, _>(
        q,
        &mut closest,
        &mut NoStats,
        &mut quiver_rt::traverse::NoFilter,
    );
    edited.any_hit_packet(rays, &mut any);
    let mut hits = 0;
    for (i, r) in rays.iter().enumerate() {
        let want = fresh.closest_hit(r).map(renamed);
        let got = edited.closest_hit(r);
        assert_eq!(got, want, "{what}: ray {i}");
        assert_eq!(closest[i], want, "{what}: ray {i} in a packet");
        assert_eq!(edited.any_hit(r), want.is_some(), "{what}: ray {i} any hit");
        assert_eq!(
            any[i],
            want.is_some(),
            "{what}: ray {i} any hit in a packet"
        );
        hits += usize::from(want.is_some());
    }
    assert!(hits > rays.len() / 4, "{what}: only {hits} hits");
}

/// Issue 52: a world edited into a state (instances removed, added, replaced and moved; a
/// geometry replaced by triangles of another count and topology built with another layout,
/// one rebuilt with another preset, one added; the top level refit, then rebuilt) answers
/// exactly what the same state built from scratch answers, in every layout; and that state's
/// hits are the f64 oracle's over it flattened.
#[test]
fn an_edited_world_answers_as_the_same_state_built_afresh() {
    for (k, layout) in Layout::ALL.into_iter().enumerate() {
        let options = BuildOptions::default().layout(layout);
        let mut s = setup(70 + k as u64);
        let mut world = s.world(&options);
        let n = s.instances.len();
        let mut removed = vec![false; n];
        let lifted: Vec<Triangle> = tris("tetra3")
            .iter()
            .map(|t| Triangle {
                v: t.v.map(|p| p * 0.5 + Vec3A::new(0.0, 3.0, 0.0)),
            })
            .collect();
        let sphere_part = tris("icosphere2")[..120].to_vec();
        let other = BuildOptions::fast().layout(Layout::ALL[(k + 5) % Layout::ALL.len()]);
        let moved = Affine3A::from_scale_rotation_translation(
            Vec3::new(1.5, 0.5, 1.0),
            Quat::from_rotation_y(0.7),
            Vec3::new(-2.0, 1.0, 0.5),
        );

        let mut edit = world.edit();
        for i in (2..n).step_by(5) {
            edit.remove_instance(InstanceId(i as u32)).unwrap();
            removed[i] = true;
        }
        let added = edit.add_triangles(lifted.clone(), &options).unwrap();
        assert_eq!(added, GeometryId(3));
        s.geometries.push(lifted);
        edit.replace_triangles(GeometryId(2), sphere_part.clone(), &other)
            .unwrap();
        s.geometries[2] = sphere_part;
        edit.rebuild_geometry(GeometryId(1), &BuildOptions::high_quality())
            .unwrap();
        let replaced = Instance::of(added).transform(moved).mask(0b10);
        edit.set_instance(InstanceId(3), replaced).unwrap();
        s.instances[3] = replaced;
        edit.set_transform(InstanceId(8), moved).unwrap();
        s.instances[8] = s.instances[8].transform(moved);
        for j in 0..6u32 {
            let at = Affine3A::from_translation(Vec3::new(j as f32 - 3.0, -2.0, 1.0));
            let inst = Instance::of(GeometryId(j % 4)).transform(at);
            assert_eq!(edit.add_instance(inst).unwrap(), InstanceId(n as u32 + j));
            s.instances.push(inst);
            removed.push(false);
        }
        edit.commit();

        let check_state = |world: &World, s: &Setup, removed: &[bool], what: &str| {
            let live: Vec<u32> = (0..s.instances.len() as u32)
                .filter(|&i| !removed[i as usize])
                .collect();
            let state = Setup {
                geometries: s.geometries.clone(),
                instances: live.iter().map(|&i| s.instances[i as usize]).collect(),
            };
            let mut b = World::builder();
            for tris in &state.geometries {
                let g = b.add_triangles(tris.clone());
                if g == GeometryId(2) {
                    b.set_options(g, &other).unwrap();
                }
            }
            for inst in &state.instances {
                b.add_instance(*inst);
            }
            let fresh = b.build(&options).unwrap();
            let rays = state.rays(300, 9 + k as u64);
            answers_alike(world, &fresh, &live, &rays, what);
            let (flat, names) = state.flattened(|_, _| true);
            let answers = Oracle::with_slack(&flat, state.slack()).closest_hits(&rays);
            for (i, r) in rays.iter().enumerate() {
                check(&answers[i], fresh.closest_hit(r), &names)
                    .unwrap_or_else(|e| panic!("{what} ray {i}: {e}"));
            }
            for (i, gone) in removed.iter().enumerate() {
                assert_eq!(world.is_live(InstanceId(i as u32)), !gone);
            }
        };
        check_state(&world, &s, &removed, &format!("{layout:?} after one edit"));

        // A second edit: one added instance removed, another moved, the top rebuilt.
        let mut edit = world.edit();
        edit.remove_instance(InstanceId(n as u32 + 1)).unwrap();
        removed[n + 1] = true;
        edit.set_transform(InstanceId(n as u32 + 2), moved).unwrap();
        s.instances[n + 2] = s.instances[n + 2].transform(moved);
        edit.rebuild_top();
        // A removed instance takes no edit, and its id is not given again.
        assert_eq!(
            edit.set_mask(InstanceId(2), 1),
            Err(WorldError::Removed { instance: 2 })
        );
        assert_eq!(
            edit.remove_instance(InstanceId(n as u32 + 1)),
            Err(WorldError::Removed {
                instance: n as u32 + 1
            })
        );
        edit.commit();
        check_state(&world, &s, &removed, &format!("{layout:?} after two edits"));
    }
}

/// Edits refuse what a build refuses, naming it, and change nothing.
#[test]
fn structural_edits_refuse_bad_input_and_change_nothing() {
    let s = setup(90);
    let mut world = s.world(&BuildOptions::default());
    let rays = s.rays(100, 3);
    let before: Vec<_> = rays.iter().map(|r| world.closest_hit(r)).collect();
    let mut edit = world.edit();
    assert!(matches!(
        edit.add_instance(Instance::of(GeometryId(9))),
        Err(WorldError::Geometry { geometry: 9, .. })
    ));
    assert!(matches!(
        edit.add_instance(Instance::of(GeometryId(0)).transform(Affine3A::from_scale(Vec3::ZERO))),
        Err(WorldError::Transform { .. })
    ));
    assert!(matches!(
        edit.replace_triangles(GeometryId(7), Vec::new(), &BuildOptions::default()),
        Err(WorldError::NoGeometry { geometry: 7, .. })
    ));
    assert!(matches!(
        edit.add_mesh(&[[0.0f32; 3]; 2], &[[0, 1, 2]], &BuildOptions::default()),
        Err(WorldError::Mesh { geometry: 3, .. })
    ));
    assert!(matches!(
        edit.rebuild_geometry(GeometryId(0), &BuildOptions::default().max_leaf_size(0)),
        Err(WorldError::Config(_))
    ));
    assert!(matches!(
        edit.remove_instance(InstanceId(40)),
        Err(WorldError::NoInstance { instance: 40, .. })
    ));
    edit.commit();
    let after: Vec<_> = rays.iter().map(|r| world.closest_hit(r)).collect();
    assert_eq!(before, after);
    assert_eq!(world.geometries().len(), 3);
    assert_eq!(world.instances().len(), 40);
}

/// Issue 52: a geometry's own filter (an alpha test on one geometry) is asked about that
/// geometry's candidates only, after the query's filter, and the world answers as the
/// flattened scene without the rejected triangles does (f64 oracle), in every layout, single
/// rays and packets, closest and any hit; edits set and clear it.
#[test]
fn a_geometry_filter_hides_what_it_rejects_and_sees_only_its_geometry() {
    use std::sync::atomic::{AtomicUsize, Ordering};
    use std::sync::Arc;
    for (k, layout) in Layout::ALL.into_iter().enumerate() {
        let s = setup(80 + k as u64);
        let alpha = |h: &WorldHit| !(h.prim + h.instance.0).is_multiple_of(3) || h.u > 0.5;
        let query = |h: &WorldHit| !(h.prim * 7 + h.instance.0).is_multiple_of(5);
        let asked_other = Arc::new(AtomicUsize::new(0));
        let seen = asked_other.clone();
        let mut b = World::builder();
        for tris in &s.geometries {
            b.add_triangles(tris.clone());
        }
        b.set_filter(GeometryId(1), move |h: &WorldHit| {
            if h.geometry != GeometryId(1) {
                seen.fetch_add(1, Ordering::Relaxed);
            }
            alpha(h)
        })
        .unwrap();
        for inst in &s.instances {
            b.add_instance(*inst);
        }
        let options = BuildOptions::default().layout(layout);
        let mut world = b.build(&options).unwrap();
        let rays = s.rays(400, 4 + k as u64);
        // Which triangles survive is known only at a hit's u; the oracle keeps the whole
        // triangle, so rays are judged where the answer does not depend on u: the alpha
        // test's verdict on the oracle's hit is checked with the oracle's own u below.
        let (flat, names) = s.flattened(|i, p| {
            let g = s.instances[i as usize].geometry;
            g != GeometryId(1) || !(p + i).is_multiple_of(3)
        });
        let oracle = Oracle::with_slack(&flat, s.slack());
        let answers = oracle.closest_hits(&rays);
        let (mut packet, mut any) = (vec![None; rays.len()], vec![false; rays.len()]);
        world.closest_hit_packet(&rays, &mut packet);
        world.any_hit_packet(&rays, &mut any);
        let mut judged = 0;
        for (i, r) in rays.iter().enumerate() {
            let got = world.closest_hit(r);
            assert_eq!(packet[i], got, "{layout:?} ray {i}: packet");
            assert_eq!(any[i], world.any_hit(r), "{layout:?} ray {i}: any packet");
            assert_eq!(world.any_hit(r), got.is_some(), "{layout:?} ray {i}: any");
            // The triangles the alpha test rejects whole are gone; those it cuts by u are
            // kept by the oracle, so a ray is judged only where it hit none of those.
            let cut = got.is_some_and(|h| {
                h.geometry == GeometryId(1) && (h.prim + h.instance.0).is_multiple_of(3)
            });
            if !cut && answers[i].is_decidable() {
                let hit_cut = answers[i].hit.is_some_and(|h| {
                    let (inst, g, p) = names[h.prim as usize];
                    g == 1 && (p + inst).is_multiple_of(3)
                });
                if !hit_cut {
                    check(&answers[i], got, &names)
                        .unwrap_or_else(|e| panic!("{layout:?} ray {i}: {e}"));
                    judged += 1;
                }
            }
            if let Some(h) = got {
                assert!(
                    h.geometry != GeometryId(1) || alpha(&h),
                    "{layout:?} ray {i}: rejected hit"
                );
            }
            // With the query's filter too: both are asked.
            let both = world.closest_hit_filtered(r, query);
            if let Some(h) = both {
                assert!(query(&h) && (h.geometry != GeometryId(1) || alpha(&h)));
            }
        }
        assert!(judged > rays.len() / 4, "{layout:?}: {judged} judged");
        assert_eq!(asked_other.load(Ordering::Relaxed), 0, "{layout:?}");

        // Cleared by an edit, the world answers as one built without it.
        let mut edit = world.edit();
        edit.set_filter(GeometryId(1), None).unwrap();
        assert!(edit.set_filter(GeometryId(9), None).is_err());
        edit.commit();
        let plain = s.world(&options);
        for r in &rays {
            assert_eq!(world.closest_hit(r), plain.closest_hit(r));
        }
    }
}
