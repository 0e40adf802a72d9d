//! Analytic first and second derivatives of the reconstructed solid f = f_c - U: of the radial
//! kernels, the polynomial part, the normalisation and the carrier (balls, ellipsoids and the
//! R-functions by the chain rule).
//!
//! # Radial functions
//!
//! A term phi(|x - P|) with d = x - P, r = |d| has
//!
//! ```text
//! grad phi = a d,              a = phi'(r) / r
//! Hess phi = a I + b d d^T,    b = (phi''(r) - phi'(r) / r) / r^2
//! ```
//!
//! ([`radial_derivatives`] returns a and b as functions of r^2). For the Green's functions:
//!
//! ```text
//! r^p (odd n):      a = p r^(p-2),                 b = p (p-2) r^(p-4)
//! r^p ln r (even n): a = r^(p-2) (p ln r + 1),      b = r^(p-4) (p (p-2) ln r + 2p - 2)
//! ```
//!
//! and for a Wendland function phi(r) = psi(s), s = r / R (support R):
//! a = psi'(s) / (R^2 s), b = (psi''(s) - psi'(s) / s) / (R^4 s^2), which for the three kinds are
//!
//! ```text
//! C0  psi = (1-s)^2:                  a = -2 (1-s) / (R^2 s),       b = 2 / (R^4 s^3)
//! C2  psi = (1-s)^4 (4s+1):           a = -20 (1-s)^3 / R^2,        b = 60 (1-s)^2 / (R^4 s)
//! C4  psi = (1-s)^6 (35s^2+18s+3):    a = -56 (5s+1) (1-s)^5 / R^2, b = 1680 (1-s)^4 / R^4
//! ```
//!
//! all zero for s >= 1.
//!
//! **At a centre (r = 0).** The terms whose b d d^T stays bounded (r^3: |b d d^T| = 3 r; C2:
//! 60 s / R^2; C4) are smooth there and get b d d^T = 0, a = phi''(0). The kernel r and the C0
//! Wendland function have a cone at each centre: grad |d| = d / r has no limit and the Hessian
//! grows like 1 / r. There the term contributes 0 to the gradient (the mean of its one-sided
//! values) and 0 to the Hessian, which is what a rendering or curvature evaluation exactly at a
//! centre (a data point on the surface) gets: a value, not NaN. The same convention holds for
//! r^2 ln r at r = 0 (finite gradient 0, logarithmically singular Hessian).
//!
//! # Normalisation and carrier
//!
//! The spline is evaluated at x' = (x - c) / s, so grad U = grad' U / s and Hess U = Hess' U / s^2.
//! The carriers: ball r^2 - |x - c|^2 has grad -2 (x - c), Hess -2 I; the ellipsoid
//! 1 - sum (x_j - c_j)^2 / a_j^2 has grad_j -2 (x_j - c_j) / a_j^2, Hess diag(-2 / a_j^2). An
//! R-function g(f1, f2) = f1 + f2 +- rho, rho = sqrt(f1^2 + f2^2) (+ union, - intersection) has
//!
//! ```text
//! g_1 = 1 +- f1 / rho,  g_2 = 1 +- f2 / rho,
//! g_11 = +- f2^2 / rho^3,  g_12 = -+ f1 f2 / rho^3,  g_22 = +- f1^2 / rho^3
//! grad g = g_1 grad f1 + g_2 grad f2
//! Hess g = g_1 H1 + g_2 H2 + g_11 grad f1 grad f1^T + g_12 (grad f1 grad f2^T + grad f2 grad f1^T)
//!          + g_22 grad f2 grad f2^T
//! ```
//!
//! and the difference is the intersection with -f2. Where f1 = f2 = 0 (rho = 0, the edge of the
//! set operation) g is not differentiable; the rho terms are dropped there.

use crate::spline::carrier::{ellipsoid_axis, ellipsoid_coordinate, Carrier};
use crate::spline::kernel::{Kernel, WendlandKind};
use crate::spline::{Model, Spline};

/// A value with its gradient and its Hessian (row-major) at a point.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Jet {
    pub value: f64,
    pub gradient: [f64; 3],
    pub hessian: [[f64; 3]; 3],
}

impl Jet {
    /// a * self + b * other, term by term.
    pub fn combine(&self, a: f64, other: &Jet, b: f64) -> Jet {
        let mut out = Jet { value: a * self.value + b * other.value, ..Jet::default() };
        for i in 0..3 {
            out.gradient[i] = a * self.gradient[i] + b * other.gradient[i];
            for j in 0..3 {
                out.hessian[i][j] = a * self.hessian[i][j] + b * other.hessian[i][j];
            }
        }
        out
    }

    /// The jet of -f.
    pub fn negated(&self) -> Jet {
        self.combine(-1.0, &Jet::default(), 0.0)
    }
}

/// (a, b) of the radial function of `kernel` at squared distance `r2` (normalised coordinates):
/// its gradient is a d and its Hessian a I + b d d^T (see the module doc, also for r = 0).
#[inline]
pub fn radial_derivatives(kernel: &Kernel, r2: f64) -> (f64, f64) {
    if let Some(w) = kernel.wendland_part() {
        let big_r = w.support;
        let s = r2.sqrt() / big_r;
        if !(s < 1.0) {
            return (0.0, 0.0);
        }
        let (r2s, r4s) = (big_r * big_r, big_r * big_r * big_r * big_r);
        let t = 1.0 - s;
        return match w.kind {
            WendlandKind::C0 => {
                if s == 0.0 {
                    (0.0, 0.0)
                } else {
                    (-2.0 * t / (r2s * s), 2.0 / (r4s * s * s * s))
                }
            }
            WendlandKind::C2 => {
                let b = if s == 0.0 { 0.0 } else { 60.0 * t * t / (r4s * s) };
                (-20.0 * t * t * t / r2s, b)
            }
            WendlandKind::C4 => {
                let t4 = t * t * t * t;
                (-56.0 * (5.0 * s + 1.0) * t4 * t / r2s, 1680.0 * t4 / r4s)
            }
        };
    }
    let p = kernel.power();
    if r2 == 0.0 {
        // r^p with p >= 3 and r^p ln r with p >= 4 have a = b d d^T = 0 in the limit; the cone r
        // and the logarithm r^2 ln r take 0 by convention (module doc)
        return (0.0, 0.0);
    }
    let r = r2.sqrt();
    let pf = p as f64;
    if kernel.dim() % 2 == 1 {
        (pf * r.powi(p - 2), pf * (pf - 2.0) * r.powi(p - 4))
    } else {
        let ln = r.ln();
        (r.powi(p - 2) * (pf * ln + 1.0), r.powi(p - 4) * (pf * (pf - 2.0) * ln + 2.0 * pf - 2.0))
    }
}

/// The derivative of the monomial with exponents `e` at x along the exponents `de` (how many
/// times to differentiate in each coordinate): prod_j e_j! / (e_j - de_j)! x_j^(e_j - de_j).
fn monomial_derivative(e: &[u8; 3], de: [u8; 3], x: &[f64; 3]) -> f64 {
    let mut v = 1.0;
    for j in 0..3 {
        if de[j] > e[j] {
            return 0.0;
        }
        for k in 0..de[j] {
            v *= (e[j] - k) as f64;
        }
        v *= x[j].powi((e[j] - de[j]) as i32);
    }
    v
}

/// The jet of the polynomial part c . p(x') at the normalised point `xn` (normalised derivatives).
pub fn polynomial_jet(spline: &Spline, xn: &[f64; 3]) -> Jet {
    let mut jet = Jet::default();
    for (e, c) in spline.kernel.monomials().iter().zip(&spline.poly) {
        jet.value += c * monomial_derivative(e, [0; 3], xn);
        for i in 0..3 {
            let mut di = [0u8; 3];
            di[i] += 1;
            jet.gradient[i] += c * monomial_derivative(e, di, xn);
            for j in 0..3 {
                let mut dij = di;
                dij[j] += 1;
                jet.hessian[i][j] += c * monomial_derivative(e, dij, xn);
            }
        }
    }
    jet
}

/// Adds w * phi(|d|) with its derivatives to `jet` (d = x' - P, normalised coordinates).
#[inline]
pub(crate) fn add_radial_term(jet: &mut Jet, kernel: &Kernel, w: f64, d: [f64; 3]) {
    let r2 = (d[0] * d[0] + d[1] * d[1]) + d[2] * d[2];
    let (a, b) = radial_derivatives(kernel, r2);
    jet.value += w * kernel.eval_r2(r2);
    for i in 0..3 {
        jet.gradient[i] += w * a * d[i];
        for j in 0..3 {
            let diag = if i == j { a } else { 0.0 };
            jet.hessian[i][j] += w * (diag + b * d[i] * d[j]);
        }
    }
}

/// Maps a jet in normalised coordinates to the caller's: gradient / s, Hessian / s^2.
pub fn denormalise(mut jet: Jet, scale: f64) -> Jet {
    for i in 0..3 {
        jet.gradient[i] /= scale;
        for j in 0..3 {
            jet.hessian[i][j] /= scale * scale;
        }
    }
    jet
}

/// The jet of U at `x` (caller's coordinates): the plain sum over all centres in index order, the
/// reference for [`crate::spline::point_eval::PointEvaluator`]. Three-dimensional splines only
/// (the coordinates beyond the spline's dimension are ignored).
pub fn spline_jet(spline: &Spline, x: &[f64; 3]) -> Jet {
    let dim = spline.kernel.dim();
    let mut xn = [0.0; 3];
    spline.norm.apply(&x[..dim], &mut xn[..dim]);
    let mut jet = polynomial_jet(spline, &xn);
    for (p, &w) in spline.centres.chunks_exact(dim).zip(&spline.weights) {
        let mut d = [0.0; 3];
        for j in 0..dim {
            d[j] = xn[j] - p[j];
        }
        add_radial_term(&mut jet, &spline.kernel, w, d);
    }
    denormalise(jet, spline.norm.scale)
}

/// The jet of the carrier f_c at `x` (caller's coordinates; a carrier of dimension < 3 leaves the
/// remaining derivatives zero). Panics on an unresolved automatic ball, as [`Carrier::eval`] does.
pub fn carrier_jet(carrier: &Carrier, x: &[f64; 3]) -> Jet {
    let mut jet = Jet { value: carrier.eval(x), ..Jet::default() };
    match carrier {
        Carrier::AutoBall | Carrier::AutoEllipsoid { .. } => unreachable!("Carrier::eval panics first"),
        Carrier::Ball { centre, .. } => {
            for (j, c) in centre.iter().enumerate() {
                jet.gradient[j] = -2.0 * (x[j] - c);
                jet.hessian[j][j] = -2.0;
            }
        }
        // f = 1 - sum_j (t_j / a_j)^2 with t_j = (x - c) . u_j: gradient -2 sum_j t_j u_j / a_j^2,
        // Hessian -2 sum_j u_j u_j^T / a_j^2
        Carrier::Ellipsoid { centre, semi_axes, axes } => {
            let n = semi_axes.len();
            for (j, a) in semi_axes.iter().enumerate() {
                let t = ellipsoid_coordinate(centre, axes.as_deref(), j, x);
                let u = |d: usize| ellipsoid_axis(axes.as_deref(), n, j, d);
                for r in 0..n {
                    // divided by a twice rather than by its square, which overflows from
                    // semi-axes of about 1e154 on
                    jet.gradient[r] -= 2.0 * (t / a) * u(r) / a;
                    for c in 0..n {
                        jet.hessian[r][c] -= 2.0 * (u(r) / a) * (u(c) / a);
                    }
                }
            }
        }
        Carrier::Union(a, b) => return r_function_jet(&carrier_jet(a, x), &carrier_jet(b, x), 1.0),
        Carrier::Intersection(a, b) => return r_function_jet(&carrier_jet(a, x), &carrier_jet(b, x), -1.0),
        Carrier::Difference(a, b) => {
            return r_function_jet(&carrier_jet(a, x), &carrier_jet(b, x).negated(), -1.0)
        }
    }
    jet
}

/// The jet of f1 + f2 + sign * sqrt(f1^2 + f2^2) (sign +1: union, -1: intersection).
pub fn r_function_jet(f1: &Jet, f2: &Jet, sign: f64) -> Jet {
    let (u, v) = (f1.value, f2.value);
    let rho = (u * u + v * v).sqrt();
    let mut out = f1.combine(1.0, f2, 1.0);
    out.value = u + v + sign * rho;
    if rho == 0.0 {
        return out;
    }
    let (g1, g2) = (1.0 + sign * u / rho, 1.0 + sign * v / rho);
    let r3 = rho * rho * rho;
    let (g11, g12, g22) = (sign * v * v / r3, -sign * u * v / r3, sign * u * u / r3);
    let (a, b) = (&f1.gradient, &f2.gradient);
    for i in 0..3 {
        out.gradient[i] = g1 * a[i] + g2 * b[i];
        for j in 0..3 {
            out.hessian[i][j] = g1 * f1.hessian[i][j]
                + g2 * f2.hessian[i][j]
                + g11 * a[i] * a[j]
                + g12 * (a[i] * b[j] + b[i] * a[j])
                + g22 * b[i] * b[j];
        }
    }
    out
}

/// The jet of f = f_c - U at `x` (every level's U in turn), summing over every centre (see
/// [`crate::spline::point_eval::PointEvaluator`] for the fast form).
pub fn model_jet(model: &Model, x: &[f64; 3]) -> Jet {
    model.levels().fold(carrier_jet(&model.carrier, x), |f, s| f.combine(1.0, &spline_jet(s, x), -1.0))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::spline::Normalisation;

    /// Central differences of `f` (value) at `x` with step h: gradient and Hessian.
    fn fd(f: &dyn Fn(&[f64; 3]) -> f64, x: [f64; 3], h: f64) -> ([f64; 3], [[f64; 3]; 3]) {
        let at = |d: [f64; 3]| f(&[x[0] + d[0], x[1] + d[1], x[2] + d[2]]);
        let mut g = [0.0; 3];
        let mut hm = [[0.0; 3]; 3];
        for i in 0..3 {
            let mut e = [0.0; 3];
            e[i] = h;
            g[i] = (at(e) - at(e.map(|v| -v))) / (2.0 * h);
            for j in 0..3 {
                let mut ej = [0.0; 3];
                ej[j] = h;
                let pp = at([e[0] + ej[0], e[1] + ej[1], e[2] + ej[2]]);
                let pm = at([e[0] - ej[0], e[1] - ej[1], e[2] - ej[2]]);
                let mp = at([-e[0] + ej[0], -e[1] + ej[1], -e[2] + ej[2]]);
                let mm = at([-e[0] - ej[0], -e[1] - ej[1], -e[2] - ej[2]]);
                hm[i][j] = (pp - pm - mp + mm) / (4.0 * h * h);
            }
        }
        (g, hm)
    }

    fn assert_jet_close(jet: &Jet, g: [f64; 3], h: [[f64; 3]; 3], tol: f64, what: &str) {
        let scale = 1.0 + jet.hessian.iter().flatten().fold(0.0f64, |m, v| m.max(v.abs()));
        for i in 0..3 {
            assert!(
                (jet.gradient[i] - g[i]).abs() <= tol * scale,
                "{what}: grad {:?} vs {g:?}",
                jet.gradient
            );
            for j in 0..3 {
                assert!(
                    (jet.hessian[i][j] - h[i][j]).abs() <= tol * scale,
                    "{what}: hess {:?} vs {h:?}",
                    jet.hessian
                );
            }
        }
    }

    #[test]
    fn every_kernel_matches_finite_differences() {
        let kernels = [
            Kernel::new(3, 2).unwrap(),
            Kernel::new(3, 3).unwrap(),
            Kernel::new(2, 2).unwrap(),
            Kernel::new(2, 3).unwrap(),
            Kernel::new(1, 2).unwrap(),
            Kernel::wendland("wendland0", 1.3).unwrap(),
            Kernel::wendland("wendland2", 1.3).unwrap(),
            Kernel::wendland("wendland4", 1.3).unwrap(),
        ];
        let centre = [0.2, -0.1, 0.4];
        for k in kernels {
            for x in [[0.9, 0.3, -0.2], [0.5, 0.1, 0.6], [-0.3, -0.4, 0.1]] {
                let d = [x[0] - centre[0], x[1] - centre[1], x[2] - centre[2]];
                let mut jet = Jet::default();
                add_radial_term(&mut jet, &k, 1.0, d);
                let f = |y: &[f64; 3]| {
                    let r2: f64 = (0..3).map(|j| (y[j] - centre[j]).powi(2)).sum();
                    k.eval_r2(r2)
                };
                assert!((jet.value - f(&x)).abs() < 1e-14);
                let (g, h) = fd(&f, x, 1e-4);
                assert_jet_close(&jet, g, h, 1e-6, &k.name());
            }
        }
    }

    #[test]
    fn smooth_kernels_take_their_limits_at_a_centre() {
        // r^3: Hessian 0 at the centre; C2: a = phi''(0) = -20 / R^2; C4: -56 / R^2, b = 1680 / R^4
        assert_eq!(radial_derivatives(&Kernel::new(3, 3).unwrap(), 0.0), (0.0, 0.0));
        assert_eq!(radial_derivatives(&Kernel::wendland("wendland2", 2.0).unwrap(), 0.0), (-5.0, 0.0));
        assert_eq!(radial_derivatives(&Kernel::wendland("wendland4", 2.0).unwrap(), 0.0), (-14.0, 105.0));
        // the cones: finite (zero) rather than NaN
        for k in [Kernel::new(3, 2).unwrap(), Kernel::wendland("wendland0", 1.0).unwrap()] {
            let (a, b) = radial_derivatives(&k, 0.0);
            assert!(a == 0.0 && b == 0.0);
        }
    }

    #[test]
    fn carriers_match_finite_differences() {
        for spec in [
            "ball:0.1,0.2,-0.3,1.5",
            "ellipsoid:0.1,0.2,-0.3,1.5,0.7,1.1",
            // turned by 0.6 rad about z: axes (cos, sin, 0), (-sin, cos, 0), (0, 0, 1)
            "ellipsoid:0.1,0.2,-0.3,1.5,0.7,1.1,0.8253356149096783,0.5646424733950354,0,\
             -0.5646424733950354,0.8253356149096783,0,0,0,1",
            "union(ball:-0.5,0,0,0.8,ellipsoid:0.5,0,0,0.7,0.9,1.0)",
            "intersection(ball:-0.2,0,0,1.2,ball:0.3,0.1,0,1.0)",
            "difference(ball:0,0,0,1.2,union(ball:0.6,0,0,0.5,ball:0,0.7,0.1,0.4))",
        ] {
            let c = Carrier::parse(spec, 3).unwrap();
            for x in [[0.3, -0.2, 0.25], [-0.7, 0.4, 0.1], [1.1, 0.9, -0.6]] {
                let jet = carrier_jet(&c, &x);
                assert_eq!(jet.value, c.eval(&x));
                let (g, h) = fd(&|y: &[f64; 3]| c.eval(y), x, 1e-4);
                assert_jet_close(&jet, g, h, 1e-6, spec);
            }
        }
    }

    #[test]
    fn splines_with_quadratic_polynomials_and_normalisation_match_finite_differences() {
        let kernel = Kernel::new(3, 3).unwrap();
        let centres = vec![0.1, 0.2, 0.3, -0.4, 0.1, 0.0, 0.5, -0.5, 0.2, 0.0, 0.3, -0.6];
        let poly: Vec<f64> = (0..10).map(|i| 0.1 * i as f64 - 0.35).collect();
        let spline = Spline {
            kernel,
            centres,
            weights: vec![0.7, -0.3, 0.2, -0.6],
            poly,
            norm: Normalisation { centre: [1.0, -2.0, 0.5], scale: 3.0 },
        };
        let x = [1.4, -1.1, 1.2];
        let jet = spline_jet(&spline, &x);
        assert!((jet.value - spline.eval(&x)).abs() < 1e-13);
        let (g, h) = fd(&|y: &[f64; 3]| spline.eval(y), x, 1e-4);
        assert_jet_close(&jet, g, h, 1e-6, "r3 spline");
    }
}
