//! Orientation matrices of the section planes: the rotation logarithm and exponential, the
//! interpolation of the frame between two sections (log/exp or quaternion slerp), and frames
//! generated from angular velocities (direction cosines integrated with RK4 and renormalised). Pure
//! functions of frames; no knowledge of splines or files.
//!
//! A frame is a rotation matrix M whose columns are the section's in-plane axes u, v and its
//! normal w = u x v, in the fixed (world) coordinates: a point with section coordinates (a, b, c)
//! is x = o + M (a, b, c), and (a, b, c) = M^T (x - o).
//!
//! # Logarithm and exponential
//!
//! Every rotation is `exp([r]x)` for a rotation vector r = theta k (unit axis k, angle theta in
//! `[0, pi]`), where `[r]x` is the skew matrix with `[r]x y = r x y`. By Rodrigues' formula
//!
//! ```text
//! exp([r]x) = I + sin(theta) [k]x + (1 - cos(theta)) [k]x^2,
//! ```
//!
//! and `ln M = [r]x` is its inverse on angles below pi (the principal logarithm). Both are computed
//! through the unit quaternion q = (cos(theta/2), sin(theta/2) k), which stays accurate for tiny
//! angles ([`rotation_log`], [`rotation_exp`]).
//!
//! # Interpolating the frame between two sections
//!
//! A point between planes i and i+1 at distances d1 and d2 from them has t = d1 / (d1 + d2), which
//! is 0 on plane i and 1 on plane i+1. Its frame must therefore be M(0) = M_i and M(1) = M_(i+1).
//!
//! **Log/exp** ([`Orient::Log`]): interpolate linearly in the logarithms,
//!
//! ```text
//! M(t) = exp((1 - t) ln M_i + t ln M_(i+1)).
//! ```
//!
//! The weight of ln M_i is 1 - t, because t = 0 on plane i. The form printed for this method by
//! Savchenko et al. (1995), M(t) = exp(t ln M_i + (1 - t) ln M_(i+1)), has the weights swapped:
//! with the same t it gives M(0) = M_(i+1) and M(1) = M_i, so each section would be read in its
//! neighbour's frame.
//!
//! **Slerp** ([`Orient::Slerp`], the default): the geodesic from M_i to M_(i+1), the rotation at
//! constant angular velocity about one fixed body axis,
//!
//! ```text
//! M(t) = M_i exp(t ln(M_i^T M_(i+1)))
//!      = the matrix of  slerp(q_i, q_(i+1); t) = (sin((1 - t) W) q_i + sin(t W) q_(i+1)) / sin(W),
//! cos(W) = q_i . q_(i+1)     (the quaternions taken in the same hemisphere: the shorter arc).
//! ```
//!
//! **Why they agree about a fixed axis.** If `M_i = exp(alpha [k]x)` and `M_(i+1) = exp(beta [k]x)`
//! turn about the same axis k (angles in (-pi, pi)), then `ln M_i = alpha [k]x`,
//! `ln M_(i+1) = beta [k]x`, and the two matrices commute, so
//! `M_i^T M_(i+1) = exp((beta - alpha) [k]x)` and
//!
//! ```text
//! log/exp:  exp(((1 - t) alpha + t beta) [k]x)
//! slerp:    exp(alpha [k]x) exp(t (beta - alpha) [k]x) = exp((alpha + t (beta - alpha)) [k]x),
//! ```
//!
//! the same rotation. About different axes the rotations do not commute (exp(A + B) is not
//! exp(A) exp(B)), and the two differ: the log/exp average depends on the world axes (turning both
//! frames by a rotation R does not turn M(t) by R) and its principal logarithm jumps near angles
//! of pi, while slerp turns with them (R M_i and R M_(i+1) give R M(t)). Between close frames the
//! difference is small.
//!
//! # Frames from angular velocities
//!
//! The second way to give the sections is by the motion of the frame: body angular velocities
//! omega = (w1, w2, w3) (components in the moving frame), under which `M' = M [omega]x`. Let
//! gamma be the direction cosines of a fixed world axis in the moving frame, a column of M^T (a row of M).
//! Then `gamma' = (M^T)' e = -[omega]x M^T e`, that is
//!
//! ```text
//! gamma' = gamma x omega:    gamma1' + w2 gamma3 - w3 gamma2 = 0
//!                            gamma2' + w3 gamma1 - w1 gamma3 = 0
//!                            gamma3' + w1 gamma2 - w2 gamma1 = 0
//! ```
//!
//! (Savchenko et al. (1995) print the third line as gamma3' + w1 gamma3 - w3 gamma1 = 0, which is
//! not the third component of gamma x omega.) |gamma|^2 = 1 is a first integral, since
//! d|gamma|^2/dt = 2 gamma . (gamma x omega) = 0; RK4 does not keep it exactly, so each step is
//! renormalised. The direction cosines of the world x and y axes are integrated, made orthogonal,
//! and the third row follows as their cross product ([`integrate_angular_velocity`]).
//!
//! The angular velocities generate the slices' frames (constant over each interval of the slice
//! parameter); between two slices the frame is then interpolated like any other pair. With a
//! constant angular velocity the exact solution is `M_i exp(t [omega]x)`, which is the geodesic, so
//! slerp reproduces the integrated motion at every t, not only at the slices.

use glam::{DMat3, DQuat, DVec3};

/// How the orientation matrix M(t) between two section frames is made.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Orient {
    /// M(t) = exp((1 - t) ln M_i + t ln M_(i+1)): linear in the rotation logarithms.
    Log,
    /// Quaternion slerp, the geodesic M_i exp(t ln(M_i^T M_(i+1))).
    Slerp,
}

impl Orient {
    pub fn parse(name: &str) -> crate::error::Result<Self> {
        match name {
            "log" => Ok(Orient::Log),
            "slerp" => Ok(Orient::Slerp),
            other => {
                Err(crate::error::Error::Usage(format!("unknown --orient '{other}' (expected log or slerp)")))
            }
        }
    }

    pub fn name(&self) -> &'static str {
        match self {
            Orient::Log => "log",
            Orient::Slerp => "slerp",
        }
    }
}

/// The unit quaternion of a rotation matrix, with a non-negative scalar part.
pub fn quat_of(m: &DMat3) -> DQuat {
    let q = DQuat::from_mat3(m).normalize();
    if q.w < 0.0 {
        -q
    } else {
        q
    }
}

/// ln M as a rotation vector (axis times angle, angle in `[0, pi]`): the skew matrix `[r]x` is the
/// principal matrix logarithm of M.
pub fn rotation_log(m: &DMat3) -> DVec3 {
    let q = quat_of(m);
    let v = DVec3::new(q.x, q.y, q.z);
    let s = v.length();
    if s == 0.0 {
        return DVec3::ZERO;
    }
    // angle = 2 atan2(|v|, w); the ratio angle / |v| stays accurate for tiny rotations
    v * (2.0 * s.atan2(q.w) / s)
}

/// `exp([r]x)` by Rodrigues' formula, through the quaternion (cos |r|/2, sin(|r|/2) r / |r|).
pub fn rotation_exp(r: DVec3) -> DMat3 {
    let a = r.length();
    let half = 0.5 * a;
    // sin(a/2)/a, with its limit 1/2 at a = 0
    let k = if a > 1e-8 { half.sin() / a } else { 0.5 - a * a / 48.0 };
    DMat3::from_quat(DQuat::from_xyzw(r.x * k, r.y * k, r.z * k, half.cos()))
}

/// Precomputed data of the interpolation between two section frames M_i and M_(i+1).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FramePair {
    pub m0: DMat3,
    pub m1: DMat3,
    log0: DVec3,
    log1: DVec3,
    q0: DQuat,
    q1: DQuat,
}

impl FramePair {
    pub fn new(m0: DMat3, m1: DMat3) -> Self {
        FramePair {
            m0,
            m1,
            log0: rotation_log(&m0),
            log1: rotation_log(&m1),
            q0: quat_of(&m0),
            q1: quat_of(&m1),
        }
    }

    /// M(t), t in [0, 1] (t = 0 on plane i).
    pub fn at(&self, t: f64, orient: Orient) -> DMat3 {
        match orient {
            Orient::Log => rotation_exp(self.log0 * (1.0 - t) + self.log1 * t),
            Orient::Slerp => DMat3::from_quat(self.q0.slerp(self.q1, t)),
        }
    }
}

/// The right-hand side of the Poisson equations gamma' = gamma x omega (see "Frames from angular
/// velocities" in the module doc): gamma is a fixed axis seen from the moving frame, omega the
/// angular velocity in the moving frame.
#[inline]
pub fn direction_cosine_rate(gamma: DVec3, omega: DVec3) -> DVec3 {
    gamma.cross(omega)
}

/// One RK4 step of gamma' = gamma x omega with constant omega, renormalised to |gamma| = 1 (the
/// first integral).
pub fn rk4_step(gamma: DVec3, omega: DVec3, h: f64) -> DVec3 {
    let k1 = direction_cosine_rate(gamma, omega);
    let k2 = direction_cosine_rate(gamma + k1 * (0.5 * h), omega);
    let k3 = direction_cosine_rate(gamma + k2 * (0.5 * h), omega);
    let k4 = direction_cosine_rate(gamma + k3 * h, omega);
    (gamma + (k1 + k2 * 2.0 + k3 * 2.0 + k4) * (h / 6.0)).normalize()
}

/// RK4 steps per unit of the slice parameter in [`integrate_angular_velocity`].
pub const RK4_STEPS: usize = 64;

/// The frame reached from `m0` after a unit of the slice parameter with constant angular velocity
/// `omega` (moving-frame components, radians per unit). The direction cosines of the fixed x and y
/// axes (the first two columns of M^T) are integrated with RK4 and renormalised; the third column
/// follows as their cross product after re-orthogonalisation (two orthonormal rows of a rotation
/// determine the third).
pub fn integrate_angular_velocity(m0: &DMat3, omega: DVec3, steps: usize) -> DMat3 {
    let mt = m0.transpose();
    let (mut g1, mut g2) = (mt.x_axis, mt.y_axis);
    let h = 1.0 / steps as f64;
    for _ in 0..steps {
        g1 = rk4_step(g1, omega, h);
        g2 = rk4_step(g2, omega, h);
        g2 = (g2 - g1 * g1.dot(g2)).normalize();
    }
    DMat3::from_cols(g1, g2, g1.cross(g2)).transpose()
}

/// The orthonormal frame (u, v, u x v) from two in-plane axes as given (u normalised, v made
/// orthogonal to it); None when they are degenerate.
pub fn frame_from_axes(u: DVec3, v: DVec3) -> Option<DMat3> {
    let lu = u.length();
    if !(lu > 0.0) || !lu.is_finite() {
        return None;
    }
    let u = u / lu;
    let v = v - u * u.dot(v);
    let lv = v.length();
    if !(lv > 1e-9 * (1.0 + u.length())) || !lv.is_finite() {
        return None;
    }
    let v = v / lv;
    Some(DMat3::from_cols(u, v, u.cross(v)))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn max_diff(a: &DMat3, b: &DMat3) -> f64 {
        (0..3)
            .flat_map(|c| (0..3).map(move |r| (c, r)))
            .map(|(c, r)| (a.col(c)[r] - b.col(c)[r]).abs())
            .fold(0.0, f64::max)
    }

    fn some_frame(a: f64) -> DMat3 {
        rotation_exp(DVec3::new(0.3 * a, -0.7, 0.2 + a))
    }

    #[test]
    fn log_and_exp_are_inverse() {
        for a in [0.0, 1e-12, 0.4, 1.3, 2.9] {
            let m = some_frame(a);
            assert!(max_diff(&rotation_exp(rotation_log(&m)), &m) < 1e-14, "{a}");
        }
        let r = DVec3::new(1e-10, 0.0, -2e-10);
        assert!((rotation_log(&rotation_exp(r)) - r).length() < 1e-22);
    }

    #[test]
    fn interpolation_reproduces_the_section_frames() {
        let pair = FramePair::new(some_frame(0.1), some_frame(0.9));
        for o in [Orient::Log, Orient::Slerp] {
            assert!(max_diff(&pair.at(0.0, o), &pair.m0) < 1e-14);
            assert!(max_diff(&pair.at(1.0, o), &pair.m1) < 1e-14);
            let m = pair.at(0.37, o);
            assert!(max_diff(&(m.transpose() * m), &DMat3::IDENTITY) < 1e-14);
            assert!((m.determinant() - 1.0).abs() < 1e-14);
        }
    }

    #[test]
    fn log_and_slerp_agree_about_a_fixed_axis() {
        // rotations about one fixed axis commute, so the Lie-algebra average is the geodesic
        let axis = DVec3::new(1.0, 2.0, -0.5).normalize();
        let pair = FramePair::new(rotation_exp(axis * 0.3), rotation_exp(axis * 1.9));
        for t in [0.1, 0.5, 0.8] {
            let (a, b) = (pair.at(t, Orient::Log), pair.at(t, Orient::Slerp));
            assert!(max_diff(&a, &b) < 1e-14, "t = {t}");
            assert!(max_diff(&a, &rotation_exp(axis * (0.3 + 1.6 * t))) < 1e-14);
        }
        // and for frames that do not commute they differ (the two methods are really different)
        let pair =
            FramePair::new(rotation_exp(DVec3::new(1.2, 0.3, 0.0)), rotation_exp(DVec3::new(0.0, 1.4, 0.9)));
        assert!(max_diff(&pair.at(0.5, Orient::Log), &pair.at(0.5, Orient::Slerp)) > 1e-3);
    }

    #[test]
    fn rk4_keeps_the_first_integral_and_matches_the_exact_rotation() {
        let m0 = some_frame(0.5);
        let omega = DVec3::new(0.4, -0.9, 0.6);
        let m1 = integrate_angular_velocity(&m0, omega, RK4_STEPS);
        // constant body angular velocity: M(1) = M0 exp([omega]x)
        let exact = m0 * rotation_exp(omega);
        let e1 = max_diff(&m1, &exact);
        let e4 = max_diff(&integrate_angular_velocity(&m0, omega, 4 * RK4_STEPS), &exact);
        // fourth order: four times the steps, about 256 times smaller error (measured 6.9e-10)
        assert!(e1 < 2e-9 && e4 < e1 / 100.0, "{e1} {e4}");
        // |gamma| = 1 along the way, without renormalisation the raw RK4 step drifts from it
        let mut g = m0.transpose().x_axis;
        let mut drift = 0.0f64;
        for _ in 0..1000 {
            let raw = {
                let k = |x: DVec3| direction_cosine_rate(x, omega * 20.0);
                let h = 0.05;
                let (k1, k2) = (k(g), k(g + k(g) * (0.5 * h)));
                let k3 = k(g + k2 * (0.5 * h));
                let k4 = k(g + k3 * h);
                g + (k1 + k2 * 2.0 + k3 * 2.0 + k4) * (h / 6.0)
            };
            drift = drift.max((raw.length() - 1.0).abs());
            g = rk4_step(g, omega * 20.0, 0.05);
            assert!((g.length() - 1.0).abs() < 1e-15);
        }
        assert!(drift > 1e-9, "RK4 alone should not conserve |gamma| exactly ({drift})");
        // between two frames made by a constant omega, slerp is the integrated motion itself
        let pair = FramePair::new(m0, m1);
        for t in [0.25, 0.6] {
            let d = max_diff(&pair.at(t, Orient::Slerp), &(m0 * rotation_exp(omega * t)));
            assert!(d < 2e-9, "t = {t}: {d}");
        }
        // the third component of gamma x omega: gamma3' + w1 gamma2 - w2 gamma1 = 0
        let (gm, w) = (DVec3::new(0.2, 0.3, 0.9), DVec3::new(1.0, 2.0, 3.0));
        let r = direction_cosine_rate(gm, w);
        assert!((r.z + w.x * gm.y - w.y * gm.x).abs() < 1e-15);
        assert!((r.x + w.y * gm.z - w.z * gm.y).abs() < 1e-15);
    }
}
