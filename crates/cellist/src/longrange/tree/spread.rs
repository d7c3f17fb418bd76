//! Gravity's Barnes-Hut tree on ranks that divide the bodies among them, by
//! locally essential trees, with the tree, the opening decisions and the
//! field of one process to the bit.
//!
//! ```text
//! the root's cube          all-gather of the ranks' boxes
//! the top of the tree      rounds of all-gathered child counts, from the
//!                          root down to the units: nodes that are groups or
//!                          hold at most N / (16 P) bodies
//! the units dealt out      contiguous runs of units in Morton order, of
//!                          about equal counts: rank r holds the sorted
//!                          bodies S_r .. S_(r+1) of one process's order
//! the bodies routed        each to the rank of its unit (and its field back
//!                          at the end)
//! own subtrees             each unit cut as one process cuts it
//! top moments              each node's running sums continued rank after
//!                          rank over its bodies (two passes: mass and centre
//!                          of mass, then the quadrupole)
//! the essential parts      for every other rank, the nodes of the own
//!                          subtrees that its groups' walks may reach, judged
//!                          against its groups' boxes (all-gathered), by
//!                          all-to-all
//! the walks                over the top, the own subtrees and the parts
//!                          received, for the own groups
//! ```
//!
//! A node goes to a rank with the boxes of that rank's groups whose walks
//! reach it (every box at a unit's root, then those that opened its
//! parent): if they all accept it, it goes alone, without children, and
//! their walks accept it again; if some open it, its children follow for
//! those boxes, or its bodies if it is a leaf. So the parts hold every node
//! and body the walks reach. The tree's cuts depend only on the counts and the sorted
//! order `(key, input index)` of one process (a rank's arrivals come in rank
//! order, then each sender's order, which is the input order), and a node's
//! sums run over its bodies in the sorted order, so every list, every
//! moment and every sum is that of one process.

use super::build::{Cube, Node, Octree, Sizes};
use super::multipole::{
    centre_of_mass, mass_sums, of_node, quadrupole_sums, Multipole, MASS_SUMS_START,
};
use super::top::{deal, gather_each, top_nodes, TopNode};
use super::walk::{accepts, open2, Walk};
use crate::longrange::mesh::route::{Arrived, Place, Route};
use crate::longrange::mesh::slab::extent;
use crate::longrange::Exchange;
use crate::threads::{exclusive_sums, Threads};
use std::ops::Range;

/// Numbers per node of an essential part: the nodes sent under it (itself
/// included: 1 for a node sent alone), the bodies sent under it, leaf (1)
/// or not (0), centre of mass (3), squared opening distance, mass,
/// quadrupole (6).
const RECORD: usize = 14;

/// Numbers per body of an essential part: `x y z m`.
const BODY: usize = 4;

/// Units hold at most `N / (UNITS_PER_RANK P)` bodies (or are groups): the
/// granularity of the ranks' shares.
const UNITS_PER_RANK: usize = 16;

/// What a rank keeps between evaluations: its bodies in tree order, their
/// subtrees, the route of the bodies and the messages' buffers.
#[derive(Debug, Default)]
pub(super) struct Spread {
    route: Route<1>,
    arrived: Arrived<1>,
    /// The own units' subtrees (a forest): node `k`'s bodies are own sorted
    /// bodies, its links within the forest.
    forest: Octree,
    /// The own bodies in tree order with the forest's walk entries.
    own: Walk,
    moments: Vec<Multipole>,
    /// The forest index of each own unit's root, in order.
    unit_roots: Vec<usize>,
    send: Vec<f64>,
    /// The essential parts received, rank after rank.
    receive: Vec<f64>,
    /// Where each rank's message starts in `receive`.
    from: Vec<usize>,
    /// The own bodies' sums, in input order.
    pub sums: Vec<[f64; 4]>,
    /// The own bodies' keys and input indices, sorted.
    keys: Vec<(u64, u32)>,
    /// Per arrived body, its place in the locally essential tree.
    at: Vec<u32>,
    /// The nodes' expansion centres and squared opening distances as the
    /// locally essential tree is put together.
    centres: Vec<([f64; 3], f64)>,
    /// The records and bodies of one essential part as it is made.
    scratch: [Vec<f64>; 2],
    /// The group boxes whose walks reach the nodes of a part being made.
    open: Vec<u32>,
}

/// The top of the tree and how its units are dealt out.
struct Top {
    nodes: Vec<TopNode>,
    /// Per top node, the rank holding its subtree (units only).
    owner: Vec<usize>,
    /// Rank `r` holds the sorted bodies `first[r]..first[r + 1]`.
    first: Vec<usize>,
    /// The top nodes' entries: centre of mass, squared opening distance,
    /// moments (the units' left empty: their subtrees bring them).
    entries: Vec<([f64; 3], f64, Multipole)>,
}

impl Spread {
    /// The field of every rank's own bodies (`position`, `mass`, the ranks'
    /// bodies in rank order) as one process's tree with `sizes` and `theta`
    /// gives it: `result[i]` of own body `i` gets the sums of `sum_groups`
    /// (run by this rank for the groups of its units over `solver`'s tree,
    /// walk and moments, which this fills with the locally essential tree).
    /// Collective.
    #[allow(clippy::too_many_arguments)]
    pub fn evaluate<L: Default + Send>(
        &mut self,
        position: &[[f64; 3]],
        mass: &[f64],
        solver: &mut super::walk::Solver<Multipole, L, 4>,
        exchange: &dyn Exchange,
        threads: &Threads,
        result: &mut [[f64; 4]],
        sum_groups: impl Fn(&mut super::walk::Solver<Multipole, L, 4>, &Threads),
    ) {
        let (rank, ranks) = (exchange.rank(), exchange.ranks());
        let sizes = Sizes {
            leaf: solver.params.leaf_size,
            group: solver.params.group_size,
        };
        let theta = solver.params.theta;
        // the root's cube: the box of every rank's bodies
        let ((lo, hi), total) = extent(position, exchange);
        if total == 0 {
            return;
        }
        let cube = Cube::stretched(lo, hi, true, 1.0);
        // the top of the tree, from the own keys
        cube.sorted_keys(position, &mut self.keys, threads);
        let keys = &self.keys;
        let most = sizes.group.max(total / (UNITS_PER_RANK * ranks));
        let nodes = top_nodes(keys, total, &cube, sizes, most, exchange);
        let (owner, first) = deal(&nodes, total, ranks);
        // the bodies to the ranks of their units
        let unit_keys: Vec<(u64, usize)> = nodes
            .iter()
            .enumerate()
            .filter(|(_, n)| n.unit)
            .map(|(k, n)| (n.prefix << n.shift(), owner[k]))
            .collect();
        let place = |x: &[f64; 3]| {
            let key = cube.key(x);
            let u = unit_keys.partition_point(|&(first, _)| first <= key) - 1;
            let to = unit_keys[u].1;
            let mut place = Place::new([to]);
            place.add(to);
            place
        };
        self.route
            .forward(position, mass, exchange, &mut self.arrived, place);
        let own_range = first[rank]..first[rank + 1];
        assert_eq!(
            self.arrived.position.len(),
            own_range.len(),
            "the bodies routed to rank {rank}"
        );
        // the own bodies in one process's order, cut into the own units' subtrees
        self.cut_own_units(&nodes, &owner, rank, &cube, sizes, theta, threads);
        let mut top = Top {
            nodes,
            owner,
            first,
            entries: Vec::new(),
        };
        top.entries = self.top_entries(&top, rank, theta, exchange);
        // the essential parts, to every other rank
        let boxes = self.group_boxes(exchange);
        self.exchange_parts(rank, &boxes, exchange);
        // the locally essential tree and its walks
        if self.arrived.position.is_empty() {
            // nothing to walk for: no tree kept
            solver.tree.nodes.clear();
            solver.tree.order.clear();
        } else {
            self.assemble(&top, rank, solver);
            sum_groups(solver, threads);
        }
        // where each arrived body sits in the tree
        let at = &mut self.at;
        at.clear();
        at.resize(self.arrived.position.len(), 0);
        for (p, &i) in solver.tree.order.iter().enumerate() {
            if i != u32::MAX {
                at[i as usize] = p as u32;
            }
        }
        let (at, sorted) = (&self.at, solver.sorted());
        self.route.back(
            &self.arrived,
            0,
            exchange,
            result,
            |i| sorted[at[i] as usize],
            threads,
        );
    }

    /// Sorts the arrived bodies into one process's order (key, then arrival,
    /// which is the input order) in [`Spread::own`], and cuts each own unit of
    /// `top` into [`Spread::forest`], whose walk entries and moments it sets.
    #[allow(clippy::too_many_arguments)]
    fn cut_own_units(
        &mut self,
        top: &[TopNode],
        owner: &[usize],
        rank: usize,
        cube: &Cube,
        sizes: Sizes,
        theta: f64,
        threads: &Threads,
    ) {
        let forest = &mut self.forest;
        let arrived = &self.arrived;
        cube.sorted_keys(&arrived.position, &mut forest.keys, threads);
        forest.order.clear();
        forest.order.extend(forest.keys.iter().map(|k| k.1));
        forest.nodes.clear();
        forest.groups.clear();
        self.unit_roots.clear();
        let mut at = 0;
        for (k, node) in top.iter().enumerate() {
            if node.unit && owner[k] == rank {
                self.unit_roots.push(forest.nodes.len());
                forest.cut(
                    at,
                    at + node.count,
                    node.level,
                    node.corner,
                    node.side,
                    sizes,
                    false,
                );
                at += node.count;
            }
        }
        let own = &mut self.own;
        own.set_dims(3);
        for a in 0..3 {
            own.x[a].clear();
            own.x[a].extend(
                forest
                    .order
                    .iter()
                    .map(|&i| arrived.position[i as usize][a]),
            );
        }
        own.w.clear();
        own.w
            .extend(forest.order.iter().map(|&i| arrived.mass[i as usize]));
        self.own.nodes(
            &self.forest,
            theta,
            0.0,
            &mut self.moments,
            threads,
            of_node,
        );
    }

    /// Every top node's entry but the units': its sums run over its bodies in order, each
    /// rank continuing the running sums of the ranks before it over its own
    /// part of them (an all-gather per rank, twice: the mass and centre of
    /// mass, then the quadrupole about it).
    fn top_entries(
        &self,
        top: &Top,
        rank: usize,
        theta: f64,
        exchange: &dyn Exchange,
    ) -> Vec<([f64; 3], f64, Multipole)> {
        let own = top.first[rank]..top.first[rank + 1];
        // the own part of node k's bodies, in own sorted indices
        let part = |node: &TopNode| -> Range<usize> {
            let (a, b) = (
                node.start.max(own.start),
                (node.start + node.count).min(own.end),
            );
            if a < b {
                a - own.start..b - own.start
            } else {
                0..0
            }
        };
        // the units' entries come with their subtrees
        let inner: Vec<usize> = (0..top.nodes.len())
            .filter(|&k| !top.nodes[k].unit)
            .collect();
        let n = inner.len();
        let mut sums: Vec<f64> = MASS_SUMS_START.repeat(n);
        Self::pass_along(&mut sums, 4, &top.first, exchange, |i, s| {
            let s: &mut [f64; 4] = s.try_into().expect("four sums");
            *s = mass_sums(*s, &self.own, part(&top.nodes[inner[i]]));
        });
        let com: Vec<[f64; 3]> = sums
            .chunks_exact(4)
            .map(|s| centre_of_mass(s.try_into().expect("four sums")))
            .collect();
        let mut quad = vec![0.0; 6 * n];
        Self::pass_along(&mut quad, 6, &top.first, exchange, |i, q| {
            let q: &mut [f64; 6] = q.try_into().expect("six sums");
            *q = quadrupole_sums(*q, &com[i], &self.own, part(&top.nodes[inner[i]]));
        });
        let mut entries = vec![Default::default(); top.nodes.len()];
        for (i, &k) in inner.iter().enumerate() {
            let node = top.nodes[k].as_node();
            let quad = quad[6 * i..6 * i + 6].try_into().expect("six sums");
            let entry = Multipole {
                mass: sums[4 * i],
                quad,
            };
            entries[k] = (com[i], open2(&node, &com[i], theta, 0.0, 3), entry);
        }
        entries
    }

    /// Runs `continue_sums(k, sums of node k)` on each rank in turn, rank 0
    /// first, each rank starting from the sums the rank before it left
    /// (`width` per node; ranks without bodies are skipped).
    fn pass_along(
        sums: &mut [f64],
        width: usize,
        first: &[usize],
        exchange: &dyn Exchange,
        continue_sums: impl Fn(usize, &mut [f64]),
    ) {
        let (rank, ranks) = (exchange.rank(), exchange.ranks());
        for turn in (0..ranks).filter(|&r| first[r] < first[r + 1]) {
            let mine = if turn == rank {
                for (k, s) in sums.chunks_exact_mut(width).enumerate() {
                    continue_sums(k, s);
                }
                sums.to_vec()
            } else {
                Vec::new()
            };
            let mut counts = vec![0; ranks];
            counts[turn] = sums.len();
            exchange.all_gather(&mine, &counts, sums);
        }
    }

    /// The boxes (`lo`, `hi`) of every rank's walk groups, rank after rank:
    /// per rank, its boxes. Collective.
    fn group_boxes(&self, exchange: &dyn Exchange) -> Vec<Vec<[f64; 6]>> {
        let own = &self.own;
        let mine: Vec<f64> = self
            .forest
            .groups
            .iter()
            .flat_map(|&g| {
                let node = &self.forest.nodes[g as usize];
                let range = node.start as usize..node.end as usize;
                let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
                for a in 0..3 {
                    for &x in &own.x[a][range.clone()] {
                        lo[a] = lo[a].min(x);
                        hi[a] = hi[a].max(x);
                    }
                }
                [lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]]
            })
            .collect();
        let counts: Vec<usize> = gather_each(&[mine.len() as f64], exchange)
            .iter()
            .map(|&c| c as usize)
            .collect();
        let mut all = vec![0.0; counts.iter().sum()];
        exchange.all_gather(&mine, &counts, &mut all);
        let starts = exclusive_sums(&counts);
        starts
            .iter()
            .zip(&counts)
            .map(|(&s, &c)| {
                all[s..s + c]
                    .chunks_exact(6)
                    .map(|b| b.try_into().expect("a box"))
                    .collect()
            })
            .collect()
    }

    /// Sends every other rank the essential parts of the own units'
    /// subtrees for the boxes of its walk groups (`boxes`, per rank), and
    /// receives theirs for this rank: a message is the count of its records,
    /// the records (depth first, unit after unit) and the bodies of the leaves
    /// it opens. Ranks without groups get nothing.
    fn exchange_parts(&mut self, rank: usize, boxes: &[Vec<[f64; 6]>], exchange: &dyn Exchange) {
        let ranks = exchange.ranks();
        let mut counts = vec![0; ranks];
        self.send.clear();
        // the scratch of the parts, kept from call to call
        let [mut records, mut bodies] = std::mem::take(&mut self.scratch);
        let mut open = std::mem::take(&mut self.open);
        for (q, boxes) in boxes.iter().enumerate() {
            if q == rank || boxes.is_empty() {
                continue;
            }
            records.clear();
            bodies.clear();
            for &root in &self.unit_roots {
                open.clear();
                open.extend(0..boxes.len() as u32);
                self.part(root, boxes, &mut open, 0, &mut records, &mut bodies);
            }
            self.send.push((records.len() / RECORD) as f64);
            self.send.extend_from_slice(&records);
            self.send.extend_from_slice(&bodies);
            counts[q] = 1 + records.len() + bodies.len();
        }
        self.scratch = [records, bodies];
        self.open = open;
        let ones = vec![1; ranks];
        let sent: Vec<f64> = counts.iter().map(|&c| c as f64).collect();
        let mut got = vec![0.0; ranks];
        exchange.all_to_all(&sent, &ones, &mut got, &ones);
        let got: Vec<usize> = got.iter().map(|&c| c as usize).collect();
        self.receive.clear();
        self.receive.resize(got.iter().sum(), 0.0);
        exchange.all_to_all(&self.send, &counts, &mut self.receive, &got);
        self.from = exclusive_sums(&got);
    }

    /// Appends the essential part under forest node `k` for the group boxes
    /// `boxes[open[from..]]` whose walks reach it: the node's record, then
    /// (if some of those walks open it) its children's parts for the boxes
    /// that open it, or its bodies if it is a leaf; a node that they all
    /// accept goes without children, and they accept it again. Returns the
    /// nodes and bodies appended. `open` is a stack of box indices, left as
    /// it was found.
    fn part(
        &self,
        k: usize,
        boxes: &[[f64; 6]],
        open: &mut Vec<u32>,
        from: usize,
        records: &mut Vec<f64>,
        bodies: &mut Vec<f64>,
    ) -> (usize, usize) {
        let at = records.len();
        records.resize(at + RECORD, 0.0);
        let node = self.forest.nodes[k];
        let reach = open.len();
        for i in from..reach {
            let b = &boxes[open[i] as usize];
            let (lo, hi) = ([b[0], b[1], b[2]], [b[3], b[4], b[5]]);
            if !accepts(&self.own, k, &lo, &hi) {
                open.push(open[i]);
            }
        }
        let accepted = open.len() == reach;
        let (mut nodes, mut count) = (1, 0);
        if accepted {
            // sent as a node without children, which the walks accept
        } else if node.leaf {
            for s in node.start as usize..node.end as usize {
                let own = &self.own;
                bodies.extend_from_slice(&[own.x[0][s], own.x[1][s], own.x[2][s], own.w[s]]);
            }
            count = (node.end - node.start) as usize;
        } else {
            for c in self.forest.children(k) {
                let (n, b) = self.part(c, boxes, open, reach, records, bodies);
                nodes += n;
                count += b;
            }
        }
        open.truncate(reach);
        let (centre, open2) = self.own.entry(k);
        let m = &self.moments[k];
        let leaf = !accepted && node.leaf;
        let record = &mut records[at..at + RECORD];
        record[..7].copy_from_slice(&[
            nodes as f64,
            count as f64,
            f64::from(u8::from(leaf)),
            centre[0],
            centre[1],
            centre[2],
            open2,
        ]);
        record[7] = m.mass;
        record[8..].copy_from_slice(&m.quad);
        (nodes, count)
    }

    /// Fills `solver`'s tree, walk and moments with the locally essential
    /// tree: the top nodes, the own subtrees (with the own bodies and groups)
    /// and the parts received, depth first; a body's input index in the tree's
    /// order is its arrival here, `u32::MAX` for another rank's.
    fn assemble<L: Default + Send>(
        &mut self,
        top: &Top,
        rank: usize,
        solver: &mut super::walk::Solver<Multipole, L, 4>,
    ) {
        let mut centres = std::mem::take(&mut self.centres);
        centres.clear();
        solver.moments.clear();
        let walk = &mut solver.walk;
        for a in 0..3 {
            walk.x[a].clear();
        }
        walk.w.clear();
        let tree = &mut solver.tree;
        tree.nodes.clear();
        tree.groups.clear();
        tree.order.clear();
        tree.keys.clear();
        // this rank's slot of `from` is empty and never read
        let mut builder = Builder {
            spread: self,
            top,
            rank,
            tree,
            walk,
            centres: &mut centres,
            moments: &mut solver.moments,
            units: 0,
            group: 0,
            records: self.from.iter().map(|&f| f + 1).collect(),
            bodies: self
                .from
                .iter()
                .map(|&f| {
                    let records = self.receive.get(f).copied().unwrap_or(0.0) as usize;
                    f + 1 + RECORD * records
                })
                .collect(),
        };
        builder.visit(0);
        solver.walk.set_dims(3);
        solver.walk.set_nodes(&solver.tree, centres.drain(..));
        self.centres = centres;
    }
}

/// The locally essential tree as it is put together.
struct Builder<'a> {
    spread: &'a Spread,
    top: &'a Top,
    rank: usize,
    tree: &'a mut Octree,
    /// The bodies in tree order.
    walk: &'a mut Walk,
    /// Per node, its expansion centre and squared opening distance.
    centres: &'a mut Vec<([f64; 3], f64)>,
    moments: &'a mut Vec<Multipole>,
    /// Own units placed so far.
    units: usize,
    /// Own forest groups placed so far.
    group: usize,
    /// Per rank, the next record of its message.
    records: Vec<usize>,
    /// Per rank, the next body of its message.
    bodies: Vec<usize>,
}

impl Builder<'_> {
    /// Places top node `t` and its subtree.
    fn visit(&mut self, t: usize) {
        let node = self.top.nodes[t];
        if !node.unit {
            let index = self.tree.nodes.len();
            let start = self.walk.w.len() as u32;
            self.tree.nodes.push(Node {
                start,
                ..node.as_node()
            });
            let (centre, open2, m) = self.top.entries[t];
            self.centres.push((centre, open2));
            self.moments.push(m);
            let mut child = t + 1;
            while child < node.next {
                self.visit(child);
                child = self.top.nodes[child].next;
            }
            let (end, next) = (self.walk.w.len() as u32, self.tree.nodes.len() as u32);
            let placed = &mut self.tree.nodes[index];
            placed.end = end;
            placed.next = next;
        } else if self.top.owner[t] == self.rank {
            self.own_unit();
        } else {
            self.received_unit(self.top.owner[t]);
        }
    }

    /// Places the next own unit's subtree, bodies and groups.
    fn own_unit(&mut self) {
        let spread = self.spread;
        let forest = &spread.forest;
        let root = spread.unit_roots[self.units];
        self.units += 1;
        let end = forest.nodes[root].next as usize;
        let node_shift = self.tree.nodes.len() as i64 - root as i64;
        let first = forest.nodes[root].start as usize;
        let body_shift = self.walk.w.len() as i64 - first as i64;
        let shifted = |v: u32, by: i64| (v as i64 + by) as u32;
        for f in root..end {
            let n = forest.nodes[f];
            self.tree.nodes.push(Node {
                start: shifted(n.start, body_shift),
                end: shifted(n.end, body_shift),
                next: shifted(n.next, node_shift),
                ..n
            });
            self.centres.push(spread.own.entry(f));
            self.moments.push(spread.moments[f]);
        }
        while let Some(&g) = forest.groups.get(self.group) {
            if g as usize >= end {
                break;
            }
            self.tree.groups.push(shifted(g, node_shift));
            self.group += 1;
        }
        let bodies = first..forest.nodes[root].end as usize;
        for a in 0..3 {
            self.walk.x[a].extend_from_slice(&spread.own.x[a][bodies.clone()]);
        }
        self.walk.w.extend_from_slice(&spread.own.w[bodies.clone()]);
        self.tree.order.extend_from_slice(&forest.order[bodies]);
    }

    /// Places the next unit of rank `from`'s message: its records, and the
    /// bodies of its leaves.
    fn received_unit(&mut self, from: usize) {
        let message = &self.spread.receive;
        let base = self.tree.nodes.len();
        let at = self.records[from];
        let count = message[at] as usize;
        for i in 0..count {
            let r = &message[at + RECORD * i..at + RECORD * (i + 1)];
            let (nodes, bodies, leaf) = (r[0] as usize, r[1] as usize, r[2] != 0.0);
            let start = self.walk.w.len();
            self.tree.nodes.push(Node {
                corner: [0.0; 3],
                side: 0.0,
                start: start as u32,
                end: (start + bodies) as u32,
                next: (base + i + nodes) as u32,
                leaf,
            });
            let quad = r[8..].try_into().expect("six sums");
            self.centres.push(([r[3], r[4], r[5]], r[6]));
            self.moments.push(Multipole { mass: r[7], quad });
            if leaf {
                let b = self.bodies[from];
                for body in message[b..b + BODY * bodies].chunks_exact(BODY) {
                    for a in 0..3 {
                        self.walk.x[a].push(body[a]);
                    }
                    self.walk.w.push(body[3]);
                    self.tree.order.push(u32::MAX);
                }
                self.bodies[from] = b + BODY * bodies;
            }
        }
        self.records[from] = at + RECORD * count;
    }
}

#[cfg(test)]
mod tests {
    use super::super::{BarnesHut, TreeParams};
    use crate::interactions::GravityLaw;
    use crate::longrange::mesh::slab::part;
    use crate::longrange::mesh::slab::testkit::Hub;
    use crate::longrange::{Exchange, FieldOut, Sources};
    use crate::random::Rng;
    use crate::threads::Threads;

    /// A cloud of `n` bodies: a Gaussian core, a uniform halo, a few far
    /// outliers and duplicated points; masses in `[0.5, 1.5)`.
    fn cloud(n: usize, seed: u64) -> (Vec<[f64; 3]>, Vec<f64>) {
        let mut rng = Rng::new(seed);
        let mut x: Vec<[f64; 3]> = (0..n)
            .map(|i| match i % 5 {
                0 => [
                    rng.uniform() * 4.0 - 2.0,
                    rng.uniform(),
                    rng.uniform() * 2.0,
                ],
                _ => [rng.normal() * 0.2, rng.normal() * 0.1, rng.normal() * 0.3],
            })
            .collect();
        if n > 20 {
            x[3] = [30.0, -4.0, 2.0];
            x[7] = x[11];
            x[12] = x[11];
        }
        let m = (0..n).map(|_| 0.5 + rng.uniform()).collect();
        (x, m)
    }

    /// `(acc, phi)` of every body as bits.
    type Bits = Vec<[u64; 4]>;

    fn bits(acc: &[[f64; 3]], phi: &[f64]) -> Bits {
        acc.iter()
            .zip(phi)
            .map(|(a, p)| [a[0].to_bits(), a[1].to_bits(), a[2].to_bits(), p.to_bits()])
            .collect()
    }

    /// The field of one process's tree, then of `ranks` thread-ranks holding
    /// the bodies in rank order, twice (the bodies moved in between): the
    /// same bits.
    /// The most bodies a rank's locally essential tree held on more than one
    /// rank is returned.
    fn spread_equals_one_process(
        (x, m): (Vec<[f64; 3]>, Vec<f64>),
        law: GravityLaw,
        params: TreeParams,
    ) -> usize {
        let n = x.len();
        let moved: Vec<[f64; 3]> = x.iter().map(|p| [p[0] * 1.1, p[1] - 0.05, p[2]]).collect();
        let single = Threads::single();
        let whole = |x: &[[f64; 3]]| {
            let mut tree = BarnesHut::new(law, params).unwrap();
            let (mut acc, mut phi) = (vec![[0.0; 3]; n], vec![0.0; n]);
            let sources = Sources {
                mass: &m,
                position: x,
            };
            let out = FieldOut {
                acc: &mut acc,
                phi: &mut phi,
            };
            tree.compute(&sources, out, &single);
            bits(&acc, &phi)
        };
        let want = [whole(&x), whole(&moved)];
        let mut held_most = 0;
        for ranks in 1..=4 {
            let got = Hub::run(ranks, |exchange| {
                let own = part(n, exchange.rank(), ranks);
                let mut tree = BarnesHut::new(law, params).unwrap();
                let threads = Threads::new(2).unwrap();
                [&x, &moved].map(|x| {
                    let (mut acc, mut phi) = (vec![[0.0; 3]; own.len()], vec![0.0; own.len()]);
                    let sources = Sources {
                        mass: &m[own.clone()],
                        position: &x[own.clone()],
                    };
                    let out = FieldOut {
                        acc: &mut acc,
                        phi: &mut phi,
                    };
                    tree.compute_spread(&sources, out, &threads, exchange);
                    (bits(&acc, &phi), tree.held())
                })
            });
            for (walked, held) in got.iter().flat_map(|g| g.iter().map(|e| e.1)) {
                held_most = held_most.max(held);
                let share = n / ranks + n / 8 + params.group_size;
                assert!(walked <= share, "{walked} of {n} on {ranks}");
            }
            for (step, want) in want.iter().enumerate() {
                let got: Bits = got.iter().flat_map(|g| g[step].0.clone()).collect();
                assert_eq!(got.len(), n);
                let differ = got.iter().zip(want).filter(|(g, w)| g != w).count();
                assert_eq!(differ, 0, "{n} bodies on {ranks} ranks, evaluation {step}");
            }
            if ranks == 1 {
                held_most = 0;
            }
        }
        held_most
    }

    #[test]
    fn divided_bodies_give_one_process_bits() {
        let law = GravityLaw::new(1.0, 0.01, 0.0).unwrap();
        let params = TreeParams {
            theta: 0.5,
            quadrupole: true,
            leaf_size: 8,
            group_size: 32,
        };
        spread_equals_one_process(cloud(6000, 1), law, params);
    }

    /// On 2 to 4 ranks a rank's locally essential tree holds its own bodies
    /// and those near its part: fewer than all.
    #[test]
    fn ranks_hold_part_of_the_bodies() {
        let law = GravityLaw::new(1.0, 0.01, 0.0).unwrap();
        let mut rng = Rng::new(4);
        let n = 20_000;
        let x = (0..n)
            .map(|_| [rng.uniform(), rng.uniform(), rng.uniform()])
            .collect();
        let held = spread_equals_one_process((x, vec![1.0; n]), law, TreeParams::default());
        assert!(held < n * 7 / 10, "a rank held {held} of {n} bodies");
    }

    #[test]
    fn divided_bodies_give_one_process_bits_whatever_the_settings() {
        let law = GravityLaw::new(2.0, 0.0, 0.0).unwrap();
        for (theta, quadrupole, leaf_size, group_size) in
            [(0.3, false, 16, 128), (0.9, true, 4, 4), (0.6, true, 32, 8)]
        {
            let params = TreeParams {
                theta,
                quadrupole,
                leaf_size,
                group_size,
            };
            spread_equals_one_process(cloud(3000, 2), law, params);
        }
    }

    /// Fewer bodies than ranks, a single group, and one body.
    #[test]
    fn few_bodies_give_one_process_bits() {
        let law = GravityLaw::new(1.0, 0.1, 0.02).unwrap();
        for n in [1, 3, 40, 300] {
            spread_equals_one_process(cloud(n, 3), law, TreeParams::default());
        }
    }
}
