//! The kernels of the volume spline and the matching polynomial space. Pure functions of
//! distances and coordinates: no knowledge of points, carriers or distribution.
//!
//! Two families:
//!
//! - **Green's functions** G_{m,n}: up to a constant factor, the fundamental solution of the
//!   iterated Laplacian Delta^m in R^n: r^(2m-n) ln r for even n, r^(2m-n) for odd n, with
//!   G(0) = 0 (2m > n). The polynomials of degree <= m - 1 in n variables (k = C(n + m - 1, n) of
//!   them) are the functions the spline's energy cannot see; they complete the kernel terms to the
//!   unique interpolant. Why these pieces, the bordered system they make and the sign under which
//!   G is conditionally positive definite are derived in the documentation of
//!   [`crate::spline::system`]. Every entry of their matrix is nonzero.
//! - **Wendland functions** phi_{3,k} (3D only), compactly supported: zero beyond a support
//!   radius R, so that the matrix is sparse. They complete with the linear polynomials (k = 4, as
//!   for G = r), and the kernel reports `order() = 2` so that everything that depends only on the
//!   polynomial part (unisolvency, the carrier's degree check) treats them alike. Their
//!   definiteness, the choice of R and the sparse system are in [`crate::spline::compact`].

use crate::error::{Error, Result};

/// The radial function of the spline together with the polynomials that make it unique: either
/// the Green's function G_{m,n}(r) = r^(2m-n) ln r for even n, r^(2m-n) for odd n (G(0) = 0) with
/// the polynomials of degree <= m-1 in n variables, or a compactly supported Wendland function
/// in 3D with the linear polynomials (`dim` 3, `order` 2).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Kernel {
    dim: usize,
    order: usize,
    compact: Option<Wendland>,
    /// The smoothing lambda >= 0 of the system (0: interpolation); see [`Kernel::nugget`].
    smoothing: f64,
}

/// The smoothness of a Wendland function phi_{3,k} (C^0, C^2 or C^4 at the origin and at the
/// edge of its support).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum WendlandKind {
    /// phi_{3,0}(r) = (1 - r)^2_+
    C0,
    /// phi_{3,1}(r) = (1 - r)^4_+ (4r + 1)
    C2,
    /// phi_{3,2}(r) = (1 - r)^6_+ (35r^2 + 18r + 3)
    C4,
}

impl WendlandKind {
    /// All kinds, in order of smoothness.
    pub const ALL: [WendlandKind; 3] = [WendlandKind::C0, WendlandKind::C2, WendlandKind::C4];

    /// The command-line name: `wendland0`, `wendland2` or `wendland4`.
    pub fn name(&self) -> &'static str {
        match self {
            WendlandKind::C0 => "wendland0",
            WendlandKind::C2 => "wendland2",
            WendlandKind::C4 => "wendland4",
        }
    }

    /// phi(r) for the scaled distance r = |x| / R (zero for r >= 1).
    #[inline]
    pub fn phi(&self, r: f64) -> f64 {
        if !(r < 1.0) {
            return 0.0;
        }
        let t = 1.0 - r;
        match self {
            WendlandKind::C0 => t * t,
            WendlandKind::C2 => {
                let t2 = t * t;
                t2 * t2 * (4.0 * r + 1.0)
            }
            WendlandKind::C4 => {
                let t3 = t * t * t;
                t3 * t3 * ((35.0 * r + 18.0) * r + 3.0)
            }
        }
    }
}

/// A Wendland function with its support radius R (in the spline's normalised coordinates).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Wendland {
    pub kind: WendlandKind,
    pub support: f64,
}

impl Wendland {
    /// phi(|x| / R) as a function of the squared distance |x|^2.
    #[inline]
    pub fn eval_r2(&self, r2: f64) -> f64 {
        self.kind.phi(r2.sqrt() / self.support)
    }
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
        Ok(Kernel { dim, order, compact: None, smoothing: 0.0 })
    }

    /// The compactly supported kernel `name` (`wendland0`, `wendland2` or `wendland4`) with support
    /// radius `support` > 0 in normalised coordinates (the unit ball holds the data; see
    /// [`crate::spline::compact::default_support`]), in 3D with the linear polynomials.
    pub fn wendland(name: &str, support: f64) -> Result<Self> {
        let Some(kind) = WendlandKind::ALL.into_iter().find(|k| k.name() == name) else {
            return Err(Error::Usage(format!(
                "unknown compactly supported kernel '{name}' (expected wendland0, wendland2 or wendland4)"
            )));
        };
        if !(support > 0.0 && support.is_finite()) {
            return Err(Error::Usage(format!(
                "kernel {name}: the support radius must be a positive number, not {support}"
            )));
        }
        Ok(Kernel { dim: 3, order: 2, compact: Some(Wendland { kind, support }), smoothing: 0.0 })
    }

    /// The Wendland function and its support when the kernel is compactly supported.
    pub fn wendland_part(&self) -> Option<Wendland> {
        self.compact
    }

    /// The support radius R (normalised coordinates) when the kernel is compactly supported:
    /// `eval_r2` is zero at every distance >= R.
    pub fn is_compact(&self) -> Option<f64> {
        self.compact.map(|w| w.support)
    }

    /// The command-line names of the 3D kernels: `r` (m = 2) and `r3` (m = 3).
    pub fn from_name_3d(name: &str) -> Result<Self> {
        match name {
            "r" => Kernel::new(3, 2),
            "r3" => Kernel::new(3, 3),
            other => Err(Error::Usage(format!("unknown kernel '{other}' (expected r or r3)"))),
        }
    }

    /// The same kernel with smoothing `lambda` (a finite number >= 0; 0 interpolates): the
    /// system's diagonal gets [`Kernel::nugget`], the values of the spline away from its centres
    /// do not change.
    pub fn with_smoothing(self, lambda: f64) -> Result<Self> {
        if !(lambda >= 0.0 && lambda.is_finite()) {
            return Err(Error::Usage(format!("smoothing must be a finite number >= 0, not {lambda}")));
        }
        Ok(Kernel { smoothing: lambda, ..self })
    }

    /// The smoothing lambda of the system (0 for an interpolating spline).
    pub fn smoothing(&self) -> f64 {
        self.smoothing
    }

    /// What smoothing adds to each diagonal entry A_ii of the system: s lambda, s the
    /// [`Kernel::definiteness_sign`]. The smoothing spline minimises
    /// sum_i (U(P_i) - r_i)^2 + lambda E(U) (E the energy that s G measures); its equations are
    /// those of the interpolant with (s A + lambda I) in place of s A, that is A + s lambda I:
    /// U(P_i) = r_i - s lambda lambda_i. The shift makes s A more definite, so every solver that
    /// takes the interpolant takes the smoothing spline too.
    #[inline]
    pub fn nugget(&self) -> f64 {
        self.definiteness_sign() * self.smoothing
    }

    pub fn dim(&self) -> usize {
        self.dim
    }

    pub fn order(&self) -> usize {
        self.order
    }

    /// A short name: r, r3, r2log, r4log, ..., or e.g. "wendland2 (support 0.2)".
    pub fn name(&self) -> String {
        if let Some(w) = self.compact {
            return format!("{} (support {})", w.kind.name(), w.support);
        }
        let p = self.power();
        let base = if p == 1 { "r".to_string() } else { format!("r{p}") };
        if self.has_log() {
            format!("{base}log")
        } else {
            base
        }
    }

    /// The exponent 2m - n of the Green's function (meaningless for a Wendland kernel).
    pub fn power(&self) -> i32 {
        (2 * self.order - self.dim) as i32
    }

    fn has_log(&self) -> bool {
        self.dim.is_multiple_of(2)
    }

    /// The kernel as a function of the squared distance, so that callers never take a square root
    /// the kernel does not need. Wendland kernels: phi(|x| / R), zero from |x| = R on.
    #[inline]
    pub fn eval_r2(&self, r2: f64) -> f64 {
        match self.compact {
            Some(w) => w.eval_r2(r2),
            None => self.green_r2(r2),
        }
    }

    /// The Green's function G_{m,n} as a function of the squared distance, whatever the kernel:
    /// for loops that have already dispatched on [`Kernel::wendland_part`] and must not test it
    /// again for every entry.
    #[inline]
    pub(crate) fn green_r2(&self, r2: f64) -> f64 {
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
    /// r^2 ln r (see "Conditional definiteness" in [`crate::spline::system`]). +1 for Wendland
    /// kernels, which are positive definite outright (see [`crate::spline::compact`]).
    pub fn definiteness_sign(&self) -> f64 {
        if self.compact.is_some() {
            return 1.0;
        }
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
    fn wendland_functions_match_their_closed_forms() {
        let r = 0.3f64;
        let support = 0.5;
        let d = r * support;
        let w = |name| Kernel::wendland(name, support).unwrap();
        let close = |a: f64, b: f64| (a - b).abs() <= 1e-14 * b.abs().max(1.0);
        assert!(close(w("wendland0").eval_r2(d * d), (1.0 - r).powi(2)));
        assert!(close(w("wendland2").eval_r2(d * d), (1.0 - r).powi(4) * (4.0 * r + 1.0)));
        assert!(close(w("wendland4").eval_r2(d * d), (1.0 - r).powi(6) * (35.0 * r * r + 18.0 * r + 3.0)));
        for (name, at0) in [("wendland0", 1.0), ("wendland2", 1.0), ("wendland4", 3.0)] {
            let k = w(name);
            assert_eq!(k.eval_r2(0.0), at0);
            // zero on and beyond the support, positive inside it
            for s in [support, 1.0001 * support, 7.0] {
                assert_eq!(k.eval_r2(s * s), 0.0, "{name} at {s}");
            }
            assert!(k.eval_r2((0.999 * support).powi(2)) > 0.0);
            assert_eq!(k.is_compact(), Some(support));
            assert_eq!(k.poly_count(), 4);
            assert_eq!(k.definiteness_sign(), 1.0);
        }
        assert_eq!(w("wendland2").name(), "wendland2 (support 0.5)");
        assert_eq!(Kernel::new(3, 2).unwrap().is_compact(), None);
    }

    #[test]
    fn wendland_functions_are_smooth_at_the_edge_of_their_support() {
        // phi_{3,k} is C^{2k}: near r = 1 it vanishes like (1 - r)^(2k + 2) at least
        for (kind, power) in [(WendlandKind::C0, 2), (WendlandKind::C2, 4), (WendlandKind::C4, 6)] {
            for t in [1e-2, 1e-3] {
                let v = kind.phi(1.0 - t);
                let scale = v / t.powi(power);
                assert!(scale > 0.1 && scale < 200.0, "{kind:?}: phi(1 - {t}) = {v}");
            }
        }
    }

    #[test]
    fn bad_wendland_kernels_are_rejected() {
        assert!(Kernel::wendland("wendland3", 0.2).is_err());
        for bad in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            assert!(Kernel::wendland("wendland2", bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn definiteness_signs() {
        assert_eq!(Kernel::new(3, 2).unwrap().definiteness_sign(), -1.0); // r
        assert_eq!(Kernel::new(3, 3).unwrap().definiteness_sign(), 1.0); // r^3
        assert_eq!(Kernel::new(2, 2).unwrap().definiteness_sign(), 1.0); // r^2 ln r
        assert_eq!(Kernel::new(2, 3).unwrap().definiteness_sign(), -1.0); // r^4 ln r
    }
}
