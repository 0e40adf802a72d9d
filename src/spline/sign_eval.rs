//! Evaluation of f = c - U, c a function evaluated in double precision (the carrier) and U a
//! spline with the kernel r, where its sign matters more than its last digits: the radial sums
//! in single precision, with a bound on their error, and again in double precision at the points
//! whose value lies within that bound of zero.
//!
//! The surface checks of a fit ([`crate::surface::blobs`], [`crate::surface::turns`]) sample f
//! on a lattice of some 10^5 nodes several times per fit; they read the sign of every node and
//! the value of a few (as targets, to a few digits). In single precision the radial sums hold
//! twice the lanes per vector register and their square roots cost less, so a lattice takes
//! about half the time.
//!
//! # The bound
//!
//! With u = 2^-24 the unit roundoff of single precision, a node x and a centre c_j rounded to
//! single precision (normalised coordinates, so every coordinate is at most P in magnitude, P
//! the largest of the node's and the centres'), each difference x_k - c_jk is off by at most
//! u (|x_k| + |c_jk|) + u |x_k - c_jk| <= 4.02 u P, the difference vector by at most 7 u P, and
//! the root of the sum of squares (two multiply-adds and a square root, each rounded once) adds
//! at most 2.1 u r_j: |r^_j - r_j| <= 7 u P + 2.2 u r_j. The weight rounded to single precision
//! is off by u |w_j|, so the product w^_j r^_j is off by at most |w_j| (7 u P + 3.3 u r_j). Each
//! lane accumulates the products of a chunk of 512 centres (m = 32 of them, fewer where the
//! spline has fewer centres) by multiply-adds, each rounded once to at most u times the chunk's
//! sum of |products| so far, m u sum_j |w_j| r_j in all over the chunks; the chunks' sums are
//! added in double precision, whose error is below 2^-29 of these as long as there are fewer
//! than some 10^7 chunks. With W = sum_j |w_j| and R the largest distance from x to a corner of
//! the centres' bounding box (r_j <= R):
//!
//! ```text
//!     |U^(x) - U(x)| <= u W ((m + 3.3) R + 7 P)  <  2 u W ((m + 4) R + 8 P) = B(x).
//! ```
//!
//! The weights are divided by a power of two that brings the largest into [1/2, 1) before they
//! are rounded (exactly, so the bound is unchanged, and the sum is multiplied back): single
//! precision's range (1e-38 to 3e38) would otherwise lose the weights of data in very small or
//! very large units; a weight that still falls below its normal range is off by at most 2^-149
//! times the scale, far below the bound. The factor 2 covers the double-precision sum's own error (about 2^-29 of the single one's)
//! and the polynomial and carrier, which are evaluated in double precision alike on both paths.
//! A node whose single-precision value lies within B(x) of zero is evaluated again by
//! [`Evaluator`]: its value is then the double-precision one, bit for bit, and every other node
//! has that value's sign. On 400 bunny samples with their off points (735 centres, W = 27,000)
//! B is about 0.2 against values of the carrier's size (up to 150 there, changing by 7 a
//! lattice step at the surface); the chunks keep B from growing with the number of centres.
//!
//! The sums run over the centres in one fixed order whatever the blocking, the thread or the
//! rank, with the same multiply-adds on every vector unit (see [`crate::simd`]), so values are
//! reproducible bit for bit, as those of [`Evaluator`] are. Splines of other kernels (r^3, the
//! compactly supported ones, 2D and 1D) are evaluated in double precision throughout.

use crate::simd::on_widest_unit;
use crate::spline::evaluator::{poly_value, reduce_lanes, Evaluator, Form, LANES};
use crate::spline::Spline;

/// Lanes of the single-precision radial sums: one 512-bit register.
const LANES32: usize = 2 * LANES;
/// Centres per block: 4 arrays x 1024 x 4 bytes = 16 KiB, in L1 with room to spare.
const BLOCK32: usize = 1024;
/// Centres whose products a lane accumulates in single precision before its sum is added to the
/// lane's double-precision sum: 32 per lane, which bounds the accumulation error whatever the
/// number of centres.
const CHUNK32: usize = 512;
const _: () = assert!(BLOCK32.is_multiple_of(CHUNK32) && CHUNK32.is_multiple_of(LANES32));
/// Unit roundoff of single precision.
const U32: f64 = 1.0 / (1u64 << 24) as f64;

/// A spline prepared for [`SignEvaluator::signed_row`].
pub struct SignEvaluator<'a> {
    exact: Evaluator<'a>,
    spline: &'a Spline,
    single: Option<Single>,
}

/// The centres and weights in single precision (x, y, z and w apart, padded to whole lanes with
/// zero weights) and the constants of the bound.
struct Single {
    c: [Vec<f32>; 4],
    /// The power of two the weights in `c` were divided by.
    scale: f64,
    /// W: the sum of |w_j|.
    abs_weights: f64,
    /// m: the products each lane accumulates in single precision, at most [`CHUNK32`] / 16.
    terms: usize,
    /// The centres' bounding box (normalised).
    lo: [f64; 3],
    hi: [f64; 3],
    /// The largest magnitude of a centre's coordinate (normalised).
    reach: f64,
}

impl<'a> SignEvaluator<'a> {
    pub fn new(spline: &'a Spline) -> Self {
        let exact = Evaluator::new(spline);
        let largest = spline.weights.iter().fold(0.0f64, |m, w| m.max(w.abs()));
        let usable = Form::of(spline) == Some(Form::R1) && largest > 0.0 && largest.is_finite();
        let single = usable.then(|| {
            // the weights scaled by a power of two into [1/2, 1) at most, whatever the data's
            // units: single precision holds magnitudes from 1e-38 to 3e38 alone
            let scale = 2f64.powi(largest.log2().floor() as i32 + 1);
            let n = spline.len();
            let padded = n.div_ceil(LANES32) * LANES32;
            let mut c = [0; 4].map(|_| vec![0.0f32; padded]);
            let (mut lo, mut hi, mut reach) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3], 0.0f64);
            for (i, p) in spline.centres.chunks_exact(3).enumerate() {
                for d in 0..3 {
                    c[d][i] = p[d] as f32;
                    lo[d] = lo[d].min(p[d]);
                    hi[d] = hi[d].max(p[d]);
                    reach = reach.max(p[d].abs());
                }
                c[3][i] = (spline.weights[i] / scale) as f32;
            }
            let abs_weights = spline.weights.iter().map(|w| w.abs()).sum();
            Single { c, scale, abs_weights, terms: padded.min(CHUNK32) / LANES32, lo, hi, reach }
        });
        SignEvaluator { exact, spline, single }
    }

    /// `out[i] = c(x_i) - U(x_i)` at the points `x_i = (xs[i], y, z)` (caller's coordinates),
    /// with the sign double precision gives it; the value is double precision's, bit for bit,
    /// where it lies within the single-precision bound of zero, else within that bound of it
    /// (see the module doc). Returns how many points were evaluated in double precision.
    pub fn signed_row(
        &self,
        xs: &[f64],
        y: f64,
        z: f64,
        c: impl Fn(&[f64; 3]) -> f64,
        out: &mut [f64],
    ) -> usize {
        let out = &mut out[..xs.len()];
        let Some(single) = &self.single else {
            self.exact.eval_row(xs, y, z, out);
            for (o, &x) in out.iter_mut().zip(xs) {
                *o = c(&[x, y, z]) - *o;
            }
            return xs.len();
        };
        let sp = self.spline;
        let norm = &sp.norm;
        let yn = (y - norm.centre[1]) / norm.scale;
        let zn = (z - norm.centre[2]) / norm.scale;
        let xn: Vec<f64> = xs.iter().map(|x| (x - norm.centre[0]) / norm.scale).collect();
        let x32: Vec<f32> = xn.iter().map(|&x| x as f32).collect();
        let mut acc = vec![[0.0f64; LANES32]; xs.len()];
        let [cx, cy, cz, w] = &single.c;
        radial_sums32(&x32, [yn as f32, zn as f32], [cx, cy, cz, w], &mut acc);
        let mut redo = Vec::new();
        for (i, ((o, a), &x)) in out.iter_mut().zip(&acc).zip(&xn).enumerate() {
            let lanes = |h: usize| -> [f64; LANES] { std::array::from_fn(|l| a[h * LANES + l]) };
            let s = (reduce_lanes(&lanes(0)) + reduce_lanes(&lanes(1))) * single.scale;
            let u = s + poly_value(sp, [x, yn, zn]);
            *o = c(&[xs[i], y, z]) - u;
            if o.abs() <= single.bound([x, yn, zn]) {
                redo.push(i);
            }
        }
        if !redo.is_empty() {
            let again: Vec<f64> = redo.iter().map(|&i| xs[i]).collect();
            let mut exact = vec![0.0; again.len()];
            self.exact.eval_row(&again, y, z, &mut exact);
            for ((&i, u), &x) in redo.iter().zip(&exact).zip(&again) {
                out[i] = c(&[x, y, z]) - u;
            }
        }
        redo.len()
    }
}

impl Single {
    /// B(x), the bound on the single-precision radial sum's error at the normalised point `x`.
    fn bound(&self, x: [f64; 3]) -> f64 {
        let far: f64 = (0..3)
            .map(|d| (x[d] - self.lo[d]).abs().max((x[d] - self.hi[d]).abs()).powi(2))
            .sum::<f64>()
            .sqrt();
        let reach = x.iter().fold(self.reach, |m, v| m.max(v.abs()));
        2.0 * U32 * self.abs_weights * ((self.terms + 4) as f64 * far + 8.0 * reach)
    }
}

on_widest_unit! {
    /// The single-precision radial sums sum_j w_j |x - c_j| at the points `(xs[i], yz[0], yz[1])`
    /// into the lanes `acc[i]` (centre j into lane j mod 16, in the order of j; each
    /// [`CHUNK32`] centres summed in single precision, those sums in double), compiled for the
    /// widest vector unit the CPU has (the same portable code, so every path gives the same bits).
    fn radial_sums32[][](xs: &[f32], yz: [f32; 2], c: [&[f32]; 4], acc: &mut [[f64; LANES32]]) = radial_sums32_portable;
}

#[inline(always)]
fn radial_sums32_portable(
    xs: &[f32],
    [y, z]: [f32; 2],
    [cx, cy, cz, w]: [&[f32]; 4],
    acc: &mut [[f64; LANES32]],
) {
    let n = w.len();
    let mut b0 = 0;
    while b0 < n {
        let b1 = (b0 + BLOCK32).min(n);
        for (&x, a) in xs.iter().zip(acc.iter_mut()) {
            let mut c0 = b0;
            while c0 < b1 {
                let c1 = (c0 + CHUNK32).min(b1);
                let (px, py, pz, pw) = (&cx[c0..c1], &cy[c0..c1], &cz[c0..c1], &w[c0..c1]);
                let mut s = [0.0f32; LANES32];
                let groups = px.chunks_exact(LANES32).zip(py.chunks_exact(LANES32));
                for (((gx, gy), gz), gw) in groups.zip(pz.chunks_exact(LANES32)).zip(pw.chunks_exact(LANES32))
                {
                    for l in 0..LANES32 {
                        let (dx, dy, dz) = (x - gx[l], y - gy[l], z - gz[l]);
                        let r2 = dz.mul_add(dz, dy.mul_add(dy, dx * dx));
                        s[l] = gw[l].mul_add(r2.sqrt(), s[l]);
                    }
                }
                add_widened(a, &s);
                c0 = c1;
            }
        }
        b0 = b1;
    }
}

/// `a[l] += s[l]` in double precision, lane by lane. Kept out of line on purpose: inlined into
/// [`radial_sums32_portable`], the vectoriser gives the whole loop the width of these double
/// additions (8 lanes in a 512-bit register), and the single-precision sums then run at half
/// the width the unit has (measured: about 1.9 times the time on an AVX-512 machine). The sums
/// are the same either way, lane by lane; only the width of the instructions differs.
#[inline(never)]
fn add_widened(a: &mut [f64; LANES32], s: &[f32; LANES32]) {
    for (a, &s) in a.iter_mut().zip(s) {
        *a += f64::from(s);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A spline of `n` random centres in the unit box with weights that sum to zero, of size
    /// `scale` (the oscillating weights of an interpolant, whose sum of |w| is far above the
    /// values).
    fn spline(order: usize, n: usize, scale: f64) -> Spline {
        let mut sp = crate::spline::evaluator::tests::spline(order, n);
        let mean = sp.weights.iter().sum::<f64>() / n as f64;
        sp.weights.iter_mut().for_each(|w| *w = scale * (*w - mean));
        sp
    }

    #[test]
    fn values_are_within_the_bound_and_signs_are_double_precisions() {
        for n in [1, 15, 16, 17, 511, 512, 513, 735, 1024, 1025, 3000, 20000] {
            let sp = spline(2, n, 100.0);
            let (ev, sign) = (Evaluator::new(&sp), SignEvaluator::new(&sp));
            // one centre has the weight 0 (the weights sum to zero): double precision alone
            let Some(single) = sign.single.as_ref() else {
                assert_eq!(n, 1);
                continue;
            };
            // the chunks bound the products a lane sums in single precision
            assert_eq!(single.terms, n.div_ceil(LANES32).min(CHUNK32 / LANES32), "n={n}");
            let xs: Vec<f64> = (0..61).map(|i| -1.4 + i as f64 * 0.05).collect();
            for (y, z) in [(0.4, -0.7), (0.0, 0.0), (1.3, 0.2)] {
                let mut exact = vec![0.0; xs.len()];
                ev.eval_row(&xs, y, z, &mut exact);
                // a carrier equal to U at every other point plus a little: values near zero of
                // both signs, which must be evaluated again; elsewhere a constant
                let c = |p: &[f64; 3]| {
                    let i = ((p[0] + 1.4) / 0.05).round() as usize;
                    if i.is_multiple_of(2) {
                        exact[i] + if i.is_multiple_of(4) { 1e-9 } else { -1e-9 }
                    } else {
                        7.0
                    }
                };
                let mut out = vec![0.0; xs.len()];
                let again = sign.signed_row(&xs, y, z, c, &mut out);
                assert!(again >= xs.len().div_ceil(2), "n={n}: {again} evaluated again");
                for (i, (&o, &x)) in out.iter().zip(&xs).enumerate() {
                    let want = c(&[x, y, z]) - exact[i];
                    let xn = [(x - 0.1) / 2.0, (y + 0.2) / 2.0, (z - 0.3) / 2.0];
                    assert!((o - want).abs() <= single.bound(xn), "n={n} i={i}: {o} vs {want}");
                    assert_eq!(o > 0.0, want > 0.0, "n={n} i={i}: {o} vs {want}");
                    if i.is_multiple_of(2) {
                        assert_eq!(o.to_bits(), want.to_bits(), "n={n} i={i}: evaluated again");
                    }
                }
            }
        }
    }

    #[test]
    fn the_bound_is_not_far_above_the_error() {
        // a bound that holds only by being huge would send every node back to double precision
        let sp = spline(2, 735, 100.0);
        let (ev, sign) = (Evaluator::new(&sp), SignEvaluator::new(&sp));
        let xs: Vec<f64> = (0..61).map(|i| -1.4 + i as f64 * 0.05).collect();
        let mut exact = vec![0.0; xs.len()];
        ev.eval_row(&xs, 0.4, -0.7, &mut exact);
        let mut out = vec![0.0; xs.len()];
        assert_eq!(sign.signed_row(&xs, 0.4, -0.7, |_| 1e6, &mut out), 0);
        let worst = out.iter().zip(&exact).map(|(o, e)| (o - (1e6 - e)).abs()).fold(0.0, f64::max);
        // the bounds along the row (normalised: centre (0.1, -0.2, 0.3), scale 2)
        let single = sign.single.as_ref().unwrap();
        let bound =
            xs.iter().map(|x| single.bound([(x - 0.1) / 2.0, 0.3, -0.5])).fold(f64::INFINITY, f64::min);
        assert!(worst > 0.0 && worst < bound && bound < 2000.0 * worst, "error {worst}, least bound {bound}");
    }

    #[test]
    fn weights_in_very_small_or_large_units_keep_their_values() {
        // beyond single precision's range: without the scaling they would round to 0 or inf
        for units in [1e-200, 1e200] {
            let mut sp = spline(2, 735, 100.0);
            sp.weights.iter_mut().for_each(|w| *w *= units);
            sp.poly.iter_mut().for_each(|p| *p *= units);
            let (ev, sign) = (Evaluator::new(&sp), SignEvaluator::new(&sp));
            let single = sign.single.as_ref().unwrap();
            let xs: Vec<f64> = (0..61).map(|i| -1.4 + i as f64 * 0.05).collect();
            let mut exact = vec![0.0; xs.len()];
            ev.eval_row(&xs, 0.4, -0.7, &mut exact);
            let mut out = vec![0.0; xs.len()];
            let again = sign.signed_row(&xs, 0.4, -0.7, |_| 0.0, &mut out);
            assert!(again < xs.len() / 4, "{units}: {again} evaluated again");
            for (i, (o, e)) in out.iter().zip(&exact).enumerate() {
                let b = single.bound([(xs[i] - 0.1) / 2.0, 0.3, -0.5]);
                assert!((o + e).abs() <= b && (*o > 0.0) == (-e > 0.0), "{units} i={i}: {o} vs {}", -e);
            }
        }
    }

    #[test]
    fn other_kernels_are_evaluated_in_double_precision() {
        let sp = spline(3, 100, 1.0);
        let (ev, sign) = (Evaluator::new(&sp), SignEvaluator::new(&sp));
        assert!(sign.single.is_none());
        let xs = [0.1, 0.2, 0.3];
        let (mut exact, mut out) = ([0.0; 3], [0.0; 3]);
        ev.eval_row(&xs, 0.0, 0.1, &mut exact);
        assert_eq!(sign.signed_row(&xs, 0.0, 0.1, |_| 2.0, &mut out), 3);
        for (o, e) in out.iter().zip(&exact) {
            assert_eq!(o.to_bits(), (2.0 - e).to_bits());
        }
    }

    #[test]
    fn rows_do_not_depend_on_how_points_are_batched() {
        let sp = spline(2, 700, 10.0);
        let sign = SignEvaluator::new(&sp);
        let xs: Vec<f64> = (0..20).map(|i| i as f64 * 0.1).collect();
        let mut whole = vec![0.0; 20];
        sign.signed_row(&xs, 0.3, 0.2, |_| 1.0, &mut whole);
        let mut parts = vec![0.0; 20];
        sign.signed_row(&xs[..7], 0.3, 0.2, |_| 1.0, &mut parts[..7]);
        sign.signed_row(&xs[7..], 0.3, 0.2, |_| 1.0, &mut parts[7..]);
        assert_eq!(whole, parts);
    }
}
