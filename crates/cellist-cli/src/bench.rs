//! `cellist bench ...`: the simulation layer's benchmarks, their flags in and
//! their figures out, as a line of text or one JSON object.

use crate::cli::{
    BenchBilliardsArgs, BenchGravityArgs, BenchLjArgs, BenchNeighborsArgs, BenchPseArgs,
    BenchVortexArgs, GravityDistributionArg, GravitySolverArg, PseMethodArg, VortexSolverArg,
};
use crate::error::{threads, CliError, CliResult};
use cellist_sim::bench::{
    self, FmmAccuracy, GravityBodies, GravitySolver, PseMethod, VortexBenchSolver, VortexPoints,
};
use cellist_sim::bench::{late_note, RebuildRule};
use cellist_sim::neighbors::Order;
use cellist_sim::Threads;

/// `cellist bench neighbors`.
pub fn neighbors(args: &BenchNeighborsArgs) -> CliResult {
    let pool = threads(Some(args.threads))?;
    let arrays = match (args.sorted, args.as_found) {
        (true, _) => Some(Order::Sorted),
        (_, true) => Some(Order::AsFound),
        _ => None,
    };
    let request = bench::NeighborsRequest {
        n: args.n,
        dim: args.dim,
        density: args.density,
        cutoff: args.cutoff,
        seed: args.seed,
        repeat: args.repeat,
        arrays,
    };
    let b = bench::neighbors(&request, &pool)?;
    let ns_per_pair = b.seconds * 1e9 / b.pairs.max(1) as f64;
    if args.json {
        let mut obj = serde_json::json!({
            "n": args.n, "dim": args.dim, "threads": args.threads, "pairs": b.pairs,
            "seconds": b.seconds, "ns_per_pair": ns_per_pair,
        });
        if args.sorted {
            obj["sorted"] = true.into();
        }
        if args.as_found {
            obj["as_found"] = true.into();
        }
        println!("{obj}");
    } else {
        println!(
            "neighbors{}: n {} dim {} threads {}: median {:.4} s over {} runs, {} pairs, {:.2} ns/pair",
            match arrays {
                Some(Order::Sorted) => " (sorted)",
                Some(Order::AsFound) => " (as found, int64)",
                None => "",
            },
            args.n,
            args.dim,
            args.threads,
            b.seconds,
            args.repeat,
            b.pairs,
            ns_per_pair
        );
    }
    Ok(())
}

/// `cellist bench lj`: the loop time of the LAMMPS melt, as LAMMPS reports it
/// (set-up excluded), median over `--repeat` runs from the same start.
pub fn lj(args: &BenchLjArgs) -> CliResult {
    let pool = threads(Some(args.threads))?;
    let rule = RebuildRule {
        every: args.every,
        check: !args.no_check,
    };
    let request = bench::LjRequest {
        atoms_per_side: args.atoms_per_side,
        steps: args.steps,
        repeat: args.repeat,
        rule,
    };
    let b = bench::lj(&request, &pool)?;
    let atoms = b.atoms;
    if args.json {
        let obj = serde_json::json!({
            "atoms": atoms, "steps": args.steps, "threads": args.threads,
            "loop_seconds": b.seconds, "us_per_atom_step": b.us_per_atom_step, "rebuilds": b.rebuilds,
            "force_seconds": b.force_seconds, "neighbor_seconds": b.neighbor_seconds,
            "every": rule.every, "check": rule.check, "late_builds": b.late_builds,
            "peak_rss_bytes": b.peak_rss_bytes,
            "peak_rss_bytes_per_atom": b.peak_rss_bytes.map(|m| m as f64 / atoms as f64),
        });
        println!("{obj}");
    } else {
        let memory = b.peak_rss_bytes.map_or(String::new(), |m| {
            format!(
                ", peak resident memory {:.1} MB ({:.0} bytes/atom)",
                m as f64 / 1e6,
                m as f64 / atoms as f64
            )
        });
        println!(
            "lj: {atoms} atoms, {} steps, {} thread(s), list every {} check {}: loop time {:.4} s \
             (median of {}), {:.4} us/atom-step, {} rebuilds{}{memory}",
            args.steps,
            args.threads,
            rule.every,
            if rule.check { "yes" } else { "no" },
            b.seconds,
            args.repeat,
            b.us_per_atom_step,
            b.rebuilds,
            late_note(b.late_builds),
        );
    }
    Ok(())
}

/// `cellist bench pse`.
pub fn pse(args: &BenchPseArgs) -> CliResult {
    let pool = threads(Some(args.threads))?;
    let method = match args.method {
        PseMethodArg::Direct => PseMethod::Direct,
        PseMethodArg::CellList => PseMethod::CellList,
    };
    let request = bench::PseRequest {
        n_per_side: args.n_per_side,
        dim: args.dim,
        method,
        eps_over_h: args.eps_over_h,
        cutoff_factor: args.cutoff_factor,
        steps: args.steps,
        repeat: args.repeat,
    };
    let b = bench::pse(&request, &pool)?;
    let (seconds, pairs, n) = (b.seconds_per_step, b.pairs_per_step, b.particles);
    let per_second = pairs as f64 / seconds;
    let method = method.name();
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

/// `cellist bench gravity`.
pub fn gravity(args: &BenchGravityArgs) -> CliResult {
    let pool = threads(Some(args.threads))?;
    let solver = match args.solver {
        GravitySolverArg::Direct => GravitySolver::Direct,
        GravitySolverArg::BarnesHut => GravitySolver::BarnesHut {
            theta: args.theta,
            quadrupole: !args.monopole,
            leaf_size: args.leaf_size,
            group_size: args.group_size,
        },
        GravitySolverArg::Pm => GravitySolver::Pm { grid: args.grid },
        GravitySolverArg::P3m => GravitySolver::P3m {
            grid: args.grid,
            split: args.split,
        },
        GravitySolverArg::Fmm => GravitySolver::Fmm {
            accuracy: match args.order {
                Some(p) => FmmAccuracy::Order(p),
                None => FmmAccuracy::Tolerance(args.tolerance),
            },
        },
    };
    let bodies = match (&args.input, args.n, args.distribution) {
        (Some(path), _, _) => GravityBodies::File(path.clone()),
        (None, Some(n), GravityDistributionArg::Plummer) => GravityBodies::Plummer { n },
        (None, Some(n), GravityDistributionArg::Uniform) => GravityBodies::Uniform { n },
        (None, None, _) => unreachable!("clap requires --n or --input"),
    };
    let request = bench::GravityRequest {
        solver,
        bodies: bodies.clone(),
        softening: args.softening,
        seed: args.seed,
        repeat: args.repeat,
        sample: args.sample,
    };
    let b = bench::gravity(&request, &pool)?;
    let (name, seconds) = (solver.name(), b.seconds);
    if args.json {
        let mut obj = serde_json::json!({
            "solver": name, "n": b.n, "threads": args.threads, "softening": args.softening,
            "seconds_per_force": seconds, "repeat": args.repeat, "seed": args.seed,
        });
        match solver {
            GravitySolver::Direct => {
                obj["ns_per_pair"] = serde_json::json!(seconds / b.pairs * 1e9);
            }
            GravitySolver::BarnesHut {
                theta,
                quadrupole,
                leaf_size,
                group_size,
            } => {
                obj["theta"] = serde_json::json!(theta);
                obj["quadrupole"] = serde_json::json!(quadrupole);
                obj["leaf_size"] = serde_json::json!(leaf_size);
                obj["group_size"] = serde_json::json!(group_size);
            }
            GravitySolver::Pm { grid } => obj["grid"] = serde_json::json!(grid),
            GravitySolver::P3m { grid, split } => {
                obj["grid"] = serde_json::json!(grid);
                obj["split_cells"] = serde_json::json!(split);
            }
            GravitySolver::Fmm { accuracy } => {
                obj["description"] = serde_json::json!(b.solver);
                match accuracy {
                    FmmAccuracy::Tolerance(t) => obj["tolerance"] = serde_json::json!(t),
                    FmmAccuracy::Order(p) => obj["order"] = serde_json::json!(p),
                }
            }
        }
        match &bodies {
            GravityBodies::Plummer { .. } => {}
            GravityBodies::Uniform { .. } => obj["distribution"] = serde_json::json!("uniform"),
            GravityBodies::File(path) => {
                obj["input"] = serde_json::json!(path.display().to_string())
            }
        }
        if let Some(r) = b.rms_relative_error {
            obj["rms_relative_force_error"] = serde_json::json!(r);
        }
        if let (Some(rms), Some(max)) = (b.rms_field_error, b.max_relative_error) {
            obj["rms_field_error"] = serde_json::json!(rms);
            obj["max_relative_error"] = serde_json::json!(max);
            if args.sample.is_some() {
                obj["error_targets"] = serde_json::json!(b.targets);
            }
        }
        if let Some((nodes, particles)) = b.interactions {
            obj["node_interactions"] = serde_json::json!(nodes);
            obj["particle_interactions"] = serde_json::json!(particles);
        }
        println!("{obj}");
    } else {
        let what = match &bodies {
            GravityBodies::Plummer { .. } => format!("Plummer, seed {}", args.seed),
            GravityBodies::Uniform { .. } => format!("uniform cube, seed {}", args.seed),
            GravityBodies::File(path) => path.display().to_string(),
        };
        let mut line = format!(
            "gravity {}: {} bodies ({what}, softening {}), {} thread(s): {seconds:.4e} s per force evaluation (median of {})",
            b.solver, b.n, args.softening, args.threads, args.repeat
        );
        if solver == GravitySolver::Direct {
            line += &format!(", {:.3} ns per pair", seconds / b.pairs * 1e9);
        }
        if let Some(r) = b.rms_relative_error {
            line += &format!(", RMS relative force error against direct {r:.3e}");
        }
        if let (Some(rms), Some(max)) = (b.rms_field_error, b.max_relative_error) {
            line += &format!(
                " (RMS error over RMS force {rms:.3e}, largest relative {max:.3e}, at {} bodies)",
                b.targets
            );
        }
        if let Some((nodes, particles)) = b.interactions {
            line += &format!(", {nodes} node and {particles} body interactions");
        }
        println!("{line}");
    }
    Ok(())
}

/// `cellist bench vortex`.
pub fn vortex(args: &BenchVortexArgs) -> CliResult {
    let pool = threads(Some(args.threads))?;
    let solver = match args.solver {
        VortexSolverArg::Direct => VortexBenchSolver::Direct,
        VortexSolverArg::BarnesHut => VortexBenchSolver::BarnesHut { theta: args.theta },
        VortexSolverArg::Mesh => VortexBenchSolver::Mesh { grid: args.grid },
        VortexSolverArg::Fmm => VortexBenchSolver::Fmm {
            accuracy: match args.order {
                Some(p) => FmmAccuracy::Order(p),
                None => FmmAccuracy::Tolerance(args.tolerance),
            },
        },
    };
    if let VortexBenchSolver::Fmm { accuracy } = solver {
        accuracy
            .check()
            .map_err(|m| CliError::Input(format!("--{m}")))?;
    }
    let points = match (&args.input, args.n) {
        (Some(path), _) if args.dim == 2 => VortexPoints::File {
            path: path.clone(),
            sigma: args.sigma,
        },
        (Some(_), _) => {
            return Err(CliError::Input(
                "--input reads 2D particles; with --dim 3 give --n".into(),
            ))
        }
        (None, Some(n)) if args.dim == 3 => return vortex3(args, n, solver, &pool),
        (None, n) => VortexPoints::Lattice { n: n.unwrap_or(0) },
    };
    let b = bench::vortex(solver, &points, args.repeat, args.sample, &pool)?;
    let what = match (b.spacing, b.sigma) {
        (Some(h), _) => format!("two Gaussian vortices, h {h:.3e}, sigma 1.5 h"),
        (None, Some(sigma)) => format!("blobs of sigma {sigma:e}"),
        (None, None) => "point vortices".to_string(),
    };
    if args.json {
        let obj = serde_json::json!({
            "solver": b.solver, "n": b.n, "threads": args.threads, "spacing": b.spacing,
            "sigma": b.sigma, "seconds_per_velocity": b.seconds, "repeat": args.repeat,
            "error_targets": b.targets,
            "rms_relative_velocity_error": b.rms_relative_error,
            "max_error_over_peak_speed": b.max_error_over_peak_speed,
            "max_relative_error": b.max_relative_error,
        });
        println!("{obj}");
    } else {
        println!(
            "vortex {}: {} particles ({what}), {} thread(s): \
             {:.4e} s per velocity evaluation (median of {}); against direct on {} particles: \
             RMS relative error {:.3e}, largest error / peak speed {:.3e}",
            b.solver,
            b.n,
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

/// `cellist bench vortex --dim 3`.
fn vortex3(
    args: &BenchVortexArgs,
    n: usize,
    solver: VortexBenchSolver,
    pool: &Threads,
) -> CliResult {
    let b = bench::vortex3(solver, n, args.repeat, args.sample, pool)?;
    let gradient_error = b.rms_relative_gradient_error.unwrap_or(0.0);
    if args.json {
        let obj = serde_json::json!({
            "dimension": 3, "solver": b.solver, "n": b.n, "threads": args.threads,
            "spacing": b.spacing, "sigma": b.sigma,
            "seconds_per_velocity_and_gradient": b.seconds, "repeat": args.repeat,
            "error_targets": b.targets,
            "rms_relative_velocity_error": b.rms_relative_error,
            "max_error_over_peak_speed": b.max_error_over_peak_speed,
            "rms_relative_gradient_error": gradient_error,
        });
        println!("{obj}");
    } else {
        println!(
            "vortex 3D {}: {} particles (a vortex ring of radius 1 and core 0.2, h {:.3e}, sigma 1.5 h), \
             {} thread(s): {:.4e} s per evaluation of the velocity and its gradient (median of {}); \
             against direct on {} particles: RMS relative error {:.3e} (velocity), {:.3e} (gradient), \
             largest velocity error / peak speed {:.3e}",
            b.solver,
            b.n,
            b.spacing.unwrap_or(f64::NAN),
            args.threads,
            b.seconds,
            args.repeat,
            b.targets,
            b.rms_relative_error,
            gradient_error,
            b.max_error_over_peak_speed
        );
    }
    Ok(())
}

/// `cellist bench billiards`: median wall time of whole runs.
pub fn billiards(args: &BenchBilliardsArgs) -> CliResult {
    let pool = threads(Some(args.threads))?;
    let request = bench::BilliardsRequest {
        input: &args.input,
        steps: args.steps,
        repeat: args.repeat,
        cells: args.cells.shape(),
    };
    let b = bench::billiards(&request, &pool)?;
    let (seconds, steps, n) = (b.seconds, b.steps, b.particles);
    let per_second = steps as f64 / seconds.max(1e-12);
    if args.json {
        let obj = serde_json::json!({
            "input": args.input.display().to_string(), "particles": n, "steps": steps,
            "threads": args.threads, "seconds": seconds, "steps_per_second": per_second,
            "max_sweeps": b.hardest.1, "hardest_step": b.hardest.0, "repeat": args.repeat,
            "cells": args.cells.name(),
        });
        println!("{obj}");
    } else {
        println!(
            "billiards: {} ({n} particles, {steps} steps), {} thread(s), {} cells: {seconds:.4} s \
             (median of {}), {per_second:.1} steps/s; hardest step {} needed {} sweeps",
            args.input.display(),
            args.threads,
            args.cells.name(),
            args.repeat,
            b.hardest.0,
            b.hardest.1
        );
    }
    Ok(())
}
