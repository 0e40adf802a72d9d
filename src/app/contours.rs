//! `volspline contours`: planar cross-sections -> the solid. Rank 0 reads the contour file and
//! every rank parses its text; the slices' systems are independent, so slice i is solved by rank
//! i mod P (a rank's slices side by side on its threads, each on one) and broadcast by its owner
//! (every rank then holds every section bit for bit the same whatever P and the threads are);
//! rank 0 writes the model; the volume outputs follow.

use std::path::Path;

use rayon::prelude::*;

use super::preflight::{check_prefix, MODEL_OUTPUTS};
use super::render::{preview_view, write_picture};
use super::report::{run_provenance, Report};
use super::stages::{Stage, Stages};
use super::volume::{check_grid, output_path, write_volume, Volume};
use crate::cli::ContoursArgs;
use crate::contour::crossing;
use crate::contour::format::{self, Section};
use crate::contour::planes::diagonal_2d;
use crate::contour::{fit_section, ContourModel, SectionCarrier, SectionFit, SectionModel};
use crate::error::{Error, Result};
use crate::frep::raycast::Colouring;
use crate::frep::Implicit;
use crate::grid::{padded_box, Grid};
use crate::io::{self, contour_model_file};
use crate::par::{agree, on_root, Comm};
use crate::spline::hygiene::bounding_box;
use crate::spline::{Kernel, Provenance};

/// Reads the contour file on rank 0, gives its text to every rank and parses it everywhere.
fn read_sections_everywhere(comm: &dyn Comm, path: &Path) -> Result<Vec<Section>> {
    let local = if comm.rank() == 0 {
        io::staging::note_input(path);
        io::text::read(path, "contour").map(Some)
    } else {
        Ok(None)
    };
    let mine = agree(comm, local)?;
    let text: String = comm.broadcast_value(0, mine);
    agree(comm, format::parse(path, &text))
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
    // this rank's slices side by side on its threads; the first failure in slice order is the one
    // reported, whatever the threads' order
    let fits: Vec<Result<SectionFit>> = sections
        .par_iter()
        .skip(r)
        .step_by(p)
        .map(|s| {
            fit_section(s, kernel, carrier, merge_tol).map_err(|e| match e {
                Error::Numerical(m) => Error::Numerical(format!("{}: {m}", source.display())),
                other => other,
            })
        })
        .collect();
    let mine: Result<Vec<SectionFit>> = fits.into_iter().collect();
    let mut mine = agree(comm, mine)?.into_iter();
    Ok((0..sections.len())
        .map(|i| {
            let owner = i % p;
            comm.broadcast_value(owner, if owner == r { mine.next() } else { None })
        })
        .collect())
}

/// Refuses the run before any slice is solved when the dense systems a rank solves at once do not
/// fit in its memory: each the matrix of a slice's points and polynomial terms and the copy the
/// LU factors (both f64), for the largest of the rank's slices, as many as it has threads (its
/// slices are solved side by side), beside the program's fixed part. Collective.
fn check_slice_systems(comm: &dyn Comm, sections: &[Section], kernel: &Kernel) -> Result<()> {
    let (p, r) = (comm.size(), comm.rank());
    let mut mine: Vec<&Section> = sections.iter().skip(r).step_by(p).collect();
    mine.sort_by_key(|s| std::cmp::Reverse(s.point_count()));
    mine.truncate(rayon::current_num_threads().max(1));
    let system = |s: &Section| 2.0 * ((s.point_count() + kernel.poly_count()) as f64).powi(2) * 8.0;
    let need = mine.iter().map(|s| system(s)).sum::<f64>() + super::preflight::FIXED_BYTES;
    let Some(largest) = mine.first() else {
        // a rank without slices (more ranks than slices) takes part in the collective check all
        // the same
        return super::preflight::check_memory(comm, need, "the program", "");
    };
    let most = if sections.iter().all(|s| s.point_count() <= largest.point_count()) {
        ", the most of any slice"
    } else {
        ""
    };
    let (what, advice) = if mine.len() == 1 {
        (
            format!(
                "the dense system of the slice of line {} ({} points{most}",
                largest.line,
                largest.point_count()
            ),
            "",
        )
    } else {
        let what = format!(
            "the dense systems of the {} slices this rank solves side by side on its threads (the largest the \
             slice of line {}, {} points{most}",
            mine.len(),
            largest.line,
            largest.point_count()
        );
        (what, ", fewer --threads")
    };
    super::preflight::check_memory(
        comm,
        need,
        &format!("{what})"),
        &format!(
            "thin its contours (every k-th point: the spline through fewer points is smooth) or give the ranks \
             more memory (fewer ranks per node, --memory-per-rank{advice})"
        ),
    )
}

/// The crossings of contours in all slices (each slice's counted up to
/// [`crossing::COUNTED_PER_SLICE`]), and the warning about them naming the first three places,
/// when there are some.
fn contour_crossings(path: &Path, sections: &[Section]) -> (usize, Option<String>) {
    const SHOWN: usize = 3;
    let mut places = Vec::new();
    let (mut total, mut slices) = (0, 0);
    for s in sections {
        let (found, n) = crossing::crossings(s, SHOWN, crossing::COUNTED_PER_SLICE);
        if n == 0 {
            continue;
        }
        total += n;
        slices += 1;
        for c in found.iter().take(SHOWN - places.len().min(SHOWN)) {
            let x = s.world(c.at);
            let what = match c.contours {
                [i, j] if i == j => format!("contour {} crosses itself", i + 1),
                [i, j] => format!("contours {} and {} cross", i.min(j) + 1, i.max(j) + 1),
            };
            places.push(format!(
                "the slice of line {}: {what} at ({:.6e}, {:.6e}, {:.6e})",
                s.line, x.x, x.y, x.z
            ));
        }
    }
    let warning = (total > 0).then(|| {
        let more = if total > places.len() { ", ..." } else { "" };
        format!(
            "{}: contours cross {total} time(s) in {slices} slice(s) ({}{more}; contours numbered from 1 in \
             their slice): near a crossing the section's inside follows no reading of the drawing, and the \
             surface pinches or fills a lobe there; mend the contours",
            path.display(),
            places.join("; ")
        )
    });
    (total, warning)
}

/// The warning about contours whose points all lie within `merge_tol` of their slice's diagonal
/// of each other: merged as duplicates, they become one point, a contour without inside, and the
/// solid has no section there (a tracing at the wrong scale, or a stray click). Names the first
/// three by slice line and number.
fn collapsed_contours(path: &Path, sections: &[Section], merge_tol: f64) -> Option<String> {
    let mut found = Vec::new();
    for s in sections {
        let diag = diagonal_2d(&s.contours.concat());
        for (k, c) in s.contours.iter().enumerate() {
            if diagonal_2d(c) <= merge_tol * diag {
                found.push(format!("contour {} of the slice of line {}", k + 1, s.line));
            }
        }
    }
    (!found.is_empty()).then(|| {
        let more = if found.len() > 3 { ", ..." } else { "" };
        format!(
            "{}: {} contour(s) span no more than --merge-tol {merge_tol:e} of their slice's diagonal ({}{more}): \
             their points merge into one, so the solid has no section there; check their scale, or remove them",
            path.display(),
            found.len(),
            found[..found.len().min(3)].join("; ")
        )
    })
}

/// Runs `volspline contours`. Collective.
pub fn run(a: &ContoursArgs, comm: &dyn Comm, threads: usize) -> Result<()> {
    let mut stages = Stages::default();
    check_prefix(comm, &a.out, MODEL_OUTPUTS, a.grid.timings.as_deref(), &[&a.input])?;
    let sections = stages.time(Stage::Read, || read_sections_everywhere(comm, &a.input))?;
    let points_read: usize = sections.iter().map(Section::point_count).sum();
    let contours: usize = sections.iter().map(|s| s.contours.len()).sum();
    let world: Vec<f64> = sections
        .iter()
        .flat_map(|s| s.contours.iter().flatten().flat_map(move |p| s.world(*p).to_array()))
        .collect();
    let (lo, hi) = bounding_box(&world, 3);
    let (plo, phi) = padded_box(&lo, &hi, a.grid.margin.fraction);
    let grid = Grid::covering(plo, phi, a.grid.grid)?;
    check_grid(comm, &grid, a.grid.curvature)?;
    check_slice_systems(comm, &sections, &a.kernel)?;
    if comm.rank() == 0 {
        crate::note!(
            "volspline contours: {} slices, {contours} contours, {points_read} points from {}; kernel {}, carrier {}",
            sections.len(),
            a.input.display(),
            a.kernel.name(),
            a.carrier.name()
        );
    }
    let (crossings, warning) = contour_crossings(&a.input, &sections);
    if let (0, Some(w)) = (comm.rank(), warning) {
        crate::note!("volspline: warning: {w}");
    }
    if let (0, Some(w)) = (comm.rank(), collapsed_contours(&a.input, &sections, a.merge_tol)) {
        crate::note!("volspline: warning: {w}");
    }
    let fits = stages.time(Stage::Solve, || {
        solve_sections(comm, &a.input, &sections, &a.kernel, a.carrier, a.merge_tol)
    })?;
    let lines: Vec<usize> = sections.iter().map(|s| s.line).collect();
    super::finite::check_sections(&a.input, &lines, &fits, &lo, &hi)?;
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
        input: a.input.display().to_string(),
        box_lo: [lo[0], lo[1], lo[2]],
        box_hi: [hi[0], hi[1], hi[2]],
        points_read,
        duplicates_merged: merged,
        solver: "lu (serial, per slice)".into(),
        residual: max_residual,
        ..run_provenance(comm, threads, &stages)
    };
    let model = ContourModel::new(models, a.interp, a.orient, provenance);
    super::finite::check_grid_field(comm, &model, &grid)?;
    let model_path = output_path(&a.out, ".model.h5");
    stages.time(Stage::Write, || {
        on_root(comm, || {
            io::write_atomically(&model_path, |tmp| contour_model_file::write_contour_model(tmp, &model))
        })
    })?;
    let curvature = a.grid.curvature.then_some(&model as &dyn Implicit);
    let job = Volume::new(&model, grid, &a.out).curvature(curvature).grow(a.grid.may_grow());
    let volume = write_volume(comm, job, &mut stages)?;
    let preview = output_path(&a.out, ".png");
    if !a.no_preview {
        write_picture(comm, &model, &preview_view(), Colouring::Shading, &preview, &mut stages)?;
    }

    let mut r = Report::new("contours", &a.input);
    r.line(format!(
        "{} slices, {contours} contours, N = {points_used} points ({points_read} read, {merged} duplicates merged), kernel {}, carrier {}",
        sections.len(),
        a.kernel.name(),
        a.carrier.name()
    ));
    r.line(format!("interp {}, orient {}", a.interp.name(), a.orient.name()));
    r.line(format!(
        "ranks = {}, threads per rank = {threads} (slice i solved on rank i mod ranks)",
        comm.size()
    ));
    r.line(format!("largest relative residual of the slice systems = {max_residual:.3e}"));
    r.line(format!("max |F_i| at the slices' points              = {max_abs:.3e}"));
    r.figure("input", a.input.display());
    r.figure("slices", sections.len());
    r.figure("contours", contours);
    r.figure("points", points_used);
    r.figure("kernel", a.kernel.name());
    r.figure("interp", a.interp.name());
    r.figure("orient", a.orient.name());
    r.figure("ranks", comm.size());
    r.figure("threads", threads);
    r.figure("residual", format!("{max_residual:e}"));
    r.figure("contour_crossings", crossings);
    r.output(&model_path);
    volume.report(&mut r);
    if !a.no_preview {
        r.output(&preview);
    }
    r.finish(comm, &stages, &|_| Vec::new(), a.grid.timings.as_deref())?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn contours_that_merge_into_one_point_are_named() {
        let square = |c: f64, h: f64| vec![[c, c], [c + h, c], [c + h, c + h], [c, c + h]];
        let section = |line: usize, contours: Vec<Vec<[f64; 2]>>| Section {
            line,
            origin: glam::DVec3::new(0.0, 0.0, line as f64),
            frame: glam::DMat3::IDENTITY,
            kind: "z",
            contours,
        };
        let sections =
            [section(1, vec![square(0.0, 1.0)]), section(7, vec![square(0.0, 1.0), square(0.5, 1e-9)])];
        let w = collapsed_contours(Path::new("c.txt"), &sections, 1e-6).unwrap();
        assert!(w.starts_with("c.txt: 1 contour(s) span no more than --merge-tol 1e-6"), "{w}");
        assert!(w.contains("(contour 2 of the slice of line 7)"), "{w}");
        assert!(collapsed_contours(Path::new("c.txt"), &sections, 1e-10).is_none());
    }
}
