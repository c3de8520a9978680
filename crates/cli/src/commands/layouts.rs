//! `quiver layouts`: traversal throughput of every memory layout side by side, with
//! Havran-style time ratios.

use super::{
    count, measured_threads, parse_layout, pool, thread_count, Result, MAX_RAYS, MAX_REPS,
};
use crate::budget::{self, Estimate};
use crate::output::{check_outputs, out, outln, write_json};
use quiver_rt::builders::{build, prim_bounds, BuildConfig, Builder};
use quiver_rt::{BuildOptions, Bvh, Layout};
use quiver_lab::measure::{self, Query};
use quiver_lab::rays;
use serde_json::{json, Value};
use std::path::PathBuf;

#[derive(clap::Args)]
pub(crate) struct LayoutsArgs {
    /// Scenes (generator names or .nff/.obj/.ply/.ply.gz/.gltf/.glb files).
    #[arg(default_values_t = ["tetra9".to_string(), "soup200000".to_string(), "tetra10".to_string()])]
    scenes: Vec<String>,
    /// Layouts to measure (default: all).
    #[arg(long = "layout", value_parser = parse_layout)]
    layouts: Vec<Layout>,
    /// Incoherent rays per measurement.
    #[arg(allow_negative_numbers = true, long, default_value_t = 300_000, value_parser = count(MAX_RAYS))]
    rays: usize,
    /// Camera rays per measurement: a RES × RES image.
    #[arg(allow_negative_numbers = true, long, default_value_t = 512, value_parser = count(8192))]
    res: usize,
    /// Thread counts to measure, comma-separated.
    #[arg(allow_negative_numbers = true, long, value_delimiter = ',', default_values_t = [1u16, 2], value_parser = thread_count())]
    threads: Vec<u16>,
    /// Timed rounds (each runs every layout once; the median per layout is reported).
    #[arg(allow_negative_numbers = true, long, default_value_t = 5, value_parser = count(MAX_REPS))]
    reps: usize,
    /// Write the rows and ratios as JSON to this file.
    #[arg(long)]
    json: Option<PathBuf>,
}

/// Memory per triangle of the largest scene with every layout, beyond the scenes: the build
/// tree, the eleven layouts kept side by side and their triangle copies (`quiver layouts
/// soup100000` and `soup300000 --rays 10 --res 8`: 213 and 593 MB, 1900 B a triangle with the
/// scene's 128), rounded up; fewer layouts take their share.
const PER_TRIANGLE: u64 = 2200;

/// Memory per random or camera ray and its results (`quiver layouts soup1000 --rays 2000000`:
/// 102 MB, 48 B a ray; `--res 1024`: 50 B a camera ray), rounded up.
const PER_RAY: u64 = 64;

/// One throughput measurement.
struct Row {
    scene: String,
    layout: Layout,
    threads: usize,
    rays: &'static str,
    query: Query,
    mrays: f64,
}

/// Runs `quiver layouts`.
pub(crate) fn run(args: LayoutsArgs) -> Result<()> {
    check_outputs(&[("--json", args.json.as_deref())], &args.scenes)?;
    let mut layouts: Vec<Layout> = Vec::new();
    // A layout named twice would be timed twice and shown as two equal columns.
    for &l in &args.layouts {
        if !layouts.contains(&l) {
            layouts.push(l);
        }
    }
    if layouts.is_empty() {
        layouts = Layout::ALL.to_vec();
    }
    let threads = measured_threads(&args.threads);
    // Every scene loads before the first measurement, so a bad name or file fails at once
    // rather than after the scenes before it were measured.
    let loaded = super::load_within(&args.scenes, |censuses, _| {
        let mut e = Estimate::new(format!("layouts {}", args.scenes.join(" ")));
        e.add("scenes", super::scenes_bytes(censuses, false));
        let tris = super::largest(censuses, super::triangles_of);
        e.add(
            format!(
                "{} triangles in {} layouts at {PER_TRIANGLE} B",
                budget::count(tris),
                layouts.len()
            ),
            tris * PER_TRIANGLE * layouts.len() as u64 / Layout::ALL.len() as u64,
        );
        e.add(
            format!("{} random rays", budget::count(args.rays as u64)),
            args.rays as u64 * PER_RAY,
        );
        let eye = (args.res as u64).pow(2);
        e.add(format!("{} camera rays", budget::count(eye)), eye * PER_RAY);
        e
    })?;
    let loaded: Vec<_> = args.scenes.iter().zip(loaded).collect();
    let config = BuildConfig::default();
    let count_pool = pool(None)?;
    let per_scene = layouts.len() * threads.len() * 4;
    let bar = indicatif::ProgressBar::new((args.scenes.len() * per_scene) as u64);
    bar.set_style(indicatif::ProgressStyle::with_template(
        "{bar:40} {pos}/{len} {msg} [{elapsed}]",
    )?);
    let mut rows = Vec::new();
    let mut sizes = Vec::new();
    for (name, scene) in &loaded {
        let tris = scene.triangles();
        let tree = build(&prim_bounds(&tris), &config, Builder::Binned);
        let sets = [
            ("random", rays::random_rays(&scene.bounds(), args.rays, 7)),
            ("camera", rays::camera_rays(&scene.camera, args.res)),
        ];
        let mut bvhs = Vec::new();
        for &layout in &layouts {
            bar.set_message(format!("{name}: laying out {layout}"));
            let bvh = Bvh::from_tree(
                &tree,
                &tris,
                &BuildOptions::default()
                    .config(config.clone())
                    .layout(layout),
            )?;
            // What each layout's boxes cost in work: counters over the random rays.
            let work = count_pool.install(|| measure::count(&bvh, &sets[0].1, Query::Closest));
            let per_ray = |x: u64| x as f64 / sets[0].1.len() as f64;
            sizes.push(json!({
                "scene": scene.name,
                "primitives": tris.len(),
                "layout": layout.name(),
                "nodes": bvh.footprint().nodes,
                "node_bytes": bvh.footprint().node_bytes,
                "node_bytes_per_prim": bvh.footprint().node_bytes as f64 / tris.len().max(1) as f64,
                "nodes_per_ray": per_ray(work.nodes),
                "box_tests_per_ray": per_ray(work.box_tests),
                "prim_tests_per_ray": per_ray(work.prim_tests),
            }));
            bvhs.push(bvh);
        }
        for &threads in &threads {
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
                            threads,
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
    let Some(first) = rows.first() else {
        return out;
    };
    for r in rows.iter().filter(|r| r.layout == first.layout) {
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
    // Each table row starts from the first layout's measurement.
    let Some(&first) = layouts.first() else {
        return;
    };
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
    for r in rows.iter().filter(|r| r.layout == first) {
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
    for r in rows.iter().filter(|r| r.layout == first) {
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
        Layout::Bvh8Dfs => "8-dfs",
    }
}
