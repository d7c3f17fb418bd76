//! How the tool fails: a message for the user and an exit status.

use std::fmt;

/// A failure of one command.
#[derive(Debug)]
pub enum CliError {
    /// Bad input: a file, a flag or a value the user gave (exit status 2).
    Input(String),
    /// Writing a result failed (exit status 1).
    Output(std::io::Error, String),
    /// A self-check of the tool failed: a bug, not the user's input (exit status 1).
    Internal(String),
    /// A simulation stopped: it blew up or left its box (exit status 3).
    Run(String),
    /// A check found a fault: the verdict, printed as it is on standard output
    /// (exit status 1).
    Rejected(String),
}

impl CliError {
    /// The process exit status for this error.
    pub fn exit_code(&self) -> u8 {
        match self {
            CliError::Input(_) => 2,
            CliError::Run(_) => 3,
            CliError::Output(..) | CliError::Internal(_) | CliError::Rejected(_) => 1,
        }
    }

    /// True when the reader of our output went away (`cellist ... | head`).
    pub fn is_broken_pipe(&self) -> bool {
        matches!(self, CliError::Output(e, _) if e.kind() == std::io::ErrorKind::BrokenPipe)
    }
}

impl fmt::Display for CliError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            CliError::Input(m) | CliError::Run(m) | CliError::Rejected(m) => f.write_str(m),
            CliError::Internal(m) => write!(f, "internal check failed (a bug in cellist): {m}"),
            CliError::Output(e, what) => write!(f, "cannot write {what}: {e}"),
        }
    }
}

impl From<cellist_sim::SimError> for CliError {
    fn from(e: cellist_sim::SimError) -> Self {
        use cellist_sim::SimError;
        match e {
            SimError::Input(m) => CliError::Input(m),
            SimError::Output(e, what) => CliError::Output(e, what),
            SimError::BlowUp(m) => CliError::Run(m),
            SimError::Internal(m) => CliError::Internal(m),
        }
    }
}

/// Shorthand for command results.
pub type CliResult<T = ()> = Result<T, CliError>;

/// A thread pool for `--threads` (default: every core).
pub fn threads(requested: Option<usize>) -> CliResult<cellist_sim::Threads> {
    let count = match requested {
        Some(0) => return Err(CliError::Input("--threads must be at least 1".into())),
        Some(n) => n,
        None => (cellist_sim::study::cores() / ranks_on_this_machine()).max(1),
    };
    cellist_sim::Threads::new(count)
        .map_err(|e| CliError::Input(format!("cannot start {count} threads: {e}")))
}

/// The MPI ranks started on this machine, as Open MPI or MPICH tell them (1
/// outside mpirun): ranks on one machine share its cores.
fn ranks_on_this_machine() -> usize {
    ["OMPI_COMM_WORLD_LOCAL_SIZE", "MPI_LOCALNRANKS"]
        .iter()
        .find_map(|k| std::env::var(k).ok()?.parse().ok())
        .unwrap_or(1usize)
        .max(1)
}
