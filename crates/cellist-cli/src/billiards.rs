//! `cellist billiards run | check | gen | sweep`: the hard-disk collision
//! benchmark of seed 001, its flags handed to the simulation layer.

use crate::cli::{
    BilliardsCheckArgs, BilliardsGenArgs, BilliardsRunArgs, BilliardsSweepArgs, StateFormatArg,
};
use crate::error::{threads, CliError, CliResult};
use cellist_sim::billiards::BilliardsRun;
use cellist_sim::billiards::{check as check_trajectory, generate, Generate, Verdict};
use cellist_sim::{CellShape, StateFormat};

/// `cellist billiards run`.
pub fn run(args: &BilliardsRunArgs) -> CliResult {
    let pool = threads(args.threads)?;
    let format = match args.format {
        StateFormatArg::Out => StateFormat::Fixed8,
        StateFormatArg::Bits => StateFormat::Bits,
    };
    let run = BilliardsRun {
        input: &args.input,
        steps: args.steps,
        max_sweeps: args.max_sweeps,
        cells: args.cells.shape(),
        format,
        viz: args.viz.as_deref(),
        gif: args.gif.as_deref(),
        png: args.png.as_deref(),
        output: args.output.as_deref(),
        frame_every: args.frame_every,
        picture_size: args.picture_size,
        checkpoint: args.checkpoint.clone().zip(args.checkpoint_every),
        restart: args.restart.as_deref(),
    };
    Ok(cellist_sim::billiards::run(&run, &pool)?)
}

/// `cellist billiards check`: one verdict line on standard output.
pub fn check(args: &BilliardsCheckArgs) -> CliResult {
    let pool = threads(args.threads)?;
    match check_trajectory(&args.input, &args.trajectory, &pool)? {
        Verdict::Pass { steps, input_steps } => {
            println!("OK: {steps} steps pass (input S = {input_steps})");
            Ok(())
        }
        Verdict::Fail(verdict) => Err(CliError::Rejected(verdict)),
    }
}

/// `cellist billiards gen`.
pub fn gen(args: &BilliardsGenArgs) -> CliResult {
    Ok(generate(&Generate {
        n: args.n,
        l: args.l,
        r: args.r,
        steps: args.steps,
        vmin: args.vmin,
        vmax: args.vmax,
        seed: args.seed,
        overlaps: args.overlaps,
        output: args.output.as_deref(),
    })?)
}

/// `cellist billiards sweep`: hands the flags to the simulation layer's study.
pub fn sweep(args: &BilliardsSweepArgs) -> CliResult {
    use cellist_sim::study::billiards_sweep::{sweep, BilliardsSweepRequest};
    let cells: Vec<CellShape> = args.cells.iter().map(|c| c.shape()).collect();
    sweep(&BilliardsSweepRequest {
        n: &args.n,
        l: &args.l,
        r: &args.r,
        steps: &args.steps,
        cells: &cells,
        threads: args.threads.clone(),
        vmin: args.vmin,
        vmax: args.vmax,
        seed: args.seed,
        overlaps: args.overlaps,
        repeat: args.repeat,
        out: args.out.clone(),
    })?;
    Ok(())
}
