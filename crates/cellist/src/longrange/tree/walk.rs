//! What both kernels share: the particles in tree order, every node as the walk
//! sees it (expansion centre and opening distance), the walk that lists a
//! group's accepted nodes and opened leaves, the copy of those lists into padded
//! lanes, the group particles as SIMD targets, and the solver state with its
//! evaluation (build, sort, node moments, then the groups in parallel, each with
//! its thread's scratch, writing only its own particles). A kernel supplies its
//! node moments and its list sums.

use super::build::{Node, Octree, Sizes};
use super::share::{Costs, Share, Split};
use super::TreeParams;
use crate::simd::F64x4;
use crate::threads::{DisjointSlice, Threads};
use rayon::prelude::*;
use std::ops::Range;
use std::sync::Mutex;

/// Entries per step of the list sums: one AVX2 vector.
pub(super) const LANES: usize = 4;

/// A node whose centre lies farther than this many sides (plus the centre's
/// offset from the cube's centre) from a group holds all its particles outside
/// the group's box whatever theta (the particles lie within `sqrt(3)/2 l + delta`
/// of the centre): the floor of the opening distance, which matters for theta
/// above `2 / sqrt(3)`.
const HALF_DIAGONAL: f64 = 0.866_025_403_784_438_6;

/// [`HALF_DIAGONAL`] of a square, for particles in a plane (`sqrt(2)/2`).
const HALF_DIAGONAL_2D: f64 = std::f64::consts::FRAC_1_SQRT_2;

/// Leaves with at most this many particles are listed as particles even when
/// they could be accepted: as cheap as a multipole, and exact.
const SMALL_LEAF: u32 = 2;

/// The particles in tree order (structure of arrays) with their weights (mass or
/// circulation), and every node as the walk sees it.
#[derive(Clone, Debug, Default)]
pub(super) struct Walk {
    /// Sorted positions, one column per axis (`z = 0` in 2D).
    pub x: [Vec<f64>; 3],
    /// Sorted weights.
    pub w: Vec<f64>,
    /// The particles' axes: 3, or 2 when they lie in the plane `z = 0` (the
    /// nodes' geometry then is that of their squares).
    dims: usize,
    /// What the walk reads of each node (with its expansion centre), packed into
    /// one cache line.
    nodes: Vec<WalkNode>,
}

/// A node as the walk sees it.
#[derive(Clone, Copy, Debug, Default)]
#[repr(C, align(64))]
struct WalkNode {
    /// The expansion centre (the centre of mass, or of `|Gamma|`).
    centre: [f64; 3],
    /// `(max(l / theta, sqrt(D)/2 l + clearance) + delta)^2`: the node is
    /// accepted for a group whose bounding box lies farther than this from its
    /// centre.
    open2: f64,
    start: u32,
    end: u32,
    next: u32,
    leaf: bool,
}

impl WalkNode {
    /// `node`'s entry with its expansion centre and squared opening distance.
    fn new(node: &Node, centre: [f64; 3], open2: f64) -> Self {
        WalkNode {
            centre,
            open2,
            start: node.start,
            end: node.end,
            next: node.next,
            leaf: node.leaf,
        }
    }
}

impl Walk {
    /// Copies `positions` (`D` = 2 or 3 axes; missing axes are 0) and `weights`
    /// into tree order.
    fn sort<const D: usize>(
        &mut self,
        tree: &Octree,
        positions: &[[f64; D]],
        weights: &[f64],
        threads: &Threads,
    ) {
        self.dims = D;
        threads.install(|| {
            for a in 0..3 {
                tree.order
                    .par_iter()
                    .map(|&i| if a < D { positions[i as usize][a] } else { 0.0 })
                    .collect_into_vec(&mut self.x[a]);
            }
            tree.order
                .par_iter()
                .map(|&i| weights[i as usize])
                .collect_into_vec(&mut self.w);
        });
    }

    /// Every node's walk entry and kernel moments: `of_node` gives a node's
    /// expansion centre and moments from the sorted particles, and the node
    /// opens within [`open2`]'s distance of its centre.
    pub fn nodes<M: Send>(
        &mut self,
        tree: &Octree,
        theta: f64,
        clearance: f64,
        moments: &mut Vec<M>,
        threads: &Threads,
        of_node: impl Fn(&Node, &Self) -> ([f64; 3], M) + Sync,
    ) {
        let dims = self.dims;
        // the entries are rebuilt in the kept allocation
        let mut walk = std::mem::take(&mut self.nodes);
        let this = &*self;
        threads.install(|| {
            tree.nodes
                .par_iter()
                .map(|node| {
                    let (centre, m) = of_node(node, this);
                    let open2 = open2(node, &centre, theta, clearance, dims);
                    (WalkNode::new(node, centre, open2), m)
                })
                .unzip_into_vecs(&mut walk, moments);
        });
        self.nodes = walk;
    }

    /// The walk entries of `tree`'s nodes (the sorted particles and the axes
    /// set), node `k`'s expansion centre and squared opening distance
    /// `centres[k]`.
    pub fn set_nodes(&mut self, tree: &Octree, centres: impl IntoIterator<Item = ([f64; 3], f64)>) {
        self.nodes.clear();
        for (node, (centre, open2)) in tree.nodes.iter().zip(centres) {
            self.nodes.push(WalkNode::new(node, centre, open2));
        }
    }

    /// Node `k`'s expansion centre and squared opening distance.
    pub fn entry(&self, k: usize) -> ([f64; 3], f64) {
        (self.nodes[k].centre, self.nodes[k].open2)
    }

    /// Sets the particles' axes: 3, or 2 when they lie in the plane `z = 0`.
    pub fn set_dims(&mut self, dims: usize) {
        self.dims = dims;
    }
}

/// `(max(l / theta, sqrt(D)/2 l + clearance) + delta)^2` for `node`, of side
/// `l`, whose expansion centre `centre` lies `delta` from its cube's centre
/// (`sqrt(2)/2` and the square's centre for `dims = 2`): a node is accepted
/// for a group whose bounding box lies farther than this from its centre, so
/// that an accepted node's particles lie farther than `clearance` from the
/// group's box.
pub(super) fn open2(
    node: &Node,
    centre: &[f64; 3],
    theta: f64,
    clearance: f64,
    dims: usize,
) -> f64 {
    let (dims, half_diagonal) = match dims {
        2 => (2, HALF_DIAGONAL_2D),
        _ => (3, HALF_DIAGONAL),
    };
    let delta = (0..dims)
        .map(|a| (centre[a] - (node.corner[a] + 0.5 * node.side)).powi(2))
        .sum::<f64>()
        .sqrt();
    let open = (node.side / theta).max(half_diagonal * node.side + clearance) + delta;
    open * open
}

/// Whether the walk accepts node `k` (of `tree`, entries in `walk`) for a
/// box `lo..hi` that holds none of its particles: its centre lies farther
/// than its opening distance from the box, and it is not a leaf of at most
/// [`SMALL_LEAF`] particles.
pub(super) fn accepts(walk: &Walk, k: usize, lo: &[f64; 3], hi: &[f64; 3]) -> bool {
    let node = &walk.nodes[k];
    d2(&node.centre, lo, hi) > node.open2 && !(node.leaf && node.end - node.start <= SMALL_LEAF)
}

/// The squared distance from `c` to the box `lo..hi` (0 inside).
#[inline]
fn d2(c: &[f64; 3], lo: &[f64; 3], hi: &[f64; 3]) -> f64 {
    let mut d2 = 0.0;
    for a in 0..3 {
        let gap = (lo[a] - c[a]).max(c[a] - hi[a]).max(0.0);
        d2 += gap * gap;
    }
    d2
}

/// One group's interaction lists, padded to whole lanes: the accepted nodes'
/// centres and the particles of opened leaves (with their weights and sorted
/// indices, to skip the self term). The kernels copy the accepted nodes'
/// moments next to these.
#[derive(Clone, Debug, Default)]
pub(super) struct Lists {
    /// Accepted node indices, in walk order.
    pub accepted: Vec<u32>,
    opened: Vec<(u32, u32)>,
    /// Accepted node centres, padded with [`Lists::far`].
    pub node_x: [Vec<f64>; 3],
    /// Opened leaves' particles, padded with [`Lists::far`].
    pub part_x: [Vec<f64>; 3],
    /// Their weights, padded with 0.
    pub part_w: Vec<f64>,
    /// Their sorted indices, padded with -1.
    pub part_id: Vec<f64>,
    /// The padding position: three root sides beyond the root's corner, so that
    /// no padding entry sits on a particle.
    pub far: [f64; 3],
    nodes: usize,
    particles: usize,
}

impl Lists {
    /// The lists of group `group`: walks the tree from the root, accepting or
    /// opening each node against the group's bounding box, then copies the
    /// accepted nodes' centres and the opened leaves' particles.
    pub fn gather<M>(&mut self, group: &Group<M>) {
        let (tree, walk) = (group.tree, group.walk);
        let own = &tree.nodes[group.node];
        let range = own.start as usize..own.end as usize;
        let bound = |a: usize, pick: fn(f64, f64) -> f64, from: f64| {
            walk.x[a][range.clone()].iter().copied().fold(from, pick)
        };
        let lo: [f64; 3] = std::array::from_fn(|a| bound(a, f64::min, f64::INFINITY));
        let hi: [f64; 3] = std::array::from_fn(|a| bound(a, f64::max, f64::NEG_INFINITY));
        self.accepted.clear();
        self.opened.clear();
        let mut k = 0;
        while k < walk.nodes.len() {
            let node = &walk.nodes[k];
            let d2 = d2(&node.centre, &lo, &hi);
            // nodes that share particles with the group are always opened
            let shares = node.start < own.end && own.start < node.end;
            if !shares && d2 > node.open2 && !(node.leaf && node.end - node.start <= SMALL_LEAF) {
                self.accepted.push(k as u32);
                k = node.next as usize;
            } else if node.leaf {
                self.opened.push((node.start, node.end));
                k = node.next as usize;
            } else {
                // a node sent alone (without children) by another rank is
                // accepted by every group whose walk reaches it, never opened
                debug_assert!(
                    node.next as usize > k + 1,
                    "node {k} opened without children"
                );
                k += 1;
            }
        }
        let root = &tree.nodes[0];
        self.far = root.corner.map(|c| c + 3.0 * root.side);
        self.fill(walk);
    }

    /// Copies the accepted nodes' centres and the opened leaves' particles into
    /// the padded SoA lists.
    fn fill(&mut self, walk: &Walk) {
        let pad = |v: &mut Vec<f64>, value: f64| v.resize(v.len().next_multiple_of(LANES), value);
        for a in 0..3 {
            copy(&mut self.node_x[a], &self.accepted, self.far[a], |k| {
                walk.nodes[k].centre[a]
            });
        }
        self.nodes = self.accepted.len();
        let spans = || self.opened.iter().map(|&(s, e)| s as usize..e as usize);
        for a in 0..3 {
            let dst = &mut self.part_x[a];
            dst.clear();
            for r in spans() {
                dst.extend_from_slice(&walk.x[a][r]);
            }
            pad(dst, self.far[a]);
        }
        self.part_w.clear();
        self.part_id.clear();
        for r in spans() {
            self.part_w.extend_from_slice(&walk.w[r.clone()]);
            self.part_id.extend(r.map(|s| s as f64));
        }
        self.particles = self.part_w.len();
        pad(&mut self.part_w, 0.0);
        pad(&mut self.part_id, -1.0);
    }

    /// `(node, particle)` interactions of a group of `len` particles, the self
    /// terms excluded.
    pub fn counts(&self, len: usize) -> (u64, u64) {
        let len = len as u64;
        (self.nodes as u64 * len, (self.particles as u64 - 1) * len)
    }
}

/// `dst = [of(k) for k in ids]`, padded to whole lanes with `value`.
pub(super) fn copy(dst: &mut Vec<f64>, ids: &[u32], value: f64, of: impl Fn(usize) -> f64) {
    dst.clear();
    dst.extend(ids.iter().map(|&k| of(k as usize)));
    dst.resize(dst.len().next_multiple_of(LANES), value);
}

/// What a tree solver keeps between evaluations, whatever its kernel: the
/// settings, the octree, the walk, the nodes' kernel moments `M`, the results
/// (`W` numbers per particle) in tree order, one list scratch `L` per thread,
/// the last interaction counts and, for a divided evaluation, the particles'
/// last costs.
#[derive(Debug)]
pub(super) struct Solver<M, L, const W: usize> {
    pub params: TreeParams,
    pub tree: Octree,
    pub walk: Walk,
    pub moments: Vec<M>,
    sorted: Vec<[f64; W]>,
    scratch: Vec<Mutex<L>>,
    /// `(node, particle)` interactions of the last evaluation's own groups.
    pub interactions: (u64, u64),
    /// Per own group of the last evaluation, its interactions.
    counts: Vec<(u64, u64)>,
    /// Per particle, its weight in the next [`Split`]: `1 +` its group's
    /// interactions per particle in the last divided evaluation.
    costs: Costs,
}

/// One walk group as a kernel sees it: the tree, the walk, the nodes' moments,
/// the group's node and its first sorted particle.
#[derive(Clone, Copy, Debug)]
pub(super) struct Group<'a, M> {
    pub tree: &'a Octree,
    pub walk: &'a Walk,
    pub moments: &'a [M],
    pub node: usize,
    pub start: usize,
}

/// A group particle during a kernel's list sums: its position (`D` axes), its
/// sorted index and `S` running sums of four lanes.
#[derive(Clone, Copy, Debug)]
pub(super) struct Target<const D: usize, const S: usize> {
    pub x: [f64; D],
    pub id: f64,
    pub sums: [F64x4; S],
}

impl<M> Group<'_, M> {
    /// The group's `len` particles as zeroed targets in `into`.
    pub fn targets<const D: usize, const S: usize>(
        &self,
        len: usize,
        into: &mut Vec<Target<D, S>>,
    ) {
        into.clear();
        into.extend((self.start..self.start + len).map(|s| Target {
            x: std::array::from_fn(|a| self.walk.x[a][s]),
            id: s as f64,
            sums: [F64x4::splat(0.0); S],
        }));
    }
}

impl<M: Send + Sync, L: Default + Send, const W: usize> Solver<M, L, W> {
    /// An empty solver with `params` (checked).
    pub fn new(params: TreeParams) -> Result<Self, String> {
        params.check()?;
        Ok(Solver {
            params,
            tree: Octree::default(),
            walk: Walk::default(),
            moments: Vec::new(),
            sorted: Vec::new(),
            scratch: Vec::new(),
            interactions: (0, 0),
            counts: Vec::new(),
            costs: Costs::default(),
        })
    }

    /// One evaluation, divided by `share`: [`Solver::arrange`], then
    /// [`Solver::evaluate_arranged`].
    #[allow(clippy::too_many_arguments)]
    pub fn evaluate<const D: usize>(
        &mut self,
        lifted: &[[f64; 3]],
        positions: &[[f64; D]],
        weights: &[f64],
        clearance: f64,
        threads: &Threads,
        share: &mut dyn Share,
        of_node: impl Fn(&Node, &Walk) -> ([f64; 3], M) + Sync,
        per_group: impl Fn(&mut L, Group<M>, &mut [[f64; W]]) -> (u64, u64) + Sync,
    ) {
        self.arrange(lifted, positions, weights, threads);
        self.evaluate_arranged(clearance, threads, share, of_node, per_group);
    }

    /// The octree of `lifted` (the positions in 3D), and the sorted
    /// `positions` (`D` axes) and `weights`; [`Solver::order`] then gives the
    /// tree order.
    pub fn arrange<const D: usize>(
        &mut self,
        lifted: &[[f64; 3]],
        positions: &[[f64; D]],
        weights: &[f64],
        threads: &Threads,
    ) {
        assert!(lifted.len() == positions.len() && positions.len() == weights.len());
        let sizes = Sizes {
            leaf: self.params.leaf_size,
            group: self.params.group_size,
        };
        self.tree.build(lifted, sizes, threads);
        self.walk.sort(&self.tree, positions, weights, threads);
    }

    /// The input index of each sorted particle of the last [`Solver::arrange`].
    pub fn order(&self) -> &[u32] {
        &self.tree.order
    }

    /// The evaluation of the particles of the last [`Solver::arrange`],
    /// divided by `share`: every node's centre and moments by `of_node` (see
    /// [`Walk::nodes`] for `clearance`), then `per_group` for every group of
    /// this process's part ([`Split`]) in parallel, each writing the results
    /// of its own particles and returning its interactions; then the other
    /// parts' results (and costs) are gathered, so that every particle's
    /// result is that of the undivided evaluation.
    pub fn evaluate_arranged(
        &mut self,
        clearance: f64,
        threads: &Threads,
        share: &mut dyn Share,
        of_node: impl Fn(&Node, &Walk) -> ([f64; 3], M) + Sync,
        per_group: impl Fn(&mut L, Group<M>, &mut [[f64; W]]) -> (u64, u64) + Sync,
    ) {
        let theta = self.params.theta;
        self.walk.nodes(
            &self.tree,
            theta,
            clearance,
            &mut self.moments,
            threads,
            of_node,
        );
        let (part, parts) = share.part();
        let split = Split::new(&self.tree, self.costs.input(), parts);
        let own = split.groups[part]..split.groups[part + 1];
        self.sum_groups(own, threads, per_group);
        if parts > 1 {
            let work = self
                .counts
                .iter()
                .map(|&(nodes, particles)| (nodes + particles) as f64);
            self.costs.gather(&self.tree, &split, part, work, share);
        }
        share.all_gather(self.sorted.as_flattened_mut(), W, &split.particles);
    }

    /// `per_group` for the groups `own` of the tree (its walk entries and
    /// moments set) in parallel, each writing the results of its own
    /// particles (in [`Solver::sorted`]) and returning its interactions.
    pub fn sum_groups(
        &mut self,
        own: Range<usize>,
        threads: &Threads,
        per_group: impl Fn(&mut L, Group<M>, &mut [[f64; W]]) -> (u64, u64) + Sync,
    ) {
        self.sorted.resize(self.tree.order.len(), [0.0; W]);
        while self.scratch.len() < threads.count() {
            self.scratch.push(Mutex::new(L::default()));
        }
        let (tree, walk, moments) = (&self.tree, &self.walk, &self.moments[..]);
        let shared = DisjointSlice::new(&mut self.sorted);
        let scratch = &self.scratch;
        threads.install(|| {
            tree.groups[own]
                .par_iter()
                .map(|&group| {
                    let thread = rayon::current_thread_index().unwrap_or(0);
                    let mut lists = scratch[thread].lock().expect("scratch of a panicked walk");
                    let node = &tree.nodes[group as usize];
                    // SAFETY: groups hold disjoint ranges of the sorted particles.
                    let target = unsafe { shared.range(node.start as usize..node.end as usize) };
                    let group = Group {
                        tree,
                        walk,
                        moments,
                        node: group as usize,
                        start: node.start as usize,
                    };
                    per_group(&mut lists, group, target)
                })
                .collect_into_vec(&mut self.counts)
        });
        self.interactions = self
            .counts
            .iter()
            .fold((0, 0), |a, b| (a.0 + b.0, a.1 + b.1));
    }

    /// The results of the last evaluation in tree order.
    pub fn sorted(&self) -> &[[f64; W]] {
        &self.sorted
    }

    /// `(input index, result)` of every particle of the last evaluation.
    pub fn results(&self) -> impl Iterator<Item = (usize, &[f64; W])> {
        self.tree
            .order
            .iter()
            .map(|&i| i as usize)
            .zip(&self.sorted)
    }
}
