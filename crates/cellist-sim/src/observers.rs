//! Observers: what the driver does after a step when their trigger fires. Each is
//! written once and works for every model that declares what it needs: thermo
//! rows (and the plot drawn from them), LAMMPS and extended XYZ dumps, field files
//! and pictures. Files that grow as the run goes are [`StreamFile`]s, so that a
//! restart continues them from the lengths its checkpoint recorded.

use crate::error::{SimError, SimResult};
use crate::progress::print_above;
use crate::trajectory::{GsdTrajectory, TrajectoryKeys, VtkSeries};
use cellist::models::{Field, Model, Particles};
use cellist_io::plot::{line_chart, Series};
use cellist_io::{
    format_g17, write_chart, write_field_columns, write_lammps_frame, write_xyz_frame, AtomicFile,
    BodyChart, ChartPalette, FieldChart, FieldPainter, Frame, GifAnimation, StreamFile,
};
use indicatif::ProgressBar;
use std::io::Write;
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

/// Opens the GIF animation `dir/name` of `width` x `height` frames in `palette`:
/// continued from its recorded length when the checkpoint recorded it and it
/// exists, else new.
pub fn open_animation(
    dir: &Path,
    name: &str,
    recorded: Recorded,
    [width, height]: [u32; 2],
    palette: &[u8],
) -> SimResult<GifAnimation> {
    let path = dir.join(name);
    let what = path.display().to_string();
    match recorded.iter().find(|(n, _)| n == name) {
        Some((_, length)) if path.exists() => {
            GifAnimation::resume(&path, *length, width, height, palette).map_err(|e| {
                match e.kind() {
                    std::io::ErrorKind::InvalidData => SimError::Input(e.to_string()),
                    _ => SimError::Output(e, what),
                }
            })
        }
        _ => GifAnimation::create(&path, width, height, palette).map_err(SimError::output(what)),
    }
}

/// An animation of annotated charts: the GIF, its palette and the frame's
/// indices (kept between frames).
pub struct ChartAnimation {
    name: String,
    gif: GifAnimation,
    palette: ChartPalette,
    indices: Vec<u8>,
}

/// Flushes an observer's animation, if it has one, and returns its name and
/// length for a checkpoint.
fn sync_animation(gif: &mut Option<(Every, ChartAnimation)>) -> SimResult<Vec<(String, u64)>> {
    match gif.as_mut() {
        Some((_, animation)) => Ok(vec![animation.sync()?]),
        None => Ok(Vec::new()),
    }
}

/// Completes an observer's animation, if it has one.
fn finish_animation(gif: &mut Option<(Every, ChartAnimation)>) -> SimResult {
    match gif.take() {
        Some((_, animation)) => animation.finish(),
        None => Ok(()),
    }
}

impl ChartAnimation {
    /// The animation `dir/name` of charts of `width` x `height` pixels painted in
    /// the colours `data` (RGB triples), continued if `recorded` says so
    /// ([`open_animation`]).
    pub fn open(
        dir: &Path,
        name: &str,
        recorded: Recorded,
        size: [u32; 2],
        data: &[u8],
    ) -> SimResult<Self> {
        let palette = ChartPalette::new(data);
        let gif = open_animation(dir, name, recorded, size, palette.rgb())?;
        Ok(ChartAnimation {
            name: name.to_string(),
            gif,
            palette,
            indices: Vec::new(),
        })
    }

    /// Appends the chart's RGB `pixels` as a frame shown for `delay` hundredths
    /// of a second.
    pub fn add(&mut self, pixels: &[u8], delay: u16) -> SimResult {
        self.palette.indices_into(pixels, &mut self.indices);
        self.gif
            .add_frame(&self.indices, delay)
            .map_err(SimError::output(self.name.clone()))
    }

    /// Flushes the frames so far; returns the file's name and length.
    pub fn sync(&mut self) -> SimResult<(String, u64)> {
        let length = self
            .gif
            .sync()
            .map_err(SimError::output(self.name.clone()))?;
        Ok((self.name.clone(), length))
    }

    /// Ends the animation.
    pub fn finish(self) -> SimResult {
        self.gif.finish().map_err(SimError::output(self.name))
    }
}

/// The title of a snapshot of `what` after `step` steps of `dt`: `"<what> at t =
/// <time> (step <step>)"`, the time with as many decimals as `dt` needs, so that
/// titles of one run have one width.
pub fn snapshot_title(what: &str, step: u64, dt: f64) -> String {
    let decimals = if dt > 0.0 && dt.is_finite() {
        ((-dt.log10() - 1e-9).ceil().max(0.0) as usize).min(12)
    } else {
        3
    };
    format!(
        "{what} at t = {:.decimals$} (step {step})",
        step as f64 * dt
    )
}

fn sync_one(file: &mut StreamFile, name: &str) -> SimResult<(String, u64)> {
    let length = file
        .sync()
        .map_err(SimError::output(file.path().display().to_string()))?;
    Ok((name.to_string(), length))
}

/// How the thermo table prints: columns of `width` characters, numbers with
/// `precision` digits in fixed or exponent form, the first `shown` value columns.
#[derive(Clone, Copy, Debug)]
pub struct TableStyle {
    /// Characters per column.
    pub width: usize,
    /// Digits after the point.
    pub precision: usize,
    /// Exponent form (`1.5e-3`) rather than fixed.
    pub exponent: bool,
    /// Value columns shown on the terminal (the CSV has all).
    pub shown: usize,
}

/// A line chart of thermo columns against time, drawn at the end of the run.
#[derive(Clone, Debug)]
pub struct PlotSpec {
    /// File name in the output folder.
    pub file: &'static str,
    /// Title.
    pub title: &'static str,
    /// Label of the time axis.
    pub x_label: &'static str,
    /// Label of the value axis.
    pub y_label: &'static str,
    /// `(legend, thermo column, plot |value|)` per curve.
    pub series: Vec<(&'static str, &'static str, bool)>,
}

/// The thermo rows: `thermo.csv` (`step` and the model's columns at `%.17g`), the
/// table on the terminal, and the plot at the end.
pub struct Thermo {
    every: u64,
    columns: Vec<&'static str>,
    style: TableStyle,
    file: StreamFile,
    dt: f64,
    rows: Vec<(u64, Vec<f64>)>,
    plot: Option<PlotSpec>,
    dir: PathBuf,
    quiet: bool,
}

const THERMO_FILE: &str = "thermo.csv";

impl Thermo {
    /// Thermo every `every` steps (and at the first and last) of `model`, the
    /// rows of a continued file read back for the plot; `quiet` prints no table.
    pub fn new<M: Model>(
        model: &M,
        every: u64,
        style: TableStyle,
        plot: Option<PlotSpec>,
        dir: &Path,
        recorded: Recorded,
        quiet: bool,
    ) -> SimResult<Self> {
        let mut columns = vec!["step"];
        columns.extend_from_slice(model.info().thermo_columns);
        let (mut file, continued) = open_stream(dir, THERMO_FILE, recorded)?;
        let rows = if continued {
            read_rows(&dir.join(THERMO_FILE), columns.len())?
        } else {
            writeln!(file.writer(), "{}", columns.join(","))
                .map_err(SimError::output(THERMO_FILE))?;
            Vec::new()
        };
        let header: String = columns[..=style.shown]
            .iter()
            .map(|c| format!("{c:>w$}", w = style.width))
            .collect();
        if !quiet {
            println!("{header}");
        }
        Ok(Thermo {
            every,
            columns,
            style,
            file,
            dt: model.dt(),
            rows,
            plot,
            dir: dir.to_path_buf(),
            quiet,
        })
    }

    fn draw_plot(&self, plot: &PlotSpec) -> SimResult {
        let curves: Vec<Vec<(f64, f64)>> = plot
            .series
            .iter()
            .map(|&(_, column, abs)| {
                let c = self
                    .columns
                    .iter()
                    .position(|n| *n == column)
                    .expect("a thermo column")
                    - 1;
                self.rows
                    .iter()
                    .map(|(step, v)| (*step as f64 * self.dt, if abs { v[c].abs() } else { v[c] }))
                    .collect()
            })
            .collect();
        let series: Vec<Series> = plot
            .series
            .iter()
            .zip(&curves)
            .map(|(&(label, _, _), points)| Series::line(label, points))
            .collect();
        let path = self.dir.join(plot.file);
        line_chart(&path, plot.title, plot.x_label, plot.y_label, &series)
            .map_err(SimError::chart(&path))
    }
}

/// The rows of a thermo CSV (after its header).
fn read_rows(path: &Path, columns: usize) -> SimResult<Vec<(u64, Vec<f64>)>> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| SimError::Input(format!("{}: cannot read: {e}", path.display())))?;
    let bad = |line: usize| {
        SimError::Input(format!(
            "{}:{line}: not a thermo row of {columns} numbers; the file does not continue the checkpoint's run",
            path.display()
        ))
    };
    let mut rows = Vec::new();
    for (k, line) in text.lines().enumerate().skip(1) {
        let mut fields = line.split(',');
        let step = fields
            .next()
            .and_then(|s| s.parse::<u64>().ok())
            .ok_or_else(|| bad(k + 1))?;
        let values: Vec<f64> = fields
            .map(|f| f.parse::<f64>())
            .collect::<Result<_, _>>()
            .map_err(|_| bad(k + 1))?;
        if values.len() + 1 != columns {
            return Err(bad(k + 1));
        }
        rows.push((step, values));
    }
    Ok(rows)
}

impl<M: Model> Observer<M> for Thermo {
    fn due(&self, step: u64, last: u64) -> bool {
        step == 0 || step == last || (self.every > 0 && step % self.every == 0)
    }

    fn needs_observables(&self, step: u64, last: u64) -> bool {
        <Self as Observer<M>>::due(self, step, last)
    }

    fn observe(&mut self, model: &M, step: u64, _last: u64, bar: &ProgressBar) -> SimResult {
        let values = model.thermo(step);
        let mut line = step.to_string();
        for &v in &values {
            line.push(',');
            format_g17(v, &mut line);
        }
        writeln!(self.file.writer(), "{line}").map_err(SimError::output(THERMO_FILE))?;
        let TableStyle {
            width: w,
            precision: p,
            exponent,
            shown,
        } = self.style;
        let table = format!("{step:>w$}")
            + &values[..shown]
                .iter()
                .map(|v| {
                    if exponent {
                        format!("{v:>w$.p$e}")
                    } else {
                        format!("{v:>w$.p$}")
                    }
                })
                .collect::<String>();
        if !self.quiet {
            print_above(bar, &table);
        }
        self.rows.push((step, values));
        Ok(())
    }

    fn sync(&mut self) -> SimResult<Vec<(String, u64)>> {
        Ok(vec![sync_one(&mut self.file, THERMO_FILE)?])
    }

    fn finish(&mut self) -> SimResult {
        self.file.sync().map_err(SimError::output(THERMO_FILE))?;
        match &self.plot {
            Some(plot) if self.rows.len() >= 2 => self.draw_plot(plot),
            _ => Ok(()),
        }
    }

    fn take_thermo_rows(&mut self) -> Option<Vec<(u64, Vec<f64>)>> {
        Some(std::mem::take(&mut self.rows))
    }
}

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

/// Snapshots every `every` steps (and at step 0 and the last step) to `file`.
#[derive(Clone, Debug)]
pub struct Every {
    /// The period in steps.
    pub every: u64,
    /// The file name (a pattern for per-step files, see [`snapshot_path`]).
    pub file: PathBuf,
}

impl Every {
    fn due(&self, step: u64, last: u64) -> bool {
        step == 0 || step == last || step % self.every == 0
    }
}

fn due(every: &Option<Every>, step: u64, last: u64) -> bool {
    every.as_ref().is_some_and(|e| e.due(step, last))
}

/// `file` for the snapshot of `step`: a `*` in the name becomes the step, otherwise
/// `_<step>` goes before the extension; the step is zero-padded to the width of the
/// last step, so that the files sort in time order.
pub fn snapshot_path(dir: &Path, file: &Path, step: u64, last: u64) -> PathBuf {
    let width = last.to_string().len();
    let stamp = format!("{step:0width$}");
    let name = file.to_string_lossy();
    let named = if name.contains('*') {
        name.replace('*', &stamp)
    } else {
        match (file.file_stem(), file.extension()) {
            (Some(stem), Some(ext)) => {
                let parent = file.parent().unwrap_or(Path::new(""));
                parent
                    .join(format!(
                        "{}_{stamp}.{}",
                        stem.to_string_lossy(),
                        ext.to_string_lossy()
                    ))
                    .to_string_lossy()
                    .into_owned()
            }
            _ => format!("{name}_{stamp}"),
        }
    };
    dir.join(named)
}

/// Writes a field CSV whole or not at all.
pub fn write_field_csv(path: &Path, field: &Field) -> SimResult {
    let what = || path.display().to_string();
    let mut file = AtomicFile::create(path).map_err(SimError::output(what()))?;
    let mut columns: Vec<(&str, &[f64])> = vec![(field.value_name, &field.values)];
    columns.extend(field.extra.iter().map(|(name, v)| (*name, &v[..])));
    write_field_columns(file.writer(), field.dimension, &field.positions, &columns)
        .map_err(SimError::output(what()))?;
    file.commit().map_err(SimError::output(what()))
}

/// The z of the particle layer a 3D field's pictures show: the layer nearest the
/// middle of the box along z; `None` in 2D.
fn middle_layer(field: &Field) -> Option<f64> {
    (field.dimension == 3).then(|| {
        let middle = field.origin[2] + 0.5 * field.side;
        field
            .positions
            .iter()
            .map(|x| x[2])
            .min_by(|a, b| (a - middle).abs().total_cmp(&(b - middle).abs()))
            .unwrap_or(middle)
    })
}

/// The particles to draw: all of a 2D field; in 3D those within half a spacing
/// of the `layer`.
fn slice(field: &Field, layer: Option<f64>) -> impl Iterator<Item = ([f64; 2], f64)> + '_ {
    field
        .positions
        .iter()
        .zip(&field.values)
        .filter(move |(x, _)| layer.is_none_or(|z| (x[2] - z).abs() < 0.5 * field.spacing))
        .map(|(x, &v)| ([x[0], x[1]], v))
}

/// What the field pictures say: the quantity in the title (followed by the
/// layer in 3D, the time and the step), the colour bar's label and the unit of
/// the axes.
#[derive(Clone, Copy, Debug)]
pub struct ChartLabels {
    /// The title's quantity ("vorticity").
    pub title: &'static str,
    /// The colour bar's label ("ω = Γ/h²").
    pub value: &'static str,
    /// The unit of length of the axes ("simulation units"; empty for none).
    pub unit: &'static str,
}

/// Field snapshots: CSV files, and PNG pictures and GIF frames as charts (the
/// field with axes, the time in the title, a colour bar).
pub struct FieldFiles {
    dir: PathBuf,
    csv: Option<Every>,
    png: Option<Every>,
    gif: Option<(Every, ChartAnimation)>,
    labels: ChartLabels,
    chart: FieldChart,
}

impl FieldFiles {
    /// Snapshots of `model`'s field as `plan` asks for them.
    pub fn new<M: Model>(
        model: &M,
        plan: &FieldPlan,
        dir: &Path,
        recorded: Recorded,
    ) -> SimResult<Self> {
        let FieldPlan {
            csv,
            png,
            gif,
            size,
            chart: labels,
        } = plan.clone();
        let field = model.field().ok_or_else(|| {
            SimError::Internal(format!("model {} has no field", model.info().name))
        })?;
        let lo = [field.origin[0], field.origin[1]];
        let mut chart = FieldChart::new(lo, field.side, field.spacing, field.scale);
        chart.width = chart.width.max(size);
        chart.value_label = labels.value.to_string();
        chart.unit = labels.unit.to_string();
        chart.periodic = field.periodic;
        let gif = match gif {
            Some(g) => {
                let animation = ChartAnimation::open(
                    dir,
                    &g.file.to_string_lossy(),
                    recorded,
                    [chart.picture_width(), chart.height()],
                    &FieldPainter::palette(),
                )?;
                Some((g, animation))
            }
            None => None,
        };
        Ok(FieldFiles {
            dir: dir.to_path_buf(),
            csv,
            png,
            gif,
            labels,
            chart,
        })
    }
}

impl<M: Model> Observer<M> for FieldFiles {
    fn due(&self, step: u64, last: u64) -> bool {
        due(&self.csv, step, last)
            || due(&self.png, step, last)
            || self.gif.as_ref().is_some_and(|(g, _)| g.due(step, last))
    }

    fn observe(&mut self, model: &M, step: u64, last: u64, _bar: &ProgressBar) -> SimResult {
        let field = model.field().expect("a model with a field");
        if let Some(c) = self.csv.as_ref().filter(|c| c.due(step, last)) {
            write_field_csv(&snapshot_path(&self.dir, &c.file, step, last), &field)?;
        }
        let png = self.png.as_ref().filter(|p| p.due(step, last));
        let gif = self.gif.as_mut().filter(|(g, _)| g.due(step, last));
        if png.is_none() && gif.is_none() {
            return Ok(());
        }
        let layer = middle_layer(&field);
        let what = match layer {
            Some(z) => format!("{} in the layer z = {z:.4}", self.labels.title),
            None => self.labels.title.to_string(),
        };
        self.chart.title = snapshot_title(&what, step, model.dt());
        let pixels = self
            .chart
            .render(slice(&field, layer))
            .map_err(SimError::output("a field picture"))?;
        if let Some(p) = png {
            let path = snapshot_path(&self.dir, &p.file, step, last);
            write_chart(&path, &self.chart, &pixels)
                .map_err(SimError::output(path.display().to_string()))?;
        }
        if let Some((_, animation)) = gif {
            animation.add(&pixels, 8)?;
        }
        Ok(())
    }

    fn sync(&mut self) -> SimResult<Vec<(String, u64)>> {
        sync_animation(&mut self.gif)
    }

    fn finish(&mut self) -> SimResult {
        finish_animation(&mut self.gif)
    }
}

/// Pictures of the bodies the scenario asks for.
#[derive(Clone, Debug)]
pub struct BodyPlan {
    /// PNG snapshots at step 0, every `every` steps and the last step (file names
    /// with the step, [`snapshot_path`]).
    pub png: Option<Every>,
    /// One PNG of the last step, under this name.
    pub final_png: Option<PathBuf>,
    /// The GIF animation.
    pub gif: Option<Every>,
    /// The picture: the view and plane, the colour scale and the labels (the
    /// title is set for each picture).
    pub chart: BodyChart,
}

/// Pictures of the bodies (any model with particles): PNG snapshots and GIF
/// frames of the positions projected on a plane, coloured by speed, with the time
/// in the title.
pub struct BodyPictures {
    dir: PathBuf,
    png: Option<Every>,
    final_png: Option<PathBuf>,
    gif: Option<(Every, ChartAnimation)>,
    chart: BodyChart,
}

impl BodyPictures {
    /// The pictures `plan` asks for, written to `dir` (continuing the animation a
    /// checkpoint `recorded`).
    pub fn new(plan: &BodyPlan, dir: &Path, recorded: Recorded) -> SimResult<Self> {
        let chart = plan.chart.clone();
        let gif = match &plan.gif {
            Some(g) => {
                let animation = ChartAnimation::open(
                    dir,
                    &g.file.to_string_lossy(),
                    recorded,
                    [chart.frame.picture_width(), chart.frame.height()],
                    &BodyChart::palette(),
                )?;
                Some((g.clone(), animation))
            }
            None => None,
        };
        Ok(BodyPictures {
            dir: dir.to_path_buf(),
            png: plan.png.clone(),
            final_png: plan.final_png.clone(),
            gif,
            chart,
        })
    }
}

impl<M: Model> Observer<M> for BodyPictures {
    fn due(&self, step: u64, last: u64) -> bool {
        due(&self.png, step, last)
            || (self.final_png.is_some() && step == last)
            || self.gif.as_ref().is_some_and(|(g, _)| g.due(step, last))
    }

    fn observe(&mut self, model: &M, step: u64, last: u64, _bar: &ProgressBar) -> SimResult {
        let Some(particles) = model.particles(step, false) else {
            return Err(SimError::Internal(format!(
                "model {} has no particles to draw",
                model.info().name
            )));
        };
        let (x, v) = (&particles.positions, &particles.velocities);
        let mut title = snapshot_title("bodies", step, model.dt());
        let outside = self.chart.outside(x);
        if outside > 0 {
            title += &format!(", {outside} outside");
        }
        self.chart.frame.title = title;
        let pixels = self
            .chart
            .render(x, v)
            .map_err(SimError::output("a picture of the bodies"))?;
        let mut paths = Vec::new();
        if let Some(p) = self.png.as_ref().filter(|p| p.due(step, last)) {
            paths.push(snapshot_path(&self.dir, &p.file, step, last));
        }
        if let Some(file) = self.final_png.as_ref().filter(|_| step == last) {
            paths.push(self.dir.join(file));
        }
        for path in paths {
            write_chart(&path, &self.chart.frame, &pixels)
                .map_err(SimError::output(path.display().to_string()))?;
        }
        if let Some((_, animation)) = self.gif.as_mut().filter(|(g, _)| g.due(step, last)) {
            animation.add(&pixels, 8)?;
        }
        Ok(())
    }

    fn sync(&mut self) -> SimResult<Vec<(String, u64)>> {
        sync_animation(&mut self.gif)
    }

    fn finish(&mut self) -> SimResult {
        finish_animation(&mut self.gif)
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

/// Field snapshots the scenario asks for.
#[derive(Clone, Debug)]
pub struct FieldPlan {
    /// CSV files.
    pub csv: Option<Every>,
    /// PNG pictures.
    pub png: Option<Every>,
    /// The GIF animation.
    pub gif: Option<Every>,
    /// Picture width in pixels (at least 640).
    pub size: u32,
    /// What the pictures say.
    pub chart: ChartLabels,
}

/// The outputs of a scenario run: thermo, dumps and field snapshots.
#[derive(Clone, Debug)]
pub struct OutputPlan {
    /// Steps between thermo rows (0: the first and last step only).
    pub thermo_every: u64,
    /// The terminal table's format.
    pub table: TableStyle,
    /// The plot of thermo columns.
    pub plot: Option<PlotSpec>,
    /// Dumps.
    pub dumps: Vec<DumpPlan>,
    /// Field snapshots.
    pub field: Option<FieldPlan>,
    /// Pictures of the bodies.
    pub bodies: Option<BodyPlan>,
    /// No thermo table on the terminal (the file and the rows are kept).
    pub quiet: bool,
    /// GSD and VTK trajectories.
    pub trajectories: TrajectoryKeys,
}

impl OutputPlan {
    /// The observers of this plan for `model`, writing to `dir` (continuing the
    /// `recorded` files of a restart).
    pub fn observers<M: Model + 'static>(
        &self,
        model: &M,
        dir: &Path,
        recorded: Recorded,
    ) -> SimResult<Vec<Box<dyn Observer<M>>>> {
        let mut observers: Vec<Box<dyn Observer<M>>> = vec![Box::new(Thermo::new(
            model,
            self.thermo_every,
            self.table,
            self.plot.clone(),
            dir,
            recorded,
            self.quiet,
        )?)];
        for d in &self.dumps {
            observers.push(Box::new(Dump::new(
                d.every,
                &d.file,
                d.columns.clone(),
                d.format,
                dir,
                recorded,
            )?));
        }
        if let Some(f) = &self.field {
            observers.push(Box::new(FieldFiles::new(model, f, dir, recorded)?));
        }
        if let Some(b) = &self.bodies {
            observers.push(Box::new(BodyPictures::new(b, dir, recorded)?));
        }
        if let Some(keys) = &self.trajectories.gsd {
            observers.push(Box::new(GsdTrajectory::new(keys, dir, recorded)?));
        }
        if let Some(keys) = &self.trajectories.vtk {
            observers.push(Box::new(VtkSeries::new(keys, model.dt(), dir)));
        }
        Ok(observers)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn snapshot_titles_show_the_time_to_the_step_size_and_the_step() {
        assert_eq!(
            snapshot_title("bodies", 100, 0.01),
            "bodies at t = 1.00 (step 100)"
        );
        assert_eq!(snapshot_title("φ", 30, 2e-5), "φ at t = 0.00060 (step 30)");
        assert_eq!(snapshot_title("ω", 3, 0.005), "ω at t = 0.015 (step 3)");
        assert_eq!(snapshot_title("x", 2, 1.0), "x at t = 2 (step 2)");
        assert_eq!(snapshot_title("x", 2, 0.0), "x at t = 0.000 (step 2)");
    }
}
