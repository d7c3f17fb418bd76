//! Models whose state every rank holds in full and advances alike, their
//! all-pairs sums divided among the ranks by the ring pass ([`super::ring`]):
//! gravity and the vortex model with their direct solvers. Every rank takes
//! the same steps on the same bits, so the checks agree without messages;
//! rank 0 writes the outputs ([`Ranks::Replicated`]).

use super::ring::{RingGravity, RingVortex};
use crate::ranks::Ranks;
use cellist::interactions::GravityLaw;
use cellist::longrange::BlobKernel;
use cellist::models::gravity::Solver;
use cellist::models::vortex::VelocityEngine;
use mpi::traits::Communicator;

/// On several ranks, gravity's direct solver by the ring pass for `law`, and
/// its ranks; `None` in one process.
pub fn gravity_ring(law: GravityLaw) -> Option<(Solver, Ranks)> {
    let world = super::world_of_many()?;
    let solver = RingGravity::new(world.duplicate(), law);
    let waited = solver.waited();
    Some((
        Solver::External(Box::new(solver)),
        Ranks::Replicated { world, waited },
    ))
}

/// On several ranks, the vortex model's direct solver by the ring pass for
/// blobs of `kernel`, and its ranks; `None` in one process.
pub fn vortex_ring(kernel: BlobKernel) -> Option<(VelocityEngine, Ranks)> {
    let world = super::world_of_many()?;
    let solver = RingVortex::new(world.duplicate(), kernel);
    let waited = solver.waited();
    Some((
        VelocityEngine::External(Box::new(solver)),
        Ranks::Replicated { world, waited },
    ))
}
