//! Helpers every test module shares: thread pools, builds, reference answers, small inputs.

use glam::Vec3A;
use quiver_rt::traverse::{
    reference, ConservativeBoxes, NoFilter, NoStats, PacketMode, PacketQuery,
};
use quiver_rt::{BuildOptions, Bvh, Hit, Layout, Primitive, Ray, RayQuery, Triangle};
use rayon::prelude::*;

/// The 4- and 8-wide layouts: the ones with a packet kernel.
pub const WIDE: [Layout; 4] = [
    Layout::Bvh4Dfs,
    Layout::Bvh4Subtree,
    Layout::Bvh4Quant,
    Layout::Bvh8Dfs,
];

/// Runs `f` on a fresh pool of `threads` threads.
pub fn in_pool<T: Send>(threads: usize, f: impl FnOnce() -> T + Send) -> T {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .expect("a thread pool")
        .install(f)
}

/// A BVH over `prims` in `layout`, every other option default.
pub fn build<P: Primitive>(prims: &[P], layout: Layout) -> Bvh<P> {
    Bvh::build(prims, &BuildOptions::default().layout(layout)).unwrap()
}

/// The brute-force reference's closest hit for every ray (in parallel).
pub fn reference_hits<P: Primitive>(prims: &[P], rays: &[Ray]) -> Vec<Option<Hit>> {
    rays.par_iter()
        .map(|r| reference::closest_hit(prims, r))
        .collect()
}

/// A triangle from three coordinate triples.
pub fn tri(a: [f32; 3], b: [f32; 3], c: [f32; 3]) -> Triangle {
    Triangle::new(a.into(), b.into(), c.into())
}

/// The triangle (0,0,0), (1,0,0), (0,1,0).
pub fn unit_tri() -> Triangle {
    Triangle::new(Vec3A::ZERO, Vec3A::X, Vec3A::Y)
}

/// Packet answers of `bvh` in `mode`, no filter: closest hits and occlusion, one per ray.
pub fn packet_answers<Q: RayQuery>(
    bvh: &Q,
    rays: &[Ray],
    mode: PacketMode,
) -> (Vec<Option<Q::Hit>>, Vec<bool>) {
    let mut hits = vec![None; rays.len()];
    let mut occluded = vec![false; rays.len()];
    let q = PacketQuery::new(rays).mode(mode);
    bvh.closest_hit_packet_with::<ConservativeBoxes, _, _>(
        q,
        &mut hits,
        &mut NoStats,
        &mut NoFilter,
    );
    bvh.any_hit_packet_with::<ConservativeBoxes, _, _>(
        q,
        &mut occluded,
        &mut NoStats,
        &mut NoFilter,
    );
    (hits, occluded)
}

/// Every instruction set a layout has kernels for (and this CPU runs): `f` on `laid_out`
/// switched to each.
pub fn each_isa<P: Primitive>(laid_out: &Bvh<P>, mut f: impl FnMut(&Bvh<P>, quiver_rt::Isa)) {
    for isa in quiver_rt::Isa::ALL {
        let bvh = laid_out.clone().with_isa(isa);
        if bvh.isa() == isa {
            f(&bvh, isa);
        }
    }
}
