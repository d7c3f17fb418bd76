//! `model = "pse"` (diffusion by particle strength exchange): the scenario keys,
//! the particles and their field, and the outputs (thermo against the exact
//! solution, field CSV snapshots, PNG pictures, a GIF animation, the error plot).

use crate::driver::{JobSpec, LastFrame};
use crate::error::SimResult;
use crate::hosted::Hosted;
use crate::launch::{Launch, RunContext};
use crate::models::field_output::FieldScenario;
use crate::observers::{ChartLabels, Every, FieldPlan, OutputPlan, PlotSpec, TableStyle};
use crate::scenario::keys::{choice, CheckpointKeys, TrajectoryKeys};
use crate::scenario::Scenario;
use cellist::decomposition::Balance;
use cellist::models::pse::{
    lattice, InitialField, Integrator, Method, PseModel, PseParams, PseSystem,
};
use cellist::models::Model;
use cellist::Domain;
use cellist_io::read_field;
use serde::Deserialize;
use std::path::PathBuf;
use std::time::Instant;

/// The keys of a pse scenario.
type PseScenario = FieldScenario<SystemKeys>;

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
    checkpoint: Option<CheckpointKeys>,
    trajectories: TrajectoryKeys,
    /// `[decomposition] balance` (read by distributed runs only).
    #[cfg_attr(not(feature = "mpi"), allow(dead_code))]
    balance: Balance,
}

/// Runs a pse scenario, from the checkpoint `restart` if given.
pub fn run<L: Launch>(
    scenario: &Scenario,
    context: &RunContext,
    launch: L,
) -> SimResult<L::Output> {
    let keys: PseScenario = scenario.parse()?;
    debug_assert_eq!(keys.model, "pse");
    match keys.dimension {
        2 => run_in::<2, L>(scenario, &keys, context, launch),
        3 => run_in::<3, L>(scenario, &keys, context, launch),
        d => Err(scenario.error(format!("dimension must be 2 or 3, got {d}"))),
    }
}

/// Checks the scenario and builds the particles and their field.
fn build<const D: usize>(scenario: &Scenario, keys: &PseScenario) -> SimResult<Setup<D>> {
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
    let cell_list = Method::CellList {
        cutoff_factor: sys.cutoff_factor,
    };
    let method = choice(
        "system.method",
        &sys.method,
        &[("cell-list", cell_list), ("direct", Method::Direct)],
    )
    .map_err(err)?;
    let cutoff_factor_ok = sys.cutoff_factor.is_finite() && sys.cutoff_factor >= 2.0;
    if matches!(method, Method::CellList { .. }) && !cutoff_factor_ok {
        return Err(err(format!(
            "system.cutoff_factor must be >= 2, got {}",
            sys.cutoff_factor
        )));
    }
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
    let integrator = run.integrator().map_err(err)?;
    let out = &keys.output;
    let steps = run.steps;
    let snapshots = out.snapshots(steps, ["field.csv", "field.png", "field.gif"]);
    out.check().map_err(err)?;
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
        field: snapshots.csv,
        png: snapshots.png,
        gif: snapshots.gif,
        picture_size: out.picture_size,
        checkpoint: out.checkpoint.clone(),
        trajectories: out.trajectories().map_err(err)?,
        balance: keys
            .decomposition
            .clone()
            .unwrap_or_default()
            .balance()
            .map_err(err)?,
    })
}

/// The initial field of the scenario's `initial` table.
fn initial_field<const D: usize>(keys: &InitialKeys, side: f64) -> Result<InitialField<D>, String> {
    /// The shapes of an initial field.
    #[derive(Clone, Copy)]
    enum Shape {
        Sine,
        Gaussian,
    }
    let shapes = [("sine", Shape::Sine), ("gaussian", Shape::Gaussian)];
    match choice("system.initial.kind", &keys.kind, &shapes)? {
        Shape::Sine => {
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
        Shape::Gaussian => {
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
    }
}

fn run_in<const D: usize, L: Launch>(
    scenario: &Scenario,
    keys: &PseScenario,
    context: &RunContext,
    launch: L,
) -> SimResult<L::Output> {
    let (threads, out_dir) = (context.threads, &context.out_dir);
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
    context.say(format!(
        "pse: {} particles in {D}D, box {} (periodic), h {:.6}, nu {}, eps {} (eps/h {:.3}), {method}: {} pair kernels per rate",
        system.len(),
        setup.domain.length[0],
        setup.spacing,
        setup.params.nu,
        setup.params.epsilon,
        setup.params.epsilon / setup.spacing,
        system.pairs_per_rate()
    ));
    context.say(format!(
        "run: {} steps of dt {} with {} (stable for dt <= {limit:.4e}), {} thread(s); results in {}",
        setup.steps,
        setup.dt,
        setup.integrator_name,
        threads.count(),
        out_dir.display()
    ));
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
        context.warn(format!(
            "{message}; running anyway (run.allow_unstable = true)"
        ));
    }
    if setup.params.epsilon < 0.5 * setup.spacing {
        context.warn(format!(
            "eps/h = {:.3} < 0.5: the kernel barely reaches the neighbours, so the \
             particles hardly exchange and diffusion is underestimated (see docs/models.md, the eps study)",
            setup.params.epsilon / setup.spacing
        ));
    }
    let plot = setup.initial.is_some().then(|| PlotSpec {
        file: "error.png",
        title: "Error against the exact solution",
        x_label: "time (simulation units)",
        y_label: "L2 error of φ",
        series: vec![("L2 error", "l2_error", false)],
    });
    let plan = OutputPlan {
        thermo_every: setup.thermo_every,
        table: TableStyle {
            width: 16,
            precision: 8,
            exponent: true,
            shown: 4,
        },
        plot,
        dumps: Vec::new(),
        field: Some(FieldPlan {
            csv: setup.field.clone(),
            png: setup.png.clone(),
            gif: setup.gif.clone(),
            size: setup.picture_size,
            chart: ChartLabels {
                title: "φ",
                value: "φ (strength per volume)",
                unit: "simulation units",
                magnitude: false,
            },
        }),
        bodies: None,
        trajectories: setup.trajectories.clone(),
    };
    let model = PseModel::new(
        system,
        setup.integrator,
        setup.dt,
        setup.initial,
        setup.spacing,
    );
    let spec = JobSpec {
        steps: setup.steps,
        dir: out_dir.to_path_buf(),
        checkpoint: setup.checkpoint.clone(),
        physics: scenario.physics_keys()?,
        last_frame: LastFrame::Field { file: "last.csv" },
    };
    #[cfg(feature = "mpi")]
    if let Some(world) = crate::distributed::world_of_many() {
        let ranks = crate::ranks::Ranks::Spread(mpi::traits::Communicator::duplicate(&world));
        let model =
            crate::distributed::pse::DistributedPse::new(world, model, setup.balance, threads)
                .map_err(|e| scenario.error(e))?;
        return launch.launch(spec.with(model).on(ranks), &plan, context, started);
    }
    launch.launch(spec.with(model), &plan, context, started)
}

impl<const D: usize> Hosted for PseModel<D> {
    /// Pair kernels evaluated per second.
    fn speed(&self, loop_seconds: f64, steps: u64, threads: usize) -> String {
        let evaluations = self.system.pairs_per_rate() * self.integrator.stages() * steps;
        format!(
            "Loop time of {loop_seconds:.4} s on {threads} thread(s) for {steps} steps with {} particles: \
             {:.3e} pair kernels per second",
            self.len(),
            evaluations as f64 / loop_seconds.max(1e-12)
        )
    }
}
