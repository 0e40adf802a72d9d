//! `fit --smooth LAMBDA`: the smoothing spline on real data with noise (bunny vertices with
//! Gaussian noise of 0.5 % of the diagonal). Its equations hold (U(P_i) = r_i - s lambda
//! lambda_i), a larger lambda gives less bending energy for more misfit, the dense solvers on 1,
//! 2 and 3 ranks and the compactly supported solvers (faer and MUMPS) give the serial oracle's
//! coefficients, and the model file keeps lambda; on a noisy sphere the smoothed surface is
//! nearer the truth than the interpolating one.

mod common;

use std::path::Path;

use common::{solve_serial, Rng};
use volspline::io::model_file::read_model;
use volspline::linalg::dist::SolverKind;
use volspline::mesh::{connected_components, TriMesh};
use volspline::spline::hygiene::{prepare, Prepared};
use volspline::spline::{Carrier, Kernel, Spline};

/// Every `step`-th bunny vertex with Gaussian noise of 0.5 % of the bunny's diagonal on every
/// coordinate.
fn noisy_bunny(step: usize) -> Vec<f64> {
    let pts = common::bunny_subset(step, 0);
    let (lo, hi) = volspline::spline::hygiene::bounding_box(&pts, 3);
    let diag = volspline::spline::hygiene::diagonal(&lo, &hi);
    let mut r = Rng(41);
    pts.iter().map(|x| x + 0.005 * diag * r.normal()).collect()
}

/// The misfit sum_i (U(P_i) - r_i)^2 at the data, the bending energy s lambda^T A lambda and the
/// largest error of the smoothing equations U(P_i) - r_i + s lambda lambda_i, relative to the
/// largest |r_i|.
fn misfit_energy_equations(prep: &Prepared, sp: &Spline) -> (f64, f64, f64) {
    let k = sp.kernel;
    let n = prep.values.len();
    let rmax = prep.values.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let (mut misfit, mut energy, mut worst) = (0.0, 0.0, 0.0f64);
    for i in 0..n {
        let u = sp.eval(&prep.points[3 * i..3 * i + 3]);
        let d = u - prep.values[i];
        misfit += d * d;
        worst = worst.max((d + k.nugget() * sp.weights[i]).abs() / rmax);
        let pi = &prep.centres[3 * i..3 * i + 3];
        let row: f64 = (0..n)
            .map(|j| {
                let pj = &prep.centres[3 * j..3 * j + 3];
                let r2: f64 = (0..3).map(|d| (pi[d] - pj[d]).powi(2)).sum();
                k.eval_r2(r2) * sp.weights[j]
            })
            .sum();
        energy += k.definiteness_sign() * sp.weights[i] * row;
    }
    (misfit, energy, worst)
}

#[test]
fn a_larger_smoothing_gives_less_bending_energy_for_more_misfit_on_a_noisy_scan() {
    let pts = noisy_bunny(20);
    let r = Kernel::new(3, 2).unwrap();
    let prep = prepare(&pts, &r, &Carrier::AutoBall, 1e-6).unwrap();
    let mut last: Option<(f64, f64)> = None;
    for lambda in [0.0, 1e-3, 1e-2, 1e-1] {
        let k = r.with_smoothing(lambda).unwrap();
        assert_eq!(k.nugget(), -lambda, "r is conditionally negative definite: the nugget is -lambda");
        let sp = solve_serial(&prep, &k, SolverKind::Householder);
        let (misfit, energy, worst) = misfit_energy_equations(&prep, &sp);
        println!("lambda {lambda:e}: misfit {misfit:e}, energy {energy:e}, equations {worst:e}");
        assert!(worst < 1e-9, "lambda {lambda}: the smoothing equations hold to {worst:e}");
        assert!(energy > 0.0);
        match last {
            None => assert!(misfit < 1e-18, "lambda 0 interpolates: misfit {misfit:e}"),
            Some((m0, e0)) => {
                assert!(misfit > m0, "lambda {lambda}: misfit {misfit:e} not above {m0:e}");
                assert!(energy < e0, "lambda {lambda}: energy {energy:e} not below {e0:e}");
            }
        }
        last = Some((misfit, energy));
    }
    // measured 0.84 of the interpolant's energy at lambda = 0.1 (the shape's energy stays)
    let first = misfit_energy_equations(&prep, &solve_serial(&prep, &r, SolverKind::Householder)).1;
    assert!(last.unwrap().1 < 0.9 * first, "{last:?} against {first:e}");
}

/// Fits `input` with `args` on `ranks` ranks (the plain carrier system, so that the oracle is the
/// data's alone) and returns the model's coefficients, the model and the report.
fn fit(dir: &Path, input: &Path, name: &str, ranks: usize, args: &[&str]) -> (Vec<f64>, Spline, String) {
    let prefix = dir.join(name);
    let mut all = vec![
        "fit",
        input.to_str().unwrap(),
        "--out",
        prefix.to_str().unwrap(),
        "--grid",
        "16",
        "--surface",
        "carrier",
    ];
    all.extend_from_slice(args);
    let text = common::run_ok(ranks, &all);
    let model = read_model(&dir.join(format!("{name}.model.h5"))).unwrap();
    let sp = model.spline;
    ([sp.weights.clone(), sp.poly.clone()].concat(), sp, text)
}

#[test]
fn smoothing_fits_on_one_two_and_three_ranks_and_with_the_sparse_solvers_match_the_serial_oracle() {
    let dir = common::temp_dir("smoothing-oracle");
    let input = dir.join("noisy-bunny.xyz");
    common::write_xyz(&input, &noisy_bunny(8));
    let read: Vec<f64> =
        volspline::io::points::read_points(&input).unwrap().points.iter().flatten().copied().collect();
    let check = |kernel: Kernel, name: &str, ranks: usize, args: &[&str], tol: f64| {
        let prep = prepare(&read, &kernel, &Carrier::AutoBall, 1e-6).unwrap();
        let oracle = solve_serial(&prep, &kernel, SolverKind::Householder);
        let oracle = [oracle.weights, oracle.poly].concat();
        let (got, sp, text) = fit(&dir, &input, name, ranks, args);
        assert_eq!(sp.kernel, kernel, "{name}: the model keeps the kernel and its smoothing");
        assert!(text.contains(&format!("smoothing {}", kernel.smoothing())), "{text}");
        let d = common::rel_diff(&got, &oracle);
        println!("{name} on {ranks} ranks: {d:e} from the serial oracle");
        assert!(d < tol, "{name} on {ranks} ranks: {d:e} from the serial oracle");
    };
    let r = Kernel::new(3, 2).unwrap().with_smoothing(0.02).unwrap();
    for ranks in [1, 2, 3] {
        let dense = ["--method", "dense", "--smooth", "0.02", "--solver", "cholesky", "--panel", "32"];
        check(r, &format!("cholesky{ranks}"), ranks, &dense, 1e-9);
    }
    check(
        r,
        "lu-2d",
        2,
        &["--method", "dense", "--smooth", "0.02", "--solver", "lu", "--layout", "2d"],
        1e-9,
    );
    let w = Kernel::wendland("wendland2", 0.15).unwrap().with_smoothing(0.5).unwrap();
    let csrbf = ["--method", "csrbf", "--kernel", "wendland2", "--support", "0.15", "--smooth", "0.5"];
    check(w, "faer", 1, &csrbf, 1e-10);
    check(w, "mumps", 2, &csrbf, 1e-9);
}

/// The mesh of `pts` fitted by the plain carrier method with `--smooth lambda`.
fn sphere_mesh(dir: &Path, pts: &[f64], lambda: &str) -> TriMesh {
    let input = dir.join("sphere.xyz");
    common::write_xyz(&input, pts);
    let prefix = dir.join(format!("smooth{lambda}"));
    let args = [
        "fit",
        input.to_str().unwrap(),
        "--out",
        prefix.to_str().unwrap(),
        "--grid",
        "60",
        "--surface",
        "carrier",
    ];
    common::run_ok(2, &[&args[..], &["--smooth", lambda, "--no-preview"]].concat());
    common::load_mesh(&dir.join(format!("smooth{lambda}.ply")))
}

#[test]
fn smoothing_brings_the_surface_of_a_noisy_sphere_nearer_the_truth() {
    let dir = common::temp_dir("smoothing-sphere");
    // 800 points on the unit sphere with noise of 2 % of its radius on every coordinate
    let mut r = Rng(3);
    let pts: Vec<f64> = (0..800)
        .flat_map(|_| {
            let mut p = [r.normal(), r.normal(), r.normal()];
            let len = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
            p.iter_mut().for_each(|x| *x /= len);
            p.map(|x| x + 0.02 * r.normal())
        })
        .collect();
    let rms = |m: &TriMesh| {
        let s: f64 =
            m.vertices.iter().map(|v| ((v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt() - 1.0).powi(2)).sum();
        (s / m.vertices.len() as f64).sqrt()
    };
    let plain = sphere_mesh(&dir, &pts, "0");
    let smooth = sphere_mesh(&dir, &pts, "0.3");
    let (a, b) = (rms(&plain), rms(&smooth));
    println!("rms of |x| - 1 over the vertices: {a:.4} interpolating, {b:.4} with --smooth 0.3");
    assert_eq!(connected_components(&smooth), 1);
    assert!(b < 0.6 * a, "smoothing left {b:.4} against {a:.4}");
}
