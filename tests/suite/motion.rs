//! Moving instances (issue 53): a ray at time `t` answers what the scene placed at `t`
//! answers, judged by the f64 oracle over the triangles placed by each motion's transform at
//! `t`, and bit for bit what a static world built at `t` answers; in every layout and
//! instruction set, single rays and packets of mixed times; times out of the shutter are its
//! nearest end; bad motions are errors; files and edits keep motions. Point queries at a time
//! (`World::closest_point_at`) likewise, judged by the f64 `PointOracle` over the scene
//! placed at that time.

use glam::{Affine3A, Quat, Vec3, Vec3A};
use quiver_lab::oracle::Oracle;
use quiver_lab::point_oracle::{points, PointOracle};
use quiver_lab::worlds::{check, Placements as Setup};
use quiver_rt::traverse::{NoFilter, NoStats, PacketMode, PacketQuery};
use quiver_rt::world::Interpolation;
use quiver_rt::{
    BuildOptions, Instance, InstanceId, Isa, Layout, Motion, Ray, RayQuery, World, WorldError,
};
use quiver_scenes::rng::Rng;

/// The world test's 40 instances, every other one moving: linear motions (a drift, a
/// growth, a shear) of two to four keys, and decomposed ones that turn up to 0.45 of a turn
/// per step about a random axis while they drift.
fn moving(seed: u64) -> (Setup, Vec<Option<Motion>>) {
    let s = crate::world::setup(seed);
    let mut rng = Rng::new(seed + 100);
    let mut unit = || rng.in_box(Vec3A::ZERO, Vec3A::ONE);
    let motions = s
        .instances
        .iter()
        .enumerate()
        .map(|(i, inst)| {
            let base = inst.transform;
            let keys_n = 2 + i % 3;
            match i % 4 {
                1 => Some(Motion::linear(
                    (0..keys_n)
                        .map(|k| {
                            let r = unit();
                            let grow = 1.0 + 0.3 * r.x * k as f32;
                            let drift = (Vec3::from(unit()) - 0.5) * 3.0 * k as f32;
                            let shear = Affine3A::from_cols_array(&[
                                grow,
                                0.0,
                                0.0,
                                0.2 * r.y,
                                1.0,
                                0.0,
                                0.0,
                                0.0,
                                1.0,
                                0.0,
                                0.0,
                                0.0,
                            ]);
                            Affine3A::from_translation(drift) * base * shear
                        })
                        .collect(),
                )),
                3 => {
                    let axis = (Vec3::from(unit()) - 0.5).normalize_or(Vec3::Y);
                    let step = unit().x * 0.45 * std::f32::consts::TAU;
                    Some(Motion::decomposed(
                        (0..keys_n)
                            .map(|k| {
                                let turn = Quat::from_axis_angle(axis, step * k as f32);
                                let drift = (Vec3::from(unit()) - 0.5) * 2.0;
                                Affine3A::from_translation(drift) * Affine3A::from_quat(turn) * base
                            })
                            .collect(),
                    ))
                }
                _ => None,
            }
        })
        .collect();
    (s, motions)
}

/// The world of `s` whose instances move by `motions`.
fn world(s: &Setup, motions: &[Option<Motion>], options: &BuildOptions) -> World {
    s.moving_world(motions, options)
}

/// The scene of `s` placed where `motions` have it at `time`.
fn at_time(s: &Setup, motions: &[Option<Motion>], time: f32) -> Setup {
    s.at_time(motions, time)
}

/// Times in and out of the shutter: its ends, a key's time, between keys, outside, NaN.
const TIMES: [f32; 8] = [0.0, 1.0, 0.5, 1.0 / 3.0, 0.8125, -0.5, 2.0, f32::NAN];

#[test]
fn a_ray_at_time_t_meets_the_scene_placed_at_t() {
    let (s, motions) = moving(21);
    let still = world(
        &at_time(&s, &motions, 0.0),
        &vec![None; motions.len()],
        &BuildOptions::default(),
    );
    let mut rays = Vec::new();
    let mut judged = Vec::new();
    let mut moved = 0;
    for (k, &time) in TIMES.iter().enumerate() {
        let clamped = Ray::new(Vec3A::ZERO, Vec3A::Z)
            .with_time(time)
            .shutter_time();
        let placed = at_time(&s, &motions, clamped);
        let (flat, names) = placed.flattened(|_, _| true);
        let answers = Oracle::with_slack(&flat, placed.slack()).closest_hits(
            &placed
                .rays(150, 40 + k as u64)
                .into_iter()
                .map(|r| r.with_time(time))
                .collect::<Vec<_>>(),
        );
        let fresh = world(
            &placed,
            &vec![None; motions.len()],
            &BuildOptions::default(),
        );
        for (r, a) in placed.rays(150, 40 + k as u64).into_iter().zip(answers) {
            moved += usize::from(fresh.closest_hit(&r) != still.closest_hit(&r));
            rays.push(r.with_time(time));
            judged.push((a, fresh.closest_hit(&r), names.clone()));
        }
    }
    // The scene at the rays' times is not the scene at time 0 for many of them (five of the
    // eight times are not 0 once clamped): a walk that ignored the time would fail.
    assert!(
        moved > rays.len() / 8,
        "{moved} of {} rays see the motion",
        rays.len()
    );
    // Mixed times in every packet.
    let mut order: Vec<usize> = (0..rays.len()).collect();
    let mut rng = Rng::new(5);
    for i in (1..order.len()).rev() {
        order.swap(i, (rng.next_u64() % (i as u64 + 1)) as usize);
    }
    let rays: Vec<Ray> = order.iter().map(|&i| rays[i]).collect();
    let judged: Vec<_> = order.iter().map(|&i| judged[i].clone()).collect();
    let decidable_hits = judged
        .iter()
        .filter(|(a, _, _)| a.is_decidable() && a.hit.is_some())
        .count();
    assert!(
        decidable_hits > rays.len() / 3,
        "{decidable_hits} decidable hits of {}",
        rays.len()
    );
    for layout in Layout::ALL {
        for isa in Isa::ALL {
            let w = world(
                &s,
                &motions,
                &BuildOptions::default().layout(layout).isa(isa),
            );
            let mut hits = vec![None; rays.len()];
            let mut occluded = vec![false; rays.len()];
            let q = PacketQuery::new(&rays).mode(PacketMode::Always);
            w.closest_hit_packet_with::<quiver_rt::traverse::FastBoxes, _, _>(
                q,
                &mut hits,
                &mut NoStats,
                &mut NoFilter,
            );
            w.any_hit_packet_with::<quiver_rt::traverse::FastBoxes, _, _>(
                q,
                &mut occluded,
                &mut NoStats,
                &mut NoFilter,
            );
            for (i, r) in rays.iter().enumerate() {
                let at = || format!("{layout} {isa} ray {i}: {r:?}");
                let single = w.closest_hit(r);
                let (answer, fresh, names) = &judged[i];
                assert_eq!(single, *fresh, "{}: against the world built at t", at());
                assert_eq!(hits[i], single, "{}: packet against single", at());
                assert_eq!(occluded[i], single.is_some(), "{}: any-hit packet", at());
                assert_eq!(w.any_hit(r), single.is_some(), "{}: any hit", at());
                if let Err(e) = check(answer, single, names) {
                    panic!("{}: {e}", at());
                }
            }
        }
    }
}

/// [`moving`]'s world with the instances it leaves still at `i % 4 == 2` decomposed too,
/// each key scaled unevenly (0.5 to 1.8 per axis, a different scale at every key) as it
/// turns and drifts: every kind of motion, non-uniform scale changing over the shutter
/// included.
fn moving_and_stretching(seed: u64) -> (Setup, Vec<Option<Motion>>) {
    let (s, mut motions) = moving(seed);
    let mut rng = Rng::new(seed + 200);
    let mut unit = || rng.in_box(Vec3A::ZERO, Vec3A::ONE);
    for (i, (inst, m)) in s.instances.iter().zip(&mut motions).enumerate() {
        if i % 4 != 2 {
            continue;
        }
        let axis = (Vec3::from(unit()) - 0.5).normalize_or(Vec3::X);
        let step = unit().x * 0.3 * std::f32::consts::TAU;
        let keys = (0..2 + i % 3)
            .map(|k| {
                let scale = Vec3::splat(0.5) + Vec3::from(unit()) * 1.3;
                let turn = Quat::from_axis_angle(axis, step * k as f32);
                let drift = (Vec3::from(unit()) - 0.5) * 2.0;
                Affine3A::from_translation(drift)
                    * Affine3A::from_quat(turn)
                    * inst.transform
                    * Affine3A::from_scale(scale)
            })
            .collect();
        *m = Some(Motion::decomposed(keys));
    }
    (s, motions)
}

#[test]
fn the_point_nearest_at_time_t_is_the_nearest_of_the_scene_placed_at_t() {
    let (s, motions) = moving_and_stretching(25);
    let kinds = |k: Interpolation| {
        motions
            .iter()
            .flatten()
            .filter(|m| m.interpolation() == k)
            .count()
    };
    assert!(kinds(Interpolation::Linear) >= 8 && kinds(Interpolation::Decomposed) >= 16);
    let w = world(&s, &motions, &BuildOptions::default());
    let (mut moved, mut checked) = (0, 0);
    for (k, &time) in TIMES.iter().enumerate() {
        // The scene at the time a ray at `time` is shot (the ray's own rule for times out of
        // the shutter and NaN), each moving instance's triangles placed by its motion then.
        let clamped = Ray::new(Vec3A::ZERO, Vec3A::Z)
            .with_time(time)
            .shutter_time();
        let placed = at_time(&s, &motions, clamped);
        let fresh = world(
            &placed,
            &vec![None; motions.len()],
            &BuildOptions::default(),
        );
        let oracle = PointOracle::for_world(&fresh);
        // Inside the placed scene's box, on its vertices and edges, and up to 100 sizes away.
        let (flat, _) = placed.flattened(|_, _| true);
        let pts = points(&flat, 60, 100.0, 60 + k as u64);
        for (j, &p) in pts.iter().enumerate() {
            let at = format!("time {time}, point {j} {p}");
            let hit = w.closest_point_at(p, f32::INFINITY, time);
            if let Err(e) = oracle.check_world(p, f32::INFINITY, hit.as_ref()) {
                panic!("{at}: {e}");
            }
            assert_eq!(
                hit,
                fresh.closest_point(p, f32::INFINITY),
                "{at}: against the world built at t"
            );
            // The cut-off, either side of the oracle's distance.
            let d = oracle.answer(p, f32::INFINITY).distance as f32;
            let max = d * [0.5, 0.95, 1.05, 3.0][j % 4];
            let cut = w.closest_point_at(p, max, time);
            if let Err(e) = oracle.check_world(p, max, cut.as_ref()) {
                panic!("{at}, max {max}: {e}");
            }
            moved += usize::from(hit != w.closest_point(p, f32::INFINITY));
            checked += 1;
        }
    }
    // Five of the eight times are not 0 once clamped: a query that ignored the time would
    // answer many of their points as at time 0, and fail above.
    assert!(
        moved > checked / 4,
        "{moved} of {checked} answers differ from time 0's"
    );
}

#[test]
fn the_world_box_holds_every_moving_instance_all_shutter_long() {
    let (s, motions) = moving(22);
    let w = world(&s, &motions, &BuildOptions::default());
    let b = w.bounds();
    for (inst, motion) in s.instances.iter().zip(&motions) {
        let Some(m) = motion else { continue };
        for j in 0..=1000 {
            let t = m.at(j as f32 / 1000.0);
            for tri in &s.geometries[inst.geometry.0 as usize] {
                for v in tri.v {
                    let p = t.transform_point3a(v);
                    assert!(
                        p.cmpge(b.min).all() && p.cmple(b.max).all(),
                        "{p} outside {b:?}"
                    );
                }
            }
        }
    }
    // A spinning wheel keeps its size: a decomposed half step of a quarter turn moves the
    // unit x axis to the diagonal at unit length; the linear one shrinks it.
    let keys = vec![
        Affine3A::IDENTITY,
        Affine3A::from_rotation_z(std::f32::consts::FRAC_PI_2),
    ];
    let half = |m: Motion| m.at(0.5).transform_vector3(Vec3::X).length();
    assert!((half(Motion::decomposed(keys.clone())) - 1.0).abs() < 1e-6);
    assert!((half(Motion::linear(keys)) - 0.5f32.sqrt()).abs() < 1e-6);
}

#[test]
fn motions_that_cannot_move_an_instance_are_errors_naming_it() {
    let (s, _) = moving(23);
    let build = |m: Motion| {
        let mut b = World::builder();
        let g = b.add_triangles(s.geometries[0].clone());
        b.add_instance(Instance::of(g));
        b.add_moving_instance(Instance::of(g), m);
        b.build(&BuildOptions::default()).map(|_| ())
    };
    let error = |instance, key, why| Err(WorldError::Motion { instance, key, why });
    let id = Affine3A::IDENTITY;
    for keys in [vec![], vec![id]] {
        assert_eq!(
            build(Motion::decomposed(keys)),
            error(1, None, "fewer than two keys")
        );
    }
    assert_eq!(
        build(Motion::linear(vec![
            id;
            quiver_rt::world::MAX_MOTION_KEYS + 1
        ])),
        error(1, None, "more keys than MAX_MOTION_KEYS")
    );
    let flat = Affine3A::from_scale(Vec3::new(1.0, 0.0, 1.0));
    assert_eq!(
        build(Motion::linear(vec![id, id, flat])),
        error(1, Some(2), "not invertible")
    );
    let nan = Affine3A::from_translation(Vec3::new(f32::NAN, 0.0, 0.0));
    assert_eq!(
        build(Motion::decomposed(vec![id, nan])),
        error(1, Some(1), "not finite")
    );
    let mirror = Affine3A::from_scale(Vec3::new(-1.0, 1.0, 1.0));
    assert!(matches!(
        build(Motion::linear(vec![id, mirror])),
        Err(WorldError::Motion {
            instance: 1,
            key: Some(1),
            ..
        })
    ));
    // Two mirrored keys are fine; so is a decomposed step just under half a turn, not one of
    // a half turn.
    assert_eq!(
        build(Motion::decomposed(vec![mirror, mirror * mirror * mirror])),
        Ok(())
    );
    let turn = |a: f32| Affine3A::from_rotation_y(a);
    assert_eq!(build(Motion::decomposed(vec![id, turn(3.1)])), Ok(()));
    assert_eq!(
        build(Motion::decomposed(vec![
            id,
            turn(0.5),
            turn(0.5 + std::f32::consts::PI)
        ])),
        error(1, Some(1), "turns half a turn or more before the next key")
    );
    let text = WorldError::Motion {
        instance: 4,
        key: Some(2),
        why: "not finite",
    }
    .to_string();
    assert_eq!(text, "instance 4: motion key 2: not finite");
}

#[test]
fn files_and_edits_keep_motions() {
    let (s, motions) = moving(24);
    let w = world(&s, &motions, &BuildOptions::default());
    let rays: Vec<Ray> = s
        .rays(400, 7)
        .into_iter()
        .enumerate()
        .map(|(i, r)| r.with_time(TIMES[i % TIMES.len()]))
        .collect();
    let bytes = w.to_bytes();
    let loaded = World::from_bytes(&bytes).unwrap();
    assert_eq!(loaded.to_bytes(), bytes);
    for i in 0..s.instances.len() as u32 {
        assert_eq!(loaded.motion(InstanceId(i)), w.motion(InstanceId(i)));
        assert_eq!(loaded.instance(InstanceId(i)), w.instance(InstanceId(i)));
    }
    let mut met = 0;
    for r in &rays {
        met += usize::from(w.closest_hit(r).is_some());
        assert_eq!(loaded.closest_hit(r), w.closest_hit(r), "{r:?}");
    }
    assert!(met > rays.len() / 4, "{met} hits");
    // The same motions set by edits on a static world: the same answers.
    let mut edited = world(&s, &vec![None; motions.len()], &BuildOptions::default());
    let mut e = edited.edit();
    for (i, m) in motions.iter().enumerate() {
        if let Some(m) = m {
            e.set_motion(InstanceId(i as u32), m.clone()).unwrap();
        }
    }
    e.commit();
    for r in &rays {
        assert_eq!(edited.closest_hit(r), w.closest_hit(r), "{r:?}");
    }
    // Standing still again: the static world placed at the first keys.
    let mut e = edited.edit();
    for (i, m) in motions.iter().enumerate() {
        if let Some(m) = m {
            e.set_transform(InstanceId(i as u32), m.keys()[0]).unwrap();
        }
    }
    e.commit();
    let still = world(
        &at_time(&s, &motions, 0.0),
        &vec![None; motions.len()],
        &BuildOptions::default(),
    );
    for r in &rays {
        assert_eq!(edited.closest_hit(r), still.closest_hit(r), "{r:?}");
        assert!(edited.motion(InstanceId(1)).is_none());
    }
    assert_eq!(
        w.motion(InstanceId(3)).map(Motion::interpolation),
        Some(Interpolation::Decomposed)
    );
}

/// The SPD renderer's motion blur (issue 53 point 6), on balls1 with every sphere drifting
/// ([`scatter`]): traced at time 0 only, the moving scene draws the static scene's image with
/// its ray counts; a static scene traced at four times traces each ray four times (counts
/// exactly four times the single render's) and draws its image up to the average's
/// rounding; the moving scene traced at four times is blurred away from it.
#[test]
fn the_renderer_blurs_what_moves_and_nothing_else() {
    use quiver_scenes::accel::SceneBvh;
    use quiver_scenes::instanced::scatter;
    use quiver_scenes::render::{render, RayCounts, RenderConfig};
    let scene = quiver_scenes::Scene::load("balls1").unwrap();
    let options = BuildOptions::default();
    let still = SceneBvh::build_instanced(&scene, 4, &options).unwrap();
    let moving = SceneBvh::build_instanced_moving(&scene, 4, &options, &scatter).unwrap();
    let draw = |bvh: &SceneBvh, time_samples: u32| {
        let config = RenderConfig {
            res: 48,
            two_sided: scene.patch_mode_two_sided_materials(),
            time_samples,
            ..RenderConfig::default()
        };
        render(&scene, bvh, &config, &|_| {})
    };
    let base = draw(&still, 1);
    let at_zero = draw(&moving, 1);
    assert_eq!(at_zero.rays, base.rays, "time 0: the static scene's rays");
    assert_eq!(at_zero.rgb, base.rgb, "time 0: the static scene's image");
    let r = base.rays;
    let four = RayCounts {
        eye: 4 * r.eye,
        eye_hit: 4 * r.eye_hit,
        reflect: 4 * r.reflect,
        refract: 4 * r.refract,
        secondary_hit: 4 * r.secondary_hit,
        shadow: 4 * r.shadow,
        shadow_blocked: 4 * r.shadow_blocked,
    };
    let still4 = draw(&still, 4);
    assert_eq!(
        still4.rays, four,
        "a static scene at four times: each ray four times"
    );
    let off = |a: &[[u8; 3]], b: &[[u8; 3]]| {
        let channels = a.iter().zip(b).flat_map(|(p, q)| p.iter().zip(q));
        channels.map(|(x, y)| x.abs_diff(*y)).max()
    };
    assert!(
        off(&still4.rgb, &base.rgb) <= Some(1),
        "a static scene stays sharp"
    );
    let moving4 = draw(&moving, 4);
    assert_eq!(moving4.rays.eye, four.eye);
    let blurred = moving4
        .rgb
        .iter()
        .zip(&base.rgb)
        .filter(|(a, b)| a != b)
        .count();
    assert!(
        blurred > base.rgb.len() / 20,
        "{blurred} of {} pixels blurred",
        base.rgb.len()
    );
}
