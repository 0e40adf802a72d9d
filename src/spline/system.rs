//! The volume spline U(x) = sum_i lambda_i G(|x - P_i|) + sum_j c_j p_j(x) (paper 000, section 3):
//! the rows of its bordered (N+k) x (N+k) system and its evaluation. Pure: the rows a rank owns are
//! given to it; no MPI here.

use rayon::prelude::*;

use crate::spline::kernel::Kernel;

/// The affine map to the internal coordinates x' = (x - centre) / scale (math.md, section 1:
/// centre of the bounding box, half its diagonal), kept for conditioning.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Normalisation {
    pub centre: [f64; 3],
    pub scale: f64,
}

impl Normalisation {
    /// The normalisation of a bounding box (lo, hi) in `dim` dimensions.
    pub fn of_box(lo: &[f64], hi: &[f64]) -> Self {
        let mut centre = [0.0; 3];
        let mut d2 = 0.0;
        for d in 0..lo.len() {
            centre[d] = 0.5 * (lo[d] + hi[d]);
            d2 += (hi[d] - lo[d]).powi(2);
        }
        let scale = 0.5 * d2.sqrt();
        Normalisation { centre, scale: if scale > 0.0 { scale } else { 1.0 } }
    }

    #[inline]
    pub fn apply(&self, x: &[f64], out: &mut [f64]) {
        for (d, o) in out.iter_mut().enumerate() {
            *o = (x[d] - self.centre[d]) / self.scale;
        }
    }
}

/// A solved volume spline in normalised coordinates.
#[derive(Debug, Clone, PartialEq)]
pub struct Spline {
    pub kernel: Kernel,
    /// Centres P'_i (normalised), `dim` values per centre.
    pub centres: Vec<f64>,
    /// lambda_1..lambda_N.
    pub weights: Vec<f64>,
    /// c_1..c_k, coefficients of `kernel.monomials()`.
    pub poly: Vec<f64>,
    pub norm: Normalisation,
}

/// The bordered system's size N + k for N centres.
pub fn system_size(kernel: &Kernel, n_centres: usize) -> usize {
    n_centres + kernel.poly_count()
}

/// Fills the rows `rows` (global indices) of [A P; P^T 0 | r 0] for centres (normalised, `dim`
/// per centre) and values r (one per centre) into `out`, column-major with leading dimension
/// `rows.len()` and N + k + 1 columns (the right-hand side last). Rows are independent: each costs
/// N kernel evaluations, so any distribution of the rows over ranks can be assembled in place.
pub fn fill_rows(kernel: &Kernel, centres: &[f64], values: &[f64], rows: &[usize], out: &mut [f64]) {
    let dim = kernel.dim();
    let n = values.len();
    let k = kernel.poly_count();
    let lc = rows.len();
    assert_eq!(centres.len(), n * dim);
    assert_eq!(out.len(), lc * (n + k + 1));
    if lc == 0 {
        return;
    }
    let monomials = kernel.monomials();
    // column j is filled for all the rows at once: one parallel task per column
    out.par_chunks_mut(lc).enumerate().for_each(|(j, col)| {
        if j < n {
            let pj = &centres[j * dim..(j + 1) * dim];
            for (v, &g) in col.iter_mut().zip(rows) {
                *v = if g < n {
                    let pg = &centres[g * dim..(g + 1) * dim];
                    let r2: f64 = pg.iter().zip(pj).map(|(a, b)| (a - b) * (a - b)).sum();
                    kernel.eval_r2(r2)
                } else {
                    monomial(&monomials[g - n], pj)
                };
            }
        } else if j < n + k {
            for (v, &g) in col.iter_mut().zip(rows) {
                *v = if g < n { monomial(&monomials[j - n], &centres[g * dim..(g + 1) * dim]) } else { 0.0 };
            }
        } else {
            for (v, &g) in col.iter_mut().zip(rows) {
                *v = if g < n { values[g] } else { 0.0 };
            }
        }
    });
}

/// The whole system [A P; P^T 0] (row-major, (N+k)^2) and its right-hand side [r; 0], on one
/// process: for small systems (slices) and serial oracles.
pub fn full_system(kernel: &Kernel, centres: &[f64], values: &[f64]) -> (Vec<f64>, Vec<f64>) {
    let n = system_size(kernel, values.len());
    let rows: Vec<usize> = (0..n).collect();
    let mut cm = vec![0.0; n * (n + 1)];
    fill_rows(kernel, centres, values, &rows, &mut cm);
    // column-major with ld n -> row-major
    let mut m = vec![0.0; n * n];
    for c in 0..n {
        for r in 0..n {
            m[r * n + c] = cm[r + c * n];
        }
    }
    (m, cm[n * n..].to_vec())
}

#[inline]
fn monomial(e: &[u8; 3], x: &[f64]) -> f64 {
    x.iter().zip(e).map(|(v, &p)| v.powi(p as i32)).product()
}

/// Sum over the rows `rows` (global indices) of (row . x - b)^2 and of b^2, re-assembling each row on the fly so
/// that no copy of the matrix is kept. The caller sums over ranks.
pub fn residual_parts(
    kernel: &Kernel,
    centres: &[f64],
    values: &[f64],
    rows: &[usize],
    x: &[f64],
) -> [f64; 2] {
    let dim = kernel.dim();
    let n = values.len();
    let monomials = kernel.monomials();
    rows.par_iter()
        .map(|&g| {
            let (dot, b) = if g < n {
                let pg = &centres[g * dim..(g + 1) * dim];
                let mut s = 0.0;
                for j in 0..n {
                    let pj = &centres[j * dim..(j + 1) * dim];
                    let r2: f64 = pg.iter().zip(pj).map(|(a, b)| (a - b) * (a - b)).sum();
                    s += kernel.eval_r2(r2) * x[j];
                }
                for (t, e) in monomials.iter().enumerate() {
                    s += monomial(e, pg) * x[n + t];
                }
                (s, values[g])
            } else {
                let e = &monomials[g - n];
                let s: f64 = (0..n).map(|j| monomial(e, &centres[j * dim..(j + 1) * dim]) * x[j]).sum();
                (s, 0.0)
            };
            [(dot - b) * (dot - b), b * b]
        })
        .reduce(|| [0.0, 0.0], |a, b| [a[0] + b[0], a[1] + b[1]])
}

impl Spline {
    /// Builds the spline from the solution vector [lambda; c] of the bordered system.
    pub fn from_solution(kernel: Kernel, centres: Vec<f64>, solution: &[f64], norm: Normalisation) -> Self {
        let n = centres.len() / kernel.dim();
        Spline { kernel, centres, weights: solution[..n].to_vec(), poly: solution[n..].to_vec(), norm }
    }

    pub fn len(&self) -> usize {
        self.weights.len()
    }

    pub fn is_empty(&self) -> bool {
        self.weights.is_empty()
    }

    /// U at a point given in the caller's coordinates.
    pub fn eval(&self, x: &[f64]) -> f64 {
        let dim = self.kernel.dim();
        let mut xn = [0.0; 3];
        self.norm.apply(x, &mut xn[..dim]);
        let mut s = 0.0;
        for (p, w) in self.centres.chunks_exact(dim).zip(&self.weights) {
            let r2: f64 = p.iter().zip(&xn).map(|(a, b)| (a - b) * (a - b)).sum();
            s += w * self.kernel.eval_r2(r2);
        }
        let mut pv = [0.0; 10];
        let k = self.poly.len();
        self.kernel.poly_eval(&xn, &mut pv[..k]);
        s + pv[..k].iter().zip(&self.poly).map(|(a, b)| a * b).sum::<f64>()
    }

    /// The moment sums sum_i lambda_i p_j(P_i), which vanish for a solved spline.
    pub fn moments(&self) -> Vec<f64> {
        let dim = self.kernel.dim();
        self.kernel
            .monomials()
            .iter()
            .map(|e| self.centres.chunks_exact(dim).zip(&self.weights).map(|(p, w)| w * monomial(e, p)).sum())
            .collect()
    }
}
