//! Serial dense solvers on one process: unblocked Householder QR (the reflectors of
//! [`crate::linalg::reflector`]) and LU with partial pivoting (Golub & Van Loan, algorithms 5.2.1
//! and 3.4.1). They are the oracle the distributed solvers are tested against and the tool for
//! small local problems (rank checks, space maps); [`lu_solve_blocked`] is faer's blocked LU on
//! one thread, for the per-slice systems. They take faer matrix views of any strides, work on a
//! copy and never touch MPI.

mod householder;
mod lu;

use faer::MatRef;

pub use householder::{householder_solve, qr_r_diagonal};
pub use lu::{lu_solve, lu_solve_blocked, BlockedLu};

/// The entries of `m`, column-major with leading dimension `m.nrows()`, whatever its strides.
fn column_major(m: MatRef<'_, f64>) -> Vec<f64> {
    (0..m.ncols()).flat_map(|j| (0..m.nrows()).map(move |i| m[(i, j)])).collect()
}

/// ||M x - b|| / ||b|| (or ||M x - b|| when b = 0), column by column.
pub fn relative_residual(m: MatRef<'_, f64>, x: &[f64], b: &[f64]) -> f64 {
    let mut r: Vec<f64> = b.iter().map(|v| -v).collect();
    for (j, &xj) in x.iter().enumerate().take(m.ncols()) {
        if xj != 0.0 {
            for (ri, mij) in r.iter_mut().zip(m.col(j).iter()) {
                *ri += mij * xj;
            }
        }
    }
    let num: f64 = r.iter().map(|v| v * v).sum::<f64>().sqrt();
    let den: f64 = b.iter().map(|v| v * v).sum::<f64>().sqrt();
    if den > 0.0 {
        num / den
    } else {
        num
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use faer::Mat;

    /// A symmetric indefinite test matrix with a zero diagonal, like the spline system.
    pub(crate) fn test_system(n: usize) -> (Mat<f64>, Vec<f64>) {
        let mut seed = 12345u64;
        let mut rnd = move || {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let mut m = Mat::<f64>::zeros(n, n);
        for i in 0..n {
            for j in 0..i {
                let v = rnd();
                m[(i, j)] = v;
                m[(j, i)] = v;
            }
        }
        let b = (0..n).map(|_| rnd()).collect();
        (m, b)
    }

    #[test]
    fn both_solvers_solve_an_indefinite_system() {
        let (m, b) = test_system(60);
        let x1 = householder_solve(m.as_ref(), &b).unwrap();
        let x2 = lu_solve(m.as_ref(), &b).unwrap();
        assert!(relative_residual(m.as_ref(), &x1, &b) < 1e-12);
        assert!(relative_residual(m.as_ref(), &x2, &b) < 1e-12);
        let diff = x1.iter().zip(&x2).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
        let scale = x1.iter().map(|v| v.abs()).fold(0.0, f64::max);
        assert!(diff < 1e-10 * scale);
    }

    #[test]
    fn singular_systems_are_reported() {
        let m = Mat::<f64>::from_fn(3, 3, |i, j| ((i + 1) * (j + 1)) as f64);
        assert!(lu_solve(m.as_ref(), &[1.0, 2.0, 3.0]).is_err());
        assert!(householder_solve(m.as_ref(), &[1.0, 2.0, 3.0]).is_err());
    }
}
