//! The real binary under `mpirun -n 1`, `-n 2` and `-n 3 --oversubscribe` on bunny points: the
//! model coefficients and the grid values agree with the serial oracle (every row-cyclic solver
//! with look-ahead too); `eval` reproduces `fit`;
//! bad input fails cleanly on every rank count; the Cholesky solver falls back to LU on every rank;
//! `--precision mixed` reaches the residual of f64, or falls back to f64 with its message.

mod common;

use std::path::Path;

use common::solve_serial;
use volspline::io::model_file::read_model;
use volspline::io::vtkhdf::read_image;
use volspline::linalg::dist::SolverKind;
use volspline::spline::hygiene::{prepare, Prepared};
use volspline::spline::{Carrier, Kernel, Model};

/// Every 20th bunny vertex (253 points), as [`bunny_every`]: the input of the oracle comparisons.
fn bunny253(dir: &Path) -> (std::path::PathBuf, Kernel, Prepared) {
    bunny_every(dir, 20)
}

/// Every `step`-th bunny vertex written to `dir`/bunny-STEP.xyz and prepared as the binary
/// prepares it (the points go through the .xyz text and back).
fn bunny_every(dir: &Path, step: usize) -> (std::path::PathBuf, Kernel, Prepared) {
    let input = dir.join(format!("bunny-{step}.xyz"));
    common::write_xyz(&input, &common::bunny_subset(step, 0));
    let k = Kernel::new(3, 2).unwrap();
    let read: Vec<f64> =
        volspline::io::points::read_points(&input).unwrap().points.iter().flatten().copied().collect();
    let prep = prepare(&read, &k, &Carrier::AutoBall, 1e-6).unwrap();
    (input, k, prep)
}

/// The serial oracle's model of `prep` solved by `solver`.
fn oracle_model(prep: &Prepared, k: &Kernel, solver: SolverKind) -> Model {
    Model {
        carrier: prep.carrier.clone(),
        spline: solve_serial(prep, k, solver),
        coarse: Vec::new(),
        provenance: Default::default(),
    }
}

/// Fits `input` on `ranks` ranks with the carrier method, panel 16 (unless `extra` gives one) and
/// grid 20 (panels of 16 over 257 rows: many panels, rows and blocks of each on every rank), plus
/// `extra`; checks the model's weights, residual and grid values against `oracle` and returns the
/// model and the report.
fn fit_like_the_oracle(
    ranks: usize,
    input: &Path,
    prefix: &Path,
    extra: &[&str],
    oracle: &Model,
    what: &str,
) -> (Model, String) {
    let p = prefix.to_str().unwrap();
    let args = ["fit", input.to_str().unwrap(), "--out", p, "--grid", "20", "--surface", "carrier"];
    let panel: &[&str] = if extra.contains(&"--panel") { &[] } else { &["--panel", "16"] };
    let out = common::run_ok(ranks, &[&args[..], panel, extra].concat());
    let model = read_model(Path::new(&format!("{p}.model.h5"))).unwrap();
    let dw = common::rel_diff(&model.spline.weights, &oracle.spline.weights);
    let dc = common::rel_diff(&model.spline.poly, &oracle.spline.poly);
    assert!(dw < 1e-9 && dc < 1e-9, "{what}: weights {dw:e}, poly {dc:e}");
    assert!(model.provenance.residual < 1e-10, "{what}: residual {}", model.provenance.residual);
    let dv = common::volume_diff(Path::new(&format!("{p}.hdf")), oracle);
    assert!(dv < 1e-9, "{what}: grid values differ by {dv:e}");
    (model, out)
}

#[test]
fn distributed_runs_match_the_serial_oracle() {
    let dir = common::temp_dir("oracle");
    let (input, k, prep) = bunny253(&dir);
    for solver in [SolverKind::Householder, SolverKind::Lu, SolverKind::Cholesky] {
        let oracle = oracle_model(&prep, &k, solver);
        for ranks in [1, 2, 3] {
            let prefix = dir.join(format!("{}-{ranks}", solver.name()));
            let what = format!("{solver:?} on {ranks} ranks");
            let (model, _) =
                fit_like_the_oracle(ranks, &input, &prefix, &["--solver", solver.name()], &oracle, &what);
            assert_eq!(model.spline.len(), 253);
            assert_eq!(model.provenance.ranks, ranks);
            // no temporary files are left behind
            let left = std::fs::read_dir(&dir)
                .unwrap()
                .filter(|e| e.as_ref().unwrap().file_name().to_string_lossy().ends_with(".partial"));
            assert_eq!(left.count(), 0, "temporary files left in {}", dir.display());
        }
        // with look-ahead: the same model, and the report says so
        for ranks in [2, 3] {
            let prefix = dir.join(format!("{}-{ranks}-lookahead", solver.name()));
            let what = format!("{solver:?} on {ranks} ranks with look-ahead");
            let extra = ["--solver", solver.name(), "--lookahead", "on"];
            let (_, out) = fit_like_the_oracle(ranks, &input, &prefix, &extra, &oracle, &what);
            let line = format!("solver {} (dense, row-cyclic), panel 16, look-ahead on", solver.name());
            assert!(out.contains(&line), "{what}: {out}");
        }
        // the local products by either engine, each named in the report: the same model
        for ranks in [2, 3] {
            for (engine, named) in [("blas", "products BLAS ("), ("faer", "products faer")] {
                let prefix = dir.join(format!("{}-{ranks}-{engine}", solver.name()));
                let what = format!("{solver:?} on {ranks} ranks, products by {engine}");
                let extra = ["--solver", solver.name(), "--gemm", engine, "--threads", "1"];
                let (_, out) = fit_like_the_oracle(ranks, &input, &prefix, &extra, &oracle, &what);
                assert!(out.contains(named), "{what}: {out}");
            }
        }
    }
}

/// From 4 ranks on, the row-cyclic LU and Householder solve their block rows (U12, T^T W) in
/// column shares, one a rank: on 4 ranks with panels of 64 over about 640 rows (the first panels'
/// blocks large enough to be shared), with and without look-ahead, the same model as the serial
/// oracles'.
#[test]
fn four_ranks_share_the_block_row_solves_and_match_the_serial_oracle() {
    let dir = common::temp_dir("oracle-shared");
    let (input, k, prep) = bunny_every(&dir, 8);
    assert!(prep.values.len() > 600, "{} points", prep.values.len());
    for solver in [SolverKind::Householder, SolverKind::Lu] {
        let oracle = oracle_model(&prep, &k, solver);
        for lookahead in ["off", "on"] {
            let prefix = dir.join(format!("{}-{lookahead}", solver.name()));
            let what = format!("{solver:?} on 4 ranks, look-ahead {lookahead}");
            let extra = [
                "--solver",
                solver.name(),
                "--layout",
                "row-cyclic",
                "--panel",
                "64",
                "--lookahead",
                lookahead,
            ];
            let (model, out) = fit_like_the_oracle(4, &input, &prefix, &extra, &oracle, &what);
            assert_eq!(model.provenance.ranks, 4);
            assert!(out.contains("(dense, row-cyclic), panel 64"), "{what}: {out}");
        }
    }
}

#[test]
fn eval_reproduces_the_fit_grid_and_mesh_exactly() {
    let dir = common::temp_dir("eval");
    let input = dir.join("bunny.xyz");
    common::write_xyz(&input, &common::bunny_subset(10, 4));
    let fit = dir.join("fit");
    let csv = dir.join("fit.csv");
    let out = common::run_ok(
        2,
        &[
            "fit",
            input.to_str().unwrap(),
            "--out",
            fit.to_str().unwrap(),
            "--grid",
            "40",
            "--timings",
            csv.to_str().unwrap(),
        ],
    );
    // the --timings record: key,value lines with the run's figures
    let rec = std::fs::read_to_string(&csv).unwrap();
    let get = |k: &str| rec.lines().find_map(|l| l.strip_prefix(&format!("{k},"))).map(String::from);
    assert_eq!(get("ranks").as_deref(), Some("2"));
    // 505 points, their off-surface points (the default 0.5 per point where the normal is
    // trusted, 0.2 elsewhere, more where most normals are doubtful: here about 77 % are), the
    // constraint points of the second fit against spurious blobs, and 4 polynomial terms
    let blobs: usize = get("blob_points").unwrap().parse().unwrap();
    // the cap binds the first round; a second round kept adds its own points
    let second: usize = match get("second_round_kept").as_deref() {
        Some("true") => get("second_round_points").unwrap().parse().unwrap(),
        _ => 0,
    };
    let cap = (505 / 4).max(volspline::surface::blobs::MIN_CAP);
    assert!(
        blobs > 0 && blobs - second <= cap,
        "{blobs} blob points ({second} of a second round), cap {cap}"
    );
    let off: usize = get("off_points").unwrap().parse().unwrap();
    let doubtful: usize = get("off_doubtful_normals").unwrap().parse().unwrap();
    let share: f64 = get("off_doubtful_share").unwrap().parse().unwrap();
    assert_eq!(share, volspline::surface::doubtful_share_in_effect(0.4, doubtful, 505));
    // each point's off point is a draw (dealt among neighbours): the count within three standard
    // deviations of the sum of the rates
    let (trusted, doubted) = (0.5, 0.5 * share);
    let want = trusted * (505 - doubtful) as f64 + doubted * doubtful as f64;
    let var =
        trusted * (1.0 - trusted) * (505 - doubtful) as f64 + doubted * (1.0 - doubted) * doubtful as f64;
    assert!(
        (off as f64 - want).abs() <= 3.0 * var.sqrt() + 2.0,
        "{off} off points, {doubtful} doubtful normals, want {want}"
    );
    // the outside off points after the turns, where their fit was kept, are appended last
    let outside: usize = match get("outside_kept").as_deref() {
        Some("true") => get("outside_points").unwrap().parse().unwrap(),
        _ => 0,
    };
    // and the off points at the mouths of holes after them
    let mouth: usize = get("mouth_points").map_or(0, |m| m.parse().unwrap());
    assert_eq!(get("system_size"), Some((505 + off + 4 + blobs + outside + mouth).to_string()));
    assert_eq!(get("solver").as_deref(), Some("cholesky")); // auto, from 100 rows
    assert!(get("residual").unwrap().parse::<f64>().unwrap() < 1e-10);
    assert!(get("stage_solve_max_s").unwrap().parse::<f64>().unwrap() > 0.0);
    assert!(out.contains("fit.model.h5") && out.contains("fit.hdf") && out.contains("fit.ply"), "{out}");
    for ranks in [1, 3] {
        let ev = dir.join(format!("eval{ranks}"));
        let model = format!("{}.model.h5", fit.display());
        common::run_ok(ranks, &["eval", &model, "--out", ev.to_str().unwrap(), "--grid", "40"]);
        let (g1, v1) = read_image(&dir.join("fit.hdf"), "f").unwrap();
        let (g2, v2) = read_image(&dir.join(format!("eval{ranks}.hdf")), "f").unwrap();
        assert_eq!(g1, g2);
        assert_eq!(v1, v2, "eval on {ranks} ranks must reproduce fit's grid bit for bit");
        let m1 = std::fs::read(dir.join("fit.ply")).unwrap();
        let m2 = std::fs::read(dir.join(format!("eval{ranks}.ply"))).unwrap();
        assert!(m1.len() > 1000);
        assert_eq!(m1, m2, "the welded mesh must not depend on the number of ranks");
    }
    // a different box re-evaluates the same function elsewhere
    let ev = dir.join("box");
    let model = format!("{}.model.h5", fit.display());
    common::run_ok(
        2,
        &["eval", &model, "--out", ev.to_str().unwrap(), "--grid", "5,6,7", "--bounds", "-5,4,-3,3,15,4"],
    );
    let (g, v) = read_image(&dir.join("box.hdf"), "f").unwrap();
    assert_eq!(g.dims, [5, 6, 7]);
    let m = read_model(Path::new(&model)).unwrap();
    assert!((v[0] - m.eval(&[-5.0, 4.0, -3.0])).abs() < 1e-12 * v[0].abs().max(1.0));
    assert!((v[v.len() - 1] - m.eval(&[3.0, 15.0, 4.0])).abs() < 1e-12 * v[v.len() - 1].abs().max(1.0));
}

#[test]
fn cholesky_falls_back_to_lu_on_every_rank_count() {
    // 4 points give N = 4 = k polynomial terms: the projected block is empty, never definite. Every
    // rank must take the fallback (were the agreed error to lose its kind on ranks other than the
    // first, rank 0 alone would fall back and the job would hang or fail).
    let dir = common::temp_dir("fallback");
    let input = dir.join("four.xyz");
    let raw = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];
    common::write_xyz(&input, &raw);
    let k = Kernel::new(3, 2).unwrap();
    let prep = prepare(&raw, &k, &Carrier::AutoBall, 1e-6).unwrap();
    let oracle = solve_serial(&prep, &k, SolverKind::Lu);
    let mut first: Option<Model> = None;
    for ranks in [1, 2, 3] {
        let prefix = dir.join(format!("four-{ranks}"));
        let p = prefix.to_str().unwrap();
        let args = ["fit", input.to_str().unwrap(), "--out", p, "--solver", "cholesky", "--grid", "12"];
        let out = common::run(ranks, &args);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{ranks} ranks: {}\n{stderr}", out.status);
        assert!(stderr.contains("fell back to LU"), "{ranks} ranks: no fallback message:\n{stderr}");
        let model = read_model(&dir.join(format!("{p}.model.h5"))).unwrap();
        assert_eq!(model.provenance.solver, "lu", "{ranks} ranks");
        assert_eq!(model.provenance.ranks, ranks);
        // the weights vanish (N = k: the moment conditions force lambda = 0), so compare the whole
        // coefficient vector against its largest entry
        let coef = |s: &volspline::spline::Spline| [s.weights.clone(), s.poly.clone()].concat();
        let d = common::rel_diff(&coef(&model.spline), &coef(&oracle));
        assert!(d < 1e-9, "{ranks} ranks vs the dense LU: coefficients differ by {d:e}");
        match &first {
            None => first = Some(model),
            Some(one) => {
                let d = common::rel_diff(&coef(&model.spline), &coef(&one.spline));
                assert!(d < 1e-12, "{ranks} ranks vs 1 rank: coefficients differ by {d:e}");
            }
        }
    }
}

fn assert_fails(ranks: usize, args: &[&str], code: i32, needles: &[&str]) {
    let out = common::run(ranks, args);
    let text = format!("{}{}", String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
    assert!(!out.status.success(), "{args:?} should fail:\n{text}");
    if ranks == 0 {
        assert_eq!(out.status.code(), Some(code), "{text}");
    }
    for n in needles {
        assert!(text.contains(n), "{args:?}: expected '{n}' in:\n{text}");
    }
    assert!(!text.contains("panicked"), "{text}");
}

#[test]
fn bad_input_fails_cleanly_on_every_rank_count() {
    let dir = common::temp_dir("errors");
    let nan = dir.join("nan.xyz");
    std::fs::write(&nan, "0 0 0\n1 0 0\n0 1 0\n0 0 nan\n1 1 1\n").unwrap();
    let flat = dir.join("flat.xyz");
    std::fs::write(&flat, "0 0 0\n1 0 0\n0 1 0\n1 1 0\n2 3 0\n").unwrap();
    let prefix = dir.join("out");
    let p = prefix.to_str().unwrap();
    for ranks in [0, 1, 2, 3] {
        assert_fails(
            ranks,
            &["fit", dir.join("missing.obj").to_str().unwrap(), "--out", p],
            1,
            &["missing.obj"],
        );
        assert_fails(ranks, &["fit", nan.to_str().unwrap(), "--out", p], 1, &["nan.xyz", "line 4"]);
        assert_fails(ranks, &["fit", flat.to_str().unwrap(), "--out", p], 1, &["plane"]);
        assert_fails(
            ranks,
            &["fit", nan.to_str().unwrap(), "--out", p, "--carrier", "cube:1"],
            2,
            &["unknown carrier"],
        );
        assert_fails(ranks, &["fit", nan.to_str().unwrap(), "--out", p, "--grid", "1"], 2, &["grid"]);
        assert_fails(ranks, &["eval", nan.to_str().unwrap(), "--out", p], 1, &["nan.xyz"]);
        // an output folder that does not exist: HDF5 cannot create the file
        let input = common::BUNNY;
        assert_fails(
            ranks,
            &["fit", input, "--out", dir.join("no/such/dir/x").to_str().unwrap(), "--grid", "8"],
            1,
            &["no/such/dir"],
        );
    }
    let left: Vec<_> = std::fs::read_dir(&dir).unwrap().map(|e| e.unwrap().file_name()).collect();
    assert_eq!(left.len(), 2, "failed runs must leave no output files: {left:?}");
}

#[test]
fn help_documents_every_option_with_its_default() {
    let out = common::run_ok(0, &["fit", "--help"]);
    for needle in [
        "--carrier",
        "[default: auto]",
        "--kernel",
        "--method",
        "--support",
        "--leaf",
        "[default: 10]",
        "--sparse-solver",
        "--solver",
        "[default: auto]",
        "--grid",
        "[default: 64]",
        "--margin <auto|F>",
        "--panel",
        "--layout",
        "--layout <auto|row-cyclic|2d|PRxPC>",
        "--off-points",
        "[default: 0.5]",
        "--doubtful-share",
        "[default: 0.4]",
        "--lookahead",
        "--gemm <auto|blas|faer>",
        "--threads",
        "--merge-tol",
    ] {
        assert!(out.contains(needle), "fit --help lacks '{needle}':\n{out}");
    }
    let out = common::run_ok(0, &["eval", "--help"]);
    for needle in ["--bounds", "--grid", "--out"] {
        assert!(out.contains(needle), "eval --help lacks '{needle}':\n{out}");
    }
}

#[test]
fn mixed_precision_reaches_the_f64_residual_or_falls_back() {
    let dir = common::temp_dir("mixed");
    // 2000 bunny points, with their off-surface and blob constraint points
    let bunny: Vec<f64> = common::bunny_subset(2, 0).into_iter().take(6000).collect();
    // the same with every 4th point again 1e-5 of the box diagonal (25) away: singular in f32
    let mut near = bunny.clone();
    near.extend(bunny.chunks(3).step_by(4).flat_map(|p| [p[0] + 2.5e-4, p[1], p[2]]));
    let fit = |name: &str, pts: &[f64], ranks: usize, precision: &str, solver: &str| {
        let input = dir.join(format!("{name}.xyz"));
        common::write_xyz(&input, pts);
        let out = dir.join(format!("{name}-{precision}-{solver}-{ranks}"));
        let csv = dir.join(format!("{name}-{precision}-{solver}-{ranks}.csv"));
        let args = [
            "fit",
            input.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--solver",
            solver,
            "--precision",
            precision,
            "--merge-tol",
            "1e-12",
            "--grid",
            "8",
            "--timings",
            csv.to_str().unwrap(),
            // the residuals' bounds were measured with the fitted ball as the carrier
            "--carrier",
            "ball",
        ];
        let text = common::run_ok(ranks, &args);
        let rec = std::fs::read_to_string(&csv).unwrap();
        let get = move |k: &str| {
            rec.lines().find_map(|l| l.strip_prefix(&format!("{k},"))).unwrap_or("").to_string()
        };
        (text, get("residual").parse::<f64>().unwrap(), get)
    };
    // the default solver (auto: the projected Cholesky at this size) factors in f32 by the
    // projected Cholesky, --solver lu by LU
    for (solver, factor) in [("auto", "cholesky"), ("lu", "lu")] {
        let (_, f64_residual, _) = fit("bunny", &bunny, 1, "f64", solver);
        assert!(f64_residual < 1e-13, "{solver}: f64 residual {f64_residual:e}");
        for ranks in [1, 2] {
            let (text, residual, get) = fit("bunny", &bunny, ranks, "mixed", solver);
            assert_eq!(get("precision"), "mixed", "{text}");
            assert_eq!(get("solver"), factor, "{text}");
            assert_eq!(get("precision_fallback"), "false", "{text}");
            assert!(get("refinement_classical").parse::<usize>().unwrap() >= 1, "{text}");
            assert!(
                text.contains(&format!("precision mixed (f32 {factor}, f64 refinement)"))
                    && text.contains("refinement: "),
                "{text}"
            );
            // the f64 path's residual, to within the rounding of the residual itself
            assert!(
                residual < 3.0 * f64_residual,
                "{solver}, {ranks} ranks: mixed {residual:e}, f64 {f64_residual:e}"
            );
        }
    }
    let (_, near_f64, _) = fit("near", &near, 2, "f64", "lu");
    let (text, residual, get) = fit("near", &near, 2, "mixed", "lu");
    assert_eq!(get("precision"), "f64", "{text}");
    assert_eq!(get("precision_fallback"), "true", "{text}");
    assert!(
        text.contains("precision mixed fell back to f64: the single-precision factorisation failed"),
        "{text}"
    );
    assert!(text.contains("volspline: precision mixed: "), "the message on stderr: {text}");
    assert_eq!(residual, near_f64, "the fallback is the f64 solve");
}

#[test]
fn the_2d_layout_matches_the_serial_oracles_and_refuses_what_it_cannot_do() {
    let dir = common::temp_dir("layout2d");
    let (input, k, prep) = bunny253(&dir);
    for solver in [SolverKind::Lu, SolverKind::Cholesky, SolverKind::Householder] {
        let oracle = oracle_model(&prep, &k, solver);
        for (ranks, layout, shape) in
            [(0, "2d", "1x1"), (2, "1x2", "1x2"), (2, "2x1", "2x1"), (3, "2d", "1x3"), (4, "2x2", "2x2")]
        {
            let prefix = dir.join(format!("{}-{ranks}-{layout}", solver.name()));
            let what = format!("{} {layout} on {ranks} ranks", solver.name());
            let extra = ["--layout", layout, "--solver", solver.name()];
            let (_, out) = fit_like_the_oracle(ranks, &input, &prefix, &extra, &oracle, &what);
            let line = format!("solver {} (dense, 2D block-cyclic {shape}), panel 16", solver.name());
            assert!(out.contains(&line), "{out}");
        }
    }
    let input = input.to_str().unwrap();
    let p = dir.join("refused");
    let p = p.to_str().unwrap();
    assert_fails(3, &["fit", input, "--out", p, "--layout", "2x2"], 2, &["needs 4 ranks, the job has 3"]);
    assert_fails(
        0,
        &["fit", input, "--out", p, "--layout", "1x1", "--precision", "mixed"],
        2,
        &["row-cyclic"],
    );
    assert_fails(0, &["fit", input, "--out", p, "--layout", "2by2"], 2, &["unknown layout '2by2'"]);
    let left = std::fs::read_dir(&dir)
        .unwrap()
        .filter(|e| e.as_ref().unwrap().file_name().to_string_lossy().starts_with("refused"))
        .count();
    assert_eq!(left, 0, "refused runs must leave no output");
}

#[test]
fn an_off_surface_fit_on_a_2d_grid_borders_its_factor_as_row_cyclic_does() {
    // the cow with a hole (tests/data/cow-1000-open.xyz, the off points dealt by index): its
    // second fits border the first fit's factor by 224 and by 303 appended centres, the last by
    // 318 (the 14 off points at the hole's rim and its cap point appended). On a 2D grid the
    // factor is moved to the row-cyclic layout and bordered there: the same second fits, none
    // factored anew, and the same spline as the serial row-cyclic fit
    let dir = common::temp_dir("layout-2d-bordered");
    let input = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/cow-1000-open.xyz");
    let fit = |ranks: usize, layout: &str| {
        let p = dir.join(format!("{layout}-{ranks}"));
        let args =
            ["fit", input.to_str().unwrap(), "--out", p.to_str().unwrap(), "--grid", "40", "--no-preview"];
        // the counts were measured with the off points dealt by index and the fitted ball
        let dealt = ["--off-deal", "index", "--carrier", "ball"];
        let out = common::run_ok(ranks, &[&args[..], &dealt, &["--layout", layout]].concat());
        let model = read_model(&p.with_extension("model.h5")).unwrap();
        (model, out, p.with_extension("hdf"))
    };
    let (serial, serial_out, _) = fit(1, "row-cyclic");
    let bordered = "bordered by 318 appended centres";
    let first = "second fit: the first fit's factor (1231 centres";
    assert!(serial_out.contains(&format!("{first}) {bordered}")), "{serial_out}");
    for (ranks, layout, grid) in [(1, "2d", "1x1"), (2, "2d", "1x2"), (2, "2x1", "2x1"), (3, "1x3", "1x3")] {
        let (model, out, hdf) = fit(ranks, layout);
        let what = format!("--layout {layout} on {ranks} ranks");
        assert!(out.contains(&format!("(dense, 2D block-cyclic {grid})")), "{what}:\n{out}");
        assert!(out.contains(bordered) && !out.contains("factoring the whole system"), "{what}:\n{out}");
        let moved = format!("{first}, moved from the process grid in ");
        assert!(out.contains(&moved), "{what}:\n{out}");
        assert_eq!(model.spline.weights.len(), serial.spline.weights.len(), "{what}");
        let dw = common::rel_diff(&model.spline.weights, &serial.spline.weights);
        let dc = common::rel_diff(&model.spline.poly, &serial.spline.poly);
        assert!(dw < 1e-8 && dc < 1e-8, "{what}: weights {dw:e}, poly {dc:e}");
        let dv = common::volume_diff(&hdf, &serial);
        assert!(dv < 1e-8, "{what}: grid values differ from the serial spline's by {dv:e}");
    }
}

#[test]
fn the_auto_layout_distributes_in_2d_on_sixteen_ranks_and_row_cyclic_below() {
    // every second bunny vertex: 2526 points, above the 2000 rows from which auto takes 2D
    let dir = common::temp_dir("layout-auto");
    let (input, k, prep) = bunny_every(&dir, 2);
    assert!(prep.values.len() >= 2000, "{} points", prep.values.len());
    let oracle = oracle_model(&prep, &k, SolverKind::Cholesky);
    // 16 ranks (oversubscribed here): the 4x4 grid, the same spline as the serial oracle's; on 3
    // ranks, row-cyclic; an off-surface fit on 16 ranks takes the 4x4 grid too (its factor is moved
    // to the row-cyclic layout for the second fits)
    for (ranks, surface, expect) in [
        (16, "carrier", "solver cholesky (dense, 2D block-cyclic 4x4), panel 16"),
        (3, "carrier", "solver cholesky (dense, row-cyclic), panel 16"),
    ] {
        let prefix = dir.join(format!("auto-{ranks}-{surface}"));
        let what = format!("--layout auto on {ranks} ranks, {surface}");
        let extra = ["--layout", "auto", "--solver", "cholesky", "--no-preview"];
        let (model, out) = fit_like_the_oracle(ranks, &input, &prefix, &extra, &oracle, &what);
        assert!(out.contains(expect), "{what}:\n{out}");
        assert_eq!(model.spline.weights.len(), prep.values.len());
    }
    let p = dir.join("auto-16-offsurface");
    let args = [
        "fit",
        input.to_str().unwrap(),
        "--out",
        p.to_str().unwrap(),
        "--grid",
        "20",
        "--no-preview",
        "--blob-choice",
        "off",
        "--orient-rays",
        "off",
    ];
    let out = common::run_ok(16, &args);
    assert!(out.contains("surface offsurface"), "{out}");
    assert!(out.contains("(dense, 2D block-cyclic 4x4)"), "an off-surface fit takes the 2D grid too:\n{out}");
}
