//! Each model's scenario section: its keys, checked, become an engine model, the
//! outputs it writes and the physics a checkpoint records. The models a
//! scenario can name are the registry's ([`ModelKind`]); [`launch_scenario`]
//! hands a scenario to its model's file.

pub mod billiards;
pub mod field_output;
mod fmm_keys;
pub mod gravity;
pub mod md;
pub mod pse;
pub mod vortex;
pub mod vortex3;
mod vortex_keys;

pub(crate) use fmm_keys::fmm_name;

use crate::error::SimResult;
use crate::launch::{Execute, Launch, RunContext, RunSummary};
use crate::scenario::{ModelKind, Scenario};
use cellist::Threads;
use std::path::{Path, PathBuf};

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

/// Runs a scenario: loads it, builds its model and runs it to the end (its
/// summary without the final particles or field).
pub fn run(request: &RunRequest, threads: &Threads) -> SimResult<RunSummary> {
    let scenario = Scenario::load(request.scenario, request.sets)?;
    let out_dir = request
        .out
        .clone()
        .unwrap_or_else(|| Path::new("out").join(&scenario.name));
    let context = RunContext::new(out_dir, request.restart, threads)
        .read_from(scenario.path.as_deref())
        .without_final_state();
    run_scenario(&scenario, &context)
}

/// Runs a loaded scenario in `context`.
pub fn run_scenario(scenario: &Scenario, context: &RunContext) -> SimResult<RunSummary> {
    launch_scenario(scenario, context, Execute)
}

/// Builds the model `scenario` names (its file's `run`) and hands its run to
/// `launch`. On the ranks other than 0 of a distributed run, nothing is
/// printed.
pub fn launch_scenario<L: Launch>(
    scenario: &Scenario,
    context: &RunContext,
    launch: L,
) -> SimResult<L::Output> {
    // the ranks other than 0 of a distributed run print nothing
    #[cfg(feature = "mpi")]
    let silent = crate::distributed::rank_of_many()
        .is_some_and(|rank| rank != 0)
        .then(|| context.silenced());
    #[cfg(feature = "mpi")]
    let context = silent.as_ref().unwrap_or(context);
    match scenario.model()? {
        ModelKind::Md => md::run(scenario, context, launch),
        ModelKind::Pse => pse::run(scenario, context, launch),
        ModelKind::Gravity => gravity::run(scenario, context, launch),
        ModelKind::Vortex => vortex::run(scenario, context, launch),
        ModelKind::Billiards => billiards::run(scenario, context, launch),
    }
}
