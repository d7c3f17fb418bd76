//! The progress bar of long runs.

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::io::IsTerminal;

/// A progress bar over `steps` steps, hidden when stderr is not a terminal.
pub fn progress_bar(steps: u64) -> ProgressBar {
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

/// Prints `line` on standard output above `bar`.
pub fn print_above(bar: &ProgressBar, line: &str) {
    bar.suspend(|| println!("{line}"));
}
