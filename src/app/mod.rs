//! The commands: one file each ([`fit`], [`eval`], [`contours`], [`slice`](mod@slice)), the checks
//! made before heavy work ([`preflight`]), the volume outputs they share ([`volume`]), their report
//! ([`report`], [`stages`], [`progress`]) and the encodings of what they send between ranks
//! (`wire`). A command takes its typed arguments from `cli` and a communicator; everything it
//! computes comes from the library rooms below it.

pub mod contours;
pub mod eval;
pub mod finite;
pub mod fit;
pub mod preflight;
pub mod progress;
pub mod report;
pub mod slice;
pub mod stages;
pub mod volume;
mod wire;

use crate::cli::Command;
use crate::error::Result;
use crate::par::Comm;

/// Runs a parsed command on `comm` with `threads` threads per rank. Collective.
pub fn run(command: &Command, comm: &dyn Comm, threads: usize) -> Result<()> {
    match command {
        Command::Fit(a) => fit::run(a, comm, threads),
        Command::Eval(a) => eval::run(a, comm, threads),
        Command::Contours(a) => contours::run(a, comm, threads),
        Command::Slice(a) => slice::run(a, comm),
    }
}
