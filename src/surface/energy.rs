//! Orientation of whole patches by the bending energy of the spline they make.
//!
//! The nearest-neighbour and dipole steps of [`mod@super::orient`] leave whole, internally
//! consistent patches turned the wrong way where the surface is thin or folded (legs, ears,
//! horns). Such a patch puts its off-surface points on the wrong side of the data: the
//! interpolant has to turn its sign across a thin sheet the wrong way and bends more. This step
//! asks the spline itself which sign of each patch it finds smoothest.
//!
//! # The energy as a function of the patch signs
//!
//! The off-surface fit solves the bordered system M [lambda; c] = [b; 0] of the kernel r (see
//! [`crate::spline::system`]) with b = f_c(x) - t: the carrier at every centre less the target t,
//! 0 at the data and -+ g delta at an off point p +- delta n. For the kernel r the bending energy
//! of U is a positive multiple of -lambda^T A lambda, and since A lambda + P c = b and P^T lambda
//! = 0 it equals -lambda^T b: one dot product once lambda is known.
//!
//! Turning the normals of a patch P around turns each of its off points to the other side of its
//! source. The energy is evaluated on off points made for it, in pairs p +- delta n for every
//! source ([`pairs`], one delta for both sides, the smaller of the two the placement rule of
//! [`super::offsurface`] gives): turning n then swaps the two places of a pair, which is exactly
//! the same two places with their targets negated. (The fit's own off points, one side per
//! source at the default rate, would only give the mirror image of the exact change: the place
//! p + side delta n kept with its target negated, against the new place p - side delta n. That
//! first version of this step measured worse, see below.) So with one sign t_P = +-1 per patch
//! (+1: as now) the right-hand side is affine in the signs,
//!
//! ```text
//! b(t) = b_0 + sum_P t_P c_P,     c_P = -t on the off points of P, 0 elsewhere,
//! ```
//!
//! b_0 holding the carrier's values at all centres and the targets of the off points of the
//! points that keep their sign (the small patches, below). The solution is affine too,
//! lambda(t) = lambda_0 + sum_P t_P lambda_P with M lambda_P = c_P: one factorisation of M and
//! m + 1 right-hand sides. With u = (t_1, .., t_m, 1), the columns R = [c_1 .. c_m b_0] and
//! X = M^-1 R (its lambda rows),
//!
//! ```text
//! E(t) = -lambda(t)^T b(t) = u^T H u,      H = -(R^T X + X^T R) / 2,
//! ```
//!
//! an (m+1) x (m+1) matrix (R^T X is symmetric in exact arithmetic since M is; it is symmetrised
//! against round-off). The signs minimise u^T H u with u_{m+1} = 1 fixed: turning patch P changes
//! E by -4 t_P sum_{Q != P} H_PQ u_Q, and the patch of the largest decrease is turned until none
//! decreases (the greedy descent of the dipole step, on another matrix). The carrier's column
//! b_0 is what makes the two global signs differ: with it, the spline that makes the solid's
//! inside positive where the carrier already is bends less than its mirror image.
//!
//! # Patches and limits
//!
//! Patches are those of the dipole step: neighbours in the orientation graph that are mutually
//! tangent with nearly parallel normals. The [`MAX_PATCHES`] with the most off points move; the
//! others keep their sign and enter b_0. M is factored once on rank 0 (a symmetric indefinite
//! LBL^T of faer, m + 1 right-hand sides) and the signs are broadcast, so every rank count gives
//! the same signs. The data and the pairs together are at most [`ENERGY_LIMIT`] rows (a strided
//! subset of the sources gets pairs when all would exceed it; about 1 s at 3000 rows and 4 s at 6000
//! on the 2-core machine of the measurements below); above that many data points the step is skipped with a note in the report.
//!
//! # What it measured (off by default)
//!
//! On area-uniform samples of the cow (1000, 2000, 4000 points; the benchmark's sets,
//! jobs/bench/surface.py) the agreement of the oriented normals with the true ones went from
//! 0.920 / 0.9225 / 0.960 to 0.943 / 0.9245 / 0.962, but the mesh's distance to the truth (rms, %
//! of the diagonal, 2 ranks, grid 100) from 0.72 / 0.87 / 0.85 to 1.21 / 0.86 / 0.86, the
//! vertices beyond 2 % of the diagonal from 3.5 / 4.7 / 4.6 % to 6.8 / 4.6 / 4.7 %. On the bunny
//! it helped at 1000 points (rms 0.64 -> 0.35 %, beyond 2 %: 2.2 -> 0.3 %; with noise of 0.5 %
//! of the diagonal 1.04 -> 0.53 %), hurt at 400 (0.85 -> 1.31 %) and changed nothing at 2000 and
//! 4000 (bench-results/2026-11-26-surface-energy). Orientation is the cow's bottleneck: the same PCA normals given the true
//! signs give 0.25 % / 0.15 % at 2000 / 4000 (0.23 % / 0.02 % of the vertices beyond 2 %), and
//! each patch turned by the majority of its points' true signs 0.77 % / 0.22 %. But the energy
//! does not point to the true signs: from the present signs, turning one truly wrong patch alone
//! raises the energy for most of them (patches holding 75 of 83 such points at 2000, 48 of 71 at
//! 4000), and the greedy descent ends below the energy of the true patch signs (10.75 against
//! 10.93 at 2000, 7.21 against 7.25 at 4000), so a better search would not help either. Without
//! the carrier's column in b_0 (the energy of the targets alone, as if the spline were the whole
//! function) the true signs had a higher energy than the present ones on the cow at 1000 and
//! 2000. The step is therefore an option (`fit --orient-energy on`), not the default.

use faer::linalg::solvers::Solve;
use faer::{Mat, MatRef, Side};
use rayon::prelude::*;

use super::offsurface::{off_value_parts, place, OffPoints, DELTA, MERGE};
use super::orient::{greedy_flips, make_outward, orientation_edges, tangent_patches};
use super::Neighbourhoods;
use crate::error::{Error, Result};
use crate::par::{agree, Comm};
use crate::spline::hygiene::{merge_indices, Prepared};
use crate::spline::octree::Octree;
use crate::spline::{full_system, Kernel};

/// Most patches whose signs the energy decides.
pub const MAX_PATCHES: usize = 200;
/// Most rows (data and off-surface pairs) of the system the energy is taken from.
pub const ENERGY_LIMIT: usize = 6000;

/// What the energy step did.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct EnergyFlips {
    /// Whether it ran (false for more data points than [`ENERGY_LIMIT`] rows hold).
    pub ran: bool,
    /// Patches found, how many moved and how many were turned.
    pub patches: usize,
    pub movable: usize,
    pub flipped: usize,
    /// Whether the outward rule turned all normals around after the patches were turned (then
    /// `after` is the energy of the signs before that).
    pub turned_all: bool,
    /// The energy -lambda^T b before and after (the carrier's units squared; 0 when it did not run).
    pub before: f64,
    pub after: f64,
}

/// u^T H u for the signs u (the last one the fixed part's 1) and H row-major.
pub fn energy(h: &[f64], u: &[f64]) -> f64 {
    let w = u.len();
    (0..w).map(|p| (0..w).map(|q| u[p] * h[p * w + q] * u[q]).sum::<f64>()).sum()
}

/// The matrix H ((m+1) x (m+1), row-major, index m the fixed part b_0) of the module doc, for
/// the centres (normalised, 3 per centre) with the carrier's values `carrier` and the
/// sign-dependent parts `target` (the c of each centre: 0 at the data), each centre's patch in
/// `owner` (m: fixed). Serial.
fn energy_matrix(
    centres: &[f64],
    carrier: &[f64],
    target: &[f64],
    owner: &[usize],
    m: usize,
) -> Result<Vec<f64>> {
    let kernel = Kernel::new(3, 2)?;
    let n = carrier.len();
    let (data, _) = full_system(&kernel, centres, carrier);
    let size = n + kernel.poly_count();
    let width = m + 1;
    let mut r = Mat::<f64>::zeros(size, width);
    for i in 0..n {
        if owner[i] == m {
            r[(i, m)] = carrier[i] + target[i];
        } else {
            r[(i, m)] = carrier[i];
            r[(i, owner[i])] = target[i];
        }
    }
    let factor = MatRef::from_column_major_slice(&data, size, size).lblt(Side::Lower);
    drop(data);
    let mut x = r.clone();
    factor.solve_in_place(x.as_mut());
    let mut h = vec![0.0; width * width];
    for p in 0..width {
        for q in 0..width {
            let rx: f64 = (0..n).map(|i| r[(i, p)] * x[(i, q)]).sum();
            let xr: f64 = (0..n).map(|i| x[(i, p)] * r[(i, q)]).sum();
            h[p * width + q] = -0.5 * (rx + xr);
        }
    }
    if h.iter().any(|v| !v.is_finite()) {
        return Err(Error::Numerical("orientation by energy: the system could not be solved".into()));
    }
    Ok(h)
}

/// The patch of every data point (0..m movable, m fixed), m and the number of patches found,
/// for the data `points` (normalised) with oriented `normals`, `kmax` neighbours `knn` each, and
/// the off points `off` the energy is taken from: the patches with the most off points move.
pub fn patches(
    points: &[f64],
    normals: &[[f64; 3]],
    knn: &[usize],
    kmax: usize,
    off: &OffPoints,
) -> (Vec<usize>, usize, usize) {
    let edges = orientation_edges(knn, kmax);
    let (raw, found) = tangent_patches(points, normals, &edges);
    // the patches ranked by their off points (those the energy sees), then by size
    let mut weight = vec![(0usize, 0usize); found];
    for &p in &raw {
        weight[p].1 += 1;
    }
    for &s in &off.source {
        weight[raw[s]].0 += 1;
    }
    let mut by_weight: Vec<usize> = (0..found).filter(|&p| weight[p].0 > 0).collect();
    by_weight.sort_by(|&a, &b| weight[b].cmp(&weight[a]).then(a.cmp(&b)));
    let m = by_weight.len().min(MAX_PATCHES);
    let mut rank_of = vec![m; found];
    for (r, &p) in by_weight.iter().take(m).enumerate() {
        rank_of[p] = r;
    }
    let patch: Vec<usize> = raw.iter().map(|&p| rank_of[p]).collect();
    (patch, m, found)
}

/// The energy matrix H of the module doc for the data `points` (normalised) with the off points
/// `off`, the carrier's values `carrier` at the data followed by those at the off points, what
/// the targets add to them at the off points (`target`, [`off_value_parts`]), each data point's
/// patch in `patch` (m: fixed). Serial.
pub fn patch_energy(
    points: &[f64],
    off: &OffPoints,
    carrier: &[f64],
    target: &[f64],
    patch: &[usize],
    m: usize,
) -> Result<Vec<f64>> {
    let n = patch.len();
    let mut centres = points.to_vec();
    centres.extend_from_slice(&off.centres);
    let mut owner = vec![m; n];
    owner.extend(off.source.iter().map(|&s| patch[s]));
    let mut values = vec![0.0; n];
    values.extend_from_slice(target);
    energy_matrix(&centres, carrier, &values, &owner, m)
}

/// Off points in pairs p +- delta n for an evenly strided subset of at most `most` of the data
/// `points` (normalised, `tree` over them) with unit `normals`: delta is the smaller of the two
/// sides' deltas of [`super::offsurface`], so that turning n swaps the two places exactly. A pair
/// one side of which finds no delta, or comes within [`MERGE`] times [`DELTA`] of an earlier off
/// point, is left out.
pub fn pairs(points: &[f64], normals: &[[f64; 3]], tree: &Octree, most: usize) -> OffPoints {
    let n = normals.len();
    let rate = (most as f64 / n.max(1) as f64).min(1.0);
    let picked: Vec<usize> =
        (0..n).filter(|&i| ((i + 1) as f64 * rate).floor() > (i as f64 * rate).floor()).collect();
    let placed: Vec<Option<f64>> = picked
        .par_iter()
        .map_init(Vec::new, |found, &i| {
            let out = place(points, &normals[i], tree, i, 1.0, found)?.0;
            let inside = place(points, &normals[i], tree, i, -1.0, found)?.0;
            Some(out.min(inside))
        })
        .collect();
    let mut all = OffPoints::default();
    for (&i, delta) in picked.iter().zip(placed) {
        let Some(delta) = delta else { continue };
        for side in [1.0, -1.0] {
            all.centres.extend((0..3).map(|d| points[3 * i + d] + side * delta * normals[i][d]));
            all.side.push(side);
            all.delta.push(delta);
            all.source.push(i);
        }
    }
    let keep = merge_indices(&all.centres, 3, MERGE * DELTA);
    let mut kept = vec![false; all.side.len()];
    for k in keep {
        kept[k] = true;
    }
    let mut off = OffPoints::default();
    for k in (0..all.side.len()).step_by(2) {
        if kept[k] && kept[k + 1] {
            for j in [k, k + 1] {
                off.centres.extend_from_slice(&all.centres[3 * j..3 * j + 3]);
                off.side.push(all.side[j]);
                off.delta.push(all.delta[j]);
                off.source.push(all.source[j]);
            }
        }
    }
    off.dropped = n - off.side.len() / 2;
    off
}

/// Turns whole patches of the oriented `normals` of the prepared data `prep` (neighbourhoods
/// `hoods`) where that lowers the bending energy of the spline through the data and pairs of off
/// points (see the module doc); the normals are changed in place and made outward again.
/// Computed on rank 0, identical on every rank. Collective.
pub fn flip_by_energy(
    comm: &dyn Comm,
    prep: &Prepared,
    hoods: &Neighbourhoods,
    normals: &mut [[f64; 3]],
) -> Result<EnergyFlips> {
    let n = normals.len();
    if n + 2 > ENERGY_LIMIT {
        return Ok(EnergyFlips::default());
    }
    let points = &prep.centres;
    let off = pairs(points, normals, &hoods.tree, (ENERGY_LIMIT - n) / 2);
    let (fc, target) = off_value_parts(&off, &prep.points, &prep.carrier, &prep.norm);
    let mut carrier = prep.values.clone();
    carrier.extend_from_slice(&fc);
    let (patch, m, found) = patches(points, normals, &hoods.knn, hoods.kmax, &off);
    let local = if comm.rank() == 0 {
        patch_energy(points, &off, &carrier, &target, &patch, m).map(|h| {
            let t = greedy_flips(&h, m);
            let before = energy(&h, &vec![1.0; m + 1]);
            let after = energy(&h, &t);
            let mut out = t;
            out.extend([before, after]);
            Some(out)
        })
    } else {
        Ok(None)
    };
    let mine = agree(comm, local)?;
    let t = comm.broadcast_value(0, mine);
    let (before, after) = (t[m + 1], t[m + 2]);
    let flipped = t[..m].iter().filter(|&&v| v < 0.0).count();
    for i in 0..n {
        if patch[i] < m && t[patch[i]] < 0.0 {
            normals[i] = normals[i].map(|v| -v);
        }
    }
    let turned_all = make_outward(points, normals, &hoods.knn, hoods.kmax);
    Ok(EnergyFlips { ran: true, patches: found, movable: m, flipped, turned_all, before, after })
}
