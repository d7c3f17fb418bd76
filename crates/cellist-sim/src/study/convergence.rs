//! `cellist convergence`: the observed order of a time integrator, by halving the
//! time step at a fixed end time.
//!
//! Seed 004's method: with `u(dt)` the observable after the runs of steps `dt`,
//! `dt/2`, ..., `dt/2^K` to the same end time, the successive differences
//! `d_k = |u(dt/2^k) - u(dt/2^(k+1))|` shrink like `dt^p` for a method of order
//! `p`, so `p ~ log2(d_k / d_(k+1))`. Where the model has an exact solution the
//! errors `e_k = |u(dt/2^k) - u_exact|` give `p ~ log2(e_k / e_(k+1))` as well (as
//! long as the time-step error dominates the spatial one).

use super::{create_dir, probe, report_warnings, run_dir, run_quiet, study_dir};
use crate::error::{SimError, SimResult};
use crate::scenario::Scenario;
use crate::RunSummary;
use cellist::geometry::{Boundary, Domain};
use cellist_io::format_g17;
use cellist_io::plot::{draw_chart, Chart, Series, SeriesStyle};
use std::path::{Path, PathBuf};

/// What `cellist convergence` asks for.
pub struct ConvergenceRequest<'a> {
    /// The scenario file.
    pub scenario: &'a Path,
    /// `--set key=value` overrides.
    pub sets: &'a [String],
    /// The largest time step.
    pub dt: f64,
    /// How many times the step is halved (runs: `halvings + 1`).
    pub halvings: u32,
    /// The end time (default: the scenario's `run.steps` times `dt`).
    pub end_time: Option<f64>,
    /// A thermo column, `position`, `velocity` or `field`.
    pub observable: &'a str,
    /// Also compare with the model's exact solution.
    pub exact: bool,
    /// The output folder (default `out/<scenario>-convergence/`).
    pub out: Option<PathBuf>,
}

/// What is compared between runs.
#[derive(Clone, Debug, PartialEq)]
pub enum Observable {
    /// A thermo column at the end.
    Column(String),
    /// Every particle's position (matched by id; minimum image on periodic axes).
    Position,
    /// Every particle's velocity (matched by id).
    Velocity,
    /// Every particle's field value (PSE strength density, vortex vorticity).
    Field,
}

impl Observable {
    /// Parses an observable name.
    pub fn parse(name: &str) -> Self {
        match name {
            "position" => Observable::Position,
            "velocity" => Observable::Velocity,
            "field" => Observable::Field,
            column => Observable::Column(column.to_string()),
        }
    }

    /// Checks that runs like `probe` have it.
    fn check(&self, probe: &RunSummary) -> SimResult {
        let ok = match self {
            Observable::Column(c) => probe.thermo_columns.contains(&c.as_str()),
            Observable::Position | Observable::Velocity => probe.particles.is_some(),
            Observable::Field => probe.field.is_some(),
        };
        if ok {
            return Ok(());
        }
        let mut known: Vec<String> = probe.thermo_columns.iter().map(|c| c.to_string()).collect();
        if probe.particles.is_some() {
            known.extend(["position".into(), "velocity".into()]);
        }
        if probe.field.is_some() {
            known.push("field".into());
        }
        Err(SimError::Input(format!(
            "--observable {}: model {} does not produce it; it produces: {}",
            self.name(),
            probe.model,
            known.join(", ")
        )))
    }

    fn name(&self) -> &str {
        match self {
            Observable::Column(c) => c,
            Observable::Position => "position",
            Observable::Velocity => "velocity",
            Observable::Field => "field",
        }
    }

    /// The difference of the observable between two runs: `|a - b|` of a column,
    /// the largest per-particle difference otherwise.
    pub fn difference(&self, a: &RunSummary, b: &RunSummary) -> SimResult<f64> {
        match self {
            Observable::Column(c) => Ok((last(a, c) - last(b, c)).abs()),
            Observable::Position | Observable::Velocity => {
                let (pa, pb) = match (&a.particles, &b.particles) {
                    (Some(pa), Some(pb)) => (pa, pb),
                    _ => return Err(SimError::Internal("a run without particles".into())),
                };
                if pa.ids.len() != pb.ids.len() {
                    return Err(count_changed(pa.ids.len(), pb.ids.len()));
                }
                let order = |ids: &[u64]| {
                    let mut k: Vec<usize> = (0..ids.len()).collect();
                    k.sort_by_key(|&i| ids[i]);
                    k
                };
                let (oa, ob) = (order(&pa.ids), order(&pb.ids));
                let position = *self == Observable::Position;
                let domain = Domain {
                    lo: pa.lo,
                    length: std::array::from_fn(|k| pa.hi[k] - pa.lo[k]),
                    boundary: pa.periodic.map(|p| {
                        if p {
                            Boundary::Periodic
                        } else {
                            Boundary::Open
                        }
                    }),
                };
                let mut largest = 0.0f64;
                for (&i, &j) in oa.iter().zip(&ob) {
                    if pa.ids[i] != pb.ids[j] {
                        return Err(SimError::Input(format!(
                            "the runs hold different particles (ids {} and {})",
                            pa.ids[i], pb.ids[j]
                        )));
                    }
                    let d = if position {
                        domain.separation(&pb.positions[j], &pa.positions[i])
                    } else {
                        std::array::from_fn(|k| pa.velocities[i][k] - pb.velocities[j][k])
                    };
                    largest = largest.max(d.iter().map(|x| x * x).sum::<f64>().sqrt());
                }
                Ok(largest)
            }
            Observable::Field => {
                let (fa, fb) = match (&a.field, &b.field) {
                    (Some(fa), Some(fb)) => (fa, fb),
                    _ => return Err(SimError::Internal("a run without a field".into())),
                };
                if fa.values.len() != fb.values.len() {
                    return Err(count_changed(fa.values.len(), fb.values.len()));
                }
                // particle k must be the same particle in both runs: within half
                // a spacing of each other (advected vortex particles move a
                // little with dt; remeshed ones may be other lattice nodes)
                let domain = Domain {
                    lo: fa.origin,
                    length: [fa.side; 3],
                    boundary: [if fa.periodic {
                        Boundary::Periodic
                    } else {
                        Boundary::Open
                    }; 3],
                };
                if let Some(k) = (0..fa.positions.len()).find(|&k| {
                    let d = domain.separation(&fa.positions[k], &fb.positions[k]);
                    d.iter().map(|x| x * x).sum::<f64>().sqrt() > 0.5 * fa.spacing
                }) {
                    return Err(SimError::Input(format!(
                        "particle {k} is at {:?} in one run and at {:?} in the other: the runs' \
                         particles differ (remeshing at a fixed step interval happens at \
                         different times when dt changes), so the field cannot be compared \
                         particle by particle; compare a thermo column instead",
                        fa.positions[k], fb.positions[k]
                    )));
                }
                Ok(fa
                    .values
                    .iter()
                    .zip(&fb.values)
                    .map(|(x, y)| (x - y).abs())
                    .fold(0.0, f64::max))
            }
        }
    }
}

fn count_changed(a: usize, b: usize) -> SimError {
    SimError::Input(format!(
        "the runs end with {a} and {b} particles: the observable compares particle by particle, \
         so the count must not change (remeshing at a fixed step interval happens at \
         different times when dt changes; compare a thermo column instead)"
    ))
}

/// A thermo column at the last step.
fn last(run: &RunSummary, column: &str) -> f64 {
    run.thermo_columns
        .iter()
        .position(|c| *c == column)
        .and_then(|k| run.thermo.last().map(|(_, v)| v[k]))
        .unwrap_or(f64::NAN)
}

/// The thermo columns holding the largest per-particle error of the field
/// against an exact solution.
const EXACT_FIELD_ERRORS: [&str; 2] = ["max_error", "omega_max_error"];

/// The exact-solution error column of `probe` that matches `observable`.
fn exact_column(observable: &Observable, probe: &RunSummary) -> SimResult<&'static str> {
    if *observable != Observable::Field {
        return Err(SimError::Input(format!(
            "--exact: the exact solutions cellist knows are of fields; use --observable field \
             (not {})",
            observable.name()
        )));
    }
    EXACT_FIELD_ERRORS
        .iter()
        .copied()
        .find(|c| {
            probe.thermo_columns.contains(c) && {
                let v = last(probe, c);
                !v.is_nan()
            }
        })
        .ok_or_else(|| {
            SimError::Input(format!(
                "--exact: this {} scenario has no exact solution (pse with an initial sine or \
                 gaussian and vortex lamb-oseen have one)",
                probe.model
            ))
        })
}

/// `log2(a / b)`, the order between two successive errors or differences.
pub fn order(a: f64, b: f64) -> f64 {
    (a / b).log2()
}

/// One run of the study and what it gave.
struct Level {
    dt: f64,
    steps: u64,
    value: Option<f64>,
    difference: Option<f64>,
    error: Option<f64>,
}

/// Runs the study: checks the scenario and the observable, runs every time step,
/// prints the table and the observed orders, writes `convergence.csv` and
/// `convergence.png`. Returns the observed orders from the differences and, with
/// `exact`, from the errors.
pub fn convergence(request: &ConvergenceRequest) -> SimResult<(Vec<f64>, Vec<f64>)> {
    let scenario = Scenario::load(Some(request.scenario), request.sets)?;
    let dt0 = request.dt;
    if !(dt0.is_finite() && dt0 > 0.0) {
        return Err(SimError::Input(format!("--dt must be > 0, got {dt0}")));
    }
    let least = if request.exact { 1 } else { 2 };
    if request.halvings < least {
        return Err(SimError::Input(format!(
            "--halvings must be at least {least}: {} runs give {} and an order{}",
            least + 1,
            if least == 1 {
                "two errors"
            } else {
                "two successive differences"
            },
            if least == 1 {
                ""
            } else {
                " (1 is enough with --exact)"
            }
        )));
    }
    if request.halvings > 20 {
        return Err(SimError::Input(format!(
            "--halvings {} would run 2^{} times the steps; at most 20",
            request.halvings, request.halvings
        )));
    }
    let steps0 = match request.end_time {
        Some(t) => {
            let steps = t / dt0;
            if !(t.is_finite() && t > 0.0 && (steps - steps.round()).abs() <= 1e-9 * steps) {
                return Err(SimError::Input(format!(
                    "--end-time {t} is not a whole number of steps of --dt {dt0}"
                )));
            }
            steps.round() as u64
        }
        None => scenario_steps(&scenario)?,
    };
    if steps0 == 0 {
        return Err(SimError::Input(
            "the end time is 0 steps; set run.steps or --end-time".into(),
        ));
    }
    let observable = Observable::parse(request.observable);
    let levels: Vec<(f64, u64)> = (0..=request.halvings)
        .map(|k| {
            steps0
                .checked_mul(1u64 << k)
                .map(|steps| (dt0 / f64::from(1u32 << k), steps))
                .ok_or_else(|| {
                    SimError::Input(format!(
                        "{steps0} steps halved {k} times overflow the step count; use a shorter end time"
                    ))
                })
        })
        .collect::<SimResult<_>>()?;
    let set = |(dt, steps): (f64, u64)| {
        scenario.with_sets(&[format!("run.dt={dt:?}"), format!("run.steps={steps}")])
    };
    let first = set(levels[0])?;
    let probed = probe(&first, &format!("--dt {dt0}"))?;
    observable.check(&probed)?;
    let exact = request
        .exact
        .then(|| exact_column(&observable, &probed))
        .transpose()?;
    let integrator = integrator_name(&scenario);
    let dir = study_dir(request.out.as_deref(), &scenario.name, "convergence");
    create_dir(&dir)?;
    let end = dt0 * steps0 as f64;
    println!(
        "convergence of {} in dt ({}{}): {} runs from dt = {dt0} to dt = {dt0}/{} at the end time {end}; runs in {}",
        observable.name(),
        probed.model,
        integrator.as_deref().map(|i| format!(", {i}")).unwrap_or_default(),
        levels.len(),
        1u64 << request.halvings,
        dir.join("runs").display()
    );
    let threads = super::pool(super::cores())?;
    let mut previous: Option<RunSummary> = None;
    let mut warnings = Vec::new();
    let mut results: Vec<Level> = Vec::new();
    for (k, &(dt, steps)) in levels.iter().enumerate() {
        let summary =
            run_quiet(&set((dt, steps))?, &threads, &run_dir(&dir, k)).map_err(|e| match e {
                SimError::BlowUp(m) => SimError::BlowUp(format!("the run with dt = {dt}: {m}")),
                other => other,
            })?;
        report_warnings(&summary, &mut warnings);
        println!(
            "run {}/{}: dt = {dt:e}, {steps} steps, loop {:.3} s",
            k + 1,
            levels.len(),
            summary.loop_time.as_secs_f64()
        );
        if let (Some(p), Some(level)) = (&previous, results.last_mut()) {
            level.difference = Some(observable.difference(p, &summary)?);
        }
        results.push(Level {
            dt,
            steps,
            value: match &observable {
                Observable::Column(c) => Some(last(&summary, c)),
                _ => None,
            },
            difference: None,
            error: exact.map(|c| last(&summary, c)),
        });
        previous = Some(summary);
    }
    let differences: Vec<f64> = results.iter().filter_map(|l| l.difference).collect();
    let errors: Vec<f64> = results.iter().filter_map(|l| l.error).collect();
    let by_difference: Vec<f64> = differences.windows(2).map(|w| order(w[0], w[1])).collect();
    let by_error: Vec<f64> = errors.windows(2).map(|w| order(w[0], w[1])).collect();
    print_table(&results, &by_difference, &by_error);
    if let Some(p) = by_difference.last() {
        println!(
            "\nobserved order from successive differences: {p:.3} (finest pair; all: {})",
            list(&by_difference)
        );
    }
    if let Some(p) = by_error.last() {
        println!(
            "observed order from the errors against the exact solution: {p:.3} (finest pair; all: {})",
            list(&by_error)
        );
        if *p < 0.5 {
            println!(
                "note: the errors hardly fall with dt: they are not the time step's but the fixed \
                 discretisation's (e.g. PSE's O(eps^2)); the successive differences measure the \
                 integrator alone"
            );
        }
    }
    let csv = dir.join("convergence.csv");
    write_csv(&csv, &results, &by_difference, &by_error)?;
    let png = dir.join("convergence.png");
    let title = format!(
        "Convergence in dt: {} of {}{}",
        observable.name(),
        scenario.name,
        integrator.map(|i| format!(" ({i})")).unwrap_or_default()
    );
    draw(&png, &title, &results)?;
    println!("results: {}, {}", csv.display(), png.display());
    Ok((by_difference, by_error))
}

fn list(orders: &[f64]) -> String {
    orders
        .iter()
        .map(|p| format!("{p:.3}"))
        .collect::<Vec<_>>()
        .join(", ")
}

/// The scenario's `run.steps`.
fn scenario_steps(scenario: &Scenario) -> SimResult<u64> {
    let table: toml::Table = toml::from_str(&scenario.text).map_err(|e| scenario.error(e))?;
    table
        .get("run")
        .and_then(|r| r.get("steps"))
        .and_then(toml::Value::as_integer)
        .and_then(|s| u64::try_from(s).ok())
        .ok_or_else(|| {
            scenario.error("no run.steps to take the end time from; set it or give --end-time")
        })
}

/// The scenario's `run.integrator`, if it names one.
fn integrator_name(scenario: &Scenario) -> Option<String> {
    let table: toml::Table = toml::from_str(&scenario.text).ok()?;
    table
        .get("run")?
        .get("integrator")?
        .as_str()
        .map(str::to_string)
}

fn cell(v: Option<f64>) -> String {
    v.map_or_else(|| "-".into(), |v| format!("{v:.6e}"))
}

fn print_table(levels: &[Level], by_difference: &[f64], by_error: &[f64]) {
    let has_value = levels[0].value.is_some();
    let has_error = levels[0].error.is_some();
    let mut head = format!("\n{:>14}  {:>10}", "dt", "steps");
    if has_value {
        head += &format!("  {:>14}", "value");
    }
    head += &format!("  {:>18}  {:>7}", "diff to dt/2", "order");
    if has_error {
        head += &format!("  {:>14}  {:>7}", "error", "order");
    }
    println!("{head}");
    for (k, l) in levels.iter().enumerate() {
        let mut line = format!("{:>14e}  {:>10}", l.dt, l.steps);
        if has_value {
            line += &format!("  {:>14}", cell(l.value));
        }
        let p = k.checked_sub(1).and_then(|j| by_difference.get(j).copied());
        line += &format!(
            "  {:>18}  {:>7}",
            cell(l.difference),
            p.map_or("-".into(), |p| format!("{p:.3}"))
        );
        if has_error {
            let q = k.checked_sub(1).and_then(|j| by_error.get(j).copied());
            line += &format!(
                "  {:>14}  {:>7}",
                cell(l.error),
                q.map_or("-".into(), |q| format!("{q:.3}"))
            );
        }
        println!("{line}");
    }
}

fn write_csv(path: &Path, levels: &[Level], by_difference: &[f64], by_error: &[f64]) -> SimResult {
    let mut text = String::from("dt,steps,value,difference,order_difference,error,order_error\n");
    for (k, l) in levels.iter().enumerate() {
        let at = |orders: &[f64]| {
            k.checked_sub(1)
                .and_then(|j| orders.get(j).copied())
                .unwrap_or(f64::NAN)
        };
        format_g17(l.dt, &mut text);
        text.push_str(&format!(",{}", l.steps));
        for v in [
            l.value.unwrap_or(f64::NAN),
            l.difference.unwrap_or(f64::NAN),
            at(by_difference),
            l.error.unwrap_or(f64::NAN),
            at(by_error),
        ] {
            text.push(',');
            format_g17(v, &mut text);
        }
        text.push('\n');
    }
    super::write_text(path, &text)
}

/// Log-log: the differences (and errors) against dt, with slopes 1, 2 and 4
/// through the first difference.
fn draw(path: &Path, title: &str, levels: &[Level]) -> SimResult {
    let differences: Vec<(f64, f64)> = levels
        .iter()
        .filter_map(|l| l.difference.map(|d| (l.dt, d)))
        .collect();
    let errors: Vec<(f64, f64)> = levels
        .iter()
        .filter_map(|l| l.error.map(|e| (l.dt, e)))
        .collect();
    let anchor = differences.first().or(errors.first()).copied();
    let (lo, hi) = (levels[levels.len() - 1].dt, levels[0].dt);
    let slopes: Vec<(String, Vec<(f64, f64)>)> = anchor
        .map(|(x0, y0)| {
            [1, 2, 4]
                .iter()
                .map(|&p| {
                    let line = [lo, hi]
                        .iter()
                        .map(|&x| (x, y0 * (x / x0).powi(p)))
                        .collect();
                    (format!("slope {p}"), line)
                })
                .collect()
        })
        .unwrap_or_default();
    let mut series = Vec::new();
    if !differences.is_empty() {
        series.push(Series {
            label: "|u(dt) - u(dt/2)|",
            points: &differences,
            style: SeriesStyle::Points,
        });
    }
    if !errors.is_empty() {
        series.push(Series {
            label: "error against the exact solution",
            points: &errors,
            style: SeriesStyle::Points,
        });
    }
    for (label, points) in &slopes {
        series.push(Series {
            label,
            points,
            style: SeriesStyle::Reference,
        });
    }
    draw_chart(
        path,
        &Chart {
            title,
            x_label: "time step dt (model time units)",
            y_label: "difference / error (units of the observable)",
            log_x: true,
            log_y: true,
            series: &series,
        },
    )
    .map_err(SimError::chart(path))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn orders_of_geometric_sequences() {
        assert!((order(1.0, 0.5) - 1.0).abs() < 1e-15);
        assert!((order(1.0, 1.0 / 16.0) - 4.0).abs() < 1e-15);
    }

    fn with_field(positions: Vec<[f64; 3]>, values: Vec<f64>) -> RunSummary {
        RunSummary {
            model: "vortex",
            dt: 0.1,
            steps: 1,
            threads: 1,
            loop_time: std::time::Duration::ZERO,
            stages: Vec::new(),
            thermo_columns: Vec::new(),
            thermo: Vec::new(),
            particles: None,
            field: Some(cellist::models::Field {
                dimension: 2,
                positions,
                values,
                value_name: "omega",
                value_written: true,
                strengths: None,
                extra: Vec::new(),
                axes: [0, 1, 2],
                origin: [0.0; 3],
                periodic: true,
                side: 1.0,
                spacing: 0.1,
                scale: 1.0,
            }),
            warnings: Vec::new(),
        }
    }

    #[test]
    fn fields_compare_the_same_particles_only() {
        let a = with_field(vec![[0.5, 0.5, 0.0], [0.99, 0.2, 0.0]], vec![1.0, 2.0]);
        // advected a little, and across the periodic edge: the same particles
        let b = with_field(vec![[0.51, 0.5, 0.0], [0.01, 0.2, 0.0]], vec![1.5, 1.75]);
        assert_eq!(Observable::Field.difference(&a, &b).unwrap(), 0.5);
        // another lattice node: refused
        let c = with_field(vec![[0.5, 0.5, 0.0], [0.8, 0.2, 0.0]], vec![1.0, 2.0]);
        let e = Observable::Field
            .difference(&a, &c)
            .unwrap_err()
            .to_string();
        assert!(e.contains("particle 1"), "{e}");
        let d = with_field(vec![[0.5, 0.5, 0.0]], vec![1.0]);
        assert!(Observable::Field.difference(&a, &d).is_err());
    }

    #[test]
    fn observables_parse() {
        assert_eq!(Observable::parse("position"), Observable::Position);
        assert_eq!(Observable::parse("field"), Observable::Field);
        assert_eq!(
            Observable::parse("etotal"),
            Observable::Column("etotal".into())
        );
    }
}
