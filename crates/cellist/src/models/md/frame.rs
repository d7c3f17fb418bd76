//! md's dump frames: atoms in a given order (by id for output), positions
//! wrapped into the box, vectors padded to 3 components, whole
//! ([`dump_particles`]) or a block of rows at a time ([`particle_blocks`]), so
//! that a dump need not hold a copy of every atom.

use super::Atoms;
use crate::geometry::Domain;
use crate::models::{ParticleBlock, Particles};
use std::ops::ControlFlow;

/// Atoms per block of [`particle_blocks`]: about 350 KB of rows.
const BLOCK: usize = 4096;

fn pad<const D: usize>(v: [f64; D]) -> [f64; 3] {
    std::array::from_fn(|a| if a < D { v[a] } else { 0.0 })
}

/// A frame without rows: the box of `domain`, with the z bounds `z_bounds`
/// for 2D systems.
fn frame_box<const D: usize>(domain: &Domain<D>, z_bounds: (f64, f64)) -> Particles {
    let mut lo = [0.0, 0.0, z_bounds.0];
    let mut hi = [0.0, 0.0, z_bounds.1];
    let mut periodic = [true; 3];
    for a in 0..D {
        lo[a] = domain.lo[a];
        hi[a] = domain.lo[a] + domain.length[a];
        periodic[a] = domain.is_periodic(a);
    }
    Particles {
        dimension: D,
        lo,
        hi,
        periodic,
        ..Particles::default()
    }
}

/// Replaces the rows of `frame` by the atoms at `slots`, in that order, with
/// their energies `energies[slot]` if given.
fn fill_rows<const D: usize>(
    frame: &mut Particles,
    atoms: &Atoms<D>,
    slots: impl Iterator<Item = usize> + Clone,
    energies: Option<&[f64]>,
    domain: &Domain<D>,
) {
    fn refill<T>(column: &mut Vec<T>, values: impl Iterator<Item = T>) {
        column.clear();
        column.extend(values);
    }
    let at = || slots.clone();
    refill(&mut frame.ids, at().map(|k| atoms.ids[k]));
    refill(&mut frame.types, at().map(|k| atoms.types[k]));
    refill(
        &mut frame.positions,
        at().map(|k| pad(domain.wrap(atoms.positions[k]))),
    );
    refill(
        &mut frame.velocities,
        at().map(|k| pad(atoms.velocities[k])),
    );
    refill(&mut frame.forces, at().map(|k| pad(atoms.forces[k])));
    if let Some(pe) = energies {
        refill(
            frame.energies.get_or_insert_with(Vec::new),
            at().map(|k| pe[k]),
        );
    }
}

/// The dump frame of `atoms` (in their order): positions wrapped into
/// `domain`, vectors padded to 3 components, the z bounds of 2D systems
/// `z_bounds`, per-atom energies if given.
pub fn dump_particles<const D: usize>(
    atoms: &Atoms<D>,
    energies: Option<Vec<f64>>,
    domain: &Domain<D>,
    z_bounds: (f64, f64),
) -> Particles {
    let mut frame = frame_box(domain, z_bounds);
    fill_rows(&mut frame, atoms, 0..atoms.len(), None, domain);
    frame.energies = energies;
    frame
}

/// The dump frame of the atoms at `slots`, in that order, with the energies
/// `energies[slot]` if given ([`dump_particles`] of those atoms).
pub(super) fn sorted_particles<const D: usize>(
    atoms: &Atoms<D>,
    slots: &[usize],
    energies: Option<&[f64]>,
    domain: &Domain<D>,
    z_bounds: (f64, f64),
) -> Particles {
    let mut frame = frame_box(domain, z_bounds);
    fill_rows(&mut frame, atoms, slots.iter().copied(), energies, domain);
    frame
}

/// The frame of [`sorted_particles`] handed to `visit` a block of rows at a
/// time (one block of none when there are no atoms), until it returns `Break`.
pub(super) fn particle_blocks<const D: usize>(
    atoms: &Atoms<D>,
    slots: &[usize],
    energies: Option<&[f64]>,
    domain: &Domain<D>,
    z_bounds: (f64, f64),
    visit: &mut dyn FnMut(ParticleBlock<'_>) -> ControlFlow<()>,
) {
    let mut rows = frame_box(domain, z_bounds);
    let mut first = 0;
    loop {
        let block = &slots[first..slots.len().min(first + BLOCK)];
        fill_rows(&mut rows, atoms, block.iter().copied(), energies, domain);
        let next = first + block.len();
        let total = slots.len();
        if visit(ParticleBlock {
            total,
            first,
            rows: &rows,
        })
        .is_break()
            || next == total
        {
            return;
        }
        first = next;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Boundary;

    /// The blocks, put end to end, are the whole frame, for a count that is
    /// not a multiple of the block size; no atoms give one empty block.
    #[test]
    fn blocks_make_up_the_frame() {
        let domain = Domain::new([4.0, 5.0], [Boundary::Periodic, Boundary::Open]).unwrap();
        let n = 2 * BLOCK + 7;
        let points = (0..n).map(|k| [k as f64 * 1e-3 - 1.0, 2.5]).collect();
        let mut atoms = Atoms::at_rest(points, 1.0);
        atoms.velocities[3] = [0.5, -0.25];
        let slots: Vec<usize> = (0..n).rev().collect();
        let pe: Vec<f64> = (0..n).map(|k| -(k as f64)).collect();
        let whole = sorted_particles(&atoms, &slots, Some(&pe), &domain, (-0.5, 0.5));
        let mut joined: Option<Particles> = None;
        let mut firsts = Vec::new();
        particle_blocks(&atoms, &slots, Some(&pe), &domain, (-0.5, 0.5), &mut |b| {
            assert_eq!(b.total, n);
            firsts.push(b.first);
            match &mut joined {
                None => joined = Some(b.rows.clone()),
                Some(joined) => joined.append(b.rows),
            }
            ControlFlow::Continue(())
        });
        let joined = joined.unwrap();
        assert_eq!(firsts, [0, BLOCK, 2 * BLOCK]);
        assert_eq!(joined, whole);
        assert_eq!(whole.positions[n - 1], [3.0, 2.5, 0.0]);
        let none = Atoms::<2>::default();
        let mut blocks = 0;
        particle_blocks(&none, &[], None, &domain, (-0.5, 0.5), &mut |b| {
            assert_eq!((b.total, b.first, b.rows.ids.len()), (0, 0, 0));
            blocks += 1;
            ControlFlow::Break(())
        });
        assert_eq!(blocks, 1);
    }
}
