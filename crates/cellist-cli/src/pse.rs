//! `cellist run` for `model = "pse"` (diffusion by particle strength exchange):
//! scenario keys, the particles and their field, the run loop with thermo against
//! the exact solution, field CSV snapshots, PNG pictures and a GIF animation; and
//! `cellist bench pse`.

use crate::bench::median;
use crate::cli::{BenchPseArgs, PseMethodArg};
use crate::error::{threads, CliError, CliResult};
use crate::progress::{progress_bar, thermo_row};
use crate::scenario::Scenario;
use cellist::models::pse::{lattice, InitialField, Integrator, Method, PseParams, PseSystem};
use cellist::{Domain, Threads};
use cellist_io::plot::{line_chart, Series};
use cellist_io::{read_field, write_field, write_png, AtomicFile, FieldPainter, GifAnimation};
use serde::Deserialize;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// The keys of a pse scenario.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct PseScenario {
    model: String,
    #[serde(default = "two")]
    dimension: u64,
    system: SystemKeys,
    run: RunKeys,
    #[serde(default)]
    output: OutputKeys,
}

fn two() -> u64 {
    2
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SystemKeys {
    #[serde(rename = "box", default = "one")]
    side: f64,
    lattice: Option<LatticeKeys>,
    particles: Option<PathBuf>,
    #[serde(default = "one")]
    nu: f64,
    epsilon: f64,
    #[serde(default = "five")]
    cutoff_factor: f64,
    #[serde(default = "cell_list")]
    method: String,
    initial: Option<InitialKeys>,
}

fn one() -> f64 {
    1.0
}

fn five() -> f64 {
    5.0
}

fn cell_list() -> String {
    "cell-list".into()
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct LatticeKeys {
    n: i64,
    #[serde(default)]
    jitter: f64,
    #[serde(default = "one_u64")]
    seed: u64,
}

fn one_u64() -> u64 {
    1
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct InitialKeys {
    kind: String,
    k: Option<Vec<i64>>,
    center: Option<Vec<f64>>,
    width: Option<f64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RunKeys {
    steps: u64,
    dt: f64,
    #[serde(default = "rk4")]
    integrator: String,
    #[serde(default)]
    allow_unstable: bool,
}

fn rk4() -> String {
    "rk4".into()
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields, default)]
struct OutputKeys {
    thermo_every: u64,
    field: Option<SnapshotKeys>,
    png: Option<SnapshotKeys>,
    gif: Option<SnapshotKeys>,
    picture_size: u32,
}

impl Default for OutputKeys {
    fn default() -> Self {
        OutputKeys {
            thermo_every: 10,
            field: None,
            png: None,
            gif: None,
            picture_size: 512,
        }
    }
}

#[derive(Deserialize, Clone)]
#[serde(deny_unknown_fields)]
struct SnapshotKeys {
    every: u64,
    file: Option<PathBuf>,
}

/// Snapshots every `every` steps (and at step 0 and the last step) to `file`.
#[derive(Clone, Debug)]
struct Every {
    every: u64,
    file: PathBuf,
}

/// Everything a run needs, checked.
struct Setup<const D: usize> {
    domain: Domain<D>,
    points: Vec<[f64; D]>,
    phi: Vec<f64>,
    params: PseParams,
    initial: Option<InitialField<D>>,
    spacing: f64,
    integrator: Integrator,
    integrator_name: String,
    dt: f64,
    steps: u64,
    allow_unstable: bool,
    thermo_every: u64,
    field: Option<Every>,
    png: Option<Every>,
    gif: Option<Every>,
    picture_size: u32,
}

/// Runs a pse scenario.
pub fn run(scenario: &Scenario, out_dir: &Path, threads: &Threads) -> CliResult {
    let keys: PseScenario = scenario.parse()?;
    debug_assert_eq!(keys.model, "pse");
    match keys.dimension {
        2 => run_in::<2>(scenario, &keys, out_dir, threads),
        3 => run_in::<3>(scenario, &keys, out_dir, threads),
        d => Err(scenario.error(format!("dimension must be 2 or 3, got {d}"))),
    }
}

/// Checks the scenario and builds the particles and their field.
fn build<const D: usize>(scenario: &Scenario, keys: &PseScenario) -> CliResult<Setup<D>> {
    let err = |m: String| scenario.error(m);
    let sys = &keys.system;
    if !(sys.side.is_finite() && sys.side > 0.0) {
        return Err(err(format!("system.box must be > 0, got {}", sys.side)));
    }
    let domain = Domain::periodic([sys.side; D]).map_err(|e| err(e.to_string()))?;
    if !(sys.epsilon.is_finite() && sys.epsilon > 0.0) {
        return Err(err(format!(
            "system.epsilon must be > 0, got {}",
            sys.epsilon
        )));
    }
    if !(sys.nu.is_finite() && sys.nu >= 0.0) {
        return Err(err(format!("system.nu must be >= 0, got {}", sys.nu)));
    }
    let method = match sys.method.as_str() {
        "direct" => Method::Direct,
        "cell-list" => {
            if !(sys.cutoff_factor.is_finite() && sys.cutoff_factor >= 2.0) {
                return Err(err(format!(
                    "system.cutoff_factor must be >= 2, got {}",
                    sys.cutoff_factor
                )));
            }
            Method::CellList {
                cutoff_factor: sys.cutoff_factor,
            }
        }
        other => {
            return Err(err(format!(
                "system.method '{other}' is unknown; expected \"cell-list\" or \"direct\""
            )))
        }
    };
    let initial = sys
        .initial
        .as_ref()
        .map(|i| initial_field::<D>(i, sys.side))
        .transpose()
        .map_err(err)?;
    let (points, file_phi) = match (&sys.lattice, &sys.particles) {
        (Some(_), Some(_)) => {
            return Err(err("system: give lattice or particles, not both".into()))
        }
        (None, None) => {
            return Err(err(
                "system: no particles; give lattice = { n = 128 } or particles = \"field.csv\""
                    .into(),
            ))
        }
        (Some(l), None) => {
            if l.n < 2 {
                return Err(err(format!(
                    "system.lattice.n must be at least 2 particles per side, got {}",
                    l.n
                )));
            }
            if (l.n as f64).powi(D as i32) > 4e9 {
                return Err(err(format!(
                    "system.lattice.n = {} gives too many particles",
                    l.n
                )));
            }
            if !(l.jitter.is_finite() && (0.0..=1.0).contains(&l.jitter)) {
                return Err(err(format!(
                    "system.lattice.jitter must be in [0, 1] (a fraction of the spacing), got {}",
                    l.jitter
                )));
            }
            (lattice::<D>(l.n as usize, sys.side, l.jitter, l.seed), None)
        }
        (None, Some(path)) => {
            let (points, phi) = read_field::<D>(&scenario.input_path(path))?;
            (points, Some(phi))
        }
    };
    let phi = match (&initial, file_phi) {
        (Some(field), _) => field.exact_at(&points, 0.0, sys.nu, &domain.length),
        (None, Some(phi)) => phi,
        (None, None) => {
            return Err(err(
                "system.initial is missing; expected { kind = \"sine\", k = [...] } or { kind = \"gaussian\", center = [...], width = ... }"
                    .into(),
            ))
        }
    };
    let run = &keys.run;
    if !(run.dt.is_finite() && run.dt > 0.0) {
        return Err(err(format!("run.dt must be > 0, got {}", run.dt)));
    }
    let integrator = Integrator::from_name(&run.integrator).ok_or_else(|| {
        let names: Vec<&str> = Integrator::ALL.iter().map(|(n, _)| *n).collect();
        err(format!(
            "run.integrator '{}' is unknown; expected one of {}",
            run.integrator,
            names.join(", ")
        ))
    })?;
    let out = &keys.output;
    let steps = run.steps;
    // every = 0 turns a snapshot off; a missing key takes the default
    let snapshot = |keys: &Option<SnapshotKeys>, name: &str, default: Option<u64>| match keys {
        Some(s) => (s.every > 0).then(|| Every {
            every: s.every,
            file: s.file.clone().unwrap_or_else(|| name.into()),
        }),
        None => default.map(|every| Every {
            every,
            file: name.into(),
        }),
    };
    let field = snapshot(&out.field, "field.csv", None);
    // pictures of the first and last steps, and an animation of about 60 frames
    let png = snapshot(&out.png, "field.png", Some(steps.max(1)));
    let gif = snapshot(&out.gif, "field.gif", Some(steps.div_ceil(60).max(1)));
    if !(16..=4096).contains(&out.picture_size) {
        return Err(err(format!(
            "output.picture_size must be between 16 and 4096 pixels, got {}",
            out.picture_size
        )));
    }
    let spacing = sys.side / (points.len() as f64).powf(1.0 / D as f64);
    Ok(Setup {
        domain,
        points,
        phi,
        params: PseParams {
            nu: sys.nu,
            epsilon: sys.epsilon,
            method,
        },
        initial,
        spacing,
        integrator,
        integrator_name: run.integrator.clone(),
        dt: run.dt,
        steps,
        allow_unstable: run.allow_unstable,
        thermo_every: out.thermo_every,
        field,
        png,
        gif,
        picture_size: out.picture_size,
    })
}

/// The initial field of the scenario's `initial` table.
fn initial_field<const D: usize>(keys: &InitialKeys, side: f64) -> Result<InitialField<D>, String> {
    match keys.kind.as_str() {
        "sine" => {
            if keys.center.is_some() || keys.width.is_some() {
                return Err("system.initial: a sine takes only k".into());
            }
            let k = keys.k.clone().unwrap_or_else(|| vec![1; D]);
            let k: [i64; D] = k.try_into().map_err(|k: Vec<i64>| {
                format!(
                    "system.initial.k has {} wavenumbers; a {D}D field needs {D}",
                    k.len()
                )
            })?;
            Ok(InitialField::Sine { k })
        }
        "gaussian" => {
            if keys.k.is_some() {
                return Err("system.initial: a gaussian takes center and width, not k".into());
            }
            let center = keys.center.clone().unwrap_or_else(|| vec![0.5 * side; D]);
            let center: [f64; D] = center.try_into().map_err(|c: Vec<f64>| {
                format!(
                    "system.initial.center has {} coordinates; a {D}D field needs {D}",
                    c.len()
                )
            })?;
            let width = keys.width.unwrap_or(0.1 * side);
            if !(width.is_finite() && width > 0.0) || center.iter().any(|c| !c.is_finite()) {
                return Err(format!(
                    "system.initial: the gaussian needs a finite center and a width > 0, got width {width}"
                ));
            }
            Ok(InitialField::Gaussian { center, width })
        }
        other => Err(format!(
            "system.initial.kind '{other}' is unknown; expected \"sine\" or \"gaussian\""
        )),
    }
}

fn run_in<const D: usize>(
    scenario: &Scenario,
    keys: &PseScenario,
    out_dir: &Path,
    threads: &Threads,
) -> CliResult {
    let setup = build::<D>(scenario, keys)?;
    let started = Instant::now();
    let mut system = PseSystem::new(
        setup.domain,
        &setup.points,
        &setup.phi,
        setup.params,
        threads,
    )
    .map_err(|e| scenario.error(e))?;
    let limit = system.stability_limit(setup.integrator, threads);
    let method = match setup.params.method {
        Method::Direct => "all pairs".to_string(),
        Method::CellList { cutoff_factor } => format!("cell list, cutoff {cutoff_factor} eps"),
    };
    println!(
        "pse: {} particles in {D}D, box {} (periodic), h {:.6}, nu {}, eps {} (eps/h {:.3}), {method}: {} pair kernels per rate",
        system.len(),
        setup.domain.length[0],
        setup.spacing,
        setup.params.nu,
        setup.params.epsilon,
        setup.params.epsilon / setup.spacing,
        system.pairs_per_rate()
    );
    println!(
        "run: {} steps of dt {} with {} (stable for dt <= {limit:.4e}), {} thread(s); results in {}",
        setup.steps,
        setup.dt,
        setup.integrator_name,
        threads.count(),
        out_dir.display()
    );
    if setup.dt > limit {
        let message = format!(
            "run.dt = {} exceeds the stability limit {limit:.6e} of {} for this kernel and spacing \
             (from the largest row sum of the pair weights)",
            setup.dt, setup.integrator_name
        );
        if !setup.allow_unstable {
            return Err(scenario.error(format!(
                "{message}; use a smaller dt, or set run.allow_unstable = true to run anyway"
            )));
        }
        eprintln!("warning: {message}; running anyway (run.allow_unstable = true)");
    }
    if setup.params.epsilon < 0.5 * setup.spacing {
        eprintln!(
            "warning: eps/h = {:.3} < 0.5: the kernel barely reaches the neighbours, so the \
             particles hardly exchange and diffusion is underestimated (see docs/models.md, the eps study)",
            setup.params.epsilon / setup.spacing
        );
    }
    std::fs::create_dir_all(out_dir)
        .map_err(CliError::output(format!("folder {}", out_dir.display())))?;
    let mut out = Outputs::create(&setup, &system, out_dir)?;
    out.observe(&setup, &system, 0)?;
    let bar = progress_bar(setup.steps);
    out.bar = Some(bar.clone());
    let loop_start = Instant::now();
    for step in 1..=setup.steps {
        if let Err(e) = system.step(setup.integrator, setup.dt, threads) {
            bar.abandon();
            let last = out_dir.join("last.csv");
            let written = write_csv(&last, &system.positions(), &system.phi());
            out.finish(&setup)?;
            return Err(CliError::Run(format!(
                "step {step}: {e}; the last state is in {}{}",
                last.display(),
                written
                    .err()
                    .map_or(String::new(), |e| format!(" (not written: {e})"))
            )));
        }
        out.observe(&setup, &system, step)?;
        bar.inc(1);
    }
    bar.finish_and_clear();
    let loop_time = loop_start.elapsed().as_secs_f64();
    out.finish(&setup)?;
    let evaluations = system.pairs_per_rate() * setup.integrator.stages() * setup.steps;
    if setup.steps > 0 {
        println!(
            "\nLoop time of {loop_time:.4} s on {} thread(s) for {} steps with {} particles: {:.3e} pair kernels per second",
            threads.count(),
            setup.steps,
            system.len(),
            evaluations as f64 / loop_time.max(1e-12)
        );
    }
    println!(
        "total wall time {:.2} s; results in {}",
        started.elapsed().as_secs_f64(),
        out_dir.display()
    );
    Ok(())
}

/// Writes a field CSV whole or not at all.
fn write_csv<const D: usize>(path: &Path, points: &[[f64; D]], phi: &[f64]) -> CliResult {
    let mut file =
        AtomicFile::create(path).map_err(CliError::output(path.display().to_string()))?;
    write_field(file.writer(), points, phi)
        .map_err(CliError::output(path.display().to_string()))?;
    file.commit()
        .map_err(CliError::output(path.display().to_string()))
}

/// `file` for the snapshot of `step`: a `*` in the name becomes the step, otherwise
/// `_<step>` goes before the extension; the step is zero-padded to the width of the
/// last step, so that the files sort in time order.
fn snapshot_path(dir: &Path, file: &Path, step: u64, last: u64) -> PathBuf {
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

fn due(every: &Option<Every>, step: u64, last: u64) -> bool {
    every
        .as_ref()
        .is_some_and(|e| step == 0 || step == last || step % e.every == 0)
}

/// Thermo, field files, pictures and the error plot.
struct Outputs {
    dir: PathBuf,
    thermo_csv: Option<AtomicFile>,
    rows: Vec<(f64, f64)>,
    painter: FieldPainter,
    gif: Option<GifAnimation>,
    bar: Option<indicatif::ProgressBar>,
}

const THERMO_COLUMNS: [&str; 5] = ["step", "time", "total", "l2_error", "max_error"];

impl Outputs {
    fn create<const D: usize>(
        setup: &Setup<D>,
        system: &PseSystem<D>,
        dir: &Path,
    ) -> CliResult<Self> {
        let csv_path = dir.join("thermo.csv");
        let mut csv = AtomicFile::create(&csv_path)
            .map_err(CliError::output(csv_path.display().to_string()))?;
        writeln!(csv.writer(), "{}", THERMO_COLUMNS.join(","))
            .map_err(CliError::output("thermo.csv"))?;
        println!("{}", THERMO_COLUMNS.map(|c| format!("{c:>16}")).join(""));
        let scale = system.phi().iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let painter = FieldPainter::new(
            setup.picture_size,
            setup.domain.length[0],
            setup.spacing,
            scale,
        );
        let gif = match &setup.gif {
            Some(g) => {
                let path = dir.join(&g.file);
                Some(
                    GifAnimation::create(&path, painter.size(), &FieldPainter::palette())
                        .map_err(CliError::output(path.display().to_string()))?,
                )
            }
            None => None,
        };
        Ok(Outputs {
            dir: dir.to_path_buf(),
            thermo_csv: Some(csv),
            rows: Vec::new(),
            painter,
            gif,
            bar: None,
        })
    }

    /// Writes what is due at `step`.
    fn observe<const D: usize>(
        &mut self,
        setup: &Setup<D>,
        system: &PseSystem<D>,
        step: u64,
    ) -> CliResult {
        let last = setup.steps;
        let thermo =
            step == 0 || step == last || (setup.thermo_every > 0 && step % setup.thermo_every == 0);
        let pictures = due(&setup.png, step, last) || due(&setup.gif, step, last);
        if !(thermo || pictures || due(&setup.field, step, last)) {
            return Ok(());
        }
        let phi = system.phi();
        let points = system.positions();
        let time = step as f64 * setup.dt;
        if thermo {
            let (l2, max) = match &setup.initial {
                Some(field) => system.errors(&field.exact_at(
                    &points,
                    time,
                    setup.params.nu,
                    &setup.domain.length,
                )),
                None => (f64::NAN, f64::NAN),
            };
            self.rows.push((time, l2));
            let values = [time, system.total(), l2, max];
            let table = format!("{step:>16}") + &values.map(|v| format!("{v:>16.8e}")).join("");
            thermo_row(
                self.thermo_csv.as_mut(),
                self.bar.as_ref(),
                step,
                &values,
                &table,
            )?;
        }
        if let Some(f) = setup
            .field
            .as_ref()
            .filter(|_| due(&setup.field, step, last))
        {
            write_csv(
                &snapshot_path(&self.dir, &f.file, step, last),
                &points,
                &phi,
            )?;
        }
        if pictures {
            let size = self.painter.size();
            let pixels =
                self.painter
                    .render(slice(&points, &phi, setup.spacing, setup.domain.length[0]));
            if let Some(p) = setup.png.as_ref().filter(|_| due(&setup.png, step, last)) {
                let path = snapshot_path(&self.dir, &p.file, step, last);
                write_png(&path, size, pixels, &FieldPainter::palette())
                    .map_err(CliError::output(path.display().to_string()))?;
            }
            if let (Some(gif), true) = (self.gif.as_mut(), due(&setup.gif, step, last)) {
                gif.add_frame(pixels, 8)
                    .map_err(CliError::output("the GIF animation"))?;
            }
        }
        Ok(())
    }

    /// Commits the thermo CSV and the animation, and plots the error over time.
    fn finish<const D: usize>(&mut self, setup: &Setup<D>) -> CliResult {
        if let Some(csv) = self.thermo_csv.take() {
            csv.commit().map_err(CliError::output("thermo.csv"))?;
        }
        if let Some(gif) = self.gif.take() {
            let path = setup
                .gif
                .as_ref()
                .map_or(PathBuf::new(), |g| self.dir.join(&g.file));
            gif.finish()
                .map_err(CliError::output(path.display().to_string()))?;
        }
        if setup.initial.is_some() && self.rows.len() >= 2 {
            let path = self.dir.join("error.png");
            line_chart(
                &path,
                "Error against the exact solution",
                "time",
                "L2 error",
                &[Series {
                    label: "L2 error",
                    points: &self.rows,
                }],
            )
            .map_err(|e| CliError::Output(std::io::Error::other(e), path.display().to_string()))?;
        }
        Ok(())
    }
}

/// The particles to draw: all of a 2D field; in 3D the layer nearest the middle of
/// the box along z (within half a spacing of it).
fn slice<'a, const D: usize>(
    points: &'a [[f64; D]],
    phi: &'a [f64],
    spacing: f64,
    side: f64,
) -> impl Iterator<Item = ([f64; 2], f64)> + 'a {
    let plane = if D == 3 {
        points
            .iter()
            .map(|x| x[2])
            .min_by(|a, b| (a - 0.5 * side).abs().total_cmp(&(b - 0.5 * side).abs()))
            .unwrap_or(0.5 * side)
    } else {
        0.0
    };
    points
        .iter()
        .zip(phi)
        .filter(move |(x, _)| D == 2 || (x[D - 1] - plane).abs() < 0.5 * spacing)
        .map(|(x, &v)| ([x[0], x[1]], v))
}

/// `cellist bench pse`.
pub fn bench(args: &BenchPseArgs) -> CliResult {
    if args.n_per_side < 2 {
        return Err(CliError::Input("--n-per-side must be at least 2".into()));
    }
    if args.repeat == 0 || args.steps == 0 {
        return Err(CliError::Input(
            "--repeat and --steps must be at least 1".into(),
        ));
    }
    crate::error::positive("--eps-over-h", args.eps_over_h)?;
    let pool = threads(Some(args.threads))?;
    let (seconds, pairs, n) = match args.dim {
        2 => time_steps::<2>(args, &pool)?,
        _ => time_steps::<3>(args, &pool)?,
    };
    let per_second = pairs as f64 / seconds;
    let method = match args.method {
        PseMethodArg::Direct => "direct",
        PseMethodArg::CellList => "cell-list",
    };
    if args.json {
        let obj = serde_json::json!({
            "n_per_side": args.n_per_side, "particles": n, "dim": args.dim, "method": method,
            "eps_over_h": args.eps_over_h, "cutoff_factor": args.cutoff_factor,
            "threads": args.threads, "seconds_per_step": seconds, "pairs_per_step": pairs,
            "pair_kernels_per_second": per_second,
        });
        println!("{obj}");
    } else {
        println!(
            "pse: {n} particles ({}^{}), {method}, eps/h {}, {} thread(s): {seconds:.4e} s per step \
             (median of {}), {pairs} pair kernels per step, {per_second:.3e} pair kernels per second",
            args.n_per_side, args.dim, args.eps_over_h, args.threads, args.repeat
        );
    }
    Ok(())
}

/// Median seconds per forward Euler step, pair kernels per step, particles.
fn time_steps<const D: usize>(args: &BenchPseArgs, pool: &Threads) -> CliResult<(f64, u64, usize)> {
    let n = args.n_per_side;
    let domain = Domain::periodic([1.0; D]).map_err(|e| CliError::Internal(e.to_string()))?;
    let points = lattice::<D>(n, 1.0, 0.0, 1);
    let field = InitialField::Sine { k: [1; D] };
    let phi = field.exact_at(&points, 0.0, 1.0, &domain.length);
    let method = match args.method {
        PseMethodArg::Direct => Method::Direct,
        PseMethodArg::CellList => Method::CellList {
            cutoff_factor: args.cutoff_factor,
        },
    };
    let params = PseParams {
        nu: 1.0,
        epsilon: args.eps_over_h / n as f64,
        method,
    };
    let mut system = PseSystem::new(domain, &points, &phi, params, pool)
        .map_err(|e| CliError::Input(e.to_string()))?;
    let dt = 0.5 * system.stability_limit(Integrator::Euler, pool);
    let mut samples = Vec::with_capacity(args.repeat);
    for _ in 0..args.repeat {
        let start = Instant::now();
        for _ in 0..args.steps {
            system
                .step(Integrator::Euler, dt, pool)
                .map_err(|e| CliError::Internal(e.to_string()))?;
        }
        samples.push(start.elapsed().as_secs_f64() / args.steps as f64);
    }
    Ok((median(&mut samples), system.pairs_per_rate(), points.len()))
}
