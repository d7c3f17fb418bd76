//! Verlet lists: each particle's neighbours within `cutoff + skin`, in CSR form,
//! reused until some particle has moved more than `skin / 2`.

use super::cell_list::CellList;
use super::grid::StencilKind;
use super::pairs::expected_pairs;
use super::traverse::{for_each_row_in_cell, CutoffTest};
use crate::geometry::norm2;
use crate::threads::{concat_into, Threads};
use rayon::prelude::*;

/// A neighbour list in compressed-sparse-row form over the sorted slots of a
/// [`CellList`].
///
/// Row `i` is `neighbors[start[i]..start[i + 1]]`; entry `k` of a row is the slot `j`
/// of a neighbour, seen at the image `x_j + shift(images[k])` (zero shift except across
/// periodic faces). A half list holds each pair once (for Newton's third law), a full
/// list holds it in both rows. The list stays valid while no particle has moved more
/// than `skin / 2` from where it was at the build: two particles then approach by at
/// most `skin`, so every pair now within `cutoff` was within `cutoff + skin`.
#[derive(Clone, Debug)]
pub struct VerletList<const D: usize> {
    kind: StencilKind,
    cutoff: f64,
    test: CutoffTest,
    skin: f64,
    start: Vec<usize>,
    neighbors: Vec<u32>,
    images: Vec<u8>,
    image_shifts: Vec<[f64; D]>,
    reference: Vec<[f64; D]>,
    chunks: Vec<ChunkRows>,
}

/// The rows of one chunk of home cells, as found by one task of a build; kept
/// between builds for their memory.
#[derive(Clone, Debug, Default)]
struct ChunkRows {
    lengths: Vec<u32>,
    neighbors: Vec<u32>,
    images: Vec<u8>,
}

impl<const D: usize> VerletList<D> {
    /// Builds the list of `kind` for the particles of `cells` (which must have been
    /// built for a cutoff of at least `cutoff + skin`), in parallel, with rows in slot
    /// order whatever the thread count.
    pub fn build(
        cells: &CellList<D>,
        kind: StencilKind,
        cutoff: f64,
        skin: f64,
        threads: &Threads,
    ) -> Self {
        assert!(skin >= 0.0, "skin must be >= 0");
        let mut list = VerletList {
            kind,
            cutoff,
            test: CutoffTest::new(cutoff),
            skin,
            start: Vec::new(),
            neighbors: Vec::new(),
            images: Vec::new(),
            image_shifts: Vec::new(),
            reference: Vec::new(),
            chunks: Vec::new(),
        };
        list.rebuild(cells, threads);
        list
    }

    /// Builds the list anew for the particles of `cells` as binned now, reusing the
    /// memory of the previous build (no allocation once the list has reached its
    /// size).
    pub fn rebuild(&mut self, cells: &CellList<D>, threads: &Threads) {
        let reach = self.cutoff + self.skin;
        assert!(
            reach <= cells.cutoff(),
            "cutoff + skin {reach} above the cell list's {}",
            cells.cutoff()
        );
        let test = CutoffTest::new(reach);
        let kind = self.kind;
        let grid = cells.grid();
        let per_slot = match kind {
            StencilKind::Half => 1.0,
            StencilKind::Full => 2.0,
        } * expected_pairs(cells, reach) as f64
            / cells.len().max(1) as f64;
        let ranges = Threads::chunks(grid.num_cells());
        self.chunks.resize_with(ranges.len(), ChunkRows::default);
        threads.install(|| {
            ranges
                .zip(self.chunks.par_iter_mut())
                .for_each(|(range, chunk)| {
                    let first_slot = cells.cell_range(range.start).start;
                    let last_slot = cells.cell_range(range.end - 1).end;
                    chunk.lengths.clear();
                    chunk.lengths.resize(last_slot - first_slot, 0);
                    chunk.neighbors.clear();
                    chunk.images.clear();
                    let capacity = (per_slot * (last_slot - first_slot) as f64) as usize;
                    chunk.neighbors.reserve(capacity);
                    chunk.images.reserve(capacity);
                    for home in range {
                        for_each_row_in_cell(cells, home, kind, &test, |i, j, image, _, _| {
                            chunk.lengths[i - first_slot] += 1;
                            chunk.neighbors.push(j as u32);
                            chunk.images.push(image);
                        });
                    }
                });
        });
        self.start.clear();
        self.start.push(0);
        let mut total = 0usize;
        for &l in self.chunks.iter().flat_map(|c| &c.lengths) {
            total += l as usize;
            self.start.push(total);
        }
        let neighbor_parts: Vec<&[u32]> = self.chunks.iter().map(|c| &c.neighbors[..]).collect();
        let image_parts: Vec<&[u8]> = self.chunks.iter().map(|c| &c.images[..]).collect();
        threads.install(|| {
            concat_into(&mut self.neighbors, &neighbor_parts);
            concat_into(&mut self.images, &image_parts);
        });
        self.image_shifts.clear();
        self.image_shifts
            .extend((0..3u8.pow(D as u32)).map(|c| grid.image_shift(c)));
        self.reference.clear();
        self.reference.extend_from_slice(cells.positions());
    }

    /// The positions of the last build (slot order, wrapped): the reference of the
    /// skin/2 test.
    pub fn reference(&self) -> &[[f64; D]] {
        &self.reference
    }

    /// Half or full.
    pub fn kind(&self) -> StencilKind {
        self.kind
    }

    /// The interaction cutoff (without skin).
    pub fn cutoff(&self) -> f64 {
        self.cutoff
    }

    /// The skin.
    pub fn skin(&self) -> f64 {
        self.skin
    }

    /// Number of rows (particles).
    pub fn len(&self) -> usize {
        self.start.len() - 1
    }

    /// True when the list has no rows.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Total number of entries.
    pub fn num_entries(&self) -> usize {
        self.neighbors.len()
    }

    /// Row `i`: neighbour slots and their image codes.
    #[inline]
    pub fn row(&self, i: usize) -> (&[u32], &[u8]) {
        let r = self.start[i]..self.start[i + 1];
        (&self.neighbors[r.clone()], &self.images[r])
    }

    /// The shift vector of an image code.
    #[inline]
    pub fn image_shift(&self, code: u8) -> &[f64; D] {
        &self.image_shifts[code as usize]
    }

    /// Visits the entries of row `i` that are within the cutoff at the current
    /// `positions` (slot order) as `visit(j, d, r2)`, `d = x_j + shift - x_i`.
    #[inline]
    pub fn for_each_in_row(
        &self,
        i: usize,
        positions: &[[f64; D]],
        mut visit: impl FnMut(usize, &[f64; D], f64),
    ) {
        let xi = &positions[i];
        let (js, images) = self.row(i);
        for (&j, &image) in js.iter().zip(images) {
            let j = j as usize;
            let shift = self.image_shift(image);
            let xj = &positions[j];
            let d: [f64; D] = std::array::from_fn(|a| (xj[a] - xi[a]) + shift[a]);
            let r2 = norm2(&d);
            if self.test.accepts(r2) {
                visit(j, &d, r2);
            }
        }
    }

    /// True when some particle has moved more than `skin / 2` since the build,
    /// `max_i |x_i - x_i^build| > skin / 2`: the cheap test, O(N), no neighbour search.
    /// `positions` are in slot order and not wrapped since the build.
    pub fn needs_rebuild(&self, positions: &[[f64; D]]) -> bool {
        moved_beyond_half_skin(positions, &self.reference, self.skin)
    }
}

/// `max_i |x_i - x_i^build| > skin / 2`: some particle moved far enough that a
/// list built at `reference` with this skin may miss a pair.
pub(crate) fn moved_beyond_half_skin<const D: usize>(
    positions: &[[f64; D]],
    reference: &[[f64; D]],
    skin: f64,
) -> bool {
    assert_eq!(positions.len(), reference.len());
    let limit = 0.25 * skin * skin;
    positions.iter().zip(reference).any(|(x, x0)| {
        let d: [f64; D] = std::array::from_fn(|a| x[a] - x0[a]);
        norm2(&d) > limit
    })
}
