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
        self.permute_all_but_positions(order, &mut scratch.vectors, &mut scratch.words);
    }

    /// Reorders every array, `self[k] = old[order[k]]`, through buffers the
    /// caller lends, `vectors` and `words` (each array gathered into one and
    /// copied back: sequential writes, no allocation once they have grown).
    pub fn permute_through(
        &mut self,
        order: &[u32],
        vectors: &mut Vec<[f64; D]>,
        words: &mut Vec<u64>,
    ) {
        self.permute_all_but_positions(order, vectors, words);
        reorder(&mut self.positions, order, vectors, |x| x, |x| x);
    }

    /// [`Atoms::permute_through`] of every array but the positions.
    fn permute_all_but_positions(
        &mut self,
        order: &[u32],
        vectors: &mut Vec<[f64; D]>,
        words: &mut Vec<u64>,
    ) {
        let same = |x| x;
        reorder(&mut self.ids, order, words, same, same);
        reorder(&mut self.types, order, words, u64::from, |w| w as u32);
        reorder(&mut self.masses, order, words, f64::to_bits, f64::from_bits);
        let same = |x| x;
        reorder(&mut self.velocities, order, vectors, same, same);
        reorder(&mut self.forces, order, vectors, same, same);
    }

    /// Reorders every array, `self[k] = old[order[k]]` (the atoms of
    /// [`Atoms::select`] of `order`), by following the cycles of the
    /// permutation: each atom is moved once, with one bit per atom and no
    /// copy of any array. Panics when `order` is not a permutation of
    /// `0..len`.
    pub fn permute_by_cycles(&mut self, order: &[u32]) {
        let n = self.len();
        assert_eq!(order.len(), n, "one slot per atom");
        let mut placed = vec![0u64; n.div_ceil(64)];
        for start in 0..n {
            if placed[start / 64] >> (start % 64) & 1 == 1 {
                continue;
            }
            let first = self.row(start);
            let mut k = start;
            loop {
                placed[k / 64] |= 1 << (k % 64);
                let from = order[k] as usize;
                if from == start {
                    self.set_row(k, first);
                    break;
                }
                assert!(
                    placed[from / 64] >> (from % 64) & 1 == 0,
                    "the order is not a permutation: slot {from} twice"
                );
                self.set_row(k, self.row(from));
                k = from;
            }
        }
    }

    /// Everything atom `k` carries.
    fn row(&self, k: usize) -> AtomRow<D> {
        AtomRow {
            id: self.ids[k],
            kind: self.types[k],
            mass: self.masses[k],
            position: self.positions[k],
            velocity: self.velocities[k],
            force: self.forces[k],
        }
    }

    /// Puts `row` in slot `k`.
    fn set_row(&mut self, k: usize, row: AtomRow<D>) {
        self.ids[k] = row.id;
        self.types[k] = row.kind;
        self.masses[k] = row.mass;
        self.positions[k] = row.position;
        self.velocities[k] = row.velocity;
        self.forces[k] = row.force;
    }

    /// The atoms at `indices`, in that order: `out[k] = self[indices[k]]`.
    pub fn select(&self, indices: &[usize]) -> Self {
        let mut out = Atoms::default();
        out.push_from(self, indices);
        out
    }

    /// Appends the atoms of `other` at `indices`, in that order.
    pub fn push_from(&mut self, other: &Atoms<D>, indices: &[usize]) {
        fn pick<T: Copy>(to: &mut Vec<T>, values: &[T], indices: &[usize]) {
            to.extend(indices.iter().map(|&k| values[k]));
        }
        pick(&mut self.ids, &other.ids, indices);
        pick(&mut self.types, &other.types, indices);
        pick(&mut self.masses, &other.masses, indices);
        pick(&mut self.positions, &other.positions, indices);
        pick(&mut self.velocities, &other.velocities, indices);
        pick(&mut self.forces, &other.forces, indices);
    }

    /// Slots in increasing id order (for output sorted by id).
    pub fn slots_by_id(&self) -> Vec<usize> {
        let mut slots: Vec<usize> = (0..self.len()).collect();
        slots.sort_unstable_by_key(|&k| self.ids[k]);
        slots
    }
}

/// One atom's entries of every array ([`Atoms::permute_by_cycles`]).
#[derive(Clone, Copy)]
struct AtomRow<const D: usize> {
    id: u64,
    kind: u32,
    mass: f64,
    position: [f64; D],
    velocity: [f64; D],
    force: [f64; D],
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

/// The buffers [`Atoms::permute_except_positions`] reorders through: one array of vectors and
/// one of 64-bit words (ids, types and the bits of masses), 8 (D + 1) bytes
/// per atom instead of a second copy of every array.
#[derive(Clone, Debug, Default)]
pub(crate) struct PermuteScratch<const D: usize> {
    pub(crate) vectors: Vec<[f64; D]>,
    pub(crate) words: Vec<u64>,
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// Permuting in place (all but the positions through the buffers, all
    /// along the cycles) is selecting in that order.
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
        let mut by_cycles = atoms.clone();
        let mut scratch = PermuteScratch::default();
        atoms.permute_except_positions(&order, &mut scratch);
        atoms.positions = selected.positions.clone();
        assert_eq!(atoms, selected);
        by_cycles.permute_by_cycles(&order);
        assert_eq!(by_cycles, selected);
        let mut through = by_cycles.clone();
        through.permute_by_cycles(&slots_of_inverse(&order));
        let (mut vectors, mut words) = (Vec::new(), Vec::new());
        through.permute_through(&order, &mut vectors, &mut words);
        assert_eq!(through, selected);
    }

    /// The permutation that undoes `order`.
    fn slots_of_inverse(order: &[u32]) -> Vec<u32> {
        let mut inverse = vec![0; order.len()];
        for (k, &o) in order.iter().enumerate() {
            inverse[o as usize] = k as u32;
        }
        inverse
    }

    /// An order with a slot twice is refused, not followed forever.
    #[test]
    #[should_panic(expected = "not a permutation")]
    fn a_repeated_slot_is_refused() {
        let mut atoms = Atoms::<2>::at_rest(vec![[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]], 1.0);
        atoms.permute_by_cycles(&[1, 2, 1]);
    }

    proptest! {
        /// Following the cycles of any permutation is selecting in its order.
        #[test]
        fn permute_by_cycles_is_select(
            order in (1usize..200).prop_flat_map(|n| {
                Just((0..n as u32).collect::<Vec<u32>>()).prop_shuffle()
            })
        ) {
            let n = order.len();
            let mut atoms = Atoms::<2>::at_rest((0..n).map(|k| [k as f64, -(k as f64)]).collect(), 1.0);
            for k in 0..n {
                atoms.ids[k] = 3 * k as u64 + 1;
                atoms.types[k] = (k % 3) as u32 + 1;
                atoms.masses[k] = 1.0 + k as f64;
                atoms.velocities[k] = [k as f64, 0.5];
                atoms.forces[k] = [-0.5, k as f64];
            }
            let slots: Vec<usize> = order.iter().map(|&k| k as usize).collect();
            let selected = atoms.select(&slots);
            atoms.permute_by_cycles(&order);
            prop_assert_eq!(atoms, selected);
        }
    }
}
