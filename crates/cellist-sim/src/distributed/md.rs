//! Lennard-Jones molecular dynamics by domain decomposition: each rank owns the
//! atoms of its subdomain, receives ghosts within cutoff + skin of it, and
//! computes the forces on its own atoms in one of two ways ([`PairSums`]):
//!
//! - by default over a half cluster list of its own atoms and the ghosts of
//!   half the directions ([`HaloForces`], [`Images::HalfShell`]): each pair
//!   once over all ranks, the single-process kernel, the ghosts' reactions
//!   sent back to their owners ([`GhostPlan::reverse`]); the result agrees
//!   with other rank counts to rounding;
//! - with `[run] reproducible = true`, over full neighbour rows in ascending
//!   id ([`OrderedRows`]) with ghosts of every image: every pair twice, and
//!   the same bits on any number of ranks and threads.
//!
//! ```text
//! step:  first half (kick + drift)          # own atoms
//!        check positions; rebuild? = some atom moved more than skin/2
//!        one all-reduce of both             # every rank stops on the same blow-up
//!          rebuild: (rcb, imbalance > 1.05: new planes), wrap, migrate to
//!                   owners, count the atoms (all-reduce), new ghost plan and
//!                   ids, new list or rows
//!          else:    send the ghosts' positions along the plan
//!        forces on own atoms and ghosts; the ghosts' reactions back (default)
//!        second half (kick)
//!        check v and f (agreed)
//!        observed step: gather everything on rank 0, sorted by id
//! ```
//!
//! Rank 0 writes every output from the gathered state (thermo summed in id
//! order, dumps, checkpoints of the global state); the other ranks write
//! nothing. The speed line adds the communication time of rank 0 and the load
//! imbalance (largest over mean atoms per rank, averaged over the rebuilds).

use super::{agree, agree_blowup, migrate, GhostPlan, LocalParticles};
use crate::hosted::{Distribution, Hosted};
use cellist::decomposition::{Balance, Decomposition, Images, Subdomain, REBALANCE_ABOVE};
use cellist::geometry::Domain;
use cellist::interactions::{LennardJones, PairPotential};
use cellist::models::md::{
    blowup_of, check_positions, checked_atoms, dump_particles, lap, late_note, load_atoms,
    ordered_forces, save_atoms, AtomForce, Atoms, HaloForces, Integrator, ListCounts, MdError,
    PairTally, StageTimes, Thermo, REMEDY,
};
use cellist::models::{check, md, Blowup, Checked, Model, ModelInfo, Particles};
use cellist::neighbors::{CellGrid, OrderedRows, Rebuild, RebuildRule};
use cellist::state::{State, StateError};
use cellist::Threads;
use mpi::collective::SystemOperation;
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;
use std::time::{Duration, Instant};

/// The global state on rank 0 after an observed step: every atom, sorted by
/// id, with its half pair energy and half virial and its position at the last
/// rebuild.
#[derive(Clone, Debug, Default)]
struct Gathered<const D: usize> {
    atoms: Atoms<D>,
    energies: Vec<f64>,
    virials: Vec<f64>,
    reference: Vec<[f64; D]>,
    energies_valid: bool,
}

/// The md model of one rank of a distributed run.
pub struct DistributedMd<const D: usize> {
    world: SimpleCommunicator,
    decomposition: Decomposition<D>,
    balance: Balance,
    /// How many times the planes were placed again.
    rebalances: u64,
    potential: LennardJones,
    skin: f64,
    rule: RebuildRule,
    integrator: Integrator,
    dt: f64,
    z_bounds: (f64, f64),
    total: usize,
    atoms: Atoms<D>,
    plan: GhostPlan<D>,
    ghost_ids: Vec<u64>,
    points: Vec<[f64; D]>,
    sums: PairSums<D>,
    /// The ghosts' reactions on their way back (the half list).
    reactions: Vec<f64>,
    computed: Vec<AtomForce<D>>,
    gathered: Option<Gathered<D>>,
    /// Set by a restore: the next step rebuilds whatever the skin test says.
    stale: bool,
    counts: ListCounts,
    times: StageTimes,
    communication: Duration,
    imbalance_sum: f64,
    imbalance_count: u64,
    ghosts_sum: f64,
}

/// What a distributed md run is built from: the whole system as one process
/// would hold it, and how it steps.
pub struct MdSpec<const D: usize> {
    /// The box.
    pub domain: Domain<D>,
    /// Every atom (the same on every rank).
    pub atoms: Atoms<D>,
    /// The pair potential.
    pub potential: LennardJones,
    /// The neighbour list's skin.
    pub skin: f64,
    /// When the list is rebuilt.
    pub rule: RebuildRule,
    /// How the atoms move.
    pub integrator: Integrator,
    /// The time step.
    pub dt: f64,
    /// The z bounds written in dumps of 2D systems.
    pub z_bounds: (f64, f64),
    /// Sum each atom's forces in id order over full rows: the same bits on
    /// any number of ranks, at twice the pair arithmetic.
    pub reproducible: bool,
    /// How the cut planes are placed (and, with [`Balance::Rcb`], placed
    /// again at a rebuild when the atoms crowd into some subdomains).
    pub balance: Balance,
}

/// How a rank sums the pair forces on its own atoms.
enum PairSums<const D: usize> {
    /// Over a half cluster list of own atoms and ghosts (`None` before the
    /// first build).
    Halo(Option<Box<HaloForces<D>>>),
    /// Over full rows sorted by id.
    Ordered(OrderedRows<D>),
}

impl<const D: usize> PairSums<D> {
    /// The ghosts a rank needs: for the half list, across the cuts from half
    /// of the directions (it bins in a box periodic along the uncut axes, and
    /// sends the ghosts' reactions back); for the rows, every image (found in
    /// open space).
    fn images(&self) -> Images {
        match self {
            PairSums::Halo(_) => Images::HalfShell,
            PairSums::Ordered(_) => Images::All,
        }
    }

    /// Builds the list or rows of the first `owned` of `points` (own atoms,
    /// then ghosts; `ids` alike); the failure (two atoms at one position, a
    /// geometry error) as its message. The half list looks for two atoms at
    /// one position at its first build only, as a single-process run does at
    /// set-up (later such a pair blows the run up); the rows at every build.
    #[allow(clippy::too_many_arguments)]
    fn build(
        &mut self,
        subdomain: &Subdomain<D>,
        points: &[[f64; D]],
        owned: usize,
        ids: &[u64],
        potential: &LennardJones,
        skin: f64,
        threads: &Threads,
    ) -> Option<String> {
        let overlap = |(first, second)| MdError::Overlap { first, second }.to_string();
        match self {
            PairSums::Ordered(rows) => {
                match OrderedRows::build(points, owned, ids, potential.cutoff(), skin, threads) {
                    Ok(built) => {
                        *rows = built;
                        rows.coincident(points, ids).map(overlap)
                    }
                    Err(e) => Some(e.to_string()),
                }
            }
            PairSums::Halo(halo) => {
                let built = HaloForces::build(subdomain, points, owned, *potential, skin, threads);
                let first = halo.is_none();
                match built {
                    Ok(built) => {
                        let built = halo.insert(Box::new(built));
                        first
                            .then(|| built.coincident(points, ids))
                            .flatten()
                            .map(overlap)
                    }
                    Err(e) => Some(e.to_string()),
                }
            }
        }
    }

    /// The own atoms' positions at the last build.
    fn reference(&self) -> &[[f64; D]] {
        match self {
            PairSums::Halo(halo) => halo.as_ref().map_or(&[], |h| h.reference()),
            PairSums::Ordered(rows) => rows.reference(),
        }
    }

    /// True when an own atom moved more than skin/2 since the last build.
    fn needs_rebuild(&self, owned: &[[f64; D]]) -> bool {
        match self {
            PairSums::Halo(halo) => halo.as_ref().is_none_or(|h| h.needs_rebuild(owned)),
            PairSums::Ordered(rows) => rows.needs_rebuild(owned),
        }
    }

    /// The forces on the own atoms from `points` (own then ghosts, as built),
    /// with `energy` their half energies and virials.
    fn forces(
        &mut self,
        potential: &LennardJones,
        points: &[[f64; D]],
        energy: bool,
        threads: &Threads,
        out: &mut [AtomForce<D>],
    ) {
        match self {
            PairSums::Halo(halo) => halo
                .as_mut()
                .expect("the list is built before the first forces")
                .forces(points, energy, threads, out),
            PairSums::Ordered(rows) if energy => {
                ordered_forces::<true, D, _>(rows, potential, points, out, threads)
            }
            PairSums::Ordered(rows) => {
                ordered_forces::<false, D, _>(rows, potential, points, out, threads)
            }
        }
    }
}

impl<const D: usize> DistributedMd<D> {
    /// The model of this rank: the atoms of `spec` (every atom, the same on
    /// every rank) kept where this rank owns them, ghosts exchanged, forces,
    /// energies and virials evaluated and gathered on rank 0. Every rank
    /// returns the same error for a box too small for the cutoff, a subdomain
    /// thinner than cutoff + skin, an atom outside a non-periodic box or two
    /// atoms at one position.
    pub fn new(
        world: SimpleCommunicator,
        spec: MdSpec<D>,
        threads: &Threads,
    ) -> Result<Self, String> {
        let MdSpec {
            domain,
            atoms,
            potential,
            skin,
            rule,
            integrator,
            dt,
            z_bounds,
            reproducible,
            balance,
        } = spec;
        if atoms.is_empty() {
            return Err("the system has no atoms".into());
        }
        let reach = potential.cutoff() + skin;
        domain.check_cutoff(reach).map_err(|e| e.to_string())?;
        check_positions(&domain, &atoms, 0, threads).map_err(|e| e.to_string())?;
        let ranks = world.size() as usize;
        let decomposition =
            Decomposition::for_particles(domain, ranks, balance, &atoms.positions, reach)?;
        let rank = world.rank() as usize;
        let total = atoms.len();
        let mine: Vec<usize> = (0..total)
            .filter(|&k| decomposition.owner(&atoms.positions[k]) == rank)
            .collect();
        let owned = atoms.select(&mine);
        let sums = if reproducible {
            PairSums::Ordered(OrderedRows::default())
        } else {
            PairSums::Halo(None)
        };
        let mut model = DistributedMd {
            plan: GhostPlan::new(&world, &decomposition, &[], reach, sums.images()),
            sums,
            world,
            decomposition,
            balance,
            rebalances: 0,
            potential,
            skin,
            rule,
            integrator,
            dt,
            z_bounds,
            total,
            atoms: owned,
            ghost_ids: Vec::new(),
            points: Vec::new(),
            reactions: Vec::new(),
            computed: Vec::new(),
            gathered: None,
            stale: false,
            counts: ListCounts::default(),
            times: StageTimes::default(),
            communication: Duration::ZERO,
            imbalance_sum: 0.0,
            imbalance_count: 0,
            ghosts_sum: 0.0,
        };
        model
            .redistribute(threads)
            .map_err(|e| e.what.to_string())?;
        model.forces(true, threads);
        model.gather();
        Ok(model)
    }

    /// The number of atoms over all ranks.
    pub fn total(&self) -> usize {
        self.total
    }

    /// One line on the decomposition: ranks, grid, how the planes are placed,
    /// the thinnest subdomain.
    pub fn describe(&self) -> String {
        let grid: Vec<String> = self
            .decomposition
            .grid
            .iter()
            .map(|g| g.to_string())
            .collect();
        let width: Vec<String> = self
            .decomposition
            .thinnest()
            .iter()
            .map(|w| format!("{w:.4}"))
            .collect();
        let planes = match self.balance {
            Balance::Uniform => "equal subdomains".to_string(),
            Balance::Rcb => {
                format!("planes placed by the atoms past an imbalance of {REBALANCE_ABOVE}")
            }
        };
        format!(
            "mpi: {} ranks, the box cut {} ({planes}, the thinnest {} wide), ghosts within \
             cutoff + skin {}",
            self.world.size(),
            grid.join(" x "),
            width.join(" x "),
            self.reach()
        )
    }

    fn reach(&self) -> f64 {
        self.potential.cutoff() + self.skin
    }

    /// Wraps and migrates the atoms to their owners, makes the new ghost plan
    /// and rows; an overlap found on any rank stops every rank.
    fn redistribute(&mut self, threads: &Threads) -> Result<(), Blowup> {
        let t = Instant::now();
        self.rebalance();
        let mut travelling = self.pack();
        migrate(&self.world, &self.decomposition, &mut travelling);
        self.unpack(&travelling);
        self.sort_by_cell();
        let reach = self.reach();
        self.plan = GhostPlan::new(
            &self.world,
            &self.decomposition,
            &self.atoms.positions,
            reach,
            self.sums.images(),
        );
        self.ghost_ids = self.plan.ids(&self.world, &self.atoms.ids);
        let n = self.atoms.len();
        self.points.clear();
        self.points.extend_from_slice(&self.atoms.positions);
        self.points.resize(n + self.ghost_ids.len(), [0.0; D]);
        self.plan
            .positions(&self.world, &self.atoms.positions, &mut self.points[n..]);
        self.imbalance_sum += self.imbalance();
        self.imbalance_count += 1;
        self.ghosts_sum += self.ghost_ids.len() as f64;
        self.communication += t.elapsed();
        let mut keys = self.atoms.ids.clone();
        keys.extend_from_slice(&self.ghost_ids);
        let subdomain = self.decomposition.subdomain(self.world.rank() as usize);
        let failure = self.sums.build(
            &subdomain,
            &self.points,
            n,
            &keys,
            &self.potential,
            self.skin,
            threads,
        );
        let t = Instant::now();
        let agreed = agree(&self.world, failure);
        self.communication += t.elapsed();
        if let Some(what) = agreed {
            return Err(Blowup::new(0, what, REMEDY));
        }
        let computed = match self.sums {
            PairSums::Halo(_) => self.points.len(),
            PairSums::Ordered(_) => n,
        };
        self.computed.resize(computed, AtomForce::default());
        self.stale = false;
        Ok(())
    }

    /// The largest over mean atoms per rank now (all-reduced: the same on
    /// every rank).
    fn imbalance(&self) -> f64 {
        let mut most = 0u64;
        self.world.all_reduce_into(
            &(self.atoms.len() as u64),
            &mut most,
            SystemOperation::max(),
        );
        most as f64 * self.world.size() as f64 / self.total as f64
    }

    /// With [`Balance::Rcb`], before the atoms migrate at a rebuild: when the
    /// load imbalance exceeds [`REBALANCE_ABOVE`], places the planes again by
    /// every rank's atoms ([`super::balance`]). Every rank decides and places
    /// alike from all-reduced counts.
    fn rebalance(&mut self) {
        if self.balance == Balance::Rcb && self.imbalance() > REBALANCE_ABOVE {
            let reach = self.reach();
            self.decomposition = super::balance(
                &self.world,
                &self.decomposition,
                &self.atoms.positions,
                reach,
            );
            self.rebalances += 1;
        }
    }

    /// Puts the own atoms in the order of the cells (of side cutoff + skin)
    /// they are in, so that neighbours lie close in memory (and the ghosts,
    /// sent in this order, too); the sums do not depend on this order.
    fn sort_by_cell(&mut self) {
        let Ok(grid) = CellGrid::new(&self.decomposition.domain, self.reach(), self.atoms.len())
        else {
            return;
        };
        let keys: Vec<usize> = self
            .atoms
            .positions
            .iter()
            .map(|x| grid.cell_of(x))
            .collect();
        let mut order: Vec<usize> = (0..self.atoms.len()).collect();
        order.sort_by_key(|&k| keys[k]);
        self.atoms = self.atoms.select(&order);
    }

    /// The own atoms as travelling rows: position, velocity, force, mass, type.
    fn pack(&self) -> LocalParticles {
        let a = &self.atoms;
        let width = 3 * D + 2;
        let mut values = Vec::with_capacity(a.len() * width);
        for k in 0..a.len() {
            values.extend_from_slice(&a.positions[k]);
            values.extend_from_slice(&a.velocities[k]);
            values.extend_from_slice(&a.forces[k]);
            values.push(a.masses[k]);
            values.push(a.types[k] as f64);
        }
        LocalParticles {
            ids: a.ids.clone(),
            values,
            width,
        }
    }

    fn unpack(&mut self, p: &LocalParticles) {
        self.atoms = atoms_of(p);
    }

    /// The forces on the own atoms; with `energy`, their half energies and
    /// virials too.
    fn forces(&mut self, energy: bool, threads: &Threads) {
        let (potential, points) = (&self.potential, &self.points);
        self.sums
            .forces(potential, points, energy, threads, &mut self.computed);
        if matches!(self.sums, PairSums::Halo(_)) {
            self.return_reactions(energy);
        }
        for (f, c) in self.atoms.forces.iter_mut().zip(&self.computed) {
            *f = c.force;
        }
    }

    /// Sends the ghosts' reactions (with `energy`, their half energies and
    /// virials too) to their owners and adds what comes back to the own
    /// atoms: each pair across a cut is computed on one rank only.
    fn return_reactions(&mut self, energy: bool) {
        let t = Instant::now();
        let n = self.atoms.len();
        let width = D + if energy { 2 } else { 0 };
        self.reactions.clear();
        for c in &self.computed[n..] {
            self.reactions.extend_from_slice(&c.force);
            if energy {
                self.reactions.extend([c.energy, c.virial]);
            }
        }
        let computed = &mut self.computed;
        self.plan
            .reverse(&self.world, width, &self.reactions, |k, values| {
                let c = &mut computed[k];
                for (f, v) in c.force.iter_mut().zip(values) {
                    *f += v;
                }
                if energy {
                    c.energy += values[D];
                    c.virial += values[D + 1];
                }
            });
        self.communication += t.elapsed();
    }

    /// Every atom on rank 0, sorted by id, with its half energy, half virial
    /// and position at the last rebuild after the columns of [`Self::pack`]
    /// (the other ranks keep nothing).
    fn gather(&mut self) {
        let t = Instant::now();
        let own = self.pack();
        let width = own.width + 2 + D;
        let mut values = Vec::with_capacity(own.len() * width);
        for k in 0..own.len() {
            values.extend_from_slice(&own.values[k * own.width..(k + 1) * own.width]);
            values.extend([self.computed[k].energy, self.computed[k].virial]);
            values.extend_from_slice(&self.sums.reference()[k]);
        }
        let mut outgoing = vec![
            LocalParticles {
                width,
                ..LocalParticles::default()
            };
            self.world.size() as usize
        ];
        outgoing[0] = LocalParticles {
            ids: own.ids,
            values,
            width,
        };
        let all = super::exchange(&self.world, &outgoing, width);
        self.communication += t.elapsed();
        if self.world.rank() != 0 {
            self.gathered = None;
            return;
        }
        let mut order: Vec<usize> = (0..all.len()).collect();
        order.sort_unstable_by_key(|&k| all.ids[k]);
        let sorted = LocalParticles {
            ids: order.iter().map(|&k| all.ids[k]).collect(),
            values: order
                .iter()
                .flat_map(|&k| all.values[k * width..(k + 1) * width].iter().copied())
                .collect(),
            width,
        };
        let base = 3 * D + 2;
        let row = |k: usize| &sorted.values[k * width..(k + 1) * width];
        self.gathered = Some(Gathered {
            atoms: atoms_of(&sorted),
            energies: (0..sorted.len()).map(|k| row(k)[base]).collect(),
            virials: (0..sorted.len()).map(|k| row(k)[base + 1]).collect(),
            reference: (0..sorted.len())
                .map(|k| std::array::from_fn(|d| row(k)[base + 2 + d]))
                .collect(),
            energies_valid: true,
        });
    }

    /// The gathered state (rank 0, after an observed step).
    fn global(&self) -> &Gathered<D> {
        self.gathered
            .as_ref()
            .expect("the global state is gathered on rank 0 at every observed step")
    }

    /// The time of the MPI exchanges and all-reduces of this rank.
    fn agree_blowup(&mut self, step: u64, local: Option<Blowup>) -> Result<(), Blowup> {
        let t = Instant::now();
        let agreed = agree_blowup(&self.world, step, local);
        self.communication += t.elapsed();
        agreed.map_or(Ok(()), Err)
    }

    /// `max` over the ranks of each flag.
    fn any<const K: usize>(&mut self, flags: [u8; K]) -> [bool; K] {
        let t = Instant::now();
        let mut all = [0u8; K];
        self.world
            .all_reduce_into(&flags[..], &mut all[..], SystemOperation::max());
        self.communication += t.elapsed();
        all.map(|f| f != 0)
    }
}

/// The atoms of travelling rows whose first `3 D + 2` columns are those of
/// [`DistributedMd::pack`]: position, velocity, force, mass, type.
fn atoms_of<const D: usize>(p: &LocalParticles) -> Atoms<D> {
    let row = |k: usize| &p.values[k * p.width..(k + 1) * p.width];
    let vector = |k: usize, at: usize| -> [f64; D] { std::array::from_fn(|d| row(k)[at + d]) };
    Atoms {
        ids: p.ids.clone(),
        positions: (0..p.len()).map(|k| vector(k, 0)).collect(),
        velocities: (0..p.len()).map(|k| vector(k, D)).collect(),
        forces: (0..p.len()).map(|k| vector(k, 2 * D)).collect(),
        masses: (0..p.len()).map(|k| row(k)[3 * D]).collect(),
        types: (0..p.len()).map(|k| row(k)[3 * D + 1] as u32).collect(),
    }
}

/// What a distributed md model is: md's, with an atom count per rank that
/// changes as atoms migrate.
const INFO: ModelInfo = ModelInfo {
    count_may_change: true,
    ..md::INFO
};

impl<const D: usize> DistributedMd<D> {
    /// Advances to `step` on every rank; the atoms are gathered on rank 0 when
    /// any rank `observe`s.
    fn advance(&mut self, step: u64, observe: bool, threads: &Threads) -> Result<(), Blowup> {
        let t = Instant::now();
        self.integrator
            .first_half(&mut self.atoms, self.dt, threads);
        let t = lap(t, &mut self.times.integrate);
        let domain = self.decomposition.domain;
        let local = check_positions(&domain, &self.atoms, step, threads)
            .err()
            .map(|e| blowup_of(&e, step));
        let since = self.counts.step();
        let (sums, positions) = (&self.sums, &self.atoms.positions);
        // after a restore the rows are not this rank's atoms': rebuild, untested
        let decision = if self.stale {
            Rebuild::Yes { late: false }
        } else {
            self.rule.decide(since, || sums.needs_rebuild(positions))
        };
        let (wanted, late) = match decision {
            Rebuild::No => (false, false),
            Rebuild::Yes { late } => (true, late),
        };
        // one all-reduce a step for the blow-up check and the list's decision
        let flags = [local.is_some(), wanted, observe, late].map(u8::from);
        let [failed, rebuild, observe, late] = self.any(flags);
        if failed {
            self.agree_blowup(step, local)?;
        }
        let t = lap(t, &mut self.times.neighbor);
        if rebuild {
            self.redistribute(threads)
                .map_err(|b| Blowup { step, ..b })?;
            self.counts.built(late);
            self.check_count(step)?;
        } else {
            let n = self.atoms.len();
            self.points[..n].copy_from_slice(&self.atoms.positions);
            let c = Instant::now();
            self.plan
                .positions(&self.world, &self.atoms.positions, &mut self.points[n..]);
            self.communication += c.elapsed();
        }
        let t = lap(t, &mut self.times.neighbor);
        self.forces(observe, threads);
        let t = lap(t, &mut self.times.force);
        self.integrator
            .second_half(&mut self.atoms, self.dt, step, threads);
        lap(t, &mut self.times.integrate);
        let local = check(self, step, 0).err();
        self.agree_blowup(step, local)?;
        if observe {
            self.gather();
        }
        Ok(())
    }
}

impl<const D: usize> DistributedMd<D> {
    /// The atoms summed over the ranks after a migration: the total of the
    /// set-up, or a blow-up naming the bug (atoms move between ranks only
    /// at rebuilds).
    fn check_count(&mut self, step: u64) -> Result<(), Blowup> {
        let c = Instant::now();
        let mut count = 0u64;
        self.world.all_reduce_into(
            &(self.atoms.len() as u64),
            &mut count,
            SystemOperation::sum(),
        );
        self.communication += c.elapsed();
        if count as usize != self.total {
            return Err(Blowup::new(
                step,
                format!(
                    "the number of atoms over the ranks changed from {} to {count}",
                    self.total
                ),
                "atoms were lost or duplicated between ranks: this is a bug in cellist",
            ));
        }
        Ok(())
    }
}

impl<const D: usize> Model for DistributedMd<D> {
    fn info(&self) -> &ModelInfo {
        &INFO
    }

    /// The atoms this rank owns (the global count is checked by the step).
    fn len(&self) -> usize {
        self.atoms.len()
    }

    fn dt(&self) -> f64 {
        self.dt
    }

    fn step(&mut self, step: u64, threads: &Threads) -> Result<(), Blowup> {
        self.advance(step, false, threads)
    }

    fn step_observed(&mut self, step: u64, threads: &Threads) -> Result<(), Blowup> {
        self.advance(step, true, threads)
    }

    /// Summed on rank 0 over the gathered atoms in id order.
    fn thermo(&self, _step: u64) -> Vec<f64> {
        let g = self.global();
        let totals = PairTally {
            energy: g.energies.iter().sum(),
            virial: g.virials.iter().sum(),
        };
        let th = Thermo::of(&g.atoms, totals, self.decomposition.domain.volume());
        vec![th.temp, th.pe, th.ke, th.etotal, th.press]
    }

    fn checked(&self) -> Checked<'_> {
        checked_atoms(&self.atoms, &self.decomposition.domain)
    }

    /// On rank 0 the gathered atoms (sorted by id, positions wrapped); `None`
    /// on the other ranks.
    fn particles(&self, _step: u64, energies: bool) -> Option<Particles> {
        let g = self.gathered.as_ref()?;
        let energies = (energies && g.energies_valid).then(|| g.energies.clone());
        Some(dump_particles(
            &g.atoms,
            energies,
            &self.decomposition.domain,
            self.z_bounds,
        ))
    }

    fn stage_times(&self) -> Vec<(&'static str, Duration)> {
        self.times.stages()
    }

    /// On rank 0 the global state sorted by id, in the single-process layout
    /// (a distributed checkpoint restarts in one process or on any number of
    /// ranks); nothing on the other ranks.
    fn save(&self, state: &mut State) {
        if let Some(g) = &self.gathered {
            save_atoms(state, &g.atoms, &g.reference, self.counts);
        }
    }

    /// Takes the atoms this rank owns from a global state (of any number of
    /// ranks, or of one process); the next step migrates and rebuilds. Not
    /// collective: a rank that fails returns its error alone.
    fn restore(&mut self, state: &State, _threads: &Threads) -> Result<(), StateError> {
        let n = self.total;
        let (all, reference, counts) = load_atoms::<D>(state, n)?;
        if all.positions.iter().flatten().any(|c| !c.is_finite()) {
            return Err(StateError("a saved position is not finite".into()));
        }
        let rank = self.world.rank() as usize;
        let mine: Vec<usize> = (0..n)
            .filter(|&k| self.decomposition.owner(&all.positions[k]) == rank)
            .collect();
        self.atoms = all.select(&mine);
        self.counts = counts;
        self.stale = true;
        self.gathered = (rank == 0).then(|| {
            let by_id = all.slots_by_id();
            Gathered {
                atoms: all.select(&by_id),
                reference: by_id.iter().map(|&k| reference[k]).collect(),
                energies: vec![0.0; n],
                virials: vec![0.0; n],
                energies_valid: false,
            }
        });
        Ok(())
    }
}

impl<const D: usize> Hosted for DistributedMd<D> {
    /// Microseconds per atom-step over the ranks, the communication, the load
    /// imbalance and the ghosts.
    fn speed(&self, loop_seconds: f64, steps: u64, threads: usize) -> String {
        let n = self.total;
        let ranks = self.world.size();
        let per = loop_seconds * 1e6 / (n as f64 * steps.max(1) as f64);
        let rebuilds = self.imbalance_count.max(1) as f64;
        let imbalance = self.mean_imbalance();
        let ghosts = self.ghosts_sum / rebuilds;
        let rebalances = self.rebalances;
        format!(
            "Loop time of {loop_seconds:.4} s on {ranks} ranks x {threads} thread(s) for {steps} \
             steps with {n} atoms: {per:.4} us/atom-step, {} neighbour-list rebuilds{}\n\
             Communication {:.4} s on rank 0 ({:.1}% of the loop; inside the sections below); \
             load imbalance {imbalance:.3} (largest over mean atoms per rank, mean over the rebuilds; \
             planes placed again {rebalances} times); rank 0 holds {ghosts:.0} ghosts for {} own atoms ({:.0} bytes of positions received per step)",
            self.counts.rebuilds,
            late_note(self.counts.late_builds),
            self.communication.as_secs_f64(),
            100.0 * self.communication.as_secs_f64() / loop_seconds.max(1e-300),
            self.atoms.len(),
            ghosts * (D * 8) as f64,
        )
    }

    /// This rank's communication time, the mean load imbalance and the atom
    /// count.
    fn distribution(&self) -> Option<Distribution> {
        Some(Distribution {
            communication: self.communication,
            imbalance_particles: self.mean_imbalance(),
            particles: self.total,
        })
    }
}

impl<const D: usize> DistributedMd<D> {
    /// Largest over mean atoms per rank, mean over the rebuilds.
    fn mean_imbalance(&self) -> f64 {
        self.imbalance_sum / self.imbalance_count.max(1) as f64
    }
}
