//! Packet traversal of 4-wide BVHs: up to [`PACKET_RAYS`] coherent rays walk the tree
//! together, so a node is fetched once per packet instead of once per ray.
//!
//! The walk follows the *first active ray* (Wald, Boulos and Shirley, "Ray Tracing Deformable
//! Scenes Using Dynamic Bounding Volume Hierarchies", 2007): every stack entry carries the
//! index of the first ray that enters its box, and a mask of the rays that may. A node's
//! children are tested against the first ray alone (one 4-wide test); a child it misses is
//! tested against the node's other candidate rays, which yields the child's exact candidate
//! mask, so searches shrink as the packet spreads out; a child no candidate enters is skipped.
//! Before those searches an interval-arithmetic bound over all the packet's origins and
//! directions (the cull test) rejects, in one 4-wide test, the children no ray of the packet
//! can enter. Leaves test 8 rays per triangle in `f32x8` lanes. A packet whose rays turn out
//! to share almost no leaves (fewer than two rays per leaf visit on average) hands its
//! remaining rays to the single-ray walk, each starting from the subtrees still stacked.
//!
//! Every per-ray computation (slab test, triangle test, tie break) is the single-ray kernel's
//! operation for operation, so each ray gets exactly the single-ray answer. Incoherent rays
//! gain nothing from sharing nodes and pay for the searches; [`PacketMode::Auto`] sends such
//! packets down the single-ray kernel instead.

use super::bvh4::{self, Ray4, WideNode};
use super::stats::{NoStats, Stats};
use super::{leaf_any_hit, leaf_closest_hit, slab_reciprocal, BoxTest, ConservativeBoxes, Stack};
use crate::build::MAX_DEPTH;
use crate::geometry::{Hit, Primitive, Ray, Triangle};
use crate::layout::{Bvh, Bvh4, Bvh4Node, QBvh4};
use std::ops::Range;
use wide::{f32x4, f32x8};

/// Rays per packet. Longer inputs are cut into packets of this size.
pub const PACKET_RAYS: usize = 64;
const LANES: usize = 8;
const CHUNKS: usize = PACKET_RAYS / LANES;

/// One value per ray of a packet, eight rays to a SIMD chunk.
type Lanes = [f32x8; CHUNKS];

/// How a packet query chooses between packet and single-ray traversal.
///
/// ```
/// use quiver::traverse::PacketMode;
/// assert_eq!(PacketMode::default(), PacketMode::Auto);
/// ```
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum PacketMode {
    /// Packets of coherent rays (every direction within about 25° of the first active ray's,
    /// at least four active rays) go down the packet kernel; others are traced ray by ray.
    /// Rays that point alike but scatter anyway (shadow rays from far-apart points of fine
    /// geometry) are handed to the single-ray walk once the packet sees it, which keeps them
    /// near, though not always at, single-ray speed (README, "Packets").
    #[default]
    Auto,
    /// Always the packet kernel, however incoherent the rays (for tests and measurements).
    Always,
    /// Always ray by ray (the single-ray kernel behind the packet interface).
    Never,
}

/// Leaves a packet visits before [`Packet::came_apart`] judges it.
const PROBATION_LEAVES: u32 = 12;
/// Average rays per leaf visit below which the rest of a packet goes ray by ray. Measured
/// averages (512² eye rays in 8×8 tiles, shadow rays toward the first light): teapot12 20 and
/// 13, balls3 in patch mode 9 and 4.3, tetra9 1.7 and 1.2; packets pay on the first two.
const MIN_RAYS_PER_LEAF: u32 = 2;

/// Smallest cosine between a packet ray and the first active ray for [`PacketMode::Auto`] to
/// take the packet path.
const COHERENT_COS: f32 = 0.9;

#[inline(always)]
fn lane(l: &Lanes, i: usize) -> f32 {
    bytemuck::cast_ref::<Lanes, [f32; PACKET_RAYS]>(l)[i]
}

#[inline(always)]
fn lane_mut(l: &mut Lanes, i: usize) -> &mut f32 {
    &mut bytemuck::cast_mut::<Lanes, [f32; PACKET_RAYS]>(l)[i]
}

/// `max(a, b)` ignoring a NaN `a`, lane by lane as [`bvh4::max_nan_first`] does for four.
#[inline(always)]
fn max_nan_first(a: f32x8, b: f32x8) -> f32x8 {
    #[cfg(target_feature = "sse")]
    {
        a.fast_max(b)
    }
    #[cfg(not(target_feature = "sse"))]
    {
        b.max(a)
    }
}

/// `min(a, b)` ignoring a NaN `a`.
#[inline(always)]
fn min_nan_first(a: f32x8, b: f32x8) -> f32x8 {
    #[cfg(target_feature = "sse")]
    {
        a.fast_min(b)
    }
    #[cfg(not(target_feature = "sse"))]
    {
        b.min(a)
    }
}

/// One axis of the packet's interval bound: every active ray's origin and reciprocal direction
/// lie in these ranges, and all reciprocals share a sign, so the near and far planes are the
/// same rows for every ray.
#[derive(Clone, Copy, Debug)]
struct AxisBound {
    near_row: usize,
    far_row: usize,
    /// The origin bound that gives the smallest near distance, and the largest far distance.
    o_near: f32,
    o_far: f32,
    i_lo: f32,
    i_hi: f32,
}

/// The cull test: bounds on what any active ray of the packet can compute in a slab test.
#[derive(Clone, Copy, Debug)]
struct Bound {
    axes: [Option<AxisBound>; 3],
    t_min_lo: f32,
    t_max_hi: f32,
}

impl Bound {
    /// Mask of the four boxes some active ray may enter. Sound because subtraction and
    /// multiplication round monotonically: `fl(p - o)` lies between its values at the ends
    /// of `o`'s range, and `fl(x · i)` between its values at the ends of `i`'s range.
    #[inline(always)]
    fn may_enter<B: BoxTest>(&self, p: &[f32x4; 6]) -> u32 {
        let mut lo = f32x4::splat(self.t_min_lo);
        let mut hi = f32x4::splat(self.t_max_hi * B::SLACK);
        for ax in self.axes.iter().flatten() {
            let (i_lo, i_hi) = (f32x4::splat(ax.i_lo), f32x4::splat(ax.i_hi));
            let xn = p[ax.near_row] - f32x4::splat(ax.o_near);
            lo = lo.fast_max((xn * i_lo).fast_min(xn * i_hi));
            let xf = p[ax.far_row] - f32x4::splat(ax.o_far);
            hi = hi.fast_min((xf * i_lo).fast_max(xf * i_hi) * f32x4::splat(B::SLACK));
        }
        lo.simd_le(hi).to_bitmask()
    }
}

/// Up to [`PACKET_RAYS`] rays in SIMD lanes, with their per-ray search limits.
struct Packet {
    o: [Lanes; 3],
    d: [Lanes; 3],
    inv: [Lanes; 3],
    /// All bits set where the reciprocal direction is negative (a select mask).
    neg: [Lanes; 3],
    t_min: Lanes,
    /// How far each ray still searches: `t_max`, then the best hit so far; `-inf` once a ray
    /// is inactive, so every test fails for it.
    limit: Lanes,
    /// Bit `i`: ray `i` is still searching.
    active: u64,
    bound: Bound,
    /// Leaves visited, and rays tested in them: how well the packet holds together.
    leaf_visits: u32,
    leaf_rays: u32,
}

impl Packet {
    /// Packs `rays` (at most [`PACKET_RAYS`]); bit `i` of `active` says whether ray `i` is
    /// traced. Rays with a NaN `t_min` or `t_max` can hit nothing and start inactive.
    #[inline(always)]
    fn new(rays: &[Ray], active: u64) -> Packet {
        debug_assert!(rays.len() <= PACKET_RAYS);
        let zero = [f32x8::ZERO; CHUNKS];
        let mut p = Packet {
            o: [zero; 3],
            d: [zero; 3],
            inv: [zero; 3],
            neg: [zero; 3],
            t_min: zero,
            limit: [f32x8::NEG_INFINITY; CHUNKS],
            active: 0,
            bound: Bound {
                axes: [None; 3],
                t_min_lo: f32::INFINITY,
                t_max_hi: f32::NEG_INFINITY,
            },
            leaf_visits: 0,
            leaf_rays: 0,
        };
        // Per axis: origin and reciprocal ranges, and whether every value suits the bound
        // (finite origins, finite non-zero reciprocals of one sign). Otherwise a product can be
        // NaN, which the per-ray test ignores but an interval cannot represent; such an axis
        // does not cull.
        let mut o_lo = [f32::INFINITY; 3];
        let mut o_hi = [f32::NEG_INFINITY; 3];
        let mut i_lo = [f32::INFINITY; 3];
        let mut i_hi = [f32::NEG_INFINITY; 3];
        let mut usable = [true; 3];
        let mut negs = [0u32; 3];
        {
            type Rows = [[f32; PACKET_RAYS]; 3];
            let o: &mut Rows = bytemuck::cast_mut(&mut p.o);
            let d: &mut Rows = bytemuck::cast_mut(&mut p.d);
            let inv_l: &mut Rows = bytemuck::cast_mut(&mut p.inv);
            let neg: &mut Rows = bytemuck::cast_mut(&mut p.neg);
            let t_min: &mut [f32; PACKET_RAYS] = bytemuck::cast_mut(&mut p.t_min);
            let limit: &mut [f32; PACKET_RAYS] = bytemuck::cast_mut(&mut p.limit);
            let all_ones = f32::from_bits(u32::MAX);
            for (i, ray) in rays.iter().enumerate() {
                if active >> i & 1 == 0 || ray.t_min.is_nan() || ray.t_max.is_nan() {
                    continue;
                }
                p.active |= 1 << i;
                let inv = slab_reciprocal(ray.dir);
                for a in 0..3 {
                    let is_neg = inv[a].is_sign_negative();
                    o[a][i] = ray.origin[a];
                    d[a][i] = ray.dir[a];
                    inv_l[a][i] = inv[a];
                    neg[a][i] = if is_neg { all_ones } else { 0.0 };
                    negs[a] += is_neg as u32;
                    usable[a] &= ray.origin[a].is_finite() && inv[a].is_finite() && inv[a] != 0.0;
                    o_lo[a] = o_lo[a].min(ray.origin[a]);
                    o_hi[a] = o_hi[a].max(ray.origin[a]);
                    i_lo[a] = i_lo[a].min(inv[a]);
                    i_hi[a] = i_hi[a].max(inv[a]);
                }
                t_min[i] = ray.t_min;
                limit[i] = ray.t_max;
                p.bound.t_min_lo = p.bound.t_min_lo.min(ray.t_min);
                p.bound.t_max_hi = p.bound.t_max_hi.max(ray.t_max);
            }
        }
        let n = p.active.count_ones();
        for a in 0..3 {
            let all_neg = negs[a] == n;
            if n == 0 || !usable[a] || (negs[a] != 0 && !all_neg) {
                continue;
            }
            p.bound.axes[a] = Some(AxisBound {
                near_row: if all_neg { a + 3 } else { a },
                far_row: if all_neg { a } else { a + 3 },
                o_near: if all_neg { o_lo[a] } else { o_hi[a] },
                o_far: if all_neg { o_hi[a] } else { o_lo[a] },
                i_lo: i_lo[a],
                i_hi: i_hi[a],
            });
        }
        p
    }

    /// Lowers the bound's `t_max` after hits shortened some rays.
    #[inline(always)]
    fn refresh_limit_bound(&mut self) {
        let m = self
            .limit
            .iter()
            .fold(f32x8::NEG_INFINITY, |m, &l| m.fast_max(l));
        self.bound.t_max_hi = m.to_array().into_iter().fold(f32::NEG_INFINITY, f32::max);
    }

    /// Ray `i` prepared for the 4-wide single-ray test.
    #[inline(always)]
    fn ray4(&self, i: usize) -> Ray4 {
        Ray4::from_parts(
            [0, 1, 2].map(|a| lane(&self.o[a], i)),
            [0, 1, 2].map(|a| lane(&self.inv[a], i)),
            lane(&self.t_min, i),
        )
    }

    /// The slab test of chunk `k`'s rays against box `b` (`[min xyz, max xyz]`): the mask of
    /// lanes entering it within their limits, and their entry distances. Per lane this is
    /// [`Ray4::enter`]'s arithmetic exactly.
    #[inline(always)]
    fn enter_chunk<B: BoxTest>(&self, k: usize, b: &[f32; 6]) -> (u32, f32x8) {
        let slack = f32x8::splat(B::SLACK);
        let mut near = self.t_min[k];
        let mut far = self.limit[k] * slack;
        for a in 0..3 {
            let (lo, hi) = (f32x8::splat(b[a]), f32x8::splat(b[3 + a]));
            let neg = self.neg[a][k];
            let (pn, pf) = (neg.select(hi, lo), neg.select(lo, hi));
            let tn = (pn - self.o[a][k]) * self.inv[a][k];
            let tf = (pf - self.o[a][k]) * self.inv[a][k];
            near = max_nan_first(tn, near);
            far = min_nan_first(tf * slack, far);
        }
        (near.simd_le(far).to_bitmask(), near)
    }

    /// The first active ray of `mask` that enters `b`, with its entry distance.
    #[inline(always)]
    fn find_first<B: BoxTest>(&self, b: &[f32; 6], mask: u64) -> Option<(usize, f32)> {
        for (k, bits) in chunks(self.active & mask) {
            let (m, near) = self.enter_chunk::<B>(k, b);
            let m = m & bits;
            if m != 0 {
                let j = m.trailing_zeros() as usize;
                return Some((LANES * k + j, near.as_array()[j]));
            }
        }
        None
    }

    /// The active rays of `mask` that enter `b`, and the entry distance of the first.
    #[inline(always)]
    fn enter_all<B: BoxTest>(&self, b: &[f32; 6], mask: u64) -> (u64, f32) {
        let (mut out, mut t) = (0u64, 0.0);
        for (k, bits) in chunks(self.active & mask) {
            let (m, near) = self.enter_chunk::<B>(k, b);
            let m = m & bits;
            if out == 0 && m != 0 {
                t = near.as_array()[m.trailing_zeros() as usize];
            }
            out |= (m as u64) << (LANES * k);
        }
        (out, t)
    }

    /// Masks, per chunk, of the active rays of `mask` that enter leaf box `b`; counted toward
    /// the packet's coherence record ([`Packet::came_apart`]).
    #[inline(always)]
    fn entering<B: BoxTest>(&mut self, b: &[f32; 6], mask: u64) -> [u32; CHUNKS] {
        let mut out = [0; CHUNKS];
        for (k, bits) in chunks(self.active & mask) {
            out[k] = bits & self.enter_chunk::<B>(k, b).0;
            self.leaf_rays += out[k].count_ones();
        }
        self.leaf_visits += 1;
        out
    }

    /// True once the packet has shown, over enough leaves, that its rays go separate ways:
    /// so few rays share each leaf that the packet's searches cost more than they share.
    #[inline(always)]
    fn came_apart(&self) -> bool {
        self.leaf_visits >= PROBATION_LEAVES
            && self.leaf_rays < MIN_RAYS_PER_LEAF * self.leaf_visits
    }

    /// Möller–Trumbore for the eight rays of chunk `k` against one triangle, operation for
    /// operation as [`Triangle::intersect`] computes it for one ray (glam's `cross` and `dot`
    /// orders, fused where glam fuses), so every lane gets the single-ray result. Returns the
    /// mask of lanes hit within `[t_min, limit]` and their `t`, `u`, `v`.
    #[inline(always)]
    fn intersect8(&self, k: usize, tri: &TriSetup) -> (u32, f32x8, f32x8, f32x8) {
        let [dx, dy, dz] = [0, 1, 2].map(|a| self.d[a][k]);
        let [nx, ny, nz] = tri.n;
        let det = (nx * dx + ny * dy) + nz * dz;
        let inv = f32x8::ONE / det;
        let [cx, cy, cz] = [0, 1, 2].map(|a| tri.v0[a] - self.o[a][k]);
        // d × c, as glam writes it: (a.y·b.z − b.y·a.z, …) with the second product fused
        // into the subtraction when the target has FMA.
        let rx = cy.mul_neg_add(dz, dy * cz);
        let ry = cz.mul_neg_add(dx, dz * cx);
        let rz = cx.mul_neg_add(dy, dx * cy);
        let [e1x, e1y, e1z] = tri.e1;
        let [e2x, e2y, e2z] = tri.e2;
        let u = ((rx * e2x + ry * e2y) + rz * e2z) * inv;
        let v = ((rx * e1x + ry * e1y) + rz * e1z) * inv;
        let t = ((nx * cx + ny * cy) + nz * cz) * inv;
        let ok = det.simd_ne(f32x8::ZERO)
            & u.simd_ge(f32x8::ZERO)
            & v.simd_ge(f32x8::ZERO)
            & (u + v).simd_le(f32x8::ONE)
            & t.simd_ge(self.t_min[k])
            & t.simd_le(self.limit[k]);
        (ok.to_bitmask(), t, u, v)
    }

    /// Retires ray `i`: it takes part in no further test.
    #[inline(always)]
    fn retire(&mut self, i: usize) {
        self.active &= !(1 << i);
        *lane_mut(&mut self.limit, i) = f32::NEG_INFINITY;
    }
}

/// A triangle's ray-independent terms, splatted once per leaf visit.
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
}

/// Stack entry: a child, where its box is (slot of a parent node), the first ray entering it
/// and that ray's entry distance, and the rays that may enter it. The box is re-read only when
/// needed (leaf, or a new first ray), which is cheaper than carrying it.
#[derive(Clone, Copy)]
struct Entry {
    child: u32,
    /// 0 for an inner node, `LEAF | count` for a leaf.
    count: u32,
    first: u32,
    t: f32,
    parent: u32,
    slot: u32,
    /// The rays that may enter the child: every ray that enters it is in here. Searches for
    /// a first ray scan only these, so they get cheaper as the packet spreads out.
    mask: u64,
}

impl Entry {
    /// The primitives of a leaf entry.
    #[inline(always)]
    fn leaf_range(&self) -> Range<usize> {
        let count = self.count & !Bvh4Node::LEAF;
        self.child as usize..(self.child + count) as usize
    }
}

#[inline(always)]
fn slot_box(p: &[f32x4; 6], i: usize) -> [f32; 6] {
    [0, 1, 2, 3, 4, 5].map(|r| p[r].as_array()[i])
}

/// Bits above `i`.
#[inline(always)]
fn above(i: usize) -> u64 {
    (u64::MAX << i) << 1
}

/// What the packet walk hands its caller.
enum Visit<'b> {
    /// A leaf's primitives, for the active rays of the mask that enter the box.
    Leaf(Range<usize>, &'b [f32; 6], u64),
    /// One ray alone, from its current limit, after the packet came apart.
    Alone(usize, AloneIn),
}

/// Where a ray continues alone.
enum AloneIn {
    Leaf(Range<usize>),
    Inner(usize),
}

/// The packet walk over one 4-wide node format. `visit(packet, what, stats)` handles a leaf
/// for the packet or a subtree for one ray ([`Visit`]) and returns true once every ray is done
/// (any-hit), which ends the walk.
///
/// Each node is tested against its first ray alone. A child that ray misses is tested
/// against the other candidate rays (those that may have entered the node), which gives
/// the child's exact candidate set, so the deeper the walk, the fewer rays a search scans.
/// When the packet comes apart ([`Packet::came_apart`]), each remaining ray finishes the
/// stacked subtrees alone with the single-ray walk.
#[inline(always)]
fn walk<N, B, S, F>(nodes: &[N], pk: &mut Packet, stats: &mut S, mut leaf: F)
where
    N: WideNode,
    B: BoxTest,
    S: Stats,
    F: FnMut(&mut Packet, Visit, &mut S) -> bool,
{
    if pk.active == 0 {
        return;
    }
    let mut stack: Stack<Entry, { 3 * MAX_DEPTH + 4 }> = Stack::new();
    let mut node = 0usize;
    let mut mask = pk.active;
    let mut first = mask.trailing_zeros() as usize;
    // The first ray prepared for 4-wide tests; it often stays first for many nodes.
    let (mut r4, mut r4_of) = (pk.ray4(first), first);
    loop {
        let n = &nodes[node];
        stats.node();
        stats.boxes(4);
        let planes = n.planes();
        let mut used = 0u32;
        for i in 0..4 {
            used |= ((n.child(i).1 != Bvh4Node::LEAF) as u32) << i;
        }
        if r4_of != first {
            (r4, r4_of) = (pk.ray4(first), first);
        }
        let (t, hit) = r4.enter::<B>(&planes, lane(&pk.limit, first) * B::SLACK);
        let hit = hit & used;
        // (entry distance, slot, first ray, candidates), sorted farthest first.
        let mut kids: [(f32, usize, usize, u64); 4] = [(0.0, 0, 0, 0); 4];
        let mut k = 0;
        let mut add = |kid: (f32, usize, usize, u64), k: &mut usize| {
            let mut j = *k;
            while j > 0 && kids[j - 1].0 < kid.0 {
                kids[j] = kids[j - 1];
                j -= 1;
            }
            kids[j] = kid;
            *k += 1;
        };
        // A child the first ray misses may still be entered by a later candidate.
        let rest = mask & above(first);
        let mut missed = !hit & used;
        if missed != 0 && rest & pk.active != 0 {
            missed &= pk.bound.may_enter::<B>(&planes);
        } else {
            missed = 0;
        }
        while missed != 0 {
            let i = missed.trailing_zeros() as usize;
            missed &= missed - 1;
            stats.boxes(1);
            let (m, tf) = pk.enter_all::<B>(&slot_box(&planes, i), rest);
            if m != 0 {
                add((tf, i, m.trailing_zeros() as usize, m), &mut k);
            }
        }
        let mut h = hit;
        while h != 0 {
            let i = h.trailing_zeros() as usize;
            h &= h - 1;
            add((t[i], i, first, mask), &mut k);
        }
        for &(ti, i, f, m) in &kids[..k] {
            let (child, count) = n.child(i);
            stack.push(Entry {
                child,
                count,
                first: f as u32,
                t: ti,
                parent: node as u32,
                slot: i as u32,
                mask: m,
            });
        }
        // Pop until an inner node some ray still enters; leaves are handled on the way.
        loop {
            let Some(e) = stack.pop() else {
                return;
            };
            let mut f = e.first as usize;
            let is_leaf = e.count & Bvh4Node::LEAF != 0;
            let valid = pk.active >> f & 1 == 1 && e.t <= lane(&pk.limit, f) * B::SLACK;
            if valid && !is_leaf {
                (node, first, mask) = (e.child as usize, f, e.mask);
                break;
            }
            let b = slot_box(&nodes[e.parent as usize].planes(), e.slot as usize);
            if !valid {
                // The first ray was shortened (or retired) since the push: look for another.
                match pk.find_first::<B>(&b, e.mask & above(f)) {
                    Some((nf, _)) => f = nf,
                    None => continue,
                }
                if !is_leaf {
                    (node, first, mask) = (e.child as usize, f, e.mask);
                    break;
                }
            }
            stats.node();
            stats.leaf();
            let visit = Visit::Leaf(e.leaf_range(), &b, e.mask & !((1u64 << f) - 1));
            if leaf(pk, visit, stats) {
                return;
            }
            if pk.came_apart() {
                let mut rest = Vec::with_capacity(64);
                while let Some(e) = stack.pop() {
                    rest.push(e);
                }
                finish_alone::<N, B, S, F>(nodes, pk, &rest, stats, &mut leaf);
                return;
            }
        }
    }
}

/// Each active ray works through the stacked entries `rest` (nearest first for the packet)
/// on its own: the entries whose box it enters (tested exactly as the single-ray walk tests
/// it), a leaf's primitives or an inner node's subtree with the single-ray walk.
#[inline(never)]
fn finish_alone<N, B, S, F>(
    nodes: &[N],
    pk: &mut Packet,
    rest: &[Entry],
    stats: &mut S,
    visit: &mut F,
) where
    N: WideNode,
    B: BoxTest,
    S: Stats,
    F: FnMut(&mut Packet, Visit, &mut S) -> bool,
{
    for i in bits(pk.active) {
        let r4 = pk.ray4(i);
        for e in rest {
            if e.mask >> i & 1 == 0 {
                continue;
            }
            let planes = nodes[e.parent as usize].planes();
            let limit = lane(&pk.limit, i);
            if r4.enter::<B>(&planes, limit * B::SLACK).1 >> e.slot & 1 == 0 {
                continue;
            }
            let at = match e.count & Bvh4Node::LEAF {
                0 => AloneIn::Inner(e.child as usize),
                _ => AloneIn::Leaf(e.leaf_range()),
            };
            visit(pk, Visit::Alone(i, at), stats);
            if pk.active >> i & 1 == 0 {
                break;
            }
        }
    }
}

/// Set bits of a mask (packet or chunk), lowest first.
#[inline(always)]
fn bits(mask: impl Into<u64>) -> impl Iterator<Item = usize> {
    let mut m = mask.into();
    std::iter::from_fn(move || {
        (m != 0).then(|| {
            let i = m.trailing_zeros() as usize;
            m &= m - 1;
            i
        })
    })
}

/// The chunks a packet mask touches: (chunk, its 8-lane mask), lowest first.
#[inline(always)]
fn chunks(mut m: u64) -> impl Iterator<Item = (usize, u32)> {
    std::iter::from_fn(move || {
        (m != 0).then(|| {
            let k = m.trailing_zeros() as usize / LANES;
            let lanes = (m >> (LANES * k)) as u32 & 0xFF;
            m &= !(0xFF << (LANES * k));
            (k, lanes)
        })
    })
}

/// Closest hits of one packet into `best` (one record per ray, [`Hit::none`] to start).
#[inline(always)]
fn closest_packet<N: WideNode, B: BoxTest, P: Primitive, S: Stats>(
    nodes: &[N],
    prims: &[P],
    ids: &[u32],
    rays: &[Ray],
    pk: &mut Packet,
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
                *lane_mut(&mut pk.limit, i) = best[i].t;
                return false;
            }
        };
        let masks = pk.entering::<B>(b, cand);
        let mut changed = false;
        match P::as_triangles(&prims[range.clone()]) {
            Some(tris) => {
                stats.prims(tris.len() as u32);
                for (tri, &id) in tris.iter().zip(&ids[range]) {
                    let setup = TriSetup::new(tri);
                    for (k, &m) in masks.iter().enumerate() {
                        if m == 0 {
                            continue;
                        }
                        let (ok, t, u, v) = pk.intersect8(k, &setup);
                        let ok = ok & m;
                        if ok == 0 {
                            continue;
                        }
                        let (t, u, v) = (t.as_array(), u.as_array(), v.as_array());
                        for j in bits(ok) {
                            let i = LANES * k + j;
                            if best[i].is_beaten_by(t[j], id) {
                                best[i] = Hit {
                                    t: t[j],
                                    prim: id,
                                    u: u[j],
                                    v: v[j],
                                };
                                *lane_mut(&mut pk.limit, i) = t[j];
                                changed = true;
                            }
                        }
                    }
                }
            }
            None => {
                for (k, &m) in masks.iter().enumerate() {
                    for j in bits(m) {
                        let i = LANES * k + j;
                        let (p, ids) = (&prims[range.clone()], &ids[range.clone()]);
                        if leaf_closest_hit(p, ids, &rays[i], &mut best[i], stats) {
                            *lane_mut(&mut pk.limit, i) = best[i].t;
                            changed = true;
                        }
                    }
                }
            }
        }
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
fn any_packet<N: WideNode, B: BoxTest, P: Primitive, S: Stats>(
    nodes: &[N],
    prims: &[P],
    rays: &[Ray],
    pk: &mut Packet,
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
        let mut masks = pk.entering::<B>(b, cand);
        let before = pk.active;
        match P::as_triangles(&prims[range.clone()]) {
            Some(tris) => {
                stats.prims(tris.len() as u32);
                for tri in tris {
                    let setup = TriSetup::new(tri);
                    for (k, m) in masks.iter_mut().enumerate() {
                        if *m == 0 {
                            continue;
                        }
                        let ok = pk.intersect8(k, &setup).0 & *m;
                        *m &= !ok;
                        for j in bits(ok) {
                            hit[LANES * k + j] = true;
                            pk.retire(LANES * k + j);
                        }
                    }
                }
            }
            None => {
                for (k, &m) in masks.iter().enumerate() {
                    for j in bits(m) {
                        let i = LANES * k + j;
                        if leaf_any_hit(&prims[range.clone()], &rays[i], stats) {
                            hit[i] = true;
                            pk.retire(i);
                        }
                    }
                }
            }
        }
        if pk.active == before {
            stats.empty_leaf();
        }
        pk.active == 0
    });
}

/// Bit mask of the rays to trace in one packet.
fn active_bits(n: usize, active: Option<&[bool]>) -> u64 {
    match active {
        None if n == 64 => u64::MAX,
        None => (1u64 << n) - 1,
        Some(a) => a
            .iter()
            .enumerate()
            .fold(0, |m, (i, &on)| m | (on as u64) << i),
    }
}

/// Whether the active rays point closely enough the same way for a packet to pay: sampled
/// directions within `acos(COHERENT_COS)` of the first active ray's, tested without square
/// roots or divisions (the check runs once per packet, on the fast path).
fn coherent(rays: &[Ray], active: u64) -> bool {
    if active.count_ones() < 4 {
        return false;
    }
    let d0 = rays[active.trailing_zeros() as usize].dir;
    let (l0, c2) = (d0.length_squared(), COHERENT_COS * COHERENT_COS);
    // Every fourth ray and the last: the answer only picks the faster path (both give the
    // same hits), so a sample suffices and keeps the check cheap.
    (0..rays.len())
        .filter(|&i| active >> i & 1 == 1 && (i % 4 == 0 || i + 1 == rays.len()))
        .all(|i| {
            let d = rays[i].dir;
            let dot = d.dot(d0);
            // False for NaN: such packets go ray by ray.
            dot > 0.0 && dot * dot >= c2 * l0 * d.length_squared()
        })
}

/// Cuts `rays` into packets and hands each to `run(rays, active bits, use packets, out)`,
/// after checking lengths and deciding by `mode` whether the packet path pays.
#[inline(always)]
fn each_packet<T>(
    rays: &[Ray],
    active: Option<&[bool]>,
    mode: PacketMode,
    out: &mut [T],
    mut run: impl FnMut(&[Ray], u64, bool, &mut [T]),
) {
    assert_eq!(rays.len(), out.len(), "one answer slot per ray");
    if let Some(a) = active {
        assert_eq!(rays.len(), a.len(), "one active flag per ray");
    }
    for (c, (rays, out)) in rays
        .chunks(PACKET_RAYS)
        .zip(out.chunks_mut(PACKET_RAYS))
        .enumerate()
    {
        let from = c * PACKET_RAYS;
        let on = active_bits(rays.len(), active.map(|a| &a[from..from + rays.len()]));
        let packet = match mode {
            PacketMode::Always => true,
            PacketMode::Never => false,
            PacketMode::Auto => coherent(rays, on),
        };
        run(rays, on, packet, out);
    }
}

/// Closest hits of any number of rays, packet by packet, over one 4-wide node format.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn closest_rays<N: WideNode, B: BoxTest, P: Primitive, S: Stats>(
    nodes: &[N],
    prims: &[P],
    ids: &[u32],
    rays: &[Ray],
    active: Option<&[bool]>,
    mode: PacketMode,
    hits: &mut [Option<Hit>],
    stats: &mut S,
) {
    each_packet(rays, active, mode, hits, |rays, on, packet, hits| {
        if packet {
            let mut pk = Packet::new(rays, on);
            let mut best = [Hit::none(0.0); PACKET_RAYS];
            for (b, r) in best.iter_mut().zip(rays) {
                *b = Hit::none(r.t_max);
            }
            closest_packet::<N, B, P, S>(nodes, prims, ids, rays, &mut pk, &mut best, stats);
            for (i, (h, b)) in hits.iter_mut().zip(best).enumerate() {
                *h = if on >> i & 1 == 1 { b.found() } else { None };
            }
        } else {
            for (i, (h, r)) in hits.iter_mut().zip(rays).enumerate() {
                *h = if on >> i & 1 == 1 {
                    bvh4::closest::<N, B, P, S>(nodes, prims, ids, r, stats)
                } else {
                    None
                };
            }
        }
    });
}

/// Any-hit answers of any number of rays, packet by packet.
#[inline(always)]
fn any_rays<N: WideNode, B: BoxTest, P: Primitive, S: Stats>(
    nodes: &[N],
    prims: &[P],
    rays: &[Ray],
    active: Option<&[bool]>,
    mode: PacketMode,
    occluded: &mut [bool],
    stats: &mut S,
) {
    each_packet(rays, active, mode, occluded, |rays, on, packet, out| {
        out.fill(false);
        if packet {
            let mut pk = Packet::new(rays, on);
            any_packet::<N, B, P, S>(nodes, prims, rays, &mut pk, out, stats);
        } else {
            for (i, (o, r)) in out.iter_mut().zip(rays).enumerate() {
                *o = on >> i & 1 == 1 && bvh4::any::<N, B, P, S>(nodes, prims, r, stats);
            }
        }
    });
}

macro_rules! packet_queries {
    ($t:ident) => {
        impl<P: Primitive> $t<P> {
            /// Closest hits of `rays` into `hits` (same length), traced in packets of
            /// [`PACKET_RAYS`] where they are coherent ([`PacketMode::Auto`]). Each answer is
            /// exactly [`Self::closest_hit`]'s for that ray.
            ///
            /// # Panics
            /// When `hits` and `rays` differ in length.
            pub fn closest_hit_packet(&self, rays: &[Ray], hits: &mut [Option<Hit>]) {
                self.closest_hit_packet_with::<ConservativeBoxes, _>(
                    rays,
                    None,
                    PacketMode::Auto,
                    hits,
                    &mut NoStats,
                )
            }

            /// Whether each ray hits anything within its interval, into `occluded`.
            ///
            /// # Panics
            /// When `occluded` and `rays` differ in length.
            pub fn any_hit_packet(&self, rays: &[Ray], occluded: &mut [bool]) {
                self.any_hit_packet_with::<ConservativeBoxes, _>(
                    rays,
                    None,
                    PacketMode::Auto,
                    occluded,
                    &mut NoStats,
                )
            }

            /// [`Self::closest_hit_packet`] with every option: only rays whose `active` flag
            /// is set are traced (the others get `None`), the packet mode, the box test and a
            /// statistics sink (which counts packet node visits, not per-ray ones).
            ///
            /// # Panics
            /// When `hits` or `active` differ in length from `rays`.
            pub fn closest_hit_packet_with<B: BoxTest, S: Stats>(
                &self,
                rays: &[Ray],
                active: Option<&[bool]>,
                mode: PacketMode,
                hits: &mut [Option<Hit>],
                stats: &mut S,
            ) {
                closest_rays::<_, B, _, _>(
                    &self.nodes,
                    &self.prims,
                    &self.prim_ids,
                    rays,
                    active,
                    mode,
                    hits,
                    stats,
                )
            }

            /// [`Self::any_hit_packet`] with every option (inactive rays get `false`).
            ///
            /// # Panics
            /// When `occluded` or `active` differ in length from `rays`.
            pub fn any_hit_packet_with<B: BoxTest, S: Stats>(
                &self,
                rays: &[Ray],
                active: Option<&[bool]>,
                mode: PacketMode,
                occluded: &mut [bool],
                stats: &mut S,
            ) {
                any_rays::<_, B, _, _>(
                    &self.nodes,
                    &self.prims,
                    rays,
                    active,
                    mode,
                    occluded,
                    stats,
                )
            }
        }
    };
}

packet_queries!(Bvh4);
packet_queries!(QBvh4);

impl<P: Primitive> Bvh<P> {
    /// Closest hits of `rays` in packets (see [`Bvh4::closest_hit_packet`]); a binary layout
    /// has no packet kernel and traces them one by one.
    ///
    /// ```
    /// use quiver::build::{BuildConfig, Builder};
    /// use quiver::{reference, Bvh, Layout};
    /// use quiver_scenes::{scene::Scene};
    /// let scene = Scene::load("tetra3").unwrap();
    /// let tris = scene.triangles();
    /// let (bvh, _) = Bvh::build(&tris, &BuildConfig::default(), Builder::Binned, Layout::Bvh4Dfs);
    /// let rays: Vec<_> = (0..64).map(|i| scene.camera.ray(i as f32 / 64.0 - 0.5, 0.0)).collect();
    /// let mut hits = vec![None; rays.len()];
    /// bvh.closest_hit_packet(&rays, &mut hits);
    /// for (ray, hit) in rays.iter().zip(&hits) {
    ///     assert_eq!(*hit, reference::closest_hit(&tris, ray));
    /// }
    /// ```
    ///
    /// # Panics
    /// When `hits` and `rays` differ in length.
    pub fn closest_hit_packet(&self, rays: &[Ray], hits: &mut [Option<Hit>]) {
        self.closest_hit_packet_with::<ConservativeBoxes, _>(
            rays,
            None,
            PacketMode::Auto,
            hits,
            &mut NoStats,
        )
    }

    /// Any-hit answers of `rays` in packets (see [`Bvh4::any_hit_packet`]).
    ///
    /// # Panics
    /// When `occluded` and `rays` differ in length.
    pub fn any_hit_packet(&self, rays: &[Ray], occluded: &mut [bool]) {
        self.any_hit_packet_with::<ConservativeBoxes, _>(
            rays,
            None,
            PacketMode::Auto,
            occluded,
            &mut NoStats,
        )
    }

    /// [`Bvh4::closest_hit_packet_with`] for any layout.
    ///
    /// # Panics
    /// When `hits` or `active` differ in length from `rays`.
    pub fn closest_hit_packet_with<B: BoxTest, S: Stats>(
        &self,
        rays: &[Ray],
        active: Option<&[bool]>,
        mode: PacketMode,
        hits: &mut [Option<Hit>],
        stats: &mut S,
    ) {
        match self {
            // No binary packet kernel: ray by ray.
            Bvh::Bvh2(b) => each_packet(rays, active, mode, hits, |rays, on, _, hits| {
                for (i, (h, r)) in hits.iter_mut().zip(rays).enumerate() {
                    *h = (on >> i & 1 == 1)
                        .then(|| b.closest_hit_with::<B, S>(r, stats))
                        .flatten();
                }
            }),
            Bvh::Bvh4(b) => b.closest_hit_packet_with::<B, S>(rays, active, mode, hits, stats),
            Bvh::QBvh4(b) => b.closest_hit_packet_with::<B, S>(rays, active, mode, hits, stats),
        }
    }

    /// [`Bvh4::any_hit_packet_with`] for any layout.
    ///
    /// # Panics
    /// When `occluded` or `active` differ in length from `rays`.
    pub fn any_hit_packet_with<B: BoxTest, S: Stats>(
        &self,
        rays: &[Ray],
        active: Option<&[bool]>,
        mode: PacketMode,
        occluded: &mut [bool],
        stats: &mut S,
    ) {
        match self {
            Bvh::Bvh2(b) => each_packet(rays, active, mode, occluded, |rays, on, _, out| {
                for (i, (o, r)) in out.iter_mut().zip(rays).enumerate() {
                    *o = on >> i & 1 == 1 && b.any_hit_with::<B, S>(r, stats);
                }
            }),
            Bvh::Bvh4(b) => b.any_hit_packet_with::<B, S>(rays, active, mode, occluded, stats),
            Bvh::QBvh4(b) => b.any_hit_packet_with::<B, S>(rays, active, mode, occluded, stats),
        }
    }
}
