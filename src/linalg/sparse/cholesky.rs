//! The production serial solver of sparse symmetric positive definite systems: faer's sparse
//! Cholesky factorisation, A = P^T L L^T P, with its fill-reducing ordering P (approximate minimum
//! degree) and, when the factor is dense enough to pay off, supernodes (groups of adjacent columns
//! of L with the same structure below the diagonal, factored as dense blocks with BLAS-3 kernels).
//!
//! # Structure and fill
//!
//! Column j of L has a nonzero in row i > j exactly when a_ij != 0 or, for some earlier column
//! k < j, both l_ik and l_jk are nonzero: eliminating unknown k couples all of its remaining
//! neighbours with each other (the elimination graph). The entries created that way are the fill;
//! the ordering decides how many there are, and minimum degree (eliminate next the unknown with the
//! fewest remaining neighbours) keeps them few without the envelope's constraint that all of
//! them lie next to the diagonal. The statistic reported is
//!
//! ```text
//!     fill = nnz(L) / nnz(lower triangle of A)    (both with the diagonal),
//! ```
//!
//! where nnz(L) counts the entries the factor stores: in a supernodal factor, the lower
//! triangle of each supernode's diagonal block and its full off-diagonal block, so the explicit
//! zeros that supernode amalgamation admits for speed are counted too.
//!
//! # The matrix handed to faer
//!
//! faer takes compressed sparse columns. The lower triangle of a symmetric matrix stored by rows
//! (a [`SymCsr`]) is, read by columns, the upper triangle of the same matrix: row i's columns
//! j <= i are column i's rows j <= i. So the [`SymCsr`] arrays are passed to faer as they are,
//! as the upper side of the matrix, without a copy.

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::solvers::LltError;
use faer::sparse::linalg::cholesky::{
    factorize_symbolic_cholesky, LltRef, SymbolicCholesky, SymbolicCholeskyRaw, SymmetricOrdering,
};
use faer::sparse::{FaerError, SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Conj, MatMut, Par, Side};

use super::check::{check_rhs, check_serial};
use super::{SpdSolve, SymCsr};
use crate::error::{Error, Result};

const WHO: &str = "sparse Cholesky";

/// The sizes of a sparse Cholesky factorisation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CholeskyStats {
    /// The order n.
    pub order: usize,
    /// Nonzeros of A's lower triangle, diagonal included.
    pub lower_nnz: usize,
    /// Entries stored for the factor L, diagonal included (see the module documentation).
    pub factor_nnz: usize,
    /// Number of supernodes, or `None` when faer chose the simplicial (column by column)
    /// factorisation.
    pub supernodes: Option<usize>,
}

impl CholeskyStats {
    /// nnz(L) / nnz(lower triangle of A).
    pub fn fill(&self) -> f64 {
        self.factor_nnz as f64 / (self.lower_nnz as f64).max(1.0)
    }
}

/// The sparse Cholesky factorisation of a [`SymCsr`] held whole on one process.
#[derive(Debug)]
pub struct SparseCholesky {
    symbolic: SymbolicCholesky<usize>,
    values: Vec<f64>,
    par: Par,
    stats: CholeskyStats,
}

/// The crate's error for a faer failure that is not a pivot.
fn faer_error(e: FaerError, n: usize) -> Error {
    match e {
        FaerError::OutOfMemory => {
            Error::Memory(format!("{WHO}: the factor of a sparse matrix of order {n} does not fit in memory"))
        }
        other => Error::Numerical(format!("{WHO}: faer failed on a matrix of order {n}: {other:?}")),
    }
}

impl SparseCholesky {
    /// Orders (approximate minimum degree), analyses and factors `a`, which must hold the whole
    /// matrix (rows 0..n). `par` is the parallelism of faer's dense kernels inside supernodes and
    /// of the solves (`Par::Seq` for one thread). Fails with [`Error::NotDefinite`] when a pivot
    /// is not positive, [`Error::Memory`] when the factor cannot be allocated.
    pub fn factor(a: &SymCsr, par: Par) -> Result<Self> {
        check_serial(a, WHO)?;
        let n = a.n;
        // the lower triangle by rows is the upper triangle by columns (module documentation)
        let pattern = SymbolicSparseColMatRef::new_checked(n, n, &a.row_ptr, None, &a.cols);
        let symbolic =
            factorize_symbolic_cholesky(pattern, Side::Upper, SymmetricOrdering::Amd, Default::default())
                .map_err(|e| faer_error(e, n))?;
        let mut values = Vec::new();
        values.try_reserve_exact(symbolic.len_val()).map_err(|_| faer_error(FaerError::OutOfMemory, n))?;
        values.resize(symbolic.len_val(), 0.0);
        let scratch = symbolic.factorize_numeric_llt_scratch::<f64>(par, Default::default());
        let mut buffer = MemBuffer::try_new(scratch).map_err(|_| faer_error(FaerError::OutOfMemory, n))?;
        symbolic
            .factorize_numeric_llt(
                &mut values,
                SparseColMatRef::new(pattern, &a.vals),
                Side::Upper,
                Default::default(),
                par,
                MemStack::new(&mut buffer),
                Default::default(),
            )
            .map_err(|LltError::NonPositivePivot { index }| {
                Error::NotDefinite(format!(
                    "{WHO}: a pivot is not positive (near step {index} of {n} of the minimum-degree \
                     order): the matrix is not positive definite"
                ))
            })?;
        let (factor_nnz, supernodes) = factor_size(&symbolic);
        let stats = CholeskyStats { order: n, lower_nnz: a.nnz(), factor_nnz, supernodes };
        Ok(SparseCholesky { symbolic, values, par, stats })
    }

    /// The sizes of A and of its factor.
    pub fn stats(&self) -> &CholeskyStats {
        &self.stats
    }
}

/// Entries stored for L (diagonal blocks counted as triangles), and the number of supernodes of
/// a supernodal factor.
fn factor_size(symbolic: &SymbolicCholesky<usize>) -> (usize, Option<usize>) {
    match symbolic.raw() {
        SymbolicCholeskyRaw::Simplicial(s) => (s.len_val(), None),
        SymbolicCholeskyRaw::Supernodal(s) => {
            let nnz = (0..s.n_supernodes())
                .map(|k| {
                    let cols = s.supernode_end()[k] - s.supernode_begin()[k];
                    cols * (cols + 1) / 2 + cols * s.supernode(k).pattern().len()
                })
                .sum();
            (nnz, Some(s.n_supernodes()))
        }
    }
}

impl SpdSolve for SparseCholesky {
    fn order(&self) -> usize {
        self.stats.order
    }

    fn solve_in_place(&self, rhs: &mut [f64], nrhs: usize) -> Result<()> {
        let n = self.order();
        check_rhs(rhs, n, nrhs, WHO)?;
        if n == 0 || nrhs == 0 {
            return Ok(());
        }
        let scratch = self.symbolic.solve_in_place_scratch::<f64>(nrhs, self.par);
        let mut buffer = MemBuffer::try_new(scratch).map_err(|_| faer_error(FaerError::OutOfMemory, n))?;
        LltRef::new(&self.symbolic, &self.values).solve_in_place_with_conj(
            Conj::No,
            MatMut::from_column_major_slice_mut(rhs, n, nrhs),
            self.par,
            MemStack::new(&mut buffer),
        );
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::linalg::dense::lu_solve;
    use crate::linalg::sparse::test_support::{bunny, dense, kernel_matrix, rel_diff, rhs};

    #[test]
    fn solves_a_bunny_kernel_matrix_like_a_dense_solve() {
        let pts = bunny(10);
        let a = kernel_matrix(&pts, 0.2);
        let n = a.n;
        let chol = SparseCholesky::factor(&a, Par::Seq).unwrap();
        assert_eq!(chol.order(), n);
        let bs: Vec<Vec<f64>> = (0..3).map(|t| rhs(n, t as f64)).collect();
        let mut x = bs.concat();
        chol.solve_in_place(&mut x, 3).unwrap();
        let m = dense(&a);
        for (t, b) in bs.iter().enumerate() {
            let want = lu_solve(m.as_ref(), b).unwrap();
            let err = rel_diff(&x[t * n..(t + 1) * n], &want);
            assert!(err < 1e-10, "sparse Cholesky vs dense LU, right-hand side {t}: {err:e}");
        }
        let s = chol.stats();
        assert_eq!(s.lower_nnz, a.nnz());
        assert!(s.factor_nnz >= s.lower_nnz && s.fill() >= 1.0, "{s:?}");
    }

    #[test]
    fn a_denser_matrix_takes_the_supernodal_path_and_agrees_with_a_dense_solve() {
        let a = kernel_matrix(&bunny(10), 0.5);
        let chol = SparseCholesky::factor(&a, Par::Seq).unwrap();
        let s = *chol.stats();
        let n = a.n;
        assert!(s.supernodes.is_some(), "{s:?}");
        assert!(s.factor_nnz >= s.lower_nnz && s.factor_nnz <= n * (n + 1) / 2, "{s:?}");
        let b = rhs(n, 0.5);
        let mut x = b.clone();
        chol.solve_in_place(&mut x, 1).unwrap();
        let want = lu_solve(dense(&a).as_ref(), &b).unwrap();
        let err = rel_diff(&x, &want);
        assert!(err < 1e-10, "supernodal Cholesky vs dense LU: {err:e}");
    }

    #[test]
    fn an_indefinite_matrix_is_not_definite() {
        let mut a = kernel_matrix(&bunny(20), 0.2);
        let diag = a.row_ptr[41] - 1; // the diagonal entry of row 40
        a.vals[diag] = -2.0;
        let err = SparseCholesky::factor(&a, Par::Seq).unwrap_err();
        assert!(err.is_not_definite(), "{err:?}");
    }

    #[test]
    fn malformed_input_is_an_error_not_a_panic() {
        let mut a = kernel_matrix(&bunny(50), 0.2);
        a.row_ptr.pop();
        assert!(matches!(SparseCholesky::factor(&a, Par::Seq), Err(Error::Numerical(_))));
        let a = kernel_matrix(&bunny(50), 0.2);
        let chol = SparseCholesky::factor(&a, Par::Seq).unwrap();
        assert!(matches!(chol.solve_in_place(&mut vec![0.0; a.n + 1], 1), Err(Error::Usage(_))));
    }
}
