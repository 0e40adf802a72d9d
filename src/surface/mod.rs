//! Surface points without normals -> oriented off-surface constraints.
//!
//! A spline through value 0 at the data alone (the plain carrier method) is pinned down only on
//! the data: between and beside the points its zero set wanders, and a scan that is open or
//! concave grows sheets and bulges. Constraints beside the surface (Carr et al. 2001: points
//! p +- delta n with values of the sign of the side) hold the zero set to the data, but need
//! normals that point consistently outward. Scans rarely come with them, so they are made here:
//! - [`normals`]: unoriented normals by local principal component analysis, each point taking
//!   the most planar of several neighbourhood sizes;
//! - [`mod@orient`]: a consistent global orientation (the smallest eigenvector of a signed graph
//!   Laplacian, corrected patch by patch by the dipole field) made outward by the divergence
//!   theorem;
//! - [`denoise`]: optionally, noisy points moved onto quadrics fitted to their same-sheet
//!   neighbours, before everything else is made again from them;
//! - [`offsurface`]: the off points and the values the spline takes there;
//! - [`rays`]: after a first fit, rays inward and outward from every data point find the small
//!   patches whose normals point inward (a false shell around a thin part), turned for a
//!   second fit;
//! - [`blobs`]: after a first fit, the regions it makes inside with no data to support them,
//!   pinned outside by further points for a second fit;
//! - [`choice`]: of two second fits (a wide and a narrow clearance of the blob search), the one
//!   with less surface that no data supports;
//! - [`turns`]: then the side vote's turns tried together, and the small patches of normals whose
//!   turn shrinks that surface, turned;
//! - [`outside`]: last, outside off points for the data points nearest to the unsupported
//!   surface left in open space;
//! - [`sheets`]: where a first fit's solid spills far beyond the data (both sides of a sheet
//!   thinner than the sampling oriented alike), the normals oriented again by side;
//! - [`support`]: where the data support the reconstructed surface, for trimming it.
//!
//! Everything works in the normalised coordinates of the spline's centres (the data's box
//! centred, its half-diagonal 1) and is identical on every rank. The work per point (nearest
//! neighbours, PCA normals, the denoising test's quadrics: [`neighbourhoods_on`],
//! [`denoise::scale_ratio_on`]) is dealt over the ranks in blocks and all-gathered, and the dense
//! dipole sums of the orientation are shared by rows: each value is the one a single process
//! computes, bit for bit (the dipole sums up to the order of their last addition over the ranks).

pub mod blobs;
pub mod choice;
pub mod denoise;
pub mod energy;
pub mod normals;
pub mod offsurface;
pub mod orient;
pub mod outside;
pub mod rays;
pub mod sheets;
pub mod support;
pub mod turns;

pub use offsurface::{
    doubtful_share_in_effect, off_points, off_points_by_trust, off_value_parts, off_values,
    off_values_sloped, Doubt, OffPoints, DELTA,
};
pub use orient::{orient, Orientation};

use crate::error::{Error, Result};
use crate::par::{self, Comm};
use crate::spline::octree::Octree;

/// Fewest points for which normals are estimated (the largest neighbourhood and the point).
pub const MIN_POINTS: usize = 21;

/// The octree, the nearest neighbours (`kmax` per point) and the unoriented normals of
/// normalised `points` (3 values per point).
pub struct Neighbourhoods {
    pub tree: Octree,
    pub knn: Vec<usize>,
    pub kmax: usize,
    pub normals: Vec<[f64; 3]>,
}

/// Nearest neighbours and unoriented PCA normals of `points`; needs [`MIN_POINTS`] points.
pub fn neighbourhoods(points: &[f64]) -> Result<Neighbourhoods> {
    let n = points.len() / 3;
    if n < MIN_POINTS {
        return Err(Error::Usage(format!(
            "{n} points are too few to estimate normals for off-surface constraints (at least {MIN_POINTS}); \
             use --surface carrier"
        )));
    }
    let tree = Octree::new(points, 10);
    let kmax = *normals::NEIGHBOURHOODS.iter().max().unwrap_or(&20);
    let knn = normals::nearest(&tree, points, kmax);
    let (normals, _) = normals::pca_normals(points, &knn, kmax);
    Ok(Neighbourhoods { tree, knn, kmax, normals })
}

/// [`neighbourhoods`] with the points dealt over the ranks of `comm` in contiguous blocks: each
/// rank finds the neighbours and the normal of its own points and all-gathers them, so every
/// rank holds the lists and normals one process finds, bit for bit (each point's depend on the
/// point and the octree alone). Collective; too few points are refused on every rank alike,
/// before any message.
pub fn neighbourhoods_on(comm: &dyn Comm, points: &[f64]) -> Result<Neighbourhoods> {
    let n = points.len() / 3;
    if n < MIN_POINTS || comm.size() == 1 {
        return neighbourhoods(points);
    }
    let tree = Octree::new(points, 10);
    let kmax = *normals::NEIGHBOURHOODS.iter().max().unwrap_or(&20);
    let mine = par::block(comm, n, comm.rank());
    let knn = normals::nearest_of(&tree, points, kmax, mine.clone());
    let (unit, _) = normals::pca_normals_of(points, &knn, kmax, mine);
    // one message: a point's kmax neighbours (indices, exact in a double) and its normal
    let width = kmax + 3;
    let send: Vec<f64> = knn
        .chunks_exact(kmax)
        .zip(&unit)
        .flat_map(|(row, v)| row.iter().map(|&j| j as f64).chain(v.iter().copied()))
        .collect();
    let all = par::all_gather_blocks(comm, n, width, &send);
    let knn = all.chunks_exact(width).flat_map(|c| c[..kmax].iter().map(|&j| j as usize)).collect();
    let normals = all.chunks_exact(width).map(|c| [c[kmax], c[kmax + 1], c[kmax + 2]]).collect();
    Ok(Neighbourhoods { tree, knn, kmax, normals })
}

/// Oriented outward normals of `points` from their neighbourhoods, without the side vote of
/// [`mod@orient`] (the default of `fit`). Collective.
pub fn oriented(comm: &dyn Comm, points: &[f64], hoods: &Neighbourhoods) -> Result<Orientation> {
    orient(comm, points, &hoods.normals, &hoods.knn, hoods.kmax, false)
}

/// [`oriented`] with the side vote on or off. Collective.
pub fn oriented_with(
    comm: &dyn Comm,
    points: &[f64],
    hoods: &Neighbourhoods,
    side_vote: bool,
) -> Result<Orientation> {
    orient(comm, points, &hoods.normals, &hoods.knn, hoods.kmax, side_vote)
}

/// Points of the unit sphere on a Fibonacci spiral (nearly even) and their outward normals: the
/// test shape of the surface modules.
#[cfg(test)]
pub(crate) fn fibonacci_sphere(n: usize) -> (Vec<f64>, Vec<[f64; 3]>) {
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    let normals: Vec<[f64; 3]> = (0..n)
        .map(|i| {
            let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
            let r = (1.0 - z * z).sqrt();
            let t = golden * i as f64;
            [r * t.cos(), r * t.sin(), z]
        })
        .collect();
    (normals.iter().flatten().copied().collect(), normals)
}
