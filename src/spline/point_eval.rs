//! Evaluation of a model f = f_c - U at single points, with or without its derivatives, as a
//! ray caster or a curvature sampler asks for them: one point at a time, from many threads.
//!
//! For the Green's functions r and r^3 the centres are kept in structure-of-arrays form and
//! summed in lanes that the compiler keeps in vector registers, with a runtime switch to AVX-512
//! or AVX2 code; the value takes the grid evaluator's own sums, so that a point gets the same
//! bits as a grid node at the same place. For a compactly supported kernel a point sums only the
//! centres within the support, found with the octree: its cost is its neighbour count, not N.
//! Other kernels take the plain sums of [`crate::spline::derivatives`].
//!
//! The value at a point depends on nothing but the point: the same bits from any thread or rank.

use crate::simd::on_widest_unit;
use crate::spline::derivatives::{
    add_radial_term, carrier_jet, denormalise, polynomial_jet, spline_jet, Jet,
};
use crate::spline::evaluator::{lane_sums, padded_lanes, reduce_lanes, Form, LANES};
use crate::spline::octree::{Octree, DEFAULT_LEAF_CAPACITY};
use crate::spline::{Model, Spline};

/// One level of a model prepared for evaluation at single points (it owns a copy of its spline).
#[derive(Debug, Clone)]
struct Level {
    spline: Spline,
    form: Option<Form>,
    cx: Vec<f64>,
    cy: Vec<f64>,
    cz: Vec<f64>,
    w: Vec<f64>,
    tree: Option<Octree>,
}

impl Level {
    fn new(spline: &Spline) -> Self {
        let k = spline.kernel;
        let form = Form::of(spline);
        let tree = (k.is_compact().is_some() && k.dim() == 3)
            .then(|| Octree::new(&spline.centres, DEFAULT_LEAF_CAPACITY));
        let [cx, cy, cz, w] = if form.is_some() { padded_lanes(spline, LANES) } else { Default::default() };
        Level { spline: spline.clone(), form, cx, cy, cz, w, tree }
    }

    fn normalised(&self, x: &[f64; 3]) -> [f64; 3] {
        let mut xn = [0.0; 3];
        self.spline.norm.apply(x, &mut xn);
        xn
    }

    /// U at `x` (caller's coordinates).
    fn value(&self, x: &[f64; 3]) -> f64 {
        let sp = &self.spline;
        match (self.form, &self.tree) {
            (Some(form), _) => {
                let xn = self.normalised(x);
                let s = radial_value(form, xn, &self.cx, &self.cy, &self.cz, &self.w);
                s + polynomial_value(sp, &xn)
            }
            (None, Some(tree)) => {
                let xn = self.normalised(x);
                let mut found = Vec::new();
                let support = sp.kernel.is_compact().unwrap_or(0.0);
                tree.within(xn, support, &mut found);
                found.sort_unstable();
                let mut s = 0.0;
                for i in found {
                    let p = &sp.centres[3 * i..3 * i + 3];
                    let (dx, dy, dz) = (xn[0] - p[0], xn[1] - p[1], xn[2] - p[2]);
                    s += sp.weights[i] * sp.kernel.eval_r2((dx * dx + dy * dy) + dz * dz);
                }
                s + polynomial_value(sp, &xn)
            }
            (None, None) => sp.eval(x),
        }
    }

    /// U at `x` with its gradient and Hessian (caller's coordinates).
    fn jet(&self, x: &[f64; 3]) -> Jet {
        let sp = &self.spline;
        match (self.form, &self.tree) {
            (Some(form), _) => {
                let xn = self.normalised(x);
                let radial = radial_jet(form, xn, &self.cx, &self.cy, &self.cz, &self.w);
                denormalise(polynomial_jet(sp, &xn).combine(1.0, &radial, 1.0), sp.norm.scale)
            }
            (None, Some(tree)) => {
                let xn = self.normalised(x);
                let mut found = Vec::new();
                tree.within(xn, sp.kernel.is_compact().unwrap_or(0.0), &mut found);
                found.sort_unstable();
                let mut jet = polynomial_jet(sp, &xn);
                for i in found {
                    let p = &sp.centres[3 * i..3 * i + 3];
                    add_radial_term(
                        &mut jet,
                        &sp.kernel,
                        sp.weights[i],
                        [xn[0] - p[0], xn[1] - p[1], xn[2] - p[2]],
                    );
                }
                denormalise(jet, sp.norm.scale)
            }
            (None, None) => spline_jet(sp, x),
        }
    }

    /// grad U at `x`: the first-order part of [`Level::jet`], at a third of its cost for the
    /// Green's functions.
    fn gradient(&self, x: &[f64; 3]) -> [f64; 3] {
        let Some(form) = self.form else { return self.jet(x).gradient };
        let sp = &self.spline;
        let xn = self.normalised(x);
        let g = radial_gradient(form, xn, &self.cx, &self.cy, &self.cz, &self.w);
        let poly = polynomial_jet(sp, &xn);
        std::array::from_fn(|i| (g[i] + poly.gradient[i]) / sp.norm.scale)
    }
}

/// A model prepared for evaluation at single points (it owns a copy of what it needs); its levels
/// are subtracted from the carrier in the model's order.
#[derive(Debug, Clone)]
pub struct PointEvaluator {
    model: Model,
    levels: Vec<Level>,
}

impl PointEvaluator {
    pub fn new(model: Model) -> Self {
        let levels = model.levels().map(Level::new).collect();
        PointEvaluator { model, levels }
    }

    /// The model evaluated.
    pub fn model(&self) -> &Model {
        &self.model
    }

    /// f at `x` (caller's coordinates).
    pub fn value(&self, x: &[f64; 3]) -> f64 {
        self.levels.iter().fold(self.model.carrier.eval(x), |f, l| f - l.value(x))
    }

    /// f at `x` with its gradient and Hessian.
    pub fn jet(&self, x: &[f64; 3]) -> Jet {
        self.levels.iter().fold(carrier_jet(&self.model.carrier, x), |f, l| f.combine(1.0, &l.jet(x), -1.0))
    }

    /// grad f at `x`: the first-order part of [`PointEvaluator::jet`], at a third of its cost.
    pub fn gradient(&self, x: &[f64; 3]) -> [f64; 3] {
        let c = carrier_jet(&self.model.carrier, x);
        self.levels.iter().fold(c.gradient, |g, l| {
            let u = l.gradient(x);
            std::array::from_fn(|i| g[i] - u[i])
        })
    }
}

/// c . p(x') at the normalised point.
fn polynomial_value(sp: &crate::spline::Spline, xn: &[f64; 3]) -> f64 {
    let k = sp.poly.len();
    let mut pv = [0.0; 10];
    sp.kernel.poly_eval(xn, &mut pv[..k]);
    pv[..k].iter().zip(&sp.poly).map(|(a, b)| a * b).sum()
}

on_widest_unit! {
    /// sum_i w_i G(|x - P_i|), lanes reduced in a fixed order: the grid evaluator's sums
    /// ([`lane_sums`]), so that a point gets the bits a grid node there gets; AVX-512 or AVX2 code
    /// where the CPU has it (the same portable code, so every path gives the same bits).
    fn radial_value[][](form: Form, x: [f64; 3], cx: &[f64], cy: &[f64], cz: &[f64], w: &[f64]) -> f64
        = radial_value_portable;
}

#[inline(always)]
fn radial_value_portable(form: Form, x: [f64; 3], cx: &[f64], cy: &[f64], cz: &[f64], w: &[f64]) -> f64 {
    let mut a = [0.0f64; LANES];
    lane_sums(form, x, [cx, cy, cz, w], &mut a);
    reduce_lanes(&a)
}

on_widest_unit! {
    /// sum_i w_i a(r_i) (x - P_i) (normalised gradient of the radial part).
    fn radial_gradient[][](form: Form, x: [f64; 3], cx: &[f64], cy: &[f64], cz: &[f64], w: &[f64]) -> [f64; 3]
        = radial_gradient_portable;
}

#[inline(always)]
fn radial_gradient_portable(
    form: Form,
    x: [f64; 3],
    cx: &[f64],
    cy: &[f64],
    cz: &[f64],
    w: &[f64],
) -> [f64; 3] {
    let mut acc = [[0.0f64; LANES]; 3];
    let lanes = cx.chunks_exact(LANES).zip(cy.chunks_exact(LANES)).zip(cz.chunks_exact(LANES));
    for (((px, py), pz), pw) in lanes.zip(w.chunks_exact(LANES)) {
        for l in 0..LANES {
            let (dx, dy, dz) = (x[0] - px[l], x[1] - py[l], x[2] - pz[l]);
            let r2 = (dx * dx + dy * dy) + dz * dz;
            let r = r2.sqrt();
            // a = G'(r) / r; the cone of r at a centre contributes 0 (derivatives module doc)
            let a = match form {
                Form::R1 => {
                    if r2 > 0.0 {
                        1.0 / r
                    } else {
                        0.0
                    }
                }
                Form::R3 => 3.0 * r,
            };
            let s = pw[l] * a;
            acc[0][l] += s * dx;
            acc[1][l] += s * dy;
            acc[2][l] += s * dz;
        }
    }
    acc.map(|a| reduce_lanes(&a))
}

on_widest_unit! {
    /// sum_i w_i G(|x - P_i|) with its gradient and Hessian (normalised coordinates), in lanes:
    /// G = r has a = 1 / r, b = -1 / r^3, G = r^3 has a = 3r, b = 3 / r (both 0 at a centre; see
    /// [`crate::spline::derivatives`]).
    fn radial_jet[][](form: Form, x: [f64; 3], cx: &[f64], cy: &[f64], cz: &[f64], w: &[f64]) -> Jet
        = radial_jet_portable;
}

#[inline(always)]
fn radial_jet_portable(form: Form, x: [f64; 3], cx: &[f64], cy: &[f64], cz: &[f64], w: &[f64]) -> Jet {
    // value, gradient (3), Hessian (xx, yy, zz, xy, xz, yz)
    let mut acc = [[0.0f64; LANES]; 10];
    let lanes = cx.chunks_exact(LANES).zip(cy.chunks_exact(LANES)).zip(cz.chunks_exact(LANES));
    for (((px, py), pz), pw) in lanes.zip(w.chunks_exact(LANES)) {
        for l in 0..LANES {
            let (dx, dy, dz) = (x[0] - px[l], x[1] - py[l], x[2] - pz[l]);
            let r2 = (dx * dx + dy * dy) + dz * dz;
            let r = r2.sqrt();
            let inv = if r2 > 0.0 { 1.0 / r } else { 0.0 };
            let (g, a, b) = match form {
                Form::R1 => (r, inv, -inv * inv * inv),
                Form::R3 => (r2 * r, 3.0 * r, 3.0 * inv),
            };
            let (wa, wb) = (pw[l] * a, pw[l] * b);
            acc[0][l] += pw[l] * g;
            acc[1][l] += wa * dx;
            acc[2][l] += wa * dy;
            acc[3][l] += wa * dz;
            acc[4][l] += wa + wb * dx * dx;
            acc[5][l] += wa + wb * dy * dy;
            acc[6][l] += wa + wb * dz * dz;
            acc[7][l] += wb * dx * dy;
            acc[8][l] += wb * dx * dz;
            acc[9][l] += wb * dy * dz;
        }
    }
    let s = acc.map(|a| reduce_lanes(&a));
    Jet {
        value: s[0],
        gradient: [s[1], s[2], s[3]],
        hessian: [[s[4], s[7], s[8]], [s[7], s[5], s[9]], [s[8], s[9], s[6]]],
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::spline::derivatives::model_jet;
    use crate::spline::kernel::Kernel;
    use crate::spline::octree::tests::bunny;
    use crate::spline::{Carrier, Normalisation, Provenance, Spline};

    /// A spline on the bunny's vertices with pseudo-random weights under `kernel`.
    fn bunny_model(kernel: Kernel) -> Model {
        let mut s = 5u64;
        let mut rnd = || {
            s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let centres = bunny();
        let weights: Vec<f64> = (0..centres.len() / 3).map(|_| 1e-3 * rnd()).collect();
        let poly: Vec<f64> = (0..kernel.poly_count()).map(|_| rnd()).collect();
        let norm = Normalisation { centre: [0.1, -0.2, 0.3], scale: 2.0 };
        Model {
            carrier: Carrier::parse("ellipsoid:0.1,-0.2,0.3,2,1.5,1", 3).unwrap(),
            spline: Spline { kernel, centres, weights, poly, norm },
            coarse: Vec::new(),
            provenance: Provenance::default(),
        }
    }

    #[test]
    fn fast_paths_agree_with_the_plain_sums() {
        for kernel in [
            Kernel::new(3, 2).unwrap(),
            Kernel::new(3, 3).unwrap(),
            Kernel::wendland("wendland2", 0.15).unwrap(),
            Kernel::wendland("wendland4", 0.3).unwrap(),
        ] {
            let mut model = bunny_model(kernel);
            if kernel.is_compact().is_some() {
                // two levels: a Green's-function level under the compactly supported one
                model.coarse = vec![bunny_model(Kernel::new(3, 2).unwrap()).spline];
            }
            let ev = PointEvaluator::new(model.clone());
            // points near the data (centres mapped back to the caller's coordinates) and away
            let sp = &model.spline;
            let mut pts: Vec<[f64; 3]> = (0..sp.len())
                .step_by(97)
                .map(|i| std::array::from_fn(|d| sp.centres[3 * i + d] * 2.0 + [0.1, -0.2, 0.3][d] + 0.01))
                .collect();
            pts.push([0.3, 0.2, -0.1]);
            for x in pts {
                let (v, plain) = (ev.value(&x), model.eval(&x));
                assert!(
                    (v - plain).abs() <= 1e-12 * (1.0 + plain.abs()),
                    "{}: {v} vs {plain}",
                    kernel.name()
                );
                let (fast, slow) = (ev.jet(&x), model_jet(&model, &x));
                let close = |a: f64, b: f64| (a - b).abs() <= 1e-10 * (1.0 + b.abs());
                let g = ev.gradient(&x);
                for i in 0..3 {
                    assert!(close(fast.gradient[i], slow.gradient[i]), "{}", kernel.name());
                    assert!(close(g[i], slow.gradient[i]), "{}: {g:?} vs {:?}", kernel.name(), slow.gradient);
                    for j in 0..3 {
                        assert!(close(fast.hessian[i][j], slow.hessian[i][j]), "{}", kernel.name());
                    }
                }
            }
        }
    }

    #[test]
    fn a_point_gets_the_bits_of_the_grid_node_at_the_same_place() {
        for kernel in [Kernel::new(3, 2).unwrap(), Kernel::new(3, 3).unwrap()] {
            let model = bunny_model(kernel);
            let sp = &model.spline;
            // more centres than one block of the grid evaluator, not a whole number of periods
            assert!(sp.len() > 576 && !sp.len().is_multiple_of(24));
            let level = Level::new(sp);
            let ev = crate::spline::evaluator::Evaluator::new(sp);
            let xs: Vec<f64> = (0..41).map(|i| -1.9 + 0.09 * i as f64).collect();
            let mut row = vec![0.0; xs.len()];
            for (y, z) in [(0.3, -0.2), (1.1, 0.7), (-0.6, 0.05)] {
                ev.eval_row(&xs, y, z, &mut row);
                for (&x, &r) in xs.iter().zip(&row) {
                    assert_eq!(
                        level.value(&[x, y, z]).to_bits(),
                        r.to_bits(),
                        "{} at ({x}, {y}, {z})",
                        kernel.name()
                    );
                }
            }
        }
    }
}
