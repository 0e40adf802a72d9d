//! Outside off points where unsupported surface in open space remains, after the turns; then
//! off points on both sides at the mouths of holes.
//!
//! # What is left after the turns
//!
//! The off points are dealt at a rate (see [`crate::surface::offsurface`]): about half the data
//! points have one, the rest are held by value 0 alone. Where such points lie on a thin or
//! strongly curved part (a leg, a muzzle), nothing holds the spline below zero just outside
//! them, and a bulge or a web of false solid can join two parts across open space. The blob
//! search pins regions detached from the data, and the turns mend patches whose normals point
//! the wrong way; a bulge attached to correctly oriented points with no off point is left.
//!
//! # The step
//!
//! After every other decision, the unsupported crossings of the kept fit (the lattice edges along
//! which f changes sign farther than 2 median spacings from every data point, as the clearance
//! choice counts them, see [`crate::surface::choice`]) that lie in open space (the data's winding
//! number below [`crate::surface::blobs::OPEN_SPACE`]) are each charged to their nearest data
//! point ([`charged`]). Each charged point without an off point gets one outside, at p + delta n
//! with value -delta ([`outside_points`]): delta is the median delta of the off points already
//! placed, halved at most [`HALVINGS`] times until the place is nearest to its own source (a
//! place nearer another data point lies across a thin part, where an outside value would cut
//! it). The off points are appended to the system, so the fit borders the kept fit's factor, and
//! it is kept when the unsupported crossings of the whole lattice fall by at least
//! [`crate::surface::turns::GAIN`] of their number ([`crate::surface::turns::gains`]). Inside
//! points are not added: a bulge is false solid, and an inside point beside a thin part pushes
//! the zero set outward, the way of the bulge.
//!
//! For that count the lattice is sampled again only around the outside points
//! ([`window_nodes`]): the box of each point, its source and the crossings charged to the source,
//! grown as the turns grow a tried patch's box; elsewhere the kept fit's values stand. New
//! values of a few constraints move the zero set near them, while far away the unchanged
//! constraints pin it, as for the turns (see [`crate::surface::turns`], "Cost").
//!
//! # Measured
//!
//! On the 259 sets of the surface benchmark (the bunny and the cow at 400-4000 points, clean,
//! noisy and with a hole, thirteen samplings; 2 ranks, grid 100) the step took the sets that meet
//! every quality target from 251 to 254: the front legs of the cow at 1000 points with noise 0.1
//! % of the diagonal (mesh -> truth 0.691 -> 0.317 % of the diagonal; screened Poisson 0.659),
//! the cow at 2000 points with noise 0.5 % (0.719 -> 0.652) and with noise 0.1 % (0.408 ->
//! 0.372). None was lost. It changed 53 sets, each with less mesh -> truth; truth -> mesh rose
//! on 32 (at most 0.552 -> 0.690 on a cow at 1000 points with noise 0.5 %, where Poisson has
//! 0.699): the outside values pull the zero set inward beside the charged points. Charging at
//! least two crossings to a point before it gets an off point mended one set fewer. Cost: on 40
//! sets timed with and without the step in one run, the fit took 0.97-1.16 times as long with
//! it, median 1.07, while the whole lattice was sampled for the decision (with the windows
//! 1.04: the winding numbers at the crossings and the bordering of the outside points' rows
//! onto the kept factor remain). The windows changed 2 of the 259 sets, both still meeting
//! every quality target.
//!
//! # Both sides at the mouths of holes
//!
//! Where a scan missed a cap (an open scan), the fit closes the hole with surface no data
//! supports. Its shape is the spline's continuation of the surface around the hole, and with
//! half the points around the rim held by value 0 alone the continuation does not keep the
//! rim's slope: the cap sags into the solid. On the cow at 1000 points with a ball of 15 % of the
//! diagonal left out over its head, 80-90 % of the truth -> mesh distance (squared) lies in that
//! ball, and the truth's points there lie outside the mesh.
//!
//! The crossings of such a cap lie in the hole's mouth, where the data's winding number is near
//! 1/2 (the data's own surface, continued across the hole). So after the outside points, the
//! unsupported crossings of the same fit (before the outside points) with winding numbers in
//! [`MOUTH`] are charged to their nearest data points, and each point charged with at least
//! [`MOUTH_HITS`] of them that lies on a rim gets an off point on each side where it has none
//! ([`mouth_points`]; the delta as for the outside points). A point lies on a rim where its
//! [`RIM_NEIGHBOURS`] nearest neighbours, seen from it in its tangent plane, leave a gap of at
//! least [`MOUTH_GAP`] degrees ([`widest_gap`]): inside a sampled surface they surround it. The
//! edge of a thin part seen from its tip (an ear, a horn) leaves such a gap too, but there the
//! surface folds back: a neighbour's normal points against the point's own (a cosine below
//! [`FOLD`]), and the point is no rim; off points on both sides of a fold's edge would hold the
//! thin part open past its tip. Held on both sides, the rim fixes the zero set's slope there,
//! and the cap leaves it along the surface. The fit with them borders the kept factor and is
//! kept without a decision: the unsupported surface is no measure of a cap (a lifted cap is as
//! unsupported as a sagging one).
//!
//! Measured on the 259 sets of the surface benchmark (the bunny and the cow at 400-4000 points,
//! clean, noisy and with a hole, thirteen samplings), quality only: without the rim rule, on
//! the 52 with a hole 49 -> 51 met every quality target (the cow at 1000 points: truth -> mesh
//! median 1.064 -> 0.865 % of the diagonal), but on the 207 closed ones 205 -> 201: unsupported
//! surface near the data's surface elsewhere (a web between the bunny's ears) was pushed out as
//! well (mesh -> truth 0.492 -> 0.566 %). With the rim rule (a gap of 140 degrees) 255 of 259
//! met every target against 254 without the step: seed 2's and 4's cow-1000-open mended (truth
//! -> mesh 1.252 -> 0.992 and 1.206 -> 0.910, screened Poisson 1.224 and 1.124), seed 5's
//! bunny-1000-clean lost (far vertices 1.90 -> 2.26 %). Inside points alone for every point
//! charged with a crossing of winding number 0.1-0.5 lifted the caps further (1.25 -> 0.87 % on
//! one cow) and met every target on 197 sets; counting only crossings beside a point (near its
//! tangent plane) lost the caps' gain: a sagging cap lies behind its rim.
//!
//! The fold rule (no neighbour's normal beyond a right angle) changed 144 of the 259 sets, with
//! 255 meeting every quality target before and after: mesh -> truth 0.994 times what it was
//! (median; 0.76-1.03), truth -> mesh unchanged (median; 0.95-1.06), the mean mesh -> truth of
//! the clean sets 0.428 -> 0.420 %. Seed 5's bunny at 2000 points with noise 0.5 % went back to
//! its value before the step (0.558 -> 0.516 %; the tip of an ear had been held open), seed 11's
//! cow at 400 points 1.451 -> 1.304 %, seed 5's bunny-1000-clean 2.26 -> 2.03 % far vertices;
//! on the holed sets the caps gave back a little (mean truth -> mesh 0.581 -> 0.584 %; seed 4's
//! cow at 1000 points 0.910 -> 0.968, screened Poisson 1.124). A bound of -0.3 instead of 0
//! changed 129 sets, with the same outcome and slightly less gain on the closed ones.
//!
//! # Steeper at the rims
//!
//! The mouth points' targets are [`MOUTH_SLOPE`] times as steep as the other off points' (-+ 3 g
//! delta instead of -+ g delta, g the carrier's slope at the source; see
//! [`crate::surface::offsurface`], "Their values"). The field is f = (f_c - U(f_c)) + U(t): its
//! second term, the plain interpolant of the targets, continues the data's surface across the
//! hole, and the first, the carrier's shape between the centres, pulls the cap toward the
//! carrier's curvature. Steeper targets at the rim weigh the continuation more there, where the
//! cap leaves the data, and nowhere else: the off points of the sampled surface keep the
//! carrier's slope, so f keeps the carrier's metric beside it (the offsets of a model measure
//! distance there; the same factor on every off point and blob point lost that, and was not
//! kept).
//!
//! How steep is a trade: the continuation of a flat surrounding (a flank) is flat and a steeper
//! rim only lifts the cap toward it, while over a rounded part (a head) the continuation rises
//! past the true surface and a steep rim carries the cap past it. On the surface benchmark's
//! 240 holed sets (2 ranks, grid 100) slopes 1, 2 and 3 met every quality target on 107, 116
//! and 122; 3 lost one cap over a cow's head that 2 kept (mesh -> truth 0.465 -> 0.563 % of the
//! diagonal), and changed the closed sets by +0.0004 % in the median of the sum of both
//! distances. `--mouth-slope` sets it; details in the README ("Steeper targets at the rims").
//!
//! # Caps pushed outward
//!
//! Held at its rim, a cap still closes a hole along the spline's continuation, which bends
//! back toward the carrier the farther it lies from the data: over a flank or the end of a
//! solid it sags below the true surface, which keeps its bulge across the hole. How far the
//! true surface rises above the cap is told by the rim itself. Continued from a rim point p
//! along its tangent plane (outward normal n), the surface would run level with that plane; a
//! crossing q of the cap lies inside it by the depth -(q - p).n. Where the surface around the
//! hole is flat (a solid's base) the cap lies in the rim's plane and the depth is nil; where
//! it curves round (a flank) the cap lies below the tangents of its rim by an angle about as
//! wide as the hole's, and where the hole takes the end of a part (the rump, a stump) the rim's
//! tangents run along the part and the cap lies a whole radius below them. The true surface
//! lies between the cap and that plane: a sphere continued over a hole whose rim points see
//! its chord at the angle t below their tangents rises above the chord by tan(t / 2) times the
//! distance from the rim, which is half the depth sin(t) for small holes and the whole of it
//! for a hemisphere.
//!
//! So the unsupported crossings of the same fit in [`MOUTH`] whose nearest data point is one of
//! the rim points just held, farther than [`CAP_FROM`] median spacings of the data from it and
//! below its tangent plane, each get an inside point at the crossing, one per spacing
//! ([`cap_points`]): delta is [`CAP_BULGE`] times the crossing's depth, the target +g delta at
//! the slope of the other off points (not the rim's steeper one). The zero set moves outward by
//! about that much, least near the rim and most in the middle of the hole, most where the
//! surface around the hole turns most. The points join the mouth points' fit; no decision keeps
//! or drops them (a raised cap is as unsupported as a sagging one). Only crossings nearest to
//! rim points are taken: those nearest to other points lie in the gaps of a sampled surface,
//! where pushing moves the surface off the data. Nor are crossings near the data: random
//! samples leave gaps of a few median spacings, and noise makes rims of their edges (on a
//! sphere of 1500 points with noise of 0.2 % of the diagonal, 16 rim points, and crossings up
//! to 3.0 spacings from the data over its sampled surface; pushed there by a quarter of their
//! distance from the data, its farthest vertex lay 0.028 from the sphere of radius 1, beyond
//! half the lattice spacing of 0.047 that the fit otherwise keeps).
//!
//! How far: on the surface benchmark (2 ranks, grid 100, quality only) the 80 sets with a hole
//! in the back, the head, a flank, the base or the far end of the long axis (five samplings)
//! met every quality target on 41 sets unpushed. Pushed by a fraction of each crossing's
//! distance from the data (the first form of this step) they met 47, 50, 55 and 59 with 0.1,
//! 0.15, 0.25 and 0.35, the sum of both distances lowest with 0.25 (109.70 % of the diagonal;
//! 107.86 with [`CAP_FROM`]), and 0.35 lost caps that rose past the truth. Pushed by a
//! fraction of their depth (with [`CAP_FROM`]) they met 58, 61 and 60 with 0.6, 0.75 and 1
//! (sums 106.65, 106.17, 106.80). On all 240 holed sets of fifteen samplings 0.75 of the depth
//! met 173 against 161 with a quarter of the distance (sum 316.93 against 321.41): the far ends
//! of the long axis (the cow's rump, the bunny's ear) 24 -> 35 of 60, the flanks 56 -> 57, the
//! base or a hoof 24 -> 25, while two caps over the cow's head went past the truth (a rounded
//! end, whose rim runs along the head as the body's does along the body; 57 -> 56 of 60).
//! On the 239 closed sets 232 met every target against 231 (sum of both distances +0.2 %; 45
//! sets nearer, 25 farther): the bunny scan's own holes in its base, open in the truth too,
//! are capped flatter (seed 6's bunny-2000-clean mended), while gaps at the edges of noisy
//! small scans are pushed a little further (seed 10's bunny-1000-noise0.5 mesh -> truth 0.600
//! -> 0.663 %).
//! [`CAP_BULGE`] is 0.75; `--cap-bulge` sets the fraction; 0 leaves the caps as the rim points
//! alone shape them.

use std::collections::HashMap;
use std::ops::{Range, RangeBounds};

use crate::spline::octree::Octree;
use crate::surface::blobs::Lattice;
use crate::surface::normals::dist2;
use crate::surface::offsurface::{place_from, OffPoints};
use crate::surface::orient::dot;
use crate::surface::turns::WINDOW;

/// The most times the median delta is halved for one outside point.
pub const HALVINGS: usize = 3;

/// The data's winding numbers of the unsupported crossings charged for off points at the rims
/// of holes: the mouths of holes (see the module doc).
pub const MOUTH: Range<f64> = 0.4..0.6;
/// Fewest crossings in the mouths of holes charged to a data point for its off points there.
pub const MOUTH_HITS: usize = 3;
/// The widest gap (degrees) between a data point's neighbours around it for it to count as on
/// a rim ([`widest_gap`]).
pub const MOUTH_GAP: f64 = 140.0;
/// The slope of the mouth points' targets as a multiple of the other off points' (see the
/// module doc, "Steeper at the rims").
pub const MOUTH_SLOPE: f64 = 3.0;
/// How far the caps over holes are pushed outward: the cap points' deltas as a fraction of
/// their depth below the tangent planes of their rim points (see the module doc, "Caps pushed
/// outward").
pub const CAP_BULGE: f64 = 0.75;
/// How far from the data (in its median spacings) a crossing must lie for a cap point (see the
/// module doc, "Caps pushed outward"): nearer, it lies where a sampled surface runs on.
pub const CAP_FROM: f64 = 3.5;
/// How many nearest neighbours [`widest_gap`] looks at.
pub const RIM_NEIGHBOURS: usize = 15;
/// The least cosine between the normals of a rim point and of each of its
/// [`RIM_NEIGHBOURS`] nearest: below it the surface folds back there (the edge of a thin part
/// seen from its tip), which is no hole's rim.
pub const FOLD: f64 = 0.0;

/// How many of the unsupported `crossings` (lattice coordinates, which are the normalised ones)
/// with the data's winding numbers `winding` in `band` (`..OPEN_SPACE` for open space,
/// [`MOUTH`] for the mouths of holes) are nearest to each of the `n` data points of `tree`.
pub fn charged(
    crossings: &[[f64; 3]],
    winding: &[f64],
    tree: &Octree,
    n: usize,
    band: impl RangeBounds<f64>,
) -> Vec<usize> {
    let mut hits = vec![0usize; n];
    let mut near = Vec::new();
    for (q, _) in crossings.iter().zip(winding).filter(|(_, w)| band.contains(w)) {
        tree.nearest_k(*q, 1, &mut near);
        if let Some(&(_, j)) = near.first() {
            hits[j] += 1;
        }
    }
    hits
}

/// The outside off points of the data `points` (normalised, 3 per point, `tree` built over them,
/// outward unit `normals`) that `hits` charged with a crossing and that have no off point in
/// `off`, the off points already placed (see the module doc). Empty where `off` has none (no
/// delta to start from).
pub fn outside_points(
    points: &[f64],
    normals: &[[f64; 3]],
    tree: &Octree,
    off: &OffPoints,
    hits: &[usize],
) -> OffPoints {
    let mut has_off = vec![false; normals.len()];
    off.source.iter().for_each(|&i| has_off[i] = true);
    placed_on_side(points, normals, tree, (off, 1.0), |i| hits[i] > 0 && !has_off[i])
}

/// The off points of the data `points` (as for [`outside_points`]; `knn` the nearest neighbours
/// of each point, `kmax` per point, nearest first) that `hits` charged with at least
/// [`MOUTH_HITS`] crossings in the mouths of holes and that lie on a rim ([`widest_gap`] of at
/// least [`MOUTH_GAP`], no neighbour's normal at a cosine below [`FOLD`] to its own), on each
/// side where they have none in `off` (see the module doc, "Both sides at the mouths of
/// holes"): the inside points first, then the outside ones, each in the order of their
/// sources; empty where `off` has none. With them, how many points so charged with the gap of
/// a rim were left out at a fold.
pub fn mouth_points(
    points: &[f64],
    normals: &[[f64; 3]],
    (tree, (knn, kmax)): (&Octree, (&[usize], usize)),
    off: &OffPoints,
    hits: &[usize],
) -> (OffPoints, usize) {
    let k = RIM_NEIGHBOURS.min(kmax);
    let mut folds = 0;
    let rim: Vec<bool> = (0..normals.len())
        .map(|i| {
            let near = &knn[i * kmax..i * kmax + k];
            if hits[i] < MOUTH_HITS || widest_gap(points, i, &normals[i], near) < MOUTH_GAP.to_radians() {
                return false;
            }
            let folded = near.iter().any(|&j| dot(&normals[i], &normals[j]) < FOLD);
            folds += usize::from(folded);
            !folded
        })
        .collect();
    let mut out = OffPoints::default();
    for side in [-1.0, 1.0] {
        let mut has = vec![false; normals.len()];
        off.source.iter().zip(&off.side).filter(|(_, &s)| s == side).for_each(|(&i, _)| has[i] = true);
        let placed = placed_on_side(points, normals, tree, (off, side), |i| rim[i] && !has[i]);
        out.centres.extend_from_slice(&placed.centres);
        out.side.extend_from_slice(&placed.side);
        out.delta.extend_from_slice(&placed.delta);
        out.source.extend_from_slice(&placed.source);
        out.dropped += placed.dropped;
    }
    (out, folds)
}

/// The cap points (see the module doc, "Caps pushed outward"): for each of the unsupported
/// `crossings` (normalised coordinates) with the data's winding number (`winding`) in
/// [`MOUTH`] whose nearest data point (of `tree`, with outward unit `normals`) is one that
/// `rim` marks, at least [`CAP_FROM`] times `spacing` (the data's median spacing)
/// from it, below its tangent plane, and `spacing` from every crossing taken before, an inside
/// point at the crossing with delta `bulge` times its depth below that plane, its source the
/// nearest data point. The crossings' coordinates are first rounded to multiples of [`SNAP`].
/// In the order of the crossings.
pub fn cap_points(
    (crossings, winding): (&[[f64; 3]], &[f64]),
    (normals, tree): (&[[f64; 3]], &Octree),
    rim: &[bool],
    spacing: f64,
    bulge: f64,
) -> OffPoints {
    let mut out = OffPoints::default();
    if !(spacing > 0.0 && bulge > 0.0) {
        return out;
    }
    // the crossings taken, hashed by cells of side `spacing`: one nearer than that to a new one
    // lies in its cell or a neighbouring one
    let cell = |q: &[f64; 3]| q.map(|x| (x / spacing).floor() as i64);
    let mut taken: HashMap<[i64; 3], Vec<[f64; 3]>> = HashMap::new();
    let mut near = Vec::new();
    for (q, _) in crossings.iter().zip(winding).filter(|(_, w)| MOUTH.contains(w)) {
        let q = &q.map(snapped);
        tree.nearest_k(*q, 1, &mut near);
        let Some(&(d2, source)) = near.first() else {
            return out;
        };
        if !rim[source] || d2 < (CAP_FROM * spacing).powi(2) {
            continue;
        }
        // how far the crossing lies inside the tangent plane of its rim point
        let p = tree.point(source);
        let depth = -dot(&[0, 1, 2].map(|k| q[k] - p[k]), &normals[source]);
        if depth <= 0.0 {
            continue;
        }
        let c = cell(q);
        let crowded = (-1..=1).any(|i| {
            (-1..=1).any(|j| {
                (-1..=1).any(|k| {
                    taken
                        .get(&[c[0] + i, c[1] + j, c[2] + k])
                        .is_some_and(|ks| ks.iter().any(|t| dist2(t, q) < spacing * spacing))
                })
            })
        });
        if crowded {
            continue;
        }
        taken.entry(c).or_default().push(*q);
        out.centres.extend_from_slice(q);
        out.side.push(-1.0);
        out.delta.push(bulge * depth);
        out.source.push(source);
    }
    out
}

/// The multiple of [`SNAP`] nearest to `x`: a crossing lies where the linear interpolation of
/// the field along its lattice edge vanishes, and fields that agree to rounding (the ranks'
/// sums in other orders) move it in the last bits; rounded to a step far below the lattice's,
/// the cap points are the same bit for bit whatever the ranks, save where a coordinate lies
/// within rounding of a half step.
fn snapped(x: f64) -> f64 {
    (x / SNAP).round() * SNAP
}

/// The step the cap points' coordinates are rounded to (normalised units, the data's box about
/// 2 across): 2^-20.
pub const SNAP: f64 = 1.0 / 1_048_576.0;

/// The widest angle (radians) between the directions from data point `i` (of `points`, 3 per
/// point) to consecutive ones of its `neighbours`, projected onto its tangent plane (unit
/// `normal`): small where the neighbours surround the point, half a turn or more on the rim of
/// a hole or at the edge of a scan.
pub fn widest_gap(points: &[f64], i: usize, normal: &[f64; 3], neighbours: &[usize]) -> f64 {
    // an orthonormal basis (u, v) of the tangent plane, from the axis least along the normal
    let axis = if normal[0].abs() < 0.9 { [1.0, 0.0, 0.0] } else { [0.0, 1.0, 0.0] };
    let t = dot(&axis, normal);
    let u = [0, 1, 2].map(|d| axis[d] - t * normal[d]);
    let u = u.map(|x| x / dot(&u, &u).sqrt());
    let v = [
        normal[1] * u[2] - normal[2] * u[1],
        normal[2] * u[0] - normal[0] * u[2],
        normal[0] * u[1] - normal[1] * u[0],
    ];
    let mut angles: Vec<f64> = neighbours
        .iter()
        .map(|&j| {
            let d = [0, 1, 2].map(|k| points[3 * j + k] - points[3 * i + k]);
            dot(&d, &v).atan2(dot(&d, &u))
        })
        .collect();
    if angles.is_empty() {
        return std::f64::consts::TAU;
    }
    angles.sort_by(f64::total_cmp);
    let around = angles[0] + std::f64::consts::TAU - angles[angles.len() - 1];
    angles.windows(2).map(|w| w[1] - w[0]).fold(around, f64::max)
}

/// Off points on `side` (+1 outside, -1 inside) of the data points that `wanted` names, in the
/// order of their indices: delta the median of `off`'s, halved at most [`HALVINGS`] times until
/// the place is nearest to its own point (dropped where none is). Empty where `off` has none.
fn placed_on_side(
    points: &[f64],
    normals: &[[f64; 3]],
    tree: &Octree,
    (off, side): (&OffPoints, f64),
    wanted: impl Fn(usize) -> bool,
) -> OffPoints {
    let mut out = OffPoints::default();
    let mut deltas = off.delta.clone();
    deltas.sort_by(f64::total_cmp);
    let Some(&start) = deltas.get(deltas.len() / 2) else {
        return out;
    };
    let mut found = Vec::new();
    for i in (0..normals.len()).filter(|&i| wanted(i)) {
        match place_from(points, &normals[i], tree, (i, side), (start, HALVINGS), &mut found) {
            Some((delta, q)) => {
                out.centres.extend_from_slice(&q);
                out.side.push(side);
                out.delta.push(delta);
                out.source.push(i);
            }
            None => out.dropped += 1,
        }
    }
    out
}

/// The nodes of `lattice` (sorted, each once) that a fit with the outside points `extra` may
/// change, sampled again for the decision (see the module doc): for each outside point, the box
/// of the point, its source among the data `points` (normalised, `tree` built over them) and the
/// unsupported `crossings` in open space (winding numbers `winding` below `open_space`) charged to
/// that source, grown by [`WINDOW`] times its longest side and two lattice spacings, as the turns
/// grow a tried patch's box.
pub fn window_nodes(
    lattice: &Lattice,
    points: &[f64],
    tree: &Octree,
    (crossings, winding, open_space): (&[[f64; 3]], &[f64], f64),
    extra: &OffPoints,
) -> Vec<usize> {
    let n = points.len() / 3;
    let mut boxes: Vec<Option<([f64; 3], [f64; 3])>> = vec![None; n];
    extra.source.iter().for_each(|&i| {
        let p = [points[3 * i], points[3 * i + 1], points[3 * i + 2]];
        boxes[i] = Some((p, p));
    });
    let grow = |b: &mut ([f64; 3], [f64; 3]), q: &[f64]| {
        for d in 0..3 {
            b.0[d] = b.0[d].min(q[d]);
            b.1[d] = b.1[d].max(q[d]);
        }
    };
    let mut near = Vec::new();
    for (q, _) in crossings.iter().zip(winding).filter(|(_, &w)| w < open_space) {
        tree.nearest_k(*q, 1, &mut near);
        if let Some(b) = near.first().and_then(|&(_, j)| boxes[j].as_mut()) {
            grow(b, q);
        }
    }
    let mut nodes = Vec::new();
    for (q, &i) in extra.centres.chunks_exact(3).zip(&extra.source) {
        let mut b = boxes[i].expect("every outside point's source has a box");
        grow(&mut b, q);
        lattice.push_window(&lattice.around(b.0, b.1, WINDOW), &mut nodes);
    }
    nodes.sort_unstable();
    nodes.dedup();
    nodes
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::surface::normals::nearest;

    /// A 5 x 5 grid of points in the plane z = 0, spacing 0.1, normals +z.
    fn plane() -> (Vec<f64>, Vec<[f64; 3]>) {
        let points: Vec<f64> =
            (0..25).flat_map(|k| [0.1 * (k % 5) as f64, 0.1 * (k / 5) as f64, 0.0]).collect();
        (points, vec![[0.0, 0.0, 1.0]; 25])
    }

    fn off_at(sources: &[usize], delta: &[f64]) -> OffPoints {
        OffPoints {
            centres: vec![0.0; 3 * sources.len()],
            side: vec![1.0; sources.len()],
            delta: delta.to_vec(),
            source: sources.to_vec(),
            dropped: 0,
        }
    }

    #[test]
    fn crossings_in_open_space_are_charged_to_their_nearest_data_point() {
        let (points, _) = plane();
        let tree = Octree::new(&points, 4);
        // above point 0, above point 12 (twice), and above point 24 but in the mouth of a hole
        let crossings = [[0.0, 0.0, 0.2], [0.2, 0.2, 0.3], [0.21, 0.19, 0.1], [0.4, 0.4, 0.2]];
        let winding = [0.0, 0.05, 0.09, 0.2];
        let hits = charged(&crossings, &winding, &tree, 25, ..0.1);
        assert_eq!((hits[0], hits[12], hits[24]), (1, 2, 0));
        assert_eq!(hits.iter().sum::<usize>(), 3);
    }

    #[test]
    fn charged_points_without_an_off_point_get_one_outside_at_the_median_delta() {
        let (points, normals) = plane();
        let tree = Octree::new(&points, 4);
        let mut hits = vec![0; 25];
        (hits[3], hits[7], hits[12]) = (1, 4, 2);
        // point 7 has an off point already; the median of 0.01, 0.02, 0.04 is 0.02
        let off = off_at(&[7, 8, 9], &[0.01, 0.04, 0.02]);
        let out = outside_points(&points, &normals, &tree, &off, &hits);
        assert_eq!(out.source, vec![3, 12]);
        assert_eq!(out.side, vec![1.0, 1.0]);
        assert_eq!(out.delta, vec![0.02, 0.02]);
        assert_eq!(&out.centres[3..], &[0.2, 0.2, 0.02]);
        // without off points there is no delta to start from
        assert!(outside_points(&points, &normals, &tree, &off_at(&[], &[]), &hits).side.is_empty());
    }

    #[test]
    fn the_widest_gap_is_small_inside_a_sampled_surface_and_half_a_turn_at_its_edge() {
        let (points, normals) = plane();
        let tree = Octree::new(&points, 4);
        let knn = nearest(&tree, &points, RIM_NEIGHBOURS);
        let gap = |i: usize| {
            widest_gap(&points, i, &normals[i], &knn[i * RIM_NEIGHBOURS..(i + 1) * RIM_NEIGHBOURS])
        };
        // the centre: its 8 nearest surround it at every 45 degrees
        assert!(gap(12) <= std::f64::consts::FRAC_PI_4 + 1e-12, "{}", gap(12));
        // an edge, a corner
        assert!((gap(2) - std::f64::consts::PI).abs() < 1e-12, "{}", gap(2));
        assert!((gap(0) - 1.5 * std::f64::consts::PI).abs() < 1e-12, "{}", gap(0));
        assert_eq!(widest_gap(&points, 0, &normals[0], &[]), std::f64::consts::TAU);
    }

    #[test]
    fn points_charged_in_the_mouth_of_a_hole_on_a_rim_get_the_sides_they_lack() {
        let (points, normals) = plane();
        let tree = Octree::new(&points, 4);
        let knn = nearest(&tree, &points, RIM_NEIGHBOURS);
        // crossings with winding numbers around 1/2 above point 12, one in open space there
        let crossings = [[0.2, 0.2, 0.1], [0.21, 0.2, 0.2], [0.2, 0.19, 0.3], [0.2, 0.2, 0.4]];
        let hits = charged(&crossings, &[0.45, 0.5, 0.59, 0.05], &tree, 25, MOUTH);
        assert_eq!((hits[12], hits.iter().sum::<usize>()), (3, 3));
        // on the edge y = 0 (a rim): point 1 has an inside off point, 3 an outside one, 2 none;
        // the corner 4 is charged twice only, the centre 12 is no rim
        let mut hits = vec![0; 25];
        (hits[1], hits[2], hits[3], hits[4], hits[12]) = (3, MOUTH_HITS, 5, 2, 9);
        let mut off = off_at(&[1, 3, 20], &[0.01, 0.04, 0.02]);
        off.side[0] = -1.0;
        let hoods = (&tree, (&knn[..], RIM_NEIGHBOURS));
        let (out, folds) = mouth_points(&points, &normals, hoods, &off, &hits);
        assert_eq!(folds, 0);
        // the inside points first, then the outside ones, each by source; delta the median 0.02
        assert_eq!(out.source, vec![2, 3, 1, 2]);
        assert_eq!(out.side, vec![-1.0, -1.0, 1.0, 1.0]);
        assert_eq!(out.delta, vec![0.02; 4]);
        assert_eq!(&out.centres[..3], &[0.2, 0.0, -0.02]);
        assert_eq!(&out.centres[9..], &[0.2, 0.0, 0.02]);
        // without off points there is no delta to start from
        assert!(mouth_points(&points, &normals, hoods, &off_at(&[], &[]), &hits).0.side.is_empty());
        // a neighbour facing the other way (point 7, beside the rim): the surface folds back
        // there, no rim; a neighbour at a right angle still leaves the rim
        let mut folded = normals.clone();
        folded[7] = [0.0, 0.0, -1.0];
        let (out, folds) = mouth_points(&points, &folded, hoods, &off, &hits);
        assert_eq!((out.side.len(), folds), (0, 3));
        folded[7] = [1.0, 0.0, 0.0];
        assert_eq!(mouth_points(&points, &folded, hoods, &off, &hits).0.source, vec![2, 3, 1, 2]);
    }

    #[test]
    fn the_decision_samples_the_boxes_of_the_outside_points_and_their_crossings_grown() {
        let (points, normals) = plane();
        let tree = Octree::new(&points, 4);
        // a lattice over [-1, 1]^3, spacing 0.05 (41 nodes a side)
        let lattice = Lattice::new([-1.0; 3], [1.0; 3], 41);
        // two crossings in open space nearest to point 12 (0.2, 0.2, 0), one in the mouth of a
        // hole above point 24 (not charged), one above point 0 (which has an off point already)
        let crossings = [[0.2, 0.2, 0.3], [0.18, 0.22, 0.05], [0.4, 0.4, 0.2], [0.0, 0.0, 0.1]];
        let winding = [0.0, 0.05, 0.2, 0.0];
        let hits = charged(&crossings, &winding, &tree, 25, ..0.1);
        let out = outside_points(&points, &normals, &tree, &off_at(&[0], &[0.02]), &hits);
        assert_eq!((out.source.clone(), &out.centres[..]), (vec![12], &[0.2, 0.2, 0.02][..]));
        let nodes = window_nodes(&lattice, &points, &tree, (&crossings, &winding, 0.1), &out);
        // the box (0.18, 0.2, 0) - (0.2, 0.22, 0.3), longest side 0.3, grown by 0.3 + 2 x 0.05
        let window = lattice.around([0.18, 0.2, 0.0], [0.2, 0.22, 0.3], WINDOW);
        assert_eq!(nodes.len(), window.iter().map(|r| r.len()).product::<usize>());
        let at = |q: [f64; 3]| {
            let idx = q.map(|v| ((v + 1.0) / 0.05).round() as usize);
            idx[0] + 41 * (idx[1] + 41 * idx[2])
        };
        // x from -0.22 to 0.6, y from -0.2 to 0.62, z from -0.4 to 0.7
        for inside in [[0.2, 0.2, 0.0], [-0.2, -0.15, -0.35], [0.55, 0.6, 0.65]] {
            assert!(nodes.binary_search(&at(inside)).is_ok(), "{inside:?}");
        }
        for outside in
            [[-0.3, 0.2, 0.0], [0.7, 0.2, 0.0], [0.2, 0.75, 0.0], [0.2, 0.2, -0.5], [0.2, 0.2, 0.8]]
        {
            assert!(nodes.binary_search(&at(outside)).is_err(), "{outside:?}");
        }
        assert!(nodes.windows(2).all(|w| w[0] < w[1]));
        // no outside point, nothing to sample
        let none = outside_points(&points, &normals, &tree, &off_at(&[], &[]), &hits);
        assert!(window_nodes(&lattice, &points, &tree, (&crossings, &winding, 0.1), &none).is_empty());
    }

    #[test]
    fn delta_is_halved_until_the_place_is_nearest_to_its_own_point() {
        // a thin part: point 1 lies 0.05 above point 0, whose normal points at it
        let points = vec![0.0, 0.0, 0.0, 0.0, 0.0, 0.05, 1.0, 0.0, 0.0];
        let normals = vec![[0.0, 0.0, 1.0], [0.0, 0.0, 1.0], [0.0, 0.0, 1.0]];
        let tree = Octree::new(&points, 4);
        let off = off_at(&[2], &[0.08]);
        let out = outside_points(&points, &normals, &tree, &off, &[1, 0, 0]);
        // 0.08, 0.04 lie nearer point 1; 0.02 is nearest to point 0
        assert_eq!(out.delta, vec![0.02]);
        // with a median delta halved more than HALVINGS times no place is its own: dropped
        let far = off_at(&[2], &[0.08 * 16.0 * 2.0]);
        let out = outside_points(&points, &normals, &tree, &far, &[1, 0, 0]);
        assert_eq!((out.side.len(), out.dropped), (0, 1));
    }

    #[test]
    fn cap_points_lie_at_mouth_crossings_nearest_to_rims_with_delta_growing_with_their_depth() {
        let (points, _) = plane();
        // the solid lies above the plane (outward normals down), so crossings above it lie
        // inside the tangent planes of their rim points
        let mut normals = vec![[0.0, 0.0, -1.0]; 25];
        // a rim point whose surface rises toward its hole: its tangent plane is tilted
        normals[2] = [-0.6, 0.0, -0.8];
        // one whose surface bends away from its crossing: the crossing lies outside
        normals[22] = [0.0, 0.0, 1.0];
        let tree = Octree::new(&points, 4);
        let data = (&normals[..], &tree);
        // the grid's spacing: every point's nearest neighbour lies 0.1 away
        let spacing = 0.1;
        let mut rim = vec![false; 25];
        (rim[2], rim[12], rim[22]) = (true, true, true);
        let crossings = [
            [0.2, 0.2, 0.4],   // above rim point 12, 0.4 away and deep: taken
            [0.21, 0.2, 0.43], // within a spacing of the one taken: left
            [0.2, 0.2, 0.3],   // nearer to the data than CAP_FROM spacings: left
            [0.2, 0.0, 0.5],   // above rim point 2, 0.5 away, 0.4 deep: taken
            [0.0, 0.0, 0.4],   // above point 0, no rim: left
            [0.2, 0.0, 0.45],  // above rim point 2 but in open space: left
            [0.2, 0.4, 0.4],   // above rim point 22, outside its tangent plane: left
        ];
        let winding = [0.5, 0.45, 0.55, 0.41, 0.5, 0.1, 0.5];
        let out = cap_points((&crossings, &winding), data, &rim, spacing, 0.5);
        assert_eq!(out.source, vec![12, 2]);
        assert_eq!(out.side, vec![-1.0, -1.0]);
        // at the crossings rounded to multiples of SNAP
        assert_eq!(out.centres, [crossings[0].map(snapped), crossings[3].map(snapped)].concat());
        assert!((out.centres[0] - 0.2).abs() <= SNAP / 2.0 && out.centres[0] != 0.2);
        // half the depth: 0.4 under a level rim, 0.5 x 0.8 under the tilted one
        assert!((out.delta[0] - 0.2).abs() < 1e-6 && (out.delta[1] - 0.2).abs() < 1e-6, "{:?}", out.delta);
        // the crossing left for crowding is taken where the first is not
        let out = cap_points((&crossings[1..], &winding[1..]), data, &rim, spacing, 0.5);
        assert_eq!(out.source, vec![12, 2]);
        // no bulge or no spacing: none
        assert!(cap_points((&crossings, &winding), data, &rim, spacing, 0.0).side.is_empty());
        assert!(cap_points((&crossings, &winding), data, &rim, 0.0, 0.5).side.is_empty());
    }
}
