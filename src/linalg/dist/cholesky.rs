//! Projected Cholesky for the bordered spline system: half of LU's flops (1/3 n^3), for the
//! systems whose kernel makes the projected block definite (all the polyharmonic ones).
//!
//! # Reduction to a definite system
//!
//! The system is [A P; P^T 0] [lambda; c] = [r; 0] with A = (G(|x_i - x_j|)) (N x N, symmetric)
//! and P = (p_j(x_i)) (N x k) of full column rank k. Let P = Q [R; 0] be its Householder QR,
//! Q = H_1 ... H_k = [Q1 Q2] with Q1 of k columns and Q2 of N - k, R upper triangular k x k and
//! invertible. The columns of Q2 are an orthonormal basis of the null space of P^T
//! (P^T = R^T Q1^T, and Q1^T Q2 = 0), so the second block row, P^T lambda = 0, says exactly
//! lambda = Q2 mu for one mu in R^(N-k). Put into the first block row, A Q2 mu + Q1 R c = r;
//! multiplied by Q2^T and by Q1^T it splits into
//!
//! ```text
//!     B mu = Q2^T r,   B = Q2^T A Q2 ((N-k) x (N-k)),      R c = Q1^T (r - A lambda).
//! ```
//!
//! B is definite. The kernel is conditionally definite of order m: there is a sign s = +-1 with
//! s lambda^T A lambda > 0 for every lambda != 0 that annihilates the polynomials of degree < m
//! (P^T lambda = 0), at distinct points. Since Q2 has orthonormal columns, lambda = Q2 mu is such
//! a vector for every mu != 0, and mu^T B mu = lambda^T A lambda, so s B is positive definite.
//! The sign is the kernel's: G = r (3D, m = 2) and r^4 ln r (2D, m = 3) give s = -1, G = r^3
//! (3D, m = 3) and r^2 ln r (2D, m = 2) give s = +1; in general (-1)^ceil(b/2) r^b for odd b and
//! (-1)^(j+1) r^(2j) ln r are conditionally positive definite of order q = ceil(b/2) resp. j + 1,
//! with q <= m here; a form definite on the vectors that annihilate the polynomials of degree < q
//! stays definite on those that annihilate the larger space of degree < m. Since every
//! diagonal entry of s B is positive, the solver reads s off the first diagonal entry of B and
//! factors s B = L L^T. If a pivot is not positive after all (rounding, near-duplicate points),
//! it returns `Error::NotDefinite` and the caller falls back to LU.
//!
//! # Work on the ranks
//!
//! Q is never formed. Every rank gathers P^T (k rows), factors it serially and applies
//! Q = I - V T V^T (compact WY) to both sides of its own rows of A and to r, in two passes:
//! X = A V, then the symmetric rank-2k update Q^T A Q = A - Y V^T - V Y^T with
//! Y = X T - V T^T (V^T X) T / 2 (expand (I - V T^T V^T) A (I - V T V^T) to check); the
//! right-hand side becomes Q^T r = [Q1^T r; Q2^T r]. Rows and columns k..N of the result are B;
//! rows 0..k, columns k..N are Q1^T A Q2, so Q1^T A lambda = (Q1^T A Q2) mu is read off the
//! owners of those rows and R c = Q1^T r - (Q1^T A Q2) mu is a k x k triangular solve. B is
//! factored by a blocked, right-looking, row-cyclic Cholesky that only updates the lower
//! triangle (L11 L11^T = B11, L21 = B21 L11^-T, B22 <- B22 - L21 L21^T); the update runs by
//! blocks of columns, so the block of L21^T that a GEMM reads stays in cache while the rank's
//! rows below the diagonal stream past it (a row chunk against all trailing columns would read
//! all of L21^T from memory for every chunk). The forward substitution L z = s Q2^T r rides
//! along: each panel's block of the right-hand side is gathered with its diagonal block,
//! z1 = L11^-1 y1 is solved on every rank, and each rank takes y2 -= L21 z1 in its rows while its
//! L21 is fresh from the panel's solve. Back substitution gives mu, and lambda = Q [0; mu] applies
//! the k reflectors to a vector, last one first.
//!
//! What is read of A: its lower triangle and its first k rows. X = A V takes each entry below
//! the diagonal twice, as itself and as its mirror image (see [`symmetric_times`]), the rank-2k
//! update writes only the blocks the factorisation and the solves read (rows 0..k, the lower
//! triangle, [`projected_blocks`]), and the factorisation and the substitutions read only L. So
//! a fit assembles only those entries (`crate::app::fit::assemble_lower`): about half the kernel
//! evaluations, and the pages of the rest of the upper triangle are never touched (on the
//! bunny's 8000 points on 2 ranks the assembly took 0.11 s instead of 0.18-0.19 s, the peak
//! memory per rank was 271 MB instead of 362 MB in f64 and 332 MB instead of 429 MB in mixed
//! precision, and X = A V took 0.016 s, as the product of whole rows did). A fallback to LU
//! assembles the whole matrix again.
//!
//! Look-ahead: every rank holds rows of every panel, so every rank prepares the next panel
//! itself. With `job.lookahead`, once L21 of panel k is on every rank, each rank updates the
//! columns of panel k+1 in its rows first, then gathers panel k+1's diagonal block, factors it,
//! solves for its L21 and all-gathers that, both gathers non-blocking
//! ([`Comm::all_gather_f64_while`]), while the rest of panel k's update runs a GEMM at a time
//! between the tests; what is left runs before panel k+1's own update. Exact: panel k+1 reads
//! and writes only its own columns, which are updated before it, and both orders run the same
//! GEMMs on the same pieces: the factors are the same, bit for bit in the tests on two and three
//! ranks.

use std::rc::Rc;

use crate::linalg::gemm::{gemm, solve_lower};
use faer::reborrow::{Reborrow, ReborrowMut};
use faer::{Accum, Mat, MatMut, MatRef, Par};

use super::layout::RowCyclic;
use super::scalar::{products_widened, update_widened, Scalar};
use super::solver::Job;
use super::system::{all_gather_packed_while, all_gather_rows, GatherBuffers, LocalRows};
use crate::error::{Error, Result};
use crate::linalg::reflector::{apply, explicit_v, qr_in_place, wy_t};
use crate::par::Comm;

/// Local rows of the smallest GEMMs of the trailing update where a column block meets the
/// diagonal ([`triangle_pieces`]): small enough that the triangle is followed closely (a piece
/// computes the entries above the diagonal of its last row too, half of its flops wasted),
/// large enough for BLAS-3 speed. The halving of a 1024-row block stops at 32 rows (64 with a
/// bound of 96): at N+k = 8000 the leaves took 0.07 s instead of 0.13-0.15 s per rank on two
/// ranks and one, at 25-30 GFLOP/s either way, and the rest of the update did not slow down.
const ROW_CHUNK: usize = 48;

/// Columns of each rank's part of L21^T per block of the trailing update (a block spans this
/// many times the number of ranks columns, every rank's share a GEMM of its own): the part a GEMM
/// reads (panel x 1024, 3 MB at the default panel of 384) stays in the shared cache while the
/// rows below the diagonal stream past it, where a chunk of rows against all trailing columns
/// streams all of L21^T from memory. At N+k = 8000 on 2 ranks 1024 is 1-2 % faster than 512;
/// on one rank they are equal.
const COL_BLOCK: usize = 1024;

/// Local rows per GEMM below the diagonal block: pieces of a few milliseconds, so the
/// non-blocking gathers of the look-ahead are tested often.
const ROW_BLOCK: usize = 1024;

/// Columns per group of the product of the symmetric A with the reflectors ([`symmetric_times`]):
/// the group's pieces below it (4 x 8 bytes a row, 128 KB at 4000 local rows) stay in cache
/// for the 2k passes over them.
const SYMMETRIC_GROUP: usize = 4;

/// Columns per GEMM of the projection Q^T A Q: narrow enough that its blocks follow the
/// diagonal closely (only the lower triangle is projected).
const COL_CHUNK: usize = 64;

/// Solves the bordered system in `rows` (its polynomial border of width `rows.border` >= 1 and
/// its right-hand side as the last column). Returns the solution on every rank, or
/// `Error::NotDefinite` (on every rank) when a pivot of B is not positive, in which case the
/// caller should fall back to LU on a freshly assembled system: `rows` is overwritten. `par` is
/// the parallelism of the local GEMMs and triangular solves.
pub fn cholesky_solve(job: &Job<'_>, rows: &mut LocalRows) -> Result<Vec<f64>> {
    factor_and_solve(job, rows).map(|(x, _, _)| x)
}

/// [`cholesky_solve`], which also returns the QR of the border and the sign s of the factored
/// block (s B = L L^T): with the rows, what [`super::extend`] needs to border the factor.
pub(super) fn factor_and_solve(job: &Job<'_>, rows: &mut LocalRows) -> Result<(Vec<f64>, Border, f64)> {
    let Job { comm, panel, par, .. } = *job;
    let lay = rows.layout;
    let border = Border::new(comm, rows)?;
    let (k, n) = (border.k, border.n);
    let nb = panel.max(1);
    let ld = rows.ld();
    let rhs = rows.cols - 1;
    let la = lay.first_local_from(n); // this rank's rows of A are local 0..la
    let r = border.r();

    let (left, right) = border.projection(comm, rows);
    for (c0, w, a, b) in projected_blocks(lay, k, n) {
        let block =
            MatMut::from_column_major_slice_with_stride_mut(&mut rows.data[c0 * ld + a..], b - a, w, ld);
        let l = left.as_ref().subrows(a, b - a);
        gemm(block, Accum::Add, l, right.as_ref().subcols(c0, w), -1.0, par);
    }
    border.project_rhs(comm, rows);
    let sign = factor_projected(job, rows, k, n, None)?;

    // the factorisation left z = L^-1 y in rows k..n of the right-hand side
    let b0 = lay.first_local_from(k);
    let mut z = vec![0.0; k];
    z.extend(all_gather_rows(comm, lay, &rows.data[rhs * ld + b0..rhs * ld + la], k..n, 1));
    let mu = back_substitute(comm, rows, (k, n), nb, &z);

    // lambda = Q [0; mu]
    let mut lambda = mu.clone();
    lambda[..k].iter_mut().for_each(|x| *x = 0.0);
    border.q(&mut lambda);
    // R c = (Q^T r)_1 - (Q^T A Q)[0..k, k..n] mu, from the owners of rows 0..k
    let mut t = vec![0.0; k];
    for i in 0..k {
        if lay.owner(i) == lay.rank {
            let l = lay.local(i);
            t[i] = rows.get(l, rhs) - (k..n).map(|j| rows.get(l, j) * mu[j]).sum::<f64>();
        }
    }
    comm.sum_f64(&mut t);
    let mut c = vec![0.0; k];
    for i in (0..k).rev() {
        let s: f64 = (i + 1..k).map(|j| r[(i, j)] * c[j]).sum();
        c[i] = (t[i] - s) / r[(i, i)];
    }
    lambda.extend(c);
    Ok((lambda, border, sign))
}

/// mu with L^T mu = z in entries k..n (entries 0..k zero), L the factor of the projected block
/// in rows and columns k..n of `rows` ([`factor_projected`]), z replicated; the panels are nb
/// wide. Collective; mu on every rank.
pub(super) fn back_substitute(
    comm: &dyn Comm,
    rows: &LocalRows,
    (k, n): (usize, usize),
    nb: usize,
    z: &[f64],
) -> Vec<f64> {
    let lay = rows.layout;
    let (ld, la) = (rows.ld(), lay.first_local_from(n));
    let mut mu = vec![0.0; n];
    // this rank's entries of mu in local order, as they become final, for contiguous products
    let mut mine = vec![0.0; la];
    let mut q1 = n;
    while q1 > k {
        let q0 = q1.saturating_sub(nb).max(k);
        let bs = q1 - q0;
        let u0 = lay.first_local_from(q1);
        let col = |c: usize| &rows.data[c * ld + u0..c * ld + la];
        let mut sums = products_widened((q0, q1), &mine[u0..], col);
        comm.sum_f64(&mut sums);
        let d = rows.gather_rows(comm, q0, q1, q0, q1);
        for i in (0..bs).rev() {
            let s: f64 = (i + 1..bs).map(|j| d[j * bs + i] * mu[q0 + j]).sum();
            mu[q0 + i] = (z[q0 + i] - sums[i] - s) / d[i * bs + i];
        }
        for l in lay.first_local_from(q0)..u0 {
            mine[l] = mu[lay.global(l)];
        }
        q1 = q0;
    }
    mu
}

/// The columns mu_j with L^T mu_j = z_j, as [`back_substitute`] gives each, for all columns of
/// `z` (n x c, replicated) in one pass over L: the products of a panel's rows with the finished
/// entries below it are one matrix product of c columns, so L is read once for all of them, not
/// once per column. Collective; the columns (n x c) on every rank.
pub(super) fn back_substitute_many(
    job: &Job<'_>,
    rows: &LocalRows,
    (k, n): (usize, usize),
    (nb, diagonal): (usize, &dyn Fn(usize, usize) -> Rc<Mat<f64>>),
    z: MatRef<'_, f64>,
) -> Mat<f64> {
    let Job { comm, par, .. } = *job;
    let lay = rows.layout;
    let la = lay.first_local_from(n);
    let c = z.ncols();
    let mut mu = Mat::<f64>::zeros(n, c);
    // this rank's rows of mu in local order, as they become final, for contiguous products
    let mut mine = Mat::<f64>::zeros(la, c);
    let mut q1 = n;
    while q1 > k {
        let q0 = q1.saturating_sub(nb).max(k);
        let bs = q1 - q0;
        let u0 = lay.first_local_from(q1);
        let mut sums = Mat::<f64>::zeros(bs, c);
        if u0 < la {
            let below = rows.view().submatrix(u0, q0, la - u0, bs);
            gemm(
                sums.as_mut(),
                Accum::Replace,
                below.transpose(),
                mine.as_ref().subrows(u0, la - u0),
                1.0,
                par,
            );
        }
        let mut buf: Vec<f64> = (0..bs * c).map(|q| sums[(q % bs, q / bs)]).collect();
        comm.sum_f64(&mut buf);
        let d = diagonal(q0, q1);
        for j in 0..c {
            for i in (0..bs).rev() {
                let s: f64 = (i + 1..bs).map(|t| d[(t, i)] * mu[(q0 + t, j)]).sum();
                mu[(q0 + i, j)] = (z[(q0 + i, j)] - buf[j * bs + i] - s) / d[(i, i)];
            }
        }
        for l in lay.first_local_from(q0)..u0 {
            let g = lay.global(l);
            (0..c).for_each(|j| mine[(l, j)] = mu[(g, j)]);
        }
        q1 = q0;
    }
    mu
}

/// The Householder QR P = Q [R; 0] of the polynomial block, on every rank: R above the diagonal
/// of the first k columns of `qr` (column-major, n rows), the tails of the reflectors below.
pub(super) struct Border {
    pub k: usize,
    /// The number of centres (rows of A).
    pub n: usize,
    qr: Vec<f64>,
    taus: Vec<f64>,
}

impl Border {
    /// Gathers P^T (the border rows, row-major, which is P column-major) and factors it.
    /// Collective; the errors are the same on every rank.
    pub fn new<T: Scalar>(comm: &dyn Comm, rows: &LocalRows<T>) -> Result<Border> {
        let k = rows.border;
        let n = rows.layout.n - k;
        assert!(k >= 1, "the projected Cholesky needs a polynomial border");
        let qr: Vec<f64> = rows.gather_rows(comm, n, n + k, 0, n).iter().map(|v| v.f64()).collect();
        Border::of(qr, n, k)
    }

    /// The QR of P, given column-major (n x k) on this rank.
    pub fn of(mut qr: Vec<f64>, n: usize, k: usize) -> Result<Border> {
        if n <= k {
            return Err(Error::NotDefinite(format!("{n} centres leave no definite block")));
        }
        let taus = qr_in_place(&mut qr, n, k);
        let border = Border { k, n, qr, taus };
        let r = border.r();
        if (0..k).any(|j| !(r[(j, j)].abs() > 0.0)) {
            return Err(Error::Numerical(format!(
                "the polynomial block has rank < {k}: points not unisolvent"
            )));
        }
        Ok(border)
    }

    /// Q = I - V T V^T: the reflectors as explicit columns (n x k, unit diagonal) and T.
    pub fn wy(&self) -> (Mat<f64>, Mat<f64>) {
        let v = explicit_v(MatRef::from_column_major_slice(&self.qr, self.n, self.k), self.k);
        let t = wy_t(&self.taus, (v.transpose() * &v).as_ref());
        (v, t)
    }

    /// R (the upper triangle of the k x k block; the strict lower triangle holds reflectors).
    pub fn r(&self) -> MatRef<'_, f64> {
        MatRef::from_column_major_slice(&self.qr, self.n, self.k).subrows(0, self.k)
    }

    /// y <- H_j y for y = the entries j..n of a vector.
    pub fn reflect(&self, j: usize, y: &mut [f64]) {
        apply(self.taus[j], &self.qr[j * self.n + j + 1..(j + 1) * self.n], y);
    }

    /// Q^T y for a replicated vector y of length n.
    pub fn q_transpose(&self, y: &mut [f64]) {
        for j in 0..self.k {
            self.reflect(j, &mut y[j..]);
        }
    }

    /// Q y for a replicated vector y of length n.
    pub fn q(&self, y: &mut [f64]) {
        for j in (0..self.k).rev() {
            self.reflect(j, &mut y[j..]);
        }
    }

    /// The factors of Q^T A Q = A - [Y V] [V^T; Y^T] for this rank's rows of A (`left`, local
    /// rows x 2k) and all columns (`right`, 2k x n), with Q = H_1 ... H_k = I - V T V^T: X = A V
    /// (A is symmetric, so V^T A = X^T; [`symmetric_times`] reads its lower triangle alone) and
    /// Y = X T - V T^T (V^T X) T / 2. One sum of X (n x k) over the ranks. Reads `rows`, changes
    /// nothing.
    pub fn projection(&self, comm: &dyn Comm, rows: &LocalRows) -> (Mat<f64>, Mat<f64>) {
        let (k, n) = (self.k, self.n);
        let lay = rows.layout;
        let la = lay.first_local_from(n);
        let (v, t) = self.wy();
        let x = symmetric_times(comm, rows, &v);
        let z = v.transpose() * &x;
        let y = &x * &t - (&v * (t.transpose() * &z * &t)) * 0.5;
        let left = Mat::<f64>::from_fn(la, 2 * k, |l, j| {
            let g = lay.global(l);
            if j < k {
                y[(g, j)]
            } else {
                v[(g, j - k)]
            }
        });
        let right = Mat::<f64>::from_fn(2 * k, n, |j, c| if j < k { v[(c, j)] } else { y[(c, j - k)] });
        (left, right)
    }

    /// y <- Q^T y on the right-hand side column of `rows` (rows 0..n). Collective.
    pub fn project_rhs(&self, comm: &dyn Comm, rows: &mut LocalRows) {
        let lay = rows.layout;
        let (ld, rhs) = (rows.ld(), rows.cols - 1);
        let la = lay.first_local_from(self.n);
        let mut y = all_gather_rows(comm, lay, &rows.data[rhs * ld..rhs * ld + la], 0..self.n, 1);
        self.q_transpose(&mut y);
        for l in 0..la {
            rows.data[rhs * ld + l] = y[lay.global(l)];
        }
    }
}

/// A V on every rank (n x k) for the symmetric n x n block A of `rows` and a replicated V, from
/// the lower triangle of A alone (with the diagonal): an entry a_gc below the diagonal stands for
/// itself in row g and for a_cg in row c, so this rank adds a_gc v_c to row g of the product and
/// a_gc v_g to row c, and one sum over the ranks completes every row. [`SYMMETRIC_GROUP`] columns
/// at a time: the rows below the group take both sums for each column of V while the group's
/// pieces of its columns are in cache (the widened multiply-adds of the f32 solves), the few rows
/// whose diagonal lies in the group entry by entry up to it. The matrix is read from memory once,
/// half of it, where a product of whole rows reads all of it. Collective.
fn symmetric_times(comm: &dyn Comm, rows: &LocalRows, v: &Mat<f64>) -> Mat<f64> {
    let (n, k) = (v.nrows(), v.ncols());
    let lay = rows.layout;
    let globals: Vec<usize> = (0..lay.first_local_from(n)).map(|l| lay.global(l)).collect();
    let columns: Vec<usize> = (0..n).collect();
    let mut sum = lower_times_part(&rows.data, rows.ld(), (&globals, &columns), v);
    comm.sum_f64(&mut sum);
    Mat::from_fn(n, k, |i, j| sum[j * n + i])
}

/// This rank's part of X = A V (n x k, column-major) for a symmetric n x n matrix A of which it
/// holds the entries at its local rows and columns (`rows`, `cols`: their global indices,
/// ascending, all below n), column-major in `data` with leading dimension `ld`, and a replicated
/// V: the sum over the ranks of these parts is A V. Only the entries on and below the diagonal
/// are read (the rest may hold anything), by the rule of [`symmetric_times`], [`SYMMETRIC_GROUP`]
/// local columns at a time; any distribution of the rows and columns works (the row-cyclic rows
/// with every column, or the blocks of a 2D grid).
pub(super) fn lower_times_part(
    data: &[f64],
    ld: usize,
    (rows, cols): (&[usize], &[usize]),
    v: &Mat<f64>,
) -> Vec<f64> {
    let (n, k) = (v.nrows(), v.ncols());
    let la = rows.len();
    let col = |c: usize| &data[c * ld..c * ld + la];
    // the columns of V, negated (the updates subtract), at this rank's columns and at its rows
    let minus_v: Vec<Vec<f64>> = (0..k).map(|j| cols.iter().map(|&c| -v[(c, j)]).collect()).collect();
    let v_loc: Vec<Vec<f64>> = (0..k).map(|j| rows.iter().map(|&g| v[(g, j)]).collect()).collect();
    // own: this rank's rows up to their diagonal; across: the transposed entries, by local column
    let mut own = vec![vec![0.0; la]; k];
    let mut across = vec![vec![0.0; cols.len()]; k];
    for c0 in (0..cols.len()).step_by(SYMMETRIC_GROUP) {
        let c1 = (c0 + SYMMETRIC_GROUP).min(cols.len());
        // the rows whose diagonal lies in the group, then those below all of it
        let r0 = rows.partition_point(|&g| g < cols[c0]);
        let r1 = rows.partition_point(|&g| g <= cols[c1 - 1]);
        for l in r0..r1 {
            let g = rows[l];
            for c in (c0..c1).take_while(|&c| cols[c] <= g) {
                let entry = col(c)[l];
                for j in 0..k {
                    own[j][l] -= entry * minus_v[j][c];
                    if cols[c] < g {
                        across[j][c] += entry * v_loc[j][l];
                    }
                }
            }
        }
        if r1 < la {
            let below = |c: usize| &col(c)[r1..];
            for j in 0..k {
                update_widened(&mut own[j][r1..], (c0, c1), &minus_v[j][c0..c1], below);
                let sums = products_widened((c0, c1), &v_loc[j][r1..], below);
                across[j][c0..c1].iter_mut().zip(sums).for_each(|(a, s)| *a += s);
            }
        }
    }
    let mut sum = vec![0.0; n * k];
    for (j, (across, own)) in across.iter().zip(&own).enumerate() {
        let out = &mut sum[j * n..(j + 1) * n];
        across.iter().zip(cols).for_each(|(a, &c)| out[c] += a);
        own.iter().zip(rows).for_each(|(o, &g)| out[g] += o);
    }
    sum
}

/// The blocks of Q^T A Q that the factorisation and the solves with it read, as (c0, w, a, b):
/// columns c0..c0 + w, this rank's local rows a..b. For the columns 0..k every row; for the
/// columns k..n the rows 0..k and the lower triangle, from the first diagonal row of each block
/// of [`COL_CHUNK`] columns down. The rest of the upper triangle is never read, so the projection
/// leaves it as it was: half the flops of the rank-2k update, and in a freshly allocated f32 copy
/// most of the upper triangle's pages are never touched (at N = 8000 on one rank the first touch
/// of every page took 0.08 s of the 0.14 s of a projection that wrote every entry).
fn projected_blocks(lay: RowCyclic, k: usize, n: usize) -> Vec<(usize, usize, usize, usize)> {
    let (la, top) = (lay.first_local_from(n), lay.first_local_from(k));
    let mut blocks = Vec::new();
    for c0 in (0..n).step_by(COL_CHUNK) {
        let w = COL_CHUNK.min(n - c0);
        let below = if c0 < k { 0 } else { lay.first_local_from(c0).max(top) };
        if below <= top {
            blocks.push((c0, w, 0, la));
        } else {
            blocks.extend([(c0, w, 0, top), (c0, w, below, la)]);
        }
    }
    blocks.retain(|&(_, _, a, b)| b > a);
    blocks
}

/// Writes the projection Q^T A Q of the f64 rows `src` (`left`, `right` from
/// [`Border::projection`]) into `dst`, rounded to its type: the blocks of
/// [`projected_blocks`] but for the rows 0..k, which the solves take in f64 from
/// [`projected_top`] (in every column of a fresh copy they would touch a page the factorisation
/// never reads); the rest left as it was. The border rows and columns are rounded as they are;
/// the right-hand side is not projected.
pub(super) fn project_into<T: Scalar>(
    src: &LocalRows,
    dst: &mut LocalRows<T>,
    (left, right): (&Mat<f64>, &Mat<f64>),
    par: Par,
) {
    let n = right.ncols();
    let ld = src.ld();
    let la = left.nrows();
    let k = left.ncols() / 2;
    let top = src.layout.first_local_from(k);
    let mut tmp = vec![0.0f64; la * COL_CHUNK.min(n)];
    let blocks = projected_blocks(src.layout, k, n).into_iter().map(|(c0, w, a, b)| (c0, w, a.max(top), b));
    for (c0, w, a, b) in blocks.filter(|&(_, _, a, b)| b > a) {
        let h = b - a;
        let t = &mut tmp[..h * w];
        for c in 0..w {
            let col = (c0 + c) * ld;
            t[c * h..(c + 1) * h].copy_from_slice(&src.data[col + a..col + b]);
        }
        let tm = MatMut::from_column_major_slice_mut(t, h, w);
        let l = left.as_ref().subrows(a, h);
        gemm(tm, Accum::Add, l, right.as_ref().subcols(c0, w), -1.0, par);
        for c in 0..w {
            let col = (c0 + c) * ld;
            let to = &mut dst.data[col + a..col + b];
            to.iter_mut().zip(&t[c * h..(c + 1) * h]).for_each(|(d, v)| *d = T::of(*v));
        }
    }
    // the border rows of every column, and the border and right-hand side columns
    for c in 0..n {
        for l in la..ld {
            dst.data[c * ld + l] = T::of(src.data[c * ld + l]);
        }
    }
    for (d, s) in dst.data[n * ld..].iter_mut().zip(&src.data[n * ld..]) {
        *d = T::of(*s);
    }
}

/// Rows 0..k of the projection Q^T A Q (k x n, row-major) on every rank, in f64, from the f64
/// rows `src` (`left`, `right` from [`Border::projection`]): the owners of those rows compute
/// theirs, one all-gather. Collective.
pub(super) fn projected_top(
    comm: &dyn Comm,
    src: &LocalRows,
    (left, right): (&Mat<f64>, &Mat<f64>),
) -> Vec<f64> {
    let (n, k) = (right.ncols(), left.ncols() / 2);
    let lay = src.layout;
    let (ld, top) = (src.ld(), lay.first_local_from(k));
    let mut t = Mat::<f64>::from_fn(top, n, |l, c| src.data[c * ld + l]);
    gemm(t.as_mut(), Accum::Add, left.as_ref().subrows(0, top), right.as_ref(), -1.0, Par::Seq);
    let send: Vec<f64> = (0..top).flat_map(|l| (0..n).map(move |c| (l, c))).map(|(l, c)| t[(l, c)]).collect();
    all_gather_rows(comm, lay, &send, 0..k, n)
}

/// Factors the projected block B (rows and columns k..n of `rows`, which hold Q^T A Q) in place:
/// reads the sign s off its first diagonal entry, negates the lower triangle of B and rows k..n
/// of the right-hand side when s < 0, and overwrites the lower triangle with L, s B = L L^T, the
/// strict upper triangle of the diagonal blocks with zeros (the rest of the upper triangle is
/// neither read nor written), and rows k..n of the right-hand side y with z = L^-1 y (the forward
/// substitution rides along: each panel's block of y is gathered with its diagonal block, solved
/// with L11, and the rows below take their L21 z1 while L21 is fresh). Returns s; with `diag`, the
/// diagonal blocks L11 of the panels are pushed there in order (every rank has them). Collective;
/// `Error::NotDefinite` when a pivot is not positive (on every rank that reached it: callers
/// agree on the outcome).
pub(super) fn factor_projected<T: Scalar>(
    job: &Job<'_>,
    rows: &mut LocalRows<T>,
    k: usize,
    n: usize,
    mut diag: Option<&mut Vec<Mat<T>>>,
) -> Result<f64> {
    let Job { comm, panel, par, progress, lookahead } = *job;
    let lay = rows.layout;
    let nb = panel.max(1);
    let ld = rows.ld();
    let rhs = rows.cols - 1;
    let la = lay.first_local_from(n);
    // B = rows/columns k..n: make it positive definite (sign of any diagonal entry)
    let mut d0 = [if lay.owner(k) == lay.rank { rows.get(lay.local(k), k).f64() } else { 0.0 }];
    comm.broadcast_f64(lay.owner(k), &mut d0);
    let sign = if d0[0] < 0.0 { -1.0 } else { 1.0 };
    let b0 = lay.first_local_from(k);
    if sign < 0.0 {
        // the lower triangle, all the factorisation reads
        for c in k..n {
            let from = lay.first_local_from(c).max(b0);
            rows.data[c * ld + from..c * ld + la].iter_mut().for_each(|a| *a = -*a);
        }
        rows.data[rhs * ld + b0..rhs * ld + la].iter_mut().for_each(|a| *a = -*a);
    }

    // the diagonal blocks, where the caller keeps them
    let mut keep = |l11: Mat<T>| {
        if let Some(d) = diag.as_deref_mut() {
            d.push(l11);
        }
    };

    // blocked right-looking Cholesky of B, lower triangle, in place
    // (on one rank there are no messages to overlap with)
    let lookahead = lookahead && comm.size() > 1;
    let (mut bufs, mut next_bufs) = (GatherBuffers::default(), GatherBuffers::default());
    // the diagonal blocks' gathers, reused: a fresh buffer of a megabyte a panel costs its page
    // faults every time
    let mut diag_bufs = GatherBuffers::default();
    let (mut p0, mut pb) = (k, nb.min(n - k));
    {
        let (mat, y) = rows.data.split_at_mut(n * ld);
        let y = &mut y[(rhs - n) * ld..(rhs - n) * ld + la];
        keep(prepare_panel(
            comm,
            lay,
            &mut mat[p0 * ld..],
            y,
            (p0, p0 + pb, n),
            par,
            (&mut bufs, &mut diag_bufs),
            None,
        )?);
    }
    loop {
        let p1 = p0 + pb;
        if p1 == n {
            progress(n, n);
            return Ok(sign);
        }
        let (pb1, t0) = (nb.min(n - p1), lay.first_local_from(p1));
        // all of L21, transposed: every rank needs it for its rows of B22 -= L21 L21^T
        // L21^T, every rank's rows of it in turn (as gathered: a column block of the update
        // needs P strided column sets of the output, each a contiguous block of one rank's part)
        let lt = MatRef::from_column_major_slice(bufs.by_rank(), pb, n - p1);
        let from: Vec<usize> = (0..lay.ranks)
            .scan(0, |acc, r| {
                let at = *acc;
                *acc += lay.count_in_on(r, p1, n);
                Some(at)
            })
            .collect();
        let split = p1 + pb1;
        let pieces = trailing_pieces(lay, (p1, split, n));
        // the pieces in the next panel's columns come first: they are what it reads
        let ahead = pieces.iter().take_while(|piece| piece.cols.1 <= split).count();
        // this rank's rows of L21, read where they lie: the update writes only columns p1.. of
        // the rows (data[p1 * ld..]), the panel's columns are before them
        // (the right-hand side, columns n.., apart: the panels' forward steps write it)
        let (mat, y) = rows.data.split_at_mut(n * ld);
        let y = &mut y[(rhs - n) * ld..(rhs - n) * ld + la];
        let (done, rest) = mat.split_at_mut(p1 * ld);
        let l21 = MatRef::from_column_major_slice_with_stride(&done[p0 * ld + t0..], la - t0, pb, ld);
        // data: this rank's rows from global column `base` on
        let update = |data: &mut [T], base: usize, piece: &Piece| {
            let (a, b) = piece.rows;
            let l = l21.subrows(a - t0, b - a);
            let (c0, c1) = piece.cols;
            for r in 0..lay.ranks {
                let cnt = lay.count_in_on(r, c0, c1);
                if cnt == 0 {
                    continue;
                }
                let first = c0 + (r + lay.ranks - c0 % lay.ranks) % lay.ranks;
                let at = from[r] + lay.count_in_on(r, p1, c0);
                let stride = lay.ranks * ld;
                let cols = MatMut::from_column_major_slice_with_stride_mut(
                    &mut data[(first - base) * ld..],
                    ld,
                    cnt,
                    stride,
                );
                let out = cols.submatrix_mut(a, 0, b - a, cnt);
                gemm(out, Accum::Add, l, lt.subcols(at, cnt), T::of(-1.0), par);
            }
        };
        if !lookahead {
            for piece in &pieces {
                update(rest, p1, piece);
            }
            keep(prepare_panel(
                comm,
                lay,
                rest,
                y,
                (p1, split, n),
                par,
                (&mut next_bufs, &mut diag_bufs),
                None,
            )?);
        } else {
            for piece in &pieces[..ahead] {
                update(rest, p1, piece);
            }
            // the other pieces one at a time, in the windows of the next panel's gathers
            let (left, right) = rest.split_at_mut((split - p1) * ld);
            let mut rest = pieces[ahead..].iter();
            let mut work = || match rest.next() {
                Some(piece) => {
                    update(right, split, piece);
                    true
                }
                None => false,
            };
            let l11 = prepare_panel(
                comm,
                lay,
                left,
                y,
                (p1, split, n),
                par,
                (&mut next_bufs, &mut diag_bufs),
                Some(&mut work),
            )?;
            while work() {}
            keep(l11);
        }
        progress(p1, n);
        std::mem::swap(&mut bufs, &mut next_bufs);
        (p0, pb) = (p1, pb1);
    }
}

/// One GEMM of the trailing update: local rows `rows.0..rows.1`, global columns `cols.0..cols.1`.
struct Piece {
    rows: (usize, usize),
    cols: (usize, usize),
}

/// The GEMMs of the update B22 -= L21 L21^T after a panel that ends at column p1, in the lower
/// triangle of this rank's rows: the columns of the next panel (p1..split) first, then blocks of
/// [`COL_BLOCK`] x ranks columns up to n. Within a block c0..c1 the rows whose global index lies in the
/// block take the columns up to their diagonal ([`triangle_pieces`]); the rows below it take the
/// whole block, [`ROW_BLOCK`] rows at a time. Every lower-triangle entry of rows and
/// columns p1..n is in exactly one piece.
fn trailing_pieces(lay: RowCyclic, (p1, split, n): (usize, usize, usize)) -> Vec<Piece> {
    let la = lay.first_local_from(n);
    let mut pieces = Vec::new();
    let mut c0 = p1;
    while c0 < n {
        let c1 = if c0 == p1 { split } else { (c0 + COL_BLOCK * lay.ranks).min(n) };
        let (r0, r1) = (lay.first_local_from(c0), lay.first_local_from(c1));
        if r0 < r1 {
            triangle_pieces(lay, (r0, r1), c0, &mut pieces);
        }
        let mut a = r1;
        while a < la {
            let b = (a + ROW_BLOCK).min(la);
            pieces.push(Piece { rows: (a, b), cols: (c0, c1) });
            a = b;
        }
        c0 = c1;
    }
    pieces
}

/// The panel p0..p1 of B, updated by every panel before it: factors its diagonal block L11 L11^T
/// (gathered, on every rank alike), stores L11 in its owners' rows and L21 = B21 L11^-T in this
/// rank's rows below it, and gathers all of L21, transposed ((p1 - p0) x (n - p1), column-major),
/// into `bufs.out`; the forward substitution's step: z1 = L11^-1 y1 into the owners' rows p0..p1
/// of `y` (gathered with the diagonal block), y2 -= L21 z1 in this rank's rows below. `data`: this
/// rank's rows, column-major from global column p0 on, through at least column p1; `y`: its rows
/// of the right-hand side (rows 0..n); `diag`: the buffers of the diagonal block's gather, reused
/// from panel to panel. With `work`, both gathers are non-blocking and `work` runs while they are
/// in flight. Collective; `Error::NotDefinite` on every rank when a pivot is not positive.
#[allow(clippy::too_many_arguments)]
fn prepare_panel<T: Scalar>(
    comm: &dyn Comm,
    lay: RowCyclic,
    data: &mut [T],
    y: &mut [T],
    (p0, p1, n): (usize, usize, usize),
    par: Par,
    (bufs, diag): (&mut GatherBuffers<T>, &mut GatherBuffers<T>),
    mut work: Option<&mut (dyn FnMut() -> bool + '_)>,
) -> Result<Mat<T>> {
    let pb = p1 - p0;
    let ld = lay.local_count();
    let la = lay.first_local_from(n);
    let data = &mut data[..pb * ld];
    // the diagonal block's rows with their entry of y appended, row-major
    let (l0, l1) = (lay.first_local_from(p0), lay.first_local_from(p1));
    let w = pb + 1;
    let send = diag.send_buffer((l1 - l0) * w);
    for (t, l) in (l0..l1).enumerate() {
        for c in 0..pb {
            send[t * w + c] = data[l + c * ld];
        }
        send[t * w + pb] = y[l];
    }
    all_gather_packed_while(comm, lay, (p0, p1, w), diag, true, work.as_deref_mut());
    let l11 = cholesky_small_strided(&diag.out, pb, w).ok_or_else(|| {
        Error::NotDefinite(format!(
            "a pivot of the projected block is not positive near row {p0} of {n} \
             (the kernel is not conditionally definite on these points to working precision)"
        ))
    })?;
    for l in l0..l1 {
        let i = lay.global(l) - p0;
        for c in 0..pb {
            data[l + c * ld] = if c <= i { l11[(i, c)] } else { T::of(0.0) };
        }
    }
    let mut z1 = Mat::<T>::from_fn(pb, 1, |i, _| diag.out[i * w + pb]);
    solve_lower(l11.as_ref(), false, z1.as_mut(), Par::Seq);
    for l in l0..l1 {
        y[l] = z1[(lay.global(l) - p0, 0)];
    }
    if p1 == n {
        return Ok(l11);
    }
    let t0 = lay.first_local_from(p1);
    // L21 = B21 L11^-T, i.e. L11 L21^T = B21^T, solved in place on the transposed view of the
    // rows (faer's solve is as fast there as on a column-major copy); the gather sends this
    // rank's rows of L21 row-major, so they are copied once, into its send buffer
    let send = bufs.send_buffer((la - t0) * pb);
    if la > t0 {
        let all = MatMut::from_column_major_slice_mut(data, ld, pb);
        let mut b21 = all.submatrix_mut(t0, 0, la - t0, pb);
        solve_lower(l11.as_ref(), false, b21.rb_mut().transpose_mut(), par);
        MatMut::from_column_major_slice_mut(send, pb, la - t0).copy_from(b21.rb().transpose());
        let y2 = MatMut::from_column_major_slice_mut(&mut y[t0..la], la - t0, 1);
        gemm(y2, Accum::Add, b21.rb(), z1.as_ref(), T::of(-1.0), Par::Seq);
    }
    all_gather_packed_while(comm, lay, (p1, n, pb), bufs, false, work);
    Ok(l11)
}

/// The pieces of the lower triangle of local rows a..b (a < b), all of whose global indices are
/// at least c0, in the columns from c0 to their diagonal: halved recursively, the lower half's
/// columns left of its first row a full rectangle, until [`ROW_CHUNK`] rows are left, which take
/// the columns up to the diagonal of their last row. Most of the triangle's flops so run in
/// GEMMs of hundreds of rows; chunks of [`ROW_CHUNK`] rows all along the diagonal ran at 70 % of
/// the rate of large ones, and the triangle holds a share of the update that grows with the
/// ranks (the blocks of columns span [`COL_BLOCK`] x ranks).
fn triangle_pieces(lay: RowCyclic, (a, b): (usize, usize), c0: usize, pieces: &mut Vec<Piece>) {
    if b - a <= ROW_CHUNK {
        pieces.push(Piece { rows: (a, b), cols: (c0, lay.global(b - 1) + 1) });
        return;
    }
    let mid = a + (b - a) / 2;
    triangle_pieces(lay, (a, mid), c0, pieces);
    pieces.push(Piece { rows: (mid, b), cols: (c0, lay.global(mid)) });
    triangle_pieces(lay, (mid, b), lay.global(mid), pieces);
}

/// Cholesky of a small symmetric matrix (row-major, lower triangle used) by faer's blocked kernel;
/// None unless every pivot is positive.
pub(super) fn cholesky_small<T: Scalar>(d: &[T], m: usize) -> Option<Mat<T>> {
    cholesky_small_strided(d, m, m)
}

/// [`cholesky_small`] of a matrix whose rows lie `stride` apart in `d`.
fn cholesky_small_strided<T: Scalar>(d: &[T], m: usize, stride: usize) -> Option<Mat<T>> {
    use faer::dyn_stack::{MemBuffer, MemStack};
    use faer::linalg::cholesky::llt::factor::{cholesky_in_place, cholesky_in_place_scratch};
    let zero = T::of(0.0);
    let mut l = Mat::<T>::from_fn(m, m, |i, j| if j <= i { d[i * stride + j] } else { zero });
    let mut mem = MemBuffer::new(cholesky_in_place_scratch::<T>(m, Par::Seq, Default::default()));
    let ok = cholesky_in_place(
        l.as_mut(),
        Default::default(),
        Par::Seq,
        MemStack::new(&mut mem),
        Default::default(),
    );
    if ok.is_err() {
        return None;
    }
    // faer leaves the strict upper triangle as it was: zero it, and reject non-finite factors
    for j in 0..m {
        for i in 0..j {
            l[(i, j)] = zero;
        }
        if !(l[(j, j)] > zero) || (j..m).any(|i| !l[(i, j)].f64().is_finite()) {
            return None;
        }
    }
    Some(l)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::linalg::dist::test_support::bunny_rows;
    use crate::par::Solo;

    /// The bordered system of every second bunny vertex for the kernel r (about 2500 rows: on one
    /// rank a panel's trailing update spans three column blocks and several row blocks), solved
    /// on one rank with panels of 64 and 384 (the default from 6000 rows), against the dense LU
    /// of the same matrix: the weights agree to 1e-9 of their largest, the residual is at
    /// rounding level.
    #[test]
    fn a_system_of_several_column_blocks_matches_the_dense_lu() {
        let system = bunny_rows(2);
        let n = system.layout.n;
        assert!(n > 2 * COL_BLOCK + 384, "{n} rows: fewer than three column blocks");
        let (a, b) = system.data.split_at(n * n);
        let want = crate::linalg::dense::lu_solve(MatRef::from_column_major_slice(a, n, n), b).unwrap();
        let scale = want.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        for panel in [64, 384] {
            let mut m = system.clone();
            let got = cholesky_solve(&Job::on(&Solo).panel(panel), &mut m).unwrap();
            let err = got.iter().zip(&want).map(|(p, q)| (p - q).abs()).fold(0.0, f64::max) / scale;
            let res = (0..n)
                .map(|i| ((0..n).map(|j| a[i + j * n] * got[j]).sum::<f64>() - b[i]).powi(2))
                .sum::<f64>()
                .sqrt()
                / b.iter().map(|v| v * v).sum::<f64>().sqrt();
            assert!(err < 1e-9 && res < 1e-12, "panel {panel}: error {err:e}, residual {res:e}");
        }
    }

    /// The projection rounded into a fresh f32 copy writes the lower triangle and the columns
    /// 0..k below row k, each the f64 projection rounded, and leaves the rows 0..k and the upper
    /// triangle above the first diagonal row of each block of columns untouched (zero), where
    /// the f64 projection is not: the factorisation does not read them, and untouched pages cost
    /// no page faults. The rows 0..k come in f64 from `projected_top`, exactly as projected.
    #[test]
    fn the_projection_into_f32_writes_what_the_factorisation_reads_and_no_more() {
        let m = bunny_rows(8);
        let border = Border::new(&Solo, &m).unwrap();
        let (k, n) = (border.k, border.n);
        assert!(n > 4 * COL_CHUNK, "{n} centres: too few column blocks");
        let (left, right) = border.projection(&Solo, &m);
        let ld = m.ld();
        let mut full = m.clone();
        let a = MatMut::from_column_major_slice_with_stride_mut(&mut full.data, n, n, ld);
        gemm(a, Accum::Add, left.as_ref(), right.as_ref(), -1.0, Par::Seq);
        let mut dst: LocalRows<f32> = LocalRows::zeros(m.layout, m.cols, m.border);
        project_into(&m, &mut dst, (&left, &right), Par::Seq);
        let (mut written, mut left_alone) = (0, 0);
        for c in 0..n {
            let first_of_block = c / COL_CHUNK * COL_CHUNK;
            for g in 0..n {
                let (got, want) = (dst.get(g, c) as f64, full.get(g, c));
                if g >= k && (c < k || g >= first_of_block) {
                    assert!(
                        (got - want).abs() <= 1e-6 * want.abs().max(1e-3),
                        "({g}, {c}): {got} against {want}"
                    );
                    written += 1;
                } else {
                    assert!(
                        got == 0.0 && want != 0.0,
                        "({g}, {c}) above the diagonal: {got} (projection {want})"
                    );
                    left_alone += 1;
                }
            }
        }
        assert!(left_alone > written / 2, "{left_alone} entries left alone, {written} written");
        let top = projected_top(&Solo, &m, (&left, &right));
        for i in 0..k {
            for c in 0..n {
                let (got, want) = (top[i * n + c], full.get(i, c));
                assert!(
                    (got - want).abs() <= 1e-12 * want.abs().max(1.0),
                    "row {i}, column {c}: {got} against {want}"
                );
            }
        }
    }

    /// The projected Cholesky reads the lower triangle of A and its first k rows alone: with the
    /// rest of the upper triangle zero (as `assemble_lower` leaves it) the solution is that of the
    /// whole matrix to rounding, and the product with the reflectors from the lower triangle is
    /// the product of the whole rows. Bunny vertices (every fourth, about 1250 rows, the last
    /// group of columns of the product partial), one rank; the ranks' sum in the product is
    /// checked on 2 and 3 ranks by the collective tests.
    #[test]
    fn the_solve_reads_the_lower_triangle_and_the_first_rows_alone() {
        let whole = bunny_rows(4);
        let (k, n) = (whole.border, whole.layout.n - whole.border);
        assert!(n > 100 * SYMMETRIC_GROUP, "{n} centres");
        let mut lower = whole.clone();
        for c in 0..n {
            (k..c).for_each(|g| lower.set(g, c, 0.0));
        }
        let border = Border::new(&Solo, &whole).unwrap();
        let (v, _) = border.wy();
        let a = MatRef::from_column_major_slice_with_stride(&whole.data, n, n, whole.ld());
        let want = a * &v;
        let got = symmetric_times(&Solo, &lower, &v);
        let scale = want.norm_max();
        let err = (&got - &want).norm_max() / scale;
        assert!(err < 1e-13, "A V from the lower triangle off by {err:e} of its largest entry");
        let job = Job::on(&Solo).panel(128);
        let want = cholesky_solve(&job, &mut whole.clone()).unwrap();
        let got = cholesky_solve(&job, &mut lower).unwrap();
        let scale = want.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        let err = got.iter().zip(&want).map(|(p, q)| (p - q).abs()).fold(0.0, f64::max) / scale;
        assert!(err < 1e-10, "the solution from the lower triangle off by {err:e}");
    }

    /// Every entry of the lower triangle of rows and columns p1..n on a rank is updated by exactly
    /// one piece, the next panel's columns by the leading pieces alone, and no piece leaves the
    /// trailing block: on 1, 2, 3 and 5 ranks, with the blocks of rows and columns ending inside
    /// and at the end, and the next panel of one column, of a block and of all columns left.
    #[test]
    fn the_trailing_pieces_cover_the_lower_triangle_once() {
        for ranks in [1, 2, 3, 5] {
            for n in [7, 700, 2 * COL_BLOCK * ranks + 37, 2 * ROW_BLOCK * ranks + 11] {
                for (p1, width) in [(3, 1), (5, 64), (1, n - 1), (n / 2, 97)] {
                    let split = (p1 + width).min(n);
                    for rank in 0..ranks {
                        let lay = RowCyclic::new(n, ranks, rank);
                        let pieces = trailing_pieces(lay, (p1, split, n));
                        let (t0, la) = (lay.first_local_from(p1), lay.first_local_from(n));
                        let mut count = vec![0u8; (la - t0) * (n - p1)];
                        let mut ahead = true;
                        for piece in &pieces {
                            let ((a, b), (c0, c1)) = (piece.rows, piece.cols);
                            assert!(t0 <= a && a < b && b <= la && p1 <= c0 && c0 < c1 && c1 <= n);
                            ahead &= c1 <= split;
                            assert!(ahead || c0 >= split, "the next panel's pieces come first");
                            for l in a..b {
                                for c in c0..c1 {
                                    count[(l - t0) * (n - p1) + c - p1] += 1;
                                }
                            }
                        }
                        for l in t0..la {
                            for c in p1..=lay.global(l) {
                                let seen = count[(l - t0) * (n - p1) + c - p1];
                                assert_eq!(
                                    seen,
                                    1,
                                    "ranks {ranks} n {n} p1 {p1} row {} column {c}",
                                    lay.global(l)
                                );
                            }
                        }
                    }
                }
            }
        }
    }
}
