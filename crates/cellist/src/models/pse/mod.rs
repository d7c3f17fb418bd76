//! Diffusion by particle strength exchange (PSE), seed 002 eq. (2)-(3): static
//! particles of equal volume `V` carry a field `phi`, and
//! ```text
//! d phi_i / dt = nu / eps^2 sum_j V (phi_j - phi_i) eta_eps(x_j - x_i),
//! eta_eps(r) = eps^-D 4 / pi^(D/2) exp(-|r|^2 / eps^2),
//! ```
//! on a periodic box (minimum image), summed over all pairs (`direct`) or over the
//! pairs within `cutoff_factor * eps` (`cell-list`). Each pair is evaluated once and
//! updates both particles, so `sum_i V phi_i` is conserved to round-off; the sums
//! are race-free and give the same bits for any thread count.

mod exact;
mod kernel;
mod model;
mod pairs;

pub use exact::InitialField;
pub use kernel::{exp_nonpositive, PairWeight};
pub use model::{PseModel, INFO};

use crate::geometry::norm2;
use crate::geometry::{Domain, GeometryError};
use crate::longrange::mesh::slab::Exchange;
use crate::memory::{as_arrays, as_arrays_mut};
use crate::neighbors::{CellList, OrderedRows};
use crate::random::Rng;
use crate::threads::Threads;
use pairs::{AllPairs, ListPairs, Summed};
use rayon::prelude::*;
use std::fmt;

/// How the pair sum is taken.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Method {
    /// All pairs, no cutoff: O(N^2).
    Direct,
    /// Pairs within `cutoff_factor * eps` from a cell list: O(N).
    CellList {
        /// `Delta / eps`, at least 2.
        cutoff_factor: f64,
    },
}

/// Explicit time integrators for `d phi / dt = L phi`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Integrator {
    /// Forward Euler: `phi += dt L phi`.
    Euler,
    /// Explicit midpoint: `phi += dt L (phi + dt/2 L phi)`.
    Rk2,
    /// The classical fourth-order Runge-Kutta method.
    Rk4,
}

impl Integrator {
    /// Names in scenario files, with their integrators.
    pub const ALL: [(&'static str, Integrator); 3] = [
        ("euler", Integrator::Euler),
        ("rk2", Integrator::Rk2),
        ("rk4", Integrator::Rk4),
    ];

    /// The integrator called `name`.
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.iter().find(|(n, _)| *n == name).map(|(_, i)| *i)
    }

    /// Where the method's stability region ends on the negative real axis: stable
    /// for `dt |lambda| <= R` (2 for Euler and RK2, about 2.785 for RK4).
    pub fn real_stability_bound(&self) -> f64 {
        match self {
            Integrator::Euler | Integrator::Rk2 => 2.0,
            Integrator::Rk4 => 2.785_293_563_405_282,
        }
    }

    /// Rate evaluations per step.
    pub fn stages(&self) -> u64 {
        match self {
            Integrator::Euler => 1,
            Integrator::Rk2 => 2,
            Integrator::Rk4 => 4,
        }
    }
}

/// Why a PSE system cannot be set up or a step cannot finish.
#[derive(Clone, Debug, PartialEq)]
pub enum PseError {
    /// A parameter out of its range.
    Parameter(String),
    /// The box or the cutoff.
    Geometry(GeometryError),
    /// A field value became NaN or infinite.
    NotFinite {
        /// The particle (input order).
        index: usize,
    },
}

impl fmt::Display for PseError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            PseError::Parameter(m) => f.write_str(m),
            PseError::Geometry(e) => write!(f, "{e}"),
            PseError::NotFinite { index } => {
                write!(f, "the field of particle {index} is not finite")
            }
        }
    }
}

impl std::error::Error for PseError {}

/// The physical and numerical parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PseParams {
    /// Diffusivity `nu >= 0`.
    pub nu: f64,
    /// Kernel width `eps > 0`.
    pub epsilon: f64,
    /// All pairs or a cell list.
    pub method: Method,
}

/// `n^D` points of a uniform lattice of spacing `h = L / n` in the box
/// `[0, L)^D`, at `(i + 1/2) h` (first axis fastest), each coordinate moved by
/// `jitter h (u - 1/2)` with `u` uniform in `[0, 1)` from `seed` (no move for
/// `jitter = 0`) and wrapped into the box.
pub fn lattice<const D: usize>(n: usize, length: f64, jitter: f64, seed: u64) -> Vec<[f64; D]> {
    let h = length / n as f64;
    let mut rng = Rng::new(seed);
    let total = n.pow(D as u32);
    (0..total)
        .map(|mut k| {
            std::array::from_fn(|_| {
                let i = k % n;
                k /= n;
                let mut x = (i as f64 + 0.5) * h;
                if jitter != 0.0 {
                    x += jitter * h * (rng.uniform() - 0.5);
                    x = x.rem_euclid(length);
                }
                x
            })
        })
        .collect()
}

/// The pairs of the chosen method.
#[derive(Clone, Debug)]
enum Pairs<const D: usize> {
    Direct(AllPairs<D>),
    CellList(Box<ListPairs<D, 1>>),
}

/// Static particles with a field, in a cache-friendly order of their own (cell by
/// cell for the cell list), and the buffers of the integrators.
#[derive(Clone, Debug)]
pub struct PseSystem<const D: usize> {
    domain: Domain<D>,
    params: PseParams,
    volume: f64,
    weight: PairWeight,
    /// Positions in slot order.
    positions: Vec<[f64; D]>,
    /// `order[slot]` is the input index of the particle in `slot`.
    order: Vec<u32>,
    phi: Vec<f64>,
    pairs: Pairs<D>,
    stages: [Vec<f64>; 4],
    trial: Vec<f64>,
}

impl<const D: usize> PseSystem<D> {
    /// Particles at `points` (wrapped into the periodic `domain`) with field `phi`,
    /// each of volume `|box| / N`.
    pub fn new(
        domain: Domain<D>,
        points: &[[f64; D]],
        phi: &[f64],
        params: PseParams,
        threads: &Threads,
    ) -> Result<Self, PseError> {
        let bad = |m: String| Err(PseError::Parameter(m));
        if !(params.epsilon.is_finite() && params.epsilon > 0.0) {
            return bad(format!("epsilon must be > 0, got {}", params.epsilon));
        }
        if !(params.nu.is_finite() && params.nu >= 0.0) {
            return bad(format!("nu must be >= 0, got {}", params.nu));
        }
        if (0..D).any(|a| !domain.is_periodic(a)) {
            return bad("the PSE box must be periodic on every axis".into());
        }
        if points.len() != phi.len() {
            return bad(format!(
                "{} points but {} field values",
                points.len(),
                phi.len()
            ));
        }
        if points.len() < 2 || points.len() >= u32::MAX as usize {
            return bad(format!(
                "the number of particles must be between 2 and 2^32 - 2, got {}",
                points.len()
            ));
        }
        if let Some(k) = (0..points.len())
            .find(|&k| !(phi[k].is_finite() && points[k].iter().all(|c| c.is_finite())))
        {
            return bad(format!("particle {k} has a non-finite position or field"));
        }
        let volume = domain.volume() / points.len() as f64;
        let weight = PairWeight::new(D, params.nu, params.epsilon, volume);
        let (positions, order, pairs) = match params.method {
            Method::Direct => (
                points.iter().map(|x| domain.wrap(*x)).collect(),
                (0..points.len() as u32).collect(),
                Pairs::Direct(AllPairs::new(&domain, points.len())),
            ),
            Method::CellList { cutoff_factor } => {
                if !(cutoff_factor.is_finite() && cutoff_factor >= 2.0) {
                    return bad(format!(
                        "cutoff_factor must be >= 2 (the kernel at 2 eps is still exp(-4) = 0.018 of its peak), got {cutoff_factor}"
                    ));
                }
                let cutoff = cutoff_factor * params.epsilon;
                let cells = CellList::build_in(&domain, cutoff, points, threads)
                    .map_err(PseError::Geometry)?;
                let pairs = ListPairs::new(&cells, cutoff, threads);
                (
                    cells.positions().to_vec(),
                    cells.order().to_vec(),
                    Pairs::CellList(Box::new(pairs)),
                )
            }
        };
        let n = points.len();
        Ok(PseSystem {
            domain,
            params,
            volume,
            weight,
            phi: order.iter().map(|&k| phi[k as usize]).collect(),
            positions,
            order,
            pairs,
            stages: std::array::from_fn(|_| vec![0.0; n]),
            trial: vec![0.0; n],
        })
    }

    /// Number of particles.
    pub fn len(&self) -> usize {
        self.phi.len()
    }

    /// Never true: a system has at least two particles.
    pub fn is_empty(&self) -> bool {
        self.phi.is_empty()
    }

    /// The box.
    pub fn domain(&self) -> &Domain<D> {
        &self.domain
    }

    /// The parameters.
    pub fn params(&self) -> &PseParams {
        &self.params
    }

    /// The volume of each particle, `|box| / N`.
    pub fn volume(&self) -> f64 {
        self.volume
    }

    /// Pair-kernel evaluations per rate evaluation.
    pub fn pairs_per_rate(&self) -> u64 {
        match &self.pairs {
            Pairs::Direct(p) => p.pairs(),
            Pairs::CellList(p) => p.pairs(),
        }
    }

    /// The field in input order.
    pub fn phi(&self) -> Vec<f64> {
        let mut out = vec![0.0; self.len()];
        for (slot, &k) in self.order.iter().enumerate() {
            out[k as usize] = self.phi[slot];
        }
        out
    }

    /// The field in slot order (the system's own order, see [`PseSystem::order`]).
    pub fn slot_phi(&self) -> &[f64] {
        &self.phi
    }

    /// `order[slot]`: the input index of the particle in each slot.
    pub fn order(&self) -> &[u32] {
        &self.order
    }

    /// The positions in slot order.
    pub fn slot_positions(&self) -> &[[f64; D]] {
        &self.positions
    }

    /// Replaces the field by `phi` in slot order (a saved state of this system).
    pub fn set_slot_phi(&mut self, phi: &[f64]) -> Result<(), String> {
        if phi.len() != self.phi.len() {
            return Err(format!(
                "{} field values for {} particles",
                phi.len(),
                self.phi.len()
            ));
        }
        self.phi.copy_from_slice(phi);
        Ok(())
    }

    /// The positions (wrapped into the box) in input order.
    pub fn positions(&self) -> Vec<[f64; D]> {
        let mut out = vec![[0.0; D]; self.len()];
        for (slot, &k) in self.order.iter().enumerate() {
            out[k as usize] = self.positions[slot];
        }
        out
    }

    /// The conserved total `sum_i V phi_i` (summed in slot order).
    pub fn total(&self) -> f64 {
        self.volume * self.phi.iter().sum::<f64>()
    }

    /// Errors against `exact` (input order): the discrete L2 norm
    /// `sqrt(sum_i V (phi_i - e_i)^2)` and the largest `|phi_i - e_i|`.
    pub fn errors(&self, exact: &[f64]) -> (f64, f64) {
        assert_eq!(exact.len(), self.len());
        let (mut sq, mut max) = (0.0f64, 0.0f64);
        for (slot, &k) in self.order.iter().enumerate() {
            let e = (self.phi[slot] - exact[k as usize]).abs();
            sq += e * e;
            max = max.max(e);
        }
        ((self.volume * sq).sqrt(), max)
    }

    /// The rate `d phi_i / dt` of the current field, in input order.
    pub fn rate(&mut self, threads: &Threads) -> Vec<f64> {
        let mut slots = std::mem::take(&mut self.trial);
        self.pair_sum(Summed::Rate, &mut slots, threads);
        let mut out = vec![0.0; self.len()];
        for (slot, &k) in self.order.iter().enumerate() {
            out[k as usize] = slots[slot];
        }
        self.trial = slots;
        out
    }

    /// The largest step the integrator is guaranteed stable with: the operator is
    /// symmetric with eigenvalues in `[-2 max_i S_i, 0]`, `S_i = sum_j w_ij`
    /// (Gershgorin), so `dt <= R / (2 max_i S_i)` with `R` the integrator's real
    /// stability bound. Infinite when no pair has weight.
    pub fn stability_limit(&mut self, integrator: Integrator, threads: &Threads) -> f64 {
        let mut sums = std::mem::take(&mut self.trial);
        self.pair_sum(Summed::Weights, &mut sums, threads);
        let widest = sums.iter().fold(0.0f64, |m, &s| m.max(s));
        self.trial = sums;
        if widest > 0.0 {
            integrator.real_stability_bound() / (2.0 * widest)
        } else {
            f64::INFINITY
        }
    }

    /// One step of `dt`; stops at the first particle (input order) whose field is
    /// not finite.
    pub fn step(
        &mut self,
        integrator: Integrator,
        dt: f64,
        threads: &Threads,
    ) -> Result<(), PseError> {
        let PseSystem {
            pairs,
            weight,
            positions,
            phi,
            stages,
            trial,
            ..
        } = self;
        let rate = |field: &[f64], out: &mut [f64]| {
            pairs.sum(weight, Summed::Rate, positions, field, out, threads)
        };
        advance(integrator, dt, phi, stages, trial, rate, threads);
        match self.phi.iter().position(|v| !v.is_finite()) {
            Some(slot) => Err(PseError::NotFinite {
                index: self.order[slot] as usize,
            }),
            None => Ok(()),
        }
    }

    /// `out = pair sum of the current field`, slot order.
    fn pair_sum(&mut self, summed: Summed, out: &mut [f64], threads: &Threads) {
        self.pairs.sum(
            &self.weight,
            summed,
            &self.positions,
            &self.phi,
            out,
            threads,
        );
    }
}

/// One step of `dt` of `d phi / dt = L phi` with `integrator`, the rate
/// `L phi` given by `rate(field, out)`: `stages` and `trial` are the buffers of
/// the stages (as long as `phi`). Each update is elementwise, so the bits do not
/// depend on the thread count.
pub fn advance(
    integrator: Integrator,
    dt: f64,
    phi: &mut [f64],
    stages: &mut [Vec<f64>; 4],
    trial: &mut [f64],
    mut rate: impl FnMut(&[f64], &mut [f64]),
    threads: &Threads,
) {
    let [k1, rest @ ..] = stages;
    rate(phi, k1);
    advance_from(integrator, dt, phi, k1, rest, trial, rate, threads);
}

/// [`advance`] from the rate `k1 = L phi` of the current state, known already
/// (a model that keeps the rate of its state): the explicit Runge-Kutta
/// tableaux
///
/// ```text
/// euler: phi += dt k1
/// rk2:   k2 = L(phi + dt/2 k1),                      phi += dt k2
/// rk4:   k2 = L(phi + dt/2 k1), k3 = L(phi + dt/2 k2), k4 = L(phi + dt k3),
///        phi += dt/6 (k1 + 2 k2 + 2 k3 + k4)
/// ```
#[allow(clippy::too_many_arguments)]
pub fn advance_from(
    integrator: Integrator,
    dt: f64,
    phi: &mut [f64],
    k1: &[f64],
    [k2, k3, k4]: &mut [Vec<f64>; 3],
    trial: &mut [f64],
    mut rate: impl FnMut(&[f64], &mut [f64]),
    threads: &Threads,
) {
    match integrator {
        Integrator::Euler => {
            combine(phi, None, &[(dt, k1)], threads);
        }
        Integrator::Rk2 => {
            combine(trial, Some(phi), &[(0.5 * dt, k1)], threads);
            rate(trial, k2);
            combine(phi, None, &[(dt, k2)], threads);
        }
        Integrator::Rk4 => {
            combine(trial, Some(phi), &[(0.5 * dt, k1)], threads);
            rate(trial, k2);
            combine(trial, Some(phi), &[(0.5 * dt, k2)], threads);
            rate(trial, k3);
            combine(trial, Some(phi), &[(dt, k3)], threads);
            rate(trial, k4);
            let sixth = dt / 6.0;
            let terms = [
                (sixth, k1),
                (2.0 * sixth, k2),
                (2.0 * sixth, k3),
                (sixth, k4),
            ];
            combine(phi, None, &terms, threads);
        }
    }
}

/// The PSE rate of a subdomain's particles over the id-sorted rows of
/// [`OrderedRows`] (owned particles first, then ghosts): `out_i = sum_{j in
/// row(i)} w_ij (phi_j - phi_i)`, with the fixed pair weights `weights` (one per
/// row entry, [`row_weights`]), each particle's sum in id order.
pub fn ordered_rate<const D: usize>(
    rows: &OrderedRows<D>,
    weights: &[f64],
    phi: &[f64],
    out: &mut [f64],
    threads: &Threads,
) {
    rows.map(out, threads, |i| {
        let entries = rows.entries(i);
        let mut rate = 0.0;
        for (&j, w) in rows.row(i).iter().zip(&weights[entries]) {
            rate += w * (phi[j as usize] - phi[i]);
        }
        rate
    });
}

/// The weight `w(r_ij^2)` of every entry of `rows` at `points` (the particles
/// do not move: computed once), zero beyond `cutoff`, indexed like the entries
/// ([`OrderedRows::entries`]).
pub fn row_weights<const D: usize>(
    rows: &OrderedRows<D>,
    weight: &PairWeight,
    points: &[[f64; D]],
    cutoff: f64,
) -> Vec<f64> {
    let mut weights = vec![0.0; rows.num_entries()];
    for i in 0..rows.len() {
        for (e, &j) in rows.entries(i).zip(rows.row(i)) {
            let d: [f64; D] = std::array::from_fn(|a| points[i][a] - points[j as usize][a]);
            let r2 = norm2(&d);
            weights[e] = if r2.sqrt() < cutoff {
                weight.at(r2)
            } else {
                0.0
            };
        }
    }
    weights
}

/// The PSE rate of particles that move (the vortex model's diffusion), for `W`
/// strength components per particle (`W = 1`: a circulation in 2D; `W = 3`: the
/// vector strength `alpha` in 3D): `out_i = sum_j w(r_ij^2) (phi_j - phi_i)`
/// component by component, over the pairs within `cutoff` in `domain` (open, or
/// periodic by the minimum image), with the same pair sums as [`PseSystem`]'s
/// cell-list method. One neighbour search and one weight per pair serve every
/// component, and each component gets the bits of a scalar call with it alone.
/// The cell list and its half Verlet list are built for these positions on every
/// call. `positions`, `phi` and `out` are in the caller's order; each particle's
/// sum runs in an order fixed by the data.
///
/// On the ranks of `exchange` (each holding every particle and calling this
/// with the same arguments) each rank builds and sums the Verlet rows of its
/// run of the cell layers ([`LayerPlan::task_runs`](crate::neighbors::LayerPlan::task_runs)),
/// the sums of the slots they wrote are all-gathered, and every rank adds
/// them up as one process does: one process's bits on every rank.
#[allow(clippy::too_many_arguments)]
pub fn moving_rate<const D: usize, const W: usize>(
    domain: &Domain<D>,
    weight: &PairWeight,
    cutoff: f64,
    positions: &[[f64; D]],
    phi: &[[f64; W]],
    out: &mut [[f64; W]],
    exchange: &dyn Exchange,
    threads: &Threads,
) -> Result<(), GeometryError> {
    let cells = CellList::build_in(domain, cutoff, positions, threads)?;
    let (mut pairs, runs) = match exchange.ranks() {
        1 => (ListPairs::new(&cells, cutoff, threads), None),
        _ => {
            let (pairs, runs) = ListPairs::of_rank(&cells, cutoff, exchange, threads);
            (pairs, Some(runs))
        }
    };
    let mut slot_phi = Vec::with_capacity(phi.len());
    cells.permute(phi, &mut slot_phi);
    let mut slot_out = vec![[0.0; W]; phi.len()];
    pairs.sum(
        weight,
        Summed::Rate,
        cells.positions(),
        &slot_phi,
        &mut slot_out,
        runs.as_deref().map(|runs| (runs, exchange)),
        threads,
    );
    for (slot, &k) in cells.order().iter().enumerate() {
        out[k as usize] = slot_out[slot];
    }
    Ok(())
}

impl<const D: usize> Pairs<D> {
    fn sum(
        &mut self,
        weight: &PairWeight,
        summed: Summed,
        positions: &[[f64; D]],
        phi: &[f64],
        out: &mut [f64],
        threads: &Threads,
    ) {
        match self {
            Pairs::Direct(p) => p.sum(weight, summed, positions, phi, out, threads),
            Pairs::CellList(p) => {
                let (phi, out) = (as_arrays::<1>(phi), as_arrays_mut::<1>(out));
                p.sum(weight, summed, positions, phi, out, None, threads)
            }
        }
    }
}

/// Elements per task of the vector updates.
const AXPY_CHUNK: usize = 8192;

/// `out = base + sum_s c_s k_s` element by element, the terms summed in the given
/// order first (`base` defaults to `out` itself: `out += ...`).
pub(crate) fn combine(
    out: &mut [f64],
    base: Option<&[f64]>,
    terms: &[(f64, &[f64])],
    threads: &Threads,
) {
    threads.install(|| {
        out.par_chunks_mut(AXPY_CHUNK)
            .enumerate()
            .for_each(|(c, chunk)| {
                let first = c * AXPY_CHUNK;
                for (m, o) in chunk.iter_mut().enumerate() {
                    let i = first + m;
                    let mut increment = 0.0;
                    for (coefficient, k) in terms {
                        increment += coefficient * k[i];
                    }
                    *o = base.map_or(*o, |b| b[i]) + increment;
                }
            });
    });
}
