//! Frames of the `hoomd` schema (version 1.4) written with a [`GsdWriter`]: the
//! chunks `configuration/step`, `configuration/box`, `particles/N`,
//! `particles/position`, ... of cellist's particles.

use std::io;

use super::file::{invalid_input, GsdData};
use super::writer::{check_shape, GsdWriter, PlacedChunk};

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
    let extra: Vec<(&str, u32)> = frame.extra.iter().map(|&(n, _, c)| (n, c)).collect();
    let head = HoomdHead {
        step: frame.step,
        dimensions: frame.dimensions,
        box_lengths: frame.box_lengths,
        lo: frame.lo,
        n: frame.positions.len() as u64,
        velocities: frame.velocities.is_some(),
        masses: frame.masses.is_some(),
        typeid: frame.typeid.is_some(),
        types: frame.types,
        extra: &extra,
    };
    let values: Vec<&[f64]> = frame.extra.iter().map(|&(_, v, _)| v).collect();
    let rows = HoomdRows {
        positions: frame.positions,
        velocities: frame.velocities,
        masses: frame.masses,
        typeid: frame.typeid,
        extra: &values,
    };
    // checked before a byte is written
    check_head(&head)?;
    check_rows(&head, &rows, 0)?;
    let mut blocks = HoomdBlocks::begin(w, head)?;
    blocks.push(&rows)?;
    blocks.end()
}

/// A HOOMD frame but its particles' values: what is known before the first
/// particle arrives ([`HoomdBlocks`]).
#[derive(Clone, Copy, Debug)]
pub struct HoomdHead<'a> {
    /// Time step (`configuration/step`).
    pub step: u64,
    /// 2 or 3 (as [`HoomdFrame::dimensions`]).
    pub dimensions: u8,
    /// Box lengths `Lx, Ly, Lz`.
    pub box_lengths: [f64; 3],
    /// The box's lower corner in the caller's coordinates.
    pub lo: [f64; 3],
    /// The particles in the frame.
    pub n: u64,
    /// Whether the rows carry velocities.
    pub velocities: bool,
    /// Whether the rows carry masses.
    pub masses: bool,
    /// Whether the rows carry type ids.
    pub typeid: bool,
    /// Type names (as [`HoomdFrame::types`]).
    pub types: &'a [String],
    /// The per-particle model quantities: name and columns.
    pub extra: &'a [(&'a str, u32)],
}

/// A block of a frame's particles, in the frame's order: a column for each
/// the head declares, `extra` in the head's order.
#[derive(Clone, Copy, Debug)]
pub struct HoomdRows<'a> {
    /// Positions.
    pub positions: &'a [[f64; 3]],
    /// Velocities.
    pub velocities: Option<&'a [[f64; 3]]>,
    /// Masses.
    pub masses: Option<&'a [f64]>,
    /// Type ids, indices into the head's `types`.
    pub typeid: Option<&'a [u32]>,
    /// The extra quantities' values (rows x columns, row-major).
    pub extra: &'a [&'a [f64]],
}

/// A HOOMD frame written a block of particles at a time: its chunks placed
/// from the head, in the order and at the places [`write_hoomd_frame`] puts
/// them, each block's rows written at their places, so that the file is the
/// one of the whole frame at once and no more than a block is held.
pub struct HoomdBlocks<'w, 'h> {
    writer: &'w mut GsdWriter,
    head: HoomdHead<'h>,
    /// typeid, mass, position, velocity, then the extra quantities.
    places: Vec<Option<PlacedChunk>>,
    /// Rows written so far.
    written: u64,
    buffer: Vec<f32>,
    /// True once the frame is committed.
    ended: bool,
}

impl<'w, 'h> HoomdBlocks<'w, 'h> {
    /// Writes the head's chunks and places the per-particle ones (a failure
    /// drops the frame from the writer).
    pub fn begin(w: &'w mut GsdWriter, head: HoomdHead<'h>) -> io::Result<Self> {
        check_head(&head)?;
        let mut frame = HoomdBlocks {
            writer: w,
            head,
            places: Vec::with_capacity(4 + head.extra.len()),
            written: 0,
            buffer: Vec::new(),
            ended: false,
        };
        frame.write_head()?;
        Ok(frame)
    }

    /// [`HoomdBlocks::begin`]'s chunks and places.
    fn write_head(&mut self) -> io::Result<()> {
        let (w, head) = (&mut *self.writer, &self.head);
        let n = head.n;
        w.write_chunk("configuration/step", 1, 1, GsdData::U64(&[head.step]))?;
        w.write_chunk(
            "configuration/dimensions",
            1,
            1,
            GsdData::U8(&[head.dimensions]),
        )?;
        w.write_chunk("configuration/box", 6, 1, GsdData::F32(&hoomd_box(head)))?;
        w.write_chunk("particles/N", 1, 1, GsdData::U32(&[n as u32]))?;
        if !head.types.is_empty() {
            let (table, width) = type_table(head.types);
            let rows = head.types.len() as u64;
            w.write_chunk("particles/types", rows, width, GsdData::I8(&table))?;
        }
        let place = |w: &mut GsdWriter, on: bool, name: &str, columns, like| {
            on.then(|| w.place_chunk(name, n, columns, &like))
                .transpose()
        };
        let places = &mut self.places;
        places.push(place(
            w,
            head.typeid,
            "particles/typeid",
            1,
            GsdData::U32(&[]),
        )?);
        places.push(place(
            w,
            head.masses,
            "particles/mass",
            1,
            GsdData::F32(&[]),
        )?);
        places.push(place(w, true, "particles/position", 3, GsdData::F32(&[]))?);
        places.push(place(
            w,
            head.velocities,
            "particles/velocity",
            3,
            GsdData::F32(&[]),
        )?);
        for &(name, columns) in head.extra {
            let name = format!("log/particles/{name}");
            places.push(place(w, true, &name, columns, GsdData::F64(&[]))?);
        }
        Ok(())
    }

    /// Writes the next block's rows.
    pub fn push(&mut self, rows: &HoomdRows) -> io::Result<()> {
        let count = check_rows(&self.head, rows, self.written)?;
        let first = self.written;
        let [typeid, mass, position, velocity] = [0, 1, 2, 3].map(|k| self.places[k]);
        if let (Some(place), Some(ids)) = (typeid, rows.typeid) {
            self.writer.write_rows(&place, first, &GsdData::U32(ids))?;
        }
        if let (Some(place), Some(masses)) = (mass, rows.masses) {
            self.buffer.clear();
            self.buffer.extend(masses.iter().map(|&m| m as f32));
            self.writer
                .write_rows(&place, first, &GsdData::F32(&self.buffer))?;
        }
        if let Some(place) = position {
            self.buffer.clear();
            centred_positions(&self.head, rows.positions, &mut self.buffer);
            self.writer
                .write_rows(&place, first, &GsdData::F32(&self.buffer))?;
        }
        if let (Some(place), Some(velocities)) = (velocity, rows.velocities) {
            self.buffer.clear();
            let flat = velocities.as_flattened().iter();
            self.buffer.extend(flat.map(|&v| v as f32));
            self.writer
                .write_rows(&place, first, &GsdData::F32(&self.buffer))?;
        }
        for (place, values) in self.places[4..].iter().zip(rows.extra) {
            let place = place.expect("extra chunks are placed");
            self.writer
                .write_rows(&place, first, &GsdData::F64(values))?;
        }
        self.written += count;
        Ok(())
    }

    /// Commits the frame once every particle's rows are written.
    pub fn end(mut self) -> io::Result<()> {
        if self.written != self.head.n {
            return Err(invalid_input(format!(
                "{} particles written of the frame's {}",
                self.written, self.head.n
            )));
        }
        let committed = self.writer.end_frame();
        self.ended = committed.is_ok();
        committed
    }
}

impl Drop for HoomdBlocks<'_, '_> {
    /// A frame not ended (an error on the way) is dropped from the writer:
    /// the file stays the valid file of the frames before it.
    fn drop(&mut self) {
        if !self.ended {
            self.writer.abandon_frame();
        }
    }
}

/// Checks a head: the dimensions, the particle count, the type names and
/// the extra quantities' columns.
fn check_head(head: &HoomdHead) -> io::Result<()> {
    if !matches!(head.dimensions, 2 | 3) {
        return Err(invalid_input(format!(
            "HOOMD frames have 2 or 3 dimensions, not {}",
            head.dimensions
        )));
    }
    if u32::try_from(head.n).is_err() {
        return Err(invalid_input(format!(
            "{} particles: too many for HOOMD",
            head.n
        )));
    }
    if let Some(bad) = head.types.iter().find(|t| t.contains('\0')) {
        return Err(invalid_input(format!("bad type name {bad:?}")));
    }
    if let Some((name, _)) = head.extra.iter().find(|(_, columns)| *columns == 0) {
        return Err(invalid_input(format!("GSD chunk {name} has 0 columns")));
    }
    Ok(())
}

/// Checks a block of rows against `head` after `written` rows: the columns
/// the head declares, each of the block's length, the type ids within the
/// types, no more rows than the frame has. The block's row count.
fn check_rows(head: &HoomdHead, rows: &HoomdRows, written: u64) -> io::Result<u64> {
    let n = rows.positions.len();
    let sizes = [
        (
            "velocities",
            head.velocities,
            rows.velocities.map(<[_]>::len),
        ),
        ("masses", head.masses, rows.masses.map(<[_]>::len)),
        ("typeid", head.typeid, rows.typeid.map(<[_]>::len)),
    ];
    for (what, declared, len) in sizes {
        if len.is_some() != declared || len.is_some_and(|len| len != n) {
            return Err(invalid_input(format!(
                "{} {what} for {n} particles",
                len.unwrap_or(0)
            )));
        }
    }
    let types = head.types.len().max(1);
    if let Some(bad) = rows
        .typeid
        .into_iter()
        .flatten()
        .find(|&&t| t as usize >= types)
    {
        return Err(invalid_input(format!(
            "type id {bad} but only {types} types"
        )));
    }
    if rows.extra.len() != head.extra.len() {
        return Err(invalid_input(format!(
            "{} extra quantities for the {} of the frame",
            rows.extra.len(),
            head.extra.len()
        )));
    }
    for (&(name, columns), values) in head.extra.iter().zip(rows.extra) {
        check_shape(name, n as u64, columns, values.len())?;
    }
    if written + n as u64 > head.n {
        return Err(invalid_input(format!(
            "{} particles for a frame of {}",
            written + n as u64,
            head.n
        )));
    }
    Ok(n as u64)
}

/// `configuration/box`: `[Lx, Ly, Lz, xy, xz, yz]`, `Lz` 0 in 2D.
fn hoomd_box(head: &HoomdHead) -> [f32; 6] {
    let [lx, ly, lz] = head.box_lengths;
    let lz = if head.dimensions == 2 { 0.0 } else { lz };
    [lx as f32, ly as f32, lz as f32, 0.0, 0.0, 0.0]
}

/// Appends `positions` shifted to the centred box, row-major, as float32.
fn centred_positions(head: &HoomdHead, positions: &[[f64; 3]], out: &mut Vec<f32>) {
    for p in positions {
        for k in 0..3 {
            if k == 2 && head.dimensions == 2 {
                out.push(0.0);
                continue;
            }
            let half = head.box_lengths[k] / 2.0;
            out.push(to_f32_inside(p[k] - head.lo[k] - half, half));
        }
    }
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

    /// A frame written a few particles at a time is the file of the whole
    /// frame at once, byte for byte; a frame dropped half written (a block
    /// of the wrong shape) leaves the file of the frames before it, and the
    /// next frame follows them.
    #[test]
    fn frames_in_blocks_are_the_whole_frames_bytes() {
        let n = 11;
        let positions: Vec<[f64; 3]> = (0..n).map(|k| [k as f64 * 0.7, 1.0, -0.5]).collect();
        let velocities: Vec<[f64; 3]> = (0..n).map(|k| [0.1, k as f64, 2.0]).collect();
        let masses: Vec<f64> = (0..n).map(|k| 1.0 + k as f64).collect();
        let typeid: Vec<u32> = (0..n).map(|k| (k % 2) as u32).collect();
        let stress: Vec<f64> = (0..3 * n).map(|k| k as f64 / 3.0).collect();
        let types = types();
        let extra = [("stress", &stress[..], 3)];
        let frame = HoomdFrame {
            step: 7,
            dimensions: 3,
            box_lengths: [10.0, 4.0, 2.0],
            lo: [0.0, 0.0, -1.0],
            positions: &positions,
            velocities: Some(&velocities),
            masses: Some(&masses),
            typeid: Some(&typeid),
            types: &types,
            extra: &extra,
        };
        let dir = tempfile::tempdir().unwrap();
        let (whole, blocks) = (dir.path().join("whole.gsd"), dir.path().join("blocks.gsd"));
        let mut w = GsdWriter::create(&whole).unwrap();
        write_hoomd_frame(&mut w, &frame).unwrap();
        write_hoomd_frame(&mut w, &HoomdFrame { step: 8, ..frame }).unwrap();
        let head = HoomdHead {
            step: 7,
            dimensions: 3,
            box_lengths: frame.box_lengths,
            lo: frame.lo,
            n: n as u64,
            velocities: true,
            masses: true,
            typeid: true,
            types: &types,
            extra: &[("stress", 3)],
        };
        let rows = |range: std::ops::Range<usize>, stress: &'_ [f64]| {
            (
                positions[range.clone()].to_vec(),
                velocities[range.clone()].to_vec(),
                masses[range.clone()].to_vec(),
                typeid[range].to_vec(),
                stress.to_vec(),
            )
        };
        let mut w = GsdWriter::create(&blocks).unwrap();
        let write = |w: &mut GsdWriter, step: u64, cut: bool| -> io::Result<()> {
            let mut frame = HoomdBlocks::begin(w, HoomdHead { step, ..head })?;
            for start in (0..n).step_by(4) {
                let end = n.min(start + 4);
                let short = if cut && start > 0 { 1 } else { 0 };
                let (p, v, m, t, s) = rows(start..end, &stress[3 * start..3 * end - short]);
                frame.push(&HoomdRows {
                    positions: &p,
                    velocities: Some(&v),
                    masses: Some(&m),
                    typeid: Some(&t),
                    extra: &[&s],
                })?;
            }
            frame.end()
        };
        write(&mut w, 7, false).unwrap();
        assert!(write(&mut w, 9, true).is_err());
        // a frame with a new name, dropped: the name goes with it
        let lone = HoomdHead {
            extra: &[("stress", 3), ("junk", 1)],
            ..head
        };
        let mut dropped = HoomdBlocks::begin(&mut w, lone).unwrap();
        let (p, v, m, t, s) = rows(0..1, &stress[..3]);
        let junk = [0.5];
        dropped
            .push(&HoomdRows {
                positions: &p,
                velocities: Some(&v),
                masses: Some(&m),
                typeid: Some(&t),
                extra: &[&s, &junk],
            })
            .unwrap();
        assert!(dropped.end().is_err());
        assert_eq!(read(&blocks).frames(), 1);
        write(&mut w, 8, false).unwrap();
        drop(w);
        assert_eq!(
            std::fs::read(&blocks).unwrap(),
            std::fs::read(&whole).unwrap()
        );
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
