//! Molecular dynamics behind the driver's [`Model`] interface.

use super::frame::{particle_blocks, sorted_particles};
use super::{Atoms, Integrator, ListCounts, MdError, MdSystem, StageTimes};
use crate::geometry::Domain;
use crate::models::{
    Blowup, Checked, CheckedArray, Ids, Model, ModelInfo, ParticleBlock, Particles,
};
use crate::state::{
    Layout, SectionSink, SectionSource, SectionWriter, State, StateBuilder, StateError,
};
use crate::threads::Threads;
use std::ops::ControlFlow;
use std::time::Duration;

/// An [`MdSystem`] with its integrator and time step: what `cellist run` drives.
pub struct MdModel<const D: usize> {
    /// The atoms, potential and neighbour list.
    pub system: MdSystem<D>,
    /// How the atoms move.
    pub integrator: Integrator,
    /// The time step.
    pub dt: f64,
    /// The z bounds written in dumps of 2D systems.
    pub z_bounds: (f64, f64),
    times: StageTimes,
}

impl<const D: usize> MdModel<D> {
    /// The model of `system` advanced by `integrator` with steps of `dt`.
    pub fn new(system: MdSystem<D>, integrator: Integrator, dt: f64, z_bounds: (f64, f64)) -> Self {
        MdModel {
            system,
            integrator,
            dt,
            z_bounds,
            times: StageTimes::default(),
        }
    }
}

/// What to try when an md run blows up.
pub const REMEDY: &str =
    "the forces grew without bound: try a smaller run.dt, or check the initial state for atoms too close together";

/// The driver's [`Blowup`] of an md error at `step`: the atom, the quantity
/// and the remedy.
pub fn blowup_of(e: &MdError, step: u64) -> Blowup {
    let (what, value, particle) = match e {
        MdError::LeftBox {
            id,
            axis,
            coordinate,
            ..
        } => (
            format!(
                "atom {id} left the box through the non-periodic {} boundary",
                ["x", "y", "z"][*axis]
            ),
            Some((["x", "y", "z"][*axis].to_string(), *coordinate)),
            Some(*id),
        ),
        MdError::NotFinite { id, .. } => (
            format!("atom {id} has a non-finite position"),
            None,
            Some(*id),
        ),
        other => (other.to_string(), None, None),
    };
    Blowup {
        step,
        what,
        particle,
        value,
        remedy: REMEDY.into(),
    }
}

/// What an md model is: atoms, LAMMPS's thermo columns, its remedy.
pub const INFO: ModelInfo = ModelInfo {
    name: "md",
    particle: "atom",
    thermo_columns: &["temp", "pe", "ke", "etotal", "press"],
    remedy: REMEDY,
    count_may_change: false,
};

impl<const D: usize> MdModel<D> {
    /// Advances to `step`, the energy and virial summed in the force pass when
    /// `observe`.
    fn advance(&mut self, step: u64, observe: bool, threads: &Threads) -> Result<(), Blowup> {
        self.system
            .step(
                &self.integrator,
                self.dt,
                step,
                observe,
                threads,
                &mut self.times,
            )
            .map_err(|e| blowup_of(&e, step))
    }

    /// Replaces the positions or velocities (`name`) by `values`, `D` numbers
    /// per atom in id order; the system is set up anew (the checks of a new
    /// run, the neighbour list, the forces).
    pub fn set_array(
        &mut self,
        name: &str,
        values: &[f64],
        threads: &Threads,
    ) -> Result<(), String> {
        let system = &self.system;
        let n = system.atoms().len();
        if values.len() != n * D {
            return Err(format!(
                "{name}: {} numbers for {n} atoms in {D}D; give an ({n}, {D}) array",
                values.len()
            ));
        }
        let mut atoms = system.atoms().select(&system.atoms().slots_by_id());
        let target = match name {
            "positions" => &mut atoms.positions,
            "velocities" => &mut atoms.velocities,
            other => {
                return Err(format!(
                    "model md allows setting positions and velocities, not {other}"
                ))
            }
        };
        for (x, row) in target.iter_mut().zip(values.chunks_exact(D)) {
            x.copy_from_slice(row);
        }
        let rule = system.rebuild_rule();
        self.system = MdSystem::new(
            *system.domain(),
            atoms,
            *system.potential(),
            system.skin(),
            threads,
        )
        .map_err(|e| format!("{name}: {e}"))?;
        self.system.set_rebuild_rule(rule);
        Ok(())
    }
}

impl<const D: usize> Model for MdModel<D> {
    fn info(&self) -> &ModelInfo {
        &INFO
    }

    fn len(&self) -> usize {
        self.system.atoms().len()
    }

    fn dt(&self) -> f64 {
        self.dt
    }

    fn step(&mut self, step: u64, threads: &Threads) -> Result<(), Blowup> {
        self.advance(step, false, threads)
    }

    fn step_observed(&mut self, step: u64, threads: &Threads) -> Result<(), Blowup> {
        self.advance(step, true, threads)
    }

    fn thermo(&self, _step: u64) -> Vec<f64> {
        let th = self.system.thermo();
        vec![th.temp, th.pe, th.ke, th.etotal, th.press]
    }

    fn checked(&self) -> Checked<'_> {
        checked_atoms(self.system.atoms(), self.system.domain())
    }

    /// Sorted by id, positions wrapped into the box.
    fn particles(&self, _step: u64, energies: bool) -> Option<Particles> {
        let system = &self.system;
        let slots = system.atoms().slots_by_id();
        let energies = energies.then(|| system.per_atom_energy());
        Some(sorted_particles(
            system.atoms(),
            &slots,
            energies.as_deref(),
            system.domain(),
            self.z_bounds,
        ))
    }

    /// [`MdModel::particles`] a few thousand atoms at a time.
    fn particle_blocks(
        &self,
        _step: u64,
        energies: bool,
        visit: &mut dyn FnMut(ParticleBlock<'_>) -> ControlFlow<()>,
    ) -> bool {
        let system = &self.system;
        let slots = system.atoms().slots_by_id();
        let energies = energies.then(|| system.per_atom_energy());
        particle_blocks(
            system.atoms(),
            &slots,
            energies.as_deref(),
            system.domain(),
            self.z_bounds,
            visit,
        );
        true
    }

    fn stage_times(&self) -> Vec<(&'static str, Duration)> {
        self.times.stages()
    }

    fn save(&self, state: &mut State) {
        let system = &self.system;
        save_atoms(
            state,
            system.atoms(),
            system.list_reference(),
            system.list_counts(),
        );
    }

    fn restore(&mut self, state: &dyn SectionSource, threads: &Threads) -> Result<(), StateError> {
        let (atoms, reference, counts) = load_atoms(state, self.len())?;
        self.system
            .restore(atoms, &reference, counts, threads)
            .map_err(StateError)
    }
}

/// What the driver checks of `atoms` in `domain`: positions, velocities and
/// forces finite, the atoms named by their ids, positions within the walls.
pub fn checked_atoms<'a, const D: usize>(atoms: &'a Atoms<D>, domain: &Domain<D>) -> Checked<'a> {
    let arrays = [
        ("position", &atoms.positions),
        ("velocity", &atoms.velocities),
        ("force", &atoms.forces),
    ]
    .map(|(quantity, v)| CheckedArray {
        quantity,
        values: v.as_flattened(),
        per_particle: D,
    })
    .into();
    Checked {
        walls: domain.walls(),
        ..Checked::new(Ids::U64(&atoms.ids), arrays)
    }
}

/// What a run summary says of `late` rebuilds ([`MdSystem::late_builds`]):
/// nothing when there were none.
pub fn late_note(late: u64) -> String {
    if late == 0 {
        return String::new();
    }
    format!(
        " ({late} late: an atom had moved more than skin/2 before the list was looked at, \
         so pairs may have been missed; lower neighbor.every)"
    )
}

/// Writes the atoms, each one's position at the last neighbour-list rebuild
/// (`reference`, the skin/2 test's) and the list's counters: an md
/// checkpoint's state, the same whether one process or several ranks wrote it.
pub fn save_atoms<const D: usize>(
    state: &mut State,
    atoms: &Atoms<D>,
    reference: &[[f64; D]],
    counts: ListCounts,
) {
    let mut layout = Layout::default();
    let mut saved = SavedAtoms::<D>::new(atoms.len(), &mut layout);
    let mut sections = StateBuilder::new(layout);
    saved.push(&mut sections, atoms, reference);
    saved.finish(&mut sections, counts);
    sections.finish(state);
}

/// The state of [`save_atoms`] written a block of atoms at a time (a
/// distributed run's atoms arriving in id order) into a [`SectionSink`]:
/// the same bytes as one call with all of them.
#[derive(Debug)]
pub struct SavedAtoms<const D: usize> {
    /// The sections' indices in the layout: `ids`, `types`, `masses`,
    /// `positions`, `velocities`, `forces`, `list_reference`, `rebuilds`,
    /// `list_counts`.
    sections: [usize; 9],
    writer: SectionWriter,
}

impl<const D: usize> SavedAtoms<D> {
    /// The sections of `n` atoms, added to `layout`.
    pub fn new(n: usize, layout: &mut Layout) -> Self {
        let sections = [
            ("ids", n),
            ("types", n),
            ("masses", n),
            ("positions", D * n),
            ("velocities", D * n),
            ("forces", D * n),
            ("list_reference", D * n),
            ("rebuilds", 1),
            ("list_counts", 2),
        ]
        .map(|(name, values)| layout.add(name, values));
        SavedAtoms {
            sections,
            writer: SectionWriter::default(),
        }
    }

    /// Appends `atoms` and their positions at the last rebuild.
    pub fn push(&mut self, sink: &mut dyn SectionSink, atoms: &Atoms<D>, reference: &[[f64; D]]) {
        let [ids, types, masses, positions, velocities, forces, list_reference, ..] = self.sections;
        let w = &mut self.writer;
        w.u64s(sink, ids, atoms.ids.iter().copied());
        w.u64s(sink, types, atoms.types.iter().map(|&t| t as u64));
        w.f64s(sink, masses, atoms.masses.iter().copied());
        w.vectors(sink, positions, &atoms.positions);
        w.vectors(sink, velocities, &atoms.velocities);
        w.vectors(sink, forces, &atoms.forces);
        w.vectors(sink, list_reference, reference);
    }

    /// Appends the list's counters, after the last atoms.
    pub fn finish(&mut self, sink: &mut dyn SectionSink, counts: ListCounts) {
        let w = &mut self.writer;
        w.u64s(sink, self.sections[7], [counts.rebuilds]);
        w.u64s(
            sink,
            self.sections[8],
            [counts.since_build, counts.late_builds],
        );
    }
}

/// The atoms read a block at a time by [`load_atoms_where`].
const LOAD_BLOCK: usize = 1 << 13;

/// Reads what [`save_atoms`] wrote for `n` atoms (a checkpoint written before
/// the list counted its steps since a build restarts with 0 of them: it was
/// written by a run that looked at its list on every step).
pub fn load_atoms<const D: usize>(
    state: &dyn SectionSource,
    n: usize,
) -> Result<(Atoms<D>, Vec<[f64; D]>, ListCounts), StateError> {
    load_atoms_where(state, n, |_| true)
}

/// [`load_atoms`] keeping only the atoms whose position `keep` accepts, in
/// the saved order with their reference positions: every section checked
/// to hold `n` atoms' numbers, the atoms read 8192 at a time (a
/// rank's share of a checkpoint file, the whole never held).
pub fn load_atoms_where<const D: usize>(
    state: &dyn SectionSource,
    n: usize,
    mut keep: impl FnMut(&[f64; D]) -> bool,
) -> Result<(Atoms<D>, Vec<[f64; D]>, ListCounts), StateError> {
    for (name, per_atom) in [
        ("types", 1),
        ("ids", 1),
        ("masses", 1),
        ("positions", D),
        ("velocities", D),
        ("forces", D),
    ] {
        state.expect_count(name, per_atom * n)?;
    }
    let [since_build, late_builds] = if state.has("list_counts") {
        let counts = state.u64s_of("list_counts", 2)?;
        [counts[0], counts[1]]
    } else {
        [0, 0]
    };
    let counts = ListCounts {
        rebuilds: state.u64("rebuilds")?,
        since_build,
        late_builds,
    };
    state.expect_count("list_reference", D * n)?;
    let mut atoms = Atoms::default();
    let mut reference = Vec::new();
    for start in (0..n).step_by(LOAD_BLOCK) {
        let len = LOAD_BLOCK.min(n - start);
        // every rank checks every type, kept or not, as the whole load did
        let types = state
            .u64s_at("types", start, len)?
            .into_iter()
            .map(|t| {
                u32::try_from(t).map_err(|_| StateError(format!("atom type {t} is out of range")))
            })
            .collect::<Result<Vec<u32>, StateError>>()?;
        let positions = state.vectors_at::<D>("positions", start, len)?;
        let kept: Vec<usize> = (0..len).filter(|&k| keep(&positions[k])).collect();
        if kept.is_empty() {
            continue;
        }
        let block = Atoms {
            ids: state.u64s_at("ids", start, len)?,
            types,
            masses: state.f64s_at("masses", start, len)?,
            positions,
            velocities: state.vectors_at("velocities", start, len)?,
            forces: state.vectors_at("forces", start, len)?,
        };
        let block_reference = state.vectors_at::<D>("list_reference", start, len)?;
        atoms.push_from(&block, &kept);
        reference.extend(kept.iter().map(|&k| block_reference[k]));
    }
    Ok((atoms, reference, counts))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Atoms saved a block at a time are the bytes of one [`save_atoms`],
    /// and load back as they were.
    #[test]
    fn saved_in_blocks_is_saved_at_once() {
        let n = 50;
        let points = (0..n).map(|k| [k as f64, 0.5 * k as f64]).collect();
        let mut atoms = Atoms::<2>::at_rest(points, 2.0);
        for k in 0..n {
            atoms.velocities[k] = [k as f64 * 0.1, -0.2];
            atoms.forces[k] = [1.0 / (k + 1) as f64, 3.0];
            atoms.types[k] = 1 + (k % 3) as u32;
        }
        let reference: Vec<[f64; 2]> = atoms
            .positions
            .iter()
            .map(|p| [p[0] + 0.01, p[1]])
            .collect();
        let counts = ListCounts {
            rebuilds: 4,
            since_build: 2,
            late_builds: 1,
        };
        let mut whole = State::default();
        save_atoms(&mut whole, &atoms, &reference, counts);
        let mut layout = Layout::default();
        let mut saved = SavedAtoms::<2>::new(n, &mut layout);
        let mut sections = StateBuilder::new(layout);
        for start in (0..n).step_by(7) {
            let slots: Vec<usize> = (start..n.min(start + 7)).collect();
            let block = &reference[start..n.min(start + 7)];
            saved.push(&mut sections, &atoms.select(&slots), block);
        }
        saved.finish(&mut sections, counts);
        let mut blocks = State::default();
        sections.finish(&mut blocks);
        assert_eq!(blocks, whole);
        let (loaded, loaded_reference, loaded_counts) = load_atoms::<2>(&blocks, n).unwrap();
        assert_eq!(loaded, atoms);
        assert_eq!((loaded_reference, loaded_counts), (reference, counts));
    }

    /// Atoms loaded where a test keeps them, over more than one block, are
    /// those of the whole load at the kept places, in order.
    #[test]
    fn atoms_loaded_where_kept_are_the_whole_loads_at_those_places() {
        let n = LOAD_BLOCK + 100;
        let points = (0..n).map(|k| [(k % 97) as f64, k as f64]).collect();
        let mut atoms = Atoms::<2>::at_rest(points, 1.5);
        for k in 0..n {
            atoms.velocities[k] = [k as f64, 0.25];
            atoms.types[k] = 1 + (k % 2) as u32;
        }
        let reference: Vec<[f64; 2]> = atoms.positions.iter().map(|p| [p[0], -p[1]]).collect();
        let counts = ListCounts::default();
        let mut state = State::default();
        save_atoms(&mut state, &atoms, &reference, counts);
        let keep = |p: &[f64; 2]| p[0] < 10.0 || p[1] > (n - 5) as f64;
        let kept: Vec<usize> = (0..n).filter(|&k| keep(&atoms.positions[k])).collect();
        let (part, part_reference, part_counts) = load_atoms_where::<2>(&state, n, keep).unwrap();
        assert_eq!(part, atoms.select(&kept));
        let want: Vec<[f64; 2]> = kept.iter().map(|&k| reference[k]).collect();
        assert_eq!((part_reference, part_counts), (want, counts));
        let wrong = load_atoms_where::<2>(&state, n + 1, keep).unwrap_err();
        assert!(wrong.0.contains("expected"), "{wrong}");
        // a type out of range in a block none of whose atoms is kept
        let types = state
            .sections
            .iter_mut()
            .find(|s| s.name == "types")
            .unwrap();
        types.data[8 * 50..8 * 51].copy_from_slice(&u64::MAX.to_le_bytes());
        let last = |p: &[f64; 2]| p[1] > (n - 5) as f64;
        let bad = load_atoms_where::<2>(&state, n, last).unwrap_err();
        assert!(bad.0.contains("out of range"), "{bad}");
    }
}
