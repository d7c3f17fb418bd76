//! `cellist billiards run | check | gen` and `cellist bench billiards`: the hard-disk
//! collision benchmark of seed 001.

use crate::cli::{
    BenchBilliardsArgs, BilliardsCheckArgs, BilliardsGenArgs, BilliardsRunArgs, BilliardsSweepArgs,
    StateFormatArg,
};
use crate::error::{threads, CliError, CliResult};
use cellist::models::billiards::{
    check_step, separated_discs, uniform_discs, CellShape, DiscState, StepChecker, Table,
};
use cellist::Threads;
use cellist_io::{read_billiards_input, AtomicFile, StateFormat, TrajectoryReader};
use cellist_sim::billiards::{load, time_steps, BilliardsRun};
use cellist_sim::study::median;
use std::io::{BufReader, Write};

/// The `--cells` of `cellist billiards run` and `cellist bench billiards`: the
/// layout of the contact search's cells ([`CellShape`]).
#[derive(clap::ValueEnum, Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum CellsArg {
    /// Squares of side just above the contact distance 2R; 4 neighbour squares
    /// searched per square.
    #[default]
    Square,
    /// Seed 001's hexagon arrangement: rows just over 2R high, every other row
    /// shifted by half a cell, cells twice as wide as high (so that 6 neighbours
    /// hold every contact); 3 neighbour cells searched per cell.
    Hex,
}

impl CellsArg {
    /// The engine's layout.
    pub fn shape(self) -> CellShape {
        match self {
            CellsArg::Square => CellShape::Square,
            CellsArg::Hex => CellShape::Hex,
        }
    }

    /// The name on the command line.
    pub fn name(self) -> &'static str {
        self.shape().name()
    }
}

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
    let input = read_billiards_input(&args.input)?;
    for w in &input.warnings {
        eprintln!("warning: {w}");
    }
    let table = Table {
        side: input.side,
        radius: input.radius,
    };
    let n = input.ids.len();
    let mut prev: Vec<DiscState> = vec![[0.0; 4]; n];
    for (k, &id) in input.ids.iter().enumerate() {
        prev[id as usize] = [input.x[k], input.y[k], input.v[k][0], input.v[k][1]];
    }
    let file = std::fs::File::open(&args.trajectory)
        .map_err(|e| CliError::Input(format!("{}: cannot read: {e}", args.trajectory.display())))?;
    let mut reader = TrajectoryReader::new(&args.trajectory, BufReader::new(file), n);
    let mut checker = StepChecker::new(&table);
    let mut steps = 0i64;
    while let Some(block) = reader.next_step()? {
        if block.step != steps + 1 {
            return Err(CliError::Rejected(format!(
                "FAIL: expected the block of step {}, found step {} (the file must hold steps 1, 2, ... in order)",
                steps + 1,
                block.step
            )));
        }
        prev = check_step(
            &mut checker,
            &table,
            &prev,
            &block.ids,
            &block.states,
            &pool,
        )
        .map_err(|f| CliError::Rejected(format!("FAIL at step {}: {f}", block.step)))?;
        steps += 1;
    }
    if steps == 0 {
        return Err(CliError::Rejected(
            "FAIL: the trajectory holds no step".into(),
        ));
    }
    println!("OK: {steps} steps pass (input S = {})", input.steps);
    Ok(())
}

/// `cellist billiards gen`.
pub fn gen(args: &BilliardsGenArgs) -> CliResult {
    if args.l <= 0 || args.r <= 0 || args.l > i32::MAX as i64 || args.r > i32::MAX as i64 {
        return Err(CliError::Input(format!(
            "L ({}) and R ({}) must be positive integers that fit the format's int",
            args.l, args.r
        )));
    }
    if !(args.vmin.is_finite() && args.vmax.is_finite() && args.vmin <= args.vmax) {
        return Err(CliError::Input(format!(
            "VMIN ({}) and VMAX ({}) must be finite with VMIN <= VMAX",
            args.vmin, args.vmax
        )));
    }
    if args.n > i32::MAX as usize || args.steps > i32::MAX as u64 {
        return Err(CliError::Input(
            "N and STEPS must fit the format's int".into(),
        ));
    }
    let table = Table {
        side: args.l,
        radius: args.r,
    };
    let drawn = if args.overlaps {
        uniform_discs(args.n, &table, args.vmin, args.vmax, args.seed)
    } else {
        separated_discs(args.n, &table, args.vmin, args.vmax, args.seed).map_err(CliError::Input)?
    };
    let mut text = format!("{}\n{}\n{}\n{}\n", args.n, args.l, args.r, args.steps);
    for k in 0..args.n {
        // `{}` prints the shortest decimal that reads back to the same double
        text.push_str(&format!(
            "{k} {} {} {} {}\n",
            drawn.x[k], drawn.y[k], drawn.v[k][0], drawn.v[k][1]
        ));
    }
    match &args.output {
        Some(path) => {
            let mut file =
                AtomicFile::create(path).map_err(CliError::output(path.display().to_string()))?;
            file.writer()
                .write_all(text.as_bytes())
                .and_then(|()| file.commit())
                .map_err(CliError::output(path.display().to_string()))
        }
        None => std::io::stdout()
            .lock()
            .write_all(text.as_bytes())
            .map_err(CliError::output("the input")),
    }
}

/// `cellist bench billiards`: median wall time of whole runs.
pub fn bench(args: &BenchBilliardsArgs) -> CliResult {
    if args.repeat == 0 {
        return Err(CliError::Input("--repeat must be at least 1".into()));
    }
    let pool: Threads = threads(Some(args.threads))?;
    let (input, start_state) = load(
        &args.input,
        cellist::models::billiards::DEFAULT_MAX_SWEEPS,
        args.cells.shape(),
    )?;
    let steps = args.steps.unwrap_or(input.steps);
    let mut samples = Vec::with_capacity(args.repeat);
    let mut hardest = (0, 0);
    for _ in 0..args.repeat {
        let (seconds, worst) = time_steps(&start_state, steps, &pool)?;
        samples.push(seconds);
        hardest = worst;
    }
    let seconds = median(&samples);
    let per_second = steps as f64 / seconds.max(1e-12);
    let n = start_state.len();
    if args.json {
        let obj = serde_json::json!({
            "input": args.input.display().to_string(), "particles": n, "steps": steps,
            "threads": args.threads, "seconds": seconds, "steps_per_second": per_second,
            "max_sweeps": hardest.1, "hardest_step": hardest.0, "repeat": args.repeat,
            "cells": args.cells.name(),
        });
        println!("{obj}");
    } else {
        println!(
            "billiards: {} ({n} particles, {steps} steps), {} thread(s), {} cells: {seconds:.4} s \
             (median of {}), {per_second:.1} steps/s; hardest step {} needed {} sweeps",
            args.input.display(),
            args.threads,
            args.cells.name(),
            args.repeat,
            hardest.0,
            hardest.1
        );
    }
    Ok(())
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
