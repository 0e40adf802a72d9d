//! PLY, ascii and both binary byte orders.
//!
//! A PLY header declares the body's encoding and a list of elements, each with a count and typed
//! properties (scalars, or lists with a count type and an item type). Only two elements matter
//! here: `vertex` supplies the points through its scalar `x`, `y` and `z` properties, and `face`
//! (optional) its polygons through an integer list named `vertex_indices` or `vertex_index`;
//! every other element and property is read past (in ascii files each value is checked against its
//! type all the same: an integer type's values must be whole numbers in its range). An element
//! name declared twice is refused. This file parses the header and assigns those roles; [`body`]
//! reads the values.

mod body;

use std::path::Path;

use super::{no_return, no_return_note, PointSet};
use crate::error::{Error, Result};

#[derive(Debug, Clone, Copy, PartialEq)]
enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    fn from_name(name: &str) -> Option<Self> {
        Some(match name {
            "char" | "int8" => Scalar::I8,
            "uchar" | "uint8" => Scalar::U8,
            "short" | "int16" => Scalar::I16,
            "ushort" | "uint16" => Scalar::U16,
            "int" | "int32" => Scalar::I32,
            "uint" | "uint32" => Scalar::U32,
            "float" | "float32" => Scalar::F32,
            "double" | "float64" => Scalar::F64,
            _ => return None,
        })
    }

    fn size(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::F64 => 8,
        }
    }

    fn is_int(self) -> bool {
        !matches!(self, Scalar::F32 | Scalar::F64)
    }

    /// The least and greatest value of an integer type.
    fn range(self) -> (i64, i64) {
        match self {
            Scalar::I8 => (i8::MIN.into(), i8::MAX.into()),
            Scalar::U8 => (0, u8::MAX.into()),
            Scalar::I16 => (i16::MIN.into(), i16::MAX.into()),
            Scalar::U16 => (0, u16::MAX.into()),
            Scalar::I32 => (i32::MIN.into(), i32::MAX.into()),
            Scalar::U32 => (0, u32::MAX.into()),
            Scalar::F32 | Scalar::F64 => (i64::MIN, i64::MAX),
        }
    }
}

#[derive(Debug, Clone, Copy)]
enum Kind {
    Scalar(Scalar),
    List { count: Scalar, item: Scalar },
}

#[derive(Debug)]
struct Property {
    name: String,
    kind: Kind,
}

/// What the body reader does with an element's data.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Role {
    /// Property indices of x, y, z.
    Vertex([usize; 3]),
    /// Property index of the vertex index list.
    Face(usize),
    Skip,
}

#[derive(Debug)]
struct Element {
    name: String,
    count: usize,
    props: Vec<Property>,
    role: Role,
}

impl Element {
    /// Bytes of one instance when it has no list properties (fixed record size).
    fn fixed_stride(&self) -> Option<usize> {
        self.props.iter().try_fold(0, |acc, p| match p.kind {
            Kind::Scalar(s) => Some(acc + s.size()),
            Kind::List { .. } => None,
        })
    }

    /// Lower bound on the bytes one instance occupies in the body.
    fn min_bytes(&self, ascii: bool) -> usize {
        if ascii {
            // Each value is at least one character plus a separator.
            return 2 * self.props.len();
        }
        self.props.iter().map(Property::min_size).sum()
    }
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Encoding {
    Ascii,
    LittleEndian,
    BigEndian,
}

struct Header {
    encoding: Encoding,
    elements: Vec<Element>,
    /// Number of header lines, so ascii body errors can give file line numbers.
    lines: usize,
    /// Byte offset where the body starts.
    body: usize,
}

impl Property {
    fn min_size(&self) -> usize {
        match self.kind {
            Kind::Scalar(s) => s.size(),
            Kind::List { count, .. } => count.size(),
        }
    }
}

/// Reads a whole PLY file: its header, then the body as the header declares it.
pub(super) fn parse(path: &Path, bytes: &[u8]) -> Result<PointSet> {
    let header = parse_header(path, bytes)?;
    let mut set = body::read(path, bytes, &header)?;
    // vertices without a return: left out of a point cloud, an error in a mesh
    if let Some(first) = set.points.iter().position(no_return) {
        let at = format!("vertex {first}");
        if !set.triangles.is_empty() {
            return Err(Error::input(
                path,
                at,
                "x, y and z are NaN (no coordinates), and the file has faces that may use the vertex",
            ));
        }
        let before = set.points.len();
        set.points.retain(|p| !no_return(p));
        let note = no_return_note(before - set.points.len(), &at);
        set.note = Some(match set.note.take() {
            Some(n) => format!("{n}; {note}"),
            None => note,
        });
    }
    Ok(set)
}

fn parse_header(path: &Path, bytes: &[u8]) -> Result<Header> {
    let magic_ok = bytes.starts_with(b"ply\n") || bytes.starts_with(b"ply\r\n");
    if !magic_ok {
        return Err(Error::input(path, "", "no 'ply' magic number on the first line; not a PLY file"));
    }
    let mut encoding = None;
    let mut elements: Vec<Element> = Vec::new();
    let mut pos = 0;
    let mut lineno = 0;
    loop {
        if pos >= bytes.len() {
            return Err(Error::input(path, "", "header has no 'end_header' line"));
        }
        let rest = &bytes[pos..];
        let (raw, next) = match rest.iter().position(|&b| b == b'\n') {
            Some(k) => (&rest[..k], pos + k + 1),
            None => (rest, bytes.len()),
        };
        pos = next;
        lineno += 1;
        let err = |reason: String| Error::input(path, format!("line {lineno}"), reason);
        // comments are free text in whatever encoding the writing tool used
        let Ok(line) = std::str::from_utf8(raw) else {
            if lineno > 1 && (raw.starts_with(b"comment") || raw.starts_with(b"obj_info")) {
                continue;
            }
            return Err(err("header line is not text (missing 'end_header'?)".into()));
        };
        let mut tokens = line.split_ascii_whitespace();
        let keyword = tokens.next();
        let args: Vec<&str> = tokens.collect();
        match keyword {
            _ if lineno == 1 => {}
            None | Some("comment") | Some("obj_info") => {}
            Some("format") => {
                let enc = match args.first().copied() {
                    Some("ascii") => Encoding::Ascii,
                    Some("binary_little_endian") => Encoding::LittleEndian,
                    Some("binary_big_endian") => Encoding::BigEndian,
                    other => {
                        return Err(err(format!("unknown format '{}'", other.unwrap_or(""))));
                    }
                };
                if args.get(1).and_then(|v| v.parse::<f64>().ok()) != Some(1.0) || args.len() != 2 {
                    return Err(err(format!("unsupported format line '{line}' (expected version 1.0)")));
                }
                encoding = Some(enc);
            }
            Some("element") => {
                let (name, count) = match args.as_slice() {
                    [name, count] => (*name, *count),
                    _ => return Err(err("expected 'element <name> <count>'".into())),
                };
                let count = count
                    .parse::<usize>()
                    .map_err(|_| err(format!("element count '{count}' is not a valid number")))?;
                if elements.iter().any(|e| e.name == name) {
                    return Err(err(format!("element '{name}' declared twice")));
                }
                elements.push(Element { name: name.to_string(), count, props: Vec::new(), role: Role::Skip });
            }
            Some("property") => {
                let el = elements.last_mut().ok_or_else(|| err("'property' before any 'element'".into()))?;
                let scalar =
                    |t: &str| Scalar::from_name(t).ok_or_else(|| err(format!("unknown property type '{t}'")));
                let (kind, name) = match args.as_slice() {
                    ["list", count, item, name] => {
                        let count = scalar(count)?;
                        if !count.is_int() {
                            return Err(err("list count type must be an integer type".into()));
                        }
                        (Kind::List { count, item: scalar(item)? }, *name)
                    }
                    [ty, name] if *ty != "list" => (Kind::Scalar(scalar(ty)?), *name),
                    _ => {
                        return Err(err(
                            "expected 'property <type> <name>' or 'property list <count> <item> <name>'"
                                .into(),
                        ))
                    }
                };
                if el.props.iter().any(|p| p.name == name) {
                    return Err(err(format!("property '{name}' declared twice in element '{}'", el.name)));
                }
                el.props.push(Property { name: name.to_string(), kind });
            }
            Some("end_header") => break,
            Some(other) => return Err(err(format!("unknown header keyword '{other}'"))),
        }
    }
    let encoding = encoding.ok_or_else(|| Error::input(path, "", "header has no 'format' line"))?;
    assign_roles(path, &mut elements)?;
    Ok(Header { encoding, elements, lines: lineno, body: pos })
}

/// Decides which element supplies the points and which the faces, so the body reader can stay a
/// plain loop over elements in whatever order the file declares them.
fn assign_roles(path: &Path, elements: &mut [Element]) -> Result<()> {
    let vertex = elements
        .iter_mut()
        .find(|e| e.name == "vertex")
        .ok_or_else(|| Error::input(path, "", "header declares no 'vertex' element"))?;
    let mut xyz = [0; 3];
    for (slot, axis) in xyz.iter_mut().zip(["x", "y", "z"]) {
        *slot = match vertex.props.iter().position(|p| p.name == axis) {
            Some(i) if matches!(vertex.props[i].kind, Kind::Scalar(_)) => i,
            Some(_) => {
                return Err(Error::input(path, "", format!("vertex property '{axis}' is a list")));
            }
            None => {
                return Err(Error::input(path, "", format!("vertex element has no '{axis}' property")));
            }
        };
    }
    vertex.role = Role::Vertex(xyz);
    if let Some(face) = elements.iter_mut().find(|e| e.name == "face") {
        let list = face.props.iter().position(|p| p.name == "vertex_indices" || p.name == "vertex_index");
        if let Some(i) = list {
            match face.props[i].kind {
                Kind::List { item, .. } if item.is_int() => face.role = Role::Face(i),
                _ => {
                    return Err(Error::input(
                        path,
                        "",
                        format!("face property '{}' must be a list of integers", face.props[i].name),
                    ))
                }
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod build {
    //! PLY files for the tests, in any encoding, from rows of typed values.

    use super::super::testutil::CUBE;
    use super::Encoding;

    /// One value of a PLY body, of the type the header declares.
    #[derive(Clone, Copy)]
    pub(super) enum V {
        U8(u8),
        I8(i8),
        I16(i16),
        U16(u16),
        I32(i32),
        U32(u32),
        F32(f32),
        F64(f64),
    }

    fn ply_body(rows: &[Vec<V>], enc: Encoding) -> Vec<u8> {
        let mut out = Vec::new();
        for row in rows {
            let mut text = Vec::new();
            for &v in row {
                macro_rules! put {
                    ($x:expr) => {
                        match enc {
                            Encoding::Ascii => text.push($x.to_string()),
                            Encoding::LittleEndian => out.extend_from_slice(&$x.to_le_bytes()),
                            Encoding::BigEndian => out.extend_from_slice(&$x.to_be_bytes()),
                        }
                    };
                }
                match v {
                    V::U8(x) => put!(x),
                    V::I8(x) => put!(x),
                    V::I16(x) => put!(x),
                    V::U16(x) => put!(x),
                    V::I32(x) => put!(x),
                    V::U32(x) => put!(x),
                    V::F32(x) => put!(x),
                    V::F64(x) => put!(x),
                }
            }
            if enc == Encoding::Ascii {
                out.extend_from_slice(text.join(" ").as_bytes());
                out.push(b'\n');
            }
        }
        out
    }

    pub(super) fn ply(header: &str, rows: &[Vec<V>], enc: Encoding) -> Vec<u8> {
        let format = match enc {
            Encoding::Ascii => "ascii",
            Encoding::LittleEndian => "binary_little_endian",
            Encoding::BigEndian => "binary_big_endian",
        };
        let mut out =
            format!("ply\nformat {format} 1.0\ncomment made by a test\n{header}end_header\n").into_bytes();
        out.extend(ply_body(rows, enc));
        out
    }

    pub(super) const ENCODINGS: [Encoding; 3] =
        [Encoding::Ascii, Encoding::LittleEndian, Encoding::BigEndian];

    pub(super) type ToValue = fn(f64) -> V;

    pub(super) fn four_vertices(ty: &str) -> String {
        format!("element vertex 4\nproperty {ty} x\nproperty {ty} y\nproperty {ty} z\n")
    }

    pub(super) fn unit_rows() -> Vec<Vec<V>> {
        CUBE[..4].iter().map(|p| p.iter().map(|&c| V::F32(c as f32)).collect()).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::super::read_points;
    use super::super::testutil::{fails_with, TempDir, CUBE};
    use super::build::{four_vertices, ply, unit_rows};
    use super::Encoding;

    #[test]
    fn ply_crlf_header() {
        let dir = TempDir::new();
        let text = "ply\r\nformat ascii 1.0\r\nelement vertex 4\r\nproperty float x\r\n\
                    property float y\r\nproperty float z\r\nend_header\r\n\
                    0 0 0\r\n1 0 0\r\n0 1 0\r\n0 0 1\r\n";
        let set = read_points(&dir.file("c.ply", text)).expect("crlf");
        assert_eq!(set.points, CUBE[..4]);
    }

    #[test]
    fn ply_comments_in_latin1_are_skipped_and_other_lines_must_be_text() {
        let dir = TempDir::new();
        let mut bytes = ply(&four_vertices("float"), &unit_rows(), Encoding::LittleEndian);
        // a comment written in Latin-1 ("comment unit: \xb5m"), after the one of `ply`
        let at = bytes.windows(7).rposition(|w| w == b"comment").unwrap();
        bytes.splice(at..at, b"comment unit: \xb5m\n".iter().copied());
        assert_eq!(read_points(&dir.file("latin1.ply", &bytes)).expect("latin1 comment").points, CUBE[..4]);
        let at = bytes.windows(7).position(|w| w == b"element").unwrap();
        bytes.splice(at..at, b"obj_info \xe9t\xe9\nelem\xe9nt\n".iter().copied());
        fails_with(&dir.file("bad.ply", &bytes), "line 6", "not text");
    }

    #[test]
    fn ply_missing_magic_or_bad_header() {
        let dir = TempDir::new();
        fails_with(&dir.file("a.ply", "0 0 0\n1 0 0\n0 1 0\n0 0 1\n"), "", "magic");
        fails_with(&dir.file("b.ply", b"\x00\x01binary junk"), "", "magic");
        let bad_headers = [
            ("format ascii 2.0\n", "line 2", "version"),
            ("format utf8 1.0\n", "line 2", "unknown format"),
            (
                "format ascii 1.0\nelement vertex 4\nproperty float32 x\nproperty float32 y\nelement\n",
                "line 6",
                "element",
            ),
            ("format ascii 1.0\nproperty float x\n", "line 3", "before any"),
            ("format ascii 1.0\nelement vertex four\n", "line 3", "four"),
            ("format ascii 1.0\nelement vertex 4\nproperty quad x\n", "line 4", "quad"),
            ("format ascii 1.0\nelement vertex 4\nproperty float x\nproperty float x\n", "line 5", "twice"),
            ("format ascii 1.0\nelement vertex 4\nproperty list float int x\n", "line 4", "integer"),
            (
                "format ascii 1.0\nelement vertex 1\nproperty float x\nelement vertex 3\nproperty float x\n",
                "line 5",
                "element 'vertex' declared twice",
            ),
            ("format ascii 1.0\nelemnt vertex 4\n", "line 3", "elemnt"),
            ("element vertex 4\nproperty float x\nproperty float y\nproperty float z\n", "", "format"),
            ("format ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n", "", "'z'"),
            ("format ascii 1.0\nelement point 4\nproperty float x\n", "", "vertex"),
        ];
        for (header, at, why) in bad_headers {
            fails_with(&dir.file("h.ply", format!("ply\n{header}end_header\n")), at, why);
        }
        let unended = format!("ply\nformat ascii 1.0\n{}", four_vertices("float"));
        fails_with(&dir.file("n.ply", unended), "", "end_header");
        let face_float =
            format!("{}element face 1\nproperty list uchar float vertex_indices\n", four_vertices("float"));
        fails_with(
            &dir.file("ff.ply", ply(&face_float, &unit_rows(), Encoding::Ascii)),
            "",
            "list of integers",
        );
    }
}
