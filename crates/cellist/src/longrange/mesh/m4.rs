//! The M4' meshes of the vortex-in-cell solvers (2D and 3D): where a mesh
//! lies, the `4^D` nodes and weights of a particle (`prod_a M4'(x_a / H)`, from
//! [`crate::interpolation`]), the particles counting-sorted by their stencil's
//! row (plane along axis 0 in 3D), the assignment of their values to a range
//! of the mesh's rows, and the interpolation of mesh fields back to them.

use super::slab::Window;
use super::RUNGS;
use crate::interpolation::m4prime_stencil;
use crate::threads::Threads;
use rayon::prelude::*;

/// Mesh cells per axis beyond the particles' bounding box on an unbounded mesh:
/// 2 on each side for the M4' support, 1 for snapping the mesh to the lattice
/// `H Z^D`, and 1 to spare.
pub(super) const SPARE_CELLS: usize = 6;

/// Where a `D`-dimensional mesh lies: node `(i_0, .., i_{D-1})` is at
/// `origin + H i`, stored row-major (axis 0 slowest: a row of the 2D mesh, a
/// plane of the 3D one, holds `grid^(D-1)` nodes).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Lattice<const D: usize> {
    /// The position of node `(0, .., 0)`.
    pub(super) origin: [f64; D],
    /// The cell side `H`.
    pub(super) cell: f64,
    /// Nodes per axis.
    pub(super) grid: usize,
    /// Periodic (indices wrap) or unbounded.
    pub(super) periodic: bool,
}

/// The 2D mesh.
pub(super) type Plane = Lattice<2>;

/// The `4^D` nodes and weights of one particle.
pub(super) struct Stencil<const D: usize> {
    /// The stencil's row (along axis 0): `floor(u_0)` (wrapped into the mesh if
    /// periodic).
    pub(super) row: usize,
    /// Node indices along each axis.
    pub(super) node: [[usize; 4]; D],
    /// Their weights.
    pub(super) weight: [[f64; 4]; D],
}

impl<const D: usize> Lattice<D> {
    /// The M4' stencil of `x`. Periodic positions are wrapped into the mesh;
    /// unbounded ones lie at least 2 cells inside it (and are clamped there).
    #[inline(always)]
    pub(super) fn stencil(&self, x: &[f64; D]) -> Stencil<D> {
        let n = self.grid;
        let mut node = [[0; 4]; D];
        let mut weight = [[0.0; 4]; D];
        let mut row = 0;
        for a in 0..D {
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

    /// Nodes in one row (axis 0 fixed): `grid^(D-1)`.
    pub(super) fn row_len(&self) -> usize {
        self.grid.pow(D as u32 - 1)
    }

    /// Calls `visit(k, w)` for the `4^(D-1)` nodes of `s` in one row, `k`
    /// being the node's index in the row and `w = prod_{a >= 1} W_a` its
    /// weight over the axes but the first, in a fixed order (the last axis
    /// fastest).
    #[inline(always)]
    pub(super) fn across(&self, s: &Stencil<D>, mut visit: impl FnMut(usize, f64)) {
        for combo in 0..1usize << (2 * (D - 1)) {
            let digit = |a: usize| (combo >> (2 * (D - 1 - a))) & 3;
            let mut k = s.node[1][digit(1)];
            let mut w = s.weight[1][digit(1)];
            for a in 2..D {
                k = k * self.grid + s.node[a][digit(a)];
                w *= s.weight[a][digit(a)];
            }
            visit(k, w);
        }
    }

    /// `sum_g f_g W(g)` of every field `f` over the nodes of `s`, each row's
    /// sum first: the fields hold the rows of `window`, [`Lattice::row_len`]
    /// numbers each. Panics if `window` lacks one of the stencil's rows.
    #[inline(always)]
    pub(super) fn gather<const F: usize>(
        &self,
        s: &Stencil<D>,
        window: Window,
        fields: [&[f64]; F],
    ) -> [f64; F] {
        let len = self.row_len();
        let mut sum = [0.0; F];
        for (&r, &wx) in s.node[0].iter().zip(&s.weight[0]) {
            let r = window
                .local(r)
                .expect("the rows around a particle of this rank's rows");
            let rows = fields.map(|f| &f[r * len..][..len]);
            let mut row = [0.0; F];
            self.across(s, |k, w| {
                for (acc, f) in row.iter_mut().zip(&rows) {
                    *acc += w * f[k];
                }
            });
            for (acc, v) in sum.iter_mut().zip(row) {
                *acc += wx * v;
            }
        }
        sum
    }

    /// Places an unbounded mesh over `positions`: the cell is the smallest rung
    /// `2^(j/8) >= extent / (grid - SPARE_CELLS)` (`extent`, the bounding box's
    /// largest side, at least `floor`), the nodes lie on the lattice `H Z^D`
    /// with the bounding box at least 2 cells inside. Returns the rung `j`.
    /// Panics if a position is not finite.
    pub(super) fn cover(&mut self, positions: &[[f64; D]], floor: f64, threads: &Threads) -> i64 {
        let init = || ([f64::INFINITY; D], [f64::NEG_INFINITY; D]);
        let (lo, hi) = threads.install(|| {
            positions
                .par_iter()
                .fold(init, |(mut lo, mut hi), x| {
                    for a in 0..D {
                        lo[a] = lo[a].min(x[a]);
                        hi[a] = hi[a].max(x[a]);
                    }
                    (lo, hi)
                })
                .reduce(init, |(l0, h0), (l1, h1)| {
                    (
                        std::array::from_fn(|a| l0[a].min(l1[a])),
                        std::array::from_fn(|a| h0[a].max(h1[a])),
                    )
                })
        });
        let extent = (0..D).map(|a| hi[a] - lo[a]).fold(0.0, f64::max);
        assert!(
            (0..D).all(|a| (hi[a] - lo[a]).is_finite()),
            "positions must be finite (bounding box {lo:?} to {hi:?})"
        );
        let need = extent.max(floor) / (self.grid - SPARE_CELLS) as f64;
        let mut rung = (RUNGS * need.log2()).ceil() as i64;
        if (rung as f64 / RUNGS).exp2() < need {
            rung += 1;
        }
        let cell = (rung as f64 / RUNGS).exp2();
        self.cell = cell;
        self.origin = lo.map(|l| cell * ((l / cell).floor() - 2.0));
        rung
    }
}

/// The particles counting-sorted by their stencil's row, each as `W` numbers:
/// its `D` coordinates, then the values it assigns (or, after an
/// interpolation, whatever the solver keeps there).
pub(super) struct Sorted<const W: usize> {
    /// Each particle's place in `entries`.
    pub(super) rank: Vec<u32>,
    /// The particles in row order, in input order within a row.
    pub(super) entries: Vec<[f64; W]>,
    /// `entries[starts[r]..starts[r + 1]]` is row `r`.
    pub(super) starts: Vec<usize>,
}

impl<const W: usize> Sorted<W> {
    /// No particles yet, for a mesh of `grid` rows.
    pub(super) fn new(grid: usize) -> Self {
        Sorted {
            rank: Vec::new(),
            entries: Vec::new(),
            starts: vec![0; grid + 1],
        }
    }

    /// Counting-sorts the particles at `positions` by stencil row on
    /// `lattice`, particle `i` as `entry(i)` (its coordinates first). Panics if
    /// a position is not finite.
    pub(super) fn sort<const D: usize>(
        &mut self,
        lattice: &Lattice<D>,
        positions: &[[f64; D]],
        entry: impl Fn(usize) -> [f64; W],
    ) {
        positions
            .par_iter()
            .map(|x| {
                assert!(
                    x.iter().all(|c| c.is_finite()),
                    "position {x:?} is not finite"
                );
                lattice.stencil(x).row as u32
            })
            .collect_into_vec(&mut self.rank);
        let starts = &mut self.starts;
        starts.fill(0);
        for &r in &self.rank {
            starts[r as usize + 1] += 1;
        }
        for r in 0..lattice.grid {
            starts[r + 1] += starts[r];
        }
        let mut cursor = starts[..lattice.grid].to_vec();
        self.entries.resize(positions.len(), [0.0; W]);
        for (i, rank) in self.rank.iter_mut().enumerate() {
            let at = &mut cursor[*rank as usize];
            self.entries[*at] = entry(i);
            *rank = *at as u32;
            *at += 1;
        }
    }

    /// The node values (`W - D` per node, interleaved) of the rows `first..`
    /// that `out` holds: each task owns a band of rows ([`assign_rows`]), fixed
    /// by the grid alone.
    pub(super) fn assign<const D: usize>(
        &self,
        lattice: &Lattice<D>,
        first: usize,
        out: &mut [f64],
    ) {
        let band = (lattice.grid / 64).max(4);
        let chunk = band * lattice.row_len() * (W - D);
        out.par_chunks_mut(chunk).enumerate().for_each(|(b, rows)| {
            assign_rows(lattice, &self.entries, &self.starts, first + b * band, rows)
        });
    }
}

/// The node values `sum_p v_p W_p(g)` (`W - D` of them per node, interleaved)
/// of the rows `r0..` that `rows` holds (whole rows): the particles of stencil
/// rows `r0 - 2 ..= r1` (wrapped if periodic) that touch them, row by row in
/// sorted order, so that every node sums its particles in an order fixed by
/// the data (the same whatever rows a task or a rank holds).
pub(super) fn assign_rows<const D: usize, const W: usize>(
    lattice: &Lattice<D>,
    sorted: &[[f64; W]],
    starts: &[usize],
    r0: usize,
    rows: &mut [f64],
) {
    let n = lattice.grid as i64;
    let values = W - D;
    let len = lattice.row_len() * values;
    rows.fill(0.0);
    let r0 = r0 as i64;
    let r1 = r0 + (rows.len() / len) as i64;
    let (first, last) = if lattice.periodic {
        (r0 - 2, r1)
    } else {
        ((r0 - 2).max(0), r1.min(n - 1))
    };
    for base in first..=last {
        let wrapped = base.rem_euclid(n) as usize;
        for p in &sorted[starts[wrapped]..starts[wrapped + 1]] {
            let s = lattice.stencil(&std::array::from_fn(|a| p[a]));
            for (k, &wx) in s.weight[0].iter().enumerate() {
                // the stencil's rows are base - 1 ..= base + 2, unwrapped
                let r = base - 1 + k as i64;
                if r < r0 || r >= r1 {
                    continue;
                }
                let mut g = [0.0; W];
                for v in D..W {
                    g[v] = p[v] * wx;
                }
                let row = &mut rows[(r - r0) as usize * len..][..len];
                lattice.across(&s, |c, w| {
                    for v in 0..values {
                        row[c * values + v] += g[D + v] * w;
                    }
                });
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
