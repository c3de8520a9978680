//! Which instruction set the wide kernels run on, chosen at run time.
//!
//! `wide` picks SSE or AVX when a crate is compiled, and a binary built for baseline x86-64
//! gets SSE. The AVX2 kernels are compiled separately under `#[target_feature]` and chosen
//! once per BVH, when it is built, from what the CPU reports; the portable kernels (`wide`:
//! SSE2 on x86-64, NEON on aarch64, scalar elsewhere) run everywhere else. Both compute every
//! float the same way, operation for operation, so they return bit-identical answers.

use std::fmt;

/// The kernels a BVH traverses with.
///
/// ```
/// use quiver::Isa;
/// let isa = Isa::detect();
/// assert!(isa.is_supported());
/// assert!(Isa::Portable.is_supported());
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Isa {
    /// `wide`'s SIMD types as compiled for the target (SSE2 on baseline x86-64).
    Portable,
    /// x86-64 AVX2 (256-bit lanes; FMA present but unused, so the answers stay
    /// bit-identical to the portable kernels').
    Avx2,
}

/// The environment variable that forces an instruction set: `portable` or `avx2`.
pub const ISA_ENV: &str = "QUIVER_ISA";

impl Isa {
    /// Every instruction set, portable first.
    pub const ALL: [Isa; 2] = [Isa::Portable, Isa::Avx2];

    /// The best instruction set this CPU runs, unless [`ISA_ENV`] says `portable` (or
    /// `avx2`, which is honoured only where supported). Read when a BVH is built.
    pub fn detect() -> Isa {
        match std::env::var(ISA_ENV).as_deref() {
            Ok("portable") => Isa::Portable,
            _ => Isa::best(),
        }
    }

    /// The best instruction set this CPU runs.
    pub fn best() -> Isa {
        if Isa::Avx2.is_supported() {
            Isa::Avx2
        } else {
            Isa::Portable
        }
    }

    /// True when this CPU can run the kernels.
    pub fn is_supported(self) -> bool {
        match self {
            Isa::Portable => true,
            Isa::Avx2 => avx2_supported(),
        }
    }

    /// `self` if supported, else [`Isa::Portable`].
    pub fn or_portable(self) -> Isa {
        if self.is_supported() {
            self
        } else {
            Isa::Portable
        }
    }

    /// The name reports use.
    pub fn name(self) -> &'static str {
        match self {
            Isa::Portable => "portable",
            Isa::Avx2 => "avx2",
        }
    }
}

impl fmt::Display for Isa {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

#[cfg(target_arch = "x86_64")]
fn avx2_supported() -> bool {
    is_x86_feature_detected!("avx2") && is_x86_feature_detected!("fma")
}

#[cfg(not(target_arch = "x86_64"))]
fn avx2_supported() -> bool {
    false
}
