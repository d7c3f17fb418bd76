//! Barnes-Hut: an octree over the particles in Morton order, with each node's
//! moments about its expansion centre, walked once per group (the largest nodes
//! of at most `group_size` nearby particles) to build the lists that the
//! group's particles then sum in straight-line SIMD code. One tree and one walk
//! serve two kernels:
//!
//! - [`BarnesHut`], 3D softened gravity ([`GravityLaw`](crate::interactions::GravityLaw)):
//!   nodes carry their mass and (optionally) traceless quadrupole about the
//!   centre of mass, `phi = -G (M/s + (r.Q.r) / (2 s^5))`,
//!   `acc = G (-M r / s^3 + Q r / s^5 - 5/2 (r.Q.r) r / s^7)` with `r = x - x_com`,
//!   `s^2 = |r|^2 + eps^2`, `Q_ab = sum_p m_p (3 y_a y_b - |y|^2 delta_ab)`,
//!   `y = x_p - x_com`; with repulsion the monopole carries its factors
//!   `(1 - a^4/s^4)` and `(1 - a^4/(5 s^4))` as particles do.
//! - [`VortexTree`], the 2D regularised Biot-Savart law of vortex blobs
//!   ([`BlobKernel`](crate::longrange::BlobKernel)), the particles at `z = 0`:
//!   nodes carry the complex moments `a_k = sum_j Gamma_j (z_j - z_c)^k`,
//!   `k < 8`, about the centre `z_c` of `|Gamma|` (circulations of both signs
//!   may cancel), and give `u - i v = 1/(2 pi i) sum_k a_k / (z - z_c)^(k+1)`.
//!
//! A node of side `l` whose expansion centre lies `delta` from its cube's
//! centre is accepted for a group when that centre is farther than
//! `max(l / theta, sqrt(3)/2 l + clearance) + delta` from the group's bounding
//! box (`sqrt(2)/2` and the square's centre for particles in a plane) and the
//! node holds none of the group's particles; otherwise it is opened, and an
//! opened leaf gives its particles, summed with the exact pair law (self term
//! skipped). The clearance is 0 for gravity and `6.1 sigma` for the vortex
//! kernel, so that an accepted node's blobs act on the group as point vortices
//! (the blob factor is 1 within `8.3e-9`).
//!
//! `walk` holds what the kernels share (sorted particles, node centres and
//! opening distances, the walk and its lists, the group-parallel evaluation);
//! `gravity` and `vortex` hold each kernel's node moments and list sums.
//!
//! The walk gathers (every group writes only its own particles) in parallel, and
//! the lists and sums run in an order fixed by the tree, so 1 and N threads give
//! the same bits. For the same reason an evaluation can be divided among
//! processes that each hold every particle (`share`: each walks a contiguous
//! run of the groups and receives the others' results) and still give every
//! particle the bits of one process; and gravity's tree can be divided among
//! processes that each hold a run of the Morton order (`spread`: locally
//! essential trees), with the same bits.

mod build;
mod fmm;
mod gravity;
mod multipole;
mod share;
mod spread;
mod top;
mod vortex;
mod vortex3;
mod walk;

pub use fmm::{
    ErrorFit, FmmAccuracy, GravityFmm, VortexFmm, VortexFmm3, ORDER_RANGE, TOLERANCE_RANGE,
};
pub use gravity::BarnesHut;
pub use share::{AmongPeers, Share};
pub use vortex::VortexTree;
pub use vortex3::VortexTree3;

/// The tree's settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TreeParams {
    /// The opening angle, in `(0, 1.2]`: smaller is more accurate and slower.
    pub theta: f64,
    /// Whether gravity's nodes carry quadrupoles (more accurate per node) or
    /// monopoles only. The vortex kernel ignores it: its nodes always carry
    /// their full expansion.
    pub quadrupole: bool,
    /// Most particles in a leaf: opened leaves give their particles.
    pub leaf_size: usize,
    /// Most particles in a walk group: the particles that share one walk and
    /// its interaction lists.
    pub group_size: usize,
}

impl Default for TreeParams {
    fn default() -> Self {
        TreeParams {
            theta: 0.5,
            quadrupole: true,
            leaf_size: 16,
            group_size: 128,
        }
    }
}

impl TreeParams {
    /// Checks the ranges: `theta` in `(0, 1.2]`, `leaf_size` and `group_size` in
    /// `1..=256`.
    pub fn check(&self) -> Result<(), String> {
        if !(self.theta > 0.0 && self.theta <= 1.2) {
            return Err(format!("theta must be in (0, 1.2], got {}", self.theta));
        }
        if !(1..=256).contains(&self.leaf_size) {
            return Err(format!(
                "leaf_size must be in 1..=256, got {}",
                self.leaf_size
            ));
        }
        if !(1..=256).contains(&self.group_size) {
            return Err(format!(
                "group_size must be in 1..=256, got {}",
                self.group_size
            ));
        }
        Ok(())
    }
}
