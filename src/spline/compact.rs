//! Volume splines with compactly supported kernels: the sparse matrix of the interpolation
//! system, assembled row by row with the octree, the polynomial block beside it, and the choice
//! of the support radius. Pure: the rows a rank owns are given to it; no MPI here.
//!
//! # Wendland functions
//!
//! The spline keeps the form of the Green's-function spline ([`crate::spline::system`]),
//!
//! ```text
//! U(x) = sum_i lambda_i phi(|x - P_i| / R) + c0 + c1 x + c2 y + c3 z,
//! ```
//!
//! with phi one of Wendland's functions phi_{3,k}: the piecewise polynomials of least degree that
//! are positive definite on R^3 and 2k times continuously differentiable, zero for r >= 1:
//!
//! ```text
//! wendland0   phi_{3,0}(r) = (1 - r)^2_+                       C^0
//! wendland2   phi_{3,1}(r) = (1 - r)^4_+ (4r + 1)              C^2
//! wendland4   phi_{3,2}(r) = (1 - r)^6_+ (35r^2 + 18r + 3)     C^4      ((t)_+ = max(t, 0))
//! ```
//!
//! (Wendland, *Piecewise polynomial, positive definite and compactly supported radial functions
//! of minimal degree*, Advances in Computational Mathematics 4, 1995.) Constant factors do not
//! matter: the lambda_i absorb them. The smoother the function, the smoother U, and the more
//! slowly phi falls off inside its support.
//!
//! # Positive definiteness
//!
//! A radial function is positive definite on R^3 when its three-dimensional Fourier transform is
//! nonnegative and not identically zero. Then for distinct points and any lambda != 0,
//!
//! ```text
//! lambda^T A lambda = (2 pi)^-3  integral over R^3 of  phi^(omega) |sum_j lambda_j e^(-i omega.P_j)|^2 d omega  >  0,
//! ```
//!
//! because the exponentials at distinct points are linearly independent, so the trigonometric sum
//! vanishes only on a set of measure zero. Wendland showed that the transforms of phi_{3,k} are
//! positive; they are obtained from the truncated power (1 - r)^l_+, positive definite on R^d for
//! l >= (d + 1) / 2 (Askey), by repeated integration r phi(r) dr, which keeps definiteness while
//! lowering the dimension it holds in by two and adding two orders of smoothness. The
//! restriction of a function positive definite on R^3 to a plane or a line stays positive
//! definite there, but not the converse: phi_{1,k} would not do in 3D.
//!
//! So A_ij = phi(|P_i - P_j| / R) is symmetric positive definite for every set of distinct
//! points and every R > 0, with no moment conditions needed: unlike the Green's functions,
//! the kernel alone already determines an interpolant. The linear part is kept so that U behaves
//! like the Green's-function spline far from the data: farther than R from every point the kernel
//! terms vanish and U is exactly c0 + c1 x + c2 y + c3 z, so f = f_c - U keeps the carrier's
//! shape there (see [`crate::spline::model`]).
//!
//! # The bordered system and its blocks
//!
//! ```text
//! [ A    P ] [ lambda ]   [ r ]      A (N x N) sparse, symmetric positive definite
//! [ P^T  0 ] [   c    ] = [ 0 ]      P (N x 4) dense, P_il = 1, x_i, y_i, z_i
//! ```
//!
//! The matrix as a whole is indefinite (it has 4 negative eigenvalues), but its leading block is
//! definite, which a block elimination uses: factor A = L L^T (sparse Cholesky), solve
//! A [u V] = [r P] (five right-hand sides), form the 4 x 4 Schur complement S = P^T V, which is
//! symmetric positive definite when P has full column rank (the points not all on one plane),
//! then
//!
//! ```text
//! S c = P^T u,        lambda = u - V c,
//! ```
//!
//! so that A lambda + P c = r and P^T lambda = P^T u - S c = 0. All the work is in the factor of
//! A; the border costs four more triangular solves and a 4 x 4 system. [`assemble_lower`]
//! builds the lower triangle of A in [`SymCsr`] for any set of rows, [`poly_block`] the matching
//! rows of P; the dense assembly [`crate::spline::fill_rows`] of the same system uses the same
//! formulas and is the oracle for both.
//!
//! # Support radius and sparsity
//!
//! R is given in the normalised coordinates of the spline (the data in the unit ball, see
//! "Normalisation" in [`crate::spline::system`]), so a value means the same relative size on
//! every data set. Unlike the Green's functions, Wendland kernels have a length scale, and the
//! spline depends on it:
//!
//! - **Too small a support** makes the interpolant useless between the points. U is a sum of
//!   bumps of radius R; when R is below the spacing of the points, each bump stands alone, A is
//!   nearly diagonal, and between the points U drops back to its linear part. The surface
//!   f_c - U = 0 then passes through the data but is not carried from one point to the next: it
//!   breaks into small blisters around each point on a carrier that shows through everywhere
//!   else. The support must reach well past the nearest neighbours so that the bumps overlap
//!   and blend.
//! - **Too large a support** makes the system dense. Row i holds one nonzero per point within R
//!   of P_i: on a surface about N (R / D)^2 of them (D the size of the data), in a volume
//!   N (R / D)^3. Memory and assembly grow with the nonzeros, and a banded Cholesky
//!   factorisation with the square of the band, itself proportional to the number of
//!   neighbours. At R comparable to the data's size A is a dense matrix with the cost of the
//!   Green's-function system (and, phi being nearly flat across the data, a worse condition).
//!
//! [`default_support`] therefore aims at a fixed number of neighbours per point,
//! [`DEFAULT_NEIGHBOURS`] = 30: on a surface, where a ball of radius R around a point holds about
//! pi R^2 rho points (rho points per unit area), 30 neighbours put R at about three typical
//! spacings, enough for every bump to overlap those of its neighbours' neighbours, while a row
//! holds a few dozen nonzeros. The estimate is the median, over a sample of up to
//! [`SUPPORT_SAMPLE`] points spread through the input order, of the distance from a point to its
//! target-th nearest other point, found with the octree: about half the points have at least
//! `target` others within R and half at most, and the median is robust to the few isolated
//! points of a scan that a mean would let dominate.
//!
//! # Ordering
//!
//! The number of a point is its row in A. The octree's ordering ([`Octree::order`], Algorithm
//! III of Kojekine, Savchenko, Berzin and Hagiwara, *Software tools for compactly supported
//! radial basis functions*, 2001) renumbers the points breadth first through the graph of
//! points closer than R, which gathers the nonzeros of each row next to the diagonal; the caller
//! permutes the centres and values ([`permuted`]) before assembling, and [`envelope`] measures
//! the result.

use rayon::prelude::*;

use crate::error::{Error, Result};
use crate::linalg::sparse::SymCsr;
use crate::spline::kernel::Kernel;
use crate::spline::octree::Octree;
use crate::spline::system::{dist2, monomial};

/// The number of neighbours per point that [`default_support`] aims at.
pub const DEFAULT_NEIGHBOURS: usize = 30;

/// The most points [`default_support`] measures.
pub const SUPPORT_SAMPLE: usize = 1000;

/// Nonzeros per row of A (the whole symmetric row, diagonal included) over the rows assembled.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct RowStats {
    pub rows: usize,
    pub mean: f64,
    pub min: usize,
    pub max: usize,
}

/// The support radius R (normalised coordinates) at which a point of `centres` (normalised,
/// 3 per point) has about `target` other points within R: the median over a sample of points of
/// the distance to the target-th nearest other point (see the module doc). With fewer than two
/// distinct points there is no spacing to measure and the answer is 2, the diameter of the unit
/// ball that holds the data.
///
/// Real scans are sampled unevenly: where the median radius would leave some point with no
/// other point within it (a spike of the spline there, useless between points), R grows to just
/// past the largest nearest-neighbour distance, up to `MAX_SUPPORT_GROWTH` times the median; an
/// outlier farther out than that is left for the fit to refuse with its fix (`--support`).
pub fn default_support(centres: &[f64], target: usize) -> f64 {
    let n = centres.len() / 3;
    let tree = Octree::new(centres, crate::spline::octree::DEFAULT_LEAF_CAPACITY);
    let k = target.clamp(1, n.saturating_sub(1).max(1));
    let stride = n.div_ceil(SUPPORT_SAMPLE).max(1);
    let mut d: Vec<f64> = (0..n).step_by(stride).map(|i| tree.kth_distance(tree.point(i), k + 1)).collect();
    if d.is_empty() {
        return 2.0;
    }
    let mid = d.len() / 2;
    d.select_nth_unstable_by(mid, f64::total_cmp);
    if !(d[mid] > 0.0 && d[mid].is_finite()) {
        return 2.0;
    }
    let median = d[mid];
    // the largest distance from a point to its nearest other point, over all points
    let loneliest =
        (0..n).into_par_iter().map(|i| tree.kth_distance(tree.point(i), 2)).reduce(|| 0.0, f64::max);
    median.max((1.0 + 1e-6) * loneliest.min(MAX_SUPPORT_GROWTH * median))
}

/// How far [`default_support`] may grow the median radius to give every point a neighbour.
pub const MAX_SUPPORT_GROWTH: f64 = 4.0;

/// The lower triangle of A_ij = phi(|P_i - P_j| / R), diagonal included, for the global rows
/// `rows` (any subset of 0..N, in any order; `SymCsr::rows` keeps them), from the normalised
/// centres (3 per point, in the numbering of the system) and `tree`, their octree. Entries that
/// are zero (points R or more apart) are not stored, except the diagonal. Threaded over the rows;
/// each entry is computed by exactly the formula of [`crate::spline::fill_rows`]. Also returns
/// the statistics of the whole rows.
pub fn assemble_lower(
    kernel: &Kernel,
    centres: &[f64],
    tree: &Octree,
    rows: &[usize],
) -> Result<(SymCsr, RowStats)> {
    let Some(support) = kernel.is_compact() else {
        return Err(Error::Usage(format!("kernel {} is not compactly supported", kernel.name())));
    };
    let n = centres.len() / 3;
    assert_eq!(tree.len(), n, "the octree must hold the centres");
    assert!(rows.iter().all(|&i| i < n), "rows index the centres");
    let per_row: Vec<(Vec<usize>, Vec<f64>, usize)> = rows
        .par_iter()
        .map_init(Vec::new, |found, &i| {
            let pi = &centres[3 * i..3 * i + 3];
            tree.within([pi[0], pi[1], pi[2]], support, found);
            let whole = found.len();
            found.retain(|&j| j <= i);
            found.sort_unstable();
            let mut cols = Vec::with_capacity(found.len());
            let mut vals = Vec::with_capacity(found.len());
            for &j in found.iter() {
                let v = kernel.eval_r2(dist2(pi, &centres[3 * j..3 * j + 3]))
                    + if j == i { kernel.nugget() } else { 0.0 };
                if v != 0.0 || j == i {
                    cols.push(j);
                    vals.push(v);
                }
            }
            (cols, vals, whole)
        })
        .collect();
    let nnz: usize = per_row.iter().map(|r| r.0.len()).sum();
    let mut a = SymCsr {
        n,
        rows: rows.to_vec(),
        row_ptr: Vec::with_capacity(rows.len() + 1),
        cols: Vec::with_capacity(nnz),
        vals: Vec::with_capacity(nnz),
    };
    a.row_ptr.push(0);
    let mut stats = RowStats { rows: rows.len(), min: usize::MAX, ..Default::default() };
    let mut total = 0usize;
    for (cols, vals, whole) in per_row {
        a.cols.extend(cols);
        a.vals.extend(vals);
        a.row_ptr.push(a.cols.len());
        total += whole;
        stats.min = stats.min.min(whole);
        stats.max = stats.max.max(whole);
    }
    if rows.is_empty() {
        stats.min = 0;
    } else {
        stats.mean = total as f64 / rows.len() as f64;
    }
    Ok((a, stats))
}

/// The rows `rows` of the polynomial block P (P_il = p_l(P_i), the basis of
/// [`Kernel::monomials`]: 1, x, y, z for the linear part), `rows.len()` x k, column-major.
pub fn poly_block(kernel: &Kernel, centres: &[f64], rows: &[usize]) -> Vec<f64> {
    let dim = kernel.dim();
    let monomials = kernel.monomials();
    let mut p = vec![0.0; rows.len() * monomials.len()];
    for (col, e) in p.chunks_exact_mut(rows.len().max(1)).zip(&monomials) {
        for (v, &g) in col.iter_mut().zip(rows) {
            *v = monomial(e, &centres[g * dim..(g + 1) * dim]);
        }
    }
    p
}

/// `data` (records of `width` values) in the order `perm` (`perm[new] = old`), e.g. centres
/// (width 3) or values (width 1) renumbered by [`Octree::order`].
pub fn permuted(data: &[f64], width: usize, perm: &[usize]) -> Vec<f64> {
    assert_eq!(data.len(), width * perm.len(), "one record per index");
    perm.iter().flat_map(|&old| data[old * width..(old + 1) * width].iter().copied()).collect()
}

/// The envelope of the rows held: the sum over them of (row - its first stored column), the
/// number of off-diagonal entries a profile (envelope) storage of the lower triangle keeps.
pub fn envelope(a: &SymCsr) -> usize {
    (0..a.rows.len())
        .map(|l| {
            let first = if a.row_ptr[l + 1] > a.row_ptr[l] { a.cols[a.row_ptr[l]] } else { a.rows[l] };
            a.rows[l] - first
        })
        .sum()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::spline::octree::tests::{bunny, random_points};
    use crate::spline::octree::DEFAULT_LEAF_CAPACITY;
    use crate::spline::{fill_rows, system_size};

    fn wendland(name: &str, support: f64) -> Kernel {
        Kernel::wendland(name, support).unwrap()
    }

    /// The lower triangle's stored entries, as they are, as (row, column, value).
    fn entries(a: &SymCsr) -> Vec<(usize, usize, f64)> {
        (0..a.rows.len()).flat_map(|l| a.row(l).map(move |(j, v)| (a.rows[l], j, v))).collect()
    }

    #[test]
    fn sparse_rows_equal_the_dense_rows_exactly() {
        let centres = bunny();
        let n = centres.len() / 3;
        let tree = Octree::new(&centres, DEFAULT_LEAF_CAPACITY);
        let values: Vec<f64> = (0..n).map(|i| i as f64).collect();
        // every 13th row, a few rows at the ends, and the polynomial rows of the dense system
        let mut rows: Vec<usize> = (0..n).step_by(13).collect();
        rows.extend([1, n - 2, n - 1]);
        // the last with smoothing: both assemblies add it to the diagonal alone
        for (name, support, lambda) in [
            ("wendland0", 0.05, 0.0),
            ("wendland2", 0.1, 0.0),
            ("wendland4", 0.03, 0.0),
            ("wendland2", 0.1, 0.25),
        ] {
            let kernel = wendland(name, support).with_smoothing(lambda).unwrap();
            let (a, stats) = assemble_lower(&kernel, &centres, &tree, &rows).unwrap();
            let width = system_size(&kernel, n) + 1;
            let mut dense = vec![0.0; rows.len() * width];
            fill_rows(&kernel, &centres, &values, &rows, &mut dense);
            let at = |l: usize, j: usize| dense[j * rows.len() + l];
            let mut counts = Vec::new();
            for (l, &i) in rows.iter().enumerate() {
                let stored: Vec<(usize, f64)> = a.row(l).collect();
                let want: Vec<(usize, f64)> =
                    (0..=i).filter(|&j| at(l, j) != 0.0 || j == i).map(|j| (j, at(l, j))).collect();
                assert_eq!(stored, want, "{name}, row {i}");
                assert_eq!(
                    at(l, i),
                    kernel.eval_r2(0.0) + lambda,
                    "{name}: phi(0) plus the smoothing on the diagonal"
                );
                counts.push((0..n).filter(|&j| at(l, j) != 0.0).count());
            }
            assert_eq!(a.rows, rows);
            assert_eq!(stats.max, *counts.iter().max().unwrap());
            assert_eq!(stats.min, *counts.iter().min().unwrap());
            let mean = counts.iter().sum::<usize>() as f64 / rows.len() as f64;
            assert!((stats.mean - mean).abs() < 1e-12, "{} vs {mean}", stats.mean);
            // the polynomial block is the dense system's columns N..N+4
            let p = poly_block(&kernel, &centres, &rows);
            for c in 0..4 {
                for l in 0..rows.len() {
                    assert_eq!(p[c * rows.len() + l], at(l, n + c));
                }
            }
        }
    }

    #[test]
    fn row_subsets_assemble_the_whole_matrix() {
        let centres = random_points(1500, 11);
        let tree = Octree::new(&centres, 4);
        let kernel = wendland("wendland2", 0.25);
        let all: Vec<usize> = (0..1500).collect();
        let (whole, _) = assemble_lower(&kernel, &centres, &tree, &all).unwrap();
        // the rows of three "ranks", cyclically
        let mut parts = Vec::new();
        for r in 0..3 {
            let mine: Vec<usize> = (r..1500).step_by(3).collect();
            parts.extend(entries(&assemble_lower(&kernel, &centres, &tree, &mine).unwrap().0));
        }
        parts.sort_by_key(|e| (e.0, e.1));
        assert_eq!(parts, entries(&whole));
        assert!(whole.nnz() < 1500 * 1500 / 10);
        // symmetric: (i, j) stored means |P_i - P_j| < R, which is symmetric, with j <= i
        assert!(entries(&whole).iter().all(|&(i, j, v)| j <= i && v > 0.0));
        assert!(assemble_lower(&Kernel::new(3, 2).unwrap(), &centres, &tree, &all).is_err());
    }

    /// Plain Cholesky of a dense symmetric matrix (column-major); None at a pivot that is not
    /// positive.
    fn cholesky(a: &[f64], n: usize) -> Option<Vec<f64>> {
        let mut l = vec![0.0; n * n];
        for j in 0..n {
            let d = a[j * n + j] - (0..j).map(|k| l[k * n + j] * l[k * n + j]).sum::<f64>();
            if !(d > 0.0) {
                return None;
            }
            l[j * n + j] = d.sqrt();
            for i in j + 1..n {
                let s = a[j * n + i] - (0..j).map(|k| l[k * n + i] * l[k * n + j]).sum::<f64>();
                l[j * n + i] = s / l[j * n + j];
            }
        }
        Some(l)
    }

    fn cholesky_solve(l: &[f64], n: usize, b: &mut [f64]) {
        for i in 0..n {
            b[i] = (b[i] - (0..i).map(|k| l[k * n + i] * b[k]).sum::<f64>()) / l[i * n + i];
        }
        for i in (0..n).rev() {
            b[i] = (b[i] - (i + 1..n).map(|k| l[i * n + k] * b[k]).sum::<f64>()) / l[i * n + i];
        }
    }

    #[test]
    fn wendland_matrices_are_positive_definite_and_the_block_elimination_interpolates() {
        let centres = random_points(300, 5);
        let n = 300;
        let values: Vec<f64> = centres.chunks_exact(3).map(|p| 1.0 - p[0] * p[0] - 0.5 * p[1]).collect();
        for name in ["wendland0", "wendland2", "wendland4"] {
            // supports from nearly diagonal to nearly full
            for support in [0.1, 0.5, 3.0] {
                let kernel = wendland(name, support);
                let (m, b) = crate::spline::full_system(&kernel, &centres, &values);
                let nk = n + 4;
                let a: Vec<f64> = (0..n).flat_map(|j| m[j * nk..j * nk + n].iter().copied()).collect();
                let l = cholesky(&a, n).unwrap_or_else(|| panic!("{name} R = {support}: not definite"));
                // A [u V] = [r P]; S = P^T V; S c = P^T u; lambda = u - V c
                let rows: Vec<usize> = (0..n).collect();
                let p = poly_block(&kernel, &centres, &rows);
                let mut u = values.clone();
                cholesky_solve(&l, n, &mut u);
                let mut v = p.clone();
                for col in v.chunks_exact_mut(n) {
                    cholesky_solve(&l, n, col);
                }
                let dot = |x: &[f64], y: &[f64]| x.iter().zip(y).map(|(a, b)| a * b).sum::<f64>();
                let s: Vec<f64> =
                    (0..16).map(|e| dot(&p[(e / 4) * n..][..n], &v[(e % 4) * n..][..n])).collect();
                let rhs: Vec<f64> = (0..4).map(|c| dot(&p[c * n..][..n], &u)).collect();
                let sm = faer::MatRef::from_column_major_slice(&s, 4, 4);
                let c = crate::linalg::dense::lu_solve(sm, &rhs).unwrap();
                let lambda: Vec<f64> =
                    (0..n).map(|i| u[i] - (0..4).map(|q| v[q * n + i] * c[q]).sum::<f64>()).collect();
                let mut x = lambda;
                x.extend(&c);
                let full = faer::MatRef::from_column_major_slice(&m, nk, nk);
                let res = crate::linalg::dense::relative_residual(full, &x, &b);
                assert!(res < 1e-9, "{name} R = {support}: residual {res}");
            }
        }
    }

    #[test]
    fn the_default_support_gives_about_the_target_number_of_neighbours() {
        for (centres, what) in [(bunny(), "bunny"), (random_points(4000, 9), "cube")] {
            let tree = Octree::new(&centres, DEFAULT_LEAF_CAPACITY);
            let n = centres.len() / 3;
            for target in [10, DEFAULT_NEIGHBOURS, 80] {
                let r = default_support(&centres, target);
                let mut found = Vec::new();
                let mut counts: Vec<usize> = (0..n)
                    .map(|i| {
                        tree.within(tree.point(i), r, &mut found);
                        found.len() - 1
                    })
                    .collect();
                counts.sort_unstable();
                let median = counts[n / 2];
                assert!(
                    median.abs_diff(target) <= target / 5 + 1,
                    "{what}: target {target}, median {median}"
                );
                crate::note!("{what}: target {target}: R = {r:.4}, median {median} neighbours");
            }
        }
        assert_eq!(default_support(&[0.0, 0.0, 0.0], 30), 2.0);
    }

    #[test]
    fn the_octree_ordering_shrinks_the_envelope_of_the_assembled_matrix() {
        let centres = bunny();
        let n = centres.len() / 3;
        let kernel = wendland("wendland2", default_support(&centres, DEFAULT_NEIGHBOURS));
        let rows: Vec<usize> = (0..n).collect();
        let tree = Octree::new(&centres, DEFAULT_LEAF_CAPACITY);
        let (a, stats) = assemble_lower(&kernel, &centres, &tree, &rows).unwrap();
        let perm = tree.order(kernel.is_compact().unwrap());
        let sorted = permuted(&centres, 3, &perm);
        assert_eq!(&sorted[3..6], &centres[3 * perm[1]..3 * perm[1] + 3]);
        let (b, stats_b) = assemble_lower(&kernel, &sorted, &Octree::new(&sorted, 10), &rows).unwrap();
        assert_eq!(a.nnz(), b.nnz());
        assert_eq!(stats, stats_b);
        let (before, after) = (envelope(&a), envelope(&b));
        crate::note!(
            "bunny, {}: nonzeros per row mean {:.1}, max {}; lower triangle {} stored; envelope {before} -> {after}",
            kernel.name(),
            stats.mean,
            stats.max,
            a.nnz()
        );
        assert!(4 * after < before);
    }
}
