//! Coherent-gap probe (issue 51): where quiver's work per ray goes beside tinybvh's and
//! Embree's, on the same triangles and rays as `quiver bench` (eye rays of a RES² camera row
//! by row, shadow rays toward the first light and diffuse bounce rays from every eye hit).
//!
//! `cargo run --release -p quiver-lab --features tinybvh,embree --example gap -- SCENE [RES]`
//!
//! Environment:
//! - `GAP_MODE`: `count` (default: nodes, leaves, box and triangle tests per ray from quiver's
//!   `Counters`, and tinybvh's when its header was instrumented, see
//!   `quiver_lab::tinybvh::take_counters`), `time` (one thread, interleaved rounds, medians:
//!   ns per ray and Mrays/s of each engine) or `pass` (each engine traces each set once, in a
//!   function of its own, for `valgrind --tool=callgrind --collect-atstart=no
//!   --toggle-collect='gap::pass_*'`: inclusive instructions per ray by function).
//! - `GAP_BUILD`: quiver's trees, comma-separated, each traced as an engine of its own in the
//!   same interleaved rounds: `default` (`Bvh::new`), `sbvh` (`BuildOptions::high_quality`) or
//!   `bins32` (the default with 32 bins). The first one makes the shadow and diffuse rays.
//! - `GAP_KINDS`: comma-separated ray sets (default `eye,shadow,diffuse`).
//! - `GAP_ROWS`: trace every Nth image row only (default 1: all), to keep callgrind runs
//!   short; whole rows keep the rays' coherence.
//! - `GAP_REPS`: timed rounds in `time` mode (default 5).
use quiver_lab::measure::{count, median_times_interleaved, Query};
use quiver_lab::rays;
use quiver_rt::traverse::Counters;
use quiver_rt::{BuildOptions, Bvh, Ray, RayQuery, Triangle};
use quiver_scenes::scene::tessellate::DEFAULT_RESOLUTION;
use quiver_scenes::Scene;

fn env(key: &str, default: &str) -> String {
    std::env::var(key).unwrap_or_else(|_| default.into())
}

/// The engines beside quiver built in.
struct Peers {
    #[cfg(feature = "tinybvh")]
    tiny8: quiver_lab::tinybvh::TinyBvh,
    #[cfg(feature = "embree")]
    embree: quiver_lab::embree::EmbreeScene,
}

impl Peers {
    #[allow(unused_variables)]
    fn new(tris: &[Triangle]) -> Peers {
        Peers {
            #[cfg(feature = "tinybvh")]
            tiny8: quiver_lab::tinybvh::TinyBvh::new(
                tris,
                quiver_lab::tinybvh::TinyLayout::Bvh8Cpu,
            )
            .expect("tinybvh BVH8_CPU"),
            #[cfg(feature = "embree")]
            embree: quiver_lab::embree::EmbreeScene::new(tris).expect("Embree"),
        }
    }

    /// The peers' names, in the order `trace` numbers them from 1.
    fn names() -> Vec<&'static str> {
        let mut v = Vec::new();
        if cfg!(feature = "tinybvh") {
            v.push("tinybvh8");
        }
        if cfg!(feature = "embree") {
            v.push("embree");
        }
        v
    }
}

#[inline(never)]
fn pass_quiver_closest(bvh: &Bvh, set: &[Ray]) -> usize {
    set.iter().filter(|r| bvh.closest_hit(r).is_some()).count()
}

#[inline(never)]
fn pass_quiver_any(bvh: &Bvh, set: &[Ray]) -> usize {
    set.iter().filter(|r| bvh.any_hit(r)).count()
}

#[cfg(feature = "tinybvh")]
#[inline(never)]
fn pass_tiny8_closest(t: &quiver_lab::tinybvh::TinyBvh, set: &[Ray]) -> usize {
    set.iter().filter(|r| t.closest_hit(r).is_some()).count()
}

#[cfg(feature = "tinybvh")]
#[inline(never)]
fn pass_tiny8_any(t: &quiver_lab::tinybvh::TinyBvh, set: &[Ray]) -> usize {
    set.iter().filter(|r| t.any_hit(r)).count()
}

#[cfg(feature = "embree")]
#[inline(never)]
fn pass_embree_closest(e: &quiver_lab::embree::EmbreeScene, set: &[Ray]) -> usize {
    set.iter().filter(|r| e.closest_hit(r).is_some()).count()
}

#[cfg(feature = "embree")]
#[inline(never)]
fn pass_embree_any(e: &quiver_lab::embree::EmbreeScene, set: &[Ray]) -> usize {
    set.iter().filter(|r| e.any_hit(r)).count()
}

/// Traces `set` once with engine `i` (quiver's trees `bvhs`, then [`Peers::names`]), on this
/// thread; returns the hits.
#[allow(unused_variables, unused_mut)]
fn trace(i: usize, bvhs: &[Bvh], peers: &Peers, set: &[Ray], any: bool) -> usize {
    if let Some(bvh) = bvhs.get(i) {
        return if any {
            pass_quiver_any(bvh, set)
        } else {
            pass_quiver_closest(bvh, set)
        };
    }
    let mut k = i - bvhs.len();
    #[cfg(feature = "tinybvh")]
    {
        if k == 0 {
            return if any {
                pass_tiny8_any(&peers.tiny8, set)
            } else {
                pass_tiny8_closest(&peers.tiny8, set)
            };
        }
        k -= 1;
    }
    #[cfg(feature = "embree")]
    if k == 0 {
        return if any {
            pass_embree_any(&peers.embree, set)
        } else {
            pass_embree_closest(&peers.embree, set)
        };
    }
    unreachable!("engine {i}")
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let name = args.get(1).map_or("teapot12", String::as_str);
    let res: usize = args.get(2).map_or(1024, |s| s.parse().expect("RES"));
    let mode = env("GAP_MODE", "count");
    let build = env("GAP_BUILD", "default");
    let every: usize = env("GAP_ROWS", "1").parse().expect("GAP_ROWS");
    let reps: usize = env("GAP_REPS", "5").parse().expect("GAP_REPS");
    let kinds = env("GAP_KINDS", "eye,shadow,diffuse");
    let scene = Scene::load(name)
        .expect("scene")
        .into_patches(DEFAULT_RESOLUTION);
    let tris = scene.triangles();
    let builds: Vec<&str> = build.split(',').collect();
    let bvhs: Vec<Bvh> = builds
        .iter()
        .map(|b| match *b {
            "default" => BuildOptions::default(),
            "sbvh" => BuildOptions::high_quality(),
            "bins32" => BuildOptions::default().bins(32),
            other => panic!("GAP_BUILD: {other}: default, sbvh or bins32"),
        })
        .map(|o| Bvh::build(&tris, &o).expect("GAP_BUILD: a valid build"))
        .collect();
    let bvh = &bvhs[0];
    let peers = Peers::new(&tris);
    // Whole rows, every `every`-th: the rays' order and coherence within a row as in the bench.
    let eye: Vec<Ray> = rays::camera_rays(&scene.camera, res)
        .chunks(res)
        .step_by(every)
        .flatten()
        .copied()
        .collect();
    let light = scene.lights.first().map_or(scene.camera.from, |l| l.pos);
    let sets: Vec<(&str, Vec<Ray>, bool)> = kinds
        .split(',')
        .map(|k| match k {
            "eye" => ("eye", eye.clone(), false),
            "shadow" => ("shadow", rays::shadow_rays(bvh, &eye, &[light]), true),
            "diffuse" => ("diffuse", rays::diffuse_rays(bvh, &tris, &eye, 51), false),
            other => panic!("GAP_KINDS: {other}: eye, shadow or diffuse"),
        })
        .collect();
    let short = name.rsplit('/').next().unwrap_or(name);
    println!(
        "{short}: {} triangles, build {build}, eye {res}² every {every} rows",
        tris.len()
    );
    #[cfg(feature = "tinybvh")]
    println!("tinybvh {}", quiver_lab::tinybvh::version());
    let quiver_names: Vec<String> = builds.iter().map(|b| format!("quiver-{b}")).collect();
    let engines: Vec<&str> = quiver_names
        .iter()
        .map(String::as_str)
        .chain(Peers::names())
        .collect();
    for (kind, set, any) in &sets {
        let n = set.len().max(1) as f64;
        match mode.as_str() {
            "count" => {
                let query = if *any { Query::Any } else { Query::Closest };
                let pool = rayon::ThreadPoolBuilder::new()
                    .num_threads(1)
                    .build()
                    .unwrap();
                for (b, bvh) in builds.iter().zip(&bvhs) {
                    let c: Counters = pool.install(|| count(bvh, set, query));
                    println!(
                    "{short} {kind} quiver-{b}: {} rays, per ray: nodes {:.2} (inner {:.2}), leaves {:.2}, box tests {:.1}, triangle tests {:.2}, leaves that changed nothing {:.2}",
                    set.len(),
                    c.nodes as f64 / n,
                    (c.nodes - c.leaves) as f64 / n,
                    c.leaves as f64 / n,
                    c.box_tests as f64 / n,
                    c.prim_tests as f64 / n,
                    c.empty_leaves as f64 / n
                );
                }
                #[cfg(feature = "tinybvh")]
                {
                    let _ = quiver_lab::tinybvh::take_counters();
                    let hits = trace(bvhs.len(), &bvhs, &peers, set, *any);
                    if let Some([nodes, leaves, tris, pushes]) =
                        quiver_lab::tinybvh::take_counters()
                    {
                        println!(
                            "{short} {kind} tinybvh8: {} rays ({hits} hits), per ray: inner nodes {:.2}, leaves {:.2}, triangle lanes {:.2}, stack pushes {:.2}",
                            set.len(),
                            nodes as f64 / n,
                            leaves as f64 / n,
                            tris as f64 / n,
                            pushes as f64 / n
                        );
                    }
                }
            }
            "time" => {
                let times = median_times_interleaved(reps, engines.len(), |i| {
                    std::hint::black_box(trace(i, &bvhs, &peers, set, *any));
                });
                let line: Vec<String> = engines
                    .iter()
                    .zip(&times)
                    .map(|(e, t)| {
                        let ns = t.as_secs_f64() * 1e9 / n;
                        format!("{e} {ns:.1} ns {:.2} Mrays/s", 1e3 / ns)
                    })
                    .collect();
                println!("{short} {kind} ({} rays): {}", set.len(), line.join(", "));
            }
            "pass" => {
                for (i, e) in engines.iter().enumerate() {
                    let hits = trace(i, &bvhs, &peers, set, *any);
                    println!("{short} {kind} {e}: {} rays, {hits} hits", set.len());
                }
            }
            other => panic!("GAP_MODE: {other}: count, time or pass"),
        }
    }
}
