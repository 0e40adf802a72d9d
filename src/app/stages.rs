//! Named stages of a run timed on every rank, keyed by the [`Stage`] enum (so no name can drift),
//! and summarised as min and max over ranks for the stage table.

use std::time::Instant;

use crate::par::Comm;

/// The stages of a run, in the order they are printed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stage {
    Read,
    Normals,
    Orient,
    Coarse,
    Tree,
    Assemble,
    Factor,
    Solve,
    /// The ray test of an off-surface fit's normals through its first fit.
    Rays,
    /// The blob search of an off-surface fit: the first fit sampled on a lattice, the spurious
    /// nodes found, and the clearance choice between the candidate fits.
    Blobs,
    /// The patches of an off-surface fit's normals tried against the unsupported surface (their
    /// fits are counted in the solve).
    Turns,
    Check,
    Evaluate,
    Mesh,
    Write,
    Slice,
    Render,
    /// Time spent in communication calls (inside the other stages, not added to the total).
    CommWait,
}

impl Stage {
    pub const ALL: [Stage; 18] = [
        Stage::Read,
        Stage::Normals,
        Stage::Orient,
        Stage::Coarse,
        Stage::Tree,
        Stage::Assemble,
        Stage::Factor,
        Stage::Solve,
        Stage::Rays,
        Stage::Blobs,
        Stage::Turns,
        Stage::Check,
        Stage::Evaluate,
        Stage::Mesh,
        Stage::Write,
        Stage::Slice,
        Stage::Render,
        Stage::CommWait,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Stage::Read => "read",
            Stage::Normals => "normals",
            Stage::Orient => "orient",
            Stage::Coarse => "coarse",
            Stage::Tree => "tree",
            Stage::Assemble => "assemble",
            Stage::Factor => "factor",
            Stage::Solve => "solve",
            Stage::Rays => "rays",
            Stage::Blobs => "blobs",
            Stage::Turns => "turns",
            Stage::Check => "check",
            Stage::Evaluate => "evaluate",
            Stage::Mesh => "mesh",
            Stage::Write => "write",
            Stage::Slice => "slice",
            Stage::Render => "render",
            Stage::CommWait => "comm_wait",
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

    /// The stage table as printed; the time spent waiting in communication, part of the other
    /// stages, follows the total.
    pub fn table(&self) -> String {
        let mut s = String::from("  stage          min [s]     max [s]\n");
        for t in self.0.iter().filter(|t| t.stage != Stage::CommWait) {
            s.push_str(&format!("  {:<12} {:>9.3}   {:>9.3}\n", t.stage.name(), t.min, t.max));
        }
        let total = self.total();
        s.push_str(&format!("  {:<12} {:>9.3}   {:>9.3}\n", "total", total.0, total.1));
        for t in self.0.iter().filter(|t| t.stage == Stage::CommWait) {
            s.push_str(&format!("  {:<12} {:>9.3}   {:>9.3}   (of solve)\n", "comm wait", t.min, t.max));
        }
        s
    }

    /// The table's total: the sums of the stages' min and of their max times, the communication
    /// wait left out (it is part of the solve).
    pub fn total(&self) -> (f64, f64) {
        self.0
            .iter()
            .filter(|t| t.stage != Stage::CommWait)
            .fold((0.0, 0.0), |(lo, hi), t| (lo + t.min, hi + t.max))
    }

    /// (name, max seconds) of every stage, as a model file records them.
    pub fn named_max(&self) -> Vec<(String, f64)> {
        self.0.iter().map(|t| (t.stage.name().to_string(), t.max)).collect()
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
        s.add(Stage::CommWait, 0.75);
        let t = s.summarise(&Solo);
        assert_eq!(t.max(Stage::CommWait), 0.75);
        let table = t.table();
        assert!(table.contains("total            2.250"), "{table}");
        assert!(table.contains("comm wait        0.750"), "{table}");
        assert_eq!(t.total(), (2.25, 2.25), "the wait is part of the solve, not added");
    }
}
