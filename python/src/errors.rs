//! The module's exceptions: `ValueError` for bad input with the CLI's message,
//! `OSError` for a file that could not be written, `cellist.BlowUp` for a run
//! that blew up (with its step, particle and quantity), `RuntimeError` for a
//! failed self-check.

use cellist_sim::Blowup;
use cellist_sim::SimError;
use pyo3::exceptions::{PyOSError, PyRuntimeError, PyValueError};
use pyo3::prelude::*;

pyo3::create_exception!(
    cellist,
    BlowUp,
    pyo3::exceptions::PyRuntimeError,
    "The simulation blew up: a value stopped being finite, a particle left the box through \
     a wall, or the particle count changed. Attributes: step (the step that failed), particle \
     (the id to blame, or None), quantity and value (the quantity and its value, or None). \
     The simulation went back to its last good state, whose frame and checkpoint were written."
);

/// A `ValueError` with `message`.
pub fn value_error(message: impl Into<String>) -> PyErr {
    PyValueError::new_err(message.into())
}

/// The Python exception of a failed run; `blowup` describes a blow-up.
pub fn sim_error(py: Python<'_>, error: SimError, blowup: Option<Blowup>) -> PyErr {
    match error {
        SimError::Input(m) => PyValueError::new_err(m),
        SimError::Output(e, what) => PyOSError::new_err(format!("cannot write {what}: {e}")),
        SimError::Internal(m) => {
            PyRuntimeError::new_err(format!("internal check failed (a bug in cellist): {m}"))
        }
        SimError::BlowUp(m) => {
            let err = BlowUp::new_err(m);
            let value = err.value(py);
            let (step, particle, quantity, amount) = match &blowup {
                Some(b) => (
                    Some(b.step),
                    b.particle,
                    b.value.as_ref().map(|(q, _)| q.clone()),
                    b.value.as_ref().map(|(_, v)| *v),
                ),
                None => (None, None, None, None),
            };
            let set = || -> PyResult<()> {
                value.setattr("step", step)?;
                value.setattr("particle", particle)?;
                value.setattr("quantity", quantity)?;
                value.setattr("value", amount)
            };
            match set() {
                Ok(()) => err,
                Err(e) => e,
            }
        }
    }
}
