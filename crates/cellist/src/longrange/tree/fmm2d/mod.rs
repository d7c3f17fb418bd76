//! The fast multipole method in 2D for vortex velocities: complex-variable
//! expansions ([`expansions`]) on the quadtree the Barnes-Hut solvers build
//! (the octree of the particles lifted to `z = 0`), a dual-tree traversal
//! per target group, and the blob law in the near field.

mod expansions;

use super::build::{Octree, Sizes};
use crate::longrange::biot_savart::{assert_lengths, row, VortexLaw};
use crate::threads::{DisjointSlice, Threads};
use expansions::{l2l, l2p, m2l, m2m, p2m, Binomials, MAX_TERMS};
use rayon::prelude::*;
use rustfft::num_complex::Complex64;
use std::f64::consts::PI;
use std::sync::Mutex;

/// Boxes `T` and `S` (radii `s_T`, `s_S`: half their squares' diagonals,
/// centres `|d|` apart) interact through their expansions when
/// `2 max(s_T, s_S) <= THETA |d|`: both `s_S / (|d| - s_T)` and
/// `s_T / (|d| - s_S)` are then at most `(THETA / 2) / (1 - THETA / 2)`
/// (0.74), so that each expansion's remainder after order `p` is below that
/// to the power `p + 1` of the box's field (times `1 / (1 - 0.74)`). Two
/// equal squares interact from two sides apart (side by side with one
/// square between, or farther); 0.85 was the fastest at 1e-6 for 10^6
/// uniform points (against 0.5, 0.6, 0.7 and 0.75).
const THETA: f64 = 0.85;

/// The fall of the measured error per order: the largest error (over the
/// largest speed) of 10^6 uniform points falls 2.2-fold per order from
/// `p = 12` to `p = 18` (the worst case of [`THETA`], 0.74 per order,
/// assumes every box at the limit).
const DECAY: f64 = 0.45;

/// The error at order 0 that [`DECAY`] starts from, with a margin of 3 or
/// more above the measured ones (uniform and clustered points, points and
/// blobs): `0.05 DECAY^p` bounds the largest error measured at order `p`.
const ERROR_AT_ORDER_ZERO: f64 = 0.05;

/// Most particles in a leaf: a leaf's particles meet the leaves beside it
/// pair by pair.
const LEAF: usize = 32;

/// Most particles in a target group: each group traverses the tree with its
/// own boxes as targets, in parallel with the others (a function of the
/// particles only, so the result does not depend on the thread count).
const GROUP: usize = 4096;

/// The tolerances an FMM takes, exclusive bounds.
pub const TOLERANCE_RANGE: (f64, f64) = (1e-15, 1e-1);

/// The expansion orders an FMM takes.
pub const ORDER_RANGE: (usize, usize) = (1, MAX_TERMS - 1);

/// How accurate an FMM evaluation is asked to be.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum FmmAccuracy {
    /// A relative tolerance `epsilon` in `(1e-15, 1e-1)`: the expansions'
    /// order is the least `p` with `0.05 0.45^p <= epsilon` (the measured fall
    /// of the error per order, see [`VortexFmm`]).
    Tolerance(f64),
    /// The expansions' order `p` itself.
    Order(usize),
}

impl FmmAccuracy {
    /// Checks the range of the tolerance or order (the message names the key).
    pub fn check(&self) -> Result<(), String> {
        match *self {
            FmmAccuracy::Tolerance(t) => {
                let (lo, hi) = TOLERANCE_RANGE;
                if !(t > lo && t < hi) {
                    return Err(format!("tolerance must be in ({lo:e}, {hi:e}), got {t}"));
                }
            }
            FmmAccuracy::Order(p) => {
                let (lo, hi) = ORDER_RANGE;
                if !(lo..=hi).contains(&p) {
                    return Err(format!("order must be in {lo}..={hi}, got {p}"));
                }
            }
        }
        Ok(())
    }

    /// The expansions' order `p`.
    pub fn order(&self) -> usize {
        match *self {
            FmmAccuracy::Tolerance(t) => {
                let p = ((t / ERROR_AT_ORDER_ZERO).ln() / DECAY.ln()).ceil() as usize;
                p.clamp(ORDER_RANGE.0, ORDER_RANGE.1)
            }
            FmmAccuracy::Order(p) => p,
        }
    }

    /// The tolerance the order stands for: the given one, or `0.05 0.45^p`.
    pub fn tolerance(&self) -> f64 {
        match *self {
            FmmAccuracy::Tolerance(t) => t,
            FmmAccuracy::Order(p) => ERROR_AT_ORDER_ZERO * DECAY.powi(p as i32),
        }
    }
}

/// A box as the expansions see it: its square's centre and radius (half the
/// diagonal), which scales its expansions.
#[derive(Clone, Copy, Debug, Default)]
struct Square {
    centre: Complex64,
    radius: f64,
}

/// The fast multipole method for 2D vortex velocities,
///
/// `u(x_i) = sum_j Gamma_j q(|x_i - x_j|^2) (-(y_i - y_j), x_i - x_j)`
///
/// with the pair law `q` of `K` ([`BlobKernel`](crate::longrange::BlobKernel)
/// or [`PointVortex`](crate::longrange::PointVortex)). Far
/// apart, the law is the point vortex's, `u - i v = sum_j Gamma_j / (2 pi i
/// (z - z_j))`, a Cauchy sum whose complex multipole and local expansions
/// (order `p`) the boxes of the quadtree carry. Each target group (a subtree
/// of at most 4096 particles) traverses the tree with its boxes as targets:
/// a target box `T` and a source box `S` whose radii and centre distance
/// satisfy `2 max(s_T, s_S) <= 0.85 d` and whose gap `d - s_T - s_S` is at
/// least the law's reach ([`VortexLaw::reach`]) interact through M2L; otherwise the
/// larger of the two is split (a leaf never is: then the other one), and two
/// leaves meet pair by pair with the law itself. Then the group's locals move down (L2L) and are evaluated at
/// its particles (L2P).
///
/// The error of one M2L is below `4 0.74^(p + 1)` relative to the source
/// box's field; the measured errors fall faster, about 2.2-fold (0.45) per
/// order, and the order is the least `p` with `0.05 0.45^p <= tolerance`
/// ([`FmmAccuracy::order`]). Each particle's sum runs in an order fixed by
/// the tree, so 1 and N threads give the same bits.
#[derive(Debug)]
pub struct VortexFmm<K: VortexLaw> {
    law: K,
    accuracy: FmmAccuracy,
    binomials: Binomials,
    tree: Octree,
    lifted: Vec<[f64; 3]>,
    /// Positions and circulations in tree order.
    x: Vec<f64>,
    y: Vec<f64>,
    gamma: Vec<f64>,
    squares: Vec<Square>,
    /// `p + 1` terms per node, node after node.
    multipoles: Vec<Complex64>,
    /// The velocities in tree order.
    sorted: Vec<[f64; 2]>,
    scratch: Vec<Mutex<Scratch>>,
    counts: Vec<(u64, u64)>,
    interactions: (u64, u64),
}

impl<K: VortexLaw> VortexFmm<K> {
    /// A solver for the pair law `law` at `accuracy` (checked).
    pub fn new(law: K, accuracy: FmmAccuracy) -> Result<Self, String> {
        accuracy.check()?;
        Ok(VortexFmm {
            law,
            accuracy,
            binomials: Binomials::new(accuracy.order()),
            tree: Octree::default(),
            lifted: Vec::new(),
            x: Vec::new(),
            y: Vec::new(),
            gamma: Vec::new(),
            squares: Vec::new(),
            multipoles: Vec::new(),
            sorted: Vec::new(),
            scratch: Vec::new(),
            counts: Vec::new(),
            interactions: (0, 0),
        })
    }

    /// The expansions' order `p`.
    pub fn order(&self) -> usize {
        self.binomials.order()
    }

    /// `(M2L, particle pair)` interactions of the last evaluation.
    pub fn interactions(&self) -> (u64, u64) {
        self.interactions
    }

    /// `velocity[i] = u(x_i)` for every particle (see [`VortexFmm`]), in
    /// input order.
    pub fn compute(
        &mut self,
        positions: &[[f64; 2]],
        gamma: &[f64],
        velocity: &mut [[f64; 2]],
        threads: &Threads,
    ) {
        assert_lengths(positions, gamma, velocity);
        self.lifted.clear();
        self.lifted
            .extend(positions.iter().map(|p| [p[0], p[1], 0.0]));
        let sizes = Sizes {
            leaf: LEAF,
            group: GROUP,
        };
        self.tree.build(&self.lifted, sizes, threads);
        let order = &self.tree.order;
        self.x.clear();
        self.y.clear();
        self.gamma.clear();
        for &i in order {
            let i = i as usize;
            self.x.push(positions[i][0]);
            self.y.push(positions[i][1]);
            self.gamma.push(gamma[i]);
        }
        self.squares.clear();
        self.squares
            .extend(self.tree.nodes.iter().map(|node| Square {
                centre: Complex64::new(
                    node.corner[0] + 0.5 * node.side,
                    node.corner[1] + 0.5 * node.side,
                ),
                radius: node.side * std::f64::consts::FRAC_1_SQRT_2,
            }));
        self.upward(threads);
        self.downward(threads);
        for (&i, u) in self.tree.order.iter().zip(&self.sorted) {
            velocity[i as usize] = *u;
        }
    }

    /// P2M at the leaves (in parallel), then M2M from the children up, last
    /// node first (children follow their parent).
    fn upward(&mut self, threads: &Threads) {
        let terms = self.order() + 1;
        let charge = Complex64::new(0.0, -0.5 / PI);
        let nodes = &self.tree.nodes;
        self.multipoles.clear();
        self.multipoles
            .resize(nodes.len() * terms, Complex64::new(0.0, 0.0));
        let (x, y, gamma, squares) = (&self.x, &self.y, &self.gamma, &self.squares);
        threads.install(|| {
            self.multipoles
                .par_chunks_mut(terms)
                .zip(nodes.par_iter())
                .zip(squares.par_iter())
                .filter(|((_, node), _)| node.leaf)
                .for_each(|((a, node), square)| {
                    let sources = (node.start as usize..node.end as usize)
                        .map(|s| (Complex64::new(x[s], y[s]), gamma[s]));
                    p2m(a, square.centre, square.radius, sources, charge);
                })
        });
        for k in (0..nodes.len()).rev() {
            if nodes[k].leaf {
                continue;
            }
            let (parent, below) = self.multipoles.split_at_mut((k + 1) * terms);
            let parent = &mut parent[k * terms..];
            for child in self.tree.children(k) {
                let offset = (child - k - 1) * terms;
                m2m(
                    &self.binomials,
                    &below[offset..offset + terms],
                    squares[child].centre,
                    squares[child].radius,
                    parent,
                    squares[k].centre,
                    squares[k].radius,
                );
            }
        }
    }

    /// Every target group in parallel: its traversal, then L2L and L2P within
    /// it, writing its particles' velocities.
    fn downward(&mut self, threads: &Threads) {
        let n = self.x.len();
        self.sorted.resize(n, [0.0; 2]);
        while self.scratch.len() < threads.count() {
            self.scratch.push(Mutex::new(Scratch::default()));
        }
        let (mut sorted, mut counts) = (
            std::mem::take(&mut self.sorted),
            std::mem::take(&mut self.counts),
        );
        let shared = DisjointSlice::new(&mut sorted);
        let this = &*self;
        let reach = this.law.reach(this.accuracy.tolerance());
        threads.install(|| {
            this.tree
                .groups
                .par_iter()
                .map(|&g| {
                    let thread = rayon::current_thread_index().unwrap_or(0);
                    let mut scratch = this.scratch[thread]
                        .lock()
                        .expect("scratch of a panicked traversal");
                    let node = &this.tree.nodes[g as usize];
                    // SAFETY: groups hold disjoint ranges of the sorted particles.
                    let out = unsafe { shared.range(node.start as usize..node.end as usize) };
                    this.group(g as usize, reach, &mut scratch, out)
                })
                .collect_into_vec(&mut counts)
        });
        (self.sorted, self.counts) = (sorted, counts);
        self.interactions = self
            .counts
            .iter()
            .fold((0, 0), |a, b| (a.0 + b.0, a.1 + b.1));
    }

    /// The velocities of group `g`'s particles into `out`: the traversal of
    /// `(g, root)`, then the locals down the group's subtree and out at its
    /// leaves. Returns its `(M2L, pair)` counts.
    fn group(
        &self,
        g: usize,
        reach: f64,
        scratch: &mut Scratch,
        out: &mut [[f64; 2]],
    ) -> (u64, u64) {
        let terms = self.order() + 1;
        let nodes = &self.tree.nodes;
        let end = nodes[g].next as usize;
        let Scratch { locals, reactions } = scratch;
        locals.clear();
        locals.resize((end - g) * terms, Complex64::new(0.0, 0.0));
        out.fill([0.0; 2]);
        let mut walk = Traversal {
            fmm: self,
            group: g,
            end,
            reach,
            locals: &mut locals[..],
            reactions,
            out,
            counts: (0, 0),
        };
        walk.interact(g, 0);
        let counts = walk.counts;
        let first = nodes[g].start as usize;
        for k in g..end {
            let node = &nodes[k];
            let (mine, below) = locals.split_at_mut((k - g + 1) * terms);
            let b = &mine[(k - g) * terms..];
            if node.leaf {
                let square = self.squares[k];
                for s in node.start as usize..node.end as usize {
                    let f = l2p(
                        b,
                        square.centre,
                        square.radius,
                        Complex64::new(self.x[s], self.y[s]),
                    );
                    let u = &mut out[s - first];
                    u[0] += f.re;
                    u[1] -= f.im;
                }
                continue;
            }
            for child in self.tree.children(k) {
                let offset = (child - k - 1) * terms;
                l2l(
                    &self.binomials,
                    b,
                    self.squares[k].centre,
                    self.squares[k].radius,
                    &mut below[offset..offset + terms],
                    self.squares[child].centre,
                    self.squares[child].radius,
                );
            }
        }
        counts
    }
}

/// What a thread keeps between its groups: the locals of a group's subtree
/// and the reactions of a leaf's pairs.
#[derive(Debug, Default)]
struct Scratch {
    locals: Vec<Complex64>,
    reactions: [Vec<f64>; 2],
}

/// One group's traversal: its locals (the group's subtree's nodes, `p + 1`
/// terms each) and its particles' pair sums.
struct Traversal<'a, K: VortexLaw> {
    fmm: &'a VortexFmm<K>,
    /// The group's node and the first node after its subtree.
    group: usize,
    end: usize,
    reach: f64,
    locals: &'a mut [Complex64],
    /// A source leaf's reactions per axis, when both leaves of a pair are the
    /// group's.
    reactions: &'a mut [Vec<f64>; 2],
    out: &'a mut [[f64; 2]],
    counts: (u64, u64),
}

impl<K: VortexLaw> Traversal<'_, K> {
    /// Target box `t` (in the group) against source box `s`: M2L when they
    /// are apart, pairs when both are leaves, else the larger one split (a
    /// leaf is never split; two boxes of one size are split both). The rule
    /// is the same with the roles swapped, so that of two leaves of the group
    /// `(t, s)` meet when `(s, t)` do: the first of them takes both sides.
    fn interact(&mut self, t: usize, s: usize) {
        let fmm = self.fmm;
        let nodes = &fmm.tree.nodes;
        let (target, source) = (&nodes[t], &nodes[s]);
        let overlap = target.start < source.end && source.start < target.end;
        if !overlap && self.apart(t, s) {
            let terms = fmm.order() + 1;
            let local = &mut self.locals[(t - self.group) * terms..(t - self.group + 1) * terms];
            let (st, ss) = (fmm.squares[t], fmm.squares[s]);
            m2l(
                &fmm.binomials,
                &fmm.multipoles[s * terms..(s + 1) * terms],
                ss.centre,
                ss.radius,
                local,
                st.centre,
                st.radius,
            );
            self.counts.0 += 1;
            return;
        }
        match (target.leaf, source.leaf) {
            (true, true) => {
                let inside = (self.group..self.end).contains(&s);
                match t.cmp(&s) {
                    std::cmp::Ordering::Less if inside => self.pairs::<true>(t, s),
                    // the pair `(s, t)` took both sides
                    std::cmp::Ordering::Greater if inside => {}
                    _ => self.pairs::<false>(t, s),
                }
            }
            (true, false) => self.each_child(s, |walk, c| walk.interact(t, c)),
            (false, true) => self.each_child(t, |walk, c| walk.interact(c, s)),
            (false, false) => {
                if source.side > target.side {
                    self.each_child(s, |walk, c| walk.interact(t, c))
                } else if target.side > source.side {
                    self.each_child(t, |walk, c| walk.interact(c, s))
                } else {
                    self.each_child(t, |walk, ct| {
                        walk.each_child(s, |walk, cs| walk.interact(ct, cs))
                    })
                }
            }
        }
    }

    /// `visit(self, child)` for every child of node `k`, in order.
    fn each_child(&mut self, k: usize, mut visit: impl FnMut(&mut Self, usize)) {
        let fmm = self.fmm;
        for child in fmm.tree.children(k) {
            visit(self, child);
        }
    }

    /// Whether boxes `t` and `s` are well apart: `2 max(s_T, s_S) <= THETA d`
    /// and a gap of at least the law's reach.
    fn apart(&self, t: usize, s: usize) -> bool {
        let (a, b) = (self.fmm.squares[t], self.fmm.squares[s]);
        let d2 = (a.centre - b.centre).norm_sqr();
        let larger = 2.0 * a.radius.max(b.radius);
        // (the radii added first: the same bits with the roles swapped)
        larger * larger <= THETA * THETA * d2 && d2.sqrt() - (a.radius + b.radius) >= self.reach
    }

    /// Adds the pair sums of leaf `s`'s particles at leaf `t`'s, a target at a
    /// time against the source leaf ([`row`]); with `BOTH` (two leaves of the
    /// group) also the reactions at `s`'s (`K` is odd), summed per source and
    /// added after the target loop, so that each pair is computed once.
    fn pairs<const BOTH: bool>(&mut self, t: usize, s: usize) {
        let fmm = self.fmm;
        let nodes = &fmm.tree.nodes;
        let (target, source) = (&nodes[t], &nodes[s]);
        let sources = source.start as usize..source.end as usize;
        let first = nodes[self.group].start as usize;
        let partners = [&fmm.x[sources.clone()], &fmm.y[sources.clone()]];
        let gamma = &fmm.gamma[sources.clone()];
        let [ru, rv] = &mut *self.reactions;
        let len = if BOTH { sources.len() } else { 0 };
        for r in [&mut *ru, &mut *rv] {
            r.clear();
            r.resize(len, 0.0);
        }
        for i in target.start as usize..target.end as usize {
            let xi = [fmm.x[i], fmm.y[i]];
            let reactions = [&mut ru[..], &mut rv[..]];
            let u = row::<K, BOTH>(&fmm.law, xi, fmm.gamma[i], partners, gamma, reactions);
            let o = &mut self.out[i - first];
            o[0] += u[0];
            o[1] += u[1];
        }
        for (j, (a, b)) in sources.clone().zip(ru.iter().zip(rv.iter())) {
            let o = &mut self.out[j - first];
            o[0] += a;
            o[1] += b;
        }
        let sides = if BOTH { 2 } else { 1 };
        self.counts.1 += sides * (target.end - target.start) as u64 * sources.len() as u64;
    }
}

#[cfg(test)]
mod tests;
