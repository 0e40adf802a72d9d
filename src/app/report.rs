//! The report of a run: named stages timed on every rank ([`Stages`], keyed by the [`Stage`] enum so
//! no name can drift), and one [`Report`] per command that every command fills the same way and
//! [`Report::finish`] prints on rank 0 as text (figures, stage table with min and max over ranks,
//! peak memory, outputs) and writes as `key,value` CSV for `--timings`. Also the progress line of
//! long stages.

use std::io::{IsTerminal, Write};
use std::path::{Path, PathBuf};
use std::time::Instant;

use crate::error::{Error, Result};
use crate::io;
use crate::par::{max_over_ranks, on_root, Comm};

/// The stages of a run, in the order they are printed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stage {
    Read,
    Assemble,
    Solve,
    Check,
    Evaluate,
    Mesh,
    Write,
    Slice,
}

impl Stage {
    pub const ALL: [Stage; 8] = [
        Stage::Read,
        Stage::Assemble,
        Stage::Solve,
        Stage::Check,
        Stage::Evaluate,
        Stage::Mesh,
        Stage::Write,
        Stage::Slice,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Stage::Read => "read",
            Stage::Assemble => "assemble",
            Stage::Solve => "solve",
            Stage::Check => "check",
            Stage::Evaluate => "evaluate",
            Stage::Mesh => "mesh",
            Stage::Write => "write",
            Stage::Slice => "slice",
        }
    }
}

/// Wall-clock seconds of each stage on this rank.
#[derive(Debug, Default, Clone)]
pub struct Stages {
    seconds: [f64; Stage::ALL.len()],
    ran: [bool; Stage::ALL.len()],
}

/// Min and max over ranks of one stage.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StageTime {
    pub stage: Stage,
    pub min: f64,
    pub max: f64,
}

/// The stages that ran, summarised over ranks.
#[derive(Debug, Clone, Default)]
pub struct StageTimes(pub Vec<StageTime>);

impl Stages {
    /// Runs `f` as `stage` and adds its time.
    pub fn time<T>(&mut self, stage: Stage, f: impl FnOnce() -> T) -> T {
        let t = Instant::now();
        let out = f();
        self.add(stage, t.elapsed().as_secs_f64());
        out
    }

    /// Adds `seconds` to `stage`.
    pub fn add(&mut self, stage: Stage, seconds: f64) {
        self.seconds[stage as usize] += seconds;
        self.ran[stage as usize] = true;
    }

    /// Min/max over ranks of every stage that ran on any rank. Collective.
    pub fn summarise(&self, comm: &dyn Comm) -> StageTimes {
        let ran: Vec<f64> = self.ran.iter().map(|&r| f64::from(u8::from(r))).collect();
        let mut v = [self.seconds.to_vec(), ran].concat();
        let mut mins = self.seconds.to_vec();
        comm.max_f64(&mut v);
        comm.min_f64(&mut mins);
        let n = Stage::ALL.len();
        StageTimes(
            Stage::ALL
                .iter()
                .filter(|s| v[n + **s as usize] > 0.0)
                .map(|&stage| StageTime { stage, min: mins[stage as usize], max: v[stage as usize] })
                .collect(),
        )
    }
}

impl StageTimes {
    /// The largest time of `stage` over ranks (0 when it did not run).
    pub fn max(&self, stage: Stage) -> f64 {
        self.0.iter().find(|t| t.stage == stage).map_or(0.0, |t| t.max)
    }

    /// The stage table as printed.
    pub fn table(&self) -> String {
        let mut s = String::from("  stage          min [s]     max [s]\n");
        let mut total = (0.0, 0.0);
        for t in &self.0 {
            s.push_str(&format!("  {:<12} {:>9.3}   {:>9.3}\n", t.stage.name(), t.min, t.max));
            total.0 += t.min;
            total.1 += t.max;
        }
        s.push_str(&format!("  {:<12} {:>9.3}   {:>9.3}\n", "total", total.0, total.1));
        s
    }

    /// (name, max seconds) of every stage, as a model file records them.
    pub fn named_max(&self) -> Vec<(String, f64)> {
        self.0.iter().map(|t| (t.stage.name().to_string(), t.max)).collect()
    }
}

/// This process's peak resident memory (VmHWM) in bytes, where the system reports it (Linux).
pub fn peak_rss_bytes() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

/// What one command reports: lines of text for people, `key,value` figures for scripts, the
/// outputs written. The same on every rank; rank 0 prints.
#[derive(Debug, Clone)]
pub struct Report {
    title: String,
    lines: Vec<String>,
    figures: Vec<(String, String)>,
    outputs: Vec<PathBuf>,
}

impl Report {
    /// A report of `command` (the first CSV figure) about `subject` (its input).
    pub fn new(command: &str, subject: &Path) -> Self {
        let mut r = Report {
            title: format!("volspline {command}: {}", subject.display()),
            lines: Vec::new(),
            figures: Vec::new(),
            outputs: Vec::new(),
        };
        r.figure("command", command);
        r
    }

    /// Adds a line of text.
    pub fn line(&mut self, text: impl Into<String>) {
        self.lines.push(text.into());
    }

    /// Adds a figure to the CSV record.
    pub fn figure(&mut self, key: &str, value: impl std::fmt::Display) {
        self.figures.push((key.to_string(), value.to_string()));
    }

    /// Records an output file.
    pub fn output(&mut self, path: &Path) {
        self.outputs.push(path.to_path_buf());
    }

    /// The figures as `key,value` CSV.
    pub fn to_csv(&self) -> String {
        let mut s = String::from("key,value\n");
        for (k, v) in &self.figures {
            s.push_str(&format!("{k},{}\n", v.replace(',', ";")));
        }
        s
    }

    /// Adds the stage times and the peak memory, prints the report on rank 0 and writes the CSV
    /// to `timings` (atomically, from rank 0). `after_table` lines follow the stage table.
    /// Collective.
    pub fn finish(
        mut self,
        comm: &dyn Comm,
        stages: &Stages,
        after_table: &dyn Fn(&StageTimes) -> Vec<String>,
        timings: Option<&Path>,
    ) -> Result<StageTimes> {
        let times = stages.summarise(comm);
        let peak = max_over_ranks(comm, peak_rss_bytes().unwrap_or(0) as f64);
        self.figure("peak_rss_bytes_max", peak);
        for t in &times.0 {
            self.figure(&format!("stage_{}_min_s", t.stage.name()), format!("{:.6}", t.min));
            self.figure(&format!("stage_{}_max_s", t.stage.name()), format!("{:.6}", t.max));
        }
        if let Some(path) = timings {
            on_root(comm, || {
                io::write_atomically(path, |tmp| {
                    std::fs::write(tmp, self.to_csv()).map_err(|e| Error::io(tmp, &e))
                })
            })?;
        }
        if comm.rank() == 0 {
            let mut out = format!("{}\n", self.title);
            for l in &self.lines {
                out.push_str(&format!("  {l}\n"));
            }
            out.push_str(&times.table());
            for l in after_table(&times) {
                out.push_str(&format!("  {l}\n"));
            }
            if peak > 0.0 {
                out.push_str(&format!("  peak memory per rank (max over ranks): {:.1} MB\n", peak / 1e6));
            }
            if !self.outputs.is_empty() {
                out.push_str("  outputs:\n");
                for o in &self.outputs {
                    out.push_str(&format!("    {}\n", o.display()));
                }
            }
            print!("{out}");
        }
        Ok(times)
    }
}

/// Progress of a long stage on rank 0, redrawn in place on a terminal, silent otherwise.
pub struct Progress {
    label: &'static str,
    enabled: bool,
    last: std::cell::Cell<i64>,
}

impl Progress {
    pub fn new(label: &'static str, comm: &dyn Comm) -> Self {
        let enabled = comm.rank() == 0 && std::io::stderr().is_terminal();
        Progress { label, enabled, last: std::cell::Cell::new(-1) }
    }

    /// Reports `done` of `total` units.
    pub fn update(&self, done: usize, total: usize) {
        if !self.enabled || total == 0 {
            return;
        }
        let pct = (100 * done / total) as i64;
        if pct != self.last.get() {
            self.last.set(pct);
            let mut e = std::io::stderr();
            let _ = write!(e, "\r  {}: {:>3}%", self.label, pct);
            if done >= total {
                let _ = writeln!(e);
            }
            let _ = e.flush();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::par::Solo;

    #[test]
    fn stages_sum_and_only_those_that_ran_are_reported() {
        let mut s = Stages::default();
        s.add(Stage::Solve, 1.5);
        s.add(Stage::Read, 0.25);
        s.add(Stage::Solve, 0.5);
        let t = s.summarise(&Solo);
        assert_eq!(t.0.iter().map(|x| x.stage).collect::<Vec<_>>(), [Stage::Read, Stage::Solve]);
        assert_eq!(t.max(Stage::Solve), 2.0);
        assert_eq!(t.max(Stage::Mesh), 0.0);
        assert!(t.table().contains("total            2.250"));
    }

    #[test]
    fn csv_escapes_commas_and_keeps_order() {
        let mut r = Report::new("fit", Path::new("a,b.xyz"));
        r.figure("input", "a,b.xyz");
        assert_eq!(r.to_csv(), "key,value\ncommand,fit\ninput,a;b.xyz\n");
    }
}
