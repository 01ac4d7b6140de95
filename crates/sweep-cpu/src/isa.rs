//! The vector instructions the sweep's row loops run on, chosen at run time.
//!
//! One build runs on every x86-64 CPU: the row kernels are compiled twice, once for the
//! baseline (SSE2, four floats a vector) and once for x86-64-v3 (AVX2, FMA, BMI: eight
//! floats, every x86-64 CPU since Haswell (2013) and Zen (2017)), and each call picks the
//! widest one the CPU has. The results are the same bit for bit on either path: Rust
//! never fuses a multiply and an add, nor reorders float sums, by itself, so wider
//! vectors run the same operations in the same order (`measure/tests/dispatch.rs` holds it).
//!
//! A kernel takes part by being `#[inline(always)]` and called through
//! `vectorised!` (this module's crate-private macro): the closure it is called from is inlined into a
//! function compiled with the v3 features, and the kernel into the closure. What the
//! kernel calls is compiled for v3 only where it is inlined too.
//!
//! `LIGHTGRID_SIMD=baseline` in the environment (read once) or [`force_baseline`]
//! keeps every sweep of the process on the baseline path, to compare the two.

use std::sync::OnceLock;
use std::sync::atomic::{AtomicBool, Ordering};

/// The instruction sets a sweep's row kernels can run on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum VectorIsa {
    /// The target's baseline (x86-64: SSE2; on other architectures, what the build targets).
    Baseline,
    /// x86-64-v3: AVX, AVX2, FMA, BMI1/2, F16C, LZCNT, MOVBE.
    X86V3,
}

/// Set by [`force_baseline`].
static FORCED_BASELINE: AtomicBool = AtomicBool::new(false);

/// What this CPU and the environment allow, found once.
fn detected() -> VectorIsa {
    static D: OnceLock<VectorIsa> = OnceLock::new();
    *D.get_or_init(|| {
        let env = std::env::var("LIGHTGRID_SIMD").ok();
        let isa = if env.as_deref() == Some("baseline") {
            VectorIsa::Baseline
        } else if has_v3() {
            VectorIsa::X86V3
        } else {
            VectorIsa::Baseline
        };
        tracing::debug!(?isa, "sweep row kernels");
        isa
    })
}

#[cfg(target_arch = "x86_64")]
fn has_v3() -> bool {
    std::arch::is_x86_feature_detected!("avx")
        && std::arch::is_x86_feature_detected!("avx2")
        && std::arch::is_x86_feature_detected!("fma")
        && std::arch::is_x86_feature_detected!("bmi1")
        && std::arch::is_x86_feature_detected!("bmi2")
        && std::arch::is_x86_feature_detected!("f16c")
        && std::arch::is_x86_feature_detected!("lzcnt")
        && std::arch::is_x86_feature_detected!("movbe")
}

#[cfg(not(target_arch = "x86_64"))]
fn has_v3() -> bool {
    false
}

/// The instruction set the next sweep's row kernels run on.
pub fn vector_isa() -> VectorIsa {
    if FORCED_BASELINE.load(Ordering::Relaxed) {
        VectorIsa::Baseline
    } else {
        detected()
    }
}

/// Keeps every later sweep of this process on the baseline path (`true`), or lets them
/// use the widest path the CPU has again (`false`). For tests and comparisons: the
/// results are the same either way, only the time differs.
pub fn force_baseline(on: bool) {
    FORCED_BASELINE.store(on, Ordering::Relaxed);
}

/// Runs `f` compiled for the widest instruction set the CPU has (see the module docs).
#[inline(always)]
pub(crate) fn run<R>(f: impl FnOnce() -> R) -> R {
    #[cfg(target_arch = "x86_64")]
    if vector_isa() == VectorIsa::X86V3 {
        // SAFETY: `run_v3` needs the x86-64-v3 features, and `vector_isa` returns
        // `X86V3` only where `is_x86_feature_detected!` found every one of them.
        #[allow(unsafe_code)]
        return unsafe { run_v3(f) };
    }
    run_baseline(f)
}

/// `f()` on the baseline path, as its own function like [`run_v3`]: a caller holds two
/// calls, not a copy of the kernel, and inlines what it inlined before.
#[inline(never)]
fn run_baseline<R>(f: impl FnOnce() -> R) -> R {
    f()
}

/// `f()` compiled with the x86-64-v3 features (`f` is an `#[inline(always)]` closure).
/// Never inlined: each kernel stays its own function, as the profiles show it.
#[cfg(target_arch = "x86_64")]
#[inline(never)]
#[target_feature(enable = "avx,avx2,fma,bmi1,bmi2,f16c,lzcnt,movbe")]
fn run_v3<R>(f: impl FnOnce() -> R) -> R {
    f()
}

/// `[f(0), f(1), …]`, as `std::array::from_fn` gives, for code the row kernels inline:
/// std's version calls `f` through generic code that LLVM will not inline into a
/// function compiled for other target features ([`run_v3`]), so a kernel using it
/// would call out to the baseline path for it; this one inlines.
#[inline(always)]
pub(crate) fn array_from<T: Copy + Default, const N: usize>(
    mut f: impl FnMut(usize) -> T,
) -> [T; N] {
    let mut out = [T::default(); N];
    for (i, o) in out.iter_mut().enumerate() {
        *o = f(i);
    }
    out
}

/// `a.map(f)` for code the row kernels inline (see [`array_from`]).
#[inline(always)]
pub(crate) fn array_map<T: Copy, U: Copy + Default, const N: usize>(
    a: [T; N],
    mut f: impl FnMut(T) -> U,
) -> [U; N] {
    array_from(
        #[inline(always)]
        |i| f(a[i]),
    )
}

/// Calls a row kernel (an `#[inline(always)]` function) through [`run`]: compiled for
/// the widest instruction set the CPU has.
macro_rules! vectorised {
    ($e:expr) => {
        $crate::isa::run(
            #[inline(always)]
            || $e,
        )
    };
}
pub(crate) use vectorised;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn array_helpers_equal_std() {
        let f = |i: usize| (i as f32).sqrt() * 3.5 - 1.0;
        assert_eq!(array_from::<f32, 7>(f), std::array::from_fn::<f32, 7, _>(f));
        let a = [1.5f64, -2.0, 1e300, 0.0];
        assert_eq!(array_map(a, |v| v * 3.0), a.map(|v| v * 3.0));
    }

    #[test]
    fn forcing_the_baseline_is_seen_and_undone() {
        let auto = vector_isa();
        force_baseline(true);
        assert_eq!(vector_isa(), VectorIsa::Baseline);
        assert_eq!(run(|| 2 + 2), 4);
        force_baseline(false);
        assert_eq!(vector_isa(), auto);
    }

    #[cfg(target_arch = "x86_64")]
    #[test]
    fn v3_only_where_the_cpu_has_it() {
        if vector_isa() == VectorIsa::X86V3 {
            assert!(std::arch::is_x86_feature_detected!("avx2"));
            assert!(std::arch::is_x86_feature_detected!("fma"));
        }
    }
}
