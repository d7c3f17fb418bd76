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
    let (points, values) = parse_field_columns::<D, 1>(path, text, [name])?;
    Ok((points, values.into_iter().map(|[v]| v).collect()))
}

/// Points and their `W` values per particle, as a field file holds them.
pub type FieldColumns<const D: usize, const W: usize> = (Vec<[f64; D]>, Vec<[f64; W]>);

/// Reads a field file of `W` value columns called `names` (`x,y,z,ax,ay,az` for
/// 3D vortex particles): an optional header naming them (further columns after
/// them are allowed and skipped, so that a field file cellist wrote reads back),
/// then `D + W` numbers per line (as many as the header names, if there is
/// one), separated by commas or blanks.
pub fn read_field_columns<const D: usize, const W: usize>(
    path: &Path,
    names: [&str; W],
) -> Result<FieldColumns<D, W>, InputError> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| InputError::file(path, format!("cannot read: {e}")))?;
    parse_field_columns(path, &text, names)
}

/// [`read_field_columns`] on text already read.
pub fn parse_field_columns<const D: usize, const W: usize>(
    path: &Path,
    text: &str,
    names: [&str; W],
) -> Result<FieldColumns<D, W>, InputError> {
    const { assert!(D + W <= 12, "at most 12 columns are read") };
    let (mut points, mut values) = (Vec::new(), Vec::new());
    let mut columns: Vec<String> = AXES[..D]
        .iter()
        .chain(&names)
        .map(|s| s.to_string())
        .collect();
    let expected = columns.join(",");
    let mut first = true;
    for (index, tokens) in data_lines(text) {
        let header = first && tokens.first().is_some_and(|t| t.parse::<f64>().is_err());
        first = false;
        if header {
            if tokens.len() < D + W || tokens[..D + W].join(",") != expected {
                return Err(InputError::at(
                    path,
                    index + 1,
                    format!(
                        "the header is '{}'; expected '{expected}' for a {D}D field",
                        tokens.join(",")
                    ),
                ));
            }
            columns = tokens.iter().map(|t| t.to_string()).collect();
            continue;
        }
        if tokens.len() != columns.len() {
            return Err(InputError::at(
                path,
                index + 1,
                format!(
                    "{} values; expected {} ({})",
                    tokens.len(),
                    columns.len(),
                    columns.join(",")
                ),
            ));
        }
        let mut numbers = [0.0; 12];
        for (k, token) in tokens.iter().take(D + W).enumerate() {
            numbers[k] = parse_finite(path, index + 1, token, || columns[k].clone())?;
        }
        points.push(std::array::from_fn(|a| numbers[a]));
        values.push(std::array::from_fn(|c| numbers[D + c]));
    }
    if points.is_empty() {
        return Err(InputError::file(
            path,
            format!("no particles; expected lines x,y[,z],{}", names.join(",")),
        ));
    }
    Ok((points, values))
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

    #[test]
    fn vector_columns_read_with_or_without_further_columns() {
        let names = ["ax", "ay", "az"];
        let written = "x,y,z,ax,ay,az,u,v,w\n1,2,3,4,5,6,7,8,9\n";
        let (p, a) = parse_field_columns::<3, 3>(Path::new("f.csv"), written, names).unwrap();
        assert_eq!((p, a), (vec![[1.0, 2.0, 3.0]], vec![[4.0, 5.0, 6.0]]));
        let plain = "1 2 3 4 5 6\n0 0 0 -1 -2 -3\n";
        let (_, a) = parse_field_columns::<3, 3>(Path::new("f.txt"), plain, names).unwrap();
        assert_eq!(a[1], [-1.0, -2.0, -3.0]);
        let bad = parse_field_columns::<3, 3>(Path::new("f.txt"), "1 2 3 4 5 nan\n", names)
            .unwrap_err()
            .to_string();
        assert!(bad.starts_with("f.txt:1: az"), "{bad}");
        let short = parse_field_columns::<3, 3>(Path::new("f.txt"), "1 2 3 4 5\n", names)
            .unwrap_err()
            .to_string();
        assert_eq!(short, "f.txt:1: 5 values; expected 6 (x,y,z,ax,ay,az)");
    }
}
