//! The single-precision projected Cholesky factors of a mixed-precision solve, applied in double
//! precision to the whole bordered system.
//!
//! # Factors
//!
//! The bordered matrix M = [A P; P^T 0] (f64, row-cyclic) is reduced as in the f64 projected
//! Cholesky (`cholesky`): P = Q [R; 0] by Householder QR in f64 on every rank, Q^T A Q computed
//! in f64 by the rank-2k update, a block of columns at a time, and rounded to f32 as it is
//! written, so that the rounding to f32 is the only error of the stored projection. The f32
//! blocked Cholesky then factors s B = L L^T, B = (Q^T A Q)[k..N, k..N], in place: a third of
//! LU's flops at twice the GEMM rate and half the bytes on the wire.
//!
//! # Solve with a general right-hand side
//!
//! The refinement needs M^-1 applied to residuals [r1; r2] whose second block is not zero. With
//! lambda = Q [alpha; mu] (alpha of length k), P^T lambda = R^T alpha, so the second block row
//! gives R^T alpha = r2. The first block row, A Q [alpha; mu] + Q [R; 0] c = r1, multiplied by
//! Q^T, reads with W = Q^T A Q and y = Q^T r1
//!
//! ```text
//!     W[k.., ..k] alpha + B mu = y[k..]          =>   L L^T mu = s (y[k..] - W[k.., ..k] alpha),
//!     W[..k, ..k] alpha + W[..k, k..] mu + R c = y[..k]  =>  R c = y[..k] - W[..k, ..] [alpha; mu].
//! ```
//!
//! So: y = Q^T r1 (k reflectors on a vector), alpha by a k x k triangular solve, the right-hand
//! side of the definite system from this rank's rows of W[k.., ..k] (untouched by the
//! factorisation), forward substitution with L panel by panel (the owners' entries of the panel
//! all-gathered, the diagonal block solved redundantly, the rows below updated by their owners),
//! back substitution with L^T (per panel one sum over the ranks of the products with the rows
//! below it), lambda = Q [alpha; mu], and c from the rows 0..k of W, computed in f64 and
//! gathered once (the f32 copy leaves them out). Everything is
//! computed in f64 with the f32 entries widened as they are read, and every vector is replicated
//! on every rank, as with the f32 LU factors (`mixed`).

use faer::linalg::triangular_solve::{solve_lower_triangular_in_place, solve_upper_triangular_in_place};
use faer::{Mat, MatMut, Par};

use super::cholesky::{factor_projected, project_into, projected_top, Border};
use super::mixed::Approximate;
use super::scalar::{products_widened, update_widened, Scalar};
use super::solver::Job;
use super::system::{all_gather_rows, LocalRows};
use crate::error::Result;
use crate::par::Comm;

/// The projected Cholesky factors of a bordered system in the precision T (f32 for the
/// mixed-precision solve; f64 checks the solve with a general right-hand side exactly).
pub struct CholeskyFactors<T: Scalar = f32> {
    /// Rows k..N: W[k.., ..k] in columns 0..k and L in k..N (rows 0..k are left zero).
    rows: LocalRows<T>,
    border: Border,
    sign: f64,
    /// Panel boundaries k = p_0 < p_1 < ... < p_m = N.
    panels: Vec<usize>,
    /// Per panel, its diagonal block of L (widened; the lower triangle is read), on every rank,
    /// as the factorisation computed it.
    diag: Vec<Mat<f64>>,
    /// W[..k, ..N], row-major, in f64 (`projected_top`), on every rank.
    top: Vec<f64>,
}

impl<T: Scalar> CholeskyFactors<T> {
    /// Projects the bordered system `m` (f64, left unchanged) in f64, rounds the projection to T
    /// and factors its definite block. Collective; `Error::NotDefinite` when a pivot of the
    /// rounded block is not positive (agreed by the caller).
    pub fn new(job: &Job<'_>, m: &LocalRows) -> Result<CholeskyFactors<T>> {
        let comm = job.comm;
        let border = Border::new(comm, m)?;
        let (k, n) = (border.k, border.n);
        let (left, right) = border.projection(comm, m);
        let mut rows: LocalRows<T> = LocalRows::zeros(m.layout, m.cols, m.border);
        project_into(m, &mut rows, (&left, &right), job.par);
        let top = projected_top(comm, m, (&left, &right));
        drop((left, right));
        let mut blocks = Vec::new();
        let sign = factor_projected(job, &mut rows, k, n, Some(&mut blocks))?;
        // the panel boundaries are those of the blocks the factorisation kept
        let mut panels = vec![k];
        for l in &blocks {
            panels.push(panels[panels.len() - 1] + l.nrows());
        }
        // the diagonal blocks as the factorisation left them on every rank, widened
        let diag =
            blocks.iter().map(|l| Mat::from_fn(l.nrows(), l.ncols(), |i, j| l[(i, j)].f64())).collect();
        Ok(CholeskyFactors { rows, border, sign, panels, diag, top })
    }
}

impl<T: Scalar> Approximate for CholeskyFactors<T> {
    fn apply(&self, comm: &dyn Comm, r: &[f64]) -> Vec<f64> {
        let (k, n) = (self.border.k, self.border.n);
        let lay = self.rows.layout;
        let ld = self.rows.ld();
        let la = lay.first_local_from(n);
        let data = &self.rows.data;
        let col = |c: usize| &data[c * ld..c * ld + la];
        let rt = self.border.r();
        // y = Q^T r1, R^T alpha = r2
        let mut y = r[..n].to_vec();
        self.border.q_transpose(&mut y);
        let mut alpha = vec![0.0; k];
        for i in 0..k {
            let s: f64 = (0..i).map(|j| rt[(j, i)] * alpha[j]).sum();
            alpha[i] = (r[n + i] - s) / rt[(i, i)];
        }
        // this rank's entries of s (y - W[k.., ..k] alpha), rows k..n
        let b0 = lay.first_local_from(k);
        let mut own = vec![0.0; la];
        for (l, o) in own.iter_mut().enumerate().skip(b0) {
            let w: f64 = (0..k).map(|j| data[l + j * ld].f64() * alpha[j]).sum();
            *o = self.sign * (y[lay.global(l)] - w);
        }
        // forward: L z = own, panel by panel
        let mut z = vec![0.0; n];
        for (w, d) in self.panels.windows(2).zip(&self.diag) {
            let (k0, k1) = (w[0], w[1]);
            let (l0, l1) = (lay.first_local_from(k0), lay.first_local_from(k1));
            let mut zp = all_gather_rows(comm, lay, &own[l0..l1], k0..k1, 1);
            solve_lower_triangular_in_place(d.as_ref(), column(&mut zp), Par::Seq);
            update_widened(&mut own[l1..], (k0, k1), &zp, |c| &col(c)[l1..]);
            z[k0..k1].copy_from_slice(&zp);
        }
        // backward: L^T mu = z; [alpha; mu] in one vector, and this rank's entries of it in
        // local order as they become final (rows below the panel), for contiguous products
        let mut x = z;
        x[..k].copy_from_slice(&alpha);
        let mut mine = vec![0.0; la];
        for (w, d) in self.panels.windows(2).zip(&self.diag).rev() {
            let (k0, k1) = (w[0], w[1]);
            let (at, below) = (lay.first_local_from(k0), lay.first_local_from(k1));
            let mut sums = products_widened((k0, k1), &mine[below..], |c| &col(c)[below..]);
            comm.sum_f64(&mut sums);
            let xp = &mut x[k0..k1];
            xp.iter_mut().zip(&sums).for_each(|(v, s)| *v -= s);
            solve_upper_triangular_in_place(d.transpose(), column(xp), Par::Seq);
            for (l, v) in mine.iter_mut().enumerate().take(below).skip(at) {
                *v = x[lay.global(l)];
            }
        }
        // R c = y[..k] - W[..k, ..] [alpha; mu]
        let t: Vec<f64> =
            (0..k).map(|i| y[i] - (0..n).map(|j| self.top[i * n + j] * x[j]).sum::<f64>()).collect();
        let mut c = vec![0.0; k];
        for i in (0..k).rev() {
            let s: f64 = (i + 1..k).map(|j| rt[(i, j)] * c[j]).sum();
            c[i] = (t[i] - s) / rt[(i, i)];
        }
        // lambda = Q [alpha; mu]
        self.border.q(&mut x);
        x.extend(c);
        x
    }
}

/// `v` as a one-column matrix.
fn column(v: &mut [f64]) -> MatMut<'_, f64> {
    let n = v.len();
    MatMut::from_column_major_slice_mut(v, n, 1)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::linalg::dist::test_support::bunny_rows;
    use crate::par::Solo;

    /// The bordered system of 250 bunny vertices (every 40th) for the kernel r, whose second
    /// block of the right-hand side is made non-zero: M x for x = (sin(i))_i.
    fn bunny_system() -> (LocalRows, Vec<f64>) {
        let mut m = bunny_rows(40);
        let n = m.layout.n;
        let x: Vec<f64> = (0..n).map(|i| (i as f64).sin()).collect();
        for i in 0..n {
            let b = (0..n).map(|j| m.get(i, j) * x[j]).sum();
            m.set(i, n, b);
        }
        (m, x)
    }

    #[test]
    fn factors_invert_the_bordered_system_with_a_general_right_hand_side() {
        let (m, x) = bunny_system();
        let n = m.layout.n;
        let b: Vec<f64> = (0..n).map(|i| m.get(i, n)).collect();
        assert!(b[n - 4..].iter().all(|v| v.abs() > 1e-3), "the border rows are not zero: {:?}", &b[n - 4..]);
        let err = |z: &[f64]| z.iter().zip(&x).map(|(p, q)| (p - q).abs()).fold(0.0, f64::max);
        // panels that end inside the block and one that holds all of it
        for panel in [7, 16, 300] {
            let job = Job::on(&Solo).panel(panel);
            let exact = CholeskyFactors::<f64>::new(&job, &m).unwrap().apply(&Solo, &b);
            assert!(err(&exact) < 1e-10, "f64 factors, panel {panel}: error {:e}", err(&exact));
            // in f32 an approximate inverse, off by about kappa eps32 (1e-6 here), not exact
            let approx = CholeskyFactors::<f32>::new(&job, &m).unwrap().apply(&Solo, &b);
            assert!(
                err(&approx) < 1e-4 && err(&approx) > 1e-9,
                "f32 factors, panel {panel}: error {:e}",
                err(&approx)
            );
        }
    }
}
