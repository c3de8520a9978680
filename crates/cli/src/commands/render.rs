//! `quiver render`: the SPD testing procedure on one scene: a PNG, the ray counts, Havran's
//! statistics, optionally a heatmap of nodes per eye ray.

use super::{layout_help, load_and_build_as, parse_layout, pool, scene_help, thread_count, Result};
use crate::output::{check_outputs, outln, print_table, write_heatmap, write_json, write_png};
use clap::ValueEnum;
use quiver_rt::traverse::NoFilter;
use quiver_rt::{BuildOptions, Layout};
use quiver_scenes::accel::SceneBvh;
use quiver_scenes::render::{render, Offset, RenderConfig, Rendered};
use serde_json::{json, Value};
use std::path::PathBuf;
use std::time::Instant;

#[derive(clap::Args)]
pub(crate) struct RenderArgs {
    /// A generator name with optional size, or an .nff/.obj/.ply/.ply.gz/.gltf/.glb file.
    #[arg(default_value = DEFAULT_SCENE, long_help = scene_help())]
    scene: String,
    /// Image width and height in pixels ((res+1)^2 eye rays at the pixel corners).
    #[arg(allow_negative_numbers = true, long, default_value_t = 512, value_parser = clap::value_parser!(u32).range(1..=16384))]
    res: u32,
    /// Output PNG.
    #[arg(short, long, default_value = "quiver.png")]
    output: PathBuf,
    /// Worker threads (default: all cores).
    #[arg(allow_negative_numbers = true, long, value_parser = thread_count())]
    threads: Option<u16>,
    /// Memory layout of the BVH.
    #[arg(long, default_value = "bvh8-dfs", value_parser = parse_layout, long_help = layout_help())]
    layout: Layout,
    /// Tessellate spheres and cones (the SPD's patch mode).
    #[arg(long)]
    patches: bool,
    /// Patch mode with every sphere and cone an instance of one tessellated unit shape (a
    /// world of instances instead of one flattened triangle list; the same image up to the
    /// placements' rounding at silhouettes).
    #[arg(long)]
    instanced: bool,
    /// Motion blur: --instanced with every sphere and cone moving, each in a straight line by
    /// its own size over the shutter along a direction of its own; each eye ray is traced at
    /// --time-samples times and its colours averaged.
    #[arg(long)]
    motion: bool,
    /// Times in the shutter each eye ray is traced at, averaged, every secondary ray at its
    /// eye ray's time (default: 16 with --motion, else 1: time 0, as the SPD traces). The
    /// ray counts are those of this many renders.
    #[arg(allow_negative_numbers = true, long, value_parser = clap::value_parser!(u32).range(1..=1024))]
    time_samples: Option<u32>,
    /// Write a false-colour image of nodes visited per eye ray.
    #[arg(long)]
    heatmap: Option<PathBuf>,
    /// Eye rays in 8 x 8 packets and their shadow rays per light as packets (on), or every
    /// ray alone (off). Image and ray counts are identical either way.
    #[arg(long, value_enum, default_value = "on")]
    packets: OnOff,
    /// How secondary rays leave a surface: epsilon (a relative t_min, as the tracers behind
    /// the SPD's counts) or ulps (offset along the normal, Wächter & Binder).
    #[arg(long, value_enum, default_value = "epsilon")]
    offset: OffsetArg,
    /// Also split the running time as Havran does (the rays recorded, traced alone, and his
    /// ideal algorithm's one test per hit, each timed) and print his minimum testing output
    /// as a table in his layout.
    #[arg(long)]
    havran: bool,
    /// Timed rounds with --havran: the render ray by ray, its rays alone, the ideal
    /// algorithm (medians reported).
    #[arg(allow_negative_numbers = true, long, default_value_t = 5, value_parser = super::count(super::MAX_REPS))]
    reps: usize,
    /// Write the report as JSON to this file.
    #[arg(long)]
    json: Option<PathBuf>,
}

/// The scene `quiver render` draws without an argument.
const DEFAULT_SCENE: &str = "teapot12";

#[derive(Clone, Copy, PartialEq, Eq, ValueEnum)]
enum OnOff {
    On,
    Off,
}

#[derive(Clone, Copy, ValueEnum)]
enum OffsetArg {
    Ulps,
    Epsilon,
}

/// Runs `quiver render`.
pub(crate) fn run(args: RenderArgs) -> Result<()> {
    check_outputs(
        &[
            ("--output", Some(args.output.as_path())),
            ("--heatmap", args.heatmap.as_deref()),
            ("--json", args.json.as_deref()),
        ],
        &[&args.scene],
    )?;
    let pool = pool(args.threads.map(usize::from))?;
    let options = BuildOptions::default()
        .layout(args.layout)
        .thread_pool(&pool);
    let threads = pool.current_num_threads();
    let instanced = args.instanced || args.motion;
    let time_samples = time_samples(&args);
    let what = format!(
        "render {} --res {}{}",
        args.scene,
        args.res,
        if args.motion {
            " --motion"
        } else if args.instanced {
            " --instanced"
        } else if args.patches {
            " --patches"
        } else {
            ""
        }
    );
    let (scene, bvh, tree, build_ms) = load_and_build_as(
        &args.scene,
        args.patches,
        instanced.then_some(args.motion),
        &options,
        |censuses, scenes| {
            let mut e = if instanced {
                super::instanced_estimate(&what, censuses)
            } else {
                super::build_estimate(&what, censuses, args.patches)
            };
            render_estimate(&mut e, &args, threads, censuses, scenes);
            e
        },
    )?;
    let rconfig = RenderConfig {
        res: args.res,
        two_sided: if instanced {
            scene.patch_mode_two_sided_materials()
        } else {
            scene.two_sided_materials()
        },
        offset: match args.offset {
            OffsetArg::Ulps => Offset::Ulps,
            OffsetArg::Epsilon => Offset::Epsilon,
        },
        packets: args.packets == OnOff::On,
        time_samples,
        ..RenderConfig::default()
    };
    let rows = args.res as u64 + 1;
    let bar = indicatif::ProgressBar::new(rows);
    bar.set_style(indicatif::ProgressStyle::with_template(
        "rendering {bar:40} {pos}/{len} rows [{elapsed}]",
    )?);
    let start = Instant::now();
    let mut image = pool.install(|| render(&scene, &bvh, &rconfig, &|n| bar.inc(n as u64)));
    let trace_ms = start.elapsed().as_secs_f64() * 1e3;
    bar.finish_and_clear();
    write_png(&args.output, image.res, image.res, &image.rgb)?;
    // Written: from here on its digest stands for it, and the pixels are not held twice.
    image.rgb = Vec::new();
    // Havran's statistics come from a second, counting pass: the timed pass above runs the
    // plain kernels. The counting pass traces ray by ray, so the statistics are per ray as
    // Havran defines them; both passes must trace the same rays and draw the same image (the
    // same digest: the counting pass keeps no image). With --havran it also records every
    // answer for the ideal runs; the node counts per eye ray are kept only for --heatmap.
    let counted_config = RenderConfig {
        counters: true,
        packets: false,
        keep_image: false,
        eye_nodes: args.heatmap.is_some(),
        ..rconfig.clone()
    };
    let recording = args.havran.then(|| bvh.clone().recording());
    let counting_bvh = recording.as_ref().unwrap_or(&bvh);
    let counted = pool.install(|| render(&scene, counting_bvh, &counted_config, &|_| {}));
    same_render(&counted, &image, "counting")?;
    let theta = match &recording {
        Some(recording) => Some(ideal_runs(
            &pool, &scene, &bvh, recording, &rconfig, &image, args.reps,
        )?),
        None => None,
    };
    if let Some(h) = &args.heatmap {
        write_heatmap(h, &counted.eye_nodes, args.res as usize + 1)?;
    }
    let census = quiver_rt::predict::census(&bvh);
    let stats = tree.as_ref().map(|t| t.stats());
    let rays = image.rays;
    let total = rays.total().max(1) as f64;
    let work = counted.work;
    let mut havran = json!({
        "N_G": census.inner,
        "N_E": census.leaves,
        "N_EE": census.empty_leaves,
        "N_ER": census.references,
        "r_ITM": work.prim_tests as f64 / rays.hits().max(1) as f64,
        "N_TS": work.nodes as f64 / total,
        "N_ETS": work.leaves as f64 / total,
        "N_EETS": work.empty_leaves as f64 / total,
        "N_IT": work.prim_tests as f64 / total,
        "r_SI": rays.hits() as f64 / total,
        "N_rays": rays.total(),
        "box_tests_per_ray": work.box_tests as f64 / total,
        "build_tree_inner": stats.map(|s| s.nodes - s.leaves),
        "build_tree_leaves": stats.map(|s| s.leaves),
        "T_B_ms": build_ms,
        "T_R_ms": trace_ms,
    });
    if let Some(t) = &theta {
        let t_app = t.t_r_ms - t.t_rsa_ms;
        havran["T_R_ms"] = json!(t.t_r_ms);
        havran["T_R_timed_pass_ms"] = json!(trace_ms);
        havran["T_RSA_ms"] = json!(t.t_rsa_ms);
        havran["T_app_ms"] = json!(t_app);
        havran["T_RSA_MIN_ms"] = json!(t.t_rsa_min_ms);
        havran["C_IT_succ_ns"] = json!(t.c_it_ns);
        havran["Theta_APP"] = json!(t_app / t.t_rsa_min_ms);
        havran["Theta_RUN"] = json!(t.t_rsa_ms / t.t_rsa_min_ms);
        // His Θ_rat weighs failed and successful tests by their own costs; only successful
        // ones are timed here, so every test is charged C_IT^succ.
        havran["Theta_rat"] = json!(work.prim_tests as f64 * t.c_it_ns * 1e-6 / t.t_rsa_ms);
    }
    let report = json!({
        "scene": scene.name,
        "objects": scene.objects.len(),
        "primitives": bvh.primitives(),
        "width": args.res,
        "height": args.res,
        "threads": pool.current_num_threads(),
        "layout": args.layout.name(),
        "packets": rconfig.packets,
        // Rays the packet kernels traced, and their share of all rays.
        "packet_rays": image.packet_rays,
        "packet_share": image.packet_rays as f64 / total,
        "rays": {
            "eye": rays.eye,
            "eye_hit": rays.eye_hit,
            "reflect": rays.reflect,
            "refract": rays.refract,
            "secondary_hit": rays.secondary_hit,
            "shadow": rays.shadow,
            "shadow_blocked": rays.shadow_blocked,
            "total": rays.total(),
        },
        "build_ms": build_ms,
        "trace_ms": trace_ms,
        "mrays_per_s": rays.total() as f64 / (trace_ms * 1e3),
        "havran": havran,
        "output": args.output.display().to_string(),
    });
    if args.havran {
        print_havran(&report);
    } else {
        print_table(&report);
    }
    write_json(args.json.as_ref(), &report)
}

/// The eye rays' times a corner: --time-samples, or its default (16 with --motion, else 1).
fn time_samples(args: &RenderArgs) -> u32 {
    args.time_samples
        .unwrap_or(if args.motion { 16 } else { 1 })
}

/// Adds what rendering takes beyond the scene and its BVH: the timed pass (the image and its
/// band buffers), the counting pass (band buffers, node counts per eye ray for --heatmap), and
/// with --havran the recording BVH's copy and every query it records, at most
/// `(1 + lights) * (1 + b + ... + b^4)` per eye ray for `b` secondary rays per hit (1 with
/// reflective or transmitting materials, 2 with transmitting ones), known once the scene is
/// loaded.
fn render_estimate(
    e: &mut crate::budget::Estimate,
    args: &RenderArgs,
    threads: usize,
    censuses: &[quiver_scenes::scene::Census],
    scenes: Option<&[quiver_scenes::Scene]>,
) {
    let timed = RenderConfig {
        res: args.res,
        time_samples: time_samples(args),
        ..RenderConfig::default()
    };
    let counting = RenderConfig {
        counters: true,
        keep_image: false,
        eye_nodes: args.heatmap.is_some(),
        ..timed.clone()
    };
    e.add(
        format!("image and render buffers at {}²", args.res),
        timed.memory_bytes(threads),
    );
    e.add("counting pass", counting.memory_bytes(threads));
    let Some(scene) = scenes.and_then(|s| s.first()) else {
        return;
    };
    if !args.havran {
        return;
    }
    let prims = super::largest(censuses, |c| {
        if args.patches {
            super::triangles_of(c)
        } else {
            c.curve_primitives()
        }
    });
    let reflective = scene.materials.iter().any(|m| m.ks > 0.0 || m.t > 0.0);
    let transmitting = scene.materials.iter().any(|m| m.t > 0.0);
    let b = reflective as u64 + transmitting as u64;
    let depth = RenderConfig::default().max_depth;
    let per_eye = (1 + scene.lights.len() as u64) * (0..depth).map(|d| b.pow(d)).sum::<u64>();
    let eye = (args.res as u64 + 1).pow(2) * timed.time_samples as u64;
    let traced = std::mem::size_of::<quiver_scenes::accel::Traced>() as u64;
    e.add(
        "--havran's copy of the BVH",
        prims * crate::budget::TRIANGLE_BUILD / 2,
    );
    e.add(
        format!(
            "--havran's record of up to {} queries",
            crate::budget::count(eye * per_eye)
        ),
        eye * per_eye * traced,
    );
}

/// Fails unless `other` traced the same rays and drew the same image (digest) as the timed
/// pass.
fn same_render(other: &Rendered, image: &Rendered, pass: &str) -> Result<()> {
    if other.rays != image.rays || other.image_digest != image.image_digest {
        return Err(format!(
            "internal error: the {pass} pass traced different rays than the plain pass"
        )
        .into());
    }
    Ok(())
}

/// Havran's split of the running time (thesis, sections 2.4-2.5), measured on the rays the
/// counting pass recorded.
struct Theta {
    /// `T_R`: the render traced ray by ray (as the counts were), median of the rounds.
    t_r_ms: f64,
    /// The recorded rays traced on their own through the BVH: the time `T_R - T_app` the
    /// render spends shooting rays.
    t_rsa_ms: f64,
    /// `T_RSA^MIN = C_IT^succ · N_rays · r_SI`: Havran's ideal algorithm, which reads each
    /// stored answer in sequence and makes one successful test per ray that hits.
    t_rsa_min_ms: f64,
    /// `C_IT^succ`: one successful intersection test.
    c_it_ns: f64,
}

/// Times, in alternating rounds (medians): the render ray by ray; the recorded rays traced
/// alone in their recorded order; and Havran's ideal algorithm over the same list (one test
/// of the recorded primitive per hit). `T_app` is then `T_R` less the tracing. Havran gets
/// `T_app` from repeated runs of the ideal algorithm inside the application (his multiple run
/// profiling); a triangle test of a few ns made twice changes a render of hundreds of ms by
/// less than this shared machine's noise, so the parts are timed apart instead.
fn ideal_runs(
    pool: &rayon::ThreadPool,
    scene: &quiver_scenes::Scene,
    bvh: &SceneBvh,
    recording: &SceneBvh,
    config: &RenderConfig,
    image: &Rendered,
    reps: usize,
) -> Result<Theta> {
    use quiver_rt::traverse::{ConservativeBoxes, NoStats, RayQuery};
    use rayon::prelude::*;
    let traced = recording.recorded();
    if traced.len() as u64 != image.rays.total() {
        return Err("internal error: the recording missed rays the render traced".into());
    }
    // The timed renders keep no image: each is checked against the first pass by its digest
    // as it finishes, so --reps costs no memory.
    let single = RenderConfig {
        packets: false,
        keep_image: false,
        ..config.clone()
    };
    let mut renders: Vec<bool> = Vec::new();
    let times = pool.install(|| {
        quiver_lab::measure::median_times_interleaved(reps, 3, |i| match i {
            0 => renders.push(
                same_render(&render(scene, bvh, &single, &|_| {}), image, "single-ray").is_ok(),
            ),
            1 => {
                let hits: usize = traced
                    .par_chunks(1024)
                    .map(|c| {
                        c.iter()
                            .filter(|t| {
                                if t.any {
                                    bvh.any_hit_with::<ConservativeBoxes, _, _>(
                                        &t.ray,
                                        &mut NoStats,
                                        &mut NoFilter,
                                    )
                                } else {
                                    bvh.closest_hit_with::<ConservativeBoxes, _, _>(
                                        &t.ray,
                                        &mut NoStats,
                                        &mut NoFilter,
                                    )
                                    .is_some()
                                }
                            })
                            .count()
                    })
                    .sum();
                std::hint::black_box(hits);
            }
            _ => {
                let hits: usize = traced
                    .par_chunks(1024)
                    .map(|c| {
                        c.iter()
                            .filter_map(|t| t.hit.map(|p| bvh.intersect_one(&t.ray, p)))
                            .count()
                    })
                    .sum();
                std::hint::black_box(hits);
            }
        })
    });
    if renders.contains(&false) {
        return Err(
            "internal error: the single-ray pass traced different rays than the plain pass".into(),
        );
    }
    let ms = |d: std::time::Duration| d.as_secs_f64() * 1e3;
    let tests = traced.iter().filter(|t| t.hit.is_some()).count().max(1) as f64;
    Ok(Theta {
        t_r_ms: ms(times[0]),
        t_rsa_ms: ms(times[1]),
        t_rsa_min_ms: ms(times[2]),
        c_it_ns: ms(times[2]) * 1e6 / tests,
    })
}

/// Havran's minimum testing output in his tables' layout: one parameter per line, in the
/// order Σ (static), Δ (dynamic), Θ (time), for this scene's column.
fn print_havran(report: &Value) {
    let h = &report["havran"];
    let scene = report["scene"].as_str().unwrap_or("");
    outln!("{:<24} {:>14}", "Parameter", scene);
    let rows: [(&str, &str, usize); 20] = [
        ("N_G", "N_G", 0),
        ("N_E", "N_E", 0),
        ("N_EE", "N_EE", 0),
        ("N_ER", "N_ER", 0),
        ("r_ITM", "r_ITM [-]", 2),
        ("N_TS", "N_TS [-]", 2),
        ("N_ETS", "N_ETS [-]", 2),
        ("N_EETS", "N_EETS [-]", 2),
        ("N_IT", "N_IT [-]", 2),
        ("r_SI", "r_SI [-]", 3),
        ("N_rays", "N_rays", 0),
        ("T_B_ms", "T_B [ms]", 1),
        ("T_R_ms", "T_R [ms]", 1),
        ("Theta_APP", "Theta_APP [-]", 2),
        ("Theta_rat", "Theta_rat [-]", 3),
        ("Theta_RUN", "Theta_RUN [-]", 2),
        ("T_RSA_ms", "T_R - T_app [ms]", 1),
        ("T_app_ms", "T_app [ms]", 1),
        ("T_RSA_MIN_ms", "T_RSA^MIN [ms]", 2),
        ("C_IT_succ_ns", "C_IT^succ [ns]", 1),
    ];
    for (key, name, digits) in rows {
        match h[key].as_f64() {
            Some(v) => outln!("{name:<24} {v:>14.digits$}"),
            None => outln!("{name:<24} {:>14}", "-"),
        }
    }
    outln!(
        "(N_EETS: leaf visits that changed nothing; layout {}, {} thread(s); T_R and Theta \
         ray by ray)",
        report["layout"].as_str().unwrap_or(""),
        report["threads"],
    );
}
