//! Time integrators for molecular dynamics, split around the force evaluation:
//! `first_half` before the new forces, `second_half` after.

use super::{Atoms, ATOM_CHUNK};
use crate::random::{stream_seed, Rng};
use crate::threads::Threads;
use rayon::prelude::*;

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
    /// The part of the step before the new forces, on every atom in parallel
    /// (each atom's update is its own: the same bits for any thread count).
    pub fn first_half<const D: usize>(&self, atoms: &mut Atoms<D>, dt: f64, threads: &Threads) {
        match self {
            Integrator::VelocityVerlet | Integrator::Langevin(_) => {
                let dtf = 0.5 * dt;
                each_atom(atoms, threads, |atom| {
                    let dtfm = dtf / atom.mass;
                    for a in 0..D {
                        atom.velocity[a] += dtfm * atom.force[a];
                        atom.position[a] += dt * atom.velocity[a];
                    }
                });
            }
            Integrator::Euler => each_atom(atoms, threads, |atom| {
                let dtm = dt / atom.mass;
                for a in 0..D {
                    atom.position[a] += dt * atom.velocity[a];
                    atom.velocity[a] += dtm * atom.force[a];
                }
            }),
            Integrator::SymplecticEuler => each_atom(atoms, threads, |atom| {
                let dtm = dt / atom.mass;
                for a in 0..D {
                    atom.velocity[a] += dtm * atom.force[a];
                    atom.position[a] += dt * atom.velocity[a];
                }
            }),
        }
    }

    /// The part of the step after the new forces (of step number `step`), on
    /// every atom in parallel.
    pub fn second_half<const D: usize>(
        &self,
        atoms: &mut Atoms<D>,
        dt: f64,
        step: u64,
        threads: &Threads,
    ) {
        match self {
            Integrator::VelocityVerlet => each_atom(atoms, threads, |atom| kick(atom, 0.5 * dt)),
            Integrator::Langevin(thermostat) => {
                let noise = thermostat.noise(dt);
                each_atom(atoms, threads, |mut atom| {
                    thermostat.add_force(&mut atom, noise, step);
                    kick(atom, 0.5 * dt);
                });
            }
            Integrator::Euler | Integrator::SymplecticEuler => {}
        }
    }
}

/// One atom's entries, as an integrator updates them.
struct AtomMut<'a, const D: usize> {
    id: u64,
    mass: f64,
    position: &'a mut [f64; D],
    velocity: &'a mut [f64; D],
    force: &'a mut [f64; D],
}

/// `update` on every atom, in chunks on `threads`.
fn each_atom<const D: usize>(
    atoms: &mut Atoms<D>,
    threads: &Threads,
    update: impl Fn(AtomMut<'_, D>) + Sync,
) {
    let Atoms {
        ids,
        masses,
        positions,
        velocities,
        forces,
        ..
    } = atoms;
    threads.install(|| {
        (
            ids.par_chunks(ATOM_CHUNK),
            masses.par_chunks(ATOM_CHUNK),
            positions.par_chunks_mut(ATOM_CHUNK),
            velocities.par_chunks_mut(ATOM_CHUNK),
            forces.par_chunks_mut(ATOM_CHUNK),
        )
            .into_par_iter()
            .for_each(|(ids, masses, positions, velocities, forces)| {
                let entries = ids.iter().zip(masses).zip(positions).zip(velocities);
                for ((((&id, &mass), position), velocity), force) in entries.zip(forces) {
                    update(AtomMut {
                        id,
                        mass,
                        position,
                        velocity,
                        force,
                    });
                }
            });
    });
}

/// `v += (dtf / m) f`.
#[inline(always)]
fn kick<const D: usize>(atom: AtomMut<'_, D>, dtf: f64) {
    let dtfm = dtf / atom.mass;
    for a in 0..D {
        atom.velocity[a] += dtfm * atom.force[a];
    }
}

impl Langevin {
    /// The amplitude of the random force per `sqrt(m)`:
    /// `sqrt(24 k_B T / (damping dt))`.
    fn noise(&self, dt: f64) -> f64 {
        (24.0 * self.temperature / (self.damping * dt)).sqrt()
    }

    /// Adds the friction and the random force (of amplitude `sqrt(m) noise`)
    /// to the atom's force.
    #[inline(always)]
    fn add_force<const D: usize>(&self, atom: &mut AtomMut<'_, D>, noise: f64, step: u64) {
        let m = atom.mass;
        let gamma1 = -m / self.damping;
        let gamma2 = m.sqrt() * noise;
        let mut rng = Rng::new(stream_seed(self.seed, &[step, atom.id]));
        for a in 0..D {
            atom.force[a] += gamma1 * atom.velocity[a] + gamma2 * (rng.uniform() - 0.5);
        }
    }
}
