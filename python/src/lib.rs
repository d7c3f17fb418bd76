//! The Python module of cellist (`cellist._cellist`, re-exported by the
//! `cellist` package): neighbour lists and simulations, numpy in, numpy out.
//! It calls the simulation layer (`cellist-sim`) alone; no physics is written here.

mod errors;
mod neighbors;
mod simulation;
mod threads;

use pyo3::prelude::*;

/// The compiled part of the `cellist` package.
#[pymodule]
fn _cellist(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(neighbors::neighbors, m)?)?;
    m.add_class::<neighbors::NeighborList>()?;
    m.add_class::<simulation::Simulation>()?;
    m.add_function(wrap_pyfunction!(simulation::_unpickle, m)?)?;
    m.add("BlowUp", m.py().get_type::<errors::BlowUp>())?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
