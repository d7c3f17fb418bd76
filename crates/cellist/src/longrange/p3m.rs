//! P3M (particle-particle particle-mesh, TreePM-style split): the mesh carries the
//! long-range part of gravity, `phi_L(r) = -G erf(s / (2 r_s)) / s`, and a cell
//! list sums the rest exactly for the pairs with `s < r_cut = CUT r_s`:
//!
//! `phi_i = phi_L,mesh(x_i) + sum_{j: s_ij < r_cut} m_j (phi(r_ij) - phi_L(r_ij))`,
//! `acc_i = acc_L,mesh(x_i) + sum_{j: s_ij < r_cut} m_j (k(r_ij) - k_L(r_ij)) (x_j - x_i)`,
//!
//! with `(phi, k)` the softened law, `(phi_L, k_L)` the long-range kernel
//! (tabulated in `s^2`) and `s^2 = r^2 + eps^2` for isolated boundaries: the
//! short-range term is then `-G erfc(s / (2 r_s)) / s`, and the mesh carries the
//! Plummer law's whole tail. Periodic boundaries take `s = r` in the split (the
//! Fourier-space Green's function is unsoftened), so pairs beyond `r_cut`
//! interact as Newtonian, off the softened law by `3 eps^2 / (2 r^2)`. The mesh's Green's function is divided by the
//! cloud-in-cell window `W(k)^2` and the mesh is interlaced, so that the mesh pair
//! force follows the erf kernel to within about 0.5 % at every separation for
//! `r_s = 1.25 h`. `r_cut = 5.5 r_s` (GADGET uses 4.5): beyond it the dropped
//! short-range force is the fraction `erfc(x) + 2x/sqrt(pi) exp(-x^2)`,
//! `x = r_cut / (2 r_s) = 2.75`, of the Newtonian one, 0.17 % (1.75 % at 4.5).
//!
//! Periodic boxes use minimum images in the pair sum and, for `phi`, the mesh
//! convention of [`super::ParticleMesh`].

use super::mesh::green::{long_pair, Reach};
use super::mesh::route::{Arrived, Place, Route};
use super::mesh::{Alone, Exchange, MeshBoundary, MeshParams, MeshSolver, Rank};
use super::{FieldOut, Sources};
use crate::interactions::GravityLaw;
use crate::simd::{axes, F64x4};
use crate::threads::Threads;
use rayon::prelude::*;
use std::ops::Range;

/// `r_cut / r_s`.
pub const CUT: f64 = 5.5;

/// The default splitting radius in mesh cells, `r_s / h`.
pub const SPLIT_CELLS: f64 = 1.25;

/// Table intervals of the long-range kernel.
const TABLE: usize = 8192;

/// The long-range pair kernel as functions of `u = r^2 / (4 r_s^2)` on
/// `[0, CUT^2 / 4]`, linearly interpolated (relative error below `1e-7`):
/// `F_k(u) = (erf(sqrt u) - 2 sqrt(u / pi) exp(-u)) / u^(3/2)` and
/// `F_phi(u) = erf(sqrt u) / sqrt u`, so that `k_L = G F_k / (8 r_s^3)` and
/// `phi_L = -G F_phi / (2 r_s)`.
struct LongTable {
    /// Intervals per unit of `u`.
    density: f64,
    /// `[F_k, F_phi]` at `u = i / density`.
    values: Vec<[f64; 2]>,
}

impl LongTable {
    fn new() -> Self {
        let density = TABLE as f64 / (CUT * CUT / 4.0);
        let values = (0..TABLE + 2)
            .map(|i| {
                // r_s = 1/2: u = r^2
                let (phi, k) = long_pair(1.0, 0.5, (i as f64 / density).sqrt());
                [k, -phi]
            })
            .collect();
        LongTable { density, values }
    }

    /// [`LongTable::at`] on four lanes, `u` clamped to the table's end.
    #[inline(always)]
    fn at4(&self, u: F64x4) -> [F64x4; 2] {
        let t = (u.min(F64x4::splat(CUT * CUT / 4.0)) * F64x4::splat(self.density)).to_array();
        let mut lo = [[0.0; 4]; 2];
        let mut step = [[0.0; 4]; 2];
        let mut frac = [0.0; 4];
        for l in 0..4 {
            let i = t[l] as usize;
            frac[l] = t[l] - i as f64;
            let (a, b) = (self.values[i], self.values[i + 1]);
            for k in 0..2 {
                lo[k][l] = a[k];
                step[k][l] = b[k] - a[k];
            }
        }
        let frac = F64x4::load(&frac);
        [0, 1].map(|k| frac.mul_add(F64x4::load(&step[k]), F64x4::load(&lo[k])))
    }

    /// `[F_k(u), F_phi(u)]` for `0 <= u <= CUT^2 / 4`.
    #[inline(always)]
    fn at(&self, u: f64) -> [f64; 2] {
        let t = u * self.density;
        let i = t as usize;
        let f = t - i as f64;
        let (a, b) = (self.values[i], self.values[i + 1]);
        [a[0] + f * (b[0] - a[0]), a[1] + f * (b[1] - a[1])]
    }
}

/// Short-range cells per `r_cut`: cells of side `>= r_cut / REACH`, each particle
/// visiting the `(2 REACH + 1)^3` around its own.
const REACH: usize = 2;

/// Particles per parallel task of the short-range sum.
const CHUNK: usize = 64;

/// A box cut into cells: cells per axis, the cell side, the lower corner.
#[derive(Clone, Copy, Debug, Default)]
struct Grid {
    count: [usize; 3],
    side: [f64; 3],
    lo: [f64; 3],
}

impl Grid {
    /// The cell coordinates of a (wrapped) position.
    fn coords(&self, x: &[f64; 3]) -> [usize; 3] {
        std::array::from_fn(|a| {
            let u = ((x[a] - self.lo[a]) / self.side[a]).floor().max(0.0) as usize;
            u.min(self.count[a] - 1)
        })
    }

    /// The cells within [`REACH`] of cell `c` along axis `a`, as at most two runs
    /// of consecutive cells (the second empty unless a periodic span wraps; every
    /// cell once when the periodic axis has fewer than `2 REACH + 1`).
    fn span(&self, c: usize, periodic: bool, a: usize) -> [Range<usize>; 2] {
        let n = self.count[a] as isize;
        let (lo, hi) = (c as isize - REACH as isize, c as isize + REACH as isize + 1);
        let run = |lo: isize, hi: isize| lo as usize..hi as usize;
        if !periodic {
            [run(lo.max(0), hi.min(n)), 0..0]
        } else if n < 2 * REACH as isize + 1 {
            [run(0, n), 0..0]
        } else if lo < 0 {
            [run(0, hi), run(n + lo, n)]
        } else if hi > n {
            [run(lo, n), run(0, hi - n)]
        } else {
            [run(lo, hi), 0..0]
        }
    }

    /// The row-major index of cell coordinates `c`.
    fn index(&self, c: [usize; 3]) -> usize {
        (c[0] * self.count[1] + c[1]) * self.count[2] + c[2]
    }
}

/// The short-range cell list: particles counting-sorted by cell, as structure of
/// arrays.
#[derive(Default)]
struct Cells {
    grid: Grid,
    /// `start[c]..start[c + 1]`: the sorted particles of cell `c`.
    start: Vec<usize>,
    cell_of: Vec<usize>,
    /// Sorted slot of each input particle.
    slot: Vec<usize>,
    x: [Vec<f64>; 3],
    m: Vec<f64>,
    /// `(acc, phi)` of each sorted particle.
    sum: Vec<[f64; 4]>,
}

/// The P3M solver: [`super::ParticleMesh`]'s machinery for the long range and
/// an exact pair sum within `r_cut` for the short range.
pub struct P3m {
    mesh: MeshSolver,
    split: f64,
    table: LongTable,
    cells: Cells,
    /// The short-range `(acc, phi)` of each own particle.
    short: Vec<[f64; 4]>,
    /// On several ranks: the particles routed here for the short range, and
    /// the routing's buffers.
    arrived: Arrived<1>,
    route: Route<1>,
}

impl std::fmt::Debug for P3m {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        self.mesh.describe(f, "P3m")
    }
}

impl P3m {
    /// The solver for `law` with `params` and splitting radius
    /// `r_s = split_cells h` (default [`SPLIT_CELLS`]). Refuses what
    /// [`super::ParticleMesh::new`] refuses, `split_cells` below 0.5 (the mesh
    /// cannot carry a narrower Gaussian) or not finite, and a periodic box
    /// narrower than `2 r_cut`.
    pub fn new(law: GravityLaw, params: MeshParams, split_cells: f64) -> Result<Self, String> {
        Self::on_rank(law, params, split_cells, Rank::ALONE)
    }

    /// The solver on `rank`'s slab of a mesh shared by several ranks, each of
    /// which holds its own part of the particles ([`P3m::compute_spread`]);
    /// refuses what [`P3m::new`] refuses and more ranks than the grid has planes.
    pub fn on_rank(
        law: GravityLaw,
        params: MeshParams,
        split_cells: f64,
        rank: Rank,
    ) -> Result<Self, String> {
        if !(split_cells.is_finite() && split_cells >= 0.5) {
            return Err(format!(
                "split_cells must be finite and >= 0.5 (r_s of at least half a mesh \
                 cell), got {split_cells}"
            ));
        }
        let mesh = MeshSolver::new(law, params, Reach::Long { cells: split_cells }, rank)?;
        if let MeshBoundary::Periodic { .. } = params.boundary {
            let cut = CUT * split_cells;
            if 2.0 * cut > params.grid as f64 {
                return Err(format!(
                    "split_cells {split_cells}: the cut {CUT} r_s = {cut} cells must be at \
                     most half the grid ({})",
                    params.grid
                ));
            }
        }
        // an isolated mesh spans at most grid - 3 cells, so the cell list has at
        // most REACH (grid - 3) / (CUT split_cells) + 1 cells per axis
        let per_axis = (REACH as f64 * params.grid as f64 / (CUT * split_cells)) as usize + 1;
        let mut cells = Cells::default();
        cells.start.reserve(per_axis.pow(3) + 1);
        Ok(P3m {
            mesh,
            split: split_cells,
            table: LongTable::new(),
            cells,
            short: Vec::new(),
            arrived: Arrived::default(),
            route: Route::default(),
        })
    }

    /// The mesh cell `h` of the last evaluation (isolated) or of the box (periodic).
    pub fn cell(&self) -> f64 {
        self.mesh.cell()
    }

    /// Fills `out` with the P3M accelerations and potentials of `sources`.
    pub fn compute(&mut self, sources: &Sources, out: FieldOut, threads: &Threads) {
        self.compute_spread(sources, out, threads, &Alone);
    }

    /// [`P3m::compute`] on the ranks of `exchange`, the particles divided
    /// among them: every rank calls it with its own part of them (`sources`),
    /// the parts following each other in rank order, and gets its own
    /// particles' results in `out`. The mesh as
    /// [`super::ParticleMesh::compute_spread`]; the short range by runs of
    /// the cell list's rows (cells along z) cut by their pair work
    /// (`balanced_cuts`): each particle travels to the ranks whose rows lie
    /// within `REACH` (2) rows of its own along x and y, so that every rank holds
    /// every cell its rows' particles visit, whole and in input order, and
    /// the rank of the particle's row sums it and sends it back.
    /// The accelerations of one process bit for bit, the potentials to
    /// rounding on an isolated mesh.
    pub fn compute_spread(
        &mut self,
        sources: &Sources,
        out: FieldOut,
        threads: &Threads,
        exchange: &dyn Exchange,
    ) {
        let rank = self.mesh.rank();
        assert_eq!(Rank::of(exchange), rank, "the exchange's ranks");
        let Some(bounds) = self.mesh.place(sources.position, threads, exchange) else {
            out.acc.fill([0.0; 3]);
            out.phi.fill(0.0);
            return;
        };
        let r_s = self.split * self.mesh.cell();
        let r_cut = CUT * r_s;
        let periodic = match self.mesh.params().boundary {
            MeshBoundary::Periodic { origin, length } => Some((origin, length)),
            MeshBoundary::Isolated => None,
        };
        let grid = Grid::covering(bounds, r_cut, periodic);
        let n = sources.mass.len();
        self.short.resize(n, [0.0; 4]);
        if rank.count == 1 {
            self.cells.sort(grid, sources, periodic);
            self.cells.sum(
                self.mesh.law(),
                &self.table,
                (r_s, r_cut),
                periodic,
                0..n,
                threads,
            );
            let cells = &self.cells;
            threads.install(|| {
                self.short
                    .par_iter_mut()
                    .zip(cells.slot.par_iter())
                    .for_each(|(short, &s)| *short = cells.sum[s])
            });
        } else {
            self.short_range_spread(sources, grid, (r_s, r_cut), periodic, exchange, threads);
        }
        let FieldOut { acc, phi } = out;
        self.mesh.solve(
            sources,
            FieldOut {
                acc: &mut *acc,
                phi: &mut *phi,
            },
            threads,
            exchange,
        );
        let short = &self.short;
        threads.install(|| {
            acc.par_iter_mut()
                .zip(phi.par_iter_mut())
                .zip(short.par_iter())
                .for_each(|((acc, phi), add)| {
                    for a in 0..3 {
                        acc[a] += add[a];
                    }
                    *phi += add[3];
                });
        });
    }

    /// The short range of this rank's own particles `sources` on several
    /// ranks into `self.short`: the particles routed by the cell list's rows
    /// of `grid` (see [`P3m::compute_spread`]), sorted and summed for the
    /// rows of this rank, the sums sent back. Collective.
    fn short_range_spread(
        &mut self,
        sources: &Sources,
        grid: Grid,
        (r_s, r_cut): (f64, f64),
        periodic: Option<([f64; 3], f64)>,
        exchange: &dyn Exchange,
        threads: &Threads,
    ) {
        let rank = self.mesh.rank();
        let [n0, n1, n2] = grid.count;
        let rows = n0 * n1;
        // the row (along the last axis) of cells of x, and the rows within
        // reach of a row, each once (every index of a periodic axis with fewer
        // than 2 REACH + 1 cells, as `Grid::span`)
        let row_of = |x: &[f64; 3]| {
            let c = grid.coords(&wrap(x, periodic));
            c[0] * n1 + c[1]
        };
        let near = |c: usize, n: usize| {
            let every = periodic.is_some() && n < 2 * REACH + 1;
            let (all, close) = if every {
                (0..n, 0..0)
            } else {
                (0..0, 0..2 * REACH + 1)
            };
            all.chain(close.filter_map(move |k| {
                let q = (c + k) as isize - REACH as isize;
                match periodic {
                    Some(_) => Some(q.rem_euclid(n as isize) as usize),
                    None => (0..n as isize).contains(&q).then_some(q as usize),
                }
            }))
        };
        let reach = |row: usize| {
            near(row / n1, n0).flat_map(move |q0| near(row % n1, n1).map(move |q1| q0 * n1 + q1))
        };
        let cuts = balanced_cuts(sources.position.iter().map(row_of), rows, reach, exchange);
        let owner = |row: usize| cuts.partition_point(|&cut| cut <= row) - 1;
        let place = |x: &[f64; 3]| {
            let row = row_of(x);
            let mut place = Place::new([owner(row)]);
            for q in reach(row) {
                place.add(owner(q));
            }
            place
        };
        let mut arrived = std::mem::take(&mut self.arrived);
        self.route.forward(
            sources.position,
            sources.mass,
            exchange,
            &mut arrived,
            place,
        );
        let routed = Sources {
            mass: &arrived.mass,
            position: &arrived.position,
        };
        self.cells.sort(grid, &routed, periodic);
        // this rank's rows: a run of the cells' row-major order (the start
        // of the cell after the last is the particle count)
        let (first, end) = (
            self.cells.start[cuts[rank.index] * n2],
            self.cells.start[cuts[rank.index + 1] * n2],
        );
        self.cells.sum(
            self.mesh.law(),
            &self.table,
            (r_s, r_cut),
            periodic,
            first..end,
            threads,
        );
        let cells = &self.cells;
        self.route.back(
            &arrived,
            0,
            exchange,
            &mut self.short,
            |i| cells.sum[cells.slot[i]],
            threads,
        );
        self.arrived = arrived;
    }
}

/// The rows of a cell list (cells along its last axis) cut among the ranks
/// of `exchange` by the work of their short-range sums: rank `r` sums the
/// rows `cuts[r]..cuts[r + 1]`, a run of the cells' row-major order. Each
/// rank passes the row of each of its own particles; a row's work is its
/// particle count `n_c` times `1 +` the particles of the rows `reach(c)`
/// within reach of it (its pairs), and the cuts split the summed work
/// evenly. Every rank gets the same cuts (collective).
fn balanced_cuts<R: Iterator<Item = usize>>(
    own: impl Iterator<Item = usize>,
    rows: usize,
    reach: impl Fn(usize) -> R,
    exchange: &dyn Exchange,
) -> Vec<usize> {
    let ranks = exchange.ranks();
    let mut mine = vec![0.0; rows];
    for c in own {
        mine[c] += 1.0;
    }
    let mut all = vec![0.0; rows * ranks];
    exchange.all_gather(&mine, &vec![rows; ranks], &mut all);
    let mut count = vec![0.0; rows];
    for part in all.chunks_exact(rows) {
        for (n, p) in count.iter_mut().zip(part) {
            *n += p;
        }
    }
    let work: Vec<f64> = (0..rows)
        .map(|c| {
            if count[c] == 0.0 {
                0.0
            } else {
                count[c] * (1.0 + reach(c).map(|q| count[q]).sum::<f64>())
            }
        })
        .collect();
    let total: f64 = work.iter().sum();
    let mut cuts = vec![0; ranks + 1];
    let (mut c, mut before) = (0, 0.0);
    for (r, cut) in cuts.iter_mut().enumerate().skip(1) {
        let goal = total * r as f64 / ranks as f64;
        while c < rows && before + work[c] <= goal {
            before += work[c];
            c += 1;
        }
        *cut = if r == ranks { rows } else { c };
    }
    cuts
}

/// `x` wrapped into the box `(origin, length)` when periodic, as the cell
/// list places it.
fn wrap(x: &[f64; 3], periodic: Option<([f64; 3], f64)>) -> [f64; 3] {
    match periodic {
        Some((origin, length)) => std::array::from_fn(|a| {
            let u = (x[a] - origin[a]).rem_euclid(length);
            if u >= length {
                0.0
            } else {
                u
            }
        }),
        None => *x,
    }
}

impl Grid {
    /// Cells of side `>= r_cut / REACH` over the box `(lo, hi)` of the
    /// particles (isolated) or the box `(origin, length)`, in which the
    /// positions are wrapped.
    fn covering(
        (lo, hi): ([f64; 3], [f64; 3]),
        r_cut: f64,
        periodic: Option<([f64; 3], f64)>,
    ) -> Grid {
        match periodic {
            Some((_, length)) => {
                let count = ((REACH as f64 * length / r_cut).floor() as usize).max(1);
                Grid {
                    count: [count; 3],
                    side: [length / count as f64; 3],
                    lo: [0.0; 3],
                }
            }
            None => {
                let mut grid = Grid {
                    lo,
                    ..Grid::default()
                };
                for a in 0..3 {
                    let extent = hi[a] - lo[a];
                    let count = ((REACH as f64 * extent / r_cut).floor() as usize).max(1);
                    grid.count[a] = count;
                    grid.side[a] = if extent > 0.0 {
                        extent / count as f64
                    } else {
                        1.0
                    };
                }
                grid
            }
        }
    }
}

impl Cells {
    /// Counting-sorts `sources` into the cells of `grid`, positions wrapped
    /// into the box `(origin, length)` when periodic.
    fn sort(&mut self, grid: Grid, sources: &Sources, periodic: Option<([f64; 3], f64)>) {
        let n = sources.mass.len();
        let wrap = |x: &[f64; 3]| wrap(x, periodic);
        self.grid = grid;
        let cells = self.grid.count.iter().product::<usize>();
        self.start.clear();
        self.start.resize(cells + 1, 0);
        self.cell_of.resize(n, 0);
        for (i, x) in sources.position.iter().enumerate() {
            let c = self.grid.index(self.grid.coords(&wrap(x)));
            self.cell_of[i] = c;
            self.start[c + 1] += 1;
        }
        for c in 0..cells {
            self.start[c + 1] += self.start[c];
        }
        self.slot.resize(n, 0);
        for a in 0..3 {
            self.x[a].resize(n, 0.0);
        }
        self.m.resize(n, 0.0);
        self.sum.resize(n, [0.0; 4]);
        // start[c] runs ahead while filling; it is restored below
        for (i, x) in sources.position.iter().enumerate() {
            let c = self.cell_of[i];
            let s = self.start[c];
            self.start[c] += 1;
            self.slot[i] = s;
            let x = wrap(x);
            for a in 0..3 {
                self.x[a][s] = x[a];
            }
            self.m[s] = sources.mass[i];
        }
        for c in (0..cells).rev() {
            self.start[c + 1] = self.start[c];
        }
        self.start[0] = 0;
    }

    /// The short-range `(acc, phi)` of the sorted particles `block` over the
    /// cells within [`REACH`] of their own (the runs along the last axis being
    /// consecutive in the sorted order), minimum image when periodic, for the
    /// splitting radius and cut `(r_s, r_cut)`.
    fn sum(
        &mut self,
        law: &GravityLaw,
        table: &LongTable,
        (r_s, r_cut): (f64, f64),
        periodic: Option<([f64; 3], f64)>,
        block: Range<usize>,
        threads: &Threads,
    ) {
        let Cells {
            grid,
            start,
            x,
            m,
            sum,
            ..
        } = self;
        let (grid, start, x, m) = (*grid, &*start, &*x, &*m);
        let length = periodic.map_or(0.0, |(_, length)| length);
        let r_cut2 = r_cut * r_cut;
        let to_u = 1.0 / (4.0 * r_s * r_s);
        let eps2 = if periodic.is_some() {
            0.0
        } else {
            law.softening2()
        };
        let (k_scale, phi_scale) = (law.g() / (8.0 * r_s * r_s * r_s), law.g() / (2.0 * r_s));
        let pairs = ShortPairs {
            law,
            table,
            x,
            m,
            length,
            periodic: periodic.is_some(),
            r_cut2,
            to_u,
            eps2,
            k_scale,
            phi_scale,
        };
        threads.install(|| {
            sum[block.clone()]
                .par_chunks_mut(CHUNK)
                .enumerate()
                .for_each(|(chunk, sums)| {
                    for (k, out) in sums.iter_mut().enumerate() {
                        let i = block.start + chunk * CHUNK + k;
                        let xi = [x[0][i], x[1][i], x[2][i]];
                        let own = grid.coords(&xi);
                        let mut total = [0.0; 4];
                        let mut lanes = [F64x4::splat(0.0); 4];
                        let [s0, s1, s2] =
                            [0, 1, 2].map(|a| grid.span(own[a], periodic.is_some(), a));
                        for c0 in s0.into_iter().flatten() {
                            for c1 in s1.clone().into_iter().flatten() {
                                let row = grid.index([c0, c1, 0]);
                                for run in s2.iter().filter(|r| !r.is_empty()) {
                                    let js = start[row + run.start]..start[row + run.end];
                                    pairs.run(i, xi, js, &mut lanes, &mut total);
                                }
                            }
                        }
                        for (t, l) in total.iter_mut().zip(lanes) {
                            *t += l.sum();
                        }
                        *out = total;
                    }
                });
        });
    }
}

/// The short-range pair term of one body against runs of sorted bodies: the exact
/// softened law minus the long-range kernel, for pairs with `s^2 < r_cut^2`.
struct ShortPairs<'a> {
    law: &'a GravityLaw,
    table: &'a LongTable,
    x: &'a [Vec<f64>; 3],
    m: &'a [f64],
    length: f64,
    periodic: bool,
    r_cut2: f64,
    to_u: f64,
    eps2: f64,
    k_scale: f64,
    phi_scale: f64,
}

impl ShortPairs<'_> {
    /// Adds the pairs of body `i` (at `xi`) with the sorted bodies `js`: four at a
    /// time into `lanes`, the rest into `total`.
    #[inline(always)]
    fn run(
        &self,
        i: usize,
        xi: [f64; 3],
        js: Range<usize>,
        lanes: &mut [F64x4; 4],
        total: &mut [f64; 4],
    ) {
        let x = self.x;
        let whole = js.start + (js.len() - js.len() % 4);
        let xi4 = xi.map(F64x4::splat);
        let (length, inv_length) = (F64x4::splat(self.length), F64x4::splat(1.0 / self.length));
        let (one, g, i4) = (
            F64x4::splat(1.0),
            F64x4::splat(self.law.g()),
            F64x4::splat(i as f64),
        );
        let (cut2, law_eps2, split_eps2) = (
            F64x4::splat(self.r_cut2),
            F64x4::splat(self.law.softening2()),
            F64x4::splat(self.eps2),
        );
        for j in (js.start..whole).step_by(4) {
            let mut d = axes(|a| F64x4::load(&x[a][j..]) - xi4[a]);
            if self.periodic {
                for v in &mut d {
                    *v = (*v * inv_length).round_ties_even().neg_mul_add(length, *v);
                }
            }
            let r2 = d[0].mul_add(d[0], d[1].mul_add(d[1], d[2] * d[2]));
            let s2 = r2 + split_eps2;
            let inv = one / (r2 + law_eps2).sqrt();
            let [f_k, f_phi] = self.table.at4(s2 * F64x4::splat(self.to_u));
            let k = g * inv * inv * inv - F64x4::splat(self.k_scale) * f_k;
            let phi = F64x4::splat(self.phi_scale) * f_phi - g * inv;
            // pairs beyond the cut and the self pair add zero (masked after the
            // products, which may be infinite for the self pair without softening)
            let ids = F64x4::load(&[j as f64, (j + 1) as f64, (j + 2) as f64, (j + 3) as f64]);
            let keep = |v: F64x4| v.zero_unless_less(s2, cut2).zero_where_equal(ids, i4);
            let m = F64x4::load(&self.m[j..]);
            let (km, pm) = (keep(k * m), keep(phi * m));
            for a in 0..3 {
                lanes[a] = km.mul_add(d[a], lanes[a]);
            }
            lanes[3] = lanes[3] + pm;
        }
        for j in whole..js.end {
            if j == i {
                continue;
            }
            let mut d = [x[0][j] - xi[0], x[1][j] - xi[1], x[2][j] - xi[2]];
            if self.periodic {
                for v in &mut d {
                    *v -= self.length * (*v / self.length).round_ties_even();
                }
            }
            let r2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
            // s^2 of the split
            let s2 = r2 + self.eps2;
            if s2 >= self.r_cut2 {
                continue;
            }
            let (phi, k) = self.law.unit_pair(r2);
            let [f_k, f_phi] = self.table.at(s2 * self.to_u);
            let (phi_l, k_l) = (-self.phi_scale * f_phi, self.k_scale * f_k);
            let km = (k - k_l) * self.m[j];
            total[0] += km * d[0];
            total[1] += km * d[1];
            total[2] += km * d[2];
            total[3] += (phi - phi_l) * self.m[j];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::longrange::mesh::slab;
    use crate::longrange::mesh::testkit::{cloud, direct, pair_error, rms_relative, run};

    fn law() -> GravityLaw {
        GravityLaw::new(1.3, 0.05, 0.0).unwrap()
    }

    #[test]
    fn cuts_divide_the_pair_work_and_agree_on_every_rank() {
        use crate::longrange::mesh::slab::testkit::Hub;
        // 12 rows, not periodic; a dense run of rows 4..7 (a cluster)
        let rows = 12;
        let reach = |c: usize| c.saturating_sub(REACH)..(c + REACH + 1).min(rows);
        let row_of = |i: usize| {
            if i.is_multiple_of(4) {
                i % rows
            } else {
                4 + i % 3
            }
        };
        let n = 600;
        let mut count = vec![0.0; rows];
        (0..n).for_each(|i| count[row_of(i)] += 1.0);
        let work: Vec<f64> = (0..rows)
            .map(|c| count[c] * (1.0 + reach(c).map(|q| count[q]).sum::<f64>()))
            .collect();
        let heaviest = work.iter().fold(0.0f64, |a, &b| a.max(b));
        for ranks in [1, 2, 3, 4] {
            let cuts = Hub::run(ranks, |exchange| {
                let own = slab::part(n, exchange.rank(), ranks).map(row_of);
                balanced_cuts(own, rows, reach, exchange)
            });
            assert!(cuts.iter().all(|c| *c == cuts[0]), "{cuts:?}");
            let cuts = &cuts[0];
            assert_eq!((cuts[0], cuts[ranks]), (0, rows));
            let total: f64 = work.iter().sum();
            for r in 0..ranks {
                let part: f64 = work[cuts[r]..cuts[r + 1]].iter().sum();
                // within one row's work of an even share
                assert!(
                    (part - total / ranks as f64).abs() <= heaviest,
                    "{ranks} ranks, {cuts:?}: {part} of {total}"
                );
            }
        }
    }

    fn isolated(grid: usize) -> MeshParams {
        MeshParams {
            grid,
            boundary: MeshBoundary::Isolated,
        }
    }

    /// The worst `(rms, max)` pair error over the separations `seps` (cells).
    fn worst_pair_error(split: f64, seps: &[f64]) -> (f64, f64) {
        let mut solver = P3m::new(law(), isolated(32), split).unwrap();
        let threads = Threads::single();
        seps.iter().fold((0.0f64, 0.0f64), |(rms, max), &sep| {
            let got = pair_error(law(), 32, sep, 8, 3, |s, o| solver.compute(s, o, &threads));
            (rms.max(got.0), max.max(got.1))
        })
    }

    #[test]
    fn pair_force_is_accurate_at_every_separation() {
        // the pair sum is exact; the mesh's erf part carries what is left of the
        // cloud-in-cell anisotropy after interlacing, which a wider split reduces
        let (rms, max) = worst_pair_error(SPLIT_CELLS, &[0.1, 0.5, 1.0]);
        // measured on a denser sweep: (3.9e-4, 5.5e-4), (3.1e-3, 5.6e-3), (1.2e-3, 1.8e-3)
        assert!(rms < 1e-3 && max < 2e-3, "below a cell: {rms} {max}");
        // r_cut = 6.875 cells
        let seps = [2.0, 4.0, 6.0, 6.8, 7.0, 10.0];
        let (rms, max) = worst_pair_error(SPLIT_CELLS, &seps);
        assert!(rms < 5e-3 && max < 1e-2, "split 1.25: {rms} {max}");
        // r_cut = 11 cells
        let seps = [0.5, 3.0, 6.0, 10.0, 11.5];
        let (rms, max) = worst_pair_error(2.0, &seps);
        assert!(rms < 2.5e-3 && max < 4e-3, "split 2: {rms} {max}");
    }

    #[test]
    fn cloud_error_against_the_direct_sum() {
        let (m, x) = cloud(2000, 1.0, [0.0; 3], 11);
        let (want_acc, want_phi) = direct(law(), &m, &x);
        let mut solver = P3m::new(law(), isolated(32), SPLIT_CELLS).unwrap();
        let (acc, phi) = run(&m, &x, |s, o| solver.compute(s, o, &Threads::single()));
        let rms = rms_relative(&acc, &want_acc);
        // measured 8.0e-4: the mesh error at a few cells, on the part of the
        // force beyond r_s
        assert!(rms < 1.5e-3, "rms {rms}");
        let worst = phi
            .iter()
            .zip(&want_phi)
            .map(|(p, w)| ((p - w) / w).abs())
            .fold(0.0, f64::max);
        // measured 1.2e-3
        assert!(worst < 3e-3, "phi {worst}");
    }

    #[test]
    fn the_mesh_carries_the_softened_tail() {
        // eps = 0.8 h: a Newtonian far field would be off by 3 eps^2 / (2 r^2),
        // 2 % at r_cut, and the RMS error would be about 5e-3
        let law = GravityLaw::new(1.0, 0.1, 0.0).unwrap();
        let (m, x) = crate::longrange::mesh::testkit::gaussian(2000, 1.0, 9);
        let (want, _) = direct(law, &m, &x);
        let mut solver = P3m::new(law, isolated(64), SPLIT_CELLS).unwrap();
        let (acc, _) = run(&m, &x, |s, o| solver.compute(s, o, &Threads::single()));
        let rms = rms_relative(&acc, &want);
        assert!(rms < 1e-3, "rms {rms}");
    }

    #[test]
    fn periodic_matches_the_direct_sum_for_a_compact_cloud() {
        // images and background act at (size / length)^3 ~ 1e-4 of the inner pull
        let params = MeshParams {
            grid: 32,
            boundary: MeshBoundary::Periodic {
                origin: [0.0; 3],
                length: 20.0,
            },
        };
        let (m, x) = cloud(1000, 0.5, [10.0, 9.0, 11.0], 5);
        let (want, _) = direct(law(), &m, &x);
        let mut solver = P3m::new(law(), params, SPLIT_CELLS).unwrap();
        let (acc, _) = run(&m, &x, |s, o| solver.compute(s, o, &Threads::single()));
        let rms = rms_relative(&acc, &want);
        // measured 7.4e-4
        assert!(rms < 1.5e-3, "rms {rms}");
    }

    #[test]
    fn periodic_forces_do_not_see_where_the_box_is_cut() {
        // the same cloud in the middle of the box and across its corner, shifted
        // by 16 cells: minimum images and wrapped cell runs give the same forces
        let params = MeshParams {
            grid: 32,
            boundary: MeshBoundary::Periodic {
                origin: [0.0; 3],
                length: 20.0,
            },
        };
        let (m, x) = cloud(1000, 1.0, [10.0; 3], 6);
        let corner: Vec<[f64; 3]> = x.iter().map(|p| p.map(|c| c - 10.0)).collect();
        let mut solver = P3m::new(law(), params, SPLIT_CELLS).unwrap();
        let threads = Threads::single();
        let (a, _) = run(&m, &x, |s, o| solver.compute(s, o, &threads));
        let (b, _) = run(&m, &corner, |s, o| solver.compute(s, o, &threads));
        let rms = rms_relative(&b, &a);
        assert!(rms < 1e-9, "rms {rms}");
    }

    #[test]
    fn table_follows_the_long_range_kernel() {
        let table = LongTable::new();
        let mut rng = crate::random::Rng::new(1);
        for _ in 0..10_000 {
            // r_s = 1/2: r up to r_cut = CUT / 2
            let r = CUT / 2.0 * rng.uniform();
            let (phi, k) = long_pair(1.0, 0.5, r);
            let [f_k, f_phi] = table.at(r * r);
            assert!((f_k - k).abs() < 1e-7 * k, "r {r}: {f_k} {k}");
            assert!((f_phi + phi).abs() < 1e-7 * -phi, "r {r}: {f_phi} {phi}");
        }
    }

    #[test]
    fn bad_parameters_are_refused() {
        for split in [0.0, 0.4, -1.0, f64::NAN] {
            let error = P3m::new(law(), isolated(16), split).err().unwrap();
            assert!(error.contains("split_cells"), "{error}");
        }
        let periodic = MeshParams {
            grid: 16,
            boundary: MeshBoundary::Periodic {
                origin: [0.0; 3],
                length: 1.0,
            },
        };
        assert!(P3m::new(law(), periodic, 1.25).is_ok());
        assert!(P3m::new(law(), periodic, 1.5)
            .err()
            .unwrap()
            .contains("half"));
        assert!(P3m::new(law(), isolated(12), 1.25)
            .err()
            .unwrap()
            .contains("grid"));
        let repulsive = GravityLaw::new(1.0, 0.0, 0.1).unwrap();
        assert!(P3m::new(repulsive, isolated(16), 1.25).is_err());
    }
}
