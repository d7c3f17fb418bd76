//! Verlet lists: each particle's neighbours within `cutoff + skin`, in CSR form,
//! reused until some particle has moved more than `skin / 2`.

use super::cell_list::CellList;
use super::grid::StencilKind;
use super::pairs::{expected_pairs, rows_by_cells};
use super::traverse::{for_each_row_in_cell, CutoffTest};
use crate::geometry::norm2;
use crate::threads::Threads;
use std::ops::Range;

/// A neighbour list in compressed-sparse-row form over the sorted slots of a
/// [`CellList`].
///
/// Row `i` is `entries[start[i]..start[i + 1]]`; an entry packs the slot `j` of a
/// neighbour (low [`SLOT_BITS`] bits) and the image code `c` it is seen at
/// (`x_j + shift(c)`, zero shift except across periodic faces), 4 bytes per
/// entry. A half list holds each pair once (for Newton's third law), a full
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
    entries: Vec<u32>,
    image_shifts: Vec<[f64; D]>,
}

/// Bits of a list entry that hold the neighbour's slot; the image code (below
/// 27) takes the 5 above them. A list holds at most `2^27` particles.
pub const SLOT_BITS: u32 = 27;

/// The entry of neighbour slot `j` seen at image code `image`.
#[inline(always)]
pub(crate) fn pack(j: usize, image: u8) -> u32 {
    debug_assert!(j < 1 << SLOT_BITS && image < 32);
    j as u32 | (image as u32) << SLOT_BITS
}

/// The neighbour slot and image code of a list entry.
#[inline(always)]
pub fn unpack(entry: u32) -> (usize, u8) {
    (
        (entry & ((1 << SLOT_BITS) - 1)) as usize,
        (entry >> SLOT_BITS) as u8,
    )
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
            entries: Vec::new(),
            image_shifts: Vec::new(),
        };
        list.rebuild(cells, threads);
        list
    }

    /// Builds the list anew for the particles of `cells` as binned now, reusing the
    /// memory of the previous build (no allocation once the list has reached its
    /// size).
    pub fn rebuild(&mut self, cells: &CellList<D>, threads: &Threads) {
        self.rebuild_rows(cells, 0..cells.len(), threads);
    }

    /// The list of `kind` for the particles of `cells` within `cutoff`
    /// (no skin), with the rows of the cells that hold some slot of `rows`
    /// (the other rows empty): the part of the list whose rows one of several
    /// ranks sums.
    pub fn build_rows(
        cells: &CellList<D>,
        kind: StencilKind,
        cutoff: f64,
        rows: Range<usize>,
        threads: &Threads,
    ) -> Self {
        let mut list = VerletList {
            kind,
            cutoff,
            test: CutoffTest::new(cutoff),
            skin: 0.0,
            start: Vec::new(),
            entries: Vec::new(),
            image_shifts: Vec::new(),
        };
        list.rebuild_rows(cells, rows, threads);
        list
    }

    /// [`VerletList::rebuild`] of the rows of the cells that hold some slot
    /// of `rows`.
    fn rebuild_rows(&mut self, cells: &CellList<D>, rows: Range<usize>, threads: &Threads) {
        let reach = self.cutoff + self.skin;
        assert!(
            reach <= cells.cutoff(),
            "cutoff + skin {reach} above the cell list's {}",
            cells.cutoff()
        );
        assert!(
            cells.len() <= 1 << SLOT_BITS,
            "a Verlet list holds at most 2^{SLOT_BITS} particles, got {}",
            cells.len()
        );
        let test = CutoffTest::new(reach);
        let kind = self.kind;
        let cell_start = cells.cell_start();
        let grid = cells.grid();
        let entries = match kind {
            StencilKind::Half => 1,
            StencilKind::Full => 2,
        } * expected_pairs(cells, reach);
        rows_by_cells(
            cells,
            cells.len(),
            entries,
            threads,
            &mut self.start,
            &mut self.entries,
            |home, out, lengths, _: &mut ()| {
                let (first, end) = (cell_start[home] as usize, cell_start[home + 1] as usize);
                if first >= rows.end || end <= rows.start {
                    return;
                }
                for_each_row_in_cell(cells, home, kind, &test, |i, j, image, _, _| {
                    // SAFETY: slot `i` is in cell `home`, which one task visits.
                    unsafe { *lengths.get_unchecked(i) += 1 };
                    out.push(pack(j, image));
                });
            },
        );
        self.image_shifts.clear();
        self.image_shifts
            .extend((0..3u8.pow(D as u32)).map(|c| grid.image_shift(c)));
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
        self.entries.len()
    }

    /// Row `i`: its entries, each a neighbour slot and image code ([`unpack`]).
    #[inline]
    pub fn row(&self, i: usize) -> &[u32] {
        &self.entries[self.start[i]..self.start[i + 1]]
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
        for &entry in self.row(i) {
            let (j, image) = unpack(entry);
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
    /// `cells` is the cell list the list was built from, not rebinned since: its
    /// positions (wrapped, slot order) are where the particles were at the build.
    pub fn needs_rebuild(&self, cells: &CellList<D>, positions: &[[f64; D]]) -> bool {
        moved_beyond_half_skin(positions, cells.positions(), self.skin)
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
