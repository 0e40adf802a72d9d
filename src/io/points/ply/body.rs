//! The body of a PLY file: every declared element in order, value by value through one
//! [`Source`] interface over ascii tokens and binary bytes, or, for binary elements without lists,
//! record by record.

use std::path::Path;

use super::{Element, Encoding, Header, Kind, Role, Scalar};
use crate::error::{Error, Result};
use crate::io::points::{capacity, check_corners, check_finite, no_return, Fan, PointSet};

const TRUNC: &str = "truncated file, or wrong counts in the PLY header";
const BAD_COUNTS: &str = "wrong counts in the PLY header?";

/// Reads every element of the body in declaration order; data left over after the last one means
/// the header's counts are wrong.
pub(super) fn read(path: &Path, bytes: &[u8], header: &Header) -> Result<PointSet> {
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

    /// The next token as a value of type `ty`: for the integer types a whole number in the type's
    /// range, as the binary forms can only hold.
    fn value(&mut self, ty: Scalar) -> std::result::Result<f64, Fail> {
        self.int_or_float(ty).map(|v| v.map_or_else(|f| f, |i| i as f64))
    }

    /// The next token as an integer (for the integer types) or a float (`Err` inside `Ok`).
    fn int_or_float(&mut self, ty: Scalar) -> std::result::Result<std::result::Result<i64, f64>, Fail> {
        let tok = self.token()?;
        let text = std::str::from_utf8(tok).ok();
        let (lo, hi) = ty.range();
        let parsed = if ty.is_int() {
            text.and_then(super::super::whole_number).filter(|v| (lo..=hi).contains(v)).map(Ok)
        } else {
            text.and_then(|s| s.parse::<f64>().ok()).map(Err)
        };
        parsed.ok_or_else(|| {
            let shown = String::from_utf8_lossy(tok);
            let range =
                if ty.is_int() { format!(" (a whole number from {lo} to {hi})") } else { String::new() };
            Fail::Bad(format!("'{shown}' is not a valid {ty:?} value{range}"))
        })
    }
}

impl Source for AsciiSource<'_> {
    fn float(&mut self, ty: Scalar) -> std::result::Result<f64, Fail> {
        self.value(ty)
    }

    fn int(&mut self, ty: Scalar) -> std::result::Result<i64, Fail> {
        // the header admits only integer types where integers are read
        self.int_or_float(ty).map(|v| v.unwrap_or_else(|f| f as i64))
    }

    fn skip(&mut self, ty: Scalar, n: u64) -> std::result::Result<(), Fail> {
        // skipped values are checked all the same: a value that is no number of its type means
        // the line is not what the header says
        for _ in 0..n {
            self.value(ty)?;
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

/// `decode_f64` and `decode_i64`: one scalar of type `ty` from exactly its bytes, converted to
/// the target type (losslessly for the integer types; the header admits only integer types where
/// integers are read, so the float arms of `decode_i64` are never taken).
macro_rules! decode_as {
    ($name:ident, $out:ty) => {
        fn $name(b: &[u8], ty: Scalar, big: bool) -> $out {
            match ty {
                Scalar::I8 => <$out>::from(decode!(i8, b, big)),
                Scalar::U8 => <$out>::from(decode!(u8, b, big)),
                Scalar::I16 => <$out>::from(decode!(i16, b, big)),
                Scalar::U16 => <$out>::from(decode!(u16, b, big)),
                Scalar::I32 => <$out>::from(decode!(i32, b, big)),
                Scalar::U32 => <$out>::from(decode!(u32, b, big)),
                Scalar::F32 => decode!(f32, b, big) as $out,
                Scalar::F64 => decode!(f64, b, big) as $out,
            }
        }
    };
}

decode_as!(decode_f64, f64);
decode_as!(decode_i64, i64);

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
        // kept for now: whether they can be left out depends on faces yet to come
        let p = if no_return(&p) {
            p
        } else {
            check_finite(p).map_err(|r| Error::input(path, format!("vertex {i}"), r))?
        };
        set.points.push(p);
    }
    Ok(())
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
        read_property(src, el, pi, nverts, &mut xyz, set).map_err(|e| match e {
            InstanceError::Fail(Fail::Bad(why)) => {
                InstanceError::Fail(Fail::Bad(format!("property '{}': {why}", prop.name)))
            }
            other => other,
        })?;
    }
    if let Role::Vertex(_) = el.role {
        let p = if no_return(&xyz) { xyz } else { check_finite(xyz).map_err(InstanceError::Invalid)? };
        set.points.push(p);
    }
    Ok(())
}

/// Reads (or skips) property `pi` of one instance of `el`, into `xyz` where it is a coordinate.
fn read_property<S: Source>(
    src: &mut S,
    el: &Element,
    pi: usize,
    nverts: usize,
    xyz: &mut [f64; 3],
    set: &mut PointSet,
) -> std::result::Result<(), InstanceError> {
    let prop = &el.props[pi];
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
            let n =
                u64::try_from(n).map_err(|_| InstanceError::Invalid(format!("negative list length {n}")))?;
            if role == Role::Face(pi) {
                read_face(src, item, n, nverts, &mut set.triangles)?;
            } else {
                src.skip(item, n)?;
            }
        }
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
    check_corners(n).map_err(InstanceError::Invalid)?;
    let mut fan = Fan::default();
    for _ in 0..n {
        let raw = src.int(item)?;
        let v = usize::try_from(raw).ok().filter(|&v| v < nverts).ok_or_else(|| {
            InstanceError::Invalid(format!("vertex index {raw} out of range (file has {nverts} vertices)"))
        })?;
        fan.push(v, triangles);
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::super::build::{four_vertices, ply, unit_rows, ToValue, ENCODINGS, V};
    use super::super::Encoding;
    use crate::io::points::testutil::{fails_with, TempDir, CUBE};
    use crate::io::points::{read_mesh, read_points, PointSet};

    /// The points of [`rich_ply`]: their z is stored as int16, so it is a whole number.
    const RICH_POINTS: [[f64; 3]; 5] =
        [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [0.5, -2.25, 3.0]];

    /// Vertices with normals and colours before x, a float64 y, an int16 z, an unknown element
    /// with a list in between, and mixed polygons.
    fn rich_ply(enc: Encoding) -> Vec<u8> {
        let header = "obj_info whatever\nelement vertex 5\nproperty float nx\nproperty float ny\n\
                      property float nz\nproperty uchar red\nproperty uchar green\n\
                      property uchar blue\nproperty float x\nproperty float64 y\n\
                      property int16 z\nproperty int8 flag\n\
                      element material 2\nproperty list uint8 float32 params\nproperty ushort id\n\
                      element face 3\nproperty uchar flags\n\
                      property list uchar int vertex_indices\nproperty list uint16 uint32 other\n";
        let vertex = |p: [f64; 3]| {
            let normal_and_colour = [V::F32(0.0), V::F32(0.0), V::F32(1.0), V::U8(255), V::U8(128), V::U8(0)];
            let xyz_and_flag = [V::F32(p[0] as f32), V::F64(p[1]), V::I16(p[2] as i16), V::I8(-1)];
            [normal_and_colour.as_slice(), &xyz_and_flag].concat()
        };
        let face = |flags: u8, corners: &[i32], other: &[u32]| {
            let mut row = vec![V::U8(flags), V::U8(corners.len() as u8)];
            row.extend(corners.iter().map(|&c| V::I32(c)));
            row.push(V::U16(other.len() as u16));
            row.extend(other.iter().map(|&o| V::U32(o)));
            row
        };
        let mut rows: Vec<Vec<V>> = RICH_POINTS.iter().map(|&p| vertex(p)).collect();
        rows.push(vec![V::U8(2), V::F32(1.5), V::F32(-2.0), V::U16(7)]);
        rows.push(vec![V::U8(0), V::U16(9)]);
        rows.push(face(1, &[0, 1, 2], &[]));
        rows.push(face(0, &[1, 2, 3, 4], &[5, 6]));
        rows.push(face(0, &[4, 3, 0], &[]));
        ply(header, &rows, enc)
    }

    #[test]
    fn ply_ascii_and_binary_agree_with_extra_properties_and_elements() {
        let dir = TempDir::new();
        let sets: Vec<PointSet> = ENCODINGS
            .iter()
            .map(|&enc| read_points(&dir.file("r.ply", rich_ply(enc))).expect("ply"))
            .collect();
        for set in &sets {
            assert_eq!(set.points, RICH_POINTS);
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

    #[test]
    fn ply_points_only_and_all_scalar_types() {
        let dir = TempDir::new();
        let set =
            read_points(&dir.file("p.ply", ply(&four_vertices("float"), &unit_rows(), Encoding::Ascii)))
                .expect("ply");
        assert_eq!(set.points, CUBE[..4]);
        assert!(set.triangles.is_empty());
        // Each type under its two names.
        let make: [([&str; 2], ToValue); 8] = [
            (["char", "int8"], |c| V::I8(c as i8)),
            (["uchar", "uint8"], |c| V::U8(c as u8)),
            (["short", "int16"], |c| V::I16(c as i16)),
            (["ushort", "uint16"], |c| V::U16(c as u16)),
            (["int", "int32"], |c| V::I32(c as i32)),
            (["uint", "uint32"], |c| V::U32(c as u32)),
            (["float", "float32"], |c| V::F32(c as f32)),
            (["double", "float64"], V::F64),
        ];
        for (ty, f) in make.iter().flat_map(|(names, f)| names.map(|n| (n, f))) {
            let rows: Vec<Vec<V>> = CUBE[..4].iter().map(|p| p.iter().map(|&c| f(c)).collect()).collect();
            for enc in ENCODINGS {
                let set = read_points(&dir.file("t.ply", ply(&four_vertices(ty), &rows, enc)))
                    .unwrap_or_else(|e| panic!("{ty}: {e}"));
                assert_eq!(set.points, CUBE[..4], "{ty}");
            }
        }
    }

    /// Where a fault is reported: a line of an ascii file, or `binary` (a byte offset or the
    /// element instance) in a binary one.
    fn at(enc: Encoding, line: usize, binary: impl std::fmt::Display) -> String {
        match enc {
            Encoding::Ascii => format!("line {line}"),
            _ => binary.to_string(),
        }
    }

    #[test]
    fn ply_truncated_or_lying_counts() {
        let dir = TempDir::new();
        let header = four_vertices("float");
        for enc in ENCODINGS {
            let full = ply(&header, &unit_rows(), enc);
            // Truncated in the middle of the last vertex.
            let cut = &full[..full.len() - 3];
            fails_with(
                &dir.file("t.ply", cut),
                &at(enc, 12, format!("byte offset {}", cut.len())),
                "truncated",
            );
            // Header claims more vertices than present.
            let more = ply(&header.replace("vertex 4", "vertex 5"), &unit_rows(), enc);
            let end = format!("byte offset {}", more.len());
            fails_with(&dir.file("m.ply", more), &at(enc, 12, end), "truncated");
            // Header claims fewer vertices than present.
            let mut rows = unit_rows();
            rows.push(vec![V::F32(2.0), V::F32(2.0), V::F32(2.0)]);
            let after = at(enc, 13, format!("byte offset {}", full.len()));
            fails_with(&dir.file("l.ply", ply(&header, &rows, enc)), &after, "header");
            // Absurd counts must fail cleanly, not try to allocate.
            let huge = ply(&header.replace("vertex 4", "vertex 18446744073709551615"), &unit_rows(), enc);
            let end = format!("byte offset {}", huge.len());
            fails_with(&dir.file("h.ply", huge), &at(enc, 12, end), "truncated");
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
            let file = ply(&header, &rows, enc);
            let end = format!("byte offset {}", file.len());
            fails_with(&dir.file("f.ply", file), &end, "face 0");
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
                fails_with(&dir.file("f.ply", ply(&header, &rows, enc)), &at(enc, 15, "face 0"), want);
            }
        }
    }

    #[test]
    fn ply_non_finite_vertex() {
        let dir = TempDir::new();
        let mut rows = unit_rows();
        rows[2][1] = V::F32(f32::NAN);
        for enc in ENCODINGS {
            let file = dir.file("n.ply", ply(&four_vertices("float"), &rows, enc));
            fails_with(&file, &at(enc, 11, "vertex 2"), "non-finite");
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
            fails_with(&dir.file("l.ply", ply(header, &rows, enc)), &at(enc, 13, "vertex 3"), "non-finite");
        }
    }

    #[test]
    fn ply_vertices_without_a_return_are_left_out_of_points_and_refused_in_meshes() {
        let dir = TempDir::new();
        let mut rows = unit_rows();
        rows.insert(1, vec![V::F32(f32::NAN); 3]);
        rows.push(vec![V::F32(f32::NAN); 3]);
        let header = "element vertex 6\nproperty float x\nproperty float y\nproperty float z\n";
        for enc in ENCODINGS {
            let set = read_points(&dir.file("o.ply", ply(header, &rows, enc))).unwrap();
            assert_eq!(set.points.len(), 4, "{enc:?}");
            assert!(set.note.as_deref().unwrap().contains("2 point(s) without coordinates"), "{enc:?}");
            assert!(set.note.as_deref().unwrap().ends_with("the first at vertex 1"), "{enc:?}");
            // with faces the vertex cannot go
            let mut with_face = rows.clone();
            with_face.push(vec![V::U8(3), V::I32(0), V::I32(2), V::I32(3)]);
            let header = format!("{header}element face 1\nproperty list uchar int vertex_indices\n");
            fails_with(&dir.file("m.ply", ply(&header, &with_face, enc)), "vertex 1", "faces that may use");
        }
    }

    #[test]
    fn ply_ascii_bad_token() {
        let dir = TempDir::new();
        let text = ply(&four_vertices("float"), &unit_rows(), Encoding::Ascii);
        let text = String::from_utf8(text).expect("utf8").replace("\n1 0 0\n", "\n1 zero 0\n");
        fails_with(
            &dir.file("b.ply", text),
            "line 10",
            "vertex 1: property 'y': 'zero' is not a valid F32 value",
        );
    }

    #[test]
    fn ply_ascii_integers_must_fit_their_type() {
        let dir = TempDir::new();
        let header = "element vertex 4\nproperty short x\nproperty char y\nproperty int z\n\
                      property uchar red\nproperty list uchar uint extra\n";
        let row = |x: &str, y: &str, z: &str, red: &str, n: &str| format!("{x} {y} {z} {red} {n} 7 7\n");
        let good =
            [row("0", "0", "0", "0", "2"), row("1", "-128", "0", "255", "2"), row("0", "127", "0", "9", "2")];
        let file = |last: String| {
            let body: String = good.iter().cloned().chain([last]).collect();
            format!("ply\nformat ascii 1.0\n{header}end_header\n{body}").replace(" 7 7\n", " 7 4294967295\n")
        };
        let set = read_points(&dir.file("g.ply", file(row("0", "0", "1", "1", "2")))).unwrap();
        assert_eq!(set.points[1], [1.0, -128.0, 0.0]);
        // whole numbers written as decimals, as writers that format every value as a float do
        let set = read_points(&dir.file("d.ply", file(row("-3.0", "0", "1.2e1", "254.000", "2.0")))).unwrap();
        assert_eq!(set.points[3], [-3.0, 0.0, 12.0]);
        let cases = [
            (
                row("0", "-300", "1", "1", "2"),
                "property 'y': '-300' is not a valid I8 value (a whole number from -128 to 127)",
            ),
            (row("0", "0", "12.345", "1", "2"), "property 'z': '12.345' is not a valid I32 value"),
            (row("0", "0", "1", "256.0", "2"), "property 'red': '256.0' is not a valid U8 value"),
            (row("0", "0", "1", "1", "inf"), "property 'extra': 'inf' is not a valid U8 value"),
            (row("40000", "0", "1", "1", "2"), "property 'x': '40000' is not a valid I16 value"),
            (
                row("0", "0", "1", "399", "2"),
                "property 'red': '399' is not a valid U8 value (a whole number from 0 to 255)",
            ),
            (row("0", "0", "1", "-1", "2"), "property 'red': '-1' is not a valid U8 value"),
            (row("0", "0", "1", "1", "2.5"), "property 'extra': '2.5' is not a valid U8 value"),
            (
                row("0", "0", "1", "1", "2").replace(" 7 7", " 7 -7"),
                "property 'extra': '-7' is not a valid U32 value",
            ),
        ];
        for (last, why) in cases {
            fails_with(&dir.file("b.ply", file(last)), "line 13", &format!("vertex 3: {why}"));
        }
    }
}
