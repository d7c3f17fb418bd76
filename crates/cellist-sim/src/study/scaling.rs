//! `cellist scaling`: strong scaling of a scenario over thread counts, with the
//! serial fraction fitted by Amdahl's law, overall and per stage of the loop.
//!
//! Amdahl's law: a run whose serial part takes the fraction `f` of its time on
//! one thread takes `T(p) = T1 (f + (1 - f) / p)` on `p` threads, so its speed-up
//! `S(p) = T(1) / T(p) = 1 / (f + (1 - f) / p)` is bounded by `1 / f`.

use super::{create_dir, median, pool, probe, report_warnings, run_dir, run_quiet, study_dir};
use crate::error::{SimError, SimResult};
use crate::scenario::Scenario;
use cellist_io::format_g17;
use cellist_io::plot::{draw_chart, Chart, Series, SeriesStyle};
use std::path::{Path, PathBuf};

/// What `cellist scaling` asks for.
pub struct ScalingRequest<'a> {
    /// The scenario file, or a collision-benchmark input (`.in`).
    pub scenario: &'a Path,
    /// `--set key=value` overrides.
    pub sets: &'a [String],
    /// Thread counts, at least two different ones.
    pub threads: Vec<usize>,
    /// Runs per thread count (alternating); the median is reported.
    pub repeat: usize,
    /// The output folder (default `out/<scenario>-scaling/`).
    pub out: Option<PathBuf>,
}

/// Amdahl's law fitted to times against thread counts.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AmdahlFit {
    /// The time on one thread, `T1 = a + b`.
    pub t1: f64,
    /// The serial fraction `f = a / (a + b)`, clamped to [0, 1].
    pub serial_fraction: f64,
    /// True when the fitted `f` was outside [0, 1] and clamped: above 1 the
    /// section got slower with more threads, below 0 faster than ideal.
    pub clamped: bool,
}

impl AmdahlFit {
    /// Least-squares fit of `T(p) = a + b / p` (linear in `a`, `b`) to the points
    /// `(p, T)`; `None` with fewer than two different thread counts or no
    /// positive time.
    pub fn fit(points: &[(usize, f64)]) -> Option<Self> {
        let n = points.len() as f64;
        let (mut su, mut suu, mut st, mut sut) = (0.0, 0.0, 0.0, 0.0);
        for &(p, t) in points {
            let u = 1.0 / p as f64;
            su += u;
            suu += u * u;
            st += t;
            sut += u * t;
        }
        let det = n * suu - su * su;
        if points.len() < 2 || det.abs() <= 1e-12 * n * suu {
            return None;
        }
        let b = (n * sut - su * st) / det;
        let a = (st - b * su) / n;
        let t1 = a + b;
        if t1.is_nan() || t1 <= 0.0 {
            return None;
        }
        let f = a / t1;
        Some(AmdahlFit {
            t1,
            serial_fraction: f.clamp(0.0, 1.0),
            clamped: !(0.0..=1.0).contains(&f),
        })
    }

    /// The fitted time on `p` threads.
    pub fn time(&self, p: f64) -> f64 {
        self.t1 * (self.serial_fraction + (1.0 - self.serial_fraction) / p)
    }
}

/// The measured times of one section (the loop, or one stage) per thread count.
struct Section {
    name: String,
    /// Per thread count (in the request's order): every run's time in seconds.
    times: Vec<Vec<f64>>,
}

/// The summary of one section at one thread count.
struct Row {
    threads: usize,
    median: f64,
    min: f64,
    max: f64,
    speedup: f64,
    efficiency: f64,
}

/// Runs the scaling study: every thread count `repeat` times (alternating),
/// prints the table, the fitted serial fractions and writes `scaling.csv` and
/// `scaling.png`.
pub fn scaling(request: &ScalingRequest) -> SimResult {
    let billiards = request.scenario.extension().is_some_and(|e| e == "in");
    if billiards && !request.sets.is_empty() {
        return Err(SimError::Input(
            "--set: a collision-benchmark input (.in) has no scenario keys".into(),
        ));
    }
    let scenario = if billiards {
        None
    } else {
        Some(Scenario::load(Some(request.scenario), request.sets)?)
    };
    let name = scenario.as_ref().map_or_else(
        || {
            request
                .scenario
                .file_stem()
                .map_or_else(|| "billiards".into(), |n| n.to_string_lossy().into_owned())
        },
        |s| s.name.clone(),
    );
    if request.repeat == 0 {
        return Err(SimError::Input("--repeat must be at least 1".into()));
    }
    let threads = super::thread_counts(&request.threads)?;
    let mut distinct = threads.clone();
    distinct.sort_unstable();
    distinct.dedup();
    if distinct.len() < 2 {
        return Err(SimError::Input(
            "--threads: give at least two different thread counts, e.g. 1,2".into(),
        ));
    }
    let threads = distinct;
    let run = |p: &cellist::Threads, dir: &Path| match &scenario {
        Some(s) => run_quiet(s, p, dir),
        None => crate::billiards::run_quiet(request.scenario, p, dir),
    };
    let model = match &scenario {
        Some(s) => probe(s, &s.origin)?.model,
        None => {
            // read the input once before timing: bad input stops here
            crate::billiards::load(
                request.scenario,
                cellist::models::billiards::DEFAULT_MAX_SWEEPS,
                cellist::models::billiards::CellShape::Square,
            )?;
            "billiards"
        }
    };
    let dir = study_dir(request.out.as_deref(), &name, "scaling");
    create_dir(&dir)?;
    let cores = super::cores();
    println!(
        "strong scaling of {} ({}) on {} threads, {} run(s) each, on a machine with {cores} cores; runs in {}",
        request.scenario.display(),
        model,
        threads
            .iter()
            .map(|t| t.to_string())
            .collect::<Vec<_>>()
            .join(", "),
        request.repeat,
        dir.join("runs").display()
    );
    let pools: Vec<cellist::Threads> =
        threads.iter().map(|&t| pool(t)).collect::<SimResult<_>>()?;
    let mut sections: Vec<Section> = vec![Section {
        name: "loop".into(),
        times: vec![Vec::new(); threads.len()],
    }];
    let mut warnings = Vec::new();
    for round in 0..request.repeat {
        for (k, p) in pools.iter().enumerate() {
            let summary = run(p, &run_dir(&dir, k))?;
            report_warnings(&summary, &mut warnings);
            println!(
                "round {}/{}: {} thread(s): loop {:.4} s",
                round + 1,
                request.repeat,
                threads[k],
                summary.loop_time.as_secs_f64()
            );
            sections[0].times[k].push(summary.loop_time.as_secs_f64());
            for (name, d) in &summary.stages {
                let at = match sections.iter().position(|s| s.name == *name) {
                    Some(at) => at,
                    None => {
                        sections.push(Section {
                            name: name.to_string(),
                            times: vec![Vec::new(); threads.len()],
                        });
                        sections.len() - 1
                    }
                };
                sections[at].times[k].push(d.as_secs_f64());
            }
        }
    }
    let table: Vec<(String, Vec<Row>, Option<AmdahlFit>)> = sections
        .iter()
        .map(|s| {
            let rows = rows(&threads, s);
            let fit = AmdahlFit::fit(
                &threads
                    .iter()
                    .zip(&rows)
                    .map(|(&t, r)| (t, r.median))
                    .collect::<Vec<_>>(),
            );
            (s.name.clone(), rows, fit)
        })
        .collect();
    print_table(&table, &threads, cores);
    let csv = dir.join("scaling.csv");
    write_csv(&csv, &table)?;
    let png = dir.join("scaling.png");
    draw(&png, &name, &threads, &table[0].1, table[0].2)?;
    println!("\nresults: {}, {}", csv.display(), png.display());
    Ok(())
}

/// Median, spread, speed-up and efficiency of a section per thread count, the
/// speed-up taken against the smallest thread count `p0`: `S(p) = T(p0) / T(p)`,
/// efficiency `S(p) p0 / p`.
fn rows(threads: &[usize], section: &Section) -> Vec<Row> {
    let base = median(&section.times[0]);
    threads
        .iter()
        .zip(&section.times)
        .map(|(&p, times)| {
            let m = median(times);
            let speedup = base / m;
            Row {
                threads: p,
                median: m,
                min: times.iter().copied().fold(f64::INFINITY, f64::min),
                max: times.iter().copied().fold(f64::NEG_INFINITY, f64::max),
                speedup,
                efficiency: speedup * threads[0] as f64 / p as f64,
            }
        })
        .collect()
}

fn print_table(table: &[(String, Vec<Row>, Option<AmdahlFit>)], threads: &[usize], cores: usize) {
    let base = threads[0];
    println!(
        "\n{:>8}  {:>12}  {:>23}  {:>9}  {:>10}",
        "threads", "median (s)", "spread (s)", "speed-up", "efficiency"
    );
    for r in &table[0].1 {
        let flag = if r.threads > cores {
            format!("  oversubscribed: {} threads on {cores} cores", r.threads)
        } else {
            String::new()
        };
        println!(
            "{:>8}  {:>12.5}  {:>23}  {:>9.3}  {:>10.3}{flag}",
            r.threads,
            r.median,
            format!("{:.5} - {:.5}", r.min, r.max),
            r.speedup,
            r.efficiency
        );
    }
    if base != 1 {
        println!("(speed-up and efficiency against {base} threads)");
    }
    println!(
        "\nper stage: median time (s) per thread count, speed-up at {} threads, and the serial \
         fraction f fitted by Amdahl's law T(p) = T1 (f + (1 - f) / p):",
        threads[threads.len() - 1]
    );
    let total = table[0].1[0].median;
    let heads: Vec<String> = threads.iter().map(|t| format!("{t} thr")).collect();
    println!(
        "{:>10}  {}  {:>9}  {:>8}  {:>9}",
        "section",
        heads
            .iter()
            .map(|h| format!("{h:>10}"))
            .collect::<Vec<_>>()
            .join("  "),
        "speed-up",
        "f",
        "limit 1/f"
    );
    for (name, rows, fit) in table {
        let times: Vec<String> = rows.iter().map(|r| format!("{:>10.5}", r.median)).collect();
        let (f, limit) = match fit {
            Some(fit) => (
                format!(
                    "{:.3}{}",
                    fit.serial_fraction,
                    if fit.clamped { "*" } else { "" }
                ),
                if fit.serial_fraction > 0.0 {
                    format!("{:.2}", 1.0 / fit.serial_fraction)
                } else {
                    "none".into()
                },
            ),
            None => ("-".into(), "-".into()),
        };
        let small = if name != "loop" && rows[0].median < 0.01 * total {
            "  (under 1% of the loop: noisy)"
        } else {
            ""
        };
        println!(
            "{name:>10}  {}  {:>9.3}  {f:>8}  {limit:>9}{small}",
            times.join("  "),
            rows[rows.len() - 1].speedup
        );
    }
    if table
        .iter()
        .any(|(_, _, fit)| fit.is_some_and(|f| f.clamped))
    {
        println!(
            "*: the fitted f was outside [0, 1] and is clamped: above 1 the section got slower \
             with more threads, below 0 faster than ideal"
        );
    }
}

fn write_csv(path: &Path, table: &[(String, Vec<Row>, Option<AmdahlFit>)]) -> SimResult {
    let mut text =
        String::from("section,threads,median_s,min_s,max_s,speedup,efficiency,serial_fraction\n");
    for (name, rows, fit) in table {
        for r in rows {
            text.push_str(name);
            text.push(',');
            text.push_str(&r.threads.to_string());
            for v in [
                r.median,
                r.min,
                r.max,
                r.speedup,
                r.efficiency,
                fit.map_or(f64::NAN, |f| f.serial_fraction),
            ] {
                text.push(',');
                format_g17(v, &mut text);
            }
            text.push('\n');
        }
    }
    super::write_text(path, &text)
}

/// The measured speed-up against the fitted Amdahl curve and ideal scaling.
fn draw(
    path: &Path,
    name: &str,
    threads: &[usize],
    rows: &[Row],
    fit: Option<AmdahlFit>,
) -> SimResult {
    let p0 = threads[0] as f64;
    let top = threads[threads.len() - 1] as f64;
    let measured: Vec<(f64, f64)> = rows.iter().map(|r| (r.threads as f64, r.speedup)).collect();
    let grid: Vec<f64> = (0..=64)
        .map(|k| p0 + (top - p0) * k as f64 / 64.0)
        .collect();
    let ideal: Vec<(f64, f64)> = grid.iter().map(|&p| (p, p / p0)).collect();
    let amdahl: Vec<(f64, f64)> = fit
        .map(|f| grid.iter().map(|&p| (p, f.time(p0) / f.time(p))).collect())
        .unwrap_or_default();
    let amdahl_label = fit.map_or_else(String::new, |f| {
        format!("Amdahl, fitted f = {:.3}", f.serial_fraction)
    });
    let mut series = vec![
        Series {
            label: "measured (median)",
            points: &measured,
            style: SeriesStyle::Points,
        },
        Series {
            label: "ideal",
            points: &ideal,
            style: SeriesStyle::Reference,
        },
    ];
    if fit.is_some() {
        series.insert(1, Series::line(&amdahl_label, &amdahl));
    }
    let title = format!(
        "Strong scaling of {name} ({} cores on this machine)",
        super::cores()
    );
    let y_label = if threads[0] == 1 {
        "speed-up T(1) / T(p)".to_string()
    } else {
        format!("speed-up T({}) / T(p)", threads[0])
    };
    draw_chart(
        path,
        &Chart {
            title: &title,
            x_label: "threads p",
            y_label: &y_label,
            log_x: false,
            log_y: false,
            series: &series,
        },
    )
    .map_err(SimError::chart(path))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn amdahl_fit_recovers_a_known_serial_fraction() {
        for f in [0.0, 0.05, 0.3, 1.0] {
            let t1 = 12.5;
            let points: Vec<(usize, f64)> = [1, 2, 3, 4, 8]
                .iter()
                .map(|&p| (p, t1 * (f + (1.0 - f) / p as f64)))
                .collect();
            let fit = AmdahlFit::fit(&points).unwrap();
            assert!((fit.serial_fraction - f).abs() < 1e-12, "{f}: {fit:?}");
            assert!((fit.t1 - t1).abs() < 1e-12);
            assert!((fit.time(2.0) - points[1].1).abs() < 1e-12);
        }
    }

    #[test]
    fn amdahl_fit_of_noisy_timings_stays_close() {
        // 10% serial, times perturbed by +-1%
        let noise = [1.01, 0.99, 1.005, 0.995];
        let points: Vec<(usize, f64)> = [1, 2, 4, 8]
            .iter()
            .zip(noise)
            .map(|(&p, e)| (p, 4.0 * (0.1 + 0.9 / p as f64) * e))
            .collect();
        let fit = AmdahlFit::fit(&points).unwrap();
        assert!((fit.serial_fraction - 0.1).abs() < 0.02, "{fit:?}");
    }

    #[test]
    fn amdahl_fit_needs_two_thread_counts_and_clamps_superlinear_runs() {
        assert!(AmdahlFit::fit(&[(2, 1.0), (2, 1.1)]).is_none());
        assert!(AmdahlFit::fit(&[(1, 1.0)]).is_none());
        // faster than ideal: a < 0, clamped to f = 0
        let fit = AmdahlFit::fit(&[(1, 1.0), (2, 0.4)]).unwrap();
        assert_eq!(fit.serial_fraction, 0.0);
        assert!(fit.clamped);
        // slower with more threads: clamped to f = 1
        let fit = AmdahlFit::fit(&[(1, 1.0), (2, 1.2)]).unwrap();
        assert_eq!(fit.serial_fraction, 1.0);
        assert!(fit.clamped);
        assert!(!AmdahlFit::fit(&[(1, 1.0), (2, 0.6)]).unwrap().clamped);
    }
}
