//! The half list of pairs sorted by `(i, j)` in input numbering, with the
//! quantities vesin returns: what `cellist neighbors` prints and what the Python
//! module's `neighbors` returns.
//!
//! The pairs are found over the half stencil in cell order, as the list as found
//! is, and each is filed under its row: the slot of its particle with the smaller
//! input number. A counting sort by that slot gathers the rows; slot order is
//! cell order, so its writes stay near the search's. The prefix sums of the row
//! lengths, in input order, then place every row, sorted by `j`, once. No global
//! sort, and the same bits for any thread count. A pair's separation is the one
//! the full stencil gives from the row's particle: the half stencil's, negated
//! when the row is the other particle's, `(x_a - x_b) + (-s) = -((x_b - x_a) + s)`
//! exactly in binary64.

use super::cell_list::CellList;
use super::grid::StencilKind;
use super::pairs::{balanced_cell_runs, expected_pairs, share_of, tasks_for};
use super::traverse::{for_each_row_in_cell, CutoffTest};
use crate::geometry::{norm2, Domain};
use crate::memory::{large_vec, populate, prefetch};
use crate::threads::{
    counting_sort_parts, map_parts, most_sort_parts, part_ranges, parts_for, DisjointSlice, Threads,
};
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
            let d = from_first(a, b, d);
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

/// The separation of a pair found from the particle numbered `a` (input
/// numbering), `d = (x_b - x_a) + s`, seen from the pair's particle with the
/// smaller number: `d` itself, or `-d` when that is `b`. The negation is what
/// a search from `b` computes, to the bit: `(x_a - x_b) + (-s) = -((x_b - x_a)
/// + s)` in binary64, and `r^2` is the same either way.
#[inline(always)]
fn from_first<const D: usize>(a: u32, b: u32, d: &[f64; D]) -> [f64; D] {
    if a < b {
        *d
    } else {
        d.map(|x| -x)
    }
}

/// Pairs filed under their rows: each pair's second input number `j` and,
/// when the quantities need them, its `r^2` and its separation `x_j - x_i`
/// (minimum image) from the row's particle `i`.
struct RowEntries<const D: usize> {
    js: Vec<u32>,
    r2s: Vec<f64>,
    separations: Vec<[f64; D]>,
}

impl<const D: usize> RowEntries<D> {
    /// Empty columns with room for `pairs` entries, those of the quantities
    /// not asked for without room (large buffers advised to use huge pages).
    fn with_capacity(pairs: usize, quantities: PairQuantities) -> Self {
        let room = |wanted: bool| if wanted { pairs } else { 0 };
        RowEntries {
            js: large_vec(pairs),
            r2s: large_vec(room(quantities.distances)),
            separations: large_vec(room(quantities.separations())),
        }
    }
}

/// The pairs one task of the search found, in the order found: each pair's
/// row (the slot of its particle with the smaller input number) and its entry
/// in that row.
struct FoundPairs<const D: usize> {
    rows: Vec<u32>,
    entries: RowEntries<D>,
}

/// Every pair `(i, j)`, `i < j` in input numbering, with `|x_j - x_i| < cutoff`
/// (minimum image on the periodic axes of `cells`' domain), sorted by `(i, j)`,
/// with the `quantities` asked for. `points` are the positions `cells` was built
/// from, in input order: the image shifts are counted from them,
/// `S_a = round((d_a - (x_{j,a} - x_{i,a})) / L_a)`.
///
/// # Panics
/// If `cutoff` exceeds the cutoff the cell list was built for, if `points` is
/// not the cell list's particle count, or at `2^32 - 1` pairs or more (the
/// rows are gathered with `u32` offsets).
pub fn sorted_half_list<const D: usize>(
    cells: &CellList<D>,
    points: &[[f64; D]],
    cutoff: f64,
    quantities: PairQuantities,
    threads: &Threads,
) -> PairArrays {
    let test = checked_test(cells, points, cutoff);
    // the bare index list gets its own search loop, as in `as_found`
    let found = if quantities == PairQuantities::default() {
        find_pairs::<D, false>(cells, &test, quantities, threads)
    } else {
        find_pairs::<D, true>(cells, &test, quantities, threads)
    };
    let (start, rows) = gather_rows(&found, cells.len(), quantities, threads);
    // the found pairs are copied into the rows: their memory goes before the
    // output's is taken
    drop(found);
    place_rows(cells, points, &start, &rows, quantities, threads)
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

/// Every pair over the half stencil, in cell order, filed under its row, in
/// parts (balanced runs of cells, in parallel): the parts in cell order. The
/// quantities are left out at compile time unless `QUANTITIES`.
fn find_pairs<const D: usize, const QUANTITIES: bool>(
    cells: &CellList<D>,
    test: &CutoffTest,
    quantities: PairQuantities,
    threads: &Threads,
) -> Vec<FoundPairs<D>> {
    let order = cells.order();
    let (keep_r2, keep_separations) = (quantities.distances, quantities.separations());
    let guess = expected_pairs(cells, test.cutoff());
    let find = |homes: &std::ops::Range<usize>| {
        let room = share_of(guess, cells, homes);
        let mut found = FoundPairs {
            rows: large_vec(room),
            entries: RowEntries::with_capacity(room, quantities),
        };
        for home in homes.clone() {
            for_each_row_in_cell(cells, home, StencilKind::Half, test, |a, b, _, d, r2| {
                let (ia, ib) = (order[a], order[b]);
                found.rows.push(if ia < ib { a } else { b } as u32);
                found.entries.js.push(ia.max(ib));
                if QUANTITIES {
                    if keep_r2 {
                        found.entries.r2s.push(r2);
                    }
                    if keep_separations {
                        found.entries.separations.push(from_first(ia, ib, d));
                    }
                }
            });
        }
        found
    };
    // the gather's counting sort keeps a row of n counts per part: at most
    // a few counts per expected pair, however many threads
    let tasks = tasks_for(threads).min(most_sort_parts(guess, cells.len()));
    let runs = balanced_cell_runs(cells, tasks);
    if threads.count() == 1 {
        return runs.iter().map(find).collect();
    }
    threads.install(|| runs.par_iter().map(find).collect())
}

/// The `found` pairs gathered row by row (the rows are the `n` slots) by a
/// stable counting sort in parts: `start` (returned first) holds the `n + 1`
/// offsets of the rows' entries, in the order found within a row. The sort's
/// parts are the search's (see [`find_pairs`] for their number).
fn gather_rows<const D: usize>(
    found: &[FoundPairs<D>],
    n: usize,
    quantities: PairQuantities,
    threads: &Threads,
) -> (Vec<u32>, RowEntries<D>) {
    let total: usize = found.iter().map(|part| part.rows.len()).sum();
    let room = |wanted: bool| if wanted { total } else { 0 };
    let (r2_room, separation_room) = (room(quantities.distances), room(quantities.separations()));
    let mut rows = RowEntries::<D>::with_capacity(total, quantities);
    let js = DisjointSlice::new(&mut rows.js.spare_capacity_mut()[..total]);
    let r2s = DisjointSlice::new(&mut rows.r2s.spare_capacity_mut()[..r2_room]);
    let separations =
        DisjointSlice::new(&mut rows.separations.spare_capacity_mut()[..separation_room]);
    let (mut start, mut counts) = (Vec::new(), Vec::new());
    // SAFETY: each part's items are its found pairs, in order, with their
    // rows as keys: the same on both passes. Every slot below `total` is
    // given to one pair (the columns of the quantities asked for are `total`
    // long), so `place` writes each slot once.
    unsafe {
        counting_sort_parts(
            found.len(),
            |q| (0..found[q].rows.len()).map(move |k| (q, k)),
            |&(q, k)| found[q].rows[k],
            n,
            Some(threads),
            &mut start,
            &mut counts,
            |(q, k), slot| {
                let entries = &found[q].entries;
                js.get_unchecked(slot).write(entries.js[k]);
                if quantities.distances {
                    r2s.get_unchecked(slot).write(entries.r2s[k]);
                }
                if quantities.separations() {
                    separations
                        .get_unchecked(slot)
                        .write(entries.separations[k]);
                }
            },
        );
    }
    // SAFETY: the counting sort gave out exactly the slots 0..total, each once
    unsafe {
        rows.js.set_len(total);
        rows.r2s.set_len(r2_room);
        rows.separations.set_len(separation_room);
    }
    (start, rows)
}

/// How many rows ahead [`place_rows`] asks for a row's entries.
const ROWS_AHEAD: usize = 8;

/// The rows (entries `start[s]..start[s + 1]` of `rows` for slot `s`) sorted by
/// `j` and placed in input order, with the `quantities` asked for: the sorted
/// half list. The rows are taken in input order, in parts (in parallel), so
/// that each part writes its stretch of the output from start to end; only
/// the rows' reads jump.
fn place_rows<const D: usize>(
    cells: &CellList<D>,
    points: &[[f64; D]],
    start: &[u32],
    rows: &RowEntries<D>,
    quantities: PairQuantities,
    threads: &Threads,
) -> PairArrays {
    let order = cells.order();
    let n = cells.len();
    // where each particle's row begins in `rows` and in the output
    let mut entries_of = vec![0u32; n];
    let mut place_of = vec![0usize; n + 1];
    for (slot, &i) in order.iter().enumerate() {
        entries_of[i as usize] = start[slot];
        place_of[i as usize + 1] = (start[slot + 1] - start[slot]) as usize;
    }
    for i in 0..n {
        place_of[i + 1] += place_of[i];
    }
    let total = place_of[n];
    // the elements of the quantities' columns that hold the pairs `pairs`
    // (`D` per pair for the vectors and shifts; none for those not asked for)
    let quantity_ranges = |pairs: std::ops::Range<usize>| {
        let wide = pairs.start * D..pairs.end * D;
        let only = |wanted: bool, range| if wanted { range } else { 0..0 };
        (
            only(quantities.distances, pairs),
            only(quantities.vectors, wide.clone()),
            only(quantities.shifts, wide),
        )
    };
    // ordinary zeroed memory, not advised to use huge pages as `large_vec` is:
    // returned to numpy and freed between calls, huge pages came back cold
    // more often than small ones (docs/benchmarks.md, 2026-11-27 evening)
    let (r, d, s) = quantity_ranges(0..total);
    let mut out = PairArrays {
        i: vec![0; total],
        j: vec![0; total],
        distances: vec![0.0; r.len()],
        vectors: vec![0.0; d.len()],
        shifts: vec![0; s.len()],
    };
    let is = DisjointSlice::new(&mut out.i);
    let js = DisjointSlice::new(&mut out.j);
    let rs = DisjointSlice::new(&mut out.distances);
    let ds = DisjointSlice::new(&mut out.vectors);
    let ss = DisjointSlice::new(&mut out.shifts);
    let domain = cells.domain();
    let with_quantities = quantities != PairQuantities::default();
    let ranges = part_ranges(n, parts_for(Some(threads)));
    map_parts(Some(threads), ranges.len(), |p| {
        // (j << 32 | entry in the row): sorting these sorts the row by j
        let mut keys: Vec<u64> = Vec::with_capacity(64);
        let mut sorted_js: Vec<u32> = Vec::with_capacity(64);
        // this part's stretch of the output, mapped in one call per array
        let stretch = place_of[ranges[p].start]..place_of[ranges[p].end];
        let (r, d, s) = quantity_ranges(stretch.clone());
        // SAFETY: the parts' stretches are disjoint; the slices end here,
        // before the rows' own are taken
        unsafe {
            populate(is.range(stretch.clone()));
            populate(js.range(stretch));
            populate(rs.range(r));
            populate(ds.range(d));
            populate(ss.range(s));
        }
        for i in ranges[p].clone() {
            let place = place_of[i]..place_of[i + 1];
            let entries = entries_of[i] as usize..entries_of[i] as usize + place.len();
            // the rows are read in random places: ask for one a few rows ahead
            if let Some(&ahead) = entries_of.get(i + ROWS_AHEAD) {
                prefetch(&rows.js, ahead as usize, 2);
            }
            // SAFETY: the rows partition 0..total (prefix sums of the row
            // lengths), and each row is placed once, by the part of its `i`
            let (out_i, out_j) = unsafe { (is.range(place.clone()), js.range(place.clone())) };
            out_i.fill(i as i64);
            if !with_quantities {
                sorted_js.clear();
                sorted_js.extend_from_slice(&rows.js[entries]);
                sorted_js.sort_unstable();
                for (out, &j) in out_j.iter_mut().zip(&sorted_js) {
                    *out = j as i64;
                }
                continue;
            }
            keys.clear();
            keys.extend(
                rows.js[entries.clone()]
                    .iter()
                    .enumerate()
                    .map(|(k, &j)| ((j as u64) << 32) | k as u64),
            );
            keys.sort_unstable();
            let entry = |key: &u64| entries.start + (key & 0xffff_ffff) as usize;
            for (out, key) in out_j.iter_mut().zip(&keys) {
                *out = (key >> 32) as i64;
            }
            let (r, d, s) = quantity_ranges(place);
            // SAFETY: as above
            let (out_r, out_d, out_s) = unsafe { (rs.range(r), ds.range(d), ss.range(s)) };
            for (r, key) in out_r.iter_mut().zip(&keys) {
                *r = rows.r2s[entry(key)].sqrt();
            }
            for (d, key) in out_d.chunks_exact_mut(D).zip(&keys) {
                d.copy_from_slice(&rows.separations[entry(key)]);
            }
            for (s, key) in out_s.chunks_exact_mut(D).zip(&keys) {
                let (j, d) = ((key >> 32) as usize, &rows.separations[entry(key)]);
                s.copy_from_slice(&image_shift(domain, &points[i], &points[j], d));
            }
        }
    });
    out
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
    fn no_points_give_no_pairs() {
        let none: Vec<[f64; 3]> = Vec::new();
        let domain = Domain::for_points(&none, [5.0; 3], [0.0; 3], [true; 3]).unwrap();
        let cells = CellList::build(&domain, 1.5, &none).unwrap();
        let all = PairQuantities {
            distances: true,
            vectors: true,
            shifts: true,
        };
        for threads in [Threads::single(), Threads::new(2).unwrap()] {
            let pairs = sorted_half_list(&cells, &none, 1.5, all, &threads);
            assert_eq!(pairs, PairArrays::default());
        }
    }

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
