//! The packet's cull test: an interval-arithmetic bound over every active ray's origin and
//! reciprocal direction, which rejects in one 4-wide test the child boxes no ray of the
//! packet can enter.

use crate::traverse::lane8::F8;
use crate::traverse::BoxTest;
use glam::Vec3A;
use wide::f32x4;

/// One axis of the bound: every active ray's origin and reciprocal direction lie in these
/// ranges, and all reciprocals share a sign, so the near and far planes are the same rows for
/// every ray.
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

/// Bounds on what any active ray of a packet can compute in a slab test.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Bound {
    axes: [Option<AxisBound>; 3],
    t_min_lo: f32,
    /// The largest search limit of any active ray; lowered as hits shorten rays.
    pub t_max_hi: f32,
}

impl Bound {
    /// Mask of the four boxes (`[min xyz, max xyz]` rows) some active ray may enter. Sound
    /// because subtraction and multiplication round monotonically: `fl(p - o)` lies between
    /// its values at the ends of `o`'s range, and `fl(x · i)` between its values at the ends
    /// of `i`'s range.
    #[inline(always)]
    pub fn may_enter<B: BoxTest>(&self, p: &[f32x4; 6]) -> u32 {
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

impl Bound {
    /// [`Bound::may_enter`] for the eight boxes of an 8-wide node (`[[f32; 8]; 6]` rows), in
    /// lanes of `V`.
    #[inline(always)]
    pub fn may_enter8<V: F8, B: BoxTest>(&self, cpu: V::Cpu, p: &[[f32; 8]; 6]) -> u32 {
        let slack = V::splat(cpu, B::SLACK);
        let mut lo = V::splat(cpu, self.t_min_lo);
        let mut hi = V::splat(cpu, self.t_max_hi * B::SLACK);
        for ax in self.axes.iter().flatten() {
            let (i_lo, i_hi) = (V::splat(cpu, ax.i_lo), V::splat(cpu, ax.i_hi));
            let xn = V::load(cpu, &p[ax.near_row]).sub(V::splat(cpu, ax.o_near));
            lo = lo.max_nan_first(xn.mul(i_lo).min_nan_first(xn.mul(i_hi)));
            let xf = V::load(cpu, &p[ax.far_row]).sub(V::splat(cpu, ax.o_far));
            hi = hi.min_nan_first(xf.mul(i_lo).max_nan_first(xf.mul(i_hi)).mul(slack));
        }
        lo.le_bits(hi)
    }
}

/// Gathers a [`Bound`] ray by ray.
pub(super) struct BoundBuilder {
    o_lo: Vec3A,
    o_hi: Vec3A,
    i_lo: Vec3A,
    i_hi: Vec3A,
    /// Per axis: every value so far suits the bound (finite origins, finite non-zero
    /// reciprocals). Otherwise a product can be NaN, which the per-ray test ignores but an
    /// interval cannot represent; such an axis does not cull.
    usable: [bool; 3],
    negs: [u32; 3],
    rays: u32,
    t_min_lo: f32,
    t_max_hi: f32,
}

impl BoundBuilder {
    #[inline(always)]
    pub fn new() -> Self {
        BoundBuilder {
            o_lo: Vec3A::INFINITY,
            o_hi: Vec3A::NEG_INFINITY,
            i_lo: Vec3A::INFINITY,
            i_hi: Vec3A::NEG_INFINITY,
            usable: [true; 3],
            negs: [0; 3],
            rays: 0,
            t_min_lo: f32::INFINITY,
            t_max_hi: f32::NEG_INFINITY,
        }
    }

    /// A builder that has seen rays with these ranges (per axis: origin `[lo, hi]`,
    /// reciprocal `[lo, hi]`), per-axis usability and negative counts, ray count and
    /// `[t_min lo, t_max hi]`.
    #[inline(always)]
    pub fn from_parts(
        o: [[f32; 2]; 3],
        i: [[f32; 2]; 3],
        usable: [bool; 3],
        negs: [u32; 3],
        rays: u32,
        t: [f32; 2],
    ) -> Self {
        BoundBuilder {
            o_lo: Vec3A::new(o[0][0], o[1][0], o[2][0]),
            o_hi: Vec3A::new(o[0][1], o[1][1], o[2][1]),
            i_lo: Vec3A::new(i[0][0], i[1][0], i[2][0]),
            i_hi: Vec3A::new(i[0][1], i[1][1], i[2][1]),
            usable,
            negs,
            rays,
            t_min_lo: t[0],
            t_max_hi: t[1],
        }
    }

    /// Adds an active ray: its origin, slab reciprocals and interval (the packet adds whole
    /// chunks and hands over [`BoundBuilder::from_parts`]; this is the reference the tests
    /// build bounds with).
    #[cfg(test)]
    #[inline(always)]
    pub fn add(&mut self, origin: Vec3A, inv: Vec3A, t_min: f32, t_max: f32) {
        for a in 0..3 {
            self.negs[a] += inv[a].is_sign_negative() as u32;
            self.usable[a] &= origin[a].is_finite() && inv[a].is_finite() && inv[a] != 0.0;
        }
        self.o_lo = self.o_lo.min(origin);
        self.o_hi = self.o_hi.max(origin);
        self.i_lo = self.i_lo.min(inv);
        self.i_hi = self.i_hi.max(inv);
        self.rays += 1;
        self.t_min_lo = self.t_min_lo.min(t_min);
        self.t_max_hi = self.t_max_hi.max(t_max);
    }

    /// The bound: an axis culls only when every ray's values there suit it and all its
    /// reciprocals share a sign.
    #[inline(always)]
    pub fn finish(&self) -> Bound {
        let n = self.rays;
        let axis = |a: usize| {
            let all_neg = self.negs[a] == n;
            if n == 0 || !self.usable[a] || (self.negs[a] != 0 && !all_neg) {
                return None;
            }
            Some(AxisBound {
                near_row: if all_neg { a + 3 } else { a },
                far_row: if all_neg { a } else { a + 3 },
                o_near: if all_neg { self.o_lo[a] } else { self.o_hi[a] },
                o_far: if all_neg { self.o_hi[a] } else { self.o_lo[a] },
                i_lo: self.i_lo[a],
                i_hi: self.i_hi[a],
            })
        };
        Bound {
            axes: [axis(0), axis(1), axis(2)],
            t_min_lo: self.t_min_lo,
            t_max_hi: self.t_max_hi,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Rng;
    use crate::traverse::bvh4::Ray4;
    use crate::traverse::{slab_reciprocal, ConservativeBoxes, FastBoxes};
    use crate::{Aabb, Ray};
    use bytemuck::Zeroable;

    /// Four boxes as the plane rows a node hands the slab test.
    fn rows(boxes: [Aabb; 4]) -> [f32x4; 6] {
        let row =
            |r: usize| f32x4::from(boxes.map(|b| if r < 3 { b.min[r] } else { b.max[r - 3] }));
        [0, 1, 2, 3, 4, 5].map(row)
    }

    /// Four random boxes, the last one flat.
    fn boxes(rng: &mut Rng, scale: f32) -> [f32x4; 6] {
        let mut out = [Aabb::EMPTY; 4];
        for (i, b) in out.iter_mut().enumerate() {
            let c = rng.in_box(Vec3A::splat(-scale), Vec3A::splat(scale));
            let mut e = rng.in_box(Vec3A::ZERO, Vec3A::splat(scale * 0.3));
            if i == 3 {
                e.y = 0.0;
            }
            *b = Aabb::new(c - e, c + e);
        }
        rows(out)
    }

    /// Rays of a packet: origins spread around a point, directions around a direction, in a
    /// mix of kinds (parallel to an axis with either zero sign, mixed signs, segments).
    fn rays(rng: &mut Rng, kind: u64) -> Vec<Ray> {
        let o = rng.in_box(Vec3A::splat(-4.0), Vec3A::splat(4.0));
        let d = rng.in_box(Vec3A::splat(-1.0), Vec3A::ONE);
        (0..1 + rng.next_u64() % 64)
            .map(|_| {
                let mut dir = d + rng.in_box(Vec3A::splat(-0.2), Vec3A::splat(0.2));
                match kind % 4 {
                    1 => dir.x = 0.0,
                    2 => dir.z = -0.0,
                    3 => dir = rng.in_box(Vec3A::splat(-1.0), Vec3A::ONE),
                    _ => {}
                }
                let origin = o + rng.in_box(Vec3A::splat(-0.5), Vec3A::splat(0.5));
                let t = (rng.next_u64() % 16) as f32;
                Ray::segment(origin, dir, t * 0.1, t + 0.5 + (rng.next_u64() % 3) as f32)
            })
            .collect()
    }

    fn check<B: BoxTest>(seed: u64) {
        let mut rng = Rng::new(seed);
        for round in 0..2000u64 {
            let rays = rays(&mut rng, round);
            let p = boxes(&mut rng, 3.0);
            let mut b = BoundBuilder::new();
            for r in &rays {
                b.add(r.origin, slab_reciprocal(r.dir), r.t_min, r.t_max);
            }
            let may = b.finish().may_enter::<B>(&p);
            for r in &rays {
                let inv = slab_reciprocal(r.dir);
                let (_, enters) = Ray4::from_parts(r.origin.into(), inv.into(), r.t_min)
                    .enter::<B>(&p, r.t_max * B::SLACK);
                assert_eq!(
                    enters & !may,
                    0,
                    "round {round}: the bound culls a box {r:?} enters ({enters:04b} vs {may:04b})"
                );
            }
        }
    }

    #[test]
    fn the_bound_never_culls_a_box_an_active_ray_enters() {
        check::<FastBoxes>(1);
        check::<ConservativeBoxes>(2);
    }

    /// The 8-wide cull test against each ray's 8-wide slab test, in lanes of `V`.
    fn check8<V: F8, B: BoxTest>(cpu: V::Cpu, seed: u64) {
        let mut rng = Rng::new(seed);
        for round in 0..2000u64 {
            let rays = rays(&mut rng, round);
            let (a, b) = (boxes(&mut rng, 3.0), boxes(&mut rng, 3.0));
            let mut node = crate::layout::Bvh8Node::zeroed();
            for r in 0..6 {
                for i in 0..4 {
                    node.planes[r][i] = a[r].as_array()[i];
                    node.planes[r][4 + i] = b[r].as_array()[i];
                }
            }
            let mut bb = BoundBuilder::new();
            for r in &rays {
                bb.add(r.origin, slab_reciprocal(r.dir), r.t_min, r.t_max);
            }
            let may = bb.finish().may_enter8::<V, B>(cpu, &node.planes);
            assert_eq!(
                may & 0x0F,
                bb.finish().may_enter::<B>(&a),
                "round {round}: the 8-wide bound differs from the 4-wide one"
            );
            for r in &rays {
                let (_, enters) = crate::traverse::bvh8::Ray8::<V>::new(cpu, r)
                    .enter::<B>(&node, r.t_max * B::SLACK);
                assert_eq!(enters & !may, 0, "round {round}: culls a box {r:?} enters");
            }
        }
    }

    #[test]
    fn the_8_wide_bound_never_culls_a_box_an_active_ray_enters() {
        check8::<wide::f32x8, FastBoxes>((), 3);
        check8::<wide::f32x8, ConservativeBoxes>((), 4);
        #[cfg(target_arch = "x86_64")]
        if let Some(cpu) = crate::isa::Avx2Cpu::detect() {
            check8::<crate::traverse::lane8::Avx, FastBoxes>(cpu, 3);
            check8::<crate::traverse::lane8::Avx, ConservativeBoxes>(cpu, 4);
        }
    }

    #[test]
    fn the_bound_culls_boxes_behind_every_ray() {
        // All rays go +x from x < 0; a box at x in [-9, -8] is behind them all.
        let mut b = BoundBuilder::new();
        for k in 0..8 {
            let o = Vec3A::new(-1.0, 0.1 * k as f32, 0.0);
            b.add(
                o,
                slab_reciprocal(Vec3A::new(1.0, 0.05, 0.02)),
                0.0,
                f32::INFINITY,
            );
        }
        let slab = |x: f32| Aabb::new(Vec3A::new(x, -5.0, -5.0), Vec3A::new(x + 1.0, 5.0, 5.0));
        let planes = rows([slab(1.0), slab(1.0), slab(-9.0), slab(1.0)]);
        let may = b.finish().may_enter::<ConservativeBoxes>(&planes);
        assert_eq!(may, 0b1011);
    }

    #[test]
    fn an_axis_with_mixed_signs_or_zero_directions_does_not_cull() {
        let mut b = BoundBuilder::new();
        b.add(
            Vec3A::ZERO,
            slab_reciprocal(Vec3A::new(1.0, 1.0, 0.0)),
            0.0,
            10.0,
        );
        b.add(
            Vec3A::ZERO,
            slab_reciprocal(Vec3A::new(-1.0, 1.0, 1.0)),
            0.0,
            10.0,
        );
        let bound = b.finish();
        assert!(bound.axes[0].is_none(), "x has both signs");
        assert!(bound.axes[1].is_some());
        assert!(
            bound.axes[2].is_none(),
            "z has a zero direction (infinite reciprocal)"
        );
    }
}
