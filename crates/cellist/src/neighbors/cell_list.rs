//! The cell list: particles sorted by cell with a counting sort, O(N).

use super::grid::CellGrid;
use crate::geometry::{Domain, GeometryError};
use crate::threads::{
    counting_sort_with, fill_in_parts, map_parts, part_ranges, parts_for, DisjointSlice, Threads,
};
use std::ops::Range;

/// Particles binned into the cells of a [`CellGrid`] and stored contiguously per cell.
///
/// Build (O(N), stable, no comparison sort):
/// 1. cell id `c_i` of every particle,
/// 2. histogram `n_c`,
/// 3. exclusive prefix sum `cell_start[c] = sum_{c' < c} n_c'` (`num_cells + 1` entries),
/// 4. scatter: `order[cell_start[c_i] + rank_i] = i`, in input order within a cell.
///
/// Particle `k` of the sorted arrays is input particle `order[k]`; the particles of cell
/// `c` are `cell_start[c]..cell_start[c + 1]`. `positions` holds the wrapped positions
/// in that order.
#[derive(Clone, Debug)]
pub struct CellList<const D: usize> {
    domain: Domain<D>,
    grid: CellGrid<D>,
    cutoff: f64,
    cell_start: Vec<u32>,
    order: Vec<u32>,
    positions: Vec<[f64; D]>,
    columns: [Vec<f64>; D],
    /// False once the columns are released: rebins no longer make them.
    keeps_columns: bool,
    anchors_by_colour: Vec<Vec<u32>>,
    // scratch, kept so that rebinning does not reallocate the arrays
    cell_ids: Vec<u32>,
    counts: Vec<u32>,
}

impl<const D: usize> CellList<D> {
    /// Bins `points` into cells of side > `cutoff` over `domain`.
    pub fn build(
        domain: &Domain<D>,
        cutoff: f64,
        points: &[[f64; D]],
    ) -> Result<Self, GeometryError> {
        Self::build_on(domain, cutoff, points, None)
    }

    /// [`CellList::build`], the sort in parallel on `threads` (the same list
    /// for any thread count).
    pub fn build_in(
        domain: &Domain<D>,
        cutoff: f64,
        points: &[[f64; D]],
        threads: &Threads,
    ) -> Result<Self, GeometryError> {
        Self::build_on(domain, cutoff, points, Some(threads))
    }

    fn build_on(
        domain: &Domain<D>,
        cutoff: f64,
        points: &[[f64; D]],
        threads: Option<&Threads>,
    ) -> Result<Self, GeometryError> {
        assert!(
            points.len() < u32::MAX as usize,
            "at most 2^32 - 1 particles per cell list"
        );
        let grid = CellGrid::new(domain, cutoff, points.len())?;
        Ok(Self::build_on_grid(domain, grid, cutoff, points, threads))
    }

    /// Bins `points` into the cells of `grid` (over `domain`, its sides at
    /// least `cutoff`), the sort in parallel on `threads` if given.
    pub fn build_on_grid(
        domain: &Domain<D>,
        grid: CellGrid<D>,
        cutoff: f64,
        points: &[[f64; D]],
        threads: Option<&Threads>,
    ) -> Self {
        let mut list = CellList {
            domain: *domain,
            anchors_by_colour: grid.anchors_by_colour(),
            grid,
            cutoff,
            cell_start: Vec::new(),
            order: Vec::new(),
            positions: Vec::new(),
            columns: std::array::from_fn(|_| Vec::new()),
            keeps_columns: true,
            cell_ids: Vec::new(),
            counts: Vec::new(),
        };
        list.sort(points, threads);
        list
    }

    /// True when this list bins in `grid` over `domain` with `cutoff`: what
    /// [`CellList::build_on_grid`] with them would make, so that
    /// [`CellList::rebin_in`] may be used instead.
    pub fn is_on(&self, domain: &Domain<D>, grid: &CellGrid<D>, cutoff: f64) -> bool {
        self.domain == *domain && self.grid == *grid && self.cutoff == cutoff
    }

    /// Sorts new positions into the same grid, reusing every buffer (the arrays are
    /// not reallocated once they have grown to the particle count).
    pub fn rebin(&mut self, points: &[[f64; D]]) {
        self.sort(points, None);
    }

    /// [`CellList::rebin`] in parallel on `threads` (the same list for any
    /// thread count).
    pub fn rebin_in(&mut self, points: &[[f64; D]], threads: &Threads) {
        self.sort(points, Some(threads));
    }

    /// Steps 1-4 of the build, each pass split in parts over `threads`
    /// ([`counting_sort_with`]): the sort writes each particle's input index
    /// and wrapped position straight into its slot (reading the points in input
    /// order, no gather), then the columns in slot order.
    fn sort(&mut self, points: &[[f64; D]], threads: Option<&Threads>) {
        // positions are wrapped twice (for the cell and for the slot) rather
        // than kept wrapped: a copy of the positions less
        let (grid, domain) = (&self.grid, &self.domain);
        fill_in_parts(&mut self.cell_ids, points.len(), threads, |range| {
            points[range]
                .iter()
                .map(|p| grid.cell_of(&domain.wrap(*p)) as u32)
        });
        let n = points.len();
        self.order.clear();
        self.order.reserve(n);
        self.positions.clear();
        self.positions.reserve(n);
        let order = DisjointSlice::new(&mut self.order.spare_capacity_mut()[..n]);
        let positions = DisjointSlice::new(&mut self.positions.spare_capacity_mut()[..n]);
        let cell_ids = &self.cell_ids;
        let place = |i: usize, slot| {
            // SAFETY: every slot is given to one index, below n
            unsafe {
                order.get_unchecked(slot).write(i as u32);
                positions.get_unchecked(slot).write(domain.wrap(points[i]));
            }
        };
        // SAFETY: the cell ids are a slice, the same on both passes
        unsafe {
            counting_sort_with(
                n,
                |i| cell_ids[i],
                grid.num_cells(),
                threads,
                &mut self.cell_start,
                &mut self.counts,
                place,
            );
        }
        // SAFETY: the slots given out are exactly 0..n, each once
        unsafe {
            self.order.set_len(n);
            self.positions.set_len(n);
        }
        if self.keeps_columns {
            self.fill_columns(threads);
        }
    }

    /// The positions axis by axis ([`CellList::columns`]).
    fn fill_columns(&mut self, threads: Option<&Threads>) {
        let positions = &self.positions;
        for (a, column) in self.columns.iter_mut().enumerate() {
            fill_in_parts(column, positions.len(), threads, |range| {
                positions[range].iter().map(|p| p[a])
            });
        }
    }

    /// Reorders the particles inside every cell along the walk of
    /// [`CellGrid::column_key`]: up one half-cell column, down the next, so that
    /// consecutive slots lie close together and every run of a few slots is a
    /// compact cluster ([`ClusterList`](super::ClusterList)). An unstable sort
    /// by `(column, along, input index)`, a total order, so the same wrapped
    /// positions in the same input order give the same slots for any thread
    /// count. Cells keep their slot ranges; `order`, `positions` and the
    /// columns (unless released) follow.
    pub fn order_cells_in_columns(&mut self, threads: Option<&Threads>) {
        let parts = part_ranges(self.grid.num_cells(), parts_for(threads));
        let (grid, start) = (&self.grid, &self.cell_start);
        let order = DisjointSlice::new(&mut self.order);
        let positions = DisjointSlice::new(&mut self.positions);
        map_parts(threads, parts.len(), |p| {
            let mut keyed: Vec<(u32, f64, u32, [f64; D])> = Vec::new();
            for c in parts[p].clone() {
                let range = start[c] as usize..start[c + 1] as usize;
                if range.len() < 2 {
                    continue;
                }
                // SAFETY: the cells' slot ranges are disjoint and each cell is
                // in one part.
                let (order, positions) =
                    unsafe { (order.range(range.clone()), positions.range(range)) };
                keyed.clear();
                keyed.extend(order.iter().zip(positions.iter()).map(|(&i, x)| {
                    let (column, along) = grid.column_key(c, x);
                    (column, along, i, *x)
                }));
                keyed.sort_unstable_by(|a, b| {
                    a.0.cmp(&b.0).then(a.1.total_cmp(&b.1)).then(a.2.cmp(&b.2))
                });
                for ((o, x), k) in order.iter_mut().zip(positions.iter_mut()).zip(&keyed) {
                    *o = k.2;
                    *x = k.3;
                }
            }
        });
        if self.keeps_columns {
            self.fill_columns(threads);
        }
    }

    /// The domain the list was built for.
    pub fn domain(&self) -> &Domain<D> {
        &self.domain
    }

    /// The grid.
    pub fn grid(&self) -> &CellGrid<D> {
        &self.grid
    }

    /// The cutoff the grid was sized for.
    pub fn cutoff(&self) -> f64 {
        self.cutoff
    }

    /// Number of particles.
    pub fn len(&self) -> usize {
        self.order.len()
    }

    /// True when there are no particles.
    pub fn is_empty(&self) -> bool {
        self.order.is_empty()
    }

    /// `cell_start`: `num_cells + 1` offsets into the sorted arrays.
    pub fn cell_start(&self) -> &[u32] {
        &self.cell_start
    }

    /// Sorted slot range of cell `c`.
    #[inline]
    pub fn cell_range(&self, c: usize) -> Range<usize> {
        self.cell_start[c] as usize..self.cell_start[c + 1] as usize
    }

    /// `order[k]`: the input index of the particle in sorted slot `k`.
    pub fn order(&self) -> &[u32] {
        &self.order
    }

    /// Wrapped positions in cell order.
    pub fn positions(&self) -> &[[f64; D]] {
        &self.positions
    }

    /// The same positions as one array per axis (structure of arrays), for the
    /// vectorised distance loops.
    ///
    /// # Panics
    /// If the columns were released ([`CellList::release_columns`]).
    pub fn columns(&self) -> &[Vec<f64>; D] {
        assert!(
            self.keeps_columns,
            "the cell list's columns were released: it cannot be searched"
        );
        &self.columns
    }

    /// Frees the per-axis columns for good (rebins no longer make them): for
    /// a holder that reads only the list's order and positions (the md
    /// system), one copy of the positions less in memory, and none made and
    /// dropped at every rebin.
    pub fn release_columns(&mut self) {
        self.columns = std::array::from_fn(|_| Vec::new());
        self.keeps_columns = false;
    }

    /// Anchor cells by colour, for coloured passes (see [`CellGrid::colour_of`]).
    pub fn anchors_by_colour(&self) -> &[Vec<u32>] {
        &self.anchors_by_colour
    }

    /// Puts the values of a per-particle array (in input order) into cell order:
    /// `out[k] = values[order[k]]`.
    pub fn permute<T: Copy>(&self, values: &[T], out: &mut Vec<T>) {
        out.clear();
        out.extend(self.order.iter().map(|&i| values[i as usize]));
    }

    /// Renumbers the particles of input index below `count` in the order of
    /// their slots, `i' = #{slots before i's holding an index below count}`,
    /// and returns each new index's former one (`former[i'] = i`), so that the
    /// caller may store those particles in slot order (its arrays permuted
    /// by `former`, `new[i'] = old[former[i']]`); the others keep their
    /// indices. Nothing else changes: the slots, their positions and the
    /// cells stay.
    pub fn renumber_first(&mut self, count: usize) -> Vec<u32> {
        let mut former = Vec::with_capacity(count);
        for o in &mut self.order {
            if (*o as usize) < count {
                former.push(*o);
                *o = (former.len() - 1) as u32;
            }
        }
        former
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counting_sort_groups_particles_by_cell_stably() {
        let dom = Domain::periodic([4.0, 4.0]).unwrap();
        let pts = [[3.5, 3.5], [0.5, 0.5], [0.2, 0.1], [-0.5, 0.5], [1.5, 0.5]];
        let cl = CellList::build(&dom, 1.0, &pts).unwrap();
        assert_eq!(cl.grid().dims(), [3, 3]);
        assert_eq!(cl.cell_start().len(), 10);
        assert_eq!(*cl.cell_start().last().unwrap(), 5);
        // cell 0 holds inputs 1 and 2 in input order; input 4 (x = 1.5) is in cell 1
        assert_eq!(&cl.order()[..3], &[1, 2, 4]);
        assert_eq!(cl.cell_range(0), 0..2);
        // -0.5 wraps to 3.5: inputs 3 and 0 are in the last column
        for (k, &i) in cl.order().iter().enumerate() {
            let c = cl.grid().cell_of(&cl.positions()[k]);
            assert!(cl.cell_range(c).contains(&k));
            assert_eq!(cl.positions()[k], dom.wrap(pts[i as usize]));
        }
        let mut ids = Vec::new();
        cl.permute(&[10, 11, 12, 13, 14], &mut ids);
        assert_eq!(ids[..3], [11, 12, 14]);
    }

    /// The first inputs renumbered in slot order, the others kept: slots in
    /// order [1, 2, 4, 3, 0] with the first 3 renumbered give [0, 1, 4, 3, 2],
    /// former numbers [1, 2, 0].
    #[test]
    fn renumber_first_numbers_in_slot_order() {
        let dom = Domain::periodic([4.0, 4.0]).unwrap();
        let pts = [[3.5, 3.5], [0.5, 0.5], [0.2, 0.1], [-0.5, 0.5], [1.5, 0.5]];
        let mut cl = CellList::build(&dom, 1.0, &pts).unwrap();
        assert_eq!(cl.order(), &[1, 2, 4, 3, 0]);
        let positions = cl.positions().to_vec();
        assert_eq!(cl.renumber_first(3), vec![1, 2, 0]);
        assert_eq!(cl.order(), &[0, 1, 4, 3, 2]);
        assert_eq!(cl.positions(), &positions[..]);
    }
}
