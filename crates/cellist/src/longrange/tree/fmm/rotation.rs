//! M2L by rotation (point and shoot): the multipole is turned so that the
//! separation lies along `+z`, translated along `z` (where only the terms of
//! one `m` meet, `O(p^3)` in all), and the local turned back.
//!
//! For the rotation `Q = R_y(-beta) R_z(-alpha)` that takes the direction
//! `(sin beta cos alpha, sin beta sin alpha, cos beta)` to `+z`, the regular
//! solid harmonics of [`super::solid`] obey
//! `R_n^m(Q x) = sum_{m'} D^n_{m m'} e^{-i m' alpha} R_n^{m'}(x)`, with the real
//!
//! `D^n_{m m'} = (-1)^(m - m') d^n_{m m'}(beta) sqrt((n - m')! (n + m')! / ((n - m)! (n + m)!))`
//!
//! (`d^n` Wigner's small d-matrix). Each turn is then `O(p^3)`.
//!
//! The expansions are those of real fields, `v_n^{-m} = (-1)^m conj(v_n^m)`,
//! so a turn needs only the terms `m >= 0` of its input: with the real `D`,
//! `sum_{m'} D_{m m'} v^{m'} = D_{m 0} v^0 + sum_{m' > 0} (P_{m m'} Re v^{m'} + i Q_{m m'} Im v^{m'})`,
//! `P, Q = D_{m m'} +- (-1)^{m'} D_{m, -m'}` ([`Turn`]'s folded matrices):
//! `2 (n + 1)` multiply-adds per output term instead of `2 (2n + 1)`.

use super::engine::Cube;
use super::solid::at;
use crate::simd::{F64x8, Register};
use rustfft::num_complex::Complex64;
use std::collections::HashMap;

/// The SIMD word of M2L: the same coefficient of [`LANES`] translations
/// side by side (one direction, so one turn, for all of them).
type Word = F64x8;

/// Translations per [`Word`].
const LANES: usize = Word::WIDTH;

/// `-x` in every lane, zeros' signs included (a product by `-1` is exact).
#[inline(always)]
fn negated(x: Word) -> Word {
    x * Word::splat(-1.0)
}

/// `(re + i im) (e.re + i e.im)` in every lane, as `Complex64`'s product
/// rounds it: `re e.re - im e.im`, `re e.im + im e.re`.
#[inline(always)]
fn times(re: Word, im: Word, e: Complex64) -> (Word, Word) {
    let (er, ei) = (Word::splat(e.re), Word::splat(e.im));
    (re * er - im * ei, re * ei + im * er)
}

/// The terms `m >= 0` of [`LANES`] expansions (or of one degree), a word
/// per coefficient, real and imaginary parts apart.
#[derive(Clone, Debug, Default)]
struct Lanes {
    re: Vec<Word>,
    im: Vec<Word>,
}

impl Lanes {
    /// Room for at least `len` coefficients, grown with zeros and never
    /// cleared: each user writes a coefficient before it reads it.
    fn fit(&mut self, len: usize) {
        for v in [&mut self.re, &mut self.im] {
            if v.len() < len {
                v.resize(len, Word::splat(0.0));
            }
        }
    }
}

/// `out[m] = sum_c (P_{m c} Re v_c + i Q_{m c} Im v_c)` for `m, c = 0..=n`
/// (`folded`: `P` then `Q`, row by row) and the `n + 1` complex inputs `v`
/// (`v_c` at `v.re[first + c]`, `v.im[first + c]`) of every lane: four
/// outputs at a time ([`rows`]), each input loaded once for the four, each
/// output's sum over the inputs in order.
#[inline(always)]
fn products(
    n: usize,
    folded: &[f64],
    (v, first): (&Lanes, usize),
    (out_re, out_im): (&mut [Word], &mut [Word]),
) {
    let inputs = n + 1;
    let (p, q) = folded.split_at(inputs * inputs);
    let input = (&v.re[first..first + inputs], &v.im[first..first + inputs]);
    let mut m = 0;
    while m + 4 <= inputs {
        rows::<4>(m, (p, q), input, (&mut *out_re, &mut *out_im));
        m += 4;
    }
    while m < inputs {
        rows::<1>(m, (p, q), input, (&mut *out_re, &mut *out_im));
        m += 1;
    }
}

/// The outputs `first..first + R` of [`products`]: `2 R` sums that do not
/// wait on each other, the inputs' words loaded once for all of them.
#[inline(always)]
fn rows<const R: usize>(
    first: usize,
    (p, q): (&[f64], &[f64]),
    (re_in, im_in): (&[Word], &[Word]),
    (out_re, out_im): (&mut [Word], &mut [Word]),
) {
    let inputs = re_in.len();
    let zero = Word::splat(0.0);
    let (mut re, mut im) = ([zero; R], [zero; R]);
    let p_rows: [&[f64]; R] = std::array::from_fn(|r| &p[(first + r) * inputs..][..inputs]);
    let q_rows: [&[f64]; R] = std::array::from_fn(|r| &q[(first + r) * inputs..][..inputs]);
    for (c, (&x, &y)) in re_in.iter().zip(&im_in[..inputs]).enumerate() {
        for r in 0..R {
            re[r] = Word::splat(p_rows[r][c]).mul_add(x, re[r]);
            im[r] = Word::splat(q_rows[r][c]).mul_add(y, im[r]);
        }
    }
    out_re[first..first + R].copy_from_slice(&re);
    out_im[first..first + R].copy_from_slice(&im);
}

/// The turn of one direction onto `+z`: the phases `e^{i m alpha}` and,
/// degree after degree, the matrices `D^n` folded for real fields (module
/// doc): for the forward turn `P, Q = D_{m c} +- (-1)^c D_{m, -c}`, for the
/// turn back (which sums over the rows) `P, Q = D_{c l} +- (-1)^c D_{-c, l}`,
/// `m, l, c = 0..=n` (at `c = 0` both are `D`'s own entry).
#[derive(Clone, Debug)]
pub(super) struct Turn {
    phases: Vec<Complex64>,
    /// Per degree `n` from [`start`]`(n)` on: the forward `P` and `Q`, then
    /// the backward `P` and `Q`, each `(n + 1)^2` row by row.
    folded: Vec<f64>,
}

/// Where degree `n`'s folded matrices start: `sum_{j < n} 4 (j + 1)^2`.
fn start(n: usize) -> usize {
    2 * n * (n + 1) * (2 * n + 1) / 3
}

/// `D^n_{m m'}` of the turn by `beta` ([`wigner_d`] with its scale and
/// sign, module doc), rows and columns `-n..=n`: at `(m + n) (2n + 1) + m' + n`.
fn full_matrix(n: usize, beta: f64, log_factorials: &[f64]) -> Vec<f64> {
    let w = 2 * n + 1;
    let mut block = vec![0.0; w * w];
    for (i, m) in (-(n as i64)..=n as i64).enumerate() {
        for (k, mp) in (-(n as i64)..=n as i64).enumerate() {
            let lf = |x: i64| log_factorials[x as usize];
            let scale = (0.5
                * (lf(n as i64 - mp) + lf(n as i64 + mp) - lf(n as i64 - m) - lf(n as i64 + m)))
            .exp();
            let sign = if (m - mp).rem_euclid(2) == 0 {
                1.0
            } else {
                -1.0
            };
            block[i * w + k] = sign * scale * wigner_d(n as i64, m, mp, beta, log_factorials);
        }
    }
    block
}

/// The angles `(beta, alpha)` of the direction `v` (any length).
fn angles(v: [f64; 3]) -> (f64, f64) {
    let r = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    ((v[2] / r).clamp(-1.0, 1.0).acos(), v[1].atan2(v[0]))
}

impl Turn {
    /// The turn of the direction `v` (any length) for degrees `0..=p`.
    pub fn new(v: [f64; 3], p: usize, log_factorials: &[f64]) -> Self {
        let (beta, alpha) = angles(v);
        let phases = (0..=p)
            .map(|m| Complex64::from_polar(1.0, m as f64 * alpha))
            .collect();
        let mut folded = vec![0.0; start(p + 1)];
        for n in 0..=p {
            let d = full_matrix(n, beta, log_factorials);
            let (w, inputs) = (2 * n + 1, n + 1);
            let at_d = |m: i64, c: i64| d[(m + n as i64) as usize * w + (c + n as i64) as usize];
            let block = &mut folded[start(n)..start(n + 1)];
            let (forward, back) = block.split_at_mut(2 * inputs * inputs);
            for (half, transposed) in [(forward, false), (back, true)] {
                let (p_half, q_half) = half.split_at_mut(inputs * inputs);
                for m in 0..inputs as i64 {
                    for c in 0..inputs as i64 {
                        let (own, mirror) = if transposed {
                            (at_d(c, m), at_d(-c, m))
                        } else {
                            (at_d(m, c), at_d(m, -c))
                        };
                        let k = m as usize * inputs + c as usize;
                        if c == 0 {
                            (p_half[k], q_half[k]) = (own, own);
                        } else {
                            let mirror = if c % 2 == 0 { mirror } else { -mirror };
                            (p_half[k], q_half[k]) = (own + mirror, own - mirror);
                        }
                    }
                }
            }
        }
        Turn { phases, folded }
    }

    /// Degree `n`'s folded matrices: the forward `P` and `Q`, and the
    /// backward ones.
    #[inline(always)]
    fn matrices(&self, n: usize) -> (&[f64], &[f64]) {
        let block = &self.folded[start(n)..start(n + 1)];
        block.split_at(2 * (n + 1) * (n + 1))
    }

    /// The turned terms `a'_n^m = sum_{m'} D^n_{m m'} e^{i m' alpha} a_n^{m'}`
    /// (`m >= 0`) of the lanes' multipoles `a` (terms `m >= 0`), into `out`.
    fn forward(&self, p: usize, a: &Lanes, out: &mut Lanes, phased: &mut Lanes) {
        out.fit(at(p + 1, 0));
        for n in 0..=p {
            phased.fit(n + 1);
            for m in 0..=n {
                let t = at(n, m);
                (phased.re[m], phased.im[m]) = times(a.re[t], a.im[t], self.phases[m]);
            }
            let range = at(n, 0)..at(n, n) + 1;
            products(
                n,
                self.matrices(n).0,
                (phased, 0),
                (&mut out.re[range.clone()], &mut out.im[range]),
            );
        }
    }

    /// The turned-back local terms `b_k^l = e^{i l alpha} sum_{l'} D^k_{l' l}
    /// b'_k^{l'}` (`l >= 0`) of the lanes' turned locals `b`, into `out`.
    fn back(&self, p: usize, b: &Lanes, out: &mut Lanes) {
        out.fit(at(p + 1, 0));
        for k in 0..=p {
            let range = at(k, 0)..at(k, k) + 1;
            products(
                k,
                self.matrices(k).1,
                (b, range.start),
                (&mut out.re[range.clone()], &mut out.im[range.clone()]),
            );
            for (l, t) in range.enumerate() {
                (out.re[t], out.im[t]) = times(out.re[t], out.im[t], self.phases[l]);
            }
        }
    }

    /// `e^{i m alpha}` for any `m`.
    #[cfg(test)]
    fn phase(&self, m: isize) -> Complex64 {
        let e = self.phases[m.unsigned_abs()];
        if m >= 0 {
            e
        } else {
            e.conj()
        }
    }
}

/// Wigner's `d^j_{m' m}(beta)` from the Jacobi polynomial
/// `P_k^{(a, b)}(cos beta)` (Edmonds):
/// `d = (-1)^lambda sqrt(C(2j - k, k + a) / C(k + b, b)) sin(beta/2)^a cos(beta/2)^b P_k^{(a,b)}(cos beta)`
/// with `k = min(j + m, j - m, j + m', j - m')` and `a`, `b`, `lambda` by
/// which of the four is least; stable for every `j` (the Jacobi recurrence
/// in `k`), unlike the alternating sum.
fn wigner_d(j: i64, mp: i64, m: i64, beta: f64, log_factorials: &[f64]) -> f64 {
    let k = (j + m).min(j - m).min(j + mp).min(j - mp);
    // k = j + m or j - m': a = m' - m, lambda = a; k = j - m or j + m': a = m - m'
    let (a, lambda) = if k == j + m || (k != j - m && k != j + mp) {
        (mp - m, mp - m)
    } else {
        (m - mp, 0)
    };
    let b = 2 * j - 2 * k - a;
    let lf = |x: i64| log_factorials[x as usize];
    // C(2j - k, k + a) / C(k + b, b)
    let log_ratio =
        (lf(2 * j - k) - lf(k + a) - lf(2 * j - 2 * k - a)) - (lf(k + b) - lf(b) - lf(k));
    let (s, c) = ((0.5 * beta).sin(), (0.5 * beta).cos());
    let sign = if lambda.rem_euclid(2) == 0 { 1.0 } else { -1.0 };
    sign * (0.5 * log_ratio).exp()
        * s.powi(a as i32)
        * c.powi(b as i32)
        * jacobi(k, a as f64, b as f64, beta.cos())
}

/// The Jacobi polynomial `P_k^{(a, b)}(x)` by its three-term recurrence.
fn jacobi(k: i64, a: f64, b: f64, x: f64) -> f64 {
    let mut previous = 1.0;
    if k == 0 {
        return previous;
    }
    let mut current = (a + 1.0) + 0.5 * (a + b + 2.0) * (x - 1.0);
    for n in 2..=k {
        let n = n as f64;
        let s = 2.0 * n + a + b;
        let next = ((s - 1.0) * (s * (s - 2.0) * x + a * a - b * b) * current
            - 2.0 * (n + a - 1.0) * (n + b - 1.0) * s * previous)
            / (2.0 * n * (n + a + b) * (s - 2.0));
        previous = current;
        current = next;
    }
    current
}

/// `ln(k!)` for `k <= last`.
pub(super) fn log_factorials(last: usize) -> Vec<f64> {
    let mut out = vec![0.0; last + 1];
    for k in 1..=last {
        out[k] = out[k - 1] + (k as f64).ln();
    }
    out
}

/// A thread's turns, one per direction met, keyed by the separation in
/// units of half the smaller box's side reduced by the greatest common
/// divisor (boxes of the octree sit on one grid, so the key is exact and the
/// turn a function of it).
#[derive(Debug, Default)]
pub(super) struct Turns {
    index: HashMap<[i64; 3], usize>,
    turns: Vec<Turn>,
}

/// The most bytes of turns a thread keeps: past them the cache starts
/// afresh (a turn depends only on its key, so results do not change). A turn
/// takes about 48 KB at order 15; a Plummer sphere of 3 x 10^5 bodies meets
/// about 1400 directions.
const TURN_BYTES: usize = 256 << 20;

impl Turns {
    /// The turn of the direction `key` (see [`direction`]).
    pub fn of(&mut self, key: [i64; 3], p: usize, log_factorials: &[f64]) -> &Turn {
        if !self.index.contains_key(&key) && (self.turns.len() + 1) * turn_bytes(p) > TURN_BYTES {
            self.index.clear();
            self.turns.clear();
        }
        let next = self.turns.len();
        let slot = *self.index.entry(key).or_insert(next);
        if slot == next {
            let v = key.map(|k| k as f64);
            self.turns.push(Turn::new(v, p, log_factorials));
        }
        &self.turns[slot]
    }
}

/// The bytes of one turn of order `p` (its matrices).
fn turn_bytes(p: usize) -> usize {
    start(p + 1) * std::mem::size_of::<f64>()
}

/// A group's far pairs `(direction, target, source)`, as M2L sorts them.
pub(super) type FarPairs = Vec<([i64; 3], u32, u32)>;

/// M2L of a target group by rotation ([`M2lLanes::translate`]) for
/// multipoles and locals of `components` expansions of order `p` each,
/// stacked per box (`components * terms(p)` numbers): for every far pair
/// `(t, s)` of the group (`far = (group, starts, sources)`, the sources of
/// box `group + k` at `sources[starts[k]..starts[k + 1]]`), each component's
/// local of `t` receives the same component's multipole of `s`. The pairs
/// run grouped by direction (then target and source), [`LANES`] translations
/// (pairs and components) of one direction at a time, and each local adds
/// its translations in that order, which is a function of the boxes.
/// `pairs` is scratch.
pub(super) fn m2l_by_direction(
    p: usize,
    components: usize,
    multipoles: &[Complex64],
    cubes: &[Cube],
    (group, starts, sources): (usize, &[usize], &[u32]),
    locals: &mut [Complex64],
    (pairs, m2l): (&mut FarPairs, &mut M2lLanes),
) {
    let terms = super::solid::terms(p);
    let stride = components * terms;
    let side = |c: Cube| c.radius * 2.0 / 3f64.sqrt();
    pairs.clear();
    for k in 0..starts.len() - 1 {
        let t = group + k;
        for &s in &sources[starts[k]..starts[k + 1]] {
            let (to, from) = (cubes[t], cubes[s as usize]);
            let d = std::array::from_fn(|a| to.centre[a] - from.centre[a]);
            pairs.push((direction(d, side(to).min(side(from))), t as u32, s));
        }
    }
    pairs.sort_unstable();
    // the translations (pair, component) in order, LANES at a time, cut
    // where the direction changes
    let mut first = 0;
    while first < pairs.len() {
        let key = pairs[first].0;
        let same = pairs[first..].iter().take_while(|q| q.0 == key).count();
        let run = &pairs[first..first + same];
        let items = run.len() * components;
        let mut done = 0;
        while done < items {
            let count = LANES.min(items - done);
            let item = |lane: usize| {
                let (t, s) = (
                    run[(done + lane) / components].1,
                    run[(done + lane) / components].2,
                );
                (t as usize, s as usize, (done + lane) % components)
            };
            m2l.translate(p, key, count, |lane| {
                let (t, s, c) = item(lane);
                let (to, from) = (cubes[t], cubes[s]);
                Translation {
                    multipole: &multipoles[s * stride + c * terms..][..terms],
                    source: (from.centre, from.radius),
                    target: (to.centre, to.radius),
                }
            });
            m2l.add_lanes(
                count,
                |lane| {
                    let (t, _, c) = item(lane);
                    (t - group) * stride + c * terms
                },
                locals,
            );
            done += count;
        }
        first += same;
    }
}

/// The direction of the separation `d` between two boxes of the octree
/// whose smaller side is `side`, exactly: `d` in units of half that side is
/// a vector of integers (the boxes sit on one grid), reduced by their
/// greatest common divisor.
pub(super) fn direction(d: [f64; 3], side: f64) -> [i64; 3] {
    let mut key = d.map(|x| (2.0 * x / side).round() as i64);
    let g = gcd(gcd(key[0].abs(), key[1].abs()), key[2].abs()).max(1);
    for k in &mut key {
        *k /= g;
    }
    key
}

fn gcd(a: i64, b: i64) -> i64 {
    if b == 0 {
        a
    } else {
        gcd(b, a % b)
    }
}

/// One M2L of [`M2lLanes::translate`]: a multipole (terms `m >= 0`) about
/// the source's centre with its scale, into a local about the target's.
pub(super) struct Translation<'a> {
    /// The multipole's terms `m >= 0`, [`super::solid::at`]'s order (at
    /// least `terms(p)` of them; those past it are not read).
    pub multipole: &'a [Complex64],
    /// The source box's centre and scale `s_c`.
    pub source: ([f64; 3], f64),
    /// The target box's centre and scale `s_t`.
    pub target: ([f64; 3], f64),
}

/// What M2L by rotation keeps per thread: the turns met so far, `ln k!`,
/// `k!`, and the lanes' expansions on their way.
#[derive(Debug, Default)]
pub(super) struct M2lLanes {
    order: usize,
    turns: Turns,
    log_factorials: Vec<f64>,
    factorials: Vec<f64>,
    multipoles: Lanes,
    turned: Lanes,
    shifted: Lanes,
    locals: Lanes,
    scratch: Lanes,
}

impl M2lLanes {
    fn prepare(&mut self, p: usize) {
        if self.order != p || self.factorials.is_empty() {
            *self = M2lLanes {
                order: p,
                log_factorials: log_factorials(4 * p + 2),
                factorials: (0..=2 * p + 4)
                    .scan(1.0, |f, k| {
                        let v = *f;
                        *f *= (k + 1) as f64;
                        Some(v)
                    })
                    .collect(),
                ..M2lLanes::default()
            };
        }
    }

    /// M2L of `count` (at most [`LANES`]) translations `lane(0..count)`
    /// whose separations `D = t - c` (target centre less source centre) all
    /// have the direction `key` ([`direction`]), side by side in the lanes:
    /// each multipole `a` about `c` (scale `s_c`) is turned so that `D`
    /// points along `+z` (`d = |D|`), translated there into the local about
    /// `t` (scale `s_t`),
    ///
    /// `b'_k^l = (-1)^k (s_t / d)^k / d sum_{n = |l|}^{p} a'_n^{-l} (s_c / d)^n (n + k)!`
    ///
    /// (`I_j^m(d z) = j! / d^(j + 1)` for `m = 0`, else 0), and turned back
    /// (every `n, k <= p`); [`M2lLanes::add_lanes`] adds the lanes' locals.
    /// Each lane's numbers take the same operations in the same order as
    /// one translation alone.
    pub fn translate<'a>(
        &mut self,
        p: usize,
        key: [i64; 3],
        count: usize,
        lane: impl Fn(usize) -> Translation<'a>,
    ) {
        assert!((1..=LANES).contains(&count));
        self.prepare(p);
        let terms = at(p + 1, 0);
        // the lanes past `count`: no multipole, at distance 1
        let mut distance = [1.0; LANES];
        let (mut rho_s, mut rho_t) = ([0.0; LANES], [0.0; LANES]);
        let mut sources: [&[Complex64]; LANES] = [&[]; LANES];
        for l in 0..count {
            let Translation {
                multipole,
                source,
                target,
            } = lane(l);
            let d: [f64; 3] = std::array::from_fn(|k| target.0[k] - source.0[k]);
            distance[l] = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
            (rho_s[l], rho_t[l]) = (source.1 / distance[l], target.1 / distance[l]);
            sources[l] = &multipole[..terms];
        }
        // the lanes' multipoles into words of one coefficient each (lanes
        // past `count` zero): four coefficients of every lane at a time by
        // a transpose, the last ones one at a time
        self.multipoles.fit(terms);
        let whole = terms - terms % 4;
        for first in (0..whole).step_by(4) {
            let rows = std::array::from_fn(|l| {
                if l < count {
                    four_coefficients(&sources[l][first..])
                } else {
                    Word::splat(0.0)
                }
            });
            let words = Word::transpose(rows);
            for (k, pair) in words.chunks_exact(2).enumerate() {
                (self.multipoles.re[first + k], self.multipoles.im[first + k]) = (pair[0], pair[1]);
            }
        }
        for t in whole..terms {
            let part = |f: fn(&Complex64) -> f64| {
                Word::load(&std::array::from_fn::<f64, LANES, _>(|l| {
                    if l < count {
                        f(&sources[l][t])
                    } else {
                        0.0
                    }
                }))
            };
            self.multipoles.re[t] = part(|c| c.re);
            self.multipoles.im[t] = part(|c| c.im);
        }
        let M2lLanes {
            turns,
            log_factorials,
            factorials,
            multipoles,
            turned,
            shifted,
            locals,
            scratch,
            ..
        } = self;
        let turn = turns.of(key, p, log_factorials);
        turn.forward(p, multipoles, turned, scratch);
        shifted.fit(terms);
        let step = Word::load(&rho_s);
        // (s_c / d)^l
        let mut first_power = Word::splat(1.0);
        for l in 0..=p {
            // a'_n^l (s_c / d)^n for n = l..=p
            let len = p - l + 1;
            scratch.fit(len);
            let mut power = first_power;
            first_power = first_power * step;
            for (i, n) in (l..=p).enumerate() {
                let t = at(n, l);
                (scratch.re[i], scratch.im[i]) = (turned.re[t] * power, turned.im[t] * power);
                power = power * step;
            }
            // sum_{n >= l} a'_n^l f[n + k], four k at a time (eight sums that
            // do not wait on each other, each over n in order, held in
            // registers; past k = p the sums are made and dropped)
            let mut k = l;
            while k <= p {
                let runs = 4.min(p + 1 - k);
                let zero = Word::splat(0.0);
                let (mut sum_re, mut sum_im) = ([zero; 4], [zero; 4]);
                for i in 0..len {
                    let four = &factorials[l + k + i..][..4];
                    for r in 0..4 {
                        let f = Word::splat(four[r]);
                        sum_re[r] = f.mul_add(scratch.re[i], sum_re[r]);
                        sum_im[r] = f.mul_add(scratch.im[i], sum_im[r]);
                    }
                }
                for r in 0..runs {
                    let t = at(k + r, l);
                    (shifted.re[t], shifted.im[t]) = (sum_re[r], sum_im[r]);
                }
                k += runs;
            }
        }
        // a'_n^{-l} = (-1)^l conj(a'_n^l), times (-1)^k (s_t / d)^k / d
        let mut factor = Word::load(&distance.map(|d| 1.0 / d));
        let step = Word::load(&rho_t.map(|r| -r));
        for k in 0..=p {
            for l in 0..=k {
                let t = at(k, l);
                let sign = if l % 2 == 0 { factor } else { negated(factor) };
                shifted.re[t] = shifted.re[t] * sign;
                shifted.im[t] = shifted.im[t] * negated(sign);
            }
            factor = factor * step;
        }
        turn.back(p, shifted, locals);
    }

    /// Adds the locals of the last [`M2lLanes::translate`]'s lanes
    /// `0..count` to `locals`, lane `l`'s from `locals[offset(l)]` on; lanes
    /// that share a local add to each term in lane order (the bits of
    /// adding them lane after lane).
    pub fn add_lanes(
        &self,
        count: usize,
        offset: impl Fn(usize) -> usize,
        locals: &mut [Complex64],
    ) {
        let terms = at(self.order + 1, 0);
        let starts: [usize; LANES] = std::array::from_fn(|l| if l < count { offset(l) } else { 0 });
        let (re, im) = (&self.locals.re[..terms], &self.locals.im[..terms]);
        // four coefficients of every lane at a time by a transpose, the lanes
        // in order (each term takes its lanes in lane order), the last
        // coefficients one at a time
        let whole = terms - terms % 4;
        for first in (0..whole).step_by(4) {
            let rows = std::array::from_fn(|k| if k % 2 == 0 { re } else { im }[first + k / 2]);
            let lanes = Word::transpose(rows);
            for (&start, lane) in starts[..count].iter().zip(lanes) {
                let local = &mut locals[start + first..][..4];
                let sum = four_coefficients(local) + lane;
                let mut parts = [0.0; LANES];
                sum.store(&mut parts);
                for (v, part) in local.iter_mut().zip(parts.chunks_exact(2)) {
                    *v = Complex64::new(part[0], part[1]);
                }
            }
        }
        for t in whole..terms {
            let (mut re_t, mut im_t) = ([0.0; LANES], [0.0; LANES]);
            re[t].store(&mut re_t);
            im[t].store(&mut im_t);
            for (l, &start) in starts[..count].iter().enumerate() {
                locals[start + t] += Complex64::new(re_t[l], im_t[l]);
            }
        }
    }
}

/// The word `[re_0, im_0, re_1, im_1, .., re_3, im_3]` of the first four of
/// `c`.
#[inline(always)]
fn four_coefficients(c: &[Complex64]) -> Word {
    let c = &c[..4];
    Word::load(&[
        c[0].re, c[0].im, c[1].re, c[1].im, c[2].re, c[2].im, c[3].re, c[3].im,
    ])
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `d^j_{m' m}(beta)` by the alternating sum over `s` (fine for small
    /// `j`), written out here.
    fn wigner_by_sum(j: i64, mp: i64, m: i64, beta: f64) -> f64 {
        let f = |x: i64| (1..=x).map(|v| v as f64).product::<f64>();
        let mut total = 0.0;
        for s in 0..=2 * j {
            let (a1, a2, a3) = (j + m - s, mp - m + s, j - mp - s);
            if a1 < 0 || a2 < 0 || a3 < 0 {
                continue;
            }
            let sign = if (mp - m + s).rem_euclid(2) == 0 {
                1.0
            } else {
                -1.0
            };
            total += sign * (f(j + mp) * f(j - mp) * f(j + m) * f(j - m)).sqrt()
                / (f(a1) * f(s) * f(a2) * f(a3))
                * (0.5 * beta).cos().powi((2 * j + m - mp - 2 * s) as i32)
                * (0.5 * beta).sin().powi((mp - m + 2 * s) as i32);
        }
        total
    }

    #[test]
    fn the_jacobi_form_matches_the_sum() {
        let lf = log_factorials(40);
        for beta in [0.0, 0.3, 1.2, 2.0, std::f64::consts::PI] {
            for j in 0..=8 {
                for mp in -j..=j {
                    for m in -j..=j {
                        let (a, b) = (wigner_d(j, mp, m, beta, &lf), wigner_by_sum(j, mp, m, beta));
                        assert!(
                            (a - b).abs() < 1e-12,
                            "j {j} m' {mp} m {m} beta {beta}: {a} vs {b}"
                        );
                    }
                }
            }
        }
    }

    /// The harmonics' turn: `R_n^m(Q x) = sum D e^{-i m' alpha} R_n^{m'}(x)`.
    #[test]
    fn turned_harmonics_are_the_harmonics_of_the_turned_point() {
        use super::super::solid::{regular, signed, terms};
        let p = 20;
        let lf = log_factorials(2 * p + 2);
        let v = [0.3, -0.7, 0.5];
        let turn = Turn::new(v, p, &lf);
        let r = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        let (beta, alpha) = ((v[2] / r).acos(), v[1].atan2(v[0]));
        // Q = R_y(-beta) R_z(-alpha)
        let x = [0.2, 0.1, -0.3];
        let rz = [
            alpha.cos() * x[0] + alpha.sin() * x[1],
            -alpha.sin() * x[0] + alpha.cos() * x[1],
            x[2],
        ];
        let qx = [
            beta.cos() * rz[0] - beta.sin() * rz[2],
            rz[1],
            beta.sin() * rz[0] + beta.cos() * rz[2],
        ];
        let (mut h, mut hq) = (
            vec![Complex64::new(0.0, 0.0); terms(p)],
            vec![Complex64::new(0.0, 0.0); terms(p)],
        );
        regular(x, p, &mut h);
        regular(qx, p, &mut hq);
        for n in 0..=p {
            let (d, w) = (full_matrix(n, beta, &lf), 2 * n as isize + 1);
            for m in 0..=n as isize {
                let mut sum = Complex64::new(0.0, 0.0);
                for mp in -(n as isize)..=n as isize {
                    let dm = d[((m + n as isize) * w + mp + n as isize) as usize];
                    sum += signed(&h, n, mp) * turn.phase(mp).conj() * dm;
                }
                let want = hq[at(n, m as usize)];
                assert!(
                    (sum - want).norm() < 1e-12 * (1.0 + want.norm()),
                    "n {n} m {m}: {sum} vs {want}"
                );
            }
        }
    }

    /// The folded turns (forward, and back) of lanes of real fields' terms
    /// against the sums over every `m'` (and `l'`) with the whole matrices
    /// `D^n`, at order 20, to rounding.
    #[test]
    fn folded_turns_are_the_whole_matrices_sums() {
        use super::super::solid::signed;
        let p = 20;
        let lf = log_factorials(2 * p + 2);
        let v = [-0.4, 0.9, 0.25];
        let turn = Turn::new(v, p, &lf);
        let (beta, _) = angles(v);
        let terms = at(p + 1, 0);
        let values: Vec<[Complex64; LANES]> = (0..terms)
            .map(|t| {
                std::array::from_fn(|l| {
                    let x = ((t * 37 + l * 11) % 29) as f64 / 9.0 - 1.6;
                    Complex64::new(x, 0.7 * x - 0.2 * l as f64)
                })
            })
            .collect();
        let mut input = Lanes::default();
        input.fit(terms);
        for (t, v) in values.iter().enumerate() {
            input.re[t] = Word::load(&v.map(|c| c.re));
            input.im[t] = Word::load(&v.map(|c| c.im));
        }
        let (mut out, mut back, mut scratch) =
            (Lanes::default(), Lanes::default(), Lanes::default());
        turn.forward(p, &input, &mut out, &mut scratch);
        turn.back(p, &input, &mut back);
        let lane = |w: Word, l: usize| {
            let mut a = [0.0; LANES];
            w.store(&mut a);
            a[l]
        };
        for l in 0..LANES {
            let h: Vec<Complex64> = values.iter().map(|v| v[l]).collect();
            for n in 0..=p {
                let (d, w) = (full_matrix(n, beta, &lf), 2 * n as isize + 1);
                let entry =
                    |m: isize, c: isize| d[((m + n as isize) * w + c + n as isize) as usize];
                for m in 0..=n as isize {
                    let (mut want, mut want_back) =
                        (Complex64::new(0.0, 0.0), Complex64::new(0.0, 0.0));
                    for c in -(n as isize)..=n as isize {
                        want += entry(m, c) * turn.phase(c) * signed(&h, n, c);
                        want_back += entry(c, m) * signed(&h, n, c);
                    }
                    want_back *= turn.phase(m);
                    let t = at(n, m as usize);
                    let got = Complex64::new(lane(out.re[t], l), lane(out.im[t], l));
                    let got_back = Complex64::new(lane(back.re[t], l), lane(back.im[t], l));
                    assert!(
                        (got - want).norm() < 1e-12 * (1.0 + want.norm()),
                        "n {n} m {m}: {got} vs {want}"
                    );
                    assert!(
                        (got_back - want_back).norm() < 1e-12 * (1.0 + want_back.norm()),
                        "back n {n} m {m}: {got_back} vs {want_back}"
                    );
                }
            }
        }
    }

    /// A multipole of `terms` terms per lane, term `k` of lane `l` being
    /// `value(k, l)`.
    fn lane_multipoles(
        terms: usize,
        value: impl Fn(usize, usize) -> Complex64,
    ) -> Vec<Vec<Complex64>> {
        (0..LANES)
            .map(|l| (0..terms).map(|k| value(k, l)).collect())
            .collect()
    }

    /// Lanes that share a local (0, 2 and 4 into one, 1 and 5 into another,
    /// 3, 6 and 7 alone) add the bits of adding each lane's local in turn.
    #[test]
    fn shared_locals_take_their_lanes_in_order() {
        // 55 terms: the transposed blocks of four and the last three alone
        let p = 9;
        let terms = super::super::solid::terms(p);
        let multipoles = lane_multipoles(terms, |k, l| {
            Complex64::new(1.0 / (1 + k + 3 * l) as f64, -0.1 * (k as f64 - l as f64))
        });
        let translation = |l: usize| Translation {
            multipole: &multipoles[l],
            source: ([0.0, 0.0, 0.0], 0.5 + 0.01 * l as f64),
            target: ([2.0 + l as f64, 0.0, 0.0], 0.5),
        };
        let mut m2l = M2lLanes::default();
        m2l.translate(p, [1, 0, 0], LANES, translation);
        let slot = [0, 1, 0, 2, 0, 1, 3, 4];
        let mut together = vec![Complex64::new(0.3, -0.2); 5 * terms];
        m2l.add_lanes(LANES, |l| slot[l] * terms, &mut together);
        // each lane's local read from its words and added alone, lane after lane
        let mut in_turn = vec![Complex64::new(0.3, -0.2); 5 * terms];
        for (l, &k) in slot.iter().enumerate() {
            for t in 0..terms {
                let (mut re, mut im) = ([0.0; LANES], [0.0; LANES]);
                m2l.locals.re[t].store(&mut re);
                m2l.locals.im[t].store(&mut im);
                in_turn[k * terms + t] += Complex64::new(re[l], im[l]);
            }
        }
        let bits = |v: &[Complex64]| {
            v.iter()
                .map(|c| (c.re.to_bits(), c.im.to_bits()))
                .collect::<Vec<_>>()
        };
        assert_eq!(bits(&together), bits(&in_turn));
        assert!(together.iter().all(|c| *c != Complex64::new(0.3, -0.2)));
    }

    /// Eight different translations of one direction in one batch give the
    /// bits of each run alone (lanes do not see each other).
    #[test]
    fn lanes_give_the_bits_of_one_translation_alone() {
        let p = 12;
        let terms = super::super::solid::terms(p);
        let multipoles = lane_multipoles(terms, |k, l| {
            let v = ((k * 31 + l * 17) % 23) as f64 / 7.0 - 1.5;
            Complex64::new(v, 0.3 * v - 0.1 * l as f64)
        });
        // one direction (1, 2, 2), at distances and scales that differ per lane
        let translation = |l: usize| {
            let (k, scale) = (1.0 + l as f64 * 0.5, 0.4 + 0.05 * l as f64);
            Translation {
                multipole: &multipoles[l],
                source: ([0.1, -0.2, 0.3], scale),
                target: ([0.1 + k, -0.2 + 2.0 * k, 0.3 + 2.0 * k], 0.8 * scale),
            }
        };
        let mut together = M2lLanes::default();
        together.translate(p, [1, 2, 2], LANES, translation);
        for l in 0..LANES {
            let mut alone = M2lLanes::default();
            alone.translate(p, [1, 2, 2], 1, |_| translation(l));
            // (the other lanes into a second local, past the first)
            let (mut a, mut b) = (
                vec![Complex64::new(0.0, 0.0); 2 * terms],
                vec![Complex64::new(0.0, 0.0); terms],
            );
            together.add_lanes(LANES, |k| if k == l { 0 } else { terms }, &mut a);
            alone.add_lanes(1, |_| 0, &mut b);
            let bits = |v: &[Complex64]| {
                v.iter()
                    .map(|c| (c.re.to_bits(), c.im.to_bits()))
                    .collect::<Vec<_>>()
            };
            assert!(a[..terms].iter().any(|c| c.norm() > 0.0));
            assert_eq!(bits(&a[..terms]), bits(&b), "lane {l}");
        }
    }
}
