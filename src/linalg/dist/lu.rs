//! Distributed LU with partial pivoting on the row-cyclic layout, blocked and right-looking.
//!
//! Gaussian elimination with partial pivoting computes P M = L U: at step j the row p >= j with
//! the largest |a_pj| is swapped into row j, the multipliers l_ij = a_ij / a_jj (|l_ij| <= 1, which
//! bounds the growth of the entries in practice) are stored in place of the eliminated entries, and
//! a_ic <- a_ic - l_ij a_jc for i, c > j. The right-hand side is the last column, so it undergoes
//! the same swaps and updates; back substitution ends the solve (2/3 n^3 flops, half of
//! Householder's).
//!
//! Blocked by panels of nb columns, with M partitioned at the panel as [A11 A12; A21 A22]: the
//! panel [A11; A21] is factored into L11 U11 and L21 (recursively halved, so that its own updates
//! are small GEMMs too), and its row swaps are applied to the columns right of it. The textbook
//! step then solves U12 = L11^-1 A12 and updates A22 -= L21 U12. Here the step is taken in block
//! form instead:
//!
//! ```text
//!     W = L21 L11^-1  (= A21 A11^-1),     A22 <- A22 - W A12,
//! ```
//!
//! the same Schur complement (L21 U12 = L21 L11^-1 A12), with W stored in place of L21 and A12
//! left as it is in the block row. The reason is the distribution: U12 is needed whole by every
//! rank, so the textbook step solves it on every rank, nb^2 (n - k) multiply-adds per panel that
//! do not shrink as ranks are added (at n = 8000 and nb = 192 about 6e9 on each rank, 4 % of the
//! whole factorisation on one rank and a growing share on more). W is computed by each rank for
//! its own rows only, nb^2 (n - k) / p. The stored factors change meaning accordingly: the
//! diagonal block of each panel holds L11\U11, the columns right of it in the panel's rows hold
//! A12 (not U12), the rows below hold W (not L21), and the right-hand side carried in the last
//! column is not multiplied by L11^-1 in the panel's rows. Back substitution takes that form
//! (`backsub`: x1 = U11^-1 L11^-1 (c1 - A12 x2)), and so do the mixed-precision solves with the
//! f32 factors (`mixed`). Inside a panel the halves use the textbook step, so that the diagonal
//! block is the panel's L11\U11.
//!
//! On the ranks: the pivot search of column j is one all-gather of each rank's best candidate,
//! which carries its row's panel part along, so the pivot row is known everywhere without a
//! broadcast; a swap is a message between the two owners. Per panel, the block row [L11 A12] is
//! all-gathered (each rank's rows column by column, as they lie, so neither side transposes).
//! Every rank then forms W for its own rows (a triangular solve from the right) and updates its
//! own rows of A22 with one local GEMM, which carries almost all the flops. The matrix is never
//! gathered.
//!
//! Look-ahead: the panel factorisation is a chain of small collectives (nb all-gathers of pivot
//! candidates, each waiting for every rank), and on the row-cyclic layout every rank takes part
//! in every one of them, so no rank can factor the next panel alone while the others update.
//! What can overlap is a rank's own trailing update with the messages of the pivot searches. At
//! step k the update A22 -= W A12 is split by columns: the columns of panel k+1 are updated
//! first (a narrow GEMM), panel k+1 is factored at once, and the remaining columns are updated
//! in pieces, one started while each pivot all-gather of panel k+1 is in flight (a non-blocking
//! all-gather, tested between pieces), the leftover after the panel. This is exact, not an
//! approximation: panel k+1's interchanges touch only its own columns (the other columns get
//! them afterwards, in one pass), and W of step k lives in columns left of panel k+1, which
//! nothing in panel k+1 writes, so the update of a column of A22 gives the same values whenever it
//! runs before that pass. The waits of the pivot searches (latency, and ranks arriving at
//! different times) are then filled with GEMM work instead of idling.

use crate::linalg::gemm::{gemm, solve_lower, solve_lower_right};
use faer::reborrow::Reborrow;
use faer::{Accum, MatMut, MatRef, Par};

use super::backsub::{back_substitute, Rows};
use super::layout::RowCyclic;
use super::scalar::Scalar;
use super::solver::Job;
use super::system::{GatherBuffers, LocalRows};
use crate::error::{Error, Result};
use crate::par::Comm;

/// Solves the distributed system in `rows` (right-hand side in the last column) and returns the
/// solution on every rank. Collective. `rows` is overwritten by the factors in block form (see
/// the module documentation). `par` is the parallelism of the local trailing-update GEMMs.
pub fn lu_solve(job: &Job<'_>, rows: &mut LocalRows) -> Result<Vec<f64>> {
    let tol = rows.singular_tol(job.comm);
    lu_factor(job, rows)?;
    back_substitute(job.comm, rows, job.panel.max(1), Rows::BlockLu, tol)
}

/// Factors the distributed matrix in `rows` in its own precision, in block form (see the module
/// documentation; the right-hand side column is carried along as a column of A12 and A22), and
/// returns the row interchanges (j, p), in the order applied: panel by panel, j ascending.
/// Collective. Column j of W is left where the interchanges of its own panel put it: the later
/// panels' interchanges reach only the columns right of their panel. With `job.lookahead`, the
/// trailing update of each panel runs in the pivot searches of the next one (see the module
/// documentation); the factors are the same up to rounding (the GEMM pieces are of other widths:
/// 9e-14 relative in the weights of a 3000-point fit on 2 ranks).
pub fn lu_factor<T: Scalar>(job: &Job<'_>, rows: &mut LocalRows<T>) -> Result<Vec<(usize, usize)>> {
    let Job { comm, panel, par, progress, lookahead } = *job;
    // on one rank there are no messages to overlap with
    let lookahead = lookahead && comm.size() > 1;
    let (lay, cols, nb) = (rows.layout, rows.cols, panel.max(1));
    let n = lay.n;
    let tol = rows.singular_tol(comm);
    let mut bufs = GatherBuffers::default();
    let mut all_swaps = Vec::with_capacity(n);
    if n == 0 {
        return Ok(all_swaps);
    }
    let (mut k, mut kb) = (0, nb.min(n));
    // the panel's interchanges are applied to the panel at once and to the columns right of it
    // afterwards, in one pass; columns left of it hold L, which nothing reads again
    let mut swaps = Vec::with_capacity(nb);
    factor_panel(comm, rows, 0, kb, (0, kb), tol, &mut swaps, &mut bufs, &mut Trailing::none())?;
    loop {
        let end = k + kb;
        rows.permute_rows(comm, &swaps, end, cols);
        all_swaps.append(&mut swaps);
        let mut rest = Trailing::block(comm, rows, (k, end, cols), par, &mut bufs);
        progress(end, n);
        if end == n {
            rest.finish(rows);
            return Ok(all_swaps);
        }
        let next = (end, end + nb.min(n - end));
        if lookahead {
            // the next panel's columns first, the rest in the windows of its pivot searches
            rest.apply(rows, next.0, next.1);
            rest.spread(next.1, next.1 - next.0);
        } else {
            rest.finish(rows);
        }
        factor_panel(comm, rows, next.0, next.1, next, tol, &mut swaps, &mut bufs, &mut rest)?;
        rest.finish(rows);
        (k, kb) = (next.0, next.1 - next.0);
    }
}

/// Columns at most this wide are factored column by column; wider ones recursively.
const LEAF: usize = 8;

/// The narrowest piece of a trailing update run in one window of a pivot search: every piece
/// reads all of L21 again, so narrow pieces lose the GEMM's speed (on one rank, pieces of 32
/// columns took 10 % longer than one GEMM at N = 4000, pieces of 1024 the same time).
const MIN_PIECE: usize = 256;

/// LU of the panel columns a..b (rows a..n), recursively: the left half, its block elimination
/// on the right half (a GEMM), then the right half. Swaps whole rows. `work` is the pending
/// trailing update of the previous panel, advanced while the pivot searches are in flight.
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
    work: &mut Trailing<T>,
) -> Result<()> {
    if b - a <= LEAF {
        return factor_columns(comm, rows, a, b - a, panel, tol, swaps, work);
    }
    let m = a + (b - a) / 2;
    factor_panel(comm, rows, a, m, panel, tol, swaps, bufs, work)?;
    Trailing::inner(comm, rows, (a, m, b), bufs).finish(rows);
    factor_panel(comm, rows, m, b, panel, tol, swaps, bufs, work)
}

/// The block elimination of the factored columns a..m on the columns m..c1, the update of this
/// rank's rows below m by the left factor stored in columns a..m (L21 inside a panel, W at its
/// end) times `right`, column range by column range, with the columns `next..c1` still to do.
/// `overlap`: the pieces run in the windows of the pivot searches (decided alike on every rank: a
/// blocking and a non-blocking all-gather do not match, while how many pieces a window takes
/// depends on the timing of each rank).
struct Trailing<T> {
    a: usize,
    m: usize,
    /// The block row right of the factored columns: U12 inside a panel, A12 at its end.
    right: faer::Mat<T>,
    next: usize,
    c1: usize,
    piece: usize,
    par: Par,
    overlap: bool,
}

impl<T: Scalar> Trailing<T> {
    /// Nothing to do.
    fn none() -> Self {
        Trailing {
            a: 0,
            m: 0,
            right: faer::Mat::new(),
            next: 0,
            c1: 0,
            piece: 1,
            par: Par::Seq,
            overlap: false,
        }
    }

    /// The block row [L11 A12] of rows a..m and columns a..c1, gathered whole on every rank: L11
    /// (unit lower triangular, read below its diagonal) and A12. Collective.
    fn block_row(
        comm: &dyn Comm,
        rows: &LocalRows<T>,
        (a, m, c1): (usize, usize, usize),
        bufs: &mut GatherBuffers<T>,
    ) -> (faer::Mat<T>, faer::Mat<T>) {
        let lay = rows.layout;
        let (w, rest) = (m - a, c1 - m);
        let (mut l11, mut a12) = (faer::Mat::<T>::zeros(w, w), faer::Mat::<T>::zeros(w, rest));
        let by_rank = rows.gather_columns_by_rank(comm, (a, m), (a, c1), bufs);
        place_by_rank(by_rank, &lay, (a, m), c1 - a, 0..w, &mut l11, 0);
        place_by_rank(by_rank, &lay, (a, m), c1 - a, w..c1 - a, &mut a12, 0);
        (l11, a12)
    }

    /// Inside a panel: U12 = L11^-1 A12 for the columns m..c1 (the panel's right half), solved
    /// whole on every rank (a few columns) and stored in the owners' rows, so that the panel's
    /// diagonal block ends as L11\U11; the update A22 -= L21 U12 is left to do. Collective.
    fn inner(
        comm: &dyn Comm,
        rows: &mut LocalRows<T>,
        (a, m, c1): (usize, usize, usize),
        bufs: &mut GatherBuffers<T>,
    ) -> Self {
        if c1 == m {
            return Trailing::none();
        }
        let (l11, mut u12) = Self::block_row(comm, rows, (a, m, c1), bufs);
        solve_lower(l11.as_ref(), true, u12.as_mut(), Par::Seq);
        let lay = rows.layout;
        let (o0, o1) = (lay.first_local_from(a), lay.first_local_from(m));
        for j in 0..c1 - m {
            for l in o0..o1 {
                rows.set(l, m + j, u12[(lay.global(l) - a, j)]);
            }
        }
        Trailing { a, m, right: u12, next: m, c1, piece: c1 - m, par: Par::Seq, overlap: false }
    }

    /// At the end of a panel (columns a..m): the block form. Each rank turns its own rows of L21
    /// into W = L21 L11^-1 in place and keeps A12 (gathered, not solved); the update A22 -= W A12
    /// is left to do. Collective.
    fn block(
        comm: &dyn Comm,
        rows: &mut LocalRows<T>,
        (a, m, c1): (usize, usize, usize),
        par: Par,
        bufs: &mut GatherBuffers<T>,
    ) -> Self {
        let (l11, a12) = Self::block_row(comm, rows, (a, m, c1), bufs);
        let (t0, lc) = (rows.layout.first_local_from(m), rows.ld());
        if t0 < lc {
            let l21 = rows.view_mut().submatrix_mut(t0, a, lc - t0, m - a);
            solve_lower_right(l11.as_ref(), true, l21, par);
        }
        Trailing { a, m, right: a12, next: m, c1, piece: c1 - m, par, overlap: false }
    }

    /// Applies the update to the columns c0..c1 (one local GEMM).
    fn apply(&self, rows: &mut LocalRows<T>, c0: usize, c1: usize) {
        let t0 = rows.layout.first_local_from(self.m);
        let lc = rows.ld();
        if c0 >= c1 || t0 >= lc {
            return;
        }
        let (a, w) = (self.a, self.m - self.a);
        let sub = rows.view_mut().submatrix_mut(t0, a, lc - t0, c1 - a);
        let (left, right) = sub.split_at_col_mut(w);
        let l21: MatRef<'_, T> = left.rb();
        let a22: MatMut<'_, T> = right.subcols_mut(c0 - self.m, c1 - c0);
        let right = self.right.as_ref().subcols(c0 - self.m, c1 - c0);
        gemm(a22, Accum::Add, l21, right, T::of(-1.0), self.par);
    }

    /// Leaves the columns from c0 on to do, in `windows` pieces of equal width (at least
    /// `MIN_PIECE` columns each), to run in the windows of the pivot searches.
    fn spread(&mut self, c0: usize, windows: usize) {
        self.overlap = true;
        self.next = c0.min(self.c1);
        self.piece = (self.c1 - self.next).div_ceil(windows.max(1)).max(MIN_PIECE);
    }

    /// Whether the whole update is done.
    fn done(&self) -> bool {
        self.next >= self.c1
    }

    /// Applies the next piece; true while pieces remain.
    fn step(&mut self, rows: &mut LocalRows<T>) -> bool {
        if self.done() {
            return false;
        }
        let end = (self.next + self.piece).min(self.c1);
        self.apply(rows, self.next, end);
        self.next = end;
        !self.done()
    }

    /// Applies what remains.
    fn finish(&mut self, rows: &mut LocalRows<T>) {
        self.apply(rows, self.next, self.c1);
        self.next = self.c1;
    }
}

/// Of the rows a..m of `cols` columns received by rank (rank r's rows of the range in local
/// order, column by column), puts the columns `take` in place: column c as column `to0 + c -
/// take.start` of `to`, row g as row g - a.
fn place_by_rank<T: Scalar>(
    by_rank: &[T],
    lay: &RowCyclic,
    (a, m): (usize, usize),
    cols: usize,
    take: std::ops::Range<usize>,
    to: &mut faer::Mat<T>,
    to0: usize,
) {
    let mut at = 0;
    for r in 0..lay.ranks {
        // rank r holds the block's rows i = first, first + P, ...
        let cnt = lay.count_in_on(r, a, m);
        let first = (r + lay.ranks - a % lay.ranks) % lay.ranks;
        for c in take.clone() {
            let dest = to.col_as_slice_mut(to0 + c - take.start);
            for (t, v) in by_rank[at + c * cnt..at + (c + 1) * cnt].iter().enumerate() {
                dest[first + t * lay.ranks] = *v;
            }
        }
        at += cnt * cols;
    }
}

/// Unblocked LU of the columns k..k+kb (rows k..n); row interchanges are applied to the panel
/// columns `panel.0..panel.1` and recorded in `swaps`. Pieces of `work` run while each pivot
/// search is in flight.
#[allow(clippy::too_many_arguments)]
fn factor_columns<T: Scalar>(
    comm: &dyn Comm,
    rows: &mut LocalRows<T>,
    k: usize,
    kb: usize,
    panel: (usize, usize),
    tol: f64,
    swaps: &mut Vec<(usize, usize)>,
    work: &mut Trailing<T>,
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
        if !work.overlap {
            T::all_gather(comm, &mine, &counts, &mut cand);
        } else {
            T::all_gather_while(comm, &mine, &counts, &mut cand, &mut || work.step(rows));
        }
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
