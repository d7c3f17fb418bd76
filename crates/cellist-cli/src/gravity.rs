//! `cellist bench gravity`: one force evaluation of a Plummer sphere by a solver,
//! timed, with its error against the direct sum.

use crate::cli::{BenchGravityArgs, GravitySolverArg};
use crate::error::{threads, CliError, CliResult};
use cellist::interactions::GravityLaw;
use cellist::longrange::{DirectSum, FieldOut, MeshBoundary, MeshParams, Sources, TreeParams};
use cellist::models::gravity::{plummer, Solver, SolverChoice};
use cellist_sim::models::gravity::MAX_BODIES;
use cellist_sim::study::median;
use std::time::Instant;

/// `cellist bench gravity`.
pub fn bench(args: &BenchGravityArgs) -> CliResult {
    if !(2..=MAX_BODIES).contains(&args.n) {
        return Err(CliError::Input(format!(
            "--n must be in 2..={MAX_BODIES}, got {}",
            args.n
        )));
    }
    if args.repeat == 0 {
        return Err(CliError::Input("--repeat must be at least 1".into()));
    }
    let pool = threads(Some(args.threads))?;
    let law = GravityLaw::new(1.0, args.softening, 0.0).map_err(CliError::Input)?;
    let bodies = plummer(args.n, args.seed, &law, &pool);
    let (choice, name) = match args.solver {
        GravitySolverArg::Direct => (SolverChoice::Direct, "direct".to_string()),
        GravitySolverArg::BarnesHut => {
            let params = TreeParams {
                theta: args.theta,
                quadrupole: !args.monopole,
                leaf_size: args.leaf_size,
                group_size: args.group_size,
            };
            params.check().map_err(CliError::Input)?;
            (SolverChoice::BarnesHut(params), "barnes-hut".to_string())
        }
        GravitySolverArg::Pm => (
            SolverChoice::Pm(MeshParams {
                grid: args.grid,
                boundary: MeshBoundary::Isolated,
            }),
            "pm".to_string(),
        ),
        GravitySolverArg::P3m => (
            SolverChoice::P3m {
                mesh: MeshParams {
                    grid: args.grid,
                    boundary: MeshBoundary::Isolated,
                },
                split_cells: args.split,
            },
            "p3m".to_string(),
        ),
    };
    let mut solver = Solver::new(&choice, law, args.n).map_err(CliError::Input)?;
    let sources = Sources {
        mass: &bodies.mass,
        position: &bodies.position,
    };
    let mut acc = vec![[0.0; 3]; args.n];
    let mut phi = vec![0.0; args.n];
    let mut samples = Vec::with_capacity(args.repeat + 1);
    // one untimed evaluation first: it builds the tables and buffers
    for _ in 0..=args.repeat {
        let start = Instant::now();
        solver.compute(
            &sources,
            FieldOut {
                acc: &mut acc,
                phi: &mut phi,
            },
            &pool,
        );
        samples.push(start.elapsed().as_secs_f64());
    }
    let seconds = median(&samples[1..]);
    let pairs = (args.n as f64) * (args.n as f64 - 1.0) / 2.0;
    let rms = match choice {
        SolverChoice::Direct => None,
        _ => {
            let mut exact = vec![[0.0; 3]; args.n];
            let mut exact_phi = vec![0.0; args.n];
            DirectSum::new(law, args.n).compute(
                &sources,
                FieldOut {
                    acc: &mut exact,
                    phi: &mut exact_phi,
                },
                &pool,
            );
            Some(rms_relative_error(&acc, &exact))
        }
    };
    let interactions = match &solver {
        Solver::BarnesHut(t) => Some(t.interactions()),
        _ => None,
    };
    if args.json {
        let mut obj = serde_json::json!({
            "solver": name, "n": args.n, "threads": args.threads, "softening": args.softening,
            "seconds_per_force": seconds, "repeat": args.repeat, "seed": args.seed,
        });
        match choice {
            SolverChoice::Direct => {
                obj["ns_per_pair"] = serde_json::json!(seconds / pairs * 1e9);
            }
            SolverChoice::BarnesHut(p) => {
                obj["theta"] = serde_json::json!(p.theta);
                obj["quadrupole"] = serde_json::json!(p.quadrupole);
                obj["leaf_size"] = serde_json::json!(p.leaf_size);
                obj["group_size"] = serde_json::json!(p.group_size);
            }
            SolverChoice::Pm(m) => obj["grid"] = serde_json::json!(m.grid),
            SolverChoice::P3m { mesh, split_cells } => {
                obj["grid"] = serde_json::json!(mesh.grid);
                obj["split_cells"] = serde_json::json!(split_cells);
            }
        }
        if let Some(r) = rms {
            obj["rms_relative_force_error"] = serde_json::json!(r);
        }
        if let Some((nodes, particles)) = interactions {
            obj["node_interactions"] = serde_json::json!(nodes);
            obj["particle_interactions"] = serde_json::json!(particles);
        }
        println!("{obj}");
    } else {
        let mut line = format!(
            "gravity {name}: {} bodies (Plummer, seed {}, softening {}), {} thread(s): {seconds:.4e} s per force evaluation (median of {})",
            args.n, args.seed, args.softening, args.threads, args.repeat
        );
        if let SolverChoice::Direct = choice {
            line += &format!(", {:.3} ns per pair", seconds / pairs * 1e9);
        }
        if let Some(r) = rms {
            line += &format!(", RMS relative force error against direct {r:.3e}");
        }
        if let Some((nodes, particles)) = interactions {
            line += &format!(", {nodes} node and {particles} body interactions");
        }
        println!("{line}");
    }
    Ok(())
}

/// `sqrt(mean_i (|a_i - e_i| / |e_i|)^2)`.
fn rms_relative_error(got: &[[f64; 3]], exact: &[[f64; 3]]) -> f64 {
    let norm = |v: [f64; 3]| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    let sum: f64 = got
        .iter()
        .zip(exact)
        .map(|(g, e)| (norm([g[0] - e[0], g[1] - e[1], g[2] - e[2]]) / norm(*e)).powi(2))
        .sum();
    (sum / got.len() as f64).sqrt()
}
