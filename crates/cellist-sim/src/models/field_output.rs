//! The keys the models whose particles carry a field (`pse`, `vortex`) share:
//! the top level ([`FieldScenario`]: the model, the dimension and the model's own
//! `[system]`), `[run]` (steps, dt, a Runge-Kutta integrator) and `[output]` (thermo, field
//! CSV snapshots, PNG pictures, the GIF animation, the picture size and
//! checkpoints), with their defaults and checks.

use crate::observers::Every;
use crate::scenario::keys::{CheckpointKeys, DecompositionKeys};
use crate::scenario::keys::{SeriesKeys, TrajectoryKeys};
use cellist::models::pse::Integrator;
use serde::Deserialize;
use std::path::PathBuf;

/// A field model's scenario: `model`, `dimension` (default 2), the model's
/// `[system]` keys `S`, and the shared `[run]` and `[output]`.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FieldScenario<S> {
    /// The model's name.
    pub model: String,
    /// 2 or 3.
    #[serde(default = "two")]
    pub dimension: u64,
    /// The model's own keys.
    pub system: S,
    /// `[run]`.
    pub run: RunKeys,
    /// `[output]`.
    #[serde(default)]
    pub output: FieldOutputKeys,
    /// `[decomposition]` (pse on several MPI ranks; refused by models that do
    /// not run by domain decomposition).
    pub decomposition: Option<DecompositionKeys>,
}

fn two() -> u64 {
    2
}

/// `[run]` of a field model.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RunKeys {
    /// Steps to run.
    pub steps: u64,
    /// The time step.
    pub dt: f64,
    /// `euler`, `rk2` or `rk4` (default).
    #[serde(default = "rk4")]
    pub integrator: String,
    /// Run even above the integrator's stability limit.
    #[serde(default)]
    pub allow_unstable: bool,
}

fn rk4() -> String {
    "rk4".into()
}

impl RunKeys {
    /// Checks `dt > 0` and returns the integrator the keys name.
    pub fn integrator(&self) -> Result<Integrator, String> {
        if !(self.dt.is_finite() && self.dt > 0.0) {
            return Err(format!("run.dt must be > 0, got {}", self.dt));
        }
        Integrator::from_name(&self.integrator).ok_or_else(|| {
            let names: Vec<&str> = Integrator::ALL.iter().map(|(n, _)| *n).collect();
            format!(
                "run.integrator '{}' is unknown; expected one of {}",
                self.integrator,
                names.join(", ")
            )
        })
    }
}

/// `[output]` of a field model.
#[derive(Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct FieldOutputKeys {
    /// Steps between thermo rows (default 10).
    pub thermo_every: u64,
    /// Field CSV snapshots (default none).
    pub field: Option<SnapshotKeys>,
    /// PNG pictures (default the first and last step).
    pub png: Option<SnapshotKeys>,
    /// The GIF animation (default about 60 frames).
    pub gif: Option<SnapshotKeys>,
    /// The pictures' width in pixels, 16 to 4096 (default 512; the charts are at
    /// least 640 pixels wide).
    pub picture_size: u32,
    /// Checkpoints.
    pub checkpoint: Option<CheckpointKeys>,
    /// The GSD trajectory.
    pub gsd: Option<SeriesKeys>,
    /// The VTK series.
    pub vtk: Option<SeriesKeys>,
}

impl Default for FieldOutputKeys {
    fn default() -> Self {
        FieldOutputKeys {
            thermo_every: 10,
            field: None,
            png: None,
            gif: None,
            picture_size: 512,
            checkpoint: None,
            gsd: None,
            vtk: None,
        }
    }
}

/// `{ every = K, file = "name" }`: every K steps (0: off) to `file`.
#[derive(Deserialize, Clone)]
#[serde(deny_unknown_fields)]
pub struct SnapshotKeys {
    every: u64,
    file: Option<PathBuf>,
}

impl SnapshotKeys {
    /// The snapshots these keys ask for, to `file` or else `name`; `None` for
    /// `every = 0`.
    pub fn every(&self, name: &str) -> Option<Every> {
        (self.every > 0).then(|| Every {
            every: self.every,
            file: self.file.clone().unwrap_or_else(|| name.into()),
        })
    }
}

/// Checks `output.picture_size`: 16 to 4096 pixels.
pub fn check_picture_size(size: u32) -> Result<(), String> {
    if (16..=4096).contains(&size) {
        Ok(())
    } else {
        Err(format!(
            "output.picture_size must be between 16 and 4096 pixels, got {size}"
        ))
    }
}

/// The snapshots of a run: field CSV files, PNG pictures and the GIF animation.
pub struct Snapshots {
    /// Field CSV files.
    pub csv: Option<Every>,
    /// PNG pictures.
    pub png: Option<Every>,
    /// The animation.
    pub gif: Option<Every>,
}

impl FieldOutputKeys {
    /// Checks the checkpoint and trajectory keys and the picture size.
    pub fn check(&self) -> Result<(), String> {
        if let Some(c) = &self.checkpoint {
            c.check("output.checkpoint")?;
        }
        self.trajectories()?;
        check_picture_size(self.picture_size)
    }

    /// The GSD and VTK trajectories asked for, checked.
    pub fn trajectories(&self) -> Result<TrajectoryKeys, String> {
        TrajectoryKeys::checked(self.gsd.clone(), self.vtk.clone())
    }

    /// The snapshots of a run of `steps` steps, files named `csv`, `png` and `gif`
    /// unless the keys name them: no field files unless asked for, pictures of
    /// the first and last steps, an animation of about 60 frames.
    pub fn snapshots(&self, steps: u64, [csv, png, gif]: [&str; 3]) -> Snapshots {
        // every = 0 turns a snapshot off; a missing key takes the default
        let snapshot = |keys: &Option<SnapshotKeys>, name: &str, default: Option<u64>| match keys {
            Some(s) => s.every(name),
            None => default.map(|every| Every {
                every,
                file: name.into(),
            }),
        };
        Snapshots {
            csv: snapshot(&self.field, csv, None),
            png: snapshot(&self.png, png, Some(steps.max(1))),
            gif: snapshot(&self.gif, gif, Some(steps.div_ceil(60).max(1))),
        }
    }
}
