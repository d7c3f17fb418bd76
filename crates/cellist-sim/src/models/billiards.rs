//! `model = "billiards"`: the hard-disk collision benchmark's input run as a
//! scenario, so that `cellist run` and the Python module's `Simulation` run it
//! like every other model (thermo, dumps, trajectories, checkpoints):
//!
//! ```text
//! model = "billiards"
//! input = "inputs/standard/10k_density_0.9.in"   # relative to the scenario file
//! [run]
//! steps = 100            # default: the input's S
//! max_sweeps = 1000000   # the bound on resolution sweeps per step
//! cells = "square"       # or "hex"; the bits are the same
//! [output]
//! thermo_every = 10
//! dump = { every = 10, file = "discs.lammpstrj" }
//! gsd = { every = 10, file = "discs.gsd" }
//! checkpoint = { every = 50 }
//! ```

use crate::billiards::{billiards_job, disc_columns, read, ENERGY_TABLE};
use crate::error::SimResult;
use crate::hosted::Hosted;
use crate::launch::{Launch, RunContext};
use crate::observers::{DumpFormat, DumpPlan, OutputPlan};
use crate::scenario::keys::{choice, CheckpointKeys, SeriesKeys, TrajectoryKeys};
use crate::scenario::Scenario;
use cellist::models::billiards::BilliardsModel;
use cellist::models::billiards::{CellShape, DEFAULT_MAX_SWEEPS};
use cellist::models::Model;
use serde::Deserialize;
use std::path::PathBuf;
use std::time::Instant;

/// The keys of a billiards scenario.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct BilliardsScenario {
    model: String,
    input: PathBuf,
    #[serde(default)]
    run: RunKeys,
    #[serde(default)]
    output: OutputKeys,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields, default)]
struct RunKeys {
    steps: Option<u64>,
    max_sweeps: u64,
    cells: String,
}

impl Default for RunKeys {
    fn default() -> Self {
        RunKeys {
            steps: None,
            max_sweeps: DEFAULT_MAX_SWEEPS,
            cells: "square".into(),
        }
    }
}

#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields, default)]
struct OutputKeys {
    thermo_every: u64,
    dump: Option<SeriesKeys>,
    checkpoint: Option<CheckpointKeys>,
    gsd: Option<SeriesKeys>,
    vtk: Option<SeriesKeys>,
}

/// Runs a billiards scenario, from the checkpoint `restart` if given.
pub fn run<L: Launch>(
    scenario: &Scenario,
    context: &RunContext,
    launch: L,
) -> SimResult<L::Output> {
    let started = Instant::now();
    let keys: BilliardsScenario = scenario.parse()?;
    debug_assert_eq!(keys.model, "billiards");
    let err = |m: String| scenario.error(m);
    let cells = choice(
        "run.cells",
        &keys.run.cells,
        &[("square", CellShape::Square), ("hex", CellShape::Hex)],
    )
    .map_err(err)?;
    if keys.run.max_sweeps == 0 {
        return Err(err("run.max_sweeps must be >= 1".into()));
    }
    let out = &keys.output;
    if let Some(c) = &out.checkpoint {
        c.check("output.checkpoint").map_err(err)?;
    }
    if let Some(d) = &out.dump {
        d.check("output.dump").map_err(err)?;
    }
    let trajectories = TrajectoryKeys::checked(out.gsd.clone(), out.vtk.clone()).map_err(err)?;
    let path = scenario.input_path(&keys.input);
    let (input, system) = read(&path, keys.run.max_sweeps, cells)?;
    for w in &input.warnings {
        context.warn(w);
    }
    let mut job = billiards_job(
        &input,
        system,
        context.out_dir.clone(),
        out.checkpoint.clone(),
    );
    if let Some(steps) = keys.run.steps {
        job.steps = steps;
    }
    context.say(format!(
        "billiards: {} discs from {}, {} steps, {} thread(s); results in {}",
        input.ids.len(),
        path.display(),
        job.steps,
        context.threads.count(),
        context.out_dir.display()
    ));
    let plan = OutputPlan {
        thermo_every: out.thermo_every,
        table: ENERGY_TABLE,
        plot: None,
        dumps: out
            .dump
            .iter()
            .map(|d| DumpPlan {
                every: d.every,
                file: d.file.clone(),
                columns: disc_columns(),
                format: DumpFormat::Lammps,
            })
            .collect(),
        field: None,
        bodies: None,
        trajectories,
    };
    launch.launch(job, &plan, context, started)
}

impl Hosted for BilliardsModel {
    /// Steps per second and the hardest step's sweeps.
    fn speed(&self, loop_seconds: f64, steps: u64, threads: usize) -> String {
        format!(
            "billiards: {} particles, {steps} steps in {loop_seconds:.3} s ({:.1} steps/s) on {threads} \
             thread(s); hardest step {} needed {} sweeps",
            self.len(),
            steps as f64 / loop_seconds.max(1e-12),
            self.hardest.0,
            self.hardest.1
        )
    }
}
