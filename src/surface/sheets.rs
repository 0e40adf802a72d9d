//! Sheets thinner than the sampling: a first fit whose solid spills far from the data, and the
//! normals oriented again by the side of the sheet each point lies on.
//!
//! # The failure
//!
//! Where the two sides of a closed part lie closer together than the points along them (a leaf,
//! a blade, a plate scanned sparsely), every neighbourhood holds points of both sides, and their
//! unoriented normals are nearly parallel. The graph's signs then join both sides into one sheet
//! (two points across the gap, seen at a shallow angle, want the same sign by the dipole rule),
//! the patches of the dipole step span both sides, and the two sides come out oriented the same
//! way. The fit then holds its zero set to the data with the inside on one side of the whole
//! sheet: the solid fills the space beside it, up to where the carrier ends. On a closed
//! ellipsoid with semi-axes 1, 0.5 and 0.02 at 1000 area-uniform points, mesh -> truth was 22.7 %
//! of the diagonal.
//!
//! # Spilling
//!
//! A fit of a closed surface has no solid far outside the data's box (the default method stays
//! within 5 % of the longest side of it on every set of the surface benchmark). After the first
//! fit, f is sampled on the faces of the data's box grown by [`SPILL`] times its longest side (a
//! lattice of [`NODES`] nodes along that side, its face nodes alone: a few thousand kernel sums
//! per centre, milliseconds); a positive node there is solid spilling far beyond the data.
//!
//! # Orientation by side
//!
//! On a sheet thinner than the sampling, a point's neighbourhood is a slab holding both sides,
//! and the plane fitted to it (the point and its nearest neighbours, least squares) lies between
//! them: a point of one side lies off that plane towards its own side's outside. So each point's
//! normal is turned to point away from the plane, n . (p - m) > 0 with m the mean of the
//! neighbourhood. The rule also holds where the surface is convex (the point lies outside the
//! chord plane of its neighbours) and fails where it is concave, so it is used only where a fit
//! spilled: there, the fit made again with these normals is kept when it spills at most a fifth as
//! much (a first fit of a long thin scan, the bunny stretched 25 times along one axis, leaves the
//! carrier's solid all round it at that distance, which the blob search clears; the side rule
//! only shrinks it, 187 -> 56 nodes, and breaks the fit), and the
//! blob search after it takes its lattice over the grown box (the flat box of a sheet's data
//! would leave the space beside the sheet out). On the ellipsoid above the rule agrees with the
//! true normals on 98-99.7 % of the points from 1000 to 4000 points and thicknesses 0.04-0.1.
//!
//! # Measured
//!
//! `jobs/bench-thin-sheet` (semi-axes 1, 0.5 and C, area-uniform samples, 2 ranks, grid 100;
//! mesh -> truth rms in % of the diagonal): the four samplings that spilled (the points 0.70 of
//! the thickness apart or more) went from 18-23 to 0.97 (C = 0.02, 1000 points), 8.4 (C = 0.02,
//! 2000: a detached blob below the sheet, where f stays near zero over a wide region, is left),
//! 0.66 (C = 0.02, 4000) and 1.59 (C = 0.03, 1000), against screened Poisson's 4.9-9.0 (truth ->
//! mesh 0.36-0.83 against Poisson's 0.63-0.98 and the carrier method's 0.61-0.97); the five
//! that did not spill are unchanged, as are the sets of the surface benchmark, none of which
//! spills.

use rayon::prelude::*;

use super::blobs::{sample_nodes, Lattice};
use crate::par::Comm;
use crate::spline::carrier::Carrier;
use crate::spline::{Normalisation, Spline};

/// How far beyond the data's box solid counts as spilling, in multiples of the box's longest
/// side: five times the margin of the output grid, so that no bulge near the data reaches it.
pub const SPILL: f64 = 0.25;
/// Lattice nodes along the longest side of the grown box.
pub const NODES: usize = 32;

/// The lattice over the data's box `lo..hi` (caller's coordinates) grown by [`SPILL`] times its
/// longest side, in the normalised coordinates of `norm`, and its nodes on the lattice's faces
/// (sorted, each once).
pub fn spill_lattice(lo: &[f64], hi: &[f64], norm: &Normalisation) -> (Lattice, Vec<usize>) {
    let lattice = Lattice::of_fit_with(lo, hi, SPILL, norm, NODES);
    let [nx, ny, nz] = lattice.dims;
    let faces = (0..lattice.len())
        .filter(|&i| {
            let (x, y, z) = (i % nx, (i / nx) % ny, i / (nx * ny));
            x == 0 || y == 0 || z == 0 || x + 1 == nx || y + 1 == ny || z + 1 == nz
        })
        .collect();
    (lattice, faces)
}

/// The nodes of the faces of [`spill_lattice`] where the fit f = f_c - U (`carrier`, `spline`)
/// is positive: solid far beyond the data. Collective; the same on every rank.
pub fn spilled(
    comm: &dyn Comm,
    (lattice, faces): &(Lattice, Vec<usize>),
    carrier: &Carrier,
    spline: &Spline,
) -> usize {
    let mut values = vec![0.0; lattice.len()];
    sample_nodes(comm, lattice, faces, (carrier, spline), &mut values);
    faces.iter().filter(|&&i| values[i] > 0.0).count()
}

/// Turns every normal of `normals` (unit, at the normalised `points`) to point away from the
/// mean of its point and that point's `kmax` nearest neighbours (`knn`): on a thin sheet the
/// least-squares plane of that neighbourhood passes through the mean between the two sides, and
/// the point's normal is nearly the plane's (see the module doc). A point at the mean keeps its
/// normal. Returns how many were turned.
pub fn orient_by_side(points: &[f64], normals: &mut [[f64; 3]], knn: &[usize], kmax: usize) -> usize {
    let turn: Vec<bool> = (0..normals.len())
        .into_par_iter()
        .map(|i| {
            let hood = std::iter::once(i).chain(knn[i * kmax..(i + 1) * kmax].iter().copied());
            let count = (kmax + 1) as f64;
            let mut mean = [0.0; 3];
            for j in hood {
                (0..3).for_each(|d| mean[d] += points[3 * j + d] / count);
            }
            let off: f64 = (0..3).map(|d| (points[3 * i + d] - mean[d]) * normals[i][d]).sum();
            off < 0.0
        })
        .collect();
    for (n, &t) in normals.iter_mut().zip(&turn) {
        if t {
            *n = n.map(|v| -v);
        }
    }
    turn.iter().filter(|&&t| t).count()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::surface::normals;

    /// `n` points of the ellipsoid with semi-axes 1, 0.5 and `c` on a Fibonacci spiral of the
    /// sphere mapped onto it, with its outward normals.
    fn ellipsoid(n: usize, c: f64) -> (Vec<f64>, Vec<[f64; 3]>) {
        let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
        let (mut p, mut o) = (Vec::new(), Vec::new());
        for i in 0..n {
            let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
            let r = (1.0 - z * z).sqrt();
            let (x, y) = (r * (golden * i as f64).cos(), r * (golden * i as f64).sin());
            p.extend_from_slice(&[x, 0.5 * y, c * z]);
            let g = [x, y / 0.5, z / c];
            let len = (g[0] * g[0] + g[1] * g[1] + g[2] * g[2]).sqrt();
            o.push(g.map(|v| v / len));
        }
        (p, o)
    }

    #[test]
    fn both_sides_of_a_sheet_thinner_than_the_sampling_point_outward() {
        // 0.04 thick, about 0.06 between neighbouring points: every neighbourhood holds both
        // sides; start from the normals all turned one way, as a failed orientation leaves them
        let (p, truth) = ellipsoid(1000, 0.02);
        let tree = crate::spline::octree::Octree::new(&p, 8);
        let kmax = 20;
        let knn = normals::nearest(&tree, &p, kmax);
        let mut n: Vec<[f64; 3]> =
            truth.iter().map(|t| if t[2] < 0.0 { t.map(|v| -v) } else { *t }).collect();
        let turned = orient_by_side(&p, &mut n, &knn, kmax);
        let agree =
            n.iter().zip(&truth).filter(|(a, b)| (0..3).map(|d| a[d] * b[d]).sum::<f64>() > 0.0).count();
        assert!(turned > 400, "{turned} turned");
        assert!(agree as f64 > 0.97 * 1000.0, "{agree} of 1000 agree with the outward normals");
    }
}
