//! Times the phases of a BVH2 build (primitive bounds, SAH build, layout) on tetra10 at 1 and
//! 2 threads; prints the fastest of five runs of each. `cargo run --release --example phase`
use quiver_rt::builders::{build, prim_bounds, BuildConfig, Builder};
use quiver_rt::{Bvh2, Bvh2Mapping};
use quiver_scenes::Scene;
use std::time::{Duration, Instant};

fn main() {
    let name = std::env::args().nth(1).unwrap_or_else(|| "tetra10".into());
    let scene = Scene::load(&name).expect("scene");
    let tris = scene.triangles();
    for threads in [1, 2] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("pool");
        let mut best = [Duration::MAX; 3];
        pool.install(|| {
            for _ in 0..5 {
                let t0 = Instant::now();
                let bounds = prim_bounds(&tris);
                let t1 = Instant::now();
                let tree = build(&bounds, &BuildConfig::default(), Builder::Binned);
                let t2 = Instant::now();
                let bvh = Bvh2::from_tree(&tree, &tris, Bvh2Mapping::DepthFirst)
                    .expect("a built tree fits its primitives");
                let t3 = Instant::now();
                std::hint::black_box(bvh);
                for (b, d) in best.iter_mut().zip([t1 - t0, t2 - t1, t3 - t2]) {
                    *b = (*b).min(d);
                }
            }
        });
        let total: Duration = best.iter().sum();
        let mtris = tris.len() as f64 / total.as_secs_f64() / 1e6;
        println!(
            "{name} threads {threads}: bounds {:?} build {:?} layout {:?} total {total:?} ({mtris:.2} M tris/s)",
            best[0], best[1], best[2]
        );
    }
}
