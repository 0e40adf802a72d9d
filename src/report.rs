//! Run-time reporting: named stages timed on every rank and printed as a min/max table on rank 0
//! (PETSc's -log_view in small), and progress lines for long stages when rank 0 writes to a
//! terminal.

use std::io::{IsTerminal, Write};
use std::time::Instant;

use crate::dist::Comm;

/// Wall-clock seconds of each named stage on this rank, in the order they ran.
#[derive(Debug, Default, Clone)]
pub struct Stages {
    entries: Vec<(String, f64)>,
}

/// Min and max over ranks of one stage.
#[derive(Debug, Clone, PartialEq)]
pub struct StageTime {
    pub name: String,
    pub min: f64,
    pub max: f64,
}

impl Stages {
    /// Runs `f` as stage `name` and records its time.
    pub fn time<T>(&mut self, name: &str, f: impl FnOnce() -> T) -> T {
        let t = Instant::now();
        let out = f();
        self.add(name, t.elapsed().as_secs_f64());
        out
    }

    /// Adds `seconds` to stage `name` (created on first use).
    pub fn add(&mut self, name: &str, seconds: f64) {
        match self.entries.iter_mut().find(|(n, _)| n == name) {
            Some(e) => e.1 += seconds,
            None => self.entries.push((name.to_string(), seconds)),
        }
    }

    /// Min/max over ranks of every stage. Collective; every rank must have run the same stages.
    pub fn summarise(&self, comm: &dyn Comm) -> Vec<StageTime> {
        let mut mins: Vec<f64> = self.entries.iter().map(|e| e.1).collect();
        let mut maxs = mins.clone();
        comm.min_f64(&mut mins);
        comm.max_f64(&mut maxs);
        self.entries
            .iter()
            .zip(mins.iter().zip(&maxs))
            .map(|((name, _), (&min, &max))| StageTime { name: name.clone(), min, max })
            .collect()
    }
}

/// The stage table as printed.
pub fn stage_table(times: &[StageTime]) -> String {
    let mut s = String::from("  stage          min [s]     max [s]\n");
    let mut total = (0.0, 0.0);
    for t in times {
        s.push_str(&format!("  {:<12} {:>9.3}   {:>9.3}\n", t.name, t.min, t.max));
        total.0 += t.min;
        total.1 += t.max;
    }
    s.push_str(&format!("  {:<12} {:>9.3}   {:>9.3}\n", "total", total.0, total.1));
    s
}

/// This process's peak resident memory (VmHWM) in bytes, where the system reports it (Linux).
pub fn peak_rss_bytes() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

/// Largest peak resident memory over ranks, in bytes (0 where unknown). Collective.
pub fn peak_rss_max(comm: &dyn Comm) -> f64 {
    let mut v = [peak_rss_bytes().unwrap_or(0) as f64];
    comm.max_f64(&mut v);
    v[0]
}

/// A machine-readable record of a run: `key,value` lines (written by `--timings`).
#[derive(Debug, Default, Clone)]
pub struct Record {
    pub entries: Vec<(String, String)>,
}

impl Record {
    pub fn put(&mut self, key: &str, value: impl std::fmt::Display) {
        self.entries.push((key.to_string(), value.to_string()));
    }

    pub fn stages(&mut self, times: &[StageTime]) {
        for t in times {
            self.put(&format!("stage_{}_min_s", t.name), format!("{:.6}", t.min));
            self.put(&format!("stage_{}_max_s", t.name), format!("{:.6}", t.max));
        }
    }

    pub fn to_csv(&self) -> String {
        let mut s = String::from("key,value\n");
        for (k, v) in &self.entries {
            s.push_str(&format!("{k},{}\n", v.replace(',', ";")));
        }
        s
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

    /// A progress that never prints (tests, library use).
    pub fn silent() -> Self {
        Progress { label: "", enabled: false, last: std::cell::Cell::new(-1) }
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
