//! The progress line of a long stage, drawn by rank 0 when it writes to a terminal.

use std::io::{IsTerminal, Write};

use crate::par::Comm;

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
