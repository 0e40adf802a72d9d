//! Metamorphosis between two solids A and B, optionally controlled by a space mapping through
//! user-given point pairs (Savchenko, Pasko, Sourin and Kunii's metamorphosis through space
//! mappings).
//!
//! # The common frame and the frames in time
//!
//! Both solids are taken in world coordinates, where they were fitted (or where the expressions
//! A and B put them: `translate`, `rotate` and `scale` align solids that were scanned apart). Their
//! values are made comparable by their units (see [`crate::frep::expr`]: f / u is near the surface
//! the signed distance in length units). Frame t in [0, 1] is
//!
//! ```text
//! f_t(x) = u_t ((1 - t) f_A(M_A,t(x)) / u_A + t f_B(M_B,t(x)) / u_B),     u_t = (1 - t) u_A + t u_B,
//! ```
//!
//! so f_0 = f_A and f_1 = f_B exactly (the first and last frames are the two solids' own volumes,
//! taken as they are) and in between the surfaces move over comparable distances. Without point
//! pairs both maps M are the identity. Such a plain blend of two distance-like functions shrinks
//! where the solids do not overlap: half-way between a solid and its copy moved by v it is thinner
//! than the solid moved by v/2 (for a convex solid the distance inside is concave, so the mean of
//! the two distances is at most the distance to the half-way copy). Point pairs that follow the
//! motion remove the shrinking.
//!
//! # Controlled metamorphosis
//!
//! Pairs (p_i, p'_i), i = 1..n, say that the feature of A at p_i becomes the feature of B at p'_i.
//! At time t the pair is at q_i(t) = (1 - t) p_i + t p'_i. A point x of frame t is looked up in A
//! at M_A,t(x) and in B at M_B,t(x), where the maps are volume splines through the pairs' positions:
//!
//! ```text
//! M_A,t(x) = x + D_A,t(x),   D_A,t(q_i(t)) = p_i  - q_i(t)  = t (p_i - p'_i)
//! M_B,t(x) = x + D_B,t(x),   D_B,t(q_i(t)) = p'_i - q_i(t)  = (1 - t) (p'_i - p_i)
//! ```
//!
//! Each component of a displacement D is the spline of least bending energy with the kernel r
//! and a linear polynomial, D(x) = sum_i mu_i |x - q_i| + c_0 + c . x with sum_i mu_i = 0 and
//! sum_i mu_i q_i = 0 (the same bordered system as the solid's spline, solved here by the serial
//! dense LU of [`crate::linalg::dense`] in the coordinates normalised to the pairs' box). So at time
//! t the point q_i(t) shows A's p_i and B's p'_i: the features travel along straight lines from
//! where A has them to where B has them, the rest of space follows smoothly, and far from the
//! pairs the maps tend to affine maps. At t = 0 D_A vanishes (A is seen as it is), at t = 1 D_B
//! does. The spline needs at least four pairs whose positions q_i(t) are distinct and not all on
//! one plane.

use std::path::Path;
use std::sync::{Arc, Mutex};

use faer::MatRef;
use rayon::prelude::*;

use super::expr::Expr;
use super::{pointwise, Implicit};
use crate::error::{Error, Result};
use crate::grid::Grid;
use crate::linalg::dense::{relative_residual, BlockedLu};
use crate::spline::hygiene::{bounding_box, check_unisolvent};
use crate::spline::system::dist2;
use crate::spline::{full_system, Field, Kernel, Normalisation, Spline};

/// Most point pairs (the displacement systems are dense and solved on one process per frame).
pub const MAX_PAIRS: usize = 2000;

/// A point pair (p, p').
pub type Pair = ([f64; 3], [f64; 3]);

/// Reads point pairs `x y z x' y' z'`, one per line; blank lines and `#` comments are skipped.
pub fn read_pairs(path: &Path) -> Result<Vec<Pair>> {
    Ok(read_pairs_with_lines(path)?.0)
}

/// [`read_pairs`] with the line of each pair in the file (from 1), for messages about them.
pub fn read_pairs_with_lines(path: &Path) -> Result<(Vec<Pair>, Vec<usize>)> {
    crate::io::staging::note_input(path);
    let text = crate::io::text::read(path, "point-pair")?;
    let (mut pairs, mut lines) = (Vec::new(), Vec::new());
    for (no, line) in text.lines().enumerate() {
        let line = line.split('#').next().unwrap_or("").trim();
        if line.is_empty() {
            continue;
        }
        let at = format!("line {}", no + 1);
        let v: Vec<f64> = line
            .split(|c: char| c.is_whitespace() || c == ',')
            .filter(|t| !t.is_empty())
            .map(|t| t.parse::<f64>().ok().filter(|v| v.is_finite()))
            .collect::<Option<_>>()
            .ok_or_else(|| Error::input(path, &at, "expected six finite numbers x y z x' y' z'"))?;
        if v.len() != 6 {
            return Err(Error::input(
                path,
                &at,
                format!("expected six numbers x y z x' y' z', found {}", v.len()),
            ));
        }
        pairs.push(([v[0], v[1], v[2]], [v[3], v[4], v[5]]));
        lines.push(no + 1);
    }
    if pairs.len() < 4 || pairs.len() > MAX_PAIRS {
        return Err(Error::input(
            path,
            "",
            format!("{} point pairs: a space mapping needs 4 to {MAX_PAIRS} pairs", pairs.len()),
        ));
    }
    if let Some((i, j, t, tol)) = paths_meeting(&pairs) {
        let x: [f64; 3] = std::array::from_fn(|d| (1.0 - t) * pairs[i].0[d] + t * pairs[i].1[d]);
        let when = match t {
            0.0 => "start at one point of A".to_string(),
            1.0 => "end at one point of B".to_string(),
            t => format!("meet on their way at t = {t:.4}"),
        };
        return Err(Error::input(
            path,
            format!("lines {} and {}", lines[i], lines[j]),
            format!(
                "the two pairs {when}, ({:.6e}, {:.6e}, {:.6e}), closer than {tol:.3e} (1e-9 of the extent of \
                 all pairs): at that frame one point would have to show two features; move one of them (or a \
                 pair far from the others, which widens the extent)",
                x[0], x[1], x[2]
            ),
        ));
    }
    // the maps' first and last frames interpolate the pairs' starts and ends: each set must
    // determine a linear polynomial
    for (side, points) in [
        ("starts (in A)", pairs.iter().map(|p| p.0).collect::<Vec<_>>()),
        ("ends (in B)", pairs.iter().map(|p| p.1).collect()),
    ] {
        let (centres, _) = normalised(&points);
        if let Err(e) = check_unisolvent(&Kernel::new(3, 2)?, &centres) {
            let m = match e {
                Error::Numerical(m) => m,
                e => e.to_string(),
            };
            return Err(Error::input(path, "", format!("the pairs' {side}: {m}")));
        }
    }
    Ok((pairs, lines))
}

/// Two pairs whose features travel through one point: i < j and the t in [0, 1] where the
/// straight paths q_i(t) = (1 - t) p_i + t p'_i and q_j(t) come closest, when that is closer than
/// 1e-9 of the pairs' extent (the displacement splines of that frame would be singular, and of
/// the frames near it fold space). The first such i, then j.
fn paths_meeting(pairs: &[Pair]) -> Option<(usize, usize, f64, f64)> {
    let all: Vec<f64> = pairs.iter().flat_map(|(p, r)| p.iter().chain(r).copied()).collect();
    let (lo, hi) = bounding_box(&all, 3);
    let extent = (0..3).map(|d| (hi[d] - lo[d]).powi(2)).sum::<f64>().sqrt();
    let tol = 1e-9 * extent;
    for i in 0..pairs.len() {
        for j in i + 1..pairs.len() {
            // q_i(t) - q_j(t) = a + t b
            let a: [f64; 3] = std::array::from_fn(|d| pairs[i].0[d] - pairs[j].0[d]);
            let b: [f64; 3] =
                std::array::from_fn(|d| (pairs[i].1[d] - pairs[i].0[d]) - (pairs[j].1[d] - pairs[j].0[d]));
            let bb: f64 = b.iter().map(|v| v * v).sum();
            let t =
                if bb > 0.0 { (-(0..3).map(|d| a[d] * b[d]).sum::<f64>() / bb).clamp(0.0, 1.0) } else { 0.0 };
            let gap = (0..3).map(|d| (a[d] + t * b[d]).powi(2)).sum::<f64>().sqrt();
            if gap <= tol {
                return Some((i, j, t, tol));
            }
        }
    }
    None
}

/// `points` in the normalised coordinates of their bounding box (3 values each), and that
/// normalisation.
fn normalised(points: &[[f64; 3]]) -> (Vec<f64>, Normalisation) {
    let flat: Vec<f64> = points.iter().flatten().copied().collect();
    let (lo, hi) = bounding_box(&flat, 3);
    let norm = Normalisation::of_box(&lo, &hi);
    let mut centres = vec![0.0; flat.len()];
    for (c, p) in centres.chunks_exact_mut(3).zip(flat.chunks_exact(3)) {
        norm.apply(p, c);
    }
    (centres, norm)
}

/// x -> x + D(x), D a volume spline (kernel r, linear polynomial) per component.
#[derive(Debug, Clone)]
pub struct SpaceMap {
    d: [Spline; 3],
}

impl SpaceMap {
    /// The map with D(from_i) = to_i - from_i.
    pub fn through(from: &[[f64; 3]], to: &[[f64; 3]]) -> Result<SpaceMap> {
        let kernel = Kernel::new(3, 2)?;
        let (centres, norm) = normalised(from);
        let why = "the pair points of a space mapping must be distinct and not all on one plane";
        let because = |e: Error| {
            Error::Numerical(match e {
                Error::Numerical(m) => format!("{why}: {m}"),
                e => format!("{why}: {e}"),
            })
        };
        check_unisolvent(&kernel, &centres).map_err(because)?;
        let (m, _) = full_system(&kernel, &centres, &vec![0.0; from.len()]);
        let n = m.len().isqrt();
        let mat = MatRef::from_column_major_slice(&m, n, n);
        let lu = BlockedLu::factor(mat).map_err(because)?;
        let solve = |d: usize| -> Result<Spline> {
            let mut b = vec![0.0; n];
            for (v, (a, t)) in b.iter_mut().zip(from.iter().zip(to)) {
                *v = t[d] - a[d];
            }
            let x = lu.solve(&b);
            if !(relative_residual(mat, &x, &b) < 1e-8) {
                return Err(Error::Numerical(format!("{why} (the displacement system is singular)")));
            }
            Ok(Spline::from_solution(kernel, centres.clone(), &x, norm))
        };
        Ok(SpaceMap { d: [solve(0)?, solve(1)?, solve(2)?] })
    }

    pub fn apply(&self, x: [f64; 3]) -> [f64; 3] {
        [0, 1, 2].map(|k| x[k] + self.d[k].eval(&x))
    }

    /// The Jacobian of x -> x + D(x) at `x`, row k the gradient of component k. With
    /// D_k(x) = sum_i mu_ki G(|x' - q_i|) + c_k0 + c_k . x' in the normalised x' = (x - centre) / s
    /// and G(r) = G(1) r, dD_k/dx_j = (G(1) sum_i mu_ki (x'_j - q_ij) / |x' - q_i| + c_kj) / s (at a
    /// centre itself, where G is not differentiable, its term is left out). The three components
    /// share their centres and normalisation, so one pass over the centres gives all nine.
    pub fn jacobian(&self, x: [f64; 3]) -> [[f64; 3]; 3] {
        let sp = &self.d[0];
        let mut xn = [0.0; 3];
        sp.norm.apply(&x, &mut xn);
        let mut g = [[0.0; 3]; 3];
        let [w0, w1, w2] = [0, 1, 2].map(|k| &self.d[k].weights);
        for (i, q) in sp.centres.chunks_exact(3).enumerate() {
            let d = [xn[0] - q[0], xn[1] - q[1], xn[2] - q[2]];
            let r = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
            if r > 0.0 {
                let u = [d[0] / r, d[1] / r, d[2] / r];
                for (gk, w) in g.iter_mut().zip([w0[i], w1[i], w2[i]]) {
                    for j in 0..3 {
                        gk[j] += w * u[j];
                    }
                }
            }
        }
        let g1 = sp.kernel.eval_r2(1.0);
        std::array::from_fn(|k| {
            let sp = &self.d[k];
            // the polynomial is linear: its differences along the axes are its gradient
            let terms = sp.poly.len();
            let poly = |x: &[f64; 3]| {
                let mut pv = [0.0; 10];
                sp.kernel.poly_eval(x, &mut pv[..terms]);
                pv[..terms].iter().zip(&sp.poly).map(|(a, b)| a * b).sum::<f64>()
            };
            let p0 = poly(&xn);
            std::array::from_fn(|j| {
                let mut e = xn;
                e[j] += 1.0;
                let own = if j == k { 1.0 } else { 0.0 };
                own + (g1 * g[k][j] + poly(&e) - p0) / sp.norm.scale
            })
        })
    }
}

/// Where a space map folds space: the points sampled at which the determinant of its Jacobian is
/// not positive. There the map turns space inside out, so the frame shows the solid's features
/// there mirrored, or twice.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Fold {
    pub folded: usize,
    pub sampled: usize,
    /// The sampled point with the smallest determinant, and that determinant.
    pub worst: [f64; 3],
    pub det: f64,
}

/// What a folding check found over one rank's share of the samples: how many folded of how
/// many, and the first sample (by index over all samples) with the smallest determinant.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FoldTally {
    pub folded: usize,
    pub sampled: usize,
    pub det: f64,
    pub index: usize,
    pub worst: [f64; 3],
}

impl FoldTally {
    /// Values a tally travels as between ranks ([`FoldTally::to_values`]).
    pub const VALUES: usize = 7;

    /// The tally as [`FoldTally::VALUES`] numbers (counts and index exact below 2^53).
    pub fn to_values(&self) -> [f64; Self::VALUES] {
        let [x, y, z] = self.worst;
        [self.folded as f64, self.sampled as f64, self.det, self.index as f64, x, y, z]
    }

    /// The tally from the numbers of [`FoldTally::to_values`] (a rank with no samples sends the
    /// index `usize::MAX`, which the saturating conversion reads back as such).
    pub fn from_values(v: &[f64]) -> Self {
        let at = |i: usize| if v[i].is_finite() { v[i] as usize } else { usize::MAX };
        FoldTally { folded: at(0), sampled: at(1), det: v[2], index: at(3), worst: [v[4], v[5], v[6]] }
    }

    /// The ranks' tallies as one fold: counts summed, the smallest determinant (the lowest index
    /// among equal ones); `None` where nothing folded.
    pub fn combine(parts: &[FoldTally]) -> Option<Fold> {
        let folded: usize = parts.iter().map(|p| p.folded).sum();
        let sampled = parts.iter().map(|p| p.sampled).sum();
        let worst = parts
            .iter()
            .filter(|p| p.sampled > 0)
            .min_by(|a, b| a.det.total_cmp(&b.det).then(a.index.cmp(&b.index)))?;
        (folded > 0).then_some(Fold { folded, sampled, worst: worst.worst, det: worst.det })
    }
}

/// Samples of a folding check along the way between a pair and each of its nearest neighbours
/// (where two features moving apart or across each other fold space first).
const FOLD_NEIGHBOURS: usize = 3;
const FOLD_STEPS: usize = 4;

/// The values of A and B on the slabs a rank evaluates, kept from frame to frame (without point
/// pairs they do not depend on t, so every frame after the first costs no model evaluation).
#[derive(Default)]
pub struct SlabCache {
    slabs: Mutex<Vec<Slab>>,
}

/// A and B (each once computed) on layers k0..k0+layers of a grid.
struct Slab {
    grid: Grid,
    k0: usize,
    layers: usize,
    values: [Option<Arc<Vec<f64>>>; 2],
}

impl SlabCache {
    /// The values of `e` (A for `which` 0, B for 1) on the layers, computed on first use.
    fn get(&self, which: usize, e: &Expr, grid: &Grid, k0: usize, layers: usize) -> Arc<Vec<f64>> {
        let known = |s: &Slab| s.grid == *grid && s.k0 == k0 && s.layers == layers;
        if let Some(v) = self.lock().iter().find(|s| known(s)).and_then(|s| s.values[which].clone()) {
            return v;
        }
        // evaluated outside the lock: the evaluation itself runs on the thread pool
        let v = Arc::new(e.layers(grid, k0, layers));
        let mut slabs = self.lock();
        match slabs.iter_mut().find(|s| known(s)) {
            Some(s) => s.values[which] = Some(v.clone()),
            None => {
                let mut values = [None, None];
                values[which] = Some(v.clone());
                slabs.push(Slab { grid: *grid, k0, layers, values });
            }
        }
        v
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, Vec<Slab>> {
        self.slabs.lock().unwrap_or_else(|e| e.into_inner())
    }
}

/// Frame t of the metamorphosis of A into B (see the module doc).
pub struct Morph<'a> {
    a: &'a Expr,
    b: &'a Expr,
    t: f64,
    maps: Option<(SpaceMap, SpaceMap)>,
    /// The pairs' positions q_i(t) at this frame.
    q: Vec<[f64; 3]>,
    cache: Option<&'a SlabCache>,
}

impl<'a> Morph<'a> {
    /// Frame `t` in [0, 1], controlled by `pairs` when given.
    pub fn new(a: &'a Expr, b: &'a Expr, t: f64, pairs: Option<&[Pair]>) -> Result<Self> {
        let pairs = pairs.unwrap_or(&[]);
        let q: Vec<[f64; 3]> =
            pairs.iter().map(|(p, r)| [0, 1, 2].map(|d| (1.0 - t) * p[d] + t * r[d])).collect();
        let maps = if pairs.is_empty() {
            None
        } else {
            let pa: Vec<[f64; 3]> = pairs.iter().map(|x| x.0).collect();
            let pb: Vec<[f64; 3]> = pairs.iter().map(|x| x.1).collect();
            let (ma, mb) = rayon::join(|| SpaceMap::through(&q, &pa), || SpaceMap::through(&q, &pb));
            Some((ma?, mb?))
        };
        Ok(Morph { a, b, t, maps, q, cache: None })
    }

    /// Where the maps of this frame fold space inside the box (lo, hi): A's map first, then B's,
    /// each `None` where it does not fold at any point sampled (both without pairs, and at t = 0
    /// and t = 1, whose frames are the solids as they are). The samples are a lattice of
    /// `per_side` points a side spanning the box and the points a quarter, half and three quarters
    /// of the way from each pair's position to those of its three nearest pairs, in the box.
    pub fn folds(&self, lo: [f64; 3], hi: [f64; 3], per_side: usize) -> [Option<Fold>; 2] {
        match self.fold_tallies(lo, hi, per_side, (0, 1)) {
            Some([a, b]) => [FoldTally::combine(&[a]), FoldTally::combine(&[b])],
            None => [None, None],
        }
    }

    /// [`Morph::folds`] over one rank's share of the samples (sample i on rank i mod `ranks`),
    /// A's map first: the tallies of all ranks, [`FoldTally::combine`]d, give the same folds as
    /// the whole sampling. `None` where nothing is checked (no pairs, t = 0 or 1).
    pub fn fold_tallies(
        &self,
        lo: [f64; 3],
        hi: [f64; 3],
        per_side: usize,
        (rank, ranks): (usize, usize),
    ) -> Option<[FoldTally; 2]> {
        let (ma, mb) = self.maps.as_ref().filter(|_| self.t > 0.0 && self.t < 1.0)?;
        let samples = self.fold_samples(lo, hi, per_side);
        let tally = |m: &SpaceMap| {
            let dets: Vec<(usize, f64)> = (rank..samples.len())
                .into_par_iter()
                .step_by(ranks.max(1))
                .map(|i| (i, glam::DMat3::from_cols_array_2d(&m.jacobian(samples[i])).determinant()))
                .collect();
            let folded = dets.iter().filter(|(_, d)| !(*d > 0.0)).count();
            // the first of the smallest, as the whole sampling finds it
            let (index, det) =
                dets.iter().fold((usize::MAX, f64::INFINITY), |b, &(i, d)| if d < b.1 { (i, d) } else { b });
            let worst = samples.get(index).copied().unwrap_or([f64::NAN; 3]);
            FoldTally { folded, sampled: dets.len(), det, index, worst }
        };
        Some([tally(ma), tally(mb)])
    }

    fn fold_samples(&self, lo: [f64; 3], hi: [f64; 3], per_side: usize) -> Vec<[f64; 3]> {
        let per_side = per_side.max(2);
        let at = |i: usize, d: usize| lo[d] + (hi[d] - lo[d]) * i as f64 / (per_side - 1) as f64;
        let mut samples: Vec<[f64; 3]> = (0..per_side.pow(3))
            .map(|i| {
                [at(i % per_side, 0), at((i / per_side) % per_side, 1), at(i / (per_side * per_side), 2)]
            })
            .collect();
        let inside = |x: &[f64; 3]| (0..3).all(|d| x[d] >= lo[d] && x[d] <= hi[d]);
        let q = &self.q;
        let near: Vec<Vec<usize>> = (0..q.len())
            .into_par_iter()
            .map(|i| {
                let mut near: Vec<(f64, usize)> =
                    (0..q.len()).filter(|&j| j != i).map(|j| (dist2(&q[i], &q[j]), j)).collect();
                let k = FOLD_NEIGHBOURS.min(near.len());
                if k > 0 && k < near.len() {
                    near.select_nth_unstable_by(k - 1, |a, b| a.0.total_cmp(&b.0));
                }
                near[..k].iter().map(|&(_, j)| j).collect()
            })
            .collect();
        let near = &near;
        // a couple that are each other's neighbours is sampled once
        let between: Vec<[f64; 3]> = (0..q.len())
            .flat_map(|i| {
                near[i].iter().filter(move |&&j| i < j || !near[j].contains(&i)).map(move |&j| (i, j))
            })
            .flat_map(|(i, j)| {
                (1..FOLD_STEPS).map(move |s| {
                    let s = s as f64 / FOLD_STEPS as f64;
                    [0, 1, 2].map(|d| q[i][d] + s * (q[j][d] - q[i][d]))
                })
            })
            .filter(inside)
            .collect();
        samples.extend(between);
        samples
    }

    /// The two pairs (indices into the pairs given) whose positions at this frame lie nearest `x`.
    pub fn nearest_pairs(&self, x: [f64; 3]) -> Vec<usize> {
        let mut order: Vec<usize> = (0..self.q.len()).collect();
        order.sort_by(|&a, &b| dist2(&self.q[a], &x).total_cmp(&dist2(&self.q[b], &x)));
        order.truncate(2);
        order
    }

    /// Takes the values of A and B on the grid from `cache` (filled by the first frame that needs
    /// them), for frames evaluated one after another on the same grid.
    pub fn with_cache(mut self, cache: &'a SlabCache) -> Self {
        self.cache = Some(cache);
        self
    }

    /// A (`which` 0) or B (1) on the layers, through the cache when there is one.
    fn solid(&self, which: usize, grid: &Grid, k0: usize, layers: usize) -> Arc<Vec<f64>> {
        let e = if which == 0 { self.a } else { self.b };
        match self.cache {
            Some(c) => c.get(which, e, grid, k0, layers),
            None => Arc::new(e.layers(grid, k0, layers)),
        }
    }

    /// u_t (1 - t) a / u_A + u_t t b / u_B for the values a of A and b of B; exactly a at t = 0 and
    /// b at t = 1.
    fn mix(&self, a: f64, b: f64) -> f64 {
        let t = self.t;
        if t == 0.0 {
            return a;
        }
        if t == 1.0 {
            return b;
        }
        let (ua, ub) = (self.a.unit(), self.b.unit());
        ((1.0 - t) * ua + t * ub) * ((1.0 - t) * a / ua + t * b / ub)
    }
}

impl Implicit for Morph<'_> {
    fn value(&self, p: [f64; 3]) -> f64 {
        match &self.maps {
            None => self.mix(self.a.value(p), self.b.value(p)),
            Some((ma, mb)) => {
                let a = if self.t == 1.0 { 0.0 } else { self.a.value(ma.apply(p)) };
                let b = if self.t == 0.0 { 0.0 } else { self.b.value(mb.apply(p)) };
                self.mix(a, b)
            }
        }
    }

    fn bounds(&self) -> ([f64; 3], [f64; 3]) {
        let (a, b) = (Implicit::bounds(self.a), Implicit::bounds(self.b));
        super::expr::hull(a, b)
    }
}

impl Field for Morph<'_> {
    /// Without pairs A and B on the grid itself (the models' blocked evaluators, once for all
    /// frames with a [`SlabCache`]); with pairs point by point through the maps. At t = 0 and t = 1
    /// only the solid shown is evaluated.
    fn eval_layers(&self, grid: &Grid, k0: usize, layers: usize) -> Vec<f64> {
        if self.t == 0.0 {
            return self.solid(0, grid, k0, layers).to_vec();
        }
        if self.t == 1.0 {
            return self.solid(1, grid, k0, layers).to_vec();
        }
        match &self.maps {
            None => {
                let (a, b) = (self.solid(0, grid, k0, layers), self.solid(1, grid, k0, layers));
                let mut out = a.to_vec();
                out.par_iter_mut().zip(b.as_slice()).for_each(|(x, y)| *x = self.mix(*x, *y));
                out
            }
            Some(_) => pointwise(self, grid, k0, layers),
        }
    }

    fn kernel_evals_per_node(&self) -> usize {
        self.a.kernel_evals() + self.b.kernel_evals()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_space_map_takes_each_pair_point_to_its_partner_and_is_affine_for_affine_pairs() {
        let from = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [0.3, 0.4, 0.5]];
        let bend = |p: [f64; 3]| [p[0] + 0.2 * p[1] * p[1], p[1] - 0.1 * p[2], p[2] + 0.3 * p[0] * p[2]];
        let to: Vec<[f64; 3]> = from.iter().map(|&p| bend(p)).collect();
        let m = SpaceMap::through(&from, &to).unwrap();
        for (p, q) in from.iter().zip(&to) {
            let r = m.apply(*p);
            for d in 0..3 {
                assert!((r[d] - q[d]).abs() < 1e-12, "{p:?} -> {r:?}, want {q:?}");
            }
        }
        // an affine motion of the pairs is reproduced everywhere (the linear part takes it exactly)
        let affine = |p: [f64; 3]| [2.0 * p[0] + 0.5 * p[2] + 1.0, p[1] - p[0], 3.0 * p[2] - 2.0];
        let to: Vec<[f64; 3]> = from.iter().map(|&p| affine(p)).collect();
        let m = SpaceMap::through(&from, &to).unwrap();
        let x = [2.5, -1.0, 4.0];
        let (r, want) = (m.apply(x), affine(x));
        for d in 0..3 {
            assert!((r[d] - want[d]).abs() < 1e-9, "{r:?} != {want:?}");
        }
        // four points on one plane do not determine the linear part
        let flat = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 1.0, 0.0]];
        assert!(SpaceMap::through(&flat, &flat).is_err());
    }

    #[test]
    fn a_space_map_s_jacobian_is_its_derivative() {
        let from = [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, 1.0],
            [0.3, 0.4, 0.5],
            [0.9, 0.8, 0.1],
        ];
        let bend = |p: [f64; 3]| [p[0] + 0.2 * p[1] * p[1], p[1] - 0.1 * p[2], p[2] + 0.3 * p[0] * p[2]];
        let to: Vec<[f64; 3]> = from.iter().map(|&p| bend(p)).collect();
        let m = SpaceMap::through(&from, &to).unwrap();
        let h = 1e-6;
        for x in [[0.2, 0.7, -0.3], [1.5, 0.1, 0.4], [0.31, 0.42, 0.53]] {
            let j = m.jacobian(x);
            for c in 0..3 {
                let (mut a, mut b) = (x, x);
                a[c] += h;
                b[c] -= h;
                let (fa, fb) = (m.apply(a), m.apply(b));
                for k in 0..3 {
                    let fd = (fa[k] - fb[k]) / (2.0 * h);
                    assert!((j[k][c] - fd).abs() < 1e-6, "d{k}/d{c} at {x:?}: {} against {fd}", j[k][c]);
                }
            }
        }
    }

    #[test]
    fn maps_that_fold_space_are_found_and_smooth_ones_are_not() {
        let ball = Expr::from_text("ball:0,0,0,1").unwrap();
        let corners =
            [[-2.0, -2.0, -2.0], [2.0, -2.0, -2.0], [-2.0, 2.0, -2.0], [-2.0, -2.0, 2.0], [2.0, 2.0, 2.0]];
        let shift = |p: [f64; 3]| (p, [p[0] + 0.5, p[1], p[2]]);
        let mut pairs: Vec<Pair> = corners.iter().map(|&p| shift(p)).collect();
        // two features 0.5 apart moving past each other, 0.05 apart half-way
        pairs.push(([-0.25, 0.0, 0.0], [0.75, 0.0, 0.05]));
        pairs.push(([0.25, 0.0, 0.0], [-0.75, 0.0, -0.05]));
        let (lo, hi) = ([-2.0; 3], [2.0; 3]);
        let half = Morph::new(&ball, &ball, 0.5, Some(&pairs)).unwrap();
        let [fa, fb] = half.folds(lo, hi, 12);
        let fa = fa.expect("A's map folds");
        println!("{fa:?}");
        assert!(fa.det <= 0.0 && fa.folded > 0 && fa.folded < fa.sampled, "{fa:?}");
        // B's map only stretches the way between them: the features keep their order towards B
        assert_eq!(fb, None);
        // dealt over 1 to 4 ranks and sent as values, the tallies combine to the same folds
        for ranks in 1..=4 {
            let parts: Vec<[FoldTally; 2]> = (0..ranks)
                .map(|r| half.fold_tallies(lo, hi, 12, (r, ranks)).unwrap())
                .map(|t| t.map(|p| FoldTally::from_values(&p.to_values())))
                .collect();
            let whole = [0, 1].map(|m| FoldTally::combine(&parts.iter().map(|p| p[m]).collect::<Vec<_>>()));
            assert_eq!(whole, [Some(fa), None], "{ranks} ranks");
            assert!(parts.iter().all(|p| p[0].sampled >= fa.sampled / ranks), "{ranks} ranks: dealt evenly");
        }
        // the fold lies between the two crossing features
        let near = half.nearest_pairs(fa.worst);
        assert!(near.contains(&5) || near.contains(&6), "{fa:?} near {near:?}");
        // the shift alone folds nothing, at any frame, and the end frames look through the identity
        let plain: Vec<Pair> = corners.iter().chain(&[[0.3, 0.1, -0.2]]).map(|&p| shift(p)).collect();
        for t in [0.0, 0.25, 0.5, 1.0] {
            assert_eq!(Morph::new(&ball, &ball, t, Some(&plain)).unwrap().folds(lo, hi, 12), [None, None]);
        }
        for t in [0.0, 1.0] {
            assert_eq!(Morph::new(&ball, &ball, t, Some(&pairs)).unwrap().folds(lo, hi, 12), [None, None]);
        }
        assert_eq!(Morph::new(&ball, &ball, 0.5, None).unwrap().folds(lo, hi, 12), [None, None]);
    }

    #[test]
    fn pairs_files_whose_starts_or_ends_lie_on_one_plane_are_refused_by_name() {
        let path = std::env::temp_dir().join(format!("volspline-pairs-{}.txt", std::process::id()));
        // four starts on the plane z = 0 (ends in space), then four ends on the plane y = 2
        let flat_starts = "0 0 0 0 0 1\n1 0 0 1 0 0\n0 1 0 0 1 0\n1 1 0 2 2 2\n";
        let flat_ends = "0 0 0 0 2 0\n1 0 0 1 2 0\n0 1 0 0 2 1\n1 1 1 1 2 1\n";
        for (text, side) in [(flat_starts, "starts (in A)"), (flat_ends, "ends (in B)")] {
            std::fs::write(&path, text).unwrap();
            let e = read_pairs(&path).unwrap_err().to_string();
            assert!(
                e.starts_with(&format!(
                    "{}: the pairs' {side}: the 4 points all lie on one plane",
                    path.display()
                )),
                "{e}"
            );
        }
        std::fs::write(&path, "0 0 0 0 0 1\n1 0 0 1 0 0\n0 1 0 0 1 0\n1 1 1 2 2 2\n").unwrap();
        assert_eq!(read_pairs(&path).unwrap().len(), 4);
        std::fs::remove_file(&path).unwrap();
    }

    #[test]
    fn pairs_whose_paths_meet_are_found_with_the_time() {
        let still = |p: [f64; 3]| (p, p);
        let base = [still([0.0, 0.0, 1.0]), still([3.0, 3.0, 3.0]), still([0.0, 3.0, 0.0])];
        let with = |a: Pair, b: Pair| [&base[..], &[a, b]].concat();
        // the same start, the same end, crossing at a quarter of the way, passing at a distance
        let cases = [
            (with(([1.0, 1.0, 0.0], [2.0, 2.0, 0.0]), ([1.0, 1.0, 0.0], [0.0, 2.0, 0.0])), Some((3, 4, 0.0))),
            (with(([1.0, 1.0, 0.0], [2.0, 2.0, 0.0]), ([0.0, 0.0, 2.0], [2.0, 2.0, 0.0])), Some((3, 4, 1.0))),
            (
                with(([0.0, 0.0, 0.0], [4.0, 0.0, 0.0]), ([1.0, 1.0, 0.0], [1.0, -3.0, 0.0])),
                Some((3, 4, 0.25)),
            ),
            (with(([0.0, 0.0, 0.0], [4.0, 0.0, 0.0]), ([1.0, 1.0, 0.1], [1.0, -3.0, 0.1])), None),
        ];
        for (pairs, want) in cases {
            assert_eq!(paths_meeting(&pairs).map(|(i, j, t, _)| (i, j, t)), want, "{pairs:?}");
        }
    }
}
