//! `cellist billiards gen`: a random input file of the collision benchmark.

use crate::error::{SimError, SimResult};
use cellist::models::billiards::{separated_discs, uniform_discs, Table};
use cellist_io::AtomicFile;
use std::io::Write;
use std::path::Path;

/// The input to draw: `n` discs of radius `r` in a box of side `l`, `steps`
/// steps, velocity components uniform in `[vmin, vmax]`.
#[derive(Clone, Copy, Debug)]
pub struct Generate<'a> {
    /// Discs.
    pub n: usize,
    /// Side of the box (an integer).
    pub l: i64,
    /// Radius of the discs (an integer).
    pub r: i64,
    /// Steps written in the file.
    pub steps: u64,
    /// Smallest velocity component.
    pub vmin: f64,
    /// Largest velocity component.
    pub vmax: f64,
    /// Seed of the random numbers.
    pub seed: u64,
    /// Positions uniform in `[0, L)` as the course's generator (discs may
    /// overlap); else discs that overlap nothing.
    pub overlaps: bool,
    /// Where the input goes (default: standard output).
    pub output: Option<&'a Path>,
}

/// Draws the input and writes it, with enough digits that every value reads
/// back exactly (a file whole or not at all).
pub fn generate(request: &Generate) -> SimResult {
    let &Generate {
        n,
        l,
        r,
        steps,
        vmin,
        vmax,
        ..
    } = request;
    if l <= 0 || r <= 0 || l > i32::MAX as i64 || r > i32::MAX as i64 {
        return Err(SimError::Input(format!(
            "L ({l}) and R ({r}) must be positive integers that fit the format's int"
        )));
    }
    if !(vmin.is_finite() && vmax.is_finite() && vmin <= vmax) {
        return Err(SimError::Input(format!(
            "VMIN ({vmin}) and VMAX ({vmax}) must be finite with VMIN <= VMAX"
        )));
    }
    if n > i32::MAX as usize || steps > i32::MAX as u64 {
        return Err(SimError::Input(
            "N and STEPS must fit the format's int".into(),
        ));
    }
    let table = Table { side: l, radius: r };
    let drawn = if request.overlaps {
        uniform_discs(n, &table, vmin, vmax, request.seed)
    } else {
        separated_discs(n, &table, vmin, vmax, request.seed).map_err(SimError::Input)?
    };
    let mut text = format!("{n}\n{l}\n{r}\n{steps}\n");
    for k in 0..n {
        // `{}` prints the shortest decimal that reads back to the same double
        text.push_str(&format!(
            "{k} {} {} {} {}\n",
            drawn.x[k], drawn.y[k], drawn.v[k][0], drawn.v[k][1]
        ));
    }
    match request.output {
        Some(path) => {
            let what = path.display().to_string();
            let mut file = AtomicFile::create(path).map_err(SimError::output(&what))?;
            file.writer()
                .write_all(text.as_bytes())
                .and_then(|()| file.commit())
                .map_err(SimError::output(what))
        }
        None => std::io::stdout()
            .lock()
            .write_all(text.as_bytes())
            .map_err(SimError::output("the input")),
    }
}
