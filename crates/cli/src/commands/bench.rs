//! `quiver bench`: quiver and obvhs 0.4 side by side in one process, on the same triangles and
//! the same rays: build time and SAH cost, then Mrays/s for eye rays (a `--res`² camera, 1024²
//! by default, row by row), shadow rays (one per eye hit, toward the first light), diffuse
//! bounce rays (one cosine-distributed direction per eye hit) and incoherent rays.
//! Built with the `embree` feature, Intel Embree 3 joins them (`rtcIntersect1` / `rtcOccluded1`
//! in the same interleaved rounds, and its build time). Coherent rays (the eye rays in 8 x 8
//! tiles and their shadow rays) also go through quiver's packet kernel and, with the
//! feature, Embree's coherent streams (`rtcIntersect1M` / `rtcOccluded1M`). Built with the
//! `tinybvh` feature, tinybvh's `BVH8_CPU` and `BVH4_CPU` join the single-ray rounds too
//! (`Intersect` / `IsOccluded`), with their build time. Every engine's BVH memory is reported
//! in bytes per triangle: quiver's `Bvh::footprint`, Embree's device memory monitor across the
//! commit, tinybvh's node and leaf array. quiver's build presets (default, fast) each report their
//! build time and SAH cost, and their trees are traced in the default layout beside the
//! kernels; the default also reports its refit time (`Bvh::refit` to the triangles slightly
//! moved, as by an animation). The report names each peer's version, and the instruction set
//! Embree's kernels run on.

use super::{measured_threads, pool, thread_count, Result, MAX_RAYS, MAX_REPS};
use crate::budget::{self, Estimate};
use crate::output::{check_outputs, out, outln, write_json};
use obvhs::{
    bvh2::builder::build_bvh2_from_tris, cwbvh::builder::build_cwbvh_from_tris, ray::RayHit,
    BvhBuildParams,
};
#[cfg(feature = "embree")]
use quiver_lab::embree::{EmbreeDevice, EmbreeScene};
use quiver_lab::measure::{
    count_hits, median_times_interleaved, mrays_per_s, trace_packets, Query,
};
#[cfg(feature = "tinybvh")]
use quiver_lab::tinybvh::{TinyBvh, TinyLayout};
use quiver_lab::{obvhs_bridge, rays};
use quiver_rt::builders::{build, prim_bounds, BuildConfig, Builder};
use quiver_rt::traverse::PacketMode;
use quiver_rt::{BuildError, BuildOptions, Bvh, Layout, RayQuery};
use quiver_scenes::scene::tessellate;
use serde_json::{json, Value};
#[cfg(feature = "tinybvh")]
use std::io::Write as _;
use std::path::PathBuf;
use std::time::{Duration, Instant};

#[derive(clap::Args)]
pub(crate) struct BenchArgs {
    /// Scenes (generator names or .obj/.nff/.ply/.ply.gz/.gltf/.glb files), measured as
    /// triangles (SPD scenes in patch mode). Default: the generated teapot12 (9.4k
    /// triangles), balls3 (158k) and tetra10 (1M), so the default needs no file and runs from
    /// anywhere. Name a mesh to add it, e.g. the Stanford bunny of the source tree or the
    /// dragon that scripts/fetch-meshes.sh fetches:
    /// `quiver bench tests/data/bunny.obj meshes/dragon_vrip.ply.gz teapot12`.
    scenes: Vec<String>,
    /// Incoherent rays per scene.
    #[arg(allow_negative_numbers = true, long, default_value_t = 200_000, value_parser = super::count(MAX_RAYS))]
    rays: usize,
    /// Image width and height for eye rays (shadow and diffuse rays: one per eye hit). Not
    /// used by --instanced, which traces a 256² image.
    #[arg(allow_negative_numbers = true, long, default_value_t = 1024, value_parser = clap::value_parser!(u32).range(8..=8192))]
    res: u32,
    /// Timed rounds per measurement (median).
    #[arg(allow_negative_numbers = true, long, default_value_t = 3, value_parser = super::count(MAX_REPS))]
    reps: usize,
    /// Thread counts to measure, comma-separated (default: 1 and all cores).
    #[arg(allow_negative_numbers = true, long, value_delimiter = ',', value_parser = thread_count())]
    threads: Vec<u16>,
    /// Write the machine description and all rows as JSON.
    #[arg(long)]
    json: Option<PathBuf>,
    /// Measure SPD scenes traced as worlds of instances (every sphere and cone an instance of
    /// one tessellated unit shape) beside the same scenes flattened, and beside Embree's
    /// instanced and flattened scenes when built with the `embree` feature: build time,
    /// memory, single rays, packets, a filter that accepts all and masks that exclude
    /// nothing. Default scenes: balls4 and lattice6.
    #[arg(long)]
    instanced: bool,
}

/// Memory per triangle of the largest scene beyond the scenes themselves: five quiver layouts,
/// obvhs's BVH2 and CWBVH, their triangle copies and the 256² eye and shadow rays (`quiver
/// bench soup100000` and `soup300000 --rays 10`: 154 and 503 MB, 1745 B a triangle with the
/// scene's 128), rounded up.
const PER_TRIANGLE: u64 = 2000;

/// Memory per incoherent ray (`quiver bench soup1000 --rays 2000000`: 113 MB, 54 B a ray),
/// rounded up.
const PER_RAY: u64 = 72;

/// Rays kept per eye pixel: the eye rays row by row and in tiles, and at most one shadow ray
/// of each and one diffuse ray.
const PER_PIXEL: u64 = 5;

/// The seed of the diffuse bounce rays (any fixed value: every engine traces the same set).
pub(crate) const DIFFUSE_SEED: u64 = 51;

/// The scenes `quiver bench` measures without arguments.
const DEFAULT_SCENES: [&str; 3] = ["teapot12", "balls3", "tetra10"];

const KERNELS: [Layout; 5] = [
    Layout::Bvh2Dfs,
    Layout::Bvh2Subtree,
    Layout::Bvh4Dfs,
    Layout::Bvh4Quant,
    Layout::Bvh8Dfs,
];

/// tinybvh's layouts, timed after quiver's kernels, obvhs and Embree.
#[cfg(feature = "tinybvh")]
const TINY: [TinyLayout; 2] = [TinyLayout::Bvh8Cpu, TinyLayout::Bvh4Cpu];

fn time<T>(f: impl FnOnce() -> T) -> (T, f64) {
    let t = Instant::now();
    let v = f();
    (v, t.elapsed().as_secs_f64() * 1e3)
}

/// The median time of `reps` runs of `f` (at least one), with the last run's value.
fn median_time<T>(reps: usize, mut f: impl FnMut() -> T) -> (T, f64) {
    let mut times = Vec::with_capacity(reps.max(1));
    let mut last = None;
    for _ in 0..reps.max(1) {
        drop(last.take());
        let (v, ms) = time(&mut f);
        times.push(ms);
        last = Some(v);
    }
    times.sort_by(f64::total_cmp);
    (last.expect("at least one run"), times[times.len() / 2])
}

/// Runs `quiver bench`.
pub(crate) fn run(args: BenchArgs) -> Result<()> {
    check_outputs(&[("--json", args.json.as_deref())], &args.scenes)?;
    if args.instanced {
        return super::instances::load_and_run(
            "bench",
            &args.scenes,
            args.rays,
            args.reps,
            &args.threads,
            args.json.as_ref(),
        );
    }
    // Generated scenes only: a file path fixed at compile time would break as soon as the
    // binary is installed elsewhere or run from another directory.
    let scenes = if args.scenes.is_empty() {
        DEFAULT_SCENES.map(String::from).to_vec()
    } else {
        args.scenes.clone()
    };
    let thread_counts = measured_threads(&args.threads);
    // Every scene loads before the first measurement, so a bad name or file fails at once
    // rather than after minutes of measuring the scenes before it.
    let loaded = super::load_within(&scenes, |censuses, _| {
        let mut e = Estimate::new(format!("bench {}", scenes.join(" ")));
        e.add(
            "scenes and their patch mode",
            super::scenes_bytes(censuses, true),
        );
        let tris = super::largest(censuses, super::triangles_of);
        e.add(
            format!(
                "{} triangles' builds, obvhs's included, at {PER_TRIANGLE} B",
                budget::count(tris)
            ),
            tris * PER_TRIANGLE,
        );
        e.add(
            format!("{} incoherent rays", budget::count(args.rays as u64)),
            args.rays as u64 * PER_RAY,
        );
        let pixels = u64::from(args.res).pow(2);
        e.add(
            format!(
                "{} eye rays, their shadow and diffuse rays",
                budget::count(pixels)
            ),
            pixels * PER_PIXEL * PER_RAY,
        );
        e
    })?;
    let (peer_lines, peers) = super::peers()?;
    let loaded: Vec<_> = scenes
        .iter()
        .zip(loaded)
        .map(|(name, scene)| (name, scene.into_patches(tessellate::DEFAULT_RESOLUTION)))
        .collect();
    let bar = indicatif::ProgressBar::new(scenes.len() as u64 * 2);
    bar.set_style(indicatif::ProgressStyle::with_template(
        "{bar:40} {pos}/{len} {msg} [{elapsed}]",
    )?);
    let mut rows: Vec<Value> = Vec::new();
    // BVH memory per engine and scene: no thread count, so apart from the timed rows.
    let mut memory_rows: Vec<Value> = Vec::new();
    let config = BuildConfig::default();
    for (name, scene) in &loaded {
        bar.set_message(format!("{name}: building"));
        let tris = scene.triangles();
        let ot = obvhs_bridge::triangles(&tris);
        let row = |engine: &str,
                   kernel: &str,
                   rays: &str,
                   threads: usize,
                   mrays: Option<f64>,
                   build_ms: Option<f64>,
                   sah: Option<f64>| {
            json!({"scene": scene.name, "primitives": tris.len(), "engine": engine, "kernel": kernel, "rays": rays,
                   "threads": threads, "mrays_per_s": mrays, "build_ms": build_ms, "sah_cost": sah})
        };
        // The same triangles a little moved, for the refit (one frame of an animation).
        let moved = super::nudged(&tris);
        // Builds at each thread count, warmed once so page faults do not count; quiver's default
        // build and Embree's are the median of `--reps` builds.
        for &threads in &thread_counts {
            let p = pool(Some(threads))?;
            // quiver's presets in the default layout: each build (median of `--reps`) and
            // its tree's SAH cost; beside the default's, a refit to the moved triangles (the
            // same tree, every box recomputed).
            for (preset, options) in presets() {
                p.install(|| -> std::result::Result<(), String> {
                    drop(Bvh::build(&tris, &options).map_err(|e| e.to_string())?);
                    // The presets' settings are in range: the first build said so.
                    let build = || Bvh::build_with_tree(&tris, &options).expect("in range");
                    let ((mut bvh, tree), ms) = median_time(args.reps, build);
                    let mut r = row(
                        "quiver",
                        &format!("{}+{}", options.builder.name(), options.layout.name()),
                        "build",
                        threads,
                        None,
                        Some(ms),
                        Some(tree.sah_cost(&config)),
                    );
                    r["preset"] = json!(preset);
                    if preset == "default" {
                        let refit = super::refit_ms(&mut bvh, &tris, &moved, args.reps);
                        r["refit_ms"] = json!(refit.map_err(|e| e.to_string())?);
                    }
                    rows.push(r);
                    Ok(())
                })?;
            }
            p.install(|| {
                let options = BuildOptions::default().layout(Layout::Bvh2Dfs);
                let build = || Bvh::build_with_tree(&tris, &options).expect("default settings");
                let _ = build();
                let ((_, tree), ms) = time(build);
                rows.push(row(
                    "quiver",
                    "binned+bvh2-dfs",
                    "build",
                    threads,
                    None,
                    Some(ms),
                    Some(tree.sah_cost(&config)),
                ));
                let medium = BvhBuildParams::medium_build();
                let _ = build_bvh2_from_tris(&ot, medium, &mut Duration::default());
                let (ob, ms) = time(|| build_bvh2_from_tris(&ot, medium, &mut Duration::default()));
                rows.push(row(
                    "obvhs",
                    "bvh2-medium",
                    "build",
                    threads,
                    None,
                    Some(ms),
                    Some(obvhs_bridge::sah_cost(&ob)),
                ));
                let (_, ms) = time(|| build_cwbvh_from_tris(&ot, medium, &mut Duration::default()));
                rows.push(row(
                    "obvhs",
                    "cwbvh-medium",
                    "build",
                    threads,
                    None,
                    Some(ms),
                    None,
                ));
            });
            // Embree builds on its own TBB threads, not on the rayon pool: `threads=N` on the
            // device sets how many (Embree takes the largest count of all live devices, and
            // none other is alive here). Device creation is not timed, as the pool's is not.
            #[cfg(feature = "embree")]
            {
                let device = EmbreeDevice::with_threads(threads)?;
                drop(EmbreeScene::on_device(&device, &tris)?);
                let (built, ms) = median_time(args.reps, || EmbreeScene::on_device(&device, &tris));
                drop(built?);
                rows.push(row(
                    "embree",
                    "bvh-medium",
                    "build",
                    threads,
                    None,
                    Some(ms),
                    None,
                ));
            }
        }
        drop(moved);
        // tinybvh builds on threads of its own (all hardware threads above 50,000 triangles),
        // which it cannot be told to limit: one build row, at that count.
        #[cfg(feature = "tinybvh")]
        for layout in TINY {
            if let Err(e) = TinyBvh::new(&tris, layout) {
                // A tree tinybvh's walk cannot trace safely: no rows for it on this scene.
                let _ = writeln!(std::io::stderr(), "warning: {}: {e}", scene.name);
                continue;
            }
            let (built, ms) = time(|| TinyBvh::new(&tris, layout));
            drop(built);
            let own = std::thread::available_parallelism().map_or(1, |n| n.get());
            rows.push(row(
                "tinybvh",
                layout.name(),
                "build",
                own,
                None,
                Some(ms),
                None,
            ));
        }
        bar.inc(1);
        bar.set_message(format!("{name}: tracing"));
        // Each layout traces the tree its own default build makes: the SAH counts a wide
        // layout's leaves by their SIMD groups of four, a binary one's by the triangle.
        let boxes = prim_bounds(&tris);
        let grouped = |g: usize| BuildConfig {
            leaf_group: g,
            ..config.clone()
        };
        let [one, four] = [1, 4].map(|g| build(&boxes, &grouped(g), Builder::Binned));
        let [one, four] = [one?, four?];
        let bvhs = KERNELS
            .iter()
            .map(|&l| {
                let g = l.leaf_group();
                Bvh::from_tree(
                    if g == 1 { &one } else { &four },
                    &tris,
                    &BuildOptions::default().config(grouped(g)).layout(l),
                )
            })
            .collect::<std::result::Result<Vec<Bvh>, _>>()?;
        // The other presets' trees in the default layout, traced beside the kernels.
        let preset_bvhs: Vec<(String, Bvh)> = presets()
            .into_iter()
            .filter(|(name, _)| *name != "default")
            .map(|(_, o)| {
                let kernel = format!("{}/{}", o.layout.name(), o.builder.name());
                Ok((kernel, Bvh::build(&tris, &o)?))
            })
            .collect::<std::result::Result<_, BuildError>>()?;
        #[cfg(feature = "tinybvh")]
        let tiny: Vec<TinyBvh> = TINY
            .iter()
            .filter_map(|&l| TinyBvh::new(&tris, l).ok())
            .collect();
        #[cfg(not(feature = "tinybvh"))]
        let tiny: Vec<()> = Vec::new();
        // Memory per triangle: quiver's node array, everything its walk reads and everything
        // it keeps; a peer's one figure is all it allocates, so its kept is the same.
        let per_tri = |b: usize| b as f64 / tris.len().max(1) as f64;
        let memory = |engine: &str,
                      kernel: &str,
                      nodes: Option<usize>,
                      bytes: usize,
                      kept: usize| {
            json!({"scene": scene.name, "primitives": tris.len(), "engine": engine, "kernel": kernel,
                   "bytes": bytes, "bytes_per_tri": per_tri(bytes),
                   "kept_bytes": kept, "kept_bytes_per_tri": per_tri(kept),
                   "node_bytes": nodes, "node_bytes_per_tri": nodes.map(per_tri)})
        };
        for (l, b) in KERNELS.iter().zip(&bvhs) {
            let f = b.footprint();
            memory_rows.push(memory(
                "quiver",
                l.name(),
                Some(f.node_bytes),
                f.bytes,
                f.kept,
            ));
        }
        let obvh = build_bvh2_from_tris(
            &ot,
            BvhBuildParams::medium_build(),
            &mut Duration::default(),
        );
        #[cfg(feature = "embree")]
        let embree = EmbreeScene::new(&tris)?;
        #[cfg(feature = "embree")]
        memory_rows.push(memory(
            "embree",
            "bvh-medium",
            None,
            embree.bvh_bytes(),
            embree.bvh_bytes(),
        ));
        #[cfg(feature = "tinybvh")]
        for t in &tiny {
            let bytes = t.bytes().0;
            memory_rows.push(memory("tinybvh", t.layout().name(), None, bytes, bytes));
        }
        let res = args.res as usize;
        let eye = rays::camera_rays(&scene.camera, res);
        let light = scene
            .lights
            .first()
            .map(|l| l.pos)
            .unwrap_or(scene.camera.from);
        let shadow = rays::shadow_rays(&bvhs[2], &eye, &[light]);
        let diffuse = rays::diffuse_rays(&bvhs[2], &tris, &eye, DIFFUSE_SEED);
        let incoherent = rays::random_rays(&scene.bounds(), args.rays, 11);
        // The same eye rays in 8 x 8 tiles, and their shadow rays in that order: coherent
        // input for the packet kernels (quiver's, and Embree's streams).
        let tiles = rays::camera_tiles(&scene.camera, res, 8);
        let tile_shadow = rays::shadow_rays(&bvhs[2], &tiles, &[light]);
        for &threads in &thread_counts {
            let p = pool(Some(threads))?;
            for (kind, set, any) in [
                ("eye-tiles", &tiles, false),
                ("shadow-tiles", &tile_shadow, true),
            ] {
                let packets = &bvhs[KERNELS.len() - 1];
                let query = if any { Query::Any } else { Query::Closest };
                let n = 1 + usize::from(cfg!(feature = "embree"));
                let times = p.install(|| {
                    median_times_interleaved(args.reps, n, |i| {
                        #[cfg(feature = "embree")]
                        if i == 1 {
                            std::hint::black_box(embree.count_hits(set, any, true));
                            return;
                        }
                        let _ = i;
                        std::hint::black_box(trace_packets(packets, set, query, PacketMode::Auto));
                    })
                });
                let packet_kernel = format!("{}-packets", KERNELS[KERNELS.len() - 1].name());
                rows.push(row(
                    "quiver",
                    &packet_kernel,
                    kind,
                    threads,
                    Some(mrays_per_s(set.len(), times[0])),
                    None,
                    None,
                ));
                #[cfg(feature = "embree")]
                {
                    let stream = if any {
                        "rtcOccluded1M"
                    } else {
                        "rtcIntersect1M"
                    };
                    rows.push(row(
                        "embree",
                        stream,
                        kind,
                        threads,
                        Some(mrays_per_s(set.len(), times[1])),
                        None,
                        None,
                    ));
                }
            }
            for (kind, set, any) in [
                ("eye", &eye, false),
                ("shadow", &shadow, true),
                ("diffuse", &diffuse, false),
                ("incoherent", &incoherent, false),
            ] {
                let ours = KERNELS.len() + preset_bvhs.len();
                let embree_at = ours + 1;
                let tiny_at = embree_at + usize::from(cfg!(feature = "embree"));
                let n = tiny_at + tiny.len();
                let times = p.install(|| {
                    median_times_interleaved(args.reps, n, |i| {
                        #[cfg(feature = "embree")]
                        if i == embree_at {
                            std::hint::black_box(count_hits(set, |r| {
                                if any {
                                    embree.any_hit(r)
                                } else {
                                    embree.closest_hit(r).is_some()
                                }
                            }));
                            return;
                        }
                        #[cfg(feature = "tinybvh")]
                        if let Some(t) = i.checked_sub(tiny_at).and_then(|k| tiny.get(k)) {
                            std::hint::black_box(t.count_hits(set, any));
                            return;
                        }
                        let hits = if i < ours {
                            let b = bvhs
                                .get(i)
                                .unwrap_or_else(|| &preset_bvhs[i - KERNELS.len()].1);
                            count_hits(set, |r| {
                                if any {
                                    b.any_hit(r)
                                } else {
                                    b.closest_hit(r).is_some()
                                }
                            })
                        } else {
                            count_hits(set, |r| {
                                let or = obvhs::ray::Ray::new(r.origin, r.dir, r.t_min, r.t_max);
                                let test = |ray: &obvhs::ray::Ray, slot: usize| {
                                    ot[obvh.primitive_indices[slot] as usize].intersect(ray)
                                };
                                if any {
                                    !obvh.ray_traverse_miss(or, test)
                                } else {
                                    obvh.ray_traverse(or, &mut RayHit::none(), test)
                                }
                            })
                        };
                        std::hint::black_box(hits);
                    })
                });
                for (i, t) in times.iter().enumerate() {
                    let mrays = mrays_per_s(set.len(), *t);
                    let (engine, kernel) = if i < KERNELS.len() {
                        ("quiver", KERNELS[i].name())
                    } else if i < ours {
                        ("quiver", preset_bvhs[i - KERNELS.len()].0.as_str())
                    } else if i == ours {
                        ("obvhs", "bvh2-medium")
                    } else if i >= tiny_at {
                        ("tinybvh", tiny_name(&tiny, i - tiny_at))
                    } else if any {
                        ("embree", "rtcOccluded1")
                    } else {
                        ("embree", "rtcIntersect1")
                    };
                    rows.push(row(engine, kernel, kind, threads, Some(mrays), None, None));
                }
            }
        }
        bar.inc(1);
    }
    bar.finish_and_clear();
    for line in &peer_lines {
        outln!("{line}");
    }
    outln!(
        "(eye: {0}x{0} camera; shadow and diffuse: one per eye hit)",
        args.res
    );
    print_throughput(&rows);
    print_memory(&memory_rows);
    let machine = json!({
        "threads": rayon::current_num_threads(),
        "measured_threads": thread_counts,
        "os": std::env::consts::OS,
        "arch": std::env::consts::ARCH,
        "target_features": {"sse2": cfg!(target_feature = "sse2"), "avx": cfg!(target_feature = "avx"), "avx2": cfg!(target_feature = "avx2")},
        "isa": quiver_rt::Isa::detect().name(),
        "eye_res": args.res,
        "peers": peers,
    });
    write_json(
        args.json.as_ref(),
        &json!({"machine": machine, "rows": rows, "memory": memory_rows}),
    )
}

/// quiver's build presets, by the name the rows give them: the default build (binned SAH,
/// `Bvh::new`) and the fast one (LBVH), both in the default layout.
fn presets() -> Vec<(&'static str, BuildOptions<'static>)> {
    vec![
        ("default", BuildOptions::default()),
        ("fast", BuildOptions::fast()),
    ]
}

/// The name of the `k`-th tinybvh BVH built for a scene.
#[cfg(feature = "tinybvh")]
fn tiny_name(tiny: &[TinyBvh], k: usize) -> &'static str {
    tiny[k].layout().name()
}

#[cfg(not(feature = "tinybvh"))]
fn tiny_name(_: &[()], k: usize) -> &'static str {
    unreachable!("no tinybvh BVH {k} without the feature")
}

/// Bytes per triangle of every engine's BVH, scene by scene.
fn print_memory(rows: &[Value]) {
    outln!();
    outln!(
        "{:<14} {:>9} {:<7} {:<17} {:>12} {:>12} {:>12} {:>13}",
        "scene",
        "prims",
        "engine",
        "kernel",
        "nodes B/tri",
        "all B/tri",
        "kept B/tri",
        "kept MB"
    );
    let num = |v: &Value, p: usize| v.as_f64().map_or("-".to_string(), |x| format!("{x:.p$}"));
    for r in rows {
        let name = r["scene"].as_str().unwrap_or("");
        let short = name.rsplit('/').next().unwrap_or(name);
        outln!(
            "{:<14} {:>9} {:<7} {:<17} {:>12} {:>12} {:>12} {:>13}",
            short,
            r["primitives"],
            r["engine"].as_str().unwrap_or(""),
            r["kernel"].as_str().unwrap_or(""),
            num(&r["node_bytes_per_tri"], 1),
            num(&r["bytes_per_tri"], 1),
            num(&r["kept_bytes_per_tri"], 1),
            r["kept_bytes"]
                .as_f64()
                .map_or("-".into(), |b| format!("{:.1}", b / 1e6))
        );
    }
    outln!("(nodes: quiver's node array; all: what the walk reads, nodes and leaf triangles: quiver's Bvh::footprint, Embree's allocations across rtcCommitScene by its memory monitor, tinybvh's interleaved node and leaf blocks; kept: everything the BVH holds, quiver's Footprint::kept (for a peer its one figure))");
}

fn print_throughput(rows: &[Value]) {
    let s = |v: &Value| v.as_str().unwrap_or("").to_string();
    let f = |v: &Value| v.as_f64();
    out!(
        "{:<14} {:>9} {:<7} {:<17} {:<10} {:>3} {:>9} {:>9} {:>9} {:>9} {:>8}",
        "scene",
        "prims",
        "engine",
        "kernel",
        "rays",
        "thr",
        "build ms",
        "refit ms",
        "SAH",
        "Mrays/s",
        "q/obvhs"
    );
    if cfg!(feature = "embree") {
        out!(" {:>8}", "q/embree");
    }
    if cfg!(feature = "tinybvh") {
        out!(" {:>8}", "q/tiny8");
    }
    outln!();
    for r in rows {
        let name = s(&r["scene"]);
        let short = name.rsplit('/').next().unwrap_or(&name).to_string();
        // Ratio against another engine (its one kernel, or `kernel`) on the same scene, ray
        // kind and thread count.
        let versus = |engine: &str, kernel: Option<&str>| {
            if r["engine"] != "quiver" {
                return None;
            }
            rows.iter()
                .find(|o| {
                    o["engine"] == engine
                        && o["scene"] == r["scene"]
                        && o["rays"] == r["rays"]
                        && o["threads"] == r["threads"]
                        && kernel.is_none_or(|k| o["kernel"] == k)
                })
                .and_then(|o| {
                    match (
                        f(&r["mrays_per_s"]),
                        f(&o["mrays_per_s"]),
                        f(&r["build_ms"]),
                        f(&o["build_ms"]),
                    ) {
                        (Some(a), Some(b), _, _) => Some(a / b),
                        (_, _, Some(a), Some(b)) => Some(b / a),
                        _ => None,
                    }
                })
        };
        let ratio = versus("obvhs", Some("bvh2-medium"));
        // Not finite: a ratio of two empty measurements (no shadow rays when no eye ray hits).
        let num = |v: Option<f64>, p: usize| {
            v.filter(|x| x.is_finite())
                .map_or("-".to_string(), |x| format!("{x:.p$}"))
        };
        out!(
            "{:<14} {:>9} {:<7} {:<17} {:<10} {:>3} {:>9} {:>9} {:>9} {:>9} {:>8}",
            short,
            r["primitives"],
            s(&r["engine"]),
            s(&r["kernel"]),
            s(&r["rays"]),
            r["threads"],
            num(f(&r["build_ms"]), 1),
            num(f(&r["refit_ms"]), 1),
            num(f(&r["sah_cost"]), 2),
            num(f(&r["mrays_per_s"]), 2),
            num(ratio, 2)
        );
        if cfg!(feature = "embree") {
            out!(" {:>8}", num(versus("embree", None), 2));
        }
        if cfg!(feature = "tinybvh") {
            out!(" {:>8}", num(versus("tinybvh", Some("BVH8_CPU")), 2));
        }
        outln!();
    }
    outln!("(q/obvhs: quiver throughput over obvhs's, or obvhs build time over quiver's: above 1 means quiver is faster)");
    outln!("(refit ms: the default layout's BVH refit to the same triangles moved by a thousandth of the scene's size, the tree kept and every box recomputed; median of --reps)");
    if cfg!(feature = "embree") {
        outln!("(q/embree: the same against Embree's rtcIntersect1 / rtcOccluded1 and its default-quality build)");
    }
    if cfg!(feature = "tinybvh") {
        outln!("(q/tiny8: the same against tinybvh's BVH8_CPU Intersect / IsOccluded and its default build, which runs on its own threads: one build row, at all hardware threads)");
    }
}
