//! Render probe: `cargo run --release --example rp -- SCENE RES REPS [LAYOUT]` renders the
//! scene (curve mode) with packets off and on, alternating, one thread, and prints the
//! fastest and median trace time of each and their ratio. A fifth argument `off` or `on`
//! renders in that mode only (for profiling one side).
use quiver_rt::{BuildOptions, Layout};
use quiver_scenes::accel::SceneBvh;
use quiver_scenes::render::{render, RenderConfig};
use quiver_scenes::Scene;
use std::time::Instant;

fn main() {
    let a: Vec<String> = std::env::args().collect();
    let name = a.get(1).map_or("tetra8", |s| s.as_str());
    let res: u32 = a.get(2).map_or(1024, |s| s.parse().expect("res"));
    let reps: usize = a.get(3).map_or(5, |s| s.parse().expect("reps"));
    let layout: Layout = a
        .get(4)
        .map_or("bvh8-dfs", |s| s.as_str())
        .parse()
        .expect("layout");
    let only = a.get(5).map(|s| s == "on");
    let scene = Scene::load(name).expect("scene");
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    pool.install(|| {
        let bvh = SceneBvh::build(&scene, &BuildOptions::default().layout(layout));
        let mut times = [vec![], vec![]];
        let mut total = 0;
        for _ in 0..reps {
            for (k, packets) in [false, true].into_iter().enumerate() {
                if only.is_some_and(|o| o != packets) {
                    continue;
                }
                let config = RenderConfig {
                    res,
                    two_sided: scene.two_sided_materials(),
                    packets,
                    ..RenderConfig::default()
                };
                let t = Instant::now();
                let r = render(&scene, &bvh, &config, &|_| {});
                times[k].push(t.elapsed().as_secs_f64() * 1e3);
                total = r.rays.total();
            }
        }
        for t in &mut times {
            t.sort_by(f64::total_cmp);
        }
        if let Some(o) = only {
            let t = &times[o as usize];
            println!("{name} {res} {}: {total} rays; min {:.1} med {:.1} ms", layout.name(), t[0], t[reps / 2]);
            return;
        }
        let (off, on) = (&times[0], &times[1]);
        println!(
            "{name} {res} {}: {total} rays; off min {:.1} med {:.1} ms; on min {:.1} med {:.1} ms; ratio min {:.2} med {:.2}",
            layout.name(), off[0], off[reps / 2], on[0], on[reps / 2], off[0] / on[0], off[reps / 2] / on[reps / 2]
        );
    });
}
