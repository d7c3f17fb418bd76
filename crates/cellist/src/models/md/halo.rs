//! The forces of one subdomain's pairs in a distributed run, each pair across
//! the ranks computed once: a half cluster pair list ([`ClusterPairs`]) over
//! the own atoms and the ghosts (copies of the atoms of the neighbouring ranks
//! of one half of the directions, [`Images::HalfShell`](crate::decomposition::Images),
//! within cutoff + skin of the subdomain), binned in a box that is periodic
//! along the axes the decomposition does not cut, so that a rank sees its own
//! atoms' images there without ghosts:
//!
//! ```text
//! f_k = sum_{j listed with k, r_kj < r_c} f_kj     (own and ghost k; Newton's third law)
//! u_k = (1/2) sum_j U(r_kj),   w_k = (1/2) sum_j r_kj^2 (-U'(r_kj)/r_kj)
//! ```
//!
//! A pair of two own atoms is computed once; a pair of an own atom and a ghost
//! once, on the one rank that holds the ghost, whose reaction (and half energy
//! and virial) the caller sends back to the ghost's owner (reverse
//! communication); ghost-ghost pairs are not computed (whole ghost clusters
//! get no entry for each other, and the kernel masks the ghost-ghost lanes of
//! the clusters that mix own atoms and ghosts: the cells along a cut axis end
//! at the subdomain's faces, so that only atoms on a face, or ghosts of a
//! diagonal neighbour, make such clusters). The sums run in the list's order,
//! which follows the cells of the subdomain: the forces agree with a
//! single-process run to rounding, not to the bit.

use super::cluster_pairs::ClusterPairs;
use super::PairTally;
use crate::decomposition::Subdomain;
use crate::geometry::{Boundary, Domain, GeometryError};
use crate::interactions::{LennardJones, PairPotential};
use crate::neighbors::{moved_beyond_half_skin, CellGrid, CellList, CLUSTER};
use crate::threads::Threads;

/// The pair list of one subdomain's own atoms and ghosts, built at a
/// neighbour-list rebuild and used until the next.
pub struct HaloForces<const D: usize> {
    pairs: ClusterPairs<D>,
    potential: LennardJones,
    skin: f64,
    owned: usize,
    reference: Vec<[f64; D]>,
    /// Per slot, the half energies and virials of the last pass with
    /// per-atom energies (kept, so that a step allocates nothing).
    energies: Vec<f64>,
    virials: Vec<f64>,
}

impl<const D: usize> HaloForces<D> {
    /// The list of `points` (the `owned` own atoms first, then the ghosts at
    /// their images next to `subdomain`), of reach `cutoff + skin`, binned in
    /// the cells of `halo_cells` for `share` atoms in the subdomain (the mean
    /// own atoms per rank, `N / P`: cells that followed the own count, which
    /// changes at every migration, would flip between two sizes when a side
    /// sits at a threshold, as the fcc lattice's does, and then differ
    /// between the ranks and cost fresh builds).
    pub fn build(
        subdomain: &Subdomain<D>,
        points: &[[f64; D]],
        owned: usize,
        share: usize,
        potential: LennardJones,
        skin: f64,
        threads: &Threads,
    ) -> Result<Self, GeometryError> {
        assert!(owned <= points.len());
        let cutoff = potential.cutoff();
        let (domain, grid, side) = halo_cells(subdomain, share, cutoff + skin)?;
        let cells = CellList::build_on_grid(&domain, grid, side, points, Some(threads));
        let pairs = ClusterPairs::from_cells(cells, owned, cutoff, skin, threads);
        Ok(HaloForces {
            pairs,
            potential,
            skin,
            owned,
            reference: points[..owned].to_vec(),
            energies: Vec::new(),
            virials: Vec::new(),
        })
    }

    /// Builds the list of new `points` (the first `owned` own) again in
    /// place when they bin in the cells of the last build (`halo_cells` of
    /// the same subdomain and `share`): the list of [`HaloForces::build`],
    /// with the buffers of the last build kept (no allocation once they have
    /// grown). `Ok(false)`, and nothing changed, when the cells differ.
    pub fn rebuild(
        &mut self,
        subdomain: &Subdomain<D>,
        points: &[[f64; D]],
        owned: usize,
        share: usize,
        threads: &Threads,
    ) -> Result<bool, GeometryError> {
        assert!(owned <= points.len());
        let (domain, grid, side) =
            halo_cells(subdomain, share, self.potential.cutoff() + self.skin)?;
        if !self.pairs.cells.is_on(&domain, &grid, side) {
            return Ok(false);
        }
        self.pairs.rebin(points, threads);
        self.pairs.build_list(owned, threads);
        self.owned = owned;
        self.reference.clear();
        self.reference.extend_from_slice(&points[..owned]);
        Ok(true)
    }

    /// Renumbers the own points in the order of their slots
    /// ([`CellList::renumber_first`]) and returns each new number's former
    /// one, `former`: the caller stores its own atoms in that order
    /// (`new[i] = old[former[i]]`), so that neighbours lie close in memory,
    /// the list's reads and writes of the own atoms run in order, and the
    /// next build bins atoms nearly sorted already. The ghosts keep their
    /// numbers; the list, its sums and their bits do not change.
    /// The reference positions are reordered through `buffer` (lent by the
    /// caller: no allocation once it has grown).
    pub fn own_in_slot_order(&mut self, buffer: &mut Vec<[f64; D]>) -> Vec<u32> {
        let former = self.pairs.cells.renumber_first(self.owned);
        buffer.clear();
        buffer.extend(former.iter().map(|&k| self.reference[k as usize]));
        self.reference.copy_from_slice(buffer);
        former
    }

    /// The own atoms' positions at the build (the reference of the skin/2
    /// test).
    pub fn reference(&self) -> &[[f64; D]] {
        &self.reference
    }

    /// True when an own atom has moved more than `skin / 2` since the build.
    pub fn needs_rebuild(&self, owned: &[[f64; D]]) -> bool {
        moved_beyond_half_skin(owned, &self.reference, self.skin)
    }

    /// The point (own atoms first, then ghosts) each slot of the list holds.
    fn order(&self) -> &[u32] {
        self.pairs.cells.order()
    }

    /// The pair sums at the own atoms' positions `own` and the ghosts'
    /// `ghosts` (in the list's numbering: the build's, or the one
    /// [`HaloForces::own_in_slot_order`] made; each within skin/2 of its
    /// build position): `forces[k]`, the force on own atom `k`; per ghost
    /// `g`, its reaction (the sum of the pairs this rank computed with it, to
    /// be sent to its owner) at `reactions[w g..w g + D]`. With
    /// [`HaloSums::Totals`] or [`HaloSums::PerAtom`], returns the energy
    /// `U = sum U(r_kj)` and virial `W = sum r_kj^2 (-U'(r_kj)/r_kj)` of the
    /// pairs this rank computed (each pair of the system on one rank only:
    /// summed over the ranks, the system's); with [`HaloSums::PerAtom`],
    /// also each own atom's half energy and half virial (half of each of its
    /// listed pairs') in its slice at `k`, and each ghost's after its reaction
    /// (`w = D + 2`); otherwise `w = D`.
    pub fn forces(
        &mut self,
        own: &[[f64; D]],
        ghosts: &[[f64; D]],
        threads: &Threads,
        forces: &mut [[f64; D]],
        reactions: &mut [f64],
        sums: HaloSums<'_>,
    ) -> Option<PairTally> {
        let n = self.owned;
        assert!(own.len() == n && forces.len() == n);
        let (energy, width) = match &sums {
            HaloSums::Forces => (false, D),
            HaloSums::Totals => (true, D),
            HaloSums::PerAtom(energies) => {
                assert_eq!(energies.len(), n);
                (true, D + 2)
            }
        };
        assert_eq!(reactions.len(), width * ghosts.len());
        let position = |k: usize| if k < n { own[k] } else { ghosts[k - n] };
        let totals =
            self.pairs
                .forces_by_point(&self.potential, position, energy, threads, |k, f| {
                    if k < n {
                        forces[k] = f;
                    } else {
                        reactions[width * (k - n)..][..D].copy_from_slice(&f);
                    }
                });
        if let HaloSums::PerAtom(energies) = sums {
            let points = n + ghosts.len();
            self.energies.resize(points, 0.0);
            self.virials.resize(points, 0.0);
            self.pairs
                .half_pair_sums(&self.potential, &mut self.energies, &mut self.virials);
            for (slot, &k) in self.pairs.cells.order().iter().enumerate() {
                let (k, halves) = (k as usize, [self.energies[slot], self.virials[slot]]);
                if k < n {
                    energies[k] = halves;
                } else {
                    reactions[width * (k - n) + D..][..2].copy_from_slice(&halves);
                }
            }
        }
        totals
    }

    /// The first pair of an own atom and a neighbour at one position, as
    /// `(smaller id, larger id)` (`ids` in the build's order).
    pub fn coincident(&self, points: &[[f64; D]], ids: &[u64]) -> Option<(u64, u64)> {
        let order = self.order();
        let slotted: Vec<[f64; D]> = order.iter().map(|&k| points[k as usize]).collect();
        let mut twin = None;
        self.pairs.list.for_each_pair(&slotted, |i, j, _, r2| {
            let (a, b) = (order[i] as usize, order[j] as usize);
            if r2 == 0.0 && twin.is_none() && (a < self.owned || b < self.owned) {
                twin = Some((ids[a].min(ids[b]), ids[a].max(ids[b])));
            }
        });
        twin
    }
}

/// What a force pass of [`HaloForces::forces`] sums beyond the forces.
pub enum HaloSums<'a> {
    /// The forces alone (a plain step).
    Forces,
    /// Also the energy and virial of the pairs the rank computes (an observed
    /// step's thermo).
    Totals,
    /// The totals, and the own atoms' half energies and half virials, one
    /// `[u_k, w_k]` per own atom (a dump with energy columns).
    PerAtom(&'a mut [[f64; 2]]),
}

/// The cells a subdomain's own atoms and ghosts are binned in, and their
/// least side: the side `s` of a single-process cluster list at the
/// density of `share` atoms in the subdomain, `2 (CLUSTER V / share)^(1/D)`
/// and at least `reach`
/// ([`ClusterList::cell_side`](crate::neighbors::ClusterList::cell_side)),
/// periodic along the uncut axes (the box's cells of at least `s`), and
/// along a cut axis of width `w` open with `k = max(1, floor(w / s))` cells
/// of `c = w / k` inside the subdomain (as many of at least `s` as fit, like
/// the uncut axes and a single-process list) and `m = ceil(reach / c)` more
/// on each side for the ghosts (one, for a subdomain at least `reach` wide):
/// the faces between subdomains are faces between cells, so that few
/// clusters mix own atoms and ghosts (atoms on a face may round into the cell
/// beyond it). Sized for the mean density, a crowded subdomain of uneven
/// atoms under equal cuts gets larger cells than its own density would
/// (more pairs tested per cluster; balanced cuts give it a smaller volume).
fn halo_cells<const D: usize>(
    subdomain: &Subdomain<D>,
    share: usize,
    reach: f64,
) -> Result<(Domain<D>, CellGrid<D>, f64), GeometryError> {
    let Subdomain {
        domain: whole,
        lo,
        hi,
        cut,
    } = *subdomain;
    let width: [f64; D] = std::array::from_fn(|d| hi[d] - lo[d]);
    let volume: f64 = width.iter().product();
    let periodic = |d: usize| !cut[d] && whole.is_periodic(d);
    let widest = (0..D)
        .filter(|&d| periodic(d))
        .map(|d| 0.5 * whole.length[d] * (1.0 - 1e-9))
        .fold(f64::INFINITY, f64::min);
    let side = (2.0 * (CLUSTER as f64 * volume / share.max(1) as f64).powf(1.0 / D as f64))
        .min(widest)
        .max(reach);
    let mut domain = whole;
    let mut dims = [1; D];
    for d in 0..D {
        if cut[d] {
            // as many cells of at least `side` (itself at least `reach`) as fit
            let inside = CellGrid::<D>::cells_along(width[d], side);
            let c = width[d] / inside as f64;
            let ghost_cells = (reach / c).ceil() as usize;
            dims[d] = inside + 2 * ghost_cells;
            domain.lo[d] = lo[d] - ghost_cells as f64 * c;
            domain.length[d] = dims[d] as f64 * c;
            domain.boundary[d] = Boundary::Open;
        } else {
            dims[d] = CellGrid::<D>::cells_along(whole.length[d], side);
        }
    }
    let least = (0..D)
        .map(|d| domain.length[d] / dims[d] as f64)
        .fold(side, f64::min);
    let grid = CellGrid::with_dims(&domain, dims, least)?;
    Ok((domain, grid, least))
}

#[cfg(test)]
mod tests {
    use super::super::AtomForce;
    use super::*;
    use crate::decomposition::{Balance, Decomposition, Images};
    use crate::geometry::norm2;
    use crate::geometry::Boundary;
    use crate::neighbors::brute_force_pairs;
    use crate::random::Rng;

    /// Every rank of a decomposition played in one process: each builds its
    /// list over its own atoms and its half-shell ghosts, the ghosts'
    /// reactions, half energies and half virials go back to their owners, and
    /// every atom's force, energy and virial, and the ranks' pair energy and
    /// virial added up, are the brute-force sums over all pairs (minimum image), for slabs, a 2 x 2 cut (3D) and a 3 x 2 cut (2D),
    /// on 1 and 2 threads alike; also with a box open along the cut axis and
    /// with balanced planes for atoms crowded towards one end. The atoms
    /// include some on the faces between subdomains (where a cell could take
    /// an own atom for a ghost).
    #[test]
    fn ranks_with_returned_reactions_give_the_brute_force_sums() {
        let cube = |l: [f64; 3]| Domain::periodic(l).unwrap();
        check(cube([9.0, 8.5, 8.0]), 2, 300, 1, Balance::Uniform);
        check(cube([9.0, 8.5, 8.0]), 3, 300, 2, Balance::Uniform);
        check(cube([9.0, 8.5, 8.0]), 4, 300, 3, Balance::Uniform);
        check(
            Domain::periodic([12.0, 9.0]).unwrap(),
            6,
            70,
            4,
            Balance::Uniform,
        );
        let open_x = [Boundary::Open, Boundary::Periodic, Boundary::Periodic];
        let open = Domain::new([11.0, 8.5, 8.0], open_x).unwrap();
        check(open, 3, 300, 5, Balance::Uniform);
        check(cube([12.0, 8.5, 8.0]), 3, 300, 6, Balance::Rcb);
    }

    /// Every point's sums from [`HaloForces::forces`] with energies: an own
    /// atom's force, half energy and half virial, a ghost's reaction and its
    /// halves; and the energy and virial of the rank's pairs. The forces and
    /// reactions with the totals alone or without energies are the same bits,
    /// and so are the totals with and without the per-atom halves.
    fn sums_by_point<const D: usize>(
        halo: &mut HaloForces<D>,
        points: &[[f64; D]],
        owned: usize,
        threads: &Threads,
    ) -> (Vec<AtomForce<D>>, PairTally) {
        let (own, ghosts) = points.split_at(owned);
        let mut forces = vec![[0.0; D]; owned];
        let mut reactions = vec![0.0; (D + 2) * ghosts.len()];
        let mut energies = vec![[0.0; 2]; owned];
        let with = HaloSums::PerAtom(&mut energies[..]);
        let totals = halo.forces(own, ghosts, threads, &mut forces, &mut reactions, with);
        let totals = totals.expect("totals with the per-atom halves");
        for sums in [HaloSums::Totals, HaloSums::Forces] {
            let wanted = matches!(sums, HaloSums::Totals);
            let mut bare_forces = vec![[0.0; D]; owned];
            let mut bare_reactions = vec![0.0; D * ghosts.len()];
            let bare_totals = halo.forces(
                own,
                ghosts,
                threads,
                &mut bare_forces,
                &mut bare_reactions,
                sums,
            );
            assert_eq!(bare_totals, wanted.then_some(totals));
            assert_eq!(bare_forces, forces);
            let reaction_forces = reactions.chunks_exact(D + 2).flat_map(|r| &r[..D]);
            assert!(bare_reactions.iter().eq(reaction_forces));
        }
        let own = forces.iter().zip(&energies).map(|(f, e)| AtomForce {
            force: *f,
            energy: e[0],
            virial: e[1],
        });
        let ghosts = reactions.chunks_exact(D + 2).map(|r| AtomForce {
            force: std::array::from_fn(|a| r[a]),
            energy: r[D],
            virial: r[D + 1],
        });
        (own.chain(ghosts).collect(), totals)
    }

    fn check<const D: usize>(
        domain: Domain<D>,
        ranks: usize,
        n: usize,
        seed: u64,
        balance: Balance,
    ) {
        let length = domain.length;
        let lj = LennardJones::new(1.0, 1.0, 1.5, false).unwrap();
        let skin = 0.3;
        let reach = lj.cutoff() + skin;
        let mut rng = Rng::new(seed);
        // with Rcb, the atoms crowd towards the lower x (u^2 spreads them)
        let crowd = |u: f64| if balance == Balance::Rcb { u * u } else { u };
        let mut points: Vec<[f64; D]> = Vec::new();
        let equal = Decomposition::new(domain, ranks);
        while points.len() < n {
            let mut x: [f64; D] = std::array::from_fn(|d| rng.uniform() * length[d]);
            x[0] = crowd(x[0] / length[0]) * length[0];
            if points.len().is_multiple_of(50) && balance == Balance::Uniform {
                x[0] = equal.bounds(0).1[0];
            }
            // no two atoms closer than 0.8: finite forces
            let close = points
                .iter()
                .any(|y| norm2(&domain.separation(&x, y)) < 0.64);
            if !close {
                points.push(x);
            }
        }
        let decomposition =
            Decomposition::for_particles(domain, ranks, balance, &points, reach).unwrap();
        decomposition.check_reach(reach).unwrap();
        if balance == Balance::Rcb {
            assert_ne!(decomposition, equal, "the planes did not move");
        }
        let owner: Vec<usize> = points.iter().map(|x| decomposition.owner(x)).collect();
        let share = n / ranks;
        let mut got = vec![AtomForce::<D>::default(); n];
        let mut got_totals = PairTally::default();
        for threads in [Threads::single(), Threads::new(2).unwrap()] {
            let mut sums = vec![AtomForce::<D>::default(); n];
            let mut totals = PairTally::default();
            for rank in 0..ranks {
                let mine: Vec<usize> = (0..n).filter(|&k| owner[k] == rank).collect();
                let own: Vec<[f64; D]> = mine.iter().map(|&k| points[k]).collect();
                let mut all = own.clone();
                let mut from = mine.clone();
                for sender in 0..ranks {
                    let theirs: Vec<usize> = (0..n).filter(|&k| owner[k] == sender).collect();
                    let at: Vec<[f64; D]> = theirs.iter().map(|&k| points[k]).collect();
                    let ghosts = decomposition.ghosts(sender, &at, reach, Images::HalfShell);
                    for g in ghosts.iter().filter(|g| g.to == rank) {
                        all.push(std::array::from_fn(|d| at[g.index][d] + g.shift[d]));
                        from.push(theirs[g.index]);
                    }
                }
                let subdomain = decomposition.subdomain(rank);
                let mut halo =
                    HaloForces::build(&subdomain, &all, own.len(), share, lj, skin, &threads)
                        .unwrap();
                let (out, rank_totals) = sums_by_point(&mut halo, &all, own.len(), &threads);
                totals.energy += rank_totals.energy;
                totals.virial += rank_totals.virial;
                // a list of other positions rebuilt in place for these gives
                // the fresh list's sums, bit for bit
                let moved: Vec<[f64; D]> = all.iter().map(|x| x.map(|c| c + 0.05)).collect();
                let mut again =
                    HaloForces::build(&subdomain, &moved, own.len(), share, lj, skin, &threads)
                        .unwrap();
                let in_place = again.rebuild(&subdomain, &all, own.len(), share, &threads);
                assert_eq!(in_place, Ok(true), "the cells changed");
                let out_again = sums_by_point(&mut again, &all, own.len(), &threads);
                assert_eq!(out_again, (out.clone(), rank_totals), "rebuilt in place");
                // the own atoms stored in slot order: the same sums, bit for
                // bit, each at its atom's new number; the ghosts' unchanged
                let former = again.own_in_slot_order(&mut Vec::new());
                assert!(former.iter().enumerate().any(|(i, &k)| k as usize != i));
                let mut renumbered = all.clone();
                for (i, &k) in former.iter().enumerate() {
                    renumbered[i] = all[k as usize];
                }
                assert_eq!(again.reference(), &renumbered[..own.len()]);
                let (out_renumbered, renumbered_totals) =
                    sums_by_point(&mut again, &renumbered, own.len(), &threads);
                assert_eq!(renumbered_totals, rank_totals);
                for (i, &k) in former.iter().enumerate() {
                    assert_eq!(
                        out_renumbered[i], out[k as usize],
                        "own atom {k} renumbered {i}"
                    );
                }
                assert_eq!(out_renumbered[own.len()..], out[own.len()..]);
                // a fresh list of the atoms stored so holds the same pairs in
                // the same slots (no two atoms tie in a cell's columns here)
                let mut fresh = HaloForces::build(
                    &subdomain,
                    &renumbered,
                    own.len(),
                    share,
                    lj,
                    skin,
                    &threads,
                )
                .unwrap();
                let out_fresh = sums_by_point(&mut fresh, &renumbered, own.len(), &threads);
                assert_eq!(
                    out_fresh,
                    (out_renumbered, rank_totals),
                    "a fresh list of the renumbered atoms"
                );
                for (k, o) in from.iter().zip(&out) {
                    let s = &mut sums[*k];
                    for d in 0..D {
                        s.force[d] += o.force[d];
                    }
                    s.energy += o.energy;
                    s.virial += o.virial;
                }
            }
            if threads.count() == 1 {
                (got, got_totals) = (sums, totals);
            } else {
                assert_eq!((&got, got_totals), (&sums, totals), "1 and 2 threads");
            }
        }
        let mut want = vec![AtomForce::<D>::default(); n];
        let mut want_totals = PairTally::default();
        for (i, j, _) in brute_force_pairs(&domain, lj.cutoff(), &points) {
            let (i, j) = (i as usize, j as usize);
            let d = domain.separation(&points[j], &points[i]);
            let r2 = norm2(&d);
            let (e, g) = lj.energy_and_force(r2);
            want_totals.energy += e;
            want_totals.virial += g * r2;
            for (k, sign) in [(i, 1.0), (j, -1.0)] {
                for a in 0..D {
                    want[k].force[a] += sign * g * d[a];
                }
                want[k].energy += 0.5 * e;
                want[k].virial += 0.5 * g * r2;
            }
        }
        for k in 0..n {
            let scale = 1.0 + norm2(&want[k].force).sqrt();
            for a in 0..D {
                let diff = (got[k].force[a] - want[k].force[a]).abs();
                assert!(diff <= 1e-10 * scale, "atom {k} axis {a}: {diff:e}");
            }
            assert!((got[k].energy - want[k].energy).abs() <= 1e-12 * (1.0 + want[k].energy.abs()));
            assert!((got[k].virial - want[k].virial).abs() <= 1e-10 * (1.0 + want[k].virial.abs()));
        }
        // the ranks' totals: each pair of the system once
        let scale = 1.0 + want_totals.energy.abs();
        assert!((got_totals.energy - want_totals.energy).abs() <= 1e-11 * scale);
        let scale = 1.0 + want_totals.virial.abs();
        assert!((got_totals.virial - want_totals.virial).abs() <= 1e-10 * scale);
    }
}
