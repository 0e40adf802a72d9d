//! The bordered system of a compactly supported spline, solved by block elimination with any
//! factorisation of its sparse block (George & Liu 1981, the bordering of a sparse matrix).
//!
//! # Block elimination
//!
//! The system is
//!
//! ```text
//!     [ A   P ] [ lambda ]   [ r ]
//!     [ P^T 0 ] [   c    ] = [ 0 ]
//! ```
//!
//! with A (N x N) sparse symmetric positive definite and P (N x k) the polynomial block (k = 4:
//! the columns 1, x, y, z at the centres). The first block row gives lambda = A^-1 (r - P c).
//! Write z = A^-1 r and Y = A^-1 P (N x k); then lambda = z - Y c, and the second block row,
//! P^T lambda = 0, becomes the k x k system
//!
//! ```text
//!     S c = P^T z,        S = P^T Y = P^T A^-1 P.
//! ```
//!
//! S is symmetric, and positive definite when P has full column rank: for v != 0, P v != 0 and
//! v^T S v = (P v)^T A^-1 (P v) > 0 because A^-1 is positive definite. When P has lower rank (for
//! k = 4, all centres on one plane) S is singular and c is not determined; that is checked on P
//! itself before anything is solved, from the QR factorisation of P with unit columns: |R_jj| is
//! the sine of the angle between column j and the span of the columns before it, and a value
//! below [`RANK_TOLERANCE`] means the columns are dependent to working precision.
//!
//! # Cost
//!
//! One factorisation of A (done by the caller), one solve with the k + 1 right-hand sides
//! [r | P] (k + 1 forward and back substitutions), 2 N k (k + 1) flops for P^T [z | Y], a dense
//! k x k Cholesky, and N k flops for lambda = z - Y c. Nothing of size N x N is ever formed.

use faer::{Mat, MatRef};

use super::SpdSolve;
use crate::error::{Error, Result};
use crate::linalg::dense::qr_r_diagonal;

/// The smallest |R_jj| of the QR factorisation of P with unit columns accepted as full rank.
pub const RANK_TOLERANCE: f64 = 1e-10;

/// Solves [A P; P^T 0] [lambda; c] = [r; 0] with `a` a factorisation of A (order N), `p` the
/// N x k polynomial block and `r` the N values; returns (lambda, c). Fails with
/// [`Error::Numerical`] when P does not have full column rank (the centres do not determine the
/// polynomial part), and with whatever `a.solve_in_place` reports.
pub fn bordered_solve(a: &dyn SpdSolve, p: MatRef<'_, f64>, r: &[f64]) -> Result<(Vec<f64>, Vec<f64>)> {
    let (n, k) = (a.order(), p.ncols());
    if p.nrows() != n || r.len() != n {
        return Err(Error::Usage(format!(
            "bordered solve: a matrix of order {n} with a {} x {k} polynomial block and {} values",
            p.nrows(),
            r.len()
        )));
    }
    check_full_rank(p)?;
    // [z | Y] = A^-1 [r | P], column-major
    let mut zy = Vec::with_capacity(n * (k + 1));
    zy.extend_from_slice(r);
    for j in 0..k {
        zy.extend((0..n).map(|i| p[(i, j)]));
    }
    a.solve_in_place(&mut zy, k + 1)?;
    let (z, y) = zy.split_at(n);
    let ycol = |j: usize| &y[j * n..(j + 1) * n];
    let pt = |i: usize, v: &[f64]| -> f64 { v.iter().enumerate().map(|(l, vl)| p[(l, i)] * vl).sum() };
    // S = P^T Y, symmetric up to rounding: symmetrised
    let mut s = Mat::<f64>::zeros(k, k);
    for j in 0..k {
        for i in 0..k {
            s[(i, j)] = pt(i, ycol(j));
        }
    }
    for j in 0..k {
        for i in 0..j {
            let m = 0.5 * (s[(i, j)] + s[(j, i)]);
            s[(i, j)] = m;
            s[(j, i)] = m;
        }
    }
    let g: Vec<f64> = (0..k).map(|i| pt(i, z)).collect();
    let c = small_spd_solve(s, g)?;
    let mut lambda = z.to_vec();
    for (j, cj) in c.iter().enumerate() {
        for (l, yl) in lambda.iter_mut().zip(ycol(j)) {
            *l -= yl * cj;
        }
    }
    Ok((lambda, c))
}

/// Fails with [`Error::Numerical`] unless P (N x k) has full column rank k.
fn check_full_rank(p: MatRef<'_, f64>) -> Result<()> {
    let (n, k) = (p.nrows(), p.ncols());
    if k == 0 {
        return Ok(());
    }
    if n < k {
        return Err(Error::Numerical(format!(
            "bordered solve: {n} centres cannot determine {k} polynomial coefficients"
        )));
    }
    let mut unit = Mat::<f64>::zeros(n, k);
    for j in 0..k {
        let norm = (0..n).map(|i| p[(i, j)].powi(2)).sum::<f64>().sqrt();
        if !(norm > 0.0) || !norm.is_finite() {
            return Err(Error::Numerical(format!(
                "bordered solve: column {j} of the polynomial block is {}",
                if norm.is_finite() { "zero" } else { "not finite" }
            )));
        }
        for i in 0..n {
            unit[(i, j)] = p[(i, j)] / norm;
        }
    }
    let r = qr_r_diagonal(unit.as_ref());
    if let Some((j, rj)) = r.iter().enumerate().find(|(_, rj)| !(**rj > RANK_TOLERANCE)) {
        return Err(Error::Numerical(format!(
            "bordered solve: the polynomial block (N = {n}, k = {k}) is rank deficient: column {j} \
             depends on the columns before it (|R_jj| = {rj:.1e} after scaling); the centres do not \
             determine the polynomial part (for 1, x, y, z: all centres lie on one plane)"
        )));
    }
    Ok(())
}

/// Solves the small symmetric positive definite system S c = g by Cholesky, S = L L^T.
fn small_spd_solve(mut s: Mat<f64>, mut g: Vec<f64>) -> Result<Vec<f64>> {
    let k = g.len();
    for j in 0..k {
        let d = s[(j, j)] - (0..j).map(|t| s[(j, t)].powi(2)).sum::<f64>();
        if !(d > 0.0) {
            return Err(Error::Numerical(format!(
                "bordered solve: P^T A^-1 P is not positive definite at pivot {j} ({d:.3e}); \
                 the polynomial block is numerically rank deficient"
            )));
        }
        let ljj = d.sqrt();
        s[(j, j)] = ljj;
        for i in j + 1..k {
            let v = s[(i, j)] - (0..j).map(|t| s[(i, t)] * s[(j, t)]).sum::<f64>();
            s[(i, j)] = v / ljj;
        }
    }
    for i in 0..k {
        g[i] = (g[i] - (0..i).map(|t| s[(i, t)] * g[t]).sum::<f64>()) / s[(i, i)];
    }
    for i in (0..k).rev() {
        g[i] = (g[i] - (i + 1..k).map(|t| s[(t, i)] * g[t]).sum::<f64>()) / s[(i, i)];
    }
    Ok(g)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::linalg::dense::lu_solve;
    use crate::linalg::sparse::test_support::{bunny, kernel_matrix, rel_diff, sorted_by_x};
    use crate::linalg::sparse::{EnvelopeCholesky, SparseCholesky, SymCsr};

    /// P = [1 x y z] at the points.
    fn poly_block(pts: &[[f64; 3]]) -> Mat<f64> {
        Mat::from_fn(pts.len(), 4, |i, j| if j == 0 { 1.0 } else { pts[i][j - 1] })
    }

    /// The whole (n + k) bordered matrix, dense.
    fn bordered_dense(a: &SymCsr, p: MatRef<'_, f64>) -> Mat<f64> {
        let (n, k) = (a.n, p.ncols());
        let mut m = Mat::zeros(n + k, n + k);
        for i in 0..n {
            for (j, v) in a.row(i) {
                m[(i, j)] = v;
                m[(j, i)] = v;
            }
            for j in 0..k {
                m[(i, n + j)] = p[(i, j)];
                m[(n + j, i)] = p[(i, j)];
            }
        }
        m
    }

    #[test]
    fn agrees_with_a_dense_solve_of_the_bordered_system() {
        let pts = bunny(10);
        let a = kernel_matrix(&pts, 0.2);
        let p = poly_block(&pts);
        // values of a smooth function at the centres, not a polynomial of degree 1
        let r: Vec<f64> = pts.iter().map(|q| (3.0 * q[0]).sin() + q[1] * q[2] + 0.3).collect();
        let mut rhs = r.clone();
        rhs.extend([0.0; 4]);
        let want = lu_solve(bordered_dense(&a, p.as_ref()).as_ref(), &rhs).unwrap();
        let envelope = EnvelopeCholesky::new(&a, &sorted_by_x(&pts)).unwrap();
        let sparse = SparseCholesky::factor(&a, faer::Par::Seq).unwrap();
        for (name, solver) in [("envelope", &envelope as &dyn SpdSolve), ("sparse", &sparse)] {
            let (lambda, c) = bordered_solve(solver, p.as_ref(), &r).unwrap();
            let err = rel_diff(&[lambda.clone(), c.clone()].concat(), &want);
            assert!(err < 1e-10, "{name}: bordered elimination vs dense LU: {err:e}");
            // the moment conditions P^T lambda = 0
            for j in 0..4 {
                let m: f64 = (0..a.n).map(|i| p[(i, j)] * lambda[i]).sum();
                assert!(m.abs() < 1e-9, "{name}: moment {j} is {m:e}");
            }
        }
    }

    #[test]
    fn centres_on_one_plane_are_reported() {
        // the bunny's points projected on the tilted plane z = 0.2 + 0.3 x - 0.1 y
        let pts: Vec<[f64; 3]> =
            bunny(10).iter().map(|q| [q[0], q[1], 0.2 + 0.3 * q[0] - 0.1 * q[1]]).collect();
        let a = kernel_matrix(&pts, 0.2);
        let chol = SparseCholesky::factor(&a, faer::Par::Seq).unwrap();
        let err = bordered_solve(&chol, poly_block(&pts).as_ref(), &vec![1.0; a.n]).unwrap_err();
        assert!(matches!(err, Error::Numerical(_)) && err.to_string().contains("one plane"), "{err}");
    }

    #[test]
    fn mismatched_sizes_are_an_error_not_a_panic() {
        let pts = bunny(50);
        let a = kernel_matrix(&pts, 0.2);
        let chol = SparseCholesky::factor(&a, faer::Par::Seq).unwrap();
        let p = poly_block(&pts);
        assert!(matches!(bordered_solve(&chol, p.as_ref(), &vec![1.0; a.n - 1]), Err(Error::Usage(_))));
        let short = poly_block(&pts[1..]);
        assert!(matches!(bordered_solve(&chol, short.as_ref(), &vec![1.0; a.n]), Err(Error::Usage(_))));
    }
}
