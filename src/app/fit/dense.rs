//! The dense method: each rank assembles its row-cyclic rows of the bordered system of a global
//! Green's function (or of any kernel: a compactly supported one gives the dense oracle of the
//! sparse method), and the distributed dense solvers factor it without ever gathering it.

use std::rc::Rc;

use faer::Par;

use super::{Fitted, Run};
use crate::app::preflight::{
    bordered_fit_bytes, check_memory, check_memory_beside, dense_fit_bytes, dense_matrix_bytes,
    largest_fitting, panel_bytes, FIXED_BYTES,
};
use crate::app::progress::Progress;
use crate::app::stages::{Stage, Stages};
use crate::cli::FitArgs;
use crate::error::Error;
use crate::error::Result;
use crate::linalg::dist::{
    self, Bordered, Factored, Job, Layout, LocalBlocks, LocalRows, Precision, ProcessGrid, RowCyclic,
    SolverKind,
};
use crate::linalg::gemm;
use crate::par::{agree, max_over_ranks, CallKind, Comm, Timed};
use crate::spline::hygiene::Prepared;
use crate::spline::{fill_block, fill_block_lower, fill_rows_lower, residual_parts, Kernel, Spline};

/// This rank's rows of the bordered system of `kernel` through `values` at `centres`.
pub fn assemble(kernel: &Kernel, centres: &[f64], values: &[f64], layout: RowCyclic) -> Result<LocalRows> {
    assemble_from(kernel, centres, values, layout, usize::MAX)
}

/// [`assemble`] for the projected Cholesky, which reads the lower triangle of A and its first k
/// rows alone (k the polynomial count; see `crate::linalg::dist::cholesky`): the rest of A's upper
/// triangle stays zero, and the assembly takes about half the kernel evaluations.
pub fn assemble_lower(
    kernel: &Kernel,
    centres: &[f64],
    values: &[f64],
    layout: RowCyclic,
) -> Result<LocalRows> {
    assemble_from(kernel, centres, values, layout, kernel.poly_count())
}

/// This rank's rows, the entries of A above the diagonal left zero in the rows from `whole` on.
fn assemble_from(
    kernel: &Kernel,
    centres: &[f64],
    values: &[f64],
    layout: RowCyclic,
    whole: usize,
) -> Result<LocalRows> {
    let mut rows = LocalRows::try_zeros(layout, layout.n + 1, kernel.poly_count())?;
    let globals: Vec<usize> = (0..layout.local_count()).map(|l| layout.global(l)).collect();
    fill_rows_lower(kernel, centres, values, &globals, whole, &mut rows.data);
    Ok(rows)
}

/// The solution of the bordered system of `kernel` through `values` at `centres`, whose first
/// `first.centres()` centres are those of the factored system `first` (the rest appended after
/// them; every value may differ from the first system's), by bordering `first`'s factor
/// ([`dist::extend_solve`]), with the bordered factor for further values of the same centres
/// ([`dist::solve_bordered`]). Collective; `Error::NotDefinite` when the bordered block is not
/// definite to working precision (then the whole system has to be solved).
pub fn solve_extended(
    job: &Job<'_>,
    kernel: &Kernel,
    centres: &[f64],
    values: &[f64],
    first: &Factored,
) -> Result<(Vec<f64>, Bordered)> {
    let (n, k) = (first.centres(), kernel.poly_count());
    assert!(values.len() >= n && k == first.border(), "the extended system keeps the first one's centres");
    let m = values.len() - n;
    let rows = first.local_centres();
    let appended: Vec<usize> = (n..n + m).collect();
    let poly_cols: Vec<usize> = (n + m..n + m + k).collect();
    let mut cross = vec![0.0; rows.len() * m];
    fill_block(kernel, centres, values, &rows, &appended, &mut cross);
    let mut block = vec![0.0; m * m];
    fill_block(kernel, centres, values, &appended, &appended, &mut block);
    let mut poly_cm = vec![0.0; m * k];
    fill_block(kernel, centres, values, &appended, &poly_cols, &mut poly_cm);
    let poly: Vec<f64> = (0..m * k).map(|q| poly_cm[(q % k) * m + q / k]).collect();
    let keys = Some(&centres[3 * n..3 * (n + m)]);
    let new = dist::Appended { cross: &cross, poly: &poly, block: &block, rhs: values, keys };
    agree(job.comm, dist::extend_solve(job, first, &new))
}

/// Whether the solvers look ahead: as asked, or by default (`auto`) on the row-cyclic layout
/// (`shape` None) for the projected Cholesky of a system of `rows` rows (5-7 % faster at 4000 and
/// 8000 rows on 2 ranks of a quiet node) and off for LU and Householder (LU no faster, Householder
/// 3-5 % slower), and on a 2D grid when it has more than one process column (with one, every rank
/// is in the next panel's column and nothing can run ahead).
pub fn lookahead_for(
    asked: Option<bool>,
    shape: Option<(usize, usize)>,
    solver: SolverKind,
    rows: usize,
) -> bool {
    asked.unwrap_or(match shape {
        None => solver.resolve(rows) == SolverKind::Cholesky || dist::LOOKAHEAD,
        Some((_, pc)) => pc > 1,
    })
}

/// This rank's blocks of the bordered system of `kernel` on a process grid, in nb x nb blocks.
pub fn assemble_blocks(
    kernel: &Kernel,
    centres: &[f64],
    values: &[f64],
    grid: &ProcessGrid<'_>,
    nb: usize,
) -> Result<LocalBlocks> {
    assemble_blocks_from(kernel, centres, values, (grid, nb), usize::MAX)
}

/// [`assemble_blocks`] for the 2D projected Cholesky, which reads the lower triangle of A and its
/// first k rows alone, as [`assemble_lower`] on the row-cyclic layout.
pub fn assemble_blocks_lower(
    kernel: &Kernel,
    centres: &[f64],
    values: &[f64],
    grid: &ProcessGrid<'_>,
    nb: usize,
) -> Result<LocalBlocks> {
    assemble_blocks_from(kernel, centres, values, (grid, nb), kernel.poly_count())
}

/// This rank's blocks, the entries of A above the diagonal left zero in the rows from `whole` on.
fn assemble_blocks_from(
    kernel: &Kernel,
    centres: &[f64],
    values: &[f64],
    (grid, nb): (&ProcessGrid<'_>, usize),
    whole: usize,
) -> Result<LocalBlocks> {
    let n = values.len() + kernel.poly_count();
    let mut a = LocalBlocks::try_zeros(grid, n, nb)?;
    let (rows, cols) = (a.rows.globals(), a.cols.globals());
    fill_block_lower(kernel, centres, values, (&rows, &cols), whole, &mut a.data);
    Ok(a)
}

/// Refuses, before any work, a `--layout` the rest of the arguments or the rank count cannot
/// use: the 2D block-cyclic layout solves in f64 only, and its grid must cover the ranks
/// exactly.
pub fn check_layout(a: &FitArgs, ranks: usize) -> Result<()> {
    let Some((pr, pc)) = a.layout.shape(ranks) else { return Ok(()) };
    if a.precision != Precision::F64 {
        return Err(Error::Usage(
            "--precision mixed runs on the row-cyclic layout only: use --layout row-cyclic".into(),
        ));
    }
    if pr * pc != ranks {
        return Err(Error::Usage(format!(
            "--layout {pr}x{pc} needs {} ranks, the job has {ranks} (or use --layout 2d for the squarest grid)",
            pr * pc
        )));
    }
    Ok(())
}

/// Whether a fit assembles the lower triangle alone for `solver` on a system of `system` rows
/// ([`assemble_lower`], [`assemble_blocks_lower`] on a 2D grid): where it resolves to the
/// projected Cholesky and the kernel has a polynomial border.
pub(super) fn lower_for(solver: SolverKind, kernel: &Kernel, system: usize) -> bool {
    solver.resolve(system) == SolverKind::Cholesky && kernel.poly_count() > 0
}

/// What a dense system's memory check advises.
pub const DENSE_ADVICE: &str = "use --method csrbf (compactly supported, sparse), more ranks or nodes (the rows are split over all ranks) or fewer points";

/// Refuses a dense system that does not fit in the ranks' memory: its rows with the solver's
/// panel buffers (panels as wide as `estimate_panel` says); for the projected Cholesky the lower
/// triangle it assembles (a fallback to LU checks the whole matrix before assembling it).
/// Collective.
pub fn check(comm: &dyn Comm, kernel: &Kernel, n: usize, a: &FitArgs) -> Result<()> {
    let system = n + kernel.poly_count();
    let lower = lower_for(a.solver, kernel, system);
    let panel = estimate_panel(a.panel, a.solver, system);
    let (ranks, mb) = (comm.size(), |b: f64| (b / 1e6).round());
    let rows = dense_matrix_bytes(system, ranks, a.precision, lower);
    check_memory(
        comm,
        dense_fit_bytes(system, ranks, a.precision, lower, panel),
        &format!(
            "the dense system of {system} rows ({n} points; per rank its rows {} MB, the solver's panels \
             {} MB and {} MB for the libraries and MPI's buffers)",
            mb(rows),
            mb(panel_bytes(system, ranks, panel)),
            mb(FIXED_BYTES)
        ),
        DENSE_ADVICE,
    )
}

/// The panel width the memory estimates of a fit assume: `panel` where the user gave one (not
/// 0), else the widest that `solver` takes by default on `system` rows.
pub(super) fn estimate_panel(panel: usize, solver: SolverKind, system: usize) -> usize {
    if panel > 0 {
        panel
    } else {
        solver.widest_default_panel(system)
    }
}

/// The factor of a first fit kept for later fits that append centres to it, with the centres of
/// the system it solves; after a bordered fit, also the bordered factor, for further fits of the
/// same centres with other values.
pub struct KeptFactor {
    /// The first fit's factor, shared by the bordered fits made from it.
    factor: Rc<Factored>,
    /// The centres of the solved system: the first fit's, then those `bordered` appends.
    centres: Vec<f64>,
    bordered: Option<Bordered>,
    /// Whether the first factorisation looked ahead (the report of the second fit says so).
    lookahead: bool,
    /// The seconds the slowest rank took to move the first factor from the process grid to the
    /// row-cyclic layout (None: factored row-cyclic).
    moved: Option<f64>,
}

impl KeptFactor {
    /// Whether `prep`'s system keeps the first fit's centres, in order, before any it appends.
    pub fn extended_by(&self, prep: &Prepared) -> bool {
        let n = 3 * self.factor.centres();
        prep.centres.len() >= n && prep.centres[..n] == self.centres[..n]
    }

    /// Whether `prep`'s system has exactly the centres of this bordered factor (only values may
    /// differ).
    fn solves(&self, prep: &Prepared) -> bool {
        self.bordered.is_some() && prep.centres == self.centres
    }
}

/// A fit after a first one whose factor was kept (`first`): where `prep` has the centres of a
/// bordered factor `first` holds (only values changed), by a solve with it; where `prep` keeps
/// the first fit's centres and appends more (or only changes values), by bordering the first
/// factor ([`solve_extended`]; the result keeps the bordered factor); otherwise, or when the
/// bordered block is not definite, by a fresh dense fit, checked for memory with the kept factor
/// still held. Collective.
pub fn refit(
    run: &Run<'_>,
    kernel: Kernel,
    prep: &Prepared,
    first: Option<&KeptFactor>,
    stages: &mut Stages,
) -> Result<Fitted> {
    let held = first.map_or(0, |f| f.factor.centres());
    if let Some(first) = first.filter(|f| f.solves(prep)) {
        return fit_bordered(run, kernel, prep, first, stages);
    }
    if let Some(first) = first.filter(|f| f.extended_by(prep)) {
        let (n, m) = (first.factor.centres(), prep.values.len() - first.factor.centres());
        let k = kernel.poly_count();
        let held = dense_matrix_bytes(n + k, run.comm.size(), Precision::F64, true) + FIXED_BYTES;
        let need = bordered_fit_bytes(n, m, k, run.comm.size());
        check_memory_beside(
            run.comm,
            held,
            need,
            &format!("bordering the first fit's factor ({n} centres) by {m} more"),
            "use more ranks or nodes, --blob-choice off, or fewer points",
        )?;
        // what the factor keeps beyond the estimate to save time lives in the room left
        first.factor.limit_extras(super::agreed_room(run.comm, held) - need);
        match fit_bordered(run, kernel, prep, first, stages) {
            Err(e) if e.is_not_definite() => {
                if run.comm.rank() == 0 {
                    crate::note!("volspline: bordered second fit: {}; factoring the whole system", e.root());
                }
            }
            outcome => return outcome,
        }
    }
    check(run.comm, &kernel, prep.values.len() + held, run.args)?;
    fit(run, kernel, prep, false, stages)
}

/// The most centres (up to `most`) that [`refit`] can append to the system of `rows` centres a
/// first fit solved (`first`: its kept factor, where it kept one) without a memory refusal: with
/// a kept factor, the bordering's blocks beside the factor's rows; without, a fresh dense fit of
/// all centres. Both needs grow with the centres appended, so the count is found by bisection.
/// The ranks agree on the room. Collective.
pub fn appendable(
    run: &Run<'_>,
    kernel: Kernel,
    rows: usize,
    first: Option<&KeptFactor>,
    most: usize,
) -> usize {
    let (k, ranks, a) = (kernel.poly_count(), run.comm.size(), run.args);
    let (held, need): (f64, Box<dyn Fn(usize) -> f64>) = match first {
        Some(f) => {
            let n = f.factor.centres();
            let held = dense_matrix_bytes(n + k, ranks, Precision::F64, true) + FIXED_BYTES;
            (held, Box::new(move |m| bordered_fit_bytes(n, m, k, ranks)))
        }
        None => (
            0.0,
            Box::new(move |m| {
                let system = rows + m + k;
                let lower = lower_for(a.solver, &kernel, system);
                dense_fit_bytes(system, ranks, a.precision, lower, estimate_panel(a.panel, a.solver, system))
            }),
        ),
    };
    let room = super::agreed_room(run.comm, held);
    if need(0) > room {
        return 0;
    }
    largest_fitting(0, most, |m| need(m) <= room)
}

/// A fit from `first`'s factor, reported as the dense fit is: with its bordered factor where
/// `prep` has those centres (only values changed), else by bordering the first factor with the
/// centres `prep` appends, the new bordered factor kept in the result.
fn fit_bordered(
    run: &Run<'_>,
    kernel: Kernel,
    prep: &Prepared,
    first: &KeptFactor,
    stages: &mut Stages,
) -> Result<Fitted> {
    let Run { comm, threads, .. } = *run;
    let timed = Timed::new(comm);
    let job = Job::on(&timed).par(Par::rayon(threads));
    let t0 = std::time::Instant::now();
    let outcome = match &first.bordered {
        Some(bordered) if first.solves(prep) => Ok((
            stages.time(Stage::Solve, || dist::solve_bordered(&job, &first.factor, bordered, &prep.values)),
            None,
        )),
        _ => stages
            .time(Stage::Solve, || solve_extended(&job, &kernel, &prep.centres, &prep.values, &first.factor))
            .map(|(x, bordered)| {
                let kept = KeptFactor {
                    factor: Rc::clone(&first.factor),
                    centres: prep.centres.clone(),
                    bordered: Some(bordered),
                    lookahead: first.lookahead,
                    moved: first.moved,
                };
                (x, Some(kept))
            }),
    };
    stages.add(Stage::CommWait, timed.seconds());
    let (x, kept) = outcome?;
    let how = if kept.is_some() { "" } else { ", solved again for new values," };
    let solved = (x, how, t0.elapsed().as_secs_f64(), true);
    let mut fitted = from_bordered(run, kernel, prep, first, solved, &timed, stages);
    fitted.factor = kept;
    Ok(fitted)
}

/// The solutions for the values `rhs` (each as many as `prep`'s centres) of `prep`'s system,
/// where `first` holds the bordered factor of exactly its centres: one forward and one back
/// substitution through the factor for all of them
/// ([`crate::linalg::dist::solve_bordered_many`]). None where it holds none. Collective.
pub fn solve_many(
    run: &Run<'_>,
    prep: &Prepared,
    first: &KeptFactor,
    rhs: &[Vec<f64>],
    stages: &mut Stages,
) -> Option<Vec<Vec<f64>>> {
    let bordered = first.bordered.as_ref().filter(|_| first.solves(prep))?;
    let Run { comm, threads, .. } = *run;
    let timed = Timed::new(comm);
    let job = Job::on(&timed).par(Par::rayon(threads));
    let rhs: Vec<&[f64]> = rhs.iter().map(|r| &r[..]).collect();
    let x = stages.time(Stage::Solve, || dist::solve_bordered_many(&job, &first.factor, bordered, &rhs));
    stages.add(Stage::CommWait, timed.seconds());
    Some(x)
}

/// The fit of `prep` whose solution `x` was found with `first`'s bordered factor of its centres
/// in `seconds` (as the sum of an earlier fit's solution and one of [`solve_many`]), reported as
/// a fit solved with that factor; its residual is NaN until [`check_residual`] takes it (a try
/// that is not kept needs none). Collective.
pub fn fitted_from_bordered(
    run: &Run<'_>,
    kernel: Kernel,
    prep: &Prepared,
    first: &KeptFactor,
    (x, seconds): (Vec<f64>, f64),
    stages: &mut Stages,
) -> Fitted {
    let timed = Timed::new(run.comm);
    let solved = (x, ", solved again for new values,", seconds, false);
    from_bordered(run, kernel, prep, first, solved, &timed, stages)
}

/// Takes the residual of `fitted`, the fit of `prep` by the dense solvers, where it was left
/// out ([`fitted_from_bordered`]). Collective.
pub fn check_residual(run: &Run<'_>, prep: &Prepared, fitted: &mut Fitted, stages: &mut Stages) {
    if fitted.residual.is_nan() {
        let spline = &fitted.spline;
        let x: Vec<f64> = spline.weights.iter().chain(&spline.poly).copied().collect();
        fitted.residual = residual(run, &spline.kernel, prep, &x, stages);
    }
}

/// The checks (the residual only with `check`), the spline and the report of the solution `x`
/// of `prep`'s system found with `first`'s factor (`how`: what the report adds after the
/// centres appended) in `seconds`. Collective.
fn from_bordered(
    run: &Run<'_>,
    kernel: Kernel,
    prep: &Prepared,
    first: &KeptFactor,
    (x, how, seconds, check): (Vec<f64>, &str, f64, bool),
    timed: &Timed<'_>,
    stages: &mut Stages,
) -> Fitted {
    let comm = run.comm;
    let n = first.factor.centres();
    let solved = dist::Solved {
        x,
        used: SolverKind::Cholesky,
        panel: first.factor.panel(),
        fallback: None,
        refinement: None,
        mixed_fallback: None,
    };
    let layout = RowCyclic::new(prep.values.len() + kernel.poly_count(), comm.size(), comm.rank());
    let m = prep.values.len() - n;
    let moved = first.moved.map_or(String::new(), |s| format!(", moved from the process grid in {s:.3} s"));
    let how = format!("the first fit's factor ({n} centres{moved}) bordered by {m} appended centres{how}");
    let bordered = Some((n, format!("{how} in {seconds:.3} s")));
    let at = (layout, first.lookahead, bordered);
    let mut fitted = finish(run, kernel, prep, solved, at, timed, stages, check);
    if let Some(seconds) = first.moved {
        fitted.figures.push(("factor_moved_max_s".into(), format!("{seconds:.6}")));
    }
    fitted
}

/// Fits the spline of `kernel` to the prepared points with the dense solvers; with `keep`, the
/// factor of a projected Cholesky in f64 is kept in the result for [`refit`] (on a 2D grid moved
/// to the row-cyclic layout, where there is room for it).
/// Collective.
pub fn fit(
    run: &Run<'_>,
    kernel: Kernel,
    prep: &Prepared,
    keep: bool,
    stages: &mut Stages,
) -> Result<Fitted> {
    let Run { args: a, comm, threads, layout: dense_layout } = *run;
    let (centres, values) = (&prep.centres, &prep.values);
    let layout = RowCyclic::new(values.len() + kernel.poly_count(), comm.size(), comm.rank());
    let progress = Progress::columns("solve", comm);
    let timed = Timed::new(comm);
    let report = |d, t| progress.update(d, t);
    let rows = values.len() + kernel.poly_count();
    let lookahead = lookahead_for(a.lookahead.0, dense_layout.shape(comm.size()), a.solver, rows);
    let job = Job::on(&timed).panel(a.panel).par(Par::rayon(threads)).progress(&report).lookahead(lookahead);
    // the projected Cholesky (in f64 or f32, on either layout) reads the lower triangle alone; a
    // fallback to LU assembles the whole matrix again, which the check before the fit did not
    // count where the lower triangle alone was assembled
    let lower = lower_for(a.solver, &kernel, rows);
    let fallback_fits = || {
        if !lower {
            return Ok(());
        }
        check_memory(
            comm,
            dense_fit_bytes(
                rows,
                comm.size(),
                Precision::F64,
                false,
                estimate_panel(a.panel, SolverKind::Lu, rows),
            ),
            &format!("the LU fallback's whole matrix of {rows} rows"),
            DENSE_ADVICE,
        )
    };
    let solved = match dense_layout {
        Layout::RowCyclic | Layout::Auto => {
            // the stage ends when every rank has assembled its rows (the ranks agree on whether
            // each could hold them): the solve starts together, and a rank's late arrival is not
            // timed as the others' wait in the solve
            let rows = stages.time(Stage::Assemble, || {
                let rows = if lower {
                    assemble_lower(&kernel, centres, values, layout)
                } else {
                    assemble(&kernel, centres, values, layout)
                };
                agree(comm, rows)
            })?;
            let reassemble =
                || fallback_fits().and_then(|()| agree(comm, assemble(&kernel, centres, values, layout)));
            stages.time(Stage::Solve, || {
                if !(keep && a.precision == Precision::F64) {
                    return dist::solve_in(&job, a.solver, a.precision, rows, reassemble).map(|s| (s, None));
                }
                dist::solve_keeping(&job, a.solver, rows, reassemble, true)
            })
        }
        Layout::BlockCyclic(_) => {
            let shape = dense_layout.shape(comm.size()).expect("a 2D layout has a grid");
            let grid = ProcessGrid::new(&timed, shape)?;
            let nb = if a.panel > 0 {
                a.panel
            } else {
                a.solver.default_block_2d(values.len() + kernel.poly_count())
            };
            let blocks = stages.time(Stage::Assemble, || {
                let blocks = if lower {
                    assemble_blocks_lower(&kernel, centres, values, &grid, nb)
                } else {
                    assemble_blocks(&kernel, centres, values, &grid, nb)
                };
                agree(comm, blocks)
            })?;
            let reassemble = || {
                fallback_fits()
                    .and_then(|()| agree(comm, assemble_blocks(&kernel, centres, values, &grid, nb)))
            };
            let k = kernel.poly_count();
            let keep = keep && lower && copy_fits(comm, rows);
            stages.time(Stage::Solve, || {
                dist::solve_2d_keeping(&job, &grid, a.solver, k, blocks, reassemble, keep)
            })
        }
    };
    stages.add(Stage::CommWait, timed.seconds());
    let (solved, factor) = solved?;
    let moved = factor.as_ref().and_then(|f| f.moved()).map(|s| max_over_ranks(comm, s));
    let kept = factor.map(|factor| KeptFactor {
        factor: Rc::new(factor),
        centres: centres.clone(),
        bordered: None,
        lookahead,
        moved,
    });
    let mut fitted = finish(run, kernel, prep, solved, (layout, lookahead, None), &timed, stages, true);
    if let Some(seconds) = moved {
        fitted.line.push_str(&format!(
            "\n  factor kept for later fits: moved from the process grid to the row-cyclic layout in {seconds:.3} s"
        ));
        fitted.figures.push(("factor_moved_max_s".into(), format!("{seconds:.6}")));
    }
    fitted.factor = kept;
    Ok(fitted)
}

/// Whether the ranks have room, beside the 2D blocks of a projected Cholesky of `rows` rows that
/// they hold, for its factor moved to the row-cyclic layout to be kept for bordering (about as
/// much again: the lower triangle). Where they have not, rank 0 says so and later fits factor
/// their systems anew. Collective.
fn copy_fits(comm: &dyn Comm, rows: usize) -> bool {
    let copy = dense_matrix_bytes(rows, comm.size(), Precision::F64, true);
    let held = copy + FIXED_BYTES;
    let room = super::agreed_room(comm, held);
    if copy <= room {
        return true;
    }
    if comm.rank() == 0 {
        crate::note!(
            "volspline: the 2D factor is not kept for later fits: its row-cyclic copy needs about {:.2} GB more per rank, {:.2} GB are free; those fits factor their systems anew",
            copy / 1e9,
            room / 1e9
        );
    }
    false
}

/// ||M x - b|| / ||b|| of the solution `x` of `prep`'s bordered system (a product of the rows
/// each rank holds on the row-cyclic layout), on every rank. Collective.
fn residual(run: &Run<'_>, kernel: &Kernel, prep: &Prepared, x: &[f64], stages: &mut Stages) -> f64 {
    let comm = run.comm;
    let layout = RowCyclic::new(prep.values.len() + kernel.poly_count(), comm.size(), comm.rank());
    stages.time(Stage::Check, || {
        let globals: Vec<usize> = (0..layout.local_count()).map(|l| layout.global(l)).collect();
        let mut parts = residual_parts(kernel, &prep.centres, &prep.values, &globals, x).to_vec();
        comm.sum_f64(&mut parts);
        if parts[1] > 0.0 {
            (parts[0] / parts[1]).sqrt()
        } else {
            parts[0].sqrt()
        }
    })
}

/// The checks (with `check`: the residual; without, it is NaN until [`check_residual`] takes
/// it), the spline and the report of a dense solve `solved` of `prep`'s system on `layout`
/// (`lookahead` as used; `bordered`: the centres of the first fit whose factor was bordered, and
/// how and in how many seconds); `timed` counted its collectives. Collective.
#[allow(clippy::too_many_arguments)]
fn finish(
    run: &Run<'_>,
    kernel: Kernel,
    prep: &Prepared,
    solved: dist::Solved,
    (layout, lookahead, bordered): (RowCyclic, bool, Option<(usize, String)>),
    timed: &Timed<'_>,
    stages: &mut Stages,
    check: bool,
) -> Fitted {
    let Run { comm, .. } = *run;
    let calls = timed.calls();
    // the slowest rank's wait in each kind of call
    let mut by_kind: Vec<f64> = CallKind::ALL.iter().map(|&k| timed.seconds_in(k)).collect();
    comm.max_f64(&mut by_kind);
    if let (Some(why), 0) = (&solved.mixed_fallback, comm.rank()) {
        crate::note!("volspline: precision mixed: {why}; solved in f64 with {}", solved.used.name());
    }
    if let (Some(why), 0) = (&solved.fallback, comm.rank()) {
        crate::note!("volspline: cholesky: {}; fell back to LU", why.root());
    }
    let residual = if check { residual(run, &kernel, prep, &solved.x, stages) } else { f64::NAN };
    let spline = Spline::from_solution(kernel, prep.centres.clone(), &solved.x, prep.norm);
    let mixed = solved.mixed_fallback.is_none() && solved.refinement.is_some();
    let precision =
        if mixed { format!("mixed (f32 {}, f64 refinement)", solved.used.name()) } else { "f64".into() };
    // every solver of both layouts looks ahead when asked (on more than one rank)
    let lookahead_used = lookahead;
    let lookahead = if lookahead { ", look-ahead on" } else { ", look-ahead off" };
    let mut line = format!(
        "solver {} (dense, {}), panel {}{lookahead}, precision {precision}, products {}",
        solved.used.name(),
        run.layout.name(comm.size()),
        solved.panel,
        gemm::describe(run.threads)
    );
    if let Some((_, how)) = &bordered {
        line.push_str(&format!("\n  second fit: {how}"));
    }
    let kinds: Vec<String> =
        CallKind::ALL.iter().zip(&by_kind).map(|(k, s)| format!("{} {s:.3} s", k.name())).collect();
    line.push_str(&format!("\n  comm wait by kind (max over ranks): {}", kinds.join(", ")));
    if let Some(r) = &solved.refinement {
        line.push_str(&format!("\n  refinement: {}", r.describe()));
    }
    if let Some(why) = &solved.mixed_fallback {
        line.push_str(&format!("\n  precision mixed fell back to f64: {why}"));
    }
    let refinement = solved.refinement.as_ref();
    Fitted {
        spline,
        coarse: Vec::new(),
        solver: if mixed {
            format!("{} (mixed)", solved.used.name())
        } else {
            solved.used.name().to_string()
        },
        residual,
        line,
        figures: [
            ("solver".into(), solved.used.name().into()),
            ("panel".into(), solved.panel.to_string()),
            ("lookahead".into(), lookahead_used.to_string()),
            ("gemm".into(), gemm::figure(run.threads).into()),
            ("layout".into(), run.layout.name(comm.size())),
            ("comm_calls".into(), calls.to_string()),
            ("system_size".into(), layout.n.to_string()),
            ("precision".into(), if mixed { "mixed" } else { "f64" }.into()),
            ("refinement_classical".into(), refinement.map_or(0, |r| r.classical).to_string()),
            ("refinement_gmres".into(), refinement.map_or(0, |r| r.gmres).to_string()),
            ("refinement_gmres_iterations".into(), refinement.map_or(0, |r| r.gmres_iterations).to_string()),
            ("precision_fallback".into(), solved.mixed_fallback.is_some().to_string()),
        ]
        .into_iter()
        .chain(
            CallKind::ALL
                .iter()
                .zip(&by_kind)
                .map(|(k, s)| (format!("comm_wait_{}_max_s", k.name()), format!("{s:.6}"))),
        )
        .chain([("bordered_from".into(), bordered.map_or(0, |(first, _)| first).to_string())])
        .collect(),
        factor: None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::linalg::dense::householder_solve;
    use crate::par::Solo;
    use crate::spline::full_system;
    use faer::MatRef;

    /// `count` points spread over a bumpy sphere and values in [-1, 1], deterministic.
    fn points(count: usize) -> (Vec<f64>, Vec<f64>) {
        let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
        let mut centres = Vec::new();
        let mut values = Vec::new();
        for i in 0..count {
            let z = 1.0 - 2.0 * (i as f64 + 0.5) / count as f64;
            let (r, a) = ((1.0 - z * z).sqrt(), golden * i as f64);
            let bump = 1.0 + 0.1 * (3.0 * a).sin() * z;
            centres.extend([bump * r * a.cos(), bump * r * a.sin(), bump * z]);
            values.push(((i * 7919) % 211) as f64 / 105.0 - 1.0);
        }
        (centres, values)
    }

    /// The first 150 centres factored, then 0 or 50 more appended and a few of the first values
    /// changed: the bordered solve matches a dense QR of the whole system, and the factor can be
    /// bordered twice.
    #[test]
    fn bordering_the_factor_solves_the_extended_system() {
        let kernel = Kernel::new(3, 2).unwrap();
        let (centres, values) = points(200);
        let n = 150;
        let layout = RowCyclic::new(n + 4, 1, 0);
        let job = Job::on(&Solo).panel(16);
        let rows = assemble(&kernel, &centres[..3 * n], &values[..n], layout).unwrap();
        let (_, first) =
            dist::solve_keeping(&job, SolverKind::Cholesky, rows, || unreachable!(), true).unwrap();
        let first = first.expect("the projected Cholesky keeps its factor");
        for total in [n, 200] {
            let mut v = values[..total].to_vec();
            (0..n).step_by(9).for_each(|i| v[i] = -v[i]);
            let (x, _) = solve_extended(&job, &kernel, &centres[..3 * total], &v, &first).unwrap();
            let size = total + 4;
            let (a, b) = full_system(&kernel, &centres[..3 * total], &v);
            let want = householder_solve(MatRef::from_column_major_slice(&a, size, size), &b).unwrap();
            let scale = want.iter().fold(0.0f64, |m, w| m.max(w.abs()));
            let err = x.iter().zip(&want).fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
            assert!(err < 1e-9 * scale, "{total} centres: max error {err:e} against {scale:e}");
        }
    }
}
