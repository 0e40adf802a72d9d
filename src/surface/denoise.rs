//! Noisy scans: every point moved onto a quadric fitted to its neighbours on the same sheet
//! (a moving-least-squares projection), before the off-surface fit (`fit --denoise on`).
//!
//! An interpolant passes through every noisy point, so its zero set carries the noise as bumps
//! of the noise's size between the points. Smoothing the spline (`--smooth`) trades that for a
//! pull towards the carrier, which shrinks a scanned solid faster than it removes the noise.
//! Here the points themselves are moved. For point p with oriented normal n:
//!
//! 1. its 19 nearest neighbours and itself, keeping those whose oriented normal is within 60
//!    degrees of n (n_j . n > 0.5): the same sheet, not the far side of a thin part whose points
//!    share the neighbourhood (the two sides of an ear would otherwise be averaged into one);
//! 2. a local frame: the mean of the kept normals as the height axis z, through the kept points'
//!    centroid c;
//! 3. the quadric height z = a + b x + c y + d x^2 + e x y + f y^2 fitted by least squares,
//!    weighted exp(-(|q - p| / h)^2) with h the distance to the 19th neighbour (the normal
//!    equations in coordinates scaled by h); its weighted rms misfit estimates the noise there;
//! 4. p moves to the quadric above its own (x, y).
//!
//! A quadric follows the surface's curvature, where a plane (tried) cuts convex parts short and
//! shrinks them. Every move is limited to twice the median misfit over all points, the estimate
//! of the noise, so a point whose neighbourhood the quadric does not describe (a crease, a
//! misoriented patch) moves no more than the noise. Fewer than 8 points on the sheet: the point
//! stays. All points move at once (each from the unmoved cloud); deterministic, so every rank
//! computes the same.

use glam::DVec3;
use rayon::prelude::*;

use crate::linalg::dense::lu_solve;
use crate::par::{self, Comm};

/// Neighbours besides the point itself that a quadric is fitted to.
pub const NEIGHBOURS: usize = 19;
/// Least cosine between two oriented normals on the same sheet.
pub const SAME_SHEET: f64 = 0.5;
/// Fewest points on the sheet (the point included) for a fit of the quadric's 6 coefficients.
pub const MIN_ON_SHEET: usize = 8;
/// The largest move in units of the noise estimate (the median misfit).
pub const MOVE_LIMIT: f64 = 2.0;

/// Neighbours of the smaller fit of [`scale_ratio`].
pub const SMALL: usize = 9;

/// Below this ratio of the quadrics' misfits over [`NEIGHBOURS`] and over [`SMALL`] neighbours
/// the misfit is taken for noise ([`scale_ratio`]).
pub const NOISE_RATIO: f64 = 1.38;

/// The projected points and what the projection did.
#[derive(Debug, Clone)]
pub struct Denoised {
    /// The moved points, 3 values per point, in the order given.
    pub points: Vec<f64>,
    /// Points moved (a fit was made).
    pub moved: usize,
    /// The noise estimate: the median rms misfit of the quadrics (the points' units).
    pub noise: f64,
    /// The longest move made.
    pub max_move: f64,
}

/// Projects `points` (3 values per point) with their oriented unit `normals` onto local quadrics;
/// `knn` holds `kmax` nearest other points per point, nearest first, `kmax` >= [`NEIGHBOURS`]
/// or every other point.
pub fn project(points: &[f64], normals: &[[f64; 3]], knn: &[usize], kmax: usize) -> Denoised {
    let n = points.len() / 3;
    let fits: Vec<Option<([f64; 3], f64)>> = (0..n)
        .into_par_iter()
        .map(|i| quadric_at(points, normals, &knn[i * kmax..(i + 1) * kmax], i))
        .collect();
    let mut misfits: Vec<f64> = fits.iter().flatten().map(|&(_, r)| r).collect();
    misfits.sort_by(f64::total_cmp);
    let noise = if misfits.is_empty() { 0.0 } else { misfits[misfits.len() / 2] };
    let limit = MOVE_LIMIT * noise;
    let mut out = points.to_vec();
    let (mut moved, mut max_move) = (0, 0.0f64);
    for (i, fit) in fits.iter().enumerate() {
        let Some((to, _)) = fit else { continue };
        let p = &points[3 * i..3 * i + 3];
        let d = [to[0] - p[0], to[1] - p[1], to[2] - p[2]];
        let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        let s = if len > limit { limit / len } else { 1.0 };
        for a in 0..3 {
            out[3 * i + a] = p[a] + s * d[a];
        }
        moved += 1;
        max_move = max_move.max(s * len);
    }
    Denoised { points: out, moved, noise, max_move }
}

/// Whether the quadrics' misfit is noise or curvature: the median misfit of unweighted quadrics
/// through each point's [`NEIGHBOURS`] nearest neighbours over that through its [`SMALL`]
/// nearest (each the rms residual over the residual's degrees of freedom, n - 6, so that the
/// few points of the small fit do not hide their noise). Noise of standard deviation sigma gives
/// sigma at both sizes, a ratio near 1; the misfit of a quadric to a smooth surface grows with
/// the cube of the neighbourhood's radius, about 1.4 times larger for twice the points, so
/// clean samples give 2-3 where they are dense and about 1.5-2 where they are sparse (the
/// neighbourhood then spans creases). `normals` need not be oriented (a neighbour is on the
/// sheet when |n_j . n_i| > 0.5). Returns the two medians and their ratio.
pub fn scale_ratio(points: &[f64], normals: &[[f64; 3]], knn: &[usize], kmax: usize) -> (f64, f64, f64) {
    let n = points.len() / 3;
    let misfits = |count: usize| -> Vec<f64> {
        (0..n).into_par_iter().filter_map(|i| misfit(points, normals, (knn, kmax), i, count)).collect()
    };
    let (small, large) = (median(misfits(SMALL)), median(misfits(NEIGHBOURS)));
    (small, large, large / small)
}

/// [`scale_ratio`] with the points dealt over the ranks of `comm` in contiguous blocks, each rank
/// fitting the quadrics of its own and all-gathering the misfits: the medians are those of one
/// process, bit for bit (a median does not depend on the order of its values). Collective.
pub fn scale_ratio_on(
    comm: &dyn Comm,
    points: &[f64],
    normals: &[[f64; 3]],
    knn: &[usize],
    kmax: usize,
) -> (f64, f64, f64) {
    let n = points.len() / 3;
    if comm.size() == 1 {
        return scale_ratio(points, normals, knn, kmax);
    }
    // per point: whether each neighbourhood gave a misfit (1 or 0), and the misfit
    let send: Vec<f64> = par::block(comm, n, comm.rank())
        .into_par_iter()
        .flat_map_iter(|i| {
            [SMALL, NEIGHBOURS].into_iter().flat_map(move |count| {
                match misfit(points, normals, (knn, kmax), i, count) {
                    Some(m) => [1.0, m],
                    None => [0.0, 0.0],
                }
            })
        })
        .collect();
    let all = par::all_gather_blocks(comm, n, 4, &send);
    let of =
        |at: usize| -> Vec<f64> { all.chunks_exact(4).filter(|c| c[at] == 1.0).map(|c| c[at + 1]).collect() };
    let (small, large) = (median(of(0)), median(of(2)));
    (small, large, large / small)
}

/// The misfit of the quadric through point `i` and its same-sheet neighbours among its `count`
/// nearest: the neighbourhood's radius times the root mean square residual per degree of freedom
/// (None where too few neighbours lie on the sheet for a quadric).
fn misfit(
    points: &[f64],
    normals: &[[f64; 3]],
    (knn, kmax): (&[usize], usize),
    i: usize,
    count: usize,
) -> Option<f64> {
    let near = &knn[i * kmax..i * kmax + count.min(kmax)];
    let p = pt(points, i);
    let sheet: Vec<usize> = std::iter::once(i)
        .chain(near.iter().copied().filter(|&j| dot(normals[j], normals[i]).abs() > SAME_SHEET))
        .collect();
    let h = near.last().map(|&j| DVec3::from(p).distance(pt(points, j).into()))?;
    let fit = fit_quadric(points, normals, &sheet, None, h)?;
    Some(h * (fit.rss / (sheet.len() - 6) as f64).sqrt())
}

/// The median of `values` (the upper one of an even count; NaN for none), in the order of
/// `f64::total_cmp`.
fn median(mut values: Vec<f64>) -> f64 {
    values.sort_by(f64::total_cmp);
    if values.is_empty() {
        f64::NAN
    } else {
        values[values.len() / 2]
    }
}

/// A quadric height over a frame: the frame's origin, axes and scale, its 6 coefficients, and
/// the weighted sum of squared residuals and of the weights (in units of the scale).
struct Quadric {
    c: [f64; 3],
    u: [f64; 3],
    v: [f64; 3],
    z: [f64; 3],
    h: f64,
    coef: [f64; 6],
    rss: f64,
    wsum: f64,
}

impl Quadric {
    fn local(&self, q: [f64; 3]) -> (f64, f64, f64) {
        let d = [q[0] - self.c[0], q[1] - self.c[1], q[2] - self.c[2]];
        (dot(d, self.u) / self.h, dot(d, self.v) / self.h, dot(d, self.z) / self.h)
    }
}

fn basis(x: f64, y: f64) -> [f64; 6] {
    [1.0, x, y, x * x, x * y, y * y]
}

/// The least-squares quadric height through the points `sheet` (at least [`MIN_ON_SHEET`]) over
/// the frame of their mean normal (normals of either sign are turned to the first's side) and
/// centroid, in coordinates scaled by `h`, weighted exp(-(|q - centre| / h)^2) around `centre`
/// where given, else unweighted. None where the fit is singular.
fn fit_quadric(
    points: &[f64],
    normals: &[[f64; 3]],
    sheet: &[usize],
    centre: Option<[f64; 3]>,
    h: f64,
) -> Option<Quadric> {
    if sheet.len() < MIN_ON_SHEET || !(h > 0.0) {
        return None;
    }
    let first = normals[sheet[0]];
    let mut z = [0.0; 3];
    let mut c = [0.0; 3];
    for &j in sheet {
        let q = pt(points, j);
        let s = if dot(normals[j], first) < 0.0 { -1.0 } else { 1.0 };
        for a in 0..3 {
            z[a] += s * normals[j][a];
            c[a] += q[a] / sheet.len() as f64;
        }
    }
    let z = unit(z)?;
    let helper = if z[0].abs() < 0.9 { [1.0, 0.0, 0.0] } else { [0.0, 1.0, 0.0] };
    let u = unit(cross(z, helper))?;
    let v = cross(z, u);
    let mut quad = Quadric { c, u, v, z, h, coef: [0.0; 6], rss: 0.0, wsum: 0.0 };
    let weight =
        |q: [f64; 3]| centre.map_or(1.0, |p| (-(DVec3::from(p).distance(q.into()) / h).powi(2)).exp());
    let (mut m, mut b) = ([[0.0; 6]; 6], [0.0; 6]);
    for &j in sheet {
        let q = pt(points, j);
        let w = weight(q);
        let (x, y, zz) = quad.local(q);
        let a = basis(x, y);
        for r in 0..6 {
            b[r] += w * a[r] * zz;
            for s in 0..6 {
                m[r][s] += w * a[r] * a[s];
            }
        }
    }
    // the serial LU with partial pivoting; a singular system: too few or degenerate points for
    // a quadric
    let coef = lu_solve(faer::Mat::from_fn(6, 6, |r, c| m[r][c]).as_ref(), &b).ok()?;
    quad.coef.copy_from_slice(&coef);
    for &j in sheet {
        let q = pt(points, j);
        let w = weight(q);
        let (x, y, zz) = quad.local(q);
        let r = zz - basis(x, y).iter().zip(&quad.coef).map(|(a, k)| a * k).sum::<f64>();
        quad.wsum += w;
        quad.rss += w * r * r;
    }
    Some(quad)
}

/// The projection of point i onto the quadric of its same-sheet neighbours (`near`, nearest
/// first) and the quadric's weighted rms misfit; None where too few neighbours share the sheet
/// or the fit is singular.
fn quadric_at(points: &[f64], normals: &[[f64; 3]], near: &[usize], i: usize) -> Option<([f64; 3], f64)> {
    let near = &near[..near.len().min(NEIGHBOURS)];
    let p = pt(points, i);
    let ni = normals[i];
    let h = near.last().map(|&j| DVec3::from(p).distance(pt(points, j).into()))?;
    let sheet: Vec<usize> = std::iter::once(i)
        .chain(near.iter().copied().filter(|&j| dot(normals[j], ni) > SAME_SHEET))
        .collect();
    let quad = fit_quadric(points, normals, &sheet, Some(p), h)?;
    let misfit = h * (quad.rss / quad.wsum).sqrt();
    let (x, y, _) = quad.local(p);
    let height: f64 = basis(x, y).iter().zip(&quad.coef).map(|(a, k)| a * k).sum();
    let to = [0, 1, 2].map(|a| quad.c[a] + h * (x * quad.u[a] + y * quad.v[a] + height * quad.z[a]));
    (to.iter().all(|t| t.is_finite()) && misfit.is_finite()).then_some((to, misfit))
}

fn pt(points: &[f64], i: usize) -> [f64; 3] {
    [points[3 * i], points[3 * i + 1], points[3 * i + 2]]
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}

fn unit(a: [f64; 3]) -> Option<[f64; 3]> {
    let l = dot(a, a).sqrt();
    (l > 0.0).then(|| a.map(|x| x / l))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::spline::octree::Octree;
    use crate::surface::normals::nearest;

    /// Points on a sphere of radius 1 (a spiral), pushed along the radius by `noise` times a
    /// deterministic sequence in [-1, 1].
    fn sphere(n: usize, noise: f64) -> (Vec<f64>, Vec<[f64; 3]>) {
        let mut pts = Vec::new();
        let mut nrm = Vec::new();
        for i in 0..n {
            let z = -1.0 + (2 * i + 1) as f64 / n as f64;
            let (r, t) = ((1.0 - z * z).sqrt(), i as f64 * 2.399963);
            let d = [r * t.cos(), r * t.sin(), z];
            let e = noise * (((i * 7919) % 1000) as f64 / 500.0 - 1.0);
            pts.extend(d.map(|x| x * (1.0 + e)));
            nrm.push(d);
        }
        (pts, nrm)
    }

    fn radial_rms(pts: &[f64]) -> f64 {
        let s: f64 = pts
            .chunks_exact(3)
            .map(|p| (dot([p[0], p[1], p[2]], [p[0], p[1], p[2]]).sqrt() - 1.0).powi(2))
            .sum();
        (s / (pts.len() / 3) as f64).sqrt()
    }

    /// On a noisy sphere the projection removes most of the noise without shrinking it (a
    /// quadric follows the curvature), and exact points on it hardly move.
    #[test]
    fn a_noisy_sphere_comes_closer_and_an_exact_one_stays() {
        let (pts, nrm) = sphere(2000, 0.02);
        let tree = Octree::new(&pts, 10);
        let knn = nearest(&tree, &pts, 20);
        let before = radial_rms(&pts);
        let d = project(&pts, &nrm, &knn, 20);
        let after = radial_rms(&d.points);
        assert_eq!(d.moved, 2000);
        assert!(after < 0.5 * before, "rms off the sphere {before} -> {after}");
        let mean_r: f64 =
            d.points.chunks_exact(3).map(|p| dot([p[0], p[1], p[2]], [p[0], p[1], p[2]]).sqrt()).sum::<f64>()
                / 2000.0;
        assert!((mean_r - 1.0).abs() < 2e-3, "mean radius {mean_r}");
        let (exact, nrm) = sphere(2000, 0.0);
        let d = project(&exact, &nrm, &knn_of(&exact), 20);
        assert!(d.max_move < 1e-3, "exact points moved by {}", d.max_move);
    }

    fn knn_of(pts: &[f64]) -> Vec<usize> {
        nearest(&Octree::new(pts, 10), pts, 20)
    }

    /// Two parallel sheets closer than the neighbourhood, normals facing away from each other:
    /// each point is fitted to its own sheet only, so the sheets stay apart; without the
    /// same-sheet rule they would be drawn together.
    #[test]
    fn the_two_sides_of_a_thin_part_stay_apart() {
        let mut pts = Vec::new();
        let mut nrm = Vec::new();
        for side in [-1.0f64, 1.0] {
            for i in 0..30 {
                for j in 0..30 {
                    let e = 0.002 * ((((i * 31 + j * 17) % 13) as f64) / 6.0 - 1.0);
                    pts.extend([i as f64 * 0.01, j as f64 * 0.01, side * (0.005 + e)]);
                    nrm.push([0.0, 0.0, side]);
                }
            }
        }
        let d = project(&pts, &nrm, &knn_of(&pts), 20);
        for (k, p) in d.points.chunks_exact(3).enumerate() {
            let side = if k < 900 { -1.0 } else { 1.0 };
            assert!(p[2] * side > 0.003, "point {k} crossed towards the other sheet: z = {}", p[2]);
        }
    }
}
