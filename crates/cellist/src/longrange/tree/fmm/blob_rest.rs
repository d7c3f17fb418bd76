//! What the 3D blob law adds to the point law near a blob: the pair sums of
//! `g - g_point` over the pairs closer than a cutoff, on a half cluster pair
//! list ([`ClusterList`]: `4 x 4` pairs at a time from lanes, as md's forces),
//! each pair once and each particle's sum in an order fixed by the list.

use super::super::share::Share;
use crate::geometry::Domain;
use crate::longrange::biot_savart3::{assemble, terms, BlobKernel3, SUMS};
use crate::neighbors::{
    scatter_half_rows, scatter_half_rows_shared, shifted, unpack, CellList, ClusterList, Lanes,
    LayerForces, LayerPlan, CLUSTER,
};
use crate::simd::{axes, F64x4};
use crate::threads::Threads;
use std::ops::Range;

/// The tail of the blob law beyond `rho = r / sigma`, relative to the point
/// law, for the velocity and its gradient: with `Q` of
/// [`crate::longrange::biot_savart3`], `g / g_point = Q` and
/// `g_2 / g_2,point = Q - rho Q' / 3`, `Q' = sqrt(2 / pi) rho^2 exp(-rho^2 / 2)`,
/// so the larger difference is `1 - Q + rho Q' / 3`, and
/// `1 - Q = erfc(rho / sqrt 2) + sqrt(2 / pi) rho exp(-rho^2 / 2)`, which for
/// `rho >= 3` is below `(1 + 1 / rho^2) sqrt(2 / pi) rho exp(-rho^2 / 2)`.
fn tail_bound(rho: f64) -> f64 {
    let gauss = (2.0 / std::f64::consts::PI).sqrt() * (-0.5 * rho * rho).exp();
    gauss * (rho + 1.0 / rho + rho * rho * rho / 3.0)
}

/// How much below the tolerance the tail of one pair at the cutoff lies:
/// the pairs near the cutoff are a thin shell of the sum, and their tails
/// point every way. Measured with the expansions exact, on 3000 and 20,000
/// random blobs and a vortex ring (`sigma = 1.5 h`): a tail of `T` per pair
/// at the cutoff gave RMS errors of the gradient of 0.02-0.05 `T` (the
/// velocity's 3-10 times less) for `T` from 1e-2 to 1e-6, so `T = 4 tol`
/// keeps them below a fifth of the tolerance. (Measured with every pair of
/// the list added; with the blocks beyond `r_c` skipped, the 10^5 ring's
/// gradient error at 1e-3 rose from 9.4e-5 to 1.3e-4, expansions included.)
const TAIL_SLACK: f64 = 0.25;

/// The blob law's difference from the point law within the cutoff `r_c`:
/// `u(x_i) += sum_{|r| < r_c} alpha_j x r (g - g_point)`, and the gradient's
/// terms with `g - g_point` and `g_2 - g_2,point`
/// ([`crate::longrange::biot_savart3`]), plus each particle's own term
/// `[alpha_i]_x g(0)`. The list holds every pair within `r_c` and some
/// beyond: a particle's four pairs with a cluster are computed together,
/// and unless all four lie beyond `r_c` their (smaller) differences beyond
/// it are added as well. Closer than [`CLOSE`] `sigma` the point law is
/// taken as zero (the FMM's near field skips such a pair) and the rest is the
/// blob law itself.
#[derive(Debug)]
pub(super) struct BlobRest {
    kernel: BlobKernel3,
    cutoff: f64,
    pairs: u64,
    list: ClusterList<3>,
    positions: Vec<Lanes<3>>,
    alpha: Vec<Lanes<3>>,
    sums: Vec<Lanes<SUMS>>,
    halo: Vec<Lanes<SUMS>>,
}

impl BlobRest {
    /// The rest for `kernel` at a relative `tolerance`: the cutoff is
    /// `rho sigma` with the least `rho >= 3` (to 1e-3) at which the tail of
    /// one pair ([`tail_bound`]) is below `tolerance / TAIL_SLACK`.
    pub(super) fn new(kernel: BlobKernel3, tolerance: f64) -> Self {
        let target = tolerance / TAIL_SLACK;
        let mut rho = 3.0;
        while tail_bound(rho) > target && rho < 40.0 {
            rho += 1e-3;
        }
        BlobRest {
            kernel,
            cutoff: rho * kernel.sigma(),
            pairs: 0,
            list: ClusterList::empty(rho * kernel.sigma(), 0.0),
            positions: Vec::new(),
            alpha: Vec::new(),
            sums: Vec::new(),
            halo: Vec::new(),
        }
    }

    /// The cutoff `r_c`.
    pub(super) fn cutoff(&self) -> f64 {
        self.cutoff
    }

    /// The pairs of particles the list held at the last evaluation (the
    /// lanes of its cluster pairs, each pair once; of this process's run of
    /// the tasks, for a divided evaluation).
    pub(super) fn pairs(&self) -> u64 {
        self.pairs
    }

    /// Adds the rest to `velocity` and `gradient` of the blobs
    /// `(positions, alpha)`, divided by `share` among processes that hold
    /// the same blobs: each runs a run of the cell layers' tasks with about
    /// the same cluster pairs ([`LayerPlan::task_runs_weighted`],
    /// [`scatter_half_rows_shared`]) and receives
    /// the others' sums, with the bits of the undivided rest.
    pub(super) fn add(
        &mut self,
        positions: &[[f64; 3]],
        alpha: &[[f64; 3]],
        velocity: &mut [[f64; 3]],
        gradient: &mut [[f64; 9]],
        threads: &Threads,
        share: &mut dyn Share,
    ) {
        let domain = Domain::open_around(positions);
        let side = ClusterList::cell_side(&domain, self.cutoff, positions.len());
        // positions beyond any finite box (a blow-up, which the model's
        // check then reports): no cells, and no finite rest
        let Ok(mut cells) = CellList::build_in(&domain, side, positions, threads) else {
            velocity.fill([f64::NAN; 3]);
            return;
        };
        cells.order_cells_in_columns(Some(threads));
        self.list.rebuild(&cells, threads, &mut self.positions);
        let list = &self.list;
        let plan = LayerPlan::over(&cells, list.cell_clusters());
        list.gather(cells.positions(), threads, &mut self.positions);
        let order = cells.order();
        // (the strengths' lanes beyond a cluster's size hold the padding too:
        // their pairs, at the padding's distance, have no rest)
        list.gather_by(|slot| alpha[order[slot] as usize], threads, &mut self.alpha);
        self.sums
            .resize(list.num_clusters(), [[0.0; CLUSTER]; SUMS]);
        let rows = Rows {
            kernel: &self.kernel,
            cutoff2: self.cutoff * self.cutoff,
            close2: close_squared(&self.kernel),
            own: self.kernel.radial(0.0)[0],
            list,
            positions: &self.positions,
            alpha: &self.alpha,
        };
        let mut tallies = vec![(); plan.num_tasks()];
        let work = |clusters: Range<usize>, sums: &LayerForces<Lanes<SUMS>>, _: &mut ()| {
            for c in clusters {
                rows.row(c, sums);
            }
        };
        let (part, parts) = share.part();
        if parts == 1 {
            self.pairs = (CLUSTER * CLUSTER * list.num_entries()) as u64;
            scatter_half_rows(
                &plan,
                &mut self.sums,
                &mut self.halo,
                &mut tallies,
                threads,
                work,
            );
        } else {
            // each rank about the same cluster pairs (the ring's rows differ)
            let runs = plan.task_runs_weighted(parts, |c| 1 + list.row(c).len());
            let own_rows = runs[part].clone().flat_map(|t| plan.task_rows(t));
            self.pairs =
                (CLUSTER * CLUSTER * own_rows.map(|c| list.row(c).len()).sum::<usize>()) as u64;
            let gather = |mine: &[Lanes<SUMS>], counts: &[usize], all: &mut [Lanes<SUMS>]| {
                let mut bounds = vec![0];
                for c in counts {
                    bounds.push(bounds[bounds.len() - 1] + c);
                }
                all[bounds[part]..bounds[part + 1]].copy_from_slice(mine);
                let width = CLUSTER * SUMS;
                share.all_gather(all.as_flattened_mut().as_flattened_mut(), width, &bounds);
            };
            let (sums, halo) = (&mut self.sums, &mut self.halo);
            let own = (&runs[..], part);
            scatter_half_rows_shared(&plan, own, sums, halo, &mut tallies, threads, gather, work);
        }
        for c in 0..list.num_clusters() {
            for (l, slot) in list.slots(c).enumerate() {
                let (u, g) = assemble(&self.sums[c].map(|s| s[l]));
                let k = order[slot] as usize;
                for (o, u) in velocity[k].iter_mut().zip(u) {
                    *o += u;
                }
                for (o, g) in gradient[k].iter_mut().zip(g) {
                    *o += g;
                }
            }
        }
    }
}

/// What the rows of the rest read: the list and its clusters' lanes.
struct Rows<'a> {
    kernel: &'a BlobKernel3,
    /// `r_c^2`.
    cutoff2: f64,
    /// [`close_squared`].
    close2: f64,
    /// `g(0)`.
    own: f64,
    list: &'a ClusterList<3>,
    positions: &'a [Lanes<3>],
    alpha: &'a [Lanes<3>],
}

impl Rows<'_> {
    /// Row `c`: adds to `sums` the terms of cluster `c`'s particles over
    /// their own pairs (slot `j` above slot `i`) and the row's clusters,
    /// their own terms, and each entry's reactions.
    fn row(&self, c: usize, sums: &LayerForces<Lanes<SUMS>>) {
        let zero = F64x4::splat(0.0);
        let (xi, ai) = (&self.positions[c], &self.alpha[c]);
        let ni = self.list.slots(c).len();
        let mut mine = [[zero; SUMS]; CLUSTER];
        // the pairs inside the cluster: lanes j > i
        let above: [F64x4; CLUSTER] = std::array::from_fn(|i| {
            F64x4::load(&std::array::from_fn::<f64, CLUSTER, _>(|j| {
                if j > i {
                    1.0
                } else {
                    0.0
                }
            }))
        });
        let mut own = self.block(c, xi, ai, ni, &above, &mut mine);
        let every = [F64x4::splat(1.0); CLUSTER];
        for &entry in self.list.row(c) {
            let cj = unpack(entry).0;
            sums.add(cj, &self.block(cj, xi, ai, ni, &every, &mut mine));
        }
        // each particle's own term: S += alpha_i g(0)
        let g0 = self.own;
        for (s, o) in own.iter_mut().enumerate() {
            for (i, m) in mine.iter().enumerate().take(ni) {
                let itself = if (3..6).contains(&s) {
                    ai[s - 3][i] * g0
                } else {
                    0.0
                };
                o[i] += m[s].sum() + itself;
            }
        }
        sums.add(c, &own);
    }

    /// The `ni x 4` pairs of the i-lanes `(xi, ai)` with cluster `cj`'s
    /// lanes (`mask[i]` on lane `j`: 1 for a pair, 0 for none): their terms
    /// added to `mine[i]`, and returned, the cluster's reactions (`u` odd in
    /// `r`).
    #[inline(always)]
    fn block(
        &self,
        cj: usize,
        xi: &Lanes<3>,
        ai: &Lanes<3>,
        ni: usize,
        mask: &[F64x4; CLUSTER],
        mine: &mut [[F64x4; SUMS]; CLUSTER],
    ) -> Lanes<SUMS> {
        let xj = shifted(&self.positions[cj], &[0.0; 3]);
        let aj = axes(|a| F64x4::load(&self.alpha[cj][a]));
        let mut theirs = [F64x4::splat(0.0); SUMS];
        let cut2 = F64x4::splat(self.cutoff2);
        for i in 0..ni {
            let d = axes(|a| F64x4::splat(xi[a][i]) - xj[a]);
            let r2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
            // four pairs beyond the cutoff: their rest is dropped
            if !F64x4::any_less(r2, cut2) {
                continue;
            }
            let [g, g2] = self.kernel.rest_from_point(r2, self.close2);
            let (g, g2) = (g * mask[i], g2 * mask[i]);
            for (m, t) in mine[i].iter_mut().zip(terms(aj, d, g, g2)) {
                *m = *m + t;
            }
            let from_i = terms(axes(|a| F64x4::splat(ai[a][i])), d, g, g2);
            for (s, (t, f)) in theirs.iter_mut().zip(from_i).enumerate() {
                *t = if s < 3 { *t - f } else { *t + f };
            }
        }
        theirs.map(F64x4::to_array)
    }
}

/// Pairs closer than `CLOSE sigma` take the blob law whole from the rest, and
/// none from the point law (whose near field skips them, by the same test on
/// the same `r^2`): there the point law is more than 5 times the blob law,
/// and adding it and taking it away again would lose that many times the
/// rounding of the sum (`(sigma / r)^3` times as `r` falls).
const CLOSE: f64 = 1.0;

/// `(CLOSE sigma)^2`.
pub(super) fn close_squared(kernel: &BlobKernel3) -> f64 {
    let close = CLOSE * kernel.sigma();
    close * close
}
