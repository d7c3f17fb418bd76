//! The top of a Barnes-Hut tree whose bodies are divided among ranks: its
//! nodes, which every rank knows, from the root down to the units (the
//! nodes one rank holds whole), and the units dealt out to the ranks in
//! contiguous runs of the Morton order (module `spread`).

use super::build::{child_corner, Cube, Node, Sizes, KEY_BITS};
use crate::longrange::Exchange;

/// A node of the top of the tree, which every rank knows.
#[derive(Clone, Copy, Debug)]
pub(super) struct TopNode {
    /// The depth below the root (0).
    pub level: u32,
    /// The node's keys are those whose leading `3 level` bits are `prefix`.
    pub prefix: u64,
    /// Its bodies over all ranks.
    pub count: usize,
    /// The first of its bodies in one process's sorted order.
    pub start: usize,
    /// The lower corner of its cube.
    pub corner: [f64; 3],
    /// Its cube's side.
    pub side: f64,
    /// One rank holds its whole subtree.
    pub unit: bool,
    /// The first top node after its subtree.
    pub next: usize,
}

impl TopNode {
    /// The first key past the node's keys is `(prefix + 1) << shift`.
    pub fn shift(&self) -> u32 {
        3 * (KEY_BITS - self.level)
    }

    /// Its cube as an octree node (no bodies or links yet).
    pub fn as_node(&self) -> Node {
        Node {
            corner: self.corner,
            side: self.side,
            start: 0,
            end: 0,
            next: 0,
            leaf: false,
        }
    }
}

/// The counts over all ranks of `local` (each rank's own numbers), added in
/// rank order.
fn add_over_ranks(local: &[f64], exchange: &dyn Exchange) -> Vec<f64> {
    let ranks = exchange.ranks();
    let mut all = vec![0.0; local.len() * ranks];
    exchange.all_gather(local, &vec![local.len(); ranks], &mut all);
    let mut total = vec![0.0; local.len()];
    for part in all.chunks_exact(local.len().max(1)) {
        for (t, v) in total.iter_mut().zip(part) {
            *t += v;
        }
    }
    total
}

/// Every rank's `mine` (as many numbers on every rank), in rank order.
pub(super) fn gather_each(mine: &[f64], exchange: &dyn Exchange) -> Vec<f64> {
    let ranks = exchange.ranks();
    let mut all = vec![0.0; mine.len() * ranks];
    exchange.all_gather(mine, &vec![mine.len(); ranks], &mut all);
    all
}

/// The top of the tree over every rank's sorted `keys`: from the root down,
/// a node becomes a unit when it is a leaf or a group under `sizes` or holds
/// at most `most` bodies; the others' children are counted over the ranks
/// (one all-gather per level). Nodes without bodies are left out, as one
/// process's tree leaves them out. Depth first.
pub(super) fn top_nodes(
    keys: &[(u64, u32)],
    total: usize,
    cube: &Cube,
    sizes: Sizes,
    most: usize,
    exchange: &dyn Exchange,
) -> Vec<TopNode> {
    let is_unit = |count: usize, level: u32| {
        // `most` is at least the group size: groups are units
        count <= sizes.leaf || level == KEY_BITS || count <= most
    };
    // breadth first: the nodes, and each one's children
    let root = TopNode {
        level: 0,
        prefix: 0,
        count: total,
        start: 0,
        corner: cube.corner,
        side: cube.side,
        unit: is_unit(total, 0),
        next: 0,
    };
    let mut nodes = vec![root];
    let mut children: Vec<Vec<usize>> = vec![Vec::new()];
    let mut open: Vec<usize> = if root.unit { vec![] } else { vec![0] };
    while !open.is_empty() {
        let mut local = Vec::with_capacity(8 * open.len());
        for &k in &open {
            let node = nodes[k];
            let shift = node.shift() - 3;
            for octant in 0..8u64 {
                let lo = ((node.prefix << 3) | octant) << shift;
                let hi = lo + (1u64 << shift);
                let from = keys.partition_point(|k| k.0 < lo);
                let to = keys.partition_point(|k| k.0 < hi);
                local.push((to - from) as f64);
            }
        }
        let counts = add_over_ranks(&local, exchange);
        let mut next_open = Vec::new();
        for (i, &k) in open.iter().enumerate() {
            let node = nodes[k];
            let half = 0.5 * node.side;
            for octant in 0..8u64 {
                let count = counts[8 * i + octant as usize] as usize;
                if count == 0 {
                    continue;
                }
                let level = node.level + 1;
                let child = TopNode {
                    level,
                    prefix: (node.prefix << 3) | octant,
                    count,
                    start: 0,
                    corner: child_corner(node.corner, half, octant),
                    side: half,
                    unit: is_unit(count, level),
                    next: 0,
                };
                children[k].push(nodes.len());
                if !child.unit {
                    next_open.push(nodes.len());
                }
                nodes.push(child);
                children.push(Vec::new());
            }
        }
        open = next_open;
    }
    // depth first, with the starts and the links past each subtree
    fn visit(
        k: usize,
        start: usize,
        nodes: &[TopNode],
        children: &[Vec<usize>],
        out: &mut Vec<TopNode>,
    ) {
        let at = out.len();
        out.push(TopNode { start, ..nodes[k] });
        let mut start = start;
        for &c in &children[k] {
            visit(c, start, nodes, children, out);
            start += nodes[c].count;
        }
        out[at].next = out.len();
    }
    let mut out = Vec::with_capacity(nodes.len());
    visit(0, 0, &nodes, &children, &mut out);
    out
}

/// The units of `nodes` dealt out to `ranks` in contiguous runs of about
/// equal counts (a unit goes to the rank in whose share the middle of its
/// count falls): each top node's rank (units only; 0 for the others) and the
/// first sorted body of each rank's run (`ranks + 1` entries).
pub(super) fn deal(nodes: &[TopNode], total: usize, ranks: usize) -> (Vec<usize>, Vec<usize>) {
    let mut owner = vec![0; nodes.len()];
    let mut first = vec![total; ranks + 1];
    first[0] = 0;
    let (mut before, mut last) = (0, 0);
    for (k, node) in nodes.iter().enumerate().filter(|(_, n)| n.unit) {
        let middle = (before as f64 + 0.5 * node.count as f64) / total as f64 * ranks as f64;
        let rank = (middle as usize).clamp(last, ranks - 1);
        // the ranks up to this one (past the last) start here
        for f in &mut first[last + 1..=rank] {
            *f = node.start;
        }
        owner[k] = rank;
        last = rank;
        before += node.count;
    }
    (owner, first)
}
