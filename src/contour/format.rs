//! The plain-text contour file: reading (with the line number of every fault) and writing.
//!
//! ```text
//! # comment; blank lines are ignored; numbers are separated by spaces, tabs or commas
//! slice z 0.5                                  # a plane z = 0.5; points are (x, y)
//! contour                                      # a closed contour (last point joins the first)
//! 1.0 0.0
//! 0.0 1.0
//! -1.0 0.0
//! contour                                      # another contour in the same slice
//! ...
//! slice plane ox oy oz  ux uy uz  vx vy vz     # origin o and in-plane axes u, v: a point
//!                                              # (a, b) is o + a u + b v (axes of any length,
//!                                              # such as a pixel spacing, and not necessarily
//!                                              # orthogonal; the normal is along u x v)
//! slice omega w1 w2 w3  ox oy oz               # by angular velocities: this frame is
//!                                              # the previous one turned for one unit of the slice
//!                                              # parameter at angular velocity w (moving axes,
//!                                              # radians), integrated by RK4; origin o
//! ```
//!
//! Rules: at least two slices; every slice has at least one contour and every contour at least
//! three points; a point line must follow a `contour` line; the slices are ordered along their
//! normals (each plane in front of the previous one, by more than a millionth of the diagonal of
//! all contour points: closer slices are one slice given twice); neighbouring planes that are
//! not parallel meet on a line outside the contours of both (every point of a slice lies behind
//! the next plane and in front of the previous one); the first slice cannot be `omega`; the
//! contours' diagonal lies within [`SPREAD`].
//!
//! A `plane` slice's axes need not be orthonormal: the slice keeps the orthonormal frame of u and
//! of v's part orthogonal to u, and its points are taken to that frame's coordinates, a' =
//! (a u + b v) . u/|u| and b' likewise along the second axis, so each lies at o + a u + b v as
//! written. Axes orthonormal to 1e-12 are taken as they are, so a file this module wrote reads
//! back to the bit.

use std::fmt::Write as _;
use std::path::Path;

use glam::{DMat3, DVec3};

use super::orientation::{frame_from_axes, integrate_angular_velocity, RK4_STEPS};
use crate::error::{Error, Result};

/// One planar cross-section: its plane and its contours in the plane's coordinates.
#[derive(Debug, Clone, PartialEq)]
pub struct Section {
    /// The line of the file that opened the slice (1-based; 0 when not from a file).
    pub line: usize,
    pub origin: DVec3,
    /// Columns u, v, w (in-plane axes and normal), a rotation.
    pub frame: DMat3,
    /// How the frame was given, for the report: "z", "plane" or "omega".
    pub kind: &'static str,
    /// Closed contours, points (a, b) meaning origin + a u + b v.
    pub contours: Vec<Vec<[f64; 2]>>,
}

impl Section {
    /// The world position of the in-plane point (a, b).
    pub fn world(&self, p: [f64; 2]) -> DVec3 {
        self.origin + self.frame.x_axis * p[0] + self.frame.y_axis * p[1]
    }

    pub fn point_count(&self) -> usize {
        self.contours.iter().map(Vec::len).sum()
    }

    /// How far a slice with `frame` and `origin` lies in front of this one: the step between the
    /// origins along the mean of the two normals (the slices' order, and their spacing).
    pub fn gap_to(&self, frame: &DMat3, origin: DVec3) -> f64 {
        0.5 * (self.frame.z_axis + frame.z_axis).dot(origin - self.origin)
    }

    /// Signed distance of x from this plane (positive in front, along the normal).
    #[inline]
    pub fn signed_distance(&self, x: DVec3) -> f64 {
        self.frame.z_axis.dot(x - self.origin)
    }
}

/// Parses the text of a contour file; `path` is only used in error messages.
pub fn parse(path: &Path, text: &str) -> Result<Vec<Section>> {
    let err = |line: usize, why: String| Error::input(path, format!("line {line}"), why);
    let mut sections: Vec<Section> = Vec::new();
    // the current slice's map from the file's (a, b) to its orthonormal frame's coordinates
    let mut to_frame: Option<[[f64; 2]; 2]> = None;
    let mut last_line = 0;
    for (i, raw) in text.lines().enumerate() {
        let line = i + 1;
        last_line = line;
        let body = raw.split('#').next().unwrap_or("");
        let toks: Vec<&str> =
            body.split(|c: char| c.is_whitespace() || c == ',').filter(|t| !t.is_empty()).collect();
        if toks.is_empty() {
            continue;
        }
        // commas separate values: two with nothing between them (or one before the first value)
        // lost a value, which splitting would hide by reading the next one in its place
        let fields: Vec<&str> = body.split(',').collect();
        if fields[..fields.len() - 1].iter().any(|f| f.trim().is_empty()) {
            return Err(err(
                line,
                "an empty value between commas (or before the first one): a value is missing".into(),
            ));
        }
        let nums = |t: &[&str], what: &str| -> Result<Vec<f64>> {
            t.iter()
                .map(|s| match s.parse::<f64>() {
                    Ok(v) if v.is_finite() => Ok(v),
                    _ => Err(err(line, format!("'{s}' is not a finite number ({what})"))),
                })
                .collect()
        };
        match toks[0].to_ascii_lowercase().as_str() {
            "slice" => {
                if let Some(prev) = sections.last() {
                    check_complete(path, prev, line)?;
                }
                let kind = toks.get(1).map(|k| k.to_ascii_lowercase()).unwrap_or_default();
                let expect = |n: usize, form: &str| -> Result<Vec<f64>> {
                    if toks.len() != n + 2 {
                        return Err(err(
                            line,
                            format!("expected '{form}' ({n} numbers), got {} numbers", toks.len() - 2),
                        ));
                    }
                    nums(&toks[2..], form)
                };
                let (origin, frame, kind) = match kind.as_str() {
                    "z" => {
                        to_frame = None;
                        let v = expect(1, "slice z Z")?;
                        (DVec3::new(0.0, 0.0, v[0]), DMat3::IDENTITY, "z")
                    }
                    "plane" => {
                        let v = expect(9, "slice plane ox oy oz ux uy uz vx vy vz")?;
                        let (u, w) = (DVec3::new(v[3], v[4], v[5]), DVec3::new(v[6], v[7], v[8]));
                        let frame = frame_from_axes(u, w).ok_or_else(|| {
                            err(line, "the in-plane axes u and v are zero or parallel".into())
                        })?;
                        to_frame = axes_map(&frame, u, w);
                        (DVec3::new(v[0], v[1], v[2]), frame, "plane")
                    }
                    "omega" => {
                        to_frame = None;
                        let v = expect(6, "slice omega w1 w2 w3 ox oy oz")?;
                        let prev = sections.last().ok_or_else(|| {
                            err(line, "the first slice cannot be 'omega': angular velocities turn the previous frame".into())
                        })?;
                        let frame =
                            integrate_angular_velocity(&prev.frame, DVec3::new(v[0], v[1], v[2]), RK4_STEPS);
                        (DVec3::new(v[3], v[4], v[5]), frame, "omega")
                    }
                    other => {
                        return Err(err(
                            line,
                            format!("unknown slice kind '{other}' (expected z, plane or omega)"),
                        ))
                    }
                };
                if let Some(prev) = sections.last() {
                    if !(prev.gap_to(&frame, origin) > 0.0) {
                        return Err(err(
                            line,
                            format!(
                                "this slice is not in front of the previous one (line {}): slices must be ordered \
                                 along their normals",
                                prev.line
                            ),
                        ));
                    }
                }
                sections.push(Section { line, origin, frame, kind, contours: Vec::new() });
            }
            "contour" => {
                if toks.len() != 1 {
                    return Err(err(line, "'contour' takes no arguments".into()));
                }
                let s = sections
                    .last_mut()
                    .ok_or_else(|| err(line, "'contour' before any 'slice' line".into()))?;
                if let Some(c) = s.contours.last() {
                    if c.len() < 3 {
                        return Err(err(
                            line,
                            format!("the previous contour has {} point(s); at least 3 are needed", c.len()),
                        ));
                    }
                }
                s.contours.push(Vec::new());
            }
            _ => {
                let v = nums(&toks, "a point is 'a b'")?;
                if v.len() != 2 {
                    return Err(err(
                        line,
                        format!("a point has 2 coordinates in its plane, got {}", v.len()),
                    ));
                }
                let s =
                    sections.last_mut().ok_or_else(|| err(line, "a point before any 'slice' line".into()))?;
                let opened = s.line;
                let c = s.contours.last_mut().ok_or_else(|| {
                    err(line, format!("a point before any 'contour' line of the slice of line {opened}"))
                })?;
                c.push(match to_frame {
                    Some([r0, r1]) => [r0[0] * v[0] + r0[1] * v[1], r1[0] * v[0] + r1[1] * v[1]],
                    None => [v[0], v[1]],
                });
            }
        }
    }
    match sections.last() {
        None => return Err(Error::input(path, "", "no slices: the file has no 'slice' line")),
        Some(s) => check_complete(path, s, last_line + 1)?,
    }
    if sections.len() < 2 {
        return Err(Error::input(
            path,
            format!("line {}", sections[0].line),
            "only one slice: at least two are needed",
        ));
    }
    check_apart(path, &sections)?;
    check_planes_clear(path, &sections)?;
    Ok(sections)
}

/// The map from a `plane` slice's coordinates (a, b) along the axes `u`, `v` as written to those
/// of its orthonormal `frame` (rows: a' and b' as combinations of a and b); None when the axes
/// are orthonormal to 1e-12 already.
fn axes_map(frame: &DMat3, u: DVec3, v: DVec3) -> Option<[[f64; 2]; 2]> {
    let map = [[frame.x_axis.dot(u), frame.x_axis.dot(v)], [frame.y_axis.dot(u), frame.y_axis.dot(v)]];
    let off = (map[0][0] - 1.0).abs().max(map[0][1].abs()).max(map[1][0].abs()).max((map[1][1] - 1.0).abs());
    (off > 1e-12).then_some(map)
}

/// The range of the contours' diagonal the model represents: its capped ends take products of
/// lengths to the fourth power (the sections' values are lengths squared, and the caps square
/// them again), which stay within double precision's range for diagonals from 1e-60 to 1e60.
/// Beyond, the caps underflow (the solid runs on past its end slices) or overflow.
pub const SPREAD: (f64, f64) = (1e-60, 1e60);

/// Refuses neighbouring slices whose planes meet within the contours: between two planes that
/// are not parallel the solid is interpolated as the plane turns about the line where they meet,
/// and a point is placed between them by its signs with respect to both, so a contour point in
/// front of the next plane (or behind the previous one) would be classed beyond its own slice
/// and that part of the contour lost.
fn check_planes_clear(path: &Path, sections: &[Section]) -> Result<()> {
    for pair in sections.windows(2) {
        let (prev, next) = (&pair[0], &pair[1]);
        let ahead: Vec<[f64; 2]> = prev
            .contours
            .iter()
            .flatten()
            .filter(|p| !(next.signed_distance(prev.world(**p)) < 0.0))
            .copied()
            .collect();
        let behind: Vec<[f64; 2]> = next
            .contours
            .iter()
            .flatten()
            .filter(|p| !(prev.signed_distance(next.world(**p)) > 0.0))
            .copied()
            .collect();
        let (count, first, whose, side) = match (ahead.first(), behind.first()) {
            (Some(p), _) => (ahead.len(), p, prev.line, "on or in front of this slice's plane"),
            (None, Some(p)) => (behind.len(), p, next.line, "on or behind the previous slice's plane"),
            (None, None) => continue,
        };
        return Err(Error::input(
            path,
            format!("line {}", next.line),
            format!(
                "this slice's plane crosses the previous one (line {}) within the contours: {count} point(s) \
                 of the slice of line {whose} lie {side} (the first at ({}, {})). Between two planes that are \
                 not parallel the solid turns about the line where they meet, which must pass outside the \
                 contours of both; add slices between them or turn them less",
                prev.line, first[0], first[1]
            ),
        ));
    }
    Ok(())
}

/// Slices closer than this fraction of the diagonal of all contour points are refused as the
/// same slice given twice.
pub const MIN_GAP: f64 = 1e-6;

/// Refuses a slice that lies within [`MIN_GAP`] of the contours' diagonal in front of the
/// previous one: a section repeated (a file concatenated with itself, a slice exported twice
/// with rounding). Parallel slices are interpolated between as if the gap were real, so a gap
/// of rounding size changes the cubic interpolation everywhere (its weights are fitted through
/// both copies) while saying nothing; the gap is measured as where the slices are ordered, at
/// the origins along the mean normal.
fn check_apart(path: &Path, sections: &[Section]) -> Result<()> {
    let (mut lo, mut hi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
    for s in sections {
        for p in s.contours.iter().flatten() {
            let x = s.world(*p);
            lo = lo.min(x);
            hi = hi.max(x);
        }
    }
    let diagonal = crate::spline::hygiene::diagonal(&lo.to_array(), &hi.to_array());
    if !(diagonal.is_finite() && diagonal >= SPREAD.0 && diagonal <= SPREAD.1) {
        let reach = lo.abs().max(hi.abs()).max_element();
        return Err(Error::input(
            path,
            "",
            format!(
                "the contours' extent is not representable: their diagonal is {diagonal:e} (coordinates up to \
                 {reach:e}), outside {:e} to {:e}, where the capped ends' products of lengths to the fourth \
                 power stay within double precision; rescale the coordinates",
                SPREAD.0, SPREAD.1
            ),
        ));
    }
    for pair in sections.windows(2) {
        let (prev, s) = (&pair[0], &pair[1]);
        let gap = prev.gap_to(&s.frame, s.origin);
        if gap < MIN_GAP * diagonal {
            return Err(Error::input(
                path,
                format!("line {}", s.line),
                format!(
                    "this slice lies only {gap:.3e} in front of the previous one (line {}), {:.1e} of the \
                     contours' diagonal {diagonal:.3e}: the same slice given twice? Slices closer than {MIN_GAP:e} \
                     of the diagonal are refused, since the interpolation between them would rest on rounding; \
                     remove one of them",
                    prev.line,
                    gap / diagonal
                ),
            ));
        }
    }
    Ok(())
}

/// Checks the slice that ends before `line`.
fn check_complete(path: &Path, s: &Section, line: usize) -> Result<()> {
    let at = format!("line {line}");
    if s.contours.is_empty() {
        return Err(Error::input(path, at, format!("the slice of line {} has no contour", s.line)));
    }
    if let Some(c) = s.contours.iter().find(|c| c.len() < 3) {
        return Err(Error::input(
            path,
            at,
            format!(
                "a contour of the slice of line {} has {} point(s); at least 3 are needed",
                s.line,
                c.len()
            ),
        ));
    }
    Ok(())
}

/// Reads and parses a contour file.
pub fn read(path: &Path) -> Result<Vec<Section>> {
    crate::io::staging::note_input(path);
    parse(path, &crate::io::text::read(path, "contour")?)
}

/// The text of a contour file holding `sections`; every slice is written as `slice plane` (or
/// `slice z` when its frame is the identity), with full precision.
pub fn to_text(sections: &[Section], header: &str) -> String {
    let mut s = String::new();
    for l in header.lines() {
        let _ = writeln!(s, "# {l}");
    }
    for sec in sections {
        if sec.frame == DMat3::IDENTITY && sec.origin.x == 0.0 && sec.origin.y == 0.0 {
            let _ = writeln!(s, "slice z {:?}", sec.origin.z);
        } else {
            let (o, u, v) = (sec.origin, sec.frame.x_axis, sec.frame.y_axis);
            let _ = writeln!(
                s,
                "slice plane {:?} {:?} {:?}  {:?} {:?} {:?}  {:?} {:?} {:?}",
                o.x, o.y, o.z, u.x, u.y, u.z, v.x, v.y, v.z
            );
        }
        for c in &sec.contours {
            s.push_str("contour\n");
            for p in c {
                let _ = writeln!(s, "{:?} {:?}", p[0], p[1]);
            }
        }
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    const GOOD: &str = "# two squares\nslice z 0\ncontour\n0 0\n1 0\n1 1\n0 1\n\nslice z 1.5  # above\ncontour\n0,0\n1,0\n1,1\n\
                        slice plane 0 0 2  1 0 0  0 1 0\ncontour\n0 0\n1 0\n1 1\nslice omega 0 0 0.1  0 0 3\ncontour\n0 0\n2 0\n0 2\n";

    #[test]
    fn a_good_file_parses_and_round_trips() {
        let p = Path::new("a.txt");
        let s = parse(p, GOOD).unwrap();
        assert_eq!(s.len(), 4);
        assert_eq!(s[0].contours[0].len(), 4);
        assert_eq!(s[1].origin.z, 1.5);
        assert_eq!(s[2].kind, "plane");
        assert_eq!(s[3].line, 19);
        // omega about the normal: the frame turned by 0.1 rad about z
        assert!((s[3].frame.x_axis.y - 0.1f64.sin()).abs() < 1e-12);
        let again = parse(p, &to_text(&s, "round trip")).unwrap();
        for (a, b) in s.iter().zip(&again) {
            assert_eq!(a.contours, b.contours);
            assert!((a.frame.x_axis - b.frame.x_axis).length() < 1e-15 && a.origin == b.origin);
        }
    }

    #[test]
    fn plane_axes_of_any_length_place_points_at_o_plus_a_u_plus_b_v() {
        let p = Path::new("axes.txt");
        // u twice a unit long, v sheared: (a, b) = (1, 1) is o + u + v = (3, 1, 0) + o
        let text =
            "slice z 0\ncontour\n0 0\n1 0\n1 1\nslice plane 0 0 1  2 0 0  1 1 0\ncontour\n0 0\n1 0\n1 1\n";
        let s = parse(p, text).unwrap();
        let world: Vec<DVec3> = s[1].contours[0].iter().map(|q| s[1].world(*q)).collect();
        for (got, want) in world.iter().zip([
            DVec3::new(0.0, 0.0, 1.0),
            DVec3::new(2.0, 0.0, 1.0),
            DVec3::new(3.0, 1.0, 1.0),
        ]) {
            assert!((*got - want).length() < 1e-14, "{got} against {want}");
        }
        // orthonormal axes keep the points' bits
        let unit = "slice z 0\ncontour\n0 0\n1 0\n1 1\nslice plane 0 0 1  0.6 0.8 0  -0.8 0.6 0\ncontour\n0.1 0.2\n1 0\n1 1\n";
        assert_eq!(parse(p, unit).unwrap()[1].contours[0][0], [0.1, 0.2]);
    }

    #[test]
    fn faults_name_their_line() {
        let p = Path::new("bad.txt");
        let cases = [
            ("slice z 0\ncontour\n0 0\n1 0\n0 x\n", "line 5", "not a finite number"),
            ("slice z 0\n0 0\n", "line 2", "before any 'contour' line of the slice of line 1"),
            ("0 0\n", "line 1", "before any 'slice' line"),
            ("slice z 0\ncontour\n1,,0\n", "line 3", "an empty value between commas"),
            // a plane turned 60 degrees about the line x = 0.5 of the square below: through it
            (
                "slice z 0\ncontour\n0 0\n1 0\n1 1\n0 1\nslice plane 1 0 0.8660254037844386  0.5 0 0.8660254037844386  0 1 0\n\
                 contour\n-0.5 0\n0.5 0\n0.5 1\n-0.5 1\n",
                "line 7",
                "crosses the previous one (line 1) within the contours: 2 point(s) of the slice of line 1",
            ),
            (
                "slice z 0\ncontour\n0 0\n1e-100 0\n1e-100 1e-100\nslice z 1e-100\ncontour\n0 0\n1e-100 0\n1e-100 1e-100\n",
                "",
                "not representable: their diagonal is 1.7",
            ),
            (
                "slice z 0\ncontour\n0 0\n1e200 0\n1e200 1e200\nslice z 1e200\ncontour\n0 0\n1e200 0\n1e200 1e200\n",
                "",
                "not representable",
            ),
            ("slice q 0\n", "line 1", "unknown slice kind"),
            ("slice z 0\ncontour\n0 0\n1 0\ncontour\n", "line 5", "at least 3"),
            (
                "slice z 0\ncontour\n0 0\n1 0\n1 1\nslice z -1\ncontour\n0 0\n1 0\n1 1\n",
                "line 6",
                "not in front",
            ),
            ("slice plane 0 0 0 1 0 0 2 0 0\n", "line 1", "parallel"),
            ("slice omega 0 0 1 0 0 0\n", "line 1", "first slice"),
            ("slice z 0\ncontour\n0 0\n1 0\n1 1\n", "line 1", "only one slice"),
            ("slice z 0\ncontour\n0 0 1\n", "line 3", "2 coordinates"),
            ("slice z 0 1\n", "line 1", "1 numbers"),
            ("slice z 0\nslice z 1\n", "line 2", "no contour"),
            ("# nothing\n", "", "no slices"),
            ("slice z inf\n", "line 1", "finite"),
            (
                "slice z 0\ncontour\n0 0\n1 0\n1 1\nslice z 1e-7\ncontour\n0 0\n1 0\n1 1\n",
                "line 6",
                "given twice",
            ),
        ];
        // a millionth of the diagonal is the limit: 1e-5 of it apart still parses
        let near = "slice z 0\ncontour\n0 0\n1 0\n1 1\nslice z 1.5e-5\ncontour\n0 0\n1 0\n1 1\n";
        assert_eq!(parse(p, near).unwrap().len(), 2);
        for (text, at, why) in cases {
            match parse(p, text) {
                Err(Error::Input { location, reason, .. }) => {
                    assert_eq!(location, at, "{text:?}: {reason}");
                    assert!(reason.contains(why), "{text:?}: {reason}");
                }
                other => panic!("{text:?}: {other:?}"),
            }
        }
    }
}
