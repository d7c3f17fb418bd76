//! What the solvers of a replicated run share: each rank computes the sums of
//! its part of the particles, the parts' results are all-gathered into every
//! rank ([`all_gather_parts`]), and the run reports the time spent in messages
//! and the balance of the parts ([`Figures`]).

use mpi::datatype::PartitionMut;
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;
use mpi::Count;
use std::sync::{Arc, Mutex};
use std::time::Duration;

/// Fills `out` (`width` numbers per particle, every rank's part in rank order,
/// rank `r`'s the particles `bounds[r]..bounds[r + 1]`) with every rank's
/// `own` values (this rank's part): `all_gather_varcount`.
pub fn all_gather_parts(
    world: &SimpleCommunicator,
    own: &[f64],
    width: usize,
    bounds: &[usize],
    out: &mut [f64],
) {
    let counts: Vec<Count> = bounds
        .windows(2)
        .map(|b| ((b[1] - b[0]) * width) as Count)
        .collect();
    let displacements: Vec<Count> = bounds[..bounds.len() - 1]
        .iter()
        .map(|&b| (b * width) as Count)
        .collect();
    let mut partition = PartitionMut::new(out, counts, &displacements[..]);
    world.all_gather_varcount_into(own, &mut partition);
}

/// Largest over mean particles per part of the parts cut at `bounds` (the
/// first 0, the last the particle count).
pub fn imbalance(bounds: &[usize]) -> f64 {
    let parts = bounds.len() - 1;
    let most = bounds.windows(2).map(|b| b[1] - b[0]).max().unwrap_or(0);
    let n = bounds[parts] - bounds[0];
    most as f64 * parts as f64 / n.max(1) as f64
}

/// What a solver whose sums are divided among the ranks measures on this
/// rank, shared with what reports it (a replicated run's
/// [`Ranks`](crate::ranks::Ranks), or the model of gravity's divided bodies):
/// how the sums are
/// divided (for the speed line), the time spent in messages and waiting for
/// the other ranks, and the balance of the parts, per evaluation.
#[derive(Clone, Debug)]
pub struct Figures {
    /// How the sums are divided, e.g. "Ring pass".
    pub method: &'static str,
    /// What the waiting time is spent on.
    pub waiting: &'static str,
    tally: Arc<Mutex<Tally>>,
}

/// [`Figures`]' sums.
#[derive(Debug, Default)]
struct Tally {
    waited: Duration,
    imbalance: f64,
    evaluations: u64,
}

impl Figures {
    /// No evaluation yet.
    pub fn new(method: &'static str, waiting: &'static str) -> Self {
        Figures {
            method,
            waiting,
            tally: Arc::default(),
        }
    }

    /// Adds one evaluation that waited `waited` and whose parts were cut at
    /// `bounds` ([`imbalance`]).
    pub fn add(&self, waited: Duration, bounds: &[usize]) {
        if let Ok(mut t) = self.tally.lock() {
            t.waited += waited;
            t.imbalance += imbalance(bounds);
            t.evaluations += 1;
        }
    }

    /// Adds `waited` to the time in messages, no evaluation counted (a
    /// solver whose parts are not particles, a mesh's slabs; or the ring of
    /// gravity's divided bodies, whose model keeps their balance).
    pub fn add_wait(&self, waited: Duration) {
        if let Ok(mut t) = self.tally.lock() {
            t.waited += waited;
        }
    }

    /// The time waited so far.
    pub fn waited(&self) -> Duration {
        self.tally.lock().map_or(Duration::ZERO, |t| t.waited)
    }

    /// The mean over the evaluations of largest over mean particles per part
    /// (1 before the first).
    pub fn imbalance(&self) -> f64 {
        self.tally.lock().map_or(1.0, |t| {
            if t.evaluations == 0 {
                1.0
            } else {
                t.imbalance / t.evaluations as f64
            }
        })
    }
}
