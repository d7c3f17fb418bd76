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

use super::engine::Cube;
use super::solid::at;
use crate::simd::{F64x8, Register};
use rustfft::num_complex::Complex64;
use std::collections::HashMap;

/// The SIMD word of the turns' matrices: eight rows at a time.
type Word = F64x8;

/// Rows per [`Word`].
const LANES: usize = Word::WIDTH;

/// `out[r] = sum_c block[c][r] v[c]` for the complex `v` (parts apart): the
/// block holds, for each input `c`, the outputs `r` in `words` SIMD words;
/// each word of outputs sums over the inputs in two interleaved halves, so
/// that the multiply-adds do not wait on each other.
#[inline(always)]
fn products(
    block: &[Word],
    words: usize,
    (vr, vi): (&[f64], &[f64]),
    out_re: &mut [f64],
    out_im: &mut [f64],
) {
    let inputs = vr.len();
    let zero = Word::splat(0.0);
    for j in 0..words {
        let (mut re, mut im, mut re2, mut im2) = (zero, zero, zero, zero);
        let mut c = 0;
        while c + 2 <= inputs {
            let (a, b) = (block[c * words + j], block[(c + 1) * words + j]);
            re = a.mul_add(Word::splat(vr[c]), re);
            im = a.mul_add(Word::splat(vi[c]), im);
            re2 = b.mul_add(Word::splat(vr[c + 1]), re2);
            im2 = b.mul_add(Word::splat(vi[c + 1]), im2);
            c += 2;
        }
        if c < inputs {
            let a = block[c * words + j];
            re = a.mul_add(Word::splat(vr[c]), re);
            im = a.mul_add(Word::splat(vi[c]), im);
        }
        let (mut sum_re, mut sum_im) = ([0.0; LANES], [0.0; LANES]);
        (re + re2).store(&mut sum_re);
        (im + im2).store(&mut sum_im);
        let (re, im) = (sum_re, sum_im);
        for i in 0..LANES {
            let r = LANES * j + i;
            if r < out_re.len() {
                (out_re[r], out_im[r]) = (re[i], im[i]);
            }
        }
    }
}

/// An expansion's terms `m >= 0` with their real and imaginary parts apart.
#[derive(Clone, Debug, Default)]
pub(super) struct Parts {
    re: Vec<f64>,
    im: Vec<f64>,
}

impl Parts {
    /// Zero terms for order `p`.
    fn clear(&mut self, p: usize) {
        let terms = at(p + 1, 0);
        for v in [&mut self.re, &mut self.im] {
            v.clear();
            v.resize(terms, 0.0);
        }
    }

    /// In a degree-`n` row of columns `-n..=n`: `v` at column `m >= 0` and
    /// `(-1)^m conj(v)` at `-m` (a term and its mirror).
    #[inline(always)]
    fn set_pair(&mut self, n: usize, m: usize, v: Complex64) {
        (self.re[n + m], self.im[n + m]) = (v.re, v.im);
        if m > 0 {
            let (re, im) = if m.is_multiple_of(2) {
                (v.re, -v.im)
            } else {
                (-v.re, v.im)
            };
            (self.re[n - m], self.im[n - m]) = (re, im);
        }
    }
}

/// The turn of one direction onto `+z`: the phases `e^{i m alpha}` and the
/// matrices `D^n` (rows and columns `-n..=n`), degree after degree.
#[derive(Clone, Debug)]
pub(super) struct Turn {
    phases: Vec<Complex64>,
    /// Per degree `n`, for each column `m'` (`-n..=n`) the rows `m = 0..=n`
    /// of `D^n`, [`LANES`] to a SIMD word (padded with zeros).
    forward: Vec<Word>,
    /// Per degree `n`, for each row `l` (`-n..=n`) the columns `l' = 0..=n`.
    back: Vec<Word>,
}

/// Words per column of degree `n`'s blocks: `ceil((n + 1) / LANES)`.
fn words(n: usize) -> usize {
    (n + 1).div_ceil(LANES)
}

/// Where degree `n`'s block starts: `sum_{j < n} (2j + 1) words(j)`.
fn block_start(n: usize) -> usize {
    (0..n).map(|j| (2 * j + 1) * words(j)).sum()
}

/// Where degree `n`'s matrix starts: `sum_{j < n} (2j + 1)^2`.
fn start(n: usize) -> usize {
    n * (2 * n - 1) * (2 * n + 1) / 3
}

impl Turn {
    /// The turn of the direction `v` (any length) for degrees `0..=p`.
    pub fn new(v: [f64; 3], p: usize, log_factorials: &[f64]) -> Self {
        let r = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        let beta = (v[2] / r).clamp(-1.0, 1.0).acos();
        let alpha = v[1].atan2(v[0]);
        let phases = (0..=p)
            .map(|m| Complex64::from_polar(1.0, m as f64 * alpha))
            .collect();
        let mut matrices = vec![0.0; start(p + 1)];
        for n in 0..=p {
            let w = 2 * n + 1;
            let block = &mut matrices[start(n)..start(n) + w * w];
            for (i, m) in (-(n as i64)..=n as i64).enumerate() {
                for (k, mp) in (-(n as i64)..=n as i64).enumerate() {
                    let lf = |x: i64| log_factorials[x as usize];
                    let scale = (0.5
                        * (lf(n as i64 - mp) + lf(n as i64 + mp)
                            - lf(n as i64 - m)
                            - lf(n as i64 + m)))
                    .exp();
                    let sign = if (m - mp).rem_euclid(2) == 0 {
                        1.0
                    } else {
                        -1.0
                    };
                    block[i * w + k] =
                        sign * scale * wigner_d(n as i64, m, mp, beta, log_factorials);
                }
            }
        }
        let mut forward = Vec::with_capacity(block_start(p + 1));
        let mut back = Vec::with_capacity(block_start(p + 1));
        for n in 0..=p {
            let w = 2 * n + 1;
            let d = |i: usize, k: usize| matrices[start(n) + i * w + k];
            // rows and columns m >= 0 sit from index n on
            let word = |f: &dyn Fn(usize) -> f64, j: usize| {
                let lanes: [f64; LANES] = std::array::from_fn(|i| {
                    if LANES * j + i <= n {
                        f(n + LANES * j + i)
                    } else {
                        0.0
                    }
                });
                Word::load(&lanes)
            };
            for c in 0..w {
                for j in 0..words(n) {
                    forward.push(word(&|r| d(r, c), j));
                }
            }
            for l in 0..w {
                for j in 0..words(n) {
                    back.push(word(&|c| d(l, c), j));
                }
            }
        }
        Turn {
            phases,
            forward,
            back,
        }
    }

    /// `D^n_{m m'}` for `m >= 0`.
    #[cfg(test)]
    fn get(&self, n: usize, m: isize, mp: isize) -> f64 {
        let c = (mp + n as isize) as usize;
        let word = self.forward[block_start(n) + c * words(n) + m as usize / LANES];
        let mut lanes = [0.0; LANES];
        word.store(&mut lanes);
        lanes[m as usize % LANES]
    }

    /// The multipole `a` (terms `m >= 0`) turned:
    /// `a'_n^m = sum_{m'} D^n_{m m'} e^{i m' alpha} a_n^{m'}` (the conjugate of
    /// the harmonics' turn, as a multipole holds `conj(R)`), into `out` (terms
    /// `m >= 0`, real and imaginary parts apart); `full` is scratch.
    pub fn forward(&self, p: usize, a: &[Complex64], out: &mut Parts, full: &mut Parts) {
        out.clear(p);
        // degree n's block starts where degree n - 1's ends (block_start(n))
        let mut start = 0;
        for n in 0..=p {
            let w = 2 * n + 1;
            full.re.resize(w, 0.0);
            full.im.resize(w, 0.0);
            // m' = -m from the same product: (-1)^m conj(x) conj(e) is
            // (-1)^m conj(x e) to the bit (the same products, negated)
            for m in 0..=n {
                full.set_pair(n, m, a[at(n, m)] * self.phases[m]);
            }
            let block = &self.forward[start..start + w * words(n)];
            start += w * words(n);
            let range = at(n, 0)..at(n, n) + 1;
            products(
                block,
                words(n),
                (&full.re[..w], &full.im[..w]),
                &mut out.re[range.clone()],
                &mut out.im[range],
            );
        }
    }

    /// The local `b'` of the turned frame (terms `m >= 0`) turned back and
    /// added to `local`: `b_k^{l'} += e^{i l' alpha} sum_l b'_k^l D^k_{l l'}`;
    /// `full` and `sums` are scratch.
    pub fn back(
        &self,
        p: usize,
        b: &Parts,
        local: &mut [Complex64],
        full: &mut Parts,
        sums: &mut Parts,
    ) {
        sums.clear(p);
        let mut start = 0;
        for k in 0..=p {
            let w = 2 * k + 1;
            full.re.resize(w, 0.0);
            full.im.resize(w, 0.0);
            for l in 0..=k {
                let t = at(k, l);
                full.set_pair(k, l, Complex64::new(b.re[t], b.im[t]));
            }
            let block = &self.back[start..start + w * words(k)];
            start += w * words(k);
            let range = at(k, 0)..at(k, k) + 1;
            products(
                block,
                words(k),
                (&full.re[..w], &full.im[..w]),
                &mut sums.re[range.clone()],
                &mut sums.im[range],
            );
            for lp in 0..=k {
                let t = at(k, lp);
                local[t] += Complex64::new(sums.re[t], sums.im[t]) * self.phase(lp as isize);
            }
        }
    }

    /// `e^{i m alpha}` for any `m`.
    #[inline(always)]
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
/// takes about 57 KB at order 15; a Plummer sphere of 3 x 10^5 bodies meets
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

/// The bytes of one turn of order `p` (its two blocks of SIMD words).
fn turn_bytes(p: usize) -> usize {
    2 * block_start(p + 1) * std::mem::size_of::<Word>()
}

/// A group's far pairs `(direction, target, source)`, as M2L sorts them.
pub(super) type FarPairs = Vec<([i64; 3], u32, u32)>;

/// M2L of a target group by rotation ([`m2l_turned`]) for multipoles and
/// locals of `components` expansions of order `p` each, stacked per box
/// (`components * terms(p)` numbers): for every far pair `(t, s)` of the
/// group (`far = (group, starts, sources)`, the sources of box `group + k`
/// at `sources[starts[k]..starts[k + 1]]`), each component's local of `t`
/// receives the same component's multipole of `s`. The pairs run grouped by
/// direction (then target and source), so that each turn's matrices stay in
/// the cache while they serve; the order is a function of the boxes.
/// `pairs` is scratch.
pub(super) fn m2l_by_direction(
    p: usize,
    components: usize,
    multipoles: &[Complex64],
    cubes: &[Cube],
    (group, starts, sources): (usize, &[usize], &[u32]),
    locals: &mut [Complex64],
    (pairs, turned): (&mut FarPairs, &mut TurnedM2l),
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
    for &(key, t, s) in pairs.iter() {
        let (t, s) = (t as usize, s as usize);
        let (to, from) = (cubes[t], cubes[s]);
        let source = (from.centre, from.radius);
        let target = (to.centre, to.radius);
        for c in 0..components {
            let a = &multipoles[s * stride + c * terms..][..terms];
            let local = &mut locals[(t - group) * stride + c * terms..][..terms];
            m2l_turned(p, a, source, local, target, key, turned);
        }
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
            for m in 0..=n as isize {
                let mut sum = Complex64::new(0.0, 0.0);
                for mp in -(n as isize)..=n as isize {
                    sum += signed(&h, n, mp) * turn.phase(mp).conj() * turn.get(n, m, mp);
                }
                let want = hq[at(n, m as usize)];
                assert!(
                    (sum - want).norm() < 1e-12 * (1.0 + want.norm()),
                    "n {n} m {m}: {sum} vs {want}"
                );
            }
        }
    }
}

/// What M2L by rotation keeps per thread: the turns met so far, `ln k!`,
/// `k!`, and the turned expansions.
#[derive(Debug, Default)]
pub(super) struct TurnedM2l {
    order: usize,
    turns: Turns,
    log_factorials: Vec<f64>,
    factorials: Vec<f64>,
    turned: Parts,
    shifted: Parts,
    sums: Parts,
    full: Parts,
}

impl TurnedM2l {
    fn prepare(&mut self, p: usize) {
        if self.order != p || self.factorials.is_empty() {
            *self = TurnedM2l {
                order: p,
                log_factorials: log_factorials(4 * p + 2),
                factorials: (0..=2 * p + LANES)
                    .scan(1.0, |f, k| {
                        let v = if k <= 2 * p + 1 { *f } else { 0.0 };
                        *f *= (k + 1) as f64;
                        Some(v)
                    })
                    .collect(),
                ..TurnedM2l::default()
            };
        }
    }
}

/// For `R` runs of [`LANES`] consecutive `k`, from `f[from]` on: the sums
/// `sum_i f[from + r LANES + i + lane] (re_i, im_i)` of the first `len` terms
/// of `full`, each over `i` in order; the runs' sums do not wait on each other.
#[inline(always)]
fn factorial_sums<const R: usize>(
    factorials: &[f64],
    from: usize,
    full: &Parts,
    len: usize,
) -> [(Word, Word); R] {
    let zero = Word::splat(0.0);
    let mut sums = [(zero, zero); R];
    for i in 0..len {
        let (vr, vi) = (Word::splat(full.re[i]), Word::splat(full.im[i]));
        for (r, (re, im)) in sums.iter_mut().enumerate() {
            let f = Word::load(&factorials[from + r * LANES + i..]);
            *re = f.mul_add(vr, *re);
            *im = f.mul_add(vi, *im);
        }
    }
    sums
}

/// M2L of the multipole `a` about `c` (scale `s_c`) into the local about `t`
/// (scale `s_t`), whose separation `D = t - c` has the direction `key`
/// ([`direction`]): turned so that `D` points along `+z` (`d = |D|`),
/// translated there,
///
/// `b'_k^l = (-1)^k (s_t / d)^k / d sum_{n = |l|}^{p} a'_n^{-l} (s_c / d)^n (n + k)!`
///
/// (`I_j^m(d z) = j! / d^(j + 1)` for `m = 0`, else 0), and turned back
/// (every `n, k <= p`).
#[allow(clippy::too_many_arguments)]
pub(super) fn m2l_turned(
    p: usize,
    a: &[Complex64],
    (source_centre, source_scale): ([f64; 3], f64),
    local: &mut [Complex64],
    (target_centre, target_scale): ([f64; 3], f64),
    key: [i64; 3],
    scratch: &mut TurnedM2l,
) {
    scratch.prepare(p);
    let d: [f64; 3] = std::array::from_fn(|k| target_centre[k] - source_centre[k]);
    let distance = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
    let TurnedM2l {
        turns,
        log_factorials,
        factorials,
        turned,
        shifted,
        sums,
        full,
        ..
    } = scratch;
    let turn = turns.of(key, p, log_factorials);
    turn.forward(p, a, turned, full);
    let (rho_s, rho_t) = (source_scale / distance, target_scale / distance);
    // b'_k^l for each l: the sums over n of a'_n^l (s_c / d)^n (n + k)!, LANES
    // k at a time
    shifted.clear(p);
    for l in 0..=p {
        let len = p - l + 1;
        full.re.resize(len, 0.0);
        full.im.resize(len, 0.0);
        let mut power = rho_s.powi(l as i32);
        for (i, n) in (l..=p).enumerate() {
            let t = at(n, l);
            (full.re[i], full.im[i]) = (turned.re[t] * power, turned.im[t] * power);
            power *= rho_s;
        }
        // sum_{n >= l} a'_n^l f[n + k] for LANES consecutive k in lanes (the
        // factorials are padded with zeros past 2p + 1), two such runs of k
        // at a time where there are two: four sums that do not wait on each
        // other, each over n in the same order
        let mut k = l;
        while k <= p {
            let two = k + LANES <= p;
            let (one_run, two_runs);
            let runs: &[(Word, Word)] = if two {
                two_runs = factorial_sums::<2>(factorials, l + k, full, len);
                &two_runs
            } else {
                one_run = factorial_sums::<1>(factorials, l + k, full, len);
                &one_run
            };
            for (run, &(re, im)) in runs.iter().enumerate() {
                let first = k + run * LANES;
                let (mut sum_re, mut sum_im) = ([0.0; LANES], [0.0; LANES]);
                re.store(&mut sum_re);
                im.store(&mut sum_im);
                for lane in 0..LANES.min(p + 1 - first) {
                    let t = at(first + lane, l);
                    (shifted.re[t], shifted.im[t]) = (sum_re[lane], sum_im[lane]);
                }
            }
            k += runs.len() * LANES;
        }
    }
    // a'_n^{-l} = (-1)^l conj(a'_n^l), times (-1)^k (s_t / d)^k / d
    let mut factor = 1.0 / distance;
    for k in 0..=p {
        for l in 0..=k {
            let t = at(k, l);
            let sign = if l % 2 == 0 { factor } else { -factor };
            shifted.re[t] *= sign;
            shifted.im[t] *= -sign;
        }
        factor *= -rho_t;
    }
    turn.back(p, shifted, local, full, sums);
}
