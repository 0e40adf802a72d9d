//! The volume outputs every command ends with: the field evaluated on the grid in z-slabs (one slab
//! per rank, rayon threads within), written in parallel as one VTKHDF file, polygonised per slab
//! (with the next slab's first layer, received from its rank), gathered and welded on rank 0 and
//! written as PLY. On request the mean and Gaussian curvature
//! ([`crate::frep::curvature`]) go with them: at every node (of the level surface through it) as
//! two more arrays of the VTKHDF file, and at every vertex of the mesh as two vertex properties.

use std::path::{Path, PathBuf};

use super::finite::reach;
use super::preflight::{check_memory, grid_bytes, FIXED_BYTES};
use super::progress::Progress;
use super::report::Report;
use super::stages::{Stage, Stages};
use crate::error::{Error, Result};
use crate::frep::curvature::{check_curvature_reach, curvature, Curvature};
use crate::frep::Implicit;
use crate::grid::{padded_box, Grid, GridSize, FACE_NAMES, GROW_NODES, GROW_STEPS};
use crate::io::{self, vtkhdf};
use crate::mesh::trim::{area, trim_regions, Regions, RAISED_SHARE};
use crate::mesh::{self, MeshPiece, SlabGrid, TriMesh};
use crate::par::{on_root, Comm};
use crate::spline::{Field, Provenance};
use crate::surface::support::{DataSupport, DEPTH, OFF_PLANE, RAISED};

/// What writing the volume and the mesh produced.
#[derive(Debug, Clone)]
pub struct VolumeSummary {
    /// The grid written: the one asked for, or grown beyond the faces the solid reached.
    pub grid: Grid,
    /// Steps of growth of the grid (`--margin auto`).
    pub grown_steps: usize,
    /// Grid nodes evaluated in all, the grids before growth included (for the throughput).
    pub nodes_evaluated: usize,
    pub triangles: usize,
    pub vertices: usize,
    pub hdf_path: PathBuf,
    pub ply_path: PathBuf,
    /// Kernel evaluations per grid node (for the throughput figures).
    pub evals_per_node: usize,
    /// The trimmed surface, when asked for.
    pub trimmed: Option<Trimmed>,
    /// Grid nodes on the grid's faces with f >= 0: where the solid is cut open by the box.
    pub face_nodes_inside: u64,
}

impl VolumeSummary {
    /// Adds the grid, the surface and the two outputs to `report`.
    pub fn report(&self, report: &mut Report) {
        let g = &self.grid;
        // six decimals, or six digits with an exponent where decimals would show too few or too
        // many digits (a box at 1e100 printed 100 of them)
        let c = |v: f64| {
            if v != 0.0 && !(1e-3..1e6).contains(&v.abs()) {
                format!("{v:.6e}")
            } else {
                format!("{v:.6}")
            }
        };
        report.line(format!(
            "grid {} x {} x {} nodes, origin ({}, {}, {}), spacing ({}, {}, {})",
            g.dims[0],
            g.dims[1],
            g.dims[2],
            c(g.origin[0]),
            c(g.origin[1]),
            c(g.origin[2]),
            c(g.spacing[0]),
            c(g.spacing[1]),
            c(g.spacing[2])
        ));
        if self.grown_steps > 0 {
            report.line(format!(
                "grid grown {} step(s) beyond the faces the solid reached (--margin auto), {} nodes evaluated in all",
                self.grown_steps, self.nodes_evaluated
            ));
        }
        report.line(format!("surface f = 0: {} triangles, {} vertices", self.triangles, self.vertices));
        report.figure("grid_nodes", g.node_count());
        report.figure("grid_grown_steps", self.grown_steps);
        report.figure("triangles", self.triangles);
        report.figure("face_nodes_inside", self.face_nodes_inside);
        report.output(&self.hdf_path);
        report.output(&self.ply_path);
        if let Some(t) = &self.trimmed {
            report.line(format!(
                "trimmed surface (--trim {}: the regions of triangles farther than {:.4e} from every data \
                 point that reach {:.4e} (or twice the local radius where the data are sparser) or stand {:.4e} \
                 off the plane of the nearest data, with {:.0} % of their area {:.4e} off it, left out): {} \
                 region{} ({} reaching deep, {} standing off; {} standing off with less of their area raised \
                 kept), {:.2} % of the area left out, {} triangles kept",
                t.factor,
                t.radius,
                DEPTH * t.radius,
                OFF_PLANE * t.radius,
                100.0 * RAISED_SHARE,
                RAISED * t.radius,
                t.regions.total(),
                if t.regions.total() == 1 { "" } else { "s" },
                t.regions.deep,
                t.regions.off,
                t.regions.spared,
                100.0 * t.area_removed,
                t.triangles,
            ));
            report.figure("trimmed_triangles", t.triangles);
            report.figure("trimmed_regions", t.regions.total());
            report.figure("trimmed_regions_deep", t.regions.deep);
            report.figure("trimmed_regions_off", t.regions.off);
            report.figure("trimmed_regions_spared", t.regions.spared);
            report.figure("trimmed_area_removed", format!("{:e}", t.area_removed));
            report.output(&t.path);
        }
    }
}

/// `PREFIX` + suffix.
pub fn output_path(prefix: &Path, suffix: &str) -> PathBuf {
    let mut s = prefix.as_os_str().to_owned();
    s.push(suffix);
    PathBuf::from(s)
}

/// The grid of a fitted model: `bounds`, or by default the fit's data box plus `margin`, so that
/// the same `--grid` and `--margin` give the fit's grid exactly.
pub fn model_grid(
    size: GridSize,
    bounds: Option<([f64; 3], [f64; 3])>,
    margin: f64,
    provenance: &Provenance,
) -> Result<Grid> {
    let (lo, hi) = match bounds {
        Some(b) => b,
        None => padded_box(&provenance.box_lo, &provenance.box_hi, margin),
    };
    Grid::covering(lo, hi, size)
}

/// Refuses a grid whose slab (with the curvature arrays where asked) would not fit in a rank's
/// memory beside the program's fixed part ([`FIXED_BYTES`], which the dense checks count too).
/// Collective.
pub fn check_grid(comm: &dyn Comm, grid: &Grid, curvature: bool) -> Result<()> {
    let [nx, ny, nz] = grid.dims;
    if curvature {
        let far = grid.node(nx - 1, ny - 1, nz - 1);
        check_curvature_reach(reach(&grid.origin).max(reach(&far)), "--curvature")?;
    }
    let slab = grid_bytes(grid, comm.size(), curvature);
    check_memory(
        comm,
        slab + FIXED_BYTES,
        &format!(
            "the grid of {nx} x {ny} x {nz} nodes (per rank its slab {:.0} MB and {:.0} MB for the libraries \
             and MPI's buffers)",
            slab / 1e6,
            FIXED_BYTES / 1e6
        ),
        "use a coarser --grid or more ranks (the grid is split in z-slabs over them)",
    )
}

/// Kernel evaluations of a piece of a slab between two reports of the evaluation's progress:
/// about half a second of one core.
const PIECE_EVALS: f64 = 2e9;

/// `field` on the `layers` layers from `k0` of `grid`, as one call of [`Field::eval_layers`]
/// would give them (a node's value depends on its position alone), computed in pieces of whole
/// layers of at least `piece_evals` kernel evaluations at `per_node` a node, with `report(done,
/// total)` in layers before the first and after each.
fn eval_in_pieces(
    field: &dyn Field,
    grid: &Grid,
    (k0, layers): (usize, usize),
    per_node: usize,
    piece_evals: f64,
    report: &dyn Fn(usize, usize),
) -> Vec<f64> {
    let [nx, ny, _] = grid.dims;
    let per_layer = (nx * ny * per_node.max(1)) as f64;
    let step = ((piece_evals / per_layer).ceil() as usize).clamp(1, layers.max(1));
    if step >= layers {
        let values = field.eval_layers(grid, k0, layers);
        report(layers, layers);
        return values;
    }
    let mut values = Vec::with_capacity(nx * ny * (layers + 1));
    report(0, layers);
    for start in (0..layers).step_by(step) {
        let count = step.min(layers - start);
        values.extend(field.eval_layers(grid, k0 + start, count));
        report(start + count, layers);
    }
    values
}

/// The names of the curvature arrays, in the VTKHDF file and the PLY mesh.
pub const CURVATURE_ARRAYS: [&str; 2] = ["mean_curvature", "gaussian_curvature"];

/// The curvatures at the `count` points `point(0..count)`, threaded: (mean, Gaussian), without
/// other arrays of the points' size (on a grid's slab they are the memory the check counts).
fn curvatures(
    solid: &dyn Implicit,
    count: usize,
    point: impl Fn(usize) -> [f64; 3] + Sync,
) -> (Vec<f64>, Vec<f64>) {
    use rayon::prelude::*;
    (0..count)
        .into_par_iter()
        .map(|q| {
            let c: Curvature = curvature(solid, point(q));
            (c.mean, c.gaussian)
        })
        .unzip()
}

/// What trimming left of the surface.
#[derive(Debug, Clone)]
pub struct Trimmed {
    pub factor: f64,
    pub radius: f64,
    pub triangles: usize,
    /// The share of the surface's area left out.
    pub area_removed: f64,
    /// The unsupported regions left out.
    pub regions: Regions,
    pub path: PathBuf,
}

/// What [`write_volume`] writes: `field` on `grid` as `prefix`.hdf and `prefix`.ply, with the
/// curvatures of `curvature` (the same solid as `field`) when given, the grid grown where the
/// solid reaches it when `grow` (`--margin auto`: by whole cells at the same spacing, at most
/// [`GROW_STEPS`] steps and [`GROW_NODES`] times the nodes), and with `trim` the surface without
/// the triangles no data supports too, `prefix`.trimmed.ply.
pub struct Volume<'a> {
    pub field: &'a dyn Field,
    pub curvature: Option<&'a dyn Implicit>,
    pub grid: Grid,
    pub grow: bool,
    pub prefix: &'a Path,
    pub trim: Option<&'a DataSupport>,
    /// What the warning adds where the solid reaches the grid's faces after all the growth
    /// allowed: the likely cause for the kind of fit that made the field.
    pub unbounded_cause: Option<&'static str>,
}

impl<'a> Volume<'a> {
    /// `field` on `grid` as `prefix`: no curvature, a fixed grid, no trimmed surface.
    pub fn new(field: &'a dyn Field, grid: Grid, prefix: &'a Path) -> Self {
        Volume { field, curvature: None, grid, grow: false, prefix, trim: None, unbounded_cause: None }
    }

    pub fn curvature(self, curvature: Option<&'a dyn Implicit>) -> Self {
        Volume { curvature, ..self }
    }

    pub fn grow(self, grow: bool) -> Self {
        Volume { grow, ..self }
    }

    pub fn trim(self, trim: Option<&'a DataSupport>) -> Self {
        Volume { trim, ..self }
    }

    pub fn unbounded_cause(self, unbounded_cause: Option<&'static str>) -> Self {
        Volume { unbounded_cause, ..self }
    }
}

/// The values of this rank's slab of a grid (its layers from `k0`, and the next rank's first
/// layer after them where there is one) and the nodes on each of the grid's six faces with
/// f >= 0, summed over the ranks. Collective.
struct Evaluated {
    grid: Grid,
    values: Vec<f64>,
    k0: usize,
    layers: usize,
    /// -x, +x, -y, +y, -z, +z.
    on_faces: [u64; 6],
    faces: u64,
    inside: u64,
}

/// `field` on `grid`, and with `grow`, while the solid reaches some faces of the grid, on the grid
/// grown beyond those faces by [`Grid::grow_cells`] of the first grid, twice as many each step
/// (at the same spacing, so the nodes already there keep their places), evaluated again: at
/// most [`GROW_STEPS`] steps and [`GROW_NODES`] times the first grid's nodes, and only while
/// the grown grid fits in the ranks' memory. Returns the last evaluation, the steps taken and
/// the nodes evaluated in all. The decision is made on sums over the ranks, so every rank
/// takes the same steps. Collective.
fn evaluate_growing(
    comm: &dyn Comm,
    field: &dyn Field,
    (grid, curvature): (&Grid, bool),
    grow: bool,
    evals_per_node: usize,
    stages: &mut Stages,
) -> Result<(Evaluated, usize, usize)> {
    let (mut current, mut steps, mut nodes) = (*grid, 0, 0);
    loop {
        let e = evaluate(comm, field, &current, evals_per_node, stages)?;
        nodes += current.node_count();
        let touched = e.on_faces.map(|c| c > 0);
        // twice the cells of the step before: a solid far beyond the box is reached in a few
        let cells = grid.grow_cells() << steps;
        let next = current.grown(touched, cells);
        let room = steps < GROW_STEPS && next.node_count() <= GROW_NODES * grid.node_count();
        // a grid inside the solid everywhere has nothing to grow towards; a grown grid that
        // would not fit in the ranks' memory is not tried (the same answer on every rank)
        if !grow
            || !touched.contains(&true)
            || !room
            || e.inside == e.grid.node_count() as u64
            || check_grid(comm, &next, curvature).is_err()
        {
            return Ok((e, steps, nodes));
        }
        if comm.rank() == 0 {
            let sides: Vec<&str> = (0..6).filter(|&f| touched[f]).map(|f| FACE_NAMES[f]).collect();
            crate::note!(
                "volspline: the solid reaches the grid's {} face(s) ({} nodes): growing the grid by {cells} \
                 cells there (--margin auto)",
                sides.join(", "),
                e.on_faces.iter().sum::<u64>()
            );
        }
        current = next;
        steps += 1;
    }
}

/// `field` on this rank's slab of `grid`, with the ghost layer and the face counts of
/// [`Evaluated`]. Collective.
fn evaluate(
    comm: &dyn Comm,
    field: &dyn Field,
    grid: &Grid,
    evals_per_node: usize,
    stages: &mut Stages,
) -> Result<Evaluated> {
    let slabs = grid.slabs(comm.size());
    let (k0, layers) = (slabs.start(comm.rank()), slabs.count(comm.rank()));
    let [nx, ny, nz] = grid.dims;
    // one ghost layer above the slab lets this rank polygonise the cells between its last layer and
    // the next rank's first
    let ghost = usize::from(layers > 0 && k0 + layers < nz);
    let layer = nx * ny;
    if comm.rank() == 0 {
        let line = format!(
            "volspline: grid {}x{}x{} = {} nodes, {} kernel evaluations per node",
            nx,
            ny,
            nz,
            grid.node_count(),
            evals_per_node
        );
        // said once for the frames of a morph, which all share it
        static SAID: std::sync::Mutex<String> = std::sync::Mutex::new(String::new());
        let mut said = SAID.lock().unwrap_or_else(|e| e.into_inner());
        if *said != line {
            crate::note!("{line}");
            *said = line;
        }
    }
    let values = stages.time(Stage::Evaluate, || {
        let progress = Progress::new("evaluate", comm);
        let mut values = eval_in_pieces(field, grid, (k0, layers), evals_per_node, PIECE_EVALS, &|d, t| {
            progress.update(d, t)
        });
        if comm.size() > 1 {
            // the ghost layer is the next rank's first layer, received rather than evaluated twice
            // (the same bits: a node's value does not depend on the rank); a cyclic shift down the
            // ranks, in which the last rank's message is not needed and a rank without layers sends
            // zeros
            let zeros;
            let first: &[f64] = if layers > 0 {
                &values[..layer]
            } else {
                zeros = vec![0.0; layer];
                &zeros
            };
            let mut next = vec![0.0; layer];
            let (rank, size) = (comm.rank(), comm.size());
            comm.shift_f64((rank + size - 1) % size, (rank + 1) % size, first, &mut next);
            if ghost == 1 {
                values.extend_from_slice(&next);
            }
        }
        values
    });
    // a non-finite value would make an unusable volume and mesh: refuse it with the cause
    super::finite::check_slab(comm, &values[..layer * layers])?;
    let mut counts = inside_on_each_face(&values[..layer * layers], grid.dims, k0).to_vec();
    counts.push(values[..layer * layers].iter().filter(|&&f| f >= 0.0).count() as u64);
    comm.sum_u64(&mut counts);
    let on_faces = [counts[0], counts[1], counts[2], counts[3], counts[4], counts[5]];
    Ok(Evaluated {
        grid: *grid,
        values,
        k0,
        layers,
        on_faces,
        faces: face_node_count(grid.dims),
        inside: counts[6],
    })
}

/// Evaluates the field of `v` on its grid in z-slabs (growing the grid first where asked),
/// writes `PREFIX.hdf` in parallel and `PREFIX.ply` (and `PREFIX.trimmed.ply`) from rank 0, all
/// under this run's temporary names (see [`io::staging`]). Collective.
pub fn write_volume(comm: &dyn Comm, v: Volume<'_>, stages: &mut Stages) -> Result<VolumeSummary> {
    let Volume { field, curvature, grid, grow, prefix, trim, unbounded_cause } = v;
    let grid = &grid;
    // measured once (a compact model samples its neighbour counts through an octree)
    let evals_per_node = field.kernel_evals_per_node();
    let (e, grown_steps, nodes_evaluated) =
        evaluate_growing(comm, field, (grid, curvature.is_some()), grow, evals_per_node, stages)?;
    let Evaluated { grid, values, k0, layers, on_faces, faces, inside } = e;
    let grid = &grid;
    let [nx, ny, nz] = grid.dims;
    let on_faces: u64 = on_faces.iter().sum();
    let ply_path = output_path(prefix, ".ply");
    if comm.rank() == 0 {
        let nodes = grid.node_count() as u64;
        let why = nothing_to_mesh(inside, nodes)
            .or_else(|| cut_open(on_faces, faces, grow.then_some(grown_steps), unbounded_cause));
        if let Some(w) = why {
            crate::note!("volspline: warning: {}: {w}", ply_path.display());
        }
    }

    let node_curvature = curvature.map(|solid| {
        stages.time(Stage::Evaluate, || {
            let node = |q: usize| grid.node(q % nx, (q / nx) % ny, k0 + q / (nx * ny));
            curvatures(solid, nx * ny * layers, node)
        })
    });
    let hdf_path = output_path(prefix, ".hdf");
    stages.time(Stage::Write, || {
        // written under this run's temporary name; renamed with the other outputs at the end
        let tmp = io::staging::register(&hdf_path);
        let mut arrays: Vec<(&str, &[f64])> = vec![("f", &values[..nx * ny * layers])];
        if let Some((mean, gauss)) = &node_curvature {
            arrays.push((CURVATURE_ARRAYS[0], mean));
            arrays.push((CURVATURE_ARRAYS[1], gauss));
        }
        vtkhdf::write_image_arrays(comm, &tmp, grid, k0, layers, &arrays)
            .map_err(|e| io::staging::named_as_output(e, &hdf_path, &tmp))
    })?;

    let trimmed_path = output_path(prefix, ".trimmed.ply");
    // triangles kept and share of the area left out, on rank 0
    let mut trim_figures = [0.0f64; 5];
    let mut counts = [0u64; 2];
    stages.time(Stage::Mesh, || -> Result<()> {
        let piece = mesh::polygonise(
            &SlabGrid { values: &values, nx, ny, nz, k0, layers, origin: grid.origin, spacing: grid.spacing },
            0.0,
        );
        let gathered: Option<Vec<MeshPiece>> = comm.gather_values(0, &piece);
        on_root(comm, || {
            let mesh: TriMesh = mesh::weld(&gathered.unwrap_or_default());
            counts = [mesh.triangles.len() as u64, mesh.vertices.len() as u64];
            let at_vertices =
                curvature.map(|solid| curvatures(solid, mesh.vertices.len(), |q| mesh.vertices[q]));
            let props: Vec<mesh::VertexProperty<'_>> = match &at_vertices {
                Some((mean, gauss)) => vec![(CURVATURE_ARRAYS[0], mean), (CURVATURE_ARRAYS[1], gauss)],
                None => Vec::new(),
            };
            io::write_atomically(&ply_path, |tmp| {
                mesh::write_ply_with(tmp, &mesh, &props).map_err(|e| Error::io(tmp, &e))
            })?;
            if let Some(support) = trim {
                let (kept, from, regions) = trim_regions(&mesh, |c| support.judge(c));
                // the kept vertices' curvatures
                let kept_props: Vec<Vec<f64>> =
                    props.iter().map(|(_, v)| from.iter().map(|&i| v[i]).collect()).collect();
                let kept_props: Vec<mesh::VertexProperty<'_>> =
                    props.iter().zip(&kept_props).map(|((name, _), v)| (*name, v.as_slice())).collect();
                let whole = area(&mesh);
                let removed = if whole > 0.0 { 1.0 - area(&kept) / whole } else { 0.0 };
                trim_figures = [
                    kept.triangles.len() as f64,
                    removed,
                    regions.deep as f64,
                    regions.off as f64,
                    regions.spared as f64,
                ];
                io::write_atomically(&trimmed_path, |tmp| {
                    mesh::write_ply_with(tmp, &kept, &kept_props).map_err(|e| Error::io(tmp, &e))
                })?;
            }
            Ok(())
        })
    })?;
    comm.sum_u64(&mut counts);
    // every rank reports what rank 0 trimmed
    let trimmed = trim.map(|support| {
        comm.broadcast_f64(0, &mut trim_figures);
        Trimmed {
            factor: support.factor,
            radius: support.radius,
            triangles: trim_figures[0] as usize,
            area_removed: trim_figures[1],
            regions: Regions {
                deep: trim_figures[2] as usize,
                off: trim_figures[3] as usize,
                spared: trim_figures[4] as usize,
            },
            path: trimmed_path,
        }
    });
    Ok(VolumeSummary {
        grid: *grid,
        grown_steps,
        nodes_evaluated,
        triangles: counts[0] as usize,
        vertices: counts[1] as usize,
        hdf_path,
        ply_path,
        evals_per_node,
        trimmed,
        face_nodes_inside: on_faces,
    })
}

/// Why no surface can come from a grid with `inside` of its `nodes` nodes at f >= 0, when none
/// can: every node outside or every node inside.
fn nothing_to_mesh(inside: u64, nodes: u64) -> Option<String> {
    if inside == 0 {
        Some(format!(
            "f < 0 at all {nodes} nodes of the grid: the solid is empty there (or thinner than a cell), \
             so the surface has no triangles; a finer --grid shows a solid thinner than the cells"
        ))
    } else if inside == nodes {
        Some(format!(
            "f >= 0 at all {nodes} nodes of the grid: the grid lies inside the solid, so the surface has \
             no triangles; a larger --bounds (or --margin) reaches its outside"
        ))
    } else {
        None
    }
}

/// Of this rank's nodes of a grid of `dims` nodes, its layers from `k0` in `values`, those with
/// f >= 0 on each of the grid's six faces (-x, +x, -y, +y, -z, +z; a node on an edge counts
/// for each face it lies on).
fn inside_on_each_face(values: &[f64], dims: [usize; 3], k0: usize) -> [u64; 6] {
    let [nx, ny, nz] = dims;
    let layer = nx * ny;
    let mut inside = [0u64; 6];
    for (t, slab) in values.chunks_exact(layer.max(1)).enumerate() {
        let k = k0 + t;
        for (q, &f) in slab.iter().enumerate() {
            if f < 0.0 {
                continue;
            }
            let (i, j) = (q % nx, q / nx);
            let on = [i == 0, i + 1 == nx, j == 0, j + 1 == ny, k == 0, k + 1 == nz];
            for (c, o) in inside.iter_mut().zip(on) {
                *c += u64::from(o);
            }
        }
    }
    inside
}

/// The nodes on the faces of a grid of `dims` nodes (each once).
fn face_node_count(dims: [usize; 3]) -> u64 {
    let all: u64 = dims.iter().map(|&n| n as u64).product();
    let interior: u64 = dims.iter().map(|&n| n.saturating_sub(2) as u64).product();
    all - interior
}

/// Why the surface is open, when the solid reaches the grid's faces: `on_faces` nodes on them
/// at f >= 0 (counted once per face a node lies on) of the `faces` nodes on them; `grown`: the
/// steps of growth `--margin auto` took (None when the margin was fixed or the box given).
/// Marching cubes closes no surface at the grid's faces, so the mesh then has holes there, and
/// the volume shows a solid cut off by the box. `cause`: the likely cause of a solid that the
/// growth did not take in, for the kind of fit that made it.
fn cut_open(on_faces: u64, faces: u64, grown: Option<usize>, cause: Option<&str>) -> Option<String> {
    (on_faces > 0).then(|| {
        let advice = match grown {
            Some(steps) => format!(
                "the grid grew {steps} step(s) (--margin auto) and stopped at its limit: the solid reaches \
                 far from the data or is unbounded{}; a fixed --margin (with eval, or --bounds) sets the box",
                cause.map(|c| format!(" ({c})")).unwrap_or_default()
            ),
            None => "a larger --margin (with eval, or --bounds) takes in the whole solid".to_string(),
        };
        format!(
            "the solid reaches the grid's faces (f >= 0 at {on_faces} places on the {faces} nodes on them), \
             so the surface is cut open there and the mesh has holes; {advice}"
        )
    })
}

/// Evaluations per second of the evaluate stage, as a report line.
pub fn throughput_line(nodes: usize, per_node: usize, seconds: f64) -> Vec<String> {
    let evals = nodes as f64 * per_node as f64;
    if seconds > 0.0 {
        vec![format!("evaluation: {evals:.3e} kernel evaluations, {:.3e} per second", evals / seconds)]
    } else {
        Vec::new()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::spline::{Carrier, Kernel, Model, Normalisation, Provenance, Spline};

    #[test]
    fn a_slab_in_pieces_is_the_slab_in_one_piece() {
        // 40 centres on a helix with uneven weights, a grid of 7 x 5 x 13 nodes: pieces of 1, 2
        // and 5 layers (the last one short), and of all 11, give the same bits; the progress is
        // reported before the first piece and after each
        let centres: Vec<f64> =
            (0..40).flat_map(|i| [(i as f64).cos(), (i as f64).sin(), i as f64 / 40.0 - 0.5]).collect();
        let model = Model {
            carrier: Carrier::parse("ball:0,0,0,1.5", 3).unwrap(),
            spline: Spline {
                kernel: Kernel::new(3, 2).unwrap(),
                centres,
                weights: (0..40).map(|i| ((i * 7) % 11) as f64 / 11.0 - 0.4).collect(),
                poly: vec![0.1, -0.2, 0.3, 0.05],
                norm: Normalisation { centre: [0.1, 0.0, -0.1], scale: 0.8 },
            },
            coarse: Vec::new(),
            provenance: Provenance::default(),
        };
        let grid = Grid { dims: [7, 5, 13], origin: [-1.6; 3], spacing: [0.45, 0.6, 0.25] };
        let whole = model.eval_layers(&grid, 1, 11);
        for (layers_per_piece, reported) in [(1, 12), (2, 7), (5, 4), (11, 1), (40, 1)] {
            let reports = std::cell::RefCell::new(Vec::new());
            let piece_evals = (layers_per_piece * 7 * 5 * 40) as f64;
            let v = eval_in_pieces(&model, &grid, (1, 11), 40, piece_evals, &|d, t| {
                reports.borrow_mut().push((d, t))
            });
            assert_eq!(v, whole, "{layers_per_piece} layers a piece");
            let r = reports.into_inner();
            assert_eq!(r.len(), reported, "{layers_per_piece} layers a piece: {r:?}");
            assert_eq!(r.last(), Some(&(11, 11)));
            assert!(r.windows(2).all(|w| w[0].0 < w[1].0), "{r:?}");
        }
    }

    #[test]
    fn the_nodes_on_the_grid_s_faces_are_counted_by_slab() {
        // a grid of 4 x 3 x 5 nodes: the faces hold all but the 2 x 1 x 3 interior nodes; the
        // slabs of layers 0..2 and 2..5 count them between them, and f >= 0 at one interior node
        // and one face node counts the face node alone
        let dims = [4, 3, 5];
        let mut values = vec![-1.0; 60];
        values[12 + 4 + 1] = 1.0; // (1, 1, 1): interior
        values[2 * 12 + 4] = 0.0; // (0, 1, 2): on the face i = 0
        let low = inside_on_each_face(&values[..24], dims, 0);
        let high = inside_on_each_face(&values[24..], dims, 2);
        assert_eq!(low, [0; 6]);
        assert_eq!(high, [1, 0, 0, 0, 0, 0]);
        assert_eq!(face_node_count(dims), 60 - 2 * 3);
        // a node on an edge and a corner count for each of their faces
        values[0] = 2.0; // (0, 0, 0): -x, -y, -z
        values[59] = 2.0; // (3, 2, 4): +x, +y, +z
        values[4 * 12 + 5] = 2.0; // (1, 1, 4): +z
        let low = inside_on_each_face(&values[..24], dims, 0);
        let high = inside_on_each_face(&values[24..], dims, 2);
        assert_eq!(low, [1, 0, 1, 0, 1, 0]);
        assert_eq!(high, [1, 1, 0, 1, 0, 2]);
        assert!(cut_open(0, 54, None, None).is_none());
        assert!(cut_open(1, 54, None, None).is_some_and(|w| w.contains("f >= 0 at 1 places on the 54 nodes")));
        assert!(cut_open(3, 54, Some(6), None).is_some_and(|w| w.contains("grew 6 step(s)")));
        assert!(
            cut_open(3, 54, Some(6), Some("a cause")).is_some_and(|w| w.contains("is unbounded (a cause);"))
        );
        // without growth the cause is not the point: the margin was the user's
        assert!(cut_open(3, 54, None, Some("a cause")).is_some_and(|w| !w.contains("a cause")));
    }

    #[test]
    fn a_grown_grid_keeps_its_nodes_and_adds_cells_beyond_the_faces_asked() {
        let g = Grid { dims: [41, 21, 11], origin: [1.0, -2.0, 0.5], spacing: [0.25, 0.25, 0.25] };
        assert_eq!(g.grow_cells(), 2);
        let h = g.grown([true, false, false, true, true, true], 3);
        assert_eq!(h.dims, [44, 24, 17]);
        assert_eq!(h.origin, [0.25, -2.0, -0.25]);
        assert_eq!(h.spacing, g.spacing);
        // node (i, j, k) of g is node (i + 3, j, k + 3) of h, at the same place
        assert_eq!(h.node(3 + 40, 20, 3 + 10), g.node(40, 20, 10));
        assert_eq!(g.grown([false; 6], 3), g);
    }
}
