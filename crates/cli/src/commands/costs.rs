//! `quiver costs`: the build cost models (SAH, Moulin and Dutré's RTSAH and SRDH) side by
//! side on eye, shadow and secondary (mirror reflection) rays: SAH cost, traversal work per
//! ray and time per ray.

use super::{count, parse_builder, parse_layout, pool, thread_count, Result, MAX_REPS};
use crate::budget::{self, Estimate};
use crate::output::{check_outputs, outln, write_json};
use quiver_rt::builders::{BuildConfig, Builder, CostModel};
use quiver_rt::{BuildOptions, Bvh, Layout, Ray};
use quiver_lab::measure::{self, Query};
use quiver_lab::rays;
use serde_json::json;
use std::path::PathBuf;
use std::time::Instant;

#[derive(clap::Args)]
pub(crate) struct CostsArgs {
    /// Scenes (generator names with sizes, or .nff/.obj/.ply/.ply.gz/.gltf/.glb files), traced as triangles.
    #[arg(default_values_t = ["teapot12".to_string(), "balls3".to_string(), "gears3".to_string(), "mount5".to_string(), "rings4".to_string(), "tetra6".to_string()])]
    scenes: Vec<String>,
    /// Builders (default: binned and sweep).
    #[arg(long = "builder", value_parser = parse_builder)]
    builders: Vec<Builder>,
    /// Layout the rays are traced through.
    #[arg(long, default_value = "bvh8-dfs", value_parser = parse_layout)]
    layout: Layout,
    /// Eye rays: a RES × RES image; shadow rays go from its hits to the first light, mirror
    /// rays reflect at its hits.
    #[arg(allow_negative_numbers = true, long, default_value_t = 256, value_parser = count(8192))]
    res: usize,
    /// Timed rounds (each times every cost model once; medians reported).
    #[arg(allow_negative_numbers = true, long, default_value_t = 7, value_parser = count(MAX_REPS))]
    reps: usize,
    /// Worker threads for builds and timings.
    #[arg(allow_negative_numbers = true, long, default_value_t = 1, value_parser = thread_count())]
    threads: u16,
    /// Write every row as JSON to this file.
    #[arg(long)]
    json: Option<PathBuf>,
}

/// Memory per triangle of the largest scene beyond the scene: a tree and layout per builder
/// and cost model (`quiver costs soup100000` and `soup300000 --res 8`: 115 and 333 MB, 1092 B a
/// triangle with the scene's 128), rounded up.
const PER_TRIANGLE: u64 = 1200;

/// Memory per eye ray with its shadow and mirror rays and their answers (`quiver costs soup1000
/// --res 1024`: 160 MB, 150 B), rounded up.
const PER_EYE: u64 = 200;

/// Runs `quiver costs`.
pub(crate) fn run(args: CostsArgs) -> Result<()> {
    check_outputs(&[("--json", args.json.as_deref())], &args.scenes)?;
    // The cost models are read by the top-down builders only.
    let builders = if args.builders.is_empty() {
        vec![Builder::Binned, Builder::Sweep]
    } else {
        args.builders.clone()
    };
    let loaded = super::load_within(&args.scenes, |censuses, _| {
        let mut e = Estimate::new(format!("costs {}", args.scenes.join(" ")));
        e.add("scenes", super::scenes_bytes(censuses, false));
        let tris = super::largest(censuses, super::triangles_of);
        e.add(
            format!(
                "{} triangles' trees and layouts at {PER_TRIANGLE} B",
                budget::count(tris)
            ),
            tris * PER_TRIANGLE,
        );
        let eye = (args.res as u64).pow(2);
        e.add(
            format!(
                "{} eye rays with their shadow and mirror rays",
                budget::count(eye)
            ),
            eye * PER_EYE,
        );
        e
    })?;
    let pool = pool(Some(args.threads as usize))?;
    let mut rows = Vec::new();
    outln!(
        "{:<10} {:<7} {:<6} {:>9} {:>8} {:>7} | {:>22} | {:>22} | {:>22}",
        "scene",
        "builder",
        "model",
        "SAH cost",
        "build ms",
        "nodes",
        "eye: nodes/prims/ns",
        "shadow: nodes/prims/ns",
        "mirror: nodes/prims/ns"
    );
    for scene in &loaded {
        let tris = scene.triangles();
        // The rays come from the SAH tree, so every model answers the same rays.
        let base = pool.install(|| BuildOptions::default().layout(args.layout).build(&tris));
        let eye = rays::camera_rays(&scene.camera, args.res);
        let lights: Vec<_> = scene.lights.iter().take(1).map(|l| l.pos).collect();
        let sets: [(&str, Query, Vec<Ray>); 3] = [
            ("eye", Query::Closest, eye.clone()),
            (
                "shadow",
                Query::Any,
                rays::shadow_rays(&base, &eye, &lights),
            ),
            (
                "mirror",
                Query::Closest,
                rays::reflection_rays(&base, &tris, &eye),
            ),
        ];
        for &builder in &builders {
            let mut bvhs: Vec<Bvh> = Vec::new();
            let mut builds = Vec::new();
            for model in CostModel::ALL {
                let options = BuildOptions::default()
                    .builder(builder)
                    .layout(args.layout)
                    .cost_model(model)
                    .thread_pool(&pool);
                let start = Instant::now();
                let (bvh, tree) = options.build_with_tree(&tris);
                let ms = start.elapsed().as_secs_f64() * 1e3;
                builds.push((tree.sah_cost(&BuildConfig::default()), ms, tree.nodes.len()));
                bvhs.push(bvh);
            }
            // Per ray kind: all models side by side, round after round.
            let mut per_kind = Vec::new();
            for (_, query, rays) in &sets {
                let times = pool.install(|| {
                    measure::median_times_interleaved(args.reps, bvhs.len(), |i| {
                        std::hint::black_box(measure::trace(&bvhs[i], rays, *query));
                    })
                });
                let work: Vec<_> = bvhs
                    .iter()
                    .map(|b| pool.install(|| measure::count(b, rays, *query)))
                    .collect();
                per_kind.push((times, work));
            }
            for (m, model) in CostModel::ALL.into_iter().enumerate() {
                let (sah, ms, nodes) = builds[m];
                let mut cells = Vec::new();
                let mut kinds = serde_json::Map::new();
                for ((kind, _, rays), (times, work)) in sets.iter().zip(&per_kind) {
                    let n = rays.len().max(1) as f64;
                    let (nodes_per, prims_per) =
                        (work[m].nodes as f64 / n, work[m].prim_tests as f64 / n);
                    let ns = times[m].as_secs_f64() * 1e9 / n;
                    cells.push(format!("{nodes_per:.2}/{prims_per:.2}/{ns:.1}"));
                    kinds.insert(
                        kind.to_string(),
                        json!({"rays": rays.len(), "nodes_per_ray": nodes_per,
                               "prim_tests_per_ray": prims_per, "ns_per_ray": ns}),
                    );
                }
                outln!(
                    "{:<10} {:<7} {:<6} {:>9.2} {:>8.1} {:>7} | {:>22} | {:>22} | {:>22}",
                    scene.name,
                    builder.name(),
                    model.name(),
                    sah,
                    ms,
                    nodes,
                    cells[0],
                    cells[1],
                    cells[2]
                );
                rows.push(json!({
                    "scene": scene.name, "triangles": tris.len(), "builder": builder.name(),
                    "cost_model": model.name(), "sah_cost": sah, "build_ms": ms,
                    "tree_nodes": nodes, "rays": kinds,
                }));
            }
        }
    }
    outln!(
        "(layout {}, {} thread(s); SAH cost with c_T = c_I = 1 of the binary tree; medians of {} \
         interleaved rounds)",
        args.layout,
        args.threads,
        args.reps
    );
    write_json(args.json.as_ref(), &json!({ "rows": rows }))
}
