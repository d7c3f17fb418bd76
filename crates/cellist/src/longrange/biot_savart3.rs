//! The regularised Biot-Savart law of 3D vortex blobs: particles at `x_q` with
//! vector strengths `alpha_q` and Gaussian cores of variance `sigma^2` per axis
//! induce
//!
//! ```text
//! u(x) = sum_q alpha_q x r g(|r|),   r = x - x_q,
//! g(r) = Q(r / sigma) / (4 pi r^3),  Q(rho) = erf(rho / sqrt 2) - sqrt(2 / pi) rho exp(-rho^2 / 2),
//! ```
//!
//! the velocity `u = curl psi` of the vorticity `omega_sigma = sum_q alpha_q
//! zeta_sigma(x - x_q)`, `Laplacian psi = -omega_sigma`,
//! `zeta_sigma(r) = (2 pi sigma^2)^(-3/2) exp(-r^2 / (2 sigma^2))`, and its gradient
//!
//! ```text
//! d u_a / d x_e = sum_q eps_abe alpha_qb g + (alpha_q x r)_a r_e g_2,   g_2 = g'(r) / r,
//! ```
//!
//! i.e. `grad u = [S]_x + T` with `S = sum_q alpha_q g` (`[S]_x v = S x v`) and
//! `T_ae = sum_q (alpha_q x r)_a r_e g_2`. The pair at `r = 0` (a particle on
//! itself) adds nothing to `u` and `[alpha]_x g(0)` to the gradient,
//! `g(0) = 1 / (3 (2 pi)^(3/2) sigma^3)`.
//!
//! [`BlobKernel3`] gives `g` and its radial derivatives, the pair formulas every
//! 3D vortex solver shares; [`DirectBiotSavart3`] sums all pairs, each once (`u`
//! is odd in `r`, the gradient's pair terms even), in parallel without atomics
//! and with every particle's sum in an order fixed by the data.

use crate::longrange::dealt::{self, Partials};
use crate::longrange::{Alone, Exchange};
use crate::models::pse::exp_nonpositive;
use crate::simd::{F64x4, Real};
use crate::threads::{tournament, DisjointSlice, Threads};
use rayon::prelude::*;
use std::f64::consts::PI;

/// Below this `x = r^2 / (2 sigma^2)` the kernel comes from the series of `I_5`
/// (see [`BlobKernel3::radial`]).
const SERIES_BELOW: f64 = 1.0;

/// From this `x = r^2 / (2 sigma^2)` on, the kernel is the point vortex's:
/// `1 - Q < 1e-18` and the derivatives' tails `Gamma(k + 1/2, x) / Gamma(k + 1/2)`
/// are below `7e-18` (`k = 2`, which `g_2` needs), `2e-15` (`k = 4`) and
/// `2e-14` (`k = 5`, the tree's third order).
const FAR: f64 = 45.0;

/// The radial functions [`BlobKernel3::radial`] gives, `g_1` to `g_5`.
pub(crate) const RADIAL: usize = 5;

/// Terms of the series of `e^x I_5(x) = sum_n (2x)^n / (11 * 13 * ... * (2n + 11))`:
/// the last is below `1e-20` of the first for `x <= 1`.
const SERIES_TERMS: usize = 18;

/// The series' coefficients `2^n / (11 * 13 * ... * (2n + 11))`.
const SERIES: [f64; SERIES_TERMS] = {
    let mut c = [0.0; SERIES_TERMS];
    c[0] = 1.0 / 11.0;
    let mut n = 1;
    while n < SERIES_TERMS {
        c[n] = c[n - 1] * 2.0 / (2 * n + 11) as f64;
        n += 1;
    }
    c
};

/// `R(z) = exp(z^2) erfc(z) = t P(s)` on `1 <= z <= 6.75`, `t = 2 / (2 + z)`,
/// `s = (t - ERFC_MID) * ERFC_SCALE` in `[-1, 1]`: `P` is the degree-16
/// Chebyshev fit (mpmath, 40 digits) of `R / t`, relative error below `5e-16`
/// evaluated in `f64`. Coefficients from the constant up.
const ERFC_FIT: [f64; 17] = [
    0.47630862986918354,
    0.13797794080804107,
    0.02559181266867705,
    0.0018783210479327219,
    -0.0003250273289708313,
    -6.606132069280908e-05,
    8.059556023849295e-06,
    2.1036662975749964e-06,
    -3.76128508256008e-07,
    -5.928618091693069e-08,
    2.120305610111959e-08,
    3.860065401228543e-10,
    -1.0617371834367836e-09,
    1.3062947118952828e-10,
    3.4540600683370004e-11,
    -1.0606970942076055e-11,
    1.893349738660298e-14,
];
/// The centre of `t` over the fit's range.
const ERFC_MID: f64 = 0.447_619_047_619_047_64;
/// One over the half-width of `t` over the fit's range.
const ERFC_SCALE: f64 = 4.565_217_391_304_348;

/// The square root, lane by lane: an exact IEEE operation, so `f64` and the
/// lanes of [`F64x4`] give the same bits.
pub trait Sqrt: Real {
    /// `sqrt(self)`.
    fn sqrt(self) -> Self;
}

impl Sqrt for f64 {
    #[inline(always)]
    fn sqrt(self) -> Self {
        f64::sqrt(self)
    }
}

impl Sqrt for F64x4 {
    #[inline(always)]
    fn sqrt(self) -> Self {
        F64x4::sqrt(self)
    }
}

/// The radial functions of the 3D blob law: `g(r) = Q(r / sigma) / (4 pi r^3)`
/// and `g_{k+1} = (1/r) d g_k / dr` (`g_1 = g`), which the velocity (`g`), its
/// gradient (`g_2`) and the tree's expansions (`g_3` to `g_5`) need.
///
/// With `x = r^2 / (2 sigma^2)`, `zeta_0 = (2 pi sigma^2)^(-3/2)` and
/// `I_k(x) = int_0^1 s^(2k) exp(-x s^2) ds`:
/// `g = zeta_0 I_1`, `g_2 = -zeta_0 I_2 / sigma^2`, `g_3 = zeta_0 I_3 / sigma^4`,
/// `g_4 = -zeta_0 I_4 / sigma^6`, `g_5 = zeta_0 I_5 / sigma^8`, and
/// `I_{k+1} = ((2k + 1) I_k - e^-x) / (2x)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BlobKernel3 {
    sigma: f64,
    inv_two_sigma2: f64,
    /// `[zeta_0, -zeta_0 / sigma^2, zeta_0 / sigma^4, -zeta_0 / sigma^6, zeta_0 / sigma^8]`.
    scale: [f64; RADIAL],
}

impl BlobKernel3 {
    /// The kernel of blobs of core `sigma > 0`.
    pub fn new(sigma: f64) -> Self {
        let s2 = sigma * sigma;
        let zeta0 = (2.0 * PI * s2).powf(-1.5);
        BlobKernel3 {
            sigma,
            inv_two_sigma2: 0.5 / s2,
            scale: [
                zeta0,
                -zeta0 / s2,
                zeta0 / (s2 * s2),
                -zeta0 / (s2 * s2 * s2),
                zeta0 / (s2 * s2 * s2 * s2),
            ],
        }
    }

    /// The core `sigma`.
    pub fn sigma(&self) -> f64 {
        self.sigma
    }

    /// `[g, g_2, g_3, g_4, g_5]` at `|r|^2 = r2`, in branch-free arithmetic on `f64`
    /// or on the four lanes of an [`F64x4`] (the bits of four scalar calls):
    ///
    /// - `x < 1`: `I_5 = e^-x sum_n (2x)^n / (11 * 13 * ... * (2n + 11))` (positive
    ///   terms), then down, `I_k = (2x I_{k+1} + e^-x) / (2k + 1)` (stable);
    /// - `1 <= x < 45`: `I_1 = sqrt(pi) Q / (4 x^(3/2))`,
    ///   `Q = 1 - e^-x (R(z) + 2 z / sqrt(pi))`, `z = sqrt x`, `R = e^(z^2) erfc z`
    ///   from a Chebyshev fit, then up by the recurrence;
    /// - `x >= 45`: the point vortex, [`BlobKernel3::far`].
    #[inline(always)]
    pub fn radial<T: Sqrt>(&self, r2: T) -> [T; RADIAL] {
        let c = T::splat;
        let x = r2 * c(self.inv_two_sigma2);
        let e = exp_nonpositive(-x);
        let (n, m, f) = (near(x, e), middle(x, e), self.far(r2));
        std::array::from_fn(|k| {
            let blob = T::select_less(x, c(SERIES_BELOW), n[k], m[k]) * c(self.scale[k]);
            T::select_less(x, c(FAR), blob, f[k])
        })
    }

    /// `[g, g_2, g_3, g_4, g_5]` of the point vortex, what [`BlobKernel3::radial`]
    /// gives for `r2 >= 90 sigma^2`: `g = 1 / (4 pi r^3)`, `g_2 = -3 g / r^2`,
    /// `g_3 = -5 g_2 / r^2`, `g_4 = -7 g_3 / r^2`, `g_5 = -9 g_4 / r^2`.
    #[inline(always)]
    pub fn far<T: Sqrt>(&self, r2: T) -> [T; RADIAL] {
        let c = T::splat;
        let inv_r = c(1.0) / r2.sqrt();
        let inv = inv_r * inv_r;
        let g = c(0.25 / PI) * inv * inv_r;
        let g2 = c(-3.0) * g * inv;
        let g3 = c(-5.0) * g2 * inv;
        let g4 = c(-7.0) * g3 * inv;
        let g5 = c(-9.0) * g4 * inv;
        [g, g2, g3, g4, g5]
    }

    /// [`BlobKernel3::radial`] with the bits of every lane, computing only the
    /// ranges that some lane is in.
    #[inline(always)]
    pub(crate) fn radial_or_far(&self, r2: F64x4) -> [F64x4; RADIAL] {
        let c = F64x4::splat;
        let x = r2 * c(self.inv_two_sigma2);
        let blob_lanes = F64x4::mask_less(x, c(FAR));
        if blob_lanes == 0 {
            return self.far(r2);
        }
        let e = exp_nonpositive(-x);
        let blob = match F64x4::mask_less(x, c(SERIES_BELOW)) {
            0 => middle(x, e),
            0b1111 => near(x, e),
            _ => {
                let (n, m) = (near(x, e), middle(x, e));
                std::array::from_fn(|k| F64x4::select_less(x, c(SERIES_BELOW), n[k], m[k]))
            }
        };
        let blob: [F64x4; RADIAL] = std::array::from_fn(|k| blob[k] * c(self.scale[k]));
        if blob_lanes == 0b1111 {
            return blob;
        }
        let far = self.far(r2);
        std::array::from_fn(|k| F64x4::select_less(x, c(FAR), blob[k], far[k]))
    }
}

impl BlobKernel3 {
    /// `[g - g_point, g_2 - g_2,point]` at `|r|^2 = r2` (lanes): the blob law's
    /// difference from the point law ([`BlobKernel3::far`]), zero from `r2 =
    /// 90 sigma^2` on (where [`BlobKernel3::radial`] is the point law), and
    /// the blob law itself below `r2 = close2` (the point law taken as zero
    /// there, where it would be far larger than the blob law). One square
    /// root and two divisions per lane: `1 / r` serves the point law and the
    /// `erfc` range's `z = r / (sqrt 2 sigma)`.
    #[inline(always)]
    pub(crate) fn rest_from_point(&self, r2: F64x4, close2: f64) -> [F64x4; 2] {
        let c = F64x4::splat;
        let zero = c(0.0);
        let x = r2 * c(self.inv_two_sigma2);
        if F64x4::mask_less(x, c(FAR)) == 0 {
            return [zero; 2];
        }
        let inv_r = c(1.0) / r2.sqrt();
        let e = exp_nonpositive(-x);
        let root = self.inv_two_sigma2.sqrt();
        let (z, inv_z) = (r2 * inv_r * c(root), inv_r * c(1.0 / root));
        let blob = match F64x4::mask_less(x, c(SERIES_BELOW)) {
            0 => middle_at(e, z, inv_z),
            0b1111 => near(x, e),
            _ => {
                let (n, m) = (near(x, e), middle_at(e, z, inv_z));
                std::array::from_fn(|k| F64x4::select_less(x, c(SERIES_BELOW), n[k], m[k]))
            }
        };
        let inv = inv_r * inv_r;
        let point = c(0.25 / PI) * inv * inv_r;
        let apart = |v: F64x4| F64x4::select_less(r2, c(close2), zero, v);
        let rest = [
            blob[0] * c(self.scale[0]) - apart(point),
            blob[1] * c(self.scale[1]) - apart(c(-3.0) * point * inv),
        ];
        rest.map(|v| F64x4::select_less(x, c(FAR), v, zero))
    }
}

/// `sum_k c[k] x^k` as `E(x^2) + x O(x^2)`, the even and odd powers' two
/// Horner chains of fused multiply-adds side by side (half the dependent steps
/// of one chain: the kernel's polynomials bound its latency).
#[inline(always)]
fn polynomial<T: Real, const N: usize>(c: &[f64; N], x: T) -> T {
    let y = x * x;
    // (a loop of a constant count, which the compiler unrolls: over a slice
    // it stayed a loop, each step waiting on the last)
    let chain = |start: usize| {
        let mut p = T::splat(0.0);
        for k in (start..N).step_by(2).rev() {
            p = p.mul_add(y, T::splat(c[k]));
        }
        p
    };
    chain(1).mul_add(x, chain(0))
}

/// `[I_1, ..., I_5]` at `x` (with `e = exp(-x)`) from the series of `I_5`
/// and the downward recurrence (see [`BlobKernel3::radial`]).
#[inline(always)]
fn near<T: Sqrt>(x: T, e: T) -> [T; RADIAL] {
    let c = T::splat;
    let two_x = x + x;
    let i5 = e * polynomial(&SERIES, x);
    let i4 = (two_x * i5 + e) * c(1.0 / 9.0);
    let i3 = (two_x * i4 + e) * c(1.0 / 7.0);
    let i2 = (two_x * i3 + e) * c(1.0 / 5.0);
    let i1 = (two_x * i2 + e) * c(1.0 / 3.0);
    [i1, i2, i3, i4, i5]
}

/// `[I_1, ..., I_5]` at `x` (with `e = exp(-x)`) from `erfc` and the
/// upward recurrence (see [`BlobKernel3::radial`]).
#[inline(always)]
fn middle<T: Sqrt>(x: T, e: T) -> [T; RADIAL] {
    let z = x.sqrt();
    middle_at(e, z, T::splat(1.0) / z)
}

/// [`middle`] with `z = sqrt x` and `1 / z` given.
#[inline(always)]
fn middle_at<T: Sqrt>(e: T, z: T, inv_z: T) -> [T; RADIAL] {
    let c = T::splat;
    let half_inv_x = c(0.5) * inv_z * inv_z;
    let t = c(2.0) / (c(2.0) + z);
    let s = (t - c(ERFC_MID)) * c(ERFC_SCALE);
    let p = polynomial(&ERFC_FIT, s);
    let q = c(1.0) - e * (t * p + c(2.0 / PI.sqrt()) * z);
    let i1 = c(PI.sqrt() / 4.0) * q * inv_z * inv_z * inv_z;
    let i2 = (c(3.0) * i1 - e) * half_inv_x;
    let i3 = (c(5.0) * i2 - e) * half_inv_x;
    let i4 = (c(7.0) * i3 - e) * half_inv_x;
    let i5 = (c(9.0) * i4 - e) * half_inv_x;
    [i1, i2, i3, i4, i5]
}

/// Running sums per target: `u` (0..3), `S = sum alpha_q g` (3..6) and
/// `T_ae = sum (alpha_q x r)_a r_e g_2` (6..15, row-major).
pub(crate) const SUMS: usize = 15;

/// `b x c`.
#[inline(always)]
fn cross<T: Real>(b: [T; 3], c: [T; 3]) -> [T; 3] {
    [
        b[1] * c[2] - b[2] * c[1],
        b[2] * c[0] - b[0] * c[2],
        b[0] * c[1] - b[1] * c[0],
    ]
}

/// One source's terms of [`SUMS`] at a target, `r = x_target - x_source`:
/// `(alpha x r) g`, `alpha g`, `(alpha x r)_a r_e g_2`. The source's terms from
/// the target are the same with `alpha` the target's and `u` negated.
#[inline(always)]
pub(crate) fn terms<T: Real>(alpha: [T; 3], r: [T; 3], g: T, g2: T) -> [T; SUMS] {
    let w = cross(alpha, r);
    let v = [w[0] * g2, w[1] * g2, w[2] * g2];
    [
        w[0] * g,
        w[1] * g,
        w[2] * g,
        alpha[0] * g,
        alpha[1] * g,
        alpha[2] * g,
        v[0] * r[0],
        v[0] * r[1],
        v[0] * r[2],
        v[1] * r[0],
        v[1] * r[1],
        v[1] * r[2],
        v[2] * r[0],
        v[2] * r[1],
        v[2] * r[2],
    ]
}

/// The velocity `u` and gradient `[S]_x + T` of a target's [`SUMS`].
#[inline]
pub(crate) fn assemble(sums: &[f64; SUMS]) -> ([f64; 3], [f64; 9]) {
    let (s, t) = (&sums[3..6], &sums[6..]);
    let gradient = [
        t[0],
        t[1] - s[2],
        t[2] + s[1],
        t[3] + s[2],
        t[4],
        t[5] - s[0],
        t[6] - s[1],
        t[7] + s[0],
        t[8],
    ];
    ([sums[0], sums[1], sums[2]], gradient)
}

/// `u(x)` and `grad u(x)` (`gradient[3 a + e] = d u_a / d x_e`) at every
/// `target` induced by all sources (positions and strengths), one target at a
/// time in source order: the brute-force reference that the fast solvers are
/// tested against. A source at the target's exact position adds nothing to `u`
/// and `[alpha]_x g(0)` to the gradient.
pub fn velocity_and_gradient_at(
    kernel: &BlobKernel3,
    targets: &[[f64; 3]],
    positions: &[[f64; 3]],
    alpha: &[[f64; 3]],
    threads: &Threads,
) -> (Vec<[f64; 3]>, Vec<[f64; 9]>) {
    assert_eq!(positions.len(), alpha.len(), "one strength per source");
    threads.install(|| {
        targets
            .par_iter()
            .map(|x| {
                let mut sums = [0.0; SUMS];
                for (p, a) in positions.iter().zip(alpha) {
                    let r = [x[0] - p[0], x[1] - p[1], x[2] - p[2]];
                    let [g, g2, ..] = kernel.radial(r[0] * r[0] + r[1] * r[1] + r[2] * r[2]);
                    for (s, t) in sums.iter_mut().zip(terms(*a, r, g, g2)) {
                        *s += t;
                    }
                }
                assemble(&sums)
            })
            .unzip()
    })
}

/// Panics unless there is one strength, one velocity and one gradient per
/// position: the contract of every 3D vortex solver's `compute`.
pub(crate) fn assert_lengths(
    positions: &[[f64; 3]],
    alpha: &[[f64; 3]],
    velocity: &[[f64; 3]],
    gradient: &[[f64; 9]],
) {
    assert!(
        positions.len() == alpha.len()
            && alpha.len() == velocity.len()
            && velocity.len() == gradient.len(),
        "{} positions, {} strengths, {} velocities, {} gradients",
        positions.len(),
        alpha.len(),
        velocity.len(),
        gradient.len()
    );
}

/// Particles per block: two blocks' positions, strengths and sums (21 arrays
/// of 8 bytes) take 42 KiB, within the level-2 cache.
const BLOCK: usize = 128;

/// Partners computed together: one AVX2 vector.
const LANES: usize = 4;

/// All pairs of particles, each once: blocks of `BLOCK` particles meet in the
/// rounds of a round-robin tournament, the block pairs of a round in parallel,
/// each pair adding its terms to both particles' running sums of `u`,
/// `S` and `T`. On several ranks that each hold every particle
/// ([`DirectBiotSavart3::compute_shared`]) the block pairs are dealt out
/// among the ranks and each particle's partial sums added in rank order
/// (module `dealt`).
#[derive(Clone, Debug)]
pub struct DirectBiotSavart3 {
    kernel: BlobKernel3,
    n: usize,
    rounds: Vec<Vec<(usize, usize)>>,
    x: [Vec<f64>; 3],
    alpha: [Vec<f64>; 3],
    sums: [Vec<f64>; SUMS],
    /// Several ranks: every particle's sums over the ranks.
    partials: Partials,
}

impl DirectBiotSavart3 {
    /// The solver for `n` particles with blobs of `kernel`.
    pub fn new(kernel: BlobKernel3, n: usize) -> Self {
        let mut solver = DirectBiotSavart3 {
            kernel,
            n: 0,
            rounds: Vec::new(),
            x: Default::default(),
            alpha: Default::default(),
            sums: std::array::from_fn(|_| Vec::new()),
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
            for v in self
                .x
                .iter_mut()
                .chain(&mut self.alpha)
                .chain(&mut self.sums)
            {
                v.resize(n, 0.0);
            }
        }
    }

    /// Pair evaluations per evaluation, `N (N - 1) / 2`.
    pub fn pairs(&self) -> u64 {
        let n = self.n as u64;
        n * n.saturating_sub(1) / 2
    }

    /// `velocity[i] = u(x_i)` and `gradient[i][3 a + e] = d u_a / d x_e` at
    /// `x_i`, summed over all particles (the self term adds `[alpha_i]_x g(0)`
    /// to the gradient).
    pub fn compute(
        &mut self,
        positions: &[[f64; 3]],
        alpha: &[[f64; 3]],
        velocity: &mut [[f64; 3]],
        gradient: &mut [[f64; 9]],
        threads: &Threads,
    ) {
        self.compute_shared(positions, alpha, velocity, gradient, threads, &Alone);
    }

    /// [`compute`](Self::compute) on the ranks of `exchange`, every rank
    /// calling it with every particle: the tournament's block pairs, counted
    /// round after round, go to the ranks in turn (pair `k` to rank `k mod
    /// P`); each rank runs its pairs into partial sums, and every particle's
    /// total is the sum of the ranks' partials in rank order. Every rank gets
    /// the same velocities and gradients, within rounding of one process's
    /// (the bits of one process on one rank).
    pub fn compute_shared(
        &mut self,
        positions: &[[f64; 3]],
        alpha: &[[f64; 3]],
        velocity: &mut [[f64; 3]],
        gradient: &mut [[f64; 9]],
        threads: &Threads,
        exchange: &dyn Exchange,
    ) {
        assert_lengths(positions, alpha, velocity, gradient);
        self.resize(positions.len());
        for (i, (p, a)) in positions.iter().zip(alpha).enumerate() {
            for c in 0..3 {
                self.x[c][i] = p[c];
                self.alpha[c][i] = a[c];
            }
        }
        for s in &mut self.sums {
            s.fill(0.0);
        }
        let n = self.n;
        let ranks = exchange.ranks();
        let block = |b: usize| b * BLOCK..((b + 1) * BLOCK).min(n);
        let (kernel, x, a) = (&self.kernel, &self.x, &self.alpha);
        let shared = self.sums.each_mut().map(|s| DisjointSlice::new(s));
        let shared = &shared;
        // SAFETY (callers): no other live reference to `range` of the sums.
        let sums_of = |range: std::ops::Range<usize>| unsafe {
            std::array::from_fn::<_, SUMS, _>(|k| shared[k].range(range.clone()))
        };
        let at = |i: usize| ([x[0][i], x[1][i], x[2][i]], [a[0][i], a[1][i], a[2][i]]);
        let part = (exchange.rank(), ranks);
        dealt::play(&self.rounds, part, threads, |p, q| {
            let (rp, rq) = (block(p), block(q));
            // each block occurs once in a round: its sums are this task's
            let mut own = sums_of(rp.clone());
            if p == q {
                for (local, i) in rp.clone().enumerate() {
                    let mut split = own.each_mut().map(|s| s.split_at_mut(local + 1));
                    let mut later = split.each_mut().map(|(_, l)| &mut **l);
                    let partners = i + 1..rp.end;
                    let (xi, ai) = at(i);
                    let got = row::<true>(
                        kernel,
                        xi,
                        ai,
                        columns(x, partners.clone()),
                        columns(a, partners),
                        &mut later,
                    );
                    for ((s, _), g) in split.iter_mut().zip(got) {
                        s[local] += g;
                    }
                }
            } else {
                let mut other = sums_of(rq.clone());
                for (local, i) in rp.clone().enumerate() {
                    let (xi, ai) = at(i);
                    let got = row::<true>(
                        kernel,
                        xi,
                        ai,
                        columns(x, rq.clone()),
                        columns(a, rq.clone()),
                        &mut other,
                    );
                    for (s, g) in own.iter_mut().zip(got) {
                        s[local] += g;
                    }
                }
            }
        });
        if ranks > 1 {
            self.partials.add(&self.sums, exchange);
        }
        let g0 = self.kernel.radial(0.0)[0];
        for (i, (u, grad)) in velocity.iter_mut().zip(gradient.iter_mut()).enumerate() {
            let mut sums: [f64; SUMS] = if ranks > 1 {
                self.partials.total(i)
            } else {
                std::array::from_fn(|k| self.sums[k][i])
            };
            for c in 0..3 {
                sums[3 + c] += self.alpha[c][i] * g0;
            }
            (*u, *grad) = assemble(&sums);
        }
    }
}

/// The entries `r` of three columns.
fn columns(v: &[Vec<f64>; 3], r: std::ops::Range<usize>) -> [&[f64]; 3] {
    v.each_ref().map(|c| &c[r.clone()])
}

/// The particle at `xi` with strength `ai` against the `partners` (positions
/// and strengths per axis): returns the partners' [`SUMS`] at `xi` and, when
/// `SYMMETRIC`, adds the particle's terms to each partner's `partner_sums`
/// (same length; untouched otherwise). Four partners per AVX2 register; a group
/// of four all in the point-vortex range skips the blob's special functions
/// (same bits); lane sums are added in lane order at the end, the last partial
/// group after them.
#[inline(always)]
fn row<const SYMMETRIC: bool>(
    kernel: &BlobKernel3,
    xi: [f64; 3],
    ai: [f64; 3],
    px: [&[f64]; 3],
    pa: [&[f64]; 3],
    partner_sums: &mut [&mut [f64]; SUMS],
) -> [f64; SUMS] {
    let sx = xi.map(F64x4::splat);
    let sa = ai.map(F64x4::splat);
    let mut acc = [F64x4::splat(0.0); SUMS];
    let len = px[0].len();
    let whole = len / LANES * LANES;
    for j in (0..whole).step_by(LANES) {
        let r: [F64x4; 3] = std::array::from_fn(|c| sx[c] - F64x4::load(&px[c][j..]));
        let aj: [F64x4; 3] = std::array::from_fn(|c| F64x4::load(&pa[c][j..]));
        let r2 = r[0] * r[0] + r[1] * r[1] + r[2] * r[2];
        let [g, g2, ..] = kernel.radial_or_far(r2);
        for (s, t) in acc.iter_mut().zip(terms(aj, r, g, g2)) {
            *s = *s + t;
        }
        if SYMMETRIC {
            for (k, (p, t)) in partner_sums.iter_mut().zip(terms(sa, r, g, g2)).enumerate() {
                let old = F64x4::load(&p[j..]);
                let new = if k < 3 { old - t } else { old + t };
                new.store(&mut p[j..]);
            }
        }
    }
    let mut sums = acc.map(F64x4::sum);
    for j in whole..len {
        let r: [f64; 3] = std::array::from_fn(|c| xi[c] - px[c][j]);
        let aj: [f64; 3] = std::array::from_fn(|c| pa[c][j]);
        let [g, g2, ..] = kernel.radial(r[0] * r[0] + r[1] * r[1] + r[2] * r[2]);
        for (s, t) in sums.iter_mut().zip(terms(aj, r, g, g2)) {
            *s += t;
        }
        if SYMMETRIC {
            for (k, (p, t)) in partner_sums.iter_mut().zip(terms(ai, r, g, g2)).enumerate() {
                if k < 3 {
                    p[j] -= t;
                } else {
                    p[j] += t;
                }
            }
        }
    }
    sums
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::random::Rng;
    use proptest::prelude::*;

    /// `erf(z)`, `z >= 0`, from its series of positive terms,
    /// `erf z = 2 / sqrt(pi) exp(-z^2) sum_n 2^n z^(2n+1) / (1 * 3 * ... * (2n + 1))`,
    /// and 1 beyond `z = 6` (`erfc 6 = 2e-17`).
    fn erf(z: f64) -> f64 {
        if z > 6.0 {
            return 1.0;
        }
        let (mut term, mut sum, mut n) = (z, z, 0.0);
        while term > 1e-18 * sum {
            n += 1.0;
            term *= 2.0 * z * z / (2.0 * n + 1.0);
            sum += term;
        }
        2.0 / PI.sqrt() * (-z * z).exp() * sum
    }

    /// `[g, g'(r) / r]` by the textbook formulas: `g = Q / (4 pi r^3)` with `Q`
    /// from [`erf`] and `Q'(rho) = sqrt(2/pi) rho^2 exp(-rho^2/2)`; below
    /// `rho = 0.3` (where `Q` cancels) the Taylor series in `x = rho^2 / 2`,
    /// `g = zeta_0 sum_m (-x)^m / (m! (2m + 3))`,
    /// `g'/r = -zeta_0 / sigma^2 sum_m (-x)^m / (m! (2m + 5))`.
    fn textbook(sigma: f64, r: f64) -> [f64; 2] {
        let rho = r / sigma;
        if rho < 0.3 {
            let x = rho * rho / 2.0;
            let zeta0 = (2.0 * PI * sigma * sigma).powf(-1.5);
            let series = |k: f64| {
                let (mut sum, mut power) = (0.0, 1.0);
                for m in 0..10 {
                    sum += power / (2.0 * m as f64 + 2.0 * k + 1.0);
                    power *= -x / (m as f64 + 1.0);
                }
                sum
            };
            return [zeta0 * series(1.0), -zeta0 / (sigma * sigma) * series(2.0)];
        }
        let root = (2.0 / PI).sqrt();
        let q = erf(rho / 2f64.sqrt()) - root * rho * (-rho * rho / 2.0).exp();
        let dq = root * rho * rho * (-rho * rho / 2.0).exp() / sigma;
        let g = q / (4.0 * PI * r.powi(3));
        let dg = dq / (4.0 * PI * r.powi(3)) - 3.0 * q / (4.0 * PI * r.powi(4));
        [g, dg / r]
    }

    /// `u` and `grad u` at each particle summed over all particles (itself
    /// included) with [`textbook`] and the Levi-Civita symbol written out.
    fn textbook_sums(
        sigma: f64,
        x: &[[f64; 3]],
        alpha: &[[f64; 3]],
    ) -> (Vec<[f64; 3]>, Vec<[f64; 9]>) {
        let eps = |a: usize, b: usize, c: usize| match (a, b, c) {
            (0, 1, 2) | (1, 2, 0) | (2, 0, 1) => 1.0,
            (0, 2, 1) | (2, 1, 0) | (1, 0, 2) => -1.0,
            _ => 0.0,
        };
        x.iter()
            .map(|xi| {
                let (mut u, mut grad) = ([0.0; 3], [0.0; 9]);
                for (xq, aq) in x.iter().zip(alpha) {
                    let r: [f64; 3] = std::array::from_fn(|c| xi[c] - xq[c]);
                    let [g, g2] = textbook(sigma, r.iter().map(|v| v * v).sum::<f64>().sqrt());
                    for a in 0..3 {
                        let mut w = 0.0;
                        for b in 0..3 {
                            for c in 0..3 {
                                w += eps(a, b, c) * aq[b] * r[c];
                            }
                        }
                        u[a] += w * g;
                        for e in 0..3 {
                            let own: f64 = (0..3).map(|b| eps(a, b, e) * aq[b]).sum();
                            grad[3 * a + e] += own * g + w * r[e] * g2;
                        }
                    }
                }
                (u, grad)
            })
            .unzip()
    }

    /// A Gaussian cloud of `n` particles with random strengths, two of them
    /// on one point.
    fn cloud(seed: u64, n: usize, width: f64) -> (Vec<[f64; 3]>, Vec<[f64; 3]>) {
        let mut rng = Rng::new(seed);
        let mut x: Vec<[f64; 3]> = (0..n)
            .map(|_| std::array::from_fn(|_| width * rng.normal()))
            .collect();
        if n > 3 {
            x[3] = x[1];
        }
        let alpha = (0..n)
            .map(|_| std::array::from_fn(|_| rng.uniform() - 0.5))
            .collect();
        (x, alpha)
    }

    /// `max |got - want|` over all components against `max |want|`.
    fn relative<const K: usize>(got: &[[f64; K]], want: &[[f64; K]]) -> f64 {
        let flat = |v: &[[f64; K]]| v.iter().flatten().copied().collect::<Vec<f64>>();
        let (got, want) = (flat(got), flat(want));
        let scale = want.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let error = got
            .iter()
            .zip(&want)
            .fold(0.0f64, |m, (g, w)| m.max((g - w).abs()));
        error / scale
    }

    #[test]
    fn the_kernel_matches_the_textbook_formulas() {
        let sigma = 0.7;
        let k = BlobKernel3::new(sigma);
        let switch = |x: f64| (x * 2.0 * sigma * sigma).sqrt();
        let mut r: Vec<f64> = vec![1e-9, 1e-4, 0.01, 0.2, 0.5, 3.0, 9.0, 30.0, 1e3];
        for edge in [switch(SERIES_BELOW), switch(FAR)] {
            r.extend([edge * (1.0 - 1e-12), edge, edge * (1.0 + 1e-12)]);
        }
        r.extend((1..200).map(|i| i as f64 * 0.05));
        for r in r {
            let got = k.radial(r * r);
            let want = textbook(sigma, r);
            for c in 0..2 {
                assert!(
                    (got[c] - want[c]).abs() <= 1e-12 * want[c].abs(),
                    "r {r}, g_{}: {} against {}",
                    c + 1,
                    got[c],
                    want[c]
                );
            }
        }
        let g0 = 1.0 / (3.0 * (2.0 * PI).powf(1.5) * sigma.powi(3));
        assert!((k.radial(0.0)[0] - g0).abs() <= 1e-15 * g0);
    }

    /// `g_3` to `g_5` (the tree's) against central differences of `g_2` to
    /// `g_4`, `g_{k+1} = (d g_k / d r) / r`, across the three ranges.
    #[test]
    fn higher_derivatives_are_the_differences_of_lower_ones() {
        let k = BlobKernel3::new(1.0);
        for r in [0.3, 0.9, 1.3, 1.5, 2.0, 4.0, 9.0, 9.6, 12.0] {
            let h = 1e-5 * r;
            let (up, down) = (k.radial((r + h) * (r + h)), k.radial((r - h) * (r - h)));
            let here = k.radial(r * r);
            for c in 1..4 {
                let fd = (up[c] - down[c]) / (2.0 * h) / r;
                assert!(
                    (fd - here[c + 1]).abs() <= 1e-7 * here[c + 1].abs(),
                    "r {r}, g_{}: {fd} against {}",
                    c + 2,
                    here[c + 1]
                );
            }
        }
    }

    #[test]
    fn four_lanes_of_the_kernel_give_the_bits_of_four_scalar_calls() {
        let k = BlobKernel3::new(0.3);
        let mut rng = Rng::new(4);
        let at = |x: f64| x / k.inv_two_sigma2;
        let special = [
            0.0,
            5e-324,
            at(SERIES_BELOW),
            at(SERIES_BELOW).next_down(),
            at(FAR),
            at(FAR).next_up(),
            1e300,
            f64::INFINITY,
        ];
        // lanes from mixed ranges, then all four from one range (the shortcuts
        // of `radial_or_far`)
        for round in 0..6000 {
            let pick = |l: usize| if round < 3000 { round + l } else { round / 4 };
            let r2: [f64; 4] = std::array::from_fn(|l| match pick(l) % 3 {
                0 => special[(round / 3 + l) % special.len()],
                1 => at(2.0 * rng.uniform()),
                _ => at(60.0 * rng.uniform()),
            });
            let bits = |v: [F64x4; RADIAL]| v.map(|v| v.to_array().map(f64::to_bits));
            let lanes = bits(k.radial(F64x4::load(&r2)));
            assert_eq!(lanes, bits(k.radial_or_far(F64x4::load(&r2))), "{r2:?}");
            for (l, &r2) in r2.iter().enumerate() {
                let scalar = k.radial(r2).map(f64::to_bits);
                assert_eq!(lanes.map(|v| v[l]), scalar, "{r2}");
            }
        }
    }

    #[test]
    fn direct_matches_the_textbook_sums_and_its_thread_count() {
        let n = 300;
        let (x, alpha) = cloud(7, n, 1.0);
        let sigma = 0.4;
        let (u_want, g_want) = textbook_sums(sigma, &x, &alpha);
        let mut solver = DirectBiotSavart3::new(BlobKernel3::new(sigma), n);
        let (mut u, mut g) = (vec![[0.0; 3]; n], vec![[0.0; 9]; n]);
        solver.compute(&x, &alpha, &mut u, &mut g, &Threads::single());
        assert!(relative(&u, &u_want) < 1e-12, "{}", relative(&u, &u_want));
        assert!(relative(&g, &g_want) < 1e-12, "{}", relative(&g, &g_want));
        let (mut u2, mut g2) = (vec![[0.0; 3]; n], vec![[0.0; 9]; n]);
        solver.compute(&x, &alpha, &mut u2, &mut g2, &Threads::new(2).unwrap());
        assert_eq!(u.concat(), u2.concat());
        assert_eq!(g.concat(), g2.concat());
    }

    /// The block pairs dealt out among 2 to 5 thread-ranks (4 blocks, 10
    /// pairs; one block on 3 ranks: ranks without pairs; 3 particles on 4
    /// ranks: a rank whose part holds no particle): every rank gets
    /// the same fields, those of one process within rounding, and two
    /// evaluations give the same bits.
    #[test]
    fn ranks_sharing_the_pairs_match_one_process() {
        for (n, ranks) in [
            (4 * BLOCK - 37, 2),
            (4 * BLOCK - 37, 3),
            (4 * BLOCK - 37, 5),
            (100, 3),
            (3, 4),
        ] {
            let (x, alpha) = cloud(11, n, 1.0);
            let mut solver = DirectBiotSavart3::new(BlobKernel3::new(0.3), n);
            let (mut u, mut g) = (vec![[0.0; 3]; n], vec![[0.0; 9]; n]);
            solver.compute(&x, &alpha, &mut u, &mut g, &Threads::single());
            let got = crate::longrange::mesh::slab::testkit::Hub::run(ranks, |exchange| {
                let mut solver = DirectBiotSavart3::new(BlobKernel3::new(0.3), n);
                let mut fields = Vec::new();
                for _ in 0..2 {
                    let (mut u, mut g) = (vec![[0.0; 3]; n], vec![[0.0; 9]; n]);
                    solver.compute_shared(&x, &alpha, &mut u, &mut g, &Threads::single(), exchange);
                    fields.push((u, g));
                }
                assert!(fields[0] == fields[1], "two evaluations");
                fields.pop().unwrap()
            });
            for (r, (ur, gr)) in got.iter().enumerate() {
                assert!((ur, gr) == (&got[0].0, &got[0].1), "rank {r} of {ranks}");
                assert!(
                    relative(ur, &u) < 1e-14,
                    "{ranks} ranks: {}",
                    relative(ur, &u)
                );
                assert!(
                    relative(gr, &g) < 1e-14,
                    "{ranks} ranks: {}",
                    relative(gr, &g)
                );
            }
        }
    }

    /// The gradient at particles (self term included) against central
    /// differences of the velocity at points around them.
    #[test]
    fn the_gradient_is_the_difference_of_velocities() {
        let (x, alpha) = cloud(9, 60, 0.5);
        let k = BlobKernel3::new(0.3);
        let one = Threads::single();
        let targets = &x[..8];
        let (_, grad) = velocity_and_gradient_at(&k, targets, &x, &alpha, &one);
        let h = 1e-5;
        for e in 0..3 {
            let moved = |sign: f64| -> Vec<[f64; 3]> {
                let shifted: Vec<[f64; 3]> = targets
                    .iter()
                    .map(|p| {
                        let mut q = *p;
                        q[e] += sign * h;
                        q
                    })
                    .collect();
                velocity_and_gradient_at(&k, &shifted, &x, &alpha, &one).0
            };
            let (up, down) = (moved(1.0), moved(-1.0));
            for t in 0..targets.len() {
                for a in 0..3 {
                    let fd = (up[t][a] - down[t][a]) / (2.0 * h);
                    let want = grad[t][3 * a + e];
                    let scale = grad[t].iter().fold(0.0f64, |m, v| m.max(v.abs()));
                    assert!(
                        (fd - want).abs() <= 1e-6 * scale,
                        "target {t}, d u_{a} / d x_{e}: {fd} against {want}"
                    );
                }
            }
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(24))]

        /// The SIMD pair sums against the brute-force reference.
        #[test]
        fn direct_matches_the_reference(
            seed in any::<u64>(),
            n in 1usize..400,
            log_sigma in -4.0f64..1.0,
        ) {
            let (x, alpha) = cloud(seed, n, 1.0);
            let k = BlobKernel3::new(log_sigma.exp());
            let (u_want, g_want) = velocity_and_gradient_at(&k, &x, &x, &alpha, &Threads::single());
            let mut solver = DirectBiotSavart3::new(k, n);
            let (mut u, mut g) = (vec![[0.0; 3]; n], vec![[0.0; 9]; n]);
            solver.compute(&x, &alpha, &mut u, &mut g, &Threads::new(2).unwrap());
            prop_assert!(relative(&u, &u_want) < 1e-12 || n == 1);
            prop_assert!(relative(&g, &g_want) < 1e-12);
        }
    }
}
