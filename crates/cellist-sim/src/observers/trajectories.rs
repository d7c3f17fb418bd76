//! Trajectories for the field's viewers, from any model: GSD frames (HOOMD
//! schema; OVITO, HOOMD-blue, freud, MDAnalysis) and VTK PolyData series (a
//! `.vtp` file per frame and a `.pvd` index; ParaView). A model's particles, or
//! the particles carrying its field, become one frame:
//!
//! ```text
//! [output]
//! gsd = { every = 100, file = "traj.gsd" }
//! vtk = { every = 100, file = "traj.pvd" }   # traj_00000100.vtp, ... beside it
//! ```

use super::observer::{Observer, Recorded};
use crate::error::{SimError, SimResult};
use crate::scenario::keys::SeriesKeys;
use cellist::models::{Field, Model, Particles};
use cellist_io::{write_hoomd_frame, write_pvd, write_vtp, GsdWriter, HoomdFrame};
use indicatif::ProgressBar;
use std::path::{Path, PathBuf};

/// One frame of a model: positions (3 components), its box, and named
/// per-particle arrays (name, values, components).
pub struct TrajectoryFrame {
    /// 2 or 3.
    pub dimension: usize,
    /// The box's lower corner.
    pub lo: [f64; 3],
    /// The box's sides.
    pub length: [f64; 3],
    /// Positions.
    pub positions: Vec<[f64; 3]>,
    /// Velocities, if the model has them.
    pub velocities: Option<Vec<[f64; 3]>>,
    /// Masses, if the model has them.
    pub masses: Option<Vec<f64>>,
    /// Type of each particle (from 1), if the model has types.
    pub types: Option<Vec<u32>>,
    /// Further per-particle quantities: name, values, components.
    pub arrays: Vec<(&'static str, Vec<f64>, usize)>,
}

impl TrajectoryFrame {
    /// The frame of `model` at `step`: its particles (as its dumps show them),
    /// or the particles carrying its field. `None` for a model with neither.
    pub fn of(model: &dyn Model, step: u64) -> Option<Self> {
        match model.particles(step, false) {
            Some(p) => Some(Self::of_particles(p)),
            None => model.field().map(Self::of_field),
        }
    }

    /// [`TrajectoryFrame::of`], or the error naming the model that has nothing
    /// to write as `format`.
    pub fn required(model: &dyn Model, step: u64, format: &str) -> SimResult<Self> {
        Self::of(model, step).ok_or_else(|| {
            SimError::Input(format!(
                "model {} has neither particles nor a field to write as {format}",
                model.info().name
            ))
        })
    }

    fn of_particles(p: Particles) -> Self {
        let flat = |v: &[[f64; 3]]| v.iter().flatten().copied().collect::<Vec<f64>>();
        let mut arrays = Vec::new();
        if !p.forces.is_empty() {
            arrays.push(("force", flat(&p.forces), 3));
        }
        if let Some(a) = &p.accelerations {
            arrays.push(("acceleration", flat(a), 3));
        }
        if let Some(phi) = p.potentials {
            arrays.push(("potential", phi, 1));
        }
        arrays.push(("id", p.ids.iter().map(|&i| i as f64).collect(), 1));
        TrajectoryFrame {
            dimension: p.dimension,
            lo: p.lo,
            length: std::array::from_fn(|a| p.hi[a] - p.lo[a]),
            velocities: Some(p.velocities),
            masses: p.masses,
            types: (!p.types.is_empty()).then_some(p.types),
            positions: p.positions,
            arrays,
        }
    }

    fn of_field(f: Field) -> Self {
        let mut arrays = vec![(f.value_name, f.values, 1)];
        let mut extra = f.extra;
        let u = extra.iter().position(|(n, _)| *n == "u");
        let v = extra.iter().position(|(n, _)| *n == "v");
        let mut velocities = None;
        if let (Some(u), Some(v)) = (u, v) {
            let (us, vs) = (&extra[u].1, &extra[v].1);
            velocities = Some(us.iter().zip(vs).map(|(&a, &b)| [a, b, 0.0]).collect());
            extra.retain(|(n, _)| !matches!(*n, "u" | "v"));
        }
        arrays.extend(extra.into_iter().map(|(n, values)| (n, values, 1)));
        let mut length = [f.side; 3];
        if f.dimension == 2 {
            length[2] = 0.0;
        }
        TrajectoryFrame {
            dimension: f.dimension,
            lo: f.origin,
            length,
            positions: f.positions,
            velocities,
            masses: None,
            types: None,
            arrays,
        }
    }

    /// Appends this frame of `step` to the GSD file `writer`.
    pub fn write_gsd(&self, writer: &mut GsdWriter, step: u64) -> std::io::Result<()> {
        let typeid: Option<Vec<u32>> = self
            .types
            .as_ref()
            .map(|t| t.iter().map(|&k| k.saturating_sub(1)).collect());
        let most = self.types.as_ref().and_then(|t| t.iter().max().copied());
        let names: Vec<String> = (1..=most.unwrap_or(1)).map(|k| k.to_string()).collect();
        let extra: Vec<(&str, &[f64], u32)> = self
            .arrays
            .iter()
            .map(|(n, v, c)| (*n, v.as_slice(), *c as u32))
            .collect();
        write_hoomd_frame(
            writer,
            &HoomdFrame {
                step,
                dimensions: self.dimension as u8,
                box_lengths: self.length,
                lo: self.lo,
                positions: &self.positions,
                velocities: self.velocities.as_deref(),
                masses: self.masses.as_deref(),
                typeid: typeid.as_deref(),
                types: &names,
                extra: &extra,
            },
        )
    }

    /// Appends this frame of `step` to the GSD file `path`, made if missing or
    /// empty.
    pub fn append_gsd(&self, path: &Path, step: u64) -> SimResult {
        let what = path.display().to_string();
        let length = std::fs::metadata(path).map_or(0, |m| m.len());
        let (dir, name) = (
            path.parent().unwrap_or(Path::new("")),
            path.file_name()
                .map_or_else(String::new, |n| n.to_string_lossy().into_owned()),
        );
        let recorded = [(name.clone(), length)];
        let recorded: Recorded = if length > 0 { &recorded } else { &[] };
        let mut writer = open_gsd(dir, &name, recorded)?;
        self.write_gsd(&mut writer, step)
            .map_err(SimError::output(what))
    }

    /// Writes this frame as the VTK PolyData file `path`.
    pub fn write_vtp(&self, path: &Path) -> std::io::Result<()> {
        let velocities: Option<Vec<f64>> = self
            .velocities
            .as_ref()
            .map(|v| v.iter().flatten().copied().collect());
        let types: Option<Vec<f64>> = self
            .types
            .as_ref()
            .map(|t| t.iter().map(|&k| k as f64).collect());
        let mut arrays: Vec<(&str, &[f64], usize)> = Vec::new();
        if let Some(v) = &velocities {
            arrays.push(("velocity", v, 3));
        }
        if let Some(m) = &self.masses {
            arrays.push(("mass", m, 1));
        }
        if let Some(t) = &types {
            arrays.push(("type", t, 1));
        }
        arrays.extend(self.arrays.iter().map(|(n, v, c)| (*n, v.as_slice(), *c)));
        write_vtp(path, &self.positions, &arrays)
    }
}

/// Opens the GSD file `dir/name`: continued from its recorded length when the
/// checkpoint recorded it and it exists, else new.
pub fn open_gsd(dir: &Path, name: &str, recorded: Recorded) -> SimResult<GsdWriter> {
    let path = dir.join(name);
    let what = path.display().to_string();
    match recorded.iter().find(|(n, _)| n == name) {
        Some((_, length)) if path.exists() => {
            GsdWriter::resume(&path, *length).map_err(|e| match e.kind() {
                std::io::ErrorKind::InvalidData => SimError::Input(format!("{what}: {e}")),
                _ => SimError::Output(e, what),
            })
        }
        _ => GsdWriter::create(&path).map_err(SimError::output(what)),
    }
}

/// The GSD trajectory observer.
pub struct GsdTrajectory {
    every: u64,
    name: String,
    path: PathBuf,
    writer: GsdWriter,
}

impl GsdTrajectory {
    /// Frames every `every` steps to `dir/name`, continuing a recorded file.
    pub fn new(keys: &SeriesKeys, dir: &Path, recorded: Recorded) -> SimResult<Self> {
        let name = keys.file.to_string_lossy().into_owned();
        Ok(GsdTrajectory {
            every: keys.every,
            writer: open_gsd(dir, &name, recorded)?,
            path: dir.join(&name),
            name,
        })
    }
}

impl<M: Model> Observer<M> for GsdTrajectory {
    fn due(&self, step: u64, _last: u64) -> bool {
        step.is_multiple_of(self.every)
    }

    fn observe(&mut self, model: &M, step: u64, _last: u64, _bar: &ProgressBar) -> SimResult {
        let frame = TrajectoryFrame::required(model, step, "GSD")?;
        frame
            .write_gsd(&mut self.writer, step)
            .map_err(SimError::output(self.path.display().to_string()))
    }

    fn sync(&mut self) -> SimResult<Vec<(String, u64)>> {
        Ok(vec![(self.name.clone(), self.writer.len())])
    }
}

/// The VTK series observer: `stem_<step>.vtp` files beside the `.pvd` index,
/// which lists the frames on disk up to the current step (so that a restart
/// overwrites the frames after its checkpoint as it passes them).
pub struct VtkSeries {
    every: u64,
    dt: f64,
    dir: PathBuf,
    index: PathBuf,
    stem: String,
}

impl VtkSeries {
    /// Frames every `every` steps into `dir`, indexed by `dir/keys.file`.
    pub fn new(keys: &SeriesKeys, dt: f64, dir: &Path) -> Self {
        let stem = keys
            .file
            .file_stem()
            .map_or_else(|| "series".into(), |s| s.to_string_lossy().into_owned());
        VtkSeries {
            every: keys.every,
            dt,
            dir: dir.to_path_buf(),
            index: dir.join(&keys.file),
            stem,
        }
    }

    /// The frame file of `step`.
    fn frame_name(&self, step: u64) -> String {
        format!("{}_{step:08}.vtp", self.stem)
    }

    /// The frames of this series on disk, by step, up to `last`.
    fn frames_up_to(&self, last: u64) -> std::io::Result<Vec<(f64, String)>> {
        let prefix = format!("{}_", self.stem);
        let mut steps: Vec<u64> = Vec::new();
        for entry in std::fs::read_dir(&self.dir)? {
            let name = entry?.file_name().to_string_lossy().into_owned();
            let step = name
                .strip_prefix(&prefix)
                .and_then(|rest| rest.strip_suffix(".vtp"))
                .filter(|digits| digits.len() >= 8 && digits.bytes().all(|b| b.is_ascii_digit()))
                .and_then(|digits| digits.parse::<u64>().ok());
            if let Some(step) = step.filter(|&s| s <= last && s % self.every == 0) {
                steps.push(step);
            }
        }
        steps.sort_unstable();
        Ok(steps
            .into_iter()
            .map(|s| (s as f64 * self.dt, self.frame_name(s)))
            .collect())
    }
}

impl<M: Model> Observer<M> for VtkSeries {
    fn due(&self, step: u64, _last: u64) -> bool {
        step.is_multiple_of(self.every)
    }

    fn observe(&mut self, model: &M, step: u64, _last: u64, _bar: &ProgressBar) -> SimResult {
        let frame = TrajectoryFrame::required(model, step, "VTK")?;
        let path = self.dir.join(self.frame_name(step));
        frame
            .write_vtp(&path)
            .map_err(SimError::output(path.display().to_string()))?;
        let entries = self
            .frames_up_to(step)
            .map_err(SimError::output(self.dir.display().to_string()))?;
        write_pvd(&self.index, &entries).map_err(SimError::output(self.index.display().to_string()))
    }
}
