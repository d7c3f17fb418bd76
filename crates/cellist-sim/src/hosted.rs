//! What the simulation layer asks of a model beyond the engine's [`Model`]
//! contract: the line it prints on the loop's speed, and the per-particle
//! arrays a Python session may set. Each model's file under `models/` (and the
//! distributed models under `distributed/`) implements it for its model.

use cellist::models::Model;
use cellist::Threads;

/// A model as the simulation layer runs it.
pub trait Hosted: Model {
    /// The line printed after the loop on its speed (`loop_seconds` over
    /// `steps` steps on `threads` threads), in the model's own measure:
    /// microseconds per atom-step, pair kernels per second, steps per second.
    fn speed(&self, loop_seconds: f64, steps: u64, threads: usize) -> String;

    /// Replaces the per-particle array `name` ("positions", "velocities") by
    /// `values`, as many numbers per particle as the model's dimension, in the
    /// order of [`Model::particles`], and recomputes what depends on it. Models
    /// that allow none refuse, naming themselves.
    fn set_array(&mut self, name: &str, values: &[f64], threads: &Threads) -> Result<(), String> {
        let _ = (values, threads);
        Err(format!(
            "model {} does not allow setting its {name}",
            self.info().name
        ))
    }
}
