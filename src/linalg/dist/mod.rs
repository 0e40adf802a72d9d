//! Distributed dense solvers of the bordered spline system on the row-cyclic layout: global row g
//! lives on rank g mod p, every rank holds its rows with the right-hand side as the last column,
//! and no solver ever gathers the matrix. Blocked Householder QR, LU with partial pivoting and the
//! projected Cholesky; [`solve`] chooses among them and falls back from Cholesky to LU.
//! [`solve_in`] adds the mixed-precision solve: the projected Cholesky or LU in f32 (the
//! factorisations are generic over [`Scalar`]), refined in f64 against the whole bordered system
//! by classical refinement and GMRES-IR ([`mixed_solve`]), with a fallback to f64 when the f32
//! factorisation fails or the refinement does not reach the accuracy of an f64 solve.
//!
//! [`extend_solve`] borders a kept projected Cholesky factor ([`solve_keeping`]; from the 2D
//! layout [`solve_2d_keeping`], which moves the factor to the row-cyclic layout by all-to-all
//! exchanges, [`LocalBlocks::to_row_cyclic`]) by appended centres, for a second fit that adds
//! constraint points to the first; [`solve_bordered`] solves the bordered system again for other
//! values of the same centres, [`solve_bordered_many`] for several at once.
//!
//! Every solver takes the panel width nb and a `faer::Par`. The panel kernels and the
//! collectives are serial; the `Par` goes to the local GEMMs and triangular solves of the
//! trailing updates, where the flops are: `Par::rayon(t)` gives each rank t threads.

mod backsub;
mod cholesky;
mod cholesky2d;
mod extend;
mod grid;
mod householder;
mod householder2d;
mod layout;
mod lu;
mod lu2d;
mod mixed;
mod mixed_cholesky;
mod refine;
mod scalar;
mod solver;
mod system;
#[cfg(test)]
mod test_support;

pub use cholesky::cholesky_solve;
pub use cholesky2d::cholesky2d_solve;
pub use extend::{
    extend_solve, kept_most, solve_bordered, solve_bordered_many, Appended, Bordered, Factored, KEPT_FLOOR,
    KEPT_SHARE,
};
pub use grid::{squarest, BlockCyclic, Layout, LocalBlocks, ProcessGrid};
pub use householder::householder_solve;
pub use householder2d::householder2d_solve;
pub use layout::RowCyclic;
pub use lu::{lu_factor, lu_solve};
pub use lu2d::{lu2d_factor, lu2d_solve};
pub use refine::{mixed_solve, Refinement};
pub use scalar::Scalar;
pub use solver::{
    solve, solve_2d, solve_2d_keeping, solve_in, solve_keeping, Job, Precision, Solved, SolverKind,
    AUTO_CHOLESKY_FROM, LOOKAHEAD,
};
pub use system::{all_gather_rows, GatherBuffers, LocalRows};
