//! `cellist sweep`: a scenario run for every combination of the values of some
//! of its keys (and thread counts), with the chosen metrics of each run.

use super::metric::Metric;
use super::table::{Column, SweepTable};
use super::{
    create_dir, median, probe, progress, report_warnings, run_dir, run_quiet, study_dir, Pools,
    SweptKey,
};
use crate::error::{SimError, SimResult};
use crate::scenario::Scenario;
use std::path::{Path, PathBuf};

/// What `cellist sweep` asks for.
pub struct SweepRequest<'a> {
    /// The scenario file.
    pub scenario: &'a Path,
    /// The swept keys, `KEY=V1,V2,...`.
    pub sets: &'a [String],
    /// Thread counts (`None`: every core, not swept).
    pub threads: Option<Vec<usize>>,
    /// Metric names (none: `time`).
    pub metrics: &'a [String],
    /// Runs per combination; times are their median.
    pub repeat: usize,
    /// The output folder (default `out/<scenario>-sweep/`).
    pub out: Option<PathBuf>,
}

/// One combination of values: the overrides, the thread count, and the values as
/// text for the table.
struct Combination {
    sets: Vec<String>,
    threads: usize,
    values: Vec<String>,
}

/// Runs the sweep: checks every combination and metric first, runs them (each
/// combination `repeat` times, the combinations alternating), prints the table
/// and writes `sweep.csv` and the PNGs.
pub fn sweep(request: &SweepRequest) -> SimResult<SweepTable> {
    let scenario = Scenario::load(Some(request.scenario), &[])?;
    if request.repeat == 0 {
        return Err(SimError::Input("--repeat must be at least 1".into()));
    }
    let keys: Vec<SweptKey> = request
        .sets
        .iter()
        .map(|s| SweptKey::parse(s))
        .collect::<SimResult<_>>()?;
    let mut named: Vec<&str> = Vec::new();
    for key in keys.iter().flat_map(|k| &k.keys) {
        if named.contains(&key.as_str()) {
            return Err(SimError::Input(format!(
                "--set {key}: the key is swept twice; give all its values in one --set"
            )));
        }
        named.push(key);
    }
    let threads = match &request.threads {
        Some(list) => super::thread_counts(list)?,
        None => vec![super::cores()],
    };
    if keys.is_empty() && threads.len() < 2 {
        return Err(SimError::Input(
            "nothing to sweep: give --set KEY=V1,V2,... or --threads with several counts".into(),
        ));
    }
    let metrics: Vec<Metric> = if request.metrics.is_empty() {
        vec![Metric::LoopTime]
    } else {
        request.metrics.iter().map(|m| Metric::parse(m)).collect()
    };
    let combinations = combinations(&keys, &threads);
    // check every combination's keys and values, and every metric, before any run
    let mut scenarios = Vec::new();
    for c in combinations.iter().step_by(threads.len()) {
        let label = if c.sets.is_empty() {
            scenario.origin.clone()
        } else {
            format!("--set {}", c.sets.join(" --set "))
        };
        let s = scenario.with_sets(&c.sets)?;
        let probed = probe(&s, &label)?;
        for m in &metrics {
            m.check(&probed)?;
        }
        scenarios.push(s);
    }
    let dir = study_dir(request.out.as_deref(), &scenario.name, "sweep");
    create_dir(&dir)?;
    let mut key_names: Vec<String> = keys.iter().flat_map(|k| k.keys.clone()).collect();
    key_names.push("threads".into());
    // a key that moves with the one before it (KEY1+KEY2=...)
    let mut linked: Vec<bool> = keys
        .iter()
        .flat_map(|k| (0..k.keys.len()).map(|j| j > 0))
        .collect();
    linked.push(false);
    println!(
        "sweep of {}: {} combinations of {}, {} run(s) each; runs in {}",
        scenario.origin,
        combinations.len(),
        key_names.join(", "),
        request.repeat,
        dir.join("runs").display()
    );
    let pools = Pools::new(&threads)?;
    let cores = super::cores();
    // the progress lines name the keys that take several values
    let mut swept: Vec<usize> = keys
        .iter()
        .flat_map(|k| std::iter::repeat_n(k.values.len() > 1, k.keys.len()))
        .enumerate()
        .filter_map(|(at, varies)| varies.then_some(at))
        .collect();
    if threads.len() > 1 {
        swept.push(key_names.len() - 1);
    }
    let mut measured: Vec<Vec<Vec<f64>>> = vec![Vec::new(); combinations.len()];
    let mut warnings = Vec::new();
    // an error other than a blow-up stops the sweep, but what was measured is
    // still reported and written
    let mut failed = None;
    'rounds: for round in 0..request.repeat {
        for (k, c) in combinations.iter().enumerate() {
            let s = &scenarios[k / threads.len()];
            let threads = pools.get(c.threads);
            let what = progress(
                k,
                combinations.len(),
                round,
                request.repeat,
                &describe(&key_names, &c.values, &swept),
            );
            let values = match run_quiet(s, threads, &run_dir(&dir, k)) {
                Ok(summary) => {
                    report_warnings(&summary, &mut warnings);
                    let v: Vec<f64> = metrics.iter().map(|m| m.value(&summary)).collect();
                    let over = if c.threads > cores {
                        format!(" (oversubscribed: {} threads on {cores} cores)", c.threads)
                    } else {
                        String::new()
                    };
                    println!(
                        "{what}: loop {:.4} s{over}",
                        summary.loop_time.as_secs_f64()
                    );
                    v
                }
                Err(SimError::BlowUp(m)) => {
                    println!("{what}: blew up: {m}");
                    vec![f64::NAN; metrics.len()]
                }
                Err(e) => {
                    failed = Some(e);
                    break 'rounds;
                }
            };
            measured[k].push(values);
        }
    }
    let rows = combinations
        .iter()
        .zip(&measured)
        .filter(|(_, runs)| !runs.is_empty())
        .map(|(c, runs)| {
            let values = metrics
                .iter()
                .enumerate()
                .map(|(m, metric)| {
                    let all: Vec<f64> = runs.iter().map(|r| r[m]).collect();
                    if all.iter().any(|v| v.is_nan()) {
                        // a run that blew up makes the row's value NaN
                        f64::NAN
                    } else if metric.is_time() {
                        median(&all)
                    } else {
                        *all.last().expect("one run at least")
                    }
                })
                .collect();
            (c.values.clone(), values)
        })
        .collect();
    let table = SweepTable {
        subject: format!("sweep of {}", scenario.name),
        keys: key_names,
        linked,
        metrics: metrics
            .iter()
            .map(|m| Column {
                name: m.name(),
                label: m.label(),
            })
            .collect(),
        rows,
    };
    table.report(&dir)?;
    match failed {
        Some(e) => Err(e),
        None => Ok(table),
    }
}

/// Every combination of the keys' values and the thread counts, the first key
/// varying slowest and the thread count fastest.
fn combinations(keys: &[SweptKey], threads: &[usize]) -> Vec<Combination> {
    let mut combos = vec![(Vec::new(), Vec::new())];
    for key in keys {
        combos = combos
            .into_iter()
            .flat_map(|(sets, values): (Vec<String>, Vec<String>)| {
                (0..key.values.len()).map(move |k| {
                    let mut s = sets.clone();
                    s.extend(key.set(k));
                    let mut v = values.clone();
                    v.extend(key.values[k].iter().cloned());
                    (s, v)
                })
            })
            .collect();
    }
    combos
        .into_iter()
        .flat_map(|(sets, values)| {
            threads.iter().map(move |&t| {
                let mut v = values.clone();
                v.push(t.to_string());
                Combination {
                    sets: sets.clone(),
                    threads: t,
                    values: v,
                }
            })
        })
        .collect()
}

/// `key = value, ...` of one combination, for the keys `shown`.
fn describe(keys: &[String], values: &[String], shown: &[usize]) -> String {
    shown
        .iter()
        .map(|&k| format!("{} = {}", keys[k], values[k]))
        .collect::<Vec<_>>()
        .join(", ")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn combinations_vary_the_first_key_slowest_and_threads_fastest() {
        let keys = [
            SweptKey::parse("a=1,2").unwrap(),
            SweptKey::parse("b=x,y,z").unwrap(),
        ];
        let c = combinations(&keys, &[1, 2]);
        assert_eq!(c.len(), 12);
        let linked = [SweptKey::parse("a+b=[1,\"x\"],[2,\"y\"]").unwrap()];
        let l = combinations(&linked, &[1]);
        assert_eq!(l.len(), 2);
        assert_eq!(l[1].sets, ["a=2", "b=\"y\""]);
        assert_eq!(l[1].values, ["2", "\"y\"", "1"]);
        assert_eq!(c[0].sets, ["a=1", "b=x"]);
        assert_eq!(c[0].values, ["1", "x", "1"]);
        assert_eq!(c[1].values, ["1", "x", "2"]);
        assert_eq!(c[2].values, ["1", "y", "1"]);
        assert_eq!(c[11].values, ["2", "z", "2"]);
        assert_eq!(c[11].threads, 2);
    }
}
