//! `cellist run` for `model = "md"`: scenario keys, initial state, the run loop with
//! thermo, dumps, progress bar and stage timers, and the energy plot.

use crate::error::{CliError, CliResult};
use crate::progress::{progress_bar, thermo_row};
use crate::scenario::Scenario;
use cellist::geometry::{Boundary, Domain};
use cellist::interactions::{LennardJones, PairPotential};
use cellist::models::md::{
    create_velocities, lattice, Atoms, Integrator, Langevin, LatticeKind, MdError, MdSystem,
    StageTimes, Thermo, VelocityDistribution,
};
use cellist::Threads;
use cellist_io::plot::{line_chart, Series};
use cellist_io::{read_data, write_lammps_frame, write_xyz_frame, AtomicFile, Frame, DUMP_COLUMNS};
use indicatif::ProgressBar;
use serde::Deserialize;
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// The keys of an md scenario.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct MdScenario {
    model: String,
    #[serde(default = "three")]
    dimension: u64,
    system: SystemKeys,
    #[serde(default)]
    pair: PairKeys,
    #[serde(default)]
    neighbor: NeighborKeys,
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
    read_data: Option<PathBuf>,
    lattice: Option<LatticeKeys>,
    velocity: Option<VelocityKeys>,
    mass: Option<f64>,
    boundary: Option<Vec<String>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct LatticeKeys {
    kind: String,
    density: f64,
    cells: Vec<usize>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct VelocityKeys {
    temperature: f64,
    seed: u64,
    #[serde(default = "uniform")]
    distribution: String,
}

fn uniform() -> String {
    "uniform".into()
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields, default)]
struct PairKeys {
    style: String,
    epsilon: f64,
    sigma: f64,
    cutoff: f64,
    shift: bool,
}

impl Default for PairKeys {
    fn default() -> Self {
        PairKeys {
            style: "lj/cut".into(),
            epsilon: 1.0,
            sigma: 1.0,
            cutoff: 2.5,
            shift: false,
        }
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields, default)]
struct NeighborKeys {
    skin: f64,
}

impl Default for NeighborKeys {
    fn default() -> Self {
        NeighborKeys { skin: 0.3 }
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RunKeys {
    steps: u64,
    #[serde(default = "default_dt")]
    dt: f64,
    #[serde(default = "default_integrator")]
    integrator: String,
    langevin: Option<LangevinKeys>,
}

fn default_dt() -> f64 {
    0.005
}

fn default_integrator() -> String {
    "velocity-verlet".into()
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct LangevinKeys {
    temperature: f64,
    damping: f64,
    seed: u64,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields, default)]
struct OutputKeys {
    thermo_every: u64,
    dump: Option<DumpKeys>,
    xyz: Option<XyzKeys>,
}

impl Default for OutputKeys {
    fn default() -> Self {
        OutputKeys {
            thermo_every: 100,
            dump: None,
            xyz: None,
        }
    }
}

#[derive(Deserialize, Clone)]
#[serde(deny_unknown_fields)]
struct DumpKeys {
    every: u64,
    file: PathBuf,
    #[serde(default = "default_columns")]
    columns: Vec<String>,
}

fn default_columns() -> Vec<String> {
    ["id", "type", "x", "y", "z"].map(String::from).to_vec()
}

#[derive(Deserialize, Clone)]
#[serde(deny_unknown_fields)]
struct XyzKeys {
    every: u64,
    file: PathBuf,
}

/// Everything a run needs, checked.
struct Setup<const D: usize> {
    domain: Domain<D>,
    atoms: Atoms<D>,
    potential: LennardJones,
    skin: f64,
    integrator: Integrator,
    integrator_name: String,
    dt: f64,
    steps: u64,
    thermo_every: u64,
    dump: Option<DumpKeys>,
    xyz: Option<XyzKeys>,
    /// z bounds written in dumps of 2D systems.
    z_bounds: (f64, f64),
    notes: Vec<String>,
}

/// Runs an md scenario.
pub fn run(scenario: &Scenario, out_dir: &Path, threads: &Threads) -> CliResult {
    let keys: MdScenario = scenario.parse()?;
    debug_assert_eq!(keys.model, "md");
    match keys.dimension {
        2 => run_in::<2>(scenario, &keys, out_dir, threads),
        3 => run_in::<3>(scenario, &keys, out_dir, threads),
        d => Err(scenario.error(format!("dimension must be 2 or 3, got {d}"))),
    }
}

fn run_in<const D: usize>(
    scenario: &Scenario,
    keys: &MdScenario,
    out_dir: &Path,
    threads: &Threads,
) -> CliResult {
    let mut setup = build::<D>(scenario, keys)?;
    let started = Instant::now();
    std::fs::create_dir_all(out_dir)
        .map_err(CliError::output(format!("folder {}", out_dir.display())))?;
    let atoms = std::mem::take(&mut setup.atoms);
    let mut system = MdSystem::new(setup.domain, atoms, setup.potential, setup.skin, threads)
        .map_err(|e| scenario.error(e))?;
    print_header(&setup, &system, threads, out_dir);
    for note in &setup.notes {
        eprintln!("warning: {note}");
    }
    let mut out = Outputs::create(&setup, out_dir)?;
    let mut times = StageTimes::default();
    out.observe(&setup, &system, 0, false)?;
    let bar = progress_bar(setup.steps);
    out.bar = Some(bar.clone());
    let loop_start = Instant::now();
    for step in 1..=setup.steps {
        let energy = out.needs_energy(&setup, step);
        if let Err(e) = system.step(
            &setup.integrator,
            setup.dt,
            step,
            energy,
            threads,
            &mut times,
        ) {
            bar.abandon();
            return Err(out.blow_up(&setup, &system, step, e));
        }
        let t = Instant::now();
        out.observe(&setup, &system, step, false)?;
        times.output += t.elapsed();
        bar.inc(1);
    }
    bar.finish_and_clear();
    let loop_time = loop_start.elapsed();
    out.finish(&setup)?;
    if setup.steps > 0 {
        print_timings(&setup, &system, threads, loop_time, &times);
    }
    println!(
        "total wall time {:.2} s; results in {}",
        started.elapsed().as_secs_f64(),
        out_dir.display()
    );
    Ok(())
}

/// Checks the scenario and builds the initial state.
fn build<const D: usize>(scenario: &Scenario, keys: &MdScenario) -> CliResult<Setup<D>> {
    let err = |m: String| scenario.error(m);
    let sys = &keys.system;
    let mut notes = Vec::new();
    let (mut domain, mut atoms, z_bounds) = match (&sys.read_data, &sys.lattice) {
        (Some(_), Some(_)) => return Err(err("system: give read_data or lattice, not both".into())),
        (None, None) => return Err(err("system: no initial state; give read_data = \"file.data\" or lattice = { kind, density, cells }".into())),
        (Some(path), None) => from_data::<D>(&scenario.input_path(path), sys.mass).map_err(|e| match e {
            CliError::Input(m) => err(m),
            other => other,
        })?,
        (None, Some(lat)) => {
            let kind = LatticeKind::from_name(&lat.kind).ok_or_else(|| {
                let names: Vec<&str> = LatticeKind::ALL.iter().map(|(n, _)| *n).collect();
                err(format!("system.lattice.kind '{}' is unknown; expected one of {}", lat.kind, names.join(", ")))
            })?;
            let cells: [usize; D] = lat.cells.clone().try_into().map_err(|_| {
                err(format!("system.lattice.cells has {} numbers; a {D}D system needs {D}", lat.cells.len()))
            })?;
            let (domain, points) = lattice(kind, lat.density, cells).map_err(|m| err(format!("system.lattice: {m}")))?;
            let mass = sys.mass.unwrap_or(1.0);
            if !(mass.is_finite() && mass > 0.0) {
                return Err(err(format!("system.mass must be > 0, got {mass}")));
            }
            (domain, Atoms::at_rest(points, mass), (-0.5, 0.5))
        }
    };
    if let Some(flags) = &sys.boundary {
        if flags.len() != D {
            return Err(err(format!(
                "system.boundary has {} entries; a {D}D system needs {D} (\"p\" or \"f\")",
                flags.len()
            )));
        }
        for (a, f) in flags.iter().enumerate() {
            domain.boundary[a] = match f.as_str() {
                "p" => Boundary::Periodic,
                "f" => Boundary::Open,
                other => return Err(err(format!("system.boundary entry '{other}' is unknown; expected \"p\" (periodic) or \"f\" (fixed, non-periodic)"))),
            };
        }
    }
    if let Some(v) = &sys.velocity {
        if !(v.temperature.is_finite() && v.temperature >= 0.0) {
            return Err(err(format!(
                "system.velocity.temperature must be >= 0, got {}",
                v.temperature
            )));
        }
        let dist = match v.distribution.as_str() {
            "uniform" => VelocityDistribution::Uniform,
            "gaussian" => VelocityDistribution::Gaussian,
            other => return Err(err(format!("system.velocity.distribution '{other}' is unknown; expected \"uniform\" or \"gaussian\""))),
        };
        create_velocities(&mut atoms, v.temperature, v.seed, dist);
    }

    let pair = &keys.pair;
    if pair.style != "lj/cut" {
        return Err(err(format!(
            "pair.style '{}' is unknown; expected \"lj/cut\"",
            pair.style
        )));
    }
    let potential = LennardJones::new(pair.epsilon, pair.sigma, pair.cutoff, pair.shift)
        .map_err(|m| err(format!("pair: {m}")))?;
    let mut skin = keys.neighbor.skin;
    if !(skin.is_finite() && skin >= 0.0) {
        return Err(err(format!("neighbor.skin must be >= 0, got {skin}")));
    }
    for a in 0..D {
        let l = domain.length[a];
        if domain.is_periodic(a) && l < 2.0 * pair.cutoff {
            return Err(err(format!(
                "the periodic box side along {} is {l}, smaller than twice the cutoff ({}): an atom would meet its own image; use a larger box or a smaller cutoff",
                ["x", "y", "z"][a],
                2.0 * pair.cutoff
            )));
        }
        if domain.is_periodic(a) && pair.cutoff + skin > l / 2.0 {
            skin = l / 2.0 - pair.cutoff;
            notes.push(format!("the skin was reduced to {skin} so that cutoff + skin fits in half the box side {l}"));
        }
    }
    let run = &keys.run;
    if !(run.dt.is_finite() && run.dt > 0.0) {
        return Err(err(format!("run.dt must be > 0, got {}", run.dt)));
    }
    let integrator = match (run.integrator.as_str(), &run.langevin) {
        ("velocity-verlet", None) => Integrator::VelocityVerlet,
        ("euler", None) => Integrator::Euler,
        ("symplectic-euler", None) => Integrator::SymplecticEuler,
        ("langevin", Some(l)) => {
            if !(l.temperature.is_finite() && l.temperature >= 0.0 && l.damping.is_finite() && l.damping > 0.0) {
                return Err(err(format!("run.langevin needs temperature >= 0 and damping > 0, got {} and {}", l.temperature, l.damping)));
            }
            Integrator::Langevin(Langevin { temperature: l.temperature, damping: l.damping, seed: l.seed })
        }
        ("langevin", None) => return Err(err("integrator \"langevin\" needs run.langevin = { temperature, damping, seed }".into())),
        ("velocity-verlet" | "euler" | "symplectic-euler", Some(_)) => {
            return Err(err("run.langevin is given but run.integrator is not \"langevin\"".into()))
        }
        (other, _) => {
            return Err(err(format!(
                "run.integrator '{other}' is unknown; expected \"velocity-verlet\", \"euler\", \"symplectic-euler\" or \"langevin\""
            )))
        }
    };
    let out = &keys.output;
    if let Some(d) = &out.dump {
        if d.every == 0 {
            return Err(err("output.dump.every must be >= 1".into()));
        }
        if d.columns.is_empty() {
            return Err(err("output.dump.columns is empty".into()));
        }
        for c in &d.columns {
            if !DUMP_COLUMNS.contains(&c.as_str()) {
                return Err(err(format!(
                    "output.dump.columns: '{c}' is unknown; expected some of {}",
                    DUMP_COLUMNS.join(" ")
                )));
            }
        }
    }
    if out.xyz.as_ref().is_some_and(|x| x.every == 0) {
        return Err(err("output.xyz.every must be >= 1".into()));
    }
    Ok(Setup {
        domain,
        atoms,
        potential,
        skin,
        integrator,
        integrator_name: run.integrator.clone(),
        dt: run.dt,
        steps: run.steps,
        thermo_every: out.thermo_every,
        dump: out.dump.clone(),
        xyz: out.xyz.clone(),
        z_bounds,
        notes,
    })
}

/// The box and atoms of a LAMMPS data file (its z bounds kept for 2D dumps).
fn from_data<const D: usize>(
    path: &Path,
    mass: Option<f64>,
) -> CliResult<(Domain<D>, Atoms<D>, (f64, f64))> {
    let data = read_data(path)?;
    let masses = match (&data.masses, mass) {
        (Some(_), Some(_)) => {
            return Err(CliError::Input(format!(
                "system.mass is given but {} has a Masses section; keep one",
                path.display()
            )))
        }
        (Some(m), None) => m.clone(),
        (None, Some(m)) if m.is_finite() && m > 0.0 => vec![m; data.atom_types as usize],
        (None, Some(m)) => {
            return Err(CliError::Input(format!("system.mass must be > 0, got {m}")))
        }
        (None, None) => {
            return Err(CliError::Input(format!(
                "{} has no Masses section; add one or set system.mass",
                path.display()
            )))
        }
    };
    if let Some(t) = masses.iter().position(|m| m.is_nan()) {
        return Err(CliError::Input(format!(
            "{}: the Masses section has no mass for atom type {}",
            path.display(),
            t + 1
        )));
    }
    if D == 2 {
        if let Some(a) = data
            .atoms
            .iter()
            .find(|a| a.position[2] != 0.0 || a.velocity[2] != 0.0)
        {
            return Err(CliError::Input(format!(
                "{}: atom {} has z = {} and vz = {}; a 2D system needs z = 0 and vz = 0 (is this a 3D data file? set dimension = 3)",
                path.display(),
                a.id,
                a.position[2],
                a.velocity[2]
            )));
        }
    }
    let length: [f64; D] = std::array::from_fn(|a| data.hi[a] - data.lo[a]);
    let mut domain = Domain::periodic(length)
        .map_err(|e| CliError::Input(format!("{}: {e}", path.display())))?;
    domain.lo = std::array::from_fn(|a| data.lo[a]);
    let atoms = Atoms {
        ids: data.atoms.iter().map(|a| a.id).collect(),
        types: data.atoms.iter().map(|a| a.kind).collect(),
        masses: data
            .atoms
            .iter()
            .map(|a| masses[a.kind as usize - 1])
            .collect(),
        positions: data
            .atoms
            .iter()
            .map(|a| std::array::from_fn(|k| a.position[k]))
            .collect(),
        velocities: data
            .atoms
            .iter()
            .map(|a| std::array::from_fn(|k| a.velocity[k]))
            .collect(),
        forces: vec![[0.0; D]; data.atoms.len()],
    };
    Ok((domain, atoms, (data.lo[2], data.hi[2])))
}

fn print_header<const D: usize>(
    setup: &Setup<D>,
    system: &MdSystem<D>,
    threads: &Threads,
    out_dir: &Path,
) {
    let sides: Vec<String> = setup
        .domain
        .length
        .iter()
        .map(|l| format!("{l:.6}"))
        .collect();
    let flags: Vec<&str> = (0..D)
        .map(|a| {
            if setup.domain.is_periodic(a) {
                "p"
            } else {
                "f"
            }
        })
        .collect();
    println!(
        "md: {} atoms in {D}D, box {} ({}), lj/cut eps {} sigma {} cutoff {}{}, skin {}",
        system.atoms().len(),
        sides.join(" x "),
        flags.join(" "),
        setup.potential.epsilon(),
        setup.potential.sigma(),
        setup.potential.cutoff(),
        if setup.potential.shift_energy() != 0.0 {
            " shifted"
        } else {
            ""
        },
        setup.skin
    );
    println!(
        "run: {} steps of dt {} with {}, {} thread(s); results in {}",
        setup.steps,
        setup.dt,
        setup.integrator_name,
        threads.count(),
        out_dir.display()
    );
}

/// Thermo, dumps and the plot.
struct Outputs {
    dir: PathBuf,
    thermo_csv: Option<AtomicFile>,
    rows: Vec<(u64, Thermo)>,
    dump: Option<BufWriter<File>>,
    xyz: Option<BufWriter<File>>,
    bar: Option<ProgressBar>,
}

const THERMO_COLUMNS: [&str; 6] = ["step", "temp", "pe", "ke", "etotal", "press"];

impl Outputs {
    fn create<const D: usize>(setup: &Setup<D>, dir: &Path) -> CliResult<Self> {
        let open = |name: &Path| -> CliResult<BufWriter<File>> {
            let path = dir.join(name);
            File::create(&path)
                .map(|f| BufWriter::with_capacity(1 << 20, f))
                .map_err(CliError::output(path.display().to_string()))
        };
        let csv_path = dir.join("thermo.csv");
        let mut csv = AtomicFile::create(&csv_path)
            .map_err(CliError::output(csv_path.display().to_string()))?;
        writeln!(csv.writer(), "{}", THERMO_COLUMNS.join(","))
            .map_err(CliError::output("thermo.csv"))?;
        println!("{}", THERMO_COLUMNS.map(|c| format!("{c:>15}")).join(""));
        Ok(Outputs {
            dir: dir.to_path_buf(),
            thermo_csv: Some(csv),
            rows: Vec::new(),
            dump: setup.dump.as_ref().map(|d| open(&d.file)).transpose()?,
            xyz: setup.xyz.as_ref().map(|x| open(&x.file)).transpose()?,
            bar: None,
        })
    }

    fn is_thermo_step<const D: usize>(setup: &Setup<D>, step: u64) -> bool {
        step == 0
            || step == setup.steps
            || (setup.thermo_every > 0 && step % setup.thermo_every == 0)
    }

    /// True when step `step` must sum the energy (thermo, or a dump with `pe`).
    fn needs_energy<const D: usize>(&self, setup: &Setup<D>, step: u64) -> bool {
        Self::is_thermo_step(setup, step)
            || setup
                .dump
                .as_ref()
                .is_some_and(|d| step % d.every == 0 && d.columns.iter().any(|c| c == "pe"))
    }

    /// Writes what is due at `step`; `forced` (after a blow-up) writes the dump
    /// frames whatever the step, and no thermo (the step did not finish).
    fn observe<const D: usize>(
        &mut self,
        setup: &Setup<D>,
        system: &MdSystem<D>,
        step: u64,
        forced: bool,
    ) -> CliResult {
        if !forced && Self::is_thermo_step(setup, step) && system.pair_totals().is_some() {
            let th = system.thermo();
            self.rows.push((step, th));
            let values = [th.temp, th.pe, th.ke, th.etotal, th.press];
            let table = format!("{step:>15}") + &values.map(|v| format!("{v:>15.8}")).join("");
            thermo_row(
                self.thermo_csv.as_mut(),
                self.bar.as_ref(),
                step,
                &values,
                &table,
            )?;
        }
        if let (Some(w), Some(d)) = (self.dump.as_mut(), &setup.dump) {
            if forced || step % d.every == 0 {
                let arrays = FrameArrays::of(system, d.columns.iter().any(|c| c == "pe"));
                write_lammps_frame(w, &arrays.frame(system, step, setup.z_bounds), &d.columns)
                    .and_then(|_| w.flush())
                    .map_err(CliError::output(d.file.display().to_string()))?;
            }
        }
        if let (Some(w), Some(x)) = (self.xyz.as_mut(), &setup.xyz) {
            if forced || step % x.every == 0 {
                let arrays = FrameArrays::of(system, false);
                write_xyz_frame(
                    w,
                    &arrays.frame(system, step, setup.z_bounds),
                    step as f64 * setup.dt,
                )
                .and_then(|_| w.flush())
                .map_err(CliError::output(x.file.display().to_string()))?;
            }
        }
        Ok(())
    }

    /// After a blow-up: the last state to the dumps (or `last.lammpstrj`), the thermo
    /// so far and the plot, then the error naming the step and the atom.
    fn blow_up<const D: usize>(
        &mut self,
        setup: &Setup<D>,
        system: &MdSystem<D>,
        step: u64,
        e: MdError,
    ) -> CliError {
        let mut written = Vec::new();
        if self.dump.is_none() && self.xyz.is_none() {
            let name = PathBuf::from("last.lammpstrj");
            let columns = [
                "id", "type", "x", "y", "z", "vx", "vy", "vz", "fx", "fy", "fz",
            ]
            .map(String::from)
            .to_vec();
            let path = self.dir.join(&name);
            let arrays = FrameArrays::of(system, false);
            let _ = File::create(&path).and_then(|mut f| {
                write_lammps_frame(
                    &mut f,
                    &arrays.frame(system, step, setup.z_bounds),
                    &columns,
                )
            });
            written.push(path.display().to_string());
        } else if let Err(e) = self.observe(setup, system, step, true) {
            eprintln!("warning: {e}");
        } else {
            for f in [
                setup.dump.as_ref().map(|d| &d.file),
                setup.xyz.as_ref().map(|x| &x.file),
            ]
            .into_iter()
            .flatten()
            {
                written.push(self.dir.join(f).display().to_string());
            }
        }
        if let Err(e) = self.finish(setup) {
            eprintln!("warning: {e}");
        }
        CliError::Run(format!(
            "{e}; the last state (step {step}) is in {}",
            written.join(" and ")
        ))
    }

    /// Commits the thermo CSV and draws the energy plot.
    fn finish<const D: usize>(&mut self, setup: &Setup<D>) -> CliResult {
        if let Some(csv) = self.thermo_csv.take() {
            csv.commit().map_err(CliError::output("thermo.csv"))?;
        }
        for w in [self.dump.as_mut(), self.xyz.as_mut()]
            .into_iter()
            .flatten()
        {
            w.flush().map_err(CliError::output("a dump file"))?;
        }
        if self.rows.len() >= 2 {
            let curve = |f: fn(&Thermo) -> f64| -> Vec<(f64, f64)> {
                self.rows
                    .iter()
                    .map(|(s, t)| (*s as f64 * setup.dt, f(t)))
                    .collect()
            };
            let (pe, ke, et) = (curve(|t| t.pe), curve(|t| t.ke), curve(|t| t.etotal));
            let series = [
                Series {
                    label: "potential",
                    points: &pe,
                },
                Series {
                    label: "kinetic",
                    points: &ke,
                },
                Series {
                    label: "total",
                    points: &et,
                },
            ];
            let path = self.dir.join("energy.png");
            line_chart(
                &path,
                "Energy per atom",
                "time (lj units)",
                "energy per atom",
                &series,
            )
            .map_err(|e| CliError::Output(std::io::Error::other(e), path.display().to_string()))?;
        }
        Ok(())
    }
}

/// Per-atom arrays of one frame, sorted by id, positions wrapped into the box.
struct FrameArrays {
    ids: Vec<u64>,
    types: Vec<u32>,
    positions: Vec<[f64; 3]>,
    velocities: Vec<[f64; 3]>,
    forces: Vec<[f64; 3]>,
    energies: Option<Vec<f64>>,
}

impl FrameArrays {
    fn of<const D: usize>(system: &MdSystem<D>, per_atom_energy: bool) -> Self {
        let atoms = system.atoms();
        let slots = atoms.slots_by_id();
        let pad =
            |v: [f64; D]| -> [f64; 3] { std::array::from_fn(|a| if a < D { v[a] } else { 0.0 }) };
        let energies = per_atom_energy.then(|| {
            let pe = system.per_atom_energy();
            slots.iter().map(|&k| pe[k]).collect()
        });
        FrameArrays {
            ids: slots.iter().map(|&k| atoms.ids[k]).collect(),
            types: slots.iter().map(|&k| atoms.types[k]).collect(),
            positions: slots
                .iter()
                .map(|&k| pad(system.domain().wrap(atoms.positions[k])))
                .collect(),
            velocities: slots.iter().map(|&k| pad(atoms.velocities[k])).collect(),
            forces: slots.iter().map(|&k| pad(atoms.forces[k])).collect(),
            energies,
        }
    }

    fn frame<'a, const D: usize>(
        &'a self,
        system: &MdSystem<D>,
        step: u64,
        z_bounds: (f64, f64),
    ) -> Frame<'a> {
        let dom = system.domain();
        let mut lo = [0.0, 0.0, z_bounds.0];
        let mut hi = [0.0, 0.0, z_bounds.1];
        let mut periodic = [true; 3];
        for a in 0..D {
            lo[a] = dom.lo[a];
            hi[a] = dom.lo[a] + dom.length[a];
            periodic[a] = dom.is_periodic(a);
        }
        Frame {
            step,
            lo,
            hi,
            periodic,
            ids: &self.ids,
            types: &self.types,
            positions: &self.positions,
            velocities: &self.velocities,
            forces: &self.forces,
            energies: self.energies.as_deref(),
            masses: None,
            accelerations: None,
            potentials: None,
        }
    }
}

fn print_timings<const D: usize>(
    setup: &Setup<D>,
    system: &MdSystem<D>,
    threads: &Threads,
    loop_time: Duration,
    times: &StageTimes,
) {
    let total = loop_time.as_secs_f64();
    let n = system.atoms().len() as f64;
    let per = if setup.steps > 0 {
        total * 1e6 / (n * setup.steps as f64)
    } else {
        0.0
    };
    println!(
        "\nLoop time of {total:.4} s on {} thread(s) for {} steps with {} atoms: {per:.4} us/atom-step, {} neighbour-list rebuilds",
        threads.count(),
        setup.steps,
        system.atoms().len(),
        system.rebuilds()
    );
    let known = times.neighbor + times.force + times.integrate + times.output;
    let other = loop_time.saturating_sub(known);
    println!("{:<10} | {:>10} | {:>6}", "Section", "time (s)", "%total");
    for (name, d) in [
        ("Neighbor", times.neighbor),
        ("Force", times.force),
        ("Integrate", times.integrate),
        ("Output", times.output),
        ("Other", other),
    ] {
        let s = d.as_secs_f64();
        let pct = if total > 0.0 { 100.0 * s / total } else { 0.0 };
        println!("{name:<10} | {s:>10.4} | {pct:>6.2}");
    }
}
