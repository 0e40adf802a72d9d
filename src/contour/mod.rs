//! Reconstruction from planar cross-sections, after section 4 of Savchenko, Pasko, Okunev and Kunii
//! (1995): every slice gets its own two-dimensional solid, and the solid between slices is
//! interpolated from theirs.
//!
//! # Sections
//!
//! Slice i is a plane with origin o_i and frame M_i, a rotation whose columns are the in-plane
//! axes u, v and the normal w = u x v; a point of the plane is o_i + a u + b v. Its contours give
//! points (a, b), and [`slice2d`] fits a 2D volume spline U_i through all of them (kernel
//! r^2 ln r, polynomials 1, a, b by default) to the values of a 2D carrier f_c,i (a disc, or a
//! union of discs), exactly as in 3D:
//!
//! ```text
//! F_i(a, b) = f_c,i(a, b) - U_i(a, b)       F_i >= 0 inside the section's contours, = 0 on them.
//! ```
//!
//! Several contours in one slice are simply more points of the same system, so branching needs no
//! correspondence between the contours of neighbouring slices.
//!
//! # Between parallel slices
//!
//! For parallel slices z = z_i the solid is the homotopy between neighbouring sections,
//!
//! ```text
//! F(x, y, z) = (1 - t) F_i(x, y) + t F_(i+1)(x, y),      t = (z - z_i) / (z_(i+1) - z_i).
//! ```
//!
//! On plane i, F = F_i, so the zero set passes through the given contours. Where the insides of
//! two neighbouring sections overlap (F_i >= 0 and F_(i+1) >= 0 at the same (x, y)), the whole
//! segment between the planes is inside (a convex combination of non-negative values): the two
//! sections are joined. A contour with no overlapping partner shrinks to nothing between the
//! planes. The smoother alternative replaces the two linear weights by cardinal cubic splines in
//! the slice parameter ([`interp`]): F = sum_j w_j(tau) F_j.
//!
//! # Non-parallel slices
//!
//! A point x between planes i and i+1 at distances d1 and d2 from them gets
//!
//! ```text
//! t = d1 / (d1 + d2)                                  (0 on plane i, 1 on plane i+1)
//! o(t) = (1 - t) o_i + t o_(i+1),    M(t) interpolated between M_i and M_(i+1)
//! (a, b, c) = M(t)^T (x - o(t))                        (c, the offset along the normal, is dropped)
//! F(x) = sum_j w_j F_j(a, b)                           (weights w_j of interval i at t)
//! ```
//!
//! with M(t) by log/exp or slerp ([`orientation`]) and the weights linear or cubic ([`interp`];
//! the monotone interpolation there is a cubic in t through F_i(a, b) and F_(i+1)(a, b) whose
//! slopes depend on the values of the slices around, not a weighted sum),
//! on knots spaced by the distances between the planes ([`knots_of`]). On plane i, t = 0,
//! o(0) = o_i and M(0) = M_i, so F = F_i again (on the inner planes; the end planes are capped,
//! below); for parallel slices M(t) = M_i and t is the fraction of the way in z, which is the
//! formula above. Every point is classified by the
//! signs of its distances to the planes: it is between i and i+1 when it is in front of plane i
//! and not in front of plane i+1; when several such pairs exist (the planes of a bent family cross
//! far from the data), the pair whose interpolated origin o(t) is nearest wins.
//!
//! # Closing the ends
//!
//! Beyond the first plane F_0 alone would continue the first section as an infinite prism. The
//! solid is closed by the R-intersection (see [`crate::spline::carrier`]) with the half-space in
//! front of the first plane, and likewise behind the last:
//!
//! ```text
//! F(x) = F_0(a, b) & (kappa s_0(x))        behind the first plane (s_0 < 0, so F < 0)
//! ```
//!
//! where s_0 is the signed distance to the first plane (positive in front) and kappa the diagonal
//! of the data's box, which turns a length into the units of F (a length squared). So that F stays
//! continuous where the end intervals meet the next ones, the cap also acts inside the end
//! intervals with the half-space value divided by 1 - t (first interval) or t (last interval): it
//! grows without bound towards the inner plane, where f & c tends to f. On the end planes
//! themselves the cap value is 0 and f & 0 = f - |f|: F = 0 over the inside of the end contours
//! (the solid's flat end faces) and 2 F_0 < 0 outside them. (Inside the end intervals the
//! R-intersection is computed as f - f^2 / (c + sqrt(f^2 + c^2)), the same value without the
//! cancellation of f + c - sqrt(f^2 + c^2) for large c.)
//!
//! The file format is in [`format`](mod@format), the plane families and mesh cutting of `volspline slice` in
//! [`planes`]. Nothing here communicates: the commands that distribute the work are in `app`.

pub mod crossing;
pub mod format;
pub mod interp;
pub mod orientation;
pub mod planes;
pub mod slice2d;

use glam::{DMat3, DVec3};
use rayon::prelude::*;

use crate::grid::Grid;
use crate::spline::carrier::{r_intersection, Carrier};
use crate::spline::model::{Field, Provenance};
use crate::spline::Spline;

pub use format::Section;
pub use interp::{Blend, Interp};
pub use orientation::{FramePair, Orient};
pub use slice2d::{fit_section, fit_values, SectionCarrier, SectionFit};

/// One solved slice: its plane and F_i = f_c,i - U_i in the plane's coordinates.
#[derive(Debug, Clone, PartialEq)]
pub struct SectionModel {
    pub origin: DVec3,
    pub frame: DMat3,
    pub carrier: Carrier,
    pub spline: Spline,
}

impl SectionModel {
    /// F_i(a, b).
    #[inline]
    pub fn eval(&self, ab: [f64; 2]) -> f64 {
        self.carrier.eval(&ab) - self.spline.eval(&ab)
    }

    #[inline]
    fn signed_distance(&self, x: DVec3) -> f64 {
        self.frame.z_axis.dot(x - self.origin)
    }
}

/// Where a point is with respect to the slices.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Placement {
    /// Between slices i and i+1, at fraction t.
    Between { i: usize, t: f64 },
    /// Behind the first plane.
    BeforeFirst,
    /// In front of the last plane.
    AfterLast,
}

/// The reconstructed solid from contours, F >= 0 inside.
#[derive(Debug, Clone, PartialEq)]
pub struct ContourModel {
    pub sections: Vec<SectionModel>,
    pub interp: Interp,
    pub orient: Orient,
    pub provenance: Provenance,
    blend: Blend,
    pairs: Vec<FramePair>,
    /// Turns plane distances (lengths) into the units of F (lengths squared) for the end caps.
    cap_scale: f64,
}

/// The R-intersection of f with a cap c >= 0 in a form without cancellation for large c (it tends
/// to f as c grows, and is f for c = infinity).
#[inline]
fn fading_cap(f: f64, c: f64) -> f64 {
    if f == 0.0 {
        return 0.0;
    }
    f - f * f / (c + (f * f + c * c).sqrt())
}

/// The knots of the slice parameter: tau_0 = 0, tau_(i+1) - tau_i = the distance between planes
/// i and i+1 measured along their mean normal (z_(i+1) - z_i for parallel slices).
pub fn knots_of(planes: &[(DVec3, DMat3)]) -> Vec<f64> {
    let mut tau = vec![0.0];
    for w in planes.windows(2) {
        let gap = 0.5 * (w[0].1.z_axis + w[1].1.z_axis).dot(w[1].0 - w[0].0);
        tau.push(tau.last().copied().unwrap_or(0.0) + gap);
    }
    tau
}

impl ContourModel {
    /// Panics unless there are at least two sections ordered along their normals (the contour
    /// file reader guarantees it).
    pub fn new(sections: Vec<SectionModel>, interp: Interp, orient: Orient, provenance: Provenance) -> Self {
        let planes: Vec<(DVec3, DMat3)> = sections.iter().map(|s| (s.origin, s.frame)).collect();
        let blend = Blend::new(interp, knots_of(&planes));
        let pairs = sections.windows(2).map(|w| FramePair::new(w[0].frame, w[1].frame)).collect();
        let d = (0..3).map(|k| (provenance.box_hi[k] - provenance.box_lo[k]).powi(2)).sum::<f64>().sqrt();
        ContourModel {
            sections,
            interp,
            orient,
            provenance,
            blend,
            pairs,
            cap_scale: d.max(f64::MIN_POSITIVE),
        }
    }

    /// The knots tau_i.
    pub fn knots(&self) -> &[f64] {
        &self.blend.knots
    }

    /// Classifies x (see the module documentation).
    pub fn place(&self, x: DVec3) -> Placement {
        let s = &self.sections;
        let n = s.len();
        let mut best: Option<(f64, Placement)> = None;
        let mut consider = |d2: f64, p: Placement| {
            if best.is_none_or(|(b, _)| d2 < b) {
                best = Some((d2, p));
            }
        };
        let mut prev = s[0].signed_distance(x);
        if prev < 0.0 {
            consider((x - s[0].origin).length_squared(), Placement::BeforeFirst);
        }
        for i in 0..n - 1 {
            let next = s[i + 1].signed_distance(x);
            if prev >= 0.0 && next <= 0.0 && prev - next > 0.0 {
                let t = prev / (prev - next);
                let o = s[i].origin * (1.0 - t) + s[i + 1].origin * t;
                consider((x - o).length_squared(), Placement::Between { i, t });
            }
            prev = next;
        }
        if prev > 0.0 {
            consider((x - s[n - 1].origin).length_squared(), Placement::AfterLast);
        }
        best.map_or(Placement::BeforeFirst, |b| b.1)
    }

    /// The interpolated section frame and origin at fraction t of interval i.
    pub fn frame_at(&self, i: usize, t: f64) -> (DVec3, DMat3) {
        let o = self.sections[i].origin * (1.0 - t) + self.sections[i + 1].origin * t;
        (o, self.pairs[i].at(t, self.orient))
    }

    /// F(x), reusing `weights` as scratch.
    pub fn eval_with(&self, x: DVec3, weights: &mut Vec<(usize, f64)>) -> f64 {
        let s = &self.sections;
        let last = s.len() - 1;
        let local = |o: DVec3, m: &DMat3| {
            let l = m.transpose() * (x - o);
            [l.x, l.y]
        };
        match self.place(x) {
            Placement::Between { i, t } => {
                let (o, m) = self.frame_at(i, t);
                let ab = local(o, &m);
                let mut f = self.blend.value(i, t, weights, |j| s[j].eval(ab));
                // the end caps fade out across the end intervals (1 / (1 - t) and 1 / t), so that F
                // is continuous where the next interval begins
                if i == 0 {
                    f = fading_cap(f, self.cap_scale * s[0].signed_distance(x) / (1.0 - t));
                }
                if i + 1 == last {
                    f = fading_cap(f, -self.cap_scale * s[last].signed_distance(x) / t);
                }
                f
            }
            Placement::BeforeFirst => {
                let f = s[0].eval(local(s[0].origin, &s[0].frame));
                r_intersection(f, self.cap_scale * s[0].signed_distance(x))
            }
            Placement::AfterLast => {
                let f = s[last].eval(local(s[last].origin, &s[last].frame));
                r_intersection(f, -self.cap_scale * s[last].signed_distance(x))
            }
        }
    }

    /// F at a point.
    pub fn eval(&self, x: [f64; 3]) -> f64 {
        self.eval_with(DVec3::from_array(x), &mut Vec::new())
    }

    /// Total number of spline centres over all sections.
    pub fn centres(&self) -> usize {
        self.sections.iter().map(|s| s.spline.len()).sum()
    }
}

impl Field for ContourModel {
    /// Threaded over rows of nodes; a node's value depends on its position only.
    fn eval_layers(&self, grid: &Grid, k0: usize, layers: usize) -> Vec<f64> {
        let [nx, ny, _] = grid.dims;
        let mut out = vec![0.0; nx * ny * layers];
        out.par_chunks_mut(nx.max(1)).enumerate().for_each(|(row, vals)| {
            let (j, k) = (row % ny, k0 + row / ny);
            let mut scratch = Vec::new();
            for (i, v) in vals.iter_mut().enumerate() {
                *v = self.eval_with(DVec3::from_array(grid.node(i, j, k)), &mut scratch);
            }
        });
        out
    }

    fn kernel_evals_per_node(&self) -> usize {
        let mean = self.centres() / self.sections.len().max(1);
        match self.interp {
            Interp::Linear => 2 * mean,
            // about fourteen neighbours on either side keep a weight above the cut-off
            Interp::Cubic => self.sections.len().min(29) * mean,
            Interp::Monotone => self.sections.len().min(4) * mean,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::spline::kernel::Kernel;

    fn circle(r: f64, n: usize) -> Vec<[f64; 2]> {
        (0..n)
            .map(|k| {
                let a = std::f64::consts::TAU * k as f64 / n as f64;
                [r * a.cos(), r * a.sin()]
            })
            .collect()
    }

    fn stack(zs: &[f64], radii: &[f64], interp: Interp) -> ContourModel {
        let k = Kernel::new(2, 2).unwrap();
        let sections = zs
            .iter()
            .zip(radii)
            .map(|(&z, &r)| {
                let s = Section {
                    line: 0,
                    origin: DVec3::new(0.0, 0.0, z),
                    frame: DMat3::IDENTITY,
                    kind: "z",
                    contours: vec![circle(r, 24)],
                };
                let f = fit_section(&s, &k, SectionCarrier::Disc, 1e-6).unwrap();
                SectionModel { origin: s.origin, frame: s.frame, carrier: f.carrier, spline: f.spline }
            })
            .collect();
        let prov = Provenance {
            box_lo: [-1.0, -1.0, zs[0]],
            box_hi: [1.0, 1.0, zs[zs.len() - 1]],
            ..Default::default()
        };
        ContourModel::new(sections, interp, Orient::Slerp, prov)
    }

    #[test]
    fn parallel_slices_follow_the_linear_formula() {
        let m = stack(&[0.0, 1.0, 3.0, 4.0], &[0.5, 0.8, 0.6, 0.4], Interp::Linear);
        assert_eq!(m.knots(), &[0.0, 1.0, 3.0, 4.0]);
        for (x, y, z) in [(0.1, 0.2, 1.5), (0.7, -0.3, 2.9), (-0.2, 0.0, 1.0 + 1e-12)] {
            let g = (z - 1.0) / 2.0;
            assert_eq!(m.place(DVec3::new(x, y, z)), Placement::Between { i: 1, t: g });
            let linear = (1.0 - g) * m.sections[1].eval([x, y]) + g * m.sections[2].eval([x, y]);
            assert!((m.eval([x, y, z]) - linear).abs() < 1e-14 * (1.0 + linear.abs()), "{z}");
        }
        // in a slice's plane F is F_i, reached from either side: the zero set is the contour
        assert!(m.eval([0.8, 0.0, 1.0]).abs() < 1e-9);
        for z in [1.0, 3.0] {
            let i = if z == 1.0 { 1 } else { 2 };
            for p in [[0.2, 0.1, z], [0.0, 0.0, z], [0.9, 0.0, z]] {
                let exact = m.sections[i].eval([p[0], p[1]]);
                assert!((m.eval(p) - exact).abs() < 1e-13 * (1.0 + exact.abs()), "{p:?}");
                let below = m.eval([p[0], p[1], z - 1e-9]);
                assert!((below - exact).abs() < 1e-6 * (1.0 + exact.abs()), "{p:?}: continuous");
            }
        }
        // closed beyond the ends, open between them
        assert_eq!(m.place(DVec3::new(0.0, 0.0, -0.1)), Placement::BeforeFirst);
        assert_eq!(m.place(DVec3::new(0.0, 0.0, 4.1)), Placement::AfterLast);
        assert!(m.eval([0.0, 0.0, -0.01]) < 0.0 && m.eval([0.0, 0.0, 0.01]) > 0.0);
        assert!(m.eval([0.0, 0.0, 4.01]) < 0.0 && m.eval([0.0, 0.0, 3.99]) > 0.0);
        // continuous through the cap: F = 0 on the first plane inside the contour
        assert!(m.eval([0.0, 0.0, -1e-9]).abs() < 1e-7 && m.eval([0.0, 0.0, 1e-9]).abs() < 1e-7);
    }

    #[test]
    fn the_contour_points_named_for_the_ray_caster_lie_on_the_surface() {
        use crate::frep::Implicit;
        let (zs, radii) = ([0.0, 1.0, 3.0, 4.0], [0.5, 0.8, 0.6, 0.4]);
        let m = stack(&zs, &radii, Interp::Linear);
        let points = m.surface_points();
        assert_eq!(points.len(), 4 * 24);
        for (k, p) in points.iter().enumerate() {
            let (z, r) = (zs[k / 24], radii[k / 24]);
            assert!(
                (p[2] - z).abs() < 1e-15 && ((p[0] * p[0] + p[1] * p[1]).sqrt() - r).abs() < 1e-14,
                "{p:?}"
            );
            assert!(m.eval(*p).abs() < 1e-9, "{p:?}: f = {}", m.eval(*p));
        }
    }

    #[test]
    fn cubic_blend_agrees_with_linear_at_the_slices() {
        let lin = stack(&[0.0, 1.0, 2.0, 3.5, 4.0], &[0.5, 0.8, 0.6, 0.7, 0.4], Interp::Linear);
        let cub = stack(&[0.0, 1.0, 2.0, 3.5, 4.0], &[0.5, 0.8, 0.6, 0.7, 0.4], Interp::Cubic);
        for z in [1.0, 2.0, 3.5] {
            let p = [0.3, -0.1, z];
            assert!((lin.eval(p) - cub.eval(p)).abs() < 1e-12, "{z}");
        }
        let p = [0.3, -0.1, 2.7];
        assert!((lin.eval(p) - cub.eval(p)).abs() > 1e-4);
    }
}
