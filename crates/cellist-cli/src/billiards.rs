//! `cellist billiards run | check | gen` and `cellist bench billiards`: the hard-disk
//! collision benchmark of seed 001.

use crate::bench::median;
use crate::cli::{
    BenchBilliardsArgs, BilliardsCheckArgs, BilliardsGenArgs, BilliardsRunArgs, StateFormatArg,
};
use crate::error::{threads, CliError, CliResult};
use crate::progress::progress_bar;
use cellist::models::billiards::{
    check_step, separated_discs, uniform_discs, Billiards, DiscState, StepChecker, Table,
};
use cellist::Threads;
use cellist_io::{
    read_billiards_input, write_png, write_state, AtomicFile, BilliardsInput, DiscPainter,
    GifAnimation, StateFormat, TrajectoryReader,
};
use std::io::{BufReader, IsTerminal, Write};
use std::path::Path;
use std::time::Instant;

/// Reads an input and sets up the table (warnings to standard error).
fn load(path: &Path, max_sweeps: u64) -> CliResult<(BilliardsInput, Billiards)> {
    let input = read_billiards_input(path)?;
    for w in &input.warnings {
        eprintln!("warning: {w}");
    }
    let table = Table {
        side: input.side,
        radius: input.radius,
    };
    let system = Billiards::new(table, input.x.clone(), input.y.clone(), input.v.clone())
        .map_err(|e| CliError::Input(format!("{}: {e}", path.display())))?
        .with_max_sweeps(max_sweeps);
    Ok((input, system))
}

/// Runs step `step`, keeping the hardest step so far as `(step, sweeps)`.
fn step_and_track(
    system: &mut Billiards,
    step: u64,
    pool: &Threads,
    hardest: &mut (u64, u64),
) -> CliResult {
    let stats = system
        .step(step, pool)
        .map_err(|e| CliError::Run(e.to_string()))?;
    if stats.sweeps > hardest.1 {
        *hardest = (step, stats.sweeps);
    }
    Ok(())
}

/// `cellist billiards run`.
pub fn run(args: &BilliardsRunArgs) -> CliResult {
    let pool = threads(args.threads)?;
    let (input, mut system) = load(&args.input, args.max_sweeps)?;
    let steps = args.steps.unwrap_or(input.steps);
    let format = match args.format {
        StateFormatArg::Out => StateFormat::Fixed8,
        StateFormatArg::Bits => StateFormat::Bits,
    };
    if args.frame_every == Some(0) {
        return Err(CliError::Input("--frame-every must be at least 1".into()));
    }
    if !(16..=4096).contains(&args.picture_size) {
        return Err(CliError::Input(format!(
            "--picture-size must be between 16 and 4096 pixels, got {}",
            args.picture_size
        )));
    }
    let mut viz = args
        .viz
        .as_deref()
        .map(|p| AtomicFile::create(p).map_err(CliError::output(p.display().to_string())))
        .transpose()?;
    let top_speed = system
        .v
        .iter()
        .map(|v| (v[0] * v[0] + v[1] * v[1]).sqrt())
        .fold(0.0, f64::max);
    let table = *system.table();
    let mut painter = DiscPainter::new(
        args.picture_size,
        table.side_f(),
        table.radius_f(),
        top_speed,
    );
    let frame_every = args.frame_every.unwrap_or(steps.div_ceil(200).max(1));
    let mut gif = match &args.gif {
        Some(p) => {
            let mut gif = GifAnimation::create(p, painter.size(), &DiscPainter::palette())
                .map_err(CliError::output(p.display().to_string()))?;
            gif.add_frame(painter.render(&system.x, &system.y, &system.v), 8)
                .map_err(CliError::output(p.display().to_string()))?;
            Some(gif)
        }
        None => None,
    };
    let bar = std::io::stderr().is_terminal().then(|| progress_bar(steps));
    let start = Instant::now();
    let mut hardest = (0, 0);
    for step in 1..=steps {
        step_and_track(&mut system, step, &pool, &mut hardest)?;
        if let (Some(file), Some(path)) = (viz.as_mut(), args.viz.as_deref()) {
            write_state(
                file.writer(),
                format,
                step,
                &input.ids,
                &system.x,
                &system.y,
                &system.v,
            )
            .map_err(CliError::output(path.display().to_string()))?;
        }
        if let (Some(gif), Some(path)) = (gif.as_mut(), args.gif.as_deref()) {
            if step % frame_every == 0 || step == steps {
                gif.add_frame(painter.render(&system.x, &system.y, &system.v), 8)
                    .map_err(CliError::output(path.display().to_string()))?;
            }
        }
        if let Some(bar) = &bar {
            bar.inc(1);
        }
    }
    let seconds = start.elapsed().as_secs_f64();
    if let Some(bar) = bar {
        bar.finish_and_clear();
    }
    if let (Some(file), Some(path)) = (viz, args.viz.as_deref()) {
        file.commit()
            .map_err(CliError::output(path.display().to_string()))?;
    }
    if let (Some(gif), Some(path)) = (gif, args.gif.as_deref()) {
        gif.finish()
            .map_err(CliError::output(path.display().to_string()))?;
    }
    if let Some(path) = &args.png {
        let size = painter.size();
        let pixels = painter.render(&system.x, &system.y, &system.v);
        write_png(path, size, pixels, &DiscPainter::palette())
            .map_err(CliError::output(path.display().to_string()))?;
    }
    write_final(args, format, steps, &input.ids, &system)?;
    eprintln!(
        "billiards: {} particles, {steps} steps in {seconds:.3} s ({:.1} steps/s) on {} thread(s); \
         hardest step {} needed {} sweeps",
        system.len(),
        steps as f64 / seconds.max(1e-12),
        pool.count(),
        hardest.0,
        hardest.1
    );
    Ok(())
}

fn write_final(
    args: &BilliardsRunArgs,
    format: StateFormat,
    steps: u64,
    ids: &[u32],
    system: &Billiards,
) -> CliResult {
    match &args.output {
        Some(path) => {
            let mut file =
                AtomicFile::create(path).map_err(CliError::output(path.display().to_string()))?;
            write_state(
                file.writer(),
                format,
                steps,
                ids,
                &system.x,
                &system.y,
                &system.v,
            )
            .and_then(|()| file.commit())
            .map_err(CliError::output(path.display().to_string()))
        }
        None => {
            let mut out = std::io::BufWriter::new(std::io::stdout().lock());
            write_state(
                &mut out, format, steps, ids, &system.x, &system.y, &system.v,
            )
            .and_then(|()| out.flush())
            .map_err(CliError::output("the final state"))
        }
    }
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
    let (input, start_state) = load(&args.input, cellist::models::billiards::DEFAULT_MAX_SWEEPS)?;
    let steps = args.steps.unwrap_or(input.steps);
    let mut samples = Vec::with_capacity(args.repeat);
    let mut hardest = (0, 0);
    for _ in 0..args.repeat {
        let mut system = start_state.clone();
        let start = Instant::now();
        for step in 1..=steps {
            step_and_track(&mut system, step, &pool, &mut hardest)?;
        }
        samples.push(start.elapsed().as_secs_f64());
    }
    let seconds = median(&mut samples);
    let per_second = steps as f64 / seconds.max(1e-12);
    let n = start_state.len();
    if args.json {
        let obj = serde_json::json!({
            "input": args.input.display().to_string(), "particles": n, "steps": steps,
            "threads": args.threads, "seconds": seconds, "steps_per_second": per_second,
            "max_sweeps": hardest.1, "hardest_step": hardest.0, "repeat": args.repeat,
        });
        println!("{obj}");
    } else {
        println!(
            "billiards: {} ({n} particles, {steps} steps), {} thread(s): {seconds:.4} s (median of {}), \
             {per_second:.1} steps/s; hardest step {} needed {} sweeps",
            args.input.display(),
            args.threads,
            args.repeat,
            hardest.0,
            hardest.1
        );
    }
    Ok(())
}
