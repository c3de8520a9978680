//! [`Aabb`]: the axis-aligned bounding box every builder and layout works with.

use glam::Vec3A;

/// An axis-aligned bounding box. The empty box has `min = +inf`, `max = -inf`.
///
/// ```
/// use quiver_rt::Aabb;
/// use glam::Vec3A;
/// let mut b = Aabb::EMPTY;
/// b.grow(Vec3A::ZERO);
/// b.grow(Vec3A::new(1.0, 2.0, 3.0));
/// assert_eq!(b.half_area(), 1.0 * 2.0 + 2.0 * 3.0 + 3.0 * 1.0);
/// ```
#[derive(Clone, Copy, Debug, PartialEq, bytemuck::Zeroable)]
pub struct Aabb {
    /// Lower corner.
    pub min: Vec3A,
    /// Upper corner.
    pub max: Vec3A,
}

impl Aabb {
    /// The box containing nothing; the identity of [`Aabb::union`].
    pub const EMPTY: Aabb = Aabb {
        min: Vec3A::splat(f32::INFINITY),
        max: Vec3A::splat(f32::NEG_INFINITY),
    };

    /// The box spanned by two corners.
    #[inline]
    pub fn new(min: Vec3A, max: Vec3A) -> Self {
        Aabb { min, max }
    }

    /// Extends the box to contain `p`.
    #[inline]
    pub fn grow(&mut self, p: Vec3A) {
        self.min = self.min.min(p);
        self.max = self.max.max(p);
    }

    /// The smallest box containing both.
    #[inline]
    pub fn union(&self, other: &Aabb) -> Aabb {
        Aabb {
            min: self.min.min(other.min),
            max: self.max.max(other.max),
        }
    }

    /// True when both corners are finite (no NaN, no infinity).
    #[inline]
    pub fn is_finite(&self) -> bool {
        // One vector test per corner and no branch: refits and builds ask it of every box.
        (self.min.is_finite_mask() & self.max.is_finite_mask()).all()
    }

    /// True when the box contains no point.
    #[inline]
    pub fn is_empty(&self) -> bool {
        self.min.cmpgt(self.max).any()
    }

    /// Edge lengths; zero for the empty box.
    #[inline]
    pub fn extent(&self) -> Vec3A {
        (self.max - self.min).max(Vec3A::ZERO)
    }

    /// Half the surface area: the SAH only ever needs ratios of areas. Zero when empty.
    ///
    /// For a finite box it is finite: past f32's range (edges of about `1e19` and more) it
    /// saturates at `f32::MAX`. [`Aabb::half_area_f64`] has the exact value.
    ///
    /// ```
    /// use quiver_rt::Aabb;
    /// use glam::Vec3A;
    /// let huge = Aabb::new(Vec3A::splat(-1e30), Vec3A::splat(1e30));
    /// assert_eq!(huge.half_area(), f32::MAX);
    /// assert_eq!(huge.half_area_f64(), 3.0 * 2e30f32 as f64 * 2e30f32 as f64);
    /// ```
    #[inline]
    pub fn half_area(&self) -> f32 {
        let e = self.extent();
        let a = e.x * e.y + e.y * e.z + e.z * e.x;
        if a.is_finite() || !self.is_finite() {
            a
        } else {
            self.half_area_f64().min(f32::MAX as f64) as f32
        }
    }

    /// Half the surface area in f64, where no finite box overflows. Zero when empty.
    #[inline]
    pub fn half_area_f64(&self) -> f64 {
        let e = (self.max.as_dvec3() - self.min.as_dvec3()).max(glam::DVec3::ZERO);
        e.x * e.y + e.y * e.z + e.z * e.x
    }

    /// The centre point.
    #[inline]
    pub fn center(&self) -> Vec3A {
        (self.min + self.max) * 0.5
    }

    /// True when `other` lies inside this box (boundaries included). The empty box lies in
    /// every box.
    #[inline]
    pub fn contains(&self, other: &Aabb) -> bool {
        other.is_empty() || (self.min.cmple(other.min).all() && other.max.cmple(self.max).all())
    }
}
