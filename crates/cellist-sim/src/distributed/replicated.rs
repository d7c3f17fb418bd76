//! Models whose state every rank holds in full and advances alike, their
//! field sums divided among the ranks: the vortex model with its direct
//! solver by the ring pass ([`super::ring`]; gravity's bodies are divided
//! among the ranks instead, [`super::gravity`]), gravity and the vortex model
//! with their Barnes-Hut
//! trees by parts of the tree ([`super::tree`]) and with their mesh solvers on
//! a mesh cut into slabs of planes ([`super::mesh`]). Every rank takes the same
//! steps on the same bits, so the checks agree without messages; rank 0 writes
//! the outputs ([`Ranks::Replicated`]).

use super::mesh::{MeshGravity, MeshGravitySolver, MeshVortex, MpiExchange};
use super::ring::RingVortex;
use super::tree::{TreeGravity, TreeVortex};
use crate::ranks::Ranks;
use cellist::interactions::GravityLaw;
use cellist::longrange::{
    BlobKernel, MeshParams, P3m, ParticleMesh, Rank, TreeParams, VortexInCell,
};
use cellist::models::gravity::{Solver, SolverChoice};
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

/// What the slab decomposition of a mesh of `grid` planes along x gives each
/// of `ranks` ranks, for the run's `mpi:` line.
fn slabs(grid: usize, ranks: usize) -> String {
    let (few, many) = (grid / ranks, grid.div_ceil(ranks));
    let planes = if few == many {
        format!("{few}")
    } else {
        format!("{few} or {many}")
    };
    format!(
        "each rank assigns to and transforms a slab of {planes} of the {grid} mesh planes along \
         x (the FFT's transposes by all-to-all) and interpolates the particles of its planes, \
         the results gathered on every rank"
    )
}

/// On several ranks, gravity's mesh solver `choice` (PM or P3M) for `law` on
/// a slab-decomposed mesh, its ranks and the run's `mpi:` line for `bodies`
/// bodies; `None` in one process or for another solver; the error of a mesh
/// with fewer planes than ranks.
pub fn gravity_mesh(
    choice: &SolverChoice,
    law: GravityLaw,
    bodies: usize,
) -> Option<Result<(Solver, Ranks, String), String>> {
    let (mesh, split): (&MeshParams, Option<f64>) = match choice {
        SolverChoice::Pm(mesh) => (mesh, None),
        SolverChoice::P3m { mesh, split_cells } => (mesh, Some(*split_cells)),
        _ => return None,
    };
    let world = super::world_of_many()?;
    let exchange = MpiExchange::new(world.duplicate());
    let rank = Rank::of(&exchange);
    let built = match split {
        None => ParticleMesh::on_rank(law, *mesh, rank).map(MeshGravitySolver::Pm),
        Some(s) => P3m::on_rank(law, *mesh, s, rank).map(MeshGravitySolver::P3m),
    };
    Some(built.map(|solver| {
        let ranks = rank.count;
        let short = if split.is_some() {
            format!(
                "; the short range summed for a block of about {} bodies by each rank",
                bodies / ranks
            )
        } else {
            String::new()
        };
        let line = format!(
            "mpi: {ranks} ranks; the {} on a slab-decomposed mesh: {}{short} (every rank \
             holds every body)",
            if split.is_some() {
                "P3M"
            } else {
                "particle-mesh"
            },
            slabs(mesh.grid, ranks)
        );
        let figures = exchange.figures();
        let solver = MeshGravity::new(solver, exchange);
        (
            Solver::External(Box::new(solver)),
            Ranks::Replicated { world, figures },
            line,
        )
    }))
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
