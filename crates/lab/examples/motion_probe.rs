//! Motion blur's price: `cargo run --release -p quiver-lab --example motion_probe -- SCENE RES REPS`
//! builds SCENE (an SPD generator name) as instances of unit shapes (the world `quiver bench
//! --instanced` measures), then the same world twice more from its geometries: once static,
//! once with every placed shape moving (a linear drift of half its size over the shutter, or,
//! with `DECOMPOSED=1`, a decomposed quarter turn about its vertical axis as it drifts). It
//! traces the RES² eye rays (closest hit) and their shadow rays to the first light (any hit),
//! each ray at its own time in the shutter, through the static and the moving world, side by
//! side (medians of REPS interleaved rounds, on the current rayon pool), and prints both
//! speeds and their ratio. With `MESH=1` the instances stay still and every triangle geometry
//! deforms instead (a moving mesh of two steps: swelling by a tenth about its box's centre and
//! sheared by a tenth of its height over the shutter). Built with `--features embree` (and not
//! `DECOMPOSED=1`, which Embree's linear keys do not express), Embree 3's world of the same
//! geometries, instances, keys and time steps runs beside them on the same rays
//! (`rtcIntersect1` / `rtcOccluded1`). With `PROFILE=1` it only prints each world's nodes,
//! leaves and primitive tests per eye ray and traces the moving world (the static one with
//! `STILL=1`) REPS times, for a profiler.
use glam::{Affine3A, Vec3, Vec3A};
use quiver_lab::measure::{median_times_interleaved, mrays_per_s, trace, Query};
use quiver_lab::rays;
use quiver_rt::world::Geometry;
use quiver_rt::{Aabb, BuildOptions, Motion, RayQuery, Triangle, World};
use quiver_scenes::instanced::Instanced;
use quiver_scenes::scene::tessellate::DEFAULT_RESOLUTION;
use quiver_scenes::Scene;

/// Triangles `tris` swollen by a tenth about their box's centre and sheared along x by a
/// tenth of their height: the deforming mesh's second step.
fn deformed(tris: &[Triangle]) -> Vec<Triangle> {
    let b = tris.iter().fold(Aabb::EMPTY, |b, t| b.union(&t.bounds()));
    let c = (b.min + b.max) * 0.5;
    let f = |v: Vec3A| {
        let d = v - c;
        c + d * 1.1 + Vec3A::new(0.1 * d.y, 0.0, 0.0)
    };
    tris.iter()
        .map(|t| Triangle::new(f(t.v[0]), f(t.v[1]), f(t.v[2])))
        .collect()
}

/// The world of `w`'s geometries and instances, every non-identity instance moving by
/// `motion(transform)` when given, every triangle geometry deforming when `mesh`.
fn rebuilt(w: &World, motion: Option<&dyn Fn(Affine3A) -> Motion>, mesh: bool) -> World {
    let mut b = World::builder();
    for g in w.geometries() {
        match g {
            Geometry::Triangles(_, tris) if mesh => b
                .add_moving_triangles(vec![tris.clone(), deformed(tris)])
                .expect("a moving mesh"),
            Geometry::Triangles(_, tris) => b.add_triangles(tris.clone()),
            Geometry::Prims(_, tris) => b.add_prims(tris.clone()),
            Geometry::MovingTriangles(m) => b.add_moving_triangles(m.steps().to_vec()).unwrap(),
        };
    }
    for inst in w.instances() {
        match motion {
            Some(m) if inst.transform != Affine3A::IDENTITY => {
                b.add_moving_instance(*inst, m(inst.transform))
            }
            _ => b.add_instance(*inst),
        };
    }
    b.build(&BuildOptions::default()).expect("the same world")
}

fn main() {
    let a: Vec<String> = std::env::args().collect();
    let name = a.get(1).map_or("balls4", |s| s.as_str());
    let res: usize = a.get(2).map_or(1024, |s| s.parse().expect("RES"));
    let reps: usize = a.get(3).map_or(5, |s| s.parse().expect("REPS"));
    let decomposed = std::env::var("DECOMPOSED").is_ok_and(|v| v == "1");
    let scene = Scene::load(name).expect("scene");
    let inst = Instanced::build(&scene, DEFAULT_RESOLUTION, &BuildOptions::default())
        .expect("an instanced world");
    let move_it = |m: Affine3A| {
        let size = m.matrix3.x_axis.length();
        let drift = Affine3A::from_translation(Vec3::new(0.5 * size, 0.0, 0.0));
        if decomposed {
            let turn = Affine3A::from_rotation_y(std::f32::consts::FRAC_PI_2);
            Motion::decomposed(vec![m, drift * m * turn])
        } else {
            Motion::linear(vec![m, drift * m])
        }
    };
    let mesh = std::env::var("MESH").is_ok_and(|v| v == "1");
    let still = rebuilt(inst.world(), None, false);
    let moving = match mesh {
        true => rebuilt(inst.world(), None, true),
        false => rebuilt(inst.world(), Some(&move_it), false),
    };
    let eye = rays::timed(rays::camera_rays(&scene.camera, res));
    let light = scene.lights.first().map_or(scene.camera.from, |l| l.pos);
    let shadow = rays::timed(rays::shadow_rays(&inst, &eye, &[light]));
    // PROFILE=1 traces the moving world alone, REPS times, for a profiler to read.
    if std::env::var("PROFILE").is_ok_and(|v| v == "1") {
        for (label, w) in [("static", &still), ("moving", &moving)] {
            let mut c = quiver_rt::traverse::Counters::default();
            for r in eye.iter().step_by(16) {
                w.closest_hit_with::<quiver_rt::traverse::FastBoxes, _, _>(
                    r,
                    &mut c,
                    &mut quiver_rt::traverse::NoFilter,
                );
            }
            let n = eye.len().div_ceil(16) as f64;
            println!(
                "{label}: per eye ray {:.2} nodes, {:.2} leaves, {:.2} prim tests",
                c.nodes as f64 / n,
                c.leaves as f64 / n,
                c.prim_tests as f64 / n
            );
        }
        let w = match std::env::var("STILL").is_ok_and(|v| v == "1") {
            true => &still,
            false => &moving,
        };
        for _ in 0..reps {
            let e = trace(w, &eye, Query::Closest);
            let s = trace(w, &shadow, Query::Any);
            println!("{name} moving alone: {e} eye hits, {s} shadow hits");
        }
        return;
    }
    #[cfg(feature = "embree")]
    let embree = (!decomposed).then(|| embree_world(inst.world(), &move_it, mesh));
    for (label, rays, query) in [
        ("eye", &eye, Query::Closest),
        ("shadow", &shadow, Query::Any),
    ] {
        #[cfg(feature = "embree")]
        if let Some(e) = &embree {
            let run = |i: usize| match i {
                0 => trace(&moving, rays, query),
                _ => match query {
                    Query::Closest => rays.iter().filter(|r| e.closest_hit(r).is_some()).count(),
                    _ => rays.iter().filter(|r| e.any_hit(r)).count(),
                },
            };
            let hits = [run(0), run(1)];
            let times = median_times_interleaved(reps, 2, |i| {
                std::hint::black_box(run(i));
            });
            let [q, e] = [0, 1].map(|i| mrays_per_s(rays.len(), times[i]));
            println!(
                "{name} {label} moving: quiver {q:.2} Mrays/s ({} hits), Embree {e:.2} Mrays/s \
                 ({} hits), quiver / Embree {:.3}",
                hits[0],
                hits[1],
                q / e
            );
        }
        let hits = [trace(&still, rays, query), trace(&moving, rays, query)];
        let times = median_times_interleaved(reps, 2, |i| {
            std::hint::black_box(trace([&still, &moving][i], rays, query));
        });
        let [s, m] = [0, 1].map(|i| mrays_per_s(rays.len(), times[i]));
        println!(
            "{name} {label} {} rays ({} {} hits static / moving): static {s:.2} Mrays/s, \
             moving {m:.2} Mrays/s, moving / static {:.3}",
            rays.len(),
            hits[0],
            hits[1],
            m / s
        );
    }
}

/// Embree's world of `w`'s triangle geometries and instances: every non-identity instance
/// moving by `motion`'s linear keys, or, when `mesh`, every geometry deforming as
/// [`deformed`] makes its second step.
#[cfg(feature = "embree")]
fn embree_world(
    w: &World,
    motion: &dyn Fn(Affine3A) -> Motion,
    mesh: bool,
) -> quiver_lab::embree::EmbreeScene {
    use quiver_lab::embree::{EmbreeDevice, EmbreeScene};
    let steps: Vec<Vec<Vec<Triangle>>> = w
        .geometries()
        .iter()
        .map(|g| match g {
            Geometry::Triangles(_, tris) if mesh => vec![tris.clone(), deformed(tris)],
            Geometry::Triangles(_, tris) => vec![tris.clone()],
            _ => panic!("the probe's Embree world holds triangle geometries only"),
        })
        .collect();
    let keys: Vec<Vec<Affine3A>> = w
        .instances()
        .iter()
        .map(|i| match mesh || i.transform == Affine3A::IDENTITY {
            true => vec![i.transform],
            false => motion(i.transform).keys().to_vec(),
        })
        .collect();
    let placed: Vec<(u32, &[Affine3A], u32)> = w
        .instances()
        .iter()
        .zip(&keys)
        .map(|(i, k)| (i.geometry.0, &k[..], i.mask))
        .collect();
    let steps: Vec<Vec<&[Triangle]>> = steps
        .iter()
        .map(|g| g.iter().map(|s| &s[..]).collect())
        .collect();
    let steps: Vec<&[&[Triangle]]> = steps.iter().map(|g| &g[..]).collect();
    let device = EmbreeDevice::new().expect("an Embree device");
    EmbreeScene::instanced_deforming(&device, &steps, &placed).expect("Embree's world")
}
