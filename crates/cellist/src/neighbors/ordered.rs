//! Neighbour rows for a domain-decomposed run: the particles a subdomain owns
//! (the first `owned` points) see every point, owned or ghost (copies of other
//! subdomains' particles and periodic images, shifted into place), within
//! `cutoff + skin`. Each row is a full list sorted by the neighbour's global
//! id, so that a sum over a row,
//!
//! ```text
//! s_i = sum_{j in row(i), ascending id_j} t(i, j),
//! ```
//!
//! runs in an order fixed by the data: not by how the box is cut, where the
//! ghosts come from, or the thread count. Each pair is in both particles' rows
//! (no Newton's third law across subdomain faces: nothing travels back to a
//! ghost's owner).

use super::verlet::moved_beyond_half_skin;
use super::{for_each_in_row, CellList, CutoffTest, ScanScratch, StencilKind, StencilRun};
use crate::geometry::{Domain, GeometryError};
use crate::threads::Threads;
use rayon::prelude::*;
use std::ops::Range;

/// The full, id-sorted neighbour rows of the owned particles, and their
/// positions at the build (the reference of the skin/2 test).
#[derive(Clone, Debug, Default)]
pub struct OrderedRows<const D: usize> {
    /// Row `i` is `neighbors[spans[i].0..spans[i].1]`.
    spans: Vec<(usize, usize)>,
    neighbors: Vec<u32>,
    reference: Vec<[f64; D]>,
    skin: f64,
}

/// Owned particles handled by one task of the row sums.
const CHUNK: usize = 1024;

/// The rows one task of the build found: for each owned particle of its
/// cells, its index and its neighbours (sorted).
#[derive(Default)]
struct ChunkRows {
    owned: Vec<u32>,
    lengths: Vec<u32>,
    neighbors: Vec<u32>,
}

impl<const D: usize> OrderedRows<D> {
    /// The rows of the first `owned` of `points` over all of `points` within
    /// `cutoff + skin` (open space: ghosts carry their periodic shifts), each
    /// sorted by `(ids[j], j)`: the points are ranked in that order once,
    /// binned in a cell list in rank order, and each owned point's row is found
    /// from its cell's stencil and sorted by rank.
    pub fn build(
        points: &[[f64; D]],
        owned: usize,
        ids: &[u64],
        cutoff: f64,
        skin: f64,
        threads: &Threads,
    ) -> Result<Self, GeometryError> {
        assert!(owned <= points.len() && ids.len() == points.len());
        assert!(points.len() < u32::MAX as usize, "at most 2^32 - 1 points");
        let mut rows = OrderedRows {
            reference: points[..owned].to_vec(),
            skin,
            spans: vec![(0, 0); owned],
            ..OrderedRows::default()
        };
        if owned == 0 {
            return Ok(rows);
        }
        // bin the points in id order: a row's entries are then the points' ranks
        let mut by_rank: Vec<u32> = (0..points.len() as u32).collect();
        by_rank.sort_unstable_by_key(|&k| (ids[k as usize], k));
        let ranked: Vec<[f64; D]> = by_rank.iter().map(|&k| points[k as usize]).collect();
        let reach = cutoff + skin;
        let cells = CellList::build_in(&Domain::open_around(&ranked), reach, &ranked, threads)?;
        let test = CutoffTest::new(reach);
        let order = cells.order();
        let grid = cells.grid();
        let chunks: Vec<ChunkRows> = threads.install(|| {
            Threads::chunks(grid.num_cells())
                .map(|range| {
                    let mut chunk = ChunkRows::default();
                    let mut runs = [StencilRun::<D>::default(); 27];
                    let mut scratch = ScanScratch::default();
                    for home in range {
                        let mut n = None;
                        for i in cells.cell_range(home) {
                            let own = by_rank[order[i] as usize];
                            if own as usize >= owned {
                                continue;
                            }
                            let n = *n.get_or_insert_with(|| {
                                grid.stencil_runs(home, StencilKind::Full, &mut runs)
                            });
                            let first = chunk.neighbors.len();
                            let row = &mut chunk.neighbors;
                            for_each_in_row(
                                &cells,
                                i,
                                &runs[..n],
                                StencilKind::Full,
                                &test,
                                &mut scratch,
                                |j, _, _, _| row.push(order[j]),
                            );
                            let row = &mut chunk.neighbors[first..];
                            row.sort_unstable();
                            for r in row.iter_mut() {
                                *r = by_rank[*r as usize];
                            }
                            chunk.owned.push(own);
                            chunk.lengths.push(row.len() as u32);
                        }
                    }
                    chunk
                })
                .collect()
        });
        rows.neighbors
            .reserve(chunks.iter().map(|c| c.neighbors.len()).sum());
        for chunk in &chunks {
            let mut at = rows.neighbors.len();
            rows.neighbors.extend_from_slice(&chunk.neighbors);
            for (&i, &length) in chunk.owned.iter().zip(&chunk.lengths) {
                rows.spans[i as usize] = (at, at + length as usize);
                at += length as usize;
            }
        }
        Ok(rows)
    }

    /// Number of rows (owned particles).
    pub fn len(&self) -> usize {
        self.spans.len()
    }

    /// True without rows.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Total entries of the rows.
    pub fn num_entries(&self) -> usize {
        self.neighbors.len()
    }

    /// Row `i`: the neighbours (indices into the build's points), sorted by id.
    #[inline]
    pub fn row(&self, i: usize) -> &[u32] {
        &self.neighbors[self.entries(i)]
    }

    /// The entry numbers of row `i` (for per-entry data such as fixed weights).
    #[inline]
    pub fn entries(&self, i: usize) -> Range<usize> {
        self.spans[i].0..self.spans[i].1
    }

    /// The owned positions at the build.
    pub fn reference(&self) -> &[[f64; D]] {
        &self.reference
    }

    /// The first owned particle that shares its position with a neighbour, as
    /// the pair of ids `(smaller, larger)`.
    pub fn coincident(&self, points: &[[f64; D]], ids: &[u64]) -> Option<(u64, u64)> {
        (0..self.len()).find_map(|i| {
            let j = *self
                .row(i)
                .iter()
                .find(|&&j| points[j as usize] == points[i])? as usize;
            Some((ids[i].min(ids[j]), ids[i].max(ids[j])))
        })
    }

    /// True when an owned particle has moved more than `skin / 2` since the
    /// build, `max_i |x_i - x_i^build| > skin / 2` (`owned` in the build's order).
    pub fn needs_rebuild(&self, owned: &[[f64; D]]) -> bool {
        moved_beyond_half_skin(owned, &self.reference, self.skin)
    }

    /// `out[i] = row_value(i)` for every owned particle, in parallel; each value
    /// computed by one task, so the result does not depend on the thread count.
    pub fn map<T: Send>(
        &self,
        out: &mut [T],
        threads: &Threads,
        row_value: impl Fn(usize) -> T + Sync,
    ) {
        assert_eq!(out.len(), self.len());
        threads.install(|| {
            out.par_chunks_mut(CHUNK).enumerate().for_each(|(c, o)| {
                for (k, v) in o.iter_mut().enumerate() {
                    *v = row_value(c * CHUNK + k);
                }
            })
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::norm2;
    use crate::random::Rng;

    /// The rows hold exactly the points within cutoff + skin, sorted by id, for
    /// any thread count and any order of the points.
    #[test]
    fn rows_are_the_neighbours_within_reach_sorted_by_id() {
        let mut rng = Rng::new(11);
        let n = 300;
        let points: Vec<[f64; 3]> = (0..n)
            .map(|_| std::array::from_fn(|_| 6.0 * rng.uniform()))
            .collect();
        let ids: Vec<u64> = (0..n as u64).map(|k| (k * 7919) % 1009).collect();
        let owned = 200;
        for t in [1, 2] {
            let threads = Threads::new(t).unwrap();
            let rows = OrderedRows::build(&points, owned, &ids, 1.0, 0.3, &threads).unwrap();
            for i in 0..owned {
                let mut brute: Vec<u32> = (0..n)
                    .filter(|&j| {
                        let d: [f64; 3] = std::array::from_fn(|a| points[i][a] - points[j][a]);
                        j != i && norm2(&d).sqrt() < 1.3
                    })
                    .map(|j| j as u32)
                    .collect();
                brute.sort_by_key(|&j| ids[j as usize]);
                assert_eq!(rows.row(i), &brute[..], "row {i}");
            }
            assert_eq!(rows.coincident(&points, &ids), None);
        }
    }

    #[test]
    fn two_points_at_one_position_are_found() {
        let points = vec![[0.0, 0.0], [1.0, 1.0], [0.0, 0.0]];
        let rows = OrderedRows::build(&points, 1, &[5, 6, 9], 2.5, 0.3, &Threads::new(1).unwrap())
            .unwrap();
        assert_eq!(rows.coincident(&points, &[5, 6, 9]), Some((5, 9)));
    }
}
