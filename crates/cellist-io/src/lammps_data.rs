//! LAMMPS data files (`read_data`), atom style `atomic`, orthogonal boxes: the
//! header (`N atoms`, `N atom types`, `lo hi xlo xhi` per axis) and the sections
//! `Masses`, `Atoms` (`id type x y z [ix iy iz]`) and `Velocities` (`id vx vy vz`).
//! Files ending in `.gz` are decompressed on the fly.

use crate::error::{parse_finite, InputError};
use std::collections::HashMap;
use std::io::Read;
use std::path::Path;

/// One atom of the `Atoms` section.
#[derive(Clone, Debug, PartialEq)]
pub struct DataAtom {
    /// Atom id.
    pub id: u64,
    /// Atom type, 1..=`atom_types`.
    pub kind: u32,
    /// Position (image flags already applied: `x + image L`).
    pub position: [f64; 3],
    /// Velocity (zero without a `Velocities` section).
    pub velocity: [f64; 3],
}

/// The content of a data file.
#[derive(Clone, Debug, PartialEq)]
pub struct DataFile {
    /// Box lower corner (x, y, z).
    pub lo: [f64; 3],
    /// Box upper corner.
    pub hi: [f64; 3],
    /// Number of atom types.
    pub atom_types: u32,
    /// Mass per type (index `type - 1`), if the file has a `Masses` section.
    pub masses: Option<Vec<f64>>,
    /// The atoms in file order.
    pub atoms: Vec<DataAtom>,
    /// True when the file had a `Velocities` section.
    pub has_velocities: bool,
}

/// Reads a LAMMPS data file.
pub fn read_data(path: &Path) -> Result<DataFile, InputError> {
    let bytes =
        std::fs::read(path).map_err(|e| InputError::file(path, format!("cannot read: {e}")))?;
    decode_data(path, &bytes)
}

/// Parses the bytes of a data file: gzip-compressed when `path` ends in `.gz`,
/// otherwise UTF-8 text (`path` only names it in errors and tells the two apart).
pub fn decode_data(path: &Path, bytes: &[u8]) -> Result<DataFile, InputError> {
    let decompressed;
    let text = if path.extension().is_some_and(|e| e == "gz") {
        let mut text = String::new();
        flate2::read::MultiGzDecoder::new(bytes)
            .read_to_string(&mut text)
            .map_err(|e| InputError::file(path, format!("cannot decompress: {e}")))?;
        decompressed = text;
        decompressed.as_str()
    } else {
        std::str::from_utf8(bytes).map_err(|_| InputError::file(path, "not UTF-8 text"))?
    };
    parse_data(path, text)
}

/// Sections with a fixed number of lines that cellist reads past (pair
/// coefficients come from the scenario).
const SKIPPED_SECTIONS: [&str; 2] = ["Pair Coeffs", "PairIJ Coeffs"];

/// Parses the text of a data file (`path` only names it in errors).
pub fn parse_data(path: &Path, text: &str) -> Result<DataFile, InputError> {
    // header counts are not trusted for allocation beyond the file's length (Lines)
    let mut lines = Lines::new(path, text);
    lines.next_raw(); // the title line
    let mut atoms_count: Option<usize> = None;
    let mut atom_types: Option<u32> = None;
    let mut bounds: [Option<(f64, f64)>; 3] = [None; 3];
    // header: until the first section keyword
    let first_section = loop {
        let Some((no, line)) = lines.next_content() else {
            return Err(InputError::file(path, "no Atoms section"));
        };
        let words: Vec<&str> = line.split_whitespace().collect();
        if is_section(line) {
            break (no, line.to_string());
        }
        match words.as_slice() {
            [n, "atoms"] => atoms_count = Some(parse_count(path, no, n, "the number of atoms")?),
            [n, "atom", "types"] => {
                let count = parse_count(path, no, n, "the number of atom types")?;
                atom_types = Some(
                    u32::try_from(count)
                        .ok()
                        .filter(|&t| t < 1 << 20)
                        .ok_or_else(|| {
                            InputError::at(
                                path,
                                no,
                                format!("{count} atom types; expected fewer than 2^20"),
                            )
                        })?,
                )
            }
            [lo, hi, axis_lo, axis_hi]
                if axis_lo.len() == 3 && axis_lo.ends_with("lo") && axis_hi.ends_with("hi") =>
            {
                let axis = match *axis_lo {
                    "xlo" => 0,
                    "ylo" => 1,
                    "zlo" => 2,
                    _ => {
                        return Err(InputError::at(
                            path,
                            no,
                            format!("unknown header line '{line}'"),
                        ))
                    }
                };
                let lo = parse_finite(path, no, lo, || axis_lo.to_string())?;
                let hi = parse_finite(path, no, hi, || axis_hi.to_string())?;
                if hi <= lo {
                    return Err(InputError::at(
                        path,
                        no,
                        format!("{axis_hi} {hi} must be above {axis_lo} {lo}"),
                    ));
                }
                if !(hi - lo).is_finite() {
                    return Err(InputError::at(
                        path,
                        no,
                        format!(
                            "{axis_hi} - {axis_lo} is {}; expected a finite box length",
                            hi - lo
                        ),
                    ));
                }
                bounds[axis] = Some((lo, hi));
            }
            [_, _, _, "xy", "xz", "yz"] => {
                return Err(InputError::at(
                    path,
                    no,
                    "triclinic boxes are not supported; expected an orthogonal box",
                ))
            }
            [n, what @ ..] if !what.is_empty() => {
                let count = parse_count(path, no, n, &format!("the number of {}", what.join(" ")))?;
                if count != 0 {
                    return Err(InputError::at(
                        path,
                        no,
                        format!(
                            "'{}' is not supported: atom style atomic has no molecular topology",
                            line
                        ),
                    ));
                }
            }
            _ => {
                return Err(InputError::at(
                    path,
                    no,
                    format!("unknown header line '{line}'"),
                ))
            }
        }
    };
    let n =
        atoms_count.ok_or_else(|| InputError::file(path, "the header has no 'N atoms' line"))?;
    let atom_types = atom_types
        .ok_or_else(|| InputError::file(path, "the header has no 'N atom types' line"))?;
    let mut lo = [0.0; 3];
    let mut hi = [0.0; 3];
    for (axis, b) in bounds.iter().enumerate() {
        let (l, h) = b.ok_or_else(|| {
            InputError::file(
                path,
                format!(
                    "the header has no '{0}lo {0}hi' line",
                    ["x", "y", "z"][axis]
                ),
            )
        })?;
        lo[axis] = l;
        hi[axis] = h;
    }

    let mut masses: Option<Vec<f64>> = None;
    let mut atoms: Option<Vec<DataAtom>> = None;
    // the line of each atom, for messages about ids
    let mut atom_lines: Vec<usize> = Vec::new();
    // the (line, id, velocity) entries of the Velocities section
    let mut velocities: Option<Vec<(usize, u64, [f64; 3])>> = None;
    let mut section = Some(first_section);
    while let Some((no, header)) = section.take() {
        let (name, hint) = match header.split_once('#') {
            Some((name, hint)) => (name.trim().to_string(), hint.trim().to_string()),
            None => (header.trim().to_string(), String::new()),
        };
        match name.as_str() {
            "Masses" => {
                let entries = lines.entries(atom_types as usize, "Masses")?;
                let mut m = vec![f64::NAN; atom_types as usize];
                // the line that gave each type its mass (0: none yet)
                let mut given = vec![0; atom_types as usize];
                for (no, line) in entries {
                    let f = fields(path, no, line, 2, 2, "type mass")?;
                    let t = parse_type(path, no, f[0], atom_types)?;
                    let mass = parse_finite(path, no, f[1], || "the mass".into())?;
                    if mass <= 0.0 {
                        return Err(InputError::at(path, no, format!("mass {mass} must be > 0")));
                    }
                    let first = std::mem::replace(&mut given[t as usize - 1], no);
                    if first != 0 {
                        return Err(InputError::at(
                            path,
                            no,
                            format!("atom type {t} was already given a mass on line {first}; expected one line per type"),
                        ));
                    }
                    m[t as usize - 1] = mass;
                }
                masses = Some(m);
            }
            "Atoms" => {
                if !hint.is_empty() && hint != "atomic" {
                    return Err(InputError::at(
                        path,
                        no,
                        format!("atom style '{hint}' is not supported; expected 'atomic' (id type x y z)"),
                    ));
                }
                let entries = lines.entries(n, "Atoms")?;
                let mut list = Vec::with_capacity(entries.len());
                for (no, line) in entries {
                    let f = fields(path, no, line, 5, 8, "id type x y z [ix iy iz]")?;
                    if f.len() != 5 && f.len() != 8 {
                        return Err(InputError::at(
                            path,
                            no,
                            format!(
                                "{} fields; expected 5 (id type x y z) or 8 (with image flags)",
                                f.len()
                            ),
                        ));
                    }
                    let id = parse_id(path, no, f[0])?;
                    let kind = parse_type(path, no, f[1], atom_types)?;
                    let mut position = [0.0; 3];
                    for a in 0..3 {
                        position[a] =
                            parse_finite(path, no, f[2 + a], || ["x", "y", "z"][a].to_string())?;
                        if f.len() == 8 {
                            let image: i64 = f[5 + a].parse().map_err(|_| {
                                InputError::at(
                                    path,
                                    no,
                                    format!(
                                        "image flag {} is '{}'; expected an integer",
                                        ["ix", "iy", "iz"][a],
                                        f[5 + a]
                                    ),
                                )
                            })?;
                            position[a] += image as f64 * (hi[a] - lo[a]);
                            if !position[a].is_finite() {
                                return Err(InputError::at(
                                    path,
                                    no,
                                    format!(
                                        "image flag {} {image} puts the atom at {} = {}; expected a finite position",
                                        ["ix", "iy", "iz"][a],
                                        ["x", "y", "z"][a],
                                        position[a]
                                    ),
                                ));
                            }
                        }
                    }
                    list.push(DataAtom {
                        id,
                        kind,
                        position,
                        velocity: [0.0; 3],
                    });
                    atom_lines.push(no);
                }
                atoms = Some(list);
            }
            "Velocities" => {
                let entries = lines.entries(n, "Velocities")?;
                let mut list = Vec::with_capacity(entries.len());
                for (no, line) in entries {
                    let f = fields(path, no, line, 4, 4, "id vx vy vz")?;
                    let id = parse_id(path, no, f[0])?;
                    let mut v = [0.0; 3];
                    for a in 0..3 {
                        v[a] =
                            parse_finite(path, no, f[1 + a], || ["vx", "vy", "vz"][a].to_string())?;
                    }
                    list.push((no, id, v));
                }
                velocities = Some(list);
            }
            s if SKIPPED_SECTIONS.contains(&s) => {
                let count = if s == "PairIJ Coeffs" {
                    atom_types as usize * (atom_types as usize + 1) / 2
                } else {
                    atom_types as usize
                };
                lines.entries(count, s)?;
            }
            _ => {
                return Err(InputError::at(
                    path,
                    no,
                    format!(
                    "unknown or unsupported section '{name}'; expected Masses, Atoms, Velocities"
                ),
                ))
            }
        }
        if let Some((no, line)) = lines.next_content() {
            if !is_section(line) {
                return Err(InputError::at(
                    path,
                    no,
                    format!(
                        "'{line}': more lines than the header's counts; expected a section keyword"
                    ),
                ));
            }
            section = Some((no, line.to_string()));
        }
    }
    let mut atoms = atoms.ok_or_else(|| InputError::file(path, "no Atoms section"))?;
    let mut index: HashMap<u64, usize> = HashMap::with_capacity(atoms.len());
    for (k, a) in atoms.iter().enumerate() {
        if let Some(first) = index.insert(a.id, k) {
            return Err(InputError::at(
                path,
                atom_lines[k],
                format!(
                    "atom id {} appears twice in the Atoms section (first on line {})",
                    a.id, atom_lines[first]
                ),
            ));
        }
    }
    let has_velocities = velocities.is_some();
    if let Some(list) = velocities {
        // the line that gave each atom its velocity (0: none yet)
        let mut seen = vec![0; atoms.len()];
        for (no, id, v) in list {
            let k = *index.get(&id).ok_or_else(|| {
                InputError::at(path, no, format!("the Velocities section names atom id {id}, which is not in the Atoms section"))
            })?;
            let first = std::mem::replace(&mut seen[k], no);
            if first != 0 {
                return Err(InputError::at(
                    path,
                    no,
                    format!("atom id {id} appears twice in the Velocities section (first on line {first})"),
                ));
            }
            atoms[k].velocity = v;
        }
    }
    Ok(DataFile {
        lo,
        hi,
        atom_types,
        masses,
        atoms,
        has_velocities,
    })
}

fn is_section(line: &str) -> bool {
    let name = line.split('#').next().unwrap_or("").trim();
    name.chars().next().is_some_and(|c| c.is_ascii_uppercase())
}

fn parse_count(path: &Path, no: usize, token: &str, what: &str) -> Result<usize, InputError> {
    token.parse::<usize>().map_err(|_| {
        InputError::at(
            path,
            no,
            format!("{what} is '{token}'; expected a non-negative integer"),
        )
    })
}

fn parse_id(path: &Path, no: usize, token: &str) -> Result<u64, InputError> {
    match token.parse::<u64>() {
        Ok(id) if id > 0 => Ok(id),
        _ => Err(InputError::at(
            path,
            no,
            format!("atom id is '{token}'; expected a positive integer"),
        )),
    }
}

fn parse_type(path: &Path, no: usize, token: &str, atom_types: u32) -> Result<u32, InputError> {
    match token.parse::<u32>() {
        Ok(t) if (1..=atom_types).contains(&t) => Ok(t),
        _ => Err(InputError::at(
            path,
            no,
            format!("atom type is '{token}'; expected an integer from 1 to {atom_types} (the header's atom types)"),
        )),
    }
}

fn fields<'a>(
    path: &Path,
    no: usize,
    line: &'a str,
    min: usize,
    max: usize,
    layout: &str,
) -> Result<Vec<&'a str>, InputError> {
    let f: Vec<&str> = line.split_whitespace().collect();
    if f.len() < min || f.len() > max {
        return Err(InputError::at(
            path,
            no,
            format!("{} fields; expected '{layout}'", f.len()),
        ));
    }
    Ok(f)
}

/// The lines of the file with their 1-based numbers, comments (`#`) removed.
struct Lines<'a> {
    path: &'a Path,
    max_lines: usize,
    inner: std::iter::Peekable<std::iter::Enumerate<std::str::Lines<'a>>>,
}

impl<'a> Lines<'a> {
    fn new(path: &'a Path, text: &'a str) -> Self {
        Lines {
            path,
            max_lines: text.lines().count(),
            inner: text.lines().enumerate().peekable(),
        }
    }

    fn next_raw(&mut self) -> Option<(usize, &'a str)> {
        self.inner.next().map(|(k, l)| (k + 1, l))
    }

    /// The next line that is not blank after removing a comment; section keywords
    /// keep their `# style` hint.
    fn next_content(&mut self) -> Option<(usize, &'a str)> {
        while let Some((no, line)) = self.next_raw() {
            let trimmed = line.trim();
            if is_section(trimmed) {
                return Some((no, trimmed));
            }
            let content = trimmed.split('#').next().unwrap_or("").trim();
            if !content.is_empty() {
                return Some((no, content));
            }
        }
        None
    }

    /// The `count` entries of section `name`: non-blank lines after the keyword.
    fn entries(&mut self, count: usize, name: &str) -> Result<Vec<(usize, &'a str)>, InputError> {
        let mut out = Vec::with_capacity(count.min(self.max_lines));
        while out.len() < count {
            match self.next_content() {
                Some((no, line)) if is_section(line) => {
                    return Err(InputError::at(
                        self.path,
                        no,
                        format!(
                            "section {name} has {} lines; the header says {count}",
                            out.len()
                        ),
                    ))
                }
                Some(entry) => out.push(entry),
                None => {
                    return Err(InputError::file(
                        self.path,
                        format!(
                            "the file ends inside section {name} after {} of {count} lines",
                            out.len()
                        ),
                    ))
                }
            }
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const GOOD: &str = "LAMMPS data file\n\n3 atoms\n1 atom types\n0 bonds\n\n0 10 xlo xhi\n0 10 ylo yhi\n-0.5 0.5 zlo zhi\n\nMasses\n\n1 2.5\n\nAtoms # atomic\n\n3 1 1.0 2.0 0.0 0 0 0\n1 1 3.0 4.0 0.0 1 0 0\n2 1 5 6 0\n\nVelocities\n\n1 0.1 0.2 0\n2 0 0 0\n3 -1 1 0 # a comment\n";

    #[test]
    fn reads_header_masses_atoms_velocities() {
        let d = parse_data(Path::new("t.data"), GOOD).unwrap();
        assert_eq!(d.lo, [0.0, 0.0, -0.5]);
        assert_eq!(d.hi, [10.0, 10.0, 0.5]);
        assert_eq!(d.masses, Some(vec![2.5]));
        assert_eq!(d.atoms.len(), 3);
        assert_eq!(d.atoms[1].id, 1);
        assert_eq!(d.atoms[1].position, [13.0, 4.0, 0.0]);
        assert_eq!(d.atoms[1].velocity, [0.1, 0.2, 0.0]);
        assert_eq!(d.atoms[0].velocity, [-1.0, 1.0, 0.0]);
        assert!(d.has_velocities);
    }

    #[test]
    fn errors_name_the_line_and_the_field() {
        let cases = [
            (GOOD.replace("3 1 1.0 2.0", "3 1 1.0 abc"), "t.data:17: y is 'abc'; expected a number"),
            (GOOD.replace("2 1 5 6 0\n", "2 1 5 6\n"), "t.data:19: 4 fields; expected 'id type x y z [ix iy iz]'"),
            (GOOD.replace("2 1 5 6 0", "2 7 5 6 0"), "t.data:19: atom type is '7'; expected an integer from 1 to 1 (the header's atom types)"),
            (GOOD.replace("0 10 ylo yhi", "0 10 0 xy xz yz"), "t.data:8: triclinic boxes are not supported; expected an orthogonal box"),
            (GOOD.replace("0 bonds", "5 bonds"), "t.data:5: '5 bonds' is not supported: atom style atomic has no molecular topology"),
            (GOOD.replace("Atoms # atomic", "Atoms # full"), "t.data:15: atom style 'full' is not supported; expected 'atomic' (id type x y z)"),
            (GOOD.replace("2 1 5 6 0\n", ""), "t.data:20: section Atoms has 2 lines; the header says 3"),
            (GOOD.replace("2 0 0 0", "9 0 0 0"), "t.data:24: the Velocities section names atom id 9, which is not in the Atoms section"),
            (GOOD.replace("2 0 0 0", "1 0 0 0"), "t.data:24: atom id 1 appears twice in the Velocities section (first on line 23)"),
            (GOOD.replace("3 1 1.0", "1 1 1.0"), "t.data:18: atom id 1 appears twice in the Atoms section (first on line 17)"),
            (GOOD.replace("1 atom types", "2 atom types").replace("1 2.5\n", "1 2.5\n1 3\n"), "t.data:14: atom type 1 was already given a mass on line 13; expected one line per type"),
            (GOOD.replace("0 10 xlo", "-1e308 1e308 xlo"), "t.data:7: xhi - xlo is inf; expected a finite box length"),
            (GOOD.replace("1 1 3.0 4.0 0.0 1 0 0", "1 1 3.0 4.0 0.0 0 9223372036854775807 0").replace("0 10 ylo", "0 1e300 ylo"), "t.data:18: image flag iy 9223372036854775807 puts the atom at y = inf; expected a finite position"),
            (GOOD.replace("1 2.5", "1 -2.5"), "t.data:13: mass -2.5 must be > 0"),
            (GOOD.replace("Velocities", "Bonds"), "t.data:21: unknown or unsupported section 'Bonds'; expected Masses, Atoms, Velocities"),
        ];
        for (text, want) in cases {
            let err = parse_data(Path::new("t.data"), &text)
                .unwrap_err()
                .to_string();
            assert_eq!(err, want);
        }
    }
}
