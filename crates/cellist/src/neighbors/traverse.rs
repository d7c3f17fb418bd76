//! The inner loops of the neighbour search: the exact cutoff test, the scan of one
//! neighbour cell, the rows of a home cell (half or full stencil), and the cell
//! pairs of an anchor (for coloured passes).

use super::cell_list::CellList;
use super::grid::{AnchoredPair, StencilKind, StencilRun};
use std::ops::Range;

/// The membership test `|x_j - x_i| < r_c`, decided exactly as `sqrt(r^2) < r_c` in
/// binary64, but with one comparison of `r^2` for all pairs that are not within a
/// relative `1e-14` of the cutoff.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CutoffTest {
    cutoff: f64,
    surely_inside: f64,
    surely_outside: f64,
}

impl CutoffTest {
    /// The test for a cutoff `r_c > 0`.
    pub fn new(cutoff: f64) -> Self {
        let rc2 = cutoff * cutoff;
        CutoffTest {
            cutoff,
            surely_inside: rc2 * (1.0 - 1e-14),
            surely_outside: rc2 * (1.0 + 1e-14),
        }
    }

    /// The cutoff.
    pub fn cutoff(&self) -> f64 {
        self.cutoff
    }

    /// True when `sqrt(r2) < r_c`.
    #[inline(always)]
    pub fn accepts(&self, r2: f64) -> bool {
        r2 < self.surely_inside || (r2 < self.surely_outside && r2.sqrt() < self.cutoff)
    }
}

const BLOCK: usize = 64;

/// The per-block buffer of [`scan`], made once per home cell rather than per scan.
pub struct ScanScratch {
    r2s: [f64; BLOCK],
}

impl Default for ScanScratch {
    fn default() -> Self {
        ScanScratch { r2s: [0.0; BLOCK] }
    }
}

/// Visits the `candidates` (sorted slots `first..`) that lie within the cutoff of
/// `xi`, with `d = (x_j - x_i) + shift` (the shift is added only when `SHIFTED`, so
/// the unshifted loop is the plain difference). The separation is formed exactly as
/// the minimum image `d - L round(d / L)` of a brute-force search forms it, so both
/// agree to the last bit for particles inside the box.
///
/// The loop is branch-free: it computes `r^2` for a block of 64 candidates and a bit
/// mask of those not surely outside, then visits the set bits (with the exact test
/// near the cutoff), because about one candidate in six is a neighbour and a
/// data-dependent branch per candidate would be mispredicted.
#[inline(always)]
pub fn scan<const D: usize, const SHIFTED: bool>(
    scratch: &mut ScanScratch,
    xi: &[f64; D],
    columns: &[Vec<f64>; D],
    candidates: Range<usize>,
    shift: &[f64; D],
    test: &CutoffTest,
    mut visit: impl FnMut(usize, &[f64; D], f64),
) {
    let ScanScratch { r2s } = scratch;
    let mut start = candidates.start;
    while start < candidates.end {
        let len = (candidates.end - start).min(BLOCK);
        let r2s = &mut r2s[..len];
        // r^2 = (d_x^2 + d_y^2) + d_z^2 (as norm2 sums it), axis by axis: vectorisable
        for a in 0..D {
            let (x, s) = (xi[a], shift[a]);
            for (r2, &xj) in r2s.iter_mut().zip(&columns[a][start..start + len]) {
                let d = if SHIFTED { (xj - x) + s } else { xj - x };
                *r2 = if a == 0 { d * d } else { *r2 + d * d };
            }
        }
        let mut mask = 0u64;
        for (k, &r2) in r2s.iter().enumerate() {
            mask |= ((r2 < test.surely_outside) as u64) << k;
        }
        while mask != 0 {
            let k = mask.trailing_zeros() as usize;
            mask &= mask - 1;
            let j = start + k;
            let r2 = r2s[k];
            if test.accepts(r2) {
                let d: [f64; D] = std::array::from_fn(|a| {
                    let xj = columns[a][j];
                    if SHIFTED {
                        (xj - xi[a]) + shift[a]
                    } else {
                        xj - xi[a]
                    }
                });
                visit(j, &d, r2);
            }
        }
        start += len;
    }
}

/// For every particle `i` of cell `home`, in slot order, visits its neighbours `j`
/// within the cutoff as `visit(i, j, image, d, r2)` with `d = x_j + shift - x_i`.
///
/// With [`StencilKind::Half`] each pair is seen once over all home cells (inside the
/// home cell only `j > i`); with [`StencilKind::Full`] each particle sees all of its
/// neighbours. Neighbours come in stencil order, then slot order: a fixed order.
#[inline]
pub fn for_each_row_in_cell<const D: usize>(
    cells: &CellList<D>,
    home: usize,
    kind: StencilKind,
    test: &CutoffTest,
    mut visit: impl FnMut(usize, usize, u8, &[f64; D], f64),
) {
    let mut runs = [StencilRun::<D>::default(); 27];
    let n = cells.grid().stencil_runs(home, kind, &mut runs);
    let mut scratch = ScanScratch::default();
    for i in cells.cell_range(home) {
        for_each_in_row(
            cells,
            i,
            &runs[..n],
            kind,
            test,
            &mut scratch,
            |j, image, d, r2| visit(i, j, image, d, r2),
        );
    }
}

/// The row of slot `i` alone: its neighbours `j` within the cutoff over the
/// stencil `runs` of its cell (from [`CellGrid::stencil_runs`](super::CellGrid::stencil_runs)),
/// visited as `visit(j, image, d, r2)` in stencil order, then slot order.
#[inline]
pub fn for_each_in_row<const D: usize>(
    cells: &CellList<D>,
    i: usize,
    runs: &[StencilRun<D>],
    kind: StencilKind,
    test: &CutoffTest,
    scratch: &mut ScanScratch,
    mut visit: impl FnMut(usize, u8, &[f64; D], f64),
) {
    let xi = &cells.positions()[i];
    let cols = cells.columns();
    let start = cells.cell_start();
    for run in runs {
        let range = start[run.first_cell] as usize..start[run.last_cell + 1] as usize;
        let image = run.image;
        let mut hit = |j: usize, d: &[f64; D], r2: f64| visit(j, image, d, r2);
        if run.shifted {
            // only the periodic image of a tiny box can bring i next to itself,
            // and that image is at least 2 r_c away: no i == j check is needed
            scan::<D, true>(scratch, xi, cols, range, &run.shift, test, &mut hit);
        } else if run.holds_home {
            // the half stencil's home run starts at the home cell: j > i
            if kind == StencilKind::Full {
                scan::<D, false>(
                    scratch,
                    xi,
                    cols,
                    range.start..i,
                    &run.shift,
                    test,
                    &mut hit,
                );
            }
            scan::<D, false>(
                scratch,
                xi,
                cols,
                i + 1..range.end,
                &run.shift,
                test,
                &mut hit,
            );
        } else {
            scan::<D, false>(scratch, xi, cols, range, &run.shift, test, &mut hit);
        }
    }
}

/// Visits every pair owned by anchor cell `anchor` (see
/// [`CellGrid::anchored_pairs`](super::CellGrid::anchored_pairs)) as `visit(i, j, d, r2)`
/// with `d = x_j + shift - x_i`, `i != j`. All slots touched lie in the cells of the
/// block `anchor + {0, 1}^D`.
#[inline]
pub fn for_each_anchored_pair<const D: usize>(
    cells: &CellList<D>,
    anchor: usize,
    test: &CutoffTest,
    mut visit: impl FnMut(usize, usize, &[f64; D], f64),
) {
    let mut pairs = [AnchoredPair::<D>::default(); 14];
    let n = cells.grid().anchored_pairs(anchor, &mut pairs);
    let mut scratch = ScanScratch::default();
    let xs = cells.positions();
    let cols = cells.columns();
    for p in &pairs[..n] {
        let a = cells.cell_range(p.first);
        let b = cells.cell_range(p.second);
        for i in a {
            let xi = &xs[i];
            let mut hit = |j: usize, d: &[f64; D], r2: f64| visit(i, j, d, r2);
            if p.shifted {
                scan::<D, true>(&mut scratch, xi, cols, b.clone(), &p.shift, test, &mut hit);
            } else if p.first == p.second {
                scan::<D, false>(
                    &mut scratch,
                    xi,
                    cols,
                    i + 1..b.end,
                    &p.shift,
                    test,
                    &mut hit,
                );
            } else {
                scan::<D, false>(&mut scratch, xi, cols, b.clone(), &p.shift, test, &mut hit);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cutoff_test_is_exact_at_the_boundary() {
        let t = CutoffTest::new(2.5);
        assert!(t.accepts(6.25 * (1.0 - 1e-13)));
        assert!(!t.accepts(6.25));
        assert!(!t.accepts(6.25 * (1.0 + 1e-13)));
        // one ulp below rc^2: sqrt rounds to 2.5, so the pair is out
        let below = f64::from_bits(6.25f64.to_bits() - 1);
        assert_eq!(t.accepts(below), below.sqrt() < 2.5);
        // 0.1 is not representable: the test must agree with sqrt
        let t = CutoffTest::new(0.1);
        let rc2: f64 = 0.1 * 0.1;
        for k in -40i64..40 {
            let r2 = f64::from_bits(rc2.to_bits().wrapping_add_signed(k));
            assert_eq!(t.accepts(r2), r2.sqrt() < 0.1, "k = {k}");
        }
    }
}
