//! The discs in a contact or on a wall split into components: each component's
//! discs gathered into one block, its pairs staged, sorted and levelled, its walls
//! listed, all in parts over the threads.

use super::label::Labels;
use super::levels::{LevelColumns, Staged};
use super::resolve::{Components, NONE};
use crate::models::billiards::contacts::{row_groups, Contact};
use crate::models::billiards::rules::Walls;
use crate::threads::{
    counting_sort_parts, counting_sort_with, map_parts, sort_parts, DisjointSlice, Threads,
};
use rayon::prelude::*;

/// The columns [`Components::group`] places the discs into, by component: each
/// component's next position (its cursor), the discs by position, and each
/// slot's position.
struct Placed<'a> {
    members: DisjointSlice<'a, u32>,
    local: DisjointSlice<'a, u32>,
    cursors: DisjointSlice<'a, u32>,
}

impl Placed<'_> {
    /// Places slot `k`, disc `disc` of component `c`, at the component's next
    /// position.
    ///
    /// # Safety
    /// No other call reaches component `c` or slot `k` at once.
    #[inline]
    unsafe fn next(&self, k: usize, c: u32, disc: u32) {
        // SAFETY: the caller's promise
        unsafe {
            let position = self.cursors.get(c as usize);
            *self.members.get(*position as usize) = disc;
            *self.local.get(k) = *position;
            *position += 1;
        }
    }
}

/// A component with at least `1 / LARGE_SHARE` of the discs' number in pairs
/// is sorted by counting sorts over all the discs ([`LevelColumns::sort_large`]).
const LARGE_SHARE: usize = 4;

impl Components {
    /// Splits the discs in a contact or on a wall into components. `found`
    /// holds the pairs (slots, roles by vector position) as the search found
    /// them (the rows of [`ContactGrid::search`]), `walls` the discs (slots,
    /// ascending) on a wall, `number` every slot's disc (a permutation of
    /// `0..n`). A component's walls keep the order of `walls` (any order would
    /// do: a wall touches one disc), and its pairs run level by level, the
    /// levels taken in canonical order (by the vector positions of `(a, b)`):
    /// see the module's text. The components are found in parts over the
    /// threads ([`Components::label_components`]). Each component sorts and
    /// levels its own pairs, in parallel with the others; a large one (a dense
    /// packing has one with nearly all the pairs) is sorted first, with
    /// counting sorts in parts over the threads, and levelled in one task
    /// while the others are levelled in tasks of their own. Each component's
    /// discs are stored in slot order; where a disc is stored, and how the
    /// components are numbered, do not change what is computed.
    ///
    /// [`ContactGrid::search`]: crate::models::billiards::contacts::ContactGrid::search
    pub(in crate::models::billiards) fn group(
        &mut self,
        found: &[Vec<Contact>],
        walls: &[(u32, Walls)],
        number: &[u32],
        threads: &Threads,
    ) {
        let n = number.len();
        let Labels {
            components,
            parts,
            firsts,
        } = self.label_components(found, walls, n, threads);

        // the discs by component, in slot order within each (the sizes, in
        // `member_start[c + 1]`, summed into first positions), and each slot's
        // position in `members` (which keeps room for all the discs): each
        // part places the discs of the components rooted in it, which come
        // first in their components; then the slots of components rooted in
        // an earlier part (`pending`), in one thread, in slot order
        self.member_start[0] = 0;
        for c in 1..=components {
            self.member_start[c] += self.member_start[c - 1];
        }
        self.members.resize(n, 0);
        self.local.resize(n, 0);
        self.counts.clear();
        self.counts
            .extend_from_slice(&self.member_start[..components]);
        let (label, pending) = (&self.label, &self.pending);
        let placed = Placed {
            members: DisjointSlice::new(&mut self.members),
            local: DisjointSlice::new(&mut self.local),
            cursors: DisjointSlice::new(&mut self.counts),
        };
        map_parts(Some(threads), parts.len(), |g| {
            for k in parts[g].clone() {
                let c = label[k];
                if c != NONE && c >= firsts[g] {
                    // SAFETY: component c is rooted in part g, so its cursor
                    // and the positions it gives are this part's alone, and
                    // so is slot k
                    unsafe { placed.next(k, c, number[k]) };
                }
            }
        });
        for &k in pending.iter().flatten() {
            let k = k as usize;
            // SAFETY: one thread, after the parts
            unsafe { placed.next(k, label[k], number[k]) };
        }
        let in_components = self.member_start[components] as usize;
        let label = &self.label;

        // pairs by component, in the order found within each
        let m: usize = found.iter().map(Vec::len).sum();
        self.staged.resize(m, Staged::default());
        let staged = DisjointSlice::new(&mut self.staged);
        let place = |c: &Contact, slot| {
            let key = (u64::from(number[c.a as usize]) << 32) | u64::from(number[c.b as usize]);
            let pair = Staged {
                key,
                a: c.a,
                b: c.b,
                sep: c.sep,
            };
            // SAFETY: every slot is given once, below the column's length
            *unsafe { staged.get_unchecked(slot) } = pair;
        };
        let groups = row_groups(found, sort_parts(m, components, Some(threads)));
        // SAFETY: the rows and labels do not change during the sort
        unsafe {
            counting_sort_parts(
                groups.len(),
                |g| found[groups[g].clone()].iter().flatten(),
                |c| label[c.a as usize],
                components,
                Some(threads),
                &mut self.pair_start,
                &mut self.counts,
                place,
            );
        }

        // each component on its own: its pairs in canonical order, their levels
        // (one more than the highest level among the earlier pairs sharing a
        // disc), then by level into the columns
        let pairs = &mut self.pairs;
        for column in [&mut pairs.a, &mut pairs.b, &mut self.level] {
            column.resize(m, 0);
        }
        for column in [&mut pairs.dx, &mut pairs.dy, &mut pairs.q] {
            column.resize(m, 0.0);
        }
        self.order.resize(m, 0);
        self.depth.resize(in_components, 0);
        self.run_bounds.resize(m + components, 0);
        self.levels.resize(components, 0);
        let columns = LevelColumns {
            staged: DisjointSlice::new(&mut self.staged),
            order: DisjointSlice::new(&mut self.order),
            level: DisjointSlice::new(&mut self.level),
            depth: DisjointSlice::new(&mut self.depth),
            bounds: DisjointSlice::new(&mut self.run_bounds),
            a: DisjointSlice::new(&mut pairs.a),
            b: DisjointSlice::new(&mut pairs.b),
            dx: DisjointSlice::new(&mut pairs.dx),
            dy: DisjointSlice::new(&mut pairs.dy),
            q: DisjointSlice::new(&mut pairs.q),
        };
        let (pair_start, member_start, local) = (&self.pair_start, &self.member_start, &self.local);
        // a component with a large share of the pairs (a dense packing has one
        // with nearly all) is sorted first, by counting sorts in parts over the
        // threads, rather than by one task; then it is levelled in one task
        // while the others are levelled in tasks of their own
        let large = |c: usize| is_large(pair_start, c, n);
        let pairs_of = |c: usize| pair_start[c] as usize..pair_start[c + 1] as usize;
        let discs_of = |c: usize| member_start[c] as usize..member_start[c + 1] as usize;
        for c in (0..components).filter(|&c| large(c)) {
            // SAFETY: one component at a time, before the tasks below
            unsafe {
                columns.sort_large(
                    pairs_of(c),
                    n,
                    threads,
                    &mut self.sort_start,
                    &mut self.counts,
                );
            }
        }
        let level = |c: usize| {
            // SAFETY: the components' pairs, discs and bounds are disjoint
            unsafe { columns.level(c, pairs_of(c), discs_of(c), local, large(c)) }
        };
        let levels = DisjointSlice::new(&mut self.levels);
        threads.install(|| {
            rayon::join(
                || {
                    for c in (0..components).filter(|&c| large(c)) {
                        // SAFETY: each component's level count is written once
                        *unsafe { levels.get(c) } = level(c);
                    }
                },
                || {
                    (0..components)
                        .into_par_iter()
                        .filter(|&c| !large(c))
                        .for_each(|c| {
                            // SAFETY: as above
                            *unsafe { levels.get(c) } = level(c);
                        })
                },
            )
        });

        // walls by component, in the order of `walls` within each
        self.walls.clear();
        self.walls.resize(walls.len(), (0, Walls::default()));
        let (label, local, member_start) = (&self.label, &self.local, &self.member_start);
        let placed = DisjointSlice::new(&mut self.walls);
        // SAFETY: every slot is given once, below the column's length
        let place = |i: usize, slot| {
            let (k, walls) = (walls[i].0 as usize, walls[i].1);
            let position = local[k] - member_start[label[k] as usize];
            *unsafe { placed.get_unchecked(slot) } = (position, walls)
        };
        // SAFETY: the key reads `walls` and `label`, unchanged during the sort
        unsafe {
            counting_sort_with(
                walls.len(),
                |i| label[walls[i].0 as usize],
                components,
                Some(threads),
                &mut self.wall_start,
                &mut self.counts,
                place,
            );
        }
    }
}

/// Whether component `c` (pairs from `pair_start[c]`) holds at least `1 /
/// LARGE_SHARE` of `n`, the number of discs, in pairs (and more than one).
fn is_large(pair_start: &[u32], c: usize, n: usize) -> bool {
    let pairs = (pair_start[c + 1] - pair_start[c]) as usize;
    pairs > 1 && pairs >= n / LARGE_SHARE
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::models::billiards::components::resolve::runs_of;
    use crate::models::billiards::components::testing::scattered_discs;

    #[test]
    fn levels_share_no_disc_and_every_disc_meets_its_pairs_in_canonical_order() {
        // about 7 contacts per disc: one large component, sorted by counting
        // sorts, beside small ones
        let scene = scattered_discs(4.0);
        let c = &scene.group(1);
        let components_count = c.member_start.len() - 1;
        let large = (0..components_count).filter(|&k| is_large(&c.pair_start, k, scene.n));
        assert_eq!(large.count(), 1, "the test should have one large component");
        // the same grouping, to the bit, on two and three threads
        for threads in [2, 3] {
            let other = scene.group(threads);
            assert_eq!(other.members, c.members);
            assert_eq!(other.member_start, c.member_start);
            assert_eq!(other.pair_start, c.pair_start);
            assert_eq!(other.levels, c.levels);
            assert_eq!(other.run_bounds, c.run_bounds);
            assert_eq!(other.wall_start, c.wall_start);
            assert_eq!(other.walls, c.walls);
            let p = (&other.pairs, &c.pairs);
            assert!(p.0.a == p.1.a && p.0.b == p.1.b && p.0.q == p.1.q);
            assert!(p.0.dx == p.1.dx && p.0.dy == p.1.dy);
        }
        assert_eq!(c.pairs.a.len(), scene.contacts.len());
        assert_eq!(c.walls.len(), scene.walls.len());
        let mut wall_only = 0;
        let mut largest_run = 0;
        let mut rows: Vec<(u32, u32, [u64; 3])> = Vec::new();
        for comp in 0..components_count {
            let global = |local: u32| c.members[(c.member_start[comp] + local) as usize];
            let runs = runs_of(&c.pair_start, &c.levels, &c.run_bounds, comp);
            wall_only += usize::from(runs.len() == 1);
            // the (a, b) of this component's pairs in the order they run
            let order: Vec<(u32, u32)> = (runs[0]..runs[runs.len() - 1])
                .map(|i| (global(c.pairs.a[i as usize]), global(c.pairs.b[i as usize])))
                .collect();
            for run in runs.windows(2) {
                // as many levels as the deepest pair needs, none empty
                assert!(run[1] > run[0], "component {comp} has an empty level");
                let range = (run[0] - runs[0]) as usize..(run[1] - runs[0]) as usize;
                largest_run = largest_run.max(range.len());
                let mut discs: Vec<u32> = order[range].iter().flat_map(|&(a, b)| [a, b]).collect();
                let count = discs.len();
                discs.sort_unstable();
                discs.dedup();
                assert_eq!(discs.len(), count, "a level shares a disc");
            }
            // each disc's pairs, in running order, are in lexicographic order
            let mut last_seen = std::collections::HashMap::new();
            for &(a, b) in &order {
                for d in [a, b] {
                    if let Some(&previous) = last_seen.get(&d) {
                        assert!(
                            previous < (a, b),
                            "disc {d} meets {previous:?} after {a},{b}"
                        );
                    }
                    last_seen.insert(d, (a, b));
                }
            }
            for i in runs[0] as usize..runs[runs.len() - 1] as usize {
                let p = &c.pairs;
                let sep = [p.dx[i], p.dy[i], p.q[i]].map(f64::to_bits);
                rows.push((global(p.a[i]), global(p.b[i]), sep));
            }
        }
        assert!(
            largest_run >= 8,
            "the test should have levels worth running in lanes"
        );
        assert!(
            wall_only > 0,
            "the test should have components of walls only"
        );
        // the rows (global a, b, separation) are exactly the contacts
        rows.sort_unstable();
        let expected: Vec<(u32, u32, [u64; 3])> = scene
            .contacts
            .iter()
            .map(|k| (k.a, k.b, [k.sep.dx, k.sep.dy, k.sep.q].map(f64::to_bits)))
            .collect();
        assert_eq!(rows, expected);
    }
}
