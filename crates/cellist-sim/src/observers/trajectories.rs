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

use super::observer::{each_block, Observer, Recorded};
use crate::error::{SimError, SimResult};
use crate::scenario::keys::SeriesKeys;
use cellist::models::{Field, Model, Particles};
use cellist_io::vtk::all_finite;
use cellist_io::{
    write_hoomd_frame, write_pvd, write_vtp, GsdWriter, HoomdBlocks, HoomdFrame, HoomdHead,
    HoomdRows, VtpBlocks,
};
use indicatif::ProgressBar;
use std::borrow::Cow;
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
        let arrays = particle_arrays(&p)
            .into_iter()
            .map(|(name, values, components)| (name, values.into_owned(), components))
            .collect();
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
        let typeid = self.types.as_deref().map(type_ids);
        let most = self.types.as_ref().and_then(|t| t.iter().max().copied());
        let names = type_names(most);
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
        let borrowed = self
            .arrays
            .iter()
            .map(|(n, v, c)| (*n, Cow::Borrowed(v.as_slice()), *c));
        let columns = vtk_columns(
            self.velocities.as_deref(),
            self.masses.as_deref(),
            self.types.as_deref(),
            borrowed,
        );
        let arrays: Vec<(&str, &[f64], usize)> =
            columns.iter().map(|(n, v, c)| (*n, &v[..], *c)).collect();
        write_vtp(path, &self.positions, &arrays)
    }
}

/// A VTK point-data array: name, values (row-major) and components.
type Column<'a> = (&'static str, Cow<'a, [f64]>, usize);

/// The point-data arrays of a VTK frame in the file's order: velocity, mass
/// and type where the frame has them, then `rest`.
fn vtk_columns<'a>(
    velocities: Option<&'a [[f64; 3]]>,
    masses: Option<&'a [f64]>,
    types: Option<&[u32]>,
    rest: impl Iterator<Item = Column<'a>>,
) -> Vec<Column<'a>> {
    let mut columns = Vec::new();
    if let Some(v) = velocities {
        columns.push(("velocity", Cow::Borrowed(v.as_flattened()), 3));
    }
    if let Some(m) = masses {
        columns.push(("mass", Cow::Borrowed(m), 1));
    }
    if let Some(t) = types {
        columns.push(("type", Cow::Owned(t.iter().map(|&k| k as f64).collect()), 1));
    }
    columns.extend(rest);
    columns
}

/// The VTK arrays of a block of particles `p` ([`vtk_columns`]).
fn particle_columns(p: &Particles) -> Vec<Column<'_>> {
    let rest = particle_arrays(p).into_iter();
    let types = (!p.types.is_empty()).then_some(&p.types[..]);
    vtk_columns(Some(&p.velocities), p.masses.as_deref(), types, rest)
}

/// What a VTK frame of a model's particles holds besides their values, from
/// a first pass over its blocks.
struct VtpShape {
    /// Per point-data array: name, components, and whether every value is
    /// finite.
    arrays: Vec<(&'static str, usize, bool)>,
    /// Whether every position is finite.
    points: bool,
    /// The particles in the frame.
    n: usize,
}

/// Column `name` of [`particle_columns`] of `p`, or an error naming the
/// block that lacks it.
fn column_of<'p>(p: &'p Particles, name: &str) -> std::io::Result<Cow<'p, [f64]>> {
    particle_columns(p)
        .into_iter()
        .find(|(n, _, _)| *n == name)
        .map(|(_, values, _)| values)
        .ok_or_else(|| missing_column(name))
}

/// The error of a block without a column its frame's first block has.
fn missing_column(name: &str) -> std::io::Error {
    std::io::Error::other(format!(
        "a block of the frame has no '{name}' column while the first has one"
    ))
}

/// Writes the frame of `model`'s particles at `step` as the VTK file `path`
/// an array at a time, each a block of rows at a time ([`VtpBlocks`]): a
/// first pass over the blocks for the arrays' names and whether each is
/// finite (ASCII) or not (binary), then one pass per array and one for the
/// points; what is held is a block, not the frame. `None` for a model
/// without particles or a frame without any (written whole). The file is
/// that of [`TrajectoryFrame::write_vtp`] of the whole frame.
fn write_vtp_blocks<M: Model + ?Sized>(
    model: &M,
    path: &Path,
    step: u64,
) -> Option<std::io::Result<()>> {
    let mut shape: Option<VtpShape> = None;
    let scanned = each_block(model, step, |block| {
        let p = block.rows;
        let columns = particle_columns(p);
        let shape = shape.get_or_insert_with(|| VtpShape {
            arrays: columns.iter().map(|(n, _, c)| (*n, *c, true)).collect(),
            points: true,
            n: block.total,
        });
        for (name, _, finite) in &mut shape.arrays {
            let (_, values, _) = columns
                .iter()
                .find(|(n, _, _)| n == name)
                .ok_or_else(|| missing_column(name))?;
            *finite &= all_finite(values);
        }
        shape.points &= all_finite(p.positions.as_flattened());
        Ok(())
    })?;
    let VtpShape { arrays, points, n } = match (scanned, shape) {
        (Err(e), _) => return Some(Err(e)),
        (Ok(()), None) => return None,
        (Ok(()), Some(shape)) => shape,
    };
    let mut file = match VtpBlocks::create(path, n) {
        Ok(file) => file,
        Err(e) => return Some(Err(e)),
    };
    let mut result = Ok(());
    for &(name, components, finite) in &arrays {
        result = result
            .and_then(|()| file.begin_array(name, components, finite))
            .and_then(|()| {
                let pass = each_block(model, step, |b| file.push(&column_of(b.rows, name)?));
                pass.unwrap_or(Ok(()))
            })
            .and_then(|()| file.end_array());
    }
    Some(
        result
            .and_then(|()| file.begin_points(points))
            .and_then(|()| {
                let pass = each_block(model, step, |b| file.push(b.rows.positions.as_flattened()));
                pass.unwrap_or(Ok(()))
            })
            .and_then(|()| file.end_array())
            .and_then(|()| file.finish()),
    )
}

/// The per-particle quantities of `p` a trajectory frame carries besides its
/// positions, velocities, masses and types: name, values (row-major) and
/// components.
fn particle_arrays(p: &Particles) -> Vec<Column<'_>> {
    let mut arrays = Vec::new();
    if !p.forces.is_empty() {
        arrays.push(("force", Cow::Borrowed(p.forces.as_flattened()), 3));
    }
    if let Some(a) = &p.accelerations {
        arrays.push(("acceleration", Cow::Borrowed(a.as_flattened()), 3));
    }
    if let Some(phi) = &p.potentials {
        arrays.push(("potential", Cow::Borrowed(&phi[..]), 1));
    }
    let ids = p.ids.iter().map(|&i| i as f64).collect();
    arrays.push(("id", Cow::Owned(ids), 1));
    arrays
}

/// GSD type ids of cellist's types (from 1): `type - 1`.
fn type_ids(types: &[u32]) -> Vec<u32> {
    types.iter().map(|&k| k.saturating_sub(1)).collect()
}

/// The GSD type names of types 1 to `most` (one type without types).
fn type_names(most: Option<u32>) -> Vec<String> {
    (1..=most.unwrap_or(1)).map(|k| k.to_string()).collect()
}

/// What a GSD frame of a model's particles holds besides their values, from
/// a first pass over its blocks: the first block's box, count and columns,
/// and the largest type of any block.
struct GsdShape {
    dimension: usize,
    lo: [f64; 3],
    length: [f64; 3],
    n: u64,
    masses: bool,
    typeid: bool,
    extra: Vec<(&'static str, u32)>,
    most: Option<u32>,
}

/// Appends the frame of `model`'s particles at `step` to `writer` a block of
/// rows at a time ([`HoomdBlocks`]): two passes over the blocks, the first
/// for the frame's shape (the type names need the largest type), the second
/// writing; what is held is a block, not the frame (a model spread over
/// ranks pulls its blocks from them). `None` for a model without particles
/// or a frame without any (written whole). The file is that of
/// [`TrajectoryFrame::write_gsd`] of the whole frame.
fn write_gsd_blocks<M: Model + ?Sized>(
    model: &M,
    writer: &mut GsdWriter,
    step: u64,
) -> Option<std::io::Result<()>> {
    let mut shape: Option<GsdShape> = None;
    let scanned = each_block(model, step, |block| {
        let p = block.rows;
        let most = p.types.iter().max().copied();
        match &mut shape {
            Some(shape) => shape.most = shape.most.max(most),
            None => {
                shape = Some(GsdShape {
                    dimension: p.dimension,
                    lo: p.lo,
                    length: std::array::from_fn(|a| p.hi[a] - p.lo[a]),
                    n: block.total as u64,
                    masses: p.masses.is_some(),
                    typeid: !p.types.is_empty(),
                    extra: particle_arrays(p)
                        .into_iter()
                        .map(|(name, _, components)| (name, components as u32))
                        .collect(),
                    most,
                })
            }
        }
        Ok(())
    })?;
    let shape = match (scanned, shape) {
        (Err(e), _) => return Some(Err(e)),
        (Ok(()), None) => return None,
        (Ok(()), Some(shape)) => shape,
    };
    let names = type_names(shape.most);
    let head = HoomdHead {
        step,
        dimensions: shape.dimension as u8,
        box_lengths: shape.length,
        lo: shape.lo,
        n: shape.n,
        velocities: true,
        masses: shape.masses,
        typeid: shape.typeid,
        types: &names,
        extra: &shape.extra,
    };
    let mut frame = match HoomdBlocks::begin(writer, head) {
        Ok(frame) => frame,
        Err(e) => return Some(Err(e)),
    };
    let written = each_block(model, step, |block| {
        let p = block.rows;
        let arrays = particle_arrays(p);
        let extra = shape
            .extra
            .iter()
            .map(|(name, _)| {
                let found = arrays.iter().find(|(n, _, _)| n == name);
                found
                    .map(|(_, v, _)| &v[..])
                    .ok_or_else(|| missing_column(name))
            })
            .collect::<std::io::Result<Vec<&[f64]>>>()?;
        let typeid = shape.typeid.then(|| type_ids(&p.types));
        frame.push(&HoomdRows {
            positions: &p.positions,
            velocities: Some(&p.velocities),
            masses: p.masses.as_deref(),
            typeid: typeid.as_deref(),
            extra: &extra,
        })
    });
    Some(written.unwrap_or(Ok(())).and_then(|()| frame.end()))
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

    /// A model's particles a block at a time (`write_gsd_blocks`), or the
    /// particles carrying its field.
    fn observe(&mut self, model: &M, step: u64, _last: u64, _bar: &ProgressBar) -> SimResult {
        let written = match write_gsd_blocks(model, &mut self.writer, step) {
            Some(written) => written,
            None => {
                TrajectoryFrame::required(model, step, "GSD")?.write_gsd(&mut self.writer, step)
            }
        };
        written.map_err(SimError::output(self.path.display().to_string()))
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

    /// A model's particles a block at a time (`write_vtp_blocks`), or the
    /// particles carrying its field; then the index.
    fn observe(&mut self, model: &M, step: u64, _last: u64, _bar: &ProgressBar) -> SimResult {
        let path = self.dir.join(self.frame_name(step));
        let written = match write_vtp_blocks(model, &path, step) {
            Some(written) => written,
            None => TrajectoryFrame::required(model, step, "VTK")?.write_vtp(&path),
        };
        written.map_err(SimError::output(path.display().to_string()))?;
        let entries = self
            .frames_up_to(step)
            .map_err(SimError::output(self.dir.display().to_string()))?;
        write_pvd(&self.index, &entries).map_err(SimError::output(self.index.display().to_string()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use cellist::models::{Blowup, Checked, Ids, ModelInfo, ParticleBlock};
    use cellist::state::{SectionSource, State, StateError};
    use cellist::Threads;
    use std::ops::{ControlFlow, Range};
    use std::time::Duration;

    const INFO: ModelInfo = ModelInfo {
        name: "blocks",
        particle: "particle",
        thermo_columns: &[],
        remedy: "",
        count_may_change: false,
    };

    /// A frame handed out in the blocks `cuts` (an empty one as a spread
    /// model's id range without atoms gives it: no forces, no types); never
    /// stepped.
    struct Blocks {
        frame: Particles,
        cuts: Vec<Range<usize>>,
    }

    impl Blocks {
        fn rows(&self, cut: &Range<usize>) -> Particles {
            let f = &self.frame;
            let box_only = Particles {
                dimension: f.dimension,
                lo: f.lo,
                hi: f.hi,
                periodic: f.periodic,
                masses: Some(Vec::new()),
                ..Particles::default()
            };
            if cut.is_empty() {
                return box_only;
            }
            let r = cut.clone();
            Particles {
                ids: f.ids[r.clone()].to_vec(),
                types: f.types[r.clone()].to_vec(),
                positions: f.positions[r.clone()].to_vec(),
                velocities: f.velocities[r.clone()].to_vec(),
                forces: f.forces[r.clone()].to_vec(),
                masses: f.masses.as_ref().map(|m| m[r].to_vec()),
                ..box_only
            }
        }
    }

    impl Model for Blocks {
        fn info(&self) -> &ModelInfo {
            &INFO
        }
        fn len(&self) -> usize {
            self.frame.ids.len()
        }
        fn dt(&self) -> f64 {
            0.5
        }
        fn step(&mut self, step: u64, _: &Threads) -> Result<(), Blowup> {
            Err(Blowup::new(step, "never stepped", ""))
        }
        fn thermo(&self, _: u64) -> Vec<f64> {
            Vec::new()
        }
        fn checked(&self) -> Checked<'_> {
            Checked::new(Ids::Index, Vec::new())
        }
        fn particles(&self, _: u64, _: bool) -> Option<Particles> {
            Some(self.frame.clone())
        }
        fn particle_blocks(
            &self,
            _: u64,
            _: bool,
            visit: &mut dyn FnMut(ParticleBlock<'_>) -> ControlFlow<()>,
        ) -> bool {
            for cut in &self.cuts {
                let rows = self.rows(cut);
                let block = ParticleBlock {
                    total: self.len(),
                    first: cut.start,
                    rows: &rows,
                };
                if visit(block).is_break() {
                    break;
                }
            }
            true
        }
        fn stage_times(&self) -> Vec<(&'static str, Duration)> {
            Vec::new()
        }
        fn save(&self, _: &mut State) {}
        fn restore(&mut self, _: &dyn SectionSource, _: &Threads) -> Result<(), StateError> {
            Ok(())
        }
    }

    /// 11 particles of types 1 to 3 in 2D, one with a speed that is not
    /// finite (its VTK velocity array goes binary), cut into blocks of 4
    /// with an empty block in the middle.
    fn blocks() -> Blocks {
        let n = 11;
        let frame = Particles {
            dimension: 2,
            lo: [0.0, 0.0, -0.5],
            hi: [10.0, 5.0, 0.5],
            periodic: [true, true, false],
            ids: (1..=n as u64).collect(),
            types: (0..n).map(|k| 1 + (k % 3) as u32).collect(),
            positions: (0..n)
                .map(|k| [0.9 * k as f64, 0.4 * k as f64, 0.0])
                .collect(),
            velocities: (0..n)
                .map(|k| [if k == 6 { f64::NAN } else { k as f64 }, -0.5, 0.0])
                .collect(),
            forces: (0..n).map(|k| [1.0 / (k + 1) as f64, 2.0, 0.0]).collect(),
            masses: Some((0..n).map(|k| 1.0 + k as f64).collect()),
            ..Particles::default()
        };
        Blocks {
            frame,
            cuts: vec![0..4, 4..4, 4..8, 8..11],
        }
    }

    /// A frame written a block at a time, an empty block among them, is
    /// the GSD and VTK file of the whole frame at once, byte for byte.
    #[test]
    fn frames_in_blocks_are_the_whole_frames_files() {
        let model = blocks();
        let whole = TrajectoryFrame::of(&model, 3).unwrap();
        let dir = tempfile::tempdir().unwrap();
        let path = |name: &str| dir.path().join(name);
        let mut writer = GsdWriter::create(&path("whole.gsd")).unwrap();
        whole.write_gsd(&mut writer, 3).unwrap();
        let mut writer = GsdWriter::create(&path("blocks.gsd")).unwrap();
        write_gsd_blocks(&model, &mut writer, 3).unwrap().unwrap();
        whole.write_vtp(&path("whole.vtp")).unwrap();
        write_vtp_blocks(&model, &path("blocks.vtp"), 3)
            .unwrap()
            .unwrap();
        for (a, b) in [("whole.gsd", "blocks.gsd"), ("whole.vtp", "blocks.vtp")] {
            let (a, b) = (
                std::fs::read(path(a)).unwrap(),
                std::fs::read(path(b)).unwrap(),
            );
            assert!(a == b, "{} bytes against {}", a.len(), b.len());
        }
        let vtp = std::fs::read_to_string(path("blocks.vtp")).unwrap();
        assert!(vtp.contains(r#"Name="velocity" NumberOfComponents="3" format="binary""#));
        assert!(vtp.contains(r#"Name="mass" NumberOfComponents="1" format="ascii""#));
    }

    /// A frame without particles (no block, as a spread model of none
    /// gives it) is left to the whole frame's writer.
    #[test]
    fn a_frame_without_blocks_is_written_whole() {
        let mut model = blocks();
        model.cuts.clear();
        let dir = tempfile::tempdir().unwrap();
        let mut writer = GsdWriter::create(&dir.path().join("t.gsd")).unwrap();
        assert!(write_gsd_blocks(&model, &mut writer, 0).is_none());
        assert!(write_vtp_blocks(&model, &dir.path().join("t.vtp"), 0).is_none());
    }
}
