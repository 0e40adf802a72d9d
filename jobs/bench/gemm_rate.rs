//! The rate of the local kernels volspline's factorisations are built on: faer's matrix product
//! C -= A B (one thread) and volspline's own `linalg::gemm::gemm`, the product the solvers call
//! (the machine's optimised BLAS where `auto` finds one, faer otherwise; its rows are named
//! `volspline_gemm_<engine>`), on the shapes of `micro_blas.c` (m = 2000 local rows, n = 4000 trailing
//! columns, inner dimension k = 16..256, the panel width) and on the projected Cholesky's
//! row-chunked update (96 rows, k = 384), and the solve from the right of the Cholesky's panels
//! (`volspline_trsm_<engine>`, m rows against a k x k triangle). Beside OpenBLAS's DGEMM rate it separates what the
//! choice of local kernel costs from what the distribution costs. Prints CSV:
//! kernel,m,n,k,seconds,gflops. Run by `jobs/bench-solve`.
//!
//!     cargo run --release --example gemm_rate

use std::time::Instant;

use faer::linalg::matmul::matmul;
use faer::{Accum, Mat, Par};
use volspline::linalg::gemm::{self, Engine};

fn main() {
    println!("kernel,m,n,k,seconds,gflops");
    let engine = gemm::choose(Engine::Auto);
    let ours = format!("volspline_gemm_{}", engine.name());
    for (name, faer_only) in [("faer_gemm", true), (ours.as_str(), false)] {
        rates(name, faer_only);
    }
}

/// Prints the rows of one kernel: faer's `matmul`, or volspline's `gemm`.
fn rates(name: &str, faer_only: bool) {
    let shapes = [(2000, 4000, 16), (2000, 4000, 32), (2000, 4000, 64), (2000, 4000, 128), (2000, 4000, 256)];
    for (m, n, k) in shapes.into_iter().chain([(96, 4000, 384)]) {
        let a = Mat::<f64>::from_fn(m, k, |i, j| ((i * 7 + j * 3) % 11) as f64 * 0.1 - 0.5);
        let b = Mat::<f64>::from_fn(k, n, |i, j| ((i * 5 + j * 13) % 17) as f64 * 0.05 - 0.4);
        let mut c = Mat::<f64>::zeros(m, n);
        let best = best_time(
            || (),
            || {
                if faer_only {
                    matmul(c.as_mut(), Accum::Add, a.as_ref(), b.as_ref(), -1.0, Par::Seq);
                } else {
                    gemm::gemm(c.as_mut(), Accum::Add, a.as_ref(), b.as_ref(), -1.0, Par::Seq);
                }
            },
        );
        std::hint::black_box(&c);
        println!("{name},{m},{n},{k},{best:.6e},{:.3}", 2.0 * (m * n * k) as f64 / best / 1e9);
    }
    if !faer_only {
        solve_rates(&name.replace("gemm", "trsm"));
    }
}

/// Prints the rows of volspline's solve from the right as the projected Cholesky calls it for
/// L21 = B21 L11^-T (`gemm::solve_lower` on the transpose of a column-major m x k block, a k x k
/// triangle; flops m k^2), in the kernel,m,n,k columns as m, k, k.
fn solve_rates(name: &str) {
    for (m, k) in [(4000, 384), (8000, 384), (4000, 192)] {
        let l = Mat::<f64>::from_fn(k, k, |i, j| match i.cmp(&j) {
            std::cmp::Ordering::Less => 0.0,
            std::cmp::Ordering::Equal => 2.0 + (i % 5) as f64 * 0.1,
            std::cmp::Ordering::Greater => ((i * 7 + j * 3) % 11) as f64 * 0.02 - 0.1,
        });
        let b0 = Mat::<f64>::from_fn(m, k, |i, j| ((i * 5 + j * 13) % 17) as f64 * 0.05 - 0.4);
        let b = std::cell::RefCell::new(b0.clone());
        let best = best_time(
            || b.borrow_mut().copy_from(&b0),
            || gemm::solve_lower(l.as_ref(), false, b.borrow_mut().as_mut().transpose_mut(), Par::Seq),
        );
        std::hint::black_box(&b);
        println!("{name},{m},{k},{k},{best:.6e},{:.3}", (m * k * k) as f64 / best / 1e9);
    }
}

/// The best time of `run` over up to 5 repetitions, each after an untimed `setup`, stopping once
/// 0.5 s are spent (as micro_blas.c).
fn best_time(mut setup: impl FnMut(), mut run: impl FnMut()) -> f64 {
    let (mut best, mut spent) = (f64::INFINITY, 0.0);
    for _ in 0..5 {
        setup();
        let t = Instant::now();
        run();
        let dt = t.elapsed().as_secs_f64();
        best = best.min(dt);
        spent += dt;
        if spent > 0.5 {
            break;
        }
    }
    best
}
