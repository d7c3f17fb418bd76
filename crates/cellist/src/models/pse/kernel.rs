//! The PSE kernel of seed 002, eq. (3): `eta(r) = 4 / pi^(D/2) exp(-|r|^2)` (second
//! moment 2 in 2D and 3D alike), scaled as `eta_eps(r) = eps^-D eta(r / eps)`, and
//! the exponential it needs, written in straight-line code so that a block of pairs
//! runs in SIMD lanes.

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

/// `log2(e)`.
const LOG2_E: f64 = std::f64::consts::LOG2_E;
/// `ln 2` split in two (Cody and Waite): `LN2_HI` has trailing zero bits so that
/// `n LN2_HI` is exact for the `n` that occur.
const LN2_HI: f64 = f64::from_bits(0x3fe6_2e42_fee0_0000);
const LN2_LO: f64 = f64::from_bits(0x3dea_39ef_3579_3c76);
/// `1.5 * 2^52`: adding it rounds to an integer held in the low mantissa bits.
const ROUNDER: f64 = 6_755_399_441_055_744.0;
/// Below this, `exp(x)` is under `3.3e-308` and returned as 0.
const UNDERFLOW: f64 = -708.0;

/// `exp(x)` for `x <= 0` (and `x` not NaN), within a few ulps of `f64::exp`, in
/// branch-free arithmetic that vectorises: `x = n ln2 + r` with `|r| <= ln2 / 2`,
/// `exp(r)` by its Taylor polynomial of degree 13 (truncation below `1e-17`
/// relative), times `2^n` built from the exponent bits. Results below `3.3e-308`
/// are flushed to 0.
#[inline(always)]
pub fn exp_nonpositive(x: f64) -> f64 {
    let clamped = x.max(UNDERFLOW);
    let shifted = clamped * LOG2_E + ROUNDER;
    let n = shifted - ROUNDER;
    let r = (clamped - n * LN2_HI) - n * LN2_LO;
    // Horner, 1/k! coefficients
    let mut p = 1.0 / 6_227_020_800.0;
    for c in [
        1.0 / 479_001_600.0,
        1.0 / 39_916_800.0,
        1.0 / 3_628_800.0,
        1.0 / 362_880.0,
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
        p = p * r + c;
    }
    let n_bits = (shifted.to_bits() as i64).wrapping_sub(ROUNDER.to_bits() as i64);
    let two_n = f64::from_bits((n_bits + 1023).wrapping_shl(52) as u64);
    if x < UNDERFLOW {
        0.0
    } else {
        p * two_n
    }
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
