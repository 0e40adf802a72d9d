//! The working precisions of the distributed factorisations: f64 for every solver, f32 for the
//! factorisation of a mixed-precision solve (see `mixed`). The trait adds to faer's `RealField`
//! what the row-cyclic code needs: conversions to and from f64 and the collectives that move
//! values of the type between ranks.

use faer::traits::RealField;

use crate::linalg::gemm::Gemm;
use crate::par::Comm;
use crate::simd::on_widest_unit;

/// A real type a row-cyclic matrix may hold: f32 or f64.
pub trait Scalar: RealField + Gemm + Copy + Send + Sync + std::ops::Neg<Output = Self> {
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

on_widest_unit! {
    /// The products of W columns with x, the columns widened to f64, reading x once for all of
    /// them and keeping eight running sums per column: one running sum waits for each addition
    /// before the next, and one column at a time reads x again for each (a backward substitution
    /// over all of L, a product per column, took twice as long as one pass over L from memory).
    fn dots_widened[const W: usize, T: Scalar][W, T](cols: [&[T]; W], x: &[f64]) -> [f64; W]
        = dots_portable;
}

#[inline(always)]
fn dots_portable<const W: usize, T: Scalar>(cols: [&[T]; W], x: &[f64]) -> [f64; W] {
    let n = x.len();
    let full = n / 8 * 8;
    let mut acc = [[0.0f64; 8]; W];
    for i in (0..full).step_by(8) {
        let xs = &x[i..i + 8];
        for (a, c) in acc.iter_mut().zip(&cols) {
            let cs = &c[i..i + 8];
            for t in 0..8 {
                a[t] += cs[t].f64() * xs[t];
            }
        }
    }
    let mut out = [0.0; W];
    for ((o, a), c) in out.iter_mut().zip(&acc).zip(&cols) {
        *o = a.iter().sum::<f64>() + (full..n).map(|i| c[i].f64() * x[i]).sum::<f64>();
    }
    out
}

on_widest_unit! {
    /// y += sum_w a_w cols_w with the columns widened to f64: W columns per pass over y.
    fn axpy_widened[const W: usize, T: Scalar][W, T](y: &mut [f64], cols: [&[T]; W], a: [f64; W])
        = axpy_portable;
}

#[inline(always)]
fn axpy_portable<const W: usize, T: Scalar>(y: &mut [f64], cols: [&[T]; W], a: [f64; W]) {
    for (i, v) in y.iter_mut().enumerate() {
        let mut s = 0.0;
        for w in 0..W {
            s += cols[w][i].f64() * a[w];
        }
        *v += s;
    }
}

/// Columns per pass of [`products_widened`] and [`update_widened`] (eight took 0.029 s per solve
/// with the f32 factors of an 8000-point system, four 0.020 s, two 0.028 s).
const PER_PASS: usize = 4;

/// The products col(c) . x for the columns c0..c1, widened to f64, [`PER_PASS`] columns per
/// pass over x.
pub(super) fn products_widened<'a, T: Scalar + 'a>(
    (c0, c1): (usize, usize),
    x: &[f64],
    col: impl Fn(usize) -> &'a [T],
) -> Vec<f64> {
    let mut out = Vec::with_capacity(c1 - c0);
    let mut c = c0;
    while c < c1 {
        if c + PER_PASS <= c1 {
            out.extend(dots_widened(std::array::from_fn::<_, PER_PASS, _>(|t| col(c + t)), x));
            c += PER_PASS;
        } else {
            out.extend(dots_widened([col(c)], x));
            c += 1;
        }
    }
    out
}

/// y -= sum_j v_j col(c0 + j) over the columns c0..c1, widened to f64, [`PER_PASS`] columns per
/// pass over y.
pub(super) fn update_widened<'a, T: Scalar + 'a>(
    y: &mut [f64],
    (c0, c1): (usize, usize),
    v: &[f64],
    col: impl Fn(usize) -> &'a [T],
) {
    let mut c = c0;
    while c < c1 {
        let j = c - c0;
        if c + PER_PASS <= c1 {
            let cols = std::array::from_fn::<_, PER_PASS, _>(|t| col(c + t));
            axpy_widened(y, cols, std::array::from_fn(|t| -v[j + t]));
            c += PER_PASS;
        } else {
            axpy_widened(y, [col(c)], [-v[j]]);
            c += 1;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn products_and_updates_over_column_blocks_match_the_plain_sums() {
        // 7 columns (one pass of four and three single ones) of 21 rows (two groups of eight
        // sums and a tail), f32 entries that are not small integers
        let (rows, cols) = (21, 7);
        let m: Vec<f32> = (0..rows * cols).map(|i| ((i * 37 % 101) as f32 - 50.0) / 7.0).collect();
        let col = |c: usize| &m[c * rows..(c + 1) * rows];
        let x: Vec<f64> = (0..rows).map(|i| (i as f64 * 0.7).sin()).collect();
        let v: Vec<f64> = (0..cols).map(|j| (j as f64 + 0.5).cos()).collect();
        let got = products_widened((1, cols), &x, col);
        for (c, g) in (1..cols).zip(&got) {
            let want: f64 = col(c).iter().zip(&x).map(|(a, b)| *a as f64 * b).sum();
            assert!((g - want).abs() < 1e-12 * (1.0 + want.abs()), "column {c}: {g} against {want}");
        }
        let mut y = x.clone();
        update_widened(&mut y, (1, cols), &v[1..], col);
        for (i, yi) in y.iter().enumerate() {
            let want = x[i] - (1..cols).map(|c| col(c)[i] as f64 * v[c]).sum::<f64>();
            assert!((yi - want).abs() < 1e-12 * (1.0 + want.abs()), "row {i}: {yi} against {want}");
        }
    }
}
