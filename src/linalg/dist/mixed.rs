//! The single-precision LU factors of a mixed-precision solve, applied in double precision.
//!
//! The matrix M (order n, f64, row-cyclic) is rounded to f32 and factored by the row-cyclic LU
//! (`lu`), P M' = L U with M' = fl32(M): the same flops as the f64 factorisation at twice the
//! GEMM rate and half the bytes on the wire. The factorisation leaves its factors in block form:
//! per panel of rows k0..k1, L11\U11 in the diagonal block, A12 right of it in the same rows, and
//! W = L21 L11^-1 in its columns below it. It leaves column j of W where the interchanges of its
//! own panel put it; here the interchanges of the later panels are applied to it afterwards (one
//! pass per panel over its columns), so that the stored W belongs to P M' with P the product of
//! all the interchanges.
//!
//! A solve with the factors, z = M'^-1 r, takes r and returns z replicated on every rank and
//! computes in f64 with the f32 entries read and widened on the fly: the factors are only an
//! approximate inverse, but rounding the right-hand side and the intermediate vectors to f32 would
//! add a relative error of 6e-8 to every correction on top of that. With y = P r, block
//! elimination gives, panel by panel from the first, c1 = the panel's current entries of y and
//! y2 -= W c1 for the rows below; then, from the last panel back, z1 = U11^-1 L11^-1 (c1 - A12
//! z2). For a panel the owners' current entries are all-gathered (b values), the diagonal block
//! (gathered once, after the factorisation) is solved redundantly on every rank, and each rank
//! updates its own entries below the panel (forward, with W) or above it (backward, with A12)
//! from its own rows of the factors. Two small all-gathers per panel; n^2 / p multiply-adds per
//! rank.
//!
//! The residual of the refinement, r = b - M x, is computed from the f64 rows that each rank
//! keeps: each rank its own rows (one GEMV; for a symmetric M one pass over the lower triangle of
//! its rows and a sum over the ranks, see [`Operator`]), then one all-gather of the n values from
//! their owners. Every vector of the refinement is thus replicated and identical on every rank,
//! and every decision taken from it (norms, stopping rules) is the same everywhere without a
//! further collective.

use crate::linalg::gemm::gemm;
use faer::{Accum, MatMut, MatRef, Par};

use super::backsub::solve_unit_lower_rows;
use super::lu::lu_factor;
use super::scalar::update_widened;
use super::solver::Job;
use super::system::{all_gather_rows, LocalRows};
use crate::error::Result;
use crate::par::Comm;
use crate::simd::on_widest_unit;

/// An approximate inverse of the f64 system, from factors of lower precision: what a refinement
/// needs of them.
pub trait Approximate {
    /// z ~ M^-1 r for the replicated r; z replicated. Collective.
    fn apply(&self, comm: &dyn Comm, r: &[f64]) -> Vec<f64>;
}

/// The f32 LU factors of a row-cyclic matrix in block form (see the module documentation), W
/// row-interchanged.
pub struct Factors {
    rows: LocalRows<f32>,
    swaps: Vec<(usize, usize)>,
    /// Panel boundaries 0 = p_0 < p_1 < ... < p_m = n.
    panels: Vec<usize>,
    /// Per panel, its diagonal block of L\U (row-major, widened to f64), on every rank.
    diag: Vec<Vec<f64>>,
}

impl Factors {
    /// Rounds the matrix of `m` (all columns but the right-hand side) to f32 and factors it.
    /// Collective; a pivot below n eps32 max |m_ij| is an error (the same on every rank).
    pub fn new(job: &Job<'_>, m: &LocalRows) -> Result<Factors> {
        let comm = job.comm;
        let lay = m.layout;
        let n = lay.n;
        // the right-hand side column comes along (the factors act on residuals, not on it)
        let mut rows: LocalRows<f32> = m.convert();
        let nb = job.panel.max(1);
        let swaps = lu_factor(job, &mut rows)?;
        let panels: Vec<usize> = (0..n).step_by(nb).chain([n]).collect();
        // W row-interchanged: the interchanges of the later panels reach each panel's columns
        for w in panels.windows(2) {
            let later = &swaps[w[1].min(swaps.len())..];
            rows.permute_rows(comm, later, w[0], w[1]);
        }
        let diag = panels
            .windows(2)
            .map(|w| rows.gather_rows(comm, w[0], w[1], w[0], w[1]).iter().map(|&v| v as f64).collect())
            .collect();
        Ok(Factors { rows, swaps, panels, diag })
    }
}

impl Approximate for Factors {
    /// z = M'^-1 r from the block form: P r, then the forward pass with W, then per panel from
    /// the last L11^-1, U11^-1 and the update of the rows above with A12.
    fn apply(&self, comm: &dyn Comm, r: &[f64]) -> Vec<f64> {
        let lay = self.rows.layout;
        let (n, ld) = (lay.n, self.rows.ld());
        let data = &self.rows.data;
        let mut y = r.to_vec();
        for &(a, b) in &self.swaps {
            y.swap(a, b);
        }
        // this rank's entries of y, updated as the panels pass
        let mut own: Vec<f64> = (0..ld).map(|l| y[lay.global(l)]).collect();
        let gather = |own: &[f64], g0: usize, g1: usize| -> Vec<f64> {
            let (l0, l1) = (lay.first_local_from(g0), lay.first_local_from(g1));
            all_gather_rows(comm, lay, &own[l0..l1], g0..g1, 1)
        };
        // forward, in block form: the rows below each panel take - W c1, with c1 the panel's
        // current entries, which stay as they are (L11^-1 is applied on the way back)
        for w in self.panels.windows(2) {
            let (k0, k1) = (w[0], w[1]);
            let yp = gather(&own, k0, k1);
            let t0 = lay.first_local_from(k1);
            let col = |c: usize| &data[c * ld + t0..(c + 1) * ld];
            update_widened(&mut own[t0..], (k0, k1), &yp, col);
        }
        // backward: z1 = U11^-1 L11^-1 (c1 - A12 z2), the rows above each panel updated with
        // its columns of A12 as z becomes known
        let mut z = vec![0.0; n];
        for (w, d) in self.panels.windows(2).zip(&self.diag).rev() {
            let (k0, k1) = (w[0], w[1]);
            let b = k1 - k0;
            let mut zb = gather(&own, k0, k1);
            solve_unit_lower_rows(d, b, &mut zb);
            for i in (0..b).rev() {
                let s: f64 = (i + 1..b).map(|j| d[i * b + j] * zb[j]).sum();
                zb[i] = (zb[i] - s) / d[i * b + i];
            }
            let above = lay.first_local_from(k0);
            let col = |c: usize| &data[c * ld..c * ld + above];
            update_widened(&mut own[..above], (k0, k1), &zb, col);
            z[k0..k1].copy_from_slice(&zb);
        }
        z
    }
}

/// The f64 matrix a refinement computes its residuals with: this rank's rows of M, and the
/// norms the stopping rules need.
///
/// A symmetric M (the bordered spline system that the projected Cholesky solves) is read in its
/// lower triangle alone, as the Cholesky itself reads it: each entry m_gc (g >= c) of this rank's
/// rows serves row g (m_gc x_c) and, below the diagonal, row c (m_gc x_g). A product is bound by
/// the bytes it reads from memory, so reading half of them halves it. The contributions to rows
/// of other ranks are summed over the ranks; each owner then takes its own rows' sums, and one
/// all-gather makes them replicated, so every rank holds the same values whatever order the sum
/// took.
pub struct Operator<'a> {
    rows: &'a LocalRows,
    par: Par,
    symmetric: bool,
    /// ||M||_inf over all rows (the right-hand side excluded).
    pub norm_inf: f64,
}

impl<'a> Operator<'a> {
    /// The operator and the residual b - M x of a first solution x (replicated), from one pass
    /// over the rows (over their lower triangle where `symmetric`): the norm takes the same
    /// entries as the product, and a second pass over a matrix of hundreds of megabytes costs as
    /// long as the product itself. Collective.
    pub fn with_residual(
        comm: &dyn Comm,
        rows: &'a LocalRows,
        par: Par,
        x: &[f64],
        symmetric: bool,
    ) -> (Self, Vec<f64>) {
        let (lay, ld) = (rows.layout, rows.ld());
        let n = lay.n;
        if symmetric {
            let (r, sums) = lower_pass::<true>(comm, rows, x, (1.0, -1.0));
            let norm_inf = sums.iter().fold(0.0f64, |a, &s| a.max(s));
            return (Operator { rows, par, symmetric, norm_inf }, r);
        }
        let mut own = rows.data[n * ld..(n + 1) * ld].to_vec();
        let mut sums = vec![0.0f64; ld];
        let col = |c: usize| &rows.data[c * ld..(c + 1) * ld];
        let mut c = 0;
        // four columns per pass over this rank's rows, then the rest one by one
        while c + 4 <= n {
            let (m0, m1, m2, m3) = (col(c), col(c + 1), col(c + 2), col(c + 3));
            let (x0, x1, x2, x3) = (x[c], x[c + 1], x[c + 2], x[c + 3]);
            for l in 0..ld {
                let (a, b, d, e) = (m0[l], m1[l], m2[l], m3[l]);
                own[l] -= a * x0 + b * x1 + d * x2 + e * x3;
                sums[l] += a.abs() + b.abs() + d.abs() + e.abs();
            }
            c += 4;
        }
        for c in c..n {
            for ((o, s), &a) in own.iter_mut().zip(sums.iter_mut()).zip(col(c)) {
                *o -= a * x[c];
                *s += a.abs();
            }
        }
        let mut m = [sums.iter().fold(0.0f64, |a, &s| a.max(s))];
        comm.max_f64(&mut m);
        let r = all_gather_rows(comm, lay, &own, 0..n, 1);
        (Operator { rows, par, symmetric, norm_inf: m[0] }, r)
    }

    /// The right-hand side of `rows`, replicated. Collective.
    pub fn rhs_of(comm: &dyn Comm, rows: &LocalRows) -> Vec<f64> {
        let (lay, ld) = (rows.layout, rows.ld());
        let b = &rows.data[lay.n * ld..(lay.n + 1) * ld];
        all_gather_rows(comm, lay, b, 0..lay.n, 1)
    }

    /// b - M x, replicated. Collective.
    pub fn residual(&self, comm: &dyn Comm, x: &[f64]) -> Vec<f64> {
        self.combine(comm, 1.0, -1.0, x)
    }

    /// M x, replicated. Collective.
    pub fn product(&self, comm: &dyn Comm, x: &[f64]) -> Vec<f64> {
        self.combine(comm, 0.0, 1.0, x)
    }

    /// alpha b + beta M x, replicated. Collective.
    fn combine(&self, comm: &dyn Comm, alpha: f64, beta: f64, x: &[f64]) -> Vec<f64> {
        if self.symmetric {
            return lower_pass::<false>(comm, self.rows, x, (alpha, beta)).0;
        }
        let (lay, ld) = (self.rows.layout, self.rows.ld());
        let n = lay.n;
        let mut own: Vec<f64> = self.rows.data[n * ld..(n + 1) * ld].iter().map(|b| alpha * b).collect();
        if ld > 0 {
            let m = MatRef::from_column_major_slice(&self.rows.data[..n * ld], ld, n);
            let xv = MatRef::from_column_major_slice(x, n, 1);
            let dst = MatMut::from_column_major_slice_mut(&mut own, ld, 1);
            gemm(dst, Accum::Add, m, xv, beta, self.par);
        }
        all_gather_rows(comm, lay, &own, 0..n, 1)
    }
}

/// alpha b + beta M x for a symmetric M from the lower triangle of this rank's rows, replicated,
/// and with `NORMS` the row sums of |M| (replicated; empty without). Collective.
fn lower_pass<const NORMS: bool>(
    comm: &dyn Comm,
    rows: &LocalRows,
    x: &[f64],
    (alpha, beta): (f64, f64),
) -> (Vec<f64>, Vec<f64>) {
    let (lay, ld) = (rows.layout, rows.ld());
    let n = lay.n;
    let col = |c: usize| &rows.data[c * ld..(c + 1) * ld];
    // x in this rank's local order, for the products of the columns below the diagonal
    let xl: Vec<f64> = (0..ld).map(|l| x[lay.global(l)]).collect();
    // own[l]: sum over c <= g(l) of m_gc x_c; across[c]: sum over this rank's g > c of m_gc x_g
    let (mut own, mut across) = (vec![0.0; ld], vec![0.0; n]);
    let (mut own_abs, mut across_abs) = if NORMS { (vec![0.0; ld], vec![0.0; n]) } else { (vec![], vec![]) };
    let mut c = 0;
    while c < n {
        let w = (n - c).min(LOWER_PER_PASS);
        // the rows g in c..c+w meet the diagonal within these columns: entry by entry
        let below = lay.first_local_from(c + w);
        for l in lay.first_local_from(c)..below {
            let g = lay.global(l);
            for cc in c..(c + w).min(g + 1) {
                let a = col(cc)[l];
                own[l] += a * x[cc];
                if NORMS {
                    own_abs[l] += a.abs();
                }
                if g > cc {
                    across[cc] += a * xl[l];
                    if NORMS {
                        across_abs[cc] += a.abs();
                    }
                }
            }
        }
        // the rows below all of them
        let tail = |c: usize| &col(c)[below..];
        let (own_t, xl_t) = (&mut own[below..], &xl[below..]);
        if w == LOWER_PER_PASS {
            let cols = std::array::from_fn(|t| tail(c + t));
            let xc = std::array::from_fn(|t| x[c + t]);
            let abs_t = if NORMS { &mut own_abs[below..] } else { &mut [][..] };
            let (d, s) = lower_columns::<LOWER_PER_PASS, NORMS>(cols, xc, xl_t, own_t, abs_t);
            for t in 0..w {
                across[c + t] += d[t];
                if NORMS {
                    across_abs[c + t] += s[t];
                }
            }
        } else {
            for t in 0..w {
                let abs_t = if NORMS { &mut own_abs[below..] } else { &mut [][..] };
                let (d, s) = lower_columns::<1, NORMS>([tail(c + t)], [x[c + t]], xl_t, &mut *own_t, abs_t);
                across[c + t] += d[0];
                if NORMS {
                    across_abs[c + t] += s[0];
                }
            }
        }
        c += w;
    }
    // this rank's shares of every row, summed over the ranks; b enters on its owner
    let b = &rows.data[n * ld..(n + 1) * ld];
    let mut sums = across.iter().map(|v| beta * v).collect::<Vec<f64>>();
    if NORMS {
        sums.extend_from_slice(&across_abs);
    }
    for l in 0..ld {
        let g = lay.global(l);
        sums[g] += alpha * b[l] + beta * own[l];
        if NORMS {
            sums[n + g] += own_abs[l];
        }
    }
    comm.sum_f64(&mut sums);
    // each owner's sums of its own rows, all-gathered: the same values on every rank
    let parts = if NORMS { 2 } else { 1 };
    let mut mine = Vec::with_capacity(ld * parts);
    for l in 0..ld {
        let g = lay.global(l);
        mine.push(sums[g]);
        if NORMS {
            mine.push(sums[n + g]);
        }
    }
    let both = all_gather_rows(comm, lay, &mine, 0..n, parts);
    if NORMS {
        (both.iter().step_by(2).copied().collect(), both.iter().skip(1).step_by(2).copied().collect())
    } else {
        (both, Vec::new())
    }
}

/// Columns per pass of [`lower_pass`].
const LOWER_PER_PASS: usize = 4;

on_widest_unit! {
    /// For W columns of rows below all their diagonal entries: own += sum_w x_w col_w (and
    /// own_abs += sum_w |col_w| with `NORMS`); returns col_w . xl (and the sums of |col_w|), with
    /// eight running sums per column (one waits for each addition before the next).
    fn lower_columns[const W: usize, const NORMS: bool][W, NORMS](
        cols: [&[f64]; W],
        xc: [f64; W],
        xl: &[f64],
        own: &mut [f64],
        own_abs: &mut [f64],
    ) -> ([f64; W], [f64; W]) = lower_columns_portable;
}

#[inline(always)]
fn lower_columns_portable<const W: usize, const NORMS: bool>(
    cols: [&[f64]; W],
    xc: [f64; W],
    xl: &[f64],
    own: &mut [f64],
    own_abs: &mut [f64],
) -> ([f64; W], [f64; W]) {
    let len = xl.len();
    let full = len / 8 * 8;
    let (mut dot, mut abs) = ([[0.0f64; 8]; W], [[0.0f64; 8]; W]);
    for i in (0..full).step_by(8) {
        let xs = &xl[i..i + 8];
        let o = &mut own[i..i + 8];
        let mut s = [0.0f64; 8];
        let mut sa = [0.0f64; 8];
        for w in 0..W {
            let cs = &cols[w][i..i + 8];
            for t in 0..8 {
                s[t] += cs[t] * xc[w];
                dot[w][t] += cs[t] * xs[t];
                if NORMS {
                    sa[t] += cs[t].abs();
                    abs[w][t] += cs[t].abs();
                }
            }
        }
        for t in 0..8 {
            o[t] += s[t];
        }
        if NORMS {
            let oa = &mut own_abs[i..i + 8];
            for t in 0..8 {
                oa[t] += sa[t];
            }
        }
    }
    let (mut d, mut a) = ([0.0; W], [0.0; W]);
    for w in 0..W {
        d[w] = dot[w].iter().sum::<f64>();
        a[w] = abs[w].iter().sum::<f64>();
        for i in full..len {
            let v = cols[w][i];
            own[i] += v * xc[w];
            d[w] += v * xl[i];
            if NORMS {
                own_abs[i] += v.abs();
                a[w] += v.abs();
            }
        }
    }
    (d, a)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::linalg::dist::test_support::bunny_rows;
    use crate::par::Solo;

    /// The residual b - M x and ||M||_inf of the one pass, and the products of the operator,
    /// agree with a plain computation over all entries, read from all of M and from its lower
    /// triangle, on a system whose order is not a multiple of the columns per pass.
    #[test]
    fn the_residuals_products_and_norm_match_a_plain_computation() {
        let mut m = bunny_rows(40);
        let n = m.layout.n;
        assert!(!n.is_multiple_of(4), "order {n}: the remainder columns would go untested");
        // the kernel r vanishes on the diagonal: a smoothing term makes it count
        for i in 0..n {
            m.data[i * n + i] += 0.5 + i as f64 * 0.01;
        }
        let x: Vec<f64> = (0..n).map(|i| (i as f64 * 0.37).cos()).collect();
        let y: Vec<f64> = (0..n).map(|i| (i as f64 * 0.11).sin()).collect();
        let product = |v: &[f64], i: usize| (0..n).map(|j| m.get(i, j) * v[j]).sum::<f64>();
        let norm = (0..n).map(|i| (0..n).map(|j| m.get(i, j).abs()).sum::<f64>()).fold(0.0, f64::max);
        let close = |got: f64, want: f64, what: &str| {
            assert!((got - want).abs() <= 1e-12 * (1.0 + want.abs()), "{what}: {got} against {want}");
        };
        for symmetric in [false, true] {
            let (op, r) = Operator::with_residual(&Solo, &m, Par::Seq, &x, symmetric);
            let (again, p) = (op.residual(&Solo, &y), op.product(&Solo, &y));
            for i in 0..n {
                let what = format!("row {i}, symmetric {symmetric}");
                close(r[i], m.get(i, n) - product(&x, i), &format!("first residual, {what}"));
                close(again[i], m.get(i, n) - product(&y, i), &format!("residual, {what}"));
                close(p[i], product(&y, i), &format!("product, {what}"));
            }
            close(op.norm_inf, norm, &format!("norm, symmetric {symmetric}"));
        }
    }
}
