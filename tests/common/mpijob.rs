//! Library checks that communicate, run as MPI jobs by a test target without the libtest harness
//! (`harness = false`).
//!
//! As the parent (what `cargo test` starts) the executable runs itself once per [`Case`], under
//! `mpirun -n ranks --oversubscribe` (or, for `ranks == 0`, directly: MPI then starts as a
//! singleton), and fails unless every job ends as its case expects within its time limit, so a
//! collective that hangs fails the suite instead of stalling it. As a child ([`CHILD`] set) it
//! starts MPI and runs its checks with [`run_checks`]: each check is collective, each rank records
//! its own mismatches in a [`Log`], the lines are gathered to rank 0 after each check, which prints
//! one line per check and a summary; the job exits non-zero if a check failed on any rank. An
//! unexpected library error panics, and the panic aborts the whole job.
//!
//! Arguments as libtest takes them: `--list`, name filters (substrings, or whole names with
//! `--exact`), `--skip NAME`; other options are accepted and ignored.

use std::path::Path;
use std::process::Command;
use std::time::{Duration, Instant};

use volspline::error::Result;
use volspline::par::Comm;

/// Set in the environment of a child job.
pub const CHILD: &str = "VOLSPLINE_MPI_CHILD";

/// What a job must do to pass.
#[derive(Clone, Copy)]
pub enum Expect {
    /// Exit 0 with every check passed.
    Pass,
    /// Exit non-zero through the agreed failure flag, with exactly one failed check, the one
    /// named here.
    Fail(&'static str),
    /// Run past its limit and be killed.
    Hang,
}

/// One job: its name (as libtest lists it), its ranks (0: without mpirun), the environment
/// variables it sets, and what it must do within its limit.
pub struct Case {
    pub name: &'static str,
    pub ranks: usize,
    pub env: &'static [(&'static str, &'static str)],
    pub expect: Expect,
    pub limit: Duration,
}

/// The entry point of a harness-free test target: the child runs `child`, the parent `cases`.
pub fn main(cases: Vec<Case>, child: fn()) {
    if std::env::var_os(CHILD).is_some() {
        child();
    } else {
        parent(cases);
    }
}

/// The cases selected by libtest-style arguments.
fn selected(cases: Vec<Case>, args: &[String]) -> Vec<Case> {
    let (mut filters, mut skips, mut exact) = (Vec::new(), Vec::new(), false);
    let mut it = args.iter();
    while let Some(a) = it.next() {
        match a.as_str() {
            "--exact" => exact = true,
            "--skip" => skips.extend(it.next().cloned()),
            // options of libtest that take a value
            "--test-threads" | "--format" | "--color" | "--logfile" | "-Z" | "--shuffle-seed" => {
                it.next();
            }
            s if s.starts_with('-') => {}
            s => filters.push(s.to_string()),
        }
    }
    let hit = |name: &str, f: &String| if exact { name == f } else { name.contains(f.as_str()) };
    cases
        .into_iter()
        .filter(|c| filters.is_empty() || filters.iter().any(|f| hit(c.name, f)))
        .filter(|c| !skips.iter().any(|f| hit(c.name, f)))
        .collect()
}

fn parent(cases: Vec<Case>) {
    let args: Vec<String> = std::env::args().skip(1).collect();
    // the variables any case sets, cleared for the others
    let all_env: Vec<&str> = cases.iter().flat_map(|c| c.env.iter().map(|(k, _)| *k)).collect();
    let cases = selected(cases, &args);
    if args.iter().any(|a| a == "--list") {
        for c in &cases {
            println!("{}: test", c.name);
        }
        return;
    }
    if args.iter().any(|a| a == "--ignored") {
        return; // no ignored cases
    }
    println!("\nrunning {} tests", cases.len());
    let exe = std::env::current_exe().expect("the path of this test executable");
    let mut failed = Vec::new();
    for case in &cases {
        let t = Instant::now();
        match run_case(&exe, case, &all_env) {
            Ok(()) => println!("test {} ... ok ({:.1} s)", case.name, t.elapsed().as_secs_f64()),
            Err(why) => {
                println!("test {} ... FAILED\n{why}", case.name);
                failed.push(case.name);
            }
        }
    }
    if !failed.is_empty() {
        println!("\nfailures: {}", failed.join(", "));
        std::process::exit(101);
    }
    println!("\ntest result: ok. {} passed\n", cases.len());
}

/// Runs one case's job and judges how it ended.
fn run_case(exe: &Path, case: &Case, all_env: &[&str]) -> std::result::Result<(), String> {
    let mut cmd = if case.ranks == 0 {
        Command::new(exe)
    } else {
        let mut c = Command::new("mpirun");
        c.args(["-n", &case.ranks.to_string(), "--oversubscribe"]).arg(exe);
        c
    };
    for k in all_env {
        cmd.env_remove(k);
    }
    cmd.env(CHILD, "1")
        .envs(case.env.iter().copied())
        .env("OMPI_ALLOW_RUN_AS_ROOT", "1")
        .env("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1")
        .env("OMPI_MCA_rmaps_base_oversubscribe", "1")
        .env("RAYON_NUM_THREADS", "1");
    let done = super::output_within(cmd, case.limit);
    let (stdout, stderr) =
        (String::from_utf8_lossy(&done.output.stdout), String::from_utf8_lossy(&done.output.stderr));
    let text = format!("--- stdout\n{stdout}--- stderr\n{stderr}");
    let summary = stdout.lines().rev().find_map(|l| l.strip_prefix("summary: ")).unwrap_or("");
    let field = |key: &str| -> Option<usize> {
        summary.split(' ').find_map(|kv| kv.strip_prefix(key)?.strip_prefix('=')?.parse().ok())
    };
    let limit = case.limit.as_secs();
    let (ok, checks) = (done.output.status.success(), field("checks").unwrap_or(0));
    match case.expect {
        _ if done.timed_out && !matches!(case.expect, Expect::Hang) => {
            Err(format!("the job did not finish within {limit} s and was killed (a hang?)\n{text}"))
        }
        Expect::Pass
            if ok
                && field("ranks") == Some(case.ranks.max(1))
                && checks > 0
                && field("failed") == Some(0)
                && !stdout.contains("FAIL") =>
        {
            print!("{stdout}");
            Ok(())
        }
        Expect::Pass => Err(format!("the job failed ({}) or ran no checks\n{text}", done.output.status)),
        // exactly the broken comparison fails, the job exits non-zero through the agreed flag
        Expect::Fail(check)
            if !ok && field("failed") == Some(1) && stdout.contains(&format!("FAIL  {check}")) =>
        {
            Ok(())
        }
        Expect::Fail(_) => Err(format!("a check against a wrong value did not fail the job\n{text}")),
        Expect::Hang if done.timed_out => Ok(()),
        Expect::Hang => Err(format!("the hung job was not killed at its limit of {limit} s\n{text}")),
    }
}

/// One rank's mismatches in one check.
#[derive(Default)]
pub struct Log {
    fails: Vec<String>,
}

impl Log {
    pub fn check(&mut self, ok: bool, what: impl FnOnce() -> String) {
        if !ok {
            self.fails.push(what());
        }
    }

    /// `got` within `tol` of `want`, relative to the largest |want|.
    pub fn close(&mut self, got: &[f64], want: &[f64], tol: f64, what: impl FnOnce() -> String) {
        if got.len() != want.len() {
            self.fails.push(format!("{}: {} values, expected {}", what(), got.len(), want.len()));
        } else {
            let d = super::rel_diff(got, want);
            self.check(d <= tol, || format!("{}: relative difference {d:e} > {tol:e}", what()));
        }
    }
}

/// A collective check: every rank runs it with its own log.
pub type Check = fn(&dyn Comm, &mut Log);

/// Runs `checks` in order, prints one line each and the summary on rank 0, and returns the number
/// of checks that failed on some rank (the same on every rank). Collective.
pub fn run_checks(comm: &dyn Comm, checks: &[(&str, Check)]) -> usize {
    let mut failed = 0;
    for (name, check) in checks {
        let start = Instant::now();
        let mut log = Log::default();
        check(comm, &mut log);
        let mut count = [log.fails.len() as u64];
        comm.sum_u64(&mut count);
        let lines = comm.gather_values(0, &log.fails);
        if let Some(lines) = lines {
            let secs = start.elapsed().as_secs_f64();
            if count[0] == 0 {
                println!("  ok    {name} ({secs:.2} s)");
            } else {
                println!("  FAIL  {name}");
                for (r, fails) in lines.iter().enumerate() {
                    for f in fails {
                        println!("          rank {r}: {f}");
                    }
                }
            }
        }
        failed += usize::from(count[0] > 0);
    }
    if comm.rank() == 0 {
        println!("summary: ranks={} checks={} failed={failed}", comm.size(), checks.len());
    }
    failed
}

/// An unexpected library error: abort the job with it (the panic hook of `World` aborts all ranks).
pub fn must<T>(r: Result<T>, what: &str) -> T {
    r.unwrap_or_else(|e| panic!("{what}: unexpected error: {e}"))
}

/// Checks that every rank holds the same values as rank 0, bit for bit. Collective.
pub fn same_on_every_rank(comm: &dyn Comm, log: &mut Log, x: &[f64], what: &str) {
    let x0: Vec<f64> = comm.broadcast_value(0, (comm.rank() == 0).then(|| x.to_vec()));
    let same = x0.len() == x.len() && x0.iter().zip(x).all(|(a, b)| a.to_bits() == b.to_bits());
    log.check(same, || format!("{what}: the values differ from rank 0's"));
}
