//! How a run fails: a message for the user and the kind of failure, which the
//! command line turns into an exit status.

use std::fmt;

/// A failure of a run.
#[derive(Debug)]
pub enum SimError {
    /// Bad input: a scenario, a file, a checkpoint or a value the user gave.
    Input(String),
    /// Writing a result failed.
    Output(std::io::Error, String),
    /// The simulation blew up or lost particles; the message names the step, the
    /// particle, the quantity and where the last good state was written.
    BlowUp(String),
    /// A self-check failed: a bug, not the user's input.
    Internal(String),
}

impl SimError {
    /// An output error with what was being written.
    pub fn output(what: impl Into<String>) -> impl FnOnce(std::io::Error) -> SimError {
        let what = what.into();
        move |e| SimError::Output(e, what)
    }

    /// An error of the chart drawn to `path` (the plotting library reports text).
    pub fn chart(path: &std::path::Path) -> impl FnOnce(String) -> SimError + '_ {
        move |e| SimError::Output(std::io::Error::other(e), path.display().to_string())
    }
}

impl fmt::Display for SimError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SimError::Input(m) | SimError::BlowUp(m) => f.write_str(m),
            SimError::Internal(m) => write!(f, "internal check failed (a bug in cellist): {m}"),
            SimError::Output(e, what) => write!(f, "cannot write {what}: {e}"),
        }
    }
}

impl std::error::Error for SimError {}

impl From<cellist_io::InputError> for SimError {
    fn from(e: cellist_io::InputError) -> Self {
        SimError::Input(e.to_string())
    }
}

/// `value` of the flag `flag` if it is finite and positive, else the input
/// error `<flag> must be a finite number > 0, got <value>`.
pub(crate) fn positive(flag: &str, value: f64) -> SimResult<f64> {
    if value.is_finite() && value > 0.0 {
        Ok(value)
    } else {
        Err(SimError::Input(format!(
            "{flag} must be a finite number > 0, got {value}"
        )))
    }
}

/// Shorthand for results of the simulation layer.
pub type SimResult<T = ()> = Result<T, SimError>;
