//! Distributed LU with partial pivoting on the 2D block-cyclic layout (see `grid`), right-looking
//! in panels of one block column, as ScaLAPACK's PDGETRF organises it.
//!
//! The elimination is the one of the row-cyclic LU (`lu`): P M = L U with the largest |a_pj| of
//! column j swapped into row j, the right-hand side carried along as global column n, then
//! U x = L^-1 P b. What changes is who does what. At the panel of columns k..k+kb (one block
//! column, owned by process column pk):
//!
//! 1. The pr ranks of process column pk factor the panel (rows k..n): per column j one all-gather
//!    over the process column of each rank's best candidate, carrying its row's panel part along,
//!    so the pivot row is known there without a broadcast; the interchange of rows j and p within
//!    the panel is a message between the two process rows that own them; then the column is
//!    scaled and the rest of the panel gets the rank-1 update. A pivot not above n eps max|a_ij|
//!    stops the panel on all of them at the same column (they hold the same candidates).
//! 2. Each of them broadcasts along its process row the pivots and its rows of the factored panel
//!    (L11 and L21), with a status word: a singular panel ends the factorisation on every rank.
//! 3. Every rank applies the kb interchanges to its columns right of the panel (the columns left
//!    of it hold L, which the solve does not read again), over its process column: one message per
//!    pair of process rows.
//! 4. The process row pr_k owning rows k..k+kb (one block row) computes U12 = L11^-1 A12 for its
//!    columns and broadcasts it down each process column.
//! 5. Every rank updates its part of A22 -= L21 U12 with one local GEMM: its rows of L21 came in
//!    step 2, its columns of U12 in step 4.
//!
//! The back substitution walks the block rows from the last: the process row owning block i sums
//! U_ij x_j over its columns right of the block and the right-hand side over its process row (one
//! all-reduce of nb values), the owner of the diagonal block solves the triangle and broadcasts x_i
//! to every rank; the solution ends on every rank.

use crate::linalg::gemm::{gemm, solve_lower};
use faer::{Accum, MatMut, MatRef};

use super::grid::{update_and_next_panel, LocalBlocks, ProcessGrid};
use super::solver::Job;
use super::system::permute_local_rows;
use crate::error::{Error, Result};
use crate::par::Comm;

/// Solves the system in `a` (right-hand side as global column n) on `grid` and returns the
/// solution on every rank. Collective over the grid; every rank returns the same outcome. `a` is
/// overwritten by the factors. The panel width is the block size of `a`; `job.par` goes to the
/// local GEMMs, `job.progress` gets the columns factored.
pub fn lu2d_solve(job: &Job<'_>, grid: &ProcessGrid<'_>, a: &mut LocalBlocks) -> Result<Vec<f64>> {
    let tol = a.max_abs(grid.comm) * f64::EPSILON * a.n() as f64;
    lu2d_factor(job, grid, a, tol)?;
    back_substitute(grid, a, tol)
}

/// Factors `a` in place: U and the multipliers of L in the matrix columns, L^-1 P b in the
/// right-hand side column. Collective over the grid. With `job.lookahead` the next panel is
/// factored first and broadcast while the trailing update runs (see the module documentation);
/// the factors are the same.
pub fn lu2d_factor(job: &Job<'_>, grid: &ProcessGrid<'_>, a: &mut LocalBlocks, tol: f64) -> Result<()> {
    let n = a.n();
    if n == 0 {
        return Ok(());
    }
    let mut panel = factor_and_pack(grid, a, 0, tol);
    grid.row.broadcast_f64(a.cols.owner(0), &mut panel);
    let mut k = 0;
    loop {
        let (rows, cols, ld) = (a.rows, a.cols, a.ld());
        let kb = a.rows.nb.min(n - k);
        let end = k + kb;
        if panel[0] != 0.0 {
            let j = panel[0] as usize - 1;
            return Err(Error::Numerical(format!(
                "the system is singular to working precision: no pivot above {tol:.3e} in column {j} of {n}"
            )));
        }
        let swaps: Vec<(usize, usize)> = (k..end).zip(panel[1..1 + kb].iter().map(|&p| p as usize)).collect();
        let lr0 = rows.first_local_from(k);
        let m = ld - lr0;
        // the columns right of the panel: interchanges, U12, the trailing update
        let (lc1, ncl) = (cols.first_local_from(end), cols.local_count());
        permute_local_rows(grid.col.as_ref(), &rows, &swaps, &mut a.data, ld, lc1..ncl);
        let u12 = block_row_of_u(grid, a, k, kb, &panel[1 + kb..]);
        let update =
            Update { l: &panel[1 + kb..], m, lr0, kb, u12: &u12, lc1, first: rows.first_local_from(end) };
        if end == n {
            update.apply(a, lc1, ncl, job);
            (job.progress)(end, n);
            return Ok(());
        }
        let (pk1, kb1) = (cols.owner(end), a.rows.nb.min(n - end));
        let len = 1 + kb1 + (ld - rows.first_local_from(end)) * kb1;
        let next = update_and_next_panel(
            grid,
            a,
            job.lookahead,
            lc1..ncl,
            (pk1, kb1),
            len,
            &|a, c0, c1| update.apply(a, c0, c1, job),
            &|a| factor_and_pack(grid, a, end, tol),
        );
        (job.progress)(end, n);
        panel = next;
        k = end;
    }
}

/// On the process column owning the panel at column k: factors it and packs the status (0, or
/// the failing column + 1), the pivot rows and this process row's part of the factored panel
/// (rows k.., column-major); elsewhere a buffer of the same length. Collective over the process
/// column.
fn factor_and_pack(grid: &ProcessGrid<'_>, a: &mut LocalBlocks, k: usize, tol: f64) -> Vec<f64> {
    let (rows, cols, ld) = (a.rows, a.cols, a.ld());
    let kb = rows.nb.min(a.n() - k);
    let lr0 = rows.first_local_from(k);
    let m = ld - lr0;
    let mut panel = vec![0.0; 1 + kb + m * kb];
    if grid.mycol != cols.owner(k) {
        return panel;
    }
    let lc0 = cols.local(k);
    match factor_panel(grid.col.as_ref(), a, k, kb, lc0, tol) {
        Ok(pivots) => {
            for (v, p) in panel[1..1 + kb].iter_mut().zip(pivots) {
                *v = p as f64;
            }
        }
        Err(j) => panel[0] = (j + 1) as f64,
    }
    for c in 0..kb {
        let src = &a.data[lr0 + (lc0 + c) * ld..ld + (lc0 + c) * ld];
        panel[1 + kb + c * m..1 + kb + (c + 1) * m].copy_from_slice(src);
    }
    panel
}

/// U12 = L11^-1 A12 for this rank's columns right of the panel at k (l: this process row's rows
/// k.. of the factored panel), computed on the process row owning rows k..k+kb, stored there and
/// broadcast down every process column; returned kb x (columns), column-major. Collective over
/// the process column.
fn block_row_of_u(grid: &ProcessGrid<'_>, a: &mut LocalBlocks, k: usize, kb: usize, l: &[f64]) -> Vec<f64> {
    let (rows, cols, ld) = (a.rows, a.cols, a.ld());
    let lc1 = cols.first_local_from(k + kb);
    let w = cols.local_count() - lc1;
    let pr_k = rows.owner(k);
    let mut u12 = vec![0.0; kb * w];
    if grid.myrow == pr_k && w > 0 {
        let (lk, lr0) = (rows.local(k), rows.first_local_from(k));
        let l = MatRef::from_column_major_slice(l, ld - lr0, kb);
        let l11 = l.subrows(lk - lr0, kb);
        let mut a12 =
            MatMut::from_column_major_slice_with_stride_mut(&mut a.data[lk + lc1 * ld..], kb, w, ld);
        solve_lower(l11, true, a12.as_mut(), faer::Par::Seq);
        for c in 0..w {
            u12[c * kb..(c + 1) * kb].copy_from_slice(&a.data[lk + (lc1 + c) * ld..lk + kb + (lc1 + c) * ld]);
        }
    }
    grid.col.broadcast_f64(pr_k, &mut u12);
    u12
}

/// The trailing update A22 -= L21 U12 of one step, applied by ranges of local columns.
struct Update<'p> {
    /// This process row's rows k.. of the factored panel (m x kb, column-major).
    l: &'p [f64],
    m: usize,
    /// The first local row at or below k, and at or below k + kb.
    lr0: usize,
    first: usize,
    kb: usize,
    /// U12 for the local columns lc1.. (kb x columns, column-major).
    u12: &'p [f64],
    lc1: usize,
}

impl Update<'_> {
    /// The update of the local columns c0..c1 (one GEMM).
    fn apply(&self, a: &mut LocalBlocks, c0: usize, c1: usize, job: &Job<'_>) {
        let ld = a.ld();
        if c0 >= c1 || self.first >= ld {
            return;
        }
        let l = MatRef::from_column_major_slice(self.l, self.m, self.kb);
        let l21 = l.subrows(self.first - self.lr0, ld - self.first);
        let w = self.u12.len() / self.kb;
        let u = MatRef::from_column_major_slice(self.u12, self.kb, w).subcols(c0 - self.lc1, c1 - c0);
        let a22 = MatMut::from_column_major_slice_with_stride_mut(
            &mut a.data[self.first + c0 * ld..],
            ld - self.first,
            c1 - c0,
            ld,
        );
        gemm(a22, Accum::Add, l21, u, -1.0, job.par);
    }
}

/// LU of the panel columns k..k+kb (local columns lc0.., rows k..n) on the ranks of one process
/// column (`col`, ranked by process row), recursively halved as in the row-cyclic LU, so that
/// most of its flops are GEMMs too. Returns the pivot row of each column, or the first column
/// without a pivot above `tol` (every rank of `col` stops at the same one).
fn factor_panel(
    col: &dyn Comm,
    a: &mut LocalBlocks,
    k: usize,
    kb: usize,
    lc0: usize,
    tol: f64,
) -> std::result::Result<Vec<usize>, usize> {
    let mut pivots = Vec::with_capacity(kb);
    factor_range(col, a, (k, kb, lc0), (k, k + kb), tol, &mut pivots)?;
    Ok(pivots)
}

/// Columns at most this wide are factored column by column; wider ones recursively.
const LEAF: usize = 8;

/// The columns c0..c1 of the panel `(k, kb, lc0)`: the left half, its block elimination on the
/// right half, the right half. The rows c0..c1 lie in one block, so on one process row: it solves
/// for the block of U and broadcasts it down the process column, every rank updates its rows.
fn factor_range(
    col: &dyn Comm,
    a: &mut LocalBlocks,
    panel: (usize, usize, usize),
    (c0, c1): (usize, usize),
    tol: f64,
    pivots: &mut Vec<usize>,
) -> std::result::Result<(), usize> {
    if c1 - c0 <= LEAF {
        return factor_columns(col, a, panel, (c0, c1), tol, pivots);
    }
    let mid = c0 + (c1 - c0) / 2;
    factor_range(col, a, panel, (c0, mid), tol, pivots)?;
    let (k, _, lc0) = panel;
    let (rows, ld) = (a.rows, a.ld());
    let lcol = |g: usize| lc0 + g - k;
    let (h, w) = (mid - c0, c1 - mid);
    let owner = rows.owner(c0);
    let mut u = vec![0.0; h * w];
    if col.rank() == owner {
        let l = rows.local(c0);
        let (left, right) = a.data.split_at_mut(lcol(mid) * ld);
        let l11 = MatRef::from_column_major_slice_with_stride(&left[l + lcol(c0) * ld..], h, h, ld);
        let mut a12 = MatMut::from_column_major_slice_with_stride_mut(&mut right[l..], h, w, ld);
        solve_lower(l11, true, a12.as_mut(), faer::Par::Seq);
        for c in 0..w {
            u[c * h..(c + 1) * h].copy_from_slice(&right[l + c * ld..l + h + c * ld]);
        }
    }
    col.broadcast_f64(owner, &mut u);
    let f = rows.first_local_from(mid);
    if f < ld {
        let (left, right) = a.data.split_at_mut(lcol(mid) * ld);
        let l21 = MatRef::from_column_major_slice_with_stride(&left[f + lcol(c0) * ld..], ld - f, h, ld);
        let a22 = MatMut::from_column_major_slice_with_stride_mut(&mut right[f..], ld - f, w, ld);
        let u12 = MatRef::from_column_major_slice(&u, h, w);
        gemm(a22, Accum::Add, l21, u12, -1.0, faer::Par::Seq);
    }
    factor_range(col, a, panel, (mid, c1), tol, pivots)
}

/// Unblocked LU of the panel columns c0..c1: per column one all-gather of each rank's best
/// candidate with its row's part of the columns (so the pivot row is known on every rank of the
/// process column), the interchange over the whole panel, the scaling and the rank-1 update of
/// the columns up to c1.
fn factor_columns(
    col: &dyn Comm,
    a: &mut LocalBlocks,
    (k, kb, lc0): (usize, usize, usize),
    (c0, c1): (usize, usize),
    tol: f64,
    pivots: &mut Vec<usize>,
) -> std::result::Result<(), usize> {
    let (rows, ld) = (a.rows, a.ld());
    let ranks = col.size();
    // each candidate: |a|, its global row, its row's part of the columns from j on
    let stride = 2 + (c1 - c0);
    let mut mine = vec![0.0; stride];
    let mut cand = vec![0.0; stride * ranks];
    let counts = vec![stride; ranks];
    for j in c0..c1 {
        let (jl, width) = (lc0 + j - k, c1 - j);
        let mut best = (-1.0f64, usize::MAX);
        for l in rows.first_local_from(j)..ld {
            let v = a.data[l + jl * ld].abs();
            if v > best.0 {
                best = (v, l);
            }
        }
        mine.fill(0.0);
        mine[0] = best.0;
        mine[1] = if best.1 == usize::MAX { f64::INFINITY } else { rows.global(best.1) as f64 };
        if best.1 != usize::MAX {
            for t in 0..width {
                mine[2 + t] = a.data[best.1 + (jl + t) * ld];
            }
        }
        col.all_gather_f64(&mine, &counts, &mut cand);
        let mut piv = (-1.0f64, f64::INFINITY, 0usize);
        for (r, c) in cand.chunks(stride).enumerate() {
            if c[0] > piv.0 || (c[0] == piv.0 && c[1] < piv.1) {
                piv = (c[0], c[1], r);
            }
        }
        if !(piv.0 > tol) {
            return Err(j);
        }
        let p = piv.1 as usize;
        let pivot_row: Vec<f64> = cand[piv.2 * stride + 2..piv.2 * stride + 2 + width].to_vec();
        swap_rows(col, a, j, p, lc0..lc0 + kb);
        pivots.push(p);
        let d = pivot_row[0];
        let l0 = rows.first_local_from(j + 1);
        if l0 == ld {
            // no rows of this rank below the pivot (possibly none at all)
            continue;
        }
        let (left, right) = a.data.split_at_mut((jl + 1) * ld);
        let lcol = &mut left[jl * ld + l0..jl * ld + ld];
        let inv = 1.0 / d;
        lcol.iter_mut().for_each(|v| *v *= inv);
        for (t, c) in right.chunks_exact_mut(ld).take(width - 1).enumerate() {
            let u = pivot_row[t + 1];
            if u != 0.0 {
                for (x, l) in c[l0..ld].iter_mut().zip(lcol.iter()) {
                    *x -= *l * u;
                }
            }
        }
    }
    Ok(())
}

/// Exchanges global rows i and j in the local columns `lcols` between the process rows owning
/// them (ranks of `col`); other ranks return at once.
fn swap_rows(col: &dyn Comm, a: &mut LocalBlocks, i: usize, j: usize, lcols: std::ops::Range<usize>) {
    if i == j {
        return;
    }
    let (rows, ld) = (a.rows, a.ld());
    let (oi, oj, me) = (rows.owner(i), rows.owner(j), col.rank());
    if oi == me && oj == me {
        let (li, lj) = (rows.local(i), rows.local(j));
        for c in lcols {
            a.data.swap(li + c * ld, lj + c * ld);
        }
    } else if oi == me || oj == me {
        let (mine, partner) = if oi == me { (rows.local(i), oj) } else { (rows.local(j), oi) };
        let send: Vec<f64> = lcols.clone().map(|c| a.data[mine + c * ld]).collect();
        let mut recv = vec![0.0; send.len()];
        col.shift_f64(partner, partner, &send, &mut recv);
        for (c, v) in lcols.zip(recv) {
            a.data[mine + c * ld] = v;
        }
    }
}

/// Solves U x = y (U the upper triangle of the factored matrix, y its right-hand side column:
/// U and L^-1 P b of the LU, R and Q^T b of the QR) block row by block row from the last; x
/// ends on every rank. A diagonal entry at most `tol` in magnitude is a singular matrix, on every
/// rank alike. Collective over the grid.
pub(super) fn back_substitute(grid: &ProcessGrid<'_>, a: &LocalBlocks, tol: f64) -> Result<Vec<f64>> {
    let (n, nb, ld) = (a.n(), a.rows.nb, a.ld());
    let (rows, cols) = (a.rows, a.cols);
    let rhs_owner = cols.owner(n);
    let mut x = vec![0.0; n];
    for b in (0..n.div_ceil(nb)).rev() {
        let (b0, b1) = (b * nb, ((b + 1) * nb).min(n));
        let bs = b1 - b0;
        let (ri, ci) = (rows.owner(b0), cols.owner(b0));
        // status (0, or the singular row + 1), then x of the block
        let mut out = vec![0.0; 1 + bs];
        if grid.myrow == ri {
            let lb = rows.local(b0);
            // s = U[block, b1..n] x[b1..n] - y[block], summed over the process row
            let mut s = vec![0.0; bs];
            for lc in cols.first_local_from(b1)..cols.first_local_from(n) {
                let xc = x[cols.global(lc)];
                for (st, u) in s.iter_mut().zip(&a.data[lb + lc * ld..lb + bs + lc * ld]) {
                    *st += u * xc;
                }
            }
            if grid.mycol == rhs_owner {
                let lc = cols.local(n);
                for (st, y) in s.iter_mut().zip(&a.data[lb + lc * ld..lb + bs + lc * ld]) {
                    *st -= y;
                }
            }
            grid.row.sum_f64(&mut s);
            if grid.mycol == ci {
                let lcb = cols.local(b0);
                let u = |t: usize, v: usize| a.data[lb + t + (lcb + v) * ld];
                for t in (0..bs).rev() {
                    let d = u(t, t);
                    if !(d.abs() > tol) {
                        out[0] = (b0 + t + 1) as f64;
                        break;
                    }
                    let r = -s[t] - (t + 1..bs).map(|v| u(t, v) * out[1 + v]).sum::<f64>();
                    out[1 + t] = r / d;
                }
            }
        }
        grid.comm.broadcast_f64(grid.rank_at(ri, ci), &mut out);
        if out[0] != 0.0 {
            return Err(Error::Numerical(format!(
                "the system is singular to working precision: diagonal at most {tol:.3e} at row {} of {n}",
                out[0] as usize - 1
            )));
        }
        x[b0..b1].copy_from_slice(&out[1..]);
    }
    Ok(x)
}
