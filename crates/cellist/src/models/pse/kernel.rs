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

/// `4 log2(e)`: quarters of a binary order of magnitude.
const QUARTERS_PER_E: f64 = 4.0 * std::f64::consts::LOG2_E;
/// `ln 2 / 4` split in two (Cody and Waite): `QUARTER_LN2_HI` has trailing zero bits
/// so that `k QUARTER_LN2_HI` is exact for the `k` that occur.
const QUARTER_LN2_HI: f64 = f64::from_bits(0x3fe6_2e42_fee0_0000) / 4.0;
const QUARTER_LN2_LO: f64 = f64::from_bits(0x3dea_39ef_3579_3c76) / 4.0;
/// `1.5 * 2^52`: adding it rounds to an integer held in the low mantissa bits.
const ROUNDER: f64 = 6_755_399_441_055_744.0;
/// `2^(j/4)` for `j = 0..3`.
const QUARTER_POWERS: [f64; 4] = [
    1.0,
    1.189_207_115_002_721,
    std::f64::consts::SQRT_2,
    1.681_792_830_507_429,
];
/// Below this, `exp(x)` is under `3.3e-308` and returned as 0.
const UNDERFLOW: f64 = -708.0;

/// `exp(x)` for `x <= 0` (and `x` not NaN), within a few ulps of `f64::exp`, in
/// branch-free arithmetic that vectorises: `x = (4n + j) ln2 / 4 + r` with
/// `|r| <= ln2 / 8`, `exp(r)` by its Taylor polynomial of degree 9 (truncation below
/// `1e-17` relative), times `2^(j/4)` picked by selects (no table lookup) and `2^n`
/// built from the exponent bits. Results below `3.3e-308` are flushed to 0.
#[inline(always)]
pub fn exp_nonpositive(x: f64) -> f64 {
    let clamped = x.max(UNDERFLOW);
    let shifted = clamped * QUARTERS_PER_E + ROUNDER;
    let k = shifted - ROUNDER;
    let r = (clamped - k * QUARTER_LN2_HI) - k * QUARTER_LN2_LO;
    // Horner, 1/i! coefficients
    let mut p = 1.0 / 362_880.0;
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
        p = p * r + c;
    }
    let k_bits = (shifted.to_bits() as i64).wrapping_sub(ROUNDER.to_bits() as i64);
    // k = 4n + j with j in 0..4 (the shift floors negative k)
    let (n, j) = (k_bits >> 2, k_bits & 3);
    let low = if j & 1 == 0 {
        QUARTER_POWERS[0]
    } else {
        QUARTER_POWERS[1]
    };
    let high = if j & 1 == 0 {
        QUARTER_POWERS[2]
    } else {
        QUARTER_POWERS[3]
    };
    let quarter = if j & 2 == 0 { low } else { high };
    let two_n = f64::from_bits((n + 1023).wrapping_shl(52) as u64);
    if x < UNDERFLOW {
        0.0
    } else {
        p * quarter * two_n
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
