//! The commands: one file each ([`fit`], [`eval`], [`contours`], [`morph`], [`slice`](mod@slice), [`render`]), the checks
//! made before heavy work ([`preflight`]), the volume outputs they share ([`volume`]), their report
//! ([`report`], [`stages`], [`progress`]) and the encodings of what they send between ranks
//! (`wire`). A command takes its typed arguments from `cli` and a communicator; everything it
//! computes comes from the library rooms below it.

pub mod contours;
pub mod eval;
pub mod finite;
pub mod fit;
pub mod morph;
pub mod preflight;
pub mod progress;
pub mod render;
pub mod report;
pub mod slice;
pub mod stages;
pub mod volume;
mod wire;

use crate::cli::Command;
use crate::error::{Error, Result};
use crate::io::staging;
use crate::par::{agree, on_root, Comm};

/// Refuses a job whose ranks were started with different command lines (a wrapper that gives
/// each rank its own output prefix, say): the ranks would open different files in collectives
/// meant for one and wait on each other for ever. `args` are this rank's arguments after the
/// program's name. Collective.
pub fn same_arguments(comm: &dyn Comm, args: Vec<String>) -> Result<()> {
    let first: Vec<String> = comm.broadcast_value(0, (comm.rank() == 0).then(|| args.clone()));
    let local = match first.iter().zip(&args).position(|(a, b)| a != b) {
        None if first.len() == args.len() => Ok(()),
        at => {
            let at = at.unwrap_or(first.len().min(args.len()));
            let show = |v: &[String]| v.get(at).map_or("nothing".to_string(), |a| format!("'{a}'"));
            Err(Error::Usage(format!(
                "rank {} was started with other arguments than rank 0 (argument {}: {} against {}); every rank \
                 of a job must get the same command line",
                comm.rank(),
                at + 1,
                show(&args),
                show(&first)
            )))
        }
    };
    agree(comm, local)
}

/// The warning about outputs an earlier run left under the prefix of `command` that this run did
/// not write (`PREFIX.png` after a rerun with `--no-preview`, `PREFIX.trimmed.ply` after one
/// without `--trim`): beside this run's outputs they would pass for them, but may show another
/// solid. They are the user's files and are left alone. (`morph` names its own, the frames of an
/// earlier longer morph.)
fn left_from_earlier(command: &Command) -> Option<String> {
    let (prefix, writes) = match command {
        Command::Fit(a) => (&a.out, preflight::MODEL_OUTPUTS),
        Command::Contours(a) => (&a.out, preflight::MODEL_OUTPUTS),
        Command::Eval(a) => (&a.out, preflight::VOLUME_OUTPUTS),
        Command::Morph(_) | Command::Slice(_) | Command::Render(_) => return None,
    };
    let candidates: Vec<_> = writes.iter().map(|ext| volume::output_path(prefix, ext)).collect();
    let left = staging::left_from_earlier(&candidates);
    if left.is_empty() {
        return None;
    }
    let names: Vec<String> = left.iter().map(|p| p.display().to_string()).collect();
    let (verb, they, them) =
        if left.len() == 1 { ("remains", "it", "it") } else { ("remain", "they", "them") };
    Some(format!(
        "{} {verb} from an earlier run under this prefix; this run did not write {them}, so beside its \
         outputs {they} may show another solid: remove {them} or choose another prefix",
        names.join(", ")
    ))
}

/// Refuses a job whose ranks run in different working directories while the command line names
/// a file by a relative path: each rank would resolve it in its own directory and read or write
/// another file (the ranks then waited on each other for ever in the parallel create of the
/// volume, each opening its own file; a model read by every rank could differ between them).
/// With absolute paths alone the directories do not matter. Collective.
pub fn same_directory(comm: &dyn Comm, command: &Command) -> Result<()> {
    let here = std::env::current_dir().map(|d| d.display().to_string()).unwrap_or_default();
    let first: String = comm.broadcast_value(0, (comm.rank() == 0).then(|| here.clone()));
    let paths = command.paths();
    let relative = paths.iter().find(|p| p.is_relative());
    let local = match relative {
        Some(p) if here != first => Err(Error::Usage(format!(
            "rank {} runs in the directory {here}, rank 0 in {first}, so the relative path {} names \
             another file on each; start every rank in one directory (mpirun --wdir DIR) or give \
             absolute paths",
            comm.rank(),
            p.display()
        ))),
        _ => Ok(()),
    };
    agree(comm, local)
}

/// Runs a parsed command on `comm` with `threads` threads per rank. Collective.
///
/// Every output is written under a temporary name unique to this run (chosen by rank 0, the same on
/// every rank) and all of them are renamed into place together at the end, once every rank has
/// succeeded; after a failure they are removed and the previous outputs stay as they were.
///
/// A rank whose address-space limit leaves less than the program's fixed part is refused first
/// ([`preflight::check_address_space`]).
pub fn run(command: &Command, comm: &dyn Comm, threads: usize) -> Result<()> {
    preflight::check_address_space(comm)?;
    let id: String = comm.broadcast_value(0, (comm.rank() == 0).then(staging::new_run_id));
    staging::begin(&id);
    let result = match command {
        Command::Fit(a) => fit::run(a, comm, threads),
        Command::Eval(a) => eval::run(a, comm, threads),
        Command::Contours(a) => contours::run(a, comm, threads),
        Command::Morph(a) => morph::run(a, comm, threads),
        Command::Slice(a) => slice::run(a, comm),
        Command::Render(a) => render::run(a, comm, threads),
    };
    match result {
        Ok(()) => {
            let committed = on_root(comm, staging::commit_all);
            staging::forget_all();
            if committed.is_ok() && comm.rank() == 0 {
                if let Some(w) = left_from_earlier(command) {
                    crate::note!("volspline: warning: {w}");
                }
            }
            committed
        }
        Err(e) => {
            staging::discard_all();
            Err(e)
        }
    }
}
