//! Candidate search for the collision benchmark: every pair `a < b` (vector
//! positions) with `q = (dx dx) + (dy dy) <= limit`, in lexicographic order, found on
//! a grid of squares (seed 001's binning). The grid only proposes candidates; the
//! exact predicate decides, so the result equals the literal all-pairs loop
//! (SPEC.md section 4, E1). Discs may be anywhere, also far outside the box: the
//! grid spans their bounding box.

use super::rules::Separation;
use crate::threads::Threads;
use rayon::prelude::*;

/// One overlapping pair: vector positions `a < b` and their frozen separation.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Contact {
    /// The first disc (role "1").
    pub a: u32,
    /// The second disc (role "2").
    pub b: u32,
    /// `x_b - x_a`, `y_b - y_a`, `q`.
    pub sep: Separation,
}

/// A grid of squares over the discs' bounding box, with the discs sorted by square
/// (counting sort), and its buffers kept between searches.
#[derive(Clone, Debug, Default)]
pub struct ContactGrid {
    region: Option<([f64; 2], [f64; 2])>,
    origin: [f64; 2],
    side: f64,
    dims: [usize; 2],
    square_of: Vec<u32>,
    start: Vec<u32>,
    cursor: Vec<u32>,
    sorted: Vec<u32>,
    sorted_x: Vec<f64>,
    sorted_y: Vec<f64>,
    rows: Vec<Vec<Contact>>,
    offsets: Vec<u32>,
}

impl ContactGrid {
    /// Replaces `out` by all pairs `a < b` with `q <= limit`, sorted by `(a, b)`.
    /// Positions must be finite. The order does not depend on the thread count.
    pub fn find(
        &mut self,
        x: &[f64],
        y: &[f64],
        limit: f64,
        threads: &Threads,
        out: &mut Vec<Contact>,
    ) {
        assert_eq!(x.len(), y.len());
        out.clear();
        let n = x.len();
        if limit.is_nan() || limit < 0.0 {
            return;
        }
        self.bin(x, y, limit);
        if n < 2 {
            return;
        }
        // search square by square (neighbouring discs are close in memory), each
        // disc's pairs together and sorted by b
        let ranges = Threads::chunks(self.dims[0] * self.dims[1]);
        let mut rows = std::mem::take(&mut self.rows);
        rows.resize_with(ranges.len(), Vec::new);
        let grid = &*self;
        threads.install(|| {
            ranges
                .zip(rows.par_iter_mut())
                .for_each(|(squares, found)| {
                    found.clear();
                    for square in squares {
                        grid.contacts_in(square, limit, found);
                    }
                });
        });
        // then place the pairs row by row in the order of a, each row sorted by b
        self.offsets.clear();
        self.offsets.resize(n + 1, 0);
        for c in rows.iter().flatten() {
            self.offsets[c.a as usize + 1] += 1;
        }
        for a in 0..n {
            self.offsets[a + 1] += self.offsets[a];
        }
        out.resize(self.offsets[n] as usize, Contact::default());
        self.cursor.clear();
        self.cursor.extend_from_slice(&self.offsets[..n]);
        for c in rows.iter().flatten() {
            out[self.cursor[c.a as usize] as usize] = *c;
            self.cursor[c.a as usize] += 1;
        }
        for a in 0..n {
            let row = &mut out[self.offsets[a] as usize..self.offsets[a + 1] as usize];
            // a handful per disc: insertion sort by b
            for k in 1..row.len() {
                let mut j = k;
                while j > 0 && row[j - 1].b > row[j].b {
                    row.swap(j - 1, j);
                    j -= 1;
                }
            }
        }
        self.rows = rows;
    }

    /// Limits the squares to the region `[lo, hi]` (they span the discs' bounding
    /// box otherwise); discs outside it go to its border squares. The pairs found
    /// are the same; only the time changes.
    pub fn with_region(mut self, lo: [f64; 2], hi: [f64; 2]) -> Self {
        self.region = Some((lo, hi));
        self
    }

    /// All discs, square by square (neighbours close together), as of the last
    /// [`ContactGrid::find`].
    pub fn nearby_order(&self) -> &[u32] {
        &self.sorted
    }

    /// Sizes the squares (side just above `sqrt(limit)`, so that a pair within the
    /// limit is never two squares apart, and no more squares than about 4 per disc)
    /// and sorts the discs by square.
    fn bin(&mut self, x: &[f64], y: &[f64], limit: f64) {
        let n = x.len();
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for (&px, &py) in x.iter().zip(y) {
            lo = [lo[0].min(px), lo[1].min(py)];
            hi = [hi[0].max(px), hi[1].max(py)];
        }
        if let Some((region_lo, region_hi)) = self.region {
            // discs beyond the region share its border squares: clamping keeps
            // neighbours in neighbouring squares, and a few outliers cannot
            // stretch the squares over everything else
            for a in 0..2 {
                lo[a] = lo[a].max(region_lo[a]).min(region_hi[a]);
                hi[a] = hi[a].min(region_hi[a]).max(lo[a]);
            }
        }
        let extent = (hi[0] - lo[0]).max(hi[1] - lo[1]);
        let max_per_axis = ((4 * n) as f64).sqrt().ceil().max(1.0);
        let side = (limit.sqrt() * (1.0 + 1e-6))
            .max(extent / max_per_axis)
            .max(f64::MIN_POSITIVE);
        let dims = [0, 1].map(|a| (((hi[a] - lo[a]) / side) as usize + 1).max(1));
        self.origin = lo;
        self.side = side;
        self.dims = dims;
        let mut square_of = std::mem::take(&mut self.square_of);
        square_of.clear();
        square_of.extend(
            x.iter()
                .zip(y)
                .map(|(&px, &py)| self.square_at(px, py) as u32),
        );
        self.square_of = square_of;
        let squares = dims[0] * dims[1];
        self.start.clear();
        self.start.resize(squares + 1, 0);
        for &s in &self.square_of {
            self.start[s as usize + 1] += 1;
        }
        for s in 0..squares {
            self.start[s + 1] += self.start[s];
        }
        self.sorted.clear();
        self.sorted.resize(n, 0);
        self.cursor.clear();
        self.cursor.extend_from_slice(&self.start[..squares]);
        for (k, &s) in self.square_of.iter().enumerate() {
            self.sorted[self.cursor[s as usize] as usize] = k as u32;
            self.cursor[s as usize] += 1;
        }
        self.sorted_x.clear();
        self.sorted_x
            .extend(self.sorted.iter().map(|&k| x[k as usize]));
        self.sorted_y.clear();
        self.sorted_y
            .extend(self.sorted.iter().map(|&k| y[k as usize]));
    }

    fn square_at(&self, x: f64, y: f64) -> usize {
        let cx = (((x - self.origin[0]) / self.side) as usize).min(self.dims[0] - 1);
        let cy = (((y - self.origin[1]) / self.side) as usize).min(self.dims[1] - 1);
        cy * self.dims[0] + cx
    }

    /// Appends the pairs within the limit that the discs of `square` form with the
    /// discs after them in the square, in the square to the right and in the three
    /// squares above (half of the 3 x 3 block: every pair of neighbouring squares
    /// is seen once), as `(min, max)` with the separation of `max` from `min`. The
    /// rest of the square and the one to its right are consecutive in square
    /// order, and so are the three above: two runs per disc.
    fn contacts_in(&self, square: usize, limit: f64, found: &mut Vec<Contact>) {
        let members = self.start[square] as usize..self.start[square + 1] as usize;
        if members.is_empty() {
            return;
        }
        let [columns, rows] = self.dims;
        let (cx, cy) = (square % columns, square / columns);
        let right_end = self.start[square + 1 + usize::from(cx + 1 < columns)] as usize;
        let above = if cy + 1 < rows {
            let row = (cy + 1) * columns;
            let (x0, x1) = (cx.saturating_sub(1), (cx + 1).min(columns - 1));
            self.start[row + x0] as usize..self.start[row + x1 + 1] as usize
        } else {
            0..0
        };
        for slot in members {
            let a = self.sorted[slot];
            let pa = [self.sorted_x[slot], self.sorted_y[slot]];
            for run in [slot + 1..right_end, above.clone()] {
                for m in run {
                    let pb = [self.sorted_x[m], self.sorted_y[m]];
                    let sep = Separation::between(pa, pb);
                    if sep.q <= limit {
                        let b = self.sorted[m];
                        // the roles by vector position: the separation of max from
                        // min, computed in that order (negating would turn +0.0
                        // into -0.0)
                        found.push(if a < b {
                            Contact { a, b, sep }
                        } else {
                            Contact {
                                a: b,
                                b: a,
                                sep: Separation::between(pb, pa),
                            }
                        });
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::random::Rng;

    fn brute(x: &[f64], y: &[f64], limit: f64) -> Vec<Contact> {
        let mut out = Vec::new();
        for a in 0..x.len() {
            for b in a + 1..x.len() {
                let sep = Separation::between([x[a], y[a]], [x[b], y[b]]);
                if sep.q <= limit {
                    out.push(Contact {
                        a: a as u32,
                        b: b as u32,
                        sep,
                    });
                }
            }
        }
        out
    }

    #[test]
    fn the_grid_finds_exactly_the_brute_force_pairs() {
        let mut rng = Rng::new(7);
        let mut grid = ContactGrid::default();
        for (n, spread, limit) in [
            (300usize, 40.0f64, 4.0f64),
            (500, 20.0, 9.0),
            (50, 1e6, 4.0),
            (3, 1.0, 0.0),
        ] {
            let mut x: Vec<f64> = (0..n).map(|_| rng.uniform() * spread).collect();
            let y: Vec<f64> = (0..n).map(|_| rng.uniform() * spread).collect();
            // a few far outside the box, and touching pairs exactly at the limit
            x[0] = -5e5;
            x[1] = x[2] + f64::sqrt(limit);
            let expected = brute(&x, &y, limit);
            let mut clamped =
                ContactGrid::default().with_region([0.0, 0.0], [spread / 2.0, spread / 2.0]);
            for threads in [Threads::single(), Threads::new(2).unwrap()] {
                let mut found = Vec::new();
                grid.find(&x, &y, limit, &threads, &mut found);
                assert_eq!(found, expected, "n {n}");
                clamped.find(&x, &y, limit, &threads, &mut found);
                assert_eq!(found, expected, "n {n}, squares over half the spread");
            }
        }
    }
}
