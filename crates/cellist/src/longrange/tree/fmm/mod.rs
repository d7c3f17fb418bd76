//! The fast multipole method on the octree the Barnes-Hut solvers build: one
//! traversal ([`engine`]) and two kinds of expansions, complex-variable ones
//! in 2D ([`complex`], the vortex velocity) and solid harmonics in 3D
//! ([`solid`]: gravity's `1/r`, and the 3D vortex velocity as the curl of
//! three such potentials, [`vortex3`]).

mod blob_rest;
mod complex;
mod engine;
mod gravity;
mod rotation;
mod solid;
mod vortex;
mod vortex3;

pub use gravity::GravityFmm;
pub use vortex::VortexFmm;
pub use vortex3::VortexFmm3;

/// The tolerances an FMM takes, exclusive bounds.
pub const TOLERANCE_RANGE: (f64, f64) = (1e-15, 1e-1);

/// The expansion orders an FMM takes.
pub const ORDER_RANGE: (usize, usize) = (1, 63);

/// How the measured error of an FMM falls with its order `p`: from order
/// `least` on, the error at order `p` is below `at_zero decay^p`, and past
/// order `knee` below `at_zero decay^knee slower^(p - knee)` (a kernel whose
/// fall slows at high orders; `knee = None` for one fall). Each kernel's fit
/// is stated where its constants are measured.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ErrorFit {
    /// The fall per order.
    pub decay: f64,
    /// The error at order 0 that the fall starts from.
    pub at_zero: f64,
    /// The least order a tolerance picks (below it the fall is slower).
    pub least: usize,
    /// The order from which the error falls by `slower` per order, and that
    /// fall.
    pub knee: Option<(usize, f64)>,
}

impl ErrorFit {
    /// The bound `at_zero decay^p` (`slower` per order past the knee).
    pub fn bound(&self, p: usize) -> f64 {
        match self.knee {
            Some((knee, slower)) if p > knee => {
                self.at_zero * self.decay.powi(knee as i32) * slower.powi((p - knee) as i32)
            }
            _ => self.at_zero * self.decay.powi(p as i32),
        }
    }
}

/// How accurate an FMM evaluation is asked to be.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum FmmAccuracy {
    /// A relative tolerance `epsilon` in `(1e-15, 1e-1)`: the expansions'
    /// order is the least `p >= least` with `at_zero decay^p <= epsilon` (the
    /// kernel's [`ErrorFit`]).
    Tolerance(f64),
    /// The expansions' order `p` itself.
    Order(usize),
}

impl FmmAccuracy {
    /// Checks the range of the tolerance or order (the message names the key).
    pub fn check(&self) -> Result<(), String> {
        match *self {
            FmmAccuracy::Tolerance(t) => {
                let (lo, hi) = TOLERANCE_RANGE;
                if !(t > lo && t < hi) {
                    return Err(format!("tolerance must be in ({lo:e}, {hi:e}), got {t}"));
                }
            }
            FmmAccuracy::Order(p) => {
                let (lo, hi) = ORDER_RANGE;
                if !(lo..=hi).contains(&p) {
                    return Err(format!("order must be in {lo}..={hi}, got {p}"));
                }
            }
        }
        Ok(())
    }

    /// The expansions' order `p` under the kernel's `fit`: the least
    /// `p >= least` whose [`ErrorFit::bound`] is at most the tolerance.
    pub fn order(&self, fit: ErrorFit) -> usize {
        match *self {
            FmmAccuracy::Tolerance(t) => {
                let p = match fit.knee {
                    Some((knee, slower)) if fit.bound(knee) > t => {
                        knee + ((t / fit.bound(knee)).ln() / slower.ln()).ceil() as usize
                    }
                    _ => ((t / fit.at_zero).ln() / fit.decay.ln()).ceil() as usize,
                };
                p.clamp(fit.least.max(ORDER_RANGE.0), ORDER_RANGE.1)
            }
            FmmAccuracy::Order(p) => p,
        }
    }

    /// The tolerance the order stands for under `fit`: the given one, or
    /// [`ErrorFit::bound`] at the order.
    pub fn tolerance(&self, fit: ErrorFit) -> f64 {
        match *self {
            FmmAccuracy::Tolerance(t) => t,
            FmmAccuracy::Order(p) => fit.bound(p),
        }
    }
}
