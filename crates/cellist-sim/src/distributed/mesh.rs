//! The mesh solvers on several ranks, each rank holding a slab of the mesh's
//! planes: gravity's particle-mesh and P3M with the bodies divided among the
//! ranks ([`super::gravity`]), and the vortex model's
//! vortex-in-cell velocity with every particle on each rank (the state is
//! replicated, [`super::replicated`]). The engine does the physics, the slab
//! FFT ([`cellist::longrange::mesh::slab`]) and the bodies' routes to the
//! slabs; this module gives it MPI's collectives ([`MpiExchange`]): the
//! all-to-all transposes of the FFT and routes of the bodies, and the
//! all-gathers of the particles' results (also the exchange of the trees'
//! and the fmm's gathers).

use super::layout;
use super::parts::Figures;
use cellist::longrange::{Exchange, VortexInCell, VortexInCell3};
use cellist::models::vortex::VelocityField;
use cellist::models::vortex3::VelocityField3;
use cellist::Threads;
use mpi::datatype::{Partition, PartitionMut};
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;
use std::time::Instant;

/// The engine's [`Exchange`] on the ranks of an MPI communicator, the time
/// spent in its collectives added to its [`Figures`].
pub struct MpiExchange {
    world: SimpleCommunicator,
    figures: Figures,
}

impl MpiExchange {
    /// The exchange on the ranks of `world`, for a mesh whose particles every
    /// rank holds.
    pub fn new(world: SimpleCommunicator) -> Self {
        MpiExchange {
            world,
            figures: Figures::new("Slab-decomposed mesh", "in the transposes and gathers"),
        }
    }

    /// The exchange on the ranks of `world`, for a mesh whose particles are
    /// divided among them.
    pub fn routing(world: SimpleCommunicator) -> Self {
        MpiExchange {
            world,
            figures: Figures::new(
                "Slab-decomposed mesh",
                "in the transposes and the bodies' routes",
            ),
        }
    }

    /// The exchange on the ranks of `world`, for a Barnes-Hut tree whose
    /// bodies are divided among them.
    pub fn essential(world: SimpleCommunicator) -> Self {
        MpiExchange {
            world,
            figures: Figures::new(
                "Locally essential trees",
                "in the bodies' routes, the top of the tree and the essential parts",
            ),
        }
    }

    /// The exchange on the ranks of `world` for gravity's fmm, which gathers
    /// every rank's bodies and the target groups' results.
    pub fn gathering(world: SimpleCommunicator) -> Self {
        MpiExchange {
            world,
            figures: Figures::new("Shared fmm", "gathering the bodies and the results"),
        }
    }

    /// The exchange on the ranks of `world` for pair sums dealt out among
    /// them, whose partial sums it adds and gathers.
    pub fn summing(world: SimpleCommunicator) -> Self {
        MpiExchange {
            world,
            figures: Figures::new("Shared pair sums", "adding and gathering the partial sums"),
        }
    }

    /// The exchange on the ranks of `world` whose time counts in `figures`
    /// (a replicated solver's): the vortex model's PSE rates, thermo pair
    /// sums and fmm.
    pub fn counted_in(world: SimpleCommunicator, figures: Figures) -> Self {
        MpiExchange { world, figures }
    }

    /// The time spent in the collectives, shared.
    pub fn figures(&self) -> Figures {
        self.figures.clone()
    }

    fn timed(&self, exchange: impl FnOnce()) {
        let t = Instant::now();
        exchange();
        self.figures.add_wait(t.elapsed());
    }
}

impl Exchange for MpiExchange {
    fn rank(&self) -> usize {
        self.world.rank() as usize
    }

    fn ranks(&self) -> usize {
        self.world.size() as usize
    }

    fn all_to_all(
        &self,
        send: &[f64],
        send_counts: &[usize],
        receive: &mut [f64],
        receive_counts: &[usize],
    ) {
        let (sc, sd) = layout(send_counts);
        let (rc, rd) = layout(receive_counts);
        self.timed(|| {
            self.world.all_to_all_varcount_into(
                &Partition::new(send, sc, sd),
                &mut PartitionMut::new(receive, rc, rd),
            )
        });
    }

    fn all_gather(&self, mine: &[f64], counts: &[usize], out: &mut [f64]) {
        let (c, d) = layout(counts);
        self.timed(|| {
            self.world
                .all_gather_varcount_into(mine, &mut PartitionMut::new(out, c, d))
        });
    }
}

/// The vortex-in-cell velocity on several ranks: the engine's
/// [`VelocityField`] for a run whose particles every rank holds.
pub struct MeshVortex {
    solver: VortexInCell,
    exchange: MpiExchange,
}

impl MeshVortex {
    /// `solver`, built for this rank's slab of `exchange`'s ranks.
    pub fn new(solver: VortexInCell, exchange: MpiExchange) -> Self {
        MeshVortex { solver, exchange }
    }
}

impl std::fmt::Debug for MeshVortex {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{:?} on {} ranks", self.solver, self.exchange.ranks())
    }
}

impl VelocityField for MeshVortex {
    fn compute(
        &mut self,
        positions: &[[f64; 2]],
        gamma: &[f64],
        velocity: &mut [[f64; 2]],
        threads: &Threads,
    ) {
        self.solver
            .compute_shared(positions, gamma, velocity, threads, &self.exchange);
    }
}

/// The 3D vortex model's vortex-in-cell on a slab-decomposed mesh: the
/// engine's [`VelocityField3`] for a run whose particles every rank holds,
/// with the velocities and gradients of one process to the bit.
pub struct MeshVortex3 {
    solver: VortexInCell3,
    exchange: MpiExchange,
}

impl MeshVortex3 {
    /// `solver` (built for this rank's slab) with the exchange among its ranks.
    pub fn new(solver: VortexInCell3, exchange: MpiExchange) -> Self {
        MeshVortex3 { solver, exchange }
    }
}

impl std::fmt::Debug for MeshVortex3 {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{:?} on {} ranks", self.solver, self.exchange.ranks())
    }
}

impl VelocityField3 for MeshVortex3 {
    fn compute(
        &mut self,
        positions: &[[f64; 3]],
        alpha: &[[f64; 3]],
        velocity: &mut [[f64; 3]],
        gradient: &mut [[f64; 9]],
        threads: &Threads,
    ) {
        self.solver.compute_shared(
            positions,
            alpha,
            velocity,
            gradient,
            threads,
            &self.exchange,
        );
    }
}
