//! One component's pairs put into canonical order and given their levels (a
//! pair's level is one more than the highest level of the earlier pairs that
//! share a disc with it), then written level by level into the columns the
//! resolution reads.

use crate::models::billiards::rules::Separation;
use crate::threads::{
    counting_sort_with, map_parts, part_ranges, parts_for, DisjointSlice, Threads,
};

/// A pair of slots `a`, `b` as found, with its canonical key `(number[a],
/// number[b])` in one integer.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Staged {
    pub(super) key: u64,
    pub(super) a: u32,
    pub(super) b: u32,
    pub(super) sep: Separation,
}

/// The columns [`Components::group`] writes component by component, shared
/// between the components' tasks (each writes its own ranges).
///
/// [`Components::group`]: super::resolve::Components::group
pub(super) struct LevelColumns<'a> {
    pub(super) staged: DisjointSlice<'a, Staged>,
    pub(super) order: DisjointSlice<'a, u128>,
    pub(super) level: DisjointSlice<'a, u32>,
    pub(super) depth: DisjointSlice<'a, u32>,
    pub(super) bounds: DisjointSlice<'a, u32>,
    pub(super) a: DisjointSlice<'a, u32>,
    pub(super) b: DisjointSlice<'a, u32>,
    pub(super) dx: DisjointSlice<'a, f64>,
    pub(super) dy: DisjointSlice<'a, f64>,
    pub(super) q: DisjointSlice<'a, f64>,
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
    pub(super) unsafe fn sort_large(
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
    ///
    /// [`Components::group`]: super::resolve::Components::group
    pub(super) unsafe fn level(
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::models::billiards::components::strategies::pairs;
    use proptest::prelude::*;

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
    }
}
