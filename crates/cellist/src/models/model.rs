//! The one interface every model offers the simulation driver: its state, one step,
//! the thermo columns and per-particle columns it can report, its field if it has
//! one, and save/restore of its complete state. The driver (crate `cellist-sim`)
//! runs the loop, the observers and the checkpoints once for all models; a model
//! only implements this trait.

use crate::state::{SectionSource, State, StateError};
use crate::threads::Threads;
use std::fmt;
use std::ops::ControlFlow;
use std::time::Duration;

/// Why a run stopped: a value that is not finite, a particle that left a
/// non-periodic box, a particle count that changed, or a step that could not
/// finish. Names the step, the particle, the quantity and its value.
#[derive(Clone, Debug, PartialEq)]
pub struct Blowup {
    /// The step that failed.
    pub step: u64,
    /// What happened, naming the particle ("atom 7 left the box through the
    /// non-periodic z boundary").
    pub what: String,
    /// The id of the particle to blame, if one is.
    pub particle: Option<u64>,
    /// The quantity and its value ("z = 12.5"), if one is to blame.
    pub value: Option<(String, f64)>,
    /// The likely cause and remedy ("try a smaller run.dt").
    pub remedy: String,
}

impl Blowup {
    /// The blow-up of `step` described by `what`, with no single value to blame.
    pub fn new(step: u64, what: impl Into<String>, remedy: &str) -> Self {
        Blowup {
            step,
            what: what.into(),
            particle: None,
            value: None,
            remedy: remedy.into(),
        }
    }
}

impl fmt::Display for Blowup {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "step {}: {}", self.step, self.what)?;
        if let Some((quantity, value)) = &self.value {
            write!(f, " ({quantity} = {value})")?;
        }
        write!(f, "; {}", self.remedy)
    }
}

impl std::error::Error for Blowup {}

/// A per-particle array the driver checks after every step: `values` holds
/// `per_particle` numbers per particle, all of which must be finite.
pub struct CheckedArray<'a> {
    /// The quantity ("position", "velocity", "force", "strength").
    pub quantity: &'static str,
    /// The values, particle by particle.
    pub values: &'a [f64],
    /// Numbers per particle (the dimension for vectors, 1 for scalars).
    pub per_particle: usize,
}

/// The ids that name the particles of the checked arrays in messages: particle
/// `k` of the arrays is `ids[k]`.
#[derive(Clone, Copy, Debug)]
pub enum Ids<'a> {
    /// Particle `k` is called `k` (its place in the input, 0-based).
    Index,
    /// Particle `k` is called `first + k`: a run of the input's places
    /// (gravity's bodies on one rank of several).
    From(u64),
    /// Ids as the model keeps them (md's atom ids).
    U64(&'a [u64]),
    /// Ids as the model keeps them (the collision benchmark's input ids, the
    /// input places of pse's particles in cell order).
    U32(&'a [u32]),
}

impl Ids<'_> {
    /// The id of particle `k`.
    pub fn of(&self, k: usize) -> u64 {
        match self {
            Ids::Index => k as u64,
            Ids::From(first) => first + k as u64,
            Ids::U64(ids) => ids[k],
            Ids::U32(ids) => ids[k] as u64,
        }
    }
}

/// What the driver checks after every step: the arrays that must stay finite,
/// the ids that name their particles, and the bounds `(axis, lo, hi)` that the
/// `"position"` array must stay within (the non-periodic walls of a box; empty
/// for none).
pub struct Checked<'a> {
    /// The arrays.
    pub arrays: Vec<CheckedArray<'a>>,
    /// The ids of their particles.
    pub ids: Ids<'a>,
    /// Walls `(axis, lo, hi)` of the positions.
    pub walls: Vec<(usize, f64, f64)>,
}

impl<'a> Checked<'a> {
    /// `arrays` of particles named by `ids`, within no walls.
    pub fn new(ids: Ids<'a>, arrays: Vec<CheckedArray<'a>>) -> Self {
        Checked {
            arrays,
            ids,
            walls: Vec::new(),
        }
    }
}

/// What a model is, for the driver's messages, tables and checkpoints: fixed
/// when the model is built.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ModelInfo {
    /// The scenario's model name ("md"); checkpoints record it.
    pub name: &'static str,
    /// What one particle is called in messages ("atom", "body", "particle").
    pub particle: &'static str,
    /// The thermo columns after `step`, in the order of [`Model::thermo`].
    pub thermo_columns: &'static [&'static str],
    /// What to try when values stop being finite.
    pub remedy: &'static str,
    /// Whether the particle count may change from step to step (a vortex run
    /// that remeshes); for other models a changed count is a blow-up.
    pub count_may_change: bool,
}

/// The particles as a dump frame shows them (3 components, sorted as the model
/// wants them written): the columns a model has are `Some` or non-empty.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Particles {
    /// The dimension (2 or 3): the first `dimension` components of the vectors
    /// count (the others are 0).
    pub dimension: usize,
    /// The box's lower corner (z bounds of 2D systems included).
    pub lo: [f64; 3],
    /// The box's upper corner.
    pub hi: [f64; 3],
    /// Periodic axes.
    pub periodic: [bool; 3],
    /// Ids.
    pub ids: Vec<u64>,
    /// Types (empty when the model has none).
    pub types: Vec<u32>,
    /// Positions.
    pub positions: Vec<[f64; 3]>,
    /// Velocities.
    pub velocities: Vec<[f64; 3]>,
    /// Forces (empty when the model has none).
    pub forces: Vec<[f64; 3]>,
    /// Per-particle potential energy.
    pub energies: Option<Vec<f64>>,
    /// Masses.
    pub masses: Option<Vec<f64>>,
    /// Accelerations.
    pub accelerations: Option<Vec<[f64; 3]>>,
    /// Potentials.
    pub potentials: Option<Vec<f64>>,
}

impl Particles {
    /// Appends the rows of `block` (a later block of the same frame, with the
    /// same columns) after these rows.
    pub fn append(&mut self, block: &Particles) {
        fn extend<T: Clone>(column: &mut Option<Vec<T>>, more: &Option<Vec<T>>) {
            if let (Some(column), Some(more)) = (column.as_mut(), more) {
                column.extend_from_slice(more);
            }
        }
        self.ids.extend_from_slice(&block.ids);
        self.types.extend_from_slice(&block.types);
        self.positions.extend_from_slice(&block.positions);
        self.velocities.extend_from_slice(&block.velocities);
        self.forces.extend_from_slice(&block.forces);
        extend(&mut self.energies, &block.energies);
        extend(&mut self.masses, &block.masses);
        extend(&mut self.accelerations, &block.accelerations);
        extend(&mut self.potentials, &block.potentials);
    }
}

/// A block of consecutive rows of a frame's particles
/// ([`Model::particle_blocks`]).
#[derive(Clone, Copy, Debug)]
pub struct ParticleBlock<'a> {
    /// Particles in the whole frame.
    pub total: usize,
    /// The place in the frame of the block's first row (0 for the first block).
    pub first: usize,
    /// The block's rows, with the frame's box.
    pub rows: &'a Particles,
}

/// The whole frame of a model that hands its particles out a block at a time
/// ([`Model::particle_blocks`]), its blocks appended in order; `None` where the
/// model gives none (or, spread over ranks, on a rank that writes no output).
pub fn whole_frame(model: &(impl Model + ?Sized), step: u64, energies: bool) -> Option<Particles> {
    let mut all: Option<Particles> = None;
    let whole = model.particle_blocks(step, energies, &mut |block| {
        match &mut all {
            None => all = Some(block.rows.clone()),
            Some(all) => all.append(block.rows),
        }
        ControlFlow::Continue(())
    });
    whole.then(|| all.unwrap_or_default())
}

/// A field carried by particles: one value per particle, for field files and
/// pictures.
#[derive(Clone, Debug, PartialEq)]
pub struct Field {
    /// The dimension (2 or 3): the first `dimension` components of `positions` count.
    pub dimension: usize,
    /// Positions, padded to 3 components, in input order.
    pub positions: Vec<[f64; 3]>,
    /// The values, in input order.
    pub values: Vec<f64>,
    /// The values' column name in field files ("phi").
    pub value_name: &'static str,
    /// Whether field CSV files carry the values (false: the values are for
    /// pictures and trajectories only, the CSV's columns are `extra`).
    pub value_written: bool,
    /// The particles' strengths, where the model defines them apart from the
    /// values (pse: `omega_p = phi_p V_p`), in input order.
    pub strengths: Option<Vec<f64>>,
    /// Further per-particle columns for field files, after the values.
    pub extra: Vec<(&'static str, Vec<f64>)>,
    /// The axes of the pictures of a 3D field: `[across, up, normal]`; they
    /// show the section through the middle of the box along `normal`
    /// (`[0, 1, 2]`: the layer nearest the middle in z).
    pub axes: [usize; 3],
    /// The lower corner of the (cubic) box the pictures show.
    pub origin: [f64; 3],
    /// Whether that box is periodic (pictures wrap across its edges).
    pub periodic: bool,
    /// Side of the (cubic) box the pictures show.
    pub side: f64,
    /// The particle spacing.
    pub spacing: f64,
    /// The value that the pictures' colour scale ends at (fixed for a run).
    pub scale: f64,
}

/// A simulation the driver can run: state, one step, what it reports, and its
/// complete state for checkpoints. Every method serves every model; what only
/// some models have (particles for dumps, a field for pictures) is asked for
/// and may be `None`.
// the driver counts particles but never asks whether there are none
#[allow(clippy::len_without_is_empty)]
pub trait Model {
    /// What the model is: its name, particle word, thermo columns and remedy.
    fn info(&self) -> &ModelInfo;

    /// Number of particles.
    fn len(&self) -> usize;

    /// The time step; the time of step `s` is `s * dt`.
    fn dt(&self) -> f64;

    /// Advances from step `step - 1` to `step`.
    fn step(&mut self, step: u64, threads: &Threads) -> Result<(), Blowup>;

    /// [`Model::step`] after which the driver reads [`Model::thermo`] or
    /// per-particle energies. A model whose observables cost work that a plain
    /// step leaves out (md: the energy and virial sums of the force pass; the
    /// vortex model: its invariants) does that work here; for the others it is
    /// the plain step.
    fn step_observed(&mut self, step: u64, threads: &Threads) -> Result<(), Blowup> {
        self.step(step, threads)
    }

    /// The thermo values of the current state (after [`Model::step_observed`],
    /// or at step 0), one per column of [`ModelInfo::thermo_columns`].
    fn thermo(&self, step: u64) -> Vec<f64>;

    /// The arrays checked for finite values after every step, with the ids and
    /// walls of their particles.
    fn checked(&self) -> Checked<'_>;

    /// The particles for a dump frame at `step`; `energies` asks for per-particle
    /// energies (after a [`Model::step_observed`] that was to make them: a
    /// model whose energies cost a pass of their own may make them only when
    /// told a dump wants them, and gives none otherwise). `None` for models
    /// without particle dumps.
    fn particles(&self, step: u64, energies: bool) -> Option<Particles> {
        let _ = (step, energies);
        None
    }

    /// The particles of [`Model::particles`] handed to `visit` a block of
    /// consecutive rows at a time, in order, so that a writer need not hold a
    /// copy of the whole frame; `visit` returns `Break` to stop. There is at
    /// least one block (an empty one for no particles). `false` for models
    /// without particle dumps. By default the whole frame is one block.
    fn particle_blocks(
        &self,
        step: u64,
        energies: bool,
        visit: &mut dyn FnMut(ParticleBlock<'_>) -> ControlFlow<()>,
    ) -> bool {
        let Some(rows) = self.particles(step, energies) else {
            return false;
        };
        let _ = visit(ParticleBlock {
            total: rows.ids.len(),
            first: 0,
            rows: &rows,
        });
        true
    }

    /// The field the particles carry, if the model has one.
    fn field(&self) -> Option<Field> {
        None
    }

    /// Wall time per stage of the steps so far, in the model's own breakdown.
    fn stage_times(&self) -> Vec<(&'static str, Duration)>;

    /// The complete state: enough that [`Model::restore`] followed by the same steps
    /// gives the same bits as the run that saved it.
    fn save(&self, state: &mut State);

    /// Replaces the state by a saved one (of a model built from the same scenario).
    fn restore(&mut self, state: &dyn SectionSource, threads: &Threads) -> Result<(), StateError>;
}

/// The first non-finite value of `model`'s checked arrays, or a position outside its
/// walls, or a particle count other than `count` (unless the model's count may
/// change), as the blow-up of `step`.
pub fn check(model: &(impl Model + ?Sized), step: u64, count: usize) -> Result<(), Blowup> {
    let info = model.info();
    let blowup = |what: String, value: Option<(String, f64)>, remedy: &str| Blowup {
        step,
        what,
        particle: None,
        value,
        remedy: remedy.to_string(),
    };
    if !info.count_may_change && model.len() != count {
        return Err(blowup(
            format!(
                "the number of {}s changed from {count} to {}",
                info.particle,
                model.len()
            ),
            None,
            "particles were lost or created: this is a bug in the model",
        ));
    }
    const AXES: [&str; 3] = ["x", "y", "z"];
    let Checked { arrays, ids, walls } = model.checked();
    for checked in arrays {
        // one fast pass over all values; the culprit is looked for only on failure
        if checked.values.iter().all(|v| v.is_finite()) {
            if checked.quantity == "position" && !walls.is_empty() {
                let n = checked.per_particle;
                for (k, x) in checked.values.chunks_exact(n).enumerate() {
                    if let Some(&(axis, _, _)) = walls
                        .iter()
                        .find(|&&(a, lo, hi)| !(lo..=hi).contains(&x[a]))
                    {
                        return Err(Blowup {
                            particle: Some(ids.of(k)),
                            ..blowup(
                                format!(
                                    "{} {} left the box through the non-periodic {} boundary",
                                    info.particle,
                                    ids.of(k),
                                    AXES[axis]
                                ),
                                Some((AXES[axis].to_string(), x[axis])),
                                "a wall only stops the box from wrapping; keep the particles \
                                 inside (a smaller run.dt, or a periodic boundary)",
                            )
                        });
                    }
                }
            }
            continue;
        }
        let n = checked.per_particle;
        let at = checked
            .values
            .iter()
            .position(|v| !v.is_finite())
            .expect("a non-finite value");
        let component = if n == 1 {
            String::new()
        } else if n <= 3 {
            format!(" {}", AXES[at % n])
        } else {
            format!(" {}", at % n)
        };
        return Err(Blowup {
            particle: Some(ids.of(at / n)),
            ..blowup(
                format!(
                    "{} {} has a non-finite {} (the run blew up)",
                    info.particle,
                    ids.of(at / n),
                    checked.quantity
                ),
                Some((
                    format!("{}{component}", checked.quantity),
                    checked.values[at],
                )),
                info.remedy,
            )
        });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::Ids;

    /// Each way of naming particles gives particle `k` its own id.
    #[test]
    fn ids_name_each_particle() {
        let (wide, narrow) = ([40u64, 7, 12], [3u32, 9]);
        let named = |ids: Ids, n: usize| (0..n).map(|k| ids.of(k)).collect::<Vec<_>>();
        assert_eq!(named(Ids::Index, 3), [0, 1, 2]);
        assert_eq!(named(Ids::From(250), 3), [250, 251, 252]);
        assert_eq!(named(Ids::U64(&wide), 3), [40, 7, 12]);
        assert_eq!(named(Ids::U32(&narrow), 2), [3, 9]);
    }
}
