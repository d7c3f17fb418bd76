//! What every model's run loop shares: the progress bar and the thermo rows
//! (one CSV line per thermo step, one table line on the terminal above the bar).

use crate::error::{CliError, CliResult};
use cellist_io::{format_g17, AtomicFile};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::io::{IsTerminal, Write};

/// A progress bar over `steps` steps, hidden when stderr is not a terminal.
pub(crate) fn progress_bar(steps: u64) -> ProgressBar {
    let bar = ProgressBar::new(steps);
    bar.set_style(
        ProgressStyle::with_template("{bar:40.cyan/blue} {pos}/{len} steps  {per_sec}  eta {eta}")
            .expect("a valid progress template"),
    );
    if !std::io::stderr().is_terminal() {
        bar.set_draw_target(ProgressDrawTarget::hidden());
    }
    bar
}

/// Appends `step,v1,v2,...` (numbers at `%.17g`) to the thermo CSV, if there is
/// one, and prints `table` (the terminal's line for the same step) above `bar`.
pub(crate) fn thermo_row(
    csv: Option<&mut AtomicFile>,
    bar: Option<&ProgressBar>,
    step: u64,
    values: &[f64],
    table: &str,
) -> CliResult {
    if let Some(csv) = csv {
        let mut line = step.to_string();
        for &v in values {
            line.push(',');
            format_g17(v, &mut line);
        }
        writeln!(csv.writer(), "{line}").map_err(CliError::output("thermo.csv"))?;
    }
    match bar {
        Some(bar) => bar.suspend(|| println!("{table}")),
        None => println!("{table}"),
    }
    Ok(())
}
