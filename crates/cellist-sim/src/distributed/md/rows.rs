//! A rank's atoms as rows: travelling to their new owner at a migration
//! ([`Travellers`] of atoms) and pulled by rank 0 for its outputs
//! ([`OwnRows`]), and the blocks of the global state rank 0 makes of them
//! ([`Gathered`]).

use super::super::pull;
use super::super::Travellers;
use super::DistributedMd;
use cellist::models::md::Atoms;

/// Atoms sorted by id with their half pair energies and half virials and
/// their positions at the last rebuild: a block of the global state pulled by
/// rank 0.
#[derive(Clone, Debug, Default)]
pub(super) struct Gathered<const D: usize> {
    pub(super) atoms: Atoms<D>,
    pub(super) energies: Vec<f64>,
    pub(super) virials: Vec<f64>,
    pub(super) reference: Vec<[f64; D]>,
}

/// Appends to `atoms` the atoms of `ids` whose rows of `width` numbers
/// start with the columns of [`Travellers::pack`].
fn push_atom_rows<const D: usize>(atoms: &mut Atoms<D>, ids: &[u64], values: &[f64], width: usize) {
    for (&id, row) in ids.iter().zip(values.chunks_exact(width)) {
        let vector = |at: usize| -> [f64; D] { std::array::from_fn(|d| row[at + d]) };
        atoms.ids.push(id);
        atoms.positions.push(vector(0));
        atoms.velocities.push(vector(D));
        atoms.forces.push(vector(2 * D));
        atoms.masses.push(row[3 * D]);
        atoms.types.push(row[3 * D + 1] as u32);
    }
}

/// Atoms travel as rows of position, velocity, force, mass and type.
impl<const D: usize> Travellers<D> for Atoms<D> {
    fn count(&self) -> usize {
        Atoms::len(self)
    }

    fn position(&self, k: usize) -> [f64; D] {
        self.positions[k]
    }

    fn width(&self) -> usize {
        3 * D + 2
    }

    fn pack(&self, k: usize, ids: &mut Vec<u64>, values: &mut Vec<f64>) {
        ids.push(self.ids[k]);
        values.extend_from_slice(&self.positions[k]);
        values.extend_from_slice(&self.velocities[k]);
        values.extend_from_slice(&self.forces[k]);
        values.extend([self.masses[k], self.types[k] as f64]);
    }

    fn keep(&mut self, from: usize, to: usize, x: [f64; D]) {
        self.ids[to] = self.ids[from];
        self.positions[to] = x;
        self.velocities[to] = self.velocities[from];
        self.forces[to] = self.forces[from];
        self.masses[to] = self.masses[from];
        self.types[to] = self.types[from];
    }

    fn truncate(&mut self, n: usize) {
        self.ids.truncate(n);
        self.positions.truncate(n);
        self.velocities.truncate(n);
        self.forces.truncate(n);
        self.masses.truncate(n);
        self.types.truncate(n);
    }

    fn push_rows(&mut self, ids: &[u64], values: &[f64]) {
        push_atom_rows(self, ids, values, 3 * D + 2);
    }
}

/// The rows of [`OwnRows`] as a block of the global state.
pub(super) fn gathered_of<const D: usize>(
    ids: &[u64],
    values: &[f64],
    width: usize,
) -> Gathered<D> {
    let base = 3 * D + 2;
    let mut atoms = Atoms::default();
    push_atom_rows(&mut atoms, ids, values, width);
    let rows = || values.chunks_exact(width);
    Gathered {
        atoms,
        energies: rows().map(|row| row[base]).collect(),
        virials: rows().map(|row| row[base + 1]).collect(),
        reference: rows()
            .map(|row| std::array::from_fn(|d| row[base + 2 + d]))
            .collect(),
    }
}

/// A rank's own atoms as the rows rank 0 pulls for its outputs: the columns
/// of [`Travellers::pack`], then the half energy, the half virial and the
/// position at the last rebuild.
pub(super) struct OwnRows<'a, const D: usize>(pub(super) &'a DistributedMd<D>);

impl<const D: usize> pull::OwnRows for OwnRows<'_, D> {
    fn width(&self) -> usize {
        4 * D + 4
    }

    fn rows(&self, a: u64, b: u64, ids: &mut Vec<u64>, values: &mut Vec<f64>) {
        let m = self.0;
        let id = |k: &u32| m.atoms.ids[*k as usize];
        let (by_id, a, b) = (m.by_id(), a, b);
        let range = by_id.partition_point(|k| id(k) < a)..by_id.partition_point(|k| id(k) < b);
        ids.clear();
        values.clear();
        let (atoms, reference) = (&m.atoms, m.reference());
        for k in by_id[range].iter().map(|&k| k as usize) {
            ids.push(atoms.ids[k]);
            values.extend_from_slice(&atoms.positions[k]);
            values.extend_from_slice(&atoms.velocities[k]);
            values.extend_from_slice(&atoms.forces[k]);
            values.extend([atoms.masses[k], atoms.types[k] as f64]);
            values.extend(m.energies[k]);
            values.extend_from_slice(&reference[k]);
        }
    }
}
