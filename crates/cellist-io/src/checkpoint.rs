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
//! `FILE.prev`, the new one renamed into place, fsync of the folder.

use crate::error::InputError;
use cellist::state::{Section, State};
use std::io::{self, Write};
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

fn section_crc(name: &str, data: &[u8]) -> u32 {
    let mut h = crc32fast::Hasher::new();
    h.update(name.as_bytes());
    h.update(data);
    h.finalize()
}

/// The bytes of a checkpoint.
pub fn encode(c: &Checkpoint) -> Vec<u8> {
    let sections: usize = c.state.sections.iter().map(|s| s.data.len() + 64).sum();
    let mut out = Vec::with_capacity(256 + sections);
    encode_to(c, &mut out).expect("writing to memory does not fail");
    out
}

/// Writes the bytes of a checkpoint ([`encode`]) to `out` as they are made,
/// without a copy of the state's sections in one buffer.
pub fn encode_to<W: Write>(c: &Checkpoint, out: W) -> io::Result<()> {
    let mut out = Summed {
        inner: out,
        crc: crc32fast::Hasher::new(),
    };
    out.write_all(MAGIC)?;
    out.write_all(&VERSION.to_le_bytes())?;
    out.write_all(&c.step.to_le_bytes())?;
    put_str(&mut out, &c.model)?;
    out.write_all(&physics_hash(&c.physics).to_le_bytes())?;
    out.write_all(&(c.physics.len() as u32).to_le_bytes())?;
    for (k, v) in &c.physics {
        put_str(&mut out, k)?;
        put_str(&mut out, v)?;
    }
    out.write_all(&(c.outputs.len() as u32).to_le_bytes())?;
    for (file, length) in &c.outputs {
        put_str(&mut out, file)?;
        out.write_all(&length.to_le_bytes())?;
    }
    out.write_all(&(c.state.sections.len() as u32).to_le_bytes())?;
    for s in &c.state.sections {
        put_str(&mut out, &s.name)?;
        out.write_all(&(s.data.len() as u64).to_le_bytes())?;
        out.write_all(&s.data)?;
        out.write_all(&section_crc(&s.name, &s.data).to_le_bytes())?;
    }
    let Summed { mut inner, crc } = out;
    inner.write_all(&crc.finalize().to_le_bytes())?;
    inner.write_all(END_MAGIC)?;
    inner.flush()
}

/// Reads the fields of a checkpoint's body, never past its end.
struct Cursor<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl<'a> Cursor<'a> {
    fn take(&mut self, n: u64, what: &str) -> Result<&'a [u8], String> {
        let left = (self.bytes.len() - self.at) as u64;
        if n > left {
            return Err(format!(
                "{what} needs {n} bytes at offset {}, but only {left} are left",
                self.at
            ));
        }
        let slice = &self.bytes[self.at..self.at + n as usize];
        self.at += n as usize;
        Ok(slice)
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
        String::from_utf8(bytes.to_vec()).map_err(|_| format!("{what} is not UTF-8"))
    }

    /// A count of items of at least `min_size` bytes each, checked against the
    /// bytes left (so that a corrupt count cannot ask for a huge allocation).
    fn count(&mut self, what: &str, min_size: u64) -> Result<usize, String> {
        let n = self.u32(what)? as u64;
        let left = (self.bytes.len() - self.at) as u64;
        if n * min_size > left {
            return Err(format!(
                "{what} claims {n} entries, more than the file holds"
            ));
        }
        Ok(n as usize)
    }
}

/// Decodes a checkpoint read from `path` (named in errors).
pub fn decode(path: &Path, bytes: &[u8]) -> Result<Checkpoint, InputError> {
    let fail = |m: String| InputError::file(path, m);
    let min = MAGIC.len() + 4 + 4 + END_MAGIC.len();
    if bytes.len() < MAGIC.len() || &bytes[..MAGIC.len()] != MAGIC {
        return Err(fail(
            "not a cellist checkpoint (it does not start with CELLCKPT)".into(),
        ));
    }
    if bytes.len() < min {
        return Err(fail(format!(
            "the checkpoint is truncated ({} bytes); use the previous one, {}.prev, if there is one",
            bytes.len(),
            path.display()
        )));
    }
    let version = u32::from_le_bytes(bytes[8..12].try_into().expect("4 bytes"));
    if version != VERSION {
        return Err(fail(format!(
            "checkpoint format version {version}; this cellist reads version {VERSION}"
        )));
    }
    let body_end = bytes.len() - END_MAGIC.len() - 4;
    if &bytes[bytes.len() - END_MAGIC.len()..] != END_MAGIC {
        return Err(fail(format!(
            "the checkpoint is truncated (no CKPTDONE end marker); use the previous one, {}.prev, if there is one",
            path.display()
        )));
    }
    let stored = u32::from_le_bytes(bytes[body_end..body_end + 4].try_into().expect("4 bytes"));
    if crc32fast::hash(&bytes[..body_end]) != stored {
        return Err(fail(format!(
            "the checkpoint is corrupt (its CRC-32 does not match); use the previous one, {}.prev, if there is one",
            path.display()
        )));
    }
    let mut c = Cursor {
        bytes: &bytes[..body_end],
        at: 12,
    };
    let parse = |c: &mut Cursor| -> Result<Checkpoint, String> {
        let step = c.u64("the step")?;
        let model = c.str("the model name")?;
        let hash = c.u64("the physics hash")?;
        let n = c.count("the physics keys", 8)?;
        let mut physics = Vec::with_capacity(n);
        for _ in 0..n {
            physics.push((c.str("a physics key")?, c.str("a physics value")?));
        }
        if physics_hash(&physics) != hash {
            return Err("the physics keys do not match their hash".into());
        }
        let n = c.count("the output files", 12)?;
        let mut outputs = Vec::with_capacity(n);
        for _ in 0..n {
            outputs.push((c.str("an output file name")?, c.u64("an output length")?));
        }
        let n = c.count("the state sections", 16)?;
        let mut sections = Vec::with_capacity(n);
        for _ in 0..n {
            let name = c.str("a section name")?;
            let len = c.u64("a section length")?;
            let data = c.take(len, &format!("section '{name}'"))?.to_vec();
            let crc = c.u32("a section checksum")?;
            if section_crc(&name, &data) != crc {
                return Err(format!("section '{name}' is corrupt (CRC-32 mismatch)"));
            }
            sections.push(Section { name, data });
        }
        if c.at != c.bytes.len() {
            return Err(format!(
                "{} bytes after the last section",
                c.bytes.len() - c.at
            ));
        }
        Ok(Checkpoint {
            model,
            step,
            physics,
            outputs,
            state: State { sections },
        })
    };
    parse(&mut c).map_err(|m| fail(format!("the checkpoint is malformed: {m}")))
}

/// Reads the checkpoint at `path`.
pub fn read_checkpoint(path: &Path) -> Result<Checkpoint, InputError> {
    let bytes =
        std::fs::read(path).map_err(|e| InputError::file(path, format!("cannot read: {e}")))?;
    decode(path, &bytes)
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
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let partial = partial_path(path);
    let written = std::fs::File::create(&partial).and_then(|file| {
        let mut out = io::BufWriter::with_capacity(1 << 20, file);
        encode_to(c, &mut out)?;
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
