//! The vortex particle method in 3D (seed 000): the vorticity equation
//!
//! ```text
//! D omega / Dt = (omega . grad) u + nu laplace(omega),
//! laplace(psi) = -omega,     u = curl psi,
//! ```
//!
//! carried by particles of vector strength `alpha_p = omega_p h^3` on a lattice of
//! spacing `h`, each a Gaussian blob of variance `sigma^2` per axis. The particles
//! move with the regularised Biot-Savart velocity, and their strengths change by
//! vortex stretching and, with viscosity, by particle strength exchange:
//!
//! ```text
//! dx_p / dt = u(x_p),
//! d alpha_p / dt = (alpha_p . grad) u(x_p)          (classical)
//!               or (alpha_p . grad^T) u(x_p)        (transpose: sum_p alpha_p is kept exactly)
//!              + nu / eps^2 sum_q h^3 (alpha_q - alpha_p) eta_eps(x_q - x_p),
//! ```
//!
//! with `eps = sigma`. The velocity and its gradient come from one of four
//! solvers: all pairs, the Barnes-Hut octree, vortex-in-cell on a 3D mesh, or
//! the fast multipole method.
//! Every `remesh_every` steps the strengths go back onto the lattice with the M4'
//! kernel, and every `relaxation.every` steps the Pedrizzetti relaxation turns
//! the strengths towards the divergence-free vorticity `curl u` of the flow,
//!
//! ```text
//! alpha_p <- (1 - f) alpha_p + f |alpha_p| w_p / |w_p|,    w_p = curl u(x_p),
//! ```
//!
//! (`f = 1` keeps each particle's `|alpha_p|` and takes the direction of `w_p`).

mod diagnostics;
mod initial;
mod model;

pub use diagnostics::{abc_errors, initial_places, ring_places, Invariants3, RingPlace};
pub use initial::{cross, dot, seed3, Abc, InitialVorticity3, Ring, RING_CUT};
pub use model::{Extras3, View3, Vortex3Model};

use super::pse::{advance_from, moving_rate, Integrator, PairWeight};
use super::vortex::{check_blob_params, pse_reach, VortexError};
use crate::geometry::{wrap_coordinate, Boundary, Domain};
use crate::interpolation::{remesh, Lattice};
use crate::longrange::{
    AmongPeers, BlobKernel3, DirectBiotSavart3, Exchange, FmmAccuracy, Peers, TreeParams,
    Vic3Boundary, Vic3Params, VortexFmm3, VortexInCell3, VortexTree3,
};
use crate::memory::{as_arrays, as_arrays_mut};
use crate::threads::Threads;
use std::fmt;
use std::time::{Duration, Instant};

/// How the stretching term is discretised.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stretching {
    /// `(alpha . grad^T) u`: the pair terms are antisymmetric, so the total
    /// vorticity `sum alpha` is kept to round-off by the direct sum.
    Transpose,
    /// `(alpha . grad) u`.
    Classical,
}

/// The Pedrizzetti relaxation: every `every` steps, `alpha` turns by the fraction
/// `factor` towards `curl u`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Relaxation {
    /// The fraction `f` in `(0, 1]`.
    pub factor: f64,
    /// Steps between relaxations (at least 1).
    pub every: u64,
}

/// How the velocity and its gradient are computed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Velocity3Solver {
    /// All pairs: exact, `O(N^2)`.
    Direct,
    /// The Barnes-Hut octree with these settings: `O(N log N)`.
    BarnesHut(TreeParams),
    /// Vortex-in-cell on a 3D mesh: `O(N + M^3 log M)`.
    Mesh(Vic3Params),
    /// The fast multipole method at this accuracy: `O(N)`.
    Fmm(FmmAccuracy),
}

/// The physical and numerical parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Vortex3Params {
    /// Kinematic viscosity `nu >= 0`.
    pub nu: f64,
    /// Lattice spacing `h > 0`.
    pub spacing: f64,
    /// Blob core `sigma > 0` (also the PSE kernel width).
    pub sigma: f64,
    /// PSE pairs within `cutoff_factor * sigma` (at least 2).
    pub pse_cutoff_factor: f64,
    /// Steps between remeshings (0: never).
    pub remesh_every: u64,
    /// Remeshed nodes with `|alpha| <= threshold * max |alpha|` are dropped.
    pub remesh_threshold: f64,
    /// The stretching scheme.
    pub stretching: Stretching,
    /// The relaxation, if any.
    pub relaxation: Option<Relaxation>,
    /// The velocity solver.
    pub solver: Velocity3Solver,
}

impl Vortex3Params {
    /// The periodic box `(lower corner, side)` of a periodic mesh solver.
    pub fn periodic_box(&self) -> Option<([f64; 3], f64)> {
        match self.solver {
            Velocity3Solver::Mesh(Vic3Params {
                boundary: Vic3Boundary::Periodic { origin, length },
                ..
            }) => Some((origin, length)),
            _ => None,
        }
    }

    /// The remeshing lattice `h Z^3` (through the origin, as the seeded
    /// particles), folded into the periodic box if there is one, keeping the
    /// nodes within the PSE cutoff of the kept ones.
    fn lattice(&self) -> Lattice<3> {
        Lattice {
            origin: [0.0; 3],
            spacing: self.spacing,
            periodic: self.periodic_box().map(|(lo, length)| (lo, [length; 3])),
            reach: pse_reach(self.nu, self.pse_cutoff_factor, self.sigma, self.spacing),
        }
    }

    /// Checks every range, naming the parameter.
    pub fn check(&self) -> Result<(), String> {
        check_blob_params(
            3,
            [self.nu, self.spacing, self.sigma],
            self.pse_cutoff_factor,
            self.remesh_threshold,
            self.periodic_box().map(|(_, length)| length),
        )?;
        match self.relaxation {
            Some(r) if !(r.factor.is_finite() && r.factor > 0.0 && r.factor <= 1.0) => Err(
                format!("relaxation.factor must be in (0, 1], got {}", r.factor),
            ),
            Some(r) if r.every == 0 => Err("relaxation.every must be at least 1".into()),
            _ => Ok(()),
        }
    }
}

/// A 3D velocity solver with its state, kept between evaluations.
#[derive(Debug)]
pub enum Velocity3Engine {
    /// All pairs.
    Direct(Box<DirectBiotSavart3>),
    /// The Barnes-Hut octree.
    Tree(Box<VortexTree3>),
    /// Vortex-in-cell.
    Mesh(Box<VortexInCell3>),
    /// The fast multipole method.
    Fmm(Box<VortexFmm3>),
    /// A solver from outside the engine (the direct sum, tree or mesh shared
    /// by the ranks of a distributed run).
    External(Box<dyn VelocityField3>),
}

/// A 3D velocity solver supplied from outside the engine: `u(x_i) = sum_j
/// K_sigma(x_i - x_j) x alpha_j` and its gradient for every particle, called
/// once per evaluation.
pub trait VelocityField3: fmt::Debug {
    /// Fills `velocity` and `gradient` (`gradient[i][3 a + b] = d u_a / d
    /// x_b`), one of each per position.
    fn compute(
        &mut self,
        positions: &[[f64; 3]],
        alpha: &[[f64; 3]],
        velocity: &mut [[f64; 3]],
        gradient: &mut [[f64; 9]],
        threads: &Threads,
    );
}

impl Velocity3Engine {
    /// The solver `kind` for `n` blobs of core `sigma`.
    pub fn new(kind: Velocity3Solver, sigma: f64, n: usize) -> Result<Self, String> {
        let kernel = BlobKernel3::new(sigma);
        Ok(match kind {
            Velocity3Solver::Direct => {
                Velocity3Engine::Direct(Box::new(DirectBiotSavart3::new(kernel, n)))
            }
            Velocity3Solver::BarnesHut(p) => {
                Velocity3Engine::Tree(Box::new(VortexTree3::new(p, kernel)?))
            }
            Velocity3Solver::Mesh(p) => {
                Velocity3Engine::Mesh(Box::new(VortexInCell3::new(p, sigma)?))
            }
            Velocity3Solver::Fmm(accuracy) => {
                Velocity3Engine::Fmm(Box::new(VortexFmm3::new(kernel, accuracy)?))
            }
        })
    }

    /// `u(x_i)` and `grad u(x_i)` (`gradient[i][3 a + b] = d u_a / d x_b`) of the
    /// blobs `(positions, alpha)`, exactly or approximately; the fmm's
    /// target groups and blob rest divided among `peers`, which hold the same
    /// blobs ([`AmongPeers`]; the other solvers divide their sums as
    /// [`Velocity3Engine::External`] solvers).
    pub fn compute(
        &mut self,
        positions: &[[f64; 3]],
        alpha: &[[f64; 3]],
        velocity: &mut [[f64; 3]],
        gradient: &mut [[f64; 9]],
        peers: &dyn Exchange,
        threads: &Threads,
    ) {
        match self {
            Velocity3Engine::Direct(s) => s.compute(positions, alpha, velocity, gradient, threads),
            Velocity3Engine::Tree(s) => s.compute(positions, alpha, velocity, gradient, threads),
            Velocity3Engine::Mesh(s) => s.compute(positions, alpha, velocity, gradient, threads),
            Velocity3Engine::Fmm(s) => {
                let mut share = AmongPeers::new(peers);
                s.compute_shared(positions, alpha, velocity, gradient, threads, &mut share)
            }
            Velocity3Engine::External(s) => {
                s.compute(positions, alpha, velocity, gradient, threads)
            }
        }
    }
}

/// Wall time per part of the steps.
#[derive(Clone, Copy, Debug, Default)]
pub struct Stage3Times {
    /// Velocity and gradient evaluations.
    pub velocity: Duration,
    /// PSE rates.
    pub diffusion: Duration,
    /// Remeshings and relaxations.
    pub remesh: Duration,
}

/// What one rate evaluation needs besides the state.
#[derive(Debug)]
struct Rater {
    params: Vortex3Params,
    weight: PairWeight,
    solver: Velocity3Engine,
    /// The gradient of the last evaluation.
    gradient: Vec<[f64; 9]>,
    /// The PSE rates of the last evaluation.
    diffusion: Vec<[f64; 3]>,
    times: Stage3Times,
    /// The ranks that share the PSE rates and the fmm's sums.
    peers: Peers,
}

impl Rater {
    /// The rate of the flat state `[x_1 .. x_N, alpha_1 .. alpha_N]` into `out`
    /// (`[u_1 .. u_N, d alpha_1 / dt .. d alpha_N / dt]`), the gradient kept.
    fn rate(
        &mut self,
        state: &[f64],
        out: &mut [f64],
        threads: &Threads,
    ) -> Result<(), VortexError> {
        if let Some(i) = first_non_finite(state) {
            return Err(VortexError::Step(format!(
                "an intermediate stage of particle {i} is not finite"
            )));
        }
        let n = state.len() / 6;
        let (x, alpha) = split(state);
        let (velocity, stretch) = out.split_at_mut(3 * n);
        let velocity = as_arrays_mut::<3>(velocity);
        let stretch = as_arrays_mut::<3>(stretch);
        self.gradient.resize(n, [0.0; 9]);
        let t = Instant::now();
        let peers = self.peers.exchange();
        self.solver
            .compute(x, alpha, velocity, &mut self.gradient, peers, threads);
        let t2 = Instant::now();
        self.times.velocity += t2 - t;
        let transpose = self.params.stretching == Stretching::Transpose;
        for ((s, a), g) in stretch.iter_mut().zip(alpha).zip(&self.gradient) {
            *s = stretching(a, g, transpose);
        }
        if self.params.nu > 0.0 {
            let cutoff = self.params.pse_cutoff_factor * self.params.sigma;
            let domain = match self.params.periodic_box() {
                Some((lo, length)) => Domain {
                    lo,
                    length: [length; 3],
                    boundary: [Boundary::Periodic; 3],
                },
                None => Domain::open_around(x),
            };
            self.diffusion.resize(n, [0.0; 3]);
            moving_rate(
                &domain,
                &self.weight,
                cutoff,
                x,
                alpha,
                &mut self.diffusion,
                self.peers.exchange(),
                threads,
            )
            .map_err(|e| VortexError::Step(format!("the PSE cell list: {e}")))?;
            for (s, d) in stretch.iter_mut().zip(&self.diffusion) {
                *s = [0, 1, 2].map(|c| s[c] + d[c]);
            }
        }
        self.times.diffusion += t2.elapsed();
        Ok(())
    }
}

/// `(alpha . grad) u` (classical) or `(alpha . grad^T) u` (transpose) from the
/// gradient `g[3 a + b] = d u_a / d x_b`.
pub fn stretching(alpha: &[f64; 3], g: &[f64; 9], transpose: bool) -> [f64; 3] {
    std::array::from_fn(|a| {
        (0..3).fold(0.0, |s, b| {
            let entry = if transpose {
                g[3 * b + a]
            } else {
                g[3 * a + b]
            };
            s + alpha[b] * entry
        })
    })
}

/// `curl u = (d w/dy - d v/dz, d u/dz - d w/dx, d v/dx - d u/dy)` from the gradient.
pub fn curl(g: &[f64; 9]) -> [f64; 3] {
    [g[7] - g[5], g[2] - g[6], g[3] - g[1]]
}

/// The positions and strengths of a flat state `[x_1 .. x_N, alpha_1 .. alpha_N]`.
fn split(state: &[f64]) -> (&[[f64; 3]], &[[f64; 3]]) {
    let (x, alpha) = state.split_at(state.len() / 2);
    (as_arrays::<3>(x), as_arrays::<3>(alpha))
}

/// The first particle of a flat state with a NaN or infinite value.
fn first_non_finite(state: &[f64]) -> Option<usize> {
    let n = state.len() / 6;
    state
        .iter()
        .position(|v| !v.is_finite())
        .map(|k| (k % (3 * n)) / 3)
}

/// 3D vortex particles, the rate of their current state (the first stage of the
/// next step, also what the field files report) and the integrators' buffers.
#[derive(Debug)]
pub struct Vortex3System {
    rater: Rater,
    /// `[x_1 .. x_N, alpha_1 .. alpha_N]`.
    state: Vec<f64>,
    /// The rate of the current state, `[u_1 .. u_N, d alpha_1 / dt ..]`.
    current: Vec<f64>,
    /// The gradient of the current state.
    current_gradient: Vec<[f64; 9]>,
    stages: [Vec<f64>; 3],
    trial: Vec<f64>,
    dropped: [f64; 3],
}

impl Vortex3System {
    /// Particles at `positions` with strengths `alpha`, and the rate of that
    /// state.
    pub fn new(
        params: Vortex3Params,
        positions: Vec<[f64; 3]>,
        alpha: Vec<[f64; 3]>,
        threads: &Threads,
    ) -> Result<Self, VortexError> {
        Self::among(params, positions, alpha, Peers::default(), threads)
    }

    /// [`Vortex3System::new`] with the PSE rates and the fmm's sums shared
    /// among `peers`, every one of which holds this system and advances it
    /// alike (the rates have the bits of one process).
    pub fn among(
        params: Vortex3Params,
        positions: Vec<[f64; 3]>,
        alpha: Vec<[f64; 3]>,
        peers: Peers,
        threads: &Threads,
    ) -> Result<Self, VortexError> {
        params.check().map_err(VortexError::Parameter)?;
        let solver = Velocity3Engine::new(params.solver, params.sigma, positions.len())
            .map_err(VortexError::Parameter)?;
        Self::with_engine(params, positions, alpha, solver, peers, threads)
    }

    /// [`Vortex3System::among`] with the velocity solver `solver` (built for
    /// `params.solver`, e.g. one shared by the ranks of a distributed run).
    pub fn with_engine(
        params: Vortex3Params,
        positions: Vec<[f64; 3]>,
        alpha: Vec<[f64; 3]>,
        solver: Velocity3Engine,
        peers: Peers,
        threads: &Threads,
    ) -> Result<Self, VortexError> {
        params.check().map_err(VortexError::Parameter)?;
        let mut system = Vortex3System {
            rater: Rater {
                params,
                weight: PairWeight::new(3, params.nu, params.sigma, params.spacing.powi(3)),
                solver,
                gradient: Vec::new(),
                diffusion: Vec::new(),
                times: Stage3Times::default(),
                peers,
            },
            state: Vec::new(),
            current: Vec::new(),
            current_gradient: Vec::new(),
            stages: Default::default(),
            trial: Vec::new(),
            dropped: [0.0; 3],
        };
        system.set_particles(&positions, &alpha, [0.0; 3], threads)?;
        Ok(system)
    }

    /// The parameters.
    pub fn params(&self) -> &Vortex3Params {
        &self.rater.params
    }

    /// Number of particles.
    pub fn len(&self) -> usize {
        self.state.len() / 6
    }

    /// Never true: a system has at least one particle.
    pub fn is_empty(&self) -> bool {
        self.state.is_empty()
    }

    /// The positions.
    pub fn positions(&self) -> &[[f64; 3]] {
        split(&self.state).0
    }

    /// The strengths `alpha_p`.
    pub fn alpha(&self) -> &[[f64; 3]] {
        split(&self.state).1
    }

    /// The velocity of every particle in the current state.
    pub fn velocity(&self) -> &[[f64; 3]] {
        split(&self.current).0
    }

    /// `d alpha_p / dt` of every particle in the current state (stretching and
    /// diffusion).
    pub fn strength_rate(&self) -> &[[f64; 3]] {
        split(&self.current).1
    }

    /// The velocity gradient of every particle in the current state.
    pub fn gradient(&self) -> &[[f64; 9]] {
        &self.current_gradient
    }

    /// The summed strength of the nodes dropped by remeshing so far.
    pub fn dropped(&self) -> [f64; 3] {
        self.dropped
    }

    /// Wall time per part of the steps so far.
    pub fn times(&self) -> Stage3Times {
        self.rater.times
    }

    /// Replaces the particles (the set-up's, or a saved state) and computes
    /// their rate, which is not a step's: [`times`](Self::times) does not
    /// count it.
    pub fn set_particles(
        &mut self,
        positions: &[[f64; 3]],
        alpha: &[[f64; 3]],
        dropped: [f64; 3],
        threads: &Threads,
    ) -> Result<(), VortexError> {
        let steps = self.rater.times;
        let replaced = self.replace_particles(positions, alpha, dropped, threads);
        self.rater.times = steps;
        replaced
    }

    /// Replaces the particles (the set-up's, a saved state, or a
    /// remeshing) and computes their rate, timed.
    fn replace_particles(
        &mut self,
        positions: &[[f64; 3]],
        alpha: &[[f64; 3]],
        dropped: [f64; 3],
        threads: &Threads,
    ) -> Result<(), VortexError> {
        if positions.len() != alpha.len() || positions.is_empty() {
            return Err(VortexError::Parameter(format!(
                "{} positions and {} strengths: need equal, nonzero counts",
                positions.len(),
                alpha.len()
            )));
        }
        if positions.len() >= u32::MAX as usize {
            return Err(VortexError::Parameter(format!(
                "at most 2^32 - 2 particles, got {}",
                positions.len()
            )));
        }
        self.state.clear();
        self.state.extend_from_slice(positions.as_flattened());
        self.state.extend_from_slice(alpha.as_flattened());
        if let Some(i) = first_non_finite(&self.state) {
            return Err(VortexError::Parameter(format!(
                "particle {i} has a non-finite position or strength"
            )));
        }
        self.dropped = dropped;
        self.refresh(threads)
    }

    /// The rate of the current state into `current`.
    fn refresh(&mut self, threads: &Threads) -> Result<(), VortexError> {
        self.current.resize(self.state.len(), 0.0);
        self.rater.rate(&self.state, &mut self.current, threads)?;
        std::mem::swap(&mut self.current_gradient, &mut self.rater.gradient);
        Ok(())
    }

    /// One step of `dt` with `integrator` (the `step`-th: it remeshes and
    /// relaxes when `step` is a multiple of their intervals), ending with the
    /// rate of the new state.
    pub fn step(
        &mut self,
        integrator: Integrator,
        dt: f64,
        step: u64,
        threads: &Threads,
    ) -> Result<(), VortexError> {
        let len = self.state.len();
        for s in &mut self.stages {
            s.resize(len, 0.0);
        }
        self.trial.resize(len, 0.0);
        let Vortex3System {
            rater,
            state,
            current,
            stages,
            trial,
            ..
        } = self;
        let mut failure = Ok(());
        advance_from(
            integrator,
            dt,
            state,
            current,
            stages,
            trial,
            |x, out| {
                if failure.is_ok() {
                    failure = rater.rate(x, out, threads);
                }
            },
            threads,
        );
        failure?;
        if let Some(i) = first_non_finite(&self.state) {
            return Err(VortexError::NotFinite { index: i });
        }
        let params = self.rater.params;
        if let Some((lo, length)) = params.periodic_box() {
            let n = self.len();
            for x in as_arrays_mut::<3>(&mut self.state[..3 * n]) {
                *x = [0, 1, 2].map(|a| wrap_coordinate(x[a], lo[a], length));
            }
        }
        if params.remesh_every > 0 && step.is_multiple_of(params.remesh_every) {
            let t = Instant::now();
            let r = remesh(
                self.positions(),
                self.alpha(),
                &params.lattice(),
                params.remesh_threshold,
            )
            .map_err(VortexError::Step)?;
            self.rater.times.remesh += t.elapsed();
            if r.strength.is_empty() {
                return Err(VortexError::Step(
                    "remeshing left no particle above the threshold".into(),
                ));
            }
            let dropped = [0, 1, 2].map(|c| self.dropped[c] + r.dropped[c]);
            self.replace_particles(&r.positions, &r.strength, dropped, threads)?;
        } else {
            self.refresh(threads)?;
        }
        match params.relaxation {
            Some(r) if step.is_multiple_of(r.every) => {
                let t = Instant::now();
                self.relax(r.factor);
                self.rater.times.remesh += t.elapsed();
                self.refresh(threads)
            }
            _ => Ok(()),
        }
    }

    /// The Pedrizzetti relaxation of the current state by `factor`:
    /// `alpha <- (1 - f) alpha + f |alpha| w / |w|` with `w = curl u` of the
    /// current rate (particles where it vanishes keep their strength).
    fn relax(&mut self, factor: f64) {
        let n = self.len();
        let alpha = as_arrays_mut::<3>(&mut self.state[3 * n..]);
        for (a, g) in alpha.iter_mut().zip(&self.current_gradient) {
            let w = curl(g);
            let size_w = dot(w, w).sqrt();
            if size_w > 0.0 {
                let size_a = dot(*a, *a).sqrt();
                *a = [0, 1, 2].map(|c| (1.0 - factor) * a[c] + factor * size_a * w[c] / size_w);
            }
        }
    }
}

#[cfg(test)]
mod tests;
