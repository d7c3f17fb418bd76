//! What the simulation layer asks of a model beyond the engine's [`Model`]
//! contract: the line it prints on the loop's speed, what a model spread over
//! MPI ranks measures of its distribution, and the per-particle arrays a Python
//! session may set. Each model's file under `models/` (and the distributed
//! models under `distributed/`) implements it for its model.

use cellist::models::Model;
use cellist::Threads;
use std::time::Duration;

/// What one rank of a distributed run measures of the distribution: the
/// MPI figures of the run's `summary.json`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Distribution {
    /// The time this rank spent in messages, reductions and waiting for the
    /// other ranks since the model was built.
    pub communication: Duration,
    /// Largest over mean particles per rank (the same on every rank).
    pub imbalance_particles: f64,
    /// The particles over all ranks.
    pub particles: usize,
}

/// A model as the simulation layer runs it.
pub trait Hosted: Model {
    /// The line printed after the loop on its speed (`loop_seconds` over
    /// `steps` steps on `threads` threads), in the model's own measure:
    /// microseconds per atom-step, pair kernels per second, steps per second.
    fn speed(&self, loop_seconds: f64, steps: u64, threads: usize) -> String;

    /// On a rank of a model spread over MPI ranks (domain decomposition), its
    /// communication time and load imbalance; `None` for a model held in one
    /// process (or whole on every rank: the ring's figures are its
    /// [`Ranks`](crate::ranks::Ranks)').
    fn distribution(&self) -> Option<Distribution> {
        None
    }

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
