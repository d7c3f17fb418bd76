//! The GSD file layer's parts: the header, the index entries, the element types
//! and the block reads and writes they are made of.

use std::fs::File;
use std::io::{self, Read, Seek, SeekFrom, Write};

const MAGIC: u64 = 0x65DF_65DF_65DF_65DF;
pub(super) const HEADER_BYTES: u64 = 256;
pub(super) const ENTRY_BYTES: u64 = 32;
/// Name list blocks are a whole number of these.
pub(super) const NAME_UNIT: u64 = 64;
pub(super) const CHARACTER: u8 = 11;
/// Chunks of the `character` type need file layer 2.1.
pub(super) const VERSION_2_0: u32 = version(2, 0);
pub(super) const VERSION_2_1: u32 = version(2, 1);

/// A version as GSD stores it: major in the high 16 bits, minor in the low.
pub(super) const fn version(major: u32, minor: u32) -> u32 {
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
    pub(super) fn type_code(&self) -> u8 {
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

    pub(super) fn len(&self) -> usize {
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

    /// Bytes per value.
    pub(super) fn value_bytes(&self) -> u64 {
        type_size(self.type_code()).expect("a GSD type")
    }

    /// Appends the values' little-endian bytes to `out`.
    pub(super) fn append_le(&self, out: &mut Vec<u8>) {
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

pub(super) fn invalid_data(message: String) -> io::Error {
    io::Error::new(io::ErrorKind::InvalidData, message)
}

pub(super) fn invalid_input(message: String) -> io::Error {
    io::Error::new(io::ErrorKind::InvalidInput, message)
}

/// The file header.
#[derive(Clone, Debug, PartialEq)]
pub(super) struct Header {
    pub(super) index_location: u64,
    pub(super) index_allocated: u64,
    pub(super) namelist_location: u64,
    /// In units of [`NAME_UNIT`] bytes.
    pub(super) namelist_allocated: u64,
    pub(super) schema_version: u32,
    pub(super) gsd_version: u32,
    pub(super) application: [u8; 64],
    pub(super) schema: [u8; 64],
}

/// `text` as a 0-terminated 64-byte field (cut to 63 bytes).
pub(super) fn name_field(text: &str) -> [u8; 64] {
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
    pub(super) fn encode(&self) -> [u8; HEADER_BYTES as usize] {
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
    pub(super) fn decode(b: &[u8; HEADER_BYTES as usize]) -> io::Result<Header> {
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

    pub(super) fn index_bytes(&self) -> Option<u64> {
        self.index_allocated.checked_mul(ENTRY_BYTES)
    }

    pub(super) fn namelist_bytes(&self) -> Option<u64> {
        self.namelist_allocated.checked_mul(NAME_UNIT)
    }

    /// Whether the index block lies within the first `length` bytes.
    pub(super) fn index_within(&self, length: u64) -> bool {
        self.index_bytes()
            .and_then(|n| self.index_location.checked_add(n))
            .is_some_and(|end| end <= length)
    }

    /// Whether the name list block lies within the first `length` bytes.
    pub(super) fn namelist_within(&self, length: u64) -> bool {
        self.namelist_bytes()
            .and_then(|n| self.namelist_location.checked_add(n))
            .is_some_and(|end| end <= length)
    }
}

/// One index entry: where a chunk's bytes are and what they are.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct Entry {
    pub(super) frame: u64,
    pub(super) rows: u64,
    pub(super) location: u64,
    pub(super) columns: u32,
    pub(super) id: u16,
    pub(super) kind: u8,
    pub(super) flags: u8,
}

impl Entry {
    pub(super) fn encode(&self) -> [u8; ENTRY_BYTES as usize] {
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

    pub(super) fn decode(b: &[u8]) -> Entry {
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
    pub(super) fn bytes(&self) -> Option<u64> {
        type_size(self.kind)?
            .checked_mul(self.rows)?
            .checked_mul(u64::from(self.columns))
    }

    /// Where the chunk's bytes end.
    pub(super) fn end(&self) -> Option<u64> {
        self.location.checked_add(self.bytes()?)
    }

    /// Whether the chunk was in the file when it was `length` bytes long. An empty
    /// chunk points at the start of its frame's data, which lies before the end
    /// of the frame's first non-empty chunk, so the test holds for empty chunks too.
    pub(super) fn written_before(&self, length: u64) -> bool {
        self.location < length && self.end().is_some_and(|end| end <= length)
    }
}

pub(super) fn write_at(file: &mut File, at: u64, bytes: &[u8]) -> io::Result<()> {
    file.seek(SeekFrom::Start(at))?;
    file.write_all(bytes)
}

pub(super) fn read_at(file: &mut File, at: u64, len: u64) -> io::Result<Vec<u8>> {
    let len = usize::try_from(len).map_err(|_| invalid_data("GSD block too large".into()))?;
    let mut bytes = vec![0u8; len];
    file.seek(SeekFrom::Start(at))?;
    file.read_exact(&mut bytes)?;
    Ok(bytes)
}

/// Writes `len` zero bytes at `at`.
pub(super) fn write_zeros(file: &mut File, at: u64, len: u64) -> io::Result<()> {
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
pub(super) fn copy_within(file: &mut File, from: u64, to: u64, len: u64) -> io::Result<()> {
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
