//! Spurious blobs: regions where a fit is positive (inside) although no data says so, found on a
//! coarse lattice and pinned negative by further constraint points for a second fit.
//!
//! # Why they appear
//!
//! The solid is f = f_c - U: the carrier f_c (a ball around the data by default) is positive in
//! a large region, and the spline U cancels it only where constraints hold it, at the data and
//! at the off-surface points a distance delta beside it. In empty space inside the carrier, away
//! from both, nothing asks U to cancel f_c, and f stays positive there: closed blobs in the gaps
//! between the legs of an animal, beside its horns or under its belly, or bulges of the solid
//! that grow far beyond the reach of the off points. More off points do not reach them (they
//! stay within delta of the data), and a tighter carrier is worse (its gradient is steeper).
//!
//! # The rule
//!
//! After the first fit, f is sampled on a lattice of [`NODES`] nodes along the longest side of
//! the data's padded box (cheap next to the fit: N kernel sums per node). A node with f > 0 is
//! spurious when either
//! 1. its connected region of positive nodes (six-neighbour lattice connectivity) comes nowhere
//!    near the data: no node of the region lies within one lattice cell diagonal of a data point.
//!    A true part of the solid is bounded by the surface, so its positive nodes reach the data;
//!    a region that does not is a blob whatever the normals say; or
//! 2. it lies farther than [`CLEARANCE`] lattice spacings from every data point and its
//!    [`VOTERS`] nearest data points p_j with outward normals n_j agree, by a fraction of at
//!    least [`AGREE`], that it is outside: (q - p_j) . n_j > 0. Inside a solid every nearby point
//!    of the surface faces away from q; outside, towards it. Near the data (within the clearance)
//!    the off points already decide, and a vote there is at the mercy of single normals; where
//!    the voters disagree (a misoriented patch, a thin part) nothing is added.
//!
//! Each spurious node q becomes a constraint point with the target t(q) = -g d, d the distance
//! to the nearest data point and g = |grad f_c| at that point: the value a field with the
//! carrier's slope takes at distance d outside the surface, continuing the off points' targets
//! -g delta outward. The spline interpolates r = f_c(q) - t there, as at the off points. At most
//! [`MAX_SHARE`] of the data's count are added (evenly strided otherwise), so the second system
//! stays close to the first.

use rayon::prelude::*;

use super::normals::dist2;
use super::offsurface::carrier_slope;
use crate::par::Comm;
use crate::spline::carrier::Carrier;
use crate::spline::octree::Octree;
use crate::spline::{Evaluator, Normalisation, Spline};

/// Lattice nodes along the longest side of the box.
pub const NODES: usize = 32;
/// Nearest data points that vote on the side of a node.
pub const VOTERS: usize = 10;
/// Fraction of the voters that must find a node outside.
pub const AGREE: f64 = 0.8;
/// Distance from the data, in lattice spacings, below which a node is left to the off points.
pub const CLEARANCE: f64 = 2.0;
/// Most blob points, as a fraction of the data points (at least [`MIN_CAP`]).
pub const MAX_SHARE: f64 = 0.25;
/// Blob points allowed whatever the data's count.
pub const MIN_CAP: usize = 64;

/// A regular lattice of nodes in normalised coordinates, x fastest.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Lattice {
    pub lo: [f64; 3],
    pub h: f64,
    pub dims: [usize; 3],
}

impl Lattice {
    /// The lattice over lo..hi with `nodes` nodes along the longest side (at least 2).
    pub fn new(lo: [f64; 3], hi: [f64; 3], nodes: usize) -> Lattice {
        let longest = (0..3).map(|d| hi[d] - lo[d]).fold(0.0, f64::max).max(f64::MIN_POSITIVE);
        let h = longest / (nodes.max(2) - 1) as f64;
        let dims = [0, 1, 2].map(|d| (((hi[d] - lo[d]) / h).ceil() as usize + 1).max(2));
        Lattice { lo, h, dims }
    }

    pub fn len(&self) -> usize {
        self.dims.iter().product()
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Node `i` (x fastest).
    pub fn node(&self, i: usize) -> [f64; 3] {
        let [nx, ny, _] = self.dims;
        let idx = [i % nx, (i / nx) % ny, i / (nx * ny)];
        [0, 1, 2].map(|d| self.lo[d] + idx[d] as f64 * self.h)
    }

    /// The six lattice neighbours of node `i` that exist.
    fn neighbours(&self, i: usize, out: &mut Vec<usize>) {
        out.clear();
        let [nx, ny, nz] = self.dims;
        let (x, y, z) = (i % nx, (i / nx) % ny, i / (nx * ny));
        if x > 0 {
            out.push(i - 1);
        }
        if x + 1 < nx {
            out.push(i + 1);
        }
        if y > 0 {
            out.push(i - nx);
        }
        if y + 1 < ny {
            out.push(i + nx);
        }
        if z > 0 {
            out.push(i - nx * ny);
        }
        if z + 1 < nz {
            out.push(i + nx * ny);
        }
    }
}

/// f = f_c - U at every node of `lattice`, the rows of nodes dealt round-robin over the ranks
/// and summed: every rank gets the same values, bit for bit, whatever the number of ranks (each
/// value is computed by one rank and the others add zeros). Collective.
pub fn sample(comm: &dyn Comm, lattice: &Lattice, carrier: &Carrier, spline: &Spline) -> Vec<f64> {
    let [nx, ny, nz] = lattice.dims;
    let norm = &spline.norm;
    let ev = Evaluator::new(spline);
    let xs: Vec<f64> = (0..nx).map(|i| norm.centre[0] + norm.scale * lattice.node(i)[0]).collect();
    let mut values = vec![0.0; lattice.len()];
    let (rank, size) = (comm.rank(), comm.size());
    values.par_chunks_mut(nx).enumerate().filter(|(row, _)| row % size == rank).for_each(|(row, out)| {
        let p = lattice.node(row * nx);
        let (y, z) = (norm.centre[1] + norm.scale * p[1], norm.centre[2] + norm.scale * p[2]);
        ev.eval_row(&xs, y, z, out);
        for (v, &x) in out.iter_mut().zip(&xs) {
            *v = carrier.eval(&[x, y, z]) - *v;
        }
    });
    debug_assert_eq!(values.len(), nx * ny * nz);
    comm.sum_f64(&mut values);
    values
}

/// The spurious nodes of a sampled fit.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Blobs {
    /// 3 values per blob point, normalised.
    pub centres: Vec<f64>,
    /// Distance to the nearest data point (normalised).
    pub distance: Vec<f64>,
    /// The nearest data point.
    pub source: Vec<usize>,
    /// Positive regions that come nowhere near the data.
    pub regions: usize,
    /// Spurious nodes found (before the cap).
    pub found: usize,
}

/// The spurious nodes (see the module doc) of the fit whose `values` were sampled on `lattice`,
/// for data `points` (normalised, the tree `tree` over them) with outward unit `normals`.
pub fn find(lattice: &Lattice, values: &[f64], points: &[f64], normals: &[[f64; 3]], tree: &Octree) -> Blobs {
    let n = normals.len();
    let h = lattice.h;
    let positive: Vec<bool> = values.iter().map(|&v| v > 0.0).collect();
    // distance to the nearest data point and the outside vote of every positive node
    let judged: Vec<Option<(f64, usize, bool)>> = (0..lattice.len())
        .into_par_iter()
        .map_init(Vec::new, |found, i| {
            if !positive[i] {
                return None;
            }
            let q = lattice.node(i);
            let r = tree.kth_distance(q, VOTERS.min(n), h);
            tree.within(q, r, found);
            let mut near: Vec<(f64, usize)> = found.iter().map(|&j| (dist2(&q, &points[3 * j..]), j)).collect();
            near.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
            near.truncate(VOTERS.min(n));
            let (d2, nearest) = *near.first()?;
            let outside = near
                .iter()
                .filter(|&&(_, j)| (0..3).map(|d| (q[d] - points[3 * j + d]) * normals[j][d]).sum::<f64>() > 0.0)
                .count();
            let voted = outside as f64 >= AGREE * near.len() as f64;
            Some((d2.sqrt(), nearest, voted))
        })
        .collect();
    // regions of positive nodes; a region is supported when one of its nodes is within a cell
    // diagonal of the data
    let reach = h * 3f64.sqrt();
    let mut region = vec![usize::MAX; lattice.len()];
    let mut supported = Vec::new();
    let (mut stack, mut adj) = (Vec::new(), Vec::new());
    for start in 0..lattice.len() {
        if !positive[start] || region[start] != usize::MAX {
            continue;
        }
        let id = supported.len();
        let mut near_data = false;
        region[start] = id;
        stack.push(start);
        while let Some(i) = stack.pop() {
            near_data |= judged[i].is_some_and(|(d, _, _)| d <= reach);
            lattice.neighbours(i, &mut adj);
            for &j in &adj {
                if positive[j] && region[j] == usize::MAX {
                    region[j] = id;
                    stack.push(j);
                }
            }
        }
        supported.push(near_data);
    }
    let mut blobs = Blobs { regions: supported.iter().filter(|&&s| !s).count(), ..Default::default() };
    for (i, j) in judged.iter().enumerate() {
        let Some((d, nearest, voted)) = *j else { continue };
        let spurious = !supported[region[i]] || (d > CLEARANCE * h && voted);
        if spurious {
            blobs.centres.extend_from_slice(&lattice.node(i));
            blobs.distance.push(d);
            blobs.source.push(nearest);
        }
    }
    blobs.found = blobs.source.len();
    let cap = ((MAX_SHARE * n as f64) as usize).max(MIN_CAP);
    if blobs.found > cap {
        let keep: Vec<usize> = (0..cap).map(|k| k * blobs.found / cap).collect();
        blobs.centres = keep.iter().flat_map(|&k| blobs.centres[3 * k..3 * k + 3].to_vec()).collect();
        blobs.distance = keep.iter().map(|&k| blobs.distance[k]).collect();
        blobs.source = keep.iter().map(|&k| blobs.source[k]).collect();
    }
    blobs
}

/// The spline's values r = f_c(q) - t at the blob points, t = -g d in the caller's units (see the
/// module doc), for data `raw` (caller's coordinates, 3 per point).
pub fn blob_values(blobs: &Blobs, raw: &[f64], carrier: &Carrier, norm: &Normalisation) -> Vec<f64> {
    let h = 1e-6 * norm.scale;
    (0..blobs.source.len())
        .into_par_iter()
        .map(|k| {
            let q: Vec<f64> = (0..3).map(|d| norm.centre[d] + norm.scale * blobs.centres[3 * k + d]).collect();
            let s = blobs.source[k];
            let g = carrier_slope(carrier, &raw[3 * s..3 * s + 3], h);
            carrier.eval(&q) + g * blobs.distance[k] * norm.scale
        })
        .collect()
}
