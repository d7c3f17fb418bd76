//! Files of the hard-disk collision benchmark (SPEC.md sections 1 and 5): the `.in`
//! input, the final state and per-step trajectories in the course's fixed
//! 8-decimal form or as exact IEEE-754 bit patterns.

use crate::error::{parse_finite, InputError};
use std::io::{BufRead, Write};
use std::path::Path;

/// An input file: `N`, `L`, `r`, `S`, then `i x y vx vy` per particle, in vector
/// order.
#[derive(Clone, Debug, PartialEq)]
pub struct BilliardsInput {
    /// Side `L`.
    pub side: i64,
    /// Radius `r`.
    pub radius: i64,
    /// Steps `S`.
    pub steps: u64,
    /// Id of each particle (a permutation of `0..N`).
    pub ids: Vec<u32>,
    /// Positions.
    pub x: Vec<f64>,
    /// Positions.
    pub y: Vec<f64>,
    /// Velocities.
    pub v: Vec<[f64; 2]>,
    /// What was read but ignored (lines after the N-th particle line).
    pub warnings: Vec<String>,
}

/// C++ `stoi` of a header line: leading whitespace, an optional sign, digits; the
/// rest of the line is ignored. `None` without digits; `Some(Err(number))`, the
/// number as written, when it does not fit in an `int`.
fn stoi(line: &str) -> Option<Result<i64, &str>> {
    let t = line.trim_start();
    let sign_len = usize::from(t.starts_with(['+', '-']));
    let digits = t[sign_len..].bytes().take_while(u8::is_ascii_digit).count();
    if digits == 0 {
        return None;
    }
    let number = &t[..sign_len + digits];
    Some(
        number
            .parse::<i64>()
            .ok()
            .filter(|v| i32::try_from(*v).is_ok())
            .ok_or(number),
    )
}

/// Reads an input file. Errors name the line: a missing line, a header that is not
/// an integer, a side, radius or particle count out of range, a particle line
/// without exactly 5 fields, a field that is not a (finite) number, ids that are
/// not a permutation of `0..N`. Non-blank lines after the N-th particle line are
/// ignored (as the course's reader does) with a warning.
pub fn read_billiards_input(path: &Path) -> Result<BilliardsInput, InputError> {
    let bytes =
        std::fs::read(path).map_err(|e| InputError::file(path, format!("cannot read: {e}")))?;
    let text = String::from_utf8(bytes)
        .map_err(|e| InputError::file(path, format!("not UTF-8 text: {e}")))?;
    parse_billiards_input(path, &text)
}

/// [`read_billiards_input`] on text already read.
pub fn parse_billiards_input(path: &Path, text: &str) -> Result<BilliardsInput, InputError> {
    let mut all: Vec<&str> = text
        .split('\n')
        .map(|l| l.strip_suffix('\r').unwrap_or(l))
        .collect();
    if all.last() == Some(&"") {
        // the final newline ends the last line; it does not start another
        all.pop();
    }
    let mut lines = all.into_iter();
    const HEADER: [(&str, i64); 4] = [
        ("the number of particles N", 0),
        ("the side L of the box", 1),
        ("the radius r", 1),
        ("the number of steps S", 0),
    ];
    let mut header = [0i64; 4];
    for (k, (what, least)) in HEADER.iter().enumerate() {
        let line = lines
            .next()
            .ok_or_else(|| InputError::at(path, k + 1, format!("missing; expected {what}")))?;
        let value = match stoi(line) {
            Some(Ok(value)) => value,
            None => {
                return Err(InputError::at(
                    path,
                    k + 1,
                    format!("'{}': expected {what}, an integer", line.trim()),
                ))
            }
            Some(Err(number)) if number.starts_with('-') => {
                return Err(InputError::at(
                    path,
                    k + 1,
                    format!("{what} is {number}; it must be at least {least}"),
                ))
            }
            Some(Err(number)) => {
                return Err(InputError::at(
                    path,
                    k + 1,
                    format!("{what} is {number}; it must be at most 2147483647 (a C++ int)"),
                ))
            }
        };
        if value < *least {
            return Err(InputError::at(
                path,
                k + 1,
                format!("{what} is {value}; it must be at least {least}"),
            ));
        }
        header[k] = value;
    }
    let [n, side, radius, steps] = header;
    let n = n as usize;
    // N is not trusted for a reservation beyond the lines the file has
    let capacity = n.min(lines.len());
    let mut input = BilliardsInput {
        side,
        radius,
        steps: steps as u64,
        ids: Vec::with_capacity(capacity),
        x: Vec::with_capacity(capacity),
        y: Vec::with_capacity(capacity),
        v: Vec::with_capacity(capacity),
        warnings: Vec::new(),
    };
    for k in 0..n {
        let number = k + 5;
        let line = lines.next().ok_or_else(|| {
            InputError::at(
                path,
                number,
                format!(
                    "missing; expected particle line {} of {n} (i x y vx vy)",
                    k + 1
                ),
            )
        })?;
        let fields: Vec<&str> = line.split_whitespace().collect();
        if fields.len() != 5 {
            return Err(InputError::at(
                path,
                number,
                format!(
                    "expected 5 fields (i x y vx vy) for particle line {} of {n}, found {}",
                    k + 1,
                    fields.len()
                ),
            ));
        }
        // like the course's reader (`stoi`): the leading integer of the field
        let id = stoi(fields[0]).ok_or_else(|| {
            InputError::at(
                path,
                number,
                format!("id '{}': expected an integer", fields[0]),
            )
        })?;
        let slot = id
            .ok()
            .and_then(|id| usize::try_from(id).ok())
            .filter(|&s| s < n)
            .ok_or_else(|| {
                let id = id.map_or_else(str::to_string, |id| id.to_string());
                InputError::at(
                    path,
                    number,
                    format!("id {id} is outside 0..{n}: ids must be a permutation of 0..N-1"),
                )
            })?;
        const NAMES: [&str; 4] = ["x", "y", "vx", "vy"];
        let mut values = [0.0; 4];
        for (a, value) in values.iter_mut().enumerate() {
            *value = parse_finite(path, number, fields[a + 1], || {
                format!("field {} ({})", a + 2, NAMES[a])
            })?;
        }
        input.ids.push(slot as u32);
        input.x.push(values[0]);
        input.y.push(values[1]);
        input.v.push([values[2], values[3]]);
    }
    // every line is read now, so N is backed by the file's own size
    let mut seen_at = vec![0usize; n];
    for (k, &slot) in input.ids.iter().enumerate() {
        let number = k + 5;
        if seen_at[slot as usize] != 0 {
            return Err(InputError::at(
                path,
                number,
                format!(
                    "id {slot} was already given on line {}: ids must be a permutation of 0..N-1",
                    seen_at[slot as usize]
                ),
            ));
        }
        seen_at[slot as usize] = number;
    }
    let rest: Vec<usize> = lines
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty())
        .map(|(k, _)| k + n + 5)
        .collect();
    if let Some(first) = rest.first() {
        input.warnings.push(format!(
            "{}: ignored {} non-blank line(s) after the {n} particle lines (the first is line {first})",
            path.display(),
            rest.len()
        ));
    }
    Ok(input)
}

/// How a state is written: the course's 8 decimals, or exact bit patterns.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StateFormat {
    /// `%.8f`, correctly rounded, ties to even; an exact zero prints as `0.00000000`.
    Fixed8,
    /// The 16 lowercase hex digits of the IEEE-754 pattern.
    Bits,
}

/// Writes one state, one `step i x y vx vy` line per particle in vector order.
pub fn write_state(
    out: &mut impl Write,
    format: StateFormat,
    step: u64,
    ids: &[u32],
    x: &[f64],
    y: &[f64],
    v: &[[f64; 2]],
) -> std::io::Result<()> {
    for k in 0..ids.len() {
        write!(out, "{step} {}", ids[k])?;
        for value in [x[k], y[k], v[k][0], v[k][1]] {
            match format {
                // +0.0 for both zeros; a tiny nonzero value keeps its sign
                StateFormat::Fixed8 => {
                    write!(out, " {:.8}", if value == 0.0 { 0.0 } else { value })?
                }
                StateFormat::Bits => write!(out, " {:016x}", value.to_bits())?,
            }
        }
        out.write_all(b"\n")?;
    }
    Ok(())
}

/// One step of a trajectory: its number, and the ids and `[x, y, vx, vy]` of its
/// lines in file order.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TrajectoryStep {
    /// The step field of the block.
    pub step: i64,
    /// Ids, as written.
    pub ids: Vec<i64>,
    /// `[x, y, vx, vy]` per line.
    pub states: Vec<[f64; 4]>,
}

/// Reads a trajectory (blocks of `n` lines `step i x y vx vy`, values in fixed
/// decimals or 16-hex-digit bit patterns, told apart by the first value) one step
/// at a time.
pub struct TrajectoryReader<R> {
    path: std::path::PathBuf,
    lines: std::io::Lines<R>,
    line: usize,
    n: usize,
    bits: Option<bool>,
}

impl<R: BufRead> TrajectoryReader<R> {
    /// A reader of `n`-line blocks from `source` (named `path` in errors).
    pub fn new(path: &Path, source: R, n: usize) -> Self {
        TrajectoryReader {
            path: path.to_path_buf(),
            lines: source.lines(),
            line: 0,
            n,
            bits: None,
        }
    }

    /// The next block, `None` at the end; blank lines are skipped. A block cut
    /// short, a line without 6 fields or a value that does not parse is an error
    /// naming the line.
    pub fn next_step(&mut self) -> Result<Option<TrajectoryStep>, InputError> {
        let mut block = TrajectoryStep::default();
        while block.ids.len() < self.n.max(1) {
            let Some(line) = self.lines.next() else {
                if block.ids.is_empty() {
                    return Ok(None);
                }
                return Err(InputError::at(
                    &self.path,
                    self.line,
                    format!(
                        "the file ends inside a step: {} of {} lines",
                        block.ids.len(),
                        self.n
                    ),
                ));
            };
            self.line += 1;
            let line = line
                .map_err(|e| InputError::at(&self.path, self.line, format!("cannot read: {e}")))?;
            let fields: Vec<&str> = line.split_whitespace().collect();
            if fields.is_empty() {
                continue;
            }
            if fields.len() != 6 {
                return Err(InputError::at(
                    &self.path,
                    self.line,
                    format!(
                        "expected 6 fields (step i x y vx vy), found {}",
                        fields.len()
                    ),
                ));
            }
            let int = |k: usize, what: &str| {
                fields[k].parse::<i64>().map_err(|_| {
                    InputError::at(
                        &self.path,
                        self.line,
                        format!("{what} '{}': expected an integer", fields[k]),
                    )
                })
            };
            let step = int(0, "step")?;
            if block.ids.is_empty() {
                block.step = step;
            } else if step != block.step {
                return Err(InputError::at(
                    &self.path,
                    self.line,
                    format!(
                        "step {step} inside the block of step {} ({} of {} lines)",
                        block.step,
                        block.ids.len(),
                        self.n
                    ),
                ));
            }
            block.ids.push(int(1, "id")?);
            let bits = *self
                .bits
                .get_or_insert_with(|| fields[2].len() == 16 && !fields[2].contains('.'));
            let mut state = [0.0; 4];
            for (a, value) in state.iter_mut().enumerate() {
                let token = fields[a + 2];
                *value = if bits {
                    u64::from_str_radix(token, 16)
                        .map(f64::from_bits)
                        .map_err(|_| {
                            InputError::at(
                                &self.path,
                                self.line,
                                format!("field {} '{token}': expected 16 hex digits", a + 3),
                            )
                        })?
                } else {
                    token.parse::<f64>().map_err(|_| {
                        InputError::at(
                            &self.path,
                            self.line,
                            format!("field {} '{token}': expected a number", a + 3),
                        )
                    })?
                };
            }
            block.states.push(state);
        }
        Ok(Some(block))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<BilliardsInput, String> {
        parse_billiards_input(Path::new("t.in"), text).map_err(|e| e.to_string())
    }

    #[test]
    fn reads_the_handout_sample() {
        let input =
            parse("4\n13\n1\n25\n0 3 5 -1 0\n1 5.05 5 0 0\n2 7.1 5 0 0\n3 9.15 5 0 0").unwrap();
        assert_eq!((input.side, input.radius, input.steps), (13, 1, 25));
        assert_eq!(input.ids, vec![0, 1, 2, 3]);
        assert_eq!(input.x[1], 5.05);
        assert_eq!(input.v[0], [-1.0, 0.0]);
        assert!(input.warnings.is_empty());
    }

    #[test]
    fn headers_are_read_like_stoi() {
        // ids too: "0.0" is 0, as the course's reader has it
        let input = parse("  1 particles\r\n+10\n1\n25 steps\n0.0 5 5 1e-1 -2E0\n\n").unwrap();
        assert_eq!((input.side, input.steps), (10, 25));
        assert_eq!(input.v[0], [0.1, -2.0]);
    }

    #[test]
    fn bad_inputs_name_the_line() {
        let cases = [
            (
                "4\n13\n1\n",
                "t.in:4: missing; expected the number of steps S",
            ),
            (
                "x\n13\n1\n1\n",
                "t.in:1: 'x': expected the number of particles N, an integer",
            ),
            (
                "1\n13\n0\n1\n0 1 1 0 0\n",
                "t.in:3: the radius r is 0; it must be at least 1",
            ),
            (
                "1\n-5\n1\n1\n0 1 1 0 0\n",
                "t.in:2: the side L of the box is -5",
            ),
            (
                "2\n13\n1\n1\n0 1 1 0 0\n",
                "t.in:6: missing; expected particle line 2 of 2",
            ),
            ("1\n13\n1\n1\n0 1 1 0\n", "t.in:5: expected 5 fields"),
            (
                "1\n13\n1\n1\nx 1 1 0 0\n",
                "t.in:5: id 'x': expected an integer",
            ),
            (
                "1\n13\n1\n1\n0 1 abc 0 0\n",
                "t.in:5: field 3 (y) is 'abc'; expected a number",
            ),
            ("1\n13\n1\n1\n0 1 nan 0 0\n", "t.in:5: field 3 (y) is NaN"),
            (
                "2\n13\n1\n1\n0 1 1 0 0\n0 3 3 0 0\n",
                "t.in:6: id 0 was already given on line 5",
            ),
            (
                "2\n13\n1\n1\n0 1 1 0 0\n2 3 3 0 0\n",
                "t.in:6: id 2 is outside 0..2",
            ),
            (
                "1\n99999999999\n1\n1\n",
                "t.in:2: the side L of the box is 99999999999; it must be at most 2147483647 (a C++ int)",
            ),
            (
                "-99999999999\n10\n1\n1\n",
                "t.in:1: the number of particles N is -99999999999; it must be at least 0",
            ),
            (
                "1\n10\n1\n1\n4000000000 1 1 0 0\n",
                "t.in:5: id 4000000000 is outside 0..1",
            ),
        ];
        for (text, expected) in cases {
            let err = parse(text).unwrap_err();
            assert!(
                err.starts_with(expected),
                "{err:?} should start with {expected:?}"
            );
        }
    }

    #[test]
    fn lines_after_the_particles_are_ignored_with_a_warning() {
        let input = parse("1\n13\n1\n1\n0 1 1 0 0\n\n1 2 2 0 0\nmore\n").unwrap();
        assert_eq!(input.ids.len(), 1);
        assert_eq!(input.warnings.len(), 1);
        assert!(
            input.warnings[0].contains("ignored 2 non-blank line(s)"),
            "{:?}",
            input.warnings
        );
        assert!(input.warnings[0].contains("line 7"), "{:?}", input.warnings);
    }

    #[test]
    fn states_print_like_glibc_and_as_bits() {
        let mut out = Vec::new();
        let v = [[-0.0, -1e-12], [2.5e-9, 1.0 / 3.0]];
        write_state(
            &mut out,
            StateFormat::Fixed8,
            7,
            &[1, 0],
            &[0.125, 1e10],
            &[-0.0, 0.000000005],
            &v,
        )
        .unwrap();
        let text = String::from_utf8(out).unwrap();
        assert_eq!(
            text,
            "7 1 0.12500000 0.00000000 0.00000000 -0.00000000\n\
             7 0 10000000000.00000000 0.00000001 0.00000000 0.33333333\n"
        );
        let mut out = Vec::new();
        write_state(
            &mut out,
            StateFormat::Bits,
            1,
            &[0],
            &[1.0],
            &[-2.0],
            &[[0.5, -0.0]],
        )
        .unwrap();
        assert_eq!(
            String::from_utf8(out).unwrap(),
            "1 0 3ff0000000000000 c000000000000000 3fe0000000000000 8000000000000000\n"
        );
    }

    #[test]
    fn trajectories_read_back_in_both_forms() {
        for format in [StateFormat::Fixed8, StateFormat::Bits] {
            let mut out = Vec::new();
            for step in 1..=2 {
                write_state(
                    &mut out,
                    format,
                    step,
                    &[1, 0],
                    &[1.5, 2.0],
                    &[3.0, 4.0],
                    &[[0.25, 0.0], [1.0, -1.0]],
                )
                .unwrap();
            }
            let mut reader = TrajectoryReader::new(Path::new("t"), &out[..], 2);
            let first = reader.next_step().unwrap().unwrap();
            assert_eq!(first.step, 1);
            assert_eq!(first.ids, vec![1, 0]);
            assert_eq!(first.states[1], [2.0, 4.0, 1.0, -1.0]);
            assert_eq!(reader.next_step().unwrap().unwrap().step, 2);
            assert_eq!(reader.next_step().unwrap(), None);
        }
        let mut reader = TrajectoryReader::new(Path::new("t"), &b"1 0 1 1 0 0\n"[..], 2);
        let err = reader.next_step().unwrap_err().to_string();
        assert!(err.contains("ends inside a step"), "{err}");
    }
}
