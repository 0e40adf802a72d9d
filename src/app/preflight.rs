//! Checks made before any heavy work, so that a run that cannot finish says so within a second
//! instead of after the solve: the output prefix names a writable place, no output (nor the
//! `--timings` file) would replace the input or another output, and the memory a rank will need
//! (the dense system's rows, the solver's panels, the grid slab) fits in what this rank can have.
//!
//! What a rank can have is the smallest of the node's available memory (`MemAvailable`) and the
//! cgroup limit of the job (v2 `memory.max`, v1 `memory.limit_in_bytes`), shared equally by the
//! ranks on the node (`OMPI_COMM_WORLD_LOCAL_SIZE` and its equivalents), the address-space limit
//! of the process (`RLIMIT_AS`: `ulimit -v`, SGE's `h_vmem`, some Slurm setups), and the limit
//! the user set (`--memory-per-rank`, [`limit_memory`]). The system's figures are read at the
//! moment of the check, so they already leave out what the rank holds by then; the user's limit
//! is on everything the rank holds, so a check made while the rank holds something
//! ([`check_memory_beside`]) compares with the limit less that.
//!
//! The address-space limit is on virtual memory, which is larger than the resident memory the
//! estimates count: the binary, MPI (its shared-memory segments among them), HDF5, the C
//! library's allocator arenas and the threads' stacks are mapped before any work, some 300-1000
//! MB a rank with Open MPI. So the limit counts like the user's, on everything the rank holds,
//! less the address space the rank had mapped at its start ([`note_start`], `VmSize` of
//! `/proc/self/status`). A rank over that limit would not be refused: its allocation would fail,
//! which aborts the process without removing its temporary files. So a run whose address-space
//! limit leaves less than the program's fixed part ([`FIXED_BYTES`]) is refused at the start
//! ([`check_address_space`]), before the first stages (reading, orienting the normals) allocate.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::OnceLock;

use crate::cli::ranks_on_this_node;
use crate::error::{Error, Result};
use crate::grid::Grid;
use crate::io::staging::{is_special, output_target, parent_dir, same_file};
use crate::linalg::dist::{Precision, KEPT_SHARE};
use crate::par::{agree, Comm};

/// Memory a dense fit of a system of `system` rows needs on each of `ranks` ranks, in bytes, with
/// panels `panel` wide: its rows of the matrix ([`dense_matrix_bytes`]), the panels the
/// factorisations gather ([`panel_bytes`]) and the program's fixed part ([`FIXED_BYTES`]).
pub fn dense_fit_bytes(system: usize, ranks: usize, precision: Precision, lower: bool, panel: usize) -> f64 {
    dense_matrix_bytes(system, ranks, precision, lower) + panel_bytes(system, ranks, panel) + FIXED_BYTES
}

/// A rank's rows of a dense system of `system` rows with the right-hand side, in bytes. In mixed
/// precision the f64 rows stay for the residuals of the refinement while an f32 copy is
/// factored: 12 bytes an entry instead of 8. With `lower` (the projected Cholesky, which reads
/// and writes the lower triangle alone) half the entries are touched, and a page of each column
/// of each copy for its first rows; but the whole matrix is allocated, so under an address-space
/// limit ([`address_space_limit`]), which counts the pages never touched as well, all of it.
pub fn dense_matrix_bytes(system: usize, ranks: usize, precision: Precision, lower: bool) -> f64 {
    let lower = lower && address_space_limit().is_none();
    let rows = system.div_ceil(ranks.max(1)) as f64;
    let cols = (system + 1) as f64;
    let (bytes, copies) = match precision {
        Precision::F64 => (8.0, 1.0),
        Precision::Mixed => (12.0, 2.0),
    };
    let whole = rows * cols * bytes;
    if lower {
        // where a column is shorter than a page, its neighbours share the pages: all are touched
        whole.min(whole / 2.0 + cols * PAGE * copies)
    } else {
        whole
    }
}

/// The buffers of a dense factorisation with panels `panel` wide on a system of `system` rows,
/// per rank, in bytes: every rank receives each panel's block across all columns (the LU's block
/// row, the Cholesky's L21, the Householder's W), the current one and, with look-ahead, the next,
/// plus its own rows' part of a panel (the reflectors, Y = V T^T, the send buffers). Measured at
/// 8004 rows, panels 128 and 768 wide, the three solvers on 1, 2 and 3 ranks row-cyclic and on
/// 1x2 and 2x1 grids: the peak grew by 2.4-4.9 times (panel x rows x 8 bytes) from the narrow
/// panel to the wide one, falling with the ranks towards about 2.3 for the part every rank holds
/// whole. So the estimate takes 2.5 panels of every row and 3 of the rank's share: on a large
/// job this is most of a rank's memory (at 100,000 rows on 1,024 ranks a panel of 384 is 770 MB
/// a rank beside 78 MB of matrix rows), which the 2D layout's blocks would cut.
pub fn panel_bytes(system: usize, ranks: usize, panel: usize) -> f64 {
    let n = system as f64;
    panel as f64 * 8.0 * (2.5 * n + 3.0 * n / ranks.max(1) as f64)
}

/// The fixed part of a rank's memory in the estimates: libraries, MPI's and HDF5's buffers. At
/// 8004 rows on 1-3 ranks over Open MPI's shared memory the peaks less the matrix rows and the
/// panels' buffers were 15-45 MB; an MPI over a cluster's network keeps buffers per peer.
pub const FIXED_BYTES: f64 = 200e6;

/// The page size the estimates assume.
const PAGE: f64 = 4096.0;

/// Memory per rank that bordering a kept factor of `n` centres by `m` more takes on top of it
/// (border `k`): five blocks of this rank's rows by m columns at the peak (the cross block, it
/// projected, its substitution through the factor, that times the border's new basis, the
/// bordered rows), the substitutions the factor keeps for later extensions ([`KEPT_SHARE`] n
/// columns of its rows; what it keeps beyond that lives in the room this leaves, see
/// [`crate::linalg::dist::Factored::limit_extras`]) and a few (k + m) x (k + m) matrices on
/// every rank.
pub fn bordered_fit_bytes(n: usize, m: usize, k: usize, ranks: usize) -> f64 {
    let rows = n.div_ceil(ranks.max(1)) as f64;
    let w = (k + m) as f64;
    1.15 * 8.0 * (rows * (5.0 * (m + 1) as f64 + KEPT_SHARE * n as f64) + 5.0 * w * w)
}

/// Memory the volume outputs need on the rank with the thickest slab of `grid`: its values with
/// a ghost layer, and about as much again for the marching-cubes piece and the welding of the
/// mesh; with `curvature`, the mean and Gaussian curvature at every node of the slab too.
pub fn grid_bytes(grid: &Grid, ranks: usize, curvature: bool) -> f64 {
    let [nx, ny, nz] = grid.dims;
    let layers = nz.div_ceil(ranks.max(1)) + 1;
    let arrays = if curvature { 4.0 } else { 2.0 };
    arrays * (nx * ny * layers) as f64 * 8.0
}

/// The user's limit on the memory of each rank, in bytes (`--memory-per-rank`).
static LIMIT: OnceLock<f64> = OnceLock::new();

/// Caps what every later check lets a rank have at `bytes` (the first call holds). Called once,
/// by the binary, from the command line; the library alone has no limit but the system's.
pub fn limit_memory(bytes: f64) {
    let _ = LIMIT.set(bytes);
}

/// The largest count in `lo..=hi` whose need fits (`fits` is true up to some count and false
/// beyond it, and true at `lo`), by bisection.
pub fn largest_fitting(lo: usize, hi: usize, fits: impl Fn(usize) -> bool) -> usize {
    if fits(hi) {
        return hi;
    }
    // fits(lo), not fits(hi)
    let (mut lo, mut hi) = (lo, hi);
    while hi - lo > 1 {
        let mid = lo + (hi - lo) / 2;
        if fits(mid) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    lo
}

/// The user's limit on each rank's memory (`--memory-per-rank`), if one was set.
pub fn user_limit() -> Option<f64> {
    LIMIT.get().copied()
}

/// Bytes this rank can take on top of the `held` bytes it holds now, and where the figure comes
/// from, when the system or the user says: the smallest of the system's figure now, the user's
/// limit less `held` and the address-space limit ([`address_space_limit`]) less `held`, the
/// address space mapped at the start ([`note_start`]) and the libraries' later mappings
/// ([`late_mappings`]). None where the fault-injection tests turned the checks off
/// (`VOLSPLINE_TEST_SKIP_MEMORY_CHECKS`).
pub fn available_beside(held: f64) -> Option<(f64, String)> {
    if checks_skipped() {
        return None;
    }
    let capped = LIMIT.get().map(|&limit| ((limit - held).max(0.0), "--memory-per-rank".to_string()));
    [system_per_rank(), capped, address_space_beside(held)].into_iter().flatten().reduce(|least, next| {
        if next.0 < least.0 {
            next
        } else {
            least
        }
    })
}

/// Whether the fault-injection tests turned the memory checks off
/// (`VOLSPLINE_TEST_SKIP_MEMORY_CHECKS`), to reach an allocation the system refuses: every check
/// then passes, as where the system gives no figure.
fn checks_skipped() -> bool {
    std::env::var_os("VOLSPLINE_TEST_SKIP_MEMORY_CHECKS").is_some()
}

/// The address space this rank had mapped at its start, in bytes (`VmSize`), as first read.
static START_MAPPED: OnceLock<Option<f64>> = OnceLock::new();

/// Reads the address space this rank has mapped now as the baseline of the address-space limit,
/// unless it was read before, and returns the baseline (None where `/proc/self/status` does not
/// say). The binary calls it once MPI and the thread pool have started, before any work; without
/// that call the first check reads it.
pub fn note_start() -> Option<f64> {
    *START_MAPPED.get_or_init(mapped_now)
}

/// The address space this process has mapped now, in bytes (`VmSize` of `/proc/self/status`).
pub fn mapped_now() -> Option<f64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmSize:"))?;
    Some(line.split_whitespace().nth(1)?.parse::<f64>().ok()? * 1024.0)
}

/// The soft address-space limit of this process (`RLIMIT_AS`), in bytes, where there is one.
pub fn address_space_limit() -> Option<f64> {
    // SAFETY: getrlimit fills the zeroed struct it is given
    let mut lim: libc::rlimit = unsafe { std::mem::zeroed() };
    if unsafe { libc::getrlimit(libc::RLIMIT_AS, &mut lim) } != 0 || lim.rlim_cur == libc::RLIM_INFINITY {
        return None;
    }
    Some(lim.rlim_cur as f64)
}

/// Address space the libraries map after the start for buffers of their own, beside the resident
/// memory the estimates count: OpenBLAS's buffer (128 MB, on its first product) and the matrix
/// kernels' scratch of each thread (64 MB, faer's `private-gemm`), mostly never touched. Measured
/// with `ulimit -v` on the bunny and the cow, 1 and 2 ranks: without it, runs that the checks let
/// through failed an allocation in the orientation of the normals or the solve (and OpenBLAS,
/// whose buffer could not be allocated, retried for ever); with it, every limit from 750 to 1300
/// MB (in steps of 50) either ran or was refused.
pub fn late_mappings(threads: usize) -> f64 {
    128e6 + 64e6 * threads as f64
}

/// Bytes the address-space limit lets this rank take on top of the `held` bytes it holds now, and
/// where the figure comes from, where there is a limit: the limit less the address space mapped
/// at the start ([`note_start`]), the libraries' later mappings ([`late_mappings`]) and `held`.
fn address_space_beside(held: f64) -> Option<(f64, String)> {
    let limit = address_space_limit()?;
    let start = note_start().unwrap_or(0.0);
    let late = late_mappings(rayon::current_num_threads());
    Some((
        (limit - start - late - held).max(0.0),
        format!(
            "the address-space limit (ulimit -v) of {}, less the {} the rank had mapped at its start and {} \
             the libraries map later",
            gigabytes(limit),
            gigabytes(start),
            gigabytes(late)
        ),
    ))
}

/// Refuses a run whose address-space limit (`ulimit -v`) leaves a rank less than the program's
/// fixed part ([`FIXED_BYTES`]) beside what it had mapped at its start: the allocations of the
/// first stages, made before the work's own checks, would fail and abort the rank. The user's
/// limit (`--memory-per-rank`), on which nothing fails, is left to the work's checks, which name
/// the part of the work that does not fit. Collective.
pub fn check_address_space(comm: &dyn Comm) -> Result<()> {
    let local = match address_space_beside(0.0).filter(|_| !checks_skipped()) {
        Some((have, source)) if have < FIXED_BYTES => Err(Error::Memory(format!(
            "the program's fixed part (libraries, MPI's and HDF5's buffers) needs about {} per rank, but this \
             rank can have {} ({source}); {}",
            gigabytes(FIXED_BYTES),
            gigabytes(have),
            below_fixed_advice()
        ))),
        _ => Ok(()),
    };
    agree(comm, local)
}

/// The advice of a refusal whose limit is below the program's fixed part: fewer points, a coarser
/// grid or more ranks do not make a rank need less than that.
fn below_fixed_advice() -> String {
    format!(
        "the limit leaves a rank less than the {} it needs for the program's fixed part whatever the work \
         (libraries, MPI's and HDF5's buffers), so fewer points or more ranks cannot help: give each rank more \
         (a larger --memory-per-rank or ulimit -v, fewer ranks per node)",
        gigabytes(FIXED_BYTES)
    )
}

/// Bytes this rank can use by the system's figures, and where they come from, when it says.
fn system_per_rank() -> Option<(f64, String)> {
    let meminfo = std::fs::read_to_string("/proc/meminfo").ok();
    let avail = meminfo.as_deref().and_then(|m| {
        let line = m.lines().find(|l| l.starts_with("MemAvailable:"))?;
        Some(line.split_whitespace().nth(1)?.parse::<f64>().ok()? * 1024.0)
    });
    let cgroup = ["/sys/fs/cgroup/memory.max", "/sys/fs/cgroup/memory/memory.limit_in_bytes"]
        .iter()
        .find_map(|p| std::fs::read_to_string(p).ok()?.trim().parse::<f64>().ok())
        .filter(|&b| b < 1e18);
    let (bytes, source) = match (avail, cgroup) {
        (Some(a), Some(c)) if c < a => (c, "the job's cgroup limit"),
        (Some(a), _) => (a, "the node's available memory"),
        (None, Some(c)) => (c, "the job's cgroup limit"),
        (None, None) => return None,
    };
    let local = ranks_on_this_node();
    Some((bytes / local as f64, format!("{source} shared by {local} rank(s) on the node")))
}

/// Refuses the run when a rank would need more than it can have. `what` names the need, `advice`
/// says what to change. Collective: every rank checks its own node and all agree.
pub fn check_memory(comm: &dyn Comm, need: f64, what: &str, advice: &str) -> Result<()> {
    check_memory_beside(comm, 0.0, need, what, advice)
}

/// The largest need (with what was held beside it) any check of this process counted, as the
/// bits of an f64 (positive, so their order is the numbers' order).
static LARGEST_NEED: AtomicU64 = AtomicU64::new(0);

/// The most memory per rank any check of this run counted (None before the first check), for
/// the report beside the measured peak.
pub fn largest_need() -> Option<f64> {
    let bits = LARGEST_NEED.load(Ordering::Relaxed);
    (bits > 0).then(|| f64::from_bits(bits))
}

/// [`check_memory`] of a `need` on top of `held` bytes the rank holds now (a kept factor).
/// Collective.
pub fn check_memory_beside(comm: &dyn Comm, held: f64, need: f64, what: &str, advice: &str) -> Result<()> {
    if (held + need).is_finite() && held + need > 0.0 {
        LARGEST_NEED.fetch_max((held + need).to_bits(), Ordering::Relaxed);
    }
    let local = match available_beside(held) {
        Some((have, source)) if need > have => {
            // no advice on the work helps where the whole limit is below the fixed part
            let advice = if need >= FIXED_BYTES && have + held < FIXED_BYTES {
                below_fixed_advice()
            } else {
                advice.to_string()
            };
            let beside =
                if held > 0.0 { format!(" beside the {} it holds", gigabytes(held)) } else { String::new() };
            // figures that would print alike are printed to more digits, which tell them apart
            let (mut n, mut h) = (gigabytes(need), gigabytes(have));
            if n == h {
                (n, h) = (format!("{:.3} MB", need / 1e6), format!("{:.3} MB", have / 1e6));
            }
            Err(Error::Memory(format!(
                "{what} needs about {n} per rank, but this rank can have {h}{beside} ({source}); {advice}"
            )))
        }
        _ => Ok(()),
    };
    agree(comm, local)
}

fn gigabytes(bytes: f64) -> String {
    if bytes >= 1e9 {
        format!("{:.1} GB", bytes / 1e9)
    } else {
        format!("{:.0} MB", bytes / 1e6)
    }
}

/// Checks on rank 0 that outputs can be written under `prefix` (its directory exists and takes a
/// new file, and the prefix has a file name), that none of them is one of the `inputs`, and that
/// the `--timings` file is neither one of the prefix's outputs nor an input; agrees on the
/// outcome. Collective.
pub fn check_prefix(
    comm: &dyn Comm,
    prefix: &Path,
    writes: &[&str],
    timings: Option<&Path>,
    inputs: &[&Path],
) -> Result<()> {
    check_prefixes(comm, prefix, writes, &[], timings, inputs)
}

/// [`check_prefix`] for a command that also writes under the prefixes `more` in the directory of
/// `prefix` (the frames of `morph`): the `--timings` file may name none of their outputs either,
/// so such a clash is refused before any work instead of at the commit. Collective.
pub fn check_prefixes(
    comm: &dyn Comm,
    prefix: &Path,
    writes: &[&str],
    more: &[PathBuf],
    timings: Option<&Path>,
    inputs: &[&Path],
) -> Result<()> {
    let local = if comm.rank() == 0 {
        let mut all = std::iter::once(prefix).chain(more.iter().map(PathBuf::as_path));
        let timings_apart = |t: &Path| all.try_for_each(|p| separate_timings(t, p, writes, inputs));
        let spared = |p: &Path| inputs.iter().try_for_each(|i| spares_input(p, writes, i));
        writable_prefix(prefix)
            .and_then(|()| {
                // the last of `more` has the longest names (the frames' numbers widen)
                std::iter::once(prefix)
                    .chain(more.last().map(PathBuf::as_path))
                    .try_for_each(|p| prefix_outputs(p, writes).try_for_each(|o| temporary_name_fits(&o)))
            })
            .and_then(|()| {
                std::iter::once(prefix).chain(more.iter().map(PathBuf::as_path)).try_for_each(spared)
            })
            .and_then(|()| timings.map_or(Ok(()), timings_apart))
    } else {
        Ok(())
    };
    agree(comm, local)
}

/// The names `fit` and `contours` may write under their prefix.
pub const MODEL_OUTPUTS: &[&str] = &[".model.h5", ".hdf", ".ply", ".png", ".trimmed.ply"];

/// The names `eval` writes under its prefix and `morph` under each frame's.
pub const VOLUME_OUTPUTS: &[&str] = &[".hdf", ".ply", ".trimmed.ply"];

/// The name `morph` writes under its prefix: the time series of the frames.
pub const SERIES_OUTPUT: &[&str] = &[".hdf.series"];

/// The outputs under `prefix` by the names in `writes`.
fn prefix_outputs<'a>(prefix: &'a Path, writes: &'a [&str]) -> impl Iterator<Item = PathBuf> + 'a {
    writes.iter().map(move |ext| {
        let mut name = prefix.as_os_str().to_owned();
        name.push(ext);
        PathBuf::from(name)
    })
}

/// Refuses an output whose temporary name (`.NAME.RUNID.partial`, some 30 characters longer than
/// its name) is too long for its directory's file system, before any work: a prefix of 220
/// characters or more failed at the first write, after the solve, with 'File name too long'.
/// Probed by creating that file and removing it at once.
fn temporary_name_fits(output: &Path) -> Result<()> {
    let tmp = crate::io::staging::temp_path(&output_target(output));
    match std::fs::OpenOptions::new().write(true).create_new(true).open(&tmp) {
        Ok(_) => {
            let _ = std::fs::remove_file(&tmp);
            Ok(())
        }
        Err(e) if e.raw_os_error() == Some(libc::ENAMETOOLONG) => Err(Error::Usage(format!(
            "--out: the output {} has a name too long for its temporary file {} ({} bytes); choose a shorter prefix",
            output.display(),
            tmp.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default(),
            tmp.file_name().map_or(0, |n| n.len())
        ))),
        // other failures (the directory's own) are the directory check's to name
        Err(_) => Ok(()),
    }
}

/// Refuses a prefix one of whose outputs is the input (`fit scan.ply --out scan`).
fn spares_input(prefix: &Path, writes: &[&str], input: &Path) -> Result<()> {
    match prefix_outputs(prefix, writes).find(|o| same_file(o, input)) {
        Some(o) => Err(Error::Usage(format!(
            "--out {}: the output {} would replace the input {}; choose another prefix",
            prefix.display(),
            o.display(),
            input.display()
        ))),
        None => Ok(()),
    }
}

fn separate_timings(timings: &Path, prefix: &Path, writes: &[&str], inputs: &[&Path]) -> Result<()> {
    let clash = |what: String| {
        Err(Error::Usage(format!("--timings {}: names {what}; give it a name of its own", timings.display())))
    };
    if timings.is_dir() {
        return clash("a directory".into());
    }
    let dir = parent_dir(timings);
    if !dir.is_dir() {
        let why =
            std::io::Error::new(std::io::ErrorKind::NotFound, "the directory of --timings does not exist");
        return Err(Error::io(dir, &why));
    }
    if let Some(input) = inputs.iter().find(|i| same_file(timings, i)) {
        return clash(format!("the input file {}", input.display()));
    }
    match prefix_outputs(prefix, writes).find(|o| same_file(timings, o)) {
        Some(o) => clash(format!("the output {}", o.display())),
        None => timings_dir_takes_files(timings),
    }
}

/// Refuses a `--timings` file whose directory takes no new file (a read-only file system, say),
/// before any work: the file is written last, and the whole run's outputs would be lost with it.
/// A special target (`/dev/stdout`, a pipe) is written directly, without a file of its own in
/// the directory, and is not probed.
fn timings_dir_takes_files(timings: &Path) -> Result<()> {
    if is_special(&output_target(timings)) {
        return Ok(());
    }
    writable_dir(&parent_dir(timings)).map_err(|e| match e {
        Error::Io { path, reason } => {
            Error::Io { path, reason: format!("{reason} (for --timings {})", timings.display()) }
        }
        e => e,
    })
}

/// Refuses an output file path (`what` it should name, for the message) that is a directory or
/// ends in a separator, lies in a directory that does not exist or cannot be written, or is also
/// the `--timings` file or one of the `inputs` (which the `--timings` file may not name either).
/// Rank 0's check; callers agree on it.
pub fn writable_file(path: &Path, what: &str, timings: Option<&Path>, inputs: &[&Path]) -> Result<()> {
    let text = path.to_string_lossy();
    if text.is_empty() || text.ends_with('/') || path.is_dir() {
        return Err(Error::Usage(format!("--out {text}: expected the name of {what}, not a directory")));
    }
    if timings.is_some_and(|t| t == path || same_file(t, path)) {
        return Err(Error::Usage(format!(
            "--timings {text}: names the output file; give it a name of its own"
        )));
    }
    if let Some(input) = inputs.iter().find(|i| same_file(path, i)) {
        return Err(Error::Usage(format!(
            "--out {text}: the output would replace the input {}; choose another name",
            input.display()
        )));
    }
    if let Some(t) = timings {
        if let Some(input) = inputs.iter().find(|i| same_file(t, i)) {
            return Err(Error::Usage(format!(
                "--timings {}: names the input file {}; give it a name of its own",
                t.display(),
                input.display()
            )));
        }
        timings_dir_takes_files(t)?;
    }
    writable_dir(&parent_dir(path))
}

/// Refuses an output directory that does not exist or in which no file can be created.
fn writable_dir(dir: &Path) -> Result<()> {
    if dir.exists() && !dir.is_dir() {
        return Err(Error::io(
            dir,
            &std::io::Error::new(
                std::io::ErrorKind::NotADirectory,
                "a file, not a directory, so no output can go in it",
            ),
        ));
    }
    if !dir.is_dir() {
        return Err(Error::io(
            dir,
            &std::io::Error::new(std::io::ErrorKind::NotFound, "the output directory does not exist"),
        ));
    }
    let probe = dir.join(format!(".volspline-probe-{}", std::process::id()));
    std::fs::write(&probe, b"").map_err(|e| Error::Io {
        path: dir.into(),
        reason: format!("cannot create a file in the output directory: {e}"),
    })?;
    let _ = std::fs::remove_file(&probe);
    Ok(())
}

fn writable_prefix(prefix: &Path) -> Result<()> {
    let text = prefix.to_string_lossy();
    if text.is_empty() || text.ends_with('/') || prefix.is_dir() {
        return Err(Error::Usage(format!(
            "--out {text}: expected a file prefix such as results/bunny (outputs are PREFIX.model.h5, PREFIX.hdf, PREFIX.ply), not a directory"
        )));
    }
    writable_dir(&parent_dir(prefix))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid::GridSize;
    use crate::par::Solo;

    #[test]
    fn the_largest_count_that_fits_is_found_by_bisection() {
        // needs growing like the bordering's, m rows times m columns, against a room
        let fits = |room: usize| move |m: usize| m * m <= room;
        assert_eq!(largest_fitting(0, 500, fits(40_000)), 200);
        assert_eq!(largest_fitting(0, 500, fits(39_999)), 199);
        assert_eq!(largest_fitting(0, 500, fits(1_000_000)), 500);
        assert_eq!(largest_fitting(50, 500, fits(2_500)), 50);
        assert_eq!(largest_fitting(7, 7, fits(0)), 7);
    }

    #[test]
    fn estimates_grow_as_the_work_does() {
        let whole = dense_matrix_bytes(8000, 2, Precision::F64, false);
        assert_eq!(whole, 4000.0 * 8001.0 * 8.0);
        let e = dense_fit_bytes(8000, 2, Precision::F64, false, 192);
        assert!((e - (whole + 192.0 * 8.0 * (2.5 * 8000.0 + 1.5 * 8000.0) + 200e6)).abs() < 1.0);
        assert!(dense_fit_bytes(85853, 1, Precision::F64, false, 192) > 5e10);
        // the f32 copy of a mixed-precision solve: half the f64 share again
        let m = dense_matrix_bytes(8000, 2, Precision::Mixed, false);
        assert_eq!(m, 1.5 * whole);
        // the lower triangle alone: half the entries and a page per column (per copy)
        let l = dense_matrix_bytes(8000, 2, Precision::F64, true);
        assert_eq!(l, 4000.0 * 8001.0 * 4.0 + 8001.0 * 4096.0);
        let lm = dense_matrix_bytes(8000, 2, Precision::Mixed, true);
        assert!(lm < m && lm > l);
        // columns shorter than a page share their pages: all of them are touched
        let short = dense_matrix_bytes(100_000, 1024, Precision::F64, true);
        assert_eq!(short, dense_matrix_bytes(100_000, 1024, Precision::F64, false));
        // above the peaks measured at 8004 rows, panels 128 and 768 wide (bytes per rank: solver,
        // ranks, panel, peak)
        let measured = [
            ("cholesky", 1, 768, 532.5e6),
            ("cholesky", 2, 768, 347.4e6),
            ("cholesky", 3, 768, 287.7e6),
            ("cholesky", 2, 128, 216.6e6),
            ("lu", 1, 768, 708.2e6),
            ("lu", 2, 768, 427.5e6),
            ("lu", 3, 128, 229.3e6),
            ("householder", 1, 768, 784.2e6),
            ("householder", 2, 768, 447.1e6),
            ("householder", 3, 768, 384.7e6),
        ];
        for (solver, ranks, panel, peak) in measured {
            let estimate = dense_fit_bytes(8004, ranks, Precision::F64, solver == "cholesky", panel);
            assert!(estimate > peak, "{solver} on {ranks} ranks, panel {panel}: {estimate} <= {peak}");
            // and close to them without the fixed allowance (the panels are not counted twice)
            let bare = estimate - FIXED_BYTES;
            assert!(bare < 1.4 * peak, "{solver} on {ranks} ranks, panel {panel}: {bare} >> {peak}");
        }
        // at scale the panels' buffers, which every rank holds whole, outgrow the matrix rows
        let rows = dense_matrix_bytes(100_000, 1024, Precision::F64, false);
        assert!(panel_bytes(100_000, 1024, 384) > 9.0 * rows);
        let g = Grid::covering([0.0; 3], [1.0; 3], GridSize::Longest(101)).unwrap();
        assert_eq!(grid_bytes(&g, 1, false), 2.0 * (101 * 101 * 102) as f64 * 8.0);
        assert_eq!(grid_bytes(&g, 1, true), 2.0 * grid_bytes(&g, 1, false));
        assert!(grid_bytes(&g, 4, false) < grid_bytes(&g, 1, false) / 3.0);
    }

    #[test]
    fn too_much_is_refused_with_the_figures() {
        let err = check_memory(&Solo, 1e30, "the dense system", "use more ranks").unwrap_err();
        let msg = err.to_string();
        assert!(matches!(err, Error::Memory(_)), "{msg}");
        assert!(msg.contains("the dense system needs about") && msg.contains("use more ranks"), "{msg}");
        assert!(check_memory(&Solo, 1.0, "a byte", "").is_ok());
    }

    #[test]
    fn prefixes_must_name_a_writable_file() {
        let dir = std::env::temp_dir().join(format!("volspline-preflight-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        assert!(check_prefix(&Solo, &dir.join("out"), MODEL_OUTPUTS, None, &[]).is_ok());
        assert!(matches!(check_prefix(&Solo, &dir, MODEL_OUTPUTS, None, &[]).unwrap_err(), Error::Usage(_)));
        let slash = format!("{}/", dir.display());
        assert!(matches!(
            check_prefix(&Solo, Path::new(&slash), MODEL_OUTPUTS, None, &[]).unwrap_err(),
            Error::Usage(_)
        ));
        assert!(matches!(
            check_prefix(&Solo, &dir.join("missing/out"), MODEL_OUTPUTS, None, &[]).unwrap_err(),
            Error::Io { .. }
        ));
        let _ = std::fs::remove_dir_all(&dir);
    }
}
