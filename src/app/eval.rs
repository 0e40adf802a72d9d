//! `volspline eval`: a saved model (scattered-point or contour), or an FRep expression over models
//! and carriers ([`crate::frep::expr`]), evaluated on a new grid, without solving again. Every rank
//! reads the small model files itself and all agree on the outcome.

use super::finite::{check_bounded, check_grid_field};
use super::preflight::{check_prefix, VOLUME_OUTPUTS};
use super::report::Report;
use super::stages::{Stage, Stages};
use std::path::{Path, PathBuf};

use super::volume::{check_grid, model_grid, throughput_line, write_volume, Volume, VolumeSummary};
use crate::cli::EvalArgs;
use crate::error::{Error, Result};
use crate::frep::{Expr, Implicit, ModelSolid};
use crate::grid::{padded_box, Grid};
use crate::io::contour_model_file::{self, read_contour_model};
use crate::io::h5::format_of;
use crate::io::model_file::read_model;
use crate::par::{agree, Comm};
use crate::spline::Model;
use crate::surface::support::DataSupport;

/// Runs `volspline eval`. Collective.
pub fn run(a: &EvalArgs, comm: &dyn Comm, threads: usize) -> Result<()> {
    let mut stages = Stages::default();
    let models = a.model.models();
    let inputs: Vec<&Path> = models.iter().map(PathBuf::as_path).collect();
    check_prefix(comm, &a.out, VOLUME_OUTPUTS, a.grid.timings.as_deref(), &inputs)?;
    let text = a.model.to_string();
    let mut r = Report::new("eval", Path::new(&text));
    r.figure("model", &text);
    let Some(path) = a.model.as_model() else {
        if a.trim.is_some() {
            return Err(Error::Usage(
                "--trim needs one model written by `fit` (its data points), not an expression".into(),
            ));
        }
        return expression(a, comm, threads, r, stages);
    };
    // an unreadable file is left to the scattered-point reader to report
    let is_contour = format_of(path).is_ok_and(|f| f == contour_model_file::FORMAT);
    if is_contour && a.trim.is_some() {
        return Err(Error::Usage(format!(
            "--trim needs a model of scattered points written by `fit`; {} is a contour model",
            path.display()
        )));
    }
    let per_node;
    let volume = if is_contour {
        let model = stages.time(Stage::Read, || agree(comm, read_contour_model(path)))?;
        let grid = model_grid(a.grid.grid, a.bounds, a.grid.margin.fraction, &model.provenance)?;
        check_grid(comm, &grid, a.grid.curvature)?;
        check_grid_field(comm, &model, &grid)?;
        let curvature = a.grid.curvature.then_some(&model as &dyn Implicit);
        let job = Volume::new(&model, grid, &a.out).curvature(curvature).grow(grows(a));
        let volume = write_volume(comm, job, &mut stages)?;
        r.line(format!(
            "contour model: {} slices, N = {} centres, interp {}, orient {}",
            model.sections.len(),
            model.centres(),
            model.interp.name(),
            model.orient.name()
        ));
        r.figure("slices", model.sections.len());
        r.figure("points", model.centres());
        per_node = 0;
        volume
    } else {
        let model = stages.time(Stage::Read, || agree(comm, read_model(path)))?;
        let grid = model_grid(a.grid.grid, a.bounds, a.grid.margin.fraction, &model.provenance)?;
        check_grid(comm, &grid, a.grid.curvature)?;
        check_grid_field(comm, &model, &grid)?;
        // grown as the fit grew its grid: not where the model is unbounded
        let grow = grows(a) && check_bounded(&model).is_none();
        let support = a.trim.map(|f| data_support(&model, path, f)).transpose()?;
        let solid = a.grid.curvature.then(|| ModelSolid::new(model.clone()));
        let curvature = solid.as_ref().map(|s| s as &dyn Implicit);
        let job = Volume::new(&model, grid, &a.out).curvature(curvature).grow(grow).trim(support.as_ref());
        let volume = write_volume(comm, job, &mut stages)?;
        let n = model.centre_count();
        let levels = if model.coarse.is_empty() {
            String::new()
        } else {
            let coarse: Vec<String> =
                model.coarse.iter().map(|s| format!("{} ({} centres)", s.kernel.name(), s.len())).collect();
            format!(" on coarse levels {}", coarse.join(", "))
        };
        r.line(format!(
            "N = {n} centres, kernel {}{levels}, carrier {}",
            model.spline.kernel.name(),
            model.carrier
        ));
        // the model's data points where it records them (as `fit` counted them), and its centres
        let data = model.provenance.data_points;
        r.figure("points", if data > 0 { data } else { n });
        r.figure("centres", n);
        per_node = volume.evals_per_node;
        r.figure("kernel_evals", volume.nodes_evaluated as f64 * per_node as f64);
        volume
    };
    finish(a, comm, threads, r, stages, volume, per_node)
}

/// An expression: its models read (every rank), evaluated on the box of its data plus the margin
/// (or `--bounds`). Collective.
fn expression(
    a: &EvalArgs,
    comm: &dyn Comm,
    threads: usize,
    mut r: Report,
    mut stages: Stages,
) -> Result<()> {
    let expr = stages.time(Stage::Read, || agree(comm, Expr::load(&a.model)))?;
    let (lo, hi) = match (a.bounds, expr.domain()) {
        (Some(b), _) => b,
        (None, Some((lo, hi))) => padded_box(&lo, &hi, a.grid.margin.fraction),
        (None, None) => {
            return Err(Error::Usage(format!(
                "the expression '{}' has no model or carrier to take a box from: give --bounds",
                a.model
            )))
        }
    };
    let grid = Grid::covering(lo, hi, a.grid.grid)?;
    check_grid(comm, &grid, a.grid.curvature)?;
    check_grid_field(comm, &expr, &grid)?;
    let curvature = a.grid.curvature.then_some(&expr as &dyn Implicit);
    // an expression's box is the caller's to choose (a difference or intersection may be meant
    // to be cut by it, a half-space is unbounded): it does not grow
    let volume = write_volume(comm, Volume::new(&expr, grid, &a.out).curvature(curvature), &mut stages)?;
    r.line(format!("expression {}: {} kernel evaluations per node", a.model, volume.evals_per_node));
    let per_node = volume.evals_per_node;
    r.figure("kernel_evals", volume.nodes_evaluated as f64 * per_node as f64);
    finish(a, comm, threads, r, stages, volume, per_node)
}

/// Whether the grid of a model may grow where the solid reaches it: as in the fit, and not in a
/// box given by `--bounds`.
fn grows(a: &EvalArgs) -> bool {
    a.grid.may_grow() && a.bounds.is_none()
}

/// The support of the data points `model` records (the first `data_points` centres of its finest
/// level, in the caller's coordinates) at `factor` times their median spacing.
fn data_support(model: &Model, path: &Path, factor: f64) -> Result<DataSupport> {
    DataSupport::of_model(model, factor).ok_or_else(|| {
        Error::Usage(format!(
            "{} does not record which of its centres are the data points (a model written before \
             volspline recorded them): fit it again with --trim",
            path.display()
        ))
    })
}

fn finish(
    a: &EvalArgs,
    comm: &dyn Comm,
    threads: usize,
    mut r: Report,
    stages: Stages,
    volume: VolumeSummary,
    per_node: usize,
) -> Result<()> {
    r.line(format!("ranks = {}, threads per rank = {threads}", comm.size()));
    r.figure("ranks", comm.size());
    r.figure("threads", threads);
    volume.report(&mut r);
    let nodes = volume.nodes_evaluated;
    r.finish(
        comm,
        &stages,
        &|t| throughput_line(nodes, per_node, t.max(Stage::Evaluate)),
        a.grid.timings.as_deref(),
    )?;
    Ok(())
}
