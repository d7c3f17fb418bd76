//! Lennard-Jones molecular dynamics by domain decomposition: each rank owns the
//! atoms of its subdomain, receives ghosts within cutoff + skin of it, and
//! computes the forces on its own atoms in one of two ways (`PairSums`):
//!
//! - by default over a half cluster list of its own atoms and the ghosts of
//!   half the directions ([`HaloForces`](cellist::models::md::HaloForces),
//!   [`Images::HalfShell`](cellist::decomposition::Images::HalfShell)): each pair
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
//!        one all-reduce of the step's flags # the blow-up, rebuild?, observed?,
//!                                           # a dump's per-atom energies wanted?
//!          rebuild: (rcb, imbalance > 1.05: new planes), wrap, migrate to
//!                   owners, count the atoms (all-reduce), new ghost plan and
//!                   ids, new list or rows
//!          else:    send the ghosts' positions along the plan
//!        forces on own atoms and ghosts; the ghosts' reactions back (default)
//!          observed: the pairs' energy and virial (the per-atom halves only
//!          for a dump that wants them)
//!        second half (kick)
//!        check v and f (agreed)
//!        observed step (default): the ranks' 2K, U and W all-gathered and
//!          added in rank order (the thermo)
//! ```
//!
//! Rank 0 writes every output, pulling the atoms from every rank a block of
//! ids at a time in id order ([`super::pull`]; each rank sorts its atoms by
//! id at the first pull after a step) while the other ranks serve its asks
//! ([`Hosted::serve_outputs`]): dumps and the global state for checkpoints,
//! the same bytes as one process would write, without the whole state on one
//! rank; with the reproducible rows also the thermo, summed in id order. The speed line adds the communication time of rank 0 and the load
//! imbalance (largest over mean atoms per rank, averaged over the rebuilds).

use super::pull::{self, IdSpan, OwnRows as _};
use super::{agree, agree_blowup, is_own_part, mark_part, migrate, GhostPlan};
use crate::hosted::{Distribution, FileState, Hosted};
use cellist::decomposition::{Balance, Decomposition, REBALANCE_ABOVE};
use cellist::geometry::Domain;
use cellist::interactions::{LennardJones, PairPotential};
use cellist::models::md::{
    blowup_of, check_positions, checked_atoms, dump_particles, lap, late_note, load_atoms,
    load_atoms_where, ordered_forces, save_atoms, twice_kinetic, AtomForce, Atoms, HaloSums,
    Integrator, ListCounts, PairTally, SavedAtoms, StageTimes, ThermoSums, REMEDY,
};
use cellist::models::{
    check, md, whole_frame, Blowup, Checked, Model, ModelInfo, ParticleBlock, Particles,
};
use cellist::neighbors::{CellGrid, OrderedRows, Rebuild, RebuildRule};
use cellist::state::{Layout, SectionSource, State, StateError};
use cellist::threads::counting_sort;
use cellist::Threads;
use mpi::collective::SystemOperation;
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;
use std::cell::OnceCell;
use std::ops::ControlFlow;
use std::time::{Duration, Instant};

mod pair_sums;
mod rows;
use pair_sums::PairSums;
use rows::{gathered_of, Gathered, OwnRows};

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
    /// The ghosts' positions now, in the plan's order.
    ghosts: Vec<[f64; D]>,
    /// The own atoms' then the ghosts' positions: at the last build for the
    /// half list (its input; after it, the buffer the atoms are reordered
    /// through), now for the reproducible rows.
    points: Vec<[f64; D]>,
    /// The buffer of the atoms' ids, types and masses as they are reordered.
    words: Vec<u64>,
    sums: PairSums<D>,
    /// The ghosts' reactions on their way back (the half list): `D` numbers
    /// per ghost, `D + 2` with the half energy and virial.
    reactions: Vec<f64>,
    /// Each own atom's half energy and half virial, set by the forces of an
    /// observed step that computed them (`energies_valid`) and read only
    /// after it (a rebuild leaves them in the old order, a plain step of the
    /// reproducible rows zeroes them).
    energies: Vec<[f64; 2]>,
    /// Any rank observed the last step: rank 0 pulls its outputs.
    observed: bool,
    /// The own atoms' slots in ascending id, sorted at the first pull of
    /// rank 0's outputs after the atoms last changed ([`Self::by_id`]).
    by_id: OnceCell<Vec<u32>>,
    /// The ids over all ranks.
    span: IdSpan,
    /// After a restore, until the next rebuild: the own atoms' positions at
    /// the last rebuild (the list is not built yet).
    restored_reference: Option<Vec<[f64; D]>>,
    /// True after an observed step that computed the own atoms' energies
    /// (with the half list: only when a rank's dump wanted them); false after
    /// a restore until then.
    energies_valid: bool,
    /// Set before an observed step ([`Hosted::want_particle_energies`]): an
    /// output of this rank reads per-atom energies after it.
    energies_wanted: bool,
    /// With the half list, after an observed step (and at set-up) on every
    /// rank, until the next step: the system's `2K = sum m v^2` and the
    /// energy and virial of its pairs, each rank's sums added in rank order
    /// ([`Self::add_up_thermo`]); `None` otherwise.
    system_sums: Option<ThermoSums>,
    /// Set by a restore: the next step rebuilds whatever the skin test says.
    stale: bool,
    /// The own atoms are stored in the half list's slot order of the last
    /// build (then moved only by the migration), which keeps neighbours
    /// close in memory without sorting them by cell at the next build.
    in_slot_order: bool,
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
    /// This rank's share of the atoms: each atom on exactly one rank
    /// ([`share_at_set_up`]), moved to its owner by the model.
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

impl<const D: usize> DistributedMd<D> {
    /// The model of this rank: the atoms of `spec` (this rank's share)
    /// moved to the ranks that own them, ghosts exchanged, forces, energies
    /// and virials evaluated. The planes are equal, or with [`Balance::Rcb`]
    /// placed by every rank's atoms when equal planes would leave an
    /// imbalance above [`REBALANCE_ABOVE`] (the planes
    /// [`Decomposition::for_particles`] places for all of them). Every rank
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
        let mut total = 0u64;
        world.all_reduce_into(&(atoms.len() as u64), &mut total, SystemOperation::sum());
        let total = total as usize;
        if total == 0 {
            return Err("the system has no atoms".into());
        }
        let reach = potential.cutoff() + skin;
        domain.check_cutoff(reach).map_err(|e| e.to_string())?;
        let misplaced = check_positions(&domain, &atoms, 0, threads)
            .err()
            .map(|e| e.to_string());
        if let Some(what) = agree(&world, misplaced) {
            return Err(what);
        }
        let ranks = world.size() as usize;
        let equal = Decomposition::new(domain, ranks);
        equal.check_reach(reach)?;
        let decomposition = match balance {
            Balance::Rcb if imbalance_of(&world, &equal, &atoms, total) > REBALANCE_ABOVE => {
                super::balance(&world, &equal, &atoms.positions, reach)
            }
            _ => equal,
        };
        let owned = atoms;
        let sums = if reproducible {
            PairSums::Ordered(OrderedRows::default(), Vec::new())
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
            ghosts: Vec::new(),
            points: Vec::new(),
            words: Vec::new(),
            reactions: Vec::new(),
            energies: Vec::new(),
            observed: false,
            by_id: OnceCell::new(),
            span: IdSpan {
                first: 0,
                last: 0,
                count: total,
            },
            restored_reference: None,
            energies_valid: true,
            energies_wanted: false,
            system_sums: None,
            stale: false,
            in_slot_order: false,
            counts: ListCounts::default(),
            times: StageTimes::default(),
            communication: Duration::ZERO,
            imbalance_sum: 0.0,
            imbalance_count: 0,
            ghosts_sum: 0.0,
        };
        // the atoms to the owners of the planes just placed, so that the
        // rebuild's imbalance test sees them there
        migrate(&model.world, &model.decomposition, &mut model.atoms);
        model
            .redistribute(threads)
            .map_err(|e| e.what.to_string())?;
        model.span = IdSpan::of(&model.world, &model.atoms.ids);
        if let Some(pairs) = model.forces(true, true, threads) {
            model.add_up_thermo(pairs);
        }
        model.observe(true);
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
        migrate(&self.world, &self.decomposition, &mut self.atoms);
        if !self.in_slot_order {
            self.sort_by_cell(threads);
        }
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
        self.ghosts.resize(self.ghost_ids.len(), [0.0; D]);
        self.plan
            .positions(&self.world, &self.atoms.positions, &mut self.ghosts);
        self.points.clear();
        self.points.extend_from_slice(&self.atoms.positions);
        self.points.extend_from_slice(&self.ghosts);
        self.imbalance_sum += self.imbalance();
        self.imbalance_count += 1;
        self.ghosts_sum += self.ghost_ids.len() as f64;
        self.communication += t.elapsed();
        let mut keys = Vec::new();
        if self.sums.needs_ids() {
            keys.extend_from_slice(&self.atoms.ids);
            keys.extend_from_slice(&self.ghost_ids);
        }
        let subdomain = self.decomposition.subdomain(self.world.rank() as usize);
        let share = self.total / self.world.size() as usize;
        let failure = self.sums.build(
            &subdomain,
            &self.points,
            n,
            share,
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
        if let PairSums::Halo(Some(halo)) = &mut self.sums {
            // the points, the list's input, are the buffer of the reordering
            let former = halo.own_in_slot_order(&mut self.points);
            let (points, words) = (&mut self.points, &mut self.words);
            self.atoms.permute_through(&former, points, words);
            self.plan.renumber(&former);
            self.in_slot_order = true;
        }
        self.energies.resize(n, [0.0; 2]);
        self.stale = false;
        self.restored_reference = None;
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
    /// sent in this order, too); the sums do not depend on this order. Before
    /// the first build, after a restore and before every build of the
    /// reproducible rows: the half list keeps the atoms in its slots' order
    /// from one build to the next instead
    /// ([`HaloForces::own_in_slot_order`](cellist::models::md::HaloForces::own_in_slot_order);
    /// atoms that tie inside a cell's columns then fall in that order). A
    /// stable counting sort by cell, the atoms moved in place along the
    /// permutation's cycles (8 bytes per atom for the keys and the order,
    /// no copy of the atoms' arrays).
    fn sort_by_cell(&mut self, threads: &Threads) {
        let Ok(grid) = CellGrid::new(&self.decomposition.domain, self.reach(), self.atoms.len())
        else {
            return;
        };
        let keys: Vec<u32> = self
            .atoms
            .positions
            .iter()
            .map(|x| grid.cell_of(x) as u32)
            .collect();
        let (mut start, mut order, mut counts) = (Vec::new(), Vec::new(), Vec::new());
        let buckets = grid.num_cells();
        counting_sort(
            &keys,
            buckets,
            Some(threads),
            &mut start,
            &mut order,
            &mut counts,
        );
        drop(keys);
        self.atoms.permute_by_cycles(&order);
    }

    /// The forces on the own atoms; when `observe`d, the half list returns
    /// the energy and virial of this rank's pairs; with `energies`, the
    /// own atoms' half energies and virials too (the reproducible rows sum
    /// them at every observed step). The half list writes the own atoms' sums
    /// and the ghosts' reactions straight to their arrays and sends the
    /// reactions back; the reproducible rows sum from the own atoms' and the
    /// ghosts' positions side by side.
    fn forces(&mut self, observe: bool, energies: bool, threads: &Threads) -> Option<PairTally> {
        match &mut self.sums {
            PairSums::Halo(halo) => {
                let halo = halo
                    .as_mut()
                    .expect("the list is built before the first forces");
                let (wanted, width) = if energies {
                    (HaloSums::PerAtom(&mut self.energies[..]), D + 2)
                } else if observe {
                    (HaloSums::Totals, D)
                } else {
                    (HaloSums::Forces, D)
                };
                self.reactions.resize(width * self.ghosts.len(), 0.0);
                let totals = halo.forces(
                    &self.atoms.positions,
                    &self.ghosts,
                    threads,
                    &mut self.atoms.forces,
                    &mut self.reactions,
                    wanted,
                );
                self.return_reactions(width);
                totals
            }
            PairSums::Ordered(rows, sums) => {
                let n = self.atoms.len();
                self.points[..n].copy_from_slice(&self.atoms.positions);
                self.points[n..].copy_from_slice(&self.ghosts);
                sums.resize(n, AtomForce::default());
                let (potential, points) = (&self.potential, &self.points);
                if observe {
                    ordered_forces::<true, D, _>(rows, potential, points, sums, threads);
                } else {
                    ordered_forces::<false, D, _>(rows, potential, points, sums, threads);
                }
                for (k, c) in sums.iter().enumerate() {
                    self.atoms.forces[k] = c.force;
                    self.energies[k] = [c.energy, c.virial];
                }
                None
            }
        }
    }

    /// With the half list, after an observed step's forces and velocities
    /// (collective; `pairs`, the energy and virial of this rank's pairs):
    /// the system's thermo sums, every rank's `[N_r, 2K_r, U_r, W_r]`
    /// gathered and added in rank order, so that the thermo needs no atom
    /// from the other ranks and its bits depend only on the rank count and
    /// the ranks' sums.
    fn add_up_thermo(&mut self, pairs: PairTally) {
        let t = Instant::now();
        let mine = [
            self.atoms.len() as f64,
            twice_kinetic(&self.atoms),
            pairs.energy,
            pairs.virial,
        ];
        let mut all = vec![0.0; mine.len() * self.world.size() as usize];
        self.world.all_gather_into(&mine[..], &mut all[..]);
        let mut sums = ThermoSums::default();
        for [atoms, kinetic, energy, virial] in all.as_chunks::<4>().0 {
            sums.add_part(
                *atoms as usize,
                *kinetic,
                PairTally {
                    energy: *energy,
                    virial: *virial,
                },
            );
        }
        self.system_sums = Some(sums);
        self.communication += t.elapsed();
    }

    /// Sends the ghosts' reactions (`width` numbers each: the force, then
    /// with `D + 2` the half energy and virial) to their owners and adds what
    /// comes back to the own atoms: each pair across a cut is computed on one
    /// rank only.
    fn return_reactions(&mut self, width: usize) {
        let t = Instant::now();
        let (forces, energies) = (&mut self.atoms.forces, &mut self.energies);
        self.plan
            .reverse(&self.world, width, &self.reactions, |k, values| {
                for (f, v) in forces[k].iter_mut().zip(values) {
                    *f += v;
                }
                if width > D {
                    energies[k][0] += values[D];
                    energies[k][1] += values[D + 1];
                }
            });
        self.communication += t.elapsed();
    }

    /// After an observed step (`energies`: that computed the own atoms'
    /// energies): rank 0 pulls its outputs ([`Hosted::serve_outputs`],
    /// [`Self::blocks`]).
    fn observe(&mut self, energies: bool) {
        self.observed = true;
        self.energies_valid = energies;
    }

    /// The own atoms' slots in ascending id: sorted once after the atoms
    /// last changed (a step or a restore forgets the order), when rank 0
    /// first pulls them, so that a step whose outputs pull no atom (the
    /// half list's thermo) sorts nothing.
    fn by_id(&self) -> &[u32] {
        self.by_id.get_or_init(|| {
            let ids = &self.atoms.ids;
            let mut order: Vec<u32> = (0..ids.len() as u32).collect();
            order.sort_unstable_by_key(|&k| ids[k as usize]);
            order
        })
    }

    /// On rank 0 after an observed step or a restore: the global state a
    /// block at a time in id order, pulled from every rank (the other ranks in
    /// [`Hosted::serve_outputs`]) and handed to `visit` until it returns false.
    fn blocks(&self, mut visit: impl FnMut(&Gathered<D>) -> bool) {
        let rows = OwnRows(self);
        pull::pull(&self.world, self.span, &rows, |ids, values| {
            visit(&gathered_of(ids, values, rows.width()))
        });
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

/// Which atoms a rank takes at set-up, before they move to their owners:
/// those that equal subdomains of `domain` would give it (generated or kept
/// by this rank alone, so that no rank holds every atom).
pub fn share_at_set_up<const D: usize>(
    world: &SimpleCommunicator,
    domain: Domain<D>,
) -> impl Fn(&[f64; D]) -> bool {
    let equal = Decomposition::new(domain, world.size() as usize);
    let rank = world.rank() as usize;
    move |x| equal.owner(x) == rank
}

/// The largest over mean atoms per subdomain of `decomposition` over every
/// rank's `atoms` (collective; integer counts: the same on every rank and
/// the same as [`Decomposition::imbalance`] of all positions).
fn imbalance_of<const D: usize>(
    world: &SimpleCommunicator,
    decomposition: &Decomposition<D>,
    atoms: &Atoms<D>,
    total: usize,
) -> f64 {
    let mut mine = vec![0u64; decomposition.ranks()];
    for x in &atoms.positions {
        mine[decomposition.owner(x)] += 1;
    }
    let mut all = vec![0u64; mine.len()];
    world.all_reduce_into(&mine[..], &mut all[..], SystemOperation::sum());
    let most = all.iter().copied().max().unwrap_or(0);
    most as f64 * decomposition.ranks() as f64 / total.max(1) as f64
}

/// What a distributed md model is: md's, with an atom count per rank that
/// changes as atoms migrate.
const INFO: ModelInfo = ModelInfo {
    count_may_change: true,
    ..md::INFO
};

impl<const D: usize> DistributedMd<D> {
    /// Advances to `step` on every rank; when any rank `observe`s, the
    /// thermo's sums (and the per-atom energies a dump wants) are made for
    /// rank 0's outputs. What the last state's outputs read is forgotten
    /// first: its id order, energies and sums.
    fn advance(&mut self, step: u64, observe: bool, threads: &Threads) -> Result<(), Blowup> {
        self.observed = false;
        self.by_id.take();
        self.energies_valid = false;
        self.system_sums = None;
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
        let energies = observe && self.energies_wanted;
        let flags = [local.is_some(), wanted, observe, late, energies].map(u8::from);
        let [failed, rebuild, observe, late, energies] = self.any(flags);
        // the reproducible rows sum the energies with the forces
        let energies = energies || (observe && matches!(self.sums, PairSums::Ordered(..)));
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
            let c = Instant::now();
            self.plan
                .positions(&self.world, &self.atoms.positions, &mut self.ghosts);
            self.communication += c.elapsed();
        }
        let t = lap(t, &mut self.times.neighbor);
        let pairs = self.forces(observe, energies, threads);
        let t = lap(t, &mut self.times.force);
        self.integrator
            .second_half(&mut self.atoms, self.dt, step, threads);
        lap(t, &mut self.times.integrate);
        let local = check(self, step, 0).err();
        self.agree_blowup(step, local)?;
        if observe {
            // the half list's pair sums: on every rank alike (observe is agreed)
            if let Some(pairs) = pairs {
                self.add_up_thermo(pairs);
            }
            self.observe(energies);
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

    /// After set-up or an observed step (when the driver reads it): with the
    /// half list, from the ranks' sums added up after the step
    /// (`add_up_thermo`); with the reproducible rows, summed on rank
    /// 0 over every rank's atoms in id order, a block at a time (collective:
    /// the other ranks serve the pulls), so that its bits do not depend on
    /// the rank count.
    fn thermo(&self, _step: u64) -> Vec<f64> {
        let volume = self.decomposition.domain.volume();
        let th = match self.system_sums {
            Some(sums) => sums.thermo::<D>(volume),
            None => {
                let mut sums = ThermoSums::default();
                self.blocks(|g| {
                    sums.add(&g.atoms, &g.energies, &g.virials);
                    true
                });
                sums.thermo::<D>(volume)
            }
        };
        vec![th.temp, th.pe, th.ke, th.etotal, th.press]
    }

    fn checked(&self) -> Checked<'_> {
        checked_atoms(&self.atoms, &self.decomposition.domain)
    }

    /// On rank 0 every atom (sorted by id, positions wrapped), pulled from
    /// every rank; `None` on the other ranks.
    fn particles(&self, step: u64, energies: bool) -> Option<Particles> {
        whole_frame(self, step, energies)
    }

    /// On rank 0 the atoms sorted by id a block at a time, pulled from every
    /// rank; false on the other ranks.
    fn particle_blocks(
        &self,
        _step: u64,
        energies: bool,
        visit: &mut dyn FnMut(ParticleBlock<'_>) -> ControlFlow<()>,
    ) -> bool {
        if self.world.rank() != 0 {
            return false;
        }
        let mut first = 0;
        let total = self.total;
        self.blocks(|g| {
            let energies = (energies && self.energies_valid).then(|| g.energies.clone());
            let rows = dump_particles(
                &g.atoms,
                energies,
                &self.decomposition.domain,
                self.z_bounds,
            );
            let go_on = visit(ParticleBlock {
                total,
                first,
                rows: &rows,
            })
            .is_continue();
            first += g.atoms.len();
            go_on
        });
        true
    }

    fn stage_times(&self) -> Vec<(&'static str, Duration)> {
        self.times.stages()
    }

    /// This rank's part of the state: its own atoms in the layout of
    /// [`save_atoms`], marked with the rank and the rank count (every rank
    /// saves at the same steps; a checkpoint file holds the global state,
    /// [`Hosted::file_state`]).
    fn save(&self, state: &mut State) {
        save_atoms(state, &self.atoms, self.reference(), self.counts);
        mark_part(&self.world, state);
    }

    /// Takes the atoms this rank owns: from its own part of the state
    /// ([`Model::save`] of this rank), or from a global state (a checkpoint
    /// file of any number of ranks, or of one process). The next step
    /// migrates and rebuilds. Not collective: a rank that fails returns its
    /// error alone.
    fn restore(&mut self, state: &dyn SectionSource, _threads: &Threads) -> Result<(), StateError> {
        self.observed = true;
        let rank = self.world.rank() as usize;
        let (atoms, reference, counts) = if is_own_part(&self.world, state)? {
            load_atoms::<D>(state, state.count("ids")?)?
        } else {
            let decomposition = &self.decomposition;
            load_atoms_where::<D>(state, self.total, |p| decomposition.owner(p) == rank)?
        };
        if atoms.positions.iter().flatten().any(|c| !c.is_finite()) {
            return Err(StateError("a saved position is not finite".into()));
        }
        self.energies.clear();
        self.energies.resize(atoms.len(), [0.0; 2]);
        self.atoms = atoms;
        self.restored_reference = Some(reference);
        self.counts = counts;
        self.stale = true;
        self.in_slot_order = false;
        self.energies_valid = false;
        self.system_sums = None;
        self.by_id.take();
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

    /// The step ends with [`check`] of the own atoms, agreed over the ranks.
    fn checks_its_steps(&self) -> bool {
        true
    }

    /// Whether this rank's dump reads per-atom energies after the coming
    /// observed step: the half list then makes its energy pass (any rank's
    /// wish, all-reduced with the step's flags).
    fn want_particle_energies(&mut self, wanted: bool) {
        self.energies_wanted = wanted;
    }

    /// After an observed step (or a restore): on rank 0, tells the other
    /// ranks that its outputs are written; on the others, serves rank 0's
    /// pulls of their atoms until then.
    fn serve_outputs(&self) {
        if self.observed_everywhere() {
            pull::serve_until_written(&self.world, &OwnRows(self));
        }
    }

    /// True after a step that any rank observed, and after a restore.
    fn observed_everywhere(&self) -> bool {
        self.observed
    }

    /// On rank 0 the global state sorted by id in the single-process layout
    /// ([`save_atoms`]), pulled from every rank's current atoms (the state
    /// just saved or restored) a block at a time and written as it comes;
    /// a distributed checkpoint restarts in one process or on any number of
    /// ranks. The other ranks' `saved`.
    fn file_state<'a>(&'a self, saved: &'a State) -> FileState<'a> {
        if self.world.rank() != 0 {
            return FileState::Saved(saved);
        }
        let mut layout = Layout::default();
        let mut atoms = SavedAtoms::<D>::new(self.total, &mut layout);
        FileState::Spread(
            layout,
            Box::new(move |sink| {
                self.blocks(|g| {
                    atoms.push(sink, &g.atoms, &g.reference);
                    !sink.failed()
                });
                atoms.finish(sink, self.counts);
            }),
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
    /// The own atoms' positions at the last rebuild (or as restored).
    fn reference(&self) -> &[[f64; D]] {
        self.restored_reference
            .as_deref()
            .unwrap_or_else(|| self.sums.reference())
    }

    /// Largest over mean atoms per rank, mean over the rebuilds.
    fn mean_imbalance(&self) -> f64 {
        self.imbalance_sum / self.imbalance_count.max(1) as f64
    }
}
