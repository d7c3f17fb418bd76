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

use super::contacts::Contact;
use super::rules::{collide_four, Separation, Walls};
use crate::simd::F64x4;
use crate::threads::{
    counting_sort_with, fill_in_parts, fill_indexed, scatter_in_parts, DisjointSlice, Threads,
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

/// A disc of a component's block: its velocity (16 bytes, so that four share a
/// cache line).
#[derive(Clone, Copy, Debug)]
struct LocalDisc {
    v: [f64; 2],
}

/// The components of one step and their buffers (kept between steps).
#[derive(Clone, Debug, Default)]
pub(super) struct Components {
    sets: DisjointSets,
    label: Vec<u32>,
    local: Vec<u32>,
    member_start: Vec<u32>,
    members: Vec<u32>,
    depth: Vec<u32>,
    levels: Vec<u32>,
    run: Vec<u32>,
    keys: Vec<u32>,
    counts: Vec<u32>,
    run_base: Vec<u32>,
    run_start: Vec<u32>,
    pairs: LocalPairs,
    wall_start: Vec<u32>,
    walls: Vec<(u32, Walls)>,
    discs: Vec<LocalDisc>,
}

const NONE: u32 = u32::MAX;

impl Components {
    /// Splits the discs in a contact or on a wall into components. A component is
    /// numbered by its smallest disc; its walls keep the order of `walls`
    /// (ascending) and its pairs run level by level, each level in the order of
    /// `contacts` (lexicographic): see the module's text. Its discs are stored in
    /// the order of `nearby` (all discs, neighbours close together), so that the
    /// velocities one pair after another reads are close in memory; where a disc
    /// is stored does not change what is computed.
    pub(super) fn group(
        &mut self,
        n: usize,
        contacts: &[Contact],
        walls: &[(u32, Walls)],
        nearby: &[u32],
        threads: &Threads,
    ) {
        // the disjoint writes below rely on every disc being in `nearby` once
        assert_eq!(nearby.len(), n, "nearby must list every disc once");
        debug_assert!({
            let mut seen = vec![false; n];
            nearby
                .iter()
                .all(|&k| !std::mem::replace(&mut seen[k as usize], true))
        });
        // two passes over the pairs, two tasks of the pool: the union-find, and
        // in canonical order each pair's level (one more than the highest level
        // among the earlier pairs sharing a disc with it; `depth` holds, per
        // disc, one more than the level of its latest pair)
        let (sets, depth, levels) = (&mut self.sets, &mut self.depth, &mut self.levels);
        threads.install(|| {
            rayon::join(
                || {
                    sets.reset(n, threads);
                    for c in contacts {
                        sets.union(c.a, c.b);
                    }
                },
                || {
                    fill_indexed(depth, n, Some(threads), |_| 0);
                    levels.clear();
                    for c in contacts {
                        let (a, b) = (c.a as usize, c.b as usize);
                        let level = depth[a].max(depth[b]);
                        depth[a] = level + 1;
                        depth[b] = level + 1;
                        levels.push(level);
                    }
                },
            )
        });
        // the discs in a component (on a wall, or in a pair) by their component,
        // numbered in the order of its smallest disc, its root
        fill_indexed(&mut self.label, n, Some(threads), |_| NONE);
        for &(k, _) in walls {
            self.label[k as usize] = 0;
        }
        let components = self.number_components();

        // discs by component, in `nearby` order within each (a stable counting
        // sort; the discs in no component go to a last bucket, left out)
        let label = &self.label;
        fill_in_parts(&mut self.keys, nearby.len(), Some(threads), |range| {
            nearby[range].iter().map(|&k| match label[k as usize] {
                NONE => components as u32,
                c => c,
            })
        });
        // every slot is overwritten by the sort: only a longer tail is filled
        self.members.resize(nearby.len(), 0);
        let members = DisjointSlice::new(&mut self.members);
        let keys = &self.keys;
        // SAFETY: every slot is given once, below the column's length
        let place = |k: usize, slot| *unsafe { members.get_unchecked(slot) } = nearby[k];
        // SAFETY: the keys are a slice, the same on both passes
        unsafe {
            counting_sort_with(
                keys.len(),
                |k| keys[k],
                components + 1,
                Some(threads),
                &mut self.member_start,
                &mut self.counts,
                place,
            );
        }
        self.member_start.pop();
        let member_start = &self.member_start;
        let members = member_start[components] as usize;
        self.members.truncate(members);
        // each component's number of levels: the largest `depth` of its discs,
        // since a disc's depth is one more than the highest level of its pairs
        let (placed, depth) = (&self.members, &self.depth);
        // (`run_base[c + 1]`, summed below; `run_base[0]` is 0)
        fill_indexed(
            &mut self.run_base,
            components + 1,
            Some(threads),
            |e| match e {
                0 => 0,
                c_plus_1 => {
                    let range =
                        member_start[c_plus_1 - 1] as usize..member_start[c_plus_1] as usize;
                    placed[range]
                        .iter()
                        .map(|&k| depth[k as usize])
                        .max()
                        .unwrap_or(0)
                }
            },
        );
        fill_indexed(&mut self.local, n, Some(threads), |_| NONE);
        let placed = &self.members;
        // SAFETY: a disc is a member of one component, once: `nearby` is a
        // permutation of the discs (asserted above)
        unsafe {
            scatter_in_parts(&mut self.local, members, Some(threads), |slots| {
                placed[slots.clone()].iter().zip(slots).map(|(&k, slot)| {
                    let k = k as usize;
                    (k, slot as u32 - member_start[label[k] as usize])
                })
            });
        }

        // pairs by component and level (a run), in canonical order within a run
        for c in 0..components {
            self.run_base[c + 1] += self.run_base[c];
        }
        let (run_base, label, levels) = (&self.run_base, &self.label, &self.levels);
        fill_in_parts(&mut self.run, contacts.len(), Some(threads), |range| {
            contacts[range.clone()]
                .iter()
                .zip(&levels[range])
                .map(|(c, &level)| level + run_base[label[c.a as usize] as usize])
        });
        let pairs = &mut self.pairs;
        let m = contacts.len();
        for column in [&mut pairs.a, &mut pairs.b] {
            column.resize(m, 0);
        }
        for column in [&mut pairs.dx, &mut pairs.dy, &mut pairs.q] {
            column.resize(m, 0.0);
        }
        let [a, b] = [&mut pairs.a, &mut pairs.b].map(|c| DisjointSlice::new(c));
        let [dx, dy, q] =
            [&mut pairs.dx, &mut pairs.dy, &mut pairs.q].map(|c| DisjointSlice::new(c));
        let local = &self.local;
        let run = &self.run;
        let place = |p: usize, slot| {
            let c = &contacts[p];
            // SAFETY: every slot is given once, below the columns' length
            unsafe {
                *a.get_unchecked(slot) = local[c.a as usize];
                *b.get_unchecked(slot) = local[c.b as usize];
                *dx.get_unchecked(slot) = c.sep.dx;
                *dy.get_unchecked(slot) = c.sep.dy;
                *q.get_unchecked(slot) = c.sep.q;
            }
        };
        // SAFETY: the runs are a slice, the same on both passes
        unsafe {
            counting_sort_with(
                m,
                |p| run[p],
                self.run_base[components] as usize,
                Some(threads),
                &mut self.run_start,
                &mut self.counts,
                place,
            );
        }

        // walls by component, in the order of `walls` within each
        self.walls.clear();
        self.walls.resize(walls.len(), (0, Walls::default()));
        let (label, local) = (&self.label, &self.local);
        let placed = DisjointSlice::new(&mut self.walls);
        // SAFETY: every slot is given once, below the column's length
        let place = |i: usize, slot| {
            *unsafe { placed.get_unchecked(slot) } = (local[walls[i].0 as usize], walls[i].1)
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

    /// Labels every disc marked in `label` (any value but `NONE`) or with a
    /// pair (`depth > 0`) with its component's number, and every other disc
    /// with `NONE`; returns the number of components. Component `c` is the one
    /// with the `c`-th smallest root (a root is its set's smallest disc). One
    /// serial pass in disc order, each root numbered as it comes (it comes
    /// before the rest of its set), each other disc taking its root's number,
    /// the paths halved on the way: on the 100000-disc benchmark this took 0.54
    /// ms a step against 0.89-0.95 for three passes in parts on one thread and
    /// 0.73-0.82 on two.
    fn number_components(&mut self) -> usize {
        let mut count = 0;
        for k in 0..self.label.len() {
            if self.label[k] == NONE && self.depth[k] == 0 {
                continue;
            }
            let root = self.sets.root(k as u32) as usize;
            self.label[k] = if root == k {
                count += 1;
                count - 1
            } else {
                self.label[root]
            };
        }
        count as usize
    }

    /// Runs the canonical loop in every component, in parallel, and writes the new
    /// velocities back. Returns the largest sweep count (at least 1), or the
    /// smallest disc and the size of the first component (by number) that had not
    /// settled within `max_sweeps`.
    pub(super) fn resolve(
        &mut self,
        v: &mut [[f64; 2]],
        max_sweeps: u64,
        threads: &Threads,
    ) -> Result<u64, (usize, usize)> {
        let components = self.member_start.len().saturating_sub(1);
        let read: &[[f64; 2]] = v;
        let (members, member_start) = (&self.members, &self.member_start);
        fill_in_parts(&mut self.discs, members.len(), Some(threads), |range| {
            members[range].iter().map(|&k| LocalDisc {
                v: read[k as usize],
            })
        });
        let (pairs, walls) = (&self.pairs, &self.walls);
        let (run_base, run_start, wall_start) = (&self.run_base, &self.run_start, &self.wall_start);
        // (largest sweep count, first component that did not settle)
        let shared = DisjointSlice::new(&mut self.discs);
        let (sweeps, failed) = threads.install(|| {
            (0..components)
                .into_par_iter()
                .map(|c| {
                    // SAFETY: the components' member ranges are disjoint
                    let block = unsafe {
                        shared.range(member_start[c] as usize..member_start[c + 1] as usize)
                    };
                    let runs = &run_start[run_base[c] as usize..=run_base[c + 1] as usize];
                    let component = Component {
                        walls: &walls[wall_start[c] as usize..wall_start[c + 1] as usize],
                        pairs: pairs.columns(runs[0] as usize..runs[runs.len() - 1] as usize),
                        runs,
                    };
                    match component.settle(block, max_sweeps) {
                        Some(sweeps) => (sweeps, NONE),
                        None => (0, c as u32),
                    }
                })
                .reduce(|| (1, NONE), |a, b| (a.0.max(b.0), a.1.min(b.1)))
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
        if failed != NONE {
            let c = failed as usize;
            let range = self.member_start[c] as usize..self.member_start[c + 1] as usize;
            let first = self.members[range].iter().min().copied().unwrap_or(0) as usize;
            let size = (self.member_start[c + 1] - self.member_start[c]) as usize;
            return Err((first, size));
        }
        Ok(sweeps)
    }
}

/// Union-find over `0..n` in which every root is the smallest element of its set.
#[derive(Clone, Debug, Default)]
pub(super) struct DisjointSets {
    parent: Vec<u32>,
}

impl DisjointSets {
    /// `n` singletons (written in parts on `threads`).
    pub(super) fn reset(&mut self, n: usize, threads: &Threads) {
        fill_indexed(&mut self.parent, n, Some(threads), |k| k as u32);
    }

    /// Joins the sets of `a` and `b`; the smaller root stays the root.
    pub(super) fn union(&mut self, a: u32, b: u32) {
        let (ra, rb) = (self.root(a), self.root(b));
        self.parent[ra.max(rb) as usize] = ra.min(rb);
    }

    /// The root of `k`'s set (its smallest element), halving the path on the way.
    pub(super) fn root(&mut self, mut k: u32) -> u32 {
        while self.parent[k as usize] != k {
            let grand = self.parent[self.parent[k as usize] as usize];
            self.parent[k as usize] = grand;
            k = grand;
        }
        k
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

    /// 2000 discs at random in a 60 x 60 square, in contact within `q <= limit`,
    /// the last five far from everything; every 97th disc and the far ones on a
    /// wall, so that some components are walls only.
    fn scattered_discs(limit: f64) -> (usize, Vec<Contact>, Vec<(u32, Walls)>, ContactGrid) {
        let mut rng = Rng::new(5);
        let n = 2000;
        let mut x: Vec<f64> = (0..n).map(|_| rng.uniform() * 60.0).collect();
        let mut y: Vec<f64> = (0..n).map(|_| rng.uniform() * 60.0).collect();
        // the last few far from everything
        for k in n - 5..n {
            (x[k], y[k]) = (500.0 + 10.0 * k as f64, 500.0);
        }
        let mut contacts = Vec::new();
        let mut grid = ContactGrid::default();
        grid.find(&x, &y, limit, &Threads::single(), &mut contacts);
        // some discs on a wall, some of them without a pair: components of walls only
        let wall = Walls {
            low_x: true,
            ..Walls::default()
        };
        let walls: Vec<(u32, Walls)> = (0..n as u32)
            .filter(|&k| k % 97 == 0 || k as usize >= n - 5)
            .map(|k| (k, wall))
            .collect();
        (n, contacts, walls, grid)
    }

    #[test]
    fn components_are_the_connected_sets_numbered_by_their_smallest_disc() {
        // about 1.7 contacts per disc: many components, some of them large
        let (n, contacts, walls, grid) = scattered_discs(1.0);
        // the reference: connected sets by a search over the contact graph
        let mut neighbours = vec![Vec::new(); n];
        for c in &contacts {
            neighbours[c.a as usize].push(c.b as usize);
            neighbours[c.b as usize].push(c.a as usize);
        }
        let on_wall: std::collections::HashSet<usize> =
            walls.iter().map(|&(k, _)| k as usize).collect();
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
        assert!(expected.len() > 100 && expected.iter().any(|set| set.len() > 10));
        for threads in [1, 2, 3] {
            let mut components = Components::default();
            let pool = Threads::new(threads).unwrap();
            components.group(n, &contacts, &walls, grid.nearby_order(), &pool);
            let c = &components;
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
        let (n, contacts, walls, grid) = scattered_discs(4.0);
        let mut components = Components::default();
        components.group(
            n,
            &contacts,
            &walls,
            grid.nearby_order(),
            &Threads::single(),
        );
        // the same grouping, to the bit, on two threads
        let mut on_two = Components::default();
        let two = Threads::new(2).unwrap();
        on_two.group(n, &contacts, &walls, grid.nearby_order(), &two);
        assert_eq!(on_two.members, components.members);
        assert_eq!(on_two.member_start, components.member_start);
        assert_eq!(on_two.run_start, components.run_start);
        assert_eq!(on_two.run_base, components.run_base);
        assert_eq!(on_two.wall_start, components.wall_start);
        assert_eq!(on_two.walls, components.walls);
        let p = (&on_two.pairs, &components.pairs);
        assert!(p.0.a == p.1.a && p.0.b == p.1.b && p.0.q == p.1.q);
        assert!(p.0.dx == p.1.dx && p.0.dy == p.1.dy);
        let c = &components;
        assert_eq!(c.pairs.a.len(), contacts.len());
        assert_eq!(c.walls.len(), walls.len());
        let mut wall_only = 0;
        let components_count = c.member_start.len() - 1;
        let mut largest_run = 0;
        for comp in 0..components_count {
            let global = |local: u32| c.members[(c.member_start[comp] + local) as usize];
            let runs = &c.run_start[c.run_base[comp] as usize..=c.run_base[comp + 1] as usize];
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
        let mut rows: Vec<(u32, u32, [u64; 3])> = Vec::new();
        for comp in 0..components_count {
            let global = |local: u32| c.members[(c.member_start[comp] + local) as usize];
            let runs = &c.run_start[c.run_base[comp] as usize..=c.run_base[comp + 1] as usize];
            for i in runs[0] as usize..runs[runs.len() - 1] as usize {
                let p = &c.pairs;
                let sep = [p.dx[i], p.dy[i], p.q[i]].map(f64::to_bits);
                rows.push((global(p.a[i]), global(p.b[i]), sep));
            }
        }
        rows.sort_unstable();
        let expected: Vec<(u32, u32, [u64; 3])> = contacts
            .iter()
            .map(|k| (k.a, k.b, [k.sep.dx, k.sep.dy, k.sep.q].map(f64::to_bits)))
            .collect();
        assert_eq!(rows, expected);
    }
}
