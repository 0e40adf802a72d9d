//! The working precisions of the distributed factorisations: f64 for every solver, f32 for the
//! factorisation of a mixed-precision solve (see `mixed`). The trait adds to faer's `RealField`
//! what the row-cyclic code needs: conversions to and from f64 and the collectives that move
//! values of the type between ranks.

use faer::traits::RealField;

use crate::par::Comm;

/// A real type a row-cyclic matrix may hold: f32 or f64.
pub trait Scalar: RealField + Copy + Send + Sync + std::ops::Neg<Output = Self> {
    /// The unit roundoff of the type, as an f64.
    const EPSILON: f64;
    /// The value nearest to `v`.
    fn of(v: f64) -> Self;
    /// The value as an f64 (exact).
    fn f64(self) -> f64;
    /// |self|.
    fn magnitude(self) -> Self;
    /// [`Comm::all_gather_f64`] for this type.
    fn all_gather(comm: &dyn Comm, send: &[Self], counts: &[usize], recv: &mut [Self]);
    /// [`Comm::shift_f64`] for this type.
    fn shift(comm: &dyn Comm, dest: usize, source: usize, send: &[Self], recv: &mut [Self]);
    /// [`Comm::all_gather_f64_while`] for this type.
    fn all_gather_while(
        comm: &dyn Comm,
        send: &[Self],
        counts: &[usize],
        recv: &mut [Self],
        work: &mut dyn FnMut() -> bool,
    );
}

/// The impl for one float type, its collectives the [`Comm`] methods of that type.
macro_rules! scalar {
    ($t:ty, $all_gather:ident, $shift:ident, $all_gather_while:ident) => {
        impl Scalar for $t {
            const EPSILON: f64 = <$t>::EPSILON as f64;
            #[inline]
            fn of(v: f64) -> Self {
                v as $t
            }
            #[inline]
            fn f64(self) -> f64 {
                self as f64
            }
            #[inline]
            fn magnitude(self) -> Self {
                self.abs()
            }
            fn all_gather(comm: &dyn Comm, send: &[Self], counts: &[usize], recv: &mut [Self]) {
                comm.$all_gather(send, counts, recv);
            }
            fn shift(comm: &dyn Comm, dest: usize, source: usize, send: &[Self], recv: &mut [Self]) {
                comm.$shift(dest, source, send, recv);
            }
            fn all_gather_while(
                comm: &dyn Comm,
                send: &[Self],
                counts: &[usize],
                recv: &mut [Self],
                work: &mut dyn FnMut() -> bool,
            ) {
                comm.$all_gather_while(send, counts, recv, work);
            }
        }
    };
}

scalar!(f64, all_gather_f64, shift_f64, all_gather_f64_while);
scalar!(f32, all_gather_f32, shift_f32, all_gather_f32_while);
