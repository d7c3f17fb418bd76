//! Pair potentials. The force loops are generic over [`PairPotential`], so the
//! potential is chosen once per run and inlined into the loop, never looked up per
//! pair.

pub mod gravity;
pub mod lj;

pub use gravity::GravityLaw;
pub use lj::LennardJones;

/// One pair's energy and force, as functions of the squared distance.
pub trait PairPotential: Send + Sync {
    /// Pairs at `r >= cutoff` do not interact.
    fn cutoff(&self) -> f64;

    /// `(U(r), -U'(r) / r)` from `r^2 < cutoff^2`: the force on `i` from `j` is
    /// `f_over_r * (x_i - x_j)`, and the pair's virial is `f_over_r * r^2`.
    fn energy_and_force(&self, r2: f64) -> (f64, f64);
}

/// Checks that every pair style must pass, shared by the tests of each style.
#[cfg(test)]
pub(crate) mod generic_tests {
    use super::PairPotential;

    /// `F = -dU/dr`: the force against a central finite difference of the energy,
    /// at distances spread over `(r_min, cutoff)`.
    pub fn force_is_minus_energy_gradient(p: &impl PairPotential, r_min: f64) {
        let rc = p.cutoff();
        for k in 0..200 {
            let r = r_min + (rc - r_min) * (k as f64 + 0.5) / 200.0;
            let h = 1e-6 * r;
            let energy = |r: f64| p.energy_and_force(r * r).0;
            let numeric = -(energy(r + h) - energy(r - h)) / (2.0 * h);
            let (_, f_over_r) = p.energy_and_force(r * r);
            let analytic = f_over_r * r;
            let scale = analytic.abs().max(energy(r).abs()).max(1.0);
            assert!(
                (numeric - analytic).abs() <= 1e-6 * scale,
                "r = {r}: -dU/dr = {numeric}, force = {analytic}"
            );
        }
    }
}
