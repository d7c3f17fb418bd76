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
//! For short-range forces, seed 003's domain decomposition: the box cut into
//! subdomains ([`Decomposition`]), particles moved to the rank that owns their
//! position ([`migrate`]) and the ghosts within cutoff + skin of each subdomain
//! sent to it, periodic images included ([`ghosts`]).
//!
//! What runs distributed so far: the ring-pass direct gravity
//! ([`ring_gravity`]) and the particle exchanges of the decomposition, tested
//! on 2 and 4 ranks. `cellist run` under `mpirun` with more than one rank
//! refuses every model with one message from rank 0 ([`refuse_run`]) until the
//! models' distributed steps are built.

use crate::error::SimError;
use crate::scenario::Scenario;
use cellist::decomposition::Decomposition;
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

/// Particles a rank holds for a distributed short-range run: an id and `width`
/// numbers each (the position's `D` coordinates first, then whatever the model
/// carries: velocities, strengths), as flat columns that travel as they are.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LocalParticles {
    /// Global ids.
    pub ids: Vec<u64>,
    /// `width` numbers per particle.
    pub values: Vec<f64>,
    /// Numbers per particle.
    pub width: usize,
}

impl LocalParticles {
    /// The position of particle `k` (its first `D` numbers).
    pub fn position<const D: usize>(&self, k: usize) -> [f64; D] {
        std::array::from_fn(|d| self.values[k * self.width + d])
    }

    /// The number of particles.
    pub fn len(&self) -> usize {
        self.ids.len()
    }

    /// True with no particle.
    pub fn is_empty(&self) -> bool {
        self.ids.is_empty()
    }

    fn push_from(&mut self, other: &LocalParticles, k: usize, shift: &[f64]) {
        self.ids.push(other.ids[k]);
        let row = &other.values[k * other.width..(k + 1) * other.width];
        self.values.extend_from_slice(row);
        let at = self.values.len() - other.width;
        for (d, s) in shift.iter().enumerate() {
            self.values[at + d] += s;
        }
    }
}

/// Sends `outgoing[r]` to rank `r` and returns what every rank sent here, in rank
/// order (counts first, then the ids and values, non-blocking both ways).
fn exchange<C: Communicator>(
    world: &C,
    outgoing: &[LocalParticles],
    width: usize,
) -> LocalParticles {
    let ranks = world.size() as usize;
    let counts: Vec<u64> = outgoing.iter().map(|o| o.len() as u64).collect();
    let mut incoming_counts = vec![0u64; ranks];
    world.all_to_all_into(&counts[..], &mut incoming_counts[..]);
    let mut ids: Vec<Vec<u64>> = incoming_counts
        .iter()
        .map(|&c| vec![0; c as usize])
        .collect();
    let mut values: Vec<Vec<f64>> = incoming_counts
        .iter()
        .map(|&c| vec![0.0; c as usize * width])
        .collect();
    mpi::request::scope(|scope| {
        let (mut id_requests, mut value_requests) = (Vec::new(), Vec::new());
        let (mut id_receives, mut value_receives) = (Vec::new(), Vec::new());
        for (r, (o, (i, v))) in outgoing
            .iter()
            .zip(ids.iter_mut().zip(values.iter_mut()))
            .enumerate()
        {
            let process = world.process_at_rank(r as i32);
            if !o.is_empty() {
                id_requests.push(process.immediate_send(scope, &o.ids[..]));
                value_requests.push(process.immediate_send(scope, &o.values[..]));
            }
            if !i.is_empty() {
                id_receives.push(process.immediate_receive_into(scope, &mut i[..]));
                value_receives.push(process.immediate_receive_into(scope, &mut v[..]));
            }
        }
        for r in id_receives {
            r.wait();
        }
        for r in value_receives {
            r.wait();
        }
        for r in id_requests {
            r.wait();
        }
        for r in value_requests {
            r.wait();
        }
    });
    LocalParticles {
        ids: ids.concat(),
        values: values.concat(),
        width,
    }
}

/// Moves every particle to the rank that owns its (wrapped) position: the
/// migration at a neighbour-list rebuild. Kept particles stay in their order,
/// arrivals follow in rank order.
pub fn migrate<C: Communicator, const D: usize>(
    world: &C,
    decomposition: &Decomposition<D>,
    particles: &mut LocalParticles,
) {
    let width = particles.width;
    let ranks = world.size() as usize;
    let rank = world.rank() as usize;
    let mut staying = LocalParticles {
        width,
        ..LocalParticles::default()
    };
    let mut outgoing = vec![
        LocalParticles {
            width,
            ..LocalParticles::default()
        };
        ranks
    ];
    let none = [0.0; D];
    for k in 0..particles.len() {
        let x = decomposition.domain.wrap(particles.position::<D>(k));
        let owner = decomposition.owner(&x);
        let target = if owner == rank {
            &mut staying
        } else {
            &mut outgoing[owner]
        };
        target.push_from(particles, k, &none);
        let at = target.values.len() - width;
        target.values[at..at + D].copy_from_slice(&x);
    }
    let arrived = exchange(world, &outgoing, width);
    staying.ids.extend_from_slice(&arrived.ids);
    staying.values.extend_from_slice(&arrived.values);
    *particles = staying;
}

/// The ghosts of this rank: every particle of another rank (or a periodic image
/// of one of its own) within `reach` of its subdomain, positions shifted to the
/// image next to it ([`Decomposition::ghosts`]), in the order of the sending
/// ranks.
pub fn ghosts<C: Communicator, const D: usize>(
    world: &C,
    decomposition: &Decomposition<D>,
    particles: &LocalParticles,
    reach: f64,
) -> LocalParticles {
    let width = particles.width;
    let rank = world.rank() as usize;
    let positions: Vec<[f64; D]> = (0..particles.len())
        .map(|k| particles.position(k))
        .collect();
    let mut outgoing = vec![
        LocalParticles {
            width,
            ..LocalParticles::default()
        };
        world.size() as usize
    ];
    for g in decomposition.ghosts(rank, &positions, reach) {
        outgoing[g.to].push_from(particles, g.index, &g.shift);
    }
    exchange(world, &outgoing, width)
}
