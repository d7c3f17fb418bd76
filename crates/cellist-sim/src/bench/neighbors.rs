//! `cellist bench neighbors`: the half neighbour list of uniform random points
//! in a periodic box (the workload of vesin's `compute(quantities="ij")`).

use super::at_least_once;
use crate::error::{positive, SimError, SimResult};
use crate::neighbors::{cells, half_list, Order};
use crate::study::median;
use cellist::neighbors::half_pairs;
use cellist::random::Rng;
use cellist::{Domain, Threads};
use std::time::Instant;

/// The points and the list to time.
#[derive(Clone, Copy, Debug)]
pub struct NeighborsRequest {
    /// Number of points.
    pub n: usize,
    /// Dimension (2 or 3).
    pub dim: u8,
    /// Points per unit volume: the box side is `(n / density)^(1/dim)`.
    pub density: f64,
    /// Cutoff radius.
    pub cutoff: f64,
    /// Seed of the random points.
    pub seed: u64,
    /// Timed repetitions.
    pub repeat: usize,
    /// The pairs as `(i, j)` values in cell order (`None`: the engine's own
    /// pair list), or int64 index arrays sorted by `(i, j)` or as found.
    pub arrays: Option<Order>,
}

/// What the neighbour-list benchmark measured.
#[derive(Clone, Copy, Debug)]
pub struct NeighborsBench {
    /// Median wall time of the cell list's build and the pair list (s).
    pub seconds: f64,
    /// Pairs found.
    pub pairs: usize,
}

/// Times the cell list's build and the half pair list: the median over
/// `repeat` runs.
pub fn neighbors(request: &NeighborsRequest, threads: &Threads) -> SimResult<NeighborsBench> {
    positive("--density", request.density)?;
    positive("--cutoff", request.cutoff)?;
    if request.n < 2 {
        return Err(SimError::Input("--n must be at least 2".into()));
    }
    at_least_once(request.repeat)?;
    match request.dim {
        2 => time_half_list::<2>(request, threads),
        _ => time_half_list::<3>(request, threads),
    }
}

/// `n` uniform random points in the periodic box `[0, L)^D` with `L = (n / rho)^(1/D)`.
fn uniform_points<const D: usize>(n: usize, density: f64, seed: u64) -> (Domain<D>, Vec<[f64; D]>) {
    let side = (n as f64 / density).powf(1.0 / D as f64);
    let mut rng = Rng::new(seed);
    let points = (0..n)
        .map(|_| std::array::from_fn(|_| rng.uniform() * side))
        .collect();
    let domain = Domain::periodic([side; D]).expect("a positive side");
    (domain, points)
}

fn time_half_list<const D: usize>(
    request: &NeighborsRequest,
    threads: &Threads,
) -> SimResult<NeighborsBench> {
    let (domain, points) = uniform_points::<D>(request.n, request.density, request.seed);
    let cutoff = request.cutoff;
    let mut times = Vec::with_capacity(request.repeat);
    let mut count = 0;
    for _ in 0..request.repeat {
        let start = Instant::now();
        count = match request.arrays {
            Some(order) => {
                let pairs = half_list(&domain, &points, cutoff, Default::default(), order, threads)
                    .map_err(|e| e.flagged("--cutoff"))?;
                times.push(start.elapsed().as_secs_f64());
                pairs.len()
            }
            None => {
                let cells =
                    cells(&domain, &points, cutoff, threads).map_err(|e| e.flagged("--cutoff"))?;
                let pairs = half_pairs(&cells, cutoff, threads, |i, j, _| [i, j]);
                times.push(start.elapsed().as_secs_f64());
                pairs.len()
            }
        };
    }
    Ok(NeighborsBench {
        seconds: median(&times),
        pairs: count,
    })
}
