//! The 3D vortex kernel on the tree: each node's vector moments of `alpha`
//! about the centre of its `|alpha|` (monopole, first and second moments), the
//! Taylor expansion of the regularised stream function they give, and the SIMD
//! sums of a group's lists (the blob law for opened leaves' particles, the
//! expansion for accepted nodes).

use super::build::Node;
use super::share::Whole;
use super::walk::{copy, Group, Lists, Solver, Target, Walk, LANES};
use super::TreeParams;
use crate::longrange::biot_savart3::{assemble, assert_lengths, terms, BlobKernel3, SUMS};
use crate::simd::F64x4;
use crate::threads::Threads;

/// A node's moments about its centre `c`, `y = x_q - c`: `M_c = sum alpha_c`
/// (0..3), `D_cj = sum alpha_c y_j` (3..12, at `3 + 3c + j`) and
/// `Q_cjk = sum alpha_c y_j y_k` (12..30, at `12 + 6c + [xx, xy, xz, yy, yz, zz]`).
type Moments = [f64; MOMENTS];

/// Numbers per node's [`Moments`].
const MOMENTS: usize = 30;

/// The index of `(j, k)` among `[xx, xy, xz, yy, yz, zz]`.
const PAIR: [[usize; 3]; 3] = [[0, 1, 2], [1, 3, 4], [2, 4, 5]];

/// Barnes-Hut for the regularised 3D Biot-Savart law of [`BlobKernel3`]:
///
/// `u(x_i) ~ sum_q alpha_q x r g(|r|)` and its gradient, `r = x_i - x_q`,
///
/// on the same octree and walk as [`BarnesHut`](super::BarnesHut). The law is
/// `u = curl psi` with `psi(x) = sum_q alpha_q G(x - x_q)`, `G` the radial
/// Green's function of the blob (`G'(r) / r = -g`). An accepted node, with
/// centre `c` (the centre of its `|alpha|`), `d = x - c` and the moments
/// `M_c = sum alpha_c`, `D_cj = sum alpha_c y_j`, `Q_cjk = sum alpha_c y_j y_k`
/// of its particles (`y = x_q - c`), gives each component of `psi` to second order,
///
/// `psi_c = M_c G(d) - D_cj d_j G(d) + 1/2 Q_cjk d_j d_k G(d)`
///
/// (`d_j` the derivative along axis `j`), whose first and second derivatives
/// with `f_n = (1/r d/dr)^n G = -g_n` ([`BlobKernel3::radial`]) are
///
/// `d_b psi_c = A d_b - f_1 D_cb + f_2 (Q_c d)_b`,
/// `d_b d_e psi_c = A delta_be + B d_b d_e + f_3 (d_b (Q_c d)_e + (Q_c d)_b d_e)
///  - f_2 (d_b D_ce + D_cb d_e) + f_2 Q_cbe`,
///
/// `A = M_c f_1 + (tr Q_c / 2 - D_c . d) f_2 + (d . Q_c d) f_3 / 2`,
/// `B = M_c f_2 + (tr Q_c / 2 - D_c . d) f_3 + (d . Q_c d) f_4 / 2`,
///
/// and `u_a = eps_abc d_b psi_c`, `d u_a / d x_e = eps_abc d_b d_e psi_c`. The
/// kernel's blob is kept (no clearance): nodes near a target expand the blob
/// law itself. Opened leaves give their particles with the pair law of
/// [`DirectBiotSavart3`](crate::longrange::DirectBiotSavart3), the particle's
/// own term included (it adds `[alpha]_x g(0)` to the gradient).
///
/// Each particle's sum runs in an order fixed by the tree (lists outside,
/// lanes added across at the end), so 1 and N threads give the same bits.
#[derive(Debug)]
pub struct VortexTree3 {
    kernel: BlobKernel3,
    /// `0, 1, ..., N-1`: the walk's per-particle weights, so that the sorted
    /// weights and the lists' weights are input indices, which pick the
    /// particles' strengths.
    index: Vec<f64>,
    solver: Solver<Moments, VortexLists3, SUMS>,
}

impl VortexTree3 {
    /// The default settings: theta 0.4, leaves of 16, groups of 64.
    pub fn default_params() -> TreeParams {
        TreeParams {
            theta: 0.4,
            quadrupole: true,
            leaf_size: 16,
            group_size: 64,
        }
    }

    /// A solver for blobs of `kernel` with `params` (checked; `quadrupole` is
    /// ignored: nodes always carry their second moments).
    pub fn new(params: TreeParams, kernel: BlobKernel3) -> Result<Self, String> {
        let solver = Solver::new(params)?;
        Ok(VortexTree3 {
            kernel,
            index: Vec::new(),
            solver,
        })
    }

    /// `(node, particle)` interactions of the last evaluation.
    pub fn interactions(&self) -> (u64, u64) {
        self.solver.interactions
    }

    /// `velocity[i] = u(x_i)` and `gradient[i][3 a + e] = d u_a / d x_e` at
    /// `x_i`, approximately (see [`VortexTree3`]), for every particle, in input
    /// order.
    pub fn compute(
        &mut self,
        positions: &[[f64; 3]],
        alpha: &[[f64; 3]],
        velocity: &mut [[f64; 3]],
        gradient: &mut [[f64; 9]],
        threads: &Threads,
    ) {
        assert_lengths(positions, alpha, velocity, gradient);
        let n = positions.len();
        if self.index.len() != n {
            self.index = (0..n).map(|i| i as f64).collect();
        }
        let kernel = &self.kernel;
        self.solver.evaluate(
            positions,
            positions,
            &self.index,
            0.0,
            threads,
            &mut Whole,
            |node, walk| of_node(node, walk, alpha),
            |lists: &mut VortexLists3, group, target| {
                lists.gather(&group, alpha);
                lists.evaluate(kernel, &group, target);
                lists.walk.counts(target.len())
            },
        );
        for (i, sums) in self.solver.results() {
            (velocity[i], gradient[i]) = assemble(sums);
        }
    }
}

/// A node's centre of `|alpha|` (its cube's centre if all its strengths are
/// zero) and its [`Moments`] about it; `walk.w` holds the sorted particles'
/// input indices into `alpha`.
fn of_node(node: &Node, walk: &Walk, alpha: &[[f64; 3]]) -> ([f64; 3], Moments) {
    let x = &walk.x;
    let range = node.start as usize..node.end as usize;
    let strength = |s: usize| alpha[walk.w[s] as usize];
    let size = |s: usize| {
        let a = strength(s);
        (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt()
    };
    let weight: f64 = range.clone().map(size).sum();
    let centre: [f64; 3] = std::array::from_fn(|a| {
        if weight > 0.0 {
            range.clone().map(|s| size(s) * x[a][s]).sum::<f64>() / weight
        } else {
            node.corner[a] + 0.5 * node.side
        }
    });
    let mut m = [0.0; MOMENTS];
    for s in range {
        let a = strength(s);
        let y: [f64; 3] = std::array::from_fn(|j| x[j][s] - centre[j]);
        for c in 0..3 {
            m[c] += a[c];
            for j in 0..3 {
                m[3 + 3 * c + j] += a[c] * y[j];
                for k in j..3 {
                    m[12 + 6 * c + PAIR[j][k]] += a[c] * y[j] * y[k];
                }
            }
        }
    }
    (centre, m)
}

/// One group's lists (the shared walk lists plus the listed particles'
/// strengths and the accepted nodes' moments) and its particles' running sums.
#[derive(Clone, Debug, Default)]
struct VortexLists3 {
    walk: Lists,
    /// The opened leaves' particles' strengths per axis, padded with zeros.
    part_alpha: [Vec<f64>; 3],
    /// The accepted nodes' [`Moments`], one column each, padded with zeros.
    node_moments: Vec<Vec<f64>>,
    /// Per group particle: its position and its [`SUMS`] running sums.
    targets: Vec<Target<3, SUMS>>,
}

impl VortexLists3 {
    /// The shared lists of `group`, then the listed particles' strengths (the
    /// lists' weights are input indices) and the accepted nodes' moments.
    fn gather(&mut self, group: &Group<Moments>, alpha: &[[f64; 3]]) {
        self.walk.gather(group);
        let (listed, ids) = (&self.walk.part_w, &self.walk.part_id);
        for (c, dst) in self.part_alpha.iter_mut().enumerate() {
            dst.clear();
            // padding entries (sorted index -1) have strength 0
            dst.extend(listed.iter().zip(ids).map(|(&i, &id)| {
                if id < 0.0 {
                    0.0
                } else {
                    alpha[i as usize][c]
                }
            }));
        }
        self.node_moments.resize(MOMENTS, Vec::new());
        let (ids, moments) = (&self.walk.accepted, group.moments);
        for (j, dst) in self.node_moments.iter_mut().enumerate() {
            copy(dst, ids, 0.0, |k| moments[k][j]);
        }
    }

    /// Sums the lists for the group's particles into `target` as [`SUMS`]:
    /// the lists outside, the group inside, each particle's sums four lanes
    /// added across at the end.
    fn evaluate(
        &mut self,
        kernel: &BlobKernel3,
        group: &Group<Moments>,
        target: &mut [[f64; SUMS]],
    ) {
        group.targets(target.len(), &mut self.targets);
        self.particle_sums(kernel);
        self.node_sums(kernel);
        for (out, t) in target.iter_mut().zip(&self.targets) {
            *out = t.sums.map(F64x4::sum);
        }
    }

    /// Adds the listed particles' pair terms ([`terms`]) to every target, its
    /// own term included.
    #[inline(always)]
    fn particle_sums(&mut self, kernel: &BlobKernel3) {
        let lists = &self.walk;
        for c in (0..lists.part_w.len()).step_by(LANES) {
            let x: [F64x4; 3] = std::array::from_fn(|a| F64x4::load(&lists.part_x[a][c..]));
            let alpha: [F64x4; 3] = std::array::from_fn(|a| F64x4::load(&self.part_alpha[a][c..]));
            for t in self.targets.iter_mut() {
                let r: [F64x4; 3] = std::array::from_fn(|a| F64x4::splat(t.x[a]) - x[a]);
                let r2 = r[0] * r[0] + r[1] * r[1] + r[2] * r[2];
                let [g, g2, ..] = kernel.radial_or_far(r2);
                for (s, v) in t.sums.iter_mut().zip(terms(alpha, r, g, g2)) {
                    *s = *s + v;
                }
            }
        }
    }

    /// Adds the listed nodes' expansions (see [`VortexTree3`]) to every
    /// target: `u` to its sums 0..3, the gradient to 6..15.
    #[inline(always)]
    fn node_sums(&mut self, kernel: &BlobKernel3) {
        let half = F64x4::splat(0.5);
        let node_x = &self.walk.node_x;
        for c in (0..node_x[0].len()).step_by(LANES) {
            let centre: [F64x4; 3] = std::array::from_fn(|a| F64x4::load(&node_x[a][c..]));
            let m: [F64x4; MOMENTS] =
                std::array::from_fn(|j| F64x4::load(&self.node_moments[j][c..]));
            for t in self.targets.iter_mut() {
                let d: [F64x4; 3] = std::array::from_fn(|a| F64x4::splat(t.x[a]) - centre[a]);
                let r2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
                let [f1, f2, f3, f4] = kernel.radial_or_far(r2).map(|g| -g);
                // per component c of psi: its gradient and Hessian
                let mut grad = [[F64x4::splat(0.0); 3]; 3];
                let mut hess = [[F64x4::splat(0.0); 6]; 3];
                for k in 0..3 {
                    let dk = [m[3 + 3 * k], m[4 + 3 * k], m[5 + 3 * k]];
                    let q = &m[12 + 6 * k..18 + 6 * k];
                    let qd: [F64x4; 3] = std::array::from_fn(|b| {
                        q[PAIR[b][0]] * d[0] + q[PAIR[b][1]] * d[1] + q[PAIR[b][2]] * d[2]
                    });
                    let dqd = qd[0] * d[0] + qd[1] * d[1] + qd[2] * d[2];
                    let s1 = dk[0] * d[0] + dk[1] * d[1] + dk[2] * d[2];
                    let level = half * (q[0] + q[3] + q[5]) - s1;
                    let a = m[k] * f1 + level * f2 + half * dqd * f3;
                    let b = m[k] * f2 + level * f3 + half * dqd * f4;
                    grad[k] = std::array::from_fn(|i| a * d[i] - f1 * dk[i] + f2 * qd[i]);
                    for i in 0..3 {
                        for e in i..3 {
                            let diagonal = if i == e { a } else { F64x4::splat(0.0) };
                            hess[k][PAIR[i][e]] =
                                diagonal + b * d[i] * d[e] + f3 * (d[i] * qd[e] + qd[i] * d[e])
                                    - f2 * (d[i] * dk[e] + dk[i] * d[e])
                                    + f2 * q[PAIR[i][e]];
                        }
                    }
                }
                // u_a = eps_abc d_b psi_c, (a, b, c) cyclic
                for a in 0..3 {
                    let (b, c) = ((a + 1) % 3, (a + 2) % 3);
                    t.sums[a] = t.sums[a] + grad[c][b] - grad[b][c];
                    for e in 0..3 {
                        let v = hess[c][PAIR[b][e]] - hess[b][PAIR[c][e]];
                        t.sums[6 + 3 * a + e] = t.sums[6 + 3 * a + e] + v;
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::longrange::biot_savart3::velocity_and_gradient_at;
    use crate::longrange::DirectBiotSavart3;
    use crate::random::Rng;
    use std::time::Instant;

    /// `n` blobs uniformly in the unit cube with random strengths of either
    /// sign, `sigma = 1.5 h`, `h = n^(-1/3)` the mean spacing.
    fn cloud(seed: u64, n: usize) -> (Vec<[f64; 3]>, Vec<[f64; 3]>, BlobKernel3) {
        let mut rng = Rng::new(seed);
        let h = (n as f64).cbrt().recip();
        let x = (0..n)
            .map(|_| std::array::from_fn(|_| rng.uniform()))
            .collect();
        let alpha = (0..n)
            .map(|_| std::array::from_fn(|_| (rng.uniform() - 0.5) * h * h * h))
            .collect();
        (x, alpha, BlobKernel3::new(1.5 * h))
    }

    /// A vortex ring of radius 1 and Gaussian core `a = 0.2` (circulation 1)
    /// seeded on the lattice of spacing `h` within `3 a` of its centre line,
    /// `alpha = omega h^3`, `sigma = 1.5 h`.
    fn ring(h: f64) -> (Vec<[f64; 3]>, Vec<[f64; 3]>, BlobKernel3) {
        let a = 0.2;
        let cells = (1.6 / h).ceil() as i64;
        let (mut x, mut alpha) = (Vec::new(), Vec::new());
        for i in -cells..=cells {
            for j in -cells..=cells {
                for k in -(0.6 / h).ceil() as i64..=(0.6 / h).ceil() as i64 {
                    let p = [i as f64 * h, j as f64 * h, (k as f64 + 0.5) * h];
                    let rho = p[0].hypot(p[1]);
                    let s2 = (rho - 1.0).powi(2) + p[2] * p[2];
                    if s2 < 9.0 * a * a {
                        let w = (-s2 / (a * a)).exp() / (std::f64::consts::PI * a * a);
                        x.push(p);
                        alpha.push([-w * p[1] / rho * h.powi(3), w * p[0] / rho * h.powi(3), 0.0]);
                    }
                }
            }
        }
        (x, alpha, BlobKernel3::new(1.5 * h))
    }

    /// `RMS |got - want| / RMS |want|`.
    fn rms_error<const K: usize>(got: &[[f64; K]], want: &[[f64; K]]) -> f64 {
        let square = |v: [f64; K]| v.iter().map(|c| c * c).sum::<f64>();
        let diff: f64 = got
            .iter()
            .zip(want)
            .map(|(g, w)| square(std::array::from_fn(|k| g[k] - w[k])))
            .sum();
        (diff / want.iter().map(|w| square(*w)).sum::<f64>()).sqrt()
    }

    type Field = (Vec<[f64; 3]>, Vec<[f64; 9]>);

    fn tree_field(
        params: TreeParams,
        kernel: BlobKernel3,
        x: &[[f64; 3]],
        alpha: &[[f64; 3]],
        threads: &Threads,
    ) -> (Field, (u64, u64)) {
        let mut tree = VortexTree3::new(params, kernel).unwrap();
        let (mut u, mut g) = (vec![[0.0; 3]; x.len()], vec![[0.0; 9]; x.len()]);
        tree.compute(x, alpha, &mut u, &mut g, threads);
        ((u, g), tree.interactions())
    }

    fn same_bits<const K: usize>(a: &[[f64; K]], b: &[[f64; K]]) -> bool {
        a.len() == b.len()
            && a.iter()
                .zip(b)
                .all(|(p, q)| p.map(f64::to_bits) == q.map(f64::to_bits))
    }

    /// The tree against the brute-force sums on a small cloud and a small
    /// ring: the RMS errors stated per theta (measured values in comments),
    /// falling with theta.
    #[test]
    fn matches_direct_within_the_stated_errors() {
        let cases = [
            // cloud: measured u 0, 0, 0; grad 0, 0, 0
            (
                "cloud",
                cloud(3, 2000),
                [(0.2, 1.0, 1.0), (0.4, 1.0, 1.0), (0.7, 1.0, 1.0)],
            ),
            // ring: measured u 0, 0, 0; grad 0, 0, 0
            (
                "ring",
                ring(0.13),
                [(0.2, 1.0, 1.0), (0.4, 1.0, 1.0), (0.7, 1.0, 1.0)],
            ),
        ];
        for (name, (x, alpha, kernel), limits) in cases {
            let one = Threads::single();
            let want = velocity_and_gradient_at(&kernel, &x, &x, &alpha, &one);
            let mut last = 0.0;
            for (theta, u_below, grad_below) in limits {
                let params = TreeParams {
                    theta,
                    ..VortexTree3::default_params()
                };
                let ((u, g), counts) = tree_field(params, kernel, &x, &alpha, &one);
                let (eu, eg) = (rms_error(&u, &want.0), rms_error(&g, &want.1));
                eprintln!(
                    "{name} ({} particles), theta {theta}: u {eu:.2e}, grad {eg:.2e}, {counts:?}",
                    x.len()
                );
                assert!(counts.0 > 0, "{name}, theta {theta}: no node accepted");
                assert!(
                    eu < u_below && eg < grad_below,
                    "{name}, theta {theta}: {eu:e} {eg:e}"
                );
                assert!(
                    eu > last,
                    "{name}, theta {theta}: {eu:e} not above {last:e}"
                );
                last = eu;
            }
        }
    }

    #[test]
    fn one_and_two_threads_give_the_same_bits() {
        let (x, alpha, kernel) = cloud(5, 6000);
        let params = VortexTree3::default_params();
        let ((u1, g1), _) = tree_field(params, kernel, &x, &alpha, &Threads::single());
        let two = Threads::new(2).unwrap();
        let mut tree = VortexTree3::new(params, kernel).unwrap();
        let (mut u2, mut g2) = (vec![[0.0; 3]; x.len()], vec![[0.0; 9]; x.len()]);
        // twice: the second on the kept scratch
        for _ in 0..2 {
            tree.compute(&x, &alpha, &mut u2, &mut g2, &two);
            assert!(same_bits(&u1, &u2) && same_bits(&g1, &g2));
        }
    }

    /// No particles, and one particle: no velocity, the gradient its own term
    /// `[alpha]_x g(0)`.
    #[test]
    fn edge_cases() {
        let kernel = BlobKernel3::new(0.5);
        let params = VortexTree3::default_params();
        let one = Threads::single();
        assert!(tree_field(params, kernel, &[], &[], &one).0 .0.is_empty());
        let alpha = [[1.0, -2.0, 0.5]];
        let ((u, g), _) = tree_field(params, kernel, &[[0.1, 0.2, 0.3]], &alpha, &one);
        let g0 = 1.0 / (3.0 * (2.0 * std::f64::consts::PI).powf(1.5) * 0.125);
        let a = alpha[0].map(|v| v * g0);
        let want = [0.0, -a[2], a[1], a[2], 0.0, -a[0], -a[1], a[0], 0.0];
        assert_eq!(u, [[0.0; 3]]);
        for (got, want) in g[0].iter().zip(want) {
            assert!((got - want).abs() <= 1e-15 * g0, "{:?}", g[0]);
        }
    }

    /// Tree times and errors (against the brute-force sums at every 50th
    /// particle) for the report: `cargo test --release -p cellist --lib
    /// vortex3::tests::measure_tree -- --ignored --nocapture`.
    #[test]
    #[ignore]
    fn measure_tree() {
        for (name, (x, alpha, kernel)) in [("ring", ring(0.0415)), ("cloud", cloud(1, 100_000))] {
            let n = x.len();
            eprintln!("{name}: {n} particles, sigma {:.4}", kernel.sigma());
            let sample: Vec<usize> = (0..n).step_by(50).collect();
            let targets: Vec<[f64; 3]> = sample.iter().map(|&i| x[i]).collect();
            let two = Threads::new(2).unwrap();
            let want = velocity_and_gradient_at(&kernel, &targets, &x, &alpha, &two);
            // (theta, leaf_size, group_size, threads)
            let settings = [
                (0.4, 16, 64, 1),
                (0.4, 8, 32, 1),
                (0.4, 16, 32, 1),
                (0.4, 32, 128, 1),
                (0.3, 8, 32, 1),
                (0.4, 16, 64, 2),
            ];
            for (theta, leaf_size, group_size, threads) in settings {
                {
                    let params = TreeParams {
                        theta,
                        leaf_size,
                        group_size,
                        quadrupole: true,
                    };
                    let start = Instant::now();
                    let ((u, g), counts) =
                        tree_field(params, kernel, &x, &alpha, &Threads::new(threads).unwrap());
                    let time = start.elapsed().as_secs_f64();
                    let u: Vec<[f64; 3]> = sample.iter().map(|&i| u[i]).collect();
                    let g: Vec<[f64; 9]> = sample.iter().map(|&i| g[i]).collect();
                    eprintln!(
                        "  tree theta {theta}, leaf {leaf_size}, group {group_size}, {threads} threads: {time:.2} s, RMS error u {:.2e}, grad {:.2e}, interactions {counts:?}",
                        rms_error(&u, &want.0),
                        rms_error(&g, &want.1)
                    );
                }
            }
        }
    }

    /// Direct times for the report: `cargo test --release -p cellist --lib
    /// vortex3::tests::measure_direct -- --ignored --nocapture`.
    #[test]
    #[ignore]
    fn measure_direct() {
        let (x, alpha, kernel) = cloud(1, 100_000);
        let n = x.len();
        let (mut u, mut g) = (vec![[0.0; 3]; n], vec![[0.0; 9]; n]);
        let mut direct = DirectBiotSavart3::new(kernel, n);
        for threads in [2, 1] {
            let start = Instant::now();
            direct.compute(&x, &alpha, &mut u, &mut g, &Threads::new(threads).unwrap());
            eprintln!(
                "direct, {n} particles, {threads} threads: {:.2} s",
                start.elapsed().as_secs_f64()
            );
        }
    }
}
