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
//! sent to it, periodic images included ([`ghosts`]); the cut planes equal or
//! placed by the particles ([`balance`]).
//!
//! What runs distributed, on the driver like every model (rank 0 writes the
//! outputs): md and pse by domain decomposition ([`md::DistributedMd`],
//! [`pse::DistributedPse`]); gravity's direct sum, mesh solvers (PM, P3M),
//! Barnes-Hut tree and fmm with the bodies divided among the ranks, summed
//! by the ring pass, on a slab-decomposed mesh, by locally essential trees
//! or by runs of the fmm's target groups over every body gathered
//! ([`gravity::DistributedGravity`], [`ring`], [`mesh`]); the vortex model's
//! direct sums by block pairs dealt out ([`pairs`]), its Barnes-Hut trees
//! by parts of the tree ([`tree`]), its fmm by runs of its target groups
//! ([`replicated::vortex_fmm`]) and the vortex-in-cell velocity (2D and 3D) on a
//! slab-decomposed mesh ([`mesh`]), their
//! state replicated on every rank ([`replicated`]) and their field sums and
//! transforms divided ([`parts`]). Whatever can fail on
//! one rank only is agreed ([`agree`]): every rank stops with the message of
//! the lowest rank that failed, none waits in an exchange.

pub mod gravity;
pub mod md;
pub mod mesh;
pub mod pairs;
pub mod parts;
pub mod pse;
pub mod pull;
pub mod replicated;
pub mod ring;
pub mod tree;

pub use ring::ring_gravity;

use crate::error::SimError;
use crate::scenario::{ModelKind, Scenario};
use cellist::decomposition::{Decomposition, Images};
use cellist::models::Blowup;
use cellist::state::{SectionSource, State, StateError};
use mpi::collective::SystemOperation;
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;
use std::path::Path;

/// MPI in this process: initialised once by [`Cluster::start`], finalised when
/// dropped.
pub struct Cluster {
    universe: mpi::environment::Universe,
}

impl Cluster {
    /// Initialises MPI (under `mpirun`, or as a single rank without it); `None`
    /// if it was initialised before in this process. On several ranks a panic
    /// on any of them then prints its message and aborts every rank
    /// (`MPI_Abort`), instead of
    /// leaving the others waiting in an exchange, or itself in `MPI_Finalize`
    /// while it unwinds.
    pub fn start() -> Option<Self> {
        let universe = mpi::initialize()?;
        if universe.world().size() > 1 {
            let report = std::panic::take_hook();
            std::panic::set_hook(Box::new(move |info| {
                report(info);
                SimpleCommunicator::world().abort(101);
            }));
        }
        Some(Cluster { universe })
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
    pub fn refuse_run(&self, scenario: Option<&Path>, sets: &[String]) -> Option<SimError> {
        refuse_run(&self.universe.world(), scenario, sets)
    }
}

/// `cellist run` on more than one rank: every rank reads the scenario, and
/// unless every rank read it and its model is distributed
/// ([`ModelKind::distributed`]), rank 0 says once why the run cannot go on (a rank
/// that cannot read its input, or a model not distributed yet). Every rank
/// returns the same error, so that every rank stops with a non-zero status and
/// none waits for another.
pub fn refuse_run<C: Communicator>(
    world: &C,
    scenario: Option<&Path>,
    sets: &[String],
) -> Option<SimError> {
    let read = Scenario::load(scenario, sets).and_then(|s| s.model());
    let mut first_failed = 0i32;
    // the lowest rank that failed (ranks that read it report size)
    let mine = if read.is_err() {
        world.rank()
    } else {
        world.size()
    };
    world.all_reduce_into(&mine, &mut first_failed, SystemOperation::min());
    let message = if first_failed < world.size() {
        match &read {
            Err(e) if first_failed == world.rank() => e.to_string(),
            _ => format!(
                "rank {first_failed} cannot read its input (do all ranks see the same files?)"
            ),
        }
    } else {
        let model = read.as_ref().map_or("?", |m| m.name());
        if read.as_ref().is_ok_and(|m| m.distributed()) {
            return None;
        }
        let distributed: Vec<&str> = ModelKind::ALL
            .iter()
            .filter(|m| m.distributed())
            .map(|m| m.name())
            .collect();
        format!(
            "model '{model}' does not run on {} MPI ranks yet: run it in one process (without \
             mpirun, or with -np 1); the models that run distributed are: {}",
            world.size(),
            distributed.join(", ")
        )
    };
    Some(SimError::Input(message))
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

/// Sends `outgoing[r]` to rank `r` and receives `width * incoming[r]` values
/// from rank `r` into `received` (exactly as long as all of them), in rank
/// order (non-blocking both ways; no message for an empty block).
fn swap_blocks<C: Communicator, T: Equivalence>(
    world: &C,
    outgoing: &[Vec<T>],
    incoming: &[usize],
    width: usize,
    received: &mut [T],
) {
    assert_eq!(received.len(), width * incoming.iter().sum::<usize>());
    mpi::request::scope(|scope| {
        let mut requests = Vec::with_capacity(2 * outgoing.len());
        let mut rest = received;
        for (r, (o, &count)) in outgoing.iter().zip(incoming).enumerate() {
            let process = world.process_at_rank(r as i32);
            if !o.is_empty() {
                requests.push(process.immediate_send(scope, &o[..]));
            }
            let (block, tail) = rest.split_at_mut(width * count);
            rest = tail;
            if count > 0 {
                requests.push(process.immediate_receive_into(scope, block));
            }
        }
        for r in requests {
            r.wait();
        }
    });
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
    let incoming: Vec<usize> = incoming_counts.iter().map(|&c| c as usize).collect();
    let ids: Vec<Vec<u64>> = outgoing.iter().map(|o| o.ids.clone()).collect();
    let values: Vec<Vec<f64>> = outgoing.iter().map(|o| o.values.clone()).collect();
    let total: usize = incoming.iter().sum();
    let mut arrived = LocalParticles {
        ids: vec![0; total],
        values: vec![0.0; total * width],
        width,
    };
    swap_blocks(world, &ids, &incoming, 1, &mut arrived.ids);
    swap_blocks(world, &values, &incoming, width, &mut arrived.values);
    arrived
}

/// Particles that move between ranks ([`migrate`]): each travels as its id
/// and a row of numbers, its position first.
pub trait Travellers<const D: usize> {
    /// The particles held.
    fn count(&self) -> usize;
    /// Particle `k`'s position.
    fn position(&self, k: usize) -> [f64; D];
    /// Numbers per travelling row.
    fn width(&self) -> usize;
    /// Appends particle `k`'s id to `ids` and its row to `values`.
    fn pack(&self, k: usize, ids: &mut Vec<u64>, values: &mut Vec<f64>);
    /// Moves particle `from` to slot `to <= from` (whatever was there is
    /// gone) and sets its position to `x`.
    fn keep(&mut self, from: usize, to: usize, x: [f64; D]);
    /// Drops every particle from slot `n` on.
    fn truncate(&mut self, n: usize);
    /// Appends the particles of `ids` and their rows `values`.
    fn push_rows(&mut self, ids: &[u64], values: &[f64]);
}

/// Moves every particle to the rank that owns its (wrapped) position: the
/// migration at a neighbour-list rebuild. Kept particles stay in their order
/// (compacted in place, their positions wrapped), arrivals follow in rank
/// order; only the leaving particles are packed into rows.
pub fn migrate<C: Communicator, const D: usize>(
    world: &C,
    decomposition: &Decomposition<D>,
    particles: &mut impl Travellers<D>,
) {
    let width = particles.width();
    let ranks = world.size() as usize;
    let rank = world.rank() as usize;
    let mut outgoing = vec![
        LocalParticles {
            width,
            ..LocalParticles::default()
        };
        ranks
    ];
    let mut kept = 0;
    for k in 0..particles.count() {
        let x = decomposition.domain.wrap(particles.position(k));
        let owner = decomposition.owner(&x);
        if owner == rank {
            particles.keep(k, kept, x);
            kept += 1;
        } else {
            let target = &mut outgoing[owner];
            particles.pack(k, &mut target.ids, &mut target.values);
            let at = target.values.len() - width;
            target.values[at..at + D].copy_from_slice(&x);
        }
    }
    particles.truncate(kept);
    let arrived = exchange(world, &outgoing, width);
    particles.push_rows(&arrived.ids, &arrived.values);
}

impl<const D: usize> Travellers<D> for LocalParticles {
    fn count(&self) -> usize {
        self.ids.len()
    }

    fn position(&self, k: usize) -> [f64; D] {
        LocalParticles::position(self, k)
    }

    fn width(&self) -> usize {
        self.width
    }

    fn pack(&self, k: usize, ids: &mut Vec<u64>, values: &mut Vec<f64>) {
        ids.push(self.ids[k]);
        values.extend_from_slice(&self.values[k * self.width..(k + 1) * self.width]);
    }

    fn keep(&mut self, from: usize, to: usize, x: [f64; D]) {
        let w = self.width;
        self.ids[to] = self.ids[from];
        self.values.copy_within(from * w..(from + 1) * w, to * w);
        self.values[to * w..to * w + D].copy_from_slice(&x);
    }

    fn truncate(&mut self, n: usize) {
        self.ids.truncate(n);
        self.values.truncate(n * self.width);
    }

    fn push_rows(&mut self, ids: &[u64], values: &[f64]) {
        self.ids.extend_from_slice(ids);
        self.values.extend_from_slice(values);
    }
}

/// `decomposition` with its planes placed by the particles of every rank
/// ([`Decomposition::balanced`]): each rank's histogram of its `positions`,
/// summed over the ranks (integers: the same sum, and so the same planes, on
/// every rank, whatever particles each holds and in whatever order).
pub fn balance<C: Communicator, const D: usize>(
    world: &C,
    decomposition: &Decomposition<D>,
    positions: &[[f64; D]],
    reach: f64,
) -> Decomposition<D> {
    let mine = decomposition.histogram(positions);
    let mut all = vec![0u64; mine.len()];
    world.all_reduce_into(&mine[..], &mut all[..], SystemOperation::sum());
    decomposition.balanced(&all, reach)
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
    images: Images,
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
    for g in decomposition.ghosts(rank, &positions, reach, images) {
        outgoing[g.to].push_from(particles, g.index, &g.shift);
    }
    exchange(world, &outgoing, width)
}

/// Who sends which ghosts where, fixed between two neighbour-list rebuilds: for
/// each rank, the indices of this rank's particles it receives as ghosts and
/// their periodic shifts, and how many ghosts come from each rank. Every step
/// sends the ghosts' new positions along the same plan (LAMMPS's forward
/// communication), so that the ghosts keep their order.
pub struct GhostPlan<const D: usize> {
    sends: Vec<Vec<(usize, [f64; D])>>,
    incoming: Vec<usize>,
    /// Per rank, the particles sent to it (what comes back from it).
    sent_counts: Vec<usize>,
    buffers: Vec<Vec<f64>>,
    returned: Vec<f64>,
}

impl<const D: usize> GhostPlan<D> {
    /// The plan for this rank's particles at `positions` (inside its
    /// subdomain), ghosts within `reach` ([`Decomposition::ghosts`], the
    /// periodic images `images`); the counts travel by one all-to-all.
    pub fn new<C: Communicator>(
        world: &C,
        decomposition: &Decomposition<D>,
        positions: &[[f64; D]],
        reach: f64,
        images: Images,
    ) -> Self {
        let ranks = world.size() as usize;
        let mut sends = vec![Vec::new(); ranks];
        for g in decomposition.ghosts(world.rank() as usize, positions, reach, images) {
            sends[g.to].push((g.index, g.shift));
        }
        let counts: Vec<u64> = sends.iter().map(|s| s.len() as u64).collect();
        let mut incoming = vec![0u64; ranks];
        world.all_to_all_into(&counts[..], &mut incoming[..]);
        GhostPlan {
            sent_counts: sends.iter().map(Vec::len).collect(),
            sends,
            incoming: incoming.iter().map(|&c| c as usize).collect(),
            buffers: vec![Vec::new(); ranks],
            returned: Vec::new(),
        }
    }

    /// The number of ghosts this rank receives.
    pub fn len(&self) -> usize {
        self.incoming.iter().sum()
    }

    /// True when no ghost comes.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The number of particles this rank sends as ghosts.
    pub fn sent(&self) -> usize {
        self.sends.iter().map(Vec::len).sum()
    }

    /// Renumbers the particles the plan sends after the caller stored them
    /// anew, `new[i] = old[former[i]]`: the same particles go out, in the
    /// same order, with the same shifts.
    pub fn renumber(&mut self, former: &[u32]) {
        let mut new_of = vec![0u32; former.len()];
        for (i, &k) in former.iter().enumerate() {
            new_of[k as usize] = i as u32;
        }
        for (k, _) in self.sends.iter_mut().flatten() {
            *k = new_of[*k] as usize;
        }
    }

    /// The ghosts' ids, in ghost order.
    pub fn ids<C: Communicator>(&self, world: &C, ids: &[u64]) -> Vec<u64> {
        let outgoing: Vec<Vec<u64>> = self
            .sends
            .iter()
            .map(|s| s.iter().map(|&(k, _)| ids[k]).collect())
            .collect();
        let mut received = vec![0; self.len()];
        swap_blocks(world, &outgoing, &self.incoming, 1, &mut received);
        received
    }

    /// The ghosts' positions now, `x_k + shift`, written to `ghosts` in ghost
    /// order (no allocation once the buffers have grown).
    pub fn positions<C: Communicator>(
        &mut self,
        world: &C,
        positions: &[[f64; D]],
        ghosts: &mut [[f64; D]],
    ) {
        self.forward(
            world,
            D,
            |k, shift, buffer| buffer.extend((0..D).map(|a| positions[k][a] + shift[a])),
            ghosts.as_flattened_mut(),
        );
    }

    /// The ghosts' values of a per-particle field, written to `ghosts` in
    /// ghost order.
    pub fn values<C: Communicator>(&mut self, world: &C, values: &[f64], ghosts: &mut [f64]) {
        self.forward(world, 1, |k, _, buffer| buffer.push(values[k]), ghosts);
    }

    /// Sends `width` numbers per ghost (`ghosts`, in ghost order) back to the
    /// rank it came from, and passes what comes back here to `add(k, values)`
    /// for the particle `k` it was sent for, in the order of the plan: the
    /// reverse of [`GhostPlan::positions`] (LAMMPS's reverse communication),
    /// `own_k += sum over the images of k sent out of the numbers computed
    /// for them`.
    pub fn reverse<C: Communicator>(
        &mut self,
        world: &C,
        width: usize,
        ghosts: &[f64],
        mut add: impl FnMut(usize, &[f64]),
    ) {
        assert_eq!(ghosts.len(), width * self.len());
        let mut at = 0;
        for (buffer, &count) in self.buffers.iter_mut().zip(&self.incoming) {
            buffer.clear();
            buffer.extend_from_slice(&ghosts[at..at + width * count]);
            at += width * count;
        }
        let mut back = std::mem::take(&mut self.returned);
        back.clear();
        back.resize(width * self.sent(), 0.0);
        swap_blocks(world, &self.buffers, &self.sent_counts, width, &mut back);
        let indices = self.sends.iter().flatten().map(|&(k, _)| k);
        for (k, values) in indices.zip(back.chunks_exact(width)) {
            add(k, values);
        }
        self.returned = back;
    }

    /// Sends `width` numbers per ghost, written by `fill(index, shift, buffer)`,
    /// along the plan, and writes what arrives to `ghosts`.
    fn forward<C: Communicator>(
        &mut self,
        world: &C,
        width: usize,
        fill: impl Fn(usize, &[f64; D], &mut Vec<f64>),
        ghosts: &mut [f64],
    ) {
        for (buffer, sends) in self.buffers.iter_mut().zip(&self.sends) {
            buffer.clear();
            for (k, shift) in sends {
                fill(*k, shift, buffer);
            }
        }
        swap_blocks(world, &self.buffers, &self.incoming, width, ghosts);
    }
}

/// The world of a run spread over several MPI ranks: `Some` when MPI was
/// started (by the command line) and has more than one rank.
pub fn world_of_many() -> Option<SimpleCommunicator> {
    if !mpi::environment::is_initialized() {
        return None;
    }
    let world = SimpleCommunicator::world();
    (world.size() > 1).then_some(world)
}

/// The section that marks one rank's part of a spread model's state:
/// `[rank, ranks]`.
const PART: &str = "rank_part";

/// Marks `state` as the part of this rank of `world` ([`is_own_part`]).
pub fn mark_part<C: Communicator>(world: &C, state: &mut State) {
    state.put_u64s(PART, [world.rank() as u64, world.size() as u64]);
}

/// Whether `state` is this rank's own part of a spread model's state (saved
/// with [`mark_part`]) rather than a global state (a checkpoint file of any
/// number of ranks, or of one process); the part of another rank, or of
/// another rank count, is an error.
pub fn is_own_part<C: Communicator>(
    world: &C,
    state: &dyn SectionSource,
) -> Result<bool, StateError> {
    if !state.has(PART) {
        return Ok(false);
    }
    let (rank, ranks) = (world.rank() as u64, world.size() as u64);
    let part = state.u64s_of(PART, 2)?;
    if part != [rank, ranks] {
        return Err(StateError(format!(
            "the state is rank {} of {}'s part, not rank {rank} of {ranks}'s",
            part[0], part[1]
        )));
    }
    Ok(true)
}

/// This process's rank in a run over several MPI ranks (`None` in one process).
pub fn rank_of_many() -> Option<i32> {
    world_of_many().map(|w| w.rank())
}

/// Every rank's outcome made one: the message of the lowest rank that failed
/// (`None` when none did), on every rank, so that all stop together and none
/// waits in a later exchange.
pub fn agree<C: Communicator>(world: &C, failure: Option<String>) -> Option<String> {
    let size = world.size();
    let mine = if failure.is_some() {
        world.rank()
    } else {
        size
    };
    let mut first = size;
    world.all_reduce_into(&mine, &mut first, SystemOperation::min());
    if first == size {
        return None;
    }
    let root = world.process_at_rank(first);
    let mut bytes = if first == world.rank() {
        failure.unwrap_or_default().into_bytes()
    } else {
        Vec::new()
    };
    let mut length = bytes.len() as u64;
    root.broadcast_into(&mut length);
    bytes.resize(length as usize, 0);
    root.broadcast_into(&mut bytes[..]);
    Some(String::from_utf8_lossy(&bytes).into_owned())
}

/// Element by element, every rank's `values` reduced by `op`, on every rank.
pub fn all_reduce<C: Communicator, const N: usize>(
    world: &C,
    values: [f64; N],
    op: SystemOperation,
) -> [f64; N] {
    let mut reduced = [0.0; N];
    world.all_reduce_into(&values[..], &mut reduced[..], op);
    reduced
}

/// Runs `add` on `value` once per rank of `world` in rank order, each rank
/// continuing from the value the rank before it sent, so that a sum over
/// blocks of particles held in rank order is added up as one process adds it;
/// every rank gets the last rank's value (collective).
pub fn fold_in_rank_order(
    world: &SimpleCommunicator,
    value: &mut [f64],
    add: &mut dyn FnMut(&mut [f64]),
) {
    let (rank, size) = (world.rank(), world.size());
    if rank > 0 {
        world.process_at_rank(rank - 1).receive_into(value);
    }
    add(value);
    if rank + 1 < size {
        world.process_at_rank(rank + 1).send(&*value);
    }
    world.process_at_rank(size - 1).broadcast_into(value);
}

/// [`agree`] on a blow-up of `step`: every rank returns the blow-up of the
/// lowest rank that had one.
pub fn agree_blowup<C: Communicator>(
    world: &C,
    step: u64,
    blowup: Option<Blowup>,
) -> Option<Blowup> {
    const SEP: char = '\u{1f}';
    let encoded = blowup.map(|b| {
        let (quantity, value) = b.value.map_or((String::new(), String::new()), |(q, v)| {
            (q, format!("{:x}", v.to_bits()))
        });
        let particle = b.particle.map_or(String::new(), |id| id.to_string());
        format!(
            "{}{SEP}{}{SEP}{quantity}{SEP}{value}{SEP}{particle}",
            b.what, b.remedy
        )
    });
    agree(world, encoded).map(|text| {
        let parts: Vec<&str> = text.split(SEP).collect();
        let value = u64::from_str_radix(parts.get(3).copied().unwrap_or(""), 16)
            .ok()
            .map(|bits| (parts[2].to_string(), f64::from_bits(bits)));
        Blowup {
            step,
            what: parts[0].to_string(),
            particle: parts.get(4).and_then(|p| p.parse().ok()),
            value,
            remedy: parts.get(1).copied().unwrap_or("").to_string(),
        }
    })
}

/// MPI's counts and displacements of blocks of `counts` numbers laid end to end.
pub(crate) fn layout(counts: &[usize]) -> (Vec<mpi::Count>, Vec<mpi::Count>) {
    let counts: Vec<mpi::Count> = counts.iter().map(|&c| c as mpi::Count).collect();
    let displacements = counts
        .iter()
        .scan(0, |at, &c| {
            let start = *at;
            *at += c;
            Some(start)
        })
        .collect();
    (counts, displacements)
}
