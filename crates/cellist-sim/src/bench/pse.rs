//! `cellist bench pse`: forward Euler steps of diffusion by particle strength
//! exchange on a lattice.

use crate::error::{positive, SimError, SimResult};
use crate::study::median;
use cellist::models::pse::{lattice, InitialField, Integrator, Method, PseParams, PseSystem};
use cellist::{Domain, Threads};
use std::time::Instant;

/// The pair sum of the PSE benchmark.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PseMethod {
    /// All pairs, O(N^2).
    Direct,
    /// Pairs within `cutoff_factor * eps` from a cell list, O(N).
    CellList,
}

impl PseMethod {
    /// The name on the command line.
    pub fn name(self) -> &'static str {
        match self {
            PseMethod::Direct => "direct",
            PseMethod::CellList => "cell-list",
        }
    }
}

/// The lattice to step: `n_per_side^dim` particles in the unit box, a sine
/// field, kernel width `eps_over_h` spacings.
#[derive(Clone, Copy, Debug)]
pub struct PseRequest {
    /// Particles per side (N = n^dim).
    pub n_per_side: usize,
    /// Dimension (2 or 3).
    pub dim: u8,
    /// All pairs or cell list.
    pub method: PseMethod,
    /// Kernel width in lattice spacings.
    pub eps_over_h: f64,
    /// Cutoff of the cell list in units of eps.
    pub cutoff_factor: f64,
    /// Timed steps per repetition.
    pub steps: u64,
    /// Timed repetitions.
    pub repeat: usize,
}

/// What the PSE benchmark measured.
#[derive(Clone, Copy, Debug)]
pub struct PseBench {
    /// Particles.
    pub particles: usize,
    /// Median seconds per step.
    pub seconds_per_step: f64,
    /// Pair kernels evaluated per step.
    pub pairs_per_step: u64,
}

/// Times forward Euler steps at half the stability limit: the median seconds
/// per step over `repeat` runs of `steps` steps.
pub fn pse(request: &PseRequest, threads: &Threads) -> SimResult<PseBench> {
    if request.n_per_side < 2 {
        return Err(SimError::Input("--n-per-side must be at least 2".into()));
    }
    if request.repeat == 0 || request.steps == 0 {
        return Err(SimError::Input(
            "--repeat and --steps must be at least 1".into(),
        ));
    }
    positive("--eps-over-h", request.eps_over_h)?;
    match request.dim {
        2 => time_steps::<2>(request, threads),
        _ => time_steps::<3>(request, threads),
    }
}

fn time_steps<const D: usize>(request: &PseRequest, threads: &Threads) -> SimResult<PseBench> {
    let n = request.n_per_side;
    let domain = Domain::periodic([1.0; D]).map_err(|e| SimError::Internal(e.to_string()))?;
    let points = lattice::<D>(n, 1.0, 0.0, 1);
    let field = InitialField::Sine { k: [1; D] };
    let phi = field.exact_at(&points, 0.0, 1.0, &domain.length);
    let method = match request.method {
        PseMethod::Direct => Method::Direct,
        PseMethod::CellList => Method::CellList {
            cutoff_factor: request.cutoff_factor,
        },
    };
    let params = PseParams {
        nu: 1.0,
        epsilon: request.eps_over_h / n as f64,
        method,
    };
    let mut system = PseSystem::new(domain, &points, &phi, params, threads)
        .map_err(|e| SimError::Input(e.to_string()))?;
    let dt = 0.5 * system.stability_limit(Integrator::Euler, threads);
    let mut samples = Vec::with_capacity(request.repeat);
    for _ in 0..request.repeat {
        let start = Instant::now();
        for _ in 0..request.steps {
            system
                .step(Integrator::Euler, dt, threads)
                .map_err(|e| SimError::Internal(e.to_string()))?;
        }
        samples.push(start.elapsed().as_secs_f64() / request.steps as f64);
    }
    Ok(PseBench {
        particles: points.len(),
        seconds_per_step: median(&samples),
        pairs_per_step: system.pairs_per_rate(),
    })
}
