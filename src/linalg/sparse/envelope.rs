//! Envelope (profile) storage and envelope Cholesky of a sparse symmetric positive definite
//! matrix, the direct solver of compactly supported splines whose centres are ordered so that
//! neighbours in space are neighbours in index (Jennings 1966; George & Liu 1981, chapter 4).
//!
//! # Envelope storage
//!
//! Let A be symmetric of order n, already reordered (row i of the reordered matrix is row
//! perm\[i\] of the given one). For row i of its lower triangle let
//!
//! ```text
//!     f_i = min { j : a_ij != 0 }  (f_i <= i, and f_i = i when only the diagonal is nonzero),
//!     beta_i = i - f_i             (the row's bandwidth).
//! ```
//!
//! The envelope is the set of positions Env(A) = { (i, j) : f_i <= j < i }: every position
//! between a row's first nonzero and its diagonal, zero or not. Jennings' scheme stores, row after
//! row, the entries a_(i, f_i), ..., a_(i, i) contiguously, so the matrix costs
//!
//! ```text
//!     |Env(A)| + n = sum_i (beta_i + 1)  doubles,
//! ```
//!
//! against n^2 for full storage and n (n + 1) / 2 for the lower triangle, plus two index arrays
//! of n entries: the first column f_i of each row and the start of each row in the value array
//! (entry (i, j) lies at start_i + j - f_i). How small the envelope is depends entirely on the
//! ordering: a kernel of compact support couples a centre only with the centres near it, so an
//! ordering that keeps spatial neighbours close in index (an octree traversal, reverse
//! Cuthill-McKee) gives small beta_i, a random one gives beta_i close to i.
//!
//! # Envelope Cholesky
//!
//! A = L L^T is computed row by row (the "bordering" form of George & Liu): once rows 0..i of L
//! are known, row i follows from
//!
//! ```text
//!     l_ij = (a_ij - sum_{k<j} l_ik l_jk) / l_jj      for j < i,
//!     l_ii = sqrt(a_ii - sum_{k<i} l_ik^2),
//! ```
//!
//! i.e. row i of L is the solution of a triangular system with the leading block of L, followed
//! by the pivot. The factor has no fill outside the envelope: l_ij = 0 for every j < f_i. By
//! induction on j: for j < f_i, a_ij = 0, and every term of the sum has k < j < f_i, where
//! l_ik = 0 by the induction hypothesis, so l_ij = 0. Hence L fits exactly in the storage of A,
//! which it overwrites, and both sums start at max(f_i, f_j): each is the dot product of two
//! contiguous pieces of the value array. Zeros inside the envelope may fill in; that is
//! accounted for by storing the whole envelope. The work is (1/2) sum_i beta_i (beta_i + 3)
//! multiply-adds and n square roots. A pivot a_ii - sum l_ik^2 that is not positive proves that
//! A is not positive definite (to working precision); the factorisation stops with
//! [`Error::NotDefinite`] naming the row.
//!
//! # Solves
//!
//! A x = b becomes L y = b (forward, row by row: y_i = (b_i - sum_{f_i<=k<i} l_ik y_k) / l_ii)
//! and L^T x = y (backward: row i of L is column i of L^T, so x_i = y_i / l_ii is followed by
//! y_k -= l_ik x_i for f_i <= k < i). Both cost |Env(A)| multiply-adds per right-hand side. The
//! right-hand sides and the solutions are in the original order; the solver applies the
//! permutation itself.

use super::check::{check_permutation, check_rhs, check_serial};
use super::{SpdSolve, SymCsr};
use crate::error::{Error, Result};

const WHO: &str = "envelope Cholesky";

/// The sizes of an envelope and of its factor.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct EnvelopeStats {
    /// The order n.
    pub order: usize,
    /// Stored doubles, sum_i (beta_i + 1): the envelope and the diagonal.
    pub envelope: usize,
    /// The largest row bandwidth, max_i beta_i.
    pub bandwidth: usize,
    /// Nonzeros of A's lower triangle, diagonal included.
    pub lower_nnz: usize,
    /// Nonzero entries of the factor L (at most `envelope`); zero before factoring.
    pub factor_nnz: usize,
}

impl EnvelopeStats {
    /// Doubles of full storage, n^2.
    pub fn full(&self) -> u128 {
        (self.order as u128).pow(2)
    }

    /// Doubles of the lower triangle with the diagonal, n (n + 1) / 2.
    pub fn lower_triangle(&self) -> u128 {
        self.order as u128 * (self.order as u128 + 1) / 2
    }

    /// The envelope as a fraction of full storage.
    pub fn fraction_of_full(&self) -> f64 {
        self.envelope as f64 / (self.full() as f64).max(1.0)
    }

    /// The envelope as a fraction of the lower triangle.
    pub fn fraction_of_lower(&self) -> f64 {
        self.envelope as f64 / (self.lower_triangle() as f64).max(1.0)
    }
}

/// A symmetric matrix reordered and held in Jennings' envelope scheme; [`Envelope::factor`]
/// overwrites it with its Cholesky factor.
#[derive(Debug, Clone)]
pub struct Envelope {
    /// perm\[new\] = old.
    perm: Vec<usize>,
    /// f_i, the first column of the envelope of (reordered) row i.
    first: Vec<usize>,
    /// Row i's entries (columns f_i..=i) lie at start\[i\]..start\[i + 1\] of `vals`.
    start: Vec<usize>,
    vals: Vec<f64>,
    lower_nnz: usize,
}

/// The first column f_i of every row of the lower triangle of A reordered by `perm`.
fn first_columns(a: &SymCsr, perm: &[usize]) -> Vec<usize> {
    let n = a.n;
    let mut inv = vec![0; n];
    for (new, &old) in perm.iter().enumerate() {
        inv[old] = new;
    }
    let mut first: Vec<usize> = (0..n).collect();
    for old_i in 0..n {
        for (old_j, _) in a.row(old_i) {
            let (i, j) = (inv[old_i], inv[old_j]);
            let (r, c) = if i >= j { (i, j) } else { (j, i) };
            first[r] = first[r].min(c);
        }
    }
    first
}

/// The envelope size (stored doubles, diagonal included) of A under the ordering `perm`
/// (perm\[new\] = old), without storing anything: for comparing orderings.
pub fn envelope_size(a: &SymCsr, perm: &[usize]) -> Result<usize> {
    check_serial(a, WHO)?;
    check_permutation(perm, a.n, WHO)?;
    Ok(first_columns(a, perm).iter().enumerate().map(|(i, f)| i - f + 1).sum())
}

impl Envelope {
    /// Stores the lower triangle of `a` (the whole matrix, on one process) reordered by `perm`
    /// (perm\[new\] = old) in envelope form. Fails with [`Error::Memory`] when the envelope cannot
    /// be allocated.
    pub fn new(a: &SymCsr, perm: &[usize]) -> Result<Self> {
        check_serial(a, WHO)?;
        check_permutation(perm, a.n, WHO)?;
        let n = a.n;
        let first = first_columns(a, perm);
        let mut start = Vec::with_capacity(n + 1);
        start.push(0usize);
        for (i, &f) in first.iter().enumerate() {
            start.push(start[i] + (i - f + 1));
        }
        let size = start[n];
        let mut vals = Vec::new();
        if vals.try_reserve_exact(size).is_err() {
            return Err(Error::Memory(format!(
                "the envelope of a sparse matrix of order {n} holds {size} doubles ({:.1} GiB); \
                 order the points spatially or use the sparse Cholesky",
                size as f64 * 8.0 / (1u64 << 30) as f64
            )));
        }
        vals.resize(size, 0.0);
        let mut inv = vec![0; n];
        for (new, &old) in perm.iter().enumerate() {
            inv[old] = new;
        }
        for old_i in 0..n {
            for (old_j, v) in a.row(old_i) {
                let (i, j) = (inv[old_i], inv[old_j]);
                let (r, c) = if i >= j { (i, j) } else { (j, i) };
                vals[start[r] + c - first[r]] = v;
            }
        }
        Ok(Envelope { perm: perm.to_vec(), first, start, vals, lower_nnz: a.nnz() })
    }

    /// The order n.
    pub fn order(&self) -> usize {
        self.first.len()
    }

    /// The sizes of the envelope (`factor_nnz` is zero: nothing is factored yet).
    pub fn stats(&self) -> EnvelopeStats {
        EnvelopeStats {
            order: self.order(),
            envelope: self.vals.len(),
            bandwidth: self.first.iter().enumerate().map(|(i, f)| i - f).max().unwrap_or(0),
            lower_nnz: self.lower_nnz,
            factor_nnz: 0,
        }
    }

    /// The entries of reordered row i, columns f_i..=i.
    fn row(&self, i: usize) -> &[f64] {
        &self.vals[self.start[i]..self.start[i + 1]]
    }

    /// Factors the matrix in place, A = L L^T, row by row. Fails with [`Error::NotDefinite`]
    /// naming the row (in the original order) whose pivot is not positive.
    pub fn factor(mut self) -> Result<EnvelopeCholesky> {
        for i in 0..self.order() {
            let (fi, si) = (self.first[i], self.start[i]);
            let (done, rest) = self.vals.split_at_mut(si);
            let row_i = &mut rest[..i - fi + 1];
            for j in fi..i {
                let (fj, sj) = (self.first[j], self.start[j]);
                let lo = fi.max(fj);
                let row_j = &done[sj..sj + j - fj + 1];
                let s = dot(&row_i[lo - fi..j - fi], &row_j[lo - fj..j - fj]);
                row_i[j - fi] = (row_i[j - fi] - s) / row_j[j - fj];
            }
            let (off, diag) = row_i.split_at_mut(i - fi);
            let d = diag[0] - dot(off, off);
            if !(d > 0.0) {
                return Err(Error::NotDefinite(format!(
                    "{WHO}: the pivot of row {} (step {i} of {} in the envelope order) is {d:.3e}, \
                     not positive: the matrix is not positive definite",
                    self.perm[i],
                    self.order()
                )));
            }
            diag[0] = d.sqrt();
        }
        let factor_nnz = self.vals.iter().filter(|v| **v != 0.0).count();
        Ok(EnvelopeCholesky { env: self, factor_nnz })
    }
}

/// The envelope Cholesky factor L of a reordered matrix, A = L L^T, as a solver.
#[derive(Debug, Clone)]
pub struct EnvelopeCholesky {
    env: Envelope,
    factor_nnz: usize,
}

impl EnvelopeCholesky {
    /// Stores `a` under the ordering `perm` (perm\[new\] = old) and factors it: the composition
    /// of [`Envelope::new`] and [`Envelope::factor`].
    pub fn new(a: &SymCsr, perm: &[usize]) -> Result<Self> {
        Envelope::new(a, perm)?.factor()
    }

    /// The sizes of the envelope and the nonzeros of the factor.
    pub fn stats(&self) -> EnvelopeStats {
        EnvelopeStats { factor_nnz: self.factor_nnz, ..self.env.stats() }
    }

    /// Solves L L^T x = b in place, in the reordered numbering.
    fn solve_reordered(&self, x: &mut [f64]) {
        let env = &self.env;
        for i in 0..env.order() {
            let (fi, row) = (env.first[i], env.row(i));
            let (off, diag) = row.split_at(i - fi);
            x[i] = (x[i] - dot(off, &x[fi..i])) / diag[0];
        }
        for i in (0..env.order()).rev() {
            let (fi, row) = (env.first[i], env.row(i));
            let (off, diag) = row.split_at(i - fi);
            let xi = x[i] / diag[0];
            x[i] = xi;
            for (y, l) in x[fi..i].iter_mut().zip(off) {
                *y -= l * xi;
            }
        }
    }
}

impl SpdSolve for EnvelopeCholesky {
    fn order(&self) -> usize {
        self.env.order()
    }

    fn solve_in_place(&self, rhs: &mut [f64], nrhs: usize) -> Result<()> {
        let n = self.order();
        check_rhs(rhs, n, nrhs, WHO)?;
        let mut work = vec![0.0; n];
        for col in rhs.chunks_exact_mut(n.max(1)).take(nrhs) {
            for (w, &old) in work.iter_mut().zip(&self.env.perm) {
                *w = col[old];
            }
            self.solve_reordered(&mut work);
            for (w, &old) in work.iter().zip(&self.env.perm) {
                col[old] = *w;
            }
        }
        Ok(())
    }
}

/// The dot product of two slices of equal length, with four partial sums (which lets the
/// compiler vectorise it).
fn dot(a: &[f64], b: &[f64]) -> f64 {
    debug_assert_eq!(a.len(), b.len());
    let mut acc = [0.0f64; 4];
    let (a4, b4) = (a.chunks_exact(4), b.chunks_exact(4));
    let tail: f64 = a4.remainder().iter().zip(b4.remainder()).map(|(x, y)| x * y).sum();
    for (x, y) in a4.zip(b4) {
        for t in 0..4 {
            acc[t] += x[t] * y[t];
        }
    }
    (acc[0] + acc[1]) + (acc[2] + acc[3]) + tail
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::linalg::dense::lu_solve;
    use crate::linalg::sparse::ordering::reverse_cuthill_mckee;
    use crate::linalg::sparse::test_support::{
        bunny, dense, kernel_matrix, rel_diff, rhs, shuffled, sorted_by_x,
    };

    /// The tridiagonal matrix 2 on the diagonal, -1 beside it.
    fn tridiagonal(n: usize) -> SymCsr {
        let mut a = SymCsr { n, rows: (0..n).collect(), row_ptr: vec![0], ..Default::default() };
        for i in 0..n {
            if i > 0 {
                a.cols.push(i - 1);
                a.vals.push(-1.0);
            }
            a.cols.push(i);
            a.vals.push(2.0);
            a.row_ptr.push(a.cols.len());
        }
        a
    }

    #[test]
    fn solves_a_bunny_kernel_matrix_like_a_dense_solve() {
        let pts = bunny(10);
        let a = kernel_matrix(&pts, 0.2);
        let n = a.n;
        let chol = EnvelopeCholesky::new(&a, &sorted_by_x(&pts)).unwrap();
        assert_eq!(chol.order(), n);
        let (b0, b1) = (rhs(n, 0.0), rhs(n, 1.3));
        let mut x = [b0.clone(), b1.clone()].concat();
        chol.solve_in_place(&mut x, 2).unwrap();
        let m = dense(&a);
        for (b, got) in [(&b0, &x[..n]), (&b1, &x[n..])] {
            let want = lu_solve(m.as_ref(), b).unwrap();
            let err = rel_diff(got, &want);
            assert!(err < 1e-10, "envelope Cholesky vs dense LU: relative difference {err:e}");
        }
        let s = chol.stats();
        assert!(s.factor_nnz <= s.envelope && s.factor_nnz >= s.lower_nnz, "{s:?}");
    }

    #[test]
    fn spatial_orderings_have_smaller_envelopes_than_a_random_one() {
        let pts = bunny(10);
        let a = kernel_matrix(&pts, 0.2);
        let random = envelope_size(&a, &shuffled(a.n, 7)).unwrap();
        let by_x = envelope_size(&a, &sorted_by_x(&pts)).unwrap();
        let rcm = envelope_size(&a, &reverse_cuthill_mckee(&a).unwrap()).unwrap();
        assert!(by_x < random && rcm < random, "random {random}, by x {by_x}, RCM {rcm}");
        let env = Envelope::new(&a, &sorted_by_x(&pts)).unwrap();
        let s = env.stats();
        assert_eq!(s.envelope, by_x);
        assert_eq!(s.lower_nnz, a.nnz());
        assert!(s.fraction_of_lower() < 1.0 && s.fraction_of_full() < s.fraction_of_lower(), "{s:?}");
    }

    #[test]
    fn tridiagonal_envelope_and_factor_are_exact() {
        let a = tridiagonal(6);
        let identity: Vec<usize> = (0..6).collect();
        let chol = EnvelopeCholesky::new(&a, &identity).unwrap();
        let s = chol.stats();
        assert_eq!(
            (s.envelope, s.bandwidth, s.factor_nnz, s.full(), s.lower_triangle()),
            (11, 1, 11, 36, 21)
        );
        // L of tridiag(-1, 2, -1): l_ii = sqrt((i + 2) / (i + 1)), l_i,i-1 = -1 / l_(i-1)(i-1)
        for i in 0..6 {
            let lii = ((i as f64 + 2.0) / (i as f64 + 1.0)).sqrt();
            let row = chol.env.row(i);
            assert!((row[row.len() - 1] - lii).abs() < 1e-15);
            if i > 0 {
                let prev = (i as f64 + 1.0) / i as f64;
                assert!((row[0] + 1.0 / prev.sqrt()).abs() < 1e-15);
            }
        }
        // A x = A 1 gives x = 1, under a reversed order too
        let reversed: Vec<usize> = (0..6).rev().collect();
        let mut b = vec![1.0, 0.0, 0.0, 0.0, 0.0, 1.0];
        EnvelopeCholesky::new(&a, &reversed).unwrap().solve_in_place(&mut b, 1).unwrap();
        assert!(b.iter().all(|v| (v - 1.0).abs() < 1e-14), "{b:?}");
    }

    #[test]
    fn an_indefinite_matrix_is_reported_with_its_row() {
        let pts = bunny(20);
        let mut a = kernel_matrix(&pts, 0.2);
        let diag = a.row_ptr[18] - 1; // the diagonal entry of row 17
        a.vals[diag] = -1.0;
        let err = EnvelopeCholesky::new(&a, &shuffled(a.n, 3)).unwrap_err();
        assert!(matches!(err, Error::NotDefinite(_)), "{err:?}");
        assert!(err.to_string().contains("the pivot of row 17 "), "{err}");
    }

    #[test]
    fn malformed_input_is_an_error_not_a_panic() {
        let a = tridiagonal(4);
        let bad_perm = EnvelopeCholesky::new(&a, &[0, 1, 1, 3]).unwrap_err();
        assert!(matches!(bad_perm, Error::Usage(_)), "{bad_perm:?}");
        let short_perm = envelope_size(&a, &[0, 1, 2]).unwrap_err();
        assert!(matches!(short_perm, Error::Usage(_)), "{short_perm:?}");
        let mut upper = a.clone();
        upper.cols[1] = 2; // row 1 would hold column 2
        assert!(matches!(Envelope::new(&upper, &[0, 1, 2, 3]), Err(Error::Numerical(_))));
        let mut distributed = a.clone();
        distributed.rows = vec![0, 2, 1, 3];
        assert!(matches!(Envelope::new(&distributed, &[0, 1, 2, 3]), Err(Error::Usage(_))));
        let chol = EnvelopeCholesky::new(&a, &[3, 2, 1, 0]).unwrap();
        assert!(matches!(chol.solve_in_place(&mut [1.0; 7], 2), Err(Error::Usage(_))));
    }
}
