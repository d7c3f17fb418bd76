//! The gravity kernel on the tree: node masses and traceless quadrupoles about
//! the centre of mass, and the SIMD sums of a group's lists.

use super::multipole::{of_node, Multipole};
use super::share::{Share, Whole};
use super::spread::Spread;
use super::walk::{copy, Group, Lists, Solver, Target, LANES};
use super::TreeParams;
use crate::interactions::GravityLaw;
use crate::longrange::direct::Kernel;
use crate::longrange::{Exchange, FieldOut, Sources};
use crate::simd::F64x4;
use crate::threads::Threads;

/// The Barnes-Hut solver of [`GravityLaw`]: the tree, its moments and the
/// per-thread scratch, kept between evaluations. Its field at `x` of an accepted
/// node, with `r = x - x_com`, `s^2 = |r|^2 + eps^2`, is
///
/// `phi = -G (M/s + (r.Q.r) / (2 s^5))`,
/// `acc = G (-M r / s^3 + Q r / s^5 - 5/2 (r.Q.r) r / s^7)`,
///
/// `Q_ab = sum_p m_p (3 y_a y_b - |y|^2 delta_ab)`, `y = x_p - x_com` (see the
/// [module](super) for the walk).
#[derive(Debug)]
pub struct BarnesHut {
    law: GravityLaw,
    solver: Solver<Multipole, GravityLists, 4>,
    /// What [`compute_spread`](Self::compute_spread) keeps.
    spread: Spread,
}

impl BarnesHut {
    /// A solver for `law` with `params` (checked).
    pub fn new(law: GravityLaw, params: TreeParams) -> Result<Self, String> {
        let solver = Solver::new(params)?;
        Ok(BarnesHut {
            law,
            solver,
            spread: Spread::default(),
        })
    }

    /// `(node, particle)` interactions of the last evaluation (of this
    /// process's part, for [`compute_shared`](Self::compute_shared); of
    /// this rank's groups, for [`compute_spread`](Self::compute_spread)).
    pub fn interactions(&self) -> (u64, u64) {
        self.solver.interactions
    }

    /// Fills `out` with the tree's accelerations and potentials of `sources`:
    /// `acc_i ~ sum_{j != i} acc_ij`, `phi_i ~ sum_{j != i} phi_ij`.
    pub fn compute(&mut self, sources: &Sources, out: FieldOut, threads: &Threads) {
        self.compute_shared(sources, out, threads, &mut Whole);
    }

    /// [`compute`](Self::compute) divided among processes that each hold every
    /// body (see [`Share`]): this one walks and sums only the groups of its
    /// part, `share` brings the others' sums, and every body's field has the
    /// bits of the undivided evaluation.
    pub fn compute_shared(
        &mut self,
        sources: &Sources,
        out: FieldOut,
        threads: &Threads,
        share: &mut dyn Share,
    ) {
        let position = sources.position;
        let sum_group = self.group_sums();
        self.solver.evaluate(
            position,
            position,
            sources.mass,
            0.0,
            threads,
            share,
            of_node,
            sum_group,
        );
        let g = self.law.g();
        for (i, v) in self.solver.results() {
            out.acc[i] = [g * v[0], g * v[1], g * v[2]];
            out.phi[i] = -g * v[3];
        }
    }

    /// [`compute`](Self::compute) on the ranks of `exchange`, the bodies
    /// divided among them: every rank calls it with its own part of them
    /// (`sources`), the parts following each other in rank order, and gets
    /// its own bodies' fields in `out`, those of one process to the bit. The
    /// bodies travel to the ranks that hold their parts of the tree, each
    /// rank builds the subtrees of its bodies and receives from the others
    /// the nodes and bodies its walks reach (locally essential trees; module
    /// `spread`).
    pub fn compute_spread(
        &mut self,
        sources: &Sources,
        out: FieldOut,
        threads: &Threads,
        exchange: &dyn Exchange,
    ) {
        let sum_group = self.group_sums();
        let mut sums = std::mem::take(&mut self.spread.sums);
        sums.resize(sources.mass.len(), [0.0; 4]);
        self.spread.evaluate(
            sources.position,
            sources.mass,
            &mut self.solver,
            exchange,
            threads,
            &mut sums,
            |solver, threads| solver.sum_groups(0..solver.tree.groups.len(), threads, &sum_group),
        );
        let g = self.law.g();
        for ((acc, phi), v) in out.acc.iter_mut().zip(out.phi.iter_mut()).zip(&sums) {
            *acc = [g * v[0], g * v[1], g * v[2]];
            *phi = -g * v[3];
        }
        self.spread.sums = sums;
    }

    /// A group's sums: its lists gathered, then summed for its bodies into
    /// `[sum acc_x, acc_y, acc_z, pot]` (without the factors `G` and `-G`);
    /// its interactions.
    fn group_sums(
        &self,
    ) -> impl Fn(&mut GravityLists, Group<Multipole>, &mut [[f64; 4]]) -> (u64, u64) + Sync {
        let kernel = Kernel::new(&self.law);
        let quadrupole = self.solver.params.quadrupole;
        let repulsion = self.law.has_repulsion();
        move |lists: &mut GravityLists, group, target| {
            lists.gather(&group, quadrupole);
            if repulsion {
                lists.evaluate::<true>(&kernel, &group, target);
            } else {
                lists.evaluate::<false>(&kernel, &group, target);
            }
            lists.walk.counts(target.len())
        }
    }
}

#[cfg(test)]
impl BarnesHut {
    /// The bodies of the last [`compute_spread`](Self::compute_spread) that
    /// this rank walked for (its own after the route) and that its locally
    /// essential tree held.
    pub(super) fn held(&self) -> (usize, usize) {
        let own = self.solver.tree.order.iter().filter(|&&i| i != u32::MAX);
        (own.count(), self.solver.tree.order.len())
    }
}

/// One group's lists (the shared walk lists plus the accepted nodes' masses and
/// quadrupoles) and its particles' running sums.
#[derive(Clone, Debug, Default)]
struct GravityLists {
    walk: Lists,
    node_m: Vec<f64>,
    node_q: [Vec<f64>; 6],
    /// Per group particle: its position and its four running sums.
    targets: Vec<Target<3, 4>>,
}

impl GravityLists {
    /// The shared lists of `group`, then the accepted nodes' masses (padded with
    /// zero mass) and quadrupoles.
    fn gather(&mut self, group: &Group<Multipole>, quadrupole: bool) {
        self.walk.gather(group);
        let (ids, multipole) = (&self.walk.accepted, group.moments);
        copy(&mut self.node_m, ids, 0.0, |k| multipole[k].mass);
        for j in 0..6 {
            if quadrupole {
                copy(&mut self.node_q[j], ids, 0.0, |k| multipole[k].quad[j]);
            } else {
                self.node_q[j].clear();
            }
        }
    }

    /// Sums the lists for the group's particles, sorted `start..`, into `target`
    /// as `[sum acc_x, acc_y, acc_z, pot]` without the factors `G` and `-G`.
    ///
    /// The loops run over the lists outside and the group inside, so that four
    /// list entries stay in registers while every group particle meets them; each
    /// particle's sums are four lanes added across at the end, an order fixed by
    /// the lists.
    fn evaluate<const REPULSION: bool>(
        &mut self,
        kernel: &Kernel,
        group: &Group<Multipole>,
        target: &mut [[f64; 4]],
    ) {
        group.targets(target.len(), &mut self.targets);
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
        let lists = &self.walk;
        for c in (0..lists.part_w.len()).step_by(LANES) {
            let x = [
                F64x4::load(&lists.part_x[0][c..]),
                F64x4::load(&lists.part_x[1][c..]),
                F64x4::load(&lists.part_x[2][c..]),
            ];
            let m = F64x4::load(&lists.part_w[c..]);
            let id = F64x4::load(&lists.part_id[c..]);
            for t in self.targets.iter_mut() {
                let d = [
                    x[0] - F64x4::splat(t.x[0]),
                    x[1] - F64x4::splat(t.x[1]),
                    x[2] - F64x4::splat(t.x[2]),
                ];
                let inv = (one / kernel.s2(d).sqrt()).zero_where_equal(id, F64x4::splat(t.id));
                let (k, p) = kernel.factors_in_lanes::<F64x4, REPULSION>(inv);
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
        let node_x = &self.walk.node_x;
        for c in (0..self.node_m.len()).step_by(LANES) {
            let com = [
                F64x4::load(&node_x[0][c..]),
                F64x4::load(&node_x[1][c..]),
                F64x4::load(&node_x[2][c..]),
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
                let (k, p) = kernel.factors_in_lanes::<F64x4, REPULSION>(inv);
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
