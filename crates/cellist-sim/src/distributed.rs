//! Distributed runs on MPI (cargo feature `mpi`).
//!
//! For all-pairs forces, seed 003's ring: each of the `P` ranks holds a block of
//! the particles, and in `P` stages every rank computes the field of the block
//! it holds on its own particles while it passes that block to rank `+1` and
//! receives the next from rank `-1` (non-blocking send and receive, overlapped
//! with the computation). With `n = N/P` particles per rank, a stage costs
//! `t_comp ~ gamma n^2` against `t_comm ~ alpha + beta n`: the communication is
//! hidden once `gamma n^2 > alpha + beta n`.
//!
//! What runs distributed so far: the ring-pass direct gravity
//! ([`ring_gravity`]). `cellist run` under `mpirun` with more than one rank
//! refuses every model with one message from rank 0 ([`refuse_run`]) until the
//! models' distributed steps are built.

use crate::error::SimError;
use crate::scenario::Scenario;
use cellist::interactions::GravityLaw;
use cellist::longrange::{FieldOut, PartialField, Sources};
use cellist::Threads;
use mpi::traits::*;
use std::path::Path;

/// The accelerations and potentials of this rank's bodies (`position`, `mass`)
/// due to every body of every rank, by the ring pass. Every rank calls it with
/// its own block; the sums are those of the direct sum up to rounding (each
/// body's sum runs over the blocks in ring order, its own first).
pub fn ring_gravity<C: Communicator>(
    world: &C,
    law: GravityLaw,
    position: &[[f64; 3]],
    mass: &[f64],
    threads: &Threads,
) -> (Vec<[f64; 3]>, Vec<f64>) {
    assert_eq!(position.len(), mass.len());
    let ranks = world.size();
    let rank = world.rank();
    let n = mass.len();
    let mut counts = vec![0u64; ranks as usize];
    world.all_gather_into(&(n as u64), &mut counts[..]);
    let most = counts.iter().copied().max().unwrap_or(0) as usize;
    let (next, previous) = ((rank + 1) % ranks, (rank + ranks - 1) % ranks);
    let mut held_position: Vec<[f64; 3]> = Vec::with_capacity(most);
    let mut held_mass: Vec<f64> = Vec::with_capacity(most);
    held_position.extend_from_slice(position);
    held_mass.extend_from_slice(mass);
    let mut incoming_position: Vec<[f64; 3]> = Vec::with_capacity(most);
    let mut incoming_mass: Vec<f64> = Vec::with_capacity(most);
    let mut partial = PartialField::new(law, n);
    for stage in 0..ranks {
        let sources = Sources {
            mass: &held_mass,
            position: &held_position,
        };
        let own = stage == 0;
        if stage + 1 == ranks {
            partial.add(position, &sources, own, threads);
            break;
        }
        // the block that arrives now left rank - stage - 1 at stage 0
        let from = (rank - stage - 1).rem_euclid(ranks) as usize;
        incoming_position.resize(counts[from] as usize, [0.0; 3]);
        incoming_mass.resize(counts[from] as usize, 0.0);
        mpi::request::scope(|scope| {
            let to_next = world.process_at_rank(next);
            let from_previous = world.process_at_rank(previous);
            let send_x = to_next.immediate_send(scope, held_position.as_flattened());
            let send_m = to_next.immediate_send(scope, &held_mass[..]);
            let receive_x =
                from_previous.immediate_receive_into(scope, incoming_position.as_flattened_mut());
            let receive_m = from_previous.immediate_receive_into(scope, &mut incoming_mass[..]);
            partial.add(position, &sources, own, threads);
            receive_x.wait();
            receive_m.wait();
            send_x.wait();
            send_m.wait();
        });
        std::mem::swap(&mut held_position, &mut incoming_position);
        std::mem::swap(&mut held_mass, &mut incoming_mass);
    }
    let mut acc = vec![[0.0; 3]; n];
    let mut phi = vec![0.0; n];
    partial.finish(FieldOut {
        acc: &mut acc,
        phi: &mut phi,
    });
    (acc, phi)
}

/// MPI in this process: initialised once by [`Cluster::start`], finalised when
/// dropped.
pub struct Cluster {
    universe: mpi::environment::Universe,
}

impl Cluster {
    /// Initialises MPI (under `mpirun`, or as a single rank without it); `None`
    /// if it was initialised before in this process.
    pub fn start() -> Option<Self> {
        mpi::initialize().map(|universe| Cluster { universe })
    }

    /// The number of ranks.
    pub fn ranks(&self) -> i32 {
        self.universe.world().size()
    }

    /// This process's rank.
    pub fn rank(&self) -> i32 {
        self.universe.world().rank()
    }

    /// [`refuse_run`] on every rank of this cluster.
    pub fn refuse_run(&self, scenario: Option<&Path>, sets: &[String]) -> SimError {
        refuse_run(&self.universe.world(), scenario, sets)
    }
}

/// `cellist run` on more than one rank: every rank reads the scenario, and
/// rank 0 says once why the run cannot go on (a rank that cannot read its
/// input, or a model not distributed yet). Every rank returns the same error,
/// so that every rank stops with a non-zero status and none waits for another.
pub fn refuse_run<C: Communicator>(
    world: &C,
    scenario: Option<&Path>,
    sets: &[String],
) -> SimError {
    let read = Scenario::load(scenario, sets).and_then(|s| s.model());
    let mut first_failed = 0i32;
    // the lowest rank that failed (ranks that read it report size)
    let mine = if read.is_err() {
        world.rank()
    } else {
        world.size()
    };
    world.all_reduce_into(
        &mine,
        &mut first_failed,
        mpi::collective::SystemOperation::min(),
    );
    let message = if first_failed < world.size() {
        match &read {
            Err(e) if first_failed == world.rank() => e.to_string(),
            _ => format!(
                "rank {first_failed} cannot read its input (do all ranks see the same files?)"
            ),
        }
    } else {
        format!(
            "model '{}' does not run on {} MPI ranks yet: run it in one process (without \
             mpirun, or with -np 1); distributed md, pse, gravity and vortex steps are not built",
            read.as_deref().unwrap_or("?"),
            world.size()
        )
    };
    SimError::Input(message)
}
