//! Unblocked LU with partial pivoting, x = U^-1 L^-1 P b.

use super::Matrix;
use crate::error::{Error, Result};

/// Solves the square system M x = b by Gaussian elimination with partial pivoting.
pub fn lu_solve(m: &Matrix, b: &[f64]) -> Result<Vec<f64>> {
    assert_eq!(m.rows, m.cols, "lu_solve needs a square matrix");
    assert_eq!(b.len(), m.rows);
    let n = m.rows;
    let mut a = m.clone();
    let mut y = b.to_vec();
    let scale = a.data.iter().fold(0.0f64, |s, v| s.max(v.abs()));
    for j in 0..n {
        let (piv, pmax) =
            (j..n)
                .map(|i| (i, a.get(i, j).abs()))
                .fold((j, -1.0), |best, c| if c.1 > best.1 { c } else { best });
        if pmax <= scale * 1e-14 * n as f64 {
            return Err(Error::Numerical(format!("matrix is singular: no pivot in column {j}")));
        }
        if piv != j {
            for c in 0..n {
                let t = a.get(j, c);
                a.set(j, c, a.get(piv, c));
                a.set(piv, c, t);
            }
            y.swap(j, piv);
        }
        let d = a.get(j, j);
        for i in j + 1..n {
            let l = a.get(i, j) / d;
            if l != 0.0 {
                for c in j + 1..n {
                    a.set(i, c, a.get(i, c) - l * a.get(j, c));
                }
                y[i] -= l * y[j];
            }
        }
    }
    let mut x = vec![0.0; n];
    for i in (0..n).rev() {
        let s: f64 = (i + 1..n).map(|j| a.get(i, j) * x[j]).sum();
        x[i] = (y[i] - s) / a.get(i, i);
    }
    Ok(x)
}
