//! Planes that cut a triangle mesh into contours (`volspline slice`): parallel families and
//! turning ("fan") families, and the cut of a mesh by a list of planes into sections expressed in
//! each plane's own coordinates. Pure geometry.

use glam::{DMat3, DVec3};

use super::format::Section;
use crate::error::{Error, Result};
use crate::mesh::{cut_by_plane, TriMesh};
use crate::spline::hygiene::bounding_box;

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
    /// Chains that ended on holes of the mesh and were closed by joining their ends.
    pub joined: usize,
}

/// Cuts `mesh` by `planes` into sections (planes that miss the mesh give no slice).
pub fn slice_mesh(mesh: &TriMesh, planes: &[(DVec3, DMat3)]) -> (Vec<Section>, SliceSummary) {
    let mut summary = SliceSummary { planes: planes.len(), ..Default::default() };
    let mut sections = Vec::new();
    for (o, m) in planes {
        let cut = cut_by_plane(mesh, o.to_array(), m.z_axis.to_array());
        summary.joined += cut.open.iter().filter(|c| c.len() >= 3).count();
        let contours: Vec<Vec<[f64; 2]>> = cut
            .closed
            .iter()
            .chain(&cut.open)
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
        if contours.is_empty() {
            continue;
        }
        summary.contours += contours.len();
        summary.points += contours.iter().map(Vec::len).sum::<usize>();
        sections.push(Section { line: 0, origin: *o, frame: *m, kind: "plane", contours });
    }
    summary.slices = sections.len();
    (sections, summary)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::contour::knots_of;

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
