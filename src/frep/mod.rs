//! Reconstructed solids as first-class function-representation (FRep) objects: anything with a
//! defining function f(x) >= 0 inside that can be evaluated at a point, differentiated, and
//! bounded in space. Models read from files, carriers and expressions over them all implement
//! [`Implicit`]; rendering, curvature and set operations are written against it alone.
//!
//! Must not touch ranks or files: callers distribute the points they evaluate.

pub mod curvature;
pub mod expr;
pub mod geom;
pub mod morph;
pub mod parse;
pub mod raycast;

pub use expr::Expr;
pub use parse::Syntax;

use rayon::prelude::*;

use crate::contour::ContourModel;
use crate::grid::Grid;
use crate::spline::derivatives::model_jet;
use crate::spline::point_eval::PointEvaluator;
use crate::spline::{Model, Provenance};

/// Step of the central differences of the default derivatives, relative to the size of the
/// solid's box (small enough for second-order accuracy, large enough to stay above rounding).
pub(crate) const DIFF_STEP: f64 = 1e-5;

/// `f.value` at every node of the layers of `grid` from layer k0 (x fastest), threaded over rows:
/// the grid evaluation of a solid without a faster one of its own.
pub(crate) fn pointwise<F: Implicit + ?Sized>(f: &F, grid: &Grid, k0: usize, layers: usize) -> Vec<f64> {
    let [nx, ny, _] = grid.dims;
    let mut out = vec![0.0; nx * ny * layers];
    out.par_chunks_mut(nx.max(1)).enumerate().for_each(|(row, vals)| {
        let (j, k) = (row % ny, k0 + row / ny);
        for (i, v) in vals.iter_mut().enumerate() {
            *v = f.value(grid.node(i, j, k));
        }
    });
    out
}

/// A solid f(x) >= 0 inside, f = 0 on its surface, f < 0 outside, in the caller's coordinates.
pub trait Implicit: Sync {
    /// f at a point.
    fn value(&self, p: [f64; 3]) -> f64;

    /// A box (lo, hi) that contains the solid and the region where its surface is meant to be
    /// looked at (for a reconstructed model: the data's box with a margin).
    fn bounds(&self) -> ([f64; 3], [f64; 3]);

    /// Points on the surface f = 0, or near it, in the caller's coordinates: for a model fitted
    /// to points, its data points. The ray caster samples f on a coarse lattice to know where
    /// the surface can be, and a part thinner than a lattice cell can fall between its nodes
    /// unseen; it looks closely around these points wherever they lie in a cell the lattice
    /// sees no surface in ([`raycast`]). None by default.
    fn surface_points(&self) -> Vec<[f64; 3]> {
        Vec::new()
    }

    /// grad f at a point. The default takes central differences of [`Implicit::value`] with a
    /// step relative to [`Implicit::bounds`]; implementations with analytic derivatives override it.
    fn gradient(&self, p: [f64; 3]) -> [f64; 3] {
        let h = diff_step(self);
        let mut g = [0.0; 3];
        for (d, gd) in g.iter_mut().enumerate() {
            let (mut a, mut b) = (p, p);
            a[d] += h;
            b[d] -= h;
            *gd = (self.value(a) - self.value(b)) / (2.0 * h);
        }
        g
    }

    /// The Hessian of f at a point, row-major. The default takes central differences of
    /// [`Implicit::gradient`].
    fn hessian(&self, p: [f64; 3]) -> [[f64; 3]; 3] {
        let h = diff_step(self);
        let mut m = [[0.0; 3]; 3];
        for d in 0..3 {
            let (mut a, mut b) = (p, p);
            a[d] += h;
            b[d] -= h;
            let (ga, gb) = (self.gradient(a), self.gradient(b));
            for e in 0..3 {
                m[e][d] = (ga[e] - gb[e]) / (2.0 * h);
            }
        }
        // symmetrise: the differences of the two orders agree only to the step's accuracy
        for d in 0..3 {
            for e in 0..d {
                let s = 0.5 * (m[d][e] + m[e][d]);
                m[d][e] = s;
                m[e][d] = s;
            }
        }
        m
    }
}

/// A solid seen in its coordinates divided by `unit`, a power of two near the largest magnitude
/// of its box's corners: y = x / unit. What squares coordinates (a camera's distance, the length
/// of a ray, |grad f|) then stays representable at any scale of the data, and since scaling by a
/// power of two is exact, every value, root and direction is the unscaled solid's, scaled: a
/// picture of a solid at unit scale is the same, pixel for pixel, through this view or without.
pub struct Rescaled<'a> {
    pub solid: &'a dyn Implicit,
    pub unit: f64,
}

impl<'a> Rescaled<'a> {
    /// `solid` in the unit of its box `bounds` (1 where the box has no finite, non-zero corner).
    pub fn of(solid: &'a dyn Implicit, bounds: ([f64; 3], [f64; 3])) -> Rescaled<'a> {
        let big = bounds.0.iter().chain(&bounds.1).fold(0.0f64, |m, v| m.max(v.abs()));
        let unit = if big.is_normal() { 2f64.powi(big.log2().floor() as i32) } else { 1.0 };
        Rescaled { solid, unit }
    }

    fn outer(&self, y: [f64; 3]) -> [f64; 3] {
        y.map(|v| v * self.unit)
    }
}

impl Implicit for Rescaled<'_> {
    fn value(&self, y: [f64; 3]) -> f64 {
        self.solid.value(self.outer(y))
    }

    fn bounds(&self) -> ([f64; 3], [f64; 3]) {
        let (lo, hi) = self.solid.bounds();
        (lo.map(|v| v / self.unit), hi.map(|v| v / self.unit))
    }

    fn surface_points(&self) -> Vec<[f64; 3]> {
        self.solid.surface_points().into_iter().map(|p| p.map(|v| v / self.unit)).collect()
    }

    fn gradient(&self, y: [f64; 3]) -> [f64; 3] {
        self.solid.gradient(self.outer(y)).map(|g| g * self.unit)
    }

    fn hessian(&self, y: [f64; 3]) -> [[f64; 3]; 3] {
        self.solid.hessian(self.outer(y)).map(|row| row.map(|h| h * self.unit * self.unit))
    }
}

fn diff_step<S: Implicit + ?Sized>(s: &S) -> f64 {
    let (lo, hi) = s.bounds();
    let size = (0..3).map(|d| (hi[d] - lo[d]).abs()).fold(0.0, f64::max);
    DIFF_STEP * if size > 0.0 { size } else { 1.0 }
}

/// The data's bounding box widened by a tenth of its size on every side.
fn padded_data_box(p: &Provenance) -> ([f64; 3], [f64; 3]) {
    let (lo, hi) = (p.box_lo, p.box_hi);
    let pad: [f64; 3] = std::array::from_fn(|d| 0.1 * (hi[d] - lo[d]).abs().max(f64::MIN_POSITIVE));
    (std::array::from_fn(|d| lo[d] - pad[d]), std::array::from_fn(|d| hi[d] + pad[d]))
}

/// The data points `model` records, as points (none where it records none).
fn model_points(model: &Model) -> Vec<[f64; 3]> {
    let points = model.data_points().unwrap_or_default();
    points.chunks_exact(3).map(|p| [p[0], p[1], p[2]]).collect()
}

/// The plain sums over all centres: every kernel, but N terms per point whatever the kernel; see
/// [`ModelSolid`] for a model prepared for many points.
impl Implicit for Model {
    fn value(&self, p: [f64; 3]) -> f64 {
        self.eval(&p)
    }

    /// The data's bounding box widened by a tenth of its size on every side.
    fn bounds(&self) -> ([f64; 3], [f64; 3]) {
        padded_data_box(&self.provenance)
    }

    /// The data points the model records.
    fn surface_points(&self) -> Vec<[f64; 3]> {
        model_points(self)
    }

    /// Analytic: carrier, kernels, polynomials and normalisation differentiated term by term
    /// ([`crate::spline::derivatives`]).
    fn gradient(&self, p: [f64; 3]) -> [f64; 3] {
        model_jet(self, &p).gradient
    }

    /// Analytic, as the gradient.
    fn hessian(&self, p: [f64; 3]) -> [[f64; 3]; 3] {
        model_jet(self, &p).hessian
    }
}

/// A model prepared for evaluation at many single points ([`PointEvaluator`]): the same values
/// and derivatives as [`Model`]'s (to rounding), at the cost of a vectorised sum for the Green's
/// functions and of the support's neighbours for a Wendland kernel.
#[derive(Debug, Clone)]
pub struct ModelSolid {
    eval: PointEvaluator,
}

impl ModelSolid {
    pub fn new(model: Model) -> Self {
        ModelSolid { eval: PointEvaluator::new(model) }
    }

    pub fn model(&self) -> &Model {
        self.eval.model()
    }
}

impl Implicit for ModelSolid {
    fn value(&self, p: [f64; 3]) -> f64 {
        self.eval.value(&p)
    }

    fn bounds(&self) -> ([f64; 3], [f64; 3]) {
        padded_data_box(&self.model().provenance)
    }

    fn surface_points(&self) -> Vec<[f64; 3]> {
        model_points(self.model())
    }

    fn gradient(&self, p: [f64; 3]) -> [f64; 3] {
        self.eval.gradient(&p)
    }

    fn hessian(&self, p: [f64; 3]) -> [[f64; 3]; 3] {
        self.eval.jet(&p).hessian
    }
}

/// A solid reconstructed from contours; its derivatives are the finite-difference defaults.
impl Implicit for ContourModel {
    fn value(&self, p: [f64; 3]) -> f64 {
        self.eval(p)
    }

    /// The contours' bounding box widened by a tenth of its size on every side.
    fn bounds(&self) -> ([f64; 3], [f64; 3]) {
        padded_data_box(&self.provenance)
    }

    /// The contours' points: every section's spline interpolates zero at its contour points,
    /// which lie in the section's plane, where the solid is the section's.
    fn surface_points(&self) -> Vec<[f64; 3]> {
        self.sections
            .iter()
            .flat_map(|s| {
                let sp = &s.spline;
                sp.centres.chunks_exact(2).map(move |c| {
                    let a = sp.norm.centre[0] + sp.norm.scale * c[0];
                    let b = sp.norm.centre[1] + sp.norm.scale * c[1];
                    (s.origin + s.frame.x_axis * a + s.frame.y_axis * b).to_array()
                })
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The ball x.x <= 4 with its exact derivatives left to the defaults.
    struct Ball;
    impl Implicit for Ball {
        fn value(&self, p: [f64; 3]) -> f64 {
            4.0 - p[0] * p[0] - p[1] * p[1] - p[2] * p[2]
        }
        fn bounds(&self) -> ([f64; 3], [f64; 3]) {
            ([-2.0; 3], [2.0; 3])
        }
    }

    #[test]
    fn default_derivatives_of_a_ball_are_exact_to_the_step() {
        let p = [0.3, -0.7, 1.1];
        let g = Ball.gradient(p);
        for d in 0..3 {
            assert!((g[d] + 2.0 * p[d]).abs() < 1e-8, "{g:?}");
        }
        let h = Ball.hessian(p);
        for d in 0..3 {
            for e in 0..3 {
                let want = if d == e { -2.0 } else { 0.0 };
                assert!((h[d][e] - want).abs() < 1e-4, "{h:?}");
            }
        }
    }
}
