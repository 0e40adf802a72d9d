//! Data hygiene for scattered points before they become spline centres: bounding boxes, merging of
//! duplicate and near-duplicate points (two equal rows make the system singular) and the
//! unisolvency check of the polynomial part: the N x k matrix P of the basis polynomials at the
//! points must have full column rank, or the bordered system is singular (see "Unisolvency" in
//! [`crate::spline::system`]).

use std::collections::HashMap;

use faer::Mat;
use rayon::prelude::*;

use crate::error::{Error, Result};
use crate::linalg::dense::qr_r_diagonal;
use crate::spline::carrier::Carrier;
use crate::spline::kernel::Kernel;
use crate::spline::octree::{Octree, DEFAULT_LEAF_CAPACITY};
use crate::spline::system::Normalisation;

/// Axis-aligned bounding box of `dim`-dimensional points stored `dim` values per point.
pub fn bounding_box(points: &[f64], dim: usize) -> (Vec<f64>, Vec<f64>) {
    let mut lo = vec![f64::INFINITY; dim];
    let mut hi = vec![f64::NEG_INFINITY; dim];
    for p in points.chunks_exact(dim) {
        for d in 0..dim {
            lo[d] = lo[d].min(p[d]);
            hi[d] = hi[d].max(p[d]);
        }
    }
    (lo, hi)
}

/// Length of the diagonal of a box, computed without overflow or underflow of the squares (the
/// extents are divided by the longest before squaring): finite whenever the extents are.
pub fn diagonal(lo: &[f64], hi: &[f64]) -> f64 {
    let longest = lo.iter().zip(hi).map(|(a, b)| (b - a).abs()).fold(0.0, f64::max);
    if !(longest > 0.0) || !longest.is_finite() {
        return longest;
    }
    longest * lo.iter().zip(hi).map(|(a, b)| ((b - a) / longest).powi(2)).sum::<f64>().sqrt()
}

/// The neighbour whose distance decides whether a point is isolated ([`isolated_points`]).
pub const ISOLATION_NEIGHBOUR: usize = 8;

/// How many times the median distance to the [`ISOLATION_NEIGHBOUR`]-th nearest other point a
/// point's own must exceed for it to count as isolated.
pub const ISOLATION_FACTOR: f64 = 10.0;

/// The most points a group apart from the rest may hold for [`isolated_points`] to take it for
/// stray returns, as a share of all points (at least [`ISOLATION_NEIGHBOUR`]).
pub const STRAY_GROUP_SHARE: f64 = 0.01;

/// The points (indices, ascending) whose [`ISOLATION_NEIGHBOUR`]-th nearest other point lies
/// more than [`ISOLATION_FACTOR`] times the median of that distance away, and the points of
/// groups apart from the rest that hold at most [`STRAY_GROUP_SHARE`] of the points: stray
/// returns of a scanner, alone or in groups far from the surface (a reflection, something
/// passing through the beam). The median is taken over at most [`ISOLATION_SAMPLES`] points
/// evenly spaced in the input's order. Empty for fewer than 2 (k + 1) points, and where the
/// median distance is 0 (most points repeated k times).
///
/// Only few points need their distance: on a lattice of cubes whose diagonal is the threshold,
/// a point whose cube holds at least k others has them within the threshold. The others (points
/// of cubes the data only graze, and the strays) are measured through an octree.
///
/// A group of more than k strays passes that test (each has its k neighbours in the group), so
/// the occupied cubes of a lattice as wide as the threshold are also joined with their 26
/// neighbours into connected parts: two parts lie more than the threshold apart.
/// The points of every part but the largest that holds at most [`STRAY_GROUP_SHARE`] of the
/// points (or k) are strays too; separate objects of a scene with more points than that are
/// kept.
pub fn isolated_points(points: &[f64]) -> Vec<usize> {
    let k = ISOLATION_NEIGHBOUR;
    let n = points.len() / 3;
    if n < 2 * (k + 1) {
        return Vec::new();
    }
    let tree = Octree::new(points, DEFAULT_LEAF_CAPACITY);
    let (lo, _) = bounding_box(points, 3);
    let kth = |i: usize| tree.kth_distance([points[3 * i], points[3 * i + 1], points[3 * i + 2]], k + 1);
    let stride = n.div_ceil(ISOLATION_SAMPLES);
    let mut sampled: Vec<f64> = (0..n).into_par_iter().step_by(stride).map(kth).collect();
    let mid = sampled.len() / 2;
    let median = *sampled.select_nth_unstable_by(mid, f64::total_cmp).1;
    let threshold = ISOLATION_FACTOR * median;
    if !(median > 0.0) || !threshold.is_finite() {
        return Vec::new();
    }
    let side = threshold / 3f64.sqrt();
    let cells: Option<Vec<[i64; 3]>> = points
        .chunks_exact(3)
        .map(|p| {
            let c: [f64; 3] = std::array::from_fn(|d| ((p[d] - lo[d]) / side).floor());
            c.iter().all(|v| *v < 1e15).then(|| c.map(|v| v as i64))
        })
        .collect();
    let candidates: Vec<usize> = match &cells {
        Some(cells) => {
            let mut count: HashMap<[i64; 3], usize> = HashMap::new();
            cells.iter().for_each(|c| *count.entry(*c).or_default() += 1);
            (0..n).filter(|&i| count[&cells[i]] <= k).collect()
        }
        // a lattice too fine to number (a few points spread over 1e15 thresholds)
        None => (0..n).collect(),
    };
    let mut isolated: Vec<usize> = candidates.into_par_iter().filter(|&i| kth(i) > threshold).collect();
    // where the lattice can be numbered: cubes as wide as the threshold, so that points in cubes
    // that do not touch are farther apart
    if cells.is_some() {
        let wide: Vec<[i64; 3]> = points
            .chunks_exact(3)
            .map(|p| std::array::from_fn(|d| ((p[d] - lo[d]) / threshold).floor() as i64))
            .collect();
        let most = ((STRAY_GROUP_SHARE * n as f64) as usize).max(k);
        isolated.extend(small_parts(&wide, most));
        isolated.sort_unstable();
        isolated.dedup();
    }
    isolated
}

/// The points (indices) of the connected parts of the occupied `cells` (one per point, joined
/// with their 26 neighbours) that hold at most `most` points, all but the largest part.
fn small_parts(cells: &[[i64; 3]], most: usize) -> Vec<usize> {
    let mut index: HashMap<[i64; 3], usize> = HashMap::new();
    for c in cells {
        let next = index.len();
        index.entry(*c).or_insert(next);
    }
    let touching = index.iter().flat_map(|(c, &i)| {
        let index = &index;
        (0..27).filter_map(move |d| {
            let off = [d % 3, d / 3 % 3, d / 9].map(|v| v as i64 - 1);
            index.get(&[c[0] + off[0], c[1] + off[1], c[2] + off[2]]).map(|&j| (i, j))
        })
    });
    let (label, count) = crate::graph::components(index.len(), touching);
    let part: Vec<usize> = cells.iter().map(|c| label[index[c]]).collect();
    let mut size = vec![0usize; count];
    part.iter().for_each(|&p| size[p] += 1);
    let largest = size.iter().copied().max().unwrap_or(0);
    (0..cells.len()).filter(|&i| size[part[i]] <= most && size[part[i]] < largest).collect()
}

/// The most points whose distances set the median of [`isolated_points`].
pub const ISOLATION_SAMPLES: usize = 4096;

/// Removes every point closer than `tol` to an earlier kept point (the first of a cluster is
/// kept, so the result does not depend on anything but the input order). Returns the kept points
/// and how many were merged away.
pub fn merge_duplicates(points: &[f64], dim: usize, tol: f64) -> (Vec<f64>, usize) {
    let kept = merge_indices(points, dim, tol);
    let merged = points.len() / dim - kept.len();
    (kept.iter().flat_map(|&i| points[i * dim..(i + 1) * dim].iter().copied()).collect(), merged)
}

/// The indices of the points [`merge_duplicates`] keeps, in order.
pub fn merge_indices(points: &[f64], dim: usize, tol: f64) -> Vec<usize> {
    let n = points.len() / dim;
    let cell = if tol > 0.0 { tol } else { f64::MIN_POSITIVE };
    let key = |p: &[f64]| -> [i64; 3] {
        let mut k = [0i64; 3];
        for d in 0..dim {
            k[d] = (p[d] / cell).floor() as i64;
        }
        k
    };
    let mut grid: HashMap<[i64; 3], Vec<usize>> = HashMap::new();
    let mut kept: Vec<usize> = Vec::with_capacity(n);
    for i in 0..n {
        let p = &points[i * dim..(i + 1) * dim];
        let c = key(p);
        let mut dup = false;
        'search: for dx in -1..=1i64 {
            for dy in if dim > 1 { -1..=1i64 } else { 0..=0 } {
                for dz in if dim > 2 { -1..=1i64 } else { 0..=0 } {
                    if let Some(list) = grid.get(&[c[0] + dx, c[1] + dy, c[2] + dz]) {
                        for &q in list {
                            let kq = &points[q * dim..(q + 1) * dim];
                            let d2: f64 = kq.iter().zip(p).map(|(a, b)| (a - b) * (a - b)).sum();
                            if d2 <= tol * tol {
                                dup = true;
                                break 'search;
                            }
                        }
                    }
                }
            }
        }
        if !dup {
            grid.entry(c).or_default().push(i);
            kept.push(i);
        }
    }
    kept
}

/// `e` (a numerical failure of the points that remain) saying, when `merged` of the `total`
/// points were merged as duplicates (closer than `merge_tol` times the diagonal), that it
/// concerns the points left, and which option decides the merging.
pub fn after_merging(e: Error, merged: usize, total: usize, merge_tol: f64) -> Error {
    match e {
        Error::Numerical(m) if merged > 0 => Error::Numerical(format!(
            "{m} ({merged} of the {total} points were merged into others as closer than --merge-tol \
             {merge_tol:e} times the diagonal)"
        )),
        other => other,
    }
}

/// The kernels whose splines carry the polynomial part of `order` in `dim` dimensions, for the
/// messages: the unisolvency they need is the same.
fn kernels_of_order(dim: usize, order: usize) -> &'static str {
    match (dim, order) {
        (3, 2) => "r, wendland0, wendland2, wendland4",
        (3, _) => "r3",
        (2, 2) => "r2log",
        (2, _) => "r4log",
        _ => "of this order",
    }
}

/// Checks that the (normalised) points determine the polynomial part uniquely: the N x k matrix
/// of the basis polynomials must have full column rank. Says what is wrong when it has not.
pub fn check_unisolvent(kernel: &Kernel, points: &[f64]) -> Result<()> {
    let dim = kernel.dim();
    let n = points.len() / dim;
    let k = kernel.poly_count();
    if n < k {
        return Err(Error::Numerical(format!(
            "{n} distinct points are too few: a spline in {dim}D with a polynomial part of degree {} (kernels \
             {}) needs at least {k} points not on a common {}",
            kernel.order() - 1,
            kernels_of_order(dim, kernel.order()),
            degenerate_set(kernel, 0)
        )));
    }
    let mut vals = vec![0.0; k];
    let mut p = Mat::<f64>::zeros(n, k);
    for (i, x) in points.chunks_exact(dim).enumerate() {
        kernel.poly_eval(x, &mut vals);
        for (j, v) in vals.iter().enumerate() {
            p[(i, j)] = *v;
        }
    }
    let diag = qr_r_diagonal(p.as_ref());
    let biggest = diag.iter().fold(0.0f64, |a, b| a.max(*b));
    // a column of P lies in the span of the ones before it exactly when its diagonal of R
    // vanishes, so the vanishing diagonals count the rank P lacks, whatever columns they are
    let lacking = diag.iter().filter(|&&d| d <= 1e-10 * biggest).count();
    if lacking > 0 {
        return Err(Error::Numerical(format!(
            "the {n} points all lie on one {}, so the polynomial part of degree {} is not \
             determined (the points are not unisolvent): every spline with that polynomial part (kernels {}) \
             needs points that span {dim}D",
            degenerate_set(kernel, lacking),
            kernel.order() - 1,
            kernels_of_order(dim, kernel.order()),
        )));
    }
    Ok(())
}

/// The kind of set the points lie on when the polynomial block lacks `lacking` of its rank (0
/// for the generic set that too few points lie on). For the linear part (1, x, ...) the rank is
/// one more than the dimension of the points' affine span.
fn degenerate_set(kernel: &Kernel, lacking: usize) -> &'static str {
    let linear = kernel.order() == 2;
    match (kernel.dim().saturating_sub(lacking.max(1)), linear) {
        (2, true) => "plane",
        (1, true) => "line",
        (0, true) => "point",
        _ => match (kernel.dim(), kernel.order()) {
            (3, _) => "quadric surface",
            (2, _) => "conic",
            _ => "low-degree algebraic set",
        },
    }
}

/// The smallest diagonal of the data's box: the square of 1e-150 (1e-300) is still a normal
/// double, so the carrier's squared distances keep their precision.
pub const MIN_SPREAD: f64 = 1e-150;

/// Points made ready for the spline: duplicates merged, normalised, checked for unisolvency, and
/// the carrier resolved and evaluated at them.
#[derive(Debug, Clone)]
pub struct Prepared {
    /// Distinct points in the caller's coordinates, 3 values per point.
    pub points: Vec<f64>,
    /// The same points normalised (the spline's centres).
    pub centres: Vec<f64>,
    /// r_i = f_c(P_i).
    pub values: Vec<f64>,
    pub carrier: Carrier,
    pub norm: Normalisation,
    pub merged: usize,
    pub box_lo: Vec<f64>,
    pub box_hi: Vec<f64>,
}

impl Prepared {
    /// The same data with every point moved to `centres` (normalised, one per point, in order):
    /// the points in the caller's coordinates and the carrier's values there follow.
    pub fn with_centres(&self, centres: Vec<f64>) -> Result<Prepared> {
        assert_eq!(centres.len(), self.centres.len(), "one new centre per point");
        let points: Vec<f64> = centres
            .chunks_exact(3)
            .flat_map(|c| (0..3).map(move |d| self.norm.centre[d] + self.norm.scale * c[d]))
            .collect();
        let values: Vec<f64> = points.chunks_exact(3).map(|p| self.carrier.eval(p)).collect();
        if values.iter().any(|v| !v.is_finite()) {
            return Err(Error::Numerical(format!(
                "the carrier '{}' is not finite at the moved points",
                self.carrier
            )));
        }
        Ok(Prepared { points, centres, values, ..self.clone() })
    }
}

/// Data hygiene, deterministic so that every rank gets the same result:
/// merge points closer than `merge_tol` times the bounding-box diagonal, normalise, check that the
/// polynomial part is determined, resolve the carrier and take its values at the points.
pub fn prepare(raw: &[f64], kernel: &Kernel, carrier: &Carrier, merge_tol: f64) -> Result<Prepared> {
    if let Some(deg) = carrier.polynomial_degree() {
        if deg < kernel.order() {
            return Err(Error::Usage(format!(
                "carrier '{carrier}' is a polynomial of degree {deg}, which kernel {} (polynomial part of \
                 degree {}) reproduces exactly: f = f_c - U would vanish everywhere. Use an R-function \
                 carrier such as union(ball:...,ball:...) or the kernel r",
                kernel.name(),
                kernel.order() - 1
            )));
        }
    }
    let (lo, hi) = bounding_box(raw, 3);
    let diag = diagonal(&lo, &hi);
    if !diag.is_finite() {
        let big = lo.iter().chain(&hi).fold(0.0f64, |a, b| a.max(b.abs()));
        return Err(Error::Numerical(format!(
            "the data's spread is not representable: the bounding box's extents overflow (coordinates \
             up to {big:e}); rescale the data"
        )));
    }
    if diag > 0.0 && diag < MIN_SPREAD {
        return Err(Error::Numerical(format!(
            "the data's spread is not representable: the bounding box's diagonal is {diag:e}, below \
             {MIN_SPREAD:e}, so squared distances underflow (the carrier would vanish everywhere); rescale \
             the data"
        )));
    }
    // merged in normalised coordinates (the box's half-diagonal is 1), where the squared distances
    // neither overflow nor underflow whatever the data's scale
    let norm = Normalisation::of_box(&lo, &hi);
    let mut all = vec![0.0; raw.len()];
    for (c, p) in all.chunks_exact_mut(3).zip(raw.chunks_exact(3)) {
        norm.apply(p, c);
    }
    let keep = merge_indices(&all, 3, 2.0 * merge_tol);
    let merged = raw.len() / 3 - keep.len();
    let pick =
        |v: &[f64]| -> Vec<f64> { keep.iter().flat_map(|&i| v[3 * i..3 * i + 3].iter().copied()).collect() };
    let (points, centres) = (pick(raw), pick(&all));
    check_unisolvent(kernel, &centres).map_err(|e| after_merging(e, merged, raw.len() / 3, merge_tol))?;
    let carrier = carrier.resolve(&lo, &hi, &points);
    let values = carrier_values(&carrier, &points, &lo, &hi)?;
    Ok(Prepared { points, centres, values, carrier, norm, merged, box_lo: lo, box_hi: hi })
}

/// The carrier's values at the points, refused where one is not finite.
fn carrier_values(carrier: &Carrier, points: &[f64], lo: &[f64], hi: &[f64]) -> Result<Vec<f64>> {
    let values: Vec<f64> = points.chunks_exact(3).map(|p| carrier.eval(p)).collect();
    if let Some(bad) = values.iter().find(|v| !v.is_finite()) {
        let big = lo.iter().chain(hi).fold(0.0f64, |a, b| a.max(b.abs()));
        return Err(Error::Numerical(format!(
            "the carrier '{carrier}' is not finite at the data (a value is {bad}): its squares overflow \
             for coordinates up to {big:e}; rescale the data or choose a carrier of smaller magnitude"
        )));
    }
    Ok(values)
}

impl Prepared {
    /// The same points with another carrier (resolved against them) and its values.
    pub fn with_carrier(self, carrier: &Carrier) -> Result<Prepared> {
        let carrier = carrier.resolve(&self.box_lo, &self.box_hi, &self.points);
        let values = carrier_values(&carrier, &self.points, &self.box_lo, &self.box_hi)?;
        Ok(Prepared { values, carrier, ..self })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn duplicates_and_near_duplicates_are_merged() {
        let pts = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0 + 1e-9, 0.0, 0.0, 0.0, 0.0, 0.0, 0.5, 0.5, 0.5];
        let (kept, merged) = merge_duplicates(&pts, 3, 1e-6);
        assert_eq!(merged, 2);
        assert_eq!(kept, vec![0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.5, 0.5, 0.5]);
        let (_, none) = merge_duplicates(&pts, 3, 0.0);
        assert_eq!(none, 1); // only the exact duplicate
    }

    #[test]
    fn merging_works_across_cell_boundaries() {
        // two points 1e-7 apart straddling a grid-cell boundary of size tol
        let tol = 1e-6;
        let pts = [tol * 10.0 - 5e-8, 0.0, 0.0, tol * 10.0 + 5e-8, 0.0, 0.0];
        assert_eq!(merge_duplicates(&pts, 3, tol).1, 1);
    }

    fn sphere(scale: f64) -> Vec<f64> {
        (0..200)
            .flat_map(|i| {
                let z = -1.0 + (2 * i + 1) as f64 / 200.0;
                let (r, t) = ((1.0 - z * z).sqrt(), i as f64 * 2.399963);
                [r * t.cos() * scale, r * t.sin() * scale, z * scale]
            })
            .collect()
    }

    #[test]
    fn extreme_scales_are_diagnosed() {
        let k = Kernel::new(3, 2).unwrap();
        // the diagonal of 2e154-wide data no longer overflows: the points stay distinct and the
        // failure is the carrier's overflow, said as such
        assert!(diagonal(&[-1e154; 3], &[1e154; 3]).is_finite());
        let e = prepare(&sphere(1e154), &k, &Carrier::AutoBall, 1e-6).unwrap_err().to_string();
        assert!(e.contains("is not finite at the data") && !e.contains("distinct"), "{e}");
        let e = prepare(&sphere(1e-200), &k, &Carrier::AutoBall, 1e-6).unwrap_err().to_string();
        assert!(e.contains("spread is not representable") && !e.contains("plane"), "{e}");
        let e = prepare(&[-1e308, 0.0, 0.0, 1e308, 1.0, 1.0], &k, &Carrier::AutoBall, 1e-6).unwrap_err();
        assert!(e.to_string().contains("extents overflow"), "{e}");
        // moderate scales are merged and checked in normalised coordinates alike
        for scale in [1e-100, 1.0, 1e100] {
            let p = prepare(&sphere(scale), &k, &Carrier::parse("ball:0,0,0,1", 3).unwrap(), 1e-6).unwrap();
            assert_eq!((p.merged, p.points.len()), (0, 600));
        }
    }

    #[test]
    fn coplanar_points_are_not_unisolvent() {
        let k = Kernel::new(3, 2).unwrap();
        let plane: Vec<f64> = (0..20).flat_map(|i| [i as f64 * 0.1, (i * i % 7) as f64 * 0.1, 0.3]).collect();
        let err = check_unisolvent(&k, &plane).unwrap_err();
        assert!(err.to_string().contains("plane"), "{err}");
        let mut solid = plane.clone();
        solid.extend_from_slice(&[0.0, 0.0, 1.0]);
        check_unisolvent(&k, &solid).unwrap();
        let line = Kernel::new(2, 2).unwrap();
        let collinear: Vec<f64> = (0..10).flat_map(|i| [i as f64, 2.0 * i as f64 + 1.0]).collect();
        assert!(check_unisolvent(&line, &collinear).unwrap_err().to_string().contains("line"));
        // in 3D, points on a line (whichever axes it follows) are named as on one line
        for dir in [[1.0, 2.0, 3.0], [0.0, 1.0, 0.0], [0.0, 0.0, 2.0]] {
            let on_line: Vec<f64> = (0..15).flat_map(|i| dir.map(|d| 0.2 + d * i as f64 * 0.05)).collect();
            let err = check_unisolvent(&k, &on_line).unwrap_err().to_string();
            assert!(err.contains("on one line") && !err.contains("plane"), "{dir:?}: {err}");
        }
        let mut twice = plane;
        twice.truncate(3);
        assert!(check_unisolvent(&k, &twice).unwrap_err().to_string().contains("plane"));
    }

    #[test]
    fn isolated_points_are_the_stray_ones() {
        // 200 points on a sphere of radius 1, then three strays alone and a group of four, all
        // well away from it
        let mut pts = sphere(1.0);
        pts.extend_from_slice(&[15.0, 0.0, 0.0, 0.0, -12.0, 0.0, 0.0, 0.0, 30.0]);
        for q in 0..4 {
            pts.extend_from_slice(&[-20.0 + 0.1 * q as f64, 20.0, 0.0]);
        }
        assert_eq!(isolated_points(&pts), (200..207).collect::<Vec<_>>());
        // the sphere alone, and too few points to say: none
        assert!(isolated_points(&sphere(1.0)).is_empty());
        assert!(isolated_points(&pts[..3 * 17]).is_empty());
        // a stray nearer than ten times the spacing of the 8th neighbour (about 0.4 here) is not
        // told from the data
        let mut near = sphere(1.0);
        near.extend_from_slice(&[4.0, 0.0, 0.0]);
        assert!(isolated_points(&near).is_empty());
        // against the definition, by all distances: a noisy shell of 3000 points (some cubes of
        // the lattice grazed) with strays at several distances
        let mut state = 7u64;
        let mut unit = || {
            state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut cloud = Vec::new();
        for i in 0..3000 {
            let z = -1.0 + (2 * i + 1) as f64 / 3000.0;
            let (r, t) = ((1.0 - z * z).sqrt() * (1.0 + 0.05 * unit()), i as f64 * 2.399963);
            cloud.extend_from_slice(&[r * t.cos(), r * t.sin(), z]);
        }
        for q in 0..12 {
            cloud.extend_from_slice(&[1.0 + 0.2 * q as f64, 0.3 * unit(), 0.0]);
        }
        let n = cloud.len() / 3;
        let kth: Vec<f64> = (0..n)
            .map(|i| {
                let mut d: Vec<f64> = (0..n)
                    .filter(|&j| j != i)
                    .map(|j| {
                        (0..3).map(|a| (cloud[3 * i + a] - cloud[3 * j + a]).powi(2)).sum::<f64>().sqrt()
                    })
                    .collect();
                d.sort_by(f64::total_cmp);
                d[ISOLATION_NEIGHBOUR - 1]
            })
            .collect();
        let mut sampled: Vec<f64> = kth.iter().step_by(n.div_ceil(ISOLATION_SAMPLES)).copied().collect();
        sampled.sort_by(f64::total_cmp);
        let threshold = ISOLATION_FACTOR * sampled[sampled.len() / 2];
        let want: Vec<usize> = (0..n).filter(|&i| kth[i] > threshold).collect();
        assert!(!want.is_empty() && want.len() < 12, "{want:?}");
        assert_eq!(isolated_points(&cloud), want);
        // a group of more points than the neighbour counted and than 1 % of all is a part of the
        // data (another object of the scene), not strays
        let mut group = sphere(1.0);
        for q in 0..ISOLATION_NEIGHBOUR + 1 {
            group.extend_from_slice(&[-20.0 + 0.1 * q as f64, 20.0, 0.0]);
        }
        assert!(isolated_points(&group).is_empty());
        // beside 3000 points, groups apart from them of up to 30 points (1 %) are strays, each
        // point with its 8 neighbours in the group, and larger ones are kept: a cloud of 20 far
        // away, a line of 25 beside the shell (0.05 apart, beyond twice the threshold of about
        // 0.9 from it), and a cloud of 31
        let ball = |at: [f64; 3], count: usize, unit: &mut dyn FnMut() -> f64| -> Vec<f64> {
            (0..3 * count).map(|q| at[q % 3] + 0.1 * (unit() - 0.5)).collect()
        };
        let mut scene = cloud[..3 * 3000].to_vec();
        scene.extend(ball([40.0, 0.0, 0.0], 20, &mut unit));
        scene.extend((0..25).flat_map(|q| [0.0, 0.0, 3.5 + 0.05 * q as f64]));
        scene.extend(ball([0.0, -30.0, 5.0], 31, &mut unit));
        assert_eq!(isolated_points(&scene), (3000..3045).collect::<Vec<_>>());
        // the same groups beside a tenth of the points: more than 1 % of them, kept
        let mut few: Vec<f64> = cloud[..3 * 3000].chunks_exact(3).step_by(3).flatten().copied().collect();
        few.extend_from_slice(&scene[3 * 3000..3 * 3020]);
        assert!(isolated_points(&few).is_empty());
    }

    #[test]
    fn too_few_points_after_merging_say_so() {
        // a triangle and a fourth point 3.5e-4 from a corner (of a diagonal about 1.7): merged
        // into it with a tolerance of 1e-3, which leaves three points
        let k = Kernel::new(3, 2).unwrap();
        let pts = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 2e-4, 2e-4, 2e-4];
        let e = prepare(&pts, &k, &Carrier::AutoBall, 1e-3).unwrap_err().to_string();
        assert!(e.contains("3 distinct points are too few"), "{e}");
        assert!(
            e.contains("(1 of the 4 points were merged into others as closer than --merge-tol 1e-3"),
            "{e}"
        );
        // a failure with nothing merged says nothing of merging
        let e = prepare(&pts[..9], &k, &Carrier::AutoBall, 1e-3).unwrap_err().to_string();
        assert!(e.contains("3 distinct points are too few") && !e.contains("merged"), "{e}");
    }
}
