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
//! knot away from the interval (by at least half), so F at a point depends (slightly) on the
//! slices within some dozens of knots (see [`Blend`] for how far they are taken), and the
//! negative weights let F overshoot across an abrupt change of the sections (see
//! [`CARDINAL_CUTOFF`]). In exchange F is C^2 in tau: between parallel slices the surface has no
//! creases at the slices.
//!
//! **Monotone** (`--interp monotone`): on interval i the cubic Hermite polynomial through F_i and
//! F_(i+1) with slopes d_i, d_(i+1) chosen from the neighbouring values so that it never leaves
//! the range of F_i and F_(i+1) (piecewise cubic Hermite interpolation that keeps the data's
//! shape, Fritsch and Butland's slopes). With the secants s_k = (F_(k+1) - F_k) / h_k, an
//! interior slope is
//!
//! ```text
//! d_k = 0                                            where s_(k-1) s_k <= 0 (F turns at knot k),
//! d_k = (w1 + w2) / (w1 / s_(k-1) + w2 / s_k)        else, w1 = 2 h_k + h_(k-1), w2 = h_k + 2 h_(k-1),
//! ```
//!
//! a weighted harmonic mean of the secants, of their sign and at most 3 min(|s_(k-1)|, |s_k|);
//! the first knot's slope is the three-point one-sided difference ((2 h_0 + h_1) s_0 - h_0 s_1) /
//! (h_0 + h_1), set to 0 where its sign is not s_0's and to 3 s_0 where the secants change sign
//! and it exceeds that (the last knot's alike), and a slope of the only interval of two slices is
//! its secant. Slopes of the secant's sign and at most three times it keep the cubic on an
//! interval monotone (Fritsch and Carlson's sufficient condition), so F between two slices lies
//! between their values: where a point is outside both neighbouring sections it stays outside,
//! and the solid between two slices never reaches beyond what the two sections' functions give,
//! however abruptly the sections change. F is C^1 in tau (no creases at parallel slices), depends
//! on the four slices around the interval only, and is not a linear combination of the F_j: the
//! slopes depend on the values at the point.

use crate::error::{Error, Result};

/// The interpolation between slices.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Interp {
    Linear,
    Cubic,
    Monotone,
}

impl Interp {
    pub fn parse(name: &str) -> Result<Self> {
        match name {
            "linear" => Ok(Interp::Linear),
            "cubic" => Ok(Interp::Cubic),
            "monotone" => Ok(Interp::Monotone),
            other => {
                Err(Error::Usage(format!("unknown --interp '{other}' (expected linear, cubic or monotone)")))
            }
        }
    }

    pub fn name(&self) -> &'static str {
        match self {
            Interp::Linear => "linear",
            Interp::Cubic => "cubic",
            Interp::Monotone => "monotone",
        }
    }
}

/// Cardinal weights below this magnitude are left out of the sum (they decay by about
/// 2 - sqrt(3) = 0.27 per knot away from the point, so some fourteen neighbours on each side
/// remain).
pub const CARDINAL_CUTOFF: f64 = 1e-8;

/// Knots on either side of knot j within which the cardinal spline w_j is computed and used
/// (see [`Blend`]).
pub const CARDINAL_REACH: usize = 64;

/// The slice weights for one interpolation on fixed knots.
///
/// The cardinal spline w_j is computed on the knots within [`CARDINAL_REACH`] of j, as the
/// natural spline of those knots alone, and taken as zero beyond. Both are exact to rounding:
/// the tridiagonal system is diagonally dominant by a factor of at least 2 (2 (h_(k-1) + h_k)
/// against h_(k-1) + h_k), so the influence of a knot, or of an end condition, shrinks by at
/// least half per knot (by 2 - sqrt(3) for even spacing): 64 knots away by 2^-64, far below
/// [`CARDINAL_CUTOFF`] and the rounding of the sum. With at most 65 slices the window is every
/// knot and the weights are those of the whole spline to the bit. So the table takes (2 * 64 + 1)
/// values a knot and a weight sum at most 130 terms, where the whole table of n^2 values took 80
/// GB at the 100,000 planes `volspline slice` may write.
#[derive(Debug, Clone, PartialEq)]
pub struct Blend {
    pub interp: Interp,
    pub knots: Vec<f64>,
    /// second[j * STRIDE + (i - window(j).0)]: second derivative of the cardinal spline w_j at
    /// knot i, for the knots i of j's window (cubic only).
    second: Vec<f64>,
}

/// Values of the table a knot.
const STRIDE: usize = 2 * CARDINAL_REACH + 1;

impl Blend {
    /// Knots must be strictly increasing (at least two).
    pub fn new(interp: Interp, knots: Vec<f64>) -> Self {
        assert!(knots.len() >= 2 && knots.windows(2).all(|w| w[1] > w[0]), "knots must increase");
        let n = knots.len();
        let mut second = Vec::new();
        if interp == Interp::Cubic {
            second = vec![0.0; n * STRIDE];
            for j in 0..n {
                let (lo, hi) = window(j, n);
                let y: Vec<f64> = (lo..=hi).map(|i| f64::from(u8::from(i == j))).collect();
                let m = natural_second_derivatives(&knots[lo..=hi], &y);
                second[j * STRIDE..j * STRIDE + m.len()].copy_from_slice(&m);
            }
        }
        Blend { interp, knots, second }
    }

    /// The interval i with `knots[i] <= tau <= knots[i+1]` (clamped to the first and last).
    pub fn interval(&self, tau: f64) -> usize {
        let n = self.knots.len();
        self.knots[1..n - 1].partition_point(|&k| k <= tau)
    }

    /// F at fraction t in [0, 1] of interval i, from the sections' values `f(j)` at the point.
    /// Linear and cubic sum the weights of [`Blend::weights`] (`scratch` holds them); monotone
    /// reads the values of at most the four slices i - 1 .. i + 2 (see the module documentation).
    pub fn value(&self, i: usize, t: f64, scratch: &mut Vec<(usize, f64)>, f: impl Fn(usize) -> f64) -> f64 {
        if self.interp != Interp::Monotone {
            self.weights(i, t, scratch);
            return scratch.iter().map(|&(j, w)| w * f(j)).sum();
        }
        let n = self.knots.len();
        let h = |k: usize| self.knots[k + 1] - self.knots[k];
        let (fi, fj) = (f(i), f(i + 1));
        let secant = (fj - fi) / h(i);
        let before = (i > 0).then(|| (h(i - 1), (fi - f(i - 1)) / h(i - 1)));
        let after = (i + 2 < n).then(|| (h(i + 1), (f(i + 2) - fj) / h(i + 1)));
        let d_i = match before {
            Some((hb, sb)) => interior_slope(hb, sb, h(i), secant),
            None => after.map_or(secant, |(ha, sa)| end_slope(h(i), secant, ha, sa)),
        };
        let d_j = match after {
            Some((ha, sa)) => interior_slope(h(i), secant, ha, sa),
            None => before.map_or(secant, |(hb, sb)| end_slope(h(i), secant, hb, sb)),
        };
        let (t2, t3) = (t * t, t * t * t);
        let h00 = 2.0 * t3 - 3.0 * t2 + 1.0;
        let h10 = t3 - 2.0 * t2 + t;
        let h01 = -2.0 * t3 + 3.0 * t2;
        let h11 = t3 - t2;
        h00 * fi + h01 * fj + h(i) * (h10 * d_i + h11 * d_j)
    }

    /// Appends (j, w_j) for a point at fraction t in [0, 1] of interval i to `out` (cleared first).
    /// Monotone interpolation has no weights (it is not linear in the F_j): see [`Blend::value`].
    pub fn weights(&self, i: usize, t: f64, out: &mut Vec<(usize, f64)>) {
        out.clear();
        match self.interp {
            Interp::Monotone => panic!("monotone interpolation has no weights; Blend::value computes it"),
            Interp::Linear => {
                out.push((i, 1.0 - t));
                out.push((i + 1, t));
            }
            Interp::Cubic => {
                let n = self.knots.len();
                let h = self.knots[i + 1] - self.knots[i];
                let (a, b) = (1.0 - t, t);
                let (ca, cb) = ((a * a * a - a) * h * h / 6.0, (b * b * b - b) * h * h / 6.0);
                // the splines whose windows hold both ends of the interval
                for j in (i + 1).saturating_sub(CARDINAL_REACH)..=(i + CARDINAL_REACH).min(n - 1) {
                    let lo = window(j, n).0;
                    let m = &self.second[j * STRIDE..(j + 1) * STRIDE];
                    let mut w = ca * m[i - lo] + cb * m[i + 1 - lo];
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

/// The slope at a knot between intervals of lengths `h0`, `h1` with secants `s0`, `s1`: their
/// weighted harmonic mean, or 0 where F turns there.
fn interior_slope(h0: f64, s0: f64, h1: f64, s1: f64) -> f64 {
    if s0 * s1 <= 0.0 {
        return 0.0;
    }
    let (w1, w2) = (2.0 * h1 + h0, h1 + 2.0 * h0);
    (w1 + w2) / (w1 / s0 + w2 / s1)
}

/// The slope at an end knot of an interval of length `h0` and secant `s0`, whose neighbour has
/// length `h1` and secant `s1`: the one-sided three-point difference, limited to the secant's sign
/// and, where the secants change sign, to three times it.
fn end_slope(h0: f64, s0: f64, h1: f64, s1: f64) -> f64 {
    let d = ((2.0 * h0 + h1) * s0 - h0 * s1) / (h0 + h1);
    if d * s0 <= 0.0 {
        0.0
    } else if s0 * s1 < 0.0 && d.abs() > 3.0 * s0.abs() {
        3.0 * s0
    } else {
        d
    }
}

/// The first and last knot of the window of the cardinal spline w_j among n knots.
fn window(j: usize, n: usize) -> (usize, usize) {
    (j.saturating_sub(CARDINAL_REACH), (j + CARDINAL_REACH).min(n - 1))
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
    fn windowed_cardinal_weights_are_the_whole_spline_s() {
        // uneven knots: the whole spline's weights (every w_j on every knot, as a dense table)
        // against the table's, on 65 knots (one window: the same bits) and on 400 (windows)
        for n in [65, 400] {
            let knots: Vec<f64> = (0..n).map(|i| i as f64 + 0.45 * (i as f64 * 1.7).sin()).collect();
            let b = Blend::new(Interp::Cubic, knots.clone());
            let whole: Vec<Vec<f64>> = (0..n)
                .map(|j| {
                    let y: Vec<f64> = (0..n).map(|i| f64::from(u8::from(i == j))).collect();
                    natural_second_derivatives(&knots, &y)
                })
                .collect();
            let mut w = Vec::new();
            for i in [0, 1, 30, n / 2, n - 2] {
                for t in [0.0, 0.4, 1.0] {
                    b.weights(i, t, &mut w);
                    let h = knots[i + 1] - knots[i];
                    let (a, c) = (1.0 - t, t);
                    let (ca, cb) = ((a * a * a - a) * h * h / 6.0, (c * c * c - c) * h * h / 6.0);
                    let want: Vec<(usize, f64)> = (0..n)
                        .map(|j| {
                            let base = if j == i {
                                a
                            } else if j == i + 1 {
                                c
                            } else {
                                0.0
                            };
                            (j, ca * whole[j][i] + cb * whole[j][i + 1] + base)
                        })
                        .filter(|&(j, x)| x.abs() >= CARDINAL_CUTOFF || j == i || j == i + 1)
                        .collect();
                    if n == 65 {
                        assert_eq!(w, want, "n {n}, interval {i}, t {t}");
                    } else {
                        assert_eq!(w.len(), want.len(), "n {n}, interval {i}, t {t}");
                        for (g, e) in w.iter().zip(&want) {
                            assert!(g.0 == e.0 && (g.1 - e.1).abs() < 1e-15, "{g:?} {e:?}");
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn cubic_weights_on_as_many_knots_as_slice_writes_planes() {
        // 100,000 knots: the whole table would take 80 GB; the windows take 103 MB, and a weight
        // sum at most 2 * CARDINAL_REACH + 2 terms
        let knots: Vec<f64> = (0..100_000).map(|i| i as f64 * 1e-3).collect();
        let b = Blend::new(Interp::Cubic, knots.clone());
        let mut w = Vec::new();
        for i in [0, 50_000, 99_998] {
            b.weights(i, 0.3, &mut w);
            let sum: f64 = w.iter().map(|p| p.1).sum();
            let lin: f64 = w.iter().map(|&(j, x)| x * knots[j]).sum();
            // (the weights below the cutoff left out, times knots up to 100)
            let tau = knots[i] + 0.3e-3;
            assert!((sum - 1.0).abs() < 1e-7 && (lin - tau).abs() < 1e-7 * (1.0 + tau), "{sum} {lin}");
            assert!(w.len() <= 2 * CARDINAL_REACH + 2 && w.len() > 10, "{}", w.len());
        }
    }

    #[test]
    fn monotone_values_stay_between_the_slices_and_follow_smooth_data() {
        let knots: Vec<f64> = (0..9).map(|i| i as f64 * 0.5 + 0.03 * (i * i) as f64).collect();
        let b = Blend::new(Interp::Monotone, knots.clone());
        let mut scratch = Vec::new();
        // an abrupt change (a section that appears between two empty ones, as a thin part
        // cut by one slice) never leaves the range of the interval's two values
        let step: [f64; 9] = [-1.0, -1.0, -1.0, 2.0, 2.0, -1.0, -1.0, 0.5, -3.0];
        for i in 0..8 {
            let (lo, hi) = (step[i].min(step[i + 1]), step[i].max(step[i + 1]));
            for k in 0..=50 {
                let t = k as f64 / 50.0;
                let v = b.value(i, t, &mut scratch, |j| step[j]);
                assert!(v >= lo - 1e-15 && v <= hi + 1e-15, "interval {i} t {t}: {v} outside [{lo}, {hi}]");
            }
            assert_eq!(b.value(i, 0.0, &mut scratch, |j| step[j]), step[i]);
            assert_eq!(b.value(i, 1.0, &mut scratch, |j| step[j]), step[i + 1]);
        }
        // the natural cubic through the same values overshoots: below -1 between two -1s
        let cubic = Blend::new(Interp::Cubic, knots.clone());
        assert!(cubic.value(1, 0.5, &mut scratch, |j| step[j]) < -1.05);
        assert_eq!(b.value(1, 0.5, &mut scratch, |j| step[j]), -1.0);
        // smooth monotone data: a line is reproduced and a quadratic followed to third order
        let line = |j: usize| 3.0 - 2.0 * knots[j];
        let quad = |tau: f64| 1.0 + tau * tau;
        for i in 0..8 {
            let tau = knots[i] + 0.37 * (knots[i + 1] - knots[i]);
            assert!((b.value(i, 0.37, &mut scratch, line) - (3.0 - 2.0 * tau)).abs() < 1e-13);
            let err = (b.value(i, 0.37, &mut scratch, |j| quad(knots[j])) - quad(tau)).abs();
            assert!(err < 0.02, "interval {i}: {err}");
        }
        // two slices: the secant
        let two = Blend::new(Interp::Monotone, vec![0.0, 2.0]);
        assert_eq!(two.value(0, 0.25, &mut scratch, |j| [1.0, -3.0][j]), 0.0);
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
