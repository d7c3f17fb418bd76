//! [`GsdWriter`]: a GSD file written a frame at a time, its index and name list
//! moved to blocks twice as large when they fill up.

use std::collections::HashMap;
use std::fs::{File, OpenOptions};
use std::io::{self, Write};
use std::path::Path;

use super::file::{
    copy_within, invalid_input, name_field, version, write_at, write_zeros, Entry, GsdData, Header,
    CHARACTER, ENTRY_BYTES, HEADER_BYTES, NAME_UNIT, VERSION_2_0, VERSION_2_1,
};

const INITIAL_INDEX_ENTRIES: u64 = 128;
const INITIAL_NAMELIST_BYTES: u64 = 1024;
const HOOMD_SCHEMA_VERSION: u32 = version(1, 4);

/// Where the bytes of a chunk of the current frame lie ([`GsdWriter::place_chunk`]).
#[derive(Clone, Copy, Debug)]
pub(super) struct PlacedChunk {
    location: u64,
    rows: u64,
    columns: u32,
    row_bytes: u64,
    /// The GSD type code of its values.
    kind: u8,
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

    pub(super) fn with_state(
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
        let place = self.place_chunk(name, rows, columns, &data)?;
        self.write_rows(&place, 0, &data)
    }

    /// Adds a chunk of `rows` x `columns` values of `like`'s type (its values
    /// are not read) to the current frame, its bytes reserved after the
    /// chunks before it and filled by [`GsdWriter::write_rows`] a block of
    /// rows at a time: the file of [`GsdWriter::write_chunk`] with all of them.
    pub(super) fn place_chunk(
        &mut self,
        name: &str,
        rows: u64,
        columns: u32,
        like: &GsdData,
    ) -> io::Result<PlacedChunk> {
        if columns == 0 {
            return Err(invalid_input(format!("GSD chunk {name} has 0 columns")));
        }
        let id = self.name_id(name)?;
        if self.pending.iter().any(|e| e.id == id) {
            return Err(invalid_input(format!(
                "GSD chunk {name} written twice in one frame"
            )));
        }
        let row_bytes = u64::from(columns) * like.value_bytes();
        let bytes = rows
            .checked_mul(row_bytes)
            .ok_or_else(|| invalid_input(format!("GSD chunk {name}: too large")))?;
        let start = *self.frame_start.get_or_insert(self.end);
        let location = if bytes == 0 {
            start
        } else {
            let at = self.end;
            self.end += bytes;
            at
        };
        self.pending.push(Entry {
            frame: self.frames,
            rows,
            location,
            columns,
            id,
            kind: like.type_code(),
            flags: 0,
        });
        Ok(PlacedChunk {
            location,
            rows,
            columns,
            row_bytes,
            kind: like.type_code(),
        })
    }

    /// Writes `data` (whole rows of `place`'s type: else an error) as the
    /// rows of `place` from `first_row` on.
    pub(super) fn write_rows(
        &mut self,
        place: &PlacedChunk,
        first_row: u64,
        data: &GsdData,
    ) -> io::Result<()> {
        if data.type_code() != place.kind {
            return Err(invalid_input(format!(
                "GSD rows of type {} for a chunk of type {}",
                data.type_code(),
                place.kind
            )));
        }
        let columns = u64::from(place.columns);
        let values = data.len() as u64;
        if !values.is_multiple_of(columns) || first_row + values / columns > place.rows {
            return Err(invalid_input(format!(
                "GSD rows {first_row}.. of {values} values do not fit {} x {columns}",
                place.rows
            )));
        }
        if values == 0 {
            return Ok(());
        }
        self.scratch.clear();
        data.append_le(&mut self.scratch);
        write_at(
            &mut self.file,
            place.location + first_row * place.row_bytes,
            &self.scratch,
        )
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

    /// Drops the frame being written: its chunks, its new names, and the
    /// bytes written for it, cut off at the file's committed length (the
    /// header and index never pointed at them; should the cut fail, they
    /// stay unseen by readers until a later frame writes over them).
    pub(super) fn abandon_frame(&mut self) {
        self.pending.clear();
        self.frame_start = None;
        self.end = self.committed_end;
        // best effort: the bytes left are harmless
        let _ = self.file.set_len(self.committed_end);
        self.names.truncate(self.committed_names);
        let committed = self.names.iter().filter(|&&b| b == 0).count();
        self.ids.retain(|_, id| usize::from(*id) < committed);
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
pub(super) fn check_shape(name: &str, rows: u64, columns: u32, values: usize) -> io::Result<()> {
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
    use super::*;
    use crate::gsd::test_reader::read;

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
