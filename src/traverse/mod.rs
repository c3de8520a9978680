//! Ray queries: the [`RayQuery`] trait, the BVH traversal kernels behind it, and the
//! brute-force [`mod@reference`] every kernel is checked against.
//!
//! - `bvh2`: single rays over binary nodes in any memory mapping;
//! - `bvh4`: single rays over 4-wide nodes (exact or quantized), four boxes per SIMD test;
//! - `bvh8`: single rays over 8-wide nodes, portable or AVX2 ([`crate::Isa`]);
//! - [`packet`]: up to 64 coherent rays at once over 4- and 8-wide nodes;
//! - `wide`: the 4- and 8-wide layouts' [`RayQuery`], above the single-ray and packet kernels;
//! - `leaves` (every leaf format's dispatcher), `tri4` (the SIMD triangle-group tests),
//!   `lane8` (eight lanes, portable or AVX2), `simd`: the helpers they share; [`Stats`] sinks
//!   that compile away when unused.

mod bvh2;
mod bvh4;
pub(crate) mod bvh8;
pub(crate) mod lane8;
mod leaves;
pub mod packet;
pub(crate) mod query;
pub mod reference;
pub(crate) mod simd;
mod stats;
mod tri4;
pub(crate) mod wide;

pub use packet::{PacketMode, PacketQuery, PACKET_RAYS};
pub use query::{Filter, NoFilter, RayQuery};
pub use stats::{Counters, NoStats, Stats};

use crate::geometry::{Hit, PrimHit, Ray};
use crate::intersect::Watertight;
use crate::primitive::{LeafFormat, Primitive};

/// The test every kernel and the reference apply to a primitive: [`Primitive::intersect`] for
/// plain types; for a triangle [`LeafFormat`], the triangle [`Primitive::triangle`] gives,
/// with the format's arithmetic (what the SIMD groups compute), so a type is tested alike in
/// every layout and `intersect` is never consulted. A triangle type without a triangle is
/// never hit.
#[inline(always)]
pub(crate) fn prim_hit<P: Primitive>(p: &P, ray: &Ray) -> Option<PrimHit> {
    match P::LEAF_FORMAT {
        LeafFormat::Plain => p.intersect(ray),
        LeafFormat::FastTriangles => p.triangle()?.intersect(ray),
        LeafFormat::WatertightTriangles => Watertight(p.triangle()?).intersect(ray),
    }
}

/// Offers primitive `prim`'s hit `h` to the closest-hit search at `best`: kept when it beats
/// `best` (nearer, or as near with a lower index) and `filter` accepts it, so a filter is only
/// asked about candidates that would change the answer. Returns true when kept.
#[inline(always)]
pub(crate) fn offer<F: Filter<Hit>>(best: &mut Hit, prim: u32, h: PrimHit, filter: &mut F) -> bool {
    if !best.is_beaten_by(h.t, prim) {
        return false;
    }
    let candidate = Hit {
        t: h.t,
        prim,
        u: h.u,
        v: h.v,
    };
    if F::ACTIVE && !filter.accept(&candidate) {
        return false;
    }
    *best = candidate;
    true
}

/// Whether an any-hit search takes primitive `prim`'s hit `h`: always without a filter.
#[inline(always)]
pub(crate) fn accepts<F: Filter<Hit>>(prim: u32, h: PrimHit, filter: &mut F) -> bool {
    !F::ACTIVE
        || filter.accept(&Hit {
            t: h.t,
            prim,
            u: h.u,
            v: h.v,
        })
}

/// Tests a leaf's primitives for the closest hit, updating `best`; `prim_ids` gives each
/// primitive's input index. Returns true when `best` changed.
#[inline(always)]
pub(crate) fn leaf_closest_hit<P: Primitive, S: Stats, F: Filter<Hit>>(
    tris: &[P],
    prim_ids: &[u32],
    ray: &Ray,
    best: &mut Hit,
    stats: &mut S,
    filter: &mut F,
) -> bool {
    stats.prims(tris.len() as u32);
    let r = Ray {
        t_max: best.t,
        ..*ray
    };
    let mut found = false;
    for (tri, &prim) in tris.iter().zip(prim_ids) {
        if let Some(h) = prim_hit(tri, &r) {
            found |= offer(best, prim, h, filter);
        }
    }
    if !found {
        stats.empty_leaf();
    }
    found
}

/// Tests a leaf's primitives until one is hit (and accepted by `filter`).
#[inline(always)]
pub(crate) fn leaf_any_hit<P: Primitive, S: Stats, F: Filter<Hit>>(
    tris: &[P],
    prim_ids: &[u32],
    ray: &Ray,
    stats: &mut S,
    filter: &mut F,
) -> bool {
    for (i, (tri, &prim)) in tris.iter().zip(prim_ids).enumerate() {
        if let Some(h) = prim_hit(tri, ray) {
            if accepts(prim, h, filter) {
                stats.prims(i as u32 + 1);
                return true;
            }
        }
    }
    stats.prims(tris.len() as u32);
    stats.empty_leaf();
    false
}

/// Slack on far distances so rounding never culls a box the exact test would enter
/// (Ize, JCGT 2013: `1 + 2·gamma(3)`, `gamma(n) = n·eps / (1 - n·eps)` with `eps = 2^-24`).
pub(crate) const FAR_SLACK: f32 = 1.0 + 2.0 * GAMMA3;
const GAMMA3: f32 = 3.0 * (f32::EPSILON * 0.5) / (1.0 - 3.0 * (f32::EPSILON * 0.5));

/// How ray-box tests treat rounding, chosen at compile time.
///
/// ```
/// use quiver_rt::traverse::{BoxTest, ConservativeBoxes, FastBoxes};
/// assert_eq!(FastBoxes::SLACK, 1.0);
/// assert!(ConservativeBoxes::SLACK > 1.0);
/// ```
pub trait BoxTest {
    /// Factor applied to far slab distances (and to the pruning distance).
    const SLACK: f32;
}

/// The plain slab test: rounding may cull a box a ray grazes.
#[derive(Clone, Copy, Debug, Default)]
pub struct FastBoxes;

impl BoxTest for FastBoxes {
    const SLACK: f32 = 1.0;
}

/// Ize's conservative slab test (JCGT 2013): far distances scaled by `1 + 2·gamma(3)`, so no
/// box the exact test would enter is culled. The default.
#[derive(Clone, Copy, Debug, Default)]
pub struct ConservativeBoxes;

impl BoxTest for ConservativeBoxes {
    const SLACK: f32 = FAR_SLACK;
}

/// Per-axis reciprocals for slab tests. A subnormal component's reciprocal overflows to ±inf,
/// which would make the ray look parallel to that axis and cull boxes it does enter at a huge
/// but finite distance; it becomes NaN instead, which the slab tests ignore (that axis then
/// never limits the interval: conservative). Found by fuzzing.
#[inline(always)]
pub(crate) fn slab_reciprocal(d: glam::Vec3A) -> glam::Vec3A {
    let subnormal =
        d.abs().cmplt(glam::Vec3A::splat(f32::MIN_POSITIVE)) & d.cmpne(glam::Vec3A::ZERO);
    glam::Vec3A::select(subnormal, glam::Vec3A::NAN, d.recip())
}

/// A ray prepared for slab tests: reciprocal direction and, per axis, which box corner is near.
#[derive(Clone, Copy, Debug)]
pub(crate) struct SlabRay {
    pub origin: [f32; 3],
    pub inv_dir: [f32; 3],
    /// Per axis, the index of the near and far plane in a box stored as `[min, _, max, _]`
    /// (8 floats): the max plane is near where the direction is negative.
    pub near: [usize; 3],
    pub far: [usize; 3],
    pub t_min: f32,
}

impl SlabRay {
    #[inline(always)]
    pub fn new(ray: &Ray) -> Self {
        let inv = slab_reciprocal(ray.dir);
        // The sign of the reciprocal decides: -0.0 gives -inf, a negative direction.
        let neg = |x: f32| x.is_sign_negative() as usize;
        let n = [neg(inv.x), neg(inv.y), neg(inv.z)];
        SlabRay {
            origin: ray.origin.into(),
            inv_dir: inv.into(),
            near: [n[0] * 4, 1 + n[1] * 4, 2 + n[2] * 4],
            far: [4 - n[0] * 4, 5 - n[1] * 4, 6 - n[2] * 4],
            t_min: ray.t_min,
        }
    }

    /// Entry distance into the box (`b[0..3]` min, `b[4..7]` max) if the ray meets it within
    /// `[t_min, t_max]`, boundaries included.
    ///
    /// A zero direction component makes the reciprocal ±inf; when the origin then lies exactly
    /// on that slab's plane the product is `0 * inf = NaN`. The ray runs inside the closed slab,
    /// so a NaN must not limit the interval: `f32::max`/`f32::min` return the non-NaN operand,
    /// and the accumulators (`t_min`, `t_max`) are never NaN.
    #[inline(always)]
    pub fn enter<B: BoxTest>(&self, b: &[f32; 8], t_max: f32) -> Option<f32> {
        let mut near = self.t_min;
        let mut far = t_max;
        for a in 0..3 {
            let tn = (b[self.near[a]] - self.origin[a]) * self.inv_dir[a];
            let tf = (b[self.far[a]] - self.origin[a]) * self.inv_dir[a];
            near = near.max(tn);
            far = far.min(tf * B::SLACK);
        }
        (near <= far).then_some(near)
    }
}

/// A fixed-capacity stack that is not initialised up front: zeroing a traversal stack of a few
/// hundred entries per ray cost more than the traversal of a small scene.
pub(crate) struct Stack<T: Copy, const N: usize> {
    items: [std::mem::MaybeUninit<T>; N],
    len: usize,
}

impl<T: Copy, const N: usize> Stack<T, N> {
    #[inline(always)]
    pub fn new() -> Self {
        Stack {
            items: [std::mem::MaybeUninit::uninit(); N],
            len: 0,
        }
    }

    /// Pushes `x`. Capacities come from the tree depth bound, so overflow is a bug: it panics
    /// (bounds check) rather than corrupting memory.
    #[inline(always)]
    pub fn push(&mut self, x: T) {
        self.items[self.len] = std::mem::MaybeUninit::new(x);
        self.len += 1;
    }

    #[inline(always)]
    pub fn pop(&mut self) -> Option<T> {
        if self.len == 0 {
            return None;
        }
        self.len -= 1;
        // SAFETY: every slot below `len` was written by `push` and `len` only shrinks here.
        Some(unsafe { self.items[self.len].assume_init() })
    }
}

#[cfg(test)]
mod tests {
    use super::Stack;

    #[test]
    fn stack_returns_what_was_pushed_last_in_first_out() {
        let mut s: Stack<(u32, f32), 4> = Stack::new();
        assert_eq!(s.pop(), None);
        for i in 0..4 {
            s.push((i, i as f32));
        }
        assert_eq!(s.pop(), Some((3, 3.0)));
        s.push((9, 9.0));

        let rest: Vec<u32> = std::iter::from_fn(|| s.pop()).map(|x| x.0).collect();
        assert_eq!(rest, vec![9, 2, 1, 0]);
    }

    #[test]
    #[should_panic]
    fn stack_overflow_panics_instead_of_corrupting() {
        let mut s: Stack<u32, 2> = Stack::new();
        for i in 0..3 {
            s.push(i);
        }
    }
}
