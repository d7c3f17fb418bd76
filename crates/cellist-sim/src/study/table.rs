//! The result of a sweep: one row per combination of the swept values, printed
//! as a table, written as `sweep.csv`, and drawn as `sweep.png` (the first metric
//! against the first swept key, one line per combination of the other swept
//! keys; further metrics as `sweep-<metric>.png`).

use crate::error::{SimError, SimResult};
use cellist_io::format_g17;
use cellist_io::plot::{draw_chart, Chart, Series, SeriesStyle};
use std::path::{Path, PathBuf};

/// A measured quantity of a sweep: its name (the CSV column) and its axis label
/// (with the unit).
#[derive(Clone, Debug)]
pub struct Column {
    /// The CSV column and table heading.
    pub name: String,
    /// The axis label, with the unit.
    pub label: String,
}

/// The rows of a sweep.
#[derive(Clone, Debug)]
pub struct SweepTable {
    /// What was swept (the title's subject), e.g. the scenario's name.
    pub subject: String,
    /// The swept keys, in the order of the command line (the thread count is a
    /// key too).
    pub keys: Vec<String>,
    /// Per key: true when it moves with the key before it (one value of the
    /// other for each of its values), so that it is neither an axis nor a line
    /// of its own in the pictures.
    pub linked: Vec<bool>,
    /// The measured quantities.
    pub metrics: Vec<Column>,
    /// One row per combination: the keys' values (as text) and the metrics.
    pub rows: Vec<(Vec<String>, Vec<f64>)>,
}

impl SweepTable {
    /// The keys whose value is not the same in every row.
    pub fn varied(&self) -> Vec<usize> {
        (0..self.keys.len())
            .filter(|&k| {
                let first = self.rows.first().map(|r| &r.0[k]);
                self.rows.iter().any(|r| Some(&r.0[k]) != first)
            })
            .collect()
    }

    /// Prints the table, writes `dir/sweep.csv` and the pictures, and names the
    /// files written.
    pub fn report(&self, dir: &Path) -> SimResult {
        println!();
        self.print();
        let csv = dir.join("sweep.csv");
        self.write_csv(&csv)?;
        let pictures = self.plot(dir)?;
        println!(
            "\nresults: {}, {}",
            csv.display(),
            pictures
                .iter()
                .map(|p| p.display().to_string())
                .collect::<Vec<_>>()
                .join(", ")
        );
        Ok(())
    }

    /// Prints the table on standard output: the keys that vary and the metrics,
    /// after a line with the keys that do not (the CSV has every key).
    pub fn print(&self) {
        let varied = self.varied();
        if let Some((first, _)) = self.rows.first() {
            let fixed: Vec<String> = (0..self.keys.len())
                .filter(|k| !varied.contains(k))
                .map(|k| format!("{} = {}", self.keys[k], first[k]))
                .collect();
            if !fixed.is_empty() {
                println!("fixed: {}", fixed.join(", "));
            }
        }
        let mut heads: Vec<String> = varied.iter().map(|&k| self.keys[k].clone()).collect();
        heads.extend(self.metrics.iter().map(|m| m.name.clone()));
        let cells: Vec<Vec<String>> = self
            .rows
            .iter()
            .map(|(values, metrics)| {
                let mut row: Vec<String> = varied.iter().map(|&k| values[k].clone()).collect();
                row.extend(metrics.iter().map(|v| format!("{v:.6e}")));
                row
            })
            .collect();
        let widths: Vec<usize> = (0..heads.len())
            .map(|c| {
                cells
                    .iter()
                    .map(|r| r[c].len())
                    .chain([heads[c].len()])
                    .max()
                    .unwrap_or(0)
            })
            .collect();
        let line = |row: &[String]| {
            row.iter()
                .zip(&widths)
                .map(|(v, w)| format!("{v:>w$}"))
                .collect::<Vec<_>>()
                .join("  ")
        };
        println!("{}", line(&heads));
        for row in &cells {
            println!("{}", line(row));
        }
    }

    /// Writes the rows as CSV (values as given, metrics at `%.17g`; a value with a
    /// comma or quote is quoted).
    pub fn write_csv(&self, path: &Path) -> SimResult {
        let mut text = String::new();
        let mut heads: Vec<String> = self.keys.iter().map(|k| csv_field(k)).collect();
        heads.extend(self.metrics.iter().map(|m| csv_field(&m.name)));
        text.push_str(&heads.join(","));
        text.push('\n');
        for (values, metrics) in &self.rows {
            let mut fields: Vec<String> = values.iter().map(|v| csv_field(v)).collect();
            for &m in metrics {
                let mut s = String::new();
                format_g17(m, &mut s);
                fields.push(s);
            }
            text.push_str(&fields.join(","));
            text.push('\n');
        }
        super::write_text(path, &text)
    }

    /// Draws each metric against the first key that takes several values (the
    /// first key if none does), one line per combination of the other keys that
    /// take several values (keys linked to another are neither): `sweep.png` for the first metric, `sweep-<name>.png`
    /// for the others. Returns the files written.
    pub fn plot(&self, dir: &Path) -> SimResult<Vec<PathBuf>> {
        let varied: Vec<usize> = self
            .varied()
            .into_iter()
            .filter(|&k| !self.linked.get(k).copied().unwrap_or(false))
            .collect();
        let x_key = varied.first().copied().unwrap_or(0);
        let others: Vec<usize> = varied.iter().copied().filter(|&k| k != x_key).collect();
        // x: the values as numbers when they all are, else their positions
        let numbers: Option<Vec<f64>> = self
            .rows
            .iter()
            .map(|r| r.0[x_key].parse::<f64>().ok())
            .collect();
        let mut levels: Vec<&str> = Vec::new();
        for r in &self.rows {
            if !levels.contains(&r.0[x_key].as_str()) {
                levels.push(&r.0[x_key]);
            }
        }
        let x_of = |row: usize| match &numbers {
            Some(v) => v[row],
            None => levels
                .iter()
                .position(|l| *l == self.rows[row].0[x_key])
                .unwrap_or(0) as f64,
        };
        let x_label = match &numbers {
            Some(_) => self.keys[x_key].clone(),
            None => format!(
                "{} ({})",
                self.keys[x_key],
                levels
                    .iter()
                    .enumerate()
                    .map(|(k, l)| format!("{k} = {l}"))
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
        };
        // one line per combination of the other varied keys, in order of appearance
        let mut groups: Vec<(String, Vec<usize>)> = Vec::new();
        for (row, (values, _)) in self.rows.iter().enumerate() {
            let label = others
                .iter()
                .map(|&k| format!("{} = {}", self.keys[k], values[k]))
                .collect::<Vec<_>>()
                .join(", ");
            match groups.iter_mut().find(|(l, _)| *l == label) {
                Some((_, rows)) => rows.push(row),
                None => groups.push((label, vec![row])),
            }
        }
        let mut written = Vec::new();
        for (m, metric) in self.metrics.iter().enumerate() {
            let curves: Vec<(String, Vec<(f64, f64)>)> = groups
                .iter()
                .map(|(label, rows)| {
                    let mut points: Vec<(f64, f64)> =
                        rows.iter().map(|&r| (x_of(r), self.rows[r].1[m])).collect();
                    points.sort_by(|a, b| a.0.total_cmp(&b.0));
                    let label = if label.is_empty() {
                        metric.name.clone()
                    } else {
                        label.clone()
                    };
                    (label, points)
                })
                .collect();
            let series: Vec<Series> = curves
                .iter()
                .map(|(label, points)| Series {
                    label,
                    points,
                    style: SeriesStyle::Points,
                })
                .collect();
            let all = curves.iter().flat_map(|(_, p)| p);
            let log_y = spans_decades(all.clone().map(|p| p.1), 30.0);
            // a power law is a line on log-log axes
            let log_x = numbers.is_some()
                && spans_decades(all.map(|p| p.0), if log_y { 4.0 } else { 30.0 });
            let file = if m == 0 {
                "sweep.png".to_string()
            } else {
                format!("sweep-{}.png", file_safe(&metric.name))
            };
            let path = dir.join(file);
            let title = format!(
                "{}: {} against {}",
                self.subject, metric.name, self.keys[x_key]
            );
            draw_chart(
                &path,
                &Chart {
                    title: &title,
                    x_label: &x_label,
                    y_label: &metric.label,
                    log_x,
                    log_y,
                    series: &series,
                },
            )
            .map_err(SimError::chart(&path))?;
            written.push(path);
        }
        Ok(written)
    }
}

/// True when every value is positive and the largest is at least `ratio` times
/// the smallest: such an axis reads better on a log scale.
pub fn spans_decades(values: impl Iterator<Item = f64>, ratio: f64) -> bool {
    let (mut lo, mut hi) = (f64::INFINITY, 0.0f64);
    for v in values.filter(|v| v.is_finite()) {
        if v <= 0.0 {
            return false;
        }
        lo = lo.min(v);
        hi = hi.max(v);
    }
    lo.is_finite() && hi >= ratio * lo
}

/// A name usable in a file name: letters, digits, `.`, `-` and `_` kept, the
/// rest `_`.
fn file_safe(name: &str) -> String {
    name.chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || matches!(c, '.' | '-' | '_') {
                c
            } else {
                '_'
            }
        })
        .collect()
}

/// A CSV field, quoted when it holds a comma, a quote or a line break.
fn csv_field(v: &str) -> String {
    if v.contains([',', '"', '\n']) {
        format!("\"{}\"", v.replace('"', "\"\""))
    } else {
        v.to_string()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn table() -> SweepTable {
        let mut rows = Vec::new();
        for cells in ["[4,4,4]", "[8,8,8]"] {
            for n in [100, 1000, 10000] {
                rows.push((
                    vec![n.to_string(), cells.to_string()],
                    vec![n as f64 / 1024.0, 1.0],
                ));
            }
        }
        SweepTable {
            subject: "test".into(),
            keys: vec!["system.n".into(), "system.cells".into()],
            linked: vec![false, false],
            metrics: vec![
                Column {
                    name: "time".into(),
                    label: "loop wall time (s)".into(),
                },
                Column {
                    name: "etotal".into(),
                    label: "etotal".into(),
                },
            ],
            rows,
        }
    }

    #[test]
    fn csv_has_a_row_per_combination_with_quoted_lists() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("sweep.csv");
        table().write_csv(&path).unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines.len(), 7);
        assert_eq!(lines[0], "system.n,system.cells,time,etotal");
        // 100 / 1024 = 0.09765625 exactly; the list value is quoted
        assert_eq!(lines[1], "100,\"[4,4,4]\",0.09765625,1");
    }

    #[test]
    fn plots_every_metric() {
        let dir = tempfile::tempdir().unwrap();
        let files = table().plot(dir.path()).unwrap();
        assert_eq!(files.len(), 2);
        assert!(files[0].ends_with("sweep.png") && files[1].ends_with("sweep-etotal.png"));
        for f in files {
            assert_eq!(&std::fs::read(f).unwrap()[1..4], b"PNG");
        }
    }

    #[test]
    fn log_axes_only_for_positive_values_over_decades() {
        assert!(spans_decades([1.0, 100.0].into_iter(), 30.0));
        assert!(!spans_decades([1.0, 10.0].into_iter(), 30.0));
        assert!(spans_decades([1.0, 10.0].into_iter(), 4.0));
        assert!(!spans_decades([0.0, 100.0].into_iter(), 30.0));
    }
}
