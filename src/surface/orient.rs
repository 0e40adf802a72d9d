//! Consistent orientation of unoriented normals: a spectral solution on the nearest-neighbour
//! graph, a correction of whole patches by the dipole field, and the outward sign.
//!
//! # Spectral orientation
//!
//! On the graph joining each point to its 15 nearest neighbours, an edge (i, j) with d the unit
//! vector from p_i to p_j asks for a relative sign by the dipole rule
//!
//! ```text
//! v_ij = n_i . n_j - 3 (n_i . d)(n_j . d),      sigma_ij = sign(v_ij),
//! w_ij = |v_ij| exp(-(|p_i - p_j| / 2h)^2),      h the median edge length.
//! ```
//!
//! Two normals of one smooth sheet (n . d ~ 0) want the same sign; two points facing each other
//! across a thin gap (n_i ~ n_j ~ d) give v = -2 and want opposite signs, as the outward normals
//! of the two sides of a thin plate are. The signs s (s_i = +-1) minimise
//! sum_edges w_ij (s_i - sigma_ij s_j)^2 = s^T L s with the signed graph Laplacian
//! L_ii = sum_j w_ij, L_ij = -sigma_ij w_ij. Relaxed to real x with |x| = 1 the minimiser is the
//! eigenvector of L's smallest eigenvalue (L is positive semidefinite; its smallest eigenvalue is
//! 0 exactly when the wanted signs are consistent around every cycle); s = sign(x). It is found
//! by inverse iteration, x <- (L + mu I)^-1 x with the sparse Cholesky factor of L + mu I
//! (mu = 1e-6 times the mean degree, so L + mu I is positive definite and the wanted eigenvector
//! is amplified by about (lambda_2 + mu) / (lambda_1 + mu) per step). Every connected component
//! of the graph has its own null vector, so x is normalised per component.
//!
//! # Dipole correction
//!
//! The nearest-neighbour graph cannot tell which way two distant pieces of the surface face each
//! other. The field of a dipole sheet can: with A_i the squared local spacing (an area) and o_i
//! the oriented normals,
//!
//! ```text
//! E(s) = sum_{i != j} s_i s_j W_ij,    W_ij = A_i A_j (3 (o_i . d)(o_j . d) - o_i . o_j) / r_ij^3,
//! ```
//!
//! is the interaction energy of the dipoles A_i s_i o_i up to sign and is least for a consistently
//! oriented closed surface (for neighbours on one sheet W_ij = -A_i A_j / r^3 < 0). Points are
//! grouped into patches (edges whose ends are mutually tangent, |o . d| < 0.35 at both, with
//! o_i . o_j > 0.9) and whole patches are flipped greedily while E decreases: with
//! B_PQ = sum_{i in P, j in Q} W_ij, flipping P changes E by -4 t_P sum_{Q != P} B_PQ t_Q (t the
//! patch signs), and the patch of the largest decrease is flipped until none decreases. B is
//! summed from the dense W without storing it: each rank takes every size-th row of W (the
//! row-cyclic split of the dense solvers) and the patch sums are added over ranks. Only small
//! patches move, those of at most [`DIPOLE_PATCH_SHARE`] of the points, the [`MAX_PATCHES`]
//! largest of them; the rest are one fixed group that still acts on them. A large patch is a
//! sheet the graph's many edges have already oriented, while the energy above is only a model
//! of the true one (sparse dipoles, areas from spacings): on 400 samples of the bunny it
//! flipped the 44 points of the flat base (11 % of the points) into the body, which lowered
//! the agreement with the true normals from 0.94 (the spectral signs) to 0.84 and let the blob
//! search hollow the body out (mesh -> truth 2.7 % of the diagonal, against 1.3 % with the base
//! left alone). On the other 119 sets of the surface benchmark's six samplings the limit
//! changes no fit: the patches flipped there (on a few sets looked at) have 1-10 points.
//! Above [`DENSE_DIPOLE_LIMIT`] points (the compactly supported method's sizes) the correction is
//! skipped: its N^2 / P pair evaluations per rank would outweigh the sparse solve, and an
//! approximation by one dipole per patch (area-weighted centroid, moment sum_P A_i o_i) lowered
//! the agreement with the true normals on 2526 bunny vertices from 0.996 to 0.975 (its near
//! field between adjacent patches is poor). On
//! closed scans the dense correction changes little (bunny 0.9968 -> 0.9964, cow 0.9576 ->
//! 0.9556); it is kept for what the spectral step cannot see, two pieces that face each other
//! without a neighbour edge between them.
//!
//! # Side vote
//!
//! Where a part of the solid is thinner than a neighbourhood (legs, ears, horns of a sparsely
//! sampled scan), a point's 15 neighbours hold points of the opposite side. Those lie well off
//! the point's tangent plane (|o . d| > [`SIDE_OFF_PLANE`], more than 30 degrees) and on its
//! inner side, so an outward normal points away from them: o . d < 0. Both steps above can leave
//! a small patch of such a part turned inward as a whole (the graph's edges across the gap are
//! few and weak against those along the sheet, and the dipole field of a small patch is weak).
//! The side vote counts, for each patch of the dipole step's kind (recomputed on the normals as
//! they now are), its points' off-plane neighbours in other patches on the outer side against
//! those on the inner side, and turns the patch when the outer ones are at least three times as
//! many. Convex curvature puts neighbours on the inner side too, which agrees; concave curvature
//! (a crease, the inside of a bend) puts them on the outer side, so only patches of at most
//! [`SIDE_PATCH_SHARE`] of the points are turned: the large smooth sheets are left to the steps
//! above. One pass; a second turned a few more patches and changed no reconstruction measured.
//! The fit applies the vote in the orientation only when asked (`--orient-side on`); by default
//! it tries the vote's turns after the first fit and keeps them where the spline's surface
//! leaves fewer unsupported crossings with them ([`side_vote`] on the oriented normals; see
//! [`crate::surface::turns`], "The side vote as one try").
//!
//! Measured (agreement with the true normals of area-uniform samples, jobs/bench/orient_energy.rs):
//! cow 1000 / 2000 / 4000 points 0.920 / 0.9225 / 0.960 without the vote, 0.945 / 0.951 / 0.9755
//! with it; bunny 1000 / 2000 0.983 / 0.994 without, 0.979 / 0.991 with (a few single points in
//! creases turned wrongly). On the mesh vertices of the test below it is slightly lower with the
//! vote: bunny 0.9964 -> 0.9949, cow 0.9556 -> 0.9545. What counts is the reconstruction; the
//! README's surface section has the benchmark.
//!
//! # Outward sign
//!
//! For a closed surface S with outward normal n and any point c, the divergence theorem gives
//! integral_S n . (x - c) dA = 3 vol > 0. The discrete sum sum_i A_i o_i . (p_i - c) (c the
//! centroid of the points) is therefore made positive, per connected component after the
//! spectral step and for the whole set after the dipole step (which only decides relative signs).

use faer::Par;

use super::normals::dist2;
use crate::error::{Error, Result};
use crate::graph::components;
use crate::linalg::sparse::{SparseCholesky, SpdSolve, SymCsr};
use crate::par::{agree, Comm};

/// Neighbours per point in the orientation graph.
pub const GRAPH_NEIGHBOURS: usize = 15;
/// Largest point count for which the dense dipole correction runs.
pub const DENSE_DIPOLE_LIMIT: usize = 40_000;
/// Largest number of patches the dipole correction moves.
pub const MAX_PATCHES: usize = 1500;
/// Largest patch, as a share of the points, that the dipole correction may flip.
pub const DIPOLE_PATCH_SHARE: f64 = 0.05;
/// |o . d| above which a neighbour counts as off the tangent plane in the side vote (30 degrees).
pub const SIDE_OFF_PLANE: f64 = 0.5;
/// Largest patch, as a share of the points, the side vote may turn.
pub const SIDE_PATCH_SHARE: f64 = 0.02;

/// What the orientation did.
#[derive(Debug, Clone, PartialEq)]
pub struct Orientation {
    /// Unit normals, consistently oriented and pointing outward.
    pub normals: Vec<[f64; 3]>,
    /// Connected components of the neighbour graph.
    pub components: usize,
    /// Patches of the dipole correction, how many moved and how many were flipped.
    pub patches: usize,
    pub movable: usize,
    pub flipped: usize,
    /// Whether the dense dipole correction ran (false above [`DENSE_DIPOLE_LIMIT`] points).
    pub dense_dipole: bool,
    /// Patches turned by the side vote (None: not run).
    pub side_turned: Option<usize>,
}

pub(super) fn dot(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn unit_between(points: &[f64], i: usize, j: usize) -> ([f64; 3], f64) {
    let d = [
        points[3 * j] - points[3 * i],
        points[3 * j + 1] - points[3 * i + 1],
        points[3 * j + 2] - points[3 * i + 2],
    ];
    let r = dot(&d, &d).sqrt();
    if r > 0.0 {
        ([d[0] / r, d[1] / r, d[2] / r], r)
    } else {
        ([0.0; 3], 0.0)
    }
}

/// The undirected edges (i < j) of the graph of the first `k` of each point's `kmax` neighbours.
fn graph_edges(knn: &[usize], kmax: usize, k: usize) -> Vec<(usize, usize)> {
    let mut e: Vec<(usize, usize)> = knn
        .chunks_exact(kmax.max(1))
        .enumerate()
        .flat_map(|(i, row)| row[..k.min(kmax)].iter().map(move |&j| (i.min(j), i.max(j))))
        .filter(|(a, b)| a != b)
        .collect();
    e.sort_unstable();
    e.dedup();
    e
}

/// Signs s_i (+-1) from the eigenvector of the smallest eigenvalue of the signed Laplacian (see
/// the module doc), normalised per component `label`.
fn spectral_signs(
    points: &[f64],
    normals: &[[f64; 3]],
    edges: &[(usize, usize)],
    label: &[usize],
    count: usize,
) -> Result<Vec<f64>> {
    let n = normals.len();
    let mut lengths: Vec<f64> =
        edges.iter().map(|&(i, j)| dist2(&points[3 * i..], &points[3 * j..]).sqrt()).collect();
    let h = if lengths.is_empty() {
        1.0
    } else {
        let mid = lengths.len() / 2;
        *lengths.select_nth_unstable_by(mid, f64::total_cmp).1
    };
    let mut rows: Vec<Vec<(usize, f64)>> = vec![Vec::new(); n];
    let mut diag = vec![0.0; n];
    for &(i, j) in edges {
        let (d, r) = unit_between(points, i, j);
        let v = dot(&normals[i], &normals[j]) - 3.0 * dot(&normals[i], &d) * dot(&normals[j], &d);
        let w = v.abs() * (-(r / (2.0 * h)).powi(2)).exp();
        diag[i] += w;
        diag[j] += w;
        rows[j].push((i, -v.signum() * w));
    }
    let mean = diag.iter().sum::<f64>() / n.max(1) as f64;
    let mu = 1e-6 * if mean > 0.0 { mean } else { 1.0 };
    let mut a = SymCsr { n, rows: (0..n).collect(), row_ptr: vec![0], ..Default::default() };
    for (i, row) in rows.iter_mut().enumerate() {
        row.sort_by_key(|e| e.0);
        for &(j, v) in row.iter() {
            a.cols.push(j);
            a.vals.push(v);
        }
        a.cols.push(i);
        a.vals.push(diag[i] + mu);
        a.row_ptr.push(a.cols.len());
    }
    let chol = SparseCholesky::factor(&a, Par::Seq)?;
    // a deterministic start with no special relation to the graph
    let mut x: Vec<f64> = (0..n).map(|i| 1.0 + 0.5 * ((i as f64) * 0.618_033_988_75).fract()).collect();
    let mut last: Vec<bool> = Vec::new();
    let mut stable = 0;
    for _ in 0..60 {
        chol.solve_in_place(&mut x, 1)?;
        let mut norms = vec![0.0; count];
        for i in 0..n {
            norms[label[i]] += x[i] * x[i];
        }
        if norms.iter().any(|v| !v.is_finite()) {
            return Err(Error::Numerical(
                "orientation: inverse iteration of the signed Laplacian diverged".into(),
            ));
        }
        for i in 0..n {
            let s = norms[label[i]].sqrt();
            x[i] = if s > 0.0 { x[i] / s } else { 1.0 };
        }
        let signs: Vec<bool> = x.iter().map(|&v| v >= 0.0).collect();
        stable = if signs == last { stable + 1 } else { 0 };
        last = signs;
        if stable >= 3 {
            break;
        }
    }
    Ok(x.iter().map(|&v| if v >= 0.0 { 1.0 } else { -1.0 }).collect())
}

/// sum_i A_i o_i . (p_i - c) over the points of `members`.
fn flux(
    points: &[f64],
    o: &[[f64; 3]],
    area: &[f64],
    c: &[f64; 3],
    members: impl Iterator<Item = usize>,
) -> f64 {
    members
        .map(|i| {
            area[i] * dot(&o[i], &[points[3 * i] - c[0], points[3 * i + 1] - c[1], points[3 * i + 2] - c[2]])
        })
        .sum()
}

/// The dipole interaction A_i A_j (3 (o_i.d)(o_j.d) - o_i.o_j) / r^3 of two oriented points, one
/// pair at a time ([`dipole_row`] computes a point's row of them alike).
#[cfg(test)]
fn dipole(pi: &[f64], pj: &[f64], oi: &[f64; 3], oj: &[f64; 3], ai: f64, aj: f64) -> f64 {
    let d = [pj[0] - pi[0], pj[1] - pi[1], pj[2] - pi[2]];
    let r2 = dot(&d, &d);
    if !(r2 > 0.0) {
        return 0.0;
    }
    let r = r2.sqrt();
    ai * aj * (3.0 * dot(oi, &d) * dot(oj, &d) / r2 - dot(oi, oj)) / (r2 * r)
}

/// The patch sums B ((m + 1) x (m + 1), row-major; index m is the fixed group) of the dense dipole
/// field, each rank summing its row-cyclic rows. Collective.
///
/// A row's interactions are computed for all its partners at once by [`dipole_row`] (vectorised,
/// each with the bits of the pair computed alone) and then added to their patches' sums in the
/// order of the partners, so the sums are those of one pair at a time.
fn dense_patch_sums(
    comm: &dyn Comm,
    points: &[f64],
    o: &[[f64; 3]],
    area: &[f64],
    patch: &[usize],
    m: usize,
) -> Vec<f64> {
    use rayon::prelude::*;
    let n = o.len();
    let width = m + 1;
    let field = Field::new(points, o, area);
    let mine: Vec<usize> = (comm.rank()..n).step_by(comm.size()).collect();
    let mut b = vec![0.0; width * width];
    for block in mine.chunks(256) {
        let rows: Vec<Vec<f64>> = block
            .par_iter()
            .map_init(
                || vec![0.0; n],
                |v, &i| {
                    dipole_row(&field, i, v);
                    let mut row = vec![0.0; width];
                    for (j, (&p, &x)) in patch.iter().zip(v.iter()).enumerate() {
                        if j != i {
                            row[p] += x;
                        }
                    }
                    row
                },
            )
            .collect();
        for (&i, row) in block.iter().zip(rows) {
            let at = patch[i] * width;
            for (slot, v) in b[at..at + width].iter_mut().zip(row) {
                *slot += v;
            }
        }
    }
    comm.sum_f64(&mut b);
    b
}

/// Oriented points with their areas, coordinate by coordinate, for [`dipole_row`].
struct Field {
    p: [Vec<f64>; 3],
    o: [Vec<f64>; 3],
    area: Vec<f64>,
}

impl Field {
    fn new(points: &[f64], o: &[[f64; 3]], area: &[f64]) -> Field {
        Field {
            p: std::array::from_fn(|d| points.chunks_exact(3).map(|q| q[d]).collect()),
            o: std::array::from_fn(|d| o.iter().map(|v| v[d]).collect()),
            area: area.to_vec(),
        }
    }
}

crate::simd::on_widest_unit! {
    /// `v[j]` = A_i A_j (3 (o_i.d)(o_j.d) - o_i.o_j) / r^3, the dipole interaction of point i
    /// with every point j (d = p_j - p_i, r = |d|; 0 for j = i and for coincident points),
    /// compiled for the widest vector unit the CPU has.
    fn dipole_row[][](field: &Field, i: usize, v: &mut [f64]) = dipole_row_portable;
}

/// [`dipole_row`] on the crate's own target: one partner per lane, each with the operations of
/// the pair computed alone in their order (Rust fuses no multiply and add of its own accord), so
/// every lane rounds as the scalar expression does, on every vector unit.
#[inline(always)]
fn dipole_row_portable(field: &Field, i: usize, v: &mut [f64]) {
    let [px, py, pz] = &field.p;
    let [ox, oy, oz] = &field.o;
    let (xi, yi, zi) = (px[i], py[i], pz[i]);
    let (oix, oiy, oiz, ai) = (ox[i], oy[i], oz[i], field.area[i]);
    let n = v.len();
    let (px, py, pz, ox, oy, oz, a) =
        (&px[..n], &py[..n], &pz[..n], &ox[..n], &oy[..n], &oz[..n], &field.area[..n]);
    for j in 0..n {
        let (d0, d1, d2) = (px[j] - xi, py[j] - yi, pz[j] - zi);
        let r2 = d0 * d0 + d1 * d1 + d2 * d2;
        let r = r2.sqrt();
        let doi = oix * d0 + oiy * d1 + oiz * d2;
        let doj = ox[j] * d0 + oy[j] * d1 + oz[j] * d2;
        let oo = oix * ox[j] + oiy * oy[j] + oiz * oz[j];
        let x = ai * a[j] * (3.0 * doi * doj / r2 - oo) / (r2 * r);
        v[j] = if r2 > 0.0 { x } else { 0.0 };
    }
}

/// Flips patches greedily while sum t_P t_Q B_PQ decreases; returns the patch signs (the fixed
/// group m keeps +1).
pub(crate) fn greedy_flips(b: &[f64], m: usize) -> Vec<f64> {
    let width = m + 1;
    let mut t = vec![1.0; width];
    let mut g: Vec<f64> =
        (0..width).map(|p| (0..width).filter(|&q| q != p).map(|q| b[p * width + q]).sum()).collect();
    for _ in 0..4 * m.max(1) {
        // flipping P changes the energy by -4 t_P g_P: take the largest t_P g_P > 0
        let best =
            (0..m).map(|p| (t[p] * g[p], p)).fold((0.0, usize::MAX), |a, c| if c.0 > a.0 { c } else { a });
        if best.1 == usize::MAX {
            break;
        }
        let p = best.1;
        t[p] = -t[p];
        for q in (0..width).filter(|&q| q != p) {
            g[q] += 2.0 * t[p] * b[q * width + p];
        }
    }
    t
}

/// Patches of oriented normals `o`: the connected components of the `edges` whose ends are
/// mutually tangent (|o . d| < 0.35 at both) with nearly parallel normals (o_i . o_j > 0.9), as
/// labels 0..count numbered in the order of their smallest point.
pub(crate) fn tangent_patches(
    points: &[f64],
    o: &[[f64; 3]],
    edges: &[(usize, usize)],
) -> (Vec<usize>, usize) {
    let tangent = edges.iter().copied().filter(|&(i, j)| {
        let (d, _) = unit_between(points, i, j);
        dot(&o[i], &d).abs() < 0.35 && dot(&o[j], &d).abs() < 0.35 && dot(&o[i], &o[j]) > 0.9
    });
    components(o.len(), tangent)
}

/// The edges of the orientation graph ([`GRAPH_NEIGHBOURS`] of each point's `kmax` nearest
/// neighbours `knn`).
pub(crate) fn orientation_edges(knn: &[usize], kmax: usize) -> Vec<(usize, usize)> {
    graph_edges(knn, kmax, GRAPH_NEIGHBOURS)
}

/// Turns all of `o` around unless sum_i A_i o_i . (p_i - c) >= 0 (the outward sign of the
/// module doc, A_i the squared distance to the 8th of the `kmax` neighbours `knn`); true if it did.
pub(crate) fn make_outward(points: &[f64], o: &mut [[f64; 3]], knn: &[usize], kmax: usize) -> bool {
    let n = o.len();
    let area = areas(points, knn, kmax, n);
    let c = centroid(points, n);
    let inward = flux(points, o, &area, &c, 0..n) < 0.0;
    if inward {
        for v in o.iter_mut() {
            *v = [-v[0], -v[1], -v[2]];
        }
    }
    inward
}

/// The area of each point: the squared distance to its 8th neighbour.
pub(crate) fn areas(points: &[f64], knn: &[usize], kmax: usize, n: usize) -> Vec<f64> {
    let k8 = 8.min(kmax);
    (0..n)
        .map(|i| if k8 == 0 { 1.0 } else { dist2(&points[3 * i..], &points[3 * knn[i * kmax + k8 - 1]..]) })
        .collect()
}

/// The centroid of `n` points.
fn centroid(points: &[f64], n: usize) -> [f64; 3] {
    let mut c = [0.0; 3];
    for p in points.chunks_exact(3) {
        for d in 0..3 {
            c[d] += p[d] / n.max(1) as f64;
        }
    }
    c
}

/// Turns the small patches of the oriented normals `o` whose points see their off-plane
/// neighbours mostly on their outer side (the side vote of the module doc); returns how many
/// patches it turned.
pub(crate) fn turn_by_neighbour_side(
    points: &[f64],
    o: &mut [[f64; 3]],
    knn: &[usize],
    kmax: usize,
) -> usize {
    let n = o.len();
    let k = GRAPH_NEIGHBOURS.min(kmax);
    let edges = graph_edges(knn, kmax, GRAPH_NEIGHBOURS);
    let (patch, count) = tangent_patches(points, o, &edges);
    let mut size = vec![0usize; count];
    for &p in &patch {
        size[p] += 1;
    }
    // per patch: sum of the sides (+1 outer, -1 inner) and the number of off-plane neighbours
    let (mut vote, mut seen) = (vec![0i64; count], vec![0i64; count]);
    for i in 0..n {
        for &j in &knn[i * kmax..i * kmax + k] {
            if patch[j] == patch[i] {
                continue;
            }
            let (d, _) = unit_between(points, i, j);
            let a = dot(&o[i], &d);
            if a.abs() > SIDE_OFF_PLANE {
                vote[patch[i]] += if a > 0.0 { 1 } else { -1 };
                seen[patch[i]] += 1;
            }
        }
    }
    let small = (SIDE_PATCH_SHARE * n as f64).floor() as usize;
    // outer >= 3 inner: (outer - inner) >= (outer + inner) / 2
    let turn: Vec<bool> =
        (0..count).map(|p| size[p] <= small && seen[p] > 0 && 2 * vote[p] >= seen[p]).collect();
    for i in 0..n {
        if turn[patch[i]] {
            o[i] = o[i].map(|v| -v);
        }
    }
    turn.iter().filter(|&&t| t).count()
}

/// The side vote on normals `o` already oriented consistently and outward (by [`orient`]
/// without it): its small patches turned as the side vote of the module doc turns them, then all
/// normals turned back outward where the turns reversed the sign of the total flux, as
/// [`orient`] ends. Returns how many patches the vote turned.
pub fn side_vote(points: &[f64], o: &mut [[f64; 3]], knn: &[usize], kmax: usize) -> usize {
    let turned = turn_by_neighbour_side(points, o, knn, kmax);
    if turned > 0 {
        make_outward(points, o, knn, kmax);
    }
    turned
}

/// Orients `normals` (unit, arbitrary signs) of `points` (3 values per point) consistently and
/// outward, given each point's `kmax` nearest neighbours (`knn`, nearest first). Identical on
/// every rank; the dense dipole sums are split over the ranks. Collective.
pub fn orient(
    comm: &dyn Comm,
    points: &[f64],
    normals: &[[f64; 3]],
    knn: &[usize],
    kmax: usize,
    side_vote: bool,
) -> Result<Orientation> {
    orient_with(comm, points, normals, knn, kmax, DENSE_DIPOLE_LIMIT, side_vote)
}

/// [`orient`] with the dense dipole correction up to `dense_limit` points (none above).
fn orient_with(
    comm: &dyn Comm,
    points: &[f64],
    normals: &[[f64; 3]],
    knn: &[usize],
    kmax: usize,
    dense_limit: usize,
    side_vote: bool,
) -> Result<Orientation> {
    let n = normals.len();
    let edges = graph_edges(knn, kmax, GRAPH_NEIGHBOURS);
    let (label, count) = components(n, edges.iter().copied());
    let signs = agree(comm, spectral_signs(points, normals, &edges, &label, count))?;
    let mut o: Vec<[f64; 3]> =
        normals.iter().zip(&signs).map(|(v, s)| [v[0] * s, v[1] * s, v[2] * s]).collect();
    let area = areas(points, knn, kmax, n);
    let c = centroid(points, n);
    let mut per_component = vec![0.0; count];
    for i in 0..n {
        per_component[label[i]] += flux(points, &o, &area, &c, std::iter::once(i));
    }
    for i in 0..n {
        if per_component[label[i]] < 0.0 {
            o[i] = [-o[i][0], -o[i][1], -o[i][2]];
        }
    }
    let dense_dipole = n <= dense_limit;
    let (mut patches, mut m, mut flipped) = (0, 0, 0);
    if dense_dipole {
        let (raw, found) = tangent_patches(points, &o, &edges);
        let mut size = vec![0usize; found];
        for &p in &raw {
            size[p] += 1;
        }
        // the small patches move, the largest first; the others are the fixed group
        let small = (DIPOLE_PATCH_SHARE * n as f64).floor() as usize;
        let mut by_size: Vec<usize> = (0..found).filter(|&p| size[p] <= small).collect();
        by_size.sort_by(|&a, &b| size[b].cmp(&size[a]).then(a.cmp(&b)));
        (patches, m) = (found, by_size.len().min(MAX_PATCHES));
        let mut rank_of = vec![m; found];
        for (r, &p) in by_size.iter().take(m).enumerate() {
            rank_of[p] = r;
        }
        let patch: Vec<usize> = raw.iter().map(|&p| rank_of[p]).collect();
        let t = greedy_flips(&dense_patch_sums(comm, points, &o, &area, &patch, m), m);
        flipped = t[..m].iter().filter(|&&v| v < 0.0).count();
        for i in 0..n {
            let s = t[patch[i]];
            o[i] = [o[i][0] * s, o[i][1] * s, o[i][2] * s];
        }
    }
    let side_turned = side_vote.then(|| turn_by_neighbour_side(points, &mut o, knn, kmax));
    if flux(points, &o, &area, &c, 0..n) < 0.0 {
        for v in o.iter_mut() {
            *v = [-v[0], -v[1], -v[2]];
        }
    }
    Ok(Orientation { normals: o, components: count, patches, movable: m, flipped, dense_dipole, side_turned })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::points::read_points;
    use crate::par::Solo;
    use crate::surface::neighbourhoods;

    /// Every `stride`-th vertex of a mesh in the repository and its area-weighted vertex normal.
    fn mesh_samples(name: &str, stride: usize) -> (Vec<f64>, Vec<[f64; 3]>) {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data").join(name);
        let set = read_points(&path).unwrap();
        let mut vn = vec![[0.0; 3]; set.points.len()];
        for t in &set.triangles {
            let [a, b, c] = t.map(|i| set.points[i]);
            let (u, v) = ([b[0] - a[0], b[1] - a[1], b[2] - a[2]], [c[0] - a[0], c[1] - a[1], c[2] - a[2]]);
            let cross = [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]];
            for &i in t {
                for d in 0..3 {
                    vn[i][d] += cross[d];
                }
            }
        }
        let picked: Vec<usize> = (0..set.points.len()).step_by(stride).collect();
        let pts = picked.iter().flat_map(|&i| set.points[i]).collect();
        let normals = picked.iter().map(|&i| vn[i].map(|x| x / dot(&vn[i], &vn[i]).sqrt())).collect();
        (pts, normals)
    }

    /// The fraction of points whose oriented normal points to the same side as the true one, with
    /// the dense dipole field up to `dense_limit` points.
    fn agreement(name: &str, stride: usize, dense_limit: usize, side: bool) -> (usize, f64, Orientation) {
        let (pts, truth) = mesh_samples(name, stride);
        let hoods = neighbourhoods(&pts).unwrap();
        let o = orient_with(&Solo, &pts, &hoods.normals, &hoods.knn, hoods.kmax, dense_limit, side).unwrap();
        let agree = o.normals.iter().zip(&truth).filter(|(a, b)| dot(a, b) > 0.0).count();
        (truth.len(), agree as f64 / truth.len() as f64, o)
    }

    #[test]
    fn a_closed_scan_is_oriented_outward_consistently() {
        // 2526 of the bunny's 5051 vertices (the scan's base is open) and all 2904 of the cow's
        // (thin legs, ears and horns); measured 0.9964 and 0.9556
        for (name, stride, bound) in [("bunny10k.obj", 2, 0.99), ("cow.obj", 1, 0.93)] {
            let (n, fraction, o) = agreement(name, stride, DENSE_DIPOLE_LIMIT, false);
            println!(
                "{name}: {n} points, {fraction:.4} agree with the mesh's normals, {o:?}",
                o = (o.components, o.patches, o.flipped)
            );
            assert!(fraction > bound, "{name}: only {fraction} of {n} normals agree with the truth");
        }
    }

    #[test]
    fn above_the_dense_limit_the_spectral_orientation_stands_alone() {
        // the large-N path (no dipole correction) on the same 2526 bunny points: measured 0.9968
        let (n, fraction, o) = agreement("bunny10k.obj", 2, 0, false);
        assert_eq!((o.dense_dipole, o.patches, o.flipped), (false, 0, 0));
        assert!(fraction > 0.99, "only {fraction} of {n} normals agree with the truth");
    }

    #[test]
    fn a_row_of_dipole_interactions_has_the_bits_of_each_pair() {
        // 37 points (not a whole number of vector lanes), two of them coincident
        let (mut pts, normals) = mesh_samples("cow.obj", 79);
        pts.truncate(3 * 37);
        pts.copy_within(0..3, 3 * 20);
        let o: Vec<[f64; 3]> = normals[..37].to_vec();
        let area: Vec<f64> = (0..37).map(|i| 0.5 + 0.01 * i as f64).collect();
        let field = Field::new(&pts, &o, &area);
        let mut v = vec![f64::NAN; 37];
        for i in [0, 1, 20, 36] {
            dipole_row(&field, i, &mut v);
            for j in 0..37 {
                let want = dipole(&pts[3 * i..], &pts[3 * j..], &o[i], &o[j], area[i], area[j]);
                assert_eq!(v[j].to_bits(), want.to_bits(), "i={i} j={j}: {} against {want}", v[j]);
            }
            assert_eq!(v[i], 0.0);
        }
        // the coincident pair interacts with nothing
        dipole_row(&field, 0, &mut v);
        assert_eq!(v[20], 0.0);
    }

    #[test]
    fn greedy_flips_undo_a_flipped_patch() {
        // two sheets of one plane seen as two patches with opposite signs: the energy is lower
        // with both the same, so exactly one of them is flipped
        let b = [0.0, 5.0, 0.0, 5.0, 0.0, 0.0, 0.0, 0.0, 0.0];
        let t = greedy_flips(&b, 2);
        assert_eq!(t[0] * t[1], -1.0);
        let b = [0.0, -5.0, 0.0, -5.0, 0.0, 0.0, 0.0, 0.0, 0.0];
        assert_eq!(greedy_flips(&b, 2), vec![1.0, 1.0, 1.0]);
    }
}
