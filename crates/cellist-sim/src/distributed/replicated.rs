//! A model whose state every rank holds in full and advances alike, its
//! all-pairs sums divided among the ranks by the ring pass ([`super::ring`]):
//! gravity and the vortex model with their direct solvers. Every rank takes
//! the same steps on the same bits, so the checks agree without messages;
//! rank 0 writes the outputs.

use super::agree;
use super::ring::{RingGravity, RingVortex, Waited};
use cellist::interactions::GravityLaw;
use cellist::longrange::BlobKernel;
use cellist::models::gravity::Solver;
use cellist::models::vortex::VelocityEngine;
use cellist::models::{Blowup, Checked, Field, Model, Particles};
use cellist::state::{State, StateError};
use cellist::Threads;
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;
use std::time::Duration;

/// `model` run alike on every rank of `world`.
pub struct Replicated<M> {
    model: M,
    world: SimpleCommunicator,
    waited: Waited,
}

impl<M: Model> Replicated<M> {
    /// `model` (whose solver is a ring, reporting its waiting time to
    /// `waited`) on the ranks of `world`.
    pub fn new(model: M, world: SimpleCommunicator, waited: Waited) -> Self {
        Replicated {
            model,
            world,
            waited,
        }
    }
}

impl<M: Model> Model for Replicated<M> {
    fn name(&self) -> &'static str {
        self.model.name()
    }

    fn particle_word(&self) -> &'static str {
        self.model.particle_word()
    }

    fn len(&self) -> usize {
        self.model.len()
    }

    fn count_may_change(&self) -> bool {
        self.model.count_may_change()
    }

    fn writes_output(&self) -> bool {
        self.world.rank() == 0
    }

    fn agree(&self, failure: Option<String>) -> Option<String> {
        agree(&self.world, failure)
    }

    fn dt(&self) -> f64 {
        self.model.dt()
    }

    fn step(&mut self, step: u64, observe: bool, threads: &Threads) -> Result<(), Blowup> {
        self.model.step(step, observe, threads)
    }

    fn thermo_columns(&self) -> &'static [&'static str] {
        self.model.thermo_columns()
    }

    fn thermo(&self, step: u64) -> Vec<f64> {
        self.model.thermo(step)
    }

    fn checked(&self) -> Vec<Checked<'_>> {
        self.model.checked()
    }

    fn id_of(&self, index: usize) -> u64 {
        self.model.id_of(index)
    }

    fn walls(&self) -> Vec<(usize, f64, f64)> {
        self.model.walls()
    }

    fn remedy(&self) -> &'static str {
        self.model.remedy()
    }

    fn particles(&self, step: u64, energies: bool) -> Option<Particles> {
        self.model.particles(step, energies)
    }

    fn field(&self) -> Option<Field> {
        self.model.field()
    }

    fn stage_times(&self) -> Vec<(&'static str, Duration)> {
        self.model.stage_times()
    }

    fn speed(&self, loop_seconds: f64, steps: u64, threads: usize) -> String {
        let waited = self.waited.lock().map_or(Duration::ZERO, |w| *w);
        format!(
            "{} (per rank)\nRing pass on {} ranks: {:.4} s on rank 0 waiting for blocks and \
             gathering the results ({:.1}% of the loop)",
            self.model.speed(loop_seconds, steps, threads),
            self.world.size(),
            waited.as_secs_f64(),
            100.0 * waited.as_secs_f64() / loop_seconds.max(1e-300)
        )
    }

    fn save(&self, state: &mut State) {
        self.model.save(state)
    }

    fn restore(&mut self, state: &State, threads: &Threads) -> Result<(), StateError> {
        self.model.restore(state, threads)
    }
}

/// The ranks of a replicated run and the waiting time of its ring.
pub struct Ring {
    world: SimpleCommunicator,
    waited: Waited,
}

impl Ring {
    /// The number of ranks.
    pub fn ranks(&self) -> i32 {
        self.world.size()
    }

    /// `model` run alike on these ranks.
    pub fn wrap<M: Model>(self, model: M) -> Replicated<M> {
        Replicated::new(model, self.world, self.waited)
    }
}

/// On several ranks, gravity's direct solver by the ring pass for `law`, and
/// its ranks; `None` in one process.
pub fn gravity_ring(law: GravityLaw) -> Option<(Solver, Ring)> {
    let world = super::world_of_many()?;
    let solver = RingGravity::new(world.duplicate(), law);
    let waited = solver.waited();
    Some((Solver::External(Box::new(solver)), Ring { world, waited }))
}

/// On several ranks, the vortex model's direct solver by the ring pass for
/// blobs of `kernel`, and its ranks; `None` in one process.
pub fn vortex_ring(kernel: BlobKernel) -> Option<(VelocityEngine, Ring)> {
    let world = super::world_of_many()?;
    let solver = RingVortex::new(world.duplicate(), kernel);
    let waited = solver.waited();
    Some((
        VelocityEngine::External(Box::new(solver)),
        Ring { world, waited },
    ))
}
