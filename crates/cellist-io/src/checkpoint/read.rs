//! Reading checkpoints: the file checked whole in one pass (its magic
//! numbers, version, structure and CRC-32s) without being held in memory,
//! then its sections read in place a block at a time ([`CheckpointFile`],
//! a [`SectionSource`]), so that a rank restoring a run spread over ranks
//! holds only the particles it keeps.

use super::{physics_hash, Checkpoint, END_MAGIC, MAGIC, VERSION};
use crate::error::InputError;
use cellist::state::{Section, SectionSource, State, StateError};
use std::cell::RefCell;
use std::fs::File;
use std::io::{self, BufReader, Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};

/// Where one section's bytes lie in a checked checkpoint.
#[derive(Debug)]
struct Placed {
    name: String,
    /// The offset of its first byte.
    start: u64,
    /// Its byte count.
    len: u64,
}

/// A checkpoint checked whole and open for reading its sections in place:
/// its step, model, physics keys and outputs in [`CheckpointFile::head`],
/// its state read through [`SectionSource`] a block at a time.
#[derive(Debug)]
pub struct CheckpointFile<R> {
    path: PathBuf,
    /// Everything but the state, whose `state` is empty: the sections stay
    /// in the file.
    pub head: Checkpoint,
    sections: Vec<Placed>,
    reader: RefCell<R>,
}

impl CheckpointFile<BufReader<File>> {
    /// Opens the checkpoint at `path` and checks it whole.
    pub fn open(path: &Path) -> Result<Self, InputError> {
        let file = File::open(path).map_err(|e| cannot_read(path, e))?;
        CheckpointFile::new(path, BufReader::with_capacity(1 << 16, file))
    }
}

impl<R: Read + Seek> CheckpointFile<R> {
    /// Checks the checkpoint `reader` holds (named `path` in errors) whole,
    /// in one pass: the magic numbers, the version, the end marker, the
    /// CRC-32 of the file and of each section, and a structure that ends
    /// where the file does. A file whose CRC-32 does not match is called
    /// corrupt before anything in it is called malformed.
    pub fn new(path: &Path, mut reader: R) -> Result<Self, InputError> {
        let fail = |m: String| InputError::file(path, m);
        let len = reader
            .seek(SeekFrom::End(0))
            .and_then(|len| reader.seek(SeekFrom::Start(0)).map(|_| len))
            .map_err(|e| cannot_read(path, e))?;
        let mut first = [0u8; 12];
        let got = read_up_to(&mut reader, &mut first).map_err(|e| cannot_read(path, e))?;
        let min = (MAGIC.len() + 4 + 4 + END_MAGIC.len()) as u64;
        if got < MAGIC.len() || &first[..MAGIC.len()] != MAGIC {
            return Err(fail(
                "not a cellist checkpoint (it does not start with CELLCKPT)".into(),
            ));
        }
        if len < min {
            return Err(fail(format!(
                "the checkpoint is truncated ({len} bytes); use the previous one, {}.prev, if there is one",
                path.display()
            )));
        }
        let version = u32::from_le_bytes(first[8..12].try_into().expect("4 bytes"));
        if version != VERSION {
            return Err(fail(format!(
                "checkpoint format version {version}; this cellist reads version {VERSION}"
            )));
        }
        let body_end = len - END_MAGIC.len() as u64 - 4;
        let mut last = [0u8; 12];
        reader
            .seek(SeekFrom::Start(body_end))
            .and_then(|_| reader.read_exact(&mut last))
            .map_err(|e| cannot_read(path, e))?;
        if &last[4..] != END_MAGIC {
            return Err(fail(format!(
                "the checkpoint is truncated (no CKPTDONE end marker); use the previous one, {}.prev, if there is one",
                path.display()
            )));
        }
        let stored = u32::from_le_bytes(last[..4].try_into().expect("4 bytes"));
        reader
            .seek(SeekFrom::Start(0))
            .map_err(|e| cannot_read(path, e))?;
        let mut scan = Scan {
            reader: &mut reader,
            at: 0,
            end: body_end,
            crc: crc32fast::Hasher::new(),
            io_error: None,
        };
        let parsed = scan.take(12, "the magic number").and_then(|_| scan.parse());
        let drained = scan.drain();
        let Scan { crc, io_error, .. } = scan;
        if let Some(e) = io_error.or(drained.err()) {
            return Err(cannot_read(path, e));
        }
        if crc.finalize() != stored {
            return Err(fail(format!(
                "the checkpoint is corrupt (its CRC-32 does not match); use the previous one, {}.prev, if there is one",
                path.display()
            )));
        }
        let (head, sections) =
            parsed.map_err(|m| fail(format!("the checkpoint is malformed: {m}")))?;
        Ok(CheckpointFile {
            path: path.to_path_buf(),
            head,
            sections,
            reader: RefCell::new(reader),
        })
    }

    /// The whole checkpoint, every section read into memory.
    pub fn into_checkpoint(self) -> Result<Checkpoint, InputError> {
        let mut sections = Vec::with_capacity(self.sections.len());
        for s in &self.sections {
            let mut data = vec![0u8; s.len as usize];
            self.read_bytes(&s.name, 0, &mut data)
                .map_err(|e| InputError::file(&self.path, e.0))?;
            sections.push(Section {
                name: s.name.clone(),
                data,
            });
        }
        Ok(Checkpoint {
            state: State { sections },
            ..self.head
        })
    }
}

impl<R: Read + Seek> SectionSource for CheckpointFile<R> {
    fn section_len(&self, name: &str) -> Option<u64> {
        self.sections.iter().find(|s| s.name == name).map(|s| s.len)
    }

    /// Reads the bytes from the file. They were checked when it was opened
    /// and are not checked again (a checkpoint replaced since keeps the open
    /// file's bytes; one cut shorter is an error).
    fn read_bytes(&self, name: &str, at: u64, bytes: &mut [u8]) -> Result<(), StateError> {
        let s = self
            .sections
            .iter()
            .find(|s| s.name == name)
            .ok_or_else(|| StateError(format!("the state has no section '{name}'")))?;
        if at + bytes.len() as u64 > s.len {
            return Err(StateError(format!(
                "section '{name}' has {} bytes, not the bytes {at}..{}",
                s.len,
                at + bytes.len() as u64
            )));
        }
        let mut reader = self.reader.borrow_mut();
        reader
            .seek(SeekFrom::Start(s.start + at))
            .and_then(|_| reader.read_exact(bytes))
            .map_err(|e| StateError(format!("cannot read section '{name}': {e}")))
    }
}

/// Decodes a checkpoint read from `path` (named in errors).
pub fn decode(path: &Path, bytes: &[u8]) -> Result<Checkpoint, InputError> {
    CheckpointFile::new(path, io::Cursor::new(bytes))?.into_checkpoint()
}

/// Reads the checkpoint at `path` whole.
pub fn read_checkpoint(path: &Path) -> Result<Checkpoint, InputError> {
    CheckpointFile::open(path)?.into_checkpoint()
}

fn cannot_read(path: &Path, e: io::Error) -> InputError {
    InputError::file(path, format!("cannot read: {e}"))
}

/// Fills as much of `buf` as `reader` holds; the byte count.
fn read_up_to(reader: &mut impl Read, buf: &mut [u8]) -> io::Result<usize> {
    let mut got = 0;
    while got < buf.len() {
        match reader.read(&mut buf[got..]) {
            Ok(0) => break,
            Ok(n) => got += n,
            Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(got)
}

/// The entries a list reserves room for before they are read: its count is
/// not yet checked against the file's CRC-32, so a corrupt one must not
/// size an allocation.
const RESERVE_AT_MOST: usize = 1024;

/// The bytes a section is checked through at once.
const SCAN_CHUNK: u64 = 1 << 16;

/// Reads the fields of a checkpoint's body in order, never past its end,
/// keeping the CRC-32 of every byte read; a read that fails is kept in
/// `io_error` and ends the scan.
struct Scan<'r, R> {
    reader: &'r mut R,
    at: u64,
    end: u64,
    crc: crc32fast::Hasher,
    io_error: Option<io::Error>,
}

impl<R: Read> Scan<'_, R> {
    /// Reads `buf.len()` bytes into `buf` (the caller checked they are left).
    fn fill(&mut self, buf: &mut [u8]) -> Result<(), String> {
        if let Err(e) = self.reader.read_exact(buf) {
            let m = format!("cannot read at offset {}: {e}", self.at);
            self.io_error = Some(e);
            return Err(m);
        }
        self.crc.update(buf);
        self.at += buf.len() as u64;
        Ok(())
    }

    fn left(&self) -> u64 {
        self.end - self.at
    }

    fn take(&mut self, n: u64, what: &str) -> Result<Vec<u8>, String> {
        if n > self.left() {
            return Err(format!(
                "{what} needs {n} bytes at offset {}, but only {} are left",
                self.at,
                self.left()
            ));
        }
        let mut bytes = vec![0u8; n as usize];
        self.fill(&mut bytes)?;
        Ok(bytes)
    }

    fn u32(&mut self, what: &str) -> Result<u32, String> {
        Ok(u32::from_le_bytes(
            self.take(4, what)?.try_into().expect("4 bytes"),
        ))
    }

    fn u64(&mut self, what: &str) -> Result<u64, String> {
        Ok(u64::from_le_bytes(
            self.take(8, what)?.try_into().expect("8 bytes"),
        ))
    }

    fn str(&mut self, what: &str) -> Result<String, String> {
        let n = self.u32(what)?;
        let bytes = self.take(n as u64, what)?;
        String::from_utf8(bytes).map_err(|_| format!("{what} is not UTF-8"))
    }

    /// A count of items of at least `min_size` bytes each, checked against the
    /// bytes left (so that a corrupt count cannot ask for a huge allocation).
    fn count(&mut self, what: &str, min_size: u64) -> Result<usize, String> {
        let n = self.u32(what)? as u64;
        if n * min_size > self.left() {
            return Err(format!(
                "{what} claims {n} entries, more than the file holds"
            ));
        }
        Ok(n as usize)
    }

    /// Reads a section of `len` bytes named `name` and its CRC-32 (of the
    /// name and the bytes), checked; where its bytes lie.
    fn section(&mut self, name: String, len: u64) -> Result<Placed, String> {
        let what = format!("section '{name}'");
        if len > self.left() {
            return Err(format!(
                "{what} needs {len} bytes at offset {}, but only {} are left",
                self.at,
                self.left()
            ));
        }
        let start = self.at;
        let mut own = crc32fast::Hasher::new();
        own.update(name.as_bytes());
        let mut chunk = vec![0u8; SCAN_CHUNK.min(len) as usize];
        while self.at < start + len {
            let n = SCAN_CHUNK.min(start + len - self.at) as usize;
            self.fill(&mut chunk[..n])?;
            own.update(&chunk[..n]);
        }
        if own.finalize() != self.u32("a section checksum")? {
            return Err(format!("section '{name}' is corrupt (CRC-32 mismatch)"));
        }
        Ok(Placed { name, start, len })
    }

    /// The head and the sections' places, after the magic number and
    /// version.
    fn parse(&mut self) -> Result<(Checkpoint, Vec<Placed>), String> {
        let step = self.u64("the step")?;
        let model = self.str("the model name")?;
        let hash = self.u64("the physics hash")?;
        let n = self.count("the physics keys", 8)?;
        let mut physics = Vec::with_capacity(n.min(RESERVE_AT_MOST));
        for _ in 0..n {
            physics.push((self.str("a physics key")?, self.str("a physics value")?));
        }
        if physics_hash(&physics) != hash {
            return Err("the physics keys do not match their hash".into());
        }
        let n = self.count("the output files", 12)?;
        let mut outputs = Vec::with_capacity(n.min(RESERVE_AT_MOST));
        for _ in 0..n {
            outputs.push((
                self.str("an output file name")?,
                self.u64("an output length")?,
            ));
        }
        let n = self.count("the state sections", 16)?;
        let mut sections = Vec::with_capacity(n.min(RESERVE_AT_MOST));
        for _ in 0..n {
            let name = self.str("a section name")?;
            let len = self.u64("a section length")?;
            sections.push(self.section(name, len)?);
        }
        if self.left() != 0 {
            return Err(format!("{} bytes after the last section", self.left()));
        }
        let head = Checkpoint {
            model,
            step,
            physics,
            outputs,
            state: State::default(),
        };
        Ok((head, sections))
    }

    /// Reads the rest of the body into the CRC-32 (after a field that did
    /// not parse, the checksum still decides whether the file is corrupt).
    fn drain(&mut self) -> io::Result<()> {
        if self.io_error.is_some() {
            return Ok(());
        }
        let mut chunk = vec![0u8; SCAN_CHUNK.min(self.left()) as usize];
        while self.left() > 0 {
            let n = SCAN_CHUNK.min(self.left()) as usize;
            self.reader.read_exact(&mut chunk[..n])?;
            self.crc.update(&chunk[..n]);
            self.at += n as u64;
        }
        Ok(())
    }
}
