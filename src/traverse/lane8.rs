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
    fn and(self, b: Self) -> Self;
    /// Lanes of `t` where `self` is set, of `f` elsewhere.
    fn select(self, t: Self, f: Self) -> Self;
    /// Bit `i` set where lane `i`'s sign bit is set (a mask lane is true).
    fn bitmask(self) -> u32;
    /// Each lane's sign bit copied into all its bits (a lane mask of the negative lanes,
    /// `-0.0` and NaNs with the sign bit among them).
    fn sign_fill(self) -> Self;

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
    fn and(self, b: Self) -> Self {
        self & b
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

#[cfg(target_arch = "x86_64")]
pub(crate) use avx::Avx;

#[cfg(target_arch = "x86_64")]
mod avx {
    use super::F8;
    use crate::isa::Avx2Cpu;
    use std::arch::x86_64::*;

    /// Eight lanes in one AVX register. The field is private to this module, and the only
    /// constructors (`splat`, `load`) take an [`Avx2Cpu`], the proof that the CPU has AVX2 and
    /// FMA: a value exists only on such a CPU. Every method is inlined into the kernels'
    /// `#[target_feature]` entry points.
    #[derive(Clone, Copy)]
    pub(crate) struct Avx(__m256);

    // SAFETY (every `unsafe` block below): the intrinsics need AVX, which the CPU has wherever
    // an `Avx` value exists (it was made from an `Avx2Cpu`, which only `Avx2Cpu::detect`
    // makes, after the CPU reported AVX2 and FMA); loads and stores go through references to
    // eight floats.
    impl F8 for Avx {
        type Cpu = Avx2Cpu;
        #[inline(always)]
        fn splat(_: Avx2Cpu, x: f32) -> Self {
            Avx(unsafe { _mm256_set1_ps(x) })
        }
        #[inline(always)]
        fn load(_: Avx2Cpu, a: &[f32; 8]) -> Self {
            Avx(unsafe { _mm256_loadu_ps(a.as_ptr()) })
        }
        #[inline(always)]
        fn to_array(self) -> [f32; 8] {
            let mut out = [0.0f32; 8];
            unsafe { _mm256_storeu_ps(out.as_mut_ptr(), self.0) };
            out
        }
        #[inline(always)]
        fn add(self, b: Self) -> Self {
            Avx(unsafe { _mm256_add_ps(self.0, b.0) })
        }
        #[inline(always)]
        fn sub(self, b: Self) -> Self {
            Avx(unsafe { _mm256_sub_ps(self.0, b.0) })
        }
        #[inline(always)]
        fn mul(self, b: Self) -> Self {
            Avx(unsafe { _mm256_mul_ps(self.0, b.0) })
        }
        #[inline(always)]
        fn div(self, b: Self) -> Self {
            Avx(unsafe { _mm256_div_ps(self.0, b.0) })
        }
        #[inline(always)]
        fn max_nan_first(self, b: Self) -> Self {
            Avx(unsafe { _mm256_max_ps(self.0, b.0) })
        }
        #[inline(always)]
        fn min_nan_first(self, b: Self) -> Self {
            Avx(unsafe { _mm256_min_ps(self.0, b.0) })
        }
        #[inline(always)]
        fn lt(self, b: Self) -> Self {
            Avx(unsafe { _mm256_cmp_ps::<_CMP_LT_OQ>(self.0, b.0) })
        }
        #[inline(always)]
        fn le(self, b: Self) -> Self {
            Avx(unsafe { _mm256_cmp_ps::<_CMP_LE_OQ>(self.0, b.0) })
        }
        #[inline(always)]
        fn ge(self, b: Self) -> Self {
            Avx(unsafe { _mm256_cmp_ps::<_CMP_GE_OQ>(self.0, b.0) })
        }
        #[inline(always)]
        fn ne(self, b: Self) -> Self {
            // Unordered: true where either is NaN, as `!=` is.
            Avx(unsafe { _mm256_cmp_ps::<_CMP_NEQ_UQ>(self.0, b.0) })
        }
        #[inline(always)]
        fn and(self, b: Self) -> Self {
            Avx(unsafe { _mm256_and_ps(self.0, b.0) })
        }
        #[inline(always)]
        fn select(self, t: Self, f: Self) -> Self {
            Avx(unsafe { _mm256_blendv_ps(f.0, t.0, self.0) })
        }
        #[inline(always)]
        fn bitmask(self) -> u32 {
            (unsafe { _mm256_movemask_ps(self.0) }) as u32
        }
        #[inline(always)]
        fn sign_fill(self) -> Self {
            // An arithmetic shift of the integer lanes (AVX2).
            Avx(unsafe {
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
        fn outlined<R>(_: Avx2Cpu, f: impl FnOnce() -> R) -> R {
            /// # Safety
            /// The CPU must support AVX2 and FMA.
            #[target_feature(enable = "avx2,fma")]
            #[cold]
            #[inline(never)]
            unsafe fn run<R>(f: impl FnOnce() -> R) -> R {
                f()
            }
            // SAFETY: the `Avx2Cpu` argument proves the CPU has AVX2 and FMA.
            unsafe { run(f) }
        }
    }
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
    }

    #[cfg(target_arch = "x86_64")]
    #[test]
    fn avx_lanes_are_the_scalar_operations() {
        if let Some(cpu) = crate::isa::Avx2Cpu::detect() {
            check::<Avx>(cpu);
        }
    }
}
