//! The octree: particles sorted along a Morton (Z-order) curve, nodes cut from
//! the sorted range by the key's octal digits, depth first, with a `next` link
//! that skips a node's subtree so that the walk needs no stack.

use crate::threads::Threads;
use rayon::prelude::*;

/// Bits per axis in a Morton key (3 x 21 = 63 bits).
pub(super) const KEY_BITS: u32 = 21;

/// `v`'s low 21 bits spread to every third bit.
#[inline]
fn spread(v: u64) -> u64 {
    let mut x = v & 0x1f_ffff;
    x = (x | (x << 32)) & 0x001f_0000_0000_ffff;
    x = (x | (x << 16)) & 0x001f_0000_ff00_00ff;
    x = (x | (x << 8)) & 0x100f_00f0_0f00_f00f;
    x = (x | (x << 4)) & 0x10c3_0c30_c30c_30c3;
    x = (x | (x << 2)) & 0x1249_2492_4924_9249;
    x
}

/// The Morton key of integer cell coordinates `q` (each below `2^21`): the bits
/// of x, y and z interleaved, x lowest.
#[inline]
pub(super) fn morton(q: [u64; 3]) -> u64 {
    spread(q[0]) | (spread(q[1]) << 1) | (spread(q[2]) << 2)
}

/// Most particles in a leaf and in a walk group.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct Sizes {
    pub leaf: usize,
    pub group: usize,
}

/// One node: its cube, its particles (a range of the sorted order) and the link
/// past its subtree. Its children, if any, follow it directly.
#[derive(Clone, Copy, Debug)]
pub(super) struct Node {
    /// The lower corner of the node's cube.
    pub corner: [f64; 3],
    /// The cube's side.
    pub side: f64,
    /// Sorted particles `start..end`.
    pub start: u32,
    /// End of the particle range.
    pub end: u32,
    /// The index of the first node after this subtree.
    pub next: u32,
    /// Whether the node has no children.
    pub leaf: bool,
}

/// The particles in Morton order and the nodes over them.
#[derive(Clone, Debug, Default)]
pub(super) struct Octree {
    /// `order[s]`: the input index of sorted particle `s`.
    pub order: Vec<u32>,
    /// `(Morton key, input index)` of each sorted particle.
    pub keys: Vec<(u64, u32)>,
    /// Depth-first nodes; node 0 is the root.
    pub nodes: Vec<Node>,
    /// The walk's groups, in order: the largest nodes of at most `group_size`
    /// particles. They partition the particles.
    pub groups: Vec<u32>,
}

impl Octree {
    /// The children of node `k`, in order: the first follows `k`, each next
    /// one follows the subtree of the one before.
    pub fn children(&self, k: usize) -> impl Iterator<Item = usize> + '_ {
        let end = self.nodes[k].next as usize;
        let mut child = k + 1;
        std::iter::from_fn(move || {
            (child < end).then(|| {
                let this = child;
                child = self.nodes[this].next as usize;
                this
            })
        })
    }

    /// Sorts `positions` along the Morton curve of their bounding cube and cuts
    /// the nodes, leaves holding at most `leaf_size` particles (or sitting at the
    /// keys' last level), and marks the groups of at most `group_size`.
    pub fn build(&mut self, positions: &[[f64; 3]], sizes: Sizes, threads: &Threads) {
        self.build_stretched(positions, sizes, 1.0, threads)
    }

    /// [`build`](Self::build) with the root the bounding cube grown
    /// `stretch` times (at least 1) about its centre: the cells of each
    /// level are then `stretch` times wider, so that a caller can choose how
    /// many particles a level's cells hold.
    pub fn build_stretched(
        &mut self,
        positions: &[[f64; 3]],
        sizes: Sizes,
        stretch: f64,
        threads: &Threads,
    ) {
        let n = positions.len();
        let (lo, hi) = crate::geometry::bounding_box(positions);
        let cube = Cube::stretched(lo, hi, n > 0, stretch);
        cube.sorted_keys(positions, &mut self.keys, threads);
        self.order.clear();
        self.order.extend(self.keys.iter().map(|k| k.1));
        self.nodes.clear();
        self.groups.clear();
        if n > 0 {
            self.cut(0, n, 0, cube.corner, cube.side, sizes, false);
        }
    }

    /// Appends the node of sorted particles `start..end` at `level` (its cube at
    /// `corner` with `side`) and its subtree; `grouped` when an ancestor is a group.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn cut(
        &mut self,
        start: usize,
        end: usize,
        level: u32,
        corner: [f64; 3],
        side: f64,
        sizes: Sizes,
        grouped: bool,
    ) {
        let index = self.nodes.len();
        let leaf = end - start <= sizes.leaf || level == KEY_BITS;
        let group = !grouped && (end - start <= sizes.group || leaf);
        if group {
            self.groups.push(index as u32);
        }
        self.nodes.push(Node {
            corner,
            side,
            start: start as u32,
            end: end as u32,
            next: 0,
            leaf,
        });
        if !leaf {
            let shift = 3 * (KEY_BITS - 1 - level);
            let half = 0.5 * side;
            let mut from = start;
            for octant in 0..8u64 {
                let to =
                    from + self.keys[from..end].partition_point(|k| (k.0 >> shift) & 7 <= octant);
                if to > from {
                    let child = child_corner(corner, half, octant);
                    self.cut(from, to, level + 1, child, half, sizes, grouped || group);
                }
                from = to;
            }
        }
        self.nodes[index].next = self.nodes.len() as u32;
    }
}

/// The lower corner of child `octant` (bit `a` set: the upper half along
/// axis `a`) of the cube at `corner` with side `2 half`.
#[inline]
pub(super) fn child_corner(corner: [f64; 3], half: f64, octant: u64) -> [f64; 3] {
    std::array::from_fn(|a| corner[a] + half * ((octant >> a) & 1) as f64)
}

/// The root's cube and the Morton keys of the positions in it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Cube {
    /// The lower corner.
    pub corner: [f64; 3],
    /// The side.
    pub side: f64,
}

impl Cube {
    /// The smallest axis-aligned cube holding the box `lo..hi` of some
    /// positions (`any`: there are some; else a unit cube at the origin),
    /// grown by a relative `1e-12` so that the largest coordinates fall
    /// inside, then `stretch` times (at least 1) about its centre.
    pub fn stretched(lo: [f64; 3], hi: [f64; 3], any: bool, stretch: f64) -> Self {
        assert!(
            stretch >= 1.0,
            "a root smaller than the bounding cube: {stretch}"
        );
        let (lower, fitted) = if any {
            let extent = (0..3).map(|a| hi[a] - lo[a]).fold(0.0, f64::max);
            let magnitude = (0..3)
                .map(|a| lo[a].abs().max(hi[a].abs()))
                .fold(0.0, f64::max);
            let side = (extent * (1.0 + 1e-12))
                .max(magnitude * 1e-12)
                .max(f64::MIN_POSITIVE);
            (lo, side)
        } else {
            ([0.0; 3], 1.0)
        };
        let side = fitted * stretch;
        let corner = std::array::from_fn(|a| lower[a] - 0.5 * (side - fitted));
        Cube { corner, side }
    }

    /// `(key, index)` of every position in `positions`, sorted (keys, then
    /// indices) into `keys`.
    pub fn sorted_keys(
        &self,
        positions: &[[f64; 3]],
        keys: &mut Vec<(u64, u32)>,
        threads: &Threads,
    ) {
        threads.install(|| {
            positions
                .par_iter()
                .enumerate()
                .map(|(i, x)| (self.key(x), i as u32))
                .collect_into_vec(keys);
            keys.par_sort_unstable();
        });
    }

    /// The Morton key of `x`: its cell among the `2^21` per axis of the cube,
    /// clamped into the cube.
    #[inline]
    pub fn key(&self, x: &[f64; 3]) -> u64 {
        let scale = (1u64 << KEY_BITS) as f64 / self.side;
        let top = (1u64 << KEY_BITS) - 1;
        morton(std::array::from_fn(|a| {
            (((x[a] - self.corner[a]) * scale) as u64).min(top)
        }))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::random::Rng;

    #[test]
    fn morton_interleaves_the_axes() {
        assert_eq!(morton([1, 0, 0]), 1);
        assert_eq!(morton([0, 1, 0]), 2);
        assert_eq!(morton([0, 0, 1]), 4);
        assert_eq!(morton([3, 0, 0]), 0b1001);
        let top = (1 << KEY_BITS) - 1;
        assert_eq!(morton([top, top, top]), (1u64 << 63) - 1);
    }

    #[test]
    fn nodes_partition_their_particles_and_hold_them_in_their_cubes() {
        let mut rng = Rng::new(3);
        let mut x: Vec<[f64; 3]> = (0..3000)
            .map(|_| [rng.normal(), rng.normal() * 0.1, rng.uniform()])
            .collect();
        x.push(x[10]); // a duplicate point
        let mut tree = Octree::default();
        tree.build(&x, Sizes { leaf: 8, group: 40 }, &Threads::single());
        let mut at = 0;
        for &g in &tree.groups {
            let node = &tree.nodes[g as usize];
            assert_eq!(node.start, at);
            assert!(node.end - node.start <= 40 || node.leaf);
            at = node.end;
        }
        assert_eq!(at as usize, x.len());
        let mut seen = tree.order.clone();
        seen.sort_unstable();
        assert_eq!(seen, (0..x.len() as u32).collect::<Vec<_>>());
        let mut leaf_particles = 0;
        for (k, node) in tree.nodes.iter().enumerate() {
            for s in node.start..node.end {
                let p = x[tree.order[s as usize] as usize];
                for a in 0..3 {
                    assert!(
                        p[a] >= node.corner[a] - 1e-12
                            && p[a] <= node.corner[a] + node.side * (1.0 + 1e-9)
                    );
                }
            }
            if node.leaf {
                assert!(node.end - node.start <= 8);
                assert_eq!(node.next as usize, k + 1);
                leaf_particles += node.end - node.start;
            } else {
                // the children tile the parent's range in order
                let mut at = node.start;
                for c in tree.children(k) {
                    assert_eq!(tree.nodes[c].start, at);
                    at = tree.nodes[c].end;
                }
                assert_eq!(at, node.end);
            }
        }
        assert_eq!(leaf_particles as usize, x.len());
    }

    /// A stretched root is centred on the bounding cube and holds every
    /// particle; its leaves' cubes are `stretch` times those of the fitted
    /// root at the same level.
    #[test]
    fn a_stretched_root_is_centred_and_holds_every_particle() {
        let mut rng = Rng::new(5);
        let x: Vec<[f64; 3]> = (0..2000)
            .map(|_| [rng.uniform(), 2.0 * rng.uniform(), rng.uniform()])
            .collect();
        let sizes = Sizes {
            leaf: 16,
            group: 64,
        };
        let (mut fitted, mut stretched) = (Octree::default(), Octree::default());
        fitted.build(&x, sizes, &Threads::single());
        stretched.build_stretched(&x, sizes, 1.5, &Threads::single());
        let (f, s) = (fitted.nodes[0], stretched.nodes[0]);
        assert!((s.side - 1.5 * f.side).abs() < 1e-12 * f.side);
        for a in 0..3 {
            let centre = |n: Node| n.corner[a] + 0.5 * n.side;
            assert!((centre(s) - centre(f)).abs() < 1e-12, "axis {a}");
        }
        for node in stretched.nodes.iter().filter(|n| n.leaf) {
            assert!(node.end - node.start <= 16);
            for k in node.start..node.end {
                let p = x[stretched.order[k as usize] as usize];
                assert!((0..3).all(|a| p[a] >= node.corner[a] - 1e-12
                    && p[a] <= node.corner[a] + node.side * (1.0 + 1e-9)));
            }
        }
    }
}
