//! Distributed LU with partial pivoting on the row-cyclic layout, blocked and right-looking.
//!
//! Gaussian elimination with partial pivoting computes P M = L U: at step j the row p >= j with
//! the largest |a_pj| is swapped into row j, the multipliers l_ij = a_ij / a_jj (|l_ij| <= 1, which
//! bounds the growth of the entries in practice) are stored in place of the eliminated entries, and
//! a_ic <- a_ic - l_ij a_jc for i, c > j. The right-hand side is the last column, so it undergoes
//! the same swaps and updates and ends as L^-1 P b; back substitution U x = L^-1 P b ends the
//! solve (2/3 n^3 flops, half of Householder's).
//!
//! Blocked by panels of nb columns, with M partitioned at the panel as [A11 A12; A21 A22]: the
//! panel [A11; A21] is factored into L11 U11 and L21 (recursively halved, so that its own updates
//! are small GEMMs too), its row swaps are applied to the columns right of it, then
//!
//! ```text
//!     U12 = L11^-1 A12,       A22 <- A22 - L21 U12.
//! ```
//!
//! On the ranks: the pivot search of column j is one all-gather of each rank's best candidate,
//! which carries its row's panel part along, so the pivot row is known everywhere without a
//! broadcast; a swap is a message between the two owners. Per panel, the block row [A11 A12] is
//! all-gathered, every rank solves for U12 redundantly (cheap: nb rows) and updates its own rows
//! of A22 with one local GEMM, which carries almost all the flops. The matrix is never gathered.

use faer::linalg::matmul::matmul;
use faer::linalg::triangular_solve::solve_unit_lower_triangular_in_place;
use faer::reborrow::Reborrow;
use faer::{Accum, MatMut, MatRef, Par};

use super::backsub::back_substitute;
use super::scalar::Scalar;
use super::solver::Job;
use super::system::{GatherBuffers, LocalRows};
use crate::error::{Error, Result};
use crate::par::Comm;

/// Solves the distributed system in `rows` (right-hand side in the last column) and returns the
/// solution on every rank. Collective. `rows` is overwritten by U (and the multipliers of L, not
/// row-interchanged) and L^-1 P b. `par` is the parallelism of the local trailing-update GEMMs.
pub fn lu_solve(job: &Job<'_>, rows: &mut LocalRows) -> Result<Vec<f64>> {
    let tol = rows.singular_tol(job.comm);
    lu_factor(job, rows)?;
    back_substitute(job.comm, rows, job.panel.max(1), tol)
}

/// Factors the distributed matrix in `rows` in its own precision (the right-hand side column is
/// carried along and ends as L^-1 P b) and returns the row interchanges (j, p), in the order
/// applied: panel by panel, j ascending. Collective. Column j of L is left where the
/// interchanges of its own panel put it: the later panels' interchanges reach only the columns
/// right of their panel.
pub fn lu_factor<T: Scalar>(job: &Job<'_>, rows: &mut LocalRows<T>) -> Result<Vec<(usize, usize)>> {
    let Job { comm, panel, par, progress } = *job;
    let (lay, cols, nb) = (rows.layout, rows.cols, panel.max(1));
    let n = lay.n;
    let tol = rows.singular_tol(comm);
    let mut bufs = GatherBuffers::default();
    let mut all_swaps = Vec::with_capacity(n);
    let mut k = 0;
    while k < n {
        let kb = nb.min(n - k);
        // the panel's interchanges are applied to the panel at once and to the columns right of
        // it afterwards, in one pass; columns left of it hold L, which nothing reads again
        let mut swaps = Vec::with_capacity(kb);
        factor_panel(comm, rows, k, k + kb, (k, k + kb), tol, &mut swaps, &mut bufs)?;
        rows.permute_rows(comm, &swaps, k + kb, cols);
        eliminate_block(comm, rows, k, k + kb, cols, par, &mut bufs);
        all_swaps.extend_from_slice(&swaps);
        k += kb;
        progress(k, n);
    }
    Ok(all_swaps)
}

/// Columns at most this wide are factored column by column; wider ones recursively.
const LEAF: usize = 8;

/// LU of the panel columns a..b (rows a..n), recursively: the left half, its block elimination
/// on the right half (a GEMM), then the right half. Swaps whole rows.
#[allow(clippy::too_many_arguments)]
fn factor_panel<T: Scalar>(
    comm: &dyn Comm,
    rows: &mut LocalRows<T>,
    a: usize,
    b: usize,
    panel: (usize, usize),
    tol: f64,
    swaps: &mut Vec<(usize, usize)>,
    bufs: &mut GatherBuffers<T>,
) -> Result<()> {
    if b - a <= LEAF {
        return factor_columns(comm, rows, a, b - a, panel, tol, swaps);
    }
    let m = a + (b - a) / 2;
    factor_panel(comm, rows, a, m, panel, tol, swaps, bufs)?;
    eliminate_block(comm, rows, a, m, b, Par::Seq, bufs);
    factor_panel(comm, rows, m, b, panel, tol, swaps, bufs)
}

/// Given the factored columns a..m (L11\U11 in rows a..m, L21 below), computes
/// U12 = L11^-1 A12 for columns m..c1 from the gathered block row (redundantly on every rank),
/// stores it in the owners' rows and updates this rank's rows below: A22 -= L21 U12.
fn eliminate_block<T: Scalar>(
    comm: &dyn Comm,
    rows: &mut LocalRows<T>,
    a: usize,
    m: usize,
    c1: usize,
    par: Par,
    bufs: &mut GatherBuffers<T>,
) {
    let lay = rows.layout;
    let (w, rest) = (m - a, c1 - m);
    if rest == 0 {
        return;
    }
    rows.gather_rows_with(comm, a, m, a, c1, bufs);
    let brow = &bufs.out;
    let width = c1 - a;
    let l11 = faer::Mat::<T>::from_fn(w, w, |i, j| brow[i * width + j]);
    let mut u12 = faer::Mat::<T>::from_fn(w, rest, |i, j| brow[i * width + w + j]);
    solve_unit_lower_triangular_in_place(l11.as_ref(), u12.as_mut(), Par::Seq);
    let (o0, o1) = (lay.first_local_from(a), lay.first_local_from(m));
    for j in 0..rest {
        for l in o0..o1 {
            rows.set(l, m + j, u12[(lay.global(l) - a, j)]);
        }
    }
    let t0 = lay.first_local_from(m);
    let lc = rows.ld();
    if t0 < lc {
        let sub = rows.view_mut().submatrix_mut(t0, a, lc - t0, width);
        let (left, right) = sub.split_at_col_mut(w);
        let l21: MatRef<'_, T> = left.rb();
        let a22: MatMut<'_, T> = right;
        matmul(a22, Accum::Add, l21, u12.as_ref(), T::of(-1.0), par);
    }
}

/// Unblocked LU of the columns k..k+kb (rows k..n); row interchanges are applied to the panel
/// columns `panel.0..panel.1` and recorded in `swaps`.
fn factor_columns<T: Scalar>(
    comm: &dyn Comm,
    rows: &mut LocalRows<T>,
    k: usize,
    kb: usize,
    panel: (usize, usize),
    tol: f64,
    swaps: &mut Vec<(usize, usize)>,
) -> Result<()> {
    let lay = rows.layout;
    let lc = rows.ld();
    let ranks = lay.ranks;
    // each candidate travels with its row's leaf part (columns j..k+kb), so that the pivot row
    // is known everywhere after one all-gather per column, without a broadcast
    let stride = 2 + kb;
    // (the global row index travels in T too: exact in f32 up to 2^24 rows)
    let zero = T::of(0.0);
    let mut mine = vec![zero; stride];
    let mut cand = vec![zero; stride * ranks];
    let counts = vec![stride; ranks];
    let mut pivot_row = vec![zero; kb];
    let tol_t = T::of(tol);
    for j in k..k + kb {
        let width = k + kb - j;
        // this rank's candidate: largest |a| in column j at or below row j (lowest row on ties)
        let mut best = (T::of(-1.0), usize::MAX);
        for l in lay.first_local_from(j)..lc {
            let v = rows.get(l, j).magnitude();
            if v > best.0 {
                best = (v, l);
            }
        }
        mine.iter_mut().for_each(|v| *v = zero);
        mine[0] = best.0;
        mine[1] = T::of(if best.1 == usize::MAX { f64::INFINITY } else { lay.global(best.1) as f64 });
        if best.1 != usize::MAX {
            rows.read_row(best.1, j, k + kb, &mut mine[2..2 + width]);
        }
        T::all_gather(comm, &mine, &counts, &mut cand);
        let mut piv = (T::of(-1.0), T::of(f64::INFINITY), 0usize);
        for (r, c) in cand.chunks(stride).enumerate() {
            if c[0] > piv.0 || (c[0] == piv.0 && c[1] < piv.1) {
                piv = (c[0], c[1], r);
            }
        }
        if !(piv.0 > tol_t) {
            return Err(Error::Numerical(format!(
                "the system is singular to working precision: no pivot above {tol:.3e} in column {j} of {}",
                lay.n
            )));
        }
        let from = piv.2 * stride + 2;
        pivot_row[..width].copy_from_slice(&cand[from..from + width]);
        let prow = piv.1.f64() as usize;
        rows.swap_rows(comm, j, prow, panel.0, panel.1);
        swaps.push((j, prow));
        let d = pivot_row[0];
        let l0 = lay.first_local_from(j + 1);
        let ld = lc;
        // column j below the pivot becomes L; the panel columns right of it get the rank-1 update
        let (left, right) = rows.data.split_at_mut((j + 1) * ld);
        let lcol = &mut left[j * ld + l0..j * ld + lc];
        let inv = T::of(1.0) / d;
        lcol.iter_mut().for_each(|v| *v *= inv);
        for (t, col) in right.chunks_exact_mut(ld).take(k + kb - j - 1).enumerate() {
            let u = pivot_row[t + 1];
            if u != zero {
                for (a, l) in col[l0..lc].iter_mut().zip(lcol.iter()) {
                    *a -= *l * u;
                }
            }
        }
    }
    Ok(())
}
