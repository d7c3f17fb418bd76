//! The thermo observer: `thermo.csv` (`step` and the model's columns at
//! `%.17g`), the table on the terminal, and the plot drawn at the end.

use super::observer::{open_stream, sync_one, Observer, Recorded};
use crate::error::{SimError, SimResult};
use crate::progress::print_above;
use cellist::models::Model;
use cellist_io::format_g17;
use cellist_io::plot::{line_chart, Series};
use cellist_io::StreamFile;
use indicatif::ProgressBar;
use std::io::Write;
use std::path::{Path, PathBuf};

/// `precision` digits in fixed or exponent form, the first `shown` value columns.
#[derive(Clone, Copy, Debug)]
pub struct TableStyle {
    /// Characters per column.
    pub width: usize,
    /// Digits after the point.
    pub precision: usize,
    /// Exponent form (`1.5e-3`) rather than fixed.
    pub exponent: bool,
    /// Value columns shown on the terminal (the CSV has all).
    pub shown: usize,
}

/// A line chart of thermo columns against time, drawn at the end of the run.
#[derive(Clone, Debug)]
pub struct PlotSpec {
    /// File name in the output folder.
    pub file: &'static str,
    /// Title.
    pub title: &'static str,
    /// Label of the time axis.
    pub x_label: &'static str,
    /// Label of the value axis.
    pub y_label: &'static str,
    /// `(legend, thermo column, plot |value|)` per curve.
    pub series: Vec<(&'static str, &'static str, bool)>,
}

/// The thermo rows: `thermo.csv` (`step` and the model's columns at `%.17g`), the
/// table on the terminal, and the plot at the end.
pub struct Thermo {
    every: u64,
    columns: Vec<&'static str>,
    style: TableStyle,
    file: StreamFile,
    dt: f64,
    rows: Vec<(u64, Vec<f64>)>,
    plot: Option<PlotSpec>,
    dir: PathBuf,
    quiet: bool,
}

const THERMO_FILE: &str = "thermo.csv";

impl Thermo {
    /// Thermo every `every` steps (and at the first and last) of `model`, the
    /// rows of a continued file read back for the plot; `quiet` prints no table.
    pub fn new<M: Model>(
        model: &M,
        every: u64,
        style: TableStyle,
        plot: Option<PlotSpec>,
        dir: &Path,
        recorded: Recorded,
        quiet: bool,
    ) -> SimResult<Self> {
        let mut columns = vec!["step"];
        columns.extend_from_slice(model.info().thermo_columns);
        let (mut file, continued) = open_stream(dir, THERMO_FILE, recorded)?;
        let rows = if continued {
            read_rows(&dir.join(THERMO_FILE), columns.len())?
        } else {
            writeln!(file.writer(), "{}", columns.join(","))
                .map_err(SimError::output(THERMO_FILE))?;
            Vec::new()
        };
        let header: String = columns[..=style.shown]
            .iter()
            .map(|c| format!("{c:>w$}", w = style.width))
            .collect();
        if !quiet {
            println!("{header}");
        }
        Ok(Thermo {
            every,
            columns,
            style,
            file,
            dt: model.dt(),
            rows,
            plot,
            dir: dir.to_path_buf(),
            quiet,
        })
    }

    fn draw_plot(&self, plot: &PlotSpec) -> SimResult {
        let curves: Vec<Vec<(f64, f64)>> = plot
            .series
            .iter()
            .map(|&(_, column, abs)| {
                let c = self
                    .columns
                    .iter()
                    .position(|n| *n == column)
                    .expect("a thermo column")
                    - 1;
                self.rows
                    .iter()
                    .map(|(step, v)| (*step as f64 * self.dt, if abs { v[c].abs() } else { v[c] }))
                    .collect()
            })
            .collect();
        let series: Vec<Series> = plot
            .series
            .iter()
            .zip(&curves)
            .map(|(&(label, _, _), points)| Series::line(label, points))
            .collect();
        let path = self.dir.join(plot.file);
        line_chart(&path, plot.title, plot.x_label, plot.y_label, &series)
            .map_err(SimError::chart(&path))
    }
}

/// The rows of a thermo CSV (after its header).
fn read_rows(path: &Path, columns: usize) -> SimResult<Vec<(u64, Vec<f64>)>> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| SimError::Input(format!("{}: cannot read: {e}", path.display())))?;
    let bad = |line: usize| {
        SimError::Input(format!(
            "{}:{line}: not a thermo row of {columns} numbers; the file does not continue the checkpoint's run",
            path.display()
        ))
    };
    let mut rows = Vec::new();
    for (k, line) in text.lines().enumerate().skip(1) {
        let mut fields = line.split(',');
        let step = fields
            .next()
            .and_then(|s| s.parse::<u64>().ok())
            .ok_or_else(|| bad(k + 1))?;
        let values: Vec<f64> = fields
            .map(|f| f.parse::<f64>())
            .collect::<Result<_, _>>()
            .map_err(|_| bad(k + 1))?;
        if values.len() + 1 != columns {
            return Err(bad(k + 1));
        }
        rows.push((step, values));
    }
    Ok(rows)
}

impl<M: Model> Observer<M> for Thermo {
    fn due(&self, step: u64, last: u64) -> bool {
        step == 0 || step == last || (self.every > 0 && step.is_multiple_of(self.every))
    }

    fn needs_observables(&self, step: u64, last: u64) -> bool {
        <Self as Observer<M>>::due(self, step, last)
    }

    fn observe(&mut self, model: &M, step: u64, _last: u64, bar: &ProgressBar) -> SimResult {
        let values = model.thermo(step);
        let mut line = step.to_string();
        for &v in &values {
            line.push(',');
            format_g17(v, &mut line);
        }
        writeln!(self.file.writer(), "{line}").map_err(SimError::output(THERMO_FILE))?;
        let TableStyle {
            width: w,
            precision: p,
            exponent,
            shown,
        } = self.style;
        let table = format!("{step:>w$}")
            + &values[..shown]
                .iter()
                .map(|v| {
                    if exponent {
                        format!("{v:>w$.p$e}")
                    } else {
                        format!("{v:>w$.p$}")
                    }
                })
                .collect::<String>();
        if !self.quiet {
            print_above(bar, &table);
        }
        self.rows.push((step, values));
        Ok(())
    }

    fn sync(&mut self) -> SimResult<Vec<(String, u64)>> {
        Ok(vec![sync_one(&mut self.file, THERMO_FILE)?])
    }

    fn finish(&mut self) -> SimResult {
        self.file.sync().map_err(SimError::output(THERMO_FILE))?;
        match &self.plot {
            Some(plot) if self.rows.len() >= 2 => self.draw_plot(plot),
            _ => Ok(()),
        }
    }

    fn take_thermo_rows(&mut self) -> Option<Vec<(u64, Vec<f64>)>> {
        Some(std::mem::take(&mut self.rows))
    }
}
