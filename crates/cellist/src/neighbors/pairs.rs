//! The half list of pairs within a cutoff, in input numbering: what `vesin`'s
//! `compute(quantities="ij")` returns and what `cellist neighbors` prints.

use super::cell_list::CellList;
use super::grid::StencilKind;
use super::traverse::{for_each_row_in_cell, CutoffTest};
use crate::memory::large_vec;
use crate::threads::{concat_in_order, Threads};
use rayon::prelude::*;

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
    let rows = |range: std::ops::Range<usize>, out: &mut Vec<T>| {
        for home in range {
            for_each_row_in_cell(cells, home, StencilKind::Half, &test, |i, j, _, _, r2| {
                let (a, b) = (order[i], order[j]);
                out.push(make(a.min(b), a.max(b), r2));
            });
        }
    };
    let num_cells = cells.grid().num_cells();
    let guess = expected_pairs(cells, cutoff);
    if threads.count() == 1 {
        // one thread: append in cell order straight into the result, no copy
        let mut out = large_vec(guess);
        rows(0..num_cells, &mut out);
        return out;
    }
    threads.install(|| {
        let parts: Vec<Vec<T>> = Threads::chunks(num_cells)
            .map(|range| {
                let slots =
                    cells.cell_range(range.start).start..cells.cell_range(range.end - 1).end;
                let mut out = Vec::with_capacity(guess * slots.len() / cells.len().max(1));
                rows(range, &mut out);
                out
            })
            .collect();
        concat_in_order(parts)
    })
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
