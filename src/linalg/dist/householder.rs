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
//! of V^T V and of W = V^T A_trail, an all-reduce sums V^T V and every rank builds the same T,
//! and an all-reduce sums W, non-blocking: every rank forms Y = V T^T for its own rows of V while
//! the sum is in flight (tested between pieces of Y), then applies
//! A_trail <- A_trail - Y W to its own rows with one local GEMM, which carries almost all the
//! flops (4/3 n^3 in total, twice LU's). Grouped as V (T^T W) instead, the kb x kb x (n - k)
//! product T^T W would be formed whole on every rank, as the same work on 1 rank or 1,000; Y
//! costs a rank kb^2 times its own rows. The matrix is never gathered; back substitution on R
//! finishes the solve.
//!
//! Look-ahead: on the row-cyclic layout every rank holds rows of every panel and takes part in
//! each of its all-reduces (one per column, then V^T V), so no rank can factor the next panel
//! alone; what can overlap is a rank's own trailing update with those small collectives. After
//! W of panel k is summed, the columns of panel k+1 are updated first, panel k+1 is factored with
//! non-blocking all-reduces (all-gathers summed in rank order, [`Comm::all_gather_f64_while`])
//! while the remaining columns of panel k's update run in pieces between the tests, and whatever
//! is left runs before W of panel k+1, which reads every trailing column. Exact: the update of a
//! column gives the same values whenever it runs, and panel k+1's reflectors touch only its own
//! columns. (No piece is a single column, which faer computes as a matrix-vector product whose
//! sums differ in the last bits; on two ranks the factors are bit-identical with and without
//! look-ahead, on more the sums in rank order may round differently from the all-reduce's.) The
//! large all-reduce of W overlaps only Y's product: every trailing column takes part in it.

use crate::linalg::gemm::{by_blas_on_every_rank, gemm};
use faer::reborrow::ReborrowMut;
use faer::{Accum, MatMut, MatRef, Par};

use super::backsub::{back_substitute, Rows};
use super::layout::RowCyclic;
use super::solver::Job;
use super::system::{LocalRows, RowIndex};
use crate::error::Result;
use crate::linalg::reflector::{wy_t, Reflector};
use crate::par::Comm;

/// Solves the distributed system in `rows` (right-hand side in the last column) and returns the
/// solution on every rank. Collective. `rows` is overwritten by R, the reflectors and Q^T b.
/// `par` is the parallelism of the local trailing-update GEMMs. With `job.lookahead`, the
/// trailing update of each panel runs in the all-reduces of the next one (see the module
/// documentation); the factors are the same.
pub fn householder_solve(job: &Job<'_>, rows: &mut LocalRows) -> Result<Vec<f64>> {
    let Job { comm, panel, par, progress, lookahead } = *job;
    // on one rank there are no messages to overlap with
    let lookahead = lookahead && comm.size() > 1;
    let (lay, cols, nb) = (rows.layout, rows.cols, panel.max(1));
    let n = lay.n;
    let tol = rows.singular_tol(comm);
    let lc = rows.ld();
    if n == 0 {
        return back_substitute(comm, rows, nb, Rows::Triangular, tol);
    }
    let (mut k, mut kb) = (0, nb.min(n));
    let taus = factor_panel(comm, &lay, &mut rows.data, lc, (k, kb), k, None);
    let mut wy = PanelWy::of(comm, &lay, &rows.data, lc, (k, kb), &taus, None);
    loop {
        let end = k + kb;
        let update = Update::of(comm, rows, &wy, cols, par);
        if end == n {
            update.apply(&mut rows.data, lc, 0, end, cols);
            progress(n, n);
            break;
        }
        let next = (end, nb.min(n - end));
        let split = end + next.1;
        let next_wy = if lookahead {
            // the next panel's columns first; the rest in the windows of its all-reduces
            let first = narrow_free(split.max(end + 2), cols);
            update.apply(&mut rows.data, lc, 0, end, first);
            let (left, right) = rows.data.split_at_mut(split * lc);
            let piece = (cols - split).div_ceil(next.1 + 1).max(MIN_PIECE);
            let mut from = first;
            let mut work = || {
                let to = narrow_free(from + piece, cols);
                update.apply(right, lc, split, from, to);
                from = to;
                from < cols
            };
            let taus = factor_panel(comm, &lay, left, lc, next, end, Some(&mut work));
            let wy = PanelWy::of(comm, &lay, left, lc, next, &taus, Some(&mut work));
            update.apply(right, lc, split, from, cols);
            wy
        } else {
            update.apply(&mut rows.data, lc, 0, end, cols);
            let taus = factor_panel(comm, &lay, &mut rows.data, lc, next, end, None);
            PanelWy::of(comm, &lay, &rows.data, lc, next, &taus, None)
        };
        wy = next_wy;
        progress(end, n);
        (k, kb) = next;
    }
    back_substitute(comm, rows, nb, Rows::Triangular, tol)
}

/// Rows of Y = V T^T per piece formed while W is summed (about half a millisecond each at a
/// panel of 192), so that the sum is tested, and so driven on, often.
const Y_PIECE: usize = 256;

/// The narrowest piece of a trailing update run in one window of an all-reduce of the next
/// panel (every piece reads all of V again; as in the LU).
const MIN_PIECE: usize = 256;

/// The end of a piece of columns of a trailing update that ends at `cols`, at least `to`: `cols`
/// where the piece would leave a single column, so that no piece is a matrix-vector product
/// (computed in another order than the same column of a wider product).
fn narrow_free(to: usize, cols: usize) -> usize {
    if to + 1 >= cols {
        cols
    } else {
        to
    }
}

/// The compact-WY form of a factored panel k..k+kb on this rank: V (this rank's rows k.., unit
/// lower trapezoidal, explicit, column-major) and T.
struct PanelWy {
    k: usize,
    kb: usize,
    /// The first of this rank's local rows at or below row k, and how many there are from it.
    r0: usize,
    mr: usize,
    v: Vec<f64>,
    t: faer::Mat<f64>,
}

impl PanelWy {
    /// V from the factored panel in `data` (column-major, leading dimension `ld`, from global
    /// column 0) and T from V^T V (dlarft, forward, column-wise), summed over the ranks with
    /// `work` run while the sum is in flight where there is some. Collective.
    fn of(
        comm: &dyn Comm,
        lay: &RowCyclic,
        data: &[f64],
        ld: usize,
        (k, kb): (usize, usize),
        taus: &[f64],
        work: Option<&mut dyn FnMut() -> bool>,
    ) -> Self {
        let r0 = lay.first_local_from(k);
        let mr = ld - r0;
        let mut v = vec![0.0; mr * kb];
        for c in 0..kb {
            for (t, l) in (r0..ld).enumerate() {
                let g = lay.global(l);
                v[t + c * mr] = match g.cmp(&(k + c)) {
                    std::cmp::Ordering::Less => 0.0,
                    std::cmp::Ordering::Equal => 1.0,
                    std::cmp::Ordering::Greater => data[l + (k + c) * ld],
                };
            }
        }
        let vref = MatRef::from_column_major_slice(&v, mr, kb);
        let mut vtv = vec![0.0; kb * kb];
        gemm(
            MatMut::from_column_major_slice_mut(&mut vtv, kb, kb),
            Accum::Replace,
            vref.transpose(),
            vref,
            1.0,
            Par::Seq,
        );
        sum_while(comm, &mut vtv, work, &mut Vec::new());
        let t = wy_t(taus, MatRef::from_column_major_slice(&vtv, kb, kb));
        PanelWy { k, kb, r0, mr, v, t }
    }

    fn v(&self) -> MatRef<'_, f64> {
        MatRef::from_column_major_slice(&self.v, self.mr, self.kb)
    }
}

/// The update of the trailing columns by a panel's Q^T = I - V T^T V^T, as A_trail -= Y W with
/// W = V^T A_trail summed over the ranks and Y = V T^T formed by each rank for its own rows of V
/// (while W is summed, [`Comm::sum_f64_while`]):
/// the same product as V (T^T W), but the kb x kb x rest product T^T W would be formed whole on
/// every rank (nb n^2 multiply-adds over a factorisation on each rank, whatever the rank count),
/// while Y costs a rank kb^2 times its own rows.
struct Update<'a> {
    wy: &'a PanelWy,
    c0: usize,
    /// Y = V T^T, this rank's rows (column-major, mr x kb).
    y: Vec<f64>,
    /// W, kb x (cols - c0), summed over the ranks: column-major, or stored as W^T (column-major,
    /// cols - c0 rows) with `transposed`.
    w: Vec<f64>,
    /// Whether `w` holds W^T: where the BLAS computes the products on every rank. It forms
    /// A_trail^T V, whose long side is the output's rows, at about 1.2 times the rate of
    /// V^T A_trail, where the kb output rows are the short side and the rank's rows the inner
    /// dimension (OpenBLAS on an AVX-512 core: 48-49 against 38-41 GFLOP/s at 8000 x 8000 x 192;
    /// the Householder solve on 8000 rows took 7 % less on 1 and 2 ranks), and reads W^T in
    /// the update at the rate of W. faer's products go the other way (the solve on 4000 rows
    /// took 14 % longer with W^T), so they keep W.
    transposed: bool,
    par: Par,
}

impl<'a> Update<'a> {
    /// Computes W from this rank's rows of the trailing columns (all updated by the earlier
    /// panels) and Y. Collective: one all-reduce of W.
    fn of(comm: &dyn Comm, rows: &LocalRows, wy: &'a PanelWy, cols: usize, par: Par) -> Self {
        let (kb, c0) = (wy.kb, wy.k + wy.kb);
        let rest = cols - c0;
        let mut w = vec![0.0; kb * rest];
        // the same on every rank: the ranks sum W as stored
        let transposed = by_blas_on_every_rank(par);
        {
            let a_trail = rows.view().submatrix(wy.r0, c0, wy.mr, rest);
            form_w(&mut w, wy.v(), a_trail, transposed, par);
        }
        // Y by pieces of rows while W is summed, testing the sum between them
        let mut y = vec![0.0; wy.mr * kb];
        {
            let mut ym = MatMut::from_column_major_slice_mut(&mut y, wy.mr, kb);
            let (v, tt) = (wy.v(), wy.t.as_ref().transpose());
            let mut from = 0;
            let mut work = || {
                let to = (from + Y_PIECE).min(wy.mr);
                if from < to {
                    let rows = ym.rb_mut().subrows_mut(from, to - from);
                    gemm(rows, Accum::Replace, v.subrows(from, to - from), tt, 1.0, par);
                }
                from = to;
                from < wy.mr
            };
            comm.sum_f64_while(&mut w, &mut work);
        }
        Update { wy, c0, y, w, transposed, par }
    }

    /// A_trail -= Y W on the global columns c0..c1 of this rank's rows in `data` (column-major,
    /// leading dimension `ld`, from global column `base`): one local GEMM.
    fn apply(&self, data: &mut [f64], ld: usize, base: usize, c0: usize, c1: usize) {
        let (r0, mr, kb) = (self.wy.r0, self.wy.mr, self.wy.kb);
        if c0 >= c1 || mr == 0 {
            return;
        }
        let all = MatMut::from_column_major_slice_mut(data, ld, data.len() / ld);
        let a = all.submatrix_mut(r0, c0 - base, mr, c1 - c0);
        let y = MatRef::from_column_major_slice(&self.y, mr, kb);
        let w = stored_w(&self.w, kb, self.transposed).subcols(c0 - self.c0, c1 - c0);
        gemm(a, Accum::Add, y, w, -1.0, self.par);
    }
}

/// W = V^T A_trail (kb x trailing columns, kb the columns of V) into `out`: column-major, or as
/// W^T (column-major, one row per trailing column) with `transposed` (see [`Update`]'s
/// `transposed`). The 2D Householder forms its W this way too.
pub(super) fn form_w(
    out: &mut [f64],
    v: MatRef<'_, f64>,
    a_trail: MatRef<'_, f64>,
    transposed: bool,
    par: Par,
) {
    let (kb, rest) = (v.ncols(), a_trail.ncols());
    if transposed {
        let wt = MatMut::from_column_major_slice_mut(out, rest, kb);
        gemm(wt, Accum::Replace, a_trail.transpose(), v, 1.0, par);
    } else {
        let w = MatMut::from_column_major_slice_mut(out, kb, rest);
        gemm(w, Accum::Replace, v.transpose(), a_trail, 1.0, par);
    }
}

/// The kb-row matrix stored in `buf` as [`form_w`] stores W: itself, or its transpose with
/// `transposed`.
pub(super) fn stored_w(buf: &[f64], kb: usize, transposed: bool) -> MatRef<'_, f64> {
    let cols = buf.len() / kb.max(1);
    if transposed {
        MatRef::from_column_major_slice(buf, cols, kb).transpose()
    } else {
        MatRef::from_column_major_slice(buf, kb, cols)
    }
}

/// Sums `buf` over the ranks in place: one all-reduce, or with `work`, a non-blocking all-gather
/// with `work` run while it is in flight and the sum taken in rank order (the same on every
/// rank). `recv` is scratch. Collective; every rank passes `work` or none alike.
fn sum_while(
    comm: &dyn Comm,
    buf: &mut [f64],
    work: Option<&mut (dyn FnMut() -> bool + '_)>,
    recv: &mut Vec<f64>,
) {
    let Some(work) = work else {
        comm.sum_f64(buf);
        return;
    };
    let (len, p) = (buf.len(), comm.size());
    recv.clear();
    recv.resize(len * p, 0.0);
    comm.all_gather_f64_while(buf, &vec![len; p], recv, work);
    for (i, b) in buf.iter_mut().enumerate() {
        *b = recv[i];
        for r in 1..p {
            *b += recv[r * len + i];
        }
    }
}

/// Panels at most this wide are factored column by column; wider ones are split in two halves
/// ([`factor_panel`]).
const LEAF: usize = 16;

/// Householder QR of the panel columns k..k+kb (rows k..n) of a column-major local matrix
/// (leading dimension `ld`, the local row count) whose rows are spread over `comm` as `rows`
/// says, global column k at local column `lc0`: the row-cyclic layout over all ranks, or one
/// process column of the 2D layout. Recursive, as LAPACK's dgeqrt3: the left half is factored,
/// its reflectors are applied to the right half in compact-WY form (I - V T^T V^T, the sums
/// V^T V and V^T A_right in one all-reduce, the update one GEMM), then the right half is
/// factored; panels of at most [`LEAF`] columns column by column ([`factor_columns`]). So the
/// work of a wide panel is mostly BLAS-3, where column by column it is all matrix-vector work
/// and grows with the panel's width. With `work`, the all-reduces are non-blocking and `work`
/// runs while each is in flight (see [`sum_while`]). Returns the tau of each reflector
/// H = I - tau v v^T (v(0) = 1, its tail stored below the diagonal; R on and above it).
pub(super) fn factor_panel(
    comm: &dyn Comm,
    rows: &dyn RowIndex,
    data: &mut [f64],
    ld: usize,
    (k, kb): (usize, usize),
    lc0: usize,
    mut work: Option<&mut (dyn FnMut() -> bool + '_)>,
) -> Vec<f64> {
    if kb <= LEAF {
        return factor_columns(comm, rows, data, ld, (k, kb), lc0, work);
    }
    let h = (kb / 2).div_ceil(LEAF) * LEAF;
    let mut taus = factor_panel(comm, rows, data, ld, (k, h), lc0, work.as_deref_mut());
    apply_left_half(comm, rows, data, ld, (k, h, kb), lc0, &taus, work.as_deref_mut());
    taus.extend(factor_panel(comm, rows, data, ld, (k + h, kb - h), lc0 + h, work));
    taus
}

/// Applies the reflectors of the factored columns k..k+h (taus `taus`) to the panel columns
/// k+h..k+kb of the same rows: A_right <- (I - V T^T V^T) A_right over rows k..n. Collective
/// over `comm` (one all-reduce of V^T V and V^T A_right).
#[allow(clippy::too_many_arguments)]
fn apply_left_half(
    comm: &dyn Comm,
    rows: &dyn RowIndex,
    data: &mut [f64],
    ld: usize,
    (k, h, kb): (usize, usize, usize),
    lc0: usize,
    taus: &[f64],
    work: Option<&mut (dyn FnMut() -> bool + '_)>,
) {
    let w = kb - h;
    let r0 = rows.first_local_from(k);
    let mr = ld - r0;
    // V explicit: zeros above the diagonal, one on it (the diagonal row is the first local row at
    // or below it, on its owner)
    let me = comm.rank();
    let mut v = vec![0.0; mr * h];
    for c in 0..h {
        let d = rows.first_local_from(k + c);
        let col = &data[(lc0 + c) * ld..(lc0 + c + 1) * ld];
        for l in d..ld {
            v[l - r0 + c * mr] = col[l];
        }
        if rows.owner(k + c) == me && d < ld {
            v[d - r0 + c * mr] = 1.0;
        }
    }
    let vref = MatRef::from_column_major_slice(&v, mr, h);
    // [V^T V | V^T A_right], h x (h + w), summed over the ranks at once
    let mut sums = vec![0.0; h * (h + w)];
    {
        let (gram, wsum) = sums.split_at_mut(h * h);
        gemm(
            MatMut::from_column_major_slice_mut(gram, h, h),
            Accum::Replace,
            vref.transpose(),
            vref,
            1.0,
            Par::Seq,
        );
        let right = MatRef::from_column_major_slice_with_stride(&data[(lc0 + h) * ld + r0..], mr, w, ld);
        gemm(
            MatMut::from_column_major_slice_mut(wsum, h, w),
            Accum::Replace,
            vref.transpose(),
            right,
            1.0,
            Par::Seq,
        );
    }
    sum_while(comm, &mut sums, work, &mut Vec::new());
    let t = wy_t(taus, MatRef::from_column_major_slice(&sums[..h * h], h, h));
    let mut tw = faer::Mat::<f64>::zeros(h, w);
    gemm(
        tw.as_mut(),
        Accum::Replace,
        t.as_ref().transpose(),
        MatRef::from_column_major_slice(&sums[h * h..], h, w),
        1.0,
        Par::Seq,
    );
    if mr > 0 {
        let right =
            MatMut::from_column_major_slice_with_stride_mut(&mut data[(lc0 + h) * ld + r0..], mr, w, ld);
        gemm(right, Accum::Add, vref, tw.as_ref(), -1.0, Par::Seq);
    }
}

/// Unblocked Householder QR of the panel columns k..k+kb, column by column ([`factor_panel`]'s
/// leaves): one all-reduce per column.
fn factor_columns(
    comm: &dyn Comm,
    rows: &dyn RowIndex,
    data: &mut [f64],
    ld: usize,
    (k, kb): (usize, usize),
    lc0: usize,
    mut work: Option<&mut (dyn FnMut() -> bool + '_)>,
) -> Vec<f64> {
    let me = comm.rank();
    let mut recv = Vec::new();
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
        sum_while(comm, s, work.as_deref_mut(), &mut recv);
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
