//! `model = "vortex"` (the viscous vortex particle method in 2D): the scenario
//! keys, the seeded particles, and the outputs (thermo with the invariants and
//! the errors against Lamb-Oseen, field CSV snapshots `x,y,omega,gamma,u,v`,
//! vorticity pictures with axes and a colour bar, a GIF animation).

use crate::driver::{JobSpec, LastFrame};
use crate::error::SimResult;
use crate::hosted::Hosted;
use crate::launch::{Launch, RunContext};
use crate::models::field_output::FieldScenario;
use crate::models::vortex_keys::{
    check_blob_keys, check_diffusion_step, four, gaussian, one_and_a_half, solver_choice,
    threshold, SolverChoice, VelocityKeys, MAX_SEEDED,
};
use crate::observers::{ChartLabels, FieldPlan, OutputPlan, PlotSpec, TableStyle};
use crate::ranks::Ranks;
use crate::scenario::keys::choice;
use crate::scenario::Scenario;
use cellist::longrange::{BlobKernel, ErrorFit, VicBoundary, VicParams};
use cellist::models::vortex::{
    seed, Extras, InitialVorticity, VelocityEngine, VelocitySolver, VortexModel, VortexParams,
    VortexSystem,
};
use cellist::models::Model;
use cellist_io::read_field_of;
use serde::Deserialize;
use std::path::PathBuf;
use std::time::Instant;

/// The keys of a vortex scenario.
type VortexScenario = FieldScenario<SystemKeys>;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SystemKeys {
    initial: InitialKeys,
    #[serde(default)]
    nu: f64,
    #[serde(default = "one_and_a_half")]
    sigma_over_h: f64,
    #[serde(default = "gaussian")]
    kernel: String,
    #[serde(default)]
    velocity: VelocityKeys,
    #[serde(default)]
    remesh_every: u64,
    #[serde(default = "threshold")]
    remesh_threshold: f64,
    #[serde(default = "four")]
    pse_cutoff_factor: f64,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct InitialKeys {
    kind: String,
    spacing: f64,
    extent: Option<f64>,
    center: Option<Vec<f64>>,
    circulation: Option<f64>,
    t0: Option<f64>,
    core: Option<f64>,
    separation: Option<f64>,
    peak: Option<f64>,
    radius: Option<f64>,
    aspect: Option<f64>,
    file: Option<PathBuf>,
}

/// The scenario's dimension, read before its other keys (which depend on it).
#[derive(Deserialize)]
struct Dimension {
    #[serde(default = "two")]
    dimension: u64,
}

fn two() -> u64 {
    2
}

/// The particles, their lattice and how they are described.
struct Seeded {
    positions: Vec<[f64; 2]>,
    gamma: Vec<f64>,
    center: [f64; 2],
    /// The square the pictures show: lower corner and side.
    view: ([f64; 2], f64),
    extras: Extras,
    what: String,
}

/// The kinds of `system.initial`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Initial {
    LambOseen,
    Gaussian,
    Pair,
    Ellipse,
    File,
}

impl Initial {
    /// Every kind with its name in a scenario.
    const NAMES: [(&'static str, Initial); 5] = [
        ("lamb-oseen", Initial::LambOseen),
        ("gaussian", Initial::Gaussian),
        ("pair", Initial::Pair),
        ("ellipse", Initial::Ellipse),
        ("file", Initial::File),
    ];

    /// The keys of `system.initial` this kind takes (besides spacing, extent
    /// and center).
    fn keys(self) -> &'static [&'static str] {
        match self {
            Initial::LambOseen => &["circulation", "t0"],
            Initial::Gaussian => &["circulation", "core"],
            Initial::Pair => &["circulation", "separation", "core"],
            Initial::Ellipse => &["peak", "radius", "aspect"],
            Initial::File => &["file"],
        }
    }
}

/// Seeds the particles of `system.initial`.
fn seed_particles(scenario: &Scenario, sys: &SystemKeys) -> SimResult<Seeded> {
    let err = |m: String| scenario.error(m);
    let i = &sys.initial;
    let kind = choice("system.initial.kind", &i.kind, &Initial::NAMES).map_err(err)?;
    let keys = kind.keys();
    let given = [
        ("circulation", i.circulation.is_some()),
        ("t0", i.t0.is_some()),
        ("core", i.core.is_some()),
        ("separation", i.separation.is_some()),
        ("peak", i.peak.is_some()),
        ("radius", i.radius.is_some()),
        ("aspect", i.aspect.is_some()),
        ("file", i.file.is_some()),
    ];
    if let Some((name, _)) = given.iter().find(|(n, g)| *g && !keys.contains(n)) {
        return Err(err(format!(
            "system.initial: a {} takes {}, spacing, extent and center, not {name}",
            i.kind,
            keys.join(", ")
        )));
    }
    let positive = |name: &str, v: Option<f64>, default: Option<f64>| -> SimResult<f64> {
        match v.or(default) {
            Some(v) if v.is_finite() && v > 0.0 => Ok(v),
            Some(v) => Err(err(format!("system.initial.{name} must be > 0, got {v}"))),
            None => Err(err(format!(
                "system.initial.{name} is missing (a {} needs {})",
                i.kind,
                keys.join(", ")
            ))),
        }
    };
    let h = positive("spacing", Some(i.spacing), None)?;
    let center: [f64; 2] = match &i.center {
        None => [0.0, 0.0],
        Some(c) => match c.as_slice() {
            [x, y] if x.is_finite() && y.is_finite() => [*x, *y],
            _ => {
                return Err(err(format!(
                    "system.initial.center must be two finite numbers [x, y], got {c:?}"
                )))
            }
        },
    };
    let circulation = || -> SimResult<f64> {
        match i.circulation.unwrap_or(1.0) {
            g if g.is_finite() && g != 0.0 => Ok(g),
            g => Err(err(format!(
                "system.initial.circulation must be finite and nonzero, got {g}"
            ))),
        }
    };
    let field = match kind {
        Initial::LambOseen => {
            if sys.nu <= 0.0 {
                return Err(err(format!(
                    "system.initial: a lamb-oseen vortex needs nu > 0 (its core is sqrt(4 nu t0)), got nu = {}; use kind = \"gaussian\" for an inviscid run",
                    sys.nu
                )));
            }
            Some(InitialVorticity::LambOseen {
                circulation: circulation()?,
                t0: positive("t0", i.t0, Some(1.0))?,
                nu: sys.nu,
            })
        }
        Initial::Gaussian => Some(InitialVorticity::Gaussian {
            circulation: circulation()?,
            core: positive("core", i.core, None)?,
        }),
        Initial::Pair => Some(InitialVorticity::Pair {
            circulation: circulation()?,
            separation: positive("separation", i.separation, None)?,
            core: positive("core", i.core, None)?,
        }),
        Initial::Ellipse => {
            let aspect = positive("aspect", i.aspect, Some(2.0))?;
            if aspect < 1.0 {
                return Err(err(format!(
                    "system.initial.aspect must be >= 1, got {aspect}"
                )));
            }
            Some(InitialVorticity::Ellipse {
                peak: positive("peak", i.peak, Some(20.0))?,
                radius: positive("radius", i.radius, Some(0.8))?,
                aspect,
            })
        }
        Initial::File => None,
    };
    let (positions, gamma, view, what) = match &field {
        Some(f) => {
            let extent = positive("extent", i.extent, None)?;
            let side = 2.0 * (extent / h).floor() + 1.0;
            if side * side > MAX_SEEDED {
                return Err(err(format!(
                    "system.initial: extent {extent} at spacing {h} seeds {:.3e} particles, more than {MAX_SEEDED:.0e}; use a smaller extent or a larger spacing",
                    side * side
                )));
            }
            let (positions, gamma) = seed(f, center, h, extent);
            let margin = extent + 2.0 * h;
            (
                positions,
                gamma,
                ([center[0] - margin, center[1] - margin], 2.0 * margin),
                format!(
                    "{} vortex seeded on a {}-wide lattice of spacing {h}",
                    i.kind,
                    2.0 * extent
                ),
            )
        }
        None => {
            let file = i.file.as_ref().ok_or_else(|| {
                err("system.initial.file is missing (a file initial condition needs file = \"particles.txt\" with lines x y gamma)".into())
            })?;
            if i.extent.is_some() {
                return Err(err(
                    "system.initial: a file initial condition takes its extent from the file; remove extent".into(),
                ));
            }
            let (points, gamma) = read_field_of::<2>(&scenario.input_path(file), "gamma")?;
            let points: Vec<[f64; 2]> = points
                .iter()
                .map(|p| [p[0] + center[0], p[1] + center[1]])
                .collect();
            let (lo, hi) = cellist::geometry::bounding_box(&points);
            let side = (hi[0] - lo[0]).max(hi[1] - lo[1]) + 4.0 * h;
            let mid = [0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1])];
            (
                points,
                gamma,
                ([mid[0] - 0.5 * side, mid[1] - 0.5 * side], side),
                format!("particles from {}", file.display()),
            )
        }
    };
    let extras = match field {
        Some(InitialVorticity::LambOseen {
            circulation, t0, ..
        }) => Extras::LambOseen {
            circulation,
            t0,
            center,
        },
        Some(InitialVorticity::Ellipse { .. }) => Extras::Ellipse,
        Some(InitialVorticity::Pair { .. }) => Extras::Pair,
        _ => Extras::None,
    };
    Ok(Seeded {
        positions,
        gamma,
        center,
        view,
        extras,
        what,
    })
}

/// The velocity solver of `system.velocity`.
fn solver(scenario: &Scenario, v: &VelocityKeys, center: [f64; 2]) -> SimResult<VelocitySolver> {
    let err = |m: String| scenario.error(m);
    Ok(match solver_choice(scenario, v, 0.4)? {
        SolverChoice::Direct => VelocitySolver::Direct,
        SolverChoice::BarnesHut(params) => VelocitySolver::BarnesHut(params),
        SolverChoice::Fmm(accuracy) => VelocitySolver::Fmm(accuracy),
        SolverChoice::Mesh { grid, periodic } => {
            let boundary = match periodic {
                None => VicBoundary::Unbounded,
                Some(side) => VicBoundary::Periodic {
                    origin: [center[0] - 0.5 * side, center[1] - 0.5 * side],
                    length: side,
                },
            };
            let params = VicParams {
                grid: grid.unwrap_or(256),
                boundary,
            };
            params
                .check()
                .map_err(|m| err(format!("system.velocity: {m}")))?;
            VelocitySolver::Mesh(params)
        }
    })
}

/// Runs a vortex scenario, from the checkpoint `restart` if given.
pub fn run<L: Launch>(
    scenario: &Scenario,
    context: &RunContext,
    launch: L,
) -> SimResult<L::Output> {
    let dimension: Dimension = scenario.parse()?;
    match dimension.dimension {
        2 => {}
        3 => return super::vortex3::run(scenario, context, launch),
        d => {
            return Err(scenario.error(format!(
                "dimension must be 2 or 3 for the vortex model, got {d}"
            )))
        }
    }
    let keys: VortexScenario = scenario.parse()?;
    debug_assert_eq!(keys.model, "vortex");
    let (threads, out_dir) = (context.threads, &context.out_dir);
    let err = |m: String| scenario.error(m);
    let started = Instant::now();
    let sys = &keys.system;
    check_blob_keys(scenario, context, sys.nu, sys.sigma_over_h, &sys.kernel)?;
    let seeded = seed_particles(scenario, sys)?;
    let velocity = solver(scenario, &sys.velocity, seeded.center)?;
    if keys.decomposition.is_some() {
        return Err(err(
            "[decomposition] applies to md and pse (domain decomposition); the vortex model \
             runs on several MPI ranks with every rank holding every particle"
                .into(),
        ));
    }
    let run = &keys.run;
    let integrator = run.integrator().map_err(err)?;
    let h = sys.initial.spacing;
    let sigma = sys.sigma_over_h * h;
    check_diffusion_step(scenario, context, run, integrator, sys.nu, sigma, 2)?;
    let params = VortexParams {
        nu: sys.nu,
        spacing: h,
        sigma,
        origin: seeded.center,
        pse_cutoff_factor: sys.pse_cutoff_factor,
        remesh_every: sys.remesh_every,
        remesh_threshold: sys.remesh_threshold,
        solver: velocity,
    };
    params.check().map_err(|m| err(format!("system: {m}")))?;
    let mut view = seeded.view;
    if let Some((lo, side)) = params.periodic_box() {
        let outside = seeded.positions.iter().position(|x| {
            (0..2).any(|a| !(lo[a] - 1e-9 * side..lo[a] + side * (1.0 - 1e-9)).contains(&x[a]))
        });
        if let Some(k) = outside {
            return Err(err(format!(
                "system.initial: particle {k} at {:?} lies outside the periodic box [{}, {}) x [{}, {}): make extent smaller than box / 2",
                seeded.positions[k],
                lo[0],
                lo[0] + side,
                lo[1],
                lo[1] + side
            )));
        }
        view = (lo, side);
    }
    let out = &keys.output;
    let steps = run.steps;
    out.check().map_err(err)?;
    let snapshots = out.snapshots(steps, ["vorticity.csv", "vorticity.png", "vorticity.gif"]);
    let n = seeded.positions.len();
    // the engine of one process (a distributed mesh builds its own slab)
    let single = || {
        VelocityEngine::new(params.solver, BlobKernel::new(params.sigma), n)
            .map_err(|e| err(format!("system: {e}")))
    };
    #[cfg(feature = "mpi")]
    let distributed = {
        use crate::distributed::replicated::{vortex_mesh, vortex_pairs, vortex_tree};
        let kernel = BlobKernel::new(params.sigma);
        let p = crate::distributed::world_of_many()
            .map_or(1, |w| mpi::traits::Communicator::size(&w) as usize);
        match velocity {
            VelocitySolver::Mesh(_) => vortex_mesh(velocity, kernel)
                .transpose()
                .map_err(|e| err(format!("system: {e}")))?,
            VelocitySolver::BarnesHut(tree) => vortex_tree(tree, kernel)
                .transpose()
                .map_err(|e| err(format!("system: {e}")))?
                .map(|(engine, ranks)| {
                    let line = format!(
                        "mpi: {p} ranks; the Barnes-Hut tree of all the particles built alike \
                        on every rank (the particles held by every rank), each rank walking a \
                        run of its groups balanced by interactions, the results all-gathered: \
                        one process's velocities to the bit"
                    );
                    (engine, ranks, line)
                }),
            VelocitySolver::Fmm(_) => crate::distributed::replicated::vortex_fmm()
                .map(|(ranks, line)| single().map(|engine| (engine, ranks, line)))
                .transpose()?,
            VelocitySolver::Direct => vortex_pairs(n, kernel),
        }
    };
    #[cfg(feature = "mpi")]
    let (engine, ranks) = match distributed {
        Some((engine, ranks, line)) => {
            context.say(line);
            (engine, ranks)
        }
        None => (single()?, Ranks::One),
    };
    #[cfg(not(feature = "mpi"))]
    let (engine, ranks) = (single()?, Ranks::One);
    let system = VortexSystem::with_engine(
        params,
        seeded.positions,
        seeded.gamma,
        engine,
        ranks.peers(),
        threads,
    )
    .map_err(|e| err(format!("system: {e}")))?;
    let solver_name = match velocity {
        VelocitySolver::Direct => "direct (all pairs)".to_string(),
        VelocitySolver::BarnesHut(p) => format!("barnes-hut (theta {})", p.theta),
        VelocitySolver::Fmm(a) => super::fmm_keys::fmm_name(a, ErrorFit::VORTEX_2D),
        VelocitySolver::Mesh(p) => match p.boundary {
            VicBoundary::Unbounded => {
                format!("mesh (vortex-in-cell, grid {}^2, unbounded)", p.grid)
            }
            VicBoundary::Periodic { length, .. } => {
                format!(
                    "mesh (vortex-in-cell, grid {}^2, periodic box of side {length})",
                    p.grid
                )
            }
        },
    };
    context.say(format!(
        "vortex: {n} particles, {}; nu {}, sigma {} ({} h), velocity by {solver_name}, remeshing {}",
        seeded.what,
        sys.nu,
        params.sigma,
        sys.sigma_over_h,
        match sys.remesh_every {
            0 => "never".to_string(),
            k => format!("every {k} steps"),
        }
    ));
    context.say(format!(
        "run: {steps} steps of dt {} with {}, {} thread(s); results in {}",
        run.dt,
        run.integrator,
        threads.count(),
        out_dir.display()
    ));
    let plot = match seeded.extras {
        Extras::LambOseen { .. } => Some(PlotSpec {
            file: "error.png",
            title: "Vorticity error against Lamb-Oseen",
            x_label: "time (simulation units)",
            y_label: "L2 error of ω",
            series: vec![("L2 error", "omega_l2_error", false)],
        }),
        _ => Some(PlotSpec {
            file: "invariants.png",
            title: "Circulation and enstrophy",
            x_label: "time (simulation units)",
            y_label: "Γ, enstrophy (simulation units)",
            series: vec![
                ("circulation", "circulation", false),
                ("enstrophy", "enstrophy", false),
            ],
        }),
    };
    let plan = OutputPlan {
        thermo_every: out.thermo_every,
        table: TableStyle {
            width: 16,
            precision: 7,
            exponent: true,
            shown: 7,
        },
        plot,
        dumps: Vec::new(),
        field: Some(FieldPlan {
            csv: snapshots.csv,
            png: snapshots.png,
            gif: snapshots.gif,
            size: out.picture_size,
            chart: ChartLabels {
                title: "vorticity",
                value: "ω = Γ/h²",
                unit: "simulation units",
                magnitude: false,
            },
        }),
        bodies: None,
        trajectories: out.trajectories().map_err(err)?,
    };
    let model = VortexModel::new(system, integrator, run.dt, seeded.extras, view, threads);
    let spec = JobSpec {
        steps,
        dir: out_dir.to_path_buf(),
        checkpoint: out.checkpoint.clone(),
        physics: scenario.physics_keys()?,
        last_frame: LastFrame::Field { file: "last.csv" },
    };
    launch.launch(spec.with(model).on(ranks), &plan, context, started)
}

impl Hosted for VortexModel {
    /// Seconds per velocity evaluation and the circulation that remeshing
    /// dropped.
    fn speed(&self, loop_seconds: f64, steps: u64, threads: usize) -> String {
        let stages = self.integrator.stages() * steps;
        format!(
            "Loop time of {loop_seconds:.4} s on {threads} thread(s) for {steps} steps with {} particles \
             (at the end): {:.4} s per velocity evaluation; circulation dropped by remeshing {:.3e}",
            self.len(),
            self.system.times().velocity.as_secs_f64() / stages.max(1) as f64,
            self.system.dropped()
        )
    }
}
