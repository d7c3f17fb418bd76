//! The M4' interpolation kernel of Monaghan (1985), used to move values between
//! particles and a lattice (vortex-in-cell assignment and interpolation,
//! remeshing):
//!
//! ```text
//! M4'(s) = 1 - 5/2 s^2 + 3/2 |s|^3        for |s| <= 1,
//!          1/2 (2 - |s|)^2 (1 - |s|)       for 1 < |s| <= 2,
//!          0                               otherwise,
//! ```
//!
//! with `s` the distance in lattice spacings. It interpolates (`M4'(0) = 1`,
//! `M4'(k) = 0` at the other nodes) and reproduces polynomials up to degree 2, so
//! a tensor-product assignment conserves a particle set's total, its first moments
//! and its second moments (circulation, linear and angular impulse).

mod remesh;

pub use remesh::{remesh, Lattice, Remeshed};

/// `M4'(s)`.
#[inline(always)]
pub fn m4prime(s: f64) -> f64 {
    let a = s.abs();
    if a <= 1.0 {
        1.0 - 2.5 * a * a + 1.5 * a * a * a
    } else if a <= 2.0 {
        0.5 * (2.0 - a) * (2.0 - a) * (1.0 - a)
    } else {
        0.0
    }
}

/// The lattice nodes and weights of the M4' kernel at `u` (a position in lattice
/// spacings): the first node `floor(u) - 1` and the weights of the four nodes
/// `floor(u) - 1 ..= floor(u) + 2`, which sum to 1.
#[inline(always)]
pub fn m4prime_stencil(u: f64) -> (i64, [f64; 4]) {
    let base = u.floor();
    let f = u - base;
    (
        base as i64 - 1,
        [
            m4prime(1.0 + f),
            m4prime(f),
            m4prime(1.0 - f),
            m4prime(2.0 - f),
        ],
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_kernel_interpolates_and_reproduces_quadratics() {
        assert_eq!(m4prime(0.0), 1.0);
        for k in [1.0, 2.0, -1.0, -2.0, 2.5, -3.0] {
            assert_eq!(m4prime(k), 0.0);
        }
        for k in 0..200 {
            let u = -3.7 + k as f64 * 0.0731;
            let (first, w) = m4prime_stencil(u);
            let moment = |p: i32| -> f64 {
                (0..4)
                    .map(|j| w[j] * ((first + j as i64) as f64 - u).powi(p))
                    .sum()
            };
            assert!((moment(0) - 1.0).abs() < 1e-14, "{u}");
            assert!(moment(1).abs() < 1e-13, "{u}");
            assert!(moment(2).abs() < 1e-13, "{u}");
        }
    }
}
