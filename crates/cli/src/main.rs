//! The `quiver` command line: thin over the library. Every command prints a table on stdout
//! and, with `--json FILE`, writes the same facts under stable keys.

use clap::{Parser, Subcommand, ValueEnum};
use quiver_scenes::accel::SceneBvh;
use quiver::build::{BuildConfig, Builder};
use quiver_lab::measure::{self, Query};
use quiver_scenes::render::{render, Offset, RenderConfig};
use quiver_scenes::scene::{Scene, GENERATORS};
use quiver::{Bvh, Layout};
use quiver_lab::{rays};
use serde_json::{json, Value};
use std::io::Write;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

mod bench;
mod packets;

/// `println!` that stops quietly when stdout is gone (`quiver ... | head`) instead of panicking.
macro_rules! outln {
    ($($t:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stdout(), $($t)*);
    }};
}
pub(crate) use outln;

/// `print!` with the same rule as [`outln!`].
macro_rules! out {
    ($($t:tt)*) => {{
        let _ = write!(std::io::stdout(), $($t)*);
    }};
}

#[derive(Parser)]
#[command(
    name = "quiver",
    version,
    about = "Parallel SAH BVHs and ray shooting on CPUs"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Build a BVH over a scene and report its size, SAH cost and build time.
    Build(BuildArgs),
    /// Measure traversal throughput of every memory layout on several scenes.
    Layouts(LayoutsArgs),
    /// Write a scene as NFF (to stdout, or to a file with -o).
    Gen(GenArgs),
    /// Render a scene by the SPD testing procedure to a PNG and report the rays it traced.
    Render(RenderArgs),
    /// Measure what accuracy costs: intersector x box test x offset, in time and errors.
    Accuracy(AccuracyArgs),
    /// quiver and obvhs side by side: builds, SAH cost, eye/shadow/incoherent Mrays/s.
    Bench(bench::BenchArgs),
    /// Packet traversal against BVH4 single rays: eye, shadow and incoherent Mrays/s.
    Packets(packets::PacketsArgs),
}

#[derive(clap::Args)]
struct AccuracyArgs {
    /// Scene (triangulated for the measurement).
    #[arg(default_value = "teapot12", long_help = scene_help())]
    scene: String,
    /// Incoherent rays for throughput, reference mismatches and secondary rays.
    #[arg(long, default_value_t = 300_000)]
    rays: usize,
    /// Timed repetitions (median).
    #[arg(long, default_value_t = 3)]
    reps: usize,
    /// Subdivisions of the icosphere the leak test shoots at (20*4^n triangles).
    #[arg(long, default_value_t = 5, value_parser = clap::value_parser!(u32).range(0..=8))]
    sphere: u32,
    /// Worker threads (default: all cores).
    #[arg(long, value_parser = clap::value_parser!(u16).range(1..=1024))]
    threads: Option<u16>,
    /// Write the time-against-error plot (SVG) here.
    #[arg(long, default_value = "accuracy.svg")]
    plot: PathBuf,
    /// Write the rows as JSON to this file.
    #[arg(long)]
    json: Option<PathBuf>,
}

#[derive(clap::Args)]
struct RenderArgs {
    /// A generator name with optional size, or an .nff/.obj file.
    #[arg(default_value = DEFAULT_SCENE, long_help = scene_help())]
    scene: String,
    /// Image width and height in pixels ((res+1)^2 eye rays at the pixel corners).
    #[arg(long, default_value_t = 512, value_parser = clap::value_parser!(u32).range(1..=16384))]
    res: u32,
    /// Output PNG.
    #[arg(short, long, default_value = "quiver.png")]
    output: PathBuf,
    /// Worker threads (default: all cores).
    #[arg(long, value_parser = clap::value_parser!(u16).range(1..=1024))]
    threads: Option<u16>,
    /// Memory layout of the BVH.
    #[arg(long, default_value = "bvh4-dfs", value_parser = parse_layout, long_help = layout_help())]
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

#[derive(clap::Args)]
struct GenArgs {
    /// A generator name with optional size, or an .nff/.obj file.
    #[arg(long_help = scene_help())]
    scene: String,
    /// Tessellate spheres and cones into polygonal patches (the SPD's patch mode).
    #[arg(long)]
    patches: bool,
    /// Tessellation resolution for --patches (the SPD's OUTPUT_RESOLUTION).
    #[arg(long, default_value_t = quiver_scenes::scene::tessellate::DEFAULT_RESOLUTION, value_parser = clap::value_parser!(u32).range(1..=1000))]
    resolution: u32,
    /// Output file (default: stdout).
    #[arg(short, long)]
    output: Option<PathBuf>,
}

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

#[derive(Clone, Copy, ValueEnum)]
enum BuilderArg {
    Binned,
    Sweep,
}

#[derive(clap::Args)]
struct BuildArgs {
    /// A generator name with optional size (see `--help`), or a .obj file.
    #[arg(long_help = scene_help())]
    scene: String,
    /// Which SAH builder.
    #[arg(long, value_enum, default_value = "binned")]
    builder: BuilderArg,
    /// Memory layout of the nodes.
    #[arg(long, default_value = "bvh2-dfs", value_parser = parse_layout, long_help = layout_help())]
    layout: Layout,
    /// Tessellate spheres and cones (the SPD's patch mode).
    #[arg(long)]
    patches: bool,
    /// Worker threads (default: all cores).
    #[arg(long, value_parser = clap::value_parser!(u16).range(1..=1024))]
    threads: Option<u16>,
    /// Bins per axis for the binned builder.
    #[arg(long, default_value_t = 16, value_parser = clap::value_parser!(u16).range(2..=1024))]
    bins: u16,
    /// Largest leaf the build may make.
    #[arg(long, default_value_t = 8, value_parser = clap::value_parser!(u16).range(1..=255))]
    max_leaf: u16,
    /// SAH cost of an inner-node visit (c_T).
    #[arg(long, default_value_t = 1.0)]
    traversal_cost: f32,
    /// SAH cost of one primitive test (c_I).
    #[arg(long, default_value_t = 1.0)]
    intersection_cost: f32,
    /// Write the report as JSON to this file.
    #[arg(long)]
    json: Option<PathBuf>,
}

#[derive(clap::Args)]
struct LayoutsArgs {
    /// Scenes (generator names or .obj files).
    #[arg(default_values_t = ["tetra9".to_string(), "soup200000".to_string(), "tetra10".to_string()])]
    scenes: Vec<String>,
    /// Layouts to measure (default: all).
    #[arg(long = "layout", value_parser = parse_layout)]
    layouts: Vec<Layout>,
    /// Incoherent rays per measurement.
    #[arg(long, default_value_t = 300_000)]
    rays: usize,
    /// Camera rays per measurement: a RES × RES image.
    #[arg(long, default_value_t = 512)]
    res: usize,
    /// Thread counts to measure.
    #[arg(long, value_delimiter = ',', default_values_t = [1u16, 2])]
    threads: Vec<u16>,
    /// Timed rounds (each runs every layout once; the median per layout is reported).
    #[arg(long, default_value_t = 5)]
    reps: usize,
    /// Write the rows and ratios as JSON to this file.
    #[arg(long)]
    json: Option<PathBuf>,
}

pub(crate) fn parse_layout(s: &str) -> std::result::Result<Layout, String> {
    s.parse()
}

fn layout_help() -> String {
    let names: Vec<&str> = Layout::ALL.iter().map(|l| l.name()).collect();
    format!(
        "Memory layout of the nodes: {}. bvh2-* are 32-byte binary nodes (dfs: depth-first; bfs: \
         breadth-first; shuffled: random order; subtree: cache-line blocks; subtree-page: 4 KiB \
         blocks; compact/compact-page: implicitly addressed blocks); bvh4-* are 4-wide nodes \
         (dfs, page subtrees, quant: 8-bit quantized 64-byte nodes).",
        names.join(", ")
    )
}

fn scene_help() -> String {
    let mut s = String::from(
        "A generator name with an optional size, e.g. tetra6 (a bare name takes the default size), \
         or a path to a .obj file. Generators:\n",
    );
    for g in GENERATORS {
        s += &format!("  {:<8} {} (default {})\n", g.name, g.about, g.default_size);
    }
    s
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Build(args) => cmd_build(args),
        Command::Layouts(args) => cmd_layouts(args),
        Command::Gen(args) => cmd_gen(args),
        Command::Render(args) => cmd_render(args),
        Command::Accuracy(args) => cmd_accuracy(args),
        Command::Bench(args) => bench::cmd_bench(args),
        Command::Packets(args) => packets::cmd_packets(args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::from(2)
        }
    }
}

pub(crate) type Result<T> = std::result::Result<T, Box<dyn std::error::Error>>;

pub(crate) fn pool(threads: Option<u16>) -> Result<rayon::ThreadPool> {
    let mut b = rayon::ThreadPoolBuilder::new();
    if let Some(n) = threads {
        b = b.num_threads(n as usize);
    }
    Ok(b.build()?)
}

fn cmd_build(args: BuildArgs) -> Result<()> {
    let config = BuildConfig {
        bins: args.bins as usize,
        max_leaf_size: args.max_leaf as usize,
        traversal_cost: finite_cost("--traversal-cost", args.traversal_cost)?,
        intersection_cost: finite_cost("--intersection-cost", args.intersection_cost)?,
        ..BuildConfig::default()
    };
    let builder = match args.builder {
        BuilderArg::Binned => Builder::Binned,
        BuilderArg::Sweep => Builder::Sweep,
    };
    let pool = pool(args.threads)?;
    let (scene, bvh, tree, build_ms) = load_and_build(
        &args.scene,
        args.patches,
        &pool,
        &config,
        builder,
        args.layout,
    )?;
    let stats = tree.stats();
    let prims = bvh.primitives().max(1) as f64;
    let report = json!({
        "scene": scene.name,
        "objects": scene.objects.len(),
        "primitives": bvh.primitives(),
        "primitive_kind": if bvh.is_triangles() { "triangles" } else { "mixed" },
        "dropped": tree.dropped,
        "builder": builder.name(),
        "layout": args.layout.name(),
        "threads": pool.current_num_threads(),
        "nodes": bvh.nodes(),
        "tree_nodes": stats.nodes,
        "leaves": stats.leaves,
        "depth": stats.depth,
        "sah_cost": tree.sah_cost(&config),
        "build_ms": build_ms,
        "bytes": bvh.bytes(),
        "node_bytes": bvh.node_bytes(),
        "node_bytes_per_prim": bvh.node_bytes() as f64 / prims,
        "bytes_per_prim": bvh.bytes() as f64 / prims,
    });
    print_table(&report);
    write_json(args.json.as_ref(), &report)
}

/// Loads a scene (in patch mode if asked) and builds its BVH on `pool`: curve mode keeps
/// analytic shapes on the mixed path, patch mode puts everything on the triangle path.
/// Returns the build time in ms beside the results.
fn load_and_build(
    name: &str,
    patches: bool,
    pool: &rayon::ThreadPool,
    config: &BuildConfig,
    builder: Builder,
    layout: Layout,
) -> Result<(Scene, SceneBvh, quiver::build::BuildTree, f64)> {
    let mut scene = Scene::load(name)?;
    if patches {
        scene = scene.into_patches(quiver_scenes::scene::tessellate::DEFAULT_RESOLUTION);
    }
    let start = Instant::now();
    let (bvh, tree) = pool.install(|| {
        if patches {
            SceneBvh::build_triangles(&scene, config, builder, layout)
        } else {
            SceneBvh::build(&scene, config, builder, layout)
        }
    });
    Ok((scene, bvh, tree, start.elapsed().as_secs_f64() * 1e3))
}

fn cmd_render(args: RenderArgs) -> Result<()> {
    let pool = pool(args.threads)?;
    let (scene, bvh, tree, build_ms) = load_and_build(
        &args.scene,
        args.patches,
        &pool,
        &BuildConfig::default(),
        Builder::Binned,
        args.layout,
    )?;
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

fn cmd_accuracy(args: AccuracyArgs) -> Result<()> {
    if args.rays == 0 {
        return Err("--rays must be at least 1".into());
    }
    let scene = Scene::load(&args.scene)?;
    let tris = scene.triangles();
    let pool = pool(args.threads)?;
    let bar = indicatif::ProgressBar::new_spinner();
    bar.set_message(format!("measuring 12 combinations on {}", scene.name));
    bar.enable_steady_tick(std::time::Duration::from_millis(200));
    let rows =
        pool.install(|| quiver_lab::accuracy::evaluate(&tris, args.rays, args.reps, args.sphere));
    bar.finish_and_clear();
    outln!(
        "{:<11} {:<13} {:<8} {:>9} {:>9} {:>12} {:>12} {:>12}",
        "intersector",
        "box test",
        "offset",
        "Mrays/s",
        "any M/s",
        "leaks/M",
        "self-hits/M",
        "ref diff/M"
    );
    for r in &rows {
        outln!(
            "{:<11} {:<13} {:<8} {:>9.2} {:>9.2} {:>12.1} {:>12.1} {:>12.1}",
            r.intersector,
            r.box_test,
            r.offset,
            r.mrays_per_s,
            r.any_mrays_per_s,
            r.leaks_per_million,
            r.self_hits_per_million,
            r.ref_mismatch_per_million
        );
    }
    outln!(
        "({} triangles, {} rays, {} threads; leaks on icosphere{})",
        tris.len(),
        args.rays,
        pool.current_num_threads(),
        args.sphere
    );
    let json_rows: Vec<Value> = rows
        .iter()
        .map(|r| {
            json!({
                "scene": scene.name,
                "intersector": r.intersector,
                "box_test": r.box_test,
                "offset": r.offset,
                "mrays_per_s": r.mrays_per_s,
                "any_mrays_per_s": r.any_mrays_per_s,
                "leaks_per_million": r.leaks_per_million,
                "self_hits_per_million": r.self_hits_per_million,
                "ref_mismatch_per_million": r.ref_mismatch_per_million,
            })
        })
        .collect();
    std::fs::write(&args.plot, accuracy_svg(&rows, &scene.name))
        .map_err(|e| format!("cannot write {}: {e}", args.plot.display()))?;
    write_json(args.json.as_ref(), &Value::Array(json_rows))
}

/// Time per ray against errors per million (log scale), one labelled point per combination.
fn accuracy_svg(rows: &[quiver_lab::accuracy::Row], scene: &str) -> String {
    let (w, h, m) = (760.0, 480.0, 70.0);
    let ns = |r: &quiver_lab::accuracy::Row| 1e3 / r.mrays_per_s.max(1e-9);
    let err = |r: &quiver_lab::accuracy::Row| {
        r.leaks_per_million + r.self_hits_per_million + r.ref_mismatch_per_million
    };
    let xmax = rows.iter().map(ns).fold(0.0f64, f64::max) * 1.1;
    let ymax = rows.iter().map(err).fold(10.0f64, f64::max).log10().ceil();
    let x = |v: f64| m + v / xmax * (w - 2.0 * m);
    let y = |v: f64| h - m - (1.0 + v).log10() / ymax * (h - 2.0 * m);
    let mut s = format!(
        "<svg xmlns='http://www.w3.org/2000/svg' width='{w}' height='{h}' font-family='sans-serif' font-size='11'>\n\
         <rect width='100%' height='100%' fill='white'/>\n\
         <text x='{}' y='20' text-anchor='middle' font-size='14'>What accuracy costs on {scene}: time per closest-hit ray vs errors</text>\n\
         <line x1='{m}' y1='{}' x2='{}' y2='{}' stroke='black'/><line x1='{m}' y1='{m}' x2='{m}' y2='{}' stroke='black'/>\n\
         <text x='{}' y='{}' text-anchor='middle'>ns per ray (closest hit, incoherent)</text>\n\
         <text x='16' y='{}' transform='rotate(-90 16 {})' text-anchor='middle'>leaks + self-hits + reference mismatches per million (log)</text>\n",
        w / 2.0, h - m, w - m, h - m, h - m, w / 2.0, h - 20.0, h / 2.0, h / 2.0
    );
    for k in 0..=ymax as i32 {
        let v = 10f64.powi(k) - 1.0;
        s += &format!(
            "<text x='{}' y='{}' text-anchor='end'>{}</text>\n",
            m - 6.0,
            y(v) + 4.0,
            10f64.powi(k) as u64 - 1
        );
    }
    for k in 0..=4 {
        let v = xmax * k as f64 / 4.0;
        s += &format!(
            "<text x='{}' y='{}' text-anchor='middle'>{v:.0}</text>\n",
            x(v),
            h - m + 16.0
        );
    }
    for (i, r) in rows.iter().enumerate() {
        let color = match r.intersector {
            "fast" => "#d62728",
            "watertight" => "#1f77b4",
            _ => "#2ca02c",
        };
        let (px, py) = (x(ns(r)), y(err(r)));
        s += &format!(
            "<circle cx='{px:.1}' cy='{py:.1}' r='5' fill='{color}' fill-opacity='0.7'/><text x='{:.1}' y='{:.1}'>{} / {} / {}</text>\n",
            px + 7.0,
            py - 4.0 + (i % 2) as f64 * 12.0,
            r.intersector,
            r.box_test,
            r.offset
        );
    }
    s + "</svg>\n"
}

fn write_png(path: &PathBuf, w: u32, h: u32, rgb: &[[u8; 3]]) -> Result<()> {
    let fail = |e: &dyn std::fmt::Display| format!("cannot write {}: {e}", path.display());
    let file = std::fs::File::create(path).map_err(|e| fail(&e))?;
    let mut enc = png::Encoder::new(std::io::BufWriter::new(file), w, h);
    enc.set_color(png::ColorType::Rgb);
    enc.set_depth(png::BitDepth::Eight);
    let mut writer = enc.write_header().map_err(|e| fail(&e))?;
    writer
        .write_image_data(rgb.as_flattened())
        .map_err(|e| fail(&e))?;
    writer.finish().map_err(|e| fail(&e))?;
    Ok(())
}

/// A false-colour picture of per-ray node counts: dark blue (few) through green and yellow to
/// red (the most, at the 99th percentile so a few outliers do not wash out the image).
fn heatmap(counts: &[u32], width: usize) -> (usize, Vec<[u8; 3]>) {
    let mut sorted = counts.to_vec();
    sorted.sort_unstable();
    let top = sorted
        .get(sorted.len() * 99 / 100)
        .copied()
        .unwrap_or(1)
        .max(1) as f32;
    let px = counts
        .iter()
        .map(|&c| {
            let x = (c as f32 / top).min(1.0);
            let ramp = [
                (0.0, [0.0, 0.0, 0.3]),
                (0.33, [0.0, 0.6, 1.0]),
                (0.66, [1.0, 1.0, 0.0]),
                (1.0, [1.0, 0.0, 0.0]),
            ];
            let k = ramp.windows(2).position(|w| x <= w[1].0).unwrap_or(2);
            let (a, b) = (ramp[k], ramp[k + 1]);
            let f = (x - a.0) / (b.0 - a.0);
            let ch = |i: usize| ((a.1[i] + (b.1[i] - a.1[i]) * f) * 255.0 + 0.5) as u8;
            [ch(0), ch(1), ch(2)]
        })
        .collect();
    (width, px)
}

fn cmd_gen(args: GenArgs) -> Result<()> {
    let mut scene = Scene::load(&args.scene)?;
    if args.patches {
        scene = scene.into_patches(args.resolution);
    }
    match &args.output {
        Some(p) => {
            let file = std::fs::File::create(p)
                .map_err(|e| format!("cannot create {}: {e}", p.display()))?;
            let mut w = std::io::BufWriter::new(file);
            quiver_scenes::scene::nff::write(&scene, &mut w)
                .map_err(|e| format!("cannot write {}: {e}", p.display()))?;
            w.flush()
                .map_err(|e| format!("cannot write {}: {e}", p.display()))?;
        }
        None => {
            let stdout = std::io::stdout();
            let mut w = std::io::BufWriter::new(stdout.lock());
            // A closed pipe (`quiver gen ... | head`) is not an error worth a message.
            match quiver_scenes::scene::nff::write(&scene, &mut w).and_then(|_| w.flush()) {
                Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => {}
                other => other?,
            }
        }
    }
    Ok(())
}

fn finite_cost(flag: &str, v: f32) -> Result<f32> {
    if v.is_finite() && v >= 0.0 {
        Ok(v)
    } else {
        Err(format!("{flag} must be a finite number >= 0, got {v}").into())
    }
}

fn print_table(report: &Value) {
    let Value::Object(map) = report else { return };
    let width = map.keys().map(|k| k.len()).max().unwrap_or(0);
    for (k, v) in map {
        let shown = match v {
            Value::String(s) => s.clone(),
            Value::Number(n) if n.is_f64() => format!("{:.3}", n.as_f64().unwrap_or(f64::NAN)),
            other => other.to_string(),
        };
        outln!("{k:<width$}  {shown}");
    }
}

pub(crate) fn write_json(path: Option<&PathBuf>, report: &Value) -> Result<()> {
    if let Some(p) = path {
        let text = serde_json::to_string_pretty(report)?;
        std::fs::write(p, text + "\n").map_err(|e| format!("cannot write {}: {e}", p.display()))?;
    }
    Ok(())
}

/// One throughput measurement.
struct Row {
    scene: String,
    layout: Layout,
    threads: usize,
    rays: &'static str,
    query: Query,
    mrays: f64,
}

fn cmd_layouts(args: LayoutsArgs) -> Result<()> {
    let layouts = if args.layouts.is_empty() {
        Layout::ALL.to_vec()
    } else {
        args.layouts.clone()
    };
    if args.rays == 0 || args.res == 0 {
        return Err("--rays and --res must be at least 1".into());
    }
    let config = BuildConfig::default();
    let per_scene = layouts.len() * args.threads.len() * 4;
    let bar = indicatif::ProgressBar::new((args.scenes.len() * per_scene) as u64);
    bar.set_style(indicatif::ProgressStyle::with_template(
        "{bar:40} {pos}/{len} {msg} [{elapsed}]",
    )?);
    let mut rows = Vec::new();
    let mut sizes = Vec::new();
    for name in &args.scenes {
        bar.set_message(format!("loading {name}"));
        let scene = Scene::load(name)?;
        let tris = scene.triangles();
        let tree = quiver::build::build(
            &quiver::layout::triangle_bounds(&tris),
            &config,
            Builder::Binned,
        );
        let sets = [
            ("random", rays::random_rays(&scene.bounds(), args.rays, 7)),
            ("camera", rays::camera_rays(&scene.camera, args.res)),
        ];
        let mut bvhs = Vec::new();
        for &layout in &layouts {
            bar.set_message(format!("{name}: laying out {layout}"));
            let bvh = Bvh::from_tree(&tree, &tris, layout);
            // What each layout's boxes cost in work: counters over the random rays.
            let work = pool(None)?.install(|| measure::count(&bvh, &sets[0].1, Query::Closest));
            let per_ray = |x: u64| x as f64 / sets[0].1.len() as f64;
            sizes.push(json!({
                "scene": scene.name,
                "primitives": tris.len(),
                "layout": layout.name(),
                "nodes": bvh.nodes(),
                "node_bytes": bvh.node_bytes(),
                "node_bytes_per_prim": bvh.node_bytes() as f64 / tris.len().max(1) as f64,
                "nodes_per_ray": per_ray(work.nodes),
                "box_tests_per_ray": per_ray(work.box_tests),
                "prim_tests_per_ray": per_ray(work.prim_tests),
            }));
            bvhs.push(bvh);
        }
        for &threads in &args.threads {
            let pool = pool(Some(threads))?;
            for (kind, rays) in &sets {
                for query in [Query::Closest, Query::Any] {
                    bar.set_message(format!(
                        "{name}: {threads} threads, {kind} rays, {}",
                        query.name()
                    ));
                    // All layouts side by side, round after round.
                    let times = pool.install(|| {
                        measure::median_times_interleaved(args.reps, bvhs.len(), |i| {
                            std::hint::black_box(measure::trace(&bvhs[i], rays, query));
                        })
                    });
                    for (&layout, t) in layouts.iter().zip(times) {
                        rows.push(Row {
                            scene: scene.name.clone(),
                            layout,
                            threads: threads as usize,
                            rays: kind,
                            query,
                            mrays: measure::mrays_per_s(rays.len(), t),
                        });
                    }
                    bar.inc(layouts.len() as u64);
                }
            }
        }
    }
    bar.finish_and_clear();
    print_layout_tables(&sizes, &rows, &layouts);
    let ratios = layout_ratios(&rows);
    let report = json!({
        "sizes": sizes,
        "rows": rows.iter().map(|r| json!({
            "scene": r.scene, "layout": r.layout.name(), "threads": r.threads,
            "rays": r.rays, "query": r.query.name(), "mrays_per_s": r.mrays,
        })).collect::<Vec<_>>(),
        "ratios": ratios,
    });
    write_json(args.json.as_ref(), &report)
}

/// Time ratios (slower layout's time over the faster's, Havran's convention) between pairs of
/// layouts, per scene, threads, ray kind and query.
const RATIOS: [(&str, Layout, Layout); 5] = [
    ("BFS/DFS", Layout::Bvh2Bfs, Layout::Bvh2Dfs),
    ("BFS/subtree", Layout::Bvh2Bfs, Layout::Bvh2Subtree),
    ("DFS/subtree", Layout::Bvh2Dfs, Layout::Bvh2Subtree),
    ("DFS/subtree-page", Layout::Bvh2Dfs, Layout::Bvh2SubtreePage),
    ("BVH2/BVH4", Layout::Bvh2Dfs, Layout::Bvh4Dfs),
];

fn find(rows: &[Row], like: &Row, layout: Layout) -> Option<f64> {
    rows.iter()
        .find(|r| {
            r.scene == like.scene
                && r.threads == like.threads
                && r.rays == like.rays
                && r.query == like.query
                && r.layout == layout
        })
        .map(|r| r.mrays)
}

fn layout_ratios(rows: &[Row]) -> Vec<Value> {
    let mut out = Vec::new();
    for r in rows.iter().filter(|r| r.layout == rows[0].layout) {
        let mut entry = json!({"scene": r.scene, "threads": r.threads, "rays": r.rays, "query": r.query.name()});
        for (name, slow, fast) in RATIOS {
            if let (Some(s), Some(f)) = (find(rows, r, slow), find(rows, r, fast)) {
                // T_slow / T_fast = throughput_fast / throughput_slow.
                entry[name] = json!(f / s);
            }
        }
        out.push(entry);
    }
    out
}

fn print_layout_tables(sizes: &[Value], rows: &[Row], layouts: &[Layout]) {
    outln!(
        "{:<12} {:<18} {:>10} {:>12} {:>8} {:>10} {:>10} {:>10}",
        "scene",
        "layout",
        "nodes",
        "node bytes",
        "B/prim",
        "nodes/ray",
        "boxes/ray",
        "prims/ray"
    );
    let f = |v: &Value| v.as_f64().unwrap_or(f64::NAN);
    for s in sizes {
        outln!(
            "{:<12} {:<18} {:>10} {:>12} {:>8.2} {:>10.1} {:>10.1} {:>10.1}",
            s["scene"].as_str().unwrap_or(""),
            s["layout"].as_str().unwrap_or(""),
            s["nodes"],
            s["node_bytes"],
            f(&s["node_bytes_per_prim"]),
            f(&s["nodes_per_ray"]),
            f(&s["box_tests_per_ray"]),
            f(&s["prim_tests_per_ray"]),
        );
    }
    outln!("(work per random closest-hit ray; node visits include leaves)");
    outln!();
    out!(
        "{:<12} {:>3} {:<7} {:<8}",
        "Mrays/s",
        "thr",
        "rays",
        "query"
    );
    for l in layouts {
        out!(" {:>8}", short(*l));
    }
    outln!();
    for r in rows.iter().filter(|r| r.layout == layouts[0]) {
        row_head(r);
        for &l in layouts {
            out!(" {:>8.2}", find(rows, r, l).unwrap_or(f64::NAN));
        }
        outln!();
    }
    outln!();
    out!(
        "{:<12} {:>3} {:<7} {:<8}",
        "time ratio",
        "thr",
        "rays",
        "query"
    );
    for (name, ..) in RATIOS {
        out!(" {name:>16}");
    }
    outln!();
    for r in rows.iter().filter(|r| r.layout == layouts[0]) {
        row_head(r);
        for (_, slow, fast) in RATIOS {
            match (find(rows, r, slow), find(rows, r, fast)) {
                (Some(s), Some(f)) => out!(" {:>16.3}", f / s),
                _ => out!(" {:>16}", "-"),
            }
        }
        outln!();
    }
}

/// The scene, threads, ray kind and query that start each row of the layout tables.
fn row_head(r: &Row) {
    out!(
        "{:<12} {:>3} {:<7} {:<8}",
        r.scene,
        r.threads,
        r.rays,
        r.query.name()
    );
}

/// Column header for a layout: its name without the common prefix noise.
fn short(l: Layout) -> &'static str {
    match l {
        Layout::Bvh2Dfs => "2-dfs",
        Layout::Bvh2Bfs => "2-bfs",
        Layout::Bvh2Shuffled => "2-shuf",
        Layout::Bvh2Subtree => "2-sub",
        Layout::Bvh2SubtreePage => "2-subpg",
        Layout::Bvh2Compact => "2-cmp",
        Layout::Bvh2CompactPage => "2-cmppg",
        Layout::Bvh4Dfs => "4-dfs",
        Layout::Bvh4Subtree => "4-sub",
        Layout::Bvh4Quant => "4-quant",
    }
}
