//! `quiver builders`: every tree builder on several scenes, measured as Frantál (2019) did:
//! SAH cost, build time (real and user, per thread count), ray time of eye, eye + shadow and
//! random rays through the default kernel, traversal steps and intersection tests per eye ray,
//! references per leaf, and the inner-node and leaf surface-area ratios; a plot of SAH cost
//! against build time.

use super::{
    count, measured_threads, parse_builder, pool, thread_count, Result, MAX_RAYS, MAX_REPS,
};
use crate::budget::{self, Estimate};
use crate::output::{check_outputs, outln, scatter_svg, write_json, write_text, Axes, Point};
use glam::Vec3A;
use quiver_rt::builders::{build, prim_bounds, BuildConfig, BuildTree, Builder};
use quiver_rt::{Aabb, BuildOptions, Bvh, Layout, Ray, Triangle};
use quiver_lab::measure::{self, median_times_interleaved, Query};
use quiver_lab::rays;
use quiver_scenes::scene::tessellate;
use serde_json::{json, Value};
use std::path::PathBuf;
use std::time::{Duration, Instant};

/// The default scenes: generated (so the default runs from anywhere), small enough for a run
/// of about a minute.
const SMALL: [&str; 2] = ["teapot12", "tetra8"];
/// What `--big` adds: 158k to 1M triangles.
const BIG: [&str; 4] = ["balls3", "soup200000", "tetra9", "tetra10"];

#[derive(clap::Args)]
pub(crate) struct BuildersArgs {
    /// Scenes (generator names or .obj/.nff files), measured as triangles (SPD scenes in patch
    /// mode). Default: teapot12 (9.4k triangles) and tetra8 (65k). Name a mesh to add it,
    /// e.g. `quiver builders teapot12 tests/data/bunny.obj tetra8`.
    scenes: Vec<String>,
    /// Also measure balls3 (158k triangles), soup200000, tetra9 (262k) and tetra10 (1M):
    /// minutes, not one.
    #[arg(long)]
    big: bool,
    /// Builders to measure (default: all).
    #[arg(long = "builder", value_parser = parse_builder)]
    builders: Vec<Builder>,
    /// Thread counts for the builds, comma-separated; rays run at the largest.
    #[arg(allow_negative_numbers = true, long, value_delimiter = ',', default_values_t = [1u16, 2], value_parser = thread_count())]
    threads: Vec<u16>,
    /// Timed builds per builder, scene and thread count (the median is reported).
    #[arg(allow_negative_numbers = true, long, default_value_t = 3, value_parser = count(MAX_REPS))]
    build_reps: usize,
    /// Timed rounds of each ray set (each round runs every builder's BVH once).
    #[arg(allow_negative_numbers = true, long, default_value_t = 5, value_parser = count(MAX_REPS))]
    reps: usize,
    /// Eye rays: a RES × RES image.
    #[arg(allow_negative_numbers = true, long, default_value_t = 256, value_parser = count(8192))]
    res: usize,
    /// Random (incoherent) rays.
    #[arg(allow_negative_numbers = true, long, default_value_t = 100_000, value_parser = count(MAX_RAYS))]
    rays: usize,
    /// Write the SAH-cost-against-build-time plot (SVG) to this file.
    #[arg(long)]
    plot: Option<PathBuf>,
    /// Write the rows as JSON to this file.
    #[arg(long)]
    json: Option<PathBuf>,
}

/// One builder on one scene.
struct Row {
    scene: String,
    prims: usize,
    builder: Builder,
    /// (threads, median real ms, median user ms) per thread count.
    builds: Vec<(usize, f64, f64)>,
    /// Whether every thread count built the identical tree.
    same_tree: bool,
    sah: f64,
    refs_per_leaf: f64,
    inner_area: f64,
    leaf_area: f64,
    depth: usize,
    /// Eye, eye + shadow, random: median ms.
    ray_ms: [f64; 3],
    steps_per_ray: f64,
    tests_per_ray: f64,
}

/// Process CPU time (user, all threads) so far.
fn user_time() -> Duration {
    // SAFETY: getrusage writes the struct it is given and nothing else.
    let mut u: libc::rusage = unsafe { std::mem::zeroed() };
    if unsafe { libc::getrusage(libc::RUSAGE_SELF, &mut u) } != 0 {
        return Duration::ZERO;
    }
    Duration::new(u.ru_utime.tv_sec as u64, u.ru_utime.tv_usec as u32 * 1000)
}

/// Median real and user milliseconds of `reps` builds (after one untimed warm-up), and the
/// tree.
fn time_builds(reps: usize, f: impl Fn() -> BuildTree) -> (BuildTree, f64, f64) {
    let tree = f();
    let mut real = Vec::new();
    let mut user = Vec::new();
    for _ in 0..reps {
        let (t, u) = (Instant::now(), user_time());
        std::hint::black_box(f());
        real.push(t.elapsed().as_secs_f64() * 1e3);
        user.push((user_time().saturating_sub(u)).as_secs_f64() * 1e3);
    }
    let median = |mut v: Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    (tree, median(real), median(user))
}

/// Memory per triangle of the largest scene beyond its patch-mode scene, with the fifteen
/// builders there were when it was measured ([`MEASURED_WITH`]; the LBVH came later): their trees, the layouts timed and counted (`quiver builders soup100000` and
/// `soup300000 --res 8 --rays 10 --build-reps 1`: 418 MB and 1.32 GB, 4517 B a triangle with the
/// scene's 128), rounded up; fewer builders take their share.
const PER_TRIANGLE: u64 = 5400;

/// How many builders [`PER_TRIANGLE`] was measured with: each builder run takes this share.
const MEASURED_WITH: u64 = 15;

/// Memory per random or eye ray and its answer (`quiver builders soup1000 --rays 2000000`:
/// 105 MB, 52 B; `--res 1024`: 78 B an eye ray with its shadow ray), rounded up.
const PER_RAY: u64 = 64;

/// Runs `quiver builders`.
pub(crate) fn run(args: BuildersArgs) -> Result<()> {
    check_outputs(
        &[
            ("--plot", args.plot.as_deref()),
            ("--json", args.json.as_deref()),
        ],
        &args.scenes,
    )?;
    let mut names: Vec<String> = args.scenes.clone();
    if names.is_empty() {
        names = SMALL.iter().map(|s| s.to_string()).collect();
    }
    if args.big {
        names.extend(BIG.iter().map(|s| s.to_string()));
    }
    let mut builders: Vec<Builder> = Vec::new();
    for &b in &args.builders {
        if !builders.contains(&b) {
            builders.push(b);
        }
    }
    if builders.is_empty() {
        builders = Builder::ALL.to_vec();
    }
    let threads = measured_threads(&args.threads);
    let ray_threads = *threads.iter().max().unwrap_or(&1);
    let loaded = super::load_within(&names, |censuses, scenes| {
        let mut e = Estimate::new(format!("builders {}", names.join(" ")));
        e.add(
            "scenes and their patch mode",
            super::scenes_bytes(censuses, true),
        );
        let tris = super::largest(censuses, super::triangles_of);
        e.add(
            format!(
                "{} triangles' trees and layouts for {} builders at {PER_TRIANGLE} B",
                budget::count(tris),
                builders.len()
            ),
            tris * PER_TRIANGLE * builders.len() as u64 / MEASURED_WITH,
        );
        e.add(
            format!("{} random rays", budget::count(args.rays as u64)),
            args.rays as u64 * PER_RAY,
        );
        // Shadow rays toward every light (the camera when there is none), known once loaded.
        let lights = scenes.map_or(1, |s| {
            s.iter().map(|s| s.lights.len().max(1)).max().unwrap_or(1)
        });
        let eye = (args.res as u64).pow(2);
        e.add(
            format!("{} eye rays with their shadow rays", budget::count(eye)),
            eye * PER_RAY * (2 + lights as u64),
        );
        e
    })?;
    let loaded: Vec<_> = loaded
        .into_iter()
        .map(|s| s.into_patches(tessellate::DEFAULT_RESOLUTION))
        .collect();
    let pools = threads
        .iter()
        .map(|&t| pool(Some(t)))
        .collect::<Result<Vec<_>>>()?;
    let ray_pool = pool(Some(ray_threads))?;
    let config = BuildConfig::default();
    let bar = indicatif::ProgressBar::new((loaded.len() * builders.len()) as u64);
    bar.set_style(indicatif::ProgressStyle::with_template(
        "{bar:40} {pos}/{len} {msg} [{elapsed}]",
    )?);
    let mut rows = Vec::new();
    for scene in &loaded {
        let tris = scene.triangles();
        let bounds = prim_bounds(&tris);
        let mut scene_rows = Vec::new();
        let mut bvhs = Vec::new();
        let mut counting = Vec::new();
        for &builder in &builders {
            bar.set_message(format!("{}: {builder}", scene.name));
            let mut builds = Vec::new();
            let mut trees = Vec::new();
            for (p, &t) in pools.iter().zip(&threads) {
                let (tree, real, user) =
                    p.install(|| time_builds(args.build_reps, || build(&bounds, &config, builder)));
                builds.push((t, real, user));
                trees.push(tree);
            }
            let same_tree = trees.windows(2).all(|w| w[0] == w[1]);
            let tree = trees.swap_remove(0);
            let stats = tree.stats();
            // Σ A(inner) / A(root) and Σ A(leaf)·n(leaf) / A(root) (Frantál's Tables 18 and
            // 19): the predicted inner nodes and primitive tests per random line.
            let areas = quiver_rt::predict::predict(&tree);
            let (inner_area, leaf_area) = (areas.inner, areas.prim_tests);
            scene_rows.push(Row {
                scene: short_name(&scene.name),
                prims: tris.len(),
                builder,
                builds,
                same_tree,
                sah: tree.sah_cost(&config),
                refs_per_leaf: tree.prim_indices.len() as f64 / stats.leaves.max(1) as f64,
                inner_area,
                leaf_area,
                depth: stats.depth,
                ray_ms: [0.0; 3],
                steps_per_ray: 0.0,
                tests_per_ray: 0.0,
            });
            let options = BuildOptions::default().config(config.clone());
            bvhs.push(Bvh::from_tree(&tree, &tris, &options)?);
            counting.push(Bvh::from_tree(
                &tree,
                &tris,
                &options.layout(Layout::Bvh2Dfs),
            )?);
            bar.inc(1);
        }
        bar.set_message(format!("{}: tracing", scene.name));
        let sets = ray_sets(scene, &tris, &bvhs[0], args.res, args.rays);
        // Every builder's BVH side by side, round after round, per ray set.
        let times: Vec<Vec<Duration>> = sets
            .iter()
            .map(|(rays, query)| {
                ray_pool.install(|| {
                    median_times_interleaved(args.reps, bvhs.len(), |i| {
                        std::hint::black_box(measure::trace(&bvhs[i], rays, *query));
                    })
                })
            })
            .collect();
        for (i, row) in scene_rows.iter_mut().enumerate() {
            let ms = |k: usize| times[k][i].as_secs_f64() * 1e3;
            row.ray_ms = [ms(0), ms(0) + ms(1), ms(2)];
            let c = ray_pool.install(|| measure::count(&counting[i], &sets[0].0, Query::Closest));
            let n = sets[0].0.len() as f64;
            row.steps_per_ray = c.nodes as f64 / n;
            row.tests_per_ray = c.prim_tests as f64 / n;
        }
        rows.extend(scene_rows);
    }
    bar.finish_and_clear();
    print_rows(&rows, &threads, ray_threads, &args);
    if let Some(path) = &args.plot {
        write_text(path, &plot(&rows))?;
    }
    write_json(
        args.json.as_ref(),
        &Value::Array(rows.iter().map(row_json).collect()),
    )
}

/// Eye rays (closest hit), shadow rays from their hits to every light (any hit), random rays
/// (closest hit). Shadow rays start where the first BVH's eye rays hit, so every builder
/// traces the same rays.
fn ray_sets(
    scene: &quiver_scenes::Scene,
    tris: &[Triangle],
    bvh: &Bvh<Triangle>,
    res: usize,
    n_random: usize,
) -> [(Vec<Ray>, Query); 3] {
    let eye = rays::camera_rays(&scene.camera, res);
    let mut lights: Vec<Vec3A> = scene.lights.iter().map(|l| l.pos).collect();
    if lights.is_empty() {
        lights.push(scene.camera.from);
    }
    let shadow = rays::shadow_rays(bvh, &eye, &lights);
    let finite = tris
        .iter()
        .filter(|t| t.is_finite())
        .fold(Aabb::EMPTY, |b, t| b.union(&t.bounds()));
    let random = rays::random_rays(&finite, n_random, 17);
    [
        (eye, Query::Closest),
        (shadow, Query::Any),
        (random, Query::Closest),
    ]
}

/// A scene's name for the table: a file by its name without directories or extension.
fn short_name(name: &str) -> String {
    let path = std::path::Path::new(name);
    match (path.file_stem(), path.extension()) {
        (Some(stem), Some(_)) => stem.to_string_lossy().into_owned(),
        _ => name.to_string(),
    }
}

fn row_json(r: &Row) -> Value {
    json!({
        "scene": r.scene,
        "primitives": r.prims,
        "builder": r.builder.name(),
        "builds": r.builds.iter().map(|(t, real, user)| json!({
            "threads": t, "real_ms": real, "user_ms": user,
        })).collect::<Vec<_>>(),
        "same_tree_for_all_thread_counts": r.same_tree,
        "sah_cost": r.sah,
        "refs_per_leaf": r.refs_per_leaf,
        "inner_area_ratio": r.inner_area,
        "leaf_area_ratio": r.leaf_area,
        "depth": r.depth,
        "eye_ms": r.ray_ms[0],
        "eye_shadow_ms": r.ray_ms[1],
        "random_ms": r.ray_ms[2],
        "steps_per_eye_ray": r.steps_per_ray,
        "tests_per_eye_ray": r.tests_per_ray,
    })
}

fn print_rows(rows: &[Row], threads: &[usize], ray_threads: usize, args: &BuildersArgs) {
    let mut head = format!(
        "{:<12} {:>8} {:<11} {:>7}",
        "scene", "prims", "builder", "SAH"
    );
    for t in threads {
        head += &format!(" {:>9} {:>9}", format!("real{t}ms"), format!("user{t}ms"));
    }
    head += &format!(
        " {:>4} {:>8} {:>8} {:>8} {:>7} {:>7} {:>6} {:>6} {:>6} {:>5}",
        "same", "eye ms", "eye+sh", "rand ms", "steps", "tests", "refs", "innA", "leafA", "depth"
    );
    outln!("{head}");
    for r in rows {
        let mut line = format!(
            "{:<12} {:>8} {:<11} {:>7.2}",
            r.scene,
            r.prims,
            r.builder.name(),
            r.sah
        );
        for (_, real, user) in &r.builds {
            line += &format!(" {real:>9.1} {user:>9.1}");
        }
        line += &format!(
            " {:>4} {:>8.2} {:>8.2} {:>8.2} {:>7.1} {:>7.1} {:>6.2} {:>6.1} {:>6.1} {:>5}",
            if r.same_tree { "yes" } else { "NO" },
            r.ray_ms[0],
            r.ray_ms[1],
            r.ray_ms[2],
            r.steps_per_ray,
            r.tests_per_ray,
            r.refs_per_leaf,
            r.inner_area,
            r.leaf_area,
            r.depth
        );
        outln!("{line}");
    }
    outln!(
        "(SAH with c_T = c_I = 1; build medians of {} runs; rays on {ray_threads} threads through \
         the default layout, medians of {} interleaved rounds: {}² eye rays, shadow rays to every \
         light, {} random rays; steps and tests per eye ray counted in bvh2-dfs; innA = ΣA(inner)/A(root), \
         leafA = ΣA(leaf)·n/A(root); same: one tree for every thread count)",
        args.build_reps,
        args.reps,
        args.res,
        args.rays
    );
}

/// SAH cost against build time (log scales), one point per builder and scene.
fn plot(rows: &[Row]) -> String {
    const COLORS: [&str; 15] = [
        "#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f",
        "#bcbd22", "#17becf", "#393b79", "#637939", "#843c39", "#7b4173", "#000000",
    ];
    let points: Vec<Point> = rows
        .iter()
        .map(|r| {
            let i = Builder::ALL
                .iter()
                .position(|&b| b == r.builder)
                .unwrap_or(0);
            // The build time at the last thread count listed (by default 2).
            let ms = r.builds.last().map_or(0.0, |b| b.1);
            // One label per scene (at its binned point) keeps a hundred points readable; the
            // legend tells the builders apart.
            let label = if r.builder == Builder::Binned {
                r.scene.clone()
            } else {
                String::new()
            };
            Point {
                x: ms,
                y: r.sah,
                label,
                color: COLORS[i % COLORS.len()],
            }
        })
        .collect();
    let legend: Vec<(&str, &str)> = Builder::ALL
        .iter()
        .enumerate()
        .filter(|(_, b)| rows.iter().any(|r| r.builder == **b))
        .map(|(i, b)| (b.name(), COLORS[i % COLORS.len()]))
        .collect();
    scatter_svg(
        "SAH cost against build time, one point per builder and scene",
        "build time, ms (log)",
        "SAH cost, c_T = c_I = 1 (log)",
        &points,
        Axes {
            x_log: true,
            legend: &legend,
        },
    )
}
