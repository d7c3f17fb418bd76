//! Field files: CSV snapshots of the field the particles carry, and its
//! pictures (the field on a square grid with axes, the time in the title and
//! a colour bar) as PNG snapshots and GIF frames.

use super::observer::{due, Every, Observer, Recorded};
use super::pictures::{snapshot_path, snapshot_title, SnapshotFiles, Snapshots};
use crate::error::{SimError, SimResult};
use cellist::models::{Field, Model};
use cellist_io::{write_field_columns, AtomicFile, FieldChart, FieldPainter};
use indicatif::ProgressBar;
use std::path::{Path, PathBuf};

/// Writes a field CSV whole or not at all.
pub fn write_field_csv(path: &Path, field: &Field) -> SimResult {
    let what = || path.display().to_string();
    let mut file = AtomicFile::create(path).map_err(SimError::output(what()))?;
    let mut columns: Vec<(&str, &[f64])> = Vec::new();
    if field.value_written {
        columns.push((field.value_name, &field.values));
    }
    columns.extend(field.extra.iter().map(|(name, v)| (*name, &v[..])));
    write_field_columns(file.writer(), field.dimension, &field.positions, &columns)
        .map_err(SimError::output(what()))?;
    file.commit().map_err(SimError::output(what()))
}

/// The coordinate along the normal axis (`field.axes[2]`) of the particle
/// layer a 3D field's pictures show: the layer nearest the middle of the box
/// along it; `None` in 2D.
fn middle_layer(field: &Field) -> Option<f64> {
    let normal = field.axes[2];
    (field.dimension == 3).then(|| {
        let middle = field.origin[normal] + 0.5 * field.side;
        field
            .positions
            .iter()
            .map(|x| x[normal])
            .min_by(|a, b| (a - middle).abs().total_cmp(&(b - middle).abs()))
            .unwrap_or(middle)
    })
}

/// The particles to draw, in the picture's axes (`field.axes`): all of a 2D
/// field; in 3D those within half a spacing of the `layer`.
fn slice(field: &Field, layer: Option<f64>) -> impl Iterator<Item = ([f64; 2], f64)> + '_ {
    let [across, up, normal] = field.axes;
    field
        .positions
        .iter()
        .zip(&field.values)
        .filter(move |(x, _)| layer.is_none_or(|z| (x[normal] - z).abs() < 0.5 * field.spacing))
        .map(move |(x, &v)| ([x[across], x[up]], v))
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
    /// The values are magnitudes, never negative: the colour bar runs from 0.
    pub magnitude: bool,
}

/// Field snapshots: CSV files, and PNG pictures and GIF frames as charts (the
/// field with axes, the time in the title, a colour bar).
pub struct FieldFiles {
    dir: PathBuf,
    csv: Option<Every>,
    labels: ChartLabels,
    chart: FieldChart,
    snapshots: Snapshots,
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
        let lo = [field.origin[field.axes[0]], field.origin[field.axes[1]]];
        let mut chart = FieldChart::new(lo, field.side, field.spacing, field.scale);
        chart.width = chart.width.max(size);
        chart.value_label = labels.value.to_string();
        chart.unit = labels.unit.to_string();
        chart.periodic = field.periodic;
        chart.magnitude = labels.magnitude;
        chart.axes = [field.axes[0], field.axes[1]].map(|a| ["x", "y", "z"][a].to_string());
        let palette = FieldPainter::palette();
        let files = SnapshotFiles {
            png,
            final_png: None,
            gif,
        };
        let snapshots = Snapshots::open(dir, files, &chart, &palette, recorded)?;
        Ok(FieldFiles {
            dir: dir.to_path_buf(),
            csv,
            labels,
            chart,
            snapshots,
        })
    }
}

impl<M: Model> Observer<M> for FieldFiles {
    fn due(&self, step: u64, last: u64) -> bool {
        due(&self.csv, step, last) || self.snapshots.due(step, last)
    }

    fn observe(&mut self, model: &M, step: u64, last: u64, _bar: &ProgressBar) -> SimResult {
        let field = model.field().expect("a model with a field");
        if let Some(c) = self.csv.as_ref().filter(|c| c.due(step, last)) {
            write_field_csv(&snapshot_path(&self.dir, &c.file, step, last), &field)?;
        }
        if !self.snapshots.due(step, last) {
            return Ok(());
        }
        let layer = middle_layer(&field);
        let what = match layer {
            Some(z) => {
                // a layer that rounds to 0 is written 0.0000, not -0.0000
                let z = if (z * 1e4).round() == 0.0 { 0.0 } else { z };
                format!(
                    "{} in the layer {} = {z:.4}",
                    self.labels.title,
                    ["x", "y", "z"][field.axes[2]]
                )
            }
            None => self.labels.title.to_string(),
        };
        self.chart.title = snapshot_title(&what, step, model.dt());
        // a view that follows the particles (3D vortex rings) moves its corner
        self.chart.lo = [field.origin[field.axes[0]], field.origin[field.axes[1]]];
        let pixels = self
            .chart
            .render(slice(&field, layer))
            .map_err(SimError::output("a field picture"))?;
        self.snapshots.write(step, last, &self.chart, &pixels)
    }

    fn sync(&mut self) -> SimResult<Vec<(String, u64)>> {
        self.snapshots.sync()
    }

    fn finish(&mut self) -> SimResult {
        self.snapshots.finish()
    }
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
