//! The one interface every model offers the simulation driver: its state, one step,
//! the thermo columns and per-particle columns it can report, its field if it has
//! one, and save/restore of its complete state. The driver (crate `cellist-sim`)
//! runs the loop, the observers and the checkpoints once for all models; a model
//! only implements this trait.

use crate::state::{State, StateError};
use crate::threads::Threads;
use std::fmt;
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
pub struct Checked<'a> {
    /// The quantity ("position", "velocity", "force", "strength").
    pub quantity: &'static str,
    /// The values, particle by particle.
    pub values: &'a [f64],
    /// Numbers per particle (the dimension for vectors, 1 for scalars).
    pub per_particle: usize,
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
    /// The particles' strengths, where the model defines them apart from the
    /// values (pse: `omega_p = phi_p V_p`), in input order.
    pub strengths: Option<Vec<f64>>,
    /// Further per-particle columns for field files, after the values.
    pub extra: Vec<(&'static str, Vec<f64>)>,
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
/// complete state for checkpoints.
pub trait Model {
    /// The scenario's model name ("md").
    fn name(&self) -> &'static str;

    /// What one particle is called in messages ("atom", "body", "particle", "disc").
    fn particle_word(&self) -> &'static str;

    /// Number of particles.
    fn len(&self) -> usize;

    /// True without particles.
    fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Whether the particle count may change from step to step (a vortex run that
    /// remeshes); for other models a changed count is a blow-up.
    fn count_may_change(&self) -> bool {
        false
    }

    /// True for a model whose state is spread over MPI ranks and gathered for
    /// output: the driver then asks for `observe` on every step where an
    /// observer fires or a checkpoint is written, not only where thermo or
    /// energies are needed.
    fn observe_when_due(&self) -> bool {
        false
    }

    /// False on the ranks of a distributed run other than rank 0: they write no
    /// output (rank 0 writes the gathered state).
    fn writes_output(&self) -> bool {
        true
    }

    /// The outcome of a stage of the run made one for every rank of a
    /// distributed model: the failure of the lowest rank that failed, or `None`.
    /// In one process, `failure` itself.
    fn agree(&self, failure: Option<String>) -> Option<String> {
        failure
    }

    /// The time step; the time of step `s` is `s * dt`.
    fn dt(&self) -> f64;

    /// Advances from step `step - 1` to `step`. With `observe`, the step also
    /// computes what [`Model::thermo`] and energy columns need (energies, virial).
    fn step(&mut self, step: u64, observe: bool, threads: &Threads) -> Result<(), Blowup>;

    /// Names of the thermo columns after `step`.
    fn thermo_columns(&self) -> &'static [&'static str];

    /// The thermo values of the current state (after a step with `observe`, or
    /// step 0), one per column of [`Model::thermo_columns`].
    fn thermo(&self, step: u64) -> Vec<f64>;

    /// The arrays checked for finite values after every step.
    fn checked(&self) -> Vec<Checked<'_>>;

    /// The id of particle `index` of the checked arrays.
    fn id_of(&self, index: usize) -> u64;

    /// Bounds `(lo, hi)` per axis that positions (the `"position"` array) must stay
    /// within: the non-periodic walls of a box. Empty for none.
    fn walls(&self) -> Vec<(usize, f64, f64)> {
        Vec::new()
    }

    /// What to try when values stop being finite.
    fn remedy(&self) -> &'static str;

    /// The particles for a dump frame at `step`; `energies` asks for per-particle
    /// energies (needs a step with `observe`). `None` for models without dumps.
    fn particles(&self, step: u64, energies: bool) -> Option<Particles>;

    /// The field the particles carry, if the model has one.
    fn field(&self) -> Option<Field> {
        None
    }

    /// Wall time per stage of the steps so far, in the model's own breakdown.
    fn stage_times(&self) -> Vec<(&'static str, Duration)>;

    /// One line on the speed of the loop, e.g. microseconds per atom-step.
    fn speed(&self, loop_seconds: f64, steps: u64, threads: usize) -> String;

    /// The complete state: enough that [`Model::restore`] followed by the same steps
    /// gives the same bits as the run that saved it.
    fn save(&self, state: &mut State);

    /// Replaces the state by a saved one (of a model built from the same scenario).
    fn restore(&mut self, state: &State, threads: &Threads) -> Result<(), StateError>;

    /// Replaces the per-particle array `name` ("positions", "velocities") by
    /// `values`, `dimension` numbers per particle in the order of
    /// [`Model::particles`], and recomputes what depends on it. Models that
    /// allow none refuse, naming themselves.
    fn set_array(&mut self, name: &str, values: &[f64], threads: &Threads) -> Result<(), String> {
        let _ = (values, threads);
        Err(format!(
            "model {} does not allow setting its {name}",
            self.name()
        ))
    }
}

/// The first non-finite value of `model`'s checked arrays, or a position outside its
/// walls, or a particle count other than `count` (unless the model's count may
/// change), as the blow-up of `step`.
pub fn check(model: &dyn Model, step: u64, count: usize) -> Result<(), Blowup> {
    let blowup = |what: String, value: Option<(String, f64)>, remedy: &str| Blowup {
        step,
        what,
        particle: None,
        value,
        remedy: remedy.to_string(),
    };
    if !model.count_may_change() && model.len() != count {
        return Err(blowup(
            format!(
                "the number of {}s changed from {count} to {}",
                model.particle_word(),
                model.len()
            ),
            None,
            "particles were lost or created: this is a bug in the model",
        ));
    }
    const AXES: [&str; 3] = ["x", "y", "z"];
    let walls = model.walls();
    for checked in model.checked() {
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
                            particle: Some(model.id_of(k)),
                            ..blowup(
                                format!(
                                    "{} {} left the box through the non-periodic {} boundary",
                                    model.particle_word(),
                                    model.id_of(k),
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
            particle: Some(model.id_of(at / n)),
            ..blowup(
                format!(
                    "{} {} has a non-finite {} (the run blew up)",
                    model.particle_word(),
                    model.id_of(at / n),
                    checked.quantity
                ),
                Some((
                    format!("{}{component}", checked.quantity),
                    checked.values[at],
                )),
                model.remedy(),
            )
        });
    }
    Ok(())
}
