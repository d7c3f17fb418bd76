//! The forces of one subdomain's atoms in a domain-decomposed run, over the
//! id-sorted full rows of [`OrderedRows`]:
//!
//! ```text
//! f_i = sum_{j in row(i), ascending id_j} f_ij,   f_ij = (-U'(r)/r) (x_i - x_j),   r < r_c
//! u_i = (1/2) sum_j U(r_ij),   w_i = (1/2) sum_j r_ij . f_ij
//! ```
//!
//! The order of every sum is fixed by the ids, so a run gives the same bits on
//! any number of ranks and threads; the total energy and virial are the sums of
//! `u_i` and `w_i`.

use crate::geometry::norm2;
use crate::interactions::PairPotential;
use crate::neighbors::OrderedRows;
use crate::threads::Threads;

/// Entries of a row handled together by the pair loop: gathered, then computed
/// in straight-line (vectorisable) code, then scattered.
const PAIR_BLOCK: usize = 16;

/// One block of a row: separations `d = x_i - (x_j + shift)` by axis, then the pair
/// force components and, for the energy, `U` and `-U'/r`.
struct PairBlock<const D: usize> {
    d: [[f64; PAIR_BLOCK]; D],
    f: [[f64; PAIR_BLOCK]; D],
    energy: [f64; PAIR_BLOCK],
    f_over_r: [f64; PAIR_BLOCK],
    r2: [f64; PAIR_BLOCK],
}

impl<const D: usize> PairBlock<D> {
    /// From the separations `d`: `r^2`, `U`, `-U'/r` and the pair forces
    /// `f = d (-U'/r)`, branch-free (vectorisable): entries at or beyond the
    /// cutoff get `-U'/r = 0`, so exact zero forces.
    #[inline(always)]
    fn compute<P: PairPotential>(&mut self, potential: &P, cutoff2: f64) {
        for k in 0..PAIR_BLOCK {
            let d: [f64; D] = std::array::from_fn(|a| self.d[a][k]);
            let r2 = norm2(&d);
            let (e, f_over_r) = potential.energy_and_force(r2);
            let f_over_r = if r2 < cutoff2 { f_over_r } else { 0.0 };
            for a in 0..D {
                self.f[a][k] = d[a] * f_over_r;
            }
            self.energy[k] = e;
            self.f_over_r[k] = f_over_r;
            self.r2[k] = r2;
        }
    }
}

impl<const D: usize> Default for PairBlock<D> {
    fn default() -> Self {
        // the lanes beyond a short block are computed but never scattered; start
        // them at a finite, nonzero separation
        PairBlock {
            d: [[1.0; PAIR_BLOCK]; D],
            f: [[0.0; PAIR_BLOCK]; D],
            energy: [0.0; PAIR_BLOCK],
            f_over_r: [0.0; PAIR_BLOCK],
            r2: [0.0; PAIR_BLOCK],
        }
    }
}

/// One owned atom's force, half pair energy and half virial.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AtomForce<const D: usize> {
    /// `f_i`.
    pub force: [f64; D],
    /// `u_i`.
    pub energy: f64,
    /// `w_i`.
    pub virial: f64,
}

impl<const D: usize> Default for AtomForce<D> {
    fn default() -> Self {
        AtomForce {
            force: [0.0; D],
            energy: 0.0,
            virial: 0.0,
        }
    }
}

/// The force of every owned atom (`out[i]`), with `ENERGY` its half energy and
/// half virial too (zero without), from `points` (owned then ghosts, in the
/// order the rows were built for, at their positions now), in parallel, each
/// atom's sum in row order.
pub fn ordered_forces<const ENERGY: bool, const D: usize, P: PairPotential + Sync>(
    rows: &OrderedRows<D>,
    potential: &P,
    points: &[[f64; D]],
    out: &mut [AtomForce<D>],
    threads: &Threads,
) {
    let cutoff2 = potential.cutoff() * potential.cutoff();
    rows.map(out, threads, |i| {
        let xi = points[i];
        let mut a = AtomForce::default();
        let mut b = PairBlock::<D>::default();
        for block in rows.row(i).chunks(PAIR_BLOCK) {
            for (k, &j) in block.iter().enumerate() {
                let xj = &points[j as usize];
                for c in 0..D {
                    b.d[c][k] = xi[c] - xj[c];
                }
            }
            b.compute(potential, cutoff2);
            // the sums in row order: entries beyond the cutoff add exact zeros
            for k in 0..block.len() {
                for c in 0..D {
                    a.force[c] += b.f[c][k];
                }
                if ENERGY {
                    let half = if b.r2[k] < cutoff2 { 0.5 } else { 0.0 };
                    a.energy += half * b.energy[k];
                    a.virial += 0.5 * b.f_over_r[k] * b.r2[k];
                }
            }
        }
        a
    });
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::interactions::LennardJones;
    use crate::random::Rng;

    /// Every owned atom's force against a brute-force sum over all points, and
    /// the same bits for 1 and 2 threads and for the points in another order.
    #[test]
    fn ordered_forces_match_brute_force_and_any_order() {
        let lj = LennardJones::new(1.0, 1.0, 2.5, false).unwrap();
        let mut rng = Rng::new(7);
        let n = 400;
        let points: Vec<[f64; 3]> = (0..n)
            .map(|_| std::array::from_fn(|_| 8.0 * rng.uniform()))
            .collect();
        let ids: Vec<u64> = (0..n as u64).map(|k| 1000 - 2 * k).collect();
        let owned = 250;
        let forces = |p: &[[f64; 3]], q: &[u64], t: usize| {
            let threads = Threads::new(t).unwrap();
            let rows = OrderedRows::build(p, owned, q, 2.5, 0.3, &threads).unwrap();
            let mut out = vec![AtomForce::default(); owned];
            ordered_forces::<true, 3, _>(&rows, &lj, p, &mut out, &threads);
            out
        };
        let one = forces(&points, &ids, 1);
        for i in 0..owned {
            let mut brute = [0.0; 3];
            for j in 0..n {
                let d: [f64; 3] = std::array::from_fn(|a| points[i][a] - points[j][a]);
                let r2 = norm2(&d);
                if j != i && r2 < 6.25 {
                    let f = lj.energy_and_force(r2).1;
                    for a in 0..3 {
                        brute[a] += d[a] * f;
                    }
                }
            }
            for a in 0..3 {
                assert!((one[i].force[a] - brute[a]).abs() <= 1e-9 * (1.0 + brute[a].abs()));
            }
        }
        assert_eq!(one, forces(&points, &ids, 2));
        // the ghosts reversed and the owned atoms rotated: the same bits per atom
        let mut perm: Vec<usize> = (1..owned).chain([0]).collect();
        perm.extend((owned..n).rev());
        let p: Vec<[f64; 3]> = perm.iter().map(|&k| points[k]).collect();
        let q: Vec<u64> = perm.iter().map(|&k| ids[k]).collect();
        let other = forces(&p, &q, 2);
        for (k, &orig) in perm[..owned].iter().enumerate() {
            assert_eq!(other[k], one[orig]);
        }
    }
}
