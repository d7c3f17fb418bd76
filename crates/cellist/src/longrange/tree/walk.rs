//! The node moments, the walk that lists a group's interactions, and the SIMD
//! sums over those lists.

use super::build::Octree;
use super::TreeParams;
use crate::longrange::direct::Kernel;
use crate::longrange::Sources;
use crate::simd::F64x4;
use crate::threads::Threads;
use rayon::prelude::*;

/// Entries per step of the list sums: one AVX2 vector.
const LANES: usize = 4;

/// A node whose centre of mass is farther than this many sides from a group
/// holds all its bodies outside the group's box whatever theta (the bodies lie
/// within `sqrt(3)/2 l + delta` of the centre of mass): the floor of the opening
/// distance, which matters for theta above `2 / sqrt(3)`.
const HALF_DIAGONAL: f64 = 0.866_025_403_784_438_6;

/// The particles in tree order (structure of arrays) and every node's moments.
#[derive(Clone, Debug, Default)]
pub(crate) struct Moments {
    x: [Vec<f64>; 3],
    m: Vec<f64>,
    /// What the walk reads of each node (with its centre of mass), packed into
    /// one cache line.
    walk: Vec<WalkNode>,
    /// What the list sums read of each accepted node besides its centre of mass.
    multipole: Vec<Multipole>,
}

/// A node's mass and traceless quadrupole `xx, xy, xz, yy, yz, zz` about its
/// centre of mass.
#[derive(Clone, Copy, Debug, Default)]
struct Multipole {
    mass: f64,
    quad: [f64; 6],
}

/// A node as the walk sees it.
#[derive(Clone, Copy, Debug, Default)]
#[repr(C, align(64))]
struct WalkNode {
    com: [f64; 3],
    /// `(l / theta + delta)^2`: the node is accepted for a group whose bounding
    /// box lies farther than this from its centre of mass.
    open2: f64,
    start: u32,
    end: u32,
    next: u32,
    leaf: bool,
}

impl Moments {
    /// The sorted particles and the moments of every node of `tree`.
    pub fn compute(
        &mut self,
        tree: &Octree,
        sources: &Sources,
        params: &TreeParams,
        threads: &Threads,
    ) {
        threads.install(|| {
            for a in 0..3 {
                tree.order
                    .par_iter()
                    .map(|&i| sources.position[i as usize][a])
                    .collect_into_vec(&mut self.x[a]);
            }
            tree.order
                .par_iter()
                .map(|&i| sources.mass[i as usize])
                .collect_into_vec(&mut self.m);
            let (x, m) = (&self.x, &self.m);
            let of_node = |node: &super::build::Node| {
                let range = node.start as usize..node.end as usize;
                let mass: f64 = m[range.clone()].iter().sum();
                let com: [f64; 3] = std::array::from_fn(|a| {
                    range.clone().map(|s| m[s] * x[a][s]).sum::<f64>() / mass
                });
                let mut quad = [0.0; 6];
                for s in range {
                    let y = [x[0][s] - com[0], x[1][s] - com[1], x[2][s] - com[2]];
                    let y2 = y[0] * y[0] + y[1] * y[1] + y[2] * y[2];
                    let w = m[s];
                    quad[0] += w * (3.0 * y[0] * y[0] - y2);
                    quad[1] += w * 3.0 * y[0] * y[1];
                    quad[2] += w * 3.0 * y[0] * y[2];
                    quad[3] += w * (3.0 * y[1] * y[1] - y2);
                    quad[4] += w * 3.0 * y[1] * y[2];
                    quad[5] += w * (3.0 * y[2] * y[2] - y2);
                }
                let delta = (0..3)
                    .map(|a| (com[a] - (node.corner[a] + 0.5 * node.side)).powi(2))
                    .sum::<f64>()
                    .sqrt();
                let open = (node.side / params.theta).max(HALF_DIAGONAL * node.side) + delta;
                let walk = WalkNode {
                    com,
                    open2: open * open,
                    start: node.start,
                    end: node.end,
                    next: node.next,
                    leaf: node.leaf,
                };
                (walk, Multipole { mass, quad })
            };
            tree.nodes
                .par_iter()
                .map(of_node)
                .unzip_into_vecs(&mut self.walk, &mut self.multipole);
        });
    }
}

/// One group's interaction lists, padded to whole lanes: accepted nodes and the
/// particles of opened leaves (with their sorted indices, to skip the self term).
#[derive(Clone, Debug, Default)]
pub(crate) struct Lists {
    accepted: Vec<u32>,
    opened: Vec<(u32, u32)>,
    node_x: [Vec<f64>; 3],
    node_m: Vec<f64>,
    node_q: [Vec<f64>; 6],
    part_x: [Vec<f64>; 3],
    part_m: Vec<f64>,
    part_id: Vec<f64>,
    nodes: usize,
    particles: usize,
    /// Per group particle: its position and its four running sums.
    targets: Vec<Target>,
}

/// A group particle during the list sums.
#[derive(Clone, Copy, Debug)]
struct Target {
    x: [f64; 3],
    id: f64,
    sums: [F64x4; 4],
}

/// Leaves with at most this many particles are listed as particles even when
/// they could be accepted: as cheap as a quadrupole, and exact.
const SMALL_LEAF: u32 = 2;

impl Lists {
    /// The lists of group `group`: walks the tree from the root, accepting or
    /// opening each node against the group's bounding box, then copies the
    /// accepted nodes' moments and the opened leaves' particles.
    pub fn gather(&mut self, tree: &Octree, moments: &Moments, group: usize, quadrupole: bool) {
        let own = &tree.nodes[group];
        let range = own.start as usize..own.end as usize;
        let bound = |a: usize, pick: fn(f64, f64) -> f64, from: f64| {
            moments.x[a][range.clone()].iter().copied().fold(from, pick)
        };
        let lo: [f64; 3] = std::array::from_fn(|a| bound(a, f64::min, f64::INFINITY));
        let hi: [f64; 3] = std::array::from_fn(|a| bound(a, f64::max, f64::NEG_INFINITY));
        self.accepted.clear();
        self.opened.clear();
        let mut k = 0;
        while k < moments.walk.len() {
            let node = &moments.walk[k];
            let mut d2 = 0.0;
            for a in 0..3 {
                let c = node.com[a];
                let gap = (lo[a] - c).max(c - hi[a]).max(0.0);
                d2 += gap * gap;
            }
            // nodes that share particles with the group are always opened
            let shares = node.start < own.end && own.start < node.end;
            if !shares && d2 > node.open2 && !(node.leaf && node.end - node.start <= SMALL_LEAF) {
                self.accepted.push(k as u32);
                k = node.next as usize;
            } else if node.leaf {
                self.opened.push((node.start, node.end));
                k = node.next as usize;
            } else {
                k += 1;
            }
        }
        // list padding: zero mass, three root sides beyond the root's corner, so
        // that no padding entry sits on a body
        let root = &tree.nodes[0];
        let far = root.corner.map(|c| c + 3.0 * root.side);
        self.fill(moments, quadrupole, far);
    }

    /// Copies the listed nodes and particles into the padded SoA lists.
    fn fill(&mut self, moments: &Moments, quadrupole: bool, far: [f64; 3]) {
        let ids = &self.accepted;
        let pad = |v: &mut Vec<f64>, value: f64| v.resize(v.len().next_multiple_of(LANES), value);
        /// `dst = [of(k) for k in ids]`, padded to whole lanes with `value`.
        fn copy(dst: &mut Vec<f64>, ids: &[u32], value: f64, of: impl Fn(usize) -> f64) {
            dst.clear();
            dst.extend(ids.iter().map(|&k| of(k as usize)));
            dst.resize(dst.len().next_multiple_of(LANES), value);
        }
        for a in 0..3 {
            copy(&mut self.node_x[a], ids, far[a], |k| moments.walk[k].com[a]);
        }
        copy(&mut self.node_m, ids, 0.0, |k| moments.multipole[k].mass);
        for j in 0..6 {
            if quadrupole {
                copy(&mut self.node_q[j], ids, 0.0, |k| {
                    moments.multipole[k].quad[j]
                });
            } else {
                self.node_q[j].clear();
            }
        }
        self.nodes = ids.len();
        let spans = || self.opened.iter().map(|&(s, e)| s as usize..e as usize);
        for a in 0..3 {
            let dst = &mut self.part_x[a];
            dst.clear();
            for r in spans() {
                dst.extend_from_slice(&moments.x[a][r]);
            }
            pad(dst, far[a]);
        }
        self.part_m.clear();
        self.part_id.clear();
        for r in spans() {
            self.part_m.extend_from_slice(&moments.m[r.clone()]);
            self.part_id.extend(r.map(|s| s as f64));
        }
        self.particles = self.part_m.len();
        pad(&mut self.part_m, 0.0);
        pad(&mut self.part_id, -1.0);
    }

    /// `(node, particle)` interactions of a group of `len` particles, the self
    /// terms excluded.
    pub fn counts(&self, len: usize) -> (u64, u64) {
        let len = len as u64;
        (self.nodes as u64 * len, (self.particles as u64 - 1) * len)
    }

    /// Sums the lists for the group's particles, sorted `start..`, into `target`
    /// as `[sum acc_x, acc_y, acc_z, pot]` without the factors `G` and `-G`.
    ///
    /// The loops run over the lists outside and the group inside, so that four
    /// list entries stay in registers while every group particle meets them; each
    /// particle's sums are four lanes added across at the end, an order fixed by
    /// the lists.
    pub fn evaluate<const REPULSION: bool>(
        &mut self,
        kernel: &Kernel,
        moments: &Moments,
        start: usize,
        target: &mut [[f64; 4]],
    ) {
        self.targets.clear();
        self.targets
            .extend((start..start + target.len()).map(|s| Target {
                x: [moments.x[0][s], moments.x[1][s], moments.x[2][s]],
                id: s as f64,
                sums: [F64x4::splat(0.0); 4],
            }));
        self.particle_sums::<REPULSION>(kernel);
        if self.node_q[0].is_empty() {
            self.node_sums::<REPULSION, false>(kernel);
        } else {
            self.node_sums::<REPULSION, true>(kernel);
        }
        for (out, t) in target.iter_mut().zip(&self.targets) {
            *out = t.sums.map(F64x4::sum);
        }
    }

    /// Adds `(sum m k d, sum m p)` over the listed particles to every target, the
    /// self term (equal sorted index) skipped.
    #[inline(always)]
    fn particle_sums<const REPULSION: bool>(&mut self, kernel: &Kernel) {
        let one = F64x4::splat(1.0);
        for c in (0..self.part_m.len()).step_by(LANES) {
            let x = [
                F64x4::load(&self.part_x[0][c..]),
                F64x4::load(&self.part_x[1][c..]),
                F64x4::load(&self.part_x[2][c..]),
            ];
            let m = F64x4::load(&self.part_m[c..]);
            let id = F64x4::load(&self.part_id[c..]);
            for t in self.targets.iter_mut() {
                let d = [
                    x[0] - F64x4::splat(t.x[0]),
                    x[1] - F64x4::splat(t.x[1]),
                    x[2] - F64x4::splat(t.x[2]),
                ];
                let inv = (one / kernel.s2(d).sqrt()).zero_where_equal(id, F64x4::splat(t.id));
                let (k, p) = kernel.factors4::<REPULSION>(inv);
                let mk = m * k;
                for a in 0..3 {
                    t.sums[a] = mk.mul_add(d[a], t.sums[a]);
                }
                t.sums[3] = m.mul_add(p, t.sums[3]);
            }
        }
    }

    /// Adds the listed nodes' monopole (and quadrupole) fields to every target.
    #[inline(always)]
    fn node_sums<const REPULSION: bool, const QUADRUPOLE: bool>(&mut self, kernel: &Kernel) {
        let one = F64x4::splat(1.0);
        let (half, five_halves) = (F64x4::splat(0.5), F64x4::splat(2.5));
        for c in (0..self.node_m.len()).step_by(LANES) {
            let com = [
                F64x4::load(&self.node_x[0][c..]),
                F64x4::load(&self.node_x[1][c..]),
                F64x4::load(&self.node_x[2][c..]),
            ];
            let m = F64x4::load(&self.node_m[c..]);
            let q: [F64x4; 6] = if QUADRUPOLE {
                std::array::from_fn(|j| F64x4::load(&self.node_q[j][c..]))
            } else {
                [m; 6]
            };
            for t in self.targets.iter_mut() {
                // d points from the centre of mass to the particle
                let d = [
                    F64x4::splat(t.x[0]) - com[0],
                    F64x4::splat(t.x[1]) - com[1],
                    F64x4::splat(t.x[2]) - com[2],
                ];
                let inv = one / kernel.s2(d).sqrt();
                let (k, p) = kernel.factors4::<REPULSION>(inv);
                let mk = m * k;
                for a in 0..3 {
                    t.sums[a] = mk.neg_mul_add(d[a], t.sums[a]);
                }
                t.sums[3] = m.mul_add(p, t.sums[3]);
                if QUADRUPOLE {
                    let qr = [
                        q[0].mul_add(d[0], q[1].mul_add(d[1], q[2] * d[2])),
                        q[1].mul_add(d[0], q[3].mul_add(d[1], q[4] * d[2])),
                        q[2].mul_add(d[0], q[4].mul_add(d[1], q[5] * d[2])),
                    ];
                    let rqr = qr[0].mul_add(d[0], qr[1].mul_add(d[1], qr[2] * d[2]));
                    let inv2 = inv * inv;
                    let inv5 = inv2 * inv2 * inv;
                    let radial = five_halves * rqr * inv5 * inv2;
                    for a in 0..3 {
                        t.sums[a] = radial.neg_mul_add(d[a], qr[a].mul_add(inv5, t.sums[a]));
                    }
                    t.sums[3] = (half * rqr).mul_add(inv5, t.sums[3]);
                }
            }
        }
    }
}
