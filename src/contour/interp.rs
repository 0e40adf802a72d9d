//! Interpolation between the section functions F_i along the slice parameter tau. Only weights
//! live here, no geometry: F = sum_j w_j(tau) F_j, with knots tau_0 < tau_1 < ... at the slices.
//!
//! **Linear** (`--interp linear`): for tau = tau_i + t (tau_(i+1) - tau_i), t in [0, 1],
//!
//! ```text
//! F = (1 - t) F_i + t F_(i+1)          (w_i = 1 - t, w_(i+1) = t, every other w_j = 0)
//! ```
//!
//! It is continuous and, at a fixed in-plane point, never leaves the range of F_i and F_(i+1),
//! but its derivative jumps at every slice, which shows as creases in the surface.
//!
//! **Cubic** (`--interp cubic`): w_j is the cardinal natural cubic spline of knot j, the C^2
//! piecewise cubic with w_j(tau_i) = delta_ij and zero second derivative at the first and last
//! knots. Interpolating any values y_j with a natural cubic spline is linear in the y_j, so the
//! spline through the values F_j(a, b) is exactly sum_j w_j(tau) F_j(a, b). Natural splines
//! reproduce straight lines, so sum_j w_j = 1 and sum_j w_j tau_j = tau. Each w_j is stored by its
//! second derivatives M_k at the knots, the solution of the tridiagonal system (k = 1 .. n-2)
//!
//! ```text
//! h_(k-1) M_(k-1) + 2 (h_(k-1) + h_k) M_k + h_k M_(k+1)
//!     = 6 ((y_(k+1) - y_k) / h_k - (y_k - y_(k-1)) / h_(k-1)),
//! M_0 = M_(n-1) = 0,     h_k = tau_(k+1) - tau_k,     y_k = delta_jk,
//! ```
//!
//! and evaluated on interval i, with a = 1 - t and b = t, as
//!
//! ```text
//! w_j = a y_i + b y_(i+1) + ((a^3 - a) M_i + (b^3 - b) M_(i+1)) h_i^2 / 6.
//! ```
//!
//! The cardinal weights are not local: they alternate in sign and decay by about 2 - sqrt(3) per
//! knot away from the interval, so F at a point depends (slightly) on every slice, and the
//! negative weights let F overshoot across an abrupt change of the sections (see
//! [`CARDINAL_CUTOFF`]). In exchange F is C^2 in tau: between parallel slices the surface has no
//! creases at the slices.

use crate::error::{Error, Result};

/// The interpolation between slices.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Interp {
    Linear,
    Cubic,
}

impl Interp {
    pub fn parse(name: &str) -> Result<Self> {
        match name {
            "linear" => Ok(Interp::Linear),
            "cubic" => Ok(Interp::Cubic),
            other => Err(Error::Usage(format!("unknown --interp '{other}' (expected linear or cubic)"))),
        }
    }

    pub fn name(&self) -> &'static str {
        match self {
            Interp::Linear => "linear",
            Interp::Cubic => "cubic",
        }
    }
}

/// Cardinal weights below this magnitude are left out of the sum (they decay by about
/// 2 - sqrt(3) = 0.27 per knot away from the point, so some fourteen neighbours on each side
/// remain).
pub const CARDINAL_CUTOFF: f64 = 1e-8;

/// The slice weights for one interpolation on fixed knots.
#[derive(Debug, Clone, PartialEq)]
pub struct Blend {
    pub interp: Interp,
    pub knots: Vec<f64>,
    /// second[j * n + i]: second derivative of the cardinal spline w_j at knot i.
    second: Vec<f64>,
}

impl Blend {
    /// Knots must be strictly increasing (at least two).
    pub fn new(interp: Interp, knots: Vec<f64>) -> Self {
        assert!(knots.len() >= 2 && knots.windows(2).all(|w| w[1] > w[0]), "knots must increase");
        let n = knots.len();
        let mut second = vec![0.0; n * n];
        if interp == Interp::Cubic {
            for j in 0..n {
                let y: Vec<f64> = (0..n).map(|i| f64::from(u8::from(i == j))).collect();
                second[j * n..(j + 1) * n].copy_from_slice(&natural_second_derivatives(&knots, &y));
            }
        }
        Blend { interp, knots, second }
    }

    /// The interval i with `knots[i] <= tau <= knots[i+1]` (clamped to the first and last).
    pub fn interval(&self, tau: f64) -> usize {
        let n = self.knots.len();
        self.knots[1..n - 1].partition_point(|&k| k <= tau)
    }

    /// Appends (j, w_j) for a point at fraction t in [0, 1] of interval i to `out` (cleared first).
    pub fn weights(&self, i: usize, t: f64, out: &mut Vec<(usize, f64)>) {
        out.clear();
        match self.interp {
            Interp::Linear => {
                out.push((i, 1.0 - t));
                out.push((i + 1, t));
            }
            Interp::Cubic => {
                let n = self.knots.len();
                let h = self.knots[i + 1] - self.knots[i];
                let (a, b) = (1.0 - t, t);
                let (ca, cb) = ((a * a * a - a) * h * h / 6.0, (b * b * b - b) * h * h / 6.0);
                for j in 0..n {
                    let m = &self.second[j * n..(j + 1) * n];
                    let mut w = ca * m[i] + cb * m[i + 1];
                    if j == i {
                        w += a;
                    } else if j == i + 1 {
                        w += b;
                    }
                    if w.abs() >= CARDINAL_CUTOFF || j == i || j == i + 1 {
                        out.push((j, w));
                    }
                }
            }
        }
    }
}

/// Second derivatives of the natural cubic spline through (x_k, y_k) (Thomas algorithm).
pub fn natural_second_derivatives(x: &[f64], y: &[f64]) -> Vec<f64> {
    let n = x.len();
    let mut m = vec![0.0; n];
    if n < 3 {
        return m;
    }
    // interior equations k = 1..n-2: h_(k-1) M_(k-1) + 2 (h_(k-1) + h_k) M_k + h_k M_(k+1) = r_k
    let h: Vec<f64> = x.windows(2).map(|w| w[1] - w[0]).collect();
    let mut diag = vec![0.0; n];
    let mut rhs = vec![0.0; n];
    for k in 1..n - 1 {
        diag[k] = 2.0 * (h[k - 1] + h[k]);
        rhs[k] = 6.0 * ((y[k + 1] - y[k]) / h[k] - (y[k] - y[k - 1]) / h[k - 1]);
    }
    for k in 2..n - 1 {
        let l = h[k - 1] / diag[k - 1];
        diag[k] -= l * h[k - 1];
        rhs[k] -= l * rhs[k - 1];
    }
    for k in (1..n - 1).rev() {
        m[k] = (rhs[k] - h[k] * m[k + 1]) / diag[k];
    }
    m
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cardinal_weights_interpolate_and_reproduce_lines() {
        let knots: Vec<f64> = (0..12).map(|i| i as f64 * 0.7 + 0.05 * (i * i) as f64).collect();
        let b = Blend::new(Interp::Cubic, knots.clone());
        let mut w = Vec::new();
        for i in 0..11 {
            for t in [0.0, 0.3, 0.77, 1.0] {
                b.weights(i, t, &mut w);
                let tau = knots[i] + t * (knots[i + 1] - knots[i]);
                let sum: f64 = w.iter().map(|p| p.1).sum();
                let lin: f64 = w.iter().map(|&(j, x)| x * knots[j]).sum();
                assert!((sum - 1.0).abs() < 1e-7, "partition of unity {sum}");
                assert!((lin - tau).abs() < 1e-6, "lines are reproduced {lin} {tau}");
                if t == 0.0 {
                    for &(j, x) in &w {
                        assert!((x - f64::from(u8::from(j == i))).abs() < 1e-15);
                    }
                }
            }
        }
        // a cubic is not linear: the weights of the neighbours outside the interval are nonzero
        b.weights(5, 0.5, &mut w);
        assert!(w.iter().any(|&(j, x)| j == 4 && x < -0.01), "{w:?}");
    }

    #[test]
    fn natural_spline_matches_a_known_case() {
        // through (0,0), (1,1), (2,0): M_1 = -3, the natural spline's curvature at the peak
        let m = natural_second_derivatives(&[0.0, 1.0, 2.0], &[0.0, 1.0, 0.0]);
        assert_eq!(m, vec![0.0, -3.0, 0.0]);
        let b = Blend::new(Interp::Linear, vec![0.0, 2.0, 3.0]);
        assert_eq!(b.interval(-1.0), 0);
        assert_eq!(b.interval(2.5), 1);
        assert_eq!(b.interval(9.0), 1);
        let mut w = Vec::new();
        b.weights(1, 0.25, &mut w);
        assert_eq!(w, vec![(1, 0.75), (2, 0.25)]);
    }
}
