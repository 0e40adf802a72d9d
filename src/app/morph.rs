//! `volspline morph`: the metamorphosis of solid A into solid B ([`crate::frep::morph`]) as K
//! frames, each a VTKHDF volume and a PLY mesh, and a ParaView file series that lists the volumes
//! with their times, so ParaView opens them as one animated dataset.
//!
//! ParaView's JSON file series is a file named after the files it lists plus `.series`
//! (`PREFIX.hdf.series`: the extension before `.series` picks the reader):
//!
//! ```text
//! {"file-series-version": "1.0", "files": [{"name": "PREFIX_000.hdf", "time": 0.0}, ...]}
//! ```
//!
//! with names relative to the series file's folder. Every output is staged and renamed into place
//! only when all frames succeeded.

use std::path::{Path, PathBuf};

use super::finite::check_grid_field;
use super::preflight::{check_prefixes, SERIES_OUTPUT, VOLUME_OUTPUTS};
use super::report::Report;
use super::stages::{Stage, Stages};
use super::volume::{check_grid, output_path, throughput_line, write_volume, Volume};
use crate::cli::MorphArgs;
use crate::error::{Error, Result};
use crate::frep::expr::{hull, Expr};
use crate::frep::morph::{read_pairs_with_lines, Fold, FoldTally, Morph, SlabCache};
use crate::frep::Implicit;
use crate::grid::{padded_box, Grid};
use crate::io;
use crate::par::{agree, on_root, Comm};

/// The prefix of frame `k`: PREFIX_NNN (three digits at least).
pub fn frame_prefix(prefix: &Path, k: usize) -> PathBuf {
    output_path(prefix, &format!("_{k:03}"))
}

/// The warning about frames of an earlier, longer morph under the same prefix (`PREFIX_NNN.hdf`
/// or `.ply` from frame `k` on): this run lists only its own in the series, but a ParaView pattern
/// open of `PREFIX_*.hdf` would mix them in. They are the user's files and are left alone.
fn stale_frames(prefix: &Path, k: usize) -> Option<String> {
    let exists = |i: usize| {
        ["hdf", "ply"].iter().any(|e| output_path(&frame_prefix(prefix, i), &format!(".{e}")).exists())
    };
    if !exists(k) {
        return None;
    }
    let last = (k..crate::cli::MAX_FRAMES).take_while(|&i| exists(i)).last().unwrap_or(k);
    Some(format!(
        "{} to {} (frames {k} to {last}) remain from an earlier morph with more frames under this prefix; \
         {} lists this run's {k} frames only, but a pattern open of the frames would mix them in: remove them",
        frame_prefix(prefix, k).display(),
        frame_prefix(prefix, last).display(),
        output_path(prefix, ".hdf.series").display()
    ))
}

/// The series file's text for the volumes `names` at `times`.
pub fn series_json(names: &[String], times: &[f64]) -> String {
    let files: Vec<String> = names
        .iter()
        .zip(times)
        .map(|(n, t)| {
            format!("    {{\"name\": \"{}\", \"time\": {t:?}}}", n.replace('\\', "\\\\").replace('"', "\\\""))
        })
        .collect();
    format!("{{\n  \"file-series-version\": \"1.0\",\n  \"files\": [\n{}\n  ]\n}}\n", files.join(",\n"))
}

/// Runs `volspline morph`. Collective.
pub fn run(a: &MorphArgs, comm: &dyn Comm, threads: usize) -> Result<()> {
    let mut stages = Stages::default();
    let frames: Vec<PathBuf> = (0..a.frames).map(|i| frame_prefix(&a.out, i)).collect();
    let mut inputs: Vec<PathBuf> = a.a.models();
    inputs.extend(a.b.models());
    inputs.extend(a.pairs.iter().cloned());
    let inputs: Vec<&Path> = inputs.iter().map(PathBuf::as_path).collect();
    let writes = [VOLUME_OUTPUTS, SERIES_OUTPUT].concat();
    check_prefixes(comm, &a.out, &writes, &frames, a.grid.timings.as_deref(), &inputs)?;
    let subject = format!("{} -> {}", a.a, a.b);
    let mut r = Report::new("morph", Path::new(&subject));
    let (ea, eb) = stages
        .time(Stage::Read, || agree(comm, Expr::load(&a.a).and_then(|x| Ok((x, Expr::load(&a.b)?)))))?;
    let (pairs, lines) = match &a.pairs {
        Some(p) => {
            let (pairs, lines) = stages.time(Stage::Read, || agree(comm, read_pairs_with_lines(p)))?;
            (Some(pairs), lines)
        }
        None => (None, Vec::new()),
    };
    let (lo, hi) = match (a.bounds, ea.domain(), eb.domain()) {
        (Some(b), ..) => b,
        (None, da, db) => match [da, db].into_iter().flatten().reduce(hull) {
            Some((lo, hi)) => padded_box(&lo, &hi, a.grid.margin.fraction),
            None => {
                return Err(Error::Usage(
                    "neither solid has a model or carrier to take a box from: give --bounds".into(),
                ))
            }
        },
    };
    let grid = Grid::covering(lo, hi, a.grid.grid)?;
    check_grid(comm, &grid, a.grid.curvature)?;
    let [nx, ny, nz] = grid.dims;
    if let Some(p) = &pairs {
        // each frame solves the two maps side by side, each a bordered system and its LU
        let n = (p.len() + 4) as f64;
        let maps = 2.0 * 2.0 * n * n * 8.0;
        let fixed = super::preflight::FIXED_BYTES;
        // fewer pairs only help where their systems are a sizeable part of the need
        let advice = if maps > 0.1 * fixed {
            "give fewer pairs or the ranks more memory (fewer ranks per node, --memory-per-rank)"
        } else {
            "give the ranks more memory (fewer ranks per node, --memory-per-rank above the fixed part)"
        };
        super::preflight::check_memory(
            comm,
            maps + fixed,
            &format!(
                "solving the space maps of {} point pairs ({:.1} MB, beside {:.0} MB for the libraries and MPI's \
                 buffers)",
                p.len(),
                maps / 1e6,
                fixed / 1e6
            ),
            advice,
        )?;
    }

    let k = a.frames;
    let times: Vec<f64> = (0..k).map(|i| i as f64 / (k - 1) as f64).collect();
    let mut names = Vec::with_capacity(k);
    let mut per_node = 0;
    let mut triangles = Vec::with_capacity(k);
    let cache = SlabCache::default();
    let (lo, hi) = (grid.origin, grid.node(nx - 1, ny - 1, nz - 1));
    let mut folds = Vec::new();
    for (i, &t) in times.iter().enumerate() {
        // the space maps of the frame (every rank solves the same small systems)
        let frame = stages
            .time(Stage::Solve, || agree(comm, Morph::new(&ea, &eb, t, pairs.as_deref())))?
            .with_cache(&cache);
        if i == 0 {
            check_grid_field(comm, &frame, &grid)?;
        }
        let [fa, fb] = stages.time(Stage::Check, || folds_over(comm, &frame, lo, hi));
        for (solid, fold) in [("A", fa), ("B", fb)] {
            if let Some(fold) = fold {
                folds.push(FrameFold { frame: i, t, solid, fold, pairs: frame.nearest_pairs(fold.worst) });
            }
        }
        let prefix = frame_prefix(&a.out, i);
        // every frame on the same grid, as a time series wants it: no growth
        let curvature = a.grid.curvature.then_some(&frame as &dyn Implicit);
        let v = write_volume(comm, Volume::new(&frame, grid, &prefix).curvature(curvature), &mut stages)?;
        per_node = per_node.max(v.evals_per_node);
        triangles.push(v.triangles);
        let name = v.hdf_path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
        names.push(name);
        r.output(&v.hdf_path);
        r.output(&v.ply_path);
    }
    let series = output_path(&a.out, ".hdf.series");
    let json = series_json(&names, &times);
    on_root(comm, || {
        io::write_atomically(&series, |tmp| std::fs::write(tmp, &json).map_err(|e| Error::io(tmp, &e)))
    })?;
    r.output(&series);

    r.figure("folded_frames", folded_frames(&folds));
    if comm.rank() == 0 {
        if let Some(w) = stale_frames(&a.out, k) {
            crate::note!("volspline: warning: {w}");
        }
        if let Some(w) = fold_warning(&folds, k, &lines) {
            crate::note!(
                "volspline: warning: {}: {w}",
                a.pairs.as_deref().unwrap_or(Path::new("")).display()
            );
        }
    }
    r.line(format!(
        "{k} frames on a {nx} x {ny} x {nz} grid{}; triangles per frame: {:?}",
        if pairs.is_some() { ", controlled by point pairs" } else { "" },
        triangles
    ));
    r.line(format!("ranks = {}, threads per rank = {threads}", comm.size()));
    r.figure("frames", k);
    r.figure("grid_nodes", grid.node_count());
    r.figure("ranks", comm.size());
    r.figure("threads", threads);
    let nodes = grid.node_count() * k;
    r.finish(
        comm,
        &stages,
        &|t| throughput_line(nodes, per_node, t.max(Stage::Evaluate)),
        a.grid.timings.as_deref(),
    )?;
    Ok(())
}

/// The lattice of the folding check: points a side over the grid's box (besides the samples
/// between neighbouring pairs, see [`Morph::folds`]).
const FOLD_LATTICE: usize = 16;

/// A frame's space map that folds space.
struct FrameFold {
    frame: usize,
    t: f64,
    /// "A" or "B": the solid the map looks into.
    solid: &'static str,
    fold: Fold,
    /// The pairs nearest the worst point (indices into the pairs).
    pairs: Vec<usize>,
}

/// The frames in which a space map folds.
/// The frame's folds, the samples dealt over the ranks (sample i on rank i mod P) and the
/// ranks' tallies all-gathered: the same folds on every rank as one rank's whole sampling finds.
/// Collective.
fn folds_over(comm: &dyn Comm, frame: &Morph, lo: [f64; 3], hi: [f64; 3]) -> [Option<Fold>; 2] {
    let Some(mine) = frame.fold_tallies(lo, hi, FOLD_LATTICE, (comm.rank(), comm.size())) else {
        return [None, None];
    };
    let n = 2 * FoldTally::VALUES;
    let send: Vec<f64> = mine.iter().flat_map(|t| t.to_values()).collect();
    let mut all = vec![0.0; n * comm.size()];
    comm.all_gather_f64(&send, &vec![n; comm.size()], &mut all);
    [0, 1].map(|m| {
        let parts: Vec<FoldTally> = all
            .chunks_exact(n)
            .map(|r| FoldTally::from_values(&r[m * FoldTally::VALUES..(m + 1) * FoldTally::VALUES]))
            .collect();
        FoldTally::combine(&parts)
    })
}

fn folded_frames(folds: &[FrameFold]) -> usize {
    let mut frames: Vec<usize> = folds.iter().map(|f| f.frame).collect();
    frames.dedup();
    frames.len()
}

/// The warning about folding space maps, naming the frames and, for the map that folds most, the
/// place and the pairs (by their lines in the pairs file) nearest it; `None` where none folds.
fn fold_warning(folds: &[FrameFold], frames: usize, lines: &[usize]) -> Option<String> {
    let worst = folds.iter().max_by(|a, b| {
        let share = |f: &FrameFold| f.fold.folded as f64 / f.fold.sampled as f64;
        share(a).total_cmp(&share(b)).then(b.fold.det.total_cmp(&a.fold.det))
    })?;
    let mut which: Vec<(usize, f64)> = folds.iter().map(|f| (f.frame, f.t)).collect();
    which.dedup_by_key(|f| f.0);
    let when = match which.as_slice() {
        [(i, t)] => format!("frame {i} (t = {t:.4})"),
        few if few.len() <= 6 => {
            let list: Vec<String> = few.iter().map(|(i, t)| format!("{i} (t = {t:.4})")).collect();
            format!("frames {}", list.join(", "))
        }
        many => {
            let ((i, t), (j, u)) = (many[0], many[many.len() - 1]);
            format!("frames {i} to {j} (t = {t:.4} to {u:.4})")
        }
    };
    let near: Vec<String> =
        worst.pairs.iter().map(|&i| lines.get(i).map_or(i + 1, |l| *l).to_string()).collect();
    let [x, y, z] = worst.fold.worst;
    Some(format!(
        "the space maps fold space in {} of the {frames} frames, {when}: where a map folds, the frame shows \
         the solid's features there mirrored or twice. Most in frame {} (t = {:.4}), whose map into {} folds at \
         {} of the {} points sampled in the grid's box, deepest at ({x:.6e}, {y:.6e}, {z:.6e}) (Jacobian \
         determinant {:.3e}), nearest the pairs on lines {}: pairs close to one another whose features move \
         apart in different directions, or pass across one another, fold space between them; moving or \
         leaving out one of them removes the fold (more frames do not)",
        folded_frames(folds),
        worst.frame,
        worst.t,
        worst.solid,
        worst.fold.folded,
        worst.fold.sampled,
        worst.fold.det,
        near.join(" and "),
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_series_lists_every_frame_with_its_time_as_json() {
        let s = series_json(&["m_000.hdf".into(), "m_001.hdf".into()], &[0.0, 1.0]);
        assert_eq!(
            s,
            "{\n  \"file-series-version\": \"1.0\",\n  \"files\": [\n    {\"name\": \"m_000.hdf\", \"time\": 0.0},\n    \
             {\"name\": \"m_001.hdf\", \"time\": 1.0}\n  ]\n}\n"
        );
        assert_eq!(frame_prefix(Path::new("out/m"), 7), PathBuf::from("out/m_007"));
    }
}
