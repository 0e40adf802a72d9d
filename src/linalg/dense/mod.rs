//! Serial dense solvers on one process: the textbook Householder QR and LU with partial pivoting
//! (Golub & Van Loan, algorithms 5.2.1 and 3.4.1). They are the oracle the distributed solvers are
//! tested against and the tool for small local problems (rank checks, per-slice systems). They
//! never touch MPI.

mod householder;
mod lu;

pub use householder::{householder_solve, qr_r_diagonal};
pub use lu::lu_solve;

/// A dense square or rectangular matrix, column-major.
#[derive(Debug, Clone, PartialEq)]
pub struct Matrix {
    pub rows: usize,
    pub cols: usize,
    pub data: Vec<f64>,
}

impl Matrix {
    pub fn zeros(rows: usize, cols: usize) -> Self {
        Matrix { rows, cols, data: vec![0.0; rows * cols] }
    }

    pub fn from_fn(rows: usize, cols: usize, f: impl Fn(usize, usize) -> f64) -> Self {
        let mut m = Matrix::zeros(rows, cols);
        for j in 0..cols {
            for i in 0..rows {
                m.data[i + j * rows] = f(i, j);
            }
        }
        m
    }

    #[inline]
    pub fn get(&self, i: usize, j: usize) -> f64 {
        self.data[i + j * self.rows]
    }

    #[inline]
    pub fn set(&mut self, i: usize, j: usize, v: f64) {
        self.data[i + j * self.rows] = v;
    }

    pub fn mul_vec(&self, x: &[f64]) -> Vec<f64> {
        let mut y = vec![0.0; self.rows];
        for j in 0..self.cols {
            let col = &self.data[j * self.rows..(j + 1) * self.rows];
            for (yi, a) in y.iter_mut().zip(col) {
                *yi += a * x[j];
            }
        }
        y
    }
}

/// ||M x - b|| / ||b|| (or ||M x - b|| when b = 0).
pub fn relative_residual(m: &Matrix, x: &[f64], b: &[f64]) -> f64 {
    let r = m.mul_vec(x);
    let num: f64 = r.iter().zip(b).map(|(a, b)| (a - b) * (a - b)).sum::<f64>().sqrt();
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

    /// A symmetric indefinite test matrix with a zero diagonal, like the spline system.
    pub(crate) fn test_system(n: usize) -> (Matrix, Vec<f64>) {
        let mut seed = 12345u64;
        let mut rnd = move || {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let mut m = Matrix::zeros(n, n);
        for i in 0..n {
            for j in 0..i {
                let v = rnd();
                m.set(i, j, v);
                m.set(j, i, v);
            }
        }
        let b = (0..n).map(|_| rnd()).collect();
        (m, b)
    }

    #[test]
    fn both_solvers_solve_an_indefinite_system() {
        let (m, b) = test_system(60);
        let x1 = householder_solve(&m, &b).unwrap();
        let x2 = lu_solve(&m, &b).unwrap();
        assert!(relative_residual(&m, &x1, &b) < 1e-12);
        assert!(relative_residual(&m, &x2, &b) < 1e-12);
        let diff = x1.iter().zip(&x2).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
        let scale = x1.iter().map(|v| v.abs()).fold(0.0, f64::max);
        assert!(diff < 1e-10 * scale);
    }

    #[test]
    fn singular_systems_are_reported() {
        let m = Matrix::from_fn(3, 3, |i, j| ((i + 1) * (j + 1)) as f64);
        assert!(lu_solve(&m, &[1.0, 2.0, 3.0]).is_err());
        assert!(householder_solve(&m, &[1.0, 2.0, 3.0]).is_err());
    }
}
