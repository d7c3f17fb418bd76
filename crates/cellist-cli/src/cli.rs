//! The command line: subcommands and their flags.

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

The scenario names its model (model = \"md\") and its keys; see docs/models.md and \
examples/. Input paths in the scenario are relative to the scenario file; output \
files go to the output folder (--out, default out/<scenario name>/): thermo.csv, \
energy.png and the dumps the scenario asks for. The thermo table is printed as the run \
goes, with a progress bar on a terminal, and a breakdown of the loop time at the end.";

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
    /// Worker threads (default: every core).
    #[arg(long)]
    pub threads: Option<usize>,
    /// Output folder (default: out/<scenario name>/).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Override a scenario key, e.g. --set run.steps=200 or
    /// --set system.lattice.cells=[10,10,10] (repeatable).
    #[arg(long = "set", value_name = "KEY=VALUE")]
    pub set: Vec<String>,
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
    /// skin 0.3, dt 0.005, NVE, list rebuilt when an atom moved more than skin/2.
    Lj(BenchLjArgs),
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
    /// Print one JSON object instead of text.
    #[arg(long)]
    pub json: bool,
}
