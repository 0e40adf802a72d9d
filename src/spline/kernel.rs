//! The Green's function G_{m,n} of the polyharmonic operator and the matching polynomial space.
//! Pure functions of distances and coordinates: no knowledge of points, carriers or distribution.
//!
//! G_{m,n} is, up to a constant factor, the fundamental solution of the iterated Laplacian
//! Delta^m in R^n: r^(2m-n) ln r for even n, r^(2m-n) for odd n, with G(0) = 0 (2m > n). The
//! polynomials of degree <= m - 1 in n variables (k = C(n + m - 1, n) of them) are the functions
//! the spline's energy cannot see; they complete the kernel terms to the unique interpolant. Why
//! these pieces, the bordered system they make and the sign under which G is conditionally
//! positive definite are derived in the documentation of [`crate::spline::system`].

use crate::error::{Error, Result};

/// Kernel G_{m,n}(r) = r^(2m-n) ln r for even n, r^(2m-n) for odd n (G(0) = 0), together with the
/// polynomials of degree <= m-1 in n variables that make the spline unique.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Kernel {
    dim: usize,
    order: usize,
}

impl Kernel {
    /// `dim` = n (1, 2 or 3), `order` = m with 2m > n.
    pub fn new(dim: usize, order: usize) -> Result<Self> {
        if !(1..=3).contains(&dim) {
            return Err(Error::Usage(format!("kernel dimension n = {dim}: only 1, 2 and 3 are supported")));
        }
        if order < 1 || 2 * order <= dim || order > 4 {
            return Err(Error::Usage(format!(
                "kernel order m = {order} in dimension n = {dim}: need 2m > n and m <= 4"
            )));
        }
        Ok(Kernel { dim, order })
    }

    /// The command-line names of the 3D kernels: `r` (m = 2) and `r3` (m = 3).
    pub fn from_name_3d(name: &str) -> Result<Self> {
        match name {
            "r" => Kernel::new(3, 2),
            "r3" => Kernel::new(3, 3),
            other => Err(Error::Usage(format!("unknown kernel '{other}' (expected r or r3)"))),
        }
    }

    pub fn dim(&self) -> usize {
        self.dim
    }

    pub fn order(&self) -> usize {
        self.order
    }

    /// A short name: r, r3, r2log, r4log, ...
    pub fn name(&self) -> String {
        let p = self.power();
        let base = if p == 1 { "r".to_string() } else { format!("r{p}") };
        if self.has_log() {
            format!("{base}log")
        } else {
            base
        }
    }

    /// The exponent 2m - n.
    pub fn power(&self) -> i32 {
        (2 * self.order - self.dim) as i32
    }

    fn has_log(&self) -> bool {
        self.dim % 2 == 0
    }

    /// G as a function of the squared distance, so that callers never take a square root the
    /// kernel does not need.
    #[inline]
    pub fn eval_r2(&self, r2: f64) -> f64 {
        let p = self.power();
        if self.has_log() {
            if r2 == 0.0 {
                0.0
            } else {
                r2.powi(p / 2) * 0.5 * r2.ln()
            }
        } else {
            r2.sqrt().powi(p)
        }
    }

    /// k = C(n + m - 1, n), the dimension of the polynomial space.
    pub fn poly_count(&self) -> usize {
        let (n, m) = (self.dim, self.order);
        // C(n+m-1, n) computed exactly for the small arguments used here
        (1..=n).fold(1usize, |acc, i| acc * (m - 1 + i) / i)
    }

    /// Exponent tuples of the monomial basis: by total degree, then lexicographically
    /// (1, x, y, z, x^2, xy, ...), so the first n+1 are always 1 and the coordinates.
    pub fn monomials(&self) -> Vec<[u8; 3]> {
        let mut out = Vec::with_capacity(self.poly_count());
        for deg in 0..self.order as u8 {
            let mut level = Vec::new();
            for a in (0..=deg).rev() {
                for b in (0..=deg - a).rev() {
                    let c = deg - a - b;
                    let e = [a, b, c];
                    if e[self.dim..].iter().all(|&x| x == 0) {
                        level.push(e);
                    }
                }
            }
            out.extend(level);
        }
        debug_assert_eq!(out.len(), self.poly_count());
        out
    }

    /// Values of the basis polynomials at `x` (first `dim` components used) into `out`.
    #[inline]
    pub fn poly_eval(&self, x: &[f64], out: &mut [f64]) {
        match (self.dim, self.order) {
            (_, 1) => out[0] = 1.0,
            (3, 2) => {
                out[0] = 1.0;
                out[1] = x[0];
                out[2] = x[1];
                out[3] = x[2];
            }
            _ => {
                for (o, e) in out.iter_mut().zip(self.monomials()) {
                    let mut v = 1.0;
                    for (d, &p) in e.iter().enumerate().take(self.dim) {
                        v *= x[d].powi(p as i32);
                    }
                    *o = v;
                }
            }
        }
    }

    /// The sign s such that s * G is conditionally positive definite of order m on distinct
    /// points (s lambda^T A lambda > 0 whenever P^T lambda = 0, lambda != 0): (-1)^(ceil(p/2)) for
    /// odd powers r^p, (-1)^(p/2 + 1) for r^p ln r; so -1 for r and r^4 ln r, +1 for r^3 and
    /// r^2 ln r (see "Conditional definiteness" in [`crate::spline::system`]).
    pub fn definiteness_sign(&self) -> f64 {
        let p = self.power();
        let e = if self.has_log() { p / 2 + 1 } else { (p + 1) / 2 };
        if e % 2 == 0 {
            1.0
        } else {
            -1.0
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn green_functions_match_their_closed_forms() {
        let r = 1.7f64;
        assert!((Kernel::new(3, 2).unwrap().eval_r2(r * r) - r).abs() < 1e-12);
        assert!((Kernel::new(3, 3).unwrap().eval_r2(r * r) - r.powi(3)).abs() < 1e-12);
        assert!((Kernel::new(2, 2).unwrap().eval_r2(r * r) - r * r * r.ln()).abs() < 1e-12);
        assert!((Kernel::new(1, 2).unwrap().eval_r2(r * r) - r.powi(3)).abs() < 1e-12);
        assert!((Kernel::new(2, 3).unwrap().eval_r2(r * r) - r.powi(4) * r.ln()).abs() < 1e-12);
        assert_eq!(Kernel::new(2, 2).unwrap().eval_r2(0.0), 0.0);
        assert_eq!(Kernel::new(3, 2).unwrap().eval_r2(0.0), 0.0);
    }

    #[test]
    fn polynomial_space_sizes() {
        let k = |n, m| Kernel::new(n, m).unwrap().poly_count();
        assert_eq!(k(3, 2), 4);
        assert_eq!(k(3, 3), 10);
        assert_eq!(k(2, 2), 3);
        assert_eq!(k(2, 3), 6);
        assert_eq!(k(1, 2), 2);
        for (n, m) in [(3, 2), (3, 3), (2, 2), (2, 3), (1, 2), (1, 3)] {
            let kern = Kernel::new(n, m).unwrap();
            let mono = kern.monomials();
            assert_eq!(mono.len(), kern.poly_count());
            assert_eq!(mono[0], [0, 0, 0]);
            let mut sorted = mono.clone();
            sorted.dedup();
            assert_eq!(sorted.len(), mono.len());
        }
    }

    #[test]
    fn fast_and_generic_polynomials_agree() {
        let kern = Kernel::new(3, 2).unwrap();
        let x = [0.3, -1.2, 2.5];
        let mut fast = [0.0; 4];
        kern.poly_eval(&x, &mut fast);
        let generic: Vec<f64> =
            kern.monomials().iter().map(|e| (0..3).map(|d| x[d].powi(e[d] as i32)).product()).collect();
        assert_eq!(fast.to_vec(), generic);
    }

    #[test]
    fn invalid_orders_are_rejected() {
        assert!(Kernel::new(3, 1).is_err());
        assert!(Kernel::new(4, 3).is_err());
        assert!(Kernel::from_name_3d("gauss").is_err());
        assert_eq!(Kernel::from_name_3d("r3").unwrap().name(), "r3");
        assert_eq!(Kernel::new(2, 2).unwrap().name(), "r2log");
    }

    #[test]
    fn definiteness_signs() {
        assert_eq!(Kernel::new(3, 2).unwrap().definiteness_sign(), -1.0); // r
        assert_eq!(Kernel::new(3, 3).unwrap().definiteness_sign(), 1.0); // r^3
        assert_eq!(Kernel::new(2, 2).unwrap().definiteness_sign(), 1.0); // r^2 ln r
        assert_eq!(Kernel::new(2, 3).unwrap().definiteness_sign(), -1.0); // r^4 ln r
    }
}
