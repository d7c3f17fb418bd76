//! The Barnes-Hut trees of the vortex model (2D and 3D) on ranks that each
//! hold every particle (a replicated run): every rank builds the same tree
//! over all particles (the same octree, moments and opening decisions as one
//! process), walks and sums only its part of the walk groups (a contiguous
//! run of the tree's Morton order, balanced by the last evaluation's
//! interaction counts: [`cellist::longrange::Share`]), and the parts' results
//! are all-gathered into every rank. A particle's sum runs as in one process,
//! so the field has the bits of the single-process tree on any number of
//! ranks. The tree's build and the node moments are repeated on every rank;
//! only the walks and the sums are divided.

use super::parts::{all_gather_parts, Figures};
use cellist::longrange::{BlobKernel, BlobKernel3, Share, TreeParams, VortexTree, VortexTree3};
use cellist::models::vortex::VelocityField;
use cellist::models::vortex3::VelocityField3;
use cellist::Threads;
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;
use std::time::{Duration, Instant};

/// The ranks of `world` as the parts of a divided tree evaluation: rank `r`
/// evaluates part `r`, and the parts are all-gathered (timed).
struct RankShare<'a> {
    world: &'a SimpleCommunicator,
    own: Vec<f64>,
    waited: Duration,
    /// The cuts of the last gather.
    bounds: Vec<usize>,
}

impl<'a> RankShare<'a> {
    fn new(world: &'a SimpleCommunicator) -> Self {
        RankShare {
            world,
            own: Vec::new(),
            waited: Duration::ZERO,
            bounds: Vec::new(),
        }
    }
}

impl Share for RankShare<'_> {
    fn part(&self) -> (usize, usize) {
        (self.world.rank() as usize, self.world.size() as usize)
    }

    fn all_gather(&mut self, values: &mut [f64], width: usize, bounds: &[usize]) {
        let t = Instant::now();
        let rank = self.world.rank() as usize;
        self.own.clear();
        self.own
            .extend_from_slice(&values[bounds[rank] * width..bounds[rank + 1] * width]);
        all_gather_parts(self.world, &self.own, width, bounds, values);
        self.waited += t.elapsed();
        self.bounds.clear();
        self.bounds.extend_from_slice(bounds);
    }
}

/// The figures of a shared tree.
fn tree_figures() -> Figures {
    Figures::new("Shared tree", "gathering the results")
}

/// The vortex model's Barnes-Hut tree divided among the ranks: the engine's
/// [`VelocityField`] for a run whose particles every rank holds, with the
/// velocities of [`VortexTree`] to the bit.
pub struct TreeVortex {
    world: SimpleCommunicator,
    tree: VortexTree,
    figures: Figures,
}

impl TreeVortex {
    /// The tree for blobs of `kernel` with `params` (checked) on the ranks of
    /// `world`.
    pub fn new(
        world: SimpleCommunicator,
        params: TreeParams,
        kernel: BlobKernel,
    ) -> Result<Self, String> {
        Ok(TreeVortex {
            world,
            tree: VortexTree::new(params, kernel)?,
            figures: tree_figures(),
        })
    }

    /// The figures, shared.
    pub fn figures(&self) -> Figures {
        self.figures.clone()
    }
}

impl std::fmt::Debug for TreeVortex {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "TreeVortex on {} ranks", self.world.size())
    }
}

impl VelocityField for TreeVortex {
    fn compute(
        &mut self,
        positions: &[[f64; 2]],
        gamma: &[f64],
        velocity: &mut [[f64; 2]],
        threads: &Threads,
    ) {
        let mut ranks = RankShare::new(&self.world);
        self.tree
            .compute_shared(positions, gamma, velocity, threads, &mut ranks);
        self.figures.add(ranks.waited, &ranks.bounds);
    }
}

/// The 3D vortex model's Barnes-Hut tree divided among the ranks: the
/// engine's [`VelocityField3`] for a run whose particles every rank holds,
/// with the velocities and gradients of [`VortexTree3`] to the bit.
pub struct TreeVortex3 {
    world: SimpleCommunicator,
    tree: VortexTree3,
    figures: Figures,
}

impl TreeVortex3 {
    /// The tree for blobs of `kernel` with `params` (checked) on the ranks of
    /// `world`.
    pub fn new(
        world: SimpleCommunicator,
        params: TreeParams,
        kernel: BlobKernel3,
    ) -> Result<Self, String> {
        Ok(TreeVortex3 {
            world,
            tree: VortexTree3::new(params, kernel)?,
            figures: tree_figures(),
        })
    }

    /// The figures, shared.
    pub fn figures(&self) -> Figures {
        self.figures.clone()
    }
}

impl std::fmt::Debug for TreeVortex3 {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "TreeVortex3 on {} ranks", self.world.size())
    }
}

impl VelocityField3 for TreeVortex3 {
    fn compute(
        &mut self,
        positions: &[[f64; 3]],
        alpha: &[[f64; 3]],
        velocity: &mut [[f64; 3]],
        gradient: &mut [[f64; 9]],
        threads: &Threads,
    ) {
        let mut ranks = RankShare::new(&self.world);
        self.tree
            .compute_shared(positions, alpha, velocity, gradient, threads, &mut ranks);
        self.figures.add(ranks.waited, &ranks.bounds);
    }
}
