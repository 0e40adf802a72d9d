//! The stages of a run, collective over all ranks: read -> hygiene -> assemble -> solve ->
//! evaluate -> mesh -> write. Each stage's local failure is agreed on by all ranks before the
//! next collective, so a job never hangs on a rank that failed.

use std::path::{Path, PathBuf};

use rayon::prelude::*;

use crate::carrier::Carrier;
use crate::dense::{self, Matrix};
use crate::dist::{agree, Comm, RowCyclic, SolverKind};
use crate::error::{Error, Result};
use crate::eval::Evaluator;
use crate::geometry::{bounding_box, check_unisolvent, diagonal, merge_duplicates};
use crate::grid::{padded_box, Grid, GridSize};
use crate::io::{self, model_file, points, vtkhdf};
use crate::kernel::Kernel;
use crate::mesh::{self, MeshPiece, SlabGrid, TriMesh};
use crate::model::{Field, Model, Provenance};
use crate::report::{Progress, Stages};
use crate::spline::{assemble_rows, residual_parts, system_size, Normalisation, Spline};

/// Options of `volspline fit`.
#[derive(Debug, Clone)]
pub struct FitOptions {
    pub input: PathBuf,
    pub prefix: PathBuf,
    pub carrier: String,
    pub kernel: Kernel,
    pub solver: SolverKind,
    pub grid: GridSize,
    pub margin: f64,
    pub panel: usize,
    /// Points closer than this fraction of the bounding-box diagonal are merged.
    pub merge_tol: f64,
    pub threads: usize,
}

/// Options of `volspline eval`.
#[derive(Debug, Clone)]
pub struct EvalOptions {
    pub model: PathBuf,
    pub prefix: PathBuf,
    pub grid: GridSize,
    pub bounds: Option<([f64; 3], [f64; 3])>,
    pub margin: f64,
    pub threads: usize,
}

/// What a `fit` run produced and measured (the same on every rank).
#[derive(Debug, Clone)]
pub struct FitSummary {
    pub points_read: usize,
    pub points_used: usize,
    pub merged: usize,
    pub residual: f64,
    /// The solver that produced the solution (cholesky may have fallen back to lu).
    pub solver_used: &'static str,
    /// The panel width it used.
    pub panel_used: usize,
    pub max_abs_f_at_points: f64,
    pub volume: VolumeSummary,
    pub model_path: PathBuf,
}

/// What writing the volume and the mesh produced.
#[derive(Debug, Clone)]
pub struct VolumeSummary {
    pub grid: Grid,
    pub triangles: usize,
    pub vertices: usize,
    pub hdf_path: PathBuf,
    pub ply_path: PathBuf,
}

/// `PREFIX` + suffix.
pub fn output_path(prefix: &Path, suffix: &str) -> PathBuf {
    let mut s = prefix.as_os_str().to_owned();
    s.push(suffix);
    PathBuf::from(s)
}

/// Reads the input points on rank 0 and gives them to every rank, 3 values per point.
fn read_points_everywhere(comm: &dyn Comm, path: &Path) -> Result<Vec<f64>> {
    let local = if comm.rank() == 0 {
        points::read_points(path).map(|set| set.points.iter().flatten().copied().collect::<Vec<f64>>())
    } else {
        Ok(Vec::new())
    };
    let pts = agree(comm, local)?;
    let mut bytes: Vec<u8> = pts.iter().flat_map(|v| v.to_le_bytes()).collect();
    comm.broadcast_bytes(0, &mut bytes);
    Ok(bytes.chunks_exact(8).map(|b| f64::from_le_bytes(b.try_into().expect("8 bytes"))).collect())
}

/// Runs rank 0's `f` (a file write) and agrees on its outcome.
pub(crate) fn on_root(comm: &dyn Comm, f: impl FnOnce() -> Result<()>) -> Result<()> {
    let local = if comm.rank() == 0 { f() } else { Ok(()) };
    agree(comm, local)
}

/// Points made ready for the spline: duplicates merged, normalised, checked for unisolvency, and
/// the carrier resolved and evaluated at them.
#[derive(Debug, Clone)]
pub struct Prepared {
    /// Distinct points in the caller's coordinates, 3 values per point.
    pub points: Vec<f64>,
    /// The same points normalised (the spline's centres).
    pub centres: Vec<f64>,
    /// r_i = f_c(P_i).
    pub values: Vec<f64>,
    pub carrier: Carrier,
    pub norm: Normalisation,
    pub merged: usize,
    pub box_lo: Vec<f64>,
    pub box_hi: Vec<f64>,
}

/// Data hygiene (math.md, section 1), deterministic so that every rank gets the same result:
/// merge points closer than `merge_tol` times the bounding-box diagonal, normalise, check that the
/// polynomial part is determined, resolve the carrier and take its values at the points.
pub fn prepare(raw: &[f64], kernel: &Kernel, carrier: &Carrier, merge_tol: f64) -> Result<Prepared> {
    if let Some(deg) = carrier.polynomial_degree() {
        if deg < kernel.order() {
            return Err(Error::Usage(format!(
                "carrier '{carrier}' is a polynomial of degree {deg}, which kernel {} (polynomial part of \
                 degree {}) reproduces exactly: f = f_c - U would vanish everywhere. Use an R-function \
                 carrier such as union(ball:...,ball:...) or the kernel r",
                kernel.name(),
                kernel.order() - 1
            )));
        }
    }
    let (lo, hi) = bounding_box(raw, 3);
    let (points, merged) = merge_duplicates(raw, 3, merge_tol * diagonal(&lo, &hi));
    let norm = Normalisation::of_box(&lo, &hi);
    let mut centres = vec![0.0; points.len()];
    for (c, p) in centres.chunks_exact_mut(3).zip(points.chunks_exact(3)) {
        norm.apply(p, c);
    }
    check_unisolvent(kernel, &centres)?;
    let carrier = carrier.resolve(&lo, &hi);
    let values: Vec<f64> = points.chunks_exact(3).map(|p| carrier.eval(p)).collect();
    Ok(Prepared { points, centres, values, carrier, norm, merged, box_lo: lo, box_hi: hi })
}

/// The serial reference: the whole bordered system assembled on one process and solved by the
/// dense oracle of `dense` (Householder or LU). Used to check the distributed solvers.
pub fn solve_serial(prep: &Prepared, kernel: &Kernel, solver: SolverKind) -> Result<Spline> {
    let n = system_size(kernel, prep.values.len());
    let rows = assemble_rows(kernel, &prep.centres, &prep.values, RowCyclic::new(n, 1, 0));
    let m = Matrix { rows: n, cols: n, data: rows.data[..n * n].to_vec() };
    let b = &rows.data[n * n..];
    let x = match solver {
        SolverKind::Lu => dense::lu_solve(&m, b)?,
        // the oracle for the projected Cholesky is the backward-stable QR solution
        SolverKind::Householder | SolverKind::Cholesky | SolverKind::Auto => dense::householder_solve(&m, b)?,
    };
    Ok(Spline::from_solution(*kernel, prep.centres.clone(), &x, prep.norm))
}

/// `volspline fit`: reconstructs the solid from scattered points and writes the model, the volume
/// and the mesh. Collective.
pub fn fit(comm: &dyn Comm, opts: &FitOptions, stages: &mut Stages) -> Result<FitSummary> {
    let carrier_spec = Carrier::parse(&opts.carrier, 3)?;
    let raw = stages.time("read", || read_points_everywhere(comm, &opts.input))?;
    let points_read = raw.len() / 3;

    let Prepared { points: pts, centres, values, carrier, norm, merged, box_lo: lo, box_hi: hi } =
        prepare(&raw, &opts.kernel, &carrier_spec, opts.merge_tol)?;
    let n = values.len();
    if comm.rank() == 0 {
        eprintln!(
            "volspline fit: {} points read from {}, {merged} duplicates merged, N = {n}, kernel {}, carrier {carrier}",
            points_read,
            opts.input.display(),
            opts.kernel.name()
        );
    }

    let layout = RowCyclic::new(n + opts.kernel.poly_count(), comm.size(), comm.rank());
    let assemble = || assemble_rows(&opts.kernel, &centres, &values, layout);
    let mut rows = stages.time("assemble", assemble);
    let progress = Progress::new("solve", comm);
    let mut solver_used = opts.solver.resolve(layout.n);
    let solution = stages.time("solve", || solver_used.solve(comm, &mut rows, opts.panel, &progress));
    let solution = match agree(comm, solution) {
        Err(Error::NotDefinite(why)) => {
            // the factorisation destroyed the system: assemble it again for LU
            if comm.rank() == 0 {
                eprintln!("volspline: cholesky: {why}; falling back to LU");
            }
            solver_used = SolverKind::Lu;
            rows = stages.time("assemble", assemble);
            let again = stages.time("solve", || SolverKind::Lu.solve(comm, &mut rows, opts.panel, &progress));
            agree(comm, again)?
        }
        other => other?,
    };
    drop(rows);

    let (residual, max_abs) = stages.time("check", || {
        let mut parts = residual_parts(&opts.kernel, &centres, &values, layout, &solution).to_vec();
        comm.sum_f64(&mut parts);
        let residual = if parts[1] > 0.0 { (parts[0] / parts[1]).sqrt() } else { parts[0].sqrt() };
        // max |f| at this rank's share of the points, with the blocked evaluator
        let spline = Spline::from_solution(opts.kernel, centres.clone(), &solution, norm);
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
        spline: Spline::from_solution(opts.kernel, centres, &solution, norm),
        provenance: Provenance {
            input: opts.input.display().to_string(),
            box_lo: [lo[0], lo[1], lo[2]],
            box_hi: [hi[0], hi[1], hi[2]],
            points_read,
            duplicates_merged: merged,
            solver: solver_used.name().to_string(),
            residual,
            ranks: comm.size(),
            threads: opts.threads,
            timings: stages.summarise(comm).into_iter().map(|t| (t.name, t.max)).collect(),
            version: env!("CARGO_PKG_VERSION").to_string(),
        },
    };
    let model_path = output_path(&opts.prefix, ".model.h5");
    stages.time("write", || {
        on_root(comm, || io::write_atomically(&model_path, |tmp| model_file::write_model(tmp, &model)))
    })?;

    let (plo, phi) = padded_box(&lo, &hi, opts.margin);
    let grid = Grid::covering(plo, phi, opts.grid)?;
    let volume = volume_outputs(comm, &model, &grid, &opts.prefix, stages)?;
    Ok(FitSummary {
        points_read,
        points_used: n,
        merged,
        residual,
        solver_used: solver_used.name(),
        panel_used: if opts.panel > 0 { opts.panel } else { solver_used.default_panel() },
        max_abs_f_at_points: max_abs,
        volume,
        model_path,
    })
}

/// The grid of `eval`: `--bounds`, or by default the fit's data box, so that the same `--grid` and
/// `--margin` give the fit's grid exactly.
pub(crate) fn eval_grid(opts: &EvalOptions, provenance: &Provenance) -> Result<Grid> {
    let (lo, hi) = match opts.bounds {
        Some(b) => b,
        None => padded_box(&provenance.box_lo, &provenance.box_hi, opts.margin),
    };
    Grid::covering(lo, hi, opts.grid)
}

/// `volspline eval`: evaluates a saved model on a new grid. Collective.
pub fn eval(comm: &dyn Comm, opts: &EvalOptions, stages: &mut Stages) -> Result<(Model, VolumeSummary)> {
    // every rank reads the (small, read-only) model file itself and all agree on the outcome
    let model = stages.time("read", || agree(comm, model_file::read_model(&opts.model)))?;
    let grid = eval_grid(opts, &model.provenance)?;
    let volume = volume_outputs(comm, &model, &grid, &opts.prefix, stages)?;
    Ok((model, volume))
}

/// Evaluates `model` on `grid` in z-slabs, writes `PREFIX.hdf` in parallel and `PREFIX.ply` from
/// rank 0. Collective.
pub fn volume_outputs(
    comm: &dyn Comm,
    model: &dyn Field,
    grid: &Grid,
    prefix: &Path,
    stages: &mut Stages,
) -> Result<VolumeSummary> {
    let slabs = grid.slabs(comm.size());
    let (k0, layers) = (slabs.start(comm.rank()), slabs.count(comm.rank()));
    let [nx, ny, nz] = grid.dims;
    // one ghost layer above the slab lets this rank polygonise the cells between its last layer and
    // the next rank's first
    let ghost = usize::from(layers > 0 && k0 + layers < nz);
    let values = stages.time("evaluate", || model.eval_layers(grid, k0, layers + ghost));
    if comm.rank() == 0 {
        eprintln!(
            "volspline: grid {}x{}x{} = {} nodes, {} kernel evaluations per node",
            nx,
            ny,
            nz,
            grid.node_count(),
            model.kernel_evals_per_node()
        );
    }

    let hdf_path = output_path(prefix, ".hdf");
    let written = stages.time("write", || {
        let tmp = io::partial_path(&hdf_path);
        let local = vtkhdf::write_image(comm, &tmp, grid, k0, layers, "f", &values[..nx * ny * layers]);
        let all = agree(comm, local);
        comm.barrier();
        match all {
            Ok(()) => on_root(comm, || io::commit(&hdf_path)),
            Err(e) => {
                if comm.rank() == 0 {
                    io::discard(&hdf_path);
                }
                Err(e)
            }
        }
    });
    written?;

    let ply_path = output_path(prefix, ".ply");
    let mut counts = [0.0f64; 2];
    stages.time("mesh", || -> Result<()> {
        let piece = mesh::polygonise(
            &SlabGrid { values: &values, nx, ny, nz, k0, layers, origin: grid.origin, spacing: grid.spacing },
            0.0,
        );
        let gathered = comm.gather_bytes(0, &piece_to_bytes(&piece));
        on_root(comm, || {
            let pieces: Vec<MeshPiece> =
                gathered.unwrap_or_default().iter().map(|b| piece_from_bytes(b)).collect();
            let mesh: TriMesh = mesh::weld(&pieces);
            counts = [mesh.triangles.len() as f64, mesh.vertices.len() as f64];
            io::write_atomically(&ply_path, |tmp| mesh::write_ply(tmp, &mesh).map_err(|e| Error::io(tmp, &e)))
        })
    })?;
    comm.broadcast_f64(0, &mut counts);
    Ok(VolumeSummary {
        grid: *grid,
        triangles: counts[0] as usize,
        vertices: counts[1] as usize,
        hdf_path,
        ply_path,
    })
}

fn piece_to_bytes(p: &MeshPiece) -> Vec<u8> {
    let mut b = Vec::with_capacity(16 + p.edge_ids.len() * 32 + p.triangles.len() * 12);
    b.extend_from_slice(&(p.edge_ids.len() as u64).to_le_bytes());
    b.extend_from_slice(&(p.triangles.len() as u64).to_le_bytes());
    for (id, pos) in p.edge_ids.iter().zip(&p.positions) {
        b.extend_from_slice(&id.to_le_bytes());
        for v in pos {
            b.extend_from_slice(&v.to_le_bytes());
        }
    }
    for t in &p.triangles {
        for v in t {
            b.extend_from_slice(&v.to_le_bytes());
        }
    }
    b
}

fn piece_from_bytes(b: &[u8]) -> MeshPiece {
    let u64_at = |o: usize| u64::from_le_bytes(b[o..o + 8].try_into().expect("8 bytes"));
    let f64_at = |o: usize| f64::from_le_bytes(b[o..o + 8].try_into().expect("8 bytes"));
    let u32_at = |o: usize| u32::from_le_bytes(b[o..o + 4].try_into().expect("4 bytes"));
    let (nv, nt) = (u64_at(0) as usize, u64_at(8) as usize);
    let mut p = MeshPiece {
        edge_ids: Vec::with_capacity(nv),
        positions: Vec::with_capacity(nv),
        triangles: Vec::with_capacity(nt),
    };
    let mut o = 16;
    for _ in 0..nv {
        p.edge_ids.push(u64_at(o));
        p.positions.push([f64_at(o + 8), f64_at(o + 16), f64_at(o + 24)]);
        o += 32;
    }
    for _ in 0..nt {
        p.triangles.push([u32_at(o), u32_at(o + 4), u32_at(o + 8)]);
        o += 12;
    }
    p
}
