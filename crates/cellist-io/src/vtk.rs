//! VTK XML files for ParaView: particles as PolyData (`.vtp`, one point and one
//! vertex cell per particle, with per-particle arrays) and the `.pvd` collection
//! that makes a series of them a time series.
//!
//! Arrays are written as ASCII, each number in the shortest form that reads back
//! to the same `f64`. VTK parses ASCII numbers with C++ streams, which stop at
//! `nan` or `inf`, so an array holding a value that is not finite is written
//! instead as inline binary (`format="binary"`: base64 of a `UInt64` byte count
//! and the little-endian values), which VTK reads bit for bit.

use std::fmt::Write as _;
use std::io::{self, Write};
use std::path::Path;

use crate::output::AtomicFile;

fn invalid_input(message: String) -> io::Error {
    io::Error::new(io::ErrorKind::InvalidInput, message)
}

/// Writes `path` (whole or not at all) as a `.vtp` file: the points `positions`,
/// each also a vertex cell, and point-data arrays given as (name, values,
/// components), `values` holding `components` numbers per point, point by point.
pub fn write_vtp(
    path: &Path,
    positions: &[[f64; 3]],
    arrays: &[(&str, &[f64], usize)],
) -> io::Result<()> {
    check_arrays(positions.len(), arrays)?;
    let mut file = VtpBlocks::create(path, positions.len())?;
    for &(name, values, components) in arrays {
        file.begin_array(name, components, all_finite(values))?;
        file.push(values)?;
        file.end_array()?;
    }
    let flat = positions.as_flattened();
    file.begin_points(all_finite(flat))?;
    file.push(flat)?;
    file.end_array()?;
    file.finish()
}

/// Whether every value is finite (an array of them is written as ASCII).
pub fn all_finite(values: &[f64]) -> bool {
    values.iter().all(|v| v.is_finite())
}

/// Checks that every array has `n` tuples of at least one component.
fn check_arrays(n: usize, arrays: &[(&str, &[f64], usize)]) -> io::Result<()> {
    for &(name, values, components) in arrays {
        if components == 0 || n.checked_mul(components) != Some(values.len()) {
            return Err(invalid_input(format!(
                "VTK array {name}: {} values are not {n} points x {components} components",
                values.len()
            )));
        }
    }
    Ok(())
}

/// A `.vtp` file of `n` points (each also a vertex cell) written an array at
/// a time, each array's values a block of points at a time, so that no
/// array need be held whole (a model spread over ranks hands its particles
/// out in blocks): the point-data arrays, then the points; the bytes of
/// [`write_vtp`] of the same arrays. Whether an array is ASCII or binary
/// (some value not finite) is said when it begins. The file appears whole
/// at [`VtpBlocks::finish`] or not at all.
pub struct VtpBlocks {
    file: AtomicFile,
    n: usize,
    /// The array being written.
    open: Option<OpenArray>,
    /// True once the points have begun.
    points: bool,
}

/// A `DataArray` being written: its name and tuple size, the tuples so far,
/// and for a binary one the base64 stream.
struct OpenArray {
    name: String,
    components: usize,
    tuples: usize,
    binary: Option<Base64Stream>,
}

impl VtpBlocks {
    /// Begins the file, up to its point data.
    pub fn create(path: &Path, n: usize) -> io::Result<Self> {
        let mut file = AtomicFile::create(path)?;
        let w = file.writer();
        writeln!(w, r#"<?xml version="1.0"?>"#)?;
        writeln!(
            w,
            r#"<VTKFile type="PolyData" version="1.0" byte_order="LittleEndian" header_type="UInt64">"#
        )?;
        writeln!(w, "  <PolyData>")?;
        writeln!(
            w,
            r#"    <Piece NumberOfPoints="{n}" NumberOfVerts="{n}" NumberOfLines="0" NumberOfStrips="0" NumberOfPolys="0">"#
        )?;
        writeln!(w, "      <PointData>")?;
        Ok(VtpBlocks {
            file,
            n,
            open: None,
            points: false,
        })
    }

    /// Begins the next point-data array: ASCII, one tuple a line, when
    /// `finite` (every value is), else binary.
    pub fn begin_array(&mut self, name: &str, components: usize, finite: bool) -> io::Result<()> {
        if self.open.is_some() || self.points {
            return Err(invalid_input(format!(
                "VTK array {name} begun inside another or after the points"
            )));
        }
        if components == 0 {
            return Err(invalid_input(format!("VTK array {name}: 0 components")));
        }
        let w = self.file.writer();
        writeln!(
            w,
            r#"        <DataArray type="Float64" Name="{}" NumberOfComponents="{components}" format="{}">"#,
            escape(name),
            if finite { "ascii" } else { "binary" }
        )?;
        let binary = if finite {
            None
        } else {
            write!(w, "          ")?;
            let mut stream = Base64Stream::default();
            let bytes = 8 * (components * self.n) as u64;
            w.write_all(stream.feed(&bytes.to_le_bytes()).as_bytes())?;
            Some(stream)
        };
        self.open = Some(OpenArray {
            name: name.to_string(),
            components,
            tuples: 0,
            binary,
        });
        Ok(())
    }

    /// Ends the point data and begins the points' array (3 components).
    pub fn begin_points(&mut self, finite: bool) -> io::Result<()> {
        if self.open.is_some() || self.points {
            return Err(invalid_input(
                "VTK points begun twice or inside an array".into(),
            ));
        }
        let w = self.file.writer();
        writeln!(w, "      </PointData>")?;
        writeln!(w, "      <Points>")?;
        self.begin_array("Points", 3, finite)?;
        self.points = true;
        Ok(())
    }

    /// Appends whole tuples to the array being written (no more than `n`
    /// in all; an ASCII array's values must be finite).
    pub fn push(&mut self, values: &[f64]) -> io::Result<()> {
        let n = self.n;
        let open = self
            .open
            .as_mut()
            .ok_or_else(|| invalid_input("VTK values outside an array".into()))?;
        let components = open.components;
        let tuples = values.len() / components;
        if !values.len().is_multiple_of(components) || open.tuples + tuples > n {
            return Err(invalid_input(format!(
                "VTK array {}: {} more values are not whole tuples of {components} within {n} points",
                open.name,
                values.len()
            )));
        }
        let w = self.file.writer();
        match &mut open.binary {
            None => {
                if !all_finite(values) {
                    return Err(invalid_input(format!(
                        "VTK array {}: a value that is not finite in an ASCII array",
                        open.name
                    )));
                }
                let mut line = String::new();
                for tuple in values.chunks(components) {
                    line.clear();
                    line.push_str("          ");
                    for (k, v) in tuple.iter().enumerate() {
                        if k > 0 {
                            line.push(' ');
                        }
                        // `{:?}` prints the shortest digits that read back to the same f64
                        let _ = write!(line, "{v:?}");
                    }
                    writeln!(w, "{line}")?;
                }
            }
            Some(stream) => {
                let bytes: Vec<u8> = values.iter().flat_map(|v| v.to_le_bytes()).collect();
                w.write_all(stream.feed(&bytes).as_bytes())?;
            }
        }
        open.tuples += tuples;
        Ok(())
    }

    /// Ends the array being written, once it holds `n` tuples.
    pub fn end_array(&mut self) -> io::Result<()> {
        let open = self
            .open
            .take()
            .ok_or_else(|| invalid_input("VTK array ended but none begun".into()))?;
        if open.tuples != self.n {
            return Err(invalid_input(format!(
                "VTK array {}: {} values are not {} points x {} components",
                open.name,
                open.tuples * open.components,
                self.n,
                open.components
            )));
        }
        let w = self.file.writer();
        if let Some(stream) = open.binary {
            writeln!(w, "{}", stream.finish())?;
        }
        writeln!(w, "        </DataArray>")
    }

    /// Ends the points, writes the vertex cells and commits the file.
    pub fn finish(mut self) -> io::Result<()> {
        if self.open.is_some() || !self.points {
            return Err(invalid_input("VTK file finished before its points".into()));
        }
        let n = self.n;
        let w = self.file.writer();
        writeln!(w, "      </Points>")?;
        writeln!(w, "      <Verts>")?;
        write_int_array(w, "connectivity", 0..n)?;
        write_int_array(w, "offsets", 1..=n)?;
        writeln!(w, "      </Verts>")?;
        writeln!(w, "    </Piece>")?;
        writeln!(w, "  </PolyData>")?;
        writeln!(w, "</VTKFile>")?;
        self.file.commit()
    }
}

/// An `Int64` `DataArray` of `values`, ASCII, sixteen a line.
fn write_int_array<W: Write>(
    w: &mut W,
    name: &str,
    mut values: impl Iterator<Item = usize>,
) -> io::Result<()> {
    writeln!(
        w,
        r#"        <DataArray type="Int64" Name="{name}" format="ascii">"#
    )?;
    let mut line = String::new();
    loop {
        line.clear();
        for (k, v) in values.by_ref().take(16).enumerate() {
            line.push_str(if k == 0 { "          " } else { " " });
            let _ = write!(line, "{v}");
        }
        if line.is_empty() {
            break;
        }
        writeln!(w, "{line}")?;
    }
    writeln!(w, "        </DataArray>")
}

/// Standard base64 (RFC 4648 alphabet, `=` padding) of bytes that arrive a
/// piece at a time: each piece's whole groups of 3 encoded as it comes, the
/// rest kept for the next.
#[derive(Default)]
struct Base64Stream {
    /// Bytes not yet encoded (fewer than 3).
    carry: Vec<u8>,
}

impl Base64Stream {
    const ALPHABET: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";

    /// The encoding of the whole groups of 3 bytes the carry and `bytes` make.
    fn feed(&mut self, bytes: &[u8]) -> String {
        self.carry.extend_from_slice(bytes);
        let whole = self.carry.len() / 3 * 3;
        let mut out = String::with_capacity(whole / 3 * 4);
        for group in self.carry[..whole].chunks(3) {
            Self::encode(group, &mut out);
        }
        self.carry.drain(..whole);
        out
    }

    /// The encoding of the bytes left, padded.
    fn finish(self) -> String {
        let mut out = String::new();
        if !self.carry.is_empty() {
            Self::encode(&self.carry, &mut out);
        }
        out
    }

    /// One group of 1 to 3 bytes as 4 characters.
    fn encode(group: &[u8], out: &mut String) {
        let b = [
            group[0],
            *group.get(1).unwrap_or(&0),
            *group.get(2).unwrap_or(&0),
        ];
        let bits = u32::from(b[0]) << 16 | u32::from(b[1]) << 8 | u32::from(b[2]);
        for k in 0..4 {
            if k <= group.len() {
                out.push(Self::ALPHABET[(bits >> (18 - 6 * k) & 63) as usize] as char);
            } else {
                out.push('=');
            }
        }
    }
}

/// `text` with the characters XML gives meaning to in attribute values escaped.
fn escape(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&apos;"),
            _ => out.push(c),
        }
    }
    out
}

/// Writes `path` (whole, replacing any older version) as the `.pvd` collection of
/// a series: one data set per (time, file name relative to the `.pvd`). Times
/// must be finite.
pub fn write_pvd(path: &Path, entries: &[(f64, String)]) -> io::Result<()> {
    if let Some((time, name)) = entries.iter().find(|(t, _)| !t.is_finite()) {
        return Err(invalid_input(format!(
            "time {time} for {name} is not finite"
        )));
    }
    let mut file = AtomicFile::create(path)?;
    let w = file.writer();
    writeln!(w, r#"<?xml version="1.0"?>"#)?;
    writeln!(
        w,
        r#"<VTKFile type="Collection" version="0.1" byte_order="LittleEndian">"#
    )?;
    writeln!(w, "  <Collection>")?;
    for (time, name) in entries {
        writeln!(
            w,
            r#"    <DataSet timestep="{time:?}" group="" part="0" file="{}"/>"#,
            escape(name)
        )?;
    }
    writeln!(w, "  </Collection>")?;
    writeln!(w, "</VTKFile>")?;
    file.commit()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The `DataArray` elements of `xml`: (opening tag, text inside).
    fn data_arrays(xml: &str) -> Vec<(&str, &str)> {
        xml.split("<DataArray ")
            .skip(1)
            .map(|s| {
                let (tag, rest) = s.split_once('>').unwrap();
                let (body, _) = rest.split_once("</DataArray>").unwrap();
                (tag, body)
            })
            .collect()
    }

    fn attribute<'a>(tag: &'a str, name: &str) -> &'a str {
        let start = tag.find(&format!(" {name}=\"")).unwrap() + name.len() + 3;
        let len = tag[start..].find('"').unwrap();
        &tag[start..start + len]
    }

    fn decode_base64(text: &str) -> Vec<u8> {
        let value = |c: u8| match c {
            b'A'..=b'Z' => c - b'A',
            b'a'..=b'z' => c - b'a' + 26,
            b'0'..=b'9' => c - b'0' + 52,
            b'+' => 62,
            _ => 63,
        };
        let mut out = Vec::new();
        for group in text.trim().as_bytes().chunks(4) {
            let pad = group.iter().filter(|&&c| c == b'=').count();
            let bits = group.iter().fold(0u32, |acc, &c| {
                acc << 6 | u32::from(if c == b'=' { 0 } else { value(c) })
            });
            out.extend_from_slice(&bits.to_be_bytes()[1..4 - pad]);
        }
        out
    }

    /// Base64 of `bytes` fed in pieces of `piece` bytes.
    fn base64_in(bytes: &[u8], piece: usize) -> String {
        let mut stream = Base64Stream::default();
        let mut out: String = bytes.chunks(piece.max(1)).map(|c| stream.feed(c)).collect();
        out += &stream.finish();
        out
    }

    fn base64(bytes: &[u8]) -> String {
        base64_in(bytes, bytes.len())
    }

    #[test]
    fn base64_matches_rfc_4648() {
        assert_eq!(base64(b""), "");
        assert_eq!(base64(b"f"), "Zg==");
        assert_eq!(base64(b"fo"), "Zm8=");
        assert_eq!(base64(b"foo"), "Zm9v");
        assert_eq!(base64(b"foobar"), "Zm9vYmFy");
        assert_eq!(decode_base64("Zm9vYg=="), b"foob");
        let text: Vec<u8> = (0..100u8).collect();
        for piece in [1, 2, 4, 5, 7] {
            assert_eq!(base64_in(&text, piece), base64(&text), "pieces of {piece}");
        }
    }

    /// A file written a block of points at a time is that of all of them
    /// at once, ASCII and binary arrays alike; an array of the wrong length
    /// is an error and leaves no file.
    #[test]
    fn vtp_in_blocks_is_the_whole_files_bytes() {
        let dir = tempfile::tempdir().unwrap();
        let n = 10;
        let positions: Vec<[f64; 3]> = (0..n).map(|k| [k as f64, 0.5, -1.0 / 3.0]).collect();
        let speed: Vec<f64> = (0..n).map(|k| (k as f64).sqrt()).collect();
        let mut odd: Vec<f64> = (0..2 * n).map(|k| k as f64 * 0.25).collect();
        odd[7] = f64::NAN;
        let arrays: [(&str, &[f64], usize); 2] = [("speed", &speed, 1), ("odd", &odd, 2)];
        let whole = dir.path().join("whole.vtp");
        write_vtp(&whole, &positions, &arrays).unwrap();
        let blocks = dir.path().join("blocks.vtp");
        let mut file = VtpBlocks::create(&blocks, n).unwrap();
        for (name, values, components) in arrays {
            file.begin_array(name, components, all_finite(values))
                .unwrap();
            for block in values.chunks(3 * components) {
                file.push(block).unwrap();
            }
            file.end_array().unwrap();
        }
        file.begin_points(true).unwrap();
        for block in positions.chunks(4) {
            file.push(block.as_flattened()).unwrap();
        }
        file.end_array().unwrap();
        file.finish().unwrap();
        assert_eq!(
            std::fs::read(&blocks).unwrap(),
            std::fs::read(&whole).unwrap()
        );
        let short = dir.path().join("short.vtp");
        let mut file = VtpBlocks::create(&short, n).unwrap();
        file.begin_array("speed", 1, true).unwrap();
        file.push(&speed[1..]).unwrap();
        assert!(file.end_array().is_err());
        assert!(file.push(&[f64::NAN]).is_err());
        drop(file);
        assert!(!short.exists());
    }

    #[test]
    fn vtp_arrays_read_back_exactly() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("p.vtp");
        let positions = [
            [0.1, -2.5, 1e-300],
            [3.0, 1.0 / 3.0, -0.0],
            [1e20, 7.0, 2.0],
        ];
        let speed = [0.5, 1.5, 2.5];
        let velocity = [1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, f64::MAX];
        let arrays: [(&str, &[f64], usize); 2] = [("speed", &speed, 1), ("v<&>", &velocity, 3)];
        write_vtp(&path, &positions, &arrays).unwrap();
        let xml = std::fs::read_to_string(&path).unwrap();
        assert!(xml.contains(r#"NumberOfPoints="3""#));
        assert!(xml.contains(r#"NumberOfVerts="3""#));
        let found = data_arrays(&xml);
        assert_eq!(found.len(), 5);
        let expected: [(&str, &[f64], usize); 3] = [
            ("speed", &speed, 1),
            ("v&lt;&amp;&gt;", &velocity, 3),
            ("Points", positions.as_flattened(), 3),
        ];
        for ((tag, body), (name, values, components)) in found.iter().zip(expected) {
            assert_eq!(attribute(tag, "Name"), name);
            assert_eq!(attribute(tag, "format"), "ascii");
            assert_eq!(attribute(tag, "NumberOfComponents"), components.to_string());
            let read: Vec<f64> = body
                .split_whitespace()
                .map(|t| t.parse().unwrap())
                .collect();
            assert_eq!(read.len(), 3 * components);
            let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&read), bits(values));
        }
        let (tag, body) = found[3];
        assert_eq!(attribute(tag, "Name"), "connectivity");
        assert_eq!(body.split_whitespace().collect::<Vec<_>>(), ["0", "1", "2"]);
        assert_eq!(
            found[4].1.split_whitespace().collect::<Vec<_>>(),
            ["1", "2", "3"]
        );
    }

    #[test]
    fn non_finite_values_go_binary() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("p.vtp");
        let values = [1.0, f64::NAN, f64::NEG_INFINITY];
        write_vtp(&path, &[[0.0; 3]; 3], &[("q", &values, 1)]).unwrap();
        let xml = std::fs::read_to_string(&path).unwrap();
        let (tag, body) = data_arrays(&xml)[0];
        assert_eq!(attribute(tag, "format"), "binary");
        let bytes = decode_base64(body);
        assert_eq!(bytes.len(), 8 + 24);
        assert_eq!(u64::from_le_bytes(bytes[..8].try_into().unwrap()), 24);
        for (k, v) in values.iter().enumerate() {
            let at = 8 + 8 * k;
            let read = u64::from_le_bytes(bytes[at..at + 8].try_into().unwrap());
            assert_eq!(read, v.to_bits());
        }
    }

    #[test]
    fn vtp_refuses_wrong_sizes() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("p.vtp");
        let err = write_vtp(&path, &[[0.0; 3]; 2], &[("q", &[1.0; 3], 1)]).unwrap_err();
        assert_eq!(err.kind(), io::ErrorKind::InvalidInput);
        let err = write_vtp(&path, &[[0.0; 3]; 2], &[("q", &[], 0)]).unwrap_err();
        assert_eq!(err.kind(), io::ErrorKind::InvalidInput);
        assert!(!path.exists());
        write_vtp(&path, &[], &[("q", &[], 2)]).unwrap();
        let xml = std::fs::read_to_string(&path).unwrap();
        assert!(xml.contains(r#"NumberOfPoints="0""#));
        assert!(data_arrays(&xml)
            .iter()
            .all(|(_, body)| body.trim().is_empty()));
    }

    #[test]
    fn pvd_lists_the_series() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("run.pvd");
        write_pvd(&path, &[(0.0, "f_0.vtp".into()), (0.1, "a&b.vtp".into())]).unwrap();
        write_pvd(&path, &[(0.0, "f_0.vtp".into()), (0.25, "f_1.vtp".into())]).unwrap();
        let xml = std::fs::read_to_string(&path).unwrap();
        assert!(xml.contains(r#"type="Collection""#));
        let sets: Vec<&str> = xml.lines().filter(|l| l.contains("<DataSet ")).collect();
        assert_eq!(sets.len(), 2);
        assert_eq!(attribute(sets[1], "timestep"), "0.25");
        assert_eq!(attribute(sets[1], "file"), "f_1.vtp");
        let err = write_pvd(&path, &[(f64::NAN, "x".into())]).unwrap_err();
        assert_eq!(err.kind(), io::ErrorKind::InvalidInput);
        let names: Vec<_> = std::fs::read_dir(dir.path()).unwrap().collect();
        assert_eq!(names.len(), 1, "no temporary files left behind");
    }
}
