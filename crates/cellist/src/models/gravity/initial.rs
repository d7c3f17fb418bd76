//! Initial conditions: the Plummer sphere and seed 004's two-body set-up.

use crate::interactions::GravityLaw;
use crate::longrange::{DirectSum, FieldOut, Sources};
use crate::random::Rng;
use crate::threads::Threads;

/// Masses, positions and velocities of a set of bodies, in input order.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Bodies {
    /// `m_i`.
    pub mass: Vec<f64>,
    /// `x_i`.
    pub position: Vec<[f64; 3]>,
    /// `v_i`.
    pub velocity: Vec<[f64; 3]>,
}

impl Bodies {
    /// The bodies `range` of the input order.
    pub fn part(&self, range: std::ops::Range<usize>) -> Bodies {
        Bodies {
            mass: self.mass[range.clone()].to_vec(),
            position: self.position[range.clone()].to_vec(),
            velocity: self.velocity[range].to_vec(),
        }
    }

    /// Number of bodies.
    pub fn len(&self) -> usize {
        self.mass.len()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.mass.is_empty()
    }
}

/// Seed 004's convergence set-up: two bodies of mass 50 at `(0,0,0)` and
/// `(0,30,0)`, both moving with velocity `(1,0,0)`; they fall towards each other.
pub fn two_body_seed004() -> Bodies {
    Bodies {
        mass: vec![50.0, 50.0],
        position: vec![[0.0, 0.0, 0.0], [0.0, 30.0, 0.0]],
        velocity: vec![[1.0, 0.0, 0.0]; 2],
    }
}

/// The fraction of the Plummer mass kept: radii are drawn up to the radius that
/// holds 99.9 % of it (about 38.7 scale radii), the usual truncation.
const MASS_TRUNCATION: f64 = 0.999;

/// Largest `n` for which the virial rescaling uses the exact softened potential
/// energy (all pairs); beyond it, the analytic `W = -3 pi / 32`.
const EXACT_VIRIAL_MAX_N: usize = 20_000;

/// An equal-mass Plummer sphere of `n` bodies with `G = M = a = 1` (Aarseth, Henon
/// and Wielen 1974): radii from the cumulative mass `X` as `r = (X^(-2/3) - 1)^(-1/2)`,
/// speeds `q v_esc(r)` with `v_esc = sqrt(2) (1 + r^2)^(-1/4)` and `q` drawn from
/// `g(q) = q^2 (1 - q^2)^(7/2)` by rejection, isotropic directions; the centre of
/// mass is moved to rest at the origin and the velocities are scaled so that
/// `2 T = |W|` with the potential energy `W` of `law` (softened), all pairs for
/// `n <= 20000`, `-3 pi / 32` beyond.
pub fn plummer(n: usize, seed: u64, law: &GravityLaw, threads: &Threads) -> Bodies {
    plummer_part(n, seed, law, threads, 0..n)
}

/// The bodies `part` of [`plummer`]`(n, seed, law, threads)`, the same bits,
/// holding no other body when `n > 20000`: the draws are made once for the
/// centre of mass (`sum m_i x_i / sum m_i`, `sum m_i v_i / sum m_i`) while
/// `part` is kept, and (unless `part` is every body) again for the kinetic
/// energy `T = 1/2 sum m_i |v_i - v_cm|^2`, each sum in input order. A
/// process of a distributed run builds its own block this way.
pub fn plummer_part(
    n: usize,
    seed: u64,
    law: &GravityLaw,
    threads: &Threads,
    part: std::ops::Range<usize>,
) -> Bodies {
    assert!(part.end <= n, "bodies {part:?} of {n}");
    if n <= EXACT_VIRIAL_MAX_N {
        let mut bodies = centred_draws(n, seed);
        let w = softened_potential_energy(&bodies, law, threads);
        let t = kinetic_energy_of(&bodies);
        scale_to_virial(&mut bodies.velocity, w, t);
        return bodies.part(part);
    }
    let m = 1.0 / n as f64;
    // the sums of `to_centre_of_mass_frame`, each in input order from -0.0
    // as `Iterator::sum` starts
    let (mut total, mut x_sum, mut v_sum) = (-0.0, [-0.0; 3], [-0.0; 3]);
    let mut mine = Bodies {
        mass: vec![m; part.len()],
        position: Vec::with_capacity(part.len()),
        velocity: Vec::with_capacity(part.len()),
    };
    for (i, (x, v)) in PlummerDraws::new(n, seed).enumerate() {
        total += m;
        for a in 0..3 {
            x_sum[a] += m * x[a];
            v_sum[a] += m * v[a];
        }
        if part.contains(&i) {
            mine.position.push(x);
            mine.velocity.push(v);
        }
    }
    let (x_cm, v_cm) = (x_sum.map(|s| s / total), v_sum.map(|s| s / total));
    let relative = |v: [f64; 3]| std::array::from_fn(|a| v[a] - v_cm[a]);
    // a second pass of draws for the velocities this process does not hold
    let t = if part == (0..n) {
        kinetic_energy(mine.velocity.iter().map(|&v| (m, relative(v))))
    } else {
        kinetic_energy(PlummerDraws::new(n, seed).map(|(_, v)| (m, relative(v))))
    };
    for x in &mut mine.position {
        *x = std::array::from_fn(|a| x[a] - x_cm[a]);
    }
    for v in &mut mine.velocity {
        *v = relative(*v);
    }
    scale_to_virial(
        &mut mine.velocity,
        -3.0 * std::f64::consts::PI / 32.0 * law.g(),
        t,
    );
    mine
}

/// The Plummer sphere's draws in input order: each body's position and
/// velocity before the centre-of-mass shift and the virial scaling.
struct PlummerDraws {
    rng: Rng,
    left: usize,
}

impl PlummerDraws {
    fn new(n: usize, seed: u64) -> Self {
        PlummerDraws {
            rng: Rng::new(seed),
            left: n,
        }
    }
}

impl Iterator for PlummerDraws {
    type Item = ([f64; 3], [f64; 3]);

    fn next(&mut self) -> Option<Self::Item> {
        self.left = self.left.checked_sub(1)?;
        let rng = &mut self.rng;
        let x = MASS_TRUNCATION * rng.uniform();
        let r = 1.0 / (x.powf(-2.0 / 3.0) - 1.0).sqrt();
        let position = isotropic(rng, r);
        let q = loop {
            let (q, y) = (rng.uniform(), 0.1 * rng.uniform());
            if y < q * q * (1.0 - q * q).powf(3.5) {
                break q;
            }
        };
        let speed = q * std::f64::consts::SQRT_2 * (1.0 + r * r).powf(-0.25);
        Some((position, isotropic(rng, speed)))
    }
}

/// `W = 1/2 sum m_i phi_i` of `law` by the direct sum.
fn softened_potential_energy(bodies: &Bodies, law: &GravityLaw, threads: &Threads) -> f64 {
    let n = bodies.len();
    let mut acc = vec![[0.0; 3]; n];
    let mut phi = vec![0.0; n];
    let sources = Sources {
        mass: &bodies.mass,
        position: &bodies.position,
    };
    DirectSum::new(*law, n).compute(
        &sources,
        FieldOut {
            acc: &mut acc,
            phi: &mut phi,
        },
        threads,
    );
    0.5 * bodies
        .mass
        .iter()
        .zip(&phi)
        .map(|(m, p)| m * p)
        .sum::<f64>()
}

/// `T = 1/2 sum m_i |v_i|^2` of the bodies' `(m_i, v_i)`, summed in input order.
fn kinetic_energy(bodies: impl Iterator<Item = (f64, [f64; 3])>) -> f64 {
    0.5 * bodies
        .map(|(m, v)| m * (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]))
        .sum::<f64>()
}

/// [`kinetic_energy`] of `bodies`.
fn kinetic_energy_of(bodies: &Bodies) -> f64 {
    kinetic_energy(
        bodies
            .mass
            .iter()
            .copied()
            .zip(bodies.velocity.iter().copied()),
    )
}

/// The whole sphere's `n` equal masses `1 / n` at the draws, moved to their
/// centre-of-mass frame.
fn centred_draws(n: usize, seed: u64) -> Bodies {
    let mut bodies = Bodies {
        mass: vec![1.0 / n as f64; n],
        ..Bodies::default()
    };
    (bodies.position, bodies.velocity) = PlummerDraws::new(n, seed).unzip();
    to_centre_of_mass_frame(&mut bodies);
    bodies
}

/// Scales `velocity` by `sqrt(-W / 2T)`, so that `2 T = |W|` (none if `T = 0`).
fn scale_to_virial(velocity: &mut [[f64; 3]], w: f64, t: f64) {
    if t > 0.0 {
        let scale = (-w / (2.0 * t)).sqrt();
        for v in velocity {
            *v = v.map(|c| c * scale);
        }
    }
}

/// A vector of length `r` in a uniformly random direction.
fn isotropic(rng: &mut Rng, r: f64) -> [f64; 3] {
    let cos_theta = 2.0 * rng.uniform() - 1.0;
    let phi = std::f64::consts::TAU * rng.uniform();
    let sin_theta = (1.0 - cos_theta * cos_theta).sqrt();
    [
        r * sin_theta * phi.cos(),
        r * sin_theta * phi.sin(),
        r * cos_theta,
    ]
}

/// Subtracts the centre-of-mass position and velocity.
fn to_centre_of_mass_frame(bodies: &mut Bodies) {
    let total: f64 = bodies.mass.iter().sum();
    for field in [&mut bodies.position, &mut bodies.velocity] {
        let mean: [f64; 3] = std::array::from_fn(|a| {
            bodies
                .mass
                .iter()
                .zip(field.iter())
                .map(|(m, x)| m * x[a])
                .sum::<f64>()
                / total
        });
        for x in field.iter_mut() {
            for a in 0..3 {
                x[a] -= mean[a];
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The whole sphere made as the draws, shifted and scaled in memory.
    fn reference(n: usize, seed: u64, law: &GravityLaw) -> Bodies {
        let mut bodies = centred_draws(n, seed);
        let t = kinetic_energy_of(&bodies);
        let w = if n <= EXACT_VIRIAL_MAX_N {
            softened_potential_energy(&bodies, law, &Threads::single())
        } else {
            -3.0 * std::f64::consts::PI / 32.0 * law.g()
        };
        scale_to_virial(&mut bodies.velocity, w, t);
        bodies
    }

    #[test]
    fn parts_are_the_whole_spheres_bodies() {
        let law = GravityLaw::new(1.0, 0.01, 0.0).unwrap();
        // two threads for the exact virial's direct sum, one in the reference
        let threads = Threads::new(2).unwrap();
        for n in [500, EXACT_VIRIAL_MAX_N + 1, 30_007] {
            let whole = reference(n, 7, &law);
            assert!(plummer(n, 7, &law, &threads) == whole, "n = {n}");
            for part in [0..0, 0..1, 3..n / 3, n / 3..n - 1, n - 1..n] {
                let got = plummer_part(n, 7, &law, &threads, part.clone());
                assert!(got == whole.part(part.clone()), "n = {n}, part {part:?}");
            }
        }
        let moved = reference(30_007, 8, &law);
        assert!(moved != reference(30_007, 7, &law));
        let mean = |a: usize| moved.position.iter().map(|x| x[a]).sum::<f64>() / 30_007.0;
        assert!((0..3).all(|a| mean(a).abs() < 1e-13));
    }
}
