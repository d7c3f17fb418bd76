//! Spatial domain decomposition for distributed short-range runs (seed 003): the
//! box cut into a Cartesian grid of subdomains, one per rank, the grid chosen to
//! minimise the surface each subdomain shares with its neighbours (the ghost
//! traffic), and the ghost rule: which particles a rank sends to which neighbour
//! so that every neighbour holds every particle within `reach` (cutoff + skin) of
//! its subdomain, periodic images included.
//!
//! The cut planes of each axis are equally spaced ([`Balance::Uniform`]) or
//! placed so that each slab holds an equal share of the particles
//! ([`Balance::Rcb`], [`Decomposition::balanced`]); either way the subdomains
//! stay a tensor grid (the planes of an axis are shared by every slab of the
//! other axes), so each has the same neighbours across faces, edges and
//! corners, and the ghost rule does not depend on where the planes lie.
//!
//! No communication here: the MPI layer moves what these functions select, and
//! the tests check them against brute force by playing every rank in one
//! process.

mod balance;

pub use balance::{Balance, BALANCE_BINS, REBALANCE_ABOVE};

use crate::geometry::{wrap_coordinate, Domain};

/// A box cut into `grid[0] x grid[1] (x grid[2])` subdomains by the planes of
/// each axis; rank `r` owns the subdomain at grid coordinates
/// [`Decomposition::coords`]`(r)`, the first axis varying fastest.
#[derive(Clone, Debug, PartialEq)]
pub struct Decomposition<const D: usize> {
    /// The whole box.
    pub domain: Domain<D>,
    /// Subdomains per axis.
    pub grid: [usize; D],
    /// Per axis, the `grid[d] + 1` planes from the box's lower face to its
    /// upper one, increasing: slab `c` is `[planes[c], planes[c + 1])`.
    planes: [Vec<f64>; D],
}

/// A particle a rank sends as a ghost: its index on the sending rank, the rank it
/// goes to, and the shift (`0` or `+-L` per periodic axis) that puts its image
/// next to the receiving subdomain.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ghost<const D: usize> {
    /// Index of the particle on the sending rank.
    pub index: usize,
    /// The receiving rank.
    pub to: usize,
    /// Added to the position: the periodic image the receiver sees.
    pub shift: [f64; D],
}

/// One rank's part of the box: `[lo, hi)` along the axes the box is cut along
/// (`cut`), and the whole box along the others (where a periodic box wraps
/// around inside the rank).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Subdomain<const D: usize> {
    /// The whole box.
    pub domain: Domain<D>,
    /// Lower corner (the box's along the uncut axes).
    pub lo: [f64; D],
    /// Upper corner (the box's along the uncut axes).
    pub hi: [f64; D],
    /// The axes the box is cut along.
    pub cut: [bool; D],
}

/// Which periodic images of particles a rank receives as ghosts.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Images {
    /// Every image within reach of the subdomain, the rank's own particles'
    /// included: for a neighbour search in open space.
    All,
    /// Only images across the axes the box is cut along (along an uncut
    /// periodic axis the rank sees its particles' images through a periodic
    /// cell list, [`Decomposition::subdomain`]), and from the neighbours of
    /// half of the directions only, those whose last nonzero offset (from the
    /// receiver) is `+1`: of two particles on two ranks, exactly one rank
    /// sees the other as a ghost, so that each pair across a cut is computed
    /// once (Newton's third law across ranks; the ghost's force goes back to
    /// its owner).
    HalfShell,
}

impl Images {
    /// Whether a rank sends its particles to the neighbour at grid offset
    /// `o` (from the sender) under this rule, the box cut `grid`.
    fn sends_towards(self, o: &[i64], grid: &[usize]) -> bool {
        let across_uncut = o.iter().zip(grid).any(|(&v, &g)| v != 0 && g == 1);
        // the receiver sees the sender at -o: its last nonzero offset is +1
        // when o's is -1
        let lower = o.iter().rev().find(|&&v| v != 0) == Some(&-1);
        match self {
            Images::All => true,
            Images::HalfShell => !across_uncut && lower,
        }
    }
}

impl<const D: usize> Decomposition<D> {
    /// Equal subdomains on the grid of `ranks` subdomains whose surface
    /// `sum_d prod_(e != d) L_e / p_e` (one subdomain's faces, up to a factor 2)
    /// is smallest; ties go to the first grid in lexicographic order.
    pub fn new(domain: Domain<D>, ranks: usize) -> Self {
        assert!(ranks >= 1, "at least one rank");
        let mut best: Option<([usize; D], f64)> = None;
        let mut grid = [1usize; D];
        loop {
            if grid.iter().product::<usize>() == ranks {
                let surface: f64 = (0..D)
                    .map(|d| {
                        (0..D)
                            .filter(|&e| e != d)
                            .map(|e| domain.length[e] / grid[e] as f64)
                            .product::<f64>()
                    })
                    .sum();
                if best.is_none_or(|(_, s)| surface < s * (1.0 - 1e-12)) {
                    best = Some((grid, surface));
                }
            }
            // next grid: odometer over the divisors
            let mut axis = 0;
            loop {
                if axis == D {
                    let grid = best.expect("ranks x 1 x 1 is a grid").0;
                    let planes = std::array::from_fn(|d| equal_planes(&domain, d, grid[d]));
                    return Decomposition {
                        domain,
                        grid,
                        planes,
                    };
                }
                grid[axis] += 1;
                if grid[axis] <= ranks {
                    break;
                }
                grid[axis] = 1;
                axis += 1;
            }
        }
    }

    /// The number of subdomains.
    pub fn ranks(&self) -> usize {
        self.grid.iter().product()
    }

    /// The grid coordinates of `rank`.
    pub fn coords(&self, rank: usize) -> [usize; D] {
        let mut rest = rank;
        std::array::from_fn(|d| {
            let c = rest % self.grid[d];
            rest /= self.grid[d];
            c
        })
    }

    /// The rank at grid coordinates `coords`.
    pub fn rank_at(&self, coords: [usize; D]) -> usize {
        (0..D)
            .rev()
            .fold(0, |rank, d| rank * self.grid[d] + coords[d])
    }

    /// The cut planes along `axis`: `grid[axis] + 1` increasing coordinates,
    /// the box's faces first and last.
    pub fn planes(&self, axis: usize) -> &[f64] {
        &self.planes[axis]
    }

    /// The width of the thinnest slab along each axis.
    pub fn thinnest(&self) -> [f64; D] {
        std::array::from_fn(|d| {
            self.planes[d]
                .windows(2)
                .map(|w| w[1] - w[0])
                .fold(f64::INFINITY, f64::min)
        })
    }

    /// The coordinate along `axis` as the slabs see it: wrapped on a periodic
    /// axis, as it is on an open one.
    fn along(&self, axis: usize, x: f64) -> f64 {
        if self.domain.is_periodic(axis) {
            wrap_coordinate(x, self.domain.lo[axis], self.domain.length[axis])
        } else {
            x
        }
    }

    /// The owner of a position: along each axis the slab `c` with
    /// `planes[c] <= x < planes[c + 1]`, periodic axes wrapped, open axes
    /// clamped to the first or last slab (a NaN to the first).
    pub fn owner(&self, x: &[f64; D]) -> usize {
        let coords = std::array::from_fn(|d| {
            let xd = self.along(d, x[d]);
            self.planes[d][1..self.grid[d]].partition_point(|&p| p <= xd)
        });
        self.rank_at(coords)
    }

    /// The subdomain of `rank`, `[lo, hi)` per axis between its planes; on an
    /// open axis the first and last subdomains reach to infinity outward.
    pub fn bounds(&self, rank: usize) -> ([f64; D], [f64; D]) {
        let c = self.coords(rank);
        let mut lo: [f64; D] = std::array::from_fn(|d| self.planes[d][c[d]]);
        let mut hi: [f64; D] = std::array::from_fn(|d| self.planes[d][c[d] + 1]);
        for d in 0..D {
            if !self.domain.is_periodic(d) {
                if c[d] == 0 {
                    lo[d] = f64::NEG_INFINITY;
                }
                if c[d] + 1 == self.grid[d] {
                    hi[d] = f64::INFINITY;
                }
            }
        }
        (lo, hi)
    }

    /// Refuses a subdomain thinner than `reach` along an axis it is cut along (or
    /// a periodic axis): its ghosts would have to come from beyond its
    /// neighbours.
    pub fn check_reach(&self, reach: f64) -> Result<(), String> {
        const AXES: [&str; 3] = ["x", "y", "z"];
        let w = self.thinnest();
        for d in 0..D {
            let cut = self.grid[d] > 1 || self.domain.is_periodic(d);
            if cut && w[d] < reach {
                return Err(format!(
                    "{} ranks cut the box into {} subdomains along {}, the thinnest {:.6} wide, \
                     thinner than the cutoff + skin {reach}: use fewer ranks or a larger box",
                    self.ranks(),
                    self.grid[d],
                    AXES[d],
                    w[d]
                ));
            }
        }
        Ok(())
    }

    /// The decomposition of `ranks` subdomains for particles at `positions`
    /// (every particle, the same on every rank, so that every rank places the
    /// same planes): the grid of [`Decomposition::new`], its planes equal or,
    /// with [`Balance::Rcb`] when the equal planes' [`Decomposition::imbalance`]
    /// exceeds [`REBALANCE_ABOVE`], [`Decomposition::balanced`] by the
    /// particles' histogram (an even system keeps its equal planes); refused
    /// when the equal subdomains are thinner than `reach`
    /// ([`Decomposition::check_reach`]).
    pub fn for_particles(
        domain: Domain<D>,
        ranks: usize,
        balance: Balance,
        positions: &[[f64; D]],
        reach: f64,
    ) -> Result<Self, String> {
        let equal = Decomposition::new(domain, ranks);
        equal.check_reach(reach)?;
        Ok(match balance {
            Balance::Rcb if equal.imbalance(positions) > REBALANCE_ABOVE => {
                equal.balanced(&equal.histogram(positions), reach)
            }
            _ => equal,
        })
    }

    /// The largest over mean number of `positions` per rank, each counted
    /// where it is owned ([`Decomposition::owner`]).
    pub fn imbalance(&self, positions: &[[f64; D]]) -> f64 {
        let mut counts = vec![0usize; self.ranks()];
        for x in positions {
            counts[self.owner(x)] += 1;
        }
        let most = counts.iter().copied().max().unwrap_or(0);
        most as f64 * self.ranks() as f64 / positions.len().max(1) as f64
    }

    /// How many of `positions` lie in each of [`BALANCE_BINS`] equal bins
    /// along each axis the box is cut along (axis after axis, zero along the
    /// others), periodic axes wrapped and open ones clamped into the box:
    /// summed over the ranks, what [`Decomposition::balanced`] places the
    /// planes by. Integer counts, so the sum does not depend on the order of
    /// the particles or of the ranks.
    pub fn histogram(&self, positions: &[[f64; D]]) -> Vec<u64> {
        let mut counts = vec![0u64; D * BALANCE_BINS];
        for d in (0..D).filter(|&d| self.grid[d] > 1) {
            let (lo, length) = (self.domain.lo[d], self.domain.length[d]);
            let bins = &mut counts[d * BALANCE_BINS..(d + 1) * BALANCE_BINS];
            for x in positions {
                bins[balance::bin(self.along(d, x[d]), lo, length)] += 1;
            }
        }
        counts
    }

    /// The same grid with the planes of each cut axis placed by the summed
    /// `histogram` ([`Decomposition::histogram`]): plane `k` of `p` where the
    /// counts, spread evenly over each bin, reach `k N / p`, so that each slab
    /// holds about `N / p` particles (LAMMPS's `balance shift`); a plane that
    /// would leave a slab thinner than `reach` is moved out to `reach`. An axis
    /// without counts, or whose moved planes still leave a slab thinner than
    /// `reach` (a box of barely `p reach`, by rounding), keeps its equal
    /// planes.
    pub fn balanced(&self, histogram: &[u64], reach: f64) -> Self {
        assert_eq!(histogram.len(), D * BALANCE_BINS);
        let mut out = self.clone();
        for d in (0..D).filter(|&d| self.grid[d] > 1) {
            let counts = &histogram[d * BALANCE_BINS..(d + 1) * BALANCE_BINS];
            let (lo, length) = (self.domain.lo[d], self.domain.length[d]);
            out.planes[d] = balance::quantile_planes(counts, self.grid[d], lo, length, reach)
                .filter(|planes| planes.windows(2).all(|w| w[1] - w[0] >= reach))
                .unwrap_or_else(|| equal_planes(&self.domain, d, self.grid[d]));
        }
        out
    }

    /// The part of the box `rank` owns as its halo list sees it
    /// ([`Images::HalfShell`]): `[lo, hi)` along the axes the box is cut
    /// along (an open face of the box bounds the first and last subdomains),
    /// the whole box along the others.
    pub fn subdomain(&self, rank: usize) -> Subdomain<D> {
        let (lo, hi) = self.bounds(rank);
        let box_hi: [f64; D] = std::array::from_fn(|d| self.domain.lo[d] + self.domain.length[d]);
        Subdomain {
            domain: self.domain,
            lo: std::array::from_fn(|d| lo[d].max(self.domain.lo[d])),
            hi: std::array::from_fn(|d| hi[d].min(box_hi[d])),
            cut: std::array::from_fn(|d| self.grid[d] > 1),
        }
    }

    /// The ghosts `rank` sends: for each of its particles at `positions` (inside
    /// its subdomain, wrapped) and each neighbouring subdomain, across faces,
    /// edges and corners, the particle goes when it lies within `reach` of every
    /// face it crosses towards that neighbour (`x - lo <= reach` towards the lower
    /// one, `hi - x <= reach` towards the upper one), with the periodic shift of
    /// its image. On a periodic axis of one or two subdomains a neighbour may be
    /// the rank itself or the same rank twice, each with its own shift; with
    /// [`Images::HalfShell`] no neighbour lies across an uncut axis, and only
    /// the neighbours below (last nonzero offset -1) receive.
    pub fn ghosts(
        &self,
        rank: usize,
        positions: &[[f64; D]],
        reach: f64,
        images: Images,
    ) -> Vec<Ghost<D>> {
        let (lo, hi) = self.bounds(rank);
        let c = self.coords(rank);
        let mut out = Vec::new();
        let offsets = 3usize.pow(D as u32);
        for code in 0..offsets {
            let o: [i64; D] = std::array::from_fn(|d| (code / 3usize.pow(d as u32) % 3) as i64 - 1);
            if o.iter().all(|&v| v == 0) {
                continue;
            }
            if !images.sends_towards(&o, &self.grid) {
                continue;
            }
            // the neighbour's coordinates and the shift of images crossing the box
            let mut to = [0usize; D];
            let mut shift = [0.0; D];
            let mut exists = true;
            for d in 0..D {
                let n = c[d] as i64 + o[d];
                let p = self.grid[d] as i64;
                if (0..p).contains(&n) {
                    to[d] = n as usize;
                } else if self.domain.is_periodic(d) {
                    to[d] = n.rem_euclid(p) as usize;
                    // leaving through the upper face: the image is x - L
                    shift[d] = -(o[d] as f64) * self.domain.length[d];
                } else {
                    exists = false;
                }
            }
            if !exists {
                continue;
            }
            let to = self.rank_at(to);
            for (index, x) in positions.iter().enumerate() {
                let near = (0..D).all(|d| match o[d] {
                    -1 => x[d] - lo[d] <= reach,
                    1 => hi[d] - x[d] <= reach,
                    _ => true,
                });
                if near {
                    out.push(Ghost { index, to, shift });
                }
            }
        }
        out
    }
}

/// `slabs + 1` equally spaced planes along `axis`, the last the box's upper face.
fn equal_planes<const D: usize>(domain: &Domain<D>, axis: usize, slabs: usize) -> Vec<f64> {
    let (lo, length) = (domain.lo[axis], domain.length[axis]);
    let width = length / slabs as f64;
    (0..=slabs)
        .map(|c| {
            if c == slabs {
                lo + length
            } else {
                lo + c as f64 * width
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Boundary;
    use crate::random::Rng;

    #[test]
    fn grids_minimise_the_surface() {
        let cube = Domain::periodic([10.0; 3]).unwrap();
        assert_eq!(Decomposition::new(cube, 1).grid, [1, 1, 1]);
        assert_eq!(Decomposition::new(cube, 2).grid, [2, 1, 1]);
        assert_eq!(Decomposition::new(cube, 4).grid, [2, 2, 1]);
        assert_eq!(Decomposition::new(cube, 8).grid, [2, 2, 2]);
        assert_eq!(Decomposition::new(cube, 12).grid, [3, 2, 2]);
        // a long box is cut along its long side
        let slab = Domain::periodic([40.0, 10.0, 10.0]).unwrap();
        assert_eq!(Decomposition::new(slab, 4).grid, [4, 1, 1]);
        let plane = Domain::periodic([10.0, 10.0]).unwrap();
        assert_eq!(Decomposition::new(plane, 6).grid, [3, 2]);
        assert_eq!(Decomposition::new(plane, 7).grid, [7, 1]);
    }

    #[test]
    fn ranks_and_coordinates_round_trip() {
        let d = Decomposition::new(Domain::periodic([6.0, 4.0, 2.0]).unwrap(), 12);
        for r in 0..d.ranks() {
            assert_eq!(d.rank_at(d.coords(r)), r);
            let (lo, hi) = d.bounds(r);
            let middle = std::array::from_fn(|k| 0.5 * (lo[k] + hi[k]));
            assert_eq!(d.owner(&middle), r);
        }
    }

    #[test]
    fn thin_subdomains_are_refused() {
        let d = Decomposition::new(Domain::periodic([10.0, 10.0, 10.0]).unwrap(), 8);
        assert!(d.check_reach(5.0).is_ok());
        let e = d.check_reach(5.5).unwrap_err();
        assert!(e.contains("thinner than the cutoff + skin 5.5"), "{e}");
    }

    /// Every rank's ghosts, played in one process, against brute force: a rank
    /// receives exactly the images of other ranks' particles (and its own shifted
    /// ones) that lie in the shell of width `reach` around its subdomain; with
    /// [`Images::HalfShell`], none shifted along an uncut axis and only those
    /// above the subdomain along the last axis they lie beyond.
    /// With equal planes and with planes balanced for particles crowded
    /// towards the lower corner of the box.
    fn check_ghosts<const D: usize>(domain: Domain<D>, ranks: usize, reach: f64, n: usize) {
        let equal = Decomposition::new(domain, ranks);
        let crowded = skewed(domain, 3 * n, ranks as u64);
        let balanced = Decomposition::for_particles(domain, ranks, Balance::Rcb, &crowded, reach);
        for d in [equal, balanced.unwrap()] {
            for images in [Images::All, Images::HalfShell] {
                check_ghost_images(&d, reach, n, images);
            }
        }
    }

    /// `n` points in `domain`, the density falling along every axis: each
    /// coordinate `lo + u^2 L` for a uniform `u`.
    fn skewed<const D: usize>(domain: Domain<D>, n: usize, seed: u64) -> Vec<[f64; D]> {
        let mut rng = Rng::new(seed + 1000);
        (0..n)
            .map(|_| {
                std::array::from_fn(|k| domain.lo[k] + rng.uniform().powi(2) * domain.length[k])
            })
            .collect()
    }

    fn check_ghost_images<const D: usize>(
        d: &Decomposition<D>,
        reach: f64,
        n: usize,
        images: Images,
    ) {
        let (domain, ranks) = (d.domain, d.ranks());
        d.check_reach(reach).unwrap();
        let mut rng = Rng::new(ranks as u64 * 31 + D as u64);
        let mut points: Vec<[f64; D]> = (0..n)
            .map(|_| std::array::from_fn(|k| domain.lo[k] + rng.uniform() * domain.length[k]))
            .collect();
        // a point on the faces between subdomains (wrapped: on one rank it is
        // the box's upper face, the lower one of its periodic axes)
        let first = d.subdomain(0).hi;
        points.push(domain.wrap(first));
        let owner: Vec<usize> = points.iter().map(|x| d.owner(x)).collect();
        let periodic: [bool; D] = std::array::from_fn(|k| domain.is_periodic(k));
        for to in 0..ranks {
            let (lo, hi) = d.bounds(to);
            let mut got: Vec<(usize, Vec<i64>)> = Vec::new();
            for from in 0..ranks {
                let mine: Vec<usize> = (0..points.len()).filter(|&i| owner[i] == from).collect();
                let local: Vec<[f64; D]> = mine.iter().map(|&i| points[i]).collect();
                for g in d
                    .ghosts(from, &local, reach, images)
                    .into_iter()
                    .filter(|g| g.to == to)
                {
                    let image = (0..D)
                        .map(|k| (g.shift[k] / domain.length[k]).round() as i64)
                        .collect();
                    got.push((mine[g.index], image));
                }
            }
            let mut expected = Vec::new();
            for (i, x) in points.iter().enumerate() {
                for code in 0..3usize.pow(D as u32) {
                    let m: [i64; D] =
                        std::array::from_fn(|k| (code / 3usize.pow(k as u32) % 3) as i64 - 1);
                    if (0..D).any(|k| m[k] != 0 && !periodic[k]) {
                        continue;
                    }
                    let uncut = (0..D).any(|k| m[k] != 0 && d.grid[k] == 1);
                    if images != Images::All && uncut {
                        continue;
                    }
                    let y: [f64; D] =
                        std::array::from_fn(|k| x[k] + m[k] as f64 * domain.length[k]);
                    let inside = (0..D).all(|k| y[k] >= lo[k] && y[k] < hi[k]);
                    let shell = (0..D).all(|k| y[k] >= lo[k] - reach && y[k] <= hi[k] + reach);
                    // where the image lies from the receiver, per axis
                    let side: Vec<i64> = (0..D)
                        .map(|k| i64::from(y[k] >= hi[k]) - i64::from(y[k] < lo[k]))
                        .collect();
                    let upper = side.iter().rev().find(|&&v| v != 0) == Some(&1);
                    if shell && !inside && (images != Images::HalfShell || upper) {
                        expected.push((i, m.to_vec()));
                    }
                }
            }
            got.sort();
            expected.sort();
            assert_eq!(got, expected, "rank {to} of {ranks}, {images:?}");
        }
    }

    #[test]
    fn ghosts_are_the_shell_around_each_subdomain() {
        for ranks in [1, 2, 3, 4, 6, 8] {
            check_ghosts(
                Domain::periodic([10.0, 12.0, 9.0]).unwrap(),
                ranks,
                1.7,
                400,
            );
        }
        for ranks in [1, 2, 4, 5] {
            check_ghosts(Domain::periodic([11.0, 7.0]).unwrap(), ranks, 1.3, 300);
        }
        let mixed = Domain::new([10.0, 10.0], [Boundary::Periodic, Boundary::Open]).unwrap();
        for ranks in [1, 2, 4] {
            check_ghosts(mixed, ranks, 1.5, 300);
        }
    }

    /// Every point of a crowded box lies in exactly one subdomain's bounds,
    /// that of its owner, and the balanced planes give every rank about its
    /// share where equal planes do not.
    #[test]
    fn balanced_planes_share_the_particles_and_own_each_once() {
        let domain = Domain::new(
            [30.0, 20.0, 10.0],
            [Boundary::Periodic, Boundary::Open, Boundary::Periodic],
        )
        .unwrap();
        let points = skewed(domain, 60000, 7);
        for ranks in [2, 3, 4, 6] {
            let load = |d: &Decomposition<3>| {
                for x in &points {
                    let inside: Vec<usize> = (0..ranks)
                        .filter(|&r| {
                            let (lo, hi) = d.bounds(r);
                            (0..3).all(|k| x[k] >= lo[k] && x[k] < hi[k])
                        })
                        .collect();
                    assert_eq!(inside, [d.owner(x)], "{x:?} on {ranks} ranks");
                }
                d.imbalance(&points)
            };
            let equal = Decomposition::new(domain, ranks);
            let balanced =
                Decomposition::for_particles(domain, ranks, Balance::Rcb, &points, 1.0).unwrap();
            assert_eq!(balanced.grid, equal.grid);
            balanced.check_reach(1.0).unwrap();
            let (before, after) = (load(&equal), load(&balanced));
            assert!(before > 1.3, "{ranks} ranks, equal planes: {before}");
            // a tensor grid balances each axis's marginal: with independent
            // coordinates the share of a rank is the product of its slabs'
            // shares, up to the sample's fluctuations
            assert!(
                after < REBALANCE_ABOVE,
                "{ranks} ranks, balanced planes: {after}"
            );
            for r in 0..ranks {
                let (lo, hi) = balanced.bounds(r);
                let middle =
                    std::array::from_fn(|k| 0.5 * (lo[k].max(0.0) + hi[k].min(domain.length[k])));
                assert_eq!(balanced.owner(&middle), r);
            }
        }
    }

    /// Particles crowded into a layer thinner than `reach`: the planes are
    /// clamped so that every slab stays `reach` wide; the same histogram gives
    /// the same planes whatever the order of the particles.
    #[test]
    fn balanced_planes_stay_reach_wide_and_ignore_the_order() {
        let domain = Domain::periodic([12.0, 12.0]).unwrap();
        let mut rng = Rng::new(3);
        let mut points: Vec<[f64; 2]> = (0..5000)
            .map(|_| [1.0 + 0.5 * rng.uniform(), 12.0 * rng.uniform()])
            .collect();
        let d = Decomposition::for_particles(domain, 4, Balance::Rcb, &points, 2.5).unwrap();
        assert_eq!(d.grid, [2, 2]);
        assert!(d.thinnest().iter().all(|&w| w >= 2.5), "{:?}", d.thinnest());
        d.check_reach(2.5).unwrap();
        points.reverse();
        let again = Decomposition::for_particles(domain, 4, Balance::Rcb, &points, 2.5).unwrap();
        assert_eq!(again, d);
        // the equal planes are refused as before when too thin
        let e = Decomposition::for_particles(domain, 4, Balance::Rcb, &points, 6.5).unwrap_err();
        assert!(e.contains("thinner than the cutoff + skin 6.5"), "{e}");
        let uniform = Decomposition::for_particles(domain, 4, Balance::Uniform, &points, 2.5);
        assert_eq!(uniform.unwrap(), Decomposition::new(domain, 4));
    }

    /// An even system (a square lattice, whose rows the equal planes split
    /// evenly) keeps its equal planes: they are balanced already.
    #[test]
    fn an_even_system_keeps_its_equal_planes() {
        let domain = Domain::periodic([12.0, 12.0]).unwrap();
        let lattice: Vec<[f64; 2]> = (0..24 * 24)
            .map(|k| [0.5 * (k % 24) as f64, 0.5 * (k / 24) as f64])
            .collect();
        let d = Decomposition::for_particles(domain, 4, Balance::Rcb, &lattice, 2.5).unwrap();
        assert_eq!(d, Decomposition::new(domain, 4));
        assert_eq!(d.imbalance(&lattice), 1.0);
    }
}
