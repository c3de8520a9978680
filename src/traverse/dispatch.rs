//! The one place a query picks its instruction set: a kernel is written once over lanes
//! ([`F8`]) as a [`LaneKernel`], and [`run`] calls it on the lanes of a BVH's [`Kernels`],
//! through a `#[target_feature]` trampoline per instruction set, with the layout's far-group
//! path compiled in or out. Adding an instruction set is one trampoline and one match arm here
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

/// Runs `kernel` on `kernels`' lanes, with the far groups' path when `far`. A layout holding
/// far groups takes a cold instantiation of its own, so the others carry no trace of it.
#[inline(always)]
pub(crate) fn run<K: LaneKernel>(kernels: Kernels, far: bool, kernel: K) -> K::Out {
    if far {
        return run_far(kernels, kernel);
    }
    run_as::<K, false>(kernels, kernel)
}

#[cold]
#[inline(never)]
fn run_far<K: LaneKernel>(kernels: Kernels, kernel: K) -> K::Out {
    run_as::<K, true>(kernels, kernel)
}

#[inline(always)]
fn run_as<K: LaneKernel, const FAR: bool>(kernels: Kernels, kernel: K) -> K::Out {
    match kernels {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: the `Avx2Cpu` proves the CPU has AVX2 and FMA (only detection makes one).
        Kernels::Avx2(cpu) => unsafe { avx2::<K, FAR>(cpu, kernel) },
        Kernels::Portable => portable::<K, FAR>(kernel),
    }
}

/// The kernel on portable lanes (`wide`'s, as compiled for the target), in a function of its
/// own as every instruction set's: inlined beside the far path's call, a walk kept its SIMD
/// state across that call.
#[inline(never)]
fn portable<K: LaneKernel, const FAR: bool>(kernel: K) -> K::Out {
    kernel.run::<f32x8, FAR>(())
}

/// The kernel on AVX2 lanes, compiled with AVX2 and FMA enabled (FMA is never contracted
/// into: the answers stay bit-identical to the portable lanes').
///
/// # Safety
/// The CPU must support AVX2 and FMA, which `cpu` proves.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn avx2<K: LaneKernel, const FAR: bool>(cpu: crate::isa::Avx2Cpu, kernel: K) -> K::Out {
    kernel.run::<super::lane8::Avx, FAR>(cpu)
}
