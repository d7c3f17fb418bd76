//! Seed 003's ring for all-pairs sums: each of the `P` ranks holds a block of
//! the particles, and in `P` stages every rank adds the field of the block it
//! holds at its own particles while it passes that block to rank `+1` and
//! receives the next from rank `-1` (non-blocking send and receive, overlapped
//! with the sums). With `n = N/P` particles per rank a stage costs
//! `t_comp ~ gamma n^2` against `t_comm ~ alpha + beta n`: the communication is
//! hidden once `gamma n^2 > alpha + beta n`.
//!
//! [`RingGravity`] is the engine's direct gravity made distributed. Gravity's
//! bodies are divided among the ranks ([`super::gravity`]): each rank sums the
//! field at its own bodies over every rank's by the ring. (The vortex model,
//! whose particles every rank holds, deals its direct sum's pairs out among
//! the ranks instead: [`super::pairs`].)

use super::parts::Figures;
use cellist::interactions::GravityLaw;
use cellist::longrange::{FieldOut, FieldSolver, PartialField, Sources};
use cellist::Threads;
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;
use std::time::{Duration, Instant};

/// Passes every rank's `block` (a few numbers per particle) round the ring:
/// `visit(held, own)` is called with each rank's block in turn, this rank's
/// own first, while the next block is on its way. Returns the time spent
/// waiting for the messages after the sums.
pub fn ring_pass<C: Communicator>(
    world: &C,
    block: &[f64],
    mut visit: impl FnMut(&[f64], bool),
) -> Duration {
    let ranks = world.size();
    let rank = world.rank();
    let mut counts = vec![0u64; ranks as usize];
    world.all_gather_into(&(block.len() as u64), &mut counts[..]);
    let most = counts.iter().copied().max().unwrap_or(0) as usize;
    let (next, previous) = ((rank + 1) % ranks, (rank + ranks - 1) % ranks);
    let mut held: Vec<f64> = Vec::with_capacity(most);
    held.extend_from_slice(block);
    let mut incoming: Vec<f64> = Vec::with_capacity(most);
    let mut waited = Duration::ZERO;
    for stage in 0..ranks {
        let own = stage == 0;
        if stage + 1 == ranks {
            visit(&held, own);
            break;
        }
        // the block that arrives now left rank - stage - 1 at stage 0
        let from = (rank - stage - 1).rem_euclid(ranks) as usize;
        incoming.resize(counts[from] as usize, 0.0);
        mpi::request::scope(|scope| {
            let send = world.process_at_rank(next).immediate_send(scope, &held[..]);
            let receive = world
                .process_at_rank(previous)
                .immediate_receive_into(scope, &mut incoming[..]);
            visit(&held, own);
            let t = Instant::now();
            receive.wait();
            send.wait();
            waited += t.elapsed();
        });
        std::mem::swap(&mut held, &mut incoming);
    }
    waited
}

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
    let (acc, phi, _) = ring_gravity_timed(world, law, position, mass, threads);
    (acc, phi)
}

/// [`ring_gravity`] and the time spent waiting for the ring's messages.
fn ring_gravity_timed<C: Communicator>(
    world: &C,
    law: GravityLaw,
    position: &[[f64; 3]],
    mass: &[f64],
    threads: &Threads,
) -> (Vec<[f64; 3]>, Vec<f64>, Duration) {
    assert_eq!(position.len(), mass.len());
    let n = mass.len();
    let block: Vec<f64> = position
        .iter()
        .zip(mass)
        .flat_map(|(x, &m)| [x[0], x[1], x[2], m])
        .collect();
    let mut partial = PartialField::new(law, n);
    let (mut held_position, mut held_mass) = (Vec::new(), Vec::new());
    let waited = ring_pass(world, &block, |held, own| {
        held_position.clear();
        held_mass.clear();
        for body in held.chunks_exact(4) {
            held_position.push([body[0], body[1], body[2]]);
            held_mass.push(body[3]);
        }
        let sources = Sources {
            mass: &held_mass,
            position: &held_position,
        };
        partial.add(position, &sources, own, threads);
    });
    let mut acc = vec![[0.0; 3]; n];
    let mut phi = vec![0.0; n];
    partial.finish(FieldOut {
        acc: &mut acc,
        phi: &mut phi,
    });
    (acc, phi, waited)
}

/// The blocks `n` particles are cut into on the ranks of `world`: rank `r`
/// sums for the particles `bounds[r]..bounds[r + 1]`, `bounds[r] = n r / P`;
/// and this rank's block.
pub(crate) fn blocks(n: usize, world: &SimpleCommunicator) -> (Vec<usize>, std::ops::Range<usize>) {
    let (rank, ranks) = (world.rank() as usize, world.size() as usize);
    let bounds: Vec<usize> = (0..=ranks).map(|r| n * r / ranks).collect();
    let mine = bounds[rank]..bounds[rank + 1];
    (bounds, mine)
}

/// Gravity's direct sum by the ring pass: the engine's [`FieldSolver`] for a
/// run whose bodies are divided among the ranks. Each rank computes with its
/// own bodies as the sources it is given, and gets their field due to every
/// rank's bodies ([`ring_gravity`]).
pub struct RingGravity {
    world: SimpleCommunicator,
    law: GravityLaw,
    figures: Figures,
}

impl RingGravity {
    /// The solver for `law` on the ranks of `world`.
    pub fn new(world: SimpleCommunicator, law: GravityLaw) -> Self {
        RingGravity {
            world,
            law,
            figures: Figures::new("Ring pass", "waiting for blocks"),
        }
    }

    /// The figures, shared: the time spent waiting for the ring's blocks.
    pub fn figures(&self) -> Figures {
        self.figures.clone()
    }
}

impl std::fmt::Debug for RingGravity {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "RingGravity on {} ranks", self.world.size())
    }
}

impl FieldSolver for RingGravity {
    /// Collective: every rank calls it with its own bodies as `sources`.
    fn compute(&mut self, sources: &Sources, out: FieldOut, threads: &Threads) {
        let (acc, phi, waited) = ring_gravity_timed(
            &self.world,
            self.law,
            sources.position,
            sources.mass,
            threads,
        );
        out.acc.copy_from_slice(&acc);
        out.phi.copy_from_slice(&phi);
        self.figures.add_wait(waited);
    }
}
