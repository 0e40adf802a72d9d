//! The two-level fit of the compactly supported method with off-surface constraints: the carrier
//! of the Wendland spline is itself a reconstructed solid.
//!
//! A Wendland spline is zero beyond its support R, so far from the data f = f_c - U is the carrier
//! minus the spline's linear part, and the zero set of a ball carrier crosses the grid there as a
//! spherical shell. Off-surface constraints cannot help where no centre reaches. Applied
//! recursively, the carrier idea removes it:
//!
//! ```text
//! level 0:  f_0 = f_c - U_0,   U_0 the dense spline (kernel r) through a subsample of the points
//!                               chosen evenly over space, with its off-surface constraints;
//! level 1:  U_1 the Wendland spline through all N points with values r_i = f_0(P_i) - t_i
//!           (t_i = 0 at a data point), i.e. U_1(P_i) = f_c(P_i) - t_i - U_0(P_i);
//! solid:    f = f_0 - U_1 = f_c - U_0 - U_1.
//! ```
//!
//! f_0 decides the sign away from the data (it is a clean solid on its own, a subsample's
//! reconstruction) and U_1 pulls the zero set onto every point; beyond its support U_1 is its
//! linear part, fitted to the small remainders, so it barely moves f_0 there. The support of U_1
//! only has to bridge neighbouring points (the default, about [`DEFAULT_NEIGHBOURS`] of them).
//!
//! The subsample keeps, in each cell of a cubic lattice, the point nearest the cell's centre; the
//! cell size is bisected (in its logarithm) until at most the wanted number of cells is occupied.
//! The wanted number is `--coarse-points`, or fewer where the ranks' memory does not hold the
//! dense fit of that many ([`level0_points`]): `auto` takes the two levels exactly where the dense
//! fit of all points does not fit, so level 0 must not be that same fit.

use std::collections::HashMap;
use std::time::Instant;

use super::surface::{check_first_fit, constrain, spilling, SurfaceSummary};
use super::{dense, Fitted, Run};
use crate::app::preflight::{dense_fit_bytes, largest_fitting};
use crate::app::stages::{Stage, Stages};
use crate::cli::{FitArgs, SideVote};
use crate::error::{Error, Result};
use crate::par::Comm;
use crate::spline::compact::DEFAULT_NEIGHBOURS;
use crate::spline::hygiene::Prepared;
use crate::spline::{Evaluator, Kernel, Spline};

/// The indices (ascending) of at most `target` points of `centres` (3 values per point), one per
/// occupied lattice cell, the one nearest the cell's centre; all of them when there are no more
/// than `target`. Deterministic: the same on every rank.
pub fn even_subsample(centres: &[f64], target: usize) -> Vec<usize> {
    let n = centres.len() / 3;
    if n <= target {
        return (0..n).collect();
    }
    let (lo, hi) = crate::spline::hygiene::bounding_box(centres, 3);
    let diag = crate::spline::hygiene::diagonal(&lo, &hi).max(f64::MIN_POSITIVE);
    let cells = |h: f64| -> Vec<usize> {
        let mut best: HashMap<[i64; 3], (f64, usize)> = HashMap::new();
        for (i, p) in centres.chunks_exact(3).enumerate() {
            let key: [i64; 3] = std::array::from_fn(|d| ((p[d] - lo[d]) / h).floor() as i64);
            let d2: f64 = (0..3).map(|d| (p[d] - lo[d] - (key[d] as f64 + 0.5) * h).powi(2)).sum();
            let e = best.entry(key).or_insert((f64::INFINITY, usize::MAX));
            if d2 < e.0 || (d2 == e.0 && i < e.1) {
                *e = (d2, i);
            }
        }
        let mut pick: Vec<usize> = best.into_values().map(|(_, i)| i).collect();
        pick.sort_unstable();
        pick
    };
    // the occupied count falls as the cell grows: bisect log h between a cell per point and one
    let (mut small, mut large) = (diag * 1e-6, diag);
    let mut chosen = cells(large);
    for _ in 0..24 {
        let mid = (small * large).sqrt();
        let c = cells(mid);
        if c.len() <= target {
            large = mid;
            chosen = c;
        } else {
            small = mid;
        }
    }
    chosen
}

/// `prep` restricted to the points `keep` (the same carrier, normalisation and box).
fn restrict(prep: &Prepared, keep: &[usize]) -> Prepared {
    let pick =
        |v: &[f64]| -> Vec<f64> { keep.iter().flat_map(|&i| v[3 * i..3 * i + 3].iter().copied()).collect() };
    Prepared {
        points: pick(&prep.points),
        centres: pick(&prep.centres),
        values: keep.iter().map(|&i| prep.values[i]).collect(),
        ..prep.clone()
    }
}

/// U at every point of `points` (caller's coordinates), each rank taking a contiguous block and
/// all ranks receiving all values. Collective.
fn eval_everywhere(comm: &dyn Comm, spline: &Spline, points: &[f64]) -> Vec<f64> {
    use rayon::prelude::*;
    let n = points.len() / 3;
    let (p, r) = (comm.size(), comm.rank());
    let counts: Vec<usize> = (0..p).map(|q| n / p + usize::from(q < n % p)).collect();
    let start: usize = counts[..r].iter().sum();
    let ev = Evaluator::new(spline);
    let mine: Vec<f64> = (start..start + counts[r])
        .into_par_iter()
        .map(|i| {
            let x = &points[3 * i..3 * i + 3];
            let mut u = [0.0];
            ev.eval_row(&x[..1], x[1], x[2], &mut u);
            u[0]
        })
        .collect();
    let mut all = vec![0.0; n];
    comm.all_gather_f64(&mine, &counts, &mut all);
    all
}

/// A memory refusal of level 0 said as such, with the advice that helps there: the dense
/// checks advise the compactly supported method, which this already is.
fn in_level0(e: Error, points: usize) -> Error {
    match e {
        Error::Memory(m) => Error::Memory(format!(
            "level 0 of the two-level fit (a dense off-surface fit of {points} of the points): {}",
            m.replace(dense::DENSE_ADVICE, LEVEL0_ADVICE)
        )),
        e => e,
    }
}

/// The points level 0 takes of `n` on `ranks` ranks with `room` bytes per rank: `--coarse-points`
/// (at most `n`), or where the dense off-surface fit of that many would not fit the room, the most
/// whose fit does, counting every point's off points (`--off-points`, the most they can add) and
/// the solver's panels as the dense check does; the second fits' blob points take what room is
/// left ([`dense::appendable`]). Below [`MIN_LEVEL0`] points the asked count is kept, and the
/// level's own check refuses it with the figures.
pub fn level0_points(args: &FitArgs, n: usize, (ranks, room): (usize, f64)) -> Result<usize> {
    let wanted = args.coarse_points.min(n);
    let r = Kernel::new(3, 2)?;
    let need = |m: usize| {
        let system = m + (args.off_points * m as f64).ceil() as usize + r.poly_count();
        let lower = dense::lower_for(args.solver, &r, system);
        let panel = dense::estimate_panel(args.panel, args.solver, system);
        dense_fit_bytes(system, ranks, args.precision, lower, panel)
    };
    if wanted <= MIN_LEVEL0 || need(MIN_LEVEL0) > room {
        return Ok(wanted);
    }
    Ok(largest_fitting(MIN_LEVEL0, wanted, |m| need(m) <= room))
}

/// The fewest points [`level0_points`] gives level 0 to fit the memory: as few as the
/// off-surface method takes (see [`super::surface::AUTO_MIN_POINTS`]).
pub const MIN_LEVEL0: usize = super::surface::AUTO_MIN_POINTS;

/// What to change where level 0 does not fit.
const LEVEL0_ADVICE: &str =
    "use a smaller --coarse-points (level 0 has about 1.5 rows per point), more ranks or nodes, or --surface carrier";

/// Fits level 0 on a subsample of `prep` and the compactly supported `kernel` through all of its
/// points on top (see the module doc). `kernel`'s support is the caller's. Collective.
pub fn fit(
    run: &Run<'_>,
    kernel: Kernel,
    prep: &Prepared,
    coarse_points: usize,
    stages: &mut Stages,
) -> Result<(Fitted, SurfaceSummary)> {
    // level 1's sparse factor is checked first: a refusal after level 0 would waste its solve
    let tree = stages.time(Stage::Tree, || {
        super::compact::check_before(run, &kernel, prep, "level 1 of the two-level fit")
    })?;
    let t0 = Instant::now();
    // level 0 has its own stage table, itemised under `coarse` in the report: its stages would
    // otherwise count twice in the run's
    let mut inner = Stages::default();
    let keep = even_subsample(&prep.centres, coarse_points);
    let sub = restrict(prep, &keep);
    let mut constrained = constrain(run, &sub, None, run.args.orient_side == SideVote::On, &mut inner)?;
    let r = Kernel::new(3, 2)?.with_smoothing(run.args.smooth)?;
    let mut refit =
        |p: &Prepared, first: Option<&dense::KeptFactor>, st: &mut Stages| dense::refit(run, r, p, first, st);
    let level0 = (|| {
        dense::check(run.comm, &r, constrained.prep.values.len(), run.args)?;
        let mut first = dense::fit(run, r, &constrained.prep, true, &mut inner)?;
        if let Some(again) = spilling(run, r, &sub, &mut constrained, &mut first, &mut inner)? {
            first = again;
        }
        let rows = constrained.prep.values.len();
        let most = super::surface::most_appended(&sub, &constrained, run.args.grid.margin.fraction);
        let room = dense::appendable(run, r, rows, first.factor.as_ref(), most);
        // level 0 decides the sign away from the data: its spurious blobs are cleared like a
        // single-level fit's
        check_first_fit(run, &sub, &mut constrained, first, &mut inner, &mut refit, room)
    })()
    .map_err(|e| in_level0(e, keep.len()))?;
    crate::app::finite::check_fit(&level0, &constrained.prep)?;
    let rows = constrained.prep.values.len();
    let summary = constrained.summary.clone();
    let u0 = eval_everywhere(run.comm, &level0.spline, &prep.points);
    let mut top = prep.clone();
    for (v, u) in top.values.iter_mut().zip(&u0) {
        *v -= u;
    }
    let coarse_seconds = t0.elapsed().as_secs_f64();
    stages.add(Stage::Coarse, coarse_seconds);
    stages.add_part(Stage::Coarse, inner);
    // the same centres as `prep`'s (only the values differ): the octree is theirs
    let level1 = super::compact::fit(run, kernel, &top, Some(tree), stages)?;
    let mut figures = level1.figures;
    figures.push(("coarse_points".into(), keep.len().to_string()));
    figures.push(("coarse_rows".into(), rows.to_string()));
    figures.push(("coarse_residual".into(), format!("{:e}", level0.residual)));
    figures.push(("coarse_seconds".into(), format!("{coarse_seconds:.3}")));
    // the rows beyond the subsample and its off points are the blob search's constraint points
    // (the pins, the solid given back), which the surface line itemises
    let pins = rows.saturating_sub(keep.len() + summary.off_points);
    let line = format!(
        "two levels: level 0 dense (kernel r, {}) on {} of the points chosen evenly over space + {} \
         off-surface points{} ({rows} rows, residual {:.3e}) in {coarse_seconds:.3} s; level 1 compactly \
         supported through all points on top of it (support about {DEFAULT_NEIGHBOURS} neighbours unless \
         --support): {}",
        level0.solver,
        keep.len(),
        summary.off_points,
        if pins > 0 { format!(" + {pins} constraint points of the blob search") } else { String::new() },
        level0.residual,
        level1.line
    );
    Ok((
        Fitted {
            spline: level1.spline,
            coarse: vec![level0.spline],
            solver: format!("{} on {}", level1.solver, level0.solver),
            residual: level1.residual,
            line,
            figures,
            factor: None,
        },
        summary,
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::spline::octree::tests::bunny;

    #[test]
    fn the_subsample_is_even_and_of_the_size_asked() {
        let pts = bunny();
        let n = pts.len() / 3;
        let keep = even_subsample(&pts, 500);
        assert!(keep.len() <= 500 && keep.len() > 400, "{} of {n}", keep.len());
        assert!(keep.windows(2).all(|w| w[0] < w[1]));
        // evenly over space: every point has a kept point within a few mean spacings, which a
        // prefix of the points (the scan's order) would not give
        let (lo, hi) = crate::spline::hygiene::bounding_box(&pts, 3);
        let diag = crate::spline::hygiene::diagonal(&lo, &hi);
        let far = pts
            .chunks_exact(3)
            .map(|p| {
                keep.iter()
                    .map(|&k| (0..3).map(|d| (p[d] - pts[3 * k + d]).powi(2)).sum::<f64>())
                    .fold(f64::INFINITY, f64::min)
                    .sqrt()
            })
            .fold(0.0f64, f64::max);
        assert!(far < 0.08 * diag, "farthest point from the subsample {far} of diagonal {diag}");
        assert_eq!(even_subsample(&pts, n + 5).len(), n);
    }
}
