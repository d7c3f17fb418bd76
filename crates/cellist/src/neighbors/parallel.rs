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
use std::ops::Range;

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

/// The layers of a cell list along its last axis (z in 3D, y in 2D) and their
/// colours, for Newton's-third-law sums over a half Verlet list in parallel.
///
/// Cells are numbered with the last axis slowest, so layer `z` is one contiguous
/// range of slots. The half stencil reaches only the last-axis offsets 0 and +1, so
/// the rows of layer `z` write only to layers `z` and `z + 1` (mod `M` on a
/// periodic axis). Layers of one colour are never adjacent: colour `z mod 2`, and on
/// a periodic axis with an odd `M >= 3` the last layer gets a colour of its own.
/// One colour's layers therefore write disjoint slots and run in parallel; colours
/// run one after another. Which layers exist and their colours depend only on the
/// grid, never on the thread count, so every sum runs in a fixed order.
#[derive(Clone, Debug, Default)]
pub struct LayerPlan {
    bounds: Vec<usize>,
    colours: Vec<Vec<usize>>,
    wraps: bool,
}

impl LayerPlan {
    /// The layers of `cells` (recompute with [`LayerPlan::update`] after a rebin).
    pub fn new<const D: usize>(cells: &CellList<D>) -> Self {
        let layers = cells.grid().dims()[D - 1];
        let wraps = cells.domain().is_periodic(D - 1) && layers > 1;
        let num_colours = match layers {
            1 => 1,
            m if wraps && m % 2 == 1 => 3,
            _ => 2,
        };
        let mut colours = vec![Vec::new(); num_colours];
        for z in 0..layers {
            let colour = if num_colours == 3 && z == layers - 1 {
                2
            } else {
                z % 2
            };
            colours[colour].push(z);
        }
        let mut plan = LayerPlan {
            bounds: Vec::with_capacity(layers + 1),
            colours,
            wraps,
        };
        plan.update(cells);
        plan
    }

    /// Re-reads the layer bounds from `cells` after a rebin on the same grid.
    pub fn update<const D: usize>(&mut self, cells: &CellList<D>) {
        let dims = cells.grid().dims();
        let per_layer: usize = dims[..D - 1].iter().product();
        let start = cells.cell_start();
        self.bounds.clear();
        self.bounds
            .extend((0..=dims[D - 1]).map(|z| start[z * per_layer] as usize));
    }

    /// Number of layers.
    pub fn num_layers(&self) -> usize {
        self.bounds.len() - 1
    }

    /// Slots of layer `z`.
    pub fn rows(&self, z: usize) -> Range<usize> {
        self.bounds[z]..self.bounds[z + 1]
    }

    /// Slots the rows of layer `z` may write, layer `z` and the layer after it, as
    /// `(first, count)` of a cyclic interval of the `n` slots.
    fn reach(&self, z: usize) -> (usize, usize) {
        let n = *self.bounds.last().expect("bounds has layers + 1 entries");
        let first = self.bounds[z];
        let next = if z + 1 < self.num_layers() {
            self.rows(z + 1).len()
        } else if self.wraps {
            self.rows(0).len()
        } else {
            0
        };
        (first, (self.bounds[z + 1] - first + next).min(n))
    }
}

/// Write access to the forces of the slots one layer may reach (see [`LayerPlan`]):
/// the cyclic interval of `count` slots from `first`.
pub struct LayerForces<'s, 'a, const D: usize> {
    shared: &'s DisjointSlice<'a, [f64; D]>,
    first: usize,
    count: usize,
    n: usize,
}

impl<const D: usize> LayerForces<'_, '_, D> {
    /// `f[k] += delta`.
    #[inline(always)]
    pub fn add(&self, k: usize, delta: &[f64; D]) {
        // offset of k in the cyclic interval: one compare, one select
        let offset = if k >= self.first {
            k - self.first
        } else {
            k + self.n - self.first
        };
        assert!(
            offset < self.count && k < self.n,
            "slot {k} outside the layer's reach: not a half list of this cell list"
        );
        // SAFETY: k lies in this layer or the next (checked above); no other task of
        // this colour reaches them (LayerPlan), and the reference lives only here.
        let f = unsafe { self.shared.get_unchecked(k) };
        for a in 0..D {
            f[a] += delta[a];
        }
    }

    /// `f[k] -= delta`.
    #[inline(always)]
    pub fn sub(&self, k: usize, delta: &[f64; D]) {
        let minus: [f64; D] = std::array::from_fn(|a| -delta[a]);
        self.add(k, &minus);
    }
}

/// Runs `work(rows, forces, tally)` once per layer of `plan`, layers of one colour
/// in parallel and colours in order: the parallel form of a Newton's-third-law sum
/// over the rows of a half Verlet list built on the cell list of `plan`.
/// `tallies[z]` is layer `z`'s own accumulator (energies, virials), to be reduced in
/// layer order by the caller.
pub fn scatter_half_rows<const D: usize, T: Send>(
    plan: &LayerPlan,
    forces: &mut [[f64; D]],
    tallies: &mut [T],
    threads: &Threads,
    work: impl Fn(Range<usize>, &LayerForces<D>, &mut T) + Sync,
) {
    assert_eq!(tallies.len(), plan.num_layers());
    assert_eq!(forces.len(), plan.bounds.last().copied().unwrap_or(0));
    let n = forces.len();
    let shared = DisjointSlice::new(forces);
    let tallies = DisjointSlice::new(tallies);
    threads.install(|| {
        for layers in &plan.colours {
            layers.par_iter().for_each(|&z| {
                let (first, count) = plan.reach(z);
                let access = LayerForces {
                    shared: &shared,
                    first,
                    count,
                    n,
                };
                // SAFETY: each layer appears in exactly one colour, once.
                let tally = unsafe { tallies.get(z) };
                work(plan.rows(z), &access, tally);
            });
        }
    });
}
