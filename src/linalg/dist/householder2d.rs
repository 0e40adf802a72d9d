//! Householder QR on the 2D block-cyclic layout (see `grid`), blocked in compact-WY form as
//! ScaLAPACK's PDGEQRF: the reflectors and T of `crate::linalg::reflector`, the ranks arranged as
//! in the row-cyclic Householder (`householder`) but over one process column at a time.
//!
//! At the panel of columns k..k+kb (one block column, on process column pk):
//!
//! 1. The PR ranks of process column pk factor the panel column by column. A reflector needs
//!    a_jj and the squared norm of the column below it, and applying it to the panel column c
//!    needs a_jc and v'^T a'_c: they travel in one all-reduce over the process column per column
//!    (as on the row-cyclic layout, where it is over all ranks), after which each rank updates its
//!    own rows of the panel.
//! 2. They sum their parts of V^T V over the process column, every one builds the same T, and
//!    each broadcasts along its process row the taus, T and its rows of V (explicit: unit
//!    diagonal, zeros above).
//! 3. Every rank forms its part of W = V^T A_trail for its columns right of the panel (the
//!    right-hand side among them, so that it receives Q^T b on the way), one all-reduce over the
//!    process column sums it, and A_trail <- A_trail - V T^T W is one local GEMM, T^T joined to
//!    the shorter side of the rank's block first (see `Update`).
//!
//! R and Q^T b end where U and L^-1 P b end in the 2D LU, so its back substitution finishes the
//! solve. With look-ahead the process column of the next panel applies step 3 to that panel's
//! columns first, factors it and starts its broadcast (non-blocking) while every rank runs the
//! rest of step 3 in pieces; the factors are the same.

use crate::linalg::gemm::{by_blas_on_every_rank, gemm};
use faer::{Accum, MatMut, MatRef};

use super::grid::{update_and_next_panel, LocalBlocks, ProcessGrid};
use super::householder::{factor_panel, form_w, stored_w};
use super::lu2d::back_substitute;
use super::solver::Job;
use crate::error::Result;
use crate::linalg::reflector::wy_t;

/// Solves the system in `a` (right-hand side as global column n) on `grid` by Householder QR and
/// returns the solution on every rank. Collective over the grid; every rank returns the same
/// outcome (a singular R is found in the back substitution). `a` is overwritten by R, the
/// reflectors and Q^T b. The panel width is the block size of `a`. With `job.lookahead` the
/// process column of the next panel applies the update to that panel's columns first, factors it
/// and broadcasts it (non-blocking) while the rest of the update runs, as in the 2D LU.
pub fn householder2d_solve(job: &Job<'_>, grid: &ProcessGrid<'_>, a: &mut LocalBlocks) -> Result<Vec<f64>> {
    let n = a.n();
    let tol = a.max_abs(grid.comm) * f64::EPSILON * n as f64;
    if n == 0 {
        return back_substitute(grid, a, tol);
    }
    let (rows, cols) = (a.rows, a.cols);
    let mut panel = factor_and_pack(grid, a, 0);
    grid.row.broadcast_f64(cols.owner(0), &mut panel);
    let mut k = 0;
    loop {
        let kb = rows.nb.min(n - k);
        let end = k + kb;
        let lc1 = cols.first_local_from(end);
        let ncl = cols.local_count();
        let update = Update::new(grid, a, k, kb, &panel, job);
        if end == n {
            update.apply(a, lc1, ncl, job);
            (job.progress)(end, n);
            break;
        }
        let (pk1, kb1) = (cols.owner(end), rows.nb.min(n - end));
        let len = panel_len(kb1, a.ld() - rows.first_local_from(end));
        let next = update_and_next_panel(
            grid,
            a,
            job.lookahead,
            lc1..ncl,
            (pk1, kb1),
            len,
            &|a, c0, c1| update.apply(a, c0, c1, job),
            &|a| factor_and_pack(grid, a, end),
        );
        (job.progress)(end, n);
        panel = next;
        k = end;
    }
    back_substitute(grid, a, tol)
}

/// Length of a packed panel of width kb with m local rows: the taus, T (kb x kb) and V (m x kb).
fn panel_len(kb: usize, m: usize) -> usize {
    kb + kb * kb + m * kb
}

/// On the process column of the panel at column k: factors it, builds T from V^T V (summed over
/// the process column) and packs the taus, T and this process row's rows k.. of V (explicit:
/// unit diagonal, zeros above), column-major; elsewhere a buffer of the same length. Collective
/// over the process column.
fn factor_and_pack(grid: &ProcessGrid<'_>, a: &mut LocalBlocks, k: usize) -> Vec<f64> {
    let (rows, cols, ld) = (a.rows, a.cols, a.ld());
    let kb = rows.nb.min(a.n() - k);
    let lr0 = rows.first_local_from(k);
    let m = ld - lr0;
    let (t_at, v_at) = (kb, kb + kb * kb);
    let mut panel = vec![0.0; panel_len(kb, m)];
    if grid.mycol != cols.owner(k) {
        return panel;
    }
    let lc0 = cols.local(k);
    let taus = factor_panel(grid.col.as_ref(), &rows, &mut a.data, ld, (k, kb), lc0, None);
    for c in 0..kb {
        for (t, lr) in (lr0..ld).enumerate() {
            let g = rows.global(lr);
            panel[v_at + t + c * m] = match g.cmp(&(k + c)) {
                std::cmp::Ordering::Less => 0.0,
                std::cmp::Ordering::Equal => 1.0,
                std::cmp::Ordering::Greater => a.data[lr + (lc0 + c) * ld],
            };
        }
    }
    let v = MatRef::from_column_major_slice(&panel[v_at..], m, kb);
    let mut gram = vec![0.0; kb * kb];
    let gm = MatMut::from_column_major_slice_mut(&mut gram, kb, kb);
    gemm(gm, Accum::Replace, v.transpose(), v, 1.0, faer::Par::Seq);
    grid.col.sum_f64(&mut gram);
    let t = wy_t(&taus, MatRef::from_column_major_slice(&gram, kb, kb));
    panel[..kb].copy_from_slice(&taus);
    for j in 0..kb {
        for i in 0..kb {
            panel[t_at + i + j * kb] = t[(i, j)];
        }
    }
    panel
}

/// The block update A_trail <- A_trail - V T^T W of one panel, W = V^T A_trail summed over the
/// process column once for all this rank's columns right of the panel; applied by column ranges.
/// The kb x kb factor T^T joins the shorter side of this rank's block: (V T^T) W where the rank
/// holds fewer rows than trailing columns (a 2x1 grid: every rank holds every column), V (T^T W)
/// otherwise, so the product that the ranks of a process row (or column) would each form whole
/// costs kb^2 times the smaller of the two.
struct Update<'p> {
    /// This process row's rows k.. of V (m x kb, column-major).
    v: MatRef<'p, f64>,
    /// Y = V T^T (m x kb, column-major) where T^T joins V; none where it joins W.
    y: Option<Vec<f64>>,
    /// W, or T^T W where there is no Y, for the local columns lc1.. (kb x columns, column-major),
    /// or its transpose (columns x kb) with `transposed`.
    right: Vec<f64>,
    /// Whether `right` is stored transposed: where the BLAS computes the products on every
    /// rank, which forms A_trail^T V faster than V^T A_trail (see the row-cyclic Householder's
    /// `Update`).
    transposed: bool,
    lr0: usize,
    lc1: usize,
}

impl<'p> Update<'p> {
    /// Forms W and Y, or T^T W, from the packed panel. Collective over the process column.
    fn new(
        grid: &ProcessGrid<'_>,
        a: &LocalBlocks,
        k: usize,
        kb: usize,
        panel: &'p [f64],
        job: &Job<'_>,
    ) -> Self {
        let (rows, cols, ld) = (a.rows, a.cols, a.ld());
        let lr0 = rows.first_local_from(k);
        let m = ld - lr0;
        let (t_at, v_at) = (kb, kb + kb * kb);
        let v = MatRef::from_column_major_slice(&panel[v_at..], m, kb);
        let lc1 = cols.first_local_from(k + kb);
        let w = cols.local_count() - lc1;
        let mut wbuf = vec![0.0; kb * w];
        // the same on every rank of the process column, which sums W as stored
        let transposed = by_blas_on_every_rank(job.par);
        if w > 0 && m > 0 {
            let trail = MatRef::from_column_major_slice_with_stride(&a.data[lr0 + lc1 * ld..], m, w, ld);
            form_w(&mut wbuf, v, trail, transposed, job.par);
        }
        let t = MatRef::from_column_major_slice(&panel[t_at..v_at], kb, kb);
        // Y while W is summed, where T^T joins V (the form is this rank's choice, the sum is
        // the process column's: every rank of it calls the same non-blocking sum)
        let mut y = Vec::new();
        let mut work = || {
            if m < w {
                y = vec![0.0; m * kb];
                if m > 0 {
                    let ym = MatMut::from_column_major_slice_mut(&mut y, m, kb);
                    gemm(ym, Accum::Replace, v, t.transpose(), 1.0, job.par);
                }
            }
            false
        };
        grid.col.sum_f64_while(&mut wbuf, &mut work);
        if m < w {
            return Update { v, y: Some(y), right: wbuf, transposed, lr0, lc1 };
        }
        let mut tw = vec![0.0; kb * w];
        if w > 0 {
            let wm = stored_w(&wbuf, kb, transposed);
            if transposed {
                // (T^T W)^T = W^T T
                let twm = MatMut::from_column_major_slice_mut(&mut tw, w, kb);
                gemm(twm, Accum::Replace, wm.transpose(), t, 1.0, job.par);
            } else {
                let twm = MatMut::from_column_major_slice_mut(&mut tw, kb, w);
                gemm(twm, Accum::Replace, t.transpose(), wm, 1.0, job.par);
            }
        }
        Update { v, y: None, right: tw, transposed, lr0, lc1 }
    }

    /// The update of the local columns c0..c1 (one GEMM).
    fn apply(&self, a: &mut LocalBlocks, c0: usize, c1: usize, job: &Job<'_>) {
        let ld = a.ld();
        let (m, kb) = (self.v.nrows(), self.v.ncols());
        if c0 >= c1 || m == 0 {
            return;
        }
        let right = stored_w(&self.right, kb, self.transposed).subcols(c0 - self.lc1, c1 - c0);
        let left = match &self.y {
            Some(y) => MatRef::from_column_major_slice(y, m, kb),
            None => self.v,
        };
        let trail = MatMut::from_column_major_slice_with_stride_mut(
            &mut a.data[self.lr0 + c0 * ld..],
            m,
            c1 - c0,
            ld,
        );
        gemm(trail, Accum::Add, left, right, -1.0, job.par);
    }
}
