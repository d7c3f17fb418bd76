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
    let mut rng = Rng::new(seed);
    let mass = vec![1.0 / n as f64; n];
    let mut position = Vec::with_capacity(n);
    let mut velocity = Vec::with_capacity(n);
    for _ in 0..n {
        let x = MASS_TRUNCATION * rng.uniform();
        let r = 1.0 / (x.powf(-2.0 / 3.0) - 1.0).sqrt();
        position.push(isotropic(&mut rng, r));
        let q = loop {
            let (q, y) = (rng.uniform(), 0.1 * rng.uniform());
            if y < q * q * (1.0 - q * q).powf(3.5) {
                break q;
            }
        };
        let speed = q * std::f64::consts::SQRT_2 * (1.0 + r * r).powf(-0.25);
        velocity.push(isotropic(&mut rng, speed));
    }
    let mut bodies = Bodies {
        mass,
        position,
        velocity,
    };
    to_centre_of_mass_frame(&mut bodies);
    let w = if n <= EXACT_VIRIAL_MAX_N {
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
    } else {
        -3.0 * std::f64::consts::PI / 32.0 * law.g()
    };
    let t: f64 = 0.5
        * bodies
            .mass
            .iter()
            .zip(&bodies.velocity)
            .map(|(m, v)| m * (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]))
            .sum::<f64>();
    if t > 0.0 {
        let scale = (-w / (2.0 * t)).sqrt();
        for v in &mut bodies.velocity {
            *v = v.map(|c| c * scale);
        }
    }
    bodies
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
