//! The vortex model's direct sums (2D and 3D) on ranks that each hold every
//! particle: the engine's tournament of particle blocks with its block pairs
//! dealt out among the ranks, each pair computed once on one rank, and each
//! particle's partial sums added in rank order by the rank of its part
//! ([`DirectBiotSavart::compute_shared`],
//! [`DirectBiotSavart3::compute_shared`]).

use super::mesh::MpiExchange;
use super::parts::Figures;
use cellist::longrange::{BlobKernel, BlobKernel3, DirectBiotSavart, DirectBiotSavart3, Exchange};
use cellist::models::vortex::VelocityField;
use cellist::models::vortex3::VelocityField3;
use cellist::Threads;

/// The 2D direct sum divided among the ranks: the engine's [`VelocityField`]
/// for a run whose particles every rank holds.
pub struct PairsVortex {
    solver: DirectBiotSavart,
    exchange: MpiExchange,
}

impl PairsVortex {
    /// The direct sum of `n` blobs of `kernel` on the ranks of `exchange`.
    pub fn new(kernel: BlobKernel, n: usize, exchange: MpiExchange) -> Self {
        PairsVortex {
            solver: DirectBiotSavart::new(kernel, n),
            exchange,
        }
    }

    /// The figures, shared.
    pub fn figures(&self) -> Figures {
        self.exchange.figures()
    }
}

impl std::fmt::Debug for PairsVortex {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "PairsVortex on {} ranks", self.exchange.ranks())
    }
}

impl VelocityField for PairsVortex {
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

/// The 3D direct sum divided among the ranks: the engine's
/// [`VelocityField3`] for a run whose particles every rank holds.
pub struct PairsVortex3 {
    solver: DirectBiotSavart3,
    exchange: MpiExchange,
}

impl PairsVortex3 {
    /// The direct sum of `n` blobs of `kernel` on the ranks of `exchange`.
    pub fn new(kernel: BlobKernel3, n: usize, exchange: MpiExchange) -> Self {
        PairsVortex3 {
            solver: DirectBiotSavart3::new(kernel, n),
            exchange,
        }
    }

    /// The figures, shared.
    pub fn figures(&self) -> Figures {
        self.exchange.figures()
    }
}

impl std::fmt::Debug for PairsVortex3 {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "PairsVortex3 on {} ranks", self.exchange.ranks())
    }
}

impl VelocityField3 for PairsVortex3 {
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
