//! The cell grid: cells of side >= cutoff, O(1) cell address, the 3^D stencil with
//! periodic image shifts, and the colouring that lets cells be processed in parallel.

use crate::geometry::{Domain, GeometryError};

/// Relative margin by which a cell side exceeds the cutoff, so that rounding in the
/// cell address can never put two particles closer than the cutoff two cells apart.
const SIDE_MARGIN: f64 = 1e-10;

/// A regular grid of `M_0 x ... x M_{D-1}` cells over a domain.
///
/// Cell `(c_0, ..., c_{D-1})` has the index `c_0 + M_0 (c_1 + M_1 c_2)`; a point `x`
/// lies in cell `c_k = floor((x_k - lo_k) / s_k)` (clamped to the grid), where the side
/// `s_k = L_k / M_k > cutoff`. On open axes particles beyond the grid are clamped
/// into the outermost cells, which stays correct because those cells are wider than
/// the cutoff.
#[derive(Clone, Debug, PartialEq)]
pub struct CellGrid<const D: usize> {
    dims: [usize; D],
    lo: [f64; D],
    inv_side: [f64; D],
    length: [f64; D],
    periodic: [bool; D],
}

/// One neighbour cell seen from a home cell: its index and the image shift to add to
/// the positions of its particles (non-zero only across a periodic face).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NeighbourCell<const D: usize> {
    /// Index of the neighbour cell.
    pub cell: usize,
    /// Shift added to the neighbour's positions: `x_j + shift` is the image near the home cell.
    pub shift: [f64; D],
    /// True when `shift` is not zero on some axis.
    pub shifted: bool,
    /// The shift as an image code (see [`image_code`]).
    pub image: u8,
}

/// Consecutive cells `first_cell..=last_cell` of a stencil seen at one image.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StencilRun<const D: usize> {
    /// First cell of the run.
    pub first_cell: usize,
    /// Last cell of the run (inclusive).
    pub last_cell: usize,
    /// Shift added to the run's positions.
    pub shift: [f64; D],
    /// True when `shift` is non-zero.
    pub shifted: bool,
    /// The shift as an image code.
    pub image: u8,
    /// True when the run holds the home cell itself (unshifted).
    pub holds_home: bool,
}

/// Which part of the 3^D stencil to visit.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StencilKind {
    /// The home cell and the (3^D - 1) / 2 "forward" neighbours: every pair once.
    Half,
    /// All 3^D cells: every particle sees all of its neighbours.
    Full,
}

impl<const D: usize> CellGrid<D> {
    /// Grid for `domain` with sides of at least `cutoff`, and at most about
    /// `2 n_particles + 64` cells (sparser grids only waste time on empty cells).
    pub fn new(domain: &Domain<D>, cutoff: f64, n_particles: usize) -> Result<Self, GeometryError> {
        domain.check_cutoff(cutoff)?;
        let mut dims = [1usize; D];
        for d in 0..D {
            dims[d] = Self::cells_along(domain.length[d], cutoff);
        }
        let cap = (2 * n_particles + 64) as f64;
        while dims.iter().map(|&m| m as f64).product::<f64>() > cap {
            let widest = (0..D).max_by_key(|&d| dims[d]).unwrap_or(0);
            dims[widest] = (dims[widest] / 2).max(1);
        }
        Self::with_dims(domain, dims, cutoff)
    }

    /// The cells along an axis of length `length` for sides of at least
    /// `side`: `floor(L / side)` (at least one), as [`CellGrid::new`] cuts it.
    pub fn cells_along(length: f64, side: f64) -> usize {
        let cells = (length / side * (1.0 - SIDE_MARGIN)).floor();
        if cells >= 1.0 {
            cells.min(1e9) as usize
        } else {
            1
        }
    }

    /// The grid of `dims[d] >= 1` cells along each axis of `domain`, whose
    /// sides must be at least `cutoff` where there are several (one cell
    /// holds an axis whatever its length; a periodic axis needs `L >= 2
    /// cutoff`).
    pub fn with_dims(
        domain: &Domain<D>,
        dims: [usize; D],
        cutoff: f64,
    ) -> Result<Self, GeometryError> {
        domain.check_cutoff(cutoff)?;
        assert!(
            (0..D)
                .all(|d| dims[d] == 1
                    || (dims[d] > 1 && domain.length[d] / dims[d] as f64 >= cutoff)),
            "cells {dims:?} of {:?} narrower than {cutoff}",
            domain.length
        );
        Ok(CellGrid {
            dims,
            lo: domain.lo,
            inv_side: std::array::from_fn(|d| dims[d] as f64 / domain.length[d]),
            length: domain.length,
            periodic: std::array::from_fn(|d| domain.is_periodic(d)),
        })
    }

    /// Cells per axis.
    pub fn dims(&self) -> [usize; D] {
        self.dims
    }

    /// Total number of cells.
    pub fn num_cells(&self) -> usize {
        self.dims.iter().product()
    }

    /// Index of the cell holding `x` (clamped onto the grid).
    #[inline]
    pub fn cell_of(&self, x: &[f64; D]) -> usize {
        let mut idx = 0;
        for d in (0..D).rev() {
            let c = ((x[d] - self.lo[d]) * self.inv_side[d]) as isize;
            let c = c.clamp(0, self.dims[d] as isize - 1) as usize;
            idx = idx * self.dims[d] + c;
        }
        idx
    }

    /// Where `x`, a point of cell `cell`, comes in the walk through the cell that
    /// [`CellList::order_cells_in_columns`](super::CellList::order_cells_in_columns)
    /// sorts by: `(column, along)`. The cell is cut in half along every axis but
    /// the last into `2^(D-1)` columns, numbered in Gray-code order (each column
    /// next to the one before it); `along` is the last coordinate, negated in
    /// odd columns, so that the walk goes up one column and down the next.
    #[inline]
    pub fn column_key(&self, cell: usize, x: &[f64; D]) -> (u32, f64) {
        let base = self.coords(cell);
        let mut gray = 0u32;
        for d in 0..D - 1 {
            let within = (x[d] - self.lo[d]) * self.inv_side[d] - base[d] as f64;
            gray = gray << 1 | u32::from(within >= 0.5);
        }
        // the rank of a Gray code g is g ^ (g >> 1) ^ (g >> 2) ^ ...
        let mut column = gray;
        let mut shifted = gray >> 1;
        while shifted != 0 {
            column ^= shifted;
            shifted >>= 1;
        }
        let along = x[D - 1];
        (
            column,
            if column.is_multiple_of(2) {
                along
            } else {
                -along
            },
        )
    }

    /// Grid coordinates of a cell index.
    #[inline]
    pub fn coords(&self, mut idx: usize) -> [usize; D] {
        std::array::from_fn(|d| {
            let c = idx % self.dims[d];
            idx /= self.dims[d];
            c
        })
    }

    /// The cell at (possibly out-of-range) coordinates `c`, with the image shift of
    /// its particles; `None` when `c` leaves the grid through an open face.
    #[inline]
    pub fn resolve(&self, c: [isize; D]) -> Option<NeighbourCell<D>> {
        let mut idx = 0;
        let mut wraps = [0isize; D];
        for d in (0..D).rev() {
            let m = self.dims[d] as isize;
            wraps[d] = c[d].div_euclid(m);
            if wraps[d] != 0 && !self.periodic[d] {
                return None;
            }
            idx = idx * self.dims[d] + c[d].rem_euclid(m) as usize;
        }
        Some(NeighbourCell {
            cell: idx,
            shift: self.image_shift(image_code(wraps)),
            shifted: wraps.iter().any(|&w| w != 0),
            image: image_code(wraps),
        })
    }

    /// The stencil of `home` as runs of consecutive cells with one image shift: the
    /// particles of a run are contiguous in the cell list, so each run is one scan.
    /// Runs come in offset order (lexicographic, x fastest). Returns how many were
    /// written.
    pub fn stencil_runs(
        &self,
        home: usize,
        kind: StencilKind,
        out: &mut [StencilRun<D>; 27],
    ) -> usize {
        let base = self.coords(home);
        let mut n = 0;
        for offset in offsets::<D>(kind) {
            let c = std::array::from_fn(|d| base[d] as isize + offset[d]);
            let Some(nb) = self.resolve(c) else { continue };
            let is_home = offset.iter().all(|&o| o == 0);
            if n > 0 && out[n - 1].image == nb.image && out[n - 1].last_cell + 1 == nb.cell {
                out[n - 1].last_cell = nb.cell;
                out[n - 1].holds_home |= is_home;
            } else {
                out[n] = StencilRun {
                    first_cell: nb.cell,
                    last_cell: nb.cell,
                    shift: nb.shift,
                    shifted: nb.shifted,
                    image: nb.image,
                    holds_home: is_home,
                };
                n += 1;
            }
        }
        n
    }

    /// The shift vector `w_k L_k` of an image code (see [`image_code`]).
    #[inline]
    pub fn image_shift(&self, mut code: u8) -> [f64; D] {
        std::array::from_fn(|d| {
            let w = (code % 3) as f64 - 1.0;
            code /= 3;
            w * self.length[d]
        })
    }

    /// Colours per axis for anchored-block passes: 1 for a single cell, 3 for an odd
    /// periodic count (the last cell gets its own colour), otherwise 2.
    fn colours_per_axis(&self, d: usize) -> usize {
        match self.dims[d] {
            1 => 1,
            m if self.periodic[d] && m % 2 == 1 => 3,
            _ => 2,
        }
    }

    /// Number of colours of [`CellGrid::colour_of`].
    pub fn num_colours(&self) -> usize {
        (0..D).map(|d| self.colours_per_axis(d)).product()
    }

    /// The colour of a cell, such that the blocks `c + {0, 1}^D` (wrapped) of two
    /// different cells of one colour never share a cell: per axis `c_k mod 2`, except
    /// that on a periodic axis with an odd count the last cell has colour 2.
    pub fn colour_of(&self, cell: usize) -> usize {
        let c = self.coords(cell);
        let mut colour = 0;
        for d in (0..D).rev() {
            let per_axis = self.colours_per_axis(d);
            let k = if per_axis == 3 && c[d] == self.dims[d] - 1 {
                2
            } else {
                c[d] % 2
            };
            colour = colour * per_axis + k.min(per_axis - 1);
        }
        colour
    }

    /// The cells grouped by colour: `result[c]` lists the anchors of colour `c` in
    /// index order.
    pub fn anchors_by_colour(&self) -> Vec<Vec<u32>> {
        let mut groups = vec![Vec::new(); self.num_colours()];
        for cell in 0..self.num_cells() {
            groups[self.colour_of(cell)].push(cell as u32);
        }
        groups
    }

    /// The cell pairs an anchor cell `h` owns: for each half-stencil offset `o` the pair
    /// `(h - min(0, o), h + max(0, o))`, both inside the block `h + {0, 1}^D`. Every
    /// neighbouring cell pair (with its image) is owned by exactly one anchor. Each
    /// entry is `(first cell, second cell, shift of the second relative to the first)`.
    pub fn anchored_pairs(&self, h: usize, out: &mut [AnchoredPair<D>; 14]) -> usize {
        let base = self.coords(h);
        let mut n = 0;
        for offset in offsets::<D>(StencilKind::Half) {
            let first: [isize; D] = std::array::from_fn(|d| base[d] as isize - offset[d].min(0));
            let second: [isize; D] = std::array::from_fn(|d| base[d] as isize + offset[d].max(0));
            if let (Some(a), Some(b)) = (self.resolve(first), self.resolve(second)) {
                let wraps: [isize; D] = std::array::from_fn(|d| {
                    let m = self.dims[d] as isize;
                    second[d].div_euclid(m) - first[d].div_euclid(m)
                });
                out[n] = AnchoredPair {
                    first: a.cell,
                    second: b.cell,
                    shift: self.image_shift(image_code(wraps)),
                    shifted: wraps.iter().any(|&w| w != 0),
                };
                n += 1;
            }
        }
        n
    }
}

/// A pair of cells processed together by an anchor (see [`CellGrid::anchored_pairs`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AnchoredPair<const D: usize> {
    /// The first cell (its particles are `i`).
    pub first: usize,
    /// The second cell (its particles are `j`, at `x_j + shift`).
    pub second: usize,
    /// Image shift of the second cell's particles.
    pub shift: [f64; D],
    /// True when `shift` is non-zero.
    pub shifted: bool,
}

impl<const D: usize> Default for AnchoredPair<D> {
    fn default() -> Self {
        AnchoredPair {
            first: 0,
            second: 0,
            shift: [0.0; D],
            shifted: false,
        }
    }
}

impl<const D: usize> Default for StencilRun<D> {
    fn default() -> Self {
        StencilRun {
            first_cell: 0,
            last_cell: 0,
            shift: [0.0; D],
            shifted: false,
            image: image_code([0; D]),
            holds_home: false,
        }
    }
}

/// Encodes an image, `w_k` periodic wraps per axis with `w_k` in {-1, 0, 1}, as the
/// integer `sum_k (w_k + 1) 3^k` (13 is the unshifted image in 3D, 4 in 2D).
#[inline]
pub fn image_code<const D: usize>(wraps: [isize; D]) -> u8 {
    let mut code = 0;
    for d in (0..D).rev() {
        debug_assert!((-1..=1).contains(&wraps[d]), "image beyond the nearest one");
        code = code * 3 + (wraps[d] + 1) as u8;
    }
    code
}

/// The offsets of the stencil in lexicographic order (x fastest). The half stencil
/// keeps the zero offset and the offsets whose last non-zero component is positive;
/// the zero offset is then the first one.
pub fn offsets<const D: usize>(kind: StencilKind) -> impl Iterator<Item = [isize; D]> {
    (0..3usize.pow(D as u32))
        .map(|mut k| {
            std::array::from_fn(|_| {
                let o = (k % 3) as isize - 1;
                k /= 3;
                o
            })
        })
        .filter(move |o: &[isize; D]| match kind {
            StencilKind::Full => true,
            StencilKind::Half => o.iter().rev().find(|&&v| v != 0).is_none_or(|&v| v > 0),
        })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Boundary;

    #[test]
    fn stencil_sizes() {
        assert_eq!(offsets::<2>(StencilKind::Half).count(), 5);
        assert_eq!(offsets::<2>(StencilKind::Full).count(), 9);
        assert_eq!(offsets::<3>(StencilKind::Half).count(), 14);
        assert_eq!(offsets::<3>(StencilKind::Full).count(), 27);
        // the half stencil and its mirror image make up the full stencil
        let half: Vec<[isize; 3]> = offsets(StencilKind::Half).collect();
        for o in offsets::<3>(StencilKind::Full).filter(|o| o != &[0, 0, 0]) {
            let mirrored = [-o[0], -o[1], -o[2]];
            assert!(half.contains(&o) != half.contains(&mirrored));
        }
    }

    #[test]
    fn cell_side_is_strictly_above_the_cutoff() {
        // L / rc = 4 exactly: four cells would have side == cutoff, so three are used
        let dom = Domain::periodic([10.0, 10.0]).unwrap();
        let g = CellGrid::new(&dom, 2.5, 1000).unwrap();
        assert_eq!(g.dims(), [3, 3]);
        let g = CellGrid::new(&dom, 2.4, 1000).unwrap();
        assert_eq!(g.dims(), [4, 4]);
    }

    #[test]
    fn cell_count_is_capped_for_sparse_systems() {
        let dom = Domain::periodic([1000.0, 1000.0, 1000.0]).unwrap();
        let g = CellGrid::new(&dom, 1.0, 10).unwrap();
        assert!(g.num_cells() <= 2 * 10 + 64);
    }

    #[test]
    fn points_on_faces_and_outside_are_clamped() {
        let dom = Domain::new([4.0, 4.0], [Boundary::Open; 2]).unwrap();
        let g = CellGrid::new(&dom, 1.0, 100).unwrap();
        assert_eq!(g.dims(), [3, 3]);
        assert_eq!(g.cell_of(&[4.0, 4.0]), 8);
        assert_eq!(g.cell_of(&[-3.0, 100.0]), 6);
        assert_eq!(g.cell_of(&[0.0, 0.0]), 0);
    }

    #[test]
    fn resolve_wraps_periodic_and_drops_open() {
        let dom = Domain::new([3.5, 3.5], [Boundary::Periodic, Boundary::Open]).unwrap();
        let g = CellGrid::new(&dom, 1.0, 100).unwrap();
        assert_eq!(g.dims(), [3, 3]);
        let nb = g.resolve([-1, 0]).unwrap();
        assert_eq!(nb.cell, 2);
        assert_eq!(nb.shift, [-3.5, 0.0]);
        assert!(g.resolve([0, -1]).is_none());
        assert!(g.resolve([0, 3]).is_none());
    }

    #[test]
    fn same_coloured_blocks_are_disjoint() {
        use Boundary::{Open, Periodic};
        let grids = [[1, 1], [2, 2], [3, 5], [4, 7], [6, 2], [5, 3]];
        let boundaries = [
            [Periodic, Periodic],
            [Open, Open],
            [Open, Periodic],
            [Periodic, Open],
        ];
        for (dims, boundary) in grids.into_iter().flat_map(|g| boundaries.map(|b| (g, b))) {
            // M = 1 only at L = 2 r_c exactly; otherwise L = M + 0.5 gives M cells
            let side = |m: usize| if m == 1 { 2.0 } else { m as f64 + 0.5 };
            let dom = Domain::new([side(dims[0]), side(dims[1])], boundary).unwrap();
            let g = CellGrid::new(&dom, 1.0, 10_000).unwrap();
            assert_eq!(g.dims(), dims);
            let mut owners = vec![vec![usize::MAX; g.num_cells()]; g.num_colours()];
            for h in 0..g.num_cells() {
                let colour = g.colour_of(h);
                let mut pairs = [AnchoredPair::default(); 14];
                let n = g.anchored_pairs(h, &mut pairs);
                let mut touched: Vec<usize> = pairs[..n]
                    .iter()
                    .flat_map(|p| [p.first, p.second])
                    .collect();
                touched.sort();
                touched.dedup();
                for c in touched {
                    let owner = &mut owners[colour][c];
                    assert!(*owner == usize::MAX || *owner == h, "{dims:?}: clash");
                    *owner = h;
                }
            }
        }
    }
}
