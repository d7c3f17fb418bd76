//! The pair sums of the PSE rate, `out_i = sum_j w(r_ij^2) (phi_j - phi_i)`, each pair
//! evaluated once and applied to both particles (so that `sum_i out_i = 0` to
//! round-off), in parallel without atomics and with every particle's sum in an
//! order fixed by the data, never by the thread count. The cell-list sum takes
//! `W` components per particle (`phi_i` in `R^W`), all weighted by the pair's one
//! `w`, each component with the operations of a scalar sum:
//! - all pairs: blocks of particles met in a round-robin tournament, each round a
//!   set of disjoint block pairs run in parallel;
//! - cell list: a half Verlet list of the static particles, built once, summed
//!   layer by layer with a halo ([`scatter_half_rows`]); ranks that each hold
//!   every particle may share it, each building and summing the rows of its
//!   run of the layers ([`ListPairs::of_rank`], [`scatter_half_rows_shared`]).

use super::kernel::PairWeight;
use crate::geometry::Domain;
use crate::longrange::mesh::slab::Exchange;
use crate::neighbors::{
    scatter_half_rows, scatter_half_rows_shared, unpack, CellList, LayerForces, LayerPlan,
    StencilKind, VerletList,
};
use crate::threads::{tournament, DisjointSlice, Threads};
use rayon::prelude::*;
use std::ops::Range;

/// What a pair sum adds up: `(phi_j - phi_i) w` (the rate, antisymmetric), or the
/// weights `w` themselves (the row sums `S_i = sum_j w_ij`, symmetric).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Summed {
    Rate,
    Weights,
}

/// Entries handled together: gathered, computed in straight-line (SIMD) code, then
/// scattered.
const BLOCK: usize = 16;

/// One block of pairs: separations by axis, `phi_j - phi_i` by component, and
/// the pair values by component.
struct PairBlock<const D: usize, const W: usize> {
    d: [[f64; BLOCK]; D],
    dphi: [[f64; BLOCK]; W],
    value: [[f64; BLOCK]; W],
}

impl<const D: usize, const W: usize> Default for PairBlock<D, W> {
    fn default() -> Self {
        PairBlock {
            d: [[1.0; BLOCK]; D],
            dphi: [[0.0; BLOCK]; W],
            value: [[0.0; BLOCK]; W],
        }
    }
}

impl<const D: usize, const W: usize> PairBlock<D, W> {
    /// `value[c][k] = w(|d_k|^2) dphi[c][k]` (or `w` alone) for every lane and
    /// component.
    #[inline(always)]
    fn evaluate(&mut self, weight: &PairWeight, summed: Summed) {
        for k in 0..BLOCK {
            let mut r2 = 0.0;
            for a in 0..D {
                r2 += self.d[a][k] * self.d[a][k];
            }
            let w = weight.at(r2);
            for c in 0..W {
                self.value[c][k] = match summed {
                    Summed::Rate => w * self.dphi[c][k],
                    Summed::Weights => w,
                };
            }
        }
    }
}

/// The sign with which particle `j` receives a pair's value.
#[inline(always)]
fn partner_sign(summed: Summed) -> f64 {
    match summed {
        Summed::Rate => -1.0,
        Summed::Weights => 1.0,
    }
}

/// Particles per block of the all-pairs sum.
const DIRECT_BLOCK: usize = 256;

/// All pairs under the minimum image: the blocks and the rounds in which they meet.
#[derive(Clone, Debug)]
pub(super) struct AllPairs<const D: usize> {
    domain: Domain<D>,
    n: usize,
    /// Round 0 pairs every block with itself; then each round holds disjoint pairs.
    rounds: Vec<Vec<(usize, usize)>>,
}

impl<const D: usize> AllPairs<D> {
    pub(super) fn new(domain: &Domain<D>, n: usize) -> Self {
        AllPairs {
            domain: *domain,
            n,
            rounds: tournament(n.div_ceil(DIRECT_BLOCK)),
        }
    }

    /// Pairs evaluated per sum.
    pub(super) fn pairs(&self) -> u64 {
        let n = self.n as u64;
        n * n.saturating_sub(1) / 2
    }

    pub(super) fn sum(
        &self,
        weight: &PairWeight,
        summed: Summed,
        positions: &[[f64; D]],
        phi: &[f64],
        out: &mut [f64],
        threads: &Threads,
    ) {
        out.fill(0.0);
        let shared = DisjointSlice::new(out);
        let block = |b: usize| b * DIRECT_BLOCK..((b + 1) * DIRECT_BLOCK).min(self.n);
        threads.install(|| {
            for round in &self.rounds {
                round.par_iter().for_each(|&(a, b)| {
                    let (ra, rb) = (block(a), block(b));
                    let mut pb = PairBlock::<D, 1>::default();
                    if a == b {
                        // SAFETY: each block occurs once in round 0.
                        let out_a = unsafe { shared.range(ra.clone()) };
                        for (local, i) in ra.clone().enumerate() {
                            let (own, later) = out_a.split_at_mut(local + 1);
                            let partners = i + 1..ra.end;
                            own[local] += self
                                .row(&mut pb, weight, summed, i, positions, phi, partners, later);
                        }
                    } else {
                        // SAFETY: the pairs of a tournament round are disjoint.
                        let (out_a, out_b) =
                            unsafe { (shared.range(ra.clone()), shared.range(rb.clone())) };
                        for (local, i) in ra.clone().enumerate() {
                            out_a[local] += self.row(
                                &mut pb,
                                weight,
                                summed,
                                i,
                                positions,
                                phi,
                                rb.clone(),
                                out_b,
                            );
                        }
                    }
                });
            }
        });
    }

    /// Particle `i` against the consecutive `partners`, whose sums are
    /// `partner_out` (same length): adds each pair's share to the partner and
    /// returns `i`'s share, summed in partner order.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn row(
        &self,
        pb: &mut PairBlock<D, 1>,
        weight: &PairWeight,
        summed: Summed,
        i: usize,
        positions: &[[f64; D]],
        phi: &[f64],
        partners: Range<usize>,
        partner_out: &mut [f64],
    ) -> f64 {
        let (xi, phii) = (positions[i], phi[i]);
        let half: [f64; D] = std::array::from_fn(|a| 0.5 * self.domain.length[a]);
        let length = self.domain.length;
        let sign = partner_sign(summed);
        let mut acc = 0.0;
        for (chunk, out_chunk) in partners
            .clone()
            .step_by(BLOCK)
            .zip(partner_out.chunks_mut(BLOCK))
        {
            let js = chunk..(chunk + BLOCK).min(partners.end);
            for (k, j) in js.enumerate() {
                for a in 0..D {
                    // the minimum image of wrapped positions
                    let d = positions[j][a] - xi[a];
                    pb.d[a][k] = if d > half[a] {
                        d - length[a]
                    } else if d < -half[a] {
                        d + length[a]
                    } else {
                        d
                    };
                }
                pb.dphi[0][k] = phi[j] - phii;
            }
            pb.evaluate(weight, summed);
            for (k, o) in out_chunk.iter_mut().enumerate() {
                acc += pb.value[0][k];
                *o += sign * pb.value[0][k];
            }
        }
        acc
    }
}

/// The pairs within the cutoff of static particles: a half Verlet list (no skin)
/// over a cell list, and the layers that sum it in parallel, for `W` components
/// per particle.
#[derive(Clone, Debug)]
pub(super) struct ListPairs<const D: usize, const W: usize> {
    list: VerletList<D>,
    plan: LayerPlan,
    halo: Vec<[f64; W]>,
    tallies: Vec<()>,
}

impl<const D: usize, const W: usize> ListPairs<D, W> {
    /// The list for the particles of `cells` (binned for at least `cutoff`).
    pub(super) fn new(cells: &CellList<D>, cutoff: f64, threads: &Threads) -> Self {
        let plan = LayerPlan::new(cells);
        ListPairs {
            list: VerletList::build(cells, StencilKind::Half, cutoff, 0.0, threads),
            tallies: vec![(); plan.num_tasks()],
            plan,
            halo: Vec::new(),
        }
    }

    /// The part of the list that one of the ranks of `exchange` sums (each
    /// holding every particle of `cells`): the rows of its run of the layer
    /// tasks ([`LayerPlan::task_runs`]), for [`ListPairs::sum_shared`].
    pub(super) fn of_rank(
        cells: &CellList<D>,
        cutoff: f64,
        exchange: &dyn Exchange,
        threads: &Threads,
    ) -> (Self, Vec<Range<usize>>) {
        let plan = LayerPlan::new(cells);
        let runs = plan.task_runs(exchange.ranks());
        let tasks = runs[exchange.rank()].clone();
        let rows = if tasks.is_empty() {
            0..0
        } else {
            plan.task_rows(tasks.start).start..plan.task_rows(tasks.end - 1).end
        };
        let list = ListPairs {
            list: VerletList::build_rows(cells, StencilKind::Half, cutoff, rows, threads),
            tallies: vec![(); plan.num_tasks()],
            plan,
            halo: Vec::new(),
        };
        (list, runs)
    }

    /// Pairs evaluated per sum.
    pub(super) fn pairs(&self) -> u64 {
        self.list.num_entries() as u64
    }

    /// The pair sum over the list; `positions` in the cell list's slot order.
    /// `shared`: the ranks that share it (every rank's run of the layer
    /// tasks and the exchange among them, the list built by
    /// [`ListPairs::of_rank`]), each summing the rows of its run, or `None`
    /// in one process; the same bits either way.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn sum(
        &mut self,
        weight: &PairWeight,
        summed: Summed,
        positions: &[[f64; D]],
        phi: &[[f64; W]],
        out: &mut [[f64; W]],
        shared: Option<(&[Range<usize>], &dyn Exchange)>,
        threads: &Threads,
    ) {
        let list = &self.list;
        let sign = partner_sign(summed);
        let rows = |rows: Range<usize>, sums: &LayerForces<[f64; W]>, _: &mut ()| {
            let mut pb = PairBlock::<D, W>::default();
            for i in rows {
                let (xi, phii) = (positions[i], phi[i]);
                let mut acc = [0.0; W];
                for block in list.row(i).chunks(BLOCK) {
                    for (k, &entry) in block.iter().enumerate() {
                        let (j, image) = unpack(entry);
                        let (xj, s) = (&positions[j], list.image_shift(image));
                        for a in 0..D {
                            pb.d[a][k] = (xj[a] + s[a]) - xi[a];
                        }
                        for c in 0..W {
                            pb.dphi[c][k] = phi[j][c] - phii[c];
                        }
                    }
                    pb.evaluate(weight, summed);
                    for (k, &entry) in block.iter().enumerate() {
                        let value: [f64; W] = std::array::from_fn(|c| pb.value[c][k]);
                        for c in 0..W {
                            acc[c] += value[c];
                        }
                        sums.add(unpack(entry).0, &value.map(|v| sign * v));
                    }
                }
                sums.add(i, &acc);
            }
        };
        match shared {
            None => scatter_half_rows(
                &self.plan,
                out,
                &mut self.halo,
                &mut self.tallies,
                threads,
                rows,
            ),
            Some((runs, exchange)) => scatter_half_rows_shared(
                &self.plan,
                (runs, exchange.rank()),
                out,
                &mut self.halo,
                &mut self.tallies,
                threads,
                |mine, counts, all| {
                    let counts: Vec<usize> = counts.iter().map(|c| W * c).collect();
                    exchange.all_gather(mine.as_flattened(), &counts, all.as_flattened_mut())
                },
                rows,
            ),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::{moving_rate, PairWeight};
    use crate::geometry::Domain;
    use crate::longrange::mesh::slab::testkit::Hub;
    use crate::longrange::Alone;
    use crate::random::Rng;
    use crate::threads::Threads;

    /// `n` particles in the unit box of dimension `D` with `W` strengths each.
    fn cloud<const D: usize, const W: usize>(
        n: usize,
        seed: u64,
    ) -> (Vec<[f64; D]>, Vec<[f64; W]>) {
        let mut rng = Rng::new(seed);
        let x = (0..n)
            .map(|_| std::array::from_fn(|_| rng.uniform()))
            .collect();
        let phi = (0..n)
            .map(|_| std::array::from_fn(|_| rng.normal()))
            .collect();
        (x, phi)
    }

    /// The rate of every rank of `ranks` sharing it, against one process's.
    fn shared_rates_have_one_process_bits<const D: usize, const W: usize>(
        domain: Domain<D>,
        cutoff: f64,
        n: usize,
    ) {
        let (x, phi) = cloud::<D, W>(n, n as u64 + D as u64);
        let weight = PairWeight::new(D, 0.01, cutoff / 3.0, 1.0 / n as f64);
        let mut alone = vec![[0.0; W]; n];
        moving_rate(
            &domain,
            &weight,
            cutoff,
            &x,
            &phi,
            &mut alone,
            &Alone,
            &Threads::single(),
        )
        .unwrap();
        for ranks in 1..=4 {
            for threads in [1, 2] {
                let got = Hub::run(ranks, |exchange| {
                    let mut out = vec![[0.0; W]; n];
                    let t = Threads::new(threads).unwrap();
                    moving_rate(&domain, &weight, cutoff, &x, &phi, &mut out, exchange, &t)
                        .map(|()| out)
                });
                for (rank, out) in got.into_iter().enumerate() {
                    let out = out.unwrap();
                    let same = out
                        .as_flattened()
                        .iter()
                        .zip(alone.as_flattened())
                        .all(|(a, b)| a.to_bits() == b.to_bits());
                    assert!(
                        same,
                        "{D}D, {n} particles, rank {rank} of {ranks}, {threads} threads"
                    );
                }
            }
        }
    }

    #[test]
    fn rates_shared_by_ranks_have_one_process_bits() {
        // 2D open: a few layers, one of them cut (an odd count below 16)
        let open2 = |x: &[[f64; 2]]| Domain::open_around(x);
        let (x2, _) = cloud::<2, 1>(700, 702);
        shared_rates_have_one_process_bits::<2, 1>(open2(&x2), 0.2, 700);
        // 2D periodic: layers that wrap, many of them
        shared_rates_have_one_process_bits::<2, 1>(Domain::periodic([1.0; 2]).unwrap(), 0.05, 700);
        // 3D, three strengths: periodic with an odd layer count, and open
        shared_rates_have_one_process_bits::<3, 3>(Domain::periodic([1.0; 3]).unwrap(), 0.2, 900);
        let (x3, _) = cloud::<3, 3>(900, 903);
        shared_rates_have_one_process_bits::<3, 3>(Domain::open_around(&x3), 0.15, 900);
        // fewer particles than ranks have layers
        shared_rates_have_one_process_bits::<2, 1>(Domain::periodic([1.0; 2]).unwrap(), 0.3, 3);
    }
}
