//! `quiver packets`: packet traversal against the BVH4 single-ray kernel, side by side on the
//! same rays: eye rays (8 x 8 pixel tiles), shadow rays (one per eye hit and light, in tile
//! order) and incoherent rays, SPD scenes in curve and patch mode, 1 thread and all threads.

use super::{parse_layout, pool, Result};
use crate::output::{outln, write_json};
use quiver::traverse::PacketMode;
use quiver::{BuildOptions, Layout, Primitive};
use quiver_lab::measure::{median_times_interleaved, mrays_per_s, trace, trace_packets, Query};
use quiver_lab::rays;
use quiver_scenes::scene::tessellate::DEFAULT_RESOLUTION;
use quiver_scenes::Scene;
use serde_json::{json, Value};
use std::path::PathBuf;

#[derive(clap::Args)]
pub(crate) struct PacketsArgs {
    /// Scenes; SPD scenes with analytic shapes are measured in curve and in patch mode.
    /// Default: balls3 (158k triangles in patch mode), gears3, teapot12 and tetra9 (262k).
    scenes: Vec<String>,
    /// Image width and height for eye rays.
    #[arg(long, default_value_t = 512, value_parser = clap::value_parser!(u32).range(8..=8192))]
    res: u32,
    /// Incoherent rays per scene.
    #[arg(long, default_value_t = 200_000)]
    rays: usize,
    /// Timed rounds per measurement (median).
    #[arg(long, default_value_t = 5)]
    reps: usize,
    /// Memory layout (a 4-wide one: binary layouts have no packet kernel).
    #[arg(long, default_value = "bvh4-dfs", value_parser = parse_layout)]
    layout: Layout,
    /// Write all rows as JSON.
    #[arg(long)]
    json: Option<PathBuf>,
}

/// The kernels timed side by side.
const KERNELS: [(&str, Option<PacketMode>); 3] = [
    ("single", None),
    ("packet", Some(PacketMode::Auto)),
    ("packet-always", Some(PacketMode::Always)),
];

/// Runs `quiver packets`.
pub(crate) fn run(args: PacketsArgs) -> Result<()> {
    if args.layout.name().starts_with("bvh2") {
        return Err(format!("--layout {}: packets need a 4-wide layout", args.layout).into());
    }
    let scenes = if args.scenes.is_empty() {
        ["balls3", "gears3", "teapot12", "tetra9"]
            .map(String::from)
            .to_vec()
    } else {
        args.scenes.clone()
    };
    let mut jobs = Vec::new();
    for name in &scenes {
        let scene = Scene::load(name)?;
        if !scene.is_all_triangles() {
            jobs.push(("curve", scene.clone()));
        }
        jobs.push(("patch", scene.into_patches(DEFAULT_RESOLUTION)));
    }
    let all = rayon::current_num_threads().max(2);
    let bar = indicatif::ProgressBar::new(jobs.len() as u64);
    bar.set_style(indicatif::ProgressStyle::with_template(
        "{bar:40} {pos}/{len} {msg} [{elapsed}]",
    )?);
    let mut rows = Vec::new();
    for (mode, scene) in &jobs {
        bar.set_message(format!("{} ({mode})", scene.name));
        if scene.is_all_triangles() {
            measure(&args, scene, mode, &scene.triangles(), all, &mut rows)?;
        } else {
            measure(&args, scene, mode, &scene.prims().0, all, &mut rows)?;
        }
        bar.inc(1);
    }
    bar.finish_and_clear();
    print_rows(&rows);
    write_json(args.json.as_ref(), &json!({ "rows": rows }))
}

fn measure<P: Primitive>(
    args: &PacketsArgs,
    scene: &Scene,
    mode: &str,
    prims: &[P],
    all: usize,
    rows: &mut Vec<Value>,
) -> Result<()> {
    let bvh = BuildOptions::default().layout(args.layout).build(prims);
    let eye = rays::camera_tiles(&scene.camera, args.res as usize, 8);
    let lights: Vec<_> = scene.lights.iter().map(|l| l.pos).collect();
    let shadow = rays::shadow_rays(&bvh, &eye, &lights);
    let random = rays::random_rays(&scene.bounds(), args.rays, 11);
    for threads in [1, all] {
        let p = pool(Some(threads as u16))?;
        for (kind, set, query) in [
            ("eye", &eye, Query::Closest),
            ("shadow", &shadow, Query::Any),
            ("incoherent", &random, Query::Closest),
        ] {
            let times = p.install(|| {
                median_times_interleaved(args.reps, KERNELS.len(), |i| {
                    let hits = match KERNELS[i].1 {
                        None => trace(&bvh, set, query),
                        Some(m) => trace_packets(&bvh, set, query, m),
                    };
                    std::hint::black_box(hits);
                })
            });
            let single = mrays_per_s(set.len(), times[0]);
            for ((kernel, _), t) in KERNELS.iter().zip(&times) {
                let mrays = mrays_per_s(set.len(), *t);
                rows.push(json!({
                    "scene": scene.name, "mode": mode, "primitives": prims.len(),
                    "layout": args.layout.name(), "rays": kind, "count": set.len(),
                    "threads": threads, "kernel": kernel, "mrays_per_s": mrays,
                    "vs_single": mrays / single,
                }));
            }
        }
    }
    Ok(())
}

fn print_rows(rows: &[Value]) {
    outln!(
        "{:<12} {:<6} {:>8} {:<11} {:>3} {:>14} {:>14} {:>6} {:>14} {:>6}",
        "scene",
        "mode",
        "prims",
        "rays",
        "thr",
        "single Mrays/s",
        "packet Mrays/s",
        "ratio",
        "always Mrays/s",
        "ratio"
    );
    for group in rows.chunks(KERNELS.len()) {
        let r = &group[0];
        let m = |i: usize| group[i]["mrays_per_s"].as_f64().unwrap_or(f64::NAN);
        let v = |i: usize| group[i]["vs_single"].as_f64().unwrap_or(f64::NAN);
        outln!(
            "{:<12} {:<6} {:>8} {:<11} {:>3} {:>14.2} {:>14.2} {:>5.2}x {:>14.2} {:>5.2}x",
            r["scene"].as_str().unwrap_or(""),
            r["mode"].as_str().unwrap_or(""),
            r["primitives"],
            r["rays"].as_str().unwrap_or(""),
            r["threads"],
            m(0),
            m(1),
            v(1),
            m(2),
            v(2)
        );
    }
}
