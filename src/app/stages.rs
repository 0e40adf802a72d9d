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
    /// A part of the run with a stage table of its own that is timed as a whole as one stage
    /// (level 0 of a two-level fit, timed as `coarse`): that stage and the part's stages.
    part: Option<(Stage, Box<Stages>)>,
}

/// Min and max over ranks of one stage.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StageTime {
    pub stage: Stage,
    pub min: f64,
    pub max: f64,
}

/// The stages that ran, summarised over ranks, and those of a part of the run timed as one of
/// them (see [`Stages::add_part`]).
#[derive(Debug, Clone, Default)]
pub struct StageTimes {
    pub stages: Vec<StageTime>,
    pub part: Option<(Stage, Vec<StageTime>)>,
}

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

    /// Records the stage table of a part of the run that was timed as a whole as `stage` (level
    /// 0 of a two-level fit as `coarse`), for the report to itemise under that stage. The
    /// part's times are not added: `stage` already holds them.
    pub fn add_part(&mut self, stage: Stage, part: Stages) {
        self.part = Some((stage, Box::new(part)));
    }

    /// Min/max over ranks of every stage that ran on any rank, and of the part's stages.
    /// Collective: the reductions are the same on every rank whether or not it holds a part.
    pub fn summarise(&self, comm: &dyn Comm) -> StageTimes {
        let n = Stage::ALL.len();
        let empty = Stages::default();
        let (parent, part) = match &self.part {
            Some((stage, part)) => (*stage as usize as f64, part.as_ref()),
            None => (-1.0, &empty),
        };
        let ran = |s: &Stages| s.ran.iter().map(|&r| f64::from(u8::from(r))).collect::<Vec<f64>>();
        let mut v =
            [&self.seconds[..], &ran(self)[..], &part.seconds[..], &ran(part)[..], &[parent]].concat();
        let mut mins = [&self.seconds[..], &part.seconds[..]].concat();
        comm.max_f64(&mut v);
        comm.min_f64(&mut mins);
        let times = |seconds: &[f64], ran: &[f64], mins: &[f64]| -> Vec<StageTime> {
            Stage::ALL
                .iter()
                .filter(|s| ran[**s as usize] > 0.0)
                .map(|&stage| StageTime { stage, min: mins[stage as usize], max: seconds[stage as usize] })
                .collect()
        };
        let stages = times(&v[..n], &v[n..2 * n], &mins[..n]);
        let part = (v[4 * n] >= 0.0).then(|| {
            let parent = Stage::ALL[v[4 * n] as usize];
            (parent, times(&v[2 * n..3 * n], &v[3 * n..4 * n], &mins[n..]))
        });
        StageTimes { stages, part }
    }
}

impl StageTimes {
    /// The largest time of `stage` over ranks (0 when it did not run).
    pub fn max(&self, stage: Stage) -> f64 {
        self.stages.iter().find(|t| t.stage == stage).map_or(0.0, |t| t.max)
    }

    /// The stage table as printed; the time spent waiting in communication, part of the other
    /// stages, follows the total.
    pub fn table(&self) -> String {
        let mut s = String::from("  stage          min [s]     max [s]\n");
        for t in self.stages.iter().filter(|t| t.stage != Stage::CommWait) {
            s.push_str(&format!("  {:<12} {:>9.3}   {:>9.3}\n", t.stage.name(), t.min, t.max));
            // the part's own stages, indented under the stage that timed it
            if let Some((_, part)) = self.part.as_ref().filter(|(parent, _)| *parent == t.stage) {
                for p in part.iter().filter(|p| p.stage != Stage::CommWait) {
                    s.push_str(&format!("    {:<10} {:>9.3}   {:>9.3}\n", p.stage.name(), p.min, p.max));
                }
            }
        }
        let total = self.total();
        s.push_str(&format!("  {:<12} {:>9.3}   {:>9.3}\n", "total", total.0, total.1));
        for t in self.stages.iter().filter(|t| t.stage == Stage::CommWait) {
            s.push_str(&format!("  {:<12} {:>9.3}   {:>9.3}   (of solve)\n", "comm wait", t.min, t.max));
        }
        s
    }

    /// The table's total: the sums of the stages' min and of their max times, the communication
    /// wait left out (it is part of the solve).
    pub fn total(&self) -> (f64, f64) {
        self.stages
            .iter()
            .filter(|t| t.stage != Stage::CommWait)
            .fold((0.0, 0.0), |(lo, hi), t| (lo + t.min, hi + t.max))
    }

    /// (name, max seconds) of every stage, as a model file records them.
    pub fn named_max(&self) -> Vec<(String, f64)> {
        self.stages.iter().map(|t| (t.stage.name().to_string(), t.max)).collect()
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
        assert_eq!(t.stages.iter().map(|x| x.stage).collect::<Vec<_>>(), [Stage::Read, Stage::Solve]);
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

    #[test]
    fn a_part_s_stages_are_itemised_under_the_stage_that_timed_it() {
        let mut part = Stages::default();
        part.add(Stage::Normals, 0.25);
        part.add(Stage::Solve, 0.5);
        let mut s = Stages::default();
        s.add(Stage::Read, 0.125);
        s.add(Stage::Coarse, 1.0);
        s.add_part(Stage::Coarse, part);
        s.add(Stage::Evaluate, 2.0);
        let t = s.summarise(&Solo);
        assert_eq!(t.total(), (3.125, 3.125), "the part is not added again");
        let (parent, stages) = t.part.as_ref().unwrap();
        assert_eq!(*parent, Stage::Coarse);
        assert_eq!(
            stages.iter().map(|x| (x.stage, x.max)).collect::<Vec<_>>(),
            [(Stage::Normals, 0.25), (Stage::Solve, 0.5)]
        );
        let table = t.table();
        let rows: Vec<&str> = table.lines().map(str::trim_end).collect();
        assert_eq!(rows[2], "  coarse           1.000       1.000", "{table}");
        assert_eq!(rows[3], "    normals        0.250       0.250", "{table}");
        assert_eq!(rows[4], "    solve          0.500       0.500", "{table}");
        assert!(rows[5].starts_with("  evaluate "), "{table}");
        assert_eq!(t.named_max().len(), 3, "the model's timings are the run's stages");
        assert!(Stages::default().summarise(&Solo).part.is_none());
    }
}
