//! `quiver packets`: packet traversal against the single-ray kernel of the same BVH, side by side on the
//! same rays: eye rays (8 x 8 pixel tiles of a `--res`² camera, 1024² by default), shadow rays
//! (one per eye hit and light, in tile order), mirror rays (patch mode: every eye hit reflected
//! about its triangle, in tile order), diffuse bounce rays (patch mode: one cosine-distributed
//! direction about each eye hit's triangle normal, in tile order) and incoherent rays, SPD scenes in curve mode (analytic shapes and whole polygons)
//! and in patch mode (the scene's triangles), 1 thread and all threads. Built with the
//! `embree` feature, Intel Embree 3 joins them in patch mode, on the same triangles: one ray
//! at a time and as coherent streams over the same packet-ordered rays. Built with the
//! `tinybvh` feature, tinybvh's `BVH8_CPU` and `BVH4_CPU` join them likewise, one ray at a
//! time (tinybvh's packet query is for its binary layout only). The report names each peer's
//! version, and the instruction set Embree's kernels run on.

use super::{
    count, measured_threads, parse_layout, pool, thread_count, Result, MAX_RAYS, MAX_REPS,
};
use crate::budget::{self, Estimate, MIXED_BUILD};
use crate::output::{check_outputs, out, outln, write_json};
#[cfg(feature = "embree")]
use quiver_lab::embree::EmbreeScene;
use quiver_lab::measure::{median_times_interleaved, mrays_per_s, trace, trace_packets, Query};
use quiver_lab::rays;
#[cfg(feature = "tinybvh")]
use quiver_lab::tinybvh::{TinyBvh, TinyLayout};
use quiver_rt::traverse::PacketMode;
use quiver_rt::{BuildOptions, Bvh, Layout, Primitive, Triangle};
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
    #[arg(allow_negative_numbers = true, long, default_value_t = 1024, value_parser = clap::value_parser!(u32).range(8..=8192))]
    res: u32,
    /// Incoherent rays per scene.
    #[arg(allow_negative_numbers = true, long, default_value_t = 200_000, value_parser = count(MAX_RAYS))]
    rays: usize,
    /// Timed rounds per measurement (median).
    #[arg(allow_negative_numbers = true, long, default_value_t = 5, value_parser = count(MAX_REPS))]
    reps: usize,
    /// Thread counts to measure, comma-separated (default: 1 and all cores).
    #[arg(allow_negative_numbers = true, long, value_delimiter = ',', value_parser = thread_count())]
    threads: Vec<u16>,
    /// Memory layout (a 4- or 8-wide one: binary layouts have no packet kernel).
    #[arg(long, default_value = "bvh8-dfs", value_parser = parse_layout)]
    layout: Layout,
    /// Write all rows as JSON.
    #[arg(long)]
    json: Option<PathBuf>,
    /// Measure SPD scenes traced as worlds of instances beside the same scenes flattened
    /// (and Embree's instanced scenes with the `embree` feature): the same table as
    /// `quiver bench --instanced`, packets included. Default scenes: balls4 and lattice6.
    #[arg(long)]
    instanced: bool,
}

/// The kernels timed side by side.
const KERNELS: [(&str, Option<PacketMode>); 3] = [
    ("single", None),
    ("packet", Some(PacketMode::Auto)),
    ("packet-always", Some(PacketMode::Always)),
];

/// Embree's kernels, after [`KERNELS`]: `rtcIntersect1` / `rtcOccluded1` per ray, and
/// `rtcIntersect1M` / `rtcOccluded1M` with the coherent flag over runs of 64 rays (one tile).
#[cfg(feature = "embree")]
const EMBREE_KERNELS: [&str; 2] = ["embree-1", "embree-stream"];

/// tinybvh's kernels, after Embree's: `Intersect` / `IsOccluded` per ray.
#[cfg(feature = "tinybvh")]
const TINY_KERNELS: [(&str, TinyLayout); 2] = [
    ("tinybvh8-1", TinyLayout::Bvh8Cpu),
    ("tinybvh4-1", TinyLayout::Bvh4Cpu),
];

/// Runs `quiver packets`.
pub(crate) fn run(args: PacketsArgs) -> Result<()> {
    check_outputs(&[("--json", args.json.as_deref())], &args.scenes)?;
    if args.instanced {
        return super::instances::load_and_run(
            "packets",
            &args.scenes,
            args.rays,
            args.reps,
            &args.threads,
            args.json.as_ref(),
        );
    }
    if args.layout.name().starts_with("bvh2") {
        return Err(format!(
            "--layout {}: packets need a 4- or 8-wide layout",
            args.layout
        )
        .into());
    }
    let scenes = if args.scenes.is_empty() {
        ["balls3", "gears3", "teapot12", "tetra9"]
            .map(String::from)
            .to_vec()
    } else {
        args.scenes.clone()
    };
    let loaded = super::load_within(&scenes, |censuses, scenes| {
        let mut e = Estimate::new(format!("packets {}", scenes_text(&args.scenes)));
        // Each scene in curve mode, its copy and its patch-mode conversion.
        e.add(
            "scenes, curve and patch mode",
            super::scenes_bytes(censuses, true) + super::scenes_bytes(censuses, false),
        );
        let tris = super::largest(censuses, super::triangles_of);
        let curve = super::largest(censuses, |c| c.curve_primitives());
        e.add(
            format!("{} triangles at {PER_TRIANGLE} B", budget::count(tris)),
            tris * PER_TRIANGLE,
        );
        e.add(
            format!(
                "{} curve-mode primitives at {} B",
                budget::count(curve),
                MIXED_BUILD
            ),
            curve * MIXED_BUILD,
        );
        e.add(
            format!("{} random rays", budget::count(args.rays as u64)),
            args.rays as u64 * PER_RAY,
        );
        // Shadow rays toward every light from every eye hit (known once loaded).
        let lights = scenes.map_or(0, |s| s.iter().map(|s| s.lights.len()).max().unwrap_or(0));
        let eye = (args.res as u64).pow(2);
        e.add(
            format!(
                "{} eye rays with their shadow, mirror and diffuse rays",
                budget::count(eye)
            ),
            eye * (PER_EYE + PER_RAY * (2 + lights as u64)),
        );
        e
    })?;
    let mut jobs = Vec::new();
    for scene in loaded {
        if !scene.is_all_triangles() {
            jobs.push(("curve", scene.clone()));
        }
        jobs.push(("patch", scene.into_patches(DEFAULT_RESOLUTION)));
    }
    let thread_counts = measured_threads(&args.threads);
    let (peer_lines, peers) = super::peers()?;
    let bar = indicatif::ProgressBar::new(jobs.len() as u64);
    bar.set_style(indicatif::ProgressStyle::with_template(
        "{bar:40} {pos}/{len} {msg} [{elapsed}]",
    )?);
    let mut rows = Vec::new();
    for (mode, scene) in &jobs {
        bar.set_message(format!("{} ({mode})", scene.name));
        // Patch mode is measured on the scene's triangles, the ones Embree gets: quiver's
        // fast leaf tests, not the shading-aware patch primitives the renderer uses.
        if *mode == "patch" || scene.is_all_triangles() {
            let tris = scene.triangles();
            measure(
                &args,
                scene,
                mode,
                &tris,
                Some(&tris),
                &thread_counts,
                &mut rows,
            )?;
        } else {
            measure(
                &args,
                scene,
                mode,
                &scene.prims().0,
                None,
                &thread_counts,
                &mut rows,
            )?;
        }
        bar.inc(1);
    }
    bar.finish_and_clear();
    for line in &peer_lines {
        outln!("{line}");
    }
    outln!("(eye: {0}x{0} camera in 8x8 tiles)", args.res);
    print_rows(&rows);
    write_json(
        args.json.as_ref(),
        &json!({ "eye_res": args.res, "peers": peers, "rows": rows }),
    )
}

/// The scenes named, for messages (the defaults when none were).
fn scenes_text(given: &[String]) -> String {
    if given.is_empty() {
        "balls3 gears3 teapot12 tetra9".into()
    } else {
        given.join(" ")
    }
}

/// Memory per triangle of the largest scene's patch mode beyond the scenes: its BVH, triangle
/// copies and packet buffers (`quiver packets balls4 --res 8 --rays 10`: 708 MB for 1.42
/// million triangles with both modes' scenes; soup100000 and soup300000: 472 B a triangle),
/// rounded up.
const PER_TRIANGLE: u64 = 600;

/// Memory per random ray and its answer (`quiver packets soup1000 --rays 2000000`: 101 MB, 48 B
/// a ray), rounded up; shadow and mirror rays likewise.
const PER_RAY: u64 = 64;

/// The seed of the diffuse bounce rays (`quiver bench`'s too, so both trace the same set).
const DIFFUSE_SEED: u64 = super::bench::DIFFUSE_SEED;

/// Memory per eye ray in tiles with its hit (`quiver packets soup1000 --res 1024`: 109 MB,
/// 100 B an eye ray with its one light's shadow ray), rounded up.
const PER_EYE: u64 = 64;

/// Times every kernel on the scene's ray sets over `prims`. `tris`, given when `prims` are
/// the scene's triangles (patch mode), adds the first-bounce mirror rays off them and
/// Embree, which traces the same triangles.
fn measure<P: Primitive>(
    args: &PacketsArgs,
    scene: &Scene,
    mode: &str,
    prims: &[P],
    tris: Option<&[Triangle]>,
    thread_counts: &[usize],
    rows: &mut Vec<Value>,
) -> Result<()> {
    let bvh = Bvh::build(prims, &BuildOptions::default().layout(args.layout))?;
    let eye = rays::camera_tiles(&scene.camera, args.res as usize, 8);
    let lights: Vec<_> = scene.lights.iter().map(|l| l.pos).collect();
    let shadow = rays::shadow_rays(&bvh, &eye, &lights);
    // `bvh` is over `tris` itself here, so its hits index them.
    let mirror = tris.map_or_else(Vec::new, |t| rays::reflection_rays(&bvh, t, &eye));
    let diffuse = tris.map_or_else(Vec::new, |t| {
        rays::diffuse_rays(&bvh, t, &eye, DIFFUSE_SEED)
    });
    let random = rays::random_rays(&scene.bounds(), args.rays, 11);
    // Embree and tinybvh trace triangles only: in patch mode the same triangles as quiver;
    // curve mode's spheres, cones and whole polygons would need user geometry, so they are
    // left out there.
    // Filled only with a comparison engine built in.
    #[allow(unused_mut)]
    let mut extra: Vec<&str> = Vec::new();
    #[allow(unused_mut)]
    let mut extra_tris = 0;
    #[cfg(feature = "embree")]
    let embree = match tris {
        Some(t) => {
            extra.extend(EMBREE_KERNELS);
            extra_tris = t.len();
            Some(EmbreeScene::new(t)?)
        }
        None => None,
    };
    #[cfg(feature = "tinybvh")]
    let mut tiny: Vec<TinyBvh> = Vec::new();
    #[cfg(feature = "tinybvh")]
    if let Some(t) = tris {
        extra_tris = t.len();
        for (name, layout) in TINY_KERNELS {
            match TinyBvh::new(t, layout) {
                Ok(b) => {
                    extra.push(name);
                    tiny.push(b);
                }
                // A tree tinybvh's walk cannot trace safely: no column for it on this scene.
                Err(e) => {
                    use std::io::Write as _;
                    let _ = writeln!(std::io::stderr(), "warning: {}: {e}", scene.name);
                }
            }
        }
    }
    #[cfg(feature = "embree")]
    let embree_count = if embree.is_some() {
        EMBREE_KERNELS.len()
    } else {
        0
    };
    for &threads in thread_counts {
        let p = pool(Some(threads))?;
        for (kind, set, query) in [
            ("eye", &eye, Query::Closest),
            ("shadow", &shadow, Query::Any),
            ("mirror", &mirror, Query::Closest),
            ("diffuse", &diffuse, Query::Closest),
            ("incoherent", &random, Query::Closest),
        ] {
            if (kind == "mirror" || kind == "diffuse") && tris.is_none() {
                continue;
            }
            let times = p.install(|| {
                median_times_interleaved(args.reps, KERNELS.len() + extra.len(), |i| {
                    #[allow(unused_mut, unused_variables)]
                    let mut j = i.checked_sub(KERNELS.len());
                    #[cfg(feature = "embree")]
                    if let (Some(e), Some(k)) = (&embree, j) {
                        if k < embree_count {
                            std::hint::black_box(e.count_hits(set, query == Query::Any, k == 1));
                            return;
                        }
                        j = Some(k - embree_count);
                    }
                    #[cfg(feature = "tinybvh")]
                    if let Some(t) = j.and_then(|k| tiny.get(k)) {
                        std::hint::black_box(t.count_hits(set, query == Query::Any));
                        return;
                    }
                    let hits = match KERNELS[i].1 {
                        None => trace(&bvh, set, query),
                        Some(m) => trace_packets(&bvh, set, query, m),
                    };
                    std::hint::black_box(hits);
                })
            });
            let single = mrays_per_s(set.len(), times[0]);
            let names = KERNELS.iter().map(|k| k.0).chain(extra.iter().copied());
            for ((i, kernel), t) in names.enumerate().zip(&times) {
                let mrays = mrays_per_s(set.len(), *t);
                let primitives = if i < KERNELS.len() {
                    prims.len()
                } else {
                    extra_tris
                };
                rows.push(json!({
                    "scene": scene.name, "mode": mode, "primitives": primitives,
                    "layout": args.layout.name(), "rays": kind, "count": set.len(),
                    "threads": threads, "kernel": kernel, "mrays_per_s": mrays,
                    "vs_single": mrays / single,
                }));
            }
        }
    }
    Ok(())
}

/// Traces every ray through Embree on the current pool, in tasks of 1024 rays as
/// `measure::trace` and `measure::trace_packets` cut them, so a stream sees the same runs of
/// packet-ordered rays as quiver's packets; returns how many hit.
fn print_rows(rows: &[Value]) {
    out!(
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
    #[cfg(feature = "embree")]
    out!(
        " {:>16} {:>6} {:>14} {:>6}",
        "embree-1 Mrays/s",
        "ratio",
        "stream Mrays/s",
        "ratio"
    );
    #[cfg(feature = "tinybvh")]
    out!(
        " {:>14} {:>6} {:>14} {:>6}",
        "tiny8-1 Mrays/s",
        "ratio",
        "tiny4-1 Mrays/s",
        "ratio"
    );
    outln!();
    // One group per scene, mode, ray set and thread count: the quiver kernels in `KERNELS`
    // order, then Embree's where it ran.
    let key = |r: &Value| {
        [&r["scene"], &r["mode"], &r["rays"], &r["threads"]]
            .map(|v| v.to_string())
            .join("/")
    };
    for group in rows.chunk_by(|a, b| key(a) == key(b)) {
        let r = &group[0];
        let m = |i: usize| {
            group
                .get(i)
                .map_or("-".into(), |r| number(&r["mrays_per_s"], ""))
        };
        let v = |i: usize| {
            group
                .get(i)
                .map_or("-".into(), |r| number(&r["vs_single"], "x"))
        };
        out!(
            "{:<12} {:<6} {:>8} {:<11} {:>3} {:>14} {:>14} {:>6} {:>14} {:>6}",
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
        #[cfg(feature = "embree")]
        for (kernel, width) in [("embree-1", 16), ("embree-stream", 14)] {
            match group.iter().find(|r| r["kernel"] == kernel) {
                Some(r) => out!(
                    " {:>width$} {:>6}",
                    number(&r["mrays_per_s"], ""),
                    number(&r["vs_single"], "x")
                ),
                None => out!(" {:>width$} {:>6}", "-", "-"),
            }
        }
        #[cfg(feature = "tinybvh")]
        for kernel in ["tinybvh8-1", "tinybvh4-1"] {
            match group.iter().find(|r| r["kernel"] == kernel) {
                Some(r) => out!(
                    " {:>14} {:>6}",
                    number(&r["mrays_per_s"], ""),
                    number(&r["vs_single"], "x")
                ),
                None => out!(" {:>14} {:>6}", "-", "-"),
            }
        }
        outln!();
    }
    #[cfg(feature = "tinybvh")]
    outln!("(tiny8-1, tiny4-1: tinybvh's BVH8_CPU and BVH4_CPU, Intersect / IsOccluded per ray, patch mode only; ratios over quiver's single-ray kernel)");
    #[cfg(feature = "embree")]
    outln!("(ratios: over quiver's single-ray kernel; embree-1: rtcIntersect1 / rtcOccluded1 per ray; embree-stream: rtcIntersect1M / rtcOccluded1M, coherent, 64 rays per call; Embree in patch mode only, on the scene's triangles)");
}

/// A measured number to two decimals with `unit`, or `-` where there is none: a ray set can
/// be empty (no shadow rays when no eye ray hits), and its throughput ratio is then 0 / 0,
/// which JSON holds as null.
fn number(v: &Value, unit: &str) -> String {
    match v.as_f64() {
        Some(x) if x.is_finite() => format!("{x:.2}{unit}"),
        _ => "-".into(),
    }
}
