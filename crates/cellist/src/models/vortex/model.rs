//! The vortex particle method behind the driver's [`Model`] interface.

use super::{energy_and_enstrophy, lamb_oseen_vorticity, Moments, VortexError, VortexSystem};
use crate::models::pse::Integrator;
use crate::models::{Blowup, Checked, CheckedArray, Field, Ids, Model, ModelInfo};
use crate::state::{SectionSource, State, StateError};
use crate::threads::Threads;
use std::f64::consts::PI;
use std::time::Duration;

/// The thermo columns of every vortex run followed by `extra`.
macro_rules! columns {
    ($($extra:literal),*) => {
        &[
            "time",
            "circulation",
            "impulse_x",
            "impulse_y",
            "angular_impulse",
            "energy",
            "enstrophy",
            $($extra),*
        ]
    };
}

/// The thermo columns after the invariants that an initial condition adds.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Extras {
    /// None.
    None,
    /// `omega_l2_error omega_max_error`: the particles' vorticity `Gamma_i / h^2`
    /// against the Lamb-Oseen vortex of age `t0 + t` about `center`, as
    /// `sqrt(sum_i h^2 e_i^2)` and `max_i |e_i|`.
    LambOseen {
        /// Total circulation.
        circulation: f64,
        /// Initial age.
        t0: f64,
        /// The vortex's centre.
        center: [f64; 2],
    },
    /// `aspect_ratio effective_viscosity`: `sqrt(l_max / l_min)` of the
    /// second-moment tensor `J = sum Gamma (x - x_c)(x - x_c)^T`, and
    /// `(tr J(t) - tr J(0)) / (4 Gamma t)` (0 at `t = 0`): a viscous vortex spreads
    /// as `d tr J / dt = 4 nu Gamma`, so this is the viscosity the run behaves as.
    Ellipse,
    /// `axis_angle`: the angle of the major axis of `J` from x, unwrapped (radians):
    /// two co-rotating vortices turn it at `Gamma / (pi b^2)`.
    Pair,
}

impl Extras {
    /// The thermo columns of a run with these extras.
    fn columns(&self) -> &'static [&'static str] {
        match self {
            Extras::None => columns!(),
            Extras::LambOseen { .. } => columns!("omega_l2_error", "omega_max_error"),
            Extras::Ellipse => columns!("aspect_ratio", "effective_viscosity"),
            Extras::Pair => columns!("axis_angle"),
        }
    }
}

/// A [`VortexSystem`] with its integrator, time step and diagnostics.
pub struct VortexModel {
    /// The particles.
    pub system: VortexSystem,
    /// How the state advances.
    pub integrator: Integrator,
    /// The time step.
    pub dt: f64,
    extras: Extras,
    /// `tr J` at step 0.
    initial_spread: f64,
    /// The pictures' fixed view: lower corner and side.
    view: ([f64; 2], f64),
    /// The largest `|omega|` at the start: the end of the pictures' colour scale.
    scale: f64,
    /// The unwrapped major-axis angle of the last thermo row.
    angle: f64,
    /// The thermo values of the last observed state (without the time).
    observed: Vec<f64>,
    info: ModelInfo,
}

/// What to try when a vortex run blows up.
const REMEDY: &str =
    "the step is too large for the flow (a particle should move less than a spacing per \
                      step, and nu dt / sigma^2 stay below about 0.5): use a smaller run.dt";

impl VortexModel {
    /// The model of `system`, its diagnostics computed for step 0 (their
    /// pair sums shared by the system's peers, which then observe the same
    /// steps); pictures show the square `view` (lower corner, side).
    pub fn new(
        system: VortexSystem,
        integrator: Integrator,
        dt: f64,
        extras: Extras,
        view: ([f64; 2], f64),
        threads: &Threads,
    ) -> Self {
        let h2 = system.params().spacing.powi(2);
        let scale = system.gamma().iter().fold(0.0f64, |m, g| m.max(g.abs())) / h2;
        let moments = Moments::of(system.positions(), system.gamma());
        let angle = moments.ellipse().1;
        let info = ModelInfo {
            name: "vortex",
            particle: "particle",
            thermo_columns: extras.columns(),
            remedy: REMEDY,
            count_may_change: system.params().remesh_every > 0,
        };
        let mut model = VortexModel {
            info,
            system,
            integrator,
            dt,
            extras,
            initial_spread: moments.second[0] + moments.second[2],
            view,
            scale,
            angle,
            observed: Vec::new(),
        };
        model.observe(0, threads);
        model
    }

    /// The elapsed time at `step`.
    fn time(&self, step: u64) -> f64 {
        step as f64 * self.dt
    }

    /// Computes the thermo values of the current state.
    fn observe(&mut self, step: u64, threads: &Threads) {
        let system = &self.system;
        let m = Moments::of(system.positions(), system.gamma());
        let (energy, enstrophy) = energy_and_enstrophy(
            system.positions(),
            system.gamma(),
            system.params().sigma,
            threads,
            system.peers(),
        );
        let mut values = vec![
            m.circulation,
            m.impulse[0],
            m.impulse[1],
            m.angular_impulse,
            energy,
            enstrophy,
        ];
        let time = self.time(step);
        match self.extras {
            Extras::None => {}
            Extras::LambOseen {
                circulation,
                t0,
                center,
            } => {
                let nu = system.params().nu;
                let h2 = system.params().spacing.powi(2);
                let (mut sq, mut max) = (0.0f64, 0.0f64);
                for (x, g) in system.positions().iter().zip(system.gamma()) {
                    let r2 = (x[0] - center[0]).powi(2) + (x[1] - center[1]).powi(2);
                    let e = (g / h2 - lamb_oseen_vorticity(circulation, nu, t0 + time, r2)).abs();
                    sq += h2 * e * e;
                    max = max.max(e);
                }
                values.extend([sq.sqrt(), max]);
            }
            Extras::Ellipse => {
                let spread = m.second[0] + m.second[2];
                let nu_eff = if time > 0.0 {
                    (spread - self.initial_spread) / (4.0 * m.circulation * time)
                } else {
                    0.0
                };
                values.extend([m.ellipse().0, nu_eff]);
            }
            Extras::Pair => {
                // the axis is defined modulo pi: follow it continuously
                let raw = m.ellipse().1;
                let turns = ((self.angle - raw) / PI).round();
                self.angle = raw + turns * PI;
                values.push(self.angle);
            }
        }
        self.observed = values;
    }
}

impl VortexModel {
    /// Advances to `step`, its invariants computed when `observe`.
    fn advance(&mut self, step: u64, observe: bool, threads: &Threads) -> Result<(), Blowup> {
        match self.system.step(self.integrator, self.dt, step, threads) {
            // the driver's check names the particle, the quantity and its value
            Err(VortexError::NotFinite { .. }) => return Ok(()),
            result => result,
        }
        .map_err(|e| {
            let remedy = match e {
                VortexError::Parameter(_) => "this is a bug in the model",
                _ => REMEDY,
            };
            Blowup::new(step, e.to_string(), remedy)
        })?;
        if observe {
            self.observe(step, threads);
        }
        Ok(())
    }
}

impl Model for VortexModel {
    fn info(&self) -> &ModelInfo {
        &self.info
    }

    fn len(&self) -> usize {
        self.system.len()
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

    fn thermo(&self, step: u64) -> Vec<f64> {
        let mut row = vec![self.time(step)];
        row.extend_from_slice(&self.observed);
        row
    }

    fn checked(&self) -> Checked<'_> {
        let arrays = vec![
            CheckedArray {
                quantity: "position",
                values: self.system.positions().as_flattened(),
                per_particle: 2,
            },
            CheckedArray {
                quantity: "circulation",
                values: self.system.gamma(),
                per_particle: 1,
            },
            CheckedArray {
                quantity: "velocity",
                values: self.system.velocity().as_flattened(),
                per_particle: 2,
            },
        ];
        Checked::new(Ids::Index, arrays)
    }

    fn field(&self) -> Option<Field> {
        let s = &self.system;
        let h2 = s.params().spacing.powi(2);
        let (lo, side) = self.view;
        Some(Field {
            dimension: 2,
            positions: s.positions().iter().map(|x| [x[0], x[1], 0.0]).collect(),
            values: s.gamma().iter().map(|g| g / h2).collect(),
            value_name: "omega",
            value_written: true,
            strengths: None,
            extra: vec![
                ("gamma", s.gamma().to_vec()),
                ("u", s.velocity().iter().map(|u| u[0]).collect()),
                ("v", s.velocity().iter().map(|u| u[1]).collect()),
            ],
            axes: [0, 1, 2],
            origin: [lo[0], lo[1], 0.0],
            periodic: false,
            side,
            spacing: s.params().spacing,
            scale: self.scale,
        })
    }

    fn stage_times(&self) -> Vec<(&'static str, Duration)> {
        let t = self.system.times();
        vec![
            ("Velocity", t.velocity),
            ("Diffusion", t.diffusion),
            ("Remesh", t.remesh),
        ]
    }

    fn save(&self, state: &mut State) {
        state.put_vectors("positions", self.system.positions());
        state.put_f64s("gamma", self.system.gamma().iter().copied());
        state.put_f64s("scalars", [self.system.dropped(), self.angle, self.scale]);
        state.put_f64s("observed", self.observed.iter().copied());
    }

    fn restore(&mut self, state: &dyn SectionSource, threads: &Threads) -> Result<(), StateError> {
        let gamma = state.f64s("gamma")?;
        let positions = state.vectors::<2>("positions", gamma.len())?;
        let scalars = state.f64s_of("scalars", 3)?;
        self.angle = scalars[1];
        self.scale = scalars[2];
        // the thermo of the saved step (checkpoints before it was saved have none)
        if let Ok(observed) = state.f64s("observed") {
            self.observed = observed;
        }
        self.system
            .set_particles(positions, gamma, scalars[0], threads)
            .map_err(|e| StateError(e.to_string()))?;
        Ok(())
    }
}
