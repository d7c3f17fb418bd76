//! The collision benchmark behind the driver's [`Model`] interface.

use super::error::{not_converged_what, overflow_what, BilliardsError};
use super::system::Billiards;
use crate::models::{Blowup, Checked, CheckedArray, Ids, Model, ModelInfo, Particles};
use crate::state::{SectionSource, State, StateError};
use crate::threads::Threads;
use std::time::{Duration, Instant};

/// A [`Billiards`] table with the input's particle ids, and the hardest step so
/// far (the one that needed the most sweeps).
pub struct BilliardsModel {
    /// The discs.
    pub system: Billiards,
    /// The ids of the input's lines, in vector order.
    pub ids: Vec<u32>,
    /// `(step, sweeps)` of the hardest step so far.
    pub hardest: (u64, u64),
    step_time: Duration,
}

impl BilliardsModel {
    /// The model of `system` whose discs carry `ids`.
    pub fn new(system: Billiards, ids: Vec<u32>) -> Self {
        BilliardsModel {
            system,
            ids,
            hardest: (0, 0),
            step_time: Duration::ZERO,
        }
    }
}

/// What the collision benchmark's model is: discs and their energy.
pub const INFO: ModelInfo = ModelInfo {
    name: "billiards",
    particle: "particle",
    thermo_columns: &["energy"],
    remedy: "the input's speeds or overlaps are beyond what the benchmark's rules settle: \
             check the input, or raise --max-sweeps (run.max_sweeps in a scenario)",
    count_may_change: false,
};

impl Model for BilliardsModel {
    fn info(&self) -> &ModelInfo {
        &INFO
    }

    fn len(&self) -> usize {
        self.system.len()
    }

    /// One step moves every disc by its velocity: time is counted in steps.
    fn dt(&self) -> f64 {
        1.0
    }

    fn step(&mut self, step: u64, threads: &Threads) -> Result<(), Blowup> {
        let t = Instant::now();
        let result = self.system.step(step, threads);
        self.step_time += t.elapsed();
        let stats = result.map_err(|e| {
            let what = match e {
                BilliardsError::Overflow { index, .. } => overflow_what(index),
                BilliardsError::NotConverged {
                    sweeps,
                    first,
                    size,
                    ..
                } => not_converged_what(sweeps, first, size),
                other => other.to_string(),
            };
            Blowup::new(step, what, INFO.remedy)
        })?;
        if stats.sweeps > self.hardest.1 {
            self.hardest = (step, stats.sweeps);
        }
        Ok(())
    }

    /// The benchmark's energy `sum (vx^2 + vy^2)`.
    fn thermo(&self, _step: u64) -> Vec<f64> {
        vec![self.system.energy()]
    }

    fn checked(&self) -> Checked<'_> {
        let s = &self.system;
        let arrays = vec![
            CheckedArray {
                quantity: "x",
                values: &s.x,
                per_particle: 1,
            },
            CheckedArray {
                quantity: "y",
                values: &s.y,
                per_particle: 1,
            },
            CheckedArray {
                quantity: "velocity",
                values: s.v.as_flattened(),
                per_particle: 2,
            },
        ];
        Checked::new(Ids::U32(&self.ids), arrays)
    }

    /// In vector order, the box `[0, L]^2` (walls, not periodic), z = 0.
    fn particles(&self, _step: u64, _energies: bool) -> Option<Particles> {
        let s = &self.system;
        Some(Particles {
            dimension: 2,
            lo: [0.0, 0.0, -0.5],
            hi: [s.table().side_f(), s.table().side_f(), 0.5],
            periodic: [false; 3],
            ids: self.ids.iter().map(|&i| i as u64).collect(),
            types: vec![1; s.len()],
            positions: s.x.iter().zip(&s.y).map(|(&x, &y)| [x, y, 0.0]).collect(),
            velocities: s.v.iter().map(|v| [v[0], v[1], 0.0]).collect(),
            ..Particles::default()
        })
    }

    fn stage_times(&self) -> Vec<(&'static str, Duration)> {
        vec![("Step", self.step_time)]
    }

    fn save(&self, state: &mut State) {
        let s = &self.system;
        state.put_u64s("ids", self.ids.iter().map(|&i| i as u64));
        state.put_f64s("x", s.x.iter().copied());
        state.put_f64s("y", s.y.iter().copied());
        state.put_vectors("v", &s.v);
        state.put_u64s("hardest", [self.hardest.0, self.hardest.1]);
    }

    fn restore(&mut self, state: &dyn SectionSource, _threads: &Threads) -> Result<(), StateError> {
        let n = self.len();
        let ids = state.u64s_of("ids", n)?;
        if ids.iter().zip(&self.ids).any(|(&a, &b)| a != b as u64) {
            return Err(StateError(
                "the particle ids differ from the input's".into(),
            ));
        }
        let hardest = state.u64s_of("hardest", 2)?;
        let (x, y, v) = (
            state.f64s_of("x", n)?,
            state.f64s_of("y", n)?,
            state.vectors("v", n)?,
        );
        self.system.x = x;
        self.system.y = y;
        self.system.v = v;
        self.hardest = (hardest[0], hardest[1]);
        Ok(())
    }
}
