//! Self-gravitating bodies (seeds 003 and 004): softened Newtonian gravity (with
//! seed 003's optional short-range repulsion) from one of the [`longrange`]
//! solvers, moved by explicit Euler, symplectic Euler or kick-drift-kick leapfrog.
//!
//! [`longrange`]: crate::longrange

mod initial;
mod model;

pub use initial::{plummer, plummer_part, two_body_seed004, Bodies};
pub use model::{
    body_particles, checked_bodies, load_bodies, save_bodies, thermo_row, GravityModel,
    SavedBodies, INFO,
};

use crate::interactions::GravityLaw;
use crate::longrange::{
    check_sources_among, first_failure, Alone, BarnesHut, DirectSum, Exchange, FieldOut,
    FieldSolver, FmmAccuracy, GravityFmm, MeshParams, P3m, ParticleMesh, Sources, TreeParams,
};
use crate::threads::Threads;
use std::fmt;

/// Which solver computes the forces, and its settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SolverChoice {
    /// All pairs, exact.
    Direct,
    /// The Barnes-Hut tree.
    BarnesHut(TreeParams),
    /// Particle-mesh: cloud-in-cell, FFT Poisson solve, interpolation back.
    Pm(MeshParams),
    /// P3M: the mesh for the long range, pairs on a cell list for the short range.
    P3m {
        /// The mesh.
        mesh: MeshParams,
        /// The splitting radius in mesh cells.
        split_cells: f64,
    },
    /// The fast multipole method at this accuracy.
    Fmm(FmmAccuracy),
}

/// A solver, built for one run.
#[derive(Debug)]
// built once per run and matched once per step: its size does not matter
#[allow(clippy::large_enum_variant)]
pub enum Solver {
    /// All pairs.
    Direct(DirectSum),
    /// Barnes-Hut.
    BarnesHut(BarnesHut),
    /// Particle-mesh.
    Pm(ParticleMesh),
    /// P3M.
    P3m(P3m),
    /// The fast multipole method.
    Fmm(GravityFmm),
    /// A solver from outside the engine (the ring pass of a distributed run).
    External(Box<dyn FieldSolver>),
}

impl Solver {
    /// The solver `choice` for `n` bodies under `law`.
    pub fn new(choice: &SolverChoice, law: GravityLaw, n: usize) -> Result<Self, String> {
        Ok(match choice {
            SolverChoice::Direct => Solver::Direct(DirectSum::new(law, n)),
            SolverChoice::BarnesHut(params) => Solver::BarnesHut(BarnesHut::new(law, *params)?),
            SolverChoice::Pm(mesh) => Solver::Pm(ParticleMesh::new(law, *mesh)?),
            SolverChoice::P3m { mesh, split_cells } => {
                Solver::P3m(P3m::new(law, *mesh, *split_cells)?)
            }
            SolverChoice::Fmm(accuracy) => Solver::Fmm(GravityFmm::new(law, *accuracy)?),
        })
    }

    /// Fills `out` with the accelerations and potentials of `sources`.
    pub fn compute(&mut self, sources: &Sources, out: FieldOut, threads: &Threads) {
        match self {
            Solver::Direct(s) => s.compute(sources, out, threads),
            Solver::BarnesHut(s) => s.compute(sources, out, threads),
            Solver::Pm(s) => s.compute(sources, out, threads),
            Solver::P3m(s) => s.compute(sources, out, threads),
            Solver::Fmm(s) => s.compute(sources, out, threads),
            Solver::External(s) => s.compute(sources, out, threads),
        }
    }
}

/// Time integrators; each takes one force evaluation per step.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Integrator {
    /// Explicit Euler, first order: `x' = x + dt v`, `v' = v + dt a(x)`.
    Euler,
    /// Symplectic Euler, first order: `v' = v + dt a(x)`, `x' = x + dt v'`.
    SymplecticEuler,
    /// Kick-drift-kick leapfrog (velocity Verlet), second order:
    /// `v += dt/2 a(x)`, `x += dt v`, `v += dt/2 a(x)`.
    Leapfrog,
}

impl Integrator {
    /// Names in scenario files, with their integrators.
    pub const ALL: [(&'static str, Integrator); 3] = [
        ("euler", Integrator::Euler),
        ("symplectic-euler", Integrator::SymplecticEuler),
        ("leapfrog", Integrator::Leapfrog),
    ];

    /// The integrator called `name`.
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.iter().find(|(n, _)| *n == name).map(|(_, i)| *i)
    }
}

/// Why a system cannot be built or stepped.
#[derive(Clone, Debug, PartialEq)]
pub enum GravityError {
    /// A parameter or a body out of range.
    Parameter(String),
    /// A position or velocity became NaN or infinite.
    NotFinite {
        /// The body (input order).
        index: usize,
    },
}

impl fmt::Display for GravityError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            GravityError::Parameter(m) => f.write_str(m),
            GravityError::NotFinite { index } => {
                write!(f, "the state of body {index} is not finite")
            }
        }
    }
}

impl std::error::Error for GravityError {}

/// The conserved quantities: energies, momentum and angular momentum.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Observables {
    /// `T = 1/2 sum m v^2`.
    pub kinetic: f64,
    /// `W = 1/2 sum m phi` (the solver's potential).
    pub potential: f64,
    /// `P = sum m v`.
    pub momentum: [f64; 3],
    /// `L = sum m x cross v`.
    pub angular_momentum: [f64; 3],
}

impl Observables {
    /// Adds body `m` at `x` with velocity `v` and potential `phi`:
    /// `T += m |v|^2 / 2`, `W += m phi / 2`, `P += m v`, `L += m x cross v`.
    pub fn add_body(&mut self, m: f64, x: [f64; 3], v: [f64; 3], phi: f64) {
        self.kinetic += 0.5 * m * (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
        self.potential += 0.5 * m * phi;
        for a in 0..3 {
            self.momentum[a] += m * v[a];
        }
        let l = [
            x[1] * v[2] - x[2] * v[1],
            x[2] * v[0] - x[0] * v[2],
            x[0] * v[1] - x[1] * v[0],
        ];
        for a in 0..3 {
            self.angular_momentum[a] += m * l[a];
        }
    }

    /// `E = T + W`.
    pub fn total(&self) -> f64 {
        self.kinetic + self.potential
    }
}

/// Bodies, their current accelerations and potentials, and the solver.
#[derive(Debug)]
pub struct GravitySystem {
    law: GravityLaw,
    bodies: Bodies,
    acc: Vec<[f64; 3]>,
    phi: Vec<f64>,
    solver: Solver,
}

impl GravitySystem {
    /// The system of `bodies` under `law`, with the forces of `choice` computed.
    pub fn new(
        law: GravityLaw,
        bodies: Bodies,
        choice: &SolverChoice,
        threads: &Threads,
    ) -> Result<Self, GravityError> {
        let solver = Solver::new(choice, law, bodies.len()).map_err(GravityError::Parameter)?;
        Self::with_solver(law, bodies, solver, threads)
    }

    /// The system of `bodies` under `law` with `solver`, forces computed.
    pub fn with_solver(
        law: GravityLaw,
        bodies: Bodies,
        solver: Solver,
        threads: &Threads,
    ) -> Result<Self, GravityError> {
        let n = bodies.len();
        if bodies.velocity.len() != n {
            return Err(GravityError::Parameter(format!(
                "{} velocities for {n} bodies",
                bodies.velocity.len()
            )));
        }
        check_bodies(&law, &bodies)?;
        let mut system = GravitySystem {
            law,
            bodies,
            acc: vec![[0.0; 3]; n],
            phi: vec![0.0; n],
            solver,
        };
        system.compute_forces(threads);
        system.check_finite()?;
        Ok(system)
    }

    /// Number of bodies.
    pub fn len(&self) -> usize {
        self.bodies.len()
    }

    /// Whether there are no bodies.
    pub fn is_empty(&self) -> bool {
        self.bodies.is_empty()
    }

    /// The law.
    pub fn law(&self) -> &GravityLaw {
        &self.law
    }

    /// Masses, positions and velocities.
    pub fn bodies(&self) -> &Bodies {
        &self.bodies
    }

    /// Accelerations at the current positions.
    pub fn accelerations(&self) -> &[[f64; 3]] {
        &self.acc
    }

    /// Potentials `phi_i` at the current positions.
    pub fn potentials(&self) -> &[f64] {
        &self.phi
    }

    /// Replaces the bodies and their accelerations and potentials by a saved state
    /// of this system (the solvers keep nothing between evaluations that changes
    /// their results, so the next step is the saved run's).
    pub fn restore(
        &mut self,
        bodies: Bodies,
        acc: Vec<[f64; 3]>,
        phi: Vec<f64>,
    ) -> Result<(), String> {
        let n = self.len();
        if bodies.len() != n || bodies.velocity.len() != n || acc.len() != n || phi.len() != n {
            return Err(format!("the saved state does not hold {n} bodies"));
        }
        self.bodies = bodies;
        self.acc = acc;
        self.phi = phi;
        Ok(())
    }

    /// The solver (for its statistics).
    pub fn solver(&self) -> &Solver {
        &self.solver
    }

    fn compute_forces(&mut self, threads: &Threads) {
        let sources = Sources {
            mass: &self.bodies.mass,
            position: &self.bodies.position,
        };
        let out = FieldOut {
            acc: &mut self.acc,
            phi: &mut self.phi,
        };
        self.solver.compute(&sources, out, threads);
    }

    /// One step of `dt` with `integrator`; accelerations and potentials are left at
    /// the new positions. A NaN or infinite position or velocity is an error
    /// naming the first such body.
    pub fn step(
        &mut self,
        dt: f64,
        integrator: Integrator,
        threads: &Threads,
    ) -> Result<(), GravityError> {
        let Bodies {
            position, velocity, ..
        } = &mut self.bodies;
        match integrator {
            Integrator::Euler => {
                for ((x, v), a) in position.iter_mut().zip(velocity.iter_mut()).zip(&self.acc) {
                    for k in 0..3 {
                        x[k] += dt * v[k];
                        v[k] += dt * a[k];
                    }
                }
                self.compute_forces(threads);
            }
            Integrator::SymplecticEuler => {
                for ((x, v), a) in position.iter_mut().zip(velocity.iter_mut()).zip(&self.acc) {
                    for k in 0..3 {
                        v[k] += dt * a[k];
                        x[k] += dt * v[k];
                    }
                }
                self.compute_forces(threads);
            }
            Integrator::Leapfrog => {
                let half = 0.5 * dt;
                for ((x, v), a) in position.iter_mut().zip(velocity.iter_mut()).zip(&self.acc) {
                    for k in 0..3 {
                        v[k] += half * a[k];
                        x[k] += dt * v[k];
                    }
                }
                self.compute_forces(threads);
                for (v, a) in self.bodies.velocity.iter_mut().zip(&self.acc) {
                    for k in 0..3 {
                        v[k] += half * a[k];
                    }
                }
            }
        }
        self.check_finite()
    }

    /// The first body whose position, velocity, acceleration or potential is NaN
    /// or infinite, as an error.
    fn check_finite(&self) -> Result<(), GravityError> {
        let b = &self.bodies;
        let bad = |i: usize| {
            b.position[i]
                .iter()
                .chain(&b.velocity[i])
                .chain(&self.acc[i])
                .chain(std::iter::once(&self.phi[i]))
                .any(|c| !c.is_finite())
        };
        match (0..self.len()).find(|&i| bad(i)) {
            Some(index) => Err(GravityError::NotFinite { index }),
            None => Ok(()),
        }
    }

    /// Energies, momentum and angular momentum now, summed over the bodies in
    /// input order ([`Observables::add_body`]).
    pub fn observables(&self) -> Observables {
        let b = &self.bodies;
        let mut o = Observables::default();
        for i in 0..self.len() {
            o.add_body(b.mass[i], b.position[i], b.velocity[i], self.phi[i]);
        }
        o
    }
}

/// The checks of a system's bodies before its first forces: those of every
/// solver's sources ([`check_sources`](crate::longrange::check_sources)) and
/// finite velocities.
pub fn check_bodies(law: &GravityLaw, bodies: &Bodies) -> Result<(), GravityError> {
    check_bodies_among(law, bodies, 0, &Alone)
}

/// [`check_bodies`] of bodies divided among the ranks of `peers` (collective),
/// this rank holding `bodies`, the bodies `first..` of the input order: every
/// rank gets the message one process holding them all would give
/// ([`check_sources_among`]).
pub fn check_bodies_among(
    law: &GravityLaw,
    bodies: &Bodies,
    first: usize,
    peers: &dyn Exchange,
) -> Result<(), GravityError> {
    let sources = Sources {
        mass: &bodies.mass,
        position: &bodies.position,
    };
    check_sources_among(law, &sources, first, peers).map_err(GravityError::Parameter)?;
    let velocity = bodies
        .velocity
        .iter()
        .position(|v| v.iter().any(|c| !c.is_finite()));
    match first_failure(velocity.map(|i| (first + i, bodies.velocity[i])), peers) {
        Some((i, _)) => Err(GravityError::Parameter(format!(
            "body {i}: velocity is not finite"
        ))),
        None => Ok(()),
    }
}
