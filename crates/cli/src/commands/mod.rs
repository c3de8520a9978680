//! One module per command; the helpers they share (thread pools, argument parsers, scene
//! loading) are here.

pub(crate) mod accuracy;
pub(crate) mod bench;
pub(crate) mod build;
pub(crate) mod gen;
pub(crate) mod layouts;
pub(crate) mod packets;
pub(crate) mod render;

use quiver::build::{BuildTree, Builder};
use quiver::{BuildOptions, Layout};
use quiver_scenes::accel::SceneBvh;
use quiver_scenes::scene::{tessellate, Scene, GENERATORS};
use std::time::Instant;

/// A command's outcome; the error is printed as `error: ...` with exit code 2.
pub(crate) type Result<T> = std::result::Result<T, Box<dyn std::error::Error>>;

/// A thread pool of `threads` workers (all cores when `None`).
pub(crate) fn pool(threads: Option<u16>) -> Result<rayon::ThreadPool> {
    let mut b = rayon::ThreadPoolBuilder::new();
    if let Some(n) = threads {
        b = b.num_threads(n as usize);
    }
    Ok(b.build()?)
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
         or a path to a .obj file. Generators:\n",
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
    let mut scene = Scene::load(name)?;
    if patches {
        scene = scene.into_patches(tessellate::DEFAULT_RESOLUTION);
    }
    let start = Instant::now();
    let (bvh, tree) = if patches {
        SceneBvh::build_triangles_with_tree(&scene, options)
    } else {
        SceneBvh::build_with_tree(&scene, options)
    };
    Ok((scene, bvh, tree, start.elapsed().as_secs_f64() * 1e3))
}
