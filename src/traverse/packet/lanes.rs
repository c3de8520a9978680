//! A packet's rays in SIMD lanes: eight rays to an `f32x8` chunk, their slab tests, and the
//! per-ray state the walk keeps (search limit, active mask, coherence record).

use super::bound::{Bound, BoundBuilder};
use super::node::PacketNode;
use crate::geometry::Ray;
use crate::primitive::{lane, ray_rows, Lanes, PacketRays, CHUNKS, LANES, PACKET_RAYS};
use crate::traverse::lane8::F8;
#[cfg(doc)]
use crate::traverse::slab_reciprocal;
use crate::traverse::BoxTest;
use wide::f32x8;

/// The chunks a packet mask touches: (chunk, its 8-lane mask), lowest first.
#[inline(always)]
pub(crate) fn chunks(mut m: u64) -> impl Iterator<Item = (usize, u32)> {
    std::iter::from_fn(move || {
        (m != 0).then(|| {
            let k = m.trailing_zeros() as usize / LANES;
            let lanes = (m >> (LANES * k)) as u32 & 0xFF;
            m &= !(0xFF << (LANES * k));
            (k, lanes)
        })
    })
}

/// All bits set in the lanes whose bit is set in `bits`.
#[inline(always)]
fn lane_mask<V: F8>(cpu: V::Cpu, bits: u32) -> V {
    let lane = |j: u32| f32::from_bits(0u32.wrapping_sub(bits >> j & 1));
    V::load(
        cpu,
        &[
            lane(0),
            lane(1),
            lane(2),
            lane(3),
            lane(4),
            lane(5),
            lane(6),
            lane(7),
        ],
    )
}

/// `|x|` lane by lane (the sign bit cleared).
#[inline(always)]
fn abs8<V: F8>(cpu: V::Cpu, x: V) -> V {
    V::splat(cpu, f32::from_bits(0x7fff_ffff)).and(x)
}

/// [`slab_reciprocal`] in eight lanes: `1 / d`, NaN for a subnormal component.
#[inline(always)]
fn reciprocal8<V: F8>(cpu: V::Cpu, d: V) -> V {
    let subnormal = abs8(cpu, d)
        .lt(V::splat(cpu, f32::MIN_POSITIVE))
        .and(d.ne(V::splat(cpu, 0.0)));
    subnormal.select(V::splat(cpu, f32::NAN), V::splat(cpu, 1.0).div(d))
}

/// [`BoundBuilder`] fed eight rays at a time (the valid lanes of each chunk), on lanes `V`.
struct ChunkBound<V: F8> {
    cpu: V::Cpu,
    o_lo: [V; 3],
    o_hi: [V; 3],
    i_lo: [V; 3],
    i_hi: [V; 3],
    t_min_lo: V,
    t_max_hi: V,
    usable: [bool; 3],
    negs: [u32; 3],
    rays: u32,
}

impl<V: F8> ChunkBound<V> {
    #[inline(always)]
    fn new(cpu: V::Cpu) -> Self {
        let (inf, ninf) = (
            V::splat(cpu, f32::INFINITY),
            V::splat(cpu, f32::NEG_INFINITY),
        );
        ChunkBound {
            cpu,
            o_lo: [inf; 3],
            o_hi: [ninf; 3],
            i_lo: [inf; 3],
            i_hi: [ninf; 3],
            t_min_lo: inf,
            t_max_hi: ninf,
            usable: [true; 3],
            negs: [0; 3],
            rays: 0,
        }
    }

    /// Adds the `valid` lanes (`vm`: their lane mask) of a chunk.
    #[inline(always)]
    fn add(&mut self, o: [V; 3], inv: [V; 3], t_min: V, t_max: V, valid: u32, vm: V) {
        let cpu = self.cpu;
        let (inf, ninf) = (
            V::splat(cpu, f32::INFINITY),
            V::splat(cpu, f32::NEG_INFINITY),
        );
        let finite = |x: V| abs8(cpu, x).lt(inf);
        for a in 0..3 {
            self.negs[a] += (inv[a].bitmask() & valid).count_ones();
            let ok = finite(o[a])
                .and(finite(inv[a]))
                .and(inv[a].ne(V::splat(cpu, 0.0)));
            self.usable[a] &= ok.bitmask() & valid == valid;
            self.o_lo[a] = self.o_lo[a].min_nan_first(vm.select(o[a], inf));
            self.o_hi[a] = self.o_hi[a].max_nan_first(vm.select(o[a], ninf));
            self.i_lo[a] = self.i_lo[a].min_nan_first(vm.select(inv[a], inf));
            self.i_hi[a] = self.i_hi[a].max_nan_first(vm.select(inv[a], ninf));
        }
        self.t_min_lo = self.t_min_lo.min_nan_first(vm.select(t_min, inf));
        self.t_max_hi = self.t_max_hi.max_nan_first(vm.select(t_max, ninf));
        self.rays += valid.count_ones();
    }

    /// (Plain loops and `#[inline(always)]` closures: an iterator fold or `array::map` here
    /// was sometimes left as a call per chunk, a tenth of a render's time.)
    #[inline(always)]
    fn finish(&self) -> Bound {
        #[inline(always)]
        fn lo<V: F8>(x: V) -> f32 {
            let mut m = f32::INFINITY;
            for v in x.to_array() {
                m = m.min(v);
            }
            m
        }
        #[inline(always)]
        fn hi<V: F8>(x: V) -> f32 {
            let mut m = f32::NEG_INFINITY;
            for v in x.to_array() {
                m = m.max(v);
            }
            m
        }
        let (o, i) = (&self.o_lo, &self.i_lo);
        let (oh, ih) = (&self.o_hi, &self.i_hi);
        BoundBuilder::from_parts(
            [
                [lo(o[0]), hi(oh[0])],
                [lo(o[1]), hi(oh[1])],
                [lo(o[2]), hi(oh[2])],
            ],
            [
                [lo(i[0]), hi(ih[0])],
                [lo(i[1]), hi(ih[1])],
                [lo(i[2]), hi(ih[2])],
            ],
            self.usable,
            self.negs,
            self.rays,
            [lo(self.t_min_lo), hi(self.t_max_hi)],
        )
        .finish()
    }
}

/// Leaves a packet visits before [`RayPacket::came_apart`] judges it.
const PROBATION_LEAVES: u32 = 12;
/// Average rays per leaf visit below which the rest of a packet goes ray by ray. Measured
/// averages (512² eye rays in 8×8 tiles, shadow rays toward the first light): teapot12 20 and
/// 13, balls3 in patch mode 9 and 4.3, tetra9 1.7 and 1.2; packets pay on the first two.
const MIN_RAYS_PER_LEAF: u32 = 2;

/// Up to [`PACKET_RAYS`] rays in SIMD lanes, with their search limits.
pub(crate) struct RayPacket {
    /// Origins, directions and intervals, as a leaf test reads them.
    pub(crate) rays: PacketRays,
    inv: [Lanes; 3],
    /// All bits set where the reciprocal direction is negative (a select mask).
    neg: [Lanes; 3],
    /// Bit `i`: ray `i` is still searching.
    pub(crate) active: u64,
    pub(crate) bound: Bound,
    /// Leaves visited, and rays tested in them: how well the packet holds together.
    leaf_visits: u32,
    leaf_rays: u32,
}

/// Fills a [`RayPacket`] chunk by chunk from rays already in lanes `V`: what
/// [`RayPacket::pack`] does after gathering, and what a world's instance entry does with rays
/// it transformed in lanes, into one packet it reuses (no round trip through one `Ray` per
/// lane, no copy of the packet). Chunks never given stay inactive. On AVX lanes each step is
/// one instruction where `wide::f32x8` on baseline x86-64 takes two SSE halves: an instanced
/// packet builds a packet at every instance it enters.
pub(crate) struct PacketBuilder<V: F8> {
    bound: ChunkBound<V>,
}

impl<V: F8> PacketBuilder<V> {
    /// Starts over `p`: every ray of it inactive.
    #[inline(always)]
    pub(crate) fn over(cpu: V::Cpu, p: &mut RayPacket) -> PacketBuilder<V> {
        p.active = 0;
        p.rays.limit = [f32x8::NEG_INFINITY; CHUNKS];
        p.leaf_visits = 0;
        p.leaf_rays = 0;
        PacketBuilder {
            bound: ChunkBound::new(cpu),
        }
    }

    /// Chunk `k`'s rays into `p`: origins, directions, intervals, and `on`, the lanes traced.
    /// Lanes with a NaN `t_min` or `t_max` can hit nothing and stay inactive.
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn chunk(
        &mut self,
        p: &mut RayPacket,
        k: usize,
        o: [V; 3],
        d: [V; 3],
        t_min: V,
        t_max: V,
        on: u32,
    ) {
        let cpu = self.bound.cpu;
        // `x <= x` is false exactly for NaN.
        let numbers = t_min.le(t_min).and(t_max.le(t_max));
        let valid = on & numbers.bitmask();
        if valid == 0 {
            return;
        }
        p.active |= u64::from(valid) << (LANES * k);
        let vm = lane_mask::<V>(cpu, valid);
        let inv = [
            reciprocal8(cpu, d[0]),
            reciprocal8(cpu, d[1]),
            reciprocal8(cpu, d[2]),
        ];
        for a in 0..3 {
            o[a].store(&mut p.rays.o[a][k]);
            d[a].store(&mut p.rays.d[a][k]);
            inv[a].store(&mut p.inv[a][k]);
            inv[a].sign_fill().store(&mut p.neg[a][k]);
        }
        t_min.store(&mut p.rays.t_min[k]);
        vm.select(t_max, V::splat(cpu, f32::NEG_INFINITY))
            .store(&mut p.rays.limit[k]);
        self.bound.add(o, inv, t_min, t_max, valid, vm);
    }

    /// The packet's bound, once every chunk is in.
    #[inline(always)]
    pub(crate) fn finish(self, p: &mut RayPacket) {
        p.bound = self.bound.finish();
    }
}

impl RayPacket {
    /// Packs `rays` (at most [`PACKET_RAYS`]) into this packet, over whatever it held; bit
    /// `i` of `active` says whether ray `i` is traced. Rays with a NaN `t_min` or `t_max` can
    /// hit nothing and start inactive.
    ///
    /// Eight rays at a time: their fields gathered into lanes, then the reciprocals, the sign
    /// masks and the bound computed on whole chunks (the per-ray version was a third of a
    /// coherent packet's time). Each lane holds exactly what the single-ray kernels compute
    /// for its ray ([`slab_reciprocal`]'s values, bit for bit). Written in place: a packet
    /// returned by value is a 3.5 KB copy per packet.
    #[inline(always)]
    pub(crate) fn pack(&mut self, rays: &[Ray], active: u64) {
        debug_assert!(rays.len() <= PACKET_RAYS);
        let mut b = PacketBuilder::<f32x8>::over((), self);
        for (k, chunk) in rays.chunks(LANES).enumerate() {
            let f = match <&[Ray; LANES]>::try_from(chunk) {
                Ok(full) => ray_rows(full),
                Err(_) => {
                    // A partial chunk: the missing lanes repeat its first ray, inactive.
                    let mut full = [chunk[0]; LANES];
                    full[..chunk.len()].copy_from_slice(chunk);
                    ray_rows(&full)
                }
            };
            let on = (active >> (LANES * k)) as u32 & (u32::MAX >> (32 - chunk.len()));
            b.chunk(
                self,
                k,
                [f[0], f[1], f[2]],
                [f[3], f[4], f[5]],
                f[6],
                f[7],
                on,
            );
        }
        b.finish(self);
    }

    /// A new packet of `rays`, as [`RayPacket::pack`] makes it.
    #[cfg(test)]
    pub(crate) fn new(rays: &[Ray], active: u64) -> RayPacket {
        let mut p = RayPacket::empty();
        p.pack(rays, active);
        p
    }

    /// A packet of no rays, to be filled by a [`PacketBuilder`].
    #[inline(always)]
    pub(crate) fn empty() -> RayPacket {
        let zero = [f32x8::ZERO; CHUNKS];
        RayPacket {
            rays: PacketRays {
                o: [zero; 3],
                d: [zero; 3],
                t_min: zero,
                limit: [f32x8::NEG_INFINITY; CHUNKS],
            },
            inv: [zero; 3],
            neg: [zero; 3],
            active: 0,
            bound: BoundBuilder::new().finish(),
            leaf_visits: 0,
            leaf_rays: 0,
        }
    }

    /// Ray `i`'s search limit.
    #[inline(always)]
    pub(crate) fn limit(&self, i: usize) -> f32 {
        self.rays.limit(i)
    }

    /// Shortens ray `i`'s search to `t` (a nearer hit was found).
    #[inline(always)]
    pub(crate) fn set_limit(&mut self, i: usize, t: f32) {
        self.rays.set_limit(i, t)
    }

    /// Lowers the bound's `t_max` after hits shortened some rays.
    #[inline(always)]
    pub(crate) fn refresh_limit_bound(&mut self) {
        let mut m = f32x8::NEG_INFINITY;
        for &l in &self.rays.limit {
            m = m.fast_max(l);
        }
        let mut hi = f32::NEG_INFINITY;
        for v in m.to_array() {
            hi = hi.max(v);
        }
        self.bound.t_max_hi = hi;
    }

    /// Ray `i` prepared for a node format's test of all its children.
    #[inline(always)]
    pub(crate) fn first<N: PacketNode, V: F8>(&self, cpu: V::Cpu, i: usize) -> N::First<V> {
        let (o, inv) = (&self.rays.o, &self.inv);
        N::first::<V>(
            cpu,
            [lane(&o[0], i), lane(&o[1], i), lane(&o[2], i)],
            [lane(&inv[0], i), lane(&inv[1], i), lane(&inv[2], i)],
            lane(&self.rays.t_min, i),
        )
    }

    /// The slab test of chunk `k`'s rays against box `b` (`[min xyz, max xyz]`): the mask of
    /// lanes entering it within their limits, and their entry distances. Per lane this is the
    /// single-ray slab test's arithmetic exactly.
    #[inline(always)]
    fn enter_chunk<V: F8, B: BoxTest>(&self, cpu: V::Cpu, k: usize, b: &[f32; 6]) -> (u32, V) {
        self.enter_chunk_planes::<V, B>(
            cpu,
            k,
            #[inline(always)]
            |row| V::splat(cpu, b[row]),
        )
    }

    /// [`RayPacket::enter_chunk`] with the box's planes given in lanes by `plane(row)` (rows
    /// as [`Bvh8Node::planes`](crate::layout::Bvh8Node::planes) orders them).
    #[inline(always)]
    fn enter_chunk_planes<V: F8, B: BoxTest>(
        &self,
        cpu: V::Cpu,
        k: usize,
        plane: impl Fn(usize) -> V,
    ) -> (u32, V) {
        let slack = V::splat(cpu, B::SLACK);
        let mut near = V::of(cpu, &self.rays.t_min[k]);
        let mut far = V::of(cpu, &self.rays.limit[k]).mul(slack);
        for a in 0..3 {
            let (lo, hi) = (plane(a), plane(3 + a));
            let neg = V::of(cpu, &self.neg[a][k]);
            let (pn, pf) = (neg.select(hi, lo), neg.select(lo, hi));
            let (o, inv) = (V::of(cpu, &self.rays.o[a][k]), V::of(cpu, &self.inv[a][k]));
            let tn = pn.sub(o).mul(inv);
            let tf = pf.sub(o).mul(inv);
            near = tn.max_nan_first(near);
            far = tf.mul(slack).min_nan_first(far);
        }
        (near.le_bits(far), near)
    }

    /// The active rays of `mask` that enter a box moving over the shutter, each meeting it
    /// where it is at the ray's own time (`times[k][l]` for ray `LANES * k + l`): `ends` holds
    /// its planes at time 0 and their change to time 1, which lane `l` takes as
    /// `start + delta * time` (the arithmetic of the single-ray walk over
    /// [`Bvh8Ends`](crate::layout::ends::Bvh8Ends)). Not counted toward the packet's coherence.
    #[inline(always)]
    pub(crate) fn entering_moving<V: F8, B: BoxTest>(
        &self,
        cpu: V::Cpu,
        ends: &[[f32; 6]; 2],
        times: &[[f32; LANES]; CHUNKS],
        mask: u64,
    ) -> u64 {
        let mut out = 0u64;
        for (k, bits) in chunks(self.active & mask) {
            let time = V::load(cpu, &times[k]);
            let (m, _) = self.enter_chunk_planes::<V, B>(
                cpu,
                k,
                #[inline(always)]
                |row| V::splat(cpu, ends[0][row]).add(V::splat(cpu, ends[1][row]).mul(time)),
            );
            out |= ((bits & m) as u64) << (LANES * k);
        }
        out
    }

    /// The first active ray of `mask` that enters `b`, with its entry distance.
    #[inline(always)]
    pub(crate) fn find_first<V: F8, B: BoxTest>(
        &self,
        cpu: V::Cpu,
        b: &[f32; 6],
        mask: u64,
    ) -> Option<(usize, f32)> {
        for (k, bits) in chunks(self.active & mask) {
            let (m, near) = self.enter_chunk::<V, B>(cpu, k, b);
            let m = m & bits;
            if m != 0 {
                let j = m.trailing_zeros() as usize;
                return Some((LANES * k + j, near.to_array()[j]));
            }
        }
        None
    }

    /// The active rays of `mask` that enter `b`, and the entry distance of the first.
    #[inline(always)]
    pub(crate) fn enter_all<V: F8, B: BoxTest>(
        &self,
        cpu: V::Cpu,
        b: &[f32; 6],
        mask: u64,
    ) -> (u64, f32) {
        let (mut out, mut t) = (0u64, 0.0);
        for (k, bits) in chunks(self.active & mask) {
            let (m, near) = self.enter_chunk::<V, B>(cpu, k, b);
            let m = m & bits;
            if out == 0 && m != 0 {
                t = near.to_array()[m.trailing_zeros() as usize];
            }
            out |= (m as u64) << (LANES * k);
        }
        (out, t)
    }

    /// The active rays of `mask` that enter leaf box `b`, counted toward the packet's
    /// coherence record ([`RayPacket::came_apart`]).
    #[inline(always)]
    pub(crate) fn entering<V: F8, B: BoxTest>(
        &mut self,
        cpu: V::Cpu,
        b: &[f32; 6],
        mask: u64,
    ) -> u64 {
        let mut out = 0u64;
        for (k, bits) in chunks(self.active & mask) {
            out |= ((bits & self.enter_chunk::<V, B>(cpu, k, b).0) as u64) << (LANES * k);
        }
        self.leaf_rays += out.count_ones();
        self.leaf_visits += 1;
        out
    }

    /// True once the packet has shown, over enough leaves, that its rays go separate ways:
    /// so few rays share each leaf that the packet's searches cost more than they share.
    #[inline(always)]
    pub(crate) fn came_apart(&self) -> bool {
        self.leaf_visits >= PROBATION_LEAVES
            && self.leaf_rays < MIN_RAYS_PER_LEAF * self.leaf_visits
    }

    /// Retires ray `i`: it takes part in no further test.
    #[inline(always)]
    pub(crate) fn retire(&mut self, i: usize) {
        self.active &= !(1 << i);
        self.rays.set_limit(i, f32::NEG_INFINITY);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::traverse::simd::bits;
    use glam::Vec3A;

    fn ray(k: usize) -> Ray {
        Ray::segment(Vec3A::new(k as f32, 0.0, -1.0), Vec3A::Z, 0.0, 10.0)
    }

    #[test]
    fn chunks_split_a_64_bit_mask_into_eight_lane_masks() {
        assert_eq!(chunks(0).count(), 0);
        assert_eq!(
            chunks(u64::MAX).collect::<Vec<_>>(),
            (0..8).map(|k| (k, 0xFF)).collect::<Vec<_>>()
        );
        assert_eq!(
            chunks(1 << 63 | 1).collect::<Vec<_>>(),
            vec![(0, 1), (7, 0x80)]
        );
        assert_eq!(chunks(0xF0 << 8).collect::<Vec<_>>(), vec![(1, 0xF0)]);
    }

    #[test]
    fn all_64_lanes_and_the_edges_of_the_mask_are_traced() {
        let rays: Vec<Ray> = (0..64).map(ray).collect();
        // A box over x in [-0.5, 63.5] is entered by every ray; each lane reads back its ray.
        let b = [-0.5, -1.0, 0.0, 63.5, 1.0, 1.0];
        for active in [u64::MAX, 1, 1 << 63, 1 << 63 | 1, 0xFF00_0000_0000_00FF, 0] {
            let mut p = RayPacket::new(&rays, active);
            assert_eq!(p.active, active);
            assert_eq!(
                p.entering::<f32x8, crate::traverse::FastBoxes>((), &b, u64::MAX),
                active
            );
            for i in bits(active) {
                assert_eq!(p.rays.ray(i), rays[i]);
            }
            if active != 0 {
                let first = active.trailing_zeros() as usize;
                assert_eq!(
                    p.find_first::<f32x8, crate::traverse::FastBoxes>((), &b, u64::MAX),
                    Some((first, 1.0))
                );
            }
        }
    }

    #[test]
    fn packing_gives_each_lane_the_single_ray_values_and_the_per_ray_bound() {
        // Awkward directions (zeros of both signs, subnormals, NaN, huge), NaN intervals,
        // partial packets and sparse active masks.
        let mut rng = crate::rng::Rng::new(5);
        let odd = [0.0, -0.0, 1e-40, -1e-40, f32::NAN, 3e38, -2.5, 1.0];
        for round in 0..500u64 {
            let n = 1 + (rng.next_u64() % 64) as usize;
            let rays: Vec<Ray> = (0..n)
                .map(|i| {
                    let mut d = rng.in_box(Vec3A::splat(-1.0), Vec3A::ONE);
                    if (i as u64 + round).is_multiple_of(3) {
                        d[i % 3] = odd[(rng.next_u64() % 8) as usize];
                    }
                    let o = rng.in_box(Vec3A::splat(-5.0), Vec3A::splat(5.0));
                    let t_max = if i % 17 == 3 {
                        f32::NAN
                    } else {
                        10.0 + i as f32
                    };
                    Ray::segment(o, d, 0.01 * (i % 5) as f32, t_max)
                })
                .collect();
            let active = if round % 2 == 0 {
                u64::MAX
            } else {
                rng.next_u64()
            };
            let p = RayPacket::new(&rays, active);
            let mut b = BoundBuilder::new();
            for (i, r) in rays.iter().enumerate() {
                let on = active >> i & 1 == 1 && !r.t_min.is_nan() && !r.t_max.is_nan();
                assert_eq!(p.active >> i & 1 == 1, on, "round {round} ray {i}");
                if !on {
                    assert_eq!(p.limit(i), f32::NEG_INFINITY);
                    continue;
                }
                let inv = crate::traverse::slab_reciprocal(r.dir);
                b.add(r.origin, inv, r.t_min, r.t_max);
                for a in 0..3 {
                    assert_eq!(lane(&p.inv[a], i).to_bits(), inv[a].to_bits(), "{r:?}");
                    assert_eq!(lane(&p.neg[a], i).to_bits() != 0, inv[a].is_sign_negative());
                }
                let bits = |r: Ray| {
                    let (o, d): ([f32; 3], [f32; 3]) = (r.origin.into(), r.dir.into());
                    [o, d, [r.t_min, r.t_max, 0.0]].map(|v| v.map(f32::to_bits))
                };
                assert_eq!(bits(p.rays.ray(i)), bits(*r), "{r:?}");
            }
            assert_eq!(
                format!("{:?}", p.bound),
                format!("{:?}", b.finish()),
                "round {round}"
            );
        }
    }

    #[test]
    fn a_box_entered_only_by_the_last_lane_is_found() {
        let rays: Vec<Ray> = (0..64).map(ray).collect();
        let p = RayPacket::new(&rays, u64::MAX);
        let b = [62.5, -1.0, 0.0, 63.5, 1.0, 1.0];
        assert_eq!(
            p.enter_all::<f32x8, crate::traverse::FastBoxes>((), &b, u64::MAX),
            (1 << 63, 1.0)
        );
        assert_eq!(
            p.find_first::<f32x8, crate::traverse::FastBoxes>((), &b, !(1 << 63)),
            None
        );
    }

    #[test]
    fn retired_and_nan_interval_rays_take_part_in_nothing() {
        let mut rays: Vec<Ray> = (0..64).map(ray).collect();
        rays[5].t_max = f32::NAN;
        rays[6].t_min = f32::NAN;
        let mut p = RayPacket::new(&rays, u64::MAX);
        assert_eq!(p.active, !(1 << 5 | 1 << 6));
        p.retire(7);
        let b = [-0.5, -1.0, 0.0, 63.5, 1.0, 1.0];
        let entered = p.entering::<f32x8, crate::traverse::FastBoxes>((), &b, u64::MAX);
        assert_eq!(entered & (1 << 5 | 1 << 6 | 1 << 7), 0);
        assert_eq!(entered.count_ones(), 61);
    }

    #[test]
    fn came_apart_after_probation_when_under_two_rays_share_a_leaf() {
        let rays: Vec<Ray> = (0..64).map(ray).collect();
        let mut p = RayPacket::new(&rays, u64::MAX);
        let b = |x: f32| [x - 0.5, -1.0, 0.0, x + 0.5, 1.0, 1.0];
        // Eleven leaves of one ray each: still on probation.
        for k in 0..11 {
            p.entering::<f32x8, crate::traverse::FastBoxes>((), &b(k as f32), u64::MAX);
        }
        assert!(!p.came_apart());
        // The twelfth leaf shared by all 64 lifts the average to (11 + 64) / 12 > 2.
        p.entering::<f32x8, crate::traverse::FastBoxes>(
            (),
            &[-0.5, -1.0, 0.0, 63.5, 1.0, 1.0],
            u64::MAX,
        );
        assert!(!p.came_apart());
        let mut q = RayPacket::new(&rays, u64::MAX);
        for k in 0..12 {
            q.entering::<f32x8, crate::traverse::FastBoxes>((), &b(k as f32), u64::MAX);
        }
        assert!(
            q.came_apart(),
            "12 leaves at one ray each: 1 < 2 rays per leaf"
        );
    }
}
