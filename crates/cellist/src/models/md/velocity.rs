//! Initial velocities at a temperature (LAMMPS `velocity create`).

use super::Atoms;
use crate::geometry::norm2;
use crate::random::{stream_seed, Rng};

/// How each velocity component is drawn before the rescaling.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum VelocityDistribution {
    /// Uniform in `[-1/2, 1/2)` (LAMMPS's default `dist uniform`).
    Uniform,
    /// Standard normal.
    Gaussian,
}

/// Sets velocities at temperature `T` (k_B = 1) ([`VelocityScaling`] over
/// `atoms` in their order): components drawn from a stream keyed by (seed,
/// atom id), so they depend on neither the atom order nor the thread count;
/// then the total momentum removed and the velocities scaled to `T` exactly.
pub fn create_velocities<const D: usize>(
    atoms: &mut Atoms<D>,
    temperature: f64,
    seed: u64,
    distribution: VelocityDistribution,
) {
    let every = || atoms.ids.iter().copied().zip(atoms.masses.iter().copied());
    let scaling = VelocityScaling::<D>::over(every, temperature, seed, distribution);
    for (v, &id) in atoms.velocities.iter_mut().zip(&atoms.ids) {
        *v = scaling.velocity(id);
    }
}

/// LAMMPS's `velocity create` for atoms given as `(id, mass)` in a fixed
/// order, which may be more atoms than a rank keeps: each atom's drawn
/// velocity `u_i` (uniform in `[-1/2, 1/2)` or normal per component, from
/// the stream of (seed, id)), the momentum shift `s = sum m u / sum m` and
/// the factor `f = sqrt(T / T_0)` with `T_0 = sum m |u - s|^2 / (D N - D)`
/// (LAMMPS's temperature with `D N - D` degrees of freedom): atom `i` gets
/// `v_i = (u_i - s) f`, so that `sum m v = 0` and `sum m v^2 / (D N - D) = T`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VelocityScaling<const D: usize> {
    shift: [f64; D],
    factor: f64,
    seed: u64,
    distribution: VelocityDistribution,
}

impl<const D: usize> VelocityScaling<D> {
    /// The scaling for the atoms `every()` yields, in its order (each call
    /// the same atoms): two passes over them, none held.
    pub fn over<I: Iterator<Item = (u64, f64)>>(
        every: impl Fn() -> I,
        temperature: f64,
        seed: u64,
        distribution: VelocityDistribution,
    ) -> Self {
        let mut scaling = VelocityScaling {
            shift: [0.0; D],
            factor: 1.0,
            seed,
            distribution,
        };
        let (mut total_mass, mut momentum, mut n) = (-0.0, [0.0; D], 0);
        for (id, m) in every() {
            let u = scaling.drawn(id);
            total_mass += m;
            for a in 0..D {
                momentum[a] += m * u[a];
            }
            n += 1;
        }
        scaling.shift = std::array::from_fn(|a| momentum[a] / total_mass);
        let mut twice_kinetic = -0.0;
        for (id, m) in every() {
            let u = scaling.drawn(id);
            let v: [f64; D] = std::array::from_fn(|a| u[a] - scaling.shift[a]);
            twice_kinetic += norm2(&v) * m;
        }
        let dof = (D * n).saturating_sub(D) as f64;
        let current = if dof > 0.0 { twice_kinetic / dof } else { 0.0 };
        scaling.factor = if current > 0.0 {
            (temperature / current).sqrt()
        } else {
            0.0
        };
        scaling
    }

    /// The velocity `(u - s) f` of the atom with `id`.
    pub fn velocity(&self, id: u64) -> [f64; D] {
        let u = self.drawn(id);
        std::array::from_fn(|a| (u[a] - self.shift[a]) * self.factor)
    }

    /// The drawn velocity `u` of the atom with `id`.
    fn drawn(&self, id: u64) -> [f64; D] {
        let mut rng = Rng::new(stream_seed(self.seed, &[id]));
        std::array::from_fn(|_| match self.distribution {
            VelocityDistribution::Uniform => rng.uniform() - 0.5,
            VelocityDistribution::Gaussian => rng.normal(),
        })
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

    /// A rank that keeps some of the atoms gives each the bits it gets when
    /// the velocities of all of them are created at once.
    #[test]
    fn scaling_over_every_atom_gives_a_kept_atom_its_velocity() {
        let n = 200;
        let mut all = Atoms::<3>::at_rest(vec![[0.0; 3]; n], 1.0);
        for (k, m) in all.masses.iter_mut().enumerate() {
            *m = 1.0 + (k % 5) as f64;
        }
        create_velocities(&mut all, 0.7, 11, VelocityDistribution::Gaussian);
        let every = || all.ids.iter().copied().zip(all.masses.iter().copied());
        let scaling = VelocityScaling::<3>::over(every, 0.7, 11, VelocityDistribution::Gaussian);
        for k in (0..n).step_by(3) {
            assert_eq!(scaling.velocity(all.ids[k]), all.velocities[k]);
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
