//! `cellist bench lj`: the loop time of LAMMPS's `bench/in.lj` melt.

use super::{at_least_once, peak_resident_bytes};
use crate::error::{SimError, SimResult};
use crate::study::median;
use cellist::interactions::LennardJones;
use cellist::models::md::{
    create_velocities, lattice, Atoms, Integrator, LatticeKind, MdSystem, StageTimes,
    VelocityDistribution,
};
use cellist::neighbors::RebuildRule;
use cellist::Threads;
use std::time::Instant;

/// The melt to time: `atoms_per_side^3` fcc cells at density 0.8442, T = 3,
/// `steps` velocity-Verlet steps of 0.005, cutoff 2.5, skin 0.3.
#[derive(Clone, Copy, Debug)]
pub struct LjRequest {
    /// fcc unit cells per box side (4 atoms each).
    pub atoms_per_side: usize,
    /// Timed steps.
    pub steps: u64,
    /// Timed repetitions (each from the same start).
    pub repeat: usize,
    /// When the neighbour list is rebuilt (LAMMPS's `neigh_modify every N
    /// check yes|no`).
    pub rule: RebuildRule,
}

/// What the melt measured (the last repetition's counts and stage times).
#[derive(Clone, Debug)]
pub struct LjBench {
    /// Atoms.
    pub atoms: usize,
    /// Median loop time, set-up excluded, as LAMMPS reports it (s).
    pub seconds: f64,
    /// `seconds / (atoms steps)` in microseconds.
    pub us_per_atom_step: f64,
    /// Neighbour-list rebuilds.
    pub rebuilds: u64,
    /// Rebuilds that came after some atom had moved more than skin/2.
    pub late_builds: u64,
    /// Time in the force pass (s).
    pub force_seconds: f64,
    /// Time in the neighbour list (s).
    pub neighbor_seconds: f64,
    /// The process's peak resident memory, where the system tells it.
    pub peak_rss_bytes: Option<u64>,
}

/// Times the melt: the median over `repeat` runs of `steps` steps, each from
/// the same start (made anew, so that the peak memory is the run's own).
pub fn lj(request: &LjRequest, threads: &Threads) -> SimResult<LjBench> {
    if request.atoms_per_side > 1000 {
        return Err(SimError::Input(
            "--atoms-per-side must be at most 1000".into(),
        ));
    }
    if request.atoms_per_side < 4 {
        return Err(SimError::Input(
            "--atoms-per-side must be at least 4 (the box must hold twice cutoff + skin)".into(),
        ));
    }
    at_least_once(request.repeat)?;
    let n = request.atoms_per_side;
    let melt_start = || {
        let (domain, points) = lattice(LatticeKind::Fcc, 0.8442, [n; 3])
            .map_err(|e| SimError::Internal(format!("melt lattice: {e}")))?;
        let mut atoms = Atoms::at_rest(points, 1.0);
        create_velocities(&mut atoms, 3.0, 87287, VelocityDistribution::Uniform);
        Ok::<_, SimError>((domain, atoms))
    };
    let lj = LennardJones::new(1.0, 1.0, 2.5, false)
        .map_err(|e| SimError::Internal(format!("melt potential: {e}")))?;
    let mut samples = Vec::with_capacity(request.repeat);
    let mut last = None;
    let mut atoms_n = 0;
    for _ in 0..request.repeat {
        let (domain, atoms) = melt_start()?;
        atoms_n = atoms.len();
        let mut system = MdSystem::new(domain, atoms, lj, 0.3, threads)
            .map_err(|e| SimError::Internal(format!("melt set-up: {e}")))?;
        system.set_rebuild_rule(request.rule);
        let mut times = StageTimes::default();
        let start = Instant::now();
        for step in 1..=request.steps {
            system
                .step(
                    &Integrator::VelocityVerlet,
                    0.005,
                    step,
                    step == request.steps,
                    threads,
                    &mut times,
                )
                .map_err(|e| SimError::Internal(format!("the melt blew up: {e}")))?;
        }
        samples.push(start.elapsed().as_secs_f64());
        last = Some((system.list_counts(), times));
    }
    let (counts, times) = last.expect("at least one repetition");
    let seconds = median(&samples);
    Ok(LjBench {
        atoms: atoms_n,
        seconds,
        us_per_atom_step: seconds * 1e6 / (atoms_n as f64 * request.steps.max(1) as f64),
        rebuilds: counts.rebuilds,
        late_builds: counts.late_builds,
        force_seconds: times.force.as_secs_f64(),
        neighbor_seconds: times.neighbor.as_secs_f64(),
        peak_rss_bytes: peak_resident_bytes(),
    })
}
