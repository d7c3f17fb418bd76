//! LAMMPS data files (`read_data`), atom style `atomic`, orthogonal boxes: the
//! header (`N atoms`, `N atom types`, `lo hi xlo xhi` per axis) and the sections
//! `Masses`, `Atoms` (`id type x y z [ix iy iz]`) and `Velocities` (`id vx vy vz`,
//! after `Atoms`, as LAMMPS requires). Files ending in `.gz` are decompressed on
//! the fly. The file is read a line at a time: [`read_data_where`] keeps only
//! the atoms a rank wants while it checks every line.

use crate::error::{parse_finite, InputError};
use std::collections::HashMap;
use std::io::{BufRead, BufReader};
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
    /// The atoms in file order (those kept, [`read_data_where`]).
    pub atoms: Vec<DataAtom>,
    /// True when the file had a `Velocities` section.
    pub has_velocities: bool,
}

/// What a reader of a data file does with the atoms as it reads them
/// ([`read_data_where`]); a closure `FnMut(&DataAtom) -> bool` keeps what it
/// accepts and ignores the velocities.
pub trait AtomsWanted {
    /// Whether to keep `atom` (every atom of the `Atoms` section in file
    /// order, its velocity not yet read).
    fn keep(&mut self, atom: &DataAtom) -> bool;
    /// Sees the velocity `v` of atom `id`, kept or not, in the order of the
    /// `Velocities` section; `place` is the atom's in the `Atoms` section
    /// (0 for the first).
    fn velocity(&mut self, place: usize, id: u64, v: [f64; 3]) {
        let _ = (place, id, v);
    }
}

impl<F: FnMut(&DataAtom) -> bool> AtomsWanted for F {
    fn keep(&mut self, atom: &DataAtom) -> bool {
        self(atom)
    }
}

/// Reads a LAMMPS data file a line at a time, keeping in
/// [`DataFile::atoms`] only the atoms `wanted` keeps; every line is checked
/// (as [`parse_data`] checks a whole text), and the memory held is that of the kept
/// atoms and of an index of every id.
pub fn read_data_where(path: &Path, wanted: &mut dyn AtomsWanted) -> Result<DataFile, InputError> {
    let file = std::fs::File::open(path)
        .map_err(|e| InputError::file(path, format!("cannot read: {e}")))?;
    if is_gzip(path) {
        let text = BufReader::new(flate2::read::MultiGzDecoder::new(BufReader::new(file)));
        parse_lines(path, text, None, wanted)
    } else {
        let size = file.metadata().ok().map(|m| m.len());
        parse_lines(path, BufReader::new(file), size, wanted)
    }
}

/// The box `(lo, hi)` of a data file's header, read without its sections.
pub fn read_data_box(path: &Path) -> Result<([f64; 3], [f64; 3]), InputError> {
    let file = std::fs::File::open(path)
        .map_err(|e| InputError::file(path, format!("cannot read: {e}")))?;
    let header = if is_gzip(path) {
        let text = BufReader::new(flate2::read::MultiGzDecoder::new(BufReader::new(file)));
        parse_header(&mut Lines::new(path, text))?
    } else {
        parse_header(&mut Lines::new(path, BufReader::new(file)))?
    };
    Ok((header.lo, header.hi))
}

/// Keeps every atom.
fn every(_: &DataAtom) -> bool {
    true
}

fn is_gzip(path: &Path) -> bool {
    path.extension().is_some_and(|e| e == "gz")
}

/// Parses the bytes of a data file: gzip-compressed when `path` ends in `.gz`,
/// otherwise UTF-8 text (`path` only names it in errors and tells the two apart).
pub fn decode_data(path: &Path, bytes: &[u8]) -> Result<DataFile, InputError> {
    decode_data_where(path, bytes, &mut every)
}

/// [`decode_data`] keeping the atoms `wanted` keeps ([`read_data_where`]).
pub fn decode_data_where(
    path: &Path,
    bytes: &[u8],
    wanted: &mut dyn AtomsWanted,
) -> Result<DataFile, InputError> {
    if is_gzip(path) {
        let text = BufReader::new(flate2::read::MultiGzDecoder::new(bytes));
        parse_lines(path, text, None, wanted)
    } else {
        parse_lines(path, bytes, Some(bytes.len() as u64), wanted)
    }
}

/// Sections with a fixed number of lines that cellist reads past (pair
/// coefficients come from the scenario).
const SKIPPED_SECTIONS: [&str; 2] = ["Pair Coeffs", "PairIJ Coeffs"];

/// Parses the text of a data file (`path` only names it in errors).
pub fn parse_data(path: &Path, text: &str) -> Result<DataFile, InputError> {
    parse_lines(path, text.as_bytes(), Some(text.len() as u64), &mut every)
}

/// What a data file's header says, and the line of the first section.
struct Header {
    atoms: usize,
    atom_types: u32,
    lo: [f64; 3],
    hi: [f64; 3],
    first_section: (usize, String),
}

/// Reads the title line and the header, up to the first section keyword.
fn parse_header<R: BufRead>(lines: &mut Lines<'_, R>) -> Result<Header, InputError> {
    let path = lines.path;
    lines.next_raw()?; // the title line
    let mut atoms_count: Option<usize> = None;
    let mut atom_types: Option<u32> = None;
    let mut bounds: [Option<(f64, f64)>; 3] = [None; 3];
    // header: until the first section keyword
    let first_section = loop {
        let Some((no, line)) = lines.next_content()? else {
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
    let atoms =
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

    Ok(Header {
        atoms,
        atom_types,
        lo,
        hi,
        first_section,
    })
}

/// The fewest bytes of an `Atoms` line: `1 1 0 0 0` and its end.
const LEAST_ATOM_LINE: u64 = 10;

/// Marks an atom that is not kept.
const NOT_KEPT: usize = usize::MAX;

/// Parses a data file from its lines, keeping the atoms `wanted` keeps.
/// `size`: the text's bytes when known, which bound the atoms it can hold
/// (an atom's line takes at least [`LEAST_ATOM_LINE`] bytes) and so what is
/// reserved for them (a header's count alone is not trusted).
fn parse_lines<R: BufRead>(
    path: &Path,
    reader: R,
    size: Option<u64>,
    wanted: &mut dyn AtomsWanted,
) -> Result<DataFile, InputError> {
    let mut lines = Lines::new(path, reader);
    let Header {
        atoms: n,
        atom_types,
        lo,
        hi,
        first_section,
    } = parse_header(&mut lines)?;
    let mut masses: Option<Vec<f64>> = None;
    let mut atoms: Option<Vec<DataAtom>> = None;
    // every atom of the Atoms section by its place there: the place of each
    // id, each atom's line and where it is kept (NOT_KEPT: not)
    let mut places: HashMap<u64, usize> = HashMap::new();
    let mut atom_lines: Vec<usize> = Vec::new();
    let mut kept_at: Vec<usize> = Vec::new();
    let mut has_velocities = false;
    let mut section = Some(first_section);
    while let Some((no, header)) = section.take() {
        let (name, hint) = match header.split_once('#') {
            Some((name, hint)) => (name.trim().to_string(), hint.trim().to_string()),
            None => (header.trim().to_string(), String::new()),
        };
        match name.as_str() {
            "Masses" => {
                // the line that gave each type its mass (a map: the header's
                // type count is not trusted for an allocation)
                let mut given: HashMap<u32, (usize, f64)> = HashMap::new();
                lines.each_entry(atom_types as usize, "Masses", |no, line| {
                    let f = fields(path, no, line, 2, 2, "type mass")?;
                    let t = parse_type(path, no, f[0], atom_types)?;
                    let mass = parse_finite(path, no, f[1], || "the mass".into())?;
                    if mass <= 0.0 {
                        return Err(InputError::at(path, no, format!("mass {mass} must be > 0")));
                    }
                    if let Some((first, _)) = given.insert(t, (no, mass)) {
                        return Err(InputError::at(
                            path,
                            no,
                            format!("atom type {t} was already given a mass on line {first}; expected one line per type"),
                        ));
                    }
                    Ok(())
                })?;
                let mut m = vec![f64::NAN; atom_types as usize];
                for (t, (_, mass)) in given {
                    m[t as usize - 1] = mass;
                }
                masses = Some(m);
            }
            "Atoms" => {
                if atoms.is_some() {
                    return Err(InputError::at(
                        path,
                        no,
                        "a second Atoms section; expected one",
                    ));
                }
                if !hint.is_empty() && hint != "atomic" {
                    return Err(InputError::at(
                        path,
                        no,
                        format!("atom style '{hint}' is not supported; expected 'atomic' (id type x y z)"),
                    ));
                }
                let mut list = Vec::new();
                let room = size.map_or(0, |bytes| n.min((bytes / LEAST_ATOM_LINE) as usize));
                places.reserve(room);
                atom_lines.reserve(room);
                kept_at.reserve(room);
                lines.each_entry(n, "Atoms", |no, line| {
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
                    let atom = DataAtom {
                        id,
                        kind,
                        position,
                        velocity: [0.0; 3],
                    };
                    if let Some(first) = places.insert(id, atom_lines.len()) {
                        return Err(InputError::at(
                            path,
                            no,
                            format!(
                                "atom id {id} appears twice in the Atoms section (first on line {})",
                                atom_lines[first]
                            ),
                        ));
                    }
                    atom_lines.push(no);
                    if wanted.keep(&atom) {
                        kept_at.push(list.len());
                        list.push(atom);
                    } else {
                        kept_at.push(NOT_KEPT);
                    }
                    Ok(())
                })?;
                atoms = Some(list);
            }
            "Velocities" => {
                let Some(list) = atoms.as_mut() else {
                    return Err(InputError::at(
                        path,
                        no,
                        "the Velocities section must follow an Atoms section",
                    ));
                };
                if has_velocities {
                    return Err(InputError::at(
                        path,
                        no,
                        "a second Velocities section; expected one",
                    ));
                }
                has_velocities = true;
                // the line that gave each atom its velocity (0: none yet)
                let mut seen = vec![0; atom_lines.len()];
                lines.each_entry(n, "Velocities", |no, line| {
                    let f = fields(path, no, line, 4, 4, "id vx vy vz")?;
                    let id = parse_id(path, no, f[0])?;
                    let mut v = [0.0; 3];
                    for a in 0..3 {
                        v[a] =
                            parse_finite(path, no, f[1 + a], || ["vx", "vy", "vz"][a].to_string())?;
                    }
                    let place = *places.get(&id).ok_or_else(|| {
                        InputError::at(path, no, format!("the Velocities section names atom id {id}, which is not in the Atoms section"))
                    })?;
                    let first = std::mem::replace(&mut seen[place], no);
                    if first != 0 {
                        return Err(InputError::at(
                            path,
                            no,
                            format!("atom id {id} appears twice in the Velocities section (first on line {first})"),
                        ));
                    }
                    if kept_at[place] != NOT_KEPT {
                        list[kept_at[place]].velocity = v;
                    }
                    wanted.velocity(place, id, v);
                    Ok(())
                })?;
            }
            s if SKIPPED_SECTIONS.contains(&s) => {
                let count = if s == "PairIJ Coeffs" {
                    atom_types as usize * (atom_types as usize + 1) / 2
                } else {
                    atom_types as usize
                };
                lines.each_entry(count, s, |_, _| Ok(()))?;
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
        if let Some((no, line)) = lines.next_content()? {
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
    let atoms = atoms.ok_or_else(|| InputError::file(path, "no Atoms section"))?;
    Ok(DataFile {
        lo,
        hi,
        atom_types,
        masses,
        atoms,
        has_velocities,
    })
}

/// A line's content: a section keyword with its `# style` hint, or the
/// line without its comment; `None` when that is blank.
fn content(line: &str) -> Option<&str> {
    let trimmed = line.trim();
    if is_section(trimmed) {
        return Some(trimmed);
    }
    Some(trimmed.split('#').next().unwrap_or("").trim()).filter(|c| !c.is_empty())
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

/// The whitespace-separated words of `line`, between `min` and `max` (at
/// most [`MOST_FIELDS`]) of them, without an allocation per line.
fn fields<'a>(
    path: &Path,
    no: usize,
    line: &'a str,
    min: usize,
    max: usize,
    layout: &str,
) -> Result<Fields<'a>, InputError> {
    debug_assert!(max <= MOST_FIELDS);
    let mut f = Fields {
        words: [""; MOST_FIELDS],
        len: 0,
    };
    let mut count = 0;
    for word in line.split_whitespace() {
        if count < MOST_FIELDS {
            f.words[count] = word;
        }
        count += 1;
    }
    if count < min || count > max {
        return Err(InputError::at(
            path,
            no,
            format!("{count} fields; expected '{layout}'"),
        ));
    }
    f.len = count;
    Ok(f)
}

/// The most words a line of a data file has (an atom with image flags).
const MOST_FIELDS: usize = 8;

/// A line's words ([`fields`]).
struct Fields<'a> {
    words: [&'a str; MOST_FIELDS],
    len: usize,
}

impl<'a> std::ops::Deref for Fields<'a> {
    type Target = [&'a str];
    fn deref(&self) -> &[&'a str] {
        &self.words[..self.len]
    }
}

/// The lines of the file with their 1-based numbers, comments (`#`) removed,
/// read one at a time.
struct Lines<'a, R> {
    path: &'a Path,
    reader: R,
    number: usize,
    /// The last line read (its bytes are reused for the next).
    line: String,
}

impl<'a, R: BufRead> Lines<'a, R> {
    fn new(path: &'a Path, reader: R) -> Self {
        Lines {
            path,
            reader,
            number: 0,
            line: String::new(),
        }
    }

    /// Reads the next line into `self.line` (with its end); false at the
    /// end of the file.
    fn read(&mut self) -> Result<bool, InputError> {
        let mut bytes = std::mem::take(&mut self.line).into_bytes();
        bytes.clear();
        let read = self.reader.read_until(b'\n', &mut bytes).map_err(|e| {
            let what = if is_gzip(self.path) {
                "cannot decompress"
            } else {
                "cannot read"
            };
            InputError::file(self.path, format!("{what}: {e}"))
        })?;
        self.line =
            String::from_utf8(bytes).map_err(|_| InputError::file(self.path, "not UTF-8 text"))?;
        self.number += usize::from(read > 0);
        Ok(read > 0)
    }

    /// The next line without its end, `None` at the end of the file.
    fn next_raw(&mut self) -> Result<Option<(usize, &str)>, InputError> {
        if !self.read()? {
            return Ok(None);
        }
        let line = self.line.strip_suffix('\n').unwrap_or(&self.line);
        Ok(Some((self.number, line.strip_suffix('\r').unwrap_or(line))))
    }

    /// The next line that is not blank after removing a comment; section keywords
    /// keep their `# style` hint.
    fn next_content(&mut self) -> Result<Option<(usize, &str)>, InputError> {
        // where the content lies is found first and the line borrowed after
        // (a borrow returned from inside the loop would hold `self` through
        // the next reads)
        let range = loop {
            if !self.read()? {
                return Ok(None);
            }
            if let Some(c) = content(&self.line) {
                let start = c.as_ptr() as usize - self.line.as_ptr() as usize;
                break start..start + c.len();
            }
        };
        Ok(Some((self.number, &self.line[range])))
    }

    /// Calls `entry` with each of the `count` entries of section `name`:
    /// non-blank lines after the keyword.
    fn each_entry(
        &mut self,
        count: usize,
        name: &str,
        mut entry: impl FnMut(usize, &str) -> Result<(), InputError>,
    ) -> Result<(), InputError> {
        let path = self.path;
        for done in 0..count {
            match self.next_content()? {
                Some((no, line)) if is_section(line) => {
                    return Err(InputError::at(
                        path,
                        no,
                        format!("section {name} has {done} lines; the header says {count}"),
                    ))
                }
                Some((no, line)) => entry(no, line)?,
                None => {
                    return Err(InputError::file(
                        path,
                        format!(
                            "the file ends inside section {name} after {done} of {count} lines"
                        ),
                    ))
                }
            }
        }
        Ok(())
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

    /// The atoms a predicate keeps, with their velocities; every line is
    /// still checked (an error in an atom not kept, a velocity of an id not
    /// kept given twice), and the velocities must follow the atoms.
    #[test]
    fn kept_atoms_are_read_and_the_rest_checked() {
        let path = Path::new("t.data");
        let mut seen = Vec::new();
        let d = parse_lines(path, GOOD.as_bytes(), None, &mut |a: &DataAtom| {
            seen.push(a.id);
            a.id != 1
        })
        .unwrap();
        assert_eq!(seen, [3, 1, 2]);
        let kept: Vec<(u64, [f64; 3])> = d.atoms.iter().map(|a| (a.id, a.velocity)).collect();
        assert_eq!(kept, [(3, [-1.0, 1.0, 0.0]), (2, [0.0, 0.0, 0.0])]);
        let mut odd = |a: &DataAtom| a.id % 2 == 1;
        let bad = GOOD.replace("2 1 5 6 0", "2 1 5 x 0");
        let err = parse_lines(path, bad.as_bytes(), None, &mut odd).unwrap_err();
        assert_eq!(err.to_string(), "t.data:19: y is 'x'; expected a number");
        let twice = GOOD.replace("1 0.1 0.2 0", "2 0.1 0.2 0");
        let err = parse_lines(path, twice.as_bytes(), None, &mut odd).unwrap_err();
        assert_eq!(
            err.to_string(),
            "t.data:24: atom id 2 appears twice in the Velocities section (first on line 23)"
        );
        let (head, atoms) = GOOD.split_at(GOOD.find("Atoms").unwrap());
        let (atoms, velocities) = atoms.split_at(atoms.find("Velocities").unwrap());
        let swapped = format!("{head}{velocities}\n{atoms}");
        let err = parse_lines(path, swapped.as_bytes(), None, &mut odd).unwrap_err();
        assert!(err
            .to_string()
            .contains("the Velocities section must follow an Atoms section"));
    }

    /// A second Atoms or Velocities section is an error (a kept atom's
    /// velocity would otherwise land on another atom).
    #[test]
    fn sections_come_once() {
        let path = Path::new("t.data");
        let atoms = &GOOD[GOOD.find("Atoms").unwrap()..GOOD.find("Velocities").unwrap()];
        let again = GOOD.replace("\nVelocities", &format!("\n{atoms}Velocities"));
        let err = parse_data(path, &again).unwrap_err().to_string();
        assert_eq!(err, "t.data:21: a second Atoms section; expected one");
        let velocities = &GOOD[GOOD.find("Velocities").unwrap()..];
        let twice = format!("{GOOD}\n{velocities}");
        let err = parse_data(path, &twice).unwrap_err().to_string();
        assert_eq!(err, "t.data:27: a second Velocities section; expected one");
    }

    /// Windows line ends and a last line without one read as the others;
    /// files on disk, plain and compressed, read as their text.
    #[test]
    fn line_ends_and_files_on_disk() {
        let path = Path::new("t.data");
        let crlf = GOOD.replace('\n', "\r\n");
        assert_eq!(
            parse_data(path, &crlf).unwrap(),
            parse_data(path, GOOD).unwrap()
        );
        let cut = GOOD.trim_end();
        assert_eq!(
            parse_data(path, cut).unwrap(),
            parse_data(path, GOOD).unwrap()
        );
        let dir = tempfile::tempdir().unwrap();
        let plain = dir.path().join("t.data");
        std::fs::write(&plain, GOOD).unwrap();
        let gz = dir.path().join("t.data.gz");
        let mut encoder = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
        std::io::Write::write_all(&mut encoder, GOOD.as_bytes()).unwrap();
        std::fs::write(&gz, encoder.finish().unwrap()).unwrap();
        for file in [&plain, &gz] {
            let d = read_data_where(file, &mut |a: &DataAtom| a.id == 3).unwrap();
            assert_eq!(d.atoms.len(), 1);
            assert_eq!(d.atoms[0].velocity, [-1.0, 1.0, 0.0]);
            assert_eq!(
                read_data_box(file).unwrap(),
                ([0.0, 0.0, -0.5], [10.0, 10.0, 0.5])
            );
        }
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
