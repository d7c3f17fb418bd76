//! Per-atom arrays of a molecular-dynamics system.

/// The atoms, one entry per atom in every array, all in the same order (the cell
/// order of the last neighbour-list build inside a running system).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Atoms<const D: usize> {
    /// Stable ids (LAMMPS atom ids), unique.
    pub ids: Vec<u64>,
    /// Atom types (1-based, as LAMMPS numbers them).
    pub types: Vec<u32>,
    /// Masses.
    pub masses: Vec<f64>,
    /// Positions.
    pub positions: Vec<[f64; D]>,
    /// Velocities.
    pub velocities: Vec<[f64; D]>,
    /// Forces of the last evaluation.
    pub forces: Vec<[f64; D]>,
}

impl<const D: usize> Atoms<D> {
    /// Atoms at `positions` with ids 1..=N, type 1, the given mass, at rest.
    pub fn at_rest(positions: Vec<[f64; D]>, mass: f64) -> Self {
        let n = positions.len();
        Atoms {
            ids: (1..=n as u64).collect(),
            types: vec![1; n],
            masses: vec![mass; n],
            velocities: vec![[0.0; D]; n],
            forces: vec![[0.0; D]; n],
            positions,
        }
    }

    /// Number of atoms.
    pub fn len(&self) -> usize {
        self.ids.len()
    }

    /// True when there are no atoms.
    pub fn is_empty(&self) -> bool {
        self.ids.is_empty()
    }

    /// True when every array has one entry per atom.
    pub fn is_consistent(&self) -> bool {
        let n = self.len();
        self.types.len() == n
            && self.masses.len() == n
            && self.positions.len() == n
            && self.velocities.len() == n
            && self.forces.len() == n
    }

    /// Panics unless every array has one entry per atom (a programming error).
    pub(crate) fn assert_consistent(&self) {
        assert!(self.is_consistent(), "per-atom arrays of different lengths");
    }

    /// Reorders every array except the positions: `self[k] = old[order[k]]`,
    /// through the two buffers of `scratch` (no allocation once they have grown).
    pub(crate) fn permute_except_positions(
        &mut self,
        order: &[u32],
        scratch: &mut PermuteScratch<D>,
    ) {
        let same = |x| x;
        reorder(&mut self.ids, order, &mut scratch.words, same, same);
        reorder(&mut self.types, order, &mut scratch.words, u64::from, |w| {
            w as u32
        });
        reorder(
            &mut self.masses,
            order,
            &mut scratch.words,
            f64::to_bits,
            f64::from_bits,
        );
        let same = |x| x;
        reorder(
            &mut self.velocities,
            order,
            &mut scratch.vectors,
            same,
            same,
        );
        reorder(&mut self.forces, order, &mut scratch.vectors, same, same);
    }

    /// Reorders every array: `self[k] = old[order[k]]` (the atoms of
    /// [`Atoms::select`] of `order`, in place through `scratch`).
    pub fn permute(&mut self, order: &[u32], scratch: &mut PermuteScratch<D>) {
        self.permute_except_positions(order, scratch);
        let same = |x| x;
        reorder(&mut self.positions, order, &mut scratch.vectors, same, same);
    }

    /// The atoms at `indices`, in that order: `out[k] = self[indices[k]]`.
    pub fn select(&self, indices: &[usize]) -> Self {
        fn pick<T: Copy>(values: &[T], indices: &[usize]) -> Vec<T> {
            indices.iter().map(|&k| values[k]).collect()
        }
        Atoms {
            ids: pick(&self.ids, indices),
            types: pick(&self.types, indices),
            masses: pick(&self.masses, indices),
            positions: pick(&self.positions, indices),
            velocities: pick(&self.velocities, indices),
            forces: pick(&self.forces, indices),
        }
    }

    /// Slots in increasing id order (for output sorted by id).
    pub fn slots_by_id(&self) -> Vec<usize> {
        let mut slots: Vec<usize> = (0..self.len()).collect();
        slots.sort_unstable_by_key(|&k| self.ids[k]);
        slots
    }
}

/// `values[k] = old[order[k]]` through `buffer` (words of type `W`, converted
/// by `to` and back by `from`).
fn reorder<T: Copy, W: Copy>(
    values: &mut [T],
    order: &[u32],
    buffer: &mut Vec<W>,
    to: impl Fn(T) -> W,
    from: impl Fn(W) -> T,
) {
    assert_eq!(values.len(), order.len(), "one slot per atom");
    buffer.clear();
    buffer.extend(order.iter().map(|&k| to(values[k as usize])));
    for (value, &word) in values.iter_mut().zip(buffer.iter()) {
        *value = from(word);
    }
}

/// The buffers [`Atoms::permute`] reorders through: one array of vectors and
/// one of 64-bit words (ids, types and the bits of masses), 8 (D + 1) bytes
/// per atom instead of a second copy of every array.
#[derive(Clone, Debug, Default)]
pub struct PermuteScratch<const D: usize> {
    pub(crate) vectors: Vec<[f64; D]>,
    pub(crate) words: Vec<u64>,
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Permuting in place is selecting in that order.
    #[test]
    fn permute_is_select() {
        let n = 40;
        let mut atoms = Atoms::<3>::at_rest((0..n).map(|k| [k as f64, 1.0, 2.0]).collect(), 1.5);
        for k in 0..n {
            atoms.ids[k] = 100 + 7 * k as u64;
            atoms.types[k] = (k % 4) as u32;
            atoms.masses[k] = k as f64;
            atoms.velocities[k] = [0.0, k as f64, 0.0];
            atoms.forces[k] = [0.0, 0.0, -(k as f64)];
        }
        let order: Vec<u32> = (0..n as u32).map(|k| (k * 17) % n as u32).collect();
        let slots: Vec<usize> = order.iter().map(|&k| k as usize).collect();
        let selected = atoms.select(&slots);
        let mut scratch = PermuteScratch::default();
        atoms.permute(&order, &mut scratch);
        assert_eq!(atoms, selected);
    }
}
