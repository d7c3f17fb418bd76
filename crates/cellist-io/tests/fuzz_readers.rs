//! Every reader fuzzed on stable Rust, inside `cargo test` (issue 14, item 5).
//!
//! Each reader gets (a) random bytes and (b) mutations of the valid seed files in
//! `tests/fuzz-corpus/<reader>/seed-*` (flipped and inserted bytes, truncation,
//! duplicated, swapped and deleted lines, a token replaced by an extreme number such
//! as a header count of 10^12). The properties, checked by [`check`]:
//!
//! - no panic: the parse returns `Ok` or `Err`;
//! - no hang: each parse of these small inputs takes well under a second;
//! - no allocation beyond what the input justifies: the peak of live heap bytes
//!   during the parse stays under [`budget`] of the input's length (a counting
//!   global allocator measures it), so a header count is never trusted for a
//!   reservation;
//! - an error names the file and, when it names a line, one that exists (at most
//!   one past the last line, for "missing" lines);
//! - an `Ok` result holds only finite numbers (trajectories excepted: their bit
//!   patterns may be anything).
//!
//! Every file under `tests/fuzz-corpus/` is replayed by [`corpus_replays`]: the
//! seeds must parse, and every input that ever broke a reader stays there.
//!
//! Cases per property: `PROPTEST_CASES` (default 1000); the random seed is fixed so
//! that CI is repeatable, unless `PROPTEST_RNG_SEED` is set (as
//! `scripts/fuzz-readers.sh` does for long runs).

use cellist_io::billiards::{parse_billiards_input, TrajectoryReader};
use cellist_io::bodies::{parse_bodies, read_bodies, read_bodies_part};
use cellist_io::field_csv::parse_field;
use cellist_io::lammps_data::{decode_data, decode_data_where, DataAtom};
use cellist_io::points::{parse_extended_xyz, parse_plain, Points};
use cellist_io::InputError;
use proptest::prelude::*;
use proptest::test_runner::{Config, RngSeed};
use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

// ---------------------------------------------------------------------------
// Allocation accounting: live heap bytes of the current thread and their peak.

struct Counting;

thread_local! {
    static LIVE: Cell<isize> = const { Cell::new(0) };
    static PEAK: Cell<isize> = const { Cell::new(0) };
}

fn account(delta: isize) {
    // `try_with`: a thread being torn down has no counters left; skip it
    let _ = LIVE.try_with(|live| {
        let now = live.get() + delta;
        live.set(now);
        let _ = PEAK.try_with(|peak| peak.set(peak.get().max(now)));
    });
}

// SAFETY: every call is forwarded to `System` unchanged; the counters are
// const-initialised thread-locals without destructors, so touching them never
// allocates.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let p = unsafe { System.alloc(layout) };
        if !p.is_null() {
            account(layout.size() as isize);
        }
        p
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        let p = unsafe { System.alloc_zeroed(layout) };
        if !p.is_null() {
            account(layout.size() as isize);
        }
        p
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) };
        account(-(layout.size() as isize));
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        let p = unsafe { System.realloc(ptr, layout, new_size) };
        if !p.is_null() {
            account(new_size as isize - layout.size() as isize);
        }
        p
    }
}

#[global_allocator]
static ALLOCATOR: Counting = Counting;

/// Runs `f` and returns its result and the peak of live heap bytes it added on
/// this thread.
fn peak_bytes<T>(f: impl FnOnce() -> T) -> (T, usize) {
    let base = LIVE.with(Cell::get);
    PEAK.with(|p| p.set(base));
    let out = f();
    let peak = PEAK.with(Cell::get);
    (out, (peak - base).max(0) as usize)
}

/// The most heap a parse may hold for an input of `len` bytes: 256 bytes per
/// input byte (line tables and parsed values cost tens of bytes per line, doubled
/// by `Vec` growth) plus 256 KiB (the gzip decoder's state, error strings).
fn budget(len: usize) -> usize {
    256 * len + 256 * 1024
}

/// The longest one parse of a small input may take (it takes microseconds; this
/// only catches hangs and blow-ups, on a loaded 2-core machine).
const TIME_LIMIT: Duration = Duration::from_secs(2);

// ---------------------------------------------------------------------------
// The readers.

/// One reader, as named by its folder under `tests/fuzz-corpus/`.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Reader {
    /// `points::parse_plain`.
    Plain,
    /// `points::parse_extended_xyz`.
    Xyz,
    /// `lammps_data::decode_data` of a text file.
    Lammps,
    /// `lammps_data::decode_data` of a `.gz` file (raw bytes).
    LammpsGz,
    /// `lammps_data::decode_data_where` of a text file, keeping the atoms
    /// of odd ids (a rank's share: every line checked, some atoms kept).
    LammpsOdd,
    /// `bodies::parse_bodies`.
    Bodies,
    /// `field_csv::parse_field::<2>`.
    Field2,
    /// `field_csv::parse_field::<3>`.
    Field3,
    /// `billiards::parse_billiards_input`.
    Billiards,
    /// `billiards::TrajectoryReader` with blocks of `n` lines, read to the end.
    Trajectory(usize),
}

const READERS: [(&str, Reader); 9] = [
    ("plain", Reader::Plain),
    ("xyz", Reader::Xyz),
    ("lammps", Reader::Lammps),
    ("lammps-gz", Reader::LammpsGz),
    ("bodies", Reader::Bodies),
    ("field2", Reader::Field2),
    ("field3", Reader::Field3),
    ("billiards", Reader::Billiards),
    ("trajectory", Reader::Trajectory(2)),
];

impl Reader {
    /// The file name the reader is given (errors must start with it).
    fn path(self) -> &'static Path {
        Path::new(match self {
            Reader::Plain => "fuzz.txt",
            Reader::Xyz => "fuzz.xyz",
            Reader::Lammps | Reader::LammpsOdd => "fuzz.data",
            Reader::LammpsGz => "fuzz.data.gz",
            Reader::Bodies => "bodies.txt",
            Reader::Field2 | Reader::Field3 => "field.csv",
            Reader::Billiards => "fuzz.in",
            Reader::Trajectory(_) => "steps.out",
        })
    }

    /// Parses `bytes` (lossy UTF-8 for the text readers) and returns the numbers
    /// an `Ok` result holds, for the finiteness check (empty for trajectories).
    fn parse(self, bytes: &[u8]) -> Result<Vec<f64>, InputError> {
        let path = self.path();
        let text = || String::from_utf8_lossy(bytes).into_owned();
        match self {
            Reader::Plain => Ok(match parse_plain(path, &text())? {
                Points::Two(p) => p.concat(),
                Points::Three(p) => p.concat(),
            }),
            Reader::Xyz => {
                let f = parse_extended_xyz(path, &text())?;
                let mut v = match f.points {
                    Points::Two(p) => p.concat(),
                    Points::Three(p) => p.concat(),
                };
                if let Some(cell) = f.cell {
                    v.extend(cell.lengths.iter().chain(&cell.origin));
                }
                Ok(v)
            }
            Reader::Lammps | Reader::LammpsGz | Reader::LammpsOdd => {
                let d = match self {
                    Reader::Lammps => decode_data(path, text().as_bytes())?,
                    Reader::LammpsOdd => {
                        let mut odd = |a: &DataAtom| a.id % 2 == 1;
                        decode_data_where(path, text().as_bytes(), &mut odd)?
                    }
                    _ => decode_data(path, bytes)?,
                };
                let mut v: Vec<f64> = d.lo.iter().chain(&d.hi).copied().collect();
                v.extend(d.masses.iter().flatten());
                for a in &d.atoms {
                    v.extend(a.position.iter().chain(&a.velocity));
                }
                Ok(v)
            }
            Reader::Bodies => {
                let b = parse_bodies(path, &text())?;
                let mut v = b.mass.clone();
                v.extend(b.position.concat());
                v.extend(b.velocity.concat());
                Ok(v)
            }
            Reader::Field2 => {
                let (p, phi) = parse_field::<2>(path, &text())?;
                Ok([p.concat(), phi].concat())
            }
            Reader::Field3 => {
                let (p, phi) = parse_field::<3>(path, &text())?;
                Ok([p.concat(), phi].concat())
            }
            Reader::Billiards => {
                let input = parse_billiards_input(path, &text())?;
                Ok([input.x, input.y, input.v.concat()].concat())
            }
            Reader::Trajectory(n) => {
                // raw bytes: the reader takes any `BufRead`, invalid UTF-8 included
                let mut reader = TrajectoryReader::new(path, bytes, n);
                while reader.next_step()?.is_some() {}
                Ok(Vec::new())
            }
        }
    }

    /// The input's size for the allocation budget: its bytes, plus what a gzip
    /// stream decompresses to (up to the first error).
    fn justified_len(self, bytes: &[u8]) -> usize {
        if self != Reader::LammpsGz {
            return bytes.len();
        }
        let mut out = Vec::new();
        let _ = flate2::read::MultiGzDecoder::new(bytes).read_to_end(&mut out);
        bytes.len() + out.len()
    }
}

/// Checks every property on one input; `Err` says which one failed.
fn check(reader: Reader, bytes: &[u8]) -> Result<(), String> {
    let len = reader.justified_len(bytes);
    let start = Instant::now();
    let (result, peak) = peak_bytes(|| {
        std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| reader.parse(bytes)))
    });
    let elapsed = start.elapsed();
    let result = result.map_err(|panic| {
        let what = panic
            .downcast_ref::<String>()
            .map(String::as_str)
            .or_else(|| panic.downcast_ref::<&str>().copied())
            .unwrap_or("?");
        format!("{reader:?} panicked: {what}")
    })?;
    if peak > budget(len) {
        return Err(format!(
            "{reader:?} held {peak} heap bytes for a {len}-byte input (budget {})",
            budget(len)
        ));
    }
    if elapsed > TIME_LIMIT {
        return Err(format!("{reader:?} took {elapsed:?}"));
    }
    match result {
        Ok(values) => {
            if let Some(v) = values.iter().find(|v| !v.is_finite()) {
                return Err(format!("{reader:?} accepted the non-finite value {v}"));
            }
        }
        Err(e) => {
            let message = e.to_string();
            if e.path != reader.path() || !message.starts_with(&*reader.path().to_string_lossy()) {
                return Err(format!(
                    "{reader:?}: the error does not name the file: {message}"
                ));
            }
            let text = String::from_utf8_lossy(bytes);
            // lines as an editor counts them, plus one for "line N is missing"
            let lines = text.split('\n').count() + 1;
            if reader != Reader::LammpsGz && e.line.is_some_and(|l| l == 0 || l > lines) {
                return Err(format!(
                    "{reader:?}: the error names line {:?} of a {lines}-line file: {message}",
                    e.line
                ));
            }
            if e.message.is_empty() {
                return Err(format!("{reader:?}: an empty error message"));
            }
        }
    }
    Ok(())
}

// ---------------------------------------------------------------------------
// Seeds and mutations.

fn corpus_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fuzz-corpus")
}

/// The files of `tests/fuzz-corpus/<folder>`, sorted, with their names.
fn corpus_files(folder: &str) -> Vec<(String, Vec<u8>)> {
    let dir = corpus_dir().join(folder);
    let mut files: Vec<(String, Vec<u8>)> = std::fs::read_dir(&dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .map(|entry| {
            let path = entry.unwrap().path();
            let name = path.file_name().unwrap().to_string_lossy().into_owned();
            (name, std::fs::read(&path).unwrap())
        })
        .collect();
    files.sort();
    files
}

/// The valid seed files of `folder` (`seed-*`, or `n<N>-seed-*` for trajectories).
fn seeds(folder: &str) -> Vec<Vec<u8>> {
    let seeds: Vec<Vec<u8>> = corpus_files(folder)
        .into_iter()
        .filter(|(name, _)| name.starts_with("seed-") || name.contains("-seed-"))
        .map(|(_, bytes)| bytes)
        .collect();
    assert!(!seeds.is_empty(), "no seed files in fuzz-corpus/{folder}");
    seeds
}

/// Numbers that break careless readers: counts past `u32`, `i32` and `u64`,
/// negative and zero counts, non-finite and denormal floats, other notations.
const EXTREMES: [&str; 18] = [
    "1000000000000",
    "4000000000",
    "2147483647",
    "2147483648",
    "18446744073709551615",
    "18446744073709551616",
    "99999999999999999999999999",
    "-1",
    "0",
    "-0",
    "nan",
    "inf",
    "-inf",
    "1e308",
    "1e309",
    "4e-324",
    "0x10",
    "",
];

/// `raw` wrapped into `0..len` (`len > 0`): mutations carry raw indices and
/// resolve them against the file as it is when they apply.
fn pick(raw: usize, len: usize) -> usize {
    raw % len
}

/// One edit of a file; indices wrap around the current length ([`pick`]).
#[derive(Clone, Debug)]
enum Mutation {
    /// XOR one byte with a mask.
    Flip(usize, u8),
    /// Insert a byte.
    Insert(usize, u8),
    /// Cut the file at a point.
    Truncate(usize),
    /// Write a line twice.
    Duplicate(usize),
    /// Exchange two lines.
    Swap(usize, usize),
    /// Remove a line.
    Delete(usize),
    /// Replace a token (a run between white space and `,:="`) by one of
    /// [`EXTREMES`].
    Extreme(usize, usize),
}

fn mutation() -> impl Strategy<Value = Mutation> {
    prop_oneof![
        (any::<usize>(), 1..=255u8).prop_map(|(i, m)| Mutation::Flip(i, m)),
        (any::<usize>(), any::<u8>()).prop_map(|(i, b)| Mutation::Insert(i, b)),
        any::<usize>().prop_map(Mutation::Truncate),
        any::<usize>().prop_map(Mutation::Duplicate),
        (any::<usize>(), any::<usize>()).prop_map(|(a, b)| Mutation::Swap(a, b)),
        any::<usize>().prop_map(Mutation::Delete),
        (any::<usize>(), any::<usize>()).prop_map(|(t, v)| Mutation::Extreme(t, v)),
    ]
}

fn apply(bytes: &mut Vec<u8>, m: &Mutation) {
    let mut lines: Vec<Vec<u8>> = bytes.split(|&b| b == b'\n').map(<[u8]>::to_vec).collect();
    match m {
        Mutation::Flip(i, mask) if !bytes.is_empty() => {
            let at = pick(*i, bytes.len());
            bytes[at] ^= mask;
            return;
        }
        Mutation::Insert(i, b) => {
            let at = pick(*i, bytes.len() + 1);
            bytes.insert(at, *b);
            return;
        }
        Mutation::Truncate(i) => {
            bytes.truncate(pick(*i, bytes.len() + 1));
            return;
        }
        Mutation::Duplicate(i) => {
            let k = pick(*i, lines.len());
            lines.insert(k, lines[k].clone());
        }
        Mutation::Swap(a, b) => {
            let (a, b) = (pick(*a, lines.len()), pick(*b, lines.len()));
            lines.swap(a, b);
        }
        Mutation::Delete(i) if lines.len() > 1 => {
            lines.remove(pick(*i, lines.len()));
        }
        Mutation::Extreme(t, v) => {
            // tokens: runs of bytes between white space and `,:="` (so that counts
            // inside `Properties=...` and `Lattice="..."` are tokens too)
            let mut tokens = Vec::new();
            let mut start = None;
            for (k, &b) in bytes.iter().chain(std::iter::once(&b' ')).enumerate() {
                let sep = b.is_ascii_whitespace() || b",:=\"".contains(&b);
                match (start, sep) {
                    (None, false) => start = Some(k),
                    (Some(s), true) => {
                        tokens.push(s..k);
                        start = None;
                    }
                    _ => {}
                }
            }
            if !tokens.is_empty() {
                let range = tokens[pick(*t, tokens.len())].clone();
                let value = EXTREMES[pick(*v, EXTREMES.len())].as_bytes();
                bytes.splice(range, value.iter().copied());
            }
            return;
        }
        _ => return,
    }
    *bytes = lines.join(&b'\n');
}

fn gzip(bytes: &[u8]) -> Vec<u8> {
    let mut enc = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
    enc.write_all(bytes).unwrap();
    enc.finish().unwrap()
}

fn gunzip(bytes: &[u8]) -> Vec<u8> {
    let mut out = Vec::new();
    flate2::read::MultiGzDecoder::new(bytes)
        .read_to_end(&mut out)
        .unwrap();
    out
}

/// `PROPTEST_CASES`, or `default`.
fn config(default: u32) -> Config {
    let cases = std::env::var("PROPTEST_CASES")
        .ok()
        .and_then(|c| c.parse().ok())
        .unwrap_or(default);
    Config {
        cases,
        // failures are copied by hand into tests/fuzz-corpus/, not to a side file
        failure_persistence: None,
        rng_seed: if std::env::var_os("PROPTEST_RNG_SEED").is_some() {
            Config::default().rng_seed
        } else {
            RngSeed::Fixed(14)
        },
        ..Config::default()
    }
}

/// Random bytes: mostly short printable text with the characters readers care
/// about, sometimes anything.
fn random_bytes() -> impl Strategy<Value = Bytes> {
    let alphabet: Vec<u8> = b"0123456789 \n\t.,-+eE#=\"':xyzloiAtomsLatticepbcTF\r".to_vec();
    prop_oneof![
        proptest::collection::vec(proptest::sample::select(alphabet), 0..400),
        proptest::collection::vec(any::<u8>(), 0..400),
    ]
    .prop_map(Bytes)
}

/// Seeds of `folder` with 1 to 5 mutations.
fn mutated(folder: &'static str) -> impl Strategy<Value = Bytes> {
    let seeds = seeds(folder);
    (any::<usize>(), proptest::collection::vec(mutation(), 1..=5)).prop_map(move |(seed, edits)| {
        let mut bytes = seeds[pick(seed, seeds.len())].clone();
        for m in &edits {
            apply(&mut bytes, m);
        }
        Bytes(bytes)
    })
}

/// An input, shown in failure reports as a byte-string literal (to paste into a
/// corpus file with `printf`).
#[derive(Clone)]
struct Bytes(Vec<u8>);

impl std::fmt::Debug for Bytes {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "b\"{}\"", self.0.escape_ascii())
    }
}

/// Block sizes for trajectories: small, the seeds' 2, and past `u32`.
fn block_size() -> impl Strategy<Value = usize> {
    prop_oneof![0..=3usize, Just(4_000_000_000usize)]
}

const CASES: u32 = 1000;

proptest! {
    #![proptest_config(config(CASES))]

    #[test]
    fn random_bytes_never_break_a_reader(bytes in random_bytes(), n in block_size()) {
        for (_, reader) in READERS {
            let reader = match reader {
                Reader::Trajectory(_) => Reader::Trajectory(n),
                r => r,
            };
            prop_assert_eq!(check(reader, &bytes.0), Ok(()));
        }
        // and as a gzip stream of those bytes
        prop_assert_eq!(check(Reader::LammpsGz, &gzip(&bytes.0)), Ok(()));
    }

    #[test]
    fn mutated_point_files(bytes in mutated("plain")) {
        prop_assert_eq!(check(Reader::Plain, &bytes.0), Ok(()));
    }

    #[test]
    fn mutated_xyz_files(bytes in mutated("xyz")) {
        prop_assert_eq!(check(Reader::Xyz, &bytes.0), Ok(()));
    }

    #[test]
    fn mutated_data_files(bytes in mutated("lammps")) {
        prop_assert_eq!(check(Reader::Lammps, &bytes.0), Ok(()));
        prop_assert_eq!(check(Reader::LammpsOdd, &bytes.0), Ok(()));
        prop_assert_eq!(check(Reader::LammpsGz, &gzip(&bytes.0)), Ok(()));
    }

    #[test]
    fn mutated_gz_streams(bytes in mutated("lammps-gz")) {
        // edits of the compressed bytes: bad headers, CRCs, lengths, cut streams
        prop_assert_eq!(check(Reader::LammpsGz, &bytes.0), Ok(()));
    }

    #[test]
    fn mutated_body_files(bytes in mutated("bodies")) {
        prop_assert_eq!(check(Reader::Bodies, &bytes.0), Ok(()));
    }

    /// The body file read line by line from disk, whole or a block of it (a
    /// rank's), is the text parser's result or its error.
    #[test]
    fn body_files_streamed_are_the_text_parsers(bytes in mutated("bodies")) {
        let text = String::from_utf8_lossy(&bytes.0).into_owned();
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("bodies.txt");
        std::fs::write(&path, &text).unwrap();
        let parsed = parse_bodies(&path, &text).map_err(|e| e.to_string());
        let whole = read_bodies(&path).map_err(|e| e.to_string());
        prop_assert_eq!(&whole, &parsed);
        let middle = |n: usize| n / 3..2 * n / 3;
        let part = read_bodies_part(&path, middle).map_err(|e| e.to_string());
        match (part, parsed) {
            (Ok((part, n)), Ok(all)) => {
                prop_assert_eq!(n, all.mass.len());
                let range = middle(n);
                prop_assert_eq!(&part.mass[..], &all.mass[range.clone()]);
                prop_assert_eq!(&part.position[..], &all.position[range.clone()]);
                prop_assert_eq!(&part.velocity[..], &all.velocity[range]);
                prop_assert_eq!(part.extra_columns, all.extra_columns);
            }
            (Err(a), Err(b)) => prop_assert_eq!(a, b),
            (a, b) => prop_assert!(false, "streamed {a:?}, parsed {b:?}"),
        }
    }

    #[test]
    fn mutated_field_files(two in mutated("field2"), three in mutated("field3")) {
        for bytes in [&two.0, &three.0] {
            prop_assert_eq!(check(Reader::Field2, bytes), Ok(()));
            prop_assert_eq!(check(Reader::Field3, bytes), Ok(()));
        }
    }

    #[test]
    fn mutated_billiards_inputs(bytes in mutated("billiards")) {
        prop_assert_eq!(check(Reader::Billiards, &bytes.0), Ok(()));
    }

    #[test]
    fn mutated_trajectories(bytes in mutated("trajectory"), n in block_size()) {
        prop_assert_eq!(check(Reader::Trajectory(n), &bytes.0), Ok(()));
    }
}

// ---------------------------------------------------------------------------
// Fixed cases.

/// Headers claiming far more items than a ~100-byte file holds: each reader must
/// say so at once, without reserving for the claim.
#[test]
fn huge_header_counts_fail_fast_and_small() {
    let data = "title\n1000000000000 atoms\n1 atom types\n0 1 xlo xhi\n0 1 ylo yhi\n0 1 zlo zhi\n\nAtoms\n\n1 1 0 0 0\n";
    let types = "title\n1 atoms\n1048575 atom types\n0 1 xlo xhi\n0 1 ylo yhi\n0 1 zlo zhi\n\nMasses\n\n1 1\n\nAtoms\n\n1 1 0 0 0\n";
    let cases: [(Reader, Vec<u8>, &str); 8] = [
        (
            Reader::Lammps,
            data.into(),
            "fuzz.data: the file ends inside section Atoms after 1 of 1000000000000 lines",
        ),
        (
            Reader::LammpsGz,
            gzip(data.as_bytes()),
            "fuzz.data.gz: the file ends inside section Atoms after 1 of 1000000000000 lines",
        ),
        (
            Reader::Lammps,
            types.into(),
            "fuzz.data:12: section Masses has 1 lines; the header says 1048575",
        ),
        (
            Reader::Xyz,
            "1000000000000\n\nAr 0 0 0\n".into(),
            "fuzz.xyz:3: the file ends here, after 1 atoms; line 1 says 1000000000000",
        ),
        (
            Reader::Billiards,
            "2147483647\n10\n1\n1\n0 1 1 0 0\n".into(),
            "fuzz.in:6: missing; expected particle line 2 of 2147483647 (i x y vx vy)",
        ),
        (
            Reader::Billiards,
            "4000000000\n10\n1\n1\n0 1 1 0 0\n".into(),
            "fuzz.in:1: the number of particles N is 4000000000; it must be at most 2147483647 (a C++ int)",
        ),
        (
            Reader::Trajectory(4_000_000_000),
            "1 0 1 1 0 0\n1 1 2 2 0 0\n".into(),
            "steps.out:2: the file ends inside a step: 2 of 4000000000 lines",
        ),
        (
            Reader::Xyz,
            "1\nProperties=a:R:18446744073709551615:b:R:1:pos:R:3\nAr 0 0 0\n".into(),
            "fuzz.xyz:2: Properties: count 18446744073709551615 of 'a' is too large",
        ),
    ];
    for (reader, bytes, want) in cases {
        assert_eq!(check(reader, &bytes), Ok(()), "{want}");
        let err = reader.parse(&bytes).unwrap_err().to_string();
        assert_eq!(err, want);
    }
}

/// The budget is not vacuous: a reader that reserved for a header count of 10^6
/// atoms in a 100-byte file would exceed it.
#[test]
fn the_allocation_budget_catches_a_reservation_from_a_header() {
    let (v, peak) = peak_bytes(|| Vec::<[f64; 3]>::with_capacity(1_000_000));
    drop(v);
    assert!(peak > budget(100), "peak {peak}");
}

/// Each kind of edit does what it says on a small file.
#[test]
fn mutations_edit_as_named() {
    let edit = |m: Mutation| {
        let mut b = b"a 1\nb 2\nc 3".to_vec();
        apply(&mut b, &m);
        String::from_utf8(b).unwrap()
    };
    assert_eq!(edit(Mutation::Truncate(3)), "a 1");
    assert_eq!(edit(Mutation::Truncate(12 + 3)), "a 1");
    assert_eq!(edit(Mutation::Duplicate(1)), "a 1\nb 2\nb 2\nc 3");
    assert_eq!(edit(Mutation::Swap(0, 2)), "c 3\nb 2\na 1");
    assert_eq!(edit(Mutation::Delete(0)), "b 2\nc 3");
    assert_eq!(edit(Mutation::Flip(0, 0x20)), "A 1\nb 2\nc 3");
    assert_eq!(edit(Mutation::Insert(11, b'9')), "a 1\nb 2\nc 39");
    assert_eq!(edit(Mutation::Extreme(3, 0)), "a 1\nb 1000000000000\nc 3");
    assert_eq!(edit(Mutation::Extreme(5, 11)), "a 1\nb 2\nc inf");
}

/// Every file of `tests/fuzz-corpus/<reader>/` is replayed through its reader:
/// the seeds must parse, and every input must pass [`check`].
#[test]
fn corpus_replays() {
    let mut failures = Vec::new();
    let mut count = 0;
    let mut folders: Vec<String> = std::fs::read_dir(corpus_dir())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|name| !name.ends_with(".md"))
        .collect();
    folders.sort();
    for folder in &folders {
        let Some(&(_, reader)) = READERS.iter().find(|(name, _)| name == folder) else {
            failures.push(format!("fuzz-corpus/{folder}: no reader of that name"));
            continue;
        };
        for (name, bytes) in corpus_files(folder) {
            count += 1;
            let reader = match reader {
                // trajectories are named n<N>-...: blocks of N lines
                Reader::Trajectory(_) => match name
                    .strip_prefix('n')
                    .and_then(|rest| rest.split('-').next())
                    .and_then(|n| n.parse().ok())
                {
                    Some(n) => Reader::Trajectory(n),
                    None => {
                        failures.push(format!("fuzz-corpus/{folder}/{name}: expected n<N>-..."));
                        continue;
                    }
                },
                r => r,
            };
            if let Err(e) = check(reader, &bytes) {
                failures.push(format!("fuzz-corpus/{folder}/{name}: {e}"));
            }
            let is_seed = name.starts_with("seed-") || name.contains("-seed-");
            if is_seed {
                if let Err(e) = reader.parse(&bytes) {
                    failures.push(format!(
                        "fuzz-corpus/{folder}/{name}: a seed must parse: {e}"
                    ));
                }
            }
        }
    }
    assert!(count >= READERS.len(), "only {count} corpus files");
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// The gzip seed is the text seed compressed, so both start from the same file.
#[test]
fn the_gz_seed_is_the_text_seed() {
    assert_eq!(gunzip(&seeds("lammps-gz")[0]), seeds("lammps")[0]);
}
