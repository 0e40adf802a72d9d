//! The reconstructed solid as a function model f = f_c - U: the carrier, the solved spline and the
//! record of how it was made. Evaluation of f at points and on grid slabs, threaded with rayon.
//!
//! # The sign of the solid
//!
//! The carrier f_c is the defining function of a simple solid (f_c >= 0 inside, see
//! [`crate::spline::carrier`]), the spline U interpolates its values r_i = f_c(P_i) at the data
//! points ([`crate::spline::system`]), and the solid is
//!
//! ```text
//! f(x) = f_c(x) - U(x) >= 0        (inside; f = 0 on the surface, f < 0 outside)
//! ```
//!
//! so f(P_i) = f_c(P_i) - r_i = 0 at every data point: the surface passes through the data.
//!
//! Savchenko et al. (1995) print the difference the other way round, f = U - f_c, with the same
//! claim that f >= 0 inside. That solid is inside-out. U is the interpolant of least bending
//! energy, so where the data do not force it to bend it stays as flat as the polynomial part
//! allows, while f_c keeps the carrier's curvature. The smallest case shows it: one dimension,
//! m = 2 (natural cubic spline, polynomials 1 and x), the carrier f_c(x) = R^2 - x^2 (the ball
//! [-R, R]) and two data points x = -a and x = a with a < R. Both values are R^2 - a^2; the
//! constant U(x) = R^2 - a^2 takes them with zero energy, so it is the interpolant, and
//!
//! ```text
//! f_c - U = a^2 - x^2   >= 0 exactly on [-a, a], the segment the points bound,
//! U - f_c = x^2 - a^2   >= 0 outside it.
//! ```
//!
//! The same holds far from any data set: for m = 2 the kernel part of U dies away (the moment
//! conditions cancel its growth), so U tends to its linear part, while a ball carrier falls off
//! like -|x|^2. Hence f = f_c - U -> -infinity far away: the far field is outside, as it must be
//! for a bounded solid (with U - f_c it would be inside).
//!
//! # Levels
//!
//! The carrier idea applies recursively: the carrier of a fit may itself be a reconstructed solid.
//! A model holds the splines U_0, ..., U_L (`coarse` then `spline`, coarsest first) and
//!
//! ```text
//! f(x) = f_c(x) - U_0(x) - U_1(x) - ... - U_L(x).
//! ```
//!
//! The two-level fit of the compactly supported method ([`crate::app::fit`]) takes U_0 as a dense
//! fit of a subsample (with off-surface constraints), so f_0 = f_c - U_0 is already a clean solid
//! that decides the sign away from the data, and U_1, a Wendland spline through all points,
//! interpolates the remainder r_i = f_0(P_i) - t_i: beyond its support U_1 = its linear part,
//! which only shifts and tilts f_0 slightly instead of exposing the carrier's sphere. A model of
//! one level (`coarse` empty) is the plain method. Every evaluation sums the levels in this order.

use rayon::prelude::*;

use crate::grid::Grid;
use crate::spline::carrier::Carrier;
use crate::spline::compact_eval::CompactRows;
use crate::spline::evaluator::Evaluator;
use crate::spline::Spline;

/// How a model was made; stored with it.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Provenance {
    pub input: String,
    /// Bounding box of the input points (the default domain of the grid).
    pub box_lo: [f64; 3],
    pub box_hi: [f64; 3],
    pub points_read: usize,
    pub duplicates_merged: usize,
    /// How many of the finest level's centres, first in its order, are the data points (the
    /// others are off-surface and blob constraints); 0 where unknown (contour models, files
    /// written before it was recorded).
    pub data_points: usize,
    pub solver: String,
    pub residual: f64,
    pub ranks: usize,
    pub threads: usize,
    /// (stage, max seconds over ranks)
    pub timings: Vec<(String, f64)>,
    pub version: String,
}

/// A function on 3D space that can be sampled on grid slabs: what the volume and mesh outputs
/// need of a model, whether it came from scattered points or from contours.
pub trait Field: Sync {
    /// f at the nodes of grid layers k0..k0+layers, x fastest. Must depend on nothing but the node
    /// positions, so that slabs computed on different ranks agree bit for bit where they overlap.
    fn eval_layers(&self, grid: &Grid, k0: usize, layers: usize) -> Vec<f64>;
    /// Kernel evaluations per node (for the throughput report).
    fn kernel_evals_per_node(&self) -> usize;
}

/// f(x) = f_c(x) - sum of the coarse levels' U_l(x) - U(x) (see "Levels" above).
#[derive(Debug, Clone, PartialEq)]
pub struct Model {
    pub carrier: Carrier,
    /// The finest level, the one that interpolates the data.
    pub spline: Spline,
    /// Coarser levels, coarsest first, subtracted before `spline`; empty for the plain method.
    pub coarse: Vec<Spline>,
    pub provenance: Provenance,
}

impl Model {
    /// A model of one level, f = f_c - U.
    pub fn single(carrier: Carrier, spline: Spline, provenance: Provenance) -> Model {
        Model { carrier, spline, coarse: Vec::new(), provenance }
    }

    /// Every level in the order of evaluation: the coarse ones, then `spline`.
    pub fn levels(&self) -> impl Iterator<Item = &Spline> {
        self.coarse.iter().chain(std::iter::once(&self.spline))
    }

    /// Centres over all levels.
    pub fn centre_count(&self) -> usize {
        self.levels().map(Spline::len).sum()
    }

    /// The data points the model records (the first `provenance.data_points` centres of its
    /// finest level, mapped back to the caller's coordinates: after denoising, the moved points
    /// the spline interpolates), 3 values per point, or None where it does not record them (a
    /// model of another dimension, or one that does not say how many of its centres are data).
    pub fn data_points(&self) -> Option<Vec<f64>> {
        let n = self.provenance.data_points;
        let sp = &self.spline;
        if n == 0 || n > sp.len() || sp.kernel.dim() != 3 {
            return None;
        }
        let norm = sp.norm;
        Some(
            sp.centres[..3 * n]
                .chunks_exact(3)
                .flat_map(|c| (0..3).map(move |d| c[d] * norm.scale + norm.centre[d]))
                .collect(),
        )
    }

    /// f at a point in the caller's coordinates.
    #[inline]
    pub fn eval(&self, x: &[f64]) -> f64 {
        self.levels().fold(self.carrier.eval(x), |f, s| f - s.eval(x))
    }
}

impl Field for Model {
    /// Threaded over rows of nodes with the blocked evaluator.
    fn eval_layers(&self, grid: &Grid, k0: usize, layers: usize) -> Vec<f64> {
        let [nx, ny, _] = grid.dims;
        let evs: Vec<Evaluator> = self.levels().map(Evaluator::new).collect();
        let xs: Vec<f64> = (0..nx).map(|i| grid.node(i, 0, 0)[0]).collect();
        let mut out = vec![0.0; nx * ny * layers];
        out.par_chunks_mut(nx.max(1)).enumerate().for_each(|(row, vals)| {
            let (j, k) = (row % ny, k0 + row / ny);
            let p = grid.node(0, j, k);
            for (v, &x) in vals.iter_mut().zip(&xs) {
                *v = self.carrier.eval(&[x, p[1], p[2]]);
            }
            let mut u = vec![0.0; vals.len()];
            for ev in &evs {
                ev.eval_row(&xs, p[1], p[2], &mut u);
                for (v, w) in vals.iter_mut().zip(&u) {
                    *v -= w;
                }
            }
        });
        out
    }

    /// N for the Green's functions; for a compactly supported kernel the mean number of centres
    /// within the support of a centre (measured on up to 1000 of them): the cost of a node near the
    /// data, where the work is (nodes farther than R from every centre cost none). Summed over the
    /// levels.
    fn kernel_evals_per_node(&self) -> usize {
        self.levels()
            .map(|s| match CompactRows::new(s) {
                Some(c) => c.mean_neighbours(1000).round() as usize,
                None => s.len(),
            })
            .sum()
    }
}
