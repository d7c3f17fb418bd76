//! Race-free parallel pair sums over a cell list or a Verlet list.
//!
//! Two strategies, both without atomics or locks, both giving the same bits for any
//! thread count because every particle's sum runs in an order fixed by the data:
//! - gather: each particle sums over its full neighbourhood and writes only itself
//!   (every pair is evaluated twice);
//! - coloured passes: anchor cells are split into colours such that the blocks
//!   `anchor + {0, 1}^D` of one colour are disjoint; each pass runs one colour in
//!   parallel, each pair once, updating both particles (Newton's third law);
//! - layers with a halo (over half-list rows, Verlet or cluster): every cell
//!   layer runs at once,
//!   writing its own particles directly and the next layer's into a halo buffer
//!   that only it writes, added afterwards (Newton's third law, one pass); one
//!   layer of an odd few may run as two tasks, the second with sums of its own
//!   ([`LayerPlan`]); processes that hold the same particles may share the
//!   tasks, each running a run of them and gathering the slots the others
//!   wrote before the halo is added ([`scatter_half_rows_shared`]).

use super::cell_list::CellList;
use super::clusters::CLUSTER;
use super::grid::StencilKind;
use super::traverse::{for_each_anchored_pair, for_each_row_in_cell, CutoffTest};
use super::verlet::VerletList;
use crate::simd::F64x4;
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

/// The cell layers along the last axis (z in 3D, y in 2D), for Newton's-third-law
/// sums over half-list rows (Verlet rows of slots, or cluster rows) in parallel.
///
/// Cells are numbered with the last axis slowest, so a layer of cells is one
/// contiguous range of slots. The half stencil reaches only the last-axis offsets 0
/// and +1, so the rows of layer `z` write only to layer `z` and to the next one
/// (cyclically on a periodic axis). All layers run at once: layer `z` adds to the
/// forces of its own slots directly and to those of layer `z + 1` in a separate
/// halo buffer, each slot of which only layer `z` writes; the halo is then added to
/// the forces, `f_j = (own rows' sum) + (previous layer's sum)`. Layers depend only
/// on the grid, never on the thread count, so every sum runs in a fixed order.
///
/// An odd number of layers, fewer than 16 (`CUT_BELOW`), would give two threads
/// uneven shares (nine layers: five against four), so there the middle layer's
/// rows are cut into two tasks: the first half of the tasks then holds as many
/// layers as the second (four and a half of nine; rayon's first split of the
/// tasks is into halves). The second part of the cut layer writes its sums of
/// its layer's slots and of the next layer's into an array of its own, added
/// after the first part's: `f = own_0 + own_1 + halo_0 + halo_1`. Whether a
/// layer is cut depends on the grid alone.
#[derive(Clone, Debug, Default)]
pub struct LayerPlan {
    bounds: Vec<usize>,
    wraps: bool,
    cut: Option<usize>,
}

/// The number of layers from which a [`LayerPlan`] no longer cuts one: with
/// this many, one layer more on one of two threads costs at most `1 /
/// CUT_BELOW` of the pass.
const CUT_BELOW: usize = 16;

impl LayerPlan {
    /// The layers of `cells` as binned now (make a new plan after every rebin).
    pub fn new<const D: usize>(cells: &CellList<D>) -> Self {
        Self::over(cells, cells.cell_start())
    }

    /// The layers of `cells` counted in units other than slots: `starts[c]` is
    /// the first unit of cell `c` (`num_cells + 1` entries, ascending), such as
    /// the clusters of a [`ClusterList`](super::ClusterList).
    pub fn over<const D: usize>(cells: &CellList<D>, starts: &[u32]) -> Self {
        let dims = cells.grid().dims();
        let layers = dims[D - 1];
        let per_layer: usize = dims[..D - 1].iter().product();
        assert_eq!(starts.len(), layers * per_layer + 1);
        let bounds: Vec<usize> = (0..=layers)
            .map(|z| starts[z * per_layer] as usize)
            .collect();
        LayerPlan {
            bounds,
            // a single periodic layer wraps onto itself: its writes are all its own
            wraps: cells.domain().is_periodic(D - 1) && layers > 1,
            cut: (layers % 2 == 1 && layers < CUT_BELOW).then_some(layers / 2),
        }
    }

    /// Number of layers.
    pub fn num_layers(&self) -> usize {
        self.bounds.len() - 1
    }

    /// Number of tasks: one per layer, and one more where a layer is cut.
    pub fn num_tasks(&self) -> usize {
        self.num_layers() + usize::from(self.cut.is_some())
    }

    /// The layer of task `t`, and whether `t` is the second part of the cut
    /// layer (tasks in layer order, the cut layer's two parts one after the
    /// other).
    fn task(&self, t: usize) -> (usize, bool) {
        match self.cut {
            Some(m) if t > m => (t - 1, t == m + 1),
            _ => (t, false),
        }
    }

    /// The rows of task `t`: its layer's, or half of them where the layer is cut.
    pub fn task_rows(&self, t: usize) -> Range<usize> {
        let (z, second) = self.task(t);
        let rows = self.rows(z);
        if self.cut != Some(z) {
            return rows;
        }
        let middle = rows.start + rows.len() / 2;
        if second {
            middle..rows.end
        } else {
            rows.start..middle
        }
    }

    /// The tasks cut into `ranks` runs in task order (for
    /// [`scatter_half_rows_shared`]), each starting at the first task whose
    /// rows start at or past its share `rows r / ranks` of the rows (a run
    /// may be empty).
    pub fn task_runs(&self, ranks: usize) -> Vec<Range<usize>> {
        self.task_runs_weighted(ranks, |_| 1)
    }

    /// [`task_runs`](Self::task_runs) with row `i` weighing `weight(i)`:
    /// each run starts at the first task whose rows start at or past its
    /// share `W r / ranks` of the total weight `W`.
    pub fn task_runs_weighted(
        &self,
        ranks: usize,
        weight: impl Fn(usize) -> usize,
    ) -> Vec<Range<usize>> {
        let tasks = self.num_tasks();
        // the weight of the rows before each task's, and of all
        let mut before = Vec::with_capacity(tasks + 1);
        let mut sum = 0;
        for t in 0..tasks {
            before.push(sum);
            sum += self.task_rows(t).map(&weight).sum::<usize>();
        }
        let cuts: Vec<usize> = (0..=ranks)
            .map(|r| match r {
                0 => 0,
                r if r == ranks => tasks,
                r => (0..tasks)
                    .find(|&t| before[t] * ranks >= sum * r)
                    .unwrap_or(tasks),
            })
            .collect();
        cuts.windows(2).map(|w| w[0]..w[1]).collect()
    }

    /// The rows (slots, or the units of [`LayerPlan::over`]) of layer `z`.
    pub fn rows(&self, z: usize) -> Range<usize> {
        self.bounds[z]..self.bounds[z + 1]
    }

    /// Slots the rows of layer `z` may write: `(first, own, count)`, the cyclic
    /// interval of `count` slots from `first`, of which the first `own` are layer
    /// `z`'s and the rest the next layer's.
    fn reach(&self, z: usize) -> (usize, usize, usize) {
        let first = self.bounds[z];
        let own = self.bounds[z + 1] - first;
        let next = if z + 1 < self.num_layers() {
            self.rows(z + 1).len()
        } else if self.wraps {
            self.rows(0).len()
        } else {
            0
        };
        (first, own, own + next)
    }

    /// The two runs of slots in the reach of layer `z` ([`LayerPlan::reach`]):
    /// its own, and the next layer's (those after its own, or the first
    /// layer's when `z` is the last and wraps; empty for the last layer of an
    /// open axis and for a single layer).
    fn reach_runs(&self, z: usize) -> (Range<usize>, Range<usize>) {
        let (first, own, count) = self.reach(z);
        let end = first + own;
        let next = if end == self.bounds[self.num_layers()] {
            0
        } else {
            end
        };
        (first..end, next..next + count - own)
    }
}

/// A per-particle sum that a layer scatter accumulates: a force vector `[f64; D]`,
/// a scalar rate `f64`.
pub trait Summand: Copy + Send + Sync {
    /// The empty sum.
    const ZERO: Self;

    /// `self += delta`, component by component.
    fn add_assign(&mut self, delta: &Self);

    /// `-self`.
    fn negated(&self) -> Self;
}

impl Summand for f64 {
    const ZERO: Self = 0.0;

    #[inline(always)]
    fn add_assign(&mut self, delta: &Self) {
        *self += delta;
    }

    #[inline(always)]
    fn negated(&self) -> Self {
        -self
    }
}

impl<const D: usize> Summand for [f64; D] {
    const ZERO: Self = [0.0; D];

    #[inline(always)]
    fn add_assign(&mut self, delta: &Self) {
        for a in 0..D {
            self[a] += delta[a];
        }
    }

    #[inline(always)]
    fn negated(&self) -> Self {
        std::array::from_fn(|a| -self[a])
    }
}

impl<const D: usize> Summand for [[f64; CLUSTER]; D] {
    const ZERO: Self = [[0.0; CLUSTER]; D];

    #[inline(always)]
    fn add_assign(&mut self, delta: &Self) {
        for (lanes, delta) in self.iter_mut().zip(delta) {
            (F64x4::load(lanes) + F64x4::load(delta)).store(lanes);
        }
    }

    #[inline(always)]
    fn negated(&self) -> Self {
        self.map(|lanes| lanes.map(|v| -v))
    }
}

/// Write access to the sums of the slots one task's layer may reach (see
/// [`LayerPlan`]): the cyclic interval of `count` slots from `first`, the first
/// `own` of them in the sums and the rest in the halo (for the second task of a
/// cut layer, both in its own array).
pub struct LayerForces<'s, 'a, V> {
    // the two slices' base pointers, taken once: a write picks one by a select
    forces: *mut V,
    halo: *mut V,
    _slices: std::marker::PhantomData<&'s DisjointSlice<'a, V>>,
    first: usize,
    own: usize,
    count: usize,
    n: usize,
    // not Sync: the task that owns the access is the only thread that may write
    _one_thread: std::marker::PhantomData<std::cell::Cell<()>>,
}

impl<V: Summand> LayerForces<'_, '_, V> {
    /// `f[k] += delta`.
    #[inline(always)]
    pub fn add(&self, k: usize, delta: &V) {
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
        let target = if offset < self.own {
            self.forces
        } else {
            self.halo
        };
        // SAFETY: both slices have n elements and k < n, checked above; k lies in
        // this layer (forces) or the next (halo), whose elements no other task
        // writes (LayerPlan), and the reference lives only here.
        let f = unsafe { &mut *target.add(k) };
        f.add_assign(delta);
    }

    /// `f[k] -= delta`.
    #[inline(always)]
    pub fn sub(&self, k: usize, delta: &V) {
        self.add(k, &delta.negated());
    }
}

/// Sets `forces` to the sums of `work(rows, forces, tally)` run once per task of
/// `plan` (a layer, or half of a cut one), all tasks in parallel, then adds the
/// halo to the sums (`forces`: vectors, scalars, any [`Summand`]): the parallel
/// form of a Newton's-third-law sum over the rows of a half list (Verlet or
/// cluster rows) built on the cell list of `plan`. `forces` need not be
/// zeroed: each task zeroes the slots it sums before its rows run, so no pass
/// over all the slots runs on one thread. `scratch` holds the halo, and after
/// it the cut layer's second array (resized here; on an open axis the first
/// layer's part of the halo is never written nor read). `tallies[t]` is task
/// `t`'s own accumulator (energies, virials), to be reduced in task order by
/// the caller.
pub fn scatter_half_rows<V: Summand, T: Send>(
    plan: &LayerPlan,
    forces: &mut [V],
    scratch: &mut Vec<V>,
    tallies: &mut [T],
    threads: &Threads,
    work: impl Fn(Range<usize>, &LayerForces<V>, &mut T) + Sync,
) {
    assert_eq!(tallies.len(), plan.num_tasks());
    let n = forces.len();
    assert_eq!(n, plan.bounds.last().copied().unwrap_or(0));
    let (halo, cut) = halo_and_cut(plan, scratch, n);
    threads.install(|| {
        run_layer_tasks(plan, 0..plan.num_tasks(), forces, halo, cut, tallies, &work);
        add_halo(plan, forces, halo, cut);
    });
}

/// [`scatter_half_rows`] on one of several ranks that hold the same particles
/// (and so the same `plan`): this rank runs only the tasks `parts[rank]`
/// (`parts`: every rank's run of the tasks, in task order, together all of
/// them), and `tallies` gets only theirs; `gather(mine, counts, all)` must
/// put every rank's `mine` into `all` in rank order (`counts[r]` values from
/// rank `r`): the sums of the slots each task wrote. Every rank then adds the
/// halo as one process does, so `forces` gets the bits of
/// [`scatter_half_rows`] on every rank.
#[allow(clippy::too_many_arguments)]
pub fn scatter_half_rows_shared<V: Summand, T: Send>(
    plan: &LayerPlan,
    (parts, rank): (&[Range<usize>], usize),
    forces: &mut [V],
    scratch: &mut Vec<V>,
    tallies: &mut [T],
    threads: &Threads,
    gather: impl FnOnce(&[V], &[usize], &mut [V]),
    work: impl Fn(Range<usize>, &LayerForces<V>, &mut T) + Sync,
) {
    assert_eq!(tallies.len(), plan.num_tasks());
    let n = forces.len();
    assert_eq!(n, plan.bounds.last().copied().unwrap_or(0));
    let (halo, cut) = halo_and_cut(plan, scratch, n);
    threads
        .install(|| run_layer_tasks(plan, parts[rank].clone(), forces, halo, cut, tallies, &work));
    // the slots each task wrote: its layer's sums, then its halo of the next
    let written = |t: usize| {
        let (z, second) = plan.task(t);
        let (own, next) = plan.reach_runs(z);
        (own, next, second)
    };
    let counts: Vec<usize> = parts
        .iter()
        .map(|p| {
            p.clone()
                .map(|t| {
                    let (own, next, _) = written(t);
                    own.len() + next.len()
                })
                .sum()
        })
        .collect();
    let mut mine = Vec::with_capacity(counts[rank]);
    for t in parts[rank].clone() {
        let (own, next, second) = written(t);
        let (sums, halo) = if second {
            (&*cut, &*cut)
        } else {
            (&*forces, &*halo)
        };
        mine.extend_from_slice(&sums[own]);
        mine.extend_from_slice(&halo[next]);
    }
    let mut all = vec![V::ZERO; counts.iter().sum()];
    gather(&mine, &counts, &mut all);
    let mut values = all.into_iter();
    let mut fill = |slots: &mut [V]| {
        for (slot, v) in slots.iter_mut().zip(&mut values) {
            *slot = v;
        }
    };
    for t in parts.iter().flat_map(|p| p.clone()) {
        let (own, next, second) = written(t);
        if second {
            fill(&mut cut[own]);
            fill(&mut cut[next]);
        } else {
            fill(&mut forces[own]);
            fill(&mut halo[next]);
        }
    }
    debug_assert!(values.next().is_none(), "every gathered value has its slot");
    threads.install(|| add_halo(plan, forces, halo, cut));
}

/// The halo (`n` slots) and the cut layer's array (`n` more if a layer is
/// cut) in `scratch`, resized when the slots changed.
fn halo_and_cut<'a, V: Summand>(
    plan: &LayerPlan,
    scratch: &'a mut Vec<V>,
    n: usize,
) -> (&'a mut [V], &'a mut [V]) {
    // the cut layer's second part sums into an array of its own
    let extra = if plan.cut.is_some() { n } else { 0 };
    if scratch.len() != n + extra {
        scratch.clear();
        scratch.resize(n + extra, V::ZERO);
    }
    scratch.split_at_mut(n)
}

/// Runs `work` for the tasks `tasks` of `plan` in parallel (on the current
/// pool), each on its layer's slots of `forces` and the next layer's of
/// `halo` (or both in `cut`, for the cut layer's second part), which it zeroes
/// first.
#[inline(always)]
fn run_layer_tasks<V: Summand, T: Send>(
    plan: &LayerPlan,
    tasks: Range<usize>,
    forces: &mut [V],
    halo: &mut [V],
    cut: &mut [V],
    tallies: &mut [T],
    work: &(impl Fn(Range<usize>, &LayerForces<V>, &mut T) + Sync),
) {
    let n = forces.len();
    let shared = DisjointSlice::new(forces);
    let shared_halo = DisjointSlice::new(halo);
    let tallies = DisjointSlice::new(tallies);
    let cut = DisjointSlice::new(cut);
    tasks.into_par_iter().for_each(|t| {
        let (z, second) = plan.task(t);
        let (first, own, count) = plan.reach(z);
        let (own_slots, next_slots) = plan.reach_runs(z);
        // the layers' own ranges are disjoint, and so are their next-layer
        // ranges (each layer is the next of one layer at most); the two
        // ranges of a layer lie apart but for a single layer, whose next
        // range is empty
        let (forces, halo) = match second {
            false => (&shared, &shared_halo),
            true => (&cut, &cut),
        };
        // SAFETY: by the above, layer z's first task is the only one to
        // touch either of its ranges in the sums and the halo, and its
        // second task (of the cut layer) the only one to touch the
        // cut layer's array
        unsafe {
            forces.range(own_slots).fill(V::ZERO);
            halo.range(next_slots).fill(V::ZERO);
        }
        let access = LayerForces {
            forces: forces.base(),
            halo: halo.base(),
            _slices: std::marker::PhantomData,
            first,
            own,
            count,
            n,
            _one_thread: std::marker::PhantomData,
        };
        // SAFETY: each task index is visited once.
        let tally = unsafe { tallies.get(t) };
        work(plan.task_rows(t), &access, tally);
    });
}

/// Adds the halo of [`run_layer_tasks`] to the sums, slot by slot: `own_0 +
/// own_1`, then `+ halo_0 + halo_1`; the cut layer's own slots and its next
/// layer's (on the current pool).
fn add_halo<V: Summand>(plan: &LayerPlan, forces: &mut [V], halo: &[V], cut: &[V]) {
    let cut_slots = plan.cut.map(|m| plan.reach_runs(m));
    if let Some((own, _)) = &cut_slots {
        add_in_chunks(&mut forces[own.clone()], &cut[own.clone()]);
    }
    // the halo of every layer but the first, and of the first when the last
    // layer wraps onto it: the slots some layer's task zeroed and wrote
    let start = if plan.wraps { 0 } else { plan.rows(0).end };
    add_in_chunks(&mut forces[start..], &halo[start..]);
    if let Some((_, next)) = cut_slots {
        add_in_chunks(&mut forces[next.clone()], &cut[next]);
    }
}

/// `sums[k] += deltas[k]` for every `k`, in chunks on the current pool. Kept
/// out of line: inlined into `scatter_half_rows` three times, it changed how the
/// layer tasks around the force kernel were compiled, and the one-thread melt
/// ran 2-3% slower.
#[inline(never)]
fn add_in_chunks<V: Summand>(sums: &mut [V], deltas: &[V]) {
    sums.par_chunks_mut(HALO_CHUNK)
        .zip(deltas.par_chunks(HALO_CHUNK))
        .for_each(|(sums, deltas)| {
            for (f, h) in sums.iter_mut().zip(deltas) {
                f.add_assign(h);
            }
        });
}

/// Slots per task when the halo is added to the forces.
const HALO_CHUNK: usize = 4096;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{Boundary, Domain};
    use crate::longrange::mesh::slab::testkit::Hub;
    use crate::longrange::mesh::slab::Exchange;

    fn plan_for(layers: usize, periodic: bool) -> LayerPlan {
        let boundary = if periodic {
            Boundary::Periodic
        } else {
            Boundary::Open
        };
        let domain = Domain::new([4.0, layers as f64], [Boundary::Periodic, boundary]).unwrap();
        let points: Vec<[f64; 2]> = (0..4 * layers)
            .map(|k| [(k % 4) as f64 + 0.5, (k / 4) as f64 + 0.5])
            .collect();
        let cells = CellList::build(&domain, 0.99, &points).unwrap();
        assert_eq!(cells.grid().dims()[1], layers);
        LayerPlan::new(&cells)
    }

    #[test]
    fn every_slot_has_one_direct_writer_and_at_most_one_halo_writer() {
        for layers in 1..=9 {
            // one periodic layer would be narrower than twice the cutoff
            for periodic in [layers > 1, false] {
                let plan = plan_for(layers, periodic);
                assert_eq!(plan.num_layers(), layers);
                let n = 4 * layers;
                let mut direct = vec![0; n];
                let mut halo = vec![0; n];
                for z in 0..plan.num_layers() {
                    let (first, own, count) = plan.reach(z);
                    assert_eq!(plan.rows(z), first..first + own);
                    for k in 0..count {
                        let slot = (first + k) % n;
                        if k < own {
                            direct[slot] += 1;
                        } else {
                            halo[slot] += 1;
                        }
                    }
                }
                assert!(direct.iter().all(|&c| c == 1), "{layers} {periodic}");
                assert!(halo.iter().all(|&c| c <= 1), "{layers} {periodic}");
            }
        }
    }

    #[test]
    fn weighted_runs_share_out_the_weight() {
        // equal weights: each run starts at the first task whose rows start
        // at or past its share of the rows; 9 layers cut the middle one
        for layers in [8, 9] {
            let plan = plan_for(layers, true);
            let (rows, tasks) = (4 * layers, plan.num_tasks());
            for ranks in 1..=5 {
                let starts: Vec<usize> = (0..=ranks)
                    .map(|r| {
                        (0..tasks)
                            .find(|&t| plan.task_rows(t).start * ranks >= rows * r)
                            .unwrap_or(tasks)
                    })
                    .collect();
                let runs: Vec<Range<usize>> = starts.windows(2).map(|w| w[0]..w[1]).collect();
                assert_eq!(
                    plan.task_runs_weighted(ranks, |_| 7),
                    runs,
                    "{layers} {ranks}"
                );
                assert_eq!(plan.task_runs(ranks), runs);
            }
        }
        // 8 layers of 4 rows
        let plan = plan_for(8, true);
        assert_eq!(plan.num_tasks(), 8);
        // the first layer's rows weigh as much as all the others: it is one
        // rank's run, the other layers the other's
        let heavy = |i: usize| if i < 4 { 7 } else { 1 };
        assert_eq!(plan.task_runs_weighted(2, heavy), vec![0..1, 1..8]);
        // the last layer's rows weigh as much as the others: two runs, the
        // second holding only the last layer
        let heavy_last = |i: usize| if i >= 28 { 7 } else { 1 };
        assert_eq!(plan.task_runs_weighted(2, heavy_last), vec![0..7, 7..8]);
        // more ranks than tasks: empty runs, every task in one
        let runs = plan.task_runs_weighted(11, heavy);
        assert_eq!(runs.len(), 11);
        assert_eq!(runs.iter().map(|r| r.len()).sum::<usize>(), 8);
        assert!(runs.windows(2).all(|w| w[0].end == w[1].start));
    }

    #[test]
    fn an_odd_number_of_few_layers_cuts_the_middle_one_in_two() {
        for layers in 1..=2 * CUT_BELOW {
            let plan = plan_for(layers, layers > 1);
            let cut = layers % 2 == 1 && layers < CUT_BELOW;
            let tasks = plan.num_tasks();
            assert_eq!(tasks, layers + usize::from(cut), "{layers}");
            // the tasks run through the rows in order, each within one layer
            let runs: Vec<Range<usize>> = (0..tasks).map(|t| plan.task_rows(t)).collect();
            assert_eq!(runs[0].start, 0);
            assert_eq!(runs[tasks - 1].end, plan.rows(layers - 1).end);
            assert!(runs.windows(2).all(|w| w[0].end == w[1].start));
            let layer_of = |t: usize| plan.task(t).0;
            assert!((0..tasks).all(|t| {
                let rows = plan.rows(layer_of(t));
                rows.start <= runs[t].start && runs[t].end <= rows.end
            }));
            // the first half of the tasks holds half of the rows (four per layer)
            let first_half: usize = runs[..tasks / 2].iter().map(|r| r.len()).sum();
            if cut || layers % 2 == 0 {
                assert_eq!(first_half, 2 * layers, "{layers} layers");
            }
        }
    }

    #[test]
    fn the_sums_are_set_on_layers_of_any_size() {
        // layers of 3, 0, 5, 2 and 4 slots, periodic and open, two layers, and more
        let cases = [
            (vec![3, 0, 5, 2, 4], true),
            (vec![3, 0, 5, 2, 4], false),
            (vec![1, 3], true),
            // three layers (the middle one cut): its halves of 1 and 2 rows,
            // an empty first half, an empty cut layer, a cut layer whose next
            // layer is empty (and ends the slots); and a single layer, cut
            (vec![2, 3, 1], true),
            (vec![2, 3, 1], false),
            (vec![2, 1, 3], true),
            (vec![2, 0, 3], true),
            (vec![2, 3, 0], true),
            (vec![3], false),
        ];
        for (counts, periodic) in cases {
            let layers = counts.len();
            let boundary = if periodic {
                Boundary::Periodic
            } else {
                Boundary::Open
            };
            let domain = Domain::new([4.0, layers as f64], [Boundary::Periodic, boundary]).unwrap();
            let points: Vec<[f64; 2]> = counts
                .iter()
                .enumerate()
                .flat_map(|(z, &c)| (0..c).map(move |k| [k as f64 % 4.0 + 0.5, z as f64 + 0.5]))
                .collect();
            let cells = CellList::build(&domain, 0.99, &points).unwrap();
            assert_eq!(cells.grid().dims()[1], layers);
            let plan = LayerPlan::new(&cells);
            let n = points.len();
            // every row adds (1, 0) to itself and (0, -1) to the first slot of
            // the next layer, when there is one and it is not empty
            let next_first = |z: usize| {
                let next = if z + 1 < layers {
                    Some(z + 1)
                } else if periodic {
                    Some(0)
                } else {
                    None
                };
                next.map(|y| plan.rows(y))
                    .filter(|r| !r.is_empty())
                    .map(|r| r.start)
            };
            let mut expected = vec![[1.0, 0.0]; n];
            for z in 0..layers {
                if let Some(target) = next_first(z) {
                    expected[target][1] -= plan.rows(z).len() as f64;
                }
            }
            let work = |rows: Range<usize>, f: &LayerForces<[f64; 2]>, seen: &mut usize| {
                // (an empty task's layer does not matter)
                let z = (0..layers)
                    .find(|&z| plan.rows(z).contains(&rows.start))
                    .unwrap_or(0);
                for i in rows {
                    f.add(i, &[1.0, 0.0]);
                    if let Some(target) = next_first(z) {
                        f.sub(target, &[0.0, 1.0]);
                    }
                    *seen += 1;
                }
            };
            for count in [1, 2] {
                // shared by ranks, each running its tasks alone: the same sums
                // on every rank, over whatever its forces and halo held
                for ranks in 1..=4 {
                    let runs = plan.task_runs(ranks);
                    assert_eq!(runs.len(), ranks);
                    assert_eq!(
                        runs.iter().map(|r| r.len()).sum::<usize>(),
                        plan.num_tasks()
                    );
                    let got = Hub::run(ranks, |exchange| {
                        let threads = Threads::new(count).unwrap();
                        let mut forces = vec![[f64::NAN; 2]; n];
                        let mut halo = vec![[f64::NAN; 2]; n];
                        let mut tallies = vec![0; plan.num_tasks()];
                        let mut sums = Vec::new();
                        for _call in 0..2 {
                            scatter_half_rows_shared(
                                &plan,
                                (&runs, exchange.rank()),
                                &mut forces,
                                &mut halo,
                                &mut tallies,
                                &threads,
                                |mine, counts, all| {
                                    let counts: Vec<usize> = counts.iter().map(|c| 2 * c).collect();
                                    exchange.all_gather(
                                        mine.as_flattened(),
                                        &counts,
                                        all.as_flattened_mut(),
                                    )
                                },
                                work,
                            );
                            sums.push(forces.clone());
                        }
                        sums
                    });
                    for sums in got.into_iter().flatten() {
                        assert_eq!(
                            sums, expected,
                            "{counts:?}, periodic {periodic}, {ranks} ranks"
                        );
                    }
                }
                let threads = Threads::new(count).unwrap();
                // the sums overwrite whatever the forces and the halo held, on a
                // first call and on the next
                let mut forces = vec![[f64::NAN; 2]; n];
                let mut halo = vec![[f64::NAN; 2]; n];
                for _call in 0..2 {
                    let mut rows_seen = vec![0; plan.num_tasks()];
                    scatter_half_rows(
                        &plan,
                        &mut forces,
                        &mut halo,
                        &mut rows_seen,
                        &threads,
                        work,
                    );
                    assert_eq!(forces, expected, "{counts:?}, periodic {periodic}");
                    // the cut layer's rows are shared by two tasks
                    let mut per_layer = vec![0; layers];
                    for (t, seen) in rows_seen.iter().enumerate() {
                        per_layer[plan.task(t).0] += seen;
                    }
                    assert_eq!(per_layer, counts);
                }
            }
        }
    }

    #[test]
    #[should_panic(expected = "outside the layer's reach")]
    fn writes_outside_the_reach_are_refused() {
        let plan = plan_for(6, true);
        let mut forces = vec![[0.0; 2]; 24];
        let mut tallies = vec![(); plan.num_tasks()];
        scatter_half_rows(
            &plan,
            &mut forces,
            &mut Vec::new(),
            &mut tallies,
            &Threads::single(),
            |rows, f, _| {
                // a slab two layers ahead is never in reach
                f.add((rows.start + 8) % 24, &[1.0, 1.0]);
            },
        );
    }
}
