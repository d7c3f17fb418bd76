//! What the simulation layer asks of a model beyond the engine's [`Model`]
//! contract: the line it prints on the loop's speed, what a model spread over
//! MPI ranks measures of its distribution, and the per-particle arrays a Python
//! session may set. Each model's file under `models/` (and the distributed
//! models under `distributed/`) implements it for its model.

use cellist::models::Model;
use cellist::state::{Layout, SectionSink, State};
use cellist::Threads;
use std::time::Duration;

/// What a checkpoint file holds of a model's state ([`Hosted::file_state`]).
pub enum FileState<'a> {
    /// The state just saved or restored, as it is.
    Saved(&'a State),
    /// A state spread over ranks, written on rank 0 without being held
    /// whole: its sections' layout, and what appends their bytes a block of
    /// particles at a time (pulling them from the ranks, in id order, until
    /// the sink has failed). It is not called when the file cannot be
    /// created (the other ranks serve pulls until rank 0's outputs are done,
    /// however many it makes).
    Spread(Layout, FillSections<'a>),
}

/// What appends a spread state's sections' bytes ([`FileState::Spread`]).
pub type FillSections<'a> = Box<dyn FnOnce(&mut dyn SectionSink) + 'a>;

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

    /// On a rank of a model spread over MPI ranks (md and pse by domain
    /// decomposition, gravity's divided bodies), its communication time and
    /// load imbalance; `None` for a model held in one process (or whole on
    /// every rank: a replicated solver's figures are its
    /// [`Ranks`](crate::ranks::Ranks)').
    fn distribution(&self) -> Option<Distribution> {
        None
    }

    /// Before each step this rank observes ([`Model::step_observed`]):
    /// whether an output reads per-particle energies after it (a dump with
    /// energy columns; false on the ranks that write no output, whose wish a
    /// spread model all-reduces with rank 0's). A model whose per-particle
    /// energies cost a pass of their own that its thermo does not need (the
    /// distributed md's half list) makes that pass only when some rank wants
    /// them; the others compute them anyway, or when read.
    fn want_particle_energies(&mut self, _wanted: bool) {}

    /// On a rank of a model spread over MPI ranks, after each step that any
    /// rank observed (and after a restore): rank 0, whose outputs pull the
    /// particles from every rank, tells the others that its outputs are
    /// written; the other ranks serve its pulls until then. Every rank calls
    /// it at the same points of the run. Nothing for a model held in one
    /// process or whole on every rank.
    fn serve_outputs(&self) {}

    /// True when the model's own step ends with [`check`] of its values,
    /// agreed over the ranks (a model spread over MPI ranks, whose ranks
    /// must stop together): the driver then does not check again, its
    /// particle count included, so a model that says true checks its count
    /// itself (the distributed md's count may change on a rank; its total
    /// is checked at every migration).
    ///
    /// [`check`]: cellist::models::check
    fn checks_its_steps(&self) -> bool {
        false
    }

    /// On a model spread over MPI ranks: true after a step that any rank
    /// observed (and after a restore). Every rank then keeps its own part of
    /// the state as the last good one ([`Model::save`]), at the same steps,
    /// so that no rank holds the whole state. False for a model held in one
    /// process or whole on every rank.
    fn observed_everywhere(&self) -> bool {
        false
    }

    /// The state a checkpoint file holds, given `saved`, the state this
    /// model has just saved or restored: `saved` itself, except for a model
    /// spread over ranks, whose rank 0 writes the global state of every
    /// rank's part a block at a time (the other ranks serving it,
    /// [`Hosted::serve_outputs`]).
    fn file_state<'a>(&'a self, saved: &'a State) -> FileState<'a> {
        FileState::Saved(saved)
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
