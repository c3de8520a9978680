//! One module per command; the helpers they share (thread pools, argument parsers, scene
//! loading) are here.

pub(crate) mod accuracy;
pub(crate) mod bench;
pub(crate) mod build;
pub(crate) mod builders;
pub(crate) mod costs;
pub(crate) mod gen;
pub(crate) mod layouts;
pub(crate) mod packets;
pub(crate) mod predict;
pub(crate) mod render;

use quiver::builders::{BuildTree, Builder};
use quiver::{BuildOptions, Layout};
use quiver_scenes::accel::SceneBvh;
use quiver_scenes::scene::{tessellate, LoadOptions, NonFinite, Scene, GENERATORS};
use std::sync::OnceLock;
use std::time::Instant;

/// How this run reads scene files (`--drop-non-finite`), set once by `main`.
static LOAD: OnceLock<LoadOptions> = OnceLock::new();

/// Makes every scene this run loads drop primitives and lights with non-finite numbers (and
/// say so on stderr) instead of refusing the file.
pub(crate) fn drop_non_finite() {
    let _ = LOAD.set(LoadOptions::default().non_finite(NonFinite::Drop));
}

/// Loads a scene by name or path with the run's options; what `--drop-non-finite` dropped is
/// reported on stderr as a warning.
pub(crate) fn load_scene(name: &str) -> Result<Scene> {
    let options = LOAD.get().copied().unwrap_or_default();
    let (scene, report) = Scene::load_with(name, &options)?;
    if !report.is_empty() {
        use std::io::Write as _;
        // A failed stderr has nowhere to be reported; the run goes on.
        let _ = writeln!(std::io::stderr(), "warning: {name}: {report}");
    }
    Ok(scene)
}

/// A command's outcome; the error is printed as `error: ...` with exit code 2.
pub(crate) type Result<T> = std::result::Result<T, Box<dyn std::error::Error>>;

/// Most worker threads `--threads` accepts: far above any machine this runs on, low enough
/// that a typo does not try to spawn millions of threads.
const MAX_THREADS: i64 = 1024;

/// Most rays `--rays` accepts (about 5 GB of rays): more is a typo, not a measurement.
pub(crate) const MAX_RAYS: u64 = 100_000_000;

/// Most timed rounds `--reps` accepts.
pub(crate) const MAX_REPS: u64 = 1000;

/// `--threads N`: a worker count from 1 to [`MAX_THREADS`] (0 would silently mean rayon's
/// default, and the report would claim 0 threads).
pub(crate) fn thread_count() -> clap::builder::RangedI64ValueParser<u16> {
    clap::value_parser!(u16).range(1..=MAX_THREADS)
}

/// A count flag (`--rays`, `--reps`, `--res`, ...): a whole number from 1 to `max`; clap's
/// error names the flag, the value and the range. Numeric flags also set
/// `allow_negative_numbers`, so `--rays -5` reaches that check instead of clap reading `-5` as
/// an unknown option and naming no flag.
pub(crate) fn count(max: u64) -> clap::builder::RangedU64ValueParser<usize> {
    clap::builder::RangedU64ValueParser::new().range(1..=max)
}

/// A thread pool of `threads` workers (all cores when `None`).
pub(crate) fn pool(threads: Option<usize>) -> Result<rayon::ThreadPool> {
    let mut b = rayon::ThreadPoolBuilder::new();
    if let Some(n) = threads {
        // rayon reads 0 as "its default", which would make every report lie about the count;
        // the flags' parsers already refuse 0, this keeps a future caller honest.
        if n == 0 {
            return Err("--threads must be at least 1, got 0".into());
        }
        b = b.num_threads(n);
    }
    Ok(b.build()?)
}

/// The thread counts a measuring command runs at: the ones asked for, in order, without
/// repeats (a repeat would measure the same thing twice and print it twice), or 1 and all
/// cores (at least 2, so there are always two columns to compare).
pub(crate) fn measured_threads(asked: &[u16]) -> Vec<usize> {
    let mut counts: Vec<usize> = Vec::new();
    if asked.is_empty() {
        counts.extend([1, rayon::current_num_threads().max(2)]);
    }
    for &n in asked {
        if !counts.contains(&(n as usize)) {
            counts.push(n as usize);
        }
    }
    counts
}

/// `--layout` by name.
pub(crate) fn parse_layout(s: &str) -> std::result::Result<Layout, String> {
    s.parse()
}

/// `--builder` by name.
pub(crate) fn parse_builder(s: &str) -> std::result::Result<Builder, String> {
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
         or a path to an .nff, .obj, .ply, .ply.gz, .gltf or .glb file. Generators:\n",
    );
    for g in GENERATORS {
        s += &format!("  {:<8} {} (default {})\n", g.name, g.about, g.default_size);
    }
    s
}

fn finite_cost(flag: &str, v: f32) -> Result<f32> {
    if v.is_finite() && v >= 0.0 {
        Ok(v)
    } else {
        Err(format!("{flag} must be a finite number >= 0, got {v}").into())
    }
}

/// Loads a scene (in patch mode if asked) and builds its BVH on `pool`: curve mode keeps
/// analytic shapes on the mixed path, patch mode puts everything on the triangle path.
/// Returns the build time in ms beside the results.
fn load_and_build(
    name: &str,
    patches: bool,
    options: &BuildOptions,
) -> Result<(Scene, SceneBvh, BuildTree, f64)> {
    let (scene, bvh, tree, ms) = load_and_build_as(name, patches, false, options)?;
    Ok((scene, bvh, tree.expect("a flattened build has a tree"), ms))
}

/// [`load_and_build`], or with `instanced` the scene in patch mode with its spheres and cones
/// as instances of unit shapes: then the scene stays in curve mode (its objects name the
/// materials) and there is no one build tree.
fn load_and_build_as(
    name: &str,
    patches: bool,
    instanced: bool,
    options: &BuildOptions,
) -> Result<(Scene, SceneBvh, Option<BuildTree>, f64)> {
    let mut scene = load_scene(name)?;
    if instanced {
        let start = Instant::now();
        let bvh = SceneBvh::build_instanced(&scene, tessellate::DEFAULT_RESOLUTION, options)?;
        return Ok((scene, bvh, None, start.elapsed().as_secs_f64() * 1e3));
    }
    if patches {
        scene = scene.into_patches(tessellate::DEFAULT_RESOLUTION);
    }
    let start = Instant::now();
    let (bvh, tree) = if patches {
        SceneBvh::build_triangles_with_tree(&scene, options)
    } else {
        SceneBvh::build_with_tree(&scene, options)
    };
    Ok((scene, bvh, Some(tree), start.elapsed().as_secs_f64() * 1e3))
}
