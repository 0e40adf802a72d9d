//! The one Householder reflector of the crate and the compact-WY form of a product of them. Pure,
//! serial, on slices and faer views: the dense oracle, the distributed Householder QR and the
//! projection of the Cholesky solver all build on these functions.
//!
//! # The reflector
//!
//! For x = [x0; x'] (x0 a scalar, x' the tail) we want H = I - tau v v^T, orthogonal and
//! symmetric, with H x = beta e1. Any reflector maps x to a vector of the same length, so
//! |beta| = ||x||, and a reflector that maps x to beta e1 has v parallel to x - beta e1. We take
//!
//! ```text
//!     beta = -sign(x0) ||x||,     v = (x - beta e1) / (x0 - beta) = [1; x' / (x0 - beta)],
//!     tau  = 2 / (v^T v) = (beta - x0) / beta,
//! ```
//!
//! the last equality from ||x - beta e1||^2 = 2 beta^2 - 2 beta x0 = 2 beta (beta - x0). The sign
//! of beta opposite to x0 makes x0 - beta a sum of two numbers of the same sign, so v is formed
//! without cancellation, and tau lies in [1, 2]. When the tail is zero, x is already a multiple of
//! e1 and we take H = I (tau = 0, beta = x0), as LAPACK's dlarfg does. Scaling v so that v(0) = 1
//! lets the tail be stored in the entries of x that H annihilates (below the diagonal of R).
//!
//! Applying H costs one dot product and one update: H y = y - tau (v^T y) v.
//!
//! # Compact WY
//!
//! The product Q = H_1 H_2 ... H_k of reflectors with v_j zero above position j is
//! Q = I - V T V^T, with V = [v_1 ... v_k] unit lower trapezoidal and T upper triangular k x k
//! (Schreiber & Van Loan 1989). By induction: if Q_{j-1} = I - V T V^T, then
//!
//! ```text
//!     Q_{j-1} (I - tau v v^T) = I - V T V^T - tau v v^T + tau V T (V^T v) v^T
//!                             = I - [V v] [ T   -tau T V^T v ] [V v]^T,
//!                                         [ 0    tau         ]
//! ```
//!
//! so T grows by the column z = -tau_j T (V^T v_j) over the diagonal entry tau_j. Only the Gram
//! matrix V^T V enters, which a distributed caller obtains with one sum over the ranks. Then
//! Q^T C = C - V (T^T (V^T C)) is two thin products and one rank-k update (BLAS-3 work).

use faer::{Mat, MatRef};

/// A Householder reflector H = I - tau v v^T with v = [1; v'], mapping x = [x0; x'] to
/// [beta; 0]; v' = scale * x'.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Reflector {
    pub tau: f64,
    pub beta: f64,
    /// 1 / (x0 - beta): the tail of v is the tail of x times this (0 when H = I).
    pub scale: f64,
}

impl Reflector {
    /// The reflector of x from x0 and the squared norm of its tail: all that a column spread
    /// over several ranks needs after one sum.
    pub fn new(x0: f64, tail_sq: f64) -> Reflector {
        if tail_sq == 0.0 {
            return Reflector { tau: 0.0, beta: x0, scale: 0.0 };
        }
        let norm = (x0 * x0 + tail_sq).sqrt();
        let beta = if x0 >= 0.0 { -norm } else { norm };
        Reflector { tau: (beta - x0) / beta, beta, scale: 1.0 / (x0 - beta) }
    }

    /// The reflector of x, in place: x(0) becomes beta, the tail of x becomes the tail of v.
    pub fn generate(x: &mut [f64]) -> Reflector {
        let Some((x0, tail)) = x.split_first_mut() else {
            return Reflector { tau: 0.0, beta: 0.0, scale: 0.0 };
        };
        let h = Reflector::new(*x0, tail.iter().map(|v| v * v).sum());
        *x0 = h.beta;
        tail.iter_mut().for_each(|v| *v *= h.scale);
        h
    }
}

/// y <- (I - tau v v^T) y with v = [1; v_tail]; `y` has one entry more than `v_tail`.
pub fn apply(tau: f64, v_tail: &[f64], y: &mut [f64]) {
    if tau == 0.0 {
        return;
    }
    let (y0, rest) = y.split_first_mut().expect("a reflector applied to an empty vector");
    debug_assert_eq!(rest.len(), v_tail.len());
    let w = tau * (*y0 + v_tail.iter().zip(rest.iter()).map(|(a, b)| a * b).sum::<f64>());
    *y0 -= w;
    rest.iter_mut().zip(v_tail).for_each(|(a, v)| *a -= w * v);
}

/// Unblocked Householder QR in place (LAPACK's dgeqr2): `a` is column-major with `m` rows; its
/// first `factored` columns are triangularised and every later column receives Q^T. On return R
/// is on and above the diagonal of the factored columns and the tail of v_j below the diagonal
/// of column j. Returns tau_j for j < min(m, factored).
pub fn qr_in_place(a: &mut [f64], m: usize, factored: usize) -> Vec<f64> {
    let cols = a.len().checked_div(m).unwrap_or(0);
    assert!(m == 0 || a.len() == m * cols, "qr_in_place: {} entries are not whole columns of {m}", a.len());
    let steps = m.min(factored.min(cols));
    let mut taus = Vec::with_capacity(steps);
    for j in 0..steps {
        let (left, right) = a.split_at_mut((j + 1) * m);
        let h = Reflector::generate(&mut left[j * m + j..]);
        let v_tail = &left[j * m + j + 1..];
        for col in right.chunks_exact_mut(m) {
            apply(h.tau, v_tail, &mut col[j..]);
        }
        taus.push(h.tau);
    }
    taus
}

/// V = [v_1 ... v_k] made explicit (unit diagonal, zeros above it) from the first k columns of a
/// matrix factored by [`qr_in_place`].
pub fn explicit_v(a: MatRef<'_, f64>, k: usize) -> Mat<f64> {
    Mat::from_fn(a.nrows(), k, |i, j| match i.cmp(&j) {
        std::cmp::Ordering::Less => 0.0,
        std::cmp::Ordering::Equal => 1.0,
        std::cmp::Ordering::Greater => a[(i, j)],
    })
}

/// The upper triangular T of H_1 ... H_k = I - V T V^T from the taus and the Gram matrix V^T V
/// (only its strict upper triangle is read): LAPACK's dlarft, forward and column-wise.
pub fn wy_t(taus: &[f64], gram: MatRef<'_, f64>) -> Mat<f64> {
    let k = taus.len();
    let mut t = Mat::<f64>::zeros(k, k);
    for i in 0..k {
        t[(i, i)] = taus[i];
        for r in 0..i {
            let s: f64 = (r..i).map(|s| t[(r, s)] * gram[(s, i)]).sum();
            t[(r, i)] = -taus[i] * s;
        }
    }
    t
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(m: usize, n: usize, seed: u64) -> Vec<f64> {
        let mut s = seed;
        (0..m * n)
            .map(|_| {
                s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5
            })
            .collect()
    }

    #[test]
    fn a_reflector_maps_x_to_beta_e1() {
        for x in
            [vec![3.0, 4.0, 0.0], vec![-1.0, 2.0, 2.0], vec![0.0, 1.0], vec![2.5, 0.0, 0.0], vec![0.0; 3]]
        {
            let mut v = x.clone();
            let h = Reflector::generate(&mut v);
            let norm = x.iter().map(|a| a * a).sum::<f64>().sqrt();
            assert!((h.beta.abs() - norm).abs() < 1e-14 * norm.max(1.0));
            let mut y = x.clone();
            apply(h.tau, &v[1..], &mut y);
            assert!((y[0] - h.beta).abs() < 1e-14 * norm.max(1.0), "{x:?} -> {y:?}");
            assert!(y[1..].iter().all(|a| a.abs() < 1e-14 * norm.max(1.0)), "{x:?} -> {y:?}");
            // H is orthogonal: applying it twice gives x back
            apply(h.tau, &v[1..], &mut y);
            assert!(y.iter().zip(&x).all(|(a, b)| (a - b).abs() < 1e-14 * norm.max(1.0)));
        }
    }

    #[test]
    fn compact_wy_equals_the_product_of_reflectors() {
        let (m, k) = (9, 4);
        let mut a = sample(m, k, 7);
        let taus = qr_in_place(&mut a, m, k);
        let v = explicit_v(MatRef::from_column_major_slice(&a, m, k), k);
        let gram = v.transpose() * &v;
        let t = wy_t(&taus, gram.as_ref());
        let q_wy = Mat::<f64>::identity(m, m) - &v * &t * v.transpose();
        // H_1 ... H_k applied to each unit vector, rightmost first
        for c in 0..m {
            let mut y: Vec<f64> = (0..m).map(|i| if i == c { 1.0 } else { 0.0 }).collect();
            for j in (0..k).rev() {
                apply(taus[j], &a[j * m + j + 1..(j + 1) * m], &mut y[j..]);
            }
            for (i, yi) in y.iter().enumerate() {
                assert!((q_wy[(i, c)] - yi).abs() < 1e-14, "Q[{i},{c}]");
            }
        }
    }

    #[test]
    fn qr_in_place_reproduces_the_matrix_and_transforms_later_columns() {
        let (m, k) = (7, 3);
        let orig = sample(m, k + 1, 11);
        let mut a = orig.clone();
        let taus = qr_in_place(&mut a, m, k);
        let v = explicit_v(MatRef::from_column_major_slice(&a[..m * k], m, k), k);
        let t = wy_t(&taus, (v.transpose() * &v).as_ref());
        let q = Mat::<f64>::identity(m, m) - &v * &t * v.transpose();
        let am = MatRef::from_column_major_slice(&a, m, k + 1);
        let om = MatRef::from_column_major_slice(&orig, m, k + 1);
        // Q [R; 0] = the factored columns, Q y = the original last column
        let r = Mat::<f64>::from_fn(m, k, |i, j| if i <= j { am[(i, j)] } else { 0.0 });
        let qr = &q * &r;
        let qy = &q * am.subcols(k, 1);
        for i in 0..m {
            for j in 0..k {
                assert!((qr[(i, j)] - om[(i, j)]).abs() < 1e-14);
            }
            assert!((qy[(i, 0)] - om[(i, k)]).abs() < 1e-14);
        }
    }
}
