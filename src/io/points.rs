//! Reading scattered surface points, and the triangles of ground-truth meshes, from files.
//!
//! This module owns the input file formats: Wavefront OBJ, PLY (ascii and both binary byte
//! orders) and plain-text point lists (.xyz/.txt/.csv). Everything is returned in the file's own
//! coordinates; normalisation belongs to the caller. The files come from users, so every parser
//! validates as it goes and reports the line, vertex or byte offset at fault instead of
//! panicking or guessing.
//!
//! OBJ is parsed by hand rather than with `tobj`: tobj either duplicates positions when texture
//! coordinates are present (`single_index`) or re-indexes them per group, whereas the solver
//! needs the file's `v` records exactly, in file order.

use std::path::Path;

use crate::error::{Error, Result};

/// Fewer points than this cannot define a volume.
const MIN_POINTS: usize = 4;

const SUPPORTED: &str = ".obj, .ply, .xyz, .txt, .csv";

const TRUNC: &str = "truncated file, or wrong counts in the PLY header";
const BAD_COUNTS: &str = "wrong counts in the PLY header?";

/// Points and (optional) triangles read from a file, in the file's coordinates.
#[derive(Debug, Clone, Default)]
pub struct PointSet {
    pub points: Vec<[f64; 3]>,
    pub triangles: Vec<[usize; 3]>,
}

/// Read scattered points by extension: .obj, .ply, .xyz/.txt/.csv (case-insensitive). Triangles
/// are filled for .obj/.ply when faces exist (polygons fan-triangulated), empty for text.
///
/// Text files hold three numbers (x y z) per line, separated by whitespace and/or commas; `#`
/// starts a comment and blank lines are ignored. The first non-blank, non-comment line may be a
/// column header such as `x,y,z`, and is skipped, but only if none of its tokens is a number;
/// anywhere else a non-numeric token is an error.
///
/// Every coordinate must be finite and the file must hold at least 4 points.
pub fn read_points(path: &Path) -> Result<PointSet> {
    let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("").to_ascii_lowercase();
    let parse: fn(&Path, &[u8]) -> Result<PointSet> = match ext.as_str() {
        "obj" => parse_obj,
        "ply" => parse_ply,
        "xyz" | "txt" | "csv" => parse_text,
        _ => {
            let shown = if ext.is_empty() { "none".to_string() } else { format!("'.{ext}'") };
            return Err(Error::input(
                path,
                "",
                format!("unsupported file extension {shown}; supported: {SUPPORTED}"),
            ));
        }
    };
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, &e))?;
    let set = parse(path, &bytes)?;
    if set.points.len() < MIN_POINTS {
        return Err(Error::input(
            path,
            "",
            format!("only {} point(s); at least {MIN_POINTS} are needed", set.points.len()),
        ));
    }
    Ok(set)
}

/// Same as read_points but requires at least one triangle (for ground-truth meshes); error
/// otherwise.
pub fn read_mesh(path: &Path) -> Result<PointSet> {
    let set = read_points(path)?;
    if set.triangles.is_empty() {
        return Err(Error::input(
            path,
            "",
            "no faces: a mesh file (.obj or .ply with faces) is needed here, not just points",
        ));
    }
    Ok(set)
}

// ---------------------------------------------------------------------------------------------
// Shared helpers for the line-oriented text formats.

/// Text formats are decoded in one pass up front so that a binary file with the wrong
/// extension is reported once, with a position, instead of as a confusing parse error.
fn as_text<'a>(path: &Path, bytes: &'a [u8], what: &str) -> Result<&'a str> {
    let nul = bytes.iter().position(|&b| b == 0);
    let prefix = &bytes[..nul.unwrap_or(bytes.len())];
    let bad_at = match std::str::from_utf8(prefix) {
        Ok(text) => match nul {
            None => return Ok(text.strip_prefix('\u{feff}').unwrap_or(text)),
            Some(at) => at,
        },
        Err(e) => e.valid_up_to(),
    };
    let line = bytes[..bad_at].iter().filter(|&&b| b == b'\n').count() + 1;
    Err(Error::input(
        path,
        format!("line {line}"),
        format!("binary data at byte offset {bad_at}; this is not a text {what} file"),
    ))
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

// ---------------------------------------------------------------------------------------------
// Plain text: x y z per line.

fn parse_text(path: &Path, bytes: &[u8]) -> Result<PointSet> {
    let text = as_text(path, bytes, "point")?;
    // Typical lines are 20-40 bytes; under-guessing costs one regrowth, over-guessing memory.
    let mut points = Vec::with_capacity(capacity(usize::MAX, text.len(), 24));
    let mut seen_data = false;
    let is_sep = |c: char| c == ',' || c.is_ascii_whitespace();
    for (i, raw) in text.lines().enumerate() {
        let line = raw.split('#').next().unwrap_or("");
        let mut tokens = line.split(is_sep).filter(|t| !t.is_empty());
        let mut xyz = [0.0; 3];
        let mut n = 0;
        let mut bad_token = None;
        for tok in tokens.by_ref() {
            match tok.parse::<f64>() {
                Ok(v) if n < 3 => xyz[n] = v,
                Ok(_) => {}
                Err(_) => {
                    bad_token = Some(tok);
                    break;
                }
            }
            n += 1;
        }
        if n == 0 && bad_token.is_none() {
            continue;
        }
        let first_data_line = !seen_data;
        seen_data = true;
        let err = |reason: String| Error::input(path, format!("line {}", i + 1), reason);
        if let Some(tok) = bad_token {
            let all_words = line.split(is_sep).filter(|t| !t.is_empty()).all(|t| t.parse::<f64>().is_err());
            if first_data_line && all_words {
                continue;
            }
            return Err(err(format!("'{tok}' is not a number")));
        }
        if n != 3 {
            return Err(err(format!("expected 3 coordinates (x y z), found {n} values")));
        }
        points.push(check_finite(xyz).map_err(err)?);
    }
    if points.is_empty() {
        return Err(Error::input(path, "", "no points found"));
    }
    Ok(PointSet { points, triangles: Vec::new() })
}

// ---------------------------------------------------------------------------------------------
// Wavefront OBJ: only `v` and `f` records matter; materials, groups, normals and texture
// coordinates are irrelevant to the geometry and are ignored (so a missing .mtl is harmless).

fn parse_obj(path: &Path, bytes: &[u8]) -> Result<PointSet> {
    let text = as_text(path, bytes, "OBJ")?;
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
                for c in xyz.iter_mut() {
                    let tok =
                        tokens.next().ok_or_else(|| err("vertex needs 3 coordinates (v x y z)".into()))?;
                    *c = tok.parse().map_err(|_| err(format!("'{tok}' is not a number")))?;
                }
                // Extra values (w, or per-vertex colours) are legal and irrelevant here.
                set.points.push(check_finite(xyz).map_err(err)?);
            }
            Some("f") => {
                let defined = set.points.len();
                let (mut first, mut prev, mut n) = (0, 0, 0);
                for tok in tokens {
                    let v = obj_index(tok, defined).map_err(err)?;
                    if v >= defined && !matches!(max_forward, Some((m, _)) if m >= v) {
                        max_forward = Some((v, lineno));
                    }
                    match n {
                        0 => first = v,
                        1 => prev = v,
                        _ => {
                            set.triangles.push([first, prev, v]);
                            prev = v;
                        }
                    }
                    n += 1;
                }
                if n < 3 {
                    return Err(err(format!("face has {n} vertices; at least 3 are needed")));
                }
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

// ---------------------------------------------------------------------------------------------
// PLY.

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

fn parse_ply(path: &Path, bytes: &[u8]) -> Result<PointSet> {
    let header = parse_ply_header(path, bytes)?;
    let body = &bytes[header.body..];
    let nverts = header.elements.iter().find(|e| matches!(e.role, Role::Vertex(_))).map_or(0, |e| e.count);
    let mut set = PointSet::default();
    match header.encoding {
        Encoding::Ascii => {
            let mut src = AsciiSource { data: body, pos: 0, line: header.lines + 1 };
            for el in &header.elements {
                read_element(path, &mut src, el, nverts, true, &mut set)?;
            }
            src.skip_space();
            if src.pos < body.len() {
                return Err(Error::input(
                    path,
                    format!("line {}", src.line),
                    format!("data continues after the last element the header declares ({BAD_COUNTS})"),
                ));
            }
        }
        Encoding::LittleEndian | Encoding::BigEndian => {
            let big = header.encoding == Encoding::BigEndian;
            let mut src = BinarySource { data: bytes, pos: header.body, big };
            for el in &header.elements {
                match el.fixed_stride() {
                    Some(stride) => read_fixed_records(path, &mut src, el, stride, &mut set)?,
                    None => read_element(path, &mut src, el, nverts, false, &mut set)?,
                }
            }
            if src.pos < bytes.len() {
                return Err(Error::input(
                    path,
                    format!("byte offset {}", src.pos),
                    format!(
                        "{} bytes follow the last element the header declares ({BAD_COUNTS})",
                        bytes.len() - src.pos
                    ),
                ));
            }
        }
    }
    Ok(set)
}

fn parse_ply_header(path: &Path, bytes: &[u8]) -> Result<Header> {
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
        let line = std::str::from_utf8(raw)
            .map_err(|_| err("header line is not text (missing 'end_header'?)".into()))?;
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

/// Why a body value could not be read.
enum Fail {
    /// The data ran out.
    Eof,
    /// An ascii token is not a number of the declared type.
    Bad(String),
}

/// One interface over ascii tokens and binary bytes, so element walking is written once.
trait Source {
    fn float(&mut self, ty: Scalar) -> std::result::Result<f64, Fail>;
    fn int(&mut self, ty: Scalar) -> std::result::Result<i64, Fail>;
    fn skip(&mut self, ty: Scalar, n: u64) -> std::result::Result<(), Fail>;
    /// (location, reason prefix) for a problem with instance `inst` of element `el`.
    fn at(&self, el: &str, inst: usize) -> (String, String);
    /// Location of the end of the data, for truncation errors.
    fn end(&self) -> String;
    fn remaining(&self) -> usize;
}

struct AsciiSource<'a> {
    data: &'a [u8],
    pos: usize,
    line: usize,
}

impl<'a> AsciiSource<'a> {
    fn skip_space(&mut self) {
        while let Some(&b) = self.data.get(self.pos) {
            if !b.is_ascii_whitespace() {
                break;
            }
            if b == b'\n' {
                self.line += 1;
            }
            self.pos += 1;
        }
    }

    fn token(&mut self) -> std::result::Result<&'a [u8], Fail> {
        self.skip_space();
        let start = self.pos;
        while self.data.get(self.pos).is_some_and(|b| !b.is_ascii_whitespace()) {
            self.pos += 1;
        }
        if start == self.pos {
            return Err(Fail::Eof);
        }
        Ok(&self.data[start..self.pos])
    }

    fn parse<T: std::str::FromStr>(&mut self, ty: Scalar) -> std::result::Result<T, Fail> {
        let tok = self.token()?;
        std::str::from_utf8(tok).ok().and_then(|s| s.parse().ok()).ok_or_else(|| {
            let shown = String::from_utf8_lossy(tok);
            Fail::Bad(format!("'{shown}' is not a valid {ty:?} value"))
        })
    }
}

impl Source for AsciiSource<'_> {
    fn float(&mut self, ty: Scalar) -> std::result::Result<f64, Fail> {
        self.parse(ty)
    }

    fn int(&mut self, ty: Scalar) -> std::result::Result<i64, Fail> {
        self.parse(ty)
    }

    fn skip(&mut self, _ty: Scalar, n: u64) -> std::result::Result<(), Fail> {
        for _ in 0..n {
            self.token()?;
        }
        Ok(())
    }

    fn at(&self, el: &str, inst: usize) -> (String, String) {
        (format!("line {}", self.line), format!("{el} {inst}: "))
    }

    fn end(&self) -> String {
        // After a final newline the counter already points past the last line of data.
        let past_end = self.pos == self.data.len() && self.data.ends_with(b"\n");
        let line = self.line - usize::from(past_end && self.line > 1);
        format!("line {line}")
    }

    fn remaining(&self) -> usize {
        self.data.len() - self.pos
    }
}

struct BinarySource<'a> {
    data: &'a [u8],
    pos: usize,
    big: bool,
}

impl<'a> BinarySource<'a> {
    fn take(&mut self, n: usize) -> std::result::Result<&'a [u8], Fail> {
        let end = self.pos.checked_add(n).filter(|&e| e <= self.data.len()).ok_or(Fail::Eof)?;
        let out = &self.data[self.pos..end];
        self.pos = end;
        Ok(out)
    }
}

impl Source for BinarySource<'_> {
    fn float(&mut self, ty: Scalar) -> std::result::Result<f64, Fail> {
        Ok(decode_f64(self.take(ty.size())?, ty, self.big))
    }

    fn int(&mut self, ty: Scalar) -> std::result::Result<i64, Fail> {
        Ok(decode_i64(self.take(ty.size())?, ty, self.big))
    }

    fn skip(&mut self, ty: Scalar, n: u64) -> std::result::Result<(), Fail> {
        let bytes = usize::try_from(n).ok().and_then(|n| n.checked_mul(ty.size())).ok_or(Fail::Eof)?;
        self.take(bytes).map(|_| ())
    }

    fn at(&self, el: &str, inst: usize) -> (String, String) {
        (format!("{el} {inst}"), String::new())
    }

    fn end(&self) -> String {
        format!("byte offset {}", self.data.len())
    }

    fn remaining(&self) -> usize {
        self.data.len() - self.pos
    }
}

/// Copies the first N bytes; callers always pass slices of exactly the scalar's size.
fn arr<const N: usize>(b: &[u8]) -> [u8; N] {
    let mut a = [0; N];
    a.copy_from_slice(&b[..N]);
    a
}

macro_rules! decode {
    ($t:ty, $b:expr, $big:expr) => {
        if $big {
            <$t>::from_be_bytes(arr($b))
        } else {
            <$t>::from_le_bytes(arr($b))
        }
    };
}

fn decode_f64(b: &[u8], ty: Scalar, big: bool) -> f64 {
    match ty {
        Scalar::I8 => f64::from(decode!(i8, b, big)),
        Scalar::U8 => f64::from(decode!(u8, b, big)),
        Scalar::I16 => f64::from(decode!(i16, b, big)),
        Scalar::U16 => f64::from(decode!(u16, b, big)),
        Scalar::I32 => f64::from(decode!(i32, b, big)),
        Scalar::U32 => f64::from(decode!(u32, b, big)),
        Scalar::F32 => f64::from(decode!(f32, b, big)),
        Scalar::F64 => decode!(f64, b, big),
    }
}

fn decode_i64(b: &[u8], ty: Scalar, big: bool) -> i64 {
    match ty {
        Scalar::I8 => i64::from(decode!(i8, b, big)),
        Scalar::U8 => i64::from(decode!(u8, b, big)),
        Scalar::I16 => i64::from(decode!(i16, b, big)),
        Scalar::U16 => i64::from(decode!(u16, b, big)),
        Scalar::I32 => i64::from(decode!(i32, b, big)),
        Scalar::U32 => i64::from(decode!(u32, b, big)),
        // The header only admits integer types where integers are read.
        Scalar::F32 => decode!(f32, b, big) as i64,
        Scalar::F64 => decode!(f64, b, big) as i64,
    }
}

/// Binary elements without lists have a fixed record size: check the whole extent once and
/// slice records directly (the common case, and the one that matters for large point clouds).
fn read_fixed_records(
    path: &Path,
    src: &mut BinarySource<'_>,
    el: &Element,
    stride: usize,
    set: &mut PointSet,
) -> Result<()> {
    let available = src.data.len() - src.pos;
    let total = el.count.checked_mul(stride).filter(|&t| t <= available).ok_or_else(|| {
        Error::input(
            path,
            format!("byte offset {}", src.data.len()),
            format!(
                "file ends inside element '{}': {} x {stride} bytes declared, {available} left ({TRUNC})",
                el.name, el.count
            ),
        )
    })?;
    let start = src.pos;
    src.pos += total;
    let Role::Vertex(axes) = el.role else {
        return Ok(());
    };
    let mut layout = [(0, Scalar::F32); 3];
    for (slot, &pi) in layout.iter_mut().zip(&axes) {
        let offset: usize = el.props[..pi].iter().map(|p| p.min_size()).sum();
        if let Kind::Scalar(ty) = el.props[pi].kind {
            *slot = (offset, ty);
        }
    }
    set.points.reserve(el.count);
    // stride > 0 because the vertex element has at least x, y and z.
    for (i, rec) in src.data[start..start + total].chunks_exact(stride).enumerate() {
        let p = layout.map(|(off, ty)| decode_f64(&rec[off..], ty, src.big));
        let p = check_finite(p).map_err(|r| Error::input(path, format!("vertex {i}"), r))?;
        set.points.push(p);
    }
    Ok(())
}

impl Property {
    fn min_size(&self) -> usize {
        match self.kind {
            Kind::Scalar(s) => s.size(),
            Kind::List { count, .. } => count.size(),
        }
    }
}

/// Reads (or skips) every instance of one element, value by value.
fn read_element<S: Source>(
    path: &Path,
    src: &mut S,
    el: &Element,
    nverts: usize,
    ascii: bool,
    set: &mut PointSet,
) -> Result<()> {
    if el.props.is_empty() {
        // Instances without properties occupy no data; looping over a huge count would hang.
        return Ok(());
    }
    let reserve = capacity(el.count, src.remaining(), el.min_bytes(ascii));
    match el.role {
        Role::Vertex(_) => set.points.reserve(reserve),
        Role::Face(_) => set.triangles.reserve(reserve),
        Role::Skip => {}
    }
    for inst in 0..el.count {
        read_instance(src, el, nverts, set).map_err(|fail| match fail {
            InstanceError::Fail(Fail::Eof) => Error::input(
                path,
                src.end(),
                format!("file ends inside {} {inst} of {} declared ({TRUNC})", el.name, el.count),
            ),
            InstanceError::Fail(Fail::Bad(reason)) | InstanceError::Invalid(reason) => {
                let (loc, prefix) = src.at(&el.name, inst);
                Error::input(path, loc, format!("{prefix}{reason}"))
            }
        })?;
    }
    Ok(())
}

enum InstanceError {
    Fail(Fail),
    Invalid(String),
}

impl From<Fail> for InstanceError {
    fn from(f: Fail) -> Self {
        InstanceError::Fail(f)
    }
}

fn read_instance<S: Source>(
    src: &mut S,
    el: &Element,
    nverts: usize,
    set: &mut PointSet,
) -> std::result::Result<(), InstanceError> {
    let mut xyz = [0.0; 3];
    for (pi, prop) in el.props.iter().enumerate() {
        match (prop.kind, el.role) {
            (Kind::Scalar(ty), Role::Vertex(axes)) if axes.contains(&pi) => {
                let v = src.float(ty)?;
                for (c, &a) in xyz.iter_mut().zip(&axes) {
                    if a == pi {
                        *c = v;
                    }
                }
            }
            (Kind::Scalar(ty), _) => src.skip(ty, 1)?,
            (Kind::List { count, item }, role) => {
                let n = src.int(count)?;
                let n = u64::try_from(n)
                    .map_err(|_| InstanceError::Invalid(format!("negative list length {n}")))?;
                if role == Role::Face(pi) {
                    read_face(src, item, n, nverts, &mut set.triangles)?;
                } else {
                    src.skip(item, n)?;
                }
            }
        }
    }
    if let Role::Vertex(_) = el.role {
        set.points.push(check_finite(xyz).map_err(InstanceError::Invalid)?);
    }
    Ok(())
}

/// Fan-triangulates one polygon as its indices stream in, so no per-face allocation is needed.
fn read_face<S: Source>(
    src: &mut S,
    item: Scalar,
    n: u64,
    nverts: usize,
    triangles: &mut Vec<[usize; 3]>,
) -> std::result::Result<(), InstanceError> {
    if n < 3 {
        return Err(InstanceError::Invalid(format!("face has {n} vertices; at least 3 are needed")));
    }
    let (mut first, mut prev) = (0, 0);
    for j in 0..n {
        let raw = src.int(item)?;
        let v = usize::try_from(raw).ok().filter(|&v| v < nverts).ok_or_else(|| {
            InstanceError::Invalid(format!("vertex index {raw} out of range (file has {nverts} vertices)"))
        })?;
        match j {
            0 => first = v,
            1 => prev = v,
            _ => {
                triangles.push([first, prev, v]);
                prev = v;
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::PathBuf;
    use std::sync::atomic::{AtomicUsize, Ordering};

    const BUNNY: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/bunny10k.obj");
    const COW: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/cow.obj");

    /// A private directory per test, removed on drop, so parallel tests never collide.
    struct TempDir(PathBuf);

    impl TempDir {
        fn new() -> Self {
            static NEXT: AtomicUsize = AtomicUsize::new(0);
            let n = NEXT.fetch_add(1, Ordering::Relaxed);
            let dir = std::env::temp_dir().join(format!("volspline_points_{}_{n}", std::process::id()));
            std::fs::create_dir_all(&dir).expect("create temp dir");
            TempDir(dir)
        }

        fn file(&self, name: &str, contents: impl AsRef<[u8]>) -> PathBuf {
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

    const CUBE: [[f64; 3]; 5] =
        [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [0.5, -2.25, 3e-3]];

    /// Reads a file that must fail and returns (location, reason).
    fn fails(path: &Path) -> (String, String) {
        match read_points(path) {
            Err(Error::Input { location, reason, .. }) => (location, reason),
            other => panic!("expected an input error for {}, got {other:?}", path.display()),
        }
    }

    // ----- text -----------------------------------------------------------------------------

    #[test]
    fn text_whitespace_commas_comments_and_blank_lines() {
        let dir = TempDir::new();
        let text = "# a comment\n\n0 0 0\n1,0,0\n 0 ,\t1 , 0 # trailing\r\n0 0 1\n\n.5 -2.25e0 3e-3\n";
        for ext in ["xyz", "txt", "csv", "XYZ"] {
            let set = read_points(&dir.file(&format!("p.{ext}"), text)).expect(ext);
            assert_eq!(set.points, CUBE);
            assert!(set.triangles.is_empty());
        }
    }

    #[test]
    fn text_header_on_first_data_line_is_skipped() {
        let dir = TempDir::new();
        let set = read_points(&dir.file("h.csv", "# exported\nx,y,z\n0,0,0\n1,0,0\n0,1,0\n0,0,1\n"))
            .expect("header");
        assert_eq!(set.points.len(), 4);
    }

    #[test]
    fn text_header_later_or_mixed_is_an_error() {
        let dir = TempDir::new();
        let (loc, reason) = fails(&dir.file("a.csv", "0,0,0\nx,y,z\n1,0,0\n0,1,0\n0,0,1\n"));
        assert_eq!(loc, "line 2");
        assert!(reason.contains("'x'"), "{reason}");
        let (loc, _) = fails(&dir.file("b.csv", "x,1,z\n0,0,0\n1,0,0\n0,1,0\n0,0,1\n"));
        assert_eq!(loc, "line 1");
    }

    #[test]
    fn text_wrong_value_count_names_the_line() {
        let dir = TempDir::new();
        let (loc, reason) = fails(&dir.file("a.xyz", "0 0 0\n1 0 0\n\n0 1\n0 0 1\n"));
        assert_eq!(loc, "line 4");
        assert!(reason.contains("found 2"), "{reason}");
        let (loc, _) = fails(&dir.file("b.xyz", "0 0 0\n1 0 0 7\n0 1 0\n0 0 1\n"));
        assert_eq!(loc, "line 2");
    }

    #[test]
    fn text_non_finite_is_an_error() {
        let dir = TempDir::new();
        for bad in ["nan", "inf", "-inf", "NaN", "1e999"] {
            let (loc, reason) = fails(&dir.file("a.txt", format!("0 0 0\n1 0 0\n0 {bad} 0\n0 0 1\n")));
            assert_eq!(loc, "line 3", "{bad}");
            assert!(reason.contains("non-finite"), "{reason}");
        }
    }

    #[test]
    fn too_few_points_is_an_error() {
        let dir = TempDir::new();
        let (loc, reason) = fails(&dir.file("a.xyz", "0 0 0\n1 0 0\n0 1 0\n"));
        assert_eq!(loc, "");
        assert!(reason.contains("at least 4"), "{reason}");
        let (_, reason) = fails(&dir.file("empty.xyz", ""));
        assert!(reason.contains("no points"), "{reason}");
    }

    #[test]
    fn binary_data_in_a_text_file_is_an_error() {
        let dir = TempDir::new();
        let (loc, reason) = fails(&dir.file("a.xyz", b"0 0 0\n1 0 0\n\x00\x01\xff\x80 junk"));
        assert_eq!(loc, "line 3");
        assert!(reason.contains("binary"), "{reason}");
        let (_, reason) = fails(&dir.file("b.obj", [0x7fu8, b'E', b'L', b'F', 2, 1, 1, 0, 0xc3]));
        assert!(reason.contains("not a text OBJ"), "{reason}");
    }

    // ----- OBJ ------------------------------------------------------------------------------

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
        let (loc, reason) = fails(&dir.file("bad.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf -5 1 2\n"));
        assert_eq!(loc, "line 5");
        assert!(reason.contains("before the first vertex"), "{reason}");
    }

    #[test]
    fn obj_bad_indices_name_the_line() {
        let dir = TempDir::new();
        let v = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\n";
        let (loc, reason) = fails(&dir.file("a.obj", format!("{v}f 1 2 3\nf 1 2 9\nf 2 3 4\n")));
        assert_eq!(loc, "line 6");
        assert!(reason.contains("out of range"), "{reason}");
        let (loc, reason) = fails(&dir.file("b.obj", format!("{v}f 0 1 2\n")));
        assert_eq!(loc, "line 5");
        assert!(reason.contains("index 0"), "{reason}");
        let (loc, _) = fails(&dir.file("c.obj", format!("{v}f 1 2\n")));
        assert_eq!(loc, "line 5");
        let (loc, _) = fails(&dir.file("d.obj", format!("{v}f 1 x 2\n")));
        assert_eq!(loc, "line 5");
        // Forward references are legal OBJ as long as the vertex eventually exists.
        let set = read_points(&dir.file("e.obj", format!("f 1 2 3\n{v}"))).expect("forward");
        assert_eq!(set.triangles, vec![[0, 1, 2]]);
    }

    #[test]
    fn obj_bad_vertices_name_the_line() {
        let dir = TempDir::new();
        let (loc, reason) = fails(&dir.file("a.obj", "v 0 0 0\nv 1 0\nv 0 1 0\nv 0 0 1\n"));
        assert_eq!(loc, "line 2");
        assert!(reason.contains("3 coordinates"), "{reason}");
        let (loc, reason) = fails(&dir.file("b.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 nan 1\n"));
        assert_eq!(loc, "line 4");
        assert!(reason.contains("non-finite"), "{reason}");
        let (loc, reason) = fails(&dir.file("c.obj", "# nothing\nvt 0 0\n"));
        assert_eq!(loc, "");
        assert!(reason.contains("no vertices"), "{reason}");
    }

    #[test]
    fn real_bunny_obj() {
        let set = read_mesh(Path::new(BUNNY)).expect("bunny");
        assert_eq!(set.points.len(), 5051);
        assert_eq!(set.triangles.len(), 9999);
        assert!(set.triangles.iter().flatten().all(|&i| i < set.points.len()));
        assert_eq!(set.points[0], [-3.24965, 17.4231, -0.238999]);
        // Every vertex is used by some face in this model.
        let mut used = vec![false; set.points.len()];
        set.triangles.iter().flatten().for_each(|&i| used[i] = true);
        assert!(used.iter().all(|&u| u));
    }

    #[test]
    fn real_cow_obj() {
        let set = read_mesh(Path::new(COW)).expect("cow");
        assert_eq!(set.points.len(), 2904);
        assert_eq!(set.triangles.len(), 5804);
        assert!(set.triangles.iter().flatten().all(|&i| i < set.points.len()));
    }

    // ----- PLY ------------------------------------------------------------------------------

    #[derive(Clone, Copy)]
    enum V {
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

    fn ply(header: &str, rows: &[Vec<V>], enc: Encoding) -> Vec<u8> {
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

    const ENCODINGS: [Encoding; 3] = [Encoding::Ascii, Encoding::LittleEndian, Encoding::BigEndian];

    /// Vertices with normals and colours before x, a float64 y, an int16 z (so the cube's
    /// fifth point is rounded), an unknown element with a list in between, and mixed polygons.
    fn rich_ply(enc: Encoding) -> Vec<u8> {
        let header = "obj_info whatever\nelement vertex 5\nproperty float nx\nproperty float ny\n\
                      property float nz\nproperty uchar red\nproperty uchar green\n\
                      property uchar blue\nproperty float x\nproperty float64 y\n\
                      property int16 z\nproperty int8 flag\n\
                      element material 2\nproperty list uint8 float32 params\nproperty ushort id\n\
                      element face 3\nproperty uchar flags\n\
                      property list uchar int vertex_indices\nproperty list uint16 uint32 other\n";
        let mut rows: Vec<Vec<V>> = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]
            .iter()
            .chain(&[[0.0, 0.0, 1.0], [0.5, -2.25, 3.0]])
            .map(|p| {
                vec![
                    V::F32(0.0),
                    V::F32(0.0),
                    V::F32(1.0),
                    V::U8(255),
                    V::U8(128),
                    V::U8(0),
                    V::F32(p[0] as f32),
                    V::F64(p[1]),
                    V::I16(p[2] as i16),
                    V::I8(-1),
                ]
            })
            .collect();
        rows.push(vec![V::U8(2), V::F32(1.5), V::F32(-2.0), V::U16(7)]);
        rows.push(vec![V::U8(0), V::U16(9)]);
        rows.push(vec![V::U8(1), V::U8(3), V::I32(0), V::I32(1), V::I32(2), V::U16(0)]);
        rows.push(vec![
            V::U8(0),
            V::U8(4),
            V::I32(1),
            V::I32(2),
            V::I32(3),
            V::I32(4),
            V::U16(2),
            V::U32(5),
            V::U32(6),
        ]);
        rows.push(vec![V::U8(0), V::U8(3), V::I32(4), V::I32(3), V::I32(0), V::U16(0)]);
        ply(header, &rows, enc)
    }

    #[test]
    fn ply_ascii_and_binary_agree_with_extra_properties_and_elements() {
        let dir = TempDir::new();
        let sets: Vec<PointSet> = ENCODINGS
            .iter()
            .map(|&enc| read_points(&dir.file("r.ply", rich_ply(enc))).expect("ply"))
            .collect();
        let expected =
            [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [0.5, -2.25, 3.0]];
        for set in &sets {
            assert_eq!(set.points, expected);
            assert_eq!(set.triangles, vec![[0, 1, 2], [1, 2, 3], [1, 3, 4], [4, 3, 0]]);
        }
    }

    /// Vertex element declared after faces and a points-only element order variant.
    #[test]
    fn ply_faces_before_vertices() {
        let dir = TempDir::new();
        let header = "element face 1\nproperty list uchar uint vertex_index\n\
                      element vertex 4\nproperty double z\nproperty double y\nproperty double x\n";
        let rows = vec![
            vec![V::U8(3), V::U32(3), V::U32(2), V::U32(1)],
            vec![V::F64(0.0), V::F64(0.0), V::F64(0.0)],
            vec![V::F64(0.0), V::F64(0.0), V::F64(1.0)],
            vec![V::F64(0.0), V::F64(1.0), V::F64(0.0)],
            vec![V::F64(1.0), V::F64(0.0), V::F64(0.0)],
        ];
        for enc in ENCODINGS {
            let set = read_mesh(&dir.file("f.PLY", ply(header, &rows, enc))).expect("ply");
            assert_eq!(set.points, CUBE[..4]);
            assert_eq!(set.triangles, vec![[3, 2, 1]]);
        }
    }

    type ToValue = fn(f64) -> V;

    fn four_vertices(ty: &str) -> String {
        format!("element vertex 4\nproperty {ty} x\nproperty {ty} y\nproperty {ty} z\n")
    }

    fn unit_rows() -> Vec<Vec<V>> {
        CUBE[..4].iter().map(|p| p.iter().map(|&c| V::F32(c as f32)).collect()).collect()
    }

    #[test]
    fn ply_points_only_and_all_scalar_types() {
        let dir = TempDir::new();
        let set =
            read_points(&dir.file("p.ply", ply(&four_vertices("float"), &unit_rows(), Encoding::Ascii)))
                .expect("ply");
        assert_eq!(set.points, CUBE[..4]);
        assert!(set.triangles.is_empty());
        let make: [(&str, ToValue); 14] = [
            ("char", |c| V::I8(c as i8)),
            ("int8", |c| V::I8(c as i8)),
            ("uchar", |c| V::U8(c as u8)),
            ("uint8", |c| V::U8(c as u8)),
            ("short", |c| V::I16(c as i16)),
            ("int16", |c| V::I16(c as i16)),
            ("ushort", |c| V::U16(c as u16)),
            ("uint16", |c| V::U16(c as u16)),
            ("int", |c| V::I32(c as i32)),
            ("int32", |c| V::I32(c as i32)),
            ("uint", |c| V::U32(c as u32)),
            ("uint32", |c| V::U32(c as u32)),
            ("float64", V::F64),
            ("double", V::F64),
        ];
        for (ty, f) in make {
            let rows: Vec<Vec<V>> = CUBE[..4].iter().map(|p| p.iter().map(|&c| f(c)).collect()).collect();
            for enc in ENCODINGS {
                let set = read_points(&dir.file("t.ply", ply(&four_vertices(ty), &rows, enc)))
                    .unwrap_or_else(|e| panic!("{ty}: {e}"));
                assert_eq!(set.points, CUBE[..4], "{ty}");
            }
        }
    }

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
    fn ply_missing_magic_or_bad_header() {
        let dir = TempDir::new();
        let (loc, reason) = fails(&dir.file("a.ply", "0 0 0\n1 0 0\n0 1 0\n0 0 1\n"));
        assert_eq!(loc, "");
        assert!(reason.contains("magic"), "{reason}");
        let (_, reason) = fails(&dir.file("b.ply", b"\x00\x01binary junk"));
        assert!(reason.contains("magic"), "{reason}");
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
            ("format ascii 1.0\nelemnt vertex 4\n", "line 3", "elemnt"),
            ("element vertex 4\nproperty float x\nproperty float y\nproperty float z\n", "", "format"),
            ("format ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n", "", "'z'"),
            ("format ascii 1.0\nelement point 4\nproperty float x\n", "", "vertex"),
        ];
        for (header, want_loc, want) in bad_headers {
            let (loc, reason) = fails(&dir.file("h.ply", format!("ply\n{header}end_header\n")));
            assert_eq!(loc, want_loc, "{header}: {reason}");
            assert!(reason.contains(want), "{header}: {reason}");
        }
        let (_, reason) =
            fails(&dir.file("n.ply", format!("ply\nformat ascii 1.0\n{}", four_vertices("float"))));
        assert!(reason.contains("end_header"), "{reason}");
        let face_float =
            format!("{}element face 1\nproperty list uchar float vertex_indices\n", four_vertices("float"));
        let (_, reason) = fails(&dir.file("ff.ply", ply(&face_float, &unit_rows(), Encoding::Ascii)));
        assert!(reason.contains("list of integers"), "{reason}");
    }

    #[test]
    fn ply_truncated_or_lying_counts() {
        let dir = TempDir::new();
        let header = four_vertices("float");
        for enc in ENCODINGS {
            let full = ply(&header, &unit_rows(), enc);
            // Truncated in the middle of the last vertex.
            let cut = &full[..full.len() - 3];
            let (loc, reason) = fails(&dir.file("t.ply", cut));
            assert!(reason.contains("truncated"), "{reason}");
            if enc != Encoding::Ascii {
                assert_eq!(loc, format!("byte offset {}", cut.len()));
            }
            // Header claims more vertices than present.
            let more = ply(&header.replace("vertex 4", "vertex 5"), &unit_rows(), enc);
            let (_, reason) = fails(&dir.file("m.ply", more));
            assert!(reason.contains("truncated"), "{reason}");
            // Header claims fewer vertices than present.
            let mut rows = unit_rows();
            rows.push(vec![V::F32(2.0), V::F32(2.0), V::F32(2.0)]);
            let (loc, reason) = fails(&dir.file("l.ply", ply(&header, &rows, enc)));
            assert!(reason.contains("header"), "{reason}");
            if enc == Encoding::Ascii {
                assert_eq!(loc, "line 13");
            } else {
                assert!(loc.starts_with("byte offset"), "{loc}");
            }
            // Absurd counts must fail cleanly, not try to allocate.
            let huge = ply(&header.replace("vertex 4", "vertex 18446744073709551615"), &unit_rows(), enc);
            let (_, reason) = fails(&dir.file("h.ply", huge));
            assert!(reason.contains("truncated"), "{reason}");
        }
    }

    #[test]
    fn ply_truncated_face_list() {
        let dir = TempDir::new();
        let header =
            format!("{}element face 1\nproperty list uint int vertex_indices\n", four_vertices("float"));
        let mut rows = unit_rows();
        rows.push(vec![V::U32(4_000_000_000), V::I32(0), V::I32(1), V::I32(2)]);
        for enc in [Encoding::LittleEndian, Encoding::BigEndian] {
            let (loc, reason) = fails(&dir.file("f.ply", ply(&header, &rows, enc)));
            assert!(loc.starts_with("byte offset"), "{loc}");
            assert!(reason.contains("face 0"), "{reason}");
        }
    }

    #[test]
    fn ply_face_index_out_of_range_and_bad_lists() {
        let dir = TempDir::new();
        let header =
            format!("{}element face 1\nproperty list char int vertex_indices\n", four_vertices("float"));
        let cases: [(Vec<V>, &str); 4] = [
            (vec![V::I8(3), V::I32(0), V::I32(1), V::I32(4)], "out of range"),
            (vec![V::I8(3), V::I32(0), V::I32(-1), V::I32(2)], "out of range"),
            (vec![V::I8(2), V::I32(0), V::I32(1)], "at least 3"),
            (vec![V::I8(-3)], "negative"),
        ];
        for (face, want) in cases {
            let mut rows = unit_rows();
            rows.push(face);
            for enc in ENCODINGS {
                let (loc, reason) = fails(&dir.file("f.ply", ply(&header, &rows, enc)));
                assert!(reason.contains(want), "{reason}");
                let want_loc = if enc == Encoding::Ascii { "line 15" } else { "face 0" };
                assert_eq!(loc, want_loc, "{reason}");
            }
        }
    }

    #[test]
    fn ply_non_finite_vertex() {
        let dir = TempDir::new();
        let mut rows = unit_rows();
        rows[2][1] = V::F32(f32::NAN);
        for enc in ENCODINGS {
            let (loc, reason) = fails(&dir.file("n.ply", ply(&four_vertices("float"), &rows, enc)));
            assert!(reason.contains("non-finite"), "{reason}");
            let want_loc = if enc == Encoding::Ascii { "line 11" } else { "vertex 2" };
            assert_eq!(loc, want_loc);
        }
        // A vertex element with a list forces the value-by-value path; it must check too.
        let header = "element vertex 4\nproperty list uchar float extra\nproperty double x\n\
                      property double y\nproperty double z\n";
        let rows: Vec<Vec<V>> = (0..4)
            .map(|i| {
                let y = if i == 3 { f64::INFINITY } else { 0.0 };
                vec![V::U8(1), V::F32(9.0), V::F64(i as f64), V::F64(y), V::F64(0.0)]
            })
            .collect();
        for enc in ENCODINGS {
            let (loc, reason) = fails(&dir.file("l.ply", ply(header, &rows, enc)));
            assert!(reason.contains("non-finite"), "{reason}");
            let want_loc = if enc == Encoding::Ascii { "line 13" } else { "vertex 3" };
            assert_eq!(loc, want_loc);
        }
    }

    #[test]
    fn ply_ascii_bad_token() {
        let dir = TempDir::new();
        let text = ply(&four_vertices("float"), &unit_rows(), Encoding::Ascii);
        let text = String::from_utf8(text).expect("utf8").replace("\n1 0 0\n", "\n1 zero 0\n");
        let (loc, reason) = fails(&dir.file("b.ply", text));
        assert_eq!(loc, "line 10");
        assert!(reason.contains("'zero'") && reason.contains("vertex 1"), "{reason}");
    }

    // ----- dispatch -------------------------------------------------------------------------

    #[test]
    fn unknown_extension_lists_supported_ones() {
        let dir = TempDir::new();
        for name in ["p.stl", "noext"] {
            let (loc, reason) = fails(&dir.file(name, "0 0 0\n"));
            assert_eq!(loc, "");
            assert!(reason.contains(".obj, .ply, .xyz, .txt, .csv"), "{reason}");
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
        let points_ply = ply(&four_vertices("float"), &unit_rows(), Encoding::LittleEndian);
        for path in [dir.file("a.xyz", text), dir.file("b.obj", obj), dir.file("c.ply", points_ply)] {
            assert!(read_points(&path).is_ok());
            match read_mesh(&path) {
                Err(Error::Input { reason, .. }) => {
                    assert!(reason.contains("no faces"), "{reason}")
                }
                other => panic!("{other:?}"),
            }
        }
    }

    /// Timing check for large inputs; run with `cargo test --release -- --ignored --nocapture`.
    #[test]
    #[ignore]
    fn million_point_text_and_ply_speed() {
        let dir = TempDir::new();
        let n = 1_000_000;
        let mut text = String::with_capacity(n * 40);
        let mut bin = format!(
            "ply\nformat binary_little_endian 1.0\nelement vertex {n}\nproperty float x\n\
             property float y\nproperty float z\nend_header\n"
        )
        .into_bytes();
        for i in 0..n {
            let p = [i as f64 * 1e-3, (i % 977) as f64 * 0.125, -(i as f64).sqrt()];
            text.push_str(&format!("{} {} {}\n", p[0], p[1], p[2]));
            p.iter().for_each(|c| bin.extend_from_slice(&(*c as f32).to_le_bytes()));
        }
        let txt = dir.file("big.xyz", &text);
        let ply = dir.file("big.ply", &bin);
        let t = std::time::Instant::now();
        let set = read_points(&txt).expect("text");
        let dt = t.elapsed();
        assert_eq!(set.points.len(), n);
        println!("1M-point text ({} MB): {dt:?}", text.len() >> 20);
        let t = std::time::Instant::now();
        assert_eq!(read_points(&ply).expect("ply").points.len(), n);
        println!("1M-point binary ply: {:?}", t.elapsed());
        let t = std::time::Instant::now();
        assert_eq!(read_points(Path::new(BUNNY)).expect("bunny").points.len(), 5051);
        println!("bunny: {:?}", t.elapsed());
    }
}
