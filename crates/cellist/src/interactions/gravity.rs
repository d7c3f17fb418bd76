//! Newtonian gravity with Plummer softening and seed 003's optional short-range
//! repulsion.

/// The law every gravity solver approximates. With `s^2 = r^2 + eps^2`, particle
/// `j` gives particle `i` the potential and acceleration
///
/// `phi_ij = -G m_j / s + G m_j a^4 / (5 s^5)`,
/// `acc_ij = G m_j (x_j - x_i) / s^3 (1 - (a / s)^4)`,
///
/// so that `acc = -grad phi`. Without repulsion (`a = 0`) this is Plummer's
/// softened potential `-G m_j / sqrt(r^2 + eps^2)`; without softening the force is
/// seed 003's `f_ij = G m_i m_j (x_j - x_i) / r^3 (1 - (a/r)^4)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GravityLaw {
    g: f64,
    softening: f64,
    repulsion_radius: f64,
}

impl GravityLaw {
    /// The law with constant `g > 0`, softening `eps >= 0` and repulsion radius
    /// `a >= 0` (0: none).
    pub fn new(g: f64, softening: f64, repulsion_radius: f64) -> Result<Self, String> {
        if !(g.is_finite() && g > 0.0) {
            return Err(format!("G must be finite and > 0, got {g}"));
        }
        if !(softening.is_finite() && softening >= 0.0) {
            return Err(format!(
                "softening must be finite and >= 0, got {softening}"
            ));
        }
        if !(repulsion_radius.is_finite() && repulsion_radius >= 0.0) {
            return Err(format!(
                "repulsion_radius must be finite and >= 0, got {repulsion_radius}"
            ));
        }
        Ok(GravityLaw {
            g,
            softening,
            repulsion_radius,
        })
    }

    /// The gravitational constant `G`.
    pub fn g(&self) -> f64 {
        self.g
    }

    /// The Plummer softening length `eps`.
    pub fn softening(&self) -> f64 {
        self.softening
    }

    /// `eps^2`.
    pub fn softening2(&self) -> f64 {
        self.softening * self.softening
    }

    /// The repulsion radius `a` (0 when there is no repulsion).
    pub fn repulsion_radius(&self) -> f64 {
        self.repulsion_radius
    }

    /// Whether the repulsion term is on.
    pub fn has_repulsion(&self) -> bool {
        self.repulsion_radius > 0.0
    }

    /// `(phi, k)` of a unit source at squared distance `r2` (without the softening):
    /// `phi = -G/s + G a^4/(5 s^5)` and `k = G/s^3 (1 - a^4/s^4)`, the acceleration
    /// being `k (x_j - x_i)` per unit source mass.
    #[inline(always)]
    pub fn unit_pair(&self, r2: f64) -> (f64, f64) {
        let s2 = r2 + self.softening2();
        let inv = 1.0 / s2.sqrt();
        let inv2 = inv * inv;
        let a2 = self.repulsion_radius * self.repulsion_radius;
        let a4_s4 = a2 * a2 * inv2 * inv2;
        let phi = -self.g * inv * (1.0 - 0.2 * a4_s4);
        let k = self.g * inv * inv2 * (1.0 - a4_s4);
        (phi, k)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn acceleration_is_minus_the_potential_gradient() {
        for (eps, a) in [(0.0, 0.0), (0.01, 0.0), (0.0, 0.3), (0.05, 0.2)] {
            let law = GravityLaw::new(1.5, eps, a).unwrap();
            for k in 1..200 {
                let r = 0.05 * k as f64;
                let h = 1e-6 * r;
                let phi = |r: f64| law.unit_pair(r * r).0;
                // acc_i = -grad_i phi(|x_j - x_i|) = phi'(r) (x_j - x_i) / r: k r = phi'(r)
                let numeric = (phi(r + h) - phi(r - h)) / (2.0 * h);
                let analytic = law.unit_pair(r * r).1 * r;
                assert!(
                    (numeric - analytic).abs() <= 1e-6 * analytic.abs().max(1.0),
                    "eps {eps} a {a} r {r}: {numeric} vs {analytic}"
                );
            }
        }
    }

    #[test]
    fn attraction_turns_to_repulsion_at_a() {
        let law = GravityLaw::new(1.0, 0.0, 0.5).unwrap();
        assert!(law.unit_pair(0.6 * 0.6).1 > 0.0);
        assert!(law.unit_pair(0.4 * 0.4).1 < 0.0);
        assert_eq!(law.unit_pair(0.25).1, 0.0);
    }

    #[test]
    fn bad_parameters_are_refused() {
        assert!(GravityLaw::new(0.0, 0.0, 0.0).is_err());
        assert!(GravityLaw::new(1.0, -0.1, 0.0).is_err());
        assert!(GravityLaw::new(1.0, 0.0, f64::NAN).is_err());
    }
}
