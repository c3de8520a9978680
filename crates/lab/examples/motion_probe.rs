//! Motion blur's price: `cargo run --release -p quiver-lab --example motion_probe -- SCENE RES REPS`
//! builds SCENE (an SPD generator name) as instances of unit shapes (the world `quiver bench
//! --instanced` measures), then the same world twice more from its geometries: once static,
//! once with every placed shape moving (a linear drift of half its size over the shutter, or,
//! with `DECOMPOSED=1`, a decomposed quarter turn about its vertical axis as it drifts). It
//! traces the RES² eye rays (closest hit) and their shadow rays to the first light (any hit),
//! each ray at its own time in the shutter, through the static and the moving world, side by
//! side (medians of REPS interleaved rounds, on the current rayon pool), and prints both
//! speeds and their ratio.
use glam::{Affine3A, Vec3};
use quiver_lab::measure::{median_times_interleaved, mrays_per_s, trace, Query};
use quiver_lab::rays;
use quiver_rt::world::Geometry;
use quiver_rt::{BuildOptions, Motion, World};
use quiver_scenes::instanced::Instanced;
use quiver_scenes::scene::tessellate::DEFAULT_RESOLUTION;
use quiver_scenes::Scene;

/// The world of `w`'s geometries and instances, every non-identity instance moving by
/// `motion(transform)` when given.
fn rebuilt(w: &World, motion: Option<&dyn Fn(Affine3A) -> Motion>) -> World {
    let mut b = World::builder();
    for g in w.geometries() {
        match g {
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
    let still = rebuilt(inst.world(), None);
    let moving = rebuilt(inst.world(), Some(&move_it));
    let eye = rays::timed(rays::camera_rays(&scene.camera, res));
    let light = scene.lights.first().map_or(scene.camera.from, |l| l.pos);
    let shadow = rays::timed(rays::shadow_rays(&inst, &eye, &[light]));
    for (label, rays, query) in [
        ("eye", &eye, Query::Closest),
        ("shadow", &shadow, Query::Any),
    ] {
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
