//! Build benchmarks: quiver's binned SAH on a million triangles at 1 and 2 threads, the
//! full-sweep reference on a smaller input, and obvhs 0.4 (`build_bvh2_from_tris`, medium
//! preset) on the same triangles. Each tree's SAH cost is printed beside the timings.
//!
//! `cargo bench --bench build` (all) or `cargo bench --bench build -- tetra8` (one input).

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use obvhs::{bvh2::builder::build_bvh2_from_tris, BvhBuildParams};
use quiver_rt::builders::{BuildConfig, Builder};
use quiver_rt::{BuildOptions, Layout};
use quiver_lab::obvhs_bridge::{sah_cost as obvhs_sah, triangles as obvhs_tris};
use quiver_scenes::Scene;
use std::time::Duration;

fn pool(threads: usize) -> rayon::ThreadPool {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .expect("thread pool")
}

fn bench_builds(c: &mut Criterion) {
    let config = BuildConfig::default();
    let mut group = c.benchmark_group("build");
    group
        .sample_size(10)
        .measurement_time(Duration::from_secs(8));
    // (scene, quiver builders to run)
    let inputs: [(&str, &[Builder]); 2] = [
        ("tetra8", &[Builder::Binned, Builder::Sweep]),
        ("tetra10", &[Builder::Binned]),
    ];
    for (name, builders) in inputs {
        let scene = Scene::load(name).expect("built-in scene");
        let tris = &scene.triangles();
        let otris = obvhs_tris(tris);
        for threads in [1, 2] {
            let pool = pool(threads);
            for &builder in builders {
                let options = BuildOptions::default()
                    .builder(builder)
                    .layout(Layout::Bvh2Dfs)
                    .thread_pool(&pool);
                let sah = options.build_with_tree(tris).1.sah_cost(&config);
                println!(
                    "{name} ({} tris) quiver {builder} threads {threads}: SAH cost {sah:.3}",
                    tris.len()
                );
                let id = BenchmarkId::new(format!("quiver-{builder}/{threads}t"), name);
                group.bench_function(id, |b| b.iter(|| options.build_with_tree(tris)));
            }
            let medium = BvhBuildParams::medium_build();
            let sah = pool.install(|| {
                obvhs_sah(&build_bvh2_from_tris(
                    &otris,
                    medium,
                    &mut Duration::default(),
                ))
            });
            println!(
                "{name} ({} tris) obvhs medium threads {threads}: SAH cost {sah:.3}",
                tris.len()
            );
            let id = BenchmarkId::new(format!("obvhs-medium/{threads}t"), name);
            group.bench_function(id, |b| {
                b.iter(|| {
                    pool.install(|| build_bvh2_from_tris(&otris, medium, &mut Duration::default()))
                })
            });
        }
    }
    group.finish();
}

criterion_group!(benches, bench_builds);
criterion_main!(benches);
