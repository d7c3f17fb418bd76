//! The invariants and diagnostics of 3D vortex particles (thermo columns), each a
//! sum over the particles in their order:
//!
//! ```text
//! total vorticity   Omega = sum_p alpha_p
//! linear impulse    I = 1/2 sum_p x_p x alpha_p
//! energy            E = sum_p u_p . (x_p x alpha_p)     (open space)
//!                   E = 1/2 sum_p |u_p|^2 h^3           (a periodic box the particles fill)
//! enstrophy         Z = sum_p |alpha_p|^2 / h^3
//! helicity          H = sum_p u_p . alpha_p
//! ```
//!
//! and the position, radius and speed of vortex rings (weighted by `|alpha|`).

use super::initial::{cross, dot, Abc, Ring};

/// The invariants of one state.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Invariants3 {
    /// `sum alpha`.
    pub total: [f64; 3],
    /// `1/2 sum x x alpha`.
    pub impulse: [f64; 3],
    /// The kinetic energy.
    pub energy: f64,
    /// `sum |alpha|^2 / h^3`.
    pub enstrophy: f64,
    /// `sum u . alpha`.
    pub helicity: f64,
}

impl Invariants3 {
    /// The invariants of particles at `x` with strengths `alpha` and velocities
    /// `u` on a lattice of spacing `h`; `periodic`: the particles fill a periodic
    /// box (the energy as `1/2 sum |u|^2 h^3`).
    pub fn of(x: &[[f64; 3]], alpha: &[[f64; 3]], u: &[[f64; 3]], h: f64, periodic: bool) -> Self {
        let volume = h * h * h;
        let mut s = Invariants3::default();
        for ((x, a), u) in x.iter().zip(alpha).zip(u) {
            let moment = cross(*x, *a);
            for c in 0..3 {
                s.total[c] += a[c];
                s.impulse[c] += 0.5 * moment[c];
            }
            s.energy += if periodic {
                0.5 * dot(*u, *u) * volume
            } else {
                dot(*u, moment)
            };
            s.enstrophy += dot(*a, *a) / volume;
            s.helicity += dot(*u, *a);
        }
        s
    }
}

/// Where a ring is, weighted by `w_p = |alpha_p|`: `z` along its initial axis
/// (from the origin), `radius` from the axis line through its initial centre,
/// and `speed = dz/dt`, the rate of that weighted mean: with the strengths'
/// rates `dw_p/dt = alpha_p . (d alpha_p / dt) / w_p`,
///
/// ```text
/// dz/dt = (sum_p w_p u_p . a + sum_p (dw_p/dt) (z_p - z)) / sum_p w_p.
/// ```
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RingPlace {
    /// `sum |alpha| x . a / sum |alpha|`.
    pub z: f64,
    /// `sum |alpha| |x_perp| / sum |alpha|`.
    pub radius: f64,
    /// `dz/dt`.
    pub speed: f64,
}

/// Lloyd iterations of the ring tracking.
const TRACKING_ROUNDS: usize = 8;

/// The places of `rings` (with their initial axes and centres) of particles
/// at `x` with strengths `alpha`, velocities `u` and strength rates `rate`,
/// each particle counted for the ring nearest in `(z, r)` to that ring's place
/// `last` (the previous observation's): weighted k-means, so that rings that
/// pass through each other (leapfrogging) keep their identity. One ring takes
/// every particle.
pub fn ring_places(
    rings: &[Ring],
    last: &[RingPlace],
    x: &[[f64; 3]],
    alpha: &[[f64; 3]],
    u: &[[f64; 3]],
    rate: &[[f64; 3]],
) -> Vec<RingPlace> {
    let coordinates = |ring: &Ring, x: [f64; 3]| {
        let (_, _, r) = ring.cylindrical(x);
        (dot(x, ring.axis), r)
    };
    let mut places = last.to_vec();
    let rounds = if rings.len() == 1 { 1 } else { TRACKING_ROUNDS };
    let mut owner = vec![0usize; x.len()];
    for _ in 0..rounds {
        let mut sums = vec![[0.0f64; 4]; rings.len()];
        for (p, (x, a)) in x.iter().zip(alpha).enumerate() {
            let weight = dot(*a, *a).sqrt();
            let nearest = (0..rings.len())
                .min_by(|&i, &j| {
                    let d = |k: usize| {
                        let (z, r) = coordinates(&rings[k], *x);
                        (z - places[k].z).powi(2) + (r - places[k].radius).powi(2)
                    };
                    d(i).total_cmp(&d(j))
                })
                .unwrap_or(0);
            owner[p] = nearest;
            let (z, r) = coordinates(&rings[nearest], *x);
            let s = &mut sums[nearest];
            s[0] += weight;
            s[1] += weight * z;
            s[2] += weight * r;
        }
        for (place, s) in places.iter_mut().zip(&sums) {
            if s[0] > 0.0 {
                place.z = s[1] / s[0];
                place.radius = s[2] / s[0];
            }
        }
    }
    // the rate of each ring's weighted mean z, for its particles of the last round
    let mut sums = vec![[0.0f64; 2]; rings.len()];
    for p in 0..x.len() {
        let (k, a) = (owner[p], alpha[p]);
        let weight = dot(a, a).sqrt();
        if weight == 0.0 {
            continue;
        }
        let z = dot(x[p], rings[k].axis);
        let growth = dot(a, rate[p]) / weight;
        sums[k][0] += weight;
        sums[k][1] += weight * dot(u[p], rings[k].axis) + growth * (z - places[k].z);
    }
    for (place, s) in places.iter_mut().zip(&sums) {
        if s[0] > 0.0 {
            place.speed = s[1] / s[0];
        }
    }
    places
}

/// The seeded places of `rings` (no speed yet): the tracking's start.
pub fn initial_places(rings: &[Ring]) -> Vec<RingPlace> {
    rings
        .iter()
        .map(|r| RingPlace {
            z: dot(r.center, r.axis),
            radius: r.radius,
            speed: 0.0,
        })
        .collect()
}

/// The particles' vorticity `alpha_p / h^3` against the ABC flow decayed to
/// `exp(-nu t)`, relative: `(sqrt(sum |e_p|^2 / sum |w_p|^2), max |e_p| / max |w_p|)`.
pub fn abc_errors(abc: &Abc, decay: f64, x: &[[f64; 3]], alpha: &[[f64; 3]], h: f64) -> (f64, f64) {
    let volume = h * h * h;
    let (mut e2, mut w2, mut e_max, mut w_max) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
    for (x, a) in x.iter().zip(alpha) {
        let w = abc.velocity(*x).map(|c| c * decay);
        let e = [0, 1, 2].map(|c| a[c] / volume - w[c]);
        e2 += dot(e, e);
        w2 += dot(w, w);
        e_max = e_max.max(dot(e, e).sqrt());
        w_max = w_max.max(dot(w, w).sqrt());
    }
    ((e2 / w2).sqrt(), e_max / w_max)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn two_rings_are_told_apart_where_they_overlap_in_z() {
        // two coaxial rings at the same z, radii 1 and 0.5, each a set of points
        let rings = [0.0, 0.2].map(|z| Ring {
            radius: 1.0,
            circulation: 1.0,
            core: 0.1,
            center: [0.0, 0.0, z],
            axis: [0.0, 0.0, 1.0],
        });
        let mut x = Vec::new();
        for k in 0..16 {
            let t = k as f64 * std::f64::consts::PI / 8.0;
            x.push([1.2 * t.cos(), 1.2 * t.sin(), 0.1]);
            x.push([0.5 * t.cos(), 0.5 * t.sin(), 0.1]);
        }
        let alpha = vec![[0.0, 0.0, 1.0]; x.len()];
        let u = vec![[0.0, 0.0, 0.5]; x.len()];
        // the inner ring's strengths grow: its weighted z stays, the speed is u
        let rate: Vec<[f64; 3]> = (0..x.len()).map(|p| [0.0, 0.0, (p % 2) as f64]).collect();
        // last seen: the first ring large, the second small
        let last = [
            RingPlace {
                z: 0.0,
                radius: 1.1,
                speed: 0.0,
            },
            RingPlace {
                z: 0.2,
                radius: 0.6,
                speed: 0.0,
            },
        ];
        let places = ring_places(&rings, &last, &x, &alpha, &u, &rate);
        assert!((places[0].radius - 1.2).abs() < 1e-12, "{places:?}");
        assert!((places[1].radius - 0.5).abs() < 1e-12, "{places:?}");
        assert!((places[0].z - 0.1).abs() < 1e-12 && (places[1].speed - 0.5).abs() < 1e-12);
        assert!((places[0].speed - 0.5).abs() < 1e-12);
    }

    #[test]
    fn a_ring_speed_is_the_rate_of_its_weighted_position() {
        // two particles of one ring at z = 0 and z = 1, the upper one's strength
        // growing: the weighted z moves up even where nothing moves
        let ring = [Ring {
            radius: 1.0,
            circulation: 1.0,
            core: 0.1,
            center: [0.0; 3],
            axis: [0.0, 0.0, 1.0],
        }];
        let x = [[1.0, 0.0, 0.0], [1.0, 0.0, 1.0]];
        let alpha = [[0.0, 1.0, 0.0], [0.0, 1.0, 0.0]];
        let u = [[0.0; 3]; 2];
        let rate = [[0.0; 3], [0.0, 0.5, 0.0]];
        let place = ring_places(&ring, &initial_places(&ring), &x, &alpha, &u, &rate)[0];
        // z = (w0 z0 + w1 z1) / (w0 + w1); dz/dt = (dw1 (z1 - z)) / (w0 + w1) = 0.5 * 0.5 / 2
        assert!((place.z - 0.5).abs() < 1e-15);
        assert!((place.speed - 0.125).abs() < 1e-15, "{place:?}");
    }

    #[test]
    fn the_exact_abc_field_has_no_error() {
        let abc = Abc {
            a: 1.0,
            b: 1.0,
            c: 1.0,
        };
        let h = 0.5;
        let x = vec![[0.1, 0.2, 0.3], [1.0, 2.0, 3.0]];
        let decay = 0.9;
        let alpha: Vec<_> = x
            .iter()
            .map(|x| abc.velocity(*x).map(|c| c * decay * h * h * h))
            .collect();
        let (l2, max) = abc_errors(&abc, decay, &x, &alpha, h);
        assert!(l2 < 1e-15 && max < 1e-15);
        let (l2, _) = abc_errors(&abc, 1.0, &x, &alpha, h);
        // against the undecayed field every value is 0.9 of it: 10 % off
        assert!((l2 - 0.1).abs() < 1e-12, "{l2}");
    }

    #[test]
    fn invariants_of_a_pair_of_particles() {
        let x = [[1.0, 0.0, 0.0], [0.0, 2.0, 0.0]];
        let alpha = [[0.0, 1.0, 0.0], [0.0, 0.0, 3.0]];
        let u = [[1.0, 1.0, 1.0], [0.0, 0.0, -1.0]];
        let s = Invariants3::of(&x, &alpha, &u, 1.0, false);
        assert_eq!(s.total, [0.0, 1.0, 3.0]);
        // x x alpha: (1,0,0)x(0,1,0) = (0,0,1); (0,2,0)x(0,0,3) = (6,0,0)
        assert_eq!(s.impulse, [3.0, 0.0, 0.5]);
        assert_eq!(s.energy, 1.0);
        assert_eq!(s.enstrophy, 10.0);
        assert_eq!(s.helicity, 1.0 - 3.0);
    }
}
