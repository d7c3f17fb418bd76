//! Input errors that say where: file, line, what was expected.

use std::fmt;
use std::path::{Path, PathBuf};

/// A problem with an input file: which file, which line (1-based) if any, and what
/// was wrong or expected there.
#[derive(Debug)]
pub struct InputError {
    /// The file.
    pub path: PathBuf,
    /// The 1-based line, when the problem is on one line.
    pub line: Option<usize>,
    /// What was found and what was expected.
    pub message: String,
}

impl InputError {
    /// An error on `line` (1-based) of `path`.
    pub fn at(path: &Path, line: usize, message: impl Into<String>) -> Self {
        InputError {
            path: path.to_path_buf(),
            line: Some(line),
            message: message.into(),
        }
    }

    /// An error about the whole file.
    pub fn file(path: &Path, message: impl Into<String>) -> Self {
        InputError {
            path: path.to_path_buf(),
            line: None,
            message: message.into(),
        }
    }
}

impl fmt::Display for InputError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.line {
            Some(line) => write!(f, "{}:{}: {}", self.path.display(), line, self.message),
            None => write!(f, "{}: {}", self.path.display(), self.message),
        }
    }
}

impl std::error::Error for InputError {}

/// The data lines of `text`: `(0-based line index, tokens)` for every line that is
/// neither blank nor a `#` comment, the tokens split at commas and whitespace.
pub fn data_lines(text: &str) -> impl Iterator<Item = (usize, Vec<&str>)> {
    text.lines()
        .enumerate()
        .filter_map(|(index, raw)| data_line(raw).map(|tokens| (index, tokens)))
}

/// The tokens of one line of [`data_lines`], `None` for a blank line or a `#`
/// comment.
pub fn data_line(raw: &str) -> Option<Vec<&str>> {
    let line = raw.trim();
    (!line.is_empty() && !line.starts_with('#')).then(|| {
        line.split(|c: char| c == ',' || c.is_whitespace())
            .filter(|t| !t.is_empty())
            .collect()
    })
}

/// Parses one number of a line, refusing text, NaN and infinities.
pub fn parse_finite(
    path: &Path,
    line: usize,
    token: &str,
    what: impl FnOnce() -> String,
) -> Result<f64, InputError> {
    match token.parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(v),
        Ok(v) => Err(InputError::at(
            path,
            line,
            format!("{} is {v}; expected a finite number", what()),
        )),
        Err(_) => Err(InputError::at(
            path,
            line,
            format!("{} is '{token}'; expected a number", what()),
        )),
    }
}
