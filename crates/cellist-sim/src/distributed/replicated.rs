//! Models whose state every rank holds in full and advances alike, their
//! field sums divided among the ranks: the vortex model (2D and 3D) with its
//! direct solver by block pairs dealt out ([`super::pairs`]), its
//! Barnes-Hut trees by parts of the tree ([`super::tree`]), its fmm by
//! runs of its target groups (the engine's, through the system's peers:
//! [`vortex_fmm`]), and its vortex-in-cell on a mesh cut into slabs of
//! planes ([`super::mesh`]).
//! (Gravity divides its bodies among the ranks instead: [`super::gravity`].) Every rank takes the same
//! steps on the same bits, so the checks agree without messages; rank 0 writes
//! the outputs ([`Ranks::Replicated`]).

use super::mesh::{MeshVortex, MeshVortex3, MpiExchange};
use super::pairs::{PairsVortex, PairsVortex3};
use super::parts::Figures;
use super::tree::{TreeVortex, TreeVortex3};
use crate::ranks::Ranks;
use cellist::longrange::{
    BlobKernel, BlobKernel3, Rank, TreeParams, Vic3Params, VortexInCell, VortexInCell3,
};
use cellist::models::vortex::{VelocityEngine, VelocitySolver};
use cellist::models::vortex3::Velocity3Engine;
use mpi::traits::Communicator;

/// On several ranks, the vortex model's direct sum of `n` blobs of `kernel`
/// with its block pairs dealt out among them, its ranks and the run's `mpi:`
/// line; `None` in one process.
pub fn vortex_pairs(n: usize, kernel: BlobKernel) -> Option<(VelocityEngine, Ranks, String)> {
    let world = super::world_of_many()?;
    let solver = PairsVortex::new(kernel, n, MpiExchange::summing(world.duplicate()));
    let figures = solver.figures();
    let line = format!("mpi: {} ranks; {PAIRS_LINE}", world.size());
    Some((
        VelocityEngine::External(Box::new(solver)),
        Ranks::Replicated { world, figures },
        line,
    ))
}

/// On several ranks, the ranks of a vortex run (2D or 3D) whose fmm divides
/// its sums among them (the engine's [`cellist::longrange::AmongPeers`],
/// through the system's [`Ranks::peers`]) and the run's `mpi:` line; `None`
/// in one process.
pub fn vortex_fmm() -> Option<(Ranks, String)> {
    let world = super::world_of_many()?;
    let line = format!(
        "mpi: {} ranks; the fmm's tree and upward pass made alike on every rank (the particles \
         held by every rank), each rank summing a run of its target groups balanced by their \
         last pair terms and M2L (in 3D also a run of the blob rest's cell layers balanced \
         by cluster pairs), the results all-gathered: one process's velocities to the bit",
        world.size()
    );
    let figures = Figures::new("Shared fmm", "gathering the results");
    Some((Ranks::Replicated { world, figures }, line))
}

/// How the direct sums' pairs are dealt out, for the run's `mpi:` line.
const PAIRS_LINE: &str = "the direct velocity with the pairs of particle blocks dealt out among \
     the ranks (each pair once), each particle's partial sums added in rank order and gathered \
     (the particles held by every rank)";

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

/// On several ranks, the 3D vortex model's direct sum of `n` blobs of
/// `kernel` with its block pairs dealt out among them, its ranks and the
/// run's `mpi:` line; `None` in one process.
pub fn vortex3_pairs(n: usize, kernel: BlobKernel3) -> Option<(Velocity3Engine, Ranks, String)> {
    let world = super::world_of_many()?;
    let solver = PairsVortex3::new(kernel, n, MpiExchange::summing(world.duplicate()));
    let figures = solver.figures();
    let line = format!("mpi: {} ranks; {PAIRS_LINE}", world.size());
    Some((
        Velocity3Engine::External(Box::new(solver)),
        Ranks::Replicated { world, figures },
        line,
    ))
}

/// On several ranks, the 3D vortex model's Barnes-Hut tree divided among
/// them for blobs of `kernel` with `params`, its ranks and the run's `mpi:`
/// line; `None` in one process.
pub fn vortex3_tree(
    params: TreeParams,
    kernel: BlobKernel3,
) -> Option<Result<(Velocity3Engine, Ranks, String), String>> {
    let world = super::world_of_many()?;
    Some(
        TreeVortex3::new(world.duplicate(), params, kernel).map(|solver| {
            let figures = solver.figures();
            let line = format!(
                "mpi: {} ranks; the Barnes-Hut tree of all the particles built alike on every \
                 rank (the particles held by every rank), each rank walking a run of its groups \
                 balanced by interactions, the results all-gathered: one process's velocities \
                 and gradients to the bit",
                world.size()
            );
            (
                Velocity3Engine::External(Box::new(solver)),
                Ranks::Replicated { world, figures },
                line,
            )
        }),
    )
}

/// On several ranks, the 3D vortex model's vortex-in-cell with `params` for
/// blobs of core `sigma` on a slab-decomposed mesh, its ranks and the run's
/// `mpi:` line; `None` in one process; the error of a mesh with too few
/// planes for the ranks.
pub fn vortex3_mesh(
    params: Vic3Params,
    sigma: f64,
) -> Option<Result<(Velocity3Engine, Ranks, String), String>> {
    let world = super::world_of_many()?;
    let exchange = MpiExchange::new(world.duplicate());
    let rank = Rank::of(&exchange);
    Some(VortexInCell3::on_rank(params, sigma, rank).map(|solver| {
        let line = format!(
            "mpi: {} ranks; the vortex-in-cell velocity and gradient on a slab-decomposed \
             mesh: {} (every rank holds every particle)",
            rank.count,
            slabs(params.grid, rank.count)
        );
        let figures = exchange.figures();
        let solver = MeshVortex3::new(solver, exchange);
        (
            Velocity3Engine::External(Box::new(solver)),
            Ranks::Replicated { world, figures },
            line,
        )
    }))
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
