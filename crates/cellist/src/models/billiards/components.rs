//! Connected components of the overlap graph (SPEC.md section 4, E2): a resolution
//! changes velocities only inside one component, so each component runs the
//! canonical loop on its own (its wall discs ascending, then its pairs in
//! lexicographic order, until a sweep changes nothing), and components run in
//! parallel. Each component's discs are gathered into one contiguous block of
//! velocities, so every task owns its own range: no shared writes at all.

use super::contacts::Contact;
use super::rules::{Separation, Walls};
use crate::threads::{DisjointSlice, Threads};
use rayon::prelude::*;

/// A pair in a component, by positions within the component's block.
#[derive(Clone, Copy, Debug)]
struct LocalPair {
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

/// The components of one step and their buffers (kept between steps).
#[derive(Clone, Debug, Default)]
pub(super) struct Components {
    sets: DisjointSets,
    label: Vec<u32>,
    cursor: Vec<u32>,
    local: Vec<u32>,
    member_start: Vec<u32>,
    members: Vec<u32>,
    pair_start: Vec<u32>,
    pairs: Vec<LocalPair>,
    wall_start: Vec<u32>,
    walls: Vec<(u32, Walls)>,
    discs: Vec<LocalDisc>,
}

const NONE: u32 = u32::MAX;

impl Components {
    /// Splits the discs in a contact or on a wall into components. A component is
    /// numbered by its smallest disc and its pairs and walls keep the order of
    /// `contacts` and `walls` (lexicographic, ascending): the canonical order. Its
    /// discs are stored in the order of `nearby` (all discs, neighbours close
    /// together), so that the velocities one pair after another reads are close
    /// in memory; where a disc is stored does not change what is computed.
    pub(super) fn group(
        &mut self,
        n: usize,
        contacts: &[Contact],
        walls: &[(u32, Walls)],
        nearby: &[u32],
    ) {
        self.sets.reset(n);
        self.label.clear();
        self.label.resize(n, NONE);
        for c in contacts {
            self.sets.union(c.a, c.b);
            self.label[c.a as usize] = 0;
            self.label[c.b as usize] = 0;
        }
        for &(k, _) in walls {
            self.label[k as usize] = 0;
        }
        let mut count = 0u32;
        for k in 0..n {
            if self.label[k] == NONE {
                continue;
            }
            let r = self.sets.root(k as u32) as usize;
            self.label[k] = if r == k {
                count += 1;
                count - 1
            } else {
                self.label[r]
            };
        }
        let components = count as usize;

        // discs by component, in `nearby` order within each
        counting_starts(
            &mut self.member_start,
            components,
            (0..n).filter_map(|k| (self.label[k] != NONE).then_some(self.label[k])),
        );
        self.members.clear();
        self.members
            .resize(*self.member_start.last().unwrap_or(&0) as usize, 0);
        self.local.clear();
        self.local.resize(n, NONE);
        self.cursor.clone_from(&self.member_start);
        for &k in nearby {
            let k = k as usize;
            let c = self.label[k];
            if c != NONE {
                let slot = self.cursor[c as usize];
                self.members[slot as usize] = k as u32;
                self.local[k] = slot - self.member_start[c as usize];
                self.cursor[c as usize] += 1;
            }
        }

        counting_starts(
            &mut self.pair_start,
            components,
            contacts.iter().map(|c| self.label[c.a as usize]),
        );
        self.pairs.clear();
        self.pairs.resize(
            contacts.len(),
            LocalPair {
                a: 0,
                b: 0,
                sep: Separation {
                    dx: 0.0,
                    dy: 0.0,
                    q: 0.0,
                },
            },
        );
        self.cursor.clone_from(&self.pair_start);
        for c in contacts {
            let comp = self.label[c.a as usize] as usize;
            self.pairs[self.cursor[comp] as usize] = LocalPair {
                a: self.local[c.a as usize],
                b: self.local[c.b as usize],
                sep: c.sep,
            };
            self.cursor[comp] += 1;
        }

        counting_starts(
            &mut self.wall_start,
            components,
            walls.iter().map(|&(k, _)| self.label[k as usize]),
        );
        self.walls.clear();
        self.walls.resize(walls.len(), (0, Walls::default()));
        self.cursor.clone_from(&self.wall_start);
        for &(k, w) in walls {
            let comp = self.label[k as usize] as usize;
            self.walls[self.cursor[comp] as usize] = (self.local[k as usize], w);
            self.cursor[comp] += 1;
        }
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
        self.discs.clear();
        let read: &[[f64; 2]] = v;
        let (members, member_start) = (&self.members, &self.member_start);
        self.discs.extend(members.iter().map(|&k| LocalDisc {
            v: read[k as usize],
        }));
        let (pairs, walls) = (&self.pairs, &self.walls);
        let (pair_start, wall_start) = (&self.pair_start, &self.wall_start);
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
                    let component = Component {
                        walls: &walls[wall_start[c] as usize..wall_start[c + 1] as usize],
                        pairs: &pairs[pair_start[c] as usize..pair_start[c + 1] as usize],
                    };
                    match component.settle(block, max_sweeps) {
                        Some(sweeps) => (sweeps, NONE),
                        None => (0, c as u32),
                    }
                })
                .reduce(|| (1, NONE), |a, b| (a.0.max(b.0), a.1.min(b.1)))
        });
        for (disc, &k) in self.discs.iter().zip(&self.members) {
            v[k as usize] = disc.v;
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
    /// `n` singletons.
    pub(super) fn reset(&mut self, n: usize) {
        self.parent.clear();
        self.parent.extend(0..n as u32);
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

/// `starts[c]..starts[c + 1]` for the counts of `labels` over `components`.
fn counting_starts(starts: &mut Vec<u32>, components: usize, labels: impl Iterator<Item = u32>) {
    starts.clear();
    starts.resize(components + 1, 0);
    for c in labels {
        starts[c as usize + 1] += 1;
    }
    for c in 0..components {
        starts[c + 1] += starts[c];
    }
}

/// One component's walls and pairs, in canonical order.
struct Component<'a> {
    walls: &'a [(u32, Walls)],
    pairs: &'a [LocalPair],
}

impl Component<'_> {
    /// The canonical loop on this component: sweeps until one changes nothing; the
    /// number of sweeps (the last included), or `None` past `max_sweeps`.
    fn settle(&self, block: &mut [LocalDisc], max_sweeps: u64) -> Option<u64> {
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
            for p in self.pairs {
                let (a, b) = (p.a as usize, p.b as usize);
                let (mut va, mut vb) = (block[a].v, block[b].v);
                if p.sep.collide(&mut va, &mut vb) {
                    block[a].v = va;
                    block[b].v = vb;
                    changed = true;
                }
            }
            if !changed {
                return Some(sweeps);
            }
        }
    }
}
