//! Unoriented normals of scattered surface points by local principal component analysis.
//!
//! For a point p and a set of its neighbours q_1..q_k, the covariance
//!
//! ```text
//! C = 1/(k+1) sum_j (q_j - m)(q_j - m)^T,      m the mean of p, q_1..q_k,
//! ```
//!
//! has eigenvalues l_0 <= l_1 <= l_2. For points on a smooth surface sampled densely enough the
//! neighbourhood is nearly flat: l_0 is small and its eigenvector is the normal up to sign. The
//! planarity l_0 / (l_0 + l_1 + l_2) (0 for a plane, 1/3 for an isotropic cloud) measures how much
//! to trust it. No single k suits a scan whose spacing varies or whose surface folds: too few
//! neighbours and noise dominates, too many and the neighbourhood reaches across a curve or onto
//! a nearby sheet. So each point takes, among k = 8, 10, 15 and 20, the neighbourhood of least
//! planarity (the most planar one) and its normal.
//!
//! The k nearest neighbours come from the octree of [`crate::spline::octree`]: the k-th distance
//! gives the search radius, the search returns a superset, sorted by distance (ties by index, so
//! the result is deterministic).

use std::ops::Range;

use rayon::prelude::*;

use crate::spline::octree::Octree;

/// The neighbourhood sizes tried for each point.
pub const NEIGHBOURHOODS: [usize; 4] = [8, 10, 15, 20];

/// The `k` nearest other points of every point (stored `k` per point, nearest first), for points
/// stored 3 values per point; fewer than `k + 1` points give every other point.
pub fn nearest(tree: &Octree, points: &[f64], k: usize) -> Vec<usize> {
    nearest_of(tree, points, k, 0..points.len() / 3)
}

/// [`nearest`] for the points `range` alone: their rows, in order.
pub fn nearest_of(tree: &Octree, points: &[f64], k: usize, range: Range<usize>) -> Vec<usize> {
    let n = points.len() / 3;
    let k = k.min(n.saturating_sub(1));
    let mut out = vec![0usize; range.len() * k];
    if k == 0 {
        return out;
    }
    out.par_chunks_mut(k).zip(range).for_each_init(Vec::new, |found, (row, i)| {
        let p = [points[3 * i], points[3 * i + 1], points[3 * i + 2]];
        // the k-th distance, squared again, may round below the point's own squared distance:
        // widen the search until it holds k other points
        let mut r = tree.kth_distance(p, k + 1) * (1.0 + 1e-9);
        loop {
            tree.within(p, r, found);
            if found.iter().filter(|&&j| j != i).count() >= k || !r.is_finite() {
                break;
            }
            r = if r > 0.0 { 2.0 * r } else { f64::MIN_POSITIVE };
        }
        let mut near: Vec<(f64, usize)> =
            found.iter().filter(|&&j| j != i).map(|&j| (dist2(&p, &points[3 * j..3 * j + 3]), j)).collect();
        near.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        for (slot, (_, j)) in row.iter_mut().zip(near) {
            *slot = j;
        }
    });
    out
}

pub(crate) fn dist2(a: &[f64], b: &[f64]) -> f64 {
    (a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)
}

/// Eigenvalues (ascending) and unit eigenvectors (columns `v[..][j]` for eigenvalue j) of a
/// symmetric 3 x 3 matrix by cyclic Jacobi rotations.
pub fn symmetric_eigen3(mut a: [[f64; 3]; 3]) -> ([f64; 3], [[f64; 3]; 3]) {
    let mut v = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    for _ in 0..50 {
        let off = a[0][1].powi(2) + a[0][2].powi(2) + a[1][2].powi(2);
        let scale = a[0][0].powi(2) + a[1][1].powi(2) + a[2][2].powi(2) + off;
        if off <= 1e-30 * scale || off == 0.0 {
            break;
        }
        for (p, q) in [(0, 1), (0, 2), (1, 2)] {
            if a[p][q] == 0.0 {
                continue;
            }
            let theta = (a[q][q] - a[p][p]) / (2.0 * a[p][q]);
            let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
            let t = if theta == 0.0 { 1.0 } else { t };
            let c = 1.0 / (t * t + 1.0).sqrt();
            let s = t * c;
            for r in 0..3 {
                let (arp, arq) = (a[r][p], a[r][q]);
                a[r][p] = c * arp - s * arq;
                a[r][q] = s * arp + c * arq;
            }
            for r in 0..3 {
                let (apr, aqr) = (a[p][r], a[q][r]);
                a[p][r] = c * apr - s * aqr;
                a[q][r] = s * apr + c * aqr;
            }
            for row in v.iter_mut() {
                let (vp, vq) = (row[p], row[q]);
                row[p] = c * vp - s * vq;
                row[q] = s * vp + c * vq;
            }
        }
    }
    let mut order = [0usize, 1, 2];
    order.sort_by(|&i, &j| a[i][i].total_cmp(&a[j][j]));
    let vals = [a[order[0]][order[0]], a[order[1]][order[1]], a[order[2]][order[2]]];
    let mut vecs = [[0.0; 3]; 3];
    for (col, &o) in order.iter().enumerate() {
        for r in 0..3 {
            vecs[r][col] = v[r][o];
        }
    }
    (vals, vecs)
}

/// The least-squares plane of a few points: their mean, and the eigenvalues (ascending) and unit
/// eigenvectors (columns) of their covariance, the first the plane's normal (sign arbitrary).
pub struct Plane {
    pub mean: [f64; 3],
    pub values: [f64; 3],
    pub vectors: [[f64; 3]; 3],
}

impl Plane {
    /// The plane of `points` (given twice over as a function of nothing, since both passes read
    /// them): the mean, then the covariance about it, each term divided by the count as it is
    /// added.
    pub fn of<I: Iterator<Item = [f64; 3]>>(points: impl Fn() -> I) -> Plane {
        let count = points().count() as f64;
        let mut mean = [0.0; 3];
        for p in points() {
            for d in 0..3 {
                mean[d] += p[d] / count;
            }
        }
        let mut c = [[0.0; 3]; 3];
        for p in points() {
            let x = [p[0] - mean[0], p[1] - mean[1], p[2] - mean[2]];
            for r in 0..3 {
                for s in 0..3 {
                    c[r][s] += x[r] * x[s] / count;
                }
            }
        }
        let (values, vectors) = symmetric_eigen3(c);
        Plane { mean, values, vectors }
    }

    /// The unit normal (sign arbitrary).
    pub fn normal(&self) -> [f64; 3] {
        [self.vectors[0][0], self.vectors[1][0], self.vectors[2][0]]
    }

    /// The distance of `x` from the plane.
    pub fn distance(&self, x: &[f64; 3]) -> f64 {
        (0..3).map(|d| self.vectors[d][0] * (x[d] - self.mean[d])).sum::<f64>().abs()
    }
}

/// The normal (unit, sign arbitrary) and planarity of point `i` with the neighbours `near`.
fn pca(points: &[f64], i: usize, near: &[usize]) -> ([f64; 3], f64) {
    let at = |j: usize| [points[3 * j], points[3 * j + 1], points[3 * j + 2]];
    let plane = Plane::of(|| std::iter::once(i).chain(near.iter().copied()).map(at));
    let sum = plane.values.iter().map(|v| v.max(0.0)).sum::<f64>();
    let planarity = if sum > 0.0 { plane.values[0].max(0.0) / sum } else { 1.0 };
    (plane.normal(), planarity)
}

/// Unoriented unit normals and their planarity for every point, given the
/// `NEIGHBOURHOODS`-largest nearest-neighbour lists (`knn`, `kmax` per point, nearest first):
/// each point takes the most planar of its neighbourhoods.
pub fn pca_normals(points: &[f64], knn: &[usize], kmax: usize) -> (Vec<[f64; 3]>, Vec<f64>) {
    pca_normals_of(points, knn, kmax, 0..points.len() / 3)
}

/// [`pca_normals`] of the points `range` alone, `knn` holding their rows only.
pub fn pca_normals_of(
    points: &[f64],
    knn: &[usize],
    kmax: usize,
    range: Range<usize>,
) -> (Vec<[f64; 3]>, Vec<f64>) {
    let first = range.start;
    range
        .into_par_iter()
        .map(|i| {
            let row = &knn[(i - first) * kmax..(i - first + 1) * kmax];
            let mut best = ([0.0, 0.0, 1.0], f64::INFINITY);
            for k in NEIGHBOURHOODS {
                let (normal, planarity) = pca(points, i, &row[..k.min(kmax)]);
                if planarity < best.1 {
                    best = (normal, planarity);
                }
            }
            best
        })
        .unzip()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn eigen_of_a_rotated_diagonal_matrix() {
        // R diag(1, 2, 5) R^T with R a rotation about (1, 1, 1)
        let (c, s) = (0.6f64, 0.8f64);
        let u = [1.0 / 3f64.sqrt(); 3];
        let mut r = [[0.0; 3]; 3];
        let k = [[0.0, -u[2], u[1]], [u[2], 0.0, -u[0]], [-u[1], u[0], 0.0]];
        for i in 0..3 {
            for j in 0..3 {
                r[i][j] = if i == j { c } else { 0.0 } + s * k[i][j] + (1.0 - c) * u[i] * u[j];
            }
        }
        let d = [1.0, 2.0, 5.0];
        let mut a = [[0.0; 3]; 3];
        for i in 0..3 {
            for j in 0..3 {
                a[i][j] = (0..3).map(|l| r[i][l] * d[l] * r[j][l]).sum();
            }
        }
        let (vals, vecs) = symmetric_eigen3(a);
        for l in 0..3 {
            assert!((vals[l] - d[l]).abs() < 1e-12, "{vals:?}");
            let dot: f64 = (0..3).map(|i| vecs[i][l] * r[i][l]).sum();
            assert!((dot.abs() - 1.0).abs() < 1e-12);
        }
    }

    #[test]
    fn normals_of_a_sphere_are_radial() {
        let n = 800;
        let pts: Vec<f64> = (0..n)
            .flat_map(|i| {
                let z = -1.0 + (2 * i + 1) as f64 / n as f64;
                let (r, t) = ((1.0 - z * z).sqrt(), i as f64 * 2.399963);
                [r * t.cos(), r * t.sin(), z]
            })
            .collect();
        let tree = Octree::new(&pts, 10);
        let knn = nearest(&tree, &pts, 20);
        let (normals, planarity) = pca_normals(&pts, &knn, 20);
        let worst = (0..n)
            .map(|i| (0..3).map(|d| normals[i][d] * pts[3 * i + d]).sum::<f64>().abs())
            .fold(1.0, f64::min);
        assert!(worst > 0.99, "worst |n . radial| = {worst}");
        assert!(planarity.iter().all(|&p| p < 0.05));
    }
}
