//! Particle dumps: LAMMPS `dump custom` text and extended XYZ, a frame every
//! so many steps.

use super::observer::{open_stream, sync_one, Observer, Recorded};
use crate::error::{SimError, SimResult};
use cellist::models::{Model, Particles};
use cellist_io::{write_lammps_frame, write_xyz_frame, Frame, StreamFile};
use indicatif::ProgressBar;
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
        self.format == DumpFormat::Lammps && self.columns.iter().any(|c| c == "pe")
    }
}

/// A dump frame borrowing `p`'s columns.
pub fn frame(p: &Particles, step: u64) -> Frame<'_> {
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
        step % self.every == 0
    }

    fn needs_observables(&self, step: u64, last: u64) -> bool {
        self.energies() && <Self as Observer<M>>::due(self, step, last)
    }

    fn observe(&mut self, model: &M, step: u64, _last: u64, _bar: &ProgressBar) -> SimResult {
        let Some(particles) = model.particles(step, self.energies()) else {
            return Err(SimError::Internal(format!(
                "model {} has no particle columns to dump",
                model.info().name
            )));
        };
        let frame = frame(&particles, step);
        let w = self.file.writer();
        match self.format {
            DumpFormat::Lammps => write_lammps_frame(w, &frame, &self.columns),
            DumpFormat::Xyz => write_xyz_frame(w, &frame, step as f64 * model.dt()),
        }
        .map_err(SimError::output(self.name.clone()))
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
