//! Wavefront OBJ: only `v` and `f` records matter; materials, groups, normals and texture
//! coordinates are irrelevant to the geometry and are ignored (so a missing .mtl is harmless). A
//! `v` record holds 3 numbers (x y z), 4 (and w), 6 (and a colour r g b) or 7; other counts are
//! refused.
//!
//! OBJ is parsed by hand rather than with `tobj`: tobj either duplicates positions when texture
//! coordinates are present (`single_index`) or re-indexes them per group, whereas the solver
//! needs the file's `v` records exactly, in file order.

use std::path::Path;

use super::{check_corners, check_finite, Fan, PointSet};
use crate::error::{Error, Result};

pub(super) fn parse(path: &Path, bytes: &[u8]) -> Result<PointSet> {
    // decoded in one pass up front, so that a binary file with the wrong extension is reported
    // once, with a position, instead of as a confusing parse error
    let text = crate::io::text::decode(path, bytes, "OBJ")?;
    let mut set = PointSet::default();
    // Positive indices may in principle point forward, so they are checked once all vertices
    // are known; remember the largest one and where it was.
    let mut max_forward: Option<(usize, usize)> = None;
    for (i, raw) in text.lines().enumerate() {
        let lineno = i + 1;
        let err = |reason: String| Error::input(path, format!("line {lineno}"), reason);
        let line = raw.split('#').next().unwrap_or("");
        let mut tokens = line.split_ascii_whitespace();
        match tokens.next() {
            Some("v") => {
                let mut xyz = [0.0; 3];
                let mut n = 0;
                for tok in tokens {
                    let v: f64 = tok.parse().map_err(|_| err(format!("'{tok}' is not a number")))?;
                    if let Some(c) = xyz.get_mut(n) {
                        *c = v;
                    }
                    n += 1;
                }
                // Extra values (w, or per-vertex colours, with or without w) are legal and
                // irrelevant here; other counts are not a vertex.
                if !matches!(n, 3 | 4 | 6 | 7) {
                    return Err(err(format!(
                        "vertex has {n} numbers; expected 3 (v x y z), 4 (x y z w), 6 (x y z r g b) or 7"
                    )));
                }
                set.points.push(check_finite(xyz).map_err(err)?);
            }
            Some("f") => {
                let defined = set.points.len();
                let mut fan = Fan::default();
                for tok in tokens {
                    let v = obj_index(tok, defined).map_err(err)?;
                    if v >= defined && !matches!(max_forward, Some((m, _)) if m >= v) {
                        max_forward = Some((v, lineno));
                    }
                    fan.push(v, &mut set.triangles);
                }
                check_corners(fan.corners).map_err(err)?;
            }
            _ => {}
        }
    }
    if set.points.is_empty() {
        return Err(Error::input(path, "", "no vertices ('v' lines) found; is this an OBJ file?"));
    }
    if let Some((v, lineno)) = max_forward {
        if v >= set.points.len() {
            return Err(Error::input(
                path,
                format!("line {lineno}"),
                format!("vertex index {} out of range (file has {} vertices)", v + 1, set.points.len()),
            ));
        }
    }
    Ok(set)
}

/// Resolves one face corner (`v`, `v/vt`, `v/vt/vn` or `v//vn`) to a 0-based vertex index.
/// Negative indices count back from the vertices defined so far.
fn obj_index(tok: &str, defined: usize) -> std::result::Result<usize, String> {
    let v = tok.split('/').next().unwrap_or("");
    let i: i64 = v.parse().map_err(|_| format!("'{tok}' is not a valid face vertex reference"))?;
    match i {
        0 => Err("vertex index 0 is invalid (OBJ indices start at 1)".into()),
        1.. => Ok(usize::try_from(i - 1).unwrap_or(usize::MAX)),
        _ => {
            let back = usize::try_from(i.unsigned_abs()).unwrap_or(usize::MAX);
            defined.checked_sub(back).ok_or_else(|| {
                format!("relative index {i} reaches before the first vertex ({defined} defined so far)")
            })
        }
    }
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use super::super::testutil::{fails_with, TempDir, CUBE};
    use super::super::{read_mesh, read_points, PointSet};

    const BUNNY: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/bunny10k.obj");
    const COW: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/cow.obj");

    #[test]
    fn obj_face_forms_and_fan_triangulation() {
        let dir = TempDir::new();
        let obj = "mtllib missing.mtl\no thing\nv 0 0 0\nv 1 0 0 1.0\nv 0 1 0 0.5 0.5 0.5\n\
                   v 0 0 1\nv .5 -2.25 3e-3\nvt 0 0\nvn 0 0 1\nusemtl none\ns off\n\
                   f 1 2 3\nf 1/1 2/1 4/1\nf 1/1/1 3/1/1 4/1/1 # comment\nf 2//1 3//1 4//1 5//1\n";
        let set = read_points(&dir.file("m.OBJ", obj)).expect("obj");
        assert_eq!(set.points, CUBE);
        assert_eq!(set.triangles, vec![[0, 1, 2], [0, 1, 3], [0, 2, 3], [1, 2, 3], [1, 3, 4]]);
    }

    #[test]
    fn obj_relative_indices() {
        let dir = TempDir::new();
        let obj = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf -3 -2 -1\nv 0 0 1\nf -4/-1 -2/-1 -1/-1\n";
        let set = read_points(&dir.file("r.obj", obj)).expect("obj");
        assert_eq!(set.triangles, vec![[0, 1, 2], [0, 2, 3]]);
        fails_with(
            &dir.file("bad.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf -5 1 2\n"),
            "line 5",
            "before the first vertex",
        );
    }

    #[test]
    fn obj_bad_indices_name_the_line() {
        let dir = TempDir::new();
        let v = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\n";
        fails_with(&dir.file("a.obj", format!("{v}f 1 2 3\nf 1 2 9\nf 2 3 4\n")), "line 6", "out of range");
        fails_with(&dir.file("b.obj", format!("{v}f 0 1 2\n")), "line 5", "index 0");
        fails_with(&dir.file("c.obj", format!("{v}f 1 2\n")), "line 5", "at least 3");
        fails_with(&dir.file("d.obj", format!("{v}f 1 x 2\n")), "line 5", "'x' is not a valid face vertex");
        // Forward references are legal OBJ as long as the vertex eventually exists.
        let set = read_points(&dir.file("e.obj", format!("f 1 2 3\n{v}"))).expect("forward");
        assert_eq!(set.triangles, vec![[0, 1, 2]]);
    }

    #[test]
    fn obj_bad_vertices_name_the_line() {
        let dir = TempDir::new();
        fails_with(
            &dir.file("a.obj", "v 0 0 0\nv 1 0\nv 0 1 0\nv 0 0 1\n"),
            "line 2",
            "vertex has 2 numbers",
        );
        for (extra, n) in [(" 1 1", 5), (" 1 1 1 1 1", 8)] {
            let text = format!("v 0 0 0\nv 1 0 0\nv 0 1 0{extra}\nv 0 0 1\n");
            fails_with(&dir.file("v.obj", text), "line 3", &format!("vertex has {n} numbers; expected 3"));
        }
        fails_with(&dir.file("w.obj", "v 0 0 0\nv 1 0 0 one\n"), "line 2", "'one' is not a number");
        // 4 (w), 6 (colour) and 7 (both) numbers are vertices
        let set = read_points(&dir.file("x.obj", "v 0 0 0\nv 1 0 0 1\nv 0 1 0 1 0 0\nv 0 0 1 1 0 0 1\n"));
        assert_eq!(set.unwrap().points, CUBE[..4]);
        fails_with(&dir.file("b.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 nan 1\n"), "line 4", "non-finite");
        fails_with(&dir.file("c.obj", "# nothing\nvt 0 0\n"), "", "no vertices");
    }

    /// Reads a real model, checks its counts and that every face index is in range.
    fn real(path: &str, points: usize, triangles: usize) -> PointSet {
        let set = read_mesh(Path::new(path)).expect(path);
        assert_eq!((set.points.len(), set.triangles.len()), (points, triangles), "{path}");
        assert!(set.triangles.iter().flatten().all(|&i| i < set.points.len()), "{path}");
        set
    }

    #[test]
    fn real_bunny_and_cow() {
        let bunny = real(BUNNY, 5051, 9999);
        assert_eq!(bunny.points[0], [-3.24965, 17.4231, -0.238999]);
        // Every vertex is used by some face in this model.
        let mut used = vec![false; bunny.points.len()];
        bunny.triangles.iter().flatten().for_each(|&i| used[i] = true);
        assert!(used.iter().all(|&u| u));
        real(COW, 2904, 5804);
    }
}
