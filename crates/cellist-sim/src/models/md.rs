//! `model = "md"`: the scenario keys of Lennard-Jones molecular dynamics, the
//! initial state (lattice or LAMMPS data file), and the outputs (thermo, LAMMPS
//! dumps, extended XYZ, the energy plot).

use crate::driver::{JobSpec, LastFrame};
use crate::error::{SimError, SimResult};
use crate::hosted::Hosted;
use crate::launch::{Launch, RunContext};
use crate::observers::{DumpFormat, DumpPlan, OutputPlan, PlotSpec, TableStyle};
use crate::scenario::keys::{
    choice, CheckpointKeys, DecompositionKeys, SeriesKeys, TrajectoryKeys,
};
use crate::scenario::Scenario;
use cellist::decomposition::Balance;
use cellist::geometry::{Boundary, Domain};
use cellist::interactions::{LennardJones, PairPotential};
use cellist::models::md::{
    late_note, Atoms, Integrator, Langevin, Lattice, LatticeKind, MdModel, MdSystem,
    VelocityDistribution, VelocityScaling,
};
use cellist::models::Model;
use cellist::neighbors::RebuildRule;
use cellist::Threads;
use cellist_io::{read_data_box, read_data_where, AtomsWanted, DataAtom, DUMP_COLUMNS};
use serde::Deserialize;
use std::path::{Path, PathBuf};
use std::time::Instant;

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
    #[serde(default)]
    decomposition: DecompositionKeys,
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
    /// LAMMPS's `neigh_modify every N`: steps between two looks at the list.
    every: u64,
    /// LAMMPS's `neigh_modify check yes|no`: rebuild only past the skin test.
    check: bool,
}

impl Default for NeighborKeys {
    fn default() -> Self {
        let rule = RebuildRule::default();
        NeighborKeys {
            skin: 0.3,
            every: rule.every,
            check: rule.check,
        }
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
    /// Under MPI: sum each atom's forces in id order over full rows, so that
    /// any number of ranks gives the same bits (twice the pair arithmetic).
    #[serde(default)]
    reproducible: bool,
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
    checkpoint: Option<CheckpointKeys>,
    gsd: Option<SeriesKeys>,
    vtk: Option<SeriesKeys>,
}

impl Default for OutputKeys {
    fn default() -> Self {
        OutputKeys {
            thermo_every: 100,
            dump: None,
            xyz: None,
            checkpoint: None,
            gsd: None,
            vtk: None,
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

/// Where the atoms of a run come from.
enum Source<const D: usize> {
    /// A filled lattice of atoms of one mass, made where they are kept.
    Lattice(Lattice<D>, f64),
    /// A data file, read where its atoms are kept, and `system.mass` (for a
    /// file without a `Masses` section).
    Data(PathBuf, Option<f64>),
}

/// The atoms a run starts from, made where they are needed: all of them in
/// one process, a rank's share on several ([`Initial::atoms_where`]).
struct Initial<const D: usize> {
    source: Source<D>,
    /// `system.velocity`: temperature, seed, distribution.
    velocities: Option<(f64, u64, VelocityDistribution)>,
}

impl<const D: usize> Initial<D> {
    /// The atoms whose initial position `keep` accepts (in id order, or a
    /// data file's order), with the velocities of `system.velocity` created
    /// over every atom ([`VelocityScaling`]: the same velocities whoever
    /// keeps which atom). A data file is read a line at a time and checked
    /// whole on every rank, which keeps only its atoms.
    fn atoms_where(self, keep: impl Fn(&[f64; D]) -> bool) -> SimResult<Atoms<D>> {
        let (mut atoms, scaling) = match self.source {
            Source::Data(path, mass) => {
                let (atoms, every) = from_data(&path, mass, keep, self.velocities.is_some())?;
                let scaling = self.velocities.map(|(t, seed, dist)| {
                    VelocityScaling::over(|| every.iter().copied(), t, seed, dist)
                });
                (atoms, scaling)
            }
            Source::Lattice(lattice, mass) => {
                let scaling = self.velocities.map(|(t, seed, dist)| {
                    let every = || (1..=lattice.len() as u64).map(|id| (id, mass));
                    VelocityScaling::over(every, t, seed, dist)
                });
                let (ids, points): (Vec<u64>, Vec<[f64; D]>) =
                    (1..).zip(lattice.points()).filter(|(_, x)| keep(x)).unzip();
                let mut atoms = Atoms::at_rest(points, mass);
                atoms.ids = ids;
                (atoms, scaling)
            }
        };
        if let Some(scaling) = scaling {
            for (v, &id) in atoms.velocities.iter_mut().zip(&atoms.ids) {
                *v = scaling.velocity(id);
            }
        }
        Ok(atoms)
    }
}

/// Everything a run needs, checked.
struct Setup<const D: usize> {
    domain: Domain<D>,
    potential: LennardJones,
    skin: f64,
    rebuild: RebuildRule,
    integrator: Integrator,
    integrator_name: String,
    dt: f64,
    steps: u64,
    thermo_every: u64,
    dump: Option<DumpKeys>,
    xyz: Option<XyzKeys>,
    checkpoint: Option<CheckpointKeys>,
    trajectories: TrajectoryKeys,
    /// z bounds written in dumps of 2D systems.
    z_bounds: (f64, f64),
    /// `[run] reproducible` (read by distributed runs only).
    #[cfg_attr(not(feature = "mpi"), allow(dead_code))]
    reproducible: bool,
    /// `[decomposition] balance` (read by distributed runs only).
    #[cfg_attr(not(feature = "mpi"), allow(dead_code))]
    balance: Balance,
    notes: Vec<String>,
}

/// Runs an md scenario, from the checkpoint `restart` if given.
pub fn run<L: Launch>(
    scenario: &Scenario,
    context: &RunContext,
    launch: L,
) -> SimResult<L::Output> {
    let keys: MdScenario = scenario.parse()?;
    debug_assert_eq!(keys.model, "md");
    match keys.dimension {
        2 => run_in::<2, L>(scenario, &keys, context, launch),
        3 => run_in::<3, L>(scenario, &keys, context, launch),
        d => Err(scenario.error(format!("dimension must be 2 or 3, got {d}"))),
    }
}

fn run_in<const D: usize, L: Launch>(
    scenario: &Scenario,
    keys: &MdScenario,
    context: &RunContext,
    launch: L,
) -> SimResult<L::Output> {
    let threads = context.threads;
    let (setup, initial) = build::<D>(scenario, keys)?;
    let in_scenario = in_scenario(scenario);
    let started = Instant::now();
    #[cfg(feature = "mpi")]
    if let Some(world) = crate::distributed::world_of_many() {
        use crate::distributed::md::{share_at_set_up, DistributedMd, MdSpec};
        let ranks = crate::ranks::Ranks::Spread(mpi::traits::Communicator::duplicate(&world));
        // a read that fails on one rank alone stops every rank
        let atoms = initial
            .atoms_where(share_at_set_up(&world, setup.domain))
            .map_err(in_scenario);
        let spec = MdSpec {
            domain: setup.domain,
            atoms: crate::driver::agreed(&ranks, atoms)?,
            potential: setup.potential,
            skin: setup.skin,
            rule: setup.rebuild,
            integrator: setup.integrator,
            dt: setup.dt,
            z_bounds: setup.z_bounds,
            reproducible: setup.reproducible,
            balance: setup.balance,
        };
        let model = DistributedMd::new(world, spec, threads).map_err(|e| scenario.error(e))?;
        print_header(&setup, model.total(), context);
        context.say(model.describe());
        for note in &setup.notes {
            context.warn(note);
        }
        let job = job_spec(&setup, scenario, context)?.with(model).on(ranks);
        return launch.launch(job, &output_plan(&setup), context, started);
    }
    let atoms = initial.atoms_where(|_| true).map_err(in_scenario)?;
    let mut system = MdSystem::new(setup.domain, atoms, setup.potential, setup.skin, threads)
        .map_err(|e| scenario.error(e))?;
    system.set_rebuild_rule(setup.rebuild);
    print_header(&setup, system.atoms().len(), context);
    for note in &setup.notes {
        context.warn(note);
    }
    let model = MdModel::new(system, setup.integrator, setup.dt, setup.z_bounds);
    let job = job_spec(&setup, scenario, context)?.with(model);
    launch.launch(job, &output_plan(&setup), context, started)
}

/// The outputs of an md run: thermo table and plot, dumps.
fn output_plan<const D: usize>(setup: &Setup<D>) -> OutputPlan {
    let mut dumps = Vec::new();
    if let Some(d) = &setup.dump {
        dumps.push(DumpPlan {
            every: d.every,
            file: d.file.clone(),
            columns: d.columns.clone(),
            format: DumpFormat::Lammps,
        });
    }
    if let Some(x) = &setup.xyz {
        dumps.push(DumpPlan {
            every: x.every,
            file: x.file.clone(),
            columns: Vec::new(),
            format: DumpFormat::Xyz,
        });
    }
    OutputPlan {
        thermo_every: setup.thermo_every,
        table: TableStyle {
            width: 15,
            precision: 8,
            exponent: false,
            shown: 5,
        },
        plot: Some(PlotSpec {
            file: "energy.png",
            title: "Energy per atom",
            x_label: "time (LJ units, τ)",
            y_label: "energy per atom (ε)",
            series: vec![
                ("potential", "pe", false),
                ("kinetic", "ke", false),
                ("total", "etotal", false),
            ],
        }),
        dumps,
        field: None,
        bodies: None,
        trajectories: setup.trajectories.clone(),
    }
}

/// The run's settings (in one process or on one rank of several) as the
/// scenario asks.
fn job_spec<const D: usize>(
    setup: &Setup<D>,
    scenario: &Scenario,
    context: &RunContext,
) -> SimResult<JobSpec> {
    Ok(JobSpec {
        steps: setup.steps,
        dir: context.out_dir.to_path_buf(),
        checkpoint: setup.checkpoint.clone(),
        physics: scenario.physics_keys()?,
        last_frame: LastFrame::Dump {
            file: "last.lammpstrj",
            columns: [
                "id", "type", "x", "y", "z", "vx", "vy", "vz", "fx", "fy", "fz",
            ]
            .map(String::from)
            .to_vec(),
        },
    })
}

/// Checks the scenario and builds the initial state.
fn build<const D: usize>(
    scenario: &Scenario,
    keys: &MdScenario,
) -> SimResult<(Setup<D>, Initial<D>)> {
    let err = |m: String| scenario.error(m);
    let sys = &keys.system;
    let mut notes = Vec::new();
    let (mut domain, source, z_bounds) = match (&sys.read_data, &sys.lattice) {
        (Some(_), Some(_)) => return Err(err("system: give read_data or lattice, not both".into())),
        (None, None) => return Err(err("system: no initial state; give read_data = \"file.data\" or lattice = { kind, density, cells }".into())),
        (Some(path), None) => {
            let path = scenario.input_path(path);
            let (domain, z_bounds) = data_box::<D>(&path).map_err(in_scenario(scenario))?;
            (domain, Source::Data(path, sys.mass), z_bounds)
        }
        (None, Some(lat)) => {
            let kind = LatticeKind::from_name(&lat.kind).ok_or_else(|| {
                let names: Vec<&str> = LatticeKind::ALL.iter().map(|(n, _)| *n).collect();
                err(format!("system.lattice.kind '{}' is unknown; expected one of {}", lat.kind, names.join(", ")))
            })?;
            let cells: [usize; D] = lat.cells.clone().try_into().map_err(|_| {
                err(format!("system.lattice.cells has {} numbers; a {D}D system needs {D}", lat.cells.len()))
            })?;
            let lattice = Lattice::new(kind, lat.density, cells).map_err(|m| err(format!("system.lattice: {m}")))?;
            let mass = sys.mass.unwrap_or(1.0);
            if !(mass.is_finite() && mass > 0.0) {
                return Err(err(format!("system.mass must be > 0, got {mass}")));
            }
            (lattice.domain, Source::Lattice(lattice, mass), (-0.5, 0.5))
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
    let mut velocities = None;
    if let Some(v) = &sys.velocity {
        if !(v.temperature.is_finite() && v.temperature >= 0.0) {
            return Err(err(format!(
                "system.velocity.temperature must be >= 0, got {}",
                v.temperature
            )));
        }
        let dist = choice(
            "system.velocity.distribution",
            &v.distribution,
            &[
                ("uniform", VelocityDistribution::Uniform),
                ("gaussian", VelocityDistribution::Gaussian),
            ],
        )
        .map_err(err)?;
        velocities = Some((v.temperature, v.seed, dist));
    }

    let pair = &keys.pair;
    choice("pair.style", &pair.style, &[("lj/cut", ())]).map_err(err)?;
    let potential = LennardJones::new(pair.epsilon, pair.sigma, pair.cutoff, pair.shift)
        .map_err(|m| err(format!("pair: {m}")))?;
    let mut skin = keys.neighbor.skin;
    if !(skin.is_finite() && skin >= 0.0) {
        return Err(err(format!("neighbor.skin must be >= 0, got {skin}")));
    }
    if keys.neighbor.every == 0 {
        return Err(err(
            "neighbor.every must be >= 1 (the list is looked at every N steps)".into(),
        ));
    }
    let rebuild = RebuildRule {
        every: keys.neighbor.every,
        check: keys.neighbor.check,
    };
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
    if let Some(c) = &out.checkpoint {
        c.check("output.checkpoint").map_err(err)?;
    }
    let setup = Setup {
        domain,
        potential,
        skin,
        rebuild,
        integrator,
        integrator_name: run.integrator.clone(),
        dt: run.dt,
        steps: run.steps,
        thermo_every: out.thermo_every,
        dump: out.dump.clone(),
        xyz: out.xyz.clone(),
        checkpoint: out.checkpoint.clone(),
        trajectories: TrajectoryKeys::checked(out.gsd.clone(), out.vtk.clone()).map_err(err)?,
        z_bounds,
        reproducible: run.reproducible,
        balance: keys.decomposition.balance().map_err(err)?,
        notes,
    };
    Ok((setup, Initial { source, velocities }))
}

/// An input error of the data file named as the scenario's (the other
/// errors as they are).
fn in_scenario(scenario: &Scenario) -> impl Fn(SimError) -> SimError + '_ {
    move |e| match e {
        SimError::Input(m) => scenario.error(m),
        other => other,
    }
}

/// The box of a LAMMPS data file's header and its z bounds (kept for 2D
/// dumps).
fn data_box<const D: usize>(path: &Path) -> SimResult<(Domain<D>, (f64, f64))> {
    let (lo, hi) = read_data_box(path)?;
    let length: [f64; D] = std::array::from_fn(|a| hi[a] - lo[a]);
    let mut domain = Domain::periodic(length)
        .map_err(|e| SimError::Input(format!("{}: {e}", path.display())))?;
    domain.lo = std::array::from_fn(|a| lo[a]);
    Ok((domain, (lo[2], hi[2])))
}

/// What md keeps of a data file as it is read: the atoms whose position
/// `keep` accepts, every atom's `(id, type)` when `system.velocity` needs
/// them all, and (2D) the first atom of the `Atoms` section off the plane
/// (`z != 0` or `vz != 0`): its place there, id, z and vz.
struct Wanted<K, const D: usize> {
    keep: K,
    every: Option<Vec<(u64, u32)>>,
    seen: usize,
    off_plane: Option<(usize, u64, f64, f64)>,
}

impl<K: Fn(&[f64; D]) -> bool, const D: usize> AtomsWanted for Wanted<K, D> {
    fn keep(&mut self, atom: &DataAtom) -> bool {
        if let Some(every) = &mut self.every {
            every.push((atom.id, atom.kind));
        }
        if D == 2 && atom.position[2] != 0.0 && self.off_plane.is_none() {
            self.off_plane = Some((self.seen, atom.id, atom.position[2], 0.0));
        }
        self.seen += 1;
        (self.keep)(&std::array::from_fn(|k| atom.position[k]))
    }

    /// An atom before the first one with `z != 0` has `z = 0`.
    fn velocity(&mut self, place: usize, id: u64, v: [f64; 3]) {
        match &mut self.off_plane {
            Some((first, _, _, vz)) if *first == place => *vz = v[2],
            Some((first, ..)) if *first < place => {}
            _ if D == 2 && v[2] != 0.0 => self.off_plane = Some((place, id, 0.0, v[2])),
            _ => {}
        }
    }
}

/// The atoms of a LAMMPS data file whose position `keep` accepts (every
/// line checked), and with `all` every atom's `(id, mass)` in file order.
fn from_data<const D: usize>(
    path: &Path,
    mass: Option<f64>,
    keep: impl Fn(&[f64; D]) -> bool,
    all: bool,
) -> SimResult<(Atoms<D>, Vec<(u64, f64)>)> {
    let mut wanted = Wanted {
        keep,
        every: all.then(Vec::new),
        seen: 0,
        off_plane: None,
    };
    let data = read_data_where(path, &mut wanted)?;
    let masses = match (&data.masses, mass) {
        (Some(_), Some(_)) => {
            return Err(SimError::Input(format!(
                "system.mass is given but {} has a Masses section; keep one",
                path.display()
            )))
        }
        (Some(m), None) => m.clone(),
        (None, Some(m)) if m.is_finite() && m > 0.0 => vec![m; data.atom_types as usize],
        (None, Some(m)) => {
            return Err(SimError::Input(format!("system.mass must be > 0, got {m}")))
        }
        (None, None) => {
            return Err(SimError::Input(format!(
                "{} has no Masses section; add one or set system.mass",
                path.display()
            )))
        }
    };
    if let Some(t) = masses.iter().position(|m| m.is_nan()) {
        return Err(SimError::Input(format!(
            "{}: the Masses section has no mass for atom type {}",
            path.display(),
            t + 1
        )));
    }
    if let Some((_, id, z, vz)) = wanted.off_plane {
        return Err(SimError::Input(format!(
            "{}: atom {id} has z = {z} and vz = {vz}; a 2D system needs z = 0 and vz = 0 (is this a 3D data file? set dimension = 3)",
            path.display(),
        )));
    }
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
    let every = wanted.every.unwrap_or_default();
    let every = every
        .into_iter()
        .map(|(id, kind)| (id, masses[kind as usize - 1]))
        .collect();
    Ok((atoms, every))
}

fn print_header<const D: usize>(setup: &Setup<D>, atoms: usize, context: &RunContext) {
    let (threads, out_dir) = (context.threads, &context.out_dir);
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
    context.say(format!(
        "md: {} atoms in {D}D, box {} ({}), lj/cut eps {} sigma {} cutoff {}{}, skin {}{}",
        atoms,
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
        setup.skin,
        if setup.rebuild == RebuildRule::default() {
            String::new()
        } else {
            format!(
                ", list looked at every {} steps, check {}",
                setup.rebuild.every,
                if setup.rebuild.check { "yes" } else { "no" }
            )
        }
    ));
    context.say(format!(
        "run: {} steps of dt {} with {}, {} thread(s); results in {}",
        setup.steps,
        setup.dt,
        setup.integrator_name,
        threads.count(),
        out_dir.display()
    ));
}

impl<const D: usize> Hosted for MdModel<D> {
    /// Microseconds per atom-step and the neighbour-list rebuilds.
    fn speed(&self, loop_seconds: f64, steps: u64, threads: usize) -> String {
        let n = self.len();
        let per = loop_seconds * 1e6 / (n as f64 * steps.max(1) as f64);
        format!(
            "Loop time of {loop_seconds:.4} s on {threads} thread(s) for {steps} steps with {n} atoms: \
             {per:.4} us/atom-step, {} neighbour-list rebuilds{}",
            self.system.rebuilds(),
            late_note(self.system.late_builds())
        )
    }

    /// Positions or velocities in id order ([`MdModel::set_array`]).
    fn set_array(&mut self, name: &str, values: &[f64], threads: &Threads) -> Result<(), String> {
        MdModel::set_array(self, name, values, threads)
    }
}
