//! Block back-substitution on a row-cyclic upper-triangular factor (R of QR, U of LU) whose
//! right-hand side column already holds the transformed right-hand side.

use super::system::{all_gather_rows, LocalRows};
use crate::error::{Error, Result};
use crate::par::Comm;

/// Solves U x = y where U is the upper triangle of the first n columns and y the last column.
/// Returns x on every rank. A diagonal entry at most `tol` in magnitude is a singular matrix.
/// Collective: one all-gather of a diagonal block per `panel` rows; each rank updates its own y.
pub fn back_substitute(comm: &dyn Comm, rows: &mut LocalRows, panel: usize, tol: f64) -> Result<Vec<f64>> {
    let lay = rows.layout;
    let n = lay.n;
    let rhs = rows.cols - 1;
    let ld = rows.ld();
    let mut x = vec![0.0; n];
    let mut b1 = n;
    while b1 > 0 {
        let b0 = b1.saturating_sub(panel.max(1));
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
            x[b0 + i] = (row[bs] - s) / d;
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
