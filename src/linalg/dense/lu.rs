//! LU with partial pivoting, x = U^-1 L^-1 P b: unblocked (the oracle) and faer's blocked one.

use faer::linalg::triangular_solve::{solve_unit_lower_triangular_in_place, solve_upper_triangular_in_place};
use faer::{Mat, MatRef, Par};

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

/// M x = b by faer's blocked LU with partial pivoting, on the calling thread: the tool for local
/// systems too large for the unblocked [`lu_solve`] (a contour slice of thousands of points: 9x
/// faster at 3000), several of which run side by side on a rank's threads. Singular by the same
/// test as [`lu_solve`]: a pivot not above 1e-14 n times the largest entry.
pub fn lu_solve_blocked(m: MatRef<'_, f64>, b: &[f64]) -> Result<Vec<f64>> {
    Ok(BlockedLu::factor(m)?.solve(b))
}

/// faer's blocked LU with partial pivoting of a square matrix, P M = L U, computed on the calling
/// thread and kept for several right-hand sides (the three components of a space map share one).
pub struct BlockedLu {
    lu: Mat<f64>,
    /// Row i of P M is row `perm[i]` of M.
    perm: Vec<usize>,
}

impl BlockedLu {
    /// Factors `m`; singular by the test of [`lu_solve`].
    pub fn factor(m: MatRef<'_, f64>) -> Result<Self> {
        use faer::dyn_stack::{MemBuffer, MemStack};
        use faer::linalg::lu::partial_pivoting::factor;
        assert_eq!(m.nrows(), m.ncols(), "BlockedLu::factor needs a square matrix");
        let n = m.nrows();
        let scale = (0..n).map(|j| m.col(j).iter().map(|v| v.abs()).fold(0.0, f64::max)).fold(0.0, f64::max);
        let mut lu = m.to_owned();
        let (mut fwd, mut bwd) = (vec![0usize; n], vec![0usize; n]);
        let params = Default::default();
        let mut mem = MemBuffer::new(factor::lu_in_place_scratch::<usize, f64>(n, n, Par::Seq, params));
        let (_, perm) =
            factor::lu_in_place(lu.as_mut(), &mut fwd, &mut bwd, Par::Seq, MemStack::new(&mut mem), params);
        let perm = perm.arrays().0.to_vec();
        if let Some(j) = (0..n).find(|&j| !(lu[(j, j)].abs() > scale * 1e-14 * n as f64)) {
            return Err(Error::Numerical(format!("matrix is singular: no pivot in column {j}")));
        }
        Ok(BlockedLu { lu, perm })
    }

    /// x = U^-1 L^-1 P b.
    pub fn solve(&self, b: &[f64]) -> Vec<f64> {
        let n = self.perm.len();
        assert_eq!(b.len(), n);
        let mut x = Mat::<f64>::from_fn(n, 1, |i, _| b[self.perm[i]]);
        solve_unit_lower_triangular_in_place(self.lu.as_ref(), x.as_mut(), Par::Seq);
        solve_upper_triangular_in_place(self.lu.as_ref(), x.as_mut(), Par::Seq);
        x.col(0).iter().copied().collect()
    }
}
