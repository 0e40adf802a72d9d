//! The dense method: each rank assembles its row-cyclic rows of the bordered system of a global
//! Green's function (or of any kernel: a compactly supported one gives the dense oracle of the
//! sparse method), and the distributed dense solvers factor it without ever gathering it.

use faer::Par;

use super::{Fitted, Run};
use crate::app::preflight::{check_memory, dense_fit_bytes};
use crate::app::progress::Progress;
use crate::app::stages::{Stage, Stages};
use crate::cli::FitArgs;
use crate::error::Error;
use crate::error::Result;
use crate::linalg::dist::{
    self, Job, Layout, LocalBlocks, LocalRows, Precision, ProcessGrid, RowCyclic, SolverKind,
};
use crate::par::{CallKind, Comm, Timed};
use crate::spline::hygiene::Prepared;
use crate::spline::{fill_block, fill_rows, residual_parts, Kernel, Spline};

/// This rank's rows of the bordered system of `kernel` through `values` at `centres`.
pub fn assemble(kernel: &Kernel, centres: &[f64], values: &[f64], layout: RowCyclic) -> LocalRows {
    let k = kernel.poly_count();
    let mut rows = LocalRows::zeros(layout, layout.n + 1, k);
    let globals: Vec<usize> = (0..layout.local_count()).map(|l| layout.global(l)).collect();
    fill_rows(kernel, centres, values, &globals, &mut rows.data);
    rows
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
) -> LocalBlocks {
    let n = values.len() + kernel.poly_count();
    let mut a = LocalBlocks::zeros(grid, n, nb);
    fill_block(kernel, centres, values, &a.rows.globals(), &a.cols.globals(), &mut a.data);
    a
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

/// Refuses a dense system that does not fit in the ranks' memory. Collective.
pub fn check(comm: &dyn Comm, kernel: &Kernel, n: usize, precision: Precision) -> Result<()> {
    let system = n + kernel.poly_count();
    check_memory(
        comm,
        dense_fit_bytes(system, comm.size(), precision),
        &format!("the dense system of {system} rows ({n} points)"),
        "use --method csrbf (compactly supported, sparse), more ranks or nodes (the rows are split over all ranks) or fewer points",
    )
}

/// Fits the spline of `kernel` to the prepared points with the dense solvers. Collective.
pub fn fit(run: &Run<'_>, kernel: Kernel, prep: &Prepared, stages: &mut Stages) -> Result<Fitted> {
    let Run { args: a, comm, threads } = *run;
    let (centres, values) = (&prep.centres, &prep.values);
    let layout = RowCyclic::new(values.len() + kernel.poly_count(), comm.size(), comm.rank());
    let progress = Progress::new("solve", comm);
    let timed = Timed::new(comm);
    let report = |d, t| progress.update(d, t);
    let rows = values.len() + kernel.poly_count();
    let lookahead = lookahead_for(a.lookahead.0, a.layout.shape(comm.size()), a.solver, rows);
    let job = Job::on(&timed).panel(a.panel).par(Par::rayon(threads)).progress(&report).lookahead(lookahead);
    let solved = match a.layout {
        Layout::RowCyclic => {
            let rows = stages.time(Stage::Assemble, || assemble(&kernel, centres, values, layout));
            stages.time(Stage::Solve, || {
                dist::solve_in(&job, a.solver, a.precision, rows, || {
                    assemble(&kernel, centres, values, layout)
                })
            })
        }
        Layout::BlockCyclic(_) => {
            let shape = a.layout.shape(comm.size()).expect("a 2D layout has a grid");
            let grid = ProcessGrid::new(&timed, shape)?;
            let nb = if a.panel > 0 {
                a.panel
            } else {
                a.solver.default_block_2d(values.len() + kernel.poly_count())
            };
            let assemble = || assemble_blocks(&kernel, centres, values, &grid, nb);
            let blocks = stages.time(Stage::Assemble, assemble);
            let k = kernel.poly_count();
            stages.time(Stage::Solve, || dist::solve_2d(&job, &grid, a.solver, k, blocks, assemble))
        }
    };
    stages.add(Stage::CommWait, timed.seconds());
    let calls = timed.calls();
    // the slowest rank's wait in each kind of call
    let mut by_kind: Vec<f64> = CallKind::ALL.iter().map(|&k| timed.seconds_in(k)).collect();
    comm.max_f64(&mut by_kind);
    let solved = solved?;
    if let (Some(why), 0) = (&solved.mixed_fallback, comm.rank()) {
        eprintln!("volspline: precision mixed: {why}; solved in f64 with {}", solved.used.name());
    }
    if let (Some(why), 0) = (&solved.fallback, comm.rank()) {
        eprintln!("volspline: cholesky: {}; fell back to LU", why.root());
    }
    let residual = stages.time(Stage::Check, || {
        let globals: Vec<usize> = (0..layout.local_count()).map(|l| layout.global(l)).collect();
        let mut parts = residual_parts(&kernel, centres, values, &globals, &solved.x).to_vec();
        comm.sum_f64(&mut parts);
        if parts[1] > 0.0 {
            (parts[0] / parts[1]).sqrt()
        } else {
            parts[0].sqrt()
        }
    });
    let spline = Spline::from_solution(kernel, centres.clone(), &solved.x, prep.norm);
    let mixed = solved.mixed_fallback.is_none() && solved.refinement.is_some();
    let precision =
        if mixed { format!("mixed (f32 {}, f64 refinement)", solved.used.name()) } else { "f64".into() };
    // every solver of both layouts looks ahead when asked (on more than one rank)
    let lookahead_used = lookahead;
    let lookahead = if lookahead { ", look-ahead on" } else { ", look-ahead off" };
    let mut line = format!(
        "solver {} (dense, {}), panel {}{lookahead}, precision {precision}",
        solved.used.name(),
        a.layout.name(comm.size()),
        solved.panel
    );
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
    Ok(Fitted {
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
            ("layout".into(), a.layout.name(comm.size())),
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
        .collect(),
    })
}
