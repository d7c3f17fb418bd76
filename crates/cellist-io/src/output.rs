//! Writing results: an output file that appears whole or not at all, and numbers
//! printed the way C's `%.17g` prints them (enough digits to read back every bit).

use std::fs::File;
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};

/// A file written under a temporary name in the target's folder and renamed into
/// place by [`AtomicFile::commit`]; dropped without a commit, it is removed, so a
/// failed run leaves no partial output behind. A target that exists and is not
/// a regular file (`/dev/null`, a pipe) is written in place: a rename would
/// replace the device with a file.
pub struct AtomicFile {
    target: PathBuf,
    /// The temporary name, or `None` when the target is written in place.
    temp: Option<PathBuf>,
    writer: Option<BufWriter<File>>,
}

impl AtomicFile {
    /// Starts writing `target`.
    pub fn create(target: &Path) -> io::Result<Self> {
        let name = target.file_name().ok_or_else(|| {
            io::Error::new(io::ErrorKind::InvalidInput, "output path has no file name")
        })?;
        if std::fs::metadata(target).is_ok_and(|m| !m.file_type().is_file()) {
            let file = std::fs::OpenOptions::new().write(true).open(target)?;
            return Ok(AtomicFile {
                target: target.to_path_buf(),
                temp: None,
                writer: Some(BufWriter::with_capacity(1 << 20, file)),
            });
        }
        let mut temp_name = std::ffi::OsString::from(".");
        temp_name.push(name);
        temp_name.push(format!(".{}.tmp", std::process::id()));
        let temp = target.with_file_name(temp_name);
        let file = File::create(&temp)?;
        Ok(AtomicFile {
            target: target.to_path_buf(),
            temp: Some(temp),
            writer: Some(BufWriter::with_capacity(1 << 20, file)),
        })
    }

    /// The writer.
    pub fn writer(&mut self) -> &mut BufWriter<File> {
        self.writer.as_mut().expect("writer present until commit")
    }

    /// Flushes, syncs and renames the file into place (a target written in
    /// place is only flushed).
    pub fn commit(mut self) -> io::Result<()> {
        let writer = self.writer.take().expect("writer present until commit");
        let file = writer.into_inner().map_err(|e| e.into_error())?;
        match &self.temp {
            Some(temp) => {
                file.sync_all()?;
                std::fs::rename(temp, &self.target)
            }
            None => Ok(()),
        }
    }
}

impl Drop for AtomicFile {
    fn drop(&mut self) {
        if let (Some(_), Some(temp)) = (self.writer.take(), &self.temp) {
            let _ = std::fs::remove_file(temp);
        }
    }
}

/// A file written as a run goes (thermo rows, dump frames, animation frames),
/// under its final name. [`StreamFile::sync`] flushes it and says how long it is,
/// which a checkpoint records; a restart from that checkpoint continues the file
/// from exactly that length ([`StreamFile::resume`]), so the restarted run writes
/// the bytes the uninterrupted one would have.
pub struct StreamFile {
    path: PathBuf,
    writer: BufWriter<File>,
}

impl StreamFile {
    /// Starts `path` empty.
    pub fn create(path: &Path) -> io::Result<Self> {
        let file = File::create(path)?;
        Ok(StreamFile {
            path: path.to_path_buf(),
            writer: BufWriter::with_capacity(1 << 20, file),
        })
    }

    /// Continues `path` from its first `length` bytes, cutting what was written
    /// after them. Fails with [`io::ErrorKind::InvalidData`] when the file is
    /// shorter than `length` (it is not the file the checkpoint knew), and leaves
    /// it untouched then.
    pub fn resume(path: &Path, length: u64) -> io::Result<Self> {
        use std::io::{Seek, SeekFrom};
        let mut file = std::fs::OpenOptions::new()
            .read(true)
            .write(true)
            .open(path)?;
        let found = file.metadata()?.len();
        if found < length {
            return Err(io::Error::new(
                io::ErrorKind::InvalidData,
                format!(
                    "{} has {found} bytes, fewer than the {length} it had at the checkpoint",
                    path.display()
                ),
            ));
        }
        file.set_len(length)?;
        file.seek(SeekFrom::End(0))?;
        Ok(StreamFile {
            path: path.to_path_buf(),
            writer: BufWriter::with_capacity(1 << 20, file),
        })
    }

    /// The path.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The writer.
    pub fn writer(&mut self) -> &mut BufWriter<File> {
        &mut self.writer
    }

    /// Flushes to the operating system and returns the file's length.
    pub fn sync(&mut self) -> io::Result<u64> {
        self.writer.flush()?;
        Ok(self.writer.get_ref().metadata()?.len())
    }
}

impl Write for StreamFile {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        self.writer.write(buf)
    }

    fn flush(&mut self) -> io::Result<()> {
        self.writer.flush()
    }
}

/// Formats `x` as C's `printf("%.17g", x)`: 17 significant digits, trailing zeros
/// removed, exponent form when the decimal exponent is below -4 or at least 17.
pub fn format_g17(x: f64, out: &mut String) {
    use std::fmt::Write as _;
    if !x.is_finite() {
        out.push_str(match x {
            v if v.is_nan() => "nan",
            v if v > 0.0 => "inf",
            _ => "-inf",
        });
        return;
    }
    let sci = format!("{x:.16e}");
    let (mantissa, exp) = sci.split_once('e').expect("exponent form");
    let exp: i32 = exp.parse().expect("integer exponent");
    if !(-4..17).contains(&exp) {
        out.push_str(trim_zeros(mantissa));
        let _ = write!(out, "e{}{:02}", if exp < 0 { '-' } else { '+' }, exp.abs());
    } else {
        let fixed = format!("{x:.prec$}", prec = (16 - exp) as usize);
        out.push_str(trim_zeros(&fixed));
    }
}

/// Writes one line `i j r` per pair, `r` as `%.17g`.
pub fn write_pairs<W: Write + ?Sized>(
    w: &mut W,
    pairs: impl IntoIterator<Item = (u32, u32, f64)>,
) -> io::Result<()> {
    let mut line = String::with_capacity(64);
    for (i, j, r) in pairs {
        use std::fmt::Write as _;
        line.clear();
        let _ = write!(line, "{i} {j} ");
        format_g17(r, &mut line);
        line.push('\n');
        w.write_all(line.as_bytes())?;
    }
    Ok(())
}

fn trim_zeros(s: &str) -> &str {
    if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.')
    } else {
        s
    }
}

#[cfg(test)]
mod tests {
    /// A device as the target is written in place, not replaced by a file
    /// (`--output /dev/null` used to turn `/dev/null` into a regular file).
    #[test]
    fn a_device_stays_a_device() {
        use std::os::unix::fs::FileTypeExt;
        let null = std::path::Path::new("/dev/null");
        if !std::fs::metadata(null).is_ok_and(|m| m.file_type().is_char_device()) {
            return; // no device to check on this machine
        }
        let mut out = super::AtomicFile::create(null).unwrap();
        std::io::Write::write_all(out.writer(), b"discarded").unwrap();
        out.commit().unwrap();
        assert!(std::fs::metadata(null)
            .unwrap()
            .file_type()
            .is_char_device());
    }

    use super::*;

    fn g(x: f64) -> String {
        let mut s = String::new();
        format_g17(x, &mut s);
        s
    }

    #[test]
    fn matches_c_printf() {
        // expected strings are what C's printf("%.17g") prints for these values
        assert_eq!(g(1.0), "1");
        assert_eq!(g(0.5), "0.5");
        assert_eq!(g(0.1), "0.10000000000000001");
        assert_eq!(g(2.4999999999999996), "2.4999999999999996");
        assert_eq!(g(1e-5), "1.0000000000000001e-05");
        assert_eq!(g(123456789012345678.0), "1.2345678901234568e+17");
        assert_eq!(g(0.0001), "0.0001");
        assert_eq!(g(-3.25), "-3.25");
        assert_eq!(g(0.0), "0");
        for x in [0.1, 1.0 / 3.0, 2.5f64.sqrt(), 1e-300, 6.02e23] {
            assert_eq!(g(x).parse::<f64>().unwrap(), x);
        }
    }

    #[test]
    fn atomic_file_appears_only_on_commit() {
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("out.txt");
        {
            let mut f = AtomicFile::create(&target).unwrap();
            writeln!(f.writer(), "partial").unwrap();
        }
        assert!(!target.exists());
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
        let mut f = AtomicFile::create(&target).unwrap();
        writeln!(f.writer(), "whole").unwrap();
        f.commit().unwrap();
        assert_eq!(std::fs::read_to_string(&target).unwrap(), "whole\n");
    }
}
