//! Runtime CPU dispatch for the Schur kernels.
//!
//! The crate is compiled for the baseline of its target (SSE2 on x86-64), where LLVM can
//! neither use 256-bit vectors nor fuse multiply-adds. The hot loops are therefore written
//! once, generic over a [`MulAdd`] strategy, and on x86-64 CPUs with AVX2 and FMA they run
//! inside a function compiled with those features, so the inlined kernels are vectorized
//! 4-wide with fused multiply-adds. Results are deterministic for a given CPU.
#![allow(unsafe_code)]

/// a · b + c, fused or not.
pub(crate) trait MulAdd: Copy + Send + Sync {
    /// a · b + c.
    fn madd(a: f64, b: f64, c: f64) -> f64;
}

/// Rounds once (`f64::mul_add`); used only where the CPU has an FMA instruction.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Fused;

/// Rounds twice (a multiply, then an add): the baseline.
#[derive(Debug, Clone, Copy)]
#[cfg_attr(target_arch = "aarch64", allow(dead_code))]
pub(crate) struct Plain;

impl MulAdd for Fused {
    #[inline(always)]
    fn madd(a: f64, b: f64, c: f64) -> f64 {
        a.mul_add(b, c)
    }
}

impl MulAdd for Plain {
    #[inline(always)]
    fn madd(a: f64, b: f64, c: f64) -> f64 {
        a * b + c
    }
}

/// The instruction set the kernels run with.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Isa {
    /// The compilation target's baseline.
    Baseline,
    /// x86-64 with AVX2 and FMA.
    #[cfg(target_arch = "x86_64")]
    Avx2Fma,
}

impl Isa {
    /// The best instruction set of the running CPU.
    pub(crate) fn detect() -> Self {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
        {
            return Isa::Avx2Fma;
        }
        Isa::Baseline
    }
}

/// A computation whose body is monomorphized per multiply-add strategy. `run` must be
/// `#[inline(always)]` (and so must everything hot it calls) so that it is compiled with the
/// caller's target features.
pub(crate) trait Kernel {
    /// The result.
    type Output;
    /// Runs the computation.
    fn run<M: MulAdd>(self) -> Self::Output;
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn run_avx2_fma<K: Kernel>(kernel: K) -> K::Output {
    kernel.run::<Fused>()
}

/// Runs `kernel` with the best code for `isa`.
#[inline]
pub(crate) fn dispatch<K: Kernel>(isa: Isa, kernel: K) -> K::Output {
    match isa {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: `Isa::Avx2Fma` is only produced by `Isa::detect` after the CPU reported
        // both AVX2 and FMA, which is all `run_avx2_fma` requires.
        Isa::Avx2Fma => unsafe { run_avx2_fma(kernel) },
        #[cfg(target_arch = "aarch64")]
        // AArch64's baseline has fused multiply-add.
        Isa::Baseline => kernel.run::<Fused>(),
        #[cfg(not(target_arch = "aarch64"))]
        Isa::Baseline => kernel.run::<Plain>(),
    }
}
