//! Initial fields with their exact solutions of `d phi / dt = nu laplace(phi)` on the
//! periodic box `[0, L_0) x ... x [0, L_{D-1})`.

use std::f64::consts::PI;

/// An initial field that has a closed-form solution on the periodic box.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum InitialField<const D: usize> {
    /// `phi(x, 0) = prod_d sin(2 pi k_d x_d / L_d)`, decaying as
    /// `exp(-nu |kappa|^2 t)` with `kappa_d = 2 pi k_d / L_d`.
    Sine {
        /// Integer wavenumbers.
        k: [i64; D],
    },
    /// `phi(x, 0) = sum_n exp(-|x - c - n L|^2 / (2 w^2))` over the periodic images;
    /// at time `t` its width is `s^2 = w^2 + 2 nu t` and its amplitude
    /// `(w^2 / s^2)^(D/2)` (the heat kernel).
    Gaussian {
        /// Centre `c`.
        center: [f64; D],
        /// Width (standard deviation) `w > 0`.
        width: f64,
    },
}

impl<const D: usize> InitialField<D> {
    /// The exact solution at `x` and time `t` for diffusivity `nu`, box sides `length`.
    pub fn exact(&self, x: &[f64; D], t: f64, nu: f64, length: &[f64; D]) -> f64 {
        match *self {
            InitialField::Sine { k } => {
                let mut value = 1.0;
                let mut kappa2 = 0.0;
                for a in 0..D {
                    let kappa = 2.0 * PI * k[a] as f64 / length[a];
                    value *= (kappa * x[a]).sin();
                    kappa2 += kappa * kappa;
                }
                value * (-nu * kappa2 * t).exp()
            }
            InitialField::Gaussian { center, width } => {
                let s2 = width * width + 2.0 * nu * t;
                let mut value = (width * width / s2).powf(D as f64 / 2.0);
                for a in 0..D {
                    value *= periodic_gaussian(x[a] - center[a], s2, length[a]);
                }
                value
            }
        }
    }

    /// The exact solution at every point.
    pub fn exact_at(&self, points: &[[f64; D]], t: f64, nu: f64, length: &[f64; D]) -> Vec<f64> {
        points
            .iter()
            .map(|x| self.exact(x, t, nu, length))
            .collect()
    }
}

/// `sum_n exp(-(d - n L)^2 / (2 s2))` over the images `n` whose terms are above
/// `exp(-745)` (none further can add a bit).
fn periodic_gaussian(d: f64, s2: f64, length: f64) -> f64 {
    let reach = (2.0 * 745.0 * s2).sqrt();
    let images = (reach / length).ceil() as i64 + 1;
    (-images..=images)
        .map(|n| {
            let e = d - n as f64 * length;
            (-(e * e) / (2.0 * s2)).exp()
        })
        .sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_gaussian_keeps_its_integral_and_is_periodic() {
        let g = InitialField::<1>::Gaussian {
            center: [0.3],
            width: 0.2,
        };
        let n = 2000;
        let h = 1.0 / n as f64;
        for t in [0.0, 0.01, 0.1] {
            let mass: f64 = (0..n)
                .map(|i| g.exact(&[(i as f64 + 0.5) * h], t, 1.0, &[1.0]) * h)
                .sum();
            assert!(
                (mass - 0.2 * (2.0 * PI).sqrt()).abs() < 1e-12,
                "{t}: {mass}"
            );
        }
        let (a, b) = (
            g.exact(&[0.05], 0.02, 1.0, &[1.0]),
            g.exact(&[1.05], 0.02, 1.0, &[1.0]),
        );
        assert!((a - b).abs() < 1e-15);
    }

    #[test]
    fn the_sine_solves_the_heat_equation() {
        // d/dt phi = nu laplace(phi) by finite differences
        let s = InitialField::<2>::Sine { k: [1, 2] };
        let (nu, l, x, t) = (0.7, [1.0, 2.0], [0.31, 0.77], 0.05);
        let e = 1e-4;
        let dt = (s.exact(&x, t + e, nu, &l) - s.exact(&x, t - e, nu, &l)) / (2.0 * e);
        let f = |dx: f64, dy: f64| s.exact(&[x[0] + dx, x[1] + dy], t, nu, &l);
        let lap = (f(e, 0.0) + f(-e, 0.0) + f(0.0, e) + f(0.0, -e) - 4.0 * f(0.0, 0.0)) / (e * e);
        assert!(
            (dt - nu * lap).abs() < 1e-5 * dt.abs(),
            "{dt} vs {}",
            nu * lap
        );
    }
}
