//! Distributed Householder QR on the row-cyclic layout, blocked in compact-WY form as ScaLAPACK's
//! PDGEQRF. The reflectors and T are those of [`crate::linalg::reflector`]; this file only
//! decides which rank computes what.
//!
//! A panel of nb columns k..k+nb is factored column by column. For column j the reflector needs
//! x0 = a_jj (on its owner) and ||x'||^2, the sum of squares below the diagonal (a sum over the
//! ranks); applying it to a panel column c needs w_c = a_jc + v'^T a'_c. Since v' = x' / (x0 - beta)
//! and beta depends only on the two scalars, the sums x'^T a'_c and the row a_j* can travel in the
//! same all-reduce as ||x'||^2: one all-reduce per column, after which every rank updates its
//! own rows of the panel.
//!
//! The trailing columns (the right-hand side among them, so that it receives Q^T b without a pass
//! of its own) are then updated at once with Q_panel^T = I - V T^T V^T: each rank forms its part
//! of V^T V and of W = V^T A_trail, one all-reduce each sums them, every rank builds the same T
//! and applies A_trail <- A_trail - V (T^T W) to its own rows with one local GEMM. That GEMM
//! carries almost all the flops (4/3 n^3 in total, twice LU's). The matrix is never gathered;
//! back substitution on R finishes the solve.

use faer::linalg::matmul::matmul;
use faer::reborrow::Reborrow;
use faer::{Accum, MatMut, MatRef, Par};

use super::backsub::back_substitute;
use super::solver::Job;
use super::system::{LocalRows, RowIndex};
use crate::error::Result;
use crate::linalg::reflector::{wy_t, Reflector};
use crate::par::Comm;

/// Solves the distributed system in `rows` (right-hand side in the last column) and returns the
/// solution on every rank. Collective. `rows` is overwritten by R, the reflectors and Q^T b.
/// `par` is the parallelism of the local trailing-update GEMMs.
pub fn householder_solve(job: &Job<'_>, rows: &mut LocalRows) -> Result<Vec<f64>> {
    let Job { comm, panel, par, progress, .. } = *job;
    let (lay, cols, nb) = (rows.layout, rows.cols, panel.max(1));
    let n = lay.n;
    let tol = rows.singular_tol(comm);
    let lc = rows.ld();
    let mut k = 0;
    while k < n {
        let kb = nb.min(n - k);
        let taus = factor_panel(comm, &lay, &mut rows.data, lc, (k, kb), k);
        let rest = cols - (k + kb);
        if rest > 0 {
            // V: this rank's rows k.. of the panel, unit lower trapezoidal, made explicit
            let r0 = lay.first_local_from(k);
            let mr = lc - r0;
            let mut v = vec![0.0; mr * kb];
            for c in 0..kb {
                for (t, l) in (r0..lc).enumerate() {
                    let g = lay.global(l);
                    v[t + c * mr] = match g.cmp(&(k + c)) {
                        std::cmp::Ordering::Less => 0.0,
                        std::cmp::Ordering::Equal => 1.0,
                        std::cmp::Ordering::Greater => rows.get(l, k + c),
                    };
                }
            }
            let vref = MatRef::from_column_major_slice(&v, mr, kb);
            // T from V^T V (dlarft, forward, column-wise)
            let mut vtv = vec![0.0; kb * kb];
            matmul(
                MatMut::from_column_major_slice_mut(&mut vtv, kb, kb),
                Accum::Replace,
                vref.transpose(),
                vref,
                1.0,
                Par::Seq,
            );
            comm.sum_f64(&mut vtv);
            let t = wy_t(&taus, MatRef::from_column_major_slice(&vtv, kb, kb));
            // W = V^T A_trail, summed over ranks; then W <- T^T W and A_trail -= V W
            let mut wbuf = vec![0.0; kb * rest];
            {
                let a_trail = rows.view().submatrix(r0, k + kb, mr, rest);
                matmul(
                    MatMut::from_column_major_slice_mut(&mut wbuf, kb, rest),
                    Accum::Replace,
                    vref.transpose(),
                    a_trail,
                    1.0,
                    par,
                );
            }
            comm.sum_f64(&mut wbuf);
            let mut tw = vec![0.0; kb * rest];
            matmul(
                MatMut::from_column_major_slice_mut(&mut tw, kb, rest),
                Accum::Replace,
                t.as_ref().transpose(),
                MatRef::from_column_major_slice(&wbuf, kb, rest),
                1.0,
                par,
            );
            let a_trail = rows.view_mut().submatrix_mut(r0, k + kb, mr, rest);
            matmul(a_trail, Accum::Add, vref.rb(), MatRef::from_column_major_slice(&tw, kb, rest), -1.0, par);
        }
        k += kb;
        progress(k, n);
    }
    back_substitute(comm, rows, nb, tol)
}

/// Unblocked Householder QR of the panel columns k..k+kb (rows k..n) of a column-major local
/// matrix (leading dimension `ld`, the local row count) whose rows are spread over `comm` as
/// `rows` says, global column k at local column `lc0`: the row-cyclic layout over all ranks, or
/// one process column of the 2D layout. Returns the tau of each reflector H = I - tau v v^T
/// (v(0) = 1, its tail stored below the diagonal; R on and above it).
pub(super) fn factor_panel(
    comm: &dyn Comm,
    rows: &dyn RowIndex,
    data: &mut [f64],
    ld: usize,
    (k, kb): (usize, usize),
    lc0: usize,
) -> Vec<f64> {
    let me = comm.rank();
    let mut taus = vec![0.0; kb];
    // one all-reduce per column: [sum of squares below the diagonal, x0, x^T A (unscaled, below),
    // row j of A], all over the panel columns right of j; w = A_j + x^T A / (x0 - alpha) follows
    let mut s = vec![0.0; 2 + 2 * kb];
    for j in k..k + kb {
        let jl = lc0 + j - k;
        let l0 = rows.first_local_from(j + 1);
        let owns_j = rows.owner(j) == me;
        let lj = rows.local(j);
        let width = k + kb - j - 1;
        let s = &mut s[..2 + 2 * width];
        s.fill(0.0);
        {
            let x = &data[jl * ld + l0..jl * ld + ld];
            s[0] = x.iter().map(|v| v * v).sum::<f64>();
            if owns_j {
                s[1] = data[lj + jl * ld];
            }
            for t in 0..width {
                let col = &data[(jl + 1 + t) * ld..(jl + 2 + t) * ld];
                s[2 + t] = col[l0..].iter().zip(x).map(|(a, b)| a * b).sum::<f64>();
                if owns_j {
                    s[2 + width + t] = col[lj];
                }
            }
        }
        comm.sum_f64(s);
        let Reflector { tau, beta, scale } = Reflector::new(s[1], s[0]);
        if tau == 0.0 {
            // already triangular in this column: H = I
            continue;
        }
        taus[j - k] = tau;
        if ld == 0 {
            // no rows here
            continue;
        }
        let (left, right) = data.split_at_mut((jl + 1) * ld);
        let v = &mut left[jl * ld + l0..jl * ld + ld];
        v.iter_mut().for_each(|x| *x *= scale);
        if owns_j {
            left[lj + jl * ld] = beta;
        }
        let v = &left[jl * ld + l0..jl * ld + ld];
        // apply H_j = I - tau v v^T (v(j) = 1) to the panel columns right of j
        for (t, col) in right.chunks_exact_mut(ld).take(width).enumerate() {
            let tw = tau * (s[2 + width + t] + scale * s[2 + t]);
            if owns_j {
                col[lj] -= tw;
            }
            for (a, vl) in col[l0..].iter_mut().zip(v) {
                *a -= vl * tw;
            }
        }
    }
    taus
}
