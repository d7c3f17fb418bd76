//! `cellist run` without a scenario: the neighbour-search demo. It times every stage
//! and strategy of the engine core on random points, checks that the strategies
//! agree, and writes the radial distribution function as a table, CSV and PNG.

use crate::bench::uniform_points;
use crate::cli::RunArgs;
use crate::error::{threads, CliError, CliResult};
use cellist::neighbors::{gather_cells, half_pairs, scatter_coloured, PairKernel};
use cellist::{CellList, StencilKind, Threads, VerletList};
use cellist_io::plot::{line_chart, Series};
use cellist_io::AtomicFile;
use std::io::Write;
use std::path::PathBuf;
use std::time::Instant;

const N: usize = 400_000;
const DENSITY: f64 = 0.8442;
const CUTOFF: f64 = 2.5;
const SKIN: f64 = 0.3;
const BINS: usize = 50;
const SEED: u64 = 1;

/// Which models `run` can run in this build, and the ones still to come.
const MODELS: &str = "\
models in this build: none yet besides this neighbour-search demo
coming: md (Lennard-Jones, LAMMPS-compatible), billiards (hard-disk collisions),
        pse (diffusion by particle strength exchange), gravity (direct, Barnes-Hut, PM, P3M)";

/// Counts neighbours: a kernel whose per-particle sum is exact, to compare strategies.
struct CountNeighbours;

impl PairKernel<3> for CountNeighbours {
    type Acc = u32;
    fn gather(&self, _: usize, _: usize, _: &[f64; 3], _: f64, acc_i: &mut u32) {
        *acc_i += 1;
    }
    fn scatter(&self, _: usize, _: usize, _: &[f64; 3], _: f64, acc_i: &mut u32, acc_j: &mut u32) {
        *acc_i += 1;
        *acc_j += 1;
    }
}

/// Runs the demo (or refuses a scenario, which needs a model).
pub fn run(args: &RunArgs) -> CliResult {
    if let Some(path) = &args.scenario {
        return Err(CliError::Input(format!(
            "cannot run {}: this build has no simulation model yet\n{MODELS}",
            path.display()
        )));
    }
    if !args.set.is_empty() {
        return Err(CliError::Input(
            "--set needs a scenario; the demo has no keys".into(),
        ));
    }
    let pool = threads(args.threads)?;
    let out = args
        .out
        .clone()
        .unwrap_or_else(|| PathBuf::from("out/neighbors-demo"));
    std::fs::create_dir_all(&out).map_err(CliError::output(format!(
        "the output folder {}",
        out.display()
    )))?;

    println!("cellist neighbour-search demo: {N} random points in a periodic cube, density {DENSITY}, cutoff {CUTOFF}, {} threads", pool.count());
    println!("{MODELS}\n");
    let (domain, points) = uniform_points::<3>(N, DENSITY, SEED);
    let mut stages: Vec<(&str, f64, String)> = Vec::new();
    let mut timed = |name: &'static str, f: &mut dyn FnMut() -> String| {
        let start = Instant::now();
        let note = f();
        stages.push((name, start.elapsed().as_secs_f64(), note));
    };

    let mut cells = None;
    timed("cell list (counting sort)", &mut || {
        let c = CellList::build(&domain, CUTOFF + SKIN, &points).expect("valid demo cutoff");
        let note = format!("{:?} cells", c.grid().dims());
        cells = Some(c);
        note
    });
    let cells = cells.expect("built above");
    let mut distances = Vec::new();
    timed("half pair list", &mut || {
        distances = half_pairs(&cells, CUTOFF, &pool, |_, _, r2| r2.sqrt());
        format!("{} pairs", distances.len())
    });
    let counts = strategy_counts(&cells, &pool, &mut timed)?;
    timed("Verlet list (full, skin 0.3)", &mut || {
        let v = VerletList::build(&cells, StencilKind::Full, CUTOFF, SKIN, &pool);
        format!("{} entries", v.num_entries())
    });
    if counts.iter().map(|&c| c as usize).sum::<usize>() != 2 * distances.len() {
        return Err(CliError::Internal(
            "pair list and neighbour counts disagree".into(),
        ));
    }

    println!("{:<32} {:>10}  note", "stage", "seconds");
    for (name, secs, note) in &stages {
        println!("{name:<32} {secs:>10.4}  {note}");
    }
    let rdf = radial_distribution(&distances, N, DENSITY);
    write_outputs(&out, &rdf, &stages)?;
    println!(
        "\nresults in {}/: rdf.csv, rdf.png, stages.csv",
        out.display()
    );
    Ok(())
}

/// Neighbour counts by gather and by coloured passes (which must agree); times both.
fn strategy_counts(
    cells: &CellList<3>,
    pool: &Threads,
    timed: &mut dyn FnMut(&'static str, &mut dyn FnMut() -> String),
) -> CliResult<Vec<u32>> {
    let mut gathered = vec![0u32; cells.len()];
    let mut coloured = vec![0u32; cells.len()];
    timed("neighbour count: gather", &mut || {
        gather_cells(cells, CUTOFF, &CountNeighbours, &mut gathered, pool);
        "full stencil, each particle writes itself".into()
    });
    timed("neighbour count: coloured", &mut || {
        scatter_coloured(cells, CUTOFF, &CountNeighbours, &mut coloured, pool);
        format!(
            "{} colours, half stencil, Newton's 3rd law",
            cells.grid().num_colours()
        )
    });
    if gathered != coloured {
        return Err(CliError::Internal(
            "gather and coloured passes disagree".into(),
        ));
    }
    Ok(gathered)
}

/// `g(r)` in `BINS` shells up to the cutoff: pair count per shell over the ideal-gas
/// count `(N / 2) rho (4 pi / 3) (r_hi^3 - r_lo^3)`.
fn radial_distribution(distances: &[f64], n: usize, density: f64) -> Vec<(f64, f64)> {
    let width = CUTOFF / BINS as f64;
    let mut hist = vec![0usize; BINS];
    for &r in distances {
        hist[((r / width) as usize).min(BINS - 1)] += 1;
    }
    hist.iter()
        .enumerate()
        .map(|(k, &count)| {
            let (lo, hi) = (k as f64 * width, (k + 1) as f64 * width);
            let ideal = 0.5 * n as f64 * density * 4.0 / 3.0
                * std::f64::consts::PI
                * (hi.powi(3) - lo.powi(3));
            (0.5 * (lo + hi), count as f64 / ideal)
        })
        .collect()
}

fn write_outputs(
    out: &std::path::Path,
    rdf: &[(f64, f64)],
    stages: &[(&str, f64, String)],
) -> CliResult {
    let mut body = String::from("r,g\n");
    for (r, g) in rdf {
        body.push_str(&format!("{r},{g}\n"));
    }
    write_whole(&out.join("rdf.csv"), &body)?;
    let mut body = String::from("stage,seconds,note\n");
    for (name, secs, note) in stages {
        body.push_str(&format!("{name},{secs},\"{note}\"\n"));
    }
    write_whole(&out.join("stages.csv"), &body)?;

    let png = out.join("rdf.png");
    line_chart(
        &png,
        "radial distribution of uniform random points (ideal gas: g = 1)",
        "r",
        "g(r)",
        &[Series {
            label: "g(r)",
            points: rdf,
        }],
    )
    .map_err(|e| CliError::Output(std::io::Error::other(e), png.display().to_string()))
}

/// Writes `body` to `path`, whole or not at all.
fn write_whole(path: &std::path::Path, body: &str) -> CliResult {
    let what = path.display().to_string();
    let mut f = AtomicFile::create(path).map_err(CliError::output(&what))?;
    f.writer()
        .write_all(body.as_bytes())
        .map_err(CliError::output(&what))?;
    f.commit().map_err(CliError::output(what))
}
