//! The observer's contract and its triggers: something done after the steps
//! its trigger picks, and the files that grow as the run goes (continued on a
//! restart from the lengths its checkpoint recorded).

use crate::error::{SimError, SimResult};
use cellist::models::{Model, ParticleBlock};
use cellist_io::StreamFile;
use indicatif::ProgressBar;
use std::ops::ControlFlow;
use std::path::{Path, PathBuf};

/// Something done after the steps its trigger picks.
pub trait Observer<M: Model> {
    /// True when `step` (of a run ending at `last`) is one of its steps.
    fn due(&self, step: u64, last: u64) -> bool;

    /// True when the step must compute what [`Model::thermo`] and per-particle
    /// energies need.
    fn needs_observables(&self, _step: u64, _last: u64) -> bool {
        false
    }

    /// True when the step must compute per-particle energies (a dump with
    /// energy columns due at `step`); implies [`Observer::needs_observables`].
    fn needs_particle_energies(&self, _step: u64, _last: u64) -> bool {
        false
    }

    /// Writes what it writes for the state after `step`.
    fn observe(&mut self, model: &M, step: u64, last: u64, bar: &ProgressBar) -> SimResult;

    /// Flushes its growing files and returns their names (relative to the output
    /// folder) and lengths, for a checkpoint.
    fn sync(&mut self) -> SimResult<Vec<(String, u64)>> {
        Ok(Vec::new())
    }

    /// Completes its files at the end of the run (or after a blow-up).
    fn finish(&mut self) -> SimResult {
        Ok(())
    }

    /// The thermo rows `(step, values)` it kept, handed over once at the end
    /// (the thermo observer; others have none).
    fn take_thermo_rows(&mut self) -> Option<Vec<(u64, Vec<f64>)>> {
        None
    }
}

/// The output files a checkpoint recorded, `(name, length)`; empty for a new run.
pub type Recorded<'a> = &'a [(String, u64)];

/// Opens `dir/name` for writing: continued from its recorded length when the
/// checkpoint recorded it and it exists, else new. Returns the file and whether it
/// was continued.
pub fn open_stream(dir: &Path, name: &str, recorded: Recorded) -> SimResult<(StreamFile, bool)> {
    let path = dir.join(name);
    let what = path.display().to_string();
    match recorded.iter().find(|(n, _)| n == name) {
        Some((_, length)) if path.exists() => StreamFile::resume(&path, *length)
            .map(|f| (f, true))
            .map_err(|e| match e.kind() {
                std::io::ErrorKind::InvalidData => SimError::Input(e.to_string()),
                _ => SimError::Output(e, what),
            }),
        _ => StreamFile::create(&path)
            .map(|f| (f, false))
            .map_err(SimError::output(what)),
    }
}

/// Flushes `file`, whose name in the output folder is `name`, and returns the
/// name and its length for a checkpoint.
pub fn sync_one(file: &mut StreamFile, name: &str) -> SimResult<(String, u64)> {
    let length = file
        .sync()
        .map_err(SimError::output(file.path().display().to_string()))?;
    Ok((name.to_string(), length))
}

/// Snapshots every `every` steps (and at step 0 and the last step) to `file`.
#[derive(Clone, Debug)]
pub struct Every {
    /// The period in steps.
    pub every: u64,
    /// The file name (a pattern for per-step files, see
    /// [`snapshot_path`](super::pictures::snapshot_path)).
    pub file: PathBuf,
}

impl Every {
    /// True at step 0, at the last step and every `every` steps.
    pub fn due(&self, step: u64, last: u64) -> bool {
        step == 0 || step == last || step.is_multiple_of(self.every)
    }
}

/// True when `every` is given and due at `step`.
pub fn due(every: &Option<Every>, step: u64, last: u64) -> bool {
    every.as_ref().is_some_and(|e| e.due(step, last))
}

/// Hands the non-empty blocks of `model`'s particles at `step` to `visit`
/// in order, stopping at its first error. `None` for a model without
/// particles; the error, if any. (A spread model may hand out empty blocks,
/// whose rows lack the columns, and none at all for no particles.)
pub(crate) fn each_block<M: Model + ?Sized>(
    model: &M,
    step: u64,
    mut visit: impl FnMut(&ParticleBlock) -> std::io::Result<()>,
) -> Option<std::io::Result<()>> {
    let mut result = Ok(());
    let has_particles = model.particle_blocks(step, false, &mut |block| {
        if block.rows.ids.is_empty() {
            return ControlFlow::Continue(());
        }
        result = visit(&block);
        match result {
            Ok(()) => ControlFlow::Continue(()),
            Err(_) => ControlFlow::Break(()),
        }
    });
    has_particles.then_some(result)
}
