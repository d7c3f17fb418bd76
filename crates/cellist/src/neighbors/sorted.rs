//! The half list of pairs sorted by `(i, j)` in input numbering, with the
//! quantities vesin returns: what `cellist neighbors` prints and what the Python
//! module's `neighbors` returns.
//!
//! The rows are found in cell order, so that the search streams through memory,
//! and written in input order: a first pass counts each particle's neighbours
//! `j > i` (its row length), the prefix sums place every row, and a second pass
//! writes each row sorted by `j` into its place. No global sort, no copy of the
//! result, and the same bits for any thread count.

use super::cell_list::CellList;
use super::grid::{StencilKind, StencilRun};
use super::traverse::{for_each_in_row, CutoffTest, ScanScratch};
use crate::geometry::Domain;
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

/// The half list in the layout of vesin and numpy: pair `k` is `(i[k], j[k])`
/// with `i < j`, sorted by `i` then `j`; the quantities not asked for are empty.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SortedPairs {
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

impl SortedPairs {
    /// Number of pairs.
    pub fn len(&self) -> usize {
        self.i.len()
    }

    /// True without pairs.
    pub fn is_empty(&self) -> bool {
        self.i.is_empty()
    }
}

/// One neighbour of a row while the row is sorted: input index, separation.
#[derive(Clone, Copy)]
struct Entry<const D: usize> {
    j: u32,
    d: [f64; D],
    r2: f64,
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
) -> SortedPairs {
    assert!(
        cutoff <= cells.cutoff(),
        "cutoff {cutoff} above the cell list's {}",
        cells.cutoff()
    );
    assert_eq!(points.len(), cells.len(), "one point per particle");
    let test = CutoffTest::new(cutoff);
    let order = cells.order();
    let n = cells.len();
    // pass 1: row lengths, in slot order, then placed in input order
    let mut by_slot = vec![0u32; n];
    for_each_chunk(cells, threads, &mut by_slot, |home, lengths, first| {
        visit_rows(cells, home, &test, |slot, row| {
            lengths[slot - first] = row.len() as u32;
        });
    });
    let mut start = vec![0usize; n + 1];
    for (slot, &length) in by_slot.iter().enumerate() {
        start[order[slot] as usize + 1] = length as usize;
    }
    for k in 0..n {
        start[k + 1] += start[k];
    }
    drop(by_slot);
    let total = start[n];
    let mut out = SortedPairs {
        i: vec![0; total],
        j: vec![0; total],
        distances: vec![0.0; if quantities.distances { total } else { 0 }],
        vectors: vec![0.0; if quantities.vectors { total * D } else { 0 }],
        shifts: vec![0; if quantities.shifts { total * D } else { 0 }],
    };
    // pass 2: every row written, sorted by j, into its own range of each array
    let is = DisjointSlice::new(&mut out.i);
    let js = DisjointSlice::new(&mut out.j);
    let rs = DisjointSlice::new(&mut out.distances);
    let ds = DisjointSlice::new(&mut out.vectors);
    let ss = DisjointSlice::new(&mut out.shifts);
    let domain = cells.domain();
    let mut unused: Vec<()> = vec![(); n];
    for_each_chunk(cells, threads, &mut unused, |home, _, _| {
        visit_rows(cells, home, &test, |slot, row| {
            let i = order[slot] as usize;
            let place = start[i]..start[i + 1];
            debug_assert_eq!(place.len(), row.len());
            // SAFETY: the rows partition 0..total (prefix sums of the row lengths),
            // and row `i` is visited by exactly one task, once.
            unsafe {
                is.range(place.clone()).fill(i as i64);
                for (slot_j, e) in js.range(place.clone()).iter_mut().zip(row.iter()) {
                    *slot_j = e.j as i64;
                }
                if quantities.distances {
                    for (r, e) in rs.range(place.clone()).iter_mut().zip(row.iter()) {
                        *r = e.r2.sqrt();
                    }
                }
                if quantities.vectors {
                    let v = ds.range(place.start * D..place.end * D);
                    for (d, e) in v.chunks_exact_mut(D).zip(row.iter()) {
                        d.copy_from_slice(&e.d);
                    }
                }
                if quantities.shifts {
                    let s = ss.range(place.start * D..place.end * D);
                    for (s, e) in s.chunks_exact_mut(D).zip(row.iter()) {
                        let shift = image_shift(domain, &points[i], &points[e.j as usize], &e.d);
                        s.copy_from_slice(&shift);
                    }
                }
            }
        });
    });
    out
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

/// Runs `work(home, part, first)` for every home cell, on chunks of cells in
/// parallel; `part` is the piece of the slot-ordered `values` that the chunk's
/// slots own, starting at slot `first`.
fn for_each_chunk<const D: usize, T: Send>(
    cells: &CellList<D>,
    threads: &Threads,
    values: &mut [T],
    work: impl Fn(usize, &mut [T], usize) + Sync,
) {
    let num_cells = cells.grid().num_cells();
    if threads.count() == 1 {
        for home in 0..num_cells {
            work(home, values, 0);
        }
        return;
    }
    // the chunks' slot ranges, in order, split the slot array without overlap
    let ranges: Vec<std::ops::Range<usize>> = Threads::chunks(num_cells).collect();
    let mut parts = Vec::with_capacity(ranges.len());
    let mut rest = values;
    let mut first = 0;
    for cells_range in &ranges {
        let end = cells.cell_range(cells_range.end - 1).end;
        let (part, tail) = rest.split_at_mut(end - first);
        parts.push((cells_range.clone(), part, first));
        rest = tail;
        first = end;
    }
    threads.install(|| {
        parts.into_par_iter().for_each(|(homes, part, first)| {
            for home in homes {
                work(home, part, first);
            }
        })
    });
}

/// For every particle of cell `home`, its row of neighbours `j > i` (input
/// numbering) over the full stencil, sorted by `j`, as `visit(slot, row)`.
fn visit_rows<const D: usize>(
    cells: &CellList<D>,
    home: usize,
    test: &CutoffTest,
    mut visit: impl FnMut(usize, &[Entry<D>]),
) {
    let order = cells.order();
    let mut runs = [StencilRun::<D>::default(); 27];
    let count = cells
        .grid()
        .stencil_runs(home, StencilKind::Full, &mut runs);
    let mut scratch = ScanScratch::default();
    let mut row: Vec<Entry<D>> = Vec::with_capacity(64);
    for slot in cells.cell_range(home) {
        let i = order[slot];
        row.clear();
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
                    row.push(Entry { j, d: *d, r2 });
                }
            },
        );
        row.sort_unstable_by_key(|e| e.j);
        visit(slot, &row);
    }
}
