//! The volume spline U(x) = sum_i lambda_i G(|x - P_i|) + sum_j c_j p_j(x): the rows of its bordered
//! (N+k) x (N+k) system and its evaluation. Pure: the rows a rank owns are given to it; no MPI here.
//!
//! # The interpolation problem
//!
//! Given distinct points P_1..P_N in R^n (n = 3 for scattered surface points, n = 2 inside a
//! contour slice, n = 1 for the line splines of the contour tests) and values r_i (the carrier's
//! values r_i = f_c(P_i), see [`crate::spline::carrier`]), U is the function that takes the values,
//! U(P_i) = r_i, and among all such functions has the least bending energy
//!
//! ```text
//! E(U) = integral over R^n of  sum_{|alpha| = m} (m! / alpha!) (D^alpha U)^2 dx
//! ```
//!
//! (the thin-plate energy for m = 2: the sum of the squared second derivatives). The energy
//! vanishes exactly on the polynomials of degree <= m - 1, and point values are only defined on
//! the space of finite energy when 2m > n, which [`Kernel::new`] enforces.
//!
//! The minimiser (Duchon's polyharmonic spline) is a sum of shifted copies of the fundamental
//! solution G of the iterated Laplacian Delta^m, plus a polynomial of degree <= m - 1:
//!
//! ```text
//! U(x) = sum_{i=1..N} lambda_i G(|x - P_i|) + sum_{j=1..k} c_j p_j(x)
//!
//! G(r) = r^(2m-n) ln r   for even n,      G(r) = r^(2m-n)   for odd n,      G(0) = 0
//! ```
//!
//! Constant factors of G are left out: they are absorbed by the lambda_i. The kernels in use:
//!
//! | n | m | G(r)       | p_1..p_k                         | k  |
//! |---|---|------------|----------------------------------|----|
//! | 3 | 2 | r          | 1, x, y, z                       | 4  |
//! | 3 | 3 | r^3        | the monomials of degree <= 2     | 10 |
//! | 2 | 2 | r^2 ln r   | 1, a, b (thin-plate spline)      | 3  |
//! | 2 | 3 | r^4 ln r   | the monomials of degree <= 2     | 6  |
//! | 1 | 2 | r^3        | 1, x (the natural cubic spline)  | 2  |
//!
//! In general k = C(n + m - 1, n), the dimension of the polynomials of degree <= m - 1 in n
//! variables ([`Kernel::poly_count`]; the basis order is [`Kernel::monomials`]).
//!
//! With a compactly supported Wendland kernel in place of G (k = 4, the linear polynomials) the
//! same rows ([`fill_rows`]) are the dense form of a sparse system; its own assembly, its
//! definiteness and its block solution are in [`crate::spline::compact`].
//!
//! # The bordered system
//!
//! The N interpolation conditions and the k moment conditions
//!
//! ```text
//! sum_j lambda_j G(|P_i - P_j|) + sum_l c_l p_l(P_i) = r_i      (i = 1..N)
//! sum_i lambda_i p_l(P_i) = 0                                    (l = 1..k), i.e. P^T lambda = 0
//! ```
//!
//! form the symmetric (N+k) x (N+k) system
//!
//! ```text
//! [ A    P ] [ lambda ]   [ r ]        A_ij = G(|P_i - P_j|)   (zero diagonal, since G(0) = 0)
//! [ P^T  0 ] [   c    ] = [ 0 ]        P_il = p_l(P_i)
//! ```
//!
//! The moment conditions are what minimising E adds to plain interpolation: they make the kernel
//! part of U orthogonal to the polynomials the energy cannot see, so that it has finite energy and
//! does not grow faster than the polynomial part. For G = r in 3D, for instance, expanding
//! |x - P| = |x| - (x / |x|) . P + O(1 / |x|) shows that sum_i lambda_i |x - P_i| is O(1 / |x|)
//! when sum_i lambda_i = 0 and sum_i lambda_i P_i = 0: far from the data U is its linear part.
//!
//! The matrix has a zero diagonal and a zero k x k block: it is indefinite (a saddle-point
//! matrix with at least k negative eigenvalues), so plain Cholesky does not apply to it.
//!
//! # Conditional definiteness
//!
//! A kernel is conditionally positive definite of order l when lambda^T A lambda > 0 for every
//! set of distinct points and every lambda != 0 with sum_i lambda_i q(P_i) = 0 for all polynomials
//! q of degree < l. The polyharmonic kernels are, up to a sign s (see Wendland, *Scattered Data
//! Approximation*, 2005, chapter 8): (-1)^ceil(p/2) r^p for odd p is conditionally positive
//! definite of order ceil(p/2), and (-1)^(q+1) r^(2q) ln r of order q + 1. Both orders are at most m
//! for every admissible (n, m), and a kernel conditionally definite of some order is so of every
//! higher order, so s G is conditionally positive definite of order m: on the null space of P^T
//! (exactly the lambda that satisfy the moment conditions),
//!
//! ```text
//! s lambda^T A lambda > 0   for lambda != 0 with P^T lambda = 0,
//! s = -1 for r and r^4 ln r,   s = +1 for r^3 and r^2 ln r        (Kernel::definiteness_sign)
//! ```
//!
//! What it implies:
//! - **Uniqueness.** If the points are unisolvent (below), the system is nonsingular. Suppose
//!   A lambda + P c = 0 and P^T lambda = 0. Multiplying the first equation by lambda^T gives
//!   lambda^T A lambda + (P^T lambda)^T c = lambda^T A lambda = 0, so lambda = 0; then P c = 0, and
//!   c = 0 because P has full column rank.
//! - **A definite solver.** Write P = Q [R; 0] (Householder QR of the N x k block, Q = [Q1 Q2],
//!   Q2 an orthonormal basis of the null space of P^T). Every lambda satisfying the moment
//!   conditions is lambda = Q2 mu, and multiplying the first block row by Q2^T removes c:
//!   (Q2^T A Q2) mu = Q2^T r. The (N-k) x (N-k) matrix s Q2^T A Q2 is symmetric positive definite,
//!   so Cholesky applies (N^3 / 3 flops against 2 N^3 / 3 for LU and 4 N^3 / 3 for Householder
//!   QR); then R c = Q1^T (r - A lambda). This is the projected Cholesky of
//!   `linalg::dist::cholesky`; a pivot that is not positive (round-off on a nearly degenerate
//!   point set) sends the solve to LU.
//! - **Energy.** The energy E(U) of the solution is a positive multiple of s lambda^T A lambda
//!   (the polynomial part has none): conditional definiteness is the statement that this energy
//!   is positive for every non-polynomial spline of this form.
//!
//! # Unisolvency
//!
//! P has full column rank k when the only polynomial of degree <= m - 1 vanishing at every P_i is
//! zero. For m = 2 this means that the points are not all on one plane (3D), on one line (2D) or
//! at one abscissa (1D); for m = 3 in 3D, not all on one quadric. `hygiene::check_unisolvent`
//! checks the rank and says which case failed. Equal points give two equal rows: `hygiene`
//! merges points closer than a small fraction of the bounding-box diagonal before the fit.
//!
//! # Normalisation
//!
//! The interpolant does not change under a translation or a uniform scaling of the data. A
//! translation moves the kernel terms with the points and maps polynomials of degree <= m - 1 to
//! polynomials of the same degree. A scaling x -> a x multiplies G by a^(2m-n) for odd n; for even
//! n it adds a^(2m-n) ln(a) |x - P_i|^(2m-n), and sum_i lambda_i |x - P_i|^(2m-n) (an even power,
//! so a polynomial in x) is, by the moment conditions, a polynomial of degree <= m - 1 (expand
//! |x - P_i|^(2m-n) into monomials x^alpha P_i^beta with |alpha| + |beta| = 2m - n: the moment
//! conditions cancel every term with |beta| <= m - 1, leaving |alpha| <= m - n), absorbed by the c_j.
//! The matrix is far from invariant, though: in raw coordinates of size 1000 the entries of A are
//! of size 1000^(2m-n) while the monomials range from 1 to 1000^(m-1). So the centres are mapped to
//! x' = (x - centre) / scale ([`Normalisation`]: centre of the bounding box, half its diagonal),
//! which puts every point in the unit ball and balances the blocks; the map is kept with the
//! spline, U is evaluated at x', and the carrier stays in the caller's coordinates.

use rayon::prelude::*;

use crate::spline::evaluator::Evaluator;
use crate::spline::kernel::Kernel;

/// The affine map to the internal coordinates x' = (x - centre) / scale (centre of the bounding
/// box, half its diagonal), kept for conditioning; see "Normalisation" in the module doc.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Normalisation {
    pub centre: [f64; 3],
    pub scale: f64,
}

impl Normalisation {
    /// The normalisation of a bounding box (lo, hi) in `dim` dimensions.
    pub fn of_box(lo: &[f64], hi: &[f64]) -> Self {
        let mut centre = [0.0; 3];
        for d in 0..lo.len() {
            centre[d] = 0.5 * lo[d] + 0.5 * hi[d];
        }
        let scale = 0.5 * crate::spline::hygiene::diagonal(lo, hi);
        Normalisation { centre, scale: if scale > 0.0 { scale } else { 1.0 } }
    }

    #[inline]
    pub fn apply(&self, x: &[f64], out: &mut [f64]) {
        for (d, o) in out.iter_mut().enumerate() {
            *o = (x[d] - self.centre[d]) / self.scale;
        }
    }

    /// The caller's coordinates of the normalised point `x` (3 values): the inverse of
    /// [`Normalisation::apply`].
    #[inline]
    pub fn undo(&self, x: &[f64]) -> [f64; 3] {
        [0, 1, 2].map(|d| self.centre[d] + self.scale * x[d])
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
    fill_rows_lower(kernel, centres, values, rows, usize::MAX, out);
}

/// [`fill_rows`] but for the entries of A above the diagonal in the rows from `whole` on, which
/// are left as they are: what a solver that reads the lower triangle of A and its first `whole`
/// rows alone needs (the projected Cholesky, with `whole` the polynomial count), in about half
/// the kernel evaluations. The entries filled are those of [`fill_rows`], bit for bit.
pub fn fill_rows_lower(
    kernel: &Kernel,
    centres: &[f64],
    values: &[f64],
    rows: &[usize],
    whole: usize,
    out: &mut [f64],
) {
    let cols: Vec<usize> = (0..values.len() + kernel.poly_count() + 1).collect();
    fill(kernel, centres, values, (rows, &cols, whole), out);
}

/// Fills the entries (rows x cols, global indices, column N + k the right-hand side) of
/// [A P; P^T 0 | r 0] into `out`, column-major with leading dimension `rows.len()`: the blocks a
/// rank of a 2D process grid owns, or whole rows ([`fill_rows`]). Every entry is the same function
/// of its indices whatever the distribution, so all layouts assemble the same matrix bit for bit.
pub fn fill_block(
    kernel: &Kernel,
    centres: &[f64],
    values: &[f64],
    rows: &[usize],
    cols: &[usize],
    out: &mut [f64],
) {
    fill_block_lower(kernel, centres, values, (rows, cols), usize::MAX, out);
}

/// [`fill_block`] but for the entries of A above the diagonal in the rows from `whole` on, which
/// are left as they are (see [`fill_rows_lower`]): the blocks a rank of a 2D process grid holds
/// for the projected Cholesky.
pub fn fill_block_lower(
    kernel: &Kernel,
    centres: &[f64],
    values: &[f64],
    (rows, cols): (&[usize], &[usize]),
    whole: usize,
    out: &mut [f64],
) {
    fill(kernel, centres, values, (rows, cols, whole), out);
}

/// [`fill_block`], but for the entries of A above the diagonal in the rows from `whole` on.
fn fill(
    kernel: &Kernel,
    centres: &[f64],
    values: &[f64],
    block: (&[usize], &[usize], usize),
    out: &mut [f64],
) {
    // one dispatch on the kind of kernel for the whole fill, not one per entry
    match kernel.wendland_part() {
        Some(w) => fill_with(kernel, move |r2| w.eval_r2(r2), centres, values, block, out),
        None => fill_with(kernel, |r2| kernel.green_r2(r2), centres, values, block, out),
    }
}

/// [`fill_block`] with the radial function `radial` (which is `kernel.eval_r2`), but for the
/// entries of A above the diagonal in the rows from `whole` on, which are left as they are.
fn fill_with(
    kernel: &Kernel,
    radial: impl Fn(f64) -> f64 + Sync,
    centres: &[f64],
    values: &[f64],
    (rows, cols, whole): (&[usize], &[usize], usize),
    out: &mut [f64],
) {
    let dim = kernel.dim();
    let n = values.len();
    let k = kernel.poly_count();
    let lc = rows.len();
    assert_eq!(centres.len(), n * dim);
    assert_eq!(out.len(), lc * cols.len());
    assert!(cols.iter().all(|&j| j <= n + k), "column index beyond the right-hand side");
    if lc == 0 {
        return;
    }
    let monomials = kernel.monomials();
    let nugget = kernel.nugget();
    // column j is filled for all the rows at once: one parallel task per column
    out.par_chunks_mut(lc).zip(cols).for_each(|(col, &j)| {
        if j < n {
            let pj = &centres[j * dim..(j + 1) * dim];
            for (v, &g) in col.iter_mut().zip(rows).filter(|(_, &g)| g < whole || g >= j) {
                *v = if g < n {
                    radial(dist2(&centres[g * dim..(g + 1) * dim], pj))
                } else {
                    monomial(&monomials[g - n], pj)
                };
            }
            if nugget != 0.0 {
                if let Some(at) = rows.iter().position(|&g| g == j) {
                    col[at] += nugget;
                }
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

/// The whole system [A P; P^T 0] (column-major, (N+k)^2) and its right-hand side [r; 0], on
/// one process: for small systems (slices) and serial oracles.
pub fn full_system(kernel: &Kernel, centres: &[f64], values: &[f64]) -> (Vec<f64>, Vec<f64>) {
    let n = system_size(kernel, values.len());
    let rows: Vec<usize> = (0..n).collect();
    let mut m = vec![0.0; n * (n + 1)];
    fill_rows(kernel, centres, values, &rows, &mut m);
    let b = m.split_off(n * n);
    (m, b)
}

/// The squared distance between two points, summed over the coordinates in order: the one
/// formula behind every matrix entry, dense or sparse, so that both assemblies agree bit for bit.
#[inline]
pub(crate) fn dist2(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(a, b)| (a - b) * (a - b)).sum()
}

/// The monomial with exponents `e` at x (first `x.len()` exponents used).
#[inline]
pub(crate) fn monomial(e: &[u8; 3], x: &[f64]) -> f64 {
    x.iter().zip(e).map(|(v, &p)| v.powi(p as i32)).product()
}

/// Sum over the rows `rows` (global indices) of (row . x - b)^2 and of b^2, re-assembling each row on the fly so
/// that no copy of the matrix is kept (in three dimensions through the vectorised [`Evaluator`]:
/// a row's product with x is the spline of weights x at the row's centre). The caller sums over
/// ranks.
///
/// Both sums are of the residual and right-hand side scaled by the power of two 2^-e nearest below
/// 1 / max |b| (the same on every rank, since every rank holds all of b): the scaling is exact, so the
/// ratio of the sums is the relative residual unchanged, and the squares stay finite for values up
/// to the largest finite number (data at 1e100 have carrier values near 1e200, whose squares
/// would overflow).
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
    let scale = power_of_two_below_inverse(values.iter().fold(0.0f64, |m, v| m.max(v.abs())));
    // in three dimensions a row's product with x is the spline of weights x at the row's centre
    // (in the normalised coordinates, which the identity normalisation keeps exact), summed by
    // the vectorised evaluator
    let spline = (dim == 3).then(|| Spline {
        kernel: *kernel,
        centres: centres.to_vec(),
        weights: x[..n].to_vec(),
        poly: x[n..].to_vec(),
        norm: Normalisation { centre: [0.0; 3], scale: 1.0 },
    });
    let ev = spline.as_ref().map(Evaluator::new);
    rows.par_iter()
        .map(|&g| {
            let (dot, b) = if g < n {
                let pg = &centres[g * dim..(g + 1) * dim];
                let mut s = 0.0;
                if let Some(ev) = &ev {
                    let mut u = [0.0];
                    ev.eval_row(&pg[..1], pg[1], pg[2], &mut u);
                    s = u[0];
                } else {
                    for j in 0..n {
                        let pj = &centres[j * dim..(j + 1) * dim];
                        let r2: f64 = pg.iter().zip(pj).map(|(a, b)| (a - b) * (a - b)).sum();
                        s += kernel.eval_r2(r2) * x[j];
                    }
                    for (t, e) in monomials.iter().enumerate() {
                        s += monomial(e, pg) * x[n + t];
                    }
                }
                s += kernel.nugget() * x[g];
                (s, values[g])
            } else {
                let e = &monomials[g - n];
                let s: f64 = (0..n).map(|j| monomial(e, &centres[j * dim..(j + 1) * dim]) * x[j]).sum();
                (s, 0.0)
            };
            let (r, b) = ((dot - b) * scale, b * scale);
            [r * r, b * b]
        })
        .reduce(|| [0.0, 0.0], |a, b| [a[0] + b[0], a[1] + b[1]])
}

/// 2^-e with 2^e <= m < 2^(e+1) for a positive finite m (1 otherwise): multiplying by it is exact
/// and brings m into [1, 2).
pub(crate) fn power_of_two_below_inverse(m: f64) -> f64 {
    if m > 0.0 && m.is_finite() {
        let e = m.log2().floor() as i32;
        // 2^-e in two steps, so that neither factor leaves the normal range
        2f64.powi(-e / 2) * 2f64.powi(-e + e / 2)
    } else {
        1.0
    }
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

    /// U at a point given in the caller's coordinates: the plain sum over all N centres, in index
    /// order (for a compactly supported kernel the terms beyond the support are zero). The
    /// reference for [`crate::spline::Evaluator`], which is the fast way to evaluate many points.
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

#[cfg(test)]
mod tests {
    use super::*;

    /// The row products of the plain sum in index order, the reference of [`residual_parts`].
    fn plain_parts(kernel: &Kernel, centres: &[f64], values: &[f64], rows: &[usize], x: &[f64]) -> [f64; 2] {
        let (n, monomials) = (values.len(), kernel.monomials());
        let mut out = [0.0; 2];
        for &g in rows {
            let (dot, b) = if g < n {
                let pg = &centres[3 * g..3 * g + 3];
                let mut s: f64 = (0..n).map(|j| kernel.eval_r2(dist2(pg, &centres[3 * j..])) * x[j]).sum();
                s += kernel.nugget() * x[g];
                s += monomials.iter().enumerate().map(|(t, e)| monomial(e, pg) * x[n + t]).sum::<f64>();
                (s, values[g])
            } else {
                ((0..n).map(|j| monomial(&monomials[g - n], &centres[3 * j..]) * x[j]).sum(), 0.0)
            };
            out[0] += (dot - b) * (dot - b);
            out[1] += b * b;
        }
        out
    }

    #[test]
    fn the_vectorised_residual_matches_the_plain_row_sums() {
        let mut seed = 7u64;
        let mut unit = || {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let n = 203;
        let centres: Vec<f64> = (0..3 * n).map(|_| unit()).collect();
        let values: Vec<f64> = (0..n).map(|_| unit()).collect();
        let kernels = [
            Kernel::new(3, 2).unwrap(),
            Kernel::new(3, 3).unwrap().with_smoothing(0.01).unwrap(),
            Kernel::wendland("wendland2", 0.4).unwrap(),
        ];
        for kernel in kernels {
            let x: Vec<f64> = (0..n + kernel.poly_count()).map(|_| unit()).collect();
            // every third row, as one rank of three holds them, and the polynomial rows
            let rows: Vec<usize> = (0..n + kernel.poly_count()).step_by(3).collect();
            let got = residual_parts(&kernel, &centres, &values, &rows, &x);
            let want = plain_parts(&kernel, &centres, &values, &rows, &x);
            let scale = power_of_two_below_inverse(values.iter().fold(0.0f64, |m, v| m.max(v.abs())));
            for (g, w) in got.iter().zip(want) {
                let w = w * scale * scale;
                assert!((g - w).abs() <= 1e-12 * w, "{kernel:?}: {g} against {w}");
            }
        }
    }
}
