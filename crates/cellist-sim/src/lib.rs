//! The simulation layer of cellist, between the scenario and the engine: a
//! scenario's keys become a model, and one driver loop runs every model with its
//! observers (thermo, dumps, fields, pictures), checkpoints and restarts, and
//! blow-up stops. The command line calls it; so will MPI runs and the Python
//! module.
#![warn(missing_docs)]

pub mod billiards;
pub mod driver;
pub mod error;
pub mod models;
pub mod observers;
pub mod progress;
pub mod scenario;

pub use error::{SimError, SimResult};
pub use scenario::Scenario;

use cellist::models::Model;
use cellist::Threads;
use driver::{recorded, Job};
use observers::OutputPlan;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// The models `cellist run` runs, for messages.
const MODELS: &str =
    "md (Lennard-Jones molecular dynamics), pse (diffusion by particle strength exchange), \
     gravity (self-gravitating bodies), vortex (2D viscous vortex particles)";

/// What `cellist run` asks for.
pub struct RunRequest<'a> {
    /// The scenario file; `None` runs the built-in LJ melt.
    pub scenario: Option<&'a Path>,
    /// `--set key=value` overrides.
    pub sets: &'a [String],
    /// The output folder (default `out/<scenario name>/`).
    pub out: Option<PathBuf>,
    /// A checkpoint to continue from.
    pub restart: Option<&'a Path>,
}

/// Runs a scenario: loads it, builds its model and runs it to the end.
pub fn run(request: &RunRequest, threads: &Threads) -> SimResult {
    let scenario = Scenario::load(request.scenario, request.sets)?;
    let model = scenario.model()?;
    let out_dir = request
        .out
        .clone()
        .unwrap_or_else(|| Path::new("out").join(&scenario.name));
    let restart = request.restart;
    match model.as_str() {
        "md" => models::md::run(&scenario, &out_dir, restart, threads),
        "pse" => models::pse::run(&scenario, &out_dir, restart, threads),
        "gravity" => models::gravity::run(&scenario, &out_dir, restart, threads),
        "vortex" => models::vortex::run(&scenario, &out_dir, restart, threads),
        other => Err(scenario.error(format!(
            "model '{other}' is unknown; this build runs: {MODELS}"
        ))),
    }
}

/// Runs `job` with the observers of `plan`, from the checkpoint `restart` if
/// given (checked before anything is written), and prints the closing line.
pub(crate) fn execute<M: Model + 'static>(
    mut job: Job<M>,
    plan: &OutputPlan,
    restart: Option<&Path>,
    threads: &Threads,
    started: Instant,
) -> SimResult {
    let checkpoint = restart
        .map(|path| {
            driver::restore(
                &mut job.model,
                path,
                &job.physics,
                job.steps,
                &job.dir,
                threads,
            )
        })
        .transpose()?;
    let dir = job.dir.clone();
    std::fs::create_dir_all(&dir).map_err(SimError::output(format!("folder {}", dir.display())))?;
    let first = checkpoint.as_ref().map_or(0, |c| c.step);
    if let Some(path) = restart {
        println!("restart: from step {first} of {}", path.display());
    }
    let observers = plan.observers(&job.model, &dir, recorded(checkpoint.as_ref()))?;
    job.run(checkpoint.as_ref(), observers, threads)?;
    println!(
        "total wall time {:.2} s; results in {}",
        started.elapsed().as_secs_f64(),
        dir.display()
    );
    Ok(())
}
