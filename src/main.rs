//! The `volspline` binary: parses the command line (before MPI starts, so `--help` and usage errors
//! need no MPI and are printed by one rank), starts MPI and the thread pool, runs the command and
//! turns its result into an exit status. All logic is in the library.

use volspline::cli::{default_threads, launcher_rank, threads_warning, Cli};
use volspline::par::mpi::World;
use volspline::par::Comm;

fn main() {
    let cli = match Cli::parse_noting_given() {
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
    // a write past the file-size limit (`ulimit -f`, a batch system's) fails with EFBIG, which the
    // writers report with the file's name and the run's temporary files removed, instead of
    // SIGXFSZ ending the rank without a word and leaving them
    // SAFETY: sets the process-wide disposition of one signal, before any other thread exists
    unsafe { libc::signal(libc::SIGXFSZ, libc::SIG_IGN) };
    interrupts::watch();
    let Some(world) = World::start() else {
        volspline::note!("volspline: error: MPI could not be initialised");
        std::process::exit(1);
    };
    // a panic removes this run's temporary outputs before the hook of `World::start` aborts the
    // job: only SIGKILL, or a lost node, may leave `.NAME.RUNID.partial` files behind
    let abort_hook = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        volspline::io::staging::discard_after_panic();
        abort_hook(info);
    }));
    volspline::app::progress::set_mode(cli.progress());
    if let Some(bytes) = cli.memory_per_rank() {
        volspline::app::preflight::limit_memory(bytes);
    }
    let threads = default_threads(cli.threads());
    let comm = world.comm();
    if let (0, Some(w)) = (comm.rank(), threads_warning(cli.threads())) {
        volspline::note!("volspline: warning: {w}");
    }
    let code = match rayon::ThreadPoolBuilder::new().num_threads(threads).build_global() {
        Err(e) => {
            volspline::note!("volspline: error: cannot start {threads} threads: {e}");
            1
        }
        Ok(()) => {
            // the address space mapped by now (the binary, MPI, HDF5, the threads' stacks) is the
            // baseline the address-space limit's checks count the work's memory on top of
            volspline::app::preflight::note_start();
            match volspline::app::same_arguments(&comm, std::env::args().skip(1).collect())
                .and_then(|()| volspline::app::same_directory(&comm, &cli.command))
                .and_then(|()| volspline::app::run(&cli.command, &comm, threads))
            {
                Ok(()) => 0,
                Err(e) => {
                    if comm.rank() == 0 {
                        match e.remote_rank() {
                            Some(rank) => volspline::note!("volspline: error on rank {rank}: {e}"),
                            None => volspline::note!("volspline: error: {e}"),
                        }
                    }
                    e.exit_code()
                }
            }
        }
    };
    interrupts::finished(code);
    drop(comm);
    // every HDF5 object is closed before MPI is finalised: otherwise the library's exit handler
    // would close a file left open by a failed close through MPI-IO after MPI_Finalize
    volspline::io::h5::close_library();
    drop(world);
    std::process::exit(code);
}

/// SIGINT, SIGTERM and SIGHUP (the terminal of a run without `mpirun` closed, a dropped ssh
/// session): blocked in every thread (they inherit the mask of the main thread, set before any
/// is started) and taken by one watcher thread, which removes this run's temporary output files,
/// says so and ends the process with 128 + the signal's number.
///
/// Once the command has finished (its outcome agreed by every rank and reported by rank 0), a
/// signal only ends the process with that outcome's status, silently: the launcher ends the other
/// ranks as soon as one exits with an error, and a rank still finalising MPI then is not
/// interrupted work.
mod interrupts {
    use std::sync::atomic::{AtomicI32, Ordering};
    use volspline::io::staging;

    /// The exit status of the finished command; -1 while it runs.
    static FINISHED: AtomicI32 = AtomicI32::new(-1);

    pub fn finished(code: i32) {
        FINISHED.store(code, Ordering::SeqCst);
    }

    pub fn watch() {
        // SAFETY: plain libc signal-set calls on a local set, before any other thread exists
        let set = unsafe {
            let mut set: libc::sigset_t = std::mem::zeroed();
            libc::sigemptyset(&mut set);
            libc::sigaddset(&mut set, libc::SIGINT);
            libc::sigaddset(&mut set, libc::SIGTERM);
            libc::sigaddset(&mut set, libc::SIGHUP);
            libc::pthread_sigmask(libc::SIG_BLOCK, &set, std::ptr::null_mut());
            set
        };
        std::thread::spawn(move || {
            let mut sig: libc::c_int = 0;
            // SAFETY: waits for one of the signals blocked above
            if unsafe { libc::sigwait(&set, &mut sig) } != 0 {
                return;
            }
            let code = FINISHED.load(Ordering::SeqCst);
            if code >= 0 {
                // SAFETY: as below
                unsafe { libc::_exit(code) }
            }
            let name = match sig {
                libc::SIGINT => "SIGINT",
                libc::SIGHUP => "SIGHUP",
                _ => "SIGTERM",
            };
            let (removed, renamed) = staging::discard_all();
            let replaced = if renamed == 0 {
                "no output was replaced".to_string()
            } else {
                format!("the {renamed} output(s) of this run had already been renamed into place, complete")
            };
            volspline::note!(
                "volspline: interrupted by {name}; removed {} temporary file(s){}; {replaced}",
                removed.len(),
                removed.first().map_or(String::new(), |t| format!(" ({})", t.display()))
            );
            // SAFETY: ends the process at once, without running exit handlers that could touch MPI
            unsafe { libc::_exit(128 + sig) }
        });
    }
}
