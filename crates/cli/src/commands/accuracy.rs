//! `quiver accuracy`: what accuracy costs: intersector x box test x offset, in time and in
//! errors, as a table and, with `--plot`, a scatter plot.

use super::{count, pool, scene_help, thread_count, Result, MAX_RAYS, MAX_REPS};
use crate::budget::{self, Estimate};
use crate::output::{check_outputs, outln, scatter_svg, write_json, write_text, Axes, Point};
use quiver_lab::accuracy::{evaluate, Row};
use serde_json::{json, Value};
use std::path::PathBuf;

#[derive(clap::Args)]
pub(crate) struct AccuracyArgs {
    /// Scene (triangulated for the measurement).
    #[arg(default_value = "teapot12", long_help = scene_help())]
    scene: String,
    /// Incoherent rays for throughput, reference mismatches and secondary rays.
    #[arg(allow_negative_numbers = true, long, default_value_t = 300_000, value_parser = count(MAX_RAYS))]
    rays: usize,
    /// Timed repetitions (median).
    #[arg(allow_negative_numbers = true, long, default_value_t = 3, value_parser = count(MAX_REPS))]
    reps: usize,
    /// Subdivisions of the icosphere the leak test shoots at (20*4^n triangles).
    #[arg(allow_negative_numbers = true, long, default_value_t = 5, value_parser = clap::value_parser!(u32).range(0..=8))]
    sphere: u32,
    /// Worker threads (default: all cores).
    #[arg(allow_negative_numbers = true, long, value_parser = thread_count())]
    threads: Option<u16>,
    /// Write the time-against-error plot (SVG) to this file (default: no plot).
    #[arg(long)]
    plot: Option<PathBuf>,
    /// Write the rows as JSON to this file.
    #[arg(long)]
    json: Option<PathBuf>,
}

/// Memory per triangle of the scene beyond it: twelve intersector, box test and offset
/// combinations' BVHs (`quiver accuracy soup100000` and `soup300000 --rays 10 --sphere 0`: 88 and
/// 287 MB, 1000 B a triangle with the scene's 128), rounded up.
const PER_TRIANGLE: u64 = 1100;

/// Memory per ray with its reference answers (`quiver accuracy soup1000 --rays 2000000`: 156
/// MB, 75 B), rounded up.
const PER_RAY: u64 = 96;

/// Memory per triangle of the leak test's icosphere (`quiver accuracy soup1000 --sphere 8`:
/// 2.31 GB for 1,310,720 triangles, 1760 B), rounded up.
const PER_SPHERE_TRIANGLE: u64 = 2000;

/// Runs `quiver accuracy`.
pub(crate) fn run(args: AccuracyArgs) -> Result<()> {
    check_outputs(
        &[
            ("--plot", args.plot.as_deref()),
            ("--json", args.json.as_deref()),
        ],
        &[&args.scene],
    )?;
    let scene = super::load_within(std::slice::from_ref(&args.scene), |censuses, _| {
        let mut e = Estimate::new(format!("accuracy {}", args.scene));
        e.add("scene", super::scenes_bytes(censuses, false));
        let tris = super::largest(censuses, super::triangles_of);
        e.add(
            format!("{} triangles at {PER_TRIANGLE} B", budget::count(tris)),
            tris * PER_TRIANGLE,
        );
        e.add(
            format!("{} rays", budget::count(args.rays as u64)),
            args.rays as u64 * PER_RAY,
        );
        let sphere = 20u64 << (2 * args.sphere);
        e.add(
            format!(
                "icosphere{} ({} triangles)",
                args.sphere,
                budget::count(sphere)
            ),
            sphere * PER_SPHERE_TRIANGLE,
        );
        e
    })?
    .pop()
    .ok_or("internal error: no scene loaded")?;
    let tris = scene.triangles();
    let pool = pool(args.threads.map(usize::from))?;
    let bar = indicatif::ProgressBar::new_spinner();
    bar.set_message(format!("measuring 12 combinations on {}", scene.name));
    bar.enable_steady_tick(std::time::Duration::from_millis(200));
    let rows = pool.install(|| evaluate(&tris, args.rays, args.reps, args.sphere));
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
    if let Some(path) = &args.plot {
        write_text(path, &plot(&rows, &scene.name))?;
    }
    write_json(args.json.as_ref(), &Value::Array(json_rows))
}

/// Time per ray against errors per million (log scale), one labelled point per combination.
fn plot(rows: &[Row], scene: &str) -> String {
    let points: Vec<Point> = rows
        .iter()
        .map(|r| Point {
            x: 1e3 / r.mrays_per_s.max(1e-9),
            y: r.leaks_per_million + r.self_hits_per_million + r.ref_mismatch_per_million,
            label: format!("{} / {} / {}", r.intersector, r.box_test, r.offset),
            color: match r.intersector {
                "fast" => "#d62728",
                "watertight" => "#1f77b4",
                _ => "#2ca02c",
            },
        })
        .collect();
    scatter_svg(
        &format!("What accuracy costs on {scene}: time per closest-hit ray vs errors"),
        "ns per ray (closest hit, incoherent)",
        "leaks + self-hits + reference mismatches per million (log)",
        &points,
        Axes {
            x_log: false,
            legend: &[],
        },
    )
}
