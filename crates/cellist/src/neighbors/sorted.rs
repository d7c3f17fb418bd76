//! The half list of pairs sorted by `(i, j)` in input numbering, with the
//! quantities vesin returns: what `cellist neighbors` prints and what the Python
//! module's `neighbors` returns.
//!
//! The rows are found in cell order, so that the search streams through memory:
//! each particle's neighbours `j > i` over the full stencil, sorted by `j`, are
//! appended to a buffer of its chunk of cells. The prefix sums of the row
//! lengths, in input order, then place every row, and each row is copied once
//! into its place. No global sort, and the same bits for any thread count.

use super::cell_list::CellList;
use super::grid::{StencilKind, StencilRun};
use super::pairs::expected_pairs;
use super::traverse::{for_each_in_row, for_each_row_in_cell, CutoffTest, ScanScratch};
use crate::geometry::{norm2, Domain};
use crate::memory::large_vec;
use crate::threads::{DisjointSlice, Threads};
use rayon::prelude::*;

/// Which quantities of each pair [`sorted_half_list`] returns, besides `i` and `j`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PairQuantities {
    /// The distances `|x_j - x_i|` (minimum image).
    pub distances: bool,
    /// The separation vectors `x_j - x_i` (minimum image).
    pub vectors: bool,
    /// The integer image shifts `S` with `x_j - x_i + S L = d` per axis (0 on
    /// open axes).
    pub shifts: bool,
}

impl PairQuantities {
    /// True when a quantity needs the separation vectors.
    fn separations(&self) -> bool {
        self.vectors || self.shifts
    }
}

/// The half list in the layout of vesin and numpy: pair `k` is `(i[k], j[k])`
/// with `i < j` (sorted by `i` then `j` from [`sorted_half_list`], in cell order
/// from [`half_list_as_found`]); the quantities not asked for are empty.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PairArrays {
    /// First indices (input numbering).
    pub i: Vec<i64>,
    /// Second indices, `j > i`.
    pub j: Vec<i64>,
    /// Distances `r = |d|`, `sqrt` of the same `r^2` the cutoff test saw.
    pub distances: Vec<f64>,
    /// Separations `d = x_j + shift - x_i`, `D` numbers per pair.
    pub vectors: Vec<f64>,
    /// Image shifts, `D` integers per pair.
    pub shifts: Vec<i32>,
}

impl PairArrays {
    /// Empty arrays with room for `pairs` pairs of the `quantities` asked for
    /// (large buffers advised to use huge pages).
    fn with_capacity<const D: usize>(pairs: usize, quantities: PairQuantities) -> Self {
        let room = |wanted: bool, per_pair: usize| if wanted { pairs * per_pair } else { 0 };
        PairArrays {
            i: large_vec(pairs),
            j: large_vec(pairs),
            distances: large_vec(room(quantities.distances, 1)),
            vectors: large_vec(room(quantities.vectors, D)),
            shifts: large_vec(room(quantities.shifts, D)),
        }
    }

    /// Appends the pair of the particles numbered `a` and `b` (either order)
    /// at separation `d = x_b - x_a` (minimum image) and `r2 = |d|^2`, as
    /// `(min, max)` with the separation from the first to the second; the
    /// `quantities` only when `QUANTITIES`. Inlined into the search loop, so
    /// that the pair costs no call.
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    fn push_found<const D: usize, const QUANTITIES: bool>(
        &mut self,
        a: u32,
        b: u32,
        d: &[f64; D],
        r2: f64,
        quantities: PairQuantities,
        domain: &Domain<D>,
        points: &[[f64; D]],
    ) {
        let (first, second) = (a.min(b), a.max(b));
        self.i.push(first as i64);
        self.j.push(second as i64);
        if !QUANTITIES {
            return;
        }
        if quantities.distances {
            self.distances.push(r2.sqrt());
        }
        if quantities.separations() {
            let d = if a < b { *d } else { d.map(|x| -x) };
            if quantities.vectors {
                self.vectors.extend_from_slice(&d);
            }
            if quantities.shifts {
                let (xi, xj) = (&points[first as usize], &points[second as usize]);
                self.shifts.extend(image_shift(domain, xi, xj, &d));
            }
        }
    }

    /// Number of pairs.
    pub fn len(&self) -> usize {
        self.i.len()
    }

    /// True without pairs.
    pub fn is_empty(&self) -> bool {
        self.i.is_empty()
    }
}

/// The rows of one chunk of cells, slot after slot: the neighbours `j > i`
/// sorted by `j` and, when asked for, their squared distances and separations.
#[derive(Default)]
struct ChunkRows<const D: usize> {
    first_slot: usize,
    lengths: Vec<u32>,
    js: Vec<u32>,
    r2s: Vec<f64>,
    separations: Vec<[f64; D]>,
}

/// Every pair `(i, j)`, `i < j` in input numbering, with `|x_j - x_i| < cutoff`
/// (minimum image on the periodic axes of `cells`' domain), sorted by `(i, j)`,
/// with the `quantities` asked for. `points` are the positions `cells` was built
/// from, in input order: the image shifts are counted from them,
/// `S_a = round((d_a - (x_{j,a} - x_{i,a})) / L_a)`.
///
/// # Panics
/// If `cutoff` exceeds the cutoff the cell list was built for, or `points` is
/// not the cell list's particle count.
pub fn sorted_half_list<const D: usize>(
    cells: &CellList<D>,
    points: &[[f64; D]],
    cutoff: f64,
    quantities: PairQuantities,
    threads: &Threads,
) -> PairArrays {
    let test = checked_test(cells, points, cutoff);
    let order = cells.order();
    let n = cells.len();
    let chunks = find_rows(cells, &test, quantities, threads);
    // each row's place, in input order
    let mut start = vec![0usize; n + 1];
    for chunk in &chunks {
        for (k, &length) in chunk.lengths.iter().enumerate() {
            start[order[chunk.first_slot + k] as usize + 1] = length as usize;
        }
    }
    for k in 0..n {
        start[k + 1] += start[k];
    }
    let total = start[n];
    let mut out = PairArrays {
        i: vec![0; total],
        j: vec![0; total],
        distances: vec![0.0; if quantities.distances { total } else { 0 }],
        vectors: vec![0.0; if quantities.vectors { total * D } else { 0 }],
        shifts: vec![0; if quantities.shifts { total * D } else { 0 }],
    };
    let is = DisjointSlice::new(&mut out.i);
    let js = DisjointSlice::new(&mut out.j);
    let rs = DisjointSlice::new(&mut out.distances);
    let ds = DisjointSlice::new(&mut out.vectors);
    let ss = DisjointSlice::new(&mut out.shifts);
    let domain = cells.domain();
    let place = |chunk: &ChunkRows<D>| {
        let mut at = 0;
        for (k, &length) in chunk.lengths.iter().enumerate() {
            let i = order[chunk.first_slot + k] as usize;
            let row = at..at + length as usize;
            at = row.end;
            let place = start[i]..start[i + 1];
            // SAFETY: the rows partition 0..total (prefix sums of the row
            // lengths), and row `i` belongs to exactly one chunk, which places it
            // once.
            unsafe {
                is.range(place.clone()).fill(i as i64);
                for (slot, &j) in js
                    .range(place.clone())
                    .iter_mut()
                    .zip(&chunk.js[row.clone()])
                {
                    *slot = j as i64;
                }
                if quantities.distances {
                    let r2s = &chunk.r2s[row.clone()];
                    for (r, r2) in rs.range(place.clone()).iter_mut().zip(r2s) {
                        *r = r2.sqrt();
                    }
                }
                if !quantities.separations() {
                    continue;
                }
                let seps = &chunk.separations[row.clone()];
                if quantities.vectors {
                    let v = ds.range(place.start * D..place.end * D);
                    for (slot, d) in v.chunks_exact_mut(D).zip(seps) {
                        slot.copy_from_slice(d);
                    }
                }
                if quantities.shifts {
                    let s = ss.range(place.start * D..place.end * D);
                    let rows = s.chunks_exact_mut(D).zip(&chunk.js[row.clone()]).zip(seps);
                    for ((slot, &j), d) in rows {
                        let shift = image_shift(domain, &points[i], &points[j as usize], d);
                        slot.copy_from_slice(&shift);
                    }
                }
            }
        }
    };
    if threads.count() == 1 {
        chunks.iter().for_each(place);
    } else {
        threads.install(|| chunks.par_iter().for_each(place));
    }
    out
}

/// The same pairs and quantities as [`sorted_half_list`], in the order the half
/// stencil finds them (cell order, fixed by the data): no row sort and no
/// placement, so about the cost of the bare pair search. What vesin returns
/// with `sorted=False`.
pub fn half_list_as_found<const D: usize>(
    cells: &CellList<D>,
    points: &[[f64; D]],
    cutoff: f64,
    quantities: PairQuantities,
    threads: &Threads,
) -> PairArrays {
    // the bare index list gets its own loop, small enough to be inlined whole
    if quantities == PairQuantities::default() {
        as_found::<D, false>(cells, points, cutoff, quantities, threads)
    } else {
        as_found::<D, true>(cells, points, cutoff, quantities, threads)
    }
}

/// [`half_list_as_found`], with the quantities other than `i` and `j` left out
/// at compile time unless `QUANTITIES`.
fn as_found<const D: usize, const QUANTITIES: bool>(
    cells: &CellList<D>,
    points: &[[f64; D]],
    cutoff: f64,
    quantities: PairQuantities,
    threads: &Threads,
) -> PairArrays {
    let test = checked_test(cells, points, cutoff);
    let order = cells.order();
    let domain = cells.domain();
    let fill = |homes: std::ops::Range<usize>, out: &mut PairArrays| {
        for home in homes {
            for_each_row_in_cell(cells, home, StencilKind::Half, &test, |i, j, _, d, r2| {
                out.push_found::<D, QUANTITIES>(
                    order[i], order[j], d, r2, quantities, domain, points,
                );
            });
        }
    };
    let num_cells = cells.grid().num_cells();
    let guess = expected_pairs(cells, cutoff);
    if threads.count() == 1 {
        let mut out = PairArrays::with_capacity::<D>(guess, quantities);
        fill(0..num_cells, &mut out);
        return out;
    }
    let parts: Vec<PairArrays> = threads.install(|| {
        Threads::chunks(num_cells)
            .map(|homes| {
                let share = guess * homes.len() / num_cells.max(1);
                let mut out = PairArrays::with_capacity::<D>(share, quantities);
                fill(homes, &mut out);
                out
            })
            .collect()
    });
    let total = parts.iter().map(PairArrays::len).sum();
    let mut out = PairArrays::with_capacity::<D>(total, quantities);
    for part in parts {
        out.i.extend_from_slice(&part.i);
        out.j.extend_from_slice(&part.j);
        out.distances.extend_from_slice(&part.distances);
        out.vectors.extend_from_slice(&part.vectors);
        out.shifts.extend_from_slice(&part.shifts);
    }
    out
}

/// The cutoff test of a list of `points` binned in `cells`.
///
/// # Panics
/// If `cutoff` exceeds the cutoff the cell list was built for, or `points` is
/// not the cell list's particle count.
fn checked_test<const D: usize>(
    cells: &CellList<D>,
    points: &[[f64; D]],
    cutoff: f64,
) -> CutoffTest {
    assert!(
        cutoff <= cells.cutoff(),
        "cutoff {cutoff} above the cell list's {}",
        cells.cutoff()
    );
    assert_eq!(points.len(), cells.len(), "one point per particle");
    CutoffTest::new(cutoff)
}

/// `S_a = round((d_a - (x_{j,a} - x_{i,a})) / L_a)` on periodic axes, 0 on open ones.
fn image_shift<const D: usize>(
    domain: &Domain<D>,
    xi: &[f64; D],
    xj: &[f64; D],
    d: &[f64; D],
) -> [i32; D] {
    std::array::from_fn(|a| {
        if domain.is_periodic(a) {
            ((d[a] - (xj[a] - xi[a])) / domain.length[a]).round() as i32
        } else {
            0
        }
    })
}

/// The rows of every particle, chunk of cells by chunk of cells (in parallel),
/// the chunks in cell order; squared distances and separations kept when the
/// `quantities` need them.
fn find_rows<const D: usize>(
    cells: &CellList<D>,
    test: &CutoffTest,
    quantities: PairQuantities,
    threads: &Threads,
) -> Vec<ChunkRows<D>> {
    let num_cells = cells.grid().num_cells();
    let rows = |homes: std::ops::Range<usize>| {
        let first_slot = if homes.is_empty() {
            0
        } else {
            cells.cell_range(homes.start).start
        };
        let mut chunk = ChunkRows {
            first_slot,
            ..ChunkRows::default()
        };
        for home in homes {
            rows_of_cell(cells, home, test, quantities, &mut chunk);
        }
        chunk
    };
    if threads.count() == 1 {
        return vec![rows(0..num_cells)];
    }
    threads.install(|| Threads::chunks(num_cells).map(rows).collect())
}

/// Appends to `chunk` the row of every particle of cell `home`: its neighbours
/// `j > i` (input numbering) over the full stencil, sorted by `j`.
fn rows_of_cell<const D: usize>(
    cells: &CellList<D>,
    home: usize,
    test: &CutoffTest,
    quantities: PairQuantities,
    chunk: &mut ChunkRows<D>,
) {
    let (keep_r2, keep_separations) = (quantities.distances, quantities.separations());
    let order = cells.order();
    let mut runs = [StencilRun::<D>::default(); 27];
    let count = cells
        .grid()
        .stencil_runs(home, StencilKind::Full, &mut runs);
    let mut scratch = ScanScratch::default();
    // (j << 32 | position in the row found): sorting these sorts the row by j
    let mut keys: Vec<u64> = Vec::with_capacity(64);
    let mut found: Vec<[f64; D]> = Vec::with_capacity(64);
    let mut found_r2: Vec<f64> = Vec::with_capacity(64);
    for slot in cells.cell_range(home) {
        let i = order[slot];
        keys.clear();
        found.clear();
        found_r2.clear();
        for_each_in_row(
            cells,
            slot,
            &runs[..count],
            StencilKind::Full,
            test,
            &mut scratch,
            |other, _, d, r2| {
                let j = order[other];
                if j > i {
                    keys.push(((j as u64) << 32) | keys.len() as u64);
                    if keep_r2 {
                        found_r2.push(r2);
                    }
                    if keep_separations {
                        found.push(*d);
                    }
                }
            },
        );
        keys.sort_unstable();
        chunk.lengths.push(keys.len() as u32);
        chunk.js.extend(keys.iter().map(|k| (k >> 32) as u32));
        let found_at = |k: &u64| (k & 0xffff_ffff) as usize;
        if keep_r2 {
            chunk.r2s.extend(keys.iter().map(|k| found_r2[found_at(k)]));
        }
        if keep_separations {
            chunk
                .separations
                .extend(keys.iter().map(|k| found[found_at(k)]));
        }
    }
}

/// The sorted half list of points that move between calls, kept with a skin:
/// the pairs within `cutoff + skin` are found only when some point has moved
/// more than `skin / 2` since the last search (or the count changed), and each
/// call keeps those within `cutoff` now, `d = x_j - x_i + S L` with the image
/// shifts `S` of the search. The Python module's `NeighborList`.
#[derive(Clone, Debug)]
pub struct SkinList<const D: usize> {
    length: [f64; D],
    lo: [f64; D],
    periodic: [bool; D],
    cutoff: f64,
    skin: f64,
    candidates: PairArrays,
    reference: Vec<[f64; D]>,
    searches: u64,
}

impl<const D: usize> SkinList<D> {
    /// The list of pairs within `cutoff` in the box of sides `length` from `lo`
    /// with the periodic axes `periodic` (open axes span the points, see
    /// [`Domain::for_points`]), searched with a margin `skin >= 0`.
    pub fn new(
        length: [f64; D],
        lo: [f64; D],
        periodic: [bool; D],
        cutoff: f64,
        skin: f64,
    ) -> Self {
        SkinList {
            length,
            lo,
            periodic,
            cutoff,
            skin,
            candidates: PairArrays::default(),
            reference: Vec::new(),
            searches: 0,
        }
    }

    /// Number of searches so far (cell list and pairs within `cutoff + skin`).
    pub fn searches(&self) -> u64 {
        self.searches
    }

    /// The pairs of `points` within the cutoff, sorted by `(i, j)`, with the
    /// `quantities` asked for; searches anew first when needed.
    pub fn update(
        &mut self,
        points: &[[f64; D]],
        quantities: PairQuantities,
        threads: &Threads,
    ) -> Result<PairArrays, crate::geometry::GeometryError> {
        let moved = points.len() != self.reference.len()
            || self.searches == 0
            || super::verlet::moved_beyond_half_skin(points, &self.reference, self.skin);
        if moved {
            let domain = Domain::for_points(points, self.length, self.lo, self.periodic)?;
            let reach = self.cutoff + self.skin;
            let cells = CellList::build_in(&domain, reach, points, threads)?;
            let all = PairQuantities {
                distances: false,
                vectors: false,
                shifts: true,
            };
            self.candidates = sorted_half_list(&cells, points, reach, all, threads);
            self.reference.clear();
            self.reference.extend_from_slice(points);
            self.searches += 1;
        }
        Ok(self.within_cutoff(points, quantities))
    }

    /// The candidates within the cutoff at `points`.
    fn within_cutoff(&self, points: &[[f64; D]], quantities: PairQuantities) -> PairArrays {
        let test = CutoffTest::new(self.cutoff);
        let c = &self.candidates;
        let mut out = PairArrays::default();
        for k in 0..c.len() {
            let (i, j) = (c.i[k] as usize, c.j[k] as usize);
            let shift = &c.shifts[k * D..(k + 1) * D];
            let d: [f64; D] = std::array::from_fn(|a| {
                (points[j][a] - points[i][a]) + shift[a] as f64 * self.length[a]
            });
            let r2 = norm2(&d);
            if !test.accepts(r2) {
                continue;
            }
            out.i.push(c.i[k]);
            out.j.push(c.j[k]);
            if quantities.distances {
                out.distances.push(r2.sqrt());
            }
            if quantities.vectors {
                out.vectors.extend_from_slice(&d);
            }
            if quantities.shifts {
                out.shifts.extend_from_slice(shift);
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::random::Rng;

    #[test]
    fn the_skin_list_follows_moving_points_with_few_searches() {
        let side = 8.0;
        let mut rng = Rng::new(7);
        let mut points: Vec<[f64; 3]> = (0..400)
            .map(|_| std::array::from_fn(|_| rng.uniform() * side))
            .collect();
        let threads = Threads::single();
        let all = PairQuantities {
            distances: true,
            vectors: true,
            shifts: true,
        };
        let mut list = SkinList::new([side; 3], [0.0; 3], [true, true, false], 1.5, 0.4);
        for _ in 0..10 {
            let kept = list.update(&points, all, &threads).unwrap();
            let domain = Domain::for_points(&points, [side; 3], [0.0; 3], [true, true, false]);
            let cells = CellList::build(&domain.unwrap(), 1.5, &points).unwrap();
            let fresh = sorted_half_list(&cells, &points, 1.5, all, &threads);
            assert_eq!((&kept.i, &kept.j), (&fresh.i, &fresh.j));
            assert_eq!(kept.shifts, fresh.shifts);
            for (a, b) in kept.distances.iter().zip(&fresh.distances) {
                assert!((a - b).abs() < 1e-12);
            }
            for p in &mut points {
                p[0] += 0.1 * (rng.uniform() - 0.5);
                p[2] += 0.05 * (rng.uniform() - 0.5);
            }
        }
        assert!(list.searches() < 10, "{} searches", list.searches());
        assert!(list.searches() > 1, "the points moved beyond skin / 2");
    }
}
