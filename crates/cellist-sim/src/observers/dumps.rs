//! Particle dumps: LAMMPS `dump custom` text and extended XYZ, a frame every
//! so many steps.

use super::observer::{open_stream, sync_one, Observer, Recorded};
use crate::error::{SimError, SimResult};
use cellist::models::{Model, ParticleBlock, Particles};
use cellist_io::{
    write_lammps_head, write_lammps_rows, write_xyz_head, write_xyz_rows, Frame, StreamFile,
};
use indicatif::ProgressBar;
use std::io::Write;
use std::ops::ControlFlow;
use std::path::{Path, PathBuf};

/// The text formats of particle frames.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DumpFormat {
    /// LAMMPS `dump custom` text.
    Lammps,
    /// Extended XYZ.
    Xyz,
}

/// A trajectory file: a frame every `every` steps.
pub struct Dump {
    every: u64,
    name: String,
    file: StreamFile,
    columns: Vec<String>,
    format: DumpFormat,
}

impl Dump {
    /// Frames of `columns` (LAMMPS) every `every` steps to `dir/name`.
    pub fn new(
        every: u64,
        name: &Path,
        columns: Vec<String>,
        format: DumpFormat,
        dir: &Path,
        recorded: Recorded,
    ) -> SimResult<Self> {
        let name = name.to_string_lossy().into_owned();
        let (file, _) = open_stream(dir, &name, recorded)?;
        Ok(Dump {
            every,
            name,
            file,
            columns,
            format,
        })
    }

    fn energies(&self) -> bool {
        needs_energies(self.format, &self.columns)
    }
}

/// True when frames in `format` with `columns` show per-particle energies.
fn needs_energies(format: DumpFormat, columns: &[String]) -> bool {
    format == DumpFormat::Lammps && columns.iter().any(|c| c == "pe")
}

/// Writes the frame of `model` after `step` to `out` in `format` (LAMMPS
/// dumps with `columns`), a block of rows at a time: what is held besides the
/// model is one block, not a copy of every particle. An internal error for a
/// model without particles, or without the per-particle energies a `pe`
/// column asks for; an output error naming `name` if a write fails.
pub fn write_frame<M: Model + ?Sized>(
    model: &M,
    step: u64,
    format: DumpFormat,
    columns: &[String],
    out: &mut dyn Write,
    name: &str,
) -> SimResult {
    let time = step as f64 * model.dt();
    let energies = needs_energies(format, columns);
    let mut written = Ok(());
    let mut without_energies = false;
    let mut write = |block: ParticleBlock| {
        if energies && block.rows.energies.is_none() {
            without_energies = true;
            return ControlFlow::Break(());
        }
        written = write_block(out, block, step, format, columns, time);
        match written {
            Ok(()) => ControlFlow::Continue(()),
            Err(_) => ControlFlow::Break(()),
        }
    };
    if !model.particle_blocks(step, energies, &mut write) {
        return Err(SimError::Internal(format!(
            "model {} has no particle columns to dump",
            model.info().name
        )));
    }
    if without_energies {
        return Err(SimError::Internal(format!(
            "model {} has no per-particle energies for the pe column at step {step}",
            model.info().name
        )));
    }
    written.map_err(SimError::output(name.to_string()))
}

/// Writes one block of the frame after `step` (at `time`): the frame's head
/// before its first block, then the block's rows.
fn write_block(
    out: &mut dyn Write,
    block: ParticleBlock,
    step: u64,
    format: DumpFormat,
    columns: &[String],
    time: f64,
) -> std::io::Result<()> {
    let rows = frame(block.rows, step);
    let head = block.first == 0;
    match format {
        DumpFormat::Lammps => {
            if head {
                write_lammps_head(out, &rows, block.total, columns)?;
            }
            write_lammps_rows(out, &rows, columns)
        }
        DumpFormat::Xyz => {
            if head {
                write_xyz_head(out, &rows, block.total, time)?;
            }
            write_xyz_rows(out, &rows)
        }
    }
}

/// A dump frame borrowing `p`'s columns.
fn frame(p: &Particles, step: u64) -> Frame<'_> {
    Frame {
        step,
        lo: p.lo,
        hi: p.hi,
        periodic: p.periodic,
        ids: &p.ids,
        types: &p.types,
        positions: &p.positions,
        velocities: &p.velocities,
        forces: &p.forces,
        energies: p.energies.as_deref(),
        masses: p.masses.as_deref(),
        accelerations: p.accelerations.as_deref(),
        potentials: p.potentials.as_deref(),
    }
}

impl<M: Model> Observer<M> for Dump {
    fn due(&self, step: u64, _last: u64) -> bool {
        step.is_multiple_of(self.every)
    }

    fn needs_observables(&self, step: u64, last: u64) -> bool {
        <Self as Observer<M>>::needs_particle_energies(self, step, last)
    }

    fn needs_particle_energies(&self, step: u64, last: u64) -> bool {
        self.energies() && <Self as Observer<M>>::due(self, step, last)
    }

    fn observe(&mut self, model: &M, step: u64, _last: u64, _bar: &ProgressBar) -> SimResult {
        let out = self.file.writer();
        write_frame(model, step, self.format, &self.columns, out, &self.name)
    }

    fn sync(&mut self) -> SimResult<Vec<(String, u64)>> {
        Ok(vec![sync_one(&mut self.file, &self.name)?])
    }

    fn finish(&mut self) -> SimResult {
        self.file
            .sync()
            .map(drop)
            .map_err(SimError::output(self.name.clone()))
    }
}

/// A dump the scenario asks for.
#[derive(Clone, Debug)]
pub struct DumpPlan {
    /// Steps between frames.
    pub every: u64,
    /// File name in the output folder.
    pub file: PathBuf,
    /// Columns (LAMMPS dumps).
    pub columns: Vec<String>,
    /// The format.
    pub format: DumpFormat,
}
