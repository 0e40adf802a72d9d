//! The surface method of `fit`: the data alone (the plain carrier method), or the data with
//! off-surface constraints from estimated and oriented normals ([`crate::surface`]), which enter
//! the dense and the compactly supported systems as further centres. After the first fit,
//! patches of normals that rays through it show turned inward are turned back
//! ([`crate::surface::rays`]), regions it makes positive with no data to support them are pinned
//! negative ([`crate::surface::blobs`]), and where either changed something the spline is fitted
//! once more.

use super::dense::{self, KeptFactor};
use super::{Fitted, Run};
use crate::app::stages::{Stage, Stages};
use crate::cli::{FitArgs, SideVote, Surface};
use crate::error::Result;
use crate::par::{agree, Comm};
use crate::spline::carrier::Carrier;
use crate::spline::hygiene::Prepared;
use crate::spline::{Kernel, Spline};
use crate::surface::blobs::{
    blob_values, data_cells, lost_solid, paths_to_solid, points_without_solid, sample, sample_nodes,
    sample_window, winding_numbers, Blobs, Lattice, Search, CLEARANCE, INSIDE, OPEN_SPACE, RESTORE_FROM,
    SECOND_ROUND_FROM,
};
use crate::surface::choice::{self, unsupported_share};
use crate::surface::denoise::Denoised;
use crate::surface::energy::{flip_by_energy, EnergyFlips};
use crate::surface::outside;
use crate::surface::rays::{self, RayCheck};
use crate::surface::sheets;
use crate::surface::support::DataSupport;
use crate::surface::turns::{self, SideTry, TurnCheck};
use crate::surface::{
    self, neighbourhoods_on, off_points_by_trust, off_values, off_values_sloped, Doubt, Neighbourhoods,
    OffPoints,
};

/// Fewest points for which `--surface auto` adds off-surface constraints.
pub const AUTO_MIN_POINTS: usize = 50;

/// The carrier of the off-surface fit under `--carrier auto`: the ellipsoid fitted to the points
/// with the spread of its semi-axes scaled by 0.3 on a log scale (`spline::carrier`, "The fitted
/// ellipsoid"). Only the shape of the carrier's quadratic part shapes the solid, and across a
/// hole in a scan the zero set continues the field from it. Measured on the surface benchmark's
/// 359 sets (README, "The carrier of the default"): under a ball the caps over a hole in a flank
/// sag into the body (3 of the 60 sets with such a hole met every target, 28 with this
/// ellipsoid, 30 with the spread halved), while over a hole at the end of the long axis the
/// ellipsoid's caps are the flatter (294 of the other 299 sets met every target with the ball,
/// 293 with this one, 290 with the spread halved; its sums of distances are the lowest of the
/// three on both groups).
pub const AUTO_CARRIER: Carrier = Carrier::AutoEllipsoid { spread: 0.3 };

/// Data points below which the turns of step 7 run without a kept factor (a dense solver the
/// user chose that keeps none, or a 2D factor without room for its row-cyclic copy): each try
/// is then a fresh fit, milliseconds on these systems.
const FRESH_TRIES_BELOW: usize = 1000;

/// What the off-surface step did, for the report.
#[derive(Debug, Clone)]
pub struct SurfaceSummary {
    pub off_points: usize,
    pub dropped: usize,
    /// Data points whose normals disagree with their neighbours' (a reduced off-point rate), and
    /// the share of the rate they get.
    pub doubtful: usize,
    pub doubtful_share: f64,
    /// Smallest and largest delta in the caller's units.
    pub delta: (f64, f64),
    pub components: usize,
    pub patches: usize,
    pub flipped: usize,
    pub dense_dipole: bool,
    /// Patches turned by the side vote (None: not run).
    pub side_turned: Option<usize>,
    /// With `--orient-side both`: the unsupported crossings left by the fit without the side
    /// vote and by that with it (see [`unsupported_left`]), and whether the one with it was
    /// kept (None: one fit made).
    pub side_choice: Option<(Option<usize>, Option<usize>, bool)>,
    /// The patch orientation by energy (None: not asked for).
    pub energy: Option<EnergyFlips>,
    /// Constraint points added by the second fit against spurious blobs (0: no second fit).
    pub blob_points: usize,
    /// Positive regions of the first fit that came nowhere near the data.
    pub blob_regions: usize,
    /// Nodes the vote of the blob search found outside that the data enclose (spared).
    pub blob_spared: usize,
    /// The ray test of the first fit (None: no first fit was checked).
    pub rays: Option<RayCheck>,
    /// The choice between the blob search's wide and narrow clearances (None: not made, since
    /// `--blob-choice off` or both pinned the same nodes).
    pub choice: Option<ClearanceChoice>,
    /// The blob search's second round, on the second fit (None: not made, since the cap pinned
    /// at least 1 / [`SECOND_ROUND_FROM`] of the spurious nodes or `--blob-choice off`).
    pub second_round: Option<SecondRound>,
    /// Solid the pins took from data points given back (None: nothing lost, or
    /// `--restore-solid off`).
    pub restored: Option<Restored>,
    /// The patches turned by the unsupported surface (None: not run, since `--orient-turns off`
    /// or the system is too large to refit afresh and kept no factor).
    pub turns: Option<TurnCheck>,
    /// Whether the turns were asked for but skipped: the system was too large to refit afresh
    /// for each try and kept no factor.
    pub turns_skipped: bool,
    /// Whether the outside off points after the turns were asked for but skipped, as the turns
    /// are: the system was too large to refit afresh and kept no factor.
    pub outside_skipped: bool,
    /// Whether the off points at the mouths of holes were asked for but skipped, as the turns
    /// are.
    pub mouth_skipped: bool,
    /// The outside off points after the turns (None: not run, since `--outside-points off`, the
    /// system was too large to refit afresh and kept no factor, or no crossing was charged to a
    /// point without an off point).
    pub outside: Option<OutsideCheck>,
    /// The off points at the mouths of holes, last (None: not run, since `--mouth-points off` or
    /// the system was too large to refit afresh and kept no factor).
    pub mouth: Option<MouthPoints>,
    /// The normals oriented again by side where the first fit's solid spilled far beyond the
    /// data (None: it did not).
    pub sides: Option<SideCheck>,
    /// Where the ranks' memory allowed the second fits fewer appended centres than the steps
    /// wanted (None: never).
    pub memory_limit: Option<MemoryLimit>,
}

/// The ranks' memory limiting the centres the second fits append (see [`check_first_fit`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MemoryLimit {
    /// The most centres a second fit could append.
    pub room: usize,
    /// The most a step wanted to append (blob points, a second round's on top of them, or the
    /// nodes of the solid given back).
    pub wanted: usize,
}

impl MemoryLimit {
    /// Records that a step wanted to append `wanted` centres where there was room for `room`.
    fn record(limit: &mut Option<MemoryLimit>, room: usize, wanted: usize) {
        let wanted = limit.map_or(wanted, |l| l.wanted.max(wanted));
        *limit = Some(MemoryLimit { room, wanted });
    }
}

impl SurfaceSummary {
    /// The fits made: one, a second where rays turned patches or blobs were pinned, or the first
    /// and the candidates of the clearance choice; then the second round's and the turns' tries.
    pub fn fits(&self) -> usize {
        let tried = self.turns.as_ref().map_or(0, |t| t.tried)
            + self.outside.as_ref().map_or(0, |o| usize::from(o.points > 0 && !o.no_room))
            + self.mouth.as_ref().map_or(0, |m| usize::from(m.points > 0 && !m.no_room));
        let second = self.second_round.as_ref().is_some_and(|r| r.points > 0);
        let restored = self.restored.as_ref().is_some_and(|r| r.points > 0);
        tried
            + usize::from(second)
            + usize::from(restored)
            + match &self.choice {
                Some(ch) => ch.fits,
                None if self.blob_points > 0 || self.rays.as_ref().is_some_and(|k| k.turned > 0) => 2,
                None => 1,
            }
    }
}

/// The outside off points after the turns (see [`crate::surface::outside`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OutsideCheck {
    /// Unsupported crossings in open space, and the data points they were charged to that had
    /// no off point.
    pub open: usize,
    pub charged: usize,
    /// Outside off points placed (a charged point whose place no delta kept nearest to it gets
    /// none).
    pub points: usize,
    /// Unsupported crossings before and after (the same where no fit was made).
    pub before: usize,
    pub after: usize,
    /// Whether the fit with them was kept: the crossings fell by at least
    /// [`crate::surface::turns::GAIN`] of their number.
    pub kept: bool,
    /// Whether they were not added since their fit would append more centres than the ranks'
    /// memory allows.
    pub no_room: bool,
}

/// The off points at the mouths of holes, after the outside points (see
/// [`crate::surface::outside`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MouthPoints {
    /// Unsupported crossings with the data's winding number in [`outside::MOUTH`].
    pub crossings: usize,
    /// Off points wanted on the sides the charged data points lacked, and placed (a place that
    /// no delta kept nearest to its own point is dropped); the fit with them is kept.
    pub wanted: usize,
    pub points: usize,
    /// Charged data points with the gap of a rim left out since the surface folds back there.
    pub folds: usize,
    /// Inside points that push the caps over the holes outward (`--cap-bulge`), fitted with
    /// the mouth points.
    pub caps: usize,
    /// Whether they were not added since their fit would append more centres than the ranks'
    /// memory allows.
    pub no_room: bool,
}

/// Two candidate fits, with the blob search's wide and narrow clearance of rule 2, and which was
/// kept (see [`crate::surface::choice`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ClearanceChoice {
    /// Constraint points of each candidate.
    pub wide_points: usize,
    pub narrow_points: usize,
    /// The share of each candidate's surface that no data point supports.
    pub wide_share: f64,
    pub narrow_share: f64,
    pub kept_narrow: bool,
    /// Fits made in all: the first and a second for each candidate that is not the first.
    pub fits: usize,
}

/// The blob search's second round on the second fit, where the cap of the first left most
/// spurious nodes unpinned (see [`crate::surface::blobs`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SecondRound {
    /// Constraint points added (in open space; 0: none found, no fit made).
    pub points: usize,
    /// The share of the surface no data point supports, and the data points without solid near
    /// them, before and after (the same where no fit was made; no share after where the fit left
    /// more data points without solid: it is dropped unmeasured).
    pub share: (f64, Option<f64>),
    pub without_solid: (usize, usize),
    /// Whether its fit was kept: less unsupported surface and no more points without solid.
    pub kept: bool,
}

/// Solid given back where the pins took it from data points (see [`crate::surface::blobs`],
/// "Solid given back").
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Restored {
    /// Data points whose solid was lost (no positive lattice node at their cell, where the first
    /// fit had one).
    pub lost: usize,
    /// The lost points' nodes inside the data's surface given back (0: fewer than
    /// [`RESTORE_FROM`]).
    pub points: usize,
    /// Nodes given back along the first fit's solid to the points that lost a whole part
    /// ([`paths_to_solid`]); no fit is made where this and `points` are both 0.
    pub along: usize,
    /// Data points without solid near them, before and after (the same where no fit was made).
    pub without_solid: (usize, usize),
    /// Whether its fit was kept: fewer points without solid.
    pub kept: bool,
    /// Whether the nodes were not given back since their fit would append more centres than
    /// the ranks' memory allows.
    pub no_room: bool,
}

/// The constrained points of a fit and what the blob search needs of the surface step.
pub struct Constrained {
    /// The data followed by the off-surface points (and, after [`check_first_fit`], the blob points).
    pub prep: Prepared,
    pub summary: SurfaceSummary,
    hoods: Neighbourhoods,
    normals: Vec<[f64; 3]>,
    off: OffPoints,
}

/// How many times fewer nodes a fit made again with the normals by side must spill than the first
/// fit for it to be kept (see [`spilling`]).
pub const SPILL_FALL: usize = 5;

/// What the orientation by side did where a first fit spilled (see [`crate::surface::sheets`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SideCheck {
    /// Positive nodes on the faces of the grown box, with the first fit and with the fit made
    /// again.
    pub spilled: (usize, usize),
    /// Normals turned by side.
    pub turned: usize,
    /// Whether the fit made again was kept (it spilled at most a [`SPILL_FALL`]-th as much).
    pub kept: bool,
}

/// Where the first fit `first` of `c.prep` spills solid far beyond the data (see
/// [`crate::surface::sheets`]): the normals oriented again by side, the off points made again
/// from them and the system fitted afresh, densely with `kernel` (checked for memory first,
/// keeping its factor for the second fits); that fit is returned, and `c` updated, when
/// it spills at most a [`SPILL_FALL`]-th as much. `first`'s factor is dropped before the fresh
/// fit (the two are not held at once), so a first fit kept after all goes on without one.
/// Collective.
pub fn spilling(
    run: &Run<'_>,
    kernel: Kernel,
    data: &Prepared,
    c: &mut Constrained,
    first: &mut Fitted,
    stages: &mut Stages,
) -> Result<Option<Fitted>> {
    if !run.args.orient_by_side {
        return Ok(None);
    }
    let lattice = sheets::spill_lattice(&data.box_lo, &data.box_hi, &data.norm);
    let spilled = |spline: &Spline| sheets::spilled(run.comm, &lattice, &data.carrier, spline);
    let before = stages.time(Stage::Blobs, || spilled(&first.spline));
    if before == 0 {
        return Ok(None);
    }
    let mut normals = c.normals.clone();
    let (turned, off, doubt, prep) = stages.time(Stage::Orient, || {
        let turned = sheets::orient_by_side(&data.centres, &mut normals, &c.hoods.knn, c.hoods.kmax);
        let (off, doubt) = by_trust(data, &c.hoods, &normals, run.args);
        let prep = with_off_points(data, &off);
        (turned, off, doubt, prep)
    });
    drop(first.factor.take());
    super::dense::check(run.comm, &kernel, prep.values.len(), run.args)?;
    let fit = super::dense::fit(run, kernel, &prep, true, stages)?;
    let after = stages.time(Stage::Blobs, || spilled(&fit.spline));
    // a decisive fall: a sheet's solid spilling on one side is gone, or nearly (0-33 of 327-339
    // nodes left on the thin ellipsoids measured), while the carrier's solid that a first fit
    // leaves round a long thin scan (the bunny stretched 25 times: 187 nodes) only shrinks (56)
    let kept = after * SPILL_FALL <= before;
    c.summary.sides = Some(SideCheck { spilled: (before, after), turned, kept });
    if !kept {
        return Ok(None);
    }
    c.summary.off_points = off.side.len();
    c.summary.dropped = off.dropped;
    c.summary.doubtful = doubt.count;
    c.summary.doubtful_share = doubt.share;
    c.summary.delta = delta_range(&off, data.norm.scale);
    (c.normals, c.off, c.prep) = (normals, off, prep);
    Ok(Some(fit))
}

/// The likely cause of an off-surface fit's solid that reaches the grid's faces however far the
/// grid grows, for the warning: normals oriented alike on both sides of a part thinner than the
/// spacing of the points, so that the solid fills the space on one side of it. Where the two
/// sides are closer than the points along them, every neighbourhood holds points of both with
/// nearly parallel normals, and neither the graph's signs nor the dipole field tell them apart.
/// Measured on a closed thin ellipsoid (semi-axes 1, 0.5 and C, area-uniform samples,
/// `jobs/bench-thin-sheet`): the four samplings whose spacing was 0.70 of the thickness or more
/// grew such a solid (mesh -> truth 18-23 % of the diagonal), the five at 0.66 or less gave a
/// closed solid near the sheet (0.14-0.72 %). The orientation by side ([`spilling`]) mends such
/// fits where it can; the warning is for those it does not.
pub const UNBOUNDED_CAUSE: &str = "with normals estimated from the points, a likely cause is a part thinner \
     than the spacing of the points whose two sides were oriented alike, so that the solid fills the \
     space beside it: a denser sampling of that part is the remedy";

/// The method `surface` resolves to for `n` points (true: off-surface constraints).
pub fn with_off_surface(surface: Surface, n: usize) -> bool {
    match surface {
        Surface::Carrier => false,
        Surface::OffSurface => true,
        Surface::Auto => n >= AUTO_MIN_POINTS,
    }
}

/// The unsupported crossings the fit of `summary` leaves on the lattice of its last step: those
/// after step 8 (the outside off points, where it ran), else after step 7 (the turns); None
/// where neither ran. What `--orient-side both` compares.
pub fn unsupported_left(summary: &SurfaceSummary) -> Option<usize> {
    summary.outside.map(|o| o.after).or(summary.turns.as_ref().map(|t| t.after))
}

/// The report's line on the choice of `--orient-side both`: the crossings `without` and `with`
/// the side vote and whether the fit with it was kept.
pub fn side_choice_line(without: Option<usize>, with: Option<usize>, keep: bool) -> String {
    let count = |c: Option<usize>| c.map_or("not counted".to_string(), |c| c.to_string());
    format!(
        "volspline fit: --orient-side both: unsupported crossings {} without the side vote, {} with it: \
         the fit {} the side vote kept",
        count(without),
        count(with),
        if keep { "with" } else { "without" }
    )
}

/// The name of the surface method in the report.
pub fn name(off: bool) -> &'static str {
    if off {
        "offsurface"
    } else {
        "carrier"
    }
}

/// `prep` with its data points moved onto quadrics fitted to their same-sheet neighbours
/// (`--denoise`, [`crate::surface::denoise`]) and what the projection did: the normals are
/// oriented once for it (from `hoods`, the neighbourhoods of `prep`'s points, where the caller
/// has them; with the side vote where `side`), and everything after it ([`constrain`] on) is
/// made again from the moved points.
/// Collective; every rank computes the same.
pub fn denoise(
    run: &Run<'_>,
    prep: &Prepared,
    hoods: Option<Neighbourhoods>,
    side: bool,
    stages: &mut Stages,
) -> Result<(Prepared, Denoised)> {
    let comm: &dyn Comm = run.comm;
    let hoods = match hoods {
        Some(h) => h,
        None => stages.time(Stage::Normals, || agree(comm, neighbourhoods_on(comm, &prep.centres)))?,
    };
    let o = stages.time(Stage::Orient, || surface::oriented_with(comm, &prep.centres, &hoods, side))?;
    let moved = stages.time(Stage::Normals, || {
        surface::denoise::project(&prep.centres, &o.normals, &hoods.knn, hoods.kmax)
    });
    let out = prep.with_centres(moved.points.clone())?;
    Ok((out, moved))
}

/// `prep` with the off-surface points appended to its centres and values (its data points are
/// left as they are) and what was done; `hoods`: the neighbourhoods of `prep`'s points where the
/// caller has them; `side`: whether the normals are oriented with the side vote. Collective.
pub fn constrain(
    run: &Run<'_>,
    prep: &Prepared,
    hoods: Option<Neighbourhoods>,
    side: bool,
    stages: &mut Stages,
) -> Result<Constrained> {
    let comm: &dyn Comm = run.comm;
    let hoods = match hoods {
        Some(h) => h,
        None => stages.time(Stage::Normals, || agree(comm, neighbourhoods_on(comm, &prep.centres)))?,
    };
    let (orientation, off) = stages.time(Stage::Orient, || -> Result<_> {
        let o = surface::oriented_with(comm, &prep.centres, &hoods, side)?;
        let off = by_trust(prep, &hoods, &o.normals, run.args);
        Ok((o, off))
    })?;
    let (mut orientation, (mut off, mut doubtful)) = (orientation, off);
    let mut energy = None;
    if run.args.orient_energy {
        let e =
            stages.time(Stage::Orient, || flip_by_energy(comm, prep, &hoods, &mut orientation.normals))?;
        if e.flipped > 0 {
            (off, doubtful) = by_trust(prep, &hoods, &orientation.normals, run.args);
        }
        energy = Some(e);
    }
    let summary = SurfaceSummary {
        off_points: off.side.len(),
        dropped: off.dropped,
        doubtful: doubtful.count,
        doubtful_share: doubtful.share,
        delta: delta_range(&off, prep.norm.scale),
        components: orientation.components,
        patches: orientation.patches,
        flipped: orientation.flipped,
        dense_dipole: orientation.dense_dipole,
        side_turned: orientation.side_turned,
        side_choice: None,
        energy,
        blob_points: 0,
        blob_regions: 0,
        blob_spared: 0,
        rays: None,
        choice: None,
        second_round: None,
        restored: None,
        turns: None,
        turns_skipped: false,
        outside_skipped: false,
        mouth_skipped: false,
        outside: None,
        mouth: None,
        sides: None,
        memory_limit: None,
    };
    Ok(Constrained { prep: with_off_points(prep, &off), summary, hoods, normals: orientation.normals, off })
}

/// The off points of `prep` at the rates of `args` (--off-points, --doubtful-share) dealt as
/// --off-deal says, how many of its points have doubtful normals and the share of the rate they
/// got.
fn by_trust(
    prep: &Prepared,
    hoods: &Neighbourhoods,
    normals: &[[f64; 3]],
    args: &FitArgs,
) -> (OffPoints, Doubt) {
    let knn = (&hoods.knn[..], hoods.kmax);
    let rates = (args.off_points, args.doubtful_share);
    off_points_by_trust(&prep.centres, normals, &hoods.tree, knn, rates, args.off_deal)
}

/// `data` with the off points `off` and their values appended to its centres and values.
fn with_off_points(data: &Prepared, off: &OffPoints) -> Prepared {
    with_off_points_sloped(data, off, 1.0)
}

/// [`with_off_points`] with the off points' targets scaled by `slope` (see
/// [`off_values_sloped`]).
fn with_off_points_sloped(data: &Prepared, off: &OffPoints, slope: f64) -> Prepared {
    let mut out = data.clone();
    out.centres.extend_from_slice(&off.centres);
    out.values.extend(off_values_sloped(off, &data.points, &data.carrier, &data.norm, slope));
    out
}

/// The smallest and largest delta of `off` in the caller's units (`scale` per normalised unit).
fn delta_range(off: &OffPoints, scale: f64) -> (f64, f64) {
    if off.delta.is_empty() {
        return (0.0, 0.0);
    }
    off.delta.iter().fold((f64::INFINITY, 0.0f64), |(lo, hi), &d| (lo.min(d * scale), hi.max(d * scale)))
}

/// A second fit of a system, given the first fit's factor where one was kept.
pub type Refit<'a> = dyn FnMut(&Prepared, Option<&KeptFactor>, &mut Stages) -> Result<Fitted> + 'a;

/// The fit `first` of `c.prep`, or, where rays through it turn patches of the normals (see
/// [`crate::surface::rays`], unless `--orient-rays off`) or it is positive in regions no data
/// supports (see [`crate::surface::blobs`]), the fit `refit` makes of `c.prep` with the turned
/// patches' off points and constraint points in those regions (`c` is updated). A turned
/// patch's off points stay where they are and change side (p + delta n with n turned is the
/// old p - delta n): the second system keeps the first one's centres and appends the blob
/// points, so `refit` is given the first fit's factor, where it kept one, to border. Where the blob
/// search's wide and narrow clearances pin different nodes (unless `--blob-choice off`), both
/// second fits are made and the one with less unsupported surface is kept (see
/// [`crate::surface::choice`]); where the cap left most spurious nodes unpinned, a second round
/// of the search may pin more (see [`crate::surface::blobs`]). Last (unless `--orient-turns
/// off`), small patches of the normals whose turn shrinks the surface no data supports are
/// turned, each tried by a solve
/// with the kept fit's bordered factor, or by a fresh fit where the system is too small for the
/// projected Cholesky that keeps one (see [`crate::surface::turns`]); then (unless
/// `--outside-points off`) the data points nearest to the unsupported surface left in open
/// space get outside off points, kept where they remove enough of it (see
/// [`crate::surface::outside`]).
/// `data` is the data alone; the lattice covers its box grown by the grid's margin. The rays,
/// the search (with the choice) and the turns have stages of their own.
///
/// `room`: the most centres a second fit may append to the first fit's within the ranks' memory
/// (`usize::MAX`: no limit; see [`super::dense::appendable`]). Where the blob points (with a
/// second round's on top of them) are more, they are thinned evenly to that many, and where the
/// solid given back would append more, it is not given back; the summary and a warning say so,
/// and the fit goes on instead of failing after the first solve. Collective.
pub fn check_first_fit(
    run: &Run<'_>,
    data: &Prepared,
    c: &mut Constrained,
    mut first: Fitted,
    stages: &mut Stages,
    refit: &mut Refit<'_>,
    room: usize,
) -> Result<Fitted> {
    let factor = first.factor.take();
    let lattice = search_lattice(data, c, run.args.grid.margin.fraction);
    // the data's support on the lattice, for every count of unsupported crossings below
    let support = DataSupport::new(&data.centres, choice::FACTOR).on_lattice(&lattice);
    let at = (factor.as_ref(), &lattice, room);
    let searched = rays_and_blobs(run, data, c, first, stages, refit, (at, &support))?;
    // the data points' shares of the surface, for the turns' winding numbers
    let areas = searched.areas.clone();
    let (mut fit, values) = if run.args.restore_solid {
        restore_solid(run, data, c, searched, stages, refit, at)?
    } else {
        (searched.fit, searched.values)
    };
    // the kept fit's own bordered factor where it has one (a second fit), else the first fit's
    let basis = fit.factor.take().or(factor);
    // without a kept factor (a solver the user chose, or no room to keep it) a try is a fresh
    // fit: affordable on small systems alone
    let affordable = basis.is_some() || c.prep.values.len() < FRESH_TRIES_BELOW;
    let at = (basis.as_ref(), &lattice, &areas[..]);
    let (fit, values) = if run.args.orient_turns && affordable {
        let (fit, values) = turn_by_surface(run, data, c, (fit, values), stages, refit, (at, &support))?;
        (fit, Some(values))
    } else {
        c.summary.turns_skipped = run.args.orient_turns;
        (fit, values)
    };
    let fit = if (run.args.outside_points || run.args.mouth_points) && affordable {
        outside_after_turns(run, data, c, (fit, values), stages, refit, (at, room, &support))?
    } else {
        c.summary.outside_skipped = run.args.outside_points;
        c.summary.mouth_skipped = run.args.mouth_points;
        fit
    };
    if let (Some(l), 0) = (c.summary.memory_limit, run.comm.rank()) {
        crate::note!(
            "volspline: warning: the ranks' memory leaves room for {} centres appended to the first fit, \
             {} wanted: the constraint points against spurious blobs were thinned or the solid lost to \
             them was not given back, so spurious sheets may remain; use more ranks or nodes{}",
            l.room,
            l.wanted,
            if crate::app::preflight::user_limit().is_some() { " or a larger --memory-per-rank" } else { "" }
        );
    }
    Ok(fit)
}

/// The most centres the second fits of [`check_first_fit`] on `data` can ask to append, the
/// bound of the room [`super::dense::appendable`] looks for: every centre they append (a blob
/// point, a second round's, a node of the solid given back) is a node of the blob search's
/// lattice. Not the first fit's own row count: a small scan (a few hundred rows, or a small
/// level 0) wants up to [`crate::surface::blobs::MIN_CAP`] blob points whatever its size, and a
/// bound below that was reported as the ranks' memory leaving no room for them.
pub fn most_appended(data: &Prepared, c: &Constrained, margin: f64) -> usize {
    search_lattice(data, c, margin).len()
}

/// The lattice of the blob search and the steps after it: over the data's box grown by the
/// grid's `margin`, or, where the normals were oriented again by side (a sheet thinner than the
/// sampling, whose first fit spilled), by [`sheets::SPILL`] of its longest side, so that it
/// reaches the solid a fit may still leave beside the sheet, beyond the flat box of the data.
fn search_lattice(data: &Prepared, c: &Constrained, margin: f64) -> Lattice {
    let grow = if c.summary.sides.is_some_and(|s| s.kept) { sheets::SPILL.max(margin) } else { margin };
    Lattice::of_fit(&data.box_lo, &data.box_hi, grow, &data.norm)
}

/// `blobs` thinned to the `room` the second fits have for appended centres, the limit recorded
/// in `summary` where it thins them.
fn within_room(blobs: Blobs, room: usize, summary: &mut SurfaceSummary) -> Blobs {
    if blobs.source.len() <= room {
        return blobs;
    }
    MemoryLimit::record(&mut summary.memory_limit, room, blobs.source.len());
    blobs.thinned(room)
}

/// The ray test and the blob search with the clearance choice of [`check_first_fit`] (`factor`:
/// the first fit's, where it was kept; `room`: the centres a second fit may append; `support`:
/// the data's support on `lattice`, which the turns and the outside points count with too): the fit
/// kept, with its values on the lattice where they were sampled, and what [`restore_solid`]
/// compares it with. Collective.
fn rays_and_blobs(
    run: &Run<'_>,
    data: &Prepared,
    c: &mut Constrained,
    first: Fitted,
    stages: &mut Stages,
    refit: &mut Refit<'_>,
    ((factor, lattice, room), support): ((Option<&KeptFactor>, &Lattice, usize), &DataSupport),
) -> Result<Searched> {
    let turned = stages.time(Stage::Rays, || {
        if !run.args.orient_rays {
            return RayCheck::default();
        }
        let spacing = rays::spacing(&data.centres, &c.hoods.knn, c.hoods.kmax);
        let verdicts = rays::verdicts(
            run.comm,
            &first.spline,
            &data.carrier,
            &data.centres,
            &c.normals,
            &c.hoods.tree,
            &spacing,
        );
        let before = c.normals.clone();
        let turned =
            rays::turn_doubtful_patches(&data.centres, &mut c.normals, &c.hoods.knn, c.hoods.kmax, &verdicts);
        // the off points of the turned normals change side in place
        for (side, &i) in c.off.side.iter_mut().zip(&c.off.source) {
            if (0..3).map(|d| before[i][d] * c.normals[i][d]).sum::<f64>() < 0.0 {
                *side = -*side;
            }
        }
        turned
    });
    if turned.turned > 0 {
        c.prep = with_off_points(data, &c.off);
    }
    // the data's support, which the clearance choice alone needs
    let support = run.args.blob_choice.then_some(support);
    let (values, wide, narrow, search) = stages.time(Stage::Blobs, || {
        let values = sample(run.comm, lattice, &data.carrier, &first.spline);
        let search = Search::new(run.comm, lattice, &values, &data.centres, &c.normals, &c.hoods.tree);
        let wide = search.blobs(lattice, CLEARANCE);
        let narrow = support.map(|s| search.blobs(lattice, choice::NARROW * s.spacing));
        (values, wide, narrow, search)
    });
    let wide = within_room(wide, room, &mut c.summary);
    let narrow = narrow.map(|b| within_room(b, room, &mut c.summary)).filter(|b| b.centres != wide.centres);
    let areas = search.areas();
    // what the solid given back afterwards compares with
    let first_values = values.clone();
    let done =
        |fit: Fitted, values: Option<Vec<f64>>| Searched { fit, values, first_values, areas: areas.to_vec() };
    c.summary.blob_regions = wide.regions;
    c.summary.blob_spared = wide.spared.len() / 3;
    c.summary.rays = run.args.orient_rays.then(|| turned.clone());
    // the first fit is the candidate of a blob set where it pins nothing and no patch turned
    let first_stands = |b: &Blobs| b.source.is_empty() && turned.turned == 0;
    let (Some(narrow), Some(support)) = (narrow, support) else {
        if first_stands(&wide) {
            return Ok(done(first, Some(values)));
        }
        drop(first);
        c.prep = with_blobs(&c.prep, &wide, data);
        c.summary.blob_points = wide.source.len();
        let fit = refit(&c.prep, factor, stages)?;
        // one clearance pinned what both would; a second round where the cap left most nodes out
        let Some(support) = support.filter(|_| wide.found > SECOND_ROUND_FROM * wide.source.len()) else {
            return Ok(done(fit, None));
        };
        let (values, share) = stages.time(Stage::Blobs, || {
            let values = sample(run.comm, lattice, &data.carrier, &fit.spline);
            let winding = |at: &[[f64; 3]]| winding_numbers(run.comm, at, &data.centres, &c.normals, areas);
            let share = unsupported_share(lattice, &values, support, winding).0;
            (values, share)
        });
        let kept = Round { fit, values, share, clearance: CLEARANCE };
        let (fit, values) =
            second_round(run, data, c, kept, (lattice, &search, support), (factor, room), stages, refit)?;
        return Ok(done(fit, Some(values)));
    };
    // two candidates: each is the first fit or a second one, with its points and the lattice
    // values of its fit (neither candidate the first fit: it goes before the second systems are
    // made)
    let reused = first_stands(&wide) || first_stands(&narrow);
    let mut first = reused.then_some((first, values));
    let mut candidate = |blobs: &Blobs, stages: &mut Stages| -> Result<(Fitted, Vec<f64>, Prepared)> {
        let prep = with_blobs(&c.prep, blobs, data);
        if first_stands(blobs) {
            let (fit, values) = first.take().expect("one candidate at most is the first fit");
            return Ok((fit, values, prep));
        }
        let fit = refit(&prep, factor, stages)?;
        let values = stages.time(Stage::Blobs, || sample(run.comm, lattice, &data.carrier, &fit.spline));
        Ok((fit, values, prep))
    };
    let (wide_fit, wide_values, wide_prep) = candidate(&wide, stages)?;
    let (narrow_fit, narrow_values, narrow_prep) = candidate(&narrow, stages)?;
    let (wide_share, narrow_share) = stages.time(Stage::Blobs, || {
        let share = |values: &[f64]| {
            let winding = |at: &[[f64; 3]]| winding_numbers(run.comm, at, &data.centres, &c.normals, areas);
            unsupported_share(lattice, values, support, winding).0
        };
        (share(&wide_values), share(&narrow_values))
    });
    let kept_narrow = narrow_share < wide_share;
    c.summary.choice = Some(ClearanceChoice {
        wide_points: wide.source.len(),
        narrow_points: narrow.source.len(),
        wide_share,
        narrow_share,
        kept_narrow,
        fits: if reused { 2 } else { 3 },
    });
    let (blobs, fit, prep, values, share, clearance) = if kept_narrow {
        (&narrow, narrow_fit, narrow_prep, narrow_values, narrow_share, choice::NARROW * support.spacing)
    } else {
        (&wide, wide_fit, wide_prep, wide_values, wide_share, CLEARANCE)
    };
    c.prep = prep;
    c.summary.blob_points = blobs.source.len();
    if blobs.found <= SECOND_ROUND_FROM * blobs.source.len() {
        return Ok(done(fit, Some(values)));
    }
    let kept = Round { fit, values, share, clearance };
    let (fit, values) =
        second_round(run, data, c, kept, (lattice, &search, support), (factor, room), stages, refit)?;
    Ok(done(fit, Some(values)))
}

/// What the ray test and the blob search leave: the fit kept, with its values on the lattice
/// where they were sampled, the first fit's values on the lattice and the data points' shares of
/// the surface (for the winding numbers).
struct Searched {
    fit: Fitted,
    values: Option<Vec<f64>>,
    first_values: Vec<f64>,
    areas: Vec<f64>,
}

/// Gives back the solid the blob search's pins took from data points (see
/// [`crate::surface::blobs`], "Solid given back"): the nodes of [`lost_solid`] inside the data's
/// surface, where there are at least [`RESTORE_FROM`], become constraint points with the first
/// fit's values as targets, and the fit with them
/// (bordering the first fit's factor, as the search's fits do) is kept when fewer data points are
/// left without solid. Only the lattice around each node is sampled again for that count; the
/// values elsewhere stay the kept fit's. Where the nodes with the blob points are more centres
/// than a second fit may append (`room`), nothing is given back. Returns the fit kept with its
/// values on the lattice (`c` is updated where the new fit is kept). Collective.
fn restore_solid(
    run: &Run<'_>,
    data: &Prepared,
    c: &mut Constrained,
    searched: Searched,
    stages: &mut Stages,
    refit: &mut Refit<'_>,
    (factor, lattice, room): (Option<&KeptFactor>, &Lattice, usize),
) -> Result<(Fitted, Option<Vec<f64>>)> {
    let Searched { fit, values, first_values, areas } = searched;
    // the first fit itself: nothing was pinned
    if c.summary.blob_points == 0 {
        return Ok((fit, values));
    }
    let (values, (lost, nodes), before) = stages.time(Stage::Blobs, || {
        let values = values.unwrap_or_else(|| sample(run.comm, lattice, &data.carrier, &fit.spline));
        let lost = lost_solid(lattice, &first_values, &values, &data.centres);
        let at: Vec<[f64; 3]> = lost.iter().map(|&i| lattice.node(i)).collect();
        let winding = winding_numbers(run.comm, &at, &data.centres, &c.normals, &areas);
        let inside: Vec<usize> =
            lost.iter().zip(&winding).filter(|(_, &w)| w >= INSIDE).map(|(&i, _)| i).collect();
        let before = points_without_solid(lattice, &values, &data.centres);
        (values, (lost.len(), inside), before)
    });
    let inside = if nodes.len() >= RESTORE_FROM { nodes } else { Vec::new() };
    let along =
        if lost > 0 { paths_to_solid(lattice, &first_values, &values, &data.centres) } else { Vec::new() };
    // a node on the way back through the first fit's solid may be one the search pinned (its
    // spurious nodes lie in that solid): a second centre there, with another value, made the
    // system singular (a level 0 of 300 cow points with a hole: residual 0.2 on one rank, a
    // singular LU on two). The pin stays
    let (inside, along) = (unpinned(&c.prep, lattice, inside), unpinned(&c.prep, lattice, along));
    let mut nodes: Vec<usize> = inside.iter().chain(&along).copied().collect();
    nodes.sort_unstable();
    nodes.dedup();
    let wanted = c.summary.blob_points + nodes.len();
    if !nodes.is_empty() && wanted > room {
        MemoryLimit::record(&mut c.summary.memory_limit, room, wanted);
        c.summary.restored = Some(Restored {
            lost,
            points: 0,
            along: 0,
            without_solid: (before, before),
            kept: false,
            no_room: true,
        });
        return Ok((fit, Some(values)));
    }
    let (points, along) = (inside.len(), along.len());
    let mut restored =
        Restored { lost, points, along, without_solid: (before, before), kept: false, no_room: false };
    if nodes.is_empty() {
        c.summary.restored = (lost > 0).then_some(restored);
        return Ok((fit, Some(values)));
    }
    let mut prep = c.prep.clone();
    for &i in &nodes {
        let q = lattice.node(i);
        prep.centres.extend_from_slice(&q);
        prep.values.push(data.carrier.eval(&data.norm.undo(&q)) - first_values[i]);
    }
    let new = refit(&prep, factor, stages)?;
    let (new_values, after) = stages.time(Stage::Blobs, || {
        let mut new_values = values.clone();
        for &i in &nodes {
            let window = lattice.around(lattice.node(i), lattice.node(i), 0.0);
            sample_window(run.comm, lattice, &window, (&data.carrier, &new.spline), &mut new_values);
        }
        let after = points_without_solid(lattice, &new_values, &data.centres);
        (new_values, after)
    });
    restored.without_solid.1 = after;
    restored.kept = after < before;
    c.summary.restored = Some(restored);
    if !restored.kept {
        return Ok((fit, Some(values)));
    }
    c.prep = prep;
    Ok((new, Some(new_values)))
}

/// The lattice nodes of `nodes` that are not already centres of `prep` (the search's pins are
/// lattice nodes, bit for bit).
fn unpinned(prep: &Prepared, lattice: &Lattice, nodes: Vec<usize>) -> Vec<usize> {
    let key = |q: &[f64]| [q[0].to_bits(), q[1].to_bits(), q[2].to_bits()];
    let taken: std::collections::HashSet<[u64; 3]> = prep.centres.chunks_exact(3).map(key).collect();
    nodes.into_iter().filter(|&i| !taken.contains(&key(&lattice.node(i)))).collect()
}

/// A fit of the blob search with its values on the lattice, the share of its surface that no
/// data supports, and the clearance of rule 2 its pins were found with.
struct Round {
    fit: Fitted,
    values: Vec<f64>,
    share: f64,
    clearance: f64,
}

/// The blob search's second round on `kept`, a second fit whose pins the cap chose from more
/// spurious nodes (see [`crate::surface::blobs`], "A second round"): the spurious nodes of its
/// fit in open space are pinned too, and the fit with them is kept when it has less unsupported
/// surface and no more data points without solid near them. `first` is the first fit's search,
/// whose judgements of the nodes it takes over. The new fit is sampled first at the corners of
/// the data points' cells alone: where more data points are left without solid the round is
/// dropped without more. Else it is sampled on the whole lattice for its share: sampled only
/// around its pins, as the turns are, one decision in 119 sets changed for the worse (the
/// strided cow with a hole at 1000 points kept a round that hollowed its cap, truth -> mesh 1.11
/// -> 1.54). Returns the fit kept with its values on the lattice (`c` is updated where the new
/// fit is kept). Collective.
#[allow(clippy::too_many_arguments)]
fn second_round(
    run: &Run<'_>,
    data: &Prepared,
    c: &mut Constrained,
    kept: Round,
    (lattice, first, support): (&Lattice, &Search, &DataSupport),
    (factor, room): (Option<&KeptFactor>, usize),
    stages: &mut Stages,
    refit: &mut Refit<'_>,
) -> Result<(Fitted, Vec<f64>)> {
    let areas = first.areas();
    let (more, before) = stages.time(Stage::Blobs, || {
        let search = first.again(run.comm, lattice, &kept.values, &data.centres, &c.normals, &c.hoods.tree);
        let more = search.open_blobs(lattice, kept.clearance);
        (more, points_without_solid(lattice, &kept.values, &data.centres))
    });
    // the round's points go on top of the blob points kept; without room for any, no round
    let held = c.summary.blob_points;
    let more = if held + more.source.len() > room {
        MemoryLimit::record(&mut c.summary.memory_limit, room, held + more.source.len());
        if room <= held {
            return Ok((kept.fit, kept.values));
        }
        more.thinned(room - held)
    } else {
        more
    };
    let mut round = SecondRound {
        points: more.source.len(),
        share: (kept.share, Some(kept.share)),
        without_solid: (before, before),
        kept: false,
    };
    if more.source.is_empty() {
        c.summary.second_round = Some(round);
        return Ok((kept.fit, kept.values));
    }
    let prep = with_blobs(&c.prep, &more, data);
    let fit = refit(&prep, factor, stages)?;
    let (values, share, after) = stages.time(Stage::Blobs, || {
        // the data points' cells first: a round that leaves more of them without solid is
        // dropped whatever its share, and the whole lattice is not sampled for it
        let mut probe = kept.values.clone();
        let cells = data_cells(lattice, &data.centres);
        sample_nodes(run.comm, lattice, &cells, (&data.carrier, &fit.spline), &mut probe);
        let after = points_without_solid(lattice, &probe, &data.centres);
        if after > before {
            return (None, None, after);
        }
        let values = sample(run.comm, lattice, &data.carrier, &fit.spline);
        let winding = |at: &[[f64; 3]]| winding_numbers(run.comm, at, &data.centres, &c.normals, areas);
        let share = unsupported_share(lattice, &values, support, winding).0;
        (Some(values), Some(share), after)
    });
    round.share.1 = share;
    round.without_solid.1 = after;
    let (Some(values), Some(share)) = (values, share) else {
        c.summary.second_round = Some(round);
        return Ok((kept.fit, kept.values));
    };
    round.kept = share < kept.share;
    c.summary.second_round = Some(round);
    if !round.kept {
        return Ok((kept.fit, kept.values));
    }
    c.prep = prep;
    c.summary.blob_points += more.source.len();
    Ok((fit, values))
}

/// The solutions of the turn tries' changes of values with a bordered factor (see
/// [`turn_by_surface`]): the factor, one solution per candidate from the first solved, and the
/// seconds per solution.
type Superposed<'a> = (&'a KeptFactor, Vec<Vec<f64>>, f64);

/// `fit` of `c.prep` after the small patches of the normals whose turn shrinks the surface no
/// data supports are turned, one candidate after the other (see [`crate::surface::turns`]): each
/// candidate changes only the values of its off points, so its fit is a solve with `factor`, the
/// fit's own (bordered) factor, where there is one (else a fresh fit of a small system): the
/// kept fit's solution plus the candidate's column of one solve of the candidates' changes,
/// where no kept turn changed the same values (see "Cost" in [`crate::surface::turns`]), and only
/// the nodes around the patch whose values bear on the unsupported crossings
/// ([`DataSupport::bears_on_crossings`]) are sampled again, and its crossings counted again: the
/// values returned are the kept fit's at every such node, and may be an earlier fit's at the
/// others, which no count of unsupported crossings reads (a patch whose
/// window holds too few unsupported crossings for their removal to be a gain is passed over
/// without a solve). The lattice is the blob search's; `values`, the
/// fit's values on it where the search sampled them; `areas`, the data points' shares of the
/// surface the search took for its winding numbers. Collective.
fn turn_by_surface(
    run: &Run<'_>,
    data: &Prepared,
    c: &mut Constrained,
    (mut fit, values): (Fitted, Option<Vec<f64>>),
    stages: &mut Stages,
    refit: &mut Refit<'_>,
    ((factor, lattice, areas), support): ((Option<&KeptFactor>, &Lattice, &[f64]), &DataSupport),
) -> Result<(Fitted, Vec<f64>)> {
    let (mut values, crossings) = stages.time(Stage::Turns, || {
        let values = values.unwrap_or_else(|| sample(run.comm, lattice, &data.carrier, &fit.spline));
        let crossings = choice::unsupported_crossings(lattice, &values, support).0;
        (values, crossings)
    });
    let (candidates, patches, side_patches) = stages.time(Stage::Turns, || {
        let knn = (&c.hoods.knn[..], c.hoods.kmax);
        let mut candidates = turns::candidates(&data.centres, &c.normals, knn, &c.hoods.tree, &crossings);
        let patches = candidates.len();
        let in_window = |cd: &turns::Candidate| {
            choice::unsupported_in_window(lattice, &values, support, &cd.window(lattice))
        };
        let facing = turns::facing_candidates(
            &data.centres,
            &c.normals,
            knn,
            (&candidates, &c.off.source),
            in_window,
            crossings.len(),
        );
        candidates.extend(facing);
        // the side vote's turns, tried together before the patches
        let side = (run.args.orient_side == SideVote::Try)
            .then(|| turns::side_candidate(&data.centres, &c.normals, knn))
            .flatten();
        let side_patches = side.map(|(candidate, patches)| {
            candidates.insert(0, candidate);
            patches
        });
        (candidates, patches, side_patches)
    });
    let mut far = crossings.len();
    // the side vote's try, where there is one, is candidate 0 and counted apart
    let sides = usize::from(side_patches.is_some());
    let mut check = TurnCheck { candidates: candidates.len() - sides, before: far, ..Default::default() };
    let nd = data.values.len();
    // a candidate's normals, off points and system turned from `c`'s
    let turned = |c: &Constrained, candidate: &turns::Candidate| {
        let mut member = vec![false; c.normals.len()];
        candidate.members.iter().for_each(|&i| member[i] = true);
        let mut normals = c.normals.clone();
        candidate.members.iter().for_each(|&i| normals[i] = normals[i].map(|v| -v));
        // the off points of the patch change side where they stand
        let mut off = c.off.clone();
        for (side, &i) in off.side.iter_mut().zip(&off.source) {
            if member[i] {
                *side = -*side;
            }
        }
        let mut prep = c.prep.clone();
        let off_values = off_values(&off, &data.points, &data.carrier, &data.norm);
        prep.values[nd..nd + off_values.len()].copy_from_slice(&off_values);
        (normals, off, prep)
    };
    let change = |prep: &Prepared, c: &Constrained| -> Vec<f64> {
        prep.values.iter().zip(&c.prep.values).map(|(v, w)| v - w).collect()
    };
    // the system is linear and a try changes values alone: with a bordered factor of these
    // centres, a try's fit is the kept fit's solution plus the solution for its candidate's
    // change (where no turn kept before it changed the same values); the changes of the first
    // candidate that comes to a try and of all after it are solved then, together, in one pass
    // through the factor (none where every candidate is passed over). `superposed`: that first
    // candidate and the solutions, with the factor and the seconds per solution
    let changes: Vec<Vec<f64>> = candidates.iter().map(|cd| change(&turned(c, cd).2, c)).collect();
    let mut superposed: Option<(usize, Option<Superposed<'_>>)> = None;
    for (number, candidate) in candidates.into_iter().enumerate() {
        let vote = number < sides;
        let facing = number >= patches + sides;
        // the count changes within the window alone: where the crossings there now are too few
        // for their removal to be a gain, no turn of this patch can be
        let window = candidate.window(lattice);
        let within = |values: &[f64]| choice::unsupported_in_window(lattice, values, support, &window);
        let now = stages.time(Stage::Turns, || within(&values));
        if !vote && !turns::gains(far, far - now) {
            continue;
        }
        // the unsupported crossings in open space within the window, before and after
        let open_count = |values: &[f64], normals: &[[f64; 3]]| {
            let data = (&data.centres[..], normals, areas);
            turns::open_space_crossings(run.comm, (lattice, &window), values, support, data)
        };
        // a group facing a sheet is turned only where that clears open space: where the window
        // holds too few crossings in open space for their removal to clear it, it is not tried
        let open_before = facing.then(|| stages.time(Stage::Turns, || open_count(&values, &c.normals)));
        if open_before.is_some_and(|open| !turns::clears_open_space(far, (open, 0))) {
            continue;
        }
        let (normals, off, prep) = turned(c, &candidate);
        let (from, solved) = superposed.get_or_insert_with(|| {
            let t0 = std::time::Instant::now();
            let solved = factor.and_then(|f| {
                let solved = dense::solve_many(run, &c.prep, f, &changes[number..], stages)?;
                Some((f, solved, t0.elapsed().as_secs_f64() / (changes.len() - number) as f64))
            });
            (number, solved)
        });
        let tried = match solved {
            Some((first, solved, seconds)) if change(&prep, c) == changes[number] => {
                let kernel = fit.spline.kernel;
                let base = fit.spline.weights.iter().chain(&fit.spline.poly);
                let x = base.zip(&solved[number - *from]).map(|(a, b)| a + b).collect();
                check.superposed += usize::from(!vote);
                dense::fitted_from_bordered(run, kernel, &prep, first, (x, *seconds), stages)
            }
            _ => refit(&prep, factor, stages)?,
        };
        check.tried += usize::from(!vote);
        check.facing += usize::from(facing);
        let (tried_values, after, kept) = stages.time(Stage::Turns, || {
            let mut tried_values = values.clone();
            let nodes = bearing_nodes(lattice, &window, support);
            sample_nodes(run.comm, lattice, &nodes, (&data.carrier, &tried.spline), &mut tried_values);
            let after = far - now + within(&tried_values);
            let kept = match open_before {
                _ if vote => turns::keeps_side(far, after).then_some(false),
                Some(open) => turns::keeps_group(far, after, || (open, open_count(&tried_values, &normals)))
                    .then_some(true),
                None => turns::keeps_by(far, after, || {
                    (open_count(&values, &c.normals), open_count(&tried_values, &normals))
                }),
            };
            (tried_values, after, kept)
        });
        // a try no count keeps is kept where it removes some unsupported surface and the spline
        // through its values is smoother
        let smoother = !vote && kept.is_none() && {
            let energy =
                |fit: &Fitted, prep: &Prepared| turns::bending_energy(&fit.spline.weights, &prep.values);
            turns::keeps_smoother(far, after, (energy(&fit, &c.prep), energy(&tried, &prep)))
        };
        if vote {
            let points = candidate.members.len();
            check.side = side_patches.map(|patches| SideTry {
                patches,
                points,
                before: far,
                after,
                kept: kept.is_some(),
            });
        }
        if let Some(by_open_space) = kept.or(smoother.then_some(false)) {
            let mut tried = tried;
            dense::check_residual(run, &prep, &mut tried, stages);
            (c.normals, c.off, c.prep, fit, far, values) = (normals, off, prep, tried, after, tried_values);
            if vote {
                continue;
            }
            check.turned += 1;
            check.turned_points += candidate.members.len();
            check.by_open_space += usize::from(by_open_space);
            check.smoother += usize::from(smoother);
            check.facing_turned += usize::from(facing);
        }
    }
    check.after = far;
    c.summary.turns = Some(check);
    Ok((fit, values))
}

/// The last steps on `fit` of `c.prep` (see [`crate::surface::outside`]; `c` is updated with
/// what is kept): with `--outside-points`, the fit with outside off points for the data points
/// nearest to its unsupported crossings in open space, kept where that removes at least
/// [`crate::surface::turns::GAIN`] of all its unsupported crossings; then, with
/// `--mouth-points`, the fit with off points on both sides of those on a rim nearest to
/// several of its unsupported crossings in the mouths of holes and, with `--cap-bulge` above 0,
/// inside points at the crossings nearest to those rim points that push the caps outward, kept.
/// The off points are appended, so each fit borders `factor` where there is one; `values` are
/// `fit`'s on `lattice` where they were sampled (at every node that bears on the unsupported
/// crossings: only those are read, here and after), `areas` the data points' shares of the
/// surface for the winding numbers. Where the points with those already appended to the first
/// fit's would be more than `room`, none are added. Collective.
fn outside_after_turns(
    run: &Run<'_>,
    data: &Prepared,
    c: &mut Constrained,
    (fit, values): (Fitted, Option<Vec<f64>>),
    stages: &mut Stages,
    refit: &mut Refit<'_>,
    ((factor, lattice, areas), room, support): ((Option<&KeptFactor>, &Lattice, &[f64]), usize, &DataSupport),
) -> Result<Fitted> {
    let (values, crossings, winding) = stages.time(Stage::Turns, || {
        let values = values.unwrap_or_else(|| sample(run.comm, lattice, &data.carrier, &fit.spline));
        let crossings = choice::unsupported_crossings(lattice, &values, support).0;
        let winding = winding_numbers(run.comm, &crossings, &data.centres, &c.normals, areas);
        (values, crossings, winding)
    });
    let n = c.normals.len();
    let (tree, normals) = (&c.hoods.tree, &c.normals);
    // the mouths' points are charged by the crossings of this fit, before any outside point
    let mouth = run.args.mouth_points.then(|| {
        let hits = outside::charged(&crossings, &winding, tree, n, outside::MOUTH);
        let hoods = (tree, (&c.hoods.knn[..], c.hoods.kmax));
        (hits.iter().sum::<usize>(), outside::mouth_points(&data.centres, normals, hoods, &c.off, &hits))
    });
    let fit = if run.args.outside_points {
        let at = ((factor, lattice), room);
        let found = (support, &crossings[..], &winding[..]);
        outside_in_open_space(run, data, c, (fit, values), stages, refit, at, found)?
    } else {
        fit
    };
    let Some((in_mouths, (mouth, folds))) = mouth else {
        return Ok(fit);
    };
    // the caps pushed outward from the crossings nearest to the rim points just held
    let caps = {
        let mut rim = vec![false; n];
        mouth.source.iter().for_each(|&i| rim[i] = true);
        let found = (&crossings[..], &winding[..]);
        let at = (&c.normals[..], &c.hoods.tree);
        outside::cap_points(found, at, &rim, support.spacing, run.args.cap_bulge)
    };
    let mut check = MouthPoints {
        crossings: in_mouths,
        wanted: mouth.side.len() + mouth.dropped,
        points: mouth.side.len(),
        folds,
        caps: caps.side.len(),
        no_room: false,
    };
    let appended = c.prep.values.len() - data.values.len() - c.off.side.len();
    if appended + check.points + check.caps > room {
        MemoryLimit::record(&mut c.summary.memory_limit, room, appended + check.points + check.caps);
        check.no_room = true;
    }
    c.summary.mouth = Some(check);
    if check.points == 0 || check.no_room {
        return Ok(fit);
    }
    // the mouth points' targets steeper than the other off points', the cap points' as theirs
    let mut prep = with_off_points_sloped(&c.prep, &mouth, run.args.mouth_slope);
    if !caps.side.is_empty() {
        prep = with_off_points_sloped(&prep, &caps, 1.0);
    }
    let fitted = refit(&prep, factor, stages)?;
    c.prep = prep;
    Ok(fitted)
}

/// `fit` of `c.prep`, or the fit with outside off points for the data points nearest to its
/// unsupported `crossings` (by `support`, with the data's winding numbers there) in open space,
/// where that removes at least [`crate::surface::turns::GAIN`] of all of them (`c` is updated
/// where it is kept; the arguments as for [`outside_after_turns`]). Collective.
#[allow(clippy::too_many_arguments)]
fn outside_in_open_space(
    run: &Run<'_>,
    data: &Prepared,
    c: &mut Constrained,
    (fit, values): (Fitted, Vec<f64>),
    stages: &mut Stages,
    refit: &mut Refit<'_>,
    ((factor, lattice), room): ((Option<&KeptFactor>, &Lattice), usize),
    (support, crossings, winding): (&DataSupport, &[[f64; 3]], &[f64]),
) -> Result<Fitted> {
    let hits = outside::charged(crossings, winding, &c.hoods.tree, c.normals.len(), ..OPEN_SPACE);
    let extra = outside::outside_points(&data.centres, &c.normals, &c.hoods.tree, &c.off, &hits);
    let open = winding.iter().filter(|&&w| w < OPEN_SPACE).count();
    // every charged point without an off point is either placed or dropped
    let charged = extra.side.len() + extra.dropped;
    if charged == 0 {
        return Ok(fit);
    }
    let mut check = OutsideCheck {
        open,
        charged,
        points: extra.side.len(),
        before: crossings.len(),
        after: crossings.len(),
        kept: false,
        no_room: false,
    };
    let appended = c.prep.values.len() - data.values.len() - c.off.side.len();
    if appended + check.points > room {
        MemoryLimit::record(&mut c.summary.memory_limit, room, appended + check.points);
        check.no_room = true;
    }
    if check.points == 0 || check.no_room {
        c.summary.outside = Some(check);
        return Ok(fit);
    }
    let prep = with_off_points(&c.prep, &extra);
    let tried = refit(&prep, factor, stages)?;
    // the lattice sampled again around the outside points alone
    check.after = stages.time(Stage::Turns, || {
        let around = (crossings, winding, OPEN_SPACE);
        let mut nodes = outside::window_nodes(lattice, &data.centres, &c.hoods.tree, around, &extra);
        nodes.retain(|&i| support.bears_on_crossings(lattice, i));
        let mut values = values;
        sample_nodes(run.comm, lattice, &nodes, (&data.carrier, &tried.spline), &mut values);
        choice::unsupported_crossings(lattice, &values, support).0.len()
    });
    check.kept = turns::gains(check.before, check.after);
    c.summary.outside = Some(check);
    if !check.kept {
        return Ok(fit);
    }
    c.prep = prep;
    Ok(tried)
}

/// The nodes of `window` (index ranges of `lattice`, x fastest) whose values bear on the
/// unsupported crossings `support` counts there ([`DataSupport::bears_on_crossings`]): the
/// nodes a try must sample again for its count. The others keep the values they had, which no
/// count of unsupported crossings reads.
fn bearing_nodes(
    lattice: &Lattice,
    window: &[std::ops::Range<usize>; 3],
    support: &DataSupport,
) -> Vec<usize> {
    let mut nodes = Vec::with_capacity(window.iter().map(|r| r.len()).product());
    lattice.push_window(window, &mut nodes);
    nodes.retain(|&i| support.bears_on_crossings(lattice, i));
    nodes
}

/// `prep` with the constraint points of `blobs` appended (`data` the data alone).
fn with_blobs(prep: &Prepared, blobs: &Blobs, data: &Prepared) -> Prepared {
    let mut out = prep.clone();
    out.centres.extend_from_slice(&blobs.centres);
    out.values.extend(blob_values(blobs, &data.points, &data.carrier, &data.norm));
    out
}
