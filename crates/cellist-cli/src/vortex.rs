//! `cellist bench vortex`: one velocity evaluation of 2D vortex particles by a
//! solver, timed, with its error against the direct sum (measured by the
//! simulation layer's benchmark; printed here).

use crate::cli::{BenchVortexArgs, VortexSolverArg};
use crate::error::{threads, CliResult};
use cellist_sim::bench::{vortex, VortexBenchSolver};

/// `cellist bench vortex`.
pub fn bench(args: &BenchVortexArgs) -> CliResult {
    let pool = threads(Some(args.threads))?;
    let solver = match args.solver {
        VortexSolverArg::Direct => VortexBenchSolver::Direct,
        VortexSolverArg::BarnesHut => VortexBenchSolver::BarnesHut { theta: args.theta },
        VortexSolverArg::Mesh => VortexBenchSolver::Mesh { grid: args.grid },
    };
    let b = vortex(solver, args.n, args.repeat, args.sample, &pool)?;
    if args.json {
        let obj = serde_json::json!({
            "solver": b.solver, "n": b.n, "threads": args.threads, "spacing": b.spacing,
            "sigma": 1.5 * b.spacing, "seconds_per_velocity": b.seconds, "repeat": args.repeat,
            "error_targets": b.targets,
            "rms_relative_velocity_error": b.rms_relative_error,
            "max_error_over_peak_speed": b.max_error_over_peak_speed,
        });
        println!("{obj}");
    } else {
        println!(
            "vortex {}: {} particles (two Gaussian vortices, h {:.3e}, sigma 1.5 h), {} thread(s): \
             {:.4e} s per velocity evaluation (median of {}); against direct on {} particles: \
             RMS relative error {:.3e}, largest error / peak speed {:.3e}",
            b.solver,
            b.n,
            b.spacing,
            args.threads,
            b.seconds,
            args.repeat,
            b.targets,
            b.rms_relative_error,
            b.max_error_over_peak_speed
        );
    }
    Ok(())
}
