//! The kernel-independent part of the fast multipole method: the tree, the
//! upward pass (P2M at the leaves, M2M to the root), and per target group a
//! dual-tree traversal that hands each pair of boxes to M2L, to M2P and P2L
//! (a leaf and a smaller box, if the kernel has them) or to the pair sums,
//! then L2L and L2P down the group's subtree. The expansions and the
//! pair law come from an [`Expansions`] implementation.

use super::super::build::{Node, Octree, Sizes};
use super::super::share::{Costs, Share, Split};
use crate::threads::{DisjointSlice, Threads};
use rayon::prelude::*;
use rustfft::num_complex::Complex64;
use std::ops::Range;
use std::sync::Mutex;

/// A box as the expansions see it: its centre and radius (half the
/// diagonal of its square or cube), which scales its expansions.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Cube {
    pub centre: [f64; 3],
    pub radius: f64,
}

impl Cube {
    /// The cube of an octree node: its centre and half its diagonal.
    pub fn around(node: &Node) -> Self {
        Cube {
            centre: node.corner.map(|c| c + 0.5 * node.side),
            radius: node.side * 0.5 * 3f64.sqrt(),
        }
    }
}

/// `shifted[i] = positions[i] - c`, `c` the middle of the points' bounding
/// box (the origin if it is not finite), so that the boxes' centres are
/// rounded at the scale of the system, not of its distance from the origin
/// (the turns of M2L follow the boxes' exact grid directions); a field that
/// depends on separations only does not change under the shift.
pub(super) fn shift_to_middle(positions: &[[f64; 3]], shifted: &mut Vec<[f64; 3]>) {
    let (low, high) = positions.iter().fold(
        ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]),
        |(lo, hi), x| {
            (
                std::array::from_fn(|a| lo[a].min(x[a])),
                std::array::from_fn(|a| hi[a].max(x[a])),
            )
        },
    );
    let middle: [f64; 3] = std::array::from_fn(|a| 0.5 * (low[a] + high[a]));
    let middle = middle.map(|m| if m.is_finite() { m } else { 0.0 });
    shifted.clear();
    shifted.extend(
        positions
            .iter()
            .map(|x| std::array::from_fn(|a| x[a] - middle[a])),
    );
}

/// How two leaves meet pair by pair.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Pairs {
    /// Two different leaves: each pair once, its sum added to both
    /// particles.
    Both,
    /// A leaf with itself.
    Within,
}

impl Pairs {
    /// The pair terms that `targets` particles of a leaf meet `sources` of
    /// another (or, [`Pairs::Within`], of the same) in this way: a pair
    /// summed at both its particles counts twice, a particle with itself not
    /// at all.
    pub fn terms(self, targets: usize, sources: usize) -> u64 {
        let n = (targets * sources) as u64;
        match self {
            Pairs::Both => 2 * n,
            Pairs::Within => n - sources as u64,
        }
    }
}

/// The expansions and pair law of one kernel, on particles that it holds in
/// the tree's order.
pub(super) trait Expansions: Sync {
    /// What a target particle's sum holds: [`WIDTH`](Self::WIDTH) numbers.
    type Sum: Copy + Default + Send + Sync;
    /// Numbers in a [`Sum`](Self::Sum).
    const WIDTH: usize;
    /// What a thread keeps for the expansions and the pair sums.
    type Scratch: Default + Send;
    /// Two boxes interact through their expansions when
    /// `2 max(s_T, s_S) <= THETA d` (and their gap is at least
    /// [`reach`](Self::reach)).
    const THETA: f64;
    /// The tree's sizes for `n` particles: most particles in a leaf and in
    /// a target group (the groups are summed in parallel, and each
    /// particle's sums do not depend on how they are grouped up to
    /// rounding, nor on the threads).
    fn sizes(n: usize) -> Sizes;
    /// How many particles the leaves of a uniform cloud should hold, if the
    /// root is to be grown for it (see [`stretch`]); `None` keeps the
    /// bounding cube.
    const FILL: Option<usize>;

    /// Complex coefficients per expansion.
    fn terms(&self) -> usize;
    /// The gap below which two boxes meet pair by pair whatever their
    /// sizes: where the pair law is not yet the expansions' law within the
    /// tolerance.
    fn reach(&self) -> f64;
    /// The box of `node`.
    fn cube(&self, node: &Node) -> Cube;
    /// P2M: adds the multipole of the sorted particles `particles` about
    /// `cube` to `multipole`.
    fn p2m(
        &self,
        particles: Range<usize>,
        cube: Cube,
        multipole: &mut [Complex64],
        scratch: &mut Self::Scratch,
    );
    /// M2M: adds the child's multipole (about `from`) shifted to `to`.
    fn m2m(
        &self,
        child: &[Complex64],
        from: Cube,
        parent: &mut [Complex64],
        to: Cube,
        scratch: &mut Self::Scratch,
    );
    /// M2L of a target group: adds to the local of each of the group's boxes
    /// `t` (`locals`, [`terms`](Self::terms) per box, box `group` first) the
    /// local expansions of the multipoles of its sources,
    /// `sources[starts[t - group]..starts[t - group + 1]]` (in the order the
    /// traversal met them; `multipoles` holds every box's, `cubes` their
    /// boxes), in an order fixed by the boxes.
    #[allow(clippy::too_many_arguments)]
    fn m2l(
        &self,
        multipoles: &[Complex64],
        cubes: &[Cube],
        group: usize,
        starts: &[usize],
        sources: &[u32],
        locals: &mut [Complex64],
        scratch: &mut Self::Scratch,
    );
    /// L2L: adds the parent's local (about `from`) shifted to `to`.
    fn l2l(
        &self,
        parent: &[Complex64],
        from: Cube,
        child: &mut [Complex64],
        to: Cube,
        scratch: &mut Self::Scratch,
    );
    /// L2P: adds the local about `cube` at the sorted particles
    /// `particles` to their sums `out` (the particles' own, in order).
    #[allow(clippy::too_many_arguments)]
    fn l2p(
        &self,
        local: &[Complex64],
        cube: Cube,
        particles: Range<usize>,
        out: &mut [Self::Sum],
        scratch: &mut Self::Scratch,
    );
    /// The W and X lists of the adaptive FMM, if the kernel has them
    /// (`Some((rho, least))`): a leaf `L` and a smaller box `B` of at least
    /// `least` particles whose radii and centres' distance `d` satisfy
    /// `s_B <= rho (d - s_L)` (and whose gap is at least the
    /// [`reach`](Self::reach)) meet by `B`'s multipole at `L`'s particles
    /// ([`m2p`](Self::m2p)) and `L`'s particles into `B`'s local
    /// ([`p2l`](Self::p2l)) instead of pair by pair: both expansions
    /// converge as `rho^(p + 1)` at least.
    fn near_expansions(&self) -> Option<(f64, usize)> {
        None
    }
    /// M2P: adds the multipole about `cube` at the sorted particles
    /// `particles` to their sums `out` (the particles' own, in order). Asked
    /// only of a kernel with [`near_expansions`](Self::near_expansions).
    fn m2p(
        &self,
        _multipole: &[Complex64],
        _cube: Cube,
        _particles: Range<usize>,
        _out: &mut [Self::Sum],
        _scratch: &mut Self::Scratch,
    ) {
        unreachable!("M2P of a kernel without near expansions")
    }
    /// P2L: adds the sorted particles `particles` to the local about
    /// `cube`. Asked only of a kernel with
    /// [`near_expansions`](Self::near_expansions).
    fn p2l(
        &self,
        _particles: Range<usize>,
        _cube: Cube,
        _local: &mut [Complex64],
        _scratch: &mut Self::Scratch,
    ) {
        unreachable!("P2L of a kernel without near expansions")
    }
    /// What one M2L costs, in pair terms of the near field (measured for
    /// each kernel): the weight that balances the parts of a divided
    /// evaluation.
    fn m2l_cost(&self) -> f64;
    /// The numbers of `sums`, sum after sum.
    fn numbers(sums: &mut [Self::Sum]) -> &mut [f64];
    /// The pair sums of the source particles at the target particles (sorted
    /// ranges), each pair once: added to `mine`, the targets' sums in
    /// order, and the reactions to `theirs`, the sources' sums in order
    /// (for [`Pairs::Within`], where the two are one leaf, to `mine`;
    /// `theirs` is then empty). Returns the pair terms computed (a pair
    /// summed at both its particles counts twice).
    fn pairs(
        &self,
        how: Pairs,
        targets: Range<usize>,
        sources: Range<usize>,
        mine: &mut [Self::Sum],
        theirs: &mut [Self::Sum],
        scratch: &mut Self::Scratch,
    ) -> u64;
}

/// The tree, the multipoles and the per-thread scratch of an FMM, kept
/// between evaluations.
#[derive(Debug)]
pub(super) struct Engine<E: Expansions> {
    pub tree: Octree,
    cubes: Vec<Cube>,
    /// [`Expansions::terms`] per node, node after node.
    multipoles: Vec<Complex64>,
    /// The sums in tree order.
    pub sorted: Vec<E::Sum>,
    scratch: Vec<Mutex<Scratch<E>>>,
    /// Per own group of the last evaluation, its `(M2L, M2P and P2L, pair)`
    /// counts.
    counts: Vec<(u64, u64, u64)>,
    /// Per own group, the reactions of its pairs with later groups' leaves.
    crossings: Vec<Crossing<E>>,
    /// In a divided evaluation, the reactions of every part's groups, part
    /// after part: per leaf of a [`Crossing`], its node and its particles'
    /// sums (one process adds its crossings' directly).
    records: Vec<f64>,
    /// This process's part of `records`, while they are gathered.
    own_records: Vec<f64>,
    /// `(box, particle pair)` interactions of the last evaluation (M2L, M2P
    /// and P2L; of this process's part of the groups, for a divided
    /// evaluation).
    pub interactions: (u64, u64),
    /// The M2P and P2L among [`interactions`](Self::interactions)' boxes.
    pub near: u64,
    /// Per particle, its weight in the next divided evaluation's [`Split`]:
    /// `1 +` its group's pair terms and M2L, M2P and P2L (each
    /// [`Expansions::m2l_cost`] pair terms) per particle.
    costs: Costs,
}

impl<E: Expansions> Default for Engine<E> {
    fn default() -> Self {
        Engine {
            tree: Octree::default(),
            cubes: Vec::new(),
            multipoles: Vec::new(),
            sorted: Vec::new(),
            scratch: Vec::new(),
            counts: Vec::new(),
            crossings: Vec::new(),
            records: Vec::new(),
            own_records: Vec::new(),
            interactions: (0, 0),
            near: 0,
            costs: Costs::default(),
        }
    }
}

impl<E: Expansions> Engine<E> {
    /// Sorts `positions` into the tree (whose `order` the kernel then
    /// arranges its particles by).
    pub fn build(&mut self, positions: &[[f64; 3]], threads: &Threads) {
        let stretch = E::FILL.map_or(1.0, |fill| stretch(positions.len(), fill));
        let sizes = E::sizes(positions.len());
        self.tree
            .build_stretched(positions, sizes, stretch, threads);
    }

    /// The sums of every particle, in tree order, into `sorted`: the upward
    /// pass, then every target group in parallel. Divided by `share`
    /// among processes that hold the same particles: each makes the whole
    /// upward pass, then the groups of its part ([`Split`], balanced by the
    /// last evaluation's pair terms and M2L), and receives the other
    /// parts' sums and reactions. A group's sums and its reactions at later
    /// groups' leaves depend only on the tree and the multipoles, and the
    /// reactions are added group after group, so every particle gets the
    /// bits of the undivided evaluation.
    pub fn evaluate(&mut self, kernel: &E, threads: &Threads, share: &mut dyn Share) {
        self.cubes.clear();
        self.cubes
            .extend(self.tree.nodes.iter().map(|node| kernel.cube(node)));
        self.upward(kernel, threads);
        self.downward(kernel, threads, share);
    }

    /// P2M at the leaves (in parallel), then M2M from the children up, last
    /// node first (children follow their parent).
    fn upward(&mut self, kernel: &E, threads: &Threads) {
        let terms = kernel.terms();
        let nodes = &self.tree.nodes;
        self.multipoles.clear();
        self.multipoles
            .resize(nodes.len() * terms, Complex64::new(0.0, 0.0));
        while self.scratch.len() < threads.count() {
            self.scratch.push(Mutex::new(Scratch::default()));
        }
        let (cubes, scratch) = (&self.cubes, &self.scratch);
        threads.install(|| {
            self.multipoles
                .par_chunks_mut(terms)
                .zip(nodes.par_iter())
                .zip(cubes.par_iter())
                .filter(|((_, node), _)| node.leaf)
                .for_each(|((a, node), cube)| {
                    let mut scratch = lock(scratch);
                    let particles = node.start as usize..node.end as usize;
                    kernel.p2m(particles, *cube, a, &mut scratch.kernel)
                })
        });
        // (sequential, outside the pool: the first thread's scratch)
        let mut scratch = scratch[0].lock().expect("scratch of a panicked pass");
        for k in (0..nodes.len()).rev() {
            if nodes[k].leaf {
                continue;
            }
            let (parent, below) = self.multipoles.split_at_mut((k + 1) * terms);
            let parent = &mut parent[k * terms..];
            for child in self.tree.children(k) {
                let offset = (child - k - 1) * terms;
                let child_terms = &below[offset..offset + terms];
                kernel.m2m(
                    child_terms,
                    cubes[child],
                    parent,
                    cubes[k],
                    &mut scratch.kernel,
                );
            }
        }
    }

    /// The target groups of this process's part in parallel: each one's
    /// traversal, then L2L and L2P within it, writing its particles' sums
    /// and keeping the reactions of its pairs with later groups' leaves;
    /// then the other parts' sums (and the groups' costs) gathered, and
    /// every group's reactions added, group after group.
    fn downward(&mut self, kernel: &E, threads: &Threads, share: &mut dyn Share) {
        let n = self.tree.order.len();
        self.sorted.clear();
        self.sorted.resize(n, E::Sum::default());
        let (part, parts) = share.part();
        let split = Split::new(&self.tree, self.costs.input(), parts);
        let own = split.groups[part]..split.groups[part + 1];
        if self.crossings.len() < own.len() {
            self.crossings.resize_with(own.len(), Crossing::default);
        }
        let (mut sorted, mut counts, mut crossings) = (
            std::mem::take(&mut self.sorted),
            std::mem::take(&mut self.counts),
            std::mem::take(&mut self.crossings),
        );
        let shared = DisjointSlice::new(&mut sorted);
        let kept = DisjointSlice::new(&mut crossings);
        let this = &*self;
        threads.install(|| {
            this.tree.groups[own.clone()]
                .par_iter()
                .enumerate()
                .map(|(k, &g)| {
                    let mut scratch = lock(&this.scratch);
                    let node = &this.tree.nodes[g as usize];
                    // SAFETY: groups hold disjoint ranges of the sorted
                    // particles, and each its own crossing.
                    let (out, crossing) = unsafe {
                        (
                            shared.range(node.start as usize..node.end as usize),
                            kept.get(k),
                        )
                    };
                    this.group(kernel, g as usize, &mut scratch, out, crossing)
                })
                .collect_into_vec(&mut counts)
        });
        (self.sorted, self.counts, self.crossings) = (sorted, counts, crossings);
        let (far, near, pairs) = self
            .counts
            .iter()
            .fold((0, 0, 0), |a, b| (a.0 + b.0, a.1 + b.1, a.2 + b.2));
        (self.interactions, self.near) = ((far + near, pairs), near);
        if parts > 1 {
            // (an M2P or P2L weighed as an M2L)
            let m2l = kernel.m2l_cost();
            let work = self
                .counts
                .iter()
                .map(|&(far, near, pairs)| pairs as f64 + m2l * (far + near) as f64);
            self.costs.gather(&self.tree, &split, part, work, share);
        }
        let numbers = E::numbers(&mut self.sorted);
        debug_assert_eq!(numbers.len(), n * E::WIDTH);
        share.all_gather(numbers, E::WIDTH, &split.particles);
        if parts == 1 {
            let numbers = E::numbers(&mut self.sorted);
            for crossing in &mut self.crossings[..own.len()] {
                let sums = E::numbers(&mut crossing.sums);
                for &(leaf, at) in &crossing.leaves {
                    add_reactions::<E>(&self.tree, leaf as usize, &sums[at * E::WIDTH..], numbers);
                }
            }
        } else {
            self.gather_records(own.len(), share);
            let numbers = E::numbers(&mut self.sorted);
            let mut at = 0;
            while at < self.records.len() {
                let leaf = self.records[at] as usize;
                let values = &self.records[at + 1..];
                at += 1 + add_reactions::<E>(&self.tree, leaf, values, numbers);
            }
        }
    }

    /// Into `records`, the reactions of every part's groups, part after
    /// part (this process's: its first `own` crossings): per leaf of a
    /// [`Crossing`], its node and its particles' sums.
    fn gather_records(&mut self, own: usize, share: &mut dyn Share) {
        let (part, parts) = share.part();
        let mine = &mut self.own_records;
        mine.clear();
        for crossing in &mut self.crossings[..own] {
            let sums = E::numbers(&mut crossing.sums);
            for &(leaf, at) in &crossing.leaves {
                let node = &self.tree.nodes[leaf as usize];
                let len = (node.end - node.start) as usize * E::WIDTH;
                mine.push(leaf as f64);
                mine.extend_from_slice(&sums[at * E::WIDTH..][..len]);
            }
        }
        // each part's count, then the records themselves
        let mut bounds: Vec<usize> = (0..=parts).collect();
        self.records.clear();
        self.records.resize(parts, 0.0);
        self.records[part] = self.own_records.len() as f64;
        share.all_gather(&mut self.records, 1, &bounds);
        let counts: Vec<usize> = self.records.iter().map(|&c| c as usize).collect();
        for k in 0..parts {
            bounds[k + 1] = bounds[k] + counts[k];
        }
        self.records.clear();
        self.records.resize(bounds[parts], 0.0);
        self.records[bounds[part]..bounds[part + 1]].copy_from_slice(&self.own_records);
        share.all_gather(&mut self.records, 1, &bounds);
    }

    /// The sums of group `g`'s particles into `out`: the traversal of the
    /// tree from `(root, root)` along the boxes that hold the group (its
    /// pair sums and M2P as it meets them), the M2L of each of the group's
    /// boxes (its sources in the order the traversal met them), the P2L in
    /// that order, then the locals down the group's subtree and out at its
    /// leaves; the reactions of its pairs with later groups' leaves into
    /// `crossing`. Returns its `(M2L, M2P and P2L, pair)` counts.
    fn group(
        &self,
        kernel: &E,
        g: usize,
        scratch: &mut Scratch<E>,
        out: &mut [E::Sum],
        crossing: &mut Crossing<E>,
    ) -> (u64, u64, u64) {
        let terms = kernel.terms();
        let nodes = &self.tree.nodes;
        let end = nodes[g].next as usize;
        let Scratch {
            locals,
            far,
            p2l,
            sources,
            starts,
            next,
            slots,
            kernel: own,
        } = scratch;
        far.clear();
        p2l.clear();
        crossing.leaves.clear();
        crossing.sums.clear();
        slots.resize(nodes.len(), NO_SLOT);
        let mut walk = Traversal {
            engine: self,
            kernel,
            group: g,
            end,
            reach: kernel.reach(),
            near: kernel.near_expansions(),
            far: &mut *far,
            p2l: &mut *p2l,
            m2p: 0,
            scratch: &mut *own,
            out: &mut *out,
            crossing: &mut *crossing,
            slots: &mut *slots,
            pairs: 0,
        };
        walk.interact(0, 0);
        let (pair_count, m2p) = (walk.pairs, walk.m2p);
        for &(leaf, _) in &crossing.leaves {
            slots[leaf as usize] = NO_SLOT;
        }
        // the far pairs bucketed by target box, in the order they were met
        starts.clear();
        starts.resize(end - g + 1, 0);
        for &(t, _) in far.iter() {
            starts[t as usize - g + 1] += 1;
        }
        for k in 1..starts.len() {
            starts[k] += starts[k - 1];
        }
        sources.clear();
        sources.resize(far.len(), 0);
        next.clear();
        next.extend_from_slice(starts);
        for &(t, s) in far.iter() {
            let slot = &mut next[t as usize - g];
            sources[*slot] = s;
            *slot += 1;
        }
        locals.clear();
        locals.resize((end - g) * terms, Complex64::new(0.0, 0.0));
        let (m, c) = (&self.multipoles, &self.cubes);
        kernel.m2l(m, c, g, starts, sources, locals, own);
        for &(t, s) in p2l.iter() {
            let (t, source) = (t as usize, &nodes[s as usize]);
            let local = &mut locals[(t - g) * terms..(t - g + 1) * terms];
            let particles = source.start as usize..source.end as usize;
            kernel.p2l(particles, self.cubes[t], local, own);
        }
        let first = nodes[g].start as usize;
        for k in g..end {
            let (mine, below) = locals.split_at_mut((k - g + 1) * terms);
            let local = &mine[(k - g) * terms..];
            let node = &nodes[k];
            if node.leaf {
                let range = node.start as usize..node.end as usize;
                let mine = &mut out[range.start - first..range.end - first];
                kernel.l2p(local, self.cubes[k], range, mine, own);
                continue;
            }
            for child in self.tree.children(k) {
                let offset = (child - k - 1) * terms;
                let child_terms = &mut below[offset..offset + terms];
                kernel.l2l(local, self.cubes[k], child_terms, self.cubes[child], own);
            }
        }
        (far.len() as u64, p2l.len() as u64 + m2p, pair_count)
    }
}

/// The factor `2^L / k` in `[1, 2)` by which the bounding cube is grown about
/// its centre, `k` the least even number with `k^3 fill >= n` and `2^L` the
/// least power of two `>= k` (1 for `n <= fill`): the cubes of level `L` are
/// then `1 / k` of the bounding cube, so a uniform cloud of `n` particles
/// fills `k` of them along each axis exactly (`(2^L - k) / 2` empty ones on
/// either side, a whole number), with `n / k^3 <= fill` particles in each
/// on average. The bounding cube alone gives its leaves anything from an
/// eighth of the leaf size to all of it, depending on `n`, and a cloud whose
/// edges cut through layers of cubes leaves those layers' leaves partly
/// empty: at 10^6 uniform bodies (order 16) the growth that gave about 200
/// per cube (17.1 cubes along an axis, centred, so the two outer layers
/// each about half full) took 4.41 s where 18 whole layers (171 per cube)
/// take 3.99 s (3 rounds, both on the two cores at once).
fn stretch(n: usize, fill: usize) -> f64 {
    assert!(fill > 0, "a cube holds at least one particle");
    if n <= fill {
        return 1.0;
    }
    let mut k = 2usize;
    while k.pow(3) * fill < n {
        k += 2;
    }
    k.next_power_of_two() as f64 / k as f64
}

/// Adds the reactions `values` (from their start on) to the sums of leaf
/// `leaf`'s particles in `sorted` (the sums' numbers); returns how many
/// numbers it took.
fn add_reactions<E: Expansions>(
    tree: &Octree,
    leaf: usize,
    values: &[f64],
    sorted: &mut [f64],
) -> usize {
    let node = &tree.nodes[leaf];
    let range = node.start as usize * E::WIDTH..node.end as usize * E::WIDTH;
    for (sum, r) in sorted[range.clone()].iter_mut().zip(values) {
        *sum += r;
    }
    range.len()
}

/// A leaf without a slot in the running group's [`Crossing`].
const NO_SLOT: u32 = u32::MAX;

/// The reactions of one group's pairs with the leaves of later groups: per
/// such leaf (in the order the traversal first met it) its node and where
/// its particles' sums start in `sums`, each summed over the group's
/// leaves in the traversal's order.
struct Crossing<E: Expansions> {
    leaves: Vec<(u32, usize)>,
    sums: Vec<E::Sum>,
}

impl<E: Expansions> Default for Crossing<E> {
    fn default() -> Self {
        Crossing {
            leaves: Vec::new(),
            sums: Vec::new(),
        }
    }
}

impl<E: Expansions> std::fmt::Debug for Crossing<E> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Crossing")
            .field("leaves", &self.leaves.len())
            .finish()
    }
}

/// The scratch of the running thread.
fn lock<E: Expansions>(scratch: &[Mutex<Scratch<E>>]) -> std::sync::MutexGuard<'_, Scratch<E>> {
    let thread = rayon::current_thread_index().unwrap_or(0);
    scratch[thread]
        .lock()
        .expect("scratch of a panicked traversal")
}

/// What a thread keeps between its groups: the locals of a group's subtree,
/// its far pairs (as met, then bucketed by target) and the kernel's pair
/// scratch.
struct Scratch<E: Expansions> {
    locals: Vec<Complex64>,
    far: Vec<(u32, u32)>,
    /// The group's P2L `(target box, source leaf)`, as met.
    p2l: Vec<(u32, u32)>,
    sources: Vec<u32>,
    starts: Vec<usize>,
    /// The next free slot of each target box while bucketing.
    next: Vec<usize>,
    /// Per node, its index in the running group's [`Crossing`] leaves (or
    /// [`NO_SLOT`]).
    slots: Vec<u32>,
    kernel: E::Scratch,
}

impl<E: Expansions> Default for Scratch<E> {
    fn default() -> Self {
        Scratch {
            locals: Vec::new(),
            far: Vec::new(),
            p2l: Vec::new(),
            sources: Vec::new(),
            starts: Vec::new(),
            next: Vec::new(),
            slots: Vec::new(),
            kernel: E::Scratch::default(),
        }
    }
}

impl<E: Expansions> std::fmt::Debug for Scratch<E> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Scratch")
            .field("locals", &self.locals.len())
            .field("far", &self.far.len())
            .field("p2l", &self.p2l.len())
            .finish()
    }
}

/// One group's traversal: the far pairs and P2L it finds, its particles'
/// pair sums and M2P, and the reactions of its pairs with later groups'
/// leaves.
struct Traversal<'a, E: Expansions> {
    engine: &'a Engine<E>,
    kernel: &'a E,
    /// The group's node and the first node after its subtree.
    group: usize,
    end: usize,
    reach: f64,
    /// The kernel's [`Expansions::near_expansions`].
    near: Option<(f64, usize)>,
    far: &'a mut Vec<(u32, u32)>,
    p2l: &'a mut Vec<(u32, u32)>,
    /// The M2P made so far.
    m2p: u64,
    scratch: &'a mut E::Scratch,
    out: &'a mut [E::Sum],
    crossing: &'a mut Crossing<E>,
    slots: &'a mut Vec<u32>,
    pairs: u64,
}

impl<E: Expansions> Traversal<'_, E> {
    /// Box `t` (in the group, or one of the boxes that hold it) against
    /// source box `s`, as the traversal of the whole tree from `(root,
    /// root)` meets them: a far pair when they are apart, M2P at a leaf or
    /// P2L from it when a leaf and a smaller box are apart for those
    /// ([`Expansions::near_expansions`], the W and X lists), pair sums when
    /// both are leaves, else the larger one split (a leaf is never split;
    /// two boxes of one size are split both), a box that holds the group
    /// into its child that holds it. The rule is the same with the roles
    /// swapped, so that leaves `t` and `s` meet when `s` and `t` do,
    /// whichever groups they are in: the first of two leaves of the group
    /// takes both sides, and of two groups the earlier one. A far pair of a
    /// box that holds the group is the group's: the group's box is no
    /// larger and no nearer to the source's edge, so its expansions
    /// converge at least as fast.
    fn interact(&mut self, t: usize, s: usize) {
        let nodes = &self.engine.tree.nodes;
        let (target, source) = (&nodes[t], &nodes[s]);
        let overlap = target.start < source.end && source.start < target.end;
        if !overlap && self.apart(t, s) {
            self.far.push((t.max(self.group) as u32, s as u32));
            return;
        }
        if !overlap {
            match self.near_expansion(t, s) {
                Some(true) => return self.m2p(t, s),
                Some(false) => return self.p2l.push((t.max(self.group) as u32, s as u32)),
                None => {}
            }
        }
        match (target.leaf, source.leaf) {
            (true, true) => self.leaves(t, s),
            (true, false) => self.each_child(s, |walk, c| walk.interact(t, c)),
            (false, true) => self.each_target(t, |walk, c| walk.interact(c, s)),
            (false, false) => {
                if source.side > target.side {
                    self.each_child(s, |walk, c| walk.interact(t, c))
                } else if target.side > source.side {
                    self.each_target(t, |walk, c| walk.interact(c, s))
                } else {
                    self.each_target(t, |walk, ct| {
                        walk.each_child(s, |walk, cs| walk.interact(ct, cs))
                    })
                }
            }
        }
    }

    /// `visit(self, child)` for every child of node `k`, in order.
    fn each_child(&mut self, k: usize, mut visit: impl FnMut(&mut Self, usize)) {
        let engine = self.engine;
        for child in engine.tree.children(k) {
            visit(self, child);
        }
    }

    /// [`each_child`](Self::each_child) of target box `k`: of a box that
    /// holds the group, only the child that holds it.
    fn each_target(&mut self, k: usize, mut visit: impl FnMut(&mut Self, usize)) {
        if k >= self.group {
            return self.each_child(k, visit);
        }
        let nodes = &self.engine.tree.nodes;
        let towards = self
            .engine
            .tree
            .children(k)
            .find(|&c| c <= self.group && self.group < nodes[c].next as usize)
            .expect("a box above the group holds it in a child");
        visit(self, towards);
    }

    /// Whether boxes `t` and `s` are well apart: `2 max(s_T, s_S) <= THETA d`
    /// and a gap of at least the law's reach.
    fn apart(&self, t: usize, s: usize) -> bool {
        let (a, b) = (self.engine.cubes[t], self.engine.cubes[s]);
        let d = [
            a.centre[0] - b.centre[0],
            a.centre[1] - b.centre[1],
            a.centre[2] - b.centre[2],
        ];
        let d2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
        let larger = 2.0 * a.radius.max(b.radius);
        // (the radii added first: the same bits with the roles swapped)
        larger * larger <= E::THETA * E::THETA * d2
            && d2.sqrt() - (a.radius + b.radius) >= self.reach
    }

    /// Whether boxes `t` and `s` meet by M2P and P2L (the kernel's
    /// [`near_expansions`](Expansions::near_expansions)), and if so whether
    /// `t` is the leaf (`true`: M2P at it) or `s` (P2L from it). The same
    /// with the roles swapped.
    fn near_expansion(&self, t: usize, s: usize) -> Option<bool> {
        let (rho, least) = self.near?;
        let (a, b) = (self.engine.cubes[t], self.engine.cubes[s]);
        let (leaf, other) = if a.radius > b.radius {
            (t, s)
        } else if b.radius > a.radius {
            (s, t)
        } else {
            return None;
        };
        let nodes = &self.engine.tree.nodes;
        if !nodes[leaf].leaf || ((nodes[other].end - nodes[other].start) as usize) < least {
            return None;
        }
        let d = [
            a.centre[0] - b.centre[0],
            a.centre[1] - b.centre[1],
            a.centre[2] - b.centre[2],
        ];
        let d = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        let (large, small) = (a.radius.max(b.radius), a.radius.min(b.radius));
        (small <= rho * (d - large) && d - (a.radius + b.radius) >= self.reach).then_some(leaf == t)
    }

    /// M2P of source box `s`'s multipole at the particles of leaf `t` of the
    /// group.
    fn m2p(&mut self, t: usize, s: usize) {
        let engine = self.engine;
        let terms = self.kernel.terms();
        let (node, first) = (&engine.tree.nodes[t], engine.tree.nodes[self.group].start);
        let range = node.start as usize..node.end as usize;
        debug_assert!(
            (self.group..self.end).contains(&t),
            "M2P at the group's leaves"
        );
        let out = &mut self.out[range.start - first as usize..range.end - first as usize];
        let multipole = &engine.multipoles[s * terms..(s + 1) * terms];
        self.kernel
            .m2p(multipole, engine.cubes[s], range, out, self.scratch);
        self.m2p += 1;
    }

    /// Leaf `t` of the group against leaf `s`: each pair once, by the
    /// first of two leaves of the group, or by the earlier of two groups
    /// (the reactions at a later group's leaf kept in the crossing).
    fn leaves(&mut self, t: usize, s: usize) {
        let nodes = &self.engine.tree.nodes;
        let first = nodes[self.group].start as usize;
        let targets = nodes[t].start as usize..nodes[t].end as usize;
        let sources = nodes[s].start as usize..nodes[s].end as usize;
        let mine = targets.start - first..targets.end - first;
        let (how, mine, theirs) = if s < self.group || (s < self.end && s < t) {
            // an earlier group, or the earlier leaf of this one, took both sides
            return;
        } else if s >= self.end {
            let slot = self.slots[s] as usize;
            let at = if slot == NO_SLOT as usize {
                let at = self.crossing.sums.len();
                self.slots[s] = self.crossing.leaves.len() as u32;
                self.crossing.leaves.push((s as u32, at));
                self.crossing
                    .sums
                    .resize(at + sources.len(), E::Sum::default());
                at
            } else {
                self.crossing.leaves[slot].1
            };
            let theirs = &mut self.crossing.sums[at..at + sources.len()];
            (Pairs::Both, &mut self.out[mine], theirs)
        } else if s == t {
            (Pairs::Within, &mut self.out[mine], &mut [][..])
        } else {
            // t < s: the target's particles come first
            let (low, high) = self.out.split_at_mut(sources.start - first);
            (Pairs::Both, &mut low[mine], &mut high[..sources.len()])
        };
        self.pairs += self
            .kernel
            .pairs(how, targets, sources, mine, theirs, self.scratch);
    }
}

#[cfg(test)]
mod tests {
    use super::stretch;

    /// The grown root's cubes of level `L` are `1 / k` of the bounding cube,
    /// `k` the least even number with at most `fill` particles per cube on
    /// average.
    #[test]
    fn the_stretch_fills_whole_layers() {
        assert_eq!(stretch(100, 200), 1.0);
        assert_eq!(stretch(200, 200), 1.0);
        assert_eq!(stretch(1600, 200), 1.0);
        for (n, k) in [
            (1601, 4),
            (100_000, 8),
            (102_401, 10),
            (300_000, 12),
            (1_000_000, 18),
            (4_000_000, 28),
        ] {
            let s = stretch(n, 200);
            assert!((1.0..2.0).contains(&s), "{n}: {s}");
            let per_side = (k as f64).log2().ceil().exp2() / s;
            assert!((per_side - k as f64).abs() < 1e-12, "{n}: {per_side}");
            assert!(n <= 200 * k * k * k && n > 200 * (k - 2).pow(3), "{n}");
        }
    }
}
