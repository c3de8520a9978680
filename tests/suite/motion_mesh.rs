//! Moving meshes (issue 53, point 3): a geometry of triangles at two or more evenly spaced
//! time steps. A ray at time `t` answers what the scene with each mesh interpolated to `t`
//! answers, judged by the f64 oracle over those triangles (interpolated by
//! `quiver_lab::worlds::interpolated`, by the rule `WorldBuilder::add_moving_triangles`
//! documents, which the instanced fuzz check shares); single rays, any hit, packets of mixed
//! times and point queries; times out of the shutter and NaN are its nearest end (NaN: 0);
//! bad steps are errors naming them; a refit answers for the new steps.

use glam::{Affine3A, Vec3, Vec3A};
use quiver_lab::oracle::Oracle;
use quiver_lab::point_oracle::{points, PointOracle};
use quiver_lab::worlds::{check, clamped, interpolated, Placements};
use quiver_rt::traverse::{FastBoxes, NoFilter, NoStats, PacketMode, PacketQuery};
use quiver_rt::{
    BuildOptions, GeometryId, Instance, Isa, Motion, Ray, RayQuery, Triangle, World, WorldError,
};
use quiver_scenes::rng::Rng;

/// A scene of moving meshes: each geometry's steps (one step for a static geometry), the
/// instances placing them, and the moving instances' motions.
struct Deforming {
    steps: Vec<Vec<Vec<Triangle>>>,
    instances: Vec<Instance>,
    motions: Vec<Option<Motion>>,
}

/// `n` random triangles in the unit box (sides up to 0.25), at `steps` times, each vertex
/// wandering by up to 0.3 per axis from one step to the next.
fn deforming_mesh(n: usize, steps: usize, seed: u64) -> Vec<Vec<Triangle>> {
    let mut rng = Rng::new(seed);
    let mut unit = || rng.in_box(Vec3A::ZERO, Vec3A::ONE);
    let first: Vec<Triangle> = (0..n)
        .map(|_| {
            let c = unit();
            let mut corner = || c + (unit() - 0.5) * 0.25;
            Triangle::new(corner(), corner(), corner())
        })
        .collect();
    let mut out = vec![first];
    for _ in 1..steps {
        let last = out.last().unwrap();
        let next = last
            .iter()
            .map(|t| {
                let mut wander = |v: Vec3A| v + (unit() - 0.5) * 0.6;
                Triangle::new(wander(t.v[0]), wander(t.v[1]), wander(t.v[2]))
            })
            .collect();
        out.push(next);
    }
    out
}

/// Three moving meshes (2, 3 and 5 steps) and a static one, placed by six instances: the
/// identity, moved, scaled (unevenly), moved and turned, one moving instance (a drift and a
/// growth), and the static mesh beside them.
fn deforming(seed: u64) -> Deforming {
    let steps = vec![
        deforming_mesh(300, 2, seed),
        deforming_mesh(200, 3, seed + 1),
        deforming_mesh(150, 5, seed + 2),
        deforming_mesh(100, 1, seed + 3),
    ];
    let at = |x: f32, y: f32, z: f32| Affine3A::from_translation(Vec3::new(x, y, z));
    let instances = vec![
        Instance::of(GeometryId(0)),
        Instance::of(GeometryId(1)).transform(at(0.6, 0.1, -0.3)),
        Instance::of(GeometryId(2))
            .transform(at(-0.4, 0.5, 0.2) * Affine3A::from_scale(Vec3::new(1.5, 0.7, 1.2))),
        Instance::of(GeometryId(0)).transform(at(0.2, -0.5, 0.4) * Affine3A::from_rotation_y(0.7)),
        Instance::of(GeometryId(1)),
        Instance::of(GeometryId(3)).transform(at(0.3, 0.3, 0.3)),
    ];
    let mut motions = vec![None; instances.len()];
    motions[4] = Some(Motion::linear(vec![
        at(-0.5, 0.0, 0.0),
        at(0.0, 0.4, 0.2) * Affine3A::from_scale(Vec3::splat(1.3)),
        at(0.5, 0.0, -0.2),
    ]));
    Deforming {
        steps,
        instances,
        motions,
    }
}

impl Deforming {
    /// The scene at time 0 with the meshes' steps beside it: what the lab's helpers take.
    fn still(&self) -> Placements {
        Placements {
            geometries: self.steps.iter().map(|s| s[0].clone()).collect(),
            instances: self.instances.clone(),
        }
    }

    /// The world: the moving meshes as moving meshes, the moving instance moving.
    fn world(&self, options: &BuildOptions) -> World {
        (self.still())
            .deforming_world(&self.steps, &self.motions, options)
            .unwrap()
    }

    /// The static scene at shutter time `c`: every mesh interpolated, every instance placed.
    fn at(&self, c: f32) -> Placements {
        self.still().deformed_at(&self.steps, &self.motions, c)
    }
}

/// Times in and out of the shutter: its ends, the steps of 3 and 5 (segment boundaries),
/// between them, outside it, NaN.
const TIMES: [f32; 11] = [
    0.0,
    1.0,
    0.5,
    0.25,
    0.75,
    1.0 / 3.0,
    0.1,
    0.9,
    -0.5,
    2.0,
    f32::NAN,
];

/// Rays at `TIMES` and at random times, each with the oracle's answer over the scene at its
/// time and that scene's names.
type Judged = (Ray, quiver_lab::oracle::Answer, Vec<(u32, u32, u32)>);

fn judged_rays(d: &Deforming, per_time: usize, seed: u64) -> Vec<Judged> {
    let mut rng = Rng::new(seed);
    let mut times: Vec<f32> = TIMES.to_vec();
    times.extend((0..8).map(|_| rng.in_box(Vec3A::ZERO, Vec3A::ONE).x));
    let mut out = Vec::new();
    for (k, &time) in times.iter().enumerate() {
        let placed = d.at(clamped(time));
        let (flat, names) = placed.flattened(|_, _| true);
        let rays: Vec<Ray> = placed
            .rays(per_time, seed + 10 + k as u64)
            .into_iter()
            .map(|r| r.with_time(time))
            .collect();
        let answers = Oracle::with_slack(&flat, placed.slack()).closest_hits(&rays);
        for (r, a) in rays.into_iter().zip(answers) {
            out.push((r, a, names.clone()));
        }
    }
    // Mixed times in every packet.
    for i in (1..out.len()).rev() {
        out.swap(i, (rng.next_u64() % (i as u64 + 1)) as usize);
    }
    out
}

/// Every ray's closest hit judged by the oracle, any hit as the closest hit found, the
/// packets' answers as the single rays'.
fn check_world(w: &World, judged: &[Judged], what: &str) {
    let rays: Vec<Ray> = judged.iter().map(|j| j.0).collect();
    let mut hits = vec![None; rays.len()];
    let mut occluded = vec![false; rays.len()];
    let q = PacketQuery::new(&rays).mode(PacketMode::Always);
    w.closest_hit_packet_with::<FastBoxes, _, _>(q, &mut hits, &mut NoStats, &mut NoFilter);
    w.any_hit_packet_with::<FastBoxes, _, _>(q, &mut occluded, &mut NoStats, &mut NoFilter);
    let mut rebuilt_hits = vec![None; rays.len()];
    w.closest_hit_packet(&rays, &mut rebuilt_hits);
    for (i, (r, answer, names)) in judged.iter().enumerate() {
        let at = || format!("{what} ray {i}: {r:?}");
        let single = w.closest_hit(r);
        if let Err(e) = check(answer, single, names) {
            panic!("{}: {e}", at());
        }
        assert_eq!(w.any_hit(r), single.is_some(), "{}: any hit", at());
        assert_eq!(hits[i], single, "{}: packet against single", at());
        assert_eq!(
            rebuilt_hits[i],
            single,
            "{}: default packet against single",
            at()
        );
        assert_eq!(occluded[i], single.is_some(), "{}: any-hit packet", at());
    }
}

#[test]
fn a_ray_at_time_t_meets_the_meshes_interpolated_to_t() {
    let d = deforming(31);
    let judged = judged_rays(&d, 150, 7);
    let decidable_hits = judged
        .iter()
        .filter(|(_, a, _)| a.is_decidable() && a.hit.is_some())
        .count();
    assert!(
        decidable_hits > judged.len() / 3,
        "{decidable_hits} decidable hits of {}",
        judged.len()
    );
    // A walk that ignored the time would fail: many rays' answers differ from time 0's.
    let still = d.at(0.0).world(&BuildOptions::default());
    let w = d.world(&BuildOptions::default());
    let moved = judged
        .iter()
        .filter(|(r, _, _)| still.closest_hit(r) != w.closest_hit(r))
        .count();
    assert!(moved > judged.len() / 8, "{moved} rays see the motion");
    for isa in Isa::ALL {
        let w = d.world(&BuildOptions::default().isa(isa));
        check_world(&w, &judged, &format!("{isa}"));
    }
}

#[test]
fn the_normal_is_the_interpolated_triangles() {
    let d = deforming(32);
    let w = d.world(&BuildOptions::default());
    let mut checked = 0;
    for (r, _, _) in judged_rays(&d, 40, 9) {
        let Some(h) = w.closest_hit(&r) else { continue };
        if h.instance.0 != 0 {
            continue; // the identity instance: object space is world space
        }
        let tri = interpolated(&d.steps[0], clamped(r.time))[h.prim as usize];
        let want = (tri.v[1] - tri.v[0]).cross(tri.v[2] - tri.v[0]).normalize();
        let got = w.normal(&r, &h).unwrap();
        assert!((got - want).length() < 1e-4, "{r:?}: {got} against {want}");
        checked += 1;
    }
    assert!(checked > 20, "{checked} normals checked");
}

#[test]
fn the_point_nearest_at_time_t_is_the_nearest_of_the_meshes_at_t() {
    let d = deforming(33);
    let w = d.world(&BuildOptions::default());
    let mut moved = 0;
    let mut total = 0;
    for (k, &time) in TIMES.iter().enumerate() {
        let placed = d.at(clamped(time));
        let fresh = placed.world(&BuildOptions::default());
        let oracle = PointOracle::for_world(&fresh);
        let (flat, _) = placed.flattened(|_, _| true);
        for (j, p) in points(&flat, 40, 100.0, 80 + k as u64)
            .into_iter()
            .enumerate()
        {
            let hit = w.closest_point_at(p, f32::INFINITY, time);
            if let Err(e) = oracle.check_world(p, f32::INFINITY, hit.as_ref()) {
                panic!("time {time}, point {j} {p}: {e}");
            }
            // The cut-off, either side of the oracle's distance.
            let d = oracle.answer(p, f32::INFINITY).distance as f32;
            let max = d * [0.5, 0.95, 1.05, 3.0][j % 4];
            let cut = w.closest_point_at(p, max, time);
            if let Err(e) = oracle.check_world(p, max, cut.as_ref()) {
                panic!("time {time}, point {j} {p}, max {max}: {e}");
            }
            moved += usize::from(hit != w.closest_point(p, f32::INFINITY));
            total += 1;
        }
    }
    assert!(moved > total / 4, "{moved} of {total} differ from time 0's");
}

#[test]
fn a_refit_answers_for_the_new_steps() {
    let mut d = deforming(34);
    let mut w = d.world(&BuildOptions::default());
    let fresh = deforming(35);
    let mut edit = w.edit();
    for g in 0..3 {
        edit.refit_moving_triangles(GeometryId(g), fresh.steps[g as usize].clone())
            .unwrap();
    }
    // Refused refits change nothing.
    let two = fresh.steps[1][..2].to_vec();
    assert_eq!(
        edit.refit_moving_triangles(GeometryId(1), two),
        Err(WorldError::Steps {
            geometry: 1,
            step: None,
            why: "a different number of steps than the mesh refit"
        })
    );
    let mut short = fresh.steps[0].clone();
    short[1].pop();
    assert!(matches!(
        edit.refit_moving_triangles(GeometryId(0), short),
        Err(WorldError::Steps {
            geometry: 0,
            step: Some(1),
            ..
        })
    ));
    assert!(matches!(
        edit.refit_moving_triangles(GeometryId(3), fresh.steps[0].clone()),
        Err(WorldError::GeometryKind { geometry: 3, .. })
    ));
    assert!(matches!(
        edit.refit_triangles(GeometryId(0), &fresh.steps[0][0]),
        Err(WorldError::GeometryKind { geometry: 0, .. })
    ));
    // A moving mesh added by the edit, placed moved and scaled.
    let added = deforming_mesh(80, 4, 77);
    assert_eq!(
        edit.add_moving_triangles(vec![added[0].clone()], &BuildOptions::default()),
        Err(WorldError::Steps {
            geometry: 4,
            step: None,
            why: "fewer than two time steps"
        })
    );
    let g = edit
        .add_moving_triangles(added.clone(), &BuildOptions::default())
        .unwrap();
    let placed = Instance::of(g).transform(
        Affine3A::from_translation(Vec3::new(0.1, 0.8, 0.0))
            * Affine3A::from_scale(Vec3::splat(0.8)),
    );
    edit.add_instance(placed).unwrap();
    edit.commit();
    for g in 0..3 {
        d.steps[g] = fresh.steps[g].clone();
    }
    d.steps.push(added);
    d.instances.push(placed);
    d.motions.push(None);
    check_world(&w, &judged_rays(&d, 100, 11), "refit");
    // Point queries walk the refit trees.
    for (k, &time) in TIMES.iter().enumerate() {
        let placed = d.at(clamped(time));
        let oracle = PointOracle::for_world(&placed.world(&BuildOptions::default()));
        let (flat, _) = placed.flattened(|_, _| true);
        for p in points(&flat, 15, 10.0, 90 + k as u64) {
            let hit = w.closest_point_at(p, f32::INFINITY, time);
            if let Err(e) = oracle.check_world(p, f32::INFINITY, hit.as_ref()) {
                panic!("refit, time {time}, point {p}: {e}");
            }
        }
    }
    // A rebuild of the refit tree answers the same.
    w.edit()
        .rebuild_geometry(GeometryId(2), &BuildOptions::default())
        .unwrap();
    check_world(&w, &judged_rays(&d, 60, 12), "rebuilt");
}

#[test]
fn steps_that_cannot_make_a_moving_mesh_are_errors_naming_them() {
    let tri = Triangle::new(Vec3A::ZERO, Vec3A::X, Vec3A::Y);
    let err = |steps: Vec<Vec<Triangle>>| {
        let mut b = World::builder();
        b.add_triangles(vec![tri]);
        let e = b.add_moving_triangles(steps).unwrap_err();
        // Reported by the build too.
        assert_eq!(b.build(&BuildOptions::default()).unwrap_err(), e);
        e
    };
    assert_eq!(
        err(vec![vec![tri]]),
        WorldError::Steps {
            geometry: 1,
            step: None,
            why: "fewer than two time steps"
        }
    );
    assert_eq!(
        err(vec![]).to_string(),
        "geometry 1: the moving mesh has fewer than two time steps"
    );
    assert_eq!(
        err(vec![vec![tri], vec![tri], vec![tri, tri]]),
        WorldError::Steps {
            geometry: 1,
            step: Some(2),
            why: "a different number of triangles than step 0"
        }
    );
    let bad = Triangle::new(Vec3A::ZERO, Vec3A::X, Vec3A::new(0.0, f32::NAN, 0.0));
    let e = err(vec![vec![tri], vec![bad]]);
    assert_eq!(
        e,
        WorldError::Steps {
            geometry: 1,
            step: Some(1),
            why: "a vertex that is not finite"
        }
    );
    assert_eq!(
        e.to_string(),
        "geometry 1: time step 1 has a vertex that is not finite"
    );
    let inf = Triangle::new(Vec3A::ZERO, Vec3A::X, Vec3A::splat(f32::INFINITY));
    assert!(matches!(
        err(vec![vec![inf], vec![tri]]),
        WorldError::Steps { step: Some(0), .. }
    ));
}

#[test]
fn an_empty_moving_mesh_is_hit_by_nothing_and_a_filter_sees_its_hits() {
    let tri = |z: f32| {
        Triangle::new(
            Vec3A::new(0.0, 0.0, z),
            Vec3A::X + Vec3A::new(0.0, 0.0, z),
            Vec3A::Y + Vec3A::new(0.0, 0.0, z),
        )
    };
    let mut b = World::builder();
    let empty = b.add_moving_triangles(vec![Vec::new(); 3]).unwrap();
    let sinking = b
        .add_moving_triangles(vec![vec![tri(0.0), tri(-1.0)], vec![tri(-4.0), tri(-1.0)]])
        .unwrap();
    b.add_instance(Instance::of(empty));
    b.add_instance(Instance::of(sinking));
    // The first triangle cut out past t = 2: rays beyond it meet the second.
    b.set_filter(sinking, |h: &quiver_rt::WorldHit| h.prim != 0 || h.t <= 2.0)
        .unwrap();
    let w = b.build(&BuildOptions::default()).unwrap();
    assert!(w.geometries()[0].is_empty());
    let ray = Ray::new(Vec3A::new(0.2, 0.2, 1.0), -Vec3A::Z);
    let hit = |time: f32| w.closest_hit(&ray.with_time(time)).map(|h| (h.prim, h.t));
    assert_eq!(hit(0.0), Some((0, 1.0)));
    assert_eq!(hit(0.125), Some((0, 1.5)));
    assert_eq!(hit(0.5), Some((1, 2.0)));
    assert_eq!(hit(1.0), Some((1, 2.0)));
    let mut found = [None; 4];
    let rays = [0.0, 0.125, 0.5, 1.0].map(|t| ray.with_time(t));
    w.closest_hit_packet(&rays, &mut found);
    assert_eq!(
        found.map(|h| h.map(|h| (h.prim, h.t))),
        [0.0, 0.125, 0.5, 1.0].map(hit)
    );
    let miss = Ray::new(Vec3A::new(5.0, 5.0, 1.0), -Vec3A::Z);
    assert!(!w.any_hit(&miss));
    assert_eq!(
        w.closest_point_at(Vec3A::new(0.2, 0.2, 1.0), 10.0, 0.5)
            .map(|h| h.distance),
        Some(2.0)
    );
}

#[test]
fn a_saved_world_with_moving_meshes_loads_answering_bit_for_bit_as_the_saved_one() {
    let d = deforming(36);
    let w = d.world(&BuildOptions::default());
    let bytes = w.to_bytes();
    assert_eq!(bytes[8..12], 2u32.to_le_bytes(), "version 2: moving meshes");
    let loaded = World::from_bytes(&bytes).unwrap();
    assert_eq!(loaded.instances(), w.instances());
    assert_eq!(
        loaded.to_bytes(),
        bytes,
        "a loaded world saves to the same bytes"
    );
    let mut file = Vec::new();
    loaded.save(&mut file).unwrap();
    assert_eq!(World::load(&mut &file[..]).unwrap().to_bytes(), bytes);
    // Random rays at random times (and the times out of the shutter), judged against the
    // saved world's answers to the bit: t, primitive, instance.
    let mut rng = Rng::new(5);
    let b = w.bounds();
    let mut rays = Vec::new();
    for i in 0..3000 {
        let from = rng.in_box(b.min, b.max);
        let to = rng.in_box(b.min, b.max);
        let time = match i % 10 {
            0 => TIMES[(i / 10) % TIMES.len()],
            _ => rng.in_box(Vec3A::ZERO, Vec3A::ONE).x,
        };
        rays.push(Ray::new(from, to - from).with_time(time));
    }
    let mut hits = 0;
    for r in &rays {
        let (want, got) = (w.closest_hit(r), loaded.closest_hit(r));
        hits += usize::from(want.is_some());
        assert_eq!(
            got.map(|h| (h.t.to_bits(), h.prim, h.instance)),
            want.map(|h| (h.t.to_bits(), h.prim, h.instance)),
            "{r:?}"
        );
        assert_eq!(got, want, "{r:?}");
        assert_eq!(loaded.any_hit(r), w.any_hit(r), "{r:?}");
    }
    assert!(
        hits > rays.len() / 4,
        "{hits} hits: the rays must meet the scene"
    );
    let (mut a, mut b) = (vec![None; rays.len()], vec![None; rays.len()]);
    w.closest_hit_packet(&rays, &mut a);
    loaded.closest_hit_packet(&rays, &mut b);
    assert_eq!(a, b);
    for (i, r) in rays.iter().take(300).enumerate() {
        let time = r.shutter_time();
        assert_eq!(
            loaded.closest_point_at(r.origin, 0.5, time),
            w.closest_point_at(r.origin, 0.5, time),
            "point {i}"
        );
    }
    // And as the oracle judges the scene at each ray's time.
    check_world(&loaded, &judged_rays(&d, 40, 8), "loaded");
}

#[test]
fn a_world_with_a_moving_mesh_counts_its_memory() {
    let d = deforming(36);
    let w = d.world(&BuildOptions::default());
    // Its steps and every segment's nodes and ends.
    let steps: usize = d.steps[..3]
        .iter()
        .map(|s| s.len() * s[0].len() * std::mem::size_of::<Triangle>())
        .sum();
    let g = w.geometries()[..3]
        .iter()
        .map(|g| g.footprint().bytes)
        .sum::<usize>();
    assert!(g > steps + 6 * 384, "{g} bytes for {steps} of steps");
    assert!(w.footprint().bytes > g);
}
