//! A tree evaluation (a Barnes-Hut walk or an fmm) divided among processes
//! that each hold every particle (MPI ranks of a replicated run): each builds
//! the same tree, walks and sums only the groups of its own part, and
//! receives the other parts' results.
//!
//! A particle's result depends only on its group's lists (and, in an fmm, on
//! the reactions of earlier groups' pairs with its leaves, gathered and added
//! group after group), and a group's lists only on the tree, so a divided
//! evaluation gives every particle the bits of the undivided one. The parts are contiguous runs of the groups in Morton
//! order (each part's targets lie close together in space and in memory),
//! balanced by the last evaluation's cost ([`Costs`]): a particle weighs one
//! plus its group's work per particle (a walk's accepted nodes and listed
//! particles; an fmm's pair terms and M2L), which every process learns before
//! the results (at the first evaluation, or when the particle count changed,
//! every particle weighs 1).

use super::build::Octree;
use crate::longrange::mesh::slab::Exchange;

/// How a tree evaluation is divided: this process evaluates part `part` of
/// `parts` and receives the others. Every process of the division must see the
/// same particles and call the evaluation alike.
pub trait Share {
    /// `(part, parts)`: this process evaluates part `part` of `parts`
    /// (`part < parts`).
    fn part(&self) -> (usize, usize);

    /// Fills every part of `values` but this process's own with what the other
    /// processes evaluated (an all-gather): `width` numbers per item (a
    /// particle in tree order, or a slot of a divided cell-list sum), part `k`
    /// the items `bounds[k]..bounds[k + 1]` (`bounds` has `parts + 1`
    /// entries, 0 first and the item count last, the same on every process).
    /// This process's part is filled on entry.
    fn all_gather(&mut self, values: &mut [f64], width: usize, bounds: &[usize]);
}

/// The undivided evaluation: one part, nothing to receive.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Whole;

impl Share for Whole {
    fn part(&self) -> (usize, usize) {
        (0, 1)
    }

    fn all_gather(&mut self, _values: &mut [f64], _width: usize, _bounds: &[usize]) {}
}

/// The ranks of `peers` as the parts of a divided evaluation: rank `r`
/// evaluates part `r`, and the parts are all-gathered through `peers` (one
/// rank: nothing to gather).
pub struct AmongPeers<'a> {
    peers: &'a dyn Exchange,
    /// A copy of this rank's part, sent while `values` receives the others.
    own: Vec<f64>,
}

impl<'a> AmongPeers<'a> {
    /// The division among `peers`.
    pub fn new(peers: &'a dyn Exchange) -> Self {
        AmongPeers {
            peers,
            own: Vec::new(),
        }
    }
}

impl Share for AmongPeers<'_> {
    fn part(&self) -> (usize, usize) {
        (self.peers.rank(), self.peers.ranks())
    }

    fn all_gather(&mut self, values: &mut [f64], width: usize, bounds: &[usize]) {
        let (rank, ranks) = self.part();
        if ranks == 1 {
            return;
        }
        self.own.clear();
        self.own
            .extend_from_slice(&values[bounds[rank] * width..bounds[rank + 1] * width]);
        let counts: Vec<usize> = bounds.windows(2).map(|w| (w[1] - w[0]) * width).collect();
        self.peers
            .all_gather(&self.own, &counts, &mut values[..bounds[ranks] * width]);
    }
}

/// Every particle's weight for the next [`Split`] of a divided evaluation,
/// in input order (empty before the first: every particle weighs 1).
#[derive(Clone, Debug, Default)]
pub(super) struct Costs {
    input: Vec<f64>,
    /// The weights in tree order, this process's part written, the others'
    /// gathered.
    sorted: Vec<f64>,
}

impl Costs {
    /// The weights, input order.
    pub fn input(&self) -> &[f64] {
        &self.input
    }

    /// The weights of the last evaluation: `work` gives the work of each
    /// group of this process's part `part` of `split` (in order), each of its
    /// particles weighing `1 + work / particles`, and `share` brings the
    /// other parts' weights.
    pub fn gather(
        &mut self,
        tree: &Octree,
        split: &Split,
        part: usize,
        work: impl Iterator<Item = f64>,
        share: &mut dyn Share,
    ) {
        let n = tree.order.len();
        self.sorted.resize(n, 0.0);
        let own = &tree.groups[split.groups[part]..split.groups[part + 1]];
        for (&group, work) in own.iter().zip(work) {
            let node = &tree.nodes[group as usize];
            let range = node.start as usize..node.end as usize;
            let weight = 1.0 + work / range.len() as f64;
            self.sorted[range].fill(weight);
        }
        share.all_gather(&mut self.sorted, 1, &split.particles);
        self.input.resize(n, 0.0);
        for (&i, &c) in tree.order.iter().zip(&self.sorted) {
            self.input[i as usize] = c;
        }
    }
}

/// The parts of a divided evaluation: part `k` walks the groups
/// `tree.groups[groups[k]..groups[k + 1]]`, which hold the sorted particles
/// `particles[k]..particles[k + 1]`.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub(super) struct Split {
    pub groups: Vec<usize>,
    pub particles: Vec<usize>,
}

impl Split {
    /// `parts` contiguous runs of `tree`'s groups of about equal weight, particle
    /// `i` (input order) weighing `cost[i]` when `cost` has one entry per
    /// particle, else 1: a group goes to the part `floor(P (W_before + w / 2) /
    /// W)` in which the middle of its weight `w` falls, `W_before` the weight of
    /// the groups before it and `W` the total.
    pub fn new(tree: &Octree, cost: &[f64], parts: usize) -> Self {
        assert!(parts > 0);
        let n = tree.order.len();
        if parts == 1 {
            return Split {
                groups: vec![0, tree.groups.len()],
                particles: vec![0, n],
            };
        }
        let weighed = cost.len() == n;
        let weights: Vec<f64> = tree
            .groups
            .iter()
            .map(|&g| {
                let node = &tree.nodes[g as usize];
                let range = node.start as usize..node.end as usize;
                if weighed {
                    range.map(|s| cost[tree.order[s] as usize]).sum()
                } else {
                    range.len() as f64
                }
            })
            .collect();
        let total: f64 = weights.iter().sum();
        let mut groups = vec![0; parts + 1];
        let mut before = 0.0;
        for (g, w) in weights.iter().enumerate() {
            let middle = (before + 0.5 * w) / total * parts as f64;
            let part = (middle as usize).min(parts - 1);
            // the groups up to g belong to parts up to `part`
            for bound in &mut groups[part + 1..] {
                *bound = g + 1;
            }
            before += w;
        }
        let particles = groups
            .iter()
            .map(|&k| match tree.groups.get(k) {
                Some(&g) => tree.nodes[g as usize].start as usize,
                None => n,
            })
            .collect();
        Split { groups, particles }
    }
}

#[cfg(test)]
mod tests {
    use super::super::build::Sizes;
    use super::super::{
        BarnesHut, FmmAccuracy, TreeParams, VortexFmm, VortexFmm3, VortexTree, VortexTree3,
    };
    use super::*;
    use crate::interactions::GravityLaw;
    use crate::longrange::mesh::slab::testkit::Hub;
    use crate::longrange::{BlobKernel, BlobKernel3, FieldOut, Sources};
    use crate::random::Rng;
    use crate::threads::Threads;
    use std::sync::{Barrier, Mutex};

    fn tree(n: usize, seed: u64) -> Octree {
        let mut rng = Rng::new(seed);
        let x: Vec<[f64; 3]> = (0..n)
            .map(|_| [rng.normal(), rng.normal(), rng.normal()])
            .collect();
        let mut tree = Octree::default();
        tree.build(&x, Sizes { leaf: 8, group: 32 }, &Threads::single());
        tree
    }

    /// The parts tile the groups and the particles in order, whatever the
    /// number of parts (more parts than groups leaves some empty).
    #[test]
    fn parts_tile_the_groups_in_order() {
        for (n, parts) in [(0, 3), (1, 4), (5000, 1), (5000, 2), (5000, 7), (40, 9)] {
            let tree = tree(n, 5);
            let split = Split::new(&tree, &[], parts);
            assert_eq!(split.groups.len(), parts + 1);
            assert_eq!(split.groups[0], 0);
            assert_eq!(split.groups[parts], tree.groups.len());
            assert_eq!(split.particles[0], 0);
            assert_eq!(split.particles[parts], n);
            for k in 0..parts {
                assert!(split.groups[k] <= split.groups[k + 1]);
                let first = split.groups[k];
                if first < tree.groups.len() {
                    let g = tree.groups[first] as usize;
                    assert_eq!(split.particles[k], tree.nodes[g].start as usize);
                }
            }
        }
    }

    /// Equal weights give parts within a group of the equal share; weights
    /// piled on a few particles move the cuts to them.
    #[test]
    fn parts_balance_the_weights() {
        let n = 20_000;
        let tree = tree(n, 7);
        let most = tree
            .groups
            .iter()
            .map(|&g| (tree.nodes[g as usize].end - tree.nodes[g as usize].start) as f64)
            .fold(0.0, f64::max);
        let parts = 4;
        let split = Split::new(&tree, &[], parts);
        for k in 0..parts {
            let len = (split.particles[k + 1] - split.particles[k]) as f64;
            assert!(
                (len - n as f64 / parts as f64).abs() <= most,
                "part {k}: {len}"
            );
        }
        // the particles of the first quarter of the tree order weigh 9 each: the
        // weight is 3 n, and the first part gets about a third of that quarter
        let mut cost = vec![1.0; n];
        for &i in &tree.order[..n / 4] {
            cost[i as usize] = 9.0;
        }
        let split = Split::new(&tree, &cost, parts);
        let weight = |k: usize| -> f64 {
            (split.particles[k]..split.particles[k + 1])
                .map(|s| cost[tree.order[s] as usize])
                .sum()
        };
        for k in 0..parts {
            let w = weight(k);
            assert!(
                (w - 3.0 * n as f64 / parts as f64).abs() <= 9.0 * most,
                "part {k}: weight {w}"
            );
        }
        assert!(split.particles[1] < n / 8);
    }

    /// An all-gather among the threads of one process, one per part: part 0
    /// fills the buffer with NaN, every part writes its own values into it, then
    /// every part copies the whole (a part whose bounds disagreed with the
    /// others' would read NaN or another part's values).
    struct Exchange {
        barrier: Barrier,
        buffer: Mutex<Vec<f64>>,
    }

    /// One part's end of an [`Exchange`], recording the bounds it was given.
    struct Member<'a> {
        part: usize,
        parts: usize,
        exchange: &'a Exchange,
        bounds: Vec<Vec<usize>>,
    }

    impl Share for Member<'_> {
        fn part(&self) -> (usize, usize) {
            (self.part, self.parts)
        }

        fn all_gather(&mut self, values: &mut [f64], width: usize, bounds: &[usize]) {
            let exchange = self.exchange;
            let buffer = || exchange.buffer.lock().unwrap();
            if self.part == 0 {
                let mut b = buffer();
                b.clear();
                b.resize(values.len(), f64::NAN);
            }
            exchange.barrier.wait();
            let own = bounds[self.part] * width..bounds[self.part + 1] * width;
            buffer()[own.clone()].copy_from_slice(&values[own]);
            exchange.barrier.wait();
            values.copy_from_slice(&buffer());
            exchange.barrier.wait();
            self.bounds.push(bounds.to_vec());
        }
    }

    /// One evaluation of a solver `S` at step `step`, divided by a share: its
    /// results' bits and its interactions.
    type Evaluation = (Vec<u64>, (u64, u64));

    /// How the gathers of one evaluation go: `per_step` gathers, of which
    /// the results' cuts are gather `results` (the costs' come before it);
    /// the results' cuts give every part some particles, and move after the
    /// first evaluation (the costs replace the counts).
    #[derive(Clone, Copy)]
    struct Gathers {
        per_step: usize,
        results: usize,
    }

    /// The gathers of a walk: the costs, then the results.
    const TWO_GATHERS: Gathers = Gathers {
        per_step: 2,
        results: 1,
    };

    /// The gathers of a 2D fmm: the costs, the results, then the reactions'
    /// counts and the reactions of the pairs across groups.
    const FMM_GATHERS: Gathers = Gathers {
        per_step: 4,
        results: 1,
    };

    /// `steps` evaluations of a solver made by `new`, undivided and divided into
    /// `parts` (each part on a thread of its own with its own solver): every
    /// part holds the undivided results bit for bit, the parts' interactions add
    /// up to the undivided ones, and the gathers go as `gathers` says.
    fn divided_equals_whole<S>(
        parts: usize,
        gathers: Gathers,
        steps: usize,
        new: impl Fn() -> S + Sync,
        evaluate: impl Fn(&mut S, usize, &mut dyn Share) -> Evaluation + Sync,
    ) {
        let mut whole = new();
        let want: Vec<Evaluation> = (0..steps)
            .map(|step| evaluate(&mut whole, step, &mut Whole))
            .collect();
        let exchange = Exchange {
            barrier: Barrier::new(parts),
            buffer: Mutex::new(Vec::new()),
        };
        let got: Vec<(Vec<Evaluation>, Vec<Vec<usize>>)> = std::thread::scope(|scope| {
            let handles: Vec<_> = (0..parts)
                .map(|part| {
                    let (exchange, new, evaluate) = (&exchange, &new, &evaluate);
                    scope.spawn(move || {
                        let mut solver = new();
                        let mut member = Member {
                            part,
                            parts,
                            exchange,
                            bounds: Vec::new(),
                        };
                        let results = (0..steps)
                            .map(|step| evaluate(&mut solver, step, &mut member))
                            .collect();
                        (results, member.bounds)
                    })
                })
                .collect();
            handles.into_iter().map(|h| h.join().unwrap()).collect()
        });
        for step in 0..steps {
            let mut counts = (0, 0);
            for (part, (results, _)) in got.iter().enumerate() {
                let (bits, c) = &results[step];
                assert!(*bits == want[step].0, "part {part} of {parts}, step {step}");
                counts = (counts.0 + c.0, counts.1 + c.1);
            }
            assert_eq!(counts, want[step].1, "{parts} parts, step {step}");
        }
        let cuts = &got[0].1;
        assert_eq!(cuts.len(), gathers.per_step * steps);
        let (first, second) = (gathers.results, gathers.per_step + gathers.results);
        for bounds in [&cuts[first], &cuts[second]] {
            assert!(
                bounds.windows(2).all(|w| w[0] < w[1]),
                "{parts} parts: {bounds:?}"
            );
        }
        assert!(
            cuts[first] != cuts[second],
            "{parts} parts: the cuts never moved"
        );
    }

    /// Four clusters of different widths (a deep, uneven tree), moved a little
    /// at each step.
    fn clusters(n: usize, step: usize) -> Vec<[f64; 3]> {
        let mut rng = Rng::new(23);
        let centres: Vec<([f64; 3], f64)> = (0..4)
            .map(|_| {
                let c = [rng.normal(), rng.normal(), rng.normal()];
                (c, 0.02 + 0.5 * rng.uniform())
            })
            .collect();
        (0..n)
            .map(|i| {
                let (c, w) = centres[i % 4];
                let shift = 0.01 * step as f64 * (i % 7) as f64;
                std::array::from_fn(|a| c[a] + w * rng.normal() + shift)
            })
            .collect()
    }

    #[test]
    fn divided_gravity_has_the_bits_of_one_evaluation() {
        let n = 6000;
        let law = GravityLaw::new(1.3, 0.01, 0.0).unwrap();
        let mass: Vec<f64> = (0..n).map(|i| 1.0 + (i % 5) as f64).collect();
        let params = TreeParams {
            theta: 0.6,
            group_size: 32,
            ..TreeParams::default()
        };
        for parts in [2, 3, 4] {
            divided_equals_whole(
                parts,
                TWO_GATHERS,
                3,
                || BarnesHut::new(law, params).unwrap(),
                |tree, step, share| {
                    let position = clusters(n, step);
                    let (mut acc, mut phi) = (vec![[0.0; 3]; n], vec![0.0; n]);
                    let sources = Sources {
                        mass: &mass,
                        position: &position,
                    };
                    let out = FieldOut {
                        acc: &mut acc,
                        phi: &mut phi,
                    };
                    tree.compute_shared(&sources, out, &Threads::single(), share);
                    let bits = acc
                        .as_flattened()
                        .iter()
                        .chain(&phi)
                        .map(|v| v.to_bits())
                        .collect();
                    (bits, tree.interactions())
                },
            );
        }
    }

    #[test]
    fn divided_vortex_tree_has_the_bits_of_one_evaluation() {
        let n = 5000;
        let kernel = BlobKernel::new(0.01);
        let gamma: Vec<f64> = (0..n).map(|i| ((i % 9) as f64 - 4.0) * 0.1).collect();
        let params = TreeParams {
            theta: 0.5,
            group_size: 32,
            ..TreeParams::default()
        };
        for parts in [2, 4] {
            divided_equals_whole(
                parts,
                TWO_GATHERS,
                3,
                || VortexTree::new(params, kernel).unwrap(),
                |tree, step, share| {
                    let x: Vec<[f64; 2]> = clusters(n, step).iter().map(|p| [p[0], p[1]]).collect();
                    let mut u = vec![[0.0; 2]; n];
                    // two threads: the parts need not run on one
                    tree.compute_shared(&x, &gamma, &mut u, &Threads::new(2).unwrap(), share);
                    let bits = u.as_flattened().iter().map(|v| v.to_bits()).collect();
                    (bits, tree.interactions())
                },
            );
        }
    }

    #[test]
    fn divided_3d_vortex_tree_has_the_bits_of_one_evaluation() {
        let n = 4000;
        let kernel = BlobKernel3::new(0.02);
        let alpha: Vec<[f64; 3]> = (0..n)
            .map(|i| {
                [
                    0.1 * (i % 5) as f64 - 0.2,
                    0.05,
                    0.1 - 0.03 * (i % 7) as f64,
                ]
            })
            .collect();
        let params = TreeParams {
            theta: 0.5,
            group_size: 32,
            ..VortexTree3::default_params()
        };
        for parts in [2, 3] {
            divided_equals_whole(
                parts,
                TWO_GATHERS,
                2,
                || VortexTree3::new(params, kernel).unwrap(),
                |tree, step, share| {
                    let x = clusters(n, step);
                    let (mut u, mut g) = (vec![[0.0; 3]; n], vec![[0.0; 9]; n]);
                    let threads = Threads::new(2).unwrap();
                    tree.compute_shared(&x, &alpha, &mut u, &mut g, &threads, share);
                    let bits = u
                        .as_flattened()
                        .iter()
                        .chain(g.as_flattened())
                        .map(|v| v.to_bits())
                        .collect();
                    (bits, tree.interactions())
                },
            );
        }
    }

    #[test]
    fn divided_vortex_fmm_has_the_bits_of_one_evaluation() {
        // about ten target groups
        let n = 40_000;
        let kernel = BlobKernel::new(0.01);
        let gamma: Vec<f64> = (0..n).map(|i| ((i % 9) as f64 - 4.0) * 0.1).collect();
        for parts in [2, 3] {
            divided_equals_whole(
                parts,
                FMM_GATHERS,
                2,
                || VortexFmm::new(kernel, FmmAccuracy::Tolerance(1e-6)).unwrap(),
                |fmm, step, share| {
                    let x: Vec<[f64; 2]> = clusters(n, step).iter().map(|p| [p[0], p[1]]).collect();
                    let mut u = vec![[0.0; 2]; n];
                    fmm.compute_shared(&x, &gamma, &mut u, &Threads::new(2).unwrap(), share);
                    let bits = u.as_flattened().iter().map(|v| v.to_bits()).collect();
                    (bits, fmm.interactions())
                },
            );
        }
    }

    #[test]
    fn divided_3d_vortex_fmm_has_the_bits_of_one_evaluation() {
        // a few target groups, and the blob rest's cell layers
        let n = 30_000;
        let kernel = BlobKernel3::new(0.03);
        let alpha: Vec<[f64; 3]> = (0..n)
            .map(|i| {
                [
                    0.1 * (i % 5) as f64 - 0.2,
                    0.05,
                    0.1 - 0.03 * (i % 7) as f64,
                ]
            })
            .collect();
        for parts in [2, 3] {
            divided_equals_whole(
                parts,
                // the fmm's gathers, then the blob rest's sums
                Gathers {
                    per_step: FMM_GATHERS.per_step + 1,
                    results: 1,
                },
                2,
                || VortexFmm3::new(kernel, FmmAccuracy::Tolerance(1e-3)).unwrap(),
                |fmm, step, share| {
                    let x = clusters(n, step);
                    let (mut u, mut g) = (vec![[0.0; 3]; n], vec![[0.0; 9]; n]);
                    let threads = Threads::new(2).unwrap();
                    fmm.compute_shared(&x, &alpha, &mut u, &mut g, &threads, share);
                    let bits = u
                        .as_flattened()
                        .iter()
                        .chain(g.as_flattened())
                        .map(|v| v.to_bits())
                        .collect();
                    (bits, fmm.interactions())
                },
            );
        }
    }

    /// The 2D fmm divided through [`AmongPeers`] over thread-ranks (the
    /// engine's exchange, as in an MPI run): every rank gets the bits of one
    /// evaluation, at the first evaluation and after the costs moved the cuts.
    #[test]
    fn an_fmm_among_peers_has_the_bits_of_one_evaluation() {
        let n = 20_000;
        let kernel = BlobKernel::new(0.01);
        let gamma: Vec<f64> = (0..n).map(|i| ((i % 7) as f64 - 3.0) * 0.1).collect();
        let new = || VortexFmm::new(kernel, FmmAccuracy::Tolerance(1e-6)).unwrap();
        let evaluate = |fmm: &mut VortexFmm<BlobKernel>, share: &mut dyn Share, step| {
            let x: Vec<[f64; 2]> = clusters(n, step).iter().map(|p| [p[0], p[1]]).collect();
            let mut u = vec![[0.0; 2]; n];
            fmm.compute_shared(&x, &gamma, &mut u, &Threads::new(2).unwrap(), share);
            u.as_flattened()
                .iter()
                .map(|v| v.to_bits())
                .collect::<Vec<u64>>()
        };
        let mut whole = new();
        let want: Vec<Vec<u64>> = (0..2)
            .map(|step| evaluate(&mut whole, &mut Whole, step))
            .collect();
        for ranks in [2, 3] {
            let got = Hub::run(ranks, |exchange| {
                let (mut fmm, mut share) = (new(), AmongPeers::new(exchange));
                (0..2)
                    .map(|step| evaluate(&mut fmm, &mut share, step))
                    .collect::<Vec<_>>()
            });
            for (rank, bits) in got.iter().enumerate() {
                assert!(*bits == want, "rank {rank} of {ranks}");
            }
        }
    }
}
