//! `quiver predict`: traversal work predicted from surface areas (Cauchy–Crofton; Aronov et
//! al.'s E(T)) beside the work measured on isotropic random lines, per builder and layout;
//! with `--time`, how well the prediction tracks measured time per ray for random, eye and
//! shadow rays across scenes (correlations, and `--plot` a scatter plot).

use super::{count, parse_builder, parse_layout, pool, thread_count, Result, MAX_RAYS, MAX_REPS};
use crate::budget::{self, Estimate};
use crate::output::{check_outputs, out, outln, scatter_svg, write_json, write_text, Axes, Point};
use quiver_rt::builders::Builder;
use quiver_rt::predict::Prediction;
use quiver_rt::{BuildOptions, Bvh, Layout, Ray, Triangle};
use quiver_lab::lines::{counters_per_ray, isotropic_lines, Pierce, Work};
use quiver_lab::measure::{self, Query};
use quiver_lab::rays;
use serde_json::{json, Value};
use std::path::PathBuf;

#[derive(clap::Args)]
pub(crate) struct PredictArgs {
    /// Scenes (generator names with sizes, or .nff/.obj/.ply/.ply.gz/.gltf/.glb files), traced as triangles.
    #[arg(default_values_t = ["tetra4".to_string(), "teapot6".to_string(), "balls2".to_string()])]
    scenes: Vec<String>,
    /// Builders (default: binned and sweep, the top-down pair; any of `quiver build --help`'s).
    #[arg(long = "builder", value_parser = parse_builder)]
    builders: Vec<Builder>,
    /// Layouts (default: all; with --time, the first is the one timed, default bvh8-dfs).
    #[arg(long = "layout", value_parser = parse_layout)]
    layouts: Vec<Layout>,
    /// Isotropic random lines per measurement.
    #[arg(allow_negative_numbers = true, long, default_value_t = 100_000, value_parser = count(MAX_RAYS))]
    lines: usize,
    /// Also time random, eye and shadow rays and correlate predicted cost with time per ray.
    #[arg(long)]
    time: bool,
    /// Random rays per timing (with --time).
    #[arg(allow_negative_numbers = true, long, default_value_t = 200_000, value_parser = count(MAX_RAYS))]
    rays: usize,
    /// Eye rays per timing: a RES × RES image (with --time); shadow rays go from its hits to
    /// the first light.
    #[arg(allow_negative_numbers = true, long, default_value_t = 256, value_parser = count(8192))]
    res: usize,
    /// Timed rounds (median reported).
    #[arg(allow_negative_numbers = true, long, default_value_t = 5, value_parser = count(MAX_REPS))]
    reps: usize,
    /// Worker threads for the timings.
    #[arg(allow_negative_numbers = true, long, default_value_t = 1, value_parser = thread_count())]
    threads: u16,
    /// Write the predicted-cost-against-time scatter plot (SVG) here (implies --time).
    #[arg(long)]
    plot: Option<PathBuf>,
    /// Write every row as JSON to this file.
    #[arg(long)]
    json: Option<PathBuf>,
}

/// Aronov et al.'s objects term `Σ_s A(s) / A(B)`: triangles count both sides (twice their
/// area), the root box its whole surface.
fn object_area(tris: &[Triangle], root: &quiver_rt::Aabb) -> f64 {
    let area: f64 = tris
        .iter()
        .map(|t| 0.5 * (t.v[1] - t.v[0]).cross(t.v[2] - t.v[0]).length() as f64)
        .sum();
    let half = root.half_area() as f64;
    if half > 0.0 {
        area / half
    } else {
        0.0
    }
}

/// One prediction row: a scene, builder and layout.
struct Row {
    scene: String,
    builder: Builder,
    layout: Layout,
    predicted: Prediction,
    aronov: f64,
    /// A walk that never stops, over the lines.
    pierced: Work,
    /// Closest-hit rays along the same lines.
    closest: Work,
}

/// One timing: a scene, builder and ray kind on the timed layout.
struct Timing {
    scene: String,
    builder: Builder,
    rays: &'static str,
    aronov: f64,
    sah: f64,
    /// Nodes + primitive tests per ray, measured.
    work: f64,
    ns_per_ray: f64,
}

/// Memory per triangle of the largest scene beyond the scene: build trees of both builders,
/// every layout over the triangles and over never-hit copies (`quiver predict soup100000` and
/// `soup300000 --time --lines 10 --rays 10 --res 8`: 118 and 383 MB, 1325 B a triangle with
/// the scene's 128), rounded up.
const PER_TRIANGLE: u64 = 1500;

/// Memory per isotropic line and its measurements (`quiver predict soup1000 --lines 2000000`:
/// 258 MB, 125 B a line), rounded up.
const PER_LINE: u64 = 160;

/// Memory per timed ray (`--rays 2000000`: 102 MB, 48 B; `--res 1024`: 77 B an eye ray with
/// its shadow ray), rounded up.
const PER_RAY: u64 = 64;

/// Runs `quiver predict`.
pub(crate) fn run(args: PredictArgs) -> Result<()> {
    check_outputs(
        &[
            ("--json", args.json.as_deref()),
            ("--plot", args.plot.as_deref()),
        ],
        &args.scenes,
    )?;
    let builders = distinct(&args.builders, &[Builder::Binned, Builder::Sweep]);
    let layouts = distinct(&args.layouts, &Layout::ALL);
    let timed_layout = args.layouts.first().copied().unwrap_or(Layout::Bvh8Dfs);
    let time = args.time || args.plot.is_some();
    let loaded = super::load_within(&args.scenes, |censuses, _| {
        let mut e = Estimate::new(format!("predict {}", args.scenes.join(" ")));
        e.add("scenes", super::scenes_bytes(censuses, false));
        let tris = super::largest(censuses, super::triangles_of);
        e.add(
            format!(
                "{} triangles' trees and layouts at {PER_TRIANGLE} B",
                budget::count(tris)
            ),
            tris * PER_TRIANGLE,
        );
        e.add(
            format!("{} lines", budget::count(args.lines as u64)),
            args.lines as u64 * PER_LINE,
        );
        if time {
            e.add(
                format!("{} random rays", budget::count(args.rays as u64)),
                args.rays as u64 * PER_RAY,
            );
            let eye = (args.res as u64).pow(2);
            e.add(
                format!("{} eye and shadow rays", budget::count(eye)),
                eye * 2 * PER_RAY,
            );
        }
        e
    })?;
    let count_pool = pool(None)?;
    let time_pool = pool(Some(args.threads as usize))?;
    let mut rows = Vec::new();
    let mut timings = Vec::new();
    for scene in &loaded {
        let tris = scene.triangles();
        let ghosts = Pierce::of(&tris);
        for &builder in &builders {
            let options = BuildOptions::default().builder(builder);
            let (_, tree) = count_pool.install(|| options.build_with_tree(&tris));
            let root = tree.nodes[0].bounds;
            let objects = object_area(&tris, &root);
            let lines = isotropic_lines(&root, args.lines, 11);
            for &layout in &layouts {
                let laid = options.clone().layout(layout);
                let bvh = Bvh::from_tree(&tree, &tris, &laid)?;
                let ghost = Bvh::from_tree(&tree, &ghosts, &laid)?;
                let predicted = bvh.predict_within(&root);
                let (pierced, closest) = count_pool.install(|| {
                    (
                        Work::of(&counters_per_ray(&ghost, &lines)),
                        Work::of(&counters_per_ray(&bvh, &lines)),
                    )
                });
                rows.push(Row {
                    scene: scene.name.clone(),
                    builder,
                    layout,
                    predicted,
                    aronov: predicted.aronov(objects),
                    pierced,
                    closest,
                });
            }
            if time {
                let bvh = Bvh::from_tree(&tree, &tris, &options.clone().layout(timed_layout))?;
                let sets = ray_sets(scene, &bvh, &args);
                let aronov = bvh.predict_within(&root).aronov(objects);
                let sah = tree.sah_cost(&quiver_rt::builders::BuildConfig::default());
                // The ray kinds side by side, round after round, so a slow spell on the
                // shared machine hits all of them alike.
                let times = time_pool.install(|| {
                    measure::median_times_interleaved(args.reps, sets.len(), |i| {
                        let (_, query, rays) = &sets[i];
                        std::hint::black_box(measure::trace(&bvh, rays, *query));
                    })
                });
                for ((kind, query, rays), t) in sets.iter().zip(times) {
                    let c = count_pool.install(|| measure::count(&bvh, rays, *query));
                    let n = rays.len().max(1) as f64;
                    timings.push(Timing {
                        scene: scene.name.clone(),
                        builder,
                        rays: kind,
                        aronov,
                        sah,
                        work: (c.nodes + c.prim_tests) as f64 / n,
                        ns_per_ray: t.as_secs_f64() * 1e9 / n,
                    });
                }
            }
        }
    }
    print_rows(&rows);
    let correlations = correlations(&timings);
    if time {
        print_timings(&timings, &correlations, timed_layout, args.threads);
    }
    if let Some(path) = &args.plot {
        write_text(path, &plot(&timings, timed_layout))?;
    }
    let report = json!({
        "rows": rows.iter().map(row_json).collect::<Vec<_>>(),
        "timed_layout": timed_layout.name(),
        "threads": args.threads,
        "timings": timings.iter().map(|t| json!({
            "scene": t.scene, "builder": t.builder.name(), "rays": t.rays,
            "aronov": t.aronov, "sah_cost": t.sah, "work_per_ray": t.work,
            "ns_per_ray": t.ns_per_ray,
        })).collect::<Vec<_>>(),
        "correlations": correlations,
    });
    write_json(args.json.as_ref(), &report)
}

/// The asked items without repeats, or all of them.
fn distinct<T: Copy + PartialEq>(asked: &[T], all: &[T]) -> Vec<T> {
    let mut v: Vec<T> = Vec::new();
    for &x in asked {
        if !v.contains(&x) {
            v.push(x);
        }
    }
    if v.is_empty() {
        v = all.to_vec();
    }
    v
}

/// Random rays (closest hit), eye rays (closest hit) and shadow rays from the eye hits to the
/// first light (any hit; none when the scene has no light).
fn ray_sets(
    scene: &quiver_scenes::Scene,
    bvh: &Bvh,
    args: &PredictArgs,
) -> Vec<(&'static str, Query, Vec<Ray>)> {
    let eye = rays::camera_rays(&scene.camera, args.res);
    let lights: Vec<_> = scene.lights.iter().take(1).map(|l| l.pos).collect();
    let shadow = rays::shadow_rays(bvh, &eye, &lights);
    let mut sets = vec![
        (
            "random",
            Query::Closest,
            rays::random_rays(&scene.bounds(), args.rays, 5),
        ),
        ("eye", Query::Closest, eye),
    ];
    if !shadow.is_empty() {
        sets.push(("shadow", Query::Any, shadow));
    }
    sets
}

fn row_json(r: &Row) -> Value {
    let w = |w: &Work| {
        json!({
            "nodes": w.nodes.mean, "nodes_se": w.nodes.std_error,
            "leaves": w.leaves.mean, "leaves_se": w.leaves.std_error,
            "box_tests": w.box_tests.mean, "box_tests_se": w.box_tests.std_error,
            "prim_tests": w.prim_tests.mean, "prim_tests_se": w.prim_tests.std_error,
        })
    };
    let p = &r.predicted;
    json!({
        "scene": r.scene, "builder": r.builder.name(), "layout": r.layout.name(),
        "predicted": {
            "nodes": p.nodes, "inner": p.inner, "leaves": p.leaves,
            "box_tests": p.box_tests, "prim_tests": p.prim_tests,
        },
        "aronov": r.aronov,
        "measured_lines": w(&r.pierced),
        "measured_closest_hit": w(&r.closest),
    })
}

fn print_rows(rows: &[Row]) {
    outln!(
        "per isotropic line through the root box: predicted (Σ SA / SA(root)) | measured, walk that \
         never stops (± 1 s.e.) | closest-hit rays on the same lines"
    );
    outln!(
        "{:<10} {:<7} {:<16} {:>22} {:>22} {:>22} {:>7} {:>7}",
        "scene",
        "builder",
        "layout",
        "nodes",
        "leaves",
        "prim tests",
        "E(T)",
        "C_R"
    );
    let cell = |p: f64, m: &quiver_lab::lines::Sample, c: f64| {
        format!("{p:.2}|{:.2}±{:.2}|{c:.2}", m.mean, m.std_error)
    };
    for r in rows {
        let (p, m, c) = (&r.predicted, &r.pierced, &r.closest);
        outln!(
            "{:<10} {:<7} {:<16} {:>22} {:>22} {:>22} {:>7.2} {:>7.2}",
            r.scene,
            r.builder.name(),
            r.layout.name(),
            cell(p.nodes, &m.nodes, c.nodes.mean),
            cell(p.leaves, &m.leaves, c.leaves.mean),
            cell(p.prim_tests, &m.prim_tests, c.prim_tests.mean),
            r.aronov,
            c.nodes.mean + c.prim_tests.mean,
        );
    }
    outln!(
        "(E(T): Aronov et al.'s predictor, cells = all nodes; C_R: nodes + primitive tests per \
         closest-hit line, measured)"
    );
}

/// Pearson's r and Spearman's ρ between predicted cost (Aronov's E) and time per ray, and
/// between measured work and time per ray, for each ray kind and for all together.
fn correlations(t: &[Timing]) -> Vec<Value> {
    let mut out = Vec::new();
    for kind in ["random", "eye", "shadow", "all"] {
        let set: Vec<&Timing> = t
            .iter()
            .filter(|x| kind == "all" || x.rays == kind)
            .collect();
        if set.len() < 3 {
            continue;
        }
        let time: Vec<f64> = set.iter().map(|x| x.ns_per_ray).collect();
        let pred: Vec<f64> = set.iter().map(|x| x.aronov).collect();
        let sah: Vec<f64> = set.iter().map(|x| x.sah).collect();
        let work: Vec<f64> = set.iter().map(|x| x.work).collect();
        out.push(json!({
            "rays": kind, "points": set.len(),
            "pearson_predicted_time": pearson(&pred, &time),
            "spearman_predicted_time": pearson(&ranks(&pred), &ranks(&time)),
            "pearson_sah_time": pearson(&sah, &time),
            "pearson_work_time": pearson(&work, &time),
            "pearson_predicted_work": pearson(&pred, &work),
        }));
    }
    out
}

/// Pearson's correlation coefficient; NaN when either side is constant.
fn pearson(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len() as f64;
    let (ma, mb) = (a.iter().sum::<f64>() / n, b.iter().sum::<f64>() / n);
    let cov: f64 = a.iter().zip(b).map(|(x, y)| (x - ma) * (y - mb)).sum();
    let va: f64 = a.iter().map(|x| (x - ma) * (x - ma)).sum();
    let vb: f64 = b.iter().map(|y| (y - mb) * (y - mb)).sum();
    cov / (va * vb).sqrt()
}

/// Ranks from 0, ties given their mean rank.
fn ranks(v: &[f64]) -> Vec<f64> {
    let mut idx: Vec<usize> = (0..v.len()).collect();
    idx.sort_by(|&i, &j| v[i].total_cmp(&v[j]));
    let mut r = vec![0.0; v.len()];
    let mut i = 0;
    while i < idx.len() {
        let mut j = i;
        while j + 1 < idx.len() && v[idx[j + 1]] == v[idx[i]] {
            j += 1;
        }
        for &k in &idx[i..=j] {
            r[k] = (i + j) as f64 / 2.0;
        }
        i = j + 1;
    }
    r
}

fn print_timings(t: &[Timing], corr: &[Value], layout: Layout, threads: u16) {
    outln!();
    outln!("timed on {layout}, {threads} thread(s), medians:");
    outln!(
        "{:<10} {:<7} {:<7} {:>8} {:>9} {:>11} {:>10}",
        "scene",
        "builder",
        "rays",
        "E(T)",
        "SAH cost",
        "work/ray",
        "ns/ray"
    );
    for x in t {
        outln!(
            "{:<10} {:<7} {:<7} {:>8.2} {:>9.2} {:>11.2} {:>10.1}",
            x.scene,
            x.builder.name(),
            x.rays,
            x.aronov,
            x.sah,
            x.work,
            x.ns_per_ray
        );
    }
    outln!();
    outln!(
        "{:<7} {:>6} {:>14} {:>14} {:>11} {:>11} {:>14}",
        "rays",
        "points",
        "r(E, time)",
        "rho(E, time)",
        "r(SAH, t)",
        "r(work, t)",
        "r(E, work)"
    );
    // A correlation over constant values (one scene and builder, an empty scene) is undefined.
    let f = |v: &Value| match v.as_f64() {
        Some(x) if x.is_finite() => format!("{x:.3}"),
        _ => "-".to_string(),
    };
    for c in corr {
        out!("{:<7} {:>6}", c["rays"].as_str().unwrap_or(""), c["points"]);
        outln!(
            " {:>14} {:>14} {:>11} {:>11} {:>14}",
            f(&c["pearson_predicted_time"]),
            f(&c["spearman_predicted_time"]),
            f(&c["pearson_sah_time"]),
            f(&c["pearson_work_time"]),
            f(&c["pearson_predicted_work"]),
        );
    }
    outln!("(work: nodes + primitive tests per ray, measured with counters)");
}

/// Time per ray against Aronov's E, one point per scene, builder and ray kind.
fn plot(t: &[Timing], layout: Layout) -> String {
    let points: Vec<Point> = t
        .iter()
        .map(|x| Point {
            x: x.aronov,
            y: x.ns_per_ray,
            label: if x.builder == Builder::Binned && x.rays == "random" {
                x.scene.clone()
            } else {
                String::new()
            },
            color: match x.rays {
                "random" => "#d62728",
                "eye" => "#1f77b4",
                _ => "#2ca02c",
            },
        })
        .collect();
    scatter_svg(
        &format!("Predicted cost E(T) against time per ray ({layout})"),
        "Aronov et al.'s E(T) for the layout (predicted before tracing)",
        "ns per ray (log)",
        &points,
        Axes {
            x_log: false,
            legend: &[
                ("random", "#d62728"),
                ("eye", "#1f77b4"),
                ("shadow", "#2ca02c"),
            ],
        },
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pearson_and_ranks() {
        assert!((pearson(&[1.0, 2.0, 3.0], &[2.0, 4.0, 6.0]) - 1.0).abs() < 1e-12);
        assert!((pearson(&[1.0, 2.0, 3.0], &[3.0, 2.0, 1.0]) + 1.0).abs() < 1e-12);
        assert_eq!(ranks(&[3.0, 1.0, 1.0, 7.0]), [2.0, 0.5, 0.5, 3.0]);
    }
}
