//! Body files for gravity: one body per line, `m x y z vx vy vz`, whitespace or
//! commas between numbers, `#` comments and blank lines skipped. Lines with more
//! columns (such as the shared reference files, which go on with
//! `ax ay az phi`) are read for their first seven.

use crate::error::{data_line, data_lines, parse_finite, InputError};
use std::fs::File;
use std::io::{BufRead, BufReader};
use std::ops::Range;
use std::path::Path;

/// Masses, positions and velocities as read, in file order.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct BodyFile {
    /// `m`.
    pub mass: Vec<f64>,
    /// `x y z`.
    pub position: Vec<[f64; 3]>,
    /// `vx vy vz`.
    pub velocity: Vec<[f64; 3]>,
    /// Whether some line had more than seven columns (ignored).
    pub extra_columns: bool,
}

/// Reads the body file at `path`, a line at a time in one pass (the errors
/// of [`parse_bodies`]).
pub fn read_bodies(path: &Path) -> Result<BodyFile, InputError> {
    let mut out = BodyFile::default();
    each_data_line(path, |index, tokens| {
        out.push(parse_body(path, index, tokens)?);
        out.extra_columns |= tokens.len() > 7;
        Ok(true)
    })?;
    if out.mass.is_empty() {
        return Err(no_bodies(path));
    }
    Ok(out)
}

/// The bodies `keep(n)` of the body file at `path` of `n` bodies, and `n`
/// (a process of a distributed run reads its block): the file is read line by
/// line twice, every line checked in the first pass (the errors of
/// [`parse_bodies`]), the kept ones taken in the second. Neither the text nor
/// any other body is held.
pub fn read_bodies_part(
    path: &Path,
    keep: impl FnOnce(usize) -> Range<usize>,
) -> Result<(BodyFile, usize), InputError> {
    let (mut n, mut extra_columns) = (0, false);
    each_data_line(path, |index, tokens| {
        parse_body(path, index, tokens)?;
        extra_columns |= tokens.len() > 7;
        n += 1;
        Ok(true)
    })?;
    if n == 0 {
        return Err(no_bodies(path));
    }
    let kept = keep(n);
    assert!(kept.end <= n, "bodies {kept:?} of {n}");
    let mut out = BodyFile {
        extra_columns,
        ..BodyFile::default()
    };
    let mut body = 0;
    each_data_line(path, |index, tokens| {
        if kept.contains(&body) {
            out.push(parse_body(path, index, tokens)?);
        }
        body += 1;
        Ok(body < kept.end)
    })?;
    if out.mass.len() != kept.len() {
        return Err(InputError::file(
            path,
            format!("the file changed while it was read ({n} bodies counted, then {body})"),
        ));
    }
    Ok((out, n))
}

/// Hands `visit(0-based line index, tokens)` each data line of the file at
/// `path` ([`data_line`]) until it returns false.
fn each_data_line(
    path: &Path,
    mut visit: impl FnMut(usize, &[&str]) -> Result<bool, InputError>,
) -> Result<(), InputError> {
    let cannot = |e: std::io::Error| InputError::file(path, format!("cannot read: {e}"));
    let mut reader = BufReader::new(File::open(path).map_err(cannot)?);
    let mut line = String::new();
    for index in 0.. {
        line.clear();
        if reader.read_line(&mut line).map_err(cannot)? == 0 {
            break;
        }
        if let Some(tokens) = data_line(&line) {
            if !visit(index, &tokens)? {
                break;
            }
        }
    }
    Ok(())
}

/// [`read_bodies`] on text already read; `path` names it in errors. Masses must be
/// positive; an empty file is an error.
pub fn parse_bodies(path: &Path, text: &str) -> Result<BodyFile, InputError> {
    let mut out = BodyFile::default();
    for (index, tokens) in data_lines(text) {
        out.push(parse_body(path, index, &tokens)?);
        out.extra_columns |= tokens.len() > 7;
    }
    if out.mass.is_empty() {
        return Err(no_bodies(path));
    }
    Ok(out)
}

impl BodyFile {
    /// Adds the body `m x y z vx vy vz`.
    fn push(&mut self, v: [f64; 7]) {
        self.mass.push(v[0]);
        self.position.push([v[1], v[2], v[3]]);
        self.velocity.push([v[4], v[5], v[6]]);
    }
}

/// The numbers `m x y z vx vy vz` of the data line `index` (0-based) of `path`.
fn parse_body(path: &Path, index: usize, tokens: &[&str]) -> Result<[f64; 7], InputError> {
    if tokens.len() < 7 {
        return Err(InputError::at(
            path,
            index + 1,
            format!("{} numbers; expected 7: m x y z vx vy vz", tokens.len()),
        ));
    }
    let mut v = [0.0; 7];
    for (k, (slot, token)) in v.iter_mut().zip(tokens).enumerate() {
        let name = ["m", "x", "y", "z", "vx", "vy", "vz"][k];
        *slot = parse_finite(path, index + 1, token, || {
            format!("column {} ({name})", k + 1)
        })?;
    }
    if v[0] <= 0.0 {
        return Err(InputError::at(
            path,
            index + 1,
            format!("mass {} must be > 0", tokens[0]),
        ));
    }
    Ok(v)
}

/// The error of a body file without a data line.
fn no_bodies(path: &Path) -> InputError {
    InputError::file(path, "no bodies: expected lines of m x y z vx vy vz")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_bodies_and_says_where_a_line_is_wrong() {
        let p = Path::new("stars.txt");
        let b = parse_bodies(
            p,
            "# m x y z vx vy vz\n1 0 0 0 0 0 0\n\n0.5, 1, 2, 3, 4, 5, 6, 9, 9\n",
        )
        .unwrap();
        assert_eq!(b.mass, vec![1.0, 0.5]);
        assert_eq!(b.position[1], [1.0, 2.0, 3.0]);
        assert_eq!(b.velocity[1], [4.0, 5.0, 6.0]);
        assert!(b.extra_columns);
        let e = parse_bodies(p, "1 0 0 0 0 0 0\n1 2 3\n").unwrap_err();
        assert_eq!(e.line, Some(2));
        let e = parse_bodies(p, "1 0 0 0 0 0 0\n0 1 1 1 0 0 0\n").unwrap_err();
        assert!(
            e.to_string().contains("stars.txt:2: mass 0 must be > 0"),
            "{e}"
        );
        let e = parse_bodies(p, "1 0 0 zero 0 0 0\n").unwrap_err();
        assert!(e.to_string().contains(":1:"), "{e}");
        assert!(parse_bodies(p, "# nothing\n").is_err());
    }

    #[test]
    fn parts_read_from_a_file_are_the_whole_files_bodies() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("stars.txt");
        let mut text = String::from("# m x y z vx vy vz\r\n");
        for i in 0..40 {
            text += &format!(
                "{} {i} {} 0.5, 1 2 3{}\r\n",
                1.0 + i as f64,
                -i,
                if i == 7 { " 9" } else { "" }
            );
            if i % 9 == 0 {
                text += "\n  # a comment\n";
            }
        }
        text += "2 0 0 0 0 0 0";
        std::fs::write(&path, &text).unwrap();
        let whole = parse_bodies(&path, &text).unwrap();
        assert_eq!(whole.mass.len(), 41);
        assert!(whole.extra_columns);
        assert_eq!(read_bodies(&path).unwrap(), whole);
        for part in [0..0, 0..41, 5..17, 40..41] {
            let (got, n) = read_bodies_part(&path, |_| part.clone()).unwrap();
            assert_eq!(n, 41);
            assert_eq!(got.mass, whole.mass[part.clone()]);
            assert_eq!(got.position, whole.position[part.clone()]);
            assert_eq!(got.velocity, whole.velocity[part.clone()]);
        }
        // an error past the kept part is still told, at its line
        std::fs::write(&path, text.replace("5 4 -4", "5 4 x")).unwrap();
        let e = read_bodies_part(&path, |_| 0..1).unwrap_err();
        assert!(e.to_string().contains("stars.txt:8: column 3 (y)"), "{e}");
        std::fs::write(&path, b"1 0 0 0 0 0 \xff\n").unwrap();
        let e = read_bodies(&path).unwrap_err().to_string();
        assert!(e.contains("cannot read") && e.contains("UTF-8"), "{e}");
        assert!(read_bodies(&dir.path().join("none.txt")).is_err());
    }
}
