//! Plain-text point lists (.xyz, .txt, .csv): three or more numbers per line, separated by
//! whitespace and/or commas (or semicolons, with decimal commas), with `#` comments and an
//! optional column header (rules in [`super::read_points`]).

use std::path::Path;

use super::{capacity, check_finite, no_return, no_return_note, PointSet};
use crate::error::{Error, Result};

pub(super) fn parse(path: &Path, bytes: &[u8]) -> Result<PointSet> {
    // decoded in one pass up front, so that a binary file with the wrong extension is reported
    // once, with a position, instead of as a confusing parse error
    let text = crate::io::text::decode(path, bytes, "point")?;
    // Typical lines are 20-40 bytes; under-guessing costs one regrowth, over-guessing memory.
    let mut points = Vec::with_capacity(capacity(usize::MAX, text.len(), 24));
    // semicolons between values (spreadsheets in locales that write decimal commas): then a comma
    // inside a value is its decimal mark
    let semicolons = text
        .lines()
        .map(|l| l.split('#').next().unwrap_or(""))
        .find(|l| !l.trim().is_empty())
        .is_some_and(|l| l.contains(';'));
    let is_sep = |c: char| c.is_ascii_whitespace() || if semicolons { c == ';' } else { c == ',' };
    let number = |tok: &str| -> Option<f64> {
        if semicolons && tok.contains(',') {
            tok.replacen(',', ".", 1).parse().ok()
        } else {
            tok.parse().ok()
        }
    };
    // the header's names, while no data line has come
    let mut header: Option<Vec<String>> = None;
    // the values per line and the columns of x, y and z, from the first data line
    let mut layout: Option<(usize, [usize; 3], usize)> = None;
    let mut values = Vec::new();
    // the points without a return left out: how many, and the first one's line
    let mut missing: (usize, Option<usize>) = (0, None);
    for (i, raw) in text.lines().enumerate() {
        let line = raw.split('#').next().unwrap_or("");
        let err = |reason: String| Error::input(path, format!("line {}", i + 1), reason);
        values.clear();
        let mut bad_token = None;
        for tok in line.split(is_sep).filter(|t| !t.is_empty()) {
            match number(tok) {
                Some(v) => values.push(v),
                None => {
                    bad_token = Some(tok);
                    break;
                }
            }
        }
        if values.is_empty() && bad_token.is_none() {
            continue;
        }
        if let Some(tok) = bad_token {
            let words: Vec<&str> = line.split(is_sep).filter(|t| !t.is_empty()).collect();
            if layout.is_none() && header.is_none() && words.iter().all(|t| number(t).is_none()) {
                header = Some(words.iter().map(|w| w.trim_start_matches('/').to_ascii_lowercase()).collect());
                continue;
            }
            let hint = if tok.contains(';') {
                " (';' separates values in files whose first line has one)"
            } else {
                ""
            };
            return Err(err(format!("'{tok}' is not a number{hint}")));
        }
        let n = values.len();
        let (width, cols, first) = match layout {
            Some(l) => l,
            None => {
                if !semicolons {
                    decimal_commas(line).map_err(err)?;
                }
                *layout.insert((n, columns(header.as_deref(), n).map_err(err)?, i + 1))
            }
        };
        if n != width {
            return Err(err(format!(
                "found {n} values, where the first data line (line {first}) has {width}{}",
                if width == 3 { " (x y z)" } else { "" }
            )));
        }
        let p = cols.map(|c| values[c]);
        if no_return(&p) {
            missing.0 += 1;
            missing.1.get_or_insert(i + 1);
            continue;
        }
        points.push(check_finite(p).map_err(err)?);
    }
    let missing_note = missing.1.map(|line| no_return_note(missing.0, &format!("line {line}")));
    if points.is_empty() {
        let why = missing_note.map_or(String::new(), |n| format!(" ({n})"));
        return Err(Error::input(path, "", format!("no points found{why}")));
    }
    let columns_note = layout.filter(|l| l.0 > 3).map(|(width, cols, _)| {
        let named = if header.as_deref().is_some_and(|h| h.iter().any(|n| n == "x")) {
            " (named in the header)"
        } else {
            ""
        };
        format!(
            "{width} values a line: x, y, z from columns {}, {}, {}{named}, the other {} ignored",
            cols[0] + 1,
            cols[1] + 1,
            cols[2] + 1,
            width - 3
        )
    });
    let decimal_note =
        semicolons.then(|| "values separated by ';', a ',' in a value read as its decimal mark".to_string());
    let notes: Vec<String> = decimal_note.into_iter().chain(columns_note).chain(missing_note).collect();
    let note = (!notes.is_empty()).then(|| notes.join("; "));
    Ok(PointSet { points, triangles: Vec::new(), note })
}

/// Refuses a first data line that looks written with decimal commas and blanks between the values
/// (`100,934 237,145 333,457`): split at its commas it would give twice the values, the wrong ones.
/// It does when every blank-separated token is a number with one comma between two digits
/// (`-12,5`, `100,934`, `1,5e3`) and there are at least three of them.
fn decimal_commas(line: &str) -> std::result::Result<(), String> {
    let comma_number = |tok: &str| {
        let b = tok.as_bytes();
        let mut commas = b.iter().enumerate().filter(|&(_, &c)| c == b',');
        match (commas.next(), commas.next()) {
            (Some((k, _)), None) => {
                k > 0
                    && b[k - 1].is_ascii_digit()
                    && b.get(k + 1).is_some_and(u8::is_ascii_digit)
                    && tok.replacen(',', ".", 1).parse::<f64>().is_ok()
            }
            _ => false,
        }
    };
    let tokens: Vec<&str> = line.split_ascii_whitespace().collect();
    if tokens.len() >= 3 && tokens.iter().all(|t| comma_number(t)) {
        return Err(format!(
            "'{}' looks like numbers with decimal commas separated by blanks, which would be split at \
             the commas: with decimal commas, separate the values by semicolons (`0,5;1,25;3`), or write \
             decimal points",
            tokens.join(" ")
        ));
    }
    Ok(())
}

/// The columns of x, y and z in lines of `n` values: those the header names x, y and z, or else
/// the first three.
fn columns(header: Option<&[String]>, n: usize) -> std::result::Result<[usize; 3], String> {
    if n < 3 {
        return Err(format!("expected 3 coordinates (x y z), found {n} values"));
    }
    let Some(names) = header else { return Ok([0, 1, 2]) };
    let find = |name: &str| names.iter().position(|h| h == name);
    match (find("x"), find("y"), find("z")) {
        (Some(x), Some(y), Some(z)) if names.len() == n => Ok([x, y, z]),
        (Some(_), Some(_), Some(_)) => Err(format!(
            "the header names {} columns ({}), the first data line has {n} values",
            names.len(),
            names.join(" ")
        )),
        _ => Ok([0, 1, 2]),
    }
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
    fn semicolons_separate_values_with_decimal_commas() {
        let dir = TempDir::new();
        // as a spreadsheet in a decimal-comma locale exports it, header and all
        let text = "X;Y;Z\r\n0;0;0\r\n1;0;0\r\n0;1;0\r\n0;0;1\r\n0,5; -2,25e0 ;3e-3\r\n";
        let set = read_points(&dir.file("p.csv", text)).expect("semicolons");
        assert_eq!(set.points, CUBE);
        assert!(set.note.unwrap().contains("separated by ';', a ',' in a value read as its decimal mark"));
        // one value with two commas is no number; a ';' in a comma-separated file is named
        fails_with(&dir.file("q.csv", "0;0;0\n1,0,0;0;0\n"), "line 2", "'1,0,0' is not a number");
        fails_with(
            &dir.file("r.csv", "0,0,0\n1;0;0\n"),
            "line 2",
            "';' separates values in files whose first line",
        );
    }

    #[test]
    fn decimal_commas_between_blanks_are_refused() {
        let dir = TempDir::new();
        // blanks or tabs between values with decimal commas: split at the commas they would be
        // twice as many values, the wrong ones
        for text in [
            "100,934 237,145 333,457\n67,785 181,190 266,707\n1,0 2,0 3,0\n4,5 5,5 6,5\n",
            "x y z\n-12,5\t1,5e3\t0,25\n1,0\t2,0\t3,0\n4,5\t5,5\t6,5\n7,0\t8,0\t9,0\n",
        ] {
            let line = if text.starts_with('x') { "line 2" } else { "line 1" };
            fails_with(&dir.file("eu.xyz", text), line, "decimal commas separated by blanks");
            fails_with(&dir.file("eu.xyz", text), line, "separate the values by semicolons (`0,5;1,25;3`)");
        }
        // commas as separators, with or without blanks, still read
        for text in [
            "1.0, 2.0, 3.0\n0, 0, 0\n1, 0, 0\n0, 1, 0\n",
            "1,2,3\n0,0,0\n1,0,0\n0,1,0\n",
            "1,2, 3\n0,0, 0\n1,0, 0\n0,1, 0\n",
            "1,2 3,4\n0,0 0,0\n1,0 0,0\n0,1 0,0\n",
        ] {
            let set = read_points(&dir.file("ok.xyz", text)).unwrap_or_else(|e| panic!("{text:?}: {e}"));
            assert_eq!(set.points[0], [1.0, 2.0, 3.0], "{text:?}");
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
    fn text_columns_past_three_are_ignored_or_chosen_by_the_header() {
        let dir = TempDir::new();
        // normals after the coordinates, no header: the first three, and a note
        let set = read_points(&dir.file("n.xyz", "0 0 0 1 0 0\n1 0 0 1 0 0\n0 1 0 0 1 0\n0 0 1 0 0 1\n"))
            .expect("normals");
        assert_eq!(set.points, CUBE[..4]);
        let note = set.note.expect("a note");
        assert!(note.contains("6 values a line: x, y, z from columns 1, 2, 3, the other 3"), "{note}");
        // a header placing the coordinates elsewhere, as exporters write it
        let text = "//ID Intensity X Y Z\n7,0.5,0,0,0\n8,0.5,1,0,0\n9,0.5,0,1,0\n10,0.5,0,0,1\n";
        let set = read_points(&dir.file("h.csv", text)).expect("header");
        assert_eq!(set.points, CUBE[..4]);
        assert!(set.note.unwrap().contains("columns 3, 4, 5 (named in the header)"));
        // three values a line: no note
        assert!(read_points(&dir.file("p.xyz", "0 0 0\n1 0 0\n0 1 0\n0 0 1\n")).unwrap().note.is_none());
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
            (
                "0 0 0\n1 0 0 7\n0 1 0\n0 0 1\n",
                "line 2",
                "found 4 values, where the first data line (line 1) has 3",
            ),
            (
                "0 0 0 1\n1 0 0 7\n0 1 0\n0 0 1 1\n",
                "line 3",
                "found 3 values, where the first data line (line 1) has 4",
            ),
            ("# x y z\n\n0 0\n1 0 0\n0 1 0\n0 0 1\n", "line 3", "expected 3 coordinates (x y z), found 2"),
            // a header naming x, y and z for lines of another width
            ("x y z\n0 0 0 1\n1 0 0 1\n0 1 0 1\n0 0 1 1\n", "line 2", "the header names 3 columns (x y z)"),
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
        // a point with no coordinates at all is a pixel without a return: left out, and counted
        fails_with(&dir.file("b.txt", "0 0 0\nnan nan nan\n0 1 0\n0 0 1\n"), "", "only 3 point(s)");
        fails_with(
            &dir.file("c.txt", "nan nan nan\n-nan NaN NAN\n"),
            "",
            "no points found (2 point(s) without",
        );
        fails_with(&dir.file("d.txt", "0 0 0\nnan nan inf\n0 1 0\n0 0 1\n"), "line 2", "non-finite");
    }

    #[test]
    fn points_without_a_return_are_left_out_and_counted() {
        let dir = TempDir::new();
        let set = read_points(&dir.file(
            "o.xyz",
            "# organised\n0 0 0 1\nnan nan nan 0\n1 0 0 1\n0 1 0 1\n\n-nan nan NaN 0\n0 0 1 1\n",
        ))
        .unwrap();
        assert_eq!(set.points, [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]);
        let note = set.note.unwrap();
        assert!(note.ends_with("2 point(s) without coordinates (x, y and z all NaN: scanner pixels with no return) left out, the first at line 3"), "{note}");
        assert!(note.starts_with("4 values a line"), "{note}");
    }
}
