//! Why a table cannot be set up or a step cannot finish, and the words that say it
//! (also in the driver's blow-up messages).

use std::fmt;

/// Why a table cannot be set up or a step cannot finish.
#[derive(Clone, Debug, PartialEq)]
pub enum BilliardsError {
    /// The radius or the side is not positive, or `(2r)^2` does not fit.
    Table(String),
    /// Position and velocity arrays of different lengths, or a non-finite value.
    State(String),
    /// A disc's position overflowed to infinity.
    Overflow {
        /// The step.
        step: u64,
        /// Its vector position.
        index: usize,
    },
    /// A component of the overlap graph was still changing after the sweep bound.
    NotConverged {
        /// The step.
        step: u64,
        /// The sweep bound.
        sweeps: u64,
        /// The smallest vector position in that component.
        first: usize,
        /// Its size.
        size: usize,
    },
}

impl fmt::Display for BilliardsError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            BilliardsError::Table(m) | BilliardsError::State(m) => f.write_str(m),
            BilliardsError::Overflow { step, index } => {
                write!(f, "step {step}: {}", overflow_what(*index))
            }
            BilliardsError::NotConverged {
                step,
                sweeps,
                first,
                size,
            } => write!(
                f,
                "step {step}: {}",
                not_converged_what(*sweeps, *first, *size)
            ),
        }
    }
}

impl std::error::Error for BilliardsError {}

pub(super) fn overflow_what(index: usize) -> String {
    format!("the position of particle {index} (vector position) overflowed")
}

pub(super) fn not_converged_what(sweeps: u64, first: usize, size: usize) -> String {
    format!(
        "the collisions did not settle within {sweeps} sweeps (a group of {size} overlapping \
         particles, the first at vector position {first})"
    )
}
