//! What a packet does at a leaf: the primitive type's packet test
//! ([`crate::Primitive::intersect_packet`]) over the rays that enter the leaf, through a
//! [`PacketLeaf`]; and the triangle's own 8-lane test.

use super::lanes::RayPacket;
use super::walk::{walk, AloneIn, Visit};
use super::{CHUNKS, LANES};
use crate::geometry::{Hit, PrimHit, Primitive, Ray, Triangle};
use crate::traverse::bvh4::{self, WideNode};
use crate::traverse::simd::bits;
use crate::traverse::{leaf_any_hit, leaf_closest_hit, BoxTest, Stats};
use wide::f32x8;

/// The rays of a packet that enter one leaf, as a primitive type's packet test
/// ([`crate::Primitive::intersect_packet`]) sees them: which rays still search, each ray
/// within its current interval, and where to report hits.
pub struct PacketLeaf<'a, F> {
    pub(crate) packet: &'a mut RayPacket,
    live: u64,
    on_hit: F,
}

impl<F: FnMut(usize, usize, PrimHit) -> Option<f32>> PacketLeaf<'_, F> {
    /// The rays still searching this leaf: bit `i` for ray `i` of the packet.
    #[inline(always)]
    pub fn rays(&self) -> u64 {
        self.live
    }

    /// Ray `i` as it searches now: `t_max` is its current limit (in a closest-hit query, the
    /// nearest hit so far).
    #[inline(always)]
    pub fn ray(&self, i: usize) -> Ray {
        self.packet.ray(i)
    }

    /// Ray `i` hits primitive `j` of the leaf at `hit`: a closest-hit query shortens the ray
    /// to its nearest hit so far, an any-hit query takes the ray out of [`PacketLeaf::rays`].
    #[inline(always)]
    pub fn report(&mut self, i: usize, j: usize, hit: PrimHit) {
        match (self.on_hit)(i, j, hit) {
            Some(limit) => self.packet.set_limit(i, limit),
            None => {
                self.packet.set_limit(i, f32::NEG_INFINITY);
                self.live &= !(1 << i);
            }
        }
    }
}

/// Closest hits of one packet into `best` (one record per ray, [`Hit::none`] to start).
#[inline(always)]
pub(super) fn closest_packet<N: WideNode, B: BoxTest, P: Primitive, S: Stats>(
    nodes: &[N],
    prims: &[P],
    ids: &[u32],
    rays: &[Ray],
    pk: &mut RayPacket,
    best: &mut [Hit],
    stats: &mut S,
) {
    walk::<N, B, S, _>(nodes, pk, stats, |pk, visit, stats| {
        let (range, b, cand) = match visit {
            Visit::Leaf(range, b, cand) => (range, b, cand),
            Visit::Alone(i, at) => {
                match at {
                    AloneIn::Leaf(r) => {
                        leaf_closest_hit(&prims[r.clone()], &ids[r], &rays[i], &mut best[i], stats);
                    }
                    AloneIn::Inner(node) => bvh4::closest_from::<N, B, P, S>(
                        nodes,
                        prims,
                        ids,
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
        let live = pk.entering::<B>(b, cand);
        stats.prims(range.len() as u32);
        let ids = &ids[range.clone()];
        let mut changed = false;
        let mut leaf = PacketLeaf {
            packet: pk,
            live,
            on_hit: |i: usize, j: usize, h: PrimHit| {
                if best[i].is_beaten_by(h.t, ids[j]) {
                    best[i] = Hit {
                        t: h.t,
                        prim: ids[j],
                        u: h.u,
                        v: h.v,
                    };
                    changed = true;
                }
                Some(best[i].t)
            },
        };
        P::intersect_packet(&prims[range], &mut leaf);
        if changed {
            pk.refresh_limit_bound();
        } else {
            stats.empty_leaf();
        }
        false
    });
}

/// Any-hit answers of one packet: sets `hit[i]` for every ray that hits something.
#[inline(always)]
pub(super) fn any_packet<N: WideNode, B: BoxTest, P: Primitive, S: Stats>(
    nodes: &[N],
    prims: &[P],
    rays: &[Ray],
    pk: &mut RayPacket,
    hit: &mut [bool],
    stats: &mut S,
) {
    walk::<N, B, S, _>(nodes, pk, stats, |pk, visit, stats| {
        let (range, b, cand) = match visit {
            Visit::Leaf(range, b, cand) => (range, b, cand),
            Visit::Alone(i, at) => {
                let found = match at {
                    AloneIn::Leaf(r) => leaf_any_hit(&prims[r], &rays[i], stats),
                    AloneIn::Inner(node) => {
                        bvh4::any_from::<N, B, P, S>(nodes, prims, &rays[i], node, stats)
                    }
                };
                if found {
                    hit[i] = true;
                    pk.retire(i);
                }
                return pk.active == 0;
            }
        };
        let live = pk.entering::<B>(b, cand);
        stats.prims(range.len() as u32);
        let mut found = 0u64;
        let mut leaf = PacketLeaf {
            packet: pk,
            live,
            on_hit: |i: usize, _, _| {
                hit[i] = true;
                found |= 1 << i;
                None
            },
        };
        P::intersect_packet(&prims[range], &mut leaf);
        for i in bits(found) {
            pk.retire(i);
        }
        if found == 0 {
            stats.empty_leaf();
        }
        pk.active == 0
    });
}

/// A triangle's ray-independent terms, splatted once per packet test.
struct TriSetup {
    v0: [f32x8; 3],
    e1: [f32x8; 3],
    e2: [f32x8; 3],
    n: [f32x8; 3],
}

impl TriSetup {
    #[inline(always)]
    fn new(tri: &Triangle) -> Self {
        // The same vectors (and glam arithmetic) as `Triangle::intersect`.
        let e1 = tri.v[0] - tri.v[1];
        let e2 = tri.v[2] - tri.v[0];
        let n = e1.cross(e2);
        let splat = |v: glam::Vec3A| [v.x, v.y, v.z].map(f32x8::splat);
        TriSetup {
            v0: splat(tri.v[0]),
            e1: splat(e1),
            e2: splat(e2),
            n: splat(n),
        }
    }

    /// Möller–Trumbore for the eight rays of chunk `k` of `pk`, operation for operation as
    /// [`Triangle::intersect`] computes it for one ray (glam's `cross` and `dot` orders, fused
    /// where glam fuses), so every lane gets the single-ray result. Returns the mask of lanes
    /// hit within `[t_min, limit]` and their `t`, `u`, `v`.
    #[inline(always)]
    fn intersect8(&self, pk: &RayPacket, k: usize) -> (u32, f32x8, f32x8, f32x8) {
        let [dx, dy, dz] = [0, 1, 2].map(|a| pk.d[a][k]);
        let [nx, ny, nz] = self.n;
        let det = (nx * dx + ny * dy) + nz * dz;
        let inv = f32x8::ONE / det;
        let [cx, cy, cz] = [0, 1, 2].map(|a| self.v0[a] - pk.o[a][k]);
        // d × c, as glam writes it: (a.y·b.z − b.y·a.z, …) with the second product fused
        // into the subtraction when the target has FMA.
        let rx = cy.mul_neg_add(dz, dy * cz);
        let ry = cz.mul_neg_add(dx, dz * cx);
        let rz = cx.mul_neg_add(dy, dx * cy);
        let [e1x, e1y, e1z] = self.e1;
        let [e2x, e2y, e2z] = self.e2;
        let u = ((rx * e2x + ry * e2y) + rz * e2z) * inv;
        let v = ((rx * e1x + ry * e1y) + rz * e1z) * inv;
        let t = ((nx * cx + ny * cy) + nz * cz) * inv;
        let ok = det.simd_ne(f32x8::ZERO)
            & u.simd_ge(f32x8::ZERO)
            & v.simd_ge(f32x8::ZERO)
            & (u + v).simd_le(f32x8::ONE)
            & t.simd_ge(pk.t_min[k])
            & t.simd_le(pk.limit[k]);
        (ok.to_bitmask(), t, u, v)
    }
}

/// [`Triangle`]'s packet test: triangle by triangle, eight rays at a time, each lane exactly
/// [`Triangle::intersect`]; a hit shortens (or ends) its ray before the next triangle.
#[inline(always)]
pub(crate) fn triangles_packet<F>(leaf: &[Triangle], rays: &mut PacketLeaf<'_, F>)
where
    F: FnMut(usize, usize, PrimHit) -> Option<f32>,
{
    for (j, tri) in leaf.iter().enumerate() {
        if rays.live == 0 {
            break;
        }
        let setup = TriSetup::new(tri);
        for k in 0..CHUNKS {
            let lanes = (rays.live >> (LANES * k)) as u32 & 0xFF;
            if lanes == 0 {
                continue;
            }
            let (ok, t, u, v) = setup.intersect8(rays.packet, k);
            let ok = ok & lanes;
            if ok == 0 {
                continue;
            }
            let (t, u, v) = (t.as_array(), u.as_array(), v.as_array());
            for l in bits(ok) {
                let hit = PrimHit {
                    t: t[l],
                    u: u[l],
                    v: v[l],
                };
                rays.report(LANES * k + l, j, hit);
            }
        }
    }
}
