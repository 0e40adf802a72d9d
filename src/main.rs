//! The `volspline` binary: parses the command line (before MPI starts, so `--help` and usage errors
//! need no MPI and are printed by one rank), starts MPI and the thread pool, runs the command and
//! turns its result into an exit status. All logic is in the library.

use clap::Parser;
use volspline::cli::{default_threads, launcher_rank, Cli};
use volspline::par::mpi::World;
use volspline::par::Comm;

fn main() {
    let cli = match Cli::try_parse() {
        Ok(c) => c,
        Err(e) => {
            if launcher_rank() == 0 {
                e.exit();
            }
            // every rank parsed the same arguments; rank 0 prints the message and exits, and the
            // launcher then ends the others: leaving first could end the job before the message
            std::thread::sleep(std::time::Duration::from_secs(10));
            std::process::exit(e.exit_code());
        }
    };
    let Some(world) = World::start() else {
        eprintln!("volspline: error: MPI could not be initialised");
        std::process::exit(1);
    };
    let threads = default_threads(cli.threads());
    let comm = world.comm();
    let code = match rayon::ThreadPoolBuilder::new().num_threads(threads).build_global() {
        Err(e) => {
            eprintln!("volspline: error: cannot start {threads} threads: {e}");
            1
        }
        Ok(()) => match volspline::app::run(&cli.command, &comm, threads) {
            Ok(()) => 0,
            Err(e) => {
                if comm.rank() == 0 {
                    match e.remote_rank() {
                        Some(rank) => eprintln!("volspline: error on rank {rank}: {e}"),
                        None => eprintln!("volspline: error: {e}"),
                    }
                }
                e.exit_code()
            }
        },
    };
    drop(comm);
    drop(world);
    std::process::exit(code);
}
