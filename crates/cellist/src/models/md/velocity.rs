//! Initial velocities at a temperature (LAMMPS `velocity create`).

use super::Atoms;
use crate::random::{stream_seed, Rng};

/// How each velocity component is drawn before the rescaling.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum VelocityDistribution {
    /// Uniform in `[-1/2, 1/2)` (LAMMPS's default `dist uniform`).
    Uniform,
    /// Standard normal.
    Gaussian,
}

/// Sets velocities at temperature `T` (k_B = 1): components drawn from a stream
/// keyed by (seed, atom id), so they depend on neither the atom order nor the thread
/// count; then the total momentum is removed, `v -= sum m v / sum m`, and all
/// velocities are scaled so that `sum m v^2 / (D N - D) = T` exactly (LAMMPS's
/// temperature with `D N - D` degrees of freedom).
pub fn create_velocities<const D: usize>(
    atoms: &mut Atoms<D>,
    temperature: f64,
    seed: u64,
    distribution: VelocityDistribution,
) {
    for k in 0..atoms.len() {
        let mut rng = Rng::new(stream_seed(seed, &[atoms.ids[k]]));
        atoms.velocities[k] = std::array::from_fn(|_| match distribution {
            VelocityDistribution::Uniform => rng.uniform() - 0.5,
            VelocityDistribution::Gaussian => rng.normal(),
        });
    }
    let total_mass: f64 = atoms.masses.iter().sum();
    let mut momentum = [0.0; D];
    for (v, m) in atoms.velocities.iter().zip(&atoms.masses) {
        for a in 0..D {
            momentum[a] += m * v[a];
        }
    }
    for v in &mut atoms.velocities {
        for a in 0..D {
            v[a] -= momentum[a] / total_mass;
        }
    }
    let current = super::temperature(atoms);
    let factor = if current > 0.0 {
        (temperature / current).sqrt()
    } else {
        0.0
    };
    for v in &mut atoms.velocities {
        for a in 0..D {
            v[a] *= factor;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn zero_momentum_and_the_requested_temperature() {
        for dist in [
            VelocityDistribution::Uniform,
            VelocityDistribution::Gaussian,
        ] {
            let mut atoms = Atoms::<3>::at_rest(vec![[0.0; 3]; 1000], 2.0);
            create_velocities(&mut atoms, 1.5, 7, dist);
            let t = crate::models::md::temperature(&atoms);
            assert!((t - 1.5).abs() < 1e-13, "{t}");
            for a in 0..3 {
                let p: f64 = atoms.velocities.iter().map(|v| 2.0 * v[a]).sum();
                assert!(p.abs() < 1e-11, "{p}");
            }
        }
    }

    #[test]
    fn velocities_follow_the_atom_not_its_position_in_the_arrays() {
        let mut a = Atoms::<2>::at_rest(vec![[0.0; 2]; 10], 1.0);
        let mut b = a.clone();
        b.ids.reverse();
        create_velocities(&mut a, 1.0, 3, VelocityDistribution::Uniform);
        create_velocities(&mut b, 1.0, 3, VelocityDistribution::Uniform);
        let va = a.velocities[0];
        let vb = b.velocities[9];
        for k in 0..2 {
            assert!((va[k] - vb[k]).abs() < 1e-14);
        }
    }
}
