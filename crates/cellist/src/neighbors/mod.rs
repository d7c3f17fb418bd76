//! Neighbour search: cell grid, cell list (counting sort), Verlet list (CSR with
//! skin), the traversals and the race-free parallel pair sums.

mod brute;
mod cell_list;
mod clusters;
mod grid;
mod ordered;
mod pairs;
mod parallel;
mod rebuild;
mod sorted;
mod traverse;
mod verlet;

pub use brute::brute_force_pairs;
pub use cell_list::CellList;
pub use clusters::{shifted, squared_length, ClusterList, Lanes, CLUSTER};
pub use grid::{
    image_code, offsets, AnchoredPair, CellGrid, NeighbourCell, StencilKind, StencilRun,
};
pub use ordered::OrderedRows;
pub use pairs::half_pairs;
pub use parallel::{
    gather_cells, gather_verlet, scatter_coloured, scatter_half_rows, scatter_half_rows_shared,
    scatter_verlet_serial, LayerForces, LayerPlan, PairKernel, Summand,
};
pub use rebuild::{Rebuild, RebuildRule};
pub use sorted::{half_list_as_found, sorted_half_list, PairArrays, PairQuantities, SkinList};
pub use traverse::{
    for_each_anchored_pair, for_each_in_row, for_each_row_in_cell, scan, CutoffTest, ScanScratch,
};
pub(crate) use verlet::moved_beyond_half_skin;
pub use verlet::{unpack, VerletList, SLOT_BITS};
