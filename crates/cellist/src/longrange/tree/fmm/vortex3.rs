//! The fast multipole method for the 3D vortex velocity and its gradient.
//!
//! The blob law is split into the point law and a short-range rest,
//!
//! ```text
//! u(x) = sum_q alpha_q x r g(|r|) = (1 / 4 pi) curl Phi + sum_{|r| < r_c} alpha_q x r (g - g_point),
//! Phi_c(x) = sum_q alpha_qc / |x - x_q|,   g_point(r) = 1 / (4 pi r^3),
//! ```
//!
//! (the rest beyond `r_c` dropped): the three Laplace potentials `Phi_c`
//! carry solid-harmonic expansions on the octree ([`super::solid`], M2L by
//! rotation as gravity's), and `u_a = eps_abc d_b Phi_c / 4 pi`,
//! `d_e u_a = eps_abc d_e d_b Phi_c / 4 pi` come from the locals of the
//! derivatives `d_b Phi_c` ([`derivative_locals`]); the near field sums the
//! point law pair by pair, and the rest runs over the pairs within `r_c` on
//! a cell list ([`super::blob_rest`]).

use super::super::build::{Node, Sizes};
use super::super::share::{Share, Whole};
use super::blob_rest::{close_squared, BlobRest};
use super::engine::{shift_to_middle, Cube, Engine, Expansions, Pairs};
use super::rotation::{m2l_by_direction, FarPairs, M2lLanes};
use super::solid::{self, at, harmonics, lanes, signed, LANES};
use super::{ErrorFit, FmmAccuracy};
use crate::longrange::biot_savart3::{assert_lengths, BlobKernel3};
use crate::simd::{axes, F64x8, Register};
use crate::threads::Threads;
use rustfft::num_complex::Complex64;
use std::f64::consts::PI;
use std::ops::Range;

/// Boxes interact through their expansions when `2 max(s_T, s_S) <= THETA d`,
/// as gravity's.
const THETA: f64 = 0.95;

/// Most particles in a leaf.
const LEAF: usize = 256;

/// The most particles a uniform cloud's leaves hold (the root grown for it).
const FILL: usize = 200;

/// Most particles in a target group (groups run in parallel; each leaf
/// pair is computed once for both sides, across groups by the earlier).
const GROUP: usize = 8192;

/// Numbers per particle's sum: `u` (3), then `d u_a / d x_e` at `3 + 3 a + e`.
const SUM: usize = 12;

impl ErrorFit {
    /// The 3D vortex FMM's fit of the RMS relative errors of the velocity
    /// and of its gradient (the larger, by 3-20 times) against the direct
    /// blob sum, measured with the rest exact, on 3000 and 20,000 random
    /// blobs and on a vortex ring (`sigma = 1.5 h`): the gradient's error
    /// falls about 0.56-fold per order up to `p = 16` (at `p = 6`: 3.4e-3,
    /// 3.0e-3, 1.4e-3; at 10: 2.1e-4, 1.9e-4, 3.8e-5; at 16: 4.9e-6, 4.8e-6,
    /// 2.2e-6), then more slowly (the ring's from 6.4e-7 at 20 to 4.6e-11 at
    /// 50: 0.73 per order; the clouds' 0.65). `0.16 0.56^p`, then 0.73 per
    /// order from `p = 16`, bounds every measured point from `p = 8` on (by
    /// 2 or more up to `p = 16`, by 6 or more beyond; at `p = 6` by 1.4 only,
    /// so a tolerance picks at least 8).
    pub const VORTEX_3D: ErrorFit = ErrorFit {
        decay: 0.56,
        at_zero: 0.16,
        least: 8,
        knee: Some((16, 0.73)),
    };
}

/// The fast multipole method for the velocity and its gradient of 3D vortex
/// blobs (the law of [`crate::longrange::biot_savart3`]) at a requested
/// accuracy: the point law's far field by expansions, its near field pair by
/// pair, and the blob law's difference from it within a cutoff `r_c` chosen
/// from the tolerance (`blob_rest`). Each particle's sum runs in an order
/// fixed by the tree and the cell list, so 1 and N threads give the same
/// bits.
#[derive(Debug)]
pub struct VortexFmm3 {
    accuracy: FmmAccuracy,
    curl: CurlLaplace,
    engine: Engine<CurlLaplace>,
    rest: BlobRest,
    shifted: Vec<[f64; 3]>,
}

impl VortexFmm3 {
    /// A solver for blobs of `kernel` at `accuracy` (checked).
    pub fn new(kernel: BlobKernel3, accuracy: FmmAccuracy) -> Result<Self, String> {
        accuracy.check()?;
        let tolerance = accuracy.tolerance(ErrorFit::VORTEX_3D);
        Ok(VortexFmm3 {
            accuracy,
            curl: CurlLaplace {
                order: accuracy.order(ErrorFit::VORTEX_3D),
                close2: close_squared(&kernel),
                x: Default::default(),
                alpha: Default::default(),
            },
            engine: Engine::default(),
            rest: BlobRest::new(kernel, tolerance),
            shifted: Vec::new(),
        })
    }

    /// The accuracy asked for.
    pub fn accuracy(&self) -> FmmAccuracy {
        self.accuracy
    }

    /// The expansions' order `p`.
    pub fn order(&self) -> usize {
        self.curl.order
    }

    /// The cutoff `r_c` of the blob law's difference from the point law.
    pub fn cutoff(&self) -> f64 {
        self.rest.cutoff()
    }

    /// `(M2L, particle pair)` interactions of the last evaluation (the pairs
    /// of the point law's near field and of the blob rest; of this process's
    /// part, for [`compute_shared`](Self::compute_shared)).
    pub fn interactions(&self) -> (u64, u64) {
        let (m2l, pairs) = self.engine.interactions;
        (m2l, pairs + 2 * self.rest.pairs())
    }

    /// `u(x_i)` and `grad u(x_i)` (`gradient[i][3 a + e] = d u_a / d x_e`) of
    /// the blobs `(positions, alpha)`. The particles are taken relative to
    /// the middle of their bounding box (`engine::shift_to_middle`).
    pub fn compute(
        &mut self,
        positions: &[[f64; 3]],
        alpha: &[[f64; 3]],
        velocity: &mut [[f64; 3]],
        gradient: &mut [[f64; 9]],
        threads: &Threads,
    ) {
        self.compute_shared(positions, alpha, velocity, gradient, threads, &mut Whole);
    }

    /// [`compute`](Self::compute) divided among processes that each hold
    /// every particle (see [`Share`]): each makes the upward pass, sums only
    /// the target groups of its part and a run of the blob rest's cell
    /// layers, and receives the others' sums, so that every particle gets the
    /// bits of the undivided evaluation.
    pub fn compute_shared(
        &mut self,
        positions: &[[f64; 3]],
        alpha: &[[f64; 3]],
        velocity: &mut [[f64; 3]],
        gradient: &mut [[f64; 9]],
        threads: &Threads,
        share: &mut dyn Share,
    ) {
        assert_lengths(positions, alpha, velocity, gradient);
        shift_to_middle(positions, &mut self.shifted);
        self.engine.build(&self.shifted, threads);
        let c = &mut self.curl;
        for v in c.x.iter_mut().chain(c.alpha.iter_mut()) {
            v.clear();
        }
        for &i in &self.engine.tree.order {
            let i = i as usize;
            for a in 0..3 {
                c.x[a].push(self.shifted[i][a]);
                c.alpha[a].push(alpha[i][a]);
            }
        }
        // room for the lanes past the last particle
        for v in c.x.iter_mut().chain(c.alpha.iter_mut()) {
            v.resize(v.len() + LANES, 0.0);
        }
        self.engine.evaluate(&self.curl, threads, share);
        for (&i, s) in self.engine.tree.order.iter().zip(&self.engine.sorted) {
            let i = i as usize;
            velocity[i] = [s[0], s[1], s[2]];
            gradient[i] = std::array::from_fn(|k| s[3 + k]);
        }
        self.rest
            .add(&self.shifted, alpha, velocity, gradient, threads, share);
    }
}

/// The expansions of the three potentials `Phi_c = sum alpha_c / r` and the
/// point law's pairs, on the particles in tree order (each array followed by
/// [`LANES`] zeros).
#[derive(Debug)]
struct CurlLaplace {
    order: usize,
    /// Pairs closer than this (squared) are the blob rest's alone
    /// ([`close_squared`]).
    close2: f64,
    x: [Vec<f64>; 3],
    alpha: [Vec<f64>; 3],
}

/// A thread's buffers.
#[derive(Debug, Default)]
struct Scratch {
    harmonics: Vec<Complex64>,
    lanes: (Vec<F64x8>, Vec<F64x8>),
    /// The nine locals of `d_b Phi_c` of a leaf (`3 c + b`).
    derived: Vec<Complex64>,
    turned: M2lLanes,
    far: FarPairs,
    /// A source leaf's reactions, [`SUM`] arrays.
    reactions: Vec<Vec<f64>>,
}

impl Expansions for CurlLaplace {
    /// `u` and its gradient, [`SUM`] numbers.
    type Sum = [f64; SUM];
    const WIDTH: usize = SUM;
    type Scratch = Scratch;
    const THETA: f64 = THETA;
    fn sizes(_: usize) -> Sizes {
        Sizes {
            leaf: LEAF,
            group: GROUP,
        }
    }
    const FILL: Option<usize> = Some(FILL);

    /// Measured at order 13 on the 10^5-particle ring (perf of one
    /// evaluation: M2L and the point law's pairs): 1640 pair terms,
    /// `0.6 (p + 1)^3`.
    fn m2l_cost(&self) -> f64 {
        0.6 * ((self.order + 1) as f64).powi(3)
    }

    fn numbers(sums: &mut [Self::Sum]) -> &mut [f64] {
        sums.as_flattened_mut()
    }

    /// Three expansions, one per component of `alpha`.
    fn terms(&self) -> usize {
        3 * solid::terms(self.order)
    }

    /// The point law is the expansions' law at any distance.
    fn reach(&self) -> f64 {
        0.0
    }

    fn cube(&self, node: &Node) -> Cube {
        Cube::around(node)
    }

    /// `M_c += alpha_c conj(R(w))` per particle, the harmonics shared by the
    /// three components.
    fn p2m(
        &self,
        particles: Range<usize>,
        cube: Cube,
        multipole: &mut [Complex64],
        scratch: &mut Scratch,
    ) {
        let terms = solid::terms(self.order);
        let h = harmonics(&mut scratch.harmonics, terms);
        let inv = 1.0 / cube.radius;
        for s in particles {
            let w = std::array::from_fn(|a| (self.x[a][s] - cube.centre[a]) * inv);
            solid::regular(w, self.order, h);
            for (c, m) in multipole.chunks_exact_mut(terms).enumerate() {
                let q = self.alpha[c][s];
                for (m, r) in m.iter_mut().zip(h.iter()) {
                    *m += q * r.conj();
                }
            }
        }
    }

    fn m2m(
        &self,
        child: &[Complex64],
        from: Cube,
        parent: &mut [Complex64],
        to: Cube,
        scratch: &mut Scratch,
    ) {
        let (from, to) = ((from.centre, from.radius), (to.centre, to.radius));
        let h = &mut scratch.harmonics;
        solid::shift_each(solid::m2m, self.order, child, from, parent, to, h);
    }

    fn m2l(
        &self,
        multipoles: &[Complex64],
        cubes: &[Cube],
        group: usize,
        starts: &[usize],
        sources: &[u32],
        locals: &mut [Complex64],
        scratch: &mut Scratch,
    ) {
        let far = (group, starts, sources);
        let turned = (&mut scratch.far, &mut scratch.turned);
        m2l_by_direction(self.order, 3, multipoles, cubes, far, locals, turned);
    }

    fn l2l(
        &self,
        parent: &[Complex64],
        from: Cube,
        child: &mut [Complex64],
        to: Cube,
        scratch: &mut Scratch,
    ) {
        let (from, to) = ((from.centre, from.radius), (to.centre, to.radius));
        let h = &mut scratch.harmonics;
        solid::shift_each(solid::l2l, self.order, parent, from, child, to, h);
    }

    /// The locals of `d_b Phi_c` ([`derivative_locals`]), evaluated with
    /// their gradients at [`LANES`] particles at a time (`d_e d_b Phi_c` and
    /// `d_b Phi_c`), then curled.
    fn l2p(
        &self,
        local: &[Complex64],
        cube: Cube,
        particles: Range<usize>,
        out: &mut [[f64; SUM]],
        scratch: &mut Scratch,
    ) {
        let (terms, below) = (solid::terms(self.order), solid::terms(self.order - 1));
        let inv = 1.0 / cube.radius;
        let derived = &mut scratch.derived;
        derived.clear();
        derived.resize(9 * below, Complex64::new(0.0, 0.0));
        for (l, d) in local
            .chunks_exact(terms)
            .zip(derived.chunks_exact_mut(3 * below))
        {
            derivative_locals(self.order, l, inv, d);
        }
        let (re, im) = lanes(&mut scratch.lanes, below);
        let quarter = F64x8::splat(0.25 / PI);
        let mut values = [[0.0; LANES]; SUM];
        for first in particles.clone().step_by(LANES) {
            let w = std::array::from_fn(|a| {
                (F64x8::load(&self.x[a][first..]) - F64x8::splat(cube.centre[a]))
                    * F64x8::splat(inv)
            });
            solid::regular_lanes(w, self.order - 1, re, im);
            // h[3 c + b] = [d_x, d_y, d_z, 1] applied to d_b Phi_c
            let h: [[F64x8; 4]; 9] = std::array::from_fn(|k| {
                let d = &derived[k * below..(k + 1) * below];
                solid::l2p_lanes(self.order - 1, d, inv, (&*re, &*im))
            });
            // eps_abc d_b Phi_c at h[3 c + b]: (b, c) = (1, 2) - (2, 1), (2, 0) - (0, 2),
            // (0, 1) - (1, 0)
            let curl = |e: usize| [h[7][e] - h[5][e], h[2][e] - h[6][e], h[3][e] - h[1][e]];
            let u = curl(3);
            let columns = [curl(0), curl(1), curl(2)];
            for a in 0..3 {
                (u[a] * quarter).store(&mut values[a]);
                for (e, column) in columns.iter().enumerate() {
                    (column[a] * quarter).store(&mut values[3 + 3 * a + e]);
                }
            }
            let count = LANES.min(particles.end - first);
            let offset = first - particles.start;
            for (lane, o) in out[offset..offset + count].iter_mut().enumerate() {
                for (o, v) in o.iter_mut().zip(&values) {
                    *o += v[lane];
                }
            }
        }
    }

    fn pairs(
        &self,
        how: Pairs,
        targets: Range<usize>,
        sources: Range<usize>,
        mine: &mut [[f64; SUM]],
        theirs: &mut [[f64; SUM]],
        scratch: &mut Scratch,
    ) -> u64 {
        self.leaf_pairs(how, targets, sources, mine, theirs, scratch)
    }
}

/// The locals (order `p - 1`) of `d_x Phi`, `d_y Phi` and `d_z Phi`, one
/// after the other in `out`, from the local `L` (order `p`, scale `s`, `inv
/// = 1 / s`) of a real `Phi = sum L_k^l conj(R_k^l(w))`, `w = (x - t) / s`.
/// From `d_z R_n^m = R_{n-1}^m` and `(d_x + i d_y) R_n^m = R_{n-1}^{m+1}`
/// ([`solid::l2p`]): `d_x Phi - i d_y Phi = sum L_{j+1}^{i-1} conj(R_j^i) / s`,
/// whose conjugate has the coefficients `-L_{j+1}^{i+1} / s` (by `L_n^{-m} =
/// (-1)^m conj(L_n^m)`, the same for `R`), so that
///
/// `X_j^i = (L_{j+1}^{i-1} - L_{j+1}^{i+1}) / 2s`,
/// `Y_j^i = i (L_{j+1}^{i-1} + L_{j+1}^{i+1}) / 2s`,
/// `Z_j^i = L_{j+1}^i / s`.
fn derivative_locals(p: usize, local: &[Complex64], inv: f64, out: &mut [Complex64]) {
    let below = solid::terms(p - 1);
    let (x, rest) = out.split_at_mut(below);
    let (y, z) = rest.split_at_mut(below);
    let half = 0.5 * inv;
    for j in 0..p {
        for i in 0..=j {
            let lower = signed(local, j + 1, i as isize - 1);
            let upper = local[at(j + 1, i + 1)];
            let k = at(j, i);
            x[k] = (lower - upper) * half;
            let sum = (lower + upper) * half;
            y[k] = Complex64::new(-sum.im, sum.re);
            z[k] = local[at(j + 1, i)] * inv;
        }
    }
}

impl CurlLaplace {
    /// [`Expansions::pairs`] by the point law, one target at a time against
    /// the source leaf's particles in lanes (a leaf with itself: against
    /// its later particles), each pair once, its reaction summed per source
    /// and added after the targets.
    fn leaf_pairs(
        &self,
        how: Pairs,
        targets: Range<usize>,
        sources: Range<usize>,
        mine: &mut [[f64; SUM]],
        theirs: &mut [[f64; SUM]],
        scratch: &mut Scratch,
    ) -> u64 {
        let len = sources.len();
        let reactions = &mut scratch.reactions;
        reactions.resize(SUM, Vec::new());
        for r in reactions.iter_mut() {
            r.clear();
            r.resize(len + LANES, 0.0);
        }
        let first = targets.start;
        for i in targets.clone() {
            let partners = match how {
                Pairs::Within => i + 1..sources.end,
                Pairs::Both => sources.clone(),
            };
            let from = partners.start - sources.start;
            let got = self.row(i, partners, &mut reactions[..], from);
            for (o, g) in mine[i - first].iter_mut().zip(got) {
                *o += g;
            }
        }
        let at_sources = if how == Pairs::Within { mine } else { theirs };
        for (k, sum) in at_sources[..len].iter_mut().enumerate() {
            for (o, r) in sum.iter_mut().zip(reactions.iter()) {
                *o += r[k];
            }
        }
        how.terms(targets.len(), len)
    }

    /// Target `i`'s point-law sums over `partners` (their reactions added
    /// to `reactions` from slot `from` on):
    ///
    /// `u += (alpha_j x r) g`, `d_e u_a += eps_abe alpha_jb g + (alpha_j x r)_a r_e g_2`,
    ///
    /// `r = x_i - x_j`, `g = 1 / (4 pi r^3)`, `g_2 = -3 g / r^2`; the
    /// partner receives the same with `alpha_i` and `u` negated. Lanes past
    /// the partners, and partners closer than `sqrt(close2)`, add nothing.
    #[inline(always)]
    fn row(
        &self,
        i: usize,
        partners: Range<usize>,
        reactions: &mut [Vec<f64>],
        from: usize,
    ) -> [f64; SUM] {
        let zero = F64x8::splat(0.0);
        let one = F64x8::splat(1.0);
        let xi = axes(|a| F64x8::splat(self.x[a][i]));
        let ai = axes(|a| F64x8::splat(self.alpha[a][i]));
        let end = F64x8::splat(partners.end as f64);
        let lane = F64x8::load(&[0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0]);
        let quarter = F64x8::splat(0.25 / PI);
        let close2 = F64x8::splat(self.close2);
        let mut acc = [zero; SUM];
        for (k, j) in partners.clone().step_by(LANES).enumerate() {
            let d = axes(|a| xi[a] - F64x8::load(&self.x[a][j..]));
            let r2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
            let inside = F64x8::splat(j as f64) + lane;
            // a lane past the partners, or a partner closer than the blob
            // rest's `CLOSE sigma` (its law is whole there): r^2 = 1, g = 0
            let near = F64x8::select_less(r2, close2, zero, one);
            let keep = F64x8::select_less(inside, end, near, zero);
            let r2 = F64x8::select_less(zero, keep, r2, one);
            let inv = one / r2.sqrt();
            let inv2 = inv * inv;
            let g = keep * quarter * inv * inv2;
            let g2 = F64x8::splat(-3.0) * g * inv2;
            let aj = axes(|a| F64x8::load(&self.alpha[a][j..]));
            let terms = |alpha: [F64x8; 3], acc: &mut [F64x8; SUM], sign: F64x8| {
                let w = cross(alpha, d);
                let v = [w[0] * g2, w[1] * g2, w[2] * g2];
                let s = [alpha[0] * g, alpha[1] * g, alpha[2] * g];
                for a in 0..3 {
                    acc[a] = acc[a] + sign * w[a] * g;
                    for e in 0..3 {
                        acc[3 + 3 * a + e] = acc[3 + 3 * a + e] + v[a] * d[e];
                    }
                }
                // eps_abe s_b: (a, e) = (0, 1): -s_2, (0, 2): s_1, (1, 0): s_2,
                // (1, 2): -s_0, (2, 0): -s_1, (2, 1): s_0
                acc[4] = acc[4] - s[2];
                acc[5] = acc[5] + s[1];
                acc[6] = acc[6] + s[2];
                acc[8] = acc[8] - s[0];
                acc[9] = acc[9] - s[1];
                acc[10] = acc[10] + s[0];
            };
            terms(aj, &mut acc, one);
            let slot = from + k * LANES;
            let mut theirs = [zero; SUM];
            terms(ai, &mut theirs, F64x8::splat(-1.0));
            for (r, t) in reactions.iter_mut().zip(theirs) {
                (F64x8::load(&r[slot..]) + t).store(&mut r[slot..]);
            }
        }
        acc.map(|a| a.sum())
    }
}

/// `b x c`.
#[inline(always)]
fn cross(b: [F64x8; 3], c: [F64x8; 3]) -> [F64x8; 3] {
    [
        b[1] * c[2] - b[2] * c[1],
        b[2] * c[0] - b[0] * c[2],
        b[0] * c[1] - b[1] * c[0],
    ]
}

#[cfg(test)]
#[path = "vortex3_tests.rs"]
mod tests;
