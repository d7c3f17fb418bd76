//! The Lennard-Jones forces over a half cluster pair list ([`ClusterList`]),
//! `4 x 4` pairs at a time, GROMACS's nbnxm scheme in double precision:
//!
//! ```text
//! for every cluster I, each i position broadcast to four lanes once:
//!     for every (J, image) of row I (first the entries with a pair within
//!     the cutoff at the build, then the others, each only if r^2 < r_c^2 in
//!     some lane now: a block of masked pairs adds only zeros):
//!         x_J + shift loaded as one lane vector per axis
//!         for every i in I:   d = x_i - (x_J + shift),  r^2 = |d|^2 (4 lanes)
//!                             (formed as -d = (x_J + shift) - x_i, so that the
//!                             broadcast x_i is a memory operand; the same
//!                             forces to the bit: only a zero's sign differs,
//!                             and the sums start at +0)
//!             g = -U'(r)/r where r^2 < r_c^2 (and the lane is a real pair), else 0
//!             f_i += d g (summed over the row),  f_J -= d g (one store per J)
//! ```
//!
//! No neighbour is gathered one at a time and no force is scattered one at a
//! time: a row entry is one cluster, loaded and stored as lanes. Lanes beyond a
//! cluster's size, the pairs `j <= i` of a cluster with itself, and the pairs
//! at or beyond the cutoff get `g = 0` from a mask, so the loop has no branch
//! per pair. Every pair's `g` is what the scalar
//! [`PairPotential::energy_and_force`](crate::interactions::PairPotential)
//! gives for the same `r^2` (the kernel sums `r^2` with fused multiply-adds,
//! so its `r^2` may differ from the scalar `norm2` in the last bit).
//! The rows run in parallel by cell layers ([`scatter_half_rows`]), each sum in
//! an order fixed by the list, so the forces do not depend on the thread count.

use super::PairTally;
use crate::interactions::LennardJones;
use crate::neighbors::{
    scatter_half_rows, shifted, squared_length, unpack, ClusterList, Lanes, LayerPlan, CLUSTER,
};
use crate::simd::F64x4;
use crate::threads::Threads;

/// What the cluster force loop reads.
pub(super) struct ClusterForces<'a, const D: usize> {
    pub(super) list: &'a ClusterList<D>,
    pub(super) layers: &'a LayerPlan,
    pub(super) potential: &'a LennardJones,
    pub(super) positions: &'a [Lanes<D>],
}

/// A mask operand for [`F64x4::zero_unless_less`]: `r^2 < limit` keeps a lane,
/// and no `r^2` is below `NO_PAIR`.
const NO_PAIR: f64 = -1.0;

/// The sums one row of the list adds to: the forces on the row's i-lanes, one
/// vector per i and axis (summed across its lanes at the end of the row), and
/// the energy and virial.
struct RowSums<const D: usize> {
    fi: [[F64x4; D]; CLUSTER],
    energy: F64x4,
    virial: F64x4,
}

impl<const D: usize> ClusterForces<'_, D> {
    /// Sets `forces` to the pair sums: `f_I = sum over row I of f_ij` (lanes of
    /// I) and `f_J -= f_ij` for every entry `J`, `f_ij = (-U'/r)(x_i - x_j)` for
    /// `r^2 < r_c^2`; with `ENERGY`, each task's (`LayerPlan`) `U` and
    /// `W = sum r^2 (-U'/r)` added to its entry of `tallies`.
    pub(super) fn run<const ENERGY: bool>(
        &self,
        forces: &mut [Lanes<D>],
        halo: &mut Vec<Lanes<D>>,
        tallies: &mut [PairTally],
        threads: &Threads,
    ) {
        let (list, positions, potential) = (self.list, self.positions, self.potential);
        let cutoff2 = potential.cutoff2();
        // above[i]: the cutoff in the lanes j > i only (a cluster's own pairs)
        let above = above_the_diagonal(cutoff2);
        scatter_half_rows(
            self.layers,
            forces,
            halo,
            tallies,
            threads,
            |rows, f, tally| {
                // copied into the task: loads through `self` would be repeated
                // after every force store, which the compiler cannot tell apart
                let (lj, shifts) = (*potential, list.image_shifts());
                for ci in rows {
                    let xi = &positions[ci];
                    // the cutoff for the cluster's real i-lanes, no pair for the rest
                    let ni = list.slots(ci).len();
                    let limits: [F64x4; CLUSTER] = std::array::from_fn(|i| {
                        F64x4::splat(if i < ni { cutoff2 } else { NO_PAIR })
                    });
                    let mut sums = RowSums {
                        fi: [[F64x4::splat(0.0); D]; CLUSTER],
                        energy: F64x4::splat(0.0),
                        virial: F64x4::splat(0.0),
                    };
                    // the pairs inside the cluster: lanes j > i of the cluster itself
                    let ghosts = list.ghost_lanes(ci);
                    let own_limits: [F64x4; CLUSTER] =
                        std::array::from_fn(|i| limits[i].min(above[i]));
                    let own_limits = without_ghost_pairs(&own_limits, ghosts, ghosts, cutoff2);
                    // an entry's limits: no pair of two ghosts
                    let limits_for = |cj: usize| {
                        without_ghost_pairs(&limits, ghosts, list.ghost_lanes(cj), cutoff2)
                    };
                    let xj = shifted(xi, &[0.0; D]);
                    // the i positions broadcast once per row
                    let xib: [[F64x4; D]; CLUSTER] =
                        std::array::from_fn(|i| std::array::from_fn(|a| F64x4::splat(xi[a][i])));
                    let f_own = Self::block::<ENERGY>(&lj, &xib, &xj, &own_limits, &mut sums);
                    // an entry's cluster and its lanes shifted by the entry's image
                    let lanes_of = |entry: u32| {
                        let (cj, image) = unpack(entry);
                        (cj, shifted(&positions[cj], &shifts[usize::from(image)]))
                    };
                    let (near, far) = list.row_parts(ci);
                    for &entry in near {
                        let (cj, xj) = lanes_of(entry);
                        let limits = limits_for(cj);
                        let fj = Self::block::<ENERGY>(&lj, &xib, &xj, &limits, &mut sums);
                        f.add(cj, &fj.map(F64x4::to_array));
                    }
                    // a block with no pair inside the limits adds only zeros:
                    // skipping it leaves every sum as it is
                    for &entry in far {
                        let (cj, xj) = lanes_of(entry);
                        let limits = limits_for(cj);
                        if any_within(&xib, &xj, &limits) {
                            let fj = Self::block::<ENERGY>(&lj, &xib, &xj, &limits, &mut sums);
                            f.add(cj, &fj.map(F64x4::to_array));
                        }
                    }
                    let own: Lanes<D> = std::array::from_fn(|a| {
                        let fj = f_own[a].to_array();
                        std::array::from_fn(|i| sums.fi[i][a].sum() + fj[i])
                    });
                    f.add(ci, &own);
                    if ENERGY {
                        tally.energy += sums.energy.sum();
                        tally.virial += sums.virial.sum();
                    }
                }
            },
        );
    }

    /// The `4 x 4` pairs of the i positions `xib` (each broadcast to four
    /// lanes) with the j-lanes `xj` under the potential `lj`: adds the i forces
    /// (and with `ENERGY` the energy and virial) to `sums`, returns the j
    /// forces. Lane `l` of pair row `i` counts where `r^2 < limits[i]_l`.
    #[inline(always)]
    fn block<const ENERGY: bool>(
        lj: &LennardJones,
        xib: &[[F64x4; D]; CLUSTER],
        xj: &[F64x4; D],
        limits: &[F64x4; CLUSTER],
        sums: &mut RowSums<D>,
    ) -> [F64x4; D] {
        let mut fj = [F64x4::splat(0.0); D];
        for (i, fi) in sums.fi.iter_mut().enumerate() {
            // -d = x_J - x_i, so that the i positions can be a memory operand
            let minus_d: [F64x4; D] = std::array::from_fn(|a| xj[a] - xib[i][a]);
            let r2 = squared_length(&minus_d);
            let (e, g) = lj.energy_and_force_lanes(r2);
            let g = g.zero_unless_less(r2, limits[i]);
            for a in 0..D {
                fi[a] = minus_d[a].neg_mul_add(g, fi[a]);
                fj[a] = minus_d[a].mul_add(g, fj[a]);
            }
            if ENERGY {
                sums.energy = sums.energy + e.zero_unless_less(r2, limits[i]);
                sums.virial = g.mul_add(r2, sums.virial);
            }
        }
        fj
    }
}

impl<const D: usize> ClusterForces<'_, D> {
    /// Per slot, half the energy `U(r)/2` and half the virial
    /// `r^2 (-U'(r)/r) / 2` of every listed pair within the cutoff it is in
    /// (LAMMPS's `pe/atom` split), four pairs at a time as the force loop forms
    /// them (the same limits, and its test that skips a block with no pair
    /// within them: such a block adds only zeros), on one thread; `energies`
    /// and `virials` (slot order) are set.
    pub(super) fn half_pair_sums(&self, energies: &mut [f64], virials: &mut [f64]) {
        energies.fill(0.0);
        virials.fill(0.0);
        let (list, positions, lj) = (self.list, self.positions, self.potential);
        let (cutoff2, half) = (lj.cutoff2(), F64x4::splat(0.5));
        let above = above_the_diagonal(cutoff2);
        let shifts = list.image_shifts();
        for ci in 0..list.num_clusters() {
            let (xi, slots) = (&positions[ci], list.slots(ci));
            let ni = slots.len();
            let limits: [F64x4; CLUSTER] =
                std::array::from_fn(|i| F64x4::splat(if i < ni { cutoff2 } else { NO_PAIR }));
            let ghosts = list.ghost_lanes(ci);
            let xib: [[F64x4; D]; CLUSTER] =
                std::array::from_fn(|i| std::array::from_fn(|a| F64x4::splat(xi[a][i])));
            // the pairs inside the cluster (lanes j > i), then the row's blocks
            let own_limits: [F64x4; CLUSTER] = std::array::from_fn(|i| limits[i].min(above[i]));
            let own = (ci, [0.0; D], own_limits);
            let entries = list.row(ci).iter().map(|&entry| {
                let (cj, image) = unpack(entry);
                (cj, shifts[usize::from(image)], limits)
            });
            for (cj, shift, limits) in std::iter::once(own).chain(entries) {
                let xj = shifted(&positions[cj], &shift);
                let limits = without_ghost_pairs(&limits, ghosts, list.ghost_lanes(cj), cutoff2);
                if !any_within(&xib, &xj, &limits) {
                    continue;
                }
                let (mut ej, mut wj) = ([0.0; CLUSTER], [0.0; CLUSTER]);
                for (i, slot) in slots.clone().enumerate() {
                    let minus_d: [F64x4; D] = std::array::from_fn(|a| xj[a] - xib[i][a]);
                    let r2 = squared_length(&minus_d);
                    let (e, g) = lj.energy_and_force_lanes(r2);
                    let e = (e * half).zero_unless_less(r2, limits[i]).to_array();
                    let w = (g * r2 * half).zero_unless_less(r2, limits[i]).to_array();
                    energies[slot] += e.iter().sum::<f64>();
                    virials[slot] += w.iter().sum::<f64>();
                    for l in 0..CLUSTER {
                        ej[l] += e[l];
                        wj[l] += w[l];
                    }
                }
                for (l, slot) in list.slots(cj).enumerate() {
                    energies[slot] += ej[l];
                    virials[slot] += wj[l];
                }
            }
        }
    }
}

/// `above[i]`: the cutoff `r_c^2` in the lanes `j > i` only, [`NO_PAIR`] in
/// the others (the pairs of a cluster with itself).
fn above_the_diagonal(cutoff2: f64) -> [F64x4; CLUSTER] {
    std::array::from_fn(|i| {
        let lanes: [f64; CLUSTER] = std::array::from_fn(|l| if l > i { cutoff2 } else { NO_PAIR });
        F64x4::load(&lanes)
    })
}

/// `limits` (per i-lane) without the pairs of two ghosts: for a ghost lane
/// `i` of the row's cluster (bit `i` of `ghosts_i`), no pair with a ghost
/// lane of the entry's (`ghosts_j`). Without ghosts in the row's cluster (every
/// list of a single process) the limits as they are.
#[inline(always)]
fn without_ghost_pairs(
    limits: &[F64x4; CLUSTER],
    ghosts_i: u8,
    ghosts_j: u8,
    cutoff2: f64,
) -> [F64x4; CLUSTER] {
    if ghosts_i == 0 {
        return *limits;
    }
    let own_j: [f64; CLUSTER] = std::array::from_fn(|l| {
        if ghosts_j >> l & 1 == 1 {
            NO_PAIR
        } else {
            cutoff2
        }
    });
    let own_j = F64x4::load(&own_j);
    std::array::from_fn(|i| {
        if ghosts_i >> i & 1 == 1 {
            limits[i].min(own_j)
        } else {
            limits[i]
        }
    })
}

/// Whether some pair of the block of `xib` and `xj` counts: `r^2 < limits[i]`
/// in some lane of some row `i`, with `r^2` formed as the block forms it.
#[inline(always)]
fn any_within<const D: usize>(
    xib: &[[F64x4; D]; CLUSTER],
    xj: &[F64x4; D],
    limits: &[F64x4; CLUSTER],
) -> bool {
    let inside = xib.iter().zip(limits).fold(0, |inside, (xi, limit)| {
        let minus_d: [F64x4; D] = std::array::from_fn(|a| xj[a] - xi[a]);
        inside | F64x4::mask_less(squared_length(&minus_d), *limit)
    });
    inside != 0
}

#[cfg(test)]
mod tests {
    use super::super::{
        create_velocities, lattice, Atoms, Integrator, LatticeKind, MdSystem, PairTally,
        StageTimes, VelocityDistribution,
    };
    use crate::geometry::{norm2, Domain};
    use crate::interactions::{LennardJones, PairPotential};
    use crate::neighbors::{brute_force_pairs, unpack, RebuildRule};
    use crate::random::Rng;
    use crate::threads::Threads;

    /// A hot, jittered fcc crystal run four steps without a rebuild (every
    /// atom still within skin/2 of its build position): some entries of the
    /// rows' second parts, which had no pair within the cutoff at the build,
    /// now hold one. The forces, energy and virial equal the brute-force sums
    /// over all pairs at the moved positions, the forces are the same bits on
    /// 1 and 2 threads, and all of them are the same bits as when every block
    /// is computed without the test.
    #[test]
    fn entries_that_come_within_the_cutoff_after_the_build_are_summed() {
        let (domain, points) = jittered_fcc(4, 7);
        let lj = LennardJones::new(1.0, 1.0, 2.5, false).unwrap();
        let run = |threads: &Threads| {
            let mut atoms = Atoms::at_rest(points.clone(), 1.0);
            create_velocities(&mut atoms, 3.0, 5, VelocityDistribution::Uniform);
            let mut system = MdSystem::new(domain, atoms, lj, 0.3, threads).unwrap();
            system.set_rebuild_rule(RebuildRule {
                every: 1000,
                check: false,
            });
            let mut times = StageTimes::default();
            for step in 1..=4 {
                let verlet = &Integrator::VelocityVerlet;
                system
                    .step(verlet, 0.005, step, false, threads, &mut times)
                    .unwrap();
            }
            system
        };
        let mut system = run(&Threads::single());
        assert_eq!(
            system.atoms.forces,
            run(&Threads::new(2).unwrap()).atoms.forces
        );
        assert_eq!(system.rebuilds(), 0);
        let (list, x) = (&system.pairs.list, &system.atoms.positions.clone());
        assert!(
            !list.needs_rebuild(&system.pairs.cells, x),
            "an atom moved beyond skin/2"
        );
        let came_within = (0..list.num_clusters()).any(|c| {
            list.row_parts(c).1.iter().any(|&entry| {
                let (other, image) = unpack(entry);
                let shift = list.image_shift(image);
                list.slots(c).any(|i| {
                    list.slots(other).any(|j| {
                        let d: [f64; 3] = std::array::from_fn(|a| x[i][a] - (x[j][a] + shift[a]));
                        norm2(&d) < lj.cutoff2()
                    })
                })
            })
        });
        assert!(
            came_within,
            "no far entry came within the cutoff: the test tests nothing"
        );
        let tested = assert_brute_force_sums(&mut system, &domain, &lj);
        let threads = Threads::single();
        let bits = |f: &[[f64; 3]]| f.iter().flatten().map(|c| c.to_bits()).collect::<Vec<_>>();
        let forces = bits(&system.atoms.forces);
        system.pairs.list.without_far_parts();
        system.compute_forces(true, &threads);
        assert_eq!(bits(&system.atoms.forces), forces);
        let all = system.pair_totals().unwrap();
        assert_eq!(all.energy.to_bits(), tested.energy.to_bits());
        assert_eq!(all.virial.to_bits(), tested.virial.to_bits());
    }

    /// Seven fcc cells a side at the melt's density make three cell layers:
    /// an odd number, so the middle layer's rows run as two tasks, the second
    /// summing into an array of its own (`LayerPlan`). The forces, energy and
    /// virial are the brute-force sums, and the same bits on 1, 2 and 3
    /// threads.
    #[test]
    fn a_layer_cut_in_two_gives_the_brute_force_sums_on_any_thread_count() {
        let (domain, points) = jittered_fcc(7, 11);
        let lj = LennardJones::new(1.0, 1.0, 2.5, false).unwrap();
        let build = |threads: &Threads| {
            let atoms = Atoms::at_rest(points.clone(), 1.0);
            MdSystem::new(domain, atoms, lj, 0.3, threads).unwrap()
        };
        let mut system = build(&Threads::single());
        assert_eq!(system.pairs.layers.num_layers(), 3);
        assert_eq!(system.pairs.layers.num_tasks(), 4);
        let bits = |system: &MdSystem<3>| {
            let totals = system.pair_totals().unwrap();
            let forces = system.atoms.forces.iter().flatten();
            let totals = [totals.energy, totals.virial];
            forces
                .chain(&totals)
                .map(|c| c.to_bits())
                .collect::<Vec<_>>()
        };
        for n in [2, 3] {
            let other = build(&Threads::new(n).unwrap());
            assert_eq!(bits(&system), bits(&other), "{n} threads");
        }
        assert_brute_force_sums(&mut system, &domain, &lj);
    }

    /// An fcc crystal of `cells` unit cells a side at the melt's density, each
    /// atom moved by up to 0.15 per axis (`seed`), so that the pair distances
    /// spread across the cutoff.
    fn jittered_fcc(cells: usize, seed: u64) -> (Domain<3>, Vec<[f64; 3]>) {
        let (domain, mut points) = lattice(LatticeKind::Fcc, 0.8442, [cells; 3]).unwrap();
        let mut rng = Rng::new(seed);
        for x in &mut points {
            *x = domain.wrap(x.map(|c| c + 0.3 * (rng.uniform() - 0.5)));
        }
        (domain, points)
    }

    /// Asserts that `system`'s forces (as they are) and its energy and virial
    /// (evaluated again, on one thread) are the brute-force sums over all pairs
    /// within the cutoff, to 1e-12; returns the evaluated totals.
    fn assert_brute_force_sums(
        system: &mut MdSystem<3>,
        domain: &Domain<3>,
        lj: &LennardJones,
    ) -> PairTally {
        let x = &system.atoms.positions.clone();
        let (mut want, mut energy, mut virial) = (vec![[0.0; 3]; x.len()], 0.0, 0.0);
        for (i, j, _) in brute_force_pairs(domain, lj.cutoff(), x) {
            let (i, j) = (i as usize, j as usize);
            let x_ji = domain.separation(&x[i], &x[j]);
            let r2 = norm2(&x_ji);
            let (e, g) = lj.energy_and_force(r2);
            energy += e;
            virial += r2 * g;
            for a in 0..3 {
                want[i][a] -= g * x_ji[a];
                want[j][a] += g * x_ji[a];
            }
        }
        let scale = want.iter().map(|f| norm2(f).sqrt()).sum::<f64>() / want.len() as f64;
        for (k, (got, want)) in system.atoms.forces.iter().zip(&want).enumerate() {
            for a in 0..3 {
                assert!(
                    (got[a] - want[a]).abs() <= 1e-12 * scale,
                    "slot {k} axis {a}"
                );
            }
        }
        system.compute_forces(true, &Threads::single());
        let tested = system.pair_totals().unwrap();
        assert!((tested.energy - energy).abs() <= 1e-12 * energy.abs());
        assert!((tested.virial - virial).abs() <= 1e-12 * virial.abs());
        tested
    }
}
