//! Diffusion by particle strength exchange by domain decomposition: the
//! particles do not move, so each rank owns the particles of its subdomain for
//! the whole run, receives the ghosts within the kernel's cutoff once (their
//! ids and shifted positions), and at every stage of the integrator receives
//! the ghosts' field values along the same plan. Each owned particle's rate
//! sums its id-sorted row ([`ordered_rate`]), so the run gives the same bits on
//! any number of ranks and threads.
//!
//! Rank 0 keeps the whole single-process model as the replica that outputs
//! read: at every observed step the field is gathered into it, and its thermo,
//! field files, pictures and checkpoints (of the global state, in the
//! single-process layout) are those of a plain run.

use super::{agree, agree_blowup, exchange, GhostPlan, LocalParticles};
use crate::hosted::{Distribution, Hosted};
use cellist::decomposition::{Balance, Decomposition, Images};
use cellist::models::pse::{
    self, advance, ordered_rate, row_weights, Method, PairWeight, PseError, PseModel,
};
use cellist::models::{Blowup, Checked, CheckedArray, Field, Ids, Model, ModelInfo};
use cellist::neighbors::OrderedRows;
use cellist::state::{SectionSource, State, StateError};
use cellist::Threads;
use mpi::collective::SystemOperation;
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;
use std::time::{Duration, Instant};

/// The pse model of one rank of a distributed run.
pub struct DistributedPse<const D: usize> {
    world: SimpleCommunicator,
    integrator: cellist::models::pse::Integrator,
    dt: f64,
    /// Rank 0: the single-process model whose field is set at observed steps.
    replica: Option<PseModel<D>>,
    /// `order[slot]`: the input index of the particle in slot `slot` of the
    /// single-process model (the layout of checkpoints).
    order: Vec<u32>,
    total: usize,
    /// Input indices of the own particles.
    ids: Vec<u64>,
    phi: Vec<f64>,
    plan: GhostPlan<D>,
    rows: OrderedRows<D>,
    weights: Vec<f64>,
    /// Own then ghost values of the field a stage reads.
    values: Vec<f64>,
    stages: [Vec<f64>; 4],
    trial: Vec<f64>,
    entries: u64,
    /// Largest over mean row entries per rank (the work of a rate).
    imbalance: f64,
    /// Largest over mean particles per rank.
    particle_imbalance: f64,
    step_time: Duration,
    communication: Duration,
}

impl<const D: usize> DistributedPse<D> {
    /// This rank's part of `model` (built from the scenario on every rank): the
    /// particles of its subdomain, their ghosts within the cutoff and the fixed
    /// pair weights of their rows; the planes placed as `balance` says, once
    /// (the particles do not move). Only the cell-list method runs
    /// distributed; a subdomain thinner than the cutoff is refused. Every rank
    /// returns the same error.
    pub fn new(
        world: SimpleCommunicator,
        model: PseModel<D>,
        balance: Balance,
        threads: &Threads,
    ) -> Result<Self, String> {
        let system = &model.system;
        let params = *system.params();
        let Method::CellList { cutoff_factor } = params.method else {
            return Err(format!(
                "pse.method \"direct\" (all pairs) does not run on {} MPI ranks: use \
                 method = \"cell-list\", or run in one process",
                world.size()
            ));
        };
        let cutoff = cutoff_factor * params.epsilon;
        let domain = *system.domain();
        let positions = system.positions();
        let ranks = world.size() as usize;
        let decomposition =
            Decomposition::for_particles(domain, ranks, balance, &positions, cutoff)?;
        let rank = world.rank() as usize;
        let field = system.phi();
        let mine: Vec<usize> = (0..positions.len())
            .filter(|&k| decomposition.owner(&positions[k]) == rank)
            .collect();
        let own: Vec<[f64; D]> = mine.iter().map(|&k| positions[k]).collect();
        let ids: Vec<u64> = mine.iter().map(|&k| k as u64).collect();
        let t = Instant::now();
        let plan = GhostPlan::new(&world, &decomposition, &own, cutoff, Images::All);
        let ghost_ids = plan.ids(&world, &ids);
        let mut points = own.clone();
        points.resize(own.len() + ghost_ids.len(), [0.0; D]);
        let mut plan = plan;
        plan.positions(&world, &own, &mut points[own.len()..]);
        let communication = t.elapsed();
        let mut keys = ids.clone();
        keys.extend_from_slice(&ghost_ids);
        let rows = OrderedRows::build(&points, own.len(), &keys, cutoff, 0.0, threads);
        let failure = rows.as_ref().err().map(|e| e.to_string());
        if let Some(message) = agree(&world, failure) {
            return Err(message);
        }
        let rows = rows.expect("no rank failed");
        let weight = PairWeight::new(D, params.nu, params.epsilon, system.volume());
        let weights = row_weights(&rows, &weight, &points, cutoff);
        let mut entries = 0u64;
        world.all_reduce_into(
            &(rows.num_entries() as u64),
            &mut entries,
            SystemOperation::sum(),
        );
        // the particles never move: the count over the ranks is checked once
        let mut count = 0u64;
        world.all_reduce_into(&(own.len() as u64), &mut count, SystemOperation::sum());
        if count as usize != positions.len() {
            return Err(format!(
                "the ranks own {count} particles between them, not {}: a bug in cellist's decomposition",
                positions.len()
            ));
        }
        let mut most = 0u64;
        world.all_reduce_into(
            &(rows.num_entries() as u64),
            &mut most,
            SystemOperation::max(),
        );
        let imbalance = most as f64 * world.size() as f64 / entries.max(1) as f64;
        let n = own.len();
        let mut most_particles = 0u64;
        world.all_reduce_into(&(n as u64), &mut most_particles, SystemOperation::max());
        let particle_imbalance = most_particles as f64 * world.size() as f64 / count.max(1) as f64;
        Ok(DistributedPse {
            integrator: model.integrator,
            dt: model.dt,
            order: system.order().to_vec(),
            total: positions.len(),
            phi: mine.iter().map(|&k| field[k]).collect(),
            ids,
            values: vec![0.0; n + ghost_ids.len()],
            stages: std::array::from_fn(|_| vec![0.0; n]),
            trial: vec![0.0; n],
            plan,
            rows,
            weights,
            entries,
            imbalance,
            particle_imbalance,
            step_time: Duration::ZERO,
            communication,
            replica: (rank == 0).then_some(model),
            world,
        })
    }

    /// The number of particles over all ranks.
    pub fn total(&self) -> usize {
        self.total
    }

    /// The field of every particle, gathered into rank 0's replica.
    fn gather(&mut self) {
        let t = Instant::now();
        let mut outgoing = vec![
            LocalParticles {
                width: 1,
                ..LocalParticles::default()
            };
            self.world.size() as usize
        ];
        outgoing[0] = LocalParticles {
            ids: self.ids.clone(),
            values: self.phi.clone(),
            width: 1,
        };
        let all = exchange(&self.world, &outgoing, 1);
        self.communication += t.elapsed();
        if let Some(replica) = &mut self.replica {
            let mut by_input = vec![0.0; self.total];
            for (&id, &v) in all.ids.iter().zip(&all.values) {
                by_input[id as usize] = v;
            }
            let slots: Vec<f64> = self.order.iter().map(|&k| by_input[k as usize]).collect();
            replica
                .system
                .set_slot_phi(&slots)
                .expect("one value per particle");
        }
    }
}

/// What a distributed pse model is: pse's, with a particle count per rank
/// that is not the run's.
const INFO: ModelInfo = ModelInfo {
    count_may_change: true,
    ..pse::INFO
};

impl<const D: usize> DistributedPse<D> {
    /// Advances to `step` on every rank; the field is gathered into rank 0's
    /// replica when any rank `observe`s.
    fn advance(&mut self, step: u64, observe: bool, threads: &Threads) -> Result<(), Blowup> {
        let t = Instant::now();
        let DistributedPse {
            world,
            plan,
            rows,
            weights,
            values,
            phi,
            stages,
            trial,
            communication,
            ..
        } = self;
        let n = phi.len();
        let rate = |field: &[f64], out: &mut [f64]| {
            values[..n].copy_from_slice(field);
            let c = Instant::now();
            plan.values(world, field, &mut values[n..]);
            *communication += c.elapsed();
            ordered_rate(rows, weights, values, out, threads);
        };
        advance(self.integrator, self.dt, phi, stages, trial, rate, threads);
        self.step_time += t.elapsed();
        let bad = self.phi.iter().position(|v| !v.is_finite()).map(|k| {
            let index = self.ids[k] as usize;
            Blowup::new(step, PseError::NotFinite { index }.to_string(), INFO.remedy)
        });
        let c = Instant::now();
        let agreed = agree_blowup(&self.world, step, bad);
        self.communication += c.elapsed();
        if let Some(blowup) = agreed {
            return Err(blowup);
        }
        let mut observe_any = 0u8;
        self.world
            .all_reduce_into(&u8::from(observe), &mut observe_any, SystemOperation::max());
        if observe_any != 0 {
            self.gather();
        }
        Ok(())
    }
}

impl<const D: usize> Model for DistributedPse<D> {
    fn info(&self) -> &ModelInfo {
        &INFO
    }

    /// The particles this rank owns (they never move between ranks).
    fn len(&self) -> usize {
        self.ids.len()
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

    /// Rank 0's replica's thermo (its field gathered at this step).
    fn thermo(&self, step: u64) -> Vec<f64> {
        self.replica
            .as_ref()
            .map_or_else(Vec::new, |r| r.thermo(step))
    }

    /// The own particles' field (checked by the step on every rank).
    fn checked(&self) -> Checked<'_> {
        let field = CheckedArray {
            quantity: "field",
            values: &self.phi,
            per_particle: 1,
        };
        Checked::new(Ids::U64(&self.ids), vec![field])
    }

    fn field(&self) -> Option<Field> {
        self.replica.as_ref()?.field()
    }

    fn stage_times(&self) -> Vec<(&'static str, Duration)> {
        vec![("Rates", self.step_time)]
    }

    /// Rank 0's replica's state: the global field in the single-process layout.
    fn save(&self, state: &mut State) {
        if let Some(r) = &self.replica {
            r.save(state);
        }
    }

    /// Takes the own particles' values from a global state (of any number of
    /// ranks or of one process); rank 0's replica takes all of it. Not
    /// collective.
    fn restore(&mut self, state: &dyn SectionSource, threads: &Threads) -> Result<(), StateError> {
        if let Some(r) = &mut self.replica {
            r.restore(state, threads)?;
        }
        let slots = state.f64s_of("phi", self.total)?;
        let mut by_input = vec![0.0; self.total];
        for (slot, &k) in self.order.iter().enumerate() {
            by_input[k as usize] = slots[slot];
        }
        for (v, &id) in self.phi.iter_mut().zip(&self.ids) {
            *v = by_input[id as usize];
        }
        Ok(())
    }
}

impl<const D: usize> Hosted for DistributedPse<D> {
    /// Row entries per second over the ranks, the communication and the load
    /// imbalance.
    fn speed(&self, loop_seconds: f64, steps: u64, threads: usize) -> String {
        let evaluations = self.entries * self.integrator.stages() * steps;
        format!(
            "Loop time of {loop_seconds:.4} s on {} ranks x {threads} thread(s) for {steps} steps \
             with {} particles: {:.3e} row entries per second (each pair on both sides)\n\
             Communication {:.4} s on rank 0 ({:.1}% of the loop); load imbalance {:.3} \
             (largest over mean row entries per rank)",
            self.world.size(),
            self.total,
            evaluations as f64 / loop_seconds.max(1e-12),
            self.communication.as_secs_f64(),
            100.0 * self.communication.as_secs_f64() / loop_seconds.max(1e-300),
            self.imbalance,
        )
    }

    /// This rank's communication time, the balance of the particles (fixed:
    /// they never move) and their count.
    fn distribution(&self) -> Option<Distribution> {
        Some(Distribution {
            communication: self.communication,
            imbalance_particles: self.particle_imbalance,
            particles: self.total,
        })
    }
}
