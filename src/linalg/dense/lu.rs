//! Unblocked LU with partial pivoting, x = U^-1 L^-1 P b.

use faer::MatRef;

use super::column_major;
use crate::error::{Error, Result};

/// Solves the square system M x = b by Gaussian elimination with partial pivoting.
pub fn lu_solve(m: MatRef<'_, f64>, b: &[f64]) -> Result<Vec<f64>> {
    assert_eq!(m.nrows(), m.ncols(), "lu_solve needs a square matrix");
    assert_eq!(b.len(), m.nrows());
    let n = m.nrows();
    let mut a = column_major(m);
    let at = |i: usize, j: usize| i + j * n;
    let mut y = b.to_vec();
    let scale = a.iter().fold(0.0f64, |s, v| s.max(v.abs()));
    for j in 0..n {
        let (piv, pmax) =
            (j..n)
                .map(|i| (i, a[at(i, j)].abs()))
                .fold((j, -1.0), |best, c| if c.1 > best.1 { c } else { best });
        if pmax <= scale * 1e-14 * n as f64 {
            return Err(Error::Numerical(format!("matrix is singular: no pivot in column {j}")));
        }
        if piv != j {
            for c in 0..n {
                a.swap(at(j, c), at(piv, c));
            }
            y.swap(j, piv);
        }
        let d = a[at(j, j)];
        for i in j + 1..n {
            a[at(i, j)] /= d;
        }
        // rank-1 update of the trailing block, column by column (contiguous)
        for c in j + 1..n {
            let u = a[at(j, c)];
            if u != 0.0 {
                for i in j + 1..n {
                    a[at(i, c)] -= a[at(i, j)] * u;
                }
            }
        }
        for i in j + 1..n {
            y[i] -= a[at(i, j)] * y[j];
        }
    }
    let mut x = vec![0.0; n];
    for i in (0..n).rev() {
        let s: f64 = (i + 1..n).map(|j| a[at(i, j)] * x[j]).sum();
        x[i] = (y[i] - s) / a[at(i, i)];
    }
    Ok(x)
}
