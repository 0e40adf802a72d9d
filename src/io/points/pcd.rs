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
//! points' second, and so on. Organised clouds mark pixels without a return with NaN coordinates:
//! those points are left out, with the other readers' note.

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
    // the value of each field's first element within a line
    let mut first = Vec::with_capacity(h.fields.len());
    let mut at = 0;
    for f in &h.fields {
        first.push(at);
        at += f.count;
    }
    let width = at;
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
        let mut p = [0.0; 3];
        for (c, &a) in p.iter_mut().zip(&axes) {
            let t = tokens[first[a]];
            *c = t.parse().map_err(|_| err(format!("'{t}' is not a number")))?;
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
}
