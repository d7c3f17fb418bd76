//! `cellist bench billiards`: whole runs of a collision-benchmark input,
//! without output.

use super::at_least_once;
use crate::billiards::{load, time_steps};
use crate::error::SimResult;
use crate::study::median;
use cellist::models::billiards::{CellShape, DEFAULT_MAX_SWEEPS};
use cellist::Threads;
use std::path::Path;

/// The input and how to run it.
#[derive(Clone, Copy, Debug)]
pub struct BilliardsRequest<'a> {
    /// The `.in` file.
    pub input: &'a Path,
    /// Steps (default: the input's S).
    pub steps: Option<u64>,
    /// Timed repetitions, each from the input state.
    pub repeat: usize,
    /// The cells of the contact search (the bits are the same either way).
    pub cells: CellShape,
}

/// What the collision benchmark measured.
#[derive(Clone, Copy, Debug)]
pub struct BilliardsBench {
    /// Discs.
    pub particles: usize,
    /// Steps of each run.
    pub steps: u64,
    /// Median wall time of a run (s).
    pub seconds: f64,
    /// The hardest step `(step, sweeps)`, the same for any thread count.
    pub hardest: (u64, u64),
}

/// Times `repeat` runs of the input from its start (the input's warnings go
/// to standard error).
pub fn billiards(request: &BilliardsRequest, threads: &Threads) -> SimResult<BilliardsBench> {
    at_least_once(request.repeat)?;
    let (input, start) = load(request.input, DEFAULT_MAX_SWEEPS, request.cells)?;
    let steps = request.steps.unwrap_or(input.steps);
    let mut samples = Vec::with_capacity(request.repeat);
    let mut hardest = (0, 0);
    for _ in 0..request.repeat {
        let (seconds, worst) = time_steps(&start, steps, threads)?;
        samples.push(seconds);
        hardest = worst;
    }
    Ok(BilliardsBench {
        particles: start.len(),
        steps,
        seconds: median(&samples),
        hardest,
    })
}
