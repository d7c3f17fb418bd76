//! Particle-mesh gravity: cloud-in-cell masses on a `grid^3` mesh (module `cic`), the
//! potential and acceleration as Fourier-space products with the Green's function
//! (modules `green`, `fft`), read back at the particles with the same weights.
//!
//! Interlaced (Hockney and Eastwood): the result is the mean of two meshes whose
//! nodes are offset by half a cell along every axis. This cancels most of
//! cloud-in-cell's dependence on where a particle sits in its cell, which is the
//! dominant error of a pair force beyond a cell (4 to 5 times smaller), for
//! twice the transforms.
//!
//! The acceleration is differentiated exactly, not by finite differences: its
//! Green's function is the gradient of the potential's (`A_a = -k_a P` periodic,
//! the transform of the real-space `-k(r) d_a` isolated), so the only errors are
//! those of cloud-in-cell assignment and interpolation. This costs four inverse
//! transforms (phi and three accelerations) instead of one.
//!
//! Isolated meshes are zero-padded to `(2 grid)^3` (Hockney and Eastwood) and cover
//! the particles' bounding cube, whose cell is rounded up to the ladder
//! `h = 2^(j/8)` so that the transformed Green's function, re-made only when `j`
//! changes, is usually reused.

mod cic;
mod fft;
pub(crate) mod green;
mod m4;
pub(crate) mod route;
pub mod slab;
#[cfg(test)]
pub(crate) mod testkit;
pub mod vic;
pub mod vic3;

pub use slab::{Alone, Exchange, Peers, Rank};
pub use vic::{VicBoundary, VicParams, VortexInCell, MAX_VIC_GRID, MIN_VIC_GRID};
pub use vic3::{Vic3Boundary, Vic3Params, VortexInCell3, MAX_VIC3_GRID, MIN_VIC3_GRID};

use super::{FieldOut, Sources};
use crate::interactions::GravityLaw;
use crate::threads::Threads;
use cic::Geometry;
use fft::Fft3;
use green::{Reach, Spectra};
use rayon::prelude::*;
use route::{mesh_place, Arrived, Route};
use rustfft::num_complex::Complex;
use slab::Slab;

/// The largest grid accepted.
pub const MAX_GRID: usize = 256;

/// The mesh's boundary.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum MeshBoundary {
    /// Open space: the mesh covers the particles' bounding cube, zero-padded to
    /// twice its side so that the cyclic convolution is the open one.
    Isolated,
    /// The periodic cube `[origin, origin + length)^3`: every particle interacts
    /// with all images of the others, against a uniform background of the mean
    /// density (the `k = 0` mode is zero).
    Periodic {
        /// The box's lower corner.
        origin: [f64; 3],
        /// The box's side.
        length: f64,
    },
}

/// A mesh solver's settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MeshParams {
    /// Mesh nodes per axis: a power of two in `8..=MAX_GRID`.
    pub grid: usize,
    /// The boundary.
    pub boundary: MeshBoundary,
}

impl MeshParams {
    /// Checks the grid and the periodic box.
    fn check(&self) -> Result<(), String> {
        if !(self.grid >= 8 && self.grid.is_power_of_two()) {
            return Err(format!(
                "grid must be a power of two >= 8, got {}",
                self.grid
            ));
        }
        if self.grid > MAX_GRID {
            return Err(format!(
                "grid must be at most {MAX_GRID}, got {} (an isolated mesh is padded to \
                 (2 grid)^3: grid 256 already takes about 4.5 GB)",
                self.grid
            ));
        }
        if let MeshBoundary::Periodic { origin, length } = self.boundary {
            if !(length.is_finite() && length > 0.0) {
                return Err(format!("length must be finite and > 0, got {length}"));
            }
            if origin.iter().any(|c| !c.is_finite()) {
                return Err(format!("origin must be finite, got {origin:?}"));
            }
        }
        Ok(())
    }
}

/// The law's check shared by the mesh solvers.
fn check_law(law: &GravityLaw) -> Result<(), String> {
    if law.has_repulsion() {
        return Err(
            "repulsion_radius is only supported by the direct and barnes-hut solvers".into(),
        );
    }
    Ok(())
}

/// Ladder rungs per factor 2 of the isolated cell size.
const RUNGS: f64 = 8.0;

/// `out = K F` (the potential) or `out = i K F` (`derivative`: a gradient or
/// curl, whose kernel `K` is the Green's function's derivative over `i`),
/// mode by mode.
pub(crate) fn apply_kernel(
    out: &mut [Complex<f64>],
    hat: &[Complex<f64>],
    kernel: &[f64],
    derivative: bool,
) {
    apply_kernels(out, &[(1.0, hat, kernel)], derivative);
}

/// One term `(s, F, K)` of [`apply_kernels`]: a factor, a transformed mesh
/// and a kernel.
pub(crate) type Term<'a> = (f64, &'a [Complex<f64>], &'a [f64]);

/// `out = sum_t s_t K_t F_t`, or `i` times that (`derivative`), mode by mode,
/// over the terms `(s_t, F_t, K_t)` (at least one) in order; one term gives
/// the bits of `K F` (`s = 1`).
pub(crate) fn apply_kernels(out: &mut [Complex<f64>], terms: &[Term], derivative: bool) {
    const CHUNK: usize = 1024;
    out.par_chunks_mut(CHUNK)
        .enumerate()
        .for_each(|(chunk, w)| {
            let at = chunk * CHUNK;
            let term = |&(s, f, k): &Term, i: usize| f[i] * k[i] * s;
            for (i, w) in (at..).zip(w.iter_mut()) {
                let mut sum = term(&terms[0], i);
                for t in &terms[1..] {
                    sum += term(t, i);
                }
                *w = if derivative {
                    Complex::new(-sum.im, sum.re)
                } else {
                    sum
                };
            }
        });
}

/// The mesh machinery shared by [`ParticleMesh`] and [`super::P3m`]: its
/// geometry, transforms, Green's function and buffers, on one rank's slab
/// of planes along axis 0 (module `slab`; every plane in one process).
pub(crate) struct MeshSolver {
    law: GravityLaw,
    params: MeshParams,
    reach: Reach,
    geometry: Geometry,
    /// The ladder rung the isolated spectra were made for.
    rung: Option<i64>,
    slab: Slab<Fft3>,
    spectra: Spectra,
    /// Cloud-in-cell masses on this rank's planes, `grid^2` each.
    mass: Vec<f64>,
    /// This rank's columns of the transformed masses, and of a product being
    /// inverted.
    masses_hat: Vec<Complex<f64>>,
    work: Vec<Complex<f64>>,
    /// phi and acc_x, acc_y, acc_z on this rank's planes and the one above,
    /// `grid^2` each.
    fields: [Vec<f64>; 4],
    /// `(acc, phi)` of every particle on one of the interlaced meshes.
    got: Vec<[f64; 4]>,
    /// The particles routed to this rank from every rank's part (on several
    /// ranks), and the routing's buffers.
    arrived: Arrived<2>,
    route: Route<2>,
}

impl MeshSolver {
    /// `name { params, cell }` for `Debug` (the FFT plans have none).
    pub(crate) fn describe(&self, f: &mut std::fmt::Formatter<'_>, name: &str) -> std::fmt::Result {
        f.debug_struct(name)
            .field("params", &self.params)
            .field("cell", &self.cell())
            .field("rank", &self.slab.rank())
            .finish_non_exhaustive()
    }

    /// The solver for `law` carrying `reach` of it, on `rank`'s slab.
    pub(crate) fn new(
        law: GravityLaw,
        params: MeshParams,
        reach: Reach,
        rank: Rank,
    ) -> Result<Self, String> {
        params.check()?;
        check_law(&law)?;
        let n = params.grid;
        rank.check(n)?;
        let (side, geometry) = match params.boundary {
            MeshBoundary::Isolated => (
                2 * n,
                Geometry {
                    origin: [0.0; 3],
                    cell: 0.0,
                    grid: n,
                    periodic: false,
                },
            ),
            MeshBoundary::Periodic { origin, length } => (
                n,
                Geometry {
                    origin,
                    cell: length / n as f64,
                    grid: n,
                    periodic: true,
                },
            ),
        };
        let slab = Slab::new(Fft3::new(side), rank);
        let len = slab.lines_len();
        let mut spectra = Spectra::new(len);
        if let MeshBoundary::Periodic { length, .. } = params.boundary {
            spectra.periodic(&law, reach, length, n, slab.columns());
        }
        let plane = n * n;
        let (owned, window) = (slab.owned(n).len(), slab.window(n, 0, 1).count());
        Ok(MeshSolver {
            law,
            params,
            reach,
            geometry,
            rung: None,
            slab,
            spectra,
            mass: vec![0.0; owned * plane],
            masses_hat: vec![Complex::default(); len],
            work: vec![Complex::default(); len],
            fields: std::array::from_fn(|_| vec![0.0; window * plane]),
            got: Vec::new(),
            arrived: Arrived::default(),
            route: Route::default(),
        })
    }

    /// The law.
    pub(crate) fn law(&self) -> &GravityLaw {
        &self.law
    }

    /// The settings.
    pub(crate) fn params(&self) -> &MeshParams {
        &self.params
    }

    /// This rank's place.
    pub(crate) fn rank(&self) -> Rank {
        self.slab.rank()
    }

    /// The cell side `h` of the last (isolated) or every (periodic) evaluation.
    pub(crate) fn cell(&self) -> f64 {
        self.geometry.cell
    }

    /// Places an isolated mesh over the box `(lo, hi)` of the particles: the
    /// cell is the smallest ladder rung `2^(j/8) >= extent / (grid - 3)` and
    /// the mesh is centred on the box, so every particle is at least a cell
    /// inside it (half a cell on the interlaced mesh). The Green's function is
    /// re-made when the rung changes.
    fn cover(
        &mut self,
        (lo, hi): ([f64; 3], [f64; 3]),
        threads: &Threads,
        exchange: &dyn Exchange,
    ) {
        let extent = (0..3).map(|a| hi[a] - lo[a]).fold(0.0, f64::max);
        let n = self.params.grid;
        let floor = self.law.softening().max(f64::MIN_POSITIVE.sqrt());
        let need = extent.max(floor) / (n - 3) as f64;
        let mut rung = (RUNGS * need.log2()).ceil() as i64;
        if (rung as f64 / RUNGS).exp2() < need {
            rung += 1;
        }
        let cell = (rung as f64 / RUNGS).exp2();
        let half = cell * (n - 1) as f64 / 2.0;
        self.geometry.origin = std::array::from_fn(|a| 0.5 * (lo[a] + hi[a]) - half);
        self.geometry.cell = cell;
        if self.rung != Some(rung) {
            let MeshSolver {
                law,
                reach,
                slab,
                spectra,
                work,
                ..
            } = self;
            spectra.isolated(law, *reach, cell, slab, work, exchange, threads);
            self.rung = Some(rung);
        }
    }

    /// Places the mesh for every rank's `positions` (collective on several
    /// ranks), re-covering them on an isolated mesh; [`MeshSolver::solve`]
    /// then uses this geometry. The box of the particles, or `None` and
    /// nothing placed when there are fewer than two in all (no field).
    pub(crate) fn place(
        &mut self,
        positions: &[[f64; 3]],
        threads: &Threads,
        exchange: &dyn Exchange,
    ) -> Option<([f64; 3], [f64; 3])> {
        let (bounds, count) = slab::extent(positions, exchange);
        if count < 2 {
            return None;
        }
        if self.params.boundary == MeshBoundary::Isolated {
            self.cover(bounds, threads, exchange);
        }
        Some(bounds)
    }

    /// Writes the mesh's `acc_i` and `phi_i` (own cloud removed) of `sources` to
    /// `out`, for the geometry of the last [`MeshSolver::place`]. On several
    /// ranks, `sources` and `out` are this rank's own part of the particles,
    /// the parts following each other in rank order: the particles travel to
    /// the ranks whose planes their stencils touch and their results back
    /// (module `route`). Each rank assigns the masses to its planes (the
    /// particles in input order, so that each node sums in the order of one
    /// process) and interpolates the particles whose stencil's lower plane it
    /// holds.
    pub(crate) fn solve(
        &mut self,
        sources: &Sources,
        out: FieldOut,
        threads: &Threads,
        exchange: &dyn Exchange,
    ) {
        let n = self.geometry.grid;
        let half = 0.5 * self.geometry.cell;
        let rank = self.slab.rank();
        let owned = self.slab.owned_window(n);
        let window = self.slab.window(n, 0, 1);
        // the two interlaced meshes: the second's nodes are half a cell lower
        let mut lower = self.geometry;
        lower.origin = lower.origin.map(|o| o - half);
        let geometries = [self.geometry, lower];
        let routing = rank.count > 1;
        let mut arrived = std::mem::take(&mut self.arrived);
        if routing {
            self.route.forward(
                sources.position,
                sources.mass,
                exchange,
                &mut arrived,
                |x| mesh_place(x, &geometries, rank.count),
            );
        }
        let (position, mass) = if routing {
            (&arrived.position[..], &arrived.mass[..])
        } else {
            (sources.position, sources.mass)
        };
        self.got.resize(sources.mass.len(), [0.0; 4]);
        for (pass, geometry) in geometries.iter().enumerate() {
            self.mass.fill(0.0);
            for (x, &m) in position.iter().zip(mass) {
                geometry
                    .stencil(x)
                    .each(n, owned, |k, w| self.mass[k] += w * m);
            }
            self.transform(threads, exchange);
            let fields = &self.fields;
            let own = &self.spectra.own;
            let value = |x: &[f64; 3], m: f64| {
                let stencil = geometry.stencil(x);
                let mut sum = [0.0; 4];
                stencil.each(n, window, |k, w| {
                    for (s, f) in sum.iter_mut().zip(fields) {
                        *s += w * f[k];
                    }
                });
                [sum[1], sum[2], sum[3], sum[0] - m * stencil.own(own)]
            };
            if routing {
                self.route.back(
                    &arrived,
                    pass,
                    exchange,
                    &mut self.got,
                    |i| value(&position[i], mass[i]),
                    threads,
                );
            } else {
                threads.install(|| {
                    self.got
                        .par_iter_mut()
                        .enumerate()
                        .for_each(|(i, g)| *g = value(&position[i], mass[i]))
                });
            }
            let got = &self.got;
            threads.install(|| {
                out.acc
                    .par_iter_mut()
                    .zip(out.phi.par_iter_mut())
                    .zip(got.par_iter())
                    .for_each(|((acc, phi), got)| {
                        if pass == 0 {
                            *acc = [0.5 * got[0], 0.5 * got[1], 0.5 * got[2]];
                            *phi = 0.5 * got[3];
                        } else {
                            for a in 0..3 {
                                acc[a] += 0.5 * got[a];
                            }
                            *phi += 0.5 * got[3];
                        }
                    });
            });
        }
        self.arrived = arrived;
    }

    /// The mesh fields from the mesh masses: `phi = IFFT(P FFT(mass))` and
    /// `acc_a = IFFT(i A_a FFT(mass))`, on this rank's window of planes.
    fn transform(&mut self, threads: &Threads, exchange: &dyn Exchange) {
        let n = self.geometry.grid;
        let MeshSolver {
            slab,
            mass,
            masses_hat,
            work,
            fields,
            spectra,
            ..
        } = self;
        let first = slab.owned(n).start;
        slab.forward(
            n,
            masses_hat,
            |i, j, row| row.copy_from_slice(&mass[((i - first) * n + j) * n..][..n]),
            exchange,
            threads,
        );
        for (q, field) in fields.iter_mut().enumerate() {
            let kernel = match q {
                0 => &spectra.phi,
                a => &spectra.acc[a - 1],
            };
            // P F for phi, i A_a F for acc_a
            threads.install(|| apply_kernel(work, masses_hat, kernel, q != 0));
            slab.inverse(n, work, field, (0, 1), exchange, threads);
        }
    }
}

/// The particle-mesh solver: `acc_i` and `phi_i` of the law's softened gravity
/// (without repulsion), smoothed on the scale of the mesh cell.
///
/// Isolated: `phi(x) = sum_y g(x - y) m(y)` over the cloud-in-cell mesh masses
/// `m(y)`, with `g(d) = -G / sqrt(|d|^2 + eps^2)` (at `d = 0` the larger of
/// `-G / eps` and the cell average `-2.3800772 G / h`), and `acc = sum_y -G d / (|d|^2 + eps^2)^(3/2)
/// m(y)`, by FFT on the zero-padded mesh. Periodic: `hat phi(k) = -4 pi G / k^2
/// hat rho(k)` and `hat acc = -i k hat phi` (the softening is not applied: the
/// mesh cell smooths more). Both are averaged over two meshes offset by half a
/// cell (interlacing). Each particle's own cloud is removed from `phi_i`
/// (periodic: with it the constant `m_i xi` of its own images and background).
pub struct ParticleMesh {
    solver: MeshSolver,
}

impl std::fmt::Debug for ParticleMesh {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        self.solver.describe(f, "ParticleMesh")
    }
}

impl ParticleMesh {
    /// The solver for `law` with `params`; refuses a law with repulsion, a grid
    /// that is not a power of two `>= 8`, a bad periodic box.
    pub fn new(law: GravityLaw, params: MeshParams) -> Result<Self, String> {
        Self::on_rank(law, params, Rank::ALONE)
    }

    /// The solver on `rank`'s slab of a mesh shared by several ranks, each of
    /// which holds its own part of the particles
    /// ([`ParticleMesh::compute_spread`]); refuses what [`ParticleMesh::new`] refuses and
    /// more ranks than the grid has planes.
    pub fn on_rank(law: GravityLaw, params: MeshParams, rank: Rank) -> Result<Self, String> {
        Ok(ParticleMesh {
            solver: MeshSolver::new(law, params, Reach::Full, rank)?,
        })
    }

    /// The mesh cell `h` of the last evaluation (isolated) or of the box
    /// (periodic).
    pub fn cell(&self) -> f64 {
        self.solver.cell()
    }

    /// Fills `out` with the mesh's accelerations and potentials of `sources`.
    pub fn compute(&mut self, sources: &Sources, out: FieldOut, threads: &Threads) {
        self.compute_spread(sources, out, threads, &Alone);
    }

    /// [`ParticleMesh::compute`] on the ranks of `exchange`, the particles
    /// divided among them: every rank calls it with its own part of them
    /// (`sources`), the parts following each other in rank order, and gets
    /// its own particles' results in `out`. Each rank transforms its slab of
    /// the mesh; the particles travel to the slabs their stencils touch and
    /// their results back (module `route`): the accelerations of one process
    /// bit for bit, the potentials to rounding on an isolated mesh (the
    /// own-cloud kernel's sum over the modes is split among the ranks).
    pub fn compute_spread(
        &mut self,
        sources: &Sources,
        out: FieldOut,
        threads: &Threads,
        exchange: &dyn Exchange,
    ) {
        assert_eq!(
            Rank::of(exchange),
            self.solver.rank(),
            "the exchange's ranks"
        );
        if self
            .solver
            .place(sources.position, threads, exchange)
            .is_none()
        {
            out.acc.fill([0.0; 3]);
            out.phi.fill(0.0);
            return;
        }
        self.solver.solve(sources, out, threads, exchange);
    }
}

#[cfg(test)]
mod tests {
    use super::testkit::{cloud, direct, gaussian, pair_error, rms_relative, run, Field};
    use super::*;
    use crate::longrange::P3m;

    fn isolated(grid: usize) -> MeshParams {
        MeshParams {
            grid,
            boundary: MeshBoundary::Isolated,
        }
    }

    fn law() -> GravityLaw {
        GravityLaw::new(1.3, 0.05, 0.0).unwrap()
    }

    fn pm(params: MeshParams, m: &[f64], x: &[[f64; 3]], threads: &Threads) -> Field {
        let mut solver = ParticleMesh::new(law(), params).unwrap();
        run(m, x, |s, o| solver.compute(s, o, threads))
    }

    #[test]
    fn pair_force_is_accurate_beyond_a_few_cells() {
        let mut solver = ParticleMesh::new(law(), isolated(32)).unwrap();
        let threads = Threads::single();
        let mut error =
            |sep| pair_error(law(), 32, sep, 20, 7, |s, o| solver.compute(s, o, &threads));
        // the mesh smooths the force away below a cell
        assert!(error(0.5).0 > 0.5);
        // beyond, what interlacing leaves of the cloud-in-cell anisotropy, about
        // 0.1 / sep^2; measured (5.5e-3, 8.9e-3), (1.6e-3, 3.0e-3), (6.1e-4, 1.3e-3)
        let bounds = [(4.0, 8e-3, 1.5e-2), (8.0, 2.5e-3, 5e-3), (12.0, 1e-3, 2e-3)];
        for (sep, rms, max) in bounds {
            let (got_rms, got_max) = error(sep);
            assert!(
                got_rms < rms && got_max < max,
                "sep {sep}: {got_rms} {got_max}"
            );
        }
    }

    #[test]
    fn cloud_error_against_the_direct_sum() {
        let (m, x) = cloud(2000, 1.0, [0.0; 3], 11);
        let (want_acc, want_phi) = direct(law(), &m, &x);
        let (acc, phi) = pm(isolated(32), &m, &x, &Threads::single());
        let rms = rms_relative(&acc, &want_acc);
        // measured 0.52: half the particles sit in clumps smaller than a cell,
        // whose inner forces the mesh smooths away
        assert!(rms < 0.6, "rms {rms}");
        let phi_rms = rms_relative(
            &phi.iter().map(|p| [*p, 0.0, 0.0]).collect::<Vec<_>>(),
            &want_phi.iter().map(|p| [*p, 0.0, 0.0]).collect::<Vec<_>>(),
        );
        assert!(phi_rms < 0.1, "phi rms {phi_rms}");
    }

    #[test]
    fn isolated_mesh_follows_a_translated_cloud() {
        let (m, x) = cloud(500, 1.0, [0.0; 3], 2);
        let shifted: Vec<[f64; 3]> = x.iter().map(|p| p.map(|c| c + 123.456)).collect();
        let threads = Threads::single();
        let mut solver = ParticleMesh::new(law(), isolated(16)).unwrap();
        let (a, _) = run(&m, &x, |s, o| solver.compute(s, o, &threads));
        let (b, _) = run(&m, &shifted, |s, o| solver.compute(s, o, &threads));
        let rms = rms_relative(&b, &a);
        assert!(rms < 1e-9, "rms {rms}");
    }

    #[test]
    fn periodic_net_force_vanishes_and_a_lattice_feels_none() {
        let length = 3.0;
        let params = MeshParams {
            grid: 16,
            boundary: MeshBoundary::Periodic {
                origin: [-1.0, -1.0, -1.0],
                length,
            },
        };
        let threads = Threads::single();
        let (m, x) = cloud(1000, 0.7, [0.2; 3], 4);
        let mut p3m = P3m::new(law(), params, 1.25).unwrap();
        for (name, (acc, _)) in [
            ("pm", pm(params, &m, &x, &threads)),
            ("p3m", run(&m, &x, |s, o| p3m.compute(s, o, &threads))),
        ] {
            for a in 0..3 {
                let total: f64 = (0..m.len()).map(|i| m[i] * acc[i][a]).sum();
                let scale: f64 = (0..m.len()).map(|i| (m[i] * acc[i][a]).abs()).sum();
                assert!(
                    total.abs() < 1e-12 * scale,
                    "{name} axis {a}: {total} of {scale}"
                );
            }
        }
        // an 8^3 lattice, off the mesh nodes
        let side = 8;
        let x: Vec<[f64; 3]> = (0..side * side * side)
            .map(|k| {
                let idx = [k / (side * side), k / side % side, k % side];
                idx.map(|i| -1.0 + (i as f64 + 0.3) * length / side as f64)
            })
            .collect();
        let m = vec![1.0; x.len()];
        // a neighbour's pull, G m / spacing^2, sets the scale
        let scale = 1.3 / (length / side as f64).powi(2);
        let mut p3m = P3m::new(law(), params, 1.25).unwrap();
        for (name, (acc, _)) in [
            ("pm", pm(params, &m, &x, &threads)),
            ("p3m", run(&m, &x, |s, o| p3m.compute(s, o, &threads))),
        ] {
            let worst = acc.iter().flatten().fold(0.0f64, |w, v| w.max(v.abs()));
            assert!(worst < 1e-10 * scale, "{name}: {worst}");
        }
    }

    #[test]
    fn one_and_two_threads_give_the_same_bits() {
        let (m, x) = cloud(700, 1.0, [0.3; 3], 8);
        let periodic = MeshParams {
            grid: 16,
            boundary: MeshBoundary::Periodic {
                origin: [-2.0; 3],
                length: 4.0,
            },
        };
        for params in [isolated(16), periodic] {
            let one = Threads::single();
            let two = Threads::new(2).unwrap();
            let a = pm(params, &m, &x, &one);
            let b = pm(params, &m, &x, &two);
            assert_eq!(format!("{a:?}"), format!("{b:?}"));
            let mut p3m = P3m::new(law(), params, 1.25).unwrap();
            let a = run(&m, &x, |s, o| p3m.compute(s, o, &one));
            let b = run(&m, &x, |s, o| p3m.compute(s, o, &two));
            assert_eq!(format!("{a:?}"), format!("{b:?}"));
        }
    }

    /// PM and P3M of `(m, x)` on `ranks` thread-ranks ([`slab::testkit::Hub`]),
    /// the particles divided among the ranks: each rank's results joined in
    /// rank order.
    fn shared(params: MeshParams, m: &[f64], x: &[[f64; 3]], ranks: usize) -> (Field, Field) {
        let parts = slab::testkit::Hub::run(ranks, |exchange| {
            let rank = Rank::of(exchange);
            let threads = Threads::single();
            let mut pm = ParticleMesh::on_rank(law(), params, rank).unwrap();
            let mut p3m = P3m::on_rank(law(), params, 1.25, rank).unwrap();
            let own = slab::part(m.len(), rank.index, ranks);
            let (m, x) = (&m[own.clone()], &x[own]);
            // twice: the second call reuses the Green's function
            let mut run_both = || {
                (
                    run(m, x, |s, o| pm.compute_spread(s, o, &threads, exchange)),
                    run(m, x, |s, o| p3m.compute_spread(s, o, &threads, exchange)),
                )
            };
            run_both();
            run_both()
        });
        let join = |fields: Vec<&Field>| -> Field {
            let acc = fields.iter().flat_map(|f| f.0.clone()).collect();
            let phi = fields.iter().flat_map(|f| f.1.clone()).collect();
            (acc, phi)
        };
        (
            join(parts.iter().map(|p| &p.0).collect()),
            join(parts.iter().map(|p| &p.1).collect()),
        )
    }

    /// `a` and `b` have the same accelerations, bit for bit, and potentials
    /// within `tolerance` of the largest.
    fn same_field(a: &Field, b: &Field, tolerance: f64, what: &str) {
        assert_eq!(a.0, b.0, "{what}: accelerations");
        let scale = b.1.iter().fold(0.0f64, |s, p| s.max(p.abs()));
        for (p, q) in a.1.iter().zip(&b.1) {
            assert!(
                (p - q).abs() <= tolerance * scale,
                "{what}: phi {p} against {q}"
            );
        }
    }

    #[test]
    fn ranks_sharing_the_mesh_match_one_process() {
        let (m, x) = cloud(600, 1.0, [0.3; 3], 21);
        let periodic = MeshParams {
            grid: 16,
            boundary: MeshBoundary::Periodic {
                origin: [-2.0; 3],
                length: 4.0,
            },
        };
        // P3M's cell list: 3 planes along x (isolated), 4 (periodic: every
        // plane within reach of every other) and 9 (fine: slabs and halos)
        let fine = MeshParams {
            grid: 32,
            ..periodic
        };
        let threads = Threads::single();
        for params in [isolated(16), periodic, fine] {
            let want_pm = pm(params, &m, &x, &threads);
            let mut p3m = P3m::new(law(), params, 1.25).unwrap();
            let want_p3m = run(&m, &x, |s, o| p3m.compute(s, o, &threads));
            // the periodic own kernel is summed over every mode on every rank,
            // the isolated one over each rank's modes, then over the ranks
            let tolerance = match params.boundary {
                MeshBoundary::Periodic { .. } => 0.0,
                MeshBoundary::Isolated => 1e-14,
            };
            for ranks in [2, 3, 4] {
                let (got_pm, got_p3m) = shared(params, &m, &x, ranks);
                let what = format!("{params:?} on {ranks} ranks");
                same_field(&got_pm, &want_pm, tolerance, &format!("pm {what}"));
                same_field(&got_p3m, &want_p3m, tolerance, &format!("p3m {what}"));
            }
        }
    }

    #[test]
    fn ranks_without_particles_match_one_process() {
        let threads = Threads::single();
        // 3 particles on 4 ranks (one rank holds none), 1 on 2 (no field), and
        // 300 on 8 ranks of one plane each (a particle's clouds on 3 ranks)
        for (count, ranks, grid) in [(3, 2, 16), (3, 4, 16), (1, 2, 16), (1, 4, 16), (300, 8, 8)] {
            let params = isolated(grid);
            let (m, x) = cloud(count, 1.0, [0.3; 3], 5);
            let want_pm = pm(params, &m, &x, &threads);
            let mut p3m = P3m::new(law(), params, 1.25).unwrap();
            let want_p3m = run(&m, &x, |s, o| p3m.compute(s, o, &threads));
            let (got_pm, got_p3m) = shared(params, &m, &x, ranks);
            let what = format!("{count} on {ranks} ranks, grid {grid}");
            same_field(&got_pm, &want_pm, 1e-13, &format!("pm, {what}"));
            same_field(&got_p3m, &want_p3m, 1e-13, &format!("p3m, {what}"));
        }
    }

    #[test]
    fn more_ranks_than_planes_are_refused() {
        let rank = Rank { index: 0, count: 9 };
        let error = ParticleMesh::on_rank(law(), isolated(8), rank).unwrap_err();
        assert!(
            error.contains("9 ranks") && error.contains("8 planes"),
            "{error}"
        );
        assert!(P3m::on_rank(law(), isolated(8), 1.25, rank).is_err());
        assert!(ParticleMesh::on_rank(law(), isolated(16), rank).is_ok());
    }

    #[test]
    fn bad_parameters_are_refused() {
        let periodic = |origin, length| MeshParams {
            grid: 16,
            boundary: MeshBoundary::Periodic { origin, length },
        };
        let error = |law, params| ParticleMesh::new(law, params).err().unwrap();
        assert_eq!(
            error(law(), isolated(100)),
            "grid must be a power of two >= 8, got 100"
        );
        assert!(error(law(), isolated(4)).contains("grid"));
        let repulsive = GravityLaw::new(1.0, 0.0, 0.1).unwrap();
        assert!(error(repulsive, isolated(16)).contains("repulsion_radius"));
        for length in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            assert!(error(law(), periodic([0.0; 3], length)).contains("length"));
        }
        assert!(error(law(), periodic([f64::NAN, 0.0, 0.0], 1.0)).contains("origin"));
        assert!(ParticleMesh::new(law(), periodic([0.0; 3], 1.0)).is_ok());
    }

    /// Prints the pair force's relative error against separation in cells on a
    /// 64 mesh. Run with
    /// `cargo test --release -p cellist --lib study_pair -- --ignored --nocapture`.
    #[test]
    #[ignore]
    fn study_pair_error() {
        let law = law();
        let threads = Threads::single();
        let split = crate::longrange::p3m::SPLIT_CELLS;
        let mut pm = ParticleMesh::new(law, isolated(64)).unwrap();
        let mut p3m = P3m::new(law, isolated(64), split).unwrap();
        let mut wide = P3m::new(law, isolated(64), 2.0).unwrap();
        println!("sep  pm_rms pm_max  p3m_rms p3m_max  p3m(split 2)_rms max");
        for sep in [
            0.25, 0.5, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 6.8, 7.0, 8.0, 12.0, 16.0, 24.0,
        ] {
            let a = pair_error(law, 64, sep, 20, 1, |s, o| pm.compute(s, o, &threads));
            let b = pair_error(law, 64, sep, 20, 1, |s, o| p3m.compute(s, o, &threads));
            let c = pair_error(law, 64, sep, 20, 1, |s, o| wide.compute(s, o, &threads));
            println!(
                "{sep:5} {:.2e} {:.2e}  {:.2e} {:.2e}  {:.2e} {:.2e}",
                a.0, a.1, b.0, b.1, c.0, c.1
            );
        }
    }

    /// Prints, for 10^4 clustered particles, the RMS relative acceleration error
    /// and the time of one evaluation on 1 thread, against the direct sum. Run with
    /// `cargo test --release -p cellist --lib study_cloud -- --ignored --nocapture`.
    #[test]
    #[ignore]
    fn study_cloud() {
        let law = law();
        let threads = Threads::single();
        let timed = |solve: &mut dyn FnMut(&Sources, FieldOut), m: &[f64], x: &[[f64; 3]]| {
            run(m, x, &mut *solve);
            let t = std::time::Instant::now();
            let (acc, _) = run(m, x, &mut *solve);
            (acc, t.elapsed().as_secs_f64())
        };
        for (name, (m, x)) in [
            ("clustered", cloud(10_000, 1.0, [0.0; 3], 3)),
            ("gaussian", gaussian(10_000, 1.0, 3)),
        ] {
            let t = std::time::Instant::now();
            let (want, _) = direct(law, &m, &x);
            println!("{name}: direct {:.3}s", t.elapsed().as_secs_f64());
            for grid in [32, 64, 128] {
                let mut pm = ParticleMesh::new(law, isolated(grid)).unwrap();
                let (acc, t) = timed(&mut |s, o| pm.compute(s, o, &threads), &m, &x);
                let rms = rms_relative(&acc, &want);
                println!("{name}: pm grid {grid}: rms {rms:.2e} {t:.3}s");
                for split in [1.25, 2.0] {
                    let mut p3m = P3m::new(law, isolated(grid), split).unwrap();
                    let (acc, t) = timed(&mut |s, o| p3m.compute(s, o, &threads), &m, &x);
                    let rms = rms_relative(&acc, &want);
                    println!("{name}: p3m grid {grid} split {split}: rms {rms:.2e} {t:.3}s");
                }
            }
        }
    }
}
