//! The brute-force reference: all N(N-1)/2 pairs with the minimum image. Every fast
//! path is tested against it.

use crate::geometry::{norm2, Domain};

/// Every pair `(i, j, r)`, `i < j`, with `r = |minimum_image(x_j - x_i)| < cutoff`,
/// sorted by `(i, j)`. O(N^2): for tests and small inputs.
pub fn brute_force_pairs<const D: usize>(
    domain: &Domain<D>,
    cutoff: f64,
    points: &[[f64; D]],
) -> Vec<(u32, u32, f64)> {
    let mut out = Vec::new();
    for (i, xi) in points.iter().enumerate() {
        for (j, xj) in points.iter().enumerate().skip(i + 1) {
            let r = norm2(&domain.separation(xi, xj)).sqrt();
            if r < cutoff {
                out.push((i as u32, j as u32, r));
            }
        }
    }
    out
}
