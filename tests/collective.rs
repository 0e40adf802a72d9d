//! Library code that communicates, run on 2 and 3 MPI ranks against serial oracles: the typed
//! collectives, the agreement on errors, the distributed solvers and the Cholesky -> LU fallback,
//! the LU and the projected Cholesky on every 2D process grid of the ranks (also on 1 and 4
//! ranks, those checks alone),
//! the projected Cholesky's factor bordered by appended centres (on the row-cyclic layout, and
//! from a 2D factor moved there),
//! the mixed-precision solve and its fallback to f64,
//! the parallel VTKHDF writer, the per-slice fits of `contours`, the blob search's lattice
//! samples, and the surface step's neighbourhoods, misfit medians and orientation.
//!
//! A target without the libtest harness (see `common::mpijob`): the checks run as jobs under
//! `mpirun -n 2` and `mpirun -n 3 --oversubscribe`, each within a time limit.
//!
//! Two more jobs check the harness itself: with `VOLSPLINE_COLLECTIVE_BREAK` set, one check compares
//! against a wrong value and the job must fail; with `VOLSPLINE_COLLECTIVE_HANG` set, rank 0 never
//! joins a barrier and the job must be killed at its (short) limit.

mod common;

use std::path::{Path, PathBuf};
use std::time::Duration;

use faer::{Mat, MatRef};
use volspline::app::contours::solve_sections;
use volspline::app::fit::{self, solve_extended};
use volspline::contour::planes::{slice_mesh, PlaneFamily};
use volspline::contour::SectionCarrier;
use volspline::error::{Error, Result};
use volspline::grid::Grid;
use volspline::io::vtkhdf::{read_image, write_image};
use volspline::linalg::dense::{householder_solve, lu_solve};
use volspline::linalg::dist::{
    self, Job, LocalBlocks, LocalRows, Precision, ProcessGrid, RowCyclic, SolverKind,
};
use volspline::par::mpi::World;
use volspline::par::{self, Comm, Solo};
use volspline::spline::hygiene::{prepare, Prepared};
use volspline::spline::{full_system, system_size, Carrier, Kernel, Spline};
use volspline::surface::blobs::{data_cells, sample, sample_nodes, sample_window, Lattice};
use volspline::surface::denoise::{scale_ratio, scale_ratio_on};
use volspline::surface::{neighbourhoods, neighbourhoods_on, orient};

use common::mpijob::{self, must, same_on_every_rank, Case, Check, Expect, Log};

/// The rows of the bordered system of `k` (this rank's), which these small systems always fit.
fn assemble(k: &Kernel, centres: &[f64], values: &[f64], layout: RowCyclic) -> LocalRows {
    fit::assemble(k, centres, values, layout).expect("the rows fit in memory")
}

/// [`assemble`] of the lower triangle and the border alone.
fn assemble_lower(k: &Kernel, centres: &[f64], values: &[f64], layout: RowCyclic) -> LocalRows {
    fit::assemble_lower(k, centres, values, layout).expect("the rows fit in memory")
}

/// This rank's blocks of the bordered system of `k` on `grid`.
fn assemble_blocks(
    k: &Kernel,
    centres: &[f64],
    values: &[f64],
    grid: &ProcessGrid<'_>,
    nb: usize,
) -> LocalBlocks {
    fit::assemble_blocks(k, centres, values, grid, nb).expect("the blocks fit in memory")
}

/// [`assemble_blocks`] of the lower triangle and the border alone.
fn assemble_blocks_lower(
    k: &Kernel,
    centres: &[f64],
    values: &[f64],
    grid: &ProcessGrid<'_>,
    nb: usize,
) -> LocalBlocks {
    fit::assemble_blocks_lower(k, centres, values, grid, nb).expect("the blocks fit in memory")
}

const BREAK: &str = "VOLSPLINE_COLLECTIVE_BREAK";
/// Set: the job runs only the checks of the 2D block-cyclic solvers (on 1 and 4 ranks), and on
/// 4 ranks those of the row-cyclic LU and Householder too, which share their block rows' solves
/// from 4 ranks on.
const ONLY_2D: &str = "VOLSPLINE_COLLECTIVE_ONLY_2D";
const HANG: &str = "VOLSPLINE_COLLECTIVE_HANG";

fn main() {
    let limit = Duration::from_secs(120);
    // more ranks than a small runner's cores share them, and a busy machine slows such a job
    // by far more than its share: 4 ranks on 2 cores took 8 s alone and 113 s beside a release
    // build, so that job gets room enough not to be taken for a hang
    let crowded = Duration::from_secs(360);
    let cases = vec![
        Case { name: "collective_checks_on_2_ranks", ranks: 2, env: &[], expect: Expect::Pass, limit },
        Case { name: "collective_checks_on_3_ranks", ranks: 3, env: &[], expect: Expect::Pass, limit },
        Case { name: "solvers_2d_on_1_rank", ranks: 1, env: &[(ONLY_2D, "1")], expect: Expect::Pass, limit },
        Case {
            name: "solvers_2d_on_4_ranks",
            ranks: 4,
            env: &[(ONLY_2D, "1")],
            expect: Expect::Pass,
            limit: crowded,
        },
        Case {
            name: "harness_a_wrong_value_fails_the_job",
            ranks: 2,
            env: &[(BREAK, "1")],
            expect: Expect::Fail("typed collectives"),
            limit,
        },
        Case {
            name: "harness_a_hung_job_is_killed",
            ranks: 2,
            env: &[(HANG, "1")],
            expect: Expect::Hang,
            limit: Duration::from_secs(5),
        },
    ];
    mpijob::main(cases, child);
}

// ---------------------------------------------------------------------------------------------
// The child: every check on the MPI world

fn child() {
    let world = World::start().expect("MPI could not be started");
    let mpi = world.comm();
    let comm: &dyn Comm = &mpi;
    if std::env::var_os(HANG).is_some() {
        // rank 0 never reaches the barrier the others wait in
        if comm.rank() == 0 {
            loop {
                std::thread::sleep(Duration::from_secs(1));
            }
        }
        comm.barrier();
    }
    let checks_2d: [(&str, Check); 4] = [
        ("2D block-cyclic LU and Householder vs the dense oracles", lu2d_matches_the_oracle),
        ("2D projected Cholesky vs the dense oracle, fallback to LU", cholesky2d_matches_the_oracle),
        ("2D blocks moved to the row-cyclic layout", blocks_move_to_row_cyclic),
        ("2D projected Cholesky factor kept and bordered", bordered_2d_factor_matches_the_oracle),
    ];
    if std::env::var_os(ONLY_2D).is_some() {
        let mut failed = mpijob::run_checks(comm, &checks_2d);
        if comm.size() >= 4 {
            let shared: [(&str, Check); 3] = [
                ("typed collectives", typed_collectives),
                ("LU with and without look-ahead vs the dense oracle", lookahead_matches_the_oracle),
                (
                    "Householder and Cholesky with and without look-ahead",
                    row_cyclic_lookahead_matches_the_oracle,
                ),
            ];
            failed += mpijob::run_checks(comm, &shared);
        }
        drop(world);
        std::process::exit(i32::from(failed > 0));
    }
    let checks: [(&str, Check); 21] = [
        ("typed collectives", typed_collectives),
        ("agree: one failing rank", agree_one_failing_rank),
        ("agree: two failing ranks, the lowest wins", agree_lowest_rank_wins),
        ("distributed solvers vs dense oracles", solvers_match_the_oracles),
        ("LU with and without look-ahead vs the dense oracle", lookahead_matches_the_oracle),
        ("Householder and Cholesky with and without look-ahead", row_cyclic_lookahead_matches_the_oracle),
        checks_2d[0],
        checks_2d[1],
        checks_2d[2],
        checks_2d[3],
        ("projected Cholesky factor bordered by appended centres", bordered_factor_matches_the_oracle),
        ("Cholesky -> LU fallback, 4 points", fallback_on_four_points),
        ("Cholesky -> LU fallback, indefinite block", fallback_on_an_indefinite_block),
        ("mixed precision vs the dense LU oracle", mixed_matches_the_oracle),
        ("mixed precision -> f64 fallback, near-coincident points", mixed_falls_back_to_f64),
        ("mixed Cholesky -> f64 fallback, coincident to f32", mixed_cholesky_falls_back_to_f64),
        ("parallel VTKHDF write vs serial values", vtkhdf_slabs_read_back),
        ("contour slices vs one process", sections_match_solo),
        ("blob lattice: whole, a window and scattered nodes vs one process", lattice_samples_match_solo),
        ("surface neighbourhoods, misfit medians and orientation vs one process", surface_steps_match_solo),
        // last: it agrees on the products' engine for the rest of the process
        (
            "Householder with the products' engine agreed vs the dense oracle",
            householder_agreed_matches_the_oracle,
        ),
    ];
    let failed = mpijob::run_checks(comm, &checks);
    drop(world);
    if failed > 0 {
        std::process::exit(1);
    }
}

/// 1 in the self-test of a failing check (`VOLSPLINE_COLLECTIVE_BREAK`), else 0.
fn broken() -> u64 {
    u64::from(std::env::var_os(BREAK).is_some())
}

// ---------------------------------------------------------------------------------------------
// Typed collectives and the agreement on errors: exact values

fn typed_collectives(comm: &dyn Comm, log: &mut Log) {
    let (p, r) = (comm.size(), comm.rank());
    for root in 0..p {
        let v = (format!("from rank {root}"), vec![root as f64 + 0.5; root + 1]);
        let got: (String, Vec<f64>) = comm.broadcast_value(root, (r == root).then(|| v.clone()));
        log.check(got == v, || format!("broadcast_value from {root}: {got:?}, expected {v:?}"));
        let mut buf = if r == root { [1.25, -3.0, root as f64] } else { [f64::NAN; 3] };
        comm.broadcast_f64(root, &mut buf);
        log.check(buf == [1.25, -3.0, root as f64], || format!("broadcast_f64 from {root}: {buf:?}"));
    }
    // rank q sends q strings (rank 0 an empty list) to the last rank
    let mine = (r, vec![format!("rank {r}"); r]);
    let got = comm.gather_values(p - 1, &mine);
    let want: Vec<(usize, Vec<String>)> = (0..p).map(|q| (q, vec![format!("rank {q}"); q])).collect();
    match got {
        Some(g) => log.check(r == p - 1 && g == want, || format!("gather_values: {g:?}, expected {want:?}")),
        None => log.check(r != p - 1, || "gather_values: nothing on the root".into()),
    }
    let mut s = [r as u64 + 1, (r as u64) << 40];
    comm.sum_u64(&mut s);
    let pp = p as u64;
    let want = [pp * (pp + 1) / 2 + broken(), (pp * (pp - 1) / 2) << 40];
    log.check(s == want, || format!("sum_u64: {s:?}, expected {want:?}"));
    let (mut sum, mut max, mut min) = ([r as f64 + 0.25], [r as f64], [r as f64 - 7.0]);
    comm.sum_f64(&mut sum);
    comm.max_f64(&mut max);
    comm.min_f64(&mut min);
    let want_sum = (p * (p - 1) / 2) as f64 + 0.25 * p as f64;
    log.check(sum[0] == want_sum, || format!("sum_f64: {}, expected {want_sum}", sum[0]));
    log.check(max[0] == (p - 1) as f64 && min[0] == -7.0, || format!("max_f64 {max:?}, min_f64 {min:?}"));
    // uneven counts: rank q sends 2q values (rank 0 none)
    let counts: Vec<usize> = (0..p).map(|q| 2 * q).collect();
    let send: Vec<f64> = (0..2 * r).map(|i| (100 * r + i) as f64).collect();
    let want: Vec<f64> = (0..p).flat_map(|q| (0..2 * q).map(move |i| (100 * q + i) as f64)).collect();
    let mut recv = vec![f64::NAN; want.len()];
    comm.all_gather_f64(&send, &counts, &mut recv);
    log.check(recv == want, || format!("all_gather_f64: {recv:?}, expected {want:?}"));
    // the same, non-blocking, with work while in flight (through the timing adapter): the work
    // runs at least once, at most until it says it is done, and the values arrive all the same
    let timed = par::Timed::new(comm);
    for pieces in [0usize, 1, 5] {
        let (mut recv, mut recv32) = (vec![f64::NAN; want.len()], vec![f32::NAN; want.len()]);
        let mut ran = 0;
        let mut work = || {
            ran += 1;
            ran < pieces
        };
        timed.all_gather_f64_while(&send, &counts, &mut recv, &mut work);
        log.check(recv == want, || {
            format!("all_gather_f64_while ({pieces} pieces): {recv:?}, expected {want:?}")
        });
        log.check(ran >= 1 && ran <= pieces.max(1), || {
            format!("all_gather_f64_while: work ran {ran} times of {pieces}")
        });
        let send32: Vec<f32> = send.iter().map(|&v| v as f32).collect();
        timed.all_gather_f32_while(&send32, &counts, &mut recv32, &mut || false);
        let want32: Vec<f32> = want.iter().map(|&v| v as f32).collect();
        log.check(recv32 == want32, || format!("all_gather_f32_while: {recv32:?}, expected {want32:?}"));
        // the non-blocking sum runs its work to the end, in flight or after
        let mut ran = 0;
        let mut work = || {
            ran += 1;
            ran < pieces
        };
        let mut sum = vec![r as f64 + 0.25, -(r as f64) * 1e10, 1.0];
        timed.sum_f64_while(&mut sum, &mut work);
        let want_sums = vec![want_sum, -((p * (p - 1) / 2) as f64) * 1e10, p as f64];
        log.check(sum == want_sums, || {
            format!("sum_f64_while ({pieces} pieces): {sum:?}, expected {want_sums:?}")
        });
        log.check(ran == pieces.max(1), || format!("sum_f64_while: work ran {ran} times of {pieces}"));
    }
    log.check(timed.calls() == 9, || format!("Timed counted {} calls, expected 9", timed.calls()));
    // the ring, both ways
    for step in [1, p - 1] {
        let (dest, source) = ((r + step) % p, (r + p - step) % p);
        let values = |q: usize| [q as f64, 10.0 * q as f64 + 1.0, -(q as f64)];
        let mut recv = [f64::NAN; 3];
        comm.shift_f64(dest, source, &values(r), &mut recv);
        log.check(recv == values(source), || format!("shift_f64 by {step}: {recv:?} from rank {source}"));
    }
}

/// Checks that `got` is the error `want` of rank `failing`, as every rank must see it.
fn check_agreed<T: std::fmt::Debug>(log: &mut Log, r: usize, got: Result<T>, want: &Error, failing: usize) {
    match got {
        Ok(v) => log.check(false, || format!("Ok({v:?}), expected the error of rank {failing}")),
        Err(e) => {
            // the failing rank keeps its own error; the others get it as Remote with its rank
            let rank = e.remote_rank().unwrap_or(r);
            let own = r == failing && e.remote_rank().is_none();
            log.check(e.root() == want && rank == failing && (own || r != failing), || {
                format!("{e:?}, expected {want:?} from rank {failing}")
            });
            log.check(e.to_string() == want.to_string() && e.exit_code() == want.exit_code(), || {
                format!("'{e}' (exit code {}), expected '{want}'", e.exit_code())
            });
            log.check(e.is_not_definite() == matches!(want, Error::NotDefinite(_)), || {
                format!("is_not_definite of {e:?}")
            });
        }
    }
}

fn agree_one_failing_rank(comm: &dyn Comm, log: &mut Log) {
    let (p, r) = (comm.size(), comm.rank());
    let last = p - 1;
    let want = Error::NotDefinite(format!("pivot -1 on rank {last}"));
    let local = if r == last { Err(want.clone()) } else { Ok(r) };
    check_agreed(log, r, par::agree(comm, local), &want, last);
    // no error anywhere: each rank keeps its own value
    let got = par::agree(comm, Ok::<usize, Error>(10 * r));
    log.check(matches!(got, Ok(v) if v == 10 * r), || format!("agree without errors: {got:?}"));
    // a failure on rank 0 alone (a file write)
    let want = Error::Io { path: PathBuf::from("/root-only"), reason: "disk full".into() };
    let got = par::on_root(comm, || Err(want.clone()));
    check_agreed(log, r, got, &want, 0);
}

fn agree_lowest_rank_wins(comm: &dyn Comm, log: &mut Log) {
    let (p, r) = (comm.size(), comm.rank());
    let (low, high) = (p - 2, p - 1);
    let want = Error::Usage(format!("bad option on rank {low}"));
    let local: Result<()> = match r {
        _ if r == low => Err(want.clone()),
        _ if r == high => Err(Error::NotDefinite("the higher rank's error".into())),
        _ => Ok(()),
    };
    check_agreed(log, r, par::agree(comm, local), &want, low);
}

// ---------------------------------------------------------------------------------------------
// The distributed solvers against the dense serial oracles

/// Every 20th bunny vertex, prepared as `fit` prepares them: 253 centres, 257 rows.
fn bunny_system(k: &Kernel) -> Prepared {
    must(prepare(&common::bunny_subset(20, 0), k, &Carrier::AutoBall, 1e-6), "prepare the bunny points")
}

/// The dense serial solution of the whole system of `prep` by `solve`.
fn oracle(prep: &Prepared, k: &Kernel, solve: fn(MatRef<'_, f64>, &[f64]) -> Result<Vec<f64>>) -> Vec<f64> {
    let n = system_size(k, prep.values.len());
    let (data, b) = full_system(k, &prep.centres, &prep.values);
    must(solve(MatRef::from_column_major_slice(&data, n, n), &b), "the dense oracle")
}

fn solvers_match_the_oracles(comm: &dyn Comm, log: &mut Log) {
    let k = Kernel::new(3, 2).unwrap();
    let prep = bunny_system(&k);
    let n = system_size(&k, prep.values.len());
    let (x_qr, x_lu) = (oracle(&prep, &k, householder_solve), oracle(&prep, &k, lu_solve));
    for kind in [SolverKind::Householder, SolverKind::Lu, SolverKind::Cholesky] {
        // 7 and 16 put the rows of every panel on every rank; 64 panels end inside a rank's rows
        for panel in [7, 16, 64] {
            let layout = RowCyclic::new(n, comm.size(), comm.rank());
            let mut rows = assemble(&k, &prep.centres, &prep.values, layout);
            let x = must(kind.run(&Job::on(comm).panel(panel), &mut rows), kind.name());
            let want = if kind == SolverKind::Lu { &x_lu } else { &x_qr };
            let what = format!("{} panel {panel}", kind.name());
            log.close(&x, want, 1e-9, || what.clone());
            same_on_every_rank(comm, log, &x, &what);
        }
    }
}

/// The bunny system of about 1000 rows (every fifth point) with r^3: the kernel, the points, the
/// size, the dense oracle's solution by `solve` and this rank's row-cyclic layout.
fn about_1000_rows(
    comm: &dyn Comm,
    solve: fn(MatRef<'_, f64>, &[f64]) -> Result<Vec<f64>>,
) -> (Kernel, Prepared, usize, Vec<f64>, RowCyclic) {
    let k = Kernel::new(3, 2).unwrap();
    let prep =
        must(prepare(&common::bunny_subset(5, 2), &k, &Carrier::AutoBall, 1e-6), "prepare the bunny points");
    let n = system_size(&k, prep.values.len());
    let want = oracle(&prep, &k, solve);
    (k, prep, n, want, RowCyclic::new(n, comm.size(), comm.rank()))
}

/// The LU with look-ahead (the trailing update in pieces inside the next panel's pivot searches:
/// about 1000 rows, so that a panel's update takes several pieces) and without, against the
/// dense LU oracle; both factor in f64 and in f32 (the factorisation of a mixed-precision solve).
fn lookahead_matches_the_oracle(comm: &dyn Comm, log: &mut Log) {
    let (k, prep, n, want, layout) = about_1000_rows(comm, lu_solve);
    for lookahead in [true, false] {
        for panel in [7, 16, 64] {
            let job = Job::on(comm).panel(panel).lookahead(lookahead);
            let mut rows = assemble(&k, &prep.centres, &prep.values, layout);
            let x = must(SolverKind::Lu.run(&job, &mut rows), "lu");
            let what = format!("lu panel {panel} n {n} look-ahead {lookahead}");
            log.close(&x, &want, 1e-9, || what.clone());
            same_on_every_rank(comm, log, &x, &what);
            // the f32 factors, refined in f64 to the f64 accuracy
            let rows = assemble(&k, &prep.centres, &prep.values, layout);
            let (x, r) = must(dist::mixed_solve(&job, &rows, SolverKind::Lu), "mixed lu");
            log.check(r.converged, || format!("{what}: mixed refinement {}", r.describe()));
            log.close(&x, &want, 1e-7, || format!("{what} (f32 factors)"));
        }
    }
}

/// The row-cyclic Householder QR and projected Cholesky with look-ahead (the trailing update in
/// pieces inside the next panel's collectives) and without, on about 1000 rows against the dense
/// QR oracle, with panels narrower than the border (1 and 3 < k = 4), ending inside a rank's rows
/// (16) and wider (64): the factors (the overwritten rows) agree to 1e-12 either way on 2 and 3
/// ranks (1e-10 from 4 on, see below). The f32 projected Cholesky of a mixed-precision solve
/// looks ahead too.
fn row_cyclic_lookahead_matches_the_oracle(comm: &dyn Comm, log: &mut Log) {
    let (k, prep, n, want, layout) = about_1000_rows(comm, householder_solve);
    for kind in [SolverKind::Householder, SolverKind::Cholesky] {
        for panel in [1, 3, 16, 64] {
            let mut factors = Vec::new();
            for lookahead in [false, true] {
                let job = Job::on(comm).panel(panel).lookahead(lookahead);
                let mut rows = assemble(&k, &prep.centres, &prep.values, layout);
                let x = must(kind.run(&job, &mut rows), kind.name());
                let what = format!("{} panel {panel} n {n} look-ahead {lookahead}", kind.name());
                log.close(&x, &want, 1e-9, || what.clone());
                same_on_every_rank(comm, log, &x, &what);
                factors.push(rows.data);
            }
            // the look-ahead sums its panel's all-reduces in rank order, the all-reduce in its
            // own, and splits the trailing updates into products of other widths, which a BLAS
            // may round otherwise column by column: on 4 ranks the factors differ by up to
            // 1.6e-11 with the products by the BLAS (panel 1; 3.4e-12 with faer's, panel 3); on
            // 2 ranks by less than 1e-12 with OpenBLAS's AVX2 kernels, 3.1e-12 with its AVX-512
            // (Cooperlake) kernels (panel 3)
            let tol = 1e-10;
            log.close(&factors[1], &factors[0], tol, || {
                format!("{} panel {panel}: the factors with look-ahead against those without", kind.name())
            });
        }
    }
    // the projected Cholesky from the lower triangle and the first k rows alone, as a fit
    // assembles them for it (several blocks of the product with the reflectors)
    for panel in [3, 64] {
        let job = Job::on(comm).panel(panel).lookahead(true);
        let mut rows = assemble_lower(&k, &prep.centres, &prep.values, layout);
        let x = must(SolverKind::Cholesky.run(&job, &mut rows), "cholesky");
        let what = format!("cholesky panel {panel} n {n} from the lower triangle");
        log.close(&x, &want, 1e-9, || what.clone());
        same_on_every_rank(comm, log, &x, &what);
    }
    for (panel, lower) in [(3, false), (64, false), (64, true)] {
        let job = Job::on(comm).panel(panel).lookahead(true);
        let rows = if lower {
            assemble_lower(&k, &prep.centres, &prep.values, layout)
        } else {
            assemble(&k, &prep.centres, &prep.values, layout)
        };
        let what = format!("mixed cholesky panel {panel} look-ahead, lower triangle alone {lower}");
        let (x, r) = must(dist::mixed_solve(&job, &rows, SolverKind::Cholesky), &what);
        log.check(r.converged, || format!("{what}: refinement {}", r.describe()));
        log.close(&x, &want, 1e-7, || what.clone());
        same_on_every_rank(comm, log, &x, &what);
    }
}

/// The row-cyclic and 2D Householder QR once the ranks have agreed on the products' engine (as
/// `fit` does): with the BLAS on every rank, W = V^T A_trail is formed and summed as W^T, which
/// the checks above (no agreement) never take. Against the dense QR oracle, with and without
/// look-ahead, on the row-cyclic layout and on the grids P x 1 and 1 x P. Changes the process's
/// engine state: run last.
fn householder_agreed_matches_the_oracle(comm: &dyn Comm, log: &mut Log) {
    use volspline::linalg::gemm::{self, Engine};
    let engine = gemm::choose_agreed(comm, Engine::Auto);
    log.check(gemm::by_blas_on_every_rank(faer::Par::Seq) == (engine == Engine::Blas), || {
        format!("the agreed engine {} and the solvers' choice of form disagree", engine.name())
    });
    let (k, prep, _, want, layout) = about_1000_rows(comm, householder_solve);
    for (panel, lookahead) in [(3, false), (16, true), (64, false), (64, true)] {
        let job = Job::on(comm).panel(panel).lookahead(lookahead);
        let mut rows = assemble(&k, &prep.centres, &prep.values, layout);
        let x = must(SolverKind::Householder.run(&job, &mut rows), "householder");
        let what = format!("householder ({}) panel {panel} look-ahead {lookahead}", engine.name());
        log.close(&x, &want, 1e-9, || what.clone());
        same_on_every_rank(comm, log, &x, &what);
    }
    let p = comm.size();
    for shape in [(p, 1), (1, p)] {
        let grid = must(dist::ProcessGrid::new(comm, shape), "the process grid");
        for (nb, lookahead) in [(7, true), (64, false)] {
            let what = format!(
                "householder2d ({}) {}x{} block {nb} look-ahead {lookahead}",
                engine.name(),
                shape.0,
                shape.1
            );
            let mut a = assemble_blocks(&k, &prep.centres, &prep.values, &grid, nb);
            let x =
                must(dist::householder2d_solve(&Job::on(comm).lookahead(lookahead), &grid, &mut a), &what);
            log.close(&x, &want, 1e-9, || what.clone());
            same_on_every_rank(comm, log, &x, &what);
        }
    }
}

/// The projected Cholesky of the first three quarters of the bunny system, its factor kept, then
/// bordered by none of the remaining quarter of the centres, by its first half, by that half in
/// reverse order and by all of it, with every ninth of the first values negated, and each
/// bordered factor solved again for values with every fifth negated, and for three other sets
/// of values at once: against the dense QR of the whole system, panels ending inside and beyond
/// a rank's rows, and the same on every rank. The
/// factor keeps the first half's substitutions, and the later extensions reuse them; held to a
/// quarter of its centres, or given no memory beyond the estimate, it keeps no more, by default
/// (small factors keep up to `dist::KEPT_FLOOR` columns) the whole quarter's too.
fn bordered_factor_matches_the_oracle(comm: &dyn Comm, log: &mut Log) {
    let k = Kernel::new(3, 2).unwrap();
    let prep = bunny_system(&k);
    let n = prep.values.len() * 3 / 4;
    for panel in [7, 16, 64] {
        let job = Job::on(comm).panel(panel);
        let layout = RowCyclic::new(n + k.poly_count(), comm.size(), comm.rank());
        let rows = assemble(&k, &prep.centres[..3 * n], &prep.values[..n], layout);
        let (_, first) = must(
            dist::solve_keeping(&job, SolverKind::Cholesky, rows, || unreachable!(), true),
            "the first projected Cholesky",
        );
        let first = first.expect("the projected Cholesky keeps its factor");
        // by default a factor this small keeps every column; held to a quarter of its centres,
        // or given no memory beyond the estimate (which counts a quarter), the whole remaining
        // quarter (a third of n) does not fit
        let (first, most) = match panel {
            7 => (first.keeping_at_most(n / 4), n / 4),
            16 => (first, dist::kept_most(n)),
            _ => {
                first.limit_extras(0.0);
                (first, n / 4)
            }
        };
        let what = format!("panel {panel}");
        check_bordering(&job, log, &k, &prep, (&first, most), &what);
        // no more memory beyond the estimate than given: with none, no diagonal block either;
        // given less than it holds, it lets go of all it kept
        let beyond = first.extra_bytes();
        match panel {
            64 => log.check(beyond == 0.0, || format!("{what}: {beyond} bytes beyond the estimate")),
            _ => {
                log.check(beyond > 0.0, || format!("{what}: nothing kept beyond the estimate"));
                first.limit_extras(beyond / 2.0);
                let (now, kept) = (first.extra_bytes(), first.kept_centres());
                log.check(now == 0.0 && kept == 0, || format!("{what}: {now} bytes, {kept} kept"));
            }
        }
    }
}

/// The 2D projected Cholesky's factor kept (moved to the row-cyclic layout), then bordered as in
/// [`bordered_factor_matches_the_oracle`]: on every process grid of the ranks, blocks ending
/// inside the border (7) and fewer blocks than ranks near the end (64), the first solve against
/// the oracle too. A factor moved with rows or columns misplaced, or without the first k rows,
/// fails the bordered solves.
fn bordered_2d_factor_matches_the_oracle(comm: &dyn Comm, log: &mut Log) {
    let k = Kernel::new(3, 2).unwrap();
    let prep = bunny_system(&k);
    let n = prep.values.len() * 3 / 4;
    let first_prep = Prepared {
        centres: prep.centres[..3 * n].to_vec(),
        values: prep.values[..n].to_vec(),
        ..prep.clone()
    };
    let want = oracle(&first_prep, &k, householder_solve);
    let p = comm.size();
    for shape in (1..=p).filter(|pr| p.is_multiple_of(*pr)).map(|pr| (pr, p / pr)) {
        let grid = must(dist::ProcessGrid::new(comm, shape), "the process grid");
        for (nb, panel) in [(7, 0), (64, 16)] {
            let what = format!("2D {}x{} block {nb}, bordering panel {panel}", shape.0, shape.1);
            let job = Job::on(comm).panel(panel);
            let a = assemble_blocks_lower(&k, &first_prep.centres, &first_prep.values, &grid, nb);
            let (s, first) = must(
                dist::solve_2d_keeping(&job, &grid, SolverKind::Cholesky, 4, a, || unreachable!(), true),
                &what,
            );
            log.close(&s.x, &want, 1e-9, || format!("{what}: the first solve"));
            let Some(first) = first else {
                log.check(false, || format!("{what}: no factor kept"));
                continue;
            };
            log.check(first.centres() == n && first.border() == 4, || {
                format!("{what}: factor of {}", first.centres())
            });
            check_bordering(&job, log, &k, &prep, (&first, dist::kept_most(n)), &what);
        }
    }
}

/// Borders `first`, the factor of the first n centres of `prep` (three quarters of them), as
/// [`bordered_factor_matches_the_oracle`] describes, and checks every solve against the oracle.
fn check_bordering(
    job: &Job<'_>,
    log: &mut Log,
    k: &Kernel,
    prep: &Prepared,
    (first, most): (&dist::Factored, usize),
    label: &str,
) {
    let total = prep.values.len();
    let n = first.centres();
    let half = n + (total - n) / 2;
    // the appended centres of each system: none, the first half, it reversed, all
    let reversed: Vec<usize> = (n..half).rev().collect();
    let orders: [Vec<usize>; 4] = [vec![], (n..half).collect(), reversed, (n..total).collect()];
    for (step, order) in orders.iter().enumerate() {
        let picked: Vec<usize> = (0..n).chain(order.iter().copied()).collect();
        let count = picked.len();
        let mut values: Vec<f64> = picked.iter().map(|&i| prep.values[i]).collect();
        (0..n).step_by(9).for_each(|i| values[i] = -values[i]);
        let centres: Vec<f64> =
            picked.iter().flat_map(|&i| prep.centres[3 * i..3 * i + 3].to_vec()).collect();
        let centres = &centres[..];
        let (x, bordered) = must(solve_extended(job, k, centres, &values, first), "the bordered solve");
        // kept after the first half (a sixth of n); after the whole quarter (a third) where it
        // fits what the factor keeps
        let kept = match step {
            0 => 0,
            3 if total - n <= most => total - n,
            _ => half - n,
        };
        log.check(first.kept_centres() == kept, || {
            format!("{label}, step {step}: {} substitutions kept, not {kept}", first.kept_centres())
        });
        let size = system_size(k, count);
        let (a, b) = full_system(k, centres, &values);
        let want = must(householder_solve(MatRef::from_column_major_slice(&a, size, size), &b), "the oracle");
        let what = format!("{label}: {n} centres bordered by {} (step {step})", count - n);
        log.close(&x, &want, 1e-9, || what.clone());
        same_on_every_rank(job.comm, log, &x, &what);
        // other values of the same centres (every fifth negated, the appended ones too),
        // solved with the bordered factor alone
        (0..count).step_by(5).for_each(|i| values[i] = -values[i]);
        let x = dist::solve_bordered(job, first, &bordered, &values);
        let (_, b) = full_system(k, centres, &values);
        let want = must(householder_solve(MatRef::from_column_major_slice(&a, size, size), &b), "the oracle");
        let what = format!("{what}, other values by the bordered factor");
        log.close(&x, &want, 1e-9, || what.clone());
        same_on_every_rank(job.comm, log, &x, &what);
        // three sets of values at once (one pass through the factor), each as the oracle solves it
        let sets: Vec<Vec<f64>> = (1..=3)
            .map(|t| {
                let v = values.iter().enumerate();
                v.map(|(i, v)| if i % (t + 2) == 0 { -v } else { v * t as f64 }).collect()
            })
            .collect();
        let rhs: Vec<&[f64]> = sets.iter().map(|v| &v[..]).collect();
        let many = dist::solve_bordered_many(job, first, &bordered, &rhs);
        log.check(many.len() == 3, || format!("{what}: {} solutions of 3", many.len()));
        for (t, (x, v)) in many.iter().zip(&sets).enumerate() {
            let (_, b) = full_system(k, centres, v);
            let want =
                must(householder_solve(MatRef::from_column_major_slice(&a, size, size), &b), "the oracle");
            let what = format!("{what}, values {t} of 3 at once");
            log.close(x, &want, 1e-9, || what.clone());
            same_on_every_rank(job.comm, log, x, &what);
        }
    }
}

/// The 2D blocks moved to the row-cyclic layout ([`dist::LocalBlocks::to_row_cyclic`]) on every
/// grid of the ranks, blocks 1, 7 and 64, in bands of one, of 5 and of all columns: the whole
/// matrix, its lower triangle, the lower triangle and the first k rows of the centres' block (what
/// a kept factor needs), and nothing, each exactly the row-cyclic assembly's values where moved
/// and zero elsewhere.
fn blocks_move_to_row_cyclic(comm: &dyn Comm, log: &mut Log) {
    let k = Kernel::new(3, 2).unwrap();
    let prep = bunny_system(&k);
    let n = system_size(&k, prep.values.len());
    let layout = RowCyclic::new(n, comm.size(), comm.rank());
    let rows = assemble(&k, &prep.centres, &prep.values, layout);
    let p = comm.size();
    let parts = [
        ("every entry", (n, n)),
        ("the lower triangle", (n, 0)),
        ("a factor's part", (n - 4, 4)),
        ("nothing", (0, 0)),
    ];
    for shape in (1..=p).filter(|pr| p.is_multiple_of(*pr)).map(|pr| (pr, p / pr)) {
        let grid = must(dist::ProcessGrid::new(comm, shape), "the process grid");
        for nb in [1, 7, 64] {
            let a = assemble_blocks(&k, &prep.centres, &prep.values, &grid, nb);
            for band in [1, 5, usize::MAX] {
                for (name, (count, top)) in parts {
                    let moved = a.to_row_cyclic_in_bands(&grid, 4, (count, top), band);
                    let what = format!("{}x{} block {nb}, bands of {band} columns: {name}", shape.0, shape.1);
                    log.check(moved.layout == layout && moved.cols == n + 1 && moved.border == 4, || {
                        what.clone()
                    });
                    let wrong = (0..layout.local_count()).flat_map(|l| (0..=n).map(move |c| (l, c))).find(
                        |&(l, c)| {
                            let g = layout.global(l);
                            let wanted = g < count && c < count && (c <= g || g < top);
                            let expect = if wanted { rows.get(l, c) } else { 0.0 };
                            moved.get(l, c).to_bits() != expect.to_bits()
                        },
                    );
                    log.check(wrong.is_none(), || format!("{what}: entry {wrong:?} differs"));
                }
            }
        }
    }
}

/// The LU and the Householder QR on the 2D block-cyclic layout, on every process grid of the
/// job's ranks and several block sizes (1: a panel per column; 7 and 16: blocks ending inside
/// the polynomial border; 64: fewer blocks than ranks in a grid dimension near the end), with and
/// without look-ahead, against the dense LU and QR oracles on about 1000 rows; a system with a
/// repeated centre is singular on every rank alike.
fn lu2d_matches_the_oracle(comm: &dyn Comm, log: &mut Log) {
    let k = Kernel::new(3, 2).unwrap();
    let prep =
        must(prepare(&common::bunny_subset(5, 2), &k, &Carrier::AutoBall, 1e-6), "prepare the bunny points");
    let want = oracle(&prep, &k, lu_solve);
    let want_qr = oracle(&prep, &k, householder_solve);
    let p = comm.size();
    let shapes: Vec<(usize, usize)> =
        (1..=p).filter(|pr| p.is_multiple_of(*pr)).map(|pr| (pr, p / pr)).collect();
    // the same centres with the first one repeated at the end: two equal rows
    let mut centres = prep.centres.clone();
    centres.extend_from_slice(&prep.centres[..3]);
    let mut values = prep.values.clone();
    values.push(prep.values[0]);
    for &shape in &shapes {
        let grid = must(dist::ProcessGrid::new(comm, shape), "the process grid");
        for nb in [1, 7, 16, 64] {
            for lookahead in [false, true] {
                let what = format!(
                    "lu2d {}x{} block {nb} look-ahead {lookahead} n {}",
                    shape.0,
                    shape.1,
                    want.len()
                );
                let mut a = assemble_blocks(&k, &prep.centres, &prep.values, &grid, nb);
                let x = must(dist::lu2d_solve(&Job::on(comm).lookahead(lookahead), &grid, &mut a), &what);
                log.close(&x, &want, 1e-9, || what.clone());
                same_on_every_rank(comm, log, &x, &what);
            }
        }
        // Householder QR on the same grid, against the dense QR oracle
        for (nb, lookahead) in [(1, false), (7, true), (16, false), (64, true)] {
            let what = format!("householder2d {}x{} block {nb} look-ahead {lookahead}", shape.0, shape.1);
            let mut a = assemble_blocks(&k, &prep.centres, &prep.values, &grid, nb);
            let x =
                must(dist::householder2d_solve(&Job::on(comm).lookahead(lookahead), &grid, &mut a), &what);
            log.close(&x, &want_qr, 1e-9, || what.clone());
            same_on_every_rank(comm, log, &x, &what);
        }
        let mut a = assemble_blocks(&k, &centres, &values, &grid, 16);
        let what = format!("lu2d {}x{} repeated centre", shape.0, shape.1);
        match dist::lu2d_solve(&Job::on(comm).lookahead(true), &grid, &mut a) {
            Ok(_) => log.check(false, || format!("{what}: solved a singular system")),
            Err(e) => {
                let msg = e.to_string();
                log.check(msg.contains("singular"), || format!("{what}: {msg}"));
                let bytes: Vec<f64> = msg.bytes().map(f64::from).collect();
                same_on_every_rank(comm, log, &bytes, &format!("{what}: the error"));
            }
        }
    }
}

/// The projected Cholesky on the 2D block-cyclic layout, on every process grid of the job's ranks
/// and block sizes 1 and 3 (panels narrower than the border), 7, 16 and 64, with and without
/// look-ahead, against the dense QR oracle; on an indefinite projected block every rank falls
/// back to the 2D LU.
fn cholesky2d_matches_the_oracle(comm: &dyn Comm, log: &mut Log) {
    let k = Kernel::new(3, 2).unwrap();
    let prep = bunny_system(&k);
    let want = oracle(&prep, &k, householder_solve);
    let (ind, kb) = indefinite_bordered();
    let n = ind.nrows();
    let b: Vec<f64> = (0..n).map(|i| ind[(i, n)]).collect();
    let want_lu = must(lu_solve(ind.as_ref().subcols(0, n), &b), "the dense LU oracle");
    let p = comm.size();
    for shape in (1..=p).filter(|pr| p.is_multiple_of(*pr)).map(|pr| (pr, p / pr)) {
        let grid = must(dist::ProcessGrid::new(comm, shape), "the process grid");
        for (nb, lookahead) in
            [(1, false), (3, true), (7, false), (7, true), (16, true), (64, false), (64, true)]
        {
            let what = format!("cholesky2d {}x{} block {nb} look-ahead {lookahead}", shape.0, shape.1);
            let job = Job::on(comm).lookahead(lookahead);
            // from the whole matrix, and from the lower triangle and the first k rows alone, as
            // a fit assembles them for it
            for lower in [false, true] {
                let a = if lower {
                    assemble_blocks_lower(&k, &prep.centres, &prep.values, &grid, nb)
                } else {
                    assemble_blocks(&k, &prep.centres, &prep.values, &grid, nb)
                };
                let what = format!("{what}, lower triangle alone {lower}");
                let s =
                    must(dist::solve_2d(&job, &grid, SolverKind::Cholesky, 4, a, || unreachable!()), &what);
                log.check(s.used == SolverKind::Cholesky && s.fallback.is_none(), || {
                    format!("{what}: {s:?}")
                });
                log.close(&s.x, &want, 1e-9, || what.clone());
                same_on_every_rank(comm, log, &s.x, &what);
            }
            let blocks = || {
                let mut a = dist::LocalBlocks::zeros(&grid, n, nb);
                let (rg, cg) = (a.rows.globals(), a.cols.globals());
                for (lc, &c) in cg.iter().enumerate() {
                    for (lr, &r) in rg.iter().enumerate() {
                        a.data[lr + lc * rg.len()] = ind[(r, c)];
                    }
                }
                a
            };
            let what = format!("{what}, indefinite block");
            let s = must(
                dist::solve_2d(&Job::on(comm), &grid, SolverKind::Cholesky, kb, blocks(), || Ok(blocks())),
                &what,
            );
            log.check(
                s.used == SolverKind::Lu && s.fallback.as_ref().is_some_and(Error::is_not_definite),
                || format!("{what}: used {:?}, fallback {:?}", s.used, s.fallback),
            );
            log.close(&s.x, &want_lu, 1e-9, || what.clone());
            same_on_every_rank(comm, log, &s.x, &what);
            let refuse = || Err(Error::Memory("the LU fallback's whole matrix (refused by the test)".into()));
            let s = dist::solve_2d(&Job::on(comm), &grid, SolverKind::Cholesky, kb, blocks(), refuse);
            log.check(matches!(s, Err(Error::Memory(_))), || format!("{what}, fallback refused: {s:?}"));
        }
    }
    // about 1000 rows, from the lower triangle: many panels, and a panel's update in several
    // pieces while the next panel's broadcast is in flight
    let big =
        must(prepare(&common::bunny_subset(5, 2), &k, &Carrier::AutoBall, 1e-6), "prepare the bunny points");
    let want = oracle(&big, &k, householder_solve);
    for shape in (1..=p).filter(|pr| p.is_multiple_of(*pr)).map(|pr| (pr, p / pr)) {
        let grid = must(dist::ProcessGrid::new(comm, shape), "the process grid");
        for (nb, lookahead) in [(16, false), (16, true), (64, true)] {
            let a = assemble_blocks_lower(&k, &big.centres, &big.values, &grid, nb);
            let what = format!(
                "cholesky2d {}x{} block {nb} look-ahead {lookahead}, {} rows",
                shape.0,
                shape.1,
                a.n()
            );
            let job = Job::on(comm).lookahead(lookahead);
            let s = must(dist::solve_2d(&job, &grid, SolverKind::Cholesky, 4, a, || unreachable!()), &what);
            log.check(s.used == SolverKind::Cholesky && s.fallback.is_none(), || format!("{what}: {s:?}"));
            log.close(&s.x, &want, 1e-9, || what.clone());
            same_on_every_rank(comm, log, &s.x, &what);
        }
    }
}

/// Solves with `dist::solve` and the Cholesky solver (with and without look-ahead), and checks
/// that every rank fell back to LU (because of a block that is not definite) and matches the dense LU solution `want`.
fn check_fallback(
    comm: &dyn Comm,
    log: &mut Log,
    rows_of: &dyn Fn(RowCyclic) -> LocalRows,
    n: usize,
    want: &[f64],
    what: &str,
) {
    for (panel, lookahead) in [(0, false), (3, false), (3, true), (8, false), (8, true)] {
        let layout = RowCyclic::new(n, comm.size(), comm.rank());
        let job = Job::on(comm).panel(panel).lookahead(lookahead);
        let solved = dist::solve(&job, SolverKind::Cholesky, rows_of(layout), || Ok(rows_of(layout)));
        let what = &format!("{what} look-ahead {lookahead}");
        let s = must(solved, what);
        log.check(s.used == SolverKind::Lu, || format!("{what} panel {panel}: used {:?}", s.used));
        let why = s.fallback.as_ref();
        log.check(why.is_some_and(Error::is_not_definite), || {
            format!("{what} panel {panel}: fallback {why:?}")
        });
        log.close(&s.x, want, 1e-9, || format!("{what} panel {panel}"));
        same_on_every_rank(comm, log, &s.x, what);
    }
    // a fallback whose whole matrix is refused (the memory check before it is assembled) ends
    // with that refusal on every rank
    let layout = RowCyclic::new(n, comm.size(), comm.rank());
    let refuse = || Err(Error::Memory("the LU fallback's whole matrix (refused by the test)".into()));
    let solved = dist::solve(&Job::on(comm), SolverKind::Cholesky, rows_of(layout), refuse);
    log.check(matches!(solved, Err(Error::Memory(_))), || format!("{what}, fallback refused: {solved:?}"));
}

fn fallback_on_four_points(comm: &dyn Comm, log: &mut Log) {
    // N = 4 = k: the projected block is empty, nothing is definite
    let k = Kernel::new(3, 2).unwrap();
    let raw = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];
    let prep = must(prepare(&raw, &k, &Carrier::AutoBall, 1e-6), "prepare 4 points");
    let n = system_size(&k, 4);
    let want = oracle(&prep, &k, lu_solve);
    let rows_of = |layout| assemble(&k, &prep.centres, &prep.values, layout);
    check_fallback(comm, log, &rows_of, n, &want, "4 points");
}

/// Symmetric random entries with a zero diagonal, bordered by [1 x y z] of random points, and a
/// random right-hand side as the last column (40 + 4 rows): the projected block is indefinite.
fn indefinite_bordered() -> (Mat<f64>, usize) {
    let (m, k) = (40, 4);
    let n = m + k;
    let mut s = 3u64;
    let mut rnd = move || {
        s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    };
    let mut a = Mat::<f64>::zeros(n, n + 1);
    for i in 0..m {
        for j in 0..i {
            let v = rnd();
            a[(i, j)] = v;
            a[(j, i)] = v;
        }
        let p = [1.0, rnd(), rnd(), rnd()];
        for (t, v) in p.iter().enumerate() {
            a[(i, m + t)] = *v;
            a[(m + t, i)] = *v;
        }
        a[(i, n)] = rnd();
    }
    (a, k)
}

fn fallback_on_an_indefinite_block(comm: &dyn Comm, log: &mut Log) {
    // the same global matrix on every rank; each keeps its rows
    let (a, k) = indefinite_bordered();
    let n = a.nrows();
    let rows_of = |layout: RowCyclic| {
        let mut rows = LocalRows::zeros(layout, n + 1, k);
        for l in 0..layout.local_count() {
            for c in 0..=n {
                rows.set(l, c, a[(layout.global(l), c)]);
            }
        }
        rows
    };
    let b: Vec<f64> = (0..n).map(|i| a[(i, n)]).collect();
    let want = must(lu_solve(a.as_ref().subcols(0, n), &b), "the dense LU oracle");
    check_fallback(comm, log, &rows_of, n, &want, "indefinite block");
}

/// The solution of `solve_in` in mixed precision with `kind` for the f64 fallback.
fn mixed(comm: &dyn Comm, k: &Kernel, prep: &Prepared, kind: SolverKind, panel: usize) -> dist::Solved {
    let n = system_size(k, prep.values.len());
    let layout = RowCyclic::new(n, comm.size(), comm.rank());
    let rows_of = || assemble(k, &prep.centres, &prep.values, layout);
    must(
        dist::solve_in(&Job::on(comm).panel(panel), kind, Precision::Mixed, rows_of(), || Ok(rows_of())),
        "mixed solve",
    )
}

fn mixed_matches_the_oracle(comm: &dyn Comm, log: &mut Log) {
    let k = Kernel::new(3, 2).unwrap();
    let prep = bunny_system(&k);
    let want = oracle(&prep, &k, lu_solve);
    // the f32 projected Cholesky where the f64 solver would be Cholesky, the f32 LU otherwise
    for (kind, factor, panel) in [
        (SolverKind::Cholesky, SolverKind::Cholesky, 7),
        (SolverKind::Cholesky, SolverKind::Cholesky, 16),
        (SolverKind::Cholesky, SolverKind::Cholesky, 64),
        (SolverKind::Lu, SolverKind::Lu, 16),
        (SolverKind::Householder, SolverKind::Lu, 64),
    ] {
        let s = mixed(comm, &k, &prep, kind, panel);
        let what = format!("mixed for {}, panel {panel}", kind.name());
        log.check(s.mixed_fallback.is_none() && s.used == factor, || {
            format!("{what}: fell back ({:?}), used {:?}", s.mixed_fallback, s.used)
        });
        let r = s.refinement.clone().unwrap_or_else(|| panic!("{what}: no refinement"));
        // the f32 solution alone is 1e-7 off: at least one step, and the f64 residual at the end
        log.check(r.converged && r.classical >= 1 && r.history[0] > 1e-9, || format!("{what}: {r:?}"));
        log.check(r.residual() < 1e-13, || format!("{what}: residual {:e}", r.residual()));
        log.close(&s.x, &want, 1e-9, || what.clone());
        same_on_every_rank(comm, log, &s.x, &what);
    }
}

/// Every 20th bunny vertex, and every 4th of those again, moved by `dx` in x (the box diagonal is
/// 25), prepared for the kernel `k` without merging them.
fn near_coincident(k: &Kernel, dx: f64) -> Prepared {
    let mut raw = common::bunny_subset(20, 0);
    let near: Vec<f64> = raw.chunks(3).step_by(4).flat_map(|p| [p[0] + dx, p[1], p[2]]).collect();
    raw.extend(near);
    must(prepare(&raw, k, &Carrier::AutoBall, 1e-12), "prepare the near-coincident points")
}

fn mixed_falls_back_to_f64(comm: &dyn Comm, log: &mut Log) {
    // 1e-5 of the box diagonal apart: rows that agree to 1e-5 are singular in f32 (pivot
    // tolerance n eps32 max |a| = 4e-5), not in f64
    let k = Kernel::new(3, 2).unwrap();
    let prep = near_coincident(&k, 2.5e-4);
    let want = oracle(&prep, &k, lu_solve);
    for panel in [0, 16] {
        let s = mixed(comm, &k, &prep, SolverKind::Lu, panel);
        let what = format!("near-coincident, panel {panel}");
        let why = s.mixed_fallback.clone().unwrap_or_default();
        log.check(why.contains("single-precision factorisation failed") && why.contains("singular"), || {
            format!("{what}: fallback message '{why}'")
        });
        log.check(s.used == SolverKind::Lu && s.refinement.is_none(), || format!("{what}: {s:?}"));
        log.close(&s.x, &want, 1e-8, || what.clone());
        same_on_every_rank(comm, log, &s.x, &what);
    }
}

fn mixed_cholesky_falls_back_to_f64(comm: &dyn Comm, log: &mut Log) {
    // 1e-8 of the box diagonal apart: the projected block is definite in f64 (barely), but its
    // rounding to f32 is not
    let k = Kernel::new(3, 2).unwrap();
    let prep = near_coincident(&k, 2.5e-7);
    let want = oracle(&prep, &k, lu_solve);
    for panel in [0, 16] {
        let s = mixed(comm, &k, &prep, SolverKind::Cholesky, panel);
        let what = format!("near-coincident, Cholesky, panel {panel}");
        let why = s.mixed_fallback.clone().unwrap_or_default();
        log.check(
            why.contains("single-precision projected Cholesky failed") && why.contains("not positive"),
            || format!("{what}: fallback message '{why}'"),
        );
        log.check(s.refinement.is_none(), || format!("{what}: {s:?}"));
        // the f64 solve with the same solver, and the dense LU to kappa eps64 (about 1e-6 here)
        let n = system_size(&k, prep.values.len());
        let rows_of =
            || assemble(&k, &prep.centres, &prep.values, RowCyclic::new(n, comm.size(), comm.rank()));
        let f64_solve = must(
            dist::solve(&Job::on(comm).panel(panel), SolverKind::Cholesky, rows_of(), || Ok(rows_of())),
            "f64",
        );
        log.check(s.x == f64_solve.x && s.used == f64_solve.used, || format!("{what}: not the f64 solve"));
        log.close(&s.x, &want, 1e-5, || what.clone());
        same_on_every_rank(comm, log, &s.x, &what);
    }
}

// ---------------------------------------------------------------------------------------------
// Parallel output and the per-slice fits: bit for bit what one process gives

fn vtkhdf_slabs_read_back(comm: &dyn Comm, log: &mut Log) {
    let (p, r) = (comm.size(), comm.rank());
    // one folder, named by rank 0, for all ranks
    let dir: PathBuf =
        comm.broadcast_value(0, (r == 0).then(|| common::temp_dir("collective-vtkhdf").into_path()));
    // 7 layers over 2 or 3 ranks (uneven slabs); 2 layers leave the third rank without any
    for dims in [[5, 4, 7], [3, 2, 2]] {
        let grid = Grid { dims, origin: [-1.0, 0.5, 2.0], spacing: [0.25, 0.5, 0.125] };
        let value = |g: usize| (g as f64 * 0.37).sin() * 1e3;
        let layer = dims[0] * dims[1];
        let slabs = grid.slabs(p);
        let (k0, layers) = (slabs.start(r), slabs.count(r));
        let mine: Vec<f64> = (k0 * layer..(k0 + layers) * layer).map(value).collect();
        let path = dir.join(format!("{}x{}x{}.hdf", dims[0], dims[1], dims[2]));
        must(write_image(comm, &path, &grid, k0, layers, "f", &mine), "write_image");
        if r == 0 {
            let (g, v) = must(read_image(&path, "f"), "read_image");
            let want: Vec<f64> = (0..grid.node_count()).map(value).collect();
            log.check(g == grid, || format!("{dims:?}: grid read back {g:?}"));
            log.check(v == want, || format!("{dims:?}: values read back differ from the serial ones"));
        }
    }
    comm.barrier();
    if r == 0 {
        let _ = std::fs::remove_dir_all(&dir);
    }
}

fn sections_match_solo(comm: &dyn Comm, log: &mut Log) {
    // 5 slices of the cow across z: 2 or 3 per rank, uneven
    let mesh = common::load_mesh(Path::new(common::COW));
    let planes = PlaneFamily::Parallel { axis: 2, count: 5 }.planes(&mesh.vertices);
    let (sections, _) = slice_mesh(&mesh, &planes);
    log.check(sections.len() == 5, || format!("{} slices of the cow, expected 5", sections.len()));
    let k = Kernel::new(2, 2).unwrap();
    let source = Path::new("cow slices");
    let serial = must(solve_sections(&Solo, source, &sections, &k, SectionCarrier::Disc, 1e-6), "Solo");
    let fits = must(solve_sections(comm, source, &sections, &k, SectionCarrier::Disc, 1e-6), "MPI");
    log.check(fits.len() == serial.len(), || format!("{} fits, expected {}", fits.len(), serial.len()));
    for (i, (a, b)) in fits.iter().zip(&serial).enumerate() {
        log.check(a == b, || format!("slice {i}: the fit differs from the one-process fit"));
    }
}

/// The blob search's samples of a fit on its lattice (whole, a window, scattered nodes), dealt
/// over the ranks, against one process: the same bits.
fn lattice_samples_match_solo(comm: &dyn Comm, log: &mut Log) {
    let k = Kernel::new(3, 2).unwrap();
    let prep = bunny_system(&k);
    let n = prep.values.len();
    let weights: Vec<f64> = (0..n).map(|i| (0.37 * i as f64).sin() / n as f64).collect();
    let spline = Spline {
        kernel: k,
        centres: prep.centres.clone(),
        weights,
        poly: vec![0.1, 0.2, -0.3, 0.4],
        norm: prep.norm,
    };
    let lattice = Lattice::new([-1.0; 3], [1.0; 3], 23);
    let pair = (&prep.carrier, &spline);
    let serial = sample(&Solo, &lattice, &prep.carrier, &spline);
    let whole = sample(comm, &lattice, &prep.carrier, &spline);
    log.check(whole == serial, || "the whole lattice differs from the one-process sampling".into());
    log.check(serial.iter().any(|&v| v > 0.0) && serial.iter().any(|&v| v < 0.0), || "no sign change".into());
    let mut window = vec![f64::NAN; serial.len()];
    sample_window(comm, &lattice, &[2..9, 0..23, 11..14], pair, &mut window);
    let mut nodes = vec![f64::NAN; serial.len()];
    let cells = data_cells(&lattice, &prep.centres);
    sample_nodes(comm, &lattice, &cells, pair, &mut nodes);
    let [nx, ny, _] = lattice.dims;
    for i in 0..serial.len() {
        let (x, z) = (i % nx, i / (nx * ny));
        let in_window = (2..9).contains(&x) && (11..14).contains(&z);
        log.check(!in_window || window[i] == serial[i], || {
            format!("window node {i}: {} vs {}", window[i], serial[i])
        });
        let asked = cells.binary_search(&i).is_ok();
        log.check(!asked || nodes[i] == serial[i], || format!("node {i}: {} vs {}", nodes[i], serial[i]));
        log.check(asked || nodes[i].is_nan(), || format!("node {i} not asked for was written"));
    }
}

/// The surface step's per-point work dealt over the ranks (nearest neighbours, PCA normals, the
/// quadrics' misfit medians) and its orientation with the dense dipole sums shared: every rank
/// holds one process's lists and values, bit for bit, on 1263 bunny points (about a quarter
/// of the scan, so the blocks end mid-way through the octree's cells).
fn surface_steps_match_solo(comm: &dyn Comm, log: &mut Log) {
    let pts = common::bunny_subset(4, 1);
    let serial = must(neighbourhoods(&pts), "neighbourhoods on one process");
    let shared = must(neighbourhoods_on(comm, &pts), "neighbourhoods dealt over the ranks");
    log.check(shared.kmax == serial.kmax && shared.knn == serial.knn, || "the neighbour lists differ".into());
    let bits = |v: &[[f64; 3]]| v.iter().flat_map(|x| x.map(f64::to_bits)).collect::<Vec<u64>>();
    log.check(bits(&shared.normals) == bits(&serial.normals), || "the normals differ".into());
    let one = scale_ratio(&pts, &serial.normals, &serial.knn, serial.kmax);
    let all = scale_ratio_on(comm, &pts, &serial.normals, &serial.knn, serial.kmax);
    log.check(one.0.is_finite() && one.1.is_finite(), || format!("no misfits: {one:?}"));
    log.check([one.0, one.1, one.2].map(f64::to_bits) == [all.0, all.1, all.2].map(f64::to_bits), || {
        format!("misfit medians {all:?} against one process's {one:?}")
    });
    let o1 =
        must(orient(&Solo, &pts, &serial.normals, &serial.knn, serial.kmax, false), "orient on one process");
    let on =
        must(orient(comm, &pts, &shared.normals, &shared.knn, shared.kmax, false), "orient over the ranks");
    log.check(o1.dense_dipole && o1.patches > 1, || format!("no dipole correction: {} patches", o1.patches));
    log.check(bits(&on.normals) == bits(&o1.normals) && on.flipped == o1.flipped, || {
        format!("oriented normals differ ({} and {} patches flipped)", on.flipped, o1.flipped)
    });
}
