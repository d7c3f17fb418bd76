//! The viscous vortex particle method in 2D (seed 000): the vorticity form of the
//! Navier-Stokes equations,
//!
//! ```text
//! Dw/Dt = nu laplace(w),     laplace(psi) = -w,     u = curl psi = (d psi/dy, -d psi/dx),
//! ```
//!
//! carried by particles of circulation `Gamma_i = w_i h^2` on a lattice of spacing
//! `h`, each a Gaussian blob of core `sigma`. The particles move with the
//! regularised Biot-Savart velocity (module [`crate::longrange::biot_savart`]),
//! computed by one of three solvers: all pairs, the Barnes-Hut tree, or
//! vortex-in-cell on a mesh. Viscosity changes the circulations by particle
//! strength exchange (the `pse` model's kernel and pair sums):
//!
//! ```text
//! dx_i/dt = u(x_i),     dGamma_i/dt = nu / eps^2 sum_j h^2 (Gamma_j - Gamma_i) eta_eps(x_j - x_i),
//! ```
//!
//! both advanced in the same Runge-Kutta stages, with `eps = sigma`. Every
//! `remesh_every` steps the circulations go back onto the lattice with the M4'
//! kernel ([`crate::interpolation::remesh`]), which keeps the particles
//! overlapping.

mod diagnostics;
mod initial;
mod model;

pub use diagnostics::{energy_and_enstrophy, log_plus_e1, Moments};
pub use initial::{lamb_oseen_speed, lamb_oseen_vorticity, seed, InitialVorticity, ELLIPSE_Q};
pub use model::{Extras, VortexModel};

use super::pse::{combine, moving_rate, Integrator, PairWeight};
use crate::geometry::Domain;
use crate::geometry::{wrap_coordinate, Boundary};
use crate::interpolation::{remesh, Lattice};
use crate::longrange::mesh::{VicBoundary, VicParams, VortexInCell};
use crate::longrange::tree::{FmmAccuracy, TreeParams, VortexFmm, VortexTree};
use crate::longrange::{AmongPeers, BlobKernel, DirectBiotSavart, Exchange, Peers};
use crate::memory::{as_arrays, as_arrays_mut};
use crate::threads::Threads;
use std::fmt;
use std::time::{Duration, Instant};

/// How the velocity is computed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum VelocitySolver {
    /// All pairs: exact, `O(N^2)`.
    Direct,
    /// The Barnes-Hut tree with these settings: `O(N log N)`.
    BarnesHut(TreeParams),
    /// Vortex-in-cell on a mesh: `O(N + M^2 log M)`.
    Mesh(VicParams),
    /// The fast multipole method at this accuracy: `O(N)` per level of the
    /// quadtree's upper part, near `O(N)`.
    Fmm(FmmAccuracy),
}

/// The physical and numerical parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VortexParams {
    /// Kinematic viscosity `nu >= 0` (0: inviscid, no diffusion).
    pub nu: f64,
    /// Lattice spacing `h > 0`: the particles' area and the remeshing lattice.
    pub spacing: f64,
    /// Blob core `sigma > 0` (also the PSE kernel width `eps`).
    pub sigma: f64,
    /// The lattice passes through this point.
    pub origin: [f64; 2],
    /// PSE pairs within `cutoff_factor * sigma` (at least 2; the kernel's tail
    /// beyond `c sigma` carries `(1 + c^2) exp(-c^2)` of its second moment, so
    /// the viscosity comes out that much low: 9 % at 2, 2e-6 at 4).
    pub pse_cutoff_factor: f64,
    /// Steps between remeshings (0: never).
    pub remesh_every: u64,
    /// Remeshed nodes with `|Gamma| <= threshold * max |Gamma|` are dropped.
    pub remesh_threshold: f64,
    /// The velocity solver.
    pub solver: VelocitySolver,
}

impl VortexParams {
    /// The periodic box `(lower corner, side)` of a periodic mesh solver; `None`
    /// for the open plane.
    pub fn periodic_box(&self) -> Option<([f64; 2], f64)> {
        match self.solver {
            VelocitySolver::Mesh(VicParams {
                boundary: VicBoundary::Periodic { origin, length },
                ..
            }) => Some((origin, length)),
            _ => None,
        }
    }

    /// The remeshing lattice `origin + h (k, l)`, folded into the periodic box if
    /// there is one, keeping the nodes within the PSE cutoff of the kept ones.
    fn lattice(&self) -> Lattice<2> {
        Lattice {
            reach: pse_reach(self.nu, self.pse_cutoff_factor, self.sigma, self.spacing),
            origin: self.origin,
            spacing: self.spacing,
            periodic: self.periodic_box().map(|(lo, length)| (lo, [length; 2])),
        }
    }

    /// Checks every range, naming the parameter.
    pub fn check(&self) -> Result<(), String> {
        check_blob_params(
            2,
            [self.nu, self.spacing, self.sigma],
            self.pse_cutoff_factor,
            self.remesh_threshold,
            self.periodic_box().map(|(_, length)| length),
        )?;
        if self.origin.iter().any(|c| !c.is_finite()) {
            return Err(format!(
                "the lattice origin must be finite, got {:?}",
                self.origin
            ));
        }
        Ok(())
    }
}

/// The nodes per axis a remeshing keeps around the kept ones: those within
/// the PSE cutoff `pse_cutoff_factor * sigma` (PSE needs every neighbour
/// within it, zeros included), none without viscosity.
pub(crate) fn pse_reach(nu: f64, pse_cutoff_factor: f64, sigma: f64, spacing: f64) -> usize {
    if nu > 0.0 {
        (pse_cutoff_factor * sigma / spacing).ceil() as usize
    } else {
        0
    }
}

/// Checks the parameters the 2D and 3D vortex models share, naming the bad
/// one: `nu >= 0`, the spacing `h > 0` and core `sigma > 0` (with `sigma^D`
/// representable), the PSE cutoff factor (at least 2), the remeshing
/// threshold in `[0, 1)`, and a periodic box side (if any) of a whole number
/// (at least 4) of spacings, at least twice the PSE cutoff.
pub(crate) fn check_blob_params(
    dimension: i32,
    [nu, spacing, sigma]: [f64; 3],
    pse_cutoff_factor: f64,
    remesh_threshold: f64,
    periodic_side: Option<f64>,
) -> Result<(), String> {
    let positive = |name: &str, v: f64| {
        if v.is_finite() && v > 0.0 {
            Ok(())
        } else {
            Err(format!("{name} must be finite and > 0, got {v}"))
        }
    };
    positive("spacing", spacing)?;
    positive("sigma", sigma)?;
    if !sigma.powi(dimension).is_normal() {
        return Err(format!(
            "sigma = {sigma} is too small: sigma^{dimension} underflows"
        ));
    }
    if !(nu.is_finite() && nu >= 0.0) {
        return Err(format!("nu must be finite and >= 0, got {nu}"));
    }
    if !(pse_cutoff_factor.is_finite() && pse_cutoff_factor >= 2.0) {
        return Err(format!(
            "pse_cutoff_factor must be >= 2, got {pse_cutoff_factor}"
        ));
    }
    if !(remesh_threshold.is_finite() && (0.0..1.0).contains(&remesh_threshold)) {
        return Err(format!(
            "remesh_threshold must be in [0, 1), got {remesh_threshold}"
        ));
    }
    if let Some(length) = periodic_side {
        let cells = length / spacing;
        if (cells - cells.round()).abs() > 1e-9 * cells || cells.round() < 4.0 {
            return Err(format!(
                "the periodic box side {length} must be a whole number (at least 4) of spacings {spacing}, got {cells}"
            ));
        }
        if pse_cutoff_factor * sigma > 0.5 * length {
            return Err(format!(
                "the PSE cutoff {pse_cutoff_factor} sigma = {} must be at most half the periodic box side {length}",
                pse_cutoff_factor * sigma
            ));
        }
    }
    Ok(())
}

/// Why a vortex system cannot be set up or a step cannot finish.
#[derive(Clone, Debug, PartialEq)]
pub enum VortexError {
    /// A parameter out of its range, or bad particles.
    Parameter(String),
    /// The PSE cell list could not be built, or remeshing left no particle.
    Step(String),
    /// A position or circulation became NaN or infinite (the first such particle);
    /// the state is left as it is, without remeshing or a new rate.
    NotFinite {
        /// The particle.
        index: usize,
    },
}

impl fmt::Display for VortexError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            VortexError::Parameter(m) | VortexError::Step(m) => f.write_str(m),
            VortexError::NotFinite { index } => write!(
                f,
                "particle {index} has a non-finite position or circulation after the step"
            ),
        }
    }
}

impl std::error::Error for VortexError {}

/// A velocity solver with its state (tables, tree, mesh), kept between
/// evaluations.
#[derive(Debug)]
pub enum VelocityEngine {
    /// All pairs.
    Direct(Box<DirectBiotSavart>),
    /// The Barnes-Hut tree.
    Tree(Box<VortexTree>),
    /// Vortex-in-cell.
    Mesh(Box<VortexInCell>),
    /// The fast multipole method.
    Fmm(Box<VortexFmm<BlobKernel>>),
    /// A solver from outside the engine (the direct sum, tree or mesh shared
    /// by the ranks of a distributed run).
    External(Box<dyn VelocityField>),
}

/// A velocity solver supplied from outside the engine: `velocity_i = sum_j
/// Gamma_j K_sigma(x_i - x_j)` for every particle, called once per evaluation.
pub trait VelocityField: fmt::Debug {
    /// Fills `velocity` (one per position).
    fn compute(
        &mut self,
        positions: &[[f64; 2]],
        gamma: &[f64],
        velocity: &mut [[f64; 2]],
        threads: &Threads,
    );
}

impl VelocityEngine {
    /// The solver `kind` for `n` particles with blobs of `kernel`.
    pub fn new(kind: VelocitySolver, kernel: BlobKernel, n: usize) -> Result<Self, String> {
        Ok(match kind {
            VelocitySolver::Direct => {
                VelocityEngine::Direct(Box::new(DirectBiotSavart::new(kernel, n)))
            }
            VelocitySolver::BarnesHut(p) => {
                VelocityEngine::Tree(Box::new(VortexTree::new(p, kernel)?))
            }
            VelocitySolver::Mesh(p) => {
                VelocityEngine::Mesh(Box::new(VortexInCell::new(p, kernel)?))
            }
            VelocitySolver::Fmm(accuracy) => {
                VelocityEngine::Fmm(Box::new(VortexFmm::new(kernel, accuracy)?))
            }
        })
    }

    /// `velocity_i = sum_j Gamma_j K_sigma(x_i - x_j)`, exactly or
    /// approximately; the fmm's target groups divided among `peers`, which
    /// hold the same particles ([`AmongPeers`]; the other solvers divide
    /// their sums as [`VelocityEngine::External`] solvers).
    pub fn compute(
        &mut self,
        positions: &[[f64; 2]],
        gamma: &[f64],
        velocity: &mut [[f64; 2]],
        peers: &dyn Exchange,
        threads: &Threads,
    ) {
        match self {
            VelocityEngine::Direct(s) => s.compute(positions, gamma, velocity, threads),
            VelocityEngine::Tree(s) => s.compute(positions, gamma, velocity, threads),
            VelocityEngine::Mesh(s) => s.compute(positions, gamma, velocity, threads),
            VelocityEngine::Fmm(s) => {
                let mut share = AmongPeers::new(peers);
                s.compute_shared(positions, gamma, velocity, threads, &mut share)
            }
            VelocityEngine::External(s) => s.compute(positions, gamma, velocity, threads),
        }
    }
}

/// The rate of the state: velocities and circulation rates.
#[derive(Clone, Debug, Default)]
struct Rate {
    velocity: Vec<[f64; 2]>,
    gamma: Vec<f64>,
}

impl Rate {
    fn resize(&mut self, n: usize) {
        self.velocity.resize(n, [0.0; 2]);
        self.gamma.resize(n, 0.0);
    }
}

/// Wall time per part of the steps.
#[derive(Clone, Copy, Debug, Default)]
pub struct StageTimes {
    /// Velocity evaluations.
    pub velocity: Duration,
    /// PSE rates.
    pub diffusion: Duration,
    /// Remeshings.
    pub remesh: Duration,
}

/// Vortex particles, their rate at the current state (the first stage of the next
/// step, also what the field files report) and the integrators' buffers.
#[derive(Debug)]
pub struct VortexSystem {
    params: VortexParams,
    kernel: BlobKernel,
    weight: PairWeight,
    solver: VelocityEngine,
    positions: Vec<[f64; 2]>,
    gamma: Vec<f64>,
    /// The rate of the current state.
    current: Rate,
    stages: [Rate; 3],
    trial_positions: Vec<[f64; 2]>,
    trial_gamma: Vec<f64>,
    dropped: f64,
    times: StageTimes,
    /// The ranks that share the PSE rates, the thermo pair sums and the
    /// fmm's sums.
    peers: Peers,
}

impl VortexSystem {
    /// Particles at `positions` with circulations `gamma`, and the velocity of
    /// that state.
    pub fn new(
        params: VortexParams,
        positions: Vec<[f64; 2]>,
        gamma: Vec<f64>,
        threads: &Threads,
    ) -> Result<Self, VortexError> {
        params.check().map_err(VortexError::Parameter)?;
        let kernel = BlobKernel::new(params.sigma);
        let solver = VelocityEngine::new(params.solver, kernel, positions.len())
            .map_err(VortexError::Parameter)?;
        Self::with_engine(params, positions, gamma, solver, Peers::default(), threads)
    }

    /// The same with the velocity solver `solver` (of the kind `params.solver`
    /// names, built elsewhere), the PSE rates, the thermo's pair sums and the
    /// fmm's sums shared among `peers`, every one of which holds this system
    /// and advances it alike (the results have the bits of one process).
    pub fn with_engine(
        params: VortexParams,
        positions: Vec<[f64; 2]>,
        gamma: Vec<f64>,
        solver: VelocityEngine,
        peers: Peers,
        threads: &Threads,
    ) -> Result<Self, VortexError> {
        params.check().map_err(VortexError::Parameter)?;
        if positions.len() != gamma.len() {
            return Err(VortexError::Parameter(format!(
                "{} positions but {} circulations",
                positions.len(),
                gamma.len()
            )));
        }
        if positions.is_empty() {
            return Err(VortexError::Parameter(
                "the particle set is empty: no particle carries vorticity".into(),
            ));
        }
        if positions.len() >= u32::MAX as usize {
            return Err(VortexError::Parameter(format!(
                "at most 2^32 - 2 particles, got {}",
                positions.len()
            )));
        }
        if let Some(i) = first_non_finite(&positions, &gamma) {
            return Err(VortexError::Parameter(format!(
                "particle {i} has a non-finite position or circulation"
            )));
        }
        let kernel = BlobKernel::new(params.sigma);
        let h2 = params.spacing * params.spacing;
        let mut system = VortexSystem {
            params,
            kernel,
            weight: PairWeight::new(2, params.nu, params.sigma, h2),
            solver,
            positions,
            gamma,
            current: Rate::default(),
            stages: Default::default(),
            trial_positions: Vec::new(),
            trial_gamma: Vec::new(),
            dropped: 0.0,
            times: StageTimes::default(),
            peers,
        };
        system.refresh(threads)?;
        // the set-up's rate is not a step's
        system.times = StageTimes::default();
        Ok(system)
    }

    /// The parameters.
    pub fn params(&self) -> &VortexParams {
        &self.params
    }

    /// The ranks that share the PSE rates, the thermo's pair sums and the
    /// fmm's sums.
    pub fn peers(&self) -> &dyn Exchange {
        self.peers.exchange()
    }

    /// The blob kernel.
    pub fn kernel(&self) -> &BlobKernel {
        &self.kernel
    }

    /// Number of particles.
    pub fn len(&self) -> usize {
        self.gamma.len()
    }

    /// Never true: a system has at least one particle.
    pub fn is_empty(&self) -> bool {
        self.gamma.is_empty()
    }

    /// The positions.
    pub fn positions(&self) -> &[[f64; 2]] {
        &self.positions
    }

    /// The circulations `Gamma_i`.
    pub fn gamma(&self) -> &[f64] {
        &self.gamma
    }

    /// The velocity of every particle in the current state.
    pub fn velocity(&self) -> &[[f64; 2]] {
        &self.current.velocity
    }

    /// The summed circulation of the nodes dropped by remeshing so far.
    pub fn dropped(&self) -> f64 {
        self.dropped
    }

    /// Wall time per part of the steps so far.
    pub fn times(&self) -> StageTimes {
        self.times
    }

    /// Replaces the particles (a saved state) and computes their rate, which
    /// is not a step's: [`times`](Self::times) does not count it.
    pub fn set_particles(
        &mut self,
        positions: Vec<[f64; 2]>,
        gamma: Vec<f64>,
        dropped: f64,
        threads: &Threads,
    ) -> Result<(), VortexError> {
        let steps = self.times;
        let replaced = self.replace_particles(positions, gamma, dropped, threads);
        self.times = steps;
        replaced
    }

    /// Replaces the particles (a saved state, or a remeshing) and computes
    /// their rate, timed.
    fn replace_particles(
        &mut self,
        positions: Vec<[f64; 2]>,
        gamma: Vec<f64>,
        dropped: f64,
        threads: &Threads,
    ) -> Result<(), VortexError> {
        if positions.len() != gamma.len() || positions.is_empty() {
            return Err(VortexError::Parameter(format!(
                "{} positions and {} circulations: need equal, nonzero counts",
                positions.len(),
                gamma.len()
            )));
        }
        if let Some(i) = first_non_finite(&positions, &gamma) {
            return Err(VortexError::Parameter(format!(
                "particle {i} has a non-finite position or circulation"
            )));
        }
        self.positions = positions;
        self.gamma = gamma;
        self.dropped = dropped;
        self.refresh(threads)
    }

    /// The rate of the current state into `current`.
    fn refresh(&mut self, threads: &Threads) -> Result<(), VortexError> {
        let n = self.len();
        self.current.resize(n);
        evaluate(
            &mut self.solver,
            &self.params,
            &self.weight,
            self.peers.exchange(),
            &mut self.times,
            &self.positions,
            &self.gamma,
            &mut self.current,
            threads,
        )
    }

    /// One step of `dt` with `integrator` (the `step`-th: it remeshes when `step` is
    /// a multiple of `remesh_every`), ending with the rate of the new state.
    pub fn step(
        &mut self,
        integrator: Integrator,
        dt: f64,
        step: u64,
        threads: &Threads,
    ) -> Result<(), VortexError> {
        let n = self.len();
        for s in &mut self.stages {
            s.resize(n);
        }
        self.trial_positions.resize(n, [0.0; 2]);
        self.trial_gamma.resize(n, 0.0);
        let VortexSystem {
            solver,
            params,
            weight,
            times,
            positions,
            gamma,
            current,
            stages: [k2, k3, k4],
            trial_positions,
            trial_gamma,
            peers,
            ..
        } = self;
        let k1 = &*current;
        let mut rate = |x: &[[f64; 2]], g: &[f64], out: &mut Rate| {
            if let Some(i) = first_non_finite(x, g) {
                return Err(VortexError::Step(format!(
                    "an intermediate stage of particle {i} is not finite (x = {:?}, gamma = {:?})",
                    x[i], g[i]
                )));
            }
            evaluate(
                solver,
                params,
                weight,
                peers.exchange(),
                times,
                x,
                g,
                out,
                threads,
            )
        };
        match integrator {
            Integrator::Euler => advance(positions, gamma, None, [(dt, k1)], threads),
            Integrator::Rk2 => {
                let base = Some((&positions[..], &gamma[..]));
                advance(
                    trial_positions,
                    trial_gamma,
                    base,
                    [(0.5 * dt, k1)],
                    threads,
                );
                rate(trial_positions, trial_gamma, k2)?;
                advance(positions, gamma, None, [(dt, &*k2)], threads);
            }
            Integrator::Rk4 => {
                let base = Some((&positions[..], &gamma[..]));
                advance(
                    trial_positions,
                    trial_gamma,
                    base,
                    [(0.5 * dt, k1)],
                    threads,
                );
                rate(trial_positions, trial_gamma, k2)?;
                advance(
                    trial_positions,
                    trial_gamma,
                    base,
                    [(0.5 * dt, &*k2)],
                    threads,
                );
                rate(trial_positions, trial_gamma, k3)?;
                advance(trial_positions, trial_gamma, base, [(dt, &*k3)], threads);
                rate(trial_positions, trial_gamma, k4)?;
                let sixth = dt / 6.0;
                let terms = [
                    (sixth, k1),
                    (2.0 * sixth, &*k2),
                    (2.0 * sixth, &*k3),
                    (sixth, &*k4),
                ];
                advance(positions, gamma, None, terms, threads);
            }
        }
        if let Some(index) = first_non_finite(&self.positions, &self.gamma) {
            return Err(VortexError::NotFinite { index });
        }
        if let Some((lo, length)) = self.params.periodic_box() {
            for x in &mut self.positions {
                *x = [0, 1].map(|a| wrap_coordinate(x[a], lo[a], length));
            }
        }
        if self.params.remesh_every > 0 && step.is_multiple_of(self.params.remesh_every) {
            let t = Instant::now();
            let r = remesh(
                &self.positions,
                as_arrays::<1>(&self.gamma),
                &self.params.lattice(),
                self.params.remesh_threshold,
            )
            .map_err(VortexError::Step)?;
            self.times.remesh += t.elapsed();
            if r.strength.is_empty() {
                return Err(VortexError::Step(
                    "remeshing left no particle above the threshold".into(),
                ));
            }
            let dropped = self.dropped + r.dropped[0];
            let gamma = r.strength.into_flattened();
            return self.replace_particles(r.positions, gamma, dropped, threads);
        }
        self.refresh(threads)
    }
}

/// The first particle whose position or circulation is NaN or infinite.
fn first_non_finite(positions: &[[f64; 2]], gamma: &[f64]) -> Option<usize> {
    (0..gamma.len())
        .find(|&i| !(gamma[i].is_finite() && positions[i].iter().all(|c| c.is_finite())))
}

/// `state = base + sum_s c_s k_s` for positions and circulations alike (`base`
/// defaults to the state itself), with the `pse` model's vector update.
fn advance<const N: usize>(
    positions: &mut [[f64; 2]],
    gamma: &mut [f64],
    base: Option<(&[[f64; 2]], &[f64])>,
    terms: [(f64, &Rate); N],
    threads: &Threads,
) {
    let xs = terms.map(|(c, k)| (c, k.velocity.as_flattened()));
    let gs = terms.map(|(c, k)| (c, &k.gamma[..]));
    combine(
        positions.as_flattened_mut(),
        base.map(|b| b.0.as_flattened()),
        &xs,
        threads,
    );
    combine(gamma, base.map(|b| b.1), &gs, threads);
}

/// The rate of `(positions, gamma)`: the solver's velocities and, with `nu > 0`,
/// the PSE circulation rates over an open domain around the particles (or the
/// periodic box), shared by the ranks of `peers`.
#[allow(clippy::too_many_arguments)]
fn evaluate(
    solver: &mut VelocityEngine,
    params: &VortexParams,
    weight: &PairWeight,
    peers: &dyn Exchange,
    times: &mut StageTimes,
    positions: &[[f64; 2]],
    gamma: &[f64],
    out: &mut Rate,
    threads: &Threads,
) -> Result<(), VortexError> {
    let t = Instant::now();
    solver.compute(positions, gamma, &mut out.velocity, peers, threads);
    let t2 = Instant::now();
    times.velocity += t2 - t;
    if params.nu > 0.0 {
        let cutoff = params.pse_cutoff_factor * params.sigma;
        let domain = match params.periodic_box() {
            Some((lo, length)) => Domain {
                lo,
                length: [length; 2],
                boundary: [Boundary::Periodic; 2],
            },
            None => Domain::open_around(positions),
        };
        moving_rate(
            &domain,
            weight,
            cutoff,
            positions,
            as_arrays::<1>(gamma),
            as_arrays_mut::<1>(&mut out.gamma),
            peers,
            threads,
        )
        .map_err(|e| VortexError::Step(format!("the PSE cell list: {e}")))?;
    } else {
        out.gamma.fill(0.0);
    }
    times.diffusion += t2.elapsed();
    Ok(())
}
