//! `quiver build`: one layout's size, tree shape, SAH cost and build time, and for triangle
//! scenes the time to refit it to the triangles slightly moved (as by an animation).

use super::{
    finite_cost, layout_help, load_and_build, parse_builder, parse_layout, pool, scene_help,
    thread_count, Result,
};
use crate::output::{check_outputs, print_table, write_file, write_json};
use quiver_rt::builders::{BuildConfig, Builder, CostModel};
use quiver_rt::{BuildOptions, Bvh, Layout};
use serde_json::json;
use std::path::PathBuf;

#[derive(clap::Args)]
pub(crate) struct BuildArgs {
    /// A generator name with optional size (see `--help`), or an .nff/.obj/.ply/.ply.gz/.gltf/.glb file.
    #[arg(long_help = scene_help())]
    scene: String,
    /// Which builder: binned (default), sweep, binned+opt, sweep+opt, ploc10, ploc25, ploc100,
    /// ploc10-emc, aac-fast, aac-hq, aac-hq-emc, bonsai, bonsai-p, bonsai-p4096, insertion
    /// (`quiver builders` compares them).
    #[arg(long, default_value = "binned", value_parser = parse_builder)]
    builder: Builder,
    /// Memory layout of the nodes.
    #[arg(long, default_value = "bvh2-dfs", value_parser = parse_layout, long_help = layout_help())]
    layout: Layout,
    /// Tessellate spheres and cones (the SPD's patch mode).
    #[arg(long)]
    patches: bool,
    /// Worker threads (default: all cores).
    #[arg(allow_negative_numbers = true, long, value_parser = thread_count())]
    threads: Option<u16>,
    /// Bins per axis for the binned builder.
    #[arg(allow_negative_numbers = true, long, default_value_t = 16, value_parser = clap::value_parser!(u16).range(2..=1024))]
    bins: u16,
    /// Largest leaf the build may make.
    #[arg(allow_negative_numbers = true, long, default_value_t = 8, value_parser = clap::value_parser!(u16).range(1..=255))]
    max_leaf: u16,
    /// How splits are scored: sah, rtsah (ray termination SAH) or srdh (shadow ray
    /// distribution heuristic), both after Moulin and Dutré.
    #[arg(long, default_value = "sah", value_parser = |s: &str| s.parse::<CostModel>())]
    cost_model: CostModel,
    /// SAH cost of an inner-node visit (c_T).
    #[arg(allow_negative_numbers = true, long, default_value_t = 1.0)]
    traversal_cost: f32,
    /// SAH cost of one primitive test (c_I).
    #[arg(allow_negative_numbers = true, long, default_value_t = 1.0)]
    intersection_cost: f32,
    /// Write the report as JSON to this file.
    #[arg(long)]
    json: Option<PathBuf>,
    /// Save the built BVH to this file in quiver's format (docs/file-format.md), all or
    /// nothing; `Bvh::load` reads it back. Triangle scenes only (add --patches for the SPD's
    /// analytic shapes).
    #[arg(long)]
    save: Option<PathBuf>,
}

/// Runs `quiver build`.
pub(crate) fn run(args: BuildArgs) -> Result<()> {
    check_outputs(
        &[
            ("--json", args.json.as_deref()),
            ("--save", args.save.as_deref()),
        ],
        &[&args.scene],
    )?;
    let config = BuildConfig {
        bins: args.bins as usize,
        max_leaf_size: args.max_leaf as usize,
        traversal_cost: finite_cost("--traversal-cost", args.traversal_cost)?,
        intersection_cost: finite_cost("--intersection-cost", args.intersection_cost)?,
        cost_model: args.cost_model,
        ..BuildConfig::default()
    };
    let builder = args.builder;
    let pool = pool(args.threads.map(usize::from))?;
    let options = BuildOptions {
        builder,
        layout: args.layout,
        config: config.clone(),
        pool: Some(&pool),
        isa: None,
    };
    let what = format!(
        "build {}{}",
        args.scene,
        if args.patches { " --patches" } else { "" }
    );
    let (scene, bvh, tree, build_ms) =
        load_and_build(&args.scene, args.patches, &options, |censuses, _| {
            super::build_estimate(&what, censuses, args.patches)
        })?;
    let footprint = bvh.footprint();
    let stats = tree.stats();
    let (primitives, triangles) = (bvh.primitives(), bvh.is_triangles());
    let prims = primitives.max(1) as f64;
    drop(bvh);
    if args.save.is_some() && !triangles {
        return Err(format!(
            "--save: {} holds analytic shapes; only triangle BVHs are saved (add --patches)",
            args.scene
        )
        .into());
    }
    // The same tree laid out again over the scene's triangles (the same arrays the build
    // made: what --save writes) and refit to them moved by a thousandth of the scene's size
    // (median of three), for triangle scenes.
    let mut saved = None;
    let refit_ms = if triangles {
        Some(pool.install(|| -> std::result::Result<f64, String> {
            let tris = scene.triangles();
            let moved = super::nudged(&tris);
            let mut laid = Bvh::from_tree(&tree, &tris, &options).map_err(|e| e.to_string())?;
            if let Some(path) = &args.save {
                let start = std::time::Instant::now();
                let mut bytes = 0u64;
                write_file(path, |w| {
                    let mut counted = Counted { w, bytes: 0 };
                    laid.save(&mut counted)?;
                    bytes = counted.bytes;
                    Ok(())
                })
                .map_err(|e| e.to_string())?;
                saved = Some((start.elapsed().as_secs_f64() * 1e3, bytes));
            }
            super::refit_ms(&mut laid, &tris, &moved, 3).map_err(|e| e.to_string())
        })?)
    } else {
        None
    };
    let report = json!({
        "scene": scene.name,
        "objects": scene.objects.len(),
        "primitives": primitives,
        "primitive_kind": if triangles { "triangles" } else { "mixed" },
        "dropped": tree.dropped,
        "builder": builder.name(),
        "cost_model": args.cost_model.name(),
        "layout": args.layout.name(),
        "threads": pool.current_num_threads(),
        "nodes": footprint.nodes,
        "tree_nodes": stats.nodes,
        "leaves": stats.leaves,
        "depth": stats.depth,
        "sah_cost": tree.sah_cost(&config),
        "build_ms": build_ms,
        "refit_ms": refit_ms,
        "bytes": footprint.bytes,
        "node_bytes": footprint.node_bytes,
        "node_bytes_per_prim": footprint.node_bytes as f64 / prims,
        "bytes_per_prim": footprint.bytes as f64 / prims,
        "kept_bytes": footprint.kept,
        "kept_bytes_per_prim": footprint.kept as f64 / prims,
        "save_ms": saved.map(|s| s.0),
        "file_bytes": saved.map(|s| s.1),
    });
    print_table(&report);
    write_json(args.json.as_ref(), &report)
}

/// A writer that counts the bytes passing through it (the saved file's size, for the report).
struct Counted<'w, W> {
    w: &'w mut W,
    bytes: u64,
}

impl<W: std::io::Write> std::io::Write for Counted<'_, W> {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        let n = self.w.write(buf)?;
        self.bytes += n as u64;
        Ok(n)
    }

    fn flush(&mut self) -> std::io::Result<()> {
        self.w.flush()
    }
}
