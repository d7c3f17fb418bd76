//! `cellist sweep`, `cellist convergence` and `cellist scaling`: hand the flags to
//! the studies of the simulation layer.

use crate::cli::{ConvergenceArgs, ScalingArgs, SweepArgs};
use crate::error::CliResult;
use cellist_sim::study::{convergence, scaling, sweep};

/// Runs `cellist sweep`.
pub fn sweep(args: &SweepArgs) -> CliResult {
    sweep::sweep(&sweep::SweepRequest {
        scenario: &args.scenario,
        sets: &args.set,
        threads: args.threads.clone(),
        metrics: &args.metric,
        repeat: args.repeat,
        out: args.out.clone(),
    })?;
    Ok(())
}

/// Runs `cellist convergence`.
pub fn convergence(args: &ConvergenceArgs) -> CliResult {
    convergence::convergence(&convergence::ConvergenceRequest {
        scenario: &args.scenario,
        sets: &args.set,
        dt: args.dt,
        halvings: args.halvings,
        end_time: args.end_time,
        observable: &args.observable,
        exact: args.exact,
        out: args.out.clone(),
    })?;
    Ok(())
}

/// Runs `cellist scaling`.
pub fn scaling(args: &ScalingArgs) -> CliResult {
    scaling::scaling(&scaling::ScalingRequest {
        scenario: &args.scenario,
        sets: &args.set,
        threads: args.threads.clone(),
        repeat: args.repeat,
        out: args.out.clone(),
    })?;
    Ok(())
}
