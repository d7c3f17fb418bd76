//! Self-gravitating bodies behind the driver's [`Model`] interface.

use super::{Bodies, GravitySystem, Integrator};
use crate::models::{Blowup, Checked, CheckedArray, Ids, Model, ModelInfo, Particles};
use crate::state::{State, StateError};
use crate::threads::Threads;
use std::time::{Duration, Instant};

/// A [`GravitySystem`] with its integrator, time step and the energy at step 0
/// (the reference of the relative energy error).
pub struct GravityModel {
    /// The bodies and their solver.
    pub system: GravitySystem,
    /// How the bodies move.
    pub integrator: Integrator,
    /// The time step.
    pub dt: f64,
    /// 2 for bodies in the plane z = 0 (a 2D scenario), else 3.
    pub dimension: usize,
    e0: f64,
    step_time: Duration,
}

impl GravityModel {
    /// The model of `system`; the energy now is the reference `E0`.
    pub fn new(system: GravitySystem, integrator: Integrator, dt: f64) -> Self {
        GravityModel {
            e0: system.observables().total(),
            system,
            integrator,
            dt,
            dimension: 3,
            step_time: Duration::ZERO,
        }
    }
}

/// What a gravity model is: bodies, their energies and momenta.
pub const INFO: ModelInfo = ModelInfo {
    name: "gravity",
    particle: "body",
    thermo_columns: &[
        "time",
        "ke",
        "pe",
        "etotal",
        "rel_energy_error",
        "px",
        "py",
        "pz",
        "lx",
        "ly",
        "lz",
    ],
    remedy:
        "two bodies came too close for the step: try a smaller run.dt or a larger system.softening",
    count_may_change: false,
};

impl Model for GravityModel {
    fn info(&self) -> &ModelInfo {
        &INFO
    }

    fn len(&self) -> usize {
        self.system.len()
    }

    fn dt(&self) -> f64 {
        self.dt
    }

    fn step(&mut self, step: u64, threads: &Threads) -> Result<(), Blowup> {
        let t = Instant::now();
        let result = self.system.step(self.dt, self.integrator, threads);
        self.step_time += t.elapsed();
        result.map_err(|e| Blowup::new(step, e.to_string(), INFO.remedy))
    }

    /// Energies, `(E - E0) / |E0|` (or `E - E0` when `E0 = 0`), momentum and angular
    /// momentum.
    fn thermo(&self, step: u64) -> Vec<f64> {
        let o = self.system.observables();
        let de = o.total() - self.e0;
        let rel = if self.e0 == 0.0 {
            de
        } else {
            de / self.e0.abs()
        };
        let (p, l) = (o.momentum, o.angular_momentum);
        vec![
            step as f64 * self.dt,
            o.kinetic,
            o.potential,
            o.total(),
            rel,
            p[0],
            p[1],
            p[2],
            l[0],
            l[1],
            l[2],
        ]
    }

    /// Bodies are named by their index in the input (0-based), as the engine's
    /// errors name them.
    fn checked(&self) -> Checked<'_> {
        let b = self.system.bodies();
        fn vector<'a>(quantity: &'static str, v: &'a [[f64; 3]]) -> CheckedArray<'a> {
            CheckedArray {
                quantity,
                values: v.as_flattened(),
                per_particle: 3,
            }
        }
        let arrays = vec![
            vector("position", &b.position),
            vector("velocity", &b.velocity),
            vector("acceleration", self.system.accelerations()),
            CheckedArray {
                quantity: "potential",
                values: self.system.potentials(),
                per_particle: 1,
            },
        ];
        Checked::new(Ids::Index, arrays)
    }

    /// In input order with ids 1..=N; the box is the bodies' bounding box.
    fn particles(&self, _step: u64, _energies: bool) -> Option<Particles> {
        let b = self.system.bodies();
        let (lo, hi) = crate::geometry::bounding_box(&b.position);
        Some(Particles {
            dimension: self.dimension,
            lo,
            hi,
            periodic: [false; 3],
            ids: (1..=b.len() as u64).collect(),
            types: Vec::new(),
            positions: b.position.clone(),
            velocities: b.velocity.clone(),
            forces: Vec::new(),
            energies: None,
            masses: Some(b.mass.clone()),
            accelerations: Some(self.system.accelerations().to_vec()),
            potentials: Some(self.system.potentials().to_vec()),
        })
    }

    fn stage_times(&self) -> Vec<(&'static str, Duration)> {
        vec![("Step", self.step_time)]
    }

    fn save(&self, state: &mut State) {
        let b = self.system.bodies();
        state.put_f64s("mass", b.mass.iter().copied());
        state.put_vectors("position", &b.position);
        state.put_vectors("velocity", &b.velocity);
        state.put_vectors("acceleration", self.system.accelerations());
        state.put_f64s("potential", self.system.potentials().iter().copied());
        state.put_f64s("e0", [self.e0]);
    }

    fn restore(&mut self, state: &State, _threads: &Threads) -> Result<(), StateError> {
        let n = self.len();
        let bodies = Bodies {
            mass: state.f64s_of("mass", n)?,
            position: state.vectors("position", n)?,
            velocity: state.vectors("velocity", n)?,
        };
        self.e0 = state.f64("e0")?;
        self.system
            .restore(
                bodies,
                state.vectors("acceleration", n)?,
                state.f64s_of("potential", n)?,
            )
            .map_err(StateError)
    }
}
