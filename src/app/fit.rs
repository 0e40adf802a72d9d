//! `volspline fit`: scattered points -> the solid. Rank 0 reads the points and every rank gets
//! them; hygiene runs identically everywhere; each rank assembles its row-cyclic rows of the
//! bordered system; the distributed solver returns the coefficients on every rank; the residual and
//! |f| at the data are checked in parallel; rank 0 writes the model; the volume outputs follow.

use std::path::Path;

use faer::Par;
use rayon::prelude::*;

use super::preflight::{check_memory, check_prefix, dense_fit_bytes};
use super::progress::Progress;
use super::report::{run_provenance, Report};
use super::stages::{Stage, Stages};
use super::volume::{check_grid, output_path, throughput_line, write_volume};
use crate::cli::FitArgs;
use crate::error::Result;
use crate::grid::{padded_box, Grid};
use crate::io::{self, model_file, points};
use crate::linalg::dist::{self, Job, LocalRows, RowCyclic};
use crate::par::{agree, on_root, Comm};
use crate::spline::hygiene::{prepare, Prepared};
use crate::spline::{fill_rows, residual_parts, Evaluator, Kernel, Model, Provenance, Spline};

/// Reads the input points on rank 0 and gives them to every rank, 3 values per point.
fn read_points_everywhere(comm: &dyn Comm, path: &Path) -> Result<Vec<f64>> {
    let local = if comm.rank() == 0 {
        points::read_points(path).map(|set| Some(set.points.iter().flatten().copied().collect::<Vec<f64>>()))
    } else {
        Ok(None)
    };
    let mine = agree(comm, local)?;
    Ok(comm.broadcast_value(0, mine))
}

/// This rank's rows of the bordered system of `kernel` through `values` at `centres`.
pub fn assemble(kernel: &Kernel, centres: &[f64], values: &[f64], layout: RowCyclic) -> LocalRows {
    let k = kernel.poly_count();
    let mut rows = LocalRows::zeros(layout, layout.n + 1, k);
    let globals: Vec<usize> = (0..layout.local_count()).map(|l| layout.global(l)).collect();
    fill_rows(kernel, centres, values, &globals, &mut rows.data);
    rows
}

/// Runs `volspline fit`. Collective.
pub fn run(a: &FitArgs, comm: &dyn Comm, threads: usize) -> Result<()> {
    let mut stages = Stages::default();
    check_prefix(comm, &a.out)?;
    let raw = stages.time(Stage::Read, || read_points_everywhere(comm, &a.input))?;
    let points_read = raw.len() / 3;
    let Prepared { points: pts, centres, values, carrier, norm, merged, box_lo: lo, box_hi: hi } =
        prepare(&raw, &a.kernel, &a.carrier, a.merge_tol)?;
    let n = values.len();
    if comm.rank() == 0 {
        eprintln!(
            "volspline fit: {points_read} points read from {}, {merged} duplicates merged, N = {n}, kernel {}, carrier {carrier}",
            a.input.display(),
            a.kernel.name()
        );
    }

    let system = n + a.kernel.poly_count();
    let (plo, phi) = padded_box(&lo, &hi, a.grid.margin);
    let grid = Grid::covering(plo, phi, a.grid.grid)?;
    check_memory(
        comm,
        dense_fit_bytes(system, comm.size()),
        &format!("the dense system of {system} rows ({n} points)"),
        "use more ranks or nodes (the rows are split over all ranks) or fewer points",
    )?;
    check_grid(comm, &grid)?;

    let layout = RowCyclic::new(system, comm.size(), comm.rank());
    let rows = stages.time(Stage::Assemble, || assemble(&a.kernel, &centres, &values, layout));
    let progress = Progress::new("solve", comm);
    let solved = stages.time(Stage::Solve, || {
        let report = |d, t| progress.update(d, t);
        let job = Job::on(comm).panel(a.panel).par(Par::rayon(threads)).progress(&report);
        dist::solve(&job, a.solver, rows, || assemble(&a.kernel, &centres, &values, layout))
    })?;
    if let (Some(why), 0) = (&solved.fallback, comm.rank()) {
        eprintln!("volspline: cholesky: {}; fell back to LU", why.root());
    }
    let spline = Spline::from_solution(a.kernel, centres, &solved.x, norm);

    let (residual, max_abs) = stages.time(Stage::Check, || {
        let globals: Vec<usize> = (0..layout.local_count()).map(|l| layout.global(l)).collect();
        let mut parts = residual_parts(&a.kernel, &spline.centres, &values, &globals, &solved.x).to_vec();
        comm.sum_f64(&mut parts);
        let residual = if parts[1] > 0.0 { (parts[0] / parts[1]).sqrt() } else { parts[0].sqrt() };
        // max |f| at this rank's share of the points, with the blocked evaluator
        let ev = Evaluator::new(&spline);
        let mine: Vec<&[f64]> = pts.chunks_exact(3).skip(comm.rank()).step_by(comm.size()).collect();
        let mut m = [mine
            .par_iter()
            .map(|p| {
                let mut u = [0.0];
                ev.eval_row(&p[..1], p[1], p[2], &mut u);
                (carrier.eval(p) - u[0]).abs()
            })
            .reduce(|| 0.0, f64::max)];
        comm.max_f64(&mut m);
        (residual, m[0])
    });
    let model = Model {
        carrier,
        spline,
        provenance: Provenance {
            input: a.input.display().to_string(),
            box_lo: [lo[0], lo[1], lo[2]],
            box_hi: [hi[0], hi[1], hi[2]],
            points_read,
            duplicates_merged: merged,
            solver: solved.used.name().to_string(),
            residual,
            ..run_provenance(comm, threads, &stages)
        },
    };
    let model_path = output_path(&a.out, ".model.h5");
    stages.time(Stage::Write, || {
        on_root(comm, || io::write_atomically(&model_path, |tmp| model_file::write_model(tmp, &model)))
    })?;

    let volume = write_volume(comm, &model, &grid, &a.out, &mut stages)?;

    let mut r = Report::new("fit", &a.input);
    r.line(format!(
        "N = {n} points ({points_read} read, {merged} duplicates merged), kernel {}, solver {}, panel {}",
        a.kernel.name(),
        solved.used.name(),
        solved.panel
    ));
    r.line(format!("ranks = {}, threads per rank = {threads}", comm.size()));
    r.line(format!("relative residual |Mx - b|/|b| = {residual:.3e}"));
    r.line(format!("max |f| at the data points   = {max_abs:.3e}"));
    r.figure("input", a.input.display());
    r.figure("points", n);
    r.figure("system_size", system);
    r.figure("kernel", a.kernel.name());
    r.figure("solver", solved.used.name());
    r.figure("panel", solved.panel);
    r.figure("ranks", comm.size());
    r.figure("threads", threads);
    r.figure("residual", format!("{residual:e}"));
    r.figure("max_abs_f_at_points", format!("{max_abs:e}"));
    r.figure("kernel_evals", grid.node_count() as f64 * n as f64);
    r.output(&model_path);
    volume.report(&mut r);
    let nodes = grid.node_count();
    r.finish(
        comm,
        &stages,
        &|t| {
            let mut l = throughput_line(nodes, n, t.max(Stage::Evaluate));
            l.push(format!(
                "Table 2 columns: matrix formation {:.3} s, solution of the SLAE {:.3} s, evaluation of {nodes} grid nodes {:.3} s",
                t.max(Stage::Assemble),
                t.max(Stage::Solve),
                t.max(Stage::Evaluate)
            ));
            l
        },
        a.grid.timings.as_deref(),
    )?;
    Ok(())
}
