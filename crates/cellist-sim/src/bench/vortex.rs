//! `cellist bench vortex`: one velocity evaluation of 2D vortex particles by a
//! solver, timed, with its error against the direct sum.

use crate::error::{SimError, SimResult};
use crate::study::median;
use cellist::longrange::biot_savart::velocity_at;
use cellist::longrange::mesh::MAX_VIC_GRID;
use cellist::longrange::{BlobKernel, TreeParams, VicBoundary, VicParams};
use cellist::models::vortex::{seed, InitialVorticity, VelocityEngine, VelocitySolver};
use cellist::Threads;
use std::time::Instant;

/// The most particles the vortex benchmark seeds.
const MAX_VORTEX_PARTICLES: usize = 20_000_000;

/// The velocity solver of the vortex benchmark and its settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum VortexBenchSolver {
    /// All pairs, exact.
    Direct,
    /// The Barnes-Hut tree with this opening angle.
    BarnesHut {
        /// Opening angle.
        theta: f64,
    },
    /// Vortex-in-cell on a mesh of this many nodes a side (default: the smallest
    /// power of two at least as fine as the particle lattice, with a margin).
    Mesh {
        /// Nodes per axis.
        grid: Option<usize>,
    },
}

/// What the vortex benchmark measured.
#[derive(Clone, Debug)]
pub struct VortexBench {
    /// The solver, with its settings, for messages.
    pub solver: String,
    /// Particles (a square lattice).
    pub n: usize,
    /// Lattice spacing `h` (the blobs' core is `1.5 h`).
    pub spacing: f64,
    /// Median seconds per velocity evaluation.
    pub seconds: f64,
    /// Target particles the error was measured on.
    pub targets: usize,
    /// `sqrt(sum |u - u_direct|^2 / sum |u_direct|^2)` over the targets.
    pub rms_relative_error: f64,
    /// The largest `|u - u_direct|` over the largest `|u_direct|`.
    pub max_error_over_peak_speed: f64,
    /// In 3D, `sqrt(sum |G - G_direct|^2 / sum |G_direct|^2)` of the velocity
    /// gradients `G` (Frobenius norms) over the targets.
    pub rms_relative_gradient_error: Option<f64>,
}

/// `(sqrt(sum |a - e|^2 / sum |e|^2), max |a - e| / max |e|)` of computed
/// vectors `a` against exact ones `e`.
pub(super) fn errors<const W: usize>(computed: &[[f64; W]], exact: &[[f64; W]]) -> (f64, f64) {
    let (mut err2, mut norm2, mut max_err, mut max_size) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
    for (a, e) in computed.iter().zip(exact) {
        let d2: f64 = (0..W).map(|c| (a[c] - e[c]).powi(2)).sum();
        let e2: f64 = e.iter().map(|c| c * c).sum();
        err2 += d2;
        norm2 += e2;
        max_err = max_err.max(d2.sqrt());
        max_size = max_size.max(e2.sqrt());
    }
    ((err2 / norm2).sqrt(), max_err / max_size)
}

/// The median seconds of `repeat` calls of `evaluate` after an untimed one
/// (which builds the solver's tables).
pub(super) fn median_seconds(repeat: usize, mut evaluate: impl FnMut()) -> f64 {
    let mut samples = Vec::with_capacity(repeat + 1);
    for _ in 0..=repeat {
        let start = Instant::now();
        evaluate();
        samples.push(start.elapsed().as_secs_f64());
    }
    median(&samples[1..])
}

/// About `sample` of the indices `0..n`, evenly spread (all if `n` is smaller).
pub(super) fn spread_targets(n: usize, sample: usize) -> Vec<usize> {
    (0..n).step_by(n.div_ceil(sample.min(n))).collect()
}

/// Two Gaussian vortices on a lattice of about `n` particles over `[-1, 1]^2`
/// (`sigma = 1.5 h`): the median time of `repeat` velocity evaluations by
/// `solver` (after an untimed one that builds its tables) and the error against
/// the one-sided direct sum on `sample` evenly spread targets.
pub fn vortex(
    solver: VortexBenchSolver,
    n: usize,
    repeat: usize,
    sample: usize,
    threads: &Threads,
) -> SimResult<VortexBench> {
    if !(4..=MAX_VORTEX_PARTICLES).contains(&n) {
        return Err(SimError::Input(format!(
            "--n must be in 4..={MAX_VORTEX_PARTICLES}, got {n}"
        )));
    }
    if repeat == 0 || sample == 0 {
        return Err(SimError::Input(
            "--repeat and --sample must be at least 1".into(),
        ));
    }
    // a lattice of (2 m + 1)^2 nodes over [-1, 1]^2 with two Gaussian vortices
    let m = (((n as f64).sqrt() - 1.0) / 2.0).round().max(1.0) as usize;
    let h = 1.0 / m as f64;
    let field = InitialVorticity::Pair {
        circulation: 1.0,
        separation: 0.6,
        core: 0.15,
    };
    let (positions, gamma) = seed(&field, [0.0, 0.0], h, 1.0);
    let n = positions.len();
    let kernel = BlobKernel::new(1.5 * h);
    let (kind, name) = match solver {
        VortexBenchSolver::Direct => (VelocitySolver::Direct, "direct".to_string()),
        VortexBenchSolver::BarnesHut { theta } => (
            VelocitySolver::BarnesHut(TreeParams {
                theta,
                ..TreeParams::default()
            }),
            format!("barnes-hut (theta {theta})"),
        ),
        VortexBenchSolver::Mesh { grid } => {
            // the particle lattice has 2 m + 1 nodes a side; the mesh adds a margin
            let grid = grid.unwrap_or_else(|| (2 * m + 8).next_power_of_two().min(MAX_VIC_GRID));
            let params = VicParams {
                grid,
                boundary: VicBoundary::Unbounded,
            };
            (
                VelocitySolver::Mesh(params),
                format!("mesh (grid {grid}^2)"),
            )
        }
    };
    let mut engine = VelocityEngine::new(kind, kernel, n).map_err(SimError::Input)?;
    let mut velocity = vec![[0.0; 2]; n];
    let seconds = median_seconds(repeat, || {
        engine.compute(&positions, &gamma, &mut velocity, threads)
    });
    // the error on evenly spread targets against the one-sided direct sum
    let targets = spread_targets(n, sample);
    let points: Vec<[f64; 2]> = targets.iter().map(|&i| positions[i]).collect();
    let exact = velocity_at(&kernel, &points, &positions, &gamma, threads);
    let computed: Vec<[f64; 2]> = targets.iter().map(|&i| velocity[i]).collect();
    let (rms_relative_error, max_error_over_peak_speed) = errors(&computed, &exact);
    Ok(VortexBench {
        solver: name,
        n,
        spacing: h,
        seconds,
        targets: targets.len(),
        rms_relative_error,
        max_error_over_peak_speed,
        rms_relative_gradient_error: None,
    })
}
