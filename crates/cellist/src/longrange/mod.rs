//! Long-range solvers for the softened gravity of
//! [`GravityLaw`](crate::interactions::GravityLaw): each fills the
//! acceleration `acc_i = sum_j acc_ij` and potential `phi_i = sum_j phi_ij` of
//! every particle (in input order, self term excluded), exactly ([`direct`]) or
//! approximately ([`tree`], [`mesh`], [`p3m`]).
//!
//! Every solver is deterministic: each particle's sum runs in an order fixed by
//! the data, so 1 and N threads give the same bits.

pub mod biot_savart;
pub mod biot_savart3;
#[cfg(test)]
pub(crate) mod blobs3_testkit;
mod checks;
mod dealt;
pub mod direct;
pub mod mesh;
pub mod p3m;
pub mod tree;

pub use biot_savart::{BlobKernel, DirectBiotSavart, PointVortex, VortexLaw};
pub use biot_savart3::{velocity_and_gradient_at, BlobKernel3, DirectBiotSavart3};
pub use checks::{check_sources, check_sources_among, first_failure};
pub use direct::{DirectSum, PartialField};
pub use mesh::{
    Alone, Exchange, MeshBoundary, MeshParams, ParticleMesh, Peers, Rank, Vic3Boundary, Vic3Params,
    VicBoundary, VicParams, VortexInCell, VortexInCell3,
};
pub use p3m::P3m;
pub use tree::{
    AmongPeers, BarnesHut, ErrorFit, FmmAccuracy, GravityFmm, Share, TreeParams, VortexFmm,
    VortexFmm3, VortexTree, VortexTree3,
};

use crate::threads::Threads;
use std::fmt;

/// The particles a solver sees: masses and positions, in input order.
#[derive(Clone, Copy, Debug)]
pub struct Sources<'a> {
    /// `m_i > 0`.
    pub mass: &'a [f64],
    /// `x_i`.
    pub position: &'a [[f64; 3]],
}

/// What a solver writes: per particle, in input order.
#[derive(Debug)]
pub struct FieldOut<'a> {
    /// `acc_i`.
    pub acc: &'a mut [[f64; 3]],
    /// `phi_i` (the potential energy is `1/2 sum_i m_i phi_i`).
    pub phi: &'a mut [f64],
}

/// A field solver supplied from outside the engine (the ring pass of a
/// distributed run): it fills `acc_i` and `phi_i` of every particle like the
/// engine's own solvers, called once per force evaluation (dynamic dispatch
/// per evaluation, not per pair).
pub trait FieldSolver: fmt::Debug {
    /// Fills `out` with the accelerations and potentials of `sources`.
    fn compute(&mut self, sources: &Sources, out: FieldOut, threads: &Threads);
}
