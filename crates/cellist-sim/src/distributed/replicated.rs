//! Models whose state every rank holds in full and advances alike, their
//! field sums divided among the ranks: the vortex model with its direct
//! solver by the ring pass ([`super::ring`]), gravity and the vortex model
//! with their Barnes-Hut trees by parts of the tree ([`super::tree`]), and
//! the vortex model's vortex-in-cell on a mesh cut into slabs of planes
//! ([`super::mesh`]). (Gravity's direct sum and mesh solvers divide the
//! bodies among the ranks instead: [`super::gravity`].) Every rank takes the same
//! steps on the same bits, so the checks agree without messages; rank 0 writes
//! the outputs ([`Ranks::Replicated`]).

use super::mesh::{MeshVortex, MpiExchange};
use super::ring::RingVortex;
use super::tree::{TreeGravity, TreeVortex};
use crate::ranks::Ranks;
use cellist::interactions::GravityLaw;
use cellist::longrange::{BlobKernel, Rank, TreeParams, VortexInCell};
use cellist::models::gravity::Solver;
use cellist::models::vortex::{VelocityEngine, VelocitySolver};
use mpi::traits::Communicator;

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

/// The planes of a mesh of `grid` planes along x that the slab decomposition
/// gives each of `ranks` ranks, for the run's `mpi:` line.
pub fn slab_planes(grid: usize, ranks: usize) -> String {
    let (few, many) = (grid / ranks, grid.div_ceil(ranks));
    let planes = if few == many {
        format!("{few}")
    } else {
        format!("{few} or {many}")
    };
    format!("{planes} of the {grid} mesh planes along x")
}

/// What the slab decomposition of a mesh of `grid` planes gives each of
/// `ranks` ranks whose particles every rank holds, for the run's `mpi:` line.
fn slabs(grid: usize, ranks: usize) -> String {
    format!(
        "each rank assigns to and transforms a slab of {} (the FFT's transposes by \
         all-to-all) and interpolates the particles of its planes, the results gathered on \
         every rank",
        slab_planes(grid, ranks)
    )
}

/// On several ranks, the vortex model's mesh solver `kind` (vortex-in-cell)
/// for blobs of `kernel` on a slab-decomposed mesh, its ranks and the run's
/// `mpi:` line; `None` in one process or for another solver; the error of a
/// mesh with fewer rows than ranks.
pub fn vortex_mesh(
    kind: VelocitySolver,
    kernel: BlobKernel,
) -> Option<Result<(VelocityEngine, Ranks, String), String>> {
    let VelocitySolver::Mesh(params) = kind else {
        return None;
    };
    let world = super::world_of_many()?;
    let exchange = MpiExchange::new(world.duplicate());
    let rank = Rank::of(&exchange);
    Some(VortexInCell::on_rank(params, kernel, rank).map(|solver| {
        let line = format!(
            "mpi: {} ranks; the vortex-in-cell velocity on a slab-decomposed mesh: {} (every \
             rank holds every particle)",
            rank.count,
            slabs(params.grid, rank.count)
        );
        let figures = exchange.figures();
        let solver = MeshVortex::new(solver, exchange);
        (
            VelocityEngine::External(Box::new(solver)),
            Ranks::Replicated { world, figures },
            line,
        )
    }))
}
