//! The volume outputs every command ends with: the field evaluated on the grid in z-slabs (one slab
//! per rank, rayon threads within), written in parallel as one VTKHDF file, polygonised per slab
//! (with the next slab's first layer, received from its rank), gathered and welded on rank 0 and
//! written as PLY. On request the mean and Gaussian curvature
//! ([`crate::frep::curvature`]) go with them: at every node (of the level surface through it) as
//! two more arrays of the VTKHDF file, and at every vertex of the mesh as two vertex properties.

use std::path::{Path, PathBuf};

use super::preflight::{check_memory, grid_bytes};
use super::progress::Progress;
use super::report::Report;
use super::stages::{Stage, Stages};
use crate::error::{Error, Result};
use crate::frep::curvature::{curvature, Curvature};
use crate::frep::Implicit;
use crate::grid::{padded_box, Grid, GridSize};
use crate::io::{self, vtkhdf};
use crate::mesh::trim::{area, keep_triangles_indexed};
use crate::mesh::{self, MeshPiece, SlabGrid, TriMesh};
use crate::par::{on_root, Comm};
use crate::spline::{Field, Provenance};
use crate::surface::support::DataSupport;

/// What writing the volume and the mesh produced.
#[derive(Debug, Clone)]
pub struct VolumeSummary {
    pub grid: Grid,
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
        report.line(format!(
            "grid {} x {} x {} nodes, origin ({:.6}, {:.6}, {:.6}), spacing ({:.6}, {:.6}, {:.6})",
            g.dims[0],
            g.dims[1],
            g.dims[2],
            g.origin[0],
            g.origin[1],
            g.origin[2],
            g.spacing[0],
            g.spacing[1],
            g.spacing[2]
        ));
        report.line(format!("surface f = 0: {} triangles, {} vertices", self.triangles, self.vertices));
        report.figure("grid_nodes", g.node_count());
        report.figure("triangles", self.triangles);
        report.figure("face_nodes_inside", self.face_nodes_inside);
        report.output(&self.hdf_path);
        report.output(&self.ply_path);
        if let Some(t) = &self.trimmed {
            report.line(format!(
                "trimmed surface (--trim {}: triangles farther than {:.4e} from every data point left out): {} \
                 triangles, {:.2} % of the area left out",
                t.factor,
                t.radius,
                t.triangles,
                100.0 * t.area_removed
            ));
            report.figure("trimmed_triangles", t.triangles);
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

/// Refuses a grid whose slab would not fit in a rank's memory. Collective.
pub fn check_grid(comm: &dyn Comm, grid: &Grid) -> Result<()> {
    let [nx, ny, nz] = grid.dims;
    check_memory(
        comm,
        grid_bytes(grid, comm.size()),
        &format!("the grid of {nx} x {ny} x {nz} nodes"),
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

/// The curvatures at `points`, threaded: (mean, Gaussian).
fn curvatures(solid: &dyn Implicit, points: &[[f64; 3]]) -> (Vec<f64>, Vec<f64>) {
    use rayon::prelude::*;
    let c: Vec<Curvature> = points.par_iter().map(|&p| curvature(solid, p)).collect();
    (c.iter().map(|c| c.mean).collect(), c.iter().map(|c| c.gaussian).collect())
}

/// What trimming left of the surface.
#[derive(Debug, Clone)]
pub struct Trimmed {
    pub factor: f64,
    pub radius: f64,
    pub triangles: usize,
    /// The share of the surface's area left out.
    pub area_removed: f64,
    pub path: PathBuf,
}

/// Evaluates `field` on `grid` in z-slabs, writes `PREFIX.hdf` in parallel and `PREFIX.ply` from
/// rank 0, both under this run's temporary names (see [`io::staging`]), with the curvatures of
/// `curvature` (the same solid as `field`) when given. Collective.
pub fn write_volume(
    comm: &dyn Comm,
    field: &dyn Field,
    curvature: Option<&dyn Implicit>,
    grid: &Grid,
    prefix: &Path,
    stages: &mut Stages,
) -> Result<VolumeSummary> {
    write_volume_with(comm, field, curvature, grid, prefix, None, stages)
}

/// [`write_volume`], and with `trim` the surface without the triangles no data supports too,
/// `PREFIX.trimmed.ply`. Collective.
pub fn write_volume_with(
    comm: &dyn Comm,
    field: &dyn Field,
    curvature: Option<&dyn Implicit>,
    grid: &Grid,
    prefix: &Path,
    trim: Option<&DataSupport>,
    stages: &mut Stages,
) -> Result<VolumeSummary> {
    let slabs = grid.slabs(comm.size());
    let (k0, layers) = (slabs.start(comm.rank()), slabs.count(comm.rank()));
    let [nx, ny, nz] = grid.dims;
    // one ghost layer above the slab lets this rank polygonise the cells between its last layer and
    // the next rank's first
    let ghost = usize::from(layers > 0 && k0 + layers < nz);
    let layer = nx * ny;
    // measured once (a compact model samples its neighbour counts through an octree)
    let evals_per_node = field.kernel_evals_per_node();
    if comm.rank() == 0 {
        eprintln!(
            "volspline: grid {}x{}x{} = {} nodes, {} kernel evaluations per node",
            nx,
            ny,
            nz,
            grid.node_count(),
            evals_per_node
        );
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
    let ply_path = output_path(prefix, ".ply");
    let [on_faces, faces] = inside_on_faces(&values[..layer * layers], grid.dims, k0);
    let mut inside = [values[..layer * layers].iter().filter(|&&f| f >= 0.0).count() as u64, on_faces, faces];
    comm.sum_u64(&mut inside);
    let [inside, on_faces, faces] = inside;
    if comm.rank() == 0 {
        let nodes = grid.node_count() as u64;
        let why = nothing_to_mesh(inside, nodes).or_else(|| cut_open(on_faces, faces));
        if let Some(w) = why {
            eprintln!("volspline: warning: {}: {w}", ply_path.display());
        }
    }

    let node_curvature = curvature.map(|solid| {
        stages.time(Stage::Evaluate, || {
            let nodes: Vec<[f64; 3]> =
                (0..nx * ny * layers).map(|q| grid.node(q % nx, (q / nx) % ny, k0 + q / (nx * ny))).collect();
            curvatures(solid, &nodes)
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
    let mut trim_figures = [0.0f64; 2];
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
            let at_vertices = curvature.map(|solid| curvatures(solid, &mesh.vertices));
            let props: Vec<mesh::VertexProperty<'_>> = match &at_vertices {
                Some((mean, gauss)) => vec![(CURVATURE_ARRAYS[0], mean), (CURVATURE_ARRAYS[1], gauss)],
                None => Vec::new(),
            };
            io::write_atomically(&ply_path, |tmp| {
                mesh::write_ply_with(tmp, &mesh, &props).map_err(|e| Error::io(tmp, &e))
            })?;
            if let Some(support) = trim {
                let (kept, from) = keep_triangles_indexed(&mesh, |c| support.supports(c));
                // the kept vertices' curvatures
                let kept_props: Vec<Vec<f64>> =
                    props.iter().map(|(_, v)| from.iter().map(|&i| v[i]).collect()).collect();
                let kept_props: Vec<mesh::VertexProperty<'_>> =
                    props.iter().zip(&kept_props).map(|((name, _), v)| (*name, v.as_slice())).collect();
                let whole = area(&mesh);
                let removed = if whole > 0.0 { 1.0 - area(&kept) / whole } else { 0.0 };
                trim_figures = [kept.triangles.len() as f64, removed];
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
            path: trimmed_path,
        }
    });
    Ok(VolumeSummary {
        grid: *grid,
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
             so the surface has no triangles"
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

/// Of this rank's nodes of a grid of `dims` nodes, its layers from `k0` in `values`, those on the
/// grid's six faces with f >= 0, and all those on the faces.
fn inside_on_faces(values: &[f64], dims: [usize; 3], k0: usize) -> [u64; 2] {
    let [nx, ny, nz] = dims;
    let layer = nx * ny;
    let (mut inside, mut faces) = (0, 0);
    for (t, slab) in values.chunks_exact(layer.max(1)).enumerate() {
        let k = k0 + t;
        let whole = k == 0 || k + 1 == nz;
        for (q, &f) in slab.iter().enumerate() {
            let (i, j) = (q % nx, q / nx);
            if whole || i == 0 || i + 1 == nx || j == 0 || j + 1 == ny {
                faces += 1;
                inside += u64::from(f >= 0.0);
            }
        }
    }
    [inside, faces]
}

/// Why the surface is open, when the solid reaches the grid's faces: `on_faces` of the `faces`
/// nodes on them at f >= 0. Marching cubes closes no surface at the grid's faces, so the mesh
/// then has holes there, and the volume shows a solid cut off by the box.
fn cut_open(on_faces: u64, faces: u64) -> Option<String> {
    (on_faces > 0).then(|| {
        format!(
            "the solid reaches the grid's faces (f >= 0 at {on_faces} of the {faces} nodes on them), so the \
             surface is cut open there and the mesh has holes; a larger --margin (or --bounds) takes in \
             the whole solid"
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
        let low = inside_on_faces(&values[..24], dims, 0);
        let high = inside_on_faces(&values[24..], dims, 2);
        assert_eq!(low, [0, 12 + 10]);
        assert_eq!(high, [1, 10 + 10 + 12]);
        assert_eq!(low[1] + high[1], 60 - 2 * 3);
        assert!(cut_open(0, 54).is_none());
        assert!(cut_open(1, 54).is_some_and(|w| w.contains("f >= 0 at 1 of the 54 nodes")));
    }
}
