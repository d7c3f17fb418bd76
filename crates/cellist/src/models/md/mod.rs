//! Molecular dynamics: atoms with a pair potential, summed once per pair (Newton's
//! third law) over a half cluster pair list (`4 x 4` atoms at a time,
//! [`ClusterList`](crate::neighbors::ClusterList)), in parallel without atomics by cell layers that write the
//! next layer through a halo ([`LayerPlan`](crate::neighbors::LayerPlan)), and advanced by an [`Integrator`].
//!
//! One step (LAMMPS's order, so that trajectories compare with LAMMPS's):
//! ```text
//! first_half (kick + drift)  ->  blow-up check  ->  rebuild the cluster list if some
//! atom moved more than skin/2 (wrap, counting sort, columns inside the cells,
//! permute the atoms)  ->  forces  ->  second_half (kick)
//! ```

mod atoms;
mod cluster_forces;
mod cluster_pairs;
mod frame;
mod halo;
mod integrate;
mod lattice;
mod model;
mod subdomain;
mod velocity;

pub use atoms::Atoms;
use atoms::PermuteScratch;
pub use frame::dump_particles;
pub use halo::{HaloForces, HaloSums};
pub use integrate::{Integrator, Langevin};
pub use lattice::{lattice, Lattice, LatticeKind};
pub use model::{
    blowup_of, checked_atoms, late_note, load_atoms, load_atoms_where, save_atoms, MdModel,
    SavedAtoms, INFO, REMEDY,
};
pub use subdomain::{ordered_forces, AtomForce};

pub use velocity::{create_velocities, VelocityDistribution, VelocityScaling};

use crate::geometry::{norm2, Domain, GeometryError};
use crate::interactions::{LennardJones, PairPotential};
use crate::neighbors::{Rebuild, RebuildRule};
use crate::threads::Threads;
use cluster_pairs::ClusterPairs;
use rayon::prelude::*;
use std::fmt;
use std::time::{Duration, Instant};

/// Why a system could not be set up, or why a run stopped.
#[derive(Clone, Debug, PartialEq)]
pub enum MdError {
    /// The box is too small for the cutoff (with its skin).
    Geometry(GeometryError),
    /// No atoms.
    Empty,
    /// Two atoms at the same position: the force between them is infinite.
    Overlap {
        /// Id of one atom.
        first: u64,
        /// Id of the other.
        second: u64,
    },
    /// A position became NaN or infinite.
    NotFinite {
        /// The step at which it was seen.
        step: u64,
        /// The atom.
        id: u64,
    },
    /// An atom left the box through a non-periodic face.
    LeftBox {
        /// The step at which it was seen.
        step: u64,
        /// The atom.
        id: u64,
        /// The axis (0 = x).
        axis: usize,
        /// Its coordinate along that axis.
        coordinate: f64,
    },
}

impl fmt::Display for MdError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        const AXES: [&str; 3] = ["x", "y", "z"];
        match self {
            MdError::Geometry(e) => write!(f, "{e}"),
            MdError::Empty => write!(f, "the system has no atoms"),
            MdError::Overlap { first, second } => write!(
                f,
                "atoms {first} and {second} are at the same position (infinite force)"
            ),
            MdError::NotFinite { step, id } => {
                write!(f, "step {step}: atom {id} has a non-finite position (the run blew up; try a smaller dt)")
            }
            MdError::LeftBox {
                step,
                id,
                axis,
                coordinate,
            } => write!(
                f,
                "step {step}: atom {id} left the box through the non-periodic {} boundary ({} = {coordinate})",
                AXES[*axis], AXES[*axis]
            ),
        }
    }
}

impl std::error::Error for MdError {}

impl From<GeometryError> for MdError {
    fn from(e: GeometryError) -> Self {
        MdError::Geometry(e)
    }
}

/// Sums of one force evaluation: pair energy `U = sum_pairs U(r_ij)` and virial
/// `W = sum_pairs r_ij . f_ij`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PairTally {
    /// Potential energy.
    pub energy: f64,
    /// Virial.
    pub virial: f64,
}

/// Thermodynamic output, normalised as LAMMPS does in lj units (`thermo_modify norm
/// yes`): energies per atom, temperature and pressure as they are.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Thermo {
    /// `T = sum m v^2 / (D N - D)`.
    pub temp: f64,
    /// Potential energy per atom.
    pub pe: f64,
    /// Kinetic energy per atom, `T (D N - D) / (2 N)`.
    pub ke: f64,
    /// `pe + ke`.
    pub etotal: f64,
    /// `P = ((D N - D) T + W) / (D V)`.
    pub press: f64,
}

/// Wall time per stage of a run (LAMMPS's breakdown).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct StageTimes {
    /// Blow-up checks, neighbour-list checks and rebuilds.
    pub neighbor: Duration,
    /// Pair forces.
    pub force: Duration,
    /// Integrator updates.
    pub integrate: Duration,
    /// Thermo, dumps, pictures (measured by the caller).
    pub output: Duration,
}

impl StageTimes {
    /// The driver's stages: `Neighbor`, `Force`, `Integrate`.
    pub fn stages(&self) -> Vec<(&'static str, Duration)> {
        vec![
            ("Neighbor", self.neighbor),
            ("Force", self.force),
            ("Integrate", self.integrate),
        ]
    }
}

/// `sum m v^2 / (D N - D)`, zero without degrees of freedom.
pub fn temperature<const D: usize>(atoms: &Atoms<D>) -> f64 {
    let dof = degrees_of_freedom::<D>(atoms.len());
    if dof > 0.0 {
        twice_kinetic(atoms) / dof
    } else {
        0.0
    }
}

fn degrees_of_freedom<const D: usize>(n: usize) -> f64 {
    (D * n).saturating_sub(D) as f64
}

/// Twice the kinetic energy of `atoms`, `2K = sum_i m_i |v_i|^2`, summed in
/// the atoms' order.
pub fn twice_kinetic<const D: usize>(atoms: &Atoms<D>) -> f64 {
    atoms
        .velocities
        .iter()
        .zip(&atoms.masses)
        .map(|(v, m)| norm2(v) * m)
        .sum()
}

/// The neighbour list's counters that a checkpoint keeps, so that a restart
/// rebuilds on the same steps as the run it continues.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ListCounts {
    /// Rebuilds since set-up.
    pub rebuilds: u64,
    /// Steps since the last build.
    pub since_build: u64,
    /// Late rebuilds since set-up ([`MdSystem::late_builds`]).
    pub late_builds: u64,
}

impl ListCounts {
    /// Counts one more step since the last build; returns the steps since it.
    pub fn step(&mut self) -> u64 {
        self.since_build += 1;
        self.since_build
    }

    /// Counts a build, `late` as [`RebuildRule::decide`] said.
    pub fn built(&mut self, late: bool) {
        self.rebuilds += 1;
        self.late_builds += u64::from(late);
        self.since_build = 0;
    }
}

/// A molecular-dynamics system: box, atoms, pair potential and its neighbour list.
pub struct MdSystem<const D: usize> {
    domain: Domain<D>,
    atoms: Atoms<D>,
    potential: LennardJones,
    skin: f64,
    pairs: ClusterPairs<D>,
    totals: Option<PairTally>,
    scratch: PermuteScratch<D>,
    rule: RebuildRule,
    counts: ListCounts,
}

impl<const D: usize> MdSystem<D> {
    /// Sets up the system: checks the box against `cutoff + skin` and the atoms
    /// (finite, inside non-periodic boxes, no two at one position), builds the
    /// neighbour list and evaluates the forces, energy and virial.
    pub fn new(
        domain: Domain<D>,
        atoms: Atoms<D>,
        potential: LennardJones,
        skin: f64,
        threads: &Threads,
    ) -> Result<Self, MdError> {
        atoms.assert_consistent();
        if atoms.is_empty() {
            return Err(MdError::Empty);
        }
        assert!(skin >= 0.0, "skin must be >= 0");
        let reach = potential.cutoff() + skin;
        domain.check_cutoff(reach)?;
        check_positions(&domain, &atoms, 0, threads)?;
        let n = atoms.len();
        let pairs = ClusterPairs::new(
            &domain,
            &atoms.positions,
            n,
            potential.cutoff(),
            skin,
            threads,
        )?;
        let mut system = MdSystem {
            domain,
            pairs,
            atoms,
            potential,
            skin,
            totals: None,
            scratch: PermuteScratch::default(),
            rule: RebuildRule::default(),
            counts: ListCounts::default(),
        };
        system.adopt_cell_order();
        system.check_overlaps()?;
        system.compute_forces(true, threads);
        Ok(system)
    }

    /// The box.
    pub fn domain(&self) -> &Domain<D> {
        &self.domain
    }

    /// The atoms, in the cell order of the last rebuild.
    pub fn atoms(&self) -> &Atoms<D> {
        &self.atoms
    }

    /// The pair potential.
    pub fn potential(&self) -> &LennardJones {
        &self.potential
    }

    /// The neighbour-list skin.
    pub fn skin(&self) -> f64 {
        self.skin
    }

    /// Neighbour-list rebuilds since set-up.
    pub fn rebuilds(&self) -> u64 {
        self.counts.rebuilds
    }

    /// When the neighbour list is rebuilt (every step on the skin test unless set).
    pub fn rebuild_rule(&self) -> RebuildRule {
        self.rule
    }

    /// Sets when the neighbour list is rebuilt, from the next step on.
    pub fn set_rebuild_rule(&mut self, rule: RebuildRule) {
        assert!(
            rule.every >= 1,
            "the list must be looked at every N >= 1 steps"
        );
        self.rule = rule;
    }

    /// The list's counters, for a checkpoint.
    pub fn list_counts(&self) -> ListCounts {
        self.counts
    }

    /// Rebuilds since set-up at which some atom had moved more than skin/2
    /// while the list was not looked at on every step: pairs may have been
    /// missed before them (LAMMPS's dangerous builds; always 0 with every 1).
    pub fn late_builds(&self) -> u64 {
        self.counts.late_builds
    }

    /// Cluster pairs in the current half list (each up to `4 x 4` atom pairs).
    pub fn list_entries(&self) -> usize {
        self.pairs.list.num_entries()
    }

    /// Advances by one step of `dt` (numbered `step`); sums energy and virial when
    /// `energy`. Stage times are added to `times`. The whole step runs on the
    /// pool of `threads`: its parallel passes then start from a pool thread,
    /// with no hand-over from the calling thread and back for each of them.
    pub fn step(
        &mut self,
        integrator: &Integrator,
        dt: f64,
        step: u64,
        energy: bool,
        threads: &Threads,
        times: &mut StageTimes,
    ) -> Result<(), MdError> {
        threads.install(|| {
            let t = Instant::now();
            integrator.first_half(&mut self.atoms, dt, threads);
            let t = lap(t, &mut times.integrate);
            check_positions(&self.domain, &self.atoms, step, threads)?;
            let since = self.counts.step();
            let (list, cells, positions) =
                (&self.pairs.list, &self.pairs.cells, &self.atoms.positions);
            if let Rebuild::Yes { late } = self
                .rule
                .decide(since, || list.needs_rebuild(cells, positions))
            {
                self.rebuild(threads);
                self.counts.built(late);
            }
            let t = lap(t, &mut times.neighbor);
            self.compute_forces(energy, threads);
            let t = lap(t, &mut times.force);
            integrator.second_half(&mut self.atoms, dt, step, threads);
            lap(t, &mut times.integrate);
            Ok(())
        })
    }

    /// Wraps the positions, sorts the atoms by cell (in columns inside a cell)
    /// and rebuilds the cluster list.
    fn rebuild(&mut self, threads: &Threads) {
        self.pairs.rebin(&self.atoms.positions, threads);
        self.adopt_cell_order();
        self.pairs.build_list(self.atoms.len(), threads);
    }

    /// The positions the neighbour list was built at (slot order, wrapped).
    pub fn list_reference(&self) -> &[[f64; D]] {
        self.pairs.cells.positions()
    }

    /// Replaces the atoms by a saved set whose neighbour list was built at
    /// `reference` (each atom's wrapped position at the last rebuild, what
    /// [`MdSystem::list_reference`] returned, in the saved atoms' order). The
    /// atoms are put in the cell order of `reference` and the list is built
    /// from it: the saved run's list, entry for entry, when the atoms come in
    /// the slot order [`MdSystem::atoms`] had (the counting sort and the columns
    /// then leave them in place), and the same pairs within the cutoff when
    /// they come from a distributed run (sorted by id: ties inside a column may
    /// then fall in another order, and the clusters differ). Forces are kept as
    /// given (those of the
    /// saved step); `counts` are the saved run's list counters.
    pub fn restore(
        &mut self,
        mut atoms: Atoms<D>,
        reference: &[[f64; D]],
        counts: ListCounts,
        threads: &Threads,
    ) -> Result<(), String> {
        let n = atoms.len();
        if n != self.atoms.len() || reference.len() != n || !atoms.is_consistent() {
            return Err(format!(
                "the saved state has {n} atoms and {} reference positions; the scenario has {}",
                reference.len(),
                self.atoms.len()
            ));
        }
        if reference.iter().flatten().any(|c| !c.is_finite()) {
            return Err("a saved reference position is not finite".into());
        }
        self.pairs.rebin(reference, threads);
        let order = self.pairs.cells.order();
        let wrapped = order
            .iter()
            .zip(self.pairs.cells.positions())
            .all(|(&k, x)| reference[k as usize] == *x);
        if !wrapped {
            return Err("the saved reference positions are not wrapped into the box".into());
        }
        if order.iter().enumerate().any(|(k, &o)| o as usize != k) {
            atoms.permute_except_positions(order, &mut self.scratch);
            self.pairs
                .cells
                .permute(&atoms.positions, &mut self.scratch.vectors);
            std::mem::swap(&mut atoms.positions, &mut self.scratch.vectors);
        }
        self.atoms = atoms;
        self.pairs.build_list(n, threads);
        self.counts = counts;
        // the energy and virial of the restored state, for its thermo; the
        // saved forces are kept (they continue the run bit for bit)
        let saved = std::mem::take(&mut self.atoms.forces);
        self.atoms.forces = vec![[0.0; D]; saved.len()];
        self.compute_forces(true, threads);
        self.atoms.forces = saved;
        Ok(())
    }

    /// Puts the atoms in the cell list's slot order, positions wrapped.
    fn adopt_cell_order(&mut self) {
        self.atoms
            .permute_except_positions(self.pairs.cells.order(), &mut self.scratch);
        self.atoms.positions.clear();
        self.atoms
            .positions
            .extend_from_slice(self.pairs.cells.positions());
    }

    fn check_overlaps(&self) -> Result<(), MdError> {
        let mut twin = None;
        self.pairs
            .list
            .for_each_pair(&self.atoms.positions, |i, j, _, r2| {
                if r2 == 0.0 && twin.is_none() {
                    twin = Some((i, j));
                }
            });
        match twin {
            Some((i, j)) => {
                let (a, b) = (self.atoms.ids[i], self.atoms.ids[j]);
                Err(MdError::Overlap {
                    first: a.min(b),
                    second: a.max(b),
                })
            }
            None => Ok(()),
        }
    }

    /// Recomputes the forces (every one is set); with `energy`, also the energy
    /// and virial.
    pub fn compute_forces(&mut self, energy: bool, threads: &Threads) {
        let atoms = &mut self.atoms;
        self.totals = self.pairs.forces(
            &self.potential,
            &atoms.positions,
            energy,
            threads,
            &mut atoms.forces,
        );
    }

    /// Energy and virial of the last force evaluation, if it summed them.
    pub fn pair_totals(&self) -> Option<PairTally> {
        self.totals
    }

    /// Per-atom potential energy (slot order): half of every pair's energy to each
    /// atom, LAMMPS's `compute pe/atom`.
    pub fn per_atom_energy(&self) -> Vec<f64> {
        let mut pe = vec![0.0; self.atoms.len()];
        let cutoff2 = self.potential.cutoff2();
        self.pairs
            .list
            .for_each_pair(&self.atoms.positions, |i, j, _, r2| {
                if r2 < cutoff2 {
                    let half = 0.5 * self.potential.energy_and_force(r2).0;
                    pe[i] += half;
                    pe[j] += half;
                }
            });
        pe
    }

    /// Thermo of the current state; needs the last force evaluation to have summed
    /// the energy (`energy = true`).
    pub fn thermo(&self) -> Thermo {
        let totals = self
            .totals
            .expect("thermo needs a force evaluation with energy");
        Thermo::of(&self.atoms, totals, self.domain.volume())
    }
}

impl Thermo {
    /// The thermo of `atoms` whose pair sums are `totals`, in a box of
    /// `volume` ([`Thermo::from_sums`]).
    pub fn of<const D: usize>(atoms: &Atoms<D>, totals: PairTally, volume: f64) -> Thermo {
        Thermo::from_sums::<D>(atoms.len(), twice_kinetic(atoms), totals, volume)
    }

    /// The thermo of `n` atoms with `sum m v^2 = twice_kinetic` and pair sums
    /// `totals`, in a box of `volume`: `T = sum m v^2 / (D N - D)`,
    /// `pe = U / N`, `ke = T (D N - D) / (2 N)`, `P = ((D N - D) T + W) / (D V)`.
    pub fn from_sums<const D: usize>(
        n: usize,
        twice_kinetic: f64,
        totals: PairTally,
        volume: f64,
    ) -> Thermo {
        let dof = degrees_of_freedom::<D>(n);
        let temp = if dof > 0.0 { twice_kinetic / dof } else { 0.0 };
        let ke_total = temp * 0.5 * dof;
        let n = n as f64;
        let pe = totals.energy / n;
        let ke = ke_total / n;
        let press = (dof * temp + totals.virial) / D as f64 * (1.0 / volume);
        Thermo {
            temp,
            pe,
            ke,
            etotal: pe + ke,
            press,
        }
    }
}

/// The sums behind [`Thermo`] taken over atoms a block at a time, in a fixed
/// order (by id, for output): `sum m v^2`, `U = sum_i u_i` and `W = sum_i w_i`
/// of per-atom half energies and virials, each one running sum from the first
/// atom to the last, so that blocks give the bits of one pass over all atoms.
#[derive(Clone, Copy, Debug)]
pub struct ThermoSums {
    atoms: usize,
    twice_kinetic: f64,
    totals: PairTally,
}

impl Default for ThermoSums {
    /// No atoms yet: the sums start where [`Iterator::sum`] starts, at `-0.0`.
    fn default() -> Self {
        ThermoSums {
            atoms: 0,
            twice_kinetic: -0.0,
            totals: PairTally {
                energy: -0.0,
                virial: -0.0,
            },
        }
    }
}

impl ThermoSums {
    /// Adds the next block: `atoms` with their half energies and virials.
    pub fn add<const D: usize>(&mut self, atoms: &Atoms<D>, energies: &[f64], virials: &[f64]) {
        self.atoms += atoms.len();
        for (v, m) in atoms.velocities.iter().zip(&atoms.masses) {
            self.twice_kinetic += norm2(v) * m;
        }
        for (u, w) in energies.iter().zip(virials) {
            self.totals.energy += u;
            self.totals.virial += w;
        }
    }

    /// Adds the sums of a part of the system taken apart (another rank's
    /// atoms): `atoms` atoms whose `sum m v^2` is `twice_kinetic` and whose
    /// pairs' energy and virial are `pairs`.
    pub fn add_part(&mut self, atoms: usize, twice_kinetic: f64, pairs: PairTally) {
        self.atoms += atoms;
        self.twice_kinetic += twice_kinetic;
        self.totals.energy += pairs.energy;
        self.totals.virial += pairs.virial;
    }

    /// The thermo of the atoms added so far in a box of `volume`.
    pub fn thermo<const D: usize>(&self, volume: f64) -> Thermo {
        Thermo::from_sums::<D>(self.atoms, self.twice_kinetic, self.totals, volume)
    }
}

/// Adds the time since `t` to `total` and returns now: a stage's timer.
pub fn lap(t: Instant, total: &mut Duration) -> Instant {
    let now = Instant::now();
    *total += now - t;
    now
}

/// Atoms per task of the per-atom passes of a step (the integrator, the
/// position check).
const ATOM_CHUNK: usize = 4096;

/// Every position finite, and inside the box on non-periodic axes
/// (`lo_a <= x_a <= lo_a + L_a`); the first atom that is not, as the error of
/// `step`. The atoms are looked at in parallel; the first is the first in
/// their order, whatever the thread count.
pub fn check_positions<const D: usize>(
    domain: &Domain<D>,
    atoms: &Atoms<D>,
    step: u64,
    threads: &Threads,
) -> Result<(), MdError> {
    let open: [bool; D] = std::array::from_fn(|a| !domain.is_periodic(a));
    let hi: [f64; D] = std::array::from_fn(|a| domain.lo[a] + domain.length[a]);
    let inside = |x: &[f64; D], a: usize| !open[a] || (domain.lo[a]..=hi[a]).contains(&x[a]);
    let any_open = open.contains(&true);
    let fine = |x: &[f64; D]| {
        x.iter().all(|c| c.is_finite()) && (!any_open || (0..D).all(|a| inside(x, a)))
    };
    let positions = &atoms.positions;
    let first_bad_chunk = threads.install(|| {
        positions
            .par_chunks(ATOM_CHUNK)
            .position_first(|chunk| !chunk.iter().all(fine))
    });
    let Some(c) = first_bad_chunk else {
        return Ok(());
    };
    let k = c * ATOM_CHUNK
        + positions[c * ATOM_CHUNK..]
            .iter()
            .position(|x| !fine(x))
            .expect("the chunk holds an atom that is not fine");
    let (x, id) = (&atoms.positions[k], atoms.ids[k]);
    if !x.iter().all(|c| c.is_finite()) {
        return Err(MdError::NotFinite { step, id });
    }
    let axis = (0..D)
        .find(|&a| !inside(x, a))
        .expect("an atom that is finite but not fine is outside on some axis");
    Err(MdError::LeftBox {
        step,
        id,
        axis,
        coordinate: x[axis],
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Boundary;

    /// Thermo summed a block at a time (any block sizes) has the bits of
    /// thermo over all atoms with the per-atom energies and virials summed
    /// as one sequence.
    #[test]
    fn thermo_sums_in_blocks_have_the_bits_of_one_pass() {
        let mut rng = crate::random::Rng::new(5);
        let n = 1000;
        let mut atoms = Atoms::<3>::at_rest((0..n).map(|_| [0.0; 3]).collect(), 1.0);
        for k in 0..n {
            atoms.velocities[k] = std::array::from_fn(|_| rng.normal());
            atoms.masses[k] = 0.5 + rng.uniform();
        }
        let energies: Vec<f64> = (0..n).map(|_| rng.normal()).collect();
        let virials: Vec<f64> = (0..n).map(|_| rng.normal()).collect();
        let totals = PairTally {
            energy: energies.iter().sum(),
            virial: virials.iter().sum(),
        };
        let whole = Thermo::of(&atoms, totals, 123.0);
        for block in [1, 7, 333, n] {
            let mut sums = ThermoSums::default();
            for start in (0..n).step_by(block) {
                let slots: Vec<usize> = (start..n.min(start + block)).collect();
                let range = start..n.min(start + block);
                sums.add(
                    &atoms.select(&slots),
                    &energies[range.clone()],
                    &virials[range],
                );
            }
            assert_eq!(sums.thermo::<3>(123.0), whole, "blocks of {block}");
        }
    }

    /// The first atom (in the atoms' order) that is not finite or is outside
    /// an open face, whatever chunk it falls in and whatever the thread count;
    /// `Ok` when every atom is fine.
    #[test]
    fn check_positions_reports_the_first_bad_atom_on_any_thread_count() {
        let domain = Domain::new([10.0; 2], [Boundary::Periodic, Boundary::Open]).unwrap();
        let n = 10_000;
        let points = (0..n).map(|k| [k as f64 * 1e-3, 5.0]).collect();
        let mut atoms = Atoms::at_rest(points, 1.0);
        let pools = [Threads::single(), Threads::new(2).unwrap()];
        for threads in &pools {
            assert_eq!(check_positions(&domain, &atoms, 3, threads), Ok(()));
        }
        atoms.positions[9_000][0] = f64::NAN;
        atoms.positions[5_000][1] = 10.5;
        let left = MdError::LeftBox {
            step: 3,
            id: 5_001,
            axis: 1,
            coordinate: 10.5,
        };
        for threads in &pools {
            assert_eq!(
                check_positions(&domain, &atoms, 3, threads),
                Err(left.clone())
            );
        }
        atoms.positions[4_100][0] = f64::INFINITY;
        let not_finite = MdError::NotFinite { step: 3, id: 4_101 };
        for threads in &pools {
            assert_eq!(
                check_positions(&domain, &atoms, 3, threads),
                Err(not_finite.clone())
            );
        }
    }
}
