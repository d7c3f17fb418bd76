//! Candidate search for the collision benchmark: every pair `a < b` (vector
//! positions) with `q = (dx dx) + (dy dy) <= limit`, in lexicographic order, found on
//! a grid of cells (seed 001's binning): squares, or bricks in rows shifted by half
//! a cell ([`CellShape`]). The grid only proposes candidates; the exact predicate
//! decides, so the result equals the literal all-pairs loop (SPEC.md section 4,
//! E1) for either layout. Discs may be anywhere, also far outside the box: the grid
//! spans their bounding box.

use super::rules::{Separation, Table};
use crate::threads::{
    counting_sort, counting_sort_parts, fill_in_parts, map_parts, part_ranges, sort_parts,
    DisjointSlice, Threads,
};
use rayon::prelude::*;

/// One overlapping pair and its frozen separation: vector positions `a < b`
/// from [`ContactGrid::find`]; from [`ContactGrid::search`], the slots of the
/// two discs, the roles still by vector position (so `a > b` may be).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Contact {
    /// The first disc (role "1").
    pub a: u32,
    /// The second disc (role "2").
    pub b: u32,
    /// `x_b - x_a`, `y_b - y_a`, `q`.
    pub sep: Separation,
}

/// How [`ContactGrid`] lays out its cells. Either way a cell is at least as tall
/// and as wide as the interaction reach `sqrt(limit)` (a little more, so that
/// rounding never moves a pair at exactly the reach two cells apart), and the
/// pairs found are the same, in the same order, with the same bits: only the
/// candidates proposed, hence the time, differ.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum CellShape {
    /// Squares of side `s >= sqrt(limit)` in aligned rows: each square has 8
    /// neighbours, and the half stencil (the square to the right and the three
    /// above) holds 4 of them. A disc is tested against half of its own square and
    /// 4 squares, about `4.5 s^2` of area.
    #[default]
    Square,
    /// Seed 001's "squares in a hexagon manner": rows of height `h >= sqrt(limit)`
    /// in which every other row is shifted by half a cell (a brick wall), so that
    /// each cell touches 6 others (2 in its row, 2 above, 2 below: the neighbours
    /// of a hexagonal lattice) and the half stencil (the cell to the right and the
    /// two above) holds 3. For the 6 to hold every pair within reach, a cell is
    /// `w = 2h` wide: a disc reaches `sqrt(limit) <= w / 2` sideways, which stays
    /// within the two cells of the next row that overlap its own (with square
    /// bricks of side `sqrt(limit)`, a disc near a corner would reach a third
    /// cell of the next row). A disc is tested against half of its own cell and 3
    /// cells, about `7 h^2` of area.
    Hex,
}

impl CellShape {
    /// The name on the command line and in outputs: `square` or `hex`.
    pub fn name(self) -> &'static str {
        match self {
            CellShape::Square => "square",
            CellShape::Hex => "hex",
        }
    }
}

/// A grid of cells ([`CellShape`]) over the discs' bounding box, with the discs
/// sorted by cell (counting sort), and its buffers kept between searches.
#[derive(Clone, Debug, Default)]
pub struct ContactGrid {
    shape: CellShape,
    region: Option<([f64; 2], [f64; 2])>,
    origin: [f64; 2],
    /// Width and height of a cell.
    size: [f64; 2],
    /// Columns and rows; cell `row * columns + column`.
    dims: [usize; 2],
    cell_of: Vec<u32>,
    start: Vec<u32>,
    sorted: Vec<u32>,
    sorted_x: Vec<f64>,
    sorted_y: Vec<f64>,
    rows: Vec<Vec<Contact>>,
    counts: Vec<u32>,
    offsets: Vec<u32>,
}

/// What a [`CellShape::Hex`] row adds to `x / w` before rounding down: odd rows
/// start half a cell to the left.
const HEX_SHIFT: [f64; 2] = [0.0, 0.5];

impl ContactGrid {
    /// Replaces `out` by all pairs `a < b` with `q <= limit`, sorted by `(a, b)`.
    /// Positions must be finite. The order does not depend on the thread count.
    pub fn find(
        &mut self,
        x: &[f64],
        y: &[f64],
        limit: f64,
        threads: &Threads,
        out: &mut Vec<Contact>,
    ) {
        out.clear();
        let n = x.len();
        self.search(x, y, limit, threads);
        let rows = std::mem::take(&mut self.rows);
        let sorted = &self.sorted;
        // the pairs by vector position (the found ones hold slots)
        let number = |c: &Contact| Contact {
            a: sorted[c.a as usize],
            b: sorted[c.b as usize],
            sep: c.sep,
        };
        // then place the pairs row by row in the order of a (a counting sort,
        // stable, reading the rows where they are), each row sorted by b; both
        // in parts over the threads
        let m: usize = rows.iter().map(Vec::len).sum();
        let groups = row_groups(&rows, sort_parts(m, n, Some(threads)));
        out.reserve(m);
        let room = DisjointSlice::new(&mut out.spare_capacity_mut()[..m]);
        // SAFETY: every slot is given once, below the number of pairs
        let place = |c: &Contact, slot| {
            unsafe { room.get_unchecked(slot) }.write(number(c));
        };
        // SAFETY: the rows do not change during the sort, so a group yields the
        // same pairs, with the same keys, on both passes
        unsafe {
            counting_sort_parts(
                groups.len(),
                |g| rows[groups[g].clone()].iter().flatten(),
                |c| sorted[c.a as usize],
                n,
                Some(threads),
                &mut self.offsets,
                &mut self.counts,
                place,
            );
        }
        // SAFETY: the sort gave out the slots 0..m, each once, and each was
        // written above
        unsafe { out.set_len(m) };
        self.rows = rows;
        let placed = DisjointSlice::new(out);
        let offsets = &self.offsets;
        let parts = part_ranges(n, threads.count());
        map_parts(Some(threads), parts.len(), |p| {
            let discs = parts[p].clone();
            let first = offsets[discs.start] as usize;
            // SAFETY: the parts' discs, hence their rows, are disjoint
            let part = unsafe { placed.range(first..offsets[discs.end] as usize) };
            for a in discs {
                let row = &mut part[offsets[a] as usize - first..offsets[a + 1] as usize - first];
                // a handful per disc: insertion sort by b
                for k in 1..row.len() {
                    let mut j = k;
                    while j > 0 && row[j - 1].b > row[j].b {
                        row.swap(j - 1, j);
                        j -= 1;
                    }
                }
            }
        });
    }

    /// Finds all pairs with `q <= limit` as the search meets them: cell by cell,
    /// in parts over the threads, `Contact { a, b, sep }` holding the *slots* of
    /// the two discs in [`ContactGrid::nearby_order`] (disc
    /// `nearby_order()[a]`), with the roles by vector position (the disc of slot
    /// `a` before the disc of slot `b`) and the separation of the second from
    /// the first, as [`ContactGrid::find`] gives them. Read them with
    /// [`ContactGrid::found`]. Positions must be finite. What is found, and in
    /// which order, does not depend on the thread count. A pair is found from
    /// its lower slot (its home disc), the other slot lying later in the same
    /// cell or in a later cell; the rows hold consecutive cells, in cell order,
    /// so the pairs' lower slots ascend through the rows.
    pub fn search(&mut self, x: &[f64], y: &[f64], limit: f64, threads: &Threads) {
        assert_eq!(x.len(), y.len());
        self.bin(x, y, limit, threads);
        let mut rows = std::mem::take(&mut self.rows);
        rows.iter_mut().for_each(Vec::clear);
        if x.len() >= 2 && limit >= 0.0 {
            // cell by cell (neighbouring discs are close in memory)
            let ranges = Threads::chunks(self.dims[0] * self.dims[1]);
            rows.resize_with(ranges.len(), Vec::new);
            let grid = &*self;
            threads.install(|| {
                ranges.zip(rows.par_iter_mut()).for_each(|(cells, found)| {
                    for cell in cells {
                        grid.contacts_in(cell, limit, found);
                    }
                });
            });
        }
        self.rows = rows;
    }

    /// The pairs of the last [`ContactGrid::search`], in the order found, in
    /// consecutive pieces (slots of [`ContactGrid::nearby_order`]).
    pub fn found(&self) -> &[Vec<Contact>] {
        &self.rows
    }

    /// The positions of the discs by slot of [`ContactGrid::nearby_order`], as
    /// of the last search.
    pub fn slot_positions(&self) -> (&[f64], &[f64]) {
        (&self.sorted_x, &self.sorted_y)
    }

    /// Lays the cells out as `shape` (squares by default). The pairs found are the
    /// same; only the time changes.
    pub fn with_cells(mut self, shape: CellShape) -> Self {
        self.shape = shape;
        self
    }

    /// The layout of the cells.
    pub fn cells(&self) -> CellShape {
        self.shape
    }

    /// Limits the cells to the region `[lo, hi]` (they span the discs' bounding
    /// box otherwise); discs outside it go to its border cells. The pairs found
    /// are the same; only the time changes.
    pub fn with_region(mut self, lo: [f64; 2], hi: [f64; 2]) -> Self {
        self.region = Some((lo, hi));
        self
    }

    /// All discs, cell by cell (neighbours close together), as of the last
    /// [`ContactGrid::find`] or [`ContactGrid::search`]: disc `nearby_order()[k]`
    /// holds slot `k`.
    pub fn nearby_order(&self) -> &[u32] {
        &self.sorted
    }

    /// Sizes the cells (rows just taller than `sqrt(limit)`, so that a pair within
    /// the limit is never two rows apart, squares as wide, bricks twice as wide;
    /// no more rows or columns than about `2 sqrt(n)`) and sorts the discs by cell.
    fn bin(&mut self, x: &[f64], y: &[f64], limit: f64, threads: &Threads) {
        let n = x.len();
        let parts = part_ranges(n, threads.count());
        let bounds = map_parts(Some(threads), parts.len(), |p| {
            let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
            for (&px, &py) in x[parts[p].clone()].iter().zip(&y[parts[p].clone()]) {
                lo = [lo[0].min(px), lo[1].min(py)];
                hi = [hi[0].max(px), hi[1].max(py)];
            }
            (lo, hi)
        });
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for (part_lo, part_hi) in bounds {
            lo = [lo[0].min(part_lo[0]), lo[1].min(part_lo[1])];
            hi = [hi[0].max(part_hi[0]), hi[1].max(part_hi[1])];
        }
        if let Some((region_lo, region_hi)) = self.region {
            // discs beyond the region share its border cells: clamping keeps
            // neighbours in neighbouring cells, and a few outliers cannot
            // stretch the cells over everything else
            for a in 0..2 {
                lo[a] = lo[a].max(region_lo[a]).min(region_hi[a]);
                hi[a] = hi[a].min(region_hi[a]).max(lo[a]);
            }
        }
        let extent = (hi[0] - lo[0]).max(hi[1] - lo[1]);
        let max_per_axis = ((4 * n) as f64).sqrt().ceil().max(1.0);
        let side = (limit.sqrt() * (1.0 + 1e-6))
            .max(extent / max_per_axis)
            .max(f64::MIN_POSITIVE);
        let (size, dims) = match self.shape {
            CellShape::Square => (
                [side, side],
                [0, 1].map(|a| ((hi[a] - lo[a]) / side) as usize + 1),
            ),
            CellShape::Hex => {
                // odd rows reach half a brick further right
                let width = 2.0 * side;
                (
                    [width, side],
                    [
                        ((hi[0] - lo[0]) / width + 0.5) as usize + 1,
                        ((hi[1] - lo[1]) / side) as usize + 1,
                    ],
                )
            }
        };
        self.origin = lo;
        self.size = size;
        self.dims = dims;
        let mut cell_of = std::mem::take(&mut self.cell_of);
        let grid = &*self;
        match self.shape {
            CellShape::Square => fill_in_parts(&mut cell_of, n, Some(threads), |range| {
                let points = x[range.clone()].iter().zip(&y[range]);
                points.map(|(&px, &py)| grid.cell_at::<false>(px, py) as u32)
            }),
            CellShape::Hex => fill_in_parts(&mut cell_of, n, Some(threads), |range| {
                let points = x[range.clone()].iter().zip(&y[range]);
                points.map(|(&px, &py)| grid.cell_at::<true>(px, py) as u32)
            }),
        }
        self.cell_of = cell_of;
        counting_sort(
            &self.cell_of,
            dims[0] * dims[1],
            Some(threads),
            &mut self.start,
            &mut self.sorted,
            &mut self.counts,
        );
        let sorted = &self.sorted;
        for (column, coordinate) in [(&mut self.sorted_x, x), (&mut self.sorted_y, y)] {
            fill_in_parts(column, n, Some(threads), |range| {
                sorted[range].iter().map(|&k| coordinate[k as usize])
            });
        }
    }

    /// The cell of a point: row `floor((y - y0) / h)`, column `floor((x - x0) / w)`,
    /// plus a half in odd rows of bricks (`HEX`), both clamped to the grid (`as`
    /// saturates below 0). Each is a nondecreasing function of the coordinate, so
    /// clamping never moves two points further apart than neighbouring cells.
    #[inline]
    fn cell_at<const HEX: bool>(&self, x: f64, y: f64) -> usize {
        let [columns, rows] = self.dims;
        let row = (((y - self.origin[1]) / self.size[1]) as usize).min(rows - 1);
        let mut u = (x - self.origin[0]) / self.size[0];
        if HEX {
            u += HEX_SHIFT[row & 1];
        }
        row * columns + (u as usize).min(columns - 1)
    }

    /// Appends the pairs within the limit that the discs of `cell` form with the
    /// discs after them in the cell, in the cell to the right and in the cells
    /// above it (squares: the three above, half of the 3 x 3 block; bricks: the
    /// two that overlap it, columns `c, c + 1` above an even row and `c - 1, c`
    /// above an odd one), so that every pair of neighbouring cells is seen once,
    /// as the slots of `(min, max)` (by vector position) with the separation of
    /// `max` from `min`. The rest of the
    /// cell and the one to its right are consecutive in cell order, and so are the
    /// cells above: two runs per disc.
    fn contacts_in(&self, cell: usize, limit: f64, found: &mut Vec<Contact>) {
        let members = self.start[cell] as usize..self.start[cell + 1] as usize;
        if members.is_empty() {
            return;
        }
        let [columns, rows] = self.dims;
        let (cx, cy) = (cell % columns, cell / columns);
        let right_end = self.start[cell + 1 + usize::from(cx + 1 < columns)] as usize;
        let above = if cy + 1 < rows {
            let row = (cy + 1) * columns;
            let (x0, x1) = match self.shape {
                CellShape::Square => (cx.saturating_sub(1), (cx + 1).min(columns - 1)),
                CellShape::Hex if cy % 2 == 0 => (cx, (cx + 1).min(columns - 1)),
                CellShape::Hex => (cx.saturating_sub(1), cx),
            };
            self.start[row + x0] as usize..self.start[row + x1 + 1] as usize
        } else {
            0..0
        };
        for slot in members {
            let a = self.sorted[slot];
            let pa = [self.sorted_x[slot], self.sorted_y[slot]];
            for run in [slot + 1..right_end, above.clone()] {
                for m in run {
                    let pb = [self.sorted_x[m], self.sorted_y[m]];
                    let sep = Separation::between(pa, pb);
                    if sep.q <= limit {
                        // the roles by vector position: the separation of max from
                        // min, computed in that order (negating would turn +0.0
                        // into -0.0)
                        found.push(if a < self.sorted[m] {
                            Contact {
                                a: slot as u32,
                                b: m as u32,
                                sep,
                            }
                        } else {
                            Contact {
                                a: m as u32,
                                b: slot as u32,
                                sep: Separation::between(pb, pa),
                            }
                        });
                    }
                }
            }
        }
    }
}

impl Table {
    /// A contact grid over the box and one box side around it (discs further out
    /// share the border squares).
    pub fn grid(&self) -> ContactGrid {
        let l = self.side_f();
        ContactGrid::default().with_region([-l, -l], [2.0 * l, 2.0 * l])
    }
}

/// `parts` runs of consecutive rows (covering every row) holding about equal
/// numbers of values.
pub(super) fn row_groups<T>(rows: &[Vec<T>], parts: usize) -> Vec<std::ops::Range<usize>> {
    let mut ends = Vec::with_capacity(rows.len());
    let mut total = 0;
    for row in rows {
        total += row.len();
        ends.push(total);
    }
    let parts = parts.clamp(1, rows.len().max(1));
    let bounds: Vec<usize> = (0..=parts)
        .map(|p| match p {
            0 => 0,
            p if p == parts => rows.len(),
            p => ends.partition_point(|&end| end <= total * p / parts),
        })
        .collect();
    bounds.windows(2).map(|w| w[0]..w[1]).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::random::Rng;
    use proptest::prelude::*;

    #[test]
    fn row_groups_cover_the_rows_in_order_with_balanced_values() {
        let rows: Vec<Vec<u8>> = [5, 0, 3, 8, 0, 0, 2, 6]
            .iter()
            .map(|&l| vec![0; l])
            .collect();
        for parts in 1..=10 {
            let groups = row_groups(&rows, parts);
            assert_eq!(groups.len(), parts.min(rows.len()));
            assert_eq!(groups[0].start, 0);
            assert_eq!(groups.last().unwrap().end, rows.len());
            assert!(groups.windows(2).all(|w| w[0].end == w[1].start));
        }
        let halves = row_groups(&rows, 2);
        let values =
            |g: &std::ops::Range<usize>| rows[g.clone()].iter().map(Vec::len).sum::<usize>();
        assert_eq!((values(&halves[0]), values(&halves[1])), (8, 16));
        assert_eq!(row_groups::<u8>(&[], 3), vec![0..0]);
    }

    const SHAPES: [CellShape; 2] = [CellShape::Square, CellShape::Hex];

    fn brute(x: &[f64], y: &[f64], limit: f64) -> Vec<Contact> {
        let mut out = Vec::new();
        for a in 0..x.len() {
            for b in a + 1..x.len() {
                let sep = Separation::between([x[a], y[a]], [x[b], y[b]]);
                if sep.q <= limit {
                    out.push(Contact {
                        a: a as u32,
                        b: b as u32,
                        sep,
                    });
                }
            }
        }
        out
    }

    /// The contacts as bit patterns, so that `-0.0` and `+0.0` differ.
    fn bits(contacts: &[Contact]) -> Vec<(u32, u32, [u64; 3])> {
        contacts
            .iter()
            .map(|c| (c.a, c.b, [c.sep.dx, c.sep.dy, c.sep.q].map(f64::to_bits)))
            .collect()
    }

    #[test]
    fn the_grid_finds_exactly_the_brute_force_pairs() {
        let mut rng = Rng::new(7);
        for (n, spread, limit) in [
            (300usize, 40.0f64, 4.0f64),
            (500, 20.0, 9.0),
            (50, 1e6, 4.0),
            (3, 1.0, 0.0),
        ] {
            let mut x: Vec<f64> = (0..n).map(|_| rng.uniform() * spread).collect();
            let y: Vec<f64> = (0..n).map(|_| rng.uniform() * spread).collect();
            // a few far outside the box, and touching pairs exactly at the limit
            x[0] = -5e5;
            x[1] = x[2] + f64::sqrt(limit);
            let expected = brute(&x, &y, limit);
            for shape in SHAPES {
                let mut grid = ContactGrid::default().with_cells(shape);
                let mut clamped = ContactGrid::default()
                    .with_cells(shape)
                    .with_region([0.0, 0.0], [spread / 2.0, spread / 2.0]);
                for threads in [Threads::single(), Threads::new(2).unwrap()] {
                    let mut found = Vec::new();
                    grid.find(&x, &y, limit, &threads, &mut found);
                    assert_eq!(found, expected, "n {n}, {shape:?}");
                    clamped.find(&x, &y, limit, &threads, &mut found);
                    assert_eq!(
                        found, expected,
                        "n {n}, {shape:?}, cells over half the spread"
                    );
                }
            }
        }
    }

    #[test]
    fn bricks_give_the_same_bits_with_1_and_2_threads() {
        // dense enough for components of many discs, with a few outliers
        let mut rng = Rng::new(11);
        let (n, side, limit) = (20_000usize, 400.0, 16.0);
        let mut x: Vec<f64> = (0..n).map(|_| rng.uniform() * side).collect();
        let mut y: Vec<f64> = (0..n).map(|_| rng.uniform() * side).collect();
        for k in 0..20 {
            x[k * 97] = -1e7 * (k as f64 + 1.0);
            y[k * 89] = 3e9;
        }
        let region = ([-side, -side], [2.0 * side, 2.0 * side]);
        let mut found = [Vec::new(), Vec::new(), Vec::new()];
        let runs = [
            (CellShape::Square, Threads::single()),
            (CellShape::Hex, Threads::single()),
            (CellShape::Hex, Threads::new(2).unwrap()),
        ];
        for ((shape, threads), out) in runs.iter().zip(&mut found) {
            let mut grid = ContactGrid::default()
                .with_cells(*shape)
                .with_region(region.0, region.1);
            // twice: the buffers kept from one search must not leak into the next
            grid.find(&y, &x, limit, threads, out);
            grid.find(&x, &y, limit, threads, out);
            assert_eq!(grid.cells(), *shape);
        }
        assert!(found[0].len() > 1000, "{} pairs", found[0].len());
        assert_eq!(bits(&found[1]), bits(&found[0]), "hex, 1 thread");
        assert_eq!(bits(&found[2]), bits(&found[0]), "hex, 2 threads");
    }

    /// Random discs, then edits: coincident points, points at exactly the cutoff
    /// from another (along an axis or along a 3-4-5 diagonal, exact in binary),
    /// points just beyond it, and points far outside the box.
    fn discs() -> impl Strategy<Value = (Vec<f64>, Vec<f64>, f64, f64)> {
        (
            1u32..4,
            prop_oneof![Just(2.0f64), Just(20.0), Just(300.0)],
            prop::collection::vec((0.0f64..1.0, 0.0f64..1.0), 0..160),
            prop::collection::vec(
                (
                    0u8..4,
                    any::<prop::sample::Index>(),
                    any::<prop::sample::Index>(),
                    0usize..12,
                ),
                0..40,
            ),
        )
            .prop_map(|(k, spread, points, edits)| {
                let k = k as f64;
                let reach = 5.0 * k;
                let limit = reach * reach;
                let spread = spread * reach;
                // positions on a 1/64 lattice: sums of the offsets below are exact
                let snap = |v: f64| (v * spread * 64.0).floor() / 64.0;
                let mut x: Vec<f64> = points.iter().map(|p| snap(p.0)).collect();
                let mut y: Vec<f64> = points.iter().map(|p| snap(p.1)).collect();
                let offsets = [
                    (reach, 0.0),
                    (-reach, 0.0),
                    (0.0, reach),
                    (0.0, -reach),
                    (3.0 * k, 4.0 * k),
                    (-3.0 * k, 4.0 * k),
                    (3.0 * k, -4.0 * k),
                    (-3.0 * k, -4.0 * k),
                    (4.0 * k, 3.0 * k),
                    (-4.0 * k, 3.0 * k),
                    (4.0 * k, -3.0 * k),
                    (-4.0 * k, -3.0 * k),
                ];
                let far = [-1e300, -3e12, -7.5e5, 5e6, 2e15, 1e300];
                if !x.is_empty() {
                    for (kind, i, j, m) in edits {
                        let (i, j) = (i.index(x.len()), j.index(x.len()));
                        match kind {
                            0 => (x[i], y[i]) = (x[j], y[j]),
                            1 => (x[i], y[i]) = (x[j] + offsets[m].0, y[j] + offsets[m].1),
                            2 => (x[i], y[i]) = (x[j] + reach.next_up(), y[j]),
                            _ => {
                                x[i] = far[m % far.len()];
                                y[i] = if m % 3 == 0 {
                                    far[(m + 1) % far.len()]
                                } else {
                                    y[i]
                                };
                            }
                        }
                    }
                }
                (x, y, limit, spread)
            })
    }

    #[test]
    fn the_random_discs_hold_every_hard_case() {
        // the strategy does make pairs at exactly the cutoff, coincident pairs and
        // discs far outside, so the property below sees them
        let mut runner = proptest::test_runner::TestRunner::deterministic();
        let (mut exact, mut coincident, mut far) = (0, 0, 0);
        for _ in 0..40 {
            let (x, y, limit, spread) =
                proptest::strategy::ValueTree::current(&discs().new_tree(&mut runner).unwrap());
            for c in brute(&x, &y, limit) {
                exact += usize::from(c.sep.q == limit && c.sep.dx != 0.0 && c.sep.dy != 0.0);
                coincident += usize::from(c.sep.q == 0.0);
            }
            far += x.iter().filter(|v| v.abs() > 100.0 * spread).count();
        }
        assert!(
            exact > 0 && coincident > 0 && far > 0,
            "{exact} {coincident} {far}"
        );
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(160))]

        /// Bricks and squares, over the discs' bounding box or clamped to a region
        /// around the box, with 1 and 2 threads: all the pairs of the all-pairs
        /// loop, in its order, with its bits.
        #[test]
        fn hex_and_square_cells_find_the_brute_force_pairs((x, y, limit, spread) in discs()) {
            let expected = bits(&brute(&x, &y, limit));
            for threads in [Threads::single(), Threads::new(2).unwrap()] {
                for shape in SHAPES {
                    for region in [None, Some(([-spread, -spread], [2.0 * spread, 2.0 * spread]))] {
                        let mut grid = ContactGrid::default().with_cells(shape);
                        if let Some((lo, hi)) = region {
                            grid = grid.with_region(lo, hi);
                        }
                        let mut found = vec![Contact::default(); 3];
                        grid.find(&x, &y, limit, &threads, &mut found);
                        prop_assert_eq!(
                            bits(&found), expected.clone(),
                            "{:?}, region {:?}, {} threads", shape, region, threads.count()
                        );
                    }
                }
            }
        }
    }
}
