//! Where the cut planes of an axis go when they balance the particles: each
//! slab of `p` holds about `N / p` of them (LAMMPS's `balance shift`, the
//! planes of a tensor grid moved one axis at a time), found from a histogram
//! of the particles' coordinates that the ranks sum, so that every rank places
//! the same planes whatever particles it holds.

/// How the planes of a decomposition are placed (scenario key
/// `[decomposition] balance`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Balance {
    /// Equally spaced planes: equal subdomains (`"uniform"`).
    Uniform,
    /// Planes placed so that each slab along an axis holds an equal share of
    /// the particles (`"rcb"`), placed again at a neighbour-list rebuild when
    /// the load imbalance exceeds [`REBALANCE_ABOVE`].
    Rcb,
}

/// Bins per axis of the histogram the balanced planes are placed from: a
/// plane lies within `L / 1024` of where the particles would put it.
pub const BALANCE_BINS: usize = 1024;

/// The load imbalance (largest over mean particles per rank) above which a
/// balanced run places its planes again at a neighbour-list rebuild: below
/// 5% the moved planes would buy less than the migration they cause.
pub const REBALANCE_ABOVE: f64 = 1.05;

/// The bin of coordinate `x` in `[lo, lo + length)` cut into
/// [`BALANCE_BINS`] (below and NaN: the first; above: the last).
pub(super) fn bin(x: f64, lo: f64, length: f64) -> usize {
    let b = ((x - lo) / length * BALANCE_BINS as f64).floor();
    if b.is_nan() || b < 0.0 {
        0
    } else {
        (b as usize).min(BALANCE_BINS - 1)
    }
}

/// The `slabs + 1` planes along an axis `[lo, lo + length)` binned as
/// `counts`: plane `k` where the counts, spread evenly over each bin, reach
/// `k N / slabs` (when they reach it at the end of a bin followed by empty
/// ones, in the middle of the gap, as far from the particles on either side:
/// a crystal's plane of atoms does not lie next to a cut), then clamped so that every slab is at least `w = reach (1 +
/// 1e-9)` wide (plane `k` within `[lo + k w, hi - (slabs - k) w]` and at least
/// `w` above plane `k - 1`): a hair wider than `reach`, so that a particle on
/// the far face of a clamped slab is beyond reach of the slab's other side.
/// `None` without counts or when `slabs` slabs of `w` do not fit.
pub(super) fn quantile_planes(
    counts: &[u64],
    slabs: usize,
    lo: f64,
    length: f64,
    reach: f64,
) -> Option<Vec<f64>> {
    let total: u64 = counts.iter().sum();
    let least = reach * (1.0 + 1e-9);
    if total == 0 || length < slabs as f64 * least {
        return None;
    }
    let hi = lo + length;
    let width = length / counts.len() as f64;
    let mut planes = Vec::with_capacity(slabs + 1);
    planes.push(lo);
    // counts[..bin] hold `below` particles, fewer than the plane's share
    let (mut bin, mut below) = (0, 0u64);
    for k in 1..slabs {
        let share = total as f64 * k as f64 / slabs as f64;
        while bin < counts.len() && ((below + counts[bin]) as f64) < share {
            below += counts[bin];
            bin += 1;
        }
        let within = match counts.get(bin) {
            Some(&c) if c > 0 => (share - below as f64) / c as f64,
            _ => 0.0,
        };
        let at = if within == 1.0 {
            let next = (bin + 1..counts.len())
                .find(|&b| counts[b] > 0)
                .unwrap_or(counts.len());
            0.5 * (bin + 1 + next) as f64
        } else {
            bin as f64 + within
        };
        let plane = (lo + at * width)
            .clamp(lo + k as f64 * least, hi - (slabs - k) as f64 * least)
            .max(planes[k - 1] + least);
        planes.push(plane);
    }
    planes.push(hi);
    Some(planes)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn planes_split_the_counts_evenly() {
        // 3 slabs over 10 bins of width 1, all counts in the first half
        let mut counts = vec![0u64; 10];
        counts[..5].copy_from_slice(&[30, 30, 30, 30, 30]);
        let planes = quantile_planes(&counts, 3, 0.0, 10.0, 0.5).unwrap();
        assert_eq!(planes.len(), 4);
        assert!((planes[1] - 50.0 / 30.0).abs() < 1e-12, "{planes:?}");
        assert!((planes[2] - 100.0 / 30.0).abs() < 1e-12, "{planes:?}");
        assert_eq!((planes[0], planes[3]), (0.0, 10.0));
    }

    #[test]
    fn a_share_reached_before_a_gap_puts_the_plane_in_its_middle() {
        // two layers in bins 1 and 5: the plane halfway between bins 2 and 5
        let mut counts = vec![0u64; 10];
        counts[1] = 10;
        counts[5] = 10;
        let planes = quantile_planes(&counts, 2, 0.0, 10.0, 0.5).unwrap();
        assert_eq!(planes, [0.0, 3.5, 10.0]);
    }

    #[test]
    fn planes_keep_every_slab_reach_wide() {
        // everything in one bin: the planes are pushed apart to `reach`
        let mut counts = vec![0u64; 10];
        counts[2] = 100;
        let planes = quantile_planes(&counts, 4, 0.0, 10.0, 2.0).unwrap();
        assert!(planes.windows(2).all(|w| w[1] - w[0] >= 2.0), "{planes:?}");
        // everything at the top: the planes are pushed down from the top face
        let mut counts = vec![0u64; 10];
        counts[9] = 100;
        let planes = quantile_planes(&counts, 4, 0.0, 10.0, 2.0).unwrap();
        assert!(planes.windows(2).all(|w| w[1] - w[0] >= 2.0), "{planes:?}");
        assert!((planes[3] - 8.0).abs() < 1e-6, "{planes:?}");
        assert_eq!(quantile_planes(&counts, 4, 0.0, 10.0, 2.6), None);
        assert_eq!(quantile_planes(&[0; 10], 4, 0.0, 10.0, 1.0), None);
    }

    #[test]
    fn bins_clamp_what_lies_outside() {
        assert_eq!(bin(-1.0, 0.0, 1.0), 0);
        assert_eq!(bin(f64::NAN, 0.0, 1.0), 0);
        assert_eq!(bin(2.0, 0.0, 1.0), BALANCE_BINS - 1);
        assert_eq!(bin(0.5, 0.0, 1.0), BALANCE_BINS / 2);
    }
}
