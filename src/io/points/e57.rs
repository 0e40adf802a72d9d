//! E57 (ASTM E2807), the exchange format of terrestrial laser scanners, read with the `e57` crate.
//! Every point cloud of the file (each scan, one per scanner station) is read and placed in the
//! file's common coordinates by its pose: the unit quaternion (w, x, y, z) rotates the scan's own
//! coordinates and the translation then moves them, world = R(q) local + t. A scan without a pose
//! is in the common coordinates already. A scan's coordinates are Cartesian (x, y, z) or
//! spherical (range r, azimuth a, elevation e, turned into x = r cos e cos a, y = r cos e sin a,
//! z = r sin e before the pose); where a scan holds both, a point's Cartesian coordinates are taken,
//! or its spherical ones where the Cartesian are invalid.
//!
//! A point whose invalid state is not 0 (`cartesianInvalidState` or `sphericalInvalidState` 1: a
//! direction without a range, 2: no coordinates), or whose x, y and z are all NaN, is a pulse
//! without a return: such points are left out and counted in the note, which also says how many
//! scans were read. Colour, intensity, row and column indices, time stamps and images are not
//! read.
//!
//! Refused, with the reason: a file without the `ASTM-E57` signature or shorter than its 48-byte
//! header; a version or page size other than E57 1.0's 1024 bytes; a page whose CRC-32C checksum
//! fails or a file cut short (not a whole number of pages); XML that does not parse; a file
//! without point clouds (images only); a scan with neither three Cartesian nor three spherical
//! coordinate fields (named by its number and name); a pose that is not a rotation (a quaternion
//! whose length is not 1, or a coordinate that is not finite); a point whose coordinates are not
//! finite. Errors in a scan name it by its number from 1 and its name, `scan 2 ('station 2')`, and
//! the point by its index in the scan from 0.

use std::io::Cursor;
use std::path::Path;

use e57::{RecordName, RecordValue};

use super::{capacity, check_finite, no_return, PointSet};
use crate::error::{Error, Result};

/// The file's first bytes.
const SIGNATURE: &[u8] = b"ASTM-E57";

/// The length of the file header (signature, version, lengths, XML offset, page size).
const HEADER: usize = 48;

/// How far the pose's quaternion may be from unit length (files store it in decimal text, often
/// with single precision) before it is refused as not a rotation; within this it is normalised.
const UNIT_TOLERANCE: f64 = 1e-4;

pub(super) fn parse(path: &Path, bytes: &[u8]) -> Result<PointSet> {
    let err = |at: &str, reason: String| Error::input(path, at, reason);
    if !bytes.starts_with(SIGNATURE) {
        let why = if bytes.is_empty() { "an empty file" } else { "no 'ASTM-E57' signature at the start" };
        return Err(err("", format!("{why}; not an E57 file")));
    }
    if bytes.len() < HEADER {
        return Err(err("", format!("{} bytes: shorter than an E57 header ({HEADER} bytes)", bytes.len())));
    }
    let mut file = e57::E57Reader::new(Cursor::new(bytes))
        .map_err(|e| err("", format!("not a readable E57 file ({}): {e}", damage(&e))))?;
    let clouds = file.pointclouds();
    if clouds.is_empty() {
        let images = file.images().len();
        let what = if images > 0 { format!(" ({images} image(s) only)") } else { String::new() };
        return Err(err("", format!("no point clouds (scans) in the file{what}")));
    }
    let mut set = PointSet::default();
    // the counts the XML declares, believed only as far as the file could hold them: three
    // coordinates take some 4 bytes at the least (bit-packed integers of a few millimetres over a
    // few metres); more points than that only make the list grow as it fills
    let declared = clouds.iter().fold(0u64, |n, pc| n.saturating_add(pc.records));
    set.points.reserve(capacity(declared.try_into().unwrap_or(usize::MAX), bytes.len(), 4));
    let (mut spherical_scans, mut missing, mut first_missing) = (0, 0u64, None);
    for (k, pc) in clouds.iter().enumerate() {
        let scan = scan_name(k, pc);
        let cartesian = Coordinates::find(pc, CARTESIAN, RecordName::CartesianInvalidState);
        let spherical = Coordinates::find(pc, SPHERICAL, RecordName::SphericalInvalidState);
        if cartesian.is_none() && spherical.is_none() {
            let fields: Vec<String> = pc.prototype.iter().map(|r| format!("{:?}", r.name)).collect();
            return Err(err(
                &scan,
                format!(
                    "no coordinates: neither cartesianX, cartesianY, cartesianZ nor sphericalRange, \
                     sphericalAzimuth, sphericalElevation among the fields ({})",
                    fields.join(", ")
                ),
            ));
        }
        if cartesian.is_none() {
            spherical_scans += 1;
        }
        let pose = Pose::of(pc).map_err(|why| err(&scan, why))?;
        // the crate's raw reader: its simple one stops at a data packet that leaves a field's values
        // for the next packet (as the crate's writer does for the 2-bit invalid state of a scan of
        // fewer than 4 points), which the raw one reads on past
        let points = file
            .pointcloud_raw(pc)
            .map_err(|e| err(&scan, format!("cannot read the points ({}): {e}", damage(&e))))?;
        for (i, values) in points.enumerate() {
            let at = || format!("{scan}, point {i}");
            let local = values
                .and_then(|values| {
                    if let Some(p) = cartesian.as_ref().map(|c| c.of(pc, &values)).transpose()?.flatten() {
                        return Ok(Some(p));
                    }
                    let rae = spherical.as_ref().map(|c| c.of(pc, &values)).transpose()?.flatten();
                    Ok(rae.map(|[r, a, e]| [r * e.cos() * a.cos(), r * e.cos() * a.sin(), r * e.sin()]))
                })
                .map_err(|e| err(&at(), format!("unreadable ({}): {e}", damage(&e))))?;
            match local {
                Some(p) if !no_return(&p) => {
                    set.points.push(check_finite(pose.apply(p)).map_err(|why| err(&at(), why))?)
                }
                _ => {
                    missing += 1;
                    first_missing.get_or_insert_with(at);
                }
            }
        }
    }
    let mut note = format!(
        "E57, {} scan(s) read{}, each placed by its pose: {} points",
        clouds.len(),
        if spherical_scans > 0 {
            format!(" ({spherical_scans} in spherical coordinates)")
        } else {
            String::new()
        },
        set.points.len()
    );
    if let Some(first) = first_missing {
        note.push_str(&format!(
            "; {missing} point(s) without a return (invalid state 1 or 2, or x, y and z all NaN) left out, the \
             first at {first}"
        ));
    }
    if set.points.is_empty() {
        return Err(err("", format!("no points ({note})")));
    }
    set.note = Some(note);
    Ok(set)
}

const CARTESIAN: [RecordName; 3] = [RecordName::CartesianX, RecordName::CartesianY, RecordName::CartesianZ];

const SPHERICAL: [RecordName; 3] =
    [RecordName::SphericalRange, RecordName::SphericalAzimuth, RecordName::SphericalElevation];

/// Where a scan's three coordinates of one kind and their invalid state are among its fields.
struct Coordinates {
    fields: [usize; 3],
    state: Option<usize>,
}

impl Coordinates {
    fn find(pc: &e57::PointCloud, names: [RecordName; 3], state: RecordName) -> Option<Coordinates> {
        let at = |name: &RecordName| pc.prototype.iter().position(|r| &r.name == name);
        let [a, b, c] = names.each_ref().map(at);
        Some(Coordinates { fields: [a?, b?, c?], state: at(&state) })
    }

    /// The point's three coordinates, or None where its invalid state is not 0.
    fn of(&self, pc: &e57::PointCloud, values: &[RecordValue]) -> e57::Result<Option<[f64; 3]>> {
        let proto = &pc.prototype;
        if let Some(s) = self.state {
            if values[s].to_i64(&proto[s].data_type)? != 0 {
                return Ok(None);
            }
        }
        let [a, b, c] = self.fields.map(|i| values[i].to_f64(&proto[i].data_type));
        Ok(Some([a?, b?, c?]))
    }
}

/// What an error of the `e57` crate most likely means, in a few words before its own message.
fn damage(e: &e57::Error) -> &'static str {
    let text = e.to_string();
    if text.contains("checksum") {
        "corrupt: a page fails its CRC checksum"
    } else if text.contains("truncated") || text.contains("end of file") {
        "truncated?"
    } else {
        "corrupt?"
    }
}

/// How errors name a scan: its number from 1 and its name where it has one.
fn scan_name(k: usize, pc: &e57::PointCloud) -> String {
    match pc.name.as_deref().map(str::trim).filter(|n| !n.is_empty()) {
        Some(name) => format!("scan {} ('{name}')", k + 1),
        None => format!("scan {}", k + 1),
    }
}

/// A scan's pose: the rotation matrix of its unit quaternion and its translation.
struct Pose {
    rotation: [[f64; 3]; 3],
    translation: [f64; 3],
}

impl Pose {
    fn of(pc: &e57::PointCloud) -> std::result::Result<Pose, String> {
        let Some(t) = &pc.transform else {
            return Ok(Pose {
                rotation: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
                translation: [0.0; 3],
            });
        };
        let q = [t.rotation.w, t.rotation.x, t.rotation.y, t.rotation.z];
        let translation = [t.translation.x, t.translation.y, t.translation.z];
        let norm = q.iter().map(|c| c * c).sum::<f64>().sqrt();
        if !(q.iter().chain(&translation).all(|c| c.is_finite()) && (norm - 1.0).abs() <= UNIT_TOLERANCE) {
            return Err(format!(
                "the pose is not a rotation and a translation: quaternion (w, x, y, z) = ({}, {}, {}, {}) \
                 of length {norm} (a unit quaternion is needed), translation ({}, {}, {})",
                q[0], q[1], q[2], q[3], translation[0], translation[1], translation[2]
            ));
        }
        let [w, x, y, z] = q.map(|c| c / norm);
        let rotation = [
            [1.0 - 2.0 * (y * y + z * z), 2.0 * (x * y - w * z), 2.0 * (x * z + w * y)],
            [2.0 * (x * y + w * z), 1.0 - 2.0 * (x * x + z * z), 2.0 * (y * z - w * x)],
            [2.0 * (x * z - w * y), 2.0 * (y * z + w * x), 1.0 - 2.0 * (x * x + y * y)],
        ];
        Ok(Pose { rotation, translation })
    }

    fn apply(&self, p: [f64; 3]) -> [f64; 3] {
        let r = &self.rotation;
        std::array::from_fn(|d| r[d][0] * p[0] + r[d][1] * p[1] + r[d][2] * p[2] + self.translation[d])
    }
}

#[cfg(test)]
mod tests {
    use super::super::read_points;
    use super::super::testutil::{fails_with, TempDir};
    use e57::{E57Writer, Quaternion, Record, RecordValue, Transform, Translation};
    use std::path::PathBuf;

    /// A scan to write: Cartesian (x, y, z) or spherical (range, azimuth, elevation) points, each
    /// with its invalid state (0 valid, 1 direction only, 2 none), and a pose.
    struct Scan {
        spherical: bool,
        points: Vec<([f64; 3], i64)>,
        pose: Option<([f64; 4], [f64; 3])>,
    }

    /// Writes `scans` with the `e57` crate's writer as `name` in `dir`; `xml` may edit the XML
    /// section before it is written.
    fn write(dir: &TempDir, name: &str, scans: &[Scan], xml: impl Fn(String) -> String) -> PathBuf {
        let path = dir.0.join(name);
        let mut w = E57Writer::from_file(&path, "file-guid").unwrap();
        for (k, scan) in scans.iter().enumerate() {
            let prototype = if scan.spherical {
                vec![
                    Record::SPHERICAL_RANGE_F64,
                    Record::SPHERICAL_AZIMUTH_F64,
                    Record::SPHERICAL_ELEVATION_F64,
                    Record::SPHERICAL_INVALID_STATE,
                ]
            } else {
                vec![
                    Record::CARTESIAN_X_F64,
                    Record::CARTESIAN_Y_F64,
                    Record::CARTESIAN_Z_F64,
                    Record::CARTESIAN_INVALID_STATE,
                ]
            };
            let mut pc = w.add_pointcloud(&format!("scan-guid-{k}"), prototype).unwrap();
            pc.set_name(Some(format!("station {}", k + 1)));
            pc.set_transform(scan.pose.map(|(q, t)| Transform {
                rotation: Quaternion { w: q[0], x: q[1], y: q[2], z: q[3] },
                translation: Translation { x: t[0], y: t[1], z: t[2] },
            }));
            for &(p, state) in &scan.points {
                let mut values: Vec<RecordValue> = p.iter().map(|&c| RecordValue::Double(c)).collect();
                values.push(RecordValue::Integer(state));
                pc.add_point(values).unwrap();
            }
            pc.finalize().unwrap();
        }
        w.finalize_customized_xml(|s| Ok(xml(s))).unwrap();
        path
    }

    fn cartesian(points: &[[f64; 3]], pose: Option<([f64; 4], [f64; 3])>) -> Scan {
        Scan { spherical: false, points: points.iter().map(|&p| (p, 0)).collect(), pose }
    }

    const SQUARE: [[f64; 3]; 4] = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];

    #[test]
    fn every_scan_is_read_and_placed_by_its_pose() {
        let dir = TempDir::new();
        // the quaternion (1/2, 1/2, 1/2, 1/2) turns by 120 degrees about (1, 1, 1): (x, y, z) goes
        // to (z, x, y), exactly in binary
        let first = Scan {
            spherical: false,
            points: vec![
                ([1.0, 2.0, 3.0], 0),
                ([9.0, 9.0, 9.0], 2),
                ([-0.25, 0.5, 1e-3], 0),
                ([0.6, 0.8, 0.0], 1),
                ([4.0, -5.0, 6.5], 0),
            ],
            pose: Some(([0.5, 0.5, 0.5, 0.5], [10.0, -20.0, 0.5])),
        };
        let (az, el) = (0.3f64, -0.2f64);
        let second = Scan {
            spherical: true,
            points: vec![
                ([2.0, 0.0, 0.0], 0),
                ([0.0, 1.0, 0.5], 2),
                ([3.0, az, el], 0),
                ([0.0, -1.0, 0.25], 1),
                ([1.5, 0.0, std::f64::consts::FRAC_PI_2], 0),
            ],
            pose: Some(([1.0, 0.0, 0.0, 0.0], [100.0, 200.0, 300.0])),
        };
        let path = write(&dir, "two.e57", &[first, second], |s| s);
        let set = read_points(&path).unwrap();
        let sph = |r: f64, a: f64, e: f64| {
            [r * e.cos() * a.cos() + 100.0, r * e.cos() * a.sin() + 200.0, r * e.sin() + 300.0]
        };
        let want = vec![
            [13.0, -19.0, 2.5],
            [1e-3 + 10.0, -20.25, 1.0],
            [16.5, -16.0, -4.5],
            [102.0, 200.0, 300.0],
            sph(3.0, az, el),
            sph(1.5, 0.0, std::f64::consts::FRAC_PI_2),
        ];
        assert_eq!(set.points, want);
        assert!(set.triangles.is_empty());
        assert_eq!(
            set.note.unwrap(),
            "E57, 2 scan(s) read (1 in spherical coordinates), each placed by its pose: 6 points; 4 point(s) \
             without a return (invalid state 1 or 2, or x, y and z all NaN) left out, the first at scan 1 \
             ('station 1'), point 1"
        );
    }

    #[test]
    fn cartesian_coordinates_are_taken_before_spherical_ones() {
        let dir = TempDir::new();
        let path = dir.0.join("both.e57");
        let mut w = E57Writer::from_file(&path, "file-guid").unwrap();
        let prototype = vec![
            Record::CARTESIAN_X_F64,
            Record::CARTESIAN_Y_F64,
            Record::CARTESIAN_Z_F64,
            Record::CARTESIAN_INVALID_STATE,
            Record::SPHERICAL_RANGE_F64,
            Record::SPHERICAL_AZIMUTH_F64,
            Record::SPHERICAL_ELEVATION_F64,
            Record::SPHERICAL_INVALID_STATE,
        ];
        let mut pc = w.add_pointcloud("scan-guid", prototype).unwrap();
        // (Cartesian, its state, spherical, its state): the spherical coordinates are used only
        // where the Cartesian ones are invalid
        let rows: [([f64; 3], i64, [f64; 3], i64); 6] = [
            ([1.0, 2.0, 3.0], 0, [50.0, 0.0, 0.0], 0),
            ([9.0, 9.0, 9.0], 2, [4.0, 0.0, 0.0], 0),
            ([9.0, 9.0, 9.0], 1, [5.0, 0.0, 0.0], 0),
            ([9.0, 9.0, 9.0], 2, [6.0, 0.0, 0.0], 2),
            ([0.5, 0.25, 0.0], 0, [0.0, 0.0, 0.0], 2),
            ([-1.0, 0.0, 2.0], 0, [0.0, 0.0, 0.0], 0),
        ];
        for (c, cs, sph, ss) in rows {
            let mut values: Vec<RecordValue> = c.iter().map(|&v| RecordValue::Double(v)).collect();
            values.push(RecordValue::Integer(cs));
            values.extend(sph.iter().map(|&v| RecordValue::Double(v)));
            values.push(RecordValue::Integer(ss));
            pc.add_point(values).unwrap();
        }
        pc.finalize().unwrap();
        w.finalize().unwrap();
        let set = read_points(&path).unwrap();
        let want = [[1.0, 2.0, 3.0], [4.0, 0.0, 0.0], [5.0, 0.0, 0.0], [0.5, 0.25, 0.0], [-1.0, 0.0, 2.0]];
        assert_eq!(set.points, want);
        let note = set.note.unwrap();
        assert!(
            note.starts_with("E57, 1 scan(s) read, each placed by its pose: 5 points; 1 point(s)"),
            "{note}"
        );
        assert!(note.ends_with("the first at scan 1, point 3"), "{note}");
    }

    #[test]
    fn a_general_pose_is_a_rotation_then_a_translation() {
        let dir = TempDir::new();
        // a unit quaternion about a skew axis, checked against q p q* computed with quaternion
        // products; a quaternion off unit length by 1e-6 is normalised
        let (half, axis) = (0.4f64, [2.0f64, -1.0, 0.5]);
        let len = axis.iter().map(|a| a * a).sum::<f64>().sqrt();
        let q =
            [half.cos(), half.sin() * axis[0] / len, half.sin() * axis[1] / len, half.sin() * axis[2] / len];
        let t = [0.5, -3.0, 7.25];
        let mul = |a: [f64; 4], b: [f64; 4]| {
            [
                a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3],
                a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2],
                a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1],
                a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0],
            ]
        };
        let pts = [[1.0, 2.0, 3.0], [-4.0, 0.5, 2.0], [0.0, 0.0, 0.0], [7.0, -1.0, -2.5]];
        for scale in [1.0, 1.0 + 1e-6] {
            let path = write(&dir, "pose.e57", &[cartesian(&pts, Some((q.map(|c| c * scale), t)))], |s| s);
            let set = read_points(&path).unwrap();
            for (got, p) in set.points.iter().zip(&pts) {
                let r = mul(mul(q, [0.0, p[0], p[1], p[2]]), [q[0], -q[1], -q[2], -q[3]]);
                for d in 0..3 {
                    assert!((got[d] - (r[d + 1] + t[d])).abs() < 1e-13, "{got:?} {r:?} scale {scale}");
                }
            }
        }
        // a scan without a pose stays where it is
        let path = write(&dir, "plain.e57", &[cartesian(&pts, None)], |s| s);
        assert_eq!(read_points(&path).unwrap().points, pts);
    }

    #[test]
    fn poses_that_are_not_rotations_are_refused() {
        let dir = TempDir::new();
        for (q, t, why) in [
            ([2.0, 0.0, 0.0, 0.0], [0.0; 3], "quaternion (w, x, y, z) = (2, 0, 0, 0) of length 2"),
            ([0.0; 4], [0.0; 3], "of length 0 (a unit quaternion is needed)"),
            ([1.0, 0.0, 0.0, 0.0], [f64::NAN, 0.0, 0.0], "translation (NaN, 0, 0)"),
        ] {
            let path =
                write(&dir, "bad.e57", &[cartesian(&SQUARE, None), cartesian(&SQUARE, Some((q, t)))], |s| s);
            fails_with(&path, "scan 2 ('station 2')", why);
        }
    }

    #[test]
    fn files_without_points_or_coordinates_are_refused() {
        let dir = TempDir::new();
        fails_with(&write(&dir, "none.e57", &[], |s| s), "", "no point clouds (scans) in the file");
        // every point without a return
        let blind = Scan { spherical: true, points: vec![([1.0, 0.0, 0.0], 2); 5], pose: None };
        fails_with(
            &write(&dir, "blind.e57", &[blind], |s| s),
            "",
            "no points (E57, 1 scan(s) read (1 in spherical coordinates), each placed by its pose: 0 points; 5 \
             point(s) without a return",
        );
        // too few points over all scans (scans this small, with an invalid state field, are
        // written with the state's bits in a later data packet than the coordinates)
        let few = [cartesian(&SQUARE[..2], None), cartesian(&SQUARE[2..3], None)];
        fails_with(
            &write(&dir, "few.e57", &few, |s| s),
            "",
            "only 3 point(s); at least 4 are needed (E57, 2 scan(s)",
        );
        // a scan whose coordinate fields are renamed out of the standard's names
        let renamed =
            write(&dir, "renamed.e57", &[cartesian(&SQUARE, None)], |s| s.replace("cartesianY", "lengthY"));
        fails_with(&renamed, "scan 1 ('station 1')", "no coordinates: neither cartesianX");
    }

    #[test]
    fn xml_that_does_not_fit_the_data_is_an_error() {
        let dir = TempDir::new();
        let scans = [cartesian(&SQUARE, Some(([1.0, 0.0, 0.0, 0.0], [1.0, 2.0, 3.0])))];
        // the XML the writer makes, then edited: each edit must give an error, never a panic
        let made = std::cell::RefCell::new(String::new());
        write(&dir, "probe.e57", &scans, |s| {
            made.replace(s.clone());
            s
        });
        let text = made.into_inner();
        let edited = |s: String| write(&dir, "x.e57", &scans, move |_| s.clone());
        for (from, to, why) in [
            ("recordCount=\"4\"", "recordCount=\"4000\"", "scan 1 ('station 1'), point 4"),
            ("recordCount=\"4\"", "recordCount=\"-4\"", "not a readable E57 file"),
            ("fileOffset=\"", "fileOffset=\"9", "scan 1 ('station 1'): cannot read the points"),
            ("<w type=\"Float\">1</w>", "<w type=\"Float\">one</w>", "not a readable E57 file"),
            ("</e57Root>", "", "not a readable E57 file"),
        ] {
            assert!(text.contains(from), "{from} not in {text}");
            let path = edited(text.replacen(from, to, 1));
            match read_points(&path) {
                Err(crate::error::Error::Input { location, reason, .. }) => {
                    let shown =
                        if location.is_empty() { reason.clone() } else { format!("{location}: {reason}") };
                    assert!(shown.contains(why), "{from} -> {to}: '{why}' not in '{shown}'");
                }
                other => panic!("{from} -> {to}: {other:?}"),
            }
        }
    }

    #[test]
    fn numbers_changed_in_the_xml_never_panic() {
        let dir = TempDir::new();
        let scans = [
            Scan {
                spherical: false,
                points: (0..40).map(|i| ([i as f64, 0.5 * i as f64, 1.0], (i % 5 == 0) as i64 * 2)).collect(),
                pose: Some(([0.5, 0.5, 0.5, 0.5], [1.0, 2.0, 3.0])),
            },
            Scan {
                spherical: true,
                points: (0..30).map(|i| ([1.0 + i as f64, 0.1 * i as f64, 0.2], 0)).collect(),
                pose: None,
            },
        ];
        let made = std::cell::RefCell::new(String::new());
        write(&dir, "probe.e57", &scans, |s| {
            made.replace(s.clone());
            s
        });
        let text = made.into_inner().into_bytes();
        let digits: Vec<usize> = (0..text.len()).filter(|&i| text[i].is_ascii_digit()).collect();
        let mut state = 0x9e3779b97f4a7c15u64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        };
        // one to three digits of the XML changed at a time: counts, offsets, limits, the pose
        for _ in 0..300 {
            let mut edited = text.clone();
            for _ in 0..1 + next() % 3 {
                let at = digits[next() as usize % digits.len()];
                edited[at] = b'0' + (next() % 10) as u8;
            }
            let edited = String::from_utf8(edited).unwrap();
            let path = write(&dir, "x.e57", &scans, move |_| edited.clone());
            let _ = read_points(&path);
        }
    }

    #[test]
    fn broken_files_are_errors_not_panics() {
        let dir = TempDir::new();
        let good = std::fs::read(write(&dir, "good.e57", &[cartesian(&SQUARE, None)], |s| s)).unwrap();
        assert!(read_points(&dir.file("ok.e57", &good)).is_ok());
        let mut flipped = good.clone();
        flipped[good.len() / 2] ^= 0x10;
        let mut random = Vec::new();
        let mut state = 0x2545f4914f6cdd1du64;
        for _ in 0..4096 {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            random.push(state as u8);
        }
        let mut signed_random = b"ASTM-E57".to_vec();
        signed_random.extend(&random);
        let cases: Vec<(&str, Vec<u8>, &str)> = vec![
            ("empty", vec![], "an empty file; not an E57 file"),
            ("random", random, "no 'ASTM-E57' signature at the start; not an E57 file"),
            ("short", good[..20].to_vec(), "20 bytes: shorter than an E57 header (48 bytes)"),
            ("truncated", good[..good.len() - 100].to_vec(), "not a readable E57 file (truncated?)"),
            ("half", good[..1024].to_vec(), "not a readable E57 file"),
            ("flipped", flipped, "(corrupt: a page fails its CRC checksum)"),
            ("signed_random", signed_random, "not a readable E57 file"),
        ];
        for (name, bytes, why) in cases {
            fails_with(&dir.file(&format!("{name}.e57"), bytes), "", why);
        }
        // every prefix at a page boundary, and every page with a bit changed (the checksum finds it)
        for end in (1024..good.len()).step_by(1024) {
            assert!(read_points(&dir.file("cut.e57", &good[..end])).is_err(), "{end}");
        }
        for at in (0..good.len()).step_by(1024).map(|p| p + 100) {
            let mut b = good.clone();
            b[at] ^= 1;
            match read_points(&dir.file("bit.e57", &b)) {
                Err(crate::error::Error::Input { reason, .. }) => {
                    assert!(reason.contains("a page fails its CRC checksum"), "{at}: {reason}")
                }
                other => panic!("{at}: {other:?}"),
            }
        }
    }
}
