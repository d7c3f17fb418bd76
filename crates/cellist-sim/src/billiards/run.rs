//! `cellist billiards run`: the collision benchmark's input run on the same
//! launch path as `cellist run` (restart checks, observers, checkpoints,
//! blow-up stops, timings on standard error), with the benchmark's own
//! outputs: its trajectory file (`--viz`), its GIF animation, the final
//! picture and the final state.

use super::{billiards_job, load};
use crate::error::{SimError, SimResult};
use crate::launch::{execute, RunContext};
use crate::observers::{open_stream, Every, Observer, Outputs, Recorded, SnapshotFiles, Snapshots};
use crate::scenario::keys::CheckpointKeys;
use cellist::models::billiards::{BilliardsModel, CellShape};
use cellist::Threads;
use cellist_io::{
    palette_rgb, write_chart, write_state, AtomicFile, DiscPainter, FieldChart, StateFormat,
    StreamFile,
};
use indicatif::ProgressBar;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// What `cellist billiards run` asks for.
pub struct BilliardsRun<'a> {
    /// The `.in` file.
    pub input: &'a Path,
    /// Steps (default: the input's S).
    pub steps: Option<u64>,
    /// The bound on sweeps per step.
    pub max_sweeps: u64,
    /// The cells of the contact search (the bits are the same either way).
    pub cells: CellShape,
    /// The number format of state files.
    pub format: StateFormat,
    /// The trajectory file: every step's state.
    pub viz: Option<&'a Path>,
    /// A GIF animation.
    pub gif: Option<&'a Path>,
    /// A PNG of the final state.
    pub png: Option<&'a Path>,
    /// The final state (default: standard output).
    pub output: Option<&'a Path>,
    /// Steps between GIF frames (default: about 200 frames).
    pub frame_every: Option<u64>,
    /// Picture size in pixels.
    pub picture_size: u32,
    /// Checkpoints: the file and the steps between them.
    pub checkpoint: Option<(PathBuf, u64)>,
    /// A checkpoint to continue from.
    pub restart: Option<&'a Path>,
}

/// The outputs of `cellist billiards run` while it steps: the trajectory file
/// and the animation, named as the user gave them (not in an output folder).
struct DiscOutputs<'a> {
    run: &'a BilliardsRun<'a>,
    /// The initial state: the view and colour scale of every picture.
    initial: &'a BilliardsModel,
    /// Steps between GIF frames.
    frame_every: u64,
}

impl Outputs<BilliardsModel> for DiscOutputs<'_> {
    fn observers(
        &self,
        _model: &BilliardsModel,
        dir: &Path,
        recorded: Recorded,
        _quiet: bool,
    ) -> SimResult<Vec<Box<dyn Observer<BilliardsModel>>>> {
        let mut list: Vec<Box<dyn Observer<BilliardsModel>>> = Vec::new();
        if let Some(path) = self.run.viz {
            let name = path.to_string_lossy().into_owned();
            let (file, _) = open_stream(dir, &name, recorded)?;
            list.push(Box::new(States {
                name,
                file,
                format: self.run.format,
            }));
        }
        if let Some(path) = self.run.gif {
            // the view and colour scale are the initial state's, also after a restart
            let chart = DiscChart::new(self.initial, self.run.picture_size);
            let every = Every {
                every: self.frame_every,
                file: path.to_path_buf(),
            };
            let colours = &DiscPainter::palette()[..3 * DiscPainter::COLOURS];
            let files = SnapshotFiles {
                gif: Some(every),
                ..SnapshotFiles::default()
            };
            let snapshots = Snapshots::open(dir, files, &chart.frame, colours, recorded)?;
            list.push(Box::new(Animation { chart, snapshots }));
        }
        Ok(list)
    }
}

/// Every step's state in the benchmark's format (`--viz`).
struct States {
    name: String,
    file: StreamFile,
    format: StateFormat,
}

impl Observer<BilliardsModel> for States {
    fn due(&self, step: u64, _last: u64) -> bool {
        step > 0
    }

    fn observe(
        &mut self,
        model: &BilliardsModel,
        step: u64,
        _last: u64,
        _bar: &ProgressBar,
    ) -> SimResult {
        let s = &model.system;
        write_state(
            self.file.writer(),
            self.format,
            step,
            &model.ids,
            &s.x,
            &s.y,
            &s.v,
        )
        .map_err(SimError::output(self.name.clone()))
    }

    fn sync(&mut self) -> SimResult<Vec<(String, u64)>> {
        let length = self
            .file
            .sync()
            .map_err(SimError::output(self.name.clone()))?;
        Ok(vec![(self.name.clone(), length)])
    }

    fn finish(&mut self) -> SimResult {
        self.file
            .sync()
            .map(drop)
            .map_err(SimError::output(self.name.clone()))
    }
}

/// Frames of the discs coloured by speed (`--gif`): the chart of the final
/// picture, the step in the title.
struct Animation {
    chart: DiscChart,
    snapshots: Snapshots,
}

impl Observer<BilliardsModel> for Animation {
    fn due(&self, step: u64, last: u64) -> bool {
        self.snapshots.due(step, last)
    }

    fn observe(
        &mut self,
        model: &BilliardsModel,
        step: u64,
        last: u64,
        _bar: &ProgressBar,
    ) -> SimResult {
        let pixels = self
            .chart
            .render(model, step)
            .map_err(SimError::output("a GIF frame of the discs"))?;
        self.snapshots.write(step, last, &self.chart.frame, &pixels)
    }

    fn sync(&mut self) -> SimResult<Vec<(String, u64)>> {
        self.snapshots.sync()
    }

    fn finish(&mut self) -> SimResult {
        self.snapshots.finish()
    }
}

fn painter(model: &BilliardsModel, size: u32) -> DiscPainter {
    let s = &model.system;
    let top_speed =
        s.v.iter()
            .map(|v| (v[0] * v[0] + v[1] * v[1]).sqrt())
            .fold(0.0, f64::max);
    let table = *s.table();
    DiscPainter::new(size, table.side_f(), table.radius_f(), top_speed)
}

/// The chart of the discs: the box with axes, the step in the title and the
/// speed colour bar, the view and colour scale of the initial state (also after
/// a restart).
struct DiscChart {
    frame: FieldChart,
    painter: DiscPainter,
}

impl DiscChart {
    /// The chart of `initial`'s table, at least `size` pixels wide.
    fn new(initial: &BilliardsModel, size: u32) -> Self {
        let (lo, side) = painter(initial, size).view();
        let mut frame = FieldChart::new(lo, side, 0.0, 1.0);
        frame.width = frame.width.max(size);
        frame.unit = "input length units".into();
        frame.value_label = "speed |v| (length per step)".into();
        let (_, n) = frame.plot_area();
        DiscChart {
            frame,
            painter: painter(initial, n),
        }
    }

    /// The RGB pixels of the chart of `model` after `step`.
    fn render(&mut self, model: &BilliardsModel, step: u64) -> std::io::Result<Vec<u8>> {
        self.frame.title = format!("discs after step {step}");
        let palette = DiscPainter::palette();
        let s = &model.system;
        let field = palette_rgb(self.painter.render(&s.x, &s.y, &s.v), &palette);
        let painter = &self.painter;
        self.frame
            .render_painted(field, (0.0, painter.top_speed()), |speed| {
                palette_rgb(&[painter.speed_index(speed)], &palette)
                    .try_into()
                    .expect("three bytes")
            })
    }
}

/// The discs at the end of the run as a chart ([`DiscChart`]).
fn final_picture(
    path: &Path,
    initial: &BilliardsModel,
    model: &BilliardsModel,
    steps: u64,
    size: u32,
) -> std::io::Result<()> {
    let mut chart = DiscChart::new(initial, size);
    let pixels = chart.render(model, steps)?;
    write_chart(path, &chart.frame, &pixels)
}

/// Runs the benchmark on the launch path of every run, then writes the final
/// picture and state.
pub fn run(run: &BilliardsRun, threads: &Threads) -> SimResult {
    if run.frame_every == Some(0) {
        return Err(SimError::Input("--frame-every must be at least 1".into()));
    }
    if run
        .checkpoint
        .as_ref()
        .is_some_and(|(_, every)| *every == 0)
    {
        return Err(SimError::Input(
            "--checkpoint-every must be at least 1".into(),
        ));
    }
    if !(16..=4096).contains(&run.picture_size) {
        return Err(SimError::Input(format!(
            "--picture-size must be between 16 and 4096 pixels, got {}",
            run.picture_size
        )));
    }
    let (input, system) = load(run.input, run.max_sweeps, run.cells)?;
    let steps = run.steps.unwrap_or(input.steps);
    let initial = BilliardsModel::new(system.clone(), input.ids.clone());
    let checkpoint = run.checkpoint.as_ref().map(|(file, every)| CheckpointKeys {
        every: *every,
        file: file.clone(),
    });
    let mut job = billiards_job(&input, system, PathBuf::new(), checkpoint);
    job.steps = steps;
    let outputs = DiscOutputs {
        run,
        initial: &initial,
        frame_every: run.frame_every.unwrap_or(steps.div_ceil(200).max(1)),
    };
    let context = RunContext::new(PathBuf::new(), run.restart, threads).on_stderr();
    let (_, model) = execute(job, &outputs, &context, Instant::now())?;
    if let Some(path) = run.png {
        final_picture(path, &initial, &model, steps, run.picture_size)
            .map_err(SimError::output(path.display().to_string()))?;
    }
    write_final(run, steps, &model)
}

fn write_final(run: &BilliardsRun, steps: u64, model: &BilliardsModel) -> SimResult {
    let s = &model.system;
    match run.output {
        Some(path) => {
            let mut file =
                AtomicFile::create(path).map_err(SimError::output(path.display().to_string()))?;
            write_state(
                file.writer(),
                run.format,
                steps,
                &model.ids,
                &s.x,
                &s.y,
                &s.v,
            )
            .and_then(|()| file.commit())
            .map_err(SimError::output(path.display().to_string()))
        }
        None => {
            let mut out = std::io::BufWriter::new(std::io::stdout().lock());
            write_state(&mut out, run.format, steps, &model.ids, &s.x, &s.y, &s.v)
                .and_then(|()| out.flush())
                .map_err(SimError::output("the final state"))
        }
    }
}
