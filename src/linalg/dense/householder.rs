//! Householder QR, x = R^-1 Q^T b, and the diagonal of R for rank checks.

use faer::MatRef;

use super::column_major;
use crate::error::{Error, Result};
use crate::linalg::reflector::qr_in_place;

/// Solves the square system M x = b by Householder QR: b travels as an extra column, so it
/// receives Q^T b from the same reflectors that triangularise M.
pub fn householder_solve(m: MatRef<'_, f64>, b: &[f64]) -> Result<Vec<f64>> {
    assert_eq!(m.nrows(), m.ncols(), "householder_solve needs a square matrix");
    assert_eq!(b.len(), m.nrows());
    let n = m.nrows();
    let mut a = column_major(m);
    a.extend_from_slice(b);
    qr_in_place(&mut a, n, n);
    let (r, y) = a.split_at(n * n);
    let scale = (0..n).fold(0.0f64, |s, i| s.max(r[i + i * n].abs()));
    let mut x = vec![0.0; n];
    for i in (0..n).rev() {
        let d = r[i + i * n];
        if d.abs() <= scale * 1e-14 * n as f64 {
            return Err(Error::Numerical(format!("matrix is singular: zero in R at column {i}")));
        }
        let s: f64 = (i + 1..n).map(|j| r[i + j * n] * x[j]).sum();
        x[i] = (y[i] - s) / d;
    }
    Ok(x)
}

/// |diag(R)| of the QR factorisation of a tall matrix, for rank decisions.
pub fn qr_r_diagonal(m: MatRef<'_, f64>) -> Vec<f64> {
    let rows = m.nrows();
    let mut a = column_major(m);
    let steps = qr_in_place(&mut a, rows, m.ncols()).len();
    (0..steps).map(|j| a[j + j * rows].abs()).collect()
}
