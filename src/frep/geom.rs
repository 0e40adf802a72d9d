//! Boxes and rotations for the expressions of [`crate::frep::expr`]: the boxes of carriers and of
//! transformed solids, and the rotation matrix of an axis and an angle.

use glam::DVec3;

use crate::spline::carrier::ellipsoid_axis;
use crate::spline::Carrier;

/// A box (lo, hi).
pub type Box3 = ([f64; 3], [f64; 3]);

/// The box of a resolved carrier's solid.
pub(crate) fn carrier_box(c: &Carrier) -> Box3 {
    let around = |centre: &[f64], r: &dyn Fn(usize) -> f64| {
        ([0, 1, 2].map(|d| centre[d] - r(d)), [0, 1, 2].map(|d| centre[d] + r(d)))
    };
    match c {
        Carrier::AutoBall | Carrier::AutoEllipsoid { .. } => ([-1.0; 3], [1.0; 3]),
        Carrier::Ball { centre, radius } => around(centre, &|_| *radius),
        // the half-extent along coordinate d of an ellipsoid: sqrt(sum_j (a_j u_j[d])^2)
        Carrier::Ellipsoid { centre, semi_axes, axes } => around(centre, &|d| {
            let n = semi_axes.len();
            (0..n)
                .map(|j| (semi_axes[j] * ellipsoid_axis(axes.as_deref(), n, j, d)).powi(2))
                .sum::<f64>()
                .sqrt()
        }),
        Carrier::Union(a, b) => hull(carrier_box(a), carrier_box(b)),
        Carrier::Intersection(a, b) => {
            let m = meet(carrier_box(a), carrier_box(b));
            if (0..3).all(|d| m.0[d] <= m.1[d]) {
                m
            } else {
                carrier_box(a)
            }
        }
        Carrier::Difference(a, _) => carrier_box(a),
    }
}

pub fn hull(a: Box3, b: Box3) -> Box3 {
    ([0, 1, 2].map(|d| a.0[d].min(b.0[d])), [0, 1, 2].map(|d| a.1[d].max(b.1[d])))
}

pub(crate) fn meet(a: Box3, b: Box3) -> Box3 {
    ([0, 1, 2].map(|d| a.0[d].max(b.0[d])), [0, 1, 2].map(|d| a.1[d].min(b.1[d])))
}

pub(crate) fn corners((lo, hi): Box3) -> Vec<[f64; 3]> {
    (0..8).map(|c| [0, 1, 2].map(|d| if c >> d & 1 == 0 { lo[d] } else { hi[d] })).collect()
}

pub(crate) fn add(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

pub(crate) fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

/// The rotation by `degrees` about the unit `axis` (Rodrigues' formula), row-major.
pub fn rotation(axis: [f64; 3], degrees: f64) -> [[f64; 3]; 3] {
    let (s, c) = degrees.to_radians().sin_cos();
    let k = DVec3::from_array(axis);
    let mut r = [[0.0; 3]; 3];
    for (i, row) in r.iter_mut().enumerate() {
        for (j, v) in row.iter_mut().enumerate() {
            let cross = match (i, j) {
                (0, 1) => -k.z,
                (0, 2) => k.y,
                (1, 0) => k.z,
                (1, 2) => -k.x,
                (2, 0) => -k.y,
                (2, 1) => k.x,
                _ => 0.0,
            };
            *v = if i == j { c } else { 0.0 } + s * cross + (1.0 - c) * axis[i] * axis[j];
        }
    }
    r
}

pub(crate) fn mul(r: &[[f64; 3]; 3], p: [f64; 3]) -> [f64; 3] {
    [0, 1, 2].map(|i| r[i][0] * p[0] + r[i][1] * p[1] + r[i][2] * p[2])
}

/// R^T p.
pub(crate) fn mul_t(r: &[[f64; 3]; 3], p: [f64; 3]) -> [f64; 3] {
    [0, 1, 2].map(|i| r[0][i] * p[0] + r[1][i] * p[1] + r[2][i] * p[2])
}

/// The box grown by a tenth of its size on every side (as [`crate::frep::Implicit::bounds`] of a model).
pub fn widened((lo, hi): Box3) -> Box3 {
    let pad = [0, 1, 2].map(|d| 0.1 * (hi[d] - lo[d]).abs().max(f64::MIN_POSITIVE));
    ([0, 1, 2].map(|d| lo[d] - pad[d]), [0, 1, 2].map(|d| hi[d] + pad[d]))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_rotation_turns_about_its_axis_by_its_angle() {
        let r = rotation([0.0, 0.0, 1.0], 90.0);
        let p = mul(&r, [1.0, 0.0, 0.5]);
        assert!((p[0]).abs() < 1e-15 && (p[1] - 1.0).abs() < 1e-15 && (p[2] - 0.5).abs() < 1e-15, "{p:?}");
        let q = mul_t(&r, p);
        assert!((q[0] - 1.0).abs() < 1e-15 && q[1].abs() < 1e-15, "{q:?}");
        let b = carrier_box(&Carrier::parse("union(ball:0,0,0,1,ellipsoid:3,0,0,1,2,3)", 3).unwrap());
        assert_eq!(b, ([-1.0, -2.0, -3.0], [4.0, 2.0, 3.0]));
    }

    #[test]
    fn a_turned_ellipsoid_lies_in_its_box() {
        // semi-axes 2 and 1 along the diagonals of the xy plane, 0.5 along z
        let h = std::f64::consts::FRAC_1_SQRT_2;
        let spec = format!("ellipsoid:1,0,0,2,1,0.5,{h},{h},0,{},{h},0,0,0,1", -h);
        let c = Carrier::parse(&spec, 3).unwrap();
        let (lo, hi) = carrier_box(&c);
        let half = (2.5f64).sqrt(); // sqrt((2 h)^2 + (1 h)^2)
        for (d, want) in [half, half, 0.5].into_iter().enumerate() {
            assert!((hi[d] - lo[d] - 2.0 * want).abs() < 1e-12, "{d}: {lo:?} {hi:?}");
        }
        // the box is tight: the ellipsoid's extreme point along x lies on it
        let u = [2.0 * h, 2.0 * h, 0.0];
        let v = [-h, h, 0.0];
        let n = (u[0] * u[0] + v[0] * v[0]).sqrt();
        let p = [1.0 + (u[0] * u[0] + v[0] * v[0]) / n, (u[0] * u[1] + v[0] * v[1]) / n, 0.0];
        assert!(c.eval(&p).abs() < 1e-12 && (p[0] - hi[0]).abs() < 1e-12, "{p:?} {}", c.eval(&p));
    }
}
