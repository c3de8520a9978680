//! The `quiver` command line: thin over the library. Every command prints a table on stdout
//! and, with `--json FILE`, writes the same facts under stable keys.

use clap::{Parser, Subcommand, ValueEnum};
use quiver::build::{BuildConfig, Builder};
use quiver::scene::{Scene, GENERATORS};
use quiver::Bvh2;
use serde_json::{json, Value};
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

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
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::from(2)
        }
    }
}

type Result<T> = std::result::Result<T, Box<dyn std::error::Error>>;

fn pool(threads: Option<u16>) -> Result<rayon::ThreadPool> {
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
    let scene = Scene::load(&args.scene)?;
    let pool = pool(args.threads)?;
    let start = Instant::now();
    let (bvh, tree) = pool.install(|| Bvh2::build(&scene.triangles, &config, builder));
    let build_ms = start.elapsed().as_secs_f64() * 1e3;
    let stats = tree.stats();
    let report = json!({
        "scene": scene.name,
        "objects": scene.objects,
        "primitives": scene.triangles.len(),
        "dropped": tree.dropped,
        "builder": builder.name(),
        "layout": "bvh2-dfs",
        "threads": pool.current_num_threads(),
        "nodes": stats.nodes,
        "leaves": stats.leaves,
        "depth": stats.depth,
        "sah_cost": tree.sah_cost(&config),
        "build_ms": build_ms,
        "bytes": bvh.bytes(),
    });
    print_table(&report);
    write_json(args.json.as_ref(), &report)
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
        println!("{k:<width$}  {shown}");
    }
}

fn write_json(path: Option<&PathBuf>, report: &Value) -> Result<()> {
    if let Some(p) = path {
        let text = serde_json::to_string_pretty(report)?;
        std::fs::write(p, text + "\n").map_err(|e| format!("cannot write {}: {e}", p.display()))?;
    }
    Ok(())
}
