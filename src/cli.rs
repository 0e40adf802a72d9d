//! The command line: argument definitions, defaults and the report printed after a run. `main`
//! only sets up MPI and threads and calls [`run`].

use std::path::PathBuf;

use clap::{Args, Parser, Subcommand};

use crate::dist::{agree, Comm, SolverKind};
use crate::error::{Error, Result};
use crate::grid::{parse_bounds, GridSize};
use crate::kernel::Kernel;
use crate::pipeline::{self, EvalOptions, FitOptions, VolumeSummary};
use crate::report::{peak_rss_max, stage_table, Record, Stages};

/// volspline: reconstruct solids from scattered surface points as a volume spline f(x,y,z) with
/// f >= 0 inside (Savchenko et al. 1995), on any number of MPI ranks.
///
/// Run under `mpirun -n P volspline ...` (or as one process without mpirun). The rows of the dense
/// system and the evaluation grid are split across ranks; each rank uses threads for its share.
#[derive(Debug, Parser)]
#[command(name = "volspline", version, about, long_about)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Debug, Subcommand)]
pub enum Command {
    /// Fit a volume spline to scattered points; write PREFIX.model.h5, PREFIX.hdf (VTKHDF volume of
    /// f for ParaView) and PREFIX.ply (the surface f = 0).
    Fit(FitArgs),
    /// Evaluate a saved model on a new grid without solving again; write PREFIX.hdf and PREFIX.ply.
    Eval(EvalArgs),
    /// Reconstruct a solid from planar cross-sections (a contour file, see README.md): one 2D
    /// spline per slice, interpolated between slices; write PREFIX.model.h5, PREFIX.hdf, PREFIX.ply.
    Contours(ContoursArgs),
    /// Cut a triangle mesh (.obj/.ply) by a family of planes and write the contour file.
    Slice(SliceArgs),
}

#[derive(Debug, Args)]
pub struct ContoursArgs {
    /// Contour file: `slice z Z` / `slice plane O U V` / `slice omega W O` lines, each followed by
    /// `contour` blocks of in-plane points `a b` (format in README.md).
    pub input: PathBuf,
    /// Output prefix: writes PREFIX.model.h5, PREFIX.hdf, PREFIX.ply.
    #[arg(long, value_name = "PREFIX")]
    pub out: PathBuf,
    /// Interpolation between slices: linear (the paper's) or cubic (cardinal natural cubic splines
    /// in the slice parameter).
    #[arg(long, default_value = "linear", value_name = "linear|cubic")]
    pub interp: String,
    /// Interpolation of the section frames of non-parallel slices: slerp (quaternion geodesic) or
    /// log (the paper's exp((1-t) ln M_i + t ln M_i+1)).
    #[arg(long, default_value = "slerp", value_name = "slerp|log")]
    pub orient: String,
    /// Green's function of the 2D section splines: r2log (m = 2, thin plate, polynomial 1, x, y)
    /// or r4log (m = 3; needs --carrier union).
    #[arg(long, default_value = "r2log", value_name = "r2log|r4log")]
    pub kernel: String,
    /// Carrier of each section: disc (one disc round the slice) or union (R-union of one disc per
    /// contour, bounded by the slice's disc: keeps neighbouring contours, such as legs, apart).
    #[arg(long, default_value = "disc", value_name = "disc|union")]
    pub carrier: String,
    /// Points of a slice closer than this fraction of the slice's diagonal are merged into one.
    #[arg(long, default_value_t = 1e-6, value_name = "F")]
    pub merge_tol: f64,
    #[command(flatten)]
    pub grid: GridArgs,
}

#[derive(Debug, Args)]
pub struct SliceArgs {
    /// Triangle mesh: .obj or .ply with faces.
    pub mesh: PathBuf,
    /// The contour file to write.
    #[arg(long, value_name = "CONTOURS")]
    pub out: PathBuf,
    /// Planes: AXIS:N (N parallel planes across the mesh, AXIS x, y or z) or fan-AXIS:N (N planes
    /// sweeping along AXIS while turning about a hinge line outside the mesh: non-parallel).
    #[arg(long, default_value = "z:40", value_name = "SPEC")]
    pub planes: String,
}

#[derive(Debug, Args)]
pub struct GridArgs {
    /// Grid nodes: N along the longest side of the box with cubic cells, or NX,NY,NZ.
    #[arg(long, default_value = "64", value_name = "N|NX,NY,NZ")]
    pub grid: String,
    /// Margin added on every side of the data's bounding box, as a fraction of its longest side.
    #[arg(long, default_value_t = 0.05, value_name = "F")]
    pub margin: f64,
    /// Threads per rank (0: the cores of this node divided by the ranks on it).
    #[arg(long, default_value_t = 0, value_name = "T")]
    pub threads: usize,
    /// Also write the run's figures (sizes, stage min/max seconds, residual, peak memory) as
    /// `key,value` CSV to this file, for scaling studies.
    #[arg(long, value_name = "FILE")]
    pub timings: Option<PathBuf>,
}

#[derive(Debug, Args)]
pub struct FitArgs {
    /// Points: .obj (vertices), .ply (ascii or binary; vertex x, y, z), .xyz/.txt/.csv (x y z per line).
    pub input: PathBuf,
    /// Output prefix: writes PREFIX.model.h5, PREFIX.hdf, PREFIX.ply.
    #[arg(long, value_name = "PREFIX")]
    pub out: PathBuf,
    /// Carrier solid: ball (fitted to the data), ball:cx,cy,cz,r, ellipsoid:cx,cy,cz,a,b,c, or
    /// union(A,B) / intersection(A,B) / difference(A,B) of carriers (R-functions).
    #[arg(long, default_value = "ball", value_name = "SPEC")]
    pub carrier: String,
    /// Green's function: r (m = 2, biharmonic) or r3 (m = 3, triharmonic).
    #[arg(long, default_value = "r", value_name = "r|r3")]
    pub kernel: String,
    /// Distributed dense solver: auto (the fastest for the size: householder below 1000 rows,
    /// cholesky above), cholesky (projected Cholesky of the
    /// definite block, falls back to lu with a message when a pivot is not positive), householder
    /// (QR, the paper's method) or lu (partial pivoting).
    #[arg(long, default_value = "auto", value_name = "auto|cholesky|householder|lu")]
    pub solver: String,
    /// Panel (block) width of the distributed solvers (0: automatic, 64 for householder, 128 for
    /// lu, 256 for cholesky).
    #[arg(long, default_value_t = 0, value_name = "NB")]
    pub panel: usize,
    /// Points closer than this fraction of the bounding-box diagonal are merged into one.
    #[arg(long, default_value_t = 1e-6, value_name = "F")]
    pub merge_tol: f64,
    #[command(flatten)]
    pub grid: GridArgs,
}

#[derive(Debug, Args)]
pub struct EvalArgs {
    /// A model written by `volspline fit` (PREFIX.model.h5).
    pub model: PathBuf,
    /// Output prefix: writes PREFIX.hdf, PREFIX.ply.
    #[arg(long, value_name = "PREFIX")]
    pub out: PathBuf,
    /// Box to evaluate: xmin,ymin,zmin,xmax,ymax,zmax (default: the centres' box plus --margin).
    #[arg(long, value_name = "BOX", allow_hyphen_values = true)]
    pub bounds: Option<String>,
    #[command(flatten)]
    pub grid: GridArgs,
}

/// Runs a parsed command on `comm` with `threads` threads per rank. Collective.
pub fn run(cli: &Cli, comm: &dyn Comm, threads: usize) -> Result<()> {
    let mut stages = Stages::default();
    match &cli.command {
        Command::Fit(a) => {
            check_margin(a.grid.margin)?;
            if !(a.merge_tol >= 0.0 && a.merge_tol < 0.1) {
                return Err(Error::Usage("--merge-tol must be in [0, 0.1)".into()));
            }
            let opts = FitOptions {
                input: a.input.clone(),
                prefix: a.out.clone(),
                carrier: a.carrier.clone(),
                kernel: Kernel::from_name_3d(&a.kernel)?,
                solver: SolverKind::parse(&a.solver)?,
                grid: GridSize::parse(&a.grid.grid)?,
                margin: a.grid.margin,
                panel: a.panel,
                merge_tol: a.merge_tol,
                threads,
            };
            let s = pipeline::fit(comm, &opts, &mut stages)?;
            let times = stages.summarise(comm);
            let peak = peak_rss_max(comm);
            let t = |name: &str| times.iter().find(|t| t.name == name).map_or(0.0, |t| t.max);
            let mut rec = Record::default();
            rec.put("command", "fit");
            rec.put("input", opts.input.display());
            rec.put("points", s.points_used);
            rec.put("system_size", s.points_used + opts.kernel.poly_count());
            rec.put("kernel", opts.kernel.name());
            rec.put("solver", s.solver_used);
            rec.put("panel", s.panel_used);
            rec.put("ranks", comm.size());
            rec.put("threads", threads);
            rec.put("residual", format!("{:e}", s.residual));
            rec.put("max_abs_f_at_points", format!("{:e}", s.max_abs_f_at_points));
            rec.put("grid_nodes", s.volume.grid.node_count());
            rec.put("kernel_evals", s.volume.grid.node_count() as f64 * s.points_used as f64);
            rec.put("triangles", s.volume.triangles);
            rec.put("peak_rss_bytes_max", peak);
            rec.stages(&times);
            write_record(comm, a.grid.timings.as_deref(), &rec)?;
            if comm.rank() == 0 {
                println!("volspline fit: {}", opts.input.display());
                println!(
                    "  N = {} points ({} read, {} duplicates merged), kernel {}, solver {}, panel {}",
                    s.points_used,
                    s.points_read,
                    s.merged,
                    opts.kernel.name(),
                    s.solver_used,
                    s.panel_used
                );
                println!("  ranks = {}, threads per rank = {}", comm.size(), threads);
                println!("  relative residual |Mx - b|/|b| = {:.3e}", s.residual);
                println!("  max |f| at the data points   = {:.3e}", s.max_abs_f_at_points);
                print_volume(&s.volume);
                print!("{}", stage_table(&times));
                print_throughput(s.volume.grid.node_count(), s.points_used, t("evaluate"));
                println!("  peak memory per rank (max over ranks): {:.1} MB", peak / 1e6);
                println!(
                    "  paper 000 Table 2 columns: matrix formation {:.3} s, solution of the SLAE {:.3} s, \
                     evaluation of {} grid nodes {:.3} s",
                    t("assemble"),
                    t("solve"),
                    s.volume.grid.node_count(),
                    t("evaluate")
                );
                println!("  outputs:");
                println!("    {}", s.model_path.display());
                println!("    {}", s.volume.hdf_path.display());
                println!("    {}", s.volume.ply_path.display());
            }
        }
        Command::Contours(a) => run_contours(a, comm, threads, &mut stages)?,
        Command::Slice(a) => run_slice(a, comm, &mut stages)?,
        Command::Eval(a) if is_contour_model(&a.model) => run_eval_contours(a, comm, threads, &mut stages)?,
        Command::Eval(a) => {
            check_margin(a.grid.margin)?;
            let opts = EvalOptions {
                model: a.model.clone(),
                prefix: a.out.clone(),
                grid: GridSize::parse(&a.grid.grid)?,
                bounds: a.bounds.as_deref().map(parse_bounds).transpose()?,
                margin: a.grid.margin,
                threads,
            };
            let (model, v) = pipeline::eval(comm, &opts, &mut stages)?;
            let times = stages.summarise(comm);
            let peak = peak_rss_max(comm);
            let mut rec = Record::default();
            rec.put("command", "eval");
            rec.put("model", opts.model.display());
            rec.put("points", model.spline.len());
            rec.put("ranks", comm.size());
            rec.put("threads", threads);
            rec.put("grid_nodes", v.grid.node_count());
            rec.put("kernel_evals", v.grid.node_count() as f64 * model.spline.len() as f64);
            rec.put("triangles", v.triangles);
            rec.put("peak_rss_bytes_max", peak);
            rec.stages(&times);
            write_record(comm, a.grid.timings.as_deref(), &rec)?;
            if comm.rank() == 0 {
                println!("volspline eval: {}", opts.model.display());
                println!(
                    "  N = {} centres, kernel {}, carrier {}",
                    model.spline.len(),
                    model.spline.kernel.name(),
                    model.carrier
                );
                println!("  ranks = {}, threads per rank = {}", comm.size(), threads);
                print_volume(&v);
                print!("{}", stage_table(&times));
                let t = times.iter().find(|t| t.name == "evaluate").map_or(0.0, |t| t.max);
                print_throughput(v.grid.node_count(), model.spline.len(), t);
                println!("  outputs:");
                println!("    {}", v.hdf_path.display());
                println!("    {}", v.ply_path.display());
            }
        }
    }
    Ok(())
}

/// Writes the `--timings` record from rank 0 (atomically) and agrees on the outcome.
fn write_record(comm: &dyn Comm, path: Option<&std::path::Path>, rec: &Record) -> Result<()> {
    let Some(path) = path else { return Ok(()) };
    let local = if comm.rank() == 0 {
        crate::io::write_atomically(path, |tmp| {
            std::fs::write(tmp, rec.to_csv()).map_err(|e| Error::io(tmp, &e))
        })
    } else {
        Ok(())
    };
    agree(comm, local)
}

fn check_margin(m: f64) -> Result<()> {
    if !(0.0..=10.0).contains(&m) {
        return Err(Error::Usage(format!("--margin {m}: expected a number in [0, 10]")));
    }
    Ok(())
}

fn print_throughput(nodes: usize, centres: usize, seconds: f64) {
    let evals = nodes as f64 * centres as f64;
    if seconds > 0.0 {
        println!("  evaluation: {evals:.3e} kernel evaluations, {:.3e} per second", evals / seconds);
    }
}

fn print_volume(v: &VolumeSummary) {
    let g = &v.grid;
    println!(
        "  grid {} x {} x {} nodes, origin ({:.6}, {:.6}, {:.6}), spacing ({:.6}, {:.6}, {:.6})",
        g.dims[0],
        g.dims[1],
        g.dims[2],
        g.origin[0],
        g.origin[1],
        g.origin[2],
        g.spacing[0],
        g.spacing[1],
        g.spacing[2]
    );
    println!("  surface f = 0: {} triangles, {} vertices", v.triangles, v.vertices);
}

/// Threads per rank when the user gave 0: this node's cores divided by the ranks on it (from the
/// launcher's environment), at least 1, so that the defaults never oversubscribe the cores.
pub fn default_threads(requested: usize) -> usize {
    if requested > 0 {
        return requested;
    }
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let local = [
        "OMPI_COMM_WORLD_LOCAL_SIZE",
        "MPI_LOCALNRANKS",
        "MV2_COMM_WORLD_LOCAL_SIZE",
        "SLURM_NTASKS_PER_NODE",
    ]
    .iter()
    .find_map(|v| std::env::var(v).ok()?.parse::<usize>().ok())
    .unwrap_or(1)
    .max(1);
    (cores / local).max(1)
}

impl Cli {
    /// The --threads value of whichever command was given.
    pub fn threads(&self) -> usize {
        match &self.command {
            Command::Fit(a) => a.grid.threads,
            Command::Eval(a) => a.grid.threads,
            Command::Contours(a) => a.grid.threads,
            Command::Slice(_) => 1,
        }
    }
}

// The contour commands (paper 000, section 4); their stages are in `contour::pipeline`.

/// Whether `path` holds a contour model (read by every rank; an unreadable file is left to the
/// scattered-point reader to report).
fn is_contour_model(path: &std::path::Path) -> bool {
    use crate::io::{contour_model_file::FORMAT, h5::format_of};
    format_of(path).is_ok_and(|f| f == FORMAT)
}

/// `volspline contours`: options checked, the run, its report.
fn run_contours(a: &ContoursArgs, comm: &dyn Comm, threads: usize, stages: &mut Stages) -> Result<()> {
    use crate::contour::pipeline::{self as contour_pipeline, ContoursOptions};
    use crate::contour::{Interp, Orient, SectionCarrier};
    check_margin(a.grid.margin)?;
    if !(a.merge_tol >= 0.0 && a.merge_tol < 0.1) {
        return Err(Error::Usage("--merge-tol must be in [0, 0.1)".into()));
    }
    let kernel = match a.kernel.as_str() {
        "r2log" => Kernel::new(2, 2)?,
        "r4log" => Kernel::new(2, 3)?,
        other => return Err(Error::Usage(format!("unknown --kernel '{other}' (expected r2log or r4log)"))),
    };
    let opts = ContoursOptions {
        input: a.input.clone(),
        prefix: a.out.clone(),
        interp: Interp::parse(&a.interp)?,
        orient: Orient::parse(&a.orient)?,
        kernel,
        carrier: SectionCarrier::parse(&a.carrier)?,
        grid: GridSize::parse(&a.grid.grid)?,
        margin: a.grid.margin,
        merge_tol: a.merge_tol,
        threads,
    };
    let s = contour_pipeline::contours(comm, &opts, stages)?;
    let times = stages.summarise(comm);
    let peak = peak_rss_max(comm);
    let mut rec = Record::default();
    rec.put("command", "contours");
    rec.put("input", opts.input.display());
    rec.put("slices", s.slices);
    rec.put("contours", s.contours);
    rec.put("points", s.points_used);
    rec.put("kernel", opts.kernel.name());
    rec.put("interp", opts.interp.name());
    rec.put("orient", opts.orient.name());
    rec.put("ranks", comm.size());
    rec.put("threads", threads);
    rec.put("residual", format!("{:e}", s.max_residual));
    rec.put("grid_nodes", s.volume.grid.node_count());
    rec.put("triangles", s.volume.triangles);
    rec.put("peak_rss_bytes_max", peak);
    rec.stages(&times);
    write_record(comm, a.grid.timings.as_deref(), &rec)?;
    if comm.rank() == 0 {
        println!("volspline contours: {}", opts.input.display());
        println!(
            "  {} slices, {} contours, N = {} points ({} read, {} duplicates merged), kernel {}, carrier {}",
            s.slices,
            s.contours,
            s.points_used,
            s.points_read,
            s.merged,
            opts.kernel.name(),
            opts.carrier.name()
        );
        println!("  interp {}, orient {}", opts.interp.name(), opts.orient.name());
        println!(
            "  ranks = {}, threads per rank = {} (slice i solved on rank i mod ranks)",
            comm.size(),
            threads
        );
        println!("  largest relative residual of the slice systems = {:.3e}", s.max_residual);
        println!("  max |F_i| at the slices' points              = {:.3e}", s.max_abs_at_points);
        print_volume(&s.volume);
        print!("{}", stage_table(&times));
        println!("  peak memory per rank (max over ranks): {:.1} MB", peak / 1e6);
        println!("  outputs:");
        println!("    {}", s.model_path.display());
        println!("    {}", s.volume.hdf_path.display());
        println!("    {}", s.volume.ply_path.display());
    }
    Ok(())
}

/// `volspline slice`: cuts the mesh on rank 0 and reports.
fn run_slice(a: &SliceArgs, comm: &dyn Comm, stages: &mut Stages) -> Result<()> {
    use crate::contour::pipeline::{self as contour_pipeline, PlaneFamily};
    let planes = PlaneFamily::parse(&a.planes)?;
    let s = stages.time("slice", || contour_pipeline::slice(comm, &a.mesh, &a.out, planes))?;
    if comm.rank() == 0 {
        println!("volspline slice: {} by {}", a.mesh.display(), a.planes);
        println!(
            "  {} planes, {} slices meet the mesh: {} contours, {} points",
            s.planes, s.slices, s.contours, s.points
        );
        if s.joined > 0 {
            println!(
                "  {} chains ended on holes of the mesh and were closed by joining their ends",
                s.joined
            );
        }
        println!("  output:\n    {}", a.out.display());
    }
    Ok(())
}

/// `volspline eval` of a contour model.
fn run_eval_contours(a: &EvalArgs, comm: &dyn Comm, threads: usize, stages: &mut Stages) -> Result<()> {
    use crate::contour::pipeline as contour_pipeline;
    check_margin(a.grid.margin)?;
    let opts = EvalOptions {
        model: a.model.clone(),
        prefix: a.out.clone(),
        grid: GridSize::parse(&a.grid.grid)?,
        bounds: a.bounds.as_deref().map(parse_bounds).transpose()?,
        margin: a.grid.margin,
        threads,
    };
    let (model, v) = contour_pipeline::eval_contour_model(comm, &opts, stages)?;
    let times = stages.summarise(comm);
    let peak = peak_rss_max(comm);
    let mut rec = Record::default();
    rec.put("command", "eval");
    rec.put("model", opts.model.display());
    rec.put("slices", model.sections.len());
    rec.put("points", model.centres());
    rec.put("ranks", comm.size());
    rec.put("threads", threads);
    rec.put("grid_nodes", v.grid.node_count());
    rec.put("triangles", v.triangles);
    rec.put("peak_rss_bytes_max", peak);
    rec.stages(&times);
    write_record(comm, a.grid.timings.as_deref(), &rec)?;
    if comm.rank() == 0 {
        println!("volspline eval: {} (contour model)", opts.model.display());
        println!(
            "  {} slices, N = {} centres, interp {}, orient {}",
            model.sections.len(),
            model.centres(),
            model.interp.name(),
            model.orient.name()
        );
        println!("  ranks = {}, threads per rank = {}", comm.size(), threads);
        print_volume(&v);
        print!("{}", stage_table(&times));
        println!("  outputs:\n    {}\n    {}", v.hdf_path.display(), v.ply_path.display());
    }
    Ok(())
}
