//! Unblocked Householder QR, x = R^-1 Q^T b, and the diagonal of R for rank checks.

use super::Matrix;
use crate::error::{Error, Result};

/// Applies the reflectors column by column to `a` (m x n, m >= n) and to `rhs` (if given);
/// returns the diagonal of R. Zero columns give a zero diagonal entry and an identity reflector.
fn triangularise(a: &mut Matrix, mut rhs: Option<&mut [f64]>) -> Vec<f64> {
    let (m, n) = (a.rows, a.cols);
    let mut diag = Vec::with_capacity(n);
    for j in 0..n.min(m) {
        let norm = (j..m).map(|i| a.get(i, j).powi(2)).sum::<f64>().sqrt();
        if norm == 0.0 {
            diag.push(0.0);
            continue;
        }
        let x0 = a.get(j, j);
        let alpha = if x0 >= 0.0 { -norm } else { norm };
        // v = x - alpha e1, H = I - 2 v v^T / (v^T v)
        let mut v: Vec<f64> = (j..m).map(|i| a.get(i, j)).collect();
        v[0] -= alpha;
        let vtv: f64 = v.iter().map(|x| x * x).sum();
        for c in j..n {
            let dot: f64 = v.iter().enumerate().map(|(t, vi)| vi * a.get(j + t, c)).sum();
            let s = 2.0 * dot / vtv;
            for (t, vi) in v.iter().enumerate() {
                a.set(j + t, c, a.get(j + t, c) - s * vi);
            }
        }
        if let Some(b) = rhs.as_deref_mut() {
            let dot: f64 = v.iter().enumerate().map(|(t, vi)| vi * b[j + t]).sum();
            let s = 2.0 * dot / vtv;
            for (t, vi) in v.iter().enumerate() {
                b[j + t] -= s * vi;
            }
        }
        diag.push(alpha);
    }
    diag
}

/// Solves the square system M x = b by Householder QR.
pub fn householder_solve(m: &Matrix, b: &[f64]) -> Result<Vec<f64>> {
    assert_eq!(m.rows, m.cols, "householder_solve needs a square matrix");
    assert_eq!(b.len(), m.rows);
    let n = m.rows;
    let mut a = m.clone();
    let mut y = b.to_vec();
    let diag = triangularise(&mut a, Some(&mut y));
    let scale = diag.iter().fold(0.0f64, |s, d| s.max(d.abs()));
    let mut x = vec![0.0; n];
    for i in (0..n).rev() {
        if diag[i].abs() <= scale * 1e-14 * n as f64 {
            return Err(Error::Numerical(format!("matrix is singular: zero in R at column {i}")));
        }
        let s: f64 = (i + 1..n).map(|j| a.get(i, j) * x[j]).sum();
        x[i] = (y[i] - s) / a.get(i, i);
    }
    Ok(x)
}

/// |diag(R)| of the QR factorisation of a tall matrix, for rank decisions.
pub fn qr_r_diagonal(m: &Matrix) -> Vec<f64> {
    let mut a = m.clone();
    triangularise(&mut a, None).into_iter().map(f64::abs).collect()
}
