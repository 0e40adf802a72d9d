//! Mixed-precision solve: factor in f32, refine in f64 (classical iterative refinement, then
//! GMRES-IR when it stalls), and say so when neither reaches the accuracy of an f64 solve.
//!
//! The f32 factors are those of LU (P M = L U, `mixed`) or, for a bordered spline system whose
//! f64 solver would be the projected Cholesky, of the projected Cholesky (`mixed_cholesky`); both
//! act as an approximate inverse of the whole f64 matrix M, written U^-1 L^-1 P below.
//!
//! # Classical refinement
//!
//! With the f32 factors as an approximate inverse, x_0 = U^-1 L^-1 P b and
//!
//! ```text
//!     r_i = b - M x_i   (f64),      d_i = U^-1 L^-1 P r_i,      x_{i+1} = x_i + d_i.
//! ```
//!
//! The error contracts per step by about c(n) kappa(M) eps32 (Moler 1967; Higham, "Accuracy and
//! Stability of Numerical Algorithms", ch. 12): for kappa(M) well below 1/eps32 = 1.7e7 a few
//! steps reach the f64 limit, near or above it the iteration stalls or diverges.
//!
//! # GMRES-IR
//!
//! When the residual stops halving, each correction is instead the solution of M d = r by GMRES in
//! f64 on the left-preconditioned system (U^-1 L^-1 P M) d = U^-1 L^-1 P r (Carson and Higham
//! 2017): the f32 factors now only cluster the spectrum, and GMRES converges in a few iterations
//! for much larger kappa(M). Each iteration is one product with M (from the f64 rows, one
//! all-gather) and one solve with the factors; the Krylov vectors are replicated on every rank, so
//! the inner products need no communication. An outer step takes at most [`GMRES_ITERATIONS`]
//! iterations to a relative preconditioned residual of [`GMRES_TOL`].
//!
//! # Stopping rule
//!
//! A backward stable f64 solve leaves a residual of order eps64 ||M|| ||x||, and the residual of
//! the refinement is computed to about sqrt(n) eps64 ||M|| ||x|| itself. So, in the infinity norm:
//!
//! - stop at once when ||r|| <= 4 eps64 ||M|| ||x|| ([`F64_LIKE`]): a backward stable f64
//!   factorisation itself leaves a small multiple of eps64 ||M|| ||x||, so below that a further
//!   step could at best gain the spread between f64 solves, at the cost of a product with M and
//!   a solve with the factors. Measured on the bunny's system at N = 8000: after two steps the
//!   residual was 2.5 times eps64 ||M|| ||x||, ||b - M x||_2 / ||b||_2 = 5.7e-14 against the f64
//!   solve's 3.4e-14; a third step (which the rule stopping at 1 times took) reached 4.8e-14;
//!   That line assumes ||b|| near ||M|| ||x||. Where the weights are large against the values
//!   (||M|| ||x|| thousands of times ||b||, as with off-surface constraints 0.5 % of the diagonal
//!   beside the data) it lies far above the residual an f64 solve leaves: on 2000 bunny points
//!   with their off points, two steps stopped at ||r||_2 / ||b||_2 = 3.9e-12 against the f64
//!   solve's 2.0e-14. So the stop also asks ||r||_2 <= 4 sqrt(n) eps64 ||b||_2, the residual a
//!   backward stable solve leaves where the system is well scaled (2.0e-14 there after one more
//!   step; at N = 8000 on the carrier's system both lines hold after two steps, as before);
//! - otherwise stop a phase when a step does not halve ||r|| (or after [`CLASSICAL_STEPS`] steps,
//!   [`GMRES_STEPS`] outer steps), keeping the best iterate;
//! - the solve has converged when then ||r|| <= sqrt(n) eps64 ||M|| ||x|| (LAPACK's DSGESV test).
//!
//! A solve that has not converged after GMRES-IR is reported as such; the caller factors in f64.

use super::mixed::{Approximate, Factors, Operator};
use super::mixed_cholesky::CholeskyFactors;
use super::solver::{Job, SolverKind};
use super::system::LocalRows;
use crate::error::Result;

/// Most classical refinement steps.
pub const CLASSICAL_STEPS: usize = 10;
/// Most GMRES-IR outer steps.
pub const GMRES_STEPS: usize = 5;
/// Most GMRES iterations per outer step (no restart).
pub const GMRES_ITERATIONS: usize = 50;
/// Relative preconditioned residual at which GMRES ends an outer step.
pub const GMRES_TOL: f64 = 1e-10;
/// Multiple of eps64 ||M|| ||x|| (infinity norms) at which the refinement has the residual of an
/// f64 solve and stops (see the stopping rule in the module doc).
pub const F64_LIKE: f64 = 4.0;

/// How a mixed-precision solve went.
#[derive(Debug, Clone, PartialEq)]
pub struct Refinement {
    /// Classical refinement steps taken.
    pub classical: usize,
    /// GMRES-IR outer steps taken, and their GMRES iterations in all.
    pub gmres: usize,
    pub gmres_iterations: usize,
    /// ||b - M x||_2 / ||b||_2 of the f32 solution and after every step.
    pub history: Vec<f64>,
    /// Whether the stopping rule accepted the solution.
    pub converged: bool,
}

impl Refinement {
    /// ||b - M x||_2 / ||b||_2 of the solution returned.
    pub fn residual(&self) -> f64 {
        self.history.iter().copied().fold(f64::INFINITY, f64::min)
    }

    /// One line for the report.
    pub fn describe(&self) -> String {
        let steps: Vec<String> = self.history.iter().map(|r| format!("{r:.1e}")).collect();
        format!(
            "{} classical refinement steps, {} GMRES-IR steps ({} iterations); residuals {}",
            self.classical,
            self.gmres,
            self.gmres_iterations,
            steps.join(" -> ")
        )
    }
}

/// Solves the distributed system `m` (f64 rows, right-hand side in the last column, left
/// unchanged) by an f32 factorisation of `m` and refinement in f64: the projected Cholesky when
/// `kind` is `Cholesky` (`m` a bordered spline system), LU otherwise. Collective; every rank
/// returns the same. An error is a failed f32 factorisation (an LU pivot below n eps32
/// max |m_ij|, `Error::NotDefinite` from the Cholesky); a solution that the stopping rule did not
/// accept comes back with `converged` false.
pub fn mixed_solve(job: &Job<'_>, m: &LocalRows, kind: SolverKind) -> Result<(Vec<f64>, Refinement)> {
    let factors: Box<dyn Approximate> = match kind {
        SolverKind::Cholesky => Box::new(CholeskyFactors::<f32>::new(job, m)?),
        _ => Box::new(Factors::new(job, m)?),
    };
    refine(job, m, factors.as_ref(), kind == SolverKind::Cholesky)
}

/// Refines the solution of `m` with the approximate inverse `factors`.
fn refine(
    job: &Job<'_>,
    m: &LocalRows,
    factors: &dyn Approximate,
    symmetric: bool,
) -> Result<(Vec<f64>, Refinement)> {
    let comm = job.comm;
    let n = m.layout.n;
    let b = Operator::rhs_of(comm, m);
    let bnorm = norm2(&b).max(f64::MIN_POSITIVE);
    let mut x = factors.apply(comm, &b);
    let (op, mut r) = Operator::with_residual(comm, m, job.par, &x, symmetric);
    let floor = |x: &[f64]| f64::EPSILON * op.norm_inf * norm_inf(x);
    let accept = |x: &[f64]| (n as f64).sqrt() * floor(x);
    let mut out = Refinement {
        classical: 0,
        gmres: 0,
        gmres_iterations: 0,
        history: vec![norm2(&r) / bnorm],
        converged: false,
    };
    // the correction d: x + d is kept when it lowers the residual; returns new / old residual
    let step = |x: &mut Vec<f64>, r: &mut Vec<f64>, d: &[f64], history: &mut Vec<f64>| {
        let next: Vec<f64> = x.iter().zip(d).map(|(a, b)| a + b).collect();
        let rn = op.residual(comm, &next);
        history.push(norm2(&rn) / bnorm);
        let (old, new) = (norm_inf(r), norm_inf(&rn));
        if new < old {
            (*x, *r) = (next, rn);
        }
        if old > 0.0 {
            new / old
        } else {
            1.0
        }
    };
    // classical refinement while the residual halves, until it is below both f64 lines
    let b_line = F64_LIKE * (n as f64).sqrt() * f64::EPSILON * bnorm;
    while out.classical < CLASSICAL_STEPS && (norm_inf(&r) > F64_LIKE * floor(&x) || norm2(&r) > b_line) {
        let d = factors.apply(comm, &r);
        out.classical += 1;
        if step(&mut x, &mut r, &d, &mut out.history) > 0.5 {
            break;
        }
    }
    // GMRES-IR while the residual halves
    while out.gmres < GMRES_STEPS && norm_inf(&r) > accept(&x) {
        let apply = |v: &[f64]| factors.apply(comm, &op.product(comm, v));
        let (d, its) = gmres(&apply, factors.apply(comm, &r), GMRES_TOL, GMRES_ITERATIONS);
        out.gmres += 1;
        out.gmres_iterations += its;
        if step(&mut x, &mut r, &d, &mut out.history) > 0.5 {
            break;
        }
    }
    out.converged = norm_inf(&r) <= accept(&x);
    Ok((x, out))
}

fn norm2(v: &[f64]) -> f64 {
    v.iter().map(|a| a * a).sum::<f64>().sqrt()
}

fn norm_inf(v: &[f64]) -> f64 {
    v.iter().fold(0.0f64, |m, a| m.max(a.abs()))
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// GMRES without restart for A d = c from d = 0, with modified Gram-Schmidt and Givens rotations:
/// at most `max_it` iterations, until the residual is `tol` ||c||. Returns d and the iterations.
/// Every vector is replicated; `a` is the (collective) operator.
fn gmres(a: &dyn Fn(&[f64]) -> Vec<f64>, c: Vec<f64>, tol: f64, max_it: usize) -> (Vec<f64>, usize) {
    let n = c.len();
    let beta = norm2(&c);
    if beta == 0.0 || n == 0 {
        return (vec![0.0; n], 0);
    }
    let mut basis = vec![c.iter().map(|v| v / beta).collect::<Vec<f64>>()];
    // h[j]: column j of the Hessenberg matrix, rotated; (cs, sn) the rotations; g the rotated beta e1
    let mut h: Vec<Vec<f64>> = Vec::new();
    let (mut cs, mut sn): (Vec<f64>, Vec<f64>) = (Vec::new(), Vec::new());
    let mut g = vec![beta];
    let mut its = 0;
    while its < max_it.min(n) {
        let j = its;
        let mut w = a(&basis[j]);
        let mut col = vec![0.0; j + 2];
        for (i, v) in basis.iter().enumerate() {
            col[i] = dot(&w, v);
            w.iter_mut().zip(v).for_each(|(wk, vk)| *wk -= col[i] * vk);
        }
        col[j + 1] = norm2(&w);
        for i in 0..j {
            let (p, q) = (col[i], col[i + 1]);
            col[i] = cs[i] * p + sn[i] * q;
            col[i + 1] = -sn[i] * p + cs[i] * q;
        }
        let rho = col[j].hypot(col[j + 1]);
        let (cj, sj) = if rho == 0.0 { (1.0, 0.0) } else { (col[j] / rho, col[j + 1] / rho) };
        col[j] = rho;
        col[j + 1] = 0.0;
        cs.push(cj);
        sn.push(sj);
        g.push(-sj * g[j]);
        g[j] *= cj;
        let breakdown = norm2(&w) == 0.0;
        if !breakdown {
            let hn = norm2(&w);
            basis.push(w.iter().map(|v| v / hn).collect());
        }
        h.push(col);
        its += 1;
        if breakdown || g[j + 1].abs() <= tol * beta || rho == 0.0 {
            break;
        }
    }
    // y = H^-1 g (upper triangular its x its), d = V y
    let mut y = vec![0.0; its];
    for i in (0..its).rev() {
        let s: f64 = (i + 1..its).map(|k| h[k][i] * y[k]).sum();
        y[i] = if h[i][i] != 0.0 { (g[i] - s) / h[i][i] } else { 0.0 };
    }
    let mut d = vec![0.0; n];
    for (v, yi) in basis.iter().zip(&y) {
        d.iter_mut().zip(v).for_each(|(dk, vk)| *dk += yi * vk);
    }
    (d, its)
}

#[cfg(test)]
mod tests {
    use super::*;
    use faer::MatRef;

    use crate::linalg::dist::RowCyclic;
    use crate::par::Solo;

    /// n x n unit upper triangular, entries above the diagonal -c (1 + u/10) with u in [0, 1)
    /// (not representable in f32), rows in reversed order (so that LU pivots), right-hand side
    /// M (1, ..., 1). kappa grows like (1 + c)^n.
    fn graded(n: usize, c: f64) -> LocalRows {
        let mut s = 7u64;
        let mut u = move || {
            s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (s >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut a = vec![vec![0.0; n]; n];
        for (i, row) in a.iter_mut().enumerate() {
            row[i] = 1.0;
            for v in row.iter_mut().skip(i + 1) {
                *v = -c * (1.0 + u() / 10.0);
            }
        }
        let mut rows = LocalRows::zeros(RowCyclic::new(n, 1, 0), n + 1, 0);
        for (l, row) in a.iter().rev().enumerate() {
            for (j, v) in row.iter().enumerate() {
                rows.set(l, j, *v);
            }
            rows.set(l, n, row.iter().sum());
        }
        rows
    }

    #[test]
    fn classical_refinement_then_gmres_ir_as_the_condition_grows() {
        for (c, gmres) in [(0.2, false), (0.5, true)] {
            let m = graded(60, c);
            let (x, r) = mixed_solve(&Job::on(&Solo).panel(16), &m, SolverKind::Lu).unwrap();
            // kappa about 1e5: classical refinement alone; about 3e8 (> 1/eps32): it stalls at
            // once and GMRES-IR takes over
            assert!(r.converged && r.residual() < 1e-14 && r.history[0] > 1e-10, "c {c}: {r:?}");
            assert_eq!(r.gmres > 0, gmres, "c {c}: {r:?}");
            assert!(r.classical >= 1 && (gmres || r.classical >= 2), "c {c}: {r:?}");
            // the f64 LU solution, to the forward error kappa eps64 both carry
            let a = MatRef::from_column_major_slice(&m.data[..60 * 60], 60, 60);
            let want = crate::linalg::dense::lu_solve(a, &m.data[60 * 60..]).unwrap();
            let d = x.iter().zip(&want).map(|(p, q)| (p - q).abs()).fold(0.0, f64::max);
            assert!(d < 1e-5, "c {c}: differs from the f64 LU by {d:e}");
        }
    }

    #[test]
    fn gmres_solves_a_small_nonsymmetric_system() {
        // A = I + 0.3 B, B_ij a function of (i mod 5, j mod 5), so of rank <= 5: the minimal
        // polynomial of A has degree <= 6, and so has the number of GMRES iterations
        let n = 12;
        let a = |i: usize, j: usize| f64::from(u8::from(i == j)) + 0.3 * ((i * 7 + j * 3) % 5) as f64 / 5.0;
        let op = |v: &[f64]| -> Vec<f64> { (0..n).map(|i| (0..n).map(|j| a(i, j) * v[j]).sum()).collect() };
        let x: Vec<f64> = (0..n).map(|i| (i as f64 - 3.5).sin()).collect();
        let c = op(&x);
        let (d, its) = gmres(&op, c, 1e-13, 50);
        let err = d.iter().zip(&x).map(|(p, q)| (p - q).abs()).fold(0.0, f64::max);
        assert!(err < 1e-11, "error {err}, {its} iterations");
        assert!(its <= 6, "{its} iterations");
    }
}
