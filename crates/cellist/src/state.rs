//! A model's complete state as named sections of little-endian numbers, for
//! checkpoints: floats by their bit patterns, so that a restored state is the saved
//! one bit for bit. The file around the sections (magic, version, checksums) is
//! `cellist-io`'s; this module only packs and unpacks numbers. Reading never
//! panics on a section of the wrong size or a missing one; a [`StateBuilder`]
//! given other bytes than its [`Layout`] declares is a bug of its caller and
//! panics.

use std::fmt;

/// One named section: `data` holds `len` numbers of 8 (or 4) little-endian bytes.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Section {
    /// Name, unique within a state (`"positions"`).
    pub name: String,
    /// The bytes.
    pub data: Vec<u8>,
}

/// A saved state: sections in the order they were written.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct State {
    /// The sections.
    pub sections: Vec<Section>,
}

/// Why a state cannot be restored: a section is missing or has the wrong size.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct StateError(pub String);

impl fmt::Display for StateError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for StateError {}

/// The sections a state will hold, in order: each one's name and byte
/// count, known before any of its bytes (a checkpoint file places each
/// section from it and fills the sections a block of particles at a time).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Layout {
    /// `(name, bytes)` per section.
    pub sections: Vec<(String, u64)>,
}

impl Layout {
    /// Adds a section of `values` numbers of 8 bytes; returns its index.
    pub fn add(&mut self, name: &str, values: usize) -> usize {
        self.sections.push((name.to_string(), 8 * values as u64));
        self.sections.len() - 1
    }

    /// The layout of `state` as it is.
    pub fn of(state: &State) -> Self {
        Layout {
            sections: state
                .sections
                .iter()
                .map(|s| (s.name.clone(), s.data.len() as u64))
                .collect(),
        }
    }
}

/// Where the sections of a [`Layout`] go as they are made: each section's
/// bytes appended in order, a block at a time, the sections in any
/// interleaving (a state in memory, [`StateBuilder`], or a checkpoint file).
pub trait SectionSink {
    /// Appends `bytes` to section `section` of the layout.
    fn append(&mut self, section: usize, bytes: &[u8]);

    /// True once an append has failed (a file that could not be written):
    /// what is appended after is dropped, and a writer may stop early.
    fn failed(&self) -> bool {
        false
    }
}

/// The bytes [`SectionWriter`] encodes before it hands them on.
const WRITER_CHUNK: usize = 1 << 16;

/// Encodes numbers into a [`SectionSink`] through a buffer of at most
/// 64 KiB, kept from block to block (a section of many
/// numbers arrives in several appends, never copied whole).
#[derive(Debug, Default)]
pub struct SectionWriter {
    buffer: Vec<u8>,
}

impl SectionWriter {
    /// Appends unsigned integers to section `section` of `sink`.
    pub fn u64s(
        &mut self,
        sink: &mut dyn SectionSink,
        section: usize,
        values: impl IntoIterator<Item = u64>,
    ) {
        self.buffer.clear();
        for v in values {
            self.buffer.extend_from_slice(&v.to_le_bytes());
            if self.buffer.len() == WRITER_CHUNK {
                sink.append(section, &self.buffer);
                self.buffer.clear();
            }
        }
        if !self.buffer.is_empty() {
            sink.append(section, &self.buffer);
        }
    }

    /// Appends floats by their bit patterns.
    pub fn f64s(
        &mut self,
        sink: &mut dyn SectionSink,
        section: usize,
        values: impl IntoIterator<Item = f64>,
    ) {
        self.u64s(sink, section, values.into_iter().map(f64::to_bits));
    }

    /// Appends vectors component by component.
    pub fn vectors<const D: usize>(
        &mut self,
        sink: &mut dyn SectionSink,
        section: usize,
        values: &[[f64; D]],
    ) {
        self.f64s(sink, section, values.as_flattened().iter().copied());
    }
}

/// A state in memory filled through [`SectionSink`]: the sections of its
/// layout, each with room for its bytes.
#[derive(Debug)]
pub struct StateBuilder {
    layout: Layout,
    data: Vec<Vec<u8>>,
}

impl StateBuilder {
    /// Empty sections of `layout`.
    pub fn new(layout: Layout) -> Self {
        let data = layout
            .sections
            .iter()
            .map(|(_, bytes)| Vec::with_capacity(*bytes as usize))
            .collect();
        StateBuilder { layout, data }
    }

    /// Adds the sections to `state`; each must hold the bytes its layout
    /// declared.
    pub fn finish(self, state: &mut State) {
        for ((name, bytes), data) in self.layout.sections.into_iter().zip(self.data) {
            assert_eq!(
                data.len() as u64,
                bytes,
                "section {name} got {} bytes of {bytes}",
                data.len()
            );
            state.push(&name, data);
        }
    }
}

impl SectionSink for StateBuilder {
    fn append(&mut self, section: usize, bytes: &[u8]) {
        self.data[section].extend_from_slice(bytes);
    }
}

impl State {
    fn section(&self, name: &str) -> Option<&Section> {
        self.sections.iter().find(|s| s.name == name)
    }

    fn push(&mut self, name: &str, data: Vec<u8>) {
        debug_assert!(
            self.sections.iter().all(|s| s.name != name),
            "section {name} written twice"
        );
        self.sections.push(Section {
            name: name.to_string(),
            data,
        });
    }

    /// Adds `values` as their IEEE-754 bit patterns.
    pub fn put_f64s(&mut self, name: &str, values: impl IntoIterator<Item = f64>) {
        self.put_u64s(name, values.into_iter().map(f64::to_bits));
    }

    /// Adds fixed-size vectors (`[x, y, z]` per particle) component by component.
    pub fn put_vectors<const D: usize>(&mut self, name: &str, values: &[[f64; D]]) {
        self.put_f64s(name, values.as_flattened().iter().copied());
    }

    /// Adds unsigned integers (their bytes allocated once when the iterator
    /// knows its length, not grown by doubling).
    pub fn put_u64s(&mut self, name: &str, values: impl IntoIterator<Item = u64>) {
        let values = values.into_iter();
        let mut data = Vec::with_capacity(8 * values.size_hint().0);
        for v in values {
            data.extend_from_slice(&v.to_le_bytes());
        }
        self.push(name, data);
    }
}

/// Where a saved state's sections are read from, a few numbers at a time:
/// a [`State`] in memory, or a checkpoint file read in place (a rank
/// restoring a run spread over ranks reads every block but keeps only
/// its own particles, so no rank holds the whole state). The numbers are
/// read through the methods of `dyn SectionSource`.
pub trait SectionSource {
    /// The byte count of section `name`, or `None` if the state has none.
    fn section_len(&self, name: &str) -> Option<u64>;

    /// Fills `bytes` with section `name`'s bytes from its byte `at` on
    /// (within the length [`SectionSource::section_len`] gives).
    fn read_bytes(&self, name: &str, at: u64, bytes: &mut [u8]) -> Result<(), StateError>;
}

impl SectionSource for State {
    fn section_len(&self, name: &str) -> Option<u64> {
        self.section(name).map(|s| s.data.len() as u64)
    }

    fn read_bytes(&self, name: &str, at: u64, bytes: &mut [u8]) -> Result<(), StateError> {
        let data = self
            .section(name)
            .map(|s| &s.data[..])
            .ok_or_else(|| no_section(name))?;
        let range = at as usize..at as usize + bytes.len();
        let part = data.get(range.clone()).ok_or_else(|| {
            StateError(format!(
                "section '{name}' has {} bytes, not the bytes {range:?}",
                data.len()
            ))
        })?;
        bytes.copy_from_slice(part);
        Ok(())
    }
}

fn no_section(name: &str) -> StateError {
    StateError(format!("the state has no section '{name}'"))
}

/// The numbers [`SectionSource::read_bytes`] hands over at once: 64 KiB.
const READ_CHUNK: usize = 1 << 13;

impl dyn SectionSource + '_ {
    /// True when the state holds a section `name`.
    pub fn has(&self, name: &str) -> bool {
        self.section_len(name).is_some()
    }

    /// The count of 8-byte numbers section `name` holds (an error if there
    /// is no such section, or its bytes are not a whole number of them).
    pub fn count(&self, name: &str) -> Result<usize, StateError> {
        let bytes = self.section_len(name).ok_or_else(|| no_section(name))?;
        if bytes % 8 != 0 {
            return Err(StateError(format!(
                "section '{name}' has {bytes} bytes, not a whole number of 8-byte values"
            )));
        }
        Ok((bytes / 8) as usize)
    }

    /// Section `name`'s numbers `start..start + len` as unsigned integers,
    /// each handed to `each` in order, read 64 KiB at a time.
    pub fn each_u64(
        &self,
        name: &str,
        start: usize,
        len: usize,
        mut each: impl FnMut(u64),
    ) -> Result<(), StateError> {
        let mut bytes = vec![0u8; 8 * READ_CHUNK.min(len)];
        let mut at = start;
        while at < start + len {
            let take = READ_CHUNK.min(start + len - at);
            let chunk = &mut bytes[..8 * take];
            self.read_bytes(name, 8 * at as u64, chunk)?;
            for c in chunk.chunks_exact(8) {
                each(u64::from_le_bytes(c.try_into().expect("8 bytes")));
            }
            at += take;
        }
        Ok(())
    }

    /// Section `name`'s numbers `start..start + len` as unsigned integers.
    pub fn u64s_at(&self, name: &str, start: usize, len: usize) -> Result<Vec<u64>, StateError> {
        let mut values = Vec::with_capacity(len);
        self.each_u64(name, start, len, |v| values.push(v))?;
        Ok(values)
    }

    /// Section `name`'s numbers `start..start + len` as floats (from their
    /// bit patterns).
    pub fn f64s_at(&self, name: &str, start: usize, len: usize) -> Result<Vec<f64>, StateError> {
        let mut values = Vec::with_capacity(len);
        self.each_u64(name, start, len, |v| values.push(f64::from_bits(v)))?;
        Ok(values)
    }

    /// Vectors `start..start + len` of section `name`, `D` floats each.
    pub fn vectors_at<const D: usize>(
        &self,
        name: &str,
        start: usize,
        len: usize,
    ) -> Result<Vec<[f64; D]>, StateError> {
        let mut values = Vec::with_capacity(len);
        let mut vector = [0.0; D];
        let mut a = 0;
        self.each_u64(name, D * start, D * len, |v| {
            vector[a] = f64::from_bits(v);
            a += 1;
            if a == D {
                values.push(vector);
                a = 0;
            }
        })?;
        Ok(values)
    }

    /// Checks that section `name` holds exactly `n` numbers.
    pub fn expect_count(&self, name: &str, n: usize) -> Result<(), StateError> {
        expect_len(name, self.count(name)?, n)
    }

    /// Section `name` as floats.
    pub fn f64s(&self, name: &str) -> Result<Vec<f64>, StateError> {
        self.f64s_at(name, 0, self.count(name)?)
    }

    /// Section `name` as unsigned integers.
    pub fn u64s(&self, name: &str) -> Result<Vec<u64>, StateError> {
        self.u64s_at(name, 0, self.count(name)?)
    }

    /// Section `name` as exactly `n` floats.
    pub fn f64s_of(&self, name: &str, n: usize) -> Result<Vec<f64>, StateError> {
        self.expect_count(name, n)?;
        self.f64s_at(name, 0, n)
    }

    /// Section `name` as exactly `n` unsigned integers.
    pub fn u64s_of(&self, name: &str, n: usize) -> Result<Vec<u64>, StateError> {
        self.expect_count(name, n)?;
        self.u64s_at(name, 0, n)
    }

    /// Section `name` as exactly `n` vectors of `D` components.
    pub fn vectors<const D: usize>(
        &self,
        name: &str,
        n: usize,
    ) -> Result<Vec<[f64; D]>, StateError> {
        self.expect_count(name, n * D)?;
        self.vectors_at(name, 0, n)
    }

    /// The single float of section `name`.
    pub fn f64(&self, name: &str) -> Result<f64, StateError> {
        Ok(self.f64s_of(name, 1)?[0])
    }

    /// The single integer of section `name`.
    pub fn u64(&self, name: &str) -> Result<u64, StateError> {
        Ok(self.u64s_of(name, 1)?[0])
    }
}

fn expect_len(name: &str, got: usize, want: usize) -> Result<(), StateError> {
    if got == want {
        Ok(())
    } else {
        Err(StateError(format!(
            "section '{name}' holds {got} numbers, expected {want}"
        )))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_round_trip_bit_for_bit() {
        let mut s = State::default();
        let odd = [0.1, -0.0, f64::MIN_POSITIVE / 4.0, f64::INFINITY, f64::NAN];
        s.put_f64s("odd", odd);
        s.put_vectors("x", &[[1.0, 2.0], [3.0, 4.5]]);
        s.put_u64s("ids", [7, u64::MAX]);
        let s: &dyn SectionSource = &s;
        let back = s.f64s("odd").unwrap();
        assert_eq!(
            back.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
            odd.iter().map(|v| v.to_bits()).collect::<Vec<_>>()
        );
        assert_eq!(s.vectors::<2>("x", 2).unwrap(), [[1.0, 2.0], [3.0, 4.5]]);
        assert_eq!(s.u64s_of("ids", 2).unwrap(), [7, u64::MAX]);
    }

    /// Sections written through a sink in blocks (each larger than the
    /// writer's chunk, in any interleaving) hold the bytes of `put_*` with
    /// all the numbers at once.
    #[test]
    fn sections_written_in_blocks_are_put_whole() {
        let n = 20_000;
        let x: Vec<f64> = (0..n).map(|k| (k as f64).sqrt()).collect();
        let v: Vec<[f64; 3]> = (0..n)
            .map(|k| [k as f64, -0.5, 1.0 / (k + 1) as f64])
            .collect();
        let mut whole = State::default();
        whole.put_f64s("x", x.iter().copied());
        whole.put_vectors("v", &v);
        whole.put_u64s("one", [7]);
        let mut layout = Layout::default();
        let sections = [("x", n), ("v", 3 * n), ("one", 1)].map(|(name, k)| layout.add(name, k));
        assert_eq!(layout, Layout::of(&whole));
        let mut builder = StateBuilder::new(layout);
        let mut writer = SectionWriter::default();
        for start in (0..n).step_by(9000) {
            let end = n.min(start + 9000);
            writer.vectors(&mut builder, sections[1], &v[start..end]);
            writer.f64s(&mut builder, sections[0], x[start..end].iter().copied());
        }
        writer.u64s(&mut builder, sections[2], [7]);
        let mut blocks = State::default();
        builder.finish(&mut blocks);
        assert_eq!(blocks, whole);
    }

    /// Numbers read from any start, across the 64 KiB chunks of a read,
    /// are the section's numbers there.
    #[test]
    fn numbers_read_from_any_start_are_the_sections() {
        let n = 3 * READ_CHUNK + 5;
        let v: Vec<[f64; 3]> = (0..n)
            .map(|k| [k as f64, -(k as f64).sqrt(), 1.0 / (k + 1) as f64])
            .collect();
        let mut s = State::default();
        s.put_vectors("v", &v);
        s.put_u64s("ids", (0..n as u64).map(|k| k * k));
        let read: &dyn SectionSource = &s;
        for (start, len) in [
            (0, n),
            (1, READ_CHUNK),
            (READ_CHUNK - 1, 2 * READ_CHUNK + 3),
            (n, 0),
        ] {
            assert_eq!(
                read.vectors_at::<3>("v", start, len).unwrap(),
                &v[start..start + len]
            );
            let ids: Vec<u64> = (start as u64..(start + len) as u64)
                .map(|k| k * k)
                .collect();
            assert_eq!(read.u64s_at("ids", start, len).unwrap(), ids);
        }
    }

    #[test]
    fn missing_and_misshapen_sections_are_errors() {
        let mut s = State::default();
        s.put_f64s("x", [1.0, 2.0, 3.0]);
        let read: &dyn SectionSource = &s;
        assert!(read.f64s("y").unwrap_err().0.contains("no section 'y'"));
        assert!(read
            .vectors::<2>("x", 1)
            .unwrap_err()
            .0
            .contains("expected 2"));
        assert!(read
            .f64s_at("x", 2, 2)
            .unwrap_err()
            .0
            .contains("not the bytes"));
        s.sections[0].data.pop();
        let read: &dyn SectionSource = &s;
        assert!(read.f64s("x").unwrap_err().0.contains("whole number"));
    }
}
