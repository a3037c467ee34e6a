//! Runtime CPU dispatch for hot loops.
//!
//! Wheels are built for the x86-64 baseline (SSE2), where LLVM cannot vectorise strided loads such
//! as de-interleaving BGR. [`multiversion!`] compiles a function body twice — baseline and AVX2 —
//! and picks the AVX2 copy at run time when the CPU has it. Both copies are the same safe Rust, so
//! results are identical; only the instructions differ.

/// Defines a function whose body is also compiled for AVX2 and dispatched at run time.
macro_rules! multiversion {
    ($(#[$m:meta])* $vis:vis fn $name:ident($($arg:ident : $ty:ty),* $(,)?) $(-> $ret:ty)? $body:block) => {
        $(#[$m])*
        $vis fn $name($($arg: $ty),*) $(-> $ret)? {
            #[inline(always)]
            fn generic($($arg: $ty),*) $(-> $ret)? $body
            #[cfg(target_arch = "x86_64")]
            {
                #[target_feature(enable = "avx2")]
                unsafe fn avx2($($arg: $ty),*) $(-> $ret)? {
                    generic($($arg),*)
                }
                if std::is_x86_feature_detected!("avx2") {
                    // SAFETY: the CPU reports AVX2, the only requirement of `avx2`.
                    return unsafe { avx2($($arg),*) };
                }
            }
            generic($($arg),*)
        }
    };
}

pub(crate) use multiversion;
