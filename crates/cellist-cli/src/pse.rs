//! `cellist bench pse`: forward Euler steps of diffusion by particle strength
//! exchange on a lattice, timed.

use crate::cli::{BenchPseArgs, PseMethodArg};
use crate::error::{threads, CliError, CliResult};
use cellist::models::pse::{lattice, InitialField, Integrator, Method, PseParams, PseSystem};
use cellist::{Domain, Threads};
use cellist_sim::study::median;
use std::time::Instant;

/// `cellist bench pse`.
pub fn bench(args: &BenchPseArgs) -> CliResult {
    if args.n_per_side < 2 {
        return Err(CliError::Input("--n-per-side must be at least 2".into()));
    }
    if args.repeat == 0 || args.steps == 0 {
        return Err(CliError::Input(
            "--repeat and --steps must be at least 1".into(),
        ));
    }
    crate::error::positive("--eps-over-h", args.eps_over_h)?;
    let pool = threads(Some(args.threads))?;
    let (seconds, pairs, n) = match args.dim {
        2 => time_steps::<2>(args, &pool)?,
        _ => time_steps::<3>(args, &pool)?,
    };
    let per_second = pairs as f64 / seconds;
    let method = match args.method {
        PseMethodArg::Direct => "direct",
        PseMethodArg::CellList => "cell-list",
    };
    if args.json {
        let obj = serde_json::json!({
            "n_per_side": args.n_per_side, "particles": n, "dim": args.dim, "method": method,
            "eps_over_h": args.eps_over_h, "cutoff_factor": args.cutoff_factor,
            "threads": args.threads, "seconds_per_step": seconds, "pairs_per_step": pairs,
            "pair_kernels_per_second": per_second,
        });
        println!("{obj}");
    } else {
        println!(
            "pse: {n} particles ({}^{}), {method}, eps/h {}, {} thread(s): {seconds:.4e} s per step \
             (median of {}), {pairs} pair kernels per step, {per_second:.3e} pair kernels per second",
            args.n_per_side, args.dim, args.eps_over_h, args.threads, args.repeat
        );
    }
    Ok(())
}

/// Median seconds per forward Euler step, pair kernels per step, particles.
fn time_steps<const D: usize>(args: &BenchPseArgs, pool: &Threads) -> CliResult<(f64, u64, usize)> {
    let n = args.n_per_side;
    let domain = Domain::periodic([1.0; D]).map_err(|e| CliError::Internal(e.to_string()))?;
    let points = lattice::<D>(n, 1.0, 0.0, 1);
    let field = InitialField::Sine { k: [1; D] };
    let phi = field.exact_at(&points, 0.0, 1.0, &domain.length);
    let method = match args.method {
        PseMethodArg::Direct => Method::Direct,
        PseMethodArg::CellList => Method::CellList {
            cutoff_factor: args.cutoff_factor,
        },
    };
    let params = PseParams {
        nu: 1.0,
        epsilon: args.eps_over_h / n as f64,
        method,
    };
    let mut system = PseSystem::new(domain, &points, &phi, params, pool)
        .map_err(|e| CliError::Input(e.to_string()))?;
    let dt = 0.5 * system.stability_limit(Integrator::Euler, pool);
    let mut samples = Vec::with_capacity(args.repeat);
    for _ in 0..args.repeat {
        let start = Instant::now();
        for _ in 0..args.steps {
            system
                .step(Integrator::Euler, dt, pool)
                .map_err(|e| CliError::Internal(e.to_string()))?;
        }
        samples.push(start.elapsed().as_secs_f64() / args.steps as f64);
    }
    Ok((median(&samples), system.pairs_per_rate(), points.len()))
}
