//! The fast multipole method in 2D for vortex velocities: complex-variable
//! expansions ([`super::complex`]) on the quadtree the Barnes-Hut solvers build
//! (the octree of the particles lifted to `z = 0`), the shared traversal
//! ([`super::engine`]), and the blob law in the near field.

use super::super::build::{Node, Sizes};
use super::super::share::{Share, Whole};
use super::complex::{l2l, l2p, m2l, m2m, p2m, Binomials};
use super::engine::{Cube, Engine, Expansions, Pairs};
use super::{ErrorFit, FmmAccuracy};
use crate::longrange::biot_savart::{assert_lengths, row, VortexLaw};
use crate::threads::Threads;
use rustfft::num_complex::Complex64;
use std::f64::consts::PI;
use std::ops::Range;

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

impl ErrorFit {
    /// The 2D vortex FMM's fit: the largest error (over the largest speed)
    /// of 10^6 uniform points falls 2.2-fold (0.45) per order from `p = 12`
    /// to `p = 18` (the worst case of THETA 0.85, 0.74 per order, assumes
    /// every box at the limit), and `0.05 0.45^p` bounds the largest error
    /// measured at order `p` with a margin of 3 or more (uniform and
    /// clustered points, points and blobs).
    pub const VORTEX_2D: ErrorFit = ErrorFit {
        decay: 0.45,
        at_zero: 0.05,
        least: 1,
        knee: None,
    };
}

/// Most particles in a leaf: a leaf's particles meet the leaves beside it
/// pair by pair.
const LEAF: usize = 32;

/// Most particles in a target group: the groups traverse the tree in
/// parallel (a function of the particles only, so the result does not
/// depend on the thread count).
const GROUP: usize = 4096;

/// The fast multipole method for 2D vortex velocities,
///
/// `u(x_i) = sum_j Gamma_j q(|x_i - x_j|^2) (-(y_i - y_j), x_i - x_j)`
///
/// with the pair law `q` of `K` ([`BlobKernel`](crate::longrange::BlobKernel)
/// or [`PointVortex`](crate::longrange::PointVortex)). Far
/// apart, the law is the point vortex's, `u - i v = sum_j Gamma_j / (2 pi i
/// (z - z_j))`, a Cauchy sum whose complex multipole and local expansions
/// (order `p`) the boxes of the quadtree carry. Each target group (a subtree
/// of at most 4096 particles) makes the traversal of the whole tree along
/// the boxes that hold it and then its own (`fmm/engine.rs`):
/// a target box `T` and a source box `S` whose radii and centre distance
/// satisfy `2 max(s_T, s_S) <= 0.85 d` and whose gap `d - s_T - s_S` is at
/// least the law's reach ([`VortexLaw::reach`]) interact through M2L; otherwise the
/// larger of the two is split (a leaf never is: then the other one), and two
/// leaves meet pair by pair with the law itself, each pair once (across
/// groups by the earlier group). Then the group's locals move down (L2L)
/// and are evaluated at its particles (L2P).
///
/// The error of one M2L is below `4 0.74^(p + 1)` relative to the source
/// box's field; the measured errors fall faster, about 2.2-fold (0.45) per
/// order, and the order is the least `p` with `0.05 0.45^p <= tolerance`
/// ([`FmmAccuracy::order`] with [`ErrorFit::VORTEX_2D`]). Each particle's sum runs in an order fixed by
/// the tree, so 1 and N threads give the same bits.
#[derive(Debug)]
pub struct VortexFmm<K: VortexLaw> {
    accuracy: FmmAccuracy,
    cauchy: Cauchy<K>,
    engine: Engine<Cauchy<K>>,
    lifted: Vec<[f64; 3]>,
}

impl<K: VortexLaw> VortexFmm<K> {
    /// A solver for the pair law `law` at `accuracy` (checked).
    pub fn new(law: K, accuracy: FmmAccuracy) -> Result<Self, String> {
        accuracy.check()?;
        let reach = law.reach(accuracy.tolerance(ErrorFit::VORTEX_2D));
        Ok(VortexFmm {
            accuracy,
            cauchy: Cauchy {
                law,
                reach,
                binomials: Binomials::new(accuracy.order(ErrorFit::VORTEX_2D)),
                x: Vec::new(),
                y: Vec::new(),
                gamma: Vec::new(),
            },
            engine: Engine::default(),
            lifted: Vec::new(),
        })
    }

    /// The accuracy asked for.
    pub fn accuracy(&self) -> FmmAccuracy {
        self.accuracy
    }

    /// The expansions' order `p`.
    pub fn order(&self) -> usize {
        self.cauchy.binomials.order()
    }

    /// `(M2L, particle pair)` interactions of the last evaluation (of this
    /// process's part, for [`compute_shared`](Self::compute_shared)).
    pub fn interactions(&self) -> (u64, u64) {
        self.engine.interactions
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
        self.compute_shared(positions, gamma, velocity, threads, &mut Whole);
    }

    /// [`compute`](Self::compute) divided among processes that each hold
    /// every particle (see [`Share`]): each makes the upward pass, sums only
    /// the target groups of its part, and receives the others' sums, which
    /// have the bits of the undivided evaluation.
    pub fn compute_shared(
        &mut self,
        positions: &[[f64; 2]],
        gamma: &[f64],
        velocity: &mut [[f64; 2]],
        threads: &Threads,
        share: &mut dyn Share,
    ) {
        assert_lengths(positions, gamma, velocity);
        self.lifted.clear();
        self.lifted
            .extend(positions.iter().map(|p| [p[0], p[1], 0.0]));
        self.engine.build(&self.lifted, threads);
        let c = &mut self.cauchy;
        c.x.clear();
        c.y.clear();
        c.gamma.clear();
        for &i in &self.engine.tree.order {
            let i = i as usize;
            c.x.push(positions[i][0]);
            c.y.push(positions[i][1]);
            c.gamma.push(gamma[i]);
        }
        self.engine.evaluate(&self.cauchy, threads, share);
        for (&i, u) in self.engine.tree.order.iter().zip(&self.engine.sorted) {
            velocity[i as usize] = *u;
        }
    }
}

/// The Cauchy sum's expansions and the pair law `K`, on the particles in
/// tree order.
#[derive(Debug)]
struct Cauchy<K: VortexLaw> {
    law: K,
    reach: f64,
    binomials: Binomials,
    x: Vec<f64>,
    y: Vec<f64>,
    gamma: Vec<f64>,
}

/// A box's centre as a complex number.
fn complex(cube: Cube) -> Complex64 {
    Complex64::new(cube.centre[0], cube.centre[1])
}

impl<K: VortexLaw> Expansions for Cauchy<K> {
    type Sum = [f64; 2];
    const WIDTH: usize = 2;
    /// A source leaf's reactions per axis.
    type Scratch = [Vec<f64>; 2];
    const THETA: f64 = THETA;
    fn sizes(_: usize) -> Sizes {
        Sizes {
            leaf: LEAF,
            group: GROUP,
        }
    }
    /// The particles lie in one plane: the octree is a quadtree there, and
    /// its leaves are left as the bounding cube cuts them.
    const FILL: Option<usize> = None;

    /// Measured at order 20 on 10^5 particles (perf of one evaluation: M2L
    /// and the pairs): 99 pair terms, `0.22 (p + 1)^2`.
    fn m2l_cost(&self) -> f64 {
        0.22 * (self.terms() as f64).powi(2)
    }

    fn numbers(sums: &mut [Self::Sum]) -> &mut [f64] {
        sums.as_flattened_mut()
    }

    fn terms(&self) -> usize {
        self.binomials.order() + 1
    }

    fn reach(&self) -> f64 {
        self.reach
    }

    /// The node's square (the plane `z = 0`): its centre and half its
    /// diagonal.
    fn cube(&self, node: &Node) -> Cube {
        Cube {
            centre: [
                node.corner[0] + 0.5 * node.side,
                node.corner[1] + 0.5 * node.side,
                0.0,
            ],
            radius: node.side * std::f64::consts::FRAC_1_SQRT_2,
        }
    }

    /// The circulations enter as `Gamma / (2 pi i)`.
    fn p2m(
        &self,
        particles: Range<usize>,
        cube: Cube,
        multipole: &mut [Complex64],
        _: &mut Self::Scratch,
    ) {
        let charge = Complex64::new(0.0, -0.5 / PI);
        let sources = particles.map(|s| (Complex64::new(self.x[s], self.y[s]), self.gamma[s]));
        p2m(multipole, complex(cube), cube.radius, sources, charge);
    }

    fn m2m(
        &self,
        child: &[Complex64],
        from: Cube,
        parent: &mut [Complex64],
        to: Cube,
        _: &mut Self::Scratch,
    ) {
        let (b, f, t) = (&self.binomials, complex(from), complex(to));
        m2m(b, child, f, from.radius, parent, t, to.radius);
    }

    /// Target by target, each source in the order met.
    fn m2l(
        &self,
        multipoles: &[Complex64],
        cubes: &[Cube],
        group: usize,
        starts: &[usize],
        sources: &[u32],
        locals: &mut [Complex64],
        _: &mut Self::Scratch,
    ) {
        let terms = self.terms();
        for (k, local) in locals.chunks_exact_mut(terms).enumerate() {
            let to = cubes[group + k];
            for &s in &sources[starts[k]..starts[k + 1]] {
                let s = s as usize;
                let a = &multipoles[s * terms..(s + 1) * terms];
                let from = cubes[s];
                let (b, f, t) = (&self.binomials, complex(from), complex(to));
                m2l(b, a, f, from.radius, local, t, to.radius);
            }
        }
    }

    fn l2l(
        &self,
        parent: &[Complex64],
        from: Cube,
        child: &mut [Complex64],
        to: Cube,
        _: &mut Self::Scratch,
    ) {
        let (b, f, t) = (&self.binomials, complex(from), complex(to));
        l2l(b, parent, f, from.radius, child, t, to.radius);
    }

    /// `u - i v` from the local: the velocity is `(re, -im)`.
    fn l2p(
        &self,
        local: &[Complex64],
        cube: Cube,
        particles: Range<usize>,
        out: &mut [[f64; 2]],
        _: &mut Self::Scratch,
    ) {
        for (s, u) in particles.zip(out) {
            let f = l2p(
                local,
                complex(cube),
                cube.radius,
                Complex64::new(self.x[s], self.y[s]),
            );
            u[0] += f.re;
            u[1] -= f.im;
        }
    }

    /// A target at a time against the source leaf ([`row`]); with
    /// [`Pairs::Both`] also the reactions at the sources (`K` is odd), summed
    /// per source and added after the target loop, so that each pair is
    /// computed once. A leaf with itself is summed one-sided (the law is 0 at
    /// `r = 0`).
    fn pairs(
        &self,
        how: Pairs,
        targets: Range<usize>,
        sources: Range<usize>,
        mine: &mut [[f64; 2]],
        theirs: &mut [[f64; 2]],
        scratch: &mut [Vec<f64>; 2],
    ) -> u64 {
        match how {
            Pairs::Both => self.leaf_pairs::<true>(targets, sources, mine, theirs, scratch),
            Pairs::Within => self.leaf_pairs::<false>(targets, sources, mine, theirs, scratch),
        }
    }
}

impl<K: VortexLaw> Cauchy<K> {
    /// [`Expansions::pairs`], with the reactions when `BOTH`.
    fn leaf_pairs<const BOTH: bool>(
        &self,
        targets: Range<usize>,
        sources: Range<usize>,
        mine: &mut [[f64; 2]],
        theirs: &mut [[f64; 2]],
        [ru, rv]: &mut [Vec<f64>; 2],
    ) -> u64 {
        let first = targets.start;
        let partners = [&self.x[sources.clone()], &self.y[sources.clone()]];
        let gamma = &self.gamma[sources.clone()];
        let len = if BOTH { sources.len() } else { 0 };
        for r in [&mut *ru, &mut *rv] {
            r.clear();
            r.resize(len, 0.0);
        }
        for i in targets.clone() {
            let xi = [self.x[i], self.y[i]];
            let reactions = [&mut ru[..], &mut rv[..]];
            let u = row::<K, BOTH>(&self.law, xi, self.gamma[i], partners, gamma, reactions);
            let o = &mut mine[i - first];
            o[0] += u[0];
            o[1] += u[1];
        }
        for (o, (a, b)) in theirs.iter_mut().zip(ru.iter().zip(rv.iter())) {
            o[0] += a;
            o[1] += b;
        }
        let sides = if BOTH { 2 } else { 1 };
        sides * targets.len() as u64 * sources.len() as u64
    }
}

#[cfg(test)]
#[path = "vortex_tests.rs"]
mod tests;
