//! The regularised Biot-Savart law of 2D vortex blobs: particles at `x_j` with
//! circulation `Gamma_j` and Gaussian cores of width `sigma` induce
//!
//! ```text
//! u(x) = sum_j Gamma_j K_sigma(x - x_j),
//! K_sigma(d) = (-d_y, d_x) / (2 pi |d|^2) (1 - exp(-|d|^2 / (2 sigma^2))),
//! ```
//!
//! the velocity of the vorticity `sum_j Gamma_j zeta_sigma(x - x_j)`,
//! `zeta_sigma(r) = exp(-r^2 / (2 sigma^2)) / (2 pi sigma^2)`. [`BlobKernel`] is
//! the pair formula every vortex solver shares; [`DirectBiotSavart`] sums all
//! pairs, each once (`K_sigma` is odd), in parallel without atomics and with
//! every particle's sum in an order fixed by the data.

use crate::longrange::dealt::{self, Partials};
use crate::longrange::{Alone, Exchange};
use crate::models::pse::exp_nonpositive;
use crate::simd::{F64x4, Real};
use crate::threads::{tournament, DisjointSlice, Threads};
use rayon::prelude::*;
use std::f64::consts::PI;
use std::fmt::Debug;

/// Below this `x = r^2 / (2 sigma^2)`, `(1 - exp(-x)) / x` is taken from its
/// series (the difference `1 - exp(-x)` would lose `log10(1/x)` digits).
const SERIES_BELOW: f64 = 1e-3;

/// The scalar part of `K_sigma`: `K_sigma(d) = q(|d|^2) (-d_y, d_x)` with
/// `q(r^2) = (1 - exp(-r^2 / (2 sigma^2))) / (2 pi r^2)`, `q(0) = 1 / (4 pi sigma^2)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BlobKernel {
    sigma: f64,
    inv_two_sigma2: f64,
    at_zero: f64,
    /// `2 FAR sigma^2`: from this `r^2` on `q` is the point vortex's.
    far_r2: f64,
}

impl BlobKernel {
    /// The kernel of blobs of core `sigma > 0`.
    pub fn new(sigma: f64) -> Self {
        BlobKernel {
            sigma,
            inv_two_sigma2: 0.5 / (sigma * sigma),
            at_zero: 1.0 / (4.0 * PI * sigma * sigma),
            far_r2: FAR / (0.5 / (sigma * sigma)),
        }
    }

    /// The core `sigma`.
    pub fn sigma(&self) -> f64 {
        self.sigma
    }

    /// `q(r^2)`, in branch-free arithmetic, on `f64` or on the four lanes of
    /// an [`F64x4`] (the bits of four scalar calls).
    #[inline(always)]
    pub fn factor<T: Real>(&self, r2: T) -> T {
        let c = T::splat;
        let x = r2 * c(self.inv_two_sigma2);
        // (1 - e^-x) / x = 1 - x/2 + x^2/6 - x^3/24 + ..., and q = that / (4 pi sigma^2)
        let series =
            c(self.at_zero) * (c(1.0) - x * (c(0.5) - x * (c(1.0 / 6.0) - x * c(1.0 / 24.0))));
        let full = (c(1.0) - exp_nonpositive(-x)) / (c(2.0 * PI) * r2.max(c(f64::MIN_POSITIVE)));
        T::select_less(x, c(SERIES_BELOW), series, full)
    }

    /// [`BlobKernel::factor`] of four lanes, skipping the exponential when every
    /// lane lies in the point-vortex range (`r^2 >= 2 FAR sigma^2`, where
    /// `1 - exp(-x)` rounds to 1): the same bits.
    #[inline(always)]
    pub fn factor_lanes(&self, r2: F64x4) -> F64x4 {
        if F64x4::any_less(r2, F64x4::splat(self.far_r2)) {
            self.factor(r2)
        } else {
            F64x4::splat(1.0) / (F64x4::splat(2.0 * PI) * r2)
        }
    }

    /// `Gamma K_sigma(d)` with `d = x - x_j`.
    #[inline(always)]
    pub fn velocity(&self, d: [f64; 2], gamma: f64) -> [f64; 2] {
        let q = gamma * self.factor(d[0] * d[0] + d[1] * d[1]);
        [-q * d[1], q * d[0]]
    }
}

/// The pair law of a 2D vortex solver, `u = Gamma q(|d|^2) (-d_y, d_x)` for
/// `d = x - x_j`, which far out is the point vortex's `q = 1 / (2 pi |d|^2)`.
pub trait VortexLaw: Copy + Debug + Send + Sync {
    /// `q(r^2)`, lane by lane.
    fn factor<T: Real>(&self, r2: T) -> T;

    /// `q(r^2)` of four lanes, the bits of [`VortexLaw::factor`] (a law may
    /// skip work the lanes do not need).
    #[inline(always)]
    fn factor_lanes(&self, r2: F64x4) -> F64x4 {
        self.factor(r2)
    }

    /// The distance from which `q` is the point vortex's to within
    /// `tolerance / 10` relative: boxes nearer than that meet pair by pair.
    fn reach(&self, tolerance: f64) -> f64;
}

impl VortexLaw for BlobKernel {
    #[inline(always)]
    fn factor<T: Real>(&self, r2: T) -> T {
        BlobKernel::factor(self, r2)
    }

    #[inline(always)]
    fn factor_lanes(&self, r2: F64x4) -> F64x4 {
        BlobKernel::factor_lanes(self, r2)
    }

    /// `q` differs from the point vortex's by `exp(-r^2 / (2 sigma^2))`
    /// relative: `sigma sqrt(2 ln(10 / tolerance))`.
    fn reach(&self, tolerance: f64) -> f64 {
        self.sigma() * (2.0 * (10.0 / tolerance).ln()).sqrt()
    }
}

/// Point vortices: `q = 1 / (2 pi r^2)`, and nothing from a source at the
/// target's position (the Cauchy kernel `sum Gamma_j / (2 pi i (z - z_j))`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct PointVortex;

impl VortexLaw for PointVortex {
    #[inline(always)]
    fn factor<T: Real>(&self, r2: T) -> T {
        let c = T::splat;
        let q = c(0.5 / PI) / r2.max(c(f64::MIN_POSITIVE));
        T::select_less(c(0.0), r2, q, c(0.0))
    }

    fn reach(&self, _tolerance: f64) -> f64 {
        0.0
    }
}

/// `u(x)` at every `target` induced by all `sources` (positions and
/// circulations) under the pair law `law` (`u = Gamma q(|d|^2) (-d_y, d_x)`),
/// one target at a time in source order: the brute-force reference that the
/// fast solvers are tested against. A source at the target's exact position
/// contributes nothing (`K_sigma(0) = 0`).
pub fn velocity_at(
    law: &impl VortexLaw,
    targets: &[[f64; 2]],
    positions: &[[f64; 2]],
    gamma: &[f64],
    threads: &Threads,
) -> Vec<[f64; 2]> {
    threads.install(|| {
        targets
            .par_iter()
            .map(|x| {
                let mut u = [0.0; 2];
                for (p, &g) in positions.iter().zip(gamma) {
                    let d = [x[0] - p[0], x[1] - p[1]];
                    let q = g * law.factor(d[0] * d[0] + d[1] * d[1]);
                    u[0] += -q * d[1];
                    u[1] += q * d[0];
                }
                u
            })
            .collect()
    })
}

/// Panics unless there is one circulation and one velocity per position: the
/// contract of every vortex solver's `compute`.
pub(crate) fn assert_lengths(positions: &[[f64; 2]], gamma: &[f64], velocity: &[[f64; 2]]) {
    assert!(
        positions.len() == gamma.len() && gamma.len() == velocity.len(),
        "{} positions, {} circulations, {} velocities",
        positions.len(),
        gamma.len(),
        velocity.len()
    );
}

/// Particles per block: two blocks' positions, circulations and sums (6 arrays of
/// 8 bytes) take 24 KiB, within the level-1 cache.
const BLOCK: usize = 256;

/// Partners computed together: one AVX2 vector.
const LANES: usize = 4;

/// All pairs of particles, each once: blocks of `BLOCK` particles meet in the
/// rounds of a round-robin tournament, the block pairs of a round in parallel.
/// On several ranks that each hold every particle
/// ([`DirectBiotSavart::compute_shared`]) the block pairs are dealt out among
/// the ranks and each particle's partial sums added in rank order (module
/// `dealt`).
#[derive(Clone, Debug)]
pub struct DirectBiotSavart {
    kernel: BlobKernel,
    n: usize,
    rounds: Vec<Vec<(usize, usize)>>,
    x: [Vec<f64>; 2],
    gamma: Vec<f64>,
    sums: [Vec<f64>; 2],
    /// Several ranks: every particle's sums over the ranks.
    partials: Partials,
}

impl DirectBiotSavart {
    /// The solver for `n` particles with blobs of `kernel`.
    pub fn new(kernel: BlobKernel, n: usize) -> Self {
        let mut solver = DirectBiotSavart {
            kernel,
            n: 0,
            rounds: Vec::new(),
            x: [Vec::new(), Vec::new()],
            gamma: Vec::new(),
            sums: [Vec::new(), Vec::new()],
            partials: Partials::default(),
        };
        solver.resize(n);
        solver
    }

    /// Makes the solver fit `n` particles (after a remeshing changed their count).
    fn resize(&mut self, n: usize) {
        if n != self.n {
            self.n = n;
            self.rounds = tournament(n.div_ceil(BLOCK));
            for v in self.x.iter_mut().chain(self.sums.iter_mut()) {
                v.resize(n, 0.0);
            }
            self.gamma.resize(n, 0.0);
        }
    }

    /// Pair evaluations per velocity evaluation, `N (N - 1) / 2`.
    pub fn pairs(&self) -> u64 {
        let n = self.n as u64;
        n * n.saturating_sub(1) / 2
    }

    /// `velocity_i = sum_{j != i} Gamma_j K_sigma(x_i - x_j)` for every particle.
    pub fn compute(
        &mut self,
        positions: &[[f64; 2]],
        gamma: &[f64],
        velocity: &mut [[f64; 2]],
        threads: &Threads,
    ) {
        self.compute_shared(positions, gamma, velocity, threads, &Alone);
    }

    /// [`compute`](Self::compute) on the ranks of `exchange`, every rank
    /// calling it with every particle: the tournament's block pairs, counted
    /// round after round, go to the ranks in turn (pair `k` to rank `k mod
    /// P`); each rank runs its pairs into partial sums, and every particle's
    /// velocity is the sum of the ranks' partials in rank order. Every rank
    /// gets the same velocities, within rounding of one process's (the bits
    /// of one process on one rank).
    pub fn compute_shared(
        &mut self,
        positions: &[[f64; 2]],
        gamma: &[f64],
        velocity: &mut [[f64; 2]],
        threads: &Threads,
        exchange: &dyn Exchange,
    ) {
        assert_lengths(positions, gamma, velocity);
        self.resize(positions.len());
        for (i, p) in positions.iter().enumerate() {
            self.x[0][i] = p[0];
            self.x[1][i] = p[1];
        }
        self.gamma.copy_from_slice(gamma);
        for s in &mut self.sums {
            s.fill(0.0);
        }
        let n = self.n;
        let ranks = exchange.ranks();
        let block = |b: usize| b * BLOCK..((b + 1) * BLOCK).min(n);
        let (kernel, x, g) = (&self.kernel, &self.x, &self.gamma[..]);
        let [su, sv] = &mut self.sums;
        let shared = [DisjointSlice::new(su), DisjointSlice::new(sv)];
        dealt::play(&self.rounds, (exchange.rank(), ranks), threads, |a, b| {
            let (ra, rb) = (block(a), block(b));
            if a == b {
                // SAFETY: each block occurs once in round 0.
                let (u, v) = unsafe { (shared[0].range(ra.clone()), shared[1].range(ra.clone())) };
                for (local, i) in ra.clone().enumerate() {
                    let (u_own, u_later) = u.split_at_mut(local + 1);
                    let (v_own, v_later) = v.split_at_mut(local + 1);
                    let partners = i + 1..ra.end;
                    let got = row::<_, true>(
                        kernel,
                        [x[0][i], x[1][i]],
                        g[i],
                        [&x[0][partners.clone()], &x[1][partners.clone()]],
                        &g[partners],
                        [u_later, v_later],
                    );
                    u_own[local] += got[0];
                    v_own[local] += got[1];
                }
            } else {
                // SAFETY: the block pairs of one round are disjoint.
                let (ua, va, ub, vb) = unsafe {
                    (
                        shared[0].range(ra.clone()),
                        shared[1].range(ra.clone()),
                        shared[0].range(rb.clone()),
                        shared[1].range(rb.clone()),
                    )
                };
                for (local, i) in ra.clone().enumerate() {
                    let got = row::<_, true>(
                        kernel,
                        [x[0][i], x[1][i]],
                        g[i],
                        [&x[0][rb.clone()], &x[1][rb.clone()]],
                        &g[rb.clone()],
                        [&mut *ub, &mut *vb],
                    );
                    ua[local] += got[0];
                    va[local] += got[1];
                }
            }
        });
        if ranks > 1 {
            self.partials.add(&self.sums, exchange);
        }
        for (i, out) in velocity.iter_mut().enumerate() {
            *out = if ranks > 1 {
                self.partials.total(i)
            } else {
                [self.sums[0][i], self.sums[1][i]]
            };
        }
    }
}

/// Beyond this `x = r^2 / (2 sigma^2)`, `exp(-x) < 5e-18` and `1 - exp(-x)` rounds
/// to exactly 1: the far-field factor `1 / (2 pi r^2)` has the same bits as
/// [`BlobKernel::factor`], without the exponential.
const FAR: f64 = 40.0;

/// The particle at `xi` with circulation `gi` against the `partners` (their
/// positions per axis and circulations) under the pair law `law`: returns
/// `sum_j Gamma_j K(x_i - x_j)` and, when `SYMMETRIC`, adds
/// `Gamma_i K(x_j - x_i)` to each partner's `partner_sums` (same length;
/// untouched otherwise). Four partners per AVX2 register (with the blob law, a
/// group of four with no pair inside `FAR` skips the exponential); lane sums
/// are added in lane order at the end, the last partial group after them.
/// The direct sums and the FMM's leaf pairs share it.
#[inline(always)]
pub(crate) fn row<K: VortexLaw, const SYMMETRIC: bool>(
    law: &K,
    xi: [f64; 2],
    gi: f64,
    partners: [&[f64]; 2],
    gamma: &[f64],
    partner_sums: [&mut [f64]; 2],
) -> [f64; 2] {
    // a copy: the partners' stores cannot alias its fields, so that their
    // splats stay out of the loop
    let law = *law;
    let [px, py] = partners;
    let [pu, pv] = partner_sums;
    let (sx, sy, sg) = (F64x4::splat(xi[0]), F64x4::splat(xi[1]), F64x4::splat(gi));
    let mut acc = [F64x4::splat(0.0); 2];
    let len = gamma.len();
    let whole = len / LANES * LANES;
    for j in (0..whole).step_by(LANES) {
        let dx = sx - F64x4::load(&px[j..]);
        let dy = sy - F64x4::load(&py[j..]);
        let gj = F64x4::load(&gamma[j..]);
        let r2 = dx * dx + dy * dy;
        let q = law.factor_lanes(r2);
        acc[0] = acc[0] - q * gj * dy;
        acc[1] = acc[1] + q * gj * dx;
        if SYMMETRIC {
            let (qgy, qgx) = (q * sg * dy, q * sg * dx);
            (F64x4::load(&pu[j..]) + qgy).store(&mut pu[j..]);
            (F64x4::load(&pv[j..]) - qgx).store(&mut pv[j..]);
        }
    }
    let mut sums = [acc[0].sum(), acc[1].sum()];
    for j in whole..len {
        let (dx, dy) = (xi[0] - px[j], xi[1] - py[j]);
        let q = law.factor(dx * dx + dy * dy);
        sums[0] -= q * gamma[j] * dy;
        sums[1] += q * gamma[j] * dx;
        if SYMMETRIC {
            pu[j] += q * gi * dy;
            pv[j] -= q * gi * dx;
        }
    }
    sums
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::random::Rng;

    #[test]
    fn the_factor_is_smooth_through_the_series_switch() {
        let k = BlobKernel::new(0.3);
        let exact = |r2: f64| -(-r2 / (2.0 * 0.09f64)).exp_m1() / (2.0 * PI * r2);
        for r2 in [1e-30, 1e-8, 1.7e-4, 1.8e-4, 1e-3, 0.05, 1.0, 40.0] {
            let got = k.factor(r2);
            assert!((got - exact(r2)).abs() <= 1e-13 * exact(r2), "{r2}: {got}");
        }
        assert_eq!(k.factor(0.0), 1.0 / (4.0 * PI * 0.09));
    }

    #[test]
    fn four_lanes_of_the_factor_give_the_bits_of_four_scalar_calls() {
        let k = BlobKernel::new(0.3);
        let mut rng = Rng::new(4);
        // around the series switch (x = 1e-3), the far field (x = 40), zero,
        // the smallest and huge distances
        let switch = SERIES_BELOW / k.inv_two_sigma2;
        let special = [
            0.0,
            5e-324,
            switch,
            switch.next_down(),
            switch.next_up(),
            FAR / k.inv_two_sigma2,
            1e300,
            f64::INFINITY,
        ];
        for round in 0..20_000 {
            let r2: [f64; 4] = std::array::from_fn(|l| match (round + l) % 3 {
                0 => special[(round / 3 + l) % special.len()],
                1 => rng.uniform() * 2.0 * switch,
                _ => rng.uniform() * 100.0 * 0.09,
            });
            let lanes = k.factor(F64x4::load(&r2)).to_array();
            assert_eq!(
                lanes.map(f64::to_bits),
                r2.map(|r2| k.factor(r2).to_bits()),
                "{r2:?}"
            );
        }
    }

    #[test]
    fn direct_matches_the_reference_and_its_thread_count() {
        let mut rng = Rng::new(5);
        let n = 700;
        let x: Vec<[f64; 2]> = (0..n).map(|_| [rng.normal(), rng.normal()]).collect();
        let g: Vec<f64> = (0..n).map(|_| rng.uniform() - 0.3).collect();
        let kernel = BlobKernel::new(0.05);
        let reference = velocity_at(&kernel, &x, &x, &g, &Threads::single());
        let mut solver = DirectBiotSavart::new(kernel, n);
        let mut one = vec![[0.0; 2]; n];
        solver.compute(&x, &g, &mut one, &Threads::single());
        let mut two = vec![[0.0; 2]; n];
        solver.compute(&x, &g, &mut two, &Threads::new(2).unwrap());
        assert_eq!(one, two);
        let scale = reference
            .iter()
            .map(|u| u[0].hypot(u[1]))
            .fold(0.0, f64::max);
        for (a, b) in one.iter().zip(&reference) {
            assert!((a[0] - b[0]).abs() + (a[1] - b[1]).abs() < 1e-12 * scale);
        }
    }

    /// The block pairs dealt out among thread-ranks (3 blocks on 2 and 4
    /// ranks; 2 particles on 3 ranks: ranks without pairs, and a part with no
    /// particle): every rank gets the same velocities, those of one process
    /// within rounding.
    #[test]
    fn ranks_sharing_the_pairs_match_one_process() {
        for (n, ranks) in [(3 * BLOCK - 11, 2), (3 * BLOCK - 11, 4), (2, 3)] {
            let mut rng = Rng::new(9);
            let x: Vec<[f64; 2]> = (0..n).map(|_| [rng.normal(), rng.normal()]).collect();
            let g: Vec<f64> = (0..n).map(|_| rng.uniform() - 0.3).collect();
            let kernel = BlobKernel::new(0.05);
            let mut want = vec![[0.0; 2]; n];
            DirectBiotSavart::new(kernel, n).compute(&x, &g, &mut want, &Threads::single());
            let scale = want.iter().map(|u| u[0].hypot(u[1])).fold(0.0, f64::max);
            let got = crate::longrange::mesh::slab::testkit::Hub::run(ranks, |exchange| {
                let mut v = vec![[0.0; 2]; n];
                DirectBiotSavart::new(kernel, n).compute_shared(
                    &x,
                    &g,
                    &mut v,
                    &Threads::single(),
                    exchange,
                );
                v
            });
            for (r, v) in got.iter().enumerate() {
                assert_eq!(v, &got[0], "rank {r} of {ranks}");
                for (a, b) in v.iter().zip(&want) {
                    assert!((a[0] - b[0]).abs() + (a[1] - b[1]).abs() <= 1e-14 * scale);
                }
            }
        }
    }
}
