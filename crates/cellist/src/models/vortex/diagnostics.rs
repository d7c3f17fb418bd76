//! The invariants and moments of a set of 2D vortex blobs (circulations
//! `Gamma_i` at `x_i`, Gaussian cores `sigma`):
//!
//! ```text
//! circulation       Gamma = sum_i Gamma_i
//! linear impulse    I = (sum_i Gamma_i y_i, -sum_i Gamma_i x_i)
//! angular impulse   A = sum_i Gamma_i |x_i|^2          (without the blob term 2 sigma^2 Gamma)
//! energy            E = -1/(8 pi) sum_i sum_j Gamma_i Gamma_j [ln r_ij^2 + E1(r_ij^2 / (4 sigma^2))]
//! enstrophy         Z = sum_i sum_j Gamma_i Gamma_j exp(-r_ij^2 / (4 sigma^2)) / (4 pi sigma^2)
//! ```
//!
//! `E = 1/2 int psi w` and `Z = int w^2` of the blob field `w = sum_j Gamma_j
//! zeta_sigma(x - x_j)`: two Gaussians of variance `sigma^2` overlap as one of
//! variance `2 sigma^2`, whose stream function is
//! `-(1 / 4 pi) [ln r^2 + E1(r^2 / 4 sigma^2)]`. With a nonzero total
//! circulation the energy of the unbounded plane diverges logarithmically; `E` is
//! its finite part, lengths in the scenario's unit. The pair sums cost `O(N^2)`
//! and run only when a thermo row is due.

use crate::longrange::Exchange;
use crate::threads::Threads;
use rayon::prelude::*;
use std::f64::consts::PI;

/// Beyond this `x`, `E1(x) < exp(-x) / x < 1e-19` is left out (and the
/// enstrophy's `exp(-x)` with it).
const FAR: f64 = 40.0;

/// Euler's constant.
const EULER_GAMMA: f64 = 0.577_215_664_901_532_9;

/// `ln(r^2) + E1(r^2 / (4 sigma^2))` with `x = r^2 / (4 sigma^2)`, given `ln(4 sigma^2)`:
/// the series `ln(4 sigma^2) - gamma + sum_k (-1)^(k+1) x^k / (k k!)` for `x <= 1`
/// (finite at `r = 0`), the continued fraction of `E1` above, and `ln(r^2)`
/// alone beyond `x = 40`.
pub fn log_plus_e1(x: f64, ln_four_sigma2: f64) -> f64 {
    if x <= 1.0 {
        let mut term = 1.0;
        let mut sum = 0.0;
        for k in 1..=30 {
            term *= -x / k as f64;
            let add = -term / k as f64;
            sum += add;
            if add.abs() < 1e-17 * sum.abs().max(1e-300) {
                break;
            }
        }
        ln_four_sigma2 - EULER_GAMMA + sum
    } else {
        let log = x.ln() + ln_four_sigma2;
        if x > FAR {
            return log;
        }
        // E1(x) = exp(-x) / (x + 1 / (1 + 1 / (x + 2 / (1 + 2 / (x + ...))))), by
        // the modified Lentz method on the even form x + 1 - 1/(x + 3 - 4/(x + 5 - ...))
        let tiny = 1e-300;
        let mut b = x + 1.0;
        let mut c = 1.0 / tiny;
        let mut d = 1.0 / b;
        let mut h = d;
        for i in 1..200 {
            let a = -((i * i) as f64);
            b += 2.0;
            d = 1.0 / (a * d + b);
            c = b + a / c;
            let delta = c * d;
            h *= delta;
            if (delta - 1.0).abs() < 1e-16 {
                break;
            }
        }
        log + h * (-x).exp()
    }
}

/// The moments of the particles that need no pairs.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Moments {
    /// `sum Gamma_i`.
    pub circulation: f64,
    /// `(sum Gamma_i y_i, -sum Gamma_i x_i)`.
    pub impulse: [f64; 2],
    /// `sum Gamma_i |x_i|^2`.
    pub angular_impulse: f64,
    /// `sum Gamma_i (x - x_c)(x - x_c)^T` as `[xx, xy, yy]`, about the centroid
    /// `x_c = sum Gamma_i x_i / Gamma`.
    pub second: [f64; 3],
}

impl Moments {
    /// The moments of `positions` and `gamma`, summed in order.
    pub fn of(positions: &[[f64; 2]], gamma: &[f64]) -> Self {
        let mut m = Moments::default();
        let mut first = [0.0; 2];
        for (x, &g) in positions.iter().zip(gamma) {
            m.circulation += g;
            first[0] += g * x[0];
            first[1] += g * x[1];
            m.angular_impulse += g * (x[0] * x[0] + x[1] * x[1]);
        }
        m.impulse = [first[1], -first[0]];
        let c = [first[0] / m.circulation, first[1] / m.circulation];
        for (x, &g) in positions.iter().zip(gamma) {
            let d = [x[0] - c[0], x[1] - c[1]];
            m.second[0] += g * d[0] * d[0];
            m.second[1] += g * d[0] * d[1];
            m.second[2] += g * d[1] * d[1];
        }
        m
    }

    /// The aspect ratio `sqrt(l_max / l_min)` of the second-moment tensor and the
    /// angle of its major axis from x, in `(-pi/2, pi/2]`.
    /// The tensor is taken with the sign of the circulation, so that a negative
    /// vortex has the same axes as its positive mirror.
    pub fn ellipse(&self) -> (f64, f64) {
        let sign = self.circulation.signum();
        let [a, b, c] = self.second.map(|m| sign * m);
        let mean = 0.5 * (a + c);
        let spread = (0.25 * (a - c) * (a - c) + b * b).sqrt();
        let (major, minor) = (mean + spread, mean - spread);
        let angle = 0.5 * (2.0 * b).atan2(a - c);
        ((major / minor).abs().sqrt(), angle)
    }
}

/// `(E, Z)`: the energy and enstrophy pair sums, each pair once (`j > i`) plus
/// the diagonal, row by row, the rows added in order: the same bits for any
/// thread count and any number of ranks. On the ranks of `peers` (every one
/// holding every particle and calling this together) rank `r` of `P` sums the
/// rows `i` with `i mod P = r` (row `i` holds `N - 1 - i` pairs, so the ranks'
/// shares differ by at most `N` pairs) and the rows' sums are all-gathered;
/// every rank then adds them in row order as one process does.
pub fn energy_and_enstrophy(
    positions: &[[f64; 2]],
    gamma: &[f64],
    sigma: f64,
    threads: &Threads,
    peers: &dyn Exchange,
) -> (f64, f64) {
    let four_sigma2 = 4.0 * sigma * sigma;
    let ln4s2 = four_sigma2.ln();
    let inv = 1.0 / four_sigma2;
    // particles without circulation add exact zeros: leave them out
    let (positions, gamma): (Vec<[f64; 2]>, Vec<f64>) = positions
        .iter()
        .zip(gamma)
        .filter(|(_, g)| **g != 0.0)
        .map(|(x, g)| (*x, *g))
        .unzip();
    let row = |i: usize| {
        let (xi, gi) = (positions[i], gamma[i]);
        let mut e = 0.5 * gi * gi * log_plus_e1(0.0, ln4s2);
        let mut z = 0.5 * gi * gi;
        for j in i + 1..positions.len() {
            let d = [positions[j][0] - xi[0], positions[j][1] - xi[1]];
            let x = (d[0] * d[0] + d[1] * d[1]) * inv;
            let gg = gi * gamma[j];
            e += gg * log_plus_e1(x, ln4s2);
            if x <= FAR {
                z += gg * (-x).exp();
            }
        }
        [e, z]
    };
    let n = positions.len();
    let (rank, count) = (peers.rank(), peers.ranks());
    let mine: Vec<f64> = threads.install(|| {
        (rank..n)
            .into_par_iter()
            .step_by(count)
            .flat_map_iter(row)
            .collect()
    });
    // rank r's rows r, r + P, .., and where its block starts among the gathered
    let counts: Vec<usize> = (0..count).map(|r| 2 * rank_rows(n, r, count)).collect();
    let starts: Vec<usize> = counts
        .iter()
        .scan(0, |start, &c| {
            let s = *start;
            *start += c;
            Some(s)
        })
        .collect();
    let mut rows = vec![0.0; 2 * n];
    peers.all_gather(&mine, &counts, &mut rows);
    let (e, z) = (0..n)
        .map(|i| &rows[starts[i % count] + 2 * (i / count)..][..2])
        .fold((0.0, 0.0), |(e, z), r| (e + r[0], z + r[1]));
    (-e / (4.0 * PI), z * 2.0 / (PI * four_sigma2))
}

/// How many of the rows `0..n` are `r, r + P, ..` (rank `r` of `P`).
fn rank_rows(n: usize, r: usize, ranks: usize) -> usize {
    n.saturating_sub(r).div_ceil(ranks)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::longrange::Alone;

    #[test]
    fn log_plus_e1_is_continuous_and_matches_the_tail() {
        let ln = 0.7f64;
        let below = log_plus_e1(1.0, ln);
        let above = log_plus_e1(1.0 + 1e-12, ln);
        assert!((below - above).abs() < 1e-11, "{below} {above}");
        // E1(5) = 0.001148295591275326
        let e1_5 = log_plus_e1(5.0, 0.0) - 5f64.ln();
        assert!((e1_5 - 0.001_148_295_591_275_326).abs() < 1e-15);
        // E1(0.5) = 0.5597735947761608
        let e1_half = log_plus_e1(0.5, 0.0) - 0.5f64.ln();
        assert!((e1_half - 0.559_773_594_776_160_8).abs() < 1e-15);
    }

    #[test]
    fn one_blob_has_the_enstrophy_of_its_gaussian() {
        // Z = Gamma^2 / (4 pi sigma^2) for one blob
        let (_, z) = energy_and_enstrophy(&[[0.3, 0.1]], &[2.0], 0.5, &Threads::single(), &Alone);
        assert!((z - 4.0 / (4.0 * PI * 0.25)).abs() < 1e-14);
    }

    /// The pair sums over every ordered pair `i != j` halved, plus the
    /// diagonal, one term at a time: the reference of the row sums.
    fn every_ordered_pair(x: &[[f64; 2]], gamma: &[f64], sigma: f64) -> (f64, f64) {
        let s2 = 4.0 * sigma * sigma;
        let (mut e, mut z) = (0.0, 0.0);
        for i in 0..x.len() {
            for j in 0..x.len() {
                let r2 = (x[i][0] - x[j][0]).powi(2) + (x[i][1] - x[j][1]).powi(2);
                let gg = 0.5 * gamma[i] * gamma[j];
                e += gg * log_plus_e1(r2 / s2, s2.ln());
                z += gg * (-r2 / s2).exp();
            }
        }
        (-e / (4.0 * PI), z * 2.0 / (PI * s2))
    }

    #[test]
    fn the_rows_dealt_to_ranks_give_one_process_bits() {
        use crate::longrange::mesh::slab::testkit::Hub;
        use crate::random::Rng;
        for n in [0, 1, 3, 157] {
            let mut rng = Rng::new(n as u64 + 5);
            let x: Vec<[f64; 2]> = (0..n).map(|_| [rng.uniform(), rng.uniform()]).collect();
            // some particles without circulation, which the sums leave out
            let gamma: Vec<f64> = (0..n)
                .map(|i| if i % 7 == 3 { 0.0 } else { rng.normal() })
                .collect();
            let sigma = 0.05;
            let alone = energy_and_enstrophy(&x, &gamma, sigma, &Threads::single(), &Alone);
            let (e, z) = every_ordered_pair(&x, &gamma, sigma);
            assert!(
                (alone.0 - e).abs() <= 1e-12 * e.abs().max(1e-300),
                "{alone:?} {e}"
            );
            assert!(
                (alone.1 - z).abs() <= 1e-12 * z.abs().max(1e-300),
                "{alone:?} {z}"
            );
            for ranks in 1..=4 {
                for threads in [1, 2] {
                    let got = Hub::run(ranks, |exchange| {
                        let t = Threads::new(threads).unwrap();
                        energy_and_enstrophy(&x, &gamma, sigma, &t, exchange)
                    });
                    for g in got {
                        assert_eq!(g.0.to_bits(), alone.0.to_bits(), "n {n}, {ranks} ranks");
                        assert_eq!(g.1.to_bits(), alone.1.to_bits(), "n {n}, {ranks} ranks");
                    }
                }
            }
        }
    }

    #[test]
    fn the_moments_of_two_points() {
        let m = Moments::of(&[[1.0, 0.0], [-1.0, 0.0]], &[1.0, 1.0]);
        assert_eq!(m.circulation, 2.0);
        assert_eq!(m.impulse, [0.0, 0.0]);
        assert_eq!(m.angular_impulse, 2.0);
        assert_eq!(m.second, [2.0, 0.0, 0.0]);
        let (_, angle) = m.ellipse();
        assert_eq!(angle, 0.0);
    }
}
