//! The M4' mesh of the vortex-in-cell solver: where a 2D mesh lies, the 4 x 4
//! nodes and weights of a particle (`M4'(x / H) M4'(y / H)`, from
//! [`crate::interpolation`]), and the assignment of circulations to a range of
//! the mesh's rows.

use crate::interpolation::m4prime_stencil;

/// Where the mesh lies: node `(i, j)` is at `origin + H (i, j)`, stored at
/// `i grid + j` (axis 0 is `x`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Plane {
    /// The position of node `(0, 0)`.
    pub(super) origin: [f64; 2],
    /// The cell side `H`.
    pub(super) cell: f64,
    /// Nodes per axis.
    pub(super) grid: usize,
    /// Periodic (indices wrap) or unbounded.
    pub(super) periodic: bool,
}

/// The 4 x 4 nodes and weights of one particle.
pub(super) struct Stencil {
    /// The stencil's row: `floor(u_x)` (wrapped into the mesh if periodic).
    pub(super) row: usize,
    /// Node indices along each axis.
    pub(super) node: [[usize; 4]; 2],
    /// Their weights.
    pub(super) weight: [[f64; 4]; 2],
}

impl Plane {
    /// The M4' stencil of `x`. Periodic positions are wrapped into the mesh;
    /// unbounded ones lie at least 2 cells inside it (and are clamped there).
    #[inline(always)]
    pub(super) fn stencil(&self, x: &[f64; 2]) -> Stencil {
        let n = self.grid;
        let mut node = [[0; 4]; 2];
        let mut weight = [[0.0; 4]; 2];
        let mut row = 0;
        for a in 0..2 {
            let u = (x[a] - self.origin[a]) / self.cell;
            let (first, w) = if self.periodic {
                m4prime_stencil(u.rem_euclid(n as f64))
            } else {
                m4prime_stencil(u.clamp(1.0, (n - 3) as f64))
            };
            for (k, out) in node[a].iter_mut().enumerate() {
                *out = if self.periodic {
                    (first + k as i64).rem_euclid(n as i64) as usize
                } else {
                    (first + k as i64) as usize
                };
            }
            weight[a] = w;
            if a == 0 {
                // node 1 is floor(u), wrapped
                row = node[0][1];
            }
        }
        Stencil { row, node, weight }
    }
}

/// The node circulations `w_g H^2` of the rows `r0..` that `rows` holds (whole
/// rows of `grid`): the particles of stencil rows `r0 - 2 ..= r1` (wrapped if
/// periodic) that touch them, row by row in sorted order, so that every node
/// sums its particles in an order fixed by the data (the same whatever rows a
/// task or a rank holds).
pub(super) fn assign_rows(
    plane: &Plane,
    sorted: &[[f64; 3]],
    starts: &[usize],
    r0: usize,
    rows: &mut [f64],
) {
    let n = plane.grid as i64;
    rows.fill(0.0);
    let r0 = r0 as i64;
    let r1 = r0 + (rows.len() / plane.grid) as i64;
    let (first, last) = if plane.periodic {
        (r0 - 2, r1)
    } else {
        ((r0 - 2).max(0), r1.min(n - 1))
    };
    for base in first..=last {
        let wrapped = base.rem_euclid(n) as usize;
        for p in &sorted[starts[wrapped]..starts[wrapped + 1]] {
            let s = plane.stencil(&[p[0], p[1]]);
            for (k, &wx) in s.weight[0].iter().enumerate() {
                // the stencil's rows are base - 1 ..= base + 2, unwrapped
                let r = base - 1 + k as i64;
                if r < r0 || r >= r1 {
                    continue;
                }
                let gx = p[2] * wx;
                let row = &mut rows[(r - r0) as usize * plane.grid..];
                for (&c, &wy) in s.node[1].iter().zip(&s.weight[1]) {
                    row[c] += gx * wy;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::longrange::mesh::slab::part;
    use crate::random::Rng;

    #[test]
    fn rows_assigned_in_parts_have_the_bits_of_the_whole() {
        let mut rng = Rng::new(4);
        let n = 32;
        let x: Vec<[f64; 3]> = (0..4000)
            .map(|_| {
                [
                    3.0 * rng.uniform() - 1.5,
                    3.0 * rng.uniform() - 1.5,
                    rng.uniform() - 0.4,
                ]
            })
            .collect();
        for periodic in [true, false] {
            let plane = Plane {
                origin: [-1.6; 2],
                cell: 3.2 / (n - 6) as f64,
                grid: n,
                periodic,
            };
            // particles in stencil-row order, input order within a row
            let mut sorted = x.clone();
            sorted.sort_by_key(|p| plane.stencil(&[p[0], p[1]]).row);
            let mut starts = vec![0; n + 1];
            for p in &sorted {
                starts[plane.stencil(&[p[0], p[1]]).row + 1] += 1;
            }
            for r in 0..n {
                starts[r + 1] += starts[r];
            }
            let mut whole = vec![0.0; n * n];
            assign_rows(&plane, &sorted, &starts, 0, &mut whole);
            let total: f64 = whole.iter().sum();
            let want: f64 = x.iter().map(|p| p[2]).sum();
            assert!((total - want).abs() < 1e-10, "{total} {want}");
            for parts in [2, 3, 5] {
                let mut joined = Vec::new();
                for k in 0..parts {
                    let rows = part(n, k, parts);
                    let mut mine = vec![0.0; rows.len() * n];
                    assign_rows(&plane, &sorted, &starts, rows.start, &mut mine);
                    joined.extend(mine);
                }
                assert_eq!(joined, whole, "periodic {periodic}, {parts} parts");
            }
        }
    }
}
