//! Initial vorticity fields of the 3D vortex model, sampled on a cubic lattice:
//! particle `p` at `x_p = o + h (i, j, k)` carries `alpha_p = omega(x_p) h^3` (its
//! own vorticity `alpha_p / h^3` is the field's value at its position).
//!
//! - A vortex ring of radius `R` about the axis `a` through `c`, circulation `G`
//!   and Gaussian core `s`: at distance `d` from the ring's centre line,
//!
//!   ```text
//!   omega(x) = G / (pi s^2) exp(-d^2 / s^2) e_theta(x),
//!   ```
//!
//!   `e_theta` the unit vector around the axis (right-handed about `a`), so that
//!   a ring of positive `G` moves along `+a`. The core is cut where
//!   `d > 4 s` (`exp(-16)` of the peak).
//! - The Arnold-Beltrami-Childress flow in the periodic box `[0, 2 pi)^3`,
//!
//!   ```text
//!   u = (A sin z + C cos y, B sin x + A cos z, C sin y + B cos x) = omega,
//!   ```
//!
//!   steady without viscosity and decaying as `exp(-nu t)` with it.

use std::f64::consts::PI;

/// How far from a ring's centre line its core is seeded, in cores.
pub const RING_CUT: f64 = 4.0;

/// One vortex ring.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ring {
    /// Radius `R` of the centre line.
    pub radius: f64,
    /// Circulation `G`.
    pub circulation: f64,
    /// Gaussian core `s`.
    pub core: f64,
    /// The centre `c`.
    pub center: [f64; 3],
    /// The axis `a` (a unit vector).
    pub axis: [f64; 3],
}

impl Ring {
    /// The ring's vorticity at `x`: `G / (pi s^2) exp(-d^2 / s^2) e_theta`, zero
    /// beyond `RING_CUT` cores and on the axis.
    pub fn vorticity(&self, x: [f64; 3]) -> [f64; 3] {
        let (along, radial, rho) = self.cylindrical(x);
        let d2 = (rho - self.radius).powi(2) + along * along;
        if rho == 0.0 || d2 > (RING_CUT * self.core).powi(2) {
            return [0.0; 3];
        }
        let e_r = radial.map(|c| c / rho);
        let e_theta = cross(self.axis, e_r);
        let w = self.circulation / (PI * self.core * self.core) * (-d2 / self.core.powi(2)).exp();
        e_theta.map(|c| w * c)
    }

    /// `(z, r_vector, r)`: the coordinate of `x - c` along the axis, its part
    /// perpendicular to the axis and that part's length.
    pub fn cylindrical(&self, x: [f64; 3]) -> (f64, [f64; 3], f64) {
        let d = [0, 1, 2].map(|a| x[a] - self.center[a]);
        let along = dot(d, self.axis);
        let radial = [0, 1, 2].map(|a| d[a] - along * self.axis[a]);
        (along, radial, dot(radial, radial).sqrt())
    }

    /// The thin-ring speed of a Gaussian core (Fraenkel, Saffman):
    /// `U = G / (4 pi R) (ln(8 R / s_e) - 0.558)` with the effective core
    /// `s_e^2 = s^2 + 2 sigma^2` of the core widened by blobs of variance `sigma^2`.
    pub fn thin_speed(&self, sigma: f64) -> f64 {
        let effective = (self.core * self.core + 2.0 * sigma * sigma).sqrt();
        self.circulation / (4.0 * PI * self.radius) * ((8.0 * self.radius / effective).ln() - 0.558)
    }
}

/// The ABC flow's coefficients.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Abc {
    /// `A`.
    pub a: f64,
    /// `B`.
    pub b: f64,
    /// `C`.
    pub c: f64,
}

impl Abc {
    /// The side of the ABC flow's periodic box, `2 pi`.
    pub const SIDE: f64 = 2.0 * PI;

    /// `u(x) = omega(x) = (A sin z + C cos y, B sin x + A cos z, C sin y + B cos x)`.
    pub fn velocity(&self, x: [f64; 3]) -> [f64; 3] {
        let Abc { a, b, c } = *self;
        [
            a * x[2].sin() + c * x[1].cos(),
            b * x[0].sin() + a * x[2].cos(),
            c * x[1].sin() + b * x[0].cos(),
        ]
    }
}

/// What seeds the particles.
#[derive(Clone, Debug, PartialEq)]
pub enum InitialVorticity3 {
    /// Vortex rings (their vorticities add).
    Rings(Vec<Ring>),
    /// The ABC flow in `[0, 2 pi)^3`.
    Abc(Abc),
}

impl InitialVorticity3 {
    /// The vorticity at `x`.
    pub fn vorticity(&self, x: [f64; 3]) -> [f64; 3] {
        match self {
            InitialVorticity3::Rings(rings) => rings.iter().fold([0.0; 3], |sum, ring| {
                let w = ring.vorticity(x);
                [0, 1, 2].map(|a| sum[a] + w[a])
            }),
            InitialVorticity3::Abc(abc) => abc.velocity(x),
        }
    }

    /// The lattice nodes `origin + h (i, j, k)` that may carry vorticity, in
    /// order (x fastest): the box of every ring's seeded torus, or the periodic
    /// box `[0, 2 pi)^3` (a whole number `n` of spacings, checked by the caller).
    fn nodes(&self, h: f64) -> (Vec<[i64; 3]>, [f64; 3]) {
        match self {
            InitialVorticity3::Rings(rings) => {
                let mut lo = [i64::MAX; 3];
                let mut hi = [i64::MIN; 3];
                for ring in rings {
                    let reach = ring.radius + RING_CUT * ring.core;
                    for a in 0..3 {
                        lo[a] = lo[a].min(((ring.center[a] - reach) / h).floor() as i64);
                        hi[a] = hi[a].max(((ring.center[a] + reach) / h).ceil() as i64);
                    }
                }
                (lattice_box(lo, hi), [0.0; 3])
            }
            InitialVorticity3::Abc(_) => {
                let n = (Abc::SIDE / h).round() as i64;
                (lattice_box([0; 3], [n - 1; 3]), [0.0; 3])
            }
        }
    }

    /// The number of lattice nodes [`seed3`] visits at spacing `h` (to refuse a
    /// lattice too large before allocating it).
    pub fn nodes_visited(&self, h: f64) -> f64 {
        match self {
            InitialVorticity3::Rings(rings) => {
                let mut lo = [f64::MAX; 3];
                let mut hi = [f64::MIN; 3];
                for ring in rings {
                    let reach = ring.radius + RING_CUT * ring.core;
                    for a in 0..3 {
                        lo[a] = lo[a].min(ring.center[a] - reach);
                        hi[a] = hi[a].max(ring.center[a] + reach);
                    }
                }
                (0..3).map(|a| (hi[a] - lo[a]) / h + 3.0).product()
            }
            InitialVorticity3::Abc(_) => (Abc::SIDE / h).round().powi(3),
        }
    }
}

/// Every node of the box `lo..=hi` (x fastest).
fn lattice_box(lo: [i64; 3], hi: [i64; 3]) -> Vec<[i64; 3]> {
    let mut nodes = Vec::new();
    for k in lo[2]..=hi[2] {
        for j in lo[1]..=hi[1] {
            for i in lo[0]..=hi[0] {
                nodes.push([i, j, k]);
            }
        }
    }
    nodes
}

/// The particles of `field` on the lattice of spacing `h` through the origin:
/// positions and strengths `alpha_p = omega(x_p) h^3`, the nodes where the field
/// is zero left out (every node of the ABC flow is kept).
pub fn seed3(field: &InitialVorticity3, h: f64) -> (Vec<[f64; 3]>, Vec<[f64; 3]>) {
    let (nodes, origin) = field.nodes(h);
    let volume = h * h * h;
    let keep_zero = matches!(field, InitialVorticity3::Abc(_));
    let mut positions = Vec::new();
    let mut alpha = Vec::new();
    for node in nodes {
        let x = [0, 1, 2].map(|a| origin[a] + h * node[a] as f64);
        let w = field.vorticity(x);
        if keep_zero || w.iter().any(|&c| c != 0.0) {
            positions.push(x);
            alpha.push(w.map(|c| c * volume));
        }
    }
    (positions, alpha)
}

/// `a . b`.
pub fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// `a x b`.
pub fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ring() -> Ring {
        Ring {
            radius: 1.0,
            circulation: 2.0,
            core: 0.2,
            center: [0.1, -0.2, 0.3],
            axis: [0.0, 0.0, 1.0],
        }
    }

    #[test]
    fn a_ring_carries_its_circulation_through_a_half_plane() {
        // the flux of omega through the half plane y = c_y, x > c_x (normal +y
        // is e_theta there for the axis +z) is G, to the truncation's exp(-16)
        // (the sum covers the cut core, 0.1 to 2.1 from the axis)
        let r = ring();
        let h = 0.005;
        let mut flux = 0.0;
        for i in 0..400 {
            for k in -200..200 {
                let x = [
                    r.center[0] + 0.1 + (i as f64 + 0.5) * h,
                    r.center[1],
                    r.center[2] + (k as f64 + 0.5) * h,
                ];
                flux += r.vorticity(x)[1] * h * h;
            }
        }
        assert!(
            (flux - r.circulation).abs() < 1e-6 * r.circulation,
            "{flux}"
        );
        assert!(
            (flux - r.circulation).abs() > 1e-9 * r.circulation,
            "the cut at 4 cores: {flux}"
        );
    }

    #[test]
    fn seeded_strengths_are_the_field_times_the_cell_volume() {
        let field = InitialVorticity3::Rings(vec![ring()]);
        let h = 0.1;
        let (x, alpha) = seed3(&field, h);
        assert!(!x.is_empty());
        for (x, a) in x.iter().zip(&alpha) {
            let w = field.vorticity(*x);
            for c in 0..3 {
                assert_eq!(a[c], w[c] * (h * h * h));
            }
            // on the lattice through the origin
            for c in 0..3 {
                assert!((x[c] / h - (x[c] / h).round()).abs() < 1e-9);
            }
        }
        // the total vorticity of a ring is zero by symmetry
        let total: f64 = alpha.iter().map(|a| a[0].abs() + a[1].abs()).sum();
        let sum = alpha
            .iter()
            .fold([0.0; 3], |s, a| [s[0] + a[0], s[1] + a[1], s[2] + a[2]]);
        assert!(sum.iter().all(|c| c.abs() < 1e-9 * total), "{sum:?}");
    }

    #[test]
    fn the_abc_flow_is_its_own_vorticity() {
        // curl u = u, checked by central differences
        let abc = Abc {
            a: 1.0,
            b: 0.7,
            c: 0.4,
        };
        let x = [0.3, 1.1, -0.7];
        let e = 1e-5;
        let d = |a: usize, b: usize| {
            let mut p = x;
            let mut m = x;
            p[b] += e;
            m[b] -= e;
            (abc.velocity(p)[a] - abc.velocity(m)[a]) / (2.0 * e)
        };
        let curl = [d(2, 1) - d(1, 2), d(0, 2) - d(2, 0), d(1, 0) - d(0, 1)];
        let u = abc.velocity(x);
        for a in 0..3 {
            assert!((curl[a] - u[a]).abs() < 1e-8, "{curl:?} {u:?}");
        }
    }

    #[test]
    fn the_abc_lattice_fills_the_box() {
        let field = InitialVorticity3::Abc(Abc {
            a: 1.0,
            b: 1.0,
            c: 1.0,
        });
        let h = Abc::SIDE / 8.0;
        let (x, _) = seed3(&field, h);
        assert_eq!(x.len(), 512);
        assert_eq!(field.nodes_visited(h), 512.0);
        assert!(x
            .iter()
            .all(|p| p.iter().all(|&c| (0.0..Abc::SIDE - 0.5 * h).contains(&c))));
    }
}
