//! `cellist bench gravity`: one force evaluation of a Plummer sphere, a
//! uniform cube or the bodies of a file by a solver, timed, with its error
//! against the direct sum.

use super::at_least_once;
use super::vortex::spread_targets;
use crate::error::{SimError, SimResult};
use crate::models::fmm_name;
use crate::models::gravity::MAX_BODIES;
use crate::study::median;
use cellist::interactions::GravityLaw;
use cellist::longrange::{
    DirectSum, ErrorFit, FieldOut, FmmAccuracy, MeshBoundary, MeshParams, PartialField, Sources,
    TreeParams,
};
use cellist::models::gravity::{plummer, Solver, SolverChoice};
use cellist::random::Rng;
use cellist::Threads;
use cellist_io::read_field_of;
use std::path::PathBuf;
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
    /// The fast multipole method at this accuracy.
    Fmm {
        /// The tolerance or the order.
        accuracy: FmmAccuracy,
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
            GravitySolver::Fmm { .. } => "fmm",
        }
    }

    /// The name with the settings that are not flags of their own: the
    /// fmm's order and tolerance.
    pub fn description(&self) -> String {
        match *self {
            GravitySolver::Fmm { accuracy } => fmm_name(accuracy, ErrorFit::LAPLACE_3D),
            _ => self.name().to_string(),
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
            GravitySolver::Fmm { accuracy } => {
                accuracy
                    .check()
                    .map_err(|e| SimError::Input(format!("--{e}")))?;
                SolverChoice::Fmm(accuracy)
            }
        })
    }
}

/// The bodies of the gravity benchmark.
#[derive(Clone, Debug, PartialEq)]
pub enum GravityBodies {
    /// A Plummer sphere of `n` equal masses (scale radius 1, total mass 1).
    Plummer {
        /// Bodies.
        n: usize,
    },
    /// `n` bodies uniformly in the unit cube, masses uniform in `[0, 2/n)`.
    Uniform {
        /// Bodies.
        n: usize,
    },
    /// The lines `x y z m` of a file.
    File(PathBuf),
}

/// The bodies and the solver to time.
#[derive(Clone, Debug)]
pub struct GravityRequest {
    /// The solver.
    pub solver: GravitySolver,
    /// The bodies.
    pub bodies: GravityBodies,
    /// Plummer softening length.
    pub softening: f64,
    /// Seed of the Plummer sphere.
    pub seed: u64,
    /// Timed force evaluations.
    pub repeat: usize,
    /// The bodies the error is measured at (evenly spread); all when None.
    pub sample: Option<usize>,
}

/// What the gravity benchmark measured.
#[derive(Clone, Debug)]
pub struct GravityBench {
    /// The solver with its settings.
    pub solver: String,
    /// Bodies.
    pub n: usize,
    /// Bodies the error was measured at.
    pub targets: usize,
    /// Median seconds per force evaluation.
    pub seconds: f64,
    /// Pairs `N (N - 1) / 2`.
    pub pairs: f64,
    /// `sqrt(mean_i (|a_i - e_i| / |e_i|)^2)` against the direct sum
    /// (approximate solvers).
    pub rms_relative_error: Option<f64>,
    /// `sqrt(sum_i |a_i - e_i|^2 / sum_i |e_i|^2)` (FMM3D's measure).
    pub rms_field_error: Option<f64>,
    /// `max_i |a_i - e_i| / |e_i|`.
    pub max_relative_error: Option<f64>,
    /// Node and body interactions of the tree walk (Barnes-Hut; M2L, M2P and
    /// P2L, and body pairs of the fmm).
    pub interactions: Option<(u64, u64)>,
}

/// Times `repeat` force evaluations (after an untimed one that builds the
/// tables and buffers) and measures the error against the direct sum.
pub fn gravity(request: &GravityRequest, threads: &Threads) -> SimResult<GravityBench> {
    at_least_once(request.repeat)?;
    if request.sample == Some(0) {
        return Err(SimError::Input("--sample must be at least 1".into()));
    }
    let law = GravityLaw::new(1.0, request.softening, 0.0).map_err(SimError::Input)?;
    let (position, mass) = bodies(&request.bodies, request.seed, &law, threads)?;
    let n = mass.len();
    let choice = request.solver.choice()?;
    let mut solver = Solver::new(&choice, law, n).map_err(SimError::Input)?;
    let sources = Sources {
        mass: &mass,
        position: &position,
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
    let targets = spread_targets(n, request.sample.unwrap_or(n));
    let errors = match choice {
        SolverChoice::Direct => None,
        _ => {
            let exact = exact_at(&targets, law, &sources, threads);
            let got: Vec<[f64; 3]> = targets.iter().map(|&i| acc[i]).collect();
            Some(errors(&got, &exact))
        }
    };
    Ok(GravityBench {
        solver: request.solver.description(),
        n,
        targets: targets.len(),
        seconds: median(&samples[1..]),
        pairs: (n as f64) * (n as f64 - 1.0) / 2.0,
        rms_relative_error: errors.map(|e| e[0]),
        rms_field_error: errors.map(|e| e[1]),
        max_relative_error: errors.map(|e| e[2]),
        interactions: match &solver {
            Solver::BarnesHut(t) => Some(t.interactions()),
            Solver::Fmm(f) => Some(f.interactions()),
            _ => None,
        },
    })
}

/// The bodies' positions and masses (checked: `2..=MAX_BODIES` generated
/// ones, at least 2 from a file, masses finite and `>= 0`).
fn bodies(
    bodies: &GravityBodies,
    seed: u64,
    law: &GravityLaw,
    threads: &Threads,
) -> SimResult<(Vec<[f64; 3]>, Vec<f64>)> {
    let count = |n: usize| {
        if (2..=MAX_BODIES).contains(&n) {
            Ok(n)
        } else {
            Err(SimError::Input(format!(
                "--n must be in 2..={MAX_BODIES}, got {n}"
            )))
        }
    };
    Ok(match bodies {
        GravityBodies::Plummer { n } => {
            let b = plummer(count(*n)?, seed, law, threads);
            (b.position, b.mass)
        }
        GravityBodies::Uniform { n } => {
            let n = count(*n)?;
            let mut rng = Rng::new(seed);
            let position = (0..n)
                .map(|_| [rng.uniform(), rng.uniform(), rng.uniform()])
                .collect();
            let mass = (0..n).map(|_| 2.0 * rng.uniform() / n as f64).collect();
            (position, mass)
        }
        GravityBodies::File(path) => {
            let (position, mass) = read_field_of::<3>(path, "m")?;
            if let Some(i) = mass.iter().position(|m| !(m.is_finite() && *m >= 0.0)) {
                return Err(SimError::Input(format!(
                    "{}: body {} has mass {}; masses must be finite and >= 0",
                    path.display(),
                    i + 1,
                    mass[i]
                )));
            }
            if mass.len() < 2 {
                return Err(SimError::Input(format!(
                    "{}: {} bodies; the benchmark needs at least 2",
                    path.display(),
                    mass.len()
                )));
            }
            (position, mass)
        }
    })
}

/// The direct sum's accelerations at the bodies `targets` (each leaving
/// itself out).
fn exact_at(
    targets: &[usize],
    law: GravityLaw,
    sources: &Sources,
    threads: &Threads,
) -> Vec<[f64; 3]> {
    let n = sources.mass.len();
    let mut acc = vec![[0.0; 3]; targets.len()];
    let mut phi = vec![0.0; targets.len()];
    let out = FieldOut {
        acc: &mut acc,
        phi: &mut phi,
    };
    if targets.len() == n {
        DirectSum::new(law, n).compute(sources, out, threads);
    } else {
        let mut partial = PartialField::new(law, targets.len());
        partial.add_at_bodies(targets, sources, threads);
        partial.finish(out);
    }
    acc
}

/// `[sqrt(mean_i (|a_i - e_i| / |e_i|)^2), sqrt(sum |a_i - e_i|^2 / sum |e_i|^2),
/// max_i |a_i - e_i| / |e_i|]` (the largest over bodies with a field).
fn errors(got: &[[f64; 3]], exact: &[[f64; 3]]) -> [f64; 3] {
    let norm = |v: [f64; 3]| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    let (mut err2, mut exact2, mut largest) = (0.0, 0.0, 0.0f64);
    for (g, e) in got.iter().zip(exact) {
        let d = norm([g[0] - e[0], g[1] - e[1], g[2] - e[2]]);
        err2 += d * d;
        exact2 += norm(*e) * norm(*e);
        if norm(*e) > 0.0 {
            largest = largest.max(d / norm(*e));
        }
    }
    [
        rms_relative_error(got, exact),
        (err2 / exact2).sqrt(),
        largest,
    ]
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
