//! `cellist billiards sweep`: seed 001's studies of its collision code on
//! generated inputs. Every combination of particle count `N`, box side `L`,
//! radius `r`, steps `S`, cell layout and thread count gets an input drawn in
//! memory with the course generator's recipe (or the separated one), and the loop
//! of `S` collision steps is timed, the combinations alternating, the median
//! reported. The output is that of `cellist sweep`: a table, `sweep.csv` and
//! `sweep.png`.

use super::table::{Column, SweepTable};
use super::{cores, create_dir, median, progress, thread_counts, Pools};
use crate::error::{SimError, SimResult};
use cellist::models::billiards::{separated_discs, uniform_discs, Billiards, CellShape, Table};
use std::path::PathBuf;

/// What `cellist billiards sweep` asks for: a list of values per key (one value
/// is fixed, several are swept).
pub struct BilliardsSweepRequest<'a> {
    /// Particle counts `N` (`--n`).
    pub n: &'a [usize],
    /// Box sides `L` (`--l`).
    pub l: &'a [i64],
    /// Disc radii `r` (`--r`).
    pub r: &'a [i64],
    /// Steps `S` (`--steps`): the timed loop.
    pub steps: &'a [u64],
    /// Layouts of the contact search's cells (`--cells`).
    pub cells: &'a [CellShape],
    /// Thread counts (`--threads`; `None`: every core).
    pub threads: Option<Vec<usize>>,
    /// Smallest velocity component (`--vmin`).
    pub vmin: f64,
    /// Largest velocity component (`--vmax`).
    pub vmax: f64,
    /// Seed of the random numbers (`--seed`): the same for every combination.
    pub seed: u64,
    /// Uniform positions as the course's generator (`--overlaps`); otherwise the
    /// separated placement, which refuses densities above `pi / 4`.
    pub overlaps: bool,
    /// Timed runs per combination (`--repeat`); the time is their median.
    pub repeat: usize,
    /// The output folder (default `out/billiards-sweep/`).
    pub out: Option<PathBuf>,
}

/// The keys of the table, in the order of their columns (the first varies
/// slowest).
pub const KEYS: [&str; 6] = ["N", "L", "r", "S", "cells", "threads"];

/// One combination of the keys' values.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Combination {
    /// Particles.
    pub n: usize,
    /// Box side.
    pub l: i64,
    /// Radius.
    pub r: i64,
    /// Steps.
    pub steps: u64,
    /// Cell layout.
    pub cells: CellShape,
    /// Worker threads.
    pub threads: usize,
}

impl Combination {
    /// The values in the order of [`KEYS`], as text for the table.
    pub fn values(&self) -> Vec<String> {
        vec![
            self.n.to_string(),
            self.l.to_string(),
            self.r.to_string(),
            self.steps.to_string(),
            self.cells.name().to_string(),
            self.threads.to_string(),
        ]
    }

    /// `N = .., L = .., r = .., S = .., cells = .., threads = ..`.
    pub fn describe(&self) -> String {
        KEYS.iter()
            .zip(self.values())
            .map(|(k, v)| format!("{k} = {v}"))
            .collect::<Vec<_>>()
            .join(", ")
    }

    /// The input this combination runs on: `(N, L, r)`.
    fn input(&self) -> (usize, i64, i64) {
        (self.n, self.l, self.r)
    }
}

/// Every combination of the lists, `N` varying slowest and the thread count
/// fastest (the order of [`KEYS`]).
pub fn combinations(
    n: &[usize],
    l: &[i64],
    r: &[i64],
    steps: &[u64],
    cells: &[CellShape],
    threads: &[usize],
) -> Vec<Combination> {
    let mut all = Vec::new();
    for &n in n {
        for &l in l {
            for &r in r {
                for &steps in steps {
                    for &cells in cells {
                        for &threads in threads {
                            all.push(Combination {
                                n,
                                l,
                                r,
                                steps,
                                cells,
                                threads,
                            });
                        }
                    }
                }
            }
        }
    }
    all
}

/// Refuses an empty list, and values for which `bad` gives a reason, naming the
/// flag.
fn check_list<T: Copy + std::fmt::Display>(
    flag: &str,
    list: &[T],
    bad: impl Fn(T) -> Option<&'static str>,
) -> SimResult {
    if list.is_empty() {
        return Err(SimError::Input(format!(
            "{flag}: an empty list; give one value, or several separated by commas"
        )));
    }
    for &v in list {
        if let Some(why) = bad(v) {
            return Err(SimError::Input(format!("{flag}: {v} in the list: {why}")));
        }
    }
    Ok(())
}

/// Checks every flag, naming the one at fault.
fn check(request: &BilliardsSweepRequest) -> SimResult<Vec<usize>> {
    if request.repeat == 0 {
        return Err(SimError::Input("--repeat must be at least 1".into()));
    }
    check_list("--n", request.n, |n| {
        (n == 0).then_some("particle counts are at least 1")
    })?;
    check_list("--l", request.l, |l| {
        (l <= 0).then_some("the box side must be a positive integer")
    })?;
    check_list("--r", request.r, |r| {
        (r <= 0).then_some("the radius must be a positive integer")
    })?;
    check_list("--steps", request.steps, |s| {
        (s == 0).then_some("steps are at least 1")
    })?;
    if request.cells.is_empty() {
        return Err(SimError::Input(
            "--cells: an empty list; give square, hex or square,hex".into(),
        ));
    }
    if !(request.vmin.is_finite() && request.vmax.is_finite() && request.vmin <= request.vmax) {
        return Err(SimError::Input(format!(
            "--vmin ({}) and --vmax ({}) must be finite with --vmin <= --vmax",
            request.vmin, request.vmax
        )));
    }
    match &request.threads {
        Some(list) => thread_counts(list),
        None => Ok(vec![cores()]),
    }
}

/// Runs the sweep: checks the flags, draws and checks every combination's input
/// (a density the separated placement cannot reach is refused here, naming the
/// combination, before anything is timed), then times every combination
/// `repeat` times round-robin, prints one line per run and the table, and writes
/// `sweep.csv` and the PNGs.
pub fn sweep(request: &BilliardsSweepRequest) -> SimResult<SweepTable> {
    let threads = check(request)?;
    let combinations = combinations(
        request.n,
        request.l,
        request.r,
        request.steps,
        request.cells,
        &threads,
    );
    // every input first: (N, L, r, cells) -> the start of its runs
    let mut starts: Vec<((usize, i64, i64), CellShape, Billiards)> = Vec::new();
    let mut densities = Vec::new();
    for c in &combinations {
        if starts
            .iter()
            .any(|(i, s, _)| *i == c.input() && *s == c.cells)
        {
            continue;
        }
        let label = format!("N = {}, L = {}, r = {}", c.n, c.l, c.r);
        let table = Table {
            side: c.l,
            radius: c.r,
        };
        let drawn = match starts.iter().find(|(i, _, _)| *i == c.input()) {
            Some((_, _, s)) => (s.x.clone(), s.y.clone(), s.v.clone()),
            None => {
                let d = if request.overlaps {
                    uniform_discs(c.n, &table, request.vmin, request.vmax, request.seed)
                } else {
                    separated_discs(c.n, &table, request.vmin, request.vmax, request.seed)
                        .map_err(|e| SimError::Input(format!("{label}: {e}")))?
                };
                let density =
                    c.n as f64 * std::f64::consts::PI * (c.r as f64).powi(2) / (c.l as f64).powi(2);
                densities.push(format!("{label}: density N pi r^2 / L^2 = {density:.3}"));
                (d.x, d.y, d.v)
            }
        };
        let system = Billiards::new(table, drawn.0, drawn.1, drawn.2)
            .map_err(|e| SimError::Input(format!("{label}: {e}")))?
            .with_cells(c.cells);
        starts.push((c.input(), c.cells, system));
    }
    let dir = super::study_dir(request.out.as_deref(), "billiards", "sweep");
    create_dir(&dir)?;
    let placement = if request.overlaps {
        "uniform positions (--overlaps, the course's generator)"
    } else {
        "separated discs"
    };
    println!(
        "billiards sweep: {} combinations of {}, {} timed run(s) each; inputs: {placement}, \
         velocity components in [{}, {}], seed {}",
        combinations.len(),
        KEYS.join(", "),
        request.repeat,
        request.vmin,
        request.vmax,
        request.seed
    );
    for d in &densities {
        println!("  {d}");
    }
    let pools = Pools::new(&threads)?;
    let cores = cores();
    let mut times: Vec<Vec<f64>> = vec![Vec::new(); combinations.len()];
    let mut sweeps = vec![f64::NAN; combinations.len()];
    for round in 0..request.repeat {
        for (k, c) in combinations.iter().enumerate() {
            let start = &starts
                .iter()
                .find(|(i, s, _)| *i == c.input() && *s == c.cells)
                .expect("an input per combination")
                .2;
            let threads = pools.get(c.threads);
            let what = progress(k, combinations.len(), round, request.repeat, &c.describe());
            match crate::billiards::time_steps(start, c.steps, threads) {
                Ok((seconds, (_, hardest))) => {
                    let over = if c.threads > cores {
                        format!(" (oversubscribed: {} threads on {cores} cores)", c.threads)
                    } else {
                        String::new()
                    };
                    println!("{what}: loop {seconds:.4} s, hardest step {hardest} sweeps{over}");
                    times[k].push(seconds);
                    sweeps[k] = hardest as f64;
                }
                Err(SimError::BlowUp(m)) => {
                    println!("{what}: stopped: {m}");
                    times[k].push(f64::NAN);
                }
                Err(e) => return Err(e),
            }
        }
    }
    let rows = combinations
        .iter()
        .zip(&times)
        .zip(&sweeps)
        .map(|((c, runs), &hardest)| {
            let time = if runs.iter().any(|t| t.is_nan()) {
                f64::NAN
            } else {
                median(runs)
            };
            let disc_steps = c.n as f64 * c.steps as f64;
            (
                c.values(),
                vec![
                    time,
                    c.steps as f64 / time,
                    time * 1e9 / disc_steps,
                    hardest,
                ],
            )
        })
        .collect();
    let column = |name: &str, label: &str| Column {
        name: name.into(),
        label: label.into(),
    };
    let table = SweepTable {
        subject: format!(
            "billiards sweep ({})",
            if request.overlaps {
                "uniform, overlaps"
            } else {
                "separated"
            }
        ),
        keys: KEYS.iter().map(|k| k.to_string()).collect(),
        linked: vec![false; KEYS.len()],
        metrics: vec![
            column("time", "loop wall time of S steps (s)"),
            column("steps_per_s", "steps per second (1/s)"),
            column("ns_per_disc_step", "time per disc and step (ns)"),
            column("max_sweeps", "sweeps of the hardest step"),
        ],
        rows,
    };
    table.report(&dir)?;
    Ok(table)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn combinations_vary_n_slowest_and_threads_fastest() {
        let c = combinations(
            &[100, 200],
            &[1000],
            &[5, 10],
            &[10],
            &[CellShape::Square, CellShape::Hex],
            &[1, 2],
        );
        assert_eq!(c.len(), 16);
        assert_eq!(c[0].values(), ["100", "1000", "5", "10", "square", "1"]);
        assert_eq!(c[1].values(), ["100", "1000", "5", "10", "square", "2"]);
        assert_eq!(c[2].values(), ["100", "1000", "5", "10", "hex", "1"]);
        assert_eq!(c[4].values(), ["100", "1000", "10", "10", "square", "1"]);
        assert_eq!(c[8].values(), ["200", "1000", "5", "10", "square", "1"]);
        assert_eq!(c[15].values(), ["200", "1000", "10", "10", "hex", "2"]);
        assert_eq!(
            c[15].describe(),
            "N = 200, L = 1000, r = 10, S = 10, cells = hex, threads = 2"
        );
    }

    fn request<'a>(n: &'a [usize], r: &'a [i64], out: PathBuf) -> BilliardsSweepRequest<'a> {
        BilliardsSweepRequest {
            n,
            l: &[100],
            r,
            steps: &[3],
            cells: &[CellShape::Square],
            threads: Some(vec![1]),
            vmin: 2.0,
            vmax: 5.0,
            seed: 1,
            overlaps: false,
            repeat: 1,
            out: Some(out),
        }
    }

    #[test]
    fn bad_flags_and_dense_separated_inputs_are_refused_before_any_run() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("sweep");
        let message = |req: &BilliardsSweepRequest| match sweep(req) {
            Err(SimError::Input(m)) => m,
            other => panic!("expected an input error, got {:?}", other.map(|_| ())),
        };
        assert!(message(&request(&[], &[2], out.clone())).starts_with("--n: an empty list"));
        assert!(message(&request(&[0], &[2], out.clone())).starts_with("--n: 0"));
        assert!(message(&request(&[10], &[-2], out.clone())).starts_with("--r: -2"));
        // 24 squares of side > 4 per axis: at most 576 separated discs
        let m = message(&request(&[10, 577], &[2], out.clone()));
        assert!(m.starts_with("N = 577, L = 100, r = 2: "), "{m}");
        assert!(!out.exists(), "nothing written");
        let table = sweep(&request(&[10, 20], &[2], out.clone())).unwrap();
        assert_eq!(table.rows.len(), 2);
        assert!(table.rows.iter().all(|(_, m)| m[0] > 0.0 && m[3] >= 1.0));
        assert!(out.join("sweep.csv").exists() && out.join("sweep.png").exists());
    }
}
