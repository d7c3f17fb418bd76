//! The half list of pairs within a cutoff, in input numbering: what `vesin`'s
//! `compute(quantities="ij")` returns and what `cellist neighbors` prints.

use super::cell_list::CellList;
use super::grid::StencilKind;
use super::traverse::{for_each_row_in_cell, CutoffTest};
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
    threads.install(|| {
        let parts: Vec<Vec<T>> = Threads::chunks(cells.grid().num_cells())
            .map(|range| {
                let mut out = Vec::new();
                for home in range {
                    for_each_row_in_cell(
                        cells,
                        home,
                        StencilKind::Half,
                        &test,
                        |i, j, _, _, r2| {
                            let (a, b) = (order[i], order[j]);
                            out.push(make(a.min(b), a.max(b), r2));
                        },
                    );
                }
                out
            })
            .collect();
        concat_in_order(parts)
    })
}
