//! STL, ascii and binary: the triangle soup that CAD systems, 3D printers and segmentation tools
//! write. Each facet carries its own three corners, so a corner shared by six facets appears six
//! times; the corners are merged where their coordinates are exactly equal (as the writer
//! repeated them), giving points in the order of first appearance and triangles indexing them.
//! The facet normals are ignored.
//!
//! Binary STL is an 80-byte header, a little-endian u32 facet count and 50 bytes a facet (normal,
//! three corners as f32 triples, a u16 attribute), so its size is exactly 84 + 50 count. Ascii STL
//! is `solid NAME`, then `facet normal nx ny nz / outer loop / vertex x y z (three times) / endloop
//! / endfacet` per facet, then `endsolid` (a `vertex` line holds exactly three numbers). Some
//! binary writers start the header with the word `solid` too, so the size decides first: a file of
//! exactly 84 + 50 count bytes is binary, one that starts with `solid` otherwise is ascii.

use std::collections::HashMap;
use std::path::Path;

use super::{capacity, check_corners, check_finite, Fan, PointSet};
use crate::error::{Error, Result};

const HEADER: usize = 80;
const FACET: usize = 50;

pub(super) fn parse(path: &Path, bytes: &[u8]) -> Result<PointSet> {
    let declared =
        bytes.get(HEADER..HEADER + 4).map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]) as usize);
    if let Some(count) = declared {
        if count.checked_mul(FACET).and_then(|b| b.checked_add(HEADER + 4)) == Some(bytes.len()) {
            return binary(path, bytes, count);
        }
    }
    let start = bytes.iter().position(|b| !b.is_ascii_whitespace()).unwrap_or(bytes.len());
    if bytes[start..].starts_with(b"solid") {
        return ascii(path, bytes);
    }
    Err(Error::input(
        path,
        "",
        match declared {
            Some(count) => format!(
                "neither ascii STL (it does not start with 'solid') nor binary STL (its header declares \
                 {count} facets, which take {} bytes; the file has {}): is it truncated?",
                (HEADER + 4) as u128 + FACET as u128 * count as u128,
                bytes.len()
            ),
            None => format!(
                "{} bytes: too short for binary STL (84 bytes of header and count) and not ascii STL \
                 (it does not start with 'solid')",
                bytes.len()
            ),
        },
    ))
}

/// Merges corners with equal coordinates into indexed points.
#[derive(Default)]
struct Corners {
    set: PointSet,
    index: HashMap<[u64; 3], usize>,
}

impl Corners {
    fn with_capacity(facets: usize) -> Self {
        // a closed triangle mesh has about half as many vertices as facets
        let mut c = Corners::default();
        c.set.points.reserve(facets / 2 + 3);
        c.set.triangles.reserve(facets);
        c.index.reserve(facets / 2 + 3);
        c
    }

    /// The index of the point at `p`; -0 and 0 are one point.
    fn add(&mut self, p: [f64; 3]) -> usize {
        let key = p.map(|c| (c + 0.0).to_bits());
        let points = &mut self.set.points;
        *self.index.entry(key).or_insert_with(|| {
            points.push(p);
            points.len() - 1
        })
    }
}

fn binary(path: &Path, bytes: &[u8], count: usize) -> Result<PointSet> {
    let mut corners = Corners::with_capacity(count);
    for (f, facet) in bytes[HEADER + 4..].chunks_exact(FACET).enumerate() {
        let at = || format!("facet {} (byte offset {})", f + 1, HEADER + 4 + f * FACET);
        let mut fan = Fan::default();
        for c in 0..3 {
            let p: [f64; 3] = std::array::from_fn(|d| {
                let o = 12 + 12 * c + 4 * d;
                f32::from_le_bytes([facet[o], facet[o + 1], facet[o + 2], facet[o + 3]]) as f64
            });
            let p = check_finite(p).map_err(|why| Error::input(path, at(), why))?;
            fan.push(corners.add(p), &mut corners.set.triangles);
        }
    }
    if count == 0 {
        return Err(Error::input(path, "", "binary STL with no facets"));
    }
    corners.set.note = Some(note("binary", count, corners.set.points.len()));
    Ok(corners.set)
}

fn ascii(path: &Path, bytes: &[u8]) -> Result<PointSet> {
    let text = crate::io::text::decode(path, bytes, "STL")?;
    let mut corners = Corners::with_capacity(capacity(usize::MAX, bytes.len(), 7 * 30));
    // the facet being read: its first line and its corners so far
    let mut open: Option<(usize, Fan)> = None;
    let mut facets = 0;
    for (i, line) in text.lines().enumerate() {
        let lineno = i + 1;
        let err = |reason: String| Error::input(path, format!("line {lineno}"), reason);
        let mut tokens = line.split_ascii_whitespace();
        match tokens.next() {
            Some("facet") => {
                if let Some((from, _)) = open {
                    return Err(err(format!(
                        "a facet begins before the facet of line {from} ended ('endfacet')"
                    )));
                }
                open = Some((lineno, Fan::default()));
            }
            Some("vertex") => {
                let Some((_, fan)) = open.as_mut() else {
                    return Err(err("'vertex' outside a facet".into()));
                };
                let mut p = [0.0; 3];
                for c in p.iter_mut() {
                    let tok = tokens
                        .next()
                        .ok_or_else(|| err("vertex needs 3 coordinates (vertex x y z)".into()))?;
                    *c = tok.parse().map_err(|_| err(format!("'{tok}' is not a number")))?;
                }
                let extra = tokens.count();
                if extra > 0 {
                    return Err(err(format!("vertex has {} values; it takes 3 (vertex x y z)", 3 + extra)));
                }
                let p = check_finite(p).map_err(err)?;
                fan.push(corners.add(p), &mut corners.set.triangles);
            }
            Some("endfacet") => {
                let Some((from, fan)) = open.take() else {
                    return Err(err("'endfacet' without 'facet'".into()));
                };
                check_corners(fan.corners)
                    .map_err(|why| Error::input(path, format!("line {from}"), format!("facet {why}")))?;
                facets += 1;
            }
            Some("endsolid") | Some("solid") | Some("outer") | Some("endloop") | None => {}
            Some(other) => return Err(err(format!("'{other}' is not an STL keyword"))),
        }
    }
    if let Some((from, _)) = open {
        return Err(Error::input(
            path,
            format!("line {from}"),
            "the file ends inside this facet (no 'endfacet')",
        ));
    }
    if facets == 0 {
        return Err(Error::input(path, "", "ascii STL with no facets"));
    }
    corners.set.note = Some(note("ascii", facets, corners.set.points.len()));
    Ok(corners.set)
}

fn note(kind: &str, facets: usize, points: usize) -> String {
    format!("{kind} STL: {facets} facets, {points} distinct corners (corners with equal coordinates merged)")
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use super::super::testutil::{fails_with, TempDir};
    use super::super::{read_mesh, read_points};

    const COW: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/cow.obj");

    /// The mesh as binary STL with `header` (padded to 80 bytes) and as ascii STL.
    fn stl(points: &[[f64; 3]], triangles: &[[usize; 3]], header: &[u8]) -> (Vec<u8>, String) {
        let mut bin = header.to_vec();
        bin.resize(80, b' ');
        bin.extend((triangles.len() as u32).to_le_bytes());
        let mut text = String::from("solid cow\n");
        for t in triangles {
            bin.extend([0f32; 3].iter().flat_map(|v| v.to_le_bytes()));
            text.push_str("  facet normal 0 0 0\n    outer loop\n");
            for &i in t {
                bin.extend(points[i].iter().flat_map(|&v| (v as f32).to_le_bytes()));
                let [x, y, z] = points[i];
                text.push_str(&format!("      vertex {x:e} {y:e} {z:e}\n"));
            }
            bin.extend([0u8; 2]);
            text.push_str("    endloop\n  endfacet\n");
        }
        text.push_str("endsolid cow\n");
        (bin, text)
    }

    #[test]
    fn a_real_mesh_reads_back_from_both_stl_forms_with_its_corners_merged() {
        let cow = read_mesh(Path::new(COW)).unwrap();
        let dir = TempDir::new();
        // binary files whose header starts with "solid" are binary all the same
        for header in [&b"binary cow"[..], b"solid cow (binary)"] {
            let (bin, text) = stl(&cow.points, &cow.triangles, header);
            for (name, bytes, tol) in [("b.stl", bin, 1e-7), ("a.STL", text.into_bytes(), 0.0)] {
                let got = read_mesh(&dir.file(name, bytes)).unwrap();
                // every vertex of the cow is a corner of some face, and two of them share a place
                assert_eq!((got.points.len(), got.triangles.len()), (2903, 5804), "{name}");
                for (t, u) in got.triangles.iter().zip(&cow.triangles) {
                    for (&i, &j) in t.iter().zip(u) {
                        let (p, q) = (got.points[i], cow.points[j]);
                        assert!(
                            (0..3).all(|d| (p[d] - q[d]).abs() <= tol * q[d].abs()),
                            "{name}: {p:?} {q:?}"
                        );
                    }
                }
                assert!(
                    got.note.as_deref().unwrap().contains("5804 facets, 2903 distinct corners"),
                    "{name}"
                );
            }
        }
    }

    #[test]
    fn broken_stl_files_name_the_place() {
        let dir = TempDir::new();
        let facet = |a: &str| format!("facet normal 0 0 1\nouter loop\n{a}endloop\nendfacet\n");
        let good = "vertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\n";
        let cases = [
            (
                format!("solid s\n{}endsolid\n", facet("vertex 0 0 0\nvertex 1 0\nvertex 0 1 0\n")),
                "line 5",
                "3 coordinates",
            ),
            (
                format!("solid s\n{}endsolid\n", facet("vertex 0 0 0\nvertex 1 0 0 4\nvertex 0 1 0\n")),
                "line 5",
                "vertex has 4 values; it takes 3 (vertex x y z)",
            ),
            (format!("solid s\n{}endsolid\n", facet("vertex 0 0 0\nvertex 1 0 0\n")), "line 2", "at least 3"),
            (
                format!("solid s\n{}endsolid\n", facet("vertex 0 0 0\nvertex 1 nan 0\nvertex 0 1 0\n")),
                "line 5",
                "non-finite",
            ),
            (format!("solid s\nfacet normal 0 0 1\nouter loop\n{good}"), "line 2", "ends inside this facet"),
            (format!("solid s\nfacet normal 0 0 1\n{}", facet(good)), "line 3", "before the facet of line 2"),
            (format!("solid s\n{}vertex 0 0 0\n", facet(good)), "line 9", "outside a facet"),
            (format!("solid s\n{}facets 2\n", facet(good)), "line 9", "'facets' is not an STL keyword"),
            ("solid s\nendsolid s\n".to_string(), "", "no facets"),
            (
                "not an stl file at all, long enough to be taken for a binary header ... ... ... ... ... ."
                    .to_string(),
                "",
                "is it truncated?",
            ),
            ("short".to_string(), "", "too short"),
        ];
        for (i, (text, at, why)) in cases.iter().enumerate() {
            fails_with(&dir.file(&format!("{i}.stl"), text), at, why);
        }
        // a binary file one facet short of its count
        let mut bin = vec![b' '; 80];
        bin.extend(2u32.to_le_bytes());
        bin.extend([0u8; 50]);
        fails_with(
            &dir.file("short.stl", &bin),
            "",
            "declares 2 facets, which take 184 bytes; the file has 134",
        );
        // a binary corner that is not finite
        let mut bin = vec![b' '; 80];
        bin.extend(1u32.to_le_bytes());
        let corners = [0f32, 0., 0., 0., 0., 0., 1., 0., 0., 0., f32::INFINITY, 0.];
        bin.extend(corners.iter().flat_map(|v| v.to_le_bytes()));
        bin.extend([0u8; 2]);
        fails_with(&dir.file("inf.stl", &bin), "facet 1 (byte offset 84)", "non-finite");
        // too few distinct corners for a volume
        assert!(read_points(&dir.file("one.stl", format!("solid s\n{}endsolid\n", facet(good)))).is_err());
    }
}
