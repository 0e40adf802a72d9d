//! Sparse symmetric positive definite systems, the linear algebra of compactly supported splines:
//! the matrix format shared by assembly and the solvers ([`SymCsr`]), and the interface every
//! factorisation offers ([`SpdSolve`]).
//!
//! The serial solvers: [`envelope`] (Jennings' envelope storage and the envelope Cholesky, for
//! centres ordered spatially), [`cholesky`] (faer's supernodal sparse Cholesky with a
//! minimum-degree ordering, the production solver), [`ordering`] (reverse Cuthill-McKee) and
//! [`bordered`] (the spline's bordered system [A P; P^T 0] by block elimination on top of any of
//! them).

pub mod bordered;
mod check;
pub mod cholesky;
pub mod envelope;
pub mod ordering;
#[cfg(test)]
mod test_support;

pub use bordered::bordered_solve;
pub use cholesky::{CholeskyStats, SparseCholesky};
pub use envelope::{envelope_size, Envelope, EnvelopeCholesky, EnvelopeStats};
pub use ordering::reverse_cuthill_mckee;

use crate::error::Result;

/// The lower triangle (diagonal included) of a symmetric n x n matrix in compressed sparse rows:
/// row i holds the entries `(i, cols[k]) = vals[k]` for k in `row_ptr[i]..row_ptr[i + 1]`, with
/// column indices strictly increasing and at most i. For a distributed matrix, `rows` lists the
/// global rows held here (row_ptr has rows.len() + 1 entries); on one process it is 0..n.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SymCsr {
    pub n: usize,
    pub rows: Vec<usize>,
    pub row_ptr: Vec<usize>,
    pub cols: Vec<usize>,
    pub vals: Vec<f64>,
}

impl SymCsr {
    /// Stored entries (the lower triangle's nonzeros held here).
    pub fn nnz(&self) -> usize {
        self.vals.len()
    }

    /// The entries of local row `l`: (global column, value).
    pub fn row(&self, l: usize) -> impl Iterator<Item = (usize, f64)> + '_ {
        let r = self.row_ptr[l]..self.row_ptr[l + 1];
        self.cols[r.clone()].iter().copied().zip(self.vals[r].iter().copied())
    }
}

/// A factorised symmetric positive definite matrix that solves systems with it.
pub trait SpdSolve {
    /// The order n of the matrix.
    fn order(&self) -> usize;
    /// Overwrites `rhs` (n x nrhs, column-major, the same on every rank for a distributed
    /// factorisation) with the solution. Collective for a distributed factorisation.
    fn solve_in_place(&self, rhs: &mut [f64], nrhs: usize) -> Result<()>;
}
