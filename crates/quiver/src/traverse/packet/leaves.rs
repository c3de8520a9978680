//! What a packet does at a leaf: the primitive type's packet test
//! ([`crate::Primitive::intersect_packet`]) over the rays that enter the leaf, through a
//! [`PacketLeaf`]; and the triangle's own 8-lane test.

use super::lanes::{ray_rows, RayPacket};
use super::node::PacketNode;
use super::walk::{walk, AloneIn, Visit};
use super::{CHUNKS, LANES};
use crate::geometry::{Hit, LeafFormat, PrimHit, Primitive, Ray, Triangle};
use crate::layout::Tri4;
use crate::traverse::lane8::F8;
use crate::traverse::simd::bits;
use crate::traverse::tri4::{group_hits, Leaves, Ray4Tri};
use crate::traverse::{BoxTest, Stats};
use std::ops::Range;
use wide::f32x8;

/// The rays of a packet that enter one leaf, as a primitive type's packet test
/// ([`crate::Primitive::intersect_packet`]) sees them: which rays still search, each ray
/// within its current interval, and where to report hits.
pub struct PacketLeaf<'a, F> {
    pub(crate) packet: &'a mut RayPacket,
    live: u64,
    /// The leaf's primitive ids (plain leaves; SIMD groups carry their own).
    ids: &'a [u32],
    on_hit: F,
}

impl<F: FnMut(usize, u32, PrimHit) -> Option<f32>> PacketLeaf<'_, F> {
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

    /// Rays `8k .. 8k + 8` of the packet in SIMD lanes, for a primitive's own eight-ray test
    /// (`k` in `0..PACKET_RAYS / 8`): lane `l` holds ray `8k + l` as [`PacketLeaf::ray`]
    /// gives it. Lanes of rays that stopped searching hold `t_max = -inf`.
    /// [`PacketLeaf::test_lanes`] runs such a test over a whole packet.
    #[inline(always)]
    pub fn lanes(&self, k: usize) -> PacketLanes {
        let p = &*self.packet;
        PacketLanes {
            origin: [p.o[0][k], p.o[1][k], p.o[2][k]],
            dir: [p.d[0][k], p.d[1][k], p.d[2][k]],
            t_min: p.t_min[k],
            t_max: p.limit[k],
            live: (self.live >> (LANES * k)) as u32 & 0xFF,
        }
    }

    /// Runs `test`, an eight-ray test of primitive `j` of the leaf, over the rays still
    /// searching, eight at a time ([`PacketLeaf::lanes`]), and reports its hits. `test` gives
    /// the lanes that hit and their `t`, `u` and `v`; lanes that do not search are ignored.
    ///
    /// A unit square at `z = 0` tested eight rays at a time:
    ///
    /// ```
    /// use quiver::traverse::{FastBoxes, NoStats, PacketLeaf, PacketMode};
    /// use quiver::{Aabb, Bvh, PrimHit, Primitive, Ray, RayQuery};
    /// use glam::Vec3A;
    /// use wide::f32x8;
    ///
    /// #[derive(Clone)]
    /// struct Square;
    /// impl Primitive for Square {
    ///     fn bounds(&self) -> Aabb {
    ///         Aabb::new(Vec3A::new(0.0, 0.0, 0.0), Vec3A::new(1.0, 1.0, 0.0))
    ///     }
    ///     fn intersect(&self, r: &Ray) -> Option<PrimHit> {
    ///         let t = -r.origin.z / r.dir.z;
    ///         let (x, y) = (r.origin.x + t * r.dir.x, r.origin.y + t * r.dir.y);
    ///         let inside = (0.0..=1.0).contains(&x) && (0.0..=1.0).contains(&y);
    ///         (inside && t >= r.t_min && t <= r.t_max).then_some(PrimHit { t, u: x, v: y })
    ///     }
    ///     fn intersect_packet<F>(leaf: &[Self], rays: &mut PacketLeaf<'_, F>)
    ///     where
    ///         F: FnMut(usize, u32, PrimHit) -> Option<f32>,
    ///     {
    ///         let (zero, one) = (f32x8::splat(0.0), f32x8::splat(1.0));
    ///         for j in 0..leaf.len() {
    ///             rays.test_lanes(j, |l| {
    ///                 // The scalar test's operations, lane by lane.
    ///                 let t = -l.origin[2] / l.dir[2];
    ///                 let x = l.origin[0] + t * l.dir[0];
    ///                 let y = l.origin[1] + t * l.dir[1];
    ///                 let ok = x.simd_ge(zero) & x.simd_le(one) & y.simd_ge(zero)
    ///                     & y.simd_le(one) & t.simd_ge(l.t_min) & t.simd_le(l.t_max);
    ///                 (ok.to_bitmask(), [t, x, y])
    ///             });
    ///         }
    ///     }
    /// }
    ///
    /// let bvh = Bvh::new(&[Square]);
    /// let rays: Vec<Ray> = (0..16)
    ///     .map(|i| Ray::new(Vec3A::new(i as f32 / 10.0, 0.5, 1.0), -Vec3A::Z))
    ///     .collect();
    /// let mut hits = vec![None; rays.len()];
    /// bvh.closest_hit_packet_with::<FastBoxes, NoStats>(
    ///     &rays, None, PacketMode::Always, &mut hits, &mut NoStats,
    /// );
    /// for (r, h) in rays.iter().zip(&hits) {
    ///     assert_eq!(*h, bvh.closest_hit(r));
    /// }
    /// assert_eq!(hits.iter().filter(|h| h.is_some()).count(), 11);
    /// ```
    #[inline(always)]
    pub fn test_lanes(
        &mut self,
        j: usize,
        mut test: impl FnMut(&PacketLanes) -> (u32, [f32x8; 3]),
    ) {
        for k in 0..CHUNKS {
            let l = self.lanes(k);
            if l.live == 0 {
                continue;
            }
            let (hit, [t, u, v]) = test(&l);
            let hit = hit & l.live;
            if hit == 0 {
                continue;
            }
            let (t, u, v) = (t.to_array(), u.to_array(), v.to_array());
            for lane in bits(hit) {
                let h = PrimHit {
                    t: t[lane],
                    u: u[lane],
                    v: v[lane],
                };
                self.report(LANES * k + lane, j, h);
            }
        }
    }

    /// Ray `i` hits primitive `j` of the leaf at `hit`: a closest-hit query shortens the ray
    /// to its nearest hit so far, an any-hit query takes the ray out of [`PacketLeaf::rays`].
    #[inline(always)]
    pub fn report(&mut self, i: usize, j: usize, hit: PrimHit) {
        self.report_id(i, self.ids[j], hit)
    }

    /// [`PacketLeaf::report`] by the primitive's input index.
    #[inline(always)]
    fn report_id(&mut self, i: usize, id: u32, hit: PrimHit) {
        match (self.on_hit)(i, id, hit) {
            Some(limit) => self.packet.set_limit(i, limit),
            None => {
                self.packet.set_limit(i, f32::NEG_INFINITY);
                self.live &= !(1 << i);
            }
        }
    }
}

/// Eight rays of a packet in SIMD lanes ([`PacketLeaf::lanes`]).
#[derive(Clone, Copy, Debug)]
pub struct PacketLanes {
    /// Origins, one `f32x8` per axis.
    pub origin: [f32x8; 3],
    /// Directions, one `f32x8` per axis.
    pub dir: [f32x8; 3],
    /// Smallest accepted hit distances.
    pub t_min: f32x8,
    /// Largest accepted hit distances now: `t_max`, in a closest-hit query the nearest hit so
    /// far, `-inf` for a ray that stopped searching.
    pub t_max: f32x8,
    /// Bit `l` set: ray `8k + l` still searches this leaf.
    pub live: u32,
}

impl PacketLanes {
    /// Eight rays as lanes, every one live: what [`PacketLeaf::lanes`] hands a test, for
    /// testing an eight-ray test against its scalar twin.
    ///
    /// ```
    /// use quiver::traverse::PacketLanes;
    /// use quiver::Ray;
    /// use glam::Vec3A;
    /// let rays: [Ray; 8] = std::array::from_fn(|i| Ray::new(Vec3A::ZERO, Vec3A::X * i as f32));
    /// let lanes = PacketLanes::from_rays(&rays);
    /// assert_eq!(lanes.ray(5), rays[5]);
    /// assert_eq!(lanes.live, 0xFF);
    /// ```
    pub fn from_rays(rays: &[Ray; LANES]) -> PacketLanes {
        let f = ray_rows(rays);
        PacketLanes {
            origin: [f[0], f[1], f[2]],
            dir: [f[3], f[4], f[5]],
            t_min: f[6],
            t_max: f[7],
            live: 0xFF,
        }
    }

    /// Lane `l` (`0..8`) as a ray, within its current interval.
    #[inline]
    pub fn ray(&self, l: usize) -> Ray {
        let at = |v: &f32x8| v.to_array()[l];
        Ray::segment(
            glam::Vec3A::new(
                at(&self.origin[0]),
                at(&self.origin[1]),
                at(&self.origin[2]),
            ),
            glam::Vec3A::new(at(&self.dir[0]), at(&self.dir[1]), at(&self.dir[2])),
            at(&self.t_min),
            at(&self.t_max),
        )
    }
}

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
        packet,
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

/// One triangle's test over the live rays of a leaf, eight at a time: `test(packet, k)` gives
/// the mask of chunk `k`'s rays it hits and their `t`, `u`, `v`; the hits are reported as
/// primitive `id`'s.
#[inline(always)]
fn chunks_packet<V: F8, F>(
    id: u32,
    rays: &mut PacketLeaf<'_, F>,
    test: impl Fn(&RayPacket, usize) -> (u32, V, V, V),
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

/// [`Triangle`]'s packet test: triangle by triangle, eight rays at a time, each lane exactly
/// [`Triangle::intersect`]; a hit shortens (or ends) its ray before the next triangle.
#[inline(always)]
pub(crate) fn triangles_packet<F>(leaf: &[Triangle], rays: &mut PacketLeaf<'_, F>)
where
    F: FnMut(usize, u32, PrimHit) -> Option<f32>,
{
    for (j, tri) in leaf.iter().enumerate() {
        if rays.live == 0 {
            break;
        }
        let (id, setup) = (rays.ids[j], TriSetup::new(tri));
        chunks_packet::<f32x8, F>(id, rays, |pk, k| setup.intersect8(pk, k));
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
fn group_lane8<V: F8>(g: &Tri4, l: usize, pk: &RayPacket, k: usize) -> (u32, V, V, V) {
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
