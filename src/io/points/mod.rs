//! Reading scattered surface points, and the triangles of ground-truth meshes, from files.
//!
//! This module owns the input file formats: plain-text point lists (.xyz/.txt/.csv, `text`),
//! Wavefront OBJ (`obj`), PLY, ascii and both binary byte orders (`ply`), and STL, ascii and
//! binary (`stl`, its corners merged into indexed points), and the Point Cloud Library's PCD
//! (`pcd`, ascii, binary and LZF-compressed), lidar's LAS (`las`), and the laser scanners' E57
//! (`e57`). It picks the parser by extension and holds what they share. Everything is returned in
//! the file's own coordinates (an E57 file's common ones, where its scans' poses place them);
//! normalisation belongs to the caller. The files come from users, so every parser
//! validates as it goes and reports the line, vertex or byte offset at fault instead of
//! panicking or guessing.

mod e57;
mod las;
mod obj;
mod pcd;
mod ply;
mod stl;
mod text;

use std::path::Path;

use crate::error::{Error, Result};

/// Fewer points than this cannot define a volume.
const MIN_POINTS: usize = 4;

const SUPPORTED: &str = ".obj, .ply, .stl, .pcd, .las, .e57, .xyz, .txt, .csv";

/// Points and (optional) triangles read from a file, in the file's coordinates.
#[derive(Debug, Clone, Default)]
pub struct PointSet {
    pub points: Vec<[f64; 3]>,
    pub triangles: Vec<[usize; 3]>,
    /// What the reader made of the file's layout where the user should hear it (the columns of a
    /// text file with more than three values a line).
    pub note: Option<String>,
}

/// Read scattered points by extension: .obj, .ply, .stl, .pcd, .las, .e57, .xyz/.txt/.csv
/// (case-insensitive).
/// Triangles are filled for .obj/.ply when faces exist (polygons fan-triangulated) and for .stl,
/// empty for text.
///
/// Text files hold three or more numbers per line, as many on every line, separated by
/// whitespace and/or commas; `#` starts a comment and blank lines are ignored. Where the first
/// non-blank, non-comment line holds a semicolon, semicolons separate the values instead of
/// commas and a comma inside a value is its decimal mark (`0,5;1,25;3`, as spreadsheets in
/// decimal-comma locales export), and [`PointSet::note`] says so. A first data line of three or
/// more blank-separated numbers each with one comma between digits (`100,934 237,145 333,457`)
/// is refused as decimal commas between blanks, which would be split at the commas. The first
/// non-blank, non-comment line may be a column header such as `x,y,z` or `//X Y Z Nx Ny Nz`,
/// but only if none of its tokens is a number; anywhere else a non-numeric token is an error.
/// The coordinates are the columns the header names x, y and z (any case, leading slashes
/// dropped), or else the first three; further columns (normals, colours, intensities) are
/// ignored, and [`PointSet::note`] says so.
///
/// E57 files give the points of all their scans, each placed in the file's common coordinates by
/// its pose (rotation quaternion, then translation); spherical coordinates are turned into
/// Cartesian ones first. Points without a return (a `cartesianInvalidState` or
/// `sphericalInvalidState` other than 0, or x, y and z all NaN) are left out, and
/// [`PointSet::note`] counts them and the scans.
///
/// Every coordinate must be finite, except that a line (or PLY vertex, where the file has no
/// faces) whose x, y and z are all NaN is a scanner's pixel without a return: such points are left
/// out and [`PointSet::note`] counts them. The file must hold at least 4 points.
pub fn read_points(path: &Path) -> Result<PointSet> {
    if path.is_dir() {
        return Err(Error::input(path, "", format!("a directory, not a point file ({SUPPORTED})")));
    }
    let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("").to_ascii_lowercase();
    let parse: fn(&Path, &[u8]) -> Result<PointSet> = match ext.as_str() {
        "obj" => obj::parse,
        "ply" => ply::parse,
        "stl" => stl::parse,
        "pcd" => pcd::parse,
        "las" => las::parse,
        "e57" => e57::parse,
        "laz" => return Err(Error::input(path, "", las::LAZ)),
        "xyz" | "txt" | "csv" => text::parse,
        _ => {
            let shown = if ext.is_empty() { "none".to_string() } else { format!("'.{ext}'") };
            return Err(Error::input(
                path,
                "",
                format!("unsupported file extension {shown}; supported: {SUPPORTED}"),
            ));
        }
    };
    crate::io::staging::note_input(path);
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, &e))?;
    let set = parse(path, &bytes)?;
    if set.points.len() < MIN_POINTS {
        return Err(Error::input(
            path,
            "",
            format!(
                "only {} point(s); at least {MIN_POINTS} are needed{}",
                set.points.len(),
                set.note.as_ref().map_or(String::new(), |n| format!(" ({n})"))
            ),
        ));
    }
    Ok(set)
}

/// Same as read_points but requires at least one triangle (for ground-truth meshes); error
/// otherwise.
pub fn read_mesh(path: &Path) -> Result<PointSet> {
    const MESHES: &str = ".obj or .ply with faces, or .stl";
    let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("").to_ascii_lowercase();
    if path.is_dir() {
        return Err(Error::input(path, "", format!("a directory, not a mesh file ({MESHES})")));
    }
    if !matches!(ext.as_str(), "obj" | "ply" | "stl") {
        let shown = if ext.is_empty() { "none".to_string() } else { format!("'.{ext}'") };
        return Err(Error::input(
            path,
            "",
            format!("file extension {shown}: a mesh file ({MESHES}) is needed here, with triangles to cut"),
        ));
    }
    let set = read_points(path)?;
    if set.triangles.is_empty() {
        return Err(Error::input(
            path,
            "",
            "no faces: a mesh file (.obj or .ply with faces, or .stl) is needed here, not just points",
        ));
    }
    Ok(set)
}

// ---------------------------------------------------------------------------------------------
// Helpers shared by the parsers.

/// A point with no coordinates at all: x, y and z NaN, as range scanners and depth cameras write
/// the pixels that had no return (organised point clouds keep them to keep the image's shape).
/// Point lists leave such points out, with a note; meshes cannot (faces may use them).
fn no_return(p: &[f64; 3]) -> bool {
    p.iter().all(|c| c.is_nan())
}

/// The note on the points without a return left out of a point list: `count` of them, the first
/// at `first` (a line or a vertex).
fn no_return_note(count: usize, first: &str) -> String {
    format!(
        "{count} point(s) without coordinates (x, y and z all NaN: scanner pixels with no return) left out, \
         the first at {first}"
    )
}

/// The whole number a text value of an integer field stands for: an integer (`-12`), or a decimal
/// that is exactly one (`12.0`, `1.2e1`, as writers that format every value as a float give
/// them) within 2^53, where doubles hold every integer. Not `12.5`, `inf` or `1e300`.
fn whole_number(s: &str) -> Option<i64> {
    const EXACT: f64 = 9_007_199_254_740_992.0; // 2^53
    s.parse::<i64>().ok().or_else(|| {
        let v = s.parse::<f64>().ok()?;
        (v.is_finite() && v.fract() == 0.0 && v.abs() <= EXACT).then_some(v as i64)
    })
}

fn check_finite(p: [f64; 3]) -> std::result::Result<[f64; 3], String> {
    if p.iter().all(|c| c.is_finite()) {
        Ok(p)
    } else {
        Err(format!("non-finite coordinate ({}, {}, {})", p[0], p[1], p[2]))
    }
}

/// Capacity guess from the file size, so large files avoid repeated regrowth while a header or
/// file that lies cannot make us allocate more than the data could possibly hold.
fn capacity(declared: usize, bytes_left: usize, min_bytes_each: usize) -> usize {
    declared.min(bytes_left / min_bytes_each.max(1) + 1)
}

/// Fan triangulation of one polygon whose corners arrive one at a time: corners `a b c d ...`
/// give the triangles `(a b c), (a c d), ...`, so no per-face buffer is needed. OBJ and PLY both
/// store polygons as corner lists.
#[derive(Default)]
struct Fan {
    first: usize,
    prev: usize,
    corners: u64,
}

impl Fan {
    fn push(&mut self, v: usize, triangles: &mut Vec<[usize; 3]>) {
        match self.corners {
            0 => self.first = v,
            1 => self.prev = v,
            _ => {
                triangles.push([self.first, self.prev, v]);
                self.prev = v;
            }
        }
        self.corners += 1;
    }
}

/// A face needs at least three corners.
fn check_corners(n: u64) -> std::result::Result<(), String> {
    if n < 3 {
        return Err(format!("face has {n} vertices; at least 3 are needed"));
    }
    Ok(())
}

#[cfg(test)]
mod testutil {
    //! Helpers shared by the tests of the parsers.

    use super::*;
    use std::path::PathBuf;
    use std::sync::atomic::{AtomicUsize, Ordering};

    /// A private directory per test, removed on drop, so parallel tests never collide.
    pub(super) struct TempDir(pub(super) PathBuf);

    impl TempDir {
        pub(super) fn new() -> Self {
            static NEXT: AtomicUsize = AtomicUsize::new(0);
            let n = NEXT.fetch_add(1, Ordering::Relaxed);
            let dir = std::env::temp_dir().join(format!("volspline_points_{}_{n}", std::process::id()));
            std::fs::create_dir_all(&dir).expect("create temp dir");
            TempDir(dir)
        }

        pub(super) fn file(&self, name: &str, contents: impl AsRef<[u8]>) -> PathBuf {
            let path = self.0.join(name);
            std::fs::write(&path, contents).expect("write temp file");
            path
        }
    }

    impl Drop for TempDir {
        fn drop(&mut self) {
            let _ = std::fs::remove_dir_all(&self.0);
        }
    }

    pub(super) const CUBE: [[f64; 3]; 5] =
        [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [0.5, -2.25, 3e-3]];

    /// Checks that reading `path` fails with an input error at `location` for a reason that
    /// mentions `want`.
    pub(super) fn fails_with(path: &Path, location: &str, want: &str) {
        let shown = path.display();
        match read_points(path) {
            Err(Error::Input { location: at, reason, .. }) => {
                assert_eq!(at, location, "{shown}: {reason}");
                assert!(reason.contains(want), "{shown}: '{want}' not in '{reason}'");
            }
            other => panic!("expected an input error for {shown}, got {other:?}"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::testutil::{fails_with, TempDir, CUBE};
    use super::*;

    #[test]
    fn faults_before_and_after_parsing() {
        let dir = TempDir::new();
        let elf = [0x7f, b'E', b'L', b'F', 2, 1, 1, 0, 0xc3];
        let supported = ".obj, .ply, .stl, .pcd, .las, .e57, .xyz, .txt, .csv";
        let cases: [(&str, &[u8], &str, &str); 8] = [
            ("few.xyz", b"0 0 0\n1 0 0\n0 1 0\n", "", "at least 4"),
            ("le.xyz", b"\xff\xfe0\x00 \x000\x00", "line 1", "UTF-16 text"),
            ("be.obj", b"\xfe\xff\x00v\x00 ", "line 1", "iconv -f UTF-16"),
            ("empty.xyz", b"", "", "no points"),
            ("binary.xyz", b"0 0 0\n1 0 0\n\x00\x01\xff\x80 junk", "line 3", "binary"),
            ("elf.obj", &elf, "line 1", "not a text OBJ"),
            ("p.e58", b"0 0 0\n", "", supported),
            ("noext", b"0 0 0\n", "", supported),
        ];
        for (name, contents, at, why) in cases {
            fails_with(&dir.file(name, contents), at, why);
        }
    }

    #[test]
    fn a_directory_is_named_as_such() {
        let dir = TempDir::new();
        for name in ["scans", "scan.xyz"] {
            std::fs::create_dir_all(dir.0.join(name)).unwrap();
            fails_with(&dir.0.join(name), "", "a directory, not a point file");
        }
    }

    #[test]
    fn missing_file_is_an_io_error() {
        let dir = TempDir::new();
        let err = read_points(&dir.0.join("absent.xyz")).expect_err("missing");
        assert!(matches!(err, Error::Io { .. }), "{err:?}");
    }

    #[test]
    fn read_mesh_requires_triangles() {
        let dir = TempDir::new();
        let (text, obj) = ("0 0 0\n1 0 0\n0 1 0\n0 0 1\n", "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\n");
        let mut points_ply = b"ply\nformat binary_little_endian 1.0\nelement vertex 4\nproperty float x\n\
                               property float y\nproperty float z\nend_header\n"
            .to_vec();
        CUBE[..4].iter().flatten().for_each(|&c| points_ply.extend((c as f32).to_le_bytes()));
        for path in [dir.file("a.xyz", text), dir.file("b.obj", obj), dir.file("c.ply", points_ply)] {
            assert!(read_points(&path).is_ok());
            match read_mesh(&path) {
                Err(Error::Input { reason, .. }) => {
                    let why = if path.extension().unwrap() == "xyz" { "a mesh file" } else { "no faces" };
                    assert!(reason.contains(why), "{reason}")
                }
                other => panic!("{other:?}"),
            }
        }
    }
}
