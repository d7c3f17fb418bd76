//! The keys of `kind = "fmm"`, shared by the gravity solver and the vortex
//! velocity: `tolerance = epsilon` or `order = p`, and how a run names it.

use cellist::longrange::{ErrorFit, FmmAccuracy};

/// The tolerance of `kind = "fmm"` without `tolerance` or `order`.
pub(crate) const FMM_TOLERANCE: f64 = 1e-6;

/// The accuracy of `kind = "fmm"` in the table `table` (`system.solver`,
/// `system.velocity`): the tolerance or the order (not both; the default
/// tolerance without either), checked.
pub(crate) fn fmm_accuracy(
    table: &str,
    tolerance: Option<f64>,
    order: Option<usize>,
) -> Result<FmmAccuracy, String> {
    let accuracy = match (tolerance, order) {
        (Some(_), Some(_)) => {
            return Err(format!(
                "{table}: give the fmm's tolerance or its order, not both"
            ))
        }
        (_, Some(p)) => FmmAccuracy::Order(p),
        (t, None) => FmmAccuracy::Tolerance(t.unwrap_or(FMM_TOLERANCE)),
    };
    accuracy.check().map_err(|m| format!("{table}: {m}"))?;
    Ok(accuracy)
}

/// How a run names the fmm at `accuracy` under the kernel's `fit`: its order
/// and tolerance.
pub(crate) fn fmm_name(accuracy: FmmAccuracy, fit: ErrorFit) -> String {
    format!(
        "fmm (order {}, tolerance {:e})",
        accuracy.order(fit),
        accuracy.tolerance(fit)
    )
}
