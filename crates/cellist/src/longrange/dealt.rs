//! All-pairs sums dealt out among ranks that each hold every particle (the
//! direct Biot-Savart sums in 2D and 3D).
//!
//! One process runs every pair once in the rounds of a round-robin
//! tournament of particle blocks ([`crate::threads::tournament`]), a round's
//! block pairs in parallel. On `P` ranks every rank runs the same rounds but
//! only the block pairs `k` (counted round after round) with `k mod P` its
//! rank ([`play`]), into partial sums of every particle: each pair is
//! computed once, on one rank. [`Partials::add`] then gives every rank each
//! particle's total, the sum of the ranks' partials in rank order:
//!
//! `S_i = (..((s_i^0 + s_i^1) + s_i^2) + ..) + s_i^(P-1)`,
//!
//! added by the rank whose part (`N r / P .. N (r + 1) / P`) holds particle
//! `i` after one all-to-all, and all-gathered. The totals do not depend on
//! the thread count; they round differently from one process's (and from
//! another rank count's), which on one rank they equal to the bit.

use super::mesh::slab::part;
use super::Exchange;
use crate::threads::Threads;
use rayon::prelude::*;

/// Runs `pair(p, q)` for the block pairs of `rounds` that rank `rank` of
/// `ranks` takes, pair `k` (counted round after round) on rank `k mod
/// ranks`; each round's pairs in parallel (no block plays twice in a round),
/// the rounds in order.
pub(crate) fn play(
    rounds: &[Vec<(usize, usize)>],
    (rank, ranks): (usize, usize),
    threads: &Threads,
    pair: impl Fn(usize, usize) + Sync,
) {
    threads.install(|| {
        let mut dealt = 0;
        for round in rounds {
            let first = dealt;
            dealt += round.len();
            round
                .par_iter()
                .enumerate()
                .filter(|(k, _)| (first + k) % ranks == rank)
                .for_each(|(_, &(p, q))| pair(p, q));
        }
    });
}

/// The buffers of [`Partials::add`], kept between evaluations.
#[derive(Clone, Debug, Default)]
pub(crate) struct Partials {
    send: Vec<f64>,
    receive: Vec<f64>,
    /// Every particle's `W` totals, particle after particle.
    totals: Vec<f64>,
}

impl Partials {
    /// Every particle's totals over the ranks of `exchange` of the partial
    /// sums `columns` (`W` columns of one number per particle), each added in
    /// rank order by the rank of the particle's part and all-gathered.
    pub(crate) fn add<const W: usize>(&mut self, columns: &[Vec<f64>; W], exchange: &dyn Exchange) {
        let (rank, ranks) = (exchange.rank(), exchange.ranks());
        let n = columns[0].len();
        let parts: Vec<std::ops::Range<usize>> = (0..ranks).map(|r| part(n, r, ranks)).collect();
        let counts: Vec<usize> = parts.iter().map(|p| W * p.len()).collect();
        self.send.clear();
        for i in parts.iter().flat_map(|p| p.clone()) {
            self.send.extend(columns.iter().map(|c| c[i]));
        }
        let own = counts[rank];
        self.receive.resize(ranks * own, 0.0);
        exchange.all_to_all(&self.send, &counts, &mut self.receive, &vec![own; ranks]);
        // this rank's totals, staged in `send`
        let (from, rest) = self.receive.split_at(own);
        self.send.clear();
        self.send.extend_from_slice(from);
        // (a rank whose part holds no particle has nothing to add)
        for partial in rest.chunks(own.max(1)) {
            for (t, p) in self.send.iter_mut().zip(partial) {
                *t += p;
            }
        }
        self.totals.resize(W * n, 0.0);
        exchange.all_gather(&self.send, &counts, &mut self.totals);
    }

    /// Particle `i`'s `W` totals of the last [`Partials::add`].
    pub(crate) fn total<const W: usize>(&self, i: usize) -> [f64; W] {
        std::array::from_fn(|k| self.totals[i * W + k])
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::longrange::mesh::slab::testkit::Hub;
    use crate::threads::tournament;
    use std::sync::Mutex;

    /// Every block pair of the tournament is played once over the ranks,
    /// whatever their count (more ranks than pairs too).
    #[test]
    fn every_pair_is_played_once_on_one_rank() {
        let rounds = tournament(7);
        for ranks in [1, 2, 3, 40] {
            let played = Mutex::new(Vec::new());
            for rank in 0..ranks {
                play(&rounds, (rank, ranks), &Threads::new(2).unwrap(), |p, q| {
                    played.lock().unwrap().push((p, q))
                });
            }
            let mut played = played.into_inner().unwrap();
            played.sort_unstable();
            let mut want: Vec<(usize, usize)> = rounds.concat();
            want.sort_unstable();
            assert_eq!(played, want, "{ranks} ranks");
        }
    }

    /// The totals are the partials added in rank order, on every rank, with
    /// parts that hold no particle (3 particles on 4 ranks).
    #[test]
    fn the_totals_add_the_partials_in_rank_order() {
        for (n, ranks) in [(10, 3), (3, 4)] {
            let partial =
                |r: usize, i: usize, k: usize| 0.1 * (r + 1) as f64 + 1e-3 * (i * 2 + k) as f64;
            let got = Hub::run(ranks, |exchange| {
                let r = exchange.rank();
                let columns: [Vec<f64>; 2] =
                    std::array::from_fn(|k| (0..n).map(|i| partial(r, i, k)).collect());
                let mut partials = Partials::default();
                partials.add(&columns, exchange);
                (0..n).map(|i| partials.total::<2>(i)).collect::<Vec<_>>()
            });
            let want: Vec<[f64; 2]> = (0..n)
                .map(|i| {
                    std::array::from_fn(|k| {
                        (1..ranks).fold(partial(0, i, k), |s, r| s + partial(r, i, k))
                    })
                })
                .collect();
            for (r, totals) in got.iter().enumerate() {
                assert_eq!(totals, &want, "rank {r} of {ranks}");
            }
        }
    }
}
