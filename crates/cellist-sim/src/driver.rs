//! The one run loop of every model: restart from a checkpoint, step, check, run
//! the observers whose trigger fires, write checkpoints, stop on a blow-up with
//! the last good state, and report the time per stage.
//!
//! ```text
//! setup:   model built from its scenario; with --restart, its state replaced by
//!          the checkpoint's (model, physics keys and output files checked first)
//!          -> observers created (growing files continued from the recorded lengths)
//!          -> observe(step 0) on a new run
//! loop:    observe = an observer needs thermo or energies at s
//!                    (or, for a state spread over MPI ranks, any output is due;
//!                    the ranks of a replicated state agree on it and on which
//!                    outputs are due, which only rank 0's observers know)
//!          model.want_particle_energies(a dump with energies is due at s)
//!          model.step_observed(s) if observe, else model.step(s)
//!                                         # the model's own stages, timed by it
//!          check(model)                   # finite values, walls, particle count
//!                                         # (unless the model's step checks itself)
//!          observers whose trigger fires  # thermo, dumps, fields, pictures
//!          if an observer or a checkpoint fired (on any rank): keep the state as
//!          the last good one
//!          if s is a checkpoint step: write the checkpoint (atomically)
//!          (on several ranks every failure is agreed, so that all stop together)
//! finish:  observers finish (plots, animations), timers report
//! blow-up: the last good state restored, its frame and checkpoint written, exit 3
//! ```

use crate::error::{SimError, SimResult};
use crate::hosted::{FileState, Hosted};
use crate::observers::{write_field_csv, write_frame, DumpFormat, Observer, Recorded};
use crate::ranks::Ranks;
use crate::scenario::keys::CheckpointKeys;
use cellist::models::{check, Blowup, Model};
use cellist::state::State;
use cellist::Threads;
use cellist_io::checkpoint::{
    write_checkpoint, write_checkpoint_in_blocks, Checkpoint, CheckpointFile,
};
use cellist_io::AtomicFile;
use indicatif::ProgressBar;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// Where a blow-up writes the last good state's particles.
#[derive(Clone, Debug)]
pub enum LastFrame {
    /// A LAMMPS dump frame of these columns.
    Dump {
        /// File name in the output folder.
        file: &'static str,
        /// Columns.
        columns: Vec<String>,
    },
    /// A field CSV.
    Field {
        /// File name in the output folder.
        file: &'static str,
    },
}

/// A run ready to go: the model (at its first step), how far to run, and what to
/// write.
pub struct Job<M: Hosted> {
    /// The model, as built from its scenario or input.
    pub model: M,
    /// Where the model lives: in this process, or over MPI ranks.
    pub ranks: Ranks,
    /// The last step.
    pub steps: u64,
    /// The output folder.
    pub dir: PathBuf,
    /// Checkpoints, if asked for.
    pub checkpoint: Option<CheckpointKeys>,
    /// The physics a checkpoint records and a restart must match.
    pub physics: Vec<(String, String)>,
    /// Where a blow-up writes its last good frame.
    pub last_frame: LastFrame,
}

/// A run's settings apart from its model: how far it goes, where it writes,
/// its checkpoints, the physics a restart must match and its last frame.
pub struct JobSpec {
    /// The last step.
    pub steps: u64,
    /// The output folder.
    pub dir: PathBuf,
    /// Checkpoints, if asked for.
    pub checkpoint: Option<CheckpointKeys>,
    /// The physics a checkpoint records and a restart must match.
    pub physics: Vec<(String, String)>,
    /// Where a blow-up writes its last good frame.
    pub last_frame: LastFrame,
}

impl JobSpec {
    /// The run of `model`, in this process, with these settings.
    pub fn with<M: Hosted>(self, model: M) -> Job<M> {
        Job {
            model,
            ranks: Ranks::One,
            steps: self.steps,
            dir: self.dir,
            checkpoint: self.checkpoint,
            physics: self.physics,
            last_frame: self.last_frame,
        }
    }
}

/// What a finished run reports.
pub struct Report<M> {
    /// The model in its final state.
    pub model: M,
    /// Where it lived.
    pub ranks: Ranks,
    /// Its first step and the wall times of its loop.
    pub timing: Timing,
    /// The thermo rows `(step, values)` the observers kept.
    pub thermo: Vec<(u64, Vec<f64>)>,
}

/// Where a run's loop began and what it has cost so far.
#[derive(Clone, Copy, Debug)]
pub struct Timing {
    /// The first step of this run (0, or the checkpoint's step).
    pub first: u64,
    /// Wall time of the loop.
    pub loop_time: Duration,
    /// Wall time of the loop spent in the observers and checkpoints.
    pub output_time: Duration,
}

/// Reads `path` and checks it against `model` and `physics`: the same model, the
/// same physics keys (the first difference named), a step within `steps`, and a
/// state `model` can take. Nothing is written. On success the model holds the
/// checkpoint's state, read from the file in place (a rank of a spread run
/// reads only the particles it keeps), and the checkpoint returned is the
/// file's head: its step, physics and outputs, no state.
pub fn restore<M: Model>(
    model: &mut M,
    path: &Path,
    physics: &[(String, String)],
    steps: u64,
    dir: &Path,
    threads: &Threads,
) -> SimResult<Checkpoint> {
    let file = CheckpointFile::open(path)?;
    let c = &file.head;
    let at = path.display();
    let name = model.info().name;
    if c.model != name {
        return Err(SimError::Input(format!(
            "{at}: a checkpoint of model '{}'; this run is model '{name}'",
            c.model,
        )));
    }
    if let Some(m) = physics_difference(&c.physics, physics) {
        return Err(SimError::Input(format!(
            "{at}: {m}; a restart continues the same physics (only [output] keys and run.steps may change)"
        )));
    }
    if c.step > steps {
        return Err(SimError::Input(format!(
            "{at}: the checkpoint is at step {}, beyond the run's last step {steps}; raise the step count",
            c.step
        )));
    }
    model
        .restore(&file, threads)
        .map_err(|e| SimError::Input(format!("{at}: the state does not fit the scenario: {e}")))?;
    for (name, length) in &c.outputs {
        let output = dir.join(name);
        if let Ok(meta) = std::fs::metadata(&output) {
            if meta.len() < *length {
                return Err(SimError::Input(format!(
                    "{at}: {} has {} bytes, fewer than the {length} it had at step {}; \
                     restore it, or restart with --out into a new folder",
                    output.display(),
                    meta.len(),
                    c.step
                )));
            }
        }
    }
    Ok(file.head)
}

/// The first key whose value differs between a checkpoint's physics and a
/// scenario's, as a sentence.
fn physics_difference(saved: &[(String, String)], now: &[(String, String)]) -> Option<String> {
    let mut keys: Vec<&str> = saved.iter().chain(now).map(|(k, _)| k.as_str()).collect();
    keys.sort_unstable();
    keys.dedup();
    let get = |list: &[(String, String)], k: &str| {
        list.iter()
            .find(|(key, _)| key == k)
            .map(|(_, v)| v.clone())
    };
    keys.into_iter()
        .find_map(|k| match (get(saved, k), get(now, k)) {
            (Some(a), Some(b)) if a != b => Some(format!(
                "the physics key `{k}` is {b} in the scenario but was {a} in the checkpoint's run"
            )),
            (Some(a), None) => Some(format!(
            "the physics key `{k}` was {a} in the checkpoint's run and is not set in the scenario"
        )),
            (None, Some(b)) => Some(format!(
            "the physics key `{k}` = {b} is set in the scenario but was not in the checkpoint's run"
        )),
            _ => None,
        })
}

impl<M: Hosted> Job<M> {
    /// The same run with its model held on `ranks`.
    pub fn on(self, ranks: Ranks) -> Self {
        Job { ranks, ..self }
    }

    /// The run under way at step 0, or at the step of `restored`: the observers
    /// have seen step 0 of a new run, and the state is kept as the last good one.
    pub fn start(
        self,
        restored: Option<&Checkpoint>,
        mut observers: Vec<Box<dyn Observer<M>>>,
        bar: ProgressBar,
    ) -> SimResult<Live<M>> {
        let first = restored.map_or(0, |c| c.step);
        let outputs = if restored.is_none() {
            observers
                .iter_mut()
                .filter(|o| o.due(0, self.steps))
                .try_for_each(|o| o.observe(&self.model, 0, self.steps, &bar))
        } else {
            Ok(())
        };
        let good = outputs.and_then(|()| self.snapshot(first, &mut observers));
        self.model.serve_outputs();
        // rank 0's outputs may fail alone: every rank stops with it
        let good = agreed(&self.ranks, good)?;
        Ok(Live {
            count: self.model.len(),
            scenario_steps: self.steps,
            job: self,
            observers,
            first,
            step: first,
            good,
            loop_time: Duration::ZERO,
            output_time: Duration::ZERO,
            bar,
            blowup: None,
        })
    }
}

/// A run under way: the model at its current step with its observers, its last
/// good state and its timers; [`Live::advance`] steps it on, as far as asked.
pub struct Live<M: Hosted> {
    job: Job<M>,
    scenario_steps: u64,
    observers: Vec<Box<dyn Observer<M>>>,
    count: usize,
    first: u64,
    step: u64,
    /// The state at the last step that passed the checks and was observed
    /// (with the lengths of the output files then): what a blow-up restores
    /// and writes.
    good: Checkpoint,
    loop_time: Duration,
    output_time: Duration,
    bar: ProgressBar,
    blowup: Option<Blowup>,
}

impl<M: Hosted> Live<M> {
    /// The model in its current state.
    pub fn model(&self) -> &M {
        &self.job.model
    }

    /// The current step.
    pub fn step(&self) -> u64 {
        self.step
    }

    /// The last blow-up met, if any (the run went back to its last good state).
    pub fn last_blowup(&self) -> Option<&Blowup> {
        self.blowup.as_ref()
    }

    /// The last step the run was built for.
    pub fn scenario_steps(&self) -> u64 {
        self.scenario_steps
    }

    /// Where the model lives: in this process, or over MPI ranks.
    pub fn ranks(&self) -> &Ranks {
        &self.job.ranks
    }

    /// The first step and the wall times of the loop so far.
    pub fn timing(&self) -> Timing {
        Timing {
            first: self.first,
            loop_time: self.loop_time,
            output_time: self.output_time,
        }
    }

    /// Steps on to step `to` of a run whose last step is `last >= to`
    /// (observers and checkpoints always take the last step): each step, its
    /// check, the observers whose trigger fires and the checkpoints due. A
    /// blow-up restores the last good state (the current step goes back to it),
    /// writes its frame and checkpoint, and is returned as the error.
    pub fn advance(&mut self, to: u64, last: u64, threads: &Threads) -> SimResult {
        debug_assert!(to <= last);
        self.job.steps = last;
        let loop_start = Instant::now();
        let outcome = self.advance_timed(to, last, threads);
        self.loop_time += loop_start.elapsed();
        outcome
    }

    fn advance_timed(&mut self, to: u64, last: u64, threads: &Threads) -> SimResult {
        for step in self.step + 1..=to {
            let job = &mut self.job;
            let observers = &mut self.observers;
            let checkpoint = job
                .checkpoint
                .as_ref()
                .is_some_and(|c| step % c.every == 0 || step == last);
            let due = observers.iter().any(|o| o.due(step, last));
            let (observe, due) = job.ranks.agree_on_step(
                observers.iter().any(|o| o.needs_observables(step, last))
                    || (job.ranks.observe_when_due() && (checkpoint || due)),
                due,
            );
            let stepped = if observe {
                let energies = observers
                    .iter()
                    .any(|o| o.needs_particle_energies(step, last));
                job.model.want_particle_energies(energies);
                job.model.step_observed(step, threads)
            } else {
                job.model.step(step, threads)
            };
            let stepped = stepped.and_then(|()| {
                if job.model.checks_its_steps() {
                    Ok(())
                } else {
                    check(&job.model, step, self.count)
                }
            });
            if let Err(blowup) = stepped {
                self.bar.abandon();
                self.step = self.good.step;
                self.blowup = Some(blowup.clone());
                return Err(job.blow_up(blowup, &self.good, observers, threads));
            }
            self.step = step;
            let t = Instant::now();
            let written = job.output(
                step,
                last,
                checkpoint || due,
                checkpoint,
                observers,
                &self.bar,
                &mut self.good,
            );
            job.model.serve_outputs();
            agreed(&job.ranks, written)?;
            self.output_time += t.elapsed();
            self.bar.inc(1);
        }
        Ok(())
    }

    /// Replaces the model's per-particle array `name` by `values` (in the
    /// order of its particles), where the model allows it; the new state is
    /// the last good one.
    pub fn set_array(&mut self, name: &str, values: &[f64], threads: &Threads) -> SimResult {
        let model = &mut self.job.model;
        model
            .set_array(name, values, threads)
            .map_err(SimError::Input)?;
        let observers = &mut self.observers;
        self.job.retake(&mut self.good, self.step, observers)?;
        Ok(())
    }

    /// A checkpoint of the current state: the model's state, the physics keys
    /// and the lengths of the growing output files (flushed).
    pub fn checkpoint(&mut self) -> SimResult<Checkpoint> {
        self.job.snapshot(self.step, &mut self.observers)
    }

    /// Completes the observers' files (plots, animations) and reports the run.
    pub fn finish(mut self) -> SimResult<Report<M>> {
        // rank 0's files may fail alone: every rank stops with it
        let finished = self.finish_outputs();
        agreed(&self.job.ranks, finished)?;
        let thermo = self
            .observers
            .iter_mut()
            .find_map(|o| o.take_thermo_rows())
            .unwrap_or_default();
        Ok(Report {
            timing: self.timing(),
            model: self.job.model,
            ranks: self.job.ranks,
            thermo,
        })
    }

    /// Completes the observers' files (plots, animations) without ending the
    /// run: what a Python session does when it is closed.
    pub fn finish_outputs(&mut self) -> SimResult {
        for o in &mut self.observers {
            o.finish()?;
        }
        Ok(())
    }
}

impl<M: Hosted> Job<M> {
    /// The checkpoint of the model at `step`, with the synced lengths of the
    /// observers' files.
    fn snapshot(&self, step: u64, observers: &mut [Box<dyn Observer<M>>]) -> SimResult<Checkpoint> {
        let mut good = Checkpoint {
            model: self.model.info().name.to_string(),
            physics: self.physics.clone(),
            ..Checkpoint::default()
        };
        self.retake(&mut good, step, observers)?;
        Ok(good)
    }

    /// Makes `good` the checkpoint of the model at `step`: the observers'
    /// files are synced first (a failure leaves `good` as it was), then the
    /// old state is dropped before the new one is saved, so that a large
    /// state is never held twice.
    fn retake(
        &self,
        good: &mut Checkpoint,
        step: u64,
        observers: &mut [Box<dyn Observer<M>>],
    ) -> SimResult {
        let mut outputs = Vec::new();
        for o in observers.iter_mut() {
            outputs.extend(o.sync()?);
        }
        good.outputs = outputs;
        good.step = step;
        good.state = State::default();
        self.model.save(&mut good.state);
        Ok(())
    }

    /// Runs the observers due at `step`, keeps the state as the last good one if
    /// `keep` (an observer or a checkpoint is due, on any rank of a replicated
    /// run, so that its ranks keep the same steps) or the model was observed
    /// everywhere, and writes the checkpoint.
    #[allow(clippy::too_many_arguments)]
    fn output(
        &mut self,
        step: u64,
        last: u64,
        keep: bool,
        checkpoint: bool,
        observers: &mut [Box<dyn Observer<M>>],
        bar: &ProgressBar,
        good: &mut Checkpoint,
    ) -> SimResult {
        for o in observers.iter_mut().filter(|o| o.due(step, last)) {
            o.observe(&self.model, step, last, bar)?;
        }
        if keep || self.model.observed_everywhere() {
            self.retake(good, step, observers)?;
        }
        if checkpoint && self.ranks.writes_output() {
            let file = self
                .checkpoint
                .as_ref()
                .expect("checkpoint keys")
                .file
                .clone();
            self.write_checkpoint(&file, good)?;
        }
        Ok(())
    }

    /// Writes `good` to `file`, with the state the model puts in files
    /// ([`Hosted::file_state`]: `good`'s, or a spread model's global one,
    /// written a block at a time).
    fn write_checkpoint(&self, file: &Path, good: &Checkpoint) -> SimResult {
        let path = self.dir.join(file);
        let written = match self.model.file_state(&good.state) {
            FileState::Saved(_) => write_checkpoint(&path, good),
            FileState::Spread(layout, fill) => {
                write_checkpoint_in_blocks(&path, good, &layout, fill)
            }
        };
        written.map_err(SimError::output(path.display().to_string()))
    }

    /// Restores the last good state, writes its frame and checkpoint, completes the
    /// observers' files, and returns the error that names the step, the particle
    /// and where the last good state is.
    fn blow_up(
        &mut self,
        blowup: Blowup,
        good: &Checkpoint,
        observers: &mut [Box<dyn Observer<M>>],
        threads: &Threads,
    ) -> SimError {
        for o in observers.iter_mut() {
            if let Err(e) = o.finish() {
                eprintln!("warning: {e}");
            }
        }
        let mut written = Vec::new();
        if !self.ranks.writes_output() {
            // the other ranks restore with rank 0: a spread model's ranks their
            // parts, then they serve rank 0's last frame and checkpoint; a
            // replicated model's ranks the whole state, whose field sums they
            // share with rank 0
            let _ = self.model.restore(&good.state, threads);
            if self.ranks.observe_when_due() {
                self.model.serve_outputs();
            }
            return SimError::BlowUp(format!("{blowup}"));
        }
        match self.model.restore(&good.state, threads) {
            Ok(()) => {
                match self.write_last_frame(good.step) {
                    Ok(path) => written.push(path),
                    Err(e) => eprintln!("warning: {e}"),
                }
                let file = self
                    .checkpoint
                    .as_ref()
                    .map_or_else(|| PathBuf::from("last.ckpt"), |c| c.file.clone());
                match self.write_checkpoint(&file, good) {
                    Ok(()) => written.push(self.dir.join(file).display().to_string()),
                    Err(e) => eprintln!("warning: {e}"),
                }
            }
            Err(e) => eprintln!("warning: the last good state could not be restored: {e}"),
        }
        self.model.serve_outputs();
        let place = if written.is_empty() {
            "could not be written".to_string()
        } else {
            format!("is in {}", written.join(" and "))
        };
        SimError::BlowUp(format!(
            "{blowup}; the last good state (step {}) {place}",
            good.step
        ))
    }

    /// Writes the model's particles (or field) at `step` to its last-frame file.
    fn write_last_frame(&self, step: u64) -> SimResult<String> {
        match &self.last_frame {
            LastFrame::Dump { file, columns } => {
                let path = self.dir.join(file);
                let what = path.display().to_string();
                let mut out = AtomicFile::create(&path).map_err(SimError::output(what.clone()))?;
                let format = DumpFormat::Lammps;
                write_frame(&self.model, step, format, columns, out.writer(), &what)?;
                out.commit().map_err(SimError::output(what.clone()))?;
                Ok(what)
            }
            LastFrame::Field { file } => {
                let path = self.dir.join(file);
                let field = self.model.field().ok_or_else(|| {
                    SimError::Internal(format!("model {} has no field", self.model.info().name))
                })?;
                write_field_csv(&path, &field)?;
                Ok(path.display().to_string())
            }
        }
    }
}

/// `result` made one for every rank of a distributed model: a rank that did
/// not fail returns the failure of the lowest rank that did.
pub(crate) fn agreed<T>(ranks: &Ranks, result: SimResult<T>) -> SimResult<T> {
    let failure = result.as_ref().err().map(ToString::to_string);
    match (ranks.agree(failure), result) {
        (Some(message), Ok(_)) => Err(SimError::Input(message)),
        (_, result) => result,
    }
}

/// The outputs a restart continues, or none for a new run.
pub fn recorded(checkpoint: Option<&Checkpoint>) -> Recorded<'_> {
    checkpoint.map_or(&[], |c| &c.outputs)
}

/// The loop's time per stage: the model's stages, `Output` (observers and
/// checkpoints) and `Other` (the rest of the loop time).
pub(crate) fn stages<M: Model>(
    model: &M,
    loop_time: Duration,
    output: Duration,
) -> Vec<(&'static str, Duration)> {
    let mut stages = model.stage_times();
    stages.push(("Output", output));
    let known: Duration = stages.iter().map(|(_, d)| *d).sum();
    stages.push(("Other", loop_time.saturating_sub(known)));
    stages
}
