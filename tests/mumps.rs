//! The distributed sparse Cholesky factorisation by MUMPS on 1, 2 and 3 MPI ranks (and on one
//! process started without mpirun, where MPI runs as a singleton), against the dense serial LU
//! oracle: a Wendland kernel matrix on bunny vertices, a matrix that is not positive definite, a
//! rank without entries, entries given twice, and input refused on one rank.
//!
//! Each rank holds the rows i = rank (mod ranks) of the lower triangle. A target without the
//! libtest harness (see `common::mpijob`): every job runs within a time limit, so a rank left
//! waiting in a collective fails the test.

mod common;

use std::path::Path;
use std::time::Duration;

use faer::{Mat, Side};
use volspline::error::Error;
use volspline::io::points::read_points;
use volspline::linalg::dense::lu_solve;
use volspline::linalg::mumps::MumpsSpd;
use volspline::linalg::sparse::{SpdSolve, SymCsr};
use volspline::par::mpi::World;
use volspline::par::Comm;

use common::mpijob::{self, must, same_on_every_rank, Case, Check, Expect, Log};

fn main() {
    let limit = Duration::from_secs(120);
    let case = |name, ranks| Case { name, ranks, env: &[], expect: Expect::Pass, limit };
    let cases = vec![
        case("mumps_without_mpirun", 0),
        case("mumps_on_1_rank", 1),
        case("mumps_on_2_ranks", 2),
        case("mumps_on_3_ranks", 3),
    ];
    mpijob::main(cases, child);
}

fn child() {
    let world = World::start().expect("MPI could not be started");
    let mpi = world.comm();
    let checks: [(&str, Check); 5] = [
        ("not positive definite: NotDefinite on every rank", indefinite_is_refused),
        ("Wendland bunny matrix vs dense LU, 3 right-hand sides", bunny_matches_dense_lu),
        ("a rank without entries, entries given twice", small_matrix_and_duplicates),
        ("bad input on one rank: the same error on every rank", bad_input_is_agreed),
        ("right-hand sides of the wrong length", wrong_rhs_length),
    ];
    let failed = mpijob::run_checks(&mpi, &checks);
    drop(world);
    if failed > 0 {
        std::process::exit(1);
    }
}

/// Wendland's C2 function of support `delta`: (1 - r/delta)^4 (4 r/delta + 1) for r < delta.
fn wendland(r: f64, delta: f64) -> f64 {
    let t = r / delta;
    if t >= 1.0 {
        0.0
    } else {
        (1.0 - t).powi(4) * (4.0 * t + 1.0)
    }
}

/// Every 8th bunny vertex, scaled uniformly into the unit box.
fn bunny_points() -> Vec<[f64; 3]> {
    let set = must(read_points(Path::new(common::BUNNY)), "read the bunny");
    let pts: Vec<[f64; 3]> = set.points.iter().step_by(8).copied().collect();
    let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
    for p in &pts {
        for d in 0..3 {
            lo[d] = lo[d].min(p[d]);
            hi[d] = hi[d].max(p[d]);
        }
    }
    let extent = (0..3).map(|d| hi[d] - lo[d]).fold(0.0, f64::max);
    pts.iter().map(|p| [0, 1, 2].map(|d| (p[d] - lo[d]) / extent)).collect()
}

/// The kernel matrix of `pts` with support `delta`, minus `shift` on the diagonal, as a dense
/// matrix (by brute force over all pairs).
fn kernel_matrix(pts: &[[f64; 3]], delta: f64, shift: f64) -> Mat<f64> {
    let n = pts.len();
    Mat::from_fn(n, n, |i, j| {
        let r = (0..3).map(|d| (pts[i][d] - pts[j][d]).powi(2)).sum::<f64>().sqrt();
        wendland(r, delta) - if i == j { shift } else { 0.0 }
    })
}

/// This rank's rows (i = rank mod ranks) of the lower triangle of `m`, its nonzeros only.
fn my_rows(comm: &dyn Comm, m: &Mat<f64>) -> SymCsr {
    let n = m.nrows();
    let mut a = SymCsr { n, row_ptr: vec![0], ..SymCsr::default() };
    for i in (comm.rank()..n).step_by(comm.size()) {
        a.rows.push(i);
        for j in 0..=i {
            if m[(i, j)] != 0.0 {
                a.cols.push(j);
                a.vals.push(m[(i, j)]);
            }
        }
        a.row_ptr.push(a.cols.len());
    }
    a
}

/// `nrhs` smooth, different right-hand sides of order n, column-major.
fn right_hand_sides(n: usize, nrhs: usize) -> Vec<f64> {
    (0..nrhs)
        .flat_map(|k| (0..n).map(move |i| ((i * (k + 2)) as f64 * 0.37).sin() + 0.5 * k as f64))
        .collect()
}

fn bunny_matches_dense_lu(comm: &dyn Comm, log: &mut Log) {
    let pts = bunny_points();
    let m = kernel_matrix(&pts, 0.2, 0.0);
    let n = m.nrows();
    let a = my_rows(comm, &m);
    let mut nnz = [a.nnz() as u64];
    comm.sum_u64(&mut nnz);
    log.check(n > 500 && (nnz[0] as usize) < n * (n + 1) / 4, || {
        format!("{n} points, {} entries in the lower triangle: not a sparse test", nnz[0])
    });
    let f = must(MumpsSpd::factor(comm, &a), "factor the bunny matrix");
    log.check(f.order() == n, || format!("order {}, expected {n}", f.order()));
    let st = f.stats().clone();
    log.check(st.factor_entries as usize >= nnz[0] as usize && st.flops > 0.0, || format!("{st:?}"));
    let all = comm.gather_values(0, &(st.factor_entries, st.ordering.clone()));
    if let Some(all) = all {
        log.check(all.iter().all(|s| *s == all[0]), || format!("the ranks' statistics differ: {all:?}"));
        println!("          n = {n}, {} entries, MUMPS: {st:?}", nnz[0]);
    }
    let nrhs = 3;
    let b = right_hand_sides(n, nrhs);
    let mut x = b.clone();
    must(f.solve_in_place(&mut x, nrhs), "solve with the bunny matrix");
    let mut worst = 0.0f64;
    for k in 0..nrhs {
        let col = k * n..(k + 1) * n;
        let want = must(lu_solve(m.as_ref(), &b[col.clone()]), "the dense LU oracle");
        worst = worst.max(common::rel_diff(&x[col.clone()], &want));
        log.close(&x[col], &want, 1e-10, || format!("right-hand side {k}"));
    }
    if comm.rank() == 0 {
        println!("          largest relative difference from dense LU: {worst:.1e}");
    }
    same_on_every_rank(comm, log, &x, "bunny solution");
    // a second solve with the same factors: on several ranks the order in which MUMPS's
    // messages arrive may change the last bits, but every rank again returns the same ones
    let mut again = b.clone();
    must(f.solve_in_place(&mut again, nrhs), "solve again");
    log.close(&again, &x, 1e-13, || "a second solve".into());
    same_on_every_rank(comm, log, &again, "second bunny solution");
}

fn indefinite_is_refused(comm: &dyn Comm, log: &mut Log) {
    // the same kernel matrix minus 0.5 I: a positive diagonal (0.5), but the smallest
    // eigenvalues of the kernel matrix are far below 0.5
    let m = kernel_matrix(&bunny_points(), 0.2, 0.5);
    log.check(m.llt(Side::Lower).is_err(), || "the shifted matrix has a Cholesky factor".into());
    match MumpsSpd::factor(comm, &my_rows(comm, &m)) {
        Ok(f) => log.check(false, || format!("factored: {:?}", f.stats())),
        Err(e) => {
            log.check(e.is_not_definite(), || format!("{e:?}, expected NotDefinite"));
            log.check(e.remote_rank().is_none_or(|r| r < comm.size() && r != comm.rank()), || {
                format!("{e:?}: a remote error from this rank")
            });
            if comm.rank() == 0 {
                println!("          {e}");
            }
        }
    }
}

fn small_matrix_and_duplicates(comm: &dyn Comm, log: &mut Log) {
    // [[4, 1], [1, 3]] with rows cycled over the ranks: on 3 ranks the last has none. Then every
    // rank adds 0.5 to entry (1, 1): MUMPS sums the duplicates, [[4, 1], [1, 3 + 0.5 p]].
    let m = Mat::from_fn(2, 2, |i, j| [[4.0, 1.0], [1.0, 3.0]][i][j]);
    let b = [1.0, 2.0, -3.0, 0.5];
    let solve2 = |d: f64, b: &[f64]| {
        let det = 4.0 * d - 1.0;
        [(d * b[0] - b[1]) / det, (4.0 * b[1] - b[0]) / det]
    };
    for twice in [false, true] {
        let mut a = my_rows(comm, &m);
        if twice {
            a.rows.push(1);
            a.cols.push(1);
            a.vals.push(0.5);
            a.row_ptr.push(a.cols.len());
        }
        let d = if twice { 3.0 + 0.5 * comm.size() as f64 } else { 3.0 };
        let f = must(MumpsSpd::factor(comm, &a), "factor the 2 x 2 matrix");
        let mut x = b.to_vec();
        must(f.solve_in_place(&mut x, 2), "solve with the 2 x 2 matrix");
        let want: Vec<f64> = b.chunks(2).flat_map(|c| solve2(d, c)).collect();
        log.close(&x, &want, 1e-14, || format!("2 x 2, entries given twice: {twice}"));
        same_on_every_rank(comm, log, &x, "2 x 2 solution");
    }
}

fn bad_input_is_agreed(comm: &dyn Comm, log: &mut Log) {
    // the last rank gives an entry above the diagonal; the others are fine
    let m = Mat::from_fn(6, 6, |i, j| {
        if i == j {
            2.0
        } else if i.abs_diff(j) == 1 {
            -1.0
        } else {
            0.0
        }
    });
    let mut a = my_rows(comm, &m);
    let last = comm.size() - 1;
    if comm.rank() == last {
        let i = a.rows[0];
        a.cols[a.row_ptr[1] - 1] = i + 1;
    }
    match MumpsSpd::factor(comm, &a) {
        Ok(_) => log.check(false, || "factored a matrix with an entry above the diagonal".into()),
        Err(e) => {
            let from = e.remote_rank().unwrap_or(comm.rank());
            log.check(
                matches!(e.root(), Error::Usage(m) if m.contains("above the diagonal")) && from == last,
                || format!("{e:?}, expected the Usage error of rank {last}"),
            );
        }
    }
}

fn wrong_rhs_length(comm: &dyn Comm, log: &mut Log) {
    let m = Mat::from_fn(5, 5, |i, j| {
        if i == j {
            3.0
        } else if i.abs_diff(j) == 1 {
            1.0
        } else {
            0.0
        }
    });
    let f = must(MumpsSpd::factor(comm, &my_rows(comm, &m)), "factor the 5 x 5 matrix");
    let mut short = vec![1.0; 9];
    let got = f.solve_in_place(&mut short, 2);
    log.check(matches!(got.as_ref().map_err(Error::root), Err(Error::Usage(_))), || format!("{got:?}"));
    // nothing to solve is not an error
    let mut none: Vec<f64> = Vec::new();
    let got = f.solve_in_place(&mut none, 0);
    log.check(got.is_ok(), || format!("no right-hand side: {got:?}"));
}
