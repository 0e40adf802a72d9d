//! `fit --method csrbf` end to end on real data (every 4th bunny vertex, 1263 points): the sparse
//! solvers (faer's sparse Cholesky, the envelope Cholesky, MUMPS on 2 and 3 ranks) give the
//! coefficients of a dense solve of the same Wendland system; the report carries the octree and
//! factor figures; `eval` of the saved model reproduces the fit's volume; a support too small to
//! connect the points is refused with the fix; `--method auto` keeps small inputs dense.

mod common;

use std::path::{Path, PathBuf};

use volspline::io::model_file::read_model;
use volspline::io::vtkhdf::read_image;
use volspline::spline::Model;

fn coefficients(m: &Model) -> Vec<f64> {
    [m.spline.weights.clone(), m.spline.poly.clone()].concat()
}

fn timings(path: &Path) -> Vec<(String, String)> {
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .skip(1)
        .filter_map(|l| l.split_once(',').map(|(k, v)| (k.to_string(), v.to_string())))
        .collect()
}

fn figure<'a>(t: &'a [(String, String)], key: &str) -> &'a str {
    &t.iter().find(|(k, _)| k == key).unwrap_or_else(|| panic!("no {key} in {t:?}")).1
}

struct Run {
    model: Model,
    prefix: PathBuf,
    timings: Vec<(String, String)>,
}

fn fit(dir: &Path, input: &Path, name: &str, ranks: usize, extra: &[&str]) -> Run {
    let prefix = dir.join(name);
    let t = dir.join(format!("{name}.csv"));
    // the plain carrier system: the sizes and coefficients compared are those of the data alone
    let mut args = vec![
        "fit",
        input.to_str().unwrap(),
        "--out",
        prefix.to_str().unwrap(),
        "--grid",
        "24",
        "--surface",
        "carrier",
    ];
    args.extend_from_slice(&["--timings", t.to_str().unwrap()]);
    args.extend_from_slice(extra);
    common::run_ok(ranks, &args);
    let model = read_model(&dir.join(format!("{name}.model.h5"))).unwrap();
    Run { model, prefix, timings: timings(&t) }
}

#[test]
fn sparse_solvers_match_the_dense_solve_of_the_same_system() {
    let dir = common::temp_dir("csrbf-fit");
    let input = dir.join("bunny1263.xyz");
    common::write_xyz(&input, &common::bunny_subset(4, 0));
    let w = ["--kernel", "wendland2", "--support", "0.15"];
    let dense = fit(&dir, &input, "dense", 0, &[&["--method", "dense"][..], &w].concat());
    let oracle = coefficients(&dense.model);
    assert_eq!(dense.model.spline.weights.len(), 1263);
    assert_eq!(figure(&dense.timings, "method"), "dense");

    let csrbf = [&["--method", "csrbf"][..], &w].concat();
    let chol = fit(&dir, &input, "cholesky", 0, &[&csrbf[..], &["--sparse-solver", "cholesky"]].concat());
    let env = fit(&dir, &input, "envelope", 0, &[&csrbf[..], &["--sparse-solver", "envelope"]].concat());
    for (name, run) in [("cholesky", &chol), ("envelope", &env)] {
        let d = common::rel_diff(&coefficients(&run.model), &oracle);
        assert!(d < 1e-10, "{name} vs the dense solve: {d:e}");
        assert_eq!(run.model.spline.kernel, dense.model.spline.kernel);
        let t = &run.timings;
        assert_eq!(figure(t, "method"), "csrbf");
        assert_eq!(figure(t, "sparse_solver"), name);
        assert!(figure(t, "tree_nodes").parse::<usize>().unwrap() > 100);
        assert!(figure(t, "tree_levels").parse::<usize>().unwrap() >= 3);
        let per_row: f64 = figure(t, "nnz_row_mean").parse().unwrap();
        assert!(per_row > 5.0 && per_row < 400.0, "{per_row}");
        let stored: f64 = figure(t, "stored_entries").parse().unwrap();
        assert!(stored > 1263.0 && stored < 1263.0 * 1263.0 / 2.0, "{stored}");
        let rms: f64 = figure(t, "rms_at_points").parse().unwrap();
        assert!(rms < 1e-9, "rms at the data {rms}");
        assert!(figure(t, "residual").parse::<f64>().unwrap() < 1e-12);
    }
    // the envelope keeps more than the supernodal factor with its fill-reducing ordering
    let stored = |r: &Run| figure(&r.timings, "stored_entries").parse::<f64>().unwrap();
    assert!(stored(&env) > stored(&chol));

    // MUMPS across ranks: the same coefficients
    for ranks in [2, 3] {
        let run = fit(&dir, &input, &format!("mumps{ranks}"), ranks, &csrbf);
        assert_eq!(figure(&run.timings, "sparse_solver"), "mumps");
        let d = common::rel_diff(&coefficients(&run.model), &oracle);
        assert!(d < 1e-9, "mumps on {ranks} ranks vs the dense solve: {d:e}");
        assert_eq!(run.model.provenance.ranks, ranks);
    }

    // eval of the saved compact model gives the fit's volume
    let p = chol.prefix.to_str().unwrap().to_string();
    let again = dir.join("again");
    common::run_ok(2, &["eval", &format!("{p}.model.h5"), "--out", again.to_str().unwrap(), "--grid", "24"]);
    let (g1, v1) = read_image(Path::new(&format!("{p}.hdf")), "f").unwrap();
    let (g2, v2) = read_image(&dir.join("again.hdf"), "f").unwrap();
    assert_eq!(g1.dims, g2.dims);
    assert!(common::rel_diff(&v2, &v1) < 1e-12);
}

#[test]
fn a_support_too_small_is_refused_and_auto_keeps_small_inputs_dense() {
    let dir = common::temp_dir("csrbf-bad");
    let input = dir.join("bunny.xyz");
    common::write_xyz(&input, &common::bunny_subset(8, 0));
    let prefix = dir.join("tiny");
    let args = |extra: &[&'static str]| -> Vec<String> {
        let head = ["fit", input.to_str().unwrap(), "--out", prefix.to_str().unwrap(), "--method", "csrbf"];
        head.iter().chain(extra).map(|a| a.to_string()).collect()
    };
    let run = |ranks, extra: &[&'static str]| {
        let a = args(extra);
        common::run(ranks, &a.iter().map(String::as_str).collect::<Vec<_>>())
    };
    for ranks in [0, 2] {
        let out = run(ranks, &["--support", "1e-4"]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{err}");
        assert!(err.contains("is too small") && err.contains("--support"), "{err}");
    }
    let out = run(0, &["--kernel", "r"]);
    assert_eq!(out.status.code(), Some(2), "{}", String::from_utf8_lossy(&out.stderr));
    let names: Vec<_> = std::fs::read_dir(&dir).unwrap().map(|e| e.unwrap().file_name()).collect();
    assert_eq!(names.len(), 1, "failed runs leave no output: {names:?}");

    let auto = fit(&dir, &input, "auto", 0, &[]);
    assert_eq!(figure(&auto.timings, "method"), "dense");
    assert_eq!(auto.model.spline.kernel.name(), "r");
}

#[test]
fn the_default_support_gives_every_point_of_an_unevenly_sampled_mesh_a_neighbour() {
    // the cow's vertices are sampled unevenly: at the median radius of 30 neighbours some vertex
    // is alone, which the fit refuses; the default grows the radius just enough
    let dir = common::temp_dir("csrbf-cow");
    let run = fit(&dir, Path::new(common::COW), "cow", 0, &["--method", "csrbf"]);
    let t = &run.timings;
    let support: f64 = figure(t, "support").parse().unwrap();
    assert!(support > 0.0 && support < 0.5, "{support}");
    assert!(figure(t, "rms_at_points").parse::<f64>().unwrap() < 1e-9);
    assert_eq!(run.model.spline.weights.len(), figure(t, "points").parse::<usize>().unwrap());
}

#[test]
fn a_scan_the_default_support_cannot_connect_is_refused_with_the_support_that_does() {
    // 2000 samples of the cow and one stray point 0.4 of the diagonal off its back, kept by
    // --drop-isolated off: the default support stops at 4 times the median radius, short of the
    // stray. The refusal came after level 0 of the two levels had been solved, as a usage error
    // of a --support never given, with no value to try; it now comes before level 0, names the
    // scan as the cause and the support that reaches every point, and that support fits
    let dir = common::temp_dir("csrbf-lonely");
    let input = dir.join("cow-stray.xyz");
    let text =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/cow-2000-seed3.xyz"))
            .unwrap();
    let mut pts: Vec<f64> = text.split_whitespace().map(|v| v.parse::<f64>().unwrap()).collect::<Vec<_>>();
    assert_eq!(pts.len(), 6000);
    let (lo, hi) = volspline::spline::hygiene::bounding_box(&pts, 3);
    let diag = volspline::spline::hygiene::diagonal(&lo, &hi);
    pts.extend_from_slice(&[0.5 * (lo[0] + hi[0]), hi[1] + 0.4 * diag, 0.5 * (lo[2] + hi[2])]);
    common::write_xyz(&input, &pts);
    let prefix = dir.join("o");
    let head = ["fit", input.to_str().unwrap(), "--out", prefix.to_str().unwrap(), "--method", "csrbf"];
    let tail = ["--drop-isolated", "off", "--grid", "16", "--coarse-points", "300", "--no-preview"];
    let mut suggested = Vec::new();
    for ranks in [0, 2] {
        let out = common::run(ranks, &[&head[..], &tail].concat());
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{err}");
        assert!(err.contains("the default support") && err.contains("is too small for this scan"), "{err}");
        assert!(err.contains("1 of the 2001 points has no other point within it"), "{err}");
        let value = err.split("use --support ").nth(1).and_then(|t| t.split(' ').next()).unwrap();
        suggested.push(value.to_string());
        assert!(!err.contains("panic"), "{err}");
    }
    assert_eq!(suggested[0], suggested[1], "the same support on one and two ranks");
    let names: Vec<_> = std::fs::read_dir(&dir).unwrap().map(|e| e.unwrap().file_name()).collect();
    assert_eq!(names.len(), 1, "refused runs leave no output: {names:?}");
    // the support named reaches the stray: the fit runs
    let text = common::run_ok(0, &[&head[..], &tail, &["--support", &suggested[0]]].concat());
    assert!(text.contains(&format!("kernel wendland2 (support {})", suggested[0])), "{text}");
    // a support the user gave that leaves the stray alone is a usage error naming the same fix
    let short = format!("{}", 0.9 * suggested[0].parse::<f64>().unwrap());
    let out = common::run(0, &[&head[..], &tail, &["--support", &short]].concat());
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains(&format!("support {short} is too small: 1 of the 2001 points")), "{err}");
    assert!(err.contains(&format!("use --support {} or larger", suggested[0])), "{err}");
}

#[test]
fn a_sparse_solver_of_one_rank_under_several_is_refused_before_the_input_is_read() {
    // with --method csrbf the method does not depend on the data: the refusal needs no input
    // (here a file that does not exist), where it came after reading and after level 0's solve
    let dir = common::temp_dir("csrbf-solver-ranks");
    let prefix = dir.join("o");
    let missing = dir.join("missing.xyz");
    for solver in ["cholesky", "envelope"] {
        let args = [
            "fit",
            missing.to_str().unwrap(),
            "--out",
            prefix.to_str().unwrap(),
            "--method",
            "csrbf",
            "--sparse-solver",
            solver,
        ];
        let out = common::run(2, &args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{err}");
        assert!(err.contains(&format!("--sparse-solver {solver} runs on one rank")), "{err}");
        assert!(!err.contains("missing.xyz"), "{err}");
    }
}

#[test]
fn the_sparse_factorisation_ticks_where_progress_is_drawn() {
    // faer and MUMPS report nothing while they factor (minutes at a million points), and no bar
    // was drawn between level 0's solve and the evaluation: under --progress on a line with the
    // time spent ticks on standard error and stays with the time the factor took; off, and auto
    // under mpirun (standard error a pipe), draw none
    let dir = common::temp_dir("csrbf-progress");
    let input = dir.join("bunny.xyz");
    common::write_xyz(&input, &common::bunny_subset(8, 0));
    let prefix = dir.join("o");
    for (ranks, mode, drawn) in [(2, "on", true), (0, "on", true), (2, "off", false), (2, "auto", false)] {
        let args = [
            "fit",
            input.to_str().unwrap(),
            "--out",
            prefix.to_str().unwrap(),
            "--method",
            "csrbf",
            "--surface",
            "carrier",
            "--grid",
            "16",
            "--no-preview",
            "--progress",
            mode,
        ];
        let out = common::run(ranks, &args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{err}");
        let ticked = err.lines().any(|l| l.contains("factor") && l.contains("elapsed, the sparse factor of"));
        assert_eq!(ticked, drawn, "--progress {mode} on {ranks} ranks:\n{err}");
        assert!(!String::from_utf8_lossy(&out.stdout).contains("elapsed"), "a line on standard output");
    }
}
