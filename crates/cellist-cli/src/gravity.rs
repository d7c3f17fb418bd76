//! `cellist run` for `model = "gravity"`: scenario keys, the initial bodies, the
//! run loop with the thermo table (energies, momentum, angular momentum), LAMMPS
//! text dumps with accelerations and potentials, and the energy-error plot; and
//! `cellist bench gravity`.

use crate::bench::median;
use crate::cli::{BenchGravityArgs, GravitySolverArg};
use crate::error::{threads, CliError, CliResult};
use crate::progress::{progress_bar, thermo_row};
use crate::scenario::Scenario;
use cellist::interactions::GravityLaw;
use cellist::longrange::p3m::SPLIT_CELLS;
use cellist::longrange::{DirectSum, FieldOut, MeshBoundary, MeshParams, Sources, TreeParams};
use cellist::models::gravity::{
    plummer, two_body_seed004, Bodies, GravityError, GravitySystem, Integrator, Observables,
    Solver, SolverChoice,
};
use cellist::Threads;
use cellist_io::plot::{line_chart, Series};
use cellist_io::{read_bodies, write_lammps_frame, AtomicFile, Frame, GRAVITY_DUMP_COLUMNS};
use serde::Deserialize;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// The most bodies a generated sphere or a benchmark may have (about 1 GB of
/// bodies and solver buffers).
const MAX_BODIES: usize = 10_000_000;

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
}

impl Default for OutputKeys {
    fn default() -> Self {
        OutputKeys {
            thermo_every: 10,
            dump: None,
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
    law: GravityLaw,
    bodies: Bodies,
    initial: String,
    choice: SolverChoice,
    solver_name: String,
    integrator: Integrator,
    integrator_name: String,
    dt: f64,
    steps: u64,
    thermo_every: u64,
    dump: Option<DumpKeys>,
}

/// Runs a gravity scenario.
pub fn run(scenario: &Scenario, out_dir: &Path, threads: &Threads) -> CliResult {
    let keys: GravityScenario = scenario.parse()?;
    debug_assert_eq!(keys.model, "gravity");
    if !(keys.dimension == 2 || keys.dimension == 3) {
        return Err(scenario.error(format!("dimension must be 2 or 3, got {}", keys.dimension)));
    }
    let setup = build(scenario, &keys, threads)?;
    if keys.dimension == 2 {
        let b = &setup.bodies;
        if let Some(i) = (0..b.len()).find(|&i| b.position[i][2] != 0.0 || b.velocity[i][2] != 0.0)
        {
            return Err(scenario.error(format!(
                "dimension = 2 needs z = 0 and vz = 0 for every body (the plane z = 0 of the \
                 3D model); body {i} has z = {}, vz = {}",
                b.position[i][2], b.velocity[i][2]
            )));
        }
    }
    run_setup(scenario, &setup, out_dir, threads)
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
        other => Err(format!(
            "system.solver kind '{other}' is unknown; expected \"direct\", \"barnes-hut\", \"pm\" or \"p3m\""
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

/// The initial bodies of `keys` and a description.
fn initial_bodies(
    scenario: &Scenario,
    keys: &InitialKeys,
    law: &GravityLaw,
    threads: &Threads,
) -> CliResult<(Bodies, String)> {
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
            let read = read_bodies(&path).map_err(|e| CliError::Input(e.to_string()))?;
            if read.extra_columns {
                eprintln!("warning: {}: columns after the 7th (m x y z vx vy vz) are ignored", path.display());
            }
            let text = format!("{} bodies from {}", read.mass.len(), path.display());
            Ok((Bodies { mass: read.mass, position: read.position, velocity: read.velocity }, text))
        }
        (Some(kind), None) => match kind.as_str() {
            "plummer" => {
                let n = keys.n.ok_or_else(|| err("system.initial.n is required for a Plummer sphere".into()))?;
                if !(2..=MAX_BODIES as i64).contains(&n) {
                    return Err(err(format!("system.initial.n must be in 2..={MAX_BODIES}, got {n}")));
                }
                let seed = keys.seed.unwrap_or(1);
                let bodies = plummer(n as usize, seed, law, threads);
                Ok((bodies, format!("Plummer sphere of {n} bodies (seed {seed}, G = M = a = 1, virial 2T = |W|)")))
            }
            "two-body-seed004" => {
                if keys.n.is_some() || keys.seed.is_some() {
                    return Err(err("system.initial.n and .seed apply to kind = \"plummer\" only".into()));
                }
                Ok((two_body_seed004(), "seed 004's two bodies (m = 50 at (0,0,0) and (0,30,0), v = (1,0,0))".into()))
            }
            other => Err(err(format!(
                "system.initial.kind '{other}' is unknown; expected \"plummer\" or \"two-body-seed004\" (or file = ...)"
            ))),
        },
    }
}

/// Checks the scenario and builds the bodies.
fn build(scenario: &Scenario, keys: &GravityScenario, threads: &Threads) -> CliResult<Setup> {
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
    let (bodies, initial) = initial_bodies(scenario, &s.initial, &law, threads)?;
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
    Ok(Setup {
        law,
        bodies,
        initial,
        choice,
        solver_name,
        integrator,
        integrator_name: keys.run.integrator.clone(),
        dt: keys.run.dt,
        steps: keys.run.steps,
        thermo_every: keys.output.thermo_every,
        dump: keys.output.dump.clone(),
    })
}

fn run_setup(scenario: &Scenario, setup: &Setup, out_dir: &Path, threads: &Threads) -> CliResult {
    let started = Instant::now();
    let mut system = GravitySystem::new(setup.law, setup.bodies.clone(), &setup.choice, threads)
        .map_err(|e| match e {
            GravityError::NotFinite { .. } => {
                scenario.error(format!("step 0 (the first forces): {e}"))
            }
            GravityError::Parameter(_) => scenario.error(e),
        })?;
    println!(
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
    );
    println!(
        "run: {} steps of dt {} with {}, {} thread(s); results in {}",
        setup.steps,
        setup.dt,
        setup.integrator_name,
        threads.count(),
        out_dir.display()
    );
    std::fs::create_dir_all(out_dir)
        .map_err(CliError::output(format!("folder {}", out_dir.display())))?;
    let mut out = Outputs::create(setup, &system, out_dir)?;
    out.observe(setup, &system, 0, false)?;
    let bar = progress_bar(setup.steps);
    out.bar = Some(bar.clone());
    let loop_start = Instant::now();
    for step in 1..=setup.steps {
        if let Err(e) = system.step(setup.dt, setup.integrator, threads) {
            bar.abandon();
            out.observe(setup, &system, step, true)?;
            out.finish()?;
            return Err(CliError::Run(format!(
                "step {step}: {e}; the state of that step is in {}",
                out.last_frame_file(setup).display()
            )));
        }
        out.observe(setup, &system, step, false)?;
        bar.inc(1);
    }
    bar.finish_and_clear();
    let loop_time = loop_start.elapsed().as_secs_f64();
    out.finish()?;
    if setup.steps > 0 {
        println!(
            "\nLoop time of {loop_time:.4} s on {} thread(s) for {} steps with {} bodies: {:.4e} s per step",
            threads.count(),
            setup.steps,
            system.len(),
            loop_time / setup.steps as f64
        );
    }
    println!(
        "total wall time {:.2} s; results in {}",
        started.elapsed().as_secs_f64(),
        out_dir.display()
    );
    Ok(())
}

const THERMO_COLUMNS: [&str; 12] = [
    "step",
    "time",
    "ke",
    "pe",
    "etotal",
    "rel_energy_error",
    "px",
    "py",
    "pz",
    "lx",
    "ly",
    "lz",
];

/// Thermo CSV, dump and plot.
struct Outputs {
    dir: PathBuf,
    thermo_csv: Option<AtomicFile>,
    dump: Option<BufWriter<std::fs::File>>,
    e0: f64,
    rows: Vec<(f64, f64)>,
    ids: Vec<u64>,
    bar: Option<indicatif::ProgressBar>,
}

impl Outputs {
    fn create(setup: &Setup, system: &GravitySystem, dir: &Path) -> CliResult<Self> {
        let csv_path = dir.join("thermo.csv");
        let mut csv = AtomicFile::create(&csv_path)
            .map_err(CliError::output(csv_path.display().to_string()))?;
        writeln!(csv.writer(), "{}", THERMO_COLUMNS.join(","))
            .map_err(CliError::output("thermo.csv"))?;
        println!(
            "{}",
            THERMO_COLUMNS[..6]
                .iter()
                .map(|c| format!("{c:>18}"))
                .collect::<String>()
        );
        let dump = match &setup.dump {
            Some(d) => {
                let path = dir.join(&d.file);
                let file = std::fs::File::create(&path)
                    .map_err(CliError::output(path.display().to_string()))?;
                Some(BufWriter::new(file))
            }
            None => None,
        };
        Ok(Outputs {
            dir: dir.to_path_buf(),
            thermo_csv: Some(csv),
            dump,
            e0: system.observables().total(),
            rows: Vec::new(),
            ids: (1..=system.len() as u64).collect(),
            bar: None,
        })
    }

    /// The file that holds the last frame after a blow-up.
    fn last_frame_file(&self, setup: &Setup) -> PathBuf {
        match &setup.dump {
            Some(d) => self.dir.join(&d.file),
            None => self.dir.join("last.dump"),
        }
    }

    /// Writes what is due at `step`; `forced` (after a blow-up) writes a dump frame
    /// whatever the step, to the dump file or to `last.dump`, and no thermo line.
    fn observe(
        &mut self,
        setup: &Setup,
        system: &GravitySystem,
        step: u64,
        forced: bool,
    ) -> CliResult {
        let last = setup.steps;
        let thermo = !forced
            && (step == 0
                || step == last
                || (setup.thermo_every > 0 && step % setup.thermo_every == 0));
        if thermo {
            let o = system.observables();
            let time = step as f64 * setup.dt;
            let rel = relative_error(&o, self.e0);
            self.rows.push((time, rel.abs()));
            let values = [
                time,
                o.kinetic,
                o.potential,
                o.total(),
                rel,
                o.momentum[0],
                o.momentum[1],
                o.momentum[2],
                o.angular_momentum[0],
                o.angular_momentum[1],
                o.angular_momentum[2],
            ];
            let table = format!("{step:>18}")
                + &values[..5]
                    .iter()
                    .map(|v| format!("{v:>18.10e}"))
                    .collect::<String>();
            thermo_row(
                self.thermo_csv.as_mut(),
                self.bar.as_ref(),
                step,
                &values,
                &table,
            )?;
        }
        let dump_due = setup.dump.as_ref().is_some_and(|d| step % d.every == 0);
        if dump_due || forced {
            let columns = setup
                .dump
                .as_ref()
                .map_or_else(dump_columns, |d| d.columns.clone());
            let frame = frame(&self.ids, system, step);
            let what = self.last_frame_file(setup).display().to_string();
            match (self.dump.as_mut(), forced) {
                (Some(w), _) => {
                    write_lammps_frame(w, &frame, &columns).map_err(CliError::output(what))?
                }
                (None, true) => {
                    let mut file = AtomicFile::create(&self.last_frame_file(setup))
                        .map_err(CliError::output(what.clone()))?;
                    write_lammps_frame(file.writer(), &frame, &columns)
                        .map_err(CliError::output(what.clone()))?;
                    file.commit().map_err(CliError::output(what))?;
                }
                (None, false) => {}
            }
        }
        Ok(())
    }
}

/// A dump frame of `system` at `step`, its box the bodies' bounding box.
fn frame<'a>(ids: &'a [u64], system: &'a GravitySystem, step: u64) -> Frame<'a> {
    let b = system.bodies();
    let (lo, hi) = cellist::geometry::bounding_box(&b.position);
    Frame {
        step,
        lo,
        hi,
        periodic: [false; 3],
        ids,
        types: &[],
        positions: &b.position,
        velocities: &b.velocity,
        forces: &[],
        energies: None,
        masses: Some(&b.mass),
        accelerations: Some(system.accelerations()),
        potentials: Some(system.potentials()),
    }
}

impl Outputs {
    /// Commits the thermo CSV, flushes the dump and plots the energy error.
    fn finish(&mut self) -> CliResult {
        if let Some(csv) = self.thermo_csv.take() {
            csv.commit().map_err(CliError::output("thermo.csv"))?;
        }
        if let Some(mut w) = self.dump.take() {
            w.flush().map_err(CliError::output("the dump file"))?;
        }
        if self.rows.len() >= 2 {
            let path = self.dir.join("energy.png");
            line_chart(
                &path,
                "Relative energy error",
                "time",
                "|E - E0| / |E0|",
                &[Series {
                    label: "relative energy error",
                    points: &self.rows,
                }],
            )
            .map_err(|e| CliError::Output(std::io::Error::other(e), path.display().to_string()))?;
        }
        Ok(())
    }
}

/// `(E - E0) / |E0|` (or `E - E0` when `E0 = 0`).
fn relative_error(o: &Observables, e0: f64) -> f64 {
    let de = o.total() - e0;
    if e0 == 0.0 {
        de
    } else {
        de / e0.abs()
    }
}

/// `cellist bench gravity`.
pub fn bench(args: &BenchGravityArgs) -> CliResult {
    if !(2..=MAX_BODIES).contains(&args.n) {
        return Err(CliError::Input(format!(
            "--n must be in 2..={MAX_BODIES}, got {}",
            args.n
        )));
    }
    if args.repeat == 0 {
        return Err(CliError::Input("--repeat must be at least 1".into()));
    }
    let pool = threads(Some(args.threads))?;
    let law = GravityLaw::new(1.0, args.softening, 0.0).map_err(CliError::Input)?;
    let bodies = plummer(args.n, args.seed, &law, &pool);
    let (choice, name) = match args.solver {
        GravitySolverArg::Direct => (SolverChoice::Direct, "direct".to_string()),
        GravitySolverArg::BarnesHut => {
            let params = TreeParams {
                theta: args.theta,
                quadrupole: !args.monopole,
                leaf_size: args.leaf_size,
                group_size: args.group_size,
            };
            params.check().map_err(CliError::Input)?;
            (SolverChoice::BarnesHut(params), "barnes-hut".to_string())
        }
        GravitySolverArg::Pm => (
            SolverChoice::Pm(MeshParams {
                grid: args.grid,
                boundary: MeshBoundary::Isolated,
            }),
            "pm".to_string(),
        ),
        GravitySolverArg::P3m => (
            SolverChoice::P3m {
                mesh: MeshParams {
                    grid: args.grid,
                    boundary: MeshBoundary::Isolated,
                },
                split_cells: args.split,
            },
            "p3m".to_string(),
        ),
    };
    let mut solver = Solver::new(&choice, law, args.n).map_err(CliError::Input)?;
    let sources = Sources {
        mass: &bodies.mass,
        position: &bodies.position,
    };
    let mut acc = vec![[0.0; 3]; args.n];
    let mut phi = vec![0.0; args.n];
    let mut samples = Vec::with_capacity(args.repeat + 1);
    // one untimed evaluation first: it builds the tables and buffers
    for _ in 0..=args.repeat {
        let start = Instant::now();
        solver.compute(
            &sources,
            FieldOut {
                acc: &mut acc,
                phi: &mut phi,
            },
            &pool,
        );
        samples.push(start.elapsed().as_secs_f64());
    }
    let seconds = median(&mut samples[1..]);
    let pairs = (args.n as f64) * (args.n as f64 - 1.0) / 2.0;
    let rms = match choice {
        SolverChoice::Direct => None,
        _ => {
            let mut exact = vec![[0.0; 3]; args.n];
            let mut exact_phi = vec![0.0; args.n];
            DirectSum::new(law, args.n).compute(
                &sources,
                FieldOut {
                    acc: &mut exact,
                    phi: &mut exact_phi,
                },
                &pool,
            );
            Some(rms_relative_error(&acc, &exact))
        }
    };
    let interactions = match &solver {
        Solver::BarnesHut(t) => Some(t.interactions()),
        _ => None,
    };
    if args.json {
        let mut obj = serde_json::json!({
            "solver": name, "n": args.n, "threads": args.threads, "softening": args.softening,
            "seconds_per_force": seconds, "repeat": args.repeat, "seed": args.seed,
        });
        match choice {
            SolverChoice::Direct => {
                obj["ns_per_pair"] = serde_json::json!(seconds / pairs * 1e9);
            }
            SolverChoice::BarnesHut(p) => {
                obj["theta"] = serde_json::json!(p.theta);
                obj["quadrupole"] = serde_json::json!(p.quadrupole);
                obj["leaf_size"] = serde_json::json!(p.leaf_size);
                obj["group_size"] = serde_json::json!(p.group_size);
            }
            SolverChoice::Pm(m) => obj["grid"] = serde_json::json!(m.grid),
            SolverChoice::P3m { mesh, split_cells } => {
                obj["grid"] = serde_json::json!(mesh.grid);
                obj["split_cells"] = serde_json::json!(split_cells);
            }
        }
        if let Some(r) = rms {
            obj["rms_relative_force_error"] = serde_json::json!(r);
        }
        if let Some((nodes, particles)) = interactions {
            obj["node_interactions"] = serde_json::json!(nodes);
            obj["particle_interactions"] = serde_json::json!(particles);
        }
        println!("{obj}");
    } else {
        let mut line = format!(
            "gravity {name}: {} bodies (Plummer, seed {}, softening {}), {} thread(s): {seconds:.4e} s per force evaluation (median of {})",
            args.n, args.seed, args.softening, args.threads, args.repeat
        );
        if let SolverChoice::Direct = choice {
            line += &format!(", {:.3} ns per pair", seconds / pairs * 1e9);
        }
        if let Some(r) = rms {
            line += &format!(", RMS relative force error against direct {r:.3e}");
        }
        if let Some((nodes, particles)) = interactions {
            line += &format!(", {nodes} node and {particles} body interactions");
        }
        println!("{line}");
    }
    Ok(())
}

/// `sqrt(mean_i (|a_i - e_i| / |e_i|)^2)`.
fn rms_relative_error(got: &[[f64; 3]], exact: &[[f64; 3]]) -> f64 {
    let norm = |v: [f64; 3]| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    let sum: f64 = got
        .iter()
        .zip(exact)
        .map(|(g, e)| (norm([g[0] - e[0], g[1] - e[1], g[2] - e[2]]) / norm(*e)).powi(2))
        .sum();
    (sum / got.len() as f64).sqrt()
}
