//! LAS, the ASPRS format of airborne and terrestrial lidar (versions 1.0 to 1.4, point data record
//! formats 0 to 10). Every record begins with the coordinates as three little-endian i32, which
//! the public header's scale and offset turn into numbers: x = X x_scale + x_offset, and so on.
//! Points classified as noise (class 7, and 18 in formats 6-10) or flagged withheld are left out
//! and counted in the note; the rest of a record (intensity, returns, GPS time, colour, waveform)
//! is skipped.
//!
//! The header fields read (byte offsets, little-endian): the signature `LASF` (0), the version
//! (24, 25), the header size (94), the offset to the point data (96), the record format (104) and
//! length (105), the legacy point count (107), the scales (131, 139, 147) and offsets (155, 163,
//! 171), and in version 1.4 the 64-bit point count (247), which the legacy count must be 0 or
//! equal to. The header size must be at least the version's (227 bytes to 1.2, 235 in 1.3, 375 in
//! 1.4), and the point data must start after the header. LAZ, the
//! LASzip-compressed form, marks the record format with its two top bits; it is named, with the
//! command that expands it.

use std::path::Path;

use super::{check_finite, PointSet};
use crate::error::{Error, Result};

/// The shortest record of each point data record format 0..=10.
const RECORD_MIN: [usize; 11] = [20, 28, 26, 34, 57, 63, 30, 36, 38, 59, 67];

fn u16_at(b: &[u8], at: usize) -> usize {
    u16::from_le_bytes([b[at], b[at + 1]]) as usize
}

fn u32_at(b: &[u8], at: usize) -> usize {
    u32::from_le_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]]) as usize
}

fn f64_at(b: &[u8], at: usize) -> f64 {
    f64::from_le_bytes(std::array::from_fn(|k| b[at + k]))
}

/// What a .laz file gets: the command that expands it.
pub(super) const LAZ: &str = "LAZ (LASzip-compressed) point data: expand it to LAS first, e.g. \
                              `laszip -i FILE.laz -o FILE.las` or `pdal translate FILE.laz FILE.las`";

pub(super) fn parse(path: &Path, bytes: &[u8]) -> Result<PointSet> {
    let err = |at: &str, reason: String| Error::input(path, at, reason);
    if !bytes.starts_with(b"LASF") {
        return Err(err("", "no 'LASF' signature at the start; not a LAS file".into()));
    }
    if bytes.len() < 227 {
        return Err(err(
            "",
            format!("{} bytes: shorter than a LAS header (227 bytes at least)", bytes.len()),
        ));
    }
    let (major, minor) = (bytes[24], bytes[25]);
    let header = u16_at(bytes, 94);
    let data = u32_at(bytes, 96);
    let format = bytes[104];
    let record = u16_at(bytes, 105);
    if format & 0xc0 != 0 {
        return Err(err("", LAZ.into()));
    }
    if major != 1 || minor > 4 {
        return Err(err("", format!("LAS version {major}.{minor}: versions 1.0 to 1.4 are read")));
    }
    let Some(&least) = RECORD_MIN.get(format as usize) else {
        return Err(err(
            "byte offset 104",
            format!("point data record format {format}: formats 0 to 10 are read"),
        ));
    };
    if record < least {
        return Err(err(
            "byte offset 105",
            format!(
                "records of {record} bytes, shorter than the {least} of point data record format {format}"
            ),
        ));
    }
    // the public header grew with the versions: 227 bytes to 1.2, 235 in 1.3, 375 in 1.4
    let least_header = match minor {
        0..=2 => 227,
        3 => 235,
        _ => 375,
    };
    if header < least_header {
        return Err(err(
            "byte offset 94",
            format!("header size {header}: a LAS {major}.{minor} header takes at least {least_header} bytes"),
        ));
    }
    if bytes.len() < header {
        return Err(err(
            "",
            format!("{} bytes: shorter than the header's {header} bytes (truncated?)", bytes.len()),
        ));
    }
    if data < header {
        return Err(err(
            "byte offset 96",
            format!("the point data start at byte {data}, inside the {header}-byte header"),
        ));
    }
    let legacy = u32_at(bytes, 107);
    let count = if minor >= 4 {
        // 1.4 counts in 64 bits; the legacy 32-bit count is 0 or the same number
        let wide = u64::from_le_bytes(std::array::from_fn(|k| bytes[247 + k]));
        if legacy != 0 && legacy as u64 != wide {
            return Err(err(
                "byte offset 107",
                format!(
                    "inconsistent header: the legacy point count {legacy} differs from the 64-bit point \
                     count {wide} (byte offset 247)"
                ),
            ));
        }
        wide.try_into().unwrap_or(usize::MAX)
    } else {
        legacy
    };
    let scale = [131, 139, 147].map(|at| f64_at(bytes, at));
    let offset = [155, 163, 171].map(|at| f64_at(bytes, at));
    if let Some(d) = (0..3).find(|&d| !(scale[d].is_finite() && scale[d] != 0.0 && offset[d].is_finite())) {
        return Err(err(
            "byte offset 131",
            format!(
                "the {} scale {:e} and offset {:e} do not make coordinates (a finite, non-zero scale is needed)",
                ["x", "y", "z"][d],
                scale[d],
                offset[d]
            ),
        ));
    }
    let body = bytes.get(data..).unwrap_or(&[]);
    let need = count.checked_mul(record).filter(|&n| n <= body.len()).ok_or_else(|| {
        err(
            "",
            format!(
                "{count} points of {record} bytes from byte {data} need {} bytes; the file has {} (truncated, or a \
                 wrong count in the header?)",
                data as u128 + count as u128 * record as u128,
                bytes.len()
            ),
        )
    })?;
    let mut set = PointSet::default();
    set.points.reserve(count);
    let (mut noise, mut withheld) = (0, 0);
    for (i, rec) in body[..need].chunks_exact(record).enumerate() {
        match classify(format, rec) {
            Kept::Noise => noise += 1,
            Kept::Withheld => withheld += 1,
            Kept::Yes => {
                let p: [f64; 3] = std::array::from_fn(|d| {
                    let v = i32::from_le_bytes([rec[4 * d], rec[4 * d + 1], rec[4 * d + 2], rec[4 * d + 3]]);
                    v as f64 * scale[d] + offset[d]
                });
                set.points.push(check_finite(p).map_err(|why| err(&format!("point {i}"), why))?);
            }
        }
    }
    let mut note = format!(
        "LAS {major}.{minor}, point data record format {format}: {count} points, scales {:e} {:e} {:e}",
        scale[0], scale[1], scale[2]
    );
    if noise + withheld > 0 {
        note.push_str(&format!(
            "; left out: {noise} classified as noise (class 7 or 18), {withheld} flagged withheld"
        ));
    }
    if set.points.is_empty() {
        let why = if count > 0 { format!(" ({note})") } else { " (the header's point count is 0)".into() };
        return Err(err("", format!("no points{why}")));
    }
    set.note = Some(note);
    Ok(set)
}

/// Whether a record's point is kept: not if its class is noise (7, low noise; 18, high noise in
/// formats 6-10) or its withheld flag is set (the point is to be treated as deleted).
enum Kept {
    Yes,
    Noise,
    Withheld,
}

fn classify(format: u8, rec: &[u8]) -> Kept {
    // formats 0-5: byte 15 holds the class (bits 0-4) and the withheld flag (bit 7); formats
    // 6-10: byte 15 holds the flags (withheld is bit 2) and byte 16 the class
    let (class, withheld) =
        if format <= 5 { (rec[15] & 0x1f, rec[15] & 0x80 != 0) } else { (rec[16], rec[15] & 0x04 != 0) };
    if withheld {
        Kept::Withheld
    } else if class == 7 || class == 18 {
        Kept::Noise
    } else {
        Kept::Yes
    }
}

#[cfg(test)]
mod tests {
    use super::super::read_points;
    use super::super::testutil::{fails_with, TempDir};

    /// A LAS file of `pts` (integer coordinates before scaling) in record format `format` of
    /// `record` bytes, version 1.`minor` (1.4 with the 64-bit count only).
    fn las(
        pts: &[[i32; 3]],
        scale: [f64; 3],
        offset: [f64; 3],
        format: u8,
        record: u16,
        minor: u8,
    ) -> Vec<u8> {
        let header: u16 = match minor {
            0..=2 => 227,
            3 => 235,
            _ => 375,
        };
        let mut b = vec![0u8; header as usize];
        b[..4].copy_from_slice(b"LASF");
        (b[24], b[25]) = (1, minor);
        b[94..96].copy_from_slice(&header.to_le_bytes());
        // a variable length record of 60 bytes between the header and the points
        let data = header as u32 + 60;
        b[96..100].copy_from_slice(&data.to_le_bytes());
        b[100..104].copy_from_slice(&1u32.to_le_bytes());
        b[104] = format;
        b[105..107].copy_from_slice(&record.to_le_bytes());
        if minor >= 4 {
            b[247..255].copy_from_slice(&(pts.len() as u64).to_le_bytes());
        } else {
            b[107..111].copy_from_slice(&(pts.len() as u32).to_le_bytes());
        }
        for d in 0..3 {
            b[131 + 8 * d..139 + 8 * d].copy_from_slice(&scale[d].to_le_bytes());
            b[155 + 8 * d..163 + 8 * d].copy_from_slice(&offset[d].to_le_bytes());
        }
        b.extend([7u8; 60]);
        for p in pts {
            // the rest of the record: class 2 (ground), no flags
            let mut r = vec![0u8; record as usize];
            r[if format <= 5 { 15 } else { 16 }] = 2;
            for d in 0..3 {
                r[4 * d..4 * d + 4].copy_from_slice(&p[d].to_le_bytes());
            }
            b.extend(r);
        }
        b
    }

    #[test]
    fn coordinates_are_scaled_and_offset_in_every_version() {
        let dir = TempDir::new();
        let raw = [[0, 0, 0], [1000, -2000, 3000], [-5, 7, 123456789], [i32::MAX, i32::MIN, 1]];
        let (scale, offset) = ([0.001, 0.01, 1e-7], [500000.0, -12.5, 0.0]);
        for (format, record, minor) in [(0u8, 20u16, 0u8), (1, 28, 2), (3, 40, 3), (6, 30, 4), (10, 67, 4)] {
            let set =
                read_points(&dir.file("s.las", las(&raw, scale, offset, format, record, minor))).unwrap();
            for (p, r) in set.points.iter().zip(&raw) {
                for d in 0..3 {
                    assert_eq!(p[d], r[d] as f64 * scale[d] + offset[d], "format {format}");
                }
            }
            assert!(set
                .note
                .unwrap()
                .starts_with(&format!("LAS 1.{minor}, point data record format {format}: 4 points")));
        }
    }

    #[test]
    fn noise_and_withheld_points_are_left_out_and_counted() {
        let dir = TempDir::new();
        let raw: Vec<[i32; 3]> = (0..8).map(|i| [i, i * i, 1 - i]).collect();
        for (format, record) in [(1u8, 28u16), (6, 30)] {
            let mut b = las(&raw, [0.5; 3], [0.0; 3], format, record, if format == 6 { 4 } else { 2 });
            let first = b.len() - raw.len() * record as usize;
            let byte = |i: usize, at: usize| first + i * record as usize + at;
            if format <= 5 {
                b[byte(1, 15)] = 7;
                b[byte(4, 15)] = 0x80 | 2;
            } else {
                b[byte(1, 16)] = 18;
                b[byte(3, 16)] = 7;
                b[byte(4, 15)] = 0x04;
            }
            let set = read_points(&dir.file("n.las", b)).unwrap();
            let left: Vec<usize> = if format <= 5 { vec![1, 4] } else { vec![1, 3, 4] };
            let want: Vec<[f64; 3]> =
                (0..8).filter(|i| !left.contains(i)).map(|i| raw[i].map(|v| v as f64 * 0.5)).collect();
            assert_eq!(set.points, want, "format {format}");
            let note = set.note.unwrap();
            let counts = if format <= 5 { "1 classified as noise" } else { "2 classified as noise" };
            assert!(
                note.ends_with(&format!("left out: {counts} (class 7 or 18), 1 flagged withheld")),
                "{note}"
            );
        }
    }

    #[test]
    fn broken_and_compressed_las_files_are_named() {
        let dir = TempDir::new();
        let raw = [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]];
        let good = las(&raw, [0.1; 3], [0.0; 3], 1, 28, 2);
        let with = |at: usize, v: &[u8]| {
            let mut b = good.clone();
            b[at..at + v.len()].copy_from_slice(v);
            b
        };
        let cases = [
            (with(104, &[0x81]), "", "LAZ (LASzip-compressed)"),
            (with(104, &[11]), "byte offset 104", "record format 11"),
            (with(105, &20u16.to_le_bytes()), "byte offset 105", "records of 20 bytes, shorter than the 28"),
            (with(24, &[2, 0]), "", "LAS version 2.0"),
            (with(139, &0f64.to_le_bytes()), "byte offset 131", "the y scale 0e0"),
            (
                with(107, &5u32.to_le_bytes()),
                "",
                "5 points of 28 bytes from byte 287 need 427 bytes; the file has 399",
            ),
            (good[..good.len() - 1].to_vec(), "", "truncated"),
            (good[..100].to_vec(), "", "shorter than a LAS header"),
            (b"LASX".repeat(80), "", "no 'LASF' signature"),
        ];
        for (i, (bytes, at, why)) in cases.iter().enumerate() {
            fails_with(&dir.file(&format!("{i}.LAS"), bytes), at, why);
        }
        fails_with(&dir.file("c.laz", &good), "", "LAZ (LASzip-compressed)");
    }

    #[test]
    fn header_sizes_and_the_data_offset_must_fit_the_version() {
        let dir = TempDir::new();
        let raw = [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]];
        for (minor, least) in [(0u8, 227u16), (2, 227), (3, 235), (4, 375)] {
            let mut b = las(&raw, [0.1; 3], [0.0; 3], 1, 28, minor);
            assert!(read_points(&dir.file("ok.las", &b)).is_ok(), "1.{minor}");
            b[94..96].copy_from_slice(&(least - 1).to_le_bytes());
            let why =
                format!("header size {}: a LAS 1.{minor} header takes at least {least} bytes", least - 1);
            fails_with(&dir.file("h.las", &b), "byte offset 94", &why);
        }
        // header bytes taken for points: the data offset inside the header
        let mut b = las(&raw, [0.1; 3], [0.0; 3], 1, 28, 2);
        b[96..100].copy_from_slice(&100u32.to_le_bytes());
        fails_with(&dir.file("d.las", &b), "byte offset 96", "start at byte 100, inside the 227-byte header");
        // a 1.4 header cut short
        let b = las(&raw, [0.1; 3], [0.0; 3], 6, 30, 4);
        fails_with(&dir.file("t.las", &b[..300]), "", "300 bytes: shorter than the header's 375 bytes");
    }

    #[test]
    fn las_1_4_counts_in_64_bits() {
        let dir = TempDir::new();
        let raw: Vec<[i32; 3]> = (0..6).map(|i| [i, 2 * i, i * i]).collect();
        let b = las(&raw, [0.5; 3], [0.0; 3], 6, 30, 4);
        // the legacy count may be 0 (the helper's), or the same number
        let with_legacy = |n: u32| {
            let mut b = b.clone();
            b[107..111].copy_from_slice(&n.to_le_bytes());
            b
        };
        for legacy in [0, 6] {
            assert_eq!(read_points(&dir.file("a.las", with_legacy(legacy))).unwrap().points.len(), 6);
        }
        // a legacy count that disagrees is refused, not taken
        fails_with(
            &dir.file("b.las", with_legacy(4)),
            "byte offset 107",
            "the legacy point count 4 differs from the 64-bit point count 6",
        );
    }
}
