//! Self-gravitating bodies behind the driver's [`Model`] interface.

use super::{Bodies, GravitySystem, Integrator, Observables};
use crate::models::{Blowup, Checked, CheckedArray, Ids, Model, ModelInfo, Particles};
use crate::state::{
    Layout, SectionSink, SectionSource, SectionWriter, State, StateBuilder, StateError,
};
use crate::threads::Threads;
use std::ops::Range;
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

    /// The row of [`thermo_row`] now.
    fn thermo(&self, step: u64) -> Vec<f64> {
        thermo_row(&self.system.observables(), self.e0, step as f64 * self.dt)
    }

    /// Bodies are named by their index in the input (0-based), as the engine's
    /// errors name them.
    fn checked(&self) -> Checked<'_> {
        let field = (self.system.accelerations(), self.system.potentials());
        checked_bodies(Ids::Index, self.system.bodies(), field)
    }

    /// In input order with ids 1..=N; the box is the bodies' bounding box.
    fn particles(&self, _step: u64, _energies: bool) -> Option<Particles> {
        let b = self.system.bodies();
        let bounds = crate::geometry::bounding_box(&b.position);
        let ids = (1..=b.len() as u64).collect();
        let field = (self.system.accelerations(), self.system.potentials());
        Some(body_particles(self.dimension, bounds, ids, b, field))
    }

    fn stage_times(&self) -> Vec<(&'static str, Duration)> {
        vec![("Step", self.step_time)]
    }

    fn save(&self, state: &mut State) {
        let field = (self.system.accelerations(), self.system.potentials());
        save_bodies(state, self.system.bodies(), field, self.e0);
    }

    fn restore(&mut self, state: &dyn SectionSource, _threads: &Threads) -> Result<(), StateError> {
        let (bodies, acc, phi, e0) = load_bodies(state, self.len(), 0..self.len())?;
        self.e0 = e0;
        self.system.restore(bodies, acc, phi).map_err(StateError)
    }
}

/// The arrays of `bodies` named by `ids` that must stay finite: positions,
/// velocities and the accelerations and potentials of `field`.
pub fn checked_bodies<'a>(
    ids: Ids<'a>,
    bodies: &'a Bodies,
    field: (&'a [[f64; 3]], &'a [f64]),
) -> Checked<'a> {
    fn vector<'a>(quantity: &'static str, v: &'a [[f64; 3]]) -> CheckedArray<'a> {
        CheckedArray {
            quantity,
            values: v.as_flattened(),
            per_particle: 3,
        }
    }
    let arrays = vec![
        vector("position", &bodies.position),
        vector("velocity", &bodies.velocity),
        vector("acceleration", field.0),
        CheckedArray {
            quantity: "potential",
            values: field.1,
            per_particle: 1,
        },
    ];
    Checked::new(ids, arrays)
}

/// The thermo row of bodies whose sums are `o`, at `time`, against the energy
/// `e0` of step 0: `time`, `T`, `W`, `E = T + W`, `(E - E0) / |E0|` (or `E -
/// E0` when `E0 = 0`), `P` and `L` (the columns of [`INFO`]).
pub fn thermo_row(o: &Observables, e0: f64, time: f64) -> Vec<f64> {
    let de = o.total() - e0;
    let rel = if e0 == 0.0 { de } else { de / e0.abs() };
    let (p, l) = (o.momentum, o.angular_momentum);
    vec![
        time,
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

/// The dump rows of `bodies` named `ids`, with their accelerations and
/// potentials `field`, in the box `bounds` (`(lo, hi)`) of a run in
/// `dimension` dimensions.
pub fn body_particles(
    dimension: usize,
    bounds: ([f64; 3], [f64; 3]),
    ids: Vec<u64>,
    bodies: &Bodies,
    field: (&[[f64; 3]], &[f64]),
) -> Particles {
    Particles {
        dimension,
        lo: bounds.0,
        hi: bounds.1,
        periodic: [false; 3],
        ids,
        types: Vec::new(),
        positions: bodies.position.clone(),
        velocities: bodies.velocity.clone(),
        forces: Vec::new(),
        energies: None,
        masses: Some(bodies.mass.clone()),
        accelerations: Some(field.0.to_vec()),
        potentials: Some(field.1.to_vec()),
    }
}

/// Writes the state of `bodies` with their accelerations and potentials
/// `field` and the energy `e0` of step 0 into `state` (a checkpoint's
/// layout: `mass`, `position`, `velocity`, `acceleration`, `potential`, `e0`).
pub fn save_bodies(state: &mut State, bodies: &Bodies, field: (&[[f64; 3]], &[f64]), e0: f64) {
    let mut layout = Layout::default();
    let mut saved = SavedBodies::new(bodies.len(), &mut layout);
    let mut sections = StateBuilder::new(layout);
    saved.push(&mut sections, bodies, field);
    saved.finish(&mut sections, e0);
    sections.finish(state);
}

/// The sections of [`save_bodies`] written a block of bodies at a time (in
/// order) into a [`SectionSink`]: the same bytes as one call with all of
/// them, so that a state gathered from parts goes to its file without being
/// held whole.
pub struct SavedBodies {
    /// The sections' indices in the layout: `mass`, `position`, `velocity`,
    /// `acceleration`, `potential`, `e0`.
    sections: [usize; 6],
    writer: SectionWriter,
}

impl SavedBodies {
    /// The sections of `n` bodies, added to `layout`.
    pub fn new(n: usize, layout: &mut Layout) -> Self {
        let sections = [
            ("mass", n),
            ("position", 3 * n),
            ("velocity", 3 * n),
            ("acceleration", 3 * n),
            ("potential", n),
            ("e0", 1),
        ]
        .map(|(name, values)| layout.add(name, values));
        SavedBodies {
            sections,
            writer: SectionWriter::default(),
        }
    }

    /// Appends `bodies` with their accelerations and potentials `field`.
    pub fn push(
        &mut self,
        sink: &mut dyn SectionSink,
        bodies: &Bodies,
        field: (&[[f64; 3]], &[f64]),
    ) {
        let [mass, position, velocity, acceleration, potential, _] = self.sections;
        let w = &mut self.writer;
        w.f64s(sink, mass, bodies.mass.iter().copied());
        w.vectors(sink, position, &bodies.position);
        w.vectors(sink, velocity, &bodies.velocity);
        w.vectors(sink, acceleration, field.0);
        w.f64s(sink, potential, field.1.iter().copied());
    }

    /// Appends the energy `e0` of step 0, after the last bodies.
    pub fn finish(&mut self, sink: &mut dyn SectionSink, e0: f64) {
        self.writer.f64s(sink, self.sections[5], [e0]);
    }
}

/// The bodies `part` of the `n` a state written by [`save_bodies`] holds,
/// their accelerations and potentials, and the energy of step 0: every
/// section checked to hold `n` bodies' numbers, only `part`'s read (a
/// rank's share of a checkpoint file).
#[allow(clippy::type_complexity)]
pub fn load_bodies(
    state: &dyn SectionSource,
    n: usize,
    part: Range<usize>,
) -> Result<(Bodies, Vec<[f64; 3]>, Vec<f64>, f64), StateError> {
    for (name, per_body) in [
        ("mass", 1),
        ("position", 3),
        ("velocity", 3),
        ("acceleration", 3),
        ("potential", 1),
    ] {
        state.expect_count(name, per_body * n)?;
    }
    let (start, len) = (part.start, part.len());
    let bodies = Bodies {
        mass: state.f64s_at("mass", start, len)?,
        position: state.vectors_at("position", start, len)?,
        velocity: state.vectors_at("velocity", start, len)?,
    };
    Ok((
        bodies,
        state.vectors_at("acceleration", start, len)?,
        state.f64s_at("potential", start, len)?,
        state.f64("e0")?,
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Bodies saved a block at a time give the bytes of one call with all
    /// of them, and load back as they were.
    #[test]
    fn bodies_saved_in_blocks_are_the_whole_state() {
        let n = 23;
        let bodies = Bodies {
            mass: (0..n).map(|k| 1.0 + k as f64).collect(),
            position: (0..n).map(|k| [k as f64, -0.5, 0.25 * k as f64]).collect(),
            velocity: (0..n).map(|k| [0.1, k as f64 * 0.3, -1.0]).collect(),
        };
        let acc: Vec<[f64; 3]> = (0..n).map(|k| [1.0 / (k + 1) as f64, 2.0, 3.0]).collect();
        let phi: Vec<f64> = (0..n).map(|k| -(k as f64)).collect();
        let mut whole = State::default();
        save_bodies(&mut whole, &bodies, (&acc, &phi), -0.75);
        let mut layout = Layout::default();
        let mut saved = SavedBodies::new(n, &mut layout);
        let mut sections = StateBuilder::new(layout);
        for start in (0..n).step_by(5) {
            let range = start..n.min(start + 5);
            let field = (&acc[range.clone()], &phi[range.clone()]);
            saved.push(&mut sections, &bodies.part(range), field);
        }
        saved.finish(&mut sections, -0.75);
        let mut blocks = State::default();
        sections.finish(&mut blocks);
        assert_eq!(blocks, whole);
        let (loaded, loaded_acc, loaded_phi, e0) = load_bodies(&blocks, n, 0..n).unwrap();
        let part = load_bodies(&blocks, n, 6..17).unwrap();
        let field = (acc[6..17].to_vec(), phi[6..17].to_vec());
        assert_eq!(part, (bodies.part(6..17), field.0, field.1, -0.75));
        assert_eq!(
            (loaded, loaded_acc, loaded_phi, e0),
            (bodies, acc, phi, -0.75)
        );
    }
}
