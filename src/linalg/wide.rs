//! The widest vector instructions the CPU has, for the dense kernels whose time shows (the
//! derivatives' M⁻¹ and products on 20–40 coordinates): the same Rust body compiled twice, for
//! the x86-64 baseline (SSE2, what a portable build may assume) and for AVX2, and chosen at run
//! time. The body is plain safe code: no intrinsics, no change of arithmetic (no FMA
//! contraction), so both versions give the same numbers; AVX2 only does four lanes at once.
//! The one exception is the product `gemm_columns` (dense.rs), which has its own AVX2 + FMA
//! build with fused multiply-adds: its results differ in the last bits between CPUs with and
//! without FMA (never between runs on one machine).

/// `fn name(args) -> ret { body }`, run through an AVX2 build of `body` when the CPU has AVX2.
macro_rules! wide_fn {
    ($(#[$m:meta])* $vis:vis fn $name:ident($($arg:ident: $ty:ty),* $(,)?) $(-> $ret:ty)? $body:block) => {
        $(#[$m])*
        $vis fn $name($($arg: $ty),*) $(-> $ret)? {
            #[inline(always)]
            fn body($($arg: $ty),*) $(-> $ret)? $body
            #[cfg(target_arch = "x86_64")]
            {
                #[target_feature(enable = "avx2")]
                fn avx2($($arg: $ty),*) $(-> $ret)? {
                    body($($arg),*)
                }
                if std::is_x86_feature_detected!("avx2") {
                    // SAFETY: the CPU has AVX2 (checked at run time just above), the only
                    // requirement of calling a function compiled for it.
                    return unsafe { avx2($($arg),*) };
                }
            }
            body($($arg),*)
        }
    };
}
