//! Projected Cholesky for the bordered spline system (math.md, section 1): the Householder
//! reflectors that triangularise the polynomial block P are applied to both sides of A, which
//! leaves a definite (N-k) x (N-k) block B = Q2^T A Q2; B (or -B) is factored by a blocked,
//! right-looking, row-cyclic Cholesky (a third of LU's flops, counting only the lower triangle),
//! and lambda = Q2 mu, R c = Q1^T (r - A lambda) recover the spline. Collective throughout.

use faer::linalg::matmul::matmul;
use faer::linalg::triangular_solve::solve_lower_triangular_in_place;
use faer::reborrow::Reborrow;
use faer::{Accum, Mat, MatMut, MatRef, Par};

use super::system::{all_gather_rows, GatherBuffers, LocalRows};
use crate::error::{Error, Result};
use crate::par::Comm;

/// Local rows updated per GEMM of the trailing update: small enough that the triangle is followed
/// closely, large enough for BLAS-3 speed.
const ROW_CHUNK: usize = 96;

/// Solves the bordered system in `rows` (its polynomial border of width `rows.border` >= 1 and
/// its right-hand side as the last column). Returns the solution on every rank, or
/// `Error::NotDefinite` (on every rank) when a pivot of B is not positive, in which case the
/// caller should fall back to LU on a freshly assembled system: `rows` is overwritten.
pub fn cholesky_solve(
    comm: &dyn Comm,
    rows: &mut LocalRows,
    panel: usize,
    progress: &dyn Fn(usize, usize),
) -> Result<Vec<f64>> {
    let lay = rows.layout;
    let k = rows.border;
    let n = lay.n - k;
    assert!(k >= 1, "the projected Cholesky needs a polynomial border");
    if n <= k {
        return Err(Error::NotDefinite(format!("{n} centres leave no definite block")));
    }
    let nb = panel.max(1);
    let ld = rows.ld();
    let rhs = rows.cols - 1;
    let la = lay.first_local_from(n); // this rank's rows of A are local 0..la
    let gl: Vec<usize> = (0..la).map(|l| lay.global(l)).collect();

    // P^T (the border rows) on every rank, and its reflectors
    let pt = rows.gather_rows(comm, n, n + k, 0, n);
    let (vs, taus, r) = reflectors(&pt, n, k)?;

    project(comm, rows, &vs, &taus, n, la);

    // B = rows/columns k..n: make it positive definite (sign of any diagonal entry)
    let mut d0 = [if lay.owner(k) == lay.rank { rows.get(lay.local(k), k) } else { 0.0 }];
    comm.broadcast_f64(lay.owner(k), &mut d0);
    let sign = if d0[0] < 0.0 { -1.0 } else { 1.0 };
    let b0 = lay.first_local_from(k);
    if sign < 0.0 {
        for c in (k..n).chain([rhs]) {
            rows.data[c * ld + b0..c * ld + la].iter_mut().for_each(|a| *a = -*a);
        }
    }

    // blocked right-looking Cholesky of B, lower triangle, in place
    let par = Par::rayon(0);
    let mut bufs = GatherBuffers::default();
    let mut p0 = k;
    while p0 < n {
        let pb = nb.min(n - p0);
        let d = rows.gather_rows(comm, p0, p0 + pb, p0, p0 + pb);
        let l11 = cholesky_small(&d, pb).ok_or_else(|| {
            Error::NotDefinite(format!(
                "a pivot of the projected block is not positive near row {p0} of {n} \
                 (the kernel is not conditionally definite on these points to working precision)"
            ))
        })?;
        for l in lay.first_local_from(p0)..lay.first_local_from(p0 + pb) {
            let i = lay.global(l) - p0;
            for c in 0..pb {
                rows.set(l, p0 + c, if c <= i { l11[(i, c)] } else { 0.0 });
            }
        }
        let t0 = lay.first_local_from(p0 + pb);
        if p0 + pb < n {
            // L21 = B21 L11^-T, i.e. L11 L21^T = B21^T
            // (solved on a column-major copy of B21^T: faer's blocked path wants unit row stride)
            {
                let mut b21 = rows.view_mut().submatrix_mut(t0, p0, la - t0, pb);
                let mut bt = b21.rb().transpose().to_owned();
                solve_lower_triangular_in_place(l11.as_ref(), bt.as_mut(), par);
                b21.copy_from(bt.transpose());
            }
            // every rank needs all of L21 for its rows of B22 -= L21 L21^T
            let rest = n - p0 - pb;
            rows.gather_rows_with(comm, p0 + pb, n, p0, p0 + pb, &mut bufs);
            let lt = MatRef::from_column_major_slice(&bufs.out, pb, rest);
            let mut a = t0;
            while a < la {
                let b = (a + ROW_CHUNK).min(la);
                let ncols = lay.global(b - 1) + 1 - (p0 + pb);
                let m = rows.view_mut().submatrix_mut(a, 0, b - a, p0 + pb + ncols);
                let (left, right) = m.split_at_col_mut(p0 + pb);
                matmul(right, Accum::Add, left.rb().subcols(p0, pb), lt.subcols(0, ncols), -1.0, par);
                a = b;
            }
        }
        p0 += pb;
        progress(p0, n);
    }

    // forward substitution L z = y (y: the right-hand side rows k..n)
    let mut z = vec![0.0; n];
    let mut q0 = k;
    while q0 < n {
        let q1 = (q0 + nb).min(n);
        let bs = q1 - q0;
        let d = rows.gather_rows(comm, q0, q1, q0, q1);
        let y = rows.gather_rows(comm, q0, q1, rhs, rhs + 1);
        for i in 0..bs {
            let s: f64 = (0..i).map(|j| d[i * bs + j] * z[q0 + j]).sum();
            z[q0 + i] = (y[i] - s) / d[i * bs + i];
        }
        let u0 = lay.first_local_from(q1);
        for c in q0..q1 {
            let zc = z[c];
            for l in u0..la {
                rows.data[l + rhs * ld] -= rows.data[l + c * ld] * zc;
            }
        }
        q0 = q1;
    }
    // back substitution L^T mu = z
    let mut mu = vec![0.0; n];
    let mut q1 = n;
    while q1 > k {
        let q0 = q1.saturating_sub(nb).max(k);
        let bs = q1 - q0;
        let u0 = lay.first_local_from(q1);
        let mut sums = vec![0.0; bs];
        for (t, c) in (q0..q1).enumerate() {
            sums[t] = (u0..la).map(|l| rows.data[l + c * ld] * mu[gl[l]]).sum();
        }
        comm.sum_f64(&mut sums);
        let d = rows.gather_rows(comm, q0, q1, q0, q1);
        for i in (0..bs).rev() {
            let s: f64 = (i + 1..bs).map(|j| d[j * bs + i] * mu[q0 + j]).sum();
            mu[q0 + i] = (z[q0 + i] - sums[i] - s) / d[i * bs + i];
        }
        q1 = q0;
    }

    // lambda = Q [0; mu]
    let mut lambda = mu.clone();
    lambda[..k].iter_mut().for_each(|x| *x = 0.0);
    for (v, &tau) in vs.iter().zip(&taus).rev() {
        let t = tau * v.iter().zip(&lambda).map(|(a, b)| a * b).sum::<f64>();
        lambda.iter_mut().zip(v).for_each(|(x, vi)| *x -= t * vi);
    }
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
        let s: f64 = (i + 1..k).map(|j| r[i * k + j] * c[j]).sum();
        c[i] = (t[i] - s) / r[i * k + i];
    }
    lambda.extend(c);
    Ok(lambda)
}

/// A <- Q^T A Q and y <- Q^T y with Q = H_1 ... H_k = I - V T V^T, in two passes over the local
/// rows: X = A V (A is symmetric, so V^T A = X^T), then the symmetric rank-2k update
/// A -= Y V^T + V Y^T with Y = X T - V T^T (V^T X) T / 2. One all-gather of X (N x k).
fn project(comm: &dyn Comm, rows: &mut LocalRows, vs: &[Vec<f64>], taus: &[f64], n: usize, la: usize) {
    let lay = rows.layout;
    let k = vs.len();
    let ld = rows.ld();
    let rhs = rows.cols - 1;
    let par = Par::rayon(0);
    let gl: Vec<usize> = (0..la).map(|l| lay.global(l)).collect();
    let v = Mat::<f64>::from_fn(n, k, |i, j| vs[j][i]);
    // T (upper, k x k) of the compact WY form, from V^T V
    let vtv = v.transpose() * &v;
    let mut t = Mat::<f64>::zeros(k, k);
    for i in 0..k {
        t[(i, i)] = taus[i];
        for r in 0..i {
            let s: f64 = (r..i).map(|s| t[(r, s)] * vtv[(s, i)]).sum();
            t[(r, i)] = -taus[i] * s;
        }
    }
    // X = A V on this rank's rows, then all of X on every rank
    let mut x_loc = Mat::<f64>::zeros(la, k);
    let a = MatRef::from_column_major_slice_with_stride(&rows.data, la, n, ld);
    matmul(x_loc.as_mut(), Accum::Replace, a, v.as_ref(), 1.0, par);
    let send: Vec<f64> =
        (0..la).flat_map(|l| (0..k).map(move |j| (l, j))).map(|(l, j)| x_loc[(l, j)]).collect();
    let x_rows = all_gather_rows(comm, lay, &send, 0, n, k);
    let x = Mat::<f64>::from_fn(n, k, |i, j| x_rows[i * k + j]);
    let z = v.transpose() * &x;
    let y = &x * &t - (&v * (t.transpose() * &z * &t)) * 0.5;
    // A -= [Y_loc V_loc] [V^T; Y^T]
    let left = Mat::<f64>::from_fn(la, 2 * k, |l, j| if j < k { y[(gl[l], j)] } else { v[(gl[l], j - k)] });
    let right = Mat::<f64>::from_fn(2 * k, n, |j, c| if j < k { v[(c, j)] } else { y[(c, j - k)] });
    let a = MatMut::from_column_major_slice_with_stride_mut(&mut rows.data, la, n, ld);
    matmul(a, Accum::Add, left.as_ref(), right.as_ref(), -1.0, par);
    // y <- Q^T y = y - V T^T V^T y on the right-hand side column
    let mut ry = vec![0.0; la];
    ry.copy_from_slice(&rows.data[rhs * ld..rhs * ld + la]);
    let y_all = all_gather_rows(comm, lay, &ry, 0, n, 1);
    let vty: Vec<f64> = (0..k).map(|j| (0..n).map(|i| v[(i, j)] * y_all[i]).sum()).collect();
    let coef: Vec<f64> = (0..k).map(|j| (0..k).map(|i| t[(i, j)] * vty[i]).sum()).collect();
    for l in 0..la {
        let g = gl[l];
        rows.data[rhs * ld + l] -= (0..k).map(|j| v[(g, j)] * coef[j]).sum::<f64>();
    }
}

/// Reflectors v_j, their tau_j, and R (row-major k x k).
type Reflectors = (Vec<Vec<f64>>, Vec<f64>, Vec<f64>);

/// Householder QR of the N x k matrix P given as P^T (row-major k x N): the reflectors v_j
/// (length N, zero before j, one at j), their tau_j (H_j = I - tau_j v_j v_j^T), and R (row-major
/// k x k) with Q^T P = [R; 0], Q = H_1 ... H_k.
fn reflectors(pt: &[f64], n: usize, k: usize) -> Result<Reflectors> {
    let mut p: Vec<Vec<f64>> = (0..k).map(|j| pt[j * n..(j + 1) * n].to_vec()).collect(); // columns
    let mut vs = Vec::with_capacity(k);
    let mut taus = Vec::with_capacity(k);
    let mut r = vec![0.0; k * k];
    for j in 0..k {
        let x0 = p[j][j];
        let norm = p[j][j..].iter().map(|v| v * v).sum::<f64>().sqrt();
        if !(norm > 0.0) {
            return Err(Error::Numerical(format!(
                "the polynomial block has rank < {k}: points not unisolvent"
            )));
        }
        let alpha = if x0 >= 0.0 { -norm } else { norm };
        let mut v = vec![0.0; n];
        v[j] = 1.0;
        let scale = 1.0 / (x0 - alpha);
        for i in j + 1..n {
            v[i] = p[j][i] * scale;
        }
        let tau = (alpha - x0) / alpha;
        r[j * k + j] = alpha;
        for c in j + 1..k {
            let wv: f64 = (j..n).map(|i| v[i] * p[c][i]).sum();
            for i in j..n {
                p[c][i] -= tau * v[i] * wv;
            }
            r[j * k + c] = p[c][j];
        }
        vs.push(v);
        taus.push(tau);
    }
    Ok((vs, taus, r))
}

/// Cholesky of a small symmetric matrix (row-major, lower triangle used) by faer's blocked kernel;
/// None unless every pivot is positive.
fn cholesky_small(d: &[f64], m: usize) -> Option<Mat<f64>> {
    use faer::dyn_stack::{MemBuffer, MemStack};
    use faer::linalg::cholesky::llt::factor::{cholesky_in_place, cholesky_in_place_scratch};
    let mut l = Mat::<f64>::from_fn(m, m, |i, j| if j <= i { d[i * m + j] } else { 0.0 });
    let mut mem = MemBuffer::new(cholesky_in_place_scratch::<f64>(m, Par::Seq, Default::default()));
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
            l[(i, j)] = 0.0;
        }
        if !(l[(j, j)] > 0.0) || (j..m).any(|i| !l[(i, j)].is_finite()) {
            return None;
        }
    }
    Some(l)
}
