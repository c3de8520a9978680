//! Packet traversal against the BVH4 single-ray kernel on the same rays: eye rays in 8 x 8
//! pixel tiles (closest hit), shadow rays from those hits toward the first light (any hit),
//! and incoherent rays (closest hit, where `PacketMode::Auto` falls back to single rays), at 1
//! and 2 threads. Criterion reports rays per second (`thrpt`).
//!
//! `cargo bench --bench packets` runs all; filter like `cargo bench --bench packets -- eye`.
//! Set `QUIVER_BENCH_SCENE` (default `teapot12`) to trace another scene. `quiver packets`
//! measures the same comparison on several scenes, curve and patch mode, in one table.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use quiver_rt::traverse::PacketMode;
use quiver_rt::Bvh;
use quiver_lab::measure::{trace, trace_packets, Query};
use quiver_lab::rays;
use quiver_scenes::Scene;
use std::time::Duration;

fn bench_packets(c: &mut Criterion) {
    let name = std::env::var("QUIVER_BENCH_SCENE").unwrap_or_else(|_| "teapot12".into());
    let scene = Scene::load(&name).expect("scene");
    let tris = scene.triangles();
    let bvh = Bvh::new(&tris);
    let eye = rays::camera_tiles(&scene.camera, 256, 8);
    let light = scene.lights.first().map_or(scene.camera.from, |l| l.pos);
    let shadow = rays::shadow_rays(&bvh, &eye, &[light]);
    let random = rays::random_rays(&scene.bounds(), 50_000, 7);
    let sets = [
        ("eye", &eye, Query::Closest),
        ("shadow", &shadow, Query::Any),
        ("incoherent", &random, Query::Closest),
    ];
    let mut group = c.benchmark_group(format!("packets-{name}"));
    group
        .sample_size(10)
        .measurement_time(Duration::from_secs(2))
        .warm_up_time(Duration::from_millis(500));
    for threads in [1, 2] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("pool");
        for (kind, rays, query) in sets {
            group.throughput(Throughput::Elements(rays.len() as u64));
            let id = |kernel: &str| BenchmarkId::new(format!("{kind}/{threads}t"), kernel);
            group.bench_function(id("single"), |b| {
                b.iter(|| pool.install(|| trace(&bvh, rays, query)))
            });
            group.bench_function(id("packet"), |b| {
                b.iter(|| pool.install(|| trace_packets(&bvh, rays, query, PacketMode::Auto)))
            });
        }
    }
    group.finish();
}

criterion_group!(benches, bench_packets);
criterion_main!(benches);
