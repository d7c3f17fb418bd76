//! Studies: many runs of one scenario, in-process on the simulation driver, and
//! what they measure. `sweep` runs every combination of key values, `convergence`
//! halves the time step and reports the observed order, `scaling` runs on more
//! and more threads and fits Amdahl's law. Each writes a table, a CSV and a PNG.
//!
//! A study checks everything before it runs anything: every combination of its
//! keys is built with zero steps (the probe: unknown keys, values of the wrong
//! type and out-of-range values are refused there) and every metric is looked up
//! in what the model reports.

pub mod billiards_sweep;
pub mod convergence;
pub mod metric;
pub mod scaling;
pub mod sweep;
pub mod table;

use crate::error::{SimError, SimResult};
use crate::launch::{RunContext, RunSummary};
use crate::models::run_scenario;
use crate::scenario::Scenario;
use cellist::Threads;
use cellist_io::AtomicFile;
use std::io::Write;
use std::path::{Path, PathBuf};

/// Runs `scenario` quietly on `threads` with its outputs in `dir`.
pub fn run_quiet(scenario: &Scenario, threads: &Threads, dir: &Path) -> SimResult<RunSummary> {
    let context = RunContext::new(dir.to_path_buf(), None, threads).quiet();
    run_scenario(scenario, &context.read_from(scenario.path.as_deref()))
}

/// Prints the warnings of a quiet run that `seen` does not hold yet (on standard
/// error, once per study) and adds them to it.
pub fn report_warnings(run: &RunSummary, seen: &mut Vec<String>) {
    for w in &run.warnings {
        if !seen.contains(w) {
            eprintln!("warning: {w}");
            seen.push(w.clone());
        }
    }
}

/// Builds `scenario` and stops before the loop (nothing is written): the check
/// of its keys and values before a study runs it, and what the model reports
/// (thermo columns and the step-0 row, stages, particles or field).
pub fn probe(scenario: &Scenario, label: &str) -> SimResult<RunSummary> {
    let threads = Threads::new(1).map_err(|e| SimError::Internal(e.to_string()))?;
    let context = RunContext::new(PathBuf::new(), None, &threads).build_only();
    run_scenario(scenario, &context).map_err(|e| match e {
        SimError::Input(m) => SimError::Input(format!("{label}: {m}")),
        SimError::BlowUp(m) => SimError::Input(format!("{label}: the initial state: {m}")),
        other => other,
    })
}

/// The output folder of a study: `out` if given, else `out/<name>-<study>/`.
pub fn study_dir(out: Option<&Path>, name: &str, study: &str) -> PathBuf {
    out.map_or_else(
        || Path::new("out").join(format!("{name}-{study}")),
        Path::to_path_buf,
    )
}

/// The folder of run `k` (0-based) of a study: `dir/runs/001/`, ...
pub fn run_dir(dir: &Path, k: usize) -> PathBuf {
    dir.join("runs").join(format!("{:03}", k + 1))
}

/// Creates the study's folder.
pub fn create_dir(dir: &Path) -> SimResult {
    std::fs::create_dir_all(dir).map_err(SimError::output(format!("folder {}", dir.display())))
}

/// Writes `text` to `path` whole or not at all.
pub fn write_text(path: &Path, text: &str) -> SimResult {
    let what = || path.display().to_string();
    let mut file = AtomicFile::create(path).map_err(SimError::output(what()))?;
    file.writer()
        .write_all(text.as_bytes())
        .and_then(|()| file.commit())
        .map_err(SimError::output(what()))
}

/// The median of `values` (the mean of the middle two for an even count); NaN
/// for none.
pub fn median(values: &[f64]) -> f64 {
    let mut v: Vec<f64> = values.to_vec();
    v.sort_by(f64::total_cmp);
    match v.len() {
        0 => f64::NAN,
        n if n % 2 == 1 => v[n / 2],
        n => 0.5 * (v[n / 2 - 1] + v[n / 2]),
    }
}

/// Splits a `--set` list `V1,V2,...` at the commas outside brackets, braces and
/// quotes, so that `[10,10,10],[20,20,20]` is two values.
pub fn split_values(list: &str) -> Vec<String> {
    let mut values = Vec::new();
    let mut depth = 0i32;
    let mut quote: Option<char> = None;
    let mut current = String::new();
    for c in list.chars() {
        match (quote, c) {
            (Some(q), _) if c == q => quote = None,
            (Some(_), _) => {}
            (None, '"' | '\'') => quote = Some(c),
            (None, '[' | '{') => depth += 1,
            (None, ']' | '}') => depth -= 1,
            (None, ',') if depth == 0 => {
                values.push(current.trim().to_string());
                current.clear();
                continue;
            }
            _ => {}
        }
        current.push(c);
    }
    values.push(current.trim().to_string());
    values
}

/// A `--set KEY=V1,V2,...` of a study: the key and its values. Several keys
/// joined by `+` move together, each value a list of one value per key:
/// `--set system.lattice.n+system.epsilon=[16,0.0625],[32,0.03125]`.
#[derive(Clone, Debug, PartialEq)]
pub struct SweptKey {
    /// The dotted scenario keys (one, or several that move together).
    pub keys: Vec<String>,
    /// Its values: per value, one TOML text per key.
    pub values: Vec<Vec<String>>,
}

impl SweptKey {
    /// Parses `KEY=V1,V2,...` or `KEY1+KEY2=[V1,W1],[V2,W2],...`; refuses a
    /// missing `=`, an empty key, an empty value, and a linked value that is not
    /// a list of one value per key.
    pub fn parse(arg: &str) -> SimResult<Self> {
        let bad = |why: &str| SimError::Input(format!("--set {arg}: {why}"));
        let (key, list) = arg
            .split_once('=')
            .ok_or_else(|| bad("expected KEY=V1,V2,..., e.g. run.dt=0.01,0.005"))?;
        let keys: Vec<String> = key.split('+').map(|k| k.trim().to_string()).collect();
        if keys
            .iter()
            .any(|k| k.is_empty() || k.split('.').any(|p| p.trim().is_empty()))
        {
            return Err(bad("empty key"));
        }
        let texts = split_values(list);
        if texts.iter().any(String::is_empty) {
            return Err(bad(
                "an empty value in the list; give one or more values separated by commas",
            ));
        }
        let values = if keys.len() == 1 {
            texts.into_iter().map(|t| vec![t]).collect()
        } else {
            texts
                .iter()
                .map(|t| {
                    let items = match t.parse::<toml_edit::Value>() {
                        Ok(toml_edit::Value::Array(a)) => a
                            .iter()
                            .map(|v| v.to_string().trim().to_string())
                            .collect::<Vec<_>>(),
                        _ => Vec::new(),
                    };
                    if items.len() == keys.len() {
                        Ok(items)
                    } else {
                        Err(bad(&format!(
                            "{t}: the keys {} move together, so each value is a list of {} values, e.g. [16,0.0625]",
                            keys.join(" + "),
                            keys.len()
                        )))
                    }
                })
                .collect::<SimResult<_>>()?
        };
        Ok(SweptKey { keys, values })
    }

    /// The overrides `KEY=value` of its `k`-th value.
    pub fn set(&self, k: usize) -> Vec<String> {
        self.keys
            .iter()
            .zip(&self.values[k])
            .map(|(key, v)| format!("{key}={v}"))
            .collect()
    }
}

/// Parses a `--threads` list, refusing an empty list and 0.
pub fn thread_counts(list: &[usize]) -> SimResult<Vec<usize>> {
    if list.is_empty() {
        return Err(SimError::Input(
            "--threads: an empty list; give thread counts such as 1,2".into(),
        ));
    }
    if list.contains(&0) {
        return Err(SimError::Input(
            "--threads: 0 in the list; thread counts are at least 1".into(),
        ));
    }
    Ok(list.to_vec())
}

/// A pool per thread count, started once for a whole study.
pub struct Pools(Vec<(usize, Threads)>);

impl Pools {
    /// Pools of each of `counts` threads.
    pub fn new(counts: &[usize]) -> SimResult<Self> {
        counts
            .iter()
            .map(|&t| pool(t).map(|p| (t, p)))
            .collect::<SimResult<_>>()
            .map(Pools)
    }

    /// The pool of `count` threads (one of those it was made with).
    pub fn get(&self, count: usize) -> &Threads {
        &self
            .0
            .iter()
            .find(|(t, _)| *t == count)
            .expect("a pool of every thread count of the study")
            .1
    }
}

/// The start of a study's progress line: `run k/n (round r/R): what`.
pub fn progress(k: usize, n: usize, round: usize, rounds: usize, what: &str) -> String {
    format!("run {}/{n} (round {}/{rounds}): {what}", k + 1, round + 1)
}

/// A pool of `count` threads.
pub fn pool(count: usize) -> SimResult<Threads> {
    Threads::new(count).map_err(|e| SimError::Input(format!("cannot start {count} threads: {e}")))
}

/// The machine's cores (what `--threads` above it oversubscribes).
pub fn cores() -> usize {
    std::thread::available_parallelism().map_or(1, |n| n.get())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lists_split_outside_brackets_and_quotes() {
        assert_eq!(split_values("1,2, 3"), ["1", "2", "3"]);
        assert_eq!(
            split_values("[10,10,10],[20,20,20]"),
            ["[10,10,10]", "[20,20,20]"]
        );
        assert_eq!(split_values("\"a,b\",c"), ["\"a,b\"", "c"]);
        assert_eq!(
            split_values("{ kind = \"mesh\", grid = 64 },{ kind = \"direct\" }"),
            ["{ kind = \"mesh\", grid = 64 }", "{ kind = \"direct\" }"]
        );
    }

    #[test]
    fn swept_keys_refuse_empty_lists_and_keys() {
        let k = SweptKey::parse("run.dt=0.1,0.05").unwrap();
        assert_eq!(k.keys, ["run.dt"]);
        assert_eq!(k.set(1), ["run.dt=0.05"]);
        assert!(SweptKey::parse("run.dt=").is_err());
        assert!(SweptKey::parse("run.dt=1,,2").is_err());
        assert!(SweptKey::parse("=1,2").is_err());
        assert!(SweptKey::parse("run..dt=1").is_err());
        assert!(SweptKey::parse("run.dt").is_err());
    }

    #[test]
    fn linked_keys_take_one_value_each_from_lists() {
        let k = SweptKey::parse("a.n+a.eps=[16, 0.0625],[32,0.03125]").unwrap();
        assert_eq!(k.keys, ["a.n", "a.eps"]);
        assert_eq!(k.values[0], ["16", "0.0625"]);
        assert_eq!(k.set(1), ["a.n=32", "a.eps=0.03125"]);
        assert!(SweptKey::parse("a.n+a.eps=[16],[32,0.1]").is_err());
        assert!(SweptKey::parse("a.n+a.eps=16,32").is_err());
        assert!(SweptKey::parse("a.n+=[1,2]").is_err());
    }

    #[test]
    fn thread_lists_refuse_zero_and_empty() {
        assert!(thread_counts(&[]).is_err());
        assert!(thread_counts(&[1, 0]).is_err());
        assert_eq!(thread_counts(&[1, 2]).unwrap(), [1, 2]);
    }

    #[test]
    fn medians_of_odd_and_even_counts() {
        assert_eq!(median(&[3.0, 1.0, 2.0]), 2.0);
        assert_eq!(median(&[4.0, 1.0, 2.0, 3.0]), 2.5);
        assert!(median(&[]).is_nan());
    }
}
