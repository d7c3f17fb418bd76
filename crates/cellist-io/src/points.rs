//! Point files: plain text (2 or 3 columns, `#` comments) and extended XYZ.

use crate::error::{parse_finite, InputError};
use std::path::Path;

/// Points of either dimension.
#[derive(Clone, Debug, PartialEq)]
pub enum Points {
    /// 2D points.
    Two(Vec<[f64; 2]>),
    /// 3D points.
    Three(Vec<[f64; 3]>),
}

impl Points {
    /// Number of points.
    pub fn len(&self) -> usize {
        match self {
            Points::Two(p) => p.len(),
            Points::Three(p) => p.len(),
        }
    }

    /// True when there are no points.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// 2 or 3.
    pub fn dimension(&self) -> usize {
        match self {
            Points::Two(_) => 2,
            Points::Three(_) => 3,
        }
    }
}

/// A periodic cell read from a file (the `Lattice` and `pbc` of extended XYZ).
#[derive(Clone, Debug, PartialEq)]
pub struct BoxInfo {
    /// Side lengths of the orthogonal box.
    pub lengths: Vec<f64>,
    /// Lower corner (`Origin`, default zero).
    pub origin: Vec<f64>,
    /// Periodicity per axis.
    pub periodic: Vec<bool>,
}

/// What a point file holds: the points, and a box when the file names one.
#[derive(Clone, Debug, PartialEq)]
pub struct PointFile {
    /// The points in file order.
    pub points: Points,
    /// The box, if the file gives one.
    pub cell: Option<BoxInfo>,
}

/// Reads a point file: extended XYZ when the name ends in `.xyz` or `.extxyz`,
/// otherwise plain text.
pub fn read_points(path: &Path) -> Result<PointFile, InputError> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| InputError::file(path, format!("cannot read the file: {e}")))?;
    let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("");
    if ext.eq_ignore_ascii_case("xyz") || ext.eq_ignore_ascii_case("extxyz") {
        parse_extended_xyz(path, &text)
    } else {
        parse_plain(path, &text).map(|points| PointFile { points, cell: None })
    }
}

/// Plain text: one point per line, 2 or 3 numbers separated by white space; the
/// column count of the first point fixes the dimension; `#` starts a comment and
/// blank lines are skipped.
pub fn parse_plain(path: &Path, text: &str) -> Result<Points, InputError> {
    let mut two = Vec::new();
    let mut three = Vec::new();
    let mut dim: Option<(usize, usize)> = None; // (columns, line that set them)
    for (k, raw) in text.lines().enumerate() {
        let line = k + 1;
        let content = raw.split('#').next().unwrap_or("");
        let tokens: Vec<&str> = content.split_whitespace().collect();
        if tokens.is_empty() {
            continue;
        }
        let (columns, first_line) = match dim {
            Some(d) => d,
            None => {
                if tokens.len() != 2 && tokens.len() != 3 {
                    return Err(InputError::at(
                        path,
                        line,
                        format!(
                            "found {} columns; expected 2 or 3 coordinates per line (x y [z])",
                            tokens.len()
                        ),
                    ));
                }
                dim = Some((tokens.len(), line));
                (tokens.len(), line)
            }
        };
        if tokens.len() != columns {
            return Err(InputError::at(
                path,
                line,
                format!(
                    "found {} columns; expected {columns} coordinates as on line {first_line}",
                    tokens.len()
                ),
            ));
        }
        let mut x = [0.0; 3];
        for (c, tok) in tokens.iter().enumerate() {
            x[c] = parse_finite(path, line, tok, || format!("coordinate {}", c + 1))?;
        }
        if columns == 2 {
            two.push([x[0], x[1]]);
        } else {
            three.push(x);
        }
    }
    match dim {
        Some((2, _)) => Ok(Points::Two(two)),
        Some(_) => Ok(Points::Three(three)),
        None => Err(InputError::file(
            path,
            "no points: expected lines of 2 or 3 coordinates",
        )),
    }
}

/// Extended XYZ: a count line, a comment line of `key=value` pairs (`Lattice` with
/// 9 numbers for an orthogonal cell, `pbc="T T T"`, `Origin`, `Properties` naming
/// the `pos` columns), then one atom per line.
pub fn parse_extended_xyz(path: &Path, text: &str) -> Result<PointFile, InputError> {
    let mut lines = text.lines().enumerate().map(|(k, l)| (k + 1, l));
    let (line, count_line) = lines
        .next()
        .ok_or_else(|| InputError::file(path, "empty file; expected an atom count on line 1"))?;
    let count: usize = count_line.trim().parse().map_err(|_| {
        InputError::at(
            path,
            line,
            format!(
                "'{}' is not an atom count; expected a whole number",
                count_line.trim()
            ),
        )
    })?;
    let (comment_line, comment) = lines
        .next()
        .ok_or_else(|| InputError::at(path, 2, "missing the comment line"))?;
    let info = key_values(comment);
    let get = |key: &str| {
        info.iter()
            .find(|(k, _)| k.eq_ignore_ascii_case(key))
            .map(|(_, v)| v.as_str())
    };
    let pos_column = position_column(path, comment_line, get("Properties"))?;
    let cell = match get("Lattice") {
        None => None,
        Some(lattice) => Some(orthogonal_cell(
            path,
            comment_line,
            lattice,
            get("pbc"),
            get("Origin"),
        )?),
    };
    let mut points = Vec::new();
    let mut last_line = comment_line;
    for (line, raw) in lines.by_ref() {
        if points.len() == count {
            break;
        }
        last_line = line;
        let tokens: Vec<&str> = raw.split_whitespace().collect();
        if tokens.len() < pos_column + 3 {
            return Err(InputError::at(
                path,
                line,
                format!(
                    "found {} columns; expected at least {} (positions in columns {}-{})",
                    tokens.len(),
                    pos_column + 3,
                    pos_column + 1,
                    pos_column + 3
                ),
            ));
        }
        let mut x = [0.0; 3];
        for (c, v) in x.iter_mut().enumerate() {
            *v = parse_finite(path, line, tokens[pos_column + c], || {
                format!("coordinate {}", c + 1)
            })?;
        }
        points.push(x);
    }
    if points.len() < count {
        return Err(InputError::at(
            path,
            last_line,
            format!(
                "the file ends here, after {} atoms; line 1 says {count}",
                points.len()
            ),
        ));
    }
    Ok(PointFile {
        points: Points::Three(points),
        cell,
    })
}

/// Splits `key=value key2="quoted value"` into pairs.
fn key_values(comment: &str) -> Vec<(String, String)> {
    let mut out = Vec::new();
    let mut rest = comment.trim();
    while !rest.is_empty() {
        let Some(eq) = rest.find('=') else { break };
        let key = rest[..eq].trim().to_string();
        let after = rest[eq + 1..].trim_start();
        let (value, remaining) = if let Some(stripped) = after.strip_prefix('"') {
            match stripped.find('"') {
                Some(end) => (&stripped[..end], &stripped[end + 1..]),
                None => (stripped, ""),
            }
        } else {
            match after.find(char::is_whitespace) {
                Some(end) => (&after[..end], &after[end..]),
                None => (after, ""),
            }
        };
        // a key may be preceded by bare words (a free comment): keep the last word
        let key = key.split_whitespace().last().unwrap_or("").to_string();
        out.push((key, value.to_string()));
        rest = remaining.trim_start();
    }
    out
}

/// The 0-based column where `pos` starts, from `Properties=name:type:count:...`.
fn position_column(
    path: &Path,
    line: usize,
    properties: Option<&str>,
) -> Result<usize, InputError> {
    let Some(props) = properties else {
        return Ok(1); // species:S:1:pos:R:3
    };
    let fields: Vec<&str> = props.split(':').collect();
    let mut column = 0;
    for triple in fields.chunks(3) {
        let [name, _kind, count] = triple else {
            return Err(InputError::at(
                path,
                line,
                format!("Properties='{props}' is not name:type:count triples"),
            ));
        };
        if name.eq_ignore_ascii_case("pos") {
            return Ok(column);
        }
        let count = count.parse::<usize>().map_err(|_| {
            InputError::at(
                path,
                line,
                format!("Properties: count '{count}' of '{name}' is not a whole number"),
            )
        })?;
        // the caller adds 3 for the pos columns
        column = column
            .checked_add(count)
            .filter(|c| c.checked_add(3).is_some())
            .ok_or_else(|| {
                InputError::at(
                    path,
                    line,
                    format!("Properties: count {count} of '{name}' is too large"),
                )
            })?;
    }
    Err(InputError::at(path, line, "Properties has no 'pos' column"))
}

fn orthogonal_cell(
    path: &Path,
    line: usize,
    lattice: &str,
    pbc: Option<&str>,
    origin: Option<&str>,
) -> Result<BoxInfo, InputError> {
    let numbers = |text: &str, what: &str| -> Result<Vec<f64>, InputError> {
        text.split_whitespace()
            .map(|t| parse_finite(path, line, t, || format!("a {what} entry")))
            .collect()
    };
    let m = numbers(lattice, "Lattice")?;
    if m.len() != 9 {
        return Err(InputError::at(
            path,
            line,
            format!("Lattice has {} numbers; expected 9", m.len()),
        ));
    }
    for (k, &v) in m.iter().enumerate() {
        if k % 4 != 0 && v != 0.0 {
            return Err(InputError::at(
                path,
                line,
                "Lattice is not orthogonal; only boxes with axis-aligned sides are supported",
            ));
        }
    }
    let lengths = vec![m[0], m[4], m[8]];
    if lengths.iter().any(|&l| l <= 0.0) {
        return Err(InputError::at(
            path,
            line,
            "Lattice side lengths must be > 0",
        ));
    }
    let periodic = match pbc {
        None => vec![true; 3],
        Some(p) => {
            let flags: Vec<&str> = p.split_whitespace().collect();
            if flags.len() != 3 {
                return Err(InputError::at(
                    path,
                    line,
                    format!("pbc=\"{p}\"; expected three of T/F"),
                ));
            }
            flags
                .iter()
                .map(|f| match *f {
                    "T" | "t" | "True" | "true" | "1" => Ok(true),
                    "F" | "f" | "False" | "false" | "0" => Ok(false),
                    other => Err(InputError::at(
                        path,
                        line,
                        format!("pbc flag '{other}'; expected T or F"),
                    )),
                })
                .collect::<Result<_, _>>()?
        }
    };
    let origin = match origin {
        None => vec![0.0; 3],
        Some(o) => {
            let v = numbers(o, "Origin")?;
            if v.len() != 3 {
                return Err(InputError::at(path, line, "Origin needs 3 numbers"));
            }
            v
        }
    };
    Ok(BoxInfo {
        lengths,
        origin,
        periodic,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn p() -> &'static Path {
        Path::new("pts.txt")
    }

    #[test]
    fn plain_text_with_comments() {
        let pts = parse_plain(p(), "# header\n1 2\n\n  3.5 -4 # trailing\n").unwrap();
        assert_eq!(pts, Points::Two(vec![[1.0, 2.0], [3.5, -4.0]]));
        let pts = parse_plain(p(), "1 2 3\n").unwrap();
        assert_eq!(pts, Points::Three(vec![[1.0, 2.0, 3.0]]));
    }

    #[test]
    fn plain_text_errors_name_the_line() {
        let e = parse_plain(p(), "1 2 3\n4 5\n").unwrap_err();
        assert_eq!(
            e.to_string(),
            "pts.txt:2: found 2 columns; expected 3 coordinates as on line 1"
        );
        let e = parse_plain(p(), "1 2\n4 x\n").unwrap_err();
        assert_eq!(
            e.to_string(),
            "pts.txt:2: coordinate 2 is 'x'; expected a number"
        );
        let e = parse_plain(p(), "#\n1 nan\n").unwrap_err();
        assert_eq!(
            e.to_string(),
            "pts.txt:2: coordinate 2 is NaN; expected a finite number"
        );
        let e = parse_plain(p(), "1 2 3 4\n").unwrap_err();
        assert!(e.to_string().starts_with("pts.txt:1: found 4 columns"));
        let e = parse_plain(p(), "# only a comment\n\n").unwrap_err();
        assert_eq!(
            e.to_string(),
            "pts.txt: no points: expected lines of 2 or 3 coordinates"
        );
        let e = parse_plain(p(), "1 inf\n").unwrap_err();
        assert!(e.to_string().contains("inf"));
    }

    #[test]
    fn extended_xyz_box_and_pbc() {
        let text = "2\nLattice=\"10 0 0 0 11 0 0 0 12\" Properties=species:S:1:pos:R:3 pbc=\"T T F\"\nAr 1 2 3\nAr 4 5 6\n";
        let f = parse_extended_xyz(Path::new("a.xyz"), text).unwrap();
        assert_eq!(
            f.points,
            Points::Three(vec![[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]])
        );
        let cell = f.cell.unwrap();
        assert_eq!(cell.lengths, vec![10.0, 11.0, 12.0]);
        assert_eq!(cell.periodic, vec![true, true, false]);
    }

    #[test]
    fn extended_xyz_errors() {
        let path = Path::new("a.xyz");
        let e = parse_extended_xyz(path, "3\n\nH 0 0 0\n").unwrap_err();
        assert_eq!(
            e.to_string(),
            "a.xyz:3: the file ends here, after 1 atoms; line 1 says 3"
        );
        let e = parse_extended_xyz(path, "18446744073709551615\n\nH 0 0 0\n").unwrap_err();
        assert!(
            e.to_string().starts_with("a.xyz:3: the file ends here"),
            "{e}"
        );
        let e = parse_extended_xyz(path, "x\n").unwrap_err();
        assert!(e.to_string().starts_with("a.xyz:1:"), "{e}");
        let e =
            parse_extended_xyz(path, "1\nLattice=\"1 1 0 0 1 0 0 0 1\"\nH 0 0 0\n").unwrap_err();
        assert!(e.to_string().contains("not orthogonal"), "{e}");
        let e = parse_extended_xyz(path, "1\n\nH 0 0\n").unwrap_err();
        assert!(e.to_string().starts_with("a.xyz:3: found 3 columns"), "{e}");
    }

    #[test]
    fn properties_locate_positions() {
        let text = "1\nProperties=id:I:1:species:S:1:pos:R:3\n7 C 1 2 3\n";
        let f = parse_extended_xyz(Path::new("a.xyz"), text).unwrap();
        assert_eq!(f.points, Points::Three(vec![[1.0, 2.0, 3.0]]));
        assert!(f.cell.is_none());
    }
}
