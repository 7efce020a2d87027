//! Runtime choice of the widest vector instructions for the loops written
//! to vectorize (the exact bands of points, the cone sweeps).
//!
//! The default build targets baseline x86-64 (SSE2), which every user's
//! CPU runs. Where the CPU also has AVX-512 (x86-64-v4), the same loops
//! compiled for it run about a fifth faster. AVX2 alone is not used: LLVM
//! turns the loops' mask selects into `vpmaskmov` stores, which are
//! microcoded and slower than SSE2 on AMD CPUs.
//!
//! Both variants give the same results bit for bit: Rust never contracts
//! or reorders floating-point operations, whatever the instruction set.

/// Run `kernel`, compiled for x86-64-v4 when the CPU has it.
///
/// The kernel must be a closure marked `#[inline(always)]` that calls
/// only `#[inline(always)]` code in its hot loops, so that they are
/// compiled inside the wide variant (a call out runs the baseline code).
#[inline(always)]
pub(crate) fn widest<R>(kernel: impl FnOnce() -> R) -> R {
    #[cfg(target_arch = "x86_64")]
    if has_x86_64_v4() && !baseline_only() {
        // SAFETY: the CPU has every feature `x86_64_v4` enables.
        return unsafe { x86_64_v4(kernel) };
    }
    kernel()
}

#[cfg(target_arch = "x86_64")]
fn has_x86_64_v4() -> bool {
    std::is_x86_feature_detected!("avx512f")
        && std::is_x86_feature_detected!("avx512bw")
        && std::is_x86_feature_detected!("avx512cd")
        && std::is_x86_feature_detected!("avx512dq")
        && std::is_x86_feature_detected!("avx512vl")
        && std::is_x86_feature_detected!("avx2")
        && std::is_x86_feature_detected!("fma")
        && std::is_x86_feature_detected!("bmi1")
        && std::is_x86_feature_detected!("bmi2")
        && std::is_x86_feature_detected!("lzcnt")
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512bw,avx512cd,avx512dq,avx512vl,avx2,fma,bmi1,bmi2,lzcnt")]
unsafe fn x86_64_v4<R>(kernel: impl FnOnce() -> R) -> R {
    kernel()
}

/// Set by a test to run the baseline variant; other tests running
/// meanwhile only take the slower path.
#[cfg(test)]
static BASELINE_ONLY: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);

#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn baseline_only() -> bool {
    #[cfg(test)]
    return BASELINE_ONLY.load(std::sync::atomic::Ordering::Relaxed);
    #[cfg(not(test))]
    false
}

/// `f`'s result with the baseline variant of every kernel.
#[cfg(test)]
pub(crate) fn with_baseline<R>(f: impl FnOnce() -> R) -> R {
    use std::sync::atomic::Ordering::Relaxed;
    BASELINE_ONLY.store(true, Relaxed);
    let result = f();
    BASELINE_ONLY.store(false, Relaxed);
    result
}
