//! Block back-substitution on a row-cyclic upper-triangular factor (R of QR, U of LU) whose
//! right-hand side column already holds the transformed right-hand side.
//!
//! A triangular factor is taken in blocks of `panel` rows from the bottom. The LU's block form
//! ([`Rows::BlockLu`]) must be taken in the factorisation's own panels, counted from the top
//! (rows 0..nb, nb..2nb, ..., the last one shorter): its block rows hold A12 as the
//! factorisation left it, not U12 = L11^-1 A12, and the right-hand side's entries c1 are not
//! multiplied by L11^-1 either. Since U11 x1 + U12 x2 = L11^-1 c1,
//!
//! ```text
//!     x1 = U11^-1 L11^-1 (c1 - A12 x2),
//! ```
//!
//! so the column-wise updates of the rows above a block (y -= A[.., block] x_block) are the same
//! for both forms, and the block form adds one unit lower triangular solve with L11 on the
//! block's right-hand side before U11's.

use super::system::{all_gather_rows, LocalRows};
use crate::error::{Error, Result};
use crate::par::Comm;

/// What the rows of a factor hold right of their diagonal blocks.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Rows {
    /// U (R): the upper triangle, the right-hand side transformed with it.
    Triangular,
    /// The LU's block form: each panel's diagonal block holds L11\U11, the columns right of it
    /// hold A12, and the right-hand side is not multiplied by L11^-1 (see the module
    /// documentation).
    BlockLu,
}

/// Solves U x = y where U is the upper triangle of the first n columns and y the last column
/// (for [`Rows::BlockLu`], the block form). `panel` is the factorisation's panel width. Returns
/// x on every rank. A diagonal entry at most `tol` in magnitude is a singular matrix.
/// Collective: one all-gather of a diagonal block per panel; each rank updates its own y.
pub fn back_substitute(
    comm: &dyn Comm,
    rows: &mut LocalRows,
    panel: usize,
    form: Rows,
    tol: f64,
) -> Result<Vec<f64>> {
    let lay = rows.layout;
    let n = lay.n;
    let rhs = rows.cols - 1;
    let ld = rows.ld();
    let nb = panel.max(1);
    let mut x = vec![0.0; n];
    let mut b1 = n;
    while b1 > 0 {
        let b0 = match form {
            Rows::Triangular => b1.saturating_sub(nb),
            // the panel that ends at b1, counted from the top: the last one may be shorter
            Rows::BlockLu => (b1 - 1) / nb * nb,
        };
        let bs = b1 - b0;
        // diagonal block and its right-hand side, replicated: bs rows of (bs + 1) values
        let (l0, l1) = (lay.first_local_from(b0), lay.first_local_from(b1));
        let mut send = Vec::with_capacity((l1 - l0) * (bs + 1));
        for l in l0..l1 {
            for c in b0..b1 {
                send.push(rows.data[l + c * ld]);
            }
            send.push(rows.data[l + rhs * ld]);
        }
        let block = all_gather_rows(comm, lay, &send, b0..b1, bs + 1);
        let mut z: Vec<f64> = (0..bs).map(|i| block[i * (bs + 1) + bs]).collect();
        if form == Rows::BlockLu {
            solve_unit_lower_rows(&block, bs + 1, &mut z);
        }
        for i in (0..bs).rev() {
            let row = &block[i * (bs + 1)..(i + 1) * (bs + 1)];
            let d = row[i];
            if !(d.abs() > tol) {
                return Err(Error::Numerical(format!(
                    "the system is singular to working precision: diagonal {:.3e} at row {} of {}",
                    d,
                    b0 + i,
                    n
                )));
            }
            let s: f64 = (i + 1..bs).map(|j| row[j] * x[b0 + j]).sum();
            x[b0 + i] = (z[i] - s) / d;
        }
        // y_l -= U[l, b0..b1] x[b0..b1] for this rank's rows above the block
        let lend = lay.first_local_from(b0);
        for (c, xc) in (b0..b1).zip(&x[b0..b1]) {
            let col = c * ld;
            for l in 0..lend {
                rows.data[l + rhs * ld] -= rows.data[l + col] * xc;
            }
        }
        b1 = b0;
    }
    Ok(x)
}

/// z <- L11^-1 z for the unit lower triangle of a block stored row by row, `stride` values a row
/// (its entries below the diagonal are read): a block form's diagonal solve.
pub(super) fn solve_unit_lower_rows(block: &[f64], stride: usize, z: &mut [f64]) {
    for i in 0..z.len() {
        let row = &block[i * stride..i * stride + i];
        z[i] -= row.iter().zip(&z[..i]).map(|(l, z)| l * z).sum::<f64>();
    }
}
