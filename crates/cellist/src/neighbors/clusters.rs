//! Cluster pair lists, the layout of GROMACS's nbnxm kernels: the slots of every
//! cell cut into clusters of [`CLUSTER`] consecutive slots (compact when the
//! cells are ordered in columns, [`CellList::order_cells_in_columns`]), and for
//! every cluster the clusters of the half stencil whose bounding boxes come
//! within `cutoff + skin` of its own. A force kernel then computes `4 x 4` pairs
//! at once from lanes ([`Lanes`]), pairs beyond the cutoff masked, instead of
//! gathering one neighbour at a time.
//!
//! The list holds every pair of a Verlet list of the same `cutoff + skin`, and
//! more: two particles closer than `cutoff + skin` have bounding boxes closer
//! than that too. It stays valid on the same skin/2 rule.

use super::cell_list::CellList;
use super::grid::{StencilKind, StencilRun};
use super::pairs::{expected_pairs, rows_by_cells};
use super::verlet::{moved_beyond_half_skin, pack, unpack, SLOT_BITS};
use crate::geometry::{norm2, Domain};
use crate::simd::F64x4;
use crate::threads::{fill_indexed, map_parts, part_ranges, DisjointSlice, Stretch, Threads};
use std::ops::Range;

/// The coordinate of a position lane beyond a cluster's size: far from any
/// particle (`r^2` about `D 10^60`, finite, and so are the terms the kernel
/// forms from it), so a pair with it is beyond any cutoff.
pub const PADDING: f64 = 1e30;

/// Slots per cluster (at most; the last cluster of a cell may hold fewer).
pub const CLUSTER: usize = 4;

/// One cluster's positions or forces, an array of lanes per axis: lane `l` of
/// axis `a` is component `a` of the cluster's slot `first + l`. Lanes beyond
/// the cluster's size hold 0 in forces and `PADDING` in positions.
pub type Lanes<const D: usize> = [[f64; CLUSTER]; D];

/// A half cluster pair list over the slots of a [`CellList`], in CSR form: row
/// `I` holds the clusters `J` (with the image code they are seen at, packed as
/// in [`VerletList`](super::VerletList)) of the half stencil of `I`'s cell,
/// `J > I` inside a run that holds the cell itself, whose bounding boxes (`J`'s
/// shifted by the image) are closer than `cutoff + skin` and which hold a pair
/// of particles that close. The pairs inside a cluster (slot `j` above slot
/// `i`) are no entry: every cluster has them.
///
/// Each row comes in two parts ([`ClusterList::row_parts`]): first the entries
/// with a pair closer than `cutoff` at the build, then those with none (a
/// pair within `cutoff + skin` only). A kernel can test an entry of the second
/// part for a pair within the cutoff before it computes the forces: most of
/// them stay out of reach until the next build.
#[derive(Clone, Debug)]
pub struct ClusterList<const D: usize> {
    cutoff: f64,
    skin: f64,
    cell_clusters: Vec<u32>,
    first: Vec<u32>,
    start: Vec<usize>,
    entries: Vec<u32>,
    near_counts: Vec<u32>,
    image_shifts: Vec<[f64; D]>,
    box_columns: [[Vec<f64>; D]; 2],
    cell_boxes: Vec<[[f64; D]; 2]>,
    /// Per cluster, bit `l` set when slot `l` holds a ghost (empty: none do).
    ghost_lanes: Vec<u8>,
}

impl<const D: usize> ClusterList<D> {
    /// Builds the list for the particles of `cells` (binned for at least
    /// `cutoff + skin`), in parallel, the same list for any thread count.
    /// `scratch` is overwritten (the positions as lanes).
    pub fn build(
        cells: &CellList<D>,
        cutoff: f64,
        skin: f64,
        threads: &Threads,
        scratch: &mut Vec<Lanes<D>>,
    ) -> Self {
        let mut list = Self::empty(cutoff, skin);
        list.rebuild(cells, threads, scratch);
        list
    }

    /// A list of no cluster yet, for [`ClusterList::rebuild`] or
    /// [`ClusterList::rebuild_owned`] to fill.
    pub fn empty(cutoff: f64, skin: f64) -> Self {
        assert!(skin >= 0.0, "skin must be >= 0");
        ClusterList {
            cutoff,
            skin,
            cell_clusters: Vec::new(),
            first: Vec::new(),
            start: Vec::new(),
            entries: Vec::new(),
            near_counts: Vec::new(),
            image_shifts: Vec::new(),
            box_columns: std::array::from_fn(|_| std::array::from_fn(|_| Vec::new())),
            cell_boxes: Vec::new(),
            ghost_lanes: Vec::new(),
        }
    }

    /// Builds the list anew for `cells` as binned now, reusing its memory;
    /// `scratch` is overwritten (the positions as lanes).
    pub fn rebuild(&mut self, cells: &CellList<D>, threads: &Threads, scratch: &mut Vec<Lanes<D>>) {
        self.rebuild_owned(cells, cells.len(), threads, scratch);
    }

    /// [`ClusterList::rebuild`] for a subdomain whose first `owned` points
    /// (in the order they were binned, [`CellList::order`]) are its own and
    /// the rest ghosts: a cluster that holds no own point (a ghost cluster)
    /// gets no entry for another ghost cluster, so the list holds every pair
    /// with an own point once and skips the ghost-ghost pairs of whole
    /// clusters; the ghost-ghost pairs it still holds (a ghost cluster with
    /// itself, a cluster that mixes own points and ghosts) are marked by
    /// [`ClusterList::ghost_lanes`] for the kernels to skip.
    pub fn rebuild_owned(
        &mut self,
        cells: &CellList<D>,
        owned: usize,
        threads: &Threads,
        scratch: &mut Vec<Lanes<D>>,
    ) {
        let reach = self.cutoff + self.skin;
        assert!(
            reach <= cells.cutoff(),
            "cutoff + skin {reach} above the cell list's {}",
            cells.cutoff()
        );
        self.cut_into_clusters(cells);
        assert!(
            self.num_clusters() <= 1 << SLOT_BITS,
            "a cluster list holds at most 2^{SLOT_BITS} clusters, got {}",
            self.num_clusters()
        );
        self.bound_clusters(cells, threads);
        self.gather(cells.positions(), threads, scratch);
        let mut ghost_lanes = std::mem::take(&mut self.ghost_lanes);
        ghost_lanes.clear();
        if owned < cells.len() {
            let order = cells.order();
            ghost_lanes.extend((0..self.num_clusters()).map(|c| {
                order[self.slots(c)]
                    .iter()
                    .enumerate()
                    .fold(0u8, |bits, (l, &k)| {
                        bits | u8::from(k as usize >= owned) << l
                    })
            }));
        }
        self.ghost_lanes = ghost_lanes;
        let active: Option<Vec<bool>> = (!self.ghost_lanes.is_empty()).then(|| {
            (0..self.num_clusters())
                .map(|c| self.ghost_lanes[c].count_ones() < self.slots(c).len() as u32)
                .collect()
        });
        let active_cells: Option<Vec<bool>> = active.as_ref().map(|a| {
            (0..cells.grid().num_cells())
                .map(|c| {
                    let clusters =
                        self.cell_clusters[c] as usize..self.cell_clusters[c + 1] as usize;
                    a[clusters].contains(&true)
                })
                .collect()
        });
        let search = RowSearch {
            active: active.as_deref(),
            active_cells: active_cells.as_deref(),
            cell_clusters: &self.cell_clusters,
            first: &self.first,
            box_columns: &self.box_columns,
            cell_boxes: &self.cell_boxes,
            lanes: scratch,
            // a hair above (cutoff + skin)^2, so that rounding in the box gap
            // never drops a pair the Verlet list of the same reach would hold
            reach2: reach * reach * (1.0 + 1e-12),
            cutoff2: self.cutoff * self.cutoff,
        };
        let guess = if self.entries.is_empty() {
            // measured on fcc and liquid LJ: about 3 times the pairs computed
            3 * expected_pairs(cells, reach) / (CLUSTER * CLUSTER)
        } else {
            self.entries.len() + self.entries.len() / 16
        };
        let grid = cells.grid();
        let clusters = self.num_clusters();
        self.near_counts.clear();
        self.near_counts.resize(clusters, 0);
        let near_counts = DisjointSlice::new(&mut self.near_counts);
        rows_by_cells(
            cells,
            clusters,
            guess,
            threads,
            &mut self.start,
            &mut self.entries,
            |home, out, lengths, far: &mut Vec<u32>| {
                let mut stencil = [StencilRun::<D>::default(); 27];
                let n = grid.stencil_runs(home, StencilKind::Half, &mut stencil);
                for i in search.clusters_of(home) {
                    let near = search.row(home, i, &stencil[..n], out, far);
                    // SAFETY: cluster `i` is in cell `home`, which one task visits.
                    unsafe {
                        *lengths.get_unchecked(i) = near + far.len();
                        *near_counts.get_unchecked(i) = near as u32;
                    }
                    for entry in far.drain(..) {
                        out.push(entry);
                    }
                }
            },
        );
        self.image_shifts.clear();
        self.image_shifts
            .extend((0..3u8.pow(D as u32)).map(|c| grid.image_shift(c)));
    }

    /// The clusters' bounding boxes as columns (`[lo, hi]`, one array per axis,
    /// padded with empty boxes for a four-lane load at every cluster), and the
    /// cells' boxes (each the union of its clusters').
    fn bound_clusters(&mut self, cells: &CellList<D>, threads: &Threads) {
        let (first, positions, clusters) = (&self.first, cells.positions(), self.num_clusters());
        for (side, columns) in self.box_columns.iter_mut().enumerate() {
            let (empty, extreme): (f64, fn(f64, f64) -> f64) = if side == 0 {
                (f64::INFINITY, f64::min)
            } else {
                (f64::NEG_INFINITY, f64::max)
            };
            for (a, column) in columns.iter_mut().enumerate() {
                fill_indexed(column, clusters, Some(threads), |c| {
                    let slots = first[c] as usize..first[c + 1] as usize;
                    positions[slots].iter().map(|x| x[a]).fold(empty, extreme)
                });
                column.extend([empty; CLUSTER - 1]);
            }
        }
        let (columns, cell_clusters) = (&self.box_columns, &self.cell_clusters);
        fill_indexed(
            &mut self.cell_boxes,
            cells.grid().num_cells(),
            Some(threads),
            |cell| {
                let clusters = cell_clusters[cell] as usize..cell_clusters[cell + 1] as usize;
                clusters.fold(empty_box(), |all, c| {
                    let b = cluster_box(columns, c);
                    [
                        std::array::from_fn(|a| all[0][a].min(b[0][a])),
                        std::array::from_fn(|a| all[1][a].max(b[1][a])),
                    ]
                })
            },
        );
    }

    /// The side of the cells to bin `particles` in for a list of reach
    /// `cutoff + skin = reach`: two sides of a cube that holds a cluster on
    /// average, `2 (CLUSTER V / N)^(1/D)`, so that a cell's half-width columns
    /// ([`CellList::order_cells_in_columns`]) cut into near-cubic clusters;
    /// at least `reach`, and a hair below half the shortest periodic side, so
    /// that such an axis keeps two cells (one when `reach` is half of it).
    pub fn cell_side(domain: &Domain<D>, reach: f64, particles: usize) -> f64 {
        let volume_per_cluster = CLUSTER as f64 * domain.volume() / particles.max(1) as f64;
        let widest = (0..D)
            .filter(|&a| domain.is_periodic(a))
            .map(|a| 0.5 * domain.length[a] * (1.0 - 1e-9))
            .fold(f64::INFINITY, f64::min);
        (2.0 * volume_per_cluster.powf(1.0 / D as f64))
            .min(widest)
            .max(reach)
    }

    /// Cuts every cell's slots into clusters of [`CLUSTER`], the last one of a
    /// cell holding the rest.
    fn cut_into_clusters(&mut self, cells: &CellList<D>) {
        self.cell_clusters.clear();
        self.first.clear();
        for c in 0..cells.grid().num_cells() {
            self.cell_clusters.push(self.first.len() as u32);
            self.first
                .extend(cells.cell_range(c).step_by(CLUSTER).map(|s| s as u32));
        }
        self.cell_clusters.push(self.first.len() as u32);
        self.first.push(cells.len() as u32);
    }

    /// Bit `l` set when slot `l` of cluster `c` holds a ghost (a list built by
    /// [`ClusterList::rebuild_owned`] with ghosts; 0 otherwise): a kernel
    /// computes no pair of two ghosts.
    #[inline(always)]
    pub fn ghost_lanes(&self, c: usize) -> u8 {
        self.ghost_lanes.get(c).copied().unwrap_or(0)
    }

    /// The interaction cutoff (without skin).
    pub fn cutoff(&self) -> f64 {
        self.cutoff
    }

    /// The skin.
    pub fn skin(&self) -> f64 {
        self.skin
    }

    /// Number of clusters (rows).
    pub fn num_clusters(&self) -> usize {
        self.first.len() - 1
    }

    /// `cell_clusters[c]`: the first cluster of cell `c` (`num_cells + 1`
    /// entries), for a [`LayerPlan`](super::LayerPlan) over clusters.
    pub fn cell_clusters(&self) -> &[u32] {
        &self.cell_clusters
    }

    /// The slots of cluster `c`.
    #[inline(always)]
    pub fn slots(&self, c: usize) -> Range<usize> {
        self.first[c] as usize..self.first[c + 1] as usize
    }

    /// Row `c`: its entries, each a neighbour cluster and image code ([`unpack`]).
    #[inline(always)]
    pub fn row(&self, c: usize) -> &[u32] {
        &self.entries[self.start[c]..self.start[c + 1]]
    }

    /// Row `c` in its two parts: the entries with a pair closer than the
    /// cutoff at the build, then the others.
    #[inline(always)]
    pub fn row_parts(&self, c: usize) -> (&[u32], &[u32]) {
        self.row(c).split_at(self.near_counts[c] as usize)
    }

    /// Puts every entry of every row in the first part (tests only): a kernel
    /// then computes every block without testing it first.
    #[cfg(test)]
    pub(crate) fn without_far_parts(&mut self) {
        for (c, near) in self.near_counts.iter_mut().enumerate() {
            *near = (self.start[c + 1] - self.start[c]) as u32;
        }
    }

    /// Total number of cluster pairs.
    pub fn num_entries(&self) -> usize {
        self.entries.len()
    }

    /// The shift vector of an image code.
    #[inline(always)]
    pub fn image_shift(&self, code: u8) -> &[f64; D] {
        &self.image_shifts[code as usize]
    }

    /// The shift vectors of all image codes, indexed by code.
    pub fn image_shifts(&self) -> &[[f64; D]] {
        &self.image_shifts
    }

    /// The positions (slot order) as lanes, one [`Lanes`] per cluster, in
    /// parallel on `threads`.
    pub fn gather(&self, positions: &[[f64; D]], threads: &Threads, out: &mut Vec<Lanes<D>>) {
        assert_eq!(positions.len() as u32, *self.first.last().unwrap_or(&0));
        self.gather_by(|slot| positions[slot], threads, out);
    }

    /// The position of every slot, `position(slot)`, as lanes, one [`Lanes`]
    /// per cluster, in parallel on `threads`.
    pub fn gather_by(
        &self,
        position: impl Fn(usize) -> [f64; D] + Sync,
        threads: &Threads,
        out: &mut Vec<Lanes<D>>,
    ) {
        fill_indexed(out, self.num_clusters(), Some(threads), |c| {
            let mut lanes = [[PADDING; CLUSTER]; D];
            for (l, slot) in self.slots(c).enumerate() {
                let x = position(slot);
                for a in 0..D {
                    lanes[a][l] = x[a];
                }
            }
            lanes
        });
    }

    /// Writes lanes back to the slots: `out[first_c + l][a] = lanes[c][a][l]`,
    /// in parallel on `threads`.
    pub fn scatter(&self, lanes: &[Lanes<D>], threads: &Threads, out: &mut [[f64; D]]) {
        assert_eq!(lanes.len(), self.num_clusters());
        assert_eq!(out.len() as u32, *self.first.last().unwrap_or(&0));
        let parts = part_ranges(self.num_clusters(), threads.count());
        let shared = DisjointSlice::new(out);
        map_parts(Some(threads), parts.len(), |p| {
            let clusters = parts[p].clone();
            if clusters.is_empty() {
                return;
            }
            let slots = self.slots(clusters.start).start..self.slots(clusters.end - 1).end;
            let base = slots.start;
            // SAFETY: the parts' clusters, and so their slots, are disjoint.
            let out = unsafe { shared.range(slots) };
            for c in clusters {
                for (l, slot) in self.slots(c).enumerate() {
                    out[slot - base] = std::array::from_fn(|a| lanes[c][a][l]);
                }
            }
        });
    }

    /// Visits every pair of slots the list holds, cluster by cluster (its own
    /// pairs, then its row), as `visit(i, j, d, r2)` with `d = x_i - (x_j +
    /// shift)` and `r2 = |d|^2` at `positions` (slot order): every pair within
    /// `cutoff + skin` at the build, and others.
    pub fn for_each_pair(
        &self,
        positions: &[[f64; D]],
        mut visit: impl FnMut(usize, usize, &[f64; D], f64),
    ) {
        let mut pair = |i: usize, j: usize, shift: &[f64; D]| {
            let (xi, xj) = (&positions[i], &positions[j]);
            let d: [f64; D] = std::array::from_fn(|a| xi[a] - (xj[a] + shift[a]));
            visit(i, j, &d, norm2(&d));
        };
        for c in 0..self.num_clusters() {
            let own = self.slots(c);
            for i in own.clone() {
                for j in i + 1..own.end {
                    pair(i, j, &[0.0; D]);
                }
            }
            for &entry in self.row(c) {
                let (other, image) = unpack(entry);
                let shift = self.image_shift(image);
                for i in self.slots(c) {
                    for j in self.slots(other) {
                        pair(i, j, shift);
                    }
                }
            }
        }
    }

    /// True when some particle has moved more than `skin / 2` since the build
    /// (see [`VerletList::needs_rebuild`](super::VerletList::needs_rebuild)):
    /// `cells` is the cell list the list was built from, not rebinned since.
    pub fn needs_rebuild(&self, cells: &CellList<D>, positions: &[[f64; D]]) -> bool {
        moved_beyond_half_skin(positions, cells.positions(), self.skin)
    }
}

/// `[lo, hi]` of no point: beyond every other box.
const fn empty_box<const D: usize>() -> [[f64; D]; 2] {
    [[f64::INFINITY; D], [f64::NEG_INFINITY; D]]
}

/// Cluster `c`'s box `[lo, hi]` from the box columns.
#[inline(always)]
fn cluster_box<const D: usize>(columns: &[[Vec<f64>; D]; 2], c: usize) -> [[f64; D]; 2] {
    columns
        .each_ref()
        .map(|side| std::array::from_fn(|a| side[a][c]))
}

/// What the search for one cluster's row reads.
struct RowSearch<'a, const D: usize> {
    /// Per cluster, whether it holds an own point (`None`: all do).
    active: Option<&'a [bool]>,
    /// Per cell, whether one of its clusters holds an own point.
    active_cells: Option<&'a [bool]>,
    cell_clusters: &'a [u32],
    first: &'a [u32],
    box_columns: &'a [[Vec<f64>; D]; 2],
    cell_boxes: &'a [[[f64; D]; 2]],
    lanes: &'a [Lanes<D>],
    reach2: f64,
    cutoff2: f64,
}

impl<const D: usize> RowSearch<'_, D> {
    /// The clusters of cell `cell`.
    fn clusters_of(&self, cell: usize) -> Range<usize> {
        self.cell_clusters[cell] as usize..self.cell_clusters[cell + 1] as usize
    }

    /// Finds the row of cluster `i` (of cell `home`, whose half stencil is
    /// `stencil`): appends its entries with a pair closer than the cutoff to
    /// `out` and returns their number, and appends the others to `far`. Per
    /// stencil cell: the cell's box, then the boxes of up to 64 of its clusters
    /// at once without a branch, then the atom pairs of those whose boxes are
    /// close.
    fn row(
        &self,
        home: usize,
        i: usize,
        stencil: &[StencilRun<D>],
        out: &mut Stretch<u32>,
        far: &mut Vec<u32>,
    ) -> usize {
        let own = cluster_box(self.box_columns, i);
        let count = (self.first[i + 1] - self.first[i]) as usize;
        // a ghost cluster's row holds only clusters with an own point
        let wanted = self.active.filter(|a| !a[i]);
        let wanted_cells = self.active_cells.filter(|_| wanted.is_some());
        let mut near_len = 0;
        let cells = stencil
            .iter()
            .flat_map(|run| (run.first_cell..=run.last_cell).map(move |c| (c, run)));
        for (cell, run) in cells {
            if wanted_cells.is_some_and(|a| !a[cell]) {
                continue;
            }
            if box_gap2(&own, &self.cell_boxes[cell], &run.shift) >= self.reach2 {
                continue;
            }
            let mut candidates = self.clusters_of(cell);
            if run.holds_home && cell == home {
                // the clusters after i (its own pairs are not a row entry)
                candidates.start = i + 1;
            }
            let [lo, hi] = own.map(|x| std::array::from_fn(|a| x[a] - run.shift[a]));
            let xi = &self.lanes[i];
            for from in candidates.clone().step_by(64) {
                let to = (from + 64).min(candidates.end);
                let mut close = close_boxes(self.box_columns, from..to, &lo, &hi, self.reach2);
                while close != 0 {
                    let j = from + close.trailing_zeros() as usize;
                    close &= close - 1;
                    if wanted.is_some_and(|a| !a[j]) {
                        continue;
                    }
                    let nearest = nearest_pair(xi, count, &self.lanes[j], &run.shift);
                    let entry = pack(j, run.image);
                    let near = F64x4::any_less(nearest, F64x4::splat(self.cutoff2));
                    out.push_if(entry, near);
                    near_len += usize::from(near);
                    if !near && F64x4::any_less(nearest, F64x4::splat(self.reach2)) {
                        far.push(entry);
                    }
                }
            }
        }
        near_len
    }
}

/// Lane `l`: the smallest `r^2` between lane `l` of `b` shifted by `shift` and
/// the first `count` lanes of `a` (padding lanes of `b` are too far to count).
#[inline]
fn nearest_pair<const D: usize>(
    a: &Lanes<D>,
    count: usize,
    b: &Lanes<D>,
    shift: &[f64; D],
) -> F64x4 {
    let xj = shifted(b, shift);
    let mut nearest = F64x4::splat(f64::INFINITY);
    for i in 0..count {
        nearest = nearest.min(separation(a, i, &xj).1);
    }
    nearest
}

/// The lanes of `lanes` shifted by `shift`: `x_J + s`, one vector per axis.
#[inline(always)]
pub fn shifted<const D: usize>(lanes: &Lanes<D>, shift: &[f64; D]) -> [F64x4; D] {
    std::array::from_fn(|a| F64x4::load(&lanes[a]) + F64x4::splat(shift[a]))
}

/// The separations `d = x_i - x_J` of lane `i` of `xi` from the four lanes
/// `xj`, and `r^2 = |d|^2` (summed axis by axis with fused multiply-adds): one
/// row of a `4 x 4` block.
#[inline(always)]
pub fn separation<const D: usize>(xi: &Lanes<D>, i: usize, xj: &[F64x4; D]) -> ([F64x4; D], F64x4) {
    let d: [F64x4; D] = std::array::from_fn(|a| F64x4::splat(xi[a][i]) - xj[a]);
    (d, squared_length(&d))
}

/// `|d|^2` lane by lane, `d_0 d_0` then one fused multiply-add per further
/// axis: the `r^2` of `separation`.
#[inline(always)]
pub fn squared_length<const D: usize>(d: &[F64x4; D]) -> F64x4 {
    d[1..]
        .iter()
        .fold(d[0] * d[0], |r2, da| da.mul_add(*da, r2))
}

/// Bit `k` set where the box of cluster `range.start + k` comes within
/// `sqrt(reach2)` of the box `[lo, hi]` (`range` at most 64 clusters; `lo` and
/// `hi` already shifted by minus the image shift of the clusters): the gap
/// `max(0, lo_j - hi, lo - hi_j)` per axis, four boxes per vector from the
/// box columns (`[lo, hi]`, one array per axis, padded for a last load).
#[inline]
fn close_boxes<const D: usize>(
    columns: &[[Vec<f64>; D]; 2],
    range: Range<usize>,
    lo: &[f64; D],
    hi: &[f64; D],
    reach2: f64,
) -> u64 {
    let zero = F64x4::splat(0.0);
    let mut close = 0u64;
    for k in range.clone().step_by(CLUSTER) {
        let mut gap2 = zero;
        for a in 0..D {
            let above = F64x4::load(&columns[0][a][k..]) - F64x4::splat(hi[a]);
            let below = F64x4::splat(lo[a]) - F64x4::load(&columns[1][a][k..]);
            let gap = above.max(below).max(zero);
            gap2 = gap.mul_add(gap, gap2);
        }
        close |= u64::from(F64x4::mask_less(gap2, F64x4::splat(reach2))) << (k - range.start);
    }
    close & (u64::MAX >> (64 - range.len()))
}

/// The squared distance between box `a` and box `b` shifted by `shift`:
/// `sum_k max(0, lo_b,k + s_k - hi_a,k, lo_a,k - hi_b,k - s_k)^2`.
#[inline(always)]
fn box_gap2<const D: usize>(a: &[[f64; D]; 2], b: &[[f64; D]; 2], shift: &[f64; D]) -> f64 {
    let mut gap2 = 0.0;
    for k in 0..D {
        let gap = (b[0][k] + shift[k] - a[1][k])
            .max(a[0][k] - (b[1][k] + shift[k]))
            .max(0.0);
        gap2 += gap * gap;
    }
    gap2
}
