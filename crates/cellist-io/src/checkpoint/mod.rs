//! Checkpoint files: a model's complete state, the step, the scenario's physics
//! keys and the lengths of the output files at that step, so that a run restarted
//! from it writes the bytes the uninterrupted run would have.
//!
//! Layout (little-endian; `str` is a `u32` byte count and UTF-8 bytes):
//! ```text
//! "CELLCKPT"  u32 version  u64 step  str model
//! u64 physics hash (FNV-1a of the "key = value\n" lines)  u32 n  n x (str key, str value)
//! u32 n  n x (str output file, u64 length)
//! u32 n  n x (str section name, u64 byte count, bytes, u32 CRC-32 of name and bytes)
//! u32 CRC-32 of everything before it   "CKPTDONE"
//! ```
//! Floats are stored by their bit patterns. Files are written atomically:
//! `FILE.partial` in the same folder, fsync, the previous checkpoint renamed to
//! `FILE.prev`, the new one renamed into place, fsync of the folder. A state
//! need not be whole in memory: its sections' sizes place them in the file,
//! their bytes arrive a block at a time, and the checksums are combined from
//! the pieces' ([`encode_in_blocks`]; a state spread over MPI ranks).

mod read;

use cellist::state::{Layout, SectionSink, State};
pub use read::{decode, read_checkpoint, CheckpointFile};
use std::io::{self, Seek, Write};
use std::path::{Path, PathBuf};

/// The magic number at the start of a checkpoint.
pub const MAGIC: &[u8; 8] = b"CELLCKPT";
/// The magic number at the end.
pub const END_MAGIC: &[u8; 8] = b"CKPTDONE";
/// The format version this build writes and reads.
pub const VERSION: u32 = 1;

/// Everything a checkpoint holds.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Checkpoint {
    /// The model's name (`"md"`).
    pub model: String,
    /// The last step the state has completed.
    pub step: u64,
    /// The scenario's physics keys, `(key, value)`, sorted by key.
    pub physics: Vec<(String, String)>,
    /// Output files (relative to the output folder) and their lengths at `step`.
    pub outputs: Vec<(String, u64)>,
    /// The model's state.
    pub state: State,
}

/// FNV-1a (64 bits) of the `key = value` lines.
pub fn physics_hash(physics: &[(String, String)]) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for (k, v) in physics {
        for &b in format!("{k} = {v}\n").as_bytes() {
            h ^= b as u64;
            h = h.wrapping_mul(0x0100_0000_01b3);
        }
    }
    h
}

/// A writer that passes bytes on to `inner` and keeps their CRC-32.
struct Summed<W> {
    inner: W,
    crc: crc32fast::Hasher,
}

impl<W: Write> Write for Summed<W> {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        let n = self.inner.write(buf)?;
        self.crc.update(&buf[..n]);
        Ok(n)
    }

    fn flush(&mut self) -> io::Result<()> {
        self.inner.flush()
    }
}

fn put_str(out: &mut impl Write, s: &str) -> io::Result<()> {
    out.write_all(&(s.len() as u32).to_le_bytes())?;
    out.write_all(s.as_bytes())
}

/// The bytes of a checkpoint.
pub fn encode(c: &Checkpoint) -> Vec<u8> {
    let sections: usize = c.state.sections.iter().map(|s| s.data.len() + 64).sum();
    let mut out = io::Cursor::new(Vec::with_capacity(256 + sections));
    encode_in_blocks(&mut out, c, &Layout::of(&c.state), |sink| {
        append_sections(sink, &c.state)
    })
    .expect("writing to memory does not fail");
    out.into_inner()
}

/// Appends every section of `state` to `sink` (whose layout is `state`'s).
fn append_sections(sink: &mut dyn SectionSink, state: &State) {
    for (k, section) in state.sections.iter().enumerate() {
        sink.append(k, &section.data);
    }
}

/// Where one section of a checkpoint being written lies and what it holds so far.
struct Placed {
    name: String,
    /// The offset of its first byte.
    start: u64,
    /// Its byte count, as the layout declared it.
    len: u64,
    /// The bytes appended so far.
    written: u64,
    /// The CRC-32 of its bytes so far.
    crc: crc32fast::Hasher,
}

/// The sections of a checkpoint being written to `out`, each at its place
/// in the file ([`encode_in_blocks`]), with the CRC-32 of the head before
/// them and where the last one ends; the first error is kept and ends the
/// writing.
struct PlacedSections<W> {
    out: W,
    head: crc32fast::Hasher,
    sections: Vec<Placed>,
    end: u64,
    /// Where `out` stands (a write that follows the last one needs no seek,
    /// which would empty a buffered writer's buffer).
    at: u64,
    error: Option<io::Error>,
}

impl<W: Write + Seek> PlacedSections<W> {
    fn write_at(&mut self, section: usize, bytes: &[u8]) -> io::Result<()> {
        let count = self.sections.len();
        let placed = self.sections.get_mut(section).ok_or_else(|| {
            io::Error::other(format!("no section {section} in a layout of {count}"))
        })?;
        if placed.written + bytes.len() as u64 > placed.len {
            return Err(io::Error::other(format!(
                "section '{}' was given more than its {} bytes",
                placed.name, placed.len
            )));
        }
        let to = placed.start + placed.written;
        if to != self.at {
            self.out.seek(io::SeekFrom::Start(to))?;
        }
        self.out.write_all(bytes)?;
        self.at = to + bytes.len() as u64;
        placed.written += bytes.len() as u64;
        placed.crc.update(bytes);
        Ok(())
    }
}

impl<W: Write + Seek> SectionSink for PlacedSections<W> {
    fn append(&mut self, section: usize, bytes: &[u8]) {
        if self.error.is_none() {
            self.error = self.write_at(section, bytes).err();
        }
    }

    fn failed(&self) -> bool {
        self.error.is_some()
    }
}

/// Writes a checkpoint to an empty `out` with `c`'s step, model,
/// physics keys and outputs, and a state of the sections `layout` declares,
/// whose bytes `fill` appends a block at a time (each section's in order,
/// the sections in any interleaving; `c.state` is not read): every section
/// is placed from its declared size and its checksum kept as its bytes
/// arrive, and the file's checksum is put together from the pieces' at the
/// end (CRC-32s combine), so no section is ever held whole. The bytes are
/// those of [`encode`] of the whole checkpoint.
pub fn encode_in_blocks<W: Write + Seek>(
    out: W,
    c: &Checkpoint,
    layout: &Layout,
    fill: impl FnOnce(&mut dyn SectionSink),
) -> io::Result<()> {
    let mut placed = place(out, c, layout)?;
    fill(&mut placed);
    let PlacedSections {
        mut out,
        head,
        sections,
        end,
        error,
        ..
    } = placed;
    if let Some(e) = error {
        return Err(e);
    }
    let mut whole = head;
    for s in &sections {
        if s.written != s.len {
            return Err(io::Error::other(format!(
                "section '{}' got {} of its {} bytes",
                s.name, s.written, s.len
            )));
        }
        // the section's checksum covers its name and bytes
        let mut own = crc32fast::Hasher::new();
        own.update(s.name.as_bytes());
        own.combine(&s.crc);
        let own = own.finalize().to_le_bytes();
        out.seek(io::SeekFrom::Start(s.start + s.len))?;
        out.write_all(&own)?;
        whole.update(&frame(&s.name, s.len));
        whole.combine(&s.crc);
        whole.update(&own);
    }
    out.seek(io::SeekFrom::Start(end))?;
    out.write_all(&whole.finalize().to_le_bytes())?;
    out.write_all(END_MAGIC)?;
    out.flush()
}

/// Writes the head of a checkpoint (everything before the first section,
/// its CRC-32 kept) and each section's name and size at its place:
/// [`encode_in_blocks`]'s first part.
fn place<W: Write + Seek>(
    out: W,
    c: &Checkpoint,
    layout: &Layout,
) -> io::Result<PlacedSections<W>> {
    let mut head = Summed {
        inner: out,
        crc: crc32fast::Hasher::new(),
    };
    head.inner.seek(io::SeekFrom::Start(0))?;
    head.write_all(MAGIC)?;
    head.write_all(&VERSION.to_le_bytes())?;
    head.write_all(&c.step.to_le_bytes())?;
    put_str(&mut head, &c.model)?;
    head.write_all(&physics_hash(&c.physics).to_le_bytes())?;
    head.write_all(&(c.physics.len() as u32).to_le_bytes())?;
    for (k, v) in &c.physics {
        put_str(&mut head, k)?;
        put_str(&mut head, v)?;
    }
    head.write_all(&(c.outputs.len() as u32).to_le_bytes())?;
    for (file, length) in &c.outputs {
        put_str(&mut head, file)?;
        head.write_all(&length.to_le_bytes())?;
    }
    head.write_all(&(layout.sections.len() as u32).to_le_bytes())?;
    let Summed {
        inner: mut out,
        crc,
    } = head;
    let mut at = out.stream_position()?;
    let mut sections = Vec::with_capacity(layout.sections.len());
    for (name, len) in &layout.sections {
        let frame = frame(name, *len);
        out.seek(io::SeekFrom::Start(at))?;
        out.write_all(&frame)?;
        sections.push(Placed {
            name: name.clone(),
            start: at + frame.len() as u64,
            len: *len,
            written: 0,
            crc: crc32fast::Hasher::new(),
        });
        at += frame.len() as u64 + len + 4;
    }
    let position = out.stream_position()?;
    Ok(PlacedSections {
        out,
        head: crc,
        sections,
        end: at,
        at: position,
        error: None,
    })
}

/// What precedes a section's bytes: its name (`str`) and its byte count.
fn frame(name: &str, len: u64) -> Vec<u8> {
    let mut frame = Vec::with_capacity(name.len() + 12);
    frame.extend_from_slice(&(name.len() as u32).to_le_bytes());
    frame.extend_from_slice(name.as_bytes());
    frame.extend_from_slice(&len.to_le_bytes());
    frame
}

/// `path` with `.prev` appended: where the previous checkpoint is kept.
pub fn previous_path(path: &Path) -> PathBuf {
    let mut name = path.as_os_str().to_owned();
    name.push(".prev");
    PathBuf::from(name)
}

/// `path` with `.partial` appended: where a checkpoint is written before it is
/// renamed into place. A run killed while writing leaves it behind; the next
/// checkpoint written to `path` replaces it.
pub fn partial_path(path: &Path) -> PathBuf {
    let mut name = path.as_os_str().to_owned();
    name.push(".partial");
    PathBuf::from(name)
}

/// Writes `c` to `path` atomically: the whole file under `path.partial`, synced;
/// the checkpoint already at `path` (if any) renamed to `path.prev`; the new file
/// renamed to `path`; the folder synced. At every moment a complete checkpoint
/// exists under `path` or `path.prev`.
pub fn write_checkpoint(path: &Path, c: &Checkpoint) -> io::Result<()> {
    write_checkpoint_in_blocks(path, c, &Layout::of(&c.state), |sink| {
        append_sections(sink, &c.state)
    })
}

/// [`write_checkpoint`] of a checkpoint whose state `fill` appends a block
/// at a time to the sections of `layout` ([`encode_in_blocks`]): a state
/// spread over ranks goes to its file without being held whole.
pub fn write_checkpoint_in_blocks(
    path: &Path,
    c: &Checkpoint,
    layout: &Layout,
    fill: impl FnOnce(&mut dyn SectionSink),
) -> io::Result<()> {
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let partial = partial_path(path);
    let written = std::fs::File::create(&partial).and_then(|file| {
        let mut out = io::BufWriter::with_capacity(1 << 16, file);
        encode_in_blocks(&mut out, c, layout, fill)?;
        out.into_inner().map_err(|e| e.into_error())?.sync_all()
    });
    if let Err(e) = written {
        // a write cut short (a full disk) leaves nothing behind
        let _ = std::fs::remove_file(&partial);
        return Err(e);
    }
    if path.exists() {
        std::fs::rename(path, previous_path(path))?;
    }
    std::fs::rename(&partial, path)?;
    std::fs::File::open(&dir)?.sync_all()
}

#[cfg(test)]
mod tests {
    use super::*;
    use cellist::state::SectionSource;

    fn sample() -> Checkpoint {
        let mut state = State::default();
        state.put_f64s("x", [0.1, -0.0, f64::NAN]);
        state.put_u64s("ids", [1, 2, 3]);
        Checkpoint {
            model: "md".into(),
            step: 42,
            physics: vec![("run.dt".into(), "0.005".into())],
            outputs: vec![("thermo.csv".into(), 1234)],
            state,
        }
    }

    #[test]
    fn round_trip_bit_for_bit() {
        let c = sample();
        let back = decode(Path::new("c"), &encode(&c)).unwrap();
        assert_eq!(back, c);
    }

    /// Sections filled a block at a time, interleaved, give the bytes of
    /// the whole state encoded at once; a section given fewer or more bytes
    /// than its layout declared is an error.
    #[test]
    fn sections_written_in_blocks_are_the_whole_states_bytes() {
        let mut c = sample();
        c.state.put_f64s("v", (0..1000).map(|k| 0.1 * k as f64));
        c.state.put_u64s("empty", []);
        let whole = encode(&c);
        let layout = Layout::of(&c.state);
        let fill = |sink: &mut dyn SectionSink, short: bool| {
            let data: Vec<&[u8]> = c.state.sections.iter().map(|s| &s.data[..]).collect();
            // the sections' bytes in blocks of 24, round robin
            let mut at = vec![0; data.len()];
            while at.iter().zip(&data).any(|(a, d)| a < &d.len()) {
                for (k, d) in data.iter().enumerate() {
                    let end = (at[k] + 24).min(d.len());
                    // short: section 'v' without its last block
                    if !(short && end == d.len() && k == 2) {
                        sink.append(k, &d[at[k]..end]);
                    }
                    at[k] = end;
                }
            }
        };
        let mut out = io::Cursor::new(Vec::new());
        encode_in_blocks(&mut out, &c, &layout, |sink| fill(sink, false)).unwrap();
        assert_eq!(out.into_inner(), whole);
        let mut out = io::Cursor::new(Vec::new());
        let short = encode_in_blocks(&mut out, &c, &layout, |sink| fill(sink, true));
        assert!(short.unwrap_err().to_string().contains("section 'v' got"));
        let mut out = io::Cursor::new(Vec::new());
        let long = encode_in_blocks(&mut out, &c, &layout, |sink| {
            fill(sink, false);
            sink.append(0, &[0; 8]);
        });
        assert!(long.unwrap_err().to_string().contains("more than its"));
    }

    #[test]
    fn every_flipped_byte_and_every_truncation_is_refused() {
        let bytes = encode(&sample());
        for k in 0..bytes.len() {
            let mut bad = bytes.clone();
            bad[k] ^= 0x10;
            assert!(decode(Path::new("c"), &bad).is_err(), "flip at {k}");
            assert!(decode(Path::new("c"), &bytes[..k]).is_err(), "cut at {k}");
        }
    }

    /// A file whose checksum does not match is called corrupt, whatever
    /// else is wrong with it; one whose checksum matches but whose fields
    /// do not fit is called malformed, with the field named.
    #[test]
    fn corrupt_is_told_before_malformed() {
        let bytes = encode(&sample());
        let mut bad = bytes.clone();
        // the count of physics keys made huge
        let keys = 8 + 4 + 8 + (4 + 2) + 8;
        bad[keys..keys + 4].copy_from_slice(&u32::MAX.to_le_bytes());
        let e = decode(Path::new("c"), &bad).unwrap_err().to_string();
        assert!(e.contains("corrupt (its CRC-32"), "{e}");
        let end = bad.len() - END_MAGIC.len() - 4;
        let crc = crc32fast::hash(&bad[..end]);
        bad[end..end + 4].copy_from_slice(&crc.to_le_bytes());
        let e = decode(Path::new("c"), &bad).unwrap_err().to_string();
        assert!(e.contains("malformed: the physics keys claims"), "{e}");
    }

    /// A checkpoint file read in place: its head, and any stretch of a
    /// section, are those of the checkpoint written; a stretch past a
    /// section's end is an error.
    #[test]
    fn sections_are_read_in_place() {
        let mut c = sample();
        c.state.put_f64s("v", (0..20_000).map(|k| 0.5 * k as f64));
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("c.ckpt");
        write_checkpoint(&path, &c).unwrap();
        let file = CheckpointFile::open(&path).unwrap();
        let state = Checkpoint {
            state: State::default(),
            ..c.clone()
        };
        assert_eq!(file.head, state);
        let read: &dyn SectionSource = &file;
        let v: Vec<f64> = (9_000..19_000).map(|k| 0.5 * k as f64).collect();
        assert_eq!(read.f64s_at("v", 9_000, 10_000).unwrap(), v);
        assert_eq!(read.u64s_of("ids", 3).unwrap(), [1, 2, 3]);
        assert!(read.f64s_at("v", 19_999, 2).is_err());
        assert!(!read.has("w"));
        assert_eq!(file.into_checkpoint().unwrap(), c);
    }

    proptest::proptest! {
        /// Random bytes, and a valid checkpoint cut, flipped or with bytes
        /// inserted: an error or (unchanged bytes only) the same checkpoint, never
        /// a panic, and no allocation beyond the file's size (counts are checked
        /// against the bytes left before anything is reserved).
        #[test]
        fn decoding_never_panics(
            noise in proptest::collection::vec(proptest::num::u8::ANY, 0..300),
            at in 0usize..10_000,
            byte in proptest::num::u8::ANY,
            cut in 0usize..10_000,
        ) {
            let path = Path::new("c");
            let _ = decode(path, &noise);
            let mut with_magic = MAGIC.to_vec();
            with_magic.extend_from_slice(&noise);
            let _ = decode(path, &with_magic);
            let good = encode(&sample());
            let k = at % good.len();
            let mut changed = good.clone();
            changed[k] = byte;
            let decoded = decode(path, &changed);
            proptest::prop_assert!(decoded.is_err() || changed == good);
            let mut inserted = good.clone();
            inserted.insert(k, byte);
            proptest::prop_assert!(decode(path, &inserted).is_err());
            proptest::prop_assert!(decode(path, &good[..cut % good.len()]).is_err());
        }
    }

    #[test]
    fn a_new_checkpoint_keeps_the_previous_one() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("state.ckpt");
        let mut c = sample();
        write_checkpoint(&path, &c).unwrap();
        c.step = 43;
        write_checkpoint(&path, &c).unwrap();
        assert_eq!(read_checkpoint(&path).unwrap().step, 43);
        assert_eq!(read_checkpoint(&previous_path(&path)).unwrap().step, 42);
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 2);
    }

    /// A checkpoint in blocks that cannot be written leaves the previous one
    /// as it was and no partial file: a short section, an append past the
    /// layout (the sink then says it failed), a folder that does not exist
    /// (nothing to fill).
    #[test]
    fn a_failed_write_in_blocks_keeps_the_previous_checkpoint() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("state.ckpt");
        let c = sample();
        write_checkpoint(&path, &c).unwrap();
        let layout = Layout::of(&c.state);
        let short = write_checkpoint_in_blocks(&path, &c, &layout, |sink| {
            sink.append(0, &c.state.sections[0].data[..8]);
        });
        assert!(short
            .unwrap_err()
            .to_string()
            .contains("section 'x' got 8 of its 24 bytes"));
        let past = write_checkpoint_in_blocks(&path, &c, &layout, |sink| {
            sink.append(2, &[0; 8]);
            assert!(sink.failed());
        });
        assert!(past.unwrap_err().to_string().contains("no section 2"));
        assert_eq!(read_checkpoint(&path).unwrap(), c);
        assert!(!partial_path(&path).exists());
        let mut filled = false;
        let nowhere = dir.path().join("missing").join("state.ckpt");
        assert!(write_checkpoint_in_blocks(&nowhere, &c, &layout, |_| filled = true).is_err());
        assert!(!filled);
    }

    #[test]
    fn a_write_cut_short_is_replaced_by_the_next_one() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("state.ckpt");
        std::fs::write(partial_path(&path), b"half a checkpoint").unwrap();
        write_checkpoint(&path, &sample()).unwrap();
        assert_eq!(read_checkpoint(&path).unwrap().step, 42);
        assert!(!partial_path(&path).exists());
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }
}
