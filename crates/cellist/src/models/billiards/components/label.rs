//! The components of the overlap graph found and numbered: a union-find over
//! the slots ([`SlotSets`]), run in parts over the threads, the pairs across
//! parts joined after, then every slot labelled with its component.

use super::resolve::{Components, NONE};
use crate::models::billiards::contacts::{row_groups, Contact};
use crate::models::billiards::rules::Walls;
use crate::threads::{exclusive_sums, map_parts, DisjointSlice, Threads};

/// What [`Components::label_components`] found: the number of components,
/// the parts of the slots it worked in, and the first component number of
/// each part's roots (the components rooted in part `g` are `firsts[g]..`
/// `firsts[g + 1]`, or `..components` for the last part; a slot of part `g`
/// with a smaller label is `pending`).
pub(super) struct Labels {
    pub(super) components: usize,
    pub(super) parts: Vec<std::ops::Range<usize>>,
    pub(super) firsts: Vec<u32>,
}

/// A label not yet known (see [`Components::label_components`]).
const PENDING: u32 = u32::MAX - 1;

impl Components {
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
    /// [`ContactGrid::search`]: crate::models::billiards::contacts::ContactGrid::search
    pub(super) fn label_components(
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
}

/// A union-find over the slots `first..first + parent.len()` (one part's, or
/// all), `parent` by slot from `first`, in which every root is the smallest
/// slot of its set: a parent is never above its child.
pub(in crate::models::billiards) struct SlotSets<'a> {
    pub(in crate::models::billiards) parent: &'a mut [u32],
    pub(in crate::models::billiards) first: usize,
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
    pub(in crate::models::billiards) fn union(
        &mut self,
        a: usize,
        b: usize,
        mut adopted: impl FnMut(usize),
    ) {
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
    pub(in crate::models::billiards) fn root(&mut self, mut k: usize) -> usize {
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::models::billiards::components::strategies::pairs;
    use crate::models::billiards::components::testing::scattered_discs;
    use proptest::prelude::*;

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

    proptest! {
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
