//! Planes that cut a triangle mesh into contours (`volspline slice`): parallel families and
//! turning ("fan") families, and the cut of a mesh by a list of planes into sections expressed in
//! each plane's own coordinates. Pure geometry.

use glam::{DMat3, DVec3};

use super::crossing::{crossings, COUNTED_PER_SLICE};
use super::format::Section;
use crate::error::{Error, Result};
use crate::mesh::{cut_by_plane, TriMesh};
use crate::spline::hygiene::{bounding_box, diagonal};

/// A family of cutting planes for `volspline slice`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PlaneFamily {
    /// `AXIS:N`: N planes perpendicular to the axis (0, 1, 2 = x, y, z), evenly spaced through the
    /// mesh's extent (half a spacing in from either end).
    Parallel { axis: usize, count: usize },
    /// `fan-AXIS:N`: N planes sweeping along the axis while turning about a hinge line parallel to
    /// the next axis (x -> y -> z -> x), one box extent away along the third: the angle between
    /// the first and the last plane is some tens of degrees and the spacing doubles across the
    /// mesh.
    Fan { axis: usize, count: usize },
}

impl std::fmt::Display for PlaneFamily {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let name = |a: usize| ["x", "y", "z"][a];
        match *self {
            PlaneFamily::Parallel { axis, count } => write!(f, "{}:{count}", name(axis)),
            PlaneFamily::Fan { axis, count } => write!(f, "fan-{}:{count}", name(axis)),
        }
    }
}

/// The most planes one family may have.
pub const MAX_PLANES: usize = 100_000;

impl PlaneFamily {
    pub fn parse(spec: &str) -> Result<Self> {
        let bad = || {
            Error::Usage(format!(
                "planes '{spec}': expected AXIS:N (parallel) or fan-AXIS:N (turning), AXIS x, y or z, N >= 2"
            ))
        };
        let (kind, n) = spec.split_once(':').ok_or_else(bad)?;
        let count: usize = n.trim().parse().map_err(|_| bad())?;
        if count < 2 {
            return Err(bad());
        }
        if count > MAX_PLANES {
            return Err(Error::Usage(format!(
                "planes '{spec}': {count} planes are more than {MAX_PLANES}, the most a contour file is \
                 cut with (each plane holds its cut in memory)"
            )));
        }
        let axis_of = |a: &str| match a {
            "x" => Ok(0),
            "y" => Ok(1),
            "z" => Ok(2),
            _ => Err(bad()),
        };
        match kind.trim().strip_prefix("fan-") {
            Some(a) => Ok(PlaneFamily::Fan { axis: axis_of(a)?, count }),
            None => Ok(PlaneFamily::Parallel { axis: axis_of(kind.trim())?, count }),
        }
    }

    /// The planes (origin, frame with columns u, v, normal) for a mesh with vertices `pts`.
    pub fn planes(&self, pts: &[[f64; 3]]) -> Vec<(DVec3, DMat3)> {
        let flat: Vec<f64> = pts.iter().flatten().copied().collect();
        let (lo, hi) = bounding_box(&flat, 3);
        let e = |i: usize| {
            let mut v = DVec3::ZERO;
            v[i] = 1.0;
            v
        };
        match *self {
            PlaneFamily::Parallel { axis, count } => {
                let (u, v) = (e((axis + 1) % 3), e((axis + 2) % 3));
                let frame = DMat3::from_cols(u, v, u.cross(v));
                (0..count)
                    .map(|k| {
                        let mut origin = DVec3::ZERO;
                        origin[axis] = lo[axis] + (k as f64 + 0.5) * (hi[axis] - lo[axis]) / count as f64;
                        (origin, frame)
                    })
                    .collect()
            }
            PlaneFamily::Fan { axis, count } => {
                let (s, h, d) = (axis, (axis + 1) % 3, (axis + 2) % 3);
                let ext_d = hi[d] - lo[d];
                let mut hinge = DVec3::ZERO;
                hinge[s] = 0.5 * (lo[s] + hi[s]);
                hinge[h] = 0.5 * (lo[h] + hi[h]);
                hinge[d] = lo[d] - ext_d;
                let angle = |p: &[f64; 3]| (p[s] - hinge[s]).atan2(p[d] - hinge[d]);
                let (amin, amax) = pts
                    .iter()
                    .map(angle)
                    .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| (a.min(x), b.max(x)));
                let radius = 1.5 * ext_d;
                (0..count)
                    .map(|k| {
                        let th = amin + (k as f64 + 0.5) * (amax - amin) / count as f64;
                        let (u, v) = (e(h), e(d) * th.cos() + e(s) * th.sin());
                        (hinge + v * radius, DMat3::from_cols(u, v, u.cross(v)))
                    })
                    .collect()
            }
        }
    }
}

/// What `volspline slice` wrote.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SliceSummary {
    pub planes: usize,
    pub slices: usize,
    pub contours: usize,
    pub points: usize,
    /// Chains that ended on holes of the mesh, joined end to nearest end into closed contours.
    pub joined: usize,
    /// Cuts dropped as one with their neighbour (a plane next to a vertex, or across a sliver).
    pub merged: usize,
    /// Places where the contours cross (where the mesh intersects itself, or where joining
    /// chains across holes could not avoid it), each slice's counted up to
    /// [`COUNTED_PER_SLICE`].
    pub crossings: usize,
    /// Contours without area left out (their points on one line: a cut through a sheet of the
    /// mesh with no volume on either side, or along a face lying in the plane).
    pub flat: usize,
    /// Planes between the first and the last slice that meet no mesh (where the mesh's parts lie
    /// apart along the family), and the first of them (1-based, 0 when none).
    pub gaps: usize,
    pub first_gap: usize,
    /// How the mesh was made fit for cutting (vertices joined, faces left out), filled in by the
    /// caller that made it so.
    pub indexing: crate::mesh::clean::Indexing,
}

/// A contour with less area than this fraction of its bounding box's diagonal squared has none:
/// its points lie on one line to rounding.
pub const FLAT_AREA: f64 = 1e-12;

/// The diagonal of the bounding box of points in a plane.
pub fn diagonal_2d(points: &[[f64; 2]]) -> f64 {
    let flat: Vec<f64> = points.iter().flatten().copied().collect();
    let (lo, hi) = bounding_box(&flat, 2);
    diagonal(&lo, &hi)
}

/// Whether a closed polygon in its plane's coordinates encloses no area ([`FLAT_AREA`]).
pub fn without_area(c: &[[f64; 2]]) -> bool {
    let diag2 = diagonal_2d(c).powi(2);
    // the shoelace sum about the first point, which keeps its terms small
    let area2: f64 = (1..c.len().saturating_sub(1))
        .map(|i| {
            let (a, b) =
                ([c[i][0] - c[0][0], c[i][1] - c[0][1]], [c[i + 1][0] - c[0][0], c[i + 1][1] - c[0][1]]);
            a[0] * b[1] - a[1] * b[0]
        })
        .sum();
    !(0.5 * area2.abs() > FLAT_AREA * diag2)
}

/// Closes the chains a plane cut that end on holes of the mesh: from the end of a chain, the
/// nearest free end, of another chain or its own start, is joined next, until the loop closes.
/// A plane that passes through one hole leaves one chain, closed across the hole by its own
/// ends; a plane through two holes leaves two chains, one on either side of the body between
/// the holes, whose ends lie pairwise at the holes. Each chain closed by its own ends would bridge
/// the body and the two contours would cross; joined at the nearest ends, they make the one
/// loop round the body that the mesh, its holes filled, would give.
fn join_open_chains(mut chains: Vec<Vec<[f64; 3]>>) -> Vec<Vec<[f64; 3]>> {
    let dist = |a: &[f64; 3], b: &[f64; 3]| (0..3).map(|d| (a[d] - b[d]).powi(2)).sum::<f64>();
    let mut loops = Vec::new();
    while let Some(mut cur) = chains.pop() {
        while let (Some(end), Some(start)) = (cur.last(), cur.first()) {
            let own = dist(end, start);
            // the nearest end of another chain: (distance, chain, joined at its last point)
            let best = chains
                .iter()
                .enumerate()
                .flat_map(|(i, c)| [(dist(end, &c[0]), i, false), (dist(end, &c[c.len() - 1]), i, true)])
                .min_by(|x, y| x.0.total_cmp(&y.0));
            match best {
                Some((d, i, reversed)) if d < own => {
                    let mut next = chains.swap_remove(i);
                    if reversed {
                        next.reverse();
                    }
                    cur.extend(next);
                }
                _ => break,
            }
        }
        loops.push(cur);
    }
    loops
}

/// Cuts `mesh` by `planes` into sections (planes that miss the mesh, or whose contours have no
/// area, give no slice).
pub fn slice_mesh(mesh: &TriMesh, planes: &[(DVec3, DMat3)]) -> (Vec<Section>, SliceSummary) {
    let mut summary = SliceSummary { planes: planes.len(), ..Default::default() };
    let mut sections = Vec::new();
    // the planes that gave a slice
    let mut met = Vec::new();
    for (k, (o, m)) in planes.iter().enumerate() {
        let cut = cut_by_plane(mesh, o.to_array(), m.z_axis.to_array());
        summary.joined += cut.open.len();
        summary.merged += cut.merged;
        let joined = join_open_chains(cut.open);
        let contours: Vec<Vec<[f64; 2]>> = cut
            .closed
            .iter()
            .chain(&joined)
            .filter(|c| c.len() >= 3)
            .map(|c| {
                c.iter()
                    .map(|p| {
                        let d = DVec3::from_array(*p) - *o;
                        [m.x_axis.dot(d), m.y_axis.dot(d)]
                    })
                    .collect()
            })
            .collect();
        let before = contours.len();
        let contours: Vec<Vec<[f64; 2]>> = contours.into_iter().filter(|c| !without_area(c)).collect();
        summary.flat += before - contours.len();
        if contours.is_empty() {
            continue;
        }
        met.push(k);
        summary.contours += contours.len();
        summary.points += contours.iter().map(Vec::len).sum::<usize>();
        let section = Section { line: 0, origin: *o, frame: *m, kind: "plane", contours };
        summary.crossings += crossings(&section, 0, COUNTED_PER_SLICE).1;
        sections.push(section);
    }
    summary.slices = sections.len();
    if let (Some(&first), Some(&last)) = (met.first(), met.last()) {
        summary.gaps = (last - first + 1) - met.len();
        summary.first_gap = met.windows(2).find(|w| w[1] > w[0] + 1).map_or(0, |w| w[0] + 2);
    }
    (sections, summary)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::contour::knots_of;

    #[test]
    fn chains_ending_on_holes_are_joined_at_their_nearest_ends() {
        // a circle cut open at two holes (at 0 and 180 degrees) into two arcs, the second
        // traced the other way round, and a third chain alone across a hole of its own
        let arc = |from: f64, to: f64| -> Vec<[f64; 3]> {
            (0..=16).map(|k| from + (to - from) * k as f64 / 16.0).map(|a| [a.cos(), a.sin(), 0.0]).collect()
        };
        let deg = std::f64::consts::PI / 180.0;
        let lone: Vec<[f64; 3]> =
            (0..=8).map(|k| [5.0 + (k as f64 * 0.7).cos(), (k as f64 * 0.7).sin(), 0.0]).collect();
        let loops =
            join_open_chains(vec![arc(10.0 * deg, 170.0 * deg), arc(350.0 * deg, 190.0 * deg), lone.clone()]);
        assert_eq!(loops.len(), 2);
        let circle = loops.iter().find(|l| l.len() == 34).expect("the two arcs in one loop");
        assert!(loops.contains(&lone), "the lone chain closed by its own ends");
        // one loop round the circle: its area is the polygon's, the points' order kept
        let area: f64 = (0..34)
            .map(|i| {
                let (p, q) = (circle[i], circle[(i + 1) % 34]);
                0.5 * (p[0] * q[1] - q[0] * p[1])
            })
            .sum();
        assert!((area.abs() - 3.1).abs() < 0.05, "{area}");
        let section = Section {
            line: 0,
            origin: DVec3::ZERO,
            frame: DMat3::IDENTITY,
            kind: "z",
            contours: loops.iter().map(|l| l.iter().map(|p| [p[0], p[1]]).collect()).collect(),
        };
        assert_eq!(crossings(&section, 0, 100).1, 0);
    }

    #[test]
    fn plane_families_parse_and_are_ordered() {
        for spec in ["z:40", "x:2", "fan-y:12", "fan-z:3"] {
            assert_eq!(PlaneFamily::parse(spec).unwrap().to_string(), spec);
        }
        for bad in ["z", "z:1", "w:4", "fan-:4", "fan-q:4", "y:x"] {
            assert!(PlaneFamily::parse(bad).is_err(), "{bad}");
        }
        let pts: Vec<[f64; 3]> = (0..200)
            .map(|i| {
                let a = i as f64 * 0.7;
                [a.cos(), (1.3 * a).sin(), (0.37 * a).cos() * 2.0]
            })
            .collect();
        for spec in ["z:10", "fan-z:10", "fan-x:7"] {
            let planes = PlaneFamily::parse(spec).unwrap().planes(&pts);
            let tau = knots_of(&planes);
            assert!(tau.windows(2).all(|w| w[1] > w[0]), "{spec}: ordered along the normals");
            for (_, m) in &planes {
                assert!((m.determinant() - 1.0).abs() < 1e-14);
            }
        }
        let fan = PlaneFamily::parse("fan-z:10").unwrap().planes(&pts);
        let turn = fan[0].1.z_axis.angle_between(fan[9].1.z_axis);
        assert!(turn > 0.3 && turn < 1.6, "{turn}");
    }
}
