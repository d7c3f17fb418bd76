//! Pictures: a chart rendered after a step becomes PNG snapshots and GIF
//! frames ([`Snapshots`], written once for every picture observer), and the
//! pictures of bodies (any model with particles: positions projected on a
//! plane, coloured by speed, the time in the title).

use super::observer::{due, each_block, Every, Observer, Recorded};
use crate::error::{SimError, SimResult};
use cellist::models::Model;
use cellist_io::{write_chart, BodyChart, ChartPalette, FieldChart, GifAnimation};
use indicatif::ProgressBar;
use std::path::{Path, PathBuf};

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

/// The pictures a chart is written as: PNG snapshots on their steps (a file
/// per step, [`snapshot_path`]), one PNG of the last step, GIF frames on
/// theirs.
#[derive(Clone, Debug, Default)]
pub struct SnapshotFiles {
    /// PNG snapshots.
    pub png: Option<Every>,
    /// One PNG of the last step, under this name.
    pub final_png: Option<PathBuf>,
    /// The GIF animation.
    pub gif: Option<Every>,
}

/// Where a chart's pictures go ([`SnapshotFiles`]), its animation open.
pub struct Snapshots {
    dir: PathBuf,
    png: Option<Every>,
    final_png: Option<PathBuf>,
    gif: Option<(Every, ChartAnimation)>,
}

impl Snapshots {
    /// The `files` of the charts `frame` in `dir`, their colours `palette` (RGB
    /// triples), continuing the animation a checkpoint `recorded`.
    pub fn open(
        dir: &Path,
        files: SnapshotFiles,
        frame: &FieldChart,
        palette: &[u8],
        recorded: Recorded,
    ) -> SimResult<Self> {
        let SnapshotFiles {
            png,
            final_png,
            gif,
        } = files;
        let gif = match gif {
            Some(g) => {
                let size = [frame.picture_width(), frame.height()];
                let name = g.file.to_string_lossy().into_owned();
                let animation = ChartAnimation::open(dir, &name, recorded, size, palette)?;
                Some((g, animation))
            }
            None => None,
        };
        Ok(Snapshots {
            dir: dir.to_path_buf(),
            png,
            final_png,
            gif,
        })
    }

    /// True when a picture is due after `step` of a run ending at `last`.
    pub fn due(&self, step: u64, last: u64) -> bool {
        due(&self.png, step, last)
            || (self.final_png.is_some() && step == last)
            || self.gif.as_ref().is_some_and(|(g, _)| g.due(step, last))
    }

    /// Writes the chart `frame` rendered after `step` as `pixels` (RGB): the
    /// PNGs and the GIF frame due at `step`.
    pub fn write(&mut self, step: u64, last: u64, frame: &FieldChart, pixels: &[u8]) -> SimResult {
        let mut paths = Vec::new();
        if let Some(p) = self.png.as_ref().filter(|p| p.due(step, last)) {
            paths.push(snapshot_path(&self.dir, &p.file, step, last));
        }
        if let Some(file) = self.final_png.as_ref().filter(|_| step == last) {
            paths.push(self.dir.join(file));
        }
        for path in paths {
            write_chart(&path, frame, pixels)
                .map_err(SimError::output(path.display().to_string()))?;
        }
        if let Some((_, animation)) = self.gif.as_mut().filter(|(g, _)| g.due(step, last)) {
            animation.add(pixels, 8)?;
        }
        Ok(())
    }

    /// Flushes the animation, if there is one, and returns its name and
    /// length for a checkpoint.
    pub fn sync(&mut self) -> SimResult<Vec<(String, u64)>> {
        match self.gif.as_mut() {
            Some((_, animation)) => Ok(vec![animation.sync()?]),
            None => Ok(Vec::new()),
        }
    }

    /// Completes the animation, if there is one.
    pub fn finish(&mut self) -> SimResult {
        match self.gif.take() {
            Some((_, animation)) => animation.finish(),
            None => Ok(()),
        }
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
    chart: BodyChart,
    snapshots: Snapshots,
}

impl BodyPictures {
    /// The pictures `plan` asks for, written to `dir` (continuing the animation a
    /// checkpoint `recorded`).
    pub fn new(plan: &BodyPlan, dir: &Path, recorded: Recorded) -> SimResult<Self> {
        let chart = plan.chart.clone();
        let files = SnapshotFiles {
            png: plan.png.clone(),
            final_png: plan.final_png.clone(),
            gif: plan.gif.clone(),
        };
        let palette = BodyChart::palette();
        let snapshots = Snapshots::open(dir, files, &chart.frame, &palette, recorded)?;
        Ok(BodyPictures { chart, snapshots })
    }
}

impl<M: Model> Observer<M> for BodyPictures {
    fn due(&self, step: u64, last: u64) -> bool {
        self.snapshots.due(step, last)
    }

    /// Paints the model's particles a block at a time ([`cellist_io::BodyCanvas`]): what
    /// is held is the picture, not the particles (a model spread over ranks
    /// pulls its blocks from them).
    fn observe(&mut self, model: &M, step: u64, last: u64, _bar: &ProgressBar) -> SimResult {
        let mut canvas = self.chart.canvas();
        let painted = each_block(model, step, |block| {
            let rows = block.rows;
            canvas.add(block.first, &rows.positions, &rows.velocities)
        });
        let Some(painted) = painted else {
            return Err(SimError::Internal(format!(
                "model {} has no particles to draw",
                model.info().name
            )));
        };
        painted.map_err(SimError::output("a picture of the bodies"))?;
        let outside = canvas.outside();
        let painted = canvas.pixels();
        let mut title = snapshot_title("bodies", step, model.dt());
        if outside > 0 {
            title += &format!(", {outside} outside");
        }
        self.chart.frame.title = title;
        let pixels = self
            .chart
            .render_painted(painted)
            .map_err(SimError::output("a picture of the bodies"))?;
        self.snapshots.write(step, last, &self.chart.frame, &pixels)
    }

    fn sync(&mut self) -> SimResult<Vec<(String, u64)>> {
        self.snapshots.sync()
    }

    fn finish(&mut self) -> SimResult {
        self.snapshots.finish()
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
