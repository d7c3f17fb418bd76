//! Models whose state every rank holds in full and advances alike, their
//! field sums divided among the ranks: gravity and the vortex model with their
//! direct solvers by the ring pass ([`super::ring`]) and with their Barnes-Hut
//! trees by parts of the tree ([`super::tree`]). Every rank takes the same
//! steps on the same bits, so the checks agree without messages; rank 0 writes
//! the outputs ([`Ranks::Replicated`]).

use super::ring::{RingGravity, RingVortex};
use super::tree::{TreeGravity, TreeVortex};
use crate::ranks::Ranks;
use cellist::interactions::GravityLaw;
use cellist::longrange::{BlobKernel, TreeParams};
use cellist::models::gravity::Solver;
use cellist::models::vortex::VelocityEngine;
use mpi::traits::Communicator;

/// On several ranks, gravity's direct solver by the ring pass for `law`, and
/// its ranks; `None` in one process.
pub fn gravity_ring(law: GravityLaw) -> Option<(Solver, Ranks)> {
    let world = super::world_of_many()?;
    let solver = RingGravity::new(world.duplicate(), law);
    let figures = solver.figures();
    Some((
        Solver::External(Box::new(solver)),
        Ranks::Replicated { world, figures },
    ))
}

/// On several ranks, gravity's Barnes-Hut tree divided among them for `law`
/// with `params`, and its ranks; `None` in one process.
pub fn gravity_tree(
    law: GravityLaw,
    params: TreeParams,
) -> Option<Result<(Solver, Ranks), String>> {
    let world = super::world_of_many()?;
    Some(
        TreeGravity::new(world.duplicate(), law, params).map(|solver| {
            let figures = solver.figures();
            (
                Solver::External(Box::new(solver)),
                Ranks::Replicated { world, figures },
            )
        }),
    )
}

/// On several ranks, the vortex model's direct solver by the ring pass for
/// blobs of `kernel`, and its ranks; `None` in one process.
pub fn vortex_ring(kernel: BlobKernel) -> Option<(VelocityEngine, Ranks)> {
    let world = super::world_of_many()?;
    let solver = RingVortex::new(world.duplicate(), kernel);
    let figures = solver.figures();
    Some((
        VelocityEngine::External(Box::new(solver)),
        Ranks::Replicated { world, figures },
    ))
}

/// On several ranks, the vortex model's Barnes-Hut tree divided among them
/// for blobs of `kernel` with `params`, and its ranks; `None` in one process.
pub fn vortex_tree(
    params: TreeParams,
    kernel: BlobKernel,
) -> Option<Result<(VelocityEngine, Ranks), String>> {
    let world = super::world_of_many()?;
    Some(
        TreeVortex::new(world.duplicate(), params, kernel).map(|solver| {
            let figures = solver.figures();
            (
                VelocityEngine::External(Box::new(solver)),
                Ranks::Replicated { world, figures },
            )
        }),
    )
}
