//! A world's packet queries: a coherent packet walks the top level as one (the packet walk of
//! `traverse::packet` over the top level's 8-wide nodes), and at each instance leaf the rays
//! that enter it and see it go into object space together, transformed in SIMD lanes, and on
//! into the instance's geometry as one packet: straight from lanes into the geometry's packet
//! walk where it is a wide layout in the caller's units on the world's kernels (the common
//! case; laying the rays out one by one and packing them again was a sixth of an instanced
//! packet query's instructions), through its packet query as rays otherwise. Packets that
//! come apart, and incoherent ones, go on ray by ray through the single-ray walk.

use super::query::InInstance;
use super::{Geometry, InstanceLeaf, World, WorldHit};
use crate::geometry::{Hit, Ray};
use crate::isa::Kernels;
use crate::layout::Bvh8Node;
use crate::primitive::{Lanes, Primitive, CHUNKS, LANES, PACKET_RAYS};
use crate::traverse::dispatch::{self, LaneKernel};
use crate::traverse::lane8::F8;
use crate::traverse::packet::{
    each_packet, walk, AloneIn, InLanes, PacketBuilder, PacketMode, RayPacket, Visit,
};
use crate::traverse::simd::bits;
use crate::traverse::{Ask, BoxTest, Filter, PacketQuery, RayQuery, Stats};
use glam::Vec3A;
use std::marker::PhantomData;

/// The rays of one packet that see instance `p`: those of `live` whose mask shares a bit with
/// the instance's. `uniform` is the packet's mask when every ray has the same one.
#[inline(always)]
fn seeing(rays: &[Ray], live: u64, uniform: Option<u32>, p: &InstanceLeaf) -> u64 {
    match uniform {
        Some(m) if m & p.mask != 0 => live,
        Some(_) => 0,
        None => bits(live)
            .filter(|&i| rays[i].mask & p.mask != 0)
            .fold(0, |m, i| m | 1 << i),
    }
}

/// The mask every ray of `rays` shares, if they all share one. Every ray is read (no early
/// exit): packets of one mask are the rule, and a loop without a branch per ray is shorter.
#[inline(always)]
fn uniform_mask(rays: &[Ray]) -> Option<u32> {
    let m = rays.first()?.mask;
    let differ = rays.iter().fold(0, |d, r| d | (r.mask ^ m));
    (differ == 0).then_some(m)
}

/// Chunk `k` of packet `pk` in instance `p`'s object space, in lanes `V`: its origin and
/// direction lanes transformed (an instance placed as it is takes them as they are).
#[inline(always)]
fn chunk_to_object<V: F8>(
    cpu: V::Cpu,
    p: &InstanceLeaf,
    pk: &RayPacket,
    k: usize,
) -> ([V; 3], [V; 3]) {
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
    // The floats of `InstanceLeaf::world_to_object`, each broadcast straight from the record:
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
fn local_packet<V: F8>(cpu: V::Cpu, p: &InstanceLeaf, pk: &RayPacket, m: u64, out: &mut RayPacket) {
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
    /// The search `A` of a packet already in object space, on the world's lanes (see
    /// [`crate::Bvh`]'s `in_lanes`): false, with nothing done, where the geometry's layout
    /// takes its rays the usual way.
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    fn in_lanes<V: F8, A: Ask, B: BoxTest, S: Stats, F: Filter<Hit>>(
        &self,
        kernels: Kernels,
        cpu: V::Cpu,
        pk: &mut RayPacket,
        best: InLanes<'_>,
        stats: &mut S,
        filter: &mut F,
    ) -> bool {
        match self {
            Geometry::Triangles(b, _) => {
                b.in_lanes::<V, A, B, S, F>(kernels, cpu, pk, best, stats, filter)
            }
            Geometry::Prims(b, _) => {
                b.in_lanes::<V, A, B, S, F>(kernels, cpu, pk, best, stats, filter)
            }
            // Its packet query, which takes the rays one by one, each at its time.
            Geometry::MovingTriangles(_) => false,
        }
    }
}

/// The rays `m` of packet `pk` in instance `p`'s object space as rays, each searching up to
/// its `limit`, for a geometry that takes its rays through its packet query (binary nodes, a
/// scaled frame, other kernels). Rays outside `m` are left as they are.
#[inline(always)]
fn local_rays<V: F8>(
    cpu: V::Cpu,
    p: &InstanceLeaf,
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
        // Written out, not `array::map`: a closure over lanes must stay inside the kernel.
        let lo = [lo[0].to_array(), lo[1].to_array(), lo[2].to_array()];
        let ld = [ld[0].to_array(), ld[1].to_array(), ld[2].to_array()];
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

/// Ray `i`'s search limit: its best hit's distance; any hit reads no record (a ray that meets
/// something retires), so its whole interval.
#[inline(always)]
fn limit<A: Ask>(rays: &[Ray], best: &[WorldHit; PACKET_RAYS], i: usize) -> f32 {
    if A::ANY {
        rays[i].t_max
    } else {
        best[i].t
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
    /// The search `A` of one packet into `best` (one record per ray, [`WorldHit::none`] at
    /// its limit to start), on lanes of `V`. Closest hit: a kept hit lowers its ray's limit.
    /// Any hit: a ray that meets something retires, and the walk ends once every ray has.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn trace_packet<V: F8, A: Ask, B: BoxTest, S: Stats, F: Filter<WorldHit>>(
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
        let mut records = [Hit::none(0.0); PACKET_RAYS];
        let mut lp = RayPacket::empty();
        let kernels = top.kernels;
        // Each ray's time in lanes, where some instance moves.
        let mut times = [[0.0f32; LANES]; CHUNKS];
        if !self.ends.leaves.is_empty() {
            for i in 0..n {
                times[i / LANES][i % LANES] = rays[i].shutter_time();
            }
        }
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
                        for pi in range {
                            let p = &top.prims[pi];
                            let mut m = seeing(rays, live & pk.active, uniform, p);
                            if p.moving {
                                // Only the rays that meet its box where it is at their time.
                                let ends = &self.ends.leaves[pi];
                                m = pk.entering_moving::<V, B>(cpu, ends, &times, m);
                            }
                            if m == 0 {
                                continue;
                            }
                            if p.moving || self.own_filter(p.geometry).is_some() {
                                // A moving instance (each ray at its own time), or a
                                // geometry with its own filter: ray by ray.
                                for i in bits(m) {
                                    let limit = limit::<A>(rays, best, i);
                                    let Some(local) = self.local_ray(p, &rays[i], limit) else {
                                        continue;
                                    };
                                    let kept = self.search_local::<A, B, S, F>(
                                        p,
                                        &local,
                                        &mut best[i],
                                        stats,
                                        filter,
                                    );
                                    if kept {
                                        if A::ANY {
                                            pk.retire(i);
                                        } else {
                                            pk.set_limit(i, best[i].t);
                                        }
                                    }
                                }
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
                                // Any hit reads no record but the mark of a hit.
                                match A::ANY {
                                    true => records[i].prim = u32::MAX,
                                    false => records[i] = Hit::none(best[i].t),
                                }
                            }
                            if !geometry.in_lanes::<V, A, B, S, _>(
                                kernels,
                                cpu,
                                &mut lp,
                                &mut records,
                                stats,
                                &mut f,
                            ) {
                                // Made here, not per packet: the geometries walked in lanes
                                // (8-wide BVHs on the world's kernels) never need them.
                                let mut local = [Ray::new(Vec3A::ZERO, Vec3A::ZERO); PACKET_RAYS];
                                let mut active = [false; PACKET_RAYS];
                                let mut found = [A::Answer::<Hit>::default(); PACKET_RAYS];
                                local_rays::<V>(
                                    cpu,
                                    p,
                                    pk,
                                    rays,
                                    m,
                                    #[inline(always)]
                                    |i| limit::<A>(rays, best, i),
                                    &mut local,
                                );
                                flags(m, n, &mut active);
                                let query = PacketQuery::new(&local[..n])
                                    .active(&active[..n])
                                    .mode(PacketMode::Always);
                                geometry.trace_packet_with::<A, B, S, _>(
                                    query,
                                    &mut found[..n],
                                    stats,
                                    &mut f,
                                );
                                for i in bits(m) {
                                    // Any hit keeps no record: a stand-in marks the hit.
                                    let stand_in = Hit {
                                        prim: 0,
                                        ..records[i]
                                    };
                                    if let Some(h) = A::into_hit(found[i], stand_in) {
                                        records[i] = h;
                                    }
                                }
                            }
                            // Straight from the records: one pass over the rays.
                            // Any hit: the ray retires, and its record is never read.
                            for i in bits(m) {
                                let h = &records[i];
                                if h.prim == u32::MAX {
                                    continue;
                                }
                                if A::ANY {
                                    pk.retire(i);
                                } else if f.improve::<A>(&mut best[i], h) {
                                    pk.set_limit(i, h.t);
                                }
                            }
                        }
                        if !A::ANY {
                            pk.refresh_limit_bound();
                        }
                    }
                    Visit::Alone(i, at) => {
                        let ray = &rays[i];
                        if A::ANY {
                            // Its record was never read before: the ray's whole interval.
                            best[i] = WorldHit::none(ray.t_max);
                        }
                        let found = match at {
                            AloneIn::Leaf(r) => self.search_leaf::<V, A, B, S, F, true>(
                                cpu,
                                r.start,
                                r.len(),
                                ray,
                                &mut best[i],
                                stats,
                                filter,
                            ),
                            AloneIn::Inner(node) => {
                                self.search_from::<V, A, B, S, F>(
                                    cpu,
                                    ray,
                                    node,
                                    &mut best[i],
                                    stats,
                                    filter,
                                );
                                best[i].found().is_some()
                            }
                        };
                        if !A::ANY {
                            pk.set_limit(i, best[i].t);
                        } else if found {
                            pk.retire(i);
                        }
                    }
                }
                A::ANY && pk.active == 0
            },
        );
    }
}

/// A world's packet query, as the kernel [`dispatch`] runs on the top level's lanes.
struct TraceRays<'a, P, A: Ask, B, S, F> {
    world: &'a World<P>,
    query: PacketQuery<'a>,
    hits: &'a mut [A::Answer<WorldHit>],
    stats: &'a mut S,
    filter: &'a mut F,
    ask: PhantomData<(A, B)>,
}

impl<P, A, B, S, F> LaneKernel for TraceRays<'_, P, A, B, S, F>
where
    P: Primitive,
    A: Ask,
    B: BoxTest,
    S: Stats,
    F: Filter<WorldHit>,
{
    type Out = ();

    #[inline(always)]
    fn run<V: F8, const FAR: bool>(self, cpu: V::Cpu) {
        let TraceRays {
            world,
            query,
            hits,
            stats,
            filter,
            ..
        } = self;
        let walkable = world.walkable();
        each_packet(
            query,
            hits,
            #[inline(always)]
            |rays, on, packet, hits| {
                for h in hits.iter_mut() {
                    *h = Default::default();
                }
                if !walkable {
                    return;
                }
                // Any hit reads no record (see `trace_packet`): its records start unset.
                let mut best = [WorldHit::none(0.0); PACKET_RAYS];
                if !A::ANY {
                    for i in 0..rays.len() {
                        best[i] = WorldHit::none(rays[i].t_max);
                    }
                }
                let mut found = 0u64;
                if packet {
                    let mut pk = RayPacket::empty();
                    pk.pack(rays, on);
                    let traced = pk.active;
                    world.trace_packet::<V, A, B, S, F>(
                        cpu, rays, &mut pk, &mut best, stats, filter,
                    );
                    // Any hit: a ray leaves the active set only when it meets something.
                    found = traced & !pk.active;
                } else {
                    for i in bits(on) {
                        if A::ANY {
                            best[i] = WorldHit::none(rays[i].t_max);
                        }
                        world.search_from::<V, A, B, S, F>(
                            cpu,
                            &rays[i],
                            0,
                            &mut best[i],
                            stats,
                            filter,
                        );
                        if best[i].found().is_some() {
                            found |= 1 << i;
                        }
                    }
                }
                if A::ANY {
                    for i in bits(found) {
                        hits[i] = A::answer(Some(best[i]));
                    }
                } else {
                    for i in bits(on) {
                        hits[i] = A::answer(best[i].found());
                    }
                }
            },
        );
    }
}

/// A world's packet query on its top level's lanes.
pub(super) fn trace_rays<P: Primitive, A: Ask, B: BoxTest, S: Stats, F: Filter<WorldHit>>(
    world: &World<P>,
    query: PacketQuery<'_>,
    hits: &mut [A::Answer<WorldHit>],
    stats: &mut S,
    filter: &mut F,
) {
    let kernel = TraceRays::<P, A, B, S, F> {
        world,
        query,
        hits,
        stats,
        filter,
        ask: PhantomData,
    };
    dispatch::run(world.top.kernels, false, kernel)
}
