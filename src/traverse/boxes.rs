//! The ray-box test every walk runs: [`BoxTest`] (plain or conservative far distances,
//! chosen at compile time), the slab reciprocals of a direction and the scalar slab test.

use crate::geometry::Ray;

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

