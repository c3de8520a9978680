//! Throughput measurement shared by the CLI reports and benchmarks: trace a ray set through
//! anything that answers [`RayQuery`] on the current rayon pool and time it.
//!
//! ```
//! use quiver_rt::Bvh;
//! use quiver_lab::measure::{trace, Query};
//! use quiver_lab::rays;
//! use quiver_scenes::Scene;
//! let s = Scene::load("tetra4").unwrap();
//! let bvh = Bvh::new(&s.triangles());
//! let rays = rays::camera_rays(&s.camera, 32);
//! assert!(trace(&bvh, &rays, Query::Closest) > 0);
//! ```

use quiver_rt::traverse::{
    ConservativeBoxes, Counters, NoFilter, NoStats, PacketMode, PacketQuery, RayQuery,
};
use quiver_rt::Ray;
use rayon::prelude::*;
use std::time::{Duration, Instant};

/// Which query to run.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Query {
    /// Nearest hit.
    Closest,
    /// Any hit (shadow-ray style, stops at the first).
    Any,
}

impl Query {
    /// Report name.
    pub fn name(self) -> &'static str {
        match self {
            Query::Closest => "closest",
            Query::Any => "any",
        }
    }
}

/// Rays per rayon task: big enough that scheduling is noise, small enough to balance.
pub const RAYS_PER_TASK: usize = 1024;

/// Traces every ray on the current thread pool; returns how many hit.
pub fn trace<Q: RayQuery + Sync>(bvh: &Q, rays: &[Ray], query: Query) -> usize {
    match query {
        Query::Closest => count_hits(rays, |r| bvh.closest_hit(r).is_some()),
        Query::Any => count_hits(rays, |r| bvh.any_hit(r)),
    }
}

/// How many rays `hit` says hit, asked on the current thread pool in tasks of
/// `RAYS_PER_TASK` rays: the timed loop of every engine and kernel we compare, so they are
/// scheduled alike.
///
/// ```
/// use quiver_lab::measure::count_hits;
/// use quiver_rt::Ray;
/// use glam::Vec3A;
/// let rays = vec![Ray::new(Vec3A::ZERO, Vec3A::X); 3000];
/// assert_eq!(count_hits(&rays, |r| r.dir.x > 0.0), 3000);
/// ```
pub fn count_hits(rays: &[Ray], hit: impl Fn(&Ray) -> bool + Sync) -> usize {
    rays.par_chunks(RAYS_PER_TASK)
        .map(|chunk| chunk.iter().filter(|r| hit(r)).count())
        .sum()
}

/// Traces the rays in packets of consecutive rays (see [`RayQuery::closest_hit_packet`]) on the
/// current thread pool; returns how many hit. Each task's rays are cut into packets in order,
/// so coherent input must come packet-ordered (e.g. [`crate::rays::camera_tiles`]).
///
/// ```
/// use quiver_rt::{traverse::PacketMode, Bvh};
/// use quiver_lab::measure::{trace, trace_packets, Query};
/// use quiver_lab::rays;
/// use quiver_scenes::Scene;
/// let s = Scene::load("tetra4").unwrap();
/// let bvh = Bvh::new(&s.triangles());
/// let rays = rays::camera_tiles(&s.camera, 32, 8);
/// let hits = trace(&bvh, &rays, Query::Closest);
/// assert_eq!(trace_packets(&bvh, &rays, Query::Closest, PacketMode::Always), hits);
/// ```
pub fn trace_packets<Q: RayQuery + Sync>(
    bvh: &Q,
    rays: &[Ray],
    query: Query,
    mode: PacketMode,
) -> usize {
    rays.par_chunks(RAYS_PER_TASK)
        .map(|chunk| match query {
            Query::Closest => {
                let mut hits = vec![None; chunk.len()];
                bvh.closest_hit_packet_with::<ConservativeBoxes, _, _>(
                    PacketQuery::new(chunk).mode(mode),
                    &mut hits,
                    &mut NoStats,
                    &mut NoFilter,
                );
                hits.iter().filter(|h| h.is_some()).count()
            }
            Query::Any => {
                let mut hit = vec![false; chunk.len()];
                bvh.any_hit_packet_with::<ConservativeBoxes, _, _>(
                    PacketQuery::new(chunk).mode(mode),
                    &mut hit,
                    &mut NoStats,
                    &mut NoFilter,
                );
                hit.iter().filter(|&&h| h).count()
            }
        })
        .sum()
}

/// Traces every ray with the counting kernels and returns the summed counters.
pub fn count<Q: RayQuery + Sync>(bvh: &Q, rays: &[Ray], query: Query) -> Counters {
    rays.par_chunks(RAYS_PER_TASK)
        .map(|chunk| {
            let mut c = Counters::default();
            for r in chunk {
                match query {
                    Query::Closest => {
                        bvh.closest_hit_counted(r, &mut c);
                    }
                    Query::Any => {
                        bvh.any_hit_counted(r, &mut c);
                    }
                }
            }
            c
        })
        .reduce(Counters::default, |mut a, b| {
            a += b;
            a
        })
}

/// The median of `reps` timings of `f` (after one untimed warm-up run).
pub fn median_time(reps: usize, mut f: impl FnMut()) -> Duration {
    f();
    let mut times: Vec<Duration> = (0..reps.max(1))
        .map(|_| {
            let t = Instant::now();
            f();
            t.elapsed()
        })
        .collect();
    times.sort();
    times[times.len() / 2]
}

/// Million rays per second for `rays` traced in `time`.
pub fn mrays_per_s(rays: usize, time: Duration) -> f64 {
    rays as f64 / time.as_secs_f64() / 1e6
}

/// Times `n` alternatives side by side: after one warm-up run of each, `reps` rounds each run
/// every alternative once (`f(i)`), so a slow spell on a shared machine hits all of them alike.
/// Returns the median time of each.
pub fn median_times_interleaved(reps: usize, n: usize, mut f: impl FnMut(usize)) -> Vec<Duration> {
    (0..n).for_each(&mut f);
    let mut times = vec![Vec::with_capacity(reps); n];
    for _ in 0..reps.max(1) {
        for (i, t) in times.iter_mut().enumerate() {
            let start = Instant::now();
            f(i);
            t.push(start.elapsed());
        }
    }
    times
        .into_iter()
        .map(|mut t| {
            t.sort();
            t[t.len() / 2]
        })
        .collect()
}
