//! What the 2D and 3D vortex scenarios share: the blob keys' defaults and
//! checks, `system.velocity` and the solver it names, the diffusion's step
//! limit.

use super::fmm_keys::fmm_accuracy;
use crate::error::SimResult;
use crate::launch::RunContext;
use crate::models::field_output::RunKeys;
use crate::scenario::keys::choice;
use crate::scenario::Scenario;
use cellist::longrange::{FmmAccuracy, TreeParams};
use cellist::models::pse::Integrator;
use serde::Deserialize;

/// The default `sigma_over_h`.
pub(super) fn one_and_a_half() -> f64 {
    1.5
}

/// The default (and only) `kernel`.
pub(super) fn gaussian() -> String {
    "gaussian".into()
}

/// The default `remesh_threshold`.
pub(super) fn threshold() -> f64 {
    1e-12
}

/// The default `pse_cutoff_factor`.
pub(super) fn four() -> f64 {
    4.0
}

/// `system.velocity`: the solver and its settings (both dimensions).
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct VelocityKeys {
    kind: String,
    theta: Option<f64>,
    leaf_size: Option<usize>,
    group_size: Option<usize>,
    grid: Option<usize>,
    boundary: Option<String>,
    #[serde(rename = "box")]
    side: Option<f64>,
    tolerance: Option<f64>,
    order: Option<usize>,
}

impl Default for VelocityKeys {
    fn default() -> Self {
        VelocityKeys {
            kind: "barnes-hut".into(),
            theta: None,
            leaf_size: None,
            group_size: None,
            grid: None,
            boundary: None,
            side: None,
            tolerance: None,
            order: None,
        }
    }
}

/// The most particles an initial condition may seed (about 2.4 GB of state and
/// buffers).
pub(super) const MAX_SEEDED: f64 = 5e7;

/// The velocity solver `system.velocity` names, its keys checked, before the
/// dimension's own settings: the tree's, or the mesh's grid and periodic box side.
pub(super) enum SolverChoice {
    /// All pairs.
    Direct,
    /// The Barnes-Hut tree.
    BarnesHut(TreeParams),
    /// Vortex-in-cell: `grid` (if given) and the periodic box's side (`None`:
    /// unbounded).
    Mesh {
        grid: Option<usize>,
        periodic: Option<f64>,
    },
    /// The fast multipole method at this accuracy.
    Fmm(FmmAccuracy),
}

/// The solver of `system.velocity` (the tree's theta `theta` unless given),
/// its keys checked against the solver's.
pub(super) fn solver_choice(
    scenario: &Scenario,
    v: &VelocityKeys,
    theta: f64,
) -> SimResult<SolverChoice> {
    let err = |m: String| scenario.error(m);
    let only = |ok: &[&str]| -> SimResult<()> {
        let given = [
            ("theta", v.theta.is_some()),
            ("leaf_size", v.leaf_size.is_some()),
            ("group_size", v.group_size.is_some()),
            ("grid", v.grid.is_some()),
            ("boundary", v.boundary.is_some()),
            ("box", v.side.is_some()),
            ("tolerance", v.tolerance.is_some()),
            ("order", v.order.is_some()),
        ];
        match given.iter().find(|(n, g)| *g && !ok.contains(n)) {
            Some((name, _)) => Err(err(format!(
                "system.velocity: the {} solver does not take {name}",
                v.kind
            ))),
            None => Ok(()),
        }
    };
    /// The velocity solvers.
    #[derive(Clone, Copy)]
    enum Kind {
        Direct,
        BarnesHut,
        Mesh,
        Fmm,
    }
    let kinds = [
        ("direct", Kind::Direct),
        ("barnes-hut", Kind::BarnesHut),
        ("mesh", Kind::Mesh),
        ("fmm", Kind::Fmm),
    ];
    match choice("system.velocity.kind", &v.kind, &kinds).map_err(err)? {
        Kind::Direct => {
            only(&[])?;
            Ok(SolverChoice::Direct)
        }
        Kind::BarnesHut => {
            only(&["theta", "leaf_size", "group_size"])?;
            let d = TreeParams::default();
            let params = TreeParams {
                theta: v.theta.unwrap_or(theta),
                quadrupole: true,
                leaf_size: v.leaf_size.unwrap_or(d.leaf_size),
                group_size: v.group_size.unwrap_or(d.group_size),
            };
            params
                .check()
                .map_err(|m| err(format!("system.velocity: {m}")))?;
            Ok(SolverChoice::BarnesHut(params))
        }
        Kind::Mesh => {
            only(&["grid", "boundary", "box"])?;
            let periodic = match (v.boundary.as_deref().unwrap_or("unbounded"), v.side) {
                ("unbounded", None) => None,
                ("unbounded", Some(_)) => {
                    return Err(err(
                        "system.velocity: box is for boundary = \"periodic\"".into(),
                    ))
                }
                ("periodic", Some(side)) if side.is_finite() && side > 0.0 => Some(side),
                ("periodic", Some(side)) => {
                    return Err(err(format!(
                        "system.velocity.box must be > 0, got {side}"
                    )))
                }
                ("periodic", None) => {
                    return Err(err(
                        "system.velocity.box is missing: a periodic mesh needs the side of its box (centred on system.initial.center)".into(),
                    ))
                }
                (other, _) => {
                    return Err(err(format!(
                        "system.velocity.boundary '{other}' is unknown; expected \"unbounded\" or \"periodic\""
                    )))
                }
            };
            Ok(SolverChoice::Mesh {
                grid: v.grid,
                periodic,
            })
        }
        Kind::Fmm => {
            only(&["tolerance", "order"])?;
            let accuracy = fmm_accuracy("system.velocity", v.tolerance, v.order).map_err(err)?;
            Ok(SolverChoice::Fmm(accuracy))
        }
    }
}

/// Checks the blob keys of both dimensions: `nu >= 0`, `sigma_over_h > 0`
/// (warning below 1) and the kernel.
pub(super) fn check_blob_keys(
    scenario: &Scenario,
    context: &RunContext,
    nu: f64,
    sigma_over_h: f64,
    kernel: &str,
) -> SimResult<()> {
    let err = |m: String| scenario.error(m);
    if !(nu.is_finite() && nu >= 0.0) {
        return Err(err(format!("system.nu must be >= 0, got {nu}")));
    }
    if !(sigma_over_h.is_finite() && sigma_over_h > 0.0) {
        return Err(err(format!(
            "system.sigma_over_h must be > 0, got {sigma_over_h}"
        )));
    }
    if kernel != "gaussian" {
        return Err(err(format!(
            "system.kernel '{kernel}' is unknown; expected \"gaussian\" (Gaussian blobs of core sigma and the Gaussian PSE kernel)"
        )));
    }
    if sigma_over_h < 1.0 {
        context.warn(format!(
            "system.sigma_over_h = {sigma_over_h} < 1: the blobs hardly overlap, so the velocity and the PSE diffusion lose accuracy (1.5 to 2 is usual)"
        ));
    }
    Ok(())
}

/// Refuses (or, with `run.allow_unstable`, warns of) a step above the
/// diffusion's stability limit `R sigma^2 / (4 D nu)`: PSE's operator has
/// eigenvalues in `[-2 S, 0]` with row sums `S` about `2 D nu / eps^2` (the
/// kernel's second moment), `eps = sigma`, `R` the integrator's real bound.
pub(super) fn check_diffusion_step(
    scenario: &Scenario,
    context: &RunContext,
    run: &RunKeys,
    integrator: Integrator,
    nu: f64,
    sigma: f64,
    dimension: u32,
) -> SimResult<()> {
    let bound = 4 * dimension;
    let limit = integrator.real_stability_bound() * sigma * sigma / (f64::from(bound) * nu);
    if nu > 0.0 && run.dt > limit {
        let message = format!(
            "run.dt = {} exceeds the diffusion stability limit {limit:.4e} of {} (dt <= R sigma^2 / ({bound} nu) with sigma = {sigma})",
            run.dt, run.integrator
        );
        if !run.allow_unstable {
            return Err(scenario.error(format!(
                "{message}; use a smaller dt, or set run.allow_unstable = true to run anyway"
            )));
        }
        context.warn(format!(
            "{message}; running anyway (run.allow_unstable = true)"
        ));
    }
    Ok(())
}
