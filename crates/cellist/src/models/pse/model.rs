//! Diffusion by particle strength exchange behind the driver's [`Model`] interface.

use super::{InitialField, Integrator, PseSystem};
use crate::models::{Blowup, Checked, CheckedArray, Field, Ids, Model, ModelInfo};
use crate::state::{SectionSource, State, StateError};
use crate::threads::Threads;
use std::time::{Duration, Instant};

/// A [`PseSystem`] with its integrator, time step and (if known) exact solution.
pub struct PseModel<const D: usize> {
    /// The particles and their field.
    pub system: PseSystem<D>,
    /// How the field advances.
    pub integrator: Integrator,
    /// The time step.
    pub dt: f64,
    /// The initial field, whose exact evolution the thermo compares with.
    pub initial: Option<InitialField<D>>,
    /// The lattice spacing `h = side / N^(1/D)`.
    pub spacing: f64,
    /// The largest `|phi|` at the start: the end of the pictures' colour scale.
    scale: f64,
    step_time: Duration,
}

/// What a pse model is: a field on particles, its total and its errors
/// against the exact solution.
pub const INFO: ModelInfo = ModelInfo {
    name: "pse",
    particle: "particle",
    thermo_columns: &["time", "total", "l2_error", "max_error"],
    remedy: "run.dt is above the stability limit of the integrator for this kernel and spacing: use a smaller run.dt",
    count_may_change: false,
};

impl<const D: usize> PseModel<D> {
    /// The model of `system`; the pictures' scale is the largest `|phi|` now.
    pub fn new(
        system: PseSystem<D>,
        integrator: Integrator,
        dt: f64,
        initial: Option<InitialField<D>>,
        spacing: f64,
    ) -> Self {
        let scale = system.slot_phi().iter().fold(0.0f64, |m, v| m.max(v.abs()));
        PseModel {
            system,
            integrator,
            dt,
            initial,
            spacing,
            scale,
            step_time: Duration::ZERO,
        }
    }
}

impl<const D: usize> Model for PseModel<D> {
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
        let result = self.system.step(self.integrator, self.dt, threads);
        self.step_time += t.elapsed();
        result.map_err(|e| Blowup::new(step, e.to_string(), INFO.remedy))
    }

    fn thermo(&self, step: u64) -> Vec<f64> {
        let time = step as f64 * self.dt;
        let (l2, max) = match &self.initial {
            Some(field) => {
                let domain = self.system.domain();
                let exact = field.exact_at(
                    &self.system.positions(),
                    time,
                    self.system.params().nu,
                    &domain.length,
                );
                self.system.errors(&exact)
            }
            None => (f64::NAN, f64::NAN),
        };
        vec![time, self.system.total(), l2, max]
    }

    fn checked(&self) -> Checked<'_> {
        let field = CheckedArray {
            quantity: "field",
            values: self.system.slot_phi(),
            per_particle: 1,
        };
        Checked::new(Ids::U32(self.system.order()), vec![field])
    }

    fn field(&self) -> Option<Field> {
        let pad = |x: &[f64; D]| std::array::from_fn(|a| if a < D { x[a] } else { 0.0 });
        Some(Field {
            dimension: D,
            positions: self.system.positions().iter().map(pad).collect(),
            strengths: Some(
                self.system
                    .phi()
                    .iter()
                    .map(|p| p * self.system.volume())
                    .collect(),
            ),
            values: self.system.phi(),
            value_name: "phi",
            value_written: true,
            extra: Vec::new(),
            axes: [0, 1, 2],
            origin: [0.0; 3],
            periodic: true,
            side: self.system.domain().length[0],
            spacing: self.spacing,
            scale: self.scale,
        })
    }

    fn stage_times(&self) -> Vec<(&'static str, Duration)> {
        vec![("Rates", self.step_time)]
    }

    fn save(&self, state: &mut State) {
        state.put_vectors("positions", self.system.slot_positions());
        state.put_f64s("phi", self.system.slot_phi().iter().copied());
        state.put_f64s("picture_scale", [self.scale]);
    }

    fn restore(&mut self, state: &dyn SectionSource, _threads: &Threads) -> Result<(), StateError> {
        let n = self.len();
        let positions = state.vectors::<D>("positions", n)?;
        if positions.as_slice() != self.system.slot_positions() {
            return Err(StateError(
                "the particles' positions differ from the saved run's (was the particle file changed?)"
                    .into(),
            ));
        }
        self.scale = state.f64("picture_scale")?;
        self.system
            .set_slot_phi(&state.f64s_of("phi", n)?)
            .map_err(StateError)
    }
}
