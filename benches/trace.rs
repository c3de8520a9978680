//! Traversal throughput per layout: closest-hit and any-hit, incoherent (random) and camera
//! rays, at 1 and 2 threads. Criterion reports rays per second (`thrpt`).
//!
//! `cargo bench --bench trace` runs all; filter like `cargo bench --bench trace -- bvh4-dfs/2t`.
//! Set `QUIVER_BENCH_SCENE` (default `tetra9`, 262,144 triangles) to trace another scene. The
//! `quiver layouts` command measures the same matrix on several scenes in one table.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use quiver_rt::builders::prim_bounds;
use quiver_rt::builders::{build, BuildConfig, Builder};
use quiver_rt::{BuildOptions, Bvh, Layout};
use quiver_lab::measure::{trace, Query};
use quiver_lab::rays;
use quiver_scenes::scene::Scene;
use std::time::Duration;

fn bench_layouts(c: &mut Criterion) {
    let name = std::env::var("QUIVER_BENCH_SCENE").unwrap_or_else(|_| "tetra9".into());
    let scene = Scene::load(&name).expect("scene");
    let tris = scene.triangles();
    let tree = build(
        &prim_bounds(&tris),
        &BuildConfig::default(),
        Builder::Binned,
    );
    let sets = [
        ("random", rays::random_rays(&scene.bounds(), 100_000, 7)),
        ("camera", rays::camera_rays(&scene.camera, 256)),
    ];
    let mut group = c.benchmark_group(format!("trace-{name}"));
    group
        .sample_size(10)
        .measurement_time(Duration::from_secs(2))
        .warm_up_time(Duration::from_millis(500));
    for layout in Layout::ALL {
        let bvh = Bvh::from_tree(&tree, &tris, &BuildOptions::default().layout(layout))
            .expect("a built tree fits its primitives");
        for threads in [1, 2] {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .expect("pool");
            for (kind, rays) in &sets {
                group.throughput(Throughput::Elements(rays.len() as u64));
                for query in [Query::Closest, Query::Any] {
                    let id = BenchmarkId::new(
                        format!("{layout}/{threads}t"),
                        format!("{kind}-{}", query.name()),
                    );
                    group.bench_function(id, |b| {
                        b.iter(|| pool.install(|| trace(&bvh, rays, query)))
                    });
                }
            }
        }
    }
    group.finish();
}

criterion_group!(benches, bench_layouts);
criterion_main!(benches);
