//! The 2D vortex kernel on the tree: each node's complex moments about the
//! centre of its `|Gamma|`, and the SIMD sums of a group's lists (the blob law
//! for opened leaves' particles, the truncated Laurent series for accepted
//! nodes).

use super::build::Node;
use super::share::{Share, Whole};
use super::walk::{copy, Group, Lists, Solver, Target, Walk, LANES};
use super::TreeParams;
use crate::longrange::biot_savart::BlobKernel;
use crate::simd::F64x4;
use crate::threads::Threads;
use std::f64::consts::PI;

/// Terms of a node's expansion, `a_0 .. a_{TERMS-1}`.
const TERMS: usize = 8;

/// Accepted nodes' blobs lie farther than this many cores `sigma` from every
/// target, where `exp(-r^2 / (2 sigma^2)) < exp(-18.6) = 8.3e-9`: their blob
/// factor `1 - exp(-r^2 / (2 sigma^2))` is 1 to that relative error.
const CLEARANCE: f64 = 6.1;

/// A node's moments `a_k / (2 pi)` as `[re, im]`.
type Coefficients = [[f64; 2]; TERMS];

/// Barnes-Hut for the regularised 2D Biot-Savart law of [`BlobKernel`]:
///
/// `velocity_i ~ sum_{j != i} Gamma_j K_sigma(x_i - x_j)`,
/// `K_sigma(d) = (-d_y, d_x) / (2 pi |d|^2) (1 - exp(-|d|^2 / (2 sigma^2)))`,
///
/// on the same octree and walk as [`BarnesHut`](super::BarnesHut) (the
/// particles at `z = 0`). Circulations may have either sign and sum to zero, so
/// a node's expansion centre `z_c` (and its opening distance) is the centre of
/// `|Gamma|`, `z_c = sum_j |Gamma_j| z_j / sum_j |Gamma_j|` (complex `z = x + i y`).
/// An accepted node gives, with the point-vortex law
/// `u - i v = 1/(2 pi i) sum_j Gamma_j / (z - z_j)` expanded about `z_c`,
///
/// `u - i v = 1/(2 pi i) sum_{k=0}^{p-1} a_k / (z - z_c)^(k+1)`,
/// `a_k = sum_j Gamma_j (z_j - z_c)^k`, `p = 8` terms,
///
/// and is accepted only when, besides the opening angle, its blobs all lie
/// farther than `6.1 sigma` from the group's box, so that the blob factor
/// `1 - exp(-r^2 / (2 sigma^2))` of every pair it stands for is 1 within
/// `8.3e-9` (relative). Opened leaves give their particles, summed exactly with
/// [`BlobKernel::factor`] (the self term skipped).
///
/// Error against direct ([`velocity_at`](crate::longrange::biot_savart::velocity_at)),
/// relative per particle, `|u_tree - u_direct| / |u_direct|`, with `p = 8` and
/// the default leaf and group sizes (16, 128), on the Gaussian vortex: particles
/// at the cell centres of a lattice of spacing `h` over `[-1, 1]^2`,
/// `Gamma_i = h^2 exp(-|x_i|^2 / 0.1)`, `sigma = 1.5 h`:
///
/// | theta | `h = 0.05` (1600 particles): RMS, max | `h = 2/316` (99 856; 3000 sampled): RMS, max |
/// |-------|---------------------|---------------------|
/// | 0.3   | 3.4e-10, 2.9e-9     | 2.2e-9, 2.4e-8      |
/// | 0.5   | 6.8e-9, 4.4e-8      | 1.0e-7, 2.2e-6      |
/// | 0.7   | 2.2e-8, 1.7e-7      | 3.6e-6, 1.5e-4      |
///
/// (with 1600 particles the `6.1 sigma` clearance, not theta, decides most
/// nodes). With `p = 4` the large lattice gives RMS 1.2e-5, 4.8e-5, 1.1e-4 and
/// with `p = 6` 3.4e-8, 1.0e-6, 1.1e-5 at these thetas. Against the scale
/// `sum_j |Gamma_j K_sigma(x_i - x_j)|` the error of every particle stays below `(1 + k) k^p / (1 - k) + 8.3e-9`,
/// `k = sqrt(2) / (1/theta + 1/sqrt(2))` (the series' remainder for the
/// farthest particle an accepted node can hold), which the tests check.
///
/// Each particle's sum runs in an order fixed by the tree (lists outside, lanes
/// added across at the end), so 1 and N threads give the same bits.
#[derive(Debug)]
pub struct VortexTree {
    kernel: BlobKernel,
    /// The positions at `z = 0`, for the octree.
    lifted: Vec<[f64; 3]>,
    solver: Solver<Coefficients, VortexLists, 2>,
}

impl VortexTree {
    /// A solver for blobs of `kernel` with `params` (checked; `quadrupole` is
    /// ignored).
    pub fn new(params: TreeParams, kernel: BlobKernel) -> Result<Self, String> {
        let solver = Solver::new(params)?;
        Ok(VortexTree {
            kernel,
            lifted: Vec::new(),
            solver,
        })
    }

    /// `(node, particle)` interactions of the last evaluation (of this
    /// process's part, for [`compute_shared`](Self::compute_shared)).
    pub fn interactions(&self) -> (u64, u64) {
        self.solver.interactions
    }

    /// `velocity_i = sum_{j != i} Gamma_j K_sigma(x_i - x_j)`, approximately (see
    /// [`VortexTree`]), for every particle, in input order.
    pub fn compute(
        &mut self,
        positions: &[[f64; 2]],
        gamma: &[f64],
        velocity: &mut [[f64; 2]],
        threads: &Threads,
    ) {
        self.compute_shared(positions, gamma, velocity, threads, &mut Whole);
    }

    /// [`compute`](Self::compute) divided among processes that each hold every
    /// particle (see [`Share`]): this one walks and sums only the groups of its
    /// part, `share` brings the others' velocities, and every particle's
    /// velocity has the bits of the undivided evaluation.
    pub fn compute_shared(
        &mut self,
        positions: &[[f64; 2]],
        gamma: &[f64],
        velocity: &mut [[f64; 2]],
        threads: &Threads,
        share: &mut dyn Share,
    ) {
        crate::longrange::biot_savart::assert_lengths(positions, gamma, velocity);
        self.lifted.clear();
        self.lifted
            .extend(positions.iter().map(|p| [p[0], p[1], 0.0]));
        let kernel = &self.kernel;
        self.solver.evaluate(
            &self.lifted,
            positions,
            gamma,
            CLEARANCE * kernel.sigma(),
            threads,
            share,
            of_node,
            |lists: &mut VortexLists, group, target| {
                lists.gather(&group);
                lists.evaluate(kernel, &group, target);
                lists.walk.counts(target.len())
            },
        );
        for (i, v) in self.solver.results() {
            velocity[i] = *v;
        }
    }
}

/// A node's centre of `|Gamma|` (its cube's centre if all its circulations are
/// zero) and its moments `a_k / (2 pi)`, from the sorted circulations `walk.w`.
fn of_node(node: &Node, walk: &Walk) -> ([f64; 3], Coefficients) {
    let (x, g) = (&walk.x, &walk.w);
    let range = node.start as usize..node.end as usize;
    let weight: f64 = g[range.clone()].iter().map(|v| v.abs()).sum();
    let centre: [f64; 3] = std::array::from_fn(|a| match a {
        2 => 0.0,
        _ if weight > 0.0 => range.clone().map(|s| g[s].abs() * x[a][s]).sum::<f64>() / weight,
        _ => node.corner[a] + 0.5 * node.side,
    });
    let mut coefficients = [[0.0; 2]; TERMS];
    for s in range {
        let y = [x[0][s] - centre[0], x[1][s] - centre[1]];
        // Gamma (z_j - z_c)^k / (2 pi), k = 0, 1, ...
        let mut power = [g[s] / (2.0 * PI), 0.0];
        for a in coefficients.iter_mut() {
            a[0] += power[0];
            a[1] += power[1];
            power = [
                power[0] * y[0] - power[1] * y[1],
                power[0] * y[1] + power[1] * y[0],
            ];
        }
    }
    (centre, coefficients)
}

/// One group's lists (the shared walk lists plus the accepted nodes' moments)
/// and its particles' running sums.
#[derive(Clone, Debug, Default)]
struct VortexLists {
    walk: Lists,
    /// `a_k / (2 pi)` of the accepted nodes: real parts at `2k`, imaginary at
    /// `2k + 1`, padded with zeros.
    node_a: [Vec<f64>; 2 * TERMS],
    /// Per group particle: its position and its two running sums.
    targets: Vec<Target<2, 2>>,
    /// Per group particle and lane: `|d|^2`, then `q(|d|^2)`.
    q: Vec<f64>,
}

impl VortexLists {
    /// The shared lists of `group`, then the accepted nodes' moments.
    fn gather(&mut self, group: &Group<Coefficients>) {
        self.walk.gather(group);
        let (ids, moments) = (&self.walk.accepted, group.moments);
        for (j, dst) in self.node_a.iter_mut().enumerate() {
            copy(dst, ids, 0.0, |k| moments[k][j / 2][j % 2]);
        }
    }

    /// Sums the lists for the group's particles, sorted `start..`, into `target`
    /// as `[u, v]`: the lists outside, the group inside, each particle's sums
    /// four lanes added across at the end.
    fn evaluate(
        &mut self,
        kernel: &BlobKernel,
        group: &Group<Coefficients>,
        target: &mut [[f64; 2]],
    ) {
        group.targets(target.len(), &mut self.targets);
        self.particle_sums(kernel);
        self.node_sums();
        for (out, t) in target.iter_mut().zip(&self.targets) {
            *out = t.sums.map(F64x4::sum);
        }
    }

    /// Adds `sum_j Gamma_j q(|d|^2) (-d_y, d_x)`, `d = x - x_j`, over the listed
    /// particles to every target, the self term (equal sorted index) skipped.
    /// Per four listed particles: `|d|^2` of every target and lane into a flat
    /// buffer, [`BlobKernel::factor`] over the buffer in one loop that the
    /// compiler vectorises, then the sums.
    #[inline(always)]
    fn particle_sums(&mut self, kernel: &BlobKernel) {
        let lists = &self.walk;
        self.q.resize(self.targets.len() * LANES, 0.0);
        for c in (0..lists.part_w.len()).step_by(LANES) {
            let x = [
                F64x4::load(&lists.part_x[0][c..]),
                F64x4::load(&lists.part_x[1][c..]),
            ];
            let g = F64x4::load(&lists.part_w[c..]);
            let id = F64x4::load(&lists.part_id[c..]);
            let d = |t: &Target<2, 2>| [F64x4::splat(t.x[0]) - x[0], F64x4::splat(t.x[1]) - x[1]];
            for (t, r2) in self.targets.iter().zip(self.q.chunks_exact_mut(LANES)) {
                let d = d(t);
                d[0].mul_add(d[0], d[1] * d[1]).store(r2);
            }
            for q in self.q.iter_mut() {
                *q = kernel.factor(*q);
            }
            for (t, q) in self.targets.iter_mut().zip(self.q.chunks_exact(LANES)) {
                let d = d(t);
                let gq = (g * F64x4::load(q)).zero_where_equal(id, F64x4::splat(t.id));
                t.sums[0] = gq.neg_mul_add(d[1], t.sums[0]);
                t.sums[1] = gq.mul_add(d[0], t.sums[1]);
            }
        }
    }

    /// Adds the listed nodes' series to every target: with `w = z - z_c` and
    /// `r = 1/w = p - i q`, `S = sum_k a_k r^(k+1) / (2 pi)` by Horner, and
    /// `u - i v = -i S`, so `u = Im S` and `v = Re S`.
    #[inline(always)]
    fn node_sums(&mut self) {
        let one = F64x4::splat(1.0);
        let node_x = &self.walk.node_x;
        for c in (0..node_x[0].len()).step_by(LANES) {
            let centre = [F64x4::load(&node_x[0][c..]), F64x4::load(&node_x[1][c..])];
            let a: [[F64x4; 2]; TERMS] = std::array::from_fn(|k| {
                [
                    F64x4::load(&self.node_a[2 * k][c..]),
                    F64x4::load(&self.node_a[2 * k + 1][c..]),
                ]
            });
            for t in self.targets.iter_mut() {
                let w = [
                    F64x4::splat(t.x[0]) - centre[0],
                    F64x4::splat(t.x[1]) - centre[1],
                ];
                let inv = one / w[0].mul_add(w[0], w[1] * w[1]);
                let (p, q) = (w[0] * inv, w[1] * inv);
                // s <- s r + a_k, with s r = (s0 p + s1 q) + i (s1 p - s0 q)
                let mut s = a[TERMS - 1];
                for ak in a[..TERMS - 1].iter().rev() {
                    s = [
                        s[0].mul_add(p, s[1].mul_add(q, ak[0])),
                        s[1].mul_add(p, s[0].neg_mul_add(q, ak[1])),
                    ];
                }
                // the last s r: its imaginary part to u, its real part to v
                t.sums[0] = s[1].mul_add(p, s[0].neg_mul_add(q, t.sums[0]));
                t.sums[1] = s[0].mul_add(p, s[1].mul_add(q, t.sums[1]));
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::longrange::biot_savart::velocity_at;
    use crate::random::Rng;
    use proptest::prelude::*;
    use std::f64::consts::{FRAC_1_SQRT_2, SQRT_2};

    fn tree_velocity(
        params: TreeParams,
        kernel: BlobKernel,
        x: &[[f64; 2]],
        g: &[f64],
        threads: &Threads,
    ) -> (Vec<[f64; 2]>, (u64, u64)) {
        let mut tree = VortexTree::new(params, kernel).unwrap();
        let mut u = vec![[0.0; 2]; x.len()];
        tree.compute(x, g, &mut u, threads);
        (u, tree.interactions())
    }

    /// `(RMS, max)` over particles of `|got_i - want_i| / |want_i|`.
    fn relative_errors(got: &[[f64; 2]], want: &[[f64; 2]]) -> (f64, f64) {
        let e: Vec<f64> = got
            .iter()
            .zip(want)
            .map(|(g, w)| (g[0] - w[0]).hypot(g[1] - w[1]) / w[0].hypot(w[1]))
            .collect();
        let rms = (e.iter().map(|v| v * v).sum::<f64>() / e.len() as f64).sqrt();
        (rms, e.iter().copied().fold(0.0, f64::max))
    }

    /// The bound of `|u_tree - u_direct|` per unit of `sum_j |Gamma_j K_sigma(x - x_j)|`:
    /// an accepted node's particles lie within `kappa R` of its centre,
    /// `kappa = sqrt(2) / (1/theta + 1/sqrt(2))` (side `l`, centre at most
    /// `l / sqrt(2)` off the square's centre, target farther than `l / theta` plus
    /// that offset), so its series' remainder is at most `kappa^p / (1 - kappa)`
    /// of `sum |Gamma| / (2 pi R)`, which is at most `1 + kappa` of its particles'
    /// share of the scale; the blob factor adds `8.3e-9`, rounding `1e-12`.
    fn bound(theta: f64) -> f64 {
        let kappa = SQRT_2 / (1.0 / theta + FRAC_1_SQRT_2);
        (1.0 + kappa) * kappa.powi(TERMS as i32) / (1.0 - kappa) + 8.3e-9 + 1e-12
    }

    /// `sum_j |Gamma_j K_sigma(x_i - x_j)|` for every particle.
    fn absolute_scale(kernel: &BlobKernel, x: &[[f64; 2]], g: &[f64]) -> Vec<f64> {
        x.iter()
            .map(|xi| {
                x.iter()
                    .zip(g)
                    .map(|(xj, gj)| {
                        let v = kernel.velocity([xi[0] - xj[0], xi[1] - xj[1]], gj.abs());
                        v[0].hypot(v[1])
                    })
                    .sum()
            })
            .collect()
    }

    /// Clusters of different widths (a deep, uneven tree) with circulations of
    /// both signs.
    fn mixed_cloud(seed: u64, n: usize) -> (Vec<[f64; 2]>, Vec<f64>) {
        let mut rng = Rng::new(seed);
        let centres: Vec<([f64; 2], f64)> = (0..4)
            .map(|_| ([rng.normal(), rng.normal()], 0.02 + 0.5 * rng.uniform()))
            .collect();
        let x = (0..n)
            .map(|i| {
                let (c, w) = centres[i % centres.len()];
                [c[0] + w * rng.normal(), c[1] + w * rng.normal()]
            })
            .collect();
        let g = (0..n).map(|_| 2.0 * rng.uniform() - 1.0).collect();
        (x, g)
    }

    /// The tree's and the direct velocities and the tree's interaction counts.
    type Checked = (Vec<[f64; 2]>, Vec<[f64; 2]>, (u64, u64));

    /// Checks every particle against [`bound`].
    fn check_against_direct(
        params: TreeParams,
        kernel: BlobKernel,
        x: &[[f64; 2]],
        g: &[f64],
    ) -> Checked {
        let (got, counts) = tree_velocity(params, kernel, x, g, &Threads::single());
        let want = velocity_at(&kernel, x, x, g, &Threads::single());
        let scale = absolute_scale(&kernel, x, g);
        let tolerance = bound(params.theta);
        for i in 0..x.len() {
            let error = (got[i][0] - want[i][0]).hypot(got[i][1] - want[i][1]);
            assert!(
                error <= tolerance * scale[i],
                "particle {i}: {:?} against {:?}, error {error:e}, scale {:e}",
                got[i],
                want[i],
                scale[i]
            );
        }
        (got, want, counts)
    }

    fn same_bits(a: &[[f64; 2]], b: &[[f64; 2]]) -> bool {
        a.len() == b.len()
            && a.iter()
                .zip(b)
                .all(|(p, q)| p.map(f64::to_bits) == q.map(f64::to_bits))
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(40))]

        /// Random clouds with mixed-sign circulations: every particle within the
        /// series' bound of the direct sum, and 1 and 2 threads give the same bits.
        #[test]
        fn matches_direct_on_mixed_sign_clouds(
            seed in any::<u64>(),
            n in 1usize..900,
            theta in 0.1f64..0.8,
            log_sigma in -7.0f64..-2.0,
            leaf_size in 1usize..40,
            group_size in 1usize..200,
        ) {
            let (x, g) = mixed_cloud(seed, n);
            let kernel = BlobKernel::new(log_sigma.exp());
            let params = TreeParams { theta, quadrupole: true, leaf_size, group_size };
            let (one, _, _) = check_against_direct(params, kernel, &x, &g);
            let (two, _) = tree_velocity(params, kernel, &x, &g, &Threads::new(2).unwrap());
            prop_assert!(same_bits(&one, &two));
        }
    }

    #[test]
    fn one_and_two_threads_give_the_same_bits() {
        let (x, g) = mixed_cloud(11, 20_000);
        let kernel = BlobKernel::new(0.01);
        for theta in [0.3, 0.7] {
            let params = TreeParams {
                theta,
                ..TreeParams::default()
            };
            let (one, counts) = tree_velocity(params, kernel, &x, &g, &Threads::single());
            let (two, _) = tree_velocity(params, kernel, &x, &g, &Threads::new(2).unwrap());
            assert!(counts.0 > 0 && counts.1 > 0);
            assert!(same_bits(&one, &two), "theta {theta}");
            // and again on the kept scratch
            let mut tree = VortexTree::new(params, kernel).unwrap();
            let mut again = vec![[0.0; 2]; x.len()];
            let two_threads = Threads::new(2).unwrap();
            tree.compute(&x, &g, &mut again, &two_threads);
            tree.compute(&x, &g, &mut again, &two_threads);
            assert!(same_bits(&one, &again), "theta {theta}, second evaluation");
        }
    }

    /// The Gaussian vortex: the cell centres of a lattice of spacing `h = 0.05`
    /// over `[-1, 1]^2` (so that no particle sits at the centre, where `u = 0`),
    /// `Gamma_i = h^2 exp(-|x_i|^2 / 0.1)`.
    fn gaussian_vortex(side: usize) -> (Vec<[f64; 2]>, Vec<f64>, f64) {
        let h = 2.0 / side as f64;
        let x: Vec<[f64; 2]> = (0..side * side)
            .map(|k| {
                let (i, j) = (k % side, k / side);
                [-1.0 + h * (i as f64 + 0.5), -1.0 + h * (j as f64 + 0.5)]
            })
            .collect();
        let g = x
            .iter()
            .map(|p| h * h * (-(p[0] * p[0] + p[1] * p[1]) / 0.1).exp())
            .collect();
        (x, g, h)
    }

    /// The errors stated in [`VortexTree`]'s documentation, with a margin.
    #[test]
    fn gaussian_vortex_error_against_direct() {
        let (x, g, h) = gaussian_vortex(40);
        assert_eq!(h, 0.05);
        let kernel = BlobKernel::new(1.5 * h);
        let want = velocity_at(&kernel, &x, &x, &g, &Threads::single());
        let mut last = 0.0;
        for (theta, rms_below, max_below) in
            [(0.3, 1e-9, 1e-8), (0.5, 2e-8, 2e-7), (0.7, 6e-8, 6e-7)]
        {
            let params = TreeParams {
                theta,
                ..TreeParams::default()
            };
            let (got, counts) = tree_velocity(params, kernel, &x, &g, &Threads::single());
            let (rms, max) = relative_errors(&got, &want);
            eprintln!("theta {theta}: RMS {rms:.2e}, max {max:.2e}, interactions {counts:?}");
            assert!(counts.0 > 0);
            assert!(
                rms < rms_below && max < max_below,
                "theta {theta}: {rms:e} {max:e}"
            );
            assert!(rms > last, "theta {theta}: {rms:e} not above {last:e}");
            last = rms;
        }
    }

    /// Pairs of opposite circulations (dipoles): every node's circulation may be
    /// near zero and the total is exactly zero; the expansion about the centre of
    /// `|Gamma|` still converges.
    #[test]
    fn zero_total_circulation_pairs() {
        let mut rng = Rng::new(17);
        let (mut x, mut g) = (Vec::new(), Vec::new());
        for _ in 0..1500 {
            let c = [rng.normal(), rng.normal()];
            let angle = 2.0 * PI * rng.uniform();
            let e = [0.005 * angle.cos(), 0.005 * angle.sin()];
            let strength = 0.5 + rng.uniform();
            x.push([c[0] + e[0], c[1] + e[1]]);
            x.push([c[0] - e[0], c[1] - e[1]]);
            g.extend([strength, -strength]);
        }
        assert_eq!(g.iter().sum::<f64>(), 0.0);
        let kernel = BlobKernel::new(0.002);
        // measured: RMS 1.7e-8, 6.6e-7, 1.3e-5; max 1.5e-7, 7.2e-6, 1.5e-4
        for (theta, rms_below, max_below) in
            [(0.3, 1e-7, 1e-6), (0.5, 3e-6, 3e-5), (0.7, 5e-5, 6e-4)]
        {
            let params = TreeParams {
                theta,
                ..TreeParams::default()
            };
            let (got, want, counts) = check_against_direct(params, kernel, &x, &g);
            assert!(counts.0 > 0);
            let (rms, max) = relative_errors(&got, &want);
            eprintln!("pairs, theta {theta}: RMS {rms:.2e}, max {max:.2e}");
            assert!(
                rms < rms_below && max < max_below,
                "theta {theta}: {rms:e} {max:e}"
            );
        }
    }

    #[test]
    fn edge_cases_give_finite_velocities() {
        let params = TreeParams::default();
        let kernel = BlobKernel::new(0.1);
        let threads = Threads::single();
        assert!(tree_velocity(params, kernel, &[], &[], &threads)
            .0
            .is_empty());
        assert_eq!(
            tree_velocity(params, kernel, &[[0.3, 0.4]], &[2.0], &threads).0,
            [[0.0; 2]]
        );
        // zero circulations everywhere (a node's centre falls back to its square's)
        let (x, _) = mixed_cloud(3, 3000);
        let zeros = vec![0.0; x.len()];
        let (u, _, counts) = check_against_direct(params, BlobKernel::new(1e-3), &x, &zeros);
        assert!(counts.0 > 0);
        assert!(u.iter().all(|v| v[0] == 0.0 && v[1] == 0.0));
        // coincident particles and a line of particles
        let mut x: Vec<[f64; 2]> = (0..500).map(|i| [i as f64 * 1e-3, 0.5]).collect();
        x.extend([[0.1, 0.5]; 40]);
        let g: Vec<f64> = (0..x.len())
            .map(|i| if i % 3 == 0 { -1.0 } else { 0.7 })
            .collect();
        check_against_direct(
            TreeParams {
                leaf_size: 4,
                group_size: 8,
                ..params
            },
            BlobKernel::new(1e-4),
            &x,
            &g,
        );
    }
}
