//! `volspline fit`: scattered points -> the solid. Rank 0 reads the points and every rank gets
//! them; hygiene runs identically everywhere; the surface method may add off-surface points
//! ([`surface`]); the method (dense or compactly supported) is chosen
//! and checked against the memory; the method fits the spline; |f| at the data is checked in
//! parallel; rank 0 writes the model; the volume outputs follow.

pub mod compact;
pub mod dense;
pub mod levels;
pub mod surface;

use std::path::Path;

use rayon::prelude::*;

use super::preflight::{available_beside, check_prefix, dense_fit_bytes, MODEL_OUTPUTS};
use super::render::{preview_view, write_picture};
use super::report::{run_provenance, Report};
use super::stages::{Stage, Stages};
use super::volume::{check_grid, output_path, throughput_line, write_volume, Volume};
use crate::cli::{FitArgs, FitCarrier, KernelChoice, Method, SideVote};
use crate::error::{Error, Result};
use crate::frep::raycast::Colouring;
use crate::frep::{Implicit, ModelSolid};
use crate::grid::{padded_box, Grid};
use crate::io::{self, model_file, points};
use crate::linalg::dist::Layout;
use crate::par::{agree, on_root, Comm};
use crate::spline::carrier::Carrier;
use crate::spline::compact::{default_support, DEFAULT_NEIGHBOURS};
use crate::spline::hygiene::{
    isolated_points, prepare, Prepared, ISOLATION_FACTOR, ISOLATION_NEIGHBOUR, STRAY_GROUP_SHARE,
};
use crate::spline::system::power_of_two_below_inverse;
use crate::spline::{Evaluator, Kernel, Model, Provenance, Spline};
use crate::surface::support::DataSupport;

pub use dense::{assemble, assemble_blocks, assemble_blocks_lower, assemble_lower, solve_extended};

/// What every method is given: the command's arguments, the ranks and the threads per rank.
#[derive(Clone, Copy)]
pub struct Run<'a> {
    pub args: &'a FitArgs,
    pub comm: &'a dyn Comm,
    pub threads: usize,
    /// The dense layout, `--layout` with `auto` resolved for this fit.
    pub layout: Layout,
}

/// What a method produced.
pub struct Fitted {
    /// The finest level (the only one of a single-level fit).
    pub spline: Spline,
    /// Coarser levels, coarsest first (see [`levels`]).
    pub coarse: Vec<Spline>,
    /// The solver, as the model file records it.
    pub solver: String,
    /// ||M x - b|| / ||b|| of the whole bordered system.
    pub residual: f64,
    /// The report line that describes the method's run.
    pub line: String,
    /// The method's own figures for the CSV record.
    pub figures: Vec<(String, String)>,
    /// The factor of a dense first fit, kept for a second fit that borders it.
    pub factor: Option<dense::KeptFactor>,
}

/// What a fit says of the `isolated` points of `raw` (indices), kept or `dropped`: how many,
/// the first few by their number in the file, and what they do.
fn isolated_line(raw: &[f64], isolated: &[usize], dropped: bool) -> String {
    const SHOWN: usize = 5;
    let mut named: Vec<String> = isolated
        .iter()
        .take(SHOWN)
        .map(|&i| format!("#{} ({:.4e}, {:.4e}, {:.4e})", i + 1, raw[3 * i], raw[3 * i + 1], raw[3 * i + 2]))
        .collect();
    if isolated.len() > SHOWN {
        named.push(format!("and {} more", isolated.len() - SHOWN));
    }
    format!(
        "{} of the {} points are isolated (their {}th nearest neighbour more than {} times the median such \
         distance away, or in a group of at most {} % of the points that far from the rest; stray returns?): \
         {}; {}",
        isolated.len(),
        raw.len() / 3,
        ISOLATION_NEIGHBOUR,
        ISOLATION_FACTOR,
        100.0 * STRAY_GROUP_SHARE,
        named.join(", "),
        if dropped {
            "left out of the fit (--drop-isolated off fits them)"
        } else {
            "fitted as they are (--drop-isolated off), which stretches the carrier and the grid towards them"
        }
    )
}

/// Reads the input points on rank 0 and gives them to every rank, 3 values per point.
fn read_points_everywhere(comm: &dyn Comm, path: &Path) -> Result<Vec<f64>> {
    let local = if comm.rank() == 0 {
        points::read_points(path).map(|set| {
            if let Some(note) = &set.note {
                crate::note!("volspline fit: {}: {note}", path.display());
            }
            Some(set.points.iter().flatten().copied().collect::<Vec<f64>>())
        })
    } else {
        Ok(None)
    };
    let mine = agree(comm, local)?;
    Ok(comm.broadcast_value(0, mine))
}

/// Dense flop rate per rank assumed by `--method auto` to predict the solve time it reports and
/// decides by (the projected Cholesky ran at 73 to 84 GFLOP/s per rank on one and two ranks of a
/// 2-core AVX-512 machine at 8000 rows; a slower node is allowed for).
const DENSE_FLOPS_PER_RANK: f64 = 60e9;

/// The longest predicted dense solve `--method auto` accepts before it turns to the sparse
/// method. The off-surface fit solves its system and borders the factor several times, so the
/// whole fit takes a few times this.
const DENSE_SECONDS: f64 = 15.0;

/// Wendland kernel of `smoothness` (0, 1, 2) with `--support` or the default support.
fn wendland(a: &FitArgs, smoothness: u8, centres: &[f64]) -> Result<Kernel> {
    let name = ["wendland0", "wendland2", "wendland4"][smoothness.min(2) as usize];
    let support = a.support.unwrap_or_else(|| default_support(centres, DEFAULT_NEIGHBOURS));
    Kernel::wendland(name, support)
}

/// The memory per rank that `auto` may count on for the dense system, or that a rank holding
/// `held` bytes may take on top of them: the least any rank has, so that every rank makes the
/// same choice (each reads its own node's memory, at its own moment). Collective.
fn agreed_room(comm: &dyn Comm, held: f64) -> f64 {
    let mut room = [available_beside(held).map_or(f64::INFINITY, |(b, _)| b)];
    comm.min_f64(&mut room);
    room[0]
}

/// The method and the kernel (with `--smooth`) of a run of `n` points on `ranks` ranks with
/// `room` bytes per rank for a dense system ([`agreed_room`]), and why they were chosen.
fn choose(
    a: &FitArgs,
    n: usize,
    (ranks, room): (usize, f64),
    centres: &[f64],
) -> Result<(Method, Kernel, String)> {
    let asked = || "as asked".to_string();
    let (method, kernel, why) = match (a.method, a.kernel) {
        (Method::Csrbf, KernelChoice::Global(k)) => {
            return Err(Error::Usage(format!(
            "--method csrbf needs a compactly supported kernel (wendland0, wendland2 or wendland4), not {}",
            k.name()
        )))
        }
        (Method::Dense, KernelChoice::Global(k)) => (Method::Dense, k, asked()),
        (Method::Auto, KernelChoice::Global(k)) => {
            (Method::Dense, k, format!("auto: kernel {} is globally supported", k.name()))
        }
        (Method::Dense, KernelChoice::Auto) => (Method::Dense, Kernel::new(3, 2)?, asked()),
        (Method::Dense, KernelChoice::Wendland(s)) => (Method::Dense, wendland(a, s, centres)?, asked()),
        (Method::Csrbf, KernelChoice::Wendland(s)) => (Method::Csrbf, wendland(a, s, centres)?, asked()),
        (Method::Auto, KernelChoice::Wendland(s)) => {
            let k = wendland(a, s, centres)?;
            let why = format!("auto: kernel {} is compactly supported", k.name());
            (Method::Csrbf, k, why)
        }
        (Method::Csrbf, KernelChoice::Auto) => (Method::Csrbf, wendland(a, 1, centres)?, asked()),
        (Method::Auto, KernelChoice::Auto) => {
            let r = Kernel::new(3, 2)?;
            let system = n + r.poly_count();
            let lower = dense::lower_for(a.solver, &r, system);
            let panel = dense::estimate_panel(a.panel, a.solver, system);
            let bytes = dense_fit_bytes(system, ranks, a.precision, lower, panel);
            let seconds = (system as f64).powi(3) / 3.0 / (DENSE_FLOPS_PER_RANK * ranks as f64);
            if bytes <= room && seconds <= DENSE_SECONDS {
                let why = format!("auto: the dense system fits and should solve in about {seconds:.0} s");
                (Method::Dense, r, why)
            } else {
                let why = format!(
                    "auto: the dense system would need {:.1} GB per rank and about {seconds:.0} s",
                    bytes / 1e9
                );
                (Method::Csrbf, wendland(a, 1, centres)?, why)
            }
        }
    };
    Ok((method, kernel.with_smoothing(a.smooth)?, why))
}

/// The warnings about options given on the command line that have no effect on this fit: `off`,
/// whether it has off-surface constraints; `method`, dense or compactly supported (`two_levels`:
/// the compactly supported level on a dense level 0, which takes the dense solvers' options).
fn idle_options(a: &FitArgs, off: bool, method: Method, two_levels: bool) -> Vec<String> {
    const OFF_SURFACE: &[&str] = &[
        "off_points",
        "doubtful_share",
        "off_deal",
        "denoise",
        "orient_side",
        "orient_energy",
        "orient_rays",
        "orient_by_side",
        "blob_choice",
        "restore_solid",
        "orient_turns",
        "outside_points",
        "mouth_points",
        "mouth_slope",
        "cap_bulge",
        "coarse_points",
    ];
    let groups: [(&[&str], bool, &str); 4] = [
        (OFF_SURFACE, !off, "the off-surface method, and this fit is the plain carrier method (--surface)"),
        (
            &["coarse_points"],
            off && !two_levels,
            "level 0 of the two-level compactly supported fit, and this fit is dense",
        ),
        (
            &["support", "leaf", "sparse_solver"],
            method == Method::Dense,
            "the compactly supported method, and this fit is dense (--method)",
        ),
        (
            &["solver", "precision", "panel", "lookahead", "layout"],
            method == Method::Csrbf && !two_levels,
            "the dense solvers, and this fit is compactly supported (--method)",
        ),
    ];
    let mut named: Vec<&str> = Vec::new();
    let mut out = Vec::new();
    for (ids, _, of) in groups.iter().filter(|g| g.1) {
        let given: Vec<String> = ids
            .iter()
            .filter(|id| a.given.iter().any(|g| g == *id) && !named.contains(id))
            .map(|id| format!("--{}", id.replace('_', "-")))
            .collect();
        named.extend(ids.iter().copied());
        match given.len() {
            0 => {}
            1 => out.push(format!("{} has no effect on this fit: an option of {of}", given[0])),
            _ => out.push(format!("{} have no effect on this fit: options of {of}", given.join(", "))),
        }
    }
    out
}

/// Says on rank 0 which of the options given have no effect on this fit ([`idle_options`]).
fn warn_idle_options(comm: &dyn Comm, a: &FitArgs, off: bool, method: Method, two_levels: bool) {
    if comm.rank() == 0 {
        for w in idle_options(a, off, method, two_levels) {
            crate::note!("volspline: warning: {w}");
        }
    }
}

/// Runs `volspline fit`. Collective.
pub fn run(a: &FitArgs, comm: &dyn Comm, threads: usize) -> Result<()> {
    let mut stages = Stages::default();
    crate::linalg::gemm::choose_agreed(comm, a.gemm);
    dense::check_layout(a, comm.size())?;
    compact::check_solver(a, comm.size())?;
    check_prefix(comm, &a.out, MODEL_OUTPUTS, a.grid.timings.as_deref(), &[&a.input])?;
    let raw = stages.time(Stage::Read, || read_points_everywhere(comm, &a.input))?;
    let points_read = raw.len() / 3;
    // the same points on every rank, so the same isolated ones
    let isolated = stages.time(Stage::Read, || isolated_points(&raw));
    if comm.rank() == 0 && !isolated.is_empty() {
        let line = isolated_line(&raw, &isolated, a.drop_isolated);
        if a.drop_isolated {
            crate::note!("volspline fit: {line}");
        } else {
            crate::note!("volspline: warning: {line}");
        }
    }
    let raw = if a.drop_isolated && !isolated.is_empty() {
        let mut keep = vec![true; points_read];
        isolated.iter().for_each(|&i| keep[i] = false);
        raw.chunks_exact(3).zip(keep).filter(|(_, k)| *k).flat_map(|(p, _)| p.iter().copied()).collect()
    } else {
        raw
    };
    // hygiene needs only the polynomial part, linear for every kernel but r3
    let base = match a.kernel {
        KernelChoice::Global(k) => k,
        _ => Kernel::new(3, 2)?,
    };
    // the points' geometry refused (too few, all on one plane) is the input file's fault
    // under `auto` the data are prepared with the off-surface fit's ellipsoid (whose values are of
    // order one at any scale) and the plain carrier method's ball replaces it below where the fit
    // has no off points, so that the ball's overflow refuses only the fits that use it
    let given = match &a.carrier {
        FitCarrier::Given(c) => c.clone(),
        FitCarrier::Auto => surface::AUTO_CARRIER,
    };
    let in_input = |e| match e {
        Error::Numerical(m) => Error::input(&a.input, "", m),
        other => other,
    };
    let mut prep = prepare(&raw, &base, &given, a.merge_tol).map_err(in_input)?;
    let n = prep.values.len();
    let off = surface::with_off_surface(a.surface, n);
    if !off && a.carrier == FitCarrier::Auto {
        prep = prep.with_carrier(&Carrier::AutoBall).map_err(in_input)?;
    }
    let layout = a.layout.resolve(comm.size(), n + base.poly_count(), a.precision);
    let run = Run { args: a, comm, threads, layout };
    let (plo, phi) = padded_box(&prep.box_lo, &prep.box_hi, a.grid.margin.fraction);
    let grid = Grid::covering(plo, phi, a.grid.grid)?;
    // the compactly supported method with off-surface constraints fits two levels: a dense
    // off-surface fit of a subsample, and the Wendland spline through all points on top of it
    // (levels.rs). The choice is made for the most rows the off points can add (the choice is
    // monotone in the rows), so a dense choice below holds once they are known
    let machine = (comm.size(), agreed_room(comm, 0.0));
    let most_rows = n + (a.off_points * n as f64).ceil() as usize;
    let most = off.then(|| choose(a, most_rows, machine, &prep.centres)).transpose()?;
    // the two-level fit takes the method and kernel chosen for those rows: `auto` may find the
    // data alone small enough for a dense fit where their off points are not
    let two_level = most.filter(|(method, _, _)| *method == Method::Csrbf);
    if a.denoise.0 == Some(true) && (!off || two_level.is_some()) {
        return Err(Error::Usage(format!(
            "--denoise on moves the data of the dense off-surface fit; this fit is {} (use --surface \
             offsurface with --method dense, or leave --denoise off)",
            if off { "the two-level compactly supported one" } else { "the plain carrier method" }
        )));
    }
    if a.orient_side == SideVote::Both && off && two_level.is_some() {
        return Err(Error::Usage(
            "--orient-side both makes the dense off-surface fit twice; this fit is the two-level compactly \
             supported one (use --method dense, or --orient-side try, on or off)"
                .to_string(),
        ));
    }
    // auto: the scale test of the quadrics' misfit on the unoriented normals
    let (auto, mut hoods) = match a.denoise.0 {
        None if off && two_level.is_none() => {
            let (ratio, hoods) = stages.time(Stage::Normals, || -> Result<_> {
                let hoods = agree(comm, crate::surface::neighbourhoods_on(comm, &prep.centres))?;
                let r = crate::surface::denoise::scale_ratio_on(
                    comm,
                    &prep.centres,
                    &hoods.normals,
                    &hoods.knn,
                    hoods.kmax,
                );
                Ok((r, hoods))
            })?;
            (Some(ratio), Some(hoods))
        }
        _ => (None, None),
    };
    let denoise = a.denoise.0.unwrap_or(false)
        || auto.is_some_and(|(_, _, ratio)| ratio < crate::surface::denoise::NOISE_RATIO);
    let auto_part = auto.map_or(String::new(), |(small, large, ratio)| {
        format!(
            "auto, misfit over 19 / 9 neighbours {:.3e} / {:.3e} = {ratio:.2} ({} {}): ",
            large * prep.norm.scale,
            small * prep.norm.scale,
            if ratio < crate::surface::denoise::NOISE_RATIO {
                "noise, below"
            } else {
                "curvature, not below"
            },
            crate::surface::denoise::NOISE_RATIO
        )
    });
    // the projection's report: moved points, and the noise estimate and longest move in the
    // data's units; the normals it projects along oriented with the side vote where `side`
    let denoise_step = |prep: Prepared,
                        side: bool,
                        hoods: &mut Option<crate::surface::Neighbourhoods>,
                        stages: &mut Stages| {
        if !denoise {
            let line = auto.map(|_| (format!("denoise: {auto_part}not applied"), 0, 0.0, 0.0));
            return Ok((prep, line));
        }
        let (moved, d) = surface::denoise(&run, &prep, hoods.take(), side, stages)?;
        let scale = prep.norm.scale;
        let line = format!(
            "denoise: {auto_part}{} of {n} points moved onto quadrics of their same-sheet neighbours, noise \
             estimate {:.3e} ({:.3} % of the diagonal), longest move {:.3e}",
            d.moved,
            d.noise * scale,
            100.0 * d.noise / 2.0,
            d.max_move * scale
        );
        if comm.rank() == 0 {
            crate::note!("volspline fit: {line}");
        }
        Ok::<_, Error>((moved, Some((line, d.moved, d.noise * scale, d.max_move * scale))))
    };
    let two_levels = two_level.is_some();
    let (prep, denoised, fitted, summary, method, kernel, why) = if let Some((method, kernel, why)) =
        two_level
    {
        let (prep, denoised) = denoise_step(prep, a.orient_side == SideVote::On, &mut hoods, &mut stages)?;
        warn_idle_options(comm, a, off, method, true);
        // level 0 takes as many points as its dense fit has room for, up to --coarse-points
        let coarse = levels::level0_points(a, n, machine)?;
        if comm.rank() == 0 {
            crate::note!(
                "volspline fit: {points_read} points read from {}, {} duplicates merged, N = {n}, two levels: \
                 dense r on up to {coarse} of them{}, then kernel {}, carrier {}",
                a.input.display(),
                prep.merged,
                if coarse < a.coarse_points.min(n) {
                    format!(
                        " (the most whose dense off-surface fit fits the ranks' memory; --coarse-points {})",
                        a.coarse_points
                    )
                } else {
                    String::new()
                },
                kernel.name(),
                prep.carrier
            );
        }
        check_grid(comm, &grid, a.grid.curvature)?;
        let (fitted, summary) = levels::fit(&run, kernel, &prep, coarse, &mut stages)?;
        super::finite::check_fit(&fitted, &prep)?;
        (prep, denoised, fitted, Some(summary), method, kernel, why)
    } else {
        // the fit from the off-surface points on (the plain carrier's where there are none), with
        // the normals oriented with the side vote or without it
        let single = |prep: Prepared,
                      side: bool,
                      mut hoods: Option<crate::surface::Neighbourhoods>,
                      stages: &mut Stages,
                      first: bool|
         -> Result<_> {
            let (prep, denoised) = denoise_step(prep, side, &mut hoods, stages)?;
            let mut constrained =
                if off { Some(surface::constrain(&run, &prep, hoods, side, stages)?) } else { None };
            // the spline's centres and values: the data's, with the off-surface points after them
            let fit_prep = constrained.as_ref().map_or(&prep, |c| &c.prep);
            let first_summary = constrained.as_ref().map(|c| c.summary.clone());
            let rows = fit_prep.values.len();
            let (method, kernel, why) = choose(a, rows, machine, &fit_prep.centres)?;
            if first {
                warn_idle_options(comm, a, off, method, false);
            }
            if comm.rank() == 0 {
                crate::note!(
                    "volspline fit: {points_read} points read from {}, {} duplicates merged, N = {n}{}, kernel {}, carrier {}",
                    a.input.display(),
                    prep.merged,
                    first_summary.as_ref().map_or(String::new(), |s| format!(" + {} off-surface points", s.off_points)),
                    kernel.name(),
                    prep.carrier
                );
            }
            if method != Method::Csrbf {
                dense::check(comm, &kernel, rows, a)?;
            }
            check_grid(comm, &grid, a.grid.curvature)?;
            // the second fit against spurious blobs has more rows: checked again
            let mut fit_with =
                |p: &Prepared, first: Option<&dense::KeptFactor>, stages: &mut Stages| match method {
                    Method::Dense | Method::Auto => dense::refit(&run, kernel, p, first, stages),
                    Method::Csrbf => compact::fit(&run, kernel, p, None, stages),
                };
            // a first fit that may be followed by a second keeps its factor for it
            let mut fitted = match method {
                Method::Dense | Method::Auto => dense::fit(&run, kernel, fit_prep, off, stages)?,
                Method::Csrbf => compact::fit(&run, kernel, fit_prep, None, stages)?,
            };
            if let Some(c) = constrained.as_mut() {
                // a sheet thinner than the sampling oriented alike on both sides: normals by side
                if matches!(method, Method::Dense | Method::Auto) {
                    if let Some(again) = surface::spilling(&run, kernel, &prep, c, &mut fitted, stages)? {
                        fitted = again;
                    }
                }
                let rows = c.prep.values.len();
                // the second fits append at most as many centres as the ranks have room for
                let room = match method {
                    Method::Dense | Method::Auto => {
                        let most = surface::most_appended(&prep, c, a.grid.margin.fraction);
                        dense::appendable(&run, kernel, rows, fitted.factor.as_ref(), most)
                    }
                    Method::Csrbf => usize::MAX,
                };
                fitted = surface::check_first_fit(&run, &prep, c, fitted, stages, &mut fit_with, room)?;
            }
            Ok((prep, denoised, fitted, constrained, method, kernel, why))
        };
        let side = a.orient_side == SideVote::On;
        // the data as read, kept for a second fit only
        let again = (off && a.orient_side == SideVote::Both).then(|| prep.clone());
        let (mut prep, mut denoised, mut fitted, mut constrained, mut method, mut kernel, mut why) =
            single(prep, side, hoods.take(), &mut stages, true)?;
        if let Some(read) = again {
            // the fit with the side vote as well: kept where its surface crosses fewer lattice
            // cells away from the data
            fitted.factor = None;
            let other = single(read, true, None, &mut stages, false)?;
            let without = constrained.as_ref().and_then(|c| surface::unsupported_left(&c.summary));
            let with = other.3.as_ref().and_then(|c| surface::unsupported_left(&c.summary));
            let keep = matches!((without, with), (Some(x), Some(y)) if y < x);
            if comm.rank() == 0 {
                crate::note!("{}", surface::side_choice_line(without, with, keep));
            }
            if keep {
                (prep, denoised, fitted, constrained, method, kernel, why) = other;
            }
            if let Some(c) = constrained.as_mut() {
                c.summary.side_choice = Some((without, with, keep));
            }
        }
        let fit_prep = constrained.as_ref().map_or(&prep, |c| &c.prep);
        let summary = constrained.as_ref().map(|c| c.summary.clone());
        super::finite::check_fit(&fitted, fit_prep)?;
        (prep, denoised, fitted, summary, method, kernel, why)
    };
    let levels: Vec<&Spline> = fitted.coarse.iter().chain(std::iter::once(&fitted.spline)).collect();
    let (rms, max_abs) = stages.time(Stage::Check, || at_points(comm, &levels, &prep));
    let Prepared { carrier, box_lo: lo, box_hi: hi, merged, .. } = prep;
    let model = Model {
        carrier,
        spline: fitted.spline,
        coarse: fitted.coarse,
        provenance: Provenance {
            input: a.input.display().to_string(),
            box_lo: [lo[0], lo[1], lo[2]],
            box_hi: [hi[0], hi[1], hi[2]],
            points_read,
            duplicates_merged: merged,
            // the data come first among the finest level's centres, the constraint points after
            data_points: n,
            solver: fitted.solver.clone(),
            residual: fitted.residual,
            ..run_provenance(comm, threads, &stages)
        },
    };
    let unbounded = super::finite::check_bounded(&model);
    if let (Some(w), 0) = (&unbounded, comm.rank()) {
        crate::note!("volspline: warning: {w}");
    }
    super::finite::check_grid_field(comm, &model, &grid)?;
    let model_path = output_path(&a.out, ".model.h5");
    stages.time(Stage::Write, || {
        on_root(comm, || io::write_atomically(&model_path, |tmp| model_file::write_model(tmp, &model)))
    })?;
    let solid = (a.grid.curvature || !a.no_preview).then(|| ModelSolid::new(model.clone()));
    let curvature = solid.as_ref().filter(|_| a.grid.curvature).map(|s| s as &dyn Implicit);
    let support =
        a.trim.map(|f| DataSupport::of_model(&model, f).expect("a fitted model records its data points"));
    // the grid grows where the solid reaches it (--margin auto), unless it is unbounded or the
    // node counts were given
    let grow = a.grid.may_grow() && unbounded.is_none();
    let job = Volume::new(&model, grid, &a.out)
        .curvature(curvature)
        .grow(grow)
        .trim(support.as_ref())
        .unbounded_cause(off.then_some(surface::UNBOUNDED_CAUSE));
    let volume = write_volume(comm, job, &mut stages)?;
    let preview = output_path(&a.out, ".png");
    if let Some(s) = solid.as_ref().filter(|_| !a.no_preview) {
        write_picture(comm, s, &preview_view(), Colouring::Shading, &preview, &mut stages)?;
    }

    let mut r = Report::new("fit", &a.input);
    let method_name = if method == Method::Csrbf { "csrbf" } else { "dense" };
    let smoothing = match kernel.smoothing() {
        0.0 => String::new(),
        l => format!(", smoothing {l} (|f| at the data is the misfit it allows)"),
    };
    let isolated_part = match (isolated.len(), a.drop_isolated) {
        (0, _) => String::new(),
        (k, true) => format!(", {k} isolated left out"),
        (k, false) => format!(", {k} isolated kept"),
    };
    r.line(format!(
        "N = {n} points ({points_read} read{isolated_part}, {merged} duplicates merged), method {method_name} ({why}), kernel {}{smoothing}",
        kernel.name()
    ));
    if let Some((line, ..)) = &denoised {
        r.line(line.clone());
    }
    r.line(surface_line(summary.as_ref(), two_levels));
    r.line(fitted.line.clone());
    r.line(format!("ranks = {}, threads per rank = {threads}", comm.size()));
    r.line(format!("relative residual |Mx - b|/|b| = {:.3e}", fitted.residual));
    r.line(format!("|f| at the data points: rms {rms:.3e}, max {max_abs:.3e}"));
    if let Some(w) = &unbounded {
        r.line(format!("warning: {w}"));
    }
    r.figure("bounded", unbounded.is_none());
    r.figure("input", a.input.display());
    r.figure("isolated_points", isolated.len());
    r.figure("isolated_dropped", a.drop_isolated && !isolated.is_empty());
    r.figure("points", n);
    r.figure("method", method_name);
    r.figure("kernel", kernel.name());
    r.figure("smoothing", kernel.smoothing());
    r.figure("surface", surface::name(off));
    r.figure("levels", if two_levels { 2 } else { 1 });
    if let Some((_, _, ratio)) = auto {
        r.figure("denoise_scale_ratio", format!("{ratio:.4}"));
    }
    if let Some((_, moved, noise, longest)) = &denoised {
        r.figure("denoise_moved", moved);
        r.figure("denoise_noise", format!("{noise:e}"));
        r.figure("denoise_longest_move", format!("{longest:e}"));
    }
    if let Some(s) = &summary {
        r.figure("off_points", s.off_points);
        r.figure("off_dropped", s.dropped);
        r.figure("off_doubtful_normals", s.doubtful);
        r.figure("off_doubtful_share", s.doubtful_share);
        r.figure("off_deal", a.off_deal.name());
        r.figure("delta_min", format!("{:e}", s.delta.0));
        r.figure("delta_max", format!("{:e}", s.delta.1));
        r.figure("orient_components", s.components);
        r.figure("orient_patches", s.patches);
        r.figure("orient_flipped", s.flipped);
        if let Some(k) = s.side_turned {
            r.figure("orient_side_turned", k);
        }
        if let Some((without, with, keep)) = s.side_choice {
            let count = |c: Option<usize>| c.map_or(String::new(), |c| c.to_string());
            r.figure("side_choice_without", count(without));
            r.figure("side_choice_with", count(with));
            r.figure("side_choice_kept", if keep { "with" } else { "without" });
        }
        if let Some(e) = &s.energy {
            r.figure("energy_ran", e.ran);
            r.figure("energy_flipped", e.flipped);
        }
        r.figure("blob_points", s.blob_points);
        r.figure("blob_regions", s.blob_regions);
        r.figure("blob_spared", s.blob_spared);
        if let Some(l) = &s.memory_limit {
            r.figure("second_fit_room", l.room);
            r.figure("second_fit_wanted", l.wanted);
        }
        r.figure("fits", s.fits());
        if let Some(ch) = &s.choice {
            r.figure("choice_wide_points", ch.wide_points);
            r.figure("choice_narrow_points", ch.narrow_points);
            r.figure("choice_wide_unsupported", format!("{:.5}", ch.wide_share));
            r.figure("choice_narrow_unsupported", format!("{:.5}", ch.narrow_share));
            r.figure("choice_kept", if ch.kept_narrow { "narrow" } else { "wide" });
        }
        if let Some(k) = &s.second_round {
            r.figure("second_round_points", k.points);
            r.figure("second_round_kept", k.kept);
        }
        if let Some(k) = &s.restored {
            r.figure("restored_lost", k.lost);
            r.figure("restored_points", k.points);
            r.figure("restored_along", k.along);
            r.figure("restored_kept", k.kept);
        }
        if let Some(k) = &s.sides {
            r.figure("sides_spilled", k.spilled.0);
            r.figure("sides_turned", k.turned);
            r.figure("sides_spilled_after", k.spilled.1);
            r.figure("sides_kept", k.kept);
        }
        if let Some(k) = &s.rays {
            r.figure("rays_doubtful", k.doubtful);
            r.figure("rays_enclosed", k.enclosed);
            r.figure("rays_turned_patches", k.turned);
            r.figure("rays_turned_points", k.turned_points);
        }
        if let Some(t) = &s.turns {
            let counts = [
                ("turns_candidates", t.candidates),
                ("turns_tried", t.tried),
                ("turns_superposed", t.superposed),
                ("turns_turned", t.turned),
                ("turns_by_open_space", t.by_open_space),
                ("turns_smoother", t.smoother),
                ("turns_facing_tried", t.facing),
                ("turns_facing_turned", t.facing_turned),
                ("turns_unsupported_before", t.before),
                ("turns_unsupported_after", t.after),
            ];
            counts.into_iter().for_each(|(key, count)| r.figure(key, count));
            if let Some(v) = &t.side {
                let counts = [
                    ("side_try_patches", v.patches),
                    ("side_try_points", v.points),
                    ("side_try_unsupported_before", v.before),
                    ("side_try_unsupported_after", v.after),
                ];
                counts.into_iter().for_each(|(key, count)| r.figure(key, count));
                r.figure("side_try_kept", v.kept);
            }
        }
        if let Some(o) = &s.outside {
            let counts = [
                ("outside_open", o.open),
                ("outside_charged", o.charged),
                ("outside_points", o.points),
                ("outside_unsupported_before", o.before),
                ("outside_unsupported_after", o.after),
            ];
            counts.into_iter().for_each(|(key, count)| r.figure(key, count));
            r.figure("outside_kept", o.kept);
        }
        if let Some(m) = &s.mouth {
            let counts = [
                ("mouth_crossings", m.crossings),
                ("mouth_wanted", m.wanted),
                ("mouth_points", m.points),
                ("mouth_folds", m.folds),
                ("cap_points", m.caps),
            ];
            counts.into_iter().for_each(|(key, count)| r.figure(key, count));
            r.figure("mouth_slope", a.mouth_slope);
            r.figure("cap_bulge", a.cap_bulge);
        }
    }
    for (k, v) in &fitted.figures {
        r.figure(k, v);
    }
    r.figure("ranks", comm.size());
    r.figure("threads", threads);
    r.figure("residual", format!("{:e}", fitted.residual));
    r.figure("rms_at_points", format!("{rms:e}"));
    r.figure("max_at_points", format!("{max_abs:e}"));
    r.figure("kernel_evals", volume.nodes_evaluated as f64 * volume.evals_per_node as f64);
    r.output(&model_path);
    volume.report(&mut r);
    if !a.no_preview {
        r.output(&preview);
    }
    let nodes = volume.nodes_evaluated;
    let per_node = volume.evals_per_node;
    r.finish(
        comm,
        &stages,
        &|t| {
            let mut l = throughput_line(nodes, per_node, t.max(Stage::Evaluate));
            l.push(format!(
                "Table 2 columns: matrix formation {:.3} s, solution of the SLAE {:.3} s, evaluation of {nodes} grid nodes {:.3} s",
                t.max(Stage::Assemble),
                t.max(Stage::Factor) + t.max(Stage::Solve),
                t.max(Stage::Evaluate)
            ));
            l
        },
        a.grid.timings.as_deref(),
    )?;
    Ok(())
}

/// The report line of the surface method.
fn surface_line(summary: Option<&surface::SurfaceSummary>, two_level: bool) -> String {
    match summary {
        None => "surface carrier: the spline interpolates the carrier at the data alone".to_string(),
        Some(s) => format!(
            "surface offsurface{}: {} off-surface points ({} dropped; {} data points with doubtful normals at {:.2} of the \
             rate), delta {:.3e} to {:.3e}; orientation: {} graph components, {}",
            if two_level { " (level 0)" } else { "" },
            s.off_points,
            s.dropped,
            s.doubtful,
            s.doubtful_share,
            s.delta.0,
            s.delta.1,
            s.components,
            if s.dense_dipole {
                format!("{} patches, {} flipped by the dense dipole field", s.patches, s.flipped)
            } else {
                "no dipole correction (too many points)".to_string()
            },
        ) + &match s.side_turned {
            Some(k) => format!(", {k} turned by the side vote"),
            None => String::new(),
        } + &match s.side_choice {
            Some((_, _, keep)) => {
                format!(" (--orient-side both: the fit {} the side vote kept)", if keep { "with" } else { "without" })
            }
            None => String::new(),
        } + &match &s.sides {
            Some(k) => format!(
                "; solid spilled far beyond the data ({} nodes of the box grown by {} of its longest side): \
                 {} normals turned by side, {} nodes: {}",
                k.spilled.0,
                crate::surface::sheets::SPILL,
                k.turned,
                k.spilled.1,
                if k.kept { "kept" } else { "dropped" }
            ),
            None => String::new(),
        } + &match &s.energy {
            None => String::new(),
            Some(e) if e.ran => format!(
                "; energy: {} of {} patches turned (energy {:.4e} -> {:.4e})",
                e.flipped, e.movable, e.before, e.after
            ),
            Some(_) => format!("; energy: skipped (more than {} rows)", crate::surface::energy::ENERGY_LIMIT),
        } + &match &s.rays {
            Some(k) => format!(
                "; rays: {} doubtful points ({} enclosed), {} patches ({} points) turned",
                k.doubtful, k.enclosed, k.turned, k.turned_points
            ),
            None => String::new(),
        } + &if s.blob_points > 0 {
            format!("; blobs: {} constraint points ({} regions away from the data)", s.blob_points, s.blob_regions)
        } else {
            "; blobs: none".to_string()
        } + &if s.blob_spared > 0 {
            format!(", {} nodes enclosed by the data spared", s.blob_spared)
        } else {
            String::new()
        } + &match &s.choice {
            Some(ch) => format!(
                "; clearance: wide {} points, {:.1} % of the surface unsupported, narrow {} points, {:.1} %: \
                 {} kept",
                ch.wide_points,
                100.0 * ch.wide_share,
                ch.narrow_points,
                100.0 * ch.narrow_share,
                if ch.kept_narrow { "narrow" } else { "wide" },
            ),
            None => String::new(),
        } + &match &s.second_round {
            Some(k) if k.points > 0 => format!(
                "; second round: {} points in open space, {}data points without solid {} -> {}: {}",
                k.points,
                match k.share.1 {
                    Some(after) => format!("unsupported {:.1} -> {:.1} %, ", 100.0 * k.share.0, 100.0 * after),
                    None => String::new(),
                },
                k.without_solid.0,
                k.without_solid.1,
                if k.kept { "kept" } else { "dropped" },
            ),
            Some(_) => "; second round: nothing in open space".to_string(),
            None => String::new(),
        } + &match &s.restored {
            Some(k) if k.points + k.along > 0 => format!(
                "; solid lost at {} data points, given back at {}, data points without solid {} -> {}: {}",
                k.lost,
                match (k.points, k.along) {
                    (inside, 0) => format!("{inside} nodes inside"),
                    (0, along) => format!("{along} nodes along the first fit's solid"),
                    (inside, along) => format!("{inside} nodes inside and {along} along the first fit's solid"),
                },
                k.without_solid.0,
                k.without_solid.1,
                if k.kept { "kept" } else { "dropped" },
            ),
            Some(k) if k.no_room => {
                format!("; solid lost at {} data points, not given back (no memory for its fit)", k.lost)
            }
            Some(k) => format!("; solid lost at {} data points, too few of their nodes inside to give back", k.lost),
            None => String::new(),
        } + &match &s.memory_limit {
            Some(l) => format!(
                "; memory: room for {} appended centres in the second fits, {} wanted",
                l.room, l.wanted
            ),
            None => String::new(),
        } + &match s.turns.as_ref().and_then(|t| t.side) {
            Some(v) => format!(
                "; side vote: {} patches ({} points) tried as one turn, unsupported crossings {} -> {}: {}",
                v.patches,
                v.points,
                v.before,
                v.after,
                if v.kept { "kept" } else { "not kept" }
            ),
            None => String::new(),
        } + &match &s.turns {
            Some(t) => format!(
                "; turns: {} of {} {} tried ({} points) turned{}{}{}{}, unsupported crossings {} -> {}",
                t.turned,
                t.tried,
                if t.facing > 0 { "patches and groups" } else { "patches" },
                t.turned_points,
                match (t.by_open_space, t.smoother) {
                    (0, 0) => String::new(),
                    (k, 0) => format!(" ({k} by open space)"),
                    (0, m) => format!(" ({m} as smoother)"),
                    (k, m) => format!(" ({k} by open space, {m} as smoother)"),
                },
                match (t.facing, t.facing_turned) {
                    (0, _) => String::new(),
                    (k, m) => format!(", {k} of the tried groups facing a sheet ({m} turned)"),
                },
                match t.candidates - t.tried {
                    0 => String::new(),
                    k => format!(", {k} of {} candidates passed over without a solve", t.candidates),
                },
                match t.superposed {
                    0 => String::new(),
                    k => format!(", {k} tried by one solve of the candidates' changes"),
                },
                t.before,
                t.after
            ),
            None if s.turns_skipped && s.outside_skipped && s.mouth_skipped => {
                "; turns, outside points and mouth points: skipped (no factor kept to fit them with)".to_string()
            }
            None if s.turns_skipped && s.outside_skipped => {
                "; turns and outside points: skipped (no factor kept to fit them with)".to_string()
            }
            None if s.turns_skipped => "; turns: skipped (no factor kept to try them with)".to_string(),
            None => String::new(),
        } + &match &s.outside {
            None if s.outside_skipped && !s.turns_skipped => {
                "; outside points: skipped (no factor kept to fit them with)".to_string()
            }
            Some(o) if o.no_room => format!(
                "; outside points: {} for {} crossings in open space, not added (no memory for their fit)",
                o.points, o.open
            ),
            Some(o) if o.points > 0 => format!(
                "; outside points: {} for {} crossings in open space, unsupported crossings {} -> {}: {}",
                o.points,
                o.open,
                o.before,
                o.after,
                if o.kept { "kept" } else { "dropped" }
            ),
            Some(o) => format!("; outside points: none placed for {} crossings in open space", o.open),
            None => String::new(),
        } + &match &s.mouth {
            None if s.mouth_skipped && !(s.turns_skipped && s.outside_skipped) => {
                "; mouth points: skipped (no factor kept to fit them with)".to_string()
            }
            Some(m) if m.no_room => format!(
                "; mouth points: {} for {} crossings in the mouths of holes{}, not added (no memory for their fit)",
                m.points,
                m.crossings,
                folds_left_out(m.folds)
            ),
            Some(m) if m.points > 0 => format!(
                "; mouth points: {} for {} crossings in the mouths of holes{}{}",
                m.points,
                m.crossings,
                folds_left_out(m.folds),
                match m.caps {
                    0 => String::new(),
                    1 => ", 1 cap point".to_string(),
                    k => format!(", {k} cap points"),
                }
            ),
            Some(m) if m.crossings > 0 => format!(
                "; mouth points: none placed for {} crossings in the mouths of holes{}",
                m.crossings,
                folds_left_out(m.folds)
            ),
            Some(_) => String::new(),
            None => String::new(),
        } + &match s.fits() {
            1 => String::new(),
            2 => ", fitted twice".to_string(),
            3 => ", fitted three times".to_string(),
            k => format!(", fitted {k} times"),
        },
    }
}

/// " (N rim points at folds left out)" where step 9 left out charged rim points at folds.
fn folds_left_out(folds: usize) -> String {
    match folds {
        0 => String::new(),
        1 => " (1 rim point at a fold left out)".to_string(),
        n => format!(" ({n} rim points at folds left out)"),
    }
}

/// RMS and maximum of |f| = |f_c - sum of the levels' U| at the data points (zero for an exact
/// interpolant), each rank taking every P-th point with the blocked evaluator. Collective.
fn at_points(comm: &dyn Comm, levels: &[&Spline], prep: &Prepared) -> (f64, f64) {
    let evs: Vec<Evaluator> = levels.iter().map(|s| Evaluator::new(s)).collect();
    // squares of the scaled differences, so that carrier values near 1e200 do not overflow them
    let scale = power_of_two_below_inverse(prep.values.iter().fold(0.0f64, |m, v| m.max(v.abs())));
    let mine: Vec<&[f64]> = prep.points.chunks_exact(3).skip(comm.rank()).step_by(comm.size()).collect();
    let (sq, max) = mine
        .par_iter()
        .map(|p| {
            let f = evs.iter().fold(prep.carrier.eval(p), |f, ev| {
                let mut u = [0.0];
                ev.eval_row(&p[..1], p[1], p[2], &mut u);
                f - u[0]
            });
            let d = f.abs();
            ((d * scale) * (d * scale), d)
        })
        .reduce(|| (0.0, 0.0), |a, b| (a.0 + b.0, a.1.max(b.1)));
    let mut s = [sq];
    comm.sum_f64(&mut s);
    let mut m = [max];
    comm.max_f64(&mut m);
    ((s[0] / prep.values.len().max(1) as f64).sqrt() / scale, m[0])
}

#[cfg(test)]
mod tests {
    use clap::Parser;

    use super::*;
    use crate::cli::{Cli, Command};

    fn fit_args(args: &[&str]) -> FitArgs {
        let all = ["volspline", "fit", "p.xyz", "--out", "o"].into_iter().chain(args.iter().copied());
        match Cli::try_parse_from(all).unwrap().command {
            Command::Fit(a) => a,
            _ => panic!("not fit"),
        }
    }

    #[test]
    fn auto_chooses_by_the_rows_and_the_memory_every_rank_is_given() {
        let a = fit_args(&[]);
        let centres: Vec<f64> = (0..300).map(|i| ((i * 37 % 101) as f64 / 50.0) - 1.0).collect();
        let method = |rows: usize, machine: (usize, f64)| choose(&a, rows, machine, &centres).unwrap();
        // 12,000 rows on one rank: 12004^3 / 3 flops at 60 GFLOP/s, about 10 s
        let (m, k, why) = method(12_000, (1, f64::INFINITY));
        assert_eq!(m, Method::Dense, "{why}");
        assert_eq!(k.name(), "r");
        assert!(why.contains("about 10 s"), "{why}");
        // with its off points, 18,000 rows take about 32 s: the compactly supported method, with
        // its own kernel (the two-level fit takes this choice)
        let (m, k, why) = method(18_000, (1, f64::INFINITY));
        assert_eq!(m, Method::Csrbf, "{why}");
        assert!(k.is_compact().is_some(), "{}", k.name());
        assert!(why.contains("about 32 s"), "{why}");
        // on two ranks 18,000 rows take about 16 s; 17,000 rows about 14 s
        assert_eq!(method(18_000, (2, f64::INFINITY)).0, Method::Csrbf);
        assert_eq!(method(17_000, (2, f64::INFINITY)).0, Method::Dense);
        // the memory the ranks agreed on decides too: the projected Cholesky, the solver for
        // these rows, takes the lower triangle alone (with its panels of 384, 1.03 GB here), LU
        // the whole matrix (1.52 GB with its panels of 320)
        let (m, _, why) = method(12_000, (1, 1.0e9));
        assert_eq!(m, Method::Csrbf, "{why}");
        assert!(why.contains("1.0 GB per rank"), "{why}");
        assert_eq!(method(12_000, (1, 1.1e9)).0, Method::Dense);
        let lu = fit_args(&["--solver", "lu"]);
        assert_eq!(choose(&lu, 12_000, (1, 1.1e9), &centres).unwrap().0, Method::Csrbf);
        assert_eq!(choose(&lu, 12_000, (1, 1.6e9), &centres).unwrap().0, Method::Dense);
        // an explicit kernel or method is taken as asked
        let a = fit_args(&["--method", "dense"]);
        assert_eq!(choose(&a, 18_000, (1, 1e6), &centres).unwrap().0, Method::Dense);
    }
}
