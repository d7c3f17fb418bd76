//! The half cluster pair list of a set of points and the buffers of its force
//! pass: the cell list the points are binned in (cells ordered in columns),
//! the [`ClusterList`] over it, the [`LayerPlan`] its rows run in parallel by,
//! and the lanes the kernel ([`ClusterForces`]) reads and writes. Both the
//! single-process system ([`MdSystem`](super::MdSystem)) and a subdomain of a
//! distributed run ([`HaloForces`](super::HaloForces)) compute their forces
//! through it:
//!
//! ```text
//! f_i = sum_{j in list, r_ij < r_c} f_ij,   f_j -= f_ij   (Newton's third law)
//! ```

use super::cluster_forces::ClusterForces;
use super::PairTally;
use crate::geometry::{Domain, GeometryError};
use crate::interactions::LennardJones;
use crate::neighbors::{CellList, ClusterList, Lanes, LayerPlan, CLUSTER};
use crate::threads::Threads;

/// A cell list, its half cluster pair list and the force pass's buffers.
pub(super) struct ClusterPairs<const D: usize> {
    /// The points binned at the last build (slot order, wrapped).
    pub(super) cells: CellList<D>,
    /// The half cluster pair list over the cells' slots.
    pub(super) list: ClusterList<D>,
    /// The cell layers the rows run in.
    pub(super) layers: LayerPlan,
    tallies: Vec<PairTally>,
    lanes: Vec<Lanes<D>>,
    lane_forces: Vec<Lanes<D>>,
    halo: Vec<Lanes<D>>,
}

impl<const D: usize> ClusterPairs<D> {
    /// Bins `points` in `domain` in cells for a list of reach `cutoff + skin`
    /// ([`ClusterList::cell_side`]) and builds the list, the first `owned`
    /// points own and the rest ghosts ([`ClusterList::rebuild_owned`]).
    pub(super) fn new(
        domain: &Domain<D>,
        points: &[[f64; D]],
        owned: usize,
        cutoff: f64,
        skin: f64,
        threads: &Threads,
    ) -> Result<Self, GeometryError> {
        let side = ClusterList::cell_side(domain, cutoff + skin, points.len());
        let cells = CellList::build_in(domain, side, points, threads)?;
        Ok(Self::from_cells(cells, owned, cutoff, skin, threads))
    }

    /// The list over points binned in `cells` (cells of at least
    /// `cutoff + skin`), the first `owned` own.
    pub(super) fn from_cells(
        mut cells: CellList<D>,
        owned: usize,
        cutoff: f64,
        skin: f64,
        threads: &Threads,
    ) -> Self {
        order_in_columns(&mut cells, threads);
        let mut pairs = ClusterPairs {
            list: ClusterList::empty(cutoff, skin),
            layers: LayerPlan::default(),
            cells,
            tallies: Vec::new(),
            lanes: Vec::new(),
            lane_forces: Vec::new(),
            halo: Vec::new(),
        };
        pairs.build_list(owned, threads);
        pairs
    }

    /// Bins `points` anew in the same grid (cells ordered in columns); the
    /// list is not rebuilt.
    pub(super) fn rebin(&mut self, points: &[[f64; D]], threads: &Threads) {
        self.cells.rebin_in(points, threads);
        order_in_columns(&mut self.cells, threads);
    }

    /// The cluster list and its layers for the cells as binned now, the first
    /// `owned` points (in binning order) own.
    pub(super) fn build_list(&mut self, owned: usize, threads: &Threads) {
        self.list
            .rebuild_owned(&self.cells, owned, threads, &mut self.lanes);
        self.layers = LayerPlan::over(&self.cells, self.list.cell_clusters());
        self.tallies
            .resize(self.layers.num_tasks(), PairTally::default());
    }

    /// Sets `forces` (slot order, every element) to the pair sums at
    /// `positions` (slot order, each within skin/2 of its build position);
    /// with `energy`, returns the energy and virial of the listed pairs.
    pub(super) fn forces(
        &mut self,
        potential: &LennardJones,
        positions: &[[f64; D]],
        energy: bool,
        threads: &Threads,
        forces: &mut [[f64; D]],
    ) -> Option<PairTally> {
        self.list.gather(positions, threads, &mut self.lanes);
        let totals = self.lane_sums(potential, energy, threads);
        self.list.scatter(&self.lane_forces, threads, forces);
        totals
    }

    /// [`ClusterPairs::forces`] from the position of each point `k`, in the
    /// numbering they were binned in ([`CellList::order`]), `position(k)`;
    /// the force on each point passed to `force(k, f_k)` (one thread); with
    /// `energy`, returns the energy and virial of the listed pairs.
    pub(super) fn forces_by_point(
        &mut self,
        potential: &LennardJones,
        position: impl Fn(usize) -> [f64; D] + Sync,
        energy: bool,
        threads: &Threads,
        mut force: impl FnMut(usize, [f64; D]),
    ) -> Option<PairTally> {
        let order = self.cells.order();
        self.list.gather_by(
            |slot| position(order[slot] as usize),
            threads,
            &mut self.lanes,
        );
        let totals = self.lane_sums(potential, energy, threads);
        let order = self.cells.order();
        for (c, lanes) in self.lane_forces.iter().enumerate() {
            for (l, slot) in self.list.slots(c).enumerate() {
                force(order[slot] as usize, std::array::from_fn(|a| lanes[a][l]));
            }
        }
        totals
    }

    /// The pair sums of the positions in `lanes` into `lane_forces`; with
    /// `energy`, the energy and virial of the listed pairs.
    fn lane_sums(
        &mut self,
        potential: &LennardJones,
        energy: bool,
        threads: &Threads,
    ) -> Option<PairTally> {
        // every element is set by the sum (scatter_half_rows): no zeroing pass
        self.lane_forces
            .resize(self.list.num_clusters(), [[0.0; CLUSTER]; D]);
        self.tallies.fill(PairTally::default());
        let kernel = ClusterForces {
            list: &self.list,
            layers: &self.layers,
            potential,
            positions: &self.lanes,
        };
        let (lanes, halo, tallies) = (&mut self.lane_forces, &mut self.halo, &mut self.tallies);
        if energy {
            kernel.run::<true>(lanes, halo, tallies, threads);
            let mut totals = PairTally::default();
            for t in tallies.iter() {
                totals.energy += t.energy;
                totals.virial += t.virial;
            }
            Some(totals)
        } else {
            kernel.run::<false>(lanes, halo, tallies, threads);
            None
        }
    }
}

impl<const D: usize> ClusterPairs<D> {
    /// Per slot, half the energy and half the virial of every listed pair
    /// within the cutoff it is in ([`ClusterForces::half_pair_sums`]), at the
    /// positions of the last force pass.
    pub(super) fn half_pair_sums(
        &self,
        potential: &LennardJones,
        energies: &mut [f64],
        virials: &mut [f64],
    ) {
        let kernel = ClusterForces {
            list: &self.list,
            layers: &self.layers,
            potential,
            positions: &self.lanes,
        };
        kernel.half_pair_sums(energies, virials);
    }
}

/// Orders each cell of `cells` in columns for the cluster list; the cell
/// list's per-axis columns, which md does not read, are released first.
fn order_in_columns<const D: usize>(cells: &mut CellList<D>, threads: &Threads) {
    cells.release_columns();
    cells.order_cells_in_columns(Some(threads));
}
