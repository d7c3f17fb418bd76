//! Blobs for the tests of the 3D vortex solvers: a random cloud, a vortex
//! ring on a lattice, and the comparisons of their fields.

use crate::longrange::biot_savart3::BlobKernel3;
use crate::random::Rng;

/// `n` blobs uniformly in the unit cube with random strengths of either
/// sign, `sigma = 1.5 h`, `h = n^(-1/3)` the mean spacing.
pub(crate) fn cloud(seed: u64, n: usize) -> (Vec<[f64; 3]>, Vec<[f64; 3]>, BlobKernel3) {
    let mut rng = Rng::new(seed);
    let h = (n as f64).cbrt().recip();
    let x = (0..n)
        .map(|_| std::array::from_fn(|_| rng.uniform()))
        .collect();
    let alpha = (0..n)
        .map(|_| std::array::from_fn(|_| (rng.uniform() - 0.5) * h * h * h))
        .collect();
    (x, alpha, BlobKernel3::new(1.5 * h))
}

/// A vortex ring of radius 1 and Gaussian core `a = 0.2` (circulation 1)
/// seeded on the lattice of spacing `h` within `3 a` of its centre line,
/// `alpha = omega h^3`, `sigma = 1.5 h`.
pub(crate) fn ring(h: f64) -> (Vec<[f64; 3]>, Vec<[f64; 3]>, BlobKernel3) {
    let a = 0.2;
    let cells = (1.6 / h).ceil() as i64;
    let (mut x, mut alpha) = (Vec::new(), Vec::new());
    for i in -cells..=cells {
        for j in -cells..=cells {
            for k in -(0.6 / h).ceil() as i64..=(0.6 / h).ceil() as i64 {
                let p = [i as f64 * h, j as f64 * h, (k as f64 + 0.5) * h];
                let rho = p[0].hypot(p[1]);
                let s2 = (rho - 1.0).powi(2) + p[2] * p[2];
                if s2 < 9.0 * a * a {
                    let w = (-s2 / (a * a)).exp() / (std::f64::consts::PI * a * a);
                    x.push(p);
                    alpha.push([-w * p[1] / rho * h.powi(3), w * p[0] / rho * h.powi(3), 0.0]);
                }
            }
        }
    }
    (x, alpha, BlobKernel3::new(1.5 * h))
}

/// `RMS |got - want| / RMS |want|`.
pub(crate) fn rms_error<const K: usize>(got: &[[f64; K]], want: &[[f64; K]]) -> f64 {
    let square = |v: [f64; K]| v.iter().map(|c| c * c).sum::<f64>();
    let diff: f64 = got
        .iter()
        .zip(want)
        .map(|(g, w)| square(std::array::from_fn(|k| g[k] - w[k])))
        .sum();
    (diff / want.iter().map(|w| square(*w)).sum::<f64>()).sqrt()
}

pub(crate) fn same_bits<const K: usize>(a: &[[f64; K]], b: &[[f64; K]]) -> bool {
    a.len() == b.len()
        && a.iter()
            .zip(b)
            .all(|(p, q)| p.map(f64::to_bits) == q.map(f64::to_bits))
}
