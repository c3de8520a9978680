//! Powers of two that bring magnitudes near 1, so products of lengths stay inside f32's range
//! at any scene scale, exactly (a power of two changes no digit).

use glam::Vec3A;

/// `v` scaled to unit length at any size, or zero for a zero or non-finite vector.
///
/// glam's `normalize_or_zero` squares the components, so a normal computed as the cross
/// product of two edges is lost beyond about 1e19 (overflow) or below 1e-19 (underflow) —
/// edges of about 1e10 and 1e-10. This first brings the largest component near 1 by powers of
/// two, which is exact: wherever `normalize_or_zero` works, the result is the same bits.
///
/// ```
/// use quiver_rt::geometry::unit_or_zero;
/// use glam::Vec3A;
/// let huge = Vec3A::new(3e30, 4e30, 0.0);
/// assert_eq!(huge.normalize_or_zero(), Vec3A::ZERO); // squared: overflow
/// assert!(unit_or_zero(huge).abs_diff_eq(Vec3A::new(0.6, 0.8, 0.0), 1e-7));
/// // Powers of two are exact: the same bits as at unit size.
/// assert_eq!(unit_or_zero(Vec3A::new(3.0, 4.0, 0.0) * 2f32.powi(100)), Vec3A::new(3.0, 4.0, 0.0).normalize());
/// assert_eq!(unit_or_zero(Vec3A::new(0.0, 1e-30, 0.0)), Vec3A::Y);
/// assert_eq!(unit_or_zero(Vec3A::new(0.0, 0.0, -1e-45)), -Vec3A::Z); // subnormal
/// assert_eq!(unit_or_zero(Vec3A::ZERO), Vec3A::ZERO);
/// ```
#[inline]
pub fn unit_or_zero(v: Vec3A) -> Vec3A {
    let m = v.abs().max_element();
    if !m.is_finite() {
        return Vec3A::ZERO;
    }
    (v * unit_scale(m)).normalize_or_zero()
}

/// The power of two that brings a magnitude `m` near 1 when products of two or three such
/// magnitudes would leave f32's range (`m` outside `2^-40..=2^40`), else 1: multiply the
/// vectors of a cross or dot product by it first, and the product keeps its digits at any
/// scale with the same bits as before wherever it had them.
///
/// ```
/// use quiver_rt::geometry::unit_scale;
/// assert_eq!(unit_scale(3.0), 1.0);
/// assert_eq!(unit_scale(1e30) * 1e30, 1e30 * 2f32.powi(-99));
/// assert!((1.0..2.0).contains(&(unit_scale(1e-30) * 1e-30)));
/// ```
#[inline]
pub fn unit_scale(m: f32) -> f32 {
    const BAND: f32 = (1u64 << 40) as f32;
    if !(m.is_finite() && m > 0.0) || (1.0 / BAND..=BAND).contains(&m) {
        return 1.0;
    }
    // 2^-e for m in [2^e, 2^(e+1)); the factor itself must be an f32, so a subnormal m only
    // comes up by 2^127 (to at least 2^-22, still far from underflow).
    scale2(1.0, -exponent(m).max(-127))
}

/// `2^e` for `e` in f32's normal exponent range.
pub(crate) fn pow2(e: i32) -> f32 {
    debug_assert!((-126..=127).contains(&e));
    f32::from_bits(((e + 127) as u32) << 23)
}

/// The exponent of `x` (finite, positive): `x` lies in `[2^e, 2^(e+1))`.
pub(crate) fn exponent(x: f32) -> i32 {
    if x >= f32::MIN_POSITIVE {
        ((x.to_bits() >> 23) & 0xff) as i32 - 127
    } else {
        // Subnormal: count from the smallest normal down.
        -127 - (x.to_bits().leading_zeros() as i32 - 9)
    }
}

/// `x * 2^e` for `e` beyond f32's exponent range too, in two exact steps.
#[inline(always)]
pub(crate) fn scale2(x: f32, e: i32) -> f32 {
    let half = e / 2;
    x * pow2(half) * pow2(e - half)
}
