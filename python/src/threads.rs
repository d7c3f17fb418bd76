//! The worker threads of a call.

use crate::errors::value_error;
use cellist_sim::Threads;
use pyo3::prelude::*;

/// A pool of `threads` workers; `None` gives one per core of the machine.
pub fn pool(threads: Option<usize>) -> PyResult<Threads> {
    let count = match threads {
        Some(0) => {
            return Err(value_error(
                "threads must be >= 1 (or None for one per core)",
            ))
        }
        Some(n) => n,
        None => std::thread::available_parallelism().map_or(1, |n| n.get()),
    };
    Threads::new(count).map_err(|e| value_error(format!("cannot start {count} threads: {e}")))
}
