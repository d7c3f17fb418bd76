//! Boxes, boundaries, periodic wrap and the minimum-image convention, for 2D and 3D
//! with one code path (the dimension `D` is a const generic).

use std::fmt;

/// What happens at the two faces of one axis.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Boundary {
    /// The axis wraps: `x` and `x + L` are the same point, distances use the nearest image.
    Periodic,
    /// No wrap: particles interact only through the box, never across it. Walls
    /// are open boundaries to the neighbour search (a model adds the wall force).
    Open,
}

/// Why a domain or a cutoff was refused.
#[derive(Clone, Debug, PartialEq)]
pub enum GeometryError {
    /// A side length that is not finite and positive.
    BadLength {
        /// The axis (0 = x).
        axis: usize,
        /// The offending length.
        length: f64,
    },
    /// A cutoff that is not finite and positive.
    BadCutoff(f64),
    /// A cutoff larger than half a periodic side: the minimum image would not be unique.
    CutoffTooLarge {
        /// The axis (0 = x).
        axis: usize,
        /// The cutoff (including any skin) that was asked for.
        cutoff: f64,
        /// The periodic side length of that axis.
        length: f64,
    },
}

impl fmt::Display for GeometryError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        const AXES: [&str; 3] = ["x", "y", "z"];
        match *self {
            GeometryError::BadLength { axis, length } => write!(
                f,
                "box side along {} must be finite and > 0, got {length}",
                AXES[axis]
            ),
            GeometryError::BadCutoff(c) => write!(f, "cutoff must be finite and > 0, got {c}"),
            GeometryError::CutoffTooLarge {
                axis,
                cutoff,
                length,
            } => write!(
                f,
                "cutoff {cutoff} is larger than half the periodic box side along {} \
                 ({length} / 2 = {}): the nearest image would not be unique; \
                 use a larger box or a smaller cutoff",
                AXES[axis],
                length / 2.0
            ),
        }
    }
}

impl std::error::Error for GeometryError {}

/// A box `[lo, lo + length)` with a boundary per axis.
///
/// On a periodic axis the wrapped coordinate is `x - L floor((x - lo) / L)` and the
/// minimum image of a separation `d` is `d - L round(d / L)`. On an open axis
/// `lo` and `length` only describe where particles are expected; nothing wraps.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Domain<const D: usize> {
    /// Lower corner.
    pub lo: [f64; D],
    /// Side lengths.
    pub length: [f64; D],
    /// Boundary per axis.
    pub boundary: [Boundary; D],
}

impl<const D: usize> Domain<D> {
    /// A box with the lower corner at the origin and the given sides and boundaries.
    pub fn new(length: [f64; D], boundary: [Boundary; D]) -> Result<Self, GeometryError> {
        for (axis, &l) in length.iter().enumerate() {
            if !(l.is_finite() && l > 0.0) {
                return Err(GeometryError::BadLength { axis, length: l });
            }
        }
        Ok(Domain {
            lo: [0.0; D],
            length,
            boundary,
        })
    }

    /// A fully periodic box `[0, L_0) x ... x [0, L_{D-1})`.
    pub fn periodic(length: [f64; D]) -> Result<Self, GeometryError> {
        Self::new(length, [Boundary::Periodic; D])
    }

    /// An open domain spanning the bounding box of `points` (a unit box when empty).
    /// Every axis is open, so the extent only sizes the cell grid.
    pub fn open_around(points: &[[f64; D]]) -> Self {
        let (lo, hi) = bounding_box(points);
        let length = std::array::from_fn(|d| (hi[d] - lo[d]).max(f64::MIN_POSITIVE));
        Domain {
            lo,
            length,
            boundary: [Boundary::Open; D],
        }
    }

    /// The box of sides `length` from `lo` for `points`, periodic on the axes
    /// where `periodic` is true. Its open axes span the points wherever they
    /// are (only the cell grid sees their extent); with no periodic axis it is
    /// [`Domain::open_around`].
    pub fn for_points(
        points: &[[f64; D]],
        length: [f64; D],
        lo: [f64; D],
        periodic: [bool; D],
    ) -> Result<Self, GeometryError> {
        if periodic.iter().all(|&p| !p) {
            return Ok(Self::open_around(points));
        }
        let boundary = periodic.map(|p| {
            if p {
                Boundary::Periodic
            } else {
                Boundary::Open
            }
        });
        let mut domain = Self::new(length, boundary)?;
        domain.lo = lo;
        let (low, high) = bounding_box(points);
        for d in (0..D).filter(|&d| !periodic[d] && !points.is_empty()) {
            domain.lo[d] = low[d];
            domain.length[d] = (high[d] - low[d]).max(f64::MIN_POSITIVE);
        }
        Ok(domain)
    }

    /// The walls of the non-periodic axes: `(axis, lo, lo + L)` for each.
    pub fn walls(&self) -> Vec<(usize, f64, f64)> {
        (0..D)
            .filter(|&a| !self.is_periodic(a))
            .map(|a| (a, self.lo[a], self.lo[a] + self.length[a]))
            .collect()
    }

    /// True when axis `d` wraps.
    #[inline]
    pub fn is_periodic(&self, d: usize) -> bool {
        self.boundary[d] == Boundary::Periodic
    }

    /// Volume (area in 2D) of the box.
    pub fn volume(&self) -> f64 {
        self.length.iter().product()
    }

    /// Checks that a cutoff is positive and at most half of every periodic side,
    /// so that at most one image of any particle lies within it.
    pub fn check_cutoff(&self, cutoff: f64) -> Result<(), GeometryError> {
        if !(cutoff.is_finite() && cutoff > 0.0) {
            return Err(GeometryError::BadCutoff(cutoff));
        }
        for d in 0..D {
            if self.is_periodic(d) && cutoff > 0.5 * self.length[d] {
                return Err(GeometryError::CutoffTooLarge {
                    axis: d,
                    cutoff,
                    length: self.length[d],
                });
            }
        }
        Ok(())
    }

    /// Maps a point into the primary box on periodic axes:
    /// `x' = x - L floor((x - lo) / L)`, with the rare rounding to `lo + L` folded to `lo`.
    #[inline]
    pub fn wrap(&self, mut x: [f64; D]) -> [f64; D] {
        for d in 0..D {
            if self.is_periodic(d) {
                x[d] = wrap_coordinate(x[d], self.lo[d], self.length[d]);
            }
        }
        x
    }

    /// The minimum image of a separation: on periodic axes `d - L round(d / L)`,
    /// so that `|d_k| <= L_k / 2`.
    #[inline]
    pub fn minimum_image(&self, mut sep: [f64; D]) -> [f64; D] {
        for d in 0..D {
            if self.is_periodic(d) {
                let l = self.length[d];
                sep[d] -= l * (sep[d] / l).round();
            }
        }
        sep
    }

    /// Minimum-image separation `x_j - x_i`.
    #[inline]
    pub fn separation(&self, xi: &[f64; D], xj: &[f64; D]) -> [f64; D] {
        self.minimum_image(std::array::from_fn(|d| xj[d] - xi[d]))
    }
}

/// `x - L floor((x - lo) / L)` in `[lo, lo + L)`.
#[inline]
pub fn wrap_coordinate(x: f64, lo: f64, length: f64) -> f64 {
    let rel = x - lo;
    if (0.0..length).contains(&rel) {
        return x;
    }
    let mut w = lo + (rel - length * (rel / length).floor());
    // rounding can leave w a hair outside [lo, lo + L): one more period, then fold
    if w < lo {
        w += length;
    }
    if w >= lo + length || w < lo {
        lo
    } else {
        w
    }
}

/// Lower and upper corner of the points (the unit box at the origin when there are none).
pub fn bounding_box<const D: usize>(points: &[[f64; D]]) -> ([f64; D], [f64; D]) {
    if points.is_empty() {
        return ([0.0; D], [1.0; D]);
    }
    let mut bounds = empty_box();
    widen_box(&mut bounds, points);
    bounds
}

/// The box around no points, for [`widen_box`]: lower corner `+inf`, upper
/// `-inf`.
pub fn empty_box<const D: usize>() -> ([f64; D], [f64; D]) {
    ([f64::INFINITY; D], [f64::NEG_INFINITY; D])
}

/// Widens `bounds` to hold `points`: `lo_d = min(lo_d, p_d)` and
/// `hi_d = max(hi_d, p_d)` point after point in order, so a box widened a
/// block at a time is the one [`bounding_box`] gives all at once, bit for
/// bit.
pub fn widen_box<const D: usize>(bounds: &mut ([f64; D], [f64; D]), points: &[[f64; D]]) {
    let (lo, hi) = bounds;
    for p in points {
        for d in 0..D {
            lo[d] = lo[d].min(p[d]);
            hi[d] = hi[d].max(p[d]);
        }
    }
}

/// Squared Euclidean norm `sum_k d_k^2`.
#[inline(always)]
pub fn norm2<const D: usize>(d: &[f64; D]) -> f64 {
    let mut s = 0.0;
    for v in d {
        s += v * v;
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wrap_lands_in_the_primary_box() {
        let dom = Domain::periodic([2.0, 3.0]).unwrap();
        let w = dom.wrap([-0.5, 7.25]);
        assert_eq!(w, [1.5, 1.25]);
        // a tiny negative coordinate rounds to L and is folded to 0
        let w = dom.wrap([-1e-300, 0.0]);
        assert!(w[0] >= 0.0 && w[0] < 2.0);
        // floor(x / L) rounds up here, so x - L floor(x / L) is slightly negative
        let (x, l): (f64, f64) = (830.4678552972781, 17.30141365202663);
        assert!(x - l * (x / l).floor() < 0.0);
        let w = wrap_coordinate(x, 0.0, l);
        assert!((0.0..l).contains(&w), "{w}");
    }

    #[test]
    fn minimum_image_is_the_nearest_image() {
        let dom = Domain::periodic([10.0, 10.0, 10.0]).unwrap();
        let d = dom.separation(&[0.5, 9.5, 5.0], &[9.5, 0.5, 5.0]);
        assert_eq!(d, [-1.0, 1.0, 0.0]);
    }

    #[test]
    fn open_axes_do_not_wrap() {
        let dom = Domain::new([1.0, 1.0], [Boundary::Open, Boundary::Periodic]).unwrap();
        assert_eq!(dom.wrap([3.0, 3.25]), [3.0, 0.25]);
        assert_eq!(dom.separation(&[0.0, 0.0], &[0.9, 0.9]), [0.9, 0.9 - 1.0]);
    }

    #[test]
    fn cutoff_above_half_a_periodic_side_is_refused() {
        let dom = Domain::periodic([4.0, 10.0]).unwrap();
        assert!(dom.check_cutoff(2.0).is_ok());
        let err = dom.check_cutoff(2.5).unwrap_err();
        assert!(matches!(err, GeometryError::CutoffTooLarge { axis: 0, .. }));
        assert!(err
            .to_string()
            .contains("half the periodic box side along x"));
        assert!(dom.check_cutoff(0.0).is_err());
        assert!(dom.check_cutoff(f64::NAN).is_err());
        let open = Domain::new([4.0, 4.0], [Boundary::Open; 2]).unwrap();
        assert!(open.check_cutoff(100.0).is_ok());
    }

    #[test]
    fn bad_lengths_are_refused() {
        assert!(Domain::periodic([1.0, 0.0]).is_err());
        assert!(Domain::periodic([f64::INFINITY, 1.0]).is_err());
    }
}
