//! The `volspline` binary: parses the command line, starts MPI and the thread pool, runs the
//! command and turns its result into an exit status. All logic is in the library.

use clap::Parser;
use volspline::cli::{default_threads, run, Cli};
use volspline::dist::MpiComm;
use volspline::error::Error;

/// This process's rank as the launcher announces it, before MPI is started (0 without one).
fn launcher_rank() -> usize {
    ["OMPI_COMM_WORLD_RANK", "PMI_RANK", "PMIX_RANK", "SLURM_PROCID"]
        .iter()
        .find_map(|v| std::env::var(v).ok()?.parse().ok())
        .unwrap_or(0)
}

fn main() {
    // parse before MPI starts so that --help and usage errors need no MPI, printed by one rank
    let cli = match Cli::try_parse() {
        Ok(c) => c,
        Err(e) => {
            if launcher_rank() == 0 {
                e.exit();
            }
            std::process::exit(e.exit_code());
        }
    };
    let Some(universe) = mpi::initialize() else {
        eprintln!("volspline: error: MPI could not be initialised");
        std::process::exit(1);
    };
    // a panic on one rank must not leave the others waiting in a collective
    let default_hook = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        default_hook(info);
        eprintln!("volspline: internal error (panic); aborting all ranks");
        unsafe {
            mpi::ffi::MPI_Abort(mpi::ffi::RSMPI_COMM_WORLD, 70);
        }
    }));
    let threads = default_threads(cli.threads());
    let comm = MpiComm::new(universe.world());
    let code = match rayon::ThreadPoolBuilder::new().num_threads(threads).build_global() {
        Err(e) => {
            eprintln!("volspline: error: cannot start {threads} threads: {e}");
            1
        }
        Ok(()) => match run(&cli, &comm, threads) {
            Ok(()) => 0,
            Err(e) => {
                if volspline::dist::Comm::rank(&comm) == 0 {
                    match &e {
                        Error::Rank { rank, message } => {
                            eprintln!("volspline: error on rank {rank}: {message}")
                        }
                        other => eprintln!("volspline: error: {other}"),
                    }
                }
                match e {
                    Error::Usage(_) => 2,
                    _ => 1,
                }
            }
        },
    };
    drop(comm);
    drop(universe);
    std::process::exit(code);
}
