//! A BVH's own frame: a scene far from unit size is scaled by a power of two before it is
//! built, and every query's ray is brought into that frame and its hit back out.
//!
//! Why: the triangle tests multiply two or three lengths (the fast test's normal `e1 × e2`
//! and `n · c`, the watertight test's edge functions), the SAH multiplies two, so a scene a
//! few orders of magnitude past 1e10 overflows f32 and one below 1e-13 underflows — hits go
//! missing, build costs turn infinite. Multiplying by a power of two is exact in f32, and
//! every test's arithmetic commutes with it, so in the frame the scene computes exactly what
//! the same scene at unit size computes: a scene scaled by `2^j` gives bit-identical hits,
//! with `t` scaled by `2^j`.
//!
//! Only a scene whose primitives are all larger than `2^20` or all smaller than `2^-20` is
//! scaled (see [`Frame::for_prims`]); every other BVH keeps the identity frame and pays
//! nothing for it (the scaled BVH is a variant of its own).

use crate::builders::BuildTree;
use crate::geometry::{exponent, pow2, scale2, Aabb, Hit, Ray};
use crate::primitive::Primitive;

/// Extents from `2^-SAFE` to `2^SAFE` keep the identity frame: the tests' products of up to
/// three lengths stay far inside f32's normal range there (`2^60` and `2^-60`).
const SAFE: i32 = 20;

/// Largest extent, as a power of two, a scaled scene may span: products of three lengths stay
/// within f32 (2^120).
const MAX_SPREAD_EXPONENT: i32 = 40;

/// Largest scaled coordinate allowed when a tiny scene far from the origin is scaled up.
const MAX_SCALED_EXPONENT: i32 = 100;

/// Ray directions are brought near unit length by at most this power of two either way.
const MAX_DIR_EXPONENT: i32 = 60;

/// What takes one ray's local hit distances back to world units.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Back {
    /// World distance = local distance * 2^e.
    e: i32,
}

impl Back {
    /// A hit found in the frame, with its distance in world units.
    #[inline(always)]
    pub(crate) fn hit(self, hit: Hit) -> Hit {
        Hit {
            t: scale2(hit.t, self.e),
            ..hit
        }
    }
}

/// The power of two that takes world coordinates to the BVH's frame: local = world · 2^-k.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct Frame {
    k: i32,
}

/// What the frame of a set of primitive boxes depends on, gathered box by box in any order
/// (every step is an exact min, max or union, so a parallel reduction in any grouping gives
/// the same frame as [`Frame::for_prims`] over the same boxes).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Sizes {
    /// The smallest and the largest extent of a finite, non-empty box of positive size.
    lo: f32,
    hi: f32,
    /// The union of the finite, non-empty boxes.
    all: Aabb,
}

impl Default for Sizes {
    fn default() -> Self {
        Sizes {
            lo: f32::INFINITY,
            hi: 0.0,
            all: Aabb::EMPTY,
        }
    }
}

impl Sizes {
    /// Counts one primitive's box (non-finite and empty ones change nothing).
    #[inline]
    pub(crate) fn add(&mut self, b: &Aabb) {
        if b.is_finite() {
            self.add_finite(b);
        }
    }

    /// [`Sizes::add`] for a box known to be finite.
    #[inline]
    pub(crate) fn add_finite(&mut self, b: &Aabb) {
        if b.is_empty() {
            return;
        }
        let size = b.extent().max_element();
        if size > 0.0 {
            (self.lo, self.hi) = (self.lo.min(size), self.hi.max(size));
        }
        self.all = self.all.union(b);
    }

    /// Both sets of boxes.
    pub(crate) fn merge(self, o: Sizes) -> Sizes {
        Sizes {
            lo: self.lo.min(o.lo),
            hi: self.hi.max(o.hi),
            all: self.all.union(&o.all),
        }
    }

    /// The frame these boxes call for (see [`Frame::for_prims`]).
    pub(crate) fn frame(self) -> Frame {
        let Sizes { lo, hi, all } = self;
        if hi == 0.0 {
            return Frame::default();
        }
        let mut k = if exponent(lo) > SAFE {
            exponent(lo)
        } else if exponent(hi) < -SAFE {
            exponent(hi)
        } else {
            return Frame::default();
        };
        // Keep the scene's spread, and its far-off coordinates, in range.
        k = k.max(exponent(all.extent().max_element()) - MAX_SPREAD_EXPONENT);
        let reach = all.min.abs().max(all.max.abs()).max_element();
        if reach > 0.0 {
            k = k.max(exponent(reach) - MAX_SCALED_EXPONENT);
        }
        Frame {
            k: k.clamp(-MAX_SCALED_EXPONENT, MAX_SCALED_EXPONENT),
        }
    }
}

impl Frame {
    /// The frame for primitives with these boxes (non-finite and empty ones ignored): the
    /// identity unless every primitive is larger than `2^SAFE` or every one smaller than
    /// `2^-SAFE` — a whole scene far from unit size. A scene that mixes sizes keeps its own
    /// units: no one power of two serves a triangle of 1 beside one of 1e30, and scaling would
    /// take from the small ones what it gave the large.
    pub(crate) fn for_prims(boxes: &[Aabb]) -> Frame {
        use rayon::prelude::*;
        let sizes = |ch: &[Aabb]| {
            let mut s = Sizes::default();
            ch.iter().for_each(|b| s.add(b));
            s
        };
        boxes
            .par_chunks(16 * 1024)
            .map(sizes)
            .reduce(Sizes::default, Sizes::merge)
            .frame()
    }

    /// The boxes of `n` primitives (`bound(i)` for each) and the frame they call for, as
    /// [`Frame::for_prims`] would choose it, in one parallel pass: a second pass over a
    /// million boxes only to size them cost as much as computing them.
    pub(crate) fn bounds(n: usize, bound: impl Fn(usize) -> Aabb + Sync) -> (Vec<Aabb>, Frame) {
        use rayon::prelude::*;
        const CHUNK: usize = 16 * 1024;
        // Zeroed memory comes from the OS untouched, so the pass below is the only write.
        let mut boxes: Vec<Aabb> = bytemuck::zeroed_vec(n);
        let sizes = boxes
            .par_chunks_mut(CHUNK)
            .enumerate()
            .map(|(c, out)| {
                let mut s = Sizes::default();
                for (j, b) in out.iter_mut().enumerate() {
                    *b = bound(c * CHUNK + j);
                    s.add(b);
                }
                s
            })
            .reduce(Sizes::default, Sizes::merge);
        (boxes, sizes.frame())
    }

    /// The power of two `k` (local = world · 2^-k), as a saved BVH stores it.
    pub(crate) fn exponent(self) -> i32 {
        self.k
    }

    /// The frame of exponent `k`, if a build could have chosen it (`|k|` at most
    /// [`MAX_SCALED_EXPONENT`]): a loaded file's frame is checked here.
    pub(crate) fn from_exponent(k: i32) -> Option<Frame> {
        (-MAX_SCALED_EXPONENT..=MAX_SCALED_EXPONENT)
            .contains(&k)
            .then_some(Frame { k })
    }

    /// True when local and world coordinates are the same.
    #[inline(always)]
    pub(crate) fn is_identity(self) -> bool {
        self.k == 0
    }

    /// The power of two a local length is multiplied by to give world units: local = world ·
    /// 2^-k.
    #[inline(always)]
    pub(crate) fn k(self) -> i32 {
        self.k
    }

    /// World to local factor.
    #[inline(always)]
    fn down(self) -> f32 {
        pow2(-self.k)
    }

    /// `ray` in the frame: the same line, its direction also brought near unit length (a
    /// renderer's shadow ray toward a far light carries the whole distance in its direction),
    /// and the factor that takes its hit distances back to world units.
    #[inline(always)]
    pub(crate) fn ray(self, ray: &Ray) -> (Ray, Back) {
        let m = ray.dir.abs().max_element();
        let j = if m > 0.0 && m.is_finite() {
            exponent(m).clamp(-MAX_DIR_EXPONENT, MAX_DIR_EXPONENT)
        } else {
            0
        };
        // Local distance = world distance * 2^(j - k).
        let back = Back { e: self.k - j };
        let local = Ray {
            origin: ray.origin * self.down(),
            dir: ray.dir * pow2(-j),
            t_min: scale2(ray.t_min, -back.e),
            t_max: scale2(ray.t_max, -back.e),
            ..*ray
        };
        (local, back)
    }

    /// A box in the frame.
    pub(crate) fn aabb(self, b: &Aabb) -> Aabb {
        let s = self.down();
        Aabb::new(b.min * s, b.max * s)
    }

    /// A box from the frame back in world units.
    #[cfg(test)]
    fn world_aabb(self, b: &Aabb) -> Aabb {
        let s = pow2(self.k);
        Aabb::new(b.min * s, b.max * s)
    }

    /// One primitive in the frame, or `None` when its type cannot be scaled
    /// ([`Primitive::scaled`]).
    pub(crate) fn prim<P: Primitive>(self, p: &P) -> Option<P> {
        p.scaled(self.down())
    }

    /// The primitives in the frame, or `None` when their type cannot be scaled.
    pub(crate) fn prims<P: Primitive>(self, prims: &[P]) -> Option<Vec<P>> {
        prims.iter().map(|p| self.prim(p)).collect()
    }

    /// A tree built in the frame, told in world units: refit to the primitives' world
    /// `bounds` (scaling its boxes back would lose subnormal coordinates).
    pub(crate) fn world_tree(self, tree: BuildTree, bounds: &[Aabb]) -> BuildTree {
        if self.is_identity() {
            tree
        } else {
            tree.refit(bounds)
        }
    }

    /// Boxes in the frame: borrowed as they are in the identity frame.
    pub(crate) fn boxes(self, boxes: &[Aabb]) -> std::borrow::Cow<'_, [Aabb]> {
        if self.is_identity() {
            boxes.into()
        } else {
            boxes.iter().map(|b| self.aabb(b)).collect()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3A;

    #[test]
    fn exponents_and_powers_agree() {
        for e in -126..=127 {
            assert_eq!(exponent(pow2(e)), e);
            assert_eq!(pow2(e), 2f32.powi(e));
        }
        assert_eq!(exponent(3.0), 1);
        assert_eq!(exponent(f32::MIN_POSITIVE / 4.0), -128);
    }

    #[test]
    fn ordinary_scenes_keep_the_identity_frame() {
        for size in [1e-6f32, 1.0, 1e6] {
            let b = Aabb::new(Vec3A::splat(-size), Vec3A::splat(size));
            assert!(Frame::for_prims(&[b]).is_identity(), "{size}");
        }
        assert!(Frame::for_prims(&[Aabb::EMPTY]).is_identity());
        assert!(Frame::for_prims(&[]).is_identity());
    }

    #[test]
    fn extreme_scenes_come_to_unit_size_exactly() {
        for size in [1e-30f32, 1e-12, 1e12, 1e30] {
            let b = Aabb::new(Vec3A::splat(-size), Vec3A::splat(size));
            let f = Frame::for_prims(&[b, b]);
            let local = f.aabb(&b);
            let e = local.extent().max_element();
            assert!((1.0..2.0).contains(&e), "{size}: {e}");
            assert_eq!(f.world_aabb(&local), b, "{size}: scaling is exact");
            // A shadow ray's direction spans the scene.
            let ray = Ray::segment(Vec3A::splat(size), Vec3A::X * size, 0.5, 3.0);
            let (local, back) = f.ray(&ray);
            assert!(
                local.dir.x.is_normal() && local.t_max.is_normal(),
                "{size}: {local:?}"
            );
            let back = back.hit(Hit {
                t: local.t_max,
                u: 0.25,
                v: 0.5,
                prim: 7,
            });
            assert_eq!(back.t, ray.t_max);
        }
    }

    #[test]
    fn a_tiny_scene_far_away_stays_in_range() {
        let b = Aabb::new(Vec3A::splat(1e30), Vec3A::splat(1e30) + Vec3A::ONE * 1e20);
        let local = Frame::for_prims(&[b]).aabb(&b);
        assert!(local.is_finite());
    }

    #[test]
    fn mixed_sizes_keep_their_units() {
        let unit = Aabb::new(Vec3A::ZERO, Vec3A::ONE);
        let huge = Aabb::new(Vec3A::ZERO, Vec3A::splat(1e30));
        let tiny = Aabb::new(Vec3A::ZERO, Vec3A::splat(1e-30));
        assert!(Frame::for_prims(&[unit, huge]).is_identity());
        assert!(Frame::for_prims(&[unit, tiny]).is_identity());
        assert!(!Frame::for_prims(&[huge, huge]).is_identity());
    }
}
