//! `cellist bench gravity`: one force evaluation of a Plummer sphere by a
//! solver, timed, with its error against the direct sum.

use super::at_least_once;
use crate::error::{SimError, SimResult};
use crate::models::gravity::MAX_BODIES;
use crate::study::median;
use cellist::interactions::GravityLaw;
use cellist::longrange::{DirectSum, FieldOut, MeshBoundary, MeshParams, Sources, TreeParams};
use cellist::models::gravity::{plummer, Solver, SolverChoice};
use cellist::Threads;
use std::time::Instant;

/// The force solver of the gravity benchmark and its settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum GravitySolver {
    /// All pairs, exact.
    Direct,
    /// The Barnes-Hut octree.
    BarnesHut {
        /// Opening angle.
        theta: f64,
        /// Quadrupole moments (else monopoles only).
        quadrupole: bool,
        /// Most bodies per leaf.
        leaf_size: usize,
        /// Most bodies per walk group.
        group_size: usize,
    },
    /// Particle-mesh, isolated (zero-padded FFT).
    Pm {
        /// Mesh nodes per axis.
        grid: usize,
    },
    /// Particle-mesh plus the short-range pairs on a cell list.
    P3m {
        /// Mesh nodes per axis.
        grid: usize,
        /// Splitting radius in mesh cells.
        split: f64,
    },
}

impl GravitySolver {
    /// The name on the command line.
    pub fn name(&self) -> &'static str {
        match self {
            GravitySolver::Direct => "direct",
            GravitySolver::BarnesHut { .. } => "barnes-hut",
            GravitySolver::Pm { .. } => "pm",
            GravitySolver::P3m { .. } => "p3m",
        }
    }

    /// The engine's solver.
    fn choice(&self) -> SimResult<SolverChoice> {
        let isolated = |grid| MeshParams {
            grid,
            boundary: MeshBoundary::Isolated,
        };
        Ok(match *self {
            GravitySolver::Direct => SolverChoice::Direct,
            GravitySolver::BarnesHut {
                theta,
                quadrupole,
                leaf_size,
                group_size,
            } => {
                let params = TreeParams {
                    theta,
                    quadrupole,
                    leaf_size,
                    group_size,
                };
                params.check().map_err(SimError::Input)?;
                SolverChoice::BarnesHut(params)
            }
            GravitySolver::Pm { grid } => SolverChoice::Pm(isolated(grid)),
            GravitySolver::P3m { grid, split } => SolverChoice::P3m {
                mesh: isolated(grid),
                split_cells: split,
            },
        })
    }
}

/// The Plummer sphere and the solver to time.
#[derive(Clone, Copy, Debug)]
pub struct GravityRequest {
    /// The solver.
    pub solver: GravitySolver,
    /// Bodies.
    pub n: usize,
    /// Plummer softening length.
    pub softening: f64,
    /// Seed of the Plummer sphere.
    pub seed: u64,
    /// Timed force evaluations.
    pub repeat: usize,
}

/// What the gravity benchmark measured.
#[derive(Clone, Copy, Debug)]
pub struct GravityBench {
    /// Median seconds per force evaluation.
    pub seconds: f64,
    /// Pairs `N (N - 1) / 2`.
    pub pairs: f64,
    /// `sqrt(mean_i (|a_i - e_i| / |e_i|)^2)` against the direct sum
    /// (approximate solvers).
    pub rms_relative_error: Option<f64>,
    /// Node and body interactions of the tree walk (Barnes-Hut).
    pub interactions: Option<(u64, u64)>,
}

/// Times `repeat` force evaluations (after an untimed one that builds the
/// tables and buffers) and measures the error against the direct sum.
pub fn gravity(request: &GravityRequest, threads: &Threads) -> SimResult<GravityBench> {
    let n = request.n;
    if !(2..=MAX_BODIES).contains(&n) {
        return Err(SimError::Input(format!(
            "--n must be in 2..={MAX_BODIES}, got {n}"
        )));
    }
    at_least_once(request.repeat)?;
    let law = GravityLaw::new(1.0, request.softening, 0.0).map_err(SimError::Input)?;
    let bodies = plummer(n, request.seed, &law, threads);
    let choice = request.solver.choice()?;
    let mut solver = Solver::new(&choice, law, n).map_err(SimError::Input)?;
    let sources = Sources {
        mass: &bodies.mass,
        position: &bodies.position,
    };
    let mut acc = vec![[0.0; 3]; n];
    let mut phi = vec![0.0; n];
    let mut samples = Vec::with_capacity(request.repeat + 1);
    // one untimed evaluation first: it builds the tables and buffers
    for _ in 0..=request.repeat {
        let start = Instant::now();
        solver.compute(
            &sources,
            FieldOut {
                acc: &mut acc,
                phi: &mut phi,
            },
            threads,
        );
        samples.push(start.elapsed().as_secs_f64());
    }
    let rms_relative_error = match choice {
        SolverChoice::Direct => None,
        _ => {
            let mut exact = vec![[0.0; 3]; n];
            let mut exact_phi = vec![0.0; n];
            DirectSum::new(law, n).compute(
                &sources,
                FieldOut {
                    acc: &mut exact,
                    phi: &mut exact_phi,
                },
                threads,
            );
            Some(rms_relative_error(&acc, &exact))
        }
    };
    Ok(GravityBench {
        seconds: median(&samples[1..]),
        pairs: (n as f64) * (n as f64 - 1.0) / 2.0,
        rms_relative_error,
        interactions: match &solver {
            Solver::BarnesHut(t) => Some(t.interactions()),
            _ => None,
        },
    })
}

/// `sqrt(mean_i (|a_i - e_i| / |e_i|)^2)`.
fn rms_relative_error(got: &[[f64; 3]], exact: &[[f64; 3]]) -> f64 {
    let norm = |v: [f64; 3]| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    let sum: f64 = got
        .iter()
        .zip(exact)
        .map(|(g, e)| (norm([g[0] - e[0], g[1] - e[1], g[2] - e[2]]) / norm(*e)).powi(2))
        .sum();
    (sum / got.len() as f64).sqrt()
}
