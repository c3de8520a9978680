//! Hit records: [`PrimHit`], what one primitive test found, and [`Hit`], a query's answer
//! naming the primitive.

/// What one primitive test found: the distance and two surface parameters (barycentrics for
/// triangles; each shape documents its own).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PrimHit {
    /// Hit distance along the ray.
    pub t: f32,
    /// First surface parameter (a triangle: barycentric weight of the second vertex).
    pub u: f32,
    /// Second surface parameter (a triangle: barycentric weight of the third vertex).
    pub v: f32,
}

/// A closest-hit answer: the distance, the primitive's index in the input, and barycentrics.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    /// Hit distance along the ray.
    pub t: f32,
    /// Index of the primitive in the scene's input order.
    pub prim: u32,
    /// Barycentric weight of the primitive's second vertex.
    pub u: f32,
    /// Barycentric weight of the primitive's third vertex.
    pub v: f32,
}

impl Hit {
    /// The "nothing yet" record a closest-hit search starts from: any hit at or before `t_max`
    /// beats it.
    #[inline(always)]
    pub(crate) fn none(t_max: f32) -> Hit {
        Hit {
            t: t_max,
            prim: u32::MAX,
            u: 0.0,
            v: 0.0,
        }
    }

    /// `Some(self)` unless this is still the [`Hit::none`] record.
    #[inline(always)]
    pub(crate) fn found(self) -> Option<Hit> {
        (self.prim != u32::MAX).then_some(self)
    }

    /// True when `(t, prim)` should replace `self` as the closest hit: nearer, or equally near
    /// with a lower primitive index. This total order makes every kernel agree on ties.
    #[inline(always)]
    pub(crate) fn is_beaten_by(&self, t: f32, prim: u32) -> bool {
        t < self.t || (t == self.t && prim < self.prim)
    }
}
