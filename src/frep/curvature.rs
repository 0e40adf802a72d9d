//! Mean and Gaussian curvature of the level surfaces of a solid, from its gradient and Hessian.
//!
//! For a surface f = const with g = grad f != 0 and H the Hessian of f, Goldman (*Curvature
//! formulas for implicit curves and surfaces*, 2005) gives
//!
//! ```text
//! Gaussian  K = (g^T adj(H) g) / |g|^4
//! mean      M = (g^T H g - |g|^2 tr H) / (2 |g|^3)
//! ```
//!
//! with adj(H) the adjugate (the transposed cofactor matrix; H^-1 det H where H is invertible).
//! K does not change when f changes sign; M does. With the convention of this crate, f >= 0
//! inside, these formulas make convex surfaces positively curved: for the ball
//! f = R^2 - |x|^2, g = -2x and H = -2I give g^T H g = -8R^2 and |g|^2 tr H = -24R^2 on |x| = R,
//! so M = 16R^2 / (2 * 8R^3) = 1/R, and adj(H) = 4I gives K = 16R^2 / 16R^4 = 1/R^2. M is the mean
//! of the principal curvatures k1, k2 and K their product, so k1,2 = M +- sqrt(M^2 - K).
//!
//! Where g = 0 there is no level surface through the point: both curvatures are NaN.

use super::Implicit;

/// The curvatures of the level surface through a point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Curvature {
    /// (k1 + k2) / 2, positive where the surface bends like a ball's (f >= 0 inside).
    pub mean: f64,
    /// k1 k2.
    pub gaussian: f64,
}

impl Curvature {
    /// The principal curvatures (k1 >= k2); a negative discriminant from rounding counts as 0.
    pub fn principal(&self) -> (f64, f64) {
        let d = (self.mean * self.mean - self.gaussian).max(0.0).sqrt();
        (self.mean + d, self.mean - d)
    }
}

/// Goldman's formulas for gradient `g` and Hessian `h` (row-major, symmetric).
pub fn from_derivatives(g: [f64; 3], h: [[f64; 3]; 3]) -> Curvature {
    let g2 = g[0] * g[0] + g[1] * g[1] + g[2] * g[2];
    if !(g2 > 0.0) || !g2.is_finite() {
        return Curvature { mean: f64::NAN, gaussian: f64::NAN };
    }
    // adj(H)_ij = cofactor_ji; H is symmetric, so adj(H) is too
    let cof = |i: usize, j: usize| {
        let (r0, r1) = ((i + 1) % 3, (i + 2) % 3);
        let (c0, c1) = ((j + 1) % 3, (j + 2) % 3);
        h[r0][c0] * h[r1][c1] - h[r0][c1] * h[r1][c0]
    };
    let mut gag = 0.0;
    let mut ghg = 0.0;
    for i in 0..3 {
        for j in 0..3 {
            gag += g[i] * cof(j, i) * g[j];
            ghg += g[i] * h[i][j] * g[j];
        }
    }
    let trace = h[0][0] + h[1][1] + h[2][2];
    let norm = g2.sqrt();
    Curvature { mean: (ghg - g2 * trace) / (2.0 * g2 * norm), gaussian: gag / (g2 * g2) }
}

/// The curvatures of the level surface of `solid` through `p`.
pub fn curvature<S: Implicit + ?Sized>(solid: &S, p: [f64; 3]) -> Curvature {
    from_derivatives(solid.gradient(p), solid.hessian(p))
}

/// The largest magnitude of a coordinate where curvature is taken: it needs f's second
/// derivatives, of the order f / length^2, and for a solid whose f is of order one (a fitted
/// ellipsoid's carrier) those underflow where lengths reach 1e154; below 1e150 they are
/// representable for every carrier.
pub const MAX_CURVATURE_REACH: f64 = 1e150;

/// Refuses curvature over a region whose coordinates reach beyond [`MAX_CURVATURE_REACH`]
/// (`reach`: their largest magnitude), naming what asked for it.
pub fn check_curvature_reach(reach: f64, what: &str) -> crate::error::Result<()> {
    if reach <= MAX_CURVATURE_REACH {
        return Ok(());
    }
    Err(crate::error::Error::Usage(format!(
        "{what} takes the mean curvature from f's second derivatives, which underflow for coordinates of \
         {reach:e} (at most {MAX_CURVATURE_REACH:e}); rescale the data"
    )))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The torus around the z axis with radii `big` (of the centre circle) and `small` (of the
    /// tube): f = small^2 - (sqrt(x^2 + y^2) - big)^2 - z^2, derivatives left to the defaults.
    struct Torus {
        big: f64,
        small: f64,
    }
    impl Implicit for Torus {
        fn value(&self, p: [f64; 3]) -> f64 {
            let rho = (p[0] * p[0] + p[1] * p[1]).sqrt();
            self.small * self.small - (rho - self.big).powi(2) - p[2] * p[2]
        }
        fn bounds(&self) -> ([f64; 3], [f64; 3]) {
            let e = self.big + self.small;
            ([-e, -e, -self.small], [e, e, self.small])
        }
    }

    #[test]
    fn a_ball_has_mean_curvature_one_over_its_radius() {
        let r = 2.5;
        let p = [1.5, 2.0, 0.0]; // |p| = 2.5
        let c = from_derivatives(p.map(|v| -2.0 * v), [[-2.0, 0.0, 0.0], [0.0, -2.0, 0.0], [0.0, 0.0, -2.0]]);
        assert!((c.mean - 1.0 / r).abs() < 1e-15 && (c.gaussian - 1.0 / (r * r)).abs() < 1e-15, "{c:?}");
        // the outside of the ball (f <= 0 inside) is curved the other way
        let c = from_derivatives(p.map(|v| 2.0 * v), [[2.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, 2.0]]);
        assert!((c.mean + 1.0 / r).abs() < 1e-15 && (c.gaussian - 1.0 / (r * r)).abs() < 1e-15);
        assert!(from_derivatives([0.0; 3], [[1.0; 3]; 3]).mean.is_nan());
    }

    #[test]
    fn a_torus_has_its_known_curvatures() {
        let t = Torus { big: 3.0, small: 1.0 };
        for v in [0.0f64, 0.7, 1.5, 2.4, std::f64::consts::PI, 4.0, 5.5] {
            let u = 0.4f64;
            let rho = t.big + t.small * v.cos();
            let p = [rho * u.cos(), rho * u.sin(), t.small * v.sin()];
            let c = curvature(&t, p);
            let k = v.cos() / (t.small * rho);
            let m = (t.big + 2.0 * t.small * v.cos()) / (2.0 * t.small * rho);
            assert!((c.gaussian - k).abs() < 1e-5 && (c.mean - m).abs() < 1e-5, "v = {v}: {c:?} vs {k}, {m}");
            let (k1, k2) = c.principal();
            assert!((k1 - 1.0 / t.small).abs() < 1e-4 || (k2 - 1.0 / t.small).abs() < 1e-4);
        }
    }
}
