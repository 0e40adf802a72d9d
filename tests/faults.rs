//! Fault injection through the binary: a full disk (a 2 MB tmpfs, mounted when the tests run as
//! root, otherwise skipped with a message), a file-size limit, SIGTERM in the middle of a run and
//! SIGHUP to one without mpirun, two concurrent runs on one prefix, a failing rerun over good
//! outputs, `--timings` to a special file or to a directory that takes no files, a standard output
//! closed before the report, outputs of an earlier run left under the prefix, and ranks started
//! with different command lines or in different directories. Each test checks the exit code, the
//! message and the exact set of files left in the output directory.

mod common;

use std::collections::BTreeSet;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use common::{output_within, run, run_limit, temp_dir, TempDir, BIN};

/// 300 points on the sphere of radius `r` about the origin.
fn sphere(path: &Path, r: f64) {
    let mut s = String::new();
    for i in 0..300 {
        let z = -1.0 + (2 * i + 1) as f64 / 300.0;
        let t = i as f64 * 2.399_963_229_728_653;
        let q = (1.0 - z * z).sqrt();
        s.push_str(&format!("{} {} {}\n", r * q * t.cos(), r * q * t.sin(), r * z));
    }
    std::fs::write(path, s).unwrap();
}

/// The names in `dir`, hidden ones included.
fn names(dir: &Path) -> BTreeSet<String> {
    std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect()
}

fn set(items: &[&str]) -> BTreeSet<String> {
    items.iter().map(|s| s.to_string()).collect()
}

/// The processes whose parent is `pid` (the ranks mpirun started on this node).
fn children_of(pid: u32) -> Vec<i32> {
    let mut out = Vec::new();
    for entry in std::fs::read_dir("/proc").unwrap().flatten() {
        let Ok(child) = entry.file_name().to_string_lossy().parse::<i32>() else { continue };
        let Ok(stat) = std::fs::read_to_string(entry.path().join("stat")) else { continue };
        // pid (comm) state ppid ...: the name may hold blanks and parentheses, so after the last ')'
        let ppid =
            stat.rsplit_once(')').and_then(|(_, rest)| rest.split_whitespace().nth(1)?.parse::<u32>().ok());
        if ppid == Some(pid) {
            out.push(child);
        }
    }
    out
}

/// Waits until the run `child`, whose standard error goes to `log`, has begun to evaluate its
/// grid; returns when it started waiting.
fn evaluating(child: &mut std::process::Child, log: &Path) -> Instant {
    let start = Instant::now();
    while !std::fs::read_to_string(log).unwrap_or_default().contains("kernel evaluations per node") {
        assert!(start.elapsed() < run_limit(), "the run never reached the evaluation");
        assert!(child.try_wait().unwrap().is_none(), "the run ended early");
        std::thread::sleep(Duration::from_millis(50));
    }
    start
}

fn mpirun(ranks: usize, args: &[&str]) -> Command {
    let mut c = Command::new("mpirun");
    c.args(["-n", &ranks.to_string(), "--oversubscribe", BIN])
        .args(args)
        .env("OMPI_ALLOW_RUN_AS_ROOT", "1")
        .env("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1")
        .env("RAYON_NUM_THREADS", "1");
    c
}

fn text(out: &std::process::Output) -> String {
    format!("{}{}", String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr))
}

/// A 2 MB tmpfs, unmounted on drop; None (with a message) where mounting is not permitted.
struct Tmpfs(TempDir);

impl Tmpfs {
    fn mount(name: &str) -> Option<Tmpfs> {
        let dir = temp_dir(name);
        let ok = Command::new("mount")
            .args(["-t", "tmpfs", "-o", "size=2m", "tmpfs"])
            .arg(&dir)
            .stderr(Stdio::null())
            .status()
            .is_ok_and(|s| s.success());
        if !ok {
            eprintln!("skipped: a 2 MB tmpfs cannot be mounted here (the disk-full tests need root)");
            return None;
        }
        Some(Tmpfs(dir))
    }
}

impl Drop for Tmpfs {
    fn drop(&mut self) {
        let _ = Command::new("umount").arg(&self.0).status();
    }
}

#[test]
fn disk_full_ends_the_job_with_a_message_on_1_and_2_ranks() {
    let Some(fs) = Tmpfs::mount("diskfull") else { return };
    let input_dir = temp_dir("diskfull-in");
    let input = input_dir.join("s.xyz");
    sphere(&input, 1.0);
    let out = fs.0.join("a");
    let args = ["fit", input.to_str().unwrap(), "--out", out.to_str().unwrap(), "--grid", "100"];
    for ranks in [1, 2] {
        // the free-space check refuses before the write
        let done = output_within(mpirun(ranks, &args), run_limit());
        let t = text(&done.output);
        assert!(!done.timed_out, "hung on {ranks} ranks:\n{t}");
        assert_eq!(done.output.status.code(), Some(1), "{t}");
        assert!(t.contains("not enough free space for the volume"), "{t}");
        assert_eq!(names(&fs.0), set(&[]), "{t}");
        // without it, the write itself fails: every rank must leave the collective close together
        let mut c = mpirun(ranks, &args);
        c.env("VOLSPLINE_TEST_SKIP_SPACE_CHECK", "1");
        let done = output_within(c, run_limit());
        let t = text(&done.output);
        assert!(!done.timed_out, "hung on {ranks} ranks after the write error:\n{t}");
        assert_eq!(done.output.status.code(), Some(1), "{ranks} ranks:\n{t}");
        assert!(t.contains("volspline: error") && t.contains("HDF5 error"), "{t}");
        assert!(t.contains(&format!("{}.hdf: HDF5 error: cannot be written", out.display())), "{t}");
        assert_eq!(names(&fs.0), set(&[]), "{t}");
    }
}

/// `mpirun -n ranks` of the binary through a wrapper that sets a file-size limit of `kb` KiB on
/// the ranks (as `ulimit -f`, or a batch system's, does): the launcher itself keeps none, since
/// its session files would not fit.
fn mpirun_with_file_size_limit(dir: &Path, ranks: usize, kb: u64, args: &[&str]) -> Command {
    let wrapper = dir.join("limited.sh");
    std::fs::write(&wrapper, format!("#!/bin/bash\nulimit -f {kb}\nexec {BIN} \"$@\"\n")).unwrap();
    use std::os::unix::fs::PermissionsExt;
    std::fs::set_permissions(&wrapper, std::fs::Permissions::from_mode(0o755)).unwrap();
    let mut c = Command::new("mpirun");
    c.args(["-n", &ranks.to_string(), "--oversubscribe"])
        .arg(&wrapper)
        .args(args)
        .env("OMPI_ALLOW_RUN_AS_ROOT", "1")
        .env("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1")
        .env("RAYON_NUM_THREADS", "1");
    c
}

#[test]
fn a_file_size_limit_is_named_and_leaves_nothing() {
    let dir = temp_dir("file-size-limit");
    let input = dir.join("s.xyz");
    sphere(&input, 1.0);
    std::fs::create_dir(dir.join("out")).unwrap();
    let out = dir.join("out/a");
    let o = out.to_str().unwrap();
    for ranks in [1, 2] {
        // a volume of 8 MB against a limit of 2 MB: refused before the write, by every rank
        let args = ["fit", input.to_str().unwrap(), "--out", o, "--grid", "100", "--surface", "carrier"];
        let done = output_within(mpirun_with_file_size_limit(&dir, ranks, 2048, &args), run_limit());
        let t = text(&done.output);
        assert!(!done.timed_out, "hung on {ranks} ranks:\n{t}");
        assert_eq!(done.output.status.code(), Some(1), "{ranks} ranks:\n{t}");
        assert!(
            t.contains("the volume needs 8.6 MB, but this process may write files of at most 2.0 MB"),
            "{ranks} ranks:\n{t}"
        );
        assert_eq!(names(&dir.join("out")), set(&[]), "{t}");
    }
    // a picture past the limit: its write fails with its name (SIGXFSZ would end the rank without
    // a word and leave the temporary file)
    let done = run(1, &["fit", input.to_str().unwrap(), "--out", o, "--grid", "16", "--no-preview"]);
    assert!(done.status.success(), "{}", text(&done));
    let model = dir.join("out/a.model.h5");
    let png = dir.join("out/big.png");
    let args = ["render", model.to_str().unwrap(), "--out", png.to_str().unwrap(), "--size", "400x400"];
    let done = output_within(mpirun_with_file_size_limit(&dir, 1, 8, &args), run_limit());
    let t = text(&done.output);
    assert!(!done.timed_out, "hung:\n{t}");
    assert_eq!(done.output.status.code(), Some(1), "{t}");
    assert!(t.contains(&format!("volspline: error: {}: cannot be written", png.display())), "{t}");
    assert!(t.contains("File too large"), "{t}");
    assert_eq!(names(&dir.join("out")), set(&["a.hdf", "a.model.h5", "a.ply"]), "{t}");
}

#[test]
fn sigterm_mid_run_removes_the_temporaries_and_says_so() {
    let dir = temp_dir("sigterm");
    let input = dir.join("s.xyz");
    sphere(&input, 1.0);
    let log = dir.join("stderr.txt");
    let out = dir.join("out/a");
    std::fs::create_dir(dir.join("out")).unwrap();
    let mut c = mpirun(2, &["fit", input.to_str().unwrap(), "--out", out.to_str().unwrap(), "--grid", "400"]);
    c.stdin(Stdio::null()).stdout(Stdio::null()).stderr(std::fs::File::create(&log).unwrap());
    let mut child = c.spawn().unwrap();
    let start = evaluating(&mut child, &log);
    std::thread::sleep(Duration::from_millis(500));
    // to every rank, as a batch system ends a job step (scancel signals all its tasks): signalled
    // itself, mpirun tears the job down and often drops the ranks' last lines
    let ranks = children_of(child.id());
    assert_eq!(ranks.len(), 2, "the ranks of mpirun {}: {ranks:?}", child.id());
    for pid in ranks {
        // SAFETY: a signal to a rank of the job this test started
        unsafe { libc::kill(pid, libc::SIGTERM) };
    }
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        assert!(start.elapsed() < run_limit(), "the run did not end after SIGTERM");
        std::thread::sleep(Duration::from_millis(50));
    };
    let t = std::fs::read_to_string(&log).unwrap();
    assert!(!status.success(), "{t}");
    assert!(t.contains("interrupted by SIGTERM"), "{t}");
    assert_eq!(names(&dir.join("out")), set(&[]), "{t}");
}

#[test]
fn a_closed_standard_output_loses_the_report_not_the_outputs() {
    // `volspline fit ... | head -1`: the reader of standard output is gone before the report
    let dir = temp_dir("closed-stdout");
    let input = dir.join("s.xyz");
    sphere(&input, 1.0);
    std::fs::create_dir(dir.join("out")).unwrap();
    let out = dir.join("out/a");
    let timings = dir.join("out/t.csv");
    let mut c = Command::new(BIN);
    c.args(["fit", input.to_str().unwrap(), "--out", out.to_str().unwrap(), "--grid", "16", "--no-preview"])
        .args(["--timings", timings.to_str().unwrap()])
        .env("RAYON_NUM_THREADS", "1")
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped());
    let mut child = c.spawn().unwrap();
    drop(child.stdout.take());
    let done = child.wait_with_output().unwrap();
    let t = text(&done);
    assert_eq!(done.status.code(), Some(0), "{t}");
    assert!(t.contains("warning: the report could not be printed on standard output"), "{t}");
    assert!(!t.contains("panic"), "{t}");
    assert_eq!(names(&dir.join("out")), set(&["a.hdf", "a.model.h5", "a.ply", "t.csv"]), "{t}");
}

#[test]
fn a_closed_standard_error_loses_the_messages_not_the_outputs() {
    // `volspline fit ... 2>&1 >/dev/null | head -1`: the reader of standard error goes after the
    // first line, and every later message met a closed pipe
    let dir = temp_dir("closed-stderr");
    let input = dir.join("s.xyz");
    sphere(&input, 1.0);
    std::fs::create_dir(dir.join("out")).unwrap();
    let out = dir.join("out/a");
    let mut c = Command::new(BIN);
    c.args(["fit", input.to_str().unwrap(), "--out", out.to_str().unwrap(), "--grid", "16", "--no-preview"])
        .env("RAYON_NUM_THREADS", "1")
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped());
    let mut child = c.spawn().unwrap();
    let mut first = String::new();
    {
        use std::io::BufRead;
        let mut err = std::io::BufReader::new(child.stderr.take().unwrap());
        err.read_line(&mut first).unwrap();
    }
    let status = child.wait().unwrap();
    assert!(first.starts_with("volspline fit: 300 points read"), "{first}");
    assert_eq!(status.code(), Some(0), "{first}");
    assert_eq!(names(&dir.join("out")), set(&["a.hdf", "a.model.h5", "a.ply"]));
}

#[test]
fn outputs_an_earlier_run_left_under_the_prefix_are_named() {
    let dir = temp_dir("left-from-earlier");
    let input = dir.join("s.xyz");
    sphere(&input, 1.0);
    std::fs::create_dir(dir.join("out")).unwrap();
    let out = dir.join("out/a");
    let fit = |more: &[&str]| {
        let mut args = vec!["fit", input.to_str().unwrap(), "--out", out.to_str().unwrap(), "--grid", "16"];
        args.extend_from_slice(more);
        let done = run(1, &args);
        assert!(done.status.success(), "{}", text(&done));
        text(&done)
    };
    let t = fit(&["--trim"]);
    assert!(!t.contains("earlier run"), "{t}");
    let all = ["a.hdf", "a.model.h5", "a.ply", "a.png", "a.trimmed.ply"];
    assert_eq!(names(&dir.join("out")), set(&all));
    // a rerun without the picture and the trimmed surface: the earlier ones stay, named
    let t = fit(&["--no-preview"]);
    let (png, trimmed) = (dir.join("out/a.png"), dir.join("out/a.trimmed.ply"));
    assert!(
        t.contains(&format!(
            "volspline: warning: {}, {} remain from an earlier run under this prefix",
            png.display(),
            trimmed.display()
        )),
        "{t}"
    );
    assert_eq!(names(&dir.join("out")), set(&all));
    // eval writes no picture: only the trimmed surface is named
    let model = dir.join("out/a.model.h5");
    let done = run(1, &["eval", model.to_str().unwrap(), "--out", out.to_str().unwrap(), "--grid", "16"]);
    let t = text(&done);
    assert!(done.status.success(), "{t}");
    assert!(
        t.contains(&format!("volspline: warning: {} remains from an earlier run", trimmed.display())),
        "{t}"
    );
    assert!(!t.contains(&format!("{},", png.display())), "{t}");
    let t = fit(&["--trim"]);
    assert!(!t.contains("earlier run"), "{t}");
}

#[test]
fn a_prefix_too_long_for_the_temporary_names_is_refused_before_the_work() {
    // the outputs' names fit the file system's 255 bytes, their temporary names do not
    let dir = temp_dir("long-prefix");
    let input = dir.join("s.xyz");
    sphere(&input, 1.0);
    let out = dir.join("x".repeat(235));
    let done = run(1, &["fit", input.to_str().unwrap(), "--out", out.to_str().unwrap(), "--grid", "16"]);
    let t = text(&done);
    assert_eq!(done.status.code(), Some(2), "{t}");
    assert!(t.contains("has a name too long for its temporary file"), "{t}");
    assert!(!t.contains("kernel evaluations per node"), "refused after the work:\n{t}");
    assert_eq!(names(&dir), set(&["s.xyz"]), "{t}");
}

#[test]
fn a_timings_directory_that_takes_no_files_is_refused_before_the_work() {
    let dir = temp_dir("timings-dir");
    let input = dir.join("s.xyz");
    sphere(&input, 1.0);
    std::fs::create_dir(dir.join("out")).unwrap();
    let out = dir.join("out/a");
    // /proc takes no new files, even from root
    let bad = format!("/proc/volspline-{}-t.csv", std::process::id());
    for ranks in [1, 2] {
        let done = run(
            ranks,
            &[
                "fit",
                input.to_str().unwrap(),
                "--out",
                out.to_str().unwrap(),
                "--grid",
                "16",
                "--timings",
                &bad,
            ],
        );
        let t = text(&done);
        assert_eq!(done.status.code(), Some(1), "{t}");
        assert!(t.contains("volspline: error: /proc: cannot create a file in the output directory"), "{t}");
        assert!(t.contains(&format!("(for --timings {bad})")), "{t}");
        assert!(!t.contains("kernel evaluations per node"), "refused after the work:\n{t}");
        assert_eq!(names(&dir.join("out")), set(&[]), "{t}");
    }
}

#[test]
fn sighup_to_a_run_without_mpirun_removes_the_temporaries() {
    // one process started from a terminal that closes (a dropped ssh session): SIGHUP ended it
    // at once, leaving the model's temporary file
    let dir = temp_dir("sighup");
    let input = dir.join("s.xyz");
    sphere(&input, 1.0);
    let log = dir.join("stderr.txt");
    std::fs::create_dir(dir.join("out")).unwrap();
    let out = dir.join("out/a");
    let mut c = Command::new(BIN);
    c.args(["fit", input.to_str().unwrap(), "--out", out.to_str().unwrap(), "--grid", "400"])
        .env("RAYON_NUM_THREADS", "1")
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(std::fs::File::create(&log).unwrap());
    let mut child = c.spawn().unwrap();
    evaluating(&mut child, &log);
    std::thread::sleep(Duration::from_millis(300));
    // SAFETY: a signal to the child process this test started
    unsafe { libc::kill(child.id() as i32, libc::SIGHUP) };
    let status = child.wait().unwrap();
    let t = std::fs::read_to_string(&log).unwrap();
    assert_eq!(status.code(), Some(129), "{status:?}: {t}");
    assert!(t.contains("volspline: interrupted by SIGHUP; removed 1 temporary file(s)"), "{t}");
    assert_eq!(names(&dir.join("out")), set(&[]), "{t}");
}

/// The x extent of a PLY mesh's vertices.
fn mesh_width(path: &Path) -> f64 {
    let m = common::load_mesh(path);
    let xs = m.vertices.iter().map(|v| v[0]);
    xs.clone().fold(f64::MIN, f64::max) - xs.fold(f64::MAX, f64::min)
}

#[test]
fn concurrent_runs_on_one_prefix_leave_one_whole_set() {
    let dir = temp_dir("concurrent");
    let (small, big) = (dir.join("small.xyz"), dir.join("big.xyz"));
    sphere(&small, 1.0);
    sphere(&big, 2.0);
    std::fs::create_dir(dir.join("out")).unwrap();
    let out = dir.join("out/a");
    let runs: Vec<_> = [&small, &big]
        .iter()
        .map(|input| {
            let c =
                mpirun(1, &["fit", input.to_str().unwrap(), "--out", out.to_str().unwrap(), "--grid", "40"]);
            std::thread::spawn(move || output_within(c, run_limit()))
        })
        .collect();
    for r in runs {
        let done = r.join().unwrap();
        assert!(!done.timed_out && done.output.status.success(), "{}", text(&done.output));
    }
    assert_eq!(names(&dir.join("out")), set(&["a.hdf", "a.model.h5", "a.ply", "a.png"]));
    let model = volspline::io::model_file::read_model(&dir.join("out/a.model.h5")).unwrap();
    let (grid, _) = volspline::io::vtkhdf::read_image(&dir.join("out/a.hdf"), "f").unwrap();
    let r = model.provenance.box_hi[0];
    assert!((r - 1.0).abs() < 0.05 || (r - 2.0).abs() < 0.1, "data box {r}");
    // the volume and the mesh are of the same run as the model
    let grid_width = grid.spacing[0] * (grid.dims[0] - 1) as f64;
    assert!(
        (grid_width / (2.0 * r) - 1.1).abs() < 0.05,
        "grid width {grid_width} for a sphere of radius {r}"
    );
    let w = mesh_width(&dir.join("out/a.ply"));
    assert!((w / (2.0 * r) - 1.0).abs() < 0.1, "mesh width {w} for a sphere of radius {r}");
}

#[test]
fn failing_rerun_leaves_the_previous_set_untouched() {
    let dir = temp_dir("rerun");
    let input = dir.join("s.xyz");
    sphere(&input, 1.0);
    std::fs::create_dir(dir.join("out")).unwrap();
    let out = dir.join("out/a");
    let o = out.to_str().unwrap();
    for ranks in [1, 2] {
        let done = run(ranks, &["fit", input.to_str().unwrap(), "--out", o, "--grid", "24"]);
        assert!(done.status.success(), "{}", text(&done));
        let before: Vec<Vec<u8>> = ["a.hdf", "a.model.h5", "a.ply", "a.png"]
            .iter()
            .map(|n| std::fs::read(dir.join("out").join(n)).unwrap())
            .collect();
        // the rerun fails at its very end (the timings file, a link to a file of /proc that takes
        // no writes, is written directly, as links to special files are), after the model, the
        // volume and the mesh were written under their temporary names
        let bad = dir.join("t.csv");
        let _ = std::fs::remove_file(&bad);
        std::os::unix::fs::symlink("/proc/version", &bad).unwrap();
        let done = run(
            ranks,
            &["fit", input.to_str().unwrap(), "--out", o, "--grid", "30", "--timings", bad.to_str().unwrap()],
        );
        let t = text(&done);
        assert_eq!(done.status.code(), Some(1), "{t}");
        assert!(t.contains(&format!("volspline: error: {}: ", bad.display())), "{t}");
        assert!(t.contains("kernel evaluations per node"), "not at the end:\n{t}");
        assert_eq!(names(&dir.join("out")), set(&["a.hdf", "a.model.h5", "a.ply", "a.png"]), "{t}");
        let after: Vec<Vec<u8>> = ["a.hdf", "a.model.h5", "a.ply", "a.png"]
            .iter()
            .map(|n| std::fs::read(dir.join("out").join(n)).unwrap())
            .collect();
        assert!(before == after, "a failing rerun changed the previous outputs");
    }
}

#[test]
fn timings_to_stdout_prints_the_csv() {
    let dir = temp_dir("timings");
    let input = dir.join("s.xyz");
    sphere(&input, 1.0);
    std::fs::create_dir(dir.join("out")).unwrap();
    let out = dir.join("out/a");
    let done = run(
        1,
        &[
            "fit",
            input.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--grid",
            "20",
            "--timings",
            "/dev/stdout",
        ],
    );
    let stdout = String::from_utf8_lossy(&done.stdout);
    assert!(done.status.success(), "{}", text(&done));
    assert!(stdout.contains("key,value\n") && stdout.contains("\npoints,300\n"), "{stdout}");
    // the stage table's total is there, the stages' sum without the wait inside the solve
    let figure = |key: &str| -> f64 {
        let line =
            stdout.lines().find(|l| l.starts_with(&format!("{key},"))).unwrap_or_else(|| panic!("{key}"));
        line[key.len() + 1..].parse().unwrap()
    };
    let stages: f64 = stdout
        .lines()
        .filter(|l| l.starts_with("stage_") && !l.starts_with("stage_comm_wait"))
        .filter_map(|l| l.split_once("_max_s,").map(|(_, v)| v.parse::<f64>().unwrap()))
        .sum();
    assert!((figure("total_max_s") - stages).abs() < 1e-5, "{stdout}");
    assert!(figure("total_min_s") <= figure("total_max_s"), "{stdout}");
    assert_eq!(names(&dir.join("out")), set(&["a.hdf", "a.model.h5", "a.ply", "a.png"]));
    // `eval` of the model counts its points as the fit did, and its centres (with the
    // off-surface points) apart
    let model = dir.join("out/a.model.h5");
    let again = dir.join("again");
    let (m, o) = (model.to_str().unwrap(), again.to_str().unwrap());
    let done = run(1, &["eval", m, "--out", o, "--grid", "20", "--timings", "/dev/stdout"]);
    let stdout = String::from_utf8_lossy(&done.stdout);
    assert!(done.status.success(), "{}", text(&done));
    let centres: usize =
        stdout.lines().find_map(|l| l.strip_prefix("centres,")).expect("centres").parse().unwrap();
    assert!(stdout.contains("\npoints,300\n") && centres > 300, "{stdout}");
    // the link itself is untouched (never renamed over)
    assert!(std::fs::symlink_metadata("/dev/stdout").is_ok_and(|m| m.file_type().is_symlink()));
}

#[test]
fn ranks_started_with_different_arguments_are_refused_without_a_hang() {
    // a wrapper that gives each rank its own output prefix: the ranks would create different
    // files in one collective and wait on each other for ever
    let dir = temp_dir("different-arguments");
    let input = dir.join("s.xyz");
    sphere(&input, 1.0);
    let wrapper = dir.join("each-its-own.sh");
    std::fs::write(
        &wrapper,
        format!(
            "#!/bin/sh\nexec {BIN} fit {} --out {}/r$OMPI_COMM_WORLD_RANK --grid 16 --no-preview\n",
            input.display(),
            dir.display()
        ),
    )
    .unwrap();
    use std::os::unix::fs::PermissionsExt;
    std::fs::set_permissions(&wrapper, std::fs::Permissions::from_mode(0o755)).unwrap();
    let mut c = Command::new("mpirun");
    c.args(["-n", "2", "--oversubscribe"])
        .arg(&wrapper)
        .env("OMPI_ALLOW_RUN_AS_ROOT", "1")
        .env("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1")
        .env("RAYON_NUM_THREADS", "1");
    let done = output_within(c, Duration::from_secs(120));
    let out = text(&done.output);
    assert!(!done.timed_out, "the job hung:\n{out}");
    assert!(!done.output.status.success(), "{out}");
    assert!(
        out.contains("error on rank 1: ")
            && out.contains("rank 1 was started with other arguments than rank 0 (argument 4: "),
        "{out}"
    );
    assert_eq!(names(&dir), set(&["s.xyz", "each-its-own.sh"]), "nothing written");
}

#[test]
fn ranks_in_different_directories_with_relative_paths_are_refused_without_a_hang() {
    // a wrapper that starts each rank in its own directory, as a launcher that does not carry the
    // working directory over to other nodes does: `out/a` is a different file on each rank, and
    // the parallel create of the volume waited for ever
    let dir = temp_dir("different-directories");
    for rank in 0..2 {
        std::fs::create_dir_all(dir.join(format!("wd{rank}/out"))).unwrap();
        sphere(&dir.join(format!("wd{rank}/s.xyz")), 1.0);
    }
    let wrapper = dir.join("each-its-own-directory.sh");
    let script = format!("#!/bin/sh\ncd {}/wd$OMPI_COMM_WORLD_RANK && exec {BIN} \"$@\"\n", dir.display());
    std::fs::write(&wrapper, script).unwrap();
    use std::os::unix::fs::PermissionsExt;
    std::fs::set_permissions(&wrapper, std::fs::Permissions::from_mode(0o755)).unwrap();
    let job = |args: &[&str]| {
        let mut c = Command::new("mpirun");
        c.args(["-n", "2", "--oversubscribe"])
            .arg(&wrapper)
            .args(args)
            .env("OMPI_ALLOW_RUN_AS_ROOT", "1")
            .env("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1")
            .env("RAYON_NUM_THREADS", "1");
        output_within(c, Duration::from_secs(120))
    };
    let done = job(&["fit", "s.xyz", "--out", "out/a", "--grid", "16", "--no-preview"]);
    let t = text(&done.output);
    assert!(!done.timed_out, "the job hung:\n{t}");
    assert_eq!(done.output.status.code(), Some(2), "{t}");
    // the directories as the ranks see them (a temporary directory may be reached through a link)
    let real = std::fs::canonicalize(&dir).unwrap();
    assert!(
        t.contains(&format!(
            "error on rank 1: invalid argument: rank 1 runs in the directory {}/wd1, rank 0 in {}/wd0",
            real.display(),
            real.display()
        )) && t.contains("mpirun --wdir DIR"),
        "{t}"
    );
    for rank in 0..2 {
        assert_eq!(names(&dir.join(format!("wd{rank}/out"))), set(&[]), "{t}");
    }
    // absolute paths name one file whatever the directory
    let input = dir.join("wd0/s.xyz");
    let out = dir.join("wd0/out/a");
    let done = job(&[
        "fit",
        input.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--grid",
        "16",
        "--no-preview",
    ]);
    let t = text(&done.output);
    assert!(!done.timed_out && done.output.status.success(), "{t}");
    assert_eq!(names(&dir.join("wd0/out")), set(&["a.hdf", "a.model.h5", "a.ply"]), "{t}");
}
