//! Which instruction set the wide kernels run on, chosen at run time.
//!
//! `wide` picks SSE or AVX when a crate is compiled, and a binary built for baseline x86-64
//! gets SSE. The AVX2 and AVX-512 kernels are compiled separately under `#[target_feature]`
//! (`traverse::dispatch`) and chosen once per BVH, when it is built, from what the CPU
//! reports; the portable kernels (`wide`: SSE2 on x86-64, NEON on aarch64, scalar elsewhere)
//! run everywhere else. All compute every float the same way, operation for operation, so they
//! return bit-identical answers.

use crate::names::{by_name, ParseError};
use std::fmt;

/// The kernels a BVH traverses with.
///
/// ```
/// use quiver_rt::Isa;
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
    /// x86-64 AVX-512 (F, VL, BW, DQ): the AVX2 kernels' lanes with mask registers,
    /// compression and 32 vector registers.
    Avx512,
}

/// Proof that this CPU runs AVX2 and FMA instructions. Its field is private to this module and
/// [`Avx2Cpu::detect`], which asks the CPU, is its only constructor: a value exists only
/// where the instructions do, which is what every AVX2 kernel's safety rests on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Avx2Cpu(());

impl Avx2Cpu {
    /// The proof, where the CPU reports AVX2 and FMA.
    pub(crate) fn detect() -> Option<Avx2Cpu> {
        avx2_supported().then_some(Avx2Cpu(()))
    }
}

/// Proof that this CPU runs AVX-512 F, VL, BW and DQ instructions, and AVX2 and FMA. Made
/// only by [`Avx512Cpu::detect`], as [`Avx2Cpu`] is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Avx512Cpu(());

impl Avx512Cpu {
    /// The proof, where the CPU reports AVX-512 F, VL, BW, DQ, AVX2 and FMA.
    pub(crate) fn detect() -> Option<Avx512Cpu> {
        avx512_supported().then_some(Avx512Cpu(()))
    }
}

/// The kernels a BVH's queries run on, checked when chosen: the AVX2 ones carry the proof
/// that the CPU has them, so no value of this type can send a query to instructions the CPU
/// lacks. Layouts keep one in a private field.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Kernels {
    /// `wide`'s lanes as compiled for the target.
    Portable,
    /// AVX2 lanes, on a CPU that has them.
    Avx2(Avx2Cpu),
    /// AVX-512 lanes, on a CPU that has them.
    Avx512(Avx512Cpu),
}

impl Kernels {
    /// The kernels for `isa` where this CPU runs them, else the best it runs below `isa`.
    pub(crate) fn new(isa: Isa) -> Kernels {
        match isa {
            Isa::Avx512 => {
                Avx512Cpu::detect().map_or_else(|| Kernels::new(Isa::Avx2), Kernels::Avx512)
            }
            Isa::Avx2 => Avx2Cpu::detect().map_or(Kernels::Portable, Kernels::Avx2),
            Isa::Portable => Kernels::Portable,
        }
    }

    /// The instruction set they run on.
    pub(crate) fn isa(self) -> Isa {
        match self {
            Kernels::Portable => Isa::Portable,
            Kernels::Avx2(_) => Isa::Avx2,
            Kernels::Avx512(_) => Isa::Avx512,
        }
    }
}

impl Isa {
    /// The environment variable that forces an instruction set, `QUIVER_ISA`: `portable`,
    /// `avx2` or `avx512` (see [`Isa::detect`]).
    ///
    /// ```
    /// assert_eq!(quiver_rt::Isa::ENV, "QUIVER_ISA");
    /// ```
    pub const ENV: &'static str = "QUIVER_ISA";

    /// Every instruction set, portable first.
    pub const ALL: [Isa; 3] = [Isa::Portable, Isa::Avx2, Isa::Avx512];

    /// The best instruction set this CPU runs, unless [`Isa::ENV`] names another (honoured
    /// only where supported; a CPU without it gets the best below it). Read when a BVH is
    /// built. A value of [`Isa::ENV`] that names no instruction set is ignored here;
    /// [`Isa::from_env`] reports it (the `quiver` command refuses to start with one).
    pub fn detect() -> Isa {
        match Isa::from_env() {
            Ok(Some(isa)) => isa.or_best_below(),
            _ => Isa::best(),
        }
    }

    /// What [`Isa::ENV`] asks for: `None` when it is unset or empty, an error naming the
    /// value and the accepted ones when it names no instruction set.
    ///
    /// ```
    /// use quiver_rt::Isa;
    /// assert_eq!("portable".parse::<Isa>(), Ok(Isa::Portable));
    /// assert_eq!("Portable".parse::<Isa>().unwrap_err().expected, ["portable", "avx2", "avx512"]);
    /// ```
    ///
    /// # Errors
    /// [`ParseError`] (its `what` names the variable) when the value names no instruction
    /// set.
    pub fn from_env() -> Result<Option<Isa>, ParseError> {
        let given = match std::env::var(Isa::ENV) {
            Err(std::env::VarError::NotPresent) => return Ok(None),
            Err(std::env::VarError::NotUnicode(v)) => v.to_string_lossy().into_owned(),
            Ok(v) if v.is_empty() => return Ok(None),
            Ok(v) => v,
        };
        given.parse().map(Some).map_err(|e: ParseError| ParseError {
            what: "instruction set in QUIVER_ISA",
            ..e
        })
    }

    /// The best instruction set this CPU runs.
    pub fn best() -> Isa {
        Isa::Avx512.or_best_below()
    }

    /// True when this CPU can run the kernels.
    pub fn is_supported(self) -> bool {
        match self {
            Isa::Portable => true,
            Isa::Avx2 => avx2_supported(),
            Isa::Avx512 => avx512_supported(),
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

    /// `self` if supported, else the best instruction set below it that is.
    pub fn or_best_below(self) -> Isa {
        Kernels::new(self).isa()
    }

    /// The name reports use.
    pub fn name(self) -> &'static str {
        match self {
            Isa::Portable => "portable",
            Isa::Avx2 => "avx2",
            Isa::Avx512 => "avx512",
        }
    }
}

impl std::str::FromStr for Isa {
    type Err = ParseError;

    /// An instruction set by its [`Isa::name`]; the error lists the names.
    fn from_str(s: &str) -> Result<Self, ParseError> {
        by_name(s, &Isa::ALL, Isa::name, "instruction set")
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

#[cfg(target_arch = "x86_64")]
fn avx512_supported() -> bool {
    avx2_supported()
        && is_x86_feature_detected!("avx512f")
        && is_x86_feature_detected!("avx512vl")
        && is_x86_feature_detected!("avx512bw")
        && is_x86_feature_detected!("avx512dq")
}

#[cfg(not(target_arch = "x86_64"))]
fn avx512_supported() -> bool {
    false
}

/// Asks the CPU to start loading the cache line that holds `x` (and, with `lines` 2, the
/// next one too), so that a gather's memory latency overlaps the work before the load; a
/// no-op off x86-64.
#[inline(always)]
pub(crate) fn prefetch<T>(x: &T, lines: usize) {
    prefetch_lines((x as *const T).cast(), lines);
}

/// [`prefetch`] of `lines` cache lines from element `i` of `s`, whether or not `s` has one:
/// for a walk that has just read an index it trusts, where a bounds check would only cost.
#[inline(always)]
pub(crate) fn prefetch_index<T>(s: &[T], i: usize, lines: usize) {
    // `wrapping_add` keeps the address arithmetic defined for any `i`; nothing is read.
    prefetch_lines(s.as_ptr().wrapping_add(i).cast(), lines);
}

#[inline(always)]
fn prefetch_lines(p: *const i8, lines: usize) {
    #[cfg(target_arch = "x86_64")]
    for l in 0..lines {
        // SAFETY: SSE is part of every x86-64 CPU. A prefetch is a hint: it reads nothing
        // into the program and faults on nothing, whatever the address (the lines may lie
        // past the caller's data; `wrapping_add` keeps that pointer arithmetic defined).
        unsafe {
            use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
            _mm_prefetch::<_MM_HINT_T0>(p.wrapping_add(64 * l));
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = (p, lines);
}

/// For a pass that reads `s` in order: prefetches the element some 2 KiB past `s[i]`. On
/// the machines we measure, the processor's own prefetching left such passes waiting on
/// memory (a refit's first pass over the dragon's triangles took about 11 ms less at 1
/// thread with it).
#[inline(always)]
pub(crate) fn prefetch_stream<T>(s: &[T], i: usize) {
    let ahead = (2048 / std::mem::size_of::<T>().max(1)).max(1);
    prefetch_at(s, i + ahead);
}

/// [`prefetch`] of `s[i]`'s first cache line, where `s` has an element `i`.
#[inline(always)]
pub(crate) fn prefetch_at<T>(s: &[T], i: usize) {
    if let Some(x) = s.get(i) {
        prefetch(x, 1);
    }
}
