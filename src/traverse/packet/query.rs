//! A packet query: its rays cut into packets ([`super::each_packet`]), each packet walked
//! ([`super::walk`]) with its leaves tested ([`super::leaves`]), or, where the packet does not
//! pay, each ray through the single-ray walk; on the lanes of the BVH's instruction set
//! ([`dispatch`]), for every node format, written once for both questions ([`Ask`]).

use super::lanes::RayPacket;
use super::leaves::test_leaf;
use super::node::PacketNode;
use super::walk::{walk, AloneIn, Visit};
use super::PacketQuery;
use super::{each_packet, PACKET_RAYS};
use crate::geometry::{Hit, PrimHit, Ray};
use crate::isa::Kernels;
use crate::primitive::{lane, Primitive};
use crate::traverse::dispatch::{self, LaneKernel};
use crate::traverse::lane8::F8;
use crate::traverse::leaves::Leaves;
use crate::traverse::search::offer;
use crate::traverse::simd::bits;
use crate::traverse::{Ask, BoxTest, Filter, Stats};
use std::marker::PhantomData;

/// The query `A` of any number of rays, packet by packet, over one node format, on
/// `kernels`' lanes: the packet kernels' entry.
#[inline]
pub(crate) fn trace_rays<N, A, B, P, S, F>(
    kernels: Kernels,
    nodes: &[N],
    leaves: &Leaves<P>,
    query: PacketQuery<'_>,
    hits: &mut [A::Answer<Hit>],
    stats: &mut S,
    filter: &mut F,
) where
    N: PacketNode,
    A: Ask,
    B: BoxTest,
    P: Primitive,
    S: Stats,
    F: Filter<Hit>,
{
    let kernel = TraceRays::<N, A, B, P, S, F> {
        nodes,
        leaves,
        query,
        hits,
        stats,
        filter,
        ask: PhantomData,
    };
    dispatch::run(kernels, false, kernel)
}

/// A packet query as the kernel [`dispatch`] runs. (The leaves check for far groups
/// themselves: a packet's leaf tests are out of the walk's line.)
struct TraceRays<'a, N, A: Ask, B, P, S, F> {
    nodes: &'a [N],
    leaves: &'a Leaves<'a, P>,
    query: PacketQuery<'a>,
    hits: &'a mut [A::Answer<Hit>],
    stats: &'a mut S,
    filter: &'a mut F,
    ask: PhantomData<(A, B)>,
}

impl<N, A, B, P, S, F> LaneKernel for TraceRays<'_, N, A, B, P, S, F>
where
    N: PacketNode,
    A: Ask,
    B: BoxTest,
    P: Primitive,
    S: Stats,
    F: Filter<Hit>,
{
    type Out = ();

    #[inline(always)]
    fn run<V: F8, const FAR: bool>(self, cpu: V::Cpu) {
        let TraceRays {
            nodes,
            leaves,
            query,
            hits,
            stats,
            filter,
            ..
        } = self;
        each_packet(
            query,
            hits,
            #[inline(always)]
            |rays, on, packet, hits| {
                // One search record per ray. Any hit reads none (it keeps the first hit a ray
                // meets; which rays met one is what the packet's retired rays say), so its
                // records start unset and a ray gets its interval only where it goes alone.
                let mut best = [Hit::none(0.0); PACKET_RAYS];
                if !A::ANY {
                    for i in 0..rays.len() {
                        best[i] = Hit::none(rays[i].t_max);
                    }
                }
                let mut found = 0u64;
                if packet {
                    let mut pk = RayPacket::empty();
                    pk.pack(rays, on);
                    let traced = pk.active;
                    trace_packet::<N, V, A, B, P, S, F>(
                        cpu,
                        nodes,
                        leaves,
                        #[inline(always)]
                        |_, i| rays[i],
                        &mut pk,
                        &mut best,
                        stats,
                        filter,
                    );
                    // Any hit: a ray leaves the active set only when it meets something.
                    found = traced & !pk.active;
                } else {
                    for i in bits(on) {
                        if A::ANY {
                            best[i] = Hit::none(rays[i].t_max);
                        }
                        N::search_from::<V, A, B, P, S, F>(
                            cpu,
                            nodes,
                            leaves,
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
                    for h in hits.iter_mut() {
                        *h = Default::default();
                    }
                    for i in bits(found) {
                        hits[i] = A::answer(Some(best[i]));
                    }
                } else {
                    for i in 0..hits.len() {
                        hits[i] = if on >> i & 1 == 1 {
                            A::answer(best[i].found())
                        } else {
                            Default::default()
                        };
                    }
                }
            },
        );
    }
}

/// Ray `i` of `pk` read back from its lanes, searching up to its limit.
#[inline(always)]
fn lane_ray(pk: &RayPacket, i: usize) -> Ray {
    pk.rays.ray(i)
}

/// The search records of a packet already in lanes (a world's rays entering an instance), one
/// per ray: [`Hit::none`] at the ray's limit to start, improved in place (any hit: set where
/// the ray hits something).
pub(crate) type InLanes<'a> = &'a mut [Hit];

/// The query `A` of packet `pk` over one node format, on the caller's lanes `V`, into `best`:
/// the packet walk without cutting and packing rays first. A ray the packet hands over to the
/// single-ray walk is read back from its lanes.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub(crate) fn in_lanes<N, V, A, B, P, S, F>(
    cpu: V::Cpu,
    nodes: &[N],
    leaves: &Leaves<P>,
    pk: &mut RayPacket,
    best: InLanes<'_>,
    stats: &mut S,
    filter: &mut F,
) where
    N: PacketNode,
    V: F8,
    A: Ask,
    B: BoxTest,
    P: Primitive,
    S: Stats,
    F: Filter<Hit>,
{
    trace_packet::<N, V, A, B, P, S, F>(cpu, nodes, leaves, lane_ray, pk, best, stats, filter)
}

/// The query `A` of one packet into `best` (one record per ray, [`Hit::none`] at its limit to
/// start; any hit reads no record, so its records may start unset). `ray(pk, i)` is ray `i` as the single-ray walk takes it when the packet hands it
/// over. Closest hit: a kept hit lowers its ray's limit. Any hit: a ray whose candidate is
/// kept retires, and the walk ends once every ray has; a rejected candidate leaves the ray
/// searching over its whole interval.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn trace_packet<N, V, A, B, P, S, F>(
    cpu: V::Cpu,
    nodes: &[N],
    leaves: &Leaves<P>,
    ray: impl Fn(&RayPacket, usize) -> Ray,
    pk: &mut RayPacket,
    best: &mut [Hit],
    stats: &mut S,
    filter: &mut F,
) where
    N: PacketNode,
    V: F8,
    A: Ask,
    B: BoxTest,
    P: Primitive,
    S: Stats,
    F: Filter<Hit>,
{
    // Every active ray's whole interval: an any-hit query never shortens one.
    let t_max = pk.rays.limit;
    walk::<N, V, B, S, _>(
        cpu,
        nodes,
        pk,
        stats,
        #[inline(always)]
        |first| leaves.prefetch(first),
        #[inline(always)]
        |pk, visit, stats| {
            let (range, b, cand) = match visit {
                Visit::Leaf(range, b, cand) => (range, b, cand),
                Visit::Alone(i, at) => {
                    let alone = ray(pk, i);
                    if A::ANY {
                        // Its record was never read before: the ray's whole interval.
                        best[i] = Hit::none(alone.t_max);
                    }
                    let found = match at {
                        AloneIn::Leaf(r) => {
                            let count = r.len() as u32;
                            leaves.test_checked::<V, A, S, F>(
                                cpu,
                                r.start,
                                count,
                                &alone,
                                &mut best[i],
                                stats,
                                filter,
                            )
                        }
                        AloneIn::Inner(node) => {
                            N::search_from::<V, A, B, P, S, F>(
                                cpu,
                                nodes,
                                leaves,
                                &alone,
                                node,
                                &mut best[i],
                                stats,
                                filter,
                            );
                            // An any-hit record is set only by a hit kept here: the ray
                            // would have retired before.
                            best[i].found().is_some()
                        }
                    };
                    if A::ANY {
                        if found {
                            pk.retire(i);
                        }
                        return pk.active == 0;
                    }
                    pk.set_limit(i, best[i].t);
                    return false;
                }
            };
            let live = pk.entering::<V, B>(cpu, b, cand);
            stats.prims(range.len() as u32);
            let mut kept = 0u64;
            test_leaf::<V, P, _>(
                cpu,
                leaves,
                range,
                pk,
                live,
                #[inline(always)]
                |i: usize, id: u32, h: PrimHit| {
                    if offer::<A, F>(&mut best[i], id, h, filter) {
                        kept |= 1 << i;
                        if A::ANY {
                            // Done: the ray takes no part in the rest of the leaf.
                            return None;
                        }
                    }
                    // Closest hit: the ray's limit, its best so far. Any hit (rejected):
                    // its whole interval.
                    Some(if A::ANY { lane(&t_max, i) } else { best[i].t })
                },
            );
            if kept == 0 {
                stats.empty_leaf();
            } else if A::ANY {
                for i in bits(kept) {
                    pk.retire(i);
                }
            } else {
                pk.refresh_limit_bound();
            }
            A::ANY && pk.active == 0
        },
    );
}
