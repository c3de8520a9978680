//! A packet's rays in SIMD lanes: eight rays to an `f32x8` chunk, their slab tests, and the
//! per-ray state the walk keeps (search limit, active mask, coherence record).

use super::bound::{Bound, BoundBuilder};
use super::node::PacketNode;
use super::{CHUNKS, LANES, PACKET_RAYS};
use crate::geometry::Ray;
use crate::traverse::lane8::F8;
use crate::traverse::{slab_reciprocal, BoxTest};
use glam::Vec3A;
use wide::f32x8;

/// One value per ray of a packet, eight rays to a SIMD chunk.
pub(super) type Lanes = [f32x8; CHUNKS];

#[inline(always)]
pub(super) fn lane(l: &Lanes, i: usize) -> f32 {
    bytemuck::cast_ref::<Lanes, [f32; PACKET_RAYS]>(l)[i]
}

#[inline(always)]
fn lane_mut(l: &mut Lanes, i: usize) -> &mut f32 {
    &mut bytemuck::cast_mut::<Lanes, [f32; PACKET_RAYS]>(l)[i]
}

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

/// Leaves a packet visits before [`RayPacket::came_apart`] judges it.
const PROBATION_LEAVES: u32 = 12;
/// Average rays per leaf visit below which the rest of a packet goes ray by ray. Measured
/// averages (512² eye rays in 8×8 tiles, shadow rays toward the first light): teapot12 20 and
/// 13, balls3 in patch mode 9 and 4.3, tetra9 1.7 and 1.2; packets pay on the first two.
const MIN_RAYS_PER_LEAF: u32 = 2;

/// Up to [`PACKET_RAYS`] rays in SIMD lanes, with their search limits.
pub(crate) struct RayPacket {
    pub(crate) o: [Lanes; 3],
    pub(crate) d: [Lanes; 3],
    inv: [Lanes; 3],
    /// All bits set where the reciprocal direction is negative (a select mask).
    neg: [Lanes; 3],
    pub(crate) t_min: Lanes,
    /// How far each ray still searches: `t_max`, then the best hit so far; `-inf` once a ray
    /// is inactive, so every test fails for it.
    pub(crate) limit: Lanes,
    /// Bit `i`: ray `i` is still searching.
    pub(super) active: u64,
    pub(super) bound: Bound,
    /// Leaves visited, and rays tested in them: how well the packet holds together.
    leaf_visits: u32,
    leaf_rays: u32,
}

impl RayPacket {
    /// Packs `rays` (at most [`PACKET_RAYS`]); bit `i` of `active` says whether ray `i` is
    /// traced. Rays with a NaN `t_min` or `t_max` can hit nothing and start inactive.
    #[inline(always)]
    pub(super) fn new(rays: &[Ray], active: u64) -> RayPacket {
        debug_assert!(rays.len() <= PACKET_RAYS);
        let zero = [f32x8::ZERO; CHUNKS];
        let mut p = RayPacket {
            o: [zero; 3],
            d: [zero; 3],
            inv: [zero; 3],
            neg: [zero; 3],
            t_min: zero,
            limit: [f32x8::NEG_INFINITY; CHUNKS],
            active: 0,
            bound: BoundBuilder::new().finish(),
            leaf_visits: 0,
            leaf_rays: 0,
        };
        let mut bound = BoundBuilder::new();
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
                    o[a][i] = ray.origin[a];
                    d[a][i] = ray.dir[a];
                    inv_l[a][i] = inv[a];
                    neg[a][i] = if inv[a].is_sign_negative() {
                        all_ones
                    } else {
                        0.0
                    };
                }
                t_min[i] = ray.t_min;
                limit[i] = ray.t_max;
                bound.add(ray.origin, inv, ray.t_min, ray.t_max);
            }
        }
        p.bound = bound.finish();
        p
    }

    /// Ray `i` with its current search limit as `t_max`.
    #[inline(always)]
    pub(crate) fn ray(&self, i: usize) -> Ray {
        let at = |l: &Lanes| lane(l, i);
        Ray::segment(
            Vec3A::new(at(&self.o[0]), at(&self.o[1]), at(&self.o[2])),
            Vec3A::new(at(&self.d[0]), at(&self.d[1]), at(&self.d[2])),
            at(&self.t_min),
            at(&self.limit),
        )
    }

    /// Ray `i`'s search limit.
    #[inline(always)]
    pub(super) fn limit(&self, i: usize) -> f32 {
        lane(&self.limit, i)
    }

    /// Shortens ray `i`'s search to `t` (a nearer hit was found).
    #[inline(always)]
    pub(crate) fn set_limit(&mut self, i: usize, t: f32) {
        *lane_mut(&mut self.limit, i) = t;
    }

    /// Lowers the bound's `t_max` after hits shortened some rays.
    #[inline(always)]
    pub(super) fn refresh_limit_bound(&mut self) {
        let m = self
            .limit
            .iter()
            .fold(f32x8::NEG_INFINITY, |m, &l| m.fast_max(l));
        self.bound.t_max_hi = m.to_array().into_iter().fold(f32::NEG_INFINITY, f32::max);
    }

    /// Ray `i` prepared for a node format's test of all its children.
    #[inline(always)]
    pub(super) fn first<N: PacketNode, V: F8>(&self, i: usize) -> N::First<V> {
        N::first::<V>(
            [0, 1, 2].map(|a| lane(&self.o[a], i)),
            [0, 1, 2].map(|a| lane(&self.inv[a], i)),
            lane(&self.t_min, i),
        )
    }

    /// The slab test of chunk `k`'s rays against box `b` (`[min xyz, max xyz]`): the mask of
    /// lanes entering it within their limits, and their entry distances. Per lane this is the
    /// single-ray slab test's arithmetic exactly.
    #[inline(always)]
    fn enter_chunk<V: F8, B: BoxTest>(&self, k: usize, b: &[f32; 6]) -> (u32, V) {
        let slack = V::splat(B::SLACK);
        let mut near = V::of(&self.t_min[k]);
        let mut far = V::of(&self.limit[k]).mul(slack);
        for a in 0..3 {
            let (lo, hi) = (V::splat(b[a]), V::splat(b[3 + a]));
            let neg = V::of(&self.neg[a][k]);
            let (pn, pf) = (neg.select(hi, lo), neg.select(lo, hi));
            let (o, inv) = (V::of(&self.o[a][k]), V::of(&self.inv[a][k]));
            let tn = pn.sub(o).mul(inv);
            let tf = pf.sub(o).mul(inv);
            near = tn.max_nan_first(near);
            far = tf.mul(slack).min_nan_first(far);
        }
        (near.le(far).bitmask(), near)
    }

    /// The first active ray of `mask` that enters `b`, with its entry distance.
    #[inline(always)]
    pub(super) fn find_first<V: F8, B: BoxTest>(
        &self,
        b: &[f32; 6],
        mask: u64,
    ) -> Option<(usize, f32)> {
        for (k, bits) in chunks(self.active & mask) {
            let (m, near) = self.enter_chunk::<V, B>(k, b);
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
    pub(super) fn enter_all<V: F8, B: BoxTest>(&self, b: &[f32; 6], mask: u64) -> (u64, f32) {
        let (mut out, mut t) = (0u64, 0.0);
        for (k, bits) in chunks(self.active & mask) {
            let (m, near) = self.enter_chunk::<V, B>(k, b);
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
    pub(super) fn entering<V: F8, B: BoxTest>(&mut self, b: &[f32; 6], mask: u64) -> u64 {
        let mut out = 0u64;
        for (k, bits) in chunks(self.active & mask) {
            out |= ((bits & self.enter_chunk::<V, B>(k, b).0) as u64) << (LANES * k);
        }
        self.leaf_rays += out.count_ones();
        self.leaf_visits += 1;
        out
    }

    /// True once the packet has shown, over enough leaves, that its rays go separate ways:
    /// so few rays share each leaf that the packet's searches cost more than they share.
    #[inline(always)]
    pub(super) fn came_apart(&self) -> bool {
        self.leaf_visits >= PROBATION_LEAVES
            && self.leaf_rays < MIN_RAYS_PER_LEAF * self.leaf_visits
    }

    /// Retires ray `i`: it takes part in no further test.
    #[inline(always)]
    pub(super) fn retire(&mut self, i: usize) {
        self.active &= !(1 << i);
        *lane_mut(&mut self.limit, i) = f32::NEG_INFINITY;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::traverse::simd::bits;

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
                p.entering::<f32x8, crate::traverse::FastBoxes>(&b, u64::MAX),
                active
            );
            for i in bits(active) {
                assert_eq!(p.ray(i), rays[i]);
            }
            if active != 0 {
                let first = active.trailing_zeros() as usize;
                assert_eq!(
                    p.find_first::<f32x8, crate::traverse::FastBoxes>(&b, u64::MAX),
                    Some((first, 1.0))
                );
            }
        }
    }

    #[test]
    fn a_box_entered_only_by_the_last_lane_is_found() {
        let rays: Vec<Ray> = (0..64).map(ray).collect();
        let p = RayPacket::new(&rays, u64::MAX);
        let b = [62.5, -1.0, 0.0, 63.5, 1.0, 1.0];
        assert_eq!(
            p.enter_all::<f32x8, crate::traverse::FastBoxes>(&b, u64::MAX),
            (1 << 63, 1.0)
        );
        assert_eq!(
            p.find_first::<f32x8, crate::traverse::FastBoxes>(&b, !(1 << 63)),
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
        let entered = p.entering::<f32x8, crate::traverse::FastBoxes>(&b, u64::MAX);
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
            p.entering::<f32x8, crate::traverse::FastBoxes>(&b(k as f32), u64::MAX);
        }
        assert!(!p.came_apart());
        // The twelfth leaf shared by all 64 lifts the average to (11 + 64) / 12 > 2.
        p.entering::<f32x8, crate::traverse::FastBoxes>(
            &[-0.5, -1.0, 0.0, 63.5, 1.0, 1.0],
            u64::MAX,
        );
        assert!(!p.came_apart());
        let mut q = RayPacket::new(&rays, u64::MAX);
        for k in 0..12 {
            q.entering::<f32x8, crate::traverse::FastBoxes>(&b(k as f32), u64::MAX);
        }
        assert!(
            q.came_apart(),
            "12 leaves at one ray each: 1 < 2 rays per leaf"
        );
    }
}
