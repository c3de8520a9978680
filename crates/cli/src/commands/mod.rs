//! One module per command; the helpers they share (thread pools, argument parsers, scene
//! loading) are here.

pub(crate) mod accuracy;
pub(crate) mod bench;
pub(crate) mod build;
pub(crate) mod builders;
pub(crate) mod costs;
pub(crate) mod gen;
pub(crate) mod instances;
pub(crate) mod layouts;
pub(crate) mod packets;
pub(crate) mod predict;
pub(crate) mod render;

use crate::budget;
use quiver_rt::builders::{BuildTree, Builder};
use quiver_rt::names::ParseError;
use quiver_rt::{BuildOptions, Bvh, Layout, Triangle};
use quiver_scenes::accel::SceneBvh;
use quiver_scenes::instanced;
use quiver_scenes::scene::{
    tessellate, Budgeted, Census, LoadOptions, NonFinite, Scene, SceneError, GENERATORS,
};
use std::sync::OnceLock;
use std::time::Instant;

/// How this run reads scene files (`--drop-non-finite`), set once by `main`.
static LOAD: OnceLock<LoadOptions> = OnceLock::new();

/// Sets how this run reads scene files: `drop` makes every scene drop primitives and lights
/// with non-finite numbers (and say so on stderr) instead of refusing the file; `outside`
/// lets a file name files outside its folder (a glTF buffer URI). Called once by `main`.
pub(crate) fn load_options(drop: bool, outside: bool) {
    let non_finite = if drop {
        NonFinite::Drop
    } else {
        NonFinite::Error
    };
    let _ = LOAD.set(
        LoadOptions::default()
            .non_finite(non_finite)
            .outside_files(outside),
    );
}

/// Loads a scene by name or path with the run's options, reading at most `max_primitives`
/// primitives from a file; what `--drop-non-finite` dropped is reported on stderr as a
/// warning.
fn load_scene(name: &str, max_primitives: u64, max_bytes: u64) -> Result<Scene> {
    let options = LOAD
        .get()
        .copied()
        .unwrap_or_default()
        .max_primitives(max_primitives)
        .max_bytes(max_bytes);
    let (scene, report) = match Scene::load_with(name, &options) {
        Ok(loaded) => loaded,
        Err(SceneError::OverBudget {
            path,
            item,
            needs,
            unit,
            ..
        }) => {
            let l = budget::limit();
            let needs = match unit {
                Budgeted::Primitives => format!("{} primitives", budget::count(needs)),
                Budgeted::Bytes => {
                    format!("about {} [{needs} bytes] to read", budget::human(needs))
                }
            };
            return Err(format!(
                "{}: {item}: needs {needs}, more than this command can hold within the {} \
                 this run may use ({})",
                path.display(),
                budget::human(l.bytes),
                l.source
            )
            .into());
        }
        Err(SceneError::TooLarge { path, line, limit }) => {
            let l = budget::limit();
            return Err(format!(
                "{}: more than {} primitives by line {line}, more than this command can hold \
                 within the {} this run may use ({})",
                path.display(),
                budget::count(limit),
                budget::human(l.bytes),
                l.source
            )
            .into());
        }
        Err(e) => return Err(e.into()),
    };
    if !report.is_empty() {
        use std::io::Write as _;
        // A failed stderr has nowhere to be reported; the run goes on.
        let _ = writeln!(std::io::stderr(), "warning: {name}: {report}");
    }
    Ok(scene)
}

/// Loads the scenes `specs` within the run's memory limit ([`budget`]). `estimate` gives the
/// command's whole estimate from the scenes' censuses, and from the scenes themselves once
/// loaded (their lights and materials); it is checked twice:
///
/// 1. before anything is made, on the generators' censuses (counted without generating) and
///    the files' sizes on disk (they are read whole); what is left of the limit caps the
///    memory each file's reader may hold and the primitives it may make
///    ([`LoadOptions::max_bytes`], [`LoadOptions::max_primitives`]), which every reader checks
///    from the sizes it is about to allocate (inflated data, lists, placements), so an
///    oversized or amplifying file is refused before the allocation that would pass the
///    limit;
/// 2. once loaded, on every scene's census: before patch mode, any build or any ray.
///
/// Returns the scenes as loaded (curve mode).
pub(crate) fn load_within(
    specs: &[String],
    estimate: impl Fn(&[Census], Option<&[Scene]>) -> budget::Estimate,
) -> Result<Vec<Scene>> {
    let mut known = Vec::new();
    let mut file_bytes = 0u64;
    let mut files = false;
    for spec in specs {
        match Census::of_generator(spec)? {
            Some(c) => known.push(c),
            // A file (or a name the loader will refuse): its bytes as read; what parsing
            // takes beyond them its reader checks against what is left.
            None => {
                files = true;
                file_bytes += std::fs::metadata(spec).map_or(0, |m| m.len());
            }
        }
    }
    let mut before = estimate(&known, None);
    before.add("scene files' bytes", file_bytes);
    before.check()?;
    // What a reader may hold: the limit less the rest (its own file's bytes it counts itself).
    let max_bytes = budget::limit()
        .bytes
        .saturating_sub(estimate(&known, None).total());
    let max_primitives = if !files {
        u64::MAX
    } else {
        // The marginal cost of one more triangle-like primitive, from the command's own
        // model, shares out what is left.
        let one = Census {
            triangles: 1,
            ..Census::default()
        };
        let mut with = known.clone();
        with.push(one);
        let per = estimate(&with, None)
            .total()
            .saturating_sub(estimate(&known, None).total())
            .max(1);
        budget::limit().bytes.saturating_sub(before.total()) / per
    };
    let scenes = specs
        .iter()
        .map(|spec| load_scene(spec, max_primitives, max_bytes))
        .collect::<Result<Vec<_>>>()?;
    let censuses: Vec<Census> = scenes.iter().map(Census::of).collect();
    estimate(&censuses, Some(&scenes)).check()?;
    Ok(scenes)
}

/// What holding scenes of `censuses` takes: each as loaded, and with `patches` its patch-mode
/// conversion too (both are alive while it is made).
pub(crate) fn scenes_bytes(censuses: &[Census], patches: bool) -> u64 {
    censuses
        .iter()
        .map(|c| {
            let patched = if patches {
                budget::scene_bytes(&c.in_patch_mode(tessellate::DEFAULT_RESOLUTION))
            } else {
                0
            };
            budget::scene_bytes(c) + patched
        })
        .sum()
}

/// The largest of `f` over `censuses` (0 for none): a command that measures scenes one after
/// another holds one scene's work at a time.
pub(crate) fn largest(censuses: &[Census], f: impl Fn(&Census) -> u64) -> u64 {
    censuses.iter().map(f).max().unwrap_or(0)
}

/// Triangles a command working on `scene.triangles()` gets from a scene of census `c` (spheres
/// and cones tessellated as patch mode does).
pub(crate) fn triangles_of(c: &Census) -> u64 {
    c.patch_triangles(tessellate::DEFAULT_RESOLUTION)
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

/// The comparison engines built in, for the reports: each one's version, and for Embree the
/// instruction set its kernels run on and any `QUIVER_EMBREE_CONFIG`; as one line each to
/// print and as JSON. No lines and an empty object without the `embree` and `tinybvh`
/// features.
pub(crate) fn peers() -> Result<(Vec<String>, serde_json::Value)> {
    #[allow(unused_mut)]
    let mut lines = Vec::new();
    #[allow(unused_mut)]
    let mut json = serde_json::Map::new();
    #[cfg(feature = "embree")]
    {
        let device = quiver_lab::embree::EmbreeDevice::new()?;
        let config = std::env::var("QUIVER_EMBREE_CONFIG").ok();
        lines.push(format!(
            "Embree {} ({} kernels{})",
            device.version(),
            device.isa(),
            config
                .as_deref()
                .map_or(String::new(), |c| format!(", QUIVER_EMBREE_CONFIG={c}"))
        ));
        json.insert(
            "embree".into(),
            serde_json::json!({"version": device.version(), "isa": device.isa(), "config": config}),
        );
    }
    #[cfg(feature = "tinybvh")]
    {
        let version = quiver_lab::tinybvh::version();
        lines.push(format!("tinybvh {version}"));
        json.insert("tinybvh".into(), serde_json::json!({ "version": version }));
    }
    Ok((lines, json.into()))
}

/// `--layout` by name.
pub(crate) fn parse_layout(s: &str) -> std::result::Result<Layout, ParseError> {
    s.parse()
}

/// `--builder` by name.
pub(crate) fn parse_builder(s: &str) -> std::result::Result<Builder, ParseError> {
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

/// `tris` slightly moved, as one frame of an animation moves a mesh: every vertex by a smooth
/// field of a thousandth of the scene's size (a function of the position, so vertices that
/// triangles share stay shared).
pub(crate) fn nudged(tris: &[Triangle]) -> Vec<Triangle> {
    use quiver_rt::glam::Vec3A;
    let b = tris
        .iter()
        .fold(quiver_rt::Aabb::EMPTY, |b, t| b.union(&t.bounds()));
    let size = b.extent().max_element();
    if !(size.is_finite() && size > 0.0) {
        return tris.to_vec();
    }
    // The phase from the position within the box (0 to 1): `TAU * 4 / size` itself would
    // overflow for a scene smaller than about 7e-38, and `p / size` for one far from 0.
    let phase = |p: Vec3A| (p - b.min) / size * (std::f32::consts::TAU * 4.0);
    let f = |p: Vec3A| {
        let a = phase(p);
        p + 1e-3 * size * Vec3A::new(a.y.sin(), a.z.sin(), a.x.sin())
    };
    tris.iter()
        .map(|t| Triangle::new(f(t.v[0]), f(t.v[1]), f(t.v[2])))
        .collect()
}

/// The median of `reps` refits of `bvh` (built over `tris`) in ms, alternately to `moved`
/// and back to `tris` (after one untimed refit), on the current pool; the BVH ends over
/// `tris`.
pub(crate) fn refit_ms(
    bvh: &mut Bvh,
    tris: &[Triangle],
    moved: &[Triangle],
    reps: usize,
) -> std::result::Result<f64, quiver_rt::RefitError> {
    bvh.refit(moved)?;
    let mut times = Vec::with_capacity(reps.max(1));
    for r in 0..reps.max(1) {
        let to = if r % 2 == 0 { tris } else { moved };
        let start = Instant::now();
        bvh.refit(to)?;
        times.push(start.elapsed().as_secs_f64() * 1e3);
    }
    bvh.refit(tris)?;
    times.sort_by(f64::total_cmp);
    Ok(times[times.len() / 2])
}

fn finite_cost(flag: &str, v: f32) -> Result<f32> {
    if v.is_finite() && v >= 0.0 {
        Ok(v)
    } else {
        Err(format!("{flag} must be a finite number >= 0, got {v}").into())
    }
}

/// The memory estimate of loading `censuses` (one scene) in curve or patch mode and building
/// its BVH: the scene (and its patch-mode conversion), and build and layout per primitive.
pub(crate) fn build_estimate(what: &str, censuses: &[Census], patches: bool) -> budget::Estimate {
    let mut e = budget::Estimate::new(what);
    e.add("scene", scenes_bytes(censuses, patches));
    let prims = largest(censuses, |c| {
        if patches {
            triangles_of(c)
        } else {
            c.curve_primitives()
        }
    });
    e.add(
        format!(
            "build and layout of {} primitives at {} B",
            budget::count(prims),
            budget::TRIANGLE_BUILD
        ),
        prims * budget::TRIANGLE_BUILD,
    );
    e
}

/// The memory estimate of loading `censuses` (one scene) in curve mode and building it as
/// a world of instances ([`SceneBvh::build_instanced`]): the scene, each sphere and cone an
/// instance at [`budget::INSTANCE_BUILD`], and the rest flattened into one world-space
/// geometry at [`budget::TRIANGLE_BUILD`] a triangle (the unit shapes are a few thousand
/// triangles).
pub(crate) fn instanced_estimate(what: &str, censuses: &[Census]) -> budget::Estimate {
    let mut e = budget::Estimate::new(what);
    e.add("scene", scenes_bytes(censuses, false));
    let instances = largest(censuses, |c| c.spheres + c.cones);
    e.add(
        format!(
            "{} instances at {} B",
            budget::count(instances),
            budget::INSTANCE_BUILD
        ),
        instances * budget::INSTANCE_BUILD,
    );
    let tris = largest(censuses, |c| c.triangles + c.polygon_triangles());
    e.add(
        format!(
            "{} world-space triangles at {} B",
            budget::count(tris),
            budget::TRIANGLE_BUILD
        ),
        tris * budget::TRIANGLE_BUILD,
    );
    e
}

/// Loads a scene (in patch mode if asked) within the memory limit, `estimate` giving what the
/// whole command takes ([`load_within`]), and builds its BVH on `pool`: curve mode keeps
/// analytic shapes on the mixed path, patch mode puts everything on the triangle path.
/// Returns the build time in ms beside the results.
fn load_and_build(
    name: &str,
    patches: bool,
    options: &BuildOptions,
    estimate: impl Fn(&[Census], Option<&[Scene]>) -> budget::Estimate,
) -> Result<(Scene, SceneBvh, BuildTree, f64)> {
    let (scene, bvh, tree, ms) = load_and_build_as(name, patches, None, options, estimate)?;
    Ok((
        scene,
        bvh,
        tree.ok_or("internal error: a flattened build without a tree")?,
        ms,
    ))
}

/// [`load_and_build`], or with `instanced` the scene in patch mode with its spheres and cones
/// as instances of unit shapes (`Some(true)`: moving, each by [`instanced::scatter`]): then
/// the scene stays in curve mode (its objects name the materials) and there is no one build
/// tree.
fn load_and_build_as(
    name: &str,
    patches: bool,
    instanced: Option<bool>,
    options: &BuildOptions,
    estimate: impl Fn(&[Census], Option<&[Scene]>) -> budget::Estimate,
) -> Result<(Scene, SceneBvh, Option<BuildTree>, f64)> {
    let mut scene = load_within(&[name.to_string()], estimate)?
        .pop()
        .ok_or("internal error: no scene loaded")?;
    if let Some(moving) = instanced {
        let start = Instant::now();
        let res = tessellate::DEFAULT_RESOLUTION;
        let bvh = match moving {
            true => SceneBvh::build_instanced_moving(&scene, res, options, &instanced::scatter)?,
            false => SceneBvh::build_instanced(&scene, res, options)?,
        };
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
    }?;
    Ok((scene, bvh, Some(tree), start.elapsed().as_secs_f64() * 1e3))
}
