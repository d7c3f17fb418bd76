//! The half list of pairs within a cutoff, in input numbering: what `vesin`'s
//! `compute(quantities="ij")` returns and what `cellist neighbors` prints.

use super::cell_list::CellList;
use super::grid::StencilKind;
use super::traverse::{for_each_row_in_cell, CutoffTest};
use crate::threads::{collect_in_order, collect_in_order_into, DisjointSlice, Stretch, Threads};

/// Every pair `(i, j)`, `i < j` in input numbering, with `|x_j - x_i| < cutoff`
/// (minimum image on periodic axes), as `make(i, j, r^2)`, in an order fixed by
/// the data (cell order), whatever the thread count.
///
/// # Panics
/// If `cutoff` exceeds the cutoff the cell list was built for.
pub fn half_pairs<const D: usize, T: Copy + Send + Sync>(
    cells: &CellList<D>,
    cutoff: f64,
    threads: &Threads,
    make: impl Fn(u32, u32, f64) -> T + Sync,
) -> Vec<T> {
    assert!(
        cutoff <= cells.cutoff(),
        "cutoff {cutoff} above the cell list's {}",
        cells.cutoff()
    );
    let test = CutoffTest::new(cutoff);
    let order = cells.order();
    let runs = balanced_cell_runs(cells, tasks_for(threads));
    let guess = expected_pairs(cells, cutoff);
    let estimates: Vec<usize> = runs
        .iter()
        .map(|homes| share_of(guess, cells, homes))
        .collect();
    collect_in_order(&estimates, threads, |k, out| {
        for home in runs[k].clone() {
            cell_pairs(cells, home, &test, order, &make, out);
        }
    })
}

/// The pairs of [`half_pairs`] whose first slot lies in cell `home`, appended
/// to `out`. Kept out of line: the scan then has the registers to itself.
#[inline(never)]
fn cell_pairs<const D: usize, T>(
    cells: &CellList<D>,
    home: usize,
    test: &CutoffTest,
    order: &[u32],
    make: &impl Fn(u32, u32, f64) -> T,
    out: &mut Stretch<T>,
) {
    for_each_row_in_cell(cells, home, StencilKind::Half, test, |i, j, _, _, r2| {
        let (a, b) = (order[i], order[j]);
        out.push(make(a.min(b), a.max(b), r2));
    });
}

/// Rows in CSR form, built in parallel by runs of cells and the same for any
/// thread count: `fill(home, out, lengths, scratch)` appends the entries of the
/// rows of cell `home` to `out`, in row order, and writes the length of each of
/// those rows to `lengths[row]` (every row belongs to one cell, and one task
/// visits a cell); `scratch` is the task's own, kept from one cell to the next
/// (which cells share a task depends on the thread count: what `fill` appends
/// must not depend on what the scratch holds when it is called).
/// `start` gets the `rows + 1` row starts (the prefix sums of the lengths),
/// `entries` the entries, both reusing their memory. `guess`, the expected
/// number of entries, sizes the tasks' stretches of the result.
pub(crate) fn rows_by_cells<const D: usize, T: Copy + Send + Sync, S: Default>(
    cells: &CellList<D>,
    rows: usize,
    guess: usize,
    threads: &Threads,
    start: &mut Vec<usize>,
    entries: &mut Vec<T>,
    fill: impl Fn(usize, &mut Stretch<T>, &DisjointSlice<usize>, &mut S) + Sync,
) {
    let runs = balanced_cell_runs(cells, tasks_for(threads));
    let estimates: Vec<usize> = runs
        .iter()
        .map(|homes| share_of(guess, cells, homes))
        .collect();
    // row lengths first, shifted by one so that the prefix sum gives the starts
    start.clear();
    start.resize(rows + 1, 0);
    let lengths = DisjointSlice::new(&mut start[1..]);
    collect_in_order_into(entries, &estimates, threads, |k, out| {
        let mut scratch = S::default();
        for home in runs[k].clone() {
            fill(home, out, &lengths, &mut scratch);
        }
    });
    for r in 0..rows {
        start[r + 1] += start[r];
    }
}

/// Tasks of a pair search split into runs of cells: one on one thread, else a
/// few per thread, so that a thread slowed down by others on its core does
/// not hold up the rest.
pub(crate) fn tasks_for(threads: &Threads) -> usize {
    const TASKS_PER_THREAD: usize = 2;
    match threads.count() {
        1 => 1,
        n => TASKS_PER_THREAD * n,
    }
}

/// `parts` runs of consecutive cells (in cell order, covering every cell)
/// holding about equal numbers of particles.
pub(crate) fn balanced_cell_runs<const D: usize>(
    cells: &CellList<D>,
    parts: usize,
) -> Vec<std::ops::Range<usize>> {
    let starts = cells.cell_start();
    let num_cells = starts.len() - 1;
    let n = cells.len();
    let parts = parts.clamp(1, num_cells.max(1));
    let bounds: Vec<usize> = (0..=parts)
        .map(|k| match k {
            0 => 0,
            k if k == parts => num_cells,
            k => starts[..num_cells].partition_point(|&s| (s as usize) < n * k / parts),
        })
        .collect();
    bounds.windows(2).map(|w| w[0]..w[1].max(w[0])).collect()
}

/// The part of `pairs` expected from the particles of cells `homes`.
pub(crate) fn share_of<const D: usize>(
    pairs: usize,
    cells: &CellList<D>,
    homes: &std::ops::Range<usize>,
) -> usize {
    if homes.is_empty() {
        return 0;
    }
    let slots = cells.cell_range(homes.start).start..cells.cell_range(homes.end - 1).end;
    (pairs as u128 * slots.len() as u128 / cells.len().max(1) as u128) as usize
}

/// A capacity hint: the half-list size of uniformly spread particles,
/// `N^2 / 2 * V_ball(r_c) / V_box` plus 10%, with the ball clipped to the box on
/// each axis (a flat open axis is not an empty box) and at most `64 N` (the
/// vector grows past a hint).
pub(crate) fn expected_pairs<const D: usize>(cells: &CellList<D>, cutoff: f64) -> usize {
    let n = cells.len() as f64;
    let ball_over_cube = match D {
        2 => std::f64::consts::PI / 4.0,
        _ => std::f64::consts::PI / 6.0,
    };
    let fraction: f64 = (0..D)
        .map(|d| (2.0 * cutoff / cells.domain().length[d]).min(1.0))
        .product();
    let estimate = 0.55 * n * n * ball_over_cube * fraction;
    estimate.min(64.0 * n) as usize
}
