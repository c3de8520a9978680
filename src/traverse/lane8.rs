//! Eight `f32` lanes, written once for the kernels and compiled twice: on `wide::f32x8`
//! (whatever `wide` was compiled for: two SSE halves on baseline x86-64, NEON on aarch64)
//! and on AVX `__m256` registers. Every operation is the same IEEE operation in both, with
//! the same NaN rules (MAXPS/MINPS return the second operand when either is NaN; ordered
//! comparisons are false on NaN, `!=` is true), so a kernel generic over [`F8`] gives
//! bit-identical answers on both. Nothing here fuses a multiply into an add.

use super::simd::NanFirst;
#[cfg(doc)]
use crate::isa::Avx2Cpu;
use wide::f32x8;

/// Eight `f32` lanes; comparisons return lane masks (all bits set where true).
///
/// Lanes are made only from a [`F8::Cpu`] value (`splat`, `load`): `()` for portable lanes,
/// for AVX lanes the proof that the CPU has AVX2 ([`Avx2Cpu`]), which only detection makes. So
/// an AVX value, and every operation on one, exists only where the instructions do.
pub(crate) trait F8: Copy {
    /// What making lanes takes: nothing, or the proof that the CPU runs them.
    type Cpu: Copy;
    fn splat(cpu: Self::Cpu, x: f32) -> Self;
    fn load(cpu: Self::Cpu, a: &[f32; 8]) -> Self;
    fn to_array(self) -> [f32; 8];
    fn add(self, b: Self) -> Self;
    fn sub(self, b: Self) -> Self;
    fn mul(self, b: Self) -> Self;
    fn div(self, b: Self) -> Self;
    /// `max(self, b)`, or `b` where either is NaN.
    fn max_nan_first(self, b: Self) -> Self;
    /// `min(self, b)`, or `b` where either is NaN.
    fn min_nan_first(self, b: Self) -> Self;
    fn lt(self, b: Self) -> Self;
    fn le(self, b: Self) -> Self;
    fn ge(self, b: Self) -> Self;
    fn ne(self, b: Self) -> Self;
    fn eq(self, b: Self) -> Self;
    fn and(self, b: Self) -> Self;
    fn or(self, b: Self) -> Self;
    /// `self & !b`, lane by lane.
    fn and_not(self, b: Self) -> Self;
    /// Four lanes from `lo` and four from `hi` (two SIMD triangle groups' rows side by side).
    fn load_halves(cpu: Self::Cpu, lo: &[f32; 4], hi: &[f32; 4]) -> Self;
    /// Lanes of `t` where `self` is set, of `f` elsewhere.
    fn select(self, t: Self, f: Self) -> Self;
    /// Bit `i` set where lane `i`'s sign bit is set (a mask lane is true).
    fn bitmask(self) -> u32;
    /// Each lane's sign bit copied into all its bits (a lane mask of the negative lanes,
    /// `-0.0` and NaNs with the sign bit among them).
    fn sign_fill(self) -> Self;

    /// Bit `i` set where lane `i` of `self` is `<=` that of `b` (false on NaN): `le` then
    /// `bitmask`, or one comparison into a mask register where the lanes have them.
    #[inline(always)]
    fn le_bits(self, b: Self) -> u32 {
        self.le(b).bitmask()
    }

    /// A node's hit children `mask` (two or more of its eight slots), ordered by their entry
    /// distances `self` (one lane per slot, none below zero), farthest first: how many, and
    /// their `child` and `count` words and distances in that order (lanes from the count on
    /// unspecified). Each child is ordered by a key: its distance's bits (a distance is never
    /// below zero, so its bits order as it does) with its slot in the lowest three, so keys
    /// are distinct and compare as integers; the distance given back is the key's (at most
    /// the child's: the low bits cleared), so culling by it stays safe. Every implementation
    /// gives the same order.
    #[inline(always)]
    fn order_hits(
        self,
        mask: u32,
        child: &[u32; 8],
        count: &[u32; 8],
    ) -> (usize, [u32; 8], [u32; 8], [f32; 8]) {
        order_hits_scalar(&self.to_array(), mask, child, count)
    }

    /// Runs `f` in a function of its own (a cold path kept out of a kernel's loop), compiled
    /// for the same instruction set as the kernel. `f` should be an `#[inline(always)]`
    /// closure, so that its body is compiled there.
    #[cold]
    #[inline(never)]
    fn outlined<R>(cpu: Self::Cpu, f: impl FnOnce() -> R) -> R {
        let _ = cpu;
        f()
    }

    /// Each of three values in all lanes. (Written out: `array::map` with a closure is not
    /// always inlined, and a kernel's lanes must stay inside the kernel's instruction set.)
    #[inline(always)]
    fn splat3(cpu: Self::Cpu, a: [f32; 3]) -> [Self; 3] {
        [
            Self::splat(cpu, a[0]),
            Self::splat(cpu, a[1]),
            Self::splat(cpu, a[2]),
        ]
    }

    /// Loads eight lanes stored as a `wide::f32x8`.
    #[inline(always)]
    fn of(cpu: Self::Cpu, x: &f32x8) -> Self {
        Self::load(cpu, bytemuck::cast_ref(x))
    }

    /// Stores the lanes into a `wide::f32x8` (what packets keep their rays in).
    #[inline(always)]
    fn store(self, out: &mut f32x8) {
        *out = f32x8::from(self.to_array());
    }
}

impl F8 for f32x8 {
    type Cpu = ();
    #[inline(always)]
    fn splat(_: (), x: f32) -> Self {
        f32x8::splat(x)
    }
    #[inline(always)]
    fn load(_: (), a: &[f32; 8]) -> Self {
        f32x8::from(*a)
    }
    #[inline(always)]
    fn to_array(self) -> [f32; 8] {
        f32x8::to_array(self)
    }
    #[inline(always)]
    fn add(self, b: Self) -> Self {
        self + b
    }
    #[inline(always)]
    fn sub(self, b: Self) -> Self {
        self - b
    }
    #[inline(always)]
    fn mul(self, b: Self) -> Self {
        self * b
    }
    #[inline(always)]
    fn div(self, b: Self) -> Self {
        self / b
    }
    #[inline(always)]
    fn max_nan_first(self, b: Self) -> Self {
        NanFirst::max_nan_first(self, b)
    }
    #[inline(always)]
    fn min_nan_first(self, b: Self) -> Self {
        NanFirst::min_nan_first(self, b)
    }
    #[inline(always)]
    fn lt(self, b: Self) -> Self {
        self.simd_lt(b)
    }
    #[inline(always)]
    fn le(self, b: Self) -> Self {
        self.simd_le(b)
    }
    #[inline(always)]
    fn ge(self, b: Self) -> Self {
        self.simd_ge(b)
    }
    #[inline(always)]
    fn ne(self, b: Self) -> Self {
        self.simd_ne(b)
    }
    #[inline(always)]
    fn eq(self, b: Self) -> Self {
        self.simd_eq(b)
    }
    #[inline(always)]
    fn and(self, b: Self) -> Self {
        self & b
    }
    #[inline(always)]
    fn or(self, b: Self) -> Self {
        self | b
    }
    #[inline(always)]
    fn and_not(self, b: Self) -> Self {
        self & !b
    }
    #[inline(always)]
    fn load_halves(_: (), lo: &[f32; 4], hi: &[f32; 4]) -> Self {
        f32x8::from([lo[0], lo[1], lo[2], lo[3], hi[0], hi[1], hi[2], hi[3]])
    }
    #[inline(always)]
    fn select(self, t: Self, f: Self) -> Self {
        wide::Select::select(self, t, f)
    }
    #[inline(always)]
    fn bitmask(self) -> u32 {
        self.to_bitmask()
    }
    #[inline(always)]
    fn sign_fill(self) -> Self {
        let i: wide::i32x8 = bytemuck::cast(self);
        bytemuck::cast(i >> 31)
    }
}

/// [`F8::order_hits`] one child at a time (what the portable lanes run, and what the SIMD
/// orders are checked against).
#[inline(always)]
fn order_hits_scalar(
    t: &[f32; 8],
    mask: u32,
    child: &[u32; 8],
    count: &[u32; 8],
) -> (usize, [u32; 8], [u32; 8], [f32; 8]) {
    let mut keys = [0u32; 8];
    let mut k = 0;
    for i in super::simd::bits(mask) {
        super::simd::insert_descending(&mut keys, k, (t[i].to_bits() & !7) | i as u32);
        k += 1;
    }
    let (mut c, mut n, mut d) = ([0u32; 8], [0u32; 8], [0.0f32; 8]);
    for j in 0..k {
        let i = (keys[j] & 7) as usize;
        c[j] = child[i];
        n[j] = count[i];
        d[j] = f32::from_bits(keys[j] & !7);
    }
    (k, c, n, d)
}

#[cfg(target_arch = "x86_64")]
pub(crate) use avx::{Avx, Avx512};

#[cfg(target_arch = "x86_64")]
mod avx {
    use super::F8;
    use crate::isa::{Avx2Cpu, Avx512Cpu};
    use std::arch::x86_64::*;

    /// Eight lanes in one AVX register, for the AVX2 kernels. The field is private to this
    /// module, and the only constructors (`splat`, `load`) take an [`Avx2Cpu`], the proof that
    /// the CPU has AVX2 and FMA: a value exists only on such a CPU. Every method is inlined
    /// into the kernels' `#[target_feature]` trampolines.
    #[derive(Clone, Copy)]
    pub(crate) struct Avx(__m256);

    /// Eight lanes in one AVX register, for the AVX-512 kernels: the same operations as
    /// [`Avx`], compiled where AVX-512 F, VL, BW and DQ are enabled (EVEX encodings, 32
    /// registers, comparisons into mask registers). Made only from an [`Avx512Cpu`].
    #[derive(Clone, Copy)]
    pub(crate) struct Avx512(__m256);

    // SAFETY (every `unsafe` block in the impls below): the intrinsics need AVX (AVX2 for the
    // integer shift; AVX-512 VL for the mask comparisons of `Avx512`), which the CPU has
    // wherever a value exists (it was made from the type's proof, which only its `detect`
    // makes, after the CPU reported those features); loads and stores go through references to
    // eight floats.
    macro_rules! avx_lanes {
        ($lanes:ident, $cpu:ty, $features:literal) => {
            impl F8 for $lanes {
                type Cpu = $cpu;
                #[inline(always)]
                fn splat(_: $cpu, x: f32) -> Self {
                    $lanes(unsafe { _mm256_set1_ps(x) })
                }
                #[inline(always)]
                fn load(_: $cpu, a: &[f32; 8]) -> Self {
                    $lanes(unsafe { _mm256_loadu_ps(a.as_ptr()) })
                }
                #[inline(always)]
                fn to_array(self) -> [f32; 8] {
                    let mut out = [0.0f32; 8];
                    unsafe { _mm256_storeu_ps(out.as_mut_ptr(), self.0) };
                    out
                }
                #[inline(always)]
                fn add(self, b: Self) -> Self {
                    $lanes(unsafe { _mm256_add_ps(self.0, b.0) })
                }
                #[inline(always)]
                fn sub(self, b: Self) -> Self {
                    $lanes(unsafe { _mm256_sub_ps(self.0, b.0) })
                }
                #[inline(always)]
                fn mul(self, b: Self) -> Self {
                    $lanes(unsafe { _mm256_mul_ps(self.0, b.0) })
                }
                #[inline(always)]
                fn div(self, b: Self) -> Self {
                    $lanes(unsafe { _mm256_div_ps(self.0, b.0) })
                }
                #[inline(always)]
                fn max_nan_first(self, b: Self) -> Self {
                    $lanes(unsafe { _mm256_max_ps(self.0, b.0) })
                }
                #[inline(always)]
                fn min_nan_first(self, b: Self) -> Self {
                    $lanes(unsafe { _mm256_min_ps(self.0, b.0) })
                }
                #[inline(always)]
                fn lt(self, b: Self) -> Self {
                    $lanes(unsafe { _mm256_cmp_ps::<_CMP_LT_OQ>(self.0, b.0) })
                }
                #[inline(always)]
                fn le(self, b: Self) -> Self {
                    $lanes(unsafe { _mm256_cmp_ps::<_CMP_LE_OQ>(self.0, b.0) })
                }
                #[inline(always)]
                fn ge(self, b: Self) -> Self {
                    $lanes(unsafe { _mm256_cmp_ps::<_CMP_GE_OQ>(self.0, b.0) })
                }
                #[inline(always)]
                fn ne(self, b: Self) -> Self {
                    // Unordered: true where either is NaN, as `!=` is.
                    $lanes(unsafe { _mm256_cmp_ps::<_CMP_NEQ_UQ>(self.0, b.0) })
                }
                #[inline(always)]
                fn eq(self, b: Self) -> Self {
                    $lanes(unsafe { _mm256_cmp_ps::<_CMP_EQ_OQ>(self.0, b.0) })
                }
                #[inline(always)]
                fn and(self, b: Self) -> Self {
                    $lanes(unsafe { _mm256_and_ps(self.0, b.0) })
                }
                #[inline(always)]
                fn or(self, b: Self) -> Self {
                    $lanes(unsafe { _mm256_or_ps(self.0, b.0) })
                }
                #[inline(always)]
                fn and_not(self, b: Self) -> Self {
                    $lanes(unsafe { _mm256_andnot_ps(b.0, self.0) })
                }
                #[inline(always)]
                fn load_halves(_: $cpu, lo: &[f32; 4], hi: &[f32; 4]) -> Self {
                    $lanes(unsafe { _mm256_loadu2_m128(hi.as_ptr(), lo.as_ptr()) })
                }
                #[inline(always)]
                fn select(self, t: Self, f: Self) -> Self {
                    $lanes(unsafe { _mm256_blendv_ps(f.0, t.0, self.0) })
                }
                #[inline(always)]
                fn bitmask(self) -> u32 {
                    (unsafe { _mm256_movemask_ps(self.0) }) as u32
                }
                #[inline(always)]
                fn sign_fill(self) -> Self {
                    // An arithmetic shift of the integer lanes (AVX2).
                    $lanes(unsafe {
                        _mm256_castsi256_ps(_mm256_srai_epi32::<31>(_mm256_castps_si256(self.0)))
                    })
                }
                #[inline(always)]
                fn store(self, out: &mut wide::f32x8) {
                    // `f32x8` is eight `f32`s (Pod), so its bytes are a `[f32; 8]`.
                    let out: &mut [f32; 8] = bytemuck::cast_mut(out);
                    unsafe { _mm256_storeu_ps(out.as_mut_ptr(), self.0) }
                }
                #[inline(always)]
                fn le_bits(self, b: Self) -> u32 {
                    avx_lanes!(@le_bits $lanes, self, b)
                }
                #[inline(always)]
                fn order_hits(
                    self,
                    mask: u32,
                    child: &[u32; 8],
                    count: &[u32; 8],
                ) -> (usize, [u32; 8], [u32; 8], [f32; 8]) {
                    // The keys of the hit slots, the others zero (a missed slot sorts last),
                    // sorted in registers by a bitonic network, the children and counts
                    // permuted by the sorted slots.
                    let keys = unsafe {
                        let slot = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
                        let bits = _mm256_and_si256(_mm256_castps_si256(self.0), _mm256_set1_epi32(!7));
                        avx_lanes!(@only $lanes, _mm256_or_si256(bits, slot), mask, slot)
                    };
                    // SAFETY: as for every method here, `self` exists only where the CPU has
                    // AVX2.
                    let sorted = unsafe { sort8_descending(keys) };
                    let mut out = ([0u32; 8], [0u32; 8], [0.0f32; 8]);
                    unsafe {
                        let slots = _mm256_and_si256(sorted, _mm256_set1_epi32(7));
                        let c = _mm256_loadu_si256(child.as_ptr().cast());
                        let n = _mm256_loadu_si256(count.as_ptr().cast());
                        let d = _mm256_and_si256(sorted, _mm256_set1_epi32(!7));
                        _mm256_storeu_si256(out.0.as_mut_ptr().cast(), _mm256_permutevar8x32_epi32(c, slots));
                        _mm256_storeu_si256(out.1.as_mut_ptr().cast(), _mm256_permutevar8x32_epi32(n, slots));
                        _mm256_storeu_si256(out.2.as_mut_ptr().cast(), d);
                    }
                    (mask.count_ones() as usize, out.0, out.1, out.2)
                }
                #[inline(always)]
                fn outlined<R>(_: $cpu, f: impl FnOnce() -> R) -> R {
                    /// # Safety
                    /// The CPU must support the features named.
                    #[target_feature(enable = $features)]
                    #[cold]
                    #[inline(never)]
                    unsafe fn run<R>(f: impl FnOnce() -> R) -> R {
                        f()
                    }
                    // SAFETY: the proof argument says the CPU has the features.
                    unsafe { run(f) }
                }
            }
        };
        (@le_bits Avx, $a:expr, $b:expr) => {
            $a.le($b).bitmask()
        };
        (@le_bits Avx512, $a:expr, $b:expr) => {
            // Straight into a mask register: no lane mask to move out.
            (unsafe { _mm256_cmp_ps_mask::<_CMP_LE_OQ>($a.0, $b.0) }) as u32
        };
        // The lanes of `v` whose bit is set in `mask`, zero elsewhere.
        (@only Avx, $v:expr, $mask:expr, $slot:expr) => {{
            let bit = _mm256_sllv_epi32(_mm256_set1_epi32(1), $slot);
            let on = _mm256_cmpeq_epi32(_mm256_and_si256(_mm256_set1_epi32($mask as i32), bit), bit);
            _mm256_and_si256($v, on)
        }};
        (@only Avx512, $v:expr, $mask:expr, $slot:expr) => {{
            let _ = $slot;
            _mm256_maskz_mov_epi32($mask as __mmask8, $v)
        }};
    }

    /// The eight lanes sorted in decreasing order as unsigned integers: a bitonic network of
    /// six compare-exchange steps, each a shuffle, a minimum, a maximum and a blend. Inlined
    /// into its caller, whose instruction set compiles it.
    ///
    /// # Safety
    /// The CPU must support AVX2.
    #[inline(always)]
    unsafe fn sort8_descending(v: __m256i) -> __m256i {
        // SAFETY: register operations of AVX2, which the caller vouches for.
        unsafe {
            // Partners i ^ 1 and i ^ 2 within each 128-bit half; i ^ 4 across the halves.
            macro_rules! step {
                ($v:expr, $partner:expr, $take_min:literal) => {{
                    let p = $partner;
                    let (lo, hi) = (_mm256_min_epu32($v, p), _mm256_max_epu32($v, p));
                    _mm256_blend_epi32::<$take_min>(hi, lo)
                }};
            }
            let v = step!(v, _mm256_shuffle_epi32::<0b1011_0001>(v), 0b0110_0110);
            let v = step!(v, _mm256_shuffle_epi32::<0b0100_1110>(v), 0b0011_1100);
            let v = step!(v, _mm256_shuffle_epi32::<0b1011_0001>(v), 0b0101_1010);
            let v = step!(v, _mm256_permute4x64_epi64::<0b0100_1110>(v), 0b1111_0000);
            let v = step!(v, _mm256_shuffle_epi32::<0b0100_1110>(v), 0b1100_1100);
            step!(v, _mm256_shuffle_epi32::<0b1011_0001>(v), 0b1010_1010)
        }
    }

    avx_lanes!(Avx, Avx2Cpu, "avx2,fma");
    avx_lanes!(
        Avx512,
        Avx512Cpu,
        "avx512f,avx512vl,avx512bw,avx512dq,avx2,fma"
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every operation on awkward lanes (NaN in either operand, signed zeros, infinities,
    /// subnormals) against the plain `f32` operation it stands for, on each implementation.
    fn check<V: F8>(cpu: V::Cpu) {
        let a = [
            f32::NAN,
            1.0,
            -0.0,
            f32::INFINITY,
            1e-40,
            -3.5,
            2.0,
            f32::NAN,
        ];
        let b = [
            2.0,
            f32::NAN,
            0.0,
            1.0,
            -1e-40,
            -3.5,
            f32::NEG_INFINITY,
            f32::NAN,
        ];
        // Opaque to the optimiser: a division folded at compile time gives a NaN of another
        // sign than the CPU's (0/0 is 0x7fc00000 folded, 0xffc00000 on x86).
        let (a, b) = std::hint::black_box((a, b));
        let (va, vb) = (V::load(cpu, &a), V::load(cpu, &b));
        let same = |got: [f32; 8], want: [f32; 8], what: &str| {
            let bits = |x: [f32; 8]| x.map(f32::to_bits);
            assert_eq!(bits(got), bits(want), "{what}");
        };
        let lanes = |f: fn(f32, f32) -> f32| std::array::from_fn(|i| f(a[i], b[i]));
        same(va.add(vb).to_array(), lanes(|x, y| x + y), "add");
        same(va.sub(vb).to_array(), lanes(|x, y| x - y), "sub");
        same(va.mul(vb).to_array(), lanes(|x, y| x * y), "mul");
        same(va.div(vb).to_array(), lanes(|x, y| x / y), "div");
        let nan_first_max = |x: f32, y: f32| if x > y { x } else { y };
        let nan_first_min = |x: f32, y: f32| if x < y { x } else { y };
        same(va.max_nan_first(vb).to_array(), lanes(nan_first_max), "max");
        same(va.min_nan_first(vb).to_array(), lanes(nan_first_min), "min");
        let mask =
            |f: fn(f32, f32) -> bool| (0..8).fold(0u32, |m, i| m | (f(a[i], b[i]) as u32) << i);
        assert_eq!(va.lt(vb).bitmask(), mask(|x, y| x < y), "lt");
        assert_eq!(va.le(vb).bitmask(), mask(|x, y| x <= y), "le");
        assert_eq!(va.ge(vb).bitmask(), mask(|x, y| x >= y), "ge");
        assert_eq!(va.ne(vb).bitmask(), mask(|x, y| x != y), "ne");
        assert_eq!(va.le_bits(vb), mask(|x, y| x <= y), "le_bits");
        assert_eq!(va.eq(vb).bitmask(), mask(|x, y| x == y), "eq");
        assert_eq!(va.lt(vb).or(va.eq(vb)).bitmask(), mask(|x, y| x <= y), "or");
        assert_eq!(
            va.le(vb).and_not(va.eq(vb)).bitmask(),
            mask(|x, y| x < y),
            "and_not"
        );
        let (lo, hi): ([f32; 4], [f32; 4]) = ([a[0], a[1], a[2], a[3]], [b[4], b[5], b[6], b[7]]);
        same(
            V::load_halves(cpu, &lo, &hi).to_array(),
            [a[0], a[1], a[2], a[3], b[4], b[5], b[6], b[7]],
            "load_halves",
        );
        assert_eq!(
            va.le(vb).and(va.ne(vb)).bitmask(),
            mask(|x, y| x < y),
            "and"
        );
        let m = va.ge(vb);
        same(
            m.select(va, vb).to_array(),
            std::array::from_fn(|i| if a[i] >= b[i] { a[i] } else { b[i] }),
            "select",
        );
        same(V::splat(cpu, -0.0).to_array(), [-0.0; 8], "splat");
        same(V::of(cpu, &f32x8::from(a)).to_array(), a, "of");
        let mut stored = f32x8::ZERO;
        vb.store(&mut stored);
        same(stored.to_array(), b, "store");
        let signs = a.map(|x| f32::from_bits(0u32.wrapping_sub(x.to_bits() >> 31)));
        same(va.sign_fill().to_array(), signs, "sign_fill");
    }

    #[test]
    fn portable_lanes_are_the_scalar_operations() {
        check::<f32x8>(());
        check_order::<f32x8>(());
    }

    /// Every set of two or more hit slots, over distances with ties, zeros and wide ranges:
    /// the order is the scalar insertion order of the keys, children and counts follow their
    /// slots, and the distances given back are the keys'.
    fn check_order<V: F8>(cpu: V::Cpu) {
        let mut rng = crate::rng::Rng::new(11);
        let child: [u32; 8] = std::array::from_fn(|i| 100 + i as u32);
        let count: [u32; 8] = std::array::from_fn(|i| (i as u32) << 28 | 7);
        for round in 0..2000 {
            let t: [f32; 8] = std::array::from_fn(|_| match round % 3 {
                0 => (rng.in_box(glam::Vec3A::ZERO, glam::Vec3A::ONE).x * 4.0).floor(),
                1 => rng.in_box(glam::Vec3A::ZERO, glam::Vec3A::splat(1e6)).x,
                _ => 0.0,
            });
            for mask in 0u32..256 {
                if mask.count_ones() < 2 {
                    continue;
                }
                let got = V::load(cpu, &t).order_hits(mask, &child, &count);
                let want = order_hits_scalar(&t, mask, &child, &count);
                let k = want.0;
                assert_eq!(got.0, k, "count, mask {mask:#b}");
                assert_eq!(got.1[..k], want.1[..k], "children, mask {mask:#b}, t {t:?}");
                assert_eq!(got.2[..k], want.2[..k], "counts, mask {mask:#b}");
                assert_eq!(got.3[..k], want.3[..k], "distances, mask {mask:#b}");
                // Farthest first, every hit slot once.
                assert!(want.3[..k].windows(2).all(|w| w[0] >= w[1]));
                let mut slots: Vec<u32> = want.1[..k].iter().map(|c| c - 100).collect();
                slots.sort();
                assert_eq!(
                    slots,
                    super::super::simd::bits(mask)
                        .map(|i| i as u32)
                        .collect::<Vec<_>>()
                );
            }
        }
    }

    #[cfg(target_arch = "x86_64")]
    #[test]
    fn avx_lanes_are_the_scalar_operations() {
        if let Some(cpu) = crate::isa::Avx2Cpu::detect() {
            check::<Avx>(cpu);
            check_order::<Avx>(cpu);
        }
    }

    #[cfg(target_arch = "x86_64")]
    #[test]
    fn avx512_lanes_are_the_scalar_operations() {
        if let Some(cpu) = crate::isa::Avx512Cpu::detect() {
            check::<Avx512>(cpu);
            check_order::<Avx512>(cpu);
        }
    }
}
