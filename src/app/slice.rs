//! `volspline slice`: rank 0 cuts a triangle mesh by a family of planes and writes the contour
//! file that `volspline contours` reads.

use super::report::Report;
use super::stages::{Stage, Stages};
use crate::cli::SliceArgs;
use crate::contour::format;
use crate::contour::planes::{slice_mesh, SliceSummary};
use crate::error::{Error, Result};
use crate::io::{self, points};
use crate::mesh::clean::indexed;
use crate::mesh::TriMesh;
use crate::par::{on_root, Comm};
use crate::spline::hygiene::bounding_box;

/// Why no two planes met the mesh, when its box is flat along an axis.
fn flat_hint(vertices: &[[f64; 3]]) -> String {
    let flat: Vec<f64> = vertices.iter().flatten().copied().collect();
    let (lo, hi) = bounding_box(&flat, 3);
    match (0..3).find(|&d| !(hi[d] > lo[d])) {
        Some(d) => format!(" (the mesh is flat: its extent along {} is 0)", ["x", "y", "z"][d]),
        None => String::new(),
    }
}

/// Runs `volspline slice`. Collective (the work is rank 0's).
pub fn run(a: &SliceArgs, comm: &dyn Comm) -> Result<()> {
    let mut stages = Stages::default();
    let mut summary = None;
    on_root(comm, || {
        let what = "the contour file to write, such as bunny.txt";
        super::preflight::writable_file(&a.out, what, a.timings.as_deref(), &[&a.mesh])
    })?;
    stages.time(Stage::Slice, || {
        on_root(comm, || {
            let set = points::read_mesh(&a.mesh)?;
            if let Some(note) = &set.note {
                crate::note!("volspline slice: {}: {note}", a.mesh.display());
            }
            let read = TriMesh {
                vertices: set.points.clone(),
                triangles: set.triangles.iter().map(|t| [t[0] as u32, t[1] as u32, t[2] as u32]).collect(),
            };
            let (mesh, indexing) = indexed(&read);
            let (sections, mut s) = slice_mesh(&mesh, &a.planes.planes(&mesh.vertices));
            s.indexing = indexing;
            if sections.len() < 2 {
                let flat = if s.flat > 0 {
                    format!(" ({} contours without area left out)", s.flat)
                } else {
                    String::new()
                };
                return Err(Error::input(
                    &a.mesh,
                    "",
                    format!(
                        "only {} of the {} planes {} meet the mesh in contours with area{flat}; at least two \
                         slices are needed{}",
                        sections.len(),
                        s.planes,
                        a.planes,
                        flat_hint(&mesh.vertices)
                    ),
                ));
            }
            let header = format!(
                "volspline contours from {} cut by planes {}\n{} slices, {} contours, {} points",
                a.mesh.display(),
                a.planes,
                s.slices,
                s.contours,
                s.points
            );
            io::write_atomically(&a.out, |tmp| {
                std::fs::write(tmp, format::to_text(&sections, &header)).map_err(|e| Error::io(&a.out, &e))
            })?;
            summary = Some(s);
            Ok(())
        })
    })?;
    let s: SliceSummary = comm.broadcast_value(0, summary);
    let mut r = Report::new("slice", &a.mesh);
    r.line(format!(
        "planes {}: {} planes, {} slices meet the mesh: {} contours, {} points",
        a.planes, s.planes, s.slices, s.contours, s.points
    ));
    let ix = s.indexing;
    if ix.joined_vertices + ix.repeated_faces + ix.collapsed_faces > 0 {
        r.line(format!(
            "the mesh as cut: {} vertices at the coordinates of an earlier one joined with it, {} faces over the \
             vertices of an earlier face (a double-sided surface) and {} faces without three distinct vertices \
             left out",
            ix.joined_vertices, ix.repeated_faces, ix.collapsed_faces
        ));
    }
    if s.joined > 0 {
        r.line(format!(
            "{} chains ended on holes of the mesh and were closed by joining each end to the nearest free end",
            s.joined
        ));
    }
    if s.merged > 0 {
        r.line(format!(
            "{} cuts lay within {} % of an edge's length of the cut before them (a plane passing next to \
             a vertex, or across a sliver triangle) and were merged with it",
            s.merged,
            crate::mesh::NEAR_CUT * 100.0
        ));
    }
    if s.flat > 0 {
        r.line(format!(
            "{} contours without area (their points on one line: a sheet of the mesh with no volume, or a face \
             in the plane) were left out",
            s.flat
        ));
    }
    if s.gaps > 0 && comm.rank() == 0 {
        crate::note!(
            "volspline: warning: {}: {} of the planes between the first and the last slice meet no mesh (the \
             first is plane {} of {}): the mesh has parts apart along the planes, and `volspline contours` \
             joins the slices on either side of such a gap into one solid; cut each part by planes of its own",
            a.out.display(),
            s.gaps,
            s.first_gap,
            s.planes
        );
    }
    if s.crossings > 0 && comm.rank() == 0 {
        crate::note!(
            "volspline: warning: {}: the contours cross {} time(s), where the mesh intersects itself (or \
             where chains ending on its holes could not be joined without crossing); `volspline \
             contours` names the places",
            a.out.display(),
            s.crossings
        );
    }
    r.figure("planes", s.planes);
    r.figure("slices", s.slices);
    r.figure("contours", s.contours);
    r.figure("points", s.points);
    r.figure("joined_vertices", ix.joined_vertices);
    r.figure("repeated_faces", ix.repeated_faces);
    r.figure("collapsed_faces", ix.collapsed_faces);
    r.figure("joined_chains", s.joined);
    r.figure("merged_cuts", s.merged);
    r.figure("contour_crossings", s.crossings);
    r.figure("flat_contours", s.flat);
    r.figure("planes_between_missing_the_mesh", s.gaps);
    r.output(&a.out);
    r.finish(comm, &stages, &|_| Vec::new(), a.timings.as_deref())?;
    Ok(())
}
