//! GSD trajectory files (file layer 2.x: the format of HOOMD-blue, read by OVITO,
//! freud, MDAnalysis and the `gsd` Python package), written a frame at a time, and
//! frames of its `hoomd` schema.
//!
//! A GSD file (all numbers little-endian) holds a 256-byte header at offset 0, an
//! index block of 32-byte entries (one per data chunk: frame, rows, location,
//! columns, name id, type), a name list block (names ended by a 0 byte, the list
//! ended by an empty name, the block a multiple of 64 bytes) and the chunks' bytes.
//! Readers find a chunk by binary search over the whole index, so the entries are
//! sorted by frame and, within a frame, by name id; the first entry whose location
//! is 0 ends the index. A block that fills up is written again, twice as large, at
//! the end of the file, and the header is pointed at the copy.

use std::collections::HashMap;
use std::fs::{File, OpenOptions};
use std::io::{self, Read, Seek, SeekFrom, Write};
use std::path::Path;

mod hoomd;
mod resume;
#[cfg(test)]
mod test_reader;

pub use hoomd::{write_hoomd_frame, HoomdFrame};

const MAGIC: u64 = 0x65DF_65DF_65DF_65DF;
const HEADER_BYTES: u64 = 256;
const ENTRY_BYTES: u64 = 32;
/// Name list blocks are a whole number of these.
const NAME_UNIT: u64 = 64;
const INITIAL_INDEX_ENTRIES: u64 = 128;
const INITIAL_NAMELIST_BYTES: u64 = 1024;
const CHARACTER: u8 = 11;
/// Chunks of the `character` type need file layer 2.1.
const VERSION_2_0: u32 = version(2, 0);
const VERSION_2_1: u32 = version(2, 1);
const HOOMD_SCHEMA_VERSION: u32 = version(1, 4);

/// A version as GSD stores it: major in the high 16 bits, minor in the low.
const fn version(major: u32, minor: u32) -> u32 {
    (major << 16) | minor
}

/// The values of one chunk, in the element type the file records.
#[derive(Clone, Copy, Debug)]
pub enum GsdData<'a> {
    /// `uint8`
    U8(&'a [u8]),
    /// `uint32`
    U32(&'a [u32]),
    /// `uint64`
    U64(&'a [u64]),
    /// `int8` (the `hoomd` schema stores type names so)
    I8(&'a [i8]),
    /// `int32`
    I32(&'a [i32]),
    /// `float` (32-bit)
    F32(&'a [f32]),
    /// `double`
    F64(&'a [f64]),
    /// `character`: a UTF-8 string, written as `len` rows of 1 column (the file
    /// is then marked as file layer 2.1, which older readers refuse)
    Chars(&'a [u8]),
}

impl GsdData<'_> {
    fn type_code(&self) -> u8 {
        match self {
            GsdData::U8(_) => 1,
            GsdData::U32(_) => 3,
            GsdData::U64(_) => 4,
            GsdData::I8(_) => 5,
            GsdData::I32(_) => 7,
            GsdData::F32(_) => 9,
            GsdData::F64(_) => 10,
            GsdData::Chars(_) => CHARACTER,
        }
    }

    fn len(&self) -> usize {
        match self {
            GsdData::U8(v) | GsdData::Chars(v) => v.len(),
            GsdData::U32(v) => v.len(),
            GsdData::U64(v) => v.len(),
            GsdData::I8(v) => v.len(),
            GsdData::I32(v) => v.len(),
            GsdData::F32(v) => v.len(),
            GsdData::F64(v) => v.len(),
        }
    }

    /// Appends the values' little-endian bytes to `out`.
    fn append_le(&self, out: &mut Vec<u8>) {
        match self {
            GsdData::U8(v) | GsdData::Chars(v) => out.extend_from_slice(v),
            GsdData::U32(v) => out.extend(v.iter().flat_map(|x| x.to_le_bytes())),
            GsdData::U64(v) => out.extend(v.iter().flat_map(|x| x.to_le_bytes())),
            GsdData::I8(v) => out.extend(v.iter().flat_map(|x| x.to_le_bytes())),
            GsdData::I32(v) => out.extend(v.iter().flat_map(|x| x.to_le_bytes())),
            GsdData::F32(v) => out.extend(v.iter().flat_map(|x| x.to_le_bytes())),
            GsdData::F64(v) => out.extend(v.iter().flat_map(|x| x.to_le_bytes())),
        }
    }
}

/// Bytes per element of a GSD type code, `None` for codes GSD does not define.
fn type_size(code: u8) -> Option<u64> {
    match code {
        1 | 5 | CHARACTER => Some(1),
        2 | 6 => Some(2),
        3 | 7 | 9 => Some(4),
        4 | 8 | 10 => Some(8),
        _ => None,
    }
}

fn invalid_data(message: String) -> io::Error {
    io::Error::new(io::ErrorKind::InvalidData, message)
}

fn invalid_input(message: String) -> io::Error {
    io::Error::new(io::ErrorKind::InvalidInput, message)
}

/// The file header.
#[derive(Clone, Debug, PartialEq)]
struct Header {
    index_location: u64,
    index_allocated: u64,
    namelist_location: u64,
    /// In units of [`NAME_UNIT`] bytes.
    namelist_allocated: u64,
    schema_version: u32,
    gsd_version: u32,
    application: [u8; 64],
    schema: [u8; 64],
}

/// `text` as a 0-terminated 64-byte field (cut to 63 bytes).
fn name_field(text: &str) -> [u8; 64] {
    let mut field = [0u8; 64];
    let n = text.len().min(63);
    field[..n].copy_from_slice(&text.as_bytes()[..n]);
    field
}

fn u64_at(bytes: &[u8], at: usize) -> u64 {
    u64::from_le_bytes(bytes[at..at + 8].try_into().expect("8 bytes"))
}

fn u32_at(bytes: &[u8], at: usize) -> u32 {
    u32::from_le_bytes(bytes[at..at + 4].try_into().expect("4 bytes"))
}

impl Header {
    fn encode(&self) -> [u8; HEADER_BYTES as usize] {
        let mut b = [0u8; HEADER_BYTES as usize];
        b[0..8].copy_from_slice(&MAGIC.to_le_bytes());
        b[8..16].copy_from_slice(&self.index_location.to_le_bytes());
        b[16..24].copy_from_slice(&self.index_allocated.to_le_bytes());
        b[24..32].copy_from_slice(&self.namelist_location.to_le_bytes());
        b[32..40].copy_from_slice(&self.namelist_allocated.to_le_bytes());
        b[40..44].copy_from_slice(&self.schema_version.to_le_bytes());
        b[44..48].copy_from_slice(&self.gsd_version.to_le_bytes());
        b[48..112].copy_from_slice(&self.application);
        b[112..176].copy_from_slice(&self.schema);
        // 80 reserved bytes stay 0
        b
    }

    /// Reads a header, refusing files that are not GSD files of file layer 2.x.
    fn decode(b: &[u8; HEADER_BYTES as usize]) -> io::Result<Header> {
        if u64_at(b, 0) != MAGIC {
            return Err(invalid_data("not a GSD file (no GSD magic number)".into()));
        }
        let header = Header {
            index_location: u64_at(b, 8),
            index_allocated: u64_at(b, 16),
            namelist_location: u64_at(b, 24),
            namelist_allocated: u64_at(b, 32),
            schema_version: u32_at(b, 40),
            gsd_version: u32_at(b, 44),
            application: b[48..112].try_into().expect("64 bytes"),
            schema: b[112..176].try_into().expect("64 bytes"),
        };
        if header.gsd_version >> 16 != 2 {
            return Err(invalid_data(format!(
                "GSD file layer {}.{} is not supported (only 2.x)",
                header.gsd_version >> 16,
                header.gsd_version & 0xffff
            )));
        }
        Ok(header)
    }

    fn index_bytes(&self) -> Option<u64> {
        self.index_allocated.checked_mul(ENTRY_BYTES)
    }

    fn namelist_bytes(&self) -> Option<u64> {
        self.namelist_allocated.checked_mul(NAME_UNIT)
    }

    /// Whether the index block lies within the first `length` bytes.
    fn index_within(&self, length: u64) -> bool {
        self.index_bytes()
            .and_then(|n| self.index_location.checked_add(n))
            .is_some_and(|end| end <= length)
    }

    /// Whether the name list block lies within the first `length` bytes.
    fn namelist_within(&self, length: u64) -> bool {
        self.namelist_bytes()
            .and_then(|n| self.namelist_location.checked_add(n))
            .is_some_and(|end| end <= length)
    }
}

/// One index entry: where a chunk's bytes are and what they are.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Entry {
    frame: u64,
    rows: u64,
    location: u64,
    columns: u32,
    id: u16,
    kind: u8,
    flags: u8,
}

impl Entry {
    fn encode(&self) -> [u8; ENTRY_BYTES as usize] {
        let mut b = [0u8; ENTRY_BYTES as usize];
        b[0..8].copy_from_slice(&self.frame.to_le_bytes());
        b[8..16].copy_from_slice(&self.rows.to_le_bytes());
        b[16..24].copy_from_slice(&self.location.to_le_bytes());
        b[24..28].copy_from_slice(&self.columns.to_le_bytes());
        b[28..30].copy_from_slice(&self.id.to_le_bytes());
        b[30] = self.kind;
        b[31] = self.flags;
        b
    }

    fn decode(b: &[u8]) -> Entry {
        Entry {
            frame: u64_at(b, 0),
            rows: u64_at(b, 8),
            location: u64_at(b, 16),
            columns: u32_at(b, 24),
            id: u16::from_le_bytes([b[28], b[29]]),
            kind: b[30],
            flags: b[31],
        }
    }

    /// The chunk's size in bytes, `None` for an unknown type or an overflow.
    fn bytes(&self) -> Option<u64> {
        type_size(self.kind)?
            .checked_mul(self.rows)?
            .checked_mul(u64::from(self.columns))
    }

    /// Where the chunk's bytes end.
    fn end(&self) -> Option<u64> {
        self.location.checked_add(self.bytes()?)
    }

    /// Whether the chunk was in the file when it was `length` bytes long. An empty
    /// chunk points at the start of its frame's data, which lies before the end
    /// of the frame's first non-empty chunk, so the test holds for empty chunks too.
    fn written_before(&self, length: u64) -> bool {
        self.location < length && self.end().is_some_and(|end| end <= length)
    }
}

fn write_at(file: &mut File, at: u64, bytes: &[u8]) -> io::Result<()> {
    file.seek(SeekFrom::Start(at))?;
    file.write_all(bytes)
}

fn read_at(file: &mut File, at: u64, len: u64) -> io::Result<Vec<u8>> {
    let len = usize::try_from(len).map_err(|_| invalid_data("GSD block too large".into()))?;
    let mut bytes = vec![0u8; len];
    file.seek(SeekFrom::Start(at))?;
    file.read_exact(&mut bytes)?;
    Ok(bytes)
}

/// Writes `len` zero bytes at `at`.
fn write_zeros(file: &mut File, at: u64, len: u64) -> io::Result<()> {
    const STEP: u64 = 1 << 16;
    let zeros = [0u8; STEP as usize];
    file.seek(SeekFrom::Start(at))?;
    let mut left = len;
    while left > 0 {
        let n = left.min(STEP);
        file.write_all(&zeros[..n as usize])?;
        left -= n;
    }
    Ok(())
}

/// Copies `len` bytes from `from` to `to` (the ranges must not overlap).
fn copy_within(file: &mut File, from: u64, to: u64, len: u64) -> io::Result<()> {
    const STEP: u64 = 1 << 20;
    let mut done = 0;
    while done < len {
        let n = (len - done).min(STEP);
        let bytes = read_at(file, from + done, n)?;
        write_at(file, to + done, &bytes)?;
        done += n;
    }
    Ok(())
}

/// Writes a GSD file a frame at a time: [`GsdWriter::write_chunk`] for each chunk
/// of a frame, then [`GsdWriter::end_frame`], after which the file is a valid GSD
/// file that holds the frame. Each chunk costs one write of its bytes plus, at the
/// frame's end, its 32-byte index entry; the index and name list are copied only
/// when they fill up, and then to blocks twice as large, so writing is amortised
/// O(1) per chunk.
///
/// Readers find the frames once [`GsdWriter::end_frame`] returns: the bytes are
/// handed to the operating system, not synced to the disk.
pub struct GsdWriter {
    file: File,
    header: Header,
    /// The names (each with its 0 terminator) in id order, committed or not.
    names: Vec<u8>,
    ids: HashMap<String, u16>,
    /// How many bytes of `names` the file's name list holds.
    committed_names: usize,
    /// Index entries in the file.
    entries: u64,
    frames: u64,
    /// Where the next bytes go: the end of what the writer has written.
    end: u64,
    /// The file's length when the last frame was committed.
    committed_end: u64,
    /// Entries of the frame being written.
    pending: Vec<Entry>,
    /// Where the current frame's data begins (empty chunks point there).
    frame_start: Option<u64>,
    scratch: Vec<u8>,
}

#[allow(clippy::len_without_is_empty)] // `len` is a file length, not a count
impl GsdWriter {
    /// Creates (or empties) `path` as a GSD file of the `hoomd` schema, version
    /// 1.4, from application `"cellist <version>"`, with no frames.
    pub fn create(path: &Path) -> io::Result<Self> {
        let mut file = OpenOptions::new()
            .read(true)
            .write(true)
            .create(true)
            .truncate(true)
            .open(path)?;
        let index_location = HEADER_BYTES;
        let namelist_location = index_location + INITIAL_INDEX_ENTRIES * ENTRY_BYTES;
        let end = namelist_location + INITIAL_NAMELIST_BYTES;
        let header = Header {
            index_location,
            index_allocated: INITIAL_INDEX_ENTRIES,
            namelist_location,
            namelist_allocated: INITIAL_NAMELIST_BYTES / NAME_UNIT,
            schema_version: HOOMD_SCHEMA_VERSION,
            gsd_version: VERSION_2_0,
            application: name_field(concat!("cellist ", env!("CARGO_PKG_VERSION"))),
            schema: name_field("hoomd"),
        };
        write_zeros(&mut file, HEADER_BYTES, end - HEADER_BYTES)?;
        write_at(&mut file, 0, &header.encode())?;
        Ok(Self::with_state(file, header, Vec::new(), 0, 0, end))
    }

    fn with_state(
        file: File,
        header: Header,
        names: Vec<String>,
        entries: u64,
        frames: u64,
        end: u64,
    ) -> Self {
        let mut bytes = Vec::new();
        let mut ids = HashMap::new();
        for (id, name) in names.into_iter().enumerate() {
            bytes.extend_from_slice(name.as_bytes());
            bytes.push(0);
            ids.insert(name, id as u16);
        }
        GsdWriter {
            file,
            header,
            committed_names: bytes.len(),
            names: bytes,
            ids,
            entries,
            frames,
            end,
            committed_end: end,
            pending: Vec::new(),
            frame_start: None,
            scratch: Vec::new(),
        }
    }

    /// Adds one chunk to the current frame: `rows` x `columns` values, row-major.
    /// A name may appear once per frame. Chunks with no rows are allowed, but a
    /// frame needs at least one chunk with data.
    pub fn write_chunk(
        &mut self,
        name: &str,
        rows: u64,
        columns: u32,
        data: GsdData,
    ) -> io::Result<()> {
        check_shape(name, rows, columns, data.len())?;
        let id = self.name_id(name)?;
        if self.pending.iter().any(|e| e.id == id) {
            return Err(invalid_input(format!(
                "GSD chunk {name} written twice in one frame"
            )));
        }
        self.scratch.clear();
        data.append_le(&mut self.scratch);
        let start = *self.frame_start.get_or_insert(self.end);
        let location = if self.scratch.is_empty() {
            start
        } else {
            write_at(&mut self.file, self.end, &self.scratch)?;
            let at = self.end;
            self.end += self.scratch.len() as u64;
            at
        };
        self.pending.push(Entry {
            frame: self.frames,
            rows,
            location,
            columns,
            id,
            kind: data.type_code(),
            flags: 0,
        });
        Ok(())
    }

    /// The id of `name`, given a new one if the file has no such name yet.
    fn name_id(&mut self, name: &str) -> io::Result<u16> {
        if let Some(&id) = self.ids.get(name) {
            return Ok(id);
        }
        if name.is_empty() || name.contains('\0') {
            return Err(invalid_input(format!("bad GSD chunk name {name:?}")));
        }
        // GSD reserves id 65535 as "not found"
        let id = u16::try_from(self.ids.len())
            .ok()
            .filter(|&id| id < u16::MAX)
            .ok_or_else(|| invalid_input("a GSD file holds at most 65535 names".into()))?;
        self.ids.insert(name.to_owned(), id);
        self.names.extend_from_slice(name.as_bytes());
        self.names.push(0);
        Ok(id)
    }

    /// Commits the current frame: when this returns, the file is a valid GSD file
    /// holding it (new names, index entries and header written and flushed).
    pub fn end_frame(&mut self) -> io::Result<()> {
        if !self.pending.iter().any(|e| e.rows > 0) {
            return Err(invalid_input(
                "a GSD frame needs at least one chunk with data".into(),
            ));
        }
        self.pending.sort_by_key(|e| e.id);
        let mut header = self.header.clone();
        let mut end = self.end;
        self.commit_names(&mut header, &mut end)?;
        self.commit_entries(&mut header, &mut end)?;
        if self.pending.iter().any(|e| e.kind == CHARACTER) {
            header.gsd_version = header.gsd_version.max(VERSION_2_1);
        }
        write_at(&mut self.file, 0, &header.encode())?;
        self.file.flush()?;
        self.header = header;
        self.end = end;
        self.committed_end = end;
        self.entries += self.pending.len() as u64;
        self.frames += 1;
        self.committed_names = self.names.len();
        self.pending.clear();
        self.frame_start = None;
        Ok(())
    }

    /// Writes the names new in this frame: into the free end of the name list
    /// block, or, when they do not fit, all names into a new block twice as large
    /// (or more) at `end`, which the header is then pointed at.
    fn commit_names(&mut self, header: &mut Header, end: &mut u64) -> io::Result<()> {
        if self.committed_names == self.names.len() {
            return Ok(());
        }
        let capacity = header.namelist_bytes().unwrap_or(0);
        let used = self.names.len() as u64;
        if used <= capacity {
            let at = header.namelist_location + self.committed_names as u64;
            return write_at(&mut self.file, at, &self.names[self.committed_names..]);
        }
        let mut size = capacity.max(NAME_UNIT);
        while size <= used {
            size *= 2;
        }
        let mut block = self.names.clone();
        block.resize(size as usize, 0);
        write_at(&mut self.file, *end, &block)?;
        header.namelist_location = *end;
        header.namelist_allocated = size / NAME_UNIT;
        *end += size;
        // point at the new names before any index entry uses one
        write_at(&mut self.file, 0, &header.encode())
    }

    /// Writes the frame's index entries after those in the file: into the index
    /// block, or, when it is full, into a new block twice as large (or more) at
    /// `end` holding a copy of the old entries, which the header is then pointed at.
    fn commit_entries(&mut self, header: &mut Header, end: &mut u64) -> io::Result<()> {
        let bytes: Vec<u8> = self.pending.iter().flat_map(|e| e.encode()).collect();
        let needed = self.entries + self.pending.len() as u64;
        if needed <= header.index_allocated {
            let at = header.index_location + self.entries * ENTRY_BYTES;
            return write_at(&mut self.file, at, &bytes);
        }
        let mut allocated = header.index_allocated.max(1);
        while allocated < needed {
            allocated *= 2;
        }
        let at = *end;
        let old = self.entries * ENTRY_BYTES;
        copy_within(&mut self.file, header.index_location, at, old)?;
        write_at(&mut self.file, at + old, &bytes)?;
        let used = needed * ENTRY_BYTES;
        write_zeros(&mut self.file, at + used, allocated * ENTRY_BYTES - used)?;
        header.index_location = at;
        header.index_allocated = allocated;
        *end = at + allocated * ENTRY_BYTES;
        write_at(&mut self.file, 0, &header.encode())
    }

    /// Frames committed.
    pub fn frames(&self) -> u64 {
        self.frames
    }

    /// The file's length when the last frame was committed: what a checkpoint
    /// records and [`GsdWriter::resume`] continues from.
    pub fn len(&self) -> u64 {
        self.committed_end
    }
}

/// Checks that `values` values fill `rows` x `columns`.
fn check_shape(name: &str, rows: u64, columns: u32, values: usize) -> io::Result<()> {
    if columns == 0 {
        return Err(invalid_input(format!("GSD chunk {name} has 0 columns")));
    }
    if rows.checked_mul(u64::from(columns)) != Some(values as u64) {
        return Err(invalid_input(format!(
            "GSD chunk {name}: {values} values do not fill {rows} x {columns}"
        )));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::test_reader::read;
    use super::*;

    #[test]
    fn refuses_bad_chunks_and_empty_frames() {
        let dir = tempfile::tempdir().unwrap();
        let mut w = GsdWriter::create(&dir.path().join("t.gsd")).unwrap();
        let kind = |r: io::Result<()>| r.err().map(|e| e.kind());
        let bad = Some(io::ErrorKind::InvalidInput);
        assert_eq!(kind(w.write_chunk("a", 2, 2, GsdData::U8(&[1, 2, 3]))), bad);
        assert_eq!(kind(w.write_chunk("a", 0, 0, GsdData::U8(&[]))), bad);
        assert_eq!(kind(w.write_chunk("", 1, 1, GsdData::U8(&[1]))), bad);
        w.write_chunk("empty", 0, 3, GsdData::F32(&[])).unwrap();
        assert_eq!(kind(w.end_frame()), bad);
        assert_eq!(kind(w.write_chunk("empty", 0, 3, GsdData::F32(&[]))), bad);
        w.write_chunk("text", 2, 1, GsdData::Chars(b"hi")).unwrap();
        w.end_frame().unwrap();
        assert_eq!(w.frames(), 1);
        let r = read(&dir.path().join("t.gsd"));
        assert_eq!(r.header.gsd_version, 0x0002_0001);
        assert_eq!(r.chunk(0, "text").unwrap().1, b"hi");
        assert_eq!(r.chunk(0, "empty").unwrap().0.rows, 0);
    }
}
