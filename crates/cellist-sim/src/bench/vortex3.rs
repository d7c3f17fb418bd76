//! `cellist bench vortex --dim 3`: one evaluation of the velocity and its
//! gradient (the stretching's input) of 3D vortex particles by a solver, timed,
//! with the errors against the direct sum.

use super::vortex::{
    errors, largest_relative, median_seconds, spread_targets, VortexBench, VortexBenchSolver,
};
use crate::error::{SimError, SimResult};
use crate::models::fmm_name;
use cellist::longrange::biot_savart3::velocity_and_gradient_at;
use cellist::longrange::{
    Alone, BlobKernel3, ErrorFit, TreeParams, Vic3Boundary, Vic3Params, VortexTree3,
};
use cellist::models::vortex3::{seed3, InitialVorticity3, Ring, Velocity3Engine, Velocity3Solver};
use cellist::Threads;

/// The most particles the 3D vortex benchmark seeds.
const MAX_VORTEX3_PARTICLES: usize = 20_000_000;

/// The benchmark's ring: radius 1, core 0.2, circulation 1, about the z axis.
const RING: Ring = Ring {
    radius: 1.0,
    circulation: 1.0,
    core: 0.2,
    center: [0.0; 3],
    axis: [0.0, 0.0, 1.0],
};

/// A vortex ring (radius 1, core 0.2) on a lattice of about `n` particles
/// (`sigma = 1.5 h`): the median time of `repeat` evaluations of the velocity
/// and its gradient by `solver` (after an untimed one that builds its tables)
/// and the errors against the direct sum on `sample` evenly spread targets.
pub fn vortex3(
    solver: VortexBenchSolver,
    n: usize,
    repeat: usize,
    sample: usize,
    threads: &Threads,
) -> SimResult<VortexBench> {
    if !(100..=MAX_VORTEX3_PARTICLES).contains(&n) {
        return Err(SimError::Input(format!(
            "--n must be in 100..={MAX_VORTEX3_PARTICLES} with --dim 3, got {n}"
        )));
    }
    if repeat == 0 || sample == 0 {
        return Err(SimError::Input(
            "--repeat and --sample must be at least 1".into(),
        ));
    }
    // the seeded torus of tube radius 4 s holds 2 pi^2 R (4 s)^2 / h^3 particles
    let tube = RING.radius * 2.0 * std::f64::consts::PI.powi(2) * (4.0 * RING.core).powi(2);
    let h = (tube / n as f64).cbrt();
    let (positions, alpha) = seed3(&InitialVorticity3::Rings(vec![RING]), h);
    let n = positions.len();
    let sigma = 1.5 * h;
    let (kind, name) = match solver {
        VortexBenchSolver::Direct => (Velocity3Solver::Direct, "direct".to_string()),
        VortexBenchSolver::BarnesHut { theta } => (
            Velocity3Solver::BarnesHut(TreeParams {
                theta,
                ..VortexTree3::default_params()
            }),
            format!("barnes-hut (theta {theta})"),
        ),
        VortexBenchSolver::Mesh { grid } => {
            // the particles span 2 (R + 4 s) along x and y, and the mesh adds a
            // margin: the power of two nearest to that many spacings (a cell of
            // about h)
            let across = 2.0 * (RING.radius + 4.0 * RING.core) / h + 4.0;
            let grid = grid.unwrap_or_else(|| 1 << (across.log2().round() as u32).clamp(4, 7));
            let params = Vic3Params {
                grid,
                boundary: Vic3Boundary::Unbounded,
            };
            (
                Velocity3Solver::Mesh(params),
                format!("mesh (grid {grid}^3)"),
            )
        }
        VortexBenchSolver::Fmm { accuracy } => (
            Velocity3Solver::Fmm(accuracy),
            fmm_name(accuracy, ErrorFit::VORTEX_3D),
        ),
    };
    let mut engine = Velocity3Engine::new(kind, sigma, n).map_err(SimError::Input)?;
    let mut velocity = vec![[0.0; 3]; n];
    let mut gradient = vec![[0.0; 9]; n];
    let seconds = median_seconds(repeat, || {
        engine.compute(
            &positions,
            &alpha,
            &mut velocity,
            &mut gradient,
            &Alone,
            threads,
        )
    });
    // the errors on evenly spread targets against the direct sum
    let targets = spread_targets(n, sample);
    let points: Vec<[f64; 3]> = targets.iter().map(|&i| positions[i]).collect();
    let kernel = BlobKernel3::new(sigma);
    let (exact_u, exact_g) =
        velocity_and_gradient_at(&kernel, &points, &positions, &alpha, threads);
    let u: Vec<[f64; 3]> = targets.iter().map(|&i| velocity[i]).collect();
    let g: Vec<[f64; 9]> = targets.iter().map(|&i| gradient[i]).collect();
    let (rms_relative_error, max_error_over_peak_speed) = errors(&u, &exact_u);
    let (gradient_error, _) = errors(&g, &exact_g);
    Ok(VortexBench {
        solver: name,
        n,
        spacing: Some(h),
        sigma: Some(sigma),
        seconds,
        targets: targets.len(),
        rms_relative_error,
        max_error_over_peak_speed,
        max_relative_error: largest_relative(&u, &exact_u),
        rms_relative_gradient_error: Some(gradient_error),
    })
}
