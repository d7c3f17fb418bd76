//! The solid-harmonic expansions of the 3D fast multipole method for the
//! Laplace sum `Phi(x) = sum_j q_j / |x - x_j|`.
//!
//! With the regular and irregular solid harmonics (Condon-Shortley phase,
//! `R_n^{-m} = (-1)^m conj(R_n^m)`, the same for `I`)
//!
//! `R_n^m(x) = r^n P_n^m(cos theta) e^{i m phi} / (n + m)!`,
//! `I_n^m(x) = (n - m)! P_n^m(cos theta) e^{i m phi} / r^(n + 1)`,
//!
//! `1 / |x - y| = sum_{n, m} conj(R_n^m(y)) I_n^m(x)` for `|y| < |x|`, and
//! `R_n^m(a + b) = sum_{k, l} R_k^l(a) R_{n-k}^{m-l}(b)`. Each expansion is
//! scaled by its box's radius `s`, so that no power over- or underflows:
//!
//! - multipole about `c`: `Phi(x) = sum M_n^m s^n I_n^m(x - c)`,
//!   `M_n^m = sum_j q_j conj(R_n^m((x_j - c) / s))` (P2M);
//! - local about `t`: `Phi(x) = sum L_k^l conj(R_k^l((x - t) / s))` (L2P).
//!
//! Only `m >= 0` is stored (`(p + 1)(p + 2) / 2` terms, `n <= p`); M2L (by
//! rotation, [`super::rotation`]) keeps every `n, k <= p`. Each function
//! states its own formula.

use crate::simd::{F64x8, Register};
use rustfft::num_complex::Complex64;

/// Where term `(n, m)`, `0 <= m <= n`, sits in an expansion.
#[inline(always)]
pub(super) fn at(n: usize, m: usize) -> usize {
    n * (n + 1) / 2 + m
}

/// Terms of an expansion of order `p`.
pub(super) fn terms(p: usize) -> usize {
    at(p + 1, 0)
}

/// Term `(n, m)` of `a` for any `m` (`(-1)^m conj` of `(n, -m)` below 0; 0
/// for `|m| > n`).
#[inline(always)]
pub(super) fn signed(a: &[Complex64], n: usize, m: isize) -> Complex64 {
    let k = m.unsigned_abs();
    if k > n {
        Complex64::new(0.0, 0.0)
    } else if m >= 0 {
        a[at(n, k)]
    } else if k.is_multiple_of(2) {
        a[at(n, k)].conj()
    } else {
        -a[at(n, k)].conj()
    }
}

/// `1 / ((n + m)(n - m))` at [`at`]`(n, m)` for `n <= 63` (1 where
/// `n - m < 2`): the recurrence's divisors, so that it multiplies.
fn reciprocals() -> &'static [f64] {
    static TABLE: std::sync::OnceLock<Vec<f64>> = std::sync::OnceLock::new();
    TABLE.get_or_init(|| {
        let last = super::ORDER_RANGE.1;
        let mut table = vec![1.0; at(last + 1, 0)];
        for n in 0..=last {
            for m in 0..=n {
                if n >= m + 2 {
                    table[at(n, m)] = 1.0 / ((n + m) * (n - m)) as f64;
                }
            }
        }
        table
    })
}

/// `R_n^m(v)` for `n <= p`, `m >= 0`, into `out`, by the recurrences
/// `R_m^m = -(x + i y) R_{m-1}^{m-1} / (2m)`, `R_{m+1}^m = z R_m^m`,
/// `R_n^m = ((2n - 1) z R_{n-1}^m - r^2 R_{n-2}^m) / ((n + m)(n - m))`.
pub(super) fn regular(v: [f64; 3], p: usize, out: &mut [Complex64]) {
    let [x, y, z] = v;
    let r2 = x * x + y * y + z * z;
    let w = Complex64::new(x, y);
    let inverse = reciprocals();
    let mut diagonal = Complex64::new(1.0, 0.0);
    for m in 0..=p {
        if m > 0 {
            diagonal = -w * diagonal * (0.5 / m as f64);
        }
        out[at(m, m)] = diagonal;
        if m < p {
            out[at(m + 1, m)] = z * diagonal;
        }
        for n in m + 2..=p {
            let a = (2 * n - 1) as f64 * z;
            out[at(n, m)] = (a * out[at(n - 1, m)] - r2 * out[at(n - 2, m)]) * inverse[at(n, m)];
        }
    }
}

/// Points computed together by the lane versions of [`regular`] and [`l2p`].
pub(super) const LANES: usize = F64x8::WIDTH;

/// `R_n^m` of [`LANES`] points at once (lane `i` of `v`), their real and
/// imaginary parts into `re` and `im`: the recurrences of [`regular`], each
/// lane the bits of its call (the same operations, in the same order).
pub(super) fn regular_lanes(v: [F64x8; 3], p: usize, re: &mut [F64x8], im: &mut [F64x8]) {
    let [x, y, z] = v;
    let r2 = x * x + y * y + z * z;
    let minus_one = F64x8::splat(-1.0);
    // -w = -(x + i y), negated exactly as the complex negation does
    let (nx, ny) = (x * minus_one, y * minus_one);
    let inverse = reciprocals();
    let (mut dr, mut di) = (F64x8::splat(1.0), F64x8::splat(0.0));
    for m in 0..=p {
        if m > 0 {
            let half = F64x8::splat(0.5 / m as f64);
            // (-w) * diagonal, then times 0.5 / m
            (dr, di) = ((nx * dr - ny * di) * half, (nx * di + ny * dr) * half);
        }
        (re[at(m, m)], im[at(m, m)]) = (dr, di);
        if m < p {
            (re[at(m + 1, m)], im[at(m + 1, m)]) = (z * dr, z * di);
        }
        for n in m + 2..=p {
            let a = F64x8::splat((2 * n - 1) as f64) * z;
            let c = F64x8::splat(inverse[at(n, m)]);
            let (t1, t2) = (at(n - 1, m), at(n - 2, m));
            re[at(n, m)] = (a * re[t1] - r2 * re[t2]) * c;
            im[at(n, m)] = (a * im[t1] - r2 * im[t2]) * c;
        }
    }
}

/// `I_n^m` of [`LANES`] points at once (lane `i` of `v`, none at the
/// origin), `n <= p`, `m >= 0`, by the recurrences `I_0^0 = 1 / r`,
/// `I_m^m = -(2m - 1)(x + i y) I_{m-1}^{m-1} / r^2`,
/// `I_{m+1}^m = (2m + 1) z I_m^m / r^2`,
/// `I_n^m = ((2n - 1) z I_{n-1}^m - (n + m - 1)(n - m - 1) I_{n-2}^m) / r^2`
/// (each term of the size of `I_n^m` itself, `r^-(n + 1)` times factorials).
pub(super) fn irregular_lanes(v: [F64x8; 3], p: usize, re: &mut [F64x8], im: &mut [F64x8]) {
    let [x, y, z] = v;
    let inv_r2 = F64x8::splat(1.0) / (x * x + y * y + z * z);
    let (mut dr, mut di) = (inv_r2.sqrt(), F64x8::splat(0.0));
    for m in 0..=p {
        if m > 0 {
            // -(2m - 1) (x + i y) / r^2 times the last diagonal term
            let c = F64x8::splat(-((2 * m - 1) as f64)) * inv_r2;
            (dr, di) = ((x * dr - y * di) * c, (x * di + y * dr) * c);
        }
        (re[at(m, m)], im[at(m, m)]) = (dr, di);
        if m < p {
            let c = F64x8::splat((2 * m + 1) as f64) * z * inv_r2;
            (re[at(m + 1, m)], im[at(m + 1, m)]) = (c * dr, c * di);
        }
        for n in m + 2..=p {
            let a = F64x8::splat((2 * n - 1) as f64) * z;
            let b = F64x8::splat(((n + m - 1) * (n - m - 1)) as f64);
            let (t1, t2) = (at(n - 1, m), at(n - 2, m));
            re[at(n, m)] = (a * re[t1] - b * re[t2]) * inv_r2;
            im[at(n, m)] = (a * im[t1] - b * im[t2]) * inv_r2;
        }
    }
}

/// M2P: `[dPhi/dx, dPhi/dy, dPhi/dz, Phi]` at [`LANES`] points `x` of the
/// multipole `M` (order `p`) about `c`, scale `s`, from the harmonics
/// `I_n^m(w)`, `n <= p + 1`, of [`irregular_lanes`] at `w = (x - c) / s`:
/// `Phi = sum M_n^m I_n^m(w) / s` over every `m`, and by
/// `d/dz I_n^m = -I_{n+1}^m`, `(d/dx - i d/dy) I_n^m = -I_{n+1}^{m-1}`,
/// `dPhi/dz = -sum M_n^m I_{n+1}^m / s^2` and
/// `dPhi/dx - i dPhi/dy = -sum M_n^m I_{n+1}^{m-1} / s^2`; the terms `m < 0`
/// folded onto `m > 0` (`M_n^{-m} I_k^{-l} = (-1)^(m + l) conj(M_n^m I_k^l)`).
pub(super) fn m2p_lanes(
    p: usize,
    multipole: &[Complex64],
    inv_scale: f64,
    (re, im): (&[F64x8], &[F64x8]),
) -> [F64x8; 4] {
    let zero = F64x8::splat(0.0);
    let (mut phi, mut dz, mut minus_re, mut minus_im) = (zero, zero, zero, zero);
    // Re(a b) and Im(a b) of a term of the multipole and a harmonic
    let real = |a: Complex64, t: usize| F64x8::splat(a.re) * re[t] - F64x8::splat(a.im) * im[t];
    let imaginary =
        |a: Complex64, t: usize| F64x8::splat(a.re) * im[t] + F64x8::splat(a.im) * re[t];
    let two = F64x8::splat(2.0);
    for n in 0..=p {
        let m_n = &multipole[at(n, 0)..=at(n, n)];
        let (mut twice_phi, mut twice_dz) = (zero, zero);
        for (m, a) in m_n.iter().enumerate().skip(1) {
            twice_phi = twice_phi + real(*a, at(n, m));
            twice_dz = twice_dz + real(*a, at(n + 1, m));
        }
        phi = phi + (real(m_n[0], at(n, 0)) + two * twice_phi);
        dz = dz + (real(m_n[0], at(n + 1, 0)) + two * twice_dz);
        // m >= 1 against I_{n+1}^{m-1}: a b; m = -j against I_{n+1}^{-j-1}:
        // -conj(M_n^j I_{n+1}^{j+1}), j >= 0
        for (m, a) in m_n.iter().enumerate() {
            if m >= 1 {
                minus_re = minus_re + real(*a, at(n + 1, m - 1));
                minus_im = minus_im + imaginary(*a, at(n + 1, m - 1));
            }
            minus_re = minus_re - real(*a, at(n + 1, m + 1));
            minus_im = minus_im + imaginary(*a, at(n + 1, m + 1));
        }
    }
    let inv = F64x8::splat(inv_scale);
    let inv2 = F64x8::splat(-inv_scale * inv_scale);
    [
        minus_re * inv2,
        minus_im * inv2 * F64x8::splat(-1.0),
        dz * inv2,
        phi * inv,
    ]
}

/// P2L: adds `q_i I_n^m(u_i) / s` (`n <= p`, `m >= 0`) of the first `count`
/// of [`LANES`] sources to the local about `t` (scale `s`), from the
/// harmonics of [`irregular_lanes`] at `u_i = (y_i - t) / s` and the words
/// `q / s`: `1 / |x - y| = sum conj(R_n^m(x - t)) I_n^m(y - t)`. Each term
/// adds the sources in lane order.
pub(super) fn p2l_lanes(
    p: usize,
    charges: F64x8,
    count: usize,
    (re, im): (&[F64x8], &[F64x8]),
    local: &mut [Complex64],
) {
    let (mut a, mut b) = ([0.0; LANES], [0.0; LANES]);
    for (t, l) in local[..terms(p)].iter_mut().enumerate() {
        (charges * re[t]).store(&mut a);
        (charges * im[t]).store(&mut b);
        for lane in 0..count {
            *l += Complex64::new(a[lane], b[lane]);
        }
    }
}

/// The buffers `lanes` with room for `terms` harmonics of [`LANES`] points.
pub(super) fn lanes(
    lanes: &mut (Vec<F64x8>, Vec<F64x8>),
    terms: usize,
) -> (&mut [F64x8], &mut [F64x8]) {
    for v in [&mut lanes.0, &mut lanes.1] {
        v.resize(terms, F64x8::splat(0.0));
    }
    (&mut lanes.0[..terms], &mut lanes.1[..terms])
}

/// `buffer` with `terms` zeros' room.
pub(super) fn harmonics(buffer: &mut Vec<Complex64>, terms: usize) -> &mut [Complex64] {
    buffer.resize(terms, Complex64::new(0.0, 0.0));
    &mut buffer[..terms]
}

/// A translation of expansions of order `p` from one box to another:
/// [`m2m`] or [`l2l`].
pub(super) type Shift =
    fn(usize, &[Complex64], [f64; 3], f64, &mut [Complex64], [f64; 3], f64, &mut [Complex64]);

/// `shift` of each of the expansions of order `p` stacked in `from` (about
/// the box `(from_centre, from_scale)`) added to the same one of `to`
/// (about `(to_centre, to_scale)`); `harmonics` is scratch.
pub(super) fn shift_each(
    shift: Shift,
    p: usize,
    from: &[Complex64],
    (from_centre, from_scale): ([f64; 3], f64),
    to: &mut [Complex64],
    (to_centre, to_scale): ([f64; 3], f64),
    harmonics: &mut Vec<Complex64>,
) {
    let terms = terms(p);
    let h = self::harmonics(harmonics, terms);
    for (a, b) in from.chunks_exact(terms).zip(to.chunks_exact_mut(terms)) {
        shift(p, a, from_centre, from_scale, b, to_centre, to_scale, h);
    }
}

/// P2M: adds `M_n^m += q conj(R_n^m((x - c) / s))` for each source `(x, q)`.
pub(super) fn p2m(
    p: usize,
    sources: impl Iterator<Item = ([f64; 3], f64)>,
    centre: [f64; 3],
    scale: f64,
    harmonics: &mut [Complex64],
    multipole: &mut [Complex64],
) {
    let inv = 1.0 / scale;
    for (x, q) in sources {
        let v = std::array::from_fn(|a| (x[a] - centre[a]) * inv);
        regular(v, p, harmonics);
        for (m, r) in multipole.iter_mut().zip(harmonics.iter()) {
            *m += q * r.conj();
        }
    }
}

/// M2M: adds the child's multipole (about `c`, scale `s`) shifted to the
/// parent's centre `c'` and scale `s'`:
/// `M'_n^m += sum_{k <= n, l} M_k^l (s / s')^k conj(R_{n-k}^{m-l}((c - c') / s'))`.
#[allow(clippy::too_many_arguments)]
pub(super) fn m2m(
    p: usize,
    child: &[Complex64],
    child_centre: [f64; 3],
    child_scale: f64,
    parent: &mut [Complex64],
    parent_centre: [f64; 3],
    parent_scale: f64,
    harmonics: &mut [Complex64],
) {
    let inv = 1.0 / parent_scale;
    let shift = std::array::from_fn(|a| (child_centre[a] - parent_centre[a]) * inv);
    regular(shift, p, harmonics);
    let ratio = child_scale / parent_scale;
    for n in 0..=p {
        for m in 0..=n {
            let mut sum = Complex64::new(0.0, 0.0);
            let mut power = 1.0;
            for k in 0..=n {
                let j = n - k;
                let (lo, hi) = ((m as isize - j as isize).max(-(k as isize)), (m + j).min(k));
                for l in lo..=hi as isize {
                    let r = signed(harmonics, j, m as isize - l).conj();
                    sum += signed(child, k, l) * r * power;
                }
                power *= ratio;
            }
            parent[at(n, m)] += sum;
        }
    }
}

/// L2L: adds the parent's local (about `t`, scale `s`) shifted to the
/// child's centre `t'` and scale `s'`:
/// `L'_j^i += (s' / s)^j sum_{k >= j, l} L_k^l conj(R_{k-j}^{l-i}((t' - t) / s))`.
#[allow(clippy::too_many_arguments)]
pub(super) fn l2l(
    p: usize,
    parent: &[Complex64],
    parent_centre: [f64; 3],
    parent_scale: f64,
    child: &mut [Complex64],
    child_centre: [f64; 3],
    child_scale: f64,
    harmonics: &mut [Complex64],
) {
    let inv = 1.0 / parent_scale;
    let shift = std::array::from_fn(|a| (child_centre[a] - parent_centre[a]) * inv);
    regular(shift, p, harmonics);
    let ratio = child_scale / parent_scale;
    let mut power = 1.0;
    for j in 0..=p {
        for i in 0..=j {
            let mut sum = Complex64::new(0.0, 0.0);
            for k in j..=p {
                let d = k - j;
                let (lo, hi) = ((i as isize - d as isize).max(-(k as isize)), (i + d).min(k));
                for l in lo..=hi as isize {
                    let r = signed(harmonics, d, l - i as isize).conj();
                    sum += signed(parent, k, l) * r;
                }
            }
            child[at(j, i)] += sum * power;
        }
        power *= ratio;
    }
}

/// L2P: `[dPhi/dx, dPhi/dy, dPhi/dz, Phi]` of the local about `t` (scale
/// `s`) at `x`: with `w = (x - t) / s`, `Phi = sum L_k^l conj(R_k^l(w))`,
/// `dPhi/dz = sum L_k^l conj(R_{k-1}^l(w)) / s` and
/// `dPhi/dx - i dPhi/dy = sum L_k^l conj(R_{k-1}^{l+1}(w)) / s`
/// (`d/dz R_n^m = R_{n-1}^m`, `(d/dx + i d/dy) R_n^m = R_{n-1}^{m+1}`), the
/// sums over `l < 0` folded onto `l > 0` by the symmetry of both: the terms
/// `l` and `-l` of the first two are conjugates, and the third's `l = -j` is
/// `-conj(L_k^j) R_{k-1}^{j-1}`.
pub(super) fn l2p(
    p: usize,
    local: &[Complex64],
    centre: [f64; 3],
    scale: f64,
    x: [f64; 3],
    harmonics: &mut [Complex64],
) -> [f64; 4] {
    let inv = 1.0 / scale;
    let w = std::array::from_fn(|a| (x[a] - centre[a]) * inv);
    regular(w, p, harmonics);
    let (mut phi, mut dz, mut minus) = (0.0, 0.0, Complex64::new(0.0, 0.0));
    // the real part of a conj(b)
    let dot = |a: Complex64, b: Complex64| a.re * b.re + a.im * b.im;
    for k in 0..=p {
        let l_k = &local[at(k, 0)..=at(k, k)];
        let r_k = &harmonics[at(k, 0)..=at(k, k)];
        let mut twice = 0.0;
        for (a, b) in l_k[1..].iter().zip(&r_k[1..]) {
            twice += dot(*a, *b);
        }
        phi += dot(l_k[0], r_k[0]) + 2.0 * twice;
        if k == 0 {
            continue;
        }
        let r_below = &harmonics[at(k - 1, 0)..=at(k - 1, k - 1)];
        let mut twice = 0.0;
        for (a, b) in l_k[1..k].iter().zip(&r_below[1..]) {
            twice += dot(*a, *b);
        }
        dz += dot(l_k[0], r_below[0]) + 2.0 * twice;
        // l >= 0 against R_{k-1}^{l+1}, and l = -j against R_{k-1}^{j-1}
        for (a, b) in l_k.iter().zip(&r_below[1..]) {
            minus += a * b.conj();
        }
        for (a, b) in l_k[1..].iter().zip(r_below) {
            minus -= a.conj() * b;
        }
    }
    [minus.re * inv, -minus.im * inv, dz * inv, phi]
}

/// [`l2p`] at [`LANES`] points at once (lane `i` of `x`), from their
/// harmonics `(re, im)` of [`regular_lanes`] at `w = (x - t) / s`: each lane
/// the bits of its call.
pub(super) fn l2p_lanes(
    p: usize,
    local: &[Complex64],
    inv_scale: f64,
    (re, im): (&[F64x8], &[F64x8]),
) -> [F64x8; 4] {
    let zero = F64x8::splat(0.0);
    let (mut phi, mut dz, mut minus_re, mut minus_im) = (zero, zero, zero, zero);
    // the real part of a conj(b), a the local's term and b a harmonic's
    let dot = |a: Complex64, t: usize| F64x8::splat(a.re) * re[t] + F64x8::splat(a.im) * im[t];
    let two = F64x8::splat(2.0);
    for k in 0..=p {
        let l_k = &local[at(k, 0)..=at(k, k)];
        let mut twice = zero;
        for (j, a) in l_k.iter().enumerate().skip(1) {
            twice = twice + dot(*a, at(k, j));
        }
        phi = phi + (dot(l_k[0], at(k, 0)) + two * twice);
        if k == 0 {
            continue;
        }
        let mut twice = zero;
        for (j, a) in l_k[..k].iter().enumerate().skip(1) {
            twice = twice + dot(*a, at(k - 1, j));
        }
        dz = dz + (dot(l_k[0], at(k - 1, 0)) + two * twice);
        // l >= 0 against R_{k-1}^{l+1}: a conj(b)
        for (j, a) in l_k[..k - 1].iter().enumerate() {
            let (ar, ai) = (F64x8::splat(a.re), F64x8::splat(a.im));
            let t = at(k - 1, j + 1);
            minus_re = minus_re + (ar * re[t] + ai * im[t]);
            minus_im = minus_im + (ai * re[t] - ar * im[t]);
        }
        // l = -j against R_{k-1}^{j-1}: minus conj(a) b
        for (j, a) in l_k.iter().enumerate().skip(1) {
            let (ar, ai) = (F64x8::splat(a.re), F64x8::splat(a.im));
            let t = at(k - 1, j - 1);
            minus_re = minus_re - (ar * re[t] + ai * im[t]);
            minus_im = minus_im - (ar * im[t] - ai * re[t]);
        }
    }
    let inv = F64x8::splat(inv_scale);
    [
        minus_re * inv,
        minus_im * F64x8::splat(-1.0) * inv,
        dz * inv,
        phi,
    ]
}

#[cfg(test)]
mod tests {
    use super::super::rotation::{direction, M2lLanes, Translation};
    use super::*;
    use crate::random::Rng;

    fn cloud(rng: &mut Rng, centre: [f64; 3], half: f64, n: usize) -> Vec<([f64; 3], f64)> {
        (0..n)
            .map(|_| {
                let x = std::array::from_fn(|a| centre[a] + half * (2.0 * rng.uniform() - 1.0));
                (x, rng.uniform() - 0.3)
            })
            .collect()
    }

    /// `[grad Phi, Phi]` by brute force, written out here.
    fn direct(sources: &[([f64; 3], f64)], x: [f64; 3]) -> [f64; 4] {
        let mut f = [0.0; 4];
        for &(y, q) in sources {
            let d = [y[0] - x[0], y[1] - x[1], y[2] - x[2]];
            let r = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
            for a in 0..3 {
                f[a] += q * d[a] / (r * r * r);
            }
            f[3] += q / r;
        }
        f
    }

    fn relative(got: [f64; 4], want: [f64; 4]) -> (f64, f64) {
        let norm = |v: &[f64]| v.iter().map(|x| x * x).sum::<f64>().sqrt();
        let e: Vec<f64> = (0..4).map(|a| got[a] - want[a]).collect();
        (norm(&e[..3]) / norm(&want[..3]), e[3].abs() / want[3].abs())
    }

    /// The lanes' words of coordinate `a` of `points` less `centre`, over
    /// `scale` (lanes past the points: the last one again).
    fn scaled_lanes(points: &[[f64; 3]], centre: [f64; 3], scale: f64) -> [F64x8; 3] {
        std::array::from_fn(|a| {
            let lane: [f64; LANES] =
                std::array::from_fn(|i| (points[i.min(points.len() - 1)][a] - centre[a]) / scale);
            F64x8::load(&lane)
        })
    }

    /// The irregular harmonics' recurrences against the module's
    /// definition by the regular ones, `I_n^m = (n - m)! (n + m)! R_n^m /
    /// r^(2n + 1)`, at order 20, near and far from the origin.
    #[test]
    fn irregular_harmonics_are_the_regular_ones_inverted() {
        let p = 20;
        let points: [[f64; 3]; LANES] = [
            [0.3, -0.4, 0.5],
            [1.0, 0.0, 0.0],
            [0.0, 0.0, -2.0],
            [-3.0, 1.5, 0.2],
            [0.05, 0.02, -0.01],
            [7.0, -8.0, 9.0],
            [0.0, 1.0, 1.0],
            [-0.5, -0.5, -0.5],
        ];
        let (mut re, mut im) = (
            vec![F64x8::splat(0.0); terms(p)],
            vec![F64x8::splat(0.0); terms(p)],
        );
        irregular_lanes(scaled_lanes(&points, [0.0; 3], 1.0), p, &mut re, &mut im);
        let factorial = |k: usize| (1..=k).map(|j| j as f64).product::<f64>();
        let mut h = vec![Complex64::new(0.0, 0.0); terms(p)];
        for (i, x) in points.iter().enumerate() {
            regular(*x, p, &mut h);
            let r = (x[0] * x[0] + x[1] * x[1] + x[2] * x[2]).sqrt();
            for n in 0..=p {
                for m in 0..=n {
                    let t = at(n, m);
                    let want =
                        h[t] * factorial(n - m) * factorial(n + m) / r.powi(2 * n as i32 + 1);
                    let lane = |v: F64x8| {
                        let mut l = [0.0; LANES];
                        v.store(&mut l);
                        l[i]
                    };
                    let got = Complex64::new(lane(re[t]), lane(im[t]));
                    assert!(
                        (got - want).norm() <= 1e-12 * want.norm().max(1e-300),
                        "point {i} n {n} m {m}: {got} vs {want}"
                    );
                }
            }
        }
    }

    /// M2P of P2M's multipole at eight targets, and P2L of the sources
    /// (eight and three at a time) read out by L2P, against the direct sum:
    /// within `10 rho^(p + 1)` for the ratio `rho` of the sources' and the
    /// targets' spread to their distance, and falling with the order (which
    /// checks the irregular harmonics' derivatives that M2P takes).
    #[test]
    fn m2p_and_p2l_converge_to_the_direct_sum() {
        let mut rng = Rng::new(5);
        let (c, t) = ([0.1, -0.2, 0.3], [1.3, 0.6, -0.4]);
        // sources within 0.25 sqrt(3) of c, targets within 0.15 sqrt(3) of t
        let sources = cloud(&mut rng, c, 0.25, 11);
        let targets: Vec<[f64; 3]> = cloud(&mut rng, t, 0.15, LANES)
            .into_iter()
            .map(|(x, _)| x)
            .collect();
        let zero = F64x8::splat(0.0);
        let mut last = (f64::INFINITY, f64::INFINITY);
        for p in [2, 5, 8, 11, 14] {
            let (s_c, s_t) = (0.45, 0.3);
            let mut h = vec![Complex64::new(0.0, 0.0); terms(p + 1)];
            let mut multipole = vec![Complex64::new(0.0, 0.0); terms(p)];
            p2m(p, sources.iter().copied(), c, s_c, &mut h, &mut multipole);
            let (mut re, mut im) = (vec![zero; terms(p + 1)], vec![zero; terms(p + 1)]);
            irregular_lanes(scaled_lanes(&targets, c, s_c), p + 1, &mut re, &mut im);
            let by_m2p = m2p_lanes(p, &multipole, 1.0 / s_c, (&re, &im));
            let mut local = vec![Complex64::new(0.0, 0.0); terms(p)];
            for chunk in sources.chunks(LANES) {
                let points: Vec<[f64; 3]> = chunk.iter().map(|&(y, _)| y).collect();
                irregular_lanes(scaled_lanes(&points, t, s_t), p, &mut re, &mut im);
                let q: [f64; LANES] =
                    std::array::from_fn(|i| chunk.get(i).map_or(0.0, |&(_, q)| q / s_t));
                p2l_lanes(p, F64x8::load(&q), chunk.len(), (&re, &im), &mut local);
            }
            let mut worst = (0.0f64, 0.0f64);
            for (i, &x) in targets.iter().enumerate() {
                let lane = |v: F64x8| {
                    let mut l = [0.0; LANES];
                    v.store(&mut l);
                    l[i]
                };
                let want = direct(&sources, x);
                let m2p_error = relative(by_m2p.map(lane), want);
                let p2l_error = relative(l2p(p, &local, t, s_t, x, &mut h), want);
                worst = (
                    worst.0.max(m2p_error.0).max(m2p_error.1),
                    worst.1.max(p2l_error.0).max(p2l_error.1),
                );
            }
            // |y - c| <= 0.44 and |x - c| >= 1.5 - 0.26; |x - t| <= 0.26 and
            // |y - t| >= 1.5 - 0.44
            let bound = |rho: f64| 10.0 * rho.powi(p as i32 + 1);
            eprintln!("p {p}: m2p {:e}, p2l {:e}", worst.0, worst.1);
            assert!(
                worst.0 < bound(0.44 / 1.24) && worst.1 < bound(0.26 / 1.06),
                "p {p}: {worst:?}"
            );
            assert!(worst.0 < last.0 && worst.1 < last.1, "p {p}: {worst:?}");
            last = worst;
        }
    }

    /// Eight points at once give each point's bits of `regular` and `l2p`,
    /// at orders 0 to 20, points near and far from the centre (the origin
    /// and the scale's corners among them).
    #[test]
    fn lanes_give_the_bits_of_single_points() {
        let mut rng = Rng::new(11);
        let bits = |c: Complex64| (c.re.to_bits(), c.im.to_bits());
        for p in [0, 1, 2, 7, 15, 20] {
            let mut points: [[f64; 3]; LANES] =
                std::array::from_fn(|_| std::array::from_fn(|_| 2.0 * rng.uniform() - 1.0));
            points[0] = [0.0; 3];
            points[1] = [1.0, -1.0, 1.0];
            let local: Vec<Complex64> = (0..terms(p))
                .map(|_| Complex64::new(rng.uniform() - 0.5, rng.uniform() - 0.5))
                .collect();
            let (centre, scale) = ([0.1, -0.2, 0.3], 0.7);
            let inv = 1.0 / scale;
            let w: [F64x8; 3] = std::array::from_fn(|a| {
                let lane: [f64; LANES] = std::array::from_fn(|i| (points[i][a] - centre[a]) * inv);
                F64x8::load(&lane)
            });
            let zero = F64x8::splat(0.0);
            let (mut re, mut im) = (vec![zero; terms(p)], vec![zero; terms(p)]);
            regular_lanes(w, p, &mut re, &mut im);
            let got = l2p_lanes(p, &local, inv, (&re, &im));
            let mut h = vec![Complex64::new(0.0, 0.0); terms(p)];
            for (i, x) in points.iter().enumerate() {
                let lane = |v: F64x8| {
                    let mut l = [0.0; LANES];
                    v.store(&mut l);
                    l[i]
                };
                let v = std::array::from_fn(|a| (x[a] - centre[a]) * inv);
                regular(v, p, &mut h);
                for t in 0..terms(p) {
                    assert_eq!(
                        bits(Complex64::new(lane(re[t]), lane(im[t]))),
                        bits(h[t]),
                        "p {p} point {i} term {t}"
                    );
                }
                let want = l2p(p, &local, centre, scale, *x, &mut h);
                for a in 0..4 {
                    assert_eq!(
                        lane(got[a]).to_bits(),
                        want[a].to_bits(),
                        "p {p} point {i} part {a}"
                    );
                }
            }
        }
    }

    /// Every step of the chain P2M, M2M, M2L (by rotation, the same source
    /// twice, halved), L2L, L2P against the direct sum, at orders 8 and 16: potential and
    /// field errors fall with the order, near the ratio of radius to
    /// distance to the power `p + 1`.
    #[test]
    fn the_chain_converges_with_the_order() {
        let mut rng = Rng::new(3);
        let (parent_c, child_c) = ([0.0, 0.0, 0.0], [0.25, -0.25, 0.25]);
        let (target_c, leaf_c) = ([4.0, 1.0, -0.5], [3.75, 1.25, -0.25]);
        let sources = cloud(&mut rng, child_c, 0.25, 40);
        let targets: Vec<[f64; 3]> = cloud(&mut rng, leaf_c, 0.25, 20)
            .into_iter()
            .map(|t| t.0)
            .collect();
        let (s_parent, s_child) = (0.5 * 3f64.sqrt(), 0.25 * 3f64.sqrt());
        let mut last = (f64::INFINITY, f64::INFINITY);
        for p in [8, 16] {
            let zero = vec![Complex64::new(0.0, 0.0); terms(p)];
            let mut h = zero.clone();
            let mut child = zero.clone();
            p2m(
                p,
                sources.iter().copied(),
                child_c,
                s_child,
                &mut h,
                &mut child,
            );
            let mut parent = zero.clone();
            m2m(
                p,
                &child,
                child_c,
                s_child,
                &mut parent,
                parent_c,
                s_parent,
                &mut h,
            );
            // the same source twice, halved: their sum is the whole
            let half: Vec<Complex64> = parent.iter().map(|c| c * 0.5).collect();
            let mut local = zero.clone();
            let mut m2l = M2lLanes::default();
            let d = std::array::from_fn(|a| target_c[a] - parent_c[a]);
            // two lanes of one batch, added one after the other
            m2l.translate(p, direction(d, 1.0), 2, |_| Translation {
                multipole: &half,
                source: (parent_c, s_parent),
                target: (target_c, s_parent),
            });
            m2l.add_lanes(2, |_| 0, &mut local);
            let mut leaf = zero.clone();
            l2l(
                p, &local, target_c, s_parent, &mut leaf, leaf_c, s_child, &mut h,
            );
            let worst = targets.iter().fold((0.0f64, 0.0f64), |w, &x| {
                let e = relative(
                    l2p(p, &leaf, leaf_c, s_child, x, &mut h),
                    direct(&sources, x),
                );
                (w.0.max(e.0), w.1.max(e.1))
            });
            // the ratio of the radii to the distance, 0.87 / (4.1 - 0.87)
            let bound = 10.0 * 0.27f64.powi(p as i32 + 1);
            eprintln!(
                "p {p}: worst field {:e}, potential {:e} (bound {bound:e})",
                worst.0, worst.1
            );
            assert!(worst.0 < bound && worst.1 < bound, "p {p}: {worst:?}");
            assert!(worst.0 < last.0 && worst.1 < last.1);
            last = worst;
        }
    }
}
