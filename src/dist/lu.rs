//! Distributed LU with partial pivoting on the row-cyclic layout: blocked, right-looking
//! (math.md, section 2). Per panel column: an all-gather of each rank's pivot candidate, one row
//! swap between two owners, a broadcast of the pivot row's panel part. Per panel: an all-gather of
//! the block row, a redundant triangular solve for U12 and one local GEMM A22 -= L21 U12 on every
//! rank. The matrix is never gathered.

use faer::linalg::matmul::matmul;
use faer::linalg::triangular_solve::solve_unit_lower_triangular_in_place;
use faer::reborrow::Reborrow;
use faer::{Accum, MatMut, MatRef, Par};

use super::backsub::back_substitute;
use super::comm::Comm;
use super::system::LocalRows;
use crate::error::{Error, Result};
use crate::report::Progress;

/// Solves the distributed system in `rows` (right-hand side in the last column) and returns the
/// solution on every rank. Collective. `rows` is overwritten by L\U and L^-1 P b.
pub fn lu_solve(
    comm: &dyn Comm,
    rows: &mut LocalRows,
    panel: usize,
    progress: &Progress,
) -> Result<Vec<f64>> {
    let lay = rows.layout;
    let n = lay.n;
    let cols = rows.cols;
    let nb = panel.max(1);
    let tol = rows.max_abs(comm) * f64::EPSILON * n as f64;
    let par = Par::rayon(0);
    let mut k = 0;
    while k < n {
        let kb = nb.min(n - k);
        factor_panel(comm, rows, k, kb, tol)?;
        // the block row k..k+kb, columns k.. on every rank: [L11\U11 | A12 | y]
        let w = cols - k;
        let brow = rows.gather_rows(comm, k, k + kb, k, cols);
        let rest = cols - (k + kb);
        if rest > 0 {
            // U12 = L11^-1 A12, computed redundantly; column-major copies for faer
            let l11 = faer::Mat::<f64>::from_fn(kb, kb, |i, j| brow[i * w + j]);
            let mut u12 = faer::Mat::<f64>::from_fn(kb, rest, |i, j| brow[i * w + kb + j]);
            solve_unit_lower_triangular_in_place(l11.as_ref(), u12.as_mut(), Par::Seq);
            // owners of the block row keep U12
            let (l0, l1) = (lay.first_local_from(k), lay.first_local_from(k + kb));
            for l in l0..l1 {
                let i = lay.global(l) - k;
                for j in 0..rest {
                    rows.set(l, k + kb + j, u12[(i, j)]);
                }
            }
            // trailing update of this rank's rows below the block row
            let t0 = lay.first_local_from(k + kb);
            let lc = rows.ld();
            if t0 < lc {
                let m = rows.view_mut().submatrix_mut(t0, 0, lc - t0, cols);
                let (left, right) = m.split_at_col_mut(k + kb);
                let l21: MatRef<'_, f64> = left.rb().subcols(k, kb);
                let a22: MatMut<'_, f64> = right;
                matmul(a22, Accum::Add, l21, u12.as_ref(), -1.0, par);
            }
        }
        k += kb;
        progress.update(k, n);
    }
    back_substitute(comm, rows, nb, tol)
}

/// Unblocked LU of the panel columns k..k+kb (rows k..n), swapping whole rows.
fn factor_panel(comm: &dyn Comm, rows: &mut LocalRows, k: usize, kb: usize, tol: f64) -> Result<()> {
    let lay = rows.layout;
    let lc = rows.ld();
    let ranks = lay.ranks;
    let mut cand = vec![0.0; 2 * ranks];
    let counts = vec![2usize; ranks];
    let mut pivot_row = vec![0.0; kb];
    for j in k..k + kb {
        // this rank's candidate: largest |a| in column j at or below row j (lowest row on ties)
        let mut best = (-1.0f64, f64::INFINITY);
        for l in lay.first_local_from(j)..lc {
            let v = rows.get(l, j).abs();
            if v > best.0 {
                best = (v, lay.global(l) as f64);
            }
        }
        comm.all_gather_f64(&[best.0, best.1], &counts, &mut cand);
        let mut piv = (-1.0f64, f64::INFINITY);
        for c in cand.chunks(2) {
            if c[0] > piv.0 || (c[0] == piv.0 && c[1] < piv.1) {
                piv = (c[0], c[1]);
            }
        }
        if !(piv.0 > tol) {
            return Err(Error::Numerical(format!(
                "the system is singular to working precision: no pivot above {tol:.3e} in column {j} of {}",
                lay.n
            )));
        }
        rows.swap_rows(comm, j, piv.1 as usize);
        // pivot row's panel part (columns j..k+kb) to every rank
        let width = k + kb - j;
        let owner = lay.owner(j);
        if owner == lay.rank {
            rows.read_row(lay.local(j), j, k + kb, &mut pivot_row[..width]);
        }
        comm.broadcast_f64(owner, &mut pivot_row[..width]);
        let d = pivot_row[0];
        let l0 = lay.first_local_from(j + 1);
        let ld = lc;
        for l in l0..lc {
            rows.data[l + j * ld] /= d;
        }
        for (t, c) in (j + 1..k + kb).enumerate() {
            let u = pivot_row[t + 1];
            if u != 0.0 {
                for l in l0..lc {
                    rows.data[l + c * ld] -= rows.data[l + j * ld] * u;
                }
            }
        }
    }
    Ok(())
}
