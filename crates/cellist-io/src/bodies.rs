//! Body files for gravity: one body per line, `m x y z vx vy vz`, whitespace or
//! commas between numbers, `#` comments and blank lines skipped. Lines with more
//! columns (such as the shared reference files, which go on with
//! `ax ay az phi`) are read for their first seven.

use crate::error::{data_lines, parse_finite, InputError};
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

/// Reads the body file at `path`.
pub fn read_bodies(path: &Path) -> Result<BodyFile, InputError> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| InputError::file(path, format!("cannot read: {e}")))?;
    parse_bodies(path, &text)
}

/// [`read_bodies`] on text already read; `path` names it in errors. Masses must be
/// positive; an empty file is an error.
pub fn parse_bodies(path: &Path, text: &str) -> Result<BodyFile, InputError> {
    let mut out = BodyFile::default();
    for (index, tokens) in data_lines(text) {
        if tokens.len() < 7 {
            return Err(InputError::at(
                path,
                index + 1,
                format!("{} numbers; expected 7: m x y z vx vy vz", tokens.len()),
            ));
        }
        out.extra_columns |= tokens.len() > 7;
        let mut v = [0.0; 7];
        for (k, (slot, token)) in v.iter_mut().zip(&tokens).enumerate() {
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
        out.mass.push(v[0]);
        out.position.push([v[1], v[2], v[3]]);
        out.velocity.push([v[4], v[5], v[6]]);
    }
    if out.mass.is_empty() {
        return Err(InputError::file(
            path,
            "no bodies: expected lines of m x y z vx vy vz",
        ));
    }
    Ok(out)
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
}
