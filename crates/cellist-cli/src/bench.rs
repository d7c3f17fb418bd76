//! `cellist bench ...`: timings on standard workloads, medians of repeated runs.

use crate::cli::{BenchLjArgs, BenchNeighborsArgs};
use crate::error::{positive, threads, CliError, CliResult};
use cellist::interactions::LennardJones;
use cellist::models::md::{
    create_velocities, late_note, lattice, Atoms, Integrator, LatticeKind, MdSystem, StageTimes,
    VelocityDistribution,
};
use cellist::neighbors::{half_list_as_found, half_pairs, sorted_half_list, RebuildRule};
use cellist::random::Rng;
use cellist::{CellList, Domain, Threads};
use cellist_sim::study::median;
use std::time::Instant;

/// `n` uniform random points in the periodic box `[0, L)^D` with `L = (n / rho)^(1/D)`.
pub fn uniform_points<const D: usize>(
    n: usize,
    density: f64,
    seed: u64,
) -> (Domain<D>, Vec<[f64; D]>) {
    let side = (n as f64 / density).powf(1.0 / D as f64);
    let mut rng = Rng::new(seed);
    let points = (0..n)
        .map(|_| std::array::from_fn(|_| rng.uniform() * side))
        .collect();
    let domain = Domain::periodic([side; D]).expect("a positive side");
    (domain, points)
}

/// `cellist bench neighbors`.
pub fn neighbors(args: &BenchNeighborsArgs) -> CliResult {
    positive("--density", args.density)?;
    positive("--cutoff", args.cutoff)?;
    if args.n < 2 {
        return Err(CliError::Input("--n must be at least 2".into()));
    }
    if args.repeat == 0 {
        return Err(CliError::Input("--repeat must be at least 1".into()));
    }
    let pool = threads(Some(args.threads))?;
    let (seconds, pairs) = match args.dim {
        2 => time_half_list::<2>(args, &pool)?,
        _ => time_half_list::<3>(args, &pool)?,
    };
    let ns_per_pair = seconds * 1e9 / pairs.max(1) as f64;
    if args.json {
        let mut obj = serde_json::json!({
            "n": args.n, "dim": args.dim, "threads": args.threads, "pairs": pairs,
            "seconds": seconds, "ns_per_pair": ns_per_pair,
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
            match (args.sorted, args.as_found) {
                (true, _) => " (sorted)",
                (_, true) => " (as found, int64)",
                _ => "",
            },
            args.n, args.dim, args.threads, seconds, args.repeat, pairs, ns_per_pair
        );
    }
    Ok(())
}

/// Median wall time of cell-list build plus half pair list, and the pair count.
fn time_half_list<const D: usize>(
    args: &BenchNeighborsArgs,
    pool: &Threads,
) -> CliResult<(f64, usize)> {
    let (domain, points) = uniform_points::<D>(args.n, args.density, args.seed);
    let mut times = Vec::with_capacity(args.repeat);
    let mut count = 0;
    for _ in 0..args.repeat {
        let start = Instant::now();
        let cells = CellList::build_in(&domain, args.cutoff, &points, pool)
            .map_err(|e| CliError::Input(format!("--cutoff {}: {e}", args.cutoff)))?;
        count = if args.sorted || args.as_found {
            let list = if args.sorted {
                sorted_half_list
            } else {
                half_list_as_found
            };
            let pairs = list(&cells, &points, args.cutoff, Default::default(), pool);
            times.push(start.elapsed().as_secs_f64());
            pairs.len()
        } else {
            let pairs = half_pairs(&cells, args.cutoff, pool, |i, j, _| [i, j]);
            times.push(start.elapsed().as_secs_f64());
            pairs.len()
        };
    }
    Ok((median(&times), count))
}

/// The peak resident set of this process (`VmHWM` of `/proc/self/status`), in
/// bytes; None where the file is not there (not Linux).
fn peak_resident_bytes() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}

/// `cellist bench lj`: the loop time of the LAMMPS melt, as LAMMPS reports it (set-up
/// excluded), median over `--repeat` runs from the same start.
pub fn lj(args: &BenchLjArgs) -> CliResult {
    if args.atoms_per_side > 1000 {
        return Err(CliError::Input(
            "--atoms-per-side must be at most 1000".into(),
        ));
    }
    if args.atoms_per_side < 4 {
        return Err(CliError::Input(
            "--atoms-per-side must be at least 4 (the box must hold twice cutoff + skin)".into(),
        ));
    }
    if args.repeat == 0 {
        return Err(CliError::Input("--repeat must be at least 1".into()));
    }
    let pool = threads(Some(args.threads))?;
    let n = args.atoms_per_side;
    // the start is made anew for every repetition rather than kept as a copy,
    // so that the peak memory is the run's own
    let melt_start = || {
        let (domain, points) = lattice(LatticeKind::Fcc, 0.8442, [n; 3])
            .map_err(|e| CliError::Internal(format!("melt lattice: {e}")))?;
        let mut atoms = Atoms::at_rest(points, 1.0);
        create_velocities(&mut atoms, 3.0, 87287, VelocityDistribution::Uniform);
        Ok::<_, CliError>((domain, atoms))
    };
    let lj = LennardJones::new(1.0, 1.0, 2.5, false)
        .map_err(|e| CliError::Internal(format!("melt potential: {e}")))?;
    let rule = RebuildRule {
        every: args.every,
        check: !args.no_check,
    };
    let mut samples = Vec::with_capacity(args.repeat);
    let mut last = None;
    let mut atoms_n = 0;
    for _ in 0..args.repeat {
        let (domain, atoms) = melt_start()?;
        atoms_n = atoms.len();
        let mut system = MdSystem::new(domain, atoms, lj, 0.3, &pool)
            .map_err(|e| CliError::Internal(format!("melt set-up: {e}")))?;
        system.set_rebuild_rule(rule);
        let mut times = StageTimes::default();
        let start = Instant::now();
        for step in 1..=args.steps {
            system
                .step(
                    &Integrator::VelocityVerlet,
                    0.005,
                    step,
                    step == args.steps,
                    &pool,
                    &mut times,
                )
                .map_err(|e| CliError::Internal(format!("the melt blew up: {e}")))?;
        }
        samples.push(start.elapsed().as_secs_f64());
        last = Some((system.list_counts(), times));
    }
    let (counts, times) = last.expect("at least one repetition");
    let rebuilds = counts.rebuilds;
    let peak_rss = peak_resident_bytes();
    let seconds = median(&samples);
    let us = seconds * 1e6 / (atoms_n as f64 * args.steps.max(1) as f64);
    if args.json {
        let obj = serde_json::json!({
            "atoms": atoms_n, "steps": args.steps, "threads": args.threads,
            "loop_seconds": seconds, "us_per_atom_step": us, "rebuilds": rebuilds,
            "force_seconds": times.force.as_secs_f64(), "neighbor_seconds": times.neighbor.as_secs_f64(),
            "every": rule.every, "check": rule.check, "late_builds": counts.late_builds,
            "peak_rss_bytes": peak_rss,
            "peak_rss_bytes_per_atom": peak_rss.map(|b| b as f64 / atoms_n as f64),
        });
        println!("{obj}");
    } else {
        let memory = peak_rss.map_or(String::new(), |b| {
            format!(
                ", peak resident memory {:.1} MB ({:.0} bytes/atom)",
                b as f64 / 1e6,
                b as f64 / atoms_n as f64
            )
        });
        println!(
            "lj: {atoms_n} atoms, {} steps, {} thread(s), list every {} check {}: loop time {seconds:.4} s \
             (median of {}), {us:.4} us/atom-step, {rebuilds} rebuilds{}{memory}",
            args.steps,
            args.threads,
            rule.every,
            if rule.check { "yes" } else { "no" },
            args.repeat,
            late_note(counts.late_builds),
        );
    }
    Ok(())
}
