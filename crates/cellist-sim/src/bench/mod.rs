//! The benchmark workloads of `cellist bench`: each builds its workload, times
//! it (medians of repeated runs) and returns what it measured as a plain
//! value; the command line prints it as text or JSON.

mod billiards;
mod gravity;
mod lj;
mod neighbors;
mod pse;
mod vortex;
mod vortex3;

pub use billiards::{billiards, BilliardsBench, BilliardsRequest};
pub use cellist::longrange::FmmAccuracy;
pub use gravity::{gravity, GravityBench, GravityBodies, GravityRequest, GravitySolver};
pub use lj::{lj, LjBench, LjRequest};
pub use neighbors::{neighbors, NeighborsBench, NeighborsRequest};
pub use pse::{pse, PseBench, PseMethod, PseRequest};
pub use vortex::{vortex, VortexBench, VortexBenchSolver, VortexPoints};
pub use vortex3::vortex3;

// the engine's names a benchmark's flags and figures need
pub use cellist::models::md::late_note;
pub use cellist::neighbors::RebuildRule;

use crate::error::{SimError, SimResult};

/// Refuses `--repeat 0`.
fn at_least_once(repeat: usize) -> SimResult {
    if repeat == 0 {
        return Err(SimError::Input("--repeat must be at least 1".into()));
    }
    Ok(())
}

/// The peak resident set of this process (`VmHWM` of `/proc/self/status`), in
/// bytes; None where the file is not there (not Linux).
fn peak_resident_bytes() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}
