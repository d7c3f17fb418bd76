//! The launch path of every run: a model's job, built from a scenario (or an
//! input), is run to the end with its outputs (`cellist run`, the studies,
//! `cellist billiards run`) or kept under way as a session (Python).
//! What is printed goes through the [`RunContext`]: standard output, standard
//! error, or nothing (collected warnings).

use crate::driver::{self, recorded, Job, Live};
use crate::error::{SimError, SimResult};
use crate::hosted::Hosted;
use crate::observers::{OutputPlan, Outputs};
use crate::progress;
use crate::ranks::Ranks;
use crate::summary::{Outcome, Pending};
use cellist::models::{Field, Model, Particles};
use cellist::Threads;
use indicatif::ProgressBar;
use std::cell::RefCell;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// Where a run writes, from what it starts, on how many threads, and how much
/// it prints.
pub struct RunContext<'a> {
    /// The output folder.
    pub out_dir: PathBuf,
    /// A checkpoint to continue from.
    pub restart: Option<&'a Path>,
    /// The worker threads.
    pub threads: &'a Threads,
    /// Print nothing (no header, table, progress bar or timings; warnings are
    /// collected in the summary instead): the studies run scenarios this way.
    pub quiet: bool,
    /// Build the model and stop before the loop (nothing written): the studies'
    /// check of a scenario before they run it.
    pub build_only: bool,
    /// Print on standard error rather than standard output (`cellist billiards
    /// run`, whose standard output is the final state).
    pub on_stderr: bool,
    /// The file the run was read from (a scenario, or a collision-benchmark
    /// input), named in its `summary.json`.
    pub scenario: Option<PathBuf>,
    /// Keep the final particles or field in the [`RunSummary`] (the studies
    /// compare them); `cellist run` does not, sparing a copy of every particle.
    pub final_state: bool,
    pub(crate) warnings: RefCell<Vec<String>>,
}

impl<'a> RunContext<'a> {
    /// A run into `out_dir` on `threads`, from `restart` if given.
    pub fn new(out_dir: PathBuf, restart: Option<&'a Path>, threads: &'a Threads) -> Self {
        RunContext {
            out_dir,
            restart,
            threads,
            quiet: false,
            build_only: false,
            on_stderr: false,
            scenario: None,
            final_state: true,
            warnings: RefCell::new(Vec::new()),
        }
    }

    /// The same run, read from the file `scenario` (if any).
    pub fn read_from(mut self, scenario: Option<&Path>) -> Self {
        self.scenario = scenario.map(Path::to_path_buf);
        self
    }

    /// The same run with no final particles or field in its summary.
    pub fn without_final_state(mut self) -> Self {
        self.final_state = false;
        self
    }

    /// The same run stopping once the model is built, quiet: its summary has
    /// the step-0 thermo row, particles and field, and no time.
    pub fn build_only(mut self) -> Self {
        self.quiet = true;
        self.build_only = true;
        self
    }

    /// This run, printing nothing (its warnings kept apart): what the ranks
    /// other than 0 of a distributed run do.
    pub fn silenced(&self) -> RunContext<'a> {
        RunContext {
            out_dir: self.out_dir.clone(),
            quiet: true,
            build_only: self.build_only,
            on_stderr: self.on_stderr,
            scenario: self.scenario.clone(),
            final_state: self.final_state,
            ..RunContext::new(PathBuf::new(), self.restart, self.threads)
        }
    }

    /// The same run without printing.
    pub fn quiet(mut self) -> Self {
        self.quiet = true;
        self
    }

    /// The same run printing on standard error.
    pub fn on_stderr(mut self) -> Self {
        self.on_stderr = true;
        self
    }

    /// Prints a line of the run's header on standard output, or standard error
    /// (not when quiet).
    pub fn say(&self, line: impl std::fmt::Display) {
        match (self.quiet, self.on_stderr) {
            (true, _) => {}
            (false, false) => println!("{line}"),
            (false, true) => eprintln!("{line}"),
        }
    }

    /// Says the loop's speed (the model's line, completed by its `ranks`) and
    /// its time per stage.
    fn timings<M: Hosted>(
        &self,
        model: &M,
        ranks: &Ranks,
        steps: u64,
        loop_time: Duration,
        stages: &[(&'static str, Duration)],
    ) {
        let total = loop_time.as_secs_f64();
        let line = ranks.speed(model.speed(total, steps, self.threads.count()), total);
        self.say(format!("\n{line}"));
        self.say(format!(
            "{:<10} | {:>10} | {:>6}",
            "Section", "time (s)", "%total"
        ));
        for (name, d) in stages {
            let s = d.as_secs_f64();
            let pct = if total > 0.0 { 100.0 * s / total } else { 0.0 };
            self.say(format!("{name:<10} | {s:>10.4} | {pct:>6.2}"));
        }
    }

    /// Prints `warning: ...` on standard error, or keeps it for the summary when
    /// quiet.
    pub fn warn(&self, message: impl std::fmt::Display) {
        if self.quiet {
            self.warnings.borrow_mut().push(message.to_string());
        } else {
            eprintln!("warning: {message}");
        }
    }
}

/// What a finished run leaves for the studies: its times, its thermo rows and its
/// final particles or field.
pub struct RunSummary {
    /// The model's name.
    pub model: &'static str,
    /// The time step.
    pub dt: f64,
    /// Steps the loop ran.
    pub steps: u64,
    /// Worker threads.
    pub threads: usize,
    /// Wall time of the loop.
    pub loop_time: Duration,
    /// Wall time per stage of the loop: the model's stages, `Output` and `Other`
    /// (the rest), summing to the loop time.
    pub stages: Vec<(&'static str, Duration)>,
    /// The thermo columns after `step`.
    pub thermo_columns: Vec<&'static str>,
    /// The thermo rows `(step, values)` of the run, in step order.
    pub thermo: Vec<(u64, Vec<f64>)>,
    /// The particles at the last step (models with particles).
    pub particles: Option<Particles>,
    /// The field at the last step (field models).
    pub field: Option<Field>,
    /// Warnings of a quiet run.
    pub warnings: Vec<String>,
}

/// What becomes of a model once its scenario has built it: run to the end
/// (`cellist run`, [`Execute`]) or kept under way to be stepped on request (a
/// Python session, [`crate::session::Open`]).
pub trait Launch {
    /// What the launch gives back.
    type Output;

    /// Takes the built `job` with the outputs of `plan`, in `context`; the
    /// set-up began at `started`.
    fn launch<M: Hosted + 'static>(
        self,
        job: Job<M>,
        plan: &OutputPlan,
        context: &RunContext,
        started: Instant,
    ) -> SimResult<Self::Output>;
}

/// The launch of `cellist run`: the run to its last step, with the timings
/// printed, summarised.
pub struct Execute;

impl Launch for Execute {
    type Output = RunSummary;

    fn launch<M: Hosted + 'static>(
        self,
        job: Job<M>,
        plan: &OutputPlan,
        context: &RunContext,
        started: Instant,
    ) -> SimResult<RunSummary> {
        execute(job, plan, context, started).map(|(summary, _)| summary)
    }
}

/// Runs `job` with the observers `outputs` makes, in `context` (from its
/// checkpoint if given, checked before anything is written), says the timings
/// and the closing line, writes `summary.json` into the output folder (also
/// after a blow-up), and returns the run's summary and its model at the last
/// step.
pub(crate) fn execute<M: Hosted + 'static, P: Outputs<M> + ?Sized>(
    job: Job<M>,
    outputs: &P,
    context: &RunContext,
    started: Instant,
) -> SimResult<(RunSummary, M)> {
    let threads = context.threads;
    if context.build_only {
        let summary = RunSummary {
            stages: driver::stages(&job.model, Duration::ZERO, Duration::ZERO),
            thermo: vec![(0, job.model.thermo(0))],
            ..RunSummary::of(&job.model, 0, context, threads)
        };
        return Ok((summary, job.model));
    }
    let (dir, last) = (job.dir.clone(), job.steps);
    let bar = if context.quiet {
        ProgressBar::hidden()
    } else {
        progress::progress_bar(0)
    };
    let mut live = begin(job, outputs, context, last, bar.clone())?;
    bar.set_length(last - live.step());
    let scenario = context.scenario.as_deref();
    let pending = Pending::new(&live, &dir, scenario, threads.count(), started);
    if let Err(e) = live.advance(last, last, threads) {
        if let (Some(pending), Some(blowup)) = (&pending, live.last_blowup()) {
            let (model, ranks) = (live.model(), live.ranks());
            let written = pending.write(model, ranks, live.timing(), blowup.step, Outcome::BlowUp);
            if let Err(w) = written {
                context.warn(w);
            }
        }
        return Err(e);
    }
    bar.finish_and_clear();
    let report = live.finish()?;
    let (model, timing) = (&report.model, report.timing);
    let steps = last - timing.first;
    let stages = driver::stages(model, timing.loop_time, timing.output_time);
    if steps > 0 {
        context.timings(model, &report.ranks, steps, timing.loop_time, &stages);
    }
    if let Some(pending) = &pending {
        let written = pending.write(model, &report.ranks, timing, last, Outcome::Completed);
        driver::agreed(&report.ranks, written)?;
    }
    let wall = started.elapsed().as_secs_f64();
    if dir.as_os_str().is_empty() {
        context.say(format!("total wall time {wall:.2} s"));
    } else {
        context.say(format!(
            "total wall time {wall:.2} s; results in {}",
            dir.display()
        ));
    }
    let summary = RunSummary {
        steps,
        loop_time: timing.loop_time,
        stages,
        thermo: report.thermo,
        ..RunSummary::of(model, last, context, threads)
    };
    Ok((summary, report.model))
}

/// The run of `job` under way in `context`: its state replaced by the
/// checkpoint's when restarting (checked before anything is written; the
/// checkpoint's step at most `last`), its output folder made, its observers
/// created (continuing the files the checkpoint recorded) and step 0 observed
/// on a new run.
pub(crate) fn begin<M: Hosted + 'static, P: Outputs<M> + ?Sized>(
    mut job: Job<M>,
    outputs: &P,
    context: &RunContext,
    last: u64,
    bar: ProgressBar,
) -> SimResult<Live<M>> {
    let threads = context.threads;
    let restart = context.restart;
    let checkpoint = restart
        .map(|path| driver::restore(&mut job.model, path, &job.physics, last, &job.dir, threads))
        .transpose();
    let checkpoint = driver::agreed(&job.ranks, checkpoint)?;
    let dir = job.dir.clone();
    if let Some(path) = restart {
        let first = checkpoint.as_ref().map_or(0, |c| c.step);
        context.say(format!("restart: from step {first} of {}", path.display()));
    }
    let observers = if job.ranks.writes_output() {
        let recorded = recorded(checkpoint.as_ref());
        std::fs::create_dir_all(&dir)
            .map_err(SimError::output(format!("folder {}", dir.display())))
            .and_then(|()| outputs.observers(&job.model, &dir, recorded, context.quiet))
    } else {
        Ok(Vec::new())
    };
    let observers = driver::agreed(&job.ranks, observers)?;
    job.start(checkpoint.as_ref(), observers, bar)
}

impl RunSummary {
    /// What `model` at step `last` reports (its particles or field if
    /// `context` keeps the final state), and the warnings of `context`; no
    /// steps, times or thermo rows yet.
    fn of<M: Model>(model: &M, last: u64, context: &RunContext, threads: &Threads) -> Self {
        RunSummary {
            model: model.info().name,
            dt: model.dt(),
            steps: 0,
            threads: threads.count(),
            loop_time: Duration::ZERO,
            stages: Vec::new(),
            thermo_columns: model.info().thermo_columns.to_vec(),
            thermo: Vec::new(),
            particles: context
                .final_state
                .then(|| model.particles(last, false))
                .flatten(),
            field: context.final_state.then(|| model.field()).flatten(),
            warnings: context.warnings.take(),
        }
    }
}
