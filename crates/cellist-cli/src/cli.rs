//! The command line: subcommands and their flags.

use cellist_sim::CellShape;
use clap::{Args, Parser, Subcommand};
use std::path::PathBuf;

/// cellist: particle simulations on cell lists, Verlet lists, trees and meshes.
#[derive(Parser, Debug)]
#[command(name = "cellist", version, about, long_about = None)]
pub struct Cli {
    /// What to do.
    #[command(subcommand)]
    pub command: Command,
}

/// The subcommands.
#[derive(Subcommand, Debug)]
pub enum Command {
    /// Run a scenario (TOML); without one, the built-in Lennard-Jones melt.
    #[command(long_about = RUN_HELP)]
    Run(RunArgs),
    /// Print the neighbour list (pairs closer than a cutoff) of a point file.
    #[command(long_about = NEIGHBORS_HELP)]
    Neighbors(NeighborsArgs),
    /// The hard-disk collision benchmark (seed 001): run, check, generate inputs.
    Billiards {
        /// What to do.
        #[command(subcommand)]
        which: BilliardsCommand,
    },
    /// Run a scenario for every combination of key values (and thread counts) and
    /// tabulate, write and plot the chosen metrics.
    #[command(long_about = SWEEP_HELP)]
    Sweep(SweepArgs),
    /// The observed order of the time integrator: runs at dt, dt/2, ..., dt/2^K to
    /// the same end time.
    #[command(long_about = CONVERGENCE_HELP)]
    Convergence(ConvergenceArgs),
    /// Strong scaling over thread counts: speed-up, efficiency and the serial
    /// fraction fitted by Amdahl's law, overall and per stage.
    #[command(long_about = SCALING_HELP)]
    Scaling(ScalingArgs),
    /// Measure speed on standard workloads.
    Bench {
        /// The workload.
        #[command(subcommand)]
        which: BenchCommand,
    },
}

const RUN_HELP: &str = "\
Run a scenario file (TOML). Without one, run the built-in Lennard-Jones melt \
(examples/lj-melt.toml: 32000 atoms, 1000 steps, LAMMPS's bench/in.lj set-up).

The scenario names its model (model = \"md\": Lennard-Jones molecular dynamics; \
model = \"pse\": diffusion by particle strength exchange; model = \"gravity\": \
self-gravitating bodies, direct, Barnes-Hut, PM or P3M; model = \"vortex\": the 2D \
viscous vortex particle method, direct, Barnes-Hut or vortex-in-cell) and its keys; see \
docs/models.md and examples/. Input paths in the scenario are relative to the \
scenario file; output files go to the output folder (--out, default \
out/<scenario name>/): thermo.csv, a plot (energy.png or error.png) and the dumps, \
field files and pictures the scenario asks for. The thermo table is printed as the run \
goes, with a progress bar on a terminal, and a breakdown of the loop time at the end.

Checkpoints: [output] checkpoint = { every = K, file = \"state.ckpt\" } writes the \
complete state every K steps and at the last step (atomically; the previous one is \
kept as state.ckpt.prev). --restart FILE continues a run from one, bit for bit.

Exit status: 0 done, 2 bad input (scenario, files, checkpoint), 3 the run blew up \
(a value not finite, a particle out of its box: the message names the step, the \
particle and the quantity, and the last good state is written as a frame and a \
checkpoint), 1 anything else.";

const SWEEP_HELP: &str = "\
Run a scenario for every combination of the values given with --set KEY=V1,V2,... \
(any scenario key; several --set multiply; keys joined by + move together, each value \
a list: --set system.lattice.n+system.epsilon=[16,0.0625],[32,0.03125]) and of the \
--threads list, in-process, and \
measure each run: wall time of the loop (`time`) or of a stage (`time.Force`, the stages \
of the run's timing table), a thermo column at the last step (`etotal`), its largest \
drift from step 0 (`etotal.drift`), or the error against the model's exact solution \
(`error`: pse with an initial sine or gaussian, vortex lamb-oseen). Every combination is \
built first (with zero steps), so an unknown key, a value of the wrong type or a metric \
the model does not produce stops the sweep before anything runs (exit status 2).

With --repeat K every combination runs K times, the combinations alternating, and the \
times are medians. Output (--out, default out/<scenario>-sweep/): the table on the \
terminal, sweep.csv (one row per combination), sweep.png (the first metric against the \
first swept key, one line per combination of the others; sweep-<metric>.png for the \
others) and each run's own outputs in runs/001/, runs/002/, ... in the CSV's row order.

Example: cellist sweep examples/pse-sine.toml --set system.lattice.n=32,64,128 \
--set system.method=direct,cell-list --metric time --metric error";

const CONVERGENCE_HELP: &str = "\
Measure the order of the time integration (seed 004's method): run the scenario with \
time steps dt, dt/2, ..., dt/2^K to the same end time (--end-time, or run.steps of the \
scenario times --dt), take the successive differences d_k = |u(dt/2^k) - u(dt/2^(k+1))| \
of the observable and report the order log2(d_k / d_(k+1)). The space discretisation \
stays fixed, so this is the time-step error alone.

Observables: any thermo column at the end (e.g. etotal, ke), or `position`, `velocity` \
(the largest per-particle distance between the runs' final states, particles matched by \
id, minimum image on periodic axes) or `field` (the largest per-particle difference of \
a PSE or vortex field). With --exact (observable `field`, models with an exact \
solution: pse with an initial sine or gaussian, vortex lamb-oseen) the errors against \
the exact solution give a second order, which levels off where the spatial error takes \
over.

Output (--out, default out/<scenario>-convergence/): the table, convergence.csv, \
convergence.png (log-log, with reference slopes 1, 2 and 4) and the runs in runs/.

Example: cellist convergence examples/gravity-two-body.toml --dt 0.004 --halvings 3 \
--observable velocity";

const SCALING_HELP: &str = "\
Strong scaling: run the scenario (or a collision-benchmark input, .in, start to end) \
with each thread count of --threads, --repeat times \
(the thread counts alternating), and report the median and spread of the loop time, the \
speed-up T(p0)/T(p) against the smallest count p0, the efficiency, and the serial \
fraction f fitted by Amdahl's law T(p) = T1 (f + (1 - f)/p) (least squares on the \
medians) with its limit 1/f; the same per stage of the run's timing table, so that the \
stage that stops scaling shows. Thread counts above the machine's cores are allowed and \
flagged as oversubscribed.

Output (--out, default out/<scenario>-scaling/): the tables, scaling.csv (one row per \
section and thread count) and scaling.png (measured speed-up, the fitted Amdahl curve \
and ideal scaling).";

const NEIGHBORS_HELP: &str = "\
Print the neighbour list of a point file: every pair i < j (0-based, in input order) \
whose distance is strictly less than the cutoff, one pair per line as `i j r`, sorted \
by (i, j), with r printed to 17 significant digits.

Input: plain text with 2 or 3 coordinates per line (`#` starts a comment), or \
extended XYZ (`.xyz`: the box from Lattice=\"...\", periodicity from pbc=\"T T T\").

Boundaries: a box (--box, or the Lattice of an XYZ file) means periodic axes unless \
--open is given; no box means open boundaries around the points. On periodic axes \
distances use the nearest image, so the cutoff may be at most half of each periodic \
side.";

/// Flags of `cellist run`.
#[derive(Args, Debug)]
pub struct RunArgs {
    /// Scenario file (TOML). Without one, the built-in LJ melt runs.
    pub scenario: Option<PathBuf>,
    /// Worker threads (default: every core; under mpirun, the cores shared
    /// among the ranks on this machine).
    #[arg(long)]
    pub threads: Option<usize>,
    /// Output folder (default: out/<scenario name>/).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Override a scenario key, e.g. --set run.steps=200 or
    /// --set system.lattice.cells=[10,10,10] (repeatable).
    #[arg(long = "set", value_name = "KEY=VALUE")]
    pub set: Vec<String>,
    /// Continue from a checkpoint (written by [output] checkpoint = { every = K,
    /// file = "state.ckpt" }): the run goes on from the checkpoint's step and
    /// continues the output files the first run had begun. The scenario's physics
    /// keys must be the checkpoint's; [output] keys and run.steps may change.
    #[arg(long, value_name = "FILE")]
    pub restart: Option<PathBuf>,
}

/// Flags of `cellist sweep`.
#[derive(Args, Debug)]
pub struct SweepArgs {
    /// Scenario file (TOML).
    pub scenario: PathBuf,
    /// A key and its values, e.g. --set run.dt=0.01,0.005 or
    /// --set system.lattice.cells=[8,8,8],[16,16,16] (repeatable: every combination
    /// runs).
    #[arg(long = "set", value_name = "KEY=V1,V2,...")]
    pub set: Vec<String>,
    /// Thread counts to sweep, e.g. 1,2 (default: every core, not swept).
    #[arg(long, value_delimiter = ',', num_args = 1..)]
    pub threads: Option<Vec<usize>>,
    /// What to measure (repeatable): time, time.<Stage>, a thermo column,
    /// <column>.drift, error. Default: time.
    #[arg(long = "metric", value_name = "NAME")]
    pub metric: Vec<String>,
    /// Runs per combination; times are their median.
    #[arg(long, default_value_t = 1)]
    pub repeat: usize,
    /// Output folder (default: out/<scenario name>-sweep/).
    #[arg(long)]
    pub out: Option<PathBuf>,
}

/// Flags of `cellist convergence`.
#[derive(Args, Debug)]
pub struct ConvergenceArgs {
    /// Scenario file (TOML).
    pub scenario: PathBuf,
    /// The largest time step.
    #[arg(long, allow_negative_numbers = true)]
    pub dt: f64,
    /// Times the step is halved: runs at dt, dt/2, ..., dt/2^K.
    #[arg(long)]
    pub halvings: u32,
    /// What is compared: a thermo column at the end, position, velocity or field.
    #[arg(long)]
    pub observable: String,
    /// Also report the errors against the model's exact solution and their order.
    #[arg(long)]
    pub exact: bool,
    /// End time of every run (default: the scenario's run.steps times --dt).
    #[arg(long, allow_negative_numbers = true)]
    pub end_time: Option<f64>,
    /// Override a scenario key for every run (repeatable), e.g. --set run.integrator=rk2.
    #[arg(long = "set", value_name = "KEY=VALUE")]
    pub set: Vec<String>,
    /// Output folder (default: out/<scenario name>-convergence/).
    #[arg(long)]
    pub out: Option<PathBuf>,
}

/// Flags of `cellist scaling`.
#[derive(Args, Debug)]
pub struct ScalingArgs {
    /// Scenario file (TOML), or a collision-benchmark input (.in).
    pub scenario: PathBuf,
    /// Thread counts, e.g. 1,2,4 (at least two different ones).
    #[arg(long, value_delimiter = ',', num_args = 1.., required = true)]
    pub threads: Vec<usize>,
    /// Runs per thread count (alternating); the median is reported.
    #[arg(long, default_value_t = 3)]
    pub repeat: usize,
    /// Override a scenario key for every run (repeatable), e.g. --set run.steps=200.
    #[arg(long = "set", value_name = "KEY=VALUE")]
    pub set: Vec<String>,
    /// Output folder (default: out/<scenario name>-scaling/).
    #[arg(long)]
    pub out: Option<PathBuf>,
}

/// Flags of `cellist neighbors`.
#[derive(Args, Debug)]
pub struct NeighborsArgs {
    /// Point file: plain text (x y [z] per line) or extended XYZ (.xyz).
    #[arg(long)]
    pub input: PathBuf,
    /// Cutoff radius: pairs with distance strictly less than it are listed.
    #[arg(long, allow_negative_numbers = true)]
    pub cutoff: f64,
    /// Box side lengths (2 or 3 numbers, as many as the points' dimension); the box
    /// is [0, L) on each axis.
    #[arg(long = "box", num_args = 2..=3, value_names = ["LX", "LY", "LZ"], allow_negative_numbers = true)]
    pub box_lengths: Option<Vec<f64>>,
    /// Periodic boundaries on every axis (the default when a box is given).
    #[arg(long, conflicts_with = "open")]
    pub periodic: bool,
    /// Open boundaries on every axis, even when a box is given.
    #[arg(long)]
    pub open: bool,
    /// Worker threads (default: every core); the output does not depend on it.
    #[arg(long)]
    pub threads: Option<usize>,
    /// Write the pairs to this file instead of standard output.
    #[arg(long)]
    pub output: Option<PathBuf>,
    /// Print only the number of pairs.
    #[arg(long)]
    pub count: bool,
}

/// Benchmarks.
#[derive(Subcommand, Debug)]
pub enum BenchCommand {
    /// Build the half neighbour list of uniform random points in a periodic box, as
    /// vesin's NeighborList.compute(quantities="ij") does.
    Neighbors(BenchNeighborsArgs),
    /// The LAMMPS Lennard-Jones melt (bench/in.lj): fcc 0.8442, T 3.0, cutoff 2.5,
    /// skin 0.3, dt 0.005, NVE, list rebuilt when an atom moved more than skin/2
    /// (or every N steps: --every 20 --no-check is LAMMPS's and GROMACS's setting).
    Lj(BenchLjArgs),
    /// Run a collision-benchmark input (.in) start to end, without output.
    Billiards(BenchBilliardsArgs),
    /// Diffusion by particle strength exchange: forward Euler steps on a uniform
    /// lattice in the unit box, a sine field; time per step and pair-kernel
    /// evaluations per second.
    Pse(BenchPseArgs),
    /// Gravity on a Plummer sphere (G = M = a = 1): time per force evaluation (ns
    /// per pair for direct) and, for the approximate solvers, the RMS relative force
    /// error against the direct sum.
    Gravity(BenchGravityArgs),
    /// Vortex particles (2D: two Gaussian vortices on a lattice over [-1, 1]^2;
    /// with --dim 3: a vortex ring; sigma = 1.5 h): time per velocity evaluation
    /// (in 3D with its gradient) and the RMS relative errors against the direct
    /// sum (on a subset of target particles when N is large).
    Vortex(BenchVortexArgs),
}

/// The velocity solver of `cellist bench vortex`.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum VortexSolverArg {
    /// All pairs, exact.
    Direct,
    /// The Barnes-Hut tree with the 2D vortex kernel.
    BarnesHut,
    /// Vortex-in-cell: M4' onto a mesh, FFT Poisson solve, M4' back.
    Mesh,
    /// The fast multipole method: complex expansions on the quadtree (2D), or
    /// the curl of three solid-harmonic potentials on the octree with the blob
    /// law's rest on a cluster list (3D); accuracy set by --tolerance or
    /// --order.
    Fmm,
}

/// Flags of `cellist bench vortex`.
#[derive(Args, Debug)]
pub struct BenchVortexArgs {
    /// The solver.
    #[arg(long, value_enum)]
    pub solver: VortexSolverArg,
    /// Particles (2D: rounded to a square lattice; 3D: a vortex ring of radius
    /// 1 and core 0.2 on a lattice of about N particles).
    #[arg(long, required_unless_present = "input", conflicts_with = "input")]
    pub n: Option<usize>,
    /// Particles from a file instead (2D): lines `x y gamma`, separated by
    /// blanks or commas; blobs of core --sigma, or point vortices without it
    /// (the Cauchy kernel, which only --solver fmm computes).
    #[arg(long, value_name = "FILE")]
    pub input: Option<std::path::PathBuf>,
    /// The blobs' core for the particles of --input.
    #[arg(long, requires = "input")]
    pub sigma: Option<f64>,
    /// Requested relative error (fmm), in (1e-15, 1e-1).
    #[arg(long, default_value_t = 1e-6)]
    pub tolerance: f64,
    /// The expansions' order (fmm), instead of --tolerance.
    #[arg(long, conflicts_with = "tolerance")]
    pub order: Option<usize>,
    /// The dimension: 2 (two Gaussian vortices, velocity) or 3 (a vortex ring,
    /// velocity and its gradient, the stretching's input).
    #[arg(long, default_value_t = 2, value_parser = clap::value_parser!(u8).range(2..=3))]
    pub dim: u8,
    /// Opening angle (barnes-hut), in (0, 1.2].
    #[arg(long, default_value_t = 0.4)]
    pub theta: f64,
    /// Mesh nodes per axis (mesh): a power of two; default: in 2D the smallest at
    /// least as fine as the particle lattice, in 3D the one whose cell is nearest
    /// the lattice spacing.
    #[arg(long)]
    pub grid: Option<usize>,
    /// Worker threads.
    #[arg(long, default_value_t = 1)]
    pub threads: usize,
    /// Timed velocity evaluations; the median is reported.
    #[arg(long, default_value_t = 3)]
    pub repeat: usize,
    /// Target particles the error is measured on (evenly spread; all if N is
    /// smaller).
    #[arg(long, default_value_t = 2000)]
    pub sample: usize,
    /// Print one JSON object instead of text.
    #[arg(long)]
    pub json: bool,
}

/// The solver of `cellist bench gravity`.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum GravitySolverArg {
    /// All pairs, exact.
    Direct,
    /// Barnes-Hut octree.
    BarnesHut,
    /// Particle-mesh (isolated: zero-padded FFT).
    Pm,
    /// Particle-mesh plus the short-range pairs on a cell list.
    P3m,
    /// The fast multipole method (3D): solid harmonics on the octree,
    /// accuracy set by --tolerance or --order.
    Fmm,
}

/// The bodies of `cellist bench gravity --n N`.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum GravityDistributionArg {
    /// A Plummer sphere of equal masses (scale radius 1, total mass 1).
    Plummer,
    /// Uniform in the unit cube, masses uniform in [0, 2/N).
    Uniform,
}

/// Flags of `cellist bench gravity`.
#[derive(Args, Debug)]
pub struct BenchGravityArgs {
    /// The solver.
    #[arg(long, value_enum)]
    pub solver: GravitySolverArg,
    /// Bodies (see --distribution).
    #[arg(long, required_unless_present = "input", conflicts_with = "input")]
    pub n: Option<usize>,
    /// How the N bodies are placed.
    #[arg(long, value_enum, default_value_t = GravityDistributionArg::Plummer)]
    pub distribution: GravityDistributionArg,
    /// Bodies from a file instead: lines `x y z m`, separated by blanks or
    /// commas.
    #[arg(long, value_name = "FILE", conflicts_with = "distribution")]
    pub input: Option<std::path::PathBuf>,
    /// Requested relative error (fmm), in (1e-15, 1e-1).
    #[arg(long, default_value_t = 1e-6)]
    pub tolerance: f64,
    /// The expansions' order (fmm), instead of --tolerance.
    #[arg(long, conflicts_with = "tolerance")]
    pub order: Option<usize>,
    /// Opening angle (barnes-hut), in (0, 1.2].
    #[arg(long, default_value_t = 0.5)]
    pub theta: f64,
    /// Monopoles only (barnes-hut; default: quadrupoles).
    #[arg(long)]
    pub monopole: bool,
    /// Most bodies per tree leaf (barnes-hut).
    #[arg(long, default_value_t = 16)]
    pub leaf_size: usize,
    /// Most bodies per walk group (barnes-hut).
    #[arg(long, default_value_t = 128)]
    pub group_size: usize,
    /// Mesh nodes per axis (pm, p3m): a power of two >= 8.
    #[arg(long, default_value_t = 64)]
    pub grid: usize,
    /// Splitting radius in mesh cells (p3m).
    #[arg(long, default_value_t = 1.25)]
    pub split: f64,
    /// Plummer softening length (0: the plain 1/r law).
    #[arg(long, default_value_t = 0.01)]
    pub softening: f64,
    /// Seed of the Plummer sphere or the uniform cube.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Worker threads.
    #[arg(long, default_value_t = 1)]
    pub threads: usize,
    /// Timed force evaluations; the median is reported.
    #[arg(long, default_value_t = 5)]
    pub repeat: usize,
    /// Bodies the error is measured at, evenly spread (default: all; the
    /// direct sum at each costs N pairs).
    #[arg(long)]
    pub sample: Option<usize>,
    /// Print one JSON object instead of text.
    #[arg(long)]
    pub json: bool,
}

/// The pair sum of `cellist bench pse`.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum PseMethodArg {
    /// All pairs, O(N^2).
    Direct,
    /// Pairs within cutoff_factor * eps from a cell list, O(N).
    CellList,
}

/// Flags of `cellist bench pse`.
#[derive(Args, Debug)]
pub struct BenchPseArgs {
    /// Particles per side of the lattice (N = n^dim).
    #[arg(long)]
    pub n_per_side: usize,
    /// Dimension (2 or 3).
    #[arg(long, default_value_t = 2, value_parser = clap::value_parser!(u8).range(2..=3))]
    pub dim: u8,
    /// All pairs or cell list.
    #[arg(long, value_enum, default_value_t = PseMethodArg::CellList)]
    pub method: PseMethodArg,
    /// Kernel width in lattice spacings, eps / h.
    #[arg(long, default_value_t = 1.0)]
    pub eps_over_h: f64,
    /// Cutoff of the cell list in units of eps.
    #[arg(long, default_value_t = 5.0)]
    pub cutoff_factor: f64,
    /// Timed steps per repetition (forward Euler: one rate evaluation each).
    #[arg(long, default_value_t = 5)]
    pub steps: u64,
    /// Worker threads.
    #[arg(long, default_value_t = 1)]
    pub threads: usize,
    /// Timed repetitions; the median is reported.
    #[arg(long, default_value_t = 3)]
    pub repeat: usize,
    /// Print one JSON object instead of text.
    #[arg(long)]
    pub json: bool,
}

/// Flags of `cellist bench billiards`.
#[derive(Args, Debug)]
pub struct BenchBilliardsArgs {
    /// The input file (.in).
    pub input: PathBuf,
    /// Worker threads.
    #[arg(long, default_value_t = 1)]
    pub threads: usize,
    /// Steps to run (default: S from the input).
    #[arg(long)]
    pub steps: Option<u64>,
    /// Timed repetitions (each from the input state); the median is reported.
    #[arg(long, default_value_t = 5)]
    pub repeat: usize,
    /// Cells of the contact search: `square`, or `hex` (seed 001's experiment:
    /// rows of cells shifted by half a cell, 3 neighbour cells to search instead of
    /// 4). The output bits are the same either way; only the time differs.
    #[arg(long, value_enum, default_value_t = CellsArg::Square)]
    pub cells: CellsArg,
    /// Print one JSON object instead of text.
    #[arg(long)]
    pub json: bool,
}

/// The subcommands of `cellist billiards`.
#[derive(Subcommand, Debug)]
pub enum BilliardsCommand {
    /// Simulate an input file and write the final state.
    #[command(long_about = BILLIARDS_RUN_HELP)]
    Run(BilliardsRunArgs),
    /// Check a per-step trajectory as the course's grader does.
    #[command(long_about = BILLIARDS_CHECK_HELP)]
    Check(BilliardsCheckArgs),
    /// Write a random input file.
    #[command(long_about = BILLIARDS_GEN_HELP)]
    Gen(BilliardsGenArgs),
    /// Time the collision steps on generated inputs for every combination of N, L,
    /// r, S, cell layout and thread count (seed 001's studies).
    #[command(long_about = BILLIARDS_SWEEP_HELP)]
    Sweep(BilliardsSweepArgs),
}

const BILLIARDS_RUN_HELP: &str = "\
Simulate a collision-benchmark input (.in: N, L, r, S, then `i x y vx vy` per \
particle) for S steps and write the final state.

Each step moves every disc by its velocity, then resolves wall and disc collisions \
with positions frozen until none is left, in the canonical order of SPEC.md \
(../shared/testdata/billiards/): walls in vector order, then overlapping pairs in \
lexicographic order, repeated until a sweep changes nothing. Only the candidates \
are visited (found on a grid) and each connected group of overlapping discs is \
resolved on its own, groups in parallel; the result is the same bits for any \
thread count.

Output: `S i x y vx vy` per particle, with 8 decimals (--format out) or the 16 hex \
digits of each IEEE-754 value (--format bits), to standard output or --output. \
--viz writes every step 1..S in the same format (the course validator's \
visualisation file with --format out). --gif animates the discs coloured by speed; \
--png draws the last step. A summary goes to standard error.";

const BILLIARDS_CHECK_HELP: &str = "\
Check a per-step trajectory (steps 1, 2, ... in order, N lines `step i x y vx vy` \
each, in fixed decimals or bit patterns) against its input, as the course's grader \
does (SPEC.md section 6): ids, positions moved by the previous velocity, energy per \
group of touching discs, momentum per group away from the walls, no collision left, \
with tolerances 1e-4 (absolute and relative). Any valid resolution order passes.

Prints one line: `OK: K steps pass` (exit 0), or `FAIL at step k: <check>: <what>` \
naming the particle or group (exit 1).";

const BILLIARDS_GEN_HELP: &str = "\
Write a random input file: N discs of radius R in a box of side L, S steps, each \
velocity component uniform in [VMIN, VMAX].

By default no disc overlaps another or a wall (one disc per square of side > 2R, \
at a random place inside it; at most density pi/4). With --overlaps, x and y are \
uniform in [0, L) as in the course's generator, which made its large inputs: \
overlaps are then normal. Values are written with enough digits to read back \
exactly.";

const BILLIARDS_SWEEP_HELP: &str = "\
Time the collision benchmark on generated inputs, for every combination of the \
values of --n (particles N), --l (box side L), --r (radius r), --steps (S), --cells \
and --threads: seed 001's studies of its collision code against N, L, r, S and \
threads. Each of these flags takes one value (fixed) or a comma list (swept), \
e.g. --n 12500,25000,50000 --l 20000 --r 30 --steps 100 --threads 1,2.

Each input is drawn in memory as `cellist billiards gen N L R S VMIN VMAX --seed \
SEED [--overlaps]` would write it (velocity components uniform in [--vmin, \
--vmax]; the same seed for every combination): with --overlaps, positions uniform \
in [0, L) as the course's generator makes its inputs; without it, discs that \
overlap nothing, which this placement can only do up to density pi/4 (a denser \
combination is refused, naming it, before anything is timed). Every combination \
is drawn and checked first; then the loop of S steps (not the drawing) is timed \
--repeat times, the combinations taking turns (round-robin), and the median is \
reported. One line is printed per timed run; thread counts above the machine's \
cores are flagged as oversubscribed.

Metrics per combination: time (the median loop time, s), steps_per_s, \
ns_per_disc_step (time / (N S)), max_sweeps (the sweeps of the hardest step, the \
same for any thread count and layout). As `cellist sweep`: the table is printed \
(the keys that take one value on a `fixed:` line above it) and written as \
sweep.csv (the keys N, L, r, S, cells, threads, then the metrics), sweep.png (time \
against the first key that takes several values, one line per combination of the \
other swept keys; log axes when the values span decades) and sweep-<metric>.png, \
in --out (default out/billiards-sweep/).";

/// Flags of `cellist billiards sweep`.
#[derive(Args, Debug)]
#[command(allow_negative_numbers = true)]
pub struct BilliardsSweepArgs {
    /// Particle counts N, e.g. 12500,25000,50000.
    #[arg(long, value_delimiter = ',', num_args = 1.., required = true)]
    pub n: Vec<usize>,
    /// Box sides L (integers), e.g. 20000.
    #[arg(long, value_delimiter = ',', num_args = 1.., required = true)]
    pub l: Vec<i64>,
    /// Disc radii r (integers), e.g. 30.
    #[arg(long, value_delimiter = ',', num_args = 1.., required = true)]
    pub r: Vec<i64>,
    /// Steps S of the timed loop, e.g. 100.
    #[arg(long, value_delimiter = ',', num_args = 1.., required = true)]
    pub steps: Vec<u64>,
    /// Smallest velocity component of the generated inputs.
    #[arg(long, default_value_t = 2.0)]
    pub vmin: f64,
    /// Largest velocity component of the generated inputs.
    #[arg(long, default_value_t = 5.0)]
    pub vmax: f64,
    /// Thread counts, e.g. 1,2 (default: every core).
    #[arg(long, value_delimiter = ',', num_args = 1..)]
    pub threads: Option<Vec<usize>>,
    /// Cells of the contact search: square, hex, or square,hex (both timed).
    #[arg(long, value_enum, value_delimiter = ',', num_args = 1.., default_value = "square")]
    pub cells: Vec<CellsArg>,
    /// Seed of the random numbers (the same for every combination).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Uniform positions in [0, L) as the course's generator (discs may overlap);
    /// without it, discs that overlap nothing (density at most pi/4).
    #[arg(long)]
    pub overlaps: bool,
    /// Timed runs per combination (round-robin); the median is reported.
    #[arg(long, default_value_t = 3)]
    pub repeat: usize,
    /// Output folder (default: out/billiards-sweep/).
    #[arg(long)]
    pub out: Option<PathBuf>,
}

/// Flags of `cellist billiards run`.
#[derive(Args, Debug)]
pub struct BilliardsRunArgs {
    /// The input file (.in).
    pub input: PathBuf,
    /// Worker threads (default: every core); the output does not depend on it.
    #[arg(long)]
    pub threads: Option<usize>,
    /// Steps to run (default: S from the input).
    #[arg(long)]
    pub steps: Option<u64>,
    /// Write the final state here instead of standard output.
    #[arg(long)]
    pub output: Option<PathBuf>,
    /// `out`: 8 decimals; `bits`: IEEE-754 bit patterns (for exact comparison).
    #[arg(long, value_enum, default_value_t = StateFormatArg::Out)]
    pub format: StateFormatArg,
    /// Also write every step 1..S to this file (same format).
    #[arg(long)]
    pub viz: Option<PathBuf>,
    /// Animate the run as a GIF (discs coloured by speed).
    #[arg(long)]
    pub gif: Option<PathBuf>,
    /// Draw the last step as a PNG.
    #[arg(long)]
    pub png: Option<PathBuf>,
    /// A GIF frame every this many steps (default: about 200 frames in all).
    #[arg(long)]
    pub frame_every: Option<u64>,
    /// Side of the pictures in pixels.
    #[arg(long, default_value_t = 600)]
    pub picture_size: u32,
    /// Stop when one step needs more sweeps than this.
    #[arg(long, default_value_t = cellist_sim::DEFAULT_MAX_SWEEPS)]
    pub max_sweeps: u64,
    /// Cells of the contact search: `square`, or `hex` (seed 001's experiment:
    /// rows of cells shifted by half a cell, 3 neighbour cells to search instead of
    /// 4). The output bits are the same either way; only the time differs.
    #[arg(long, value_enum, default_value_t = CellsArg::Square)]
    pub cells: CellsArg,
    /// Write a checkpoint (the complete state) to this file every
    /// --checkpoint-every steps and at the last step; the previous one is kept as
    /// FILE.prev.
    #[arg(long, requires = "checkpoint_every")]
    pub checkpoint: Option<PathBuf>,
    /// Steps between checkpoints.
    #[arg(long, requires = "checkpoint")]
    pub checkpoint_every: Option<u64>,
    /// Continue from a checkpoint of this input: the run goes on from its step and
    /// continues the --viz and --gif files the first run had begun, giving the
    /// bytes of an uninterrupted run.
    #[arg(long)]
    pub restart: Option<PathBuf>,
}

/// The `--cells` of `cellist billiards run` and `cellist bench billiards`: the
/// layout of the contact search's cells ([`CellShape`]).
#[derive(clap::ValueEnum, Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum CellsArg {
    /// Squares of side just above the contact distance 2R; 4 neighbour squares
    /// searched per square.
    #[default]
    Square,
    /// Seed 001's hexagon arrangement: rows just over 2R high, every other row
    /// shifted by half a cell, cells twice as wide as high (so that 6 neighbours
    /// hold every contact); 3 neighbour cells searched per cell.
    Hex,
}

impl CellsArg {
    /// The engine's layout.
    pub fn shape(self) -> CellShape {
        match self {
            CellsArg::Square => CellShape::Square,
            CellsArg::Hex => CellShape::Hex,
        }
    }

    /// The name on the command line.
    pub fn name(self) -> &'static str {
        self.shape().name()
    }
}

/// The state formats of `cellist billiards run`.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum StateFormatArg {
    /// `step i x y vx vy` with 8 decimals.
    Out,
    /// `step i` and the 16 hex digits of each value's bit pattern.
    Bits,
}

/// Flags of `cellist billiards check`.
#[derive(Args, Debug)]
pub struct BilliardsCheckArgs {
    /// The input file (.in) the trajectory started from.
    pub input: PathBuf,
    /// The trajectory: every step 1..K.
    pub trajectory: PathBuf,
    /// Worker threads (default: every core).
    #[arg(long)]
    pub threads: Option<usize>,
}

/// Flags of `cellist billiards gen`.
#[derive(Args, Debug)]
#[command(allow_negative_numbers = true)]
pub struct BilliardsGenArgs {
    /// Number of discs.
    pub n: usize,
    /// Side of the box (an integer).
    pub l: i64,
    /// Radius of the discs (an integer).
    pub r: i64,
    /// Number of steps to write in the file.
    pub steps: u64,
    /// Smallest velocity component.
    pub vmin: f64,
    /// Largest velocity component.
    pub vmax: f64,
    /// Seed of the random numbers.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Uniform positions in [0, L) as the course's generator (discs may overlap).
    #[arg(long)]
    pub overlaps: bool,
    /// Write the input here instead of standard output.
    #[arg(long)]
    pub output: Option<PathBuf>,
}

/// Flags of `cellist bench lj`.
#[derive(Args, Debug)]
pub struct BenchLjArgs {
    /// fcc unit cells per box side (4 atoms each): 20 gives 32000 atoms.
    #[arg(long, default_value_t = 20)]
    pub atoms_per_side: usize,
    /// Timed steps.
    #[arg(long, default_value_t = 100)]
    pub steps: u64,
    /// Worker threads.
    #[arg(long, default_value_t = 1)]
    pub threads: usize,
    /// Timed repetitions (each from the same start); the median is reported.
    #[arg(long, default_value_t = 3)]
    pub repeat: usize,
    /// Look at the neighbour list every N steps since its last build (LAMMPS's
    /// `neigh_modify every N`; LAMMPS's bench/in.lj and GROMACS's nstlist use 20).
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u64).range(1..))]
    pub every: u64,
    /// Rebuild every `--every` steps without the skin/2 test (LAMMPS's
    /// `check no`); by default the list is rebuilt only when some atom moved
    /// more than skin/2.
    #[arg(long)]
    pub no_check: bool,
    /// Print one JSON object instead of text.
    #[arg(long)]
    pub json: bool,
}

/// Flags of `cellist bench neighbors`.
#[derive(Args, Debug)]
pub struct BenchNeighborsArgs {
    /// Number of points.
    #[arg(long, default_value_t = 1_000_000)]
    pub n: usize,
    /// Dimension (2 or 3).
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u8).range(2..=3))]
    pub dim: u8,
    /// Number density (points per unit volume); sets the box side (N / rho)^(1/dim).
    #[arg(long, default_value_t = 0.8442)]
    pub density: f64,
    /// Cutoff radius.
    #[arg(long, default_value_t = 2.5)]
    pub cutoff: f64,
    /// Worker threads.
    #[arg(long, default_value_t = 1)]
    pub threads: usize,
    /// Seed of the random points.
    #[arg(long, default_value_t = 20260601)]
    pub seed: u64,
    /// Timed repetitions; the median is reported.
    #[arg(long, default_value_t = 5)]
    pub repeat: usize,
    /// Time the sorted half list instead (sorted by (i, j), int64 indices), as
    /// `cellist neighbors` prints it and the Python module's `neighbors` returns it.
    #[arg(long)]
    pub sorted: bool,
    /// Time the half list in the order the cells find it instead (int64 index
    /// arrays), as the Python module's `neighbors(..., sorted=False)` returns it.
    #[arg(long, conflicts_with = "sorted")]
    pub as_found: bool,
    /// Print one JSON object instead of text.
    #[arg(long)]
    pub json: bool,
}
