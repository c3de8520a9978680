//! Point-query probe: `RAYON_NUM_THREADS=1 cargo run --release -p quiver-lab --features embree
//! --example point_probe -- [SCENE ...]` times closest-point queries on SCENE (SPD generator
//! names or mesh files; default balls4 lattice6 teapot40 tetra8) in quiver, Embree 3
//! (`rtcPointQuery` with a callback that measures each offered triangle by quiver's own
//! `Triangle::closest_point`, [`EmbreeScene::closest_point`]) and a brute-force scan over every
//! triangle, on one thread, in sequential loops: (a) the flat scene (its triangles, patches
//! tessellated) as one default `Bvh` against one Embree scene, (b) the scene as instances of
//! unit shapes (`quiver_scenes::instanced::Instanced`, the world `quiver bench --instanced`
//! measures) as a quiver `World` against Embree's instanced scene of the same geometries and
//! transforms, distances in world space in both.
//!
//! Two point sets per scene: `box`, POINTS points uniform in the scene's box, searched without
//! a limit; `near`, POINTS points on random triangles moved along their normals by up to a
//! thousandth of the box's extent, searched within a hundredth of it. The brute-force scan runs
//! on the first few points only (as many as about 2·10^7 triangle tests a round allow) and is
//! scaled to a per-query rate. Speeds are medians of REPS interleaved rounds
//! ([`median_times_interleaved`]), in million queries per second. Every query's distance is
//! compared between quiver and Embree (and, on the scan's points, the scan): a mismatch is a
//! difference of more than 8 f32 roundings of the distance plus the scene's size; exact ties
//! may name different triangles (counted as `other`). Environment: `POINTS` (default
//! 100,000), `REPS` (default 5), `SEED`.
//!
//! `PROFILE=flat-near` (or `flat-box`, `world-near`, `world-box`) runs quiver's queries of
//! that set alone, REPS rounds, and prints their rate: a loop for `perf` or callgrind.
//!
//! Without `--features embree` the Embree column is absent.
use glam::Vec3A;
use quiver_lab::measure::median_times_interleaved;
use quiver_rt::world::Geometry;
use quiver_rt::{Aabb, BuildOptions, Bvh, Triangle, World};
use quiver_scenes::instanced::Instanced;
use quiver_scenes::rng::Rng;
use quiver_scenes::scene::tessellate::DEFAULT_RESOLUTION;
use quiver_scenes::Scene;
use std::hint::black_box;
use std::time::Duration;

/// A point set and the radius its queries search within.
struct Points {
    kind: &'static str,
    pts: Vec<Vec3A>,
    radius: f32,
}

/// One closest-point answer as the probe compares them: the distance and a name of the
/// triangle (instance, primitive).
type Answer = Option<(f32, (u32, u32))>;

/// The `box` and `near` point sets of `tris` (world space).
fn point_sets(tris: &[Triangle], n: usize, seed: u64) -> [Points; 2] {
    let b = bounds(tris);
    let extent = (b.max - b.min).max_element();
    let mut rng = Rng::new(seed);
    let inside = (0..n).map(|_| rng.in_box(b.min, b.max)).collect();
    let near = (0..n)
        .map(|_| {
            let t = &tris[(rng.next_u64() % tris.len() as u64) as usize];
            let (mut u, mut v) = (rng.f32(), rng.f32());
            if u + v > 1.0 {
                (u, v) = (1.0 - u, 1.0 - v);
            }
            let (ab, ac) = (t.v[1] - t.v[0], t.v[2] - t.v[0]);
            let n = ab.cross(ac).normalize_or_zero();
            t.v[0] + ab * u + ac * v + n * (extent * 1e-3 * rng.range(-1.0, 1.0))
        })
        .collect();
    [
        Points {
            kind: "box",
            pts: inside,
            radius: f32::INFINITY,
        },
        Points {
            kind: "near",
            pts: near,
            radius: extent * 1e-2,
        },
    ]
}

fn bounds(tris: &[Triangle]) -> Aabb {
    tris.iter().fold(Aabb::EMPTY, |b, t| b.union(&t.bounds()))
}

/// The nearest of all `tris` to `p` within `r`, every triangle measured.
fn brute(tris: &[Triangle], p: Vec3A, r: f32) -> Answer {
    let w = |v: Vec3A| glam::DVec3::new(v.x as f64, v.y as f64, v.z as f64);
    let mut best: Option<(f64, u32)> = None;
    for (i, t) in tris.iter().enumerate() {
        let d = (w(p) - w(t.closest_point(p).0)).length();
        if best.is_none_or(|(bd, _)| d < bd) {
            best = Some((d, i as u32));
        }
    }
    best.filter(|&(d, _)| d <= r as f64)
        .map(|(d, i)| (d as f32, (0, i)))
}

/// The world's triangles placed in world space, instance by instance.
fn placed(world: &World) -> Vec<Triangle> {
    world
        .instances()
        .iter()
        .flat_map(|inst| {
            let tris: &[Triangle] = match &world.geometries()[inst.geometry.0 as usize] {
                Geometry::Triangles(_, t) | Geometry::Prims(_, t) => t,
                Geometry::MovingTriangles(m) => &m.steps()[0],
            };
            let m = inst.transform;
            tris.iter().map(move |t| Triangle {
                v: t.v.map(|v| m.transform_point3a(v)),
            })
        })
        .collect()
}

/// One row of the table.
struct Row {
    scene: String,
    what: String,
    queries: usize,
    rates: Vec<f64>,
    mismatches: usize,
    other: usize,
    brute_checked: usize,
    brute_mismatches: usize,
}

/// An engine answering closest-point queries.
type Engine<'a> = Box<dyn Fn(Vec3A, f32) -> Answer + 'a>;

/// Times `engines` (the last one the brute-force scan, on the first `sub` points) on `set`,
/// and compares their answers.
fn measure(
    scene: &str,
    what: &str,
    set: &Points,
    engines: &[Engine],
    sub: usize,
    size: f32,
    reps: usize,
) -> Row {
    let last = engines.len() - 1;
    let count = |i: usize| if i == last { sub } else { set.pts.len() };
    let answers: Vec<Vec<Answer>> = engines
        .iter()
        .enumerate()
        .map(|(i, e)| {
            set.pts[..count(i)]
                .iter()
                .map(|&p| e(p, set.radius))
                .collect()
        })
        .collect();
    let times: Vec<Duration> = median_times_interleaved(reps, engines.len(), |i| {
        for &p in &set.pts[..count(i)] {
            black_box(engines[i](black_box(p), set.radius));
        }
    });
    let rates = times
        .iter()
        .enumerate()
        .map(|(i, t)| count(i) as f64 / t.as_secs_f64() / 1e6)
        .collect();
    let differ = |a: &Answer, b: &Answer| match (a, b) {
        (None, None) => false,
        (Some((a, _)), Some((b, _))) => (a - b).abs() > 8.0 * f32::EPSILON * (a.max(*b) + size),
        _ => true,
    };
    let names = |a: &Answer, b: &Answer| matches!((a, b), (Some((_, x)), Some((_, y))) if x != y);
    let (q, e) = (&answers[0], &answers[1.min(last)]);
    let mut mismatches = 0;
    let mut other = 0;
    if last > 1 {
        for (k, (a, b)) in q.iter().zip(e).enumerate() {
            if differ(a, b) {
                if mismatches < 5 {
                    println!(
                        "  {scene} {what}: point {} quiver {a:?}, Embree {b:?}",
                        set.pts[k]
                    );
                }
                mismatches += 1;
            } else if names(a, b) {
                other += 1;
            }
        }
    }
    let brute_mismatches = q
        .iter()
        .zip(&answers[last])
        .filter(|(a, b)| differ(a, b))
        .count();
    Row {
        scene: scene.to_string(),
        what: what.to_string(),
        queries: set.pts.len(),
        rates,
        mismatches,
        other,
        brute_checked: sub,
        brute_mismatches,
    }
}

/// Brute-force points a round: about 2·10^7 triangle tests.
fn brute_points(tris: usize, n: usize) -> usize {
    (20_000_000 / tris.max(1)).clamp(8, n)
}

/// `PROFILE=flat-near` (or `flat-box`, `world-near`, `world-box`): quiver's queries of that
/// set alone, REPS rounds, for `perf` or callgrind.
fn profile(
    spec: &str,
    bvh: &Bvh,
    world: &World,
    tris: [&Vec<Triangle>; 2],
    n: usize,
    seed: u64,
    reps: usize,
) {
    let (what, kind) = spec
        .split_once('-')
        .expect("PROFILE=flat-near, world-box, ...");
    let flat = what == "flat";
    let set = point_sets(tris[usize::from(!flat)], n, seed)
        .into_iter()
        .find(|s| s.kind == kind)
        .expect("PROFILE's point set: box or near");
    let start = std::time::Instant::now();
    let mut found = 0;
    for _ in 0..reps {
        for &p in &set.pts {
            found += usize::from(if flat {
                bvh.closest_point(p, set.radius).is_some()
            } else {
                world.closest_point(p, set.radius).is_some()
            });
        }
    }
    let queries = (reps * set.pts.len()) as f64;
    println!(
        "  {spec}: {:.3} Mq/s, {found} found",
        queries / start.elapsed().as_secs_f64() / 1e6
    );
}

fn main() {
    let mut names: Vec<String> = std::env::args().skip(1).collect();
    if names.is_empty() {
        names = ["balls4", "lattice6", "teapot40", "tetra8"]
            .map(String::from)
            .to_vec();
    }
    let env = |k: &str, d: u64| std::env::var(k).map_or(d, |v| v.parse().expect(k));
    let n = env("POINTS", 100_000) as usize;
    let reps = env("REPS", 5) as usize;
    let seed = env("SEED", 1);
    #[cfg(feature = "embree")]
    let device = quiver_lab::embree::EmbreeDevice::new().expect("an Embree device");
    let mut rows = Vec::new();
    for name in &names {
        let scene = Scene::load(name).expect("scene");
        let flat = scene.clone().into_patches(DEFAULT_RESOLUTION).triangles();
        let bvh = Bvh::new(&flat);
        let inst = Instanced::build(&scene, DEFAULT_RESOLUTION, &BuildOptions::default())
            .expect("an instanced world");
        let world = inst.world();
        let world_tris = placed(world);
        println!(
            "{name}: {} triangles flat; world of {} instances over {} geometries, {} placed",
            flat.len(),
            world.instances().len(),
            world.geometries().len(),
            world_tris.len()
        );
        if let Ok(spec) = std::env::var("PROFILE") {
            profile(&spec, &bvh, world, [&flat, &world_tris], n, seed, reps);
            continue;
        }
        #[cfg(feature = "embree")]
        let (e_flat, e_world) = (
            quiver_lab::embree::EmbreeScene::on_device(&device, &flat).expect("Embree's scene"),
            quiver_lab::embree::EmbreeScene::of_world_for_points(&device, world)
                .expect("Embree's world"),
        );
        // Embree's instances as built for rays, which 3.13 answers wrongly under shrinking
        // similarities (see `EmbreeScene::of_world_for_points`): how often, on the near points.
        #[cfg(feature = "embree")]
        {
            let plain = quiver_lab::embree::EmbreeScene::of_world(&device, world).unwrap();
            let set = &point_sets(&world_tris, n.min(20_000), seed)[1];
            let wrong = set
                .pts
                .iter()
                .filter(|&&p| {
                    let q = world.closest_point(p, set.radius).map(|h| h.distance);
                    let e = plain.closest_point(p, set.radius).map(|h| h.distance);
                    q != e
                        && (q.is_none()
                            || e.is_none()
                            || (q.unwrap() - e.unwrap()).abs() > 1e-5 * q.unwrap())
                })
                .count();
            println!(
                "  Embree's instances without the rescaling: {wrong} of {} near answers wrong",
                set.pts.len()
            );
        }
        for (what, tris) in [("flat", &flat), ("world", &world_tris)] {
            let b = bounds(tris);
            let size = (b.max - b.min).max_element() + b.min.abs().max(b.max.abs()).max_element();
            let mut engines: Vec<Engine> = Vec::new();
            if what == "flat" {
                engines.push(Box::new(|p, r| {
                    bvh.closest_point(p, r).map(|h| (h.distance, (0, h.prim)))
                }));
                #[cfg(feature = "embree")]
                engines.push(Box::new(|p, r| {
                    e_flat
                        .closest_point(p, r)
                        .map(|h| (h.distance, (0, h.prim)))
                }));
            } else {
                engines.push(Box::new(|p, r| {
                    world
                        .closest_point(p, r)
                        .map(|h| (h.distance, (h.instance.0, h.prim)))
                }));
                #[cfg(feature = "embree")]
                engines.push(Box::new(|p, r| {
                    e_world
                        .closest_point(p, r)
                        .map(|h| (h.distance, (h.instance.unwrap_or(0), h.prim)))
                }));
            }
            engines.push(Box::new(move |p, r| brute(tris, p, r)));
            let sub = brute_points(tris.len(), n);
            for set in point_sets(tris, n, seed) {
                let row = measure(name, what, &set, &engines, sub, size, reps);
                println!(
                    "  {what} {}: {:.3?} Mq/s, {} mismatches ({} other triangle at equal \
                     distance), brute {}/{} mismatches",
                    set.kind,
                    row.rates,
                    row.mismatches,
                    row.other,
                    row.brute_mismatches,
                    row.brute_checked
                );
                rows.push(Row {
                    what: format!("{what} {}", set.kind),
                    ..row
                });
            }
        }
    }
    println!();
    println!(
        "| scene | points | queries | quiver Mq/s | Embree Mq/s | brute Mq/s | quiver / Embree \
         | mismatches |"
    );
    println!("|---|---|---:|---:|---:|---:|---:|---:|");
    for r in &rows {
        let (q, b) = (r.rates[0], r.rates[r.rates.len() - 1]);
        let (e, ratio) = match r.rates.len() {
            3 => (
                format!("{:.3}", r.rates[1]),
                format!("{:.2}", q / r.rates[1]),
            ),
            _ => ("-".into(), "-".into()),
        };
        println!(
            "| {} | {} | {} | {q:.3} | {e} | {b:.5} | {ratio} | {} |",
            r.scene,
            r.what,
            r.queries,
            r.mismatches + r.brute_mismatches
        );
    }
}
