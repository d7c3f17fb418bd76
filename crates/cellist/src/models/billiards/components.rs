//! Connected components of the overlap graph (SPEC.md section 4, E2): a resolution
//! changes velocities only inside one component, so each component runs the
//! canonical loop on its own (its wall discs ascending, then its pairs in
//! lexicographic order, until a sweep changes nothing), and components run in
//! parallel. Each component's discs are gathered into one contiguous block of
//! velocities, so every task owns its own range; the gather and the write-back
//! run in parts (a disc belongs to one component: each velocity is written once).
//!
//! Within a sweep only the order of the pairs that share a disc matters: each pair
//! reads and writes the velocities of its two discs alone. The pairs are therefore
//! run by *level* (a pair's level is one more than the highest level of the earlier
//! pairs, in canonical order, that share a disc with it). Every disc meets its
//! pairs in the canonical order, so the bits are those of the canonical loop, and
//! the pairs of one level share no disc, so they run four at a time in SIMD lanes
//! without waiting for each other.

use super::contacts::{row_groups, Contact};
use super::rules::{collide_four, Separation, Walls};
use crate::simd::F64x4;
use crate::threads::{
    counting_sort_parts, counting_sort_with, exclusive_sums, fill_in_parts, map_parts, part_ranges,
    parts_for, scatter_in_parts, sort_parts, DisjointSlice, Threads,
};
use rayon::prelude::*;

/// The pairs of all components by positions within their component's block,
/// structure of arrays, ordered by component, then level, then canonical order.
#[derive(Clone, Debug, Default)]
struct LocalPairs {
    a: Vec<u32>,
    b: Vec<u32>,
    dx: Vec<f64>,
    dy: Vec<f64>,
    q: Vec<f64>,
}

/// A pair of slots `a`, `b` as found, with its canonical key `(number[a],
/// number[b])` in one integer.
#[derive(Clone, Copy, Debug, Default)]
struct Staged {
    key: u64,
    a: u32,
    b: u32,
    sep: Separation,
}

/// A disc of a component's block: its velocity (16 bytes, so that four share a
/// cache line).
#[derive(Clone, Copy, Debug)]
struct LocalDisc {
    v: [f64; 2],
}

/// The components of one step and their buffers (kept between steps). The discs
/// are seen by *slot*: their places in a spatial order (the contact grid's
/// cells), so that the discs of a component, and the passes over them, lie close
/// together in memory; `number[slot]` is a disc's vector position, which alone
/// decides the canonical order.
#[derive(Clone, Debug, Default)]
pub(super) struct Components {
    /// By slot: the union-find's parent ([`SlotSets`]).
    parent: Vec<u32>,
    /// By part of [`Components::label_components`]: the pairs that reach a
    /// later part's slots.
    crossing: Vec<Vec<(u32, u32)>>,
    /// By part: the slots whose label waits for a root in an earlier part
    /// (their components' discs that are placed after the parts').
    pending: Vec<Vec<u32>>,
    /// By slot: the disc's component, or `NONE`.
    label: Vec<u32>,
    /// By slot: the disc's position in `members` (its place in its component's
    /// block plus the component's first position).
    local: Vec<u32>,
    member_start: Vec<u32>,
    /// Each component's discs (vector positions), in slot order, component by
    /// component (up to `member_start[components]`; room for all the discs).
    members: Vec<u32>,
    counts: Vec<u32>,
    /// Each component's first pair (in `staged` and in `pairs`).
    pair_start: Vec<u32>,
    /// The pairs by component, in the order found.
    staged: Vec<Staged>,
    /// By member position: one more than the level of the disc's latest pair.
    depth: Vec<u32>,
    /// Each component's pairs in canonical order: `key << 32 | position`
    /// (within the component's range of `staged`).
    order: Vec<u128>,
    /// The bucket offsets of a large component's sorts (scratch).
    sort_start: Vec<u32>,
    /// By pair, in canonical order: its level.
    level: Vec<u32>,
    /// Each component's number of levels.
    levels: Vec<u32>,
    /// Component `c`'s level bounds (pair positions), `levels[c] + 1` of them
    /// from `pair_start[c] + c` (room for one more than its pairs).
    run_bounds: Vec<u32>,
    pairs: LocalPairs,
    wall_start: Vec<u32>,
    walls: Vec<(u32, Walls)>,
    discs: Vec<LocalDisc>,
}

const NONE: u32 = u32::MAX;

/// What [`Components::label_components`] found: the number of components,
/// the parts of the slots it worked in, and the first component number of
/// each part's roots (the components rooted in part `g` are `firsts[g]..`
/// `firsts[g + 1]`, or `..components` for the last part; a slot of part `g`
/// with a smaller label is `pending`).
struct Labels {
    components: usize,
    parts: Vec<std::ops::Range<usize>>,
    firsts: Vec<u32>,
}

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

/// A label not yet known (see [`Components::label_components`]).
const PENDING: u32 = u32::MAX - 1;

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
    /// [`ContactGrid::search`]: super::ContactGrid::search
    pub(super) fn group(
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

    /// Numbers the components of the slots `0..n`, in parts over the
    /// threads: the sets joined by the pairs in `found` (rows of the search,
    /// see [`ContactGrid::search`]), those with a pair or a disc in `walls`
    /// (ascending slots). Sets `label[k]` to slot `k`'s component, or `NONE`,
    /// and `member_start[c + 1]` to component `c`'s size (counted as its
    /// slots are labelled), and returns their number with the parts
    /// and each part's first component ([`Labels`]). Component `c`
    /// is the one with the `c`-th smallest marked root (a root is its set's
    /// smallest slot; it is marked if its set has a pair, so that it was made
    /// a parent, or a wall disc), whatever the thread count.
    ///
    /// A pair's lower slot is its home disc's, and the rows hold their pairs
    /// by home slot, ascending: consecutive rows hold the pairs whose lower
    /// slots lie in one range. Each part takes its rows' range of slots and
    /// joins the pairs that lie within it ([`SlotSets::union`]), writing only
    /// its own parents (every root is its set's smallest slot); the pairs
    /// that reach a later range are joined after, in one thread. Then each
    /// part counts its marked roots, and a second pass labels its slots in
    /// slot order (a parent comes before its child): a root numbered after
    /// the marked roots before it, another slot its parent's label. The slots whose
    /// parent lies in an earlier part, and their descendants, are labelled
    /// after, in one thread, in slot order, from their parents.
    ///
    /// [`ContactGrid::search`]: super::ContactGrid::search
    fn label_components(
        &mut self,
        found: &[Vec<Contact>],
        walls: &[(u32, Walls)],
        n: usize,
        threads: &Threads,
    ) -> Labels {
        assert!(n <= PENDING as usize, "at most 2^32 - 2 discs");
        let groups = row_groups(found, threads.count());
        // part g's slots: from the first pair's lower slot in its rows (the
        // next part's start if it has none) to the next part's start
        let mut bounds = vec![n; groups.len() + 1];
        for g in (1..groups.len()).rev() {
            let first = found[groups[g].clone()].iter().flatten().next();
            bounds[g] = first.map_or(bounds[g + 1], |c| c.a.min(c.b) as usize);
        }
        bounds[0] = 0;
        let parts: Vec<std::ops::Range<usize>> = bounds.windows(2).map(|w| w[0]..w[1]).collect();
        self.parent.resize(n, 0);
        self.label.resize(n, 0);
        self.crossing.resize_with(parts.len(), Vec::new);
        self.pending.resize_with(parts.len(), Vec::new);

        // the pairs within each part's slots joined, every slot made a
        // parent marked (`label` 0: the root of a set of two or more is one)
        // and so are the discs on a wall, the other pairs kept for later
        let (parent, label) = (
            DisjointSlice::new(&mut self.parent),
            DisjointSlice::new(&mut self.label),
        );
        let crossing = DisjointSlice::new(&mut self.crossing);
        map_parts(Some(threads), parts.len(), |g| {
            let slots = parts[g].clone();
            // SAFETY: the parts' slots are disjoint, and part g alone takes
            // `crossing[g]`
            let (parent, label, crossing) = unsafe {
                (
                    parent.range(slots.clone()),
                    label.range(slots.clone()),
                    crossing.get(g),
                )
            };
            for (p, k) in parent.iter_mut().zip(slots.clone()) {
                *p = k as u32;
            }
            label.fill(NONE);
            crossing.clear();
            let mut sets = SlotSets {
                parent,
                first: slots.start,
            };
            for c in found[groups[g].clone()].iter().flatten() {
                let (low, high) = (c.a.min(c.b) as usize, c.a.max(c.b) as usize);
                assert!(slots.contains(&low), "a pair outside its rows' slots");
                if high < slots.end {
                    sets.union(low, high, |p| label[p - slots.start] = 0);
                } else {
                    crossing.push((low as u32, high as u32));
                }
            }
            let first_wall = walls.partition_point(|&(k, _)| (k as usize) < slots.start);
            for &(k, _) in walls[first_wall..]
                .iter()
                .take_while(|&&(k, _)| (k as usize) < slots.end)
            {
                label[k as usize - slots.start] = 0;
            }
        });
        let mut sets = SlotSets {
            parent: &mut self.parent,
            first: 0,
        };
        let label = &mut self.label;
        for &(low, high) in self.crossing.iter().flatten() {
            sets.union(low as usize, high as usize, |p| label[p] = 0);
        }

        // each part's marked roots (a streaming pass), so that each part
        // knows its first component number
        let (parent, label) = (&self.parent, &self.label);
        let counts = map_parts(Some(threads), parts.len(), |g| {
            let slots = parts[g].clone();
            let marked = parent[slots.clone()]
                .iter()
                .zip(&label[slots.clone()])
                .zip(slots)
                .filter(|&((&up, &mark), k)| up as usize == k && mark != NONE);
            marked.count() as u32
        });
        let firsts = exclusive_sums(&counts);
        let components = counts.iter().sum::<u32>() as usize;
        self.member_start.resize(components + 1, 0);

        // every slot labelled with its root's number in one pass in slot
        // order: a root numbered as it comes (its size, in
        // `member_start[number + 1]`, started at one), any other slot taking
        // its parent's label, which comes before it, and adding one to that
        // size; a slot whose parent lies in an earlier part (its set crosses
        // parts) is left `PENDING`, and so are its descendants, to be
        // labelled (and counted) after, in one thread
        let parent = &self.parent;
        let (labels, sizes) = (
            DisjointSlice::new(&mut self.label),
            DisjointSlice::new(&mut self.member_start),
        );
        let pending = DisjointSlice::new(&mut self.pending);
        map_parts(Some(threads), parts.len(), |g| {
            let slots = parts[g].clone();
            // SAFETY: the parts' slots are disjoint, and part g alone takes
            // `pending[g]`
            let (labels, pending) = unsafe { (labels.range(slots.clone()), pending.get(g)) };
            pending.clear();
            let mut next = firsts[g];
            for k in slots.clone() {
                let up = parent[k] as usize;
                let l = if up == k {
                    if labels[k - slots.start] == NONE {
                        NONE
                    } else {
                        // SAFETY: a part's roots' numbers are its own
                        *unsafe { sizes.get(next as usize + 1) } = 1;
                        next += 1;
                        next - 1
                    }
                } else if up >= slots.start && labels[up - slots.start] != PENDING {
                    let l = labels[up - slots.start];
                    // SAFETY: as above (the root of `l` is in this part)
                    *unsafe { sizes.get(l as usize + 1) } += 1;
                    l
                } else {
                    pending.push(k as u32);
                    PENDING
                };
                labels[k - slots.start] = l;
            }
        });
        // (in slot order, so a parent, below its child, is labelled first)
        for &k in self.pending.iter().flatten() {
            let l = self.label[self.parent[k as usize] as usize];
            self.label[k as usize] = l;
            self.member_start[l as usize + 1] += 1;
        }
        Labels {
            components,
            parts,
            firsts,
        }
    }

    /// Runs the canonical loop in every component, in parallel, and writes the new
    /// velocities back. Returns the largest sweep count (at least 1), or,
    /// of the components that had not settled within `max_sweeps`, the one with
    /// the smallest disc: that disc and the component's size.
    pub(super) fn resolve(
        &mut self,
        v: &mut [[f64; 2]],
        max_sweeps: u64,
        threads: &Threads,
    ) -> Result<u64, (usize, usize)> {
        let components = self.levels.len();
        let read: &[[f64; 2]] = v;
        let member_start = &self.member_start;
        let members = &self.members[..member_start[components] as usize];
        fill_in_parts(&mut self.discs, members.len(), Some(threads), |range| {
            members[range].iter().map(|&k| LocalDisc {
                v: read[k as usize],
            })
        });
        let (pairs, walls, wall_start) = (&self.pairs, &self.walls, &self.wall_start);
        let (pair_start, levels, run_bounds) = (&self.pair_start, &self.levels, &self.run_bounds);
        // (largest sweep count, (smallest disc, size) of the components that did
        // not settle)
        let shared = DisjointSlice::new(&mut self.discs);
        let (sweeps, failed) = threads.install(|| {
            (0..components)
                .into_par_iter()
                .map(|c| {
                    let range = member_start[c] as usize..member_start[c + 1] as usize;
                    // SAFETY: the components' member ranges are disjoint
                    let block = unsafe { shared.range(range.clone()) };
                    let runs = runs_of(pair_start, levels, run_bounds, c);
                    let component = Component {
                        walls: &walls[wall_start[c] as usize..wall_start[c + 1] as usize],
                        pairs: pairs.columns(runs[0] as usize..runs[runs.len() - 1] as usize),
                        runs,
                    };
                    match component.settle(block, max_sweeps) {
                        Some(sweeps) => (sweeps, (NONE, 0)),
                        None => {
                            let first = members[range.clone()].iter().min().copied();
                            (0, (first.unwrap_or(0), range.len()))
                        }
                    }
                })
                .reduce(|| (1, (NONE, 0)), |a, b| (a.0.max(b.0), a.1.min(b.1)))
        });
        let discs = &self.discs;
        // SAFETY: a disc is a member of one component, once
        unsafe {
            scatter_in_parts(v, members.len(), Some(threads), |slots| {
                members[slots.clone()]
                    .iter()
                    .zip(&discs[slots])
                    .map(|(&k, disc)| (k as usize, disc.v))
            });
        }
        match failed {
            (NONE, _) => Ok(sweeps),
            (first, size) => Err((first as usize, size)),
        }
    }
}

/// Whether component `c` (pairs from `pair_start[c]`) holds at least `1 /
/// LARGE_SHARE` of `n`, the number of discs, in pairs (and more than one).
fn is_large(pair_start: &[u32], c: usize, n: usize) -> bool {
    let pairs = (pair_start[c + 1] - pair_start[c]) as usize;
    pairs > 1 && pairs >= n / LARGE_SHARE
}

/// Component `c`'s level bounds in `run_bounds` (see [`Components`]):
/// `levels[c] + 1` pair positions, level `k`'s pairs from the `k`-th to the next.
fn runs_of<'a>(pair_start: &[u32], levels: &[u32], run_bounds: &'a [u32], c: usize) -> &'a [u32] {
    let first = pair_start[c] as usize + c;
    &run_bounds[first..=first + levels[c] as usize]
}

/// The columns [`Components::group`] writes component by component, shared
/// between the components' tasks (each writes its own ranges).
struct LevelColumns<'a> {
    staged: DisjointSlice<'a, Staged>,
    order: DisjointSlice<'a, u128>,
    level: DisjointSlice<'a, u32>,
    depth: DisjointSlice<'a, u32>,
    bounds: DisjointSlice<'a, u32>,
    a: DisjointSlice<'a, u32>,
    b: DisjointSlice<'a, u32>,
    dx: DisjointSlice<'a, f64>,
    dy: DisjointSlice<'a, f64>,
    q: DisjointSlice<'a, f64>,
}

impl LevelColumns<'_> {
    /// Puts the staged `pairs` of one component into canonical order in
    /// `order` (`key << 32 | position`, as [`LevelColumns::level`] reads them
    /// when given `sorted`): a counting sort by `number[a]` (`n` discs), then
    /// each disc's few pairs sorted by `number[b]`, both in parts on
    /// `threads`. `start` and `counts` are scratch.
    ///
    /// # Safety
    /// No other call reaches this component's range at once.
    unsafe fn sort_large(
        &self,
        pairs: std::ops::Range<usize>,
        n: usize,
        threads: &Threads,
        start: &mut Vec<u32>,
        counts: &mut Vec<u32>,
    ) {
        // SAFETY: the caller's promise
        let (staged, order) = unsafe {
            (
                &*self.staged.range(pairs.clone()),
                self.order.range(pairs.clone()),
            )
        };
        let slots = DisjointSlice::new(order);
        // SAFETY: the keys read `staged`, unchanged during the sort; every
        // slot is given once, below the number of pairs
        unsafe {
            counting_sort_with(
                staged.len(),
                |i| (staged[i].key >> 32) as u32,
                n,
                Some(threads),
                start,
                counts,
                |i, slot| {
                    *slots.get_unchecked(slot) = (u128::from(staged[i].key) << 32) | i as u128
                },
            );
        }
        let (start, discs) = (&*start, part_ranges(n, parts_for(Some(threads))));
        map_parts(Some(threads), discs.len(), |p| {
            for disc in discs[p].clone() {
                let (first, end) = (start[disc] as usize, start[disc + 1] as usize);
                if end - first > 1 {
                    // SAFETY: the discs' ranges of `order` are disjoint
                    unsafe { slots.range(first..end) }.sort_unstable();
                }
            }
        });
    }

    /// Component `c`, whose staged pairs are `pairs` and whose discs are the
    /// member positions `discs`: sorts its pairs into canonical order (by
    /// `(number[a], number[b])`; unless `sorted`: then `order` already holds
    /// them in that order), gives each its level, places them
    /// level by level (canonical order within a level) into the columns, with
    /// local disc positions, and writes the level bounds; returns the number
    /// of levels.
    ///
    /// # Safety
    /// No two calls at once may share a component, and the ranges of different
    /// components must be disjoint (as [`Components::group`] makes them).
    unsafe fn level(
        &self,
        c: usize,
        pairs: std::ops::Range<usize>,
        discs: std::ops::Range<usize>,
        local: &[u32],
        sorted: bool,
    ) -> u32 {
        let first = pairs.start + c;
        // SAFETY: the caller's promise
        let staged = unsafe { self.staged.range(pairs.clone()) };
        // the disc positions within the block
        let block = |slot: u32| local[slot as usize] - discs.start as u32;
        let levels = if let [p] = staged {
            // one pair (most components): one level
            // SAFETY: the caller's promise
            unsafe { self.place(pairs.start, p, block(p.a), block(p.b)) };
            1
        } else {
            // SAFETY: the caller's promise
            let (level, depth) = unsafe {
                (
                    self.level.range(pairs.clone()),
                    self.depth.range(discs.clone()),
                )
            };
            // the canonical order: the keys with their positions, sorted (16
            // bytes to move instead of a pair's 40)
            // SAFETY: the caller's promise
            let order = unsafe { self.order.range(pairs.clone()) };
            if !sorted {
                for (k, (o, p)) in order.iter_mut().zip(staged.iter()).enumerate() {
                    *o = (u128::from(p.key) << 32) | k as u128;
                }
                order.sort_unstable();
            }
            depth.fill(0);
            let mut levels = 0;
            for (o, l) in order.iter_mut().zip(level.iter_mut()) {
                let p = &mut staged[*o as u32 as usize];
                // (the slots are not needed after this: the positions replace them)
                (p.a, p.b) = (block(p.a), block(p.b));
                let (a, b) = (p.a as usize, p.b as usize);
                *l = depth[a].max(depth[b]);
                depth[a] = *l + 1;
                depth[b] = *l + 1;
                levels = levels.max(*l + 1);
            }
            // a counting sort by level: `bounds[l]` first counts level l - 1,
            // then is level l's cursor, then (shifted by one) its first position
            // SAFETY: `levels <= pairs.len()`, within the component's room
            let bounds = unsafe { self.bounds.range(first..first + levels as usize + 1) };
            bounds.fill(0);
            for &l in level.iter() {
                bounds[l as usize + 1] += 1;
            }
            for k in 1..bounds.len() {
                bounds[k] += bounds[k - 1];
            }
            for (o, &l) in order.iter().zip(level.iter()) {
                let p = &staged[*o as u32 as usize];
                let cursor = &mut bounds[l as usize];
                // SAFETY: the slot lies in the component's pairs, given once
                unsafe { self.place(pairs.start + *cursor as usize, p, p.a, p.b) };
                *cursor += 1;
            }
            for k in (1..levels as usize).rev() {
                bounds[k] = bounds[k - 1];
            }
            bounds[0] = 0;
            levels
        };
        // SAFETY: as above
        let bounds = unsafe { self.bounds.range(first..first + levels as usize + 1) };
        if levels == 1 {
            bounds.copy_from_slice(&[0, pairs.len() as u32]);
        }
        for bound in bounds.iter_mut() {
            *bound += pairs.start as u32;
        }
        levels
    }

    /// Writes pair `p` into the columns at `slot`, with the block positions `a`
    /// and `b` of its discs.
    ///
    /// # Safety
    /// `slot` is below the columns' length, and no other call writes it at once.
    #[inline]
    unsafe fn place(&self, slot: usize, p: &Staged, a: u32, b: u32) {
        // SAFETY: the caller's promise
        unsafe {
            *self.a.get_unchecked(slot) = a;
            *self.b.get_unchecked(slot) = b;
            *self.dx.get_unchecked(slot) = p.sep.dx;
            *self.dy.get_unchecked(slot) = p.sep.dy;
            *self.q.get_unchecked(slot) = p.sep.q;
        }
    }
}

/// A union-find over the slots `first..first + parent.len()` (one part's, or
/// all), `parent` by slot from `first`, in which every root is the smallest
/// slot of its set: a parent is never above its child.
pub(super) struct SlotSets<'a> {
    pub(super) parent: &'a mut [u32],
    pub(super) first: usize,
}

impl SlotSets<'_> {
    /// Joins the sets of `a` and `b` by Rem's algorithm with splicing: the
    /// two paths are climbed together, the slot whose parent is the larger
    /// taking the other's parent (so a parent stays below its child) and
    /// the climb going on from its old parent, until the parents meet (one
    /// set) or a root takes the other's parent (the sets joined; the smaller
    /// root stays the root). `adopted(p)` is called with every slot `p` made
    /// a parent, so that, over the calls, the root of every set of two or
    /// more slots has been passed to it (as long as `parent` started as the
    /// identity and changed only here and in [`SlotSets::root`]).
    #[inline]
    pub(super) fn union(&mut self, a: usize, b: usize, mut adopted: impl FnMut(usize)) {
        let first = self.first;
        let (mut x, mut y) = (a, b);
        loop {
            let (px, py) = (
                self.parent[x - first] as usize,
                self.parent[y - first] as usize,
            );
            if px == py {
                return;
            }
            let (climber, old, new) = if px > py {
                (&mut x, px, py)
            } else {
                (&mut y, py, px)
            };
            self.parent[*climber - first] = new as u32;
            adopted(new);
            if *climber == old {
                return;
            }
            *climber = old;
        }
    }

    /// The root of `k`'s set (its smallest slot), halving the path on the way.
    pub(super) fn root(&mut self, mut k: usize) -> usize {
        loop {
            let up = self.parent[k - self.first] as usize;
            if up == k {
                return k;
            }
            let grand = self.parent[up - self.first];
            self.parent[k - self.first] = grand;
            k = grand as usize;
        }
    }
}

/// One component's pairs: the columns of [`LocalPairs`] over its range.
#[derive(Clone, Copy)]
struct PairColumns<'a> {
    a: &'a [u32],
    b: &'a [u32],
    dx: &'a [f64],
    dy: &'a [f64],
    q: &'a [f64],
}

impl LocalPairs {
    fn columns(&self, range: std::ops::Range<usize>) -> PairColumns<'_> {
        PairColumns {
            a: &self.a[range.clone()],
            b: &self.b[range.clone()],
            dx: &self.dx[range.clone()],
            dy: &self.dy[range.clone()],
            q: &self.q[range],
        }
    }
}

/// One component's walls (ascending) and its pairs, run by run.
struct Component<'a> {
    walls: &'a [(u32, Walls)],
    pairs: PairColumns<'a>,
    /// `runs[k] - runs[0]..runs[k + 1] - runs[0]`: the pairs of level `k`.
    runs: &'a [u32],
}

impl Component<'_> {
    /// The canonical loop on this component: sweeps until one changes nothing; the
    /// number of sweeps (the last included), or `None` past `max_sweeps`.
    fn settle(&self, block: &mut [LocalDisc], max_sweeps: u64) -> Option<u64> {
        let p = self.pairs;
        // the lanes below index `block` unchecked
        assert!(p.a.iter().chain(p.b).all(|&k| (k as usize) < block.len()));
        let mut sweeps = 0;
        loop {
            sweeps += 1;
            if sweeps > max_sweeps {
                return None;
            }
            let mut changed = false;
            for (k, w) in self.walls {
                let v = &mut block[*k as usize].v;
                if w.collides(v) {
                    w.resolve(v);
                    changed = true;
                }
            }
            let first = self.runs[0];
            for run in self.runs.windows(2) {
                let (start, end) = ((run[0] - first) as usize, (run[1] - first) as usize);
                let four = start + (end - start) / 4 * 4;
                for lanes in (start..four).step_by(4) {
                    let lanes = lanes..lanes + 4;
                    let a: [u32; 4] = p.a[lanes.clone()].try_into().unwrap();
                    let b: [u32; 4] = p.b[lanes.clone()].try_into().unwrap();
                    let separation =
                        [p.dx, p.dy, p.q].map(|column| F64x4::load(&column[lanes.clone()]));
                    // SAFETY: every index was checked against `block.len()` above
                    let velocity = |k: u32| unsafe { block.get_unchecked(k as usize).v };
                    let (mut va, mut vb) = (a.map(velocity), b.map(velocity));
                    changed |= collide_four(separation, &mut va, &mut vb);
                    for l in 0..4 {
                        // SAFETY: as above
                        unsafe {
                            block.get_unchecked_mut(a[l] as usize).v = va[l];
                            block.get_unchecked_mut(b[l] as usize).v = vb[l];
                        }
                    }
                }
                for pair in four..end {
                    let (a, b) = (p.a[pair] as usize, p.b[pair] as usize);
                    let sep = Separation {
                        dx: p.dx[pair],
                        dy: p.dy[pair],
                        q: p.q[pair],
                    };
                    let (mut va, mut vb) = (block[a].v, block[b].v);
                    if sep.collide(&mut va, &mut vb) {
                        block[a].v = va;
                        block[b].v = vb;
                        changed = true;
                    }
                }
            }
            if !changed {
                return Some(sweeps);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::models::billiards::ContactGrid;
    use crate::random::Rng;
    use proptest::prelude::*;

    /// What [`Components::group`] is given, and the pairs by vector position.
    struct Scene {
        n: usize,
        /// The pairs by vector position, in canonical order ([`ContactGrid::find`]).
        contacts: Vec<Contact>,
        /// The same pairs as the search found them (slots).
        found: Vec<Vec<Contact>>,
        /// The discs on a wall, by slot, ascending.
        walls: Vec<(u32, Walls)>,
        /// Each slot's disc.
        number: Vec<u32>,
    }

    impl Scene {
        /// Each disc's slot.
        fn slot_of(&self) -> Vec<u32> {
            let mut slot_of = vec![0; self.n];
            for (k, &d) in self.number.iter().enumerate() {
                slot_of[d as usize] = k as u32;
            }
            slot_of
        }

        fn group(&self, threads: usize) -> Components {
            let mut components = Components::default();
            let pool = Threads::new(threads).unwrap();
            components.group(&self.found, &self.walls, &self.number, &pool);
            components
        }
    }

    /// 2000 discs at random in a 60 x 60 square, in contact within `q <= limit`,
    /// the last five far from everything; every 97th disc and the far ones on a
    /// wall, so that some components are walls only.
    fn scattered_discs(limit: f64) -> Scene {
        let mut rng = Rng::new(5);
        let n = 2000;
        let mut x: Vec<f64> = (0..n).map(|_| rng.uniform() * 60.0).collect();
        let mut y: Vec<f64> = (0..n).map(|_| rng.uniform() * 60.0).collect();
        // the last few far from everything
        for k in n - 5..n {
            (x[k], y[k]) = (500.0 + 10.0 * k as f64, 500.0);
        }
        let mut contacts = Vec::new();
        // (the cells over the square alone: the search's rows then split its
        // pairs into parts of the slots, with pairs across them)
        let mut grid = ContactGrid::default().with_region([0.0; 2], [60.0; 2]);
        grid.find(&x, &y, limit, &Threads::single(), &mut contacts);
        // some discs on a wall, some of them without a pair: components of walls only
        let wall = Walls {
            low_x: true,
            ..Walls::default()
        };
        let number = grid.nearby_order().to_vec();
        let walls: Vec<(u32, Walls)> = (0..n as u32)
            .filter(|&k| number[k as usize] % 97 == 0 || number[k as usize] as usize >= n - 5)
            .map(|k| (k, wall))
            .collect();
        Scene {
            n,
            contacts,
            found: grid.found().to_vec(),
            walls,
            number,
        }
    }

    #[test]
    fn components_are_the_connected_sets_numbered_by_their_smallest_slot() {
        // about 1.7 contacts per disc: many components, some of them large
        let scene = scattered_discs(1.0);
        let n = scene.n;
        // the reference: connected sets by a search over the contact graph
        let mut neighbours = vec![Vec::new(); n];
        for c in &scene.contacts {
            neighbours[c.a as usize].push(c.b as usize);
            neighbours[c.b as usize].push(c.a as usize);
        }
        let slot_of = scene.slot_of();
        let on_wall: std::collections::HashSet<usize> = scene
            .walls
            .iter()
            .map(|&(k, _)| scene.number[k as usize] as usize)
            .collect();
        let mut seen = vec![false; n];
        let mut expected: Vec<Vec<u32>> = Vec::new();
        for first in 0..n {
            if seen[first] || (neighbours[first].is_empty() && !on_wall.contains(&first)) {
                continue;
            }
            seen[first] = true;
            let (mut set, mut stack) = (vec![first as u32], vec![first]);
            while let Some(d) = stack.pop() {
                for &e in &neighbours[d] {
                    if !std::mem::replace(&mut seen[e], true) {
                        set.push(e as u32);
                        stack.push(e);
                    }
                }
            }
            set.sort_unstable();
            expected.push(set);
        }
        expected.sort_by_key(|set| set.iter().map(|&d| slot_of[d as usize]).min());
        assert!(expected.len() > 100 && expected.iter().any(|set| set.len() > 10));
        // (the search's rows split in 2, 3 and 7 parts: pairs across parts)
        for threads in [1, 2, 3, 7] {
            let c = scene.group(threads);
            // (the case the parts exist for: pairs joined across them)
            let across: usize = c.crossing.iter().map(Vec::len).sum();
            assert_eq!(across > 0, threads > 1, "{threads} thread(s)");
            // (and slots of components rooted in an earlier part)
            let pending: usize = c.pending.iter().map(Vec::len).sum();
            assert_eq!(pending > 0, threads > 1, "{threads} thread(s)");
            let found: Vec<Vec<u32>> = c
                .member_start
                .windows(2)
                .map(|w| {
                    let mut set = c.members[w[0] as usize..w[1] as usize].to_vec();
                    set.sort_unstable();
                    set
                })
                .collect();
            assert_eq!(found, expected, "{threads} thread(s)");
        }
    }

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

    /// Distinct pairs `(a, b)`, `a != b`, of discs below `n`, in any order.
    fn pairs() -> impl Strategy<Value = (usize, Vec<(u32, u32)>)> {
        (2usize..60).prop_flat_map(|n| {
            let pair = (0..n as u32, 0..n as u32).prop_filter("two discs", |(a, b)| a != b);
            (
                Just(n),
                prop::collection::vec(pair, 0..300).prop_map(|mut pairs| {
                    let mut seen = std::collections::HashSet::new();
                    pairs.retain(|&p| seen.insert(p));
                    pairs
                }),
            )
        })
    }

    proptest! {
        #[test]
        fn the_counting_sorts_of_a_large_component_give_the_canonical_order(
            (n, pairs) in pairs(),
            threads in 1usize..4,
        ) {
            let m = pairs.len();
            let mut staged: Vec<Staged> = pairs
                .iter()
                .map(|&(a, b)| Staged {
                    key: (u64::from(a) << 32) | u64::from(b),
                    ..Staged::default()
                })
                .collect();
            let (mut order, mut level, mut depth, mut bounds) =
                (vec![0u128; m], vec![0; m], vec![0; n], vec![0; m + 1]);
            let (mut a, mut b) = (vec![0; m], vec![0; m]);
            let (mut dx, mut dy, mut q) = (vec![0.0; m], vec![0.0; m], vec![0.0; m]);
            let columns = LevelColumns {
                staged: DisjointSlice::new(&mut staged),
                order: DisjointSlice::new(&mut order),
                level: DisjointSlice::new(&mut level),
                depth: DisjointSlice::new(&mut depth),
                bounds: DisjointSlice::new(&mut bounds),
                a: DisjointSlice::new(&mut a),
                b: DisjointSlice::new(&mut b),
                dx: DisjointSlice::new(&mut dx),
                dy: DisjointSlice::new(&mut dy),
                q: DisjointSlice::new(&mut q),
            };
            let pool = Threads::new(threads).unwrap();
            // SAFETY: one call, over all the columns
            unsafe {
                columns.sort_large(0..m, n, &pool, &mut Vec::new(), &mut Vec::new());
            }
            let mut expected: Vec<(u32, u32)> = pairs.clone();
            expected.sort_unstable();
            let sorted: Vec<(u32, u32)> = order.iter().map(|&o| pairs[o as u32 as usize]).collect();
            prop_assert_eq!(sorted, expected);
            // the keys ride along, as the comparison sort leaves them
            for &o in &order {
                prop_assert_eq!((o >> 32) as u64, staged[o as u32 as usize].key);
            }
        }

        #[test]
        fn the_union_gives_the_connected_sets_rooted_at_their_smallest_slot(
            (n, pairs) in pairs(),
            first in 0usize..100,
        ) {
            // slots `first..first + n`, as one part's
            let mut parent: Vec<u32> = (first as u32..(first + n) as u32).collect();
            let mut adopted = vec![false; n];
            let mut sets = SlotSets { parent: &mut parent, first };
            for &(a, b) in &pairs {
                sets.union(first + a as usize, first + b as usize, |p| adopted[p - first] = true);
            }
            // the connected sets by a graph search: each slot's smallest
            // reachable slot
            let mut next = vec![Vec::new(); n];
            for &(a, b) in &pairs {
                next[a as usize].push(b as usize);
                next[b as usize].push(a as usize);
            }
            let mut smallest = vec![usize::MAX; n];
            for start in 0..n {
                if smallest[start] == usize::MAX {
                    let mut stack = vec![start];
                    smallest[start] = start;
                    while let Some(k) = stack.pop() {
                        for &j in &next[k] {
                            if smallest[j] == usize::MAX {
                                smallest[j] = start;
                                stack.push(j);
                            }
                        }
                    }
                }
            }
            for k in 0..n {
                prop_assert!(sets.parent[k] as usize <= first + k, "a parent above its child");
                prop_assert_eq!(sets.root(first + k), first + smallest[k]);
                // a root of a set of two or more was made a parent
                if smallest[k] == k {
                    prop_assert_eq!(adopted[k], !next[k].is_empty());
                }
            }
        }
    }
}
