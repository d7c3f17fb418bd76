//! The discs of one table and its step: move every disc, find the candidates on
//! the contact grid, then resolve them component by component in parallel.

use super::components::Components;
use super::contacts::{CellShape, ContactGrid};
use super::error::BilliardsError;
use super::rules::{Separation, Table, Walls};
use crate::threads::{
    collect_in_order_into, map_parts, part_ranges, parts_for, DisjointSlice, Threads,
};

/// What one step did: candidates found and sweeps of the canonical loop.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct StepStats {
    /// Discs overlapping a wall.
    pub wall_discs: usize,
    /// Overlapping pairs.
    pub pairs: usize,
    /// Sweeps the global canonical loop would make, the last one changing nothing:
    /// the largest over the components, at least 1.
    pub sweeps: u64,
}

/// The discs in vector (file) order, structure of arrays, and the buffers of a step.
#[derive(Clone, Debug)]
pub struct Billiards {
    table: Table,
    /// x of each disc.
    pub x: Vec<f64>,
    /// y of each disc.
    pub y: Vec<f64>,
    /// vx, vy of each disc.
    pub v: Vec<[f64; 2]>,
    max_sweeps: u64,
    grid: ContactGrid,
    walls: Vec<(u32, Walls)>,
    components: Components,
}

/// Default bound on the sweeps of one step (the reference stops at 10^7; the
/// hardest public input needs 120).
pub const DEFAULT_MAX_SWEEPS: u64 = 1_000_000;

impl Billiards {
    /// A table with discs at `x`, `y` moving with `v` (finite values).
    pub fn new(
        table: Table,
        x: Vec<f64>,
        y: Vec<f64>,
        v: Vec<[f64; 2]>,
    ) -> Result<Self, BilliardsError> {
        if table.radius <= 0 || table.side <= 0 {
            return Err(BilliardsError::Table(format!(
                "the radius ({}) and the side ({}) must be positive",
                table.radius, table.side
            )));
        }
        if table.radius > 1 << 30 {
            return Err(BilliardsError::Table(format!(
                "the radius {} is too large for (2r)^2 in integers",
                table.radius
            )));
        }
        if x.len() != y.len() || x.len() != v.len() {
            return Err(BilliardsError::State("x, y and v differ in length".into()));
        }
        let finite =
            |k: usize| x[k].is_finite() && y[k].is_finite() && v[k].iter().all(|c| c.is_finite());
        if let Some(k) = (0..x.len()).find(|&k| !finite(k)) {
            return Err(BilliardsError::State(format!(
                "particle at vector position {k} has a non-finite position or velocity"
            )));
        }
        Ok(Billiards {
            table,
            x,
            y,
            v,
            max_sweeps: DEFAULT_MAX_SWEEPS,
            grid: table.grid(),
            walls: Vec::new(),
            components: Components::default(),
        })
    }

    /// Sets the bound on sweeps per step (at least 1).
    pub fn with_max_sweeps(mut self, sweeps: u64) -> Self {
        self.max_sweeps = sweeps.max(1);
        self
    }

    /// Lays out the cells of the contact search as `shape` ([`CellShape::Square`]
    /// by default, or seed 001's hexagonal bricks). Every step gives the same bits
    /// either way; only the time changes.
    pub fn with_cells(mut self, shape: CellShape) -> Self {
        self.grid = std::mem::take(&mut self.grid).with_cells(shape);
        self
    }

    /// The layout of the cells of the contact search.
    pub fn cells(&self) -> CellShape {
        self.grid.cells()
    }

    /// The box and radius.
    pub fn table(&self) -> &Table {
        &self.table
    }

    /// Number of discs.
    pub fn len(&self) -> usize {
        self.x.len()
    }

    /// True without discs.
    pub fn is_empty(&self) -> bool {
        self.x.is_empty()
    }

    /// Energy `sum (vx^2 + vy^2)` (no 1/2, as the benchmark defines it).
    pub fn energy(&self) -> f64 {
        self.v.iter().map(|v| v[0] * v[0] + v[1] * v[1]).sum()
    }

    /// Step `step`: move, then resolve over the candidates, component by component
    /// in parallel. The whole step runs on the pool, so that its parallel passes
    /// start there rather than being handed over from the calling thread one by
    /// one.
    pub fn step(&mut self, step: u64, threads: &Threads) -> Result<StepStats, BilliardsError> {
        threads.install(|| {
            self.advance(step, Some(threads))?;
            let table = self.table;
            self.grid.search(&self.x, &self.y, table.contact(), threads);
            // the walls by slot of the grid's spatial order, as the pairs
            let (x, y) = self.grid.slot_positions();
            let parts = part_ranges(x.len(), threads.count());
            let sizes: Vec<usize> = parts.iter().map(|part| part.len()).collect();
            collect_in_order_into(&mut self.walls, &sizes, threads, |p, out| {
                for k in parts[p].clone() {
                    let walls = table.walls_at(x[k], y[k]);
                    out.push_if((k as u32, walls), walls.any());
                }
            });
            let number = self.grid.nearby_order();
            self.components
                .group(self.grid.found(), &self.walls, number, threads);
            let sweeps = self
                .components
                .resolve(&mut self.v, self.max_sweeps, threads)
                .map_err(|(first, size)| BilliardsError::NotConverged {
                    step,
                    sweeps: self.max_sweeps,
                    first,
                    size,
                })?;
            Ok(StepStats {
                wall_discs: self.walls.len(),
                pairs: self.grid.found().iter().map(Vec::len).sum(),
                sweeps,
            })
        })
    }

    /// The same step by the literal loops of SPEC.md section 4: every disc in the
    /// wall pass, every pair `a < b` in the pair pass, O(N^2) per sweep. The
    /// reference the fast step is tested against.
    pub fn step_brute(&mut self, step: u64) -> Result<StepStats, BilliardsError> {
        self.advance(step, None)?;
        let n = self.len();
        let table = self.table;
        let contact = table.contact();
        let walls: Vec<Walls> = (0..n)
            .map(|k| table.walls_at(self.x[k], self.y[k]))
            .collect();
        let mut sweeps = 0;
        let mut pairs = 0;
        loop {
            sweeps += 1;
            if sweeps > self.max_sweeps {
                return Err(BilliardsError::NotConverged {
                    step,
                    sweeps: self.max_sweeps,
                    first: 0,
                    size: n,
                });
            }
            let mut changed = false;
            for (k, w) in walls.iter().enumerate() {
                if w.collides(&self.v[k]) {
                    w.resolve(&mut self.v[k]);
                    changed = true;
                }
            }
            for a in 0..n {
                for b in a + 1..n {
                    let sep = Separation::between([self.x[a], self.y[a]], [self.x[b], self.y[b]]);
                    if sep.q <= contact {
                        pairs += usize::from(sweeps == 1);
                        let (head, tail) = self.v.split_at_mut(b);
                        changed |= sep.collide(&mut head[a], &mut tail[0]);
                    }
                }
            }
            if !changed {
                break;
            }
        }
        Ok(StepStats {
            wall_discs: walls.iter().filter(|w| w.any()).count(),
            pairs,
            sweeps,
        })
    }

    /// Phase I: `x <- x + vx`, `y <- y + vy`, in parts on `threads` (in this
    /// thread without them); the first disc (by vector position) that left the
    /// finite numbers is reported.
    fn advance(&mut self, step: u64, threads: Option<&Threads>) -> Result<(), BilliardsError> {
        let parts = part_ranges(self.len(), parts_for(threads));
        let (xs, ys) = (
            DisjointSlice::new(&mut self.x),
            DisjointSlice::new(&mut self.y),
        );
        let v = &self.v;
        let first_bad = map_parts(threads, parts.len(), |p| {
            let range = parts[p].clone();
            // SAFETY: the parts' ranges are disjoint
            let (x, y) = unsafe { (xs.range(range.clone()), ys.range(range.clone())) };
            for ((x, y), v) in x.iter_mut().zip(y.iter_mut()).zip(&v[range.clone()]) {
                *x += v[0];
                *y += v[1];
            }
            let finite = |(x, y): (&f64, &f64)| x.is_finite() && y.is_finite();
            x.iter()
                .zip(y.iter())
                .position(|p| !finite(p))
                .map(|k| range.start + k)
        });
        match first_bad.into_iter().flatten().next() {
            Some(index) => Err(BilliardsError::Overflow { step, index }),
            None => Ok(()),
        }
    }
}
