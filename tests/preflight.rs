//! Runs that cannot finish are refused before the heavy work, with the figures and what to do, on
//! every rank count, and leave no output: a dense system larger than the memory (a densely
//! resampled bunny, `--method dense`), a grid larger than the memory, an output prefix that names a directory or a
//! missing one, an absurd thread count. The user's `--memory-per-rank` decides those checks, the
//! method `auto` takes and whether a 2D factor is kept for the second fits (the fit is the same).

mod common;

use std::path::Path;

use volspline::io::model_file::read_model;

/// `per_face` points on each bunny triangle (barycentric lattice), 3 values per point.
fn resampled_bunny(per_face: usize) -> Vec<f64> {
    let mesh = common::load_mesh(Path::new(common::BUNNY));
    let mut pts = Vec::new();
    for t in &mesh.triangles {
        let [a, b, c] = t.map(|i| mesh.vertices[i as usize]);
        for s in 0..per_face {
            let u = ((s * 7919) % 97) as f64 / 97.0;
            let v = ((s * 104_729) % 89) as f64 / 89.0 * (1.0 - u);
            pts.extend((0..3).map(|d| a[d] + u * (b[d] - a[d]) + v * (c[d] - a[d])));
        }
    }
    pts
}

fn files_in(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

#[test]
fn a_system_too_large_for_memory_is_refused_before_assembly() {
    let dir = common::temp_dir("preflight-dense");
    let input = dir.join("bunny150k.xyz");
    let pts = resampled_bunny(15);
    assert!(pts.len() / 3 > 140_000);
    common::write_xyz(&input, &pts);
    for ranks in [1, 2] {
        let prefix = dir.join(format!("big{ranks}"));
        let args = ["fit", input.to_str().unwrap(), "--out", prefix.to_str().unwrap(), "--method", "dense"];
        let out = common::run(ranks, &args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{err}");
        assert!(err.contains("not enough memory: the dense system of"), "{err}");
        assert!(err.contains("GB per rank") && err.contains("use --method csrbf"), "{err}");
        assert!(!err.contains("panic"), "{err}");
    }
    assert_eq!(files_in(&dir), ["bunny150k.xyz"]);
}

#[test]
fn a_grid_too_large_and_bad_prefixes_are_refused_with_reasons() {
    let dir = common::temp_dir("preflight-grid");
    let input = dir.join("bunny.xyz");
    common::write_xyz(&input, &common::bunny_subset(25, 0));
    let i = input.to_str().unwrap();
    let p = dir.join("o");
    let missing = dir.join("missing/o");
    let cases: [(&[&str], i32, &str); 5] = [
        (&["fit", i, "--out", p.to_str().unwrap(), "--grid", "4000"], 1, "not enough memory: the grid of"),
        // the dense system fits 300 MB, a slab of the grid of 400 nodes does not
        (
            &["fit", i, "--out", p.to_str().unwrap(), "--grid", "400", "--memory-per-rank", "300MB"],
            1,
            "(--memory-per-rank); use a coarser --grid",
        ),
        (&["fit", i, "--out", dir.to_str().unwrap()], 2, "expected a file prefix"),
        (&["fit", i, "--out", missing.to_str().unwrap()], 1, "the output directory does not exist"),
        (&["fit", i, "--out", p.to_str().unwrap(), "--threads", "20000"], 2, "at most 1024"),
    ];
    for ranks in [1, 2] {
        for (args, code, message) in &cases {
            let out = common::run(ranks, args);
            let err = String::from_utf8_lossy(&out.stderr);
            assert_eq!(out.status.code(), Some(*code), "{args:?} on {ranks}: {err}");
            assert!(err.contains(message), "{args:?} on {ranks}: {err}");
        }
    }
    assert_eq!(files_in(&dir), ["bunny.xyz"]);
}

/// The bytes per rank the checks count for a dense off-surface fit of `rows` rows on `ranks`
/// ranks (the projected Cholesky's lower triangle, its default panel).
fn dense_bytes(rows: usize, ranks: usize) -> f64 {
    dense_bytes_with(rows, ranks, volspline::linalg::dist::SolverKind::Auto.widest_default_panel(rows))
}

/// [`dense_bytes`] with panels `panel` wide.
fn dense_bytes_with(rows: usize, ranks: usize, panel: usize) -> f64 {
    volspline::app::preflight::dense_fit_bytes(
        rows,
        ranks,
        volspline::linalg::dist::Precision::F64,
        true,
        panel,
    )
}

/// The off points dealt by index: the tests below count rows, which the dealing among neighbours
/// (the default) draws only in expectation.
const BY_INDEX: [&str; 2] = ["--off-deal", "index"];

/// `--memory-per-rank` bytes, as the option takes them.
fn megabytes(bytes: f64) -> String {
    format!("{:.1}MB", bytes / 1e6)
}

#[test]
fn the_memory_per_rank_the_user_sets_decides_the_checks_and_the_method() {
    // the cow with a hole: 896 points, 335 off points dealt by index (BY_INDEX) in the dense fit
    // (1235 rows); the checks
    // count the lower triangle, the panels' buffers and 200 MB of fixed part per rank, so
    // 225 MB on one rank
    let dir = common::temp_dir("preflight-limit");
    let input = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/cow-1000-open.xyz");
    let i = input.to_str().unwrap();
    let p = dir.join("o");
    let o = p.to_str().unwrap();
    for ranks in [1, 2] {
        // too little for the dense system: refused before the assembly, saying whose limit it is
        // and what the need is made of; `auto` takes the two levels for it, whose grid does not
        // fit either (the fixed part alone is more)
        let mb = |b: f64| (b / 1e6).round();
        let parts = format!(
            "not enough memory: the dense system of 1235 rows (1231 points; per rank its rows {} MB, the \
             solver's panels {} MB and 200 MB for the libraries and MPI's buffers) needs about",
            mb(volspline::app::preflight::dense_matrix_bytes(
                1235,
                ranks,
                volspline::linalg::dist::Precision::F64,
                true
            )),
            mb(volspline::app::preflight::panel_bytes(1235, ranks, 256)),
        );
        let cases: [(&[&str], &str); 2] =
            [(&["--method", "dense"], &parts), (&[], "not enough memory: the grid of")];
        for (extra, message) in cases {
            let args = [&["fit", i, "--out", o, "--memory-per-rank", "150MB"][..], &BY_INDEX, extra].concat();
            let out = common::run(ranks, &args);
            let err = String::from_utf8_lossy(&out.stderr);
            assert_eq!(out.status.code(), Some(1), "{args:?} on {ranks}: {err}");
            assert!(err.contains(message), "{args:?} on {ranks}: {err}");
            assert!(
                err.contains("this rank can have 150 MB (--memory-per-rank)"),
                "{args:?} on {ranks}: {err}"
            );
            assert_eq!(files_in(&dir), Vec::<String>::new(), "{args:?} on {ranks}");
        }
    }
    // `auto` chooses by the limit: with room for level 0 (300 points and their off points) but
    // not for the dense system of all points with theirs (at most 896 + 448 + 4 rows), the two
    // levels; without the limit, dense
    let most = dense_bytes(896 + 448 + 4, 1);
    let level0 = dense_bytes(300 + 150 + 4, 1);
    assert!(most - level0 > 8e6, "{most} vs {level0}");
    assert!((most - 228.0e6).abs() < 0.1e6, "{most}");
    let limit = megabytes(most - 2e6);
    let args = [
        "fit",
        i,
        "--out",
        o,
        "--grid",
        "32",
        "--no-preview",
        "--coarse-points",
        "300",
        BY_INDEX[0],
        BY_INDEX[1],
    ];
    let text = common::run_ok(1, &[&args[..], &["--memory-per-rank", &limit]].concat());
    assert!(text.contains("method csrbf (auto: the dense system would need 0.2 GB per rank"), "{text}");
    assert!(
        text.contains("two levels: level 0 dense (kernel r") && text.contains("on 300 of the points"),
        "{text}"
    );
    let csv = dir.join("t.csv");
    let text = common::run_ok(1, &[&args[..], &["--timings", csv.to_str().unwrap()]].concat());
    assert!(text.contains("method dense (auto: the dense system fits"), "{text}");
    // the report sets the largest estimate a check counted beside the measured peak: at least
    // the first fit's dense system, and above the peak (the estimates are meant to be safe)
    let figures = std::fs::read_to_string(&csv).unwrap();
    let get = |k: &str| -> f64 {
        let line = figures.lines().find(|l| l.starts_with(&format!("{k},"))).unwrap_or_else(|| panic!("{k}"));
        line[k.len() + 1..].parse().unwrap()
    };
    let (estimate, peak) = (get("memory_estimate_bytes_max"), get("peak_rss_bytes_max"));
    assert!(estimate >= dense_bytes(1235, 1) && estimate > peak, "estimate {estimate}, peak {peak}");
    assert!(text.contains(&format!("(the memory checks counted up to {:.1} MB)", estimate / 1e6)), "{text}");
}

#[test]
fn a_2d_factor_without_room_for_its_copy_is_not_kept_and_the_fit_is_the_same() {
    // the cow with a hole on a process grid: the first fit (1235 rows) keeps its factor for the
    // second fits by moving it to the row-cyclic layout, a second copy of its lower triangle.
    // With a limit that takes the largest fresh second fit (1231 + 303 centres) but not the
    // two copies, the factor is not kept, the second fits factor their systems anew, the turns
    // and the outside points are skipped (none kept with the factor either), and the spline is
    // the same
    let dir = common::temp_dir("preflight-no-copy");
    let input = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/cow-1000-open.xyz");
    for (ranks, layout) in [(1, "2d"), (2, "1x2")] {
        // (narrow panels: with the default ones their buffers make a fresh fit of 1538 rows
        // need more than two copies of the factor of 1235)
        let held = volspline::app::preflight::dense_matrix_bytes(
            1235,
            ranks,
            volspline::linalg::dist::Precision::F64,
            true,
        );
        let (fresh, both) = (dense_bytes_with(1538, ranks, 8), 2.0 * held + 200e6);
        assert!(both - fresh > 2e6, "{fresh} vs {both}");
        let limit = megabytes((fresh + both) / 2.0);
        let fit_with = |name: &str, limit: Option<&str>, extra: &[&str]| {
            let p = dir.join(format!("{name}-{ranks}"));
            let mut args = vec![
                "fit",
                input.to_str().unwrap(),
                "--out",
                p.to_str().unwrap(),
                "--grid",
                "40",
                "--no-preview",
                "--layout",
                layout,
                "--panel",
                "8",
            ];
            args.extend(limit.iter().flat_map(|l| ["--memory-per-rank", l]));
            args.extend(extra);
            let out = common::run(ranks, &args);
            let text =
                format!("{}{}", String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
            assert!(out.status.success(), "{args:?}: {text}");
            (read_model(&p.with_extension("model.h5")).unwrap(), text, p.with_extension("hdf"))
        };
        // without the mouth points, which the kept factor lets the first fit add and the fit
        // anew skips (compared below)
        let fit = |name: &str, limit: Option<&str>| fit_with(name, limit, &["--mouth-points", "off"]);
        let (kept, kept_text, _) = fit("kept", None);
        assert!(kept_text.contains("moved from the process grid in"), "{kept_text}");
        // the turns ran with the kept factor: one try solved, three passed over without a solve
        assert!(kept_text.contains("turns: 0 of 1 patches tried"), "{kept_text}");
        assert!(kept_text.contains("3 of 4 candidates passed over without a solve"), "{kept_text}");
        let (anew, text, hdf) = fit("anew", Some(&limit));
        let what = format!("{layout} on {ranks} ranks, --memory-per-rank {limit}");
        assert!(text.contains("the 2D factor is not kept for later fits"), "{what}: {text}");
        assert!(
            !text.contains("moved from the process grid") && !text.contains("bordered by"),
            "{what}: {text}"
        );
        assert!(
            text.contains(
                "turns and outside points: skipped (no factor kept to fit them with), fitted 4 times"
            ),
            "{what}: {text}"
        );
        // with the turns off, the outside points are said to be skipped on their own
        let (_, text, _) = fit_with("anew-no-turns", Some(&limit), &["--orient-turns", "off"]);
        assert!(
            text.contains("; outside points: skipped (no factor kept to fit them with)"),
            "{what}: {text}"
        );
        assert!(!text.contains("; turns"), "{what}: {text}");
        // and so are the off points at the mouths of holes after them (on by default)
        assert!(text.contains("; mouth points: skipped (no factor kept to fit them with)"), "{what}: {text}");
        let dw = common::rel_diff(&anew.spline.weights, &kept.spline.weights);
        let dc = common::rel_diff(&anew.spline.poly, &kept.spline.poly);
        assert!(dw < 1e-8 && dc < 1e-8, "{what}: weights {dw:e}, poly {dc:e}");
        assert!(common::volume_diff(&hdf, &kept) < 1e-8, "{what}");
    }
}

#[test]
fn a_slice_too_large_for_memory_is_refused_before_its_solve() {
    // the bunny in 12 slices, and the same with the middle slice's contours traced 40 times more
    // finely (as a segmentation at full resolution would): the slices' dense systems fit 800 MB
    // a rank, the fine slice's does not, and the run says which slice before solving any
    let dir = common::temp_dir("preflight-slice");
    let coarse = dir.join("coarse.txt");
    common::run_ok(0, &["slice", common::BUNNY, "--out", coarse.to_str().unwrap(), "--planes", "y:12"]);
    let mut sections = volspline::contour::format::read(&coarse).unwrap();
    let mid = sections.len() / 2;
    for c in &mut sections[mid].contours {
        *c = common::traced_finer(c, 40);
    }
    let fine = dir.join("fine.txt");
    std::fs::write(&fine, volspline::contour::format::to_text(&sections, "fine middle slice")).unwrap();
    let points = sections[mid].point_count();
    let line = volspline::contour::format::read(&fine).unwrap()[mid].line;
    // the matrix and the LU's copy of it, the fixed part beside
    let need = 2.0 * ((points + 3) as f64).powi(2) * 8.0 + 200e6;
    let limit = "800MB";
    assert!(need > 800e6 * 1.1, "{points} points");
    let contours = |input: &Path, out: &Path| {
        ["contours", input.to_str().unwrap(), "--out", out.to_str().unwrap(), "--memory-per-rank", limit]
            .map(String::from)
            .to_vec()
    };
    for ranks in [1, 2] {
        let out = dir.join(format!("r{ranks}"));
        let args = contours(&fine, &out);
        let run = common::run(ranks, &args.iter().map(String::as_str).collect::<Vec<_>>());
        let err = String::from_utf8_lossy(&run.stderr);
        assert_eq!(run.status.code(), Some(1), "{err}");
        let said = format!(
            "not enough memory: the dense system of the slice of line {line} ({points} points, the most of any \
             slice) needs about {}",
            if need >= 1e9 { format!("{:.1} GB", need / 1e9) } else { format!("{:.0} MB", need / 1e6) }
        );
        assert!(err.contains(&said) && err.contains("thin its contours"), "{said}\n{err}");
        let mut args = contours(&coarse, &out);
        args.extend(["--grid", "24", "--no-preview"].map(String::from));
        common::run_ok(ranks, &args.iter().map(String::as_str).collect::<Vec<_>>());
    }
    assert_eq!(
        files_in(&dir),
        ["coarse.txt", "fine.txt", "r1.hdf", "r1.model.h5", "r1.ply", "r2.hdf", "r2.model.h5", "r2.ply"]
    );
}

#[test]
fn morph_pairs_too_many_for_memory_are_refused_before_any_frame() {
    // 2000 of the bunny's vertices as features moving with it by (6, 2, 0): each frame solves two
    // space maps side by side, each a 2004 x 2004 system and its LU's copy
    let dir = common::temp_dir("preflight-morph");
    let bunny = common::bunny();
    let pairs: String = bunny
        .chunks_exact(3)
        .step_by(2)
        .take(2000)
        .map(|p| format!("{} {} {} {} {} {}\n", p[0], p[1], p[2], p[0] + 6.0, p[1] + 2.0, p[2]))
        .collect();
    let file = dir.join("pairs.txt");
    std::fs::write(&file, pairs).unwrap();
    let need = 4.0 * 2004f64.powi(2) * 8.0 + 200e6;
    for ranks in [1, 2] {
        let out = dir.join(format!("m{ranks}"));
        let args = [
            "morph",
            "ball:-2,10,0,8",
            "ball:4,12,0,8",
            "--out",
            out.to_str().unwrap(),
            "--pairs",
            file.to_str().unwrap(),
            "--frames",
            "3",
            "--memory-per-rank",
            "250MB",
        ];
        let run = common::run(ranks, &args);
        let err = String::from_utf8_lossy(&run.stderr);
        assert_eq!(run.status.code(), Some(1), "{err}");
        let said = format!(
            "solving the space maps of 2000 point pairs ({:.1} MB, beside 200 MB for the libraries and MPI's buffers) \
             needs about {:.0} MB",
            (need - 200e6) / 1e6,
            need / 1e6
        );
        assert!(err.contains(&said), "{said} not in {err}");
        assert!(std::fs::read_dir(&dir).unwrap().all(|e| !e
            .unwrap()
            .file_name()
            .to_string_lossy()
            .starts_with('m')));
    }
}

#[test]
fn slices_solved_side_by_side_are_counted_together() {
    // the bunny in 12 slices, two neighbouring ones traced 15 times more finely: one such system
    // fits 400 MB a rank, two at once on one rank's two threads do not; on two ranks each takes one
    let dir = common::temp_dir("preflight-threads");
    let mut sections = common::bunny_slices(&dir, "y:12");
    let mid = sections.len() / 2;
    for s in &mut sections[mid..mid + 2] {
        for c in &mut s.contours {
            let n = c.len();
            // on the Catmull-Rom curve through the traced points (points on straight edges would
            // make the slice's system needlessly ill-conditioned)
            *c = (0..15 * n)
                .map(|k| {
                    let (i, t) = (k / 15, (k % 15) as f64 / 15.0);
                    let [a, p, q, b] = [c[(i + n - 1) % n], c[i], c[(i + 1) % n], c[(i + 2) % n]];
                    let (t2, t3) = (t * t, t * t * t);
                    let w = [
                        -0.5 * t3 + t2 - 0.5 * t,
                        1.5 * t3 - 2.5 * t2 + 1.0,
                        -1.5 * t3 + 2.0 * t2 + 0.5 * t,
                        0.5 * t3 - 0.5 * t2,
                    ];
                    [0, 1].map(|d| w[0] * a[d] + w[1] * p[d] + w[2] * q[d] + w[3] * b[d])
                })
                .collect();
        }
    }
    let fine = dir.join("fine.txt");
    std::fs::write(&fine, volspline::contour::format::to_text(&sections, "two fine slices")).unwrap();
    let need = |n: usize| 2.0 * ((n + 3) as f64).powi(2) * 8.0;
    let (a, b) = (sections[mid].point_count(), sections[mid + 1].point_count());
    assert!(need(a.max(b)) + 200e6 < 400e6 && need(a) + need(b) + 200e6 > 400e6, "{a} and {b} points");
    let contours = |ranks: usize, threads: &str| {
        let out = dir.join(format!("r{ranks}t{threads}"));
        let args = [
            "contours",
            fine.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--grid",
            "24",
            "--memory-per-rank",
            "400MB",
            "--threads",
            threads,
        ];
        common::run(ranks, &args)
    };
    // one process without a launcher, which binds nothing: two threads on this node's two CPUs
    // (a rank bound to one CPU starts one thread, whatever --threads asks)
    if std::thread::available_parallelism().map_or(1, |n| n.get()) < 2 {
        eprintln!(
            "slices_solved_side_by_side_are_counted_together: one CPU here, nothing side by side to count"
        );
        return;
    }
    let refused = contours(0, "2");
    let err = String::from_utf8_lossy(&refused.stderr);
    assert_eq!(refused.status.code(), Some(1), "{err}");
    assert!(
        err.contains("the dense systems of the 2 slices this rank solves side by side on its threads"),
        "{err}"
    );
    assert!(err.contains("fewer --threads"), "{err}");
    for (ranks, threads) in [(1, "1"), (2, "2")] {
        let run = contours(ranks, threads);
        assert!(
            run.status.success(),
            "{ranks} ranks, {threads} threads: {}",
            String::from_utf8_lossy(&run.stderr)
        );
    }
}

/// The report of a `fit` of `input` on `ranks` ranks that succeeds within `--memory-per-rank
/// limit`, writing under the prefix `p` and the timings to `csv`, with the options `extra`.
fn fit_within(ranks: usize, input: &Path, (p, csv): (&Path, &Path), limit: &str, extra: &[&str]) -> String {
    let args = [
        "fit",
        input.to_str().unwrap(),
        "--out",
        p.to_str().unwrap(),
        "--no-preview",
        "--memory-per-rank",
        limit,
        "--timings",
        csv.to_str().unwrap(),
    ];
    common::run_ok(ranks, &[&args[..], extra].concat())
}

#[test]
fn second_fits_without_room_for_every_blob_point_thin_them_and_finish() {
    // the cow with a hole: the first fit (1231 centres, 1235 rows) keeps its factor, and its
    // second fits border it with 303 blob points (224 of the wide or narrow clearance, 79 of a
    // second round). With a limit that takes the first fit but leaves room for about 200 appended
    // centres, the blob points are thinned to the room, the round is left out, a warning says
    // so, and the fit finishes: no refusal after the first solve
    use volspline::app::preflight::{bordered_fit_bytes, dense_matrix_bytes, FIXED_BYTES};
    use volspline::linalg::dist::Precision;
    let dir = common::temp_dir("preflight-pins");
    let input = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/cow-1000-open.xyz");
    for ranks in [1, 2, 3] {
        let held = dense_matrix_bytes(1235, ranks, Precision::F64, true) + FIXED_BYTES;
        let limit = held + bordered_fit_bytes(1231, 200, 4, ranks);
        // (narrow panels: with the default ones their buffers outweigh such a bordering on 2 and
        // 3 ranks, and a limit that takes the first fit takes all the blob points)
        assert!(dense_bytes_with(1235, ranks, 32) < limit - 1e6, "the first fit fits on {ranks} ranks");
        assert!(held + bordered_fit_bytes(1231, 303, 4, ranks) > limit + 1e6);
        let limit = megabytes(limit);
        // the room as the option's value gives it (rounded to 0.1 MB): the largest count whose
        // bordering fits beside the factor
        let beside = limit.trim_end_matches("MB").parse::<f64>().unwrap() * 1e6 - held;
        let room = (0..303).take_while(|&m| bordered_fit_bytes(1231, m, 4, ranks) <= beside).last().unwrap();
        assert!((190..210).contains(&room), "room {room}");
        let (p, csv) = (dir.join(format!("o{ranks}")), dir.join(format!("t{ranks}.csv")));
        // (the blob counts were measured with the fitted ball as the carrier)
        let extra = [
            "--grid",
            "40",
            "--method",
            "dense",
            "--panel",
            "32",
            BY_INDEX[0],
            BY_INDEX[1],
            "--carrier",
            "ball",
        ];
        let text = fit_within(ranks, &input, (&p, &csv), &limit, &extra);
        let what = format!("{ranks} ranks, --memory-per-rank {limit}");
        assert!(text.contains("method dense (as asked)"), "{what}: {text}");
        assert!(
            text.contains(&format!(
                "warning: the ranks' memory leaves room for {room} centres appended to the first fit"
            )),
            "{what}: {text}"
        );
        assert!(
            text.contains(&format!("memory: room for {room} appended centres in the second fits")),
            "{what}: {text}"
        );
        assert!(text.contains("or a larger --memory-per-rank"), "{what}: {text}");
        assert!(text.contains(&format!("bordered by {room} appended centres")), "{what}: {text}");
        assert!(!text.contains("second round:"), "{what}: {text}");
        let figures = std::fs::read_to_string(&csv).unwrap();
        let figure =
            |k: &str| figures.lines().find_map(|l| l.strip_prefix(&format!("{k},"))).unwrap().to_string();
        assert_eq!(figure("blob_points"), room.to_string(), "{what}");
        assert_eq!(figure("second_fit_room"), room.to_string(), "{what}");
        // at least the clearances' 224 (the second round's, on the thinned fit, on top of the
        // points kept)
        let wanted: usize = figure("second_fit_wanted").parse().unwrap();
        assert!(wanted >= 224, "{what}: {wanted}");
        let model = read_model(&p.with_extension("model.h5")).unwrap();
        assert_eq!(model.spline.weights.len(), 1231 + room, "{what}");
        assert!(p.with_extension("ply").exists(), "{what}");
    }
}

#[test]
fn a_small_scan_s_blob_points_are_not_limited_as_if_by_memory() {
    // 80 points of the cow: the first fit has 80 + 40 rows, and the blob search pins up to 200
    // nodes whatever the scan's size. The room for appended centres was bounded by the first
    // fit's rows, so every such fit thinned its pins to 120 and warned that the ranks' memory
    // left no room, with gigabytes free
    let dir = common::temp_dir("preflight-small-pins");
    let input = dir.join("cow80.xyz");
    let text = std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/cow-400.xyz"))
        .unwrap();
    let pts: Vec<f64> = text
        .lines()
        .step_by(5)
        .flat_map(|l| l.split_whitespace().map(|v| v.parse::<f64>().unwrap()).collect::<Vec<_>>())
        .collect();
    assert_eq!(pts.len(), 240);
    common::write_xyz(&input, &pts);
    let (p, csv) = (dir.join("o"), dir.join("t.csv"));
    let args = ["fit", input.to_str().unwrap(), "--out", p.to_str().unwrap(), "--grid", "24", "--no-preview"];
    // the fitted ball as the carrier: its blob search pins more nodes than the fit has rows
    let ball = ["--carrier", "ball", "--timings", csv.to_str().unwrap()];
    let text = common::run_ok(0, &[&args[..], &ball].concat());
    assert!(!text.contains("leaves room for"), "{text}");
    assert!(!text.contains("memory: room for"), "{text}");
    let figures = std::fs::read_to_string(&csv).unwrap();
    let figure = |k: &str| -> usize {
        figures.lines().find_map(|l| l.strip_prefix(&format!("{k},"))).unwrap().parse().unwrap()
    };
    assert!(figures.lines().all(|l| !l.starts_with("second_fit_room,")), "{figures}");
    let rows = figure("points") + figure("off_points");
    let pinned = figure("choice_wide_points").max(figure("choice_narrow_points")).max(figure("blob_points"));
    assert!(pinned > rows, "{pinned} blob points at most, {rows} rows: {figures}");
}

#[test]
fn level_0_takes_as_many_points_as_its_dense_fit_has_room_for() {
    // the cow with a hole, 896 points: where the dense off-surface fit of all of them (at most
    // 896 + 448 + 4 rows) does not fit, `auto` takes the two levels, and level 0, which would be
    // that same dense fit, takes the most points whose fit does (evenly over space), says so,
    // and the fit finishes instead of refusing level 0
    let dir = common::temp_dir("preflight-level0");
    let input = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/cow-1000-open.xyz");
    let rows = |m: usize| m + m.div_ceil(2) + 4;
    for ranks in [1, 2] {
        let limit = megabytes(dense_bytes(rows(700), ranks));
        let room = limit.trim_end_matches("MB").parse::<f64>().unwrap() * 1e6;
        assert!(dense_bytes(rows(896), ranks) > room + 1e6);
        let m = (0..=896).take_while(|&m| dense_bytes(rows(m), ranks) <= room).last().unwrap();
        assert!((690..=700).contains(&m), "{m}");
        let (p, csv) = (dir.join(format!("o{ranks}")), dir.join(format!("t{ranks}.csv")));
        let text = fit_within(ranks, &input, (&p, &csv), &limit, &["--grid", "32"]);
        let what = format!("{ranks} ranks, --memory-per-rank {limit}");
        assert!(text.contains("method csrbf (auto: the dense system would need"), "{what}: {text}");
        assert!(
            text.contains(&format!(
                "dense r on up to {m} of them (the most whose dense off-surface fit fits the ranks' memory; \
                 --coarse-points 4000)"
            )),
            "{what}: {text}"
        );
        assert!(text.contains(&format!("on {m} of the points chosen evenly over space")), "{what}: {text}");
        let figures = std::fs::read_to_string(&csv).unwrap();
        assert!(figures.lines().any(|l| l == format!("coarse_points,{m}")), "{what}: {figures}");
        let model = read_model(&p.with_extension("model.h5")).unwrap();
        assert_eq!(model.coarse.len(), 1, "{what}");
        assert!(p.with_extension("ply").exists(), "{what}");
    }
}

#[test]
fn level_1_of_the_two_levels_is_checked_before_level_0() {
    // 2000 points of the cow with a support that takes every point as a neighbour: level 0 (300
    // points and their off points) fits 230 MB a rank, level 1's sparse factor (the lower
    // triangle of 2000 x 2000, the second rank's rows holding three quarters of it) does not;
    // the estimate from a sample of each rank's rows refuses the run before level 0 is solved
    let dir = common::temp_dir("preflight-level1");
    let input = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/cow-2000-seed3.xyz");
    let p = dir.join("o");
    for ranks in [1, 2] {
        let args = [
            "fit",
            input.to_str().unwrap(),
            "--out",
            p.to_str().unwrap(),
            "--grid",
            "24",
            "--no-preview",
            "--method",
            "csrbf",
            "--coarse-points",
            "300",
            "--support",
            "3.0",
            "--memory-per-rank",
            "230MB",
        ];
        let out = common::run(ranks, &args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{ranks} ranks: {err}");
        let said =
            "not enough memory: level 1 of the two-level fit: the sparse factor of 2000 points with about \
                    2000 neighbours each (support 3)";
        assert!(err.contains(said), "{ranks} ranks: {err}");
        // all 2000 x 2001 / 2 entries, 12 + 8 x 12 bytes each with the fill allowed, on the
        // rank holding the most of them
        let most = if ranks == 1 { 2_001_000.0 } else { 2_001_000.0 - 1000.0 * 1001.0 / 2.0 };
        let mb = (most * 108.0 + 100e6) / 1e6;
        assert!(err.contains(&format!("needs about {mb:.0} MB per rank")), "{ranks} ranks, {mb}: {err}");
        assert_eq!(files_in(&dir), Vec::<String>::new());
    }
}

#[test]
fn the_curvature_arrays_count_in_the_grid_s_memory() {
    // a grid of 100^3 nodes: its values, ghost layer and mesh fit 220 MB on one rank beside the
    // fixed 200 MB, with the mean and Gaussian curvature at every node as well they do not (32 MB),
    // and the run is refused before the evaluation
    let dir = common::temp_dir("preflight-curvature");
    let p = dir.join("e");
    let args =
        ["eval", "ball:0,0,0,1", "--bounds", "-1.5,-1.5,-1.5,1.5,1.5,1.5", "--out", p.to_str().unwrap()];
    let limit = ["--grid", "100", "--memory-per-rank", "220MB"];
    common::run_ok(1, &[&args[..], &limit].concat());
    let out = common::run(1, &[&args[..], &limit, &["--curvature"]].concat());
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(
        err.contains(
            "the grid of 100 x 100 x 100 nodes (per rank its slab 32 MB and 200 MB for the libraries and MPI's \
             buffers) needs about 232 MB per rank"
        ),
        "{err}"
    );
}

/// Runs the binary on `ranks` ranks under the address-space limit `ulimit -v kb` (KiB), set on
/// `mpirun`, whose ranks inherit it; panics where it runs past [`common::run_limit`] (OpenBLAS
/// retries for ever where its buffer cannot be allocated).
fn run_under_ulimit(ranks: usize, kb: u64, args: &[&str]) -> std::process::Output {
    run_under_ulimit_with(ranks, kb, args, &[])
}

/// [`run_under_ulimit`] with further environment variables.
fn run_under_ulimit_with(ranks: usize, kb: u64, args: &[&str], env: &[(&str, &str)]) -> std::process::Output {
    let mut cmd = std::process::Command::new("bash");
    cmd.arg("-c")
        .arg(format!("ulimit -v {kb} && exec mpirun -n {ranks} --oversubscribe \"$@\""))
        .arg("bash")
        .arg(common::BIN)
        .args(args)
        .env("OMPI_ALLOW_RUN_AS_ROOT", "1")
        .env("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1")
        .env("OMPI_MCA_rmaps_base_oversubscribe", "1")
        .env("RAYON_NUM_THREADS", "1")
        .envs(env.iter().copied());
    let done = common::output_within(cmd, common::run_limit());
    assert!(
        !done.timed_out,
        "{args:?} on {ranks} ranks under ulimit -v {kb} did not finish (a hang?): {}",
        String::from_utf8_lossy(&done.output.stderr)
    );
    done.output
}

#[test]
fn an_address_space_limit_is_refused_like_a_memory_limit() {
    // `ulimit -v` (a batch system's h_vmem): a rank over it fails an allocation, which aborts it
    // without a word and leaves its temporary files. The checks count the limit less the address
    // space a rank maps at its start (some 400 MB with Open MPI) and what the libraries map later
    // (192 MB with one thread), so a run that cannot fit is refused like one over
    // --memory-per-rank: exit 1, the limit named, nothing left. 600 MB leaves less than the fixed
    // part (refused at the start); 950 MB leaves about 380 MB, less than the bunny's dense system
    // (450 MB a rank on two ranks, 660 MB on one, the whole matrix counted: the limit counts the
    // untouched upper triangle too); 3 GB takes the same fit
    let dir = common::temp_dir("preflight-ulimit");
    let p = dir.join("o");
    let o = p.to_str().unwrap();
    let cow = ["fit", common::COW, "--out", o, "--grid", "32", "--no-preview"];
    let bunny = [
        &["fit", common::BUNNY, "--out", o, "--grid", "32", "--no-preview", "--method", "dense"][..],
        &BY_INDEX,
    ]
    .concat();
    let cases: [(&[&str], u64, &str); 2] = [
        (
            &cow,
            600_000,
            "not enough memory: the program's fixed part (libraries, MPI's and HDF5's buffers) needs",
        ),
        (&bunny[..], 950_000, "not enough memory: the dense system of 6900 rows"),
    ];
    for ranks in [1, 2] {
        for (args, kb, message) in cases {
            let out = run_under_ulimit(ranks, kb, args);
            let err = String::from_utf8_lossy(&out.stderr);
            let what = format!("{ranks} ranks, ulimit -v {kb}");
            assert_eq!(out.status.code(), Some(1), "{what}: {err}");
            assert!(err.contains(message), "{what}: {err}");
            let limit =
                format!("(the address-space limit (ulimit -v) of {:.0} MB, less the ", kb as f64 * 1.024e-3);
            assert!(err.contains(&limit), "{what}: {err}");
            assert!(err.contains("the rank had mapped at its start"), "{what}: {err}");
            assert!(!err.contains("panic") && !err.contains("memory allocation"), "{what}: {err}");
            // neither outputs nor temporary files
            assert_eq!(files_in(&dir), Vec::<String>::new(), "{what}");
        }
        // the baseline and the libraries' mappings leave a generous limit room for the work
        let out = run_under_ulimit(ranks, 3_000_000, &bunny);
        let said =
            format!("{}{}", String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
        assert!(out.status.success(), "{ranks} ranks, ulimit -v 3000000: {said}");
        assert_eq!(files_in(&dir), ["o.hdf", "o.model.h5", "o.ply"], "{ranks} ranks");
        for f in files_in(&dir) {
            std::fs::remove_file(dir.join(f)).unwrap();
        }
    }
}

#[test]
fn an_allocation_the_system_refuses_is_an_error_not_an_abort() {
    // where the checks find room but the system refuses the dense rows anyway (an address-space
    // limit or strict overcommit counting what the checks cannot see), the ranks agree on a
    // clean refusal naming the rows and the likely cause, instead of the abort of a failed
    // allocation ("memory allocation of 397 MB failed", exit 134, temporary files left). The
    // checks are turned off here to reach the allocation: under ulimit -v 560 MB a rank has
    // about 160 MB beside what it mapped at its start, less than the bunny's rows (381 MB on one
    // rank, 190 MB a rank on two) and more than the stages before them take
    let dir = common::temp_dir("preflight-refused-allocation");
    let p = dir.join("o");
    let args = [
        "fit",
        common::BUNNY,
        "--out",
        p.to_str().unwrap(),
        "--grid",
        "32",
        "--no-preview",
        "--method",
        "dense",
        BY_INDEX[0],
        BY_INDEX[1],
    ];
    for ranks in [1, 2] {
        let out = run_under_ulimit_with(ranks, 560_000, &args, &[("VOLSPLINE_TEST_SKIP_MEMORY_CHECKS", "1")]);
        let err = String::from_utf8_lossy(&out.stderr);
        let what = format!("{ranks} ranks");
        assert_eq!(out.status.code(), Some(1), "{what}: {err}");
        let rows = format!("for this rank's {} rows of the dense 6900 x 6901 system", 6900 / ranks);
        assert!(
            err.contains("not enough memory: the system refused") && err.contains(&rows),
            "{what}: {err}"
        );
        assert!(err.contains("ulimit -v"), "{what}: {err}");
        assert!(!err.contains("panic") && !err.contains("memory allocation"), "{what}: {err}");
        assert_eq!(files_in(&dir), Vec::<String>::new(), "{what}");
    }
}

#[test]
fn eval_counts_the_fixed_part_in_its_memory_estimate() {
    // eval's check counted the grid's slab alone: its "memory checks counted" figure lay below the
    // peak it reported beside it (131 MB against 148 MB on two ranks). It counts the fixed part
    // the fit's checks count, and lies above the peak
    let dir = common::temp_dir("preflight-eval-estimate");
    let model = dir.join("cow");
    common::run_ok(
        2,
        &["fit", common::COW, "--out", model.to_str().unwrap(), "--grid", "24", "--no-preview"],
    );
    let m = model.with_extension("model.h5");
    for ranks in [1, 2] {
        let (e, csv) = (dir.join(format!("e{ranks}")), dir.join(format!("t{ranks}.csv")));
        let args = [
            "eval",
            m.to_str().unwrap(),
            "--out",
            e.to_str().unwrap(),
            "--grid",
            "120",
            "--timings",
            csv.to_str().unwrap(),
        ];
        let text = common::run_ok(ranks, &args);
        let figures = std::fs::read_to_string(&csv).unwrap();
        let get = |k: &str| -> f64 {
            figures
                .lines()
                .find_map(|l| l.strip_prefix(&format!("{k},")))
                .unwrap_or_else(|| panic!("{k}"))
                .parse()
                .unwrap()
        };
        let (estimate, peak) = (get("memory_estimate_bytes_max"), get("peak_rss_bytes_max"));
        let what = format!("{ranks} ranks: estimate {estimate}, peak {peak}");
        assert!(estimate >= volspline::app::preflight::FIXED_BYTES && estimate > peak, "{what}");
        assert!(
            text.contains(&format!("(the memory checks counted up to {:.1} MB)", estimate / 1e6)),
            "{text}"
        );
    }
}

#[test]
fn a_limit_below_the_fixed_part_is_said_to_be_so() {
    // 150 MB a rank is less than the fixed 200 MB every rank needs, whatever the work: the
    // refusal says so and names that figure, instead of advising a smaller --coarse-points for
    // level 0 of the two-level fit (which `auto` takes for the cow), more ranks or fewer points
    let dir = common::temp_dir("preflight-below-fixed");
    let p = dir.join("o");
    let args =
        ["fit", common::COW, "--out", p.to_str().unwrap(), "--grid", "32", "--memory-per-rank", "150MB"];
    for ranks in [1, 2] {
        for extra in [&[][..], &["--method", "dense"], &["--method", "csrbf"]] {
            let out = common::run(ranks, &[&args[..], extra].concat());
            let err = String::from_utf8_lossy(&out.stderr);
            let what = format!("{ranks} ranks, {extra:?}");
            assert_eq!(out.status.code(), Some(1), "{what}: {err}");
            assert!(err.contains("this rank can have 150 MB (--memory-per-rank)"), "{what}: {err}");
            assert!(
                err.contains(
                    "the limit leaves a rank less than the 200 MB it needs for the program's fixed part whatever the work"
                ),
                "{what}: {err}"
            );
            assert!(!err.contains("--coarse-points"), "{what}: {err}");
            assert!(!err.contains("use --method csrbf"), "{what}: {err}");
            assert_eq!(files_in(&dir), Vec::<String>::new(), "{what}");
        }
    }
}
