//! The projected Cholesky (see `cholesky`) on the 2D block-cyclic layout (see `grid`).
//!
//! The reduction is the same: P = Q [R; 0], B = Q2^T A Q2 is definite with the kernel's sign s,
//! s B = L L^T, mu from the two triangular solves, lambda = Q [0; mu] and R c from the first k
//! rows of Q^T A Q. What the grid changes:
//!
//! - P^T is small (k x N): every rank contributes the entries it owns and one all-reduce puts the
//!   whole of it on every rank, which factors it (the same bits everywhere).
//! - The projection Q^T A Q = A - [Y V] [V^T; Y^T] needs X = A V. A is symmetric, and only its
//!   lower triangle is read: each entry on or below the diagonal adds to X at its row and,
//!   mirrored, at its column's row (as on the row-cyclic layout), and one all-reduce of the N x k
//!   result sums the parts of the whole grid. Each rank then applies the rank-2k update to its own
//!   block, GEMMs of its rows of [Y V] and its columns of [V^T; Y^T], in the entries the solve
//!   reads: the lower triangle and the first k rows. So a fit assembles those alone (half the
//!   kernel evaluations, and the pages of the upper triangle's blocks mostly never touched).
//! - B is factored in panels of the blocks (the first panel starts at row k, so it is k narrower):
//!   the owner of the diagonal block factors it and sends L11 down its process column, which
//!   solves for its rows of L21 = B21 L11^-T; those travel along the process rows (each rank gets
//!   its rows of L21), and the symmetric update B22 -= L21 L21^T needs L21 also at the rows that
//!   are this rank's columns: the rank of each process row that holds such rows gives them to its
//!   process column in one all-gather (every row index of B is some process row's, so each rank
//!   receives exactly the rows at its columns, about N/pc of them). The update runs on column
//!   chunks from the diagonal down, so only the lower triangle (and a sliver above it) is
//!   touched: half of LU's flops, as on the row-cyclic layout.
//! - The forward solve L z = y walks the panels down: the process row of the panel sums L z over
//!   its columns left of it (one all-reduce over the process row), the diagonal block's owner
//!   solves and broadcasts the piece of z; the back solve L^T mu = z walks up, summing down the
//!   panel's process column instead.
//!
//! A pivot that is not positive is reported with the panel's status word, so every rank returns
//! `Error::NotDefinite` at the same panel and the caller can fall back to LU.

use crate::linalg::gemm::{gemm, solve_lower};
use faer::reborrow::ReborrowMut;
use faer::{Accum, Mat, MatMut, MatRef};

use super::cholesky::{cholesky_small, lower_times_part, Border};
use super::grid::{update_and_next_panel, LocalBlocks, ProcessGrid};
use super::solver::Job;
use crate::error::{Error, Result};

/// Local columns updated per GEMM of the trailing update (the rows of each chunk start at its
/// first column's diagonal).
const COL_CHUNK: usize = 96;

/// Solves the bordered system in `a` (k polynomial rows and columns before the right-hand side,
/// k >= 1) by the projected Cholesky and returns the solution on every rank; or
/// `Error::NotDefinite` on every rank when a pivot of the projected block is not positive (the
/// caller falls back to LU on a fresh assembly: `a` is overwritten). Collective over the grid.
pub fn cholesky2d_solve(
    job: &Job<'_>,
    grid: &ProcessGrid<'_>,
    a: &mut LocalBlocks,
    k: usize,
) -> Result<Vec<f64>> {
    factor_and_solve(job, grid, a, k).map(|(x, _, _)| x)
}

/// [`cholesky2d_solve`], which also returns the QR of the border and the sign s of the factored
/// block (s B = L L^T), and leaves in `a` what the row-cyclic solver leaves in its rows: L in the
/// lower triangle of rows and columns k..n, Q^T A Q in the columns 0..k and the rows 0..k. Moved
/// to the row-cyclic layout ([`LocalBlocks::to_row_cyclic`]), that is a factor to border (see
/// `extend`).
pub(super) fn factor_and_solve(
    job: &Job<'_>,
    grid: &ProcessGrid<'_>,
    a: &mut LocalBlocks,
    k: usize,
) -> Result<(Vec<f64>, Border, f64)> {
    assert!(k >= 1, "the projected Cholesky needs a polynomial border");
    let (rows, cols, ld) = (a.rows, a.cols, a.ld());
    let n = a.n() - k;
    // P (n x k, column-major) from the border rows n.., columns 0..n, wherever they are
    let (la, ca) = (rows.first_local_from(n), cols.first_local_from(n));
    let mut p = vec![0.0; n * k];
    for lr in la..ld {
        let j = rows.global(lr) - n;
        for lc in 0..ca {
            p[cols.global(lc) + j * n] = a.data[lr + lc * ld];
        }
    }
    grid.comm.sum_f64(&mut p);
    let border = Border::of(p, n, k)?;
    project(job, grid, a, &border, n);
    let rhs = cols.owner(n + k);
    let lrhs = cols.local(n + k);

    // the right-hand side: Q^T r
    let mut y = vec![0.0; n];
    if grid.mycol == rhs {
        for lr in 0..la {
            y[rows.global(lr)] = a.data[lr + lrhs * ld];
        }
    }
    grid.comm.sum_f64(&mut y);
    border.q_transpose(&mut y);

    // s B positive definite: the sign of its first diagonal entry
    let mut d0 = [0.0];
    let diag = grid.rank_at(rows.owner(k), cols.owner(k));
    if grid.comm.rank() == diag {
        d0[0] = a.data[rows.local(k) + cols.local(k) * ld];
    }
    grid.comm.broadcast_f64(diag, &mut d0);
    let sign = if d0[0] < 0.0 { -1.0 } else { 1.0 };
    if sign < 0.0 {
        // the lower triangle of B, from each column's diagonal row down
        for lc in cols.first_local_from(k)..ca {
            let r0 = rows.first_local_from(cols.global(lc));
            a.data[lc * ld + r0..lc * ld + la].iter_mut().for_each(|v| *v = -*v);
        }
    }
    factor(job, grid, a, k, n)?;

    let panels = panels(k, n, rows.nb);
    // forward solve L z = s y[k..n], panel by panel down
    let mut z = vec![0.0; n];
    for &(p0, p1) in &panels {
        let (ri, ci) = (rows.owner(p0), cols.owner(p0));
        let mut out = vec![0.0; p1 - p0];
        if grid.myrow == ri {
            let lb = rows.local(p0);
            // s = sum over columns k..p0 of L[p0..p1, c] z[c], over the process row
            let mut s = vec![0.0; p1 - p0];
            for lc in cols.first_local_from(k)..cols.first_local_from(p0) {
                let zc = z[cols.global(lc)];
                for (st, l) in s.iter_mut().zip(&a.data[lb + lc * ld..lb + (p1 - p0) + lc * ld]) {
                    *st += l * zc;
                }
            }
            grid.row.sum_f64(&mut s);
            if grid.mycol == ci {
                let lcb = cols.local(p0);
                let l = |i: usize, j: usize| a.data[lb + i + (lcb + j) * ld];
                for i in 0..p1 - p0 {
                    let t: f64 = (0..i).map(|j| l(i, j) * out[j]).sum();
                    out[i] = (sign * y[p0 + i] - s[i] - t) / l(i, i);
                }
            }
        }
        grid.comm.broadcast_f64(grid.rank_at(ri, ci), &mut out);
        z[p0..p1].copy_from_slice(&out);
    }
    // back solve L^T mu = z, panel by panel up
    let mut mu = vec![0.0; n];
    for &(p0, p1) in panels.iter().rev() {
        let (ri, ci) = (rows.owner(p0), cols.owner(p0));
        let mut out = vec![0.0; p1 - p0];
        if grid.mycol == ci {
            let lcb = cols.local(p0);
            // s = sum over rows p1..n of L[r, p0..p1] mu[r], over the process column
            let mut s = vec![0.0; p1 - p0];
            let r0 = rows.first_local_from(p1);
            for (t, st) in s.iter_mut().enumerate() {
                let col = &a.data[(lcb + t) * ld..(lcb + t) * ld + la];
                *st = (r0..la).map(|lr| col[lr] * mu[rows.global(lr)]).sum();
            }
            grid.col.sum_f64(&mut s);
            if grid.myrow == ri {
                let lb = rows.local(p0);
                let l = |i: usize, j: usize| a.data[lb + i + (lcb + j) * ld];
                for i in (0..p1 - p0).rev() {
                    let t: f64 = (i + 1..p1 - p0).map(|j| l(j, i) * out[j]).sum();
                    out[i] = (z[p0 + i] - s[i] - t) / l(i, i);
                }
            }
        }
        grid.comm.broadcast_f64(grid.rank_at(ri, ci), &mut out);
        mu[p0..p1].copy_from_slice(&out);
    }

    // lambda = Q [0; mu]; R c = (Q^T r)[0..k] - (Q^T A Q)[0..k, k..n] mu
    let mut lambda = mu.clone();
    lambda[..k].iter_mut().for_each(|x| *x = 0.0);
    border.q(&mut lambda);
    let mut t = vec![0.0; k];
    for lr in 0..rows.first_local_from(k) {
        let i = rows.global(lr);
        t[i] =
            -(cols.first_local_from(k)..ca).map(|lc| a.data[lr + lc * ld] * mu[cols.global(lc)]).sum::<f64>();
    }
    grid.comm.sum_f64(&mut t);
    let r = border.r();
    let mut c = vec![0.0; k];
    for i in (0..k).rev() {
        let s: f64 = (i + 1..k).map(|j| r[(i, j)] * c[j]).sum();
        c[i] = (y[i] + t[i] - s) / r[(i, i)];
    }
    lambda.extend(c);
    Ok((lambda, border, sign))
}

/// The panels of B: from row k to the end of its block, then block by block to n.
fn panels(k: usize, n: usize, nb: usize) -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    let mut p0 = k;
    while p0 < n {
        let p1 = ((p0 / nb + 1) * nb).min(n);
        out.push((p0, p1));
        p0 = p1;
    }
    out
}

/// A <- Q^T A Q on this rank's block of A (rows and columns 0..n), in the entries the solve reads:
/// every row of the columns 0..k, and in the columns k..n the rows 0..k and the lower triangle
/// (from the diagonal row of each chunk of [`COL_CHUNK`] local columns down). X = A V is taken
/// from the lower triangle alone, so the rest of the upper triangle is never read and is left as
/// it was. Collective over the grid.
fn project(job: &Job<'_>, grid: &ProcessGrid<'_>, a: &mut LocalBlocks, border: &Border, n: usize) {
    let (rows, cols, ld) = (a.rows, a.cols, a.ld());
    let k = border.k;
    let (la, ca) = (rows.first_local_from(n), cols.first_local_from(n));
    let (v, t) = border.wy();
    // X = A V: this block's part, summed over the whole grid
    let (rg, cg) = (rows.globals(), cols.globals());
    let mut xg = lower_times_part(&a.data, ld, (&rg[..la], &cg[..ca]), &v);
    grid.comm.sum_f64(&mut xg);
    let x = MatRef::from_column_major_slice(&xg, n, k);
    let zm = v.transpose() * x;
    let y = x * &t - (&v * (t.transpose() * &zm * &t)) * 0.5;
    let left = Mat::<f64>::from_fn(la, 2 * k, |lr, j| {
        let g = rows.global(lr);
        if j < k {
            y[(g, j)]
        } else {
            v[(g, j - k)]
        }
    });
    let right = Mat::<f64>::from_fn(2 * k, ca, |j, lc| {
        let c = cols.global(lc);
        if j < k {
            v[(c, j)]
        } else {
            y[(c, j - k)]
        }
    });
    let top = rows.first_local_from(k);
    for c0 in (0..ca).step_by(COL_CHUNK) {
        let w = COL_CHUNK.min(ca - c0);
        let g0 = cols.global(c0);
        let below = if g0 < k { 0 } else { rows.first_local_from(g0).max(top) };
        let ranges = if below <= top { [(0, la), (la, la)] } else { [(0, top), (below, la)] };
        for (r0, r1) in ranges.into_iter().filter(|(r0, r1)| r1 > r0) {
            let block =
                MatMut::from_column_major_slice_with_stride_mut(&mut a.data[r0 + c0 * ld..], r1 - r0, w, ld);
            let l = left.as_ref().subrows(r0, r1 - r0);
            gemm(block, Accum::Add, l, right.as_ref().subcols(c0, w), -1.0, job.par);
        }
    }
}

/// Factors s B (rows and columns k..n, already multiplied by the sign) in place: L in the lower
/// triangle of the factored panels. Collective over the grid; `Error::NotDefinite` on every rank
/// when a pivot is not positive. With `job.lookahead` the process column of the next panel
/// updates that panel's columns first, factors it and broadcasts it (non-blocking) while the rest
/// of the trailing update runs, as the 2D LU does; the factor is the same.
fn factor(job: &Job<'_>, grid: &ProcessGrid<'_>, a: &mut LocalBlocks, k: usize, n: usize) -> Result<()> {
    let panels = panels(k, n, a.rows.nb);
    let Some(&first) = panels.first() else { return Ok(()) };
    let mut panel = factor_and_pack(job, grid, a, first, n);
    grid.row.broadcast_f64(a.cols.owner(first.0), &mut panel);
    for (i, &(p0, p1)) in panels.iter().enumerate() {
        if panel[0] != 0.0 {
            return Err(Error::NotDefinite(format!(
                "a pivot of the projected block is not positive near row {p0} of {n} \
                 (the kernel is not conditionally definite on these points to working precision)"
            )));
        }
        let Some(&next) = panels.get(i + 1) else {
            (job.progress)(p1, n);
            return Ok(());
        };
        let (rows, cols) = (a.rows, a.cols);
        let (t0, la) = (rows.first_local_from(p1), rows.first_local_from(n));
        let update = Update::new(grid, a, (p0, p1, n), &panel[1..], la - t0);
        let (c1, cn) = (cols.first_local_from(p1), cols.first_local_from(n));
        let len = 1 + (la - rows.first_local_from(next.1)) * (next.1 - next.0);
        let next_panel = update_and_next_panel(
            grid,
            a,
            job.lookahead,
            c1..cn,
            (cols.owner(next.0), next.1 - next.0),
            len,
            &|a, c0, ce| update.apply(job, a, c0, ce),
            &|a| factor_and_pack(job, grid, a, next, n),
        );
        (job.progress)(p1, n);
        panel = next_panel;
    }
    Ok(())
}

/// On the process column of the panel (p0, p1): the owner of the diagonal block factors it and
/// sends L11 down the process column, which solves for its rows of L21 = B21 L11^-T (stored in
/// place). Returns the status (0, or 1: not definite) and this process row's rows p1..n of L21
/// (column-major), to travel along the process rows; elsewhere a buffer of the same length.
/// Collective over the panel's process column.
fn factor_and_pack(
    job: &Job<'_>,
    grid: &ProcessGrid<'_>,
    a: &mut LocalBlocks,
    (p0, p1): (usize, usize),
    n: usize,
) -> Vec<f64> {
    let (rows, cols, ld) = (a.rows, a.cols, a.ld());
    let pb = p1 - p0;
    let (ri, ci) = (rows.owner(p0), cols.owner(p0));
    let t0 = rows.first_local_from(p1);
    let m = rows.first_local_from(n) - t0;
    let mut panel = vec![0.0; 1 + m * pb];
    if grid.mycol != ci {
        return panel;
    }
    let lcb = cols.local(p0);
    let mut d = vec![0.0; 1 + pb * pb];
    if grid.myrow == ri {
        let lb = rows.local(p0);
        let b11: Vec<f64> = (0..pb * pb).map(|e| a.data[lb + e / pb + (lcb + e % pb) * ld]).collect();
        match cholesky_small(&b11, pb) {
            Some(l11) => {
                for j in 0..pb {
                    for i in 0..pb {
                        d[1 + i + j * pb] = l11[(i, j)];
                        a.data[lb + i + (lcb + j) * ld] = l11[(i, j)];
                    }
                }
            }
            None => d[0] = 1.0,
        }
    }
    grid.col.broadcast_f64(ri, &mut d);
    panel[0] = d[0];
    if d[0] == 0.0 && m > 0 {
        // L21 = B21 L11^-T: L21 L11^T = B21, solved in place (from the right, on the rows where
        // they lie), then copied column by column into the panel that travels
        let l11 = MatRef::from_column_major_slice(&d[1..], pb, pb);
        let mut b21 =
            MatMut::from_column_major_slice_with_stride_mut(&mut a.data[t0 + lcb * ld..], m, pb, ld);
        solve_lower(l11, false, b21.rb_mut().transpose_mut(), job.par);
        for j in 0..pb {
            panel[1 + j * m..1 + (j + 1) * m]
                .copy_from_slice(&a.data[t0 + (lcb + j) * ld..t0 + (lcb + j) * ld + m]);
        }
    }
    panel
}

/// The symmetric update B22 -= L21 L21^T of one panel on this rank's block: its rows of L21 and
/// the rows of L21 at its columns.
struct Update<'p> {
    /// This process row's rows p1..n of L21 (m x pb, column-major).
    l21: &'p [f64],
    m: usize,
    pb: usize,
    /// The rows of L21 at this rank's columns p1..n, as the columns of a pb x (columns) matrix.
    lt: Vec<f64>,
    /// The first local row and column at or below p1; the end of the rows of B.
    t0: usize,
    c1: usize,
    la: usize,
}

impl<'p> Update<'p> {
    /// Collects the rows of L21 at this rank's columns: the rank of each process row that holds
    /// such rows gives them to the process column in one all-gather. Collective over the process
    /// column.
    fn new(
        grid: &ProcessGrid<'_>,
        a: &LocalBlocks,
        (p0, p1, n): (usize, usize, usize),
        l21: &'p [f64],
        m: usize,
    ) -> Self {
        let (rows, cols) = (a.rows, a.cols);
        let pb = p1 - p0;
        let (t0, la) = (rows.first_local_from(p1), rows.first_local_from(n));
        let mut send = Vec::new();
        for lr in t0..la {
            if cols.owner(rows.global(lr)) == grid.mycol {
                send.extend((0..pb).map(|j| l21[lr - t0 + j * m]));
            }
        }
        // every process row's count, and the order its rows arrive in: ascending global index
        let mut counts = vec![0usize; grid.pr];
        let (c1, cn) = (cols.first_local_from(p1), cols.first_local_from(n));
        for lc in c1..cn {
            counts[rows.owner(cols.global(lc))] += pb;
        }
        let mut recv = vec![0.0; counts.iter().sum()];
        grid.col.all_gather_f64(&send, &counts, &mut recv);
        let mut lt = vec![0.0; pb * (cn - c1)];
        let mut offset = vec![0usize; grid.pr];
        for r in 1..grid.pr {
            offset[r] = offset[r - 1] + counts[r - 1];
        }
        for lc in c1..cn {
            let r = rows.owner(cols.global(lc));
            lt[(lc - c1) * pb..(lc - c1 + 1) * pb].copy_from_slice(&recv[offset[r]..offset[r] + pb]);
            offset[r] += pb;
        }
        Update { l21, m, pb, lt, t0, c1, la }
    }

    /// The update of the local columns c0..ce, lower triangle: chunks of columns, each from the
    /// row of its first column's diagonal down.
    fn apply(&self, job: &Job<'_>, a: &mut LocalBlocks, c0: usize, ce: usize) {
        let (rows, cols, ld) = (a.rows, a.cols, a.ld());
        if self.m == 0 || c0 >= ce {
            return;
        }
        let l = MatRef::from_column_major_slice(self.l21, self.m, self.pb);
        let w = self.lt.len() / self.pb;
        let ltm = MatRef::from_column_major_slice(&self.lt, self.pb, w);
        let mut c = c0;
        while c < ce {
            let e = (c + COL_CHUNK).min(ce);
            let r0 = rows.first_local_from(cols.global(c)).max(self.t0);
            if r0 < self.la {
                let block = MatMut::from_column_major_slice_with_stride_mut(
                    &mut a.data[r0 + c * ld..],
                    self.la - r0,
                    e - c,
                    ld,
                );
                let lrows = l.subrows(r0 - self.t0, self.la - r0);
                gemm(block, Accum::Add, lrows, ltm.subcols(c - self.c1, e - c), -1.0, job.par);
            }
            c = e;
        }
    }
}
