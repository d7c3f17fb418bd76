//! `cellist billiards run` on the driver: the collision benchmark's input, its
//! trajectory file (`--viz`), its GIF animation, the final picture and state, and
//! checkpoints that restart bit for bit.

mod check;
mod generate;

pub use check::{check, Verdict};
pub use generate::{generate, Generate};

use crate::driver::{self, recorded, CheckpointKeys, Job, LastFrame};
use crate::error::{SimError, SimResult};
use crate::hosted::Hosted;
use crate::observers::{open_stream, ChartAnimation, Observer, OutputPlan, Recorded, TableStyle};
use crate::{RunContext, RunSummary};
use cellist::models::billiards::{Billiards, BilliardsModel, CellShape, Table, DEFAULT_MAX_SWEEPS};

use cellist::Threads;
use cellist_io::{
    palette_rgb, read_billiards_input, write_chart, write_state, AtomicFile, BilliardsInput,
    DiscPainter, FieldChart, StateFormat, StreamFile, DUMP_COLUMNS,
};
use indicatif::ProgressBar;
use std::io::Write;
use std::path::{Path, PathBuf};

/// Reads an input and sets up the table with the bound on sweeps per step and the
/// cells of the contact search (warnings to standard error).
pub fn load(
    path: &Path,
    max_sweeps: u64,
    cells: CellShape,
) -> SimResult<(BilliardsInput, Billiards)> {
    let (input, system) = read(path, max_sweeps, cells)?;
    for w in &input.warnings {
        eprintln!("warning: {w}");
    }
    Ok((input, system))
}

/// [`load`] without printing the input's warnings (they stay in the input).
pub(crate) fn read(
    path: &Path,
    max_sweeps: u64,
    cells: CellShape,
) -> SimResult<(BilliardsInput, Billiards)> {
    let input = read_billiards_input(path)?;
    let table = Table {
        side: input.side,
        radius: input.radius,
    };
    let system = Billiards::new(table, input.x.clone(), input.y.clone(), input.v.clone())
        .map_err(|e| SimError::Input(format!("{}: {e}", path.display())))?
        .with_max_sweeps(max_sweeps)
        .with_cells(cells);
    Ok((input, system))
}

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

/// The table's physics, which a restart must match: the disc count, the box, the
/// radius and the initial state's bits.
fn physics(input: &BilliardsInput) -> Vec<(String, String)> {
    let mut hash: u64 = 0xcbf2_9ce4_8422_2325;
    let bits = input
        .x
        .iter()
        .chain(&input.y)
        .chain(input.v.iter().flatten())
        .map(|v| v.to_bits());
    for b in input.ids.iter().map(|&i| i as u64).chain(bits) {
        for byte in b.to_le_bytes() {
            hash ^= byte as u64;
            hash = hash.wrapping_mul(0x0100_0000_01b3);
        }
    }
    vec![
        ("input.discs".into(), input.ids.len().to_string()),
        ("input.initial_state_fnv1a".into(), format!("{hash:016x}")),
        ("input.radius".into(), input.radius.to_string()),
        ("input.side".into(), input.side.to_string()),
    ]
}

/// The terminal table of the discs' energy.
pub(crate) const ENERGY_TABLE: TableStyle = TableStyle {
    width: 16,
    precision: 8,
    exponent: true,
    shown: 1,
};

/// The dump columns of discs: id, type, x y z, vx vy vz.
pub(crate) fn disc_columns() -> Vec<String> {
    DUMP_COLUMNS[..8].iter().map(|c| c.to_string()).collect()
}

/// The run of `input`'s `system` to its S steps, writing to `dir`, with its
/// physics (for restarts) and its last frame (a LAMMPS dump of the discs).
pub(crate) fn billiards_job(
    input: &BilliardsInput,
    system: Billiards,
    dir: PathBuf,
    checkpoint: Option<CheckpointKeys>,
) -> Job<BilliardsModel> {
    Job {
        model: BilliardsModel::new(system, input.ids.clone()),
        ranks: Default::default(),
        steps: input.steps,
        dir,
        checkpoint,
        physics: physics(input),
        last_frame: LastFrame::Dump {
            file: "last.lammpstrj",
            columns: disc_columns(),
        },
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
    every: u64,
    chart: DiscChart,
    gif: Option<ChartAnimation>,
}

impl Observer<BilliardsModel> for Animation {
    fn due(&self, step: u64, last: u64) -> bool {
        step == 0 || step % self.every == 0 || step == last
    }

    fn observe(
        &mut self,
        model: &BilliardsModel,
        step: u64,
        _last: u64,
        _bar: &ProgressBar,
    ) -> SimResult {
        let pixels = self
            .chart
            .render(model, step)
            .map_err(SimError::output("a GIF frame of the discs"))?;
        self.gif
            .as_mut()
            .expect("an open animation")
            .add(&pixels, 8)
    }

    fn sync(&mut self) -> SimResult<Vec<(String, u64)>> {
        let gif = self.gif.as_mut().expect("an open animation");
        Ok(vec![gif.sync()?])
    }

    fn finish(&mut self) -> SimResult {
        match self.gif.take() {
            Some(gif) => gif.finish(),
            None => Ok(()),
        }
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

fn observers(
    run: &BilliardsRun,
    initial: &BilliardsModel,
    steps: u64,
    recorded: Recorded,
) -> SimResult<Vec<Box<dyn Observer<BilliardsModel>>>> {
    let here = Path::new("");
    let mut list: Vec<Box<dyn Observer<BilliardsModel>>> = Vec::new();
    if let Some(path) = run.viz {
        let name = path.to_string_lossy().into_owned();
        let (file, _) = open_stream(here, &name, recorded)?;
        list.push(Box::new(States {
            name,
            file,
            format: run.format,
        }));
    }
    if let Some(path) = run.gif {
        let name = path.to_string_lossy().into_owned();
        // the view and colour scale are the initial state's, also after a restart
        let chart = DiscChart::new(initial, run.picture_size);
        let size = [chart.frame.picture_width(), chart.frame.height()];
        let colours = &DiscPainter::palette()[..3 * DiscPainter::COLOURS];
        let gif = ChartAnimation::open(here, &name, recorded, size, colours)?;
        list.push(Box::new(Animation {
            every: run.frame_every.unwrap_or(steps.div_ceil(200).max(1)),
            chart,
            gif: Some(gif),
        }));
    }
    Ok(list)
}

/// Runs the benchmark: steps with the observers, then the final picture and state.
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
    let mut job = Job {
        model: BilliardsModel::new(system, input.ids.clone()),
        ranks: Default::default(),
        steps,
        dir: PathBuf::new(),
        checkpoint: run.checkpoint.as_ref().map(|(file, every)| CheckpointKeys {
            every: *every,
            file: file.clone(),
        }),
        physics: physics(&input),
        last_frame: LastFrame::Dump {
            file: "last.lammpstrj",
            columns: disc_columns(),
        },
    };
    let checkpoint = run
        .restart
        .map(|path| {
            driver::restore(
                &mut job.model,
                path,
                &job.physics,
                steps,
                Path::new(""),
                threads,
            )
        })
        .transpose()?;
    let first = checkpoint.as_ref().map_or(0, |c| c.step);
    if let Some(path) = run.restart {
        eprintln!("restart: from step {first} of {}", path.display());
    }
    let list = observers(run, &initial, steps, recorded(checkpoint.as_ref()))?;
    let report = job.run(checkpoint.as_ref(), list, threads, false)?;
    let model = report.model;
    if let Some(path) = run.png {
        final_picture(path, &initial, &model, steps, run.picture_size)
            .map_err(SimError::output(path.display().to_string()))?;
    }
    write_final(run, steps, &model)?;
    eprintln!(
        "{}",
        model.speed(
            report.loop_time.as_secs_f64(),
            steps - first,
            threads.count()
        )
    );
    Ok(())
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

/// Runs a collision-benchmark input start to end on the driver, quietly, with
/// only its thermo file (the energy at the first and last step) in `dir`: the
/// studies time it this way (`cellist scaling INPUT.in`, which loads the input
/// once first and prints its warnings then).
pub fn run_quiet(path: &Path, threads: &Threads, dir: &Path) -> SimResult<RunSummary> {
    let (input, system) = read(path, DEFAULT_MAX_SWEEPS, CellShape::Square)?;
    let job = billiards_job(&input, system, dir.to_path_buf(), None);
    let plan = OutputPlan {
        thermo_every: 0,
        table: ENERGY_TABLE,
        plot: None,
        dumps: Vec::new(),
        field: None,
        bodies: None,
        quiet: true,
        trajectories: Default::default(),
    };
    let context = RunContext::new(dir.to_path_buf(), None, threads).quiet();
    crate::execute(job, &plan, &context, std::time::Instant::now())
}

/// `steps` collision steps from a copy of `start` on `threads`, timed: the wall
/// time of the loop and the hardest step `(step, sweeps)`. The benchmarks and
/// the billiards sweep time the collision benchmark this way.
pub fn time_steps(
    start: &Billiards,
    steps: u64,
    threads: &Threads,
) -> SimResult<(f64, (u64, u64))> {
    let mut system = start.clone();
    let mut hardest = (0, 0);
    let clock = std::time::Instant::now();
    for step in 1..=steps {
        let stats = system
            .step(step, threads)
            .map_err(|e| SimError::BlowUp(e.to_string()))?;
        if stats.sweeps > hardest.1 {
            hardest = (step, stats.sweeps);
        }
    }
    Ok((clock.elapsed().as_secs_f64(), hardest))
}
