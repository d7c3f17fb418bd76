//! Every fast neighbour path against the brute-force reference, on random inputs:
//! 2D and 3D, periodic and open axes, tiny grids (1 and 2 cells per axis), points on
//! cell faces and box faces, points outside the box; 1 and 2 threads.

use cellist::neighbors::{
    brute_force_pairs, gather_cells, gather_verlet, half_list_as_found, half_pairs,
    scatter_coloured, scatter_verlet_serial, sorted_half_list, PairKernel, PairQuantities,
};
use cellist::neighbors::{unpack, ClusterList, CLUSTER};
use cellist::{Boundary, CellList, Domain, StencilKind, Threads, VerletList};
use proptest::prelude::*;

/// Per particle: number of neighbours, sum of their input ids, and sum of the
/// separations (floating point, to check bit-for-bit determinism).
#[derive(Clone, Copy, Debug, PartialEq)]
struct Tally<const D: usize> {
    count: u64,
    id_sum: u64,
    sep_sum: [f64; D],
}

impl<const D: usize> Default for Tally<D> {
    fn default() -> Self {
        Tally {
            count: 0,
            id_sum: 0,
            sep_sum: [0.0; D],
        }
    }
}

struct TallyKernel<'a> {
    ids: &'a [u32],
}

impl<const D: usize> PairKernel<D> for TallyKernel<'_> {
    type Acc = Tally<D>;
    fn gather(&self, _i: usize, j: usize, d: &[f64; D], _r2: f64, acc_i: &mut Tally<D>) {
        acc_i.count += 1;
        acc_i.id_sum += self.ids[j] as u64;
        for (sum, da) in acc_i.sep_sum.iter_mut().zip(d) {
            *sum += da;
        }
    }
    fn scatter(
        &self,
        i: usize,
        j: usize,
        d: &[f64; D],
        r2: f64,
        acc_i: &mut Tally<D>,
        acc_j: &mut Tally<D>,
    ) {
        self.gather(i, j, d, r2, acc_i);
        let minus: [f64; D] = std::array::from_fn(|a| -d[a]);
        self.gather(j, i, &minus, r2, acc_j);
    }
}

/// Brute-force tallies in input order (counts and id sums only: exact integers).
fn brute_tally(pairs: &[(u32, u32, f64)], n: usize) -> Vec<(u64, u64)> {
    let mut t = vec![(0u64, 0u64); n];
    for &(i, j, _) in pairs {
        t[i as usize].0 += 1;
        t[i as usize].1 += j as u64;
        t[j as usize].0 += 1;
        t[j as usize].1 += i as u64;
    }
    t
}

/// Same pair sets; distances within 1e-12 relative, or within a few ulps of the
/// largest coordinate `scale` (wrapping a point that lies outside a periodic box
/// costs that much absolute precision, in the brute force as in the fast path).
fn assert_same_pairs(fast: &[(u32, u32, f64)], brute: &[(u32, u32, f64)], scale: f64) {
    assert_eq!(fast.len(), brute.len(), "pair counts differ");
    for (f, b) in fast.iter().zip(brute) {
        assert_eq!((f.0, f.1), (b.0, b.1), "pair sets differ");
        let diff = (f.2 - b.2).abs();
        assert!(
            diff <= 1e-12 * b.2 || diff <= 8.0 * f64::EPSILON * scale,
            "distance {} vs {} for {:?}",
            f.2,
            b.2,
            (f.0, f.1)
        );
    }
}

/// Runs every fast path on one input and compares with brute force.
fn check_all_paths<const D: usize>(domain: &Domain<D>, cutoff: f64, points: &[[f64; D]]) {
    let brute = brute_force_pairs(domain, cutoff, points);
    let one = Threads::single();
    let two = Threads::new(2).unwrap();
    let cells = CellList::build(domain, cutoff, points).unwrap();

    // the half pair list, on 1 and 2 threads
    let mut fast_one = half_pairs(&cells, cutoff, &one, |i, j, r2| (i, j, r2.sqrt()));
    let fast_two = half_pairs(&cells, cutoff, &two, |i, j, r2| (i, j, r2.sqrt()));
    assert_eq!(
        fast_one
            .iter()
            .map(|p| (p.0, p.1, p.2.to_bits()))
            .collect::<Vec<_>>(),
        fast_two
            .iter()
            .map(|p| (p.0, p.1, p.2.to_bits()))
            .collect::<Vec<_>>()
    );
    fast_one.sort_by_key(|p| (p.0, p.1));
    let scale = points.iter().flatten().fold(0.0f64, |m, x| m.max(x.abs()));
    assert_same_pairs(&fast_one, &brute, scale);

    // the sorted half list with every quantity: the same pairs, the same
    // distances as the unsorted list, separations and shifts consistent with
    // the input points, the same bits on 1 and 2 threads
    let all = PairQuantities {
        distances: true,
        vectors: true,
        shifts: true,
    };
    let sorted = sorted_half_list(&cells, points, cutoff, all, &one);
    assert_eq!(sorted, sorted_half_list(&cells, points, cutoff, all, &two));
    let three = Threads::new(3).unwrap();
    assert_eq!(
        sorted,
        sorted_half_list(&cells, points, cutoff, all, &three)
    );
    // the indices alone (their own search loop and row sort): the same pairs
    let bare = sorted_half_list(&cells, points, cutoff, PairQuantities::default(), &three);
    assert_eq!((&bare.i, &bare.j), (&sorted.i, &sorted.j));
    assert!(bare.distances.is_empty() && bare.vectors.is_empty() && bare.shifts.is_empty());
    let listed: Vec<(u32, u32, u64)> = (0..sorted.len())
        .map(|k| {
            (
                sorted.i[k] as u32,
                sorted.j[k] as u32,
                sorted.distances[k].to_bits(),
            )
        })
        .collect();
    let unsorted: Vec<(u32, u32, u64)> =
        fast_one.iter().map(|p| (p.0, p.1, p.2.to_bits())).collect();
    assert_eq!(listed, unsorted);
    // the list as found: the same pairs and quantities in cell order, the same
    // bits on 1 and 2 threads
    let found = half_list_as_found(&cells, points, cutoff, all, &one);
    assert_eq!(found, half_list_as_found(&cells, points, cutoff, all, &two));
    let mut by_pair: Vec<usize> = (0..found.len()).collect();
    by_pair.sort_by_key(|&k| (found.i[k], found.j[k]));
    assert_eq!(by_pair.len(), sorted.len());
    for (k, &f) in by_pair.iter().enumerate() {
        assert_eq!((found.i[f], found.j[f]), (sorted.i[k], sorted.j[k]));
        assert_eq!(found.distances[f].to_bits(), sorted.distances[k].to_bits());
        assert_eq!(
            found.vectors[f * D..(f + 1) * D],
            sorted.vectors[k * D..(k + 1) * D]
        );
        assert_eq!(
            found.shifts[f * D..(f + 1) * D],
            sorted.shifts[k * D..(k + 1) * D]
        );
    }
    for k in 0..sorted.len() {
        let (i, j) = (sorted.i[k] as usize, sorted.j[k] as usize);
        let d = &sorted.vectors[k * D..(k + 1) * D];
        let s = &sorted.shifts[k * D..(k + 1) * D];
        let r2: f64 = d.iter().map(|x| x * x).sum();
        assert!((r2.sqrt() - sorted.distances[k]).abs() <= 1e-12 * (1.0 + sorted.distances[k]));
        for a in 0..D {
            let unwrapped = points[j][a] - points[i][a] + s[a] as f64 * domain.length[a];
            assert!(
                (unwrapped - d[a]).abs() <= 1e-9 * (1.0 + scale),
                "pair ({i}, {j}) axis {a}: d {} but x_j - x_i + S L = {unwrapped}",
                d[a]
            );
            if !domain.is_periodic(a) {
                assert_eq!(s[a], 0);
            }
        }
    }

    // per-particle sums by every strategy
    let expected = brute_tally(&brute, points.len());
    let kernel = TallyKernel { ids: cells.order() };
    let to_input_order = |acc: &[Tally<D>]| {
        let mut out = vec![(0, 0); acc.len()];
        for (k, t) in acc.iter().enumerate() {
            out[cells.order()[k] as usize] = (t.count, t.id_sum);
        }
        out
    };
    let run = |f: &dyn Fn(&Threads, &mut [Tally<D>])| {
        let mut a = vec![Tally::default(); points.len()];
        let mut b = vec![Tally::default(); points.len()];
        f(&one, &mut a);
        f(&two, &mut b);
        assert_eq!(a, b, "1 and 2 threads differ");
        assert_eq!(to_input_order(&a), expected);
    };
    run(&|t, acc| gather_cells(&cells, cutoff, &kernel, acc, t));
    run(&|t, acc| scatter_coloured(&cells, cutoff, &kernel, acc, t));

    // Verlet lists with a skin, over a cell list built for cutoff + skin
    let skin = 0.1 * cutoff;
    let max_cutoff = (0..D)
        .filter(|&d| domain.is_periodic(d))
        .map(|d| domain.length[d] / 2.0)
        .fold(f64::INFINITY, f64::min);
    let reach = (cutoff + skin).min(max_cutoff);
    let skin = reach - cutoff;
    let wide = CellList::build(domain, reach, points).unwrap();
    let kernel = TallyKernel { ids: wide.order() };
    let to_input_order = |acc: &[Tally<D>]| {
        let mut out = vec![(0, 0); acc.len()];
        for (k, t) in acc.iter().enumerate() {
            out[wide.order()[k] as usize] = (t.count, t.id_sum);
        }
        out
    };
    let full = VerletList::build(&wide, StencilKind::Full, cutoff, skin, &two);
    let full_one = VerletList::build(&wide, StencilKind::Full, cutoff, skin, &one);
    assert_eq!(full.len(), full_one.len());
    for i in 0..full.len() {
        assert_eq!(
            full.row(i),
            full_one.row(i),
            "row {i} differs between 1 and 2 threads"
        );
    }
    let mut a = vec![Tally::default(); points.len()];
    let mut b = vec![Tally::default(); points.len()];
    gather_verlet(&full, wide.positions(), &kernel, &mut a, &one);
    gather_verlet(&full, wide.positions(), &kernel, &mut b, &two);
    assert_eq!(a, b);
    assert_eq!(to_input_order(&a), expected);
    let half = VerletList::build(&wide, StencilKind::Half, cutoff, skin, &two);
    let mut h = vec![Tally::default(); points.len()];
    scatter_verlet_serial(&half, wide.positions(), &kernel, &mut h);
    assert_eq!(to_input_order(&h), expected);
    check_verlet_after_moves(domain, cutoff, skin, &wide, &full, &half);
    check_cluster_list(domain, cutoff, skin, points);
}

/// The cluster pair list: the same cell order and list on no pool, 1 and 2
/// threads; after moves below skin/2 (no rebuild asked for) it holds every pair
/// within the cutoff exactly once, and no pair it holds within the cutoff is
/// missing from the brute-force list (pairs within 1e-9 of the cutoff, where
/// the two separations may round apart, are left out of both checks).
fn check_cluster_list<const D: usize>(
    domain: &Domain<D>,
    cutoff: f64,
    skin: f64,
    points: &[[f64; D]],
) {
    let (one, two) = (Threads::single(), Threads::new(2).unwrap());
    let side = ClusterList::cell_side(domain, cutoff + skin, points.len());
    let binned = |threads: Option<&Threads>| {
        let mut cells = CellList::build(domain, side, points).unwrap();
        cells.order_cells_in_columns(threads);
        cells
    };
    let cells = binned(Some(&two));
    assert_eq!(cells.order(), binned(None).order());
    let mut scratch = Vec::new();
    let list = ClusterList::build(&cells, cutoff, skin, &two, &mut scratch);
    let list_one = ClusterList::build(&cells, cutoff, skin, &one, &mut scratch);
    for c in 0..list.num_clusters() {
        assert!(list.slots(c).len() <= CLUSTER);
        assert_eq!(
            list.row_parts(c),
            list_one.row_parts(c),
            "row {c} differs between 1 and 2 threads"
        );
    }
    let (inside, outside) = (cutoff * (1.0 - 1e-9), cutoff * (1.0 + 1e-9));
    check_row_parts(&list, cells.positions(), inside, outside);
    let moved = moved_below_half_skin(cells.positions(), skin, points.len() as u64 + 7);
    assert!(!list.needs_rebuild(&cells, &moved));
    let mut seen = std::collections::HashMap::new();
    list.for_each_pair(&moved, |i, j, _, r2| {
        let r = r2.sqrt();
        if r < outside {
            *seen.entry((i.min(j), i.max(j))).or_insert(0) += usize::from(r < inside);
        }
    });
    let brute = brute_force_pairs(domain, cutoff, &moved);
    for &(i, j, r) in &brute {
        if r < inside {
            assert_eq!(
                seen.get(&(i as usize, j as usize)),
                Some(&1),
                "pair {i} {j} at {r}"
            );
        }
    }
    let near: std::collections::HashSet<(usize, usize)> =
        brute_force_pairs(domain, outside, &moved)
            .iter()
            .map(|&(i, j, _)| (i as usize, j as usize))
            .collect();
    for (pair, &count) in &seen {
        assert!(
            count <= 1 && near.contains(pair),
            "pair {pair:?} seen {count} times"
        );
    }
}

/// Each row's first part holds the entries with a pair closer than the cutoff
/// at the build positions `built` (slot order), its second part those without:
/// the closest pair of every entry, against the cutoff as `inside` and
/// `outside` bracket it (a pair between the two may round either way).
fn check_row_parts<const D: usize>(
    list: &ClusterList<D>,
    built: &[[f64; D]],
    inside: f64,
    outside: f64,
) {
    for c in 0..list.num_clusters() {
        let (near, far) = list.row_parts(c);
        let closest = |entry: u32| {
            let (other, image) = unpack(entry);
            let shift = list.image_shift(image);
            let mut closest = f64::INFINITY;
            for i in list.slots(c) {
                for j in list.slots(other) {
                    let d: [f64; D] =
                        std::array::from_fn(|a| built[i][a] - (built[j][a] + shift[a]));
                    closest = closest.min(d.iter().map(|x| x * x).sum::<f64>().sqrt());
                }
            }
            closest
        };
        for &entry in near {
            assert!(
                closest(entry) < outside,
                "row {c}: near entry {entry} has no pair within the cutoff"
            );
        }
        for &entry in far {
            assert!(
                closest(entry) >= inside,
                "row {c}: far entry {entry} has a pair within the cutoff"
            );
        }
    }
}

/// Moves every particle by less than skin/2 (without re-wrapping): the lists must
/// still give exactly the brute-force neighbours of the moved positions; one move
/// beyond skin/2 must ask for a rebuild.
fn check_verlet_after_moves<const D: usize>(
    domain: &Domain<D>,
    cutoff: f64,
    skin: f64,
    wide: &CellList<D>,
    full: &VerletList<D>,
    half: &VerletList<D>,
) {
    let moved = moved_below_half_skin(wide.positions(), skin, wide.len() as u64);
    assert!(!full.needs_rebuild(wide, &moved));
    let slots: Vec<u32> = (0..moved.len() as u32).collect();
    let kernel = TallyKernel { ids: &slots };
    let expected = brute_tally(&brute_force_pairs(domain, cutoff, &moved), moved.len());
    let mut a = vec![Tally::default(); moved.len()];
    gather_verlet(full, &moved, &kernel, &mut a, &Threads::single());
    assert_eq!(
        a.iter().map(|t| (t.count, t.id_sum)).collect::<Vec<_>>(),
        expected
    );
    let mut h = vec![Tally::default(); moved.len()];
    scatter_verlet_serial(half, &moved, &kernel, &mut h);
    assert_eq!(
        h.iter().map(|t| (t.count, t.id_sum)).collect::<Vec<_>>(),
        expected
    );
    if let Some(built) = wide.positions().first() {
        let mut far = moved.clone();
        far[0] = std::array::from_fn(|a| built[a] + if a == 0 { 0.51 * skin } else { 0.0 });
        assert_eq!(full.needs_rebuild(wide, &far), skin > 0.0);
    }
}

/// `positions`, each moved by less than skin/2 (at most `0.49 skin / sqrt(D)`
/// per axis, uniformly, from the stream `seed`), not wrapped again.
fn moved_below_half_skin<const D: usize>(
    positions: &[[f64; D]],
    skin: f64,
    seed: u64,
) -> Vec<[f64; D]> {
    let mut rng = cellist::random::Rng::new(seed);
    let step = 0.49 * skin / (D as f64).sqrt();
    positions
        .iter()
        .map(|x| std::array::from_fn(|a| x[a] + (2.0 * rng.uniform() - 1.0) * step))
        .collect()
}

fn boundary(periodic: bool) -> Boundary {
    if periodic {
        Boundary::Periodic
    } else {
        Boundary::Open
    }
}

/// A coordinate on axis of length `l` with `m` cells: uniform inside (kinds 0-2),
/// exactly on a cell face or a box face (3), outside the box (4), or on the upper
/// box face (5).
fn coordinate(kind: u8, u: f64, k: usize, l: f64, m: usize) -> f64 {
    match kind {
        0..=2 => u * l,
        3 => (k % (m + 1)) as f64 * (l / m as f64),
        4 => (u - 0.5) * 3.0 * l,
        _ => l,
    }
}

fn input<const D: usize>(
    lengths: [f64; D],
    periodic: [bool; D],
    cutoff_frac: f64,
    raw: &[([u8; D], [f64; D], [usize; D])],
) -> (Domain<D>, f64, Vec<[f64; D]>) {
    let domain = Domain::new(lengths, periodic.map(boundary)).unwrap();
    let shortest = lengths.iter().cloned().fold(f64::INFINITY, f64::min);
    let cutoff = (cutoff_frac * shortest / 2.0).max(1e-3);
    let grid = cellist::neighbors::CellGrid::new(&domain, cutoff, raw.len()).unwrap();
    let dims = grid.dims();
    let points = raw
        .iter()
        .map(|(kind, u, k)| {
            std::array::from_fn(|d| coordinate(kind[d], u[d], k[d], lengths[d], dims[d]))
        })
        .collect();
    (domain, cutoff, points)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn fast_paths_equal_brute_force_2d(
        lengths in prop::array::uniform2(1.0f64..40.0),
        periodic in prop::array::uniform2(any::<bool>()),
        cutoff_frac in 0.02f64..1.0,
        raw in prop::collection::vec((prop::array::uniform2(0u8..6), prop::array::uniform2(0.0f64..1.0), prop::array::uniform2(0usize..1000)), 0..300),
    ) {
        let (domain, cutoff, points) = input(lengths, periodic, cutoff_frac, &raw);
        check_all_paths(&domain, cutoff, &points);
    }

    #[test]
    fn fast_paths_equal_brute_force_3d(
        lengths in prop::array::uniform3(1.0f64..20.0),
        periodic in prop::array::uniform3(any::<bool>()),
        cutoff_frac in 0.05f64..1.0,
        raw in prop::collection::vec((prop::array::uniform3(0u8..6), prop::array::uniform3(0.0f64..1.0), prop::array::uniform3(0usize..1000)), 0..300),
    ) {
        let (domain, cutoff, points) = input(lengths, periodic, cutoff_frac, &raw);
        check_all_paths(&domain, cutoff, &points);
    }
}

/// The cutoff exactly half the box: one and two cells per axis, the largest cutoff
/// allowed, with points on a lattice so that many distances equal the cutoff exactly.
#[test]
fn half_box_cutoff_on_a_lattice() {
    for l in [1.0, 2.0, 3.0] {
        let domain = Domain::periodic([l, l, l]).unwrap();
        let mut pts = Vec::new();
        for x in 0..4 {
            for y in 0..4 {
                for z in 0..4 {
                    pts.push([x as f64 * l / 4.0, y as f64 * l / 4.0, z as f64 * l / 4.0]);
                }
            }
        }
        check_all_paths(&domain, l / 2.0, &pts);
        check_all_paths(&domain, 0.25 * l, &pts);
    }
}

/// 200 cells per side in 2D.
#[test]
fn two_hundred_cells_per_side() {
    let n = 20_000;
    let l = 200.0;
    let mut state = 12345u64;
    let mut next = || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    let pts: Vec<[f64; 2]> = (0..n).map(|_| [next() * l, next() * l]).collect();
    let domain = Domain::periodic([l, l]).unwrap();
    let cells = CellList::build(&domain, 0.999, &pts).unwrap();
    assert_eq!(cells.grid().dims(), [200, 200]);
    check_all_paths(&domain, 0.999, &pts);
}
