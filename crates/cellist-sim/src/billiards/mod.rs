//! The hard-disk collision benchmark of seed 001 on the simulation layer: its
//! input read into a model and a job (for `cellist billiards run`, a
//! `model = "billiards"` scenario and the studies), the grader's check of a
//! trajectory, random inputs, and the timed loop of the benchmarks.

mod check;
mod generate;
mod run;

pub use check::{check, Verdict};
pub use generate::{generate, Generate};
pub use run::{run, BilliardsRun};

use crate::driver::{Job, LastFrame};
use crate::error::{SimError, SimResult};
use crate::launch::{execute, RunContext, RunSummary};
use crate::observers::{OutputPlan, TableStyle};
use crate::scenario::keys::CheckpointKeys;
use cellist::models::billiards::{Billiards, BilliardsModel, CellShape, Table, DEFAULT_MAX_SWEEPS};
use cellist::Threads;
use cellist_io::{read_billiards_input, BilliardsInput, DUMP_COLUMNS};
use std::path::{Path, PathBuf};

/// Reads an input and sets up the table with the bound on sweeps per step and the
/// cells of the contact search (warnings to standard error).
pub fn load(
    path: &Path,
    max_sweeps: u64,
    cells: CellShape,
) -> SimResult<(BilliardsInput, Billiards)> {
    let (input, system) = read(path, max_sweeps, cells)?;
    for w in &input.warnings {
        eprintln!("warning: {w}");
    }
    Ok((input, system))
}

/// [`load`] without printing the input's warnings (they stay in the input).
pub(crate) fn read(
    path: &Path,
    max_sweeps: u64,
    cells: CellShape,
) -> SimResult<(BilliardsInput, Billiards)> {
    let input = read_billiards_input(path)?;
    let table = Table {
        side: input.side,
        radius: input.radius,
    };
    let system = Billiards::new(table, input.x.clone(), input.y.clone(), input.v.clone())
        .map_err(|e| SimError::Input(format!("{}: {e}", path.display())))?
        .with_max_sweeps(max_sweeps)
        .with_cells(cells);
    Ok((input, system))
}

/// The table's physics, which a restart must match: the disc count, the box, the
/// radius and the initial state's bits.
fn physics(input: &BilliardsInput) -> Vec<(String, String)> {
    let mut hash: u64 = 0xcbf2_9ce4_8422_2325;
    let bits = input
        .x
        .iter()
        .chain(&input.y)
        .chain(input.v.iter().flatten())
        .map(|v| v.to_bits());
    for b in input.ids.iter().map(|&i| i as u64).chain(bits) {
        for byte in b.to_le_bytes() {
            hash ^= byte as u64;
            hash = hash.wrapping_mul(0x0100_0000_01b3);
        }
    }
    vec![
        ("input.discs".into(), input.ids.len().to_string()),
        ("input.initial_state_fnv1a".into(), format!("{hash:016x}")),
        ("input.radius".into(), input.radius.to_string()),
        ("input.side".into(), input.side.to_string()),
    ]
}

/// The terminal table of the discs' energy.
pub(crate) const ENERGY_TABLE: TableStyle = TableStyle {
    width: 16,
    precision: 8,
    exponent: true,
    shown: 1,
};

/// The dump columns of discs: id, type, x y z, vx vy vz.
pub(crate) fn disc_columns() -> Vec<String> {
    DUMP_COLUMNS[..8].iter().map(|c| c.to_string()).collect()
}

/// The run of `input`'s `system` to its S steps, writing to `dir`, with its
/// physics (for restarts) and its last frame (a LAMMPS dump of the discs).
pub(crate) fn billiards_job(
    input: &BilliardsInput,
    system: Billiards,
    dir: PathBuf,
    checkpoint: Option<CheckpointKeys>,
) -> Job<BilliardsModel> {
    Job {
        model: BilliardsModel::new(system, input.ids.clone()),
        ranks: Default::default(),
        steps: input.steps,
        dir,
        checkpoint,
        physics: physics(input),
        last_frame: LastFrame::Dump {
            file: "last.lammpstrj",
            columns: disc_columns(),
        },
    }
}

/// Runs a collision-benchmark input start to end on the driver, quietly, with
/// only its thermo file (the energy at the first and last step) in `dir`: the
/// studies time it this way (`cellist scaling INPUT.in`, which loads the input
/// once first and prints its warnings then).
pub fn run_quiet(path: &Path, threads: &Threads, dir: &Path) -> SimResult<RunSummary> {
    let (input, system) = read(path, DEFAULT_MAX_SWEEPS, CellShape::Square)?;
    let job = billiards_job(&input, system, dir.to_path_buf(), None);
    let plan = OutputPlan {
        thermo_every: 0,
        table: ENERGY_TABLE,
        plot: None,
        dumps: Vec::new(),
        field: None,
        bodies: None,
        trajectories: Default::default(),
    };
    let context = RunContext::new(dir.to_path_buf(), None, threads)
        .quiet()
        .read_from(Some(path));
    execute(job, &plan, &context, std::time::Instant::now()).map(|(summary, _)| summary)
}

/// `steps` collision steps from a copy of `start` on `threads`, timed: the wall
/// time of the loop and the hardest step `(step, sweeps)`. The benchmarks and
/// the billiards sweep time the collision benchmark this way.
pub fn time_steps(
    start: &Billiards,
    steps: u64,
    threads: &Threads,
) -> SimResult<(f64, (u64, u64))> {
    let mut system = start.clone();
    let mut hardest = (0, 0);
    let clock = std::time::Instant::now();
    for step in 1..=steps {
        let stats = system
            .step(step, threads)
            .map_err(|e| SimError::BlowUp(e.to_string()))?;
        if stats.sweeps > hardest.1 {
            hardest = (step, stats.sweeps);
        }
    }
    Ok((clock.elapsed().as_secs_f64(), hardest))
}
