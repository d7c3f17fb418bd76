//! All pairs, each once (Newton's third law): `acc_i += k_ij m_j d_ij` and
//! `acc_j -= k_ij m_i d_ij` with `d_ij = x_j - x_i`, `k_ij = G/s^3 (1 - a^4/s^4)`,
//! `s^2 = |d_ij|^2 + eps^2` (see [`GravityLaw`]).
//!
//! The particles are copied to structure-of-arrays buffers and cut into blocks of
//! [`BLOCK`]; blocks meet in the rounds of a round-robin [`tournament`], the pairs
//! of a round running in parallel on disjoint blocks. A row (one particle against
//! a run of partners) is computed a SIMD register of partners at a time
//! ([`Register`]: four lanes here, eight in the FMM's near field). Every sum runs in an order fixed by the
//! data, so the result does not depend on the thread count.

use super::{FieldOut, Sources};
use crate::interactions::GravityLaw;
use crate::simd::{F64x4, Register};
use crate::threads::{tournament, DisjointSlice, Threads};
use rayon::prelude::*;
use std::ops::Range;

/// Particles per block: a block's positions, masses and sums (8 arrays of 8 bytes)
/// take 16 KiB, so two blocks stay in the level-1 cache.
pub const BLOCK: usize = 256;

/// Per-axis positions and masses, and the running sums, as structure of arrays.
#[derive(Clone, Debug, Default)]
struct Columns {
    x: [Vec<f64>; 3],
    m: Vec<f64>,
    acc: [Vec<f64>; 3],
    /// `sum_j m_j (phi factor)`: the potential before its `-G`.
    pot: Vec<f64>,
}

/// The direct solver: its buffers and the tournament's rounds for one particle
/// count.
#[derive(Clone, Debug)]
pub struct DirectSum {
    law: GravityLaw,
    n: usize,
    rounds: Vec<Vec<(usize, usize)>>,
    columns: Columns,
}

impl DirectSum {
    /// The solver for `n` particles under `law`.
    pub fn new(law: GravityLaw, n: usize) -> Self {
        DirectSum {
            law,
            n,
            rounds: tournament(n.div_ceil(BLOCK)),
            columns: Columns {
                x: std::array::from_fn(|_| vec![0.0; n]),
                m: vec![0.0; n],
                acc: std::array::from_fn(|_| vec![0.0; n]),
                pot: vec![0.0; n],
            },
        }
    }

    /// Pair interactions per evaluation, `N (N - 1) / 2`.
    pub fn pairs(&self) -> u64 {
        let n = self.n as u64;
        n * n.saturating_sub(1) / 2
    }

    /// Fills `out` with the exact accelerations and potentials of `sources`
    /// (which must hold the `n` particles this solver was made for).
    pub fn compute(&mut self, sources: &Sources, out: FieldOut, threads: &Threads) {
        assert_eq!(
            sources.mass.len(),
            self.n,
            "direct sum built for {} particles",
            self.n
        );
        let c = &mut self.columns;
        for (i, p) in sources.position.iter().enumerate() {
            for a in 0..3 {
                c.x[a][i] = p[a];
            }
        }
        c.m.copy_from_slice(sources.mass);
        for a in 0..3 {
            c.acc[a].fill(0.0);
        }
        c.pot.fill(0.0);
        if self.law.has_repulsion() {
            self.sum::<true>(threads);
        } else {
            self.sum::<false>(threads);
        }
        let g = self.law.g();
        let c = &self.columns;
        for i in 0..self.n {
            out.acc[i] = [g * c.acc[0][i], g * c.acc[1][i], g * c.acc[2][i]];
            out.phi[i] = -g * c.pot[i];
        }
    }

    fn sum<const REPULSION: bool>(&mut self, threads: &Threads) {
        let n = self.n;
        let block = |b: usize| b * BLOCK..((b + 1) * BLOCK).min(n);
        let kernel = Kernel::new(&self.law);
        let Columns { x, m, acc, pot } = &mut self.columns;
        let (x, m) = (&*x, &*m);
        let [ax, ay, az] = acc;
        let sums = [
            DisjointSlice::new(ax),
            DisjointSlice::new(ay),
            DisjointSlice::new(az),
            DisjointSlice::new(pot),
        ];
        threads.install(|| {
            for round in &self.rounds {
                round.par_iter().for_each(|&(a, b)| {
                    if a == b {
                        // SAFETY: each block occurs once in round 0.
                        let mut own = unsafe { Block::of(&sums, block(a)) };
                        for i in block(a) {
                            let local = i - block(a).start;
                            let partners_of_i = block(a).start + local + 1..block(a).end;
                            let (mut mine, later) = own.split(local);
                            let (px, pm) = partners(x, m, partners_of_i);
                            let xi = [x[0][i], x[1][i], x[2][i]];
                            let got = kernel
                                .row::<F64x4, REPULSION, true, false>(xi, m[i], px, pm, later);
                            mine.add(0, got);
                        }
                    } else {
                        // SAFETY: the block pairs of one round are disjoint.
                        let (mut own, other) =
                            unsafe { (Block::of(&sums, block(a)), Block::of(&sums, block(b))) };
                        let mut other = other;
                        for i in block(a) {
                            let (px, pm) = partners(x, m, block(b));
                            let xi = [x[0][i], x[1][i], x[2][i]];
                            let got = kernel.row::<F64x4, REPULSION, true, false>(
                                xi,
                                m[i],
                                px,
                                pm,
                                other.reborrow(),
                            );
                            own.add(i - block(a).start, got);
                        }
                    }
                });
            }
        });
    }
}

/// The sums of a set of targets against sources held elsewhere (one side of each
/// pair only): what a rank of a distributed direct sum adds up while the sources
/// of the other ranks pass by in a ring.
///
/// `acc_i = G sum_j k_ij m_j d_ij` and `phi_i = -G sum_j p_ij m_j` over every
/// source `j` that is not `i` itself, with `d_ij = x_j - x_i` and `k`, `p` of
/// [`GravityLaw`]; each target's sum runs over the source blocks in the order they
/// are added, so the result does not depend on the thread count.
#[derive(Clone, Debug)]
pub struct PartialField {
    law: GravityLaw,
    /// `sum k m d` per target (before `G`).
    acc: Vec<[f64; 3]>,
    /// `sum p m` per target (before `-G`).
    pot: Vec<f64>,
}

impl PartialField {
    /// Zero sums for `n` targets under `law`.
    pub fn new(law: GravityLaw, n: usize) -> Self {
        PartialField {
            law,
            acc: vec![[0.0; 3]; n],
            pot: vec![0.0; n],
        }
    }

    /// Adds the field of `sources` (positions and masses) at `targets`; with
    /// `same`, the sources are the targets themselves and `j = i` is left out.
    pub fn add(&mut self, targets: &[[f64; 3]], sources: &Sources, same: bool, threads: &Threads) {
        assert_eq!(targets.len(), self.acc.len(), "one sum per target");
        self.add_where(sources, threads, |i| (targets[i], same.then_some(i)));
    }

    /// Adds the field of `sources` at the sources `bodies` themselves (one sum
    /// per entry of `bodies`, each leaving its own body out).
    pub fn add_at_bodies(&mut self, bodies: &[usize], sources: &Sources, threads: &Threads) {
        assert_eq!(bodies.len(), self.acc.len(), "one sum per body");
        self.add_where(sources, threads, |i| {
            (sources.position[bodies[i]], Some(bodies[i]))
        });
    }

    /// Adds at target `i` the field of every source but `skip`, where
    /// `target(i) = (x_i, skip)`.
    fn add_where(
        &mut self,
        sources: &Sources,
        threads: &Threads,
        target: impl Fn(usize) -> ([f64; 3], Option<usize>) + Sync,
    ) {
        let kernel = Kernel::new(&self.law);
        let x: [Vec<f64>; 3] =
            std::array::from_fn(|a| sources.position.iter().map(|p| p[a]).collect());
        let m = sources.mass;
        let repulsion = self.law.has_repulsion();
        threads.install(|| {
            self.acc
                .par_iter_mut()
                .zip(self.pot.par_iter_mut())
                .enumerate()
                .with_min_len(16)
                .for_each(|(i, (acc, pot))| {
                    let (xi, skip) = target(i);
                    // the sources before and after the one left out
                    let (first, second) = match skip {
                        Some(j) => (0..j, j + 1..m.len()),
                        None => (0..m.len(), 0..0),
                    };
                    let mut sum = [0.0; 4];
                    for part in [first, second] {
                        let (px, pm) = partners(&x, m, part);
                        let got = if repulsion {
                            kernel.row::<F64x4, true, false, false>(xi, 0.0, px, pm, Block::none())
                        } else {
                            kernel.row::<F64x4, false, false, false>(xi, 0.0, px, pm, Block::none())
                        };
                        for (s, g) in sum.iter_mut().zip(got) {
                            *s += g;
                        }
                    }
                    for a in 0..3 {
                        acc[a] += sum[a];
                    }
                    *pot += sum[3];
                });
        });
    }

    /// Writes the accelerations and potentials of the sums so far.
    pub fn finish(&self, out: FieldOut) {
        let g = self.law.g();
        for (i, (a, p)) in self.acc.iter().zip(&self.pot).enumerate() {
            out.acc[i] = a.map(|v| g * v);
            out.phi[i] = -g * p;
        }
    }
}

/// The running sums of a run of particles: x, y, z and potential.
pub(crate) struct Block<'s> {
    sums: [&'s mut [f64]; 4],
}

impl<'s> Block<'s> {
    /// No sums: the partners of a one-sided row.
    pub(crate) fn none() -> Self {
        Block {
            sums: [&mut [], &mut [], &mut [], &mut []],
        }
    }

    /// The sums held in `sums` (x, y, z, potential).
    pub(crate) fn new(sums: [&'s mut [f64]; 4]) -> Self {
        Block { sums }
    }

    /// The sums of the particles `range`.
    ///
    /// # Safety
    /// No other thread may touch those particles' sums while the block lives.
    unsafe fn of(sums: &'s [DisjointSlice<'_, f64>; 4], range: Range<usize>) -> Self {
        Block {
            sums: [
                sums[0].range(range.clone()),
                sums[1].range(range.clone()),
                sums[2].range(range.clone()),
                sums[3].range(range),
            ],
        }
    }

    /// Particle `local` alone, and the particles after it.
    fn split(&mut self, local: usize) -> (Block<'_>, Block<'_>) {
        let [x, y, z, p] = &mut self.sums;
        let (x0, x1) = x.split_at_mut(local + 1);
        let (y0, y1) = y.split_at_mut(local + 1);
        let (z0, z1) = z.split_at_mut(local + 1);
        let (p0, p1) = p.split_at_mut(local + 1);
        (
            Block {
                sums: [
                    &mut x0[local..],
                    &mut y0[local..],
                    &mut z0[local..],
                    &mut p0[local..],
                ],
            },
            Block {
                sums: [x1, y1, z1, p1],
            },
        )
    }

    fn reborrow(&mut self) -> Block<'_> {
        let [x, y, z, p] = &mut self.sums;
        Block { sums: [x, y, z, p] }
    }

    #[inline(always)]
    fn add(&mut self, local: usize, v: [f64; 4]) {
        for (s, v) in self.sums.iter_mut().zip(v) {
            s[local] += v;
        }
    }
}

/// The pair formula without `G`, with its constants hoisted.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Kernel {
    eps2: f64,
    a4: f64,
}

impl Kernel {
    pub(crate) fn new(law: &GravityLaw) -> Self {
        let a2 = law.repulsion_radius() * law.repulsion_radius();
        Kernel {
            eps2: law.softening2(),
            a4: a2 * a2,
        }
    }

    /// `(k, p)` at squared separation `r2`: `k = 1/s^3 (1 - a^4/s^4)` and
    /// `p = 1/s (1 - a^4/(5 s^4))` with `s^2 = r2 + eps^2`.
    #[inline(always)]
    pub(crate) fn at<const REPULSION: bool>(&self, r2: f64) -> (f64, f64) {
        self.factors::<REPULSION>(1.0 / (r2 + self.eps2).sqrt())
    }

    /// `(k, p)` from `inv = 1/s`.
    #[inline(always)]
    pub(crate) fn factors<const REPULSION: bool>(&self, inv: f64) -> (f64, f64) {
        let inv2 = inv * inv;
        if REPULSION {
            let q = self.a4 * inv2 * inv2;
            (inv * inv2 * (1.0 - q), inv * (1.0 - 0.2 * q))
        } else {
            (inv * inv2, inv)
        }
    }

    /// [`Kernel::factors`] on the lanes of a register, from `1/s`.
    #[inline(always)]
    pub(crate) fn factors_in_lanes<L: Register, const REPULSION: bool>(&self, inv: L) -> (L, L) {
        let inv2 = inv * inv;
        if REPULSION {
            let q = L::splat(self.a4) * inv2 * inv2;
            let one = L::splat(1.0);
            (inv * inv2 * (one - q), inv * L::splat(-0.2).mul_add(q, one))
        } else {
            (inv * inv2, inv)
        }
    }

    /// `eps^2` on the lanes plus the squared length of `d`.
    #[inline(always)]
    pub(crate) fn s2<L: Register>(&self, d: [L; 3]) -> L {
        d[0].mul_add(
            d[0],
            d[1].mul_add(d[1], d[2].mul_add(d[2], L::splat(self.eps2))),
        )
    }

    /// The particle at `xi` of mass `mi` against the `partners` (positions
    /// per axis, masses `pm`): returns `(sum k m_j d, sum m_j p)`, summed lane
    /// by lane and then across lanes, the last partial group after them; when
    /// `SYMMETRIC`, also adds `-k m_i d` and `m_i p` to each partner's sums in
    /// `theirs` (same length; untouched otherwise). With `ESTIMATE` the lanes'
    /// `1 / sqrt(r^2 + eps^2)` is [`Register::inverse_sqrt`] (on eight lanes
    /// built for AVX-512, a refined estimate within a few ulp: the FMM's near
    /// field), without it the exactly rounded division (the direct sum).
    #[inline(always)]
    pub(crate) fn row<
        L: Register,
        const REPULSION: bool,
        const SYMMETRIC: bool,
        const ESTIMATE: bool,
    >(
        &self,
        xi: [f64; 3],
        mi: f64,
        partners: [&[f64]; 3],
        pm: &[f64],
        theirs: Block,
    ) -> [f64; 4] {
        let [total] =
            self.rows::<L, REPULSION, SYMMETRIC, ESTIMATE, 1>([xi], [mi], partners, pm, theirs);
        total
    }

    /// [`row`](Self::row) of `T` particles against the same partners, with
    /// the bits of `T` calls in turn: each partner's sums take the
    /// particles' terms in their order, loaded and stored once per group of
    /// lanes for all `T`.
    #[inline(always)]
    pub(crate) fn rows<
        L: Register,
        const REPULSION: bool,
        const SYMMETRIC: bool,
        const ESTIMATE: bool,
        const T: usize,
    >(
        &self,
        xi: [[f64; 3]; T],
        mi: [f64; T],
        partners: [&[f64]; 3],
        pm: &[f64],
        mut theirs: Block,
    ) -> [[f64; 4]; T] {
        let len = pm.len();
        let [px, py, pz] = partners;
        let [sx, sy, sz, sp] = &mut theirs.sums;
        let whole = len - len % L::WIDTH;
        let (zero, one) = (L::splat(0.0), L::splat(1.0));
        let mut lanes = [[zero; 4]; T];
        for j in (0..whole).step_by(L::WIDTH) {
            let mj = L::load(&pm[j..]);
            let mut d = [[zero; 3]; T];
            let mut ki = [zero; T];
            let mut pi = [zero; T];
            for t in 0..T {
                d[t] = [
                    L::load(&px[j..]) - L::splat(xi[t][0]),
                    L::load(&py[j..]) - L::splat(xi[t][1]),
                    L::load(&pz[j..]) - L::splat(xi[t][2]),
                ];
                let s2 = self.s2(d[t]);
                let inverse = if ESTIMATE {
                    s2.inverse_sqrt()
                } else {
                    one / s2.sqrt()
                };
                let (k, p) = self.factors_in_lanes::<L, REPULSION>(inverse);
                let kj = k * mj;
                for a in 0..3 {
                    lanes[t][a] = kj.mul_add(d[t][a], lanes[t][a]);
                }
                lanes[t][3] = p.mul_add(mj, lanes[t][3]);
                (ki[t], pi[t]) = (k * L::splat(mi[t]), p);
            }
            if SYMMETRIC {
                for (a, s) in [&mut *sx, &mut *sy, &mut *sz].into_iter().enumerate() {
                    let mut r = L::load(&s[j..]);
                    for t in 0..T {
                        r = ki[t].neg_mul_add(d[t][a], r);
                    }
                    r.store(&mut s[j..]);
                }
                let mut r = L::load(&sp[j..]);
                for t in 0..T {
                    r = pi[t].mul_add(L::splat(mi[t]), r);
                }
                r.store(&mut sp[j..]);
            }
        }
        let mut totals = lanes.map(|l| l.map(L::sum));
        for j in whole..len {
            for (t, total) in totals.iter_mut().enumerate() {
                let d = [px[j] - xi[t][0], py[j] - xi[t][1], pz[j] - xi[t][2]];
                let (k, p) = self.at::<REPULSION>(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
                let kj = k * pm[j];
                total[0] += kj * d[0];
                total[1] += kj * d[1];
                total[2] += kj * d[2];
                total[3] += p * pm[j];
                if SYMMETRIC {
                    let ki = k * mi[t];
                    sx[j] -= ki * d[0];
                    sy[j] -= ki * d[1];
                    sz[j] -= ki * d[2];
                    sp[j] += p * mi[t];
                }
            }
        }
        totals
    }
}

/// The columns `range` of `x` and `m`: a row's partners.
fn partners<'a>(
    x: &'a [Vec<f64>; 3],
    m: &'a [f64],
    range: Range<usize>,
) -> ([&'a [f64]; 3], &'a [f64]) {
    (
        [
            &x[0][range.clone()],
            &x[1][range.clone()],
            &x[2][range.clone()],
        ],
        &m[range],
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::simd::F64x8;

    /// Two particles' rows at once give the bits of two rows in turn: their
    /// sums and the partners' reactions, on eight lanes with the estimate
    /// and on four exact, with and without repulsion, for every remainder
    /// of the partners.
    #[test]
    fn two_rows_at_once_give_the_bits_of_two_in_turn() {
        fn check<L: Register, const ESTIMATE: bool, const REPULSION: bool>(
            kernel: &Kernel,
            len: usize,
            next: &mut impl FnMut() -> f64,
        ) {
            let px: [Vec<f64>; 3] =
                std::array::from_fn(|_| (0..len).map(|_| 1.0 + next()).collect());
            let pm: Vec<f64> = (0..len).map(|_| 0.5 + next()).collect();
            let partners = [&px[0][..], &px[1][..], &px[2][..]];
            let xi = [[next(), next(), next()], [next(), next(), next()]];
            let mi = [0.5 + next(), 0.5 + next()];
            let mut apart: [Vec<f64>; 4] = std::array::from_fn(|_| vec![0.1; len]);
            let mut together = apart.clone();
            let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            let one_by_one: Vec<[f64; 4]> = (0..2)
                .map(|t| {
                    let [a, b, c, d] = &mut apart;
                    kernel.row::<L, REPULSION, true, ESTIMATE>(
                        xi[t],
                        mi[t],
                        partners,
                        &pm,
                        Block::new([a, b, c, d]),
                    )
                })
                .collect();
            let [a, b, c, d] = &mut together;
            let both = kernel.rows::<L, REPULSION, true, ESTIMATE, 2>(
                xi,
                mi,
                partners,
                &pm,
                Block::new([a, b, c, d]),
            );
            for t in 0..2 {
                assert_eq!(bits(&both[t]), bits(&one_by_one[t]), "len {len} target {t}");
            }
            for k in 0..4 {
                assert_eq!(
                    bits(&together[k]),
                    bits(&apart[k]),
                    "len {len} reactions {k}"
                );
            }
            let one_sided = kernel.rows::<L, REPULSION, false, ESTIMATE, 2>(
                xi,
                mi,
                partners,
                &pm,
                Block::none(),
            );
            for t in 0..2 {
                let alone = kernel.row::<L, REPULSION, false, ESTIMATE>(
                    xi[t],
                    mi[t],
                    partners,
                    &pm,
                    Block::none(),
                );
                assert_eq!(bits(&one_sided[t]), bits(&alone), "len {len} one-sided {t}");
            }
        }
        let mut rng = crate::random::Rng::new(17);
        let mut next = || rng.uniform();
        let repelled = Kernel::new(&GravityLaw::new(1.0, 0.05, 0.02).unwrap());
        let plain = Kernel::new(&GravityLaw::new(1.0, 0.0, 0.0).unwrap());
        for len in 0..21 {
            check::<F64x8, true, true>(&repelled, len, &mut next);
            check::<crate::simd::F64x4, false, true>(&repelled, len, &mut next);
            check::<F64x8, true, false>(&plain, len, &mut next);
            check::<crate::simd::F64x4, false, false>(&plain, len, &mut next);
        }
    }

    /// The row on eight lanes with the estimated inverse square root (the
    /// FMM's near field) against four lanes with the exact one (the direct
    /// sum), for every remainder of the partners: the sums and the partners'
    /// reactions agree to 1e-14 relative, with softening and repulsion.
    #[test]
    fn eight_lanes_with_the_estimate_agree_with_four_exact() {
        let mut rng = crate::random::Rng::new(11);
        let mut next = || rng.uniform();
        for law in [
            GravityLaw::new(1.0, 0.0, 0.0),
            GravityLaw::new(1.0, 0.05, 0.02),
        ] {
            let kernel = Kernel::new(&law.unwrap());
            for len in 0..21 {
                let px: [Vec<f64>; 3] =
                    std::array::from_fn(|_| (0..len).map(|_| 1.0 + next()).collect());
                let pm: Vec<f64> = (0..len).map(|_| 0.5 + next()).collect();
                let xi = [next(), next(), next()];
                let partners = [&px[0][..], &px[1][..], &px[2][..]];
                let mut four: [Vec<f64>; 4] = std::array::from_fn(|_| vec![0.0; len]);
                let mut eight = four.clone();
                let [a, b, c, d] = &mut four;
                let exact = kernel.row::<F64x4, true, true, false>(
                    xi,
                    0.7,
                    partners,
                    &pm,
                    Block::new([a, b, c, d]),
                );
                let [a, b, c, d] = &mut eight;
                let estimated = kernel.row::<F64x8, true, true, true>(
                    xi,
                    0.7,
                    partners,
                    &pm,
                    Block::new([a, b, c, d]),
                );
                let close =
                    |p: f64, q: f64| (p - q).abs() <= 1e-14 * p.abs().max(q.abs()).max(1e-300);
                for (p, q) in exact.iter().zip(&estimated) {
                    assert!(close(*p, *q), "len {len}: {p} against {q}");
                }
                for (p, q) in four.iter().flatten().zip(eight.iter().flatten()) {
                    assert!(close(*p, *q), "len {len}: reaction {p} against {q}");
                }
            }
        }
    }

    #[test]
    fn partial_sums_over_split_sources_match_the_direct_sum() {
        let law = GravityLaw::new(1.5, 0.01, 0.0).unwrap();
        let n = 301;
        let mut rng = crate::random::Rng::new(7);
        let mut next = || rng.uniform();
        let x: Vec<[f64; 3]> = (0..n).map(|_| [next(), next(), next()]).collect();
        let m: Vec<f64> = (0..n).map(|_| 0.5 + next()).collect();
        let threads = Threads::new(2).unwrap();
        let (mut acc, mut phi) = (vec![[0.0; 3]; n], vec![0.0; n]);
        DirectSum::new(law, n).compute(
            &Sources {
                mass: &m,
                position: &x,
            },
            FieldOut {
                acc: &mut acc,
                phi: &mut phi,
            },
            &threads,
        );
        // targets 100..200, sources in three pieces, its own piece marked `same`
        let targets = &x[100..200];
        let mut partial = PartialField::new(law, targets.len());
        for range in [200..301, 0..100, 100..200] {
            let sources = Sources {
                mass: &m[range.clone()],
                position: &x[range.clone()],
            };
            partial.add(targets, &sources, range.start == 100, &threads);
        }
        let (mut a2, mut p2) = (vec![[0.0; 3]; 100], vec![0.0; 100]);
        partial.finish(FieldOut {
            acc: &mut a2,
            phi: &mut p2,
        });
        for i in 0..100 {
            let (a, b) = (acc[100 + i], a2[i]);
            let norm = a.iter().map(|v| v * v).sum::<f64>().sqrt();
            let diff = (0..3).map(|k| (a[k] - b[k]).powi(2)).sum::<f64>().sqrt();
            assert!(diff <= 1e-13 * norm, "{i}: {a:?} {b:?}");
            assert!((phi[100 + i] - p2[i]).abs() <= 1e-13 * phi[100 + i].abs());
        }
    }

    /// The plain double loop over ordered pairs, from the law's own formula.
    fn reference(law: &GravityLaw, m: &[f64], x: &[[f64; 3]]) -> (Vec<[f64; 3]>, Vec<f64>) {
        let n = m.len();
        let mut acc = vec![[0.0; 3]; n];
        let mut phi = vec![0.0; n];
        for i in 0..n {
            for j in 0..n {
                if i != j {
                    let d = [x[j][0] - x[i][0], x[j][1] - x[i][1], x[j][2] - x[i][2]];
                    let (p, k) = law.unit_pair(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
                    for a in 0..3 {
                        acc[i][a] += k * m[j] * d[a];
                    }
                    phi[i] += p * m[j];
                }
            }
        }
        (acc, phi)
    }

    /// The direct solver's accelerations and potentials of masses `m` at `x`.
    fn field(
        law: GravityLaw,
        m: &[f64],
        x: &[[f64; 3]],
        threads: &Threads,
    ) -> (Vec<[f64; 3]>, Vec<f64>) {
        let n = m.len();
        let mut acc = vec![[0.0; 3]; n];
        let mut phi = vec![0.0; n];
        let sources = Sources {
            mass: m,
            position: x,
        };
        DirectSum::new(law, n).compute(
            &sources,
            FieldOut {
                acc: &mut acc,
                phi: &mut phi,
            },
            threads,
        );
        (acc, phi)
    }

    fn cloud(n: usize, seed: u64) -> (Vec<f64>, Vec<[f64; 3]>) {
        let mut rng = crate::random::Rng::new(seed);
        let m = (0..n).map(|_| 0.5 + rng.uniform()).collect();
        let x = (0..n)
            .map(|_| [rng.uniform(), rng.uniform(), rng.uniform()])
            .collect();
        (m, x)
    }

    #[test]
    fn matches_the_double_loop_across_block_edges() {
        for (n, eps, a) in [
            (1, 0.0, 0.0),
            (7, 0.0, 0.0),
            (300, 0.01, 0.0),
            (600, 0.02, 0.03),
        ] {
            let law = GravityLaw::new(1.3, eps, a).unwrap();
            let (m, x) = cloud(n, n as u64);
            let (want_acc, want_phi) = reference(&law, &m, &x);
            let (acc, phi) = field(law, &m, &x, &Threads::single());
            for i in 0..n {
                let scale = want_acc[i]
                    .iter()
                    .map(|v| v * v)
                    .sum::<f64>()
                    .sqrt()
                    .max(1e-300);
                for a in 0..3 {
                    assert!(
                        (acc[i][a] - want_acc[i][a]).abs() <= 1e-12 * scale,
                        "n {n} i {i}"
                    );
                }
                assert!((phi[i] - want_phi[i]).abs() <= 1e-12 * want_phi[i].abs().max(1e-300));
            }
        }
    }

    #[test]
    fn one_and_two_threads_give_the_same_bits() {
        let n = 1100;
        let law = GravityLaw::new(1.0, 0.01, 0.0).unwrap();
        let (m, x) = cloud(n, 5);
        let one = field(law, &m, &x, &Threads::single());
        let two = field(law, &m, &x, &Threads::new(2).unwrap());
        assert_eq!(format!("{:?}", one), format!("{:?}", two));
    }

    #[test]
    fn momentum_is_conserved_to_round_off() {
        let n = 700;
        let law = GravityLaw::new(1.0, 0.0, 0.0).unwrap();
        let (m, x) = cloud(n, 9);
        let (acc, _) = field(law, &m, &x, &Threads::single());
        for a in 0..3 {
            let total: f64 = (0..n).map(|i| m[i] * acc[i][a]).sum();
            let scale: f64 = (0..n).map(|i| (m[i] * acc[i][a]).abs()).sum();
            assert!(total.abs() <= 1e-13 * scale, "axis {a}: {total} of {scale}");
        }
    }
}
