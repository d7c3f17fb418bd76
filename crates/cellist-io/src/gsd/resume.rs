//! Resuming a GSD file at the length a checkpoint recorded: its header, name list
//! and index read back and checked, and the file cut back to the frames it held
//! then.

use std::fs::{File, OpenOptions};
use std::io::{self, Write};
use std::path::Path;

use super::file::{
    invalid_data, read_at, write_at, write_zeros, Entry, Header, ENTRY_BYTES, HEADER_BYTES,
};
use super::writer::GsdWriter;

impl GsdWriter {
    /// Continues a file that a checkpoint recorded at `length` bytes (what
    /// [`GsdWriter::len`] returned then): keeps exactly the frames whose data lay
    /// within those bytes, drops the frames written after, and appends from there.
    /// This works however the index and name list moved after the checkpoint; the
    /// file is a valid GSD file at every step, and a resume interrupted part way
    /// can be done again with the same `length`.
    ///
    /// Fails with [`io::ErrorKind::InvalidData`] when the file is not a GSD 2.x
    /// file, is corrupt, or is shorter than `length`; the file is untouched then.
    pub fn resume(path: &Path, length: u64) -> io::Result<Self> {
        let mut file = OpenOptions::new().read(true).write(true).open(path)?;
        let found = file.metadata()?.len();
        if found < length {
            return Err(invalid_data(format!(
                "{} has {found} bytes, fewer than the {length} it had at the checkpoint",
                path.display()
            )));
        }
        let header = read_header(&mut file, found)?;
        if length < HEADER_BYTES {
            return Err(invalid_data(format!(
                "a GSD file cannot be {length} bytes long"
            )));
        }
        let (names, names_used) = read_names(&mut file, &header)?;
        let index = read_index(&mut file, &header, found, names.len())?;
        let kept = kept_entries(&index, length);
        let frames = index[..kept].last().map_or(0, |e| e.frame + 1);
        let kept_names = index[..kept]
            .iter()
            .map(|e| usize::from(e.id) + 1)
            .max()
            .unwrap_or(0);
        let names: Vec<String> = names.into_iter().take(kept_names).collect();
        let plan = Trim {
            header,
            found,
            length,
            kept: &index[..kept],
            old_entries: index.len() as u64,
            names: &names,
            old_names_used: names_used,
        };
        let (header, end) = plan.apply(&mut file)?;
        Ok(Self::with_state(
            file,
            header,
            names,
            kept as u64,
            frames,
            end,
        ))
    }
}

/// Reads and checks the header of a file of `found` bytes: both blocks must lie
/// within the file.
fn read_header(file: &mut File, found: u64) -> io::Result<Header> {
    if found < HEADER_BYTES {
        return Err(invalid_data(format!(
            "not a GSD file ({found} bytes, shorter than a GSD header)"
        )));
    }
    let bytes = read_at(file, 0, HEADER_BYTES)?;
    let header = Header::decode(bytes[..].try_into().expect("header bytes"))?;
    if !header.index_within(found) || !header.namelist_within(found) {
        return Err(invalid_data(
            "corrupt GSD file: index or name list beyond the end of the file".into(),
        ));
    }
    Ok(header)
}

/// Reads the name list: the names in id order and the bytes they use.
fn read_names(file: &mut File, header: &Header) -> io::Result<(Vec<String>, u64)> {
    let size = header.namelist_bytes().unwrap_or(0);
    let block = read_at(file, header.namelist_location, size)?;
    if block.last().is_some_and(|&b| b != 0) {
        return Err(invalid_data(
            "corrupt GSD file: name list not 0-terminated".into(),
        ));
    }
    let mut names = Vec::new();
    let mut used = 0;
    for name in block.split(|&b| b == 0) {
        if name.is_empty() {
            break;
        }
        let name = String::from_utf8(name.to_vec())
            .map_err(|_| invalid_data("GSD chunk name is not UTF-8".into()))?;
        used += name.len() as u64 + 1;
        names.push(name);
    }
    Ok((names, used))
}

/// Reads the index entries up to the first with location 0, checking each as
/// the GSD reader does: known type and zero flags, a known name, data within the
/// file, frames that never decrease.
fn read_index(
    file: &mut File,
    header: &Header,
    found: u64,
    names: usize,
) -> io::Result<Vec<Entry>> {
    let block = read_at(
        file,
        header.index_location,
        header.index_bytes().unwrap_or(0),
    )?;
    let mut entries: Vec<Entry> = Vec::new();
    for bytes in block.chunks_exact(ENTRY_BYTES as usize) {
        let entry = Entry::decode(bytes);
        if entry.location == 0 {
            break;
        }
        let fits = entry.end().is_some_and(|end| end <= found);
        let ordered = entries.last().is_none_or(|e| e.frame <= entry.frame);
        if !fits || entry.flags != 0 || usize::from(entry.id) >= names || !ordered {
            return Err(invalid_data(format!(
                "corrupt GSD file: bad index entry {}",
                entries.len()
            )));
        }
        entries.push(entry);
    }
    Ok(entries)
}

/// How many entries, from the start, belong to whole frames whose chunks all lay
/// within the first `length` bytes.
fn kept_entries(index: &[Entry], length: u64) -> usize {
    let mut kept = 0;
    while kept < index.len() {
        let frame = index[kept].frame;
        let size = index[kept..]
            .iter()
            .take_while(|e| e.frame == frame)
            .count();
        if !index[kept..kept + size]
            .iter()
            .all(|e| e.written_before(length))
        {
            break;
        }
        kept += size;
    }
    kept
}

/// Cutting a GSD file back to the frames it held at `length` bytes.
struct Trim<'a> {
    header: Header,
    found: u64,
    length: u64,
    kept: &'a [Entry],
    old_entries: u64,
    names: &'a [String],
    old_names_used: u64,
}

impl Trim<'_> {
    /// Rewrites the file to hold the kept frames and names only, ending right
    /// after them; returns the new header and the file's length. Blocks that lie
    /// within `length` are cleared in place past the kept part; blocks that lie
    /// beyond are rewritten, first past everything (so that the header never
    /// points at bytes about to be overwritten) and then from `length`. Every step
    /// leaves a valid file.
    fn apply(&self, file: &mut File) -> io::Result<(Header, u64)> {
        let mut header = self.header.clone();
        let kept = self.kept.len() as u64;
        let index_stays = header.index_within(self.length);
        let names_stay = header.namelist_within(self.length);
        if index_stays {
            let at = header.index_location + kept * ENTRY_BYTES;
            write_zeros(file, at, (self.old_entries - kept) * ENTRY_BYTES)?;
        }
        let names_block = (!names_stay).then(|| self.names_block());
        let index_block = (!index_stays).then(|| self.index_block());
        let moved = names_block.as_ref().map_or(0, Vec::len) as u64
            + index_block.as_ref().map_or(0, Vec::len) as u64;
        let mut end = self.length;
        if moved > 0 {
            let spare = self.found.max(self.length + moved);
            let blocks = (names_block.as_deref(), index_block.as_deref());
            place_blocks(file, &mut header, spare, blocks)?;
            place_blocks(file, &mut header, self.length, blocks)?;
            end += moved;
        }
        if names_stay {
            let kept_used: u64 = self.names.iter().map(|n| n.len() as u64 + 1).sum();
            let at = header.namelist_location + kept_used;
            write_zeros(file, at, self.old_names_used - kept_used)?;
        }
        file.set_len(end)?;
        file.flush()?;
        Ok((header, end))
    }

    /// The kept names in a block the size of the old one.
    fn names_block(&self) -> Vec<u8> {
        let mut block = Vec::new();
        for name in self.names {
            block.extend_from_slice(name.as_bytes());
            block.push(0);
        }
        block.resize(self.header.namelist_bytes().unwrap_or(0) as usize, 0);
        block
    }

    /// The kept entries in a block the size of the old one.
    fn index_block(&self) -> Vec<u8> {
        let mut block: Vec<u8> = self.kept.iter().flat_map(|e| e.encode()).collect();
        block.resize(self.header.index_bytes().unwrap_or(0) as usize, 0);
        block
    }
}

/// Writes the given name list and index blocks one after the other at `at`,
/// then the header pointing at them.
fn place_blocks(
    file: &mut File,
    header: &mut Header,
    at: u64,
    (names, index): (Option<&[u8]>, Option<&[u8]>),
) -> io::Result<()> {
    let mut pos = at;
    if let Some(block) = names {
        write_at(file, pos, block)?;
        header.namelist_location = pos;
        pos += block.len() as u64;
    }
    if let Some(block) = index {
        write_at(file, pos, block)?;
        header.index_location = pos;
    }
    write_at(file, 0, &header.encode())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gsd::test_reader::read;
    use crate::gsd::GsdData;

    /// Frames with ten chunks each, one name longer than the first name list.
    fn write_many(w: &mut GsdWriter, frames: u64, long_name: &str) {
        for f in 0..frames {
            let step = w.frames() * 10;
            w.write_chunk("configuration/step", 1, 1, GsdData::U64(&[step]))
                .unwrap();
            for k in 0..8u32 {
                let v = [f as f64, k as f64];
                w.write_chunk(&format!("log/q{k}"), 2, 1, GsdData::F64(&v))
                    .unwrap();
            }
            w.write_chunk(long_name, 0, 1, GsdData::U8(&[])).unwrap();
            w.end_frame().unwrap();
        }
    }

    #[test]
    fn resume_after_the_index_and_names_moved() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("t.gsd");
        let mut w = GsdWriter::create(&path).unwrap();
        write_many(&mut w, 3, "short");
        let length = w.len();
        let header_then = read(&path).header;
        write_many(&mut w, 40, &"x".repeat(2000));
        let r = read(&path);
        assert_eq!(r.frames(), 43);
        assert!(r.header.index_location >= length && r.header.namelist_location >= length);
        assert_eq!(r.header.index_allocated, 512);
        drop(w);

        for _ in 0..2 {
            // a second resume from the same checkpoint finds the same frames
            let w = GsdWriter::resume(&path, length).unwrap();
            assert_eq!(w.frames(), 3);
            let r = read(&path);
            assert_eq!(r.frames(), 3);
            assert_eq!(r.index.len(), 30);
            assert_eq!(r.names.len(), 10);
            assert_eq!(r.header.index_allocated, 512);
            assert_ne!(r.header, header_then);
        }
        let mut w = GsdWriter::resume(&path, length).unwrap();
        write_many(&mut w, 2, "other");
        let r = read(&path);
        assert_eq!(r.frames(), 5);
        assert_eq!(r.u64s(4, "configuration/step"), [40]);
        assert_eq!(r.f64s(4, "log/q7"), [1.0, 7.0]);
        let (e, data) = r.chunk(4, "other").unwrap();
        assert_eq!((e.rows, data.len()), (0, 0));
        assert!(r.chunk(3, &"x".repeat(2000)).is_none());
    }

    #[test]
    fn resume_in_place_clears_dropped_entries() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("t.gsd");
        let mut w = GsdWriter::create(&path).unwrap();
        let start = w.len();
        write_many(&mut w, 2, "a");
        let length = w.len();
        write_many(&mut w, 3, "b");
        drop(w);
        let w = GsdWriter::resume(&path, length).unwrap();
        assert_eq!((w.frames(), w.len()), (2, length));
        let r = read(&path);
        assert_eq!((r.frames(), r.index.len(), r.names.len()), (2, 20, 10));
        assert_eq!(r.bytes.len() as u64, length);
        let w = GsdWriter::resume(&path, start).unwrap();
        assert_eq!((w.frames(), w.len()), (0, start));
        let r = read(&path);
        assert_eq!((r.frames(), r.names.len()), (0, 0));
    }

    #[test]
    fn resume_refuses_short_and_foreign_files() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("t.gsd");
        let mut w = GsdWriter::create(&path).unwrap();
        write_many(&mut w, 2, "a");
        let length = w.len();
        drop(w);
        let kind = |p: &Path, n| GsdWriter::resume(p, n).err().map(|e| e.kind());
        assert_eq!(kind(&path, length + 1), Some(io::ErrorKind::InvalidData));
        assert_eq!(kind(&path, 100), Some(io::ErrorKind::InvalidData));
        assert_eq!(std::fs::metadata(&path).unwrap().len(), length);

        let bytes = std::fs::read(&path).unwrap();
        std::fs::write(&path, &bytes[..length as usize - 8]).unwrap();
        assert_eq!(kind(&path, 300), Some(io::ErrorKind::InvalidData));
        let foreign = dir.path().join("foreign");
        std::fs::write(&foreign, vec![7u8; 6000]).unwrap();
        assert_eq!(kind(&foreign, 5000), Some(io::ErrorKind::InvalidData));
        std::fs::write(&foreign, b"short").unwrap();
        assert_eq!(kind(&foreign, 3), Some(io::ErrorKind::InvalidData));
        let mut v1 = bytes.clone();
        v1[44..48].copy_from_slice(&0x0001_0000u32.to_le_bytes());
        std::fs::write(&foreign, &v1).unwrap();
        assert_eq!(kind(&foreign, length), Some(io::ErrorKind::InvalidData));
    }
}
