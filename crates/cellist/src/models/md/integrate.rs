//! Time integrators for molecular dynamics, split around the force evaluation:
//! `first_half` before the new forces, `second_half` after.

use super::Atoms;
use crate::random::{stream_seed, Rng};

/// The Langevin thermostat (LAMMPS `fix langevin`): on top of velocity Verlet,
/// every atom feels `f += -(m / damping) v + sqrt(24 k_B T m / (damping dt)) (u - 1/2)`
/// per component, `u` uniform in `[0, 1)`, drawn from a stream keyed by
/// (seed, step, atom id), so the noise does not depend on the atom order or the
/// thread count.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Langevin {
    /// Target temperature `T` (k_B = 1).
    pub temperature: f64,
    /// Damping time: the friction coefficient is `m / damping`.
    pub damping: f64,
    /// Seed of the noise.
    pub seed: u64,
}

/// How positions and velocities advance by `dt` with `a = f / m`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Integrator {
    /// Velocity Verlet (LAMMPS `fix nve`): `v += (dt/2) a; x += dt v`, new forces,
    /// `v += (dt/2) a`. Second order, symplectic, time reversible.
    VelocityVerlet,
    /// Explicit Euler: `x += dt v_n; v += dt a_n`. First order; energy drifts.
    Euler,
    /// Symplectic Euler: `v += dt a_n; x += dt v_{n+1}`. First order, symplectic.
    SymplecticEuler,
    /// Velocity Verlet with the Langevin thermostat (NVT).
    Langevin(Langevin),
}

impl Integrator {
    /// The part of the step before the new forces.
    pub fn first_half<const D: usize>(&self, atoms: &mut Atoms<D>, dt: f64) {
        let Atoms {
            masses,
            positions,
            velocities,
            forces,
            ..
        } = atoms;
        match self {
            Integrator::VelocityVerlet | Integrator::Langevin(_) => {
                let dtf = 0.5 * dt;
                for k in 0..positions.len() {
                    let dtfm = dtf / masses[k];
                    for a in 0..D {
                        velocities[k][a] += dtfm * forces[k][a];
                        positions[k][a] += dt * velocities[k][a];
                    }
                }
            }
            Integrator::Euler => {
                for k in 0..positions.len() {
                    let dtm = dt / masses[k];
                    for a in 0..D {
                        positions[k][a] += dt * velocities[k][a];
                        velocities[k][a] += dtm * forces[k][a];
                    }
                }
            }
            Integrator::SymplecticEuler => {
                for k in 0..positions.len() {
                    let dtm = dt / masses[k];
                    for a in 0..D {
                        velocities[k][a] += dtm * forces[k][a];
                        positions[k][a] += dt * velocities[k][a];
                    }
                }
            }
        }
    }

    /// The part of the step after the new forces (of step number `step`).
    pub fn second_half<const D: usize>(&self, atoms: &mut Atoms<D>, dt: f64, step: u64) {
        match self {
            Integrator::VelocityVerlet => kick(atoms, 0.5 * dt),
            Integrator::Langevin(thermostat) => {
                thermostat.add_forces(atoms, dt, step);
                kick(atoms, 0.5 * dt);
            }
            Integrator::Euler | Integrator::SymplecticEuler => {}
        }
    }
}

/// `v += (dtf / m) f`.
fn kick<const D: usize>(atoms: &mut Atoms<D>, dtf: f64) {
    for k in 0..atoms.len() {
        let dtfm = dtf / atoms.masses[k];
        for a in 0..D {
            atoms.velocities[k][a] += dtfm * atoms.forces[k][a];
        }
    }
}

impl Langevin {
    /// Adds the friction and the random force to `atoms.forces`.
    fn add_forces<const D: usize>(&self, atoms: &mut Atoms<D>, dt: f64, step: u64) {
        let noise = (24.0 * self.temperature / (self.damping * dt)).sqrt();
        for k in 0..atoms.len() {
            let m = atoms.masses[k];
            let gamma1 = -m / self.damping;
            let gamma2 = m.sqrt() * noise;
            let mut rng = Rng::new(stream_seed(self.seed, &[step, atoms.ids[k]]));
            for a in 0..D {
                atoms.forces[k][a] +=
                    gamma1 * atoms.velocities[k][a] + gamma2 * (rng.uniform() - 0.5);
            }
        }
    }
}
