//! Test matrices from real data: Wendland C2 kernel matrices of bunny vertices, assembled by
//! brute force, with dense copies and orderings for the solver tests.

use std::path::Path;

use faer::Mat;

use super::SymCsr;
use crate::io::points::read_points;

/// Every `step`-th vertex of the test bunny, scaled into the unit box (its longest side becomes
/// [0, 1], the aspect ratio is kept).
pub(crate) fn bunny(step: usize) -> Vec<[f64; 3]> {
    let set = read_points(Path::new("tests/data/bunny10k.obj")).expect("the test bunny reads");
    let pts: Vec<[f64; 3]> = set.points.iter().step_by(step).copied().collect();
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for p in &pts {
        for d in 0..3 {
            lo[d] = lo[d].min(p[d]);
            hi[d] = hi[d].max(p[d]);
        }
    }
    let side = (0..3).map(|d| hi[d] - lo[d]).fold(0.0, f64::max);
    pts.iter().map(|p| [0, 1, 2].map(|d| (p[d] - lo[d]) / side)).collect()
}

/// Wendland's C2 function in 3D, (1 - r/s)_+^4 (4 r/s + 1): positive definite, support s.
pub(crate) fn wendland_c2(r: f64, support: f64) -> f64 {
    let t = r / support;
    if t >= 1.0 {
        0.0
    } else {
        (1.0 - t).powi(4) * (4.0 * t + 1.0)
    }
}

/// The lower triangle of the kernel matrix (phi(|x_i - x_j|)) by brute force.
pub(crate) fn kernel_matrix(pts: &[[f64; 3]], support: f64) -> SymCsr {
    let n = pts.len();
    let mut a = SymCsr { n, rows: (0..n).collect(), row_ptr: vec![0], ..Default::default() };
    for i in 0..n {
        for j in 0..=i {
            let r = (0..3).map(|d| (pts[i][d] - pts[j][d]).powi(2)).sum::<f64>().sqrt();
            let v = wendland_c2(r, support);
            if v != 0.0 {
                a.cols.push(j);
                a.vals.push(v);
            }
        }
        a.row_ptr.push(a.cols.len());
    }
    a
}

/// The full symmetric matrix of `a`.
pub(crate) fn dense(a: &SymCsr) -> Mat<f64> {
    let mut m = Mat::zeros(a.n, a.n);
    for i in 0..a.n {
        for (j, v) in a.row(i) {
            m[(i, j)] = v;
            m[(j, i)] = v;
        }
    }
    m
}

/// A pseudo-random permutation of 0..n (xorshift, Fisher-Yates), reproducible from `seed`.
pub(crate) fn shuffled(n: usize, seed: u64) -> Vec<usize> {
    let mut state = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
    let mut perm: Vec<usize> = (0..n).collect();
    for i in (1..n).rev() {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        perm.swap(i, (state % (i as u64 + 1)) as usize);
    }
    perm
}

/// The order of the points by increasing x (perm[new] = old).
pub(crate) fn sorted_by_x(pts: &[[f64; 3]]) -> Vec<usize> {
    let mut perm: Vec<usize> = (0..pts.len()).collect();
    perm.sort_by(|&a, &b| pts[a][0].total_cmp(&pts[b][0]));
    perm
}

/// ||x - y|| / ||y||.
pub(crate) fn rel_diff(x: &[f64], y: &[f64]) -> f64 {
    assert_eq!(x.len(), y.len());
    let d = x.iter().zip(y).map(|(a, b)| (a - b).powi(2)).sum::<f64>().sqrt();
    d / y.iter().map(|b| b * b).sum::<f64>().sqrt()
}

/// A smooth right-hand side of length n, no entry zero.
pub(crate) fn rhs(n: usize, shift: f64) -> Vec<f64> {
    (0..n).map(|i| 1.0 + (0.37 * i as f64 + shift).sin() * 0.5).collect()
}
