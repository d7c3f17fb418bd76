//! Frames of the `hoomd` schema (version 1.4) written with a [`GsdWriter`]: the
//! chunks `configuration/step`, `configuration/box`, `particles/N`,
//! `particles/position`, ... of cellist's particles.

use std::io;

use super::file::{invalid_input, GsdData};
use super::writer::{check_shape, GsdWriter};

/// One frame of the `hoomd` schema (version 1.4): an orthorhombic box and
/// per-particle data. Positions are given in the caller's box `[lo, lo + L)`;
/// HOOMD boxes are centred at the origin, so they are written shifted by
/// `-(lo + L/2)`.
#[derive(Clone, Copy, Debug)]
pub struct HoomdFrame<'a> {
    /// Time step (`configuration/step`).
    pub step: u64,
    /// 2 or 3. In 2D the box's `Lz` and every position's z are written as 0, as
    /// HOOMD expects of 2D boxes.
    pub dimensions: u8,
    /// Box lengths `Lx, Ly, Lz` (tilts are 0).
    pub box_lengths: [f64; 3],
    /// The box's lower corner in the caller's coordinates.
    pub lo: [f64; 3],
    /// Positions, in `[lo, lo + L)`.
    pub positions: &'a [[f64; 3]],
    /// Velocities, if known (`particles/velocity`).
    pub velocities: Option<&'a [[f64; 3]]>,
    /// Masses, if not all 1 (`particles/mass`).
    pub masses: Option<&'a [f64]>,
    /// Type of each particle as an index into `types`, if not all 0.
    pub typeid: Option<&'a [u32]>,
    /// Type names, e.g. `["A"]` (`particles/types`); empty means HOOMD's default
    /// `["A"]`.
    pub types: &'a [String],
    /// Per-particle model quantities: name, values (N x columns, row-major) and
    /// columns, written as float64 chunks `log/particles/<name>`.
    pub extra: &'a [(&'a str, &'a [f64], u32)],
}

/// Writes `frame`'s chunks (every chunk it has, in every frame) and commits the
/// frame. Floating-point particle data are stored as float32, as schema 1.4 has
/// them; the extra quantities as float64.
pub fn write_hoomd_frame(w: &mut GsdWriter, frame: &HoomdFrame) -> io::Result<()> {
    check_frame(frame)?;
    let n = frame.positions.len() as u64;
    let n32 = n as u32;
    w.write_chunk("configuration/step", 1, 1, GsdData::U64(&[frame.step]))?;
    w.write_chunk(
        "configuration/dimensions",
        1,
        1,
        GsdData::U8(&[frame.dimensions]),
    )?;
    w.write_chunk("configuration/box", 6, 1, GsdData::F32(&hoomd_box(frame)))?;
    w.write_chunk("particles/N", 1, 1, GsdData::U32(&[n32]))?;
    if !frame.types.is_empty() {
        let (table, width) = type_table(frame.types);
        let rows = frame.types.len() as u64;
        w.write_chunk("particles/types", rows, width, GsdData::I8(&table))?;
    }
    if let Some(typeid) = frame.typeid {
        w.write_chunk("particles/typeid", n, 1, GsdData::U32(typeid))?;
    }
    if let Some(masses) = frame.masses {
        let masses: Vec<f32> = masses.iter().map(|&m| m as f32).collect();
        w.write_chunk("particles/mass", n, 1, GsdData::F32(&masses))?;
    }
    let positions = centred_positions(frame);
    w.write_chunk("particles/position", n, 3, GsdData::F32(&positions))?;
    if let Some(velocities) = frame.velocities {
        let velocities: Vec<f32> = velocities
            .as_flattened()
            .iter()
            .map(|&v| v as f32)
            .collect();
        w.write_chunk("particles/velocity", n, 3, GsdData::F32(&velocities))?;
    }
    for &(name, values, columns) in frame.extra {
        let name = format!("log/particles/{name}");
        w.write_chunk(&name, n, columns, GsdData::F64(values))?;
    }
    w.end_frame()
}

/// Checks a frame's sizes and ids.
fn check_frame(frame: &HoomdFrame) -> io::Result<()> {
    let n = frame.positions.len();
    if !matches!(frame.dimensions, 2 | 3) {
        return Err(invalid_input(format!(
            "HOOMD frames have 2 or 3 dimensions, not {}",
            frame.dimensions
        )));
    }
    if u32::try_from(n).is_err() {
        return Err(invalid_input(format!("{n} particles: too many for HOOMD")));
    }
    let sizes = [
        ("velocities", frame.velocities.map(<[_]>::len)),
        ("masses", frame.masses.map(<[_]>::len)),
        ("typeid", frame.typeid.map(<[_]>::len)),
    ];
    for (what, len) in sizes {
        if len.is_some_and(|len| len != n) {
            return Err(invalid_input(format!(
                "{} {what} for {n} particles",
                len.unwrap_or(0)
            )));
        }
    }
    let types = frame.types.len().max(1);
    if let Some(bad) = frame
        .typeid
        .into_iter()
        .flatten()
        .find(|&&t| t as usize >= types)
    {
        return Err(invalid_input(format!(
            "type id {bad} but only {types} types"
        )));
    }
    if let Some(bad) = frame.types.iter().find(|t| t.contains('\0')) {
        return Err(invalid_input(format!("bad type name {bad:?}")));
    }
    for &(name, values, columns) in frame.extra {
        check_shape(name, n as u64, columns, values.len())?;
    }
    Ok(())
}

/// `configuration/box`: `[Lx, Ly, Lz, xy, xz, yz]`, `Lz` 0 in 2D.
fn hoomd_box(frame: &HoomdFrame) -> [f32; 6] {
    let [lx, ly, lz] = frame.box_lengths;
    let lz = if frame.dimensions == 2 { 0.0 } else { lz };
    [lx as f32, ly as f32, lz as f32, 0.0, 0.0, 0.0]
}

/// Positions shifted to the centred box, row-major, as float32.
fn centred_positions(frame: &HoomdFrame) -> Vec<f32> {
    let mut out = Vec::with_capacity(3 * frame.positions.len());
    for p in frame.positions {
        for k in 0..3 {
            if k == 2 && frame.dimensions == 2 {
                out.push(0.0);
                continue;
            }
            let half = frame.box_lengths[k] / 2.0;
            out.push(to_f32_inside(p[k] - frame.lo[k] - half, half));
        }
    }
    out
}

/// `c` as float32, except that a `c` inside the box that rounds up onto its upper
/// face `half` becomes the float32 just below the face: HOOMD boxes are half-open,
/// `[-L/2, L/2)`. Coordinates outside the box are left as they are.
fn to_f32_inside(c: f64, half: f64) -> f32 {
    let rounded = c as f32;
    let face = half as f32;
    if c < half && rounded >= face && face > 0.0 && face.is_finite() {
        f32::from_bits(face.to_bits() - 1)
    } else {
        rounded
    }
}

/// Type names as the schema stores them: one row per name, each 0-padded to the
/// longest name plus a 0 terminator.
fn type_table(types: &[String]) -> (Vec<i8>, u32) {
    let width = types.iter().map(String::len).max().unwrap_or(0) + 1;
    let mut table = vec![0i8; width * types.len()];
    for (row, name) in types.iter().enumerate() {
        for (k, &b) in name.as_bytes().iter().enumerate() {
            table[row * width + k] = b as i8;
        }
    }
    (table, width as u32)
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use super::*;
    use crate::gsd::test_reader::{read, Parsed};

    fn types() -> Vec<String> {
        vec!["A".to_string(), "Big".to_string()]
    }

    /// A frame of two particles in the box [1, 11) x [0, 4) x [-1, 1).
    fn write_frame(w: &mut GsdWriter, step: u64, shift: f64) {
        write_frame_with(w, step, shift, None);
    }

    /// [`write_frame`], with one more per-particle quantity if `more` names one.
    fn write_frame_with(w: &mut GsdWriter, step: u64, shift: f64, more: Option<&str>) {
        let positions = [[1.0 + shift, 0.5, -1.0], [10.5, 3.0 + shift, 0.25]];
        let velocities = [[1.0, 2.0, 3.0], [-1.0, -2.0, -3.0 + shift]];
        let energy = [0.1 + shift, 0.2];
        let stress = [1.0, 2.0, 3.0, 4.0, 5.0, 6.0 + shift];
        let mut extra: Vec<(&str, &[f64], u32)> =
            vec![("energy", &energy, 1), ("stress", &stress, 3)];
        if let Some(name) = more {
            extra.push((name, &energy, 1));
        }
        let types = types();
        let frame = HoomdFrame {
            step,
            dimensions: 3,
            box_lengths: [10.0, 4.0, 2.0],
            lo: [1.0, 0.0, -1.0],
            positions: &positions,
            velocities: Some(&velocities),
            masses: Some(&[1.0, 2.5]),
            typeid: Some(&[0, 1]),
            types: &types,
            extra: &extra,
        };
        write_hoomd_frame(w, &frame).unwrap();
    }

    fn check_frame_values(r: &Parsed, frame: u64, step: u64, shift: f64) {
        assert_eq!(r.u64s(frame, "configuration/step"), [step]);
        assert_eq!(
            r.f32s(frame, "configuration/box"),
            [10.0, 4.0, 2.0, 0.0, 0.0, 0.0]
        );
        let x = (1.0 + shift - 1.0 - 5.0) as f32;
        let y = (3.0 + shift - 2.0) as f32;
        assert_eq!(
            r.f32s(frame, "particles/position"),
            [x, -1.5, -1.0, 4.5, y, 0.25]
        );
        assert_eq!(r.f32s(frame, "particles/mass"), [1.0, 2.5]);
        assert_eq!(r.f64s(frame, "log/particles/energy"), [0.1 + shift, 0.2]);
        let (e, _) = r.chunk(frame, "log/particles/stress").unwrap();
        assert_eq!((e.rows, e.columns, e.kind), (2, 3, 10));
        let (e, types) = r.chunk(frame, "particles/types").unwrap();
        assert_eq!((e.rows, e.columns, e.kind), (2, 4, 5));
        assert_eq!(types, b"A\0\0\0Big\0");
        let (e, n) = r.chunk(frame, "particles/N").unwrap();
        assert_eq!((e.kind, n), (3, &2u32.to_le_bytes()[..]));
    }

    #[test]
    fn writes_frames_a_reader_finds() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("t.gsd");
        let mut w = GsdWriter::create(&path).unwrap();
        assert_eq!(read(&path).frames(), 0);
        write_frame(&mut w, 100, 0.0);
        write_frame(&mut w, 200, 0.5);
        assert_eq!(w.frames(), 2);
        assert_eq!(w.len(), std::fs::metadata(&path).unwrap().len());
        let r = read(&path);
        assert_eq!(r.header.gsd_version, 0x0002_0000);
        assert_eq!(r.header.schema_version, 0x0001_0004);
        assert_eq!(&r.header.schema[..6], b"hoomd\0");
        assert!(r.header.application.starts_with(b"cellist "));
        assert_eq!(r.frames(), 2);
        check_frame_values(&r, 0, 100, 0.0);
        check_frame_values(&r, 1, 200, 0.5);
    }

    #[test]
    fn resume_drops_later_frames() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("t.gsd");
        let mut w = GsdWriter::create(&path).unwrap();
        write_frame(&mut w, 100, 0.0);
        let length = w.len();
        write_frame(&mut w, 200, 0.5);
        drop(w);
        let mut w = GsdWriter::resume(&path, length).unwrap();
        assert_eq!(w.frames(), 1);
        assert_eq!(read(&path).frames(), 1);
        write_frame(&mut w, 150, 0.25);
        let r = read(&path);
        assert_eq!(r.frames(), 2);
        check_frame_values(&r, 0, 100, 0.0);
        check_frame_values(&r, 1, 150, 0.25);
    }

    #[test]
    fn positions_stay_below_the_upper_face() {
        let just_below = 0.5 - 1e-12;
        assert_eq!(just_below as f32, 0.5);
        let face = f32::from_bits(0.5f32.to_bits() - 1);
        assert_eq!(to_f32_inside(just_below, 0.5), face);
        assert_eq!(to_f32_inside(-0.5, 0.5), -0.5);
        assert_eq!(to_f32_inside(0.25, 0.5), 0.25);
        // outside the box: left alone
        assert_eq!(to_f32_inside(0.5, 0.5), 0.5);
        assert_eq!(to_f32_inside(3.75, 0.5), 3.75);
    }

    /// Writes a file for checking with the `gsd` Python package:
    /// `CELLIST_GSD_OUT=/tmp/x.gsd cargo test -p cellist-io --lib gsd -- --ignored`.
    /// Frames of `write_frame`: steps 100, 200 (shifts 0, 0.5); then 20 frames with
    /// one more, long-named quantity that move the index and the name list; then a
    /// resume at the length after step 200, and steps 300, 400, ..., 2200 (shift
    /// 0.25 k for step 300 + 100 k): 22 frames.
    #[test]
    #[ignore]
    fn file_for_the_python_reader() {
        let Some(path) = std::env::var_os("CELLIST_GSD_OUT") else {
            return;
        };
        let path = Path::new(&path);
        let mut w = GsdWriter::create(path).unwrap();
        write_frame(&mut w, 100, 0.0);
        write_frame(&mut w, 200, 0.5);
        let length = w.len();
        let long = "x".repeat(1100);
        for k in 0..20 {
            write_frame_with(&mut w, 1000 + k, 0.0, Some(&long));
        }
        drop(w);
        let mut w = GsdWriter::resume(path, length).unwrap();
        for k in 0..20 {
            write_frame(&mut w, 300 + 100 * k, 0.25 * k as f64);
        }
        assert_eq!(w.frames(), 22);
        let r = read(path);
        // 2 x 11 + 20 x 12 entries grew the index to 512, which the resume kept
        assert_eq!(r.header.index_allocated, 512);
        assert!(!r.names.contains(&long));
    }
}
