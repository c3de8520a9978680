//! What a packet does at a leaf: the primitive type's packet test
//! ([`crate::Primitive::intersect_packet`]) over the rays that enter the leaf, through a
//! [`PacketLeaf`]; for triangle formats, the [`Tri4`] groups eight rays at a time.

use super::lanes::RayPacket;
use super::{CHUNKS, LANES};
use crate::geometry::{PrimHit, Ray};
use crate::layout::Tri4;
use crate::primitive::{LeafFormat, PacketLeaf, PacketRays, Primitive};
use crate::traverse::lane8::F8;
use crate::traverse::leaves::Leaves;
use crate::traverse::simd::bits;
use crate::traverse::tri4::{group_hits, LeafGroups, Ray4Tri};
use std::ops::Range;

/// Runs the leaf `range` (primitives, or groups holding `range.len()` triangles) for the
/// `live` rays of the packet, answering hits with `on_hit`.
#[inline(always)]
pub(super) fn test_leaf<V: F8, P: Primitive, F>(
    cpu: V::Cpu,
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
        format => {
            let groups = (
                leaves.groups(range.start, range.len() as u32),
                range.start,
                leaves.far,
            );
            if leaves.far.any() {
                // Out of the fast path's line, on the portable lanes (as `dispatch` runs a
                // layout holding far groups).
                groups_packet_far::<F>(groups, format, &mut leaf);
            } else {
                groups_packet::<V, F, false>(cpu, groups, format, &mut leaf);
            }
        }
    }
}

/// [`groups_packet`] for a layout holding far groups ([`Tri4`]), out of the fast path's line.
#[cold]
#[inline(never)]
fn groups_packet_far<F>(groups: LeafGroups<'_>, format: LeafFormat, rays: &mut PacketLeaf<'_, F>)
where
    F: FnMut(usize, u32, PrimHit) -> Option<f32>,
{
    groups_packet::<wide::f32x8, F, true>((), groups, format, rays)
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
/// direction axis, which eight rays need not share. `FAR`: the layout holds far groups, which
/// every live ray tests lane by lane with the scalar test.
#[inline(always)]
fn groups_packet<V: F8, F, const FAR: bool>(
    cpu: V::Cpu,
    (groups, first, far): LeafGroups<'_>,
    format: LeafFormat,
    rays: &mut PacketLeaf<'_, F>,
) where
    F: FnMut(usize, u32, PrimHit) -> Option<f32>,
{
    let is_far = |i: usize| FAR && far.has(first + i);
    if format == LeafFormat::WatertightTriangles {
        for i in bits(rays.live) {
            let ray = rays.ray(i);
            let r = Ray4Tri::new(&ray, format);
            for (j, g) in groups.iter().enumerate() {
                if rays.live >> i & 1 == 0 {
                    break;
                }
                group_for_ray::<F, FAR>((g, is_far(j)), i, &ray, &r, format, rays);
            }
        }
        return;
    }
    for (j, g) in groups.iter().enumerate() {
        if is_far(j) {
            for i in bits(rays.live) {
                if rays.live >> i & 1 == 0 {
                    continue;
                }
                let ray = rays.ray(i);
                let r = Ray4Tri::new(&ray, format);
                group_for_ray::<F, true>((g, true), i, &ray, &r, format, rays);
            }
            continue;
        }
        for (l, &id) in g.id.iter().enumerate() {
            if id == u32::MAX || rays.live == 0 {
                continue;
            }
            chunks_packet::<V, F>(
                id,
                rays,
                #[inline(always)]
                |pk, k| group_lane8::<V>(cpu, g, l, pk, k),
            );
        }
    }
}

/// One group for packet ray `i` (`ray`, its group terms `r`) through the single-ray group
/// test, which takes a far group lane by lane when `FAR`; the hits reported as the lanes' ids.
#[inline(always)]
fn group_for_ray<F, const FAR: bool>(
    (g, far): (&Tri4, bool),
    i: usize,
    ray: &Ray,
    r: &Ray4Tri,
    format: LeafFormat,
    rays: &mut PacketLeaf<'_, F>,
) where
    F: FnMut(usize, u32, PrimHit) -> Option<f32>,
{
    let limit = rays.packet.limit(i);
    let ray = Ray {
        t_max: limit,
        ..*ray
    };
    let mut found = [None; 4];
    group_hits::<FAR>(
        (g, far),
        r,
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
fn group_lane8<V: F8>(
    cpu: V::Cpu,
    g: &Tri4,
    l: usize,
    pk: &PacketRays,
    k: usize,
) -> (u32, V, V, V) {
    let row = |v: usize| V::splat3(cpu, [g.rows[v][0][l], g.rows[v][1][l], g.rows[v][2][l]]);
    let (v0, e1, e2) = (row(0), row(1), row(2));
    let n = [
        e1[1].mul(e2[2]).sub(e1[2].mul(e2[1])),
        e1[2].mul(e2[0]).sub(e1[0].mul(e2[2])),
        e1[0].mul(e2[1]).sub(e1[1].mul(e2[0])),
    ];
    let (dx, dy, dz) = (
        V::of(cpu, &pk.d[0][k]),
        V::of(cpu, &pk.d[1][k]),
        V::of(cpu, &pk.d[2][k]),
    );
    let det = dot3(n, [dx, dy, dz]);
    let inv = V::splat(cpu, 1.0).div(det);
    let cx = v0[0].sub(V::of(cpu, &pk.o[0][k]));
    let cy = v0[1].sub(V::of(cpu, &pk.o[1][k]));
    let cz = v0[2].sub(V::of(cpu, &pk.o[2][k]));
    let r = [
        dy.mul(cz).sub(cy.mul(dz)),
        dz.mul(cx).sub(cz.mul(dx)),
        dx.mul(cy).sub(cx.mul(dy)),
    ];
    let u = dot3(r, e2).mul(inv);
    let v = dot3(r, e1).mul(inv);
    let t = dot3(n, [cx, cy, cz]).mul(inv);
    let zero = V::splat(cpu, 0.0);
    let ok = det
        .ne(zero)
        .and(u.ge(zero))
        .and(v.ge(zero))
        .and(u.add(v).le(V::splat(cpu, 1.0)))
        .and(t.ge(V::of(cpu, &pk.t_min[k])))
        .and(t.le(V::of(cpu, &pk.limit[k])));
    (ok.bitmask(), t, u, v)
}
