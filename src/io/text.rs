//! Text input files (point lists, OBJ, contours, point pairs) as text, whatever their encoding
//! within reason.
//!
//! The data of these files is ASCII (numbers and keywords); only comments and headers carry
//! free text, written by whatever tool or editor made the file. UTF-8 (with or without a byte
//! order mark) is read as it is. Text that is not UTF-8 but has no control bytes (other than tab,
//! line feed, carriage return and form feed) is read as Latin-1, byte by byte: a comment such as
//! `# unit: µm` saved by an editor in Latin-1 or Windows-1252 must not make the file unreadable,
//! and since the numbers are ASCII, how the other bytes are shown changes nothing that is read. A
//! NUL or another control byte marks binary data (a binary PLY named `.xyz`, an executable),
//! refused with the line and byte offset where it starts. UTF-16, whose every ASCII character
//! carries a NUL, is named as such, with the conversion that fixes it. Lines may end in LF, CR LF,
//! or CR alone (a file without a single LF: classic Mac OS and some instruments' exports).

use std::borrow::Cow;
use std::path::Path;

use crate::error::{Error, Result};

/// `bytes` as text (see the module documentation); `what` names the kind of file in the errors
/// ("point", "OBJ", "contour").
pub fn decode<'a>(path: &Path, bytes: &'a [u8], what: &str) -> Result<Cow<'a, str>> {
    if bytes.starts_with(&[0xff, 0xfe]) || bytes.starts_with(&[0xfe, 0xff]) {
        return Err(Error::input(
            path,
            "line 1",
            format!(
                "UTF-16 text (a byte-order mark at byte offset 0); {what} files are read as ASCII or UTF-8: \
                 convert it, for instance with iconv -f UTF-16 -t UTF-8"
            ),
        ));
    }
    if let Some(at) = bytes.iter().position(|&b| is_control(b)) {
        let line = bytes[..at].iter().filter(|&&b| b == b'\n').count() + 1;
        return Err(Error::input(
            path,
            format!("line {line}"),
            format!("binary data at byte offset {at}; this is not a text {what} file"),
        ));
    }
    let text = match std::str::from_utf8(bytes) {
        Ok(text) => Cow::Borrowed(text.strip_prefix('\u{feff}').unwrap_or(text)),
        Err(_) => Cow::Owned(bytes.iter().map(|&b| char::from(b)).collect()),
    };
    // lines ended by carriage returns alone (classic Mac OS, some instruments' exports)
    Ok(if text.contains('\r') && !text.contains('\n') { Cow::Owned(text.replace('\r', "\n")) } else { text })
}

/// The file at `path` read and decoded as [`decode`] does.
pub fn read(path: &Path, what: &str) -> Result<String> {
    if path.is_dir() {
        return Err(Error::input(path, "", format!("a directory, not a {what} file")));
    }
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, &e))?;
    decode(path, &bytes, what).map(Cow::into_owned)
}

/// A byte no text file holds: the C0 controls but tab, line feed, form feed and carriage
/// return, and DEL.
fn is_control(b: u8) -> bool {
    (b < 0x20 && !matches!(b, b'\t' | b'\n' | 0x0c | b'\r')) || b == 0x7f
}

#[cfg(test)]
mod tests {
    use super::*;

    fn decoded(bytes: &[u8]) -> std::result::Result<String, String> {
        decode(Path::new("f.txt"), bytes, "point").map(Cow::into_owned).map_err(|e| e.to_string())
    }

    #[test]
    fn lines_ended_by_carriage_returns_alone_are_lines() {
        assert_eq!(decoded(b"0 0 0\r1 2 3\r").unwrap(), "0 0 0\n1 2 3\n");
        // with line feeds present, a carriage return is left for the line's reader to trim
        assert_eq!(decoded(b"0 0 0\r\n1 2 3\n").unwrap(), "0 0 0\r\n1 2 3\n");
    }

    #[test]
    fn latin1_comments_are_read_and_binary_is_refused_where_it_starts() {
        assert_eq!(decoded(b"\xef\xbb\xbf0 0 0\n").unwrap(), "0 0 0\n");
        assert_eq!(decoded("# µm\n1 2 3\n".as_bytes()).unwrap(), "# µm\n1 2 3\n");
        // the same comment saved in Latin-1: one byte 0xb5, not UTF-8
        assert_eq!(decoded(b"# \xb5m\r\n1 2 3\n").unwrap(), "# µm\r\n1 2 3\n");
        assert_eq!(decoded(b"# Windows-1252 quote \x93x\x94\n").unwrap().lines().count(), 1);
        for (bytes, at) in [
            (&b"0 0 0\n1 0 0\n\x00\x01 junk"[..], "line 3: binary data at byte offset 12"),
            (&b"0 0 0\n\x7fELF"[..], "line 2: binary data at byte offset 6"),
            (&b"1 2 3\n\xb5\x1b"[..], "line 2: binary data at byte offset 7"),
            (&b"\xff\xfe1\x00"[..], "UTF-16 text"),
        ] {
            let e = decoded(bytes).unwrap_err();
            assert!(e.contains(at) && e.contains("f.txt"), "{e}");
        }
    }
}
