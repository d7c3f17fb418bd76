//! The Lennard-Jones potential with a cutoff (LAMMPS `pair_style lj/cut`).

use super::PairPotential;
use crate::simd::F64x4;
use std::ops::{Div, Mul, Sub};

/// `U(r) = 4 eps ((sigma/r)^12 - (sigma/r)^6) - U_shift` for `r < r_c`, zero beyond.
///
/// `U_shift = 4 eps ((sigma/r_c)^12 - (sigma/r_c)^6)` when shifted (LAMMPS
/// `pair_modify shift yes`), so that `U(r_c) = 0`; forces do not change. The
/// arithmetic is LAMMPS's: with `lj1 = 48 eps sigma^12`, `lj2 = 24 eps sigma^6`,
/// `lj3 = 4 eps sigma^12`, `lj4 = 4 eps sigma^6` and `s = 1/r^2`,
/// `-U'(r)/r = s^3 (lj1 s^3 - lj2) s` and `U = s^3 (lj3 s^3 - lj4) - U_shift`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LennardJones {
    epsilon: f64,
    sigma: f64,
    cutoff: f64,
    cutoff2: f64,
    lj1: f64,
    lj2: f64,
    lj3: f64,
    lj4: f64,
    offset: f64,
}

impl LennardJones {
    /// The potential of well depth `epsilon >= 0` and size `sigma > 0`, cut at
    /// `cutoff > 0`, shifted to zero there when `shift`.
    pub fn new(epsilon: f64, sigma: f64, cutoff: f64, shift: bool) -> Result<Self, String> {
        if !(epsilon.is_finite() && epsilon >= 0.0) {
            return Err(format!("epsilon must be finite and >= 0, got {epsilon}"));
        }
        if !(sigma.is_finite() && sigma > 0.0) {
            return Err(format!("sigma must be finite and > 0, got {sigma}"));
        }
        if !(cutoff.is_finite() && cutoff > 0.0) {
            return Err(format!("cutoff must be finite and > 0, got {cutoff}"));
        }
        let offset = if shift {
            let ratio = sigma / cutoff;
            4.0 * epsilon * (ratio.powf(12.0) - ratio.powf(6.0))
        } else {
            0.0
        };
        Ok(LennardJones {
            epsilon,
            sigma,
            cutoff,
            cutoff2: cutoff * cutoff,
            lj1: 48.0 * epsilon * sigma.powf(12.0),
            lj2: 24.0 * epsilon * sigma.powf(6.0),
            lj3: 4.0 * epsilon * sigma.powf(12.0),
            lj4: 4.0 * epsilon * sigma.powf(6.0),
            offset,
        })
    }

    /// Well depth.
    pub fn epsilon(&self) -> f64 {
        self.epsilon
    }

    /// Size parameter.
    pub fn sigma(&self) -> f64 {
        self.sigma
    }

    /// `r_c^2`: pairs interact when `r^2 < r_c^2`, LAMMPS's test.
    #[inline(always)]
    pub fn cutoff2(&self) -> f64 {
        self.cutoff2
    }

    /// The energy subtracted per pair inside the cutoff (zero when not shifted).
    pub fn shift_energy(&self) -> f64 {
        self.offset
    }
}

impl PairPotential for LennardJones {
    fn cutoff(&self) -> f64 {
        self.cutoff
    }

    #[inline(always)]
    fn energy_and_force(&self, r2: f64) -> (f64, f64) {
        lj_terms(
            r2,
            1.0,
            [self.lj1, self.lj2, self.lj3, self.lj4],
            self.offset,
        )
    }
}

impl LennardJones {
    /// [`PairPotential::energy_and_force`] on four `r^2` at once: `(U, -U'/r)`
    /// lane by lane, the same operations, so the same bits as four scalar calls.
    #[inline(always)]
    pub fn energy_and_force_lanes(&self, r2: F64x4) -> (F64x4, F64x4) {
        let lj = [self.lj1, self.lj2, self.lj3, self.lj4].map(F64x4::splat);
        lj_terms(r2, F64x4::splat(1.0), lj, F64x4::splat(self.offset))
    }
}

/// LAMMPS's arithmetic, on scalars or lanes: with `s = 1/r^2`,
/// `U = s^3 (lj3 s^3 - lj4) - U_shift` and `-U'/r = s^3 (lj1 s^3 - lj2) s`.
#[inline(always)]
fn lj_terms<T>(r2: T, one: T, lj: [T; 4], offset: T) -> (T, T)
where
    T: Copy + Mul<Output = T> + Sub<Output = T> + Div<Output = T>,
{
    let r2inv = one / r2;
    let r6inv = r2inv * r2inv * r2inv;
    let force = r6inv * (lj[0] * r6inv - lj[1]);
    let energy = r6inv * (lj[2] * r6inv - lj[3]) - offset;
    (energy, force * r2inv)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::interactions::generic_tests::force_is_minus_energy_gradient;

    #[test]
    fn passes_the_generic_pair_tests() {
        for shift in [false, true] {
            for (eps, sigma) in [(1.0, 1.0), (0.7, 1.3)] {
                let lj = LennardJones::new(eps, sigma, 2.5 * sigma, shift).unwrap();
                force_is_minus_energy_gradient(&lj, 0.85 * sigma);
            }
        }
    }

    #[test]
    fn minimum_and_zero_crossing_are_where_the_formula_puts_them() {
        let lj = LennardJones::new(1.0, 1.0, 2.5, false).unwrap();
        // U(sigma) = 0, U(2^(1/6) sigma) = -eps with zero force there
        assert_eq!(lj.energy_and_force(1.0).0, 0.0);
        let rmin2 = 2f64.powf(1.0 / 3.0);
        let (u, f) = lj.energy_and_force(rmin2);
        assert!((u + 1.0).abs() < 1e-15 && f.abs() < 1e-13, "{u} {f}");
    }

    #[test]
    fn shift_makes_the_energy_vanish_at_the_cutoff() {
        let lj = LennardJones::new(1.0, 1.0, 2.5, true).unwrap();
        // the value quoted in ../shared/testdata/lammps/README.md
        assert!((lj.shift_energy() + 0.016316891136).abs() < 1e-12);
        assert!(lj.energy_and_force(2.5 * 2.5).0.abs() < 1e-15);
    }

    #[test]
    fn refuses_bad_parameters() {
        assert!(LennardJones::new(-1.0, 1.0, 2.5, false).is_err());
        assert!(LennardJones::new(1.0, 0.0, 2.5, false).is_err());
        assert!(LennardJones::new(1.0, 1.0, f64::NAN, false).is_err());
    }
}
