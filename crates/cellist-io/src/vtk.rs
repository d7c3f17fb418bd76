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
    let mut file = AtomicFile::create(path)?;
    write_polydata(file.writer(), positions, arrays)?;
    file.commit()
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

fn write_polydata<W: Write>(
    w: &mut W,
    positions: &[[f64; 3]],
    arrays: &[(&str, &[f64], usize)],
) -> io::Result<()> {
    let n = positions.len();
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
    for &(name, values, components) in arrays {
        write_float_array(w, name, values, components)?;
    }
    writeln!(w, "      </PointData>")?;
    writeln!(w, "      <Points>")?;
    write_float_array(w, "Points", positions.as_flattened(), 3)?;
    writeln!(w, "      </Points>")?;
    writeln!(w, "      <Verts>")?;
    write_int_array(w, "connectivity", 0..n)?;
    write_int_array(w, "offsets", 1..=n)?;
    writeln!(w, "      </Verts>")?;
    writeln!(w, "    </Piece>")?;
    writeln!(w, "  </PolyData>")?;
    writeln!(w, "</VTKFile>")
}

/// A `Float64` `DataArray`: ASCII, one tuple a line, or binary when a value is
/// not finite.
fn write_float_array<W: Write>(
    w: &mut W,
    name: &str,
    values: &[f64],
    components: usize,
) -> io::Result<()> {
    let ascii = values.iter().all(|v| v.is_finite());
    writeln!(
        w,
        r#"        <DataArray type="Float64" Name="{}" NumberOfComponents="{components}" format="{}">"#,
        escape(name),
        if ascii { "ascii" } else { "binary" }
    )?;
    if ascii {
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
    } else {
        writeln!(w, "          {}", binary_payload(values))?;
    }
    writeln!(w, "        </DataArray>")
}

/// An `Int64` `DataArray` of `values`, ASCII, sixteen a line.
fn write_int_array<W: Write>(
    w: &mut W,
    name: &str,
    values: impl Iterator<Item = usize>,
) -> io::Result<()> {
    writeln!(
        w,
        r#"        <DataArray type="Int64" Name="{name}" format="ascii">"#
    )?;
    let values: Vec<usize> = values.collect();
    for row in values.chunks(16) {
        let row: Vec<String> = row.iter().map(usize::to_string).collect();
        writeln!(w, "          {}", row.join(" "))?;
    }
    writeln!(w, "        </DataArray>")
}

/// VTK's inline binary form of `values` with a `UInt64` header: base64 of the
/// byte count followed by the little-endian values, encoded as one stream.
fn binary_payload(values: &[f64]) -> String {
    let mut bytes = Vec::with_capacity(8 + 8 * values.len());
    bytes.extend_from_slice(&(8 * values.len() as u64).to_le_bytes());
    for v in values {
        bytes.extend_from_slice(&v.to_le_bytes());
    }
    base64(&bytes)
}

/// Standard base64 (RFC 4648 alphabet, `=` padding).
fn base64(bytes: &[u8]) -> String {
    const ALPHABET: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::with_capacity(bytes.len().div_ceil(3) * 4);
    for group in bytes.chunks(3) {
        let b = [
            group[0],
            *group.get(1).unwrap_or(&0),
            *group.get(2).unwrap_or(&0),
        ];
        let bits = u32::from(b[0]) << 16 | u32::from(b[1]) << 8 | u32::from(b[2]);
        for k in 0..4 {
            if k <= group.len() {
                out.push(ALPHABET[(bits >> (18 - 6 * k) & 63) as usize] as char);
            } else {
                out.push('=');
            }
        }
    }
    out
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

    #[test]
    fn base64_matches_rfc_4648() {
        assert_eq!(base64(b""), "");
        assert_eq!(base64(b"f"), "Zg==");
        assert_eq!(base64(b"fo"), "Zm8=");
        assert_eq!(base64(b"foo"), "Zm9v");
        assert_eq!(base64(b"foobar"), "Zm9vYmFy");
        assert_eq!(decode_base64("Zm9vYg=="), b"foob");
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
