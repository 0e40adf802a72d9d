//! Reconstruction from planar cross-sections (paper 000, section 4; math.md section 3).
//!
//! This module owns the contour model: each slice i is a plane (origin o_i, frame M_i with columns
//! u, v and normal w) holding a two-dimensional section function F_i(a, b) = f_c,i - U_i (a volume
//! spline in the plane's coordinates, [`slice2d`]), and the solid between slices is
//! F(x) = sum_j w_j(t) F_j(a, b), where the point x lies between planes i and i+1 at
//! t = d1 / (d1 + d2) (its distances to them), (a, b, c) = M(t)^T (x - o(t)) with
//! o(t) = (1 - t) o_i + t o_(i+1) and M(t) from [`orientation`] (log/exp or slerp), and the weights
//! w_j are linear or cardinal cubic ([`interp`]) on knots spaced by the distance between planes.
//! For parallel slices z = z_i this is exactly the paper's F = (1 - g) F_i + g F_(i+1).
//!
//! The solid is closed beyond the first and last slices by the R-intersection with the half-spaces
//! in front of the first plane and behind the last. Every point is classified by the signs of its
//! distances to the planes: it is between i and i+1 when it is in front of plane i and not in
//! front of plane i+1; when several such pairs exist (planes of a bent family cross far from the
//! data), the pair whose interpolated origin o(t) is nearest wins.
//!
//! The file format is in [`format`]; the collective command in [`pipeline`]. It must not touch
//! MPI directly (only through `dist::Comm`).

pub mod format;
pub mod interp;
pub mod orientation;
pub mod pipeline;
pub mod slice2d;

use glam::{DMat3, DVec3};
use rayon::prelude::*;

use crate::carrier::{r_intersection, Carrier};
use crate::grid::Grid;
use crate::model::{Field, Provenance};
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
                self.blend.weights(i, t, weights);
                let mut f: f64 = weights.iter().map(|&(j, w)| w * s[j].eval(ab)).sum();
                if i == 0 {
                    f = r_intersection(f, self.cap_scale * s[0].signed_distance(x));
                }
                if i + 1 == last {
                    f = r_intersection(f, -self.cap_scale * s[last].signed_distance(x));
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
        }
    }
}
