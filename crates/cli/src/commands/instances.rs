//! `quiver bench --instanced` and `quiver packets --instanced`: an SPD scene in patch mode traced
//! as a world of instances (every sphere and cone an instance of a tessellated unit shape)
//! beside the same scene flattened to world-space triangles, and, built with the `embree`
//! feature, Embree's instanced scene over the same unit meshes and transforms
//! (`RTC_GEOMETRY_TYPE_INSTANCE`) and its flattened one: build time, memory, and Mrays/s for
//! eye, shadow and incoherent rays one at a time, for the eye and shadow rays in 8 x 8 tiles
//! as packets (Embree's coherent streams), the price of a filter that accepts everything
//! and of masks that exclude nothing, and motion blur's: the same world with every sphere
//! and cone moving ([`instanced::scatter`]) against it static, on the same rays, each at its
//! own time.

use super::{measured_threads, pool, Result};
use crate::output::{outln, write_json};
#[cfg(feature = "embree")]
use quiver_lab::embree::{EmbreeDevice, EmbreeScene};
use quiver_lab::measure::{
    count_hits, median_times_interleaved, mrays_per_s, trace_packets, Query,
};
use quiver_lab::rays;
use quiver_rt::traverse::PacketMode;
use quiver_rt::{Hit, Ray, RayQuery};
use quiver_scenes::accel::SceneBvh;
use quiver_scenes::instanced::{self, Instanced};
use quiver_scenes::scene::{tessellate, Scene};
use serde_json::{json, Value};
use std::path::PathBuf;
use std::time::Instant;

/// What the instanced measurement takes from `bench` or `packets`.
pub(crate) struct Settings {
    /// The scenes, loaded in curve mode.
    pub scenes: Vec<Scene>,
    /// Incoherent rays per scene.
    pub rays: usize,
    /// Timed rounds per measurement (median).
    pub reps: usize,
    /// Thread counts.
    pub threads: Vec<u16>,
    /// JSON output.
    pub json: Option<PathBuf>,
}

/// The scenes measured without arguments: spheres (balls) and cylinders with spheres
/// (lattice), the two SPD families made of affine images of one shape.
pub(crate) const DEFAULT_SCENES: [&str; 2] = ["balls4", "lattice6"];

fn ms<T>(f: impl FnOnce() -> T) -> (T, f64) {
    let t = Instant::now();
    let v = f();
    (v, t.elapsed().as_secs_f64() * 1e3)
}

/// The world's unit meshes and instances as Embree takes them, a moving instance with its
/// motion's keys as Embree's time steps (the bench's motions are linear, as Embree's are).
#[cfg(feature = "embree")]
fn embree_instanced(world: &quiver_rt::World, device: &EmbreeDevice) -> Result<EmbreeScene> {
    Ok(EmbreeScene::of_world(device, world)?)
}

/// Loads `names` (or [`DEFAULT_SCENES`]) within the memory limit for the instanced
/// measurement: each scene with its patch-mode copy and flattened build beside its instanced
/// one, plus the rays.
pub(crate) fn load(command: &str, names: &[String], rays: usize) -> Result<Vec<Scene>> {
    let names = if names.is_empty() {
        DEFAULT_SCENES.map(String::from).to_vec()
    } else {
        names.to_vec()
    };
    super::load_within(&names, |censuses, _| {
        let what = format!("{command} --instanced {}", names.join(" "));
        let mut e = super::build_estimate(&what, censuses, true);
        let instanced = super::instanced_estimate(&what, censuses);
        e.add("the instanced build", instanced.total());
        e.add(
            format!("{} incoherent rays", crate::budget::count(rays as u64)),
            rays as u64 * 72,
        );
        e
    })
}

/// `command --instanced` (`bench` or `packets`): loads the scenes ([`load`]) and measures
/// them ([`run`]).
pub(crate) fn load_and_run(
    command: &str,
    names: &[String],
    rays: usize,
    reps: usize,
    threads: &[u16],
    json: Option<&PathBuf>,
) -> Result<()> {
    let scenes = load(command, names, rays)?;
    run(Settings {
        scenes,
        rays,
        reps,
        threads: threads.to_vec(),
        json: json.cloned(),
    })
}

/// Runs the instanced measurement.
pub(crate) fn run(s: Settings) -> Result<()> {
    let loaded = &s.scenes;
    let thread_counts = measured_threads(&s.threads);
    let mut rows: Vec<Value> = Vec::new();
    let mut memory: Vec<Value> = Vec::new();
    let res = tessellate::DEFAULT_RESOLUTION;
    for scene in loaded {
        let options = quiver_rt::BuildOptions::default();
        let patched = scene.clone().into_patches(res);
        let tris = patched.triangles();
        let (flat, flat_ms) = ms(|| SceneBvh::build_triangles(&patched, &options));
        let flat = flat?;
        let (inst, inst_ms) = ms(|| SceneBvh::build_instanced(scene, res, &options));
        let inst = inst?;
        let (world_ms, world) = {
            let (w, t) = ms(|| Instanced::build(scene, res, &options));
            (t, w?)
        };
        let instances = world.world().instances().len();
        let (moving, moving_ms) =
            ms(|| SceneBvh::build_instanced_moving(scene, res, &options, &instanced::scatter));
        let moving = moving?;
        let row = |engine: &str,
                   kernel: &str,
                   rays: &str,
                   threads: usize,
                   mrays: Option<f64>,
                   build: Option<f64>| {
            json!({"scene": scene.name, "triangles": tris.len(), "instances": instances,
                   "engine": engine, "kernel": kernel, "rays": rays, "threads": threads,
                   "mrays_per_s": mrays, "build_ms": build})
        };
        rows.push(row("quiver", "flattened", "build", 0, None, Some(flat_ms)));
        rows.push(row(
            "quiver",
            "instanced",
            "build",
            0,
            None,
            Some(inst_ms.min(world_ms)),
        ));
        rows.push(row(
            "quiver",
            "instanced+motion",
            "build",
            0,
            None,
            Some(moving_ms),
        ));
        let mem = |engine: &str, kernel: &str, bytes: usize| json!({"scene": scene.name, "engine": engine, "kernel": kernel, "bytes": bytes});
        memory.push(mem("quiver", "flattened", flat.footprint().bytes));
        memory.push(mem("quiver", "instanced", inst.footprint().bytes));
        memory.push(mem("quiver", "instanced+motion", moving.footprint().bytes));
        #[cfg(feature = "embree")]
        let device = EmbreeDevice::new()?;
        #[cfg(feature = "embree")]
        let (e_flat, e_flat_ms) = ms(|| EmbreeScene::on_device(&device, &tris));
        #[cfg(feature = "embree")]
        let e_flat = e_flat?;
        #[cfg(feature = "embree")]
        let (e_inst, e_inst_ms) = ms(|| embree_instanced(world.world(), &device));
        #[cfg(feature = "embree")]
        let e_inst = e_inst?;
        #[cfg(feature = "embree")]
        let moving_world = Instanced::build_moving(scene, res, &options, &instanced::scatter)?;
        #[cfg(feature = "embree")]
        let (e_moving, e_moving_ms) = ms(|| embree_instanced(moving_world.world(), &device));
        #[cfg(feature = "embree")]
        let e_moving = e_moving?;
        #[cfg(feature = "embree")]
        {
            rows.push(row(
                "embree",
                "flattened",
                "build",
                0,
                None,
                Some(e_flat_ms),
            ));
            rows.push(row(
                "embree",
                "instanced",
                "build",
                0,
                None,
                Some(e_inst_ms),
            ));
            memory.push(mem("embree", "flattened", e_flat.bvh_bytes()));
            memory.push(mem("embree", "instanced", e_inst.bvh_bytes()));
            rows.push(row(
                "embree",
                "instanced+motion",
                "build",
                0,
                None,
                Some(e_moving_ms),
            ));
            memory.push(mem("embree", "instanced+motion", e_moving.bvh_bytes()));
        }
        let eye = rays::camera_rays(&scene.camera, 256);
        let light = scene
            .lights
            .first()
            .map(|l| l.pos)
            .unwrap_or(scene.camera.from);
        let shadow = rays::shadow_rays(&flat, &eye, &[light]);
        let incoherent = rays::random_rays(&patched.bounds(), s.rays, 11);
        let tiles = rays::camera_tiles(&scene.camera, 256, 8);
        let tile_shadow = rays::shadow_rays(&flat, &tiles, &[light]);
        let masked: Vec<Ray> = eye.iter().map(|r| r.with_mask(0b1)).collect();
        // The same rays, each at its own time in the shutter, for the static and moving worlds.
        let timed = [
            ("eye-timed", rays::timed(eye.clone()), Query::Closest),
            ("shadow-timed", rays::timed(shadow.clone()), Query::Any),
            (
                "eye-tiles-timed",
                rays::timed(tiles.clone()),
                Query::Closest,
            ),
        ];
        for &threads in &thread_counts {
            let p = pool(Some(threads))?;
            // Single rays: flattened, instanced, instanced with an accept-all filter, and
            // (with the feature) Embree's instanced and flattened scenes.
            let engines = 3 + 2 * usize::from(cfg!(feature = "embree"));
            for (kind, set, any) in [
                ("eye", &eye, false),
                ("shadow", &shadow, true),
                ("incoherent", &incoherent, false),
            ] {
                let times = p.install(|| {
                    median_times_interleaved(s.reps, engines, |i| {
                        let hits = match i {
                            0 => trace_one(&flat, set, any),
                            1 => trace_one(&inst, set, any),
                            2 => count_hits(set, |r| {
                                if any {
                                    inst.any_hit_filtered(r, |_: &Hit| true)
                                } else {
                                    inst.closest_hit_filtered(r, |_: &Hit| true).is_some()
                                }
                            }),
                            #[cfg(feature = "embree")]
                            3 => count_hits(set, |r| {
                                if any {
                                    e_inst.any_hit(r)
                                } else {
                                    e_inst.closest_hit(r).is_some()
                                }
                            }),
                            #[cfg(feature = "embree")]
                            4 => count_hits(set, |r| {
                                if any {
                                    e_flat.any_hit(r)
                                } else {
                                    e_flat.closest_hit(r).is_some()
                                }
                            }),
                            _ => 0,
                        };
                        std::hint::black_box(hits);
                    })
                });
                let names = [
                    ("quiver", "flattened"),
                    ("quiver", "instanced"),
                    ("quiver", "instanced+filter"),
                    ("embree", "instanced"),
                    ("embree", "flattened"),
                ];
                for (&(e, k), t) in names.iter().zip(&times) {
                    rows.push(row(
                        e,
                        k,
                        kind,
                        threads,
                        Some(mrays_per_s(set.len(), *t)),
                        None,
                    ));
                }
            }
            // Masks that exclude nothing: the eye rays with mask 1 (every instance has every
            // bit), against the default mask.
            let times = p.install(|| {
                median_times_interleaved(s.reps, 2, |i| {
                    let set = if i == 0 { &eye } else { &masked };
                    std::hint::black_box(trace_one(&inst, set, false));
                })
            });
            rows.push(row(
                "quiver",
                "instanced",
                "eye",
                threads,
                Some(mrays_per_s(eye.len(), times[0])),
                None,
            ));
            rows.push(row(
                "quiver",
                "instanced+mask",
                "eye",
                threads,
                Some(mrays_per_s(eye.len(), times[1])),
                None,
            ));
            // Packets: quiver's through the instances, Embree's coherent streams.
            for (kind, set, any) in [
                ("eye-tiles", &tiles, false),
                ("shadow-tiles", &tile_shadow, true),
            ] {
                let query = if any { Query::Any } else { Query::Closest };
                let n = 2 + usize::from(cfg!(feature = "embree"));
                let times = p.install(|| {
                    median_times_interleaved(s.reps, n, |i| match i {
                        0 => {
                            std::hint::black_box(trace_packets(
                                &flat,
                                set,
                                query,
                                PacketMode::Auto,
                            ));
                        }
                        1 => {
                            std::hint::black_box(trace_packets(
                                &inst,
                                set,
                                query,
                                PacketMode::Auto,
                            ));
                        }
                        #[cfg(feature = "embree")]
                        _ => {
                            std::hint::black_box(e_inst.count_hits(set, any, true));
                        }
                        #[cfg(not(feature = "embree"))]
                        _ => {}
                    })
                });
                let names = [
                    ("quiver", "flattened-packets"),
                    ("quiver", "instanced-packets"),
                    ("embree", "instanced-stream"),
                ];
                for (&(e, k), t) in names.iter().zip(&times) {
                    rows.push(row(
                        e,
                        k,
                        kind,
                        threads,
                        Some(mrays_per_s(set.len(), *t)),
                        None,
                    ));
                }
            }
            // Motion blur: the static world against the moving one on the same timed rays
            // (single rays, then the eye tiles as packets, whose rays differ in time), and
            // (with the feature) Embree's static and motion-blurred instances, its streams
            // for the tiles.
            for (kind, set, query) in &timed {
                let packets = kind.contains("tiles");
                let any = *query == Query::Any;
                let n = 2 + 2 * usize::from(cfg!(feature = "embree"));
                let times = p.install(|| {
                    median_times_interleaved(s.reps, n, |i| {
                        let hits = match i {
                            0 | 1 => {
                                let q = [&inst, &moving][i];
                                match packets {
                                    true => trace_packets(q, set, *query, PacketMode::Auto),
                                    false => trace_one(q, set, any),
                                }
                            }
                            #[cfg(feature = "embree")]
                            _ => [&e_inst, &e_moving][i - 2].count_hits(set, any, packets),
                            #[cfg(not(feature = "embree"))]
                            _ => 0,
                        };
                        std::hint::black_box(hits);
                    })
                });
                let kernels = match packets {
                    true => [
                        ("quiver", "instanced-packets"),
                        ("quiver", "instanced+motion-packets"),
                        ("embree", "instanced-stream"),
                        ("embree", "instanced+motion-stream"),
                    ],
                    false => [
                        ("quiver", "instanced"),
                        ("quiver", "instanced+motion"),
                        ("embree", "instanced"),
                        ("embree", "instanced+motion"),
                    ],
                };
                for (&(e, k), t) in kernels.iter().zip(&times) {
                    let mrays = Some(mrays_per_s(set.len(), *t));
                    rows.push(row(e, k, kind, threads, mrays, None));
                }
            }
        }
    }
    print(&rows, &memory);
    write_json(s.json.as_ref(), &json!({"rows": rows, "memory": memory}))
}

/// How many rays hit, one ray at a time on the current pool.
fn trace_one<Q: RayQuery + Sync>(q: &Q, rays: &[Ray], any: bool) -> usize {
    count_hits(rays, |r| {
        if any {
            q.any_hit(r)
        } else {
            q.closest_hit(r).is_some()
        }
    })
}

/// The table: per scene, ray kind and thread count, each engine's Mrays/s, and the ratios the
/// targets name; then memory.
fn print(rows: &[Value], memory: &[Value]) {
    outln!(
        "{:<10} {:<15} {:>3} {:<10} {:<24} {:>10}",
        "scene",
        "rays",
        "thr",
        "engine",
        "kernel",
        "Mrays/s"
    );
    for r in rows {
        let (Some(m), Some(t)) = (r["mrays_per_s"].as_f64(), r["threads"].as_u64()) else {
            continue;
        };
        outln!(
            "{:<10} {:<15} {:>3} {:<10} {:<24} {:>10.3}",
            r["scene"].as_str().unwrap_or(""),
            r["rays"].as_str().unwrap_or(""),
            t,
            r["engine"].as_str().unwrap_or(""),
            r["kernel"].as_str().unwrap_or(""),
            m
        );
    }
    for r in rows.iter().filter(|r| r["rays"] == "build") {
        outln!(
            "{:<10} build {:<10} {:<16} {:>10.1} ms",
            r["scene"].as_str().unwrap_or(""),
            r["engine"].as_str().unwrap_or(""),
            r["kernel"].as_str().unwrap_or(""),
            r["build_ms"].as_f64().unwrap_or(f64::NAN)
        );
    }
    for m in memory {
        outln!(
            "{:<10} memory {:<10} {:<16} {:>12} bytes",
            m["scene"].as_str().unwrap_or(""),
            m["engine"].as_str().unwrap_or(""),
            m["kernel"].as_str().unwrap_or(""),
            m["bytes"].as_u64().unwrap_or(0)
        );
    }
}
