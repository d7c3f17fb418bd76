//! Initial vorticity fields of the vortex model, sampled on a square lattice:
//! particle `i` at `x_i = c + h (k, l)`, `|k|, |l| <= extent / h`, carries
//! `Gamma_i = w(x_i) h^2` (its own vorticity `Gamma_i / h^2` is the field's
//! value at its position).

use std::f64::consts::PI;

/// The Koumoutsakos (1997) smoothing constant of the elliptical vortex.
pub const ELLIPSE_Q: f64 = 2.560_85;

/// A vorticity field `w(x)` that seeds the particles.
#[derive(Clone, Debug, PartialEq)]
pub enum InitialVorticity {
    /// The Lamb-Oseen vortex of age `t0`:
    /// `w(r) = Gamma / (4 pi nu t0) exp(-r^2 / (4 nu t0))`, which under viscosity
    /// `nu` stays a Lamb-Oseen vortex of age `t0 + t` (see [`lamb_oseen_vorticity`]).
    LambOseen {
        /// Total circulation `Gamma`.
        circulation: f64,
        /// Age `t0 > 0`.
        t0: f64,
        /// Viscosity `nu > 0` that sets the core `sqrt(4 nu t0)`.
        nu: f64,
    },
    /// A Gaussian vortex `w(r) = Gamma / (pi a^2) exp(-r^2 / a^2)` of core `a`.
    Gaussian {
        /// Total circulation `Gamma`.
        circulation: f64,
        /// Core `a > 0`.
        core: f64,
    },
    /// Two equal Gaussian vortices (circulation and core each) at `c -+ (b/2, 0)`:
    /// they co-rotate with period `2 pi^2 b^2 / Gamma` until they merge.
    Pair {
        /// Circulation of each vortex.
        circulation: f64,
        /// Distance `b` between their centres.
        separation: f64,
        /// Core `a` of each.
        core: f64,
    },
    /// The smooth elliptical vortex of Koumoutsakos (1997):
    /// `w = w0 (1 - f_q(s / R))` for `s < R`, 0 outside, with
    /// `f_q(z) = exp(-(q / z) exp(1 / (z - 1)))`, `q = 2.56085`, and the elliptical
    /// radius `s^2 = x^2 / A + A y^2` (semi-axes `R sqrt(A)` along x and
    /// `R / sqrt(A)` along y: aspect ratio `A`, the area of the circle of radius `R`).
    Ellipse {
        /// Peak vorticity `w0`.
        peak: f64,
        /// Radius `R` of the circle of equal area.
        radius: f64,
        /// Aspect ratio `A >= 1` of the vorticity contours.
        aspect: f64,
    },
}

/// The Lamb-Oseen vorticity `Gamma / (4 pi nu t) exp(-r^2 / (4 nu t))` at `r^2`.
pub fn lamb_oseen_vorticity(circulation: f64, nu: f64, t: f64, r2: f64) -> f64 {
    let core2 = 4.0 * nu * t;
    circulation / (PI * core2) * (-r2 / core2).exp()
}

/// The azimuthal speed of the Lamb-Oseen vortex,
/// `Gamma / (2 pi r) (1 - exp(-r^2 / (4 nu t)))`, at radius `r`.
pub fn lamb_oseen_speed(circulation: f64, nu: f64, t: f64, r: f64) -> f64 {
    let core2 = 4.0 * nu * t;
    if r == 0.0 {
        return 0.0;
    }
    -circulation / (2.0 * PI * r) * (-(r * r) / core2).exp_m1()
}

impl InitialVorticity {
    /// `w(x)` with `x` relative to the centre.
    pub fn vorticity(&self, x: [f64; 2]) -> f64 {
        let r2 = x[0] * x[0] + x[1] * x[1];
        let gaussian = |circulation: f64, core: f64, r2: f64| {
            circulation / (PI * core * core) * (-r2 / (core * core)).exp()
        };
        match *self {
            InitialVorticity::LambOseen {
                circulation,
                t0,
                nu,
            } => lamb_oseen_vorticity(circulation, nu, t0, r2),
            InitialVorticity::Gaussian { circulation, core } => gaussian(circulation, core, r2),
            InitialVorticity::Pair {
                circulation,
                separation,
                core,
            } => {
                let half = 0.5 * separation;
                let left = (x[0] + half).powi(2) + x[1] * x[1];
                let right = (x[0] - half).powi(2) + x[1] * x[1];
                gaussian(circulation, core, left) + gaussian(circulation, core, right)
            }
            InitialVorticity::Ellipse {
                peak,
                radius,
                aspect,
            } => {
                let s = (x[0] * x[0] / aspect + aspect * x[1] * x[1]).sqrt();
                let z = s / radius;
                if z >= 1.0 {
                    0.0
                } else if z == 0.0 {
                    peak
                } else {
                    peak * (1.0 - (-(ELLIPSE_Q / z) * (1.0 / (z - 1.0)).exp()).exp())
                }
            }
        }
    }
}

/// The lattice `c + h (k, l)`, `-n <= k, l <= n`, `n = floor(extent / h)` (l
/// slowest), with `Gamma = w(x - c) h^2` at each node.
pub fn seed(
    field: &InitialVorticity,
    center: [f64; 2],
    spacing: f64,
    extent: f64,
) -> (Vec<[f64; 2]>, Vec<f64>) {
    let n = (extent / spacing * (1.0 + 1e-12)).floor() as i64;
    let mut positions = Vec::new();
    let mut gamma = Vec::new();
    for l in -n..=n {
        for k in -n..=n {
            let offset = [k as f64 * spacing, l as f64 * spacing];
            positions.push([center[0] + offset[0], center[1] + offset[1]]);
            gamma.push(field.vorticity(offset) * spacing * spacing);
        }
    }
    (positions, gamma)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn seeded_circulations_add_up_to_the_fields() {
        let h = 0.02;
        let total = |field: &InitialVorticity, extent: f64| -> f64 {
            seed(field, [0.3, -0.1], h, extent).1.iter().sum()
        };
        let lamb = InitialVorticity::LambOseen {
            circulation: 2.0,
            t0: 1.0,
            nu: 0.01,
        };
        assert!((total(&lamb, 1.5) - 2.0).abs() < 1e-10);
        let pair = InitialVorticity::Pair {
            circulation: 1.0,
            separation: 1.0,
            core: 0.15,
        };
        assert!((total(&pair, 2.0) - 2.0).abs() < 1e-10);
        // the ellipse's circulation is w0 times the area pi R^2 times the mean of 1 - f_q
        let ellipse = InitialVorticity::Ellipse {
            peak: 20.0,
            radius: 0.8,
            aspect: 2.0,
        };
        let circle = InitialVorticity::Ellipse {
            peak: 20.0,
            radius: 0.8,
            aspect: 1.0,
        };
        let (a, b) = (total(&ellipse, 1.6), total(&circle, 1.6));
        assert!((a - b).abs() < 1e-3 * b, "{a} {b}");
        assert!(b > 0.0 && b < 20.0 * PI * 0.64);
    }

    #[test]
    fn the_lamb_oseen_speed_is_the_curl_of_its_vorticity() {
        // circulation inside r: 2 pi r u(r) = Gamma (1 - exp(-r^2 / 4 nu t))
        let (g, nu, t) = (1.5, 0.02, 2.0);
        let r = 0.4;
        let inside: f64 = (0..20_000)
            .map(|k| {
                let s = (k as f64 + 0.5) * r / 20_000.0;
                2.0 * PI * s * lamb_oseen_vorticity(g, nu, t, s * s) * r / 20_000.0
            })
            .sum();
        let speed = lamb_oseen_speed(g, nu, t, r);
        assert!((2.0 * PI * r * speed - inside).abs() < 1e-8);
    }
}
