//! `cellist run [SCENARIO]`: load the scenario (or the built-in LJ melt), apply
//! `--set`, and hand it to its model.

use crate::cli::RunArgs;
use crate::error::{threads, CliResult};
use crate::gravity;
use crate::md;
use crate::pse;
use crate::scenario::Scenario;
use std::path::Path;

/// The models this build runs, for messages.
const MODELS: &str =
    "md (Lennard-Jones molecular dynamics), pse (diffusion by particle strength exchange), \
     gravity (self-gravitating bodies)";

/// Runs `cellist run`.
pub fn run(args: &RunArgs) -> CliResult {
    let scenario = Scenario::load(args.scenario.as_deref(), &args.set)?;
    let model = scenario.model()?;
    let pool = threads(args.threads)?;
    let out_dir = args
        .out
        .clone()
        .unwrap_or_else(|| Path::new("out").join(&scenario.name));
    match model.as_str() {
        "md" => md::run(&scenario, &out_dir, &pool),
        "pse" => pse::run(&scenario, &out_dir, &pool),
        "gravity" => gravity::run(&scenario, &out_dir, &pool),
        other => Err(scenario.error(format!(
            "model '{other}' is unknown; this build runs: {MODELS}"
        ))),
    }
}
