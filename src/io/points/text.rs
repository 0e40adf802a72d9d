//! Plain-text point lists (.xyz, .txt, .csv): three numbers per line, separated by whitespace
//! and/or commas, with `#` comments and an optional column header (rules in [`super::read_points`]).

use std::path::Path;

use super::{as_text, capacity, check_finite, PointSet};
use crate::error::{Error, Result};

pub(super) fn parse(path: &Path, bytes: &[u8]) -> Result<PointSet> {
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

#[cfg(test)]
mod tests {
    use super::super::read_points;
    use super::super::testutil::{fails_with, TempDir, CUBE};

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
    fn text_faults_name_their_line() {
        let dir = TempDir::new();
        let cases = [
            // A header after data, and a first line mixing words and numbers.
            ("0,0,0\nx,y,z\n1,0,0\n0,1,0\n0,0,1\n", "line 2", "'x'"),
            ("x,1,z\n0,0,0\n1,0,0\n0,1,0\n0,0,1\n", "line 1", "'x'"),
            // Too few and too many values.
            ("0 0 0\n1 0 0\n\n0 1\n0 0 1\n", "line 4", "found 2"),
            ("0 0 0\n1 0 0 7\n0 1 0\n0 0 1\n", "line 2", "found 4"),
        ];
        for (text, at, why) in cases {
            fails_with(&dir.file("p.csv", text), at, why);
        }
        for bad in ["nan", "inf", "-inf", "NaN", "1e999"] {
            fails_with(
                &dir.file("a.txt", format!("0 0 0\n1 0 0\n0 {bad} 0\n0 0 1\n")),
                "line 3",
                "non-finite",
            );
        }
    }
}
