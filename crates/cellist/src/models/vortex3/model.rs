//! The 3D vortex particle method behind the driver's [`Model`] interface.

use super::{
    abc_errors, initial_places, ring_places, Abc, Invariants3, Ring, RingPlace, Vortex3System,
};
use crate::models::pse::Integrator;
use crate::models::vortex::VortexError;
use crate::models::{Blowup, Checked, CheckedArray, Field, Ids, Model, ModelInfo};
use crate::state::{SectionSource, State, StateError};
use crate::threads::Threads;
use std::time::Duration;

/// The thermo columns of every 3D vortex run followed by `extra`.
macro_rules! columns {
    ($($extra:literal),*) => {
        &[
            "time",
            "total_vorticity_x",
            "total_vorticity_y",
            "total_vorticity_z",
            "impulse_x",
            "impulse_y",
            "impulse_z",
            "energy",
            "enstrophy",
            "helicity",
            $($extra),*
        ]
    };
}

/// The thermo columns after the invariants that an initial condition adds.
#[derive(Clone, Debug, PartialEq)]
pub enum Extras3 {
    /// None.
    None,
    /// One ring: `ring_z ring_radius ring_speed` ([`RingPlace`]).
    Ring(Ring),
    /// Several rings: `ring_k_z ring_k_radius` for each, tracked through each
    /// other.
    Rings(Vec<Ring>),
    /// `omega_l2_error omega_max_error`: the particles' vorticity against the
    /// ABC flow decayed by `exp(-nu t)` ([`abc_errors`]).
    Abc(Abc),
}

impl Extras3 {
    /// The thermo columns of a run with these extras. Those of several rings
    /// depend on their number: they are made when the model is built and kept
    /// for the process's life (`ModelInfo` holds static names).
    fn columns(&self) -> &'static [&'static str] {
        match self {
            Extras3::None => columns!(),
            Extras3::Ring(_) => columns!("ring_z", "ring_radius", "ring_speed"),
            Extras3::Abc(_) => columns!("omega_l2_error", "omega_max_error"),
            Extras3::Rings(rings) => {
                let base: &[&str] = columns!();
                let names: Vec<&'static str> = base
                    .iter()
                    .copied()
                    .chain((1..=rings.len()).flat_map(|k| {
                        [format!("ring_{k}_z"), format!("ring_{k}_radius")]
                            .map(|name| &*Box::leak(name.into_boxed_str()))
                    }))
                    .collect();
                Box::leak(names.into_boxed_slice())
            }
        }
    }

    /// The rings these extras track.
    fn rings(&self) -> &[Ring] {
        match self {
            Extras3::Ring(ring) => std::slice::from_ref(ring),
            Extras3::Rings(rings) => rings,
            _ => &[],
        }
    }
}

/// The pictures' plane: the axes drawn across and up, the axis across the
/// plane, the lower corner of the square shown (its middle along the third
/// axis is the plane's position) and its side.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct View3 {
    /// `[across, up, normal]`.
    pub axes: [usize; 3],
    /// The lower corner of the cube whose middle section is shown.
    pub origin: [f64; 3],
    /// Its side.
    pub side: f64,
    /// Whether it is the periodic box.
    pub periodic: bool,
}

/// A [`Vortex3System`] with its integrator, time step and diagnostics.
pub struct Vortex3Model {
    /// The particles.
    pub system: Vortex3System,
    /// How the state advances.
    pub integrator: Integrator,
    /// The time step.
    pub dt: f64,
    extras: Extras3,
    view: View3,
    /// The largest `|omega|` at the start: the end of the pictures' colour scale.
    scale: f64,
    /// The `|alpha|`-weighted position of the seeded rings along the first one's
    /// axis: the pictures follow the rings from there.
    start: f64,
    /// The ring places of the last thermo row (the tracking's start).
    places: Vec<RingPlace>,
    /// The thermo values of the last observed state (without the time).
    observed: Vec<f64>,
    info: ModelInfo,
}

/// What to try when a vortex run blows up.
const REMEDY: &str = "the step is too large for the flow (a particle should move less than a \
                      spacing per step, and nu dt / sigma^2 stay below about 0.5): use a smaller run.dt";

impl Vortex3Model {
    /// The model of `system`, its diagnostics computed for step 0; pictures show
    /// the section `view`.
    pub fn new(
        system: Vortex3System,
        integrator: Integrator,
        dt: f64,
        extras: Extras3,
        view: View3,
    ) -> Self {
        let volume = system.params().spacing.powi(3);
        let scale = system
            .alpha()
            .iter()
            .fold(0.0f64, |m, a| m.max(super::dot(*a, *a).sqrt()))
            / volume;
        let info = ModelInfo {
            name: "vortex",
            particle: "particle",
            thermo_columns: extras.columns(),
            remedy: REMEDY,
            count_may_change: system.params().remesh_every > 0,
        };
        let places = initial_places(extras.rings());
        let start = ring_position(&extras, &system);
        let mut model = Vortex3Model {
            info,
            system,
            integrator,
            dt,
            extras,
            view,
            scale,
            start,
            places,
            observed: Vec::new(),
        };
        model.observe(0);
        model
    }

    /// The elapsed time at `step`.
    fn time(&self, step: u64) -> f64 {
        step as f64 * self.dt
    }

    /// Computes the thermo values of the current state.
    fn observe(&mut self, step: u64) {
        let s = &self.system;
        let (x, alpha, u) = (s.positions(), s.alpha(), s.velocity());
        let h = s.params().spacing;
        let m = Invariants3::of(x, alpha, u, h, s.params().periodic_box().is_some());
        let mut values: Vec<f64> = m.total.into_iter().chain(m.impulse).collect();
        values.extend([m.energy, m.enstrophy, m.helicity]);
        match &self.extras {
            Extras3::None => {}
            Extras3::Ring(_) | Extras3::Rings(_) => {
                let rate = s.strength_rate();
                self.places = ring_places(self.extras.rings(), &self.places, x, alpha, u, rate);
                if matches!(self.extras, Extras3::Ring(_)) {
                    let p = self.places[0];
                    values.extend([p.z, p.radius, p.speed]);
                } else {
                    values.extend(self.places.iter().flat_map(|p| [p.z, p.radius]));
                }
            }
            Extras3::Abc(abc) => {
                let decay = (-s.params().nu * self.time(step)).exp();
                let (l2, max) = abc_errors(abc, decay, x, alpha, h);
                values.extend([l2, max]);
            }
        }
        self.observed = values;
    }

    /// Advances to `step`, its diagnostics computed when `observe`.
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
            self.observe(step);
        }
        Ok(())
    }
}

impl Vortex3Model {
    /// The pictures' corner: the seeded view's, moved along the rings' axis as
    /// far as the rings' weighted position has moved (a state's own, so that a
    /// restart draws the same pictures); the seeded view's itself where that
    /// position is not finite (strengths whose squares overflow, in a state on
    /// its way to a blow-up: its picture is drawn and the check of the next
    /// step stops the run).
    fn view_origin(&self) -> [f64; 3] {
        let shift = ring_position(&self.extras, &self.system) - self.start;
        match self.extras.rings().first() {
            Some(ring) if shift.is_finite() => {
                [0, 1, 2].map(|a| self.view.origin[a] + shift * ring.axis[a])
            }
            _ => self.view.origin,
        }
    }
}

/// `sum |alpha| x . a / sum |alpha|` along the first ring's axis `a` (0 without
/// rings).
fn ring_position(extras: &Extras3, system: &Vortex3System) -> f64 {
    let Some(ring) = extras.rings().first() else {
        return 0.0;
    };
    let (mut weight, mut moment) = (0.0, 0.0);
    for (x, a) in system.positions().iter().zip(system.alpha()) {
        let w = super::dot(*a, *a).sqrt();
        weight += w;
        moment += w * super::dot(*x, ring.axis);
    }
    if weight > 0.0 {
        moment / weight
    } else {
        0.0
    }
}

impl Model for Vortex3Model {
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
                per_particle: 3,
            },
            CheckedArray {
                quantity: "strength",
                values: self.system.alpha().as_flattened(),
                per_particle: 3,
            },
            CheckedArray {
                quantity: "velocity",
                values: self.system.velocity().as_flattened(),
                per_particle: 3,
            },
        ];
        Checked::new(Ids::Index, arrays)
    }

    fn field(&self) -> Option<Field> {
        let s = &self.system;
        let volume = s.params().spacing.powi(3);
        let component = |v: &[[f64; 3]], c: usize| v.iter().map(|a| a[c]).collect::<Vec<f64>>();
        let (alpha, u) = (s.alpha(), s.velocity());
        Some(Field {
            dimension: 3,
            positions: s.positions().to_vec(),
            values: alpha
                .iter()
                .map(|a| super::dot(*a, *a).sqrt() / volume)
                .collect(),
            value_name: "omega_magnitude",
            value_written: false,
            strengths: None,
            extra: vec![
                ("ax", component(alpha, 0)),
                ("ay", component(alpha, 1)),
                ("az", component(alpha, 2)),
                ("u", component(u, 0)),
                ("v", component(u, 1)),
                ("w", component(u, 2)),
            ],
            axes: self.view.axes,
            origin: self.view_origin(),
            periodic: self.view.periodic,
            side: self.view.side,
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
        state.put_vectors("alpha", self.system.alpha());
        let tracked = self.places.iter().flat_map(|p| [p.z, p.radius, p.speed]);
        state.put_f64s("dropped", self.system.dropped());
        state.put_f64s("places", tracked);
        state.put_f64s("scale", [self.scale]);
        state.put_f64s("observed", self.observed.iter().copied());
    }

    fn restore(&mut self, state: &dyn SectionSource, threads: &Threads) -> Result<(), StateError> {
        let n = state.f64s("alpha")?.len() / 3;
        let alpha = state.vectors::<3>("alpha", n)?;
        let positions = state.vectors::<3>("positions", n)?;
        let dropped = state.f64s_of("dropped", 3)?;
        let places = state.f64s_of("places", 3 * self.places.len())?;
        self.places = places
            .chunks(3)
            .map(|p| RingPlace {
                z: p[0],
                radius: p[1],
                speed: p[2],
            })
            .collect();
        self.scale = state.f64s_of("scale", 1)?[0];
        self.observed = state.f64s("observed")?;
        self.system
            .set_particles(
                &positions,
                &alpha,
                [dropped[0], dropped[1], dropped[2]],
                threads,
            )
            .map_err(|e| StateError(e.to_string()))
    }
}
