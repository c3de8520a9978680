//! `quiver render`: the SPD testing procedure on one scene: a PNG, the ray counts, Havran's
//! statistics, optionally a heatmap of nodes per eye ray.

use super::{layout_help, load_and_build, parse_layout, pool, scene_help, thread_count, Result};
use crate::output::{check_outputs, heatmap, print_table, write_json, write_png};
use clap::ValueEnum;
use quiver::{BuildOptions, Layout};
use quiver_scenes::render::{render, Offset, RenderConfig};
use serde_json::json;
use std::path::PathBuf;
use std::time::Instant;

#[derive(clap::Args)]
pub(crate) struct RenderArgs {
    /// A generator name with optional size, or an .nff/.obj file.
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
    check_outputs(&[
        ("--output", Some(args.output.as_path())),
        ("--heatmap", args.heatmap.as_deref()),
        ("--json", args.json.as_deref()),
    ])?;
    let pool = pool(args.threads.map(usize::from))?;
    let options = BuildOptions::default()
        .layout(args.layout)
        .thread_pool(&pool);
    let (scene, bvh, tree, build_ms) = load_and_build(&args.scene, args.patches, &options)?;
    let rconfig = RenderConfig {
        res: args.res,
        two_sided: scene.two_sided_materials(),
        offset: match args.offset {
            OffsetArg::Ulps => Offset::Ulps,
            OffsetArg::Epsilon => Offset::Epsilon,
        },
        packets: args.packets == OnOff::On,
        ..RenderConfig::default()
    };
    let rows = args.res as u64 + 1;
    let bar = indicatif::ProgressBar::new(rows);
    bar.set_style(indicatif::ProgressStyle::with_template(
        "rendering {bar:40} {pos}/{len} rows [{elapsed}]",
    )?);
    let start = Instant::now();
    let image = pool.install(|| render(&scene, &bvh, &rconfig, &|n| bar.inc(n as u64)));
    let trace_ms = start.elapsed().as_secs_f64() * 1e3;
    bar.finish_and_clear();
    write_png(&args.output, image.res, image.res, &image.rgb)?;
    // Havran's statistics come from a second, counting pass: the timed pass above runs the
    // plain kernels. The counting pass traces ray by ray, so the statistics are per ray as
    // Havran defines them; both passes must trace the same rays and draw the same image.
    let counted_config = RenderConfig {
        counters: true,
        packets: false,
        ..rconfig.clone()
    };
    let counted = pool.install(|| render(&scene, &bvh, &counted_config, &|_| {}));
    if counted.rays != image.rays || counted.rgb != image.rgb {
        return Err(
            "internal error: the counting pass traced different rays than the plain pass".into(),
        );
    }
    if let Some(h) = &args.heatmap {
        let (w, px) = heatmap(&counted.eye_nodes, args.res as usize + 1);
        write_png(h, w as u32, w as u32, &px)?;
    }
    let stats = tree.stats();
    let rays = image.rays;
    let total = rays.total().max(1) as f64;
    let work = counted.work;
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
            "shadow": rays.shadow,
            "shadow_blocked": rays.shadow_blocked,
            "total": rays.total(),
        },
        "build_ms": build_ms,
        "trace_ms": trace_ms,
        "mrays_per_s": rays.total() as f64 / (trace_ms * 1e3),
        "havran": {
            "N_G": stats.nodes - stats.leaves,
            "N_E": stats.leaves,
            "N_EE": 0,
            "N_ER": bvh.primitives(),
            "N_TS": work.nodes as f64 / total,
            "N_ETS": work.leaves as f64 / total,
            "N_EETS": work.empty_leaves as f64 / total,
            "N_IT": work.prim_tests as f64 / total,
            "box_tests_per_ray": work.box_tests as f64 / total,
            "T_B_ms": build_ms,
            "T_R_ms": trace_ms,
        },
        "output": args.output.display().to_string(),
    });
    print_table(&report);
    write_json(args.json.as_ref(), &report)
}
