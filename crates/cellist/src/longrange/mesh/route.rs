//! A mesh solver's particles divided among the ranks that share its mesh:
//! each rank holds its own part of them, the parts following each other in
//! rank order (rank 0's first), so that rank order is the particles' order.
//!
//! ```text
//! own particles  --(x, m) to each rank holding a plane of their stencils-->
//! routed here:   assigned to the own planes, every rank's in rank order
//! routed here whose stencil's lower plane is own  --(field)-->  their rank
//! ```
//!
//! A node sums the masses of the particles whose stencils touch it in the
//! particles' order, as one process does, and a particle's field is read from
//! the same planes by the same arithmetic as in one process; so the fields
//! have the bits of one process on any number of ranks. A particle's two
//! interlaced stencils span at most three planes, so it travels to one rank,
//! or two or three when they straddle cuts between slabs.

use super::cic::Geometry;
use super::slab::{owner, Exchange};
use crate::threads::exclusive_sums;
use crate::Threads;
use rayon::prelude::*;

/// Numbers per routed particle besides its flags: `x y z m`.
const BODY: usize = 4;

/// Room for the ranks a particle goes to: at most 3 for a mesh's stencils,
/// 25 for P3M's 5 x 5 rows of cells.
const PLACES: usize = 32;

/// Where a particle must go: the ranks that need it (`count` of them first
/// in `ranks`, no repeats) and, for each of `K` evaluations, the one rank
/// that computes its value.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Place<const K: usize> {
    pub(crate) ranks: [usize; PLACES],
    pub(crate) count: usize,
    pub(crate) lower: [usize; K],
}

impl<const K: usize> Place<K> {
    /// No rank yet; `lower` computes the values.
    pub(crate) fn new(lower: [usize; K]) -> Self {
        Place {
            ranks: [0; PLACES],
            count: 0,
            lower,
        }
    }

    /// Adds rank `r` (once).
    pub(crate) fn add(&mut self, r: usize) {
        if !self.ranks[..self.count].contains(&r) {
            self.ranks[self.count] = r;
            self.count += 1;
        }
    }
}

/// The particles of every rank routed to this one.
#[derive(Debug, Default)]
pub(crate) struct Arrived<const K: usize> {
    /// Their positions, every rank's in rank order.
    pub(crate) position: Vec<[f64; 3]>,
    /// Their masses.
    pub(crate) mass: Vec<f64>,
    /// Whether this rank computes each one's value in each of the `K`
    /// evaluations.
    here: Vec<[bool; K]>,
    /// How many came from each rank.
    from: Vec<usize>,
}

/// The routing's bookkeeping and message buffers (kept from call to call).
#[derive(Debug, Default)]
pub(crate) struct Route<const K: usize> {
    /// The rank that computes each own particle's value in each evaluation.
    owners: Vec<[u32; K]>,
    send: Vec<f64>,
    receive: Vec<f64>,
    values: Vec<[f64; 4]>,
}

/// Where the stencils of `x` on the two interlaced `geometries` lie among
/// `ranks`: the ranks holding a plane of either, and the rank holding each
/// one's lower plane (which interpolates it).
pub(crate) fn mesh_place(x: &[f64; 3], geometries: &[Geometry; 2], ranks: usize) -> Place<2> {
    let n = geometries[0].grid;
    let stencils = geometries.map(|g| g.stencil(x).planes());
    let mut place = Place::new(stencils.map(|planes| owner(planes[0], n, ranks)));
    for plane in stencils.into_iter().flatten() {
        place.add(owner(plane, n, ranks));
    }
    place
}

/// `counts` as the numbers of an exchange.
fn as_numbers(counts: &[usize]) -> Vec<f64> {
    counts.iter().map(|&c| c as f64).collect()
}

impl<const K: usize> Route<K> {
    /// Numbers per routed particle: `x y z m` and its flags (bit `k`: the
    /// receiving rank computes its value in evaluation `k`).
    const SENT: usize = BODY + 1;

    /// Routes this rank's particles (`position`, `mass`) to the ranks that
    /// `place` names, and receives every rank's particles for this one into
    /// `arrived`. Collective.
    pub(crate) fn forward(
        &mut self,
        position: &[[f64; 3]],
        mass: &[f64],
        exchange: &dyn Exchange,
        arrived: &mut Arrived<K>,
        place: impl Fn(&[f64; 3]) -> Place<K>,
    ) {
        let sent = Self::SENT;
        let ranks = exchange.ranks();
        let mut to = vec![0; ranks];
        self.owners.clear();
        for x in position {
            let p = place(x);
            for &r in &p.ranks[..p.count] {
                to[r] += sent;
            }
            self.owners.push(p.lower.map(|r| r as u32));
        }
        let mut at = exclusive_sums(&to);
        self.send.clear();
        self.send.resize(to.iter().sum(), 0.0);
        for (x, &m) in position.iter().zip(mass) {
            let p = place(x);
            for &r in &p.ranks[..p.count] {
                let flags: u32 = (0..K).map(|k| u32::from(p.lower[k] == r) << k).sum();
                let row = &mut self.send[at[r]..at[r] + sent];
                row[..BODY].copy_from_slice(&[x[0], x[1], x[2], m]);
                row[BODY] = f64::from(flags);
                at[r] += sent;
            }
        }
        let ones = vec![1; ranks];
        let mut from = vec![0.0; ranks];
        exchange.all_to_all(&as_numbers(&to), &ones, &mut from, &ones);
        let from: Vec<usize> = from.iter().map(|&c| c as usize).collect();
        self.receive.clear();
        self.receive.resize(from.iter().sum(), 0.0);
        exchange.all_to_all(&self.send, &to, &mut self.receive, &from);
        arrived.from = from.iter().map(|&c| c / sent).collect();
        arrived.position.clear();
        arrived.mass.clear();
        arrived.here.clear();
        for r in self.receive.chunks_exact(sent) {
            arrived.position.push([r[0], r[1], r[2]]);
            arrived.mass.push(r[3]);
            let flags = r[BODY] as u32;
            arrived
                .here
                .push(std::array::from_fn(|k| flags & (1 << k) != 0));
        }
    }

    /// The `arrived` particles' values in evaluation `k` sent back to their
    /// ranks: this rank computes `value(i)` for the arrived particles `i`
    /// whose value in evaluation `k` it computes, and `got[j]` becomes the
    /// value of own particle `j` (of the last [`Route::forward`]) from the
    /// rank that computed it. Collective.
    pub(crate) fn back(
        &mut self,
        arrived: &Arrived<K>,
        k: usize,
        exchange: &dyn Exchange,
        got: &mut [[f64; 4]],
        value: impl Fn(usize) -> [f64; 4] + Sync,
        threads: &Threads,
    ) {
        let ranks = exchange.ranks();
        let Route {
            owners,
            receive,
            values,
            ..
        } = self;
        let here = |i: usize| arrived.here[i][k];
        values.clear();
        threads.install(|| {
            values.par_extend(
                (0..arrived.position.len())
                    .into_par_iter()
                    .filter(|&i| here(i))
                    .map(&value),
            )
        });
        let mut send_counts = vec![0; ranks];
        let mut first = 0;
        for (count, &c) in send_counts.iter_mut().zip(&arrived.from) {
            *count = 4 * (first..first + c).filter(|&i| here(i)).count();
            first += c;
        }
        let mut receive_counts = vec![0; ranks];
        for o in owners.iter() {
            receive_counts[o[k] as usize] += 4;
        }
        receive.clear();
        receive.resize(receive_counts.iter().sum(), 0.0);
        exchange.all_to_all(
            values.as_flattened(),
            &send_counts,
            receive,
            &receive_counts,
        );
        // rank r's values follow the ranks before it, in the own order
        let mut cursor = exclusive_sums(&receive_counts);
        for (g, o) in got.iter_mut().zip(owners.iter()) {
            let at = &mut cursor[o[k] as usize];
            g.copy_from_slice(&receive[*at..*at + 4]);
            *at += 4;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::slab::part;
    use super::super::slab::testkit::Hub;
    use super::*;

    /// Each rank's own particles along x in `[0, 1)`, scattered over every
    /// rank's stretch of x: the particle `i` of `n` at x = `(7 i mod n) / n`.
    fn own(n: usize, rank: usize, ranks: usize) -> Vec<[f64; 3]> {
        part(n, rank, ranks)
            .map(|i| [((7 * i) % n) as f64 / n as f64, i as f64, 0.5])
            .collect()
    }

    #[test]
    fn every_particle_gets_the_value_of_the_rank_its_place_names() {
        let n = 50;
        for ranks in [1, 2, 3, 4] {
            let results = Hub::run(ranks, |exchange| {
                let rank = exchange.rank();
                let position = own(n, rank, ranks);
                let mass: Vec<f64> = position.iter().map(|x| x[1] + 0.25).collect();
                // the stretch of x that holds the particle computes it; its
                // neighbours along x (and rank 0) receive it too
                let stretch = |x: &[f64; 3]| ((x[0] * ranks as f64) as usize).min(ranks - 1);
                let place = |x: &[f64; 3]| {
                    let r = stretch(x);
                    let mut place = Place::new([r]);
                    for s in [r.saturating_sub(1), r, (r + 1).min(ranks - 1), 0] {
                        place.add(s);
                    }
                    place
                };
                let (mut route, mut arrived) = (Route::<1>::default(), Arrived::default());
                route.forward(&position, &mass, exchange, &mut arrived, place);
                // every rank's particles arrive in rank order, then own order
                let ids: Vec<f64> = arrived.position.iter().map(|x| x[1]).collect();
                assert!(ids.windows(2).all(|w| w[0] < w[1]), "{ids:?}");
                let mut got = vec![[0.0; 4]; position.len()];
                route.back(
                    &arrived,
                    0,
                    exchange,
                    &mut got,
                    |i| {
                        let x = arrived.position[i];
                        [x[0], x[1], arrived.mass[i], rank as f64]
                    },
                    &crate::Threads::single(),
                );
                (position, got)
            });
            for (position, got) in &results {
                for (x, g) in position.iter().zip(got) {
                    let r = ((x[0] * ranks as f64) as usize).min(ranks - 1);
                    assert_eq!(*g, [x[0], x[1], x[1] + 0.25, r as f64], "{ranks} ranks");
                }
            }
        }
    }
}
