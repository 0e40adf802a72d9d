//! FRep expressions over reconstructed solids: model files, carriers and numbers combined by
//! R-functions, blends, offsets, rigid motions, scaling and the swap of a model's carrier. The text
//! is parsed by [`crate::frep::parse`]; [`Expr::load`] reads the files; an [`Expr`] evaluates at
//! points ([`Implicit`]) and on grid slabs ([`Field`]).
//!
//! # Making the values of different solids comparable
//!
//! The defining functions of two reconstructed solids live on unrelated scales: with a ball
//! carrier f has the units of a squared length and grows with the size of the data, with an
//! ellipsoid carrier it has no units at all. A union or an intersection does not care (the
//! R-functions keep the sign of their arguments whatever their scale), but a blend and an offset
//! do. So every *operand* of an operation is first divided by its **unit** u, the root mean square
//! of |grad f| over (up to 64 of) its data points:
//!
//! ```text
//! operand(x) = f(x) / u,        u = sqrt( mean_i |grad f(P_i)|^2 ).
//! ```
//!
//! On the surface f = 0 the signed distance to the surface is f / |grad f| to first order, and u
//! is the typical |grad f| there, so f / u is near the surface approximately the signed distance
//! in the data's length units, for any carrier and any size of the data. The blending parameters
//! a0, a1, a2 and the offset distances are therefore lengths for every model. A carrier operand
//! gets the unit of its own surface: 2r for `ball:..,r` (|grad f_c| = 2r on its sphere), the root
//! mean square of 2/a_j over the semi-axes for an ellipsoid (|grad f_c| at the tips of its axes),
//! the root mean square of the two units for an R-function of carriers; a number has unit 1.
//!
//! A model standing alone is its own f (so `eval a.model.h5` writes exactly the volume of the fit),
//! and `carrier(MODEL, SPEC)` keeps the unit of MODEL, so that alone it is f' = f_c' - U. The result
//! of an operation is in length units already (unit 1).
//!
//! # The operations (f1, f2, ... the operands)
//!
//! ```text
//! union(f1, f2, ...)            R-union, folded from the left:  f1 + f2 + sqrt(f1^2 + f2^2)
//! intersection(f1, f2, ...)     R-intersection:                 f1 + f2 - sqrt(f1^2 + f2^2)
//! difference(f1, f2)            f1 & (-f2)
//! complement(f1)                -f1
//! blend_union(f1, f2, a0, a1, a2)         f1 | f2 + a0 / (1 + (f1/a1)^2 + (f2/a2)^2)
//! blend_intersection(f1, f2, a0, a1, a2)  f1 & f2 + a0 / (1 + (f1/a1)^2 + (f2/a2)^2)
//! offset(f1, d)                 f1(x) + d |grad f1(x)|
//! translate(f1, t)              f1(x - t)
//! rotate(f1, axis, angle)       f1(R^T x), R the rotation by angle about axis (through the origin)
//! scale(f1, s)                  s f1(x / s)
//! scale(f1, sx, sy, sz)         min(sx, sy, sz) f1(x1 / sx, x2 / sy, x3 / sz)
//! carrier(MODEL, SPEC)          f_c'(x) - U(x), U the model's spline, f_c' the carrier SPEC
//! ```
//!
//! The blend is that of Pasko and Savchenko (1994): the displacement a0 / (1 + ...) is largest
//! (a0) where both operands vanish, on the edge where the two surfaces meet, and falls off over
//! distances a1 and a2 from each surface; a0 > 0 adds material, a0 < 0 removes it.
//!
//! The offset moves the surface by d along its normal (outward for d > 0): its zero set is
//! f1 / |grad f1| = -d, the set where the first-order distance to the surface is d. For a ball of
//! radius R (f1 = R^2 - |x|^2) it is the sphere of radius d + sqrt(d^2 + R^2), which is
//! R + d + d^2 / (2R) up to terms of fourth order: the error is of second order in d / R. The gradient is taken by central differences with the
//! step of [`Implicit::gradient`]. `scale` multiplies by s so that a distance stays a distance; scaled
//! by different factors no factor keeps distances, and the smallest one keeps the bound that
//! matters: for g(x) = c f(S^-1 x), |grad g| <= c |grad f| / min_j s_j, so with c = min_j s_j the
//! slope of g is no steeper than that of f (a distance bound stays a bound).
//!
//! `carrier(MODEL, SPEC)` is the deformation of Savchenko et al. (1995): the spline interpolated
//! r_i = f_c(P_i) and stays as it is, so at the data points f'(P_i) = f_c'(P_i) - f_c(P_i); where
//! the new carrier differs from the old one the surface follows it.
//!
//! # Evaluation on a grid
//!
//! Translations and scalings map a regular grid to a regular grid, and the offset's central
//! differences are values on grids shifted by one step; so along every path of the tree that
//! holds only these and the pointwise operations, a model is evaluated on whole grid rows with its
//! blocked evaluator, at its own cost (an offset costs its operand's seven times). Below a rotation
//! the nodes are no longer on a grid and the operand is evaluated point by point. Either way a
//! value depends on the node's position only, as [`Field`] requires.

use std::path::Path;

use rayon::prelude::*;

use super::geom::{add, carrier_box, corners, meet, mul, mul_t, sub};
pub use super::geom::{hull, rotation, widened, Box3};
use super::parse::{Op, Syntax};
use super::{pointwise, Implicit};
use crate::contour::ContourModel;
use crate::error::{Error, Result};
use crate::grid::Grid;
use crate::io::contour_model_file::{self, read_contour_model};
use crate::io::h5::format_of;
use crate::io::model_file::read_model;
use crate::spline::carrier::{r_intersection, r_union};
use crate::spline::{Carrier, Field, Model};

/// How many data points the unit of a model is measured on.
const UNIT_SAMPLES: usize = 64;

/// A loaded expression.
#[derive(Debug, Clone)]
pub enum Expr {
    /// A model fitted to points (also one whose carrier was swapped); `domain` is its data box
    /// (and the new carrier's box after a swap).
    Model {
        model: Box<Model>,
        unit: f64,
        domain: Box3,
    },
    /// A model reconstructed from contours.
    Contour {
        model: Box<ContourModel>,
        unit: f64,
    },
    Carrier {
        carrier: Carrier,
        unit: f64,
    },
    Number(f64),
    Apply(Op, Vec<Expr>),
}

impl Expr {
    /// Reads the model files of `syntax` (on every rank that calls it).
    pub fn load(syntax: &Syntax) -> Result<Expr> {
        Ok(match syntax {
            Syntax::Number(v) => Expr::Number(*v),
            Syntax::Carrier(c) => Expr::Carrier { carrier: c.clone(), unit: carrier_unit(c) },
            Syntax::Model(path) => {
                if format_of(path).is_ok_and(|f| f == contour_model_file::FORMAT) {
                    let model = read_contour_model(path)?;
                    let unit = rms_gradient(&model, &contour_samples(&model));
                    Expr::Contour { model: Box::new(model), unit }
                } else {
                    let model = read_model(path)?;
                    let unit = rms_gradient(&model, &model_samples(&model));
                    let domain = (model.provenance.box_lo, model.provenance.box_hi);
                    Expr::Model { model: Box::new(model), unit, domain }
                }
            }
            Syntax::Swap(path, carrier) => swap(path, carrier)?,
            Syntax::Apply(op, args) => {
                Expr::Apply(op.clone(), args.iter().map(Expr::load).collect::<Result<_>>()?)
            }
        })
    }

    /// Parses and loads `text`.
    pub fn from_text(text: &str) -> Result<Expr> {
        Expr::load(&Syntax::parse(text)?)
    }

    /// The unit its values are divided by as an operand (see the module doc); 1 for operations.
    pub fn unit(&self) -> f64 {
        match self {
            Expr::Model { unit, .. } | Expr::Contour { unit, .. } | Expr::Carrier { unit, .. } => *unit,
            Expr::Number(_) | Expr::Apply(..) => 1.0,
        }
    }

    /// The value in length units: f / unit.
    pub fn operand(&self, p: [f64; 3]) -> f64 {
        self.value(p) / self.unit()
    }

    /// The box of the data the expression is made of (None for a plain number): the default grid
    /// of `eval` is this box plus its margin, as for a single model.
    pub fn domain(&self) -> Option<Box3> {
        match self {
            Expr::Model { domain, .. } => Some(*domain),
            Expr::Contour { model, .. } => Some((model.provenance.box_lo, model.provenance.box_hi)),
            Expr::Carrier { carrier, .. } => Some(carrier_box(carrier)),
            Expr::Number(_) => None,
            Expr::Apply(op, args) => {
                let first = args[0].domain();
                match op {
                    Op::Union | Op::Blend { .. } => args.iter().filter_map(Expr::domain).reduce(hull),
                    Op::Intersection => {
                        let all: Vec<Box3> = args.iter().filter_map(Expr::domain).collect();
                        all.iter()
                            .copied()
                            .reduce(meet)
                            .filter(|b| (0..3).all(|d| b.0[d] <= b.1[d]))
                            .or_else(|| all.into_iter().reduce(hull))
                    }
                    Op::Difference | Op::Complement => first,
                    Op::Offset(d) => {
                        first.map(|(lo, hi)| (lo.map(|v| v - d.max(0.0)), hi.map(|v| v + d.max(0.0))))
                    }
                    Op::Translate(t) => first.map(|(lo, hi)| (add(lo, *t), add(hi, *t))),
                    Op::Rotate { axis, degrees } => first.map(|b| {
                        let r = rotation(*axis, *degrees);
                        corners(b).into_iter().map(|c| (mul(&r, c), mul(&r, c))).reduce(hull).unwrap_or(b)
                    }),
                    Op::Scale(s) => first
                        .map(|(lo, hi)| ([0, 1, 2].map(|d| lo[d] * s[d]), [0, 1, 2].map(|d| hi[d] * s[d]))),
                }
            }
        }
    }

    /// f at a point.
    pub fn value(&self, p: [f64; 3]) -> f64 {
        match self {
            Expr::Model { model, .. } => model.eval(&p),
            Expr::Contour { model, .. } => model.eval(p),
            Expr::Carrier { carrier, .. } => carrier.eval(&p),
            Expr::Number(v) => *v,
            Expr::Apply(op, args) => match op {
                Op::Union | Op::Intersection => {
                    let vals: Vec<f64> = args.iter().map(|a| a.operand(p)).collect();
                    combine(op, &vals)
                }
                Op::Difference | Op::Blend { .. } => combine(op, &[args[0].operand(p), args[1].operand(p)]),
                Op::Complement => -args[0].operand(p),
                Op::Offset(d) => {
                    let e = &args[0];
                    let h = step(e);
                    let g: Vec<f64> = (0..3)
                        .map(|k| {
                            let (mut a, mut b) = (p, p);
                            a[k] += h;
                            b[k] -= h;
                            (e.operand(a) - e.operand(b)) / (2.0 * h)
                        })
                        .collect();
                    offset(e.operand(p), *d, [g[0], g[1], g[2]])
                }
                Op::Translate(t) => args[0].operand(sub(p, *t)),
                Op::Rotate { axis, degrees } => args[0].operand(mul_t(&rotation(*axis, *degrees), p)),
                Op::Scale(s) => min3(s) * args[0].operand([0, 1, 2].map(|d| p[d] / s[d])),
            },
        }
    }

    /// f at the nodes of layers k0..k0+layers of `grid`, x fastest (see "Evaluation on a grid").
    pub fn layers(&self, grid: &Grid, k0: usize, layers: usize) -> Vec<f64> {
        match self {
            Expr::Model { model, .. } => model.eval_layers(grid, k0, layers),
            Expr::Contour { model, .. } => model.eval_layers(grid, k0, layers),
            Expr::Number(v) => vec![*v; grid.dims[0] * grid.dims[1] * layers],
            Expr::Carrier { .. } | Expr::Apply(Op::Rotate { .. }, _) => pointwise(self, grid, k0, layers),
            Expr::Apply(op, args) => {
                let operand = |e: &Expr, g: &Grid| {
                    let mut v = e.layers(g, k0, layers);
                    let u = e.unit();
                    if u != 1.0 {
                        v.iter_mut().for_each(|x| *x /= u);
                    }
                    v
                };
                match op {
                    Op::Translate(t) => {
                        let g = Grid { origin: sub(grid.origin, *t), ..*grid };
                        operand(&args[0], &g)
                    }
                    Op::Scale(s) => {
                        let g = Grid {
                            origin: [0, 1, 2].map(|d| grid.origin[d] / s[d]),
                            spacing: [0, 1, 2].map(|d| grid.spacing[d] / s[d]),
                            ..*grid
                        };
                        let mut v = operand(&args[0], &g);
                        let c = min3(s);
                        v.iter_mut().for_each(|x| *x *= c);
                        v
                    }
                    Op::Offset(d) => {
                        let e = &args[0];
                        let h = step(e);
                        let mut v = operand(e, grid);
                        let shifted: Vec<[Vec<f64>; 2]> = (0..3)
                            .map(|k| {
                                let mut a = *grid;
                                let mut b = *grid;
                                a.origin[k] += h;
                                b.origin[k] -= h;
                                [operand(e, &a), operand(e, &b)]
                            })
                            .collect();
                        v.par_iter_mut().enumerate().for_each(|(i, x)| {
                            let g = [0, 1, 2].map(|k| (shifted[k][0][i] - shifted[k][1][i]) / (2.0 * h));
                            *x = offset(*x, *d, g);
                        });
                        v
                    }
                    Op::Complement => {
                        let mut v = operand(&args[0], grid);
                        v.iter_mut().for_each(|x| *x = -*x);
                        v
                    }
                    _ => {
                        let vals: Vec<Vec<f64>> = args.iter().map(|a| operand(a, grid)).collect();
                        let mut out = vals[0].clone();
                        out.par_iter_mut().enumerate().for_each_init(Vec::new, |row, (i, x)| {
                            row.clear();
                            row.extend(vals.iter().map(|v| v[i]));
                            *x = combine(op, row);
                        });
                        out
                    }
                }
            }
        }
    }

    /// Kernel evaluations per grid node, summed over the models (seven per offset).
    pub fn kernel_evals(&self) -> usize {
        match self {
            Expr::Model { model, .. } => model.kernel_evals_per_node(),
            Expr::Contour { model, .. } => model.kernel_evals_per_node(),
            Expr::Carrier { .. } | Expr::Number(_) => 0,
            Expr::Apply(Op::Offset(_), args) => 7 * args[0].kernel_evals(),
            Expr::Apply(_, args) => args.iter().map(Expr::kernel_evals).sum(),
        }
    }
}

/// The pointwise operations on operand values (union and intersection fold from the left).
fn combine(op: &Op, v: &[f64]) -> f64 {
    match op {
        Op::Union => v[1..].iter().fold(v[0], |a, &b| r_union(a, b)),
        Op::Intersection => v[1..].iter().fold(v[0], |a, &b| r_intersection(a, b)),
        Op::Difference => r_intersection(v[0], -v[1]),
        Op::Blend { union, a0, a1, a2 } => {
            let r = if *union { r_union(v[0], v[1]) } else { r_intersection(v[0], v[1]) };
            r + a0 / (1.0 + (v[0] / a1).powi(2) + (v[1] / a2).powi(2))
        }
        _ => unreachable!("not a pointwise operation: {op:?}"),
    }
}

/// The smallest of three factors: the value factor of a scaling (see the module doc).
fn min3(s: &[f64; 3]) -> f64 {
    s[0].min(s[1]).min(s[2])
}

fn offset(f: f64, d: f64, g: [f64; 3]) -> f64 {
    f + d * (g[0] * g[0] + g[1] * g[1] + g[2] * g[2]).sqrt()
}

/// The difference step of an operand: the step of [`Implicit::gradient`] for its box.
fn step(e: &Expr) -> f64 {
    let (lo, hi) = Implicit::bounds(e);
    let size = (0..3).map(|d| (hi[d] - lo[d]).abs()).fold(0.0, f64::max);
    super::DIFF_STEP * if size > 0.0 { size } else { 1.0 }
}

/// `carrier(MODEL, SPEC)`: the model of `path` with `carrier` (an automatic carrier fitted to its
/// data box: the ball round it, or the ellipsoid of its extents), keeping its unit.
fn swap(path: &Path, carrier: &Carrier) -> Result<Expr> {
    if format_of(path).is_ok_and(|f| f == contour_model_file::FORMAT) {
        return Err(Error::Usage(format!(
            "carrier({}, ...): the carrier of a contour model belongs to its slices; carrier() takes a model \
             fitted to points",
            path.display()
        )));
    }
    let mut model = read_model(path)?;
    let unit = rms_gradient(&model, &model_samples(&model));
    let (lo, hi) = (model.provenance.box_lo, model.provenance.box_hi);
    model.carrier = carrier.resolve(&lo, &hi, &[]);
    let domain = hull((lo, hi), carrier_box(&model.carrier));
    Ok(Expr::Model { model: Box::new(model), unit, domain })
}

/// Up to [`UNIT_SAMPLES`] of a model's data points (its spline's centres) in world coordinates.
fn model_samples(m: &Model) -> Vec<[f64; 3]> {
    let (s, n) = (&m.spline, m.spline.len());
    let stride = n.div_ceil(UNIT_SAMPLES).max(1);
    (0..n)
        .step_by(stride)
        .map(|i| [0, 1, 2].map(|d| s.norm.centre[d] + s.norm.scale * s.centres[3 * i + d]))
        .collect()
}

/// Up to [`UNIT_SAMPLES`] of a contour model's section points in world coordinates.
fn contour_samples(m: &ContourModel) -> Vec<[f64; 3]> {
    let all = m.surface_points();
    let stride = all.len().div_ceil(UNIT_SAMPLES).max(1);
    all.into_iter().step_by(stride).collect()
}

/// sqrt(mean |grad f|^2) over `points`; 1 when that is not a positive number.
fn rms_gradient(f: &dyn Implicit, points: &[[f64; 3]]) -> f64 {
    let sum: f64 = points.iter().map(|&p| f.gradient(p).iter().map(|g| g * g).sum::<f64>()).sum();
    let u = (sum / points.len().max(1) as f64).sqrt();
    if u > 0.0 && u.is_finite() {
        u
    } else {
        1.0
    }
}

/// The unit of a carrier operand: |grad f_c| on its surface (see the module doc).
fn carrier_unit(c: &Carrier) -> f64 {
    match c {
        Carrier::AutoBall | Carrier::AutoEllipsoid { .. } => 1.0,
        Carrier::Ball { radius, .. } => 2.0 * radius,
        Carrier::Ellipsoid { semi_axes, .. } => {
            (semi_axes.iter().map(|a| 4.0 / (a * a)).sum::<f64>() / semi_axes.len() as f64).sqrt()
        }
        Carrier::Union(a, b) | Carrier::Intersection(a, b) | Carrier::Difference(a, b) => {
            (0.5 * (carrier_unit(a).powi(2) + carrier_unit(b).powi(2))).sqrt()
        }
    }
}

impl Implicit for Expr {
    fn value(&self, p: [f64; 3]) -> f64 {
        Expr::value(self, p)
    }

    /// The domain widened by a tenth on every side; the cube [-1, 1]^3 for a number.
    fn bounds(&self) -> Box3 {
        self.domain().map_or(([-1.0; 3], [1.0; 3]), widened)
    }

    /// The data points of every fitted model and the contour points of every contour model in
    /// the expression, moved with them by translations, rotations and scalings (points of an
    /// operand's surface: some lie on the result's, the others only cost the ray caster a closer
    /// look).
    fn surface_points(&self) -> Vec<[f64; 3]> {
        match self {
            Expr::Model { model, .. } => model.surface_points(),
            Expr::Contour { model, .. } => model.surface_points(),
            Expr::Apply(op, args) => {
                let points = args.iter().flat_map(|a| a.surface_points());
                match op {
                    Op::Translate(t) => points.map(|p| add(p, *t)).collect(),
                    Op::Rotate { axis, degrees } => {
                        let r = rotation(*axis, *degrees);
                        points.map(|p| mul(&r, p)).collect()
                    }
                    Op::Scale(s) => points.map(|p| [0, 1, 2].map(|d| p[d] * s[d])).collect(),
                    _ => points.collect(),
                }
            }
            Expr::Carrier { .. } | Expr::Number(_) => Vec::new(),
        }
    }

    /// A model's own gradient for a model; central differences of the value otherwise.
    fn gradient(&self, p: [f64; 3]) -> [f64; 3] {
        match self {
            Expr::Model { model, .. } => model.gradient(p),
            Expr::Contour { model, .. } => model.gradient(p),
            _ => {
                let h = step(self);
                [0, 1, 2].map(|k| {
                    let (mut a, mut b) = (p, p);
                    a[k] += h;
                    b[k] -= h;
                    (self.value(a) - self.value(b)) / (2.0 * h)
                })
            }
        }
    }
}

impl Field for Expr {
    fn eval_layers(&self, grid: &Grid, k0: usize, layers: usize) -> Vec<f64> {
        self.layers(grid, k0, layers)
    }

    fn kernel_evals_per_node(&self) -> usize {
        self.kernel_evals()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn e(text: &str) -> Expr {
        Expr::from_text(text).unwrap()
    }

    #[test]
    fn operands_are_compared_in_length_units() {
        // two balls of radii 1 and 3: as operands f / (2r), so the union is the R-union of
        // (1 - |x|^2) / 2 and (9 - |x - c|^2) / 6
        let u = e("union(ball:0,0,0,1, ball:4,0,0,3)");
        for p in [[0.2f64, 0.1, 0.0], [2.0, 0.5, -0.3], [-3.0, 1.0, 1.0]] {
            let a = (1.0 - p[0] * p[0] - p[1] * p[1] - p[2] * p[2]) / 2.0;
            let b = (9.0 - (p[0] - 4.0).powi(2) - p[1] * p[1] - p[2] * p[2]) / 6.0;
            assert_eq!(u.value(p), r_union(a, b));
        }
        // near its sphere a ball operand is the signed distance to first order
        let ball = e("translate(ball:0,0,0,3, 0,0,0)");
        assert!((ball.value([3.01, 0.0, 0.0]) + 0.01).abs() < 1e-4);
        // a blend adds a0 where both surfaces meet
        let b = e("blend_union(ball:0,0,0,1, ball:1,0,0,1, 0.25, 0.5, 0.5)");
        let edge = [0.5, 0.75f64.sqrt(), 0.0];
        assert!((b.value(edge) - 0.25).abs() < 1e-12, "{}", b.value(edge));
    }

    #[test]
    fn motions_and_offsets_move_a_ball_where_they_should() {
        let radius_along_x = |x: &Expr, from: f64| {
            // bisection of f along the x axis from an inside point outwards
            let (mut lo, mut hi) = (from, from + 10.0);
            for _ in 0..100 {
                let mid = 0.5 * (lo + hi);
                if x.value([mid, 0.0, 0.0]) >= 0.0 {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            lo
        };
        let shifted = e("translate(ball:0,0,0,1, 2,0,0)");
        assert!((radius_along_x(&shifted, 2.0) - 3.0).abs() < 1e-12);
        let turned = e("rotate(ball:2,0,0,1, 0,0,1, 180)");
        assert!(turned.value([-2.0, 0.0, 0.0]) > 0.0 && turned.value([2.0, 0.0, 0.0]) < 0.0);
        let grown = e("scale(ball:1,0,0,1, 2)");
        assert!((radius_along_x(&grown, 2.0) - 4.0).abs() < 1e-12);
        let stretched = e("scale(ball:1,0,0,1, 3,1,0.5)");
        assert!((radius_along_x(&stretched, 3.0) - 6.0).abs() < 1e-12);
        assert!(stretched.value([3.0, 0.0, 0.49]) > 0.0 && stretched.value([3.0, 0.0, 0.51]) < 0.0);
        let off = e("offset(ball:0,0,0,2, 0.5)");
        assert!((radius_along_x(&off, 0.0) - (0.5 + 4.25f64.sqrt())).abs() < 1e-6);
        let domain = e("rotate(translate(ball:0,0,0,1, 3,0,0), 0,0,1, 90)").domain().unwrap();
        assert!((domain.0[1] - 2.0).abs() < 1e-12 && (domain.1[1] - 4.0).abs() < 1e-12, "{domain:?}");
    }

    #[test]
    fn grid_layers_agree_with_pointwise_values() {
        let x = e("difference(offset(scale(translate(ball:0,0,0,1, 0.3,0,0), 1.5, 1.2, 0.9), 0.2), \
                   rotate(ellipsoid:0,0,0,0.5,1,2, 1,1,0, 30))");
        let grid = Grid { dims: [9, 8, 7], origin: [-2.0, -1.9, -1.8], spacing: [0.5, 0.5, 0.6] };
        let v = x.layers(&grid, 2, 3);
        for k in 0..3 {
            for j in 0..8 {
                for i in 0..9 {
                    let want = x.value(grid.node(i, j, k + 2));
                    let got = v[i + 9 * (j + 8 * k)];
                    assert!((got - want).abs() < 1e-9, "({i},{j},{k}): {got} != {want}");
                }
            }
        }
    }
}
