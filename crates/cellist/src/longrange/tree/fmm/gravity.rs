//! The fast multipole method for gravity: solid-harmonic expansions
//! ([`super::solid`]) of `1/r` on the octree, the shared traversal
//! ([`super::engine`]), and the exact pair law (softening, repulsion) in the
//! near field.

use super::super::build::{Node, Sizes};
use super::super::share::{AmongPeers, Share, Whole};
use super::engine::{shift_to_middle, Cube, Engine, Expansions, Pairs};
use super::rotation::{m2l_by_direction, FarPairs, M2lLanes};
use super::solid;
use super::solid::{harmonics, lanes, LANES};
use super::{ErrorFit, FmmAccuracy};
use crate::interactions::GravityLaw;
use crate::longrange::direct::{Block, Kernel};
use crate::longrange::mesh::slab::Exchange;
use crate::longrange::{FieldOut, Sources};
use crate::simd::{F64x8, Register};
use crate::threads::Threads;
use rustfft::num_complex::Complex64;
use std::ops::Range;

/// Boxes interact through their expansions when
/// `2 max(s_T, s_S) <= THETA d` (radii half the cubes' diagonals): each
/// expansion's ratio of radius to distance is then at most
/// `(THETA / 2) / (1 - THETA / 2)` (0.9), and two equal cubes interact from
/// one cube apart (the classical FMM's separation). With leaves of 256 it
/// was the fastest at an RMS error of 2.7e-8 for 10^6 uniform bodies
/// (15.0 s at order 15, against 17.9 s at 0.85 and 28.4 s at 0.7).
const THETA: f64 = 0.95;

impl ErrorFit {
    /// The 3D Laplace FMM's fit: the RMS field error (over the RMS field) of
    /// 20,000 uniform bodies and of a Plummer sphere falls about 0.53-fold
    /// per order from `p = 8` to `p = 20`, and `3e-3 0.55^p` bounds it with a
    /// margin of 2.4 at `p = 8` and 4 or more from `p = 10` on (measured
    /// again with the root grown for leaves of about 200 bodies, before its
    /// whole layers; the tests hold the errors below the tolerance with
    /// them); below order 8 the fall is slower, so a tolerance picks at
    /// least 8. At 10^6 uniform bodies the RMS error at `p = 15` is 4.9e-8
    /// (5.4e-8 with the earlier root), under the fit's 3.8e-7.
    pub const LAPLACE_3D: ErrorFit = ErrorFit {
        decay: 0.55,
        at_zero: 3e-3,
        least: 8,
        knee: None,
    };
}

/// Most particles in a leaf.
const LEAF: usize = 256;

/// The W and X lists' ratio ([`Expansions::near_expansions`]): a leaf and a
/// smaller box with `s_B <= NEAR_RHO (d - s_L)` (and at least
/// [`near_least`] bodies) meet by M2P and P2L.
const NEAR_RHO: f64 = 0.5;

/// The fewest bodies of a box that meets a leaf by M2P and P2L at order `p`:
/// 64 at 1e-6 (order 14; 32 and 128 were not told apart from it), growing
/// with the expansions' terms, as the cost of M2P and P2L per body of the
/// leaf does against the `2 n_B` pair terms it replaces.
fn near_least(p: usize) -> usize {
    (solid::terms(p) / 2).max(64)
}

/// The most particles a uniform cloud's leaves hold (the root grown so that
/// the cloud fills an even number of cubes along each axis, each with at
/// most this many, [`super::engine`]'s `stretch`). Uniform cubes of 10^5,
/// 3x10^5, 10^6 and 4x10^6 bodies at 1e-6 (order 14) took 6.2, 7.8, 8.3 and
/// 8.5 us per body with about 200 per cube, against 6.4, 12.3, 9.4 and 10.3
/// with the bounding cube (leaves of 195, 73, 244 and 122); 150 and 170
/// were slower at 3x10^5 and 10^6 when they left the cloud's outer layers
/// of cubes partly filled. Whole layers of at most 200 on average (195, 174, 171 and
/// 182 per cube at those sizes) took 1.00, 0.96 and 0.90 times the time of
/// about 200 at 10^5, 3x10^5 and 10^6 (3 rounds, both on the two cores at
/// once).
const FILL: usize = 200;

/// Most particles in a target group (each traverses the tree on its own, in
/// parallel with the others; the leaf pairs of two groups are summed once,
/// by the earlier). Groups of at most `n / 4` bodies make 8 groups (the
/// root's children) below 10^6 uniform bodies, for the threads and the
/// ranks to share (1 group of 10^5 bodies took 0.952 s on 1 thread and
/// 2, 8 groups 0.922 s and 0.549 s); at 10^6 the 8 groups (about 125,000
/// bodies each) took 12.43 s, 64 groups of at most 32,768 12.76 s.
const GROUP: usize = 262144;

/// The fast multipole method for gravity,
///
/// `acc_i = G sum_{j != i} k_ij m_j (x_j - x_i)`, `phi_i = -G sum_{j != i} p_ij m_j`
///
/// with `k`, `p` of [`GravityLaw`] (`1/r^3` and `1/r` without softening or
/// repulsion). Far apart the law is `1/r`, whose multipole and local
/// expansions (solid harmonics of order `p`) the octree's boxes carry; a
/// target box and a source box interact through them (M2L) when
/// `2 max(s_T, s_S) <= 0.95 d` and their gap is at least the distance at
/// which the softened or repulsive law is `1/r` within the tolerance
/// (`eps sqrt(1.5 / tol)`, `a tol^(-1/4)`); a leaf and a smaller box with
/// `s_B <= 0.5 (d - s_L)` by `B`'s multipole at the leaf's bodies and the
/// leaf's bodies into `B`'s local (M2P and P2L, the W and X lists);
/// otherwise the larger one is split, and two leaves meet pair by pair
/// with the law itself, each pair once (across target groups too). Each particle's sum runs in an order
/// fixed by the tree, so 1 and N threads give the same bits.
#[derive(Debug)]
pub struct GravityFmm {
    accuracy: FmmAccuracy,
    law: GravityLaw,
    laplace: Laplace,
    engine: Engine<Laplace>,
    /// The bodies relative to the middle of their bounding box.
    shifted: Vec<[f64; 3]>,
    /// Every rank's bodies of a spread evaluation ([`GravityFmm::compute_spread`]).
    gathered: Gathered,
}

/// Every rank's bodies and their field, for [`GravityFmm::compute_spread`]:
/// the ranks' body counts, `x y z m` per body as gathered, then as arrays
/// (kept from call to call).
#[derive(Debug, Default)]
struct Gathered {
    /// Per rank: its bodies, then the numbers it sends (`4` per body).
    counts: Vec<f64>,
    sizes: Vec<usize>,
    rows: Vec<f64>,
    mine: Vec<f64>,
    position: Vec<[f64; 3]>,
    mass: Vec<f64>,
    acc: Vec<[f64; 3]>,
    phi: Vec<f64>,
}

impl GravityFmm {
    /// The gap below which the fmm for `law` at `accuracy` meets two boxes
    /// pair by pair whatever their sizes: where the law is not yet `1/r`
    /// within the tolerance `tol`. The softened law
    /// `1 / sqrt(r^2 + eps^2) = (1 / r) (1 - eps^2 / (2 r^2) + ...)` is
    /// within `tol` of `1/r` (its field within `1.5 eps^2 / r^2`) beyond
    /// `eps sqrt(1.5 / tol)`, the repulsion beyond `a tol^(-1/4)`; the
    /// larger of the two (0 for the plain law).
    pub fn direct_reach(law: &GravityLaw, accuracy: FmmAccuracy) -> f64 {
        let tolerance = accuracy.tolerance(ErrorFit::LAPLACE_3D);
        let softened = law.softening() * (1.5 / tolerance).sqrt();
        let repelled = law.repulsion_radius() * tolerance.powf(-0.25);
        softened.max(repelled)
    }

    /// A solver for `law` at `accuracy` (checked).
    pub fn new(law: GravityLaw, accuracy: FmmAccuracy) -> Result<Self, String> {
        accuracy.check()?;
        Ok(GravityFmm {
            accuracy,
            law,
            laplace: Laplace {
                order: accuracy.order(ErrorFit::LAPLACE_3D),
                kernel: Kernel::new(&law),
                repulsion: law.has_repulsion(),
                reach: Self::direct_reach(&law, accuracy),
                x: Default::default(),
                m: Vec::new(),
            },
            engine: Engine::default(),
            shifted: Vec::new(),
            gathered: Gathered::default(),
        })
    }

    /// The accuracy asked for.
    pub fn accuracy(&self) -> FmmAccuracy {
        self.accuracy
    }

    /// The expansions' order `p`.
    pub fn order(&self) -> usize {
        self.laplace.order
    }

    /// `(box, particle pair)` interactions of the last evaluation (M2L, M2P
    /// and P2L; of this rank's target groups, for
    /// [`compute_spread`](Self::compute_spread)).
    pub fn interactions(&self) -> (u64, u64) {
        self.engine.interactions
    }

    /// The M2P and P2L (the W and X lists) among the last evaluation's box
    /// interactions.
    pub fn near_interactions(&self) -> u64 {
        self.engine.near
    }

    /// Fills `out` with the accelerations and potentials of `sources` (see
    /// [`GravityFmm`]).
    ///
    /// The bodies are taken relative to the middle of their bounding box
    /// (`engine::shift_to_middle`).
    pub fn compute(&mut self, sources: &Sources, out: FieldOut, threads: &Threads) {
        self.compute_shared(sources, out, threads, &mut Whole);
    }

    /// [`compute`](Self::compute) on the ranks of `exchange`, each holding a
    /// block of the bodies (`sources`), the blocks in rank order making the
    /// input order: every rank gathers every body (`x y z m`), builds the
    /// same tree and makes the same upward pass, sums its run of the target
    /// groups ([`AmongPeers`]) and keeps the field of its own block, which
    /// has one process's bits. Each rank holds every body (in buffers kept
    /// from call to call).
    pub fn compute_spread(
        &mut self,
        sources: &Sources,
        out: FieldOut,
        threads: &Threads,
        exchange: &dyn Exchange,
    ) {
        let (rank, ranks) = (exchange.rank(), exchange.ranks());
        let n = sources.mass.len();
        assert_eq!(sources.position.len(), n);
        let g = &mut self.gathered;
        g.sizes.clear();
        g.sizes.resize(ranks, 1);
        g.counts.clear();
        g.counts.resize(ranks, 0.0);
        exchange.all_gather(&[n as f64], &g.sizes, &mut g.counts);
        g.sizes.clear();
        g.sizes.extend(g.counts.iter().map(|&c| 4 * c as usize));
        g.mine.clear();
        for (x, &m) in sources.position.iter().zip(sources.mass) {
            g.mine.extend_from_slice(&[x[0], x[1], x[2], m]);
        }
        g.rows.clear();
        g.rows.resize(g.sizes.iter().sum(), 0.0);
        exchange.all_gather(&g.mine, &g.sizes, &mut g.rows);
        g.position.clear();
        g.position
            .extend(g.rows.chunks_exact(4).map(|b| [b[0], b[1], b[2]]));
        g.mass.clear();
        g.mass.extend(g.rows.chunks_exact(4).map(|b| b[3]));
        let total = g.mass.len();
        g.acc.resize(total, [0.0; 3]);
        g.phi.resize(total, 0.0);
        let mut g = std::mem::take(&mut self.gathered);
        let everyone = Sources {
            mass: &g.mass,
            position: &g.position,
        };
        let field = FieldOut {
            acc: &mut g.acc,
            phi: &mut g.phi,
        };
        self.compute_shared(&everyone, field, threads, &mut AmongPeers::new(exchange));
        let first = g.sizes[..rank].iter().sum::<usize>() / 4;
        out.acc.copy_from_slice(&g.acc[first..first + n]);
        out.phi.copy_from_slice(&g.phi[first..first + n]);
        self.gathered = g;
    }

    /// [`compute`](Self::compute) divided by `share` among processes that
    /// hold the same bodies.
    fn compute_shared(
        &mut self,
        sources: &Sources,
        out: FieldOut,
        threads: &Threads,
        share: &mut dyn Share,
    ) {
        let position = sources.position;
        assert_eq!(position.len(), sources.mass.len());
        shift_to_middle(position, &mut self.shifted);
        self.engine.build(&self.shifted, threads);
        let l = &mut self.laplace;
        for c in l.x.iter_mut() {
            c.clear();
        }
        l.m.clear();
        for &i in &self.engine.tree.order {
            let i = i as usize;
            for a in 0..3 {
                l.x[a].push(self.shifted[i][a]);
            }
            l.m.push(sources.mass[i]);
        }
        self.engine.evaluate(&self.laplace, threads, share);
        let g = self.law.g();
        for (&i, f) in self.engine.tree.order.iter().zip(&self.engine.sorted) {
            let i = i as usize;
            out.acc[i] = [g * f[0], g * f[1], g * f[2]];
            out.phi[i] = -g * f[3];
        }
    }
}

/// The Laplace sum's expansions and gravity's pair law, on the bodies in
/// tree order.
#[derive(Debug)]
struct Laplace {
    order: usize,
    kernel: Kernel,
    repulsion: bool,
    reach: f64,
    x: [Vec<f64>; 3],
    m: Vec<f64>,
}

/// A thread's buffers: the harmonics of one point and of
/// [`solid::LANES`] points, M2L's lanes, and a leaf's reactions (x, y, z,
/// potential).
#[derive(Debug, Default)]
struct Scratch {
    harmonics: Vec<Complex64>,
    lanes: (Vec<F64x8>, Vec<F64x8>),
    /// The lanes' harmonics, term by term, lane after lane within a term.
    spread: Vec<f64>,
    turned: M2lLanes,
    /// A group's far pairs `(direction, target, source)`.
    far: FarPairs,
    reactions: [Vec<f64>; 4],
}

impl Expansions for Laplace {
    /// `[dPhi/dx, dPhi/dy, dPhi/dz, Phi]` of `Phi = sum m_j / r_j` (the
    /// law's factors in the near field).
    type Sum = [f64; 4];
    const WIDTH: usize = 4;
    type Scratch = Scratch;
    const THETA: f64 = THETA;
    /// Target groups of at most `n / 4` bodies (8 groups, the root's
    /// children, up to 10^6 uniform bodies) and at most [`GROUP`].
    fn sizes(n: usize) -> Sizes {
        Sizes {
            leaf: LEAF,
            group: (n / 4).clamp(LEAF, GROUP),
        }
    }
    const FILL: Option<usize> = Some(FILL);

    fn near_expansions(&self) -> Option<(f64, usize)> {
        Some((NEAR_RHO, near_least(self.order)))
    }

    fn m2p(
        &self,
        multipole: &[Complex64],
        cube: Cube,
        particles: Range<usize>,
        out: &mut [[f64; 4]],
        scratch: &mut Scratch,
    ) {
        let inv = 1.0 / cube.radius;
        let (re, im) = lanes(&mut scratch.lanes, solid::terms(self.order + 1));
        for (first, f) in particles.step_by(LANES).zip(out.chunks_mut(LANES)) {
            let w = self.scaled_padded(first, f.len(), cube.centre, inv);
            solid::irregular_lanes(w, self.order + 1, re, im);
            let got = solid::m2p_lanes(self.order, multipole, inv, (re, im));
            add_lanes(got, f);
        }
    }

    fn p2l(
        &self,
        particles: Range<usize>,
        cube: Cube,
        local: &mut [Complex64],
        scratch: &mut Scratch,
    ) {
        let inv = 1.0 / cube.radius;
        let (re, im) = lanes(&mut scratch.lanes, solid::terms(self.order));
        for first in particles.clone().step_by(LANES) {
            let count = LANES.min(particles.end - first);
            let u = self.scaled_padded(first, count, cube.centre, inv);
            solid::irregular_lanes(u, self.order, re, im);
            let q: [f64; LANES] = std::array::from_fn(|l| {
                if l < count {
                    self.m[first + l] * inv
                } else {
                    0.0
                }
            });
            solid::p2l_lanes(self.order, F64x8::load(&q), count, (re, im), local);
        }
    }

    /// Measured at order 14 on 10^5 uniform bodies (perf of one evaluation:
    /// M2L and the pairs): 2800 pair terms, `0.8 (p + 1)^3`.
    fn m2l_cost(&self) -> f64 {
        0.8 * ((self.order + 1) as f64).powi(3)
    }

    fn numbers(sums: &mut [Self::Sum]) -> &mut [f64] {
        sums.as_flattened_mut()
    }

    fn terms(&self) -> usize {
        solid::terms(self.order)
    }

    fn reach(&self) -> f64 {
        self.reach
    }

    fn cube(&self, node: &Node) -> Cube {
        Cube::around(node)
    }

    fn p2m(
        &self,
        particles: Range<usize>,
        cube: Cube,
        multipole: &mut [Complex64],
        scratch: &mut Scratch,
    ) {
        let terms = self.terms();
        let inv = 1.0 / cube.radius;
        let (re, im) = lanes(&mut scratch.lanes, terms);
        let spread = &mut scratch.spread;
        spread.resize(2 * terms * LANES, 0.0);
        let whole = particles.start + particles.len() / LANES * LANES;
        for first in (particles.start..whole).step_by(LANES) {
            let w = self.scaled(first, cube.centre, inv);
            solid::regular_lanes(w, self.order, re, im);
            let (spread_re, spread_im) = spread.split_at_mut(terms * LANES);
            for t in 0..terms {
                re[t].store(&mut spread_re[t * LANES..]);
                im[t].store(&mut spread_im[t * LANES..]);
            }
            // each body in turn, its terms in order: the bits of `solid::p2m`
            for (lane, q) in self.m[first..first + LANES].iter().enumerate() {
                for (t, m) in multipole.iter_mut().enumerate() {
                    let r =
                        Complex64::new(spread_re[t * LANES + lane], spread_im[t * LANES + lane]);
                    *m += q * r.conj();
                }
            }
        }
        let harmonics = harmonics(&mut scratch.harmonics, terms);
        let rest =
            (whole..particles.end).map(|s| ([self.x[0][s], self.x[1][s], self.x[2][s]], self.m[s]));
        solid::p2m(
            self.order,
            rest,
            cube.centre,
            cube.radius,
            harmonics,
            multipole,
        );
    }

    fn m2m(
        &self,
        child: &[Complex64],
        from: Cube,
        parent: &mut [Complex64],
        to: Cube,
        scratch: &mut Scratch,
    ) {
        let (from, to) = ((from.centre, from.radius), (to.centre, to.radius));
        let h = &mut scratch.harmonics;
        solid::shift_each(solid::m2m, self.order, child, from, parent, to, h);
    }

    fn m2l(
        &self,
        multipoles: &[Complex64],
        cubes: &[Cube],
        group: usize,
        starts: &[usize],
        sources: &[u32],
        locals: &mut [Complex64],
        scratch: &mut Scratch,
    ) {
        let far = (group, starts, sources);
        let turned = (&mut scratch.far, &mut scratch.turned);
        m2l_by_direction(self.order, 1, multipoles, cubes, far, locals, turned);
    }

    fn l2l(
        &self,
        parent: &[Complex64],
        from: Cube,
        child: &mut [Complex64],
        to: Cube,
        scratch: &mut Scratch,
    ) {
        let (from, to) = ((from.centre, from.radius), (to.centre, to.radius));
        let h = &mut scratch.harmonics;
        solid::shift_each(solid::l2l, self.order, parent, from, child, to, h);
    }

    fn l2p(
        &self,
        local: &[Complex64],
        cube: Cube,
        particles: Range<usize>,
        out: &mut [[f64; 4]],
        scratch: &mut Scratch,
    ) {
        let terms = self.terms();
        let inv = 1.0 / cube.radius;
        let (re, im) = lanes(&mut scratch.lanes, terms);
        let whole = particles.len() / LANES * LANES;
        let (lanes_out, rest_out) = out.split_at_mut(whole);
        for (first, f) in (particles.start..)
            .step_by(LANES)
            .zip(lanes_out.chunks_exact_mut(LANES))
        {
            let w = self.scaled(first, cube.centre, inv);
            solid::regular_lanes(w, self.order, re, im);
            let got = solid::l2p_lanes(self.order, local, inv, (re, im));
            add_lanes(got, f);
        }
        let h = harmonics(&mut scratch.harmonics, terms);
        for (s, f) in (particles.start + whole..particles.end).zip(rest_out) {
            let x = [self.x[0][s], self.x[1][s], self.x[2][s]];
            let got = solid::l2p(self.order, local, cube.centre, cube.radius, x, h);
            for a in 0..4 {
                f[a] += got[a];
            }
        }
    }

    fn pairs(
        &self,
        how: Pairs,
        targets: Range<usize>,
        sources: Range<usize>,
        mine: &mut [[f64; 4]],
        theirs: &mut [[f64; 4]],
        scratch: &mut Scratch,
    ) -> u64 {
        let reactions = &mut scratch.reactions;
        if self.repulsion {
            self.leaf_pairs::<true>(how, targets, sources, mine, theirs, reactions)
        } else {
            self.leaf_pairs::<false>(how, targets, sources, mine, theirs, reactions)
        }
    }
}

/// `sums += got`, part by part.
#[inline(always)]
fn add(sums: &mut [f64; 4], got: [f64; 4]) {
    for (s, g) in sums.iter_mut().zip(got) {
        *s += g;
    }
}

/// Adds lane `i` of the words `got` (`[dPhi/dx, dPhi/dy, dPhi/dz, Phi]` of
/// [`LANES`] bodies) to `sums[i]`, for each of the `sums` (at most
/// [`LANES`]).
fn add_lanes(got: [F64x8; 4], sums: &mut [[f64; 4]]) {
    let mut values = [[0.0; LANES]; 4];
    for (v, g) in values.iter_mut().zip(got) {
        g.store(v);
    }
    for (lane, f) in sums.iter_mut().enumerate() {
        for a in 0..4 {
            f[a] += values[a][lane];
        }
    }
}

impl Laplace {
    /// [`scaled`](Self::scaled) of the `count` (at most [`LANES`]) bodies
    /// from `first` on, the last one again in the lanes past them.
    fn scaled_padded(&self, first: usize, count: usize, centre: [f64; 3], inv: f64) -> [F64x8; 3] {
        std::array::from_fn(|a| {
            let x: [f64; LANES] = std::array::from_fn(|l| self.x[a][first + l.min(count - 1)]);
            (F64x8::load(&x) - F64x8::splat(centre[a])) * F64x8::splat(inv)
        })
    }

    /// `(x - c) / s` (`inv = 1 / s`) of the [`LANES`] sorted bodies from
    /// `first` on, as `solid`'s scalar functions compute it.
    #[inline(always)]
    fn scaled(&self, first: usize, centre: [f64; 3], inv: f64) -> [F64x8; 3] {
        std::array::from_fn(|a| {
            (F64x8::load(&self.x[a][first..]) - F64x8::splat(centre[a])) * F64x8::splat(inv)
        })
    }

    /// The rows of the targets `ids` against the source leaf `sources` (for
    /// [`Pairs::Within`], one target against the leaf's later particles),
    /// the reactions added to `reactions`.
    fn target_rows<const REPULSION: bool, const T: usize>(
        &self,
        how: Pairs,
        ids: [usize; T],
        sources: &Range<usize>,
        reactions: &mut [Vec<f64>; 4],
    ) -> [[f64; 4]; T] {
        debug_assert!(how != Pairs::Within || T == 1);
        let xi = ids.map(|i| [self.x[0][i], self.x[1][i], self.x[2][i]]);
        let mi = ids.map(|i| self.m[i]);
        let partners = match how {
            Pairs::Within => ids[0] + 1..sources.end,
            Pairs::Both => sources.clone(),
        };
        let from = partners.start - sources.start;
        let px = self.x.each_ref().map(|c| &c[partners.clone()]);
        let pm = &self.m[partners];
        let theirs = Block::new(reactions.each_mut().map(|r| &mut r[from..]));
        self.kernel
            .rows::<F64x8, REPULSION, true, true, T>(xi, mi, px, pm, theirs)
    }

    /// [`Expansions::pairs`]: two targets at a time against the source leaf
    /// (the direct sum's rows; a leaf with itself one at a time, against
    /// its later particles only), each pair once, its reaction summed per
    /// source and added after the target loop.
    fn leaf_pairs<const REPULSION: bool>(
        &self,
        how: Pairs,
        targets: Range<usize>,
        sources: Range<usize>,
        mine: &mut [[f64; 4]],
        theirs: &mut [[f64; 4]],
        reactions: &mut [Vec<f64>; 4],
    ) -> u64 {
        let len = sources.len();
        for r in reactions.iter_mut() {
            r.clear();
            r.resize(len, 0.0);
        }
        let first = targets.start;
        // two targets at a time against the same partners (a leaf with itself:
        // one, as each has its own later partners)
        let mut i = targets.start;
        while i < targets.end {
            let next = if how != Pairs::Within && i + 1 < targets.end {
                let got = self.target_rows::<REPULSION, 2>(how, [i, i + 1], &sources, reactions);
                for (t, g) in [i, i + 1].into_iter().zip(got) {
                    add(&mut mine[t - first], g);
                }
                i + 2
            } else {
                let [got] = self.target_rows::<REPULSION, 1>(how, [i], &sources, reactions);
                add(&mut mine[i - first], got);
                i + 1
            };
            i = next;
        }
        let at_sources = if how == Pairs::Within { mine } else { theirs };
        for (k, sum) in at_sources[..len].iter_mut().enumerate() {
            add(sum, reactions.each_ref().map(|r| r[k]));
        }
        how.terms(targets.len(), len)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::longrange::DirectSum;
    use crate::random::Rng;

    /// `n` bodies uniformly in the unit cube, or (`clustered`) half of them
    /// in a small ball's cube, with masses in `[0.5, 1.5)`.
    fn bodies(seed: u64, n: usize, clustered: bool) -> (Vec<[f64; 3]>, Vec<f64>) {
        let mut rng = Rng::new(seed);
        let x = (0..n)
            .map(|i| {
                let p = [rng.uniform(), rng.uniform(), rng.uniform()];
                if clustered && i % 2 == 0 {
                    p.map(|v| 0.4 + 0.01 * v)
                } else {
                    p
                }
            })
            .collect();
        let m = (0..n).map(|_| 0.5 + rng.uniform()).collect();
        (x, m)
    }

    fn field(
        solver: &mut impl FnMut(&Sources, FieldOut),
        x: &[[f64; 3]],
        m: &[f64],
    ) -> (Vec<[f64; 3]>, Vec<f64>) {
        let mut acc = vec![[0.0; 3]; x.len()];
        let mut phi = vec![0.0; x.len()];
        let sources = Sources {
            position: x,
            mass: m,
        };
        solver(
            &sources,
            FieldOut {
                acc: &mut acc,
                phi: &mut phi,
            },
        );
        (acc, phi)
    }

    /// `(RMS |e| / RMS |a|, max |e| / max |a|)` of the accelerations.
    fn errors(got: &[[f64; 3]], want: &[[f64; 3]]) -> (f64, f64) {
        let norm = |v: &[f64; 3]| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        let diff: Vec<f64> = got
            .iter()
            .zip(want)
            .map(|(g, w)| norm(&[g[0] - w[0], g[1] - w[1], g[2] - w[2]]))
            .collect();
        let rms = (diff.iter().map(|d| d * d).sum::<f64>()
            / want.iter().map(|w| norm(w).powi(2)).sum::<f64>())
        .sqrt();
        let max =
            diff.iter().copied().fold(0.0, f64::max) / want.iter().map(norm).fold(0.0, f64::max);
        (rms, max)
    }

    /// Uniform and clustered bodies, with and without softening: at every
    /// tolerance from 1e-3 to 1e-10 the RMS and largest errors of the
    /// accelerations, and the potentials', stay below the tolerance.
    #[test]
    fn errors_stay_below_the_tolerance() {
        let one = Threads::single();
        for (clustered, eps) in [(false, 0.0), (true, 0.0), (false, 1e-4)] {
            let (x, m) = bodies(5, 6000, clustered);
            let law = GravityLaw::new(1.0, eps, 0.0).unwrap();
            let mut direct = DirectSum::new(law, x.len());
            let (want, want_phi) = field(&mut |s, o| direct.compute(s, o, &one), &x, &m);
            for tolerance in [1e-3, 1e-6, 1e-8, 1e-10] {
                let mut fmm = GravityFmm::new(law, FmmAccuracy::Tolerance(tolerance)).unwrap();
                let (got, phi) = field(&mut |s, o| fmm.compute(s, o, &one), &x, &m);
                let (rms, max) = errors(&got, &want);
                let phi_err = phi
                    .iter()
                    .zip(&want_phi)
                    .map(|(a, b)| (a - b).abs())
                    .fold(0.0, f64::max)
                    / want_phi.iter().map(|p| p.abs()).fold(0.0, f64::max);
                eprintln!(
                    "clustered {clustered} eps {eps} tol {tolerance:e} p {}: rms {rms:e} max {max:e} phi {phi_err:e} {:?}",
                    fmm.order(),
                    fmm.interactions()
                );
                assert!(rms < tolerance && max < tolerance && phi_err < tolerance);
                // the small ball's leaves meet the larger ones around it by
                // M2P and P2L
                assert_eq!(clustered, fmm.near_interactions() > 0);
                if eps == 0.0 {
                    let m2l = fmm.interactions().0 - fmm.near_interactions();
                    assert!(m2l > 0, "no M2L at all");
                }
            }
        }
    }

    /// Bodies 1e10 from the origin (spread 1): the boxes' directions stay
    /// those of the grid, and the error stays below the tolerance.
    #[test]
    fn far_from_the_origin_the_error_holds() {
        let one = Threads::single();
        let (x, m) = bodies(7, 4000, true);
        let x: Vec<[f64; 3]> = x.iter().map(|p| p.map(|v| v + 1e10)).collect();
        let law = GravityLaw::new(1.0, 0.0, 0.0).unwrap();
        let mut direct = DirectSum::new(law, x.len());
        let (want, _) = field(&mut |s, o| direct.compute(s, o, &one), &x, &m);
        let mut fmm = GravityFmm::new(law, FmmAccuracy::Tolerance(1e-8)).unwrap();
        let (got, _) = field(&mut |s, o| fmm.compute(s, o, &one), &x, &m);
        let (rms, max) = errors(&got, &want);
        assert!(rms < 1e-8 && max < 1e-8, "{rms:e} {max:e}");
        assert!(fmm.interactions().0 > 0);
    }

    /// P2M and L2P over a leaf, eight bodies at a time and the rest one by
    /// one, give the bits of `solid`'s one-body-at-a-time functions.
    #[test]
    fn leaf_expansions_give_the_bits_of_one_body_at_a_time() {
        let (x, m) = bodies(13, 21, false);
        let law = GravityLaw::new(1.0, 0.0, 0.0).unwrap();
        let mut fmm = GravityFmm::new(law, FmmAccuracy::Order(9)).unwrap();
        let l = &mut fmm.laplace;
        for a in 0..3 {
            l.x[a] = x.iter().map(|p| p[a]).collect();
        }
        l.m = m.clone();
        let cube = Cube {
            centre: [0.5, 0.4, 0.6],
            radius: 0.9,
        };
        let terms = l.terms();
        let zero = Complex64::new(0.0, 0.0);
        let mut scratch = Scratch::default();
        let bits = |v: &[Complex64]| {
            v.iter()
                .map(|c| (c.re.to_bits(), c.im.to_bits()))
                .collect::<Vec<_>>()
        };
        for range in [0..21, 3..19, 5..13, 2..4] {
            let mut got = vec![zero; terms];
            l.p2m(range.clone(), cube, &mut got, &mut scratch);
            let mut want = vec![zero; terms];
            let mut h = vec![zero; terms];
            let each = range.clone().map(|s| (x[s], m[s]));
            solid::p2m(l.order, each, cube.centre, cube.radius, &mut h, &mut want);
            assert_eq!(bits(&got), bits(&want), "p2m {range:?}");
            let mut sums = vec![[0.0; 4]; range.len()];
            l.l2p(&want, cube, range.clone(), &mut sums, &mut scratch);
            for (s, f) in range.clone().zip(&sums) {
                let one = solid::l2p(l.order, &want, cube.centre, cube.radius, x[s], &mut h);
                assert_eq!(
                    f.map(f64::to_bits),
                    one.map(f64::to_bits),
                    "l2p {range:?} body {s}"
                );
            }
        }
    }

    /// Softened (pairs within the reach) and plain (M2P and P2L between
    /// the small ball's leaves and the larger ones around it): 1 and 2
    /// threads give the same bits.
    #[test]
    fn threads_give_the_same_bits() {
        let (x, m) = bodies(9, 9000, true);
        for eps in [0.001, 0.0] {
            let law = GravityLaw::new(1.0, eps, 0.0).unwrap();
            let run = |threads: &Threads| {
                let mut fmm = GravityFmm::new(law, FmmAccuracy::Tolerance(1e-6)).unwrap();
                let out = field(&mut |s, o| fmm.compute(s, o, threads), &x, &m);
                (out, fmm.near_interactions())
            };
            let ((a1, p1), near) = run(&Threads::single());
            let ((a2, p2), _) = run(&Threads::new(2).unwrap());
            assert_eq!(eps == 0.0, near > 0, "eps {eps}: {near} M2P and P2L");
            assert!(a1
                .iter()
                .zip(&a2)
                .all(|(a, b)| a.map(f64::to_bits) == b.map(f64::to_bits)));
            assert!(p1.iter().zip(&p2).all(|(a, b)| a.to_bits() == b.to_bits()));
        }
    }

    /// Bodies divided among 1 to 4 thread-ranks in blocks of the input order
    /// (uneven, and empty for 3 bodies on 4 ranks): every rank's block gets
    /// the bits of one process's evaluation, twice, and the ranks'
    /// interactions add up to the whole run's (3000 bodies make 8 target
    /// groups, whose pairs across groups one rank sums for both and
    /// gathers; unsoftened, M2P and P2L too).
    #[test]
    fn spread_bodies_get_one_process_bits() {
        use crate::longrange::mesh::slab::testkit::Hub;
        let accuracy = FmmAccuracy::Tolerance(1e-6);
        let threads = Threads::new(2).unwrap();
        for (n, clustered, eps) in [(3000, true, 0.01), (3000, true, 0.0), (3, false, 0.01)] {
            let law = GravityLaw::new(1.0, eps, 0.0).unwrap();
            let (x, m) = bodies(5, n, clustered);
            let mut whole = GravityFmm::new(law, accuracy).unwrap();
            let want = field(&mut |s, o| whole.compute(s, o, &threads), &x, &m);
            assert_eq!(eps == 0.0, whole.near_interactions() > 0);
            for ranks in 1..=4 {
                // rank r holds the bodies from n r^2 / ranks^2 on
                let start = |r: usize| n * r * r / (ranks * ranks);
                let got = Hub::run(ranks, |exchange| {
                    let r = exchange.rank();
                    let own = start(r)..start(r + 1);
                    let mut fmm = GravityFmm::new(law, accuracy).unwrap();
                    let (x, m) = (&x[own.clone()], &m[own]);
                    let mut spread =
                        |s: &Sources, o: FieldOut| fmm.compute_spread(s, o, &threads, exchange);
                    let fields = [field(&mut spread, x, m), field(&mut spread, x, m)];
                    (fields, fmm.interactions())
                });
                // the ranks' groups are the whole run's
                let sum = got.iter().fold((0, 0), |a, (_, c)| (a.0 + c.0, a.1 + c.1));
                assert_eq!(sum, whole.interactions(), "{n} bodies on {ranks} ranks");
                for (r, (evaluations, _)) in got.iter().enumerate() {
                    let own = start(r)..start(r + 1);
                    for (acc, phi) in evaluations {
                        let bits = |v: &[f64]| v.iter().map(|c| c.to_bits()).collect::<Vec<_>>();
                        assert_eq!(
                            bits(acc.as_flattened()),
                            bits(want.0[own.clone()].as_flattened())
                        );
                        assert_eq!(
                            bits(phi),
                            bits(&want.1[own.clone()]),
                            "{n} bodies, rank {r} of {ranks}"
                        );
                    }
                }
            }
        }
    }
}
