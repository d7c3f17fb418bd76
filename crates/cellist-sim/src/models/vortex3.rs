//! `model = "vortex"` with `dimension = 3` (the vortex particle method in 3D):
//! the scenario keys, the seeded rings, ABC flow or file, and the outputs
//! (thermo with the invariants, the rings' places or the errors against the
//! ABC flow; field CSV snapshots `x,y,z,ax,ay,az,u,v,w`; pictures of `|omega|`
//! on the plane through the rings' axis; VTK, GSD; checkpoints).

use super::field_output::FieldScenario;
use super::vortex_keys::{
    check_blob_keys, check_diffusion_step, four, gaussian, one_and_a_half, solver_choice,
    threshold, SolverChoice, VelocityKeys, MAX_SEEDED,
};
use crate::driver::{JobSpec, LastFrame};
use crate::error::SimResult;
use crate::hosted::Hosted;
use crate::launch::{Launch, RunContext};
use crate::observers::{ChartLabels, FieldPlan, OutputPlan, PlotSpec, TableStyle};
use crate::ranks::Ranks;
use crate::scenario::keys::choice;
use crate::scenario::Scenario;
use cellist::longrange::{ErrorFit, Vic3Boundary, Vic3Params};
use cellist::models::vortex3::{
    seed3, Abc, Extras3, InitialVorticity3, Relaxation, Ring, Stretching, Velocity3Engine,
    Velocity3Solver, View3, Vortex3Model, Vortex3Params, Vortex3System, RING_CUT,
};
use cellist::models::Model;
use cellist_io::read_field_columns;
use serde::de::IgnoredAny;
use serde::Deserialize;
use std::path::PathBuf;
use std::time::Instant;

/// The keys of a 3D vortex scenario.
type Vortex3Scenario = FieldScenario<System3Keys>;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct System3Keys {
    initial: Initial3Keys,
    #[serde(default)]
    nu: f64,
    #[serde(default = "one_and_a_half")]
    sigma_over_h: f64,
    #[serde(default = "gaussian")]
    kernel: String,
    velocity: Option<VelocityKeys>,
    #[serde(default)]
    remesh_every: u64,
    #[serde(default = "threshold")]
    remesh_threshold: f64,
    #[serde(default = "four")]
    pse_cutoff_factor: f64,
    #[serde(default = "transpose")]
    stretching: String,
    relaxation: Option<RelaxationKeys>,
}

fn transpose() -> String {
    "transpose".into()
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RelaxationKeys {
    factor: f64,
    #[serde(default = "one")]
    every: u64,
}

fn one() -> u64 {
    1
}

/// One ring's keys (of `kind = "ring"`, or an entry of `rings`).
#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct RingKeys {
    radius: Option<f64>,
    circulation: Option<f64>,
    core: Option<f64>,
    center: Option<Vec<f64>>,
    axis: Option<Vec<f64>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Initial3Keys {
    kind: String,
    spacing: f64,
    #[serde(flatten)]
    ring: RingKeys,
    rings: Option<Vec<RingKeys>>,
    a: Option<f64>,
    b: Option<f64>,
    c: Option<f64>,
    path: Option<PathBuf>,
    // the keys of 2D initial conditions, refused by name
    extent: Option<IgnoredAny>,
    t0: Option<IgnoredAny>,
    separation: Option<IgnoredAny>,
    peak: Option<IgnoredAny>,
    aspect: Option<IgnoredAny>,
    file: Option<IgnoredAny>,
}

/// The kinds of `system.initial` in 3D.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Initial3 {
    Ring,
    Rings,
    Abc,
    File,
}

impl Initial3 {
    /// Every kind with its name in a scenario.
    const NAMES: [(&'static str, Initial3); 4] = [
        ("ring", Initial3::Ring),
        ("rings", Initial3::Rings),
        ("abc", Initial3::Abc),
        ("file", Initial3::File),
    ];

    /// The keys of `system.initial` this kind takes besides `spacing`.
    fn keys(self) -> &'static [&'static str] {
        match self {
            Initial3::Ring => &["radius", "circulation", "core", "center", "axis"],
            Initial3::Rings => &["rings"],
            Initial3::Abc => &["a", "b", "c"],
            Initial3::File => &["path"],
        }
    }
}

/// The particles and how they are described and shown.
struct Seeded3 {
    positions: Vec<[f64; 3]>,
    alpha: Vec<[f64; 3]>,
    extras: Extras3,
    view: View3,
    what: String,
}

/// Three finite numbers, or the message naming `key`.
fn vector(key: &str, v: &Option<Vec<f64>>, default: [f64; 3]) -> Result<[f64; 3], String> {
    match v.as_deref() {
        None => Ok(default),
        Some([x, y, z]) if [x, y, z].iter().all(|c| c.is_finite()) => Ok([*x, *y, *z]),
        Some(other) => Err(format!(
            "{key} must be three finite numbers [x, y, z], got {other:?}"
        )),
    }
}

/// The ring of `keys` (`key` names it in messages), its core resolved by at
/// least 2 spacings `h`.
fn ring_of(key: &str, keys: &RingKeys, h: f64) -> Result<Ring, String> {
    let positive = |name: &str, v: Option<f64>, default: Option<f64>| {
        match v.or(default) {
        Some(v) if v.is_finite() && v > 0.0 => Ok(v),
        Some(v) => Err(format!("{key}.{name} must be > 0, got {v}")),
        None => Err(format!(
            "{key}.{name} is missing (a ring needs radius and core; circulation, center and axis have defaults)"
        )),
    }
    };
    let radius = positive("radius", keys.radius, None)?;
    let core = positive("core", keys.core, None)?;
    let circulation = match keys.circulation.unwrap_or(1.0) {
        g if g.is_finite() && g != 0.0 => g,
        g => {
            return Err(format!(
                "{key}.circulation must be finite and nonzero, got {g}"
            ))
        }
    };
    let center = vector(&format!("{key}.center"), &keys.center, [0.0; 3])?;
    let axis = vector(&format!("{key}.axis"), &keys.axis, [0.0, 0.0, 1.0])?;
    let size = (axis[0] * axis[0] + axis[1] * axis[1] + axis[2] * axis[2]).sqrt();
    if !(size > 0.0 && size.is_finite()) {
        return Err(format!("{key}.axis must not be zero, got {axis:?}"));
    }
    if core < 2.0 * h {
        return Err(format!(
            "{key}.core = {core} is resolved by {:.2} spacings of {h}; the core needs at least 2 (a spacing of at most {})",
            core / h,
            0.5 * core
        ));
    }
    if core >= radius {
        return Err(format!(
            "{key}.core = {core} must be smaller than its radius {radius} (a ring, not a blob)"
        ));
    }
    Ok(Ring {
        radius,
        circulation,
        core,
        center,
        axis: axis.map(|c| c / size),
    })
}

/// Seeds the particles of `system.initial`.
fn seed_particles(scenario: &Scenario, sys: &System3Keys) -> SimResult<Seeded3> {
    let err = |m: String| scenario.error(m);
    let i = &sys.initial;
    let two_d = [
        ("extent", i.extent.is_some()),
        ("t0", i.t0.is_some()),
        ("separation", i.separation.is_some()),
        ("peak", i.peak.is_some()),
        ("aspect", i.aspect.is_some()),
        ("file", i.file.is_some()),
    ];
    if let Some((name, _)) = two_d.iter().find(|(_, g)| *g) {
        let hint = if *name == "file" {
            "; a 3D file is named by path = \"...\""
        } else {
            ""
        };
        return Err(err(format!(
            "system.initial.{name} is a key of 2D initial conditions, not of dimension = 3{hint}"
        )));
    }
    let names: Vec<&str> = Initial3::NAMES.iter().map(|(n, _)| *n).collect();
    let kind = choice("system.initial.kind", &i.kind, &Initial3::NAMES).map_err(|m| {
        err(format!(
            "{m} (with dimension = 3; {} are 2D initial conditions)",
            "lamb-oseen, gaussian, pair and ellipse"
        ))
    })?;
    let given = [
        ("radius", i.ring.radius.is_some()),
        ("circulation", i.ring.circulation.is_some()),
        ("core", i.ring.core.is_some()),
        ("center", i.ring.center.is_some()),
        ("axis", i.ring.axis.is_some()),
        ("rings", i.rings.is_some()),
        ("a", i.a.is_some()),
        ("b", i.b.is_some()),
        ("c", i.c.is_some()),
        ("path", i.path.is_some()),
    ];
    if let Some((name, _)) = given.iter().find(|(n, g)| *g && !kind.keys().contains(n)) {
        return Err(err(format!(
            "system.initial: a 3D {} takes spacing and {}, not {name} (kinds: {})",
            i.kind,
            kind.keys().join(", "),
            names.join(", ")
        )));
    }
    let h = i.spacing;
    if !(h.is_finite() && h > 0.0) {
        return Err(err(format!("system.initial.spacing must be > 0, got {h}")));
    }
    let field = match kind {
        Initial3::Ring => Some(InitialVorticity3::Rings(vec![ring_of(
            "system.initial",
            &i.ring,
            h,
        )
        .map_err(err)?])),
        Initial3::Rings => {
            let list = i.rings.as_deref().unwrap_or_default();
            if list.is_empty() {
                return Err(err(
                    "system.initial.rings is missing or empty: rings = [{ radius = 1.0, core = 0.1 }, ...]".into(),
                ));
            }
            let rings = list
                .iter()
                .enumerate()
                .map(|(k, r)| ring_of(&format!("system.initial.rings[{k}]"), r, h))
                .collect::<Result<Vec<_>, _>>()
                .map_err(err)?;
            Some(InitialVorticity3::Rings(rings))
        }
        Initial3::Abc => {
            let coefficient = |name: &str, v: Option<f64>| match v.unwrap_or(1.0) {
                v if v.is_finite() => Ok(v),
                v => Err(err(format!(
                    "system.initial.{name} must be finite, got {v}"
                ))),
            };
            let abc = Abc {
                a: coefficient("a", i.a)?,
                b: coefficient("b", i.b)?,
                c: coefficient("c", i.c)?,
            };
            Some(InitialVorticity3::Abc(abc))
        }
        Initial3::File => None,
    };
    let Some(field) = field else {
        let path = i.path.as_ref().ok_or_else(|| {
            err("system.initial.path is missing (a file initial condition needs path = \"particles.csv\" with columns x y z ax ay az)".into())
        })?;
        let (positions, alpha) =
            read_field_columns::<3, 3>(&scenario.input_path(path), ["ax", "ay", "az"])?;
        let (lo, hi) = cellist::geometry::bounding_box(&positions);
        let side = (0..3).map(|a| hi[a] - lo[a]).fold(0.0, f64::max) + 4.0 * h;
        let view = View3 {
            axes: [0, 1, 2],
            origin: [0, 1, 2].map(|a| 0.5 * (lo[a] + hi[a]) - 0.5 * side),
            side,
            periodic: false,
        };
        return Ok(Seeded3 {
            positions,
            alpha,
            extras: Extras3::None,
            view,
            what: format!("particles from {}", path.display()),
        });
    };
    let nodes = field.nodes_visited(h);
    if nodes > MAX_SEEDED {
        return Err(err(format!(
            "system.initial: spacing {h} visits {nodes:.3e} lattice nodes, more than {MAX_SEEDED:.0e}; use a larger spacing"
        )));
    }
    let (positions, alpha) = seed3(&field, h);
    let (extras, view, what) = match field {
        InitialVorticity3::Rings(rings) => {
            let view = ring_view(&rings, h);
            let what = match rings.as_slice() {
                [r] => format!(
                    "a vortex ring of radius {}, circulation {} and core {}",
                    r.radius, r.circulation, r.core
                ),
                many => format!("{} vortex rings", many.len()),
            };
            let extras = match <[Ring; 1]>::try_from(rings) {
                Ok([ring]) => Extras3::Ring(ring),
                Err(rings) => Extras3::Rings(rings),
            };
            (extras, view, what)
        }
        InitialVorticity3::Abc(abc) => {
            let view = View3 {
                axes: [0, 1, 2],
                origin: [0.0; 3],
                side: Abc::SIDE,
                periodic: true,
            };
            let what = format!(
                "the ABC flow (A {}, B {}, C {}) in the periodic box [0, 2 pi)^3",
                abc.a, abc.b, abc.c
            );
            (Extras3::Abc(abc), view, what)
        }
    };
    Ok(Seeded3 {
        positions,
        alpha,
        extras,
        view,
        what: format!("{what}, seeded on a lattice of spacing {h}"),
    })
}

/// The square the pictures of rings show: the plane through the first ring's
/// axis, drawn upwards (the axis's largest component), wide enough for every
/// ring with a margin; the model moves it along the axis with the rings.
fn ring_view(rings: &[Ring], h: f64) -> View3 {
    let first = rings[0];
    let up = (0..3)
        .max_by(|&a, &b| first.axis[a].abs().total_cmp(&first.axis[b].abs()))
        .unwrap_or(2);
    let across = (0..3).find(|&a| a != up).unwrap_or(0);
    let normal = 3 - up - across;
    let reach = rings
        .iter()
        .map(|r| {
            let d = [0, 1, 2].map(|a| r.center[a] - first.center[a]);
            (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt() + r.radius + RING_CUT * r.core
        })
        .fold(0.0, f64::max);
    let side = 2.0 * reach + 4.0 * h;
    View3 {
        axes: [across, up, normal],
        origin: first.center.map(|c| c - 0.5 * side),
        side,
        periodic: false,
    }
}

/// The 3D velocity solver of `system.velocity` (default: the tree), the
/// periodic box `[0, L)^3` for the ABC flow and centred on the origin otherwise.
fn solver3(
    scenario: &Scenario,
    velocity: Option<&VelocityKeys>,
    abc: bool,
) -> SimResult<Velocity3Solver> {
    let err = |m: String| scenario.error(m);
    let abc_needs = "the abc initial condition needs the periodic mesh solver: velocity = { kind = \"mesh\", boundary = \"periodic\", box = 6.283185307179586, grid = 32 }";
    let Some(velocity) = velocity else {
        if abc {
            return Err(err(abc_needs.into()));
        }
        return Ok(Velocity3Solver::BarnesHut(default_tree()));
    };
    Ok(
        match solver_choice(scenario, velocity, default_tree().theta)? {
            SolverChoice::Direct
            | SolverChoice::BarnesHut(_)
            | SolverChoice::Fmm(_)
            | SolverChoice::Mesh { periodic: None, .. }
                if abc =>
            {
                return Err(err(abc_needs.into()))
            }
            SolverChoice::Direct => Velocity3Solver::Direct,
            SolverChoice::Fmm(accuracy) => Velocity3Solver::Fmm(accuracy),
            SolverChoice::BarnesHut(p) => Velocity3Solver::BarnesHut(p),
            SolverChoice::Mesh { grid, periodic } => {
                let boundary = match periodic {
                    None => Vic3Boundary::Unbounded,
                    Some(side) if abc => {
                        if (side - Abc::SIDE).abs() > 1e-9 * Abc::SIDE {
                            return Err(err(format!(
                            "system.velocity.box must be 2 pi = {} for the abc flow, got {side}",
                            Abc::SIDE
                        )));
                        }
                        Vic3Boundary::Periodic {
                            origin: [0.0; 3],
                            length: Abc::SIDE,
                        }
                    }
                    Some(side) => Vic3Boundary::Periodic {
                        origin: [-0.5 * side; 3],
                        length: side,
                    },
                };
                let params = Vic3Params {
                    grid: grid.unwrap_or(64),
                    boundary,
                };
                params
                    .check()
                    .map_err(|m| err(format!("system.velocity: {m}")))?;
                Velocity3Solver::Mesh(params)
            }
        },
    )
}

/// The tree settings of 3D runs unless the scenario sets them: the engine's
/// defaults for the 3D vortex tree.
fn default_tree() -> cellist::longrange::TreeParams {
    cellist::longrange::VortexTree3::default_params()
}

/// On several MPI ranks, the velocity solver `solver` for `n` blobs of core
/// `sigma` shared by the ranks (each holding every particle) and the ranks,
/// the run's `mpi:` line said, or for the fmm no solver (the engine of one
/// process, which divides its sums among the system's peers) and the
/// ranks; `(None, Ranks::One)` in one process.
fn distributed_engine(
    scenario: &Scenario,
    context: &RunContext,
    solver: Velocity3Solver,
    n: usize,
    sigma: f64,
) -> SimResult<(Option<Velocity3Engine>, Ranks)> {
    #[cfg(feature = "mpi")]
    {
        use crate::distributed::replicated::{vortex3_mesh, vortex3_pairs, vortex3_tree};
        let err = |m: String| scenario.error(format!("system: {m}"));
        let shared = match solver {
            Velocity3Solver::Mesh(p) => vortex3_mesh(p, sigma),
            Velocity3Solver::BarnesHut(p) => {
                vortex3_tree(p, cellist::longrange::BlobKernel3::new(sigma))
            }
            Velocity3Solver::Direct => {
                vortex3_pairs(n, cellist::longrange::BlobKernel3::new(sigma)).map(Ok)
            }
            Velocity3Solver::Fmm(_) => {
                // the engine of one process, its sums divided among the peers
                if let Some((ranks, line)) = crate::distributed::replicated::vortex_fmm() {
                    context.say(line);
                    return Ok((None, ranks));
                }
                None
            }
        };
        if let Some(shared) = shared {
            let (engine, ranks, line) = shared.map_err(err)?;
            context.say(line);
            return Ok((Some(engine), ranks));
        }
    }
    #[cfg(not(feature = "mpi"))]
    let _ = (scenario, context, solver, n, sigma);
    Ok((None, Ranks::One))
}

/// Runs a 3D vortex scenario, from the checkpoint `restart` if given.
pub fn run<L: Launch>(
    scenario: &Scenario,
    context: &RunContext,
    launch: L,
) -> SimResult<L::Output> {
    let keys: Vortex3Scenario = scenario.parse()?;
    let (threads, out_dir) = (context.threads, &context.out_dir);
    let err = |m: String| scenario.error(m);
    let started = Instant::now();
    let sys = &keys.system;
    check_blob_keys(scenario, context, sys.nu, sys.sigma_over_h, &sys.kernel)?;
    if keys.decomposition.is_some() {
        return Err(err(
            "[decomposition] applies to md and pse (domain decomposition), not to the vortex model"
                .into(),
        ));
    }
    let stretching = choice(
        "system.stretching",
        &sys.stretching,
        &[
            ("transpose", Stretching::Transpose),
            ("classical", Stretching::Classical),
        ],
    )
    .map_err(err)?;
    let run = &keys.run;
    let integrator = run.integrator().map_err(err)?;
    let seeded = seed_particles(scenario, sys)?;
    let abc = matches!(seeded.extras, Extras3::Abc(_));
    let solver = solver3(scenario, sys.velocity.as_ref(), abc)?;
    let mut h = sys.initial.spacing;
    if abc {
        // the box must be a whole number of spacings: 2 pi / n
        let cells = Abc::SIDE / h;
        if (cells - cells.round()).abs() > 1e-6 * cells || cells.round() < 4.0 {
            return Err(err(format!(
                "system.initial.spacing = {h} must divide the ABC box 2 pi into a whole number (at least 4) of cells, e.g. 2 pi / 32 = {}",
                Abc::SIDE / 32.0
            )));
        }
        h = Abc::SIDE / cells.round();
    }
    let sigma = sys.sigma_over_h * h;
    check_diffusion_step(scenario, context, run, integrator, sys.nu, sigma, 3)?;
    let relaxation = sys.relaxation.as_ref().map(|r| Relaxation {
        factor: r.factor,
        every: r.every,
    });
    let params = Vortex3Params {
        nu: sys.nu,
        spacing: h,
        sigma,
        pse_cutoff_factor: sys.pse_cutoff_factor,
        remesh_every: sys.remesh_every,
        remesh_threshold: sys.remesh_threshold,
        stretching,
        relaxation,
        solver,
    };
    params.check().map_err(|m| err(format!("system: {m}")))?;
    if let Some((lo, side)) = params.periodic_box() {
        let outside = seeded.positions.iter().position(|x| {
            (0..3).any(|a| !(lo[a] - 1e-9 * side..lo[a] + side * (1.0 - 1e-9)).contains(&x[a]))
        });
        if let Some(k) = outside {
            return Err(err(format!(
                "system.initial: particle {k} at {:?} lies outside the periodic box [{}, {})^3: make the box larger",
                seeded.positions[k],
                lo[0],
                lo[0] + side
            )));
        }
    }
    let out = &keys.output;
    let steps = run.steps;
    out.check().map_err(err)?;
    let snapshots = out.snapshots(steps, ["vorticity.csv", "vorticity.png", "vorticity.gif"]);
    let n = seeded.positions.len();
    let (engine, ranks) = distributed_engine(scenario, context, solver, n, sigma)?;
    let (positions, alpha, peers) = (seeded.positions, seeded.alpha, ranks.peers());
    let system = match engine {
        Some(engine) => {
            Vortex3System::with_engine(params, positions, alpha, engine, peers, threads)
        }
        None => Vortex3System::among(params, positions, alpha, peers, threads),
    }
    .map_err(|e| err(format!("system: {e}")))?;
    let solver_name = match solver {
        Velocity3Solver::Direct => "direct (all pairs)".to_string(),
        Velocity3Solver::BarnesHut(p) => format!("barnes-hut (theta {})", p.theta),
        Velocity3Solver::Mesh(p) => match p.boundary {
            Vic3Boundary::Unbounded => {
                format!("mesh (vortex-in-cell, grid {}^3, unbounded)", p.grid)
            }
            Vic3Boundary::Periodic { length, .. } => format!(
                "mesh (vortex-in-cell, grid {}^3, periodic box of side {length})",
                p.grid
            ),
        },
        Velocity3Solver::Fmm(a) => super::fmm_keys::fmm_name(a, ErrorFit::VORTEX_3D),
    };
    context.say(format!(
        "vortex (3D): {n} particles, {}; nu {}, sigma {} ({} h), {} stretching, velocity by {solver_name}, remeshing {}{}",
        seeded.what,
        sys.nu,
        sigma,
        sys.sigma_over_h,
        sys.stretching,
        match sys.remesh_every {
            0 => "never".to_string(),
            k => format!("every {k} steps"),
        },
        match relaxation {
            None => String::new(),
            Some(r) => format!(", relaxation {} every {} steps", r.factor, r.every),
        }
    ));
    context.say(format!(
        "run: {steps} steps of dt {} with {}, {} thread(s); results in {}",
        run.dt,
        run.integrator,
        threads.count(),
        out_dir.display()
    ));
    let plot = match &seeded.extras {
        Extras3::Ring(_) => PlotSpec {
            file: "ring.png",
            title: "Vortex ring: position along its axis",
            x_label: "time (simulation units)",
            y_label: "ring z (simulation units)",
            series: vec![("ring", "ring_z", false)],
        },
        Extras3::Rings(rings) => PlotSpec {
            file: "rings.png",
            title: "Vortex rings: positions along the axis",
            x_label: "time (simulation units)",
            y_label: "ring z (simulation units)",
            series: (1..=rings.len().min(RING_NAMES.len()))
                .map(|k| RING_NAMES[k - 1])
                .collect(),
        },
        Extras3::Abc(_) => PlotSpec {
            file: "error.png",
            title: "Vorticity error against the ABC flow",
            x_label: "time (simulation units)",
            y_label: "relative L2 error of ω",
            series: vec![("L2 error", "omega_l2_error", false)],
        },
        Extras3::None => PlotSpec {
            file: "invariants.png",
            title: "Enstrophy and helicity",
            x_label: "time (simulation units)",
            y_label: "enstrophy, helicity (simulation units)",
            series: vec![
                ("enstrophy", "enstrophy", false),
                ("helicity", "helicity", false),
            ],
        },
    };
    let plan = OutputPlan {
        thermo_every: out.thermo_every,
        table: TableStyle {
            width: 19,
            precision: 7,
            exponent: true,
            shown: 7,
        },
        plot: Some(plot),
        dumps: Vec::new(),
        field: Some(FieldPlan {
            csv: snapshots.csv,
            png: snapshots.png,
            gif: snapshots.gif,
            size: out.picture_size,
            chart: ChartLabels {
                title: "|vorticity|",
                value: "|ω| = |α|/h³",
                unit: "simulation units",
                magnitude: true,
            },
        }),
        bodies: None,
        trajectories: out.trajectories().map_err(err)?,
    };
    let model = Vortex3Model::new(system, integrator, run.dt, seeded.extras, seeded.view);
    let spec = JobSpec {
        steps,
        dir: out_dir.to_path_buf(),
        checkpoint: out.checkpoint.clone(),
        physics: scenario.physics_keys()?,
        last_frame: LastFrame::Field { file: "last.csv" },
    };
    launch.launch(spec.with(model).on(ranks), &plan, context, started)
}

/// The plotted series of the first rings: (legend, thermo column, log scale).
const RING_NAMES: [(&str, &str, bool); 4] = [
    ("ring 1", "ring_1_z", false),
    ("ring 2", "ring_2_z", false),
    ("ring 3", "ring_3_z", false),
    ("ring 4", "ring_4_z", false),
];

impl Hosted for Vortex3Model {
    /// Seconds per velocity evaluation and the strength that remeshing dropped.
    fn speed(&self, loop_seconds: f64, steps: u64, threads: usize) -> String {
        let stages = self.integrator.stages() * steps;
        let dropped = self.system.dropped();
        format!(
            "Loop time of {loop_seconds:.4} s on {threads} thread(s) for {steps} steps with {} particles \
             (at the end): {:.4} s per velocity evaluation; |strength| dropped by remeshing {:.3e}",
            self.len(),
            self.system.times().velocity.as_secs_f64() / stages.max(1) as f64,
            (dropped[0] * dropped[0] + dropped[1] * dropped[1] + dropped[2] * dropped[2]).sqrt()
        )
    }
}
