//! PCD, the Point Cloud Library's format (version 0.7 and the 0.6/0.5 headers without VIEWPOINT),
//! as robot and depth-camera pipelines write it: a text header naming the fields, then the points
//! as text (`DATA ascii`), as packed records (`DATA binary`) or LZF-compressed field by field
//! (`DATA binary_compressed`).
//!
//! ```text
//! VERSION 0.7
//! FIELDS x y z rgb          (names; `_` is padding)
//! SIZE 4 4 4 4              (bytes of one value: 1, 2, 4 or 8)
//! TYPE F F F U              (F float, I signed, U unsigned integer)
//! COUNT 1 1 1 1             (values per field, 1 when the line is absent)
//! WIDTH 640                 (points per row of an organised cloud)
//! HEIGHT 480                (rows; 1 for an unorganised cloud)
//! VIEWPOINT 0 0 0 1 0 0 0   (the sensor's pose; the points are not moved by it)
//! POINTS 307200
//! DATA binary
//! ```
//!
//! The coordinates are the fields x, y and z; every other field is skipped. A binary record is the
//! fields in order, COUNT x SIZE bytes each, little-endian; the compressed form is two u32 sizes
//! (compressed, uncompressed) and an LZF stream that expands to all points' first field, then all
//! points' second, and so on. Data beyond the points the header declares is refused, as are ascii
//! values that are no number of their field's type (an integer type's values must be whole numbers
//! in its range, written as integers or as decimals that are exactly one, `12.0`). Organised clouds mark pixels without a return with NaN coordinates: those points
//! are left out, with the other readers' note.

use std::path::Path;

use super::{check_finite, no_return, no_return_note, PointSet};
use crate::error::{Error, Result};

/// One field of the header.
#[derive(Debug, Clone)]
struct Field {
    name: String,
    size: usize,
    kind: u8,
    count: usize,
}

impl Field {
    fn bytes(&self) -> usize {
        self.size * self.count
    }

    /// One value of this field written as text: a number, for the integer types a whole number in
    /// the type's range, as the binary forms can only hold.
    fn parse(&self, tok: &str) -> std::result::Result<f64, String> {
        let bits = 8 * self.size as u32;
        let (value, range) = match self.kind {
            b'F' => (tok.parse::<f64>().ok(), String::new()),
            b'U' => {
                let hi = u64::MAX >> (64 - bits);
                let v = tok.parse::<u64>().ok().or_else(|| super::whole_number(tok)?.try_into().ok());
                (v.filter(|&v| v <= hi).map(|v| v as f64), format!("from 0 to {hi}"))
            }
            _ => {
                let (lo, hi) = (i64::MIN >> (64 - bits), i64::MAX >> (64 - bits));
                let v = super::whole_number(tok).filter(|v| (lo..=hi).contains(v));
                (v.map(|v| v as f64), format!("from {lo} to {hi}"))
            }
        };
        value.ok_or_else(|| {
            let what =
                if range.is_empty() { "a number".to_string() } else { format!("a whole number {range}") };
            format!(
                "field '{}' (TYPE {}, SIZE {}): '{tok}' is not {what}",
                self.name, self.kind as char, self.size
            )
        })
    }

    /// The first value of this field at the start of `b`, little-endian.
    fn value(&self, b: &[u8]) -> f64 {
        let mut w = [0u8; 8];
        w[..self.size].copy_from_slice(&b[..self.size]);
        match (self.kind, self.size) {
            (b'F', 4) => f32::from_le_bytes([w[0], w[1], w[2], w[3]]) as f64,
            (b'F', _) => f64::from_le_bytes(w),
            (b'U', _) => u64::from_le_bytes(w) as f64,
            (_, s) => {
                // sign-extend from the value's width
                let shift = 64 - 8 * s as u32;
                ((i64::from_le_bytes(w) << shift) >> shift) as f64
            }
        }
    }
}

/// What the header says.
struct Header {
    fields: Vec<Field>,
    points: usize,
    data: String,
    /// The byte after the DATA line.
    body: usize,
    /// The line of the DATA keyword.
    data_line: usize,
}

pub(super) fn parse(path: &Path, bytes: &[u8]) -> Result<PointSet> {
    let h = header(path, bytes)?;
    let axes: [usize; 3] =
        ["x", "y", "z"].map(|a| h.fields.iter().position(|f| f.name == a).unwrap_or(usize::MAX));
    if let Some(a) = (0..3).find(|&a| axes[a] == usize::MAX) {
        return Err(Error::input(
            path,
            "",
            format!(
                "no field '{}' among FIELDS {}: a point file needs x, y and z",
                ["x", "y", "z"][a],
                h.fields.iter().map(|f| f.name.as_str()).collect::<Vec<_>>().join(" ")
            ),
        ));
    }
    let mut raw = Vec::with_capacity(h.points.min(bytes.len() / 3 + 1));
    let body = &bytes[h.body..];
    match h.data.as_str() {
        "ascii" => ascii(path, body, &h, axes, &mut raw)?,
        "binary" => binary(path, body, &h, axes, &mut raw)?,
        "binary_compressed" => compressed(path, body, &h, axes, &mut raw)?,
        other => {
            return Err(Error::input(
                path,
                format!("line {}", h.data_line),
                format!("DATA '{other}': expected ascii, binary or binary_compressed"),
            ))
        }
    }
    let mut set = PointSet::default();
    let mut missing = (0, None);
    for (i, p) in raw.into_iter().enumerate() {
        if no_return(&p) {
            missing.0 += 1;
            missing.1.get_or_insert(i);
            continue;
        }
        let p = check_finite(p).map_err(|why| Error::input(path, format!("point {i}"), why))?;
        set.points.push(p);
    }
    if let Some(first) = missing.1 {
        set.note = Some(no_return_note(missing.0, &format!("point {first}")));
    }
    if set.points.is_empty() {
        let why = set.note.map_or(String::new(), |n| format!(" ({n})"));
        return Err(Error::input(path, "", format!("no points found{why}")));
    }
    Ok(set)
}

fn header(path: &Path, bytes: &[u8]) -> Result<Header> {
    let (mut names, mut sizes, mut kinds, mut counts) = (None, None, None, None);
    let (mut width, mut height, mut points) = (None, None, None);
    let mut pos = 0;
    let mut lineno = 0;
    loop {
        if pos >= bytes.len() {
            return Err(Error::input(path, "", "the header has no DATA line; is this a PCD file?"));
        }
        let end = bytes[pos..].iter().position(|&b| b == b'\n').map_or(bytes.len(), |k| pos + k + 1);
        let raw = &bytes[pos..end];
        pos = end;
        lineno += 1;
        let at = format!("line {lineno}");
        let err = |reason: String| Error::input(path, &at, reason);
        let Ok(line) = std::str::from_utf8(raw) else {
            return Err(err("a header line that is not text; is this a PCD file?".into()));
        };
        let line = line.split('#').next().unwrap_or("");
        let mut tokens = line.split_ascii_whitespace();
        let Some(key) = tokens.next() else { continue };
        let args: Vec<&str> = tokens.collect();
        let numbers = |what: &str| -> Result<Vec<usize>> {
            args.iter()
                .map(|t| t.parse::<usize>().map_err(|_| err(format!("{what}: '{t}' is not a count"))))
                .collect()
        };
        let one = |what: &str| -> Result<usize> {
            match numbers(what)?.as_slice() {
                [n] => Ok(*n),
                _ => Err(err(format!("{what} takes one number"))),
            }
        };
        match key {
            "VERSION" | "VIEWPOINT" => {}
            "FIELDS" | "COLUMNS" => names = Some(args.iter().map(|s| s.to_string()).collect::<Vec<_>>()),
            "SIZE" => sizes = Some(numbers("SIZE")?),
            "TYPE" => {
                let k: Vec<u8> = args.iter().map(|t| t.as_bytes().first().copied().unwrap_or(b'?')).collect();
                if let Some(t) = args.iter().find(|t| !matches!(**t, "F" | "I" | "U")) {
                    return Err(err(format!("TYPE '{t}': expected F, I or U")));
                }
                kinds = Some(k);
            }
            "COUNT" => counts = Some(numbers("COUNT")?),
            "WIDTH" => width = Some(one("WIDTH")?),
            "HEIGHT" => height = Some(one("HEIGHT")?),
            "POINTS" => points = Some(one("POINTS")?),
            "DATA" => {
                let data = args.first().map_or(String::new(), |d| d.to_string());
                let names = names.ok_or_else(|| err("DATA before FIELDS".into()))?;
                let sizes = sizes.ok_or_else(|| err("DATA before SIZE".into()))?;
                let kinds = kinds.ok_or_else(|| err("DATA before TYPE".into()))?;
                let counts = counts.unwrap_or_else(|| vec![1; names.len()]);
                if [sizes.len(), kinds.len(), counts.len()].iter().any(|&l| l != names.len()) {
                    return Err(err(format!(
                        "FIELDS names {} fields, SIZE gives {}, TYPE {}, COUNT {}: they must agree",
                        names.len(),
                        sizes.len(),
                        kinds.len(),
                        counts.len()
                    )));
                }
                let mut fields = Vec::with_capacity(names.len());
                for (((name, size), kind), count) in names.into_iter().zip(sizes).zip(kinds).zip(counts) {
                    let ok = match kind {
                        b'F' => size == 4 || size == 8,
                        _ => matches!(size, 1 | 2 | 4 | 8),
                    };
                    if !ok || count == 0 {
                        return Err(err(format!(
                            "field '{name}': SIZE {size}, TYPE {}, COUNT {count} is not a PCD value type",
                            kind as char
                        )));
                    }
                    fields.push(Field { name, size, kind, count });
                }
                let points = match (points, width, height) {
                    (Some(p), ..) => p,
                    (None, Some(w), Some(h)) => w.saturating_mul(h),
                    _ => return Err(err("neither POINTS nor WIDTH and HEIGHT say how many points".into())),
                };
                if let (Some(w), Some(h)) = (width, height) {
                    if w.checked_mul(h) != Some(points) {
                        return Err(err(format!("POINTS {points} is not WIDTH {w} x HEIGHT {h}")));
                    }
                }
                return Ok(Header { fields, points, data, body: pos, data_line: lineno });
            }
            other => return Err(err(format!("'{other}' is not a PCD header keyword"))),
        }
    }
}

fn ascii(path: &Path, body: &[u8], h: &Header, axes: [usize; 3], out: &mut Vec<[f64; 3]>) -> Result<()> {
    let text = crate::io::text::decode(path, body, "PCD")?;
    let width: usize = h.fields.iter().map(|f| f.count).sum();
    let data_line = h.data_line;
    for (i, line) in text.lines().enumerate() {
        let err = |reason: String| Error::input(path, format!("line {}", data_line + 1 + i), reason);
        let tokens: Vec<&str> = line.split_ascii_whitespace().collect();
        if tokens.is_empty() {
            continue;
        }
        if out.len() == h.points {
            return Err(err(format!("more points than POINTS {}", h.points)));
        }
        if tokens.len() != width {
            return Err(err(format!("found {} values, where the fields have {width}", tokens.len())));
        }
        // every value is checked against its field's type, so that a line that is not what the
        // header says is named
        let mut p = [0.0; 3];
        let mut at = 0;
        for (fi, f) in h.fields.iter().enumerate() {
            for (k, t) in tokens[at..at + f.count].iter().enumerate() {
                let v = f.parse(t).map_err(err)?;
                if let (0, Some(a)) = (k, axes.iter().position(|&a| a == fi)) {
                    p[a] = v;
                }
            }
            at += f.count;
        }
        out.push(p);
    }
    if out.len() != h.points {
        return Err(Error::input(path, "", format!("{} points, where POINTS says {}", out.len(), h.points)));
    }
    Ok(())
}

fn binary(path: &Path, body: &[u8], h: &Header, axes: [usize; 3], out: &mut Vec<[f64; 3]>) -> Result<()> {
    let stride: usize = h.fields.iter().map(Field::bytes).sum();
    let need = stride.checked_mul(h.points).filter(|&n| n <= body.len()).ok_or_else(|| {
        Error::input(
            path,
            "",
            format!(
                "POINTS {} of {stride} bytes each need {} bytes after the header; the file has {} (truncated?)",
                h.points,
                stride as u128 * h.points as u128,
                body.len()
            ),
        )
    })?;
    if body.len() > need {
        return Err(Error::input(
            path,
            format!("byte offset {}", h.body + need),
            format!(
                "{} bytes follow the {} points the header declares (POINTS {} of {stride} bytes); wrong \
                 WIDTH, HEIGHT or POINTS in the header?",
                body.len() - need,
                h.points,
                h.points
            ),
        ));
    }
    let offsets: Vec<usize> =
        h.fields.iter().scan(0, |o, f| Some(std::mem::replace(o, *o + f.bytes()))).collect();
    for rec in body[..need].chunks_exact(stride) {
        out.push(axes.map(|a| h.fields[a].value(&rec[offsets[a]..])));
    }
    Ok(())
}

fn compressed(path: &Path, body: &[u8], h: &Header, axes: [usize; 3], out: &mut Vec<[f64; 3]>) -> Result<()> {
    let word =
        |at: usize| body.get(at..at + 4).map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as usize);
    let (Some(packed), Some(size)) = (word(0), word(4)) else {
        return Err(Error::input(path, "", "binary_compressed data without its two sizes (truncated?)"));
    };
    let stride: usize = h.fields.iter().map(Field::bytes).sum();
    if stride.checked_mul(h.points) != Some(size) {
        return Err(Error::input(
            path,
            "",
            format!(
                "the compressed data expand to {size} bytes, but POINTS {} of {stride} bytes take {}",
                h.points,
                stride as u128 * h.points as u128
            ),
        ));
    }
    let stream = body.get(8..8 + packed).ok_or_else(|| {
        Error::input(
            path,
            "",
            format!(
                "{packed} bytes of compressed data declared, {} present (truncated?)",
                body.len().saturating_sub(8)
            ),
        )
    })?;
    if body.len() > 8 + packed {
        return Err(Error::input(
            path,
            format!("byte offset {}", h.body + 8 + packed),
            format!(
                "{} bytes follow the {packed} bytes of compressed data that its size declares",
                body.len() - 8 - packed
            ),
        ));
    }
    let data =
        lzf_expand(stream, size).map_err(|why| Error::input(path, "", format!("compressed data: {why}")))?;
    // field by field: all points' values of field 0, then of field 1, ...
    let starts: Vec<usize> =
        h.fields.iter().scan(0, |o, f| Some(std::mem::replace(o, *o + f.bytes() * h.points))).collect();
    for i in 0..h.points {
        out.push(axes.map(|a| {
            let f = &h.fields[a];
            f.value(&data[starts[a] + i * f.bytes()..])
        }));
    }
    Ok(())
}

/// Expands an LZF stream to exactly `size` bytes. Each run starts with a control byte c: c < 32
/// copies the next c + 1 bytes; otherwise it repeats len = (c >> 5) + 2 bytes (with a further
/// length byte added when c >> 5 is 7) from ((c & 31) << 8) + next byte + 1 bytes back.
fn lzf_expand(input: &[u8], size: usize) -> std::result::Result<Vec<u8>, String> {
    // a run of three bytes expands to at most 264: a header that lies cannot make us reserve more
    let mut out = Vec::with_capacity(size.min(input.len().saturating_mul(88)));
    let mut ip = 0;
    let short = |at: usize| format!("the stream ends inside the run at byte {at}");
    while ip < input.len() {
        let at = ip;
        let c = input[ip] as usize;
        ip += 1;
        if c < 32 {
            let run = input.get(ip..ip + c + 1).ok_or_else(|| short(at))?;
            out.extend_from_slice(run);
            ip += c + 1;
        } else {
            let mut len = c >> 5;
            if len == 7 {
                len += *input.get(ip).ok_or_else(|| short(at))? as usize;
                ip += 1;
            }
            len += 2;
            let back = ((c & 31) << 8) + *input.get(ip).ok_or_else(|| short(at))? as usize + 1;
            ip += 1;
            let from = out.len().checked_sub(back).ok_or_else(|| {
                format!("the run at byte {at} refers {back} bytes back, before the start of the data")
            })?;
            for k in 0..len {
                out.push(out[from + k]);
            }
        }
        if out.len() > size {
            return Err(format!("the stream expands past the {size} bytes declared (at byte {at})"));
        }
    }
    if out.len() != size {
        return Err(format!("the stream expands to {} bytes, not the {size} declared", out.len()));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::super::read_points;
    use super::super::testutil::{fails_with, TempDir};
    use super::*;

    #[test]
    fn lzf_literals_and_back_references_expand() {
        // "abc", then 6 bytes from 3 back, then 12 bytes from 1 back (the extra length byte)
        let stream = [2, b'a', b'b', b'c', 4 << 5, 2, 7 << 5, 3, 0];
        assert_eq!(lzf_expand(&stream, 21).unwrap(), b"abcabcabccccccccccccc");
        assert!(lzf_expand(&stream, 20).unwrap_err().contains("past the 20 bytes"));
        assert!(lzf_expand(&stream, 22).unwrap_err().contains("to 21 bytes, not the 22"));
        assert!(lzf_expand(&[4 << 5, 0], 6).unwrap_err().contains("before the start"));
        assert!(lzf_expand(&[5, b'a'], 6).unwrap_err().contains("ends inside the run at byte 0"));
    }

    fn head(fields: &str, size: &str, kind: &str, count: &str, n: usize, data: &str) -> String {
        format!(
            "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\nFIELDS {fields}\nSIZE {size}\nTYPE {kind}\n\
             COUNT {count}\nWIDTH {n}\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS {n}\nDATA {data}\n"
        )
    }

    #[test]
    fn the_three_encodings_give_the_same_points() {
        let pts: [[f64; 3]; 5] =
            [[0.5, -1.25, 2.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [3.0, 2.0, 1.0]];
        let dir = TempDir::new();
        // x y z among other fields: a colour before them, a 3-value normal, a double and a short
        let h =
            |data| head("rgb x y z normal _ t", "4 4 4 8 4 1 2", "U F F F F U I", "1 1 1 1 3 1 1", 5, data);
        let mut ascii = h("ascii");
        let mut binary = h("binary").into_bytes();
        let mut soa: [Vec<u8>; 7] = Default::default();
        for (i, p) in pts.iter().enumerate() {
            ascii.push_str(&format!("4278190080 {} {} {} 0 0 1 7 -3\n", p[0], p[1], p[2]));
            let rec: [Vec<u8>; 7] = [
                4278190080u32.to_le_bytes().to_vec(),
                (p[0] as f32).to_le_bytes().to_vec(),
                (p[1] as f32).to_le_bytes().to_vec(),
                p[2].to_le_bytes().to_vec(),
                [0f32, 0., 1.].iter().flat_map(|v| v.to_le_bytes()).collect(),
                vec![i as u8],
                (-3i16).to_le_bytes().to_vec(),
            ];
            for (f, r) in rec.iter().enumerate() {
                binary.extend(r);
                soa[f].extend(r);
            }
        }
        // the field-by-field data as an LZF stream of literal runs of at most 32 bytes
        let flat: Vec<u8> = soa.concat();
        let stream: Vec<u8> =
            flat.chunks(32).flat_map(|c| [vec![c.len() as u8 - 1], c.to_vec()].concat()).collect();
        let mut compressed = h("binary_compressed").into_bytes();
        compressed.extend((stream.len() as u32).to_le_bytes());
        compressed.extend((flat.len() as u32).to_le_bytes());
        compressed.extend(stream);
        for (name, bytes) in [("a.pcd", ascii.into_bytes()), ("b.pcd", binary), ("c.PCD", compressed)] {
            let set = read_points(&dir.file(name, bytes)).unwrap();
            assert_eq!(set.points, pts, "{name}");
            assert!(set.note.is_none(), "{name}");
        }
    }

    #[test]
    fn organised_clouds_lose_their_pixels_without_a_return() {
        let dir = TempDir::new();
        let mut text = head("x y z", "4 4 4", "F F F", "1 1 1", 6, "ascii")
            .replace("WIDTH 6\nHEIGHT 1", "WIDTH 3\nHEIGHT 2");
        text.push_str("0 0 0\nnan nan nan\n1 0 0\n0 1 0\nnan nan nan\n0 0 1\n");
        let set = read_points(&dir.file("o.pcd", text)).unwrap();
        assert_eq!(set.points.len(), 4);
        assert!(set.note.unwrap().ends_with("2 point(s) without coordinates (x, y and z all NaN: scanner pixels with no return) left out, the first at point 1"));
    }

    #[test]
    fn broken_pcd_files_name_the_fault() {
        let dir = TempDir::new();
        let pts = "0 0 0\n1 0 0\n0 1 0\n0 0 1\n";
        let good = head("x y z", "4 4 4", "F F F", "1 1 1", 4, "ascii");
        let cases: Vec<(String, &str, &str)> = vec![
            (
                head("x y", "4 4", "F F", "1 1", 4, "ascii") + "0 0\n1 0\n0 1\n1 1\n",
                "",
                "no field 'z' among FIELDS x y",
            ),
            (head("x y z", "4 4", "F F F", "1 1 1", 4, "ascii") + pts, "line 11", "SIZE gives 2"),
            (head("x y z", "4 4 3", "F F F", "1 1 1", 4, "ascii") + pts, "line 11", "field 'z': SIZE 3"),
            (head("x y z", "4 4 4", "F F D", "1 1 1", 4, "ascii") + pts, "line 5", "TYPE 'D'"),
            (head("x y z", "4 4 4", "F F F", "1 1 1", 4, "lzma") + pts, "line 11", "DATA 'lzma'"),
            (good.replace("POINTS 4", "POINTS 5") + pts, "line 11", "POINTS 5 is not WIDTH 4 x HEIGHT 1"),
            (good.clone() + "0 0 0\n1 0 0\n0 1\n0 0 1\n", "line 14", "found 2 values"),
            (good.clone() + "0 0 0\n1 0 0\n0 x 0\n0 0 1\n", "line 14", "'x' is not a number"),
            (good.clone() + pts + "1 1 1\n", "line 16", "more points than POINTS 4"),
            (good.clone() + "0 0 0\n", "", "1 points, where POINTS says 4"),
            (good.clone() + "0 0 0\n1 0 0\n0 inf 0\n0 0 1\n", "point 2", "non-finite"),
            (good.replace("DATA ascii\n", ""), "", "no DATA line"),
            (good.replace("VERSION", "VERSOIN"), "line 2", "'VERSOIN' is not a PCD header keyword"),
            (
                head("x y z", "4 4 4", "F F F", "1 1 1", 4, "binary") + "0000",
                "",
                "need 48 bytes after the header; the file has 4",
            ),
            (
                head("x y z", "4 4 4", "F F F", "1 1 1", 4, "binary_compressed") + "00",
                "",
                "without its two sizes",
            ),
        ];
        for (i, (text, at, why)) in cases.iter().enumerate() {
            fails_with(&dir.file(&format!("{i}.pcd"), text), at, why);
        }
    }

    #[test]
    fn ascii_integers_must_fit_their_type() {
        let dir = TempDir::new();
        let h = head("x y z rgb n", "1 2 4 4 8", "I U I U I", "1 1 1 1 2", 4, "ascii");
        let good = "0 0 0 4278190080 -9 9\n-128 65535 -2147483648 0 0 0\n127 1 2147483647 1 0 0\n";
        let set =
            read_points(&dir.file("g.pcd", format!("{h}{good}0 0 1 0 -9223372036854775808 0\n"))).unwrap();
        assert_eq!(set.points[1], [-128.0, 65535.0, -2147483648.0]);
        // whole numbers written as decimals, as writers that format every value as a float do
        let decimals =
            read_points(&dir.file("d.pcd", format!("{h}{good}-1.0 2.000 3e2 7.0 -0.0 0\n"))).unwrap();
        assert_eq!(decimals.points[3], [-1.0, 2.0, 300.0]);
        let cases = [
            ("0 0 1 0 0 1e300", "field 'n' (TYPE I, SIZE 8): '1e300' is not"),
            ("0 255.0 1 -1.0 0 0", "field 'rgb' (TYPE U, SIZE 4): '-1.0' is not"),
            ("-300 0 1 0 0 0", "field 'x' (TYPE I, SIZE 1): '-300' is not a whole number from -128 to 127"),
            ("0 65536 1 0 0 0", "field 'y' (TYPE U, SIZE 2): '65536' is not a whole number from 0 to 65535"),
            ("0 -1 1 0 0 0", "field 'y' (TYPE U, SIZE 2): '-1' is not"),
            ("0 0 12.345 0 0 0", "field 'z' (TYPE I, SIZE 4): '12.345' is not a whole number"),
            ("0 0 1 4294967296 0 0", "field 'rgb' (TYPE U, SIZE 4): '4294967296' is not"),
            ("0 0 1 0 0 1.5", "field 'n' (TYPE I, SIZE 8): '1.5' is not"),
        ];
        for (last, why) in cases {
            fails_with(&dir.file("b.pcd", format!("{h}{good}{last}\n")), "line 15", why);
        }
        let floats = head("x y z", "4 4 4", "F F F", "1 1 1", 4, "ascii") + "0 0 0\n1 0 0\n0 1 0\n0 0 1,5\n";
        fails_with(
            &dir.file("f.pcd", floats),
            "line 15",
            "field 'z' (TYPE F, SIZE 4): '1,5' is not a number",
        );
    }

    #[test]
    fn binary_data_past_the_declared_points_are_refused() {
        let dir = TempDir::new();
        let records: Vec<u8> =
            (0..5u8).flat_map(|i| [i as f32, 1.0, 2.0]).flat_map(f32::to_le_bytes).collect();
        // the header declares 4 points of 12 bytes; the data hold 5
        let mut binary = head("x y z", "4 4 4", "F F F", "1 1 1", 4, "binary").into_bytes();
        let start = binary.len();
        binary.extend(&records);
        fails_with(
            &dir.file("b.pcd", &binary),
            &format!("byte offset {}", start + 48),
            "12 bytes follow the 4 points the header declares (POINTS 4 of 12 bytes)",
        );
        assert_eq!(read_points(&dir.file("c.pcd", &binary[..start + 48])).unwrap().points.len(), 4);
        // compressed: bytes after the stream its sizes declare
        let soa: Vec<u8> =
            (0..4u8).map(|i| i as f32).chain([1.0; 4]).chain([2.0; 4]).flat_map(f32::to_le_bytes).collect();
        let stream: Vec<u8> =
            soa.chunks(32).flat_map(|c| [vec![c.len() as u8 - 1], c.to_vec()].concat()).collect();
        let mut compressed = head("x y z", "4 4 4", "F F F", "1 1 1", 4, "binary_compressed").into_bytes();
        compressed.extend((stream.len() as u32).to_le_bytes());
        compressed.extend((soa.len() as u32).to_le_bytes());
        compressed.extend(&stream);
        let end = compressed.len();
        assert_eq!(read_points(&dir.file("d.pcd", &compressed)).unwrap().points.len(), 4);
        compressed.extend([0u8; 7]);
        fails_with(
            &dir.file("e.pcd", &compressed),
            &format!("byte offset {end}"),
            "7 bytes follow the 50 bytes",
        );
    }
}
