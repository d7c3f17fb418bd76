//! `cellist bench vortex`: one velocity evaluation of 2D vortex particles by a
//! solver, timed, with its error against the direct sum.

use crate::error::{SimError, SimResult};
use crate::models::fmm_name;
use crate::study::median;
use cellist::longrange::biot_savart::velocity_at;
use cellist::longrange::mesh::MAX_VIC_GRID;
use cellist::longrange::{
    Alone, BlobKernel, ErrorFit, FmmAccuracy, PointVortex, TreeParams, VicBoundary, VicParams,
    VortexFmm,
};
use cellist::models::vortex::{seed, InitialVorticity, VelocityEngine, VelocitySolver};
use cellist::Threads;
use cellist_io::read_field_of;
use std::path::PathBuf;
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
    /// The fast multipole method at this accuracy (2D).
    Fmm {
        /// The tolerance or the order.
        accuracy: FmmAccuracy,
    },
}

/// The particles of the 2D vortex benchmark.
#[derive(Clone, Debug, PartialEq)]
pub enum VortexPoints {
    /// Two Gaussian vortices on a lattice of about `n` particles over
    /// `[-1, 1]^2`, blobs of `sigma = 1.5 h`.
    Lattice {
        /// Particles (rounded to a square lattice).
        n: usize,
    },
    /// The lines `x y gamma` of a file: blobs of core `sigma`, or point
    /// vortices (the Cauchy kernel) without it.
    File {
        /// The file.
        path: PathBuf,
        /// The blobs' core, if any.
        sigma: Option<f64>,
    },
}

/// What the vortex benchmark measured.
#[derive(Clone, Debug)]
pub struct VortexBench {
    /// The solver, with its settings, for messages.
    pub solver: String,
    /// Particles.
    pub n: usize,
    /// Lattice spacing `h` of the generated particles (their blobs' core is
    /// `1.5 h`); `None` for particles from a file.
    pub spacing: Option<f64>,
    /// The blobs' core; `None` for point vortices.
    pub sigma: Option<f64>,
    /// Median seconds per velocity evaluation.
    pub seconds: f64,
    /// Target particles the error was measured on.
    pub targets: usize,
    /// `sqrt(sum |u - u_direct|^2 / sum |u_direct|^2)` over the targets.
    pub rms_relative_error: f64,
    /// The largest `|u - u_direct|` over the largest `|u_direct|`.
    pub max_error_over_peak_speed: f64,
    /// The largest `|u - u_direct| / |u_direct|` of a target (targets with
    /// `u_direct = 0` left out).
    pub max_relative_error: f64,
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

/// The largest `|a - e| / |e|` of computed vectors `a` against exact ones
/// `e` (those with `e = 0` left out).
pub(super) fn largest_relative<const W: usize>(computed: &[[f64; W]], exact: &[[f64; W]]) -> f64 {
    let norm = |v: &mut dyn Iterator<Item = f64>| v.map(|c| c * c).sum::<f64>().sqrt();
    computed
        .iter()
        .zip(exact)
        .filter_map(|(a, e)| {
            let size = norm(&mut e.iter().copied());
            (size > 0.0).then(|| norm(&mut (0..W).map(|c| a[c] - e[c])) / size)
        })
        .fold(0.0, f64::max)
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

/// The median time of `repeat` velocity evaluations of the particles of
/// `points` by `solver` (after an untimed one that builds its tables) and the
/// error against the one-sided direct sum on `sample` evenly spread targets.
pub fn vortex(
    solver: VortexBenchSolver,
    points: &VortexPoints,
    repeat: usize,
    sample: usize,
    threads: &Threads,
) -> SimResult<VortexBench> {
    if repeat == 0 || sample == 0 {
        return Err(SimError::Input(
            "--repeat and --sample must be at least 1".into(),
        ));
    }
    let (positions, gamma, spacing, sigma) = match points {
        VortexPoints::Lattice { n } => {
            let (positions, gamma, h) = lattice(*n)?;
            (positions, gamma, Some(h), Some(1.5 * h))
        }
        VortexPoints::File { path, sigma } => {
            if let Some(s) = sigma {
                if !(s.is_finite() && *s > 0.0) {
                    return Err(SimError::Input(format!("--sigma must be > 0, got {s}")));
                }
            }
            let (positions, gamma) = read_field_of::<2>(path, "gamma")?;
            (positions, gamma, None, *sigma)
        }
    };
    let n = positions.len();
    let side = spacing.map_or(0, |h| (1.0 / h).round() as usize);
    let (name, mut evaluate) = evaluator(solver, sigma, side, n, threads)?;
    let mut velocity = vec![[0.0; 2]; n];
    let seconds = median_seconds(repeat, || evaluate(&positions, &gamma, &mut velocity));
    // the error on evenly spread targets against the one-sided direct sum
    let targets = spread_targets(n, sample);
    let points: Vec<[f64; 2]> = targets.iter().map(|&i| positions[i]).collect();
    let exact = match sigma {
        Some(s) => velocity_at(&BlobKernel::new(s), &points, &positions, &gamma, threads),
        None => velocity_at(&PointVortex, &points, &positions, &gamma, threads),
    };
    let computed: Vec<[f64; 2]> = targets.iter().map(|&i| velocity[i]).collect();
    let (rms_relative_error, max_error_over_peak_speed) = errors(&computed, &exact);
    Ok(VortexBench {
        solver: name,
        n,
        spacing,
        sigma,
        seconds,
        targets: targets.len(),
        rms_relative_error,
        max_error_over_peak_speed,
        max_relative_error: largest_relative(&computed, &exact),
        rms_relative_gradient_error: None,
    })
}

/// Two Gaussian vortices on a lattice of `(2 m + 1)^2` nodes, about `n`, over
/// `[-1, 1]^2`: positions, circulations and the spacing `h = 1 / m`.
fn lattice(n: usize) -> SimResult<(Vec<[f64; 2]>, Vec<f64>, f64)> {
    if !(4..=MAX_VORTEX_PARTICLES).contains(&n) {
        return Err(SimError::Input(format!(
            "--n must be in 4..={MAX_VORTEX_PARTICLES}, got {n}"
        )));
    }
    let m = (((n as f64).sqrt() - 1.0) / 2.0).round().max(1.0) as usize;
    let h = 1.0 / m as f64;
    let field = InitialVorticity::Pair {
        circulation: 1.0,
        separation: 0.6,
        core: 0.15,
    };
    let (positions, gamma) = seed(&field, [0.0, 0.0], h, 1.0);
    Ok((positions, gamma, h))
}

/// One velocity evaluation of `n` particles.
type Evaluate<'a> = Box<dyn FnMut(&[[f64; 2]], &[f64], &mut [[f64; 2]]) + 'a>;

/// The solver's name and its evaluation, for blobs of `sigma` or point
/// vortices; `m` is the lattice's nodes per unit length (0 for a file), which
/// picks the mesh's default grid.
fn evaluator<'a>(
    solver: VortexBenchSolver,
    sigma: Option<f64>,
    m: usize,
    n: usize,
    threads: &'a Threads,
) -> SimResult<(String, Evaluate<'a>)> {
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
            // the particle lattice has 2 m + 1 nodes a side; the mesh adds a
            // margin (particles from a file: 256)
            let grid = grid.unwrap_or_else(|| match m {
                0 => 256,
                m => (2 * m + 8).next_power_of_two().min(MAX_VIC_GRID),
            });
            let params = VicParams {
                grid,
                boundary: VicBoundary::Unbounded,
            };
            (
                VelocitySolver::Mesh(params),
                format!("mesh (grid {grid}^2)"),
            )
        }
        VortexBenchSolver::Fmm { accuracy } => (
            VelocitySolver::Fmm(accuracy),
            fmm_name(accuracy, ErrorFit::VORTEX_2D),
        ),
    };
    match (sigma, kind) {
        (Some(sigma), _) => {
            let mut engine =
                VelocityEngine::new(kind, BlobKernel::new(sigma), n).map_err(SimError::Input)?;
            let evaluate: Evaluate =
                Box::new(move |x, g, u| engine.compute(x, g, u, &Alone, threads));
            Ok((name, evaluate))
        }
        (None, VelocitySolver::Fmm(accuracy)) => {
            let mut fmm = VortexFmm::new(PointVortex, accuracy).map_err(SimError::Input)?;
            let evaluate: Evaluate = Box::new(move |x, g, u| fmm.compute(x, g, u, threads));
            Ok((format!("{name}, point vortices"), evaluate))
        }
        (None, _) => Err(SimError::Input(
            "--input without --sigma gives point vortices, which only --solver fmm computes; \
             give --sigma S for blobs of core S"
                .into(),
        )),
    }
}
