//! The collective stages of `volspline contours` (read -> solve the slices -> write the model ->
//! evaluate -> mesh -> write), `volspline eval` of a contour model, and `volspline slice`, which
//! cuts a triangle mesh by a family of planes into a contour file.
//!
//! The slices' systems are independent: slice i is assembled and solved serially by rank
//! i mod P, then its owner broadcasts the solution, so every rank holds every section bit for bit
//! the same whatever P is. The grid is evaluated in z-slabs by `pipeline::volume_outputs`.

use std::path::{Path, PathBuf};

use glam::{DMat3, DVec3};

use super::format::{self, Section};
use super::{fit_section, ContourModel, Interp, Orient, SectionCarrier, SectionFit, SectionModel};
use crate::carrier::Carrier;
use crate::dist::{agree, Comm};
use crate::error::{Error, Result};
use crate::geometry::bounding_box;
use crate::grid::{padded_box, Grid, GridSize};
use crate::io::{self, contour_model_file, points};
use crate::kernel::Kernel;
use crate::mesh::{cut_by_plane, TriMesh};
use crate::model::Provenance;
use crate::pipeline::{on_root, output_path, volume_outputs, EvalOptions, VolumeSummary};
use crate::report::Stages;
use crate::spline::{Normalisation, Spline};

/// Options of `volspline contours`.
#[derive(Debug, Clone)]
pub struct ContoursOptions {
    pub input: PathBuf,
    pub prefix: PathBuf,
    pub interp: Interp,
    pub orient: Orient,
    /// The two-dimensional kernel of the sections.
    pub kernel: Kernel,
    pub carrier: SectionCarrier,
    pub grid: GridSize,
    pub margin: f64,
    pub merge_tol: f64,
    pub threads: usize,
}

/// What a `contours` run produced and measured (the same on every rank).
#[derive(Debug, Clone)]
pub struct ContoursSummary {
    pub slices: usize,
    pub contours: usize,
    pub points_read: usize,
    pub points_used: usize,
    pub merged: usize,
    /// Largest relative residual of the slices' systems.
    pub max_residual: f64,
    /// Largest |F_i| at slice i's own points.
    pub max_abs_at_points: f64,
    pub volume: VolumeSummary,
    pub model_path: PathBuf,
}

/// Reads the contour file on rank 0, gives its text to every rank and parses it everywhere.
fn read_sections_everywhere(comm: &dyn Comm, path: &Path) -> Result<Vec<Section>> {
    let local =
        if comm.rank() == 0 { std::fs::read(path).map_err(|e| Error::io(path, &e)) } else { Ok(Vec::new()) };
    let mut bytes = agree(comm, local)?;
    comm.broadcast_bytes(0, &mut bytes);
    let text = String::from_utf8(bytes).map_err(|e| Error::input(path, "", format!("not UTF-8 text: {e}")));
    agree(comm, text.and_then(|t| format::parse(path, &t)))
}

fn fit_to_bytes(f: &SectionFit) -> Vec<u8> {
    let sp = &f.spline;
    let mut v = vec![
        f.points as f64,
        f.merged as f64,
        f.residual,
        f.max_abs_at_points,
        sp.norm.centre[0],
        sp.norm.centre[1],
        sp.norm.scale,
        sp.weights.len() as f64,
    ];
    v.extend_from_slice(&sp.poly);
    v.extend_from_slice(&sp.centres);
    v.extend_from_slice(&sp.weights);
    let mut b: Vec<u8> = (v.len() as u64).to_le_bytes().to_vec();
    b.extend(v.iter().flat_map(|x| x.to_le_bytes()));
    b.extend_from_slice(f.carrier.to_string().as_bytes());
    b
}

fn fit_from_bytes(b: &[u8], kernel: Kernel) -> Result<SectionFit> {
    let corrupt = || Error::Numerical("a slice's solution arrived corrupted".into());
    let count =
        u64::from_le_bytes(b.get(..8).ok_or_else(corrupt)?.try_into().map_err(|_| corrupt())?) as usize;
    let end = count.checked_mul(8).and_then(|x| x.checked_add(8)).ok_or_else(corrupt)?;
    let v: Vec<f64> = b
        .get(8..end)
        .ok_or_else(corrupt)?
        .chunks_exact(8)
        .map(|c| f64::from_le_bytes(c.try_into().expect("8 bytes")))
        .collect();
    let k = kernel.poly_count();
    let n = v.get(7).copied().ok_or_else(corrupt)? as usize;
    if v.len() != 8 + k + 3 * n {
        return Err(corrupt());
    }
    let carrier = Carrier::parse(std::str::from_utf8(&b[end..]).map_err(|_| corrupt())?, 2)?;
    let norm = Normalisation { centre: [v[4], v[5], 0.0], scale: v[6] };
    let spline = Spline {
        kernel,
        poly: v[8..8 + k].to_vec(),
        centres: v[8 + k..8 + k + 2 * n].to_vec(),
        weights: v[8 + k + 2 * n..].to_vec(),
        norm,
    };
    Ok(SectionFit {
        carrier,
        spline,
        points: v[0] as usize,
        merged: v[1] as usize,
        residual: v[2],
        max_abs_at_points: v[3],
    })
}

/// Solves every slice: slice i on rank i mod P, then broadcast from its owner. Collective.
pub fn solve_sections(
    comm: &dyn Comm,
    source: &Path,
    sections: &[Section],
    kernel: &Kernel,
    carrier: SectionCarrier,
    merge_tol: f64,
) -> Result<Vec<SectionFit>> {
    let (p, r) = (comm.size(), comm.rank());
    let mine: Result<Vec<SectionFit>> = sections
        .iter()
        .skip(r)
        .step_by(p)
        .map(|s| {
            fit_section(s, kernel, carrier, merge_tol).map_err(|e| match e {
                Error::Numerical(m) => Error::Numerical(format!("{}: {m}", source.display())),
                other => other,
            })
        })
        .collect();
    let mine = agree(comm, mine)?;
    let mut fits = Vec::with_capacity(sections.len());
    for i in 0..sections.len() {
        let owner = i % p;
        let mut bytes = if owner == r { fit_to_bytes(&mine[i / p]) } else { Vec::new() };
        comm.broadcast_bytes(owner, &mut bytes);
        fits.push(if owner == r { Ok(mine[i / p].clone()) } else { fit_from_bytes(&bytes, *kernel) });
    }
    let fits: Result<Vec<SectionFit>> = fits.into_iter().collect();
    agree(comm, fits)
}

/// `volspline contours`: reconstructs the solid from a contour file and writes the model, the
/// volume and the mesh. Collective.
pub fn contours(comm: &dyn Comm, opts: &ContoursOptions, stages: &mut Stages) -> Result<ContoursSummary> {
    let sections = stages.time("read", || read_sections_everywhere(comm, &opts.input))?;
    let points_read: usize = sections.iter().map(Section::point_count).sum();
    let contours: usize = sections.iter().map(|s| s.contours.len()).sum();
    let world: Vec<f64> = sections
        .iter()
        .flat_map(|s| s.contours.iter().flatten().flat_map(move |p| s.world(*p).to_array()))
        .collect();
    let (lo, hi) = bounding_box(&world, 3);
    if comm.rank() == 0 {
        eprintln!(
            "volspline contours: {} slices, {contours} contours, {points_read} points from {}; kernel {}, carrier {}",
            sections.len(),
            opts.input.display(),
            opts.kernel.name(),
            opts.carrier.name()
        );
    }
    let fits = stages.time("solve", || {
        solve_sections(comm, &opts.input, &sections, &opts.kernel, opts.carrier, opts.merge_tol)
    })?;
    let max_residual = fits.iter().map(|f| f.residual).fold(0.0, f64::max);
    let max_abs = fits.iter().map(|f| f.max_abs_at_points).fold(0.0, f64::max);
    let merged: usize = fits.iter().map(|f| f.merged).sum();
    let points_used: usize = fits.iter().map(|f| f.points).sum();
    let models: Vec<SectionModel> = sections
        .iter()
        .zip(fits)
        .map(|(s, f)| SectionModel { origin: s.origin, frame: s.frame, carrier: f.carrier, spline: f.spline })
        .collect();
    let provenance = Provenance {
        input: opts.input.display().to_string(),
        box_lo: [lo[0], lo[1], lo[2]],
        box_hi: [hi[0], hi[1], hi[2]],
        points_read,
        duplicates_merged: merged,
        solver: "lu (serial, per slice)".into(),
        residual: max_residual,
        ranks: comm.size(),
        threads: opts.threads,
        timings: stages.summarise(comm).into_iter().map(|t| (t.name, t.max)).collect(),
        version: env!("CARGO_PKG_VERSION").to_string(),
    };
    let model = ContourModel::new(models, opts.interp, opts.orient, provenance);
    let model_path = output_path(&opts.prefix, ".model.h5");
    stages.time("write", || {
        on_root(comm, || {
            io::write_atomically(&model_path, |tmp| contour_model_file::write_contour_model(tmp, &model))
        })
    })?;
    let (plo, phi) = padded_box(&lo, &hi, opts.margin);
    let grid = Grid::covering(plo, phi, opts.grid)?;
    let volume = volume_outputs(comm, &model, &grid, &opts.prefix, stages)?;
    Ok(ContoursSummary {
        slices: sections.len(),
        contours,
        points_read,
        points_used,
        merged,
        max_residual,
        max_abs_at_points: max_abs,
        volume,
        model_path,
    })
}

/// `volspline eval` of a contour model. Collective.
pub fn eval_contour_model(
    comm: &dyn Comm,
    opts: &EvalOptions,
    stages: &mut Stages,
) -> Result<(ContourModel, VolumeSummary)> {
    let model = stages.time("read", || agree(comm, contour_model_file::read_contour_model(&opts.model)))?;
    let grid = crate::pipeline::eval_grid(opts, &model.provenance)?;
    let volume = volume_outputs(comm, &model, &grid, &opts.prefix, stages)?;
    Ok((model, volume))
}

/// A family of cutting planes for `volspline slice`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PlaneFamily {
    /// `AXIS:N`: N planes perpendicular to the axis (0, 1, 2 = x, y, z), evenly spaced through the
    /// mesh's extent (half a spacing in from either end).
    Parallel { axis: usize, count: usize },
    /// `fan-AXIS:N`: N planes sweeping along the axis while turning about a hinge line parallel to
    /// the next axis (x -> y -> z -> x), one box extent away along the third: the angle between
    /// the first and the last plane is some tens of degrees and the spacing doubles across the
    /// mesh.
    Fan { axis: usize, count: usize },
}

impl std::fmt::Display for PlaneFamily {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let name = |a: usize| ["x", "y", "z"][a];
        match *self {
            PlaneFamily::Parallel { axis, count } => write!(f, "{}:{count}", name(axis)),
            PlaneFamily::Fan { axis, count } => write!(f, "fan-{}:{count}", name(axis)),
        }
    }
}

impl PlaneFamily {
    pub fn parse(spec: &str) -> Result<Self> {
        let bad = || {
            Error::Usage(format!(
                "planes '{spec}': expected AXIS:N (parallel) or fan-AXIS:N (turning), AXIS x, y or z, N >= 2"
            ))
        };
        let (kind, n) = spec.split_once(':').ok_or_else(bad)?;
        let count: usize = n.trim().parse().map_err(|_| bad())?;
        if count < 2 {
            return Err(bad());
        }
        let axis_of = |a: &str| match a {
            "x" => Ok(0),
            "y" => Ok(1),
            "z" => Ok(2),
            _ => Err(bad()),
        };
        match kind.trim().strip_prefix("fan-") {
            Some(a) => Ok(PlaneFamily::Fan { axis: axis_of(a)?, count }),
            None => Ok(PlaneFamily::Parallel { axis: axis_of(kind.trim())?, count }),
        }
    }

    /// The planes (origin, frame with columns u, v, normal) for a mesh with vertices `pts`.
    pub fn planes(&self, pts: &[[f64; 3]]) -> Vec<(DVec3, DMat3)> {
        let flat: Vec<f64> = pts.iter().flatten().copied().collect();
        let (lo, hi) = bounding_box(&flat, 3);
        let e = |i: usize| {
            let mut v = DVec3::ZERO;
            v[i] = 1.0;
            v
        };
        match *self {
            PlaneFamily::Parallel { axis, count } => {
                let (u, v) = (e((axis + 1) % 3), e((axis + 2) % 3));
                let frame = DMat3::from_cols(u, v, u.cross(v));
                (0..count)
                    .map(|k| {
                        let mut origin = DVec3::ZERO;
                        origin[axis] = lo[axis] + (k as f64 + 0.5) * (hi[axis] - lo[axis]) / count as f64;
                        (origin, frame)
                    })
                    .collect()
            }
            PlaneFamily::Fan { axis, count } => {
                let (s, h, d) = (axis, (axis + 1) % 3, (axis + 2) % 3);
                let ext_d = hi[d] - lo[d];
                let mut hinge = DVec3::ZERO;
                hinge[s] = 0.5 * (lo[s] + hi[s]);
                hinge[h] = 0.5 * (lo[h] + hi[h]);
                hinge[d] = lo[d] - ext_d;
                let angle = |p: &[f64; 3]| (p[s] - hinge[s]).atan2(p[d] - hinge[d]);
                let (amin, amax) = pts
                    .iter()
                    .map(angle)
                    .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| (a.min(x), b.max(x)));
                let radius = 1.5 * ext_d;
                (0..count)
                    .map(|k| {
                        let th = amin + (k as f64 + 0.5) * (amax - amin) / count as f64;
                        let (u, v) = (e(h), e(d) * th.cos() + e(s) * th.sin());
                        (hinge + v * radius, DMat3::from_cols(u, v, u.cross(v)))
                    })
                    .collect()
            }
        }
    }
}

/// What `volspline slice` wrote.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SliceSummary {
    pub planes: usize,
    pub slices: usize,
    pub contours: usize,
    pub points: usize,
    /// Chains that ended on holes of the mesh and were closed by joining their ends.
    pub joined: usize,
}

/// Cuts `mesh` by `planes` into sections (planes that miss the mesh give no slice).
pub fn slice_mesh(mesh: &TriMesh, planes: &[(DVec3, DMat3)]) -> (Vec<Section>, SliceSummary) {
    let mut summary = SliceSummary { planes: planes.len(), ..Default::default() };
    let mut sections = Vec::new();
    for (o, m) in planes {
        let cut = cut_by_plane(mesh, o.to_array(), m.z_axis.to_array());
        summary.joined += cut.open.iter().filter(|c| c.len() >= 3).count();
        let contours: Vec<Vec<[f64; 2]>> = cut
            .closed
            .iter()
            .chain(&cut.open)
            .filter(|c| c.len() >= 3)
            .map(|c| {
                c.iter()
                    .map(|p| {
                        let d = DVec3::from_array(*p) - *o;
                        [m.x_axis.dot(d), m.y_axis.dot(d)]
                    })
                    .collect()
            })
            .collect();
        if contours.is_empty() {
            continue;
        }
        summary.contours += contours.len();
        summary.points += contours.iter().map(Vec::len).sum::<usize>();
        sections.push(Section { line: 0, origin: *o, frame: *m, kind: "plane", contours });
    }
    summary.slices = sections.len();
    (sections, summary)
}

/// `volspline slice`: rank 0 cuts the mesh and writes the contour file. Collective.
pub fn slice(comm: &dyn Comm, mesh_path: &Path, out: &Path, planes: PlaneFamily) -> Result<SliceSummary> {
    let mut summary = SliceSummary::default();
    on_root(comm, || {
        let set = points::read_mesh(mesh_path)?;
        let mesh = TriMesh {
            vertices: set.points.clone(),
            triangles: set.triangles.iter().map(|t| [t[0] as u32, t[1] as u32, t[2] as u32]).collect(),
        };
        let (sections, s) = slice_mesh(&mesh, &planes.planes(&mesh.vertices));
        if sections.len() < 2 {
            return Err(Error::Usage(format!(
                "only {} of the {} planes meet the mesh; at least two slices are needed",
                sections.len(),
                s.planes
            )));
        }
        let header = format!(
            "volspline contours from {} cut by planes {}\n{} slices, {} contours, {} points",
            mesh_path.display(),
            planes,
            s.slices,
            s.contours,
            s.points
        );
        io::write_atomically(out, |tmp| {
            std::fs::write(tmp, format::to_text(&sections, &header)).map_err(|e| Error::io(out, &e))
        })?;
        summary = s;
        Ok(())
    })?;
    let mut v =
        [summary.planes, summary.slices, summary.contours, summary.points, summary.joined].map(|x| x as f64);
    comm.broadcast_f64(0, &mut v);
    Ok(SliceSummary {
        planes: v[0] as usize,
        slices: v[1] as usize,
        contours: v[2] as usize,
        points: v[3] as usize,
        joined: v[4] as usize,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::contour::knots_of;

    #[test]
    fn plane_families_parse_and_are_ordered() {
        for spec in ["z:40", "x:2", "fan-y:12", "fan-z:3"] {
            assert_eq!(PlaneFamily::parse(spec).unwrap().to_string(), spec);
        }
        for bad in ["z", "z:1", "w:4", "fan-:4", "fan-q:4", "y:x"] {
            assert!(PlaneFamily::parse(bad).is_err(), "{bad}");
        }
        let pts: Vec<[f64; 3]> = (0..200)
            .map(|i| {
                let a = i as f64 * 0.7;
                [a.cos(), (1.3 * a).sin(), (0.37 * a).cos() * 2.0]
            })
            .collect();
        for spec in ["z:10", "fan-z:10", "fan-x:7"] {
            let planes = PlaneFamily::parse(spec).unwrap().planes(&pts);
            let tau = knots_of(&planes);
            assert!(tau.windows(2).all(|w| w[1] > w[0]), "{spec}: ordered along the normals");
            for (_, m) in &planes {
                assert!((m.determinant() - 1.0).abs() < 1e-14);
            }
        }
        let fan = PlaneFamily::parse("fan-z:10").unwrap().planes(&pts);
        let turn = fan[0].1.z_axis.angle_between(fan[9].1.z_axis);
        assert!(turn > 0.3 && turn < 1.6, "{turn}");
    }
}
