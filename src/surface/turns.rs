//! Patches of normals turned where that shrinks the surface no data supports.
//!
//! # What the earlier steps miss
//!
//! The ray test ([`crate::surface::rays`]) finds a patch turned inward on a thick part by the
//! hole its inside becomes. On a sheet thinner than the sampling (an ear, a fin) a turned patch
//! leaves no hole: the off points on its wrong side hold up a bulge of false solid beside the
//! sheet, and the rays of its points run into open space on the other side, as those of correct
//! points do. The bulge is surface that no data point supports, the quantity the clearance
//! choice ([`crate::surface::choice`]) already measures without any truth: the lattice edges
//! along which f changes sign farther than 2 median spacings from every data point.
//!
//! # The test
//!
//! After the fit that the blob search and the clearance choice leave, every unsupported crossing
//! is charged to the orientation patch (of the kind the ray test turns: mutually tangent
//! neighbours with nearly parallel normals) of its nearest data point. The small patches (at most
//! [`crate::surface::rays::PATCH_SHARE`] of the points) charged with at least [`MIN_HITS`]
//! crossings are candidates, the most charged first: the first [`FIRST_TRIES`] whatever their
//! size, then up to [`TRIES`] in all of at least [`LATE_POINTS`] points (below). For each, its
//! normals and the off points of its points are turned (the off points stay where they are and
//! change side, so the system keeps its centres and only values change) and the spline is fitted
//! again; the turn is kept when the unsupported crossings fall by at least [`GAIN`] of their
//! number, or when they fall and those in open space fall by that much (below), or when they
//! fall by [`SMOOTHER_GAIN`] and the spline is smoother (below), and the next candidate is tried
//! from there.
//!
//! # Open space
//!
//! The count of all unsupported crossings mixes surfaces of three kinds: bulges and webs of false
//! solid in open space, where the data's winding number (see [`crate::surface::blobs`]) is near 0;
//! caps over a scan's holes, in the hole's mouth, near 1/4; and dents pulled into the solid, above
//! 1/2. A turn that removes a bulge beside a thin part moves the zero set around it too, and the
//! count of the other kinds can rise as the bulge goes. Beside the tail of a cow sampled at 4000
//! points, the turn of an 18-point patch took the unsupported crossings in open space (winding
//! number below [`crate::surface::blobs::OPEN_SPACE`], as the blob search's rule 3 reads it)
//! within its window from 62 to 17, while those between 0.1 and 0.3 rose from 23 to 54: the whole
//! count fell by 13 of 464 (2.8 %), under [`GAIN`], although the turn is right (mesh -> truth
//! 0.366 -> 0.318 % of the diagonal, the separate blob beside the tail gone). At the rim of an
//! open cow's hole, the 5-point patch whose turn cost completeness where a smaller [`GAIN`] kept
//! it (below; 480 -> 464 in all with the present steps) raised the open-space count, 2 -> 8.
//! So a try is also kept when it lowers the whole count and the open-space count within its
//! window ([`open_space_crossings`]) falls by more than [`GAIN`] of the whole count ([`keeps`]).
//! The winding numbers are taken for those tries alone (the ones the first rule rejects although
//! they lower the whole count), at the unsupported crossings of the window before and after: a
//! sum over the data points for each, split over the ranks.
//!
//! # Measured
//!
//! On 16 sets of the surface benchmark (the bunny and the cow, 400-2000 points, three
//! samplings; mesh -> truth rms in % of the diagonal): no set got worse, and the ear of the
//! bunny at 1000 points went 0.71 -> 0.59 (far vertices 2.28 -> 1.77 %), a second sample of the
//! bunny with noise 0.68 -> 0.39, a second sample of the cow 0.52 -> 0.37. Keeping every turn
//! that lowers the count by 3 % instead of 5 % also turned a 5-point patch at the rim of an open
//! cow's hole (480 -> 460 crossings) and cost that set's completeness (truth -> mesh 1.13 ->
//! 1.19); the threshold was chosen between the two. On 12 samples not used to choose it (the
//! tests' own sampler, seeds 1-6 of the bunny and the cow at 1000 points) it changed 5 fits,
//! each for the better (the bunny's seed 2 0.50 -> 0.34, seed 5 0.44 -> 0.36, the cow's seed 3
//! 0.66 -> 0.59).
//!
//! # How many tries
//!
//! Three tries left turns undone on the larger cows, where more small patches are charged with
//! crossings: six tried on the surface benchmark's 259 sets (below) took 15 fits nearer the
//! truth (seed 4's cow at 2000 points: mesh -> truth 0.289 -> 0.242 % of the diagonal) but turned
//! a one-point patch at the rim of an open cow's hole, kept by the whole count, that ate part of
//! the cap over the hole (truth -> mesh 0.759 -> 0.837), one target lost. A patch of one to three
//! points at a rim is where a turn trades the cap for the count, and the patches the later tries
//! mend are larger, so the tries past the first [`FIRST_TRIES`] take patches of at least
//! [`LATE_POINTS`] points: 9 sets changed, 8 nearer the truth (0.289 -> 0.242 as above, seed 6's
//! cow at 2000 points 0.288 -> 0.252, an open cow at 1000 points 0.549 -> 0.502) and one a little
//! farther (0.342 -> 0.346), no target lost. With 2 points at least a cow at 4000 points went the
//! other way (0.291 -> 0.307).
//!
//! # The smoother spline
//!
//! The count sees the false solid a turned patch holds up only where it lies farther than 2
//! median spacings from every data point; near the data a turn's gain can stay under [`GAIN`]
//! although the patch was wrong. A second witness costs nothing: the spline is the interpolant of
//! least bending energy through its values ([`bending_energy`]: -w . r, from the weights w the
//! solve gives and the values r), and off points on the wrong side of the surface make it bend
//! to pass through them. So a try that no count keeps is kept where it removes at least
//! [`SMOOTHER_GAIN`] of the unsupported crossings and takes at least [`SMOOTHER`] of the energy
//! off ([`keeps_smoother`]). The energy alone does not tell the true signs (turning whole
//! patches greedily from the first orientation by the energy alone mended the bunny and broke
//! the cow: `crate::surface::energy`), nor does it veto: keeping only the turns a count keeps
//! where they also lower the energy lost 3 of the 119 sets of seeds 1-6 of the surface
//! benchmark (seed 6's cow at 1000 points: mesh -> truth 0.320 -> 0.604 % of the diagonal). As
//! a witness beside a count that already points the same way, it is right. Measured on the 259
//! sets of the surface benchmark (the bunny and the cow at 400-4000 points, clean, noisy and
//! with a hole, twelve random samplings and one of the mesh's own vertices; 2 ranks, grid 100):
//! 23 sets changed, mesh -> truth lower on 19 (seed 2's cow at 2000 points 0.308 -> 0.283 % of the
//! diagonal, seed 12's cow at 4000 points 0.265 -> 0.218, the strided cow at 1000 points 0.399 ->
//! 0.331), higher on 4 (at most seed 9's cow at 1000 points with a hole, 0.398 -> 0.452, where
//! Poisson has 0.612); seed 8's cow at 1000 points with a hole now meets every quality target
//! (0.515 -> 0.469, Poisson 0.490), 256 of the 259 sets do. On the 40 sets held out from every
//! choice (seeds 13 and 14) 3 changed, each nearer the truth (seed 13's cow at 4000 points 0.261
//! -> 0.233, seed 13's bunny at 1000 points with noise of 0.5 % 0.518 -> 0.488).
//! The thresholds were set from the tries of seeds 1-4 before those runs. Over the 894 tries of
//! the 259 sets, the patch was wrong by the true normals (most of its points facing against the
//! nearest triangle of the truth) on 55 % of the tries that lowered the energy and on 13 % of
//! those that raised it.
//!
//! # Points facing a sheet
//!
//! A patch turned as a whole cannot mend one side of a part thinner than the sampling: where one
//! side of an ear is turned, its normals are parallel to the other side's and the points of both
//! sides are mutually tangent (their distance across the part is small beside their distance
//! along it), so one patch spans both sides and the main sheet of the body, far too large to
//! try. What tells the turned side is its outside: a correctly oriented point has empty space in
//! front of it (along its normal) and, on a thin part, the part's other side behind it; a turned
//! point has the other side in front. So a point *faces a sheet* when, among its
//! [`FACING_NEIGHBOURS`] nearest within [`FACING_REACH`] local spacings (the distance to its
//! 8th nearest neighbour), more lie in front of it (the direction to them within the cone
//! [`FACING_CONE`] of its normal) than behind it; such points with normals the same way are
//! joined into groups along the neighbour graph ([`facing_groups`]). The groups whose window
//! holds the most unsupported crossings, at most [`FACING_TRIES`] of them, are tried after the
//! patches ([`facing_candidates`]); they are not charged by nearest points, since the false solid
//! that a turned side holds up lies beside the part, nearer to its edge's points than to the
//! turned ones. A group's turn is kept only by the open-space rule (the unsupported crossings in open
//! space within its window fall by more than [`GAIN`] of all, and the whole count falls): at the
//! rim of a scan's hole, a group that faces across the hole also lowers the whole count, by
//! eating the cap, and takes true solid with it. That rule needs the open-space count within
//! the window to fall by more than [`GAIN`] of all, so a group whose window holds no more than
//! that in open space before the try is passed over without a solve; the count costs a winding
//! number at each unsupported crossing of the window, a few milliseconds, against about 15 for
//! the solve and the window's sampling.
//!
//! Measured on the surface benchmark's 259 sets (the bunny and the cow at 400-4000 points,
//! clean, noisy and with a hole, twelve random samplings and one of the mesh's own vertices):
//! 7 sets changed, each for the better (seed 11's cow at 2000 points with a hole: mesh -> truth
//! 0.538 -> 0.314 % of the diagonal, the bulge beside its left ear gone; three cows at 4000
//! points 0.22-0.35 -> 0.16-0.29), none for the worse. Kept as a patch's turn is (by either
//! rule of [`keeps`]), 20 sets got better and 7 worse, each a cow with a hole whose rim faces
//! across it (seed 4's cow at 1000 points: truth -> mesh 1.21 -> 1.88).
//!
//! # The side vote as one try
//!
//! The side vote of [`mod@crate::surface::orient`] turns small patches whose off-plane neighbours lie
//! mostly on their outer side (the two sides of a thin part seen in one neighbourhood). Applied
//! in the orientation it is as often wrong as right: on the 299 sets of the surface benchmark it
//! brought 138 fits nearer the truth and 153 farther. Which of the two is right the spline tells
//! well: the fit leaving fewer unsupported crossings is the nearer on about 7 of 10 sets. Making
//! the fit twice to ask costs about half the fit again; asking here costs one try. With
//! `--orient-side try` (the default) the vote runs on the normals as the rays and the blob search
//! left them, all the patches it turns (most of one or two points) become one candidate, tried
//! first, with its off points changing side where they stand like any patch's, and kept where
//! it removes any unsupported crossing ([`keeps_side`]): the vote, not the count, chose the
//! patches, and the count only decides between the normals with and without it. The patches
//! are then charged and tried from there. Measured on the 299 sets (quality only, two ranks,
//! grid 100): 159 fits changed, 125 nearer the truth by the sum of both distances and 33
//! farther (19 and 4 of the 40 held-out sets); the sum over all sets fell from 255.4 to 251.3
//! (the two fits of `--orient-side both`: 250.4). Only the vote's patches of at least 4 points:
//! 110 changed, 84 nearer, 24 farther, 253.4.
//!
//! # Cost
//!
//! A try changes values alone, so it is solved with the factor the kept fit already has: the
//! first fit's projected Cholesky factor bordered by the blob points (see
//! `crate::linalg::dist::extend`), kept with the fit, makes a solve one forward and one back
//! substitution through the distributed factor plus products with the small blocks of the
//! border, O(n^2) flops instead of the O(n^2 m) of bordering again. The system is linear in its
//! values: with M the bordered matrix, a try whose values differ from the kept fit's by d has
//! the solution x + M^{-1} d, x the kept fit's. So when the first candidate comes to its try,
//! its change d and those of all candidates after it are solved together, as columns of one
//! forward and one back substitution (nothing is solved where every candidate is passed over
//! before its try): the
//! substitutions read the whole factor (n^2 / 2 entries over the ranks) and do 2 flops per entry
//! and column, so they are bound by memory for a few columns, and nine candidates cost about
//! three single solves (0.046 s against 0.016 s each on a cow at 4000 points, 5556 rows on
//! 2 ranks). A try then adds its column to the kept fit's solution; where a turn kept before it
//! changed some of the same values (its patch shares points with the candidate), it is solved
//! alone. A try's residual is taken only when it is kept. The first fit keeps its
//! factor where it is a projected Cholesky of a dense f64 fit on the row-cyclic layout, the
//! default from 100 rows. Where the fit keeps none (a solver or layout the user chose), a try is
//! a fresh fit on systems of fewer than 1000 points (milliseconds), and the turns do not run on
//! larger ones.
//!
//! Only the lattice around the tried patch is sampled again: the box of the patch's points and
//! the crossings charged to it, grown by [`WINDOW`] times its longest side and two lattice
//! spacings ([`Candidate::window`]); the crossings are then counted as on the whole lattice with
//! the values outside the window left as they were: the count before the try, less the crossings
//! on the edges that reach into the window before it, plus those after it. A turn changes the values of a few off
//! points, which moves the zero set near them; far from the patch the fit is pinned by the
//! unchanged constraints. Measured against sampling the whole lattice on 8 sets of the
//! benchmark (the bunny and the cow, 1000-2000 points, 22 tries): the counts after a try differ
//! by at most 4 of 300-900 crossings, and no decision changed.
//!
//! The side vote's try is the exception: its one box holds patches all over the shape, so it
//! samples nearly the whole lattice, about 6 % of a small set's fit time. A box for each of its
//! patches (13 % of the nodes on a cow at 2000 points) counted the crossings after the try one or
//! two apart from the whole lattice (410 against 408 of 409 before, on a bunny at 1263 points),
//! and the try is kept on any fall: over the 299 sets of the surface benchmark that changed 42
//! fits, by tries near the margin and the steps after them, 28 of them for the worse. Its count
//! is taken on the whole lattice.
//!
//! Within the window, a node every point of whose edges lies within the support radius of some
//! data point ([`DataSupport::bears_on_crossings`]) is not sampled again: no crossing on its
//! edges is unsupported whatever f does there, so the counts, and every decision, are those of
//! the whole window, to the bit. Such nodes are a tenth of the windows at 400 points (seed 6's
//! bunny) and more where the data are denser; on seed 6's bunny at 1000 points the turns took
//! 0.073 s instead of 0.094 (fastest of five runs, 2 ranks).

use std::ops::Range;

use super::blobs::{winding_numbers, Lattice, OPEN_SPACE};
use super::choice::unsupported_crossings_in_window;
use super::orient::{dot, orientation_edges, side_vote, tangent_patches};
use super::rays::PATCH_SHARE;
use super::support::DataSupport;
use crate::par::Comm;
use crate::spline::octree::Octree;

/// Fewest unsupported crossings charged to a patch for it to be tried.
pub const MIN_HITS: usize = 5;
/// Most patches tried (each costs a solve and a sampling of the lattice around the patch).
pub const TRIES: usize = 6;
/// The patches tried whatever their size, the most charged first; those after them are tried
/// only with at least [`LATE_POINTS`] points.
pub const FIRST_TRIES: usize = 3;
/// Fewest points of a patch tried after the first [`FIRST_TRIES`].
pub const LATE_POINTS: usize = 4;
/// Most groups facing a sheet tried.
pub const FACING_TRIES: usize = 3;
/// The share of the unsupported crossings a turn must remove to be kept.
pub const GAIN: f64 = 0.05;
/// The share of the unsupported crossings a turn must remove to be kept by [`keeps_smoother`],
/// where it also makes the spline smoother.
pub const SMOOTHER_GAIN: f64 = 0.02;
/// The share of the bending energy a turn kept by [`keeps_smoother`] must take off.
pub const SMOOTHER: f64 = 1e-3;
/// How far around a tried patch (and the crossings charged to it) the lattice is sampled again,
/// in multiples of the longest side of their box.
pub const WINDOW: f64 = 1.0;

/// What the turns did, for the report.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TurnCheck {
    /// Patches and groups chosen to try ([`candidates`], [`facing_candidates`]).
    pub candidates: usize,
    /// Those tried with a solve (a candidate whose window holds too few unsupported crossings
    /// for a turn to be kept is passed over), and those turned with their points.
    pub tried: usize,
    /// Tries whose fit is the kept fit's solution plus their candidate's column of the one solve
    /// of the candidates' changes (the others were solved alone).
    pub superposed: usize,
    pub turned: usize,
    pub turned_points: usize,
    /// Turns kept by the open-space rule of [`keeps`] alone.
    pub by_open_space: usize,
    /// Turns kept by [`keeps_smoother`] alone.
    pub smoother: usize,
    /// Groups of points facing a sheet tried with a solve, and those turned (counted in
    /// `tried`, `turned` and `by_open_space` too).
    pub facing: usize,
    pub facing_turned: usize,
    /// Unsupported crossings before and after.
    pub before: usize,
    pub after: usize,
    /// The side vote tried as one turn before the patches (None: not asked for, or it turns
    /// nothing).
    pub side: Option<SideTry>,
}

/// The side vote's turns tried together as one turn ([`side_candidate`]).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct SideTry {
    /// Patches the vote turns and their points.
    pub patches: usize,
    pub points: usize,
    /// Unsupported crossings before the try and with it, and whether it was kept
    /// ([`keeps_side`]).
    pub before: usize,
    pub after: usize,
    pub kept: bool,
}

/// A patch to try: its members and the box (normalised coordinates) around them and the
/// crossings charged to them.
#[derive(Debug, Clone, PartialEq)]
pub struct Candidate {
    pub members: Vec<usize>,
    pub lo: [f64; 3],
    pub hi: [f64; 3],
}

impl Candidate {
    /// The candidate of `members`, with the box of their `points` (normalised, 3 values each).
    pub fn of_points(points: &[f64], members: Vec<usize>) -> Candidate {
        let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
        for &i in &members {
            for d in 0..3 {
                lo[d] = lo[d].min(points[3 * i + d]);
                hi[d] = hi[d].max(points[3 * i + d]);
            }
        }
        Candidate { members, lo, hi }
    }

    /// The nodes of `lattice` whose values a turn of this patch may change: those of the box
    /// grown by [`WINDOW`] times its longest side and 2 lattice spacings on every side, as index
    /// ranges along x, y and z.
    pub fn window(&self, lattice: &Lattice) -> [Range<usize>; 3] {
        lattice.around(self.lo, self.hi, WINDOW)
    }
}

/// The turns of the side vote (see [`mod@crate::surface::orient`]) on the oriented `normals` of
/// `points` (normalised, `kmax` nearest neighbours each in `knn`) as one candidate, all its
/// patches together, with the number of patches. None where the vote turns nothing, or would
/// turn more than half of the points (after it, the total flux turned them all back outward:
/// not a turn of small patches).
pub fn side_candidate(
    points: &[f64],
    normals: &[[f64; 3]],
    (knn, kmax): (&[usize], usize),
) -> Option<(Candidate, usize)> {
    let mut voted = normals.to_vec();
    let patches = side_vote(points, &mut voted, knn, kmax);
    let members: Vec<usize> = (0..normals.len()).filter(|&i| dot(&voted[i], &normals[i]) < 0.0).collect();
    if members.is_empty() || 2 * members.len() > normals.len() {
        return None;
    }
    Some((Candidate::of_points(points, members), patches))
}

/// Whether the side vote's try ([`side_candidate`]) that takes the unsupported crossings from
/// `before` to `after` is kept: where it removes any. Unlike a single patch's turn, the vote
/// turns patches by a rule of their own; the crossings only decide between the normals with
/// and without it.
pub fn keeps_side(before: usize, after: usize) -> bool {
    after < before
}

/// The candidate patches of `points` (normalised, `tree` over them) with oriented `normals` and
/// `kmax` nearest neighbours each in `knn`, given the unsupported surface crossings `far` of a
/// fit: each small patch charged with at least [`MIN_HITS`] crossings, the most charged first, at
/// most [`TRIES`], of which those past the first [`FIRST_TRIES`] only with [`LATE_POINTS`] points
/// or more.
pub fn candidates(
    points: &[f64],
    normals: &[[f64; 3]],
    (knn, kmax): (&[usize], usize),
    tree: &Octree,
    far: &[[f64; 3]],
) -> Vec<Candidate> {
    let n = normals.len();
    let edges = orientation_edges(knn, kmax);
    let (patch, count) = tangent_patches(points, normals, &edges);
    let mut size = vec![0usize; count];
    patch.iter().for_each(|&p| size[p] += 1);
    let mut hits = vec![0usize; count];
    let mut charged = vec![usize::MAX; far.len()];
    let mut near = Vec::new();
    for (c, q) in far.iter().enumerate() {
        // the nearest data point, the lower index of two at one distance
        tree.nearest_k(*q, 1, &mut near);
        if let Some(&(_, j)) = near.first() {
            hits[patch[j]] += 1;
            charged[c] = patch[j];
        }
    }
    let small = (PATCH_SHARE * n as f64).floor() as usize;
    let mut chosen: Vec<usize> = (0..count).filter(|&p| size[p] <= small && hits[p] >= MIN_HITS).collect();
    chosen.sort_by(|&a, &b| hits[b].cmp(&hits[a]).then(a.cmp(&b)));
    chosen.truncate(TRIES);
    let mut place = 0;
    chosen.retain(|&p| {
        place += 1;
        place <= FIRST_TRIES || size[p] >= LATE_POINTS
    });
    chosen
        .iter()
        .map(|&p| {
            let members: Vec<usize> = (0..n).filter(|&i| patch[i] == p).collect();
            let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
            let mut cover = |q: &[f64]| {
                for d in 0..3 {
                    lo[d] = lo[d].min(q[d]);
                    hi[d] = hi[d].max(q[d]);
                }
            };
            members.iter().for_each(|&i| cover(&points[3 * i..3 * i + 3]));
            far.iter().zip(&charged).filter(|(_, &c)| c == p).for_each(|(q, _)| cover(q));
            Candidate { members, lo, hi }
        })
        .collect()
}

/// The candidates that [`facing_groups`] adds to the `patches` of [`candidates`] (points
/// normalised, oriented `normals`, `kmax` nearest neighbours each in `knn`): each group not
/// already a patch that holds a source of an off point (`sources`: the data point of each; the
/// turn of a group without one changes no value), with the box of its points, whose window
/// (`in_window` counts the unsupported crossings there) holds enough of all `far` crossings for
/// their removal to be a gain ([`gains`]), the most first, at most [`FACING_TRIES`].
pub fn facing_candidates(
    points: &[f64],
    normals: &[[f64; 3]],
    (knn, kmax): (&[usize], usize),
    (patches, sources): (&[Candidate], &[usize]),
    in_window: impl Fn(&Candidate) -> usize,
    far: usize,
) -> Vec<Candidate> {
    let mut source = vec![false; normals.len()];
    sources.iter().for_each(|&i| source[i] = true);
    let mut scored: Vec<(usize, Candidate)> = facing_groups(points, normals, knn, kmax)
        .into_iter()
        .filter(|g| g.iter().any(|&i| source[i]) && !patches.iter().any(|p| p.members == *g))
        .map(|members| {
            let candidate = Candidate::of_points(points, members);
            (in_window(&candidate), candidate)
        })
        .filter(|&(now, _)| gains(far, far - now.min(far)))
        .collect();
    scored.sort_by(|a, b| b.0.cmp(&a.0).then_with(|| a.1.members.cmp(&b.1.members)));
    scored.truncate(FACING_TRIES);
    scored.into_iter().map(|(_, c)| c).collect()
}

/// How many of each point's nearest neighbours [`facing_groups`] looks at.
pub const FACING_NEIGHBOURS: usize = 10;
/// The cosine between a point's normal and the direction to a neighbour beyond which the
/// neighbour lies in front of the point (or, negated, behind it).
pub const FACING_CONE: f64 = 0.3;
/// How far, in the point's local spacings, a neighbour in front or behind is counted.
pub const FACING_REACH: f64 = 1.5;

/// Groups of points that face another sheet of data (see the module doc, "Points facing a
/// sheet"): each point of `points` (normalised) with oriented `normals` and `kmax` nearest
/// neighbours in `knn` that has more of its [`FACING_NEIGHBOURS`] nearest within
/// [`FACING_REACH`] local spacings in front of it (along its normal, beyond the cone
/// [`FACING_CONE`]) than behind it, joined with such neighbours whose normals point the same way
/// into connected groups, each as its points in increasing order.
pub fn facing_groups(points: &[f64], normals: &[[f64; 3]], knn: &[usize], kmax: usize) -> Vec<Vec<usize>> {
    let n = normals.len();
    let k = FACING_NEIGHBOURS.min(kmax);
    let spacing = super::rays::spacing(points, knn, kmax);
    let at = |i: usize| [points[3 * i], points[3 * i + 1], points[3 * i + 2]];
    let facing: Vec<bool> = (0..n)
        .map(|i| {
            let (p, o, reach) = (at(i), normals[i], FACING_REACH * spacing[i]);
            let (mut front, mut back) = (0usize, 0usize);
            for &j in &knn[i * kmax..i * kmax + k] {
                let q = at(j);
                let d = [q[0] - p[0], q[1] - p[1], q[2] - p[2]];
                let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
                if len == 0.0 || len >= reach {
                    continue;
                }
                let h = (d[0] * o[0] + d[1] * o[1] + d[2] * o[2]) / len;
                front += usize::from(h > FACING_CONE);
                back += usize::from(h < -FACING_CONE);
            }
            front > back
        })
        .collect();
    let mut label = vec![usize::MAX; n];
    let mut groups = Vec::new();
    for start in 0..n {
        if !facing[start] || label[start] != usize::MAX {
            continue;
        }
        let id = groups.len();
        let (mut members, mut stack) = (Vec::new(), vec![start]);
        label[start] = id;
        while let Some(i) = stack.pop() {
            members.push(i);
            for &j in &knn[i * kmax..i * kmax + k] {
                let same = normals[i].iter().zip(&normals[j]).map(|(a, b)| a * b).sum::<f64>() > 0.0;
                if facing[j] && label[j] == usize::MAX && same {
                    label[j] = id;
                    stack.push(j);
                }
            }
        }
        members.sort_unstable();
        groups.push(members);
    }
    groups
}

/// Whether a fit with `after` unsupported crossings is kept over one with `before`.
pub fn gains(before: usize, after: usize) -> bool {
    (after as f64) < (1.0 - GAIN) * before as f64
}

/// Whether a try that takes the unsupported crossings from `before` to `after` is kept: when it
/// removes at least [`GAIN`] of them ([`gains`]), or when it removes some and the unsupported
/// crossings in open space within the tried patch's window (the data's winding number there below
/// [`crate::surface::blobs::OPEN_SPACE`]) fall by more than [`GAIN`] of `before`. `open` gives
/// those two counts, before and after the try; it is called only where the second rule decides.
pub fn keeps(before: usize, after: usize, open: impl FnOnce() -> (usize, usize)) -> bool {
    keeps_by(before, after, open).is_some()
}

/// [`keeps`], telling by which rule: `Some(false)` by the whole count, `Some(true)` by open space
/// alone, None where the try is not kept.
pub fn keeps_by(before: usize, after: usize, open: impl FnOnce() -> (usize, usize)) -> Option<bool> {
    if gains(before, after) {
        Some(false)
    } else if keeps_group(before, after, open) {
        Some(true)
    } else {
        None
    }
}

/// Whether the turn of a group facing a sheet ([`facing_candidates`]) is kept: by open space
/// alone, where it removes some of all `before` unsupported crossings (`after` are left) and
/// [`clears_open_space`] with the crossings in open space within its window before and after
/// (`open`, called only where the first test passes). A group is found by its own geometry, not
/// by the surface it is charged with, so an overall gain without a clearing of open space does
/// not keep it.
pub fn keeps_group(before: usize, after: usize, open: impl FnOnce() -> (usize, usize)) -> bool {
    after < before && clears_open_space(before, open())
}

/// The bending energy of the spline with RBF weights `weights` that interpolates `values` (one
/// per weight): -w . r. With the interpolation conditions A w + Q c = r and the side conditions
/// Q^T w = 0 (Q the polynomial part's columns at the centres), w^T A w = w . r - (Q^T w) . c =
/// w . r, and for the kernel |x - y|, conditionally negative definite of order 1, -w^T A w is
/// the spline's energy semi-norm (a multiple of the integral of its squared Laplacian), >= 0.
/// The interpolant has the least of it among all functions through the same values.
pub fn bending_energy(weights: &[f64], values: &[f64]) -> f64 {
    debug_assert_eq!(weights.len(), values.len(), "one value per weight");
    -weights.iter().zip(values).map(|(w, r)| w * r).sum::<f64>()
}

/// Whether a try that no count keeps is kept since it makes the spline smoother: it removes at
/// least [`SMOOTHER_GAIN`] of the `before` unsupported crossings (`after` are left) and takes at
/// least [`SMOOTHER`] of the bending energy off (`energy`: the kept fit's and the try's, see
/// [`bending_energy`]).
pub fn keeps_smoother(before: usize, after: usize, energy: (f64, f64)) -> bool {
    let removes = after + (SMOOTHER_GAIN * before as f64).ceil() as usize <= before;
    removes && energy.1 / energy.0 - 1.0 < -SMOOTHER
}

/// The unsupported crossings of the field `values` on `lattice` (as
/// [`unsupported_crossings_in_window`] finds them within `window`) that lie in open space: where
/// the winding number of the data `points` with outward `normals` and surface shares `areas` (see
/// [`winding_numbers`]) is below [`OPEN_SPACE`]. The second count of [`keeps`]. Collective.
pub fn open_space_crossings(
    comm: &dyn Comm,
    (lattice, window): (&Lattice, &[Range<usize>; 3]),
    values: &[f64],
    support: &DataSupport,
    (points, normals, areas): (&[f64], &[[f64; 3]], &[f64]),
) -> usize {
    let at = unsupported_crossings_in_window(lattice, values, support, window);
    winding_numbers(comm, &at, points, normals, areas).iter().filter(|&&w| w < OPEN_SPACE).count()
}

/// Whether the unsupported crossings in open space fell from `open.0` to `open.1` by more than
/// [`GAIN`] of all `before` unsupported crossings.
pub fn clears_open_space(before: usize, open: (usize, usize)) -> bool {
    open.0 > open.1 && (open.0 - open.1) as f64 > GAIN * before as f64
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::surface::normals::dist2;

    #[test]
    fn a_turn_is_kept_only_when_it_removes_a_twentieth_of_the_unsupported_surface() {
        assert!(gains(710, 651));
        assert!(!gains(480, 460));
        assert!(!gains(100, 95));
        assert!(gains(100, 94));
        assert!(!gains(0, 0));
    }

    #[test]
    fn the_bending_energy_is_minus_the_quadratic_form_of_the_weights() {
        // four corners of a tetrahedron and their centroid: the weights (1, 1, 1, 1, -4) / 4 sum
        // to zero with their moments, as the side conditions of a linear polynomial ask
        let p = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [0.25, 0.25, 0.25]];
        let w = [0.25, 0.25, 0.25, 0.25, -1.0];
        let c = [0.3, -0.2, 0.5, 0.1];
        let r = |a: &[f64; 3], b: &[f64; 3]| dist2(a, b).sqrt();
        // the spline's values at its centres, with the polynomial c0 + c . x
        let values: Vec<f64> = p
            .iter()
            .map(|x| {
                (0..5).map(|j| w[j] * r(x, &p[j])).sum::<f64>()
                    + c[0]
                    + (0..3).map(|d| c[d + 1] * x[d]).sum::<f64>()
            })
            .collect();
        let form: f64 = (0..5)
            .flat_map(|i| (0..5).map(move |j| (i, j)))
            .map(|(i, j)| w[i] * w[j] * r(&p[i], &p[j]))
            .sum();
        let energy = bending_energy(&w, &values);
        assert!((energy + form).abs() < 1e-12, "{energy} against {}", -form);
        assert!(energy > 0.1, "{energy}");
    }

    #[test]
    fn a_turn_that_smooths_the_spline_is_kept_with_a_smaller_gain() {
        // two of a hundred crossings and 0.2 % of the energy off: kept; one of a hundred, or 0.05 %
        // of the energy, not
        assert!(keeps_smoother(100, 98, (2.0, 1.996)));
        assert!(!keeps_smoother(100, 99, (2.0, 1.0)));
        assert!(!keeps_smoother(100, 90, (2.0, 1.999)));
        assert!(!keeps_smoother(100, 98, (2.0, 2.1)));
        // the second patch of the open cow's test (tests/surface.rs): 431 -> 411 crossings is
        // under the count's twentieth, over its fiftieth, and the energy falls by 0.22 %
        assert!(!gains(431, 411) && keeps_smoother(431, 411, (9.652241, 9.630604)));
    }

    #[test]
    fn a_turn_that_clears_open_space_is_kept_with_a_smaller_overall_gain() {
        // the patch beside a cow's tail: 464 -> 451 in all, 62 -> 17 in open space
        assert!(!gains(464, 451));
        assert!(keeps(464, 451, || (62, 17)));
        // a patch at a hole's rim: fewer in all, but more in open space
        assert!(!keeps(480, 464, || (2, 8)));
        // open space cleared while the whole grows: not kept
        assert!(!keeps(464, 470, || (62, 0)));
        // a twentieth of all crossings is needed, not merely some
        assert!(!keeps(464, 451, || (62, 39)));
        assert!(keeps(464, 451, || (62, 38)));
        // the first rule decides without asking for the open-space counts
        assert!(keeps(710, 651, || unreachable!()));
        assert!(!keeps(100, 100, || unreachable!()));
        assert_eq!(keeps_by(710, 651, || unreachable!()), Some(false));
        assert_eq!(keeps_by(464, 451, || (62, 17)), Some(true));
        assert_eq!(keeps_by(480, 464, || (2, 8)), None);
        // a group is kept by open space alone: a large overall gain is not enough
        assert!(!keeps_group(710, 500, || (10, 9)));
        assert!(keeps_group(464, 451, || (62, 17)));
        assert!(!keeps_group(464, 464, || unreachable!()));
    }

    /// The `kmax` nearest neighbours of each of `points` (xyz), by brute force.
    fn brute_knn(points: &[f64], kmax: usize) -> Vec<usize> {
        let n = points.len() / 3;
        (0..n)
            .flat_map(|i| {
                let mut by: Vec<usize> = (0..n).filter(|&j| j != i).collect();
                by.sort_by(|&a, &b| {
                    dist2(&points[3 * i..], &points[3 * a..])
                        .total_cmp(&dist2(&points[3 * i..], &points[3 * b..]))
                });
                by.truncate(kmax);
                by
            })
            .collect()
    }

    /// Two sheets of 10 x 10 points 0.1 apart, the upper one at height 0.03 and shifted by half
    /// a spacing (a part thinner than the sampling), the upper normals up and the lower ones
    /// `lower` (z component); brute-force nearest neighbours.
    fn thin_part(lower: f64) -> (Vec<f64>, Vec<[f64; 3]>, Vec<usize>, usize) {
        let mut points = Vec::new();
        let mut normals = Vec::new();
        for (shift, z, nz) in [(0.0, 0.0, lower), (0.05, 0.03, 1.0)] {
            for i in 0..100 {
                points.extend_from_slice(&[shift + 0.1 * (i % 10) as f64, shift + 0.1 * (i / 10) as f64, z]);
                normals.push([0.0, 0.0, nz]);
            }
        }
        let kmax = 12;
        let knn = brute_knn(&points, kmax);
        (points, normals, knn, kmax)
    }

    #[test]
    fn the_turned_side_of_a_thin_part_faces_a_sheet_and_the_right_sides_do_not() {
        // the lower side turned up: its points have the upper side in front of them
        let (points, normals, knn, kmax) = thin_part(1.0);
        let groups = facing_groups(&points, &normals, &knn, kmax);
        assert_eq!(groups, vec![(0..100).collect::<Vec<usize>>()]);
        // both sides outward: each has the other behind it, none faces a sheet
        let (points, normals, knn, kmax) = thin_part(-1.0);
        assert!(facing_groups(&points, &normals, &knn, kmax).is_empty());
        // a single flat sheet: neighbours neither in front nor behind
        let (flat, flat_normals) = (points[..300].to_vec(), normals[..100].to_vec());
        let flat_knn: Vec<usize> =
            knn[..100 * kmax].iter().map(|&j| if j < 100 { j } else { (j + 1) % 100 }).collect();
        assert!(facing_groups(&flat, &flat_normals, &flat_knn, kmax).is_empty());
    }

    #[test]
    fn a_facing_group_is_tried_where_its_window_holds_enough_unsupported_crossings() {
        let (points, normals, knn, kmax) = thin_part(1.0);
        let lower: Vec<usize> = (0..100).collect();
        // 30 of 100 crossings in its window: tried, with the box of its points
        let got = facing_candidates(&points, &normals, (&knn, kmax), (&[], &[7]), |_| 30, 100);
        assert_eq!(got.len(), 1);
        assert_eq!(got[0].members, lower);
        assert_eq!(got[0].lo, [0.0; 3]);
        assert!(got[0].hi.iter().zip([0.9, 0.9, 0.0]).all(|(a, b)| (a - b).abs() < 1e-12));
        // 5 of 100: removing them all is no gain
        assert!(facing_candidates(&points, &normals, (&knn, kmax), (&[], &[7]), |_| 5, 100).is_empty());
        // without an off point among its points a turn changes nothing: not tried
        assert!(facing_candidates(&points, &normals, (&knn, kmax), (&[], &[150]), |_| 30, 100).is_empty());
        // a group that is already a patch candidate is not tried twice
        let patch = Candidate { members: lower, lo: [0.0; 3], hi: [1.0; 3] };
        assert!(facing_candidates(&points, &normals, (&knn, kmax), (&[patch], &[7]), |_| 30, 100).is_empty());
    }

    #[test]
    fn the_tries_past_the_first_three_take_patches_of_four_points_or_more() {
        // seven small flat clusters high above a large sheet, each its own patch, charged with
        // 20, 19, .. 14 crossings; their sizes 1, 1, 1, 2, 5, 1, 4
        let sizes = [1, 1, 1, 2, 5, 1, 4];
        let (mut points, mut normals, mut first) = (Vec::new(), Vec::new(), Vec::new());
        for (c, &size) in sizes.iter().enumerate() {
            first.push(normals.len());
            for m in 0..size {
                points.extend_from_slice(&[3.0 * c as f64 + 0.1 * m as f64, 0.0, 50.0]);
                normals.push([0.0, 0.0, 1.0]);
            }
        }
        let small = normals.len();
        for i in 0..2000 {
            points.extend_from_slice(&[10.0 + 0.1 * (i % 40) as f64, 10.0 + 0.1 * (i / 40) as f64, 0.0]);
            normals.push([0.0, 0.0, 1.0]);
        }
        // a cluster's neighbours are its other points, then points of the sheet (not tangent)
        let kmax = 8;
        let cluster = |i: usize| (0..sizes.len()).rev().find(|&c| first[c] <= i).unwrap();
        let knn: Vec<usize> = (0..normals.len())
            .flat_map(|i| {
                let mut row: Vec<usize> = if i < small {
                    let c = cluster(i);
                    (first[c]..first[c] + sizes[c]).filter(|&j| j != i).collect()
                } else {
                    (1..=kmax).map(|d| small + (i - small + d) % 2000).collect()
                };
                row.extend((0..kmax).map(|d| small + d));
                row.truncate(kmax);
                row
            })
            .collect();
        let far: Vec<[f64; 3]> = sizes
            .iter()
            .enumerate()
            .flat_map(|(c, _)| (0..20 - c).map(move |k| [3.0 * c as f64, 0.01 * k as f64, 50.5]))
            .collect();
        let tree = Octree::new(&points, 10);
        let got = candidates(&points, &normals, (&knn, kmax), &tree, &far);
        // the first three whatever their size; then the 5-point one; the 2- and 1-point ones
        // passed over, and the 4-point one past the sixth
        let want: Vec<Vec<usize>> =
            [0, 1, 2, 4].iter().map(|&c| (first[c]..first[c] + sizes[c]).collect()).collect();
        assert_eq!(got.iter().map(|g| g.members.clone()).collect::<Vec<_>>(), want);
    }

    #[test]
    fn the_crossings_are_charged_to_the_patch_of_their_nearest_point() {
        // two parallel sheets of 10 x 10 points (z = 0 and z = 1, spacing 0.1), the upper one's
        // normals turned down: two patches; crossings above the upper sheet are charged to it
        let mut points = Vec::new();
        let mut normals = Vec::new();
        for (z, nz) in [(0.0, 1.0), (1.0, -1.0)] {
            for i in 0..100 {
                points.extend_from_slice(&[0.1 * (i % 10) as f64, 0.1 * (i / 10) as f64, z]);
                normals.push([0.0, 0.0, nz]);
            }
        }
        let tree = Octree::new(&points, 10);
        let kmax = 8;
        let knn = brute_knn(&points, kmax);
        let far: Vec<[f64; 3]> = (0..12).map(|k| [0.05 + 0.07 * k as f64, 0.45, 1.3]).collect();
        // a patch of 100 points is more than 5 % of 200: none is small enough
        assert!(candidates(&points, &normals, (&knn, kmax), &tree, &far).is_empty());
        // with 2000 further points far away, both are small; only the upper one is charged
        let mut more = points.clone();
        let mut more_normals = normals.clone();
        for i in 0..2000 {
            more.extend_from_slice(&[10.0 + 0.1 * (i % 40) as f64, 10.0 + 0.1 * (i / 40) as f64, 0.0]);
            more_normals.push([0.0, 0.0, 1.0]);
        }
        let tree = Octree::new(&more, 10);
        let knn_more: Vec<usize> = (0..2200)
            .flat_map(|i| {
                if i < 200 {
                    knn[i * kmax..(i + 1) * kmax].to_vec()
                } else {
                    let b = i - 200;
                    (1..=kmax).map(|d| 200 + (b + d) % 2000).collect()
                }
            })
            .collect();
        let got = candidates(&more, &more_normals, (&knn_more, kmax), &tree, &far);
        assert_eq!(got.len(), 1, "{got:?}");
        assert_eq!(got[0].members, (100..200).collect::<Vec<_>>());
        // the box holds the upper sheet and the crossings above it
        assert_eq!((got[0].lo, got[0].hi), ([0.0, 0.0, 1.0], [0.1 * 9.0, 0.1 * 9.0, 1.3]));
        // grown by its longest side (0.9) and two lattice spacings (z: -0.1..2.4), clamped to the
        // lattice in x and y
        let lattice = Lattice { lo: [-1.05; 3], h: 0.1, dims: [31, 31, 41] };
        assert_eq!(got[0].window(&lattice), [0..31, 0..31, 9..36]);
    }
}
