//! The PSE kernel of seed 002, eq. (3): `eta(r) = 4 / pi^(D/2) exp(-|r|^2)` (second
//! moment 2 in 2D and 3D alike), scaled as `eta_eps(r) = eps^-D eta(r / eps)`, and
//! the exponential it needs, written in straight-line code so that a block of pairs
//! runs in SIMD lanes.

use crate::simd::{Real, ROUNDER};

/// The pair weight of the PSE rate on equal volumes `V`:
/// `w(r^2) = nu / eps^2 * V * eta_eps(r) = c exp(-r^2 / eps^2)`, with
/// `c = nu / eps^2 * V * eps^-D * 4 / pi^(D/2)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PairWeight {
    /// `c`.
    pub scale: f64,
    /// `1 / eps^2`.
    pub inv_eps2: f64,
}

impl PairWeight {
    /// The weight for diffusivity `nu`, kernel width `eps`, particle volume `volume`
    /// in `dimension` dimensions.
    pub fn new(dimension: usize, nu: f64, eps: f64, volume: f64) -> Self {
        let d = dimension as i32;
        let eta_norm = 4.0 / std::f64::consts::PI.powf(dimension as f64 / 2.0);
        PairWeight {
            scale: nu / (eps * eps) * volume * eps.powi(-d) * eta_norm,
            inv_eps2: 1.0 / (eps * eps),
        }
    }

    /// `w(r^2)`.
    #[inline(always)]
    pub fn at(&self, r2: f64) -> f64 {
        self.scale * exp_nonpositive(-(r2 * self.inv_eps2))
    }
}

/// `4 log2(e)`: quarters of a binary order of magnitude.
const QUARTERS_PER_E: f64 = 4.0 * std::f64::consts::LOG2_E;
/// `ln 2 / 4` split in two (Cody and Waite): `QUARTER_LN2_HI` has trailing zero bits
/// so that `k QUARTER_LN2_HI` is exact for the `k` that occur.
const QUARTER_LN2_HI: f64 = f64::from_bits(0x3fe6_2e42_fee0_0000) / 4.0;
const QUARTER_LN2_LO: f64 = f64::from_bits(0x3dea_39ef_3579_3c76) / 4.0;
/// Below this, `exp(x)` is under `3.3e-308` and returned as 0.
const UNDERFLOW: f64 = -708.0;

/// `exp(x)` for `x <= 0` (and `x` not NaN), within a few ulps of `f64::exp`, in
/// branch-free arithmetic that vectorises: `x = (4n + j) ln2 / 4 + r` with
/// `|r| <= ln2 / 8`, `exp(r)` by its Taylor polynomial of degree 9 (truncation below
/// `1e-17` relative), times `2^(j/4)` picked by selects (no table lookup) and `2^n`
/// built from the exponent bits. Results below `3.3e-308` are flushed to 0. On
/// `f64`, or on the four lanes of an [`F64x4`](crate::simd::F64x4) with the
/// bits of four scalar calls.
#[inline(always)]
pub fn exp_nonpositive<T: Real>(x: T) -> T {
    let clamped = x.max(T::splat(UNDERFLOW));
    let shifted = clamped * T::splat(QUARTERS_PER_E) + T::splat(ROUNDER);
    let k = shifted - T::splat(ROUNDER);
    let r = (clamped - k * T::splat(QUARTER_LN2_HI)) - k * T::splat(QUARTER_LN2_LO);
    // Horner, 1/i! coefficients
    let mut p = T::splat(1.0 / 362_880.0);
    for c in [
        1.0 / 40_320.0,
        1.0 / 5_040.0,
        1.0 / 720.0,
        1.0 / 120.0,
        1.0 / 24.0,
        1.0 / 6.0,
        0.5,
        1.0,
        1.0,
    ] {
        p = p * r + T::splat(c);
    }
    // times 2^(k/4), k = 4n + j the integer rounded into `shifted`
    let scaled = p.times_two_to_quarters(shifted);
    T::select_less(x, T::splat(UNDERFLOW), T::splat(0.0), scaled)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ulps(a: f64, b: f64) -> u64 {
        (a.to_bits() as i64 - b.to_bits() as i64).unsigned_abs()
    }

    #[test]
    fn exp_is_within_a_few_ulps_of_the_library() {
        let mut worst = 0;
        for k in 0..=200_000 {
            let x = -708.0 * (k as f64 / 200_000.0).powi(2);
            worst = worst.max(ulps(exp_nonpositive(x), x.exp()));
        }
        assert!(worst <= 2, "{worst} ulps");
        assert_eq!(exp_nonpositive(0.0), 1.0);
        assert_eq!(exp_nonpositive(-0.0), 1.0);
        assert_eq!(exp_nonpositive(-709.0), 0.0);
        assert_eq!(exp_nonpositive(f64::NEG_INFINITY), 0.0);
    }

    #[test]
    fn four_lanes_give_the_bits_of_four_scalar_calls() {
        use crate::random::Rng;
        use crate::simd::F64x4;
        let mut rng = Rng::new(9);
        let special = [
            0.0,
            -0.0,
            -1e-300,
            -5e-324,
            -1e-9,
            -708.0,
            -708.0f64.next_down(),
            -709.0,
            -1e5,
            f64::NEG_INFINITY,
        ];
        for round in 0..20_000 {
            let x: [f64; 4] = std::array::from_fn(|l| match (round + l) % 4 {
                0 => special[(round / 4 + l) % special.len()],
                1 => -rng.uniform() * 1e-3,
                _ => -rng.uniform() * 750.0,
            });
            let lanes = exp_nonpositive(F64x4::load(&x)).to_array();
            assert_eq!(
                lanes.map(f64::to_bits),
                x.map(|x| exp_nonpositive(x).to_bits()),
                "{x:?}"
            );
        }
    }

    #[test]
    fn the_kernel_integrates_to_four_and_has_second_moment_two_per_axis() {
        // eta_eps on a fine 2D grid: integral 4, and integral x^2 eta = 2 eps^2
        let eps = 0.1;
        let h = eps / 20.0;
        let w = PairWeight::new(2, 1.0, eps, 1.0);
        let (mut mass, mut moment) = (0.0, 0.0);
        for i in -200..=200 {
            for j in -200..=200 {
                let (x, y) = (i as f64 * h, j as f64 * h);
                // w = eta_eps / eps^2 with nu = V = 1
                let eta = w.at(x * x + y * y) * eps * eps;
                mass += eta * h * h;
                moment += x * x * eta * h * h;
            }
        }
        assert!((mass - 4.0).abs() < 1e-12, "{mass}");
        assert!((moment / (eps * eps) - 2.0).abs() < 1e-12, "{moment}");
    }
}
