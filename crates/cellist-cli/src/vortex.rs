//! `cellist bench vortex`: one velocity evaluation of 2D vortex particles by a
//! solver, timed, with its error against the direct sum.

use crate::cli::{BenchVortexArgs, VortexSolverArg};
use crate::error::{threads, CliError, CliResult};
use cellist::longrange::biot_savart::velocity_at;
use cellist::longrange::mesh::MAX_VIC_GRID;
use cellist::longrange::{BlobKernel, TreeParams, VicBoundary, VicParams};
use cellist::models::vortex::{seed, InitialVorticity, VelocityEngine, VelocitySolver};
use cellist_sim::study::median;
use std::time::Instant;

/// The most particles the benchmark seeds.
const MAX_PARTICLES: usize = 20_000_000;

/// `cellist bench vortex`.
pub fn bench(args: &BenchVortexArgs) -> CliResult {
    if !(4..=MAX_PARTICLES).contains(&args.n) {
        return Err(CliError::Input(format!(
            "--n must be in 4..={MAX_PARTICLES}, got {}",
            args.n
        )));
    }
    if args.repeat == 0 || args.sample == 0 {
        return Err(CliError::Input(
            "--repeat and --sample must be at least 1".into(),
        ));
    }
    let pool = threads(Some(args.threads))?;
    // a lattice of (2 m + 1)^2 nodes over [-1, 1]^2 with two Gaussian vortices
    let m = (((args.n as f64).sqrt() - 1.0) / 2.0).round().max(1.0) as usize;
    let h = 1.0 / m as f64;
    let field = InitialVorticity::Pair {
        circulation: 1.0,
        separation: 0.6,
        core: 0.15,
    };
    let (positions, gamma) = seed(&field, [0.0, 0.0], h, 1.0);
    let n = positions.len();
    let kernel = BlobKernel::new(1.5 * h);
    let mut velocity = vec![[0.0; 2]; n];
    let (kind, name) = match args.solver {
        VortexSolverArg::Direct => (VelocitySolver::Direct, "direct".to_string()),
        VortexSolverArg::BarnesHut => {
            let params = TreeParams {
                theta: args.theta,
                ..TreeParams::default()
            };
            (
                VelocitySolver::BarnesHut(params),
                format!("barnes-hut (theta {})", args.theta),
            )
        }
        VortexSolverArg::Mesh => {
            // the particle lattice has 2 m + 1 nodes a side; the mesh adds a margin
            let grid = args
                .grid
                .unwrap_or_else(|| (2 * m + 8).next_power_of_two().min(MAX_VIC_GRID));
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
    let mut solver = VelocityEngine::new(kind, kernel, n).map_err(CliError::Input)?;
    let mut samples = Vec::with_capacity(args.repeat + 1);
    // one untimed evaluation first: it builds the tables and buffers
    for _ in 0..=args.repeat {
        let start = Instant::now();
        solver.compute(&positions, &gamma, &mut velocity, &pool);
        samples.push(start.elapsed().as_secs_f64());
    }
    let seconds = median(&samples[1..]);
    // the error on evenly spread targets against the one-sided direct sum
    let stride = n.div_ceil(args.sample.min(n));
    let targets: Vec<usize> = (0..n).step_by(stride).collect();
    let points: Vec<[f64; 2]> = targets.iter().map(|&i| positions[i]).collect();
    let exact = velocity_at(&kernel, &points, &positions, &gamma, &pool);
    let (mut err2, mut norm2, mut max_err, mut max_speed) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
    for (&i, e) in targets.iter().zip(&exact) {
        let d = (velocity[i][0] - e[0]).hypot(velocity[i][1] - e[1]);
        err2 += d * d;
        norm2 += e[0] * e[0] + e[1] * e[1];
        max_err = max_err.max(d);
        max_speed = max_speed.max(e[0].hypot(e[1]));
    }
    let rms = (err2 / norm2).sqrt();
    let max_relative = max_err / max_speed;
    if args.json {
        let obj = serde_json::json!({
            "solver": name, "n": n, "threads": args.threads, "spacing": h, "sigma": 1.5 * h,
            "seconds_per_velocity": seconds, "repeat": args.repeat,
            "error_targets": targets.len(),
            "rms_relative_velocity_error": rms, "max_error_over_peak_speed": max_relative,
        });
        println!("{obj}");
    } else {
        println!(
            "vortex {name}: {n} particles (two Gaussian vortices, h {h:.3e}, sigma 1.5 h), {} thread(s): \
             {seconds:.4e} s per velocity evaluation (median of {}); against direct on {} particles: \
             RMS relative error {rms:.3e}, largest error / peak speed {max_relative:.3e}",
            args.threads,
            args.repeat,
            targets.len()
        );
    }
    Ok(())
}
