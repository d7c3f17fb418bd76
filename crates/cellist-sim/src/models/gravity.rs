//! `model = "gravity"`: the scenario keys of self-gravitating bodies, the initial
//! bodies (Plummer sphere, seed 004's two bodies, a body file), the solver, and
//! the outputs (thermo with energies and momenta, LAMMPS dumps with accelerations
//! and potentials, the energy-error plot).

use super::fmm_keys::{fmm_accuracy, fmm_name};
use crate::driver::{JobSpec, LastFrame};
use crate::error::{SimError, SimResult};
use crate::hosted::Hosted;
use crate::launch::{Launch, RunContext};
use crate::models::field_output::{check_picture_size, SnapshotKeys};
use crate::observers::{BodyPlan, DumpFormat, DumpPlan, OutputPlan, PlotSpec, TableStyle};
use crate::ranks::Ranks;
use crate::scenario::keys::CheckpointKeys;
use crate::scenario::keys::{SeriesKeys, TrajectoryKeys};
use crate::scenario::Scenario;
use cellist::interactions::GravityLaw;
use cellist::longrange::p3m::SPLIT_CELLS;
use cellist::longrange::{ErrorFit, FmmAccuracy, GravityFmm, MeshBoundary, MeshParams, TreeParams};
use cellist::models::gravity::{
    plummer_part, two_body_seed004, Bodies, GravityError, GravityModel, GravitySystem, Integrator,
    Solver, SolverChoice,
};
use cellist::models::Model;
use cellist_io::{read_bodies, read_bodies_part, BodyChart, Parts, Plane, GRAVITY_DUMP_COLUMNS};
use serde::Deserialize;
use std::path::PathBuf;
use std::time::Instant;

/// The most bodies a generated sphere or a benchmark may have (about 1 GB of
/// bodies and solver buffers).
pub const MAX_BODIES: usize = 10_000_000;

/// The keys of a gravity scenario.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct GravityScenario {
    model: String,
    #[serde(default = "three")]
    dimension: u64,
    system: SystemKeys,
    run: RunKeys,
    #[serde(default)]
    output: OutputKeys,
}

fn three() -> u64 {
    3
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SystemKeys {
    initial: InitialKeys,
    #[serde(rename = "G", default = "one")]
    g: f64,
    #[serde(default)]
    softening: f64,
    #[serde(default)]
    repulsion_radius: f64,
    #[serde(default = "direct")]
    solver: SolverKeys,
}

fn one() -> f64 {
    1.0
}

fn direct() -> SolverKeys {
    SolverKeys::Name("direct".into())
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct InitialKeys {
    kind: Option<String>,
    n: Option<i64>,
    seed: Option<u64>,
    file: Option<PathBuf>,
}

/// `solver = "direct"` or `solver = { kind = ..., ... }`.
enum SolverKeys {
    Name(String),
    Table(SolverTable),
}

/// By the value's type, so that a table's own error (such as an unknown key) is
/// reported, not serde's "did not match any variant of untagged enum".
impl<'de> Deserialize<'de> for SolverKeys {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct Keys;
        impl<'de> serde::de::Visitor<'de> for Keys {
            type Value = SolverKeys;
            fn expecting(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.write_str("a solver name such as \"direct\" or a table { kind = ..., ... }")
            }
            fn visit_str<E: serde::de::Error>(self, name: &str) -> Result<SolverKeys, E> {
                Ok(SolverKeys::Name(name.to_string()))
            }
            fn visit_map<A: serde::de::MapAccess<'de>>(
                self,
                map: A,
            ) -> Result<SolverKeys, A::Error> {
                SolverTable::deserialize(serde::de::value::MapAccessDeserializer::new(map))
                    .map(SolverKeys::Table)
            }
        }
        d.deserialize_any(Keys)
    }
}

#[derive(Deserialize, Clone, Default)]
#[serde(deny_unknown_fields)]
struct SolverTable {
    kind: String,
    theta: Option<f64>,
    quadrupole: Option<bool>,
    leaf_size: Option<i64>,
    group_size: Option<i64>,
    grid: Option<i64>,
    split: Option<f64>,
    boundary: Option<String>,
    #[serde(rename = "box")]
    side: Option<f64>,
    tolerance: Option<f64>,
    order: Option<usize>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RunKeys {
    steps: u64,
    dt: f64,
    #[serde(default = "leapfrog")]
    integrator: String,
}

fn leapfrog() -> String {
    "leapfrog".into()
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields, default)]
struct OutputKeys {
    thermo_every: u64,
    dump: Option<DumpKeys>,
    checkpoint: Option<CheckpointKeys>,
    gsd: Option<SeriesKeys>,
    vtk: Option<SeriesKeys>,
    /// PNG snapshots of the bodies (default: `bodies.png` of the last step).
    png: Option<SnapshotKeys>,
    /// The GIF animation of the bodies (default none).
    gif: Option<SnapshotKeys>,
    /// The pictures' width in pixels (at least 640 are drawn).
    picture_size: u32,
    /// The plane the pictures project the bodies on: "xy", "xz" or "yz".
    plane: String,
}

impl Default for OutputKeys {
    fn default() -> Self {
        OutputKeys {
            thermo_every: 10,
            dump: None,
            checkpoint: None,
            gsd: None,
            vtk: None,
            png: None,
            gif: None,
            picture_size: 512,
            plane: "xy".into(),
        }
    }
}

#[derive(Deserialize, Clone)]
#[serde(deny_unknown_fields)]
struct DumpKeys {
    every: u64,
    #[serde(default = "dump_file")]
    file: PathBuf,
    #[serde(default = "dump_columns")]
    columns: Vec<String>,
}

fn dump_file() -> PathBuf {
    "bodies.dump".into()
}

fn dump_columns() -> Vec<String> {
    GRAVITY_DUMP_COLUMNS.iter().map(|c| c.to_string()).collect()
}

/// Everything a run needs, checked.
struct Setup {
    dimension: usize,
    law: GravityLaw,
    /// This process's bodies: all of them, or under MPI its block
    /// `first..first + bodies.len()` of the input order.
    bodies: Bodies,
    /// The index in the input order of `bodies`' first.
    first: usize,
    /// The number of bodies on every rank.
    total: usize,
    initial: String,
    choice: SolverChoice,
    solver_name: String,
    integrator: Integrator,
    integrator_name: String,
    dt: f64,
    steps: u64,
    thermo_every: u64,
    dump: Option<DumpKeys>,
    checkpoint: Option<CheckpointKeys>,
    trajectories: TrajectoryKeys,
    pictures: Pictures,
}

/// The pictures of the bodies a scenario asks for.
struct Pictures {
    png: Option<SnapshotKeys>,
    gif: Option<SnapshotKeys>,
    size: u32,
    plane: Plane,
}

/// Runs a gravity scenario, from the checkpoint `restart` if given.
pub fn run<L: Launch>(
    scenario: &Scenario,
    context: &RunContext,
    launch: L,
) -> SimResult<L::Output> {
    let keys: GravityScenario = scenario.parse()?;
    debug_assert_eq!(keys.model, "gravity");
    if !(keys.dimension == 2 || keys.dimension == 3) {
        return Err(scenario.error(format!("dimension must be 2 or 3, got {}", keys.dimension)));
    }
    let ranks = body_ranks();
    let setup = build(scenario, &keys, context, &ranks)?;
    if keys.dimension == 2 {
        let b = &setup.bodies;
        let off_plane = (0..b.len())
            .find(|&i| b.position[i][2] != 0.0 || b.velocity[i][2] != 0.0)
            .map(|i| {
                format!(
                    "dimension = 2 needs z = 0 and vz = 0 for every body (the plane z = 0 of \
                     the 3D model); body {} has z = {}, vz = {}",
                    setup.first + i,
                    b.position[i][2],
                    b.velocity[i][2]
                )
            });
        // the lowest rank's body is the first in the input order
        if let Some(message) = ranks.agree(off_plane) {
            return Err(scenario.error(message));
        }
    }
    run_setup(scenario, setup, context, launch, ranks)
}

/// The ranks the bodies are divided among: under MPI on several ranks, each
/// holds a block of the input order from the start ([`Ranks::block_of`]).
fn body_ranks() -> Ranks {
    #[cfg(feature = "mpi")]
    if let Some(world) = crate::distributed::world_of_many() {
        return Ranks::Spread(world);
    }
    Ranks::One
}

/// The solver of `keys` and its name for messages.
fn solver_choice(keys: &SolverKeys) -> Result<(SolverChoice, String), String> {
    let table = match keys {
        SolverKeys::Name(name) => SolverTable {
            kind: name.clone(),
            ..SolverTable::default()
        },
        SolverKeys::Table(t) => t.clone(),
    };
    const TREE: &[&str] = &["barnes-hut"];
    const MESH: &[&str] = &["pm", "p3m"];
    for (key, set, kinds) in [
        ("theta", table.theta.is_some(), TREE),
        ("quadrupole", table.quadrupole.is_some(), TREE),
        ("leaf_size", table.leaf_size.is_some(), TREE),
        ("group_size", table.group_size.is_some(), TREE),
        ("grid", table.grid.is_some(), MESH),
        ("boundary", table.boundary.is_some(), MESH),
        ("box", table.side.is_some(), MESH),
        ("split", table.split.is_some(), &["p3m"]),
        ("tolerance", table.tolerance.is_some(), &["fmm"]),
        ("order", table.order.is_some(), &["fmm"]),
    ] {
        if set && !kinds.contains(&table.kind.as_str()) {
            return Err(format!(
                "system.solver.{key} applies to kind = {} only",
                kinds
                    .iter()
                    .map(|k| format!("\"{k}\""))
                    .collect::<Vec<_>>()
                    .join(" or ")
            ));
        }
    }
    match table.kind.as_str() {
        "direct" => Ok((SolverChoice::Direct, "direct (all pairs)".into())),
        "barnes-hut" => {
            let d = TreeParams::default();
            let size = |key: &str, v: Option<i64>, default: usize| {
                v.map_or(Ok(default), |v| {
                    usize::try_from(v).map_err(|_| format!("system.solver.{key} must be in 1..=256, got {v}"))
                })
            };
            let params = TreeParams {
                theta: table.theta.unwrap_or(d.theta),
                quadrupole: table.quadrupole.unwrap_or(d.quadrupole),
                leaf_size: size("leaf_size", table.leaf_size, d.leaf_size)?,
                group_size: size("group_size", table.group_size, d.group_size)?,
            };
            params.check().map_err(|e| format!("system.solver: {e}"))?;
            Ok((SolverChoice::BarnesHut(params), tree_name(&params)))
        }
        "pm" | "p3m" => {
            let grid = table.grid.unwrap_or(64);
            let grid = usize::try_from(grid)
                .map_err(|_| format!("system.solver.grid must be a power of two >= 8, got {grid}"))?;
            let boundary = mesh_boundary(table.boundary.as_deref(), table.side)?;
            let mesh = MeshParams { grid, boundary };
            if table.kind == "pm" {
                Ok((SolverChoice::Pm(mesh), mesh_name("pm", &mesh, None)))
            } else {
                let split_cells = table.split.unwrap_or(SPLIT_CELLS);
                Ok((SolverChoice::P3m { mesh, split_cells }, mesh_name("p3m", &mesh, Some(split_cells))))
            }
        }
        "fmm" => {
            let accuracy = fmm_accuracy("system.solver", table.tolerance, table.order)?;
            Ok((SolverChoice::Fmm(accuracy), fmm_name(accuracy, ErrorFit::LAPLACE_3D)))
        }
        other => Err(format!(
            "system.solver kind '{other}' is unknown; expected \"direct\", \"barnes-hut\", \"pm\", \"p3m\" or \"fmm\""
        )),
    }
}

/// `boundary = "isolated"` (default) or `"periodic"` with `box = L`: the periodic
/// cube of side `L` centred on the origin.
fn mesh_boundary(boundary: Option<&str>, side: Option<f64>) -> Result<MeshBoundary, String> {
    match (boundary.unwrap_or("isolated"), side) {
        ("isolated", None) => Ok(MeshBoundary::Isolated),
        ("isolated", Some(_)) => {
            Err("system.solver.box applies to boundary = \"periodic\" only".into())
        }
        ("periodic", Some(l)) if l.is_finite() && l > 0.0 => Ok(MeshBoundary::Periodic {
            origin: [-0.5 * l; 3],
            length: l,
        }),
        ("periodic", Some(l)) => Err(format!("system.solver.box must be > 0, got {l}")),
        ("periodic", None) => Err(
            "system.solver.boundary = \"periodic\" needs box = L (the cube [-L/2, L/2)^3)".into(),
        ),
        (other, _) => Err(format!(
            "system.solver.boundary '{other}' is unknown; expected \"isolated\" or \"periodic\""
        )),
    }
}

fn tree_name(p: &TreeParams) -> String {
    format!(
        "barnes-hut (theta {}, {}, leaves of {}, groups of {})",
        p.theta,
        if p.quadrupole {
            "quadrupoles"
        } else {
            "monopoles"
        },
        p.leaf_size,
        p.group_size
    )
}

fn mesh_name(kind: &str, mesh: &MeshParams, split: Option<f64>) -> String {
    let boundary = match mesh.boundary {
        MeshBoundary::Isolated => "isolated".to_string(),
        MeshBoundary::Periodic { length, .. } => format!("periodic box {length}"),
    };
    let split = split.map_or(String::new(), |s| format!(", split {s} cells"));
    format!("{kind} (grid {}^3, {boundary}{split})", mesh.grid)
}

/// The initial bodies of `keys`: this process's block of them
/// ([`Ranks::block_of`]; a Plummer sphere is drawn without the others), its
/// first index, the number of all bodies, and a description.
fn initial_bodies(
    scenario: &Scenario,
    keys: &InitialKeys,
    law: &GravityLaw,
    context: &RunContext,
    ranks: &Ranks,
) -> SimResult<(Bodies, usize, usize, String)> {
    let (bodies, total, text) = all_or_part(scenario, keys, law, context, ranks)?;
    Ok((bodies, ranks.block_of(total).start, total, text))
}

/// The bodies of [`initial_bodies`], the number of all, and the description.
fn all_or_part(
    scenario: &Scenario,
    keys: &InitialKeys,
    law: &GravityLaw,
    context: &RunContext,
    ranks: &Ranks,
) -> SimResult<(Bodies, usize, String)> {
    let err = |m: String| scenario.error(m);
    match (&keys.kind, &keys.file) {
        (Some(_), Some(_)) => Err(err("system.initial has both kind and file; give one".into())),
        (None, None) => Err(err(
            "system.initial needs kind = \"plummer\" (with n, seed), kind = \"two-body-seed004\", or file = \"bodies.txt\"".into(),
        )),
        (None, Some(file)) => {
            if keys.n.is_some() || keys.seed.is_some() {
                return Err(err("system.initial.n and .seed apply to kind = \"plummer\" only".into()));
            }
            let path = scenario.input_path(file);
            let read = if ranks.is_spread() {
                read_bodies_part(&path, |n| ranks.block_of(n))
            } else {
                read_bodies(&path).map(|all| {
                    let n = all.mass.len();
                    (all, n)
                })
            };
            let read = read.map_err(|e| e.to_string());
            // one message when a rank cannot read the file; every rank's blocks of one count
            if let Some(message) = ranks.agree(read.as_ref().err().cloned()) {
                return Err(SimError::Input(message));
            }
            let (read, n) = read.map_err(SimError::Input)?;
            let [most, least] = ranks.largest([n as f64, -(n as f64)]);
            if most != -least {
                return Err(SimError::Input(format!(
                    "{}: the file changed while the ranks read it ({} to {most} bodies counted)",
                    path.display(),
                    -least
                )));
            }
            if read.extra_columns {
                context.warn(format!("{}: columns after the 7th (m x y z vx vy vz) are ignored", path.display()));
            }
            let text = format!("{n} bodies from {}", path.display());
            Ok((Bodies { mass: read.mass, position: read.position, velocity: read.velocity }, n, text))
        }
        (Some(kind), None) => match kind.as_str() {
            "plummer" => {
                let n = keys.n.ok_or_else(|| err("system.initial.n is required for a Plummer sphere".into()))?;
                if !(2..=MAX_BODIES as i64).contains(&n) {
                    return Err(err(format!("system.initial.n must be in 2..={MAX_BODIES}, got {n}")));
                }
                let seed = keys.seed.unwrap_or(1);
                let n = n as usize;
                let bodies = plummer_part(n, seed, law, context.threads, ranks.block_of(n));
                Ok((bodies, n, format!("Plummer sphere of {n} bodies (seed {seed}, G = M = a = 1, virial 2T = |W|)")))
            }
            "two-body-seed004" => {
                if keys.n.is_some() || keys.seed.is_some() {
                    return Err(err("system.initial.n and .seed apply to kind = \"plummer\" only".into()));
                }
                Ok((two_body_seed004().part(ranks.block_of(2)), 2, "seed 004's two bodies (m = 50 at (0,0,0) and (0,30,0), v = (1,0,0))".into()))
            }
            other => Err(err(format!(
                "system.initial.kind '{other}' is unknown; expected \"plummer\" or \"two-body-seed004\" (or file = ...)"
            ))),
        },
    }
}

/// Bodies sampled by [`warn_direct_fmm`].
const REACH_SAMPLE: usize = 1000;

/// Warns when the fmm would sum most pairs of the bodies one by one: when
/// more than half the pairs of at most [`REACH_SAMPLE`] bodies spread evenly
/// through the input order lie closer than the law's
/// [`GravityFmm::direct_reach`] (with the examples' softening 0.01 at
/// tolerance 1e-6, 12 length units: nearly every pair of a Plummer sphere).
/// This process holds the bodies `first..` of `total` at `positions`; the
/// sample is gathered from every rank (collective).
fn warn_direct_fmm(
    (positions, first, total): (&[[f64; 3]], usize, usize),
    law: &GravityLaw,
    accuracy: FmmAccuracy,
    context: &RunContext,
    ranks: &Ranks,
) {
    let reach = GravityFmm::direct_reach(law, accuracy);
    let every = total.div_ceil(REACH_SAMPLE).max(1);
    let mine: Vec<f64> = (first.next_multiple_of(every)..first + positions.len())
        .step_by(every)
        .flat_map(|i| positions[i - first])
        .collect();
    let peers = ranks.exchange();
    let mut counts = vec![0.0; peers.ranks()];
    peers.all_gather(&[mine.len() as f64], &vec![1; peers.ranks()], &mut counts);
    let counts: Vec<usize> = counts.iter().map(|&c| c as usize).collect();
    let mut gathered = vec![0.0; counts.iter().sum()];
    peers.all_gather(&mine, &counts, &mut gathered);
    let sample: Vec<[f64; 3]> = gathered
        .chunks_exact(3)
        .map(|x| [x[0], x[1], x[2]])
        .collect();
    let (mut closer, mut pairs) = (0u64, 0u64);
    for (i, a) in sample.iter().enumerate() {
        for b in &sample[i + 1..] {
            let d2: f64 = (0..3).map(|k| (a[k] - b[k]).powi(2)).sum();
            closer += u64::from(d2 < reach * reach);
            pairs += 1;
        }
    }
    if 2 * closer > pairs {
        let tolerance = accuracy.tolerance(ErrorFit::LAPLACE_3D);
        let mut causes = Vec::new();
        if law.softening() > 0.0 {
            causes.push(format!("the softening ({})", law.softening()));
        }
        if law.has_repulsion() {
            causes.push(format!("the repulsion (radius {})", law.repulsion_radius()));
        }
        let looser = match accuracy {
            FmmAccuracy::Tolerance(_) => "a larger tolerance",
            FmmAccuracy::Order(_) => "a lower order",
        };
        context.warn(format!(
            "system.solver: the fmm sums directly every pair of bodies closer than {reach:.3}, \
             where {} {} the law more than the tolerance ({tolerance:e}) away from 1/r: \
             {:.0}% of the pairs here, so it may cost more than solver = \"direct\" (\"direct\" \
             or \"barnes-hut\", a smaller softening or {looser} is faster)",
            causes.join(" and "),
            if causes.len() > 1 { "keep" } else { "keeps" },
            100.0 * closer as f64 / pairs as f64
        ));
    }
}

/// Checks the scenario and builds the bodies.
fn build(
    scenario: &Scenario,
    keys: &GravityScenario,
    context: &RunContext,
    ranks: &Ranks,
) -> SimResult<Setup> {
    let err = |m: String| scenario.error(m);
    let s = &keys.system;
    if !(s.softening.is_finite() && s.softening >= 0.0) {
        return Err(err(format!(
            "system.softening must be >= 0, got {}",
            s.softening
        )));
    }
    let law = GravityLaw::new(s.g, s.softening, s.repulsion_radius)
        .map_err(|e| err(format!("system: {e}")))?;
    let (choice, solver_name) = solver_choice(&s.solver).map_err(err)?;
    let (bodies, first, total, initial) =
        initial_bodies(scenario, &s.initial, &law, context, ranks)?;
    let integrator = Integrator::from_name(&keys.run.integrator).ok_or_else(|| {
        err(format!(
            "run.integrator '{}' is unknown; expected one of: {}",
            keys.run.integrator,
            Integrator::ALL.map(|(n, _)| n).join(", ")
        ))
    })?;
    if !(keys.run.dt.is_finite() && keys.run.dt > 0.0) {
        return Err(err(format!("run.dt must be > 0, got {}", keys.run.dt)));
    }
    if let Some(c) = &keys.output.checkpoint {
        c.check("output.checkpoint").map_err(err)?;
    }
    check_picture_size(keys.output.picture_size).map_err(err)?;
    let plane = Plane::from_name(&keys.output.plane).ok_or_else(|| {
        err(format!(
            "output.plane '{}' is unknown; expected \"xy\", \"xz\" or \"yz\"",
            keys.output.plane
        ))
    })?;
    if keys.dimension == 2 && plane != Plane::Xy {
        return Err(err(format!(
            "output.plane = \"{}\" shows a line of a 2D run (the bodies lie in z = 0); use \"xy\"",
            keys.output.plane
        )));
    }
    if let Some(d) = &keys.output.dump {
        if d.every == 0 {
            return Err(err("output.dump.every must be >= 1".into()));
        }
        if d.columns.is_empty() {
            return Err(err("output.dump.columns is empty".into()));
        }
        if let Some(c) = d
            .columns
            .iter()
            .find(|c| !GRAVITY_DUMP_COLUMNS.contains(&c.as_str()))
        {
            return Err(err(format!(
                "output.dump.columns: '{c}' is unknown; expected some of {}",
                GRAVITY_DUMP_COLUMNS.join(" ")
            )));
        }
    }
    if let SolverChoice::Fmm(accuracy) = choice {
        warn_direct_fmm(
            (&bodies.position, first, total),
            &law,
            accuracy,
            context,
            ranks,
        );
    }
    Ok(Setup {
        dimension: keys.dimension as usize,
        law,
        bodies,
        first,
        total,
        initial,
        choice,
        solver_name,
        integrator,
        integrator_name: keys.run.integrator.clone(),
        dt: keys.run.dt,
        steps: keys.run.steps,
        thermo_every: keys.output.thermo_every,
        dump: keys.output.dump.clone(),
        checkpoint: keys.output.checkpoint.clone(),
        trajectories: TrajectoryKeys::checked(keys.output.gsd.clone(), keys.output.vtk.clone())
            .map_err(err)?,
        pictures: Pictures {
            png: keys.output.png.clone(),
            gif: keys.output.gif.clone(),
            size: keys.output.picture_size,
            plane,
        },
    })
}

/// The pictures of the bodies: PNG snapshots when `png` asks for them, else
/// `bodies.png` of the last step (none for `every = 0`), and the animation when
/// `gif` asks for it. The view (a square around the centre of mass holding 98 %
/// of the bodies, with a margin) and the colour scale (the speed 98 % of the
/// bodies do not exceed, at least the circular speed `sqrt(G M / R)` at the
/// view's half side `R`) come from the initial bodies, the same for the whole
/// run and after a restart. The bodies may be divided among `parts`
/// (collective): the same plan as one process's.
fn body_plan(setup: &Setup, parts: &dyn Parts) -> Option<BodyPlan> {
    let p = &setup.pictures;
    let png = p.png.as_ref().and_then(|k| k.every("bodies.png"));
    let final_png = p.png.is_none().then(|| PathBuf::from("bodies.png"));
    let gif = p.gif.as_ref().and_then(|k| k.every("bodies.gif"));
    if png.is_none() && final_png.is_none() && gif.is_none() {
        return None;
    }
    let b = &setup.bodies;
    let (lo, side) = BodyChart::view_among(&b.position, Some(&b.mass), p.plane, 0.98, parts);
    let g = setup.law.g();
    // the total mass in input order, from -0.0 as `Iterator::sum` starts
    let mut mass = [-0.0];
    parts.fold(&mut mass, &mut |m| b.mass.iter().for_each(|x| m[0] += x));
    let circular = (g * mass[0] / (0.5 * side)).sqrt();
    let top = BodyChart::speed_scale_among(&b.velocity, 0.98, circular, parts);
    let mut chart = BodyChart::new(p.plane, lo, side, top, setup.total);
    chart.frame.width = chart.frame.width.max(p.size);
    chart.set_dot_radius(setup.total);
    chart.frame.unit = if g == 1.0 {
        "simulation units, G = 1".into()
    } else {
        "simulation units".into()
    };
    chart.frame.value_label = "speed |v| (simulation units)".into();
    Some(BodyPlan {
        png,
        final_png,
        gif,
        chart,
    })
}

fn run_setup<L: Launch>(
    scenario: &Scenario,
    mut setup: Setup,
    context: &RunContext,
    launch: L,
    ranks: Ranks,
) -> SimResult<L::Output> {
    let (threads, out_dir) = (context.threads, &context.out_dir);
    let started = Instant::now();
    #[cfg(feature = "mpi")]
    if let Ranks::Spread(world) = ranks {
        use crate::distributed::gravity::SpreadField;
        let field = match setup.choice {
            SolverChoice::Pm(mesh) => SpreadField::Pm(mesh),
            SolverChoice::P3m { mesh, split_cells } => SpreadField::P3m(mesh, split_cells),
            SolverChoice::BarnesHut(params) => SpreadField::Tree(params),
            SolverChoice::Direct => SpreadField::Ring,
            SolverChoice::Fmm(accuracy) => SpreadField::Fmm(accuracy),
        };
        return run_spread(scenario, setup, context, launch, world, field, started);
    }
    // the solver of one process (a distributed one builds its own part)
    let solver =
        Solver::new(&setup.choice, setup.law, setup.bodies.len()).map_err(|e| scenario.error(e))?;
    let plan = output_plan(&setup, &ranks);
    let bodies = std::mem::take(&mut setup.bodies);
    let system =
        GravitySystem::with_solver(setup.law, bodies, solver, threads).map_err(|e| match e {
            GravityError::NotFinite { .. } => {
                scenario.error(format!("step 0 (the first forces): {e}"))
            }
            GravityError::Parameter(_) => scenario.error(e),
        })?;
    say_setup(&setup, context);
    let mut model = GravityModel::new(system, setup.integrator, setup.dt);
    model.dimension = setup.dimension;
    let spec = job_spec(scenario, &setup, out_dir)?;
    launch.launch(spec.with(model).on(Ranks::One), &plan, context, started)
}

/// The run of `setup` into `dir`: its steps, checkpoints, physics keys and
/// last frame.
fn job_spec(scenario: &Scenario, setup: &Setup, dir: &std::path::Path) -> SimResult<JobSpec> {
    Ok(JobSpec {
        steps: setup.steps,
        dir: dir.to_path_buf(),
        checkpoint: setup.checkpoint.clone(),
        physics: scenario.physics_keys()?,
        last_frame: LastFrame::Dump {
            file: "last.dump",
            columns: dump_columns(),
        },
    })
}

/// On the ranks of `world`, the run with the bodies divided among the ranks
/// and their field by `field` ([`DistributedGravity`]).
#[cfg(feature = "mpi")]
fn run_spread<L: Launch>(
    scenario: &Scenario,
    mut setup: Setup,
    context: &RunContext,
    launch: L,
    world: mpi::topology::SimpleCommunicator,
    field: crate::distributed::gravity::SpreadField,
    started: Instant,
) -> SimResult<L::Output> {
    use crate::distributed::gravity::{DistributedGravity, SpreadField};
    use crate::distributed::replicated::slab_planes;
    use mpi::traits::Communicator;
    let (ranks, n) = (world.size() as usize, setup.total);
    context.say(match field {
        SpreadField::Ring => format!(
            "mpi: {ranks} ranks; the direct sum by the ring pass, each rank holding and summing \
             for a block of about {} bodies",
            n / ranks
        ),
        SpreadField::Pm(mesh) => format!(
            "mpi: {ranks} ranks; the particle-mesh on a slab-decomposed mesh, each rank holding \
             a block of about {} bodies and a slab of {} (the FFT's transposes by all-to-all); \
             the bodies sent to the slabs their clouds touch, their fields sent back",
            n / ranks,
            slab_planes(mesh.grid, ranks)
        ),
        SpreadField::Tree(_) => format!(
            "mpi: {ranks} ranks; the Barnes-Hut tree by locally essential trees, each rank \
             holding a block of about {} bodies; the bodies sent to the ranks of their parts \
             of the tree (runs of its Morton order), each rank receiving the nodes and bodies \
             of the other parts its walks reach: one process's forces to the bit",
            n / ranks
        ),
        SpreadField::P3m(mesh, _) => format!(
            "mpi: {ranks} ranks; P3M on a slab-decomposed mesh, each rank holding a block of \
             about {} bodies and a slab of {} (the FFT's transposes by all-to-all); the bodies \
             sent to the slabs their clouds touch and to the slabs of the cell list within \
             reach of theirs, their fields sent back",
            n / ranks,
            slab_planes(mesh.grid, ranks)
        ),
        SpreadField::Fmm(_) => format!(
            "mpi: {ranks} ranks; the fmm, each rank stepping a block of about {} bodies and \
             gathering every body at each evaluation (the same tree and upward pass on every \
             rank), summing a run of the target groups (balanced by their last pair terms and \
             M2L): one process's forces to the bit",
            n / ranks
        ),
    });
    let spread = Ranks::Spread(world.duplicate());
    let plan = output_plan(&setup, &spread);
    let bodies = std::mem::take(&mut setup.bodies);
    let model = DistributedGravity::new(
        world,
        setup.law,
        (bodies, setup.total),
        field,
        setup.integrator,
        setup.dt,
        setup.dimension,
        context.threads,
    )
    .map_err(|e| scenario.error(e))?;
    say_setup(&setup, context);
    let spec = job_spec(scenario, &setup, &context.out_dir)?;
    launch.launch(spec.with(model).on(spread), &plan, context, started)
}

/// Says what the run is: the bodies, the law and the solver, the steps and
/// where the results go.
fn say_setup(setup: &Setup, context: &RunContext) {
    context.say(format!(
        "gravity: {}; G {}, softening {}{}; solver {}",
        setup.initial,
        setup.law.g(),
        setup.law.softening(),
        if setup.law.has_repulsion() {
            format!(", repulsion radius {}", setup.law.repulsion_radius())
        } else {
            String::new()
        },
        setup.solver_name
    ));
    context.say(format!(
        "run: {} steps of dt {} with {}, {} thread(s); results in {}",
        setup.steps,
        setup.dt,
        setup.integrator_name,
        context.threads.count(),
        context.out_dir.display()
    ));
}

/// The outputs of `setup`: the thermo table and its energy plot, the dumps,
/// the pictures of the bodies and the trajectories (collective on `ranks`).
fn output_plan(setup: &Setup, ranks: &Ranks) -> OutputPlan {
    OutputPlan {
        thermo_every: setup.thermo_every,
        table: TableStyle {
            width: 18,
            precision: 10,
            exponent: true,
            shown: 5,
        },
        plot: Some(PlotSpec {
            file: "energy.png",
            title: "Relative energy error",
            x_label: "time (simulation units)",
            y_label: "|E - E0| / |E0| (dimensionless)",
            series: vec![("relative energy error", "rel_energy_error", true)],
        }),
        dumps: setup
            .dump
            .iter()
            .map(|d| DumpPlan {
                every: d.every,
                file: d.file.clone(),
                columns: d.columns.clone(),
                format: DumpFormat::Lammps,
            })
            .collect(),
        field: None,
        bodies: body_plan(setup, ranks),
        trajectories: setup.trajectories.clone(),
    }
}

impl Hosted for GravityModel {
    /// Seconds per step.
    fn speed(&self, loop_seconds: f64, steps: u64, threads: usize) -> String {
        format!(
            "Loop time of {loop_seconds:.4} s on {threads} thread(s) for {steps} steps with {} bodies: {:.4e} s per step",
            self.len(),
            loop_seconds / steps.max(1) as f64
        )
    }
}
