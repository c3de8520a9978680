//! Single-ray traversal of 4-wide BVHs: the four child boxes of a node are tested at once
//! with `wide::f32x4`, hit children are visited nearest first, any-hit exits at the first hit.

use super::stats::{Counters, NoStats, Stats};
use super::{leaf_any_hit, leaf_closest_hit, slab_reciprocal, BoxTest, ConservativeBoxes, Stack};
use crate::build::MAX_DEPTH;
use crate::geometry::Primitive;
use crate::geometry::{Hit, Ray};
use crate::layout::bvh4::pow2;
use crate::layout::{Bvh4, Bvh4Node, QBvh4, QBvh4Node};
use wide::f32x4;

/// What the kernel needs from a 4-wide node format.
pub(super) trait WideNode {
    /// Child boxes as `[min_x, min_y, min_z, max_x, max_y, max_z]` rows.
    fn planes(&self) -> [f32x4; 6];
    /// Child `i` as (node index or first primitive, `LEAF | count` for a leaf, 0 for an inner
    /// node). Unused slots are empty leaves: a ray whose every slab distance is NaN (all
    /// direction components subnormal) "enters" every box, so they must be harmless.
    fn child(&self, i: usize) -> (u32, u32);
}

impl WideNode for Bvh4Node {
    #[inline(always)]
    fn planes(&self) -> [f32x4; 6] {
        *bytemuck::cast_ref::<[[f32; 4]; 6], [f32x4; 6]>(&self.planes)
    }
    #[inline(always)]
    fn child(&self, i: usize) -> (u32, u32) {
        (self.child[i], self.count[i])
    }
}

impl WideNode for QBvh4Node {
    #[inline(always)]
    fn planes(&self) -> [f32x4; 6] {
        let mut out = [f32x4::ZERO; 6];
        for (row, q) in out.iter_mut().zip(&self.q) {
            *row = f32x4::new([q[0] as f32, q[1] as f32, q[2] as f32, q[3] as f32]);
        }
        for a in 0..3 {
            // Multiply, then add: the arithmetic the encoder verified as conservative.
            let (o, step) = (
                f32x4::splat(self.origin[a]),
                f32x4::splat(pow2(self.exp[a])),
            );
            out[a] = out[a] * step + o;
            out[3 + a] = out[3 + a] * step + o;
        }
        out
    }
    #[inline(always)]
    fn child(&self, i: usize) -> (u32, u32) {
        match self.count[i] {
            // Inner, unless this is an unused slot (marked by an impossible node index).
            0 if self.child[i] == u32::MAX => (0, Bvh4Node::LEAF),
            0 => (self.child[i], 0),
            n => (self.child[i], Bvh4Node::LEAF | n as u32),
        }
    }
}

/// `max(a, b)` where `a` may be NaN and `b` never is; returns `b` for a NaN `a`, so a NaN slab
/// distance (a zero direction with the origin on the plane) never limits the interval.
#[inline(always)]
pub(super) fn max_nan_first(a: f32x4, b: f32x4) -> f32x4 {
    #[cfg(target_feature = "sse")]
    {
        // MAXPS returns its second operand when either is NaN.
        a.fast_max(b)
    }
    #[cfg(not(target_feature = "sse"))]
    {
        b.max(a)
    }
}

/// `min(a, b)` with the same NaN rule as [`max_nan_first`].
#[inline(always)]
pub(super) fn min_nan_first(a: f32x4, b: f32x4) -> f32x4 {
    #[cfg(target_feature = "sse")]
    {
        a.fast_min(b)
    }
    #[cfg(not(target_feature = "sse"))]
    {
        b.min(a)
    }
}

/// A ray prepared for 4-wide slab tests.
pub(super) struct Ray4 {
    origin: [f32x4; 3],
    inv: [f32x4; 3],
    /// Per axis, the plane row entered first (min row, or max row for a negative direction).
    near: [usize; 3],
    far: [usize; 3],
    t_min: f32x4,
}

impl Ray4 {
    #[inline(always)]
    fn new(ray: &Ray) -> Self {
        let inv = slab_reciprocal(ray.dir);
        Self::from_parts(ray.origin.into(), inv.into(), ray.t_min)
    }

    /// From an origin, the slab reciprocals of the direction and `t_min`.
    #[inline(always)]
    pub(super) fn from_parts(origin: [f32; 3], inv: [f32; 3], t_min: f32) -> Self {
        let neg = inv.map(|x| x.is_sign_negative() as usize);
        Ray4 {
            origin: origin.map(f32x4::splat),
            inv: inv.map(f32x4::splat),
            near: [0, 1, 2].map(|a| a + 3 * neg[a]),
            far: [0, 1, 2].map(|a| a + 3 - 3 * neg[a]),
            t_min: f32x4::splat(t_min),
        }
    }

    /// Entry distances of the four boxes and the mask of those entered within
    /// `[t_min, t_max]` (boundaries included).
    #[inline(always)]
    pub(super) fn enter<B: BoxTest>(&self, p: &[f32x4; 6], t_max: f32) -> ([f32; 4], u32) {
        let mut near = self.t_min;
        let mut far = f32x4::splat(t_max);
        for a in 0..3 {
            let tn = (p[self.near[a]] - self.origin[a]) * self.inv[a];
            let tf = (p[self.far[a]] - self.origin[a]) * self.inv[a];
            near = max_nan_first(tn, near);
            far = min_nan_first(tf * f32x4::splat(B::SLACK), far);
        }
        (near.to_array(), near.simd_le(far).to_bitmask())
    }
}

/// Stack entry: (node or first triangle, leaf count or 0, entry distance).
type Entry = (u32, u32, f32);

/// The 4-wide walk, shared by both node formats, over the subtree of inner node `root`,
/// searching up to `limit`. See `Bvh2`'s walk for the `leaf` contract.
#[inline(always)]
fn walk<N, B, S, F>(nodes: &[N], ray: &Ray, root: usize, mut limit: f32, stats: &mut S, mut leaf: F)
where
    N: WideNode,
    B: BoxTest,
    S: Stats,
    F: FnMut(std::ops::Range<usize>, &mut f32, &mut S) -> bool,
{
    let r4 = Ray4::new(ray);
    // Each node pushes at most three entries beyond the one it continues with.
    let mut stack: Stack<Entry, { 3 * MAX_DEPTH + 4 }> = Stack::new();
    let mut node = root;
    loop {
        let n = &nodes[node];
        stats.node();
        stats.boxes(4);
        let (t, mut mask) = r4.enter::<B>(&n.planes(), limit * B::SLACK);
        // Push hit children farthest first, so the nearest is popped next.
        let mut hits: [(f32, usize); 4] = [(0.0, 0); 4];
        let mut k = 0;
        while mask != 0 {
            let i = mask.trailing_zeros() as usize;
            mask &= mask - 1;
            let mut j = k;
            while j > 0 && hits[j - 1].0 < t[i] {
                hits[j] = hits[j - 1];
                j -= 1;
            }
            hits[j] = (t[i], i);
            k += 1;
        }
        for &(ti, i) in &hits[..k] {
            let (c, count) = n.child(i);
            stack.push((c, count, ti));
        }
        // Pop until an inner node worth entering; leaves are handled on the way.
        loop {
            let Some((c, count, ti)) = stack.pop() else {
                return;
            };
            if ti > limit * B::SLACK {
                continue;
            }
            if count & Bvh4Node::LEAF == 0 {
                node = c as usize;
                break;
            }
            let count = count & !Bvh4Node::LEAF;
            stats.node();
            stats.leaf();
            if leaf(c as usize..(c + count) as usize, &mut limit, stats) {
                return;
            }
        }
    }
}

/// Closest-hit and any-hit over one 4-wide node format.
#[inline(always)]
pub(super) fn closest<N: WideNode, B: BoxTest, P: Primitive, S: Stats>(
    nodes: &[N],
    tris: &[P],
    ids: &[u32],
    ray: &Ray,
    stats: &mut S,
) -> Option<Hit> {
    let mut best = Hit::none(ray.t_max);
    closest_from::<N, B, P, S>(nodes, tris, ids, ray, 0, &mut best, stats);
    best.found()
}

/// Closest hit in the subtree of inner node `root`, improving on `best`, whose distance is
/// the search limit.
#[inline(always)]
pub(super) fn closest_from<N: WideNode, B: BoxTest, P: Primitive, S: Stats>(
    nodes: &[N],
    tris: &[P],
    ids: &[u32],
    ray: &Ray,
    root: usize,
    best: &mut Hit,
    stats: &mut S,
) {
    walk::<N, B, S, _>(nodes, ray, root, best.t, stats, |range, limit, stats| {
        leaf_closest_hit(&tris[range.clone()], &ids[range], ray, best, stats);
        *limit = best.t;
        false
    });
}

#[inline(always)]
pub(super) fn any<N: WideNode, B: BoxTest, P: Primitive, S: Stats>(
    nodes: &[N],
    tris: &[P],
    ray: &Ray,
    stats: &mut S,
) -> bool {
    any_from::<N, B, P, S>(nodes, tris, ray, 0, stats)
}

/// Any hit in the subtree of inner node `root`.
#[inline(always)]
pub(super) fn any_from<N: WideNode, B: BoxTest, P: Primitive, S: Stats>(
    nodes: &[N],
    tris: &[P],
    ray: &Ray,
    root: usize,
    stats: &mut S,
) -> bool {
    let mut hit = false;
    walk::<N, B, S, _>(nodes, ray, root, ray.t_max, stats, |range, _, stats| {
        hit = leaf_any_hit(&tris[range], ray, stats);
        hit
    });
    hit
}

macro_rules! wide_queries {
    ($t:ident) => {
        impl<P: Primitive> $t<P> {
            /// The nearest hit along `ray` (lowest primitive index on ties): exactly what
            /// [`crate::reference::closest_hit`] returns for the same triangles.
            pub fn closest_hit(&self, ray: &Ray) -> Option<Hit> {
                closest::<_, ConservativeBoxes, _, _>(
                    &self.nodes,
                    &self.prims,
                    &self.prim_ids,
                    ray,
                    &mut NoStats,
                )
            }

            /// Closest hit, adding what the traversal did to `counters`.
            pub fn closest_hit_counted(&self, ray: &Ray, counters: &mut Counters) -> Option<Hit> {
                closest::<_, ConservativeBoxes, _, _>(
                    &self.nodes,
                    &self.prims,
                    &self.prim_ids,
                    ray,
                    counters,
                )
            }

            /// True when anything is hit within the ray's interval; stops at the first hit.
            pub fn any_hit(&self, ray: &Ray) -> bool {
                any::<_, ConservativeBoxes, _, _>(&self.nodes, &self.prims, ray, &mut NoStats)
            }

            /// Any hit, adding what the traversal did to `counters`.
            pub fn any_hit_counted(&self, ray: &Ray, counters: &mut Counters) -> bool {
                any::<_, ConservativeBoxes, _, _>(&self.nodes, &self.prims, ray, counters)
            }

            /// Closest hit with any box test and statistics sink.
            pub fn closest_hit_with<B: BoxTest, S: Stats>(
                &self,
                ray: &Ray,
                stats: &mut S,
            ) -> Option<Hit> {
                closest::<_, B, _, _>(&self.nodes, &self.prims, &self.prim_ids, ray, stats)
            }

            /// Any hit with any box test and statistics sink.
            pub fn any_hit_with<B: BoxTest, S: Stats>(&self, ray: &Ray, stats: &mut S) -> bool {
                any::<_, B, _, _>(&self.nodes, &self.prims, ray, stats)
            }
        }
    };
}

wide_queries!(Bvh4);
wide_queries!(QBvh4);
