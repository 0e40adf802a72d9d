//! Fast evaluation of a 3D volume spline at many points: centres in structure-of-arrays form,
//! processed in cache-sized blocks with independent accumulator lanes that the compiler keeps in
//! vector registers, and a runtime switch to AVX-512 or AVX2 code where the CPU has it. The sum
//! for each point runs over the centres in one fixed order whatever the blocking, the thread or
//! the rank, so values are reproducible bit for bit: Rust contracts no multiply and add on its
//! own, and the explicit multiply-adds ([`f64::mul_add`]) are fused on every path (in software
//! where the CPU has no FMA), so the AVX-512, AVX2 and portable code round identically. The
//! square roots, the limit of these sums, are shared between the hardware and a multiply-add
//! iteration (`lane_sums`).
//!
//! A compactly supported kernel takes another path ([`crate::spline::compact_eval`]): each point
//! sums only the centres within the support, gathered with the octree once per row, again in an
//! order that depends on the point alone.

use crate::simd::on_widest_unit;
use crate::spline::compact_eval::CompactRows;
use crate::spline::Spline;

/// Lanes of the vectorised radial sums, here and in [`crate::spline::point_eval`].
pub(crate) const LANES: usize = 8;
/// Centres per block: 4 arrays x 576 x 8 bytes = 18 KiB, in L1 with room to spare; a whole
/// number of [`PERIOD`]s of lane groups.
const BLOCK: usize = 576;
const _: () = assert!(BLOCK.is_multiple_of(PERIOD * LANES));

/// Which closed form the vectorised loops use (here and in [`crate::spline::point_eval`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Form {
    /// G = r (n = 3, m = 2)
    R1,
    /// G = r^3 (n = 3, m = 3)
    R3,
}

impl Form {
    /// The closed form of a spline's kernel: the 3D Green's functions have one, the others
    /// (compactly supported kernels, 2D and 1D splines) are summed generically.
    pub(crate) fn of(spline: &Spline) -> Option<Form> {
        let k = spline.kernel;
        match (k.dim(), k.order(), k.is_compact()) {
            (3, 2, None) => Some(Form::R1),
            (3, 3, None) => Some(Form::R3),
            _ => None,
        }
    }
}

/// A spline prepared for evaluation at many points.
pub struct Evaluator<'a> {
    spline: &'a Spline,
    form: Option<Form>,
    cx: Vec<f64>,
    cy: Vec<f64>,
    cz: Vec<f64>,
    w: Vec<f64>,
    compact: Option<CompactRows>,
}

/// The centres (x, y and z apart) and weights of a 3D spline, padded to whole lanes of `lanes`
/// with zero weights at the origin, which add exactly 0.0 to every sum: the layout of the
/// vectorised radial sums, here and in [`crate::spline::point_eval`].
pub(crate) fn padded_lanes(spline: &Spline, lanes: usize) -> [Vec<f64>; 4] {
    let n = spline.len();
    let padded = n.div_ceil(lanes) * lanes;
    let (mut cx, mut cy, mut cz, mut w) =
        (vec![0.0; padded], vec![0.0; padded], vec![0.0; padded], vec![0.0; padded]);
    for (i, p) in spline.centres.chunks_exact(3).enumerate() {
        cx[i] = p[0];
        cy[i] = p[1];
        cz[i] = p[2];
    }
    w[..n].copy_from_slice(&spline.weights);
    [cx, cy, cz, w]
}

/// The sum of the lanes of a radial sum, pairwise in a fixed order, so that every evaluator gives
/// the same bits for the same point.
#[inline(always)]
pub(crate) fn reduce_lanes(a: &[f64; LANES]) -> f64 {
    ((a[0] + a[4]) + (a[2] + a[6])) + ((a[1] + a[5]) + (a[3] + a[7]))
}

impl<'a> Evaluator<'a> {
    pub fn new(spline: &'a Spline) -> Self {
        let compact = CompactRows::new(spline);
        let form = Form::of(spline);
        let [cx, cy, cz, w] = if form.is_some() { padded_lanes(spline, LANES) } else { Default::default() };
        Evaluator { spline, form, cx, cy, cz, w, compact }
    }

    /// Number of kernel evaluations per point (for a compactly supported kernel: at most; a
    /// point near the data evaluates about [`Evaluator::compact_rows`]'s mean neighbour count).
    pub fn centres(&self) -> usize {
        self.spline.len()
    }

    /// The row evaluator of a compactly supported spline (None for the Green's functions).
    pub fn compact_rows(&self) -> Option<&CompactRows> {
        self.compact.as_ref()
    }

    /// U at the points `(xs[i], y, z)`, caller's coordinates, into `out`.
    pub fn eval_row(&self, xs: &[f64], y: f64, z: f64, out: &mut [f64]) {
        let sp = self.spline;
        if let Some(c) = &self.compact {
            let norm = &sp.norm;
            let yn = (y - norm.centre[1]) / norm.scale;
            let zn = (z - norm.centre[2]) / norm.scale;
            let xn: Vec<f64> = xs.iter().map(|x| (x - norm.centre[0]) / norm.scale).collect();
            c.radial_row(sp, &xn, yn, zn, &mut out[..xs.len()]);
            for (o, &x) in out.iter_mut().zip(&xn) {
                *o += poly_value(sp, [x, yn, zn]);
            }
            return;
        }
        let Some(form) = self.form else {
            for (o, &x) in out.iter_mut().zip(xs) {
                *o = sp.eval(&[x, y, z]);
            }
            return;
        };
        let norm = &sp.norm;
        let yn = (y - norm.centre[1]) / norm.scale;
        let zn = (z - norm.centre[2]) / norm.scale;
        let xn: Vec<f64> = xs.iter().map(|x| (x - norm.centre[0]) / norm.scale).collect();
        let mut acc = vec![[0.0f64; LANES]; xs.len()];
        let row = Row { form, xn: &xn, y: yn, z: zn, cx: &self.cx, cy: &self.cy, cz: &self.cz, w: &self.w };
        radial_sums(&row, &mut acc);
        for ((o, a), &x) in out.iter_mut().zip(&acc).zip(&xn) {
            *o = reduce_lanes(a) + poly_value(sp, [x, yn, zn]);
        }
    }
}

/// The polynomial part of `sp` at the normalised point `x`, summed in one fixed order (the
/// evaluators' rows and [`crate::spline::sign_eval`] add it alike).
#[inline]
pub(crate) fn poly_value(sp: &Spline, x: [f64; 3]) -> f64 {
    let k = sp.poly.len();
    let mut pv = [0.0; 10];
    sp.kernel.poly_eval(&x, &mut pv[..k]);
    pv[..k].iter().zip(&sp.poly).map(|(p, c)| p * c).sum::<f64>()
}

/// One row of evaluation points against all centres: the row's normalised x values at (y, z),
/// and the centres and weights in structure-of-arrays form.
struct Row<'a> {
    form: Form,
    xn: &'a [f64],
    y: f64,
    z: f64,
    cx: &'a [f64],
    cy: &'a [f64],
    cz: &'a [f64],
    w: &'a [f64],
}

on_widest_unit! {
    /// The radial sums of `row` into `acc`, compiled for the widest vector unit the CPU has (the
    /// same portable code, so every path gives the same bits).
    fn radial_sums[][](row: &Row<'_>, acc: &mut [[f64; LANES]]) = radial_sums_portable;
}

#[inline(always)]
fn radial_sums_portable(row: &Row<'_>, acc: &mut [[f64; LANES]]) {
    let Row { form, xn, y, z, cx, cy, cz, w } = *row;
    let n = w.len();
    let mut b0 = 0;
    while b0 < n {
        let b1 = (b0 + BLOCK).min(n);
        let (bx, by, bz, bw) = (&cx[b0..b1], &cy[b0..b1], &cz[b0..b1], &w[b0..b1]);
        for (&x, a) in xn.iter().zip(acc.iter_mut()) {
            lane_sums(form, [x, y, z], [bx, by, bz, bw], a);
        }
        b0 = b1;
    }
}

/// Lane groups per period of the square roots: the last group of each period takes
/// [`soft_sqrt`], the others the hardware's.
const PERIOD: usize = 3;

/// Adds sum_j w_j G(|x - c_j|) over the centres given (whole lane groups, the first one at a
/// multiple of [`PERIOD`] groups of the padded arrays) into the lanes `acc`: centre j into lane
/// j mod [`LANES`], in the order of j. Shared by the grid and the point evaluator, so that both
/// give the same bits at the same point.
///
/// The square root is the throughput limit of these sums: the hardware's unit is not pipelined,
/// and while it works the multiply-add units wait. Every [`PERIOD`]-th lane group therefore takes
/// its roots from [`soft_sqrt`], which runs on those units beside it. Which root a centre gets
/// depends only on its index, so every blocking and every path agree.
/// `centres` are the x, y, z and weight arrays, in that order.
#[inline(always)]
pub(crate) fn lane_sums(form: Form, x: [f64; 3], centres: [&[f64]; 4], acc: &mut [f64; LANES]) {
    match form {
        Form::R1 => periods(x, centres, acc, |_, r| r),
        Form::R3 => periods(x, centres, acc, |r2, r| r2 * r),
    }
}

#[inline(always)]
fn periods(
    x: [f64; 3],
    [cx, cy, cz, w]: [&[f64]; 4],
    acc: &mut [f64; LANES],
    g: impl Fn(f64, f64) -> f64 + Copy,
) {
    const SPAN: usize = PERIOD * LANES;
    let mut a = *acc;
    let whole = cx.len() / SPAN * SPAN;
    let spans = cx[..whole].chunks_exact(SPAN).zip(cy[..whole].chunks_exact(SPAN));
    for (((px, py), pz), pw) in spans.zip(cz[..whole].chunks_exact(SPAN)).zip(w[..whole].chunks_exact(SPAN)) {
        for q in 0..PERIOD {
            let r = q * LANES..(q + 1) * LANES;
            let group = (&px[r.clone()], &py[r.clone()], &pz[r.clone()], &pw[r]);
            if q + 1 == PERIOD {
                lane_group(x, group, &mut a, soft_sqrt, g);
            } else {
                lane_group(x, group, &mut a, f64::sqrt, g);
            }
        }
    }
    // fewer than PERIOD groups left: none is the last of its period
    for q in (whole..cx.len()).step_by(LANES) {
        let r = q..q + LANES;
        lane_group(x, (&cx[r.clone()], &cy[r.clone()], &cz[r.clone()], &w[r]), &mut a, f64::sqrt, g);
    }
    *acc = a;
}

/// `a[l] += w_l G` over one lane group (x, y, z and w of its centres), G = g(r^2, r) with r from
/// `root`; r^2 and the sum by multiply-add.
#[inline(always)]
fn lane_group(
    x: [f64; 3],
    (px, py, pz, pw): (&[f64], &[f64], &[f64], &[f64]),
    a: &mut [f64; LANES],
    root: impl Fn(f64) -> f64,
    g: impl Fn(f64, f64) -> f64,
) {
    let (px, py, pz, pw) = (&px[..LANES], &py[..LANES], &pz[..LANES], &pw[..LANES]);
    for l in 0..LANES {
        let (dx, dy, dz) = (x[0] - px[l], x[1] - py[l], x[2] - pz[l]);
        let r2 = dz.mul_add(dz, dy.mul_add(dy, dx * dx));
        a[l] = pw[l].mul_add(g(r2, root(r2)), a[l]);
    }
}

/// sqrt(r2) for finite r2 >= 0 by multiply-adds alone, to run beside the hardware square root.
///
/// The estimate of 1/sqrt(r2) from the bits (the exponent halved and negated by one integer
/// subtraction) is within 3.5 %; three Newton steps y <- y (3/2 - r2 y^2 / 2) take the relative
/// error to 1.8e-3, 4.6e-6 and 3.2e-11; then s = r2 y is corrected once by Newton on the root
/// itself, s + (r2 - s^2) / (2 s) with 1/(2 s) taken as y/2 and the residual r2 - s^2 exact by
/// fused multiply-add, which squares the error again. The result is the rounded root or its
/// neighbour (faithful, not always correctly rounded). r2 = 0 gives 0 exactly; a subnormal r2
/// gives a root below 1.5e-154, an error of that size at most.
#[inline(always)]
pub(crate) fn soft_sqrt(r2: f64) -> f64 {
    let mut y = f64::from_bits(0x5fe6_eb50_c7b5_37a9u64.wrapping_sub(r2.to_bits() >> 1));
    let h = 0.5 * r2;
    for _ in 0..3 {
        y *= (-(h * y)).mul_add(y, 1.5);
    }
    let s = r2 * y;
    (0.5 * y).mul_add((-s).mul_add(s, r2), s)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::spline::kernel::Kernel;
    use crate::spline::Normalisation;

    /// A 3D spline of order `order` with `n` random centres in the unit box, random weights and
    /// polynomial (also the single-precision evaluator's test spline).
    pub(crate) fn spline(order: usize, n: usize) -> Spline {
        let mut s = 99u64;
        let mut rnd = || {
            s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let kernel = Kernel::new(3, order).unwrap();
        let centres: Vec<f64> = (0..3 * n).map(|_| rnd()).collect();
        let weights: Vec<f64> = (0..n).map(|_| rnd()).collect();
        let poly: Vec<f64> = (0..kernel.poly_count()).map(|_| rnd()).collect();
        Spline {
            kernel,
            centres,
            weights,
            poly,
            norm: Normalisation { centre: [0.1, -0.2, 0.3], scale: 2.0 },
        }
    }

    #[test]
    fn fast_rows_agree_with_the_plain_sum() {
        for order in [2, 3] {
            // sizes around the lane and block boundaries
            for n in [1, 7, 8, 9, 23, 24, 25, 575, 576, 577, 1100] {
                let sp = spline(order, n);
                let ev = Evaluator::new(&sp);
                let xs: Vec<f64> = (0..37).map(|i| -1.0 + i as f64 * 0.05).collect();
                let mut out = vec![0.0; xs.len()];
                ev.eval_row(&xs, 0.4, -0.7, &mut out);
                for (o, &x) in out.iter().zip(&xs) {
                    let plain = sp.eval(&[x, 0.4, -0.7]);
                    assert!(
                        (o - plain).abs() <= 1e-12 * (1.0 + plain.abs()),
                        "m={order} n={n}: {o} vs {plain}"
                    );
                }
            }
        }
    }

    #[test]
    fn rows_do_not_depend_on_how_points_are_batched() {
        let sp = spline(2, 700);
        let ev = Evaluator::new(&sp);
        let xs: Vec<f64> = (0..20).map(|i| i as f64 * 0.1).collect();
        let mut whole = vec![0.0; 20];
        ev.eval_row(&xs, 0.3, 0.2, &mut whole);
        let mut parts = vec![0.0; 20];
        ev.eval_row(&xs[..7], 0.3, 0.2, &mut parts[..7]);
        ev.eval_row(&xs[7..], 0.3, 0.2, &mut parts[7..]);
        assert_eq!(whole, parts);
    }

    #[test]
    fn the_soft_square_root_is_the_rounded_root_or_its_neighbour() {
        let mut s = 7u64;
        let mut bits = || {
            s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            s >> 11
        };
        assert_eq!(soft_sqrt(0.0), 0.0);
        let (mut exact, mut total) = (0usize, 0usize);
        for e in -60..=60 {
            for _ in 0..20_000 {
                // uniform mantissas across 120 binades, the squared distances of any scale
                let r2 = (1.0 + bits() as f64 / (1u64 << 53) as f64) * 2f64.powi(e);
                let (soft, hard) = (soft_sqrt(r2), r2.sqrt());
                let ulps = (soft.to_bits() as i64 - hard.to_bits() as i64).abs();
                assert!(ulps <= 1, "sqrt({r2:e}): {soft:e} against {hard:e}");
                exact += (ulps == 0) as usize;
                total += 1;
            }
        }
        assert!(exact as f64 > 0.99 * total as f64, "{exact} of {total} correctly rounded");
    }
}
