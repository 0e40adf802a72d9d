//! The report of a command: [`Report`] holds its lines of text for people and its `key,value`
//! figures for scripts; [`Report::finish`] adds the stage times and the peak memory, prints it on
//! rank 0 and writes the CSV of `--timings`.

use std::path::{Path, PathBuf};

use super::stages::{StageTimes, Stages};
use crate::error::{Error, Result};
use crate::io;
use crate::par::{max_over_ranks, on_root, Comm};
use crate::spline::Provenance;

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
        r.figure("version", crate::cli::VERSION);
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
        let estimate = max_over_ranks(comm, super::preflight::largest_need().unwrap_or(0.0));
        if estimate > 0.0 {
            self.figure("memory_estimate_bytes_max", format!("{estimate:.0}"));
        }
        for t in &times.stages {
            self.figure(&format!("stage_{}_min_s", t.stage.name()), format!("{:.6}", t.min));
            self.figure(&format!("stage_{}_max_s", t.stage.name()), format!("{:.6}", t.max));
        }
        // a part's stages (level 0's within `coarse`) as `coarse_stage_factor_max_s` and so on:
        // not named stage_..., so that scripts summing the stages' figures do not count them twice
        if let Some((parent, part)) = &times.part {
            for t in part {
                let key = format!("{}_stage_{}", parent.name(), t.stage.name());
                self.figure(&format!("{key}_min_s"), format!("{:.6}", t.min));
                self.figure(&format!("{key}_max_s"), format!("{:.6}", t.max));
            }
        }
        // the table's total row (not named stage_..., so that scripts summing the stages' figures
        // do not count it twice; their sum counts the wait of the solve twice)
        let (total_min, total_max) = times.total();
        self.figure("total_min_s", format!("{total_min:.6}"));
        self.figure("total_max_s", format!("{total_max:.6}"));
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
                out.push_str(&format!("  peak memory per rank (max over ranks): {:.1} MB", peak / 1e6));
                if estimate > 0.0 {
                    // what --memory-per-rank and the node's memory were compared with
                    out.push_str(&format!(" (the memory checks counted up to {:.1} MB)", estimate / 1e6));
                }
                out.push('\n');
            }
            if !self.outputs.is_empty() {
                out.push_str("  outputs:\n");
                for o in &self.outputs {
                    out.push_str(&format!("    {}\n", o.display()));
                }
            }
            print_report(&out);
        }
        Ok(times)
    }
}

/// Prints the report `text` on standard output. A standard output whose reader has gone (`fit
/// ... | head -1`, or a launcher that stopped forwarding it) loses the report, not the run: the
/// outputs are still renamed into place, and a warning on standard error says why the report is
/// missing. (`print!` would panic there, and the panic would abort the job with its outputs
/// left under their temporary names.)
fn print_report(text: &str) {
    use std::io::Write;
    let mut out = std::io::stdout().lock();
    if let Err(e) = out.write_all(text.as_bytes()).and_then(|()| out.flush()) {
        let _ = writeln!(
            std::io::stderr(),
            "volspline: warning: the report could not be printed on standard output ({e}); the outputs are \
             written all the same"
        );
    }
}

/// The part of a model's provenance that describes the run rather than the data: ranks, threads,
/// the stage times so far and the version. Collective (the times are summarised over ranks).
pub fn run_provenance(comm: &dyn Comm, threads: usize, stages: &Stages) -> Provenance {
    Provenance {
        ranks: comm.size(),
        threads,
        timings: stages.summarise(comm).named_max(),
        version: crate::cli::VERSION.to_string(),
        ..Provenance::default()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn csv_escapes_commas_and_keeps_order() {
        let mut r = Report::new("fit", Path::new("a,b.xyz"));
        r.figure("input", "a,b.xyz");
        let version = crate::cli::VERSION;
        assert_eq!(r.to_csv(), format!("key,value\ncommand,fit\nversion,{version}\ninput,a;b.xyz\n"));
    }
}
