//! Watertight probe: `cargo run --release -p quiver-lab --example wt -- KERNEL SCENE RAYS REPS`
//! traces RAYS incoherent rays (the accuracy study's) through SCENE as triangles on one thread,
//! closest then any hit, with KERNEL `fast` (fast triangles, plain boxes) or `water`
//! (watertight triangles, conservative boxes), or `fast-conservative` / `water-plain`, and prints the fastest round's Mrays/s of each;
//! `alt` times `fast` and `water` round by round through the accuracy study's timing (medians of
//! REPS interleaved rounds, on the current rayon pool: `RAYON_NUM_THREADS=1` for one thread).
//! `COUNT=1` also prints the nodes, leaves and triangle tests per closest-hit ray.
//! For quick A/B runs and instruction counts under callgrind; the table comes from
//! `quiver accuracy`.
use quiver_rt::intersect::Watertight;
use quiver_rt::traverse::{BoxTest, ConservativeBoxes, FastBoxes, NoFilter, NoStats};
use quiver_rt::{Bvh, Primitive, Ray, RayQuery};
use quiver_scenes::Scene;
use std::time::Instant;

fn time<P: Primitive, B: BoxTest>(bvh: &Bvh<P>, rays: &[Ray], reps: usize) -> [f64; 2] {
    [false, true].map(|any| {
        let mut best = f64::MAX;
        for _ in 0..reps {
            let t = Instant::now();
            let mut n = 0usize;
            for r in rays {
                n += if any {
                    bvh.any_hit_with::<B, _, _>(r, &mut NoStats, &mut NoFilter) as usize
                } else {
                    bvh.closest_hit_with::<B, _, _>(r, &mut NoStats, &mut NoFilter)
                        .is_some() as usize
                };
            }
            std::hint::black_box(n);
            best = best.min(t.elapsed().as_secs_f64());
        }
        rays.len() as f64 / best / 1e6
    })
}

fn main() {
    let a: Vec<String> = std::env::args().collect();
    let kernel = a.get(1).map_or("fast", |s| s.as_str());
    let name = a.get(2).map_or("teapot12", |s| s.as_str());
    let n: usize = a.get(3).map_or(300_000, |s| s.parse().expect("rays"));
    let reps: usize = a.get(4).map_or(5, |s| s.parse().expect("reps"));
    let tris = Scene::load(name).expect("scene").triangles();
    let bounds = tris
        .iter()
        .fold(quiver_rt::Aabb::EMPTY, |b, t| b.union(&t.bounds()));
    let rays = quiver_lab::rays::random_rays(&bounds, n, 17);
    if kernel == "alt" {
        // Fast + plain against watertight + conservative interleaved round by round, through
        // the accuracy study's timing (medians), for comparing the two ways of timing.
        let w: Vec<Watertight> = tris.iter().map(|&t| Watertight(t)).collect();
        let (fast, water) = (Bvh::new(&tris), Bvh::new(&w));
        for any in [false, true] {
            let t = quiver_lab::measure::median_times_interleaved(reps, 2, |i| {
                let n = quiver_lab::measure::count_hits(&rays, |r| match (i, any) {
                    (0, false) => fast
                        .closest_hit_with::<FastBoxes, _, _>(r, &mut NoStats, &mut NoFilter)
                        .is_some(),
                    (0, true) => {
                        fast.any_hit_with::<FastBoxes, _, _>(r, &mut NoStats, &mut NoFilter)
                    }
                    (_, false) => water
                        .closest_hit_with::<ConservativeBoxes, _, _>(r, &mut NoStats, &mut NoFilter)
                        .is_some(),
                    (_, true) => water.any_hit_with::<ConservativeBoxes, _, _>(
                        r,
                        &mut NoStats,
                        &mut NoFilter,
                    ),
                });
                std::hint::black_box(n);
            });
            let m: Vec<f64> = t
                .iter()
                .map(|t| rays.len() as f64 / t.as_secs_f64() / 1e6)
                .collect();
            println!(
                "alt {name} any={any}: fast {:.2} water {:.2} ratio {:.3}",
                m[0],
                m[1],
                m[1] / m[0]
            );
        }
        return;
    }
    let [c, y] = match kernel {
        "water" | "water-plain" => {
            let w: Vec<Watertight> = tris.iter().map(|&t| Watertight(t)).collect();
            match kernel {
                "water" => time::<_, ConservativeBoxes>(&Bvh::new(&w), &rays, reps),
                _ => time::<_, FastBoxes>(&Bvh::new(&w), &rays, reps),
            }
        }
        "fast-conservative" => time::<_, ConservativeBoxes>(&Bvh::new(&tris), &rays, reps),
        _ => time::<_, FastBoxes>(&Bvh::new(&tris), &rays, reps),
    };
    println!("{kernel} {name}: closest {c:.2} any {y:.2} Mrays/s");
    if std::env::var_os("COUNT").is_some() {
        // The fast layout's work per closest-hit ray (the watertight one walks the same tree).
        let bvh = Bvh::new(&tris);
        let mut s = quiver_rt::traverse::Counters::default();
        for r in &rays {
            bvh.closest_hit_with::<FastBoxes, _, _>(r, &mut s, &mut NoFilter);
        }
        let per = |x: u64| x as f64 / rays.len() as f64;
        println!(
            "closest per ray: nodes {:.2} leaves {:.2} triangle tests {:.2}",
            per(s.nodes),
            per(s.leaves),
            per(s.prim_tests)
        );
    }
}
