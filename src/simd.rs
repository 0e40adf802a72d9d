//! Run-time dispatch of hand-written loops to the widest vector unit the CPU has.
//!
//! The crate is built for plain x86-64, whose vector registers hold two doubles, so a loop the
//! compiler vectorises runs at that width unless it is compiled a second time for AVX-512 or
//! AVX2 and chosen at run time. `on_widest_unit!` does that for one `#[inline(always)]`
//! function: the same portable code on every path. Rust never fuses a multiply and an add of its
//! own accord, and an explicit [`f64::mul_add`] is fused on every path (by the hardware where the
//! target has FMA, in software elsewhere), so every path rounds alike and gives the same bits:
//! the evaluator, the point evaluator and the solvers' substitutions and residuals rely on that
//! for results that do not depend on the machine.

/// Defines `fn $name` running `$portable`, an `#[inline(always)]` function of the same
/// signature, compiled for AVX-512F, else AVX2 with FMA, else the crate's own target (see the
/// module doc). The generics are written twice, as declared and as passed:
/// `fn name[const W: usize, T: Scalar][W, T](..)`, or `fn name[][](..)` without generics.
macro_rules! on_widest_unit {
    ($(#[$attr:meta])* $vis:vis fn $name:ident [$($decl:tt)*] [$($pass:tt)*]
     ($($a:ident: $at:ty),* $(,)?) $(-> $ret:ty)? = $portable:ident;) => {
        $(#[$attr])*
        $vis fn $name<$($decl)*>($($a: $at),*) $(-> $ret)? {
            #[cfg(target_arch = "x86_64")]
            {
                #[target_feature(enable = "avx512f")]
                unsafe fn wide512<$($decl)*>($($a: $at),*) $(-> $ret)? {
                    $portable::<$($pass)*>($($a),*)
                }
                #[target_feature(enable = "avx2,fma")]
                unsafe fn wide256<$($decl)*>($($a: $at),*) $(-> $ret)? {
                    $portable::<$($pass)*>($($a),*)
                }
                if std::arch::is_x86_feature_detected!("avx512f") {
                    // SAFETY: the CPU supports AVX-512F (checked just above).
                    return unsafe { wide512::<$($pass)*>($($a),*) };
                }
                if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma") {
                    // SAFETY: the CPU supports AVX2 and FMA (checked just above).
                    return unsafe { wide256::<$($pass)*>($($a),*) };
                }
            }
            $portable::<$($pass)*>($($a),*)
        }
    };
}
pub(crate) use on_widest_unit;
