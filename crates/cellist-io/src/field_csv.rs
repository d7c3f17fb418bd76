//! Particle fields as CSV: a header `x,y[,z],phi`, then one particle per line,
//! numbers to 17 significant digits (they read back to the same bits).

use crate::error::{data_lines, parse_finite, InputError};
use crate::output::format_g17;
use std::io::{self, Write};
use std::path::Path;

const AXES: [&str; 3] = ["x", "y", "z"];

/// The header line of a `dimension`-D field file, `x,y[,z],phi`.
pub fn field_header(dimension: usize) -> String {
    let mut names: Vec<&str> = AXES[..dimension].to_vec();
    names.push("phi");
    names.join(",")
}

/// Writes the header and one line `x,y[,z],phi` per particle: the first
/// `dimension` components of each point.
pub fn write_field<W: Write>(
    out: &mut W,
    dimension: usize,
    points: &[[f64; 3]],
    phi: &[f64],
) -> io::Result<()> {
    write_field_columns(out, dimension, points, &[("phi", phi)])
}

/// Writes the header `x,y[,z],name1,name2,...` and one line per particle: the
/// first `dimension` components of each point, then its value in every column.
pub fn write_field_columns<W: Write>(
    out: &mut W,
    dimension: usize,
    points: &[[f64; 3]],
    columns: &[(&str, &[f64])],
) -> io::Result<()> {
    let mut names: Vec<&str> = AXES[..dimension].to_vec();
    names.extend(columns.iter().map(|c| c.0));
    writeln!(out, "{}", names.join(","))?;
    let mut line = String::new();
    for (k, x) in points.iter().enumerate() {
        line.clear();
        for c in &x[..dimension] {
            format_g17(*c, &mut line);
            line.push(',');
        }
        for (_, values) in columns {
            format_g17(values[k], &mut line);
            line.push(',');
        }
        line.pop();
        line.push('\n');
        out.write_all(line.as_bytes())?;
    }
    Ok(())
}

/// Reads a field file written by [`write_field`] (or by hand): an optional header
/// line, then `D + 1` numbers per line separated by commas or blanks; blank lines
/// and lines starting with `#` are skipped.
pub fn read_field<const D: usize>(path: &Path) -> Result<(Vec<[f64; D]>, Vec<f64>), InputError> {
    read_field_of::<D>(path, "phi")
}

/// [`read_field`] for a value column called `name` (`x,y,gamma` for vortex
/// particles): the header, if any, must name it, and errors do.
pub fn read_field_of<const D: usize>(
    path: &Path,
    name: &str,
) -> Result<(Vec<[f64; D]>, Vec<f64>), InputError> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| InputError::file(path, format!("cannot read: {e}")))?;
    parse_field_of(path, &text, name)
}

/// [`read_field`] on text already read; `path` names it in errors.
pub fn parse_field<const D: usize>(
    path: &Path,
    text: &str,
) -> Result<(Vec<[f64; D]>, Vec<f64>), InputError> {
    parse_field_of(path, text, "phi")
}

/// [`read_field_of`] on text already read.
pub fn parse_field_of<const D: usize>(
    path: &Path,
    text: &str,
    name: &str,
) -> Result<(Vec<[f64; D]>, Vec<f64>), InputError> {
    let (mut points, mut phi) = (Vec::new(), Vec::new());
    let expected = format!("{},{name}", AXES[..D].join(","));
    let mut first = true;
    for (index, tokens) in data_lines(text) {
        let header = first && tokens.first().is_some_and(|t| t.parse::<f64>().is_err());
        first = false;
        if header {
            if tokens.join(",") != expected {
                return Err(InputError::at(
                    path,
                    index + 1,
                    format!(
                        "the header is '{}'; expected '{expected}' for a {D}D field",
                        tokens.join(",")
                    ),
                ));
            }
            continue;
        }
        if tokens.len() != D + 1 {
            return Err(InputError::at(
                path,
                index + 1,
                format!("{} values; expected {} ({expected})", tokens.len(), D + 1),
            ));
        }
        let mut values = [0.0; 4];
        for (k, token) in tokens.iter().enumerate() {
            let name = expected.split(',').nth(k).unwrap_or("value");
            values[k] = parse_finite(path, index + 1, token, || name.to_string())?;
        }
        points.push(std::array::from_fn(|a| values[a]));
        phi.push(values[D]);
    }
    if points.is_empty() {
        return Err(InputError::file(
            path,
            format!("no particles; expected lines x,y[,z],{name}"),
        ));
    }
    Ok((points, phi))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_written_field_reads_back_to_the_same_bits() {
        let points = vec![[0.1, 1.0 / 3.0], [0.7, 2e-300]];
        let phi = vec![-1.0 / 7.0, 0.0];
        let mut out = Vec::new();
        let padded: Vec<[f64; 3]> = points.iter().map(|p| [p[0], p[1], 0.0]).collect();
        write_field(&mut out, 2, &padded, &phi).unwrap();
        let text = String::from_utf8(out).unwrap();
        assert!(text.starts_with("x,y,phi\n"));
        let (p, f) = parse_field::<2>(Path::new("f.csv"), &text).unwrap();
        assert_eq!((p, f), (points, phi));
    }

    #[test]
    fn bad_lines_are_named() {
        let bad = |text: &str| {
            parse_field::<2>(Path::new("f.csv"), text)
                .unwrap_err()
                .to_string()
        };
        assert_eq!(
            bad("x,y,phi\n0.1,0.2\n"),
            "f.csv:2: 2 values; expected 3 (x,y,phi)"
        );
        assert!(bad("x,y,z,phi\n").contains("f.csv:1: the header is"));
        assert!(bad("0.1 0.2 abc\n").contains("f.csv:1: phi is 'abc'"));
        assert!(bad("# nothing\n").contains("no particles"));
    }
}
