//! The progress bar of a long stage (the dense solve, the grid evaluation, the ray casting), or
//! the ticking line of one whose work cannot be counted (the sparse factorisation), drawn by
//! rank 0 on its standard error for a person watching.
//!
//! When to draw is `--progress` ([`set_mode`]): `auto` draws where rank 0's standard error is a
//! terminal, so that output redirected to files holds the report alone. Open MPI's `mpirun`
//! hands every rank a pseudo-terminal for standard output whatever the user's terminal is, and
//! a pipe for standard error, so neither tells whether a person watches: under it `auto` draws
//! nothing, and `on` draws on standard error all the same (it reaches the user's terminal
//! through the launcher, escape codes and all).

use std::io::{IsTerminal, Write};
use std::sync::OnceLock;
use std::time::Duration;

use indicatif::{HumanDuration, ProgressBar, ProgressDrawTarget, ProgressState, ProgressStyle, TermLike};

use crate::par::Comm;

/// When progress bars are drawn (`--progress`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mode {
    /// Where rank 0's standard error is a terminal.
    Auto,
    /// Always, on rank 0's standard error.
    On,
    /// Never.
    Off,
}

impl Mode {
    pub fn parse(s: &str) -> Result<Mode, String> {
        match s {
            "auto" => Ok(Mode::Auto),
            "on" => Ok(Mode::On),
            "off" => Ok(Mode::Off),
            other => Err(format!("expected auto, on or off, not '{other}'")),
        }
    }
}

static MODE: OnceLock<Mode> = OnceLock::new();

/// Sets when bars are drawn for the rest of the run (the first call holds; `auto` without one).
/// Called once, by the binary, from the command line.
pub fn set_mode(mode: Mode) {
    let _ = MODE.set(mode);
}

/// Progress of a long stage on rank 0, redrawn in place, silent where no bar is drawn. The bar
/// appears with the first report, so its clock starts with the work; threads may report.
pub struct Progress {
    label: &'static str,
    draw: bool,
    /// Whether the units reported are columns of a dense factorisation, whose trailing updates
    /// shrink as the square of the columns left: the bar then shows the share of the flops done.
    columns: bool,
    bar: OnceLock<ProgressBar>,
}

/// Steps of a bar that shows the flops of a factorisation.
const FLOP_STEPS: u64 = 1000;

impl Progress {
    /// A bar named `label`, drawn on rank 0 as the mode says (see the module doc). Not
    /// collective.
    pub fn new(label: &'static str, comm: &dyn Comm) -> Self {
        let draw = comm.rank() == 0
            && match MODE.get().copied().unwrap_or(Mode::Auto) {
                Mode::Auto => std::io::stderr().is_terminal(),
                Mode::On => true,
                Mode::Off => false,
            };
        Progress { label, draw, columns: false, bar: OnceLock::new() }
    }

    /// [`Progress::new`] for a dense factorisation that reports its columns done: the bar
    /// counts its flops, 1 - (1 - done / total)^3 of them, so that its estimate of the time
    /// left holds from the start.
    pub fn columns(label: &'static str, comm: &dyn Comm) -> Self {
        let mut p = Self::new(label, comm);
        p.columns = true;
        p
    }

    /// A stage whose work cannot be counted from outside (a sparse factorisation inside faer or
    /// MUMPS, which can take minutes at a million points): a line with a spinner, the time spent
    /// and `what`, redrawn twice a second from now until [`Progress::done`], where it stays with
    /// the time the stage took. Drawn on rank 0 as the mode says. Not collective.
    pub fn ticking(label: &'static str, what: String, comm: &dyn Comm) -> Self {
        let p = Self::new(label, comm);
        if p.draw {
            let style = ProgressStyle::with_template("  {prefix:<8} {spinner} {elapsed} elapsed, {msg}")
                .expect("a valid template")
                .tick_chars("-\\|/ ");
            let target = ProgressDrawTarget::term_like_with_hz(Box::new(Stderr), 10);
            let bar = ProgressBar::with_draw_target(None, target).with_prefix(label).with_message(what);
            bar.set_style(style);
            bar.tick();
            bar.enable_steady_tick(Duration::from_millis(500));
            let _ = p.bar.set(bar);
        }
        p
    }

    /// Ends a [`Progress::ticking`] stage: its line stays, with the time it took.
    pub fn done(&self) {
        if let Some(bar) = self.bar.get().filter(|b| !b.is_finished()) {
            bar.finish();
            let _ = writeln!(std::io::stderr());
        }
    }

    fn bar(&self, total: u64) -> ProgressBar {
        let style = ProgressStyle::with_template(
            "  {prefix:<8} [{bar:32}] {percent:>3}%  {elapsed} elapsed, about {eta} left",
        )
        .expect("a valid template")
        .with_key("eta", |s: &ProgressState, w: &mut dyn std::fmt::Write| {
            let _ = w.write_str(&time_left(s.pos(), s.eta()));
        })
        .progress_chars("=> ");
        let target = ProgressDrawTarget::term_like_with_hz(Box::new(Stderr), 10);
        let bar = ProgressBar::with_draw_target(Some(total), target);
        bar.set_style(style);
        bar.set_prefix(self.label);
        bar
    }

    /// Reports `done` of `total` units; the bar ends, drawn full on a line of its own, once
    /// `done` reaches `total` (and only then).
    pub fn update(&self, done: usize, total: usize) {
        if !self.draw || total == 0 {
            return;
        }
        let (done, total) = if self.columns {
            // floored: full at the last column alone
            let left = 1.0 - done.min(total) as f64 / total as f64;
            (((1.0 - left.powi(3)) * FLOP_STEPS as f64).floor() as u64, FLOP_STEPS)
        } else {
            (done.min(total) as u64, total as u64)
        };
        let mut fresh = false;
        let bar = self.bar.get_or_init(|| {
            fresh = true;
            self.bar(total)
        });
        if bar.is_finished() {
            return;
        }
        // each of these draws the bar: only what changed, so that an update draws it once
        if bar.length() != Some(total) {
            bar.set_length(total);
        }
        // threads may report out of order, or the same count again: the bar never goes back
        if done >= total {
            // drawn once more, full
            bar.finish();
            // the bar leaves the cursor at its end, where the next message would go on
            let _ = writeln!(std::io::stderr());
        } else if done > bar.position() {
            bar.set_position(done);
        } else if fresh {
            bar.tick();
        }
    }
}

impl Drop for Progress {
    /// A stage that ended early (an error) leaves no half bar behind.
    fn drop(&mut self) {
        if let Some(bar) = self.bar.get() {
            if !bar.is_finished() {
                bar.finish_and_clear();
            }
        }
    }
}

/// Standard error as a terminal that understands ANSI cursor movement, whatever it is connected
/// to (a launcher's pipe that ends on a terminal).
#[derive(Debug)]
struct Stderr;

impl Stderr {
    fn put(&self, s: &str) -> std::io::Result<()> {
        std::io::stderr().write_all(s.as_bytes())
    }

    /// Moves the cursor `n` places in the direction of the ANSI code `code` (none for 0).
    fn cursor(&self, n: usize, code: char) -> std::io::Result<()> {
        if n > 0 {
            self.put(&format!("\x1b[{n}{code}"))?;
        }
        Ok(())
    }
}

impl TermLike for Stderr {
    fn width(&self) -> u16 {
        100
    }

    fn move_cursor_up(&self, n: usize) -> std::io::Result<()> {
        self.cursor(n, 'A')
    }

    fn move_cursor_down(&self, n: usize) -> std::io::Result<()> {
        self.cursor(n, 'B')
    }

    fn move_cursor_right(&self, n: usize) -> std::io::Result<()> {
        self.cursor(n, 'C')
    }

    fn move_cursor_left(&self, n: usize) -> std::io::Result<()> {
        self.cursor(n, 'D')
    }

    fn write_line(&self, s: &str) -> std::io::Result<()> {
        self.put(&format!("{s}\n"))
    }

    fn write_str(&self, s: &str) -> std::io::Result<()> {
        self.put(s)
    }

    fn clear_line(&self) -> std::io::Result<()> {
        self.put("\r\x1b[2K")
    }

    fn flush(&self) -> std::io::Result<()> {
        std::io::stderr().flush()
    }
}

/// The time left as a bar shows it: unknown (`?`) while none of the work is done, where the rate
/// is nothing to go by yet (the library's own estimate says 0 s there), else the estimate.
fn time_left(done: u64, estimate: Duration) -> String {
    if done == 0 {
        "?".to_string()
    } else {
        format!("{:#}", HumanDuration(estimate))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::par::Solo;

    #[test]
    fn the_time_left_is_unknown_until_some_work_is_done() {
        assert_eq!(time_left(0, Duration::ZERO), "?");
        assert_eq!(time_left(0, Duration::from_secs(7)), "?");
        assert_eq!(
            time_left(5, Duration::from_secs(7)),
            format!("{:#}", HumanDuration(Duration::from_secs(7)))
        );
        assert_ne!(time_left(5, Duration::from_secs(90)), "?");
    }

    #[test]
    fn a_factorisation_bar_counts_flops_and_ends_with_the_last_column() {
        let mut p = Progress::columns("solve", &Solo);
        p.draw = true;
        let bar = ProgressBar::hidden();
        p.bar.set(bar.clone()).unwrap();
        // half the columns are seven eighths of the flops
        p.update(500, 1000);
        assert_eq!((bar.position(), bar.length()), (875, Some(FLOP_STEPS)));
        // the last columns but one leave the bar open, and it never goes back
        p.update(999, 1000);
        assert!(bar.position() < FLOP_STEPS && !bar.is_finished());
        p.update(10, 1000);
        assert_eq!(bar.position(), 999);
        p.update(1000, 1000);
        assert!(bar.is_finished() && bar.position() == FLOP_STEPS);
    }
}
