//! A packet query: its rays cut into packets ([`super::each_packet`]), each packet walked
//! ([`super::walk`]) with its leaves tested ([`super::leaves`]), or, where the packet does not
//! pay, each ray through the single-ray walk; on the lanes of the BVH's instruction set,
//! chosen in one place for every node format.

use super::lanes::RayPacket;
use super::leaves::test_leaf;
use super::node::PacketNode;
use super::walk::{walk, AloneIn, Visit};
use super::PacketQuery;
use super::{each_packet, PACKET_RAYS};
use crate::geometry::{Hit, PrimHit, Ray};
use crate::isa::Kernels;
use crate::primitive::{lane, Primitive};
use crate::traverse::lane8::F8;
use crate::traverse::leaves::Leaves;
use crate::traverse::simd::bits;
use crate::traverse::{accepts, offer, BoxTest, Filter, Stats};
use wide::f32x8;

/// Closest hits of any number of rays, packet by packet, over one node format, in lanes of
/// `V`.
#[inline(always)]
fn closest_rays<N: PacketNode, V: F8, B: BoxTest, P: Primitive, S: Stats, F: Filter<Hit>>(
    cpu: V::Cpu,
    nodes: &[N],
    leaves: &Leaves<P>,
    query: PacketQuery<'_>,
    hits: &mut [Option<Hit>],
    stats: &mut S,
    filter: &mut F,
) {
    each_packet(
        query,
        hits,
        #[inline(always)]
        |rays, on, packet, hits| {
            if packet {
                let mut pk = RayPacket::new(rays, on);
                let mut best = [Hit::none(0.0); PACKET_RAYS];
                for (b, r) in best.iter_mut().zip(rays) {
                    *b = Hit::none(r.t_max);
                }
                closest_packet::<N, V, B, P, S, F>(
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
                for (i, (h, b)) in hits.iter_mut().zip(best).enumerate() {
                    *h = if on >> i & 1 == 1 { b.found() } else { None };
                }
            } else {
                for (i, (h, r)) in hits.iter_mut().zip(rays).enumerate() {
                    *h = if on >> i & 1 == 1 {
                        let mut best = Hit::none(r.t_max);
                        N::closest_from::<V, B, P, S, F>(
                            cpu, nodes, leaves, r, 0, &mut best, stats, filter,
                        );
                        best.found()
                    } else {
                        None
                    };
                }
            }
        },
    );
}

/// Any-hit answers of any number of rays, packet by packet, over one node format, in lanes
/// of `V`.
#[inline(always)]
fn any_rays<N: PacketNode, V: F8, B: BoxTest, P: Primitive, S: Stats, F: Filter<Hit>>(
    cpu: V::Cpu,
    nodes: &[N],
    leaves: &Leaves<P>,
    query: PacketQuery<'_>,
    occluded: &mut [bool],
    stats: &mut S,
    filter: &mut F,
) {
    each_packet(
        query,
        occluded,
        #[inline(always)]
        |rays, on, packet, out| {
            out.fill(false);
            if packet {
                let mut pk = RayPacket::new(rays, on);
                any_packet::<N, V, B, P, S, F>(
                    cpu,
                    nodes,
                    leaves,
                    #[inline(always)]
                    |_, i| rays[i],
                    &mut pk,
                    out,
                    stats,
                    filter,
                );
            } else {
                for (i, (o, r)) in out.iter_mut().zip(rays).enumerate() {
                    *o = on >> i & 1 == 1
                        && N::any_from::<V, B, P, S, F>(cpu, nodes, leaves, r, 0, stats, filter);
                }
            }
        },
    );
}

/// Ray `i` of `pk` read back from its lanes, searching up to its limit.
#[inline(always)]
fn lane_ray(pk: &RayPacket, i: usize) -> Ray {
    pk.rays.ray(i)
}

/// What a packet already in lanes asks of a BVH (a world's rays entering an instance).
pub(crate) enum InLanes<'a> {
    /// Closest hits into these records, one per ray ([`Hit::none`] at its limit to start).
    Closest(&'a mut [Hit]),
    /// Whether each ray hits anything: sets these flags (false to start).
    Any(&'a mut [bool]),
}

/// `ask` of packet `pk` over one node format, on the caller's lanes `V`: the packet walk
/// without cutting and packing rays first. A ray the packet hands over to the single-ray walk
/// is read back from its lanes.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub(crate) fn in_lanes<N: PacketNode, V: F8, B: BoxTest, P: Primitive, S: Stats, F: Filter<Hit>>(
    cpu: V::Cpu,
    nodes: &[N],
    leaves: &Leaves<P>,
    pk: &mut RayPacket,
    ask: InLanes<'_>,
    stats: &mut S,
    filter: &mut F,
) {
    match ask {
        InLanes::Closest(best) => closest_packet::<N, V, B, P, S, F>(
            cpu, nodes, leaves, lane_ray, pk, best, stats, filter,
        ),
        InLanes::Any(hit) => {
            any_packet::<N, V, B, P, S, F>(cpu, nodes, leaves, lane_ray, pk, hit, stats, filter)
        }
    }
}

/// Closest hits of one packet into `best` (one record per ray, [`Hit::none`] to start).
/// `ray(pk, i)` is ray `i` as the single-ray walk takes it when the packet hands it over.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn closest_packet<N: PacketNode, V: F8, B: BoxTest, P: Primitive, S: Stats, F: Filter<Hit>>(
    cpu: V::Cpu,
    nodes: &[N],
    leaves: &Leaves<P>,
    ray: impl Fn(&RayPacket, usize) -> Ray,
    pk: &mut RayPacket,
    best: &mut [Hit],
    stats: &mut S,
    filter: &mut F,
) {
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
                    match at {
                        AloneIn::Leaf(r) => {
                            let count = r.len() as u32;
                            leaves.closest(
                                r.start,
                                count,
                                &alone,
                                &mut None,
                                &mut best[i],
                                stats,
                                filter,
                            );
                        }
                        AloneIn::Inner(node) => N::closest_from::<V, B, P, S, F>(
                            cpu,
                            nodes,
                            leaves,
                            &alone,
                            node,
                            &mut best[i],
                            stats,
                            filter,
                        ),
                    }
                    pk.set_limit(i, best[i].t);
                    return false;
                }
            };
            let live = pk.entering::<V, B>(cpu, b, cand);
            stats.prims(range.len() as u32);
            let mut changed = false;
            test_leaf::<V, P, _>(
                cpu,
                leaves,
                range,
                pk,
                live,
                #[inline(always)]
                |i: usize, id: u32, h: PrimHit| {
                    changed |= offer(&mut best[i], id, h, filter);
                    Some(best[i].t)
                },
            );
            if changed {
                pk.refresh_limit_bound();
            } else {
                stats.empty_leaf();
            }
            false
        },
    );
}

/// Any-hit answers of one packet: sets `hit[i]` for every ray that hits something. `ray`
/// as for [`closest_packet`].
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn any_packet<N: PacketNode, V: F8, B: BoxTest, P: Primitive, S: Stats, F: Filter<Hit>>(
    cpu: V::Cpu,
    nodes: &[N],
    leaves: &Leaves<P>,
    ray: impl Fn(&RayPacket, usize) -> Ray,
    pk: &mut RayPacket,
    hit: &mut [bool],
    stats: &mut S,
    filter: &mut F,
) {
    // Every active ray's whole interval: an any-hit query never shortens one, and a ray
    // whose candidate the filter rejects searches on over all of it.
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
                    let found = match at {
                        AloneIn::Leaf(r) => {
                            let (first, n) = (r.start, r.len() as u32);
                            leaves.any(first, n, &alone, &mut None, stats, filter)
                        }
                        AloneIn::Inner(node) => N::any_from::<V, B, P, S, F>(
                            cpu, nodes, leaves, &alone, node, stats, filter,
                        ),
                    };
                    if found {
                        hit[i] = true;
                        pk.retire(i);
                    }
                    return pk.active == 0;
                }
            };
            let live = pk.entering::<V, B>(cpu, b, cand);
            stats.prims(range.len() as u32);
            let mut found = 0u64;
            test_leaf::<V, P, _>(
                cpu,
                leaves,
                range,
                pk,
                live,
                #[inline(always)]
                |i: usize, id: u32, h: PrimHit| {
                    if !accepts(id, h, filter) {
                        // Rejected: the ray searches on over its whole interval.
                        return Some(lane(&t_max, i));
                    }
                    hit[i] = true;
                    found |= 1 << i;
                    None
                },
            );
            for i in bits(found) {
                pk.retire(i);
            }
            if found == 0 {
                stats.empty_leaf();
            }
            pk.active == 0
        },
    );
}

/// [`closest_rays`] on `kernels`' lanes: the one place a packet query picks its instruction
/// set, for every node format.
#[inline]
pub(crate) fn closest_rays_on<N: PacketNode, B: BoxTest, P: Primitive, S: Stats, F: Filter<Hit>>(
    kernels: Kernels,
    nodes: &[N],
    leaves: &Leaves<P>,
    query: PacketQuery<'_>,
    hits: &mut [Option<Hit>],
    stats: &mut S,
    filter: &mut F,
) {
    match kernels {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: `cpu` proves the CPU has AVX2 and FMA (only detection makes one).
        Kernels::Avx2(cpu) => unsafe {
            avx2::closest_rays::<N, B, P, S, F>(cpu, nodes, leaves, query, hits, stats, filter)
        },
        _ => closest_rays::<N, f32x8, B, P, S, F>((), nodes, leaves, query, hits, stats, filter),
    }
}

/// [`any_rays`] on `kernels`' lanes (see [`closest_rays_on`]).
#[inline]
pub(crate) fn any_rays_on<N: PacketNode, B: BoxTest, P: Primitive, S: Stats, F: Filter<Hit>>(
    kernels: Kernels,
    nodes: &[N],
    leaves: &Leaves<P>,
    query: PacketQuery<'_>,
    occluded: &mut [bool],
    stats: &mut S,
    filter: &mut F,
) {
    match kernels {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: as in `closest_rays_on`.
        Kernels::Avx2(cpu) => unsafe {
            avx2::any_rays::<N, B, P, S, F>(cpu, nodes, leaves, query, occluded, stats, filter)
        },
        _ => any_rays::<N, f32x8, B, P, S, F>((), nodes, leaves, query, occluded, stats, filter),
    }
}

/// The packet kernels with their lanes on AVX2, compiled with AVX2 enabled (everything they
/// call is inlined into these).
#[cfg(target_arch = "x86_64")]
mod avx2 {
    use super::*;
    use crate::isa::Avx2Cpu;
    use crate::traverse::lane8::Avx;

    /// # Safety
    /// The CPU must support AVX2 and FMA (as `cpu` proves).
    #[target_feature(enable = "avx2,fma")]
    pub(super) unsafe fn closest_rays<
        N: PacketNode,
        B: BoxTest,
        P: Primitive,
        S: Stats,
        F: Filter<Hit>,
    >(
        cpu: Avx2Cpu,
        nodes: &[N],
        leaves: &Leaves<P>,
        query: PacketQuery<'_>,
        hits: &mut [Option<Hit>],
        stats: &mut S,
        filter: &mut F,
    ) {
        super::closest_rays::<N, Avx, B, P, S, F>(cpu, nodes, leaves, query, hits, stats, filter)
    }

    /// # Safety
    /// The CPU must support AVX2 and FMA (as `cpu` proves).
    #[target_feature(enable = "avx2,fma")]
    pub(super) unsafe fn any_rays<
        N: PacketNode,
        B: BoxTest,
        P: Primitive,
        S: Stats,
        F: Filter<Hit>,
    >(
        cpu: Avx2Cpu,
        nodes: &[N],
        leaves: &Leaves<P>,
        query: PacketQuery<'_>,
        occluded: &mut [bool],
        stats: &mut S,
        filter: &mut F,
    ) {
        super::any_rays::<N, Avx, B, P, S, F>(cpu, nodes, leaves, query, occluded, stats, filter)
    }
}
