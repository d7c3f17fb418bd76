//! Cloud-in-cell: a particle at mesh coordinate `u = (x - origin) / h` spreads
//! over the 8 nodes around it with weights `prod_a w_a`, `w_a = 1 - f_a` at node
//! `floor(u_a)` and `f_a` at the next, `f_a = u_a - floor(u_a)`; a mesh field is
//! read back with the same weights.

use super::slab::Window;

/// Where a mesh lies and whether it wraps.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Geometry {
    /// The position of node `(0, 0, 0)`.
    pub(crate) origin: [f64; 3],
    /// The cell side `h`.
    pub(crate) cell: f64,
    /// Nodes per axis.
    pub(crate) grid: usize,
    /// Periodic (indices wrap) or isolated (particles lie inside the mesh).
    pub(crate) periodic: bool,
}

/// The 8 nodes and weights of one particle.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Stencil {
    node: [[usize; 2]; 3],
    weight: [[f64; 2]; 3],
}

impl Geometry {
    /// The stencil of position `x`. Periodic positions are wrapped into the mesh;
    /// isolated ones must lie in `[0, grid - 1)` mesh units and are clamped there.
    #[inline]
    pub(crate) fn stencil(&self, x: &[f64; 3]) -> Stencil {
        let n = self.grid;
        let mut node = [[0; 2]; 3];
        let mut weight = [[0.0; 2]; 3];
        for a in 0..3 {
            let u = (x[a] - self.origin[a]) / self.cell;
            let (i, f) = if self.periodic {
                let u = u.rem_euclid(n as f64);
                let i = u.floor();
                // rem_euclid may round up to n itself
                if i as usize >= n {
                    (0, 0.0)
                } else {
                    (i as usize, u - i)
                }
            } else {
                let i = u.floor().clamp(0.0, (n - 2) as f64);
                (i as usize, (u - i).clamp(0.0, 1.0))
            };
            node[a] = [i, if i + 1 == n { 0 } else { i + 1 }];
            weight[a] = [1.0 - f, f];
        }
        Stencil { node, weight }
    }
}

impl Stencil {
    /// The two planes (along axis 0) of the stencil's nodes, the lower first
    /// (the upper wraps to 0 on a periodic mesh).
    #[inline]
    pub(crate) fn planes(&self) -> [usize; 2] {
        self.node[0]
    }

    /// Calls `visit(index, weight)` for those of the 8 nodes whose plane
    /// `window` holds, `index` being the node's in the window's planes of a
    /// row-major `grid^3` mesh, in a fixed order.
    #[inline]
    pub(crate) fn each(&self, grid: usize, window: Window, mut visit: impl FnMut(usize, f64)) {
        for a in 0..2 {
            let Some(plane) = window.local(self.node[0][a]) else {
                continue;
            };
            for b in 0..2 {
                let row = (plane * grid + self.node[1][b]) * grid;
                let wab = self.weight[0][a] * self.weight[1][b];
                for c in 0..2 {
                    visit(row + self.node[2][c], wab * self.weight[2][c]);
                }
            }
        }
    }

    /// `sum_ab w_a w_b g(a - b)` over the node pairs of this stencil, `g` having
    /// the value `own[c]` at an offset with `c` nonzero (unit) components: per
    /// axis the pair is the same node with weight `s = w0^2 + w1^2` or adjacent
    /// nodes with weight `d = 2 w0 w1`.
    #[inline]
    pub(crate) fn own(&self, own: &[f64; 4]) -> f64 {
        let s = self.weight.map(|w| w[0] * w[0] + w[1] * w[1]);
        let d = self.weight.map(|w| 2.0 * w[0] * w[1]);
        own[0] * s[0] * s[1] * s[2]
            + own[1] * (d[0] * s[1] * s[2] + s[0] * d[1] * s[2] + s[0] * s[1] * d[2])
            + own[2] * (d[0] * d[1] * s[2] + d[0] * s[1] * d[2] + s[0] * d[1] * d[2])
            + own[3] * d[0] * d[1] * d[2]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::longrange::mesh::slab::part;
    use crate::random::Rng;

    /// The masses of `(m, x)` assigned to the planes of `window`, particle by
    /// particle in input order.
    fn assign(geometry: &Geometry, m: &[f64], x: &[[f64; 3]], window: Window) -> Vec<f64> {
        let n = geometry.grid;
        let mut mass = vec![0.0; window.count() * n * n];
        for (x, &m) in x.iter().zip(m) {
            geometry.stencil(x).each(n, window, |k, w| mass[k] += w * m);
        }
        mass
    }

    #[test]
    fn slab_by_slab_assignment_has_the_bits_of_the_whole() {
        let mut rng = Rng::new(17);
        let n = 16;
        let x: Vec<[f64; 3]> = (0..3000)
            .map(|_| std::array::from_fn(|_| 4.0 * rng.uniform() - 2.0))
            .collect();
        let m: Vec<f64> = (0..x.len()).map(|_| 0.5 + rng.uniform()).collect();
        for (periodic, side) in [(true, n), (false, 2 * n)] {
            let geometry = Geometry {
                origin: [-2.1; 3],
                cell: 4.2 / (n - 1) as f64,
                grid: n,
                periodic,
            };
            let whole = assign(&geometry, &m, &x, Window::whole(n, side));
            // every node's sum is over the same particles in the same order
            let total: f64 = whole.iter().sum();
            let want: f64 = m.iter().sum();
            assert!((total - want).abs() < 1e-10 * want, "{total} {want}");
            for ranks in [2, 3, 5] {
                let mut joined = Vec::new();
                for r in 0..ranks {
                    let planes = part(n, r, ranks);
                    let window = Window::planes(planes.start, planes.len(), side);
                    joined.extend(assign(&geometry, &m, &x, window));
                }
                assert_eq!(joined, whole, "periodic {periodic}, {ranks} slabs");
            }
        }
    }
}
