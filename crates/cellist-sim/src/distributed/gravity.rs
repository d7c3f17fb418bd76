//! Gravity's direct sum, mesh solvers, Barnes-Hut tree and fmm on several ranks
//! with the bodies divided among them: rank `r` owns the bodies
//! `N r / P .. N (r + 1) / P` of the input order for the whole run (no
//! solver cares which rank holds a body), steps them, and sums their field
//! over every rank's bodies: the direct sum by seed 003's ring pass
//! ([`RingGravity`]), particle-mesh and P3M on a slab-decomposed mesh to
//! whose slabs (and P3M's slabs of cells) the bodies travel, and the tree by
//! locally essential trees, the bodies travelling to the ranks of their
//! parts of the tree, and the fmm with every body gathered on every rank at
//! each evaluation and the target groups dealt out ([`SpreadGravity`]).
//! Through the steps a rank holds its `N / P` bodies and the block in flight
//! on the ring, or the bodies routed to its slabs, or those routed to its
//! part of the tree and the nodes and bodies of the other parts that its
//! walks reach, or (the fmm) every body, in buffers kept from step to
//! step. Above 20,000 bodies no rank holds the whole system at any time
//! but the fmm's evaluations: at set-up each rank makes only its block (the
//! Plummer sphere's draws streamed; a smaller sphere is made whole on every
//! rank for its exact virial, then cut; the body file read twice, its block
//! kept), a restart reads its block of the checkpoint, and the outputs take
//! a block at a time.
//!
//! ```text
//! step:  kick + drift of the own bodies (the integrator's first part)
//!        the field at the own bodies (the ring pass, the mesh, the tree or
//!          the fmm)
//!        kick (leapfrog's second half); check the own bodies
//!        all-reduces: a blow-up on any rank (the lowest one's message), then
//!          observed?; observed: the box of all bodies (two more)
//! ```
//!
//! Rank 0 writes every output, pulling the bodies from every rank a block of
//! ids at a time in id order ([`super::pull`]) while the other ranks serve
//! its asks: dumps, pictures and checkpoints (in the single-process layout,
//! so a checkpoint of `P` ranks restarts in one process or on any number of
//! ranks) are those of a plain run, and the thermo sums run over the bodies
//! in id order as one process sums them. The ring's forces follow its order
//! (each body's sum over the blocks, its own first), so a run agrees with
//! one process to rounding; the meshes' accelerations are those of one
//! process to the bit, their potentials to rounding; the tree's and the
//! fmm's fields are those of one process to the bit.

use super::mesh::MpiExchange;
use super::parts::{imbalance, Figures};
use super::pull::{self, IdSpan, OwnRows};
use super::ring::{blocks, RingGravity};
use super::{agree, agree_blowup, is_own_part, mark_part};
use crate::hosted::{Distribution, FileState, Hosted};
use cellist::geometry::{bounding_box, empty_box, widen_box};
use cellist::interactions::GravityLaw;
use cellist::longrange::Exchange;
use cellist::longrange::{
    BarnesHut, FieldOut, FieldSolver, FmmAccuracy, GravityFmm, MeshParams, P3m, ParticleMesh, Rank,
    Sources, TreeParams,
};
use cellist::models::gravity::{
    body_particles, check_bodies_among, checked_bodies, load_bodies, save_bodies, thermo_row,
    Bodies, GravityError, GravitySystem, Integrator, Observables, SavedBodies, Solver,
    INFO as GRAVITY,
};
use cellist::models::{
    whole_frame, Blowup, Checked, Ids, Model, ModelInfo, ParticleBlock, Particles,
};
use cellist::state::{Layout, SectionSource, State, StateError};
use cellist::Threads;
use mpi::collective::SystemOperation;
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;
use std::ops::{ControlFlow, Range};
use std::time::{Duration, Instant};

/// Numbers per body in a pulled row: `x y z vx vy vz m ax ay az phi`.
const ROW: usize = 11;

/// The box of every body at the last observed step, in one rank's part:
/// `lo` then `hi`.
const BOUNDS: &str = "bounds";

/// What a distributed gravity model is: gravity's, with a body count per rank
/// that is not the run's.
const INFO: ModelInfo = ModelInfo {
    count_may_change: true,
    ..GRAVITY
};

/// How a rank's bodies get their field from every rank's.
#[derive(Clone, Copy, Debug)]
pub enum SpreadField {
    /// The direct sum by the ring pass.
    Ring,
    /// The particle-mesh solver on a slab-decomposed mesh with these
    /// settings.
    Pm(MeshParams),
    /// P3M on a slab-decomposed mesh with these settings and its splitting
    /// radius in mesh cells.
    P3m(MeshParams, f64),
    /// The Barnes-Hut tree with these settings, by locally essential trees.
    Tree(TreeParams),
    /// The fmm at this accuracy, every rank gathering every body and summing
    /// a run of the target groups.
    Fmm(FmmAccuracy),
}

impl SpreadField {
    /// The field solver over this rank's own bodies under `law`, and the
    /// figures of its messages; the error of a mesh the ranks cannot share.
    fn solver(
        self,
        world: &SimpleCommunicator,
        law: GravityLaw,
    ) -> Result<(Solver, Figures), String> {
        let rank = Rank {
            index: world.rank() as usize,
            count: world.size() as usize,
        };
        let (solver, exchange) = match self {
            SpreadField::Ring => {
                let solver = RingGravity::new(world.duplicate(), law);
                let figures = solver.figures();
                return Ok((Solver::External(Box::new(solver)), figures));
            }
            SpreadField::Pm(params) => (
                SpreadSolver::Pm(ParticleMesh::on_rank(law, params, rank)?),
                MpiExchange::routing(world.duplicate()),
            ),
            SpreadField::P3m(params, split) => (
                SpreadSolver::P3m(P3m::on_rank(law, params, split, rank)?),
                MpiExchange::routing(world.duplicate()),
            ),
            SpreadField::Tree(params) => (
                SpreadSolver::Tree(BarnesHut::new(law, params)?),
                MpiExchange::essential(world.duplicate()),
            ),
            SpreadField::Fmm(accuracy) => (
                SpreadSolver::Fmm(GravityFmm::new(law, accuracy)?),
                MpiExchange::gathering(world.duplicate()),
            ),
        };
        let figures = exchange.figures();
        let solver = SpreadGravity { solver, exchange };
        Ok((Solver::External(Box::new(solver)), figures))
    }
}

/// Gravity's solvers whose bodies travel among the ranks (to the slabs or
/// the tree's parts, or to every rank for the fmm).
#[derive(Debug)]
// built once per run and matched once per step: its size does not matter
#[allow(clippy::large_enum_variant)]
pub enum SpreadSolver {
    /// Particle-mesh.
    Pm(ParticleMesh),
    /// P3M.
    P3m(P3m),
    /// The Barnes-Hut tree.
    Tree(BarnesHut),
    /// The fmm.
    Fmm(GravityFmm),
}

/// Gravity's mesh, tree or fmm solver on several ranks, the bodies divided among
/// them: the engine's [`FieldSolver`] over a rank's own bodies, the ranks'
/// bodies following each other in rank order
/// ([`ParticleMesh::compute_spread`], [`P3m::compute_spread`],
/// [`BarnesHut::compute_spread`], [`GravityFmm::compute_spread`]).
pub struct SpreadGravity {
    solver: SpreadSolver,
    exchange: MpiExchange,
}

impl std::fmt::Debug for SpreadGravity {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{:?} on {} ranks", self.solver, self.exchange.ranks())
    }
}

impl FieldSolver for SpreadGravity {
    fn compute(&mut self, sources: &Sources, out: FieldOut, threads: &Threads) {
        let exchange = &self.exchange;
        match &mut self.solver {
            SpreadSolver::Pm(s) => s.compute_spread(sources, out, threads, exchange),
            SpreadSolver::P3m(s) => s.compute_spread(sources, out, threads, exchange),
            SpreadSolver::Tree(s) => s.compute_spread(sources, out, threads, exchange),
            SpreadSolver::Fmm(s) => s.compute_spread(sources, out, threads, exchange),
        }
    }
}

/// The gravity model of one rank of a distributed run (direct sum, PM, P3M,
/// Barnes-Hut or fmm).
pub struct DistributedGravity {
    world: SimpleCommunicator,
    /// The own bodies, their field by the ring, the mesh, the tree or the fmm.
    system: GravitySystem,
    integrator: Integrator,
    dt: f64,
    /// 2 for bodies in the plane z = 0, else 3.
    dimension: usize,
    /// The energy at step 0.
    e0: f64,
    /// The own bodies' places in the input order (0-based).
    own: Range<usize>,
    /// The bodies over all ranks.
    total: usize,
    /// The box `(lo, hi)` of every body at the last observed step.
    bounds: ([f64; 3], [f64; 3]),
    /// Any rank observed the last step (or the state was restored): rank 0
    /// pulls its outputs.
    observed: bool,
    /// Largest over mean bodies per rank.
    imbalance: f64,
    /// The field solver's time in messages (the ring's waiting, the mesh's
    /// transposes and routes, the tree's or the fmm's gathers).
    field: Figures,
    /// The field solver's time in messages at set-up (the first forces),
    /// not the loop's.
    setup_wait: Duration,
    /// The time in the steps' other messages: the blow-up's agreement, the
    /// observed flag and the box.
    communication: Duration,
    step_time: Duration,
}

impl DistributedGravity {
    /// This rank's bodies `mine`, its block of the `total` bodies in input
    /// order (rank `r` of `P` holds `total r / P .. total (r + 1) / P`), under
    /// `law`, their field by `field`, stepped by `integrator` with `dt`; the
    /// checks of every rank's bodies and the first forces. Collective; every
    /// rank returns the same error.
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        world: SimpleCommunicator,
        law: GravityLaw,
        (mine, total): (Bodies, usize),
        field: SpreadField,
        integrator: Integrator,
        dt: f64,
        dimension: usize,
        threads: &Threads,
    ) -> Result<Self, String> {
        let (bounds, own) = blocks(total, &world);
        assert_eq!(mine.len(), own.len(), "the bodies of this rank's block");
        // the checks of every rank's bodies, so that all give the same message
        let peers = MpiExchange::new(world.duplicate());
        check_bodies_among(&law, &mine, own.start, &peers).map_err(|e| e.to_string())?;
        // every rank builds the same mesh, so that all give the same message
        let (solver, field) = field.solver(&world, law)?;
        let system = GravitySystem::with_solver(law, mine, solver, threads);
        let failure = system
            .as_ref()
            .err()
            .map(|e| format!("step 0 (the first forces): {}", global(e, own.start)));
        if let Some(message) = agree(&world, failure) {
            return Err(message);
        }
        let system = system.expect("no rank failed");
        let mut model = DistributedGravity {
            imbalance: imbalance(&bounds),
            setup_wait: field.waited(),
            world,
            system,
            integrator,
            dt,
            dimension,
            e0: 0.0,
            own,
            total,
            bounds: ([0.0; 3], [0.0; 3]),
            observed: true,
            field,
            communication: Duration::ZERO,
            step_time: Duration::ZERO,
        };
        model.bounds = model.box_of_all();
        let mut e0 = 0.0;
        if model.world.rank() == 0 {
            e0 = model.observables().total();
        }
        pull::serve_until_written(&model.world, &Rows(&model));
        model.world.process_at_rank(0).broadcast_into(&mut e0);
        model.e0 = e0;
        Ok(model)
    }

    /// Advances to `step` on every rank; the box of all bodies is found when
    /// any rank `observe`s.
    fn advance(&mut self, step: u64, observe: bool, threads: &Threads) -> Result<(), Blowup> {
        let t = Instant::now();
        let stepped = self.system.step(self.dt, self.integrator, threads);
        self.step_time += t.elapsed();
        let bad = stepped
            .err()
            .map(|e| Blowup::new(step, global(&e, self.own.start), INFO.remedy));
        let c = Instant::now();
        let agreed = agree_blowup(&self.world, step, bad);
        self.communication += c.elapsed();
        if let Some(blowup) = agreed {
            return Err(blowup);
        }
        let c = Instant::now();
        let mut observe_any = 0u8;
        self.world
            .all_reduce_into(&u8::from(observe), &mut observe_any, SystemOperation::max());
        self.observed = observe_any != 0;
        if self.observed {
            self.bounds = self.box_of_all();
        }
        self.communication += c.elapsed();
        Ok(())
    }

    /// The box `(lo, hi)` of every rank's bodies (collective).
    fn box_of_all(&self) -> ([f64; 3], [f64; 3]) {
        let position = &self.system.bodies().position;
        // a rank without bodies adds nothing to the minimum and the maximum
        let (lo, hi) = if position.is_empty() {
            empty_box()
        } else {
            bounding_box(position)
        };
        let (mut all_lo, mut all_hi) = ([0.0; 3], [0.0; 3]);
        self.world
            .all_reduce_into(&lo[..], &mut all_lo[..], SystemOperation::min());
        self.world
            .all_reduce_into(&hi[..], &mut all_hi[..], SystemOperation::max());
        (all_lo, all_hi)
    }

    /// On rank 0: every rank's bodies a block of ids at a time, in id order,
    /// as `visit(ids, rows)` ([`ROW`] numbers each) until it returns false.
    /// The other ranks must serve ([`Hosted::serve_outputs`]).
    fn blocks(&self, visit: impl FnMut(&[u64], &[f64]) -> bool) {
        let span = IdSpan {
            first: 1,
            last: self.total as u64,
            count: self.total,
        };
        pull::pull(&self.world, span, &Rows(self), visit);
    }

    /// The field solver's time in messages since set-up.
    fn field_wait(&self) -> Duration {
        self.field.waited().saturating_sub(self.setup_wait)
    }

    /// On rank 0: the energies and momenta of every body, summed in id
    /// order as one process sums them.
    fn observables(&self) -> Observables {
        let mut o = Observables::default();
        self.blocks(|_, rows| {
            for r in rows.chunks_exact(ROW) {
                o.add_body(r[6], [r[0], r[1], r[2]], [r[3], r[4], r[5]], r[10]);
            }
            true
        });
        o
    }
}

/// `e` with the body it names numbered in the input order, the own bodies
/// starting at `first`.
fn global(e: &GravityError, first: usize) -> String {
    match e {
        GravityError::NotFinite { index } => GravityError::NotFinite {
            index: index + first,
        }
        .to_string(),
        GravityError::Parameter(m) => m.clone(),
    }
}

/// A block of pulled rows as bodies, their accelerations and potentials.
fn bodies_of(rows: &[f64]) -> (Bodies, Vec<[f64; 3]>, Vec<f64>) {
    let mut bodies = Bodies::default();
    let (mut acc, mut phi) = (Vec::new(), Vec::new());
    for r in rows.chunks_exact(ROW) {
        bodies.position.push([r[0], r[1], r[2]]);
        bodies.velocity.push([r[3], r[4], r[5]]);
        bodies.mass.push(r[6]);
        acc.push([r[7], r[8], r[9]]);
        phi.push(r[10]);
    }
    (bodies, acc, phi)
}

/// A rank's bodies as rows for rank 0's pulls, ids `1..=N` in input order.
struct Rows<'a>(&'a DistributedGravity);

impl OwnRows for Rows<'_> {
    fn width(&self) -> usize {
        ROW
    }

    fn rows(&self, a: u64, b: u64, ids: &mut Vec<u64>, values: &mut Vec<f64>) {
        ids.clear();
        values.clear();
        let model = self.0;
        let first = model.own.start as u64 + 1;
        let (lo, hi) = (a.max(first), b.min(model.own.end as u64 + 1));
        let bodies = model.system.bodies();
        let (acc, phi) = (model.system.accelerations(), model.system.potentials());
        for id in lo..hi.max(lo) {
            let k = (id - first) as usize;
            let (x, v) = (bodies.position[k], bodies.velocity[k]);
            ids.push(id);
            values.extend_from_slice(&[x[0], x[1], x[2], v[0], v[1], v[2], bodies.mass[k]]);
            values.extend_from_slice(&acc[k]);
            values.push(phi[k]);
        }
    }
}

impl Model for DistributedGravity {
    fn info(&self) -> &ModelInfo {
        &INFO
    }

    /// The bodies this rank owns (they never move between ranks).
    fn len(&self) -> usize {
        self.own.len()
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

    /// On rank 0, the row of one process ([`thermo_row`]), its sums over
    /// every body in id order (pulled; the other ranks serve); empty on the
    /// others.
    fn thermo(&self, step: u64) -> Vec<f64> {
        if self.world.rank() != 0 {
            return Vec::new();
        }
        thermo_row(&self.observables(), self.e0, step as f64 * self.dt)
    }

    /// The own bodies' state (checked by the step on every rank).
    fn checked(&self) -> Checked<'_> {
        let field = (self.system.accelerations(), self.system.potentials());
        checked_bodies(
            Ids::From(self.own.start as u64),
            self.system.bodies(),
            field,
        )
    }

    /// On rank 0 every body in input order, pulled from every rank; `None`
    /// on the others.
    fn particles(&self, step: u64, energies: bool) -> Option<Particles> {
        whole_frame(self, step, energies)
    }

    /// On rank 0 the bodies in input order a block at a time, pulled from
    /// every rank, in the box of all bodies; false on the others.
    fn particle_blocks(
        &self,
        _step: u64,
        _energies: bool,
        visit: &mut dyn FnMut(ParticleBlock<'_>) -> ControlFlow<()>,
    ) -> bool {
        if self.world.rank() != 0 {
            return false;
        }
        let mut first = 0;
        self.blocks(|ids, rows| {
            let (bodies, acc, phi) = bodies_of(rows);
            let rows = body_particles(
                self.dimension,
                self.bounds,
                ids.to_vec(),
                &bodies,
                (&acc, &phi),
            );
            let go_on = visit(ParticleBlock {
                total: self.total,
                first,
                rows: &rows,
            })
            .is_continue();
            first += ids.len();
            go_on
        });
        true
    }

    fn stage_times(&self) -> Vec<(&'static str, Duration)> {
        vec![("Step", self.step_time)]
    }

    /// This rank's part of the state: its own bodies in the layout of
    /// [`save_bodies`], the box of all bodies, marked with the rank and the
    /// rank count (every rank saves at the same steps; a checkpoint file
    /// holds the global state, [`Hosted::file_state`]).
    fn save(&self, state: &mut State) {
        let field = (self.system.accelerations(), self.system.potentials());
        save_bodies(state, self.system.bodies(), field, self.e0);
        let (lo, hi) = self.bounds;
        state.put_f64s(BOUNDS, lo.into_iter().chain(hi));
        mark_part(&self.world, state);
    }

    /// Takes the bodies this rank owns: from its own part of the state
    /// ([`Model::save`] of this rank), or from a global state (a checkpoint
    /// file of any number of ranks, or of one process). Not collective: a
    /// rank that fails returns its error alone.
    fn restore(&mut self, state: &dyn SectionSource, _threads: &Threads) -> Result<(), StateError> {
        self.observed = true;
        let (bodies, acc, phi, e0, bounds) = if is_own_part(&self.world, state)? {
            let (bodies, acc, phi, e0) = load_bodies(state, self.len(), 0..self.len())?;
            let b = state.f64s_of(BOUNDS, 6)?;
            let bounds = ([b[0], b[1], b[2]], [b[3], b[4], b[5]]);
            (bodies, acc, phi, e0, bounds)
        } else {
            let (bodies, acc, phi, e0) = load_bodies(state, self.total, self.own.clone())?;
            (bodies, acc, phi, e0, bounds_of_all(state, self.total)?)
        };
        self.e0 = e0;
        self.bounds = bounds;
        self.system.restore(bodies, acc, phi).map_err(StateError)
    }
}

/// The bodies whose positions [`bounds_of_all`] reads at once.
const BOUNDS_BLOCK: usize = 1 << 13;

/// The box of the `n` bodies of a global state, their positions read a
/// block at a time in order: the box [`bounding_box`] gives of them all.
fn bounds_of_all(state: &dyn SectionSource, n: usize) -> Result<([f64; 3], [f64; 3]), StateError> {
    if n == 0 {
        return Ok(bounding_box::<3>(&[]));
    }
    let mut bounds = empty_box();
    for start in (0..n).step_by(BOUNDS_BLOCK) {
        let block = state.vectors_at::<3>("position", start, BOUNDS_BLOCK.min(n - start))?;
        widen_box(&mut bounds, &block);
    }
    Ok(bounds)
}

impl Hosted for DistributedGravity {
    /// Seconds per step, the field solver's time in messages (the ring's
    /// waiting, the mesh's transposes and routes, the tree's or the fmm's
    /// gathers), the other messages' and the balance of the blocks.
    fn speed(&self, loop_seconds: f64, steps: u64, threads: usize) -> String {
        let waited = self.field_wait().as_secs_f64();
        let share = |s: f64| 100.0 * s / loop_seconds.max(1e-300);
        format!(
            "Loop time of {loop_seconds:.4} s on {} ranks x {threads} thread(s) for {steps} \
             steps with {} bodies: {:.4e} s per step\n\
             {}: {waited:.4} s on rank 0 {} ({:.1}% of the loop); other messages {:.4} s \
             ({:.1}%); load imbalance {:.3} (largest over mean bodies per rank)",
            self.world.size(),
            self.total,
            loop_seconds / steps.max(1) as f64,
            self.field.method,
            self.field.waiting,
            share(waited),
            self.communication.as_secs_f64(),
            share(self.communication.as_secs_f64()),
            self.imbalance,
        )
    }

    /// The step ends with the own bodies' check, agreed over the ranks.
    fn checks_its_steps(&self) -> bool {
        true
    }

    /// After an observed step (or a restore): on rank 0, tells the other
    /// ranks that its outputs are written; on the others, serves rank 0's
    /// pulls of their bodies until then.
    fn serve_outputs(&self) {
        if self.observed_everywhere() {
            pull::serve_until_written(&self.world, &Rows(self));
        }
    }

    /// True after a step that any rank observed, and after a restore.
    fn observed_everywhere(&self) -> bool {
        self.observed
    }

    /// On rank 0 the global state in the single-process layout
    /// ([`save_bodies`]), pulled from every rank's current bodies (the state
    /// just saved or restored) a block at a time and written as it comes
    /// ([`SavedBodies`]), so that it is never held whole. The other ranks'
    /// `saved`.
    fn file_state<'a>(&'a self, saved: &'a State) -> FileState<'a> {
        if self.world.rank() != 0 {
            return FileState::Saved(saved);
        }
        let mut layout = Layout::default();
        let mut bodies = SavedBodies::new(self.total, &mut layout);
        FileState::Spread(
            layout,
            Box::new(move |sink| {
                self.blocks(|_, rows| {
                    let (block, acc, phi) = bodies_of(rows);
                    bodies.push(sink, &block, (&acc, &phi));
                    !sink.failed()
                });
                bodies.finish(sink, self.e0);
            }),
        )
    }

    /// This rank's communication time, the balance of the blocks (fixed:
    /// bodies never move between ranks) and the body count.
    fn distribution(&self) -> Option<Distribution> {
        Some(Distribution {
            communication: self.communication + self.field_wait(),
            imbalance_particles: self.imbalance,
            particles: self.total,
        })
    }
}
