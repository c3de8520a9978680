//! What a packet does at a leaf: the primitive type's packet test
//! ([`crate::Primitive::intersect_packet`]) over the rays that enter the leaf, through a
//! [`PacketLeaf`]; and the triangle's own 8-lane test.

use super::lanes::RayPacket;
use super::node::PacketNode;
use super::walk::{walk, AloneIn, Visit};
use super::{CHUNKS, LANES};
use crate::geometry::{Hit, PrimHit, Ray};
use crate::layout::Tri4;
use crate::primitive::{LeafFormat, Primitive};
use crate::primitive::{PacketLeaf, PacketRays};
use crate::traverse::lane8::F8;
use crate::traverse::simd::bits;
use crate::traverse::tri4::{group_hits, Leaves, Ray4Tri};
use crate::traverse::{BoxTest, Stats};
use std::ops::Range;

/// Runs the leaf `range` (primitives, or groups holding `range.len()` triangles) for the
/// `live` rays of the packet, answering hits with `on_hit`.
#[inline(always)]
fn test_leaf<V: F8, P: Primitive, F>(
    leaves: &Leaves<P>,
    range: Range<usize>,
    packet: &mut RayPacket,
    live: u64,
    on_hit: F,
) where
    F: FnMut(usize, u32, PrimHit) -> Option<f32>,
{
    let ids = match P::LEAF_FORMAT {
        LeafFormat::Plain => &leaves.ids[range.clone()],
        _ => &[],
    };
    let mut leaf = PacketLeaf {
        packet: &mut packet.rays,
        live,
        ids,
        on_hit,
    };
    match P::LEAF_FORMAT {
        LeafFormat::Plain => P::intersect_packet(&leaves.prims[range], &mut leaf),
        format => groups_packet::<V, F>(
            leaves.groups(range.start, range.len() as u32),
            format,
            &mut leaf,
        ),
    }
}

/// Closest hits of one packet into `best` (one record per ray, [`Hit::none`] to start).
#[inline(always)]
pub(super) fn closest_packet<N: PacketNode, V: F8, B: BoxTest, P: Primitive, S: Stats>(
    nodes: &[N],
    leaves: &Leaves<P>,
    rays: &[Ray],
    pk: &mut RayPacket,
    best: &mut [Hit],
    stats: &mut S,
) {
    walk::<N, V, B, S, _>(
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
                    match at {
                        AloneIn::Leaf(r) => {
                            let count = r.len() as u32;
                            leaves.closest(
                                r.start,
                                count,
                                &rays[i],
                                &mut None,
                                &mut best[i],
                                stats,
                            );
                        }
                        AloneIn::Inner(node) => N::closest_from::<V, B, P, S>(
                            nodes,
                            leaves,
                            &rays[i],
                            node,
                            &mut best[i],
                            stats,
                        ),
                    }
                    pk.set_limit(i, best[i].t);
                    return false;
                }
            };
            let live = pk.entering::<V, B>(b, cand);
            stats.prims(range.len() as u32);
            let mut changed = false;
            test_leaf::<V, P, _>(
                leaves,
                range,
                pk,
                live,
                #[inline(always)]
                |i: usize, id: u32, h: PrimHit| {
                    changed |= best[i].offer(id, h);
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

/// Any-hit answers of one packet: sets `hit[i]` for every ray that hits something.
#[inline(always)]
pub(super) fn any_packet<N: PacketNode, V: F8, B: BoxTest, P: Primitive, S: Stats>(
    nodes: &[N],
    leaves: &Leaves<P>,
    rays: &[Ray],
    pk: &mut RayPacket,
    hit: &mut [bool],
    stats: &mut S,
) {
    walk::<N, V, B, S, _>(
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
                    let found = match at {
                        AloneIn::Leaf(r) => {
                            leaves.any(r.start, r.len() as u32, &rays[i], &mut None, stats)
                        }
                        AloneIn::Inner(node) => {
                            N::any_from::<V, B, P, S>(nodes, leaves, &rays[i], node, stats)
                        }
                    };
                    if found {
                        hit[i] = true;
                        pk.retire(i);
                    }
                    return pk.active == 0;
                }
            };
            let live = pk.entering::<V, B>(b, cand);
            stats.prims(range.len() as u32);
            let mut found = 0u64;
            test_leaf::<V, P, _>(
                leaves,
                range,
                pk,
                live,
                #[inline(always)]
                |i: usize, _, _| {
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

/// One triangle's test over the live rays of a leaf, eight at a time: `test(packet, k)` gives
/// the mask of chunk `k`'s rays it hits and their `t`, `u`, `v`; the hits are reported as
/// primitive `id`'s.
#[inline(always)]
fn chunks_packet<V: F8, F>(
    id: u32,
    rays: &mut PacketLeaf<'_, F>,
    test: impl Fn(&PacketRays, usize) -> (u32, V, V, V),
) where
    F: FnMut(usize, u32, PrimHit) -> Option<f32>,
{
    for k in 0..CHUNKS {
        let lanes = (rays.live >> (LANES * k)) as u32 & 0xFF;
        if lanes == 0 {
            continue;
        }
        let (ok, t, u, v) = test(rays.packet, k);
        let ok = ok & lanes;
        if ok == 0 {
            continue;
        }
        let (t, u, v) = (t.to_array(), u.to_array(), v.to_array());
        for l in bits(ok) {
            let hit = PrimHit {
                t: t[l],
                u: u[l],
                v: v[l],
            };
            rays.report_id(LANES * k + l, id, hit);
        }
    }
}

/// A leaf of SIMD groups for a packet. Fast groups: triangle by triangle, eight rays at a
/// time in lanes of `V` ([`group_lane8`]). Watertight groups: ray by ray through the single-ray
/// group test (four triangles per SIMD test), whose shear depends on the ray's largest
/// direction axis, which eight rays need not share.
#[inline(always)]
fn groups_packet<V: F8, F>(groups: &[Tri4], format: LeafFormat, rays: &mut PacketLeaf<'_, F>)
where
    F: FnMut(usize, u32, PrimHit) -> Option<f32>,
{
    if format == LeafFormat::WatertightTriangles {
        for i in bits(rays.live) {
            let ray = rays.ray(i);
            let r = Ray4Tri::new(&ray, format);
            for g in groups {
                if rays.live >> i & 1 == 0 {
                    break;
                }
                let limit = rays.packet.limit(i);
                let mut found = [None; 4];
                let ray = Ray {
                    t_max: limit,
                    ..ray
                };
                group_hits(
                    g,
                    &r,
                    &ray,
                    limit,
                    format,
                    #[inline(always)]
                    |l, h| found[l] = Some(h),
                );
                for (l, h) in found.into_iter().enumerate() {
                    if let Some(h) = h {
                        rays.report_id(i, g.id[l], h);
                    }
                }
            }
        }
        return;
    }
    for g in groups {
        for (l, &id) in g.id.iter().enumerate() {
            if id == u32::MAX || rays.live == 0 {
                continue;
            }
            chunks_packet::<V, F>(
                id,
                rays,
                #[inline(always)]
                |pk, k| group_lane8::<V>(g, l, pk, k),
            );
        }
    }
}

/// `(a.x·b.x + a.y·b.y) + a.z·b.z`, glam's order.
#[inline(always)]
fn dot3<V: F8>(a: [V; 3], b: [V; 3]) -> V {
    a[0].mul(b[0]).add(a[1].mul(b[1])).add(a[2].mul(b[2]))
}

/// Lane `l` of a fast-format group against the eight rays of chunk `k`, in the operations of
/// the single-ray group test (`tri4::fast4`: glam's dot and cross orders, nothing fused), so
/// each ray gets the single-ray result. Returns the mask of rays hit within
/// `[t_min, limit]` and their `t`, `u`, `v`.
#[inline(always)]
fn group_lane8<V: F8>(g: &Tri4, l: usize, pk: &PacketRays, k: usize) -> (u32, V, V, V) {
    let row = |v: usize| V::splat3([g.rows[v][0][l], g.rows[v][1][l], g.rows[v][2][l]]);
    let (v0, e1, e2, n) = (row(0), row(1), row(2), row(3));
    let (dx, dy, dz) = (V::of(&pk.d[0][k]), V::of(&pk.d[1][k]), V::of(&pk.d[2][k]));
    let det = dot3(n, [dx, dy, dz]);
    let inv = V::splat(1.0).div(det);
    let cx = v0[0].sub(V::of(&pk.o[0][k]));
    let cy = v0[1].sub(V::of(&pk.o[1][k]));
    let cz = v0[2].sub(V::of(&pk.o[2][k]));
    let r = [
        dy.mul(cz).sub(cy.mul(dz)),
        dz.mul(cx).sub(cz.mul(dx)),
        dx.mul(cy).sub(cx.mul(dy)),
    ];
    let u = dot3(r, e2).mul(inv);
    let v = dot3(r, e1).mul(inv);
    let t = dot3(n, [cx, cy, cz]).mul(inv);
    let zero = V::splat(0.0);
    let ok = det
        .ne(zero)
        .and(u.ge(zero))
        .and(v.ge(zero))
        .and(u.add(v).le(V::splat(1.0)))
        .and(t.ge(V::of(&pk.t_min[k])))
        .and(t.le(V::of(&pk.limit[k])));
    (ok.bitmask(), t, u, v)
}
