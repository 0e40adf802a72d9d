//! LAS, the ASPRS format of airborne and terrestrial lidar (versions 1.0 to 1.4, point data record
//! formats 0 to 10). Every record begins with the coordinates as three little-endian i32, which
//! the public header's scale and offset turn into numbers: x = X x_scale + x_offset, and so on.
//! The rest of a record (intensity, returns, classification, GPS time, colour, waveform) is
//! skipped.
//!
//! The header fields read (byte offsets, little-endian): the signature `LASF` (0), the version
//! (24, 25), the header size (94), the offset to the point data (96), the record format (104) and
//! length (105), the legacy point count (107), the scales (131, 139, 147) and offsets (155, 163,
//! 171), and from version 1.4 the 64-bit point count (247) where the legacy count is 0. LAZ, the
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
    let mut count = u32_at(bytes, 107);
    if count == 0 && minor >= 4 && header >= 255 && bytes.len() >= 255 {
        count = u64::from_le_bytes(std::array::from_fn(|k| bytes[247 + k])).try_into().unwrap_or(usize::MAX);
    }
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
    let need = count.checked_mul(record).filter(|&n| data >= header && n <= body.len()).ok_or_else(|| {
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
    for (i, rec) in body[..need].chunks_exact(record).enumerate() {
        let p: [f64; 3] = std::array::from_fn(|d| {
            let v = i32::from_le_bytes([rec[4 * d], rec[4 * d + 1], rec[4 * d + 2], rec[4 * d + 3]]);
            v as f64 * scale[d] + offset[d]
        });
        set.points.push(check_finite(p).map_err(|why| err(&format!("point {i}"), why))?);
    }
    if set.points.is_empty() {
        return Err(err("", "no points (the header's point count is 0)".into()));
    }
    set.note = Some(format!(
        "LAS {major}.{minor}, point data record format {format}: {count} points, scales {:e} {:e} {:e}",
        scale[0], scale[1], scale[2]
    ));
    Ok(set)
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
        let header: u16 = if minor >= 4 { 375 } else { 227 };
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
            let mut r = vec![0xabu8; record as usize];
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
}
