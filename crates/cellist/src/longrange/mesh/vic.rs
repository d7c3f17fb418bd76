//! Vortex-in-cell (VIC): the velocity of 2D vortex blobs (the regularised
//! Biot-Savart law of [`crate::longrange::biot_savart`]) on a mesh.
//!
//! 1. **Assign.** The circulations go to the nodes `x_g` of a mesh of cell `H`
//!    with the M4' kernel of [`crate::interpolation`]:
//!
//!    ```text
//!    w_g = sum_p Gamma_p M4'((x_g - x_p) / H) M4'((y_g - y_p) / H) / H^2.
//!    ```
//!
//!    Every task owns a band of mesh rows and adds, in a fixed order (particles
//!    counting-sorted by their stencil's row, in input order within a row), the
//!    particles that touch it: no atomics, and the same bits for any thread count.
//!
//! 2. **Solve.** `Laplacian psi = -w` and `u = curl psi = (d psi / dy, -d psi / dx)`
//!    by FFT, the derivative taken exactly on the Green's function and the
//!    Gaussian blobs' regularisation included, so that the mesh approximates the
//!    same field as the direct sum `u(x) = sum_j Gamma_j K_sigma(x - x_j)`:
//!
//!    - periodic box `[origin, origin + L)^2` on `grid^2` nodes (`H = L / grid`),
//!      with `k = 2 pi q / L`:
//!
//!      ```text
//!      hat psi(k) = hat w(k) exp(-k^2 sigma^2 / 2) / k^2,   hat psi(0) = 0,
//!      hat u(k) = i k_y hat psi(k),   hat v(k) = -i k_x hat psi(k)
//!      ```
//!
//!      (zero on the Nyquist line of the derivative's axis). The total
//!      circulation, the `k = 0` mode, does not move anything.
//!
//!    - unbounded: the mesh covers the particles' bounding box with a margin of
//!      at least 2 cells (the M4' support), its nodes on the lattice `H Z^2`, and
//!      is zero-padded to `(2 grid)^2` (Hockney and Eastwood), so that the cyclic
//!      convolution is the open one,
//!
//!      ```text
//!      u_g = sum_g' K_sigma(x_g - x_g') w_g' H^2,
//!      ```
//!
//!      with `K_sigma` sampled at the mesh offsets (zero on the padded mesh's
//!      middle lines `|o_a| = grid`, which no pair reaches) and transformed once
//!      per cell size. `H` is the smallest rung `2^(j/8) >= extent / (grid - 6)`
//!      of a ladder (as the gravity mesh's), so the transformed kernel, re-made
//!      only when `j` changes, is usually reused.
//!
//! 3. **Interpolate.** `u_p = sum_g u_g M4'((x_g - x_p) / H) M4'((y_g - y_p) / H)`,
//!    with the weights of step 1.
//!
//! M4' interpolates (`M4'(0) = 1`, zero at the other nodes): particles that sit
//! on mesh nodes, as they do after a remeshing onto the mesh's lattice (the
//! periodic mesh's, or `H Z^2` with `H` = [`VortexInCell::cell`] unbounded), are
//! assigned and interpolated exactly, and the unbounded mesh then reproduces the
//! direct sum to round-off. Off the nodes, assignment and interpolation err by
//! `O((k H)^4)` on a mode `k` (M4' reproduces quadratics), with a coefficient
//! that depends on where the particles sit in their cells. Dividing the spectra
//! by the window `W(k H)^2` (`W(t) = 3 s^4 - 2 s^3 cos(t/2)`, `s = sin(t/2) /
//! (t/2)`, per axis) was measured on the periodic Taylor-Green test: it halves
//! the error off the nodes (`4.2e-4` to `2.0e-4` of the peak speed at the worst
//! offset) but makes the on-node error `2.2e-4` instead of round-off, so it is
//! not done.

use super::apply_kernel;
use super::fft::Fft2;
use super::green::signed;
use super::m4::{Plane, Sorted};
use super::slab::{part, Alone, Exchange, Rank, Slab};
use crate::longrange::biot_savart::BlobKernel;
use crate::threads::Threads;
use rayon::prelude::*;
use rustfft::num_complex::Complex;
use std::f64::consts::PI;
use std::ops::{Range, RangeInclusive};

/// The smallest grid accepted.
pub const MIN_VIC_GRID: usize = 16;

/// The largest grid accepted (an unbounded mesh is padded to `(2 grid)^2`: grid
/// 4096 takes about 2 GB).
pub const MAX_VIC_GRID: usize = 4096;

/// The VIC mesh's boundary.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum VicBoundary {
    /// Open space: the velocity vanishes at infinity. The mesh covers the
    /// particles' bounding box and is zero-padded to twice its side.
    Unbounded,
    /// The periodic square `[origin, origin + length)^2`: every particle feels all
    /// images of the others. The total circulation (the `k = 0` mode) is ignored,
    /// as a periodic velocity field can only carry a zero-mean vorticity.
    Periodic {
        /// The box's lower corner.
        origin: [f64; 2],
        /// The box's side `L`.
        length: f64,
    },
}

/// A vortex-in-cell solver's settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VicParams {
    /// Mesh nodes per axis, a power of two in `MIN_VIC_GRID..=MAX_VIC_GRID`: the
    /// periodic box's, or the part of the unbounded mesh that covers the
    /// particles (before the padding).
    pub grid: usize,
    /// The boundary.
    pub boundary: VicBoundary,
}

impl VicParams {
    /// Checks the grid and the periodic box.
    pub fn check(&self) -> Result<(), String> {
        let periodic = match &self.boundary {
            VicBoundary::Unbounded => None,
            VicBoundary::Periodic { origin, length } => Some((&origin[..], *length)),
        };
        check_mesh(self.grid, MIN_VIC_GRID..=MAX_VIC_GRID, periodic)
    }
}

/// Checks a vortex-in-cell mesh: `grid` a power of two in `range` and, if
/// `periodic`, its box `(origin, length)` finite with `length > 0`.
pub(super) fn check_mesh(
    grid: usize,
    range: RangeInclusive<usize>,
    periodic: Option<(&[f64], f64)>,
) -> Result<(), String> {
    if !(grid.is_power_of_two() && range.contains(&grid)) {
        return Err(format!(
            "grid must be a power of two in {}..={}, got {grid}",
            range.start(),
            range.end()
        ));
    }
    if let Some((origin, length)) = periodic {
        if !(length.is_finite() && length > 0.0) {
            return Err(format!("length must be finite and > 0, got {length}"));
        }
        if origin.iter().any(|c| !c.is_finite()) {
            return Err(format!("origin must be finite, got {origin:?}"));
        }
    }
    Ok(())
}

/// The vortex-in-cell velocity of 2D Gaussian vortex blobs: assignment of the
/// circulations to a mesh with M4', `u = curl psi` with `Laplacian psi = -w`
/// solved by FFT (blob regularisation `exp(-k^2 sigma^2 / 2)` included, periodic;
/// or the regularised kernel `K_sigma` on a zero-padded mesh, unbounded), and
/// M4' interpolation back to the particles; see the [module](self) for the
/// equations. The result approximates
/// `u_i = sum_j Gamma_j K_sigma(x_i - x_j)` of [`crate::longrange::biot_savart`].
///
/// Measured errors (tests of this module; `max` is the largest error over
/// the particles relative to the peak speed, `rms` the RMS error relative to
/// the RMS speed):
///
/// - unbounded, a Gaussian vortex `w = exp(-|x|^2 / 0.1) / (0.1 pi)` on the
///   lattice of spacing `h = 0.05` over `[-1.5, 1.5]^2` (3721 particles,
///   `Gamma = h^2 w`), `sigma = 1.5 h`, against the direct sum: grid 64, cell
///   `H = 2^(-34/8) = 1.05 h`, particles off the nodes: rms `2.4e-4`, max
///   `8.1e-4`; grid 128 (`H = 0.53 h`): `5.1e-5`, `2.2e-4`; grid 256
///   (`H = 0.24 h`): `9.5e-6`, `3.9e-5`. With `h = H = 2^(-34/8)`, particles on
///   the nodes: `2e-15`, `6e-15` (round-off). Off the nodes the error depends
///   on how the lattice falls on the mesh: for `h` from 0.046 to 0.0575 on grid
///   64 (`H / h` from 1.14 to 0.91) max runs from `2e-5` (`H / h = 1.001`) to
///   `2.2e-3` (`H / h = 0.91`); on grid 128 (`H` about `h / 2`) it stays below
///   `3.5e-4`.
/// - periodic, Taylor-Green `psi = sin(k_x x) sin(k_y y)` with `(k_x, k_y) = (2,
///   3) 2 pi / L` on `64^2` nodes, `sigma = 1.5 H`, particles on a `64^2`
///   lattice: on the nodes max `1.6e-15`; shifted by `(0.37, 0.61)` cells
///   `3.8e-4`, by half a cell `4.2e-4`; `100^2` particles `4.9e-4`; on `128^2`
///   nodes (and particles) `2.4e-5`, on `32^2` `5.9e-3`.
pub struct VortexInCell {
    params: VicParams,
    kernel: BlobKernel,
    plane: Plane,
    /// The ladder rung the unbounded spectra were made for (`Some(0)` once the
    /// periodic ones are made, in the first evaluation's pool).
    rung: Option<i64>,
    /// The transform, on this rank's slab of rows (every row in one process).
    slab: Slab<Fft2>,
    /// `A_x`, `A_y` with `hat u_a = i A_a hat Gamma` (`1 / M^2` included), on
    /// this rank's columns.
    spectra: [Vec<f64>; 2],
    /// Circulation per node, `w_g H^2`, on this rank's rows of `grid`.
    circulation: Vec<f64>,
    /// This rank's columns of the transformed circulation and of a product
    /// being inverted.
    hat: Vec<Complex<f64>>,
    work: Vec<Complex<f64>>,
    /// `u`, `v` on this rank's rows, one more below and two above.
    fields: [Vec<f64>; 2],
    /// `(x, y, Gamma)` counting-sorted by stencil row (after the
    /// interpolation: `(u, v, Gamma)`).
    sorted: Sorted<3>,
}

impl std::fmt::Debug for VortexInCell {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("VortexInCell")
            .field("params", &self.params)
            .field("sigma", &self.kernel.sigma())
            .field("cell", &self.plane.cell)
            .field("rank", &self.slab.rank())
            .finish_non_exhaustive()
    }
}

impl VortexInCell {
    /// The solver for blobs of `kernel` with `params`; refuses a grid that is not
    /// a power of two in `MIN_VIC_GRID..=MAX_VIC_GRID`, a bad periodic box, a core
    /// `sigma` that is not finite and `> 0`.
    pub fn new(params: VicParams, kernel: BlobKernel) -> Result<Self, String> {
        Self::on_rank(params, kernel, Rank::ALONE)
    }

    /// The solver on `rank`'s slab of rows of a mesh shared by several ranks,
    /// each of which holds every particle; refuses what [`VortexInCell::new`]
    /// refuses and more ranks than half the grid's rows (or the columns of its
    /// half spectrum).
    pub fn on_rank(params: VicParams, kernel: BlobKernel, rank: Rank) -> Result<Self, String> {
        params.check()?;
        let sigma = kernel.sigma();
        if !(sigma.is_finite() && sigma > 0.0) {
            return Err(format!("sigma must be finite and > 0, got {sigma}"));
        }
        let n = params.grid;
        let (side, plane) = match params.boundary {
            VicBoundary::Unbounded => (
                2 * n,
                Plane {
                    origin: [0.0; 2],
                    cell: 0.0,
                    grid: n,
                    periodic: false,
                },
            ),
            VicBoundary::Periodic { origin, length } => (
                n,
                Plane {
                    origin,
                    cell: length / n as f64,
                    grid: n,
                    periodic: true,
                },
            ),
        };
        let slab = Slab::new(Fft2::new(side), rank);
        // the M4' stencil reads two rows above a slab from the next rank alone
        rank.check_slabs(n, 2, slab.plane_len())?;
        rank.check(n)?;
        let len = slab.lines_len();
        let (owned, window) = (slab.owned(n).len(), slab.window(n, 1, 2).count());
        Ok(VortexInCell {
            params,
            kernel,
            plane,
            rung: None,
            slab,
            spectra: [vec![0.0; len], vec![0.0; len]],
            circulation: vec![0.0; owned * n],
            hat: vec![Complex::default(); len],
            work: vec![Complex::default(); len],
            fields: [vec![0.0; window * n], vec![0.0; window * n]],
            sorted: Sorted::new(n),
        })
    }

    /// The settings.
    pub fn params(&self) -> &VicParams {
        &self.params
    }

    /// The mesh cell `H` of the last evaluation (unbounded; 0 before the first)
    /// or of the box, `L / grid` (periodic).
    pub fn cell(&self) -> f64 {
        self.plane.cell
    }

    /// `velocity[i]` = the mesh's `u(x_i)` of the blobs at `positions` with
    /// circulations `gamma`. Panics if the slices' lengths differ or a position
    /// is not finite.
    pub fn compute(
        &mut self,
        positions: &[[f64; 2]],
        gamma: &[f64],
        velocity: &mut [[f64; 2]],
        threads: &Threads,
    ) {
        self.compute_shared(positions, gamma, velocity, threads, &Alone);
    }

    /// [`VortexInCell::compute`] on the ranks of `exchange`, every rank calling
    /// it with every particle: each assigns to and transforms its slab of rows
    /// and interpolates the particles of its rows, and every rank gets every
    /// particle's velocity, the same bits as one process's.
    pub fn compute_shared(
        &mut self,
        positions: &[[f64; 2]],
        gamma: &[f64],
        velocity: &mut [[f64; 2]],
        threads: &Threads,
        exchange: &dyn Exchange,
    ) {
        assert_eq!(Rank::of(exchange), self.slab.rank(), "the exchange's ranks");
        crate::longrange::biot_savart::assert_lengths(positions, gamma, velocity);
        assert!(
            positions.len() <= u32::MAX as usize,
            "at most 2^32 - 1 particles"
        );
        if positions.is_empty() {
            return;
        }
        match self.params.boundary {
            VicBoundary::Unbounded => self.cover(positions, threads, exchange),
            VicBoundary::Periodic { length, .. } => {
                if self.rung.is_none() {
                    threads.install(|| self.periodic_spectra(length));
                    self.rung = Some(0);
                }
            }
        }
        threads.install(|| {
            self.sort(positions, gamma);
            self.assign();
        });
        self.solve(threads, exchange);
        self.interpolate(velocity, threads, exchange);
    }

    /// `A_x = k_y g / L^2`, `A_y = -k_x g / L^2` with
    /// `g = exp(-k^2 sigma^2 / 2) / k^2` (0 at `k = 0`), zero on the Nyquist line
    /// of the derivative's axis: `u(x_g) = L^-2 sum_k i A hat Gamma(k) exp(i k.x_g)`
    /// with `hat Gamma` the DFT of the node circulations.
    fn periodic_spectra(&mut self, length: f64) {
        let n = self.params.grid;
        let columns = self.slab.columns();
        let s2 = self.kernel.sigma().powi(2);
        let area = length * length;
        let [ax, ay] = &mut self.spectra;
        ax.par_chunks_mut(columns.len())
            .zip(ay.par_chunks_mut(columns.len()))
            .enumerate()
            .for_each(|(row, (ox, oy))| {
                for (k, q1) in columns.clone().enumerate() {
                    let (ox, oy) = (&mut ox[k], &mut oy[k]);
                    let k = [row, q1].map(|q| 2.0 * PI * signed(q, n) / length);
                    let k2 = k[0] * k[0] + k[1] * k[1];
                    let g = if k2 == 0.0 {
                        0.0
                    } else {
                        (-0.5 * k2 * s2).exp() / (k2 * area)
                    };
                    *ox = if q1 == n / 2 { 0.0 } else { k[1] * g };
                    *oy = if row == n / 2 { 0.0 } else { -k[0] * g };
                }
            });
    }

    /// Places the unbounded mesh over `positions`: the cell is the smallest rung
    /// `2^(j/8) >= extent / (grid - 6)` (`extent` at least `sigma`), the nodes lie
    /// on the lattice `H Z^2` with the bounding box at least 2 cells inside; the
    /// kernel's spectra are re-made when the rung changes.
    fn cover(&mut self, positions: &[[f64; 2]], threads: &Threads, exchange: &dyn Exchange) {
        let rung = self.plane.cover(positions, self.kernel.sigma(), threads);
        let cell = self.plane.cell;
        if self.rung != Some(rung) {
            self.unbounded_spectra(cell, threads, exchange);
            self.rung = Some(rung);
        }
    }

    /// `A_x` = the imaginary part of the DFT of `K_sigma`'s x component
    /// `K_x = -f(r^2) d_y` ([`BlobKernel::factor`]), sampled at the offsets
    /// `d = H (o_x, o_y)`, `-M/2 < o < M/2` (zero on `o = M/2`), divided by
    /// `M^2`: `K_sigma` is real and odd, so its transform is `i A_a M^2`. This
    /// rank's columns, transformed over the ranks. `K_y(d_x, d_y) = f(r^2) d_x =
    /// -K_x(d_y, d_x)`, and the sampled kernels are the same transposed, so
    /// `A_y(q0, q1) = -A_x(q1, q0)` and, `A_x` being odd, `= A_x(-q1, -q0)`: the
    /// half spectrum's rows `q1` and `-q1` of `A_x` for this rank's columns
    /// `q1`, gathered from every rank ([`Slab::whole_rows`]), give `A_y` on
    /// them (the row `q1` for `q0 <= M/2`, the row `-q1` for `q0 > M/2`).
    fn unbounded_spectra(&mut self, cell: f64, threads: &Threads, exchange: &dyn Exchange) {
        let m = self.slab.size();
        let norm = 1.0 / (m * m) as f64;
        let kernel = self.kernel;
        let sample = |i: usize, _: usize, row: &mut [f64]| {
            let dx = signed(i, m) * cell;
            for (l, v) in row.iter_mut().enumerate() {
                let dy = signed(l, m) * cell;
                *v = if i == m / 2 || l == m / 2 {
                    0.0
                } else {
                    -kernel.factor(dx * dx + dy * dy) * dy
                };
            }
        };
        self.slab
            .forward(m, &mut self.work, sample, exchange, threads);
        let [ax, ay] = &mut self.spectra;
        let work = &self.work;
        threads.install(|| {
            ax.par_chunks_mut(1024)
                .zip(work.par_chunks(1024))
                .for_each(|(o, w)| {
                    for (o, w) in o.iter_mut().zip(w) {
                        *o = w.im * norm;
                    }
                })
        });
        let (h, width) = (self.slab.plane_len(), self.slab.columns().len());
        let transposed =
            |cols: Range<usize>| -> Vec<usize> { cols.flat_map(|q1| [q1, (m - q1) % m]).collect() };
        let mut rows = vec![0.0; 2 * width * h];
        self.slab.whole_rows(ax, transposed, &mut rows, exchange);
        threads.install(|| {
            ay.par_chunks_mut(width).enumerate().for_each(|(q0, out)| {
                for (o, pair) in out.iter_mut().zip(rows.chunks(2 * h)) {
                    let (row, mirror) = pair.split_at(h);
                    *o = if q0 <= m / 2 {
                        -row[q0]
                    } else {
                        mirror[m - q0]
                    };
                }
            })
        });
    }

    /// Counting-sorts the particles by stencil row ([`Sorted::sort`]).
    fn sort(&mut self, positions: &[[f64; 2]], gamma: &[f64]) {
        let entry = |i: usize| [positions[i][0], positions[i][1], gamma[i]];
        self.sorted.sort(&self.plane, positions, entry);
    }

    /// The node circulations `w_g H^2` on this rank's rows: each task owns a
    /// band of them ([`Sorted::assign`]).
    fn assign(&mut self) {
        let first = self.slab.owned(self.plane.grid).start;
        self.sorted
            .assign(&self.plane, first, &mut self.circulation);
    }

    /// The mesh velocities on this rank's window of rows from the node
    /// circulations: `u_a = IFFT(i A_a FFT(w H^2))`.
    fn solve(&mut self, threads: &Threads, exchange: &dyn Exchange) {
        let n = self.plane.grid;
        let first = self.slab.owned(n).start;
        let circulation = &self.circulation;
        self.slab.forward(
            n,
            &mut self.hat,
            |i, _, row| row.copy_from_slice(&circulation[(i - first) * n..][..n]),
            exchange,
            threads,
        );
        for (field, a) in self.fields.iter_mut().zip(&self.spectra) {
            threads.install(|| apply_kernel(&mut self.work, &self.hat, a, true));
            self.slab
                .inverse(n, &mut self.work, field, (1, 2), exchange, threads);
        }
    }

    /// `velocity_p = sum_g u_g W_p(g)` with the assignment's weights, computed
    /// in sorted order (neighbours read neighbouring nodes) and gathered back.
    /// On several ranks each interpolates the particles of its rows, which are
    /// contiguous in sorted order, and the ranks' blocks are gathered.
    fn interpolate(
        &mut self,
        velocity: &mut [[f64; 2]],
        threads: &Threads,
        exchange: &dyn Exchange,
    ) {
        let plane = self.plane;
        let n = plane.grid;
        let rank = self.slab.rank();
        let window = self.slab.window(n, 1, 2);
        let starts = &self.sorted.starts;
        let block = |r: usize| {
            let rows = part(n, r, rank.count);
            starts[rows.start]..starts[rows.end]
        };
        let mine = block(rank.index);
        let [fu, fv] = &self.fields;
        threads.install(|| {
            self.sorted.entries[mine.clone()]
                .par_chunks_mut(1024)
                .for_each(|chunk| {
                    for p in chunk {
                        let s = plane.stencil(&[p[0], p[1]]);
                        let sum = plane.gather(&s, window, [fu, fv]);
                        // the position is no longer needed: keep the velocity there
                        p[0] = sum[0];
                        p[1] = sum[1];
                    }
                })
        });
        if rank.count > 1 {
            let counts: Vec<usize> = (0..rank.count).map(|r| 3 * block(r).len()).collect();
            let own = self.sorted.entries[mine].to_vec();
            exchange.all_gather(
                own.as_flattened(),
                &counts,
                self.sorted.entries.as_flattened_mut(),
            );
        }
        let (sorted, order) = (&self.sorted.entries, &self.sorted.rank);
        threads.install(|| {
            velocity
                .par_iter_mut()
                .zip(order.par_iter())
                .for_each(|(out, &k)| {
                    let p = sorted[k as usize];
                    *out = [p[0], p[1]];
                })
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::longrange::biot_savart::velocity_at;
    use crate::random::Rng;

    fn unbounded(grid: usize) -> VicParams {
        VicParams {
            grid,
            boundary: VicBoundary::Unbounded,
        }
    }

    fn run(
        solver: &mut VortexInCell,
        x: &[[f64; 2]],
        g: &[f64],
        threads: &Threads,
    ) -> Vec<[f64; 2]> {
        let mut v = vec![[0.0; 2]; x.len()];
        solver.compute(x, g, &mut v, threads);
        v
    }

    /// `(sqrt(sum |a - b|^2 / sum |b|^2), max |a - b| / max |b|)`: the RMS and
    /// the largest error relative to the RMS and the peak speed.
    fn errors(a: &[[f64; 2]], b: &[[f64; 2]]) -> (f64, f64) {
        let (mut e2, mut b2) = (0.0, 0.0);
        let (mut worst, mut peak) = (0.0f64, 0.0f64);
        for (a, b) in a.iter().zip(b) {
            let e = (a[0] - b[0]).hypot(a[1] - b[1]);
            let s = b[0].hypot(b[1]);
            e2 += e * e;
            b2 += s * s;
            worst = worst.max(e);
            peak = peak.max(s);
        }
        ((e2 / b2).sqrt(), worst / peak)
    }

    /// The Gaussian vortex `w = exp(-|x|^2 / 0.1) / (0.1 pi)` on the lattice
    /// `h (i, j)`, `|h i|, |h j| <= 1.5`: positions and `Gamma = h^2 w`.
    fn gaussian_vortex(h: f64) -> (Vec<[f64; 2]>, Vec<f64>) {
        let half = (1.5 / h + 1e-9).floor() as i64;
        let mut x = Vec::new();
        let mut g = Vec::new();
        for i in -half..=half {
            for j in -half..=half {
                let p = [i as f64 * h, j as f64 * h];
                x.push(p);
                g.push(h * h * (-(p[0] * p[0] + p[1] * p[1]) / 0.1).exp() / (0.1 * PI));
            }
        }
        (x, g)
    }

    /// The unbounded VIC velocity of the Gaussian vortex on the lattice of
    /// spacing `h` with `sigma = 1.5 h`, against the direct sum.
    fn vortex_error(h: f64, grid: usize) -> (f64, f64, f64) {
        let (x, g) = gaussian_vortex(h);
        let kernel = BlobKernel::new(1.5 * h);
        let threads = Threads::single();
        let want = velocity_at(&kernel, &x, &x, &g, &threads);
        let mut vic = VortexInCell::new(unbounded(grid), kernel).unwrap();
        let got = run(&mut vic, &x, &g, &threads);
        let (rms, max) = errors(&got, &want);
        (vic.cell(), rms, max)
    }

    #[test]
    fn unbounded_gaussian_vortex_matches_the_direct_sum() {
        // h = 0.05 on grid 64: the cell is the rung 2^(-34/8) = 1.05 h, the
        // particles sit off the nodes; measured rms 2.4e-4, max 8.1e-4
        let (cell, rms, max) = vortex_error(0.05, 64);
        assert!(
            (cell - (-34.0f64 / 8.0).exp2()).abs() < 1e-15,
            "cell {cell}"
        );
        assert!(rms < 3e-4 && max < 1e-3, "rms {rms} max {max}");
        // a cell of about h / 2: measured 5.1e-5, 2.2e-4
        let (_, rms, max) = vortex_error(0.05, 128);
        assert!(rms < 1e-4 && max < 3e-4, "rms {rms} max {max}");
        // particles on the nodes: exact up to round-off
        let h = (-34.0f64 / 8.0).exp2();
        let (cell, rms, max) = vortex_error(h, 64);
        assert_eq!(cell, h);
        assert!(rms < 1e-12 && max < 1e-12, "rms {rms} max {max}");
    }

    /// Taylor-Green `psi = sin(k_x x) sin(k_y y)` on a periodic lattice of
    /// `side^2` particles offset by `shift` lattice spacings from the mesh nodes:
    /// the max error relative to the peak speed, against the exact blob velocity
    /// `exp(-k^2 sigma^2 / 2) (k_y sin(k_x x) cos(k_y y), -k_x cos(k_x x) sin(k_y y))`.
    fn taylor_green_error(grid: usize, side: usize, shift: [f64; 2]) -> f64 {
        let (origin, length) = ([-1.0, 0.5], 2.0);
        let params = VicParams {
            grid,
            boundary: VicBoundary::Periodic { origin, length },
        };
        let h = length / side as f64;
        let sigma = 1.5 * length / grid as f64;
        let k = [2.0, 3.0].map(|q| 2.0 * PI * q / length);
        let k2 = k[0] * k[0] + k[1] * k[1];
        let damp = (-0.5 * k2 * sigma * sigma).exp();
        let mut x = Vec::new();
        let mut g = Vec::new();
        let mut want = Vec::new();
        for i in 0..side {
            for j in 0..side {
                let p = [i as f64 + shift[0], j as f64 + shift[1]].map(|c| c * h);
                let (s, c) = (
                    [k[0] * p[0], k[1] * p[1]].map(f64::sin),
                    [k[0] * p[0], k[1] * p[1]].map(f64::cos),
                );
                x.push([origin[0] + p[0], origin[1] + p[1]]);
                g.push(h * h * k2 * s[0] * s[1]);
                want.push([damp * k[1] * s[0] * c[1], -damp * k[0] * c[0] * s[1]]);
            }
        }
        let mut vic = VortexInCell::new(params, BlobKernel::new(sigma)).unwrap();
        let got = run(&mut vic, &x, &g, &Threads::single());
        errors(&got, &want).1
    }

    #[test]
    fn periodic_taylor_green_matches_the_exact_velocity() {
        let on_nodes = taylor_green_error(64, 64, [0.0; 2]);
        assert!(on_nodes < 1e-12, "{on_nodes}");
        // measured 3.8e-4
        let off = taylor_green_error(64, 64, [0.37, 0.61]);
        assert!(off < 1e-3, "{off}");
    }

    #[test]
    fn one_and_two_threads_give_the_same_bits() {
        let mut rng = Rng::new(3);
        let n = 5000;
        let x: Vec<[f64; 2]> = (0..n).map(|_| [rng.normal(), 0.5 * rng.normal()]).collect();
        let g: Vec<f64> = (0..n).map(|_| rng.uniform() - 0.4).collect();
        let kernel = BlobKernel::new(0.05);
        let periodic = VicParams {
            grid: 64,
            boundary: VicBoundary::Periodic {
                origin: [-1.0, -1.5],
                length: 2.5,
            },
        };
        for params in [unbounded(64), periodic, unbounded(16)] {
            let mut vic = VortexInCell::new(params, kernel).unwrap();
            let one = run(&mut vic, &x, &g, &Threads::single());
            let two = run(&mut vic, &x, &g, &Threads::new(2).unwrap());
            assert_eq!(one, two, "{params:?}");
        }
    }

    #[test]
    fn ranks_sharing_the_mesh_match_one_process() {
        let mut rng = Rng::new(8);
        let n = 3000;
        let x: Vec<[f64; 2]> = (0..n).map(|_| [rng.normal(), 0.7 * rng.normal()]).collect();
        let g: Vec<f64> = (0..n).map(|_| rng.uniform() - 0.4).collect();
        let kernel = BlobKernel::new(0.08);
        let periodic = VicParams {
            grid: 32,
            boundary: VicBoundary::Periodic {
                origin: [-1.0, -1.5],
                length: 2.5,
            },
        };
        for params in [unbounded(32), periodic] {
            let mut vic = VortexInCell::new(params, kernel).unwrap();
            let want = run(&mut vic, &x, &g, &Threads::single());
            for ranks in [2, 3, 4] {
                let got = super::super::slab::testkit::Hub::run(ranks, |exchange| {
                    let mut vic =
                        VortexInCell::on_rank(params, kernel, Rank::of(exchange)).unwrap();
                    let mut v = vec![[0.0; 2]; n];
                    for _ in 0..2 {
                        vic.compute_shared(&x, &g, &mut v, &Threads::single(), exchange);
                    }
                    v
                });
                for (r, v) in got.iter().enumerate() {
                    assert_eq!(v, &want, "{params:?}: rank {r} of {ranks}");
                }
            }
        }
        let many = Rank {
            index: 0,
            count: 17,
        };
        let error = VortexInCell::on_rank(unbounded(16), kernel, many).unwrap_err();
        assert!(error.contains("17 ranks"), "{error}");
    }

    #[test]
    fn the_unbounded_spectra_are_the_sampled_kernels_transforms() {
        // grid 16, padded to M = 32: A_a(q) = -sum_o K_a(H o) sin(2 pi q.o / M) / M^2
        // summed term by term, against the spectra on 1 to 3 ranks (A_y read
        // off A_x's transposed and mirrored modes)
        let (grid, cell, kernel) = (16, 0.1, BlobKernel::new(0.15));
        let (m, h) = (32, 17);
        let sampled = |a: usize, i: usize, l: usize| {
            if i == m / 2 || l == m / 2 {
                return 0.0;
            }
            let d = [signed(i, m) * cell, signed(l, m) * cell];
            let f = kernel.factor(d[0] * d[0] + d[1] * d[1]);
            if a == 0 {
                -f * d[1]
            } else {
                f * d[0]
            }
        };
        let want: [Vec<f64>; 2] = std::array::from_fn(|a| {
            (0..m * h)
                .map(|mode| {
                    let (q0, q1) = (mode / h, mode % h);
                    let mut sum = 0.0;
                    for i in 0..m {
                        for l in 0..m {
                            let turns = ((q0 * i + q1 * l) % m) as f64 / m as f64;
                            sum -= sampled(a, i, l) * (2.0 * PI * turns).sin();
                        }
                    }
                    sum / (m * m) as f64
                })
                .collect()
        });
        let peak = want.iter().flatten().fold(0.0f64, |p, v| p.max(v.abs()));
        for ranks in [1, 2, 3] {
            let got = super::super::slab::testkit::Hub::run(ranks, |exchange| {
                let mut vic =
                    VortexInCell::on_rank(unbounded(grid), kernel, Rank::of(exchange)).unwrap();
                vic.unbounded_spectra(cell, &Threads::single(), exchange);
                (vic.slab.columns(), vic.spectra)
            });
            for (r, (cols, spectra)) in got.into_iter().enumerate() {
                for (a, (got, want)) in spectra.iter().zip(&want).enumerate() {
                    for (q0, row) in got.chunks(cols.len()).enumerate() {
                        for (v, c) in row.iter().zip(cols.clone()) {
                            let w = want[q0 * h + c];
                            assert!(
                                (v - w).abs() < 1e-12 * peak,
                                "A_{a}({q0}, {c}) on rank {r} of {ranks}: {v} against {w}"
                            );
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn the_kernel_follows_the_cell() {
        // one solver, clouds of different spreads: the unbounded kernel must be
        // re-made for each cell
        let mut rng = Rng::new(9);
        let kernel = BlobKernel::new(0.2);
        let threads = Threads::single();
        let mut vic = VortexInCell::new(unbounded(32), kernel).unwrap();
        let mut cells = Vec::new();
        for spread in [1.0, 4.0, 1.0] {
            let x: Vec<[f64; 2]> = (0..300)
                .map(|_| [spread * rng.normal(), spread * rng.normal()])
                .collect();
            let g: Vec<f64> = (0..300).map(|_| rng.uniform()).collect();
            let want = velocity_at(&kernel, &x, &x, &g, &threads);
            let got = run(&mut vic, &x, &g, &threads);
            // scattered particles, a cell of about sigma: a coarse check that the
            // kernel is the right one
            let (_, max) = errors(&got, &want);
            cells.push(vic.cell());
            assert!(max < 0.2, "spread {spread}: {max}");
        }
        assert!(
            cells[1] > 2.0 * cells[0] && cells[2] == cells[0],
            "{cells:?}"
        );
    }

    #[test]
    fn bad_parameters_are_refused() {
        let periodic = |origin, length| VicParams {
            grid: 32,
            boundary: VicBoundary::Periodic { origin, length },
        };
        let kernel = BlobKernel::new(0.1);
        let error = |params, kernel| VortexInCell::new(params, kernel).err().unwrap();
        assert_eq!(
            error(unbounded(100), kernel),
            "grid must be a power of two in 16..=4096, got 100"
        );
        for grid in [0, 8, 8192] {
            assert!(error(unbounded(grid), kernel).contains("grid"));
        }
        for length in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            assert_eq!(
                error(periodic([0.0; 2], length), kernel),
                format!("length must be finite and > 0, got {length}")
            );
        }
        assert!(error(periodic([f64::NAN, 0.0], 1.0), kernel).contains("origin"));
        for sigma in [0.0, -0.1, f64::NAN] {
            assert!(error(unbounded(16), BlobKernel::new(sigma)).contains("sigma"));
        }
        assert!(VortexInCell::new(periodic([0.0; 2], 1.0), kernel).is_ok());
        // no particles: nothing to do
        let mut vic = VortexInCell::new(unbounded(16), kernel).unwrap();
        vic.compute(&[], &[], &mut [], &Threads::single());
        assert_eq!(vic.cell(), 0.0);
    }

    /// Prints the unbounded Gaussian vortex's errors against grid and lattice, the
    /// periodic Taylor-Green's, and the time of one evaluation for 10^5 and 10^6
    /// particles. Run with
    /// `cargo test --release -p cellist --lib study_vic -- --ignored --nocapture`.
    #[test]
    #[ignore]
    fn study_vic() {
        println!("unbounded Gaussian vortex, sigma = 1.5 h:");
        println!("h        grid  cell/h  rms       max/peak");
        let on_rung = (-34.0f64 / 8.0).exp2();
        for (h, grid) in [
            (0.05, 64),
            (0.05, 128),
            (0.05, 256),
            (on_rung, 64),
            (on_rung, 128),
            (0.1, 32),
            (0.1, 64),
        ] {
            let (cell, rms, max) = vortex_error(h, grid);
            println!("{h:.5}  {grid:4}  {:.3}   {rms:.2e}  {max:.2e}", cell / h);
        }
        println!("periodic Taylor-Green (2, 3), max error / peak:");
        for (grid, side, shift) in [
            (64, 64, [0.0, 0.0]),
            (64, 64, [0.37, 0.61]),
            (64, 64, [0.5, 0.5]),
            (64, 100, [0.37, 0.61]),
            (128, 128, [0.37, 0.61]),
            (32, 32, [0.37, 0.61]),
        ] {
            let e = taylor_green_error(grid, side, shift);
            println!("grid {grid} particles {side}^2 shift {shift:?}: {e:.2e}");
        }
        // timings: the first call (with the kernel's transform), then the
        // fastest of 5, and the phases of the fastest of 5 each
        let configs = [
            (100_000, 256),
            (100_000, 512),
            (1_000_000, 1024),
            (1_000_000, 2048),
        ];
        for (n, grid) in configs {
            let mut rng = Rng::new(1);
            let x: Vec<[f64; 2]> = (0..n).map(|_| [rng.normal(), rng.normal()]).collect();
            let g: Vec<f64> = (0..n).map(|_| rng.uniform() - 0.5).collect();
            for threads in [Threads::single(), Threads::new(2).unwrap()] {
                let mut vic = VortexInCell::new(unbounded(grid), BlobKernel::new(0.01)).unwrap();
                let mut v = vec![[0.0; 2]; n];
                let t = std::time::Instant::now();
                vic.compute(&x, &g, &mut v, &threads);
                let first = t.elapsed().as_secs_f64();
                let mut best = f64::INFINITY;
                let mut phases = [f64::INFINITY; 5];
                for _ in 0..5 {
                    let t = std::time::Instant::now();
                    vic.compute(&x, &g, &mut v, &threads);
                    best = best.min(t.elapsed().as_secs_f64());
                    let mut lap = std::time::Instant::now();
                    let mut time = |k: usize| {
                        phases[k] = phases[k].min(lap.elapsed().as_secs_f64());
                        lap = std::time::Instant::now();
                    };
                    vic.cover(&x, &threads, &Alone);
                    time(0);
                    threads.install(|| vic.sort(&x, &g));
                    time(1);
                    threads.install(|| vic.assign());
                    time(2);
                    vic.solve(&threads, &Alone);
                    time(3);
                    vic.interpolate(&mut v, &threads, &Alone);
                    time(4);
                }
                let [cover, sort, assign, solve, interpolate] = phases;
                println!(
                    "{n} particles, grid {grid}, {} thread(s): first {first:.3}s, then {best:.3}s \
                     (cover {cover:.3} sort {sort:.3} assign {assign:.3} solve {solve:.3} \
                     interpolate {interpolate:.3})",
                    threads.count()
                );
            }
        }
    }
}
