//! A world's packet queries: a coherent packet walks the top level as one (the packet walk of
//! `traverse::packet` over the top level's 8-wide nodes), and at each instance leaf the rays
//! that enter it and see it go into object space together, transformed in SIMD lanes, and on
//! into the instance's geometry as one packet: straight from lanes into the geometry's packet
//! walk where it is a wide layout in the caller's units on the world's kernels (the common
//! case; laying the rays out one by one and packing them again was a sixth of an instanced
//! packet query's instructions), through its packet query as rays otherwise. Packets that
//! come apart, and incoherent ones, go on ray by ray through the single-ray walk.

use super::query::InInstance;
use super::{Geometry, Placed, World, WorldHit};
use crate::geometry::{Hit, Ray};
use crate::isa::Kernels;
use crate::layout::Bvh8Node;
use crate::primitive::{Lanes, Primitive, CHUNKS, LANES, PACKET_RAYS};
use crate::traverse::lane8::F8;
use crate::traverse::packet::{
    each_packet, walk, AloneIn, InLanes, PacketBuilder, PacketMode, RayPacket, Visit,
};
use crate::traverse::simd::bits;
use crate::traverse::{BoxTest, Filter, PacketQuery, RayQuery, Stats};
use glam::Vec3A;
use wide::f32x8;

/// The rays of one packet that see instance `p`: those of `live` whose mask shares a bit with
/// the instance's. `uniform` is the packet's mask when every ray has the same one.
#[inline(always)]
fn seeing(rays: &[Ray], live: u64, uniform: Option<u32>, p: &Placed) -> u64 {
    match uniform {
        Some(m) if m & p.mask != 0 => live,
        Some(_) => 0,
        None => bits(live)
            .filter(|&i| rays[i].mask & p.mask != 0)
            .fold(0, |m, i| m | 1 << i),
    }
}

/// The mask every ray of `rays` shares, if they all share one.
fn uniform_mask(rays: &[Ray]) -> Option<u32> {
    let m = rays.first()?.mask;
    rays.iter().all(|r| r.mask == m).then_some(m)
}

/// Chunk `k` of packet `pk` in instance `p`'s object space, in lanes `V`: its origin and
/// direction lanes transformed (an instance placed as it is takes them as they are).
#[inline(always)]
fn chunk_to_object<V: F8>(cpu: V::Cpu, p: &Placed, pk: &RayPacket, k: usize) -> ([V; 3], [V; 3]) {
    let (o, d) = (&pk.rays.o, &pk.rays.d);
    let lanes = |x: &[Lanes; 3]| {
        [
            V::of(cpu, &x[0][k]),
            V::of(cpu, &x[1][k]),
            V::of(cpu, &x[2][k]),
        ]
    };
    let (wo, wd) = (lanes(o), lanes(d));
    if p.identity {
        return (wo, wd);
    }
    // The floats of `Placed::world_to_object`, each broadcast straight from the record:
    // column `j` of the linear part in lanes 0..3 of `to_object[j]`, translation component
    // `a` in lane 3 of `to_object[a]`.
    let [cx, cy, cz] = &p.to_object;
    let s = |x: f32| V::splat(cpu, x);
    // glam's `transform_point3a` / `transform_vector3a` lane-wise (x·col0 + y·col1 + z·col2,
    // + translation), so every ray is transformed as the single-ray walk transforms it.
    let mut lo = [s(0.0); 3];
    let mut ld = [s(0.0); 3];
    for a in 0..3 {
        let (x, y, z) = (s(cx[a]), s(cy[a]), s(cz[a]));
        lo[a] = x
            .mul(wo[0])
            .add(y.mul(wo[1]))
            .add(z.mul(wo[2]))
            .add(s(p.to_object[a][3]));
        ld[a] = x.mul(wd[0]).add(y.mul(wd[1])).add(z.mul(wd[2]));
    }
    (lo, ld)
}

/// The rays `m` of packet `pk` in instance `p`'s object space, as a packet of their own in
/// `out`, each searching over its interval so far.
#[inline(always)]
fn local_packet<V: F8>(cpu: V::Cpu, p: &Placed, pk: &RayPacket, m: u64, out: &mut RayPacket) {
    let mut b = PacketBuilder::<V>::over(cpu, out);
    for k in 0..CHUNKS {
        let lanes = (m >> (LANES * k)) as u32 & 0xFF;
        if lanes != 0 {
            let (lo, ld) = chunk_to_object::<V>(cpu, p, pk, k);
            let t_min = V::of(cpu, &pk.rays.t_min[k]);
            let limit = V::of(cpu, &pk.rays.limit[k]);
            b.chunk(out, k, lo, ld, t_min, limit, lanes);
        }
    }
    b.finish(out);
}

impl<P: Primitive> Geometry<P> {
    /// `ask` of a packet already in object space, on the world's lanes (see
    /// [`crate::Bvh`]'s `in_lanes`): false, with nothing done, where the geometry's layout
    /// takes its rays the usual way.
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    fn in_lanes<V: F8, B: BoxTest, S: Stats, F: Filter<Hit>>(
        &self,
        kernels: Kernels,
        cpu: V::Cpu,
        pk: &mut RayPacket,
        ask: InLanes<'_>,
        stats: &mut S,
        filter: &mut F,
    ) -> bool {
        match self {
            Geometry::Triangles(b, _) => {
                b.in_lanes::<V, B, S, F>(kernels, cpu, pk, ask, stats, filter)
            }
            Geometry::Prims(b, _) => b.in_lanes::<V, B, S, F>(kernels, cpu, pk, ask, stats, filter),
        }
    }
}

/// The rays `m` of packet `pk` in instance `p`'s object space as rays, each searching up to
/// its `limit`, for a geometry that takes its rays through its packet query (binary nodes, a
/// scaled frame, other kernels). Rays outside `m` are left as they are.
#[inline(always)]
fn local_rays<V: F8>(
    cpu: V::Cpu,
    p: &Placed,
    pk: &RayPacket,
    rays: &[Ray],
    m: u64,
    limit: impl Fn(usize) -> f32,
    out: &mut [Ray],
) {
    for k in 0..CHUNKS {
        let lanes = (m >> (LANES * k)) as u32 & 0xFF;
        if lanes == 0 {
            continue;
        }
        let (lo, ld) = chunk_to_object::<V>(cpu, p, pk, k);
        let (lo, ld) = (lo.map(|v| v.to_array()), ld.map(|v| v.to_array()));
        for l in bits(lanes) {
            let i = LANES * k + l;
            out[i] = Ray {
                origin: Vec3A::new(lo[0][l], lo[1][l], lo[2][l]),
                dir: Vec3A::new(ld[0][l], ld[1][l], ld[2][l]),
                t_max: limit(i),
                ..rays[i]
            };
        }
    }
}

/// Flags for the rays of `m` among the first `n`.
#[inline(always)]
fn flags(m: u64, n: usize, out: &mut [bool; PACKET_RAYS]) {
    for (i, f) in out.iter_mut().enumerate().take(n) {
        *f = m >> i & 1 == 1;
    }
}

impl<P: Primitive> World<P> {
    /// Closest hits of one packet into `best`, on lanes of `V`.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn closest_packet<V: F8, B: BoxTest, S: Stats, F: Filter<WorldHit>>(
        &self,
        cpu: V::Cpu,
        rays: &[Ray],
        pk: &mut RayPacket,
        best: &mut [WorldHit; PACKET_RAYS],
        stats: &mut S,
        filter: &mut F,
    ) {
        let top = &self.top;
        let uniform = uniform_mask(rays);
        let n = rays.len();
        let mut local = [Ray::new(Vec3A::ZERO, Vec3A::ZERO); PACKET_RAYS];
        let mut active = [false; PACKET_RAYS];
        let mut found: [Option<Hit>; PACKET_RAYS] = [None; PACKET_RAYS];
        let mut records = [Hit::none(0.0); PACKET_RAYS];
        let mut lp = RayPacket::empty();
        let kernels = top.kernels;
        walk::<Bvh8Node, V, B, S, _>(
            cpu,
            &top.nodes,
            pk,
            stats,
            #[inline(always)]
            |_| {},
            #[inline(always)]
            |pk, visit, stats| {
                match visit {
                    Visit::Leaf(range, b, cand) => {
                        let live = pk.entering::<V, B>(cpu, b, cand);
                        stats.prims(range.len() as u32);
                        for p in &top.prims[range] {
                            let m = seeing(rays, live & pk.active, uniform, p);
                            if m == 0 {
                                continue;
                            }
                            let geometry = &self.geometries[p.geometry as usize];
                            let mut f = InInstance {
                                filter: &mut *filter,
                                instance: p.instance,
                                geometry: p.geometry,
                            };
                            local_packet::<V>(cpu, p, pk, m, &mut lp);
                            for i in bits(m) {
                                records[i] = Hit::none(best[i].t);
                            }
                            let ask = InLanes::Closest(&mut records);
                            if geometry
                                .in_lanes::<V, B, S, _>(kernels, cpu, &mut lp, ask, stats, &mut f)
                            {
                                // Straight from the records: one pass over the rays, not a
                                // copy into `found` and a second.
                                for i in bits(m) {
                                    let h = &records[i];
                                    if h.prim != u32::MAX && f.improve(&mut best[i], h) {
                                        pk.set_limit(i, h.t);
                                    }
                                }
                            } else {
                                local_rays::<V>(
                                    cpu,
                                    p,
                                    pk,
                                    rays,
                                    m,
                                    #[inline(always)]
                                    |i| best[i].t,
                                    &mut local,
                                );
                                flags(m, n, &mut active);
                                let query = PacketQuery::new(&local[..n])
                                    .active(&active[..n])
                                    .mode(PacketMode::Always);
                                geometry.closest_hit_packet_with::<B, S, _>(
                                    query,
                                    &mut found[..n],
                                    stats,
                                    &mut f,
                                );
                                for i in bits(m) {
                                    if let Some(h) = &found[i] {
                                        if f.improve(&mut best[i], h) {
                                            pk.set_limit(i, h.t);
                                        }
                                    }
                                }
                            }
                        }
                        pk.refresh_limit_bound();
                    }
                    Visit::Alone(i, at) => {
                        let ray = &rays[i];
                        match at {
                            AloneIn::Leaf(r) => {
                                for p in &top.prims[r] {
                                    self.closest_in::<V, B, S, F>(
                                        cpu,
                                        p,
                                        ray,
                                        &mut best[i],
                                        stats,
                                        filter,
                                    );
                                }
                            }
                            AloneIn::Inner(node) => self.closest_from::<V, B, S, F>(
                                cpu,
                                ray,
                                node,
                                &mut best[i],
                                stats,
                                filter,
                            ),
                        }
                        pk.set_limit(i, best[i].t);
                    }
                }
                false
            },
        );
    }

    /// Any-hit answers of one packet into `hit`, on lanes of `V`.
    #[inline(always)]
    fn any_packet<V: F8, B: BoxTest, S: Stats, F: Filter<WorldHit>>(
        &self,
        cpu: V::Cpu,
        rays: &[Ray],
        pk: &mut RayPacket,
        hit: &mut [bool],
        stats: &mut S,
        filter: &mut F,
    ) {
        let top = &self.top;
        let uniform = uniform_mask(rays);
        let n = rays.len();
        let mut local = [Ray::new(Vec3A::ZERO, Vec3A::ZERO); PACKET_RAYS];
        let mut active = [false; PACKET_RAYS];
        let mut blocked = [false; PACKET_RAYS];
        let mut lp = RayPacket::empty();
        let kernels = top.kernels;
        walk::<Bvh8Node, V, B, S, _>(
            cpu,
            &top.nodes,
            pk,
            stats,
            #[inline(always)]
            |_| {},
            #[inline(always)]
            |pk, visit, stats| {
                match visit {
                    Visit::Leaf(range, b, cand) => {
                        let live = pk.entering::<V, B>(cpu, b, cand);
                        stats.prims(range.len() as u32);
                        for p in &top.prims[range] {
                            let m = seeing(rays, live & pk.active, uniform, p);
                            if m == 0 {
                                continue;
                            }
                            let geometry = &self.geometries[p.geometry as usize];
                            let mut f = InInstance {
                                filter: &mut *filter,
                                instance: p.instance,
                                geometry: p.geometry,
                            };
                            local_packet::<V>(cpu, p, pk, m, &mut lp);
                            for i in bits(m) {
                                blocked[i] = false;
                            }
                            let ask = InLanes::Any(&mut blocked);
                            if !geometry
                                .in_lanes::<V, B, S, _>(kernels, cpu, &mut lp, ask, stats, &mut f)
                            {
                                local_rays::<V>(cpu, p, pk, rays, m, |i| rays[i].t_max, &mut local);
                                flags(m, n, &mut active);
                                let query = PacketQuery::new(&local[..n])
                                    .active(&active[..n])
                                    .mode(PacketMode::Always);
                                geometry.any_hit_packet_with::<B, S, _>(
                                    query,
                                    &mut blocked[..n],
                                    stats,
                                    &mut f,
                                );
                            }
                            for i in bits(m) {
                                if blocked[i] {
                                    hit[i] = true;
                                    pk.retire(i);
                                }
                            }
                        }
                    }
                    Visit::Alone(i, at) => {
                        let ray = &rays[i];
                        let found = match at {
                            AloneIn::Leaf(r) => top.prims[r]
                                .iter()
                                .any(|p| self.any_in::<V, B, S, F>(cpu, p, ray, stats, filter)),
                            AloneIn::Inner(node) => {
                                self.any_from::<V, B, S, F>(cpu, ray, node, stats, filter)
                            }
                        };
                        if found {
                            hit[i] = true;
                            pk.retire(i);
                        }
                    }
                }
                pk.active == 0
            },
        );
    }

    #[inline(always)]
    fn closest_rays_on<V: F8, B: BoxTest, S: Stats, F: Filter<WorldHit>>(
        &self,
        cpu: V::Cpu,
        query: PacketQuery<'_>,
        hits: &mut [Option<WorldHit>],
        stats: &mut S,
        filter: &mut F,
    ) {
        let walkable = !self.top.prims.is_empty();
        each_packet(
            query,
            hits,
            #[inline(always)]
            |rays, on, packet, hits| {
                hits.fill(None);
                if !walkable {
                    return;
                }
                if packet {
                    let mut pk = RayPacket::new(rays, on);
                    let mut best = [WorldHit::none(0.0); PACKET_RAYS];
                    for (b, r) in best.iter_mut().zip(rays) {
                        *b = WorldHit::none(r.t_max);
                    }
                    self.closest_packet::<V, B, S, F>(cpu, rays, &mut pk, &mut best, stats, filter);
                    for i in bits(on) {
                        hits[i] = best[i].found();
                    }
                } else {
                    for i in bits(on) {
                        let mut best = WorldHit::none(rays[i].t_max);
                        self.closest_from::<V, B, S, F>(cpu, &rays[i], 0, &mut best, stats, filter);
                        hits[i] = best.found();
                    }
                }
            },
        );
    }

    #[inline(always)]
    fn any_rays_on<V: F8, B: BoxTest, S: Stats, F: Filter<WorldHit>>(
        &self,
        cpu: V::Cpu,
        query: PacketQuery<'_>,
        occluded: &mut [bool],
        stats: &mut S,
        filter: &mut F,
    ) {
        let walkable = !self.top.prims.is_empty();
        each_packet(
            query,
            occluded,
            #[inline(always)]
            |rays, on, packet, out| {
                out.fill(false);
                if !walkable {
                    return;
                }
                if packet {
                    let mut pk = RayPacket::new(rays, on);
                    self.any_packet::<V, B, S, F>(cpu, rays, &mut pk, out, stats, filter);
                } else {
                    for i in bits(on) {
                        out[i] = self.any_from::<V, B, S, F>(cpu, &rays[i], 0, stats, filter);
                    }
                }
            },
        );
    }
}

/// A world's closest-hit packet query on its top level's lanes.
pub(super) fn closest_rays<P: Primitive, B: BoxTest, S: Stats, F: Filter<WorldHit>>(
    world: &World<P>,
    query: PacketQuery<'_>,
    hits: &mut [Option<WorldHit>],
    stats: &mut S,
    filter: &mut F,
) {
    match world.top.kernels {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: `cpu` proves the CPU has AVX2 and FMA (only detection makes one).
        Kernels::Avx2(cpu) => unsafe {
            avx2::closest_rays::<P, B, S, F>(world, cpu, query, hits, stats, filter)
        },
        _ => world.closest_rays_on::<f32x8, B, S, F>((), query, hits, stats, filter),
    }
}

/// A world's any-hit packet query on its top level's lanes.
pub(super) fn any_rays<P: Primitive, B: BoxTest, S: Stats, F: Filter<WorldHit>>(
    world: &World<P>,
    query: PacketQuery<'_>,
    occluded: &mut [bool],
    stats: &mut S,
    filter: &mut F,
) {
    match world.top.kernels {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: as above.
        Kernels::Avx2(cpu) => unsafe {
            avx2::any_rays::<P, B, S, F>(world, cpu, query, occluded, stats, filter)
        },
        _ => world.any_rays_on::<f32x8, B, S, F>((), query, occluded, stats, filter),
    }
}

#[cfg(target_arch = "x86_64")]
mod avx2 {
    use super::*;
    use crate::isa::Avx2Cpu;
    use crate::traverse::lane8::Avx;

    /// # Safety
    /// The CPU must support AVX2 and FMA (as `cpu` proves).
    #[target_feature(enable = "avx2,fma")]
    pub(super) unsafe fn closest_rays<P: Primitive, B: BoxTest, S: Stats, F: Filter<WorldHit>>(
        world: &World<P>,
        cpu: Avx2Cpu,
        query: PacketQuery<'_>,
        hits: &mut [Option<WorldHit>],
        stats: &mut S,
        filter: &mut F,
    ) {
        world.closest_rays_on::<Avx, B, S, F>(cpu, query, hits, stats, filter)
    }

    /// # Safety
    /// The CPU must support AVX2 and FMA (as `cpu` proves).
    #[target_feature(enable = "avx2,fma")]
    pub(super) unsafe fn any_rays<P: Primitive, B: BoxTest, S: Stats, F: Filter<WorldHit>>(
        world: &World<P>,
        cpu: Avx2Cpu,
        query: PacketQuery<'_>,
        occluded: &mut [bool],
        stats: &mut S,
        filter: &mut F,
    ) {
        world.any_rays_on::<Avx, B, S, F>(cpu, query, occluded, stats, filter)
    }
}
