//! Where the data support a reconstructed surface: within a distance of some data point. The
//! distance is a multiple F of the data's median spacing (the median distance from a data point
//! to its nearest other one), so that one F serves scans of every size and density.
//!
//! Trimming the surface that no data point supports (`fit --trim F`) opens the solid where the
//! scan has holes, and removes what the spline invented away from the data (bulges over the thin
//! parts, webs between them), as density trimming does for screened Poisson. The closed solid
//! stays the model; the trimmed surface is a further output.
//!
//! A triangle whose centroid lies farther than the radius from every data point is unsupported,
//! but it is left out only with its whole region (the unsupported triangles joined to it through
//! shared vertices), and only where that region reaches deep or stands off the data. For a scan
//! sampled uniformly at random, a point of its surface lies farther than F median spacings from
//! every sample with probability 2^(-F^2) (the sample's nearest-neighbour distance has the
//! distribution of the surface's nearest-sample distance): 6 % of the surface at F = 2, which a
//! single threshold punched into a fully sampled 90,000-point bunny as 2,801 small holes over 8 %
//! of its area. A region goes when one of its centroids
//! - lies farther than [`DEPTH`] times the radius from every data point: reaching twice as far
//!   has probability 2^(-16), so holes cut out of a scan, and bulges and webs far from the data,
//!   go whole, cut at the radius, while the gaps of a random sample stay; or
//! - stands off the surface the data describe: farther than [`OFF_PLANE`] times the radius from
//!   the least-squares plane of its [`PLANE_POINTS`] nearest data points. A gap in the sample
//!   lies in that surface, so its points lie near that plane: a gap of radius a on a surface
//!   whose radius of curvature is rho departs from the plane of its rim by about a^2 / (2 rho),
//!   under the radius R for every gap that is not deep (a < 2R) unless rho < 2R, a curvature
//!   that a sample of spacing R/F does not resolve anyway. A bulge that the spline put beside
//!   the data (over a thin part, or where the solid rounds a concave corner) stands off the
//!   plane by about its own distance from the data, which for an unsupported centroid is more
//!   than R. On the surface benchmark's 20 sets of 400-4000 points this second test leaves out
//!   0-7 further regions a set, nearly all of whose triangles lie 0.2-4.2 % of the diagonal
//!   from the true surface (median), where the deep rule alone left them all.
//!
//!   One triangle standing off takes its region only where a share of the region's area
//!   ([`crate::mesh::trim::RAISED_SHARE`]) is raised at least [`RAISED`] times the radius off
//!   the plane: a bulge rises over most of its area, while a large gap of a sparsely sampled
//!   flank lies in the data's surface but for a few triangles where the plane of ten sparse
//!   points misses the curvature (on a scanner's own vertices of the cow strided to 2000
//!   points, with noise, one such triangle took 13 % of the surface with it).

use rayon::prelude::*;

use crate::mesh::trim::Support;
use crate::spline::octree::{Octree, DEFAULT_LEAF_CAPACITY};
use crate::spline::Model;
use crate::surface::blobs::Lattice;
use crate::surface::normals::Plane;

/// How deep an unsupported region of a surface must reach to be left out, in multiples of the
/// radius: a random sample leaves a point of its surface this far (4 median spacings at F = 2)
/// from every sample with probability 2^(-16).
pub const DEPTH: f64 = 2.0;

/// How far an unsupported point must stand off the plane of its nearest data points for its
/// region to be left out, in multiples of the radius.
pub const OFF_PLANE: f64 = 1.0;

/// How far an unsupported point must stand off the plane of its nearest data points to count
/// as raised off them (towards a region's share standing off), in multiples of the radius.
pub const RAISED: f64 = 0.5;

/// The nearest data points whose least-squares plane an unsupported point is measured against.
pub const PLANE_POINTS: usize = 10;

/// The data points and the radius within which they support a surface.
pub struct DataSupport {
    tree: Octree,
    /// Each data point's distance to its nearest other data point (input order).
    nearest: Vec<f64>,
    /// The median distance from a data point to its nearest other data point.
    pub spacing: f64,
    /// F, the multiple of the spacing.
    pub factor: f64,
    /// F times the spacing.
    pub radius: f64,
    /// What [`DataSupport::on_lattice`] found at the nodes of a lattice.
    nodes: Option<NodeReach>,
}

/// Whether the data support every point within one lattice spacing of each node of a lattice,
/// none of them, or some (see [`DataSupport::on_lattice`]).
struct NodeReach {
    lattice: Lattice,
    /// [`ALL_NEAR`], [`SOME_NEAR`] or [`NONE_NEAR`] per node.
    class: Vec<u8>,
}

/// Every point within one lattice spacing of the node is supported.
const ALL_NEAR: u8 = 2;
/// Some may be: the tree decides.
const SOME_NEAR: u8 = 1;
/// None is.
const NONE_NEAR: u8 = 0;

impl DataSupport {
    /// The support of `points` (3 values per point, at least 2 distinct) at `factor` times their
    /// median spacing.
    pub fn new(points: &[f64], factor: f64) -> Self {
        let tree = Octree::new(points, DEFAULT_LEAF_CAPACITY);
        let n = points.len() / 3;
        let nearest: Vec<f64> = (0..n)
            .into_par_iter()
            .map(|i| tree.kth_distance([points[3 * i], points[3 * i + 1], points[3 * i + 2]], 2))
            .collect();
        let spacing = median(nearest.iter().copied().filter(|d| *d > 0.0 && d.is_finite()).collect());
        DataSupport { tree, nearest, spacing, factor, radius: factor * spacing, nodes: None }
    }

    /// This support with the answer of [`DataSupport::supports`] for the points near each node
    /// of `lattice` worked out once, for [`DataSupport::supports_near`]. A point q within one
    /// spacing h of a node x has |q - p| <= |x - p| + h for every data point p, and
    /// |q - p| >= |x - p| - h: so where some data point lies within R - h of the node (R the
    /// radius), every such q is supported; where none lies within R + h, none is; only the nodes
    /// in between leave the answer to the tree. Both bounds are widened by a billionth of R + h,
    /// far above the rounding of the distances, so the answers are exactly those of
    /// [`DataSupport::supports`]. The classes are found from the data points, each marking the
    /// nodes within R + h of it: a few hundred nodes a point, where the surface checks of a fit
    /// asked the tree again at each of some 10^4 crossings of the lattice's edges, tens of times
    /// a fit.
    pub fn on_lattice(mut self, lattice: &Lattice) -> Self {
        let h = lattice.h;
        let margin = 1e-9 * (self.radius + h);
        let (near, reach) = (self.radius - h - margin, self.radius + h + margin);
        let near2 = if near > 0.0 { near * near } else { -1.0 };
        let reach2 = reach * reach;
        let [nx, ny, _] = lattice.dims;
        let mut class = vec![NONE_NEAR; lattice.len()];
        // each z-plane of nodes marked by the data points within reach of it, the planes in
        // parallel; the points sorted by z so that each plane visits its own
        let n = self.nearest.len();
        let mut by_z: Vec<[f64; 3]> = (0..n).map(|i| self.tree.point(i)).collect();
        by_z.sort_by(|a, b| a[2].total_cmp(&b[2]));
        let z_of: Vec<f64> = by_z.iter().map(|p| p[2]).collect();
        let span = |x: f64, d: usize, len: usize| -> Option<std::ops::Range<usize>> {
            let a = ((x - reach - lattice.lo[d]) / h).ceil().max(0.0);
            let b = ((x + reach - lattice.lo[d]) / h).floor().min((len - 1) as f64);
            (a <= b).then(|| a as usize..b as usize + 1)
        };
        class.par_chunks_mut(nx * ny).enumerate().for_each(|(z, plane)| {
            let qz = lattice.lo[2] + z as f64 * h;
            let first = z_of.partition_point(|&pz| pz < qz - reach);
            let last = z_of.partition_point(|&pz| pz <= qz + reach);
            for p in &by_z[first..last] {
                let (Some(xs), Some(ys)) = (span(p[0], 0, nx), span(p[1], 1, ny)) else {
                    continue;
                };
                let dz2 = (qz - p[2]) * (qz - p[2]);
                for y in ys {
                    let dy = lattice.lo[1] + y as f64 * h - p[1];
                    let dyz2 = dy * dy + dz2;
                    for x in xs.clone() {
                        let dx = lattice.lo[0] + x as f64 * h - p[0];
                        let d2 = dx * dx + dyz2;
                        let c = &mut plane[x + nx * y];
                        if d2 <= near2 {
                            *c = ALL_NEAR;
                        } else if d2 <= reach2 && *c == NONE_NEAR {
                            *c = SOME_NEAR;
                        }
                    }
                }
            }
        });
        self.nodes = Some(NodeReach { lattice: *lattice, class });
        self
    }

    /// Whether the value of f at node `i` of `lattice` can bear on the unsupported crossings of
    /// the lattice's edges ([`crate::surface::choice`]): false where the classes of
    /// [`DataSupport::on_lattice`] for this lattice say that every point within one spacing of
    /// the node is supported. Every edge of the node lies within one spacing of it, so a surface
    /// crossing on one is supported whatever f does: the answer for an edge whose lower end is the
    /// node, and, for an edge from the node below, the tree's (that node's class cannot say none,
    /// since a data point within R - h of this node lies within R of it). True wherever the
    /// classes do not decide it (another lattice, or none worked out).
    pub fn bears_on_crossings(&self, lattice: &Lattice, i: usize) -> bool {
        match &self.nodes {
            Some(r) if r.lattice == *lattice => r.class[i] != ALL_NEAR,
            _ => true,
        }
    }

    /// [`DataSupport::supports`] for a point `x` within one spacing of node `i` of `lattice`
    /// (a crossing of one of the node's edges): the same answer, found from the node's class
    /// where [`DataSupport::on_lattice`] worked them out for this lattice, from the tree where
    /// the node's class leaves it open or there are none.
    pub fn supports_near(&self, lattice: &Lattice, i: usize, x: &[f64; 3]) -> bool {
        match &self.nodes {
            Some(r) if r.lattice == *lattice => match r.class[i] {
                ALL_NEAR => true,
                NONE_NEAR => false,
                _ => self.supports(x),
            },
            _ => self.supports(x),
        }
    }

    /// The support of the data points `model` records (the first `data_points` centres of its
    /// finest level, mapped back to the caller's coordinates), or None where it does not record
    /// them. `fit --trim` and `eval --trim` both take it, so that they trim alike.
    pub fn of_model(model: &Model, factor: f64) -> Option<Self> {
        model.data_points().map(|points| DataSupport::new(&points, factor))
    }

    /// Whether some data point lies within the radius of `x`.
    pub fn supports(&self, x: &[f64; 3]) -> bool {
        self.tree.any_within(*x, self.radius)
    }

    /// Whether `x` is supported, and where not, whether it lies deep (farther than [`DEPTH`]
    /// times the radius from every data point), stands off the data's surface (farther than
    /// [`OFF_PLANE`] times the radius from the plane of its [`PLANE_POINTS`] nearest data points)
    /// or is raised off it (farther than [`RAISED`] times the radius).
    ///
    /// The depth is measured in the local radius where the data around `x` are sparser than the
    /// median: F times the median spacing of its [`PLANE_POINTS`] nearest data points, where that
    /// is more than the radius. A scan of uneven density (a scanner's own vertices, dense on the
    /// detailed parts and sparse on the flat ones) has gaps as wide as its sparse spacing, which
    /// the median spacing of the dense parts made deep: 7-10 % of the surface of the cow's
    /// strided vertices went as deep regions. The support and the plane's test keep the
    /// radius: a bulge beside a thin part has sparse data nearest to it, and a local radius
    /// there kept it.
    pub fn judge(&self, x: &[f64; 3]) -> Support {
        if self.supports(x) {
            return Support::Near;
        }
        let mut near = Vec::with_capacity(PLANE_POINTS);
        self.tree.nearest_k(*x, PLANE_POINTS, &mut near);
        let local = self.factor * median(near.iter().map(|&(_, i)| self.nearest[i]).collect());
        let deep = DEPTH * self.radius.max(local);
        if near.first().is_none_or(|&(d2, _)| d2 > deep * deep) {
            Support::Deep
        } else {
            let off = self.plane_distance(x, &near);
            if off > OFF_PLANE * self.radius {
                Support::Off
            } else if off > RAISED * self.radius {
                Support::Raised
            } else {
                Support::Shallow
            }
        }
    }

    /// The distance from `x` to the least-squares plane of its [`PLANE_POINTS`] nearest data
    /// points (their mean and the eigenvector of their scatter's smallest eigenvalue).
    pub fn off_plane(&self, x: &[f64; 3]) -> f64 {
        let mut near = Vec::with_capacity(PLANE_POINTS);
        self.tree.nearest_k(*x, PLANE_POINTS, &mut near);
        self.plane_distance(x, &near)
    }

    /// The distance from `x` to the least-squares plane of the data points `near` (as
    /// [`Octree::nearest_k`] lists them).
    fn plane_distance(&self, x: &[f64; 3], near: &[(f64, usize)]) -> f64 {
        Plane::of(|| near.iter().map(|&(_, i)| self.tree.point(i))).distance(x)
    }
}

/// The median of `v` (the upper of the two middle values of an even count; 0 for none).
fn median(mut v: Vec<f64>) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    let mid = v.len() / 2;
    *v.select_nth_unstable_by(mid, f64::total_cmp).1
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::surface::choice::unsupported_crossings;

    #[test]
    fn a_grid_of_points_supports_its_neighbourhood_only() {
        // a 10 x 10 grid of spacing 0.5 in the plane z = 0
        let pts: Vec<f64> =
            (0..100).flat_map(|i| [0.5 * (i % 10) as f64, 0.5 * (i / 10) as f64, 0.0]).collect();
        let s = DataSupport::new(&pts, 2.0);
        assert_eq!(s.spacing, 0.5);
        assert_eq!((s.factor, s.radius), (2.0, 1.0));
        assert!(s.supports(&[2.25, 2.25, 0.9]));
        assert!(s.supports(&[0.0, 0.0, 1.0]));
        assert!(!s.supports(&[0.0, 0.0, 1.01]));
        assert!(!s.supports(&[-1.0, -1.0, 0.0]));
    }

    #[test]
    fn the_nodes_of_a_lattice_answer_as_the_tree_does_up_to_the_radius_itself() {
        // a 10 x 10 grid of spacing 0.5 in the plane z = 0 (radius 1) and a lattice of spacing
        // 0.25 whose nodes and edge ends lie on binary fractions: the nodes 0.75 = R - h and
        // 1.25 = R + h below a data point are left to the tree, whose answer for the far end
        // of their edges, exactly R and R - h from the point, is "supported"
        let pts: Vec<f64> =
            (0..100).flat_map(|i| [0.5 * (i % 10) as f64, 0.5 * (i / 10) as f64, 0.0]).collect();
        let lattice = Lattice::new([-2.0; 3], [6.5, 6.5, 2.0], 35);
        assert_eq!(lattice.h, 0.25);
        let s = DataSupport::new(&pts, 2.0).on_lattice(&lattice);
        let index = |x: [f64; 3]| {
            let i = x.map(|v| v + 2.0).map(|v| (v / 0.25) as usize);
            i[0] + lattice.dims[0] * (i[1] + lattice.dims[1] * i[2])
        };
        let classes = &s.nodes.as_ref().unwrap().class;
        for (node, class, end, supported) in [
            ([2.0, 2.0, -1.25], SOME_NEAR, [2.0, 2.0, -1.0], true),
            ([2.0, 2.0, -0.75], SOME_NEAR, [2.0, 2.0, -0.5], true),
            ([2.0, 2.0, -0.5], ALL_NEAR, [2.0, 2.0, -0.25], true),
            ([2.0, 2.0, -1.5], NONE_NEAR, [2.0, 2.0, -1.25], false),
            ([2.0, 2.0, 1.25], SOME_NEAR, [2.0, 2.0, 1.5], false),
            ([-1.25, 2.0, 0.0], SOME_NEAR, [-1.0, 2.0, 0.0], true),
        ] {
            let i = index(node);
            assert_eq!(lattice.node(i), node);
            assert_eq!(classes[i], class, "{node:?}");
            for x in [node, end] {
                assert_eq!(s.supports_near(&lattice, i, &x), s.supports(&x), "{x:?}");
            }
            assert_eq!(s.supports_near(&lattice, i, &end), supported, "{end:?}");
        }
        // most nodes are decided by their class alone
        let open = classes.iter().filter(|&&c| c == SOME_NEAR).count();
        assert!(open * 4 < classes.len(), "{open} of {} left to the tree", classes.len());
    }

    #[test]
    fn values_at_nodes_that_bear_on_no_crossing_change_no_count() {
        // every 8th vertex of the test bunny (about 4500 points) and a lattice of 48 nodes along
        // the longest side of their box with a margin; a field of random signs and sizes, so
        // that most edges change sign
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/bunny10k.obj");
        let set = crate::io::points::read_points(std::path::Path::new(path)).unwrap();
        let pts: Vec<f64> = set.points.iter().step_by(8).flatten().copied().collect();
        let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
        for p in pts.chunks_exact(3) {
            for d in 0..3 {
                (lo[d], hi[d]) = (lo[d].min(p[d]), hi[d].max(p[d]));
            }
        }
        let pad = 0.05 * (0..3).map(|d| hi[d] - lo[d]).fold(0.0, f64::max);
        let lattice = Lattice::new(lo.map(|v| v - pad), hi.map(|v| v + pad), 48);
        let s = DataSupport::new(&pts, 2.0).on_lattice(&lattice);
        let mut x = 7u64;
        let mut draw = || {
            x = x.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (x >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let values: Vec<f64> = (0..lattice.len()).map(|_| draw()).collect();
        let (far, all) = unsupported_crossings(&lattice, &values, &s);
        // the others' values changed, signs and sizes
        let idle: Vec<usize> = (0..lattice.len()).filter(|&i| !s.bears_on_crossings(&lattice, i)).collect();
        let mut changed = values.clone();
        for &i in &idle {
            changed[i] = -3.0 * changed[i] + draw();
        }
        let (far2, all2) = unsupported_crossings(&lattice, &changed, &s);
        assert_eq!(far2, far, "the unsupported crossings moved");
        // the count of all crossings did change: the idle nodes hold supported ones
        assert_ne!(all2, all);
        assert!(idle.len() > 1000 && far.len() > 1000, "{} idle nodes, {} far", idle.len(), far.len());
        // another lattice, or none worked out: every node bears
        let bare = DataSupport::new(&pts, 2.0);
        assert!((0..lattice.len()).all(|i| bare.bears_on_crossings(&lattice, i)));
    }

    #[test]
    fn a_gap_in_the_data_stays_and_what_stands_off_them_goes() {
        // a 20 x 20 grid of spacing 0.5 in the plane z = 0 with a 5 x 5 block of points taken
        // out around (4.5, 4.5): radius 1, the gap's centre 1.5 from the nearest point
        let pts: Vec<f64> = (0..400)
            .map(|i| [0.5 * (i % 20) as f64, 0.5 * (i / 20) as f64, 0.0])
            .filter(|p| !((3.4..5.6).contains(&p[0]) && (3.4..5.6).contains(&p[1])))
            .flatten()
            .collect();
        let s = DataSupport::new(&pts, 2.0);
        assert_eq!(s.radius, 1.0);
        assert_eq!(s.judge(&[4.5, 4.5, 0.0]), Support::Shallow, "the gap lies in the data's plane");
        assert_eq!(s.off_plane(&[4.5, 4.5, 1.2]), 1.2);
        assert_eq!(s.judge(&[4.5, 4.5, 0.4]), Support::Shallow, "0.4 off the plane");
        assert_eq!(s.judge(&[4.5, 4.5, 0.9]), Support::Raised, "0.9 off the plane");
        assert_eq!(s.judge(&[4.5, 4.5, 1.2]), Support::Off, "1.92 from the data, 1.2 off their plane");
        assert_eq!(s.judge(&[0.0, 0.0, 1.5]), Support::Off, "beside the grid's corner");
        assert_eq!(s.judge(&[4.5, 4.5, 2.0]), Support::Deep, "2.5 from the data");
        assert_eq!(s.judge(&[4.5, 3.0, 0.5]), Support::Near);
    }

    #[test]
    fn a_gap_as_wide_as_the_sparse_data_around_it_is_not_deep() {
        // a 20 x 20 grid of spacing 0.5 beside a 4 x 20 grid of spacing 3 in the plane z = 0:
        // radius 1 (the median spacing is the dense part's); the centre of a sparse cell lies
        // 2.12 from the data, beyond twice the radius, but within twice the local radius (6)
        let dense = (0..400).map(|i| [0.5 * (i % 20) as f64, 0.5 * (i / 20) as f64, 0.0]);
        let sparse = (0..80).map(|i| [12.0 + 3.0 * (i % 4) as f64, 3.0 * (i / 4) as f64 - 27.0, 0.0]);
        let pts: Vec<f64> = dense.chain(sparse).flatten().collect();
        let s = DataSupport::new(&pts, 2.0);
        assert_eq!(s.radius, 1.0);
        assert_eq!(s.judge(&[16.5, -10.5, 0.0]), Support::Shallow, "a gap of the sparse part");
        assert_eq!(s.judge(&[16.5, -10.5, 1.5]), Support::Off, "standing off the sparse part");
        assert_eq!(s.judge(&[16.5, -10.5, 13.0]), Support::Deep, "beyond twice the local radius");
        // between the parts the nearest data are dense: the radius decides
        assert_eq!(s.judge(&[4.75, 4.75, 2.5]), Support::Deep);
    }
}
