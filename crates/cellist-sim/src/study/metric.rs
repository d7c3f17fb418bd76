//! What a study measures on a run: wall times, thermo columns, the error against
//! an exact solution.

use crate::error::{SimError, SimResult};
use crate::RunSummary;

/// A quantity measured on one run.
#[derive(Clone, Debug, PartialEq)]
pub enum Metric {
    /// `time`: wall time of the loop, in seconds.
    LoopTime,
    /// `time.<Stage>`: wall time of one stage of the loop (the stages of the run's
    /// timing table: the model's own, `Output`, `Other`), in seconds.
    StageTime(String),
    /// `<column>`: a thermo column at the last step.
    Last(String),
    /// `<column>.drift`: the largest `|v(step) - v(0)|` of a thermo column over the
    /// thermo rows.
    Drift(String),
    /// `error`: the model's error against its exact solution at the last step
    /// (pse: `l2_error`, vortex Lamb-Oseen: `omega_l2_error`).
    Error,
}

/// The thermo columns that hold an error against an exact solution, L2 first.
const ERROR_COLUMNS: [&str; 2] = ["l2_error", "omega_l2_error"];

impl Metric {
    /// Parses a metric name.
    pub fn parse(name: &str) -> Self {
        if name == "time" {
            Metric::LoopTime
        } else if name == "error" {
            Metric::Error
        } else if let Some(stage) = name.strip_prefix("time.") {
            Metric::StageTime(stage.to_string())
        } else if let Some(column) = name.strip_suffix(".drift") {
            Metric::Drift(column.to_string())
        } else {
            Metric::Last(name.to_string())
        }
    }

    /// The metric's name as the user writes it.
    pub fn name(&self) -> String {
        match self {
            Metric::LoopTime => "time".into(),
            Metric::StageTime(s) => format!("time.{s}"),
            Metric::Last(c) => c.clone(),
            Metric::Drift(c) => format!("{c}.drift"),
            Metric::Error => "error".into(),
        }
    }

    /// The axis label: the name and, for times, the unit.
    pub fn label(&self) -> String {
        match self {
            Metric::LoopTime => "loop wall time (s)".into(),
            Metric::StageTime(s) => format!("{s} wall time (s)"),
            Metric::Last(c) => format!("{c} at the last step"),
            Metric::Drift(c) => format!("largest drift of {c}"),
            Metric::Error => "L2 error against the exact solution".into(),
        }
    }

    /// True for wall times (the median over repeats is taken).
    pub fn is_time(&self) -> bool {
        matches!(self, Metric::LoopTime | Metric::StageTime(_))
    }

    /// Checks that runs like `probe` produce this metric; the message lists what
    /// they do produce.
    pub fn check(&self, probe: &RunSummary) -> SimResult {
        let stages: Vec<&str> = probe.stages.iter().map(|(s, _)| *s).collect();
        let columns = &probe.thermo_columns;
        let known = || {
            let mut names = vec!["time".to_string()];
            if error_column(probe).is_some() {
                names.push("error".to_string());
            }
            names.extend(stages.iter().map(|s| format!("time.{s}")));
            // a `time` column (the simulated time) is shadowed by the wall time
            let columns = columns.iter().filter(|c| **c != "time");
            names.extend(columns.clone().map(|c| c.to_string()));
            names.extend(columns.map(|c| format!("{c}.drift")));
            names.join(", ")
        };
        let ok = match self {
            Metric::LoopTime => true,
            Metric::StageTime(s) => stages.contains(&s.as_str()),
            Metric::Last(c) | Metric::Drift(c) => columns.contains(&c.as_str()),
            Metric::Error => {
                return error_column(probe).map(drop).ok_or_else(|| {
                    SimError::Input(format!(
                        "--metric error: this {} scenario has no exact solution to compare with \
                         (pse with an initial sine or gaussian, vortex lamb-oseen have one)",
                        probe.model
                    ))
                })
            }
        };
        if ok {
            Ok(())
        } else {
            Err(SimError::Input(format!(
                "--metric {}: model {} does not produce it; it produces: {}",
                self.name(),
                probe.model,
                known()
            )))
        }
    }

    /// The metric's value on a finished run (checked with [`Metric::check`]).
    pub fn value(&self, run: &RunSummary) -> f64 {
        let column = |c: &str| run.thermo_columns.iter().position(|n| *n == c);
        match self {
            Metric::LoopTime => run.loop_time.as_secs_f64(),
            Metric::StageTime(s) => run
                .stages
                .iter()
                .find(|(n, _)| n == s)
                .map_or(f64::NAN, |(_, d)| d.as_secs_f64()),
            Metric::Last(c) => column(c)
                .and_then(|k| run.thermo.last().map(|(_, v)| v[k]))
                .unwrap_or(f64::NAN),
            Metric::Drift(c) => column(c)
                .and_then(|k| {
                    let first = run.thermo.first()?.1[k];
                    Some(
                        run.thermo
                            .iter()
                            .map(|(_, v)| (v[k] - first).abs())
                            .fold(0.0, f64::max),
                    )
                })
                .unwrap_or(f64::NAN),
            Metric::Error => error_column(run)
                .and_then(|k| run.thermo.last().map(|(_, v)| v[k]))
                .unwrap_or(f64::NAN),
        }
    }
}

/// The index of the thermo column holding the L2 error against an exact solution,
/// when the run has one (a column of NaN means none).
fn error_column(run: &RunSummary) -> Option<usize> {
    let k = ERROR_COLUMNS
        .iter()
        .find_map(|c| run.thermo_columns.iter().position(|n| n == c))?;
    run.thermo
        .first()
        .is_some_and(|(_, v)| !v[k].is_nan())
        .then_some(k)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;

    fn summary() -> RunSummary {
        RunSummary {
            model: "pse",
            dt: 0.1,
            steps: 2,
            threads: 1,
            loop_time: Duration::from_millis(300),
            stages: vec![
                ("Rates", Duration::from_millis(200)),
                ("Output", Duration::from_millis(50)),
                ("Other", Duration::from_millis(50)),
            ],
            thermo_columns: vec!["time", "total", "l2_error", "max_error"],
            thermo: vec![
                (0, vec![0.0, 1.0, 0.0, 0.0]),
                (1, vec![0.1, 1.5, 1e-3, 2e-3]),
                (2, vec![0.2, 0.75, 2e-3, 4e-3]),
            ],
            particles: None,
            field: None,
            warnings: Vec::new(),
        }
    }

    #[test]
    fn metrics_read_times_columns_drifts_and_errors() {
        let s = summary();
        assert_eq!(Metric::parse("time").value(&s), 0.3);
        assert_eq!(Metric::parse("time.Rates").value(&s), 0.2);
        assert_eq!(Metric::parse("total").value(&s), 0.75);
        assert_eq!(Metric::parse("total.drift").value(&s), 0.5);
        assert_eq!(Metric::parse("error").value(&s), 2e-3);
        for name in ["time", "time.Other", "total", "total.drift", "error"] {
            let m = Metric::parse(name);
            assert_eq!(m.name(), name);
            assert!(m.check(&s).is_ok(), "{name}");
        }
    }

    #[test]
    fn unknown_metrics_are_refused_with_the_known_ones() {
        let s = summary();
        let e = Metric::parse("etotal").check(&s).unwrap_err().to_string();
        assert!(
            e.contains("--metric etotal") && e.contains("l2_error.drift"),
            "{e}"
        );
        assert!(Metric::parse("time.Force").check(&s).is_err());
        let mut no_exact = summary();
        for row in &mut no_exact.thermo {
            row.1[2] = f64::NAN;
        }
        assert!(Metric::Error.check(&no_exact).is_err());
    }
}
