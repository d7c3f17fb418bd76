//! `cellist run [SCENARIO]`: hands the scenario (or the built-in LJ melt), its
//! `--set` overrides and `--restart` to the simulation layer.

use crate::cli::RunArgs;
use crate::error::{threads, CliResult};
use cellist_sim::RunRequest;

/// Runs `cellist run`.
pub fn run(args: &RunArgs) -> CliResult {
    let pool = threads(args.threads)?;
    let request = RunRequest {
        scenario: args.scenario.as_deref(),
        sets: &args.set,
        out: args.out.clone(),
        restart: args.restart.as_deref(),
    };
    cellist_sim::run(&request, &pool)?;
    Ok(())
}
