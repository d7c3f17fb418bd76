//! Race-free parallel pair sums over a cell list or a Verlet list.
//!
//! Two strategies, both without atomics or locks, both giving the same bits for any
//! thread count because every particle's sum runs in an order fixed by the data:
//! - gather: each particle sums over its full neighbourhood and writes only itself
//!   (every pair is evaluated twice);
//! - coloured passes: anchor cells are split into colours such that the blocks
//!   `anchor + {0, 1}^D` of one colour are disjoint; each pass runs one colour in
//!   parallel, each pair once, updating both particles (Newton's third law).

use super::cell_list::CellList;
use super::grid::StencilKind;
use super::traverse::{for_each_anchored_pair, for_each_row_in_cell, CutoffTest};
use super::verlet::VerletList;
use crate::threads::{DisjointSlice, Threads};
use rayon::prelude::*;

/// One pair interaction, applied inside a generic (monomorphised) loop.
///
/// `i` and `j` are sorted slots, `d = x_j - x_i` is the minimum-image separation and
/// `r2 = |d|^2` is below the cutoff of the traversal.
pub trait PairKernel<const D: usize>: Sync {
    /// The per-particle sum (a force, a rate, ...).
    type Acc: Send;

    /// Adds the effect of `j` on `i` to `acc_i`.
    fn gather(&self, i: usize, j: usize, d: &[f64; D], r2: f64, acc_i: &mut Self::Acc);

    /// Adds the effect of the pair to both particles from one evaluation.
    fn scatter(
        &self,
        i: usize,
        j: usize,
        d: &[f64; D],
        r2: f64,
        acc_i: &mut Self::Acc,
        acc_j: &mut Self::Acc,
    );
}

/// Gather over the cell list: `acc[i] += sum_{j in full stencil, r_ij < cutoff} k(i, j)`,
/// neighbours in stencil order. `acc` is in slot order.
pub fn gather_cells<const D: usize, K: PairKernel<D>>(
    cells: &CellList<D>,
    cutoff: f64,
    kernel: &K,
    acc: &mut [K::Acc],
    threads: &Threads,
) {
    assert_eq!(acc.len(), cells.len());
    assert!(cutoff <= cells.cutoff());
    let test = CutoffTest::new(cutoff);
    // split acc at cell-chunk boundaries: each task owns a contiguous run of slots
    let mut tasks = Vec::new();
    let mut rest = acc;
    let mut offset = 0;
    for range in threads.install(|| Threads::chunks(cells.grid().num_cells()).collect::<Vec<_>>()) {
        let end = cells.cell_range(range.end - 1).end;
        let (head, tail) = rest.split_at_mut(end - offset);
        tasks.push((range, offset, head));
        rest = tail;
        offset = end;
    }
    threads.install(|| {
        tasks.into_par_iter().for_each(|(range, first, own)| {
            for home in range {
                for_each_row_in_cell(cells, home, StencilKind::Full, &test, |i, j, _, d, r2| {
                    kernel.gather(i, j, d, r2, &mut own[i - first]);
                });
            }
        })
    });
}

/// Coloured passes over the cell list: every pair within the cutoff once,
/// `k.scatter(i, j)`, anchors of one colour in parallel, colours in order.
pub fn scatter_coloured<const D: usize, K: PairKernel<D>>(
    cells: &CellList<D>,
    cutoff: f64,
    kernel: &K,
    acc: &mut [K::Acc],
    threads: &Threads,
) {
    assert_eq!(acc.len(), cells.len());
    assert!(cutoff <= cells.cutoff());
    let test = CutoffTest::new(cutoff);
    let shared = DisjointSlice::new(acc);
    threads.install(|| {
        for anchors in cells.anchors_by_colour() {
            anchors.par_iter().with_min_len(16).for_each(|&h| {
                for_each_anchored_pair(cells, h as usize, &test, |i, j, d, r2| {
                    if i == j {
                        return; // an image of i itself: impossible while r_c <= L/2
                    }
                    // SAFETY: slots i != j lie in the block of anchor h; blocks of
                    // anchors of one colour are disjoint (CellGrid::colour_of), so no
                    // other task of this pass touches them.
                    let (ai, aj) = unsafe { (shared.get(i), shared.get(j)) };
                    kernel.scatter(i, j, d, r2, ai, aj);
                });
            });
        }
    });
}

/// Gather over a full Verlet list at the current `positions` (slot order):
/// `acc[i] += sum_{j in row i, r_ij < cutoff} k(i, j)`, rows in parallel.
pub fn gather_verlet<const D: usize, K: PairKernel<D>>(
    list: &VerletList<D>,
    positions: &[[f64; D]],
    kernel: &K,
    acc: &mut [K::Acc],
    threads: &Threads,
) {
    assert_eq!(list.kind(), StencilKind::Full, "gather needs a full list");
    assert_eq!(acc.len(), list.len());
    threads.install(|| {
        acc.par_iter_mut()
            .with_min_len(256)
            .enumerate()
            .for_each(|(i, acc_i)| {
                list.for_each_in_row(i, positions, |j, d, r2| kernel.gather(i, j, d, r2, acc_i));
            })
    });
}

/// Scatter over a half Verlet list on one thread: every listed pair within the
/// cutoff once, rows in slot order.
pub fn scatter_verlet_serial<const D: usize, K: PairKernel<D>>(
    list: &VerletList<D>,
    positions: &[[f64; D]],
    kernel: &K,
    acc: &mut [K::Acc],
) {
    assert_eq!(list.kind(), StencilKind::Half, "scatter needs a half list");
    assert_eq!(acc.len(), list.len());
    for i in 0..list.len() {
        list.for_each_in_row(i, positions, |j, d, r2| {
            if i == j {
                return;
            }
            let (lo, hi) = acc.split_at_mut(i.max(j));
            let (ai, aj) = if i < j {
                (&mut lo[i], &mut hi[0])
            } else {
                (&mut hi[0], &mut lo[j])
            };
            kernel.scatter(i, j, d, r2, ai, aj);
        });
    }
}
