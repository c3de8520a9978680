//! The one place a query picks its instruction set: a kernel is written once over lanes
//! ([`F8`]) as a [`LaneKernel`], and [`run`] calls it on the lanes of a BVH's [`Kernels`],
//! through a `#[target_feature]` trampoline per instruction set, with the layout's far-group
//! path compiled in or out (a layout holding far groups runs the portable lanes). Adding an instruction set is one trampoline and one match arm here
//! (and its lane type in `lane8`); no kernel changes.
//!
//! Everything a kernel calls is `#[inline(always)]` (closures included), so it is compiled
//! inside the trampoline, with the trampoline's target features, whatever crate or codegen
//! unit the kernel is instantiated in; a generic function that were not inlined would be
//! compiled without them, and every lane operation in it would become a call.

use super::lane8::F8;
use crate::isa::Kernels;
use wide::f32x8;

/// A kernel written once over lanes: [`run`] calls `run::<V, FAR>` with the lanes of the
/// instruction set chosen. `FAR`: the layout holds far groups ([`crate::layout::Tri4`]), whose
/// path is compiled in only then.
pub(crate) trait LaneKernel {
    /// What the kernel answers.
    type Out;
    /// The kernel on lanes `V`. Must be `#[inline(always)]`, as everything it calls.
    fn run<V: F8, const FAR: bool>(self, cpu: V::Cpu) -> Self::Out;
}

/// Runs `kernel` on `kernels`' lanes; with the far groups' path when `far`, on the portable
/// lanes. A layout holding far groups (a scene mixing sizes far apart, rare) thus takes one
/// cold instantiation of its own, so the others carry no trace of it, and each kernel is
/// compiled once per instruction set plus once for that case, not twice per instruction set.
#[inline(always)]
pub(crate) fn run<K: LaneKernel>(kernels: Kernels, far: bool, kernel: K) -> K::Out {
    if far {
        return run_far(kernel);
    }
    run_as(kernels, kernel)
}

#[cold]
#[inline(never)]
fn run_far<K: LaneKernel>(kernel: K) -> K::Out {
    kernel.run::<f32x8, true>(())
}

#[inline(always)]
fn run_as<K: LaneKernel>(kernels: Kernels, kernel: K) -> K::Out {
    match kernels {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: the `Avx512Cpu` proves the CPU has AVX-512 F, VL, BW, DQ, AVX2 and FMA
        // (only detection makes one).
        Kernels::Avx512(cpu) => unsafe { avx512(cpu, kernel) },
        #[cfg(target_arch = "x86_64")]
        // SAFETY: the `Avx2Cpu` proves the CPU has AVX2 and FMA (only detection makes one).
        Kernels::Avx2(cpu) => unsafe { avx2(cpu, kernel) },
        Kernels::Portable => portable(kernel),
    }
}

/// The kernel on portable lanes (`wide`'s, as compiled for the target), in a function of its
/// own as every instruction set's: inlined beside the far path's call, a walk kept its SIMD
/// state across that call.
#[inline(never)]
fn portable<K: LaneKernel>(kernel: K) -> K::Out {
    kernel.run::<f32x8, false>(())
}

/// The kernel on AVX2 lanes, compiled with AVX2 and FMA enabled (FMA is never contracted
/// into: the answers stay bit-identical to the portable lanes').
///
/// # Safety
/// The CPU must support AVX2 and FMA, which `cpu` proves.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn avx2<K: LaneKernel>(cpu: crate::isa::Avx2Cpu, kernel: K) -> K::Out {
    kernel.run::<super::lane8::Avx, false>(cpu)
}

/// The kernel on AVX-512 lanes (256-bit, with mask registers), compiled with AVX-512 F, VL, BW
/// and DQ enabled.
///
/// # Safety
/// The CPU must support AVX-512 F, VL, BW, DQ, AVX2 and FMA, which `cpu` proves.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512vl,avx512bw,avx512dq,avx2,fma")]
unsafe fn avx512<K: LaneKernel>(cpu: crate::isa::Avx512Cpu, kernel: K) -> K::Out {
    kernel.run::<super::lane8::Avx512, false>(cpu)
}
