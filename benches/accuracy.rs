//! What accuracy costs in time: fast vs watertight vs f64 triangles, plain vs conservative
//! boxes, closest-hit on incoherent rays through one scene (BVH4, 1 thread).
//!
//! `cargo bench --bench accuracy` (or filter, e.g. `-- watertight`). `QUIVER_BENCH_SCENE`
//! picks the scene (default tetra8, 65,536 triangles). `quiver accuracy` adds the error side.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use quiver_rt::intersect::{Exact, Watertight};
use quiver_rt::traverse::{BoxTest, ConservativeBoxes, FastBoxes, NoFilter, NoStats};
use quiver_rt::{Bvh, Primitive, Ray, RayQuery, Triangle};
use quiver_lab::rays;
use quiver_scenes::Scene;
use std::time::Duration;

fn one<P: Primitive, B: BoxTest>(
    c: &mut criterion::BenchmarkGroup<criterion::measurement::WallTime>,
    name: &str,
    prims: &[P],
    rays: &[Ray],
) {
    let bvh = Bvh::new(prims);
    c.bench_function(name, |b| {
        b.iter(|| {
            rays.iter()
                .filter(|r| {
                    bvh.closest_hit_with::<B, _, _>(r, &mut NoStats, &mut NoFilter)
                        .is_some()
                })
                .count()
        })
    });
}

fn bench_accuracy(c: &mut Criterion) {
    let name = std::env::var("QUIVER_BENCH_SCENE").unwrap_or_else(|_| "tetra8".into());
    let tris: Vec<Triangle> = Scene::load(&name).expect("scene").triangles();
    let bounds = tris
        .iter()
        .fold(quiver_rt::Aabb::EMPTY, |b, t| b.union(&t.bounds()));
    let rays = rays::random_rays(&bounds, 50_000, 3);
    let wt: Vec<Watertight> = tris.iter().map(|&t| Watertight(t)).collect();
    let ex: Vec<Exact> = tris.iter().map(|&t| Exact(t)).collect();
    let mut g = c.benchmark_group(format!("accuracy-{name}"));
    g.sample_size(10)
        .measurement_time(Duration::from_secs(2))
        .throughput(Throughput::Elements(rays.len() as u64));
    one::<_, FastBoxes>(&mut g, "fast/plain", &tris, &rays);
    one::<_, ConservativeBoxes>(&mut g, "fast/conservative", &tris, &rays);
    one::<_, FastBoxes>(&mut g, "watertight/plain", &wt, &rays);
    one::<_, ConservativeBoxes>(&mut g, "watertight/conservative", &wt, &rays);
    one::<_, ConservativeBoxes>(&mut g, "f64/conservative", &ex, &rays);
    g.finish();
}

criterion_group!(benches, bench_accuracy);
criterion_main!(benches);
