//! Single-ray traversal of 8-wide BVHs: the eight child boxes of a node in one 8-lane slab
//! test. Two implementations of that test, chosen per BVH ([`crate::Isa`]): `wide::f32x8`
//! (two SSE halves on baseline x86-64) and AVX2 intrinsics (one 256-bit register), which
//! compute every lane with the same operations in the same order, so both walks visit the
//! same nodes and return the same hits. Closest hit visits hit children nearest first; any
//! hit pushes them unordered and stops at the first hit.

use super::simd::{bits, insert_farthest_first, NanFirst};
use super::stats::Stats;
use super::tri4::Leaves;
use super::{slab_reciprocal, BoxTest, RayQuery, Stack};
use crate::build::MAX_DEPTH;
use crate::geometry::{Hit, Primitive, Ray};
use crate::isa::Isa;
use crate::layout::{Bvh8, Bvh8Node};
use wide::f32x8;

/// The slab test of one ray against a node's eight boxes.
trait Test8 {
    /// Entry distances of the eight boxes and the mask of those entered within
    /// `[t_min, t_max]` (boundaries included; `t_max` already scaled by the box test's slack).
    fn enter<B: BoxTest>(&self, n: &Bvh8Node, t_max: f32) -> ([f32; 8], u32);
}

/// A ray prepared for the portable 8-lane test.
struct Portable8 {
    origin: [f32x8; 3],
    inv: [f32x8; 3],
    /// Per axis, the plane row entered first (min row, or max row for a negative direction).
    near: [usize; 3],
    far: [usize; 3],
    t_min: f32x8,
}

/// Per axis, the near and far plane rows for a ray with these reciprocals.
#[inline(always)]
fn rows(inv: [f32; 3]) -> ([usize; 3], [usize; 3]) {
    let neg = inv.map(|x| x.is_sign_negative() as usize);
    (
        [0, 1, 2].map(|a| a + 3 * neg[a]),
        [0, 1, 2].map(|a| a + 3 - 3 * neg[a]),
    )
}

impl Portable8 {
    #[inline(always)]
    fn new(ray: &Ray) -> Self {
        let inv: [f32; 3] = slab_reciprocal(ray.dir).into();
        let (near, far) = rows(inv);
        Portable8 {
            origin: <[f32; 3]>::from(ray.origin).map(f32x8::splat),
            inv: inv.map(f32x8::splat),
            near,
            far,
            t_min: f32x8::splat(ray.t_min),
        }
    }
}

impl Test8 for Portable8 {
    #[inline(always)]
    fn enter<B: BoxTest>(&self, n: &Bvh8Node, t_max: f32) -> ([f32; 8], u32) {
        let p = |row: usize| f32x8::from(n.planes[row]);
        let mut near = self.t_min;
        let mut far = f32x8::splat(t_max);
        for a in 0..3 {
            let tn = (p(self.near[a]) - self.origin[a]) * self.inv[a];
            let tf = (p(self.far[a]) - self.origin[a]) * self.inv[a];
            near = tn.max_nan_first(near);
            far = (tf * f32x8::splat(B::SLACK)).min_nan_first(far);
        }
        (near.to_array(), near.simd_le(far).to_bitmask())
    }
}

/// The walk over the subtree of inner node `root`, searching up to `limit`: `leaf(first,
/// count, limit, stats)` tests a leaf (its first primitive or group, and its primitive
/// count), may lower the limit, and returns true to stop. `ORDERED`:
/// visit hit children nearest first (closest hit) or in slot order (any hit, which stops at
/// the first hit and gains nothing from sorting).
#[inline(always)]
fn walk<T, B, S, F, const ORDERED: bool>(
    nodes: &[Bvh8Node],
    ray: &T,
    mut limit: f32,
    stats: &mut S,
    mut leaf: F,
) where
    T: Test8,
    B: BoxTest,
    S: Stats,
    F: FnMut(usize, u32, &mut f32, &mut S) -> bool,
{
    // Each node pushes at most seven entries beyond the one it continues with.
    let mut stack: Stack<(u32, u32, f32), { 7 * MAX_DEPTH + 8 }> = Stack::new();
    let mut node = 0usize;
    loop {
        let n = &nodes[node];
        stats.node();
        stats.boxes(8);
        let (t, mask) = ray.enter::<B>(n, limit * B::SLACK);
        if ORDERED {
            // Push hit children farthest first, so the nearest is popped next. Measured
            // against per-octant precomputed orders (children by centre along the ray's
            // octant, 32 more bytes a node): those ran eye rays 4-29% faster but incoherent
            // rays up to 12% slower (`quiver layouts`, 1 thread, medians of 3 runs), and the
            // nearest hit child first plus octant order for the rest was slower than both.
            if mask.is_power_of_two() {
                // One child hit (the common case): nothing to order.
                let i = mask.trailing_zeros() as usize;
                stack.push((n.child[i], n.count[i], t[i]));
            } else {
                let mut hits = [(0.0f32, 0u32); 8];
                let mut k = 0;
                for i in bits(mask) {
                    insert_farthest_first(&mut hits, k, t[i], i as u32);
                    k += 1;
                }
                for &(ti, i) in &hits[..k] {
                    stack.push((n.child[i as usize], n.count[i as usize], ti));
                }
            }
        } else {
            for i in bits(mask) {
                stack.push((n.child[i], n.count[i], t[i]));
            }
        }
        // Pop until an inner node worth entering; leaves are handled on the way.
        loop {
            let Some((c, count, ti)) = stack.pop() else {
                return;
            };
            if ti > limit * B::SLACK {
                continue;
            }
            if count & Bvh8Node::LEAF == 0 {
                node = c as usize;
                break;
            }
            let count = count & !Bvh8Node::LEAF;
            stats.node();
            stats.leaf();
            if leaf(c as usize, count, &mut limit, stats) {
                return;
            }
        }
    }
}

/// Closest hit over any 8-lane test.
#[inline(always)]
fn closest<T: Test8, B: BoxTest, P: Primitive, S: Stats>(
    bvh: &Bvh8<P>,
    t8: &T,
    ray: &Ray,
    stats: &mut S,
) -> Option<Hit> {
    let mut best = Hit::none(ray.t_max);
    let leaves = bvh.leaves();
    // Prepared at the first leaf: many rays never reach one.
    let mut prep = None;
    walk::<T, B, S, _, true>(
        &bvh.nodes,
        t8,
        ray.t_max,
        stats,
        |first, count, limit, stats| {
            leaves.closest(first, count, ray, &mut prep, &mut best, stats);
            *limit = best.t;
            false
        },
    );
    best.found()
}

/// Any hit over any 8-lane test.
#[inline(always)]
fn any<T: Test8, B: BoxTest, P: Primitive, S: Stats>(
    bvh: &Bvh8<P>,
    t8: &T,
    ray: &Ray,
    stats: &mut S,
) -> bool {
    let leaves = bvh.leaves();
    let mut prep = None;
    let mut hit = false;
    walk::<T, B, S, _, false>(
        &bvh.nodes,
        t8,
        ray.t_max,
        stats,
        |first, count, _, stats| {
            hit = leaves.any(first, count, ray, &mut prep, stats);
            hit
        },
    );
    hit
}

impl<P: Primitive> Bvh8<P> {
    #[inline(always)]
    fn leaves(&self) -> Leaves<'_, P> {
        Leaves {
            prims: &self.prims,
            ids: &self.prim_ids,
            tri4: &self.tri4,
        }
    }
}

/// No 8-wide packet kernel yet: packet queries go ray by ray (the trait's default).
impl<P: Primitive> RayQuery for Bvh8<P> {
    fn closest_hit_with<B: BoxTest, S: Stats>(&self, ray: &Ray, stats: &mut S) -> Option<Hit> {
        match self.isa {
            #[cfg(target_arch = "x86_64")]
            // SAFETY: `isa` is Avx2 only where the CPU has AVX2 and FMA (`Isa::or_portable`).
            Isa::Avx2 => unsafe { avx2::closest::<B, P, S>(self, ray, stats) },
            _ => closest::<Portable8, B, P, S>(self, &Portable8::new(ray), ray, stats),
        }
    }

    fn any_hit_with<B: BoxTest, S: Stats>(&self, ray: &Ray, stats: &mut S) -> bool {
        match self.isa {
            #[cfg(target_arch = "x86_64")]
            // SAFETY: as in `closest_hit_with`.
            Isa::Avx2 => unsafe { avx2::any::<B, P, S>(self, ray, stats) },
            _ => any::<Portable8, B, P, S>(self, &Portable8::new(ray), ray, stats),
        }
    }
}

/// The AVX2 kernels: the same walk, the slab test on 256-bit registers.
#[cfg(target_arch = "x86_64")]
mod avx2 {
    use super::*;
    use std::arch::x86_64::*;

    /// A ray prepared for the AVX2 test.
    pub(super) struct Avx8 {
        origin: [__m256; 3],
        inv: [__m256; 3],
        near: [usize; 3],
        far: [usize; 3],
        t_min: __m256,
    }

    impl Avx8 {
        #[target_feature(enable = "avx2,fma")]
        #[inline]
        fn new(ray: &Ray) -> Self {
            let inv: [f32; 3] = slab_reciprocal(ray.dir).into();
            let (near, far) = rows(inv);
            let o: [f32; 3] = ray.origin.into();
            Avx8 {
                origin: o.map(|x| _mm256_set1_ps(x)),
                inv: inv.map(|x| _mm256_set1_ps(x)),
                near,
                far,
                t_min: _mm256_set1_ps(ray.t_min),
            }
        }

        /// [`Test8::enter`] on AVX2: `_mm256_max_ps(a, b)` returns `b` when either is NaN,
        /// as the portable NaN-first max does lane by lane, and `<=` is ordered (false on
        /// NaN) in both.
        #[target_feature(enable = "avx2,fma")]
        #[inline]
        fn enter_avx<B: BoxTest>(&self, n: &Bvh8Node, t_max: f32) -> ([f32; 8], u32) {
            // SAFETY: the rows are 32-byte aligned (64-byte aligned node, 32-byte rows).
            let p = |row: usize| unsafe { _mm256_load_ps(n.planes[row].as_ptr()) };
            let slack = _mm256_set1_ps(B::SLACK);
            let mut near = self.t_min;
            let mut far = _mm256_set1_ps(t_max);
            for a in 0..3 {
                let tn = _mm256_mul_ps(_mm256_sub_ps(p(self.near[a]), self.origin[a]), self.inv[a]);
                let tf = _mm256_mul_ps(_mm256_sub_ps(p(self.far[a]), self.origin[a]), self.inv[a]);
                near = _mm256_max_ps(tn, near);
                far = _mm256_min_ps(_mm256_mul_ps(tf, slack), far);
            }
            let mut t = [0.0f32; 8];
            // SAFETY: `t` holds eight floats; the unaligned store needs no alignment.
            unsafe { _mm256_storeu_ps(t.as_mut_ptr(), near) };
            let mask = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(near, far)) as u32;
            (t, mask)
        }
    }

    impl Test8 for Avx8 {
        #[inline(always)]
        fn enter<B: BoxTest>(&self, n: &Bvh8Node, t_max: f32) -> ([f32; 8], u32) {
            // SAFETY: an `Avx8` is only made inside the AVX2 kernels below, which run only
            // where the CPU has AVX2 and FMA.
            unsafe { self.enter_avx::<B>(n, t_max) }
        }
    }

    /// # Safety
    /// The CPU must support AVX2 and FMA.
    #[target_feature(enable = "avx2,fma")]
    pub(super) unsafe fn closest<B: BoxTest, P: Primitive, S: Stats>(
        bvh: &Bvh8<P>,
        ray: &Ray,
        stats: &mut S,
    ) -> Option<Hit> {
        super::closest::<Avx8, B, P, S>(bvh, &Avx8::new(ray), ray, stats)
    }

    /// # Safety
    /// The CPU must support AVX2 and FMA.
    #[target_feature(enable = "avx2,fma")]
    pub(super) unsafe fn any<B: BoxTest, P: Primitive, S: Stats>(
        bvh: &Bvh8<P>,
        ray: &Ray,
        stats: &mut S,
    ) -> bool {
        super::any::<Avx8, B, P, S>(bvh, &Avx8::new(ray), ray, stats)
    }
}
